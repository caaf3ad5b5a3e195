/*
 * drives.h - private to rt/drives.c (bring-up, shut-down) and
 * rt/drivehooks.c (the period's hooks): what both do with the bus.
 */
#ifndef MLIP_RT_DRIVES_H
#define MLIP_RT_DRIVES_H

#include <stdint.h>

#include "rt.h"

/* The index of the drive of node, or -1. */
int mlip_drives_find_node(const struct mlip_drives *ds, uint8_t node);
/* The master's heartbeat when it is due (both outside and in the loop). */
void mlip_drives_serve_heartbeat(struct mlip_drives *ds, uint64_t now);
/* Note what a heartbeat, EMCY or TPDO says about a drive (in and out of the
 * loop); returns the classified message. `cycle`: the period (0 outside). */
void mlip_drives_observe(struct mlip_drives *ds, const struct mlip_can_frame *f, uint64_t now,
                         uint64_t cycle, struct mlip_co_msg *m);

#endif
