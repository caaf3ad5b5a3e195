/*
 * offsets.h - the state that outlives a program (work offsets G54-G59.3,
 * G92, the G28/G30 positions, the selected system) in a small text file
 * the operator can read, edit and delete (deleting it resets everything to
 * zero, G54, G28/G30 at HOME). The tools read it before a program and
 * mlip-feed writes it back after one; the real-time loop never touches it.
 *
 *   # mlip offsets: machine units (mm, degrees), config axis order
 *   SELECT = G55
 *   G92_ON = 0
 *   G54 = 0 0 0
 *   G55 = 10 20 -5
 *   ...
 *   G92 = 0 0 0
 *   G28 = 0 0 50
 *   G30 = 0 0 50
 *
 * One value per configured axis, in config order. A missing key keeps its
 * default; an unknown key, a bad number or a wrong count is an error naming
 * file:line.
 */
#ifndef MLIP_TOOLS_OFFSETS_H
#define MLIP_TOOLS_OFFSETS_H

#include <stddef.h>
#include <stdio.h>

#include "mlip/gcode/gcode.h"

/* Defaults, then the file at path when it exists. 0, or -1 after printing
 * "prog: path:LINE: error: ..." to err. */
int mlip_offsets_load(const char *path, const struct mlip_machine *m, struct mlip_gcode_offsets *o,
                      const char *prog, FILE *err);

/* Write o to path (a temporary file renamed over it). 0, or -1 with a message. */
int mlip_offsets_save(const char *path, const struct mlip_machine *m,
                      const struct mlip_gcode_offsets *o, const char *prog, FILE *err);

/* One line for the operator: "G55 X10 Y20 Z-5, G92 off" (the selected
 * system's origin; the G92 offset when on). */
void mlip_offsets_describe(const struct mlip_machine *m, const struct mlip_gcode_offsets *o,
                           char *buf, size_t len);

#endif
