/*
 * rtplan.c - mlip-rt's planning thread for [TRAJ] JERK_PLAN = path (issue
 * 21; docs/algorithm.md "The planning thread and its queue"). SCHED_OTHER
 * beside the loop: it owns the ring's read port, runs each program's
 * records through the plan's controller and the streaming plan
 * (tools/lib/planfeed.h) into the planned queue, and publishes the queue to
 * the period (struct mlip_period_plan, rt/rt.h) once its first entry is
 * queued. Being late is safe: a dry queue is the period's braking run,
 * inside the limits. A refused plan is the controller's FAULT (reason
 * PLAN_REFUSED; pp.fault counts them); once the controller is done with a
 * program (its end, a stop, a refusal's FAULT left: pp.fault_left) the rest
 * of its records is dropped and the plan starts afresh.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "mlip/ctl/state.h"
#include "mlip/motion/smooth.h"
#include "planfeed.h"
#include "rtparts.h"

#define LD(p)    __atomic_load_n((p), __ATOMIC_ACQUIRE)
#define ST(p, v) __atomic_store_n((p), (v), __ATOMIC_RELEASE)

/* the plan's controller and plan: large (4.5 MB), fixed, the thread's
 * alone; allocated only with the key (locked with the rest) */
static struct plan_mem {
	struct mlip_planner planner;
	struct mlip_smooth_store store;
	struct mlip_ctl ctl;
	struct mlip_pathrun run;
	struct mlip_planq queue;
	struct mlip_config cfg; /* the machine's, HOME where the controller stands */
	struct mlip_planfeed pf;
} * M;

enum { WAIT, PLAN, DROP, DEAD };

static const struct mlip_ring_rec *rec_at(const struct mlip_rec_view *v, uint32_t k)
{
	return k < v->len[0] ? &v->span[0][k] : &v->span[1][k - v->len[0]];
}

static void take(struct mlip_rtplan *t, uint32_t k)
{
	t->taken += k;
	if (t->phase == DEAD || t->phase == DROP) {
		/* a refused or stopped program's records: no program to come, so
		 * counted before their slots go back (a feeder that finds the
		 * ring empty takes the status as its base) */
		ST(&t->pp.taken_base, t->taken);
	}
	mlip_ring_port_pop_n(&t->rx, k);
	ST(&t->pp.taken, t->taken);
}

/* A program's first records are queued: its plan from where the controller
 * stands, under the machine's cap and each block's own feed (its knots'
 * cap, mlip_simpath_tag); it begins at the first move (or the END). */
static int begin(struct mlip_rtplan *t, const struct mlip_rec_view *v, uint32_t n)
{
	int moves = 0;
	for (uint32_t k = 0; k < n && !moves; k++) {
		const struct mlip_ring_rec *r = rec_at(v, k);
		moves = r->type == MLIP_REC_MOVE || r->type == MLIP_REC_END;
	}
	struct mlip_ring_status st;
	if (!moves || mlip_ring_status_read(t->ring, &st) != MLIP_OK) {
		return -1;
	}
	M->cfg = *t->cfg;
	for (int k = 0; k < M->cfg.machine.n_axes; k++) {
		M->cfg.machine.axis[k].home = st.pos[k];
	}
	uint32_t la = M->cfg.lookahead ? M->cfg.lookahead : MLIP_LOOKAHEAD; /* as mlip-sim */
	const char *why = NULL;
	if (mlip_planfeed_init(&M->pf, &M->cfg, 0.0, la, &M->ctl, &M->planner, &M->store, &M->run,
	                       &M->queue, &why) != 0) {
		M->pf.why = why;
	}
	t->published = 0;
	t->queued_all = 0;
	return 0;
}

/* The controller is done with the program: the next starts afresh. */
static void reset(struct mlip_rtplan *t)
{
	ST(&t->pp.prog, 0u);
	ST(&t->pp.end_seq, (uint64_t)0);
	ST(&t->pp.taken_base, t->taken);
}

static void refuse(struct mlip_rtplan *t)
{
	/* its records taken so far count for the status at once: refused
	 * before it was published (prog 0), the status shows taken_base, and
	 * the next feeder reads it as its base (else the next program's first
	 * record, kept by drop, moved it while that program waited to start,
	 * and its feeder took itself for stopped) */
	ST(&t->pp.taken_base, t->taken);
	fprintf(stderr,
	        "mlip-rt: JERK_PLAN = path: the plan refused the program (t = %.3f s of "
	        "its controller): %s\n",
	        M->pf.why_t, M->pf.why ? M->pf.why : "?");
	ST(&t->pp.fault, ++t->faults);
}

/* The feeder gone (killed, or left without its END: a file that changed)
 * before the program's END: looked at every 50 ms while the ring is dry.
 * Dead only: a late feeder (its process there, not scheduled for a while,
 * as on a loaded host) sends the rest when it runs again; meanwhile the
 * queue runs dry into its braking run, as the records' controller waits
 * at rest for records (ring_dry, src/ctl/run.c). */
static int feeder_gone(struct mlip_rtplan *t)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	uint64_t now = (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
	if (now - t->looked_ns < 50000000u) {
		return 0;
	}
	t->looked_ns = now;
	struct mlip_ring_feeder f;
	return mlip_ring_feeder_read(t->ring, &f) == MLIP_OK &&
	       mlip_peer_feeder(&f) == MLIP_PEER_DEAD;
}

/* One round of the plan: records offered, one unit of work. 1: busy. */
static int plan(struct mlip_rtplan *t, const struct mlip_rec_view *v, uint32_t n)
{
	uint32_t k = 0, room = mlip_planfeed_room(&M->pf);
	for (; k < n && k < room; k++) {
		const struct mlip_ring_rec *r = rec_at(v, k);
		mlip_planfeed_offer(&M->pf, r);
		t->last_seq = r->seq;
		if (r->type == MLIP_REC_END) {
			ST(&t->pp.end_seq, r->seq);
			k++;
			break;
		}
	}
	take(t, k);
	if (n == 0 && !M->pf.end_in && room > 0 && feeder_gone(t)) {
		/* the END it never sent: the plan ends at rest on the last point
		 * sent, as a program of records stops after its last record */
		struct mlip_ring_rec end;
		mlip_ring_rec_end(&end, t->last_seq + 1, 0);
		mlip_planfeed_offer(&M->pf, &end);
		ST(&t->pp.end_seq, end.seq);
	}
	/* also once the last entry is queued: a hold or a lower feed in the
	 * queue's last periods asks for a plan from its rest (the resume) */
	int r = mlip_planfeed_work(&M->pf);
	if (r < 0) {
		refuse(t);
		t->phase = DEAD;
		return 1;
	}
	t->queued_all |= r == 2;
	/* published once the queue is full (or holds the whole program): the
	 * period's first pop finds its entry, and the queue its cushion */
	if (!t->published && (M->pf.planned >= MLIP_PLANQ_LEN || t->queued_all)) {
		t->published = 1;
		ST(&t->pp.prog, ++t->prog);
	}
	if (t->published && LD(&t->pp.done) == t->prog) {
		/* the period is done with the queue (pp.done stored after its
		 * last step): its figures are still */
		if (M->queue.c.starved > 0) {
			fprintf(stderr,
			        "mlip-rt: JERK_PLAN = path: program %u: the queue ran dry %ld "
			        "time(s) (the planning thread was late): the period braked there, "
			        "the motion is not mlip-sim's\n",
			        (unsigned)t->prog, M->queue.c.starved);
		}
		t->phase = M->pf.end_in ? WAIT : DROP;
		if (M->pf.end_in) {
			reset(t);
		}
		return 1;
	}
	return k > 0 || r == 1; /* 2: the last entry queued, nothing to plan */
}

/* A stopped program's records up to its END (a record numbered 1 is the
 * next program's: kept). 1: busy. */
static int drop(struct mlip_rtplan *t, const struct mlip_rec_view *v, uint32_t n)
{
	uint32_t k = 0;
	int end = 0;
	for (; k < n && !end; k++) {
		const struct mlip_ring_rec *r = rec_at(v, k);
		if (r->seq == 1) {
			end = 1;
			break; /* kept */
		}
		end = r->type == MLIP_REC_END;
	}
	take(t, k);
	if (end) {
		reset(t);
		t->phase = WAIT;
	}
	return k > 0;
}

static void *thread(void *arg)
{
	struct mlip_rtplan *t = arg;
	while (!LD(&t->quit)) {
		struct mlip_rec_view v;
		uint32_t apart = 0, n;
		int busy = 0;
		if (mlip_ring_port_view(&t->rx, &v, &apart) != MLIP_OK && t->phase != DEAD) {
			M->pf.why = "the ring is corrupt (its indices more than a capacity apart)";
			refuse(t);
			t->phase = DEAD;
		}
		n = v.len[0] + v.len[1];
		switch (t->phase) {
		case WAIT:
			if (n > 0 && begin(t, &v, n) == 0) {
				t->phase = PLAN;
				busy = 1;
			}
			break;
		case PLAN:
			busy = plan(t, &v, n);
			break;
		case DROP:
			busy = drop(t, &v, n);
			break;
		default:
			/* refused: what comes is dropped while the controller is in
			 * FAULT; once it has left it (a reset after an E-stop, as for
			 * every fault on the path) and dropped the queue, the rest of
			 * the refused program goes too (up to its END; a record
			 * numbered 1 starts the next, which plans). Read after the
			 * view: a feeder that saw the controller idle sent after the
			 * period stored fault_left, so its records are never taken here */
			if (LD(&t->pp.fault_left) == t->faults) {
				t->phase = DROP;
				busy = 1;
			} else if (n > 0 && apart == 0) {
				take(t, n);
			}
			break;
		}
		if (!busy) {
			/* nothing to do (the queue full, no record): a fifth of a period */
			struct timespec ts = {0, 200000};
			nanosleep(&ts, NULL);
		}
	}
	return NULL;
}

int mlip_rtplan_start(struct mlip_rtplan *t, const struct mlip_config *cfg, struct mlip_ring *ring)
{
	memset(t, 0, sizeof(*t));
	if (M == NULL && (M = calloc(1, sizeof(*M))) == NULL) {
		return -1;
	}
	t->cfg = cfg;
	t->ring = ring;
	t->pp.q = &M->queue;
	pthread_attr_t attr;
	pthread_attr_init(&attr);
	pthread_attr_setstacksize(&attr, 512 * 1024); /* memory is locked: not 8 MB */
	int rc = mlip_ring_port_open(&t->rx, ring, 0) == MLIP_OK &&
	                 pthread_create(&t->th, &attr, thread, t) == 0
	             ? 0
	             : -1;
	pthread_attr_destroy(&attr);
	if (rc != 0) {
		return -1;
	}
	t->running = 1;
	return 0;
}

void mlip_rtplan_stop(struct mlip_rtplan *t)
{
	if (t->running) {
		ST(&t->quit, 1);
		pthread_join(t->th, NULL);
		t->running = 0;
	}
}
