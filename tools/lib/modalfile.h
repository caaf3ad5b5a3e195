/*
 * modalfile.h - the modal state MDI carries from one command to the next
 * (mlip-ctl mdi; LinuxCNC's interpreter keeps it between MDI commands): a
 * state file (statefile.h: a new file, fsync, rename, folder fsync; read
 * back whole, sealed by its end marker, merged per key with a change made
 * meanwhile). By default it sits next to the offsets file: OFFSETS.modal.
 *
 *   # mlip MDI modal state: ... (comment lines)
 *   MOTION G1            G0 G1 G2 G3, or none (no motion mode yet)
 *   PLANE G17            G17 G18 G19
 *   DISTANCE G90         G90 G91
 *   UNITS G21            G20 G21
 *   FEED_MODE G94        G93 G94
 *   F 600                as written, in UNITS per minute; none
 *   PATH G64             G61 (exact stop) or G64
 *   TOLERANCE 0.01       mm: G64 P in force (at most CONTOUR_TOLERANCE)
 *   S 12000              rpm; none
 *   T 3                  tool selected for M6; none
 *   TOOL_OFFSET G43 2.5  G49, or G43/G43.1 and the Z offset in mm
 *   # end 11 lines sha256 ...
 *
 * Not in it: the offsets and the selected system (the offsets file), the
 * position (the machine's), the spindle's and the coolant's on/off.
 */
#ifndef MLIP_TOOLS_MODALFILE_H
#define MLIP_TOOLS_MODALFILE_H

#include <stdio.h>

#include "mlip/gcode/gcode.h"
#include "statefile.h"

/* A modal state file as loaded: the base of the write-back's merge. */
struct mlip_modal_file {
	const char *path;
	struct mlip_sf loaded;
	int ok; /* loaded (0: there was none yet) */
};

/* The kind (statefile.h) of a modal state file. */
void mlip_modal_kind(struct mlip_sf_kind *k);

/* Read path into md for machine m: 0 (a missing file: md = a program's
 * start, f->ok 0, *missing 1), or -1 after printing "prog: error: ..." to
 * err (damaged, hand-edited without --accept, out of range for m). */
int mlip_modal_load(struct mlip_modal_file *f, const char *path, const struct mlip_machine *m,
                    struct mlip_gcode_modal *md, int *missing, const char *prog, FILE *err);

/* Write md to f's path (merged with a change made since the load). 0, or -1
 * after printing why. */
int mlip_modal_save(struct mlip_modal_file *f, const struct mlip_gcode_modal *md, const char *prog,
                    FILE *err);

/* A hand-edited file at path checked (every record, every key) and sealed
 * again (mlip-ctl mdi --accept). 0, or -1 after printing why. */
int mlip_modal_accept(const char *path, const char *prog, FILE *err);

void mlip_modal_file_free(struct mlip_modal_file *f);

/* md <-> records (each value as mlip writes it). */
int mlip_modal_to_records(const struct mlip_gcode_modal *md, struct mlip_sf *sf);
/* 0, or -1 with why (a key missing or unreadable). */
int mlip_modal_from_records(const struct mlip_sf *sf, const struct mlip_machine *m,
                            struct mlip_gcode_modal *md, char *why, size_t why_len);

/* One line for the operator: "G1 G17 G90 G21 G94 G64 P0.01 F600 G43 (Z 2.5)". */
void mlip_modal_describe(const struct mlip_gcode_modal *md, char *buf, size_t len);

#endif
