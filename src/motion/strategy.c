/*
 * strategy.c - the corner strategies behind one table (mlip/motion/strategy.h):
 * each is its corner and, for smooth, the planner hooks and the storage its
 * data needs. A new strategy is a row here, not a branch in the planner.
 */
#include <string.h>

#include "mlip/motion/strategy.h"

const struct mlip_strategy_ops mlip_strategies[MLIP_STRATEGY_COUNT] = {
    [MLIP_STRATEGY_MPCT] = {.name = "mpct", .corner = mlip_corner_mpct},
    [MLIP_STRATEGY_BISECTOR] = {.name = "bisector", .corner = mlip_corner_bisector},
    [MLIP_STRATEGY_STOP] = {.name = "stop", .corner = mlip_corner_stop},
    [MLIP_STRATEGY_SMOOTH] = {.name = "smooth",
                              .corner = mlip_corner_smooth,
                              .link = mlip_smooth_link,
                              .choose = mlip_smooth_choose,
                              .commit = mlip_smooth_commit,
                              .line_start = mlip_smooth_line_start,
                              .needs_store = 1},
};

const char *mlip_strategy_name(mlip_strategy st)
{
	return (unsigned)st < MLIP_STRATEGY_COUNT ? mlip_strategies[st].name : NULL;
}

int mlip_strategy_from_name(const char *name)
{
	for (int i = 0; i < MLIP_STRATEGY_COUNT; i++) {
		if (strcmp(name, mlip_strategies[i].name) == 0) {
			return i;
		}
	}
	return -1;
}
