/*
 * simstorm.h - mlip-sim's --storm: seeded random override changes, holds
 * and resumes through the controller's commands (a test of online
 * override).
 */
#ifndef MLIP_TOOLS_SIMSTORM_H
#define MLIP_TOOLS_SIMSTORM_H

#include <stdint.h>

#include "mlip/ipc/ring.h"

struct mlip_simstorm {
	uint64_t state;
	uint64_t next_at;
	int active;
	int held, zero; /* what the storm has done */
	uint64_t events;
};

/* Change the override or hold state at random periods, through the
 * controller's commands; never leaves the machine stopped for more than one
 * event, so every program finishes. Returns 1 with *cmd set, or 0. */
int mlip_simstorm_tick(struct mlip_simstorm *st, uint64_t period, struct mlip_ring_cmd *cmd);

#endif
