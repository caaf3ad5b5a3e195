/*
 * trace.h - the setpoint trace of one program, written the same way by
 * mlip-sim (from its virtual clock) and mlip-rt --record (from its monitor
 * thread): CSV `t,x,y,...`, t = 0 at the last period before the program
 * leaves IDLE/PRE-READ (the start point), then one row per period up to and
 * including the first period back in IDLE (at rest on the last point, or
 * where a stop ended).
 */
#ifndef MLIP_TOOLS_TRACE_H
#define MLIP_TOOLS_TRACE_H

#include <stdint.h>
#include <stdio.h>

#include "mlip/types.h"

struct mlip_trace {
	FILE *f; /* NULL: rows are counted, not written */
	int n;
	double period_s;
	int started, ended;
	uint64_t rows;     /* rows after t = 0 */
	uint64_t t0, last; /* period index of t = 0, and of the last row */
	double pending[MLIP_MAX_AXES];
	int have_pending;
};

/* Writes the header when f is not NULL. start (may be NULL): the setpoint
 * before the first sample (the controller's first period may already move). */
void mlip_trace_open(struct mlip_trace *tr, FILE *f, const struct mlip_machine *m,
                     const double *start);
/* One period's setpoint and the state after it. Returns 1 for a row written
 * (the t = 0 row and this one, at the start), 0 when none, and *start (may be
 * NULL) gets the t = 0 point when this is the first. Stops after the end. */
int mlip_trace_sample(struct mlip_trace *tr, uint32_t state, const double *pos,
                      const double **start);
/* The same at period index `period` (increasing): a gap in the indices (a
 * late controller's missed deadlines) is a gap in t, a hole for mlip-check. */
int mlip_trace_sample_at(struct mlip_trace *tr, uint64_t period, uint32_t state, const double *pos,
                         const double **start);

#endif
