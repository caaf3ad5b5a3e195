/*
 * program.h - host-side program reading around the G-code front end, in
 * memory bounded by a constant whatever the program's length:
 *
 *   mlip_program_open()   checks the whole file (first pass): every error
 *                         listed, the notices, the block count; nothing kept
 *                         of the blocks;
 *   mlip_program_next()   streams the blocks (second pass), the same ones;
 *   mlip_program_close().
 *
 * So "a program with any error never starts" holds without holding the
 * program. Only regular files are read (several times): a FIFO, a device
 * such as /dev/zero or a directory is refused with a message. Lines end in
 * LF, CRLF or a lone CR; a line longer than MLIP_GCODE_MAX_LINE is an error,
 * and only that many bytes of it are kept.
 *
 * The program is pinned for the whole run: every pass reads the file in
 * chunks, and the first pass keeps each chunk's SHA-256 (a table of at most
 * MLIP_PROGRAM_MAX_CHUNKS, 16 bytes each). Every later pass (the check, the
 * stream, a second reader) reads a chunk whole into its own buffer and
 * compares its hash before it parses a byte of it, so the blocks given out
 * are the bytes that were checked: a file rewritten in place, replaced
 * (cp, an editor's rename) or cut is found at the first chunk that differs,
 * and the stream ends there with "the file changed after it was checked"
 * (mlip-feed: the machine stops at rest at the end of the last block sent,
 * every one of them verified). Memory stays independent of the program's
 * length: the table, and one chunk of MLIP_PROGRAM_CHUNK bytes (larger only
 * for a program over MLIP_PROGRAM_CHUNK x MLIP_PROGRAM_MAX_CHUNKS = 256 MiB:
 * 1/4096 of its size).
 *
 * mlip_program_list_*() collect a whole program into an array, for the
 * benchmarks and tests that need every block at once (never the tools that
 * run programs). Uses stdio and malloc; not for the real-time path.
 */
#ifndef MLIP_TOOLS_PROGRAM_H
#define MLIP_TOOLS_PROGRAM_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "mlip/gcode/gcode.h"
#include "mlip/types.h"

#define MLIP_PROGRAM_MAX_ERRORS 1000   /* errors kept; all are counted */
#define MLIP_PROGRAM_CHUNK      65536u /* bytes hashed as one (at least) */
#define MLIP_PROGRAM_MAX_CHUNKS 4096u  /* chunks of a file (more: larger chunks) */
#define MLIP_PROGRAM_PIN_BYTES  16     /* of each chunk's SHA-256 */
#define MLIP_PROGRAM_BATCH                                                                         \
	4096 /* blocks of one line held at once (longer                                            \
	        arcs are parsed again from the line) */

struct mlip_program_options {
	int strict;                               /* mlip_gcode_set_strict */
	const struct mlip_gcode_offsets *offsets; /* in force at the start; NULL: defaults */
	double default_feed;            /* F (units/min) for a program that sets none; 0: none */
	const struct mlip_gcode_io *io; /* the machine's I/O (mlip_gcode_set_io; kept, must
	                                   outlive the program); NULL: its words are notices */
	const struct mlip_gcode_modal *modal; /* modal state at the start (MDI: the one the
	                                         last MDI left; copied); NULL: a program's */
	int mdi; /* lines typed at the machine: no motion is no error (mlip_gcode_set_mdi) */
};

struct mlip_program {
	/* what the check found (valid after open) */
	size_t n;                        /* blocks (moves and events) */
	struct mlip_gcode_error *errors; /* in order, at most MLIP_PROGRAM_MAX_ERRORS */
	size_t n_errors;
	size_t n_errors_total; /* including those not kept */
	struct mlip_gcode_notice notices[MLIP_GCODE_MAX_NOTICES];
	uint32_t n_notices;
	uint32_t lines;
	double initial_feed_word;                /* F used before the first F (0: none) */
	uint32_t initial_feed_line;              /* line of that first F */
	struct mlip_gcode_offsets offsets_start; /* in force at the first line */
	struct mlip_gcode_offsets offsets_end;   /* left by the last line */
	struct mlip_gcode_modal modal_end;       /* the modal state the last line left */
	uint32_t moves;                          /* blocks that move (n counts events too) */
	char msg[256];                           /* why open or next failed (return < 0) */
	/* private */
	const struct mlip_machine *m;
	struct mlip_program_options opt;
	struct mlip_gcode_modal modal_start; /* opt.modal's copy */
	int has_modal;
	int file, fd; /* a file (fd), else mem */
	/* the pin: chunk hashes of the first pass (shared with readers) */
	uint8_t (*pin)[MLIP_PROGRAM_PIN_BYTES];
	int pin_owner, pinning; /* this pass records (the first) */
	size_t chunk, n_chunks; /* bytes per chunk; chunks the first pass read */
	unsigned char *buf;     /* the chunk being parsed (verified) */
	size_t buf_len, buf_pos, chunk_at;
	int io_err;     /* 0, -errno, or -ESTALE: a chunk that differs */
	char stale[96]; /* which one, how */
	const char *mem;
	size_t mem_len, mem_pos;
	char *line;      /* MLIP_GCODE_MAX_LINE + 2 bytes */
	size_t line_len; /* as read, may exceed what line holds */
	uint32_t lineno;
	struct mlip_gcode g, saved; /* streaming state, and at the line's start */
	struct mlip_block *batch;
	size_t batch_n, batch_pos, skip, skip_base, delivered;
	int streaming, more, done;
	int keep_going; /* lists: stream the valid lines of a bad program */
};

/* Check the program at path on machine m (m must outlive prog). Returns 0
 * when it is valid, 1 when it has errors (prog->errors), < 0 when it can't
 * be read (prog->msg says why: missing, not a regular file, I/O). Close it
 * in every case. */
int mlip_program_open(struct mlip_program *prog, const char *path, const struct mlip_machine *m,
                      const struct mlip_program_options *opt);

/* The same from a buffer of len bytes (kept by the caller until close). */
int mlip_program_open_mem(struct mlip_program *prog, const char *text, size_t len,
                          const struct mlip_machine *m, const struct mlip_program_options *opt);

/* The next block of a valid program: 1, 0 at the end, < 0 when the file no
 * longer gives what was checked (prog->msg: "the file changed after it was
 * checked (...)"; an I/O error). */
int mlip_program_next(struct mlip_program *prog, struct mlip_block *b);

/* Stream the blocks again from the first (a third pass over the file). */
void mlip_program_rewind(struct mlip_program *prog);

void mlip_program_close(struct mlip_program *prog);

/* A second, independent reader of the blocks of checked (open, valid),
 * opened on the same file (path) or buffer without checking it again:
 * mlip_program_next on it gives the same blocks, at its own pace (the
 * simulator's check follows the program behind its feeder). Errors and
 * notices stay with checked. 0, or < 0 with reader->msg; close it too. */
int mlip_program_open_reader(struct mlip_program *reader, const struct mlip_program *checked,
                             const char *path);

/* 0 when path is a regular file that can be opened, else < 0 with msg (the
 * reason, as mlip_program_open gives it). */
int mlip_program_check_file(const char *path, char *msg, size_t msg_len);

/* Axis letters among XYZABC the file at path uses, NUL-terminated in that
 * order into letters (room for 7); returns how many, or < 0 with msg. */
int mlip_program_scan_axes(const char *path, char *letters, char *msg, size_t msg_len);

/* "path:LINE:COL: error: MSG" per error ("path:LINE: error: MSG" when the
 * column is 0), then "path: N errors, program rejected". Nothing when valid. */
void mlip_program_print_errors(const struct mlip_program *prog, const char *path, FILE *f);

/* "path:LINE: note: WORD what mlip did, N times" per notice (LINE is the
 * first line it appears on). */
void mlip_program_print_notices(const struct mlip_program *prog, const char *path, FILE *f);

/* Read a whole file (tests). Returns 0 or -errno; *buf is NUL-terminated
 * (len does not count the NUL; the text may hold NULs of its own), caller
 * frees. */
int mlip_read_file(const char *path, char **buf, size_t *len);

/* A whole program in an array (benchmarks, tests). */
struct mlip_program_list {
	struct mlip_block *blocks;
	size_t n, cap;
	struct mlip_program r; /* errors, notices, counts */
	/* copies of r's, for brevity */
	const struct mlip_gcode_error *errors;
	size_t n_errors, n_errors_total;
	const struct mlip_gcode_notice *notices;
	uint32_t n_notices, lines;
};

/* 0 valid, 1 errors, < 0 unreadable or out of memory (list->r.msg). */
int mlip_program_list_load(const char *path, const struct mlip_machine *m,
                           struct mlip_program_list *list);
int mlip_program_list_parse(const char *text, size_t len, const struct mlip_machine *m,
                            struct mlip_program_list *list);
void mlip_program_list_free(struct mlip_program_list *list);

#endif
