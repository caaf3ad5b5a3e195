/*
 * mlip/gcode.h - G-code front end: text in, joint-space blocks out.
 *
 * Pure: reads a line from a buffer, never a file; no allocation, no I/O.
 * The caller feeds a program line by line (mlip_gcode_line), then calls
 * mlip_gcode_finish. Every error names line and column (1-based column of
 * the offending character). After an error on a line the parser continues
 * with the next line, so a caller can list every error of a file; a program
 * with any error must be rejected as a whole (the tools do that).
 *
 * Supported: G0/G1 (modal, bare axis words continue the motion mode), G2/G3
 * in G17/G18/G19 with I J K or R (turned into chords within a fraction of the
 * contour tolerance), G90/G91, G20/G21, F (units per minute), comments in ( )
 * and after ';', '%' lines, N line numbers, block delete is not supported.
 * Accepted without motion and reported once (see notices): S, M3/M4/M5,
 * M7/M8/M9, T, M6, G17-G19, G40, G49, G54, G61/G64, G80, G94, M0/M1/M2/M30,
 * G53 (machine coordinates: mlip has no work offsets, so the same frame),
 * G28/G30 whose intermediate point is the current position (no homing).
 * Everything else is an error.
 */
#ifndef MLIP_GCODE_H
#define MLIP_GCODE_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/types.h"

#define MLIP_GCODE_MAX_LINE 256   /* longer lines are an error */
#define MLIP_GCODE_MSG 160
#define MLIP_GCODE_MAX_NOTICES 24
/* points closer than this (joint-space distance) to the previous one are
 * merged so no zero-length segment reaches the planner */
#define MLIP_GCODE_MERGE_MM 1e-6
/* chord sagitta allowed when turning an arc into chords, as a fraction of
 * the contour tolerance; the corner between chords gets the rest */
#define MLIP_GCODE_ARC_FRACTION 0.1

struct mlip_gcode_error {
	uint32_t line;   /* 1-based */
	uint32_t col;    /* 1-based; 0 when the error concerns the whole line/file */
	char msg[MLIP_GCODE_MSG]; /* one line, no trailing newline */
};

/* A word accepted but with no effect on motion, reported once. */
struct mlip_gcode_notice {
	char word[8];      /* e.g. "M3", "S", "G54", "T" */
	uint32_t first_line;
	uint32_t count;
};

/* Called for every block produced; return non-zero to abort parsing (the
 * line then fails with MLIP_E_FULL). */
typedef int (*mlip_block_sink)(void *ctx, const struct mlip_block *b);

/* Modal state: fixed size, owned by the caller. Fields are private. */
struct mlip_gcode {
	const struct mlip_machine *m;
	double pos[MLIP_MAX_AXES];   /* last emitted point, machine units */
	double cur[MLIP_MAX_AXES];   /* programmed point (pos lags it by < MERGE) */
	double feed_mm_s;            /* current F, converted; <= 0: none yet */
	double feed_word;            /* current F as written, units/min (deg/min
	                                for rotary-only moves) */
	double initial_feed_word;    /* F used by feed moves before any F; <= 0:
	                                none, such a move is an error */
	int motion;                  /* 0,1,2,3 or -1 before any */
	int plane;                   /* 17, 18, 19 */
	int absolute;                /* G90 = 1, G91 = 0 */
	int inches;                  /* G20 = 1 */
	uint32_t blocks;             /* blocks emitted so far */
	uint32_t n_notices;
	struct mlip_gcode_notice notices[MLIP_GCODE_MAX_NOTICES];
};

/* Start a program at the machine's home position. */
void mlip_gcode_init(struct mlip_gcode *g, const struct mlip_machine *m);

/* Parse one line (without its newline; len bytes, need not be NUL-terminated).
 * Emits zero or more blocks through sink. Returns MLIP_OK or an error code
 * with *err filled (line, column, message). */
mlip_status mlip_gcode_line(struct mlip_gcode *g, const char *text, size_t len,
                            uint32_t lineno, mlip_block_sink sink, void *ctx,
                            struct mlip_gcode_error *err);

/* End of program: MLIP_E_SYNTAX "empty program: no motion" when no block was
 * ever emitted. */
mlip_status mlip_gcode_finish(struct mlip_gcode *g, uint32_t last_line,
                              struct mlip_gcode_error *err);

/* Let feed moves before the program's first F run at f_word (an F value, in
 * the units in effect at the move) instead of failing with "missing feed";
 * each such line is counted in the notice "F". Real files do this (they
 * rely on the F a previous job left behind); the tools pass the program's
 * first F (see mlip_gcode_scan_feed), which is the conservative choice.
 * f_word <= 0 restores the default: such a move is an error. */
void mlip_gcode_set_initial_feed(struct mlip_gcode *g, double f_word);

/* What a notice means, for printing after its word: "ignored (no effect on
 * motion)", or a specific text for G53, G28/G30 and F. Static string. */
const char *mlip_gcode_notice_text(const struct mlip_gcode_notice *n);

/* Axis letters among X Y Z A B C used as words outside comments in a whole
 * program (len bytes), written NUL-terminated in the order XYZABC to letters
 * (room for 7). Returns how many; the caller decides whether 0 or 1 is enough. */
int mlip_gcode_scan_axes(const char *text, size_t len, char *letters);

/* The first positive F word outside comments in a whole program: its value
 * (as written) in *f_word; returns its 1-based line, or 0 when there is none. */
uint32_t mlip_gcode_scan_feed(const char *text, size_t len, double *f_word);

#endif
