/*
 * grblstream.h - G-code lines arriving one at a time, turned into the ring's
 * records exactly as mlip-feed turns a file into them: the same reader
 * (mlip/gcode/gcode.h) with the same modal state carried from line to line,
 * the same smoothing filter when the controller runs `smooth`
 * (blockiter.h's mlip_smooth_stream, which mlip-feed's iterator is built
 * on), records numbered 1, 2, ... per program with the END record last.
 *
 * A line is checked whole before any of its blocks is given out (a line
 * with an error changes nothing: not the modal state, not the output), then
 * its blocks are staged; a line with more blocks than the stage holds (a
 * long arc) is given out in parts, parsed again from its start each time
 * (as program.c does with a batch). The caller moves the staged records to
 * the ring (grbl_stream_take) and answers the line once it is done.
 *
 * A program here is what runs between two END records: it ends at M2/M30,
 * at grbl_stream_end (the sender went quiet with the controller waiting, a
 * line was refused), and the next line starts a new one from where the last
 * ended. The smoothing filter is finished at each end and starts again with
 * the next program, as it would for two files.
 *
 * Pure: memory fixed by the caller (the smoothing filter's ~1 MB included),
 * no I/O.
 */
#ifndef MLIP_TOOLS_GRBLSTREAM_H
#define MLIP_TOOLS_GRBLSTREAM_H

#include <stddef.h>
#include <stdint.h>

#include "blockiter.h"
#include "mlip/gcode/gcode.h"
#include "mlip/ipc/ring.h"
#include "mlip/motion/smooth.h"
#include "mlip/types.h"

#define GRBL_STAGE 512 /* records staged before the ring takes them */

struct grbl_stream {
	struct mlip_machine m;        /* axis[k].home: where the next program starts */
	struct mlip_gcode g;          /* modal state, line to line, program to program */
	struct mlip_smooth *sm;       /* NULL: the controller does not smooth */
	struct mlip_smooth_stream ss; /* over sm, for the open program */
	int open;                     /* a program is open (records given, or smoothing) */
	uint64_t seq;                 /* records of the open program given so far */
	uint32_t last_line;           /* line of the last block given */
	uint64_t programs;            /* programs ended (END records given) */
	/* a line whose blocks did not all fit */
	int partial;
	char text[MLIP_GCODE_MAX_LINE + 1];
	size_t len;
	uint32_t lineno;
	struct mlip_gcode before, after; /* the state at its start and at its end */
	size_t given;                    /* its blocks already given */
	size_t count;                    /* blocks in this parse */
	int full;                        /* the stage filled during this parse */
	int end_pending;                 /* an END waits for room in the stage */
	int m2;                          /* the last line ended its program (M2/M30) */
	int flush_end;                   /* the flush under way ends the program */
	/* the stage */
	struct mlip_ring_rec stage[GRBL_STAGE];
	uint32_t staged, taken;
};

/* Start at pos (machine axis order) on machine m; sm: the smoothing filter's
 * memory when the controller runs `smooth` (m->smooth), else NULL. */
void grbl_stream_init(struct grbl_stream *st, const struct mlip_machine *m, const double *pos,
                      struct mlip_smooth *sm);

/* The machine stands at pos (after a stop, a reset, another feeder's
 * program): the next program starts there. Drops anything staged and any
 * partial line; keep_modes 0 restores the modal defaults as a reset does
 * (the offsets stay: they are the machine's), 1 keeps them. */
void grbl_stream_restart(struct grbl_stream *st, const double *pos, int keep_modes);

/* Check a line without giving out anything (the modal state is unchanged):
 * MLIP_OK, or the reader's error in *err. */
mlip_status grbl_stream_check(const struct grbl_stream *st, const char *text, size_t len,
                              uint32_t lineno, struct mlip_gcode_error *err);

/* Check mode ($C): check a line and keep its modal state, give out nothing. */
mlip_status grbl_stream_dry(struct grbl_stream *st, const char *text, size_t len, uint32_t lineno,
                            struct mlip_gcode_error *err);

/* Take a line: < 0 with *err (nothing changed), 1 done (its blocks staged),
 * 0 not all its blocks fit: grbl_stream_more once records were taken. */
int grbl_stream_line(struct grbl_stream *st, const char *text, size_t len, uint32_t lineno,
                     struct mlip_gcode_error *err);
/* Go on with a partial line: 1 done, 0 not yet. */
int grbl_stream_more(struct grbl_stream *st);

/* The line just taken ended the program (M2/M30). */
int grbl_stream_ended(const struct grbl_stream *st);

/* End the open program: the filter's rest, then END. 1 done (or nothing
 * open), 0 the stage is full: call again once records were taken. */
int grbl_stream_end(struct grbl_stream *st);

/* Let the smoothing filter give everything it holds, then start it again
 * for what follows, within the same program (the sender paused: what it
 * sent must not wait for lines that may not come). 1 done, 0 the stage is
 * full: call again. */
int grbl_stream_flush(struct grbl_stream *st, int with_end);
/* The smoothing filter holds blocks back (a flush would give them). */
int grbl_stream_holding(const struct grbl_stream *st);

/* Staged records not yet taken, and taking them. */
uint32_t grbl_stream_staged(const struct grbl_stream *st);
const struct mlip_ring_rec *grbl_stream_peek(const struct grbl_stream *st);
void grbl_stream_take(struct grbl_stream *st, uint32_t n);

/* The machine's I/O (mlip_gcode_set_io: [SPINDLE], [COOLANT], [TOOL] as
 * mlip-feed takes them from the controller), kept through restarts; NULL:
 * the words are notices. io must outlive st. */
void grbl_stream_set_io(struct grbl_stream *st, const struct mlip_gcode_io *io);

/* What the machine's spindle (rpm: > 0 clockwise, < 0 counter-clockwise, 0
 * stopped) and coolant (MLIP_COOLANT_* bits) are doing now: the reader's
 * state from the next line on, so that an M5 or M9 after a reset that
 * dropped what was queued still asks for what the machine needs. */
void grbl_stream_machine_io(struct grbl_stream *st, double rpm, unsigned coolant);

/* Where the program given so far ends (the machine's rest point once it has
 * run everything), machine axis order. */
const double *grbl_stream_pos(const struct grbl_stream *st);

#endif
