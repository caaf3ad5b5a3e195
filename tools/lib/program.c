/*
 * program.c - program reading in two passes and bounded memory: check the
 * whole file, then stream its blocks. See program.h.
 */
#include "program.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "sha256.h"
#include "statefile.h"

#define LINE_CAP (MLIP_GCODE_MAX_LINE + 2) /* one byte more than a valid line */

/* ---- the file, in pinned chunks (program.h) ---- */

static void stale(struct mlip_program *p, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
static void stale(struct mlip_program *p, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(p->stale, sizeof p->stale, fmt, ap);
	va_end(ap);
	p->io_err = -ESTALE;
}

/* The next chunk into p->buf, recorded in the pin (the first pass) or
 * verified against it (every other one) before a byte of it is used: its
 * length (0 at the end), or -1 with p->io_err. */
static int load_chunk(struct mlip_program *p)
{
	size_t n = 0, k = p->chunk_at;
	unsigned long long at = (unsigned long long)k * p->chunk;
	uint8_t h[MLIP_SHA256_BYTES];

	while (n < p->chunk) {
		ssize_t r = read(p->fd, p->buf + n, p->chunk - n);
		if (r < 0 && errno == EINTR) {
			continue;
		}
		if (r < 0) {
			p->io_err = -errno;
			return -1;
		}
		if (r == 0) {
			break;
		}
		n += (size_t)r;
	}
	p->buf_len = n;
	p->buf_pos = 0;
	if (n == 0) {
		if (p->pinning) {
			p->n_chunks = k;
		} else if (k != p->n_chunks) {
			stale(p, "it ends at byte %llu, before the %llu chunks that were checked",
			      at, (unsigned long long)p->n_chunks);
			return -1;
		}
		return 0;
	}
	mlip_sha256(p->buf, n, h);
	if (p->pinning) {
		if (k == MLIP_PROGRAM_MAX_CHUNKS) {
			stale(p, "it grew past byte %llu while it was read (%llu chunks)", at,
			      (unsigned long long)k);
			return -1;
		}
		memcpy(p->pin[k], h, MLIP_PROGRAM_PIN_BYTES);
	} else if (k >= p->n_chunks) {
		stale(p, "bytes from %llu on were not there when it was checked", at);
		return -1;
	} else if (memcmp(p->pin[k], h, MLIP_PROGRAM_PIN_BYTES) != 0) {
		stale(p, "bytes %llu to %llu differ from the ones checked", at,
		      at + (unsigned long long)n - 1);
		return -1;
	}
	p->chunk_at++;
	return (int)n;
}

/* ---- lines: LF, CRLF or a lone CR end one ---- */

static int get_byte(struct mlip_program *p)
{
	if (p->file) {
		if (p->buf_pos == p->buf_len && (p->io_err || load_chunk(p) <= 0)) {
			return EOF;
		}
		return p->buf[p->buf_pos++];
	}
	return p->mem_pos < p->mem_len ? (unsigned char)p->mem[p->mem_pos++] : EOF;
}

static void unget_byte(struct mlip_program *p, int c)
{
	(void)c;
	if (p->file) {
		p->buf_pos--; /* the byte just taken is still in the buffer */
	} else {
		p->mem_pos--;
	}
}

/* The next line into p->line (at most LINE_CAP bytes kept, p->line_len
 * counts them all): 1, 0 at the end of the input, -errno (-ESTALE: the
 * file is not the one checked, p->stale says how). */
static int read_line(struct mlip_program *p)
{
	size_t n = 0;
	int c, any = 0;

	for (;;) {
		c = get_byte(p);
		if (c == EOF) {
			if (p->file && p->io_err) {
				return p->io_err;
			}
			break;
		}
		any = 1;
		if (c == '\n') {
			break;
		}
		if (c == '\r') {
			c = get_byte(p);
			if (c != '\n' && c != EOF) {
				unget_byte(p, c);
			}
			if (c == EOF && p->file && p->io_err) {
				return p->io_err;
			}
			break;
		}
		if (n < LINE_CAP) {
			p->line[n] = (char)c;
		}
		n += n < (size_t)-1;
	}
	p->line_len = n;
	return any ? 1 : 0;
}

static int rewind_input(struct mlip_program *p)
{
	if (p->file) {
		if (lseek(p->fd, 0, SEEK_SET) != 0) {
			return -errno;
		}
		p->buf_len = p->buf_pos = p->chunk_at = 0;
		p->io_err = 0;
		p->pinning = 0; /* only the first pass records */
	} else {
		p->mem_pos = 0;
	}
	p->lineno = 0;
	return 0;
}

/* The message for a failed read: a changed file, or the system's error. */
static void read_failed(struct mlip_program *p, int rc, const char *when)
{
	if (rc == -ESTALE) {
		snprintf(p->msg, sizeof p->msg, "the file changed %s (%s, line %u)", when, p->stale,
		         (unsigned)p->lineno + 1);
	} else {
		snprintf(p->msg, sizeof p->msg, "%s", strerror(-rc));
	}
}

/* The parser gets the length as read: it reads no byte of a line longer
 * than a valid one (that is an error), so the bytes not kept are not needed. */
static size_t line_arg(const struct mlip_program *p)
{
	return p->line_len;
}

/* The bytes of the line that are kept. */
static size_t line_kept(const struct mlip_program *p)
{
	return p->line_len > LINE_CAP ? LINE_CAP : p->line_len;
}

/* ---- opening ---- */

/* A regular file, opened without blocking on a FIFO: the fd, or -1 with
 * msg; *size its size. */
static int open_regular(const char *path, char *msg, size_t len, uint64_t *size)
{
	struct stat st;
	int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);

	if (fd < 0) {
		snprintf(msg, len, "%s", strerror(errno));
		return -1;
	}
	if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
		snprintf(msg, len,
		         "%s: mlip reads a program from a regular file only (it checks the whole "
		         "file before anything moves, then reads it again to run it): save it to "
		         "a file first",
		         mlip_file_kind(st.st_mode));
		close(fd);
		return -1;
	}
	if (fcntl(fd, F_SETFL, 0) != 0) {
		snprintf(msg, len, "%s", strerror(errno));
		close(fd);
		return -1;
	}
	*size = (uint64_t)st.st_size;
	return fd;
}

/* Open path as p's input: the fd, the chunk buffer, and (pin NULL) a new
 * pin table recorded by the first pass, else the given one (a second reader
 * of a checked program). 0, or < 0 with p->msg. */
static int open_file(struct mlip_program *p, const char *path,
                     uint8_t (*pin)[MLIP_PROGRAM_PIN_BYTES], size_t chunk)
{
	uint64_t size = 0;
	p->fd = open_regular(path, p->msg, sizeof p->msg, &size);
	if (p->fd < 0) {
		return -EINVAL;
	}
	p->file = 1;
	if (pin == NULL) {
		/* 64 KiB chunks, larger for a program over 256 MiB (4096 of them) */
		uint64_t c = (size + MLIP_PROGRAM_MAX_CHUNKS - 1) / MLIP_PROGRAM_MAX_CHUNKS;
		c = (c + 4095) / 4096 * 4096;
		chunk = c > MLIP_PROGRAM_CHUNK ? (size_t)c : MLIP_PROGRAM_CHUNK;
		p->pin = malloc(MLIP_PROGRAM_MAX_CHUNKS * sizeof *p->pin);
		p->pin_owner = 1;
		p->pinning = 1;
	} else {
		p->pin = pin;
	}
	p->chunk = chunk;
	p->buf = malloc(chunk);
	if (!p->pin || !p->buf) {
		snprintf(p->msg, sizeof p->msg, "%s", strerror(ENOMEM));
		return -ENOMEM;
	}
	return 0;
}

static int add_error(struct mlip_program *p, const struct mlip_gcode_error *e)
{
	p->n_errors_total++;
	if (p->n_errors < MLIP_PROGRAM_MAX_ERRORS) {
		p->errors[p->n_errors++] = *e;
	}
	return 0;
}

static int count_sink(void *ctx, const struct mlip_block *b)
{
	(void)b;
	((struct mlip_program *)ctx)->n++;
	return 0;
}

static void start_parser(struct mlip_program *p, struct mlip_gcode *g)
{
	mlip_gcode_init(g, p->m);
	mlip_gcode_set_initial_feed(g, p->initial_feed_word);
	mlip_gcode_set_strict(g, p->opt.strict);
	mlip_gcode_set_offsets(g, &p->offsets_start);
	mlip_gcode_set_io(g, p->opt.io);
	mlip_gcode_set_mdi(g, p->opt.mdi);
	if (p->has_modal) {
		(void)mlip_gcode_set_modal(g, &p->modal_start); /* checked in open_common */
	}
}

/* First pass after the feed scan: every line through the parser, blocks
 * counted only. */
static int check_all(struct mlip_program *p)
{
	struct mlip_gcode_error err;
	unsigned axes = 0;
	double f;
	int rc;

	/* the program's first F, for feed moves before it (scan pass) */
	while ((rc = read_line(p)) > 0) {
		p->lineno++;
		f = mlip_gcode_scan_line(p->line, line_kept(p), &axes);
		/* an over-long line is an error: its F (maybe cut off) is not taken */
		if (f > 0 && !p->initial_feed_line && p->line_len <= MLIP_GCODE_MAX_LINE) {
			p->initial_feed_word = f;
			p->initial_feed_line = p->lineno;
		}
	}
	if (!p->initial_feed_line && p->opt.default_feed > 0) {
		p->initial_feed_word = p->opt.default_feed; /* line 0: from the option */
	}
	if (rc < 0 || (rc = rewind_input(p)) < 0) {
		read_failed(p, rc, "while it was read");
		return rc;
	}
	start_parser(p, &p->g);
	while ((rc = read_line(p)) > 0) {
		p->lineno++;
		if (mlip_gcode_line(&p->g, p->line, line_arg(p), p->lineno, count_sink, p, &err) !=
		    MLIP_OK) {
			add_error(p, &err);
		}
	}
	if (rc < 0) {
		read_failed(p, rc, "while it was checked: check it again");
		return rc;
	}
	p->lines = p->lineno;
	/* "empty program" only when nothing else explains the lack of motion */
	if (p->n_errors_total == 0 && mlip_gcode_finish(&p->g, p->lineno, &err) != MLIP_OK) {
		add_error(p, &err);
	}
	memcpy(p->notices, p->g.notices, sizeof p->notices);
	p->n_notices = p->g.n_notices;
	p->offsets_end = p->g.off;
	mlip_gcode_get_modal(&p->g, &p->modal_end);
	p->moves = p->g.moves;
	return p->n_errors_total ? 1 : 0;
}

static int open_common(struct mlip_program *p, const struct mlip_machine *m,
                       const struct mlip_program_options *opt)
{
	p->m = m;
	if (opt) {
		p->opt = *opt;
	}
	if (p->opt.offsets) {
		p->offsets_start = *p->opt.offsets;
	} else {
		mlip_gcode_offsets_init(&p->offsets_start, m);
	}
	p->opt.offsets = NULL;
	if (p->opt.modal) {
		struct mlip_gcode g;
		p->modal_start = *p->opt.modal;
		p->has_modal = 1;
		mlip_gcode_init(&g, m);
		if (mlip_gcode_set_modal(&g, &p->modal_start) != MLIP_OK) {
			snprintf(p->msg, sizeof p->msg,
			         "the modal state to start from is out of range for this machine");
			return -EINVAL;
		}
	}
	p->opt.modal = NULL;
	p->errors = malloc(MLIP_PROGRAM_MAX_ERRORS * sizeof *p->errors);
	p->line = malloc(LINE_CAP);
	p->batch = malloc(MLIP_PROGRAM_BATCH * sizeof *p->batch);
	if (!p->errors || !p->line || !p->batch) {
		snprintf(p->msg, sizeof p->msg, "%s", strerror(ENOMEM));
		return -ENOMEM;
	}
	return check_all(p);
}

int mlip_program_open(struct mlip_program *p, const char *path, const struct mlip_machine *m,
                      const struct mlip_program_options *opt)
{
	memset(p, 0, sizeof *p);
	int rc = open_file(p, path, NULL, 0);
	if (rc < 0) {
		return rc;
	}
	return open_common(p, m, opt);
}

int mlip_program_open_mem(struct mlip_program *p, const char *text, size_t len,
                          const struct mlip_machine *m, const struct mlip_program_options *opt)
{
	memset(p, 0, sizeof *p);
	p->mem = text;
	p->mem_len = len;
	return open_common(p, m, opt);
}

/* ---- streaming ---- */

static int stream_sink(void *ctx, const struct mlip_block *b)
{
	struct mlip_program *p = ctx;

	if (p->skip) {
		p->skip--; /* given out by the previous parse of this line */
		return 0;
	}
	if (p->batch_n == MLIP_PROGRAM_BATCH) {
		return 1;
	}
	p->batch[p->batch_n++] = *b;
	return 0;
}

static int changed(struct mlip_program *p, const char *what)
{
	size_t n = strlen(what) > 180 ? 180 : strlen(what);

	snprintf(p->msg, sizeof p->msg,
	         "the file changed after it was checked (%.*s): the rest is not run", (int)n, what);
	p->done = 1;
	return -EIO;
}

int mlip_program_next(struct mlip_program *p, struct mlip_block *b)
{
	struct mlip_gcode_error err;
	mlip_status st;
	size_t given;
	int rc;

	if (p->n_errors_total && !p->keep_going) {
		snprintf(p->msg, sizeof p->msg, "the program has errors: it does not run");
		return -EINVAL;
	}
	if (p->done) {
		return p->done == 2 ? 0 : -EIO;
	}
	if (!p->streaming) {
		rc = rewind_input(p);
		if (rc < 0) {
			snprintf(p->msg, sizeof p->msg, "%s", strerror(-rc));
			return rc;
		}
		start_parser(p, &p->g);
		p->streaming = 1;
	}
	for (;;) {
		if (p->batch_pos < p->batch_n) {
			*b = p->batch[p->batch_pos++];
			p->delivered++;
			return 1;
		}
		if (p->more) {
			/* the line gave more blocks than a batch: parse it again from
			 * its start, skipping those already given */
			given = p->skip_base + p->batch_n;
			p->g = p->saved;
		} else {
			rc = read_line(p);
			if (rc == -ESTALE) {
				char what[sizeof p->stale + 32];
				snprintf(what, sizeof what, "%s, line %u", p->stale,
				         (unsigned)p->lineno + 1);
				return changed(p, what);
			}
			if (rc < 0) {
				snprintf(p->msg, sizeof p->msg, "%s", strerror(-rc));
				p->done = 1;
				return rc;
			}
			if (rc == 0) {
				p->done = 2;
				return p->delivered == p->n ? 0 : changed(p, "fewer blocks");
			}
			p->lineno++;
			given = 0;
			p->saved = p->g;
		}
		p->skip_base = given;
		p->skip = given;
		p->batch_n = p->batch_pos = 0;
		st = mlip_gcode_line(&p->g, p->line, line_arg(p), p->lineno, stream_sink, p, &err);
		p->more = st == MLIP_E_FULL && p->batch_n == MLIP_PROGRAM_BATCH;
		if (st != MLIP_OK && !p->more && !p->keep_going) {
			char what[200];

			snprintf(what, sizeof what, "line %u: %s", (unsigned)err.line, err.msg);
			return changed(p, what);
		}
		if (p->delivered + p->batch_n > p->n) {
			return changed(p, "more blocks");
		}
	}
}

void mlip_program_rewind(struct mlip_program *p)
{
	p->streaming = 0;
	p->done = 0;
	p->more = 0;
	p->delivered = 0;
	p->batch_n = p->batch_pos = p->skip = p->skip_base = 0;
}

int mlip_program_open_reader(struct mlip_program *p, const struct mlip_program *checked,
                             const char *path)
{
	*p = *checked; /* counts, first F, offsets at the start: what next() needs */
	p->file = 0;
	p->fd = -1;
	p->buf = NULL;
	p->pin_owner = 0; /* the checked program's pin, verified here too */
	p->pinning = 0;
	p->buf_len = p->buf_pos = p->chunk_at = 0;
	p->io_err = 0;
	p->errors = NULL;
	p->n_errors = 0; /* kept by checked; n_errors_total still refuses a bad one */
	p->line = NULL;
	p->batch = NULL;
	mlip_program_rewind(p);
	if (checked->file) {
		int rc = open_file(p, path, checked->pin, checked->chunk);
		if (rc < 0) {
			return rc;
		}
	}
	p->line = malloc(LINE_CAP);
	p->batch = malloc(MLIP_PROGRAM_BATCH * sizeof *p->batch);
	if (!p->line || !p->batch) {
		snprintf(p->msg, sizeof p->msg, "%s", strerror(ENOMEM));
		return -ENOMEM;
	}
	return 0;
}

void mlip_program_close(struct mlip_program *p)
{
	if (p->file && p->fd >= 0) {
		close(p->fd);
	}
	if (p->pin_owner) {
		free(p->pin);
	}
	free(p->buf);
	free(p->errors);
	free(p->line);
	free(p->batch);
	memset(p, 0, sizeof *p);
}

int mlip_program_check_file(const char *path, char *msg, size_t msg_len)
{
	uint64_t size;
	int fd = open_regular(path, msg, msg_len, &size);

	if (fd < 0) {
		return -EINVAL;
	}
	close(fd);
	return 0;
}

int mlip_program_scan_axes(const char *path, char *letters, char *msg, size_t msg_len)
{
	static const char all[] = "XYZABC";
	struct mlip_program p;
	unsigned axes = 0;
	int rc, k, n = 0;

	memset(&p, 0, sizeof p);
	rc = open_file(&p, path, NULL, 0);
	p.line = malloc(LINE_CAP);
	if (rc < 0 || !p.line) {
		snprintf(msg, msg_len, "%s", rc < 0 ? p.msg : strerror(ENOMEM));
		mlip_program_close(&p);
		return -EINVAL;
	}
	while ((rc = read_line(&p)) > 0) {
		mlip_gcode_scan_line(p.line, line_kept(&p), &axes);
	}
	mlip_program_close(&p);
	if (rc < 0) {
		snprintf(msg, msg_len, "%s", strerror(-rc));
		return rc;
	}
	for (k = 0; k < 6; k++) {
		if (axes & (1u << k)) {
			letters[n++] = all[k];
		}
	}
	letters[n] = '\0';
	return n;
}

/* ---- messages ---- */

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

		if (strcmp(n->word, "F") == 0 && prog->initial_feed_line == 0) {
			fprintf(
			    f,
			    "%s:%u: note: F: the program sets no feed: --default-feed F%g is used "
			    "for its %u feed move%s\n",
			    path, (unsigned)n->first_line, prog->initial_feed_word,
			    (unsigned)n->count, n->count == 1 ? "" : "s");
			continue;
		}
		if (strcmp(n->word, "F") == 0) {
			fprintf(f,
			        "%s:%u: note: F missing before a feed move: the program's first F"
			        " (F%g, line %u) is used for %u move%s before it\n",
			        path, (unsigned)n->first_line, prog->initial_feed_word,
			        (unsigned)prog->initial_feed_line, (unsigned)n->count,
			        n->count == 1 ? "" : "s");
			continue;
		}
		fprintf(f, "%s:%u: note: %s %s", path, (unsigned)n->first_line,
		        strcmp(n->word, "G64P") == 0   ? "G64 P"
		        : strcmp(n->word, "G64Q") == 0 ? "G64 Q"
		                                       : n->word,
		        mlip_gcode_notice_text(n));
		if (n->count > 1) {
			fprintf(f, " (%u times)", (unsigned)n->count);
		}
		fputc('\n', f);
	}
}

/* ---- whole programs in an array ---- */

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

static int list_fill(struct mlip_program_list *l, int rc)
{
	struct mlip_block b;
	int got;

	l->errors = l->r.errors;
	l->n_errors = l->r.n_errors;
	l->n_errors_total = l->r.n_errors_total;
	l->notices = l->r.notices;
	l->n_notices = l->r.n_notices;
	l->lines = l->r.lines;
	if (rc < 0) {
		return rc;
	}
	l->r.keep_going = 1; /* the blocks of the valid lines, for tests */
	while ((got = mlip_program_next(&l->r, &b)) > 0) {
		if (l->n == l->cap) {
			size_t cap = l->cap ? l->cap * 2 : 4096;
			struct mlip_block *nb = realloc(l->blocks, cap * sizeof *nb);

			if (!nb) {
				snprintf(l->r.msg, sizeof l->r.msg, "%s", strerror(ENOMEM));
				return -ENOMEM;
			}
			l->blocks = nb;
			l->cap = cap;
		}
		l->blocks[l->n++] = b;
	}
	return got < 0 ? got : rc;
}

int mlip_program_list_load(const char *path, const struct mlip_machine *m,
                           struct mlip_program_list *list)
{
	memset(list, 0, sizeof *list);
	return list_fill(list, mlip_program_open(&list->r, path, m, NULL));
}

int mlip_program_list_parse(const char *text, size_t len, const struct mlip_machine *m,
                            struct mlip_program_list *list)
{
	memset(list, 0, sizeof *list);
	return list_fill(list, mlip_program_open_mem(&list->r, text, len, m, NULL));
}

void mlip_program_list_free(struct mlip_program_list *list)
{
	free(list->blocks);
	mlip_program_close(&list->r);
	memset(list, 0, sizeof *list);
}
