/*
 * sim_fault.c - the test side of test_check_exact.py's fault build of
 * mlip-sim: linked with -Wl,--wrap=mlip_trace_sample, it pushes the setpoint
 * of trace row MLIP_SIM_FAULT_AT (1-based after t = 0) 0.05 mm off on every
 * axis before the trace and mlip-sim's own check see it, so that the check
 * must catch it. mlip-sim itself has no hook for it.
 */
#include "trace.h"

int __real_mlip_trace_sample(struct mlip_trace *tr, uint32_t state, const double *pos,
                             const double **start);
int __wrap_mlip_trace_sample(struct mlip_trace *tr, uint32_t state, const double *pos,
                             const double **start);

int __wrap_mlip_trace_sample(struct mlip_trace *tr, uint32_t state, const double *pos,
                             const double **start)
{
	if (tr->started && !tr->ended && tr->rows + 1 == MLIP_SIM_FAULT_AT) {
		double *p = (double *)pos; /* the controller's output: not const there */
		for (int a = 0; a < tr->n; a++) {
			p[a] += 0.05;
		}
	}
	return __real_mlip_trace_sample(tr, state, pos, start);
}
