/*
 * confjson.h - a machine configuration as parsed, printed as JSON, so that
 * tools in other languages (the Python listener, the tests) ask the C reader
 * (mlip-config --json) instead of reading the INI file a second way.
 */
#ifndef MLIP_CONFJSON_H
#define MLIP_CONFJSON_H

#include <stdio.h>

#include "mlip/machine/config.h"

/* One JSON object: "file", "machine" (the [TRAJ] values and "axes", one
 * object per axis in COORDINATES order), "lookahead", and "can" (the [CAN]
 * values and "frames": every frame the profile sends each period, in send
 * order, as {"id", "name"}), and "drives" (the [DRIVES] values). Doubles
 * with 17 significant digits (they read back to the same value); ids as
 * numbers. Written with the tools' one JSON writer (json.h). */
void mlip_config_print_json(FILE *f, const char *path, const struct mlip_config *c);

#endif
