/*
 * planfeed.h - the planning thread's work for [TRAJ] JERK_PLAN = path
 * (issue 21; docs/algorithm.md "The planning thread and its queue"): a
 * second controller (smooth without J, eps less the plan's band: mlip-sim's
 * path candidate) runs the program's records ahead of the 1 ms period; its
 * setpoints go through the streaming plan (mlip/motion/pathrun.h) into the
 * planned queue (mlip/motion/planq.h), which the period pops.
 *
 * Deterministic: the records wait in a FIFO of MLIP_RING_CAPACITY, and the
 * controller runs a period only when the FIFO is full or holds the END, the
 * view mlip-sim's controller has in every period; the plan steps only on a
 * full window (pathrun.h), and what its compaction keeps does not depend on
 * the consumer's lag (tests/unit/test_planq.c test_lag_independent). So the
 * queue's entries are mlip-sim --jerk-plan path's setpoints bit for bit,
 * whatever the thread's timing; only a dry queue (the period brakes) or a
 * hold changes the motion.
 *
 * Not for the 1 ms thread: a controller period plus a planned period cost
 * ~1e6 instructions. No allocation (the caller's memory), no I/O, no lock.
 */
#ifndef MLIP_TOOLS_PLANFEED_H
#define MLIP_TOOLS_PLANFEED_H

#include "mlip/ctl/controller.h"
#include "mlip/ipc/ring.h"
#include "mlip/machine/config.h"
#include "mlip/motion/planq.h"
#include "trace.h"

#define MLIP_PLANFEED_CAP MLIP_RING_CAPACITY /* mlip-sim's queue of records */

struct mlip_planfeed {
	struct mlip_machine cm; /* the controller's machine: no J, eps less the band */
	struct mlip_path_limits lim;
	double band_mm;
	struct mlip_ctl *ctl;
	struct mlip_pathrun *pr;
	struct mlip_planq *q;
	const struct mlip_io_config *io;
	struct mlip_trace ctl_trace; /* its setpoints' start and end (not written) */
	struct mlip_ring_rec rec[MLIP_PLANFEED_CAP];
	uint32_t head, tail; /* free-running */
	int end_in;          /* the END is offered */
	uint64_t period;     /* the controller's */
	double pending[MLIP_MAX_AXES];
	int has_pending, finished;
	int started; /* atomic: the queue is initialised (the consumer may step) */
	double start[MLIP_MAX_AXES];
	uint64_t first_seq, end_seq; /* the program's first record's, its END's */
	uint32_t end_line;
	const char *why; /* a refusal */
	double why_t;    /* the controller's time there, s */
	/* figures */
	uint64_t planned, ctl_periods;
};

/* m: the machine (with J on every axis); feed: the plan's speed cap
 * beside the blocks' own (0: the machine's; each block's F is its knots'
 * cap, mlip_simpath_tag, as mlip-sim's); the controller and its
 * planner, smooth store, the window and the queue: the caller's (large).
 * -1 with *why on a machine the plan cannot run. */
int mlip_planfeed_init(struct mlip_planfeed *pf, const struct mlip_config *cfg, double feed,
                       uint32_t lookahead, struct mlip_ctl *ctl, struct mlip_planner *pl,
                       struct mlip_smooth_store *store, struct mlip_pathrun *pr,
                       struct mlip_planq *q, const char **why);

/* The controller's machine (for the smoothing filter a feeder runs). */
const struct mlip_machine *mlip_planfeed_machine(const struct mlip_planfeed *pf);

/* Records it can take now, and one record (in the ring's order, END last). */
uint32_t mlip_planfeed_room(const struct mlip_planfeed *pf);
void mlip_planfeed_offer(struct mlip_planfeed *pf, const struct mlip_ring_rec *r);

/* One unit of work: a controller period, a setpoint into the window, or a
 * planned period into the queue. 1 done, 0 blocked (it needs records, or
 * the queue is full), 2 the program's last setpoint is queued (again
 * after it: a request, a resume from rest, is taken first), -1 refused
 * (pf->why: the controller left RUNNING, the plan refused a piece). */
int mlip_planfeed_work(struct mlip_planfeed *pf);

#endif
