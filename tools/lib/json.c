/* json.c - see json.h */
#include "json.h"

#include <inttypes.h>
#include <math.h>

/* Bytes of the valid UTF-8 sequence at p (1..4), 0 when it is not one
 * (RFC 3629: no overlong forms, no surrogates, nothing above U+10FFFF). */
static int utf8_len(const unsigned char *p)
{
	unsigned c = p[0];
	int n;
	uint32_t cp;
	if (c < 0x80) {
		return 1;
	}
	if (c >= 0xC2 && c <= 0xDF) {
		n = 2;
		cp = c & 0x1Fu;
	} else if (c >= 0xE0 && c <= 0xEF) {
		n = 3;
		cp = c & 0x0Fu;
	} else if (c >= 0xF0 && c <= 0xF4) {
		n = 4;
		cp = c & 0x07u;
	} else {
		return 0;
	}
	for (int i = 1; i < n; i++) {
		if ((p[i] & 0xC0u) != 0x80u) {
			return 0; /* also the terminating NUL */
		}
		cp = (cp << 6) | (p[i] & 0x3Fu);
	}
	if ((n == 3 && cp < 0x800u) || (n == 4 && (cp < 0x10000u || cp > 0x10FFFFu)) ||
	    (cp >= 0xD800u && cp <= 0xDFFFu)) {
		return 0;
	}
	return n;
}

void mlip_json_str(FILE *f, const char *s)
{
	const unsigned char *p = (const unsigned char *)s;
	fputc('"', f);
	while (*p != '\0') {
		int n = utf8_len(p);
		if (n == 0) {
			fprintf(f, "\\udc%02x", *p++); /* surrogateescape */
		} else if (*p == '"' || *p == '\\') {
			fprintf(f, "\\%c", *p++);
		} else if (*p == '\n') {
			fputs("\\n", f);
			p++;
		} else if (*p == '\t') {
			fputs("\\t", f);
			p++;
		} else if (*p < 0x20) {
			fprintf(f, "\\u%04x", *p++);
		} else {
			fwrite(p, 1, (size_t)n, f);
			p += n;
		}
	}
	fputc('"', f);
}

static void indent(const struct mlip_json *j)
{
	fputc('\n', j->f);
	for (int i = 0; i < j->depth; i++) {
		fputs("  ", j->f);
	}
}

/* Before a member or element: the comma, the line, the key. */
static void item(struct mlip_json *j, const char *key)
{
	int d = j->depth - 1;
	if (d < 0) {
		return;
	}
	if (j->members[d]++ > 0) {
		fputs(j->one_line[d] ? ", " : ",", j->f);
	}
	if (!j->one_line[d]) {
		indent(j);
	}
	if (key != NULL) {
		mlip_json_str(j->f, key);
		fputs(": ", j->f);
	}
}

static void open_level(struct mlip_json *j, const char *key, char open, char close, int one_line)
{
	if (j->depth >= MLIP_JSON_DEPTH) {
		j->too_deep = 1;
		return;
	}
	item(j, key);
	fputc(open, j->f);
	j->members[j->depth] = 0;
	j->closer[j->depth] = close;
	j->one_line[j->depth] = (char)(one_line || (j->depth > 0 && j->one_line[j->depth - 1]));
	j->depth++;
}

void mlip_json_begin(struct mlip_json *j, FILE *f)
{
	j->f = f;
	j->depth = 0;
	j->too_deep = 0;
	open_level(j, NULL, '{', '}', 0);
}

void mlip_json_object(struct mlip_json *j, const char *key, int one_line)
{
	open_level(j, key, '{', '}', one_line);
}

void mlip_json_array(struct mlip_json *j, const char *key, int one_line)
{
	open_level(j, key, '[', ']', one_line);
}

void mlip_json_close(struct mlip_json *j)
{
	if (j->depth <= 0) {
		return;
	}
	int d = --j->depth;
	if (j->members[d] > 0 && !j->one_line[d]) {
		indent(j);
	}
	fputc(j->closer[d], j->f);
}

int mlip_json_end(struct mlip_json *j)
{
	while (j->depth > 0) {
		mlip_json_close(j);
	}
	fputc('\n', j->f);
	return ferror(j->f) || j->too_deep ? -1 : 0;
}

void mlip_json_string(struct mlip_json *j, const char *key, const char *v)
{
	item(j, key);
	mlip_json_str(j->f, v);
}

void mlip_json_number(struct mlip_json *j, const char *key, const char *fmt, double v)
{
	item(j, key);
	if (isfinite(v)) {
		fprintf(j->f, fmt, v);
	} else {
		fputs("null", j->f);
	}
}

void mlip_json_numbers(struct mlip_json *j, const char *key, const char *fmt, const double *v,
                       int n)
{
	mlip_json_array(j, key, 1);
	for (int i = 0; i < n; i++) {
		mlip_json_number(j, NULL, fmt, v[i]);
	}
	mlip_json_close(j);
}

void mlip_json_uint(struct mlip_json *j, const char *key, uint64_t v)
{
	item(j, key);
	fprintf(j->f, "%" PRIu64, v);
}

void mlip_json_int(struct mlip_json *j, const char *key, int64_t v)
{
	item(j, key);
	fprintf(j->f, "%" PRId64, v);
}

void mlip_json_bool(struct mlip_json *j, const char *key, int v)
{
	item(j, key);
	fputs(v ? "true" : "false", j->f);
}

void mlip_json_null(struct mlip_json *j, const char *key)
{
	item(j, key);
	fputs("null", j->f);
}

void mlip_json_raw(struct mlip_json *j, const char *key, const char *v)
{
	item(j, key);
	fputs(v, j->f);
}
