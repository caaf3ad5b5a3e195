/*
 * program.c - whole-program parsing for the host tools: file in, block array
 * and error list out. See program.h.
 */
#include "program.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

int mlip_read_file(const char *path, char **buf, size_t *len)
{
	FILE *f;
	char *p = NULL, *q;
	size_t n = 0, cap = 0, got;
	int rc = 0;

	*buf = NULL;
	*len = 0;
	f = fopen(path, "rb");
	if (!f) {
		return -errno;
	}
	/* read in chunks: works for pipes and files whose size changes */
	for (;;) {
		if (cap - n < 2) {
			cap = cap ? cap * 2 : 65536;
			q = realloc(p, cap);
			if (!q) {
				rc = -ENOMEM;
				goto out;
			}
			p = q;
		}
		got = fread(p + n, 1, cap - n - 1, f);
		n += got;
		if (got == 0) {
			if (ferror(f)) {
				rc = errno ? -errno : -EIO;
			}
			break;
		}
	}
out:
	fclose(f);
	if (rc) {
		free(p);
		return rc;
	}
	p[n] = '\0';
	*buf = p;
	*len = n;
	return 0;
}

struct sink_ctx {
	struct mlip_program *prog;
	int oom;
};

static int program_sink(void *ctx, const struct mlip_block *b)
{
	struct sink_ctx *c = ctx;
	struct mlip_program *p = c->prog;

	if (p->n == p->cap) {
		size_t cap = p->cap ? p->cap * 2 : 4096;
		struct mlip_block *nb = realloc(p->blocks, cap * sizeof *nb);

		if (!nb) {
			c->oom = 1;
			return -1;
		}
		p->blocks = nb;
		p->cap = cap;
	}
	p->blocks[p->n++] = *b;
	return 0;
}

static int add_error(struct mlip_program *p, const struct mlip_gcode_error *e)
{
	p->n_errors_total++;
	if (p->n_errors >= MLIP_PROGRAM_MAX_ERRORS) {
		return 0;
	}
	if (!p->errors) {
		p->errors = malloc(MLIP_PROGRAM_MAX_ERRORS * sizeof *p->errors);
		if (!p->errors) {
			return -ENOMEM;
		}
	}
	p->errors[p->n_errors++] = *e;
	return 0;
}

int mlip_program_parse(const char *text, size_t len, const struct mlip_machine *m,
                       struct mlip_program *prog)
{
	struct mlip_gcode g;
	struct mlip_gcode_error err;
	struct sink_ctx sc;
	size_t i = 0;
	uint32_t line = 0;
	mlip_status st;

	memset(prog, 0, sizeof *prog);
	sc.prog = prog;
	sc.oom = 0;
	mlip_gcode_init(&g, m);
	prog->initial_feed_line = mlip_gcode_scan_feed(text, len, &prog->initial_feed_word);
	if (!prog->initial_feed_line) {
		prog->initial_feed_word = 0;
	}
	mlip_gcode_set_initial_feed(&g, prog->initial_feed_word);
	while (i < len) {
		const char *nl = memchr(text + i, '\n', len - i);
		size_t end = nl ? (size_t)(nl - text) : len;

		line++;
		st = mlip_gcode_line(&g, text + i, end - i, line, program_sink, &sc, &err);
		if (sc.oom) {
			return -ENOMEM;
		}
		if (st != MLIP_OK && add_error(prog, &err) != 0) {
			return -ENOMEM;
		}
		i = end + 1;
	}
	prog->lines = line;
	/* "empty program" only when nothing else explains the lack of motion */
	if (prog->n_errors_total == 0 && mlip_gcode_finish(&g, line, &err) != MLIP_OK &&
	    add_error(prog, &err) != 0) {
		return -ENOMEM;
	}
	memcpy(prog->notices, g.notices, sizeof prog->notices);
	prog->n_notices = g.n_notices;
	return prog->n_errors_total ? 1 : 0;
}

int mlip_program_load(const char *path, const struct mlip_machine *m, struct mlip_program *prog)
{
	char *buf;
	size_t len;
	int rc;

	memset(prog, 0, sizeof *prog);
	rc = mlip_read_file(path, &buf, &len);
	if (rc) {
		return rc;
	}
	rc = mlip_program_parse(buf, len, m, prog);
	free(buf);
	return rc;
}

void mlip_program_print_errors(const struct mlip_program *prog, const char *path, FILE *f)
{
	size_t k;

	for (k = 0; k < prog->n_errors; k++) {
		const struct mlip_gcode_error *e = &prog->errors[k];

		if (e->col) {
			fprintf(f, "%s:%u:%u: error: %s\n", path, (unsigned)e->line,
			        (unsigned)e->col, e->msg);
		} else {
			fprintf(f, "%s:%u: error: %s\n", path, (unsigned)e->line, e->msg);
		}
	}
	if (prog->n_errors_total > prog->n_errors) {
		fprintf(f, "%s: %zu more errors not listed\n", path,
		        prog->n_errors_total - prog->n_errors);
	}
	if (prog->n_errors_total) {
		fprintf(f, "%s: %zu error%s, program rejected: nothing was run\n", path,
		        prog->n_errors_total, prog->n_errors_total == 1 ? "" : "s");
	}
}

void mlip_program_print_notices(const struct mlip_program *prog, const char *path, FILE *f)
{
	uint32_t k;

	for (k = 0; k < prog->n_notices; k++) {
		const struct mlip_gcode_notice *n = &prog->notices[k];

		if (strcmp(n->word, "F") == 0) {
			fprintf(f,
			        "%s:%u: note: F missing before a feed move: the program's first F"
			        " (F%g, line %u) is used for %u move%s before it\n",
			        path, (unsigned)n->first_line, prog->initial_feed_word,
			        (unsigned)prog->initial_feed_line, (unsigned)n->count,
			        n->count == 1 ? "" : "s");
			continue;
		}
		fprintf(f, "%s:%u: note: %s %s", path, (unsigned)n->first_line, n->word,
		        mlip_gcode_notice_text(n));
		if (n->count > 1) {
			fprintf(f, " (%u times)", (unsigned)n->count);
		}
		fputc('\n', f);
	}
}

void mlip_program_free(struct mlip_program *prog)
{
	free(prog->blocks);
	free(prog->errors);
	memset(prog, 0, sizeof *prog);
}
