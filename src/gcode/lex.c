/*
 * lex.c - step 1 of a line: bytes -> words (letter, number, column);
 * comments skipped, malformed numbers, stray bytes and bad UTF-8 rejected.
 * Numbers through the core's one number lexer (mlip/text/number.h): G-code
 * has no exponent, so "1e5" runs on and is malformed.
 */
#include <stdarg.h>

#include "gc.h"
#include "mlip/text/format.h"
#include "mlip/text/number.h"

mlip_status mlip_gc_fail(struct mlip_gcode_error *e, uint32_t line, uint32_t col, mlip_status st,
                         const char *fmt, ...)
{
	struct mlip_tb b;
	va_list ap;

	e->line = line;
	e->col = col;
	mlip_tb_init(&b, e->msg, sizeof e->msg);
	va_start(ap, fmt);
	mlip_tb_vformat(&b, fmt, ap);
	va_end(ap);
	return st;
}

/* Comment bytes t[i..end) must be well-formed UTF-8 without NUL: returns the
 * offset of the first bad byte, or end. */
static size_t comment_check(const unsigned char *t, size_t i, size_t end)
{
	while (i < end) {
		size_t l = t[i] ? mlip_utf8_len(t + i, end - i) : 0;

		if (!l) {
			return i;
		}
		i += l;
	}
	return end;
}

/* "nan", "inf", "infinity" (any case) as the letters at t[i..): strtod would
 * take them, so name them as malformed numbers. */
static int is_nan_inf(const char *t, size_t n, size_t i, size_t *end)
{
	static const char *const names[] = {"INFINITY", "INF", "NAN"};
	size_t k, e = i;
	int j;

	while (e < n && mlip_is_alpha(t[e])) {
		e++;
	}
	for (j = 0; j < 3; j++) {
		for (k = 0; names[j][k] && i + k < e && mlip_upper(t[i + k]) == names[j][k]; k++) {
		}
		if (!names[j][k] && i + k == e) {
			*end = e;
			return 1;
		}
	}
	return 0;
}

/* A unary function (SIN[..]) begins at t[j]: letters, then '['. */
static int function_next(const char *t, size_t n, size_t j)
{
	while (j < n && mlip_is_alpha(t[j])) {
		j++;
	}
	while (j < n && mlip_is_blank(t[j])) {
		j++;
	}
	return j < n && t[j] == '[';
}

/* One word at t[*pi] (a letter); blanks may separate letter and value: a
 * number, or a parameter, expression or function (expr.c). */
static mlip_status lex_word(struct mlip_gcode *g, const char *t, size_t n, size_t *pi,
                            uint32_t line, struct word *w, struct mlip_gcode_error *e)
{
	size_t i = *pi, j, k;

	w->letter = mlip_upper(t[i]);
	w->col = (uint32_t)i + 1;
	for (j = i + 1; j < n && mlip_is_blank(t[j]); j++) {
	}
	if (j < n && mlip_gc_starts_number(t[j]) &&
	    !((t[j] == '+' || t[j] == '-') && j + 1 < n && (t[j + 1] == '#' || t[j + 1] == '['))) {
		return mlip_gc_number(t, n, j, 0, line, &w->value, pi, e);
	}
	if (j < n && is_nan_inf(t, n, j, &k)) {
		return mlip_gc_fail(e, line, (uint32_t)j + 1, MLIP_E_SYNTAX,
		                    "malformed number '%t'", t + j, k - j);
	}
	if (j < n && (t[j] == '#' || t[j] == '[' || t[j] == '+' || t[j] == '-' ||
	              (mlip_is_alpha(t[j]) && function_next(t, n, j)))) {
		*pi = j;
		return mlip_gc_real_value(g, t, n, pi, line, &w->value, e);
	}
	return mlip_gc_fail(e, line, w->col, MLIP_E_SYNTAX, "word %c has no number", w->letter);
}

mlip_status mlip_gc_lex_line(struct mlip_gcode *g, const char *text, size_t len, uint32_t line,
                             struct lexed *lx, struct mlip_gcode_error *e)
{
	const unsigned char *t = (const unsigned char *)text;
	size_t i = 0, end, k;
	int percent = 0;
	mlip_status st;

	lx->n = 0;
	lx->n_set = 0;
	lx->first_col = 0;
	lx->percent = 0;
	if (line == 1 && len >= 3 && t[0] == 0xEF && t[1] == 0xBB && t[2] == 0xBF) {
		i = 3; /* UTF-8 byte order mark */
	}
	while (i < len) {
		unsigned char c = t[i];
		uint32_t col = (uint32_t)i + 1;

		if (mlip_is_blank(c)) {
			i++;
			continue;
		}
		if (c == '(' || c == ';') {
			for (end = i + 1; c == '(' && end < len && t[end] != ')'; end++) {
			}
			end = c == ';' ? len : end;
			k = comment_check(t, i + 1, end);
			if (k < end) {
				return mlip_gc_fail(e, line, (uint32_t)k + 1, MLIP_E_SYNTAX,
				                    t[k] ? "invalid UTF-8 in comment"
				                         : "NUL byte in line");
			}
			if (c == '(' && end == len) {
				return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX,
				                    "unterminated comment: '(' without ')'");
			}
			i = end + 1;
			continue;
		}
		if (percent) {
			return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX,
			                    "'%%' must be alone on its line");
		}
		if (!lx->first_col) {
			lx->first_col = col;
			if (c == '%') { /* program delimiter */
				percent = 1;
				lx->percent = 1;
				i++;
				continue;
			}
			if (c == '/') {
				return mlip_gc_fail(e, line, col, MLIP_E_UNSUPPORTED,
				                    "block delete '/' not supported");
			}
		}
		if (c == 0) {
			return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX, "NUL byte in line");
		}
		if (c >= 0x80) {
			return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX,
			                    "non-ASCII byte %b outside a comment", c);
		}
		if (mlip_is_alpha(c)) {
			st = lex_word(g, text, len, &i, line, &lx->w[lx->n], e);
			if (st != MLIP_OK) {
				return st;
			}
			lx->n++;
			continue;
		}
		if (mlip_gc_starts_number(c)) {
			for (k = i; k < len && mlip_gc_starts_number(t[k]); k++) {
			}
			return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX,
			                    "number '%t' without a word letter", text + i, k - i);
		}
		if (c == '#') {
			st = mlip_gc_setting(g, text, len, &i, line, lx, e);
			if (st != MLIP_OK) {
				return st;
			}
			continue;
		}
		return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX, "unexpected character %b", c);
	}
	return MLIP_OK;
}
