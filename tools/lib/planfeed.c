/* planfeed.c - see planfeed.h */
#include "planfeed.h"

#include <string.h>

#include "mlip/ctl/state.h"
#include "simpath.h"

/* The plan's braking runs (as mlip-sim's, simpath.c) */
#define RUN_PERIODS 3000

int mlip_planfeed_init(struct mlip_planfeed *pf, const struct mlip_config *cfg, double feed,
                       uint32_t lookahead, struct mlip_ctl *ctl, struct mlip_planner *pl,
                       struct mlip_smooth_store *store, struct mlip_pathrun *pr,
                       struct mlip_planq *q, const char **why)
{
	const struct mlip_machine *m = &cfg->machine;
	memset(pf, 0, sizeof(*pf));
	if (mlip_simpath_limits(m, feed, &pf->lim, &pf->band_mm, why) != 0) {
		return -1;
	}
	mlip_simpath_machine(m, &pf->cm); /* smooth's, as mlip-feed's and mlip-sim's */
	for (int k = 0; k < m->n_axes; k++) {
		pf->start[k] = m->axis[k].home;
	}
	pf->cm.smooth = 1;
	pf->ctl = ctl;
	pf->pr = pr;
	pf->q = q;
	pf->io = &cfg->inputs;
	struct mlip_ctl_opts co = {.strategy = MLIP_STRATEGY_SMOOTH,
	                           .smooth = store,
	                           .lookahead = lookahead,
	                           .io = &cfg->inputs};
	if (mlip_ctl_init(ctl, pl, &pf->cm, &co) != MLIP_OK) {
		*why = "the look-ahead is not a power of two in 2..MLIP_LOOKAHEAD";
		return -1;
	}
	mlip_planner_set_override(pl, 100.0);
	mlip_trace_open(&pf->ctl_trace, NULL, &pf->cm, pf->start);
	return 0;
}

const struct mlip_machine *mlip_planfeed_machine(const struct mlip_planfeed *pf)
{
	return &pf->cm;
}

uint32_t mlip_planfeed_room(const struct mlip_planfeed *pf)
{
	return pf->end_in ? 0 : MLIP_PLANFEED_CAP - (pf->head - pf->tail);
}

void mlip_planfeed_offer(struct mlip_planfeed *pf, const struct mlip_ring_rec *r)
{
	if (pf->head == 0 && r->seq > 1) {
		/* a continuation (mlip-feed --start-seq): its controller takes
		 * it as the block after the last one completed (the follower
		 * checks that against its own, mlip_planq.first_seq) */
		pf->ctl->prog.exec.seq = r->seq - 1;
	}
	if (pf->head == 0) {
		pf->first_seq = r->seq;
	}
	if (r->type == MLIP_REC_END) {
		pf->end_seq = r->seq;
		pf->end_line = r->line;
	}
	pf->rec[pf->head++ & (MLIP_PLANFEED_CAP - 1u)] = *r;
	pf->end_in |= r->type == MLIP_REC_END;
}

static int refuse(struct mlip_planfeed *pf, const char *why)
{
	pf->why = why;
	pf->why_t = (double)pf->period * pf->cm.period_s;
	return -1;
}

/* One controller period (the FIFO full or holding the END, as mlip-sim's
 * queue before each of its periods): 1 a setpoint pending, 0 none (before
 * the motion), 3 the motion ended, -1 refused. */
static int ctl_period(struct mlip_planfeed *pf)
{
	static struct mlip_ctl_out out;
	struct mlip_ctl_in in = {.period = pf->period++, .feeder_alive = 1};
	in.io.known = pf->io->mapped;
	uint32_t n = pf->head - pf->tail, at = pf->tail & (MLIP_PLANFEED_CAP - 1u);
	in.recs.span[0] = pf->rec + at;
	in.recs.len[0] = n < MLIP_PLANFEED_CAP - at ? n : MLIP_PLANFEED_CAP - at;
	in.recs.span[1] = pf->rec;
	in.recs.len[1] = n - in.recs.len[0];
	mlip_ctl_period(pf->ctl, &in, &out);
	pf->tail += out.taken;
	pf->ctl_periods++;
	uint32_t state = out.status.state;
	if (state == MLIP_STATE_FAULT) {
		return refuse(pf, "the plan's controller faulted");
	}
	const double *start;
	if (!mlip_trace_sample(&pf->ctl_trace, state, out.pos, &start)) {
		return pf->ctl_trace.ended ? 3 : 0;
	}
	if (start != NULL) {
		memcpy(pf->start, start, sizeof(double) * (size_t)pf->cm.n_axes);
		if (mlip_pathrun_init(pf->pr, &pf->lim, pf->band_mm, RUN_PERIODS, start) != 0 ||
		    mlip_simpath_fair(pf->pr) != 0) {
			return refuse(pf, "the plan's limits are not positive");
		}
		mlip_planq_init(pf->q, pf->pr);
		pf->q->first_seq = pf->first_seq;
		__atomic_store_n(&pf->started, 1, __ATOMIC_RELEASE);
	}
	if (state == MLIP_STATE_RUNNING) {
		/* the record this setpoint's motion belongs to, and the last
		 * completed, carried with it as a knot (planq.h c.mark) */
		struct mlip_pathrun_tag *t = &pf->pr->tag_in;
		t->seq = out.status.exec_seq;
		t->line = out.status.exec_line;
		/* in a corner past its middle: its block done, so a stop that
		 * rests there names the next (a continuation from the corner's
		 * block went back 0.37 mm to its corner point: (P6) refused) */
		mlip_planner_resume_done(pf->ctl->planner, &t->done_seq, &t->done_line);
		mlip_simpath_tag(t, pf->ctl->planner); /* its cap: as mlip-sim's */
	}
	if (state != MLIP_STATE_RUNNING && state != MLIP_STATE_IDLE) {
		return refuse(pf, "the program left RUNNING (a pause, dwell or hold): the plan "
		                  "takes none yet");
	}
	memcpy(pf->pending, out.pos, sizeof(double) * (size_t)pf->cm.n_axes);
	pf->has_pending = 1;
	return pf->ctl_trace.ended ? 3 : 1;
}

int mlip_planfeed_work(struct mlip_planfeed *pf)
{
	if (pf->why != NULL) {
		return -1;
	}
	if (pf->has_pending) {
		/* the setpoint into the window; a full window plans a period */
		int r = mlip_pathrun_push(pf->pr, pf->pending);
		if (r < 0) {
			return refuse(pf, pf->pr->why);
		}
		if (r == 0) {
			pf->has_pending = 0;
			if (pf->ctl_trace.ended && !pf->finished) {
				if (mlip_pathrun_finish(pf->pr) != 0) {
					return refuse(pf, pf->pr->why);
				}
				pf->finished = 1;
				/* the END, which no knot carries, for the follower at
				 * the last entry (queued after this) */
				pf->q->end_seq = pf->end_seq;
				pf->q->end_line = pf->end_line;
			}
			return 1;
		}
	} else if (!pf->finished) {
		if (!pf->end_in && pf->head - pf->tail < MLIP_PLANFEED_CAP) {
			return 0; /* mlip-sim's controller would see more records */
		}
		int r = ctl_period(pf);
		return r < 0 ? -1 : 1;
	}
	uint32_t head = pf->q->head; /* ours: the producer's index */
	int r = mlip_planq_produce(pf->q, pf->pr);
	if (r < 0) {
		return refuse(pf, pf->pr->why);
	}
	if (r == 3) {
		return refuse(pf, "the plan asked for input it had"); /* a defect */
	}
	pf->planned += pf->q->head != head; /* 2 also after the last: nothing queued */
	return r;
}
