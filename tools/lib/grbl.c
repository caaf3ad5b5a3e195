/*
 * grbl.c - the Grbl 1.1 protocol, pure (see grbl.h). The behaviour cited is
 * gnea/grbl v1.1h: grbl/serial.c (real-time bytes picked off in the receive
 * interrupt), grbl/protocol.c (line assembly), grbl/system.c
 * (system_execute_line), grbl/report.c (report_realtime_status and the
 * settings, parameter and parser-state reports), the docs in doc/markdown.
 */
#include "grbl.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* ---- real-time bytes -------------------------------------------------- */

grbl_rt grbl_rt_of(unsigned char c)
{
	switch (c) {
	case 0x18:
		return GRBL_RT_RESET;
	case '?':
		return GRBL_RT_STATUS;
	case '~':
		return GRBL_RT_CYCLE_START;
	case '!':
		return GRBL_RT_FEED_HOLD;
	case 0x84:
		return GRBL_RT_SAFETY_DOOR;
	case 0x85:
		return GRBL_RT_JOG_CANCEL;
	case 0x9E:
		return GRBL_RT_SPINDLE_STOP;
	case 0xA0:
		return GRBL_RT_FLOOD;
	case 0xA1:
		return GRBL_RT_MIST;
	default:
		break;
	}
	if (c >= 0x90 && c <= 0x97) {
		return (grbl_rt)(GRBL_RT_FEED_100 + (c - 0x90));
	}
	if (c >= 0x99 && c <= 0x9D) {
		return (grbl_rt)(GRBL_RT_SPINDLE_100 + (c - 0x99));
	}
	return GRBL_RT_NONE;
}

const char *grbl_rt_name(grbl_rt rt)
{
	static const char *const names[GRBL_RT_COUNT] = {
	    "none",          "soft reset",    "status",       "cycle start",
	    "feed hold",     "safety door",   "jog cancel",   "feed override 100 %",
	    "feed +10 %",    "feed -10 %",    "feed +1 %",    "feed -1 %",
	    "rapid 100 %",   "rapid 50 %",    "rapid 25 %",   "spindle override 100 %",
	    "spindle +10 %", "spindle -10 %", "spindle +1 %", "spindle -1 %",
	    "spindle stop",  "flood coolant", "mist coolant"};
	return (unsigned)rt < GRBL_RT_COUNT ? names[rt] : "?";
}

static int clampi(int v, int lo, int hi)
{
	return v < lo ? lo : v > hi ? hi : v;
}

int grbl_override_step(grbl_rt rt, int pct)
{
	switch (rt) {
	case GRBL_RT_FEED_100:
	case GRBL_RT_RAPID_100:
	case GRBL_RT_SPINDLE_100:
		return 100;
	case GRBL_RT_FEED_PLUS_10:
	case GRBL_RT_SPINDLE_PLUS_10:
		return clampi(pct + 10, 10, 200);
	case GRBL_RT_FEED_MINUS_10:
	case GRBL_RT_SPINDLE_MINUS_10:
		return clampi(pct - 10, 10, 200);
	case GRBL_RT_FEED_PLUS_1:
	case GRBL_RT_SPINDLE_PLUS_1:
		return clampi(pct + 1, 10, 200);
	case GRBL_RT_FEED_MINUS_1:
	case GRBL_RT_SPINDLE_MINUS_1:
		return clampi(pct - 1, 10, 200);
	case GRBL_RT_RAPID_50:
		return 50;
	case GRBL_RT_RAPID_25:
		return 25;
	default:
		return pct;
	}
}

/* ---- receiving ---------------------------------------------------------- */

#define RX_CAP  (GRBL_RX_SIZE + GRBL_RX_MARKS)
#define RX_MARK 256u

void grbl_rx_init(struct grbl_rx *rx)
{
	memset(rx, 0, sizeof(*rx));
}

void grbl_rx_reset(struct grbl_rx *rx)
{
	uint64_t overflows = rx->overflows;
	grbl_rx_init(rx);
	rx->overflows = overflows;
}

static uint32_t rx_count(const struct grbl_rx *rx)
{
	return rx->head - rx->tail;
}

static uint16_t *rx_at(struct grbl_rx *rx, uint32_t i)
{
	return &rx->buf[i % RX_CAP];
}

/* One line byte into the line being assembled (not ready). */
static int assemble(struct grbl_rx *rx, uint16_t v)
{
	if (v >= RX_MARK) {
		rx->ready = 1;
		rx->lost = v - RX_MARK;
		rx->len = 0;
		rx->over = 0;
		return 1;
	}
	if (v == '\n' || v == '\r') {
		rx->ready = 1;
		return 1;
	}
	if (rx->len < GRBL_LINE_MAX) {
		rx->line[rx->len++] = (char)v;
	} else {
		rx->over = 1; /* the rest is dropped; the line is answered error:11 */
	}
	return 0;
}

/* The newest lost-line mark in the buffer, or NULL. */
static uint16_t *last_mark(struct grbl_rx *rx)
{
	for (uint32_t i = rx->head; i != rx->tail; i--) {
		uint16_t *v = rx_at(rx, i - 1);
		if (*v >= RX_MARK) {
			return v;
		}
	}
	return NULL;
}

/* The receive buffer is full: drop the line this byte belongs to. Its bytes
 * already buffered (after the last line end in the buffer) go too, and a
 * mark takes their place, counting the lines lost (when GRBL_RX_MARKS marks
 * wait already, the newest one counts them: the answers stay one per line). */
static void overflow(struct grbl_rx *rx, unsigned char c)
{
	rx->overflows++;
	if (!rx->dropping) {
		rx->dropping = 1;
		rx->drop_bytes = 0;
		/* take back the partial line's bytes */
		while (rx_count(rx) > 0) {
			uint16_t v = *rx_at(rx, rx->head - 1);
			if (v == '\n' || v == '\r' || v >= RX_MARK) {
				break;
			}
			rx->head--;
			rx->bytes--;
			rx->drop_bytes++;
		}
		uint16_t *last = rx_count(rx) ? rx_at(rx, rx->head - 1) : NULL;
		if ((last == NULL || *last < RX_MARK) && rx->marks < GRBL_RX_MARKS) {
			*rx_at(rx, rx->head++) = (uint16_t)RX_MARK; /* 0 lines so far */
			rx->marks++;
		}
	}
	rx->drop_bytes++;
	if (c == '\n' || c == '\r') {
		/* the dropped line ends: count it on the newest mark */
		uint16_t *m = last_mark(rx);
		if (m != NULL && *m < 0xFFFF) {
			(*m)++;
		}
		rx->dropping = 0;
	}
}

static void store(struct grbl_rx *rx, unsigned char c)
{
	if (rx->dropping) {
		overflow(rx, c);
		return;
	}
	if (rx->bytes >= GRBL_RX_SIZE) {
		overflow(rx, c);
		return;
	}
	*rx_at(rx, rx->head++) = c;
	rx->bytes++;
}

/* Move buffered bytes into the line until it is complete. A mark whose line
 * is still being dropped stays until that line's end has been counted. */
static void pull(struct grbl_rx *rx)
{
	while (!rx->ready && rx_count(rx) > 0) {
		uint16_t v = *rx_at(rx, rx->tail);
		if (v >= RX_MARK && rx->dropping && rx_count(rx) == 1) {
			break;
		}
		rx->tail++;
		if (v >= RX_MARK) {
			rx->marks--;
			rx->dropped = rx->drop_bytes;
			rx->drop_bytes = 0;
		} else {
			rx->bytes--;
		}
		assemble(rx, v);
	}
}

static void line_byte(struct grbl_rx *rx, unsigned char c)
{
	if (!rx->ready && rx_count(rx) == 0) {
		assemble(rx, c); /* straight into the line */
	} else {
		store(rx, c);
	}
}

void grbl_rx_feed(struct grbl_rx *rx, const unsigned char *b, size_t n,
                  void (*rt)(void *ctx, grbl_rt cmd), void *ctx)
{
	for (size_t i = 0; i < n; i++) {
		grbl_rt cmd = grbl_rt_of(b[i]);
		if (rx->lead) {
			rx->lead = 0;
			if (!(cmd != GRBL_RT_NONE && b[i] > 0x7F)) {
				line_byte(rx, 0xC2); /* not a UTF-8 real-time byte: data */
			}
		}
		if (cmd != GRBL_RT_NONE) {
			if (rt != NULL) {
				rt(ctx, cmd);
			}
			continue;
		}
		if (b[i] == 0xC2) {
			rx->lead = 1;
			continue;
		}
		line_byte(rx, b[i]);
	}
}

int grbl_rx_line(const struct grbl_rx *rx, struct grbl_line *out)
{
	if (!rx->ready) {
		return 0;
	}
	out->text = rx->line;
	out->len = rx->len;
	out->lost = rx->lost;
	out->overflow = rx->lost ? rx->dropped : 0;
	out->kind = rx->lost ? GRBL_LINE_LOST : rx->over ? GRBL_LINE_TOO_LONG : GRBL_LINE_TEXT;
	return 1;
}

void grbl_rx_done(struct grbl_rx *rx)
{
	rx->ready = 0;
	rx->len = 0;
	rx->over = 0;
	rx->lost = 0;
	rx->dropped = 0;
	pull(rx);
}

uint32_t grbl_rx_available(const struct grbl_rx *rx)
{
	return rx->bytes >= GRBL_RX_SIZE ? 0 : GRBL_RX_SIZE - rx->bytes;
}

int grbl_rx_pending(const struct grbl_rx *rx)
{
	return rx->ready || rx->len > 0 || rx->over || rx_count(rx) > 0 || rx->dropping || rx->lead;
}

/* ---- system lines ------------------------------------------------------ */

/* The line as Grbl's protocol_main_loop keeps it: bytes <= ' ' and '/'
 * dropped, comments removed, letters upper-cased; map[k]: raw offset of
 * kept byte k. */
static size_t preparse(const char *t, size_t n, char *out, size_t *map, size_t cap)
{
	size_t k = 0;
	int paren = 0, semi = 0;
	for (size_t i = 0; i < n && k + 1 < cap; i++) {
		unsigned char c = (unsigned char)t[i];
		if (semi) {
			break;
		}
		if (paren) {
			paren = c != ')';
			continue;
		}
		if (c <= ' ' || c == '/') {
			continue;
		}
		if (c == '(') {
			paren = 1;
			continue;
		}
		if (c == ';') {
			semi = 1;
			continue;
		}
		out[k] = (char)(c >= 'a' && c <= 'z' ? c - 'a' + 'A' : c);
		map[k++] = i;
	}
	out[k] = '\0';
	return k;
}

/* Grbl's read_float: a decimal number (sign, digits, one point). */
static int read_num(const char *s, size_t *i, double *v)
{
	size_t j = *i;
	int neg = 0, digits = 0;
	double x = 0.0, scale = 1.0;
	if (s[j] == '-' || s[j] == '+') {
		neg = s[j] == '-';
		j++;
	}
	for (;; j++) {
		if (s[j] >= '0' && s[j] <= '9') {
			if (scale < 1.0) {
				x += (s[j] - '0') * scale;
				scale *= 0.1;
			} else {
				x = x * 10.0 + (s[j] - '0');
			}
			digits++;
		} else if (s[j] == '.' && scale == 1.0) {
			scale = 0.1;
		} else {
			break;
		}
	}
	if (!digits) {
		return 0;
	}
	*v = neg ? -x : x;
	*i = j;
	return 1;
}

void grbl_sys_parse(const char *text, size_t len, struct grbl_sys *o)
{
	char l[GRBL_LINE_MAX + 2];
	size_t map[GRBL_LINE_MAX + 2];
	size_t n = preparse(text, len, l, map, sizeof(l));
	memset(o, 0, sizeof(*o));
	o->kind = GRBL_SYS_BAD;
	o->code = GRBL_E_INVALID_STATEMENT;
	if (n == 0 || l[0] != '$') {
		return;
	}
	switch (l[1]) {
	case '\0':
		o->kind = GRBL_SYS_HELP;
		return;
	case 'J':
		if (l[2] != '=') {
			return; /* error:3, as Grbl */
		}
		o->kind = GRBL_SYS_JOG;
		o->arg = map[2] + 1;
		return;
	case '$':
	case 'G':
	case 'C':
	case 'X':
		if (l[2] != '\0') {
			return;
		}
		o->kind = l[1] == '$'   ? GRBL_SYS_SETTINGS
		          : l[1] == 'G' ? GRBL_SYS_GCODE
		          : l[1] == 'C' ? GRBL_SYS_CHECK
		                        : GRBL_SYS_UNLOCK;
		return;
	case '#':
		if (l[2] == '\0') {
			o->kind = GRBL_SYS_PARAMS;
		}
		return;
	case 'H':
		if (l[2] == '\0' || (l[3] == '\0' && strchr("XYZABC", l[2]) != NULL)) {
			o->kind = GRBL_SYS_HOME;
			o->axis = l[2];
		}
		return;
	case 'S':
		if (strcmp(l, "$SLP") == 0) {
			o->kind = GRBL_SYS_SLEEP;
		}
		return;
	case 'I':
		if (l[2] == '\0') {
			o->kind = GRBL_SYS_INFO;
		} else if (l[2] == '=') {
			o->kind = GRBL_SYS_INFO_SET;
			o->arg = map[2] + 1;
		}
		return;
	case 'R':
		if (strncmp(l, "$RST=", 5) == 0 && l[5] != '\0' && strchr("$#*", l[5]) && !l[6]) {
			o->kind = GRBL_SYS_RESTORE;
		}
		return;
	case 'N':
		if (l[2] == '\0') {
			o->kind = GRBL_SYS_STARTUP;
			return;
		}
		break;
	default:
		break;
	}
	/* $x=val or $Nx=line */
	size_t i = l[1] == 'N' ? 2 : 1;
	double p, v;
	if (!read_num(l, &i, &p)) {
		o->code = GRBL_E_BAD_NUMBER;
		return;
	}
	if (l[i] != '=') {
		return;
	}
	if (l[1] == 'N') {
		o->kind = GRBL_SYS_STARTUP_SET;
		o->number = (int)p;
		o->arg = map[i] + 1;
		return;
	}
	i++;
	if (!read_num(l, &i, &v)) {
		o->code = GRBL_E_BAD_NUMBER;
		return;
	}
	if (l[i] != '\0' || p > 255 || p < 0 || p != floor(p)) {
		return;
	}
	o->kind = GRBL_SYS_SET;
	o->number = (int)p;
	o->value = v;
}

/* ---- reports ------------------------------------------------------------ */

void grbl_axes_of(const struct mlip_machine *m, struct grbl_axes *ax)
{
	static const char letters[] = "XYZABC";
	ax->n = 3;
	for (int k = 0; k < MLIP_MAX_AXES; k++) {
		ax->of[k] = -1;
		for (int a = 0; a < m->n_axes; a++) {
			if (m->axis[a].letter == letters[k]) {
				ax->of[k] = a;
				if (k >= 3) {
					ax->n = k + 1;
				}
			}
		}
	}
}

/* Grbl's printFloat: fixed decimals, no "-0.000". */
static size_t put_num(char *buf, size_t len, double v, int decimals)
{
	double r = pow(10.0, decimals);
	double x = round(v * r) / r;
	if (x == 0.0 || !isfinite(x)) {
		x = 0.0;
	}
	int n = snprintf(buf, len, "%.*f", decimals, x);
	return n < 0 ? 0 : (size_t)n >= len ? len - 1 : (size_t)n;
}

struct out {
	char *b;
	size_t len, k;
};

static void put(struct out *o, const char *s)
{
	size_t n = strlen(s);
	if (o->len == 0) {
		return;
	}
	if (o->k + n >= o->len) {
		n = o->len - 1 - o->k;
	}
	memcpy(o->b + o->k, s, n);
	o->k += n;
	o->b[o->k] = '\0';
}

static void putf(struct out *o, double v, int decimals)
{
	char t[64];
	put_num(t, sizeof(t), v, decimals);
	put(o, t);
}

static void puti(struct out *o, long v)
{
	char t[32];
	snprintf(t, sizeof(t), "%ld", v);
	put(o, t);
}

size_t grbl_axis_values(char *buf, size_t len, const double *v, const struct grbl_axes *ax,
                        const struct grbl_fmt *fmt)
{
	struct out o = {buf, len, 0};
	if (len) {
		buf[0] = '\0';
	}
	for (int k = 0; k < ax->n; k++) {
		double x = ax->of[k] >= 0 ? v[ax->of[k]] : 0.0;
		if (fmt->inches) {
			x /= 25.4;
		}
		if (k) {
			put(&o, ",");
		}
		putf(&o, x, fmt->inches ? 4 : 3);
	}
	return o.k;
}

void grbl_refresh_wco(struct grbl_refresh *r)
{
	r->wco = 0;
}

void grbl_refresh_ovr(struct grbl_refresh *r)
{
	r->ovr = 0;
}

size_t grbl_status_format(char *buf, size_t len, const struct grbl_status *s,
                          const struct grbl_axes *ax, const struct grbl_fmt *fmt,
                          struct grbl_refresh *rf)
{
	struct out o = {buf, len, 0};
	char v[256];
	double pos[MLIP_MAX_AXES];
	int mpos = fmt->mask & 1;
	if (len) {
		buf[0] = '\0';
	}
	put(&o, "<");
	put(&o, s->state);
	for (int k = 0; k < MLIP_MAX_AXES; k++) {
		pos[k] = mpos ? s->mpos[k] : s->mpos[k] - s->wco[k];
	}
	put(&o, mpos ? "|MPos:" : "|WPos:");
	grbl_axis_values(v, sizeof(v), pos, ax, fmt);
	put(&o, v);
	if (fmt->mask & 2) {
		put(&o, "|Bf:");
		puti(&o, s->bf_blocks);
		put(&o, ",");
		puti(&o, s->bf_bytes);
	}
	if (s->line > 0) {
		put(&o, "|Ln:");
		puti(&o, (long)s->line);
	}
	put(&o, "|FS:");
	putf(&o, fmt->inches ? s->feed_mm_min / 25.4 : s->feed_mm_min, fmt->inches ? 1 : 0);
	put(&o, ",");
	putf(&o, s->spindle_rpm, 0);
	if (s->pins != NULL && s->pins[0] != '\0') {
		put(&o, "|Pn:");
		put(&o, s->pins);
	}
	/* report.c: WCO every 30 reports busy, 10 idle, at once after a
	 * change; Ov every 20 / 10, at once after a change but not with WCO */
	if (rf->wco > 0) {
		rf->wco--;
	} else {
		rf->wco = (s->busy ? 30 : 10) - 1;
		if (rf->ovr == 0) {
			rf->ovr = 1;
		}
		put(&o, "|WCO:");
		grbl_axis_values(v, sizeof(v), s->wco, ax, fmt);
		put(&o, v);
	}
	if (rf->ovr > 0) {
		rf->ovr--;
	} else {
		rf->ovr = (s->busy ? 20 : 10) - 1;
		put(&o, "|Ov:");
		puti(&o, s->ov_feed);
		put(&o, ",");
		puti(&o, s->ov_rapid);
		put(&o, ",");
		puti(&o, s->ov_spindle);
		if (s->accessories != NULL && s->accessories[0] != '\0') {
			put(&o, "|A:");
			put(&o, s->accessories);
		}
	}
	put(&o, ">");
	return o.k;
}

void grbl_wco(const struct mlip_gcode_offsets *o, int n_axes, int z, double tlo_mm, double *wco)
{
	int sel = o->select >= 0 && o->select < MLIP_GCODE_N_COORD ? o->select : 0;
	for (int k = 0; k < MLIP_MAX_AXES; k++) {
		wco[k] = 0.0;
		if (k < n_axes) {
			wco[k] = o->coord[sel][k] + (o->g92_on ? o->g92[k] : 0.0) +
			         (k == z ? tlo_mm : 0.0);
		}
	}
}

/* $$: Grbl's numbered settings that mlip's machine answers (settings.md):
 * the rest (step pulses, inversions, debounce, pull-off, spindle PWM) have
 * no meaning for CiA 402 servo drives (their homing is the drive's own) and
 * are not listed. */
size_t grbl_setting_line(char *buf, size_t len, const struct mlip_machine *m,
                         const struct grbl_fmt *fmt, const struct grbl_homing *h, int index)
{
	static const char letters[] = "XYZABC";
	static const struct grbl_homing none;
	struct out o = {buf, len, 0};
	if (len) {
		buf[0] = '\0';
	}
	if (h == NULL) {
		h = &none;
	}
	int homing = h->enabled ? 3 : 0; /* $23..$25 */
	switch (index) {
	case 0:
		put(&o, "$10=");
		puti(&o, fmt->mask);
		return o.k;
	case 1: /* the contour tolerance is what junction deviation stands for */
		put(&o, "$11=");
		putf(&o, m->tolerance_mm, 3);
		return o.k;
	case 2: /* arcs become chords within this sagitta */
		put(&o, "$12=");
		putf(&o, m->tolerance_mm * MLIP_GCODE_ARC_FRACTION, 3);
		return o.k;
	case 3:
		put(&o, "$13=");
		puti(&o, fmt->inches);
		return o.k;
	case 4: /* every target is checked against the soft limits */
		put(&o, "$20=1");
		return o.k;
	case 5: /* a limit switch stops the machine (ALARM:1) */
		put(&o, h->hard_limits ? "$21=1" : "$21=0");
		return o.k;
	case 6: /* $H runs the drives' homing */
		put(&o, h->enabled ? "$22=1" : "$22=0");
		return o.k;
	default:
		break;
	}
	if (index < 7 + homing) {
		switch (index) {
		case 7:
			put(&o, "$23=");
			puti(&o, h->dir_mask);
			break;
		case 8:
			put(&o, "$24=");
			putf(&o, h->feed_mm_min, 3);
			break;
		default:
			put(&o, "$25=");
			putf(&o, h->seek_mm_min, 3);
			break;
		}
		return o.k;
	}
	/* per axis, in X Y Z A B C order, numbered by letter (grblHAL's A = 3) */
	int i = index - 7 - homing, group = 0;
	for (; group < 4; group++) {
		for (int k = 0; k < MLIP_MAX_AXES; k++) {
			int a = -1;
			for (int j = 0; j < m->n_axes; j++) {
				if (m->axis[j].letter == letters[k]) {
					a = j;
				}
			}
			if (a < 0) {
				continue;
			}
			if (i-- > 0) {
				continue;
			}
			const struct mlip_axis *x = &m->axis[a];
			put(&o, "$");
			puti(&o, 100 + group * 10 + k);
			put(&o, "=");
			switch (group) {
			case 0: /* steps/mm: the drive's counts per unit */
				putf(&o, x->counts_per_unit, 3);
				break;
			case 1: /* max rate, mm/min */
				putf(&o, x->max_vel * 60.0, 3);
				break;
			case 2: /* acceleration, mm/s^2 */
				putf(&o, x->max_accel, 3);
				break;
			default: /* max travel, mm */
				putf(&o, x->max_limit - x->min_limit, 3);
				break;
			}
			return o.k;
		}
	}
	return 0;
}

size_t grbl_gcode_state(char *buf, size_t len, const struct mlip_gcode *g, int program)
{
	static const char *const coord[] = {"G54", "G55",   "G56",   "G57",  "G58",
	                                    "G59", "G59.1", "G59.2", "G59.3"};
	struct out o = {buf, len, 0};
	if (len) {
		buf[0] = '\0';
	}
	put(&o, "[GC:G");
	/* G80: no motion mode after a canned cycle (Grbl's motion cancel) */
	puti(&o, g->motion >= 0 ? g->motion : g->cycle || g->cycle_off ? 80 : 0);
	put(&o, " ");
	int sel = g->off.select;
	put(&o, sel >= 0 && sel < MLIP_GCODE_N_COORD ? coord[sel] : "G54");
	put(&o, g->plane == 18 ? " G18" : g->plane == 19 ? " G19" : " G17");
	put(&o, g->inches ? " G20" : " G21");
	put(&o, g->absolute ? " G90" : " G91");
	put(&o, g->inverse_time ? " G93" : " G94");
	if (program >= 0) {
		put(&o, " M");
		puti(&o, program);
	}
	/* report.c: M3/M4/M5, then M7 and M8 both when both are on (else M9) */
	put(&o, g->spindle == 3 ? " M3" : g->spindle == 4 ? " M4" : " M5");
	if (g->coolant & MLIP_COOLANT_MIST) {
		put(&o, " M7");
	}
	if (g->coolant & MLIP_COOLANT_FLOOD) {
		put(&o, " M8");
	}
	if (!(g->coolant & (MLIP_COOLANT_MIST | MLIP_COOLANT_FLOOD))) {
		put(&o, " M9");
	}
	put(&o, " T");
	puti(&o, g->tool_sel > 0 ? g->tool_sel : g->off.tool > 0 ? g->off.tool : 0);
	put(&o, " F");
	putf(&o, g->feed_word > 0.0 ? g->feed_word : 0.0, g->inches ? 1 : 0);
	put(&o, " S");
	putf(&o, g->s_rpm > 0.0 ? g->s_rpm : 0.0, 0);
	put(&o, "]");
	return o.k;
}

size_t grbl_param_line(char *buf, size_t len, const struct mlip_gcode_offsets *o, double tlo_mm,
                       const struct grbl_axes *ax, const struct grbl_fmt *fmt, int index)
{
	static const char *const names[] = {"G54", "G55", "G56", "G57", "G58", "G59"};
	struct out w = {buf, len, 0};
	char v[256];
	if (len) {
		buf[0] = '\0';
	}
	if (index < 6) {
		put(&w, "[");
		put(&w, names[index]);
		put(&w, ":");
		grbl_axis_values(v, sizeof(v), o->coord[index], ax, fmt);
	} else if (index == 6 || index == 7) {
		put(&w, index == 6 ? "[G28:" : "[G30:");
		grbl_axis_values(v, sizeof(v), index == 6 ? o->g28 : o->g30, ax, fmt);
	} else if (index == 8) {
		double z[MLIP_MAX_AXES] = {0};
		put(&w, "[G92:");
		grbl_axis_values(v, sizeof(v), o->g92_on ? o->g92 : z, ax, fmt);
	} else if (index == 9) {
		put(&w, "[TLO:");
		put_num(v, sizeof(v), fmt->inches ? tlo_mm / 25.4 : tlo_mm, fmt->inches ? 4 : 3);
	} else if (index == 10) {
		double z[MLIP_MAX_AXES] = {0};
		put(&w, "[PRB:");
		grbl_axis_values(v, sizeof(v), z, ax, fmt); /* no probing yet (19) */
		strncat(v, ":0", sizeof(v) - strlen(v) - 1);
	} else {
		return 0;
	}
	put(&w, v);
	put(&w, "]");
	return w.k;
}

static int has(const char *msg, const char *s)
{
	return strstr(msg, s) != NULL;
}

int grbl_error_travel(const struct mlip_gcode_error *e)
{
	return has(e->msg, "soft limit");
}

int grbl_error_code(const struct mlip_gcode_error *e, int jog)
{
	const char *m = e->msg;
	if (has(m, "soft limit")) {
		return jog ? GRBL_E_TRAVEL : GRBL_E_TARGET;
	}
	if (has(m, "jog without F")) {
		return GRBL_E_FEED; /* Grbl: a jog's F is not modal, none is error 22 */
	}
	if (has(m, "Grbl jog")) {
		return GRBL_E_JOG;
	}
	if (has(m, "line too long")) {
		return GRBL_E_OVERFLOW;
	}
	if (has(m, "missing feed") || has(m, "feed F must be positive") ||
	    has(m, "needs its own F")) {
		return GRBL_E_FEED;
	}
	if (has(m, "duplicate") && has(m, "word")) {
		return GRBL_E_WORD_REPEATED;
	}
	if (has(m, "same modal group") || has(m, "two motion codes")) {
		return GRBL_E_MODAL_GROUP;
	}
	if (has(m, "both use axis words")) {
		return GRBL_E_AXIS_CONFLICT;
	}
	if (has(m, "G53")) {
		return GRBL_E_G53;
	}
	if (has(m, "without axis words")) {
		return GRBL_E_NO_AXIS_WORDS;
	}
	if (has(m, "takes no axis words") || has(m, "axis words with no motion mode")) {
		return GRBL_E_UNUSED_AXIS;
	}
	if (has(m, "arc with no I/J/K or R")) {
		return GRBL_E_NO_OFFSETS;
	}
	if (has(m, "R arc") || has(m, "zero radius") || has(m, "radius to start")) {
		return GRBL_E_ARC_RADIUS;
	}
	if (has(m, "arc too long") || has(m, "arc with both")) {
		return GRBL_E_TARGET;
	}
	if (has(m, "without G10") || has(m, "without G64") || has(m, "without G4") ||
	    has(m, "without an arc") || has(m, "not used by an arc")) {
		return GRBL_E_UNUSED_WORDS;
	}
	if (has(m, "G4 without P") || has(m, "needs P0") || has(m, "without L2")) {
		return GRBL_E_VALUE_MISSING;
	}
	if (has(m, "must be >= 0")) {
		return GRBL_E_NEGATIVE;
	}
	if (has(m, "has no number") || has(m, "malformed number") || has(m, "not finite")) {
		return GRBL_E_BAD_NUMBER;
	}
	if (has(m, "without a word letter") || has(m, "unexpected character") ||
	    has(m, "NUL byte") || has(m, "non-ASCII") || has(m, "UTF-8") ||
	    has(m, "unterminated comment")) {
		return GRBL_E_EXPECTED_LETTER;
	}
	return GRBL_E_UNSUPPORTED;
}

void grbl_msg_clean(char *s)
{
	for (; *s; s++) {
		unsigned char c = (unsigned char)*s;
		if (c < ' ' || c > '~') {
			*s = '?';
		} else if (c == ']') {
			*s = ')';
		} else if (c == '[') {
			*s = '(';
		}
	}
}
