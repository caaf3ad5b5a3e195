/*
 * rtparts.h - the parts of mlip-rt beside it (tools/rtparts.c).
 */
#ifndef MLIP_TOOLS_RTPARTS_H
#define MLIP_TOOLS_RTPARTS_H

#include <stddef.h>
#include <stdint.h>

#include <pthread.h>

#include "mlip/can/canenc.h"
#include "mlip/machine/config.h"
#include "rt.h"

int mlip_rt_bus_budget(const struct mlip_config *cfg, mlip_can_profile prof);
void mlip_rt_process_name(int32_t pid, char *out, size_t n);

/* The planning thread for [TRAJ] JERK_PLAN = path (tools/rtplan.c): pp is
 * what the period reads (per.plan = &t->pp), the rest the thread's. */
struct mlip_rtplan {
	struct mlip_period_plan pp;
	const struct mlip_config *cfg;
	struct mlip_ring *ring;
	struct mlip_ring_port rx; /* the ring's consumer side: the thread's alone */
	pthread_t th;
	int running, quit; /* quit: atomic */
	int phase;         /* waiting for a program, planning it, dropping its rest, refused */
	int published, queued_all;
	uint32_t prog;      /* programs published */
	uint32_t faults;    /* programs refused (pp.fault) */
	uint64_t taken;     /* records taken from the ring */
	uint64_t last_seq;  /* the last record offered to the plan */
	uint64_t looked_ns; /* the feeder's liveness last read */
};

/* Start the thread on ring (cfg: the machine file's, kept): -1 on failure. */
int mlip_rtplan_start(struct mlip_rtplan *t, const struct mlip_config *cfg, struct mlip_ring *ring);
/* Stop and join it (after the loop). */
void mlip_rtplan_stop(struct mlip_rtplan *t);

#endif
