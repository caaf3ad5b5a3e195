/*
 * iostatus.h - the machine's outputs and the last probe (issue 19) as
 * mlip-ctl status shows them, from the status area alone: the I/O module's
 * output bytes 0x6200:1..8, the coolant outlets on, and the last G38's
 * result as LinuxCNC's parameters #5061.. (position) and #5070 (tripped).
 */
#ifndef MLIP_TOOLS_IOSTATUS_H
#define MLIP_TOOLS_IOSTATUS_H

#include <stdio.h>

#include "json.h"
#include "mlip/ipc/ring.h"
#include "mlip/types.h"

#define MLIP_IO_BYTES_SHOWN 8 /* the module's output bytes 0x6200:1..8 */

/* "outputs": {"0x6200:1": 5, ...} (only non-zero bytes, {} when all off),
 * "coolant": {"mist": b, "flood": b} with [COOLANT] TYPE = io (the segment's
 * I/O area of r says so), else "none" (nothing the controller switches),
 * "probe": null or {"count", "tripped", "line", "position": {"X": ..},
 * "parameters": {"5061": .., "5070": 0|1}}. */
void mlip_iostatus_json(struct mlip_json *j, const struct mlip_machine *m,
                        const struct mlip_ring_status *st, const struct mlip_ring *r);

/* "outputs    ..." when the machine has outputs (the segment's I/O area
 * says so) or one is on, "probe      ..." once a probe ended. */
void mlip_iostatus_text(FILE *f, const struct mlip_machine *m, const struct mlip_ring_status *st,
                        const struct mlip_ring *r);

#endif
