/*
 * interp.h - private to src/motion/: what the look-ahead and the commands
 * (planner.c) share with the interpolation (interp.c).
 */
#ifndef MLIP_MOTION_INTERP_H
#define MLIP_MOTION_INTERP_H

#include <stdint.h>

#include "mlip/motion/strategy.h"

static inline struct mlip_seg *seg_at(struct mlip_planner *p, uint32_t i)
{
	return mlip_seg_at(p, i);
}

static inline const struct mlip_seg *cseg_at(const struct mlip_planner *p, uint32_t i)
{
	return &p->seg[i & (p->cap - 1)];
}

static inline double effective_override(const struct mlip_planner *p)
{
	return p->hold ? 0.0 : p->override;
}

/* The mark of the sample at the window's centre, (m - 1) / 2 periods ago:
 * the setpoint is within E_f of the plan there (J5; m is odd). */
const struct mlip_exec_mark *mlip_centre_mark(const struct mlip_planner *p);
/* The mean has come to rest: the plan stood still over the whole window. */
int mlip_settled(const struct mlip_planner *p);
/* Every sample of the window at p->pos, where the plan is now: at rest. */
void mlip_filter_reset(struct mlip_planner *p);
/* Segment tail is finished: account for it and free its slot. */
void mlip_retire(struct mlip_planner *p);

#endif
