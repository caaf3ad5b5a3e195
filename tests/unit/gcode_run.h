/*
 * gcode_run.h - the G-code reader run over a text, line by line, for the
 * unit tests of the reader's I/O words (test_io.c, test_machio.c): every
 * error counted, the first kept. The including file defines gr_machine().
 */
#ifndef MLIP_TEST_GCODE_RUN_H
#define MLIP_TEST_GCODE_RUN_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mlip/gcode/gcode.h"

static struct mlip_machine gr_machine(void);

#define MAXB 256

struct sink {
	struct mlip_block b[MAXB];
	int n;
};

static int put(void *ctx, const struct mlip_block *b)
{
	struct sink *s = ctx;

	if (s->n == MAXB) {
		return -1;
	}
	s->b[s->n++] = *b;
	return 0;
}

struct run {
	struct mlip_machine m;
	struct mlip_gcode g;
	struct sink s;
	struct mlip_gcode_error e;
	int errors;
	uint32_t first_line, first_col;
	char first_msg[MLIP_GCODE_MSG];
};

static int gr_mdi; /* run() parses MDI lines (mlip_gcode_set_mdi) */

/* Parse text line by line with io (NULL: none set); every error counted,
 * the first kept. */
static void run(struct run *r, const struct mlip_gcode_io *io, const char *text)
{
	const char *p = text;
	uint32_t line = 0;

	memset(r, 0, sizeof *r);
	r->m = gr_machine();
	mlip_gcode_init(&r->g, &r->m);
	mlip_gcode_set_io(&r->g, io);
	mlip_gcode_set_mdi(&r->g, gr_mdi);
	while (*p) {
		const char *nl = strchr(p, '\n');
		size_t n = nl ? (size_t)(nl - p) : strlen(p);
		line++;
		if (mlip_gcode_line(&r->g, p, n, line, put, &r->s, &r->e) != MLIP_OK) {
			if (r->errors++ == 0) {
				r->first_line = r->e.line;
				r->first_col = r->e.col;
				memcpy(r->first_msg, r->e.msg, sizeof r->first_msg);
			}
		}
		p += n + (nl != NULL);
	}
}

static void expect_err(const struct mlip_gcode_io *io, const char *text, uint32_t line,
                       uint32_t col, const char *part)
{
	struct run *r = malloc(sizeof *r);

	assert_non_null(r);
	run(r, io, text);
	if (r->errors == 0 || r->first_line != line || r->first_col != col ||
	    strstr(r->first_msg, part) == NULL) {
		fprintf(stderr,
		        "for \"%s\": %d errors, first %u:%u \"%s\"; expected %u:%u \"%s\"\n", text,
		        r->errors, r->first_line, r->first_col, r->first_msg, line, col, part);
		fail();
	}
	free(r);
}

#endif
