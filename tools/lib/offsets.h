/*
 * offsets.h - the state that outlives a program (work offsets G54-G59.3,
 * G92, the G28/G30 positions, the selected system) in the offsets file: a
 * state file (statefile.h: written through a new file, fsync and rename,
 * read back whole and checked, merged per key with a change made during a
 * run) that the operator can read and edit. The tools read it before a
 * program and mlip-feed (mlip-sim --save-offsets) writes it back after one;
 * the real-time loop never touches it.
 *
 *   # mlip offsets: ... (comment lines)
 *   SELECT G55
 *   G92_ON 0
 *   G54 X0 Y0 Z0
 *   G55 X10 Y20 Z-5
 *   ...                    G56 .. G59.3
 *   G92 X0 Y0 Z0
 *   G28 X0 Y0 Z50
 *   G30 X0 Y0 Z50
 *   TOOL 2                 the tool in the spindle (0: none), left by M6/M61;
 *                          optional (a file of an older mlip has none: 0)
 *   # end 21 lines sha256 3f2a9c5b1d7e0a42
 *
 * Every key once, every value named by its axis letter (each axis of the
 * machine once, in any order: a file read on a machine whose COORDINATES
 * lists the axes in another order still puts each value on its axis),
 * numbers strict (a sign, digits, a point, an exponent; finite, |v| <=
 * 1e6). The end marker is the file's last line: a file cut short, empty,
 * holding NUL bytes, edited without being accepted, or of the old format
 * (KEY = values in config order, no axis letters, no marker: refused with
 * the command that converts it, since it cannot be told from a file cut
 * short) is refused with what to do. A missing file is an error too (a
 * mistyped path must not run a program on zero offsets): `mlip-offsets
 * --init` makes a new one.
 */
#ifndef MLIP_TOOLS_OFFSETS_H
#define MLIP_TOOLS_OFFSETS_H

#include <stddef.h>
#include <stdio.h>

#include "mlip/gcode/gcode.h"
#include "statefile.h"

#define MLIP_OFFSETS_MAX_ABS 1e6 /* mm or degrees: a larger value is not an offset */

/* An offsets file as loaded: the base of the write-back's merge. */
struct mlip_offsets_file {
	const char *path;
	struct mlip_sf loaded;
	int ok; /* loaded */
};

/* Read the file at path into o for machine m (f: kept for the save; may be
 * NULL). 0, or -1 after printing "prog: path...: error: ... what to do" to
 * err. */
int mlip_offsets_load(struct mlip_offsets_file *f, const char *path, const struct mlip_machine *m,
                      struct mlip_gcode_offsets *o, const char *prog, FILE *err);

/* Write o back to the file f was loaded from, merged per key with a change
 * made to it since (a record changed both there and in o refuses the
 * write). 0, or -1 after printing why and the values that were not written. */
int mlip_offsets_save(struct mlip_offsets_file *f, const struct mlip_machine *m,
                      const struct mlip_gcode_offsets *o, const char *prog, FILE *err);

void mlip_offsets_file_free(struct mlip_offsets_file *f);

/* One line for the operator: "G55 X10 Y20 Z-5, G92 off" (the selected
 * system's origin; the G92 offset when on; ", tool 2 in the spindle" when
 * one is). */
void mlip_offsets_describe(const struct mlip_machine *m, const struct mlip_gcode_offsets *o,
                           char *buf, size_t len);

/* ---- for mlip-offsets (the operator's tool) and tests ---- */

/* The kind (statefile.h) for axes `letters` ("XYZ"; "" takes them from the
 * file's first coordinate line). The returned kind points into *ctx. */
struct mlip_offsets_kind_ctx {
	char axes[MLIP_MAX_AXES + 1];
};
void mlip_offsets_kind(struct mlip_offsets_kind_ctx *ctx, const char *letters,
                       struct mlip_sf_kind *k);

/* o <-> records (each value as mlip writes it). */
int mlip_offsets_to_records(const struct mlip_machine *m, const struct mlip_gcode_offsets *o,
                            struct mlip_sf *sf);
void mlip_offsets_from_records(const struct mlip_machine *m, const struct mlip_sf *sf,
                               struct mlip_gcode_offsets *o);

/* An old offsets file (KEY = values in config order, no axis letters) at
 * path: 1 when it is one, 0 when not (or unreadable). */
int mlip_offsets_is_old(const char *path);
/* Read an old file in m's axis order into o: 0, or -1 with why. */
int mlip_offsets_read_old(const char *path, const struct mlip_machine *m,
                          struct mlip_gcode_offsets *o, char *why, size_t why_len);

/* The shortest decimal text that reads back as v exactly (no "-0"). */
void mlip_offsets_number(double v, char *buf, size_t len);

#endif
