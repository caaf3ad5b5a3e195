/*
 * fuzz/invariants.h - what must hold for any input to the two text front ends
 * (src/gcode/, src/machine/), checked by the fuzz targets (fuzz_gcode.c,
 * fuzz_config.c, which abort on a violation) and by the regression test
 * (tests/unit/test_fuzz_regress.c, which fails with the same text).
 *
 * Header-only, static functions: each includer gets its own copy. Every check
 * returns NULL when the invariant holds, else a static description of the
 * first violation (also kept in the context's why[] with the numbers).
 *
 * G-code, per emitted block (the sink sees every block):
 *   targets finite and within the soft limits, unused axes 0;
 *   feed finite and > 0 (rapids carry v_m, which is > 0 too);
 *   tol_mm in (0, eps];
 *   line = the line being parsed, rapid 0 or 1, seq 0, exact_stop 0 or 1;
 *   consecutive move points (home first) at least MLIP_GCODE_MERGE_MM apart;
 *   an event (dwell, pause) at the last point, dwell finite and >= 0.
 * Per line: an error names that line, a column within the line (or the
 *   "too long" column), a non-empty, NUL-terminated, printable-ASCII message;
 *   a line with an error other than MLIP_E_FULL emits nothing; MLIP_E_FULL
 *   exactly when the sink refused a block of that line.
 * Per program: mlip_gcode_finish fails ("empty program") exactly when no
 *   move was accepted, at line max(last, 1), column 0; notices well formed.
 *
 * Config: on success mlip_machine_check passes, every number is finite, the
 * axes, CAN ids, bitrates, profile and LOOKAHEAD are within their ranges; on
 * error the struct is unchanged (the caller compares with a copy), the line is
 * 0 or within the text, the column within a line, and the message non-empty,
 * NUL-terminated, valid UTF-8 without control characters other than tab.
 */
#ifndef MLIP_FUZZ_INVARIANTS_H
#define MLIP_FUZZ_INVARIANTS_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mlip/machine/config.h"
#include "mlip/gcode/gcode.h"
#include "mlip/types.h"
#include "program.h" /* tools/lib: mlip_program_list_parse, the second opinion */

#define INV_WHY 320

/* ---- shared ---------------------------------------------------------------- */

/* Length of the well-formed UTF-8 character at s[0..n), 0 when malformed
 * (RFC 3629), written independently of the two parsers' own. */
static size_t inv_utf8_len(const unsigned char *s, size_t n)
{
	uint32_t cp;
	size_t len, k;

	if (n == 0) {
		return 0;
	}
	if (s[0] < 0x80) {
		return 1;
	}
	if ((s[0] & 0xE0) == 0xC0) {
		len = 2;
		cp = s[0] & 0x1Fu;
	} else if ((s[0] & 0xF0) == 0xE0) {
		len = 3;
		cp = s[0] & 0x0Fu;
	} else if ((s[0] & 0xF8) == 0xF0) {
		len = 4;
		cp = s[0] & 0x07u;
	} else {
		return 0;
	}
	if (n < len) {
		return 0;
	}
	for (k = 1; k < len; k++) {
		if ((s[k] & 0xC0) != 0x80) {
			return 0;
		}
		cp = cp << 6 | (s[k] & 0x3Fu);
	}
	if ((len == 2 && cp < 0x80) || (len == 3 && cp < 0x800) || (len == 4 && cp < 0x10000) ||
	    (cp >= 0xD800 && cp <= 0xDFFF) || cp > 0x10FFFF) {
		return 0;
	}
	return len;
}

/* A message buffer of cap bytes: NUL within it, non-empty; ascii_only: bytes
 * 0x20..0x7E only, else valid UTF-8 with no control character but tab. */
static const char *inv_message(const char *msg, size_t cap, int ascii_only)
{
	const unsigned char *u = (const unsigned char *)msg;
	size_t n = 0, k;

	while (n < cap && msg[n] != '\0') {
		n++;
	}
	if (n == cap) {
		return "error message not NUL-terminated";
	}
	if (n == 0) {
		return "empty error message";
	}
	for (k = 0; k < n;) {
		size_t l;
		if (u[k] == 0x7F || (u[k] < 0x20 && (ascii_only || u[k] != '\t'))) {
			return "control character in error message";
		}
		if (ascii_only && u[k] >= 0x80) {
			return "non-ASCII byte in error message";
		}
		l = inv_utf8_len(u + k, n - k);
		if (l == 0) {
			return "invalid UTF-8 in error message";
		}
		k += l;
	}
	if (msg[n - 1] == ' ') {
		return "error message ends in a blank";
	}
	return NULL;
}

/* ---- G-code ------------------------------------------------------------------ */

/* A block as the check saw it, for a second run to compare with. */
struct inv_block_list {
	const struct mlip_block *b;
	size_t n;
};

struct inv_gcode {
	const struct mlip_machine *m;
	double prev[MLIP_MAX_AXES]; /* last accepted point, home first */
	uint32_t line;              /* line being parsed */
	size_t accepted;            /* blocks taken by the sink */
	size_t moves;               /* of which moves (events are no motion) */
	size_t line_blocks;         /* blocks taken during the current line */
	int line_refused;           /* the sink refused a block of this line */
	unsigned refuse_every;      /* 0: never; else refuse attempt k when k % n == n - 1 */
	size_t attempts;
	const struct inv_block_list *expect; /* NULL, or blocks another run gave */
	const char *bad;                     /* first violation */
	char why[INV_WHY];
};

/* The machine's I/O of INV_IO: a manual spindle 1000..24000 rpm, a manual
 * tool change at Z100 (inside both machines' limits, axis index 2), manual
 * coolant, three tools (sorted), digital outputs P0..P3, a probe. */
static const struct mlip_tool inv_tools[] = {
    {1, 1, 10.0, 6.0}, {2, 2, 30.5, 3.0}, {7, 5, -2.0, 0.0}};
static const struct mlip_gcode_io inv_io = {MLIP_IO_MANUAL,
                                            1000,
                                            24000,
                                            MLIP_IO_MANUAL,
                                            1u << 2,
                                            {0, 0, 100, 0, 0, 0},
                                            MLIP_IO_MANUAL,
                                            inv_tools,
                                            3,
                                            0,
                                            0,
                                            0,
                                            0,
                                            0x0Fu,
                                            1,
                                            0};

static void inv_gcode_init(struct inv_gcode *c, const struct mlip_machine *m)
{
	int i;

	memset(c, 0, sizeof *c);
	c->m = m;
	for (i = 0; i < m->n_axes; i++) {
		c->prev[i] = m->axis[i].home;
	}
}

static const char *inv_gcode_fail(struct inv_gcode *c, const char *what, int axis, double v)
{
	if (!c->bad) {
		c->bad = what;
		snprintf(c->why, sizeof c->why, "line %u, block %zu: %s (axis %d, value %.17g)",
		         (unsigned)c->line, c->accepted + 1, what, axis, v);
	}
	return what;
}

/* One block: the checks above. Does not decide acceptance. */
static const char *inv_gcode_block(struct inv_gcode *c, const struct mlip_block *b)
{
	const struct mlip_machine *m = c->m;
	double d2 = 0, eps = m->tolerance_mm;
	int i;

	for (i = 0; i < MLIP_MAX_AXES; i++) {
		double t = b->target[i];
		if (i >= m->n_axes) {
			if (t != 0.0) {
				return inv_gcode_fail(c, "unused axis slot not 0", i, t);
			}
			continue;
		}
		if (!isfinite(t)) {
			return inv_gcode_fail(c, "target not finite", i, t);
		}
		if (t < m->axis[i].min_limit || t > m->axis[i].max_limit) {
			return inv_gcode_fail(c, "target beyond a soft limit", i, t);
		}
		d2 += (t - c->prev[i]) * (t - c->prev[i]);
	}
	if (b->kind > MLIP_BLOCK_SPEED) {
		return inv_gcode_fail(c, "unknown block kind", -1, b->kind);
	}
	/* the machine's I/O (INV_IO): a speed within the spindle's, a whole
	 * tool of the table (or 0), coolant bits; nothing else carries a value */
	if (b->kind == MLIP_BLOCK_SPINDLE &&
	    !(fabs(b->value) <= inv_io.max_rpm &&
	      (b->value == 0 || fabs(b->value) >= inv_io.min_rpm))) {
		return inv_gcode_fail(c, "spindle speed outside MIN_RPM..MAX_RPM", -1, b->value);
	}
	if (b->kind == MLIP_BLOCK_SPEED && !(b->value >= 0 && b->value <= inv_io.max_rpm &&
	                                     (b->value == 0 || b->value >= inv_io.min_rpm))) {
		return inv_gcode_fail(c, "MDI speed outside 0, MIN_RPM..MAX_RPM", -1, b->value);
	}
	if (b->kind == MLIP_BLOCK_TOOL &&
	    !(b->value == 0 || mlip_gcode_find_tool(&inv_io, (int32_t)b->value) != NULL)) {
		return inv_gcode_fail(c, "tool change to a tool not in the table", -1, b->value);
	}
	if (b->kind == MLIP_BLOCK_COOLANT &&
	    !(b->value >= 0 && b->value <= 3 && b->value == floor(b->value))) {
		return inv_gcode_fail(c, "coolant bits not 0..3", -1, b->value);
	}
	if (b->kind == MLIP_BLOCK_OUTPUT &&
	    !(fabs(b->value) >= 1 && fabs(b->value) <= MLIP_DOUT_MAX &&
	      b->value == floor(b->value) &&
	      ((inv_io.dout_mask >> (unsigned)(fabs(b->value) - 1)) & 1u))) {
		return inv_gcode_fail(c, "output not +-(n + 1) of a mapped output n", -1, b->value);
	}
	if (b->kind == MLIP_BLOCK_PROBE &&
	    !(b->value >= 0 && b->value <= 3 && b->value == floor(b->value) && b->exact_stop == 1 &&
	      !b->rapid)) {
		return inv_gcode_fail(c, "probe not a feed move with MLIP_PROBE_* bits", -1,
		                      b->value);
	}
	if (b->kind < MLIP_BLOCK_SPINDLE && b->value != 0) {
		return inv_gcode_fail(c, "a value on a block that carries none", -1, b->value);
	}
	if (b->kind != MLIP_BLOCK_MOVE && b->kind != MLIP_BLOCK_PROBE) {
		/* an event: at the last point, a finite dwell >= 0 (DWELL only) */
		if (d2 != 0.0) {
			return inv_gcode_fail(c, "event not at the last point", -1, sqrt(d2));
		}
		if (!(b->dwell_s >= 0 && isfinite(b->dwell_s)) ||
		    (b->kind != MLIP_BLOCK_DWELL && b->dwell_s != 0)) {
			return inv_gcode_fail(c, "dwell not finite and >= 0", -1, b->dwell_s);
		}
	} else if (b->dwell_s != 0) {
		return inv_gcode_fail(c, "dwell on a move", -1, b->dwell_s);
	}
	if (b->exact_stop > 1) {
		return inv_gcode_fail(c, "exact_stop not 0 or 1", -1, b->exact_stop);
	}
	if ((b->kind == MLIP_BLOCK_MOVE || b->kind == MLIP_BLOCK_PROBE) &&
	    !(d2 >= MLIP_GCODE_MERGE_MM * MLIP_GCODE_MERGE_MM * (1 - 1e-9))) {
		return inv_gcode_fail(c, "block shorter than MLIP_GCODE_MERGE_MM", -1, sqrt(d2));
	}
	if (!isfinite(b->feed_mm_s) || !(b->feed_mm_s > 0)) {
		return inv_gcode_fail(
		    c, b->rapid ? "rapid feed not finite and > 0" : "feed not finite and > 0", -1,
		    b->feed_mm_s);
	}
	if (!(b->tol_mm > 0 && b->tol_mm <= eps)) {
		return inv_gcode_fail(c, "tol_mm outside (0, eps]", -1, b->tol_mm);
	}
	if (b->line != c->line) {
		return inv_gcode_fail(c, "block line is not the line parsed", -1, b->line);
	}
	if (b->rapid > 1) {
		return inv_gcode_fail(c, "rapid not 0 or 1", -1, b->rapid);
	}
	if (b->seq != 0) {
		return inv_gcode_fail(c, "seq set by the parser", -1, (double)b->seq);
	}
	if (c->expect) {
		const struct mlip_block *e;
		if (c->accepted >= c->expect->n) {
			return inv_gcode_fail(c, "more blocks than the other run", -1, 0);
		}
		e = &c->expect->b[c->accepted];
		if (memcmp(e->target, b->target, sizeof b->target) != 0 ||
		    e->feed_mm_s != b->feed_mm_s || e->tol_mm != b->tol_mm || e->line != b->line ||
		    e->rapid != b->rapid || e->kind != b->kind || e->dwell_s != b->dwell_s ||
		    e->exact_stop != b->exact_stop) {
			return inv_gcode_fail(c, "block differs from the other run", -1, 0);
		}
	}
	return NULL;
}

/* The sink: check, then accept or (as configured) refuse. Keeps going after
 * a violation so that the caller sees it once parsing is done. */
static int inv_gcode_sink(void *ctx, const struct mlip_block *b)
{
	struct inv_gcode *c = ctx;
	int i;

	c->attempts++;
	inv_gcode_block(c, b);
	if (c->refuse_every && c->attempts % c->refuse_every == c->refuse_every - 1) {
		c->line_refused = 1;
		return 1;
	}
	for (i = 0; i < c->m->n_axes; i++) {
		c->prev[i] = b->target[i];
	}
	c->accepted++;
	c->moves += b->kind == MLIP_BLOCK_MOVE || b->kind == MLIP_BLOCK_PROBE;
	c->line_blocks++;
	return 0;
}

static void inv_gcode_line_start(struct inv_gcode *c, uint32_t line)
{
	c->line = line;
	c->line_blocks = 0;
	c->line_refused = 0;
}

/* After mlip_gcode_line(text of len bytes) returned st with *e. */
static const char *inv_gcode_line_end(struct inv_gcode *c, size_t len, mlip_status st,
                                      const struct mlip_gcode_error *e)
{
	const char *w;
	size_t maxcol;

	if (c->bad) {
		return c->bad;
	}
	if ((st == MLIP_E_FULL) != (c->line_refused != 0)) {
		return inv_gcode_fail(c,
		                      c->line_refused ? "sink refused but no MLIP_E_FULL"
		                                      : "MLIP_E_FULL but the sink took all",
		                      -1, st);
	}
	if (st == MLIP_OK) {
		return NULL;
	}
	if (st != MLIP_E_FULL && c->line_blocks) {
		return inv_gcode_fail(c, "a line with an error emitted blocks", -1,
		                      (double)c->line_blocks);
	}
	if (st != MLIP_E_SYNTAX && st != MLIP_E_RANGE && st != MLIP_E_UNSUPPORTED &&
	    st != MLIP_E_FULL) {
		return inv_gcode_fail(c, "unexpected status", -1, st);
	}
	if (e->line != c->line || e->line < 1) {
		return inv_gcode_fail(c, "error names another line", -1, e->line);
	}
	maxcol = (len > MLIP_GCODE_MAX_LINE ? MLIP_GCODE_MAX_LINE : len) + 1;
	if (e->col > maxcol) {
		return inv_gcode_fail(c, "error column beyond the line", -1, e->col);
	}
	w = inv_message(e->msg, sizeof e->msg, 1);
	if (w) {
		return inv_gcode_fail(c, w, -1, 0);
	}
	return NULL;
}

/* After mlip_gcode_finish(g, last) returned st with *e. */
static const char *inv_gcode_finish(struct inv_gcode *c, const struct mlip_gcode *g, uint32_t last,
                                    mlip_status st, const struct mlip_gcode_error *e)
{
	const char *w;
	uint32_t k;

	if (c->bad) {
		return c->bad;
	}
	c->line = last;
	/* a program opened by '%' and never closed (nor ended by M2/M30) is
	 * refused however many blocks it had: the file may be cut short */
	int unclosed = g->percent && !g->ended;
	/* a program without motion that sets offsets (G10, G92, G54..G59.3),
	 * and any MDI command, is a program (mlip_gcode_finish) */
	int runs = c->moves > 0 || g->mdi || mlip_gcode_offsets_changed(g);
	if ((st == MLIP_OK) != (runs && !unclosed)) {
		return inv_gcode_fail(c, "finish disagrees with the blocks taken", -1,
		                      (double)c->accepted);
	}
	if (st != MLIP_OK) {
		const char *want = !runs ? "empty program: no motion"
		                         : "the program opens with '%' but ends without "
		                           "the closing '%' or M2/M30: the file may be cut "
		                           "short (LinuxCNC refuses it)";
		if (e->line != (last ? last : 1) || e->col != 0 || strcmp(e->msg, want) != 0) {
			return inv_gcode_fail(c, "finish error not the expected one at the end", -1,
			                      e->line);
		}
		w = inv_message(e->msg, sizeof e->msg, 1);
		if (w) {
			return inv_gcode_fail(c, w, -1, 0);
		}
	}
	if (g->n_notices > MLIP_GCODE_MAX_NOTICES) {
		return inv_gcode_fail(c, "too many notices", -1, g->n_notices);
	}
	for (k = 0; k < g->n_notices; k++) {
		const struct mlip_gcode_notice *n = &g->notices[k];
		if (memchr(n->word, '\0', sizeof n->word) == NULL || n->word[0] == '\0' ||
		    n->first_line < 1 || n->first_line > (last ? last : 1) || n->count < 1 ||
		    mlip_gcode_notice_text(n) == NULL) {
			return inv_gcode_fail(c, "malformed notice", (int)k, n->first_line);
		}
	}
	return NULL;
}

/* mlip_gcode_scan_axes: letters of XYZABC, in that order, NUL-terminated. */
static const char *inv_scan_axes(int n, const char *letters)
{
	const char *order = "XYZABC", *p = order;
	int k;

	if (n < 0 || n > 6 || letters[n] != '\0') {
		return "scan_axes: bad count or no NUL";
	}
	for (k = 0; k < n; k++) {
		p = strchr(p, letters[k]);
		if (!p || !*p) {
			return "scan_axes: letter not in XYZABC order";
		}
		p++;
	}
	return NULL;
}

/* ---- config --------------------------------------------------------------------- */

/* Lines the parser counts in text[0..len): one per LF, plus a last one not
 * ended by LF. */
static uint32_t inv_count_lines(const char *text, size_t len)
{
	uint32_t n = 0;
	size_t i;

	for (i = 0; i < len; i++) {
		n += text[i] == '\n';
	}
	return n + (len > 0 && text[len - 1] != '\n');
}

static const char *inv_config_error(mlip_status st, const struct mlip_config_error *e,
                                    uint32_t n_lines)
{
	if (st != MLIP_E_SYNTAX && st != MLIP_E_RANGE && st != MLIP_E_UNSUPPORTED &&
	    st != MLIP_E_INVALID) {
		return "config: unexpected status";
	}
	if (e->line > n_lines) {
		return "config: error line beyond the text";
	}
	if (e->col > MLIP_CONFIG_MAX_LINE + 1 || (e->line == 0 && e->col != 0)) {
		return "config: error column beyond a line";
	}
	return inv_message(e->msg, sizeof e->msg, 0);
}

static int inv_pow2(uint32_t v)
{
	return v != 0 && (v & (v - 1)) == 0;
}

/* parsed: c came from mlip_config_parse, so the unused axis slots are cleared
 * too (a machine built otherwise may hold anything there). */
static const char *inv_config_ok(const struct mlip_config *c, int parsed)
{
	const struct mlip_machine *m = &c->machine;
	const struct mlip_can_config *can = &c->can;
	struct mlip_config_error e;
	int i, j;

	if (mlip_machine_check(m, &e) != MLIP_OK) {
		return "config: parsed, but mlip_machine_check fails";
	}
	if (m->n_axes < 2 || m->n_axes > MLIP_MAX_AXES) {
		return "config: axis count";
	}
	if (!isfinite(m->max_feed_mm_s) || !isfinite(m->max_rot_feed_deg_s) ||
	    !isfinite(m->tolerance_mm) || !isfinite(m->period_s) || !(m->max_feed_mm_s > 0) ||
	    !(m->max_rot_feed_deg_s > 0) || !(m->tolerance_mm > 0) ||
	    !(m->period_s >= MLIP_CONFIG_PERIOD_MIN_S && m->period_s <= MLIP_CONFIG_PERIOD_MAX_S)) {
		return "config: TRAJ number not finite or out of range";
	}
	for (i = 0; i < m->n_axes; i++) {
		const struct mlip_axis *a = &m->axis[i];
		if (!a->letter || !strchr("XYZABC", a->letter)) {
			return "config: axis letter";
		}
		for (j = 0; j < i; j++) {
			if (m->axis[j].letter == a->letter || m->axis[j].can_node == a->can_node) {
				return "config: duplicate letter or CAN node";
			}
		}
		if (!isfinite(a->max_accel) || !isfinite(a->max_vel) || !isfinite(a->min_limit) ||
		    !isfinite(a->max_limit) || !isfinite(a->home) ||
		    !isfinite(a->counts_per_unit) || !(a->max_accel > 0) || !(a->max_vel > 0) ||
		    !(a->counts_per_unit > 0) || !(a->min_limit < a->max_limit) ||
		    !(a->home >= a->min_limit) || !(a->home <= a->max_limit)) {
			return "config: axis number not finite or out of range";
		}
		if (a->kind != MLIP_AXIS_LINEAR && a->kind != MLIP_AXIS_ROTARY) {
			return "config: axis kind";
		}
		if (a->can_node < 1 || a->can_node > 127 ||
		    can->rpdo_base + (uint32_t)a->can_node > 0x7FF) {
			return "config: CAN node or RPDO id out of range";
		}
	}
	for (i = m->n_axes; parsed && i < MLIP_MAX_AXES; i++) {
		const struct mlip_axis *a = &m->axis[i];
		if (a->letter || a->max_vel != 0 || a->max_accel != 0 || a->can_node != 0) {
			return "config: unused axis slot not cleared";
		}
	}
	if (!inv_pow2(c->lookahead) || c->lookahead < 2 || c->lookahead > MLIP_LOOKAHEAD) {
		return "config: LOOKAHEAD";
	}
	if (memchr(can->profile, '\0', sizeof can->profile) == NULL ||
	    (strcmp(can->profile, "cia402") != 0 && strcmp(can->profile, "packed") != 0 &&
	     strcmp(can->profile, "fd") != 0)) {
		return "config: CAN profile";
	}
	if (can->bitrate < 10000 || can->bitrate > 1000000 || can->data_bitrate < 10000 ||
	    can->data_bitrate > 12000000 ||
	    (strcmp(can->profile, "fd") == 0 && can->data_bitrate < can->bitrate)) {
		return "config: bitrate";
	}
	if (can->sync_id > 0x7FF || can->rpdo_base > 0x7FF || can->packed_base > 0x7FF ||
	    can->fd_id > 0x7FF || can->status_id > 0x7FF || can->sync_id == can->status_id) {
		return "config: CAN id";
	}
	return NULL;
}

/* Field by field (padding bytes are not part of the value). */
static int inv_config_equal(const struct mlip_config *a, const struct mlip_config *b)
{
	const struct mlip_machine *p = &a->machine, *q = &b->machine;
	int i;

	if (p->n_axes != q->n_axes || p->max_feed_mm_s != q->max_feed_mm_s ||
	    p->max_rot_feed_deg_s != q->max_rot_feed_deg_s || p->tolerance_mm != q->tolerance_mm ||
	    p->period_s != q->period_s || a->lookahead != b->lookahead ||
	    memcmp(&a->can, &b->can, sizeof a->can) != 0) {
		return 0;
	}
	for (i = 0; i < MLIP_MAX_AXES; i++) {
		const struct mlip_axis *x = &p->axis[i], *y = &q->axis[i];
		if (x->letter != y->letter || x->kind != y->kind || x->max_accel != y->max_accel ||
		    x->max_vel != y->max_vel || x->min_limit != y->min_limit ||
		    x->max_limit != y->max_limit || x->home != y->home ||
		    x->can_node != y->can_node || x->counts_per_unit != y->counts_per_unit) {
			return 0;
		}
	}
	return 1;
}

/* ---- the machines the G-code target runs against ---------------------------- */

/* config/mill-3axis.ini and config/rotary-4axis.ini without their comments
 * (the fuzzers must not depend on the working directory). */
static const char inv_mill_ini[] =
    "[TRAJ]\nCOORDINATES = X Y Z\nMAX_LINEAR_VELOCITY = 200\nMAX_ANGULAR_VELOCITY = 360\n"
    "CONTOUR_TOLERANCE = 0.01\nPERIOD = 0.001\nLOOKAHEAD = 4096\n"
    "[AXIS_X]\nTYPE = LINEAR\nMAX_VELOCITY = 200\nMAX_ACCELERATION = 1000\n"
    "MIN_LIMIT = -1000\nMAX_LIMIT = 1000\nHOME = 0\nCAN_NODE = 1\n"
    "[AXIS_Y]\nTYPE = LINEAR\nMAX_VELOCITY = 200\nMAX_ACCELERATION = 1000\n"
    "MIN_LIMIT = -1000\nMAX_LIMIT = 1000\nHOME = 0\nCAN_NODE = 2\n"
    "[AXIS_Z]\nTYPE = LINEAR\nMAX_VELOCITY = 200\nMAX_ACCELERATION = 1000\n"
    "MIN_LIMIT = -500\nMAX_LIMIT = 500\nHOME = 0\nCAN_NODE = 3\n";

static const char inv_rotary_ini[] =
    "[TRAJ]\nCOORDINATES = X Y Z A\nMAX_LINEAR_VELOCITY = 200\nMAX_ANGULAR_VELOCITY = 720\n"
    "CONTOUR_TOLERANCE = 0.01\nPERIOD = 0.001\n"
    "[AXIS_X]\nMAX_VELOCITY = 200\nMAX_ACCELERATION = 1000\n"
    "MIN_LIMIT = -1000\nMAX_LIMIT = 1000\nCAN_NODE = 1\n"
    "[AXIS_Y]\nMAX_VELOCITY = 200\nMAX_ACCELERATION = 1000\n"
    "MIN_LIMIT = -1000\nMAX_LIMIT = 1000\nCAN_NODE = 2\n"
    "[AXIS_Z]\nMAX_VELOCITY = 200\nMAX_ACCELERATION = 1000\n"
    "MIN_LIMIT = -500\nMAX_LIMIT = 500\nCAN_NODE = 3\n"
    "[AXIS_A]\nTYPE = ANGULAR\nMAX_VELOCITY = 720\nMAX_ACCELERATION = 3600\n"
    "MIN_LIMIT = -1e7\nMAX_LIMIT = 1e7\nCAN_NODE = 4\nCOUNTS_PER_UNIT = 100\n";

/* Parse one of the two above into *m; 0 or -1. */
static int inv_machine(const char *ini, struct mlip_machine *m)
{
	struct mlip_config c;

	mlip_config_defaults(&c);
	if (mlip_config_parse(&c, ini, strlen(ini), NULL) != MLIP_OK) {
		return -1;
	}
	*m = c.machine;
	return 0;
}

/* ---- whole inputs, as the fuzz targets and the regression test run them ---- */

#define INV_INITIAL_FEED 2     /* use the program's first F before it, as the tools do */
#define INV_REFUSE       4     /* the sink refuses every n-th block, n = 2 + (flags >> 3 & 31) */
#define INV_IO           0x100 /* the machine's I/O set (inv_io: all manual, a table) */

/* What a program gave: blocks taken, errors (finish's included), the first. */
struct inv_gcode_result {
	size_t blocks, errors;
	struct mlip_gcode_error first;
	char why[INV_WHY]; /* the violation, with numbers */
};

/* The program text[0..len) on machine m, cut into lines at LF, CRLF or a
 * lone CR as mlip_program_open does, every line in a buffer of its own exact size (so
 * that ASan sees a read past the length given); every check of this file.
 * With INV_INITIAL_FEED and without INV_REFUSE the blocks and errors must be
 * those of mlip_program_list_parse. NULL, or the violation. */
static const char *inv_gcode_program(const struct mlip_machine *m, const char *text, size_t len,
                                     int flags, struct inv_gcode_result *r)
{
	static struct mlip_program_list prog;
	struct inv_block_list list;
	struct mlip_gcode g;
	struct mlip_gcode_error err;
	struct inv_gcode c;
	const char *w = NULL;
	size_t i = 0;
	uint32_t line = 0;
	double f_word = 0;
	char letters[8];
	int n, rc = 0,
	       compare = (flags & INV_INITIAL_FEED) && !(flags & INV_REFUSE) && !(flags & INV_IO);
	mlip_status st;
	int finish_failed = 0;

	memset(r, 0, sizeof *r);
	memset(letters, 0x55, sizeof letters);
	n = mlip_gcode_scan_axes(text, len, letters);
	w = inv_scan_axes(n, letters);
	if (w) {
		return w;
	}
	if (compare) {
		rc = mlip_program_list_parse(text, len, m, &prog);
		if (rc < 0) {
			return "mlip_program_list_parse ran out of memory";
		}
		list.b = prog.blocks;
		list.n = prog.n;
	}
	inv_gcode_init(&c, m);
	c.expect = compare ? &list : NULL;
	c.refuse_every = (flags & INV_REFUSE) ? 2u + (((unsigned)flags >> 3) & 31u) : 0u;
	mlip_gcode_init(&g, m);
	if (flags & INV_IO) {
		mlip_gcode_set_io(&g, &inv_io);
	}
	if (flags & INV_INITIAL_FEED) {
		if (!mlip_gcode_scan_feed(text, len, &f_word)) {
			f_word = 0;
		}
		mlip_gcode_set_initial_feed(&g, f_word);
	}
	while (i < len && !w) {
		size_t end = i, n_line;

		while (end < len && text[end] != '\n' && text[end] != '\r') {
			end++;
		}
		n_line = end - i;
		char *copy = malloc(n_line ? n_line : 1);

		if (!copy) {
			w = "out of memory";
			break;
		}
		memcpy(copy, text + i, n_line);
		line++;
		inv_gcode_line_start(&c, line);
		memset(&err, 0x55, sizeof err); /* a message must always be written */
		st = mlip_gcode_line(&g, copy, n_line, line, inv_gcode_sink, &c, &err);
		free(copy);
		w = inv_gcode_line_end(&c, n_line, st, &err);
		if (!w && st != MLIP_OK) {
			if (compare && r->errors < prog.n_errors &&
			    (prog.errors[r->errors].line != err.line ||
			     prog.errors[r->errors].col != err.col ||
			     strcmp(prog.errors[r->errors].msg, err.msg) != 0)) {
				w = "error differs from mlip_program_list_parse's";
			}
			if (r->errors++ == 0) {
				r->first = err;
			}
		}
		i = end + 1 + (end + 1 < len && text[end] == '\r' && text[end + 1] == '\n');
	}
	if (!w) {
		memset(&err, 0x55, sizeof err);
		st = mlip_gcode_finish(&g, line, &err);
		w = inv_gcode_finish(&c, &g, line, st, &err);
		finish_failed = st != MLIP_OK;
		if (!w && st != MLIP_OK && r->errors++ == 0) {
			r->first = err;
		}
	}
	r->blocks = c.accepted;
	if (!w && compare) {
		/* the tools leave out finish's error ("empty program", an
		 * unclosed '%') after other errors */
		size_t total = r->errors - (r->errors > 1 && finish_failed);
		if (prog.n != c.accepted || prog.n_errors_total != total || prog.lines != line ||
		    rc != (total ? 1 : 0) || prog.n_notices != g.n_notices) {
			w = "mlip_program_list_parse disagrees with the line-by-line run";
		}
	}
	if (compare) {
		mlip_program_list_free(&prog);
	}
	snprintf(r->why, sizeof r->why, "%s", c.bad ? c.why : w ? w : "");
	return w;
}

/* What a config text gave: the status and error of the parse into defaults. */
struct inv_config_result {
	mlip_status st;
	struct mlip_config_error err;
	struct mlip_config c;
};

/* text[0..len) parsed three times: into defaults (then every check of this
 * file, and on error *c unchanged byte for byte), the same with err == NULL
 * (same status and result), and into *base, a parsed machine whose optional
 * [TRAJ] and [CAN] values are the defaults (axes come from the text alone,
 * so status, error and result must be the same). NULL, or the violation. */
static const char *inv_config_text(const struct mlip_config *base, const char *text, size_t len,
                                   struct inv_config_result *r)
{
	struct mlip_config before, c2, c3;
	struct mlip_config_error err3;
	const char *w;
	mlip_status st2, st3;

	mlip_config_defaults(&r->c);
	before = r->c;
	memset(&r->err, 0x55, sizeof r->err); /* a message must always be written */
	r->st = mlip_config_parse(&r->c, text, len, &r->err);
	if (r->st == MLIP_OK) {
		w = inv_config_ok(&r->c, 1);
		if (w) {
			return w;
		}
	} else {
		if (memcmp(&r->c, &before, sizeof r->c) != 0) {
			return "config: *c changed by a failed parse";
		}
		w = inv_config_error(r->st, &r->err, inv_count_lines(text, len));
		if (w) {
			return w;
		}
	}
	mlip_config_defaults(&c2);
	st2 = mlip_config_parse(&c2, text, len, NULL);
	if (st2 != r->st || (st2 == MLIP_OK && !inv_config_equal(&r->c, &c2))) {
		return "config: the parse with err == NULL differs";
	}
	c3 = *base;
	before = c3;
	memset(&err3, 0x55, sizeof err3);
	st3 = mlip_config_parse(&c3, text, len, &err3);
	if (st3 != r->st) {
		return "config: the status depends on the struct parsed into";
	}
	if (st3 == MLIP_OK && !inv_config_equal(&r->c, &c3)) {
		return "config: the result depends on the struct parsed into";
	}
	if (st3 != MLIP_OK &&
	    (err3.line != r->err.line || err3.col != r->err.col ||
	     strcmp(err3.msg, r->err.msg) != 0 || memcmp(&c3, &before, sizeof c3) != 0)) {
		return "config: the error depends on the struct parsed into";
	}
	return NULL;
}

/* mlip_machine_check on any machine: a well-formed error at 0:0, or a
 * machine that is sane. NULL, or the violation. */
static const char *inv_machine_raw(const struct mlip_machine *m)
{
	struct mlip_config c;
	struct mlip_config_error err;
	mlip_status st;

	mlip_config_defaults(&c);
	c.machine = *m;
	memset(&err, 0x55, sizeof err);
	st = mlip_machine_check(&c.machine, &err);
	if (st == MLIP_OK) {
		return inv_config_ok(&c, 0);
	}
	if (st != MLIP_E_RANGE && st != MLIP_E_INVALID) {
		return "machine check: unexpected status";
	}
	if (err.line != 0 || err.col != 0) {
		return "machine check: an error with a line or column";
	}
	return inv_message(err.msg, sizeof err.msg, 0);
}

#endif
