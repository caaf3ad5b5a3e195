/*
 * ini.c - the machine configuration: a small INI reader for [TRAJ],
 * [AXIS_X]..[AXIS_C], [CAN] and [DRIVES] (format in
 * include/mlip/machine/config.h).
 *
 * Pure: reads the caller's buffer, writes the caller's struct; no allocation,
 * no stdio (messages through mlip/text/format.h) and no locale (numbers
 * through mlip/text/number.h, since strtod accepts "nan", "inf", hex floats
 * and, under some locales, a decimal comma).
 *
 * Two passes. The first reads line by line and checks every byte, token and
 * single value where it stands, so that its errors point at a line and a
 * column. The second needs the whole file (sections may come in any order):
 * required sections and keys, axis sections against COORDINATES, values
 * against each other (through the same check as mlip_machine_check, its
 * error then placed on the key that set the value), CAN ids (the rules of
 * mlip/can/canconf.h), [DRIVES]. Only then is *c written, so a failed parse
 * leaves it as it was.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "keys.h"
#include "mlip/can/canenc.h" /* mlip_can_profile_name */
#include "mlip/text/chars.h"
#include "mlip/text/number.h"

/* ---- the first pass: one line ------------------------------------------- */

/* The whole token as a decimal (mlip/text/number.h, with an exponent).
 * Returns 0 with *out, -1 when malformed, -2 when it overflows a double. */
static int parse_real(const char *s, size_t n, double *out)
{
	struct mlip_number num;
	double v;

	if (mlip_number_lex(s, n, 0, MLIP_NUM_EXPONENT, &num) != n || num.ndig == 0 ||
	    num.exp_bad) {
		return -1;
	}
	v = mlip_number_value(&num);
	if (!isfinite(v)) {
		return -2;
	}
	*out = v;
	return 0;
}

static int is_keych(char ch)
{
	return (ch >= 'A' && ch <= 'Z') || (ch >= 'a' && ch <= 'z') || mlip_is_digit(ch) ||
	       ch == '_';
}

static size_t skip_ws(const char *s, size_t n, size_t p)
{
	while (p < n && mlip_is_blank(s[p])) {
		p++;
	}
	return p;
}

static int tok_is(const char *s, size_t n, const char *word)
{
	return strlen(word) == n && memcmp(s, word, n) == 0;
}

/* Bytes of one line: UTF-8, no NUL, no control character but tab, not too
 * long. */
static mlip_status check_bytes(const char *s, size_t n, uint32_t line,
                               struct mlip_config_error *err)
{
	const unsigned char *u = (const unsigned char *)s;
	size_t j = 0, lim = n < MLIP_CONFIG_MAX_LINE ? n : MLIP_CONFIG_MAX_LINE;
	struct mlip_tb b;

	while (j < lim) {
		size_t k;
		if (u[j] == 0) {
			err_at(err, &b, line, (uint32_t)j + 1);
			mlip_tb_puts(&b, "NUL byte (is this a text file?)");
			return MLIP_E_SYNTAX;
		}
		if ((u[j] < 0x20 && u[j] != '\t') || u[j] == 0x7F) {
			err_at(err, &b, line, (uint32_t)j + 1);
			mlip_tb_puts(&b, "control character ");
			mlip_tb_hex(&b, u[j], 2);
			mlip_tb_puts(&b, u[j] == '\r' ? " (a CR not followed by LF)"
			                              : " (only tab is allowed)");
			return MLIP_E_SYNTAX;
		}
		k = mlip_utf8_len(u + j, n - j);
		if (k == 0) {
			err_at(err, &b, line, (uint32_t)j + 1);
			mlip_tb_puts(&b, "invalid UTF-8 byte ");
			mlip_tb_hex(&b, u[j], 2);
			mlip_tb_puts(&b, " (save the file as UTF-8)");
			return MLIP_E_SYNTAX;
		}
		j += k;
	}
	if (n > MLIP_CONFIG_MAX_LINE) {
		err_at(err, &b, line, MLIP_CONFIG_MAX_LINE + 1);
		mlip_tb_puts(&b, "line too long (");
		mlip_tb_uint(&b, n);
		mlip_tb_puts(&b, " bytes, at most ");
		mlip_tb_uint(&b, MLIP_CONFIG_MAX_LINE);
		mlip_tb_putc(&b, ')');
		return MLIP_E_SYNTAX;
	}
	return MLIP_OK;
}

/* "[NAME]" at s[p]: known, not seen before, nothing but a comment after. */
static mlip_status parse_header(struct pstate *ps, const char *s, size_t n, size_t p, uint32_t line,
                                struct mlip_config_error *err)
{
	static const char *const names[] = {"TRAJ",   "AXIS_X",  "AXIS_Y", "AXIS_Z", "AXIS_A",
	                                    "AXIS_B", "AXIS_C",  "CAN",    "DRIVES", "SPINDLE",
	                                    "TOOL",   "COOLANT", "IO",     "PROBE"};
	size_t q = p + 1, r, a, z;
	struct mlip_tb b;
	int sec;

	for (r = q; r < n && s[r] != ']'; r++) {
	}
	if (r == n) {
		err_at(err, &b, line, (uint32_t)p + 1);
		mlip_tb_puts(&b, "missing ']' in section header");
		return MLIP_E_SYNTAX;
	}
	a = skip_ws(s, r, q);
	for (z = r; z > a && mlip_is_blank(s[z - 1]); z--) {
	}
	if (a == z) {
		err_at(err, &b, line, (uint32_t)p + 1);
		mlip_tb_puts(&b, "empty section name");
		return MLIP_E_SYNTAX;
	}
	q = skip_ws(s, n, r + 1);
	if (q < n && s[q] != '#' && s[q] != ';') {
		err_at(err, &b, line, (uint32_t)q + 1);
		mlip_tb_puts(&b, "unexpected ");
		mlip_tb_byte(&b, (unsigned char)s[q]);
		mlip_tb_puts(&b, " after section header (comments start with # or ;)");
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
		                 letter_index(mlip_upper(s[a + 5])) < 0;
		const char *hint = bad_letter ? NULL : mlip_mc_suggest(s + a, z - a, names, N_SEC);
		err_at(err, &b, line, (uint32_t)a + 1);
		mlip_tb_puts(&b, "unknown section [");
		mlip_tb_token(&b, s + a, z - a);
		mlip_tb_putc(&b, ']');
		if (bad_letter) {
			mlip_tb_puts(&b, " (axis letters are X Y Z A B C)");
		} else if (hint != NULL) {
			mlip_tb_puts(&b, " (did you mean [");
			mlip_tb_puts(&b, hint);
			mlip_tb_puts(&b, "]?)");
		} else {
			mlip_tb_puts(&b,
			             " (sections are [TRAJ], [AXIS_X]..[AXIS_C], [CAN], [DRIVES], "
			             "[SPINDLE], [TOOL], [COOLANT], [IO])");
		}
		return MLIP_E_SYNTAX;
	}
	if (ps->sec[sec].at.line != 0) {
		err_at(err, &b, line, (uint32_t)a + 1);
		mlip_tb_puts(&b, "duplicate section [");
		mlip_tb_puts(&b, names[sec]);
		mlip_tb_puts(&b, "] (first at line ");
		mlip_tb_uint(&b, ps->sec[sec].at.line);
		mlip_tb_putc(&b, ')');
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
	static const char *const where[N_KINDS] = {
	    "[TRAJ]", "an [AXIS_*] section", "[CAN]", "[DRIVES]", "[SPINDLE]",
	    "[TOOL]", "[COOLANT]",           "[IO]"};
	int kd, k;

	for (kd = 0; kd < N_KINDS; kd++) {
		for (k = 0; kd != except_kind && k < nkeys(kd); k++) {
			if (tok_is(s, n, mlip_mc_keytab[kd][k].name)) {
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
	struct mlip_tb b;

	err_at(err, &b, line, col);
	mlip_tb_puts(&b, key);
	mlip_tb_puts(&b, what);
	mlip_tb_puts(&b, ", got ");
	mlip_tb_token(&b, tok, ntok);
	return MLIP_E_RANGE;
}

static mlip_status parse_coords(struct pstate *ps, const char *v, size_t nv, uint32_t line,
                                uint32_t col0, struct mlip_config_error *err)
{
	size_t q;
	struct mlip_tb b;
	int i, n = 0;

	for (q = 0; q < nv; q++) {
		char l = v[q];
		int li;
		if (mlip_is_blank(l)) {
			continue;
		}
		li = letter_index(l);
		if (li < 0) {
			size_t k = mlip_utf8_len((const unsigned char *)v + q, nv - q);
			err_at(err, &b, line, col0 + (uint32_t)q);
			mlip_tb_putc(&b, '\'');
			mlip_tb_token(&b, v + q, k);
			mlip_tb_puts(&b, "' in COORDINATES is not an axis letter");
			mlip_tb_puts(&b, " (X Y Z A B C, upper case)");
			return MLIP_E_SYNTAX;
		}
		for (i = 0; i < n; i++) {
			if (ps->coords[i] == l) {
				err_at(err, &b, line, col0 + (uint32_t)q);
				mlip_tb_puts(&b, "duplicate axis letter ");
				mlip_tb_putc(&b, l);
				mlip_tb_puts(&b, " in COORDINATES");
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
		mlip_tb_puts(&b, "COORDINATES must have 2 to 6 axes, got ");
		mlip_tb_uint(&b, (uint64_t)n);
		return MLIP_E_RANGE;
	}
	ps->n_coords = n;
	return MLIP_OK;
}

/* Read the value v[0..nv) of key k of section sec, at line:col. */
static mlip_status parse_value(struct pstate *ps, int sec, int k, const char *v, size_t nv,
                               uint32_t line, uint32_t col, struct mlip_config_error *err)
{
	const struct keydef *kd = &mlip_mc_keytab[sec_kind(sec)][k];
	struct sec *st = &ps->sec[sec];
	struct mlip_tb b;
	double x = 0;
	int64_t i = 0;
	int rc;

	switch (kd->type) {
	case V_COORDS:
		return parse_coords(ps, v, nv, line, col, err);
	case V_IOBIT:
		return mlip_mc_parse_iobit(v, nv, line, col, kd->name, &st->ival[k], err);
	case V_COOLANT:
	case V_OUTBIT:
		return mlip_mc_parse_output(kd->type, v, nv, line, col, kd->name, &st->ival[k],
		                            err);
	case V_POS:
	case V_REAL:
	case V_PERIOD:
	case V_RPM:
		rc = parse_real(v, nv, &x);
		if (rc != 0) {
			err_at(err, &b, line, col);
			mlip_tb_puts(&b, rc == -1 ? "malformed number '" : "number out of range '");
			mlip_tb_token(&b, v, nv);
			mlip_tb_puts(&b, "' for ");
			mlip_tb_puts(&b, kd->name);
			if (rc == -1) {
				mlip_tb_puts(&b,
				             " (a plain decimal like 200, 0.5 or 1e-3, no units)");
			}
			return rc == -1 ? MLIP_E_SYNTAX : MLIP_E_RANGE;
		}
		if (kd->type == V_POS && !(x > 0)) {
			return range_err(err, line, col, kd->name, " must be > 0", v, nv);
		}
		if (kd->type == V_RPM && !(x >= 0 && x <= 1e6)) {
			return range_err(err, line, col, kd->name, " must be within 0..1000000 rpm",
			                 v, nv);
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
			mlip_tb_puts(&b, "LINEAR_UNITS ");
			mlip_tb_token(&b, v, nv);
			mlip_tb_puts(&b, " is not supported: convert every length to mm");
			mlip_tb_puts(&b, " (1 inch = 25.4 mm)");
			return MLIP_E_UNSUPPORTED;
		}
		mlip_tb_puts(&b, "LINEAR_UNITS must be mm, got '");
		mlip_tb_token(&b, v, nv);
		mlip_tb_putc(&b, '\'');
		return MLIP_E_SYNTAX;
	case V_AUNITS:
		if (tok_is(v, nv, "degree")) {
			return MLIP_OK;
		}
		err_at(err, &b, line, col);
		if (tok_is(v, nv, "radian") || tok_is(v, nv, "grad")) {
			mlip_tb_puts(&b, "ANGULAR_UNITS ");
			mlip_tb_token(&b, v, nv);
			mlip_tb_puts(&b, " is not supported: convert every angle to degrees");
			return MLIP_E_UNSUPPORTED;
		}
		mlip_tb_puts(&b, "ANGULAR_UNITS must be degree, got '");
		mlip_tb_token(&b, v, nv);
		mlip_tb_putc(&b, '\'');
		return MLIP_E_SYNTAX;
	case V_IO:
		i = tok_is(v, nv, "none")                           ? MLIP_IO_NONE
		    : tok_is(v, nv, "manual")                       ? MLIP_IO_MANUAL
		    : sec == SEC_SPINDLE && tok_is(v, nv, "cia402") ? MLIP_IO_CIA402
		                                                    : -1;
		if (i < 0) {
			err_at(err, &b, line, col);
			mlip_tb_puts(&b, kd->name);
			mlip_tb_puts(&b, sec == SEC_SPINDLE
			                     ? " must be none, manual or cia402, got '"
			                     : " must be none or manual, got '");
			mlip_tb_token(&b, v, nv);
			mlip_tb_putc(&b, '\'');
			return MLIP_E_SYNTAX;
		}
		st->ival[k] = i;
		return MLIP_OK;
	case V_LINPUTS:
		if (!tok_is(v, nv, "drive")) {
			err_at(err, &b, line, col);
			mlip_tb_puts(&b,
			             "LIMIT_INPUTS must be drive (the axis drive's digital inputs "
			             "0x60FD: bit 0 negative limit, 1 positive limit, 2 home "
			             "switch), got '");
			mlip_tb_token(&b, v, nv);
			mlip_tb_putc(&b, '\'');
			return MLIP_E_SYNTAX;
		}
		st->ival[k] = 1;
		return MLIP_OK;
	case V_JPLAN:
		i = tok_is(v, nv, "mean")   ? MLIP_JERK_PLAN_MEAN
		    : tok_is(v, nv, "path") ? MLIP_JERK_PLAN_PATH
		                            : -1;
		if (i < 0) {
			err_at(err, &b, line, col);
			mlip_tb_puts(&b, "JERK_PLAN must be mean or path, got '");
			mlip_tb_token(&b, v, nv);
			mlip_tb_putc(&b, '\'');
			return MLIP_E_SYNTAX;
		}
		st->ival[k] = i;
		return MLIP_OK;
	case V_PSOURCE:
		i = tok_is(v, nv, "io")      ? MLIP_PROBE_SRC_IO
		    : tok_is(v, nv, "drive") ? MLIP_PROBE_SRC_DRIVE
		                             : -1;
		if (i < 0) {
			err_at(err, &b, line, col);
			mlip_tb_puts(
			    &b, "SOURCE must be io (the [IO] PROBE input) or drive (the drives' "
			        "touch probe 0x60B8..0x60BB), got '");
			mlip_tb_token(&b, v, nv);
			mlip_tb_putc(&b, '\'');
			return MLIP_E_SYNTAX;
		}
		st->ival[k] = i;
		return MLIP_OK;
	case V_TYPE:
	case V_PROFILE:
		if (kd->type == V_TYPE) {
			i = tok_is(v, nv, "LINEAR")    ? MLIP_AXIS_LINEAR
			    : tok_is(v, nv, "ANGULAR") ? MLIP_AXIS_ROTARY
			                               : -1;
		} else {
			for (i = 2;
			     i >= 0 && !tok_is(v, nv, mlip_can_profile_name((mlip_can_profile)i));
			     i--) {
			}
		}
		if (i < 0) {
			err_at(err, &b, line, col);
			mlip_tb_puts(&b, kd->name);
			mlip_tb_puts(&b, kd->type == V_TYPE
			                     ? " must be LINEAR or ANGULAR, got '"
			                     : " must be cia402, packed or fd, got '");
			mlip_tb_token(&b, v, nv);
			mlip_tb_putc(&b, '\'');
			return MLIP_E_SYNTAX;
		}
		st->ival[k] = i;
		return MLIP_OK;
	default: /* integers */
		if (mlip_number_int(v, nv, &i) != 0) {
			err_at(err, &b, line, col);
			mlip_tb_puts(&b, "malformed integer '");
			mlip_tb_token(&b, v, nv);
			mlip_tb_puts(&b, "' for ");
			mlip_tb_puts(&b, kd->name);
			mlip_tb_puts(&b, " (decimal digits or 0x hex)");
			return MLIP_E_SYNTAX;
		}
		if (kd->type == V_LOOKAHEAD &&
		    (i < 2 || i > MLIP_LOOKAHEAD || (i & (i - 1)) != 0)) {
			/* MLIP_LOOKAHEAD is 4096 unless a build overrides it */
			err_at(err, &b, line, col);
			mlip_tb_puts(&b, "LOOKAHEAD must be a power of two within 2..");
			mlip_tb_uint(&b, MLIP_LOOKAHEAD);
			mlip_tb_puts(&b, ", got ");
			mlip_tb_token(&b, v, nv);
			return MLIP_E_RANGE;
		}
		if (kd->type == V_NODE && (i < 1 || i > MLIP_CAN_NODE_MAX)) {
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
		if (kd->type == V_METHOD && (i < -128 || i > 127)) {
			return range_err(err, line, col, kd->name,
			                 " must be within -128..127 (0x6098 is an INTEGER8)", v,
			                 nv);
		}
		if (kd->type == V_SEQUENCE && (i < 0 || i > 9)) {
			return range_err(err, line, col, kd->name, " must be within 0..9", v, nv);
		}
		if (kd->type == V_BOOL && i != 0 && i != 1) {
			return range_err(err, line, col, kd->name, " must be 0 or 1", v, nv);
		}
		if (kd->type == V_MS && (i < 1 || i > 65535)) {
			return range_err(err, line, col, kd->name, " must be within 1..65535 ms", v,
			                 nv);
		}
		if (kd->type == V_ID && (i < 0 || i > (int64_t)MLIP_CAN_ID_MAX)) {
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
	struct mlip_tb b;
	int kind, k;

	if (p == n || s[p] == '#' || s[p] == ';') {
		return MLIP_OK;
	}
	if (s[p] == '[') {
		return parse_header(ps, s, n, p, line, err);
	}
	if (!is_keych(s[p])) {
		err_at(err, &b, line, (uint32_t)p + 1);
		mlip_tb_puts(&b, "expected KEY = VALUE, a [SECTION] or a comment, got ");
		mlip_tb_byte(&b, (unsigned char)s[p]);
		return MLIP_E_SYNTAX;
	}
	for (k0 = p; p < n && is_keych(s[p]); p++) {
	}
	nk = p - k0;
	p = skip_ws(s, n, p);
	if (p == n || s[p] != '=') {
		err_at(err, &b, line, (uint32_t)p + 1);
		if (p == n) {
			mlip_tb_puts(&b, "missing '=' after key ");
			mlip_tb_token(&b, s + k0, nk);
		} else {
			mlip_tb_puts(&b, "expected '=' after key ");
			mlip_tb_token(&b, s + k0, nk);
			mlip_tb_puts(&b, ", got ");
			mlip_tb_byte(&b, (unsigned char)s[p]);
		}
		return MLIP_E_SYNTAX;
	}
	/* the value: up to a '#' or ';' that starts it or follows a blank */
	v0 = skip_ws(s, n, p + 1);
	for (v1 = v0; v1 < n; v1++) {
		if ((s[v1] == '#' || s[v1] == ';') && (v1 == v0 || mlip_is_blank(s[v1 - 1]))) {
			break;
		}
	}
	while (v1 > v0 && mlip_is_blank(s[v1 - 1])) {
		v1--;
	}

	if (ps->cur < 0) {
		const char *where = home_of(s + k0, nk, -1);
		err_at(err, &b, line, (uint32_t)k0 + 1);
		mlip_tb_puts(&b, "key ");
		mlip_tb_token(&b, s + k0, nk);
		mlip_tb_puts(&b, " outside any section");
		if (where != NULL) {
			mlip_tb_puts(&b, " (it belongs in ");
			mlip_tb_puts(&b, where);
			mlip_tb_putc(&b, ')');
		}
		return MLIP_E_SYNTAX;
	}
	kind = sec_kind(ps->cur);
	for (k = 0; k < nkeys(kind); k++) {
		names[k] = mlip_mc_keytab[kind][k].name;
		if (tok_is(s + k0, nk, names[k])) {
			break;
		}
	}
	if (k == nkeys(kind)) {
		const char *hint = mlip_mc_suggest(s + k0, nk, names, nkeys(kind));
		const char *where = hint == NULL ? home_of(s + k0, nk, kind) : NULL;
		err_at(err, &b, line, (uint32_t)k0 + 1);
		mlip_tb_puts(&b, "unknown key ");
		mlip_tb_token(&b, s + k0, nk);
		mlip_tb_puts(&b, " in [");
		mlip_mc_secname(&b, ps->cur);
		mlip_tb_putc(&b, ']');
		if (hint != NULL) {
			mlip_tb_puts(&b, " (did you mean ");
			mlip_tb_puts(&b, hint);
			mlip_tb_puts(&b, "?)");
		} else if (where != NULL) {
			mlip_tb_puts(&b, " (it belongs in ");
			mlip_tb_puts(&b, where);
			mlip_tb_putc(&b, ')');
		}
		return MLIP_E_SYNTAX;
	}
	if (has(ps, ps->cur, k)) {
		err_at(err, &b, line, (uint32_t)k0 + 1);
		mlip_tb_puts(&b, "duplicate key ");
		mlip_tb_puts(&b, names[k]);
		mlip_tb_puts(&b, " in [");
		mlip_mc_secname(&b, ps->cur);
		mlip_tb_puts(&b, "] (first at line ");
		mlip_tb_uint(&b, ps->sec[ps->cur].key[k].line);
		mlip_tb_putc(&b, ')');
		return MLIP_E_SYNTAX;
	}
	if (v1 == v0) {
		err_at(err, &b, line, (uint32_t)v0 + 1);
		mlip_tb_puts(&b, "missing value for ");
		mlip_tb_puts(&b, names[k]);
		return MLIP_E_SYNTAX;
	}
	ps->sec[ps->cur].seen |= 1u << k;
	ps->sec[ps->cur].key[k].line = line;
	ps->sec[ps->cur].key[k].col = (uint32_t)k0 + 1;
	return parse_value(ps, ps->cur, k, s + v0, v1 - v0, line, (uint32_t)v0 + 1, err);
}

/* ---- the second pass --------------------------------------------------- */

/* Place err on the latest given of up to three keys (sec or key < 0: unused):
 * the value a user changed last is the one to look at. When none was
 * given (the values are defaults), on the first section's header, column 0. */
void mlip_mc_place(const struct pstate *ps, struct mlip_config_error *err, int s1, int k1, int s2,
                   int k2, int s3, int k3)
{
	const int sec[3] = {s1, s2, s3}, key[3] = {k1, k2, k3};
	struct pos best = {0, 0};
	int i;

	for (i = 0; i < 3; i++) {
		if (sec[i] >= 0 && key[i] >= 0 && has(ps, sec[i], key[i])) {
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
	struct mlip_tb b;

	err_at(err, &b, line, col);
	mlip_tb_puts(&b, "missing ");
	mlip_tb_puts(&b, what);
	mlip_tb_puts(&b, " in [");
	mlip_mc_secname(&b, sec);
	mlip_tb_putc(&b, ']');
	return MLIP_E_SYNTAX;
}

/* Required sections and keys, axis sections against COORDINATES. */
static mlip_status check_presence(const struct pstate *ps, struct mlip_config_error *err)
{
	const struct sec *tr = &ps->sec[SEC_TRAJ];
	struct mlip_tb b;
	int i, k, first = -1;

	if (tr->at.line == 0) {
		err_at(err, &b, 0, 0);
		mlip_tb_puts(&b, "missing section [TRAJ]");
		return MLIP_E_SYNTAX;
	}
	if (!has(ps, SEC_TRAJ, TK_COORDS)) {
		return missing(err, tr->at.line, 0, "COORDINATES", SEC_TRAJ);
	}
	/* an axis section for a letter not in COORDINATES: the first in the file */
	for (i = 0; i < MLIP_MAX_AXES; i++) {
		const struct sec *st = &ps->sec[SEC_AXIS0 + i];
		int listed = memchr(ps->coords, AXIS_LETTERS[i], (size_t)ps->n_coords) != NULL;
		if (st->at.line != 0 && !listed &&
		    (first < 0 || st->at.line < ps->sec[SEC_AXIS0 + first].at.line)) {
			first = i;
		}
	}
	if (first >= 0) {
		const struct sec *st = &ps->sec[SEC_AXIS0 + first];
		err_at(err, &b, st->at.line, st->at.col);
		mlip_tb_puts(&b, "section [AXIS_");
		mlip_tb_putc(&b, AXIS_LETTERS[first]);
		mlip_tb_puts(&b, "] is for axis ");
		mlip_tb_putc(&b, AXIS_LETTERS[first]);
		mlip_tb_puts(&b, ", which is not in COORDINATES (line ");
		mlip_tb_uint(&b, tr->key[TK_COORDS].line);
		mlip_tb_putc(&b, ')');
		return MLIP_E_SYNTAX;
	}
	for (i = 0; i < ps->n_coords; i++) {
		if (ps->sec[SEC_AXIS0 + letter_index(ps->coords[i])].at.line == 0) {
			err_at(err, &b, tr->key[TK_COORDS].line, ps->coord_col[i]);
			mlip_tb_puts(&b, "missing section [AXIS_");
			mlip_tb_putc(&b, ps->coords[i]);
			mlip_tb_puts(&b, "] for axis ");
			mlip_tb_putc(&b, ps->coords[i]);
			mlip_tb_puts(&b, " of COORDINATES");
			return MLIP_E_SYNTAX;
		}
	}
	for (k = 0; k < NKEYS; k++) {
		if (mlip_mc_keytab[K_TRAJ][k].required && !has(ps, SEC_TRAJ, k)) {
			return missing(err, tr->at.line, 0, mlip_mc_keytab[K_TRAJ][k].name,
			               SEC_TRAJ);
		}
	}
	for (i = 0; i < ps->n_coords; i++) {
		int sec = SEC_AXIS0 + letter_index(ps->coords[i]);
		for (k = 0; k < NKEYS; k++) {
			if (mlip_mc_keytab[K_AXIS][k].required && !has(ps, sec, k)) {
				return missing(err, ps->sec[sec].at.line, 0,
				               mlip_mc_keytab[K_AXIS][k].name, sec);
			}
		}
	}
	return MLIP_OK;
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
		a->max_jerk = has(ps, sec, AK_JERK) ? st->num[AK_JERK] : 0.0; /* 0: none */
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
	if (has(ps, SEC_TRAJ, TK_JERK_PLAN)) {
		c->jerk_plan = (uint8_t)tr->ival[TK_JERK_PLAN];
		c->jerk_plan_line = tr->key[TK_JERK_PLAN].line;
	}
}

/* JERK_PLAN = path plans with every axis's jerk limit: one without is
 * refused at the key. */
static mlip_status check_jerk_plan(const struct pstate *ps, const struct mlip_config *c,
                                   struct mlip_config_error *err)
{
	struct mlip_tb b;
	if (c->jerk_plan != MLIP_JERK_PLAN_PATH) {
		return MLIP_OK;
	}
	for (int i = 0; i < c->machine.n_axes; i++) {
		if (!(c->machine.axis[i].max_jerk > 0.0)) {
			err_at(err, &b, 0, 0);
			mlip_tb_puts(&b, "JERK_PLAN = path needs MAX_JERK on every axis; [AXIS_");
			mlip_tb_putc(&b, c->machine.axis[i].letter);
			mlip_tb_puts(&b, "] has none");
			mlip_mc_place(ps, err, SEC_TRAJ, TK_JERK_PLAN, -1, 0, -1, 0);
			return MLIP_E_RANGE;
		}
	}
	return MLIP_OK;
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
		const char *name = mlip_can_profile_name((mlip_can_profile)st->ival[CK_PROFILE]);
		memcpy(can->profile, name, strlen(name));
	}
	for (k = CK_BITRATE; k < NKEYS; k++) {
		if (has(ps, SEC_CAN, k) && dst[k] != NULL) {
			*dst[k] = (uint32_t)st->ival[k];
		}
	}
}

/* The CAN id rules (mlip/can/canconf.h) for the file's profile, the error
 * on the latest of the keys involved. */
static mlip_status check_can(const struct pstate *ps, const struct mlip_config *c,
                             struct mlip_config_error *err)
{
	struct mlip_can_issue is;
	mlip_status st = mlip_can_rules(&c->can, &c->machine, &is);
	int s[3] = {-1, -1, -1}, k[3] = {0, 0, 0}, i;

	if (st == MLIP_OK) {
		return st;
	}
	err->line = err->col = 0;
	memcpy(err->msg, is.msg, sizeof err->msg);
	for (i = 0; i < is.n_keys; i++) {
		if (is.at[i].key == MLIP_CAN_KEY_NODE) { /* machine index -> section */
			s[i] = SEC_AXIS0 + letter_index(c->machine.axis[is.at[i].axis].letter);
			k[i] = AK_NODE;
		} else {
			s[i] = SEC_CAN;
			k[i] = is.at[i].key;
		}
	}
	mlip_mc_place(ps, err, s[0], k[0], s[1], k[1], s[2], k[2]);
	return st;
}

mlip_status mlip_can_config_check(const struct mlip_can_config *can, const struct mlip_machine *m,
                                  struct mlip_config_error *err)
{
	struct mlip_can_issue is;
	mlip_status st;

	if (can == NULL || m == NULL) {
		return MLIP_E_INVALID;
	}
	st = mlip_can_rules(can, m, &is);
	if (err != NULL) {
		err->line = err->col = 0;
		memcpy(err->msg, st == MLIP_OK ? "" : is.msg, st == MLIP_OK ? 1 : sizeof err->msg);
	}
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
	mlip_mc_fill_drives(&ps, &out.drives);
	st = mlip_mc_check_machine(&out.machine, err, &is);
	if (st != MLIP_OK) {
		if (is.key == TK_PERIOD && is.axis2 >= 0) {
			/* the period against eps and the largest acceleration: on
			 * PERIOD when the file sets it, else on the later of the
			 * tolerance and that acceleration */
			int sec = SEC_AXIS0 + letter_index(out.machine.axis[is.axis2].letter);
			if (has(&ps, SEC_TRAJ, TK_PERIOD)) {
				mlip_mc_place(&ps, err, SEC_TRAJ, TK_PERIOD, -1, 0, -1, 0);
			} else {
				mlip_mc_place(&ps, err, SEC_TRAJ, TK_TOL, sec, AK_ACC, -1, 0);
			}
		} else if (is.axis < 0) {
			mlip_mc_place(&ps, err, SEC_TRAJ, is.key, -1, 0, -1, 0);
		} else {
			int sec = SEC_AXIS0 + letter_index(out.machine.axis[is.axis].letter);
			if (is.key == AK_MIN) {
				mlip_mc_place(&ps, err, sec, AK_MIN, sec, AK_MAX, -1, 0);
			} else if (is.key == AK_HOME && !has(&ps, sec, AK_HOME)) {
				mlip_mc_place(&ps, err, sec, AK_MIN, sec, AK_MAX, -1, 0);
			} else if (is.key == AK_NODE && is.axis2 >= 0) {
				char l2 = out.machine.axis[is.axis2].letter;
				int sec2 = SEC_AXIS0 + letter_index(l2);
				mlip_mc_place(&ps, err, sec, AK_NODE, sec2, AK_NODE, -1, 0);
			} else {
				mlip_mc_place(&ps, err, sec, is.key, -1, 0, -1, 0);
			}
		}
		return st;
	}
	st = check_can(&ps, &out, err);
	if (st == MLIP_OK) {
		st = check_jerk_plan(&ps, &out, err);
	}
	if (st == MLIP_OK) {
		st = mlip_mc_check_drives(&ps, &out, err);
	}
	if (st == MLIP_OK) {
		mlip_mc_fill_io(&ps, &out);
		st = mlip_mc_check_io(&ps, &out, err);
	}
	if (st == MLIP_OK) {
		st = mlip_mc_fill_inputs(&ps, &out, err);
	}
	if (st == MLIP_OK) {
		st = mlip_mc_fill_outputs(&ps, &out, err);
	}
	if (st == MLIP_OK) {
		st = mlip_mc_fill_home(&ps, &out, err);
	}
	if (st != MLIP_OK) {
		return st;
	}
	*c = out;
	return MLIP_OK;
}
