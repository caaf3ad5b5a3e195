/*
 * json.h - the one JSON writer of the tools (summaries, --json results,
 * status): a tree written to a FILE as it is built, two spaces a level,
 * commas, quoting and escaping done here, nothing allocated.
 *
 *   struct mlip_json j;
 *   mlip_json_begin(&j, f);                  {
 *   mlip_json_string(&j, "file", path);        "file": "a \"b\".ngc",
 *   mlip_json_array(&j, "acc", 1);             "acc": [1, 2],
 *   mlip_json_number(&j, NULL, "%g", 1); ...
 *   mlip_json_close(&j);
 *   mlip_json_end(&j);                       }
 *
 * Strings are escaped as RFC 8259 says (quote, backslash, control
 * characters); a byte that is not part of valid UTF-8 (a file name may hold
 * any) is written as \udcXX, Python's surrogateescape, so os.fsencode() of
 * the decoded string gives the bytes back. Numbers that are not finite are
 * null (JSON has no NaN).
 */
#ifndef MLIP_TOOLS_JSON_H
#define MLIP_TOOLS_JSON_H

#include <stdint.h>
#include <stdio.h>

#define MLIP_JSON_DEPTH 8

struct mlip_json {
	FILE *f;
	int depth;                         /* open objects and arrays */
	int too_deep;                      /* nesting beyond MLIP_JSON_DEPTH was refused */
	uint32_t members[MLIP_JSON_DEPTH]; /* written at each level */
	char closer[MLIP_JSON_DEPTH];      /* '}' or ']' */
	char one_line[MLIP_JSON_DEPTH];    /* that level on one line */
};

/* The top-level object: "{". */
void mlip_json_begin(struct mlip_json *j, FILE *f);
/* Closes every level and the top one, "}\n"; 0, or -1 when the stream had
 * an error (or the nesting went beyond MLIP_JSON_DEPTH). */
int mlip_json_end(struct mlip_json *j);
/* A member (key) or element (key NULL) that is an object or an array; on
 * one line when one_line is set. Ends with mlip_json_close. */
void mlip_json_object(struct mlip_json *j, const char *key, int one_line);
void mlip_json_array(struct mlip_json *j, const char *key, int one_line);
void mlip_json_close(struct mlip_json *j);
/* Members (key) or elements (key NULL). */
void mlip_json_string(struct mlip_json *j, const char *key, const char *v);
void mlip_json_number(struct mlip_json *j, const char *key, const char *fmt, double v);
void mlip_json_uint(struct mlip_json *j, const char *key, uint64_t v);
void mlip_json_int(struct mlip_json *j, const char *key, int64_t v);
void mlip_json_bool(struct mlip_json *j, const char *key, int v);
void mlip_json_null(struct mlip_json *j, const char *key);
/* n numbers on one line: [v0, v1, ...] */
void mlip_json_numbers(struct mlip_json *j, const char *key, const char *fmt, const double *v,
                       int n);
/* v is JSON already (e.g. another tool's output, copied in). */
void mlip_json_raw(struct mlip_json *j, const char *key, const char *v);
/* s as a JSON string, quotes included (the escaping above). */
void mlip_json_str(FILE *f, const char *s);

#endif
