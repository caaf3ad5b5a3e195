/*
 * gcode.c - G-code front end: one line of RS274NGC text in, joint-space
 * G01-style blocks out (see mlip/gcode/gcode.h for what is supported).
 *
 * A line goes through four steps, so that a line with an error changes
 * nothing but what it validly said:
 *   1. lex:      bytes -> words (letter, number, column); comments skipped,
 *                malformed numbers, stray bytes and bad UTF-8 rejected;
 *   2. classify: words -> one block description (G/M codes by modal group,
 *                axis and arc words, F, notices), every word checked alone;
 *   3. check:    words against the machine and the modal state;
 *   4. execute:  modal state committed, then the motion (if any) turned into
 *                targets, checked against the soft limits, and emitted.
 *
 * Arcs (G2/G3) become chords of equal angle. For a chord of angle d on a
 * circle of radius r the sagitta is  s = r (1 - cos(d/2)) = 2 r sin^2(d/4),
 * so the largest step with s <= S is  d = 4 asin(sqrt(S / (2 r))),  with
 * S = MLIP_GCODE_ARC_FRACTION * eps. The corner between two chords of one
 * arc then gets eps - s, so chord error plus corner error stays within eps.
 * Plane conventions follow RS274NGC/LinuxCNC: G17 (u,v) = (X,Y) with I,J;
 * G18 (u,v) = (Z,X) with K,I; G19 (u,v) = (Y,Z) with J,K; G3 turns from u
 * toward v (counter-clockwise seen from the positive normal axis).
 *
 * Pure: libm, <string.h> and <stdarg.h> only; messages formatted by hand.
 */
#include <math.h>
#include <stdarg.h>
#include <string.h>

#include "mlip/gcode/gcode.h"

#define MAX_WORDS   (MLIP_GCODE_MAX_LINE / 2 + 1) /* a word takes two bytes at least */
#define MAX_CHORDS  1000000u
#define PI          3.14159265358979323846
#define MM_PER_INCH 25.4

static const char axis_letters[] = "XYZABC";

/* ---- messages: a tiny formatter, since the core has no stdio ---- */

struct msg {
	char *s;
	size_t n;
};

static void put_c(struct msg *m, char c)
{
	if (m->n + 1 < MLIP_GCODE_MSG) {
		m->s[m->n++] = c;
		m->s[m->n] = '\0';
	}
}

static void put_u(struct msg *m, uint64_t v)
{
	char d[24];
	int k = 0;

	do {
		d[k++] = (char)('0' + v % 10);
		v /= 10;
	} while (v);
	while (k) {
		put_c(m, d[--k]);
	}
}

/* v with three decimals, like "%.3f" (for |v| < 1e15) */
static void put_f(struct msg *m, double v)
{
	double r = floor(fabs(v) * 1000.0 + 0.5);
	const char *p;
	uint64_t q;

	if (v < 0 && r > 0) {
		put_c(m, '-');
	}
	if (!(r < 1e18)) {
		for (p = isnan(v) ? "nan" : isinf(v) ? "inf" : "huge"; *p; p++) {
			put_c(m, *p);
		}
		return;
	}
	q = (uint64_t)r;
	put_u(m, q / 1000);
	put_c(m, '.');
	put_c(m, (char)('0' + q / 100 % 10));
	put_c(m, (char)('0' + q / 10 % 10));
	put_c(m, (char)('0' + q % 10));
}

/* Fill *e and return st. fmt knows %s (string), %c (char), %u (unsigned),
 * %f (double, three decimals), %G and %M (a G or M code from its value*10:
 * 641 -> "G64.1"), %b (a byte: 'c' when printable, else 0xNN) and %t (a
 * span: pointer and size_t length, at most 24 bytes shown). */
static mlip_status failf(struct mlip_gcode_error *e, uint32_t line, uint32_t col, mlip_status st,
                         const char *fmt, ...)
{
	static const char hex[] = "0123456789ABCDEF";
	struct msg m;
	va_list ap;
	const char *p;
	size_t n, k;
	int v;

	e->line = line;
	e->col = col;
	e->msg[0] = '\0';
	m.s = e->msg;
	m.n = 0;
	va_start(ap, fmt);
	for (; *fmt; fmt++) {
		if (*fmt != '%' || !fmt[1]) {
			put_c(&m, *fmt);
			continue;
		}
		switch (*++fmt) {
		case 's':
			for (p = va_arg(ap, const char *); *p; p++) {
				put_c(&m, *p);
			}
			break;
		case 'c':
			put_c(&m, (char)va_arg(ap, int));
			break;
		case 'u':
			put_u(&m, va_arg(ap, unsigned));
			break;
		case 'f':
			put_f(&m, va_arg(ap, double));
			break;
		case 'G':
		case 'M':
			v = va_arg(ap, int);
			put_c(&m, *fmt);
			put_u(&m, (uint64_t)(v / 10));
			if (v % 10) {
				put_c(&m, '.');
				put_c(&m, (char)('0' + v % 10));
			}
			break;
		case 'b':
			v = va_arg(ap, int) & 0xFF;
			if (v >= 0x20 && v < 0x7f) {
				put_c(&m, '\'');
				put_c(&m, (char)v);
				put_c(&m, '\'');
			} else {
				put_c(&m, '0');
				put_c(&m, 'x');
				put_c(&m, hex[v >> 4]);
				put_c(&m, hex[v & 15]);
			}
			break;
		case 't':
			p = va_arg(ap, const char *);
			n = va_arg(ap, size_t);
			for (k = 0; k < n && k < 24; k++) {
				/* a quoted excerpt stays one printable line */
				put_c(&m, p[k] >= 0x20 && p[k] < 0x7f ? p[k] : '?');
			}
			break;
		default:
			put_c(&m, *fmt);
			break;
		}
	}
	va_end(ap);
	return st;
}

/* ---- characters ---- */

static int is_digit(int c)
{
	return c >= '0' && c <= '9';
}

static int is_alpha(int c)
{
	return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z');
}

static int is_blank(int c)
{
	return c == ' ' || c == '\t';
}

static int starts_number(int c)
{
	return is_digit(c) || c == '.' || c == '+' || c == '-';
}

static char upper(char c)
{
	return (c >= 'a' && c <= 'z') ? (char)(c - 'a' + 'A') : c;
}

/* Index of an axis letter in axis_letters, or -1. */
static int axis_slot(char c)
{
	int k;

	for (k = 0; k < 6; k++) {
		if (axis_letters[k] == c) {
			return k;
		}
	}
	return -1;
}

/* Length of the well-formed UTF-8 sequence at p (RFC 3629: no overlongs,
 * no surrogates, nothing above U+10FFFF), or 0. */
static size_t utf8_len(const unsigned char *p, size_t n)
{
	unsigned lo = 0x80, hi = 0xBF;
	size_t len, k;

	if (p[0] < 0x80) {
		return 1;
	}
	if (p[0] >= 0xC2 && p[0] <= 0xDF) {
		len = 2;
	} else if (p[0] >= 0xE0 && p[0] <= 0xEF) {
		len = 3;
		lo = p[0] == 0xE0 ? 0xA0 : 0x80;
		hi = p[0] == 0xED ? 0x9F : 0xBF;
	} else if (p[0] >= 0xF0 && p[0] <= 0xF4) {
		len = 4;
		lo = p[0] == 0xF0 ? 0x90 : 0x80;
		hi = p[0] == 0xF4 ? 0x8F : 0xBF;
	} else {
		return 0;
	}
	if (n < len || p[1] < lo || p[1] > hi) {
		return 0;
	}
	for (k = 2; k < len; k++) {
		if (p[k] < 0x80 || p[k] > 0xBF) {
			return 0;
		}
	}
	return len;
}

/* Comment bytes t[i..end) must be well-formed UTF-8 without NUL: returns the
 * offset of the first bad byte, or end. */
static size_t comment_check(const unsigned char *t, size_t i, size_t end)
{
	while (i < end) {
		size_t l = t[i] ? utf8_len(t + i, end - i) : 0;

		if (!l) {
			return i;
		}
		i += l;
	}
	return end;
}

/* ---- lexing ---- */

struct word {
	char letter;  /* upper case */
	uint32_t col; /* 1-based column of the letter */
	double value;
};

struct lexed {
	struct word w[MAX_WORDS];
	int n;
	uint32_t first_col; /* first non-blank column, 0 for a blank line */
};

/* Scan [+-]digits[.digits] at t[i..n): returns its end, the number of digits
 * in *ndig and the value in *val. Up to 15 significant digits the value is an
 * exact integer over an exact power of ten, hence correctly rounded (Clinger's
 * fast path) and independent of the locale, unlike strtod. */
static size_t scan_number(const char *t, size_t n, size_t i, double *val, int *ndig)
{
	static const double p10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
	                             1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
	                             1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
	uint64_t mant = 0;
	int neg = 0, sig = 0, frac = 0, exp10 = 0, dot = 0;

	*ndig = 0;
	if (i < n && (t[i] == '+' || t[i] == '-')) {
		neg = t[i] == '-';
		i++;
	}
	for (; i < n; i++) {
		if (t[i] == '.' && !dot) {
			dot = 1;
			continue;
		}
		if (!is_digit(t[i])) {
			break;
		}
		(*ndig)++;
		if (sig < 19) {
			mant = mant * 10 + (uint64_t)(t[i] - '0');
			sig += mant != 0;
			frac += dot;
		} else if (!dot) {
			exp10++;
		}
	}
	if (sig <= 15 && frac <= 22 && exp10 == 0) {
		*val = (double)mant / p10[frac];
	} else {
		*val = (double)mant * pow(10.0, exp10 - frac); /* approximate: no CAM writes this */
	}
	if (neg) {
		*val = -*val;
	}
	return i;
}

/* "nan", "inf", "infinity" (any case) as the letters at t[i..): strtod would
 * take them, so name them as malformed numbers. */
static int is_nan_inf(const char *t, size_t n, size_t i, size_t *end)
{
	static const char *const names[] = {"INFINITY", "INF", "NAN"};
	size_t k, e = i;
	int j;

	while (e < n && is_alpha(t[e])) {
		e++;
	}
	for (j = 0; j < 3; j++) {
		for (k = 0; names[j][k] && i + k < e && upper(t[i + k]) == names[j][k]; k++) {
		}
		if (!names[j][k] && i + k == e) {
			*end = e;
			return 1;
		}
	}
	return 0;
}

/* One word at t[*pi] (a letter); blanks may separate letter and number. */
static mlip_status lex_word(const char *t, size_t n, size_t *pi, uint32_t line, struct word *w,
                            struct mlip_gcode_error *e)
{
	size_t i = *pi, j, k;
	int ndig;

	w->letter = upper(t[i]);
	w->col = (uint32_t)i + 1;
	for (j = i + 1; j < n && is_blank(t[j]); j++) {
	}
	if (j < n && starts_number(t[j])) {
		k = scan_number(t, n, j, &w->value, &ndig);
		/* "1.2.3", "1e5", "--1", ".": the number runs on in number-like bytes */
		if (ndig == 0 || (k < n && (t[k] == '.' || t[k] == '+' || t[k] == '-')) ||
		    (k + 1 < n && (t[k] == 'e' || t[k] == 'E') &&
		     (is_digit(t[k + 1]) || t[k + 1] == '+' || t[k + 1] == '-'))) {
			while (k < n && (starts_number(t[k]) || t[k] == 'e' || t[k] == 'E')) {
				k++;
			}
			return failf(e, line, (uint32_t)j + 1, MLIP_E_SYNTAX,
			             "malformed number '%t'", t + j, k - j);
		}
		*pi = k;
		return MLIP_OK;
	}
	if (j < n && is_nan_inf(t, n, j, &k)) {
		return failf(e, line, (uint32_t)j + 1, MLIP_E_SYNTAX, "malformed number '%t'",
		             t + j, k - j);
	}
	if (j < n && (t[j] == '#' || t[j] == '[')) {
		return failf(e, line, (uint32_t)j + 1, MLIP_E_UNSUPPORTED,
		             "parameters and expressions (# [ ]) not supported: have the CAM "
		             "write plain numbers");
	}
	return failf(e, line, w->col, MLIP_E_SYNTAX, "word %c has no number", w->letter);
}

static mlip_status lex_line(const char *text, size_t len, uint32_t line, struct lexed *lx,
                            struct mlip_gcode_error *e)
{
	const unsigned char *t = (const unsigned char *)text;
	size_t i = 0, end, k;
	int percent = 0;
	mlip_status st;

	lx->n = 0;
	lx->first_col = 0;
	if (line == 1 && len >= 3 && t[0] == 0xEF && t[1] == 0xBB && t[2] == 0xBF) {
		i = 3; /* UTF-8 byte order mark */
	}
	while (i < len) {
		unsigned char c = t[i];
		uint32_t col = (uint32_t)i + 1;

		if (is_blank(c)) {
			i++;
			continue;
		}
		if (c == '(' || c == ';') {
			for (end = i + 1; c == '(' && end < len && t[end] != ')'; end++) {
			}
			end = c == ';' ? len : end;
			k = comment_check(t, i + 1, end);
			if (k < end) {
				return failf(e, line, (uint32_t)k + 1, MLIP_E_SYNTAX,
				             t[k] ? "invalid UTF-8 in comment"
				                  : "NUL byte in line");
			}
			if (c == '(' && end == len) {
				return failf(e, line, col, MLIP_E_SYNTAX,
				             "unterminated comment: '(' without ')'");
			}
			i = end + 1;
			continue;
		}
		if (percent) {
			return failf(e, line, col, MLIP_E_SYNTAX, "'%%' must be alone on its line");
		}
		if (!lx->first_col) {
			lx->first_col = col;
			if (c == '%') { /* program delimiter */
				percent = 1;
				i++;
				continue;
			}
			if (c == '/') {
				return failf(e, line, col, MLIP_E_UNSUPPORTED,
				             "block delete '/' not supported");
			}
		}
		if (c == 0) {
			return failf(e, line, col, MLIP_E_SYNTAX, "NUL byte in line");
		}
		if (c >= 0x80) {
			return failf(e, line, col, MLIP_E_SYNTAX,
			             "non-ASCII byte %b outside a comment", c);
		}
		if (is_alpha(c)) {
			st = lex_word(text, len, &i, line, &lx->w[lx->n], e);
			if (st != MLIP_OK) {
				return st;
			}
			lx->n++;
			continue;
		}
		if (starts_number(c)) {
			for (k = i; k < len && starts_number(t[k]); k++) {
			}
			return failf(e, line, col, MLIP_E_SYNTAX,
			             "number '%t' without a word letter", text + i, k - i);
		}
		if (c == '#') {
			return failf(
			    e, line, col, MLIP_E_UNSUPPORTED,
			    "parameters and expressions (# [ ]) not supported: have the CAM "
			    "write plain numbers");
		}
		return failf(e, line, col, MLIP_E_SYNTAX, "unexpected character %b", c);
	}
	return MLIP_OK;
}

/* ---- classification ---- */

enum gkind {
	GK_MOTION,   /* G0..G3 */
	GK_PLANE,    /* G17..G19 */
	GK_UNITS,    /* G20/G21 */
	GK_DIST,     /* G90/G91 */
	GK_HOME,     /* G28/G30 */
	GK_G53,      /* machine coordinates for this line */
	GK_DWELL,    /* G4 */
	GK_G10,      /* G10 L2 / L20 */
	GK_HOMESET,  /* G28.1/G30.1 */
	GK_COORD,    /* G54..G59.3 */
	GK_PATH,     /* G61, G61.1, G64 */
	GK_G92,      /* G92, G92.1, G92.2, G92.3 */
	GK_FEEDMODE, /* G93/G94 */
	GK_NOTICE,   /* accepted, no effect on motion */
	GK_SILENT,   /* accepted, it is what mlip does anyway (G91.1) */
	GK_UNSUP
};

/* modal groups, to refuse two codes of one group on a line */
enum {
	GR_NONE,
	GR_MOTION,
	GR_PLANE,
	GR_UNITS,
	GR_DIST,
	GR_NONMODAL,
	GR_FEEDMODE,
	GR_CUTTER,
	GR_TOOLLEN,
	GR_COORD,
	GR_PATH,
	GR_ARCDIST,
	GR_N
};

/* G codes by value*10, as ranges [lo, hi] */
struct gdef {
	short lo, hi;
	unsigned char kind, group;
	const char *why; /* GK_UNSUP: what it is, for the message */
};

static const struct gdef gtab[] = {
    {0, 30, GK_MOTION, GR_MOTION, 0},
    {170, 190, GK_PLANE, GR_PLANE, 0},
    {200, 210, GK_UNITS, GR_UNITS, 0},
    {280, 280, GK_HOME, GR_NONMODAL, 0},
    {300, 300, GK_HOME, GR_NONMODAL, 0},
    {400, 400, GK_NOTICE, GR_CUTTER, 0},
    {490, 490, GK_NOTICE, GR_TOOLLEN, 0},
    {530, 530, GK_G53, GR_NONMODAL, 0},
    {40, 40, GK_DWELL, GR_NONMODAL, 0},
    {100, 100, GK_G10, GR_NONMODAL, 0},
    {281, 281, GK_HOMESET, GR_NONMODAL, 0},
    {301, 301, GK_HOMESET, GR_NONMODAL, 0},
    {540, 540, GK_COORD, GR_COORD, 0},
    {550, 550, GK_COORD, GR_COORD, 0},
    {560, 560, GK_COORD, GR_COORD, 0},
    {570, 570, GK_COORD, GR_COORD, 0},
    {580, 580, GK_COORD, GR_COORD, 0},
    {590, 593, GK_COORD, GR_COORD, 0},
    {610, 611, GK_PATH, GR_PATH, 0},
    {640, 640, GK_PATH, GR_PATH, 0},
    {920, 923, GK_G92, GR_NONMODAL, 0},
    {930, 940, GK_FEEDMODE, GR_FEEDMODE, 0},
    {800, 800, GK_NOTICE, GR_MOTION, 0},
    {900, 900, GK_DIST, GR_DIST, 0},
    {910, 910, GK_DIST, GR_DIST, 0},
    {911, 911, GK_SILENT, GR_ARCDIST, 0},
    {50, 53, GK_UNSUP, 0, "splines"},
    {70, 80, GK_UNSUP, 0, "lathe diameter/radius mode"},
    {330, 331, GK_UNSUP, 0, "spindle-synchronized motion"},
    {760, 760, GK_UNSUP, 0, "threading cycle"},
    {382, 385, GK_UNSUP, 0, "probing"},
    {410, 421, GK_UNSUP, 0, "cutter radius compensation"},
    {430, 432, GK_UNSUP, 0, "tool length offset"},
    {520, 520, GK_UNSUP, 0, "local offsets (use G92 or G10 L2)"},
    {730, 730, GK_UNSUP, 0, "canned cycles"},
    {810, 890, GK_UNSUP, 0, "canned cycles"},
    {980, 990, GK_UNSUP, 0, "canned cycles"},
    {901, 901, GK_UNSUP, 0, "absolute arc centers"},
    {950, 950, GK_UNSUP, 0, "feed per revolution"},
    {960, 970, GK_UNSUP, 0, "constant surface speed"},
};

static const struct gdef *gfind(int code10)
{
	size_t k;

	for (k = 0; k < sizeof gtab / sizeof gtab[0]; k++) {
		/* motion and plane ranges hold whole codes only */
		if (code10 >= gtab[k].lo && code10 <= gtab[k].hi &&
		    !((gtab[k].kind <= GK_UNITS || gtab[k].kind == GK_FEEDMODE) && code10 % 10)) {
			return &gtab[k];
		}
	}
	return 0;
}

/* M codes that cannot be ignored, and why (LinuxCNC's meanings); every
 * other whole M code up to M199 is a notice: no effect on motion (spindle,
 * coolant, tool change, overrides, user M codes, printer fans, ...). */
static const char *m_refused(int code10)
{
	int m = code10 / 10;

	if (code10 % 10 || m > 199) {
		return "";
	}
	if (m == 98 || m == 99) {
		return ": subprogram calls (have the CAM expand them)";
	}
	if (m >= 62 && m <= 68) {
		return ": digital/analog I/O synchronized with motion or a wait for an input";
	}
	if (m >= 70 && m <= 73) {
		return ": saving and restoring the modal state";
	}
	return 0;
}

/* value*10 as an int when value is a non-negative multiple of 0.1, else -1 */
static int code_of(double v)
{
	double t = floor(v * 10.0 + 0.5);

	if (v < 0 || t > 10000 || fabs(v * 10.0 - t) > 1e-6) {
		return -1;
	}
	return (int)t;
}

/* Everything one line says, each word checked alone. */
struct blk {
	int motion;                 /* G0..G3 on this line, -1 none */
	int plane, units, dist;     /* 0 when not on this line, else 17..19, 20/21, 90/91 */
	int home;                   /* 28 or 30, 0 none */
	int g53, g64, g4, g10, g92; /* g92: 920..923 (value*10), 0 none */
	int homeset;                /* 28 or 30 for G28.1/G30.1, 0 none */
	int coord;                  /* 0..8 for G54..G59.3, -1 none */
	int path;                   /* 610, 611, 640, 0 none */
	int feedmode;               /* 93, 94, 0 none */
	int pause;                  /* M0/M60: 1, M1: 2, 0 none */
	int end;                    /* M2/M30 */
	uint32_t motion_col, home_col, g53_col, g4_col, g10_col, g92_col, homeset_col, end_col;
	int has_ax[6];
	double ax[6]; /* as written, indexed like axis_letters */
	uint32_t ax_col[6];
	int has_ijk[3];
	double ijk[3];
	uint32_t ijk_col[3];
	int has_r, has_f, has_p, has_q, has_l;
	double r, f, p, q, l;
	uint32_t r_col, p_col, q_col, l_col, f_col;
	char notes[MAX_WORDS][8]; /* notices to record once the line is accepted */
	int n_notes;
};

static void note_word(struct blk *b, char letter, int code10)
{
	char *w = b->notes[b->n_notes++];
	int k = 0;

	w[k++] = letter;
	if (code10 >= 0) { /* at most "G61.1" or "M199" (code10 < 10000): fits */
		if (code10 >= 1000) {
			w[k++] = (char)('0' + code10 / 1000 % 10);
		}
		if (code10 >= 100) {
			w[k++] = (char)('0' + code10 / 100 % 10);
		}
		w[k++] = (char)('0' + code10 / 10 % 10);
		if (code10 % 10) {
			w[k++] = '.';
			w[k++] = (char)('0' + code10 % 10);
		}
	}
	w[k] = '\0';
}

/* One G word: a supported code, and the only one of its modal group. */
static mlip_status classify_g(const struct word *w, uint32_t line, struct blk *b, int *group_code,
                              struct mlip_gcode_error *e)
{
	int c = code_of(w->value);
	const struct gdef *d = c >= 0 ? gfind(c) : 0;

	if (c < 0) {
		return failf(e, line, w->col, MLIP_E_UNSUPPORTED, "unsupported G code G%f",
		             w->value);
	}
	if (!d || d->kind == GK_UNSUP) {
		return failf(e, line, w->col, MLIP_E_UNSUPPORTED, "unsupported G code %G%s%s", c,
		             d ? ": " : "", d ? d->why : "");
	}
	if (d->group != GR_NONE && group_code[d->group] >= 0 && group_code[d->group] != c) {
		return failf(e, line, w->col, MLIP_E_SYNTAX,
		             d->group == GR_MOTION ? "two motion codes on one line: %G and %G"
		                                   : "%G and %G on one line: same modal group",
		             group_code[d->group], c);
	}
	group_code[d->group] = c;
	switch (d->kind) {
	case GK_MOTION:
		b->motion = c / 10;
		b->motion_col = w->col;
		break;
	case GK_PLANE:
		b->plane = c / 10;
		break;
	case GK_UNITS:
		b->units = c / 10;
		break;
	case GK_DIST:
		b->dist = c / 10;
		break;
	case GK_HOME:
		b->home = c / 10;
		b->home_col = w->col;
		break;
	case GK_G53:
		b->g53 = 1;
		b->g53_col = w->col;
		break;
	case GK_DWELL:
		b->g4 = 1;
		b->g4_col = w->col;
		break;
	case GK_G10:
		b->g10 = 1;
		b->g10_col = w->col;
		break;
	case GK_HOMESET:
		b->homeset = c / 10;
		b->homeset_col = w->col;
		break;
	case GK_COORD:
		b->coord = c < 590 ? c / 10 - 54 : 5 + c % 10;
		break;
	case GK_PATH:
		b->path = c;
		b->g64 = c == 640;
		break;
	case GK_G92:
		b->g92 = c;
		b->g92_col = w->col;
		break;
	case GK_FEEDMODE:
		b->feedmode = c / 10;
		break;
	case GK_NOTICE:
		note_word(b, 'G', c);
		break;
	default:
		break;
	}
	return MLIP_OK;
}

static mlip_status classify_params(const struct blk *b, uint32_t line, struct mlip_gcode_error *e);

static mlip_status classify(const struct lexed *lx, uint32_t line, struct blk *b,
                            struct mlip_gcode_error *e)
{
	int group_code[GR_N], k, a, c;
	uint32_t seen[26] = {0}; /* column of the first word of each letter */
	mlip_status st;

	memset(b, 0, sizeof *b);
	b->motion = -1;
	b->coord = -1;
	for (k = 0; k < GR_N; k++) {
		group_code[k] = -1;
	}
	for (k = 0; k < lx->n; k++) {
		const struct word *w = &lx->w[k];
		char L = w->letter;

		if (!seen[L - 'A']) {
			seen[L - 'A'] = w->col;
		} else if (L != 'G' && L != 'M' && L != 'N') {
			return failf(e, line, w->col, MLIP_E_SYNTAX,
			             "duplicate %c word (first at column %u)", L, seen[L - 'A']);
		}
		switch (L) {
		case 'G':
			st = classify_g(w, line, b, group_code, e);
			if (st != MLIP_OK) {
				return st;
			}
			break;
		case 'M':
			c = code_of(w->value);
			if (c < 0) {
				return failf(e, line, w->col, MLIP_E_UNSUPPORTED,
				             "unsupported M code M%f", w->value);
			}
			if (m_refused(c)) {
				return failf(e, line, w->col, MLIP_E_UNSUPPORTED,
				             "unsupported M code %M%s", c, m_refused(c));
			}
			if (c == 0 || c == 10 || c == 600) {
				b->pause = c == 10 ? 2 : 1;
				if (c == 600) {
					note_word(b, 'M', c);
				}
			} else if (c == 20 || c == 300) {
				b->end = 1;
				b->end_col = w->col;
				note_word(b, 'M', c);
			} else {
				note_word(b, 'M', c);
			}
			break;
		case 'X':
		case 'Y':
		case 'Z':
		case 'A':
		case 'B':
		case 'C':
			a = axis_slot(L);
			b->has_ax[a] = 1;
			b->ax[a] = w->value;
			b->ax_col[a] = w->col;
			break;
		case 'I':
		case 'J':
		case 'K':
			b->has_ijk[L - 'I'] = 1;
			b->ijk[L - 'I'] = w->value;
			b->ijk_col[L - 'I'] = w->col;
			break;
		case 'R':
			b->has_r = 1;
			b->r = w->value;
			b->r_col = w->col;
			break;
		case 'F':
			if (!(w->value > 0)) {
				return failf(e, line, w->col, MLIP_E_RANGE,
				             "feed F must be positive");
			}
			b->has_f = 1;
			b->f = w->value;
			b->f_col = w->col;
			break;
		case 'P':
			b->has_p = 1;
			b->p = w->value;
			b->p_col = w->col;
			break;
		case 'Q':
			b->has_q = 1;
			b->q = w->value;
			b->q_col = w->col;
			break;
		case 'L':
			b->has_l = 1;
			b->l = w->value;
			b->l_col = w->col;
			break;
		case 'S':
		case 'T':
			note_word(b, L, -1);
			break;
		case 'N':
			break; /* line numbers: ignored */
		case 'U':
		case 'V':
		case 'W':
			return failf(e, line, w->col, MLIP_E_UNSUPPORTED,
			             "axis %c not supported: mlip axes are X Y Z A B C", L);
		default:
			return failf(e, line, w->col, MLIP_E_SYNTAX, "unknown word letter %c", L);
		}
	}
	return classify_params(b, line, e);
}

/* P, Q, L and R words against the codes that take them (LinuxCNC's rules). */
static mlip_status classify_params(const struct blk *b, uint32_t line, struct mlip_gcode_error *e)
{
	int n = (b->g4 != 0) + (b->g10 != 0) + (b->g64 != 0);

	if (b->has_p && n != 1) {
		return failf(e, line, b->p_col, MLIP_E_SYNTAX,
		             n ? "P word with two of G4, G10, G64: put them on separate lines"
		               : "P word without G4, G10 or G64");
	}
	if (b->has_q && !b->g64) {
		return failf(e, line, b->q_col, MLIP_E_SYNTAX, "Q word without G64");
	}
	if (b->has_l && !b->g10) {
		return failf(e, line, b->l_col, MLIP_E_SYNTAX, "L word without G10");
	}
	if (b->g4 && !b->has_p) {
		return failf(e, line, b->g4_col, MLIP_E_SYNTAX,
		             "G4 without P: write the dwell in seconds, e.g. G4 P0.5");
	}
	if (b->g4 && !(b->p >= 0)) {
		return failf(e, line, b->p_col, MLIP_E_RANGE, "G4 P must be >= 0 seconds");
	}
	if (b->g10) {
		if (!b->has_l || (b->l != 2 && b->l != 20)) {
			return failf(
			    e, line, b->has_l ? b->l_col : b->g10_col, MLIP_E_UNSUPPORTED,
			    "G10 without L2 or L20: only work offsets can be set (mlip has no "
			    "tool table)");
		}
		if (!b->has_p || b->p != floor(b->p) || b->p < 0 || b->p > 9) {
			return failf(
			    e, line, b->has_p ? b->p_col : b->g10_col, MLIP_E_SYNTAX,
			    "G10 L%u needs P0..P9 (0: the system in use, 1..9: G54..G59.3)",
			    (unsigned)b->l);
		}
		if (b->has_r) {
			return failf(e, line, b->r_col, MLIP_E_UNSUPPORTED,
			             "G10 R (rotated coordinate system) not supported");
		}
	}
	if (b->g53 && b->dist == 91) {
		return failf(e, line, b->g53_col, MLIP_E_SYNTAX,
		             "G53 with G91: machine coordinates must be absolute");
	}
	return MLIP_OK;
}

/* ---- state, notices ---- */

void mlip_gcode_offsets_init(struct mlip_gcode_offsets *o, const struct mlip_machine *m)
{
	int i;

	memset(o, 0, sizeof *o);
	for (i = 0; i < m->n_axes && i < MLIP_MAX_AXES; i++) {
		o->g28[i] = m->axis[i].home;
		o->g30[i] = m->axis[i].home;
	}
}

const char *mlip_gcode_coord_name(int select)
{
	static const char *const names[MLIP_GCODE_N_COORD] = {
	    "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3"};

	return select >= 0 && select < MLIP_GCODE_N_COORD ? names[select] : "?";
}

void mlip_gcode_init(struct mlip_gcode *g, const struct mlip_machine *m)
{
	int i;

	memset(g, 0, sizeof *g);
	g->m = m;
	g->motion = -1;
	g->plane = 17;
	g->absolute = 1;
	g->tol_mm = m->tolerance_mm;
	for (i = 0; i < m->n_axes && i < MLIP_MAX_AXES; i++) {
		g->pos[i] = m->axis[i].home;
		g->cur[i] = m->axis[i].home;
	}
	mlip_gcode_offsets_init(&g->off, m);
}

void mlip_gcode_set_initial_feed(struct mlip_gcode *g, double f_word)
{
	g->initial_feed_word = f_word > 0 && isfinite(f_word) ? f_word : 0.0;
}

void mlip_gcode_set_strict(struct mlip_gcode *g, int on)
{
	g->strict = on != 0;
}

void mlip_gcode_set_offsets(struct mlip_gcode *g, const struct mlip_gcode_offsets *o)
{
	g->off = *o;
	if (g->off.select < 0 || g->off.select >= MLIP_GCODE_N_COORD) {
		g->off.select = 0;
	}
	g->off.g92_on = g->off.g92_on != 0;
}

static void notice(struct mlip_gcode *g, const char *word, uint32_t line)
{
	struct mlip_gcode_notice *n;
	uint32_t k;

	for (k = 0; k < g->n_notices; k++) {
		if (strcmp(g->notices[k].word, word) == 0) {
			g->notices[k].count++;
			return;
		}
	}
	if (g->n_notices < MLIP_GCODE_MAX_NOTICES) {
		n = &g->notices[g->n_notices++];
		memset(n->word, 0, sizeof n->word);
		strncpy(n->word, word, sizeof n->word - 1);
		n->first_line = line;
		n->count = 1;
	}
}

/* Texts of the notices that are not "ignored": what mlip did instead. */
static const struct {
	const char *word, *text;
} notice_texts[] = {
    {"G28", "rapid to the G28 position (through the intermediate point, if any): HOME of "
            "the config or G28.1 in the offsets file"},
    {"G30", "rapid to the G30 position (through the intermediate point, if any): HOME of "
            "the config or G30.1 in the offsets file"},
    {"F", "missing before a feed move: the initial feed was used"},
    {"G0", "axis words before any G0/G1/G2/G3 moved as G0, Grbl's start-up motion mode "
           "(--strict refuses them)"},
    {"G64P", "tolerance larger than the machine's CONTOUR_TOLERANCE: capped to it"},
    {"G64Q", "(LinuxCNC's naive-CAM merge tolerance) ignored: every segment is kept and "
             "corners blend within P"},
    {"M60", "pauses as M0 (no pallet shuttle)"},
    {"M2", "program end (LinuxCNC: G54 selected, G92 offsets off); later lines are not run"},
    {"M30", "program end (LinuxCNC: G54 selected, G92 offsets off); later lines are not run"},
    {"/", "block delete: the line was skipped (the block-delete switch is on, as LinuxCNC "
          "starts)"},
    {"$J", "(Grbl jog) run as a G1 move at its own F; the modal state is left as it was "
           "(Grbl 1.1)"},
    {"$H", "(Grbl homing cycle) skipped: mlip does not home; home the machine with the "
           "drives before starting mlip-rt and check HOME in the config"},
    {"$X", "(Grbl alarm unlock) skipped: mlip has no alarm lock (mlip-rt restarts a "
           "faulted machine)"},
    {"$C", "(Grbl check mode) skipped: mlip checks every program before it moves"},
    {"$SLP", "(Grbl sleep) skipped: stop mlip-rt instead"},
    {"$", "(Grbl settings or report) skipped: mlip's settings are in its config file"},
    {"?", "(Grbl status request) skipped: mlip-ctl status reports the machine"},
    {"~", "(Grbl cycle start) skipped: mlip-ctl resume continues a held or paused machine"},
    {"!", "(Grbl feed hold) skipped: a pause in a program is M0; mlip-ctl hold holds"},
};

const char *mlip_gcode_notice_text(const struct mlip_gcode_notice *n)
{
	size_t k;

	for (k = 0; k < sizeof notice_texts / sizeof notice_texts[0]; k++) {
		if (strcmp(n->word, notice_texts[k].word) == 0 ||
		    (n->word[0] == '$' && notice_texts[k].word[1] == '\0' &&
		     notice_texts[k].word[0] == '$')) {
			return notice_texts[k].text;
		}
	}
	return "ignored (no effect on motion)";
}

static int axis_index(const struct mlip_machine *m, char letter)
{
	int i;

	for (i = 0; i < m->n_axes; i++) {
		if (upper(m->axis[i].letter) == letter) {
			return i;
		}
	}
	return -1;
}

/* ---- emission ---- */

/* What a line's blocks share, besides target and tolerance. */
struct emit_ctx {
	mlip_block_sink sink;
	void *ctx;
	uint32_t line;
	uint8_t rapid;
	double feed_mm_s;
	int dwell_pending; /* G4: its DWELL goes first, once the line is known good */
	double dwell_s;
};

static int emit_event(struct mlip_gcode *g, mlip_block_sink sink, void *ctx, uint32_t line,
                      mlip_block_kind kind, double dwell_s);

/* The line's dwell, before its first move (LinuxCNC: dwell, then motion). */
static int flush_dwell(struct mlip_gcode *g, struct emit_ctx *c)
{
	if (c->dwell_pending) {
		if (emit_event(g, c->sink, c->ctx, c->line, MLIP_BLOCK_DWELL, c->dwell_s) != 0) {
			return -1;
		}
		c->dwell_pending = 0;
	}
	return 0;
}

/* Emit t unless it is within MLIP_GCODE_MERGE_MM of the last emitted point
 * (no zero-length segment for the planner). Returns 0, or -1 when the sink
 * refused the block. */
static int emit(struct mlip_gcode *g, struct emit_ctx *c, const double *t, double tol_mm)
{
	struct mlip_block b;
	double d2 = 0;
	int i, n = g->m->n_axes;

	if (flush_dwell(g, c) != 0) {
		return -1;
	}
	for (i = 0; i < n; i++) {
		d2 += (t[i] - g->pos[i]) * (t[i] - g->pos[i]);
	}
	if (d2 < MLIP_GCODE_MERGE_MM * MLIP_GCODE_MERGE_MM) {
		return 0;
	}
	memset(&b, 0, sizeof b);
	for (i = 0; i < n; i++) {
		b.target[i] = t[i];
	}
	b.feed_mm_s = c->feed_mm_s;
	b.tol_mm = tol_mm;
	b.line = c->line;
	b.rapid = c->rapid;
	b.exact_stop = (uint8_t)g->exact_stop;
	if (c->sink(c->ctx, &b) != 0) {
		return -1;
	}
	for (i = 0; i < n; i++) {
		g->pos[i] = t[i];
	}
	g->blocks++;
	g->moves++;
	return 0;
}

/* A program event (dwell, pause) at the last emitted point. 0, or -1 when
 * the sink refused it. */
static int emit_event(struct mlip_gcode *g, mlip_block_sink sink, void *ctx, uint32_t line,
                      mlip_block_kind kind, double dwell_s)
{
	struct mlip_block b;

	memset(&b, 0, sizeof b);
	memcpy(b.target, g->pos, sizeof b.target);
	b.feed_mm_s = g->m->max_feed_mm_s;
	b.tol_mm = g->tol_mm;
	b.line = line;
	b.kind = (uint8_t)kind;
	b.dwell_s = dwell_s;
	if (sink(ctx, &b) != 0) {
		return -1;
	}
	g->blocks++;
	return 0;
}

/* Soft limits (and finiteness) of a target; col_of[i] is the column to blame
 * for axis i. */
static mlip_status check_limits(const struct mlip_gcode *g, const double *t, const uint32_t *col_of,
                                uint32_t line, int on_arc, struct mlip_gcode_error *e)
{
	const struct mlip_machine *m = g->m;
	int i;

	for (i = 0; i < m->n_axes; i++) {
		const struct mlip_axis *ax = &m->axis[i];

		if (!isfinite(t[i])) {
			return failf(e, line, col_of[i], MLIP_E_RANGE, "%c value is not finite",
			             upper(ax->letter));
		}
		if (!(t[i] >= ax->min_limit && t[i] <= ax->max_limit)) {
			return failf(e, line, col_of[i], MLIP_E_RANGE,
			             "%c %f beyond soft limit %f%s", upper(ax->letter), t[i],
			             t[i] < ax->min_limit ? ax->min_limit : ax->max_limit,
			             on_arc ? " on the arc" : "");
		}
	}
	return MLIP_OK;
}

/* ---- arcs ---- */

struct arc {
	int iu, iv;       /* config indices of the plane axes */
	double cu, cv;    /* center */
	double r0, r1;    /* radius at start and at end: a slight spiral, as LinuxCNC */
	double a0, sweep; /* start angle and signed sweep, rad; G3 > 0 */
	uint32_t n;       /* chords */
	double sag_mm;    /* sagitta of each chord */
};

/* Plane tables for G17, G18, G19: the (u, v) axes, their offset words (I=0,
 * J=1, K=2) and the offset word of the normal axis, which is not allowed. */
static const char plane_u[3] = {'X', 'Z', 'Y'}, plane_v[3] = {'Y', 'X', 'Z'};
static const int plane_ou[3] = {0, 2, 1}, plane_ov[3] = {1, 0, 2}, plane_off[3] = {2, 1, 0};

/* Point k of n along the arc; the last one is the programmed end exactly.
 * Axes other than the plane's move linearly with the angle (helix). */
static void arc_point(const struct arc *a, const double *s, const double *t, int n_axes, uint32_t k,
                      double *p)
{
	double f = (double)k / a->n, ang, r;
	int i;

	for (i = 0; i < n_axes; i++) {
		p[i] = k == a->n ? t[i] : s[i] + (t[i] - s[i]) * f;
	}
	if (k == a->n) {
		return;
	}
	ang = a->a0 + a->sweep * f;
	r = a->r0 + (a->r1 - a->r0) * f;
	p[a->iu] = a->cu + r * cos(ang);
	p[a->iv] = a->cv + r * sin(ang);
}

/* Center and radius of an R arc: on the left of start->end for a short G3,
 * mirrored for G2 and for the long arc (R < 0). */
static mlip_status arc_center_r(const struct blk *b, int cw, double scale, double su, double sv,
                                double eu, double ev, uint32_t line, struct arc *a,
                                struct mlip_gcode_error *e)
{
	double r = fabs(b->r) * scale, du = eu - su, dv = ev - sv;
	double d = sqrt(du * du + dv * dv), h, side;

	if (!(r > 0)) {
		return failf(e, line, b->r_col, MLIP_E_RANGE, "R arc with zero radius");
	}
	if (d < 1e-9) {
		return failf(e, line, b->r_col, MLIP_E_RANGE,
		             "R arc with end equal to start: use I/J/K for a full circle");
	}
	if (d > 2 * r * (1 + 1e-9) + 1e-9) {
		return failf(e, line, b->r_col, MLIP_E_RANGE,
		             "R arc: endpoints %f mm apart, more than 2R = %f mm", d, 2 * r);
	}
	h = d >= 2 * r ? 0 : sqrt(r * r - d * d / 4);
	side = (cw ? -1.0 : 1.0) * (b->r > 0 ? 1.0 : -1.0);
	a->cu = (su + eu) / 2 - side * h * dv / d;
	a->cv = (sv + ev) / 2 + side * h * du / d;
	return MLIP_OK;
}

static mlip_status arc_setup(const struct mlip_gcode *g, const struct blk *b, int motion,
                             double scale, const double *s, const double *t, uint32_t line,
                             uint32_t col, struct arc *a, struct mlip_gcode_error *e)
{
	int p = g->plane - 17, cw = motion == 2;
	int has_uv = b->has_ijk[plane_ou[p]] || b->has_ijk[plane_ov[p]];
	double su, sv, eu, ev, sweep, rmax, smax, step;
	mlip_status st;

	memset(a, 0, sizeof *a);
	a->iu = axis_index(g->m, plane_u[p]);
	a->iv = axis_index(g->m, plane_v[p]);
	if (a->iu < 0 || a->iv < 0) {
		return failf(e, line, col, MLIP_E_UNSUPPORTED,
		             "%G in G%u needs axes %c and %c configured", motion * 10,
		             (unsigned)g->plane, plane_u[p], plane_v[p]);
	}
	if (b->has_ijk[plane_off[p]]) {
		return failf(e, line, b->ijk_col[plane_off[p]], MLIP_E_SYNTAX,
		             "%c word not used by an arc in the G%u plane", 'I' + plane_off[p],
		             (unsigned)g->plane);
	}
	su = s[a->iu];
	sv = s[a->iv];
	eu = t[a->iu];
	ev = t[a->iv];
	if (b->has_r && has_uv) {
		return failf(e, line, b->r_col, MLIP_E_SYNTAX, "arc with both R and I/J/K");
	}
	if (b->has_r) {
		st = arc_center_r(b, cw, scale, su, sv, eu, ev, line, a, e);
		if (st != MLIP_OK) {
			return st;
		}
	} else if (!has_uv) {
		return failf(e, line, col, MLIP_E_SYNTAX, "arc with no I/J/K or R");
	} else {
		/* I J K: offsets from the start (G91.1) */
		a->cu = su + b->ijk[plane_ou[p]] * scale;
		a->cv = sv + b->ijk[plane_ov[p]] * scale;
	}
	a->r0 = hypot(su - a->cu, sv - a->cv);
	a->r1 = hypot(eu - a->cu, ev - a->cv);
	if (a->r0 < 1e-9) {
		return failf(e, line, col, MLIP_E_RANGE, "arc with zero radius");
	}
	if (fabs(a->r0 - a->r1) > fmax(0.002, 0.001 * a->r0)) { /* LinuxCNC's test */
		return failf(e, line, col, MLIP_E_RANGE,
		             "arc radius to start %f differs from radius to end %f mm", a->r0,
		             a->r1);
	}
	a->a0 = atan2(sv - a->cv, su - a->cu);
	if (hypot(eu - su, ev - sv) < 1e-9) {
		sweep = 2 * PI; /* end = start with I/J/K: a full circle */
	} else {
		sweep = atan2(ev - a->cv, eu - a->cu) - a->a0;
		sweep = cw ? -sweep : sweep;
		while (sweep <= 0) {
			sweep += 2 * PI;
		}
		while (sweep > 2 * PI) {
			sweep -= 2 * PI;
		}
	}
	a->sweep = cw ? -sweep : sweep;
	/* equal steps, each within the sagitta budget (header comment) */
	rmax = fmax(a->r0, a->r1);
	smax = MLIP_GCODE_ARC_FRACTION * g->tol_mm;
	step = smax >= 2 * rmax ? PI : 4 * asin(sqrt(smax / (2 * rmax)));
	step = fmin(step, PI / 2); /* some shape even on arcs smaller than the tolerance */
	if (!(step > 0) || sweep / step > MAX_CHORDS) {
		return failf(e, line, col, MLIP_E_RANGE, "arc too long: more than %u chords",
		             MAX_CHORDS);
	}
	a->n = (uint32_t)ceil(sweep / step - 1e-9);
	a->n = a->n < 1 ? 1 : a->n;
	step = sweep / a->n;
	a->sag_mm = 2 * rmax * sin(step / 4) * sin(step / 4);
	return MLIP_OK;
}

/* Chords of an arc: every point checked against the limits before any is
 * emitted (an arc may bulge past a limit its ends respect), so a rejected line
 * emits nothing. Inner corners get eps minus the chord's sagitta. */
static mlip_status emit_arc(struct mlip_gcode *g, struct emit_ctx *ec, const struct arc *arc,
                            const double *s, const double *t, const uint32_t *col_of,
                            struct mlip_gcode_error *e)
{
	const struct mlip_machine *m = g->m;
	double p[MLIP_MAX_AXES];
	mlip_status st;
	uint32_t k;

	for (k = 1; k < arc->n; k++) {
		arc_point(arc, s, t, m->n_axes, k, p);
		st = check_limits(g, p, col_of, ec->line, 1, e);
		if (st != MLIP_OK) {
			return st;
		}
	}
	for (k = 1; k <= arc->n; k++) {
		arc_point(arc, s, t, m->n_axes, k, p);
		if (emit(g, ec, p, k < arc->n ? g->tol_mm - arc->sag_mm : g->tol_mm)) {
			return MLIP_E_FULL;
		}
	}
	return MLIP_OK;
}

/* ---- one line ---- */

/* What the checks found out about a line, for its motion. */
struct plan {
	int motion;     /* in effect for this line, -1 none */
	int moves;      /* the line moves: axis words, or a center-only arc */
	int has_axes;   /* axis words on the line */
	int axis_use;   /* they are not motion: G10, G92, G28/G30 */
	int g0_default; /* they move as G0: no motion mode yet (Grbl) */
	uint32_t mcol;  /* column to blame for the motion: its G word, else the line */
};

/* Work offset plus G92 offset of axis i: machine = program + this. */
static double offset_of(const struct mlip_gcode *g, int i)
{
	return g->off.coord[g->off.select][i] + (g->off.g92_on ? g->off.g92[i] : 0.0);
}

/* Words against the machine and the modal state. */
static mlip_status check_line(const struct mlip_gcode *g, const struct blk *b,
                              const struct lexed *lx, uint32_t line, struct plan *pl,
                              struct mlip_gcode_error *e)
{
	uint32_t first_ax = 0, c;
	int a, i, has_axes = 0, arc_words, inverse;
	char L = 'R';

	for (a = 0; a < 6; a++) {
		if (!b->has_ax[a]) {
			continue;
		}
		if (axis_index(g->m, axis_letters[a]) < 0) {
			return failf(e, line, b->ax_col[a], MLIP_E_UNSUPPORTED,
			             "axis %c not configured", axis_letters[a]);
		}
		has_axes = 1;
		first_ax = !first_ax || b->ax_col[a] < first_ax ? b->ax_col[a] : first_ax;
	}
	pl->has_axes = has_axes;
	pl->axis_use = b->home || b->g10 || b->g92 == 920;
	pl->g0_default = 0;
	if (pl->axis_use && b->motion >= 0 && has_axes) {
		return failf(e, line, b->motion_col, MLIP_E_SYNTAX,
		             "%G and %G on one line: both use axis words",
		             b->home  ? b->home * 10
		             : b->g10 ? 100
		                      : 920,
		             b->motion * 10);
	}
	if (b->homeset && has_axes) {
		return failf(e, line, first_ax, MLIP_E_SYNTAX,
		             "%G takes no axis words: it stores the current position",
		             b->homeset * 10 + 1);
	}
	if (b->g92 > 920 && has_axes) {
		return failf(e, line, first_ax, MLIP_E_SYNTAX, "%G takes no axis words", b->g92);
	}
	if (b->g92 == 920 && !has_axes) {
		return failf(e, line, b->g92_col, MLIP_E_SYNTAX,
		             "G92 without axis words: give the coordinates the current point "
		             "gets, e.g. G92 X0 Y0");
	}
	pl->motion = b->motion >= 0 ? b->motion : g->motion;
	pl->mcol = b->motion >= 0 ? b->motion_col : lx->first_col;
	arc_words = b->has_ijk[0] || b->has_ijk[1] || b->has_ijk[2] || (b->has_r && !b->g10);
	if (arc_words && (pl->motion < 2 || pl->axis_use)) {
		c = b->has_r ? b->r_col : 0;
		for (i = 0; i < 3; i++) {
			if (b->has_ijk[i] && (!c || b->ijk_col[i] < c)) {
				c = b->ijk_col[i];
				L = (char)('I' + i);
			}
		}
		return failf(e, line, c, MLIP_E_SYNTAX, "%c word without an arc (G2/G3)", L);
	}
	if (has_axes && !pl->axis_use && pl->motion < 0) {
		if (g->strict) {
			return failf(
			    e, line, first_ax, MLIP_E_SYNTAX,
			    "axis words with no motion mode: program G0, G1, G2 or G3 first");
		}
		pl->motion = 0; /* Grbl starts in G0 */
		pl->g0_default = 1;
	}
	if (b->g53 && pl->motion >= 2 && (has_axes || arc_words)) {
		return failf(e, line, b->g53_col, MLIP_E_SYNTAX, "G53 needs G0 or G1");
	}
	pl->moves = !pl->axis_use && (has_axes || arc_words);
	inverse = b->feedmode ? b->feedmode == 93 : g->inverse_time;
	if (inverse && pl->moves && pl->motion >= 1 && !b->has_f) {
		return failf(e, line, pl->mcol, MLIP_E_SYNTAX,
		             "G93 inverse time: every feed move needs its own F (the move takes "
		             "1/F minutes)");
	}
	return MLIP_OK;
}

/* Modal state, committed before the motion so that an error in the motion
 * does not cascade into every following line. F is kept both as written (for
 * rotary-only moves) and in mm/s, converted with the units of its own line.
 * In G93 an F belongs to its line only; a change of feed mode forgets F
 * (LinuxCNC). */
static void commit_modal(struct mlip_gcode *g, const struct blk *b, const struct plan *pl,
                         uint32_t line)
{
	double tol;
	int i;

	if (b->units) {
		g->inches = b->units == 20;
	}
	if (b->dist) {
		g->absolute = b->dist == 90;
	}
	if (b->plane) {
		g->plane = b->plane;
	}
	if (b->motion >= 0) {
		g->motion = b->motion;
	}
	if (pl->g0_default) {
		g->motion = 0;
		notice(g, "G0", line);
	}
	if (b->feedmode && (b->feedmode == 93) != g->inverse_time) {
		g->inverse_time = b->feedmode == 93;
		g->feed_mm_s = 0;
		g->feed_word = 0;
		g->feed_reset = 1;
	}
	if (b->has_f && !g->inverse_time) {
		g->feed_word = b->f;
		g->feed_mm_s = b->f * (g->inches ? MM_PER_INCH : 1.0) / 60.0;
		g->feed_reset = 0;
	}
	if (b->coord >= 0) {
		g->off.select = b->coord;
	}
	if (b->path == 610 || b->path == 611) {
		g->exact_stop = 1; /* rest at the end of every move (corners exact) */
		g->tol_mm = g->m->tolerance_mm;
	} else if (b->path == 640) {
		g->exact_stop = 0;
		tol = b->has_p && b->p > 0 ? b->p * (g->inches ? MM_PER_INCH : 1.0) : 0;
		g->tol_mm = tol > 0 && tol < g->m->tolerance_mm ? tol : g->m->tolerance_mm;
		if (tol > g->m->tolerance_mm) {
			notice(g, "G64P", line);
		}
		if (b->has_q) {
			notice(g, "G64Q", line);
		}
	}
	for (i = 0; i < b->n_notes; i++) {
		notice(g, b->notes[i], line);
	}
}

/* The block feed: F as a path speed when a linear axis moves, else in deg/min
 * (G94). Before any F: the initial feed if one was set, else an error. */
static mlip_status block_feed(struct mlip_gcode *g, const struct plan *pl, const double *s,
                              const double *t, uint32_t line, double *feed_mm_s,
                              struct mlip_gcode_error *e)
{
	const struct mlip_machine *m = g->m;
	double fmm = g->feed_mm_s, fword = g->feed_word;
	int i, linear = 0;

	if (!(fmm > 0)) {
		if (g->feed_reset) {
			return failf(e, line, pl->mcol, MLIP_E_SYNTAX,
			             "missing feed: a change between G93 and G94 needs a new F");
		}
		if (!(g->initial_feed_word > 0)) {
			return failf(
			    e, line, pl->mcol, MLIP_E_SYNTAX,
			    "missing feed: no F before the first feed move (a program with "
			    "none runs with --default-feed F)");
		}
		fword = g->initial_feed_word;
		fmm = fword * (g->inches ? MM_PER_INCH : 1.0) / 60.0;
		notice(g, "F", line);
	}
	for (i = 0; i < m->n_axes; i++) {
		if (m->axis[i].kind != MLIP_AXIS_ROTARY &&
		    (pl->motion >= 2 || fabs(t[i] - s[i]) >= MLIP_GCODE_MERGE_MM)) {
			linear = 1;
		}
	}
	*feed_mm_s = linear ? fmm : fword / 60.0;
	return MLIP_OK;
}

/* G93: the move takes 1/F minutes, so its speed is its length times F/60:
 * the linear axes' path length (the arc's, for G2/G3), or the rotary axes'
 * (deg/s) when no linear axis moves. */
static double inverse_time_feed(const struct mlip_gcode *g, double f, const double *s,
                                const double *t, const struct arc *arc)
{
	const struct mlip_machine *m = g->m;
	double lin = 0, rot = 0, d, len;
	int i;

	for (i = 0; i < m->n_axes; i++) {
		d = arc && (i == arc->iu || i == arc->iv) ? 0 : t[i] - s[i];
		if (m->axis[i].kind == MLIP_AXIS_ROTARY) {
			rot += d * d;
		} else {
			lin += d * d;
		}
	}
	if (arc) {
		d = fabs(arc->sweep) * (arc->r0 + arc->r1) / 2;
		if (m->axis[arc->iu].kind == MLIP_AXIS_ROTARY) {
			rot += d * d;
		} else {
			lin += d * d;
		}
	}
	len = sqrt(lin) >= MLIP_GCODE_MERGE_MM ? sqrt(lin) : sqrt(rot);
	return len * f / 60.0;
}

/* Grbl's jog "$J=" + words at t[j..len): a G1 move at its own F, with G20/
 * G21, G90/G91 and G53 for that move only; the modal state stays as it was
 * (Grbl 1.1). Errors name columns of the original line. */
static mlip_status jog_line(struct mlip_gcode *g, const char *t, size_t len, size_t j,
                            uint32_t line, mlip_block_sink sink, void *ctx,
                            struct mlip_gcode_error *e)
{
	struct lexed lx;
	struct mlip_gcode saved;
	char buf[MLIP_GCODE_MAX_LINE + 4];
	mlip_status st;
	int k, c, has_f = 0;

	st = lex_line(t + j, len - j, 0, &lx, e);
	if (st != MLIP_OK) {
		e->col += e->col ? (uint32_t)j : 0;
		e->line = line;
		return st;
	}
	for (k = 0; k < lx.n; k++) {
		c = code_of(lx.w[k].value);
		has_f |= lx.w[k].letter == 'F';
		if (!(axis_slot(lx.w[k].letter) >= 0 || lx.w[k].letter == 'F' ||
		      (lx.w[k].letter == 'G' &&
		       (c == 200 || c == 210 || c == 900 || c == 910 || c == 530)))) {
			return failf(e, line, lx.w[k].col + (uint32_t)j, MLIP_E_UNSUPPORTED,
			             "Grbl jog: only G20, G21, G90, G91, G53, axis words and F");
		}
	}
	if (!has_f) {
		return failf(e, line, (uint32_t)j - 2, MLIP_E_SYNTAX,
		             "Grbl jog without F: a jog gives its own feed, e.g. $J=G91 X10 F600");
	}
	memcpy(buf, "G1 ", 3);
	memcpy(buf + 3, t + j, len - j);
	saved = *g;
	g->motion = 1;
	g->inverse_time = 0;
	st = mlip_gcode_line(g, buf, len - j + 3, line, sink, ctx, e);
	if (st != MLIP_OK && e->col) {
		e->col = e->col > 3 ? e->col - 3 + (uint32_t)j : (uint32_t)j - 2;
	}
	g->motion = saved.motion;
	g->absolute = saved.absolute;
	g->inches = saved.inches;
	g->inverse_time = saved.inverse_time;
	g->feed_mm_s = saved.feed_mm_s;
	g->feed_word = saved.feed_word;
	g->feed_reset = saved.feed_reset;
	if (st == MLIP_OK) {
		notice(g, "$J", line);
	}
	return st;
}

/* Grbl system lines ('$' first): not G-code. Each kind is a notice naming
 * what mlip does instead, or an error in strict mode; a jog runs as a G1
 * move (skipping it would change the path). */
static mlip_status system_line(struct mlip_gcode *g, const char *t, size_t len, size_t i0,
                               uint32_t line, mlip_block_sink sink, void *ctx,
                               struct mlip_gcode_error *e)
{
	static const char *const cmds[] = {"$H", "$X", "$C",   "$G",   "$I", "$N",
	                                   "$$", "$#", "$SLP", "$RST", "$"};
	char word[8];
	size_t i, n, k;

	for (i = i0; i < len; i++) {
		unsigned char c = (unsigned char)t[i];

		if ((c < 0x20 && c != '\t') || c >= 0x7f) {
			return failf(e, line, (uint32_t)i + 1, MLIP_E_SYNTAX,
			             "unexpected character %b in a Grbl system line", c);
		}
	}
	while (len > i0 && is_blank(t[len - 1])) {
		len--;
	}
	n = len - i0;
	if (n >= 3 && upper(t[i0 + 1]) == 'J' && t[i0 + 2] == '=') {
		if (g->strict) {
			return failf(e, line, (uint32_t)i0 + 1, MLIP_E_UNSUPPORTED,
			             "Grbl jog '%t' is not G-code (strict mode): write it as G1",
			             t + i0, n);
		}
		return jog_line(g, t, len, i0 + 3, line, sink, ctx, e);
	}
	/* the command: '$', then digits up to '=' (a setting), or letters/$/# */
	word[0] = '$';
	k = 1;
	i = i0 + 1;
	if (i < len && is_digit(t[i])) {
		while (i < len && is_digit(t[i]) && k < 5) {
			word[k++] = t[i++];
		}
		if (i < len && t[i] == '=') {
			word[k++] = '=';
			i = len;
		}
	} else if (i < len && (t[i] == '$' || t[i] == '#')) {
		word[k++] = t[i++];
	} else {
		while (i < len && is_alpha(t[i]) && k < 5) {
			word[k++] = upper(t[i++]);
		}
		while (k == 2 && word[1] == 'N' && i < len && is_digit(t[i])) {
			i++; /* $N0=..., $N1=...: startup blocks */
		}
		if (i < len && t[i] == '=') {
			i = len; /* $N0=..., $RST=..., $I=...: the value is Grbl's */
		}
	}
	word[k] = '\0';
	for (k = 0; k < sizeof cmds / sizeof cmds[0]; k++) {
		if (strcmp(word, cmds[k]) == 0 ||
		    (k == 10 && word[1] && word[strlen(word) - 1] == '=')) {
			break;
		}
	}
	if (i != len || k == sizeof cmds / sizeof cmds[0]) {
		return failf(e, line, (uint32_t)i0 + 1, MLIP_E_SYNTAX,
		             "unknown Grbl system command '%t'", t + i0, n);
	}
	if (g->strict) {
		return failf(e, line, (uint32_t)i0 + 1, MLIP_E_UNSUPPORTED,
		             "Grbl system line '%t' is not G-code (strict mode): delete it", t + i0,
		             n);
	}
	notice(g, word, line);
	return MLIP_OK;
}

/* G10 L2/L20, G92 and its variants, G28.1/G30.1: the offsets state, in
 * LinuxCNC's order (after the modes, before the motion). Values are in the
 * line's units; G91 does not apply to them. */
static void set_offsets(struct mlip_gcode *g, const struct blk *b, double scale)
{
	struct mlip_gcode_offsets *o = &g->off;
	const struct mlip_machine *m = g->m;
	int i, a, sys;
	double v, k;

	for (i = 0; i < m->n_axes; i++) {
		a = axis_slot(upper(m->axis[i].letter));
		k = m->axis[i].kind == MLIP_AXIS_ROTARY ? 1.0 : scale;
		v = a >= 0 && b->has_ax[a] ? b->ax[a] * k : 0;
		if (b->g10 && a >= 0 && b->has_ax[a]) {
			sys = b->p == 0 ? o->select : (int)b->p - 1;
			/* L2: the origin in machine coordinates; L20: the origin that
			 * makes the current point read v */
			o->coord[sys][i] =
			    b->l == 2 ? v : g->cur[i] - (o->g92_on ? o->g92[i] : 0.0) - v;
		}
		if (b->g92 == 920) {
			o->g92[i] = a >= 0 && b->has_ax[a] ? g->cur[i] - o->coord[o->select][i] - v
			                                   : (o->g92_on ? o->g92[i] : 0.0);
		} else if (b->g92 == 921) {
			o->g92[i] = 0;
		}
		if (b->homeset == 28) {
			o->g28[i] = g->cur[i];
		} else if (b->homeset == 30) {
			o->g30[i] = g->cur[i];
		}
	}
	if (b->g92) {
		o->g92_on = b->g92 == 920 || b->g92 == 923;
	}
}

/* G28/G30: rapid to the intermediate point t (when axis words were given,
 * those axes only), then to the stored position (those axes, or all). */
static mlip_status go_home(struct mlip_gcode *g, const struct blk *b, const struct plan *pl,
                           struct emit_ctx *ec, const double *t, const uint32_t *col_of,
                           uint32_t line, struct mlip_gcode_error *e)
{
	const struct mlip_machine *m = g->m;
	const double *stored = b->home == 28 ? g->off.g28 : g->off.g30;
	double dest[MLIP_MAX_AXES];
	uint32_t col[MLIP_MAX_AXES];
	mlip_status st;
	int i, a;

	for (i = 0; i < m->n_axes; i++) {
		a = axis_slot(upper(m->axis[i].letter));
		dest[i] = !pl->has_axes || (a >= 0 && b->has_ax[a]) ? stored[i] : t[i];
		col[i] = b->home_col;
	}
	st = check_limits(g, t, col_of, line, 0, e);
	if (st == MLIP_OK) {
		st = check_limits(g, dest, col, line, 0, e);
	}
	if (st != MLIP_OK) {
		return st;
	}
	ec->rapid = 1;
	ec->feed_mm_s = m->max_feed_mm_s;
	if (emit(g, ec, t, g->tol_mm) != 0 || emit(g, ec, dest, g->tol_mm) != 0) {
		return MLIP_E_FULL;
	}
	memcpy(g->cur, dest, sizeof dest);
	notice(g, b->home == 28 ? "G28" : "G30", line);
	return MLIP_OK;
}

/* First non-blank byte of a line (after a BOM on line 1), or len. */
static size_t first_byte(const char *text, size_t len, uint32_t lineno)
{
	const unsigned char *t = (const unsigned char *)text;
	size_t i = 0;

	if (lineno == 1 && len >= 3 && t[0] == 0xEF && t[1] == 0xBB && t[2] == 0xBF) {
		i = 3;
	}
	while (i < len && is_blank(t[i])) {
		i++;
	}
	return i;
}

mlip_status mlip_gcode_line(struct mlip_gcode *g, const char *text, size_t len, uint32_t lineno,
                            mlip_block_sink sink, void *ctx, struct mlip_gcode_error *err)
{
	const struct mlip_machine *m = g->m;
	struct mlip_gcode_error dummy;
	struct lexed lx;
	struct blk b;
	struct plan pl = {-1, 0, 0, 0, 0, 0};
	struct emit_ctx ec;
	struct arc arc;
	double start[MLIP_MAX_AXES], t[MLIP_MAX_AXES], scale, k;
	uint32_t col_of[MLIP_MAX_AXES];
	size_t i0;
	int i, a;
	mlip_status st;

	if (!err) {
		err = &dummy;
	}
	if (m->n_axes < 1 || m->n_axes > MLIP_MAX_AXES) {
		return failf(err, lineno, 0, MLIP_E_INVALID, "machine has no valid axis count");
	}
	/* checked before any byte is read: a caller may pass the length of a
	 * line it did not keep whole */
	if (len > MLIP_GCODE_MAX_LINE + 1 ||
	    (len == MLIP_GCODE_MAX_LINE + 1 && text[len - 1] != '\r')) {
		return failf(err, lineno, MLIP_GCODE_MAX_LINE + 1, MLIP_E_SYNTAX,
		             "line too long: %u bytes, at most %u",
		             (unsigned)(len > 999999 ? 999999 : len), MLIP_GCODE_MAX_LINE);
	}
	if (len > 0 && text[len - 1] == '\r') {
		len--; /* CRLF line ends */
	}
	if (g->ended) {
		return MLIP_OK; /* after M2/M30: LinuxCNC reads no further */
	}
	i0 = first_byte(text, len, lineno);
	if (i0 < len && text[i0] == '$') {
		return system_line(g, text, len, i0, lineno, sink, ctx, err);
	}
	if (i0 < len && (text[i0] == '?' || text[i0] == '~' || text[i0] == '!') &&
	    first_byte(text + i0 + 1, len - i0 - 1, 0) == len - i0 - 1) {
		/* Grbl's real-time commands, alone on a line: status, cycle
		 * start, feed hold (a sender's, never a program's) */
		if (g->strict) {
			return failf(
			    err, lineno, (uint32_t)i0 + 1, MLIP_E_UNSUPPORTED,
			    "Grbl real-time command '%c' is not G-code (strict mode): delete "
			    "it",
			    text[i0]);
		}
		notice(g, text[i0] == '?' ? "?" : text[i0] == '~' ? "~" : "!", lineno);
		return MLIP_OK;
	}
	if (i0 < len && upper(text[i0]) == 'O' && i0 + 1 < len &&
	    (is_digit(text[i0 + 1]) || text[i0 + 1] == '<')) {
		return failf(err, lineno, (uint32_t)i0 + 1, MLIP_E_UNSUPPORTED,
		             "O-words (subroutines, loops, conditions) not supported: have the CAM "
		             "expand them");
	}
	if (i0 < len && text[i0] == '/') {
		notice(g, "/", lineno);
		return MLIP_OK;
	}
	st = lex_line(text, len, lineno, &lx, err);
	if (st == MLIP_OK) {
		st = classify(&lx, lineno, &b, err);
	}
	if (st == MLIP_OK) {
		st = check_line(g, &b, &lx, lineno, &pl, err);
	}
	if (st != MLIP_OK) {
		return st;
	}
	/* LinuxCNC's order of execution: dwell, modes, offsets, motion, stop;
	 * the dwell is emitted with the motion, once that is known good */
	commit_modal(g, &b, &pl, lineno);
	scale = g->inches ? MM_PER_INCH : 1.0;
	set_offsets(g, &b, scale);

	/* target: absolute machine coordinates, config order, machine units
	 * (rotary axes: degrees) */
	for (i = 0; i < m->n_axes; i++) {
		a = axis_slot(upper(m->axis[i].letter));
		start[i] = t[i] = g->cur[i];
		col_of[i] = pl.motion >= 2 ? pl.mcol : lx.first_col; /* arcs move wordless axes */
		if (a >= 0 && b.has_ax[a] && !b.g10 && b.g92 != 920) {
			k = m->axis[i].kind == MLIP_AXIS_ROTARY ? 1.0 : scale;
			t[i] = b.g53         ? b.ax[a] * k
			       : g->absolute ? b.ax[a] * k + offset_of(g, i)
			                     : g->cur[i] + b.ax[a] * k;
			col_of[i] = b.ax_col[a];
		}
	}
	ec.sink = sink;
	ec.ctx = ctx;
	ec.line = lineno;
	ec.rapid = pl.motion == 0;
	ec.feed_mm_s = m->max_feed_mm_s; /* rapids: informative, the planner ignores it */
	ec.dwell_pending = b.g4;
	ec.dwell_s = b.p;
	st = MLIP_OK;
	if (b.home) {
		st = go_home(g, &b, &pl, &ec, t, col_of, lineno, err);
	} else if (pl.moves) {
		st = pl.motion > 0 && !g->inverse_time
		         ? block_feed(g, &pl, start, t, lineno, &ec.feed_mm_s, err)
		         : MLIP_OK;
		if (st == MLIP_OK) {
			st = check_limits(g, t, col_of, lineno, 0, err);
		}
		if (st == MLIP_OK && pl.motion >= 2) {
			st = arc_setup(g, &b, pl.motion, scale, start, t, lineno, pl.mcol, &arc,
			               err);
			if (st == MLIP_OK && g->inverse_time) {
				ec.feed_mm_s = inverse_time_feed(g, b.f, start, t, &arc);
			}
			if (st == MLIP_OK) {
				st = emit_arc(g, &ec, &arc, start, t, col_of, err);
			}
		} else if (st == MLIP_OK) {
			if (pl.motion == 1 && g->inverse_time) {
				ec.feed_mm_s = inverse_time_feed(g, b.f, start, t, 0);
			}
			if (emit(g, &ec, t, g->tol_mm) != 0) {
				st = MLIP_E_FULL;
			}
		}
		if (st == MLIP_OK) {
			memcpy(g->cur, t, sizeof g->cur);
		}
	}
	if (st == MLIP_OK && flush_dwell(g, &ec) != 0) {
		st = MLIP_E_FULL;
	}
	if (st == MLIP_OK && b.pause &&
	    emit_event(g, sink, ctx, lineno,
	               b.pause == 2 ? MLIP_BLOCK_OPTIONAL_PAUSE : MLIP_BLOCK_PAUSE, 0) != 0) {
		st = MLIP_E_FULL;
	}
	if (st == MLIP_E_FULL) {
		for (i = 0; i < m->n_axes; i++) {
			g->cur[i] = g->pos[i]; /* resume from what the sink holds */
		}
		return failf(err, lineno, 0, MLIP_E_FULL, "block sink full: parsing stopped");
	}
	if (b.end) {
		/* M2/M30 (LinuxCNC): G54 selected, G92 offsets off, values kept */
		g->ended = 1;
		g->off.select = 0;
		g->off.g92_on = 0;
	}
	return st;
}

mlip_status mlip_gcode_finish(struct mlip_gcode *g, uint32_t last_line,
                              struct mlip_gcode_error *err)
{
	struct mlip_gcode_error dummy;

	if (g->moves == 0) {
		return failf(err ? err : &dummy, last_line ? last_line : 1, 0, MLIP_E_SYNTAX,
		             "empty program: no motion");
	}
	return MLIP_OK;
}

/* ---- whole-program scans (no machine needed) ---- */

/* Next word outside comments from *pi on: its letter (upper case), where its
 * number starts, and its line. A letter counts only when a number follows it
 * (after blanks), as for the lexer. */
static int next_word(const char *t, size_t n, size_t *pi, uint32_t *line, char *letter, size_t *num)
{
	size_t i = *pi, j;

	while (i < n) {
		char c = t[i];

		if (c == '\n' || (c == '\r' && (i + 1 == n || t[i + 1] != '\n'))) {
			(*line)++; /* LF, CRLF or a lone CR */
			i++;
		} else if (c == '(' || c == ';') {
			while (i < n && t[i] != '\n' && t[i] != '\r' &&
			       !(c == '(' && t[i] == ')')) {
				i++;
			}
			i += i < n && t[i] == ')';
		} else if (is_alpha(c)) {
			for (j = i + 1; j < n && is_blank(t[j]); j++) {
			}
			i++;
			if (j < n && starts_number(t[j])) {
				*letter = upper(c);
				*num = j;
				*pi = i;
				return 1;
			}
		} else {
			i++;
		}
	}
	*pi = i;
	return 0;
}

int mlip_gcode_scan_axes(const char *text, size_t len, char *letters)
{
	int used[6] = {0}, k, n = 0;
	size_t i = 0, num;
	uint32_t line = 1;
	char L;

	while (next_word(text, len, &i, &line, &L, &num)) {
		k = axis_slot(L);
		if (k >= 0) {
			used[k] = 1;
		}
	}
	for (k = 0; k < 6; k++) {
		if (used[k]) {
			letters[n++] = axis_letters[k];
		}
	}
	letters[n] = '\0';
	return n;
}

uint32_t mlip_gcode_scan_feed(const char *text, size_t len, double *f_word)
{
	size_t s = 0, e;
	uint32_t line = 1;
	unsigned axes = 0;
	double f;

	/* line by line (LF, CRLF or a lone CR), as the tools' bounded reader sees
	 * it: a line too long to parse is an error, and its F is not taken */
	while (s < len) {
		for (e = s; e < len && text[e] != '\n' && text[e] != '\r'; e++) {
		}
		if (e - s <= MLIP_GCODE_MAX_LINE) {
			f = mlip_gcode_scan_line(text + s, e - s, &axes);
			if (f > 0) {
				*f_word = f;
				return line;
			}
		}
		line++;
		s = e + 1 + (e + 1 < len && text[e] == '\r' && text[e + 1] == '\n');
	}
	return 0;
}

double mlip_gcode_scan_line(const char *text, size_t len, unsigned *axes)
{
	size_t i = 0, num;
	uint32_t line = 1;
	double v, f = 0;
	int k, ndig;
	char L;

	while (next_word(text, len, &i, &line, &L, &num)) {
		k = axis_slot(L);
		if (k >= 0) {
			*axes |= 1u << k;
		}
		if (L == 'F' && !(f > 0)) {
			scan_number(text, len, num, &v, &ndig);
			f = ndig > 0 && v > 0 ? v : 0;
		}
	}
	return f;
}
