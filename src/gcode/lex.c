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

/* One word at t[*pi] (a letter); blanks may separate letter and number. */
static mlip_status lex_word(const char *t, size_t n, size_t *pi, uint32_t line, struct word *w,
                            struct mlip_gcode_error *e)
{
	struct mlip_number num;
	size_t i = *pi, j, k;
	int ndig;

	w->letter = mlip_upper(t[i]);
	w->col = (uint32_t)i + 1;
	for (j = i + 1; j < n && mlip_is_blank(t[j]); j++) {
	}
	if (j < n && mlip_gc_starts_number(t[j])) {
		k = mlip_number_lex(t, n, j, 0, &num);
		ndig = num.ndig;
		w->value = mlip_number_value(&num);
		/* "1.2.3", "1e5", "--1", ".": the number runs on in number-like bytes */
		if (ndig == 0 || (k < n && (t[k] == '.' || t[k] == '+' || t[k] == '-')) ||
		    (k + 1 < n && (t[k] == 'e' || t[k] == 'E') &&
		     (mlip_is_digit(t[k + 1]) || t[k + 1] == '+' || t[k + 1] == '-'))) {
			while (k < n &&
			       (mlip_gc_starts_number(t[k]) || t[k] == 'e' || t[k] == 'E')) {
				k++;
			}
			return mlip_gc_fail(e, line, (uint32_t)j + 1, MLIP_E_SYNTAX,
			                    "malformed number '%t'", t + j, k - j);
		}
		*pi = k;
		return MLIP_OK;
	}
	if (j < n && is_nan_inf(t, n, j, &k)) {
		return mlip_gc_fail(e, line, (uint32_t)j + 1, MLIP_E_SYNTAX,
		                    "malformed number '%t'", t + j, k - j);
	}
	if (j < n && (t[j] == '#' || t[j] == '[')) {
		return mlip_gc_fail(
		    e, line, (uint32_t)j + 1, MLIP_E_UNSUPPORTED,
		    "parameters and expressions (# [ ]) not supported: have the CAM "
		    "write plain numbers");
	}
	return mlip_gc_fail(e, line, w->col, MLIP_E_SYNTAX, "word %c has no number", w->letter);
}

mlip_status mlip_gc_lex_line(const char *text, size_t len, uint32_t line, struct lexed *lx,
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
			st = lex_word(text, len, &i, line, &lx->w[lx->n], e);
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
			return mlip_gc_fail(
			    e, line, col, MLIP_E_UNSUPPORTED,
			    "parameters and expressions (# [ ]) not supported: have the CAM "
			    "write plain numbers");
		}
		return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX, "unexpected character %b", c);
	}
	return MLIP_OK;
}
