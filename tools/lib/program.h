/*
 * program.h - host-side helpers around the G-code front end: read a file,
 * parse a whole program into a growable array of blocks, print errors and
 * notices GCC-style. Uses stdio and malloc; not for the real-time path.
 */
#ifndef MLIP_TOOLS_PROGRAM_H
#define MLIP_TOOLS_PROGRAM_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "mlip/gcode.h"
#include "mlip/types.h"

#define MLIP_PROGRAM_MAX_ERRORS 1000 /* errors kept; all are counted */

/* Read a whole file. Returns 0 or -errno; *buf is NUL-terminated (len does
 * not count the NUL; the text may hold NULs of its own), caller frees. */
int mlip_read_file(const char *path, char **buf, size_t *len);

struct mlip_program {
	struct mlip_block *blocks;
	size_t n, cap;                   /* growable */
	struct mlip_gcode_error *errors; /* in order, at most MLIP_PROGRAM_MAX_ERRORS */
	size_t n_errors;
	size_t n_errors_total;           /* including those not kept */
	struct mlip_gcode_notice notices[MLIP_GCODE_MAX_NOTICES];
	uint32_t n_notices;
	uint32_t lines;
	double initial_feed_word;        /* F used before the first F (0: none) */
	uint32_t initial_feed_line;      /* line of that first F */
};

/* Parse a whole file with the front end. *prog is overwritten (free it first
 * when reusing it). Feed moves before the program's first F run at that
 * first F (notice "F"); a program with no F at all and a feed move gets
 * "missing feed". Returns 0 when the program is valid, 1 when it has errors
 * (in prog->errors; the blocks are then not to be run), -errno when the file
 * can't be read or memory runs out. */
int mlip_program_load(const char *path, const struct mlip_machine *m, struct mlip_program *prog);

/* The same from a buffer of len bytes (lines end in \n or \r\n). */
int mlip_program_parse(const char *text, size_t len, const struct mlip_machine *m,
                       struct mlip_program *prog);

/* "path:LINE:COL: error: MSG" per error ("path:LINE: error: MSG" when the
 * column is 0), then "path: N errors, program rejected". Nothing when valid. */
void mlip_program_print_errors(const struct mlip_program *prog, const char *path, FILE *f);

/* "path:LINE: note: WORD ignored (no effect on motion), N times" per notice
 * (LINE is the first line it appears on; G53, G28/G30, F get their own text). */
void mlip_program_print_notices(const struct mlip_program *prog, const char *path, FILE *f);

void mlip_program_free(struct mlip_program *prog);

#endif
