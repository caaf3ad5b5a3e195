/*
 * config.c - the machine configuration: a small INI reader for [TRAJ],
 * [AXIS_X]..[AXIS_C] and [CAN] (format in include/mlip/machine/config.h), and the
 * consistency check of a struct mlip_machine.
 *
 * Pure: reads the caller's buffer, writes the caller's struct; no allocation,
 * no stdio (messages are built by the sb_* helpers below) and no locale:
 * numbers are converted here because strtod accepts "nan", "inf", hex floats
 * and, under some locales, a decimal comma.
 *
 * Two passes. The first reads line by line and checks every byte, token and
 * single value where it stands, so that its errors point at a line and a
 * column. The second needs the whole file (sections may come in any order):
 * required sections and keys, axis sections against COORDINATES, values
 * against each other (through the same check as mlip_machine_check, its
 * error then placed on the key that set the value), CAN ids. Only then is
 * *c written, so a failed parse leaves it as it was.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "mlip/machine/config.h"
#include "mlip/motion/planner.h" /* MLIP_LOOKAHEAD: default and largest LOOKAHEAD */

#define TOK_SHOW         32     /* longest piece of input quoted in a message, bytes */
#define NKEYS            8      /* keys per section kind (every kind has eight) */
#define ID_MAX           0x7FFu /* largest 11-bit CAN id */
#define NODE_MAX         127
#define BITRATE_MIN      10000
#define BITRATE_MAX      1000000  /* classical CAN, and the CAN FD arbitration phase */
#define DATA_BITRATE_MAX 12000000 /* CAN FD data phase */
#define LIMIT_DEFAULT    1e9      /* soft limits when not given: none, in practice */

/* ---- messages: bounded, always NUL-terminated ---------------------------- */

struct sb {
	char *p;
	size_t n, cap;
};

static void sb_init(struct sb *b, char *buf, size_t cap)
{
	b->p = buf;
	b->n = 0;
	b->cap = cap;
	buf[0] = '\0';
}

static void sb_putc(struct sb *b, char ch)
{
	if (b->n + 1 < b->cap) {
		b->p[b->n++] = ch;
		b->p[b->n] = '\0';
	}
}

static void sb_puts(struct sb *b, const char *s)
{
	while (*s != '\0') {
		sb_putc(b, *s++);
	}
}

/* A piece of the input, cut to TOK_SHOW bytes on a character boundary so the
 * message stays valid UTF-8. */
static void sb_tok(struct sb *b, const char *s, size_t n)
{
	size_t i, cut = n;

	if (n > TOK_SHOW) {
		cut = TOK_SHOW;
		while (cut > 0 && ((unsigned char)s[cut] & 0xC0u) == 0x80u) {
			cut--;
		}
	}
	for (i = 0; i < cut; i++) {
		sb_putc(b, s[i]);
	}
	if (cut < n) {
		sb_puts(b, "...");
	}
}

static void sb_uint(struct sb *b, uint64_t v)
{
	char d[24];
	int k = 0;

	do {
		d[k++] = (char)('0' + v % 10);
		v /= 10;
	} while (v != 0);
	while (k > 0) {
		sb_putc(b, d[--k]);
	}
}

/* 0x and upper-case hex digits, at least ndig of them. */
static void sb_hex(struct sb *b, uint32_t v, int ndig)
{
	static const char hx[] = "0123456789ABCDEF";
	int shift = 28;

	sb_puts(b, "0x");
	while (shift >= 4 * ndig && (v >> shift) == 0) {
		shift -= 4;
	}
	for (; shift >= 0; shift -= 4) {
		sb_putc(b, hx[(v >> shift) & 0xFu]);
	}
}

/* One byte as 'c' when printable ASCII, else as 0xNN. */
static void sb_byte(struct sb *b, unsigned char ch)
{
	if (ch >= 0x21 && ch < 0x7F) {
		sb_putc(b, '\'');
		sb_putc(b, (char)ch);
		sb_putc(b, '\'');
	} else {
		sb_hex(b, ch, 2);
	}
}

/* A double the way %.9g prints it, with a shorter exponent ("1e9" for
 * "1e+09"): nine significant digits show anything typed in a config file
 * as typed, and this reader takes the result back. */
static void sb_double(struct sb *b, double x)
{
	char dig[10];
	uint64_t d = 0;
	int e, k, nd;

	if (isnan(x)) {
		sb_puts(b, "nan");
		return;
	}
	if (x < 0) {
		sb_putc(b, '-');
		x = -x;
	}
	if (isinf(x)) {
		sb_puts(b, "inf");
		return;
	}
	if (x == 0) {
		sb_putc(b, '0');
		return;
	}
	/* d = x / 10^(e-8) rounded, 10^8 <= d < 10^9; log10 may be off by one */
	e = (int)floor(log10(x));
	for (k = 0; k < 3; k++) {
		int p = e - 8;
		double s = x;
		if (p < -290) { /* keep 10^p a normal double */
			s *= 1e100;
			p += 100;
		}
		d = (uint64_t)llround(s / pow(10.0, p));
		if (d >= 1000000000u) {
			e++;
		} else if (d < 100000000u) {
			e--;
		} else {
			break;
		}
	}
	for (k = 8; k >= 0; k--) {
		dig[k] = (char)('0' + d % 10);
		d /= 10;
	}
	for (nd = 9; nd > 1 && dig[nd - 1] == '0'; nd--) {
	}
	if (e >= -4 && e < 9) {
		if (e < 0) {
			sb_puts(b, "0.");
			for (k = -1; k > e; k--) {
				sb_putc(b, '0');
			}
			for (k = 0; k < nd; k++) {
				sb_putc(b, dig[k]);
			}
		} else {
			for (k = 0; k <= e; k++) {
				sb_putc(b, k < nd ? dig[k] : '0');
			}
			if (nd > e + 1) {
				sb_putc(b, '.');
				for (k = e + 1; k < nd; k++) {
					sb_putc(b, dig[k]);
				}
			}
		}
		return;
	}
	sb_putc(b, dig[0]);
	if (nd > 1) {
		sb_putc(b, '.');
		for (k = 1; k < nd; k++) {
			sb_putc(b, dig[k]);
		}
	}
	sb_putc(b, 'e');
	if (e < 0) {
		sb_putc(b, '-');
		e = -e;
	}
	sb_uint(b, (uint64_t)e);
}

/* Start an error message at line:col (0: not applicable). */
static void err_at(struct mlip_config_error *err, struct sb *b, uint32_t line, uint32_t col)
{
	err->line = line;
	err->col = col;
	sb_init(b, err->msg, sizeof err->msg);
}

/* ---- numbers ----------------------------------------------------------- */

static int is_digit(char ch)
{
	return ch >= '0' && ch <= '9';
}

static int hex_val(char ch)
{
	if (is_digit(ch)) {
		return ch - '0';
	}
	if (ch >= 'a' && ch <= 'f') {
		return ch - 'a' + 10;
	}
	if (ch >= 'A' && ch <= 'F') {
		return ch - 'A' + 10;
	}
	return -1;
}

/* The whole token as a decimal: [+-] (D+ [. D*] | . D+) [(e|E) [+-] D+].
 * Returns 0 with *out, -1 when malformed, -2 when it overflows a double.
 * Keeps 19 significant digits m and an exponent e, value m * 10^e. With
 * m <= 2^53 and |e| <= 22 (any sane config value) both factors are exact
 * doubles and one operation rounds once, so the result is the correctly
 * rounded one, as from strtod (Clinger's fast path); beyond that a few
 * ulps, which no machine limit will notice. Plain double arithmetic, so
 * valgrind (which runs long double as double) sees the same numbers. */
static int parse_real(const char *s, size_t n, double *out)
{
	static const double p10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
	                               1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
	                               1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
	size_t i = 0;
	uint64_t m = 0;
	long e10 = 0;
	int neg = 0, nd = 0, any = 0;
	double v;

	if (i < n && (s[i] == '+' || s[i] == '-')) {
		neg = s[i] == '-';
		i++;
	}
	for (; i < n && is_digit(s[i]); i++) {
		any = 1;
		if (nd < 19) {
			m = m * 10 + (uint64_t)(s[i] - '0');
			nd += m != 0; /* leading zeros are not significant */
		} else {
			e10++;
		}
	}
	if (i < n && s[i] == '.') {
		for (i++; i < n && is_digit(s[i]); i++) {
			any = 1;
			if (nd < 19) {
				m = m * 10 + (uint64_t)(s[i] - '0');
				nd += m != 0;
				e10--;
			}
		}
	}
	if (!any) {
		return -1;
	}
	if (i < n && (s[i] == 'e' || s[i] == 'E')) {
		long x = 0;
		int eneg = 0, eany = 0;
		i++;
		if (i < n && (s[i] == '+' || s[i] == '-')) {
			eneg = s[i] == '-';
			i++;
		}
		for (; i < n && is_digit(s[i]); i++) {
			eany = 1;
			if (x < 100000) { /* saturate: 1e100000 is out of range anyway */
				x = x * 10 + (s[i] - '0');
			}
		}
		if (!eany) {
			return -1;
		}
		e10 += eneg ? -x : x;
	}
	if (i != n) {
		return -1;
	}
	if (m == 0) {
		v = 0.0;
	} else if (m <= (1ull << 53) && e10 >= -22 && e10 <= 22) {
		v = e10 >= 0 ? (double)m * p10[e10] : (double)m / p10[-e10];
	} else {
		/* m = mant 10^d, mant in [1, 10): with the value's own exponent
		 * E = e10 + d, 10^E is a normal double wherever the value is */
		uint64_t t = m;
		long d = 0, ex;
		double mant;
		while (t >= 10) {
			t /= 10;
			d++;
		}
		mant = (double)m / p10[d];
		ex = e10 + d;
		if (ex > 308) {
			v = HUGE_VAL;
		} else if (ex < -340) {
			v = 0.0;
		} else if (ex < -300) { /* a subnormal result: scale in two steps */
			v = mant * pow(10.0, (double)(ex + 40)) * 1e-40;
		} else {
			v = mant * pow(10.0, (double)ex);
		}
	}
	if (!isfinite(v)) {
		return -2;
	}
	*out = neg ? -v : v;
	return 0;
}

/* The whole token as an integer: [+-] (D+ | 0x H+), decimal even with a
 * leading 0. Returns 0 with *out (saturated at +-2^40, far outside every
 * range checked), -1 when malformed. */
static int parse_int(const char *s, size_t n, int64_t *out)
{
	const int64_t cap = (int64_t)1 << 40;
	size_t i = 0;
	int64_t v = 0;
	int neg = 0, base = 10, any = 0;

	if (i < n && (s[i] == '+' || s[i] == '-')) {
		neg = s[i] == '-';
		i++;
	}
	if (i + 1 < n && s[i] == '0' && (s[i + 1] == 'x' || s[i + 1] == 'X')) {
		base = 16;
		i += 2;
	}
	for (; i < n; i++) {
		int d = hex_val(s[i]);
		if (d < 0 || d >= base) {
			return -1;
		}
		any = 1;
		if (v < cap) {
			v = v * base + d;
		}
	}
	if (!any) {
		return -1;
	}
	if (v > cap) {
		v = cap;
	}
	*out = neg ? -v : v;
	return 0;
}

/* ---- sections and keys --------------------------------------------------- */

static const char axis_letters[] = "XYZABC";

/* Sections by index: TRAJ, one per axis letter (XYZABC order), CAN. */
enum { SEC_TRAJ = 0, SEC_AXIS0 = 1, SEC_CAN = SEC_AXIS0 + MLIP_MAX_AXES, SEC_DRIVES, N_SEC };
enum { K_TRAJ, K_AXIS, K_CAN, K_DRIVES, N_KINDS };

enum { TK_COORDS, TK_VLIN, TK_VANG, TK_TOL, TK_PERIOD, TK_LUNITS, TK_AUNITS, TK_LOOKAHEAD };
enum { AK_TYPE, AK_VEL, AK_ACC, AK_MIN, AK_MAX, AK_HOME, AK_NODE, AK_CPU };
enum { CK_PROFILE, CK_BITRATE, CK_DBITRATE, CK_SYNC, CK_RPDO, CK_PACKED, CK_FD, CK_STATUS };
enum { DK_ENABLE, DK_MASTER, DK_HB, DK_HB_TIMEOUT, DK_FERR, DK_SDO, DK_BOOT, DK_STATE };

/* How a value is read and which single-value range it must meet. */
enum vtype {
	V_COORDS,    /* axis letters */
	V_POS,       /* decimal > 0 */
	V_REAL,      /* any decimal */
	V_PERIOD,    /* decimal in [PERIOD_MIN, PERIOD_MAX] */
	V_LUNITS,    /* "mm" */
	V_AUNITS,    /* "degree" */
	V_LOOKAHEAD, /* power of two in 2..MLIP_LOOKAHEAD */
	V_TYPE,      /* LINEAR | ANGULAR */
	V_NODE,      /* integer 1..127 */
	V_PROFILE,   /* cia402 | packed | fd */
	V_BITRATE,   /* integer BITRATE_MIN..BITRATE_MAX */
	V_DBITRATE,  /* integer BITRATE_MIN..DATA_BITRATE_MAX */
	V_ID,        /* integer 0..0x7FF */
	V_BOOL,      /* 0 | 1 */
	V_MS         /* integer 1..65535 (CiA 301 heartbeat times are 16-bit ms) */
};

struct keydef {
	const char *name;
	unsigned char type;
	unsigned char required;
};

static const struct keydef keytab[N_KINDS][NKEYS] = {
    [K_TRAJ] = {{"COORDINATES", V_COORDS, 1},
                {"MAX_LINEAR_VELOCITY", V_POS, 1},
                {"MAX_ANGULAR_VELOCITY", V_POS, 0},
                {"CONTOUR_TOLERANCE", V_POS, 1},
                {"PERIOD", V_PERIOD, 0},
                {"LINEAR_UNITS", V_LUNITS, 0},
                {"ANGULAR_UNITS", V_AUNITS, 0},
                {"LOOKAHEAD", V_LOOKAHEAD, 0}},
    [K_AXIS] = {{"TYPE", V_TYPE, 0},
                {"MAX_VELOCITY", V_POS, 1},
                {"MAX_ACCELERATION", V_POS, 1},
                {"MIN_LIMIT", V_REAL, 0},
                {"MAX_LIMIT", V_REAL, 0},
                {"HOME", V_REAL, 0},
                {"CAN_NODE", V_NODE, 0},
                {"COUNTS_PER_UNIT", V_POS, 0}},
    [K_CAN] = {{"PROFILE", V_PROFILE, 0},
               {"BITRATE", V_BITRATE, 0},
               {"DATA_BITRATE", V_DBITRATE, 0},
               {"SYNC_ID", V_ID, 0},
               {"RPDO_BASE", V_ID, 0},
               {"PACKED_BASE", V_ID, 0},
               {"FD_ID", V_ID, 0},
               {"STATUS_ID", V_ID, 0}},
    [K_DRIVES] = {{"ENABLE", V_BOOL, 0},
                  {"MASTER_NODE", V_NODE, 0},
                  {"HEARTBEAT_MS", V_MS, 0},
                  {"HEARTBEAT_TIMEOUT_MS", V_MS, 0},
                  {"FOLLOWING_ERROR", V_POS, 0},
                  {"SDO_TIMEOUT_MS", V_MS, 0},
                  {"BOOT_TIMEOUT_MS", V_MS, 0},
                  {"STATE_TIMEOUT_MS", V_MS, 0}},
};

static const char *const profiles[] = {"cia402", "packed", "fd"};

static int sec_kind(int sec)
{
	return sec == SEC_TRAJ     ? K_TRAJ
	       : sec == SEC_CAN    ? K_CAN
	       : sec == SEC_DRIVES ? K_DRIVES
	                           : K_AXIS;
}

static int letter_index(char l)
{
	int i;

	for (i = 0; i < MLIP_MAX_AXES; i++) {
		if (axis_letters[i] == l) {
			return i;
		}
	}
	return -1;
}

/* "TRAJ", "CAN", "AXIS_X", ... */
static void sb_secname(struct sb *b, int sec)
{
	if (sec == SEC_TRAJ) {
		sb_puts(b, "TRAJ");
	} else if (sec == SEC_CAN) {
		sb_puts(b, "CAN");
	} else if (sec == SEC_DRIVES) {
		sb_puts(b, "DRIVES");
	} else {
		sb_puts(b, "AXIS_");
		sb_putc(b, axis_letters[sec - SEC_AXIS0]);
	}
}

/* ---- did you mean ------------------------------------------------------- */

static char upper(char ch)
{
	return ch >= 'a' && ch <= 'z' ? (char)(ch - 'a' + 'A') : ch;
}

#define SUGGEST_MAX 40 /* longer names get no suggestion */

/* Optimal-string-alignment distance (edits and swaps of neighbours),
 * ignoring case. */
static int edit_distance(const char *a, size_t na, const char *b, size_t nb)
{
	int row0[SUGGEST_MAX + 1], row1[SUGGEST_MAX + 1], row2[SUGGEST_MAX + 1];
	int *pp = row0, *pr = row1, *cur = row2;
	size_t i, j;

	for (j = 0; j <= nb; j++) {
		pr[j] = (int)j;
	}
	for (i = 1; i <= na; i++) {
		int *t;
		cur[0] = (int)i;
		for (j = 1; j <= nb; j++) {
			int sub = upper(a[i - 1]) != upper(b[j - 1]);
			int v = pr[j - 1] + sub;
			if (pr[j] + 1 < v) {
				v = pr[j] + 1;
			}
			if (cur[j - 1] + 1 < v) {
				v = cur[j - 1] + 1;
			}
			if (i > 1 && j > 1 && upper(a[i - 1]) == upper(b[j - 2]) &&
			    upper(a[i - 2]) == upper(b[j - 1]) && pp[j - 2] + 1 < v) {
				v = pp[j - 2] + 1;
			}
			cur[j] = v;
		}
		t = pp;
		pp = pr;
		pr = cur;
		cur = t;
	}
	return pr[nb];
}

static int prefix_fold(const char *a, size_t na, const char *b, size_t nb)
{
	size_t i, n = na < nb ? na : nb;

	for (i = 0; i < n; i++) {
		if (upper(a[i]) != upper(b[i])) {
			return 0;
		}
	}
	return 1;
}

/* The candidate the user most likely meant by s[0..n): the one equal
 * ignoring case, else the only one that s abbreviates or extends (4 letters
 * in common at least: MAX_ACCEL -> MAX_ACCELERATION), else the nearest within
 * a few edits. NULL when nothing is close. */
static const char *suggest(const char *s, size_t n, const char *const *cand, int ncand)
{
	const char *best = NULL, *pre = NULL;
	int i, npre = 0, bestd = n < 5 ? 2 : n < 10 ? 3 : 4; /* distance must be below */

	if (n > SUGGEST_MAX) {
		return NULL;
	}
	for (i = 0; i < ncand; i++) {
		size_t nc = strlen(cand[i]);
		if (nc <= SUGGEST_MAX && (n < nc ? n : nc) >= 4 && prefix_fold(s, n, cand[i], nc)) {
			pre = cand[i];
			npre++;
		}
	}
	for (i = 0; i < ncand; i++) {
		size_t nc = strlen(cand[i]);
		int d;
		if (nc > SUGGEST_MAX) {
			continue;
		}
		d = edit_distance(s, n, cand[i], nc);
		if (d == 0) {
			return cand[i];
		}
		if (d < bestd) {
			bestd = d;
			best = cand[i];
		}
	}
	return npre == 1 ? pre : best;
}

/* ---- parse state ---------------------------------------------------------- */

struct pos {
	uint32_t line, col; /* line 0: not given */
};

struct sec {
	struct pos at;         /* the header, at the section name */
	unsigned seen;         /* bit k: key k given */
	struct pos key[NKEYS]; /* where each given key stands */
	double num[NKEYS];     /* decimal values */
	int64_t ival[NKEYS];   /* integer and enumerated values */
};

struct pstate {
	struct sec sec[N_SEC];
	int cur; /* section of the lines read, -1 before any */
	int n_coords;
	char coords[MLIP_MAX_AXES]; /* COORDINATES, in order */
	uint32_t coord_col[MLIP_MAX_AXES];
};

static int has(const struct pstate *ps, int sec, int key)
{
	return (ps->sec[sec].seen >> key) & 1u;
}

/* ---- the first pass: one line ------------------------------------------- */

static int is_ws(char ch)
{
	return ch == ' ' || ch == '\t';
}

static int is_keych(char ch)
{
	return (ch >= 'A' && ch <= 'Z') || (ch >= 'a' && ch <= 'z') || is_digit(ch) || ch == '_';
}

static size_t skip_ws(const char *s, size_t n, size_t p)
{
	while (p < n && is_ws(s[p])) {
		p++;
	}
	return p;
}

static int tok_is(const char *s, size_t n, const char *word)
{
	return strlen(word) == n && memcmp(s, word, n) == 0;
}

/* Length of the UTF-8 character at s[0..n) (RFC 3629: no overlong forms,
 * no surrogates, nothing above U+10FFFF), 0 when invalid. */
static size_t utf8_len(const unsigned char *s, size_t n)
{
	unsigned c = s[0], lo = 0x80, hi = 0xBF;
	size_t k, need;

	if (c < 0x80) {
		return 1;
	} else if (c >= 0xC2 && c <= 0xDF) {
		need = 1;
	} else if (c == 0xE0) {
		need = 2;
		lo = 0xA0;
	} else if (c == 0xED) {
		need = 2;
		hi = 0x9F;
	} else if (c >= 0xE1 && c <= 0xEF) {
		need = 2;
	} else if (c == 0xF0) {
		need = 3;
		lo = 0x90;
	} else if (c == 0xF4) {
		need = 3;
		hi = 0x8F;
	} else if (c >= 0xF1 && c <= 0xF3) {
		need = 3;
	} else {
		return 0;
	}
	if (n < need + 1) {
		return 0;
	}
	for (k = 1; k <= need; k++) {
		unsigned x = s[k];
		if (x < (k == 1 ? lo : 0x80u) || x > (k == 1 ? hi : 0xBFu)) {
			return 0;
		}
	}
	return need + 1;
}

/* Bytes of one line: UTF-8, no NUL, no control character but tab, not too
 * long. */
static mlip_status check_bytes(const char *s, size_t n, uint32_t line,
                               struct mlip_config_error *err)
{
	const unsigned char *u = (const unsigned char *)s;
	size_t j = 0, lim = n < MLIP_CONFIG_MAX_LINE ? n : MLIP_CONFIG_MAX_LINE;
	struct sb b;

	while (j < lim) {
		size_t k;
		if (u[j] == 0) {
			err_at(err, &b, line, (uint32_t)j + 1);
			sb_puts(&b, "NUL byte (is this a text file?)");
			return MLIP_E_SYNTAX;
		}
		if ((u[j] < 0x20 && u[j] != '\t') || u[j] == 0x7F) {
			err_at(err, &b, line, (uint32_t)j + 1);
			sb_puts(&b, "control character ");
			sb_hex(&b, u[j], 2);
			sb_puts(&b, u[j] == '\r' ? " (a CR not followed by LF)"
			                         : " (only tab is allowed)");
			return MLIP_E_SYNTAX;
		}
		k = utf8_len(u + j, n - j);
		if (k == 0) {
			err_at(err, &b, line, (uint32_t)j + 1);
			sb_puts(&b, "invalid UTF-8 byte ");
			sb_hex(&b, u[j], 2);
			sb_puts(&b, " (save the file as UTF-8)");
			return MLIP_E_SYNTAX;
		}
		j += k;
	}
	if (n > MLIP_CONFIG_MAX_LINE) {
		err_at(err, &b, line, MLIP_CONFIG_MAX_LINE + 1);
		sb_puts(&b, "line too long (");
		sb_uint(&b, n);
		sb_puts(&b, " bytes, at most ");
		sb_uint(&b, MLIP_CONFIG_MAX_LINE);
		sb_putc(&b, ')');
		return MLIP_E_SYNTAX;
	}
	return MLIP_OK;
}

/* "[NAME]" at s[p]: known, not seen before, nothing but a comment after. */
static mlip_status parse_header(struct pstate *ps, const char *s, size_t n, size_t p, uint32_t line,
                                struct mlip_config_error *err)
{
	static const char *const names[] = {"TRAJ",   "AXIS_X", "AXIS_Y", "AXIS_Z", "AXIS_A",
	                                    "AXIS_B", "AXIS_C", "CAN",    "DRIVES"};
	size_t q = p + 1, r, a, z;
	struct sb b;
	int sec;

	for (r = q; r < n && s[r] != ']'; r++) {
	}
	if (r == n) {
		err_at(err, &b, line, (uint32_t)p + 1);
		sb_puts(&b, "missing ']' in section header");
		return MLIP_E_SYNTAX;
	}
	a = skip_ws(s, r, q);
	for (z = r; z > a && is_ws(s[z - 1]); z--) {
	}
	if (a == z) {
		err_at(err, &b, line, (uint32_t)p + 1);
		sb_puts(&b, "empty section name");
		return MLIP_E_SYNTAX;
	}
	q = skip_ws(s, n, r + 1);
	if (q < n && s[q] != '#' && s[q] != ';') {
		err_at(err, &b, line, (uint32_t)q + 1);
		sb_puts(&b, "unexpected ");
		sb_byte(&b, (unsigned char)s[q]);
		sb_puts(&b, " after section header (comments start with # or ;)");
		return MLIP_E_SYNTAX;
	}
	for (sec = 0; sec < N_SEC; sec++) {
		if (tok_is(s + a, z - a, names[sec])) {
			break;
		}
	}
	if (sec == N_SEC) {
		/* [AXIS_W]: no nearest letter to suggest, the letters are the news */
		int bad_letter = z - a == 6 && memcmp(s + a, "AXIS_", 5) == 0 &&
		                 letter_index(upper(s[a + 5])) < 0;
		const char *hint = bad_letter ? NULL : suggest(s + a, z - a, names, N_SEC);
		err_at(err, &b, line, (uint32_t)a + 1);
		sb_puts(&b, "unknown section [");
		sb_tok(&b, s + a, z - a);
		sb_putc(&b, ']');
		if (bad_letter) {
			sb_puts(&b, " (axis letters are X Y Z A B C)");
		} else if (hint != NULL) {
			sb_puts(&b, " (did you mean [");
			sb_puts(&b, hint);
			sb_puts(&b, "]?)");
		} else {
			sb_puts(&b, " (sections are [TRAJ], [AXIS_X]..[AXIS_C], [CAN], [DRIVES])");
		}
		return MLIP_E_SYNTAX;
	}
	if (ps->sec[sec].at.line != 0) {
		err_at(err, &b, line, (uint32_t)a + 1);
		sb_puts(&b, "duplicate section [");
		sb_puts(&b, names[sec]);
		sb_puts(&b, "] (first at line ");
		sb_uint(&b, ps->sec[sec].at.line);
		sb_putc(&b, ')');
		return MLIP_E_SYNTAX;
	}
	ps->sec[sec].at.line = line;
	ps->sec[sec].at.col = (uint32_t)a + 1;
	ps->cur = sec;
	return MLIP_OK;
}

/* Where a key that is not in the current section's table belongs, if it
 * belongs anywhere: "[TRAJ]", "an [AXIS_*] section", "[CAN]". */
static const char *home_of(const char *s, size_t n, int except_kind)
{
	static const char *const where[N_KINDS] = {"[TRAJ]", "an [AXIS_*] section", "[CAN]",
	                                           "[DRIVES]"};
	int kd, k;

	for (kd = 0; kd < N_KINDS; kd++) {
		for (k = 0; kd != except_kind && k < NKEYS; k++) {
			if (tok_is(s, n, keytab[kd][k].name)) {
				return where[kd];
			}
		}
	}
	return NULL;
}

/* "KEY must be within LO..HI UNIT, got TOKEN" */
static mlip_status range_err(struct mlip_config_error *err, uint32_t line, uint32_t col,
                             const char *key, const char *what, const char *tok, size_t ntok)
{
	struct sb b;

	err_at(err, &b, line, col);
	sb_puts(&b, key);
	sb_puts(&b, what);
	sb_puts(&b, ", got ");
	sb_tok(&b, tok, ntok);
	return MLIP_E_RANGE;
}

static mlip_status parse_coords(struct pstate *ps, const char *v, size_t nv, uint32_t line,
                                uint32_t col0, struct mlip_config_error *err)
{
	size_t q;
	struct sb b;
	int i, n = 0;

	for (q = 0; q < nv; q++) {
		char l = v[q];
		int li;
		if (is_ws(l)) {
			continue;
		}
		li = letter_index(l);
		if (li < 0) {
			size_t k = utf8_len((const unsigned char *)v + q, nv - q);
			err_at(err, &b, line, col0 + (uint32_t)q);
			sb_putc(&b, '\'');
			sb_tok(&b, v + q, k);
			sb_puts(&b, "' in COORDINATES is not an axis letter");
			sb_puts(&b, " (X Y Z A B C, upper case)");
			return MLIP_E_SYNTAX;
		}
		for (i = 0; i < n; i++) {
			if (ps->coords[i] == l) {
				err_at(err, &b, line, col0 + (uint32_t)q);
				sb_puts(&b, "duplicate axis letter ");
				sb_putc(&b, l);
				sb_puts(&b, " in COORDINATES");
				return MLIP_E_SYNTAX;
			}
		}
		/* six distinct letters at most, so n < MLIP_MAX_AXES here */
		ps->coords[n] = l;
		ps->coord_col[n] = col0 + (uint32_t)q;
		n++;
	}
	if (n < 2) {
		err_at(err, &b, line, col0);
		sb_puts(&b, "COORDINATES must have 2 to 6 axes, got ");
		sb_uint(&b, (uint64_t)n);
		return MLIP_E_RANGE;
	}
	ps->n_coords = n;
	return MLIP_OK;
}

/* Read the value v[0..nv) of key k of section sec, at line:col. */
static mlip_status parse_value(struct pstate *ps, int sec, int k, const char *v, size_t nv,
                               uint32_t line, uint32_t col, struct mlip_config_error *err)
{
	const struct keydef *kd = &keytab[sec_kind(sec)][k];
	struct sec *st = &ps->sec[sec];
	struct sb b;
	double x = 0;
	int64_t i = 0;
	int rc;

	switch (kd->type) {
	case V_COORDS:
		return parse_coords(ps, v, nv, line, col, err);
	case V_POS:
	case V_REAL:
	case V_PERIOD:
		rc = parse_real(v, nv, &x);
		if (rc != 0) {
			err_at(err, &b, line, col);
			sb_puts(&b, rc == -1 ? "malformed number '" : "number out of range '");
			sb_tok(&b, v, nv);
			sb_puts(&b, "' for ");
			sb_puts(&b, kd->name);
			if (rc == -1) {
				sb_puts(&b, " (a plain decimal like 200, 0.5 or 1e-3, no units)");
			}
			return rc == -1 ? MLIP_E_SYNTAX : MLIP_E_RANGE;
		}
		if (kd->type == V_POS && !(x > 0)) {
			return range_err(err, line, col, kd->name, " must be > 0", v, nv);
		}
		if (kd->type == V_PERIOD &&
		    !(x >= MLIP_CONFIG_PERIOD_MIN_S && x <= MLIP_CONFIG_PERIOD_MAX_S)) {
			return range_err(err, line, col, kd->name, " must be within 0.0001..0.1 s",
			                 v, nv);
		}
		st->num[k] = x;
		return MLIP_OK;
	case V_LUNITS:
		if (tok_is(v, nv, "mm")) {
			return MLIP_OK;
		}
		err_at(err, &b, line, col);
		if (tok_is(v, nv, "inch") || tok_is(v, nv, "in") || tok_is(v, nv, "imperial")) {
			sb_puts(&b, "LINEAR_UNITS ");
			sb_tok(&b, v, nv);
			sb_puts(&b, " is not supported: convert every length to mm");
			sb_puts(&b, " (1 inch = 25.4 mm)");
			return MLIP_E_UNSUPPORTED;
		}
		sb_puts(&b, "LINEAR_UNITS must be mm, got '");
		sb_tok(&b, v, nv);
		sb_putc(&b, '\'');
		return MLIP_E_SYNTAX;
	case V_AUNITS:
		if (tok_is(v, nv, "degree")) {
			return MLIP_OK;
		}
		err_at(err, &b, line, col);
		if (tok_is(v, nv, "radian") || tok_is(v, nv, "grad")) {
			sb_puts(&b, "ANGULAR_UNITS ");
			sb_tok(&b, v, nv);
			sb_puts(&b, " is not supported: convert every angle to degrees");
			return MLIP_E_UNSUPPORTED;
		}
		sb_puts(&b, "ANGULAR_UNITS must be degree, got '");
		sb_tok(&b, v, nv);
		sb_putc(&b, '\'');
		return MLIP_E_SYNTAX;
	case V_TYPE:
	case V_PROFILE:
		if (kd->type == V_TYPE) {
			i = tok_is(v, nv, "LINEAR")    ? MLIP_AXIS_LINEAR
			    : tok_is(v, nv, "ANGULAR") ? MLIP_AXIS_ROTARY
			                               : -1;
		} else {
			for (i = 2; i >= 0 && !tok_is(v, nv, profiles[i]); i--) {
			}
		}
		if (i < 0) {
			err_at(err, &b, line, col);
			sb_puts(&b, kd->name);
			sb_puts(&b, kd->type == V_TYPE ? " must be LINEAR or ANGULAR, got '"
			                               : " must be cia402, packed or fd, got '");
			sb_tok(&b, v, nv);
			sb_putc(&b, '\'');
			return MLIP_E_SYNTAX;
		}
		st->ival[k] = i;
		return MLIP_OK;
	default: /* integers */
		if (parse_int(v, nv, &i) != 0) {
			err_at(err, &b, line, col);
			sb_puts(&b, "malformed integer '");
			sb_tok(&b, v, nv);
			sb_puts(&b, "' for ");
			sb_puts(&b, kd->name);
			sb_puts(&b, " (decimal digits or 0x hex)");
			return MLIP_E_SYNTAX;
		}
		if (kd->type == V_LOOKAHEAD &&
		    (i < 2 || i > MLIP_LOOKAHEAD || (i & (i - 1)) != 0)) {
			/* MLIP_LOOKAHEAD is 4096 unless a build overrides it */
			err_at(err, &b, line, col);
			sb_puts(&b, "LOOKAHEAD must be a power of two within 2..");
			sb_uint(&b, MLIP_LOOKAHEAD);
			sb_puts(&b, ", got ");
			sb_tok(&b, v, nv);
			return MLIP_E_RANGE;
		}
		if (kd->type == V_NODE && (i < 1 || i > NODE_MAX)) {
			return range_err(err, line, col, kd->name, " must be within 1..127", v, nv);
		}
		if (kd->type == V_BITRATE && (i < BITRATE_MIN || i > BITRATE_MAX)) {
			return range_err(err, line, col, kd->name,
			                 " must be within 10000..1000000 bit/s", v, nv);
		}
		if (kd->type == V_DBITRATE && (i < BITRATE_MIN || i > DATA_BITRATE_MAX)) {
			return range_err(err, line, col, kd->name,
			                 " must be within 10000..12000000 bit/s", v, nv);
		}
		if (kd->type == V_BOOL && i != 0 && i != 1) {
			return range_err(err, line, col, kd->name, " must be 0 or 1", v, nv);
		}
		if (kd->type == V_MS && (i < 1 || i > 65535)) {
			return range_err(err, line, col, kd->name, " must be within 1..65535 ms", v,
			                 nv);
		}
		if (kd->type == V_ID && (i < 0 || i > (int64_t)ID_MAX)) {
			return range_err(err, line, col, kd->name,
			                 " must be within 0..0x7FF (11-bit id)", v, nv);
		}
		st->ival[k] = i;
		return MLIP_OK;
	}
}

static mlip_status parse_line(struct pstate *ps, const char *s, size_t n, uint32_t line,
                              struct mlip_config_error *err)
{
	const char *names[NKEYS];
	size_t p = skip_ws(s, n, 0), k0, nk, v0, v1;
	struct sb b;
	int kind, k;

	if (p == n || s[p] == '#' || s[p] == ';') {
		return MLIP_OK;
	}
	if (s[p] == '[') {
		return parse_header(ps, s, n, p, line, err);
	}
	if (!is_keych(s[p])) {
		err_at(err, &b, line, (uint32_t)p + 1);
		sb_puts(&b, "expected KEY = VALUE, a [SECTION] or a comment, got ");
		sb_byte(&b, (unsigned char)s[p]);
		return MLIP_E_SYNTAX;
	}
	for (k0 = p; p < n && is_keych(s[p]); p++) {
	}
	nk = p - k0;
	p = skip_ws(s, n, p);
	if (p == n || s[p] != '=') {
		err_at(err, &b, line, (uint32_t)p + 1);
		if (p == n) {
			sb_puts(&b, "missing '=' after key ");
			sb_tok(&b, s + k0, nk);
		} else {
			sb_puts(&b, "expected '=' after key ");
			sb_tok(&b, s + k0, nk);
			sb_puts(&b, ", got ");
			sb_byte(&b, (unsigned char)s[p]);
		}
		return MLIP_E_SYNTAX;
	}
	/* the value: up to a '#' or ';' that starts it or follows a blank */
	v0 = skip_ws(s, n, p + 1);
	for (v1 = v0; v1 < n; v1++) {
		if ((s[v1] == '#' || s[v1] == ';') && (v1 == v0 || is_ws(s[v1 - 1]))) {
			break;
		}
	}
	while (v1 > v0 && is_ws(s[v1 - 1])) {
		v1--;
	}

	if (ps->cur < 0) {
		const char *where = home_of(s + k0, nk, -1);
		err_at(err, &b, line, (uint32_t)k0 + 1);
		sb_puts(&b, "key ");
		sb_tok(&b, s + k0, nk);
		sb_puts(&b, " outside any section");
		if (where != NULL) {
			sb_puts(&b, " (it belongs in ");
			sb_puts(&b, where);
			sb_putc(&b, ')');
		}
		return MLIP_E_SYNTAX;
	}
	kind = sec_kind(ps->cur);
	for (k = 0; k < NKEYS; k++) {
		names[k] = keytab[kind][k].name;
		if (tok_is(s + k0, nk, names[k])) {
			break;
		}
	}
	if (k == NKEYS) {
		const char *hint = suggest(s + k0, nk, names, NKEYS);
		const char *where = hint == NULL ? home_of(s + k0, nk, kind) : NULL;
		err_at(err, &b, line, (uint32_t)k0 + 1);
		sb_puts(&b, "unknown key ");
		sb_tok(&b, s + k0, nk);
		sb_puts(&b, " in [");
		sb_secname(&b, ps->cur);
		sb_putc(&b, ']');
		if (hint != NULL) {
			sb_puts(&b, " (did you mean ");
			sb_puts(&b, hint);
			sb_puts(&b, "?)");
		} else if (where != NULL) {
			sb_puts(&b, " (it belongs in ");
			sb_puts(&b, where);
			sb_putc(&b, ')');
		}
		return MLIP_E_SYNTAX;
	}
	if (has(ps, ps->cur, k)) {
		err_at(err, &b, line, (uint32_t)k0 + 1);
		sb_puts(&b, "duplicate key ");
		sb_puts(&b, names[k]);
		sb_puts(&b, " in [");
		sb_secname(&b, ps->cur);
		sb_puts(&b, "] (first at line ");
		sb_uint(&b, ps->sec[ps->cur].key[k].line);
		sb_putc(&b, ')');
		return MLIP_E_SYNTAX;
	}
	if (v1 == v0) {
		err_at(err, &b, line, (uint32_t)v0 + 1);
		sb_puts(&b, "missing value for ");
		sb_puts(&b, names[k]);
		return MLIP_E_SYNTAX;
	}
	ps->sec[ps->cur].seen |= 1u << k;
	ps->sec[ps->cur].key[k].line = line;
	ps->sec[ps->cur].key[k].col = (uint32_t)k0 + 1;
	return parse_value(ps, ps->cur, k, s + v0, v1 - v0, line, (uint32_t)v0 + 1, err);
}

/* ---- the machine check, shared by both entry points ----------------------- */

/* What a failed check is about, so that the parser can point at the keys
 * that set the values: axis index (-1: TRAJ), key (AK_* or TK_*), the other
 * axis of a CAN_NODE clash. */
struct issue {
	int axis, key, axis2;
};

static void sb_field(struct sb *b, const struct mlip_machine *m, int axis, int key)
{
	if (axis < 0) {
		sb_puts(b, "TRAJ ");
		sb_puts(b, keytab[K_TRAJ][key].name);
	} else {
		sb_puts(b, "AXIS_");
		sb_putc(b, m->axis[axis].letter);
		sb_putc(b, ' ');
		sb_puts(b, keytab[K_AXIS][key].name);
	}
}

/* A limit: finite and > 0. */
static int bad_pos(struct sb *b, const struct mlip_machine *m, int axis, int key, double v)
{
	if (isfinite(v) && v > 0) {
		return 0;
	}
	sb_field(b, m, axis, key);
	sb_puts(b, isfinite(v) ? " must be > 0, got " : " must be finite, got ");
	sb_double(b, v);
	return 1;
}

static int bad_finite(struct sb *b, const struct mlip_machine *m, int axis, int key, double v)
{
	if (isfinite(v)) {
		return 0;
	}
	sb_field(b, m, axis, key);
	sb_puts(b, " must be finite, got ");
	sb_double(b, v);
	return 1;
}

/* A limit at most max ("must be at most 1e6, got 2e6"). */
static int bad_max(struct sb *b, const struct mlip_machine *m, int axis, int key, double v,
                   double max)
{
	if (v <= max) {
		return 0;
	}
	sb_field(b, m, axis, key);
	sb_puts(b, " must be at most ");
	sb_double(b, max);
	sb_puts(b, ", got ");
	sb_double(b, v);
	return 1;
}

/* |x| at most MLIP_CONFIG_LIMIT_MAX. */
static int bad_abs(struct sb *b, const struct mlip_machine *m, int axis, int key, double v)
{
	if (fabs(v) <= MLIP_CONFIG_LIMIT_MAX) {
		return 0;
	}
	sb_field(b, m, axis, key);
	sb_puts(b, " must be within -1e9..1e9, got ");
	sb_double(b, v);
	return 1;
}

/*
 * The period against the contour tolerance. Each setpoint lies on the planned
 * curve, which stays within eps of the polyline ((17)(18): a corner of
 * acceleration a lasting t_m deviates by |a| t_m^2 / 8). Between two
 * setpoints, though, a drive in cyclic synchronous position mode moves in a
 * straight line, and a motion with |acceleration| <= a departs from the chord
 * of one period by up to a T^2 / 8: the same bound (17) gives for a corner
 * passed in one period, the bisector method's case (10). At the machine's
 * full acceleration, |A| = sqrt(sum A_k^2) (the polygon's farthest vertex,
 * Theorem 2), that must not exceed eps:
 *     |A| T^2 / 8 <= eps   <=>   T <= sqrt(8 eps / |A|)
 * (1 ms, 0.01 mm: |A| up to 80000 mm/s^2). A longer period is refused: the
 * machine could cut corners by more than the whole tolerance between
 * setpoints (at T = 0.1 s and 1000 mm/s^2 per axis, by 2 mm).
 */
static mlip_status check_period(const struct mlip_machine *m, struct sb *b, struct issue *is)
{
	double a2 = 0.0, amax = 0.0, dev, tmax;
	int i;

	for (i = 0; i < m->n_axes; i++) {
		a2 += m->axis[i].max_accel * m->axis[i].max_accel;
		if (m->axis[i].max_accel > amax) {
			amax = m->axis[i].max_accel;
			is->axis2 = i;
		}
	}
	dev = sqrt(a2) * m->period_s * m->period_s / 8.0;
	if (dev <= m->tolerance_mm) {
		is->axis2 = -1;
		return MLIP_OK;
	}
	tmax = sqrt(8.0 * m->tolerance_mm / sqrt(a2));
	is->key = TK_PERIOD;
	sb_puts(b, "TRAJ PERIOD ");
	sb_double(b, m->period_s);
	sb_puts(b, " s is too long for CONTOUR_TOLERANCE ");
	sb_double(b, m->tolerance_mm);
	sb_puts(b, " mm: between two setpoints the path may leave the curve by |A| T^2/8 = ");
	sb_double(b, floor(dev * 1e6 + 0.5) / 1e6);
	sb_puts(b, " mm (|A| = ");
	sb_double(b, floor(sqrt(a2) + 0.5));
	sb_puts(b, " mm/s^2, eq. 17); PERIOD must be at most ");
	sb_double(b, floor(tmax * 1e6) / 1e6);
	sb_puts(b, " s");
	return MLIP_E_RANGE;
}

static mlip_status check_machine(const struct mlip_machine *m, struct mlip_config_error *err,
                                 struct issue *is)
{
	struct sb b;
	int i, j;

	err_at(err, &b, 0, 0);
	is->axis = -1;
	is->key = -1;
	is->axis2 = -1;
	if (m->n_axes < 2 || m->n_axes > MLIP_MAX_AXES) {
		sb_puts(&b, "TRAJ COORDINATES must have 2 to 6 axes, got ");
		if (m->n_axes < 0) {
			sb_putc(&b, '-');
		}
		sb_uint(&b, (uint64_t)(m->n_axes < 0 ? -(int64_t)m->n_axes : m->n_axes));
		is->key = TK_COORDS;
		return MLIP_E_INVALID;
	}
	if (m->smooth > 1) {
		/* not from an INI: a published segment's flag (mlip-rt --strategy) */
		sb_puts(&b, "the smooth flag must be 0 or 1, got ");
		sb_uint(&b, m->smooth);
		return MLIP_E_INVALID;
	}
	is->key = TK_VLIN;
	if (bad_pos(&b, m, -1, TK_VLIN, m->max_feed_mm_s) ||
	    bad_max(&b, m, -1, TK_VLIN, m->max_feed_mm_s, MLIP_CONFIG_VEL_MAX)) {
		return MLIP_E_RANGE;
	}
	is->key = TK_VANG;
	if (bad_pos(&b, m, -1, TK_VANG, m->max_rot_feed_deg_s) ||
	    bad_max(&b, m, -1, TK_VANG, m->max_rot_feed_deg_s, MLIP_CONFIG_VEL_MAX)) {
		return MLIP_E_RANGE;
	}
	is->key = TK_TOL;
	if (bad_pos(&b, m, -1, TK_TOL, m->tolerance_mm)) {
		return MLIP_E_RANGE;
	}
	if (m->tolerance_mm < MLIP_CONFIG_TOL_MIN) {
		sb_puts(&b, "TRAJ CONTOUR_TOLERANCE must be at least 1e-6 mm, got ");
		sb_double(&b, m->tolerance_mm);
		return MLIP_E_RANGE;
	}
	is->key = TK_PERIOD;
	if (!(m->period_s >= MLIP_CONFIG_PERIOD_MIN_S && m->period_s <= MLIP_CONFIG_PERIOD_MAX_S)) {
		sb_puts(&b, "TRAJ PERIOD must be within 0.0001..0.1 s, got ");
		sb_double(&b, m->period_s);
		return MLIP_E_RANGE;
	}
	for (i = 0; i < m->n_axes; i++) {
		const struct mlip_axis *a = &m->axis[i];
		is->axis = i;
		is->key = TK_COORDS; /* letter problems: no AXIS_ key to point at */
		if (letter_index(a->letter) < 0) {
			sb_puts(&b, "TRAJ COORDINATES: axis ");
			sb_uint(&b, (uint64_t)i);
			sb_puts(&b, " has letter ");
			sb_byte(&b, (unsigned char)a->letter);
			sb_puts(&b, ", not one of X Y Z A B C");
			is->axis = -1;
			return MLIP_E_INVALID;
		}
		for (j = 0; j < i; j++) {
			if (m->axis[j].letter == a->letter) {
				sb_puts(&b, "TRAJ COORDINATES: duplicate axis letter ");
				sb_putc(&b, a->letter);
				is->axis = -1;
				return MLIP_E_INVALID;
			}
		}
		is->key = AK_TYPE;
		if (a->kind != MLIP_AXIS_LINEAR && a->kind != MLIP_AXIS_ROTARY) {
			sb_field(&b, m, i, AK_TYPE);
			sb_puts(&b, " must be LINEAR or ANGULAR");
			return MLIP_E_INVALID;
		}
		is->key = AK_VEL;
		if (bad_pos(&b, m, i, AK_VEL, a->max_vel) ||
		    bad_max(&b, m, i, AK_VEL, a->max_vel, MLIP_CONFIG_VEL_MAX)) {
			return MLIP_E_RANGE;
		}
		is->key = AK_ACC;
		if (bad_pos(&b, m, i, AK_ACC, a->max_accel) ||
		    bad_max(&b, m, i, AK_ACC, a->max_accel, MLIP_CONFIG_ACCEL_MAX)) {
			return MLIP_E_RANGE;
		}
		is->key = AK_MIN;
		if (bad_finite(&b, m, i, AK_MIN, a->min_limit) ||
		    bad_abs(&b, m, i, AK_MIN, a->min_limit)) {
			return MLIP_E_RANGE;
		}
		is->key = AK_MAX;
		if (bad_finite(&b, m, i, AK_MAX, a->max_limit) ||
		    bad_abs(&b, m, i, AK_MAX, a->max_limit)) {
			return MLIP_E_RANGE;
		}
		is->key = AK_MIN; /* the pair: the parser points at the later key */
		if (!(a->min_limit < a->max_limit)) {
			sb_field(&b, m, i, AK_MIN);
			sb_puts(&b, " must be < MAX_LIMIT, got ");
			sb_double(&b, a->min_limit);
			sb_puts(&b, " >= ");
			sb_double(&b, a->max_limit);
			return MLIP_E_RANGE;
		}
		is->key = AK_HOME;
		if (bad_finite(&b, m, i, AK_HOME, a->home)) {
			return MLIP_E_RANGE;
		}
		if (a->home < a->min_limit || a->home > a->max_limit) {
			sb_field(&b, m, i, AK_HOME);
			sb_putc(&b, ' ');
			sb_double(&b, a->home);
			sb_puts(&b, " is outside MIN_LIMIT..MAX_LIMIT ");
			sb_double(&b, a->min_limit);
			sb_puts(&b, "..");
			sb_double(&b, a->max_limit);
			return MLIP_E_RANGE;
		}
		is->key = AK_NODE;
		if (a->can_node < 1 || a->can_node > NODE_MAX) {
			sb_field(&b, m, i, AK_NODE);
			sb_puts(&b, " must be within 1..127, got ");
			if (a->can_node < 0) {
				sb_putc(&b, '-');
			}
			sb_uint(&b,
			        (uint64_t)(a->can_node < 0 ? -(int64_t)a->can_node : a->can_node));
			return MLIP_E_RANGE;
		}
		for (j = 0; j < i; j++) {
			if (m->axis[j].can_node == a->can_node) {
				sb_field(&b, m, i, AK_NODE);
				sb_putc(&b, ' ');
				sb_uint(&b, (uint64_t)a->can_node);
				sb_puts(&b, " is also the CAN_NODE of AXIS_");
				sb_putc(&b, m->axis[j].letter);
				is->axis2 = j;
				return MLIP_E_RANGE;
			}
		}
		is->key = AK_CPU;
		if (bad_pos(&b, m, i, AK_CPU, a->counts_per_unit) ||
		    bad_max(&b, m, i, AK_CPU, a->counts_per_unit, MLIP_CONFIG_COUNTS_MAX)) {
			return MLIP_E_RANGE;
		}
	}
	is->axis = -1;
	is->key = -1;
	return check_period(m, &b, is);
}

mlip_status mlip_machine_check(const struct mlip_machine *m, struct mlip_config_error *err)
{
	struct mlip_config_error dummy;
	struct issue is;

	return check_machine(m, err != NULL ? err : &dummy, &is);
}

/* ---- the second pass --------------------------------------------------- */

/* Place err on the latest given of up to three keys (sec < 0: unused):
 * the value a user changed last is the one to look at. When none was
 * given (the values are defaults), on the first section's header, column 0. */
static void place(const struct pstate *ps, struct mlip_config_error *err, int s1, int k1, int s2,
                  int k2, int s3, int k3)
{
	const int sec[3] = {s1, s2, s3}, key[3] = {k1, k2, k3};
	struct pos best = {0, 0};
	int i;

	for (i = 0; i < 3; i++) {
		if (sec[i] >= 0 && has(ps, sec[i], key[i])) {
			struct pos p = ps->sec[sec[i]].key[key[i]];
			if (p.line > best.line || (p.line == best.line && p.col > best.col)) {
				best = p;
			}
		}
	}
	if (best.line == 0 && s1 >= 0) {
		best.line = ps->sec[s1].at.line;
	}
	err->line = best.line;
	err->col = best.col;
}

static mlip_status missing(struct mlip_config_error *err, uint32_t line, uint32_t col,
                           const char *what, int sec)
{
	struct sb b;

	err_at(err, &b, line, col);
	sb_puts(&b, "missing ");
	sb_puts(&b, what);
	sb_puts(&b, " in [");
	sb_secname(&b, sec);
	sb_putc(&b, ']');
	return MLIP_E_SYNTAX;
}

/* Required sections and keys, axis sections against COORDINATES. */
static mlip_status check_presence(const struct pstate *ps, struct mlip_config_error *err)
{
	const struct sec *tr = &ps->sec[SEC_TRAJ];
	struct sb b;
	int i, k, first = -1;

	if (tr->at.line == 0) {
		err_at(err, &b, 0, 0);
		sb_puts(&b, "missing section [TRAJ]");
		return MLIP_E_SYNTAX;
	}
	if (!has(ps, SEC_TRAJ, TK_COORDS)) {
		return missing(err, tr->at.line, 0, "COORDINATES", SEC_TRAJ);
	}
	/* an axis section for a letter not in COORDINATES: the first in the file */
	for (i = 0; i < MLIP_MAX_AXES; i++) {
		const struct sec *st = &ps->sec[SEC_AXIS0 + i];
		int listed = memchr(ps->coords, axis_letters[i], (size_t)ps->n_coords) != NULL;
		if (st->at.line != 0 && !listed &&
		    (first < 0 || st->at.line < ps->sec[SEC_AXIS0 + first].at.line)) {
			first = i;
		}
	}
	if (first >= 0) {
		const struct sec *st = &ps->sec[SEC_AXIS0 + first];
		err_at(err, &b, st->at.line, st->at.col);
		sb_puts(&b, "section [AXIS_");
		sb_putc(&b, axis_letters[first]);
		sb_puts(&b, "] is for axis ");
		sb_putc(&b, axis_letters[first]);
		sb_puts(&b, ", which is not in COORDINATES (line ");
		sb_uint(&b, tr->key[TK_COORDS].line);
		sb_putc(&b, ')');
		return MLIP_E_SYNTAX;
	}
	for (i = 0; i < ps->n_coords; i++) {
		if (ps->sec[SEC_AXIS0 + letter_index(ps->coords[i])].at.line == 0) {
			err_at(err, &b, tr->key[TK_COORDS].line, ps->coord_col[i]);
			sb_puts(&b, "missing section [AXIS_");
			sb_putc(&b, ps->coords[i]);
			sb_puts(&b, "] for axis ");
			sb_putc(&b, ps->coords[i]);
			sb_puts(&b, " of COORDINATES");
			return MLIP_E_SYNTAX;
		}
	}
	for (k = 0; k < NKEYS; k++) {
		if (keytab[K_TRAJ][k].required && !has(ps, SEC_TRAJ, k)) {
			return missing(err, tr->at.line, 0, keytab[K_TRAJ][k].name, SEC_TRAJ);
		}
	}
	for (i = 0; i < ps->n_coords; i++) {
		int sec = SEC_AXIS0 + letter_index(ps->coords[i]);
		for (k = 0; k < NKEYS; k++) {
			if (keytab[K_AXIS][k].required && !has(ps, sec, k)) {
				return missing(err, ps->sec[sec].at.line, 0, keytab[K_AXIS][k].name,
				               sec);
			}
		}
	}
	return MLIP_OK;
}

/* ---- CAN ids: the one home of their rules ---------------------------------
 *
 * Used by the INI reader (placed on the keys involved), by mlip_canenc_init
 * and by mlip-rt after --profile (mlip_can_config_check), so that what the
 * reader accepts the encoder accepts, and the reverse. For the profile in
 * force, every identifier sent each period (cia402: SYNC_ID and RPDO_BASE +
 * CAN_NODE of each axis; packed: PACKED_BASE + k for the ceil(n/2) position
 * frames and the commit frame; fd: FD_ID) is an 11-bit id, distinct from the
 * others and from STATUS_ID; SYNC_ID != STATUS_ID; cia402 node ids 1..127;
 * with fd, DATA_BITRATE >= BITRATE. */

/* The keys an issue involves: up to three (sec, key), sec < 0 unused; an
 * axis's key as SEC_AXIS0 + its index in the machine (mapped by the reader). */
struct can_where {
	int sec[3], key[3];
};

static void where(struct can_where *w, int s1, int k1, int s2, int k2, int s3, int k3)
{
	w->sec[0] = s1;
	w->key[0] = k1;
	w->sec[1] = s2;
	w->key[1] = k2;
	w->sec[2] = s3;
	w->key[2] = k3;
}

/* "RPDO_BASE 0x200 + CAN_NODE 3 of AXIS_Z" (the id's sum follows) */
static void sb_rpdo(struct sb *b, const struct mlip_can_config *can, const struct mlip_axis *a)
{
	sb_puts(b, "RPDO_BASE ");
	sb_hex(b, can->rpdo_base, 3);
	sb_puts(b, " + CAN_NODE ");
	sb_uint(b, (uint64_t)a->can_node);
	sb_puts(b, " of AXIS_");
	sb_putc(b, a->letter);
}

static mlip_status can_rules(const struct mlip_can_config *can, const struct mlip_machine *m,
                             struct mlip_config_error *err, struct can_where *w)
{
	const uint32_t other[2] = {can->sync_id, can->status_id};
	static const char *const other_name[2] = {"SYNC_ID", "STATUS_ID"};
	const int other_key[2] = {CK_SYNC, CK_STATUS};
	char name[sizeof can->profile + 1];
	struct sb b;
	int i, j, prof = -1;

	err_at(err, &b, 0, 0);
	where(w, -1, 0, -1, 0, -1, 0);
	memcpy(name, can->profile, sizeof can->profile);
	name[sizeof can->profile] = '\0';
	for (i = 0; i < 3; i++) {
		if (strcmp(name, profiles[i]) == 0) {
			prof = i;
		}
	}
	if (prof < 0) {
		sb_puts(&b, "PROFILE '");
		sb_tok(&b, name, strlen(name));
		sb_puts(&b, "' must be cia402, packed or fd");
		where(w, SEC_CAN, CK_PROFILE, -1, 0, -1, 0);
		return MLIP_E_INVALID;
	}
	if (m->n_axes < 1 || m->n_axes > MLIP_MAX_AXES) {
		sb_puts(&b, "CAN output needs 1 to 6 axes");
		return MLIP_E_INVALID;
	}
	for (i = 0; prof == 0 && i < m->n_axes; i++) {
		const struct mlip_axis *a = &m->axis[i];
		uint64_t id = (uint64_t)can->rpdo_base + (uint64_t)a->can_node;
		if (a->can_node < 1 || a->can_node > NODE_MAX) {
			sb_puts(&b, "AXIS_");
			sb_putc(&b, a->letter);
			sb_puts(&b, " CAN_NODE must be within 1..127 with PROFILE cia402");
			where(w, SEC_AXIS0 + i, AK_NODE, SEC_CAN, CK_PROFILE, -1, 0);
			return MLIP_E_RANGE;
		}
		if (id > ID_MAX) {
			sb_rpdo(&b, can, a);
			sb_puts(&b, " = ");
			sb_hex(&b, (uint32_t)(id > 0xFFFFFFFFu ? 0xFFFFFFFFu : id), 3);
			sb_puts(&b, " is not an 11-bit id (at most 0x7FF)");
			where(w, SEC_CAN, CK_RPDO, SEC_AXIS0 + i, AK_NODE, -1, 0);
			return MLIP_E_RANGE;
		}
		for (j = 0; j < 2; j++) {
			if (other[j] == id) {
				sb_puts(&b, other_name[j]);
				sb_putc(&b, ' ');
				sb_hex(&b, other[j], 3);
				sb_puts(&b, " is also the RPDO of AXIS_");
				sb_putc(&b, a->letter);
				sb_puts(&b, " (RPDO_BASE + CAN_NODE ");
				sb_uint(&b, (uint64_t)a->can_node);
				sb_putc(&b, ')');
				where(w, SEC_CAN, other_key[j], SEC_CAN, CK_RPDO, SEC_AXIS0 + i,
				      AK_NODE);
				return MLIP_E_RANGE;
			}
		}
		for (j = 0; j < i; j++) {
			if (m->axis[j].can_node == a->can_node) {
				sb_rpdo(&b, can, a);
				sb_puts(&b, " is also the RPDO of AXIS_");
				sb_putc(&b, m->axis[j].letter);
				where(w, SEC_AXIS0 + i, AK_NODE, SEC_AXIS0 + j, AK_NODE, -1, 0);
				return MLIP_E_RANGE;
			}
		}
	}
	if (can->sync_id == can->status_id) {
		sb_puts(&b, "STATUS_ID ");
		sb_hex(&b, can->status_id, 3);
		sb_puts(&b, " is also the SYNC_ID");
		where(w, SEC_CAN, CK_STATUS, SEC_CAN, CK_SYNC, -1, 0);
		return MLIP_E_RANGE;
	}
	if (prof == 1) {
		/* ceil(n/2) position frames, then the commit frame */
		int nf = (m->n_axes + 1) / 2;
		for (i = 0; i <= nf; i++) {
			uint64_t id = (uint64_t)can->packed_base + (uint64_t)i;
			int over = id > ID_MAX;
			if (!over && id != can->status_id) {
				continue;
			}
			sb_puts(&b, "PACKED_BASE ");
			sb_hex(&b, can->packed_base, 3);
			sb_puts(&b, " + ");
			sb_uint(&b, (uint64_t)i);
			sb_puts(&b, " = ");
			sb_hex(&b, (uint32_t)(id > 0xFFFFFFFFu ? 0xFFFFFFFFu : id), 3);
			sb_puts(&b, i < nf ? " (position frame " : " (the commit frame");
			if (i < nf) {
				sb_uint(&b, (uint64_t)i);
			}
			sb_puts(&b, " of ");
			sb_uint(&b, (uint64_t)m->n_axes);
			sb_puts(&b, over ? " axes) is not an 11-bit id (at most 0x7FF)"
			                 : " axes) is also the STATUS_ID");
			where(w, SEC_CAN, CK_PACKED, SEC_CAN, over ? CK_PROFILE : CK_STATUS,
			      SEC_CAN, CK_PROFILE);
			return MLIP_E_RANGE;
		}
	}
	if (prof == 2 && (can->fd_id > ID_MAX || can->fd_id == can->status_id)) {
		sb_puts(&b, "FD_ID ");
		sb_hex(&b, can->fd_id, 3);
		sb_puts(&b, can->fd_id > ID_MAX ? " is not an 11-bit id (at most 0x7FF)"
		                                : " is also the STATUS_ID");
		where(w, SEC_CAN, CK_FD, SEC_CAN, CK_STATUS, SEC_CAN, CK_PROFILE);
		return MLIP_E_RANGE;
	}
	if (prof == 2 && can->data_bitrate < can->bitrate) {
		sb_puts(&b, "DATA_BITRATE ");
		sb_uint(&b, can->data_bitrate);
		sb_puts(&b, " must be >= BITRATE ");
		sb_uint(&b, can->bitrate);
		sb_puts(&b, " with PROFILE fd");
		where(w, SEC_CAN, CK_DBITRATE, SEC_CAN, CK_BITRATE, SEC_CAN, CK_PROFILE);
		return MLIP_E_RANGE;
	}
	return MLIP_OK;
}

mlip_status mlip_can_config_check(const struct mlip_can_config *can, const struct mlip_machine *m,
                                  struct mlip_config_error *err)
{
	struct mlip_config_error dummy;
	struct can_where w;

	if (can == NULL || m == NULL) {
		return MLIP_E_INVALID;
	}
	return can_rules(can, m, err != NULL ? err : &dummy, &w);
}

static void fill_machine(const struct pstate *ps, struct mlip_config *c)
{
	struct mlip_machine *m = &c->machine;
	const struct sec *tr = &ps->sec[SEC_TRAJ];
	int i;

	memset(m->axis, 0, sizeof m->axis);
	m->n_axes = ps->n_coords;
	for (i = 0; i < ps->n_coords; i++) {
		int li = letter_index(ps->coords[i]), sec = SEC_AXIS0 + li;
		const struct sec *st = &ps->sec[sec];
		struct mlip_axis *a = &m->axis[i];
		a->letter = ps->coords[i];
		a->kind = has(ps, sec, AK_TYPE) ? (mlip_axis_kind)st->ival[AK_TYPE]
		          : li < 3              ? MLIP_AXIS_LINEAR
		                                : MLIP_AXIS_ROTARY;
		a->max_vel = st->num[AK_VEL];
		a->max_accel = st->num[AK_ACC];
		a->min_limit = has(ps, sec, AK_MIN) ? st->num[AK_MIN] : -LIMIT_DEFAULT;
		a->max_limit = has(ps, sec, AK_MAX) ? st->num[AK_MAX] : LIMIT_DEFAULT;
		a->home = has(ps, sec, AK_HOME) ? st->num[AK_HOME] : 0.0;
		a->can_node = has(ps, sec, AK_NODE) ? (int)st->ival[AK_NODE] : i + 1;
		a->counts_per_unit = has(ps, sec, AK_CPU) ? st->num[AK_CPU] : 1000.0;
	}
	m->max_feed_mm_s = tr->num[TK_VLIN];
	m->tolerance_mm = tr->num[TK_TOL];
	if (has(ps, SEC_TRAJ, TK_VANG)) {
		m->max_rot_feed_deg_s = tr->num[TK_VANG];
	}
	if (has(ps, SEC_TRAJ, TK_PERIOD)) {
		m->period_s = tr->num[TK_PERIOD];
	}
	if (has(ps, SEC_TRAJ, TK_LOOKAHEAD)) {
		c->lookahead = (uint32_t)tr->ival[TK_LOOKAHEAD];
	}
}

static void fill_can(const struct pstate *ps, struct mlip_can_config *can)
{
	const struct sec *st = &ps->sec[SEC_CAN];
	uint32_t *const dst[NKEYS] = {NULL,          &can->bitrate,   &can->data_bitrate,
	                              &can->sync_id, &can->rpdo_base, &can->packed_base,
	                              &can->fd_id,   &can->status_id};
	int k;

	if (has(ps, SEC_CAN, CK_PROFILE)) {
		memset(can->profile, 0, sizeof can->profile);
		memcpy(can->profile, profiles[st->ival[CK_PROFILE]],
		       strlen(profiles[st->ival[CK_PROFILE]]));
	}
	for (k = CK_BITRATE; k < NKEYS; k++) {
		if (has(ps, SEC_CAN, k)) {
			*dst[k] = (uint32_t)st->ival[k];
		}
	}
}

static void fill_drives(const struct pstate *ps, struct mlip_drives_config *d)
{
	const struct sec *st = &ps->sec[SEC_DRIVES];
	uint32_t *const dst[NKEYS] = {NULL,
	                              NULL,
	                              &d->heartbeat_ms,
	                              &d->heartbeat_timeout_ms,
	                              NULL,
	                              &d->sdo_timeout_ms,
	                              &d->boot_timeout_ms,
	                              &d->state_timeout_ms};
	int k;

	for (k = 0; k < NKEYS; k++) {
		if (has(ps, SEC_DRIVES, k) && dst[k] != NULL) {
			*dst[k] = (uint32_t)st->ival[k];
		}
	}
	if (has(ps, SEC_DRIVES, DK_ENABLE)) {
		d->enable = (int)st->ival[DK_ENABLE];
	}
	if (has(ps, SEC_DRIVES, DK_MASTER)) {
		d->master_node = (uint8_t)st->ival[DK_MASTER];
	}
	if (has(ps, SEC_DRIVES, DK_FERR)) {
		d->following_error = st->num[DK_FERR];
	}
}

/* [DRIVES] against the rest: the drives' heartbeat is lost only after it is
 * due; the master's node is none of the drives'. */
static mlip_status check_drives(const struct pstate *ps, const struct mlip_config *c,
                                struct mlip_config_error *err)
{
	const struct mlip_drives_config *d = &c->drives;
	struct sb b;
	int i;

	if (ps->sec[SEC_DRIVES].at.line == 0) {
		return MLIP_OK; /* mlip-rt --drives checks the defaults against the nodes */
	}
	if (d->heartbeat_timeout_ms <= d->heartbeat_ms) {
		err_at(err, &b, 0, 0);
		sb_puts(&b, "HEARTBEAT_TIMEOUT_MS ");
		sb_uint(&b, d->heartbeat_timeout_ms);
		sb_puts(&b, " must be > HEARTBEAT_MS ");
		sb_uint(&b, d->heartbeat_ms);
		sb_puts(&b, " (a heartbeat is lost only after it is due)");
		place(ps, err, SEC_DRIVES, DK_HB_TIMEOUT, SEC_DRIVES, DK_HB, -1, 0);
		return MLIP_E_RANGE;
	}
	for (i = 0; i < c->machine.n_axes; i++) {
		if (c->machine.axis[i].can_node == d->master_node) {
			int sec = SEC_AXIS0 + letter_index(c->machine.axis[i].letter);
			err_at(err, &b, 0, 0);
			sb_puts(&b, "MASTER_NODE ");
			sb_uint(&b, d->master_node);
			sb_puts(&b, " is also the CAN_NODE of AXIS_");
			sb_putc(&b, c->machine.axis[i].letter);
			place(ps, err, SEC_DRIVES, DK_MASTER, sec, AK_NODE, -1, 0);
			return MLIP_E_RANGE;
		}
	}
	return MLIP_OK;
}

/* The CAN ids that need the axes: every RPDO_BASE + node an 11-bit id; with
 * cia402, SYNC_ID and STATUS_ID clear of those RPDOs; SYNC_ID != STATUS_ID;
 * with fd, a data phase no slower than the arbitration phase. */
static mlip_status check_can(const struct pstate *ps, const struct mlip_config *c,
                             struct mlip_config_error *err)
{
	/* all of can_rules (above) for the file's profile, the error on the
	 * latest of the keys involved */
	struct can_where w;
	mlip_status st = can_rules(&c->can, &c->machine, err, &w);
	int i;

	if (st == MLIP_OK) {
		return st;
	}
	for (i = 0; i < 3; i++) {
		if (w.sec[i] >= SEC_AXIS0 && w.sec[i] < SEC_CAN) { /* machine index -> section */
			w.sec[i] =
			    SEC_AXIS0 + letter_index(c->machine.axis[w.sec[i] - SEC_AXIS0].letter);
		}
	}
	place(ps, err, w.sec[0], w.key[0], w.sec[1], w.key[1], w.sec[2], w.key[2]);
	return st;
}

/* ---- entry points -------------------------------------------------------- */

void mlip_config_defaults(struct mlip_config *c)
{
	memset(c, 0, sizeof *c);
	c->machine.n_axes = 0;
	c->machine.max_feed_mm_s = 0.0; /* required: MAX_LINEAR_VELOCITY */
	c->machine.tolerance_mm = 0.0;  /* required: CONTOUR_TOLERANCE */
	c->machine.max_rot_feed_deg_s = 360.0;
	c->machine.period_s = 0.001;
	c->lookahead = MLIP_LOOKAHEAD;
	memcpy(c->can.profile, "cia402", sizeof "cia402");
	c->can.bitrate = 1000000;
	c->can.data_bitrate = 5000000;
	c->can.sync_id = 0x080;
	c->can.rpdo_base = 0x200;
	c->can.packed_base = 0x300;
	c->can.fd_id = 0x400;
	c->can.status_id = 0x180;
	c->drives.enable = 0;
	c->drives.master_node = 127;
	c->drives.heartbeat_ms = 100;
	c->drives.heartbeat_timeout_ms = 300;
	c->drives.following_error = 1.0;
	c->drives.sdo_timeout_ms = 200;
	c->drives.boot_timeout_ms = 3000;
	c->drives.state_timeout_ms = 1000;
}

mlip_status mlip_config_parse(struct mlip_config *c, const char *text, size_t len,
                              struct mlip_config_error *err)
{
	struct mlip_config_error dummy;
	struct mlip_config out;
	struct pstate ps;
	struct issue is;
	size_t i = 0;
	uint32_t line = 0;
	mlip_status st;

	if (err == NULL) {
		err = &dummy;
	}
	memset(&ps, 0, sizeof ps);
	ps.cur = -1;
	/* a UTF-8 byte order mark, as some Windows editors write: not a column */
	if (len >= 3 && memcmp(text, "\xEF\xBB\xBF", 3) == 0) {
		i = 3;
	}
	while (i < len) {
		const char *s = text + i, *nl = memchr(s, '\n', len - i);
		size_t n = nl != NULL ? (size_t)(nl - s) : len - i;
		i += n + (nl != NULL);
		line++;
		if (n > 0 && s[n - 1] == '\r') {
			n--; /* CRLF */
		}
		st = check_bytes(s, n, line, err);
		if (st == MLIP_OK) {
			st = parse_line(&ps, s, n, line, err);
		}
		if (st != MLIP_OK) {
			return st;
		}
	}

	st = check_presence(&ps, err);
	if (st != MLIP_OK) {
		return st;
	}
	out = *c;
	fill_machine(&ps, &out);
	fill_can(&ps, &out.can);
	fill_drives(&ps, &out.drives);
	st = check_machine(&out.machine, err, &is);
	if (st != MLIP_OK) {
		if (is.key == TK_PERIOD && is.axis2 >= 0) {
			/* the period against eps and the largest acceleration: on
			 * PERIOD when the file sets it, else on the later of the
			 * tolerance and that acceleration */
			int sec = SEC_AXIS0 + letter_index(out.machine.axis[is.axis2].letter);
			if (has(&ps, SEC_TRAJ, TK_PERIOD)) {
				place(&ps, err, SEC_TRAJ, TK_PERIOD, -1, 0, -1, 0);
			} else {
				place(&ps, err, SEC_TRAJ, TK_TOL, sec, AK_ACC, -1, 0);
			}
		} else if (is.axis < 0) {
			place(&ps, err, SEC_TRAJ, is.key, -1, 0, -1, 0);
		} else {
			int sec = SEC_AXIS0 + letter_index(out.machine.axis[is.axis].letter);
			if (is.key == AK_MIN) {
				place(&ps, err, sec, AK_MIN, sec, AK_MAX, -1, 0);
			} else if (is.key == AK_HOME && !has(&ps, sec, AK_HOME)) {
				place(&ps, err, sec, AK_MIN, sec, AK_MAX, -1, 0);
			} else if (is.key == AK_NODE && is.axis2 >= 0) {
				char l2 = out.machine.axis[is.axis2].letter;
				int sec2 = SEC_AXIS0 + letter_index(l2);
				place(&ps, err, sec, AK_NODE, sec2, AK_NODE, -1, 0);
			} else {
				place(&ps, err, sec, is.key, -1, 0, -1, 0);
			}
		}
		return st;
	}
	st = check_can(&ps, &out, err);
	if (st == MLIP_OK) {
		st = check_drives(&ps, &out, err);
	}
	if (st != MLIP_OK) {
		return st;
	}
	*c = out;
	return MLIP_OK;
}
