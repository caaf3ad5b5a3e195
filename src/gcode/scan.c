/*
 * scan.c - whole-program scans (no machine needed): the axis letters a
 * program uses, its first F.
 */
#include "gc.h"
#include "mlip/text/number.h"

/* A unary function's name, then '[' (X SIN[30]), at t[j]. */
static int function_at(const char *t, size_t n, size_t j)
{
	size_t k = j, q;
	while (k < n && mlip_is_alpha(t[k])) {
		k++;
	}
	for (q = k; q < n && mlip_is_blank(t[q]); q++) {
	}
	if (q >= n || t[q] != '[') {
		return 0;
	}
	for (size_t f = 0; f < MLIP_GC_N_FUNCTIONS; f++) {
		size_t m = 0;
		while (mlip_gc_functions[f][m] && j + m < k &&
		       mlip_upper(t[j + m]) == mlip_gc_functions[f][m]) {
			m++;
		}
		if (!mlip_gc_functions[f][m] && j + m == k) {
			return 1;
		}
	}
	return 0;
}

/* Next word outside comments from *pi on: its letter (upper case), where its
 * number starts, and its line. A letter counts only when a value follows it
 * (after blanks: a number, #, [ or a function), as for the lexer. */
static int next_word(const char *t, size_t n, size_t *pi, uint32_t *line, char *letter, size_t *num)
{
	size_t i = *pi, j;
	int depth = 0; /* inside [ ]: functions and operators, no words */

	while (i < n) {
		char c = t[i];

		if (c == '\n' || (c == '\r' && (i + 1 == n || t[i + 1] != '\n'))) {
			(*line)++; /* LF, CRLF or a lone CR */
			depth = 0;
			i++;
		} else if (c == '[' || c == ']') {
			depth += c == '[' ? 1 : depth > 0 ? -1 : 0;
			i++;
		} else if (depth > 0 && c != '(' && c != ';') {
			i++;
		} else if (c == '(' || c == ';') {
			while (i < n && t[i] != '\n' && t[i] != '\r' &&
			       !(c == '(' && t[i] == ')')) {
				i++;
			}
			i += i < n && t[i] == ')';
		} else if (c == '#' && i + 1 < n && t[i + 1] == '<') {
			while (i < n && t[i] != '>' && t[i] != '\n' && t[i] != '\r') {
				i++; /* a named parameter's name */
			}
		} else if (mlip_is_alpha(c)) {
			for (j = i + 1; j < n && mlip_is_blank(t[j]); j++) {
			}
			i++;
			if (j < n && (mlip_gc_starts_number(t[j]) || t[j] == '#' || t[j] == '[' ||
			              function_at(t, n, j))) {
				*letter = mlip_upper(c);
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
		k = mlip_gc_axis_slot(L);
		if (k >= 0) {
			used[k] = 1;
		}
	}
	for (k = 0; k < 6; k++) {
		if (used[k]) {
			letters[n++] = GC_AXES[k];
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
	struct mlip_number n;
	double v, f = 0;
	int k;
	char L;

	while (next_word(text, len, &i, &line, &L, &num)) {
		k = mlip_gc_axis_slot(L);
		if (k >= 0) {
			*axes |= 1u << k;
		}
		if (L == 'F' && !(f > 0)) {
			mlip_number_lex(text, len, num, 0, &n);
			v = mlip_number_value(&n);
			f = n.ndig > 0 && v > 0 ? v : 0;
		}
	}
	return f;
}
