/*
 * follow.c - the controller's run mode for [TRAJ] JERK_PLAN = path (issue
 * 21; ctl.h, docs/algorithm.md "The planning thread and its queue"): the
 * setpoints of a program come from the planned queue a planning thread
 * fills (mlip/motion/planq.h), not from the controller's own planner, which
 * rests meanwhile. The period pops one entry (or takes one braking step) and
 * keeps the supervision it has in every mode (E-stop, quick stop, faults,
 * inputs, the bus, the drives' power, the status).
 *
 *   IDLE --in->plan, a new program number, drives enabled--> RUNNING (START)
 *   RUNNING --hold | override 0 | the bus, the queue's braking run at rest-->
 *     HELD --released--> RUNNING (RESUME), the plan asked again from rest
 *   RUNNING --a stall--> HELD at once, at rest at the last setpoint sent
 *     (mlip_planq_rest: the drives stood there)
 *   RUNNING|HELD --stop | exit--> STOPPING: the braking run, at rest IDLE
 *   RUNNING --the queue's last entry, at rest--> IDLE (END)
 *   a drive fault, or an E-stop without drives: the braking run (the
 *   state FAULT or ESTOP as today), the program dropped at rest; an E-stop
 *   with drives: the program dropped at once (they quick stop)
 * A hold, a stop and a lower override act in the period they arrive: the
 * queue's entry is already the braking run's first step, inside A and J
 * (the run certified with the state). The braking run is the queue's, so
 * the plan's limits hold through it; only the quick stop exceeds them.
 * The override scales the plan's cap (mlip_planq_feed), at most to it: the
 * machine's and each block's own F (the knots' caps, pathplan.h Q5) scale
 * with it. No allocation, no I/O, no lock.
 */
#include "ctl.h"

#include <math.h>
#include <string.h>

/* The program's queue is dropped (at rest, or where the drives are): the
 * controller's own planner rests at the last setpoint, as after a program
 * of records; the planning thread starts the next one under a new number. */
void mlip_ct_ext_drop(struct mlip_ctl *c)
{
	if (c->ext.q != NULL) {
		(void)mlip_planner_abort(c->planner, c->pos); /* finite: a setpoint sent */
	}
	c->ext.q = NULL;
	c->ext.stopping = 0;
}

/* Feed override pct (0: a hold, handled by the caller's hold) onto the
 * plan's cap. */
void mlip_ct_ext_override(struct mlip_ctl *c, double pct)
{
	if (c->ext.q != NULL && pct > 0.0) {
		(void)mlip_planq_feed(c->ext.q, c->ext.vmax * fmin(pct, 100.0) / 100.0);
	}
}

/* A program of in->plan starts: at rest in IDLE, once per number, with the
 * drives enabled (a program waiting asks for them, as records do). A queue
 * that does not start at the machine's position is refused (counted and
 * reported as a refused program), one whose feeder began before a stop
 * never starts (STOP_EARLY). 1: it runs. */
int mlip_ct_ext_start(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out)
{
	struct mlip_planq *q = in->plan;
	if (q == NULL || c->ext.q != NULL || in->plan_prog == c->ext.last || c->io.estop ||
	    c->state != MLIP_STATE_IDLE || c->jog.on || c->home.on) {
		return c->ext.q != NULL;
	}
	if (c->drives && c->power.seq.step != MLIP_POWER_ENABLED) {
		c->power.want = 1;
		return 0;
	}
	if (in->feeder_unread) {
		return 0; /* whose program this is: known next period */
	}
	c->ext.last = in->plan_prog;
	if (mlip_ring_stop_after(c->op.stop_seen, in->feeder_stop_base)) {
		/* a stop came after its feeder began (before the queue was
		 * published): it never starts, as a program of records */
		c->counts.refused++;
		if (c->why.why == MLIP_WHY_STOP_EARLY) {
			c->why.why = MLIP_WHY_NONE; /* a second refusal is named too */
		}
		go(c, out, MLIP_STATE_IDLE, reason(MLIP_WHY_STOP_EARLY, 0, 0));
		return 0;
	}
	if (q->first_seq > 1 && q->first_seq != c->prog.exec.seq + 1) {
		/* neither a program's start nor the block after the last one
		 * completed here (as a program of records, run.c) */
		struct mlip_ctl_reason r = reason(MLIP_WHY_NONE, q->first_seq, 0);
		r.value = (double)(c->prog.exec.seq + 1);
		c->counts.refused++;
		emit(c, out, MLIP_EV_REFUSED, c->state, &r);
		return 0;
	}
	for (int k = 0; k < c->m.n_axes; k++) {
		if (!(fabs(q->c.x[k] - c->pos[k]) <= 1e-9)) {
			struct mlip_ctl_reason r = reason(MLIP_WHY_BAD_RECORD, 0, 0);
			r.value = q->c.x[k];
			c->counts.refused++;
			emit(c, out, MLIP_EV_REFUSED, c->state, &r);
			return 0;
		}
	}
	if (q->first_seq <= 1) {
		c->prog.exec = (struct mlip_ctl_mark){0, 0}; /* a new program */
	}
	c->ext.q = q;
	c->ext.prog = in->plan_prog;
	c->ext.vmax = q->c.vmax;
	c->ext.stopping = 0;
	memcpy(c->prog.start, c->pos, sizeof(c->prog.start));
	mlip_ct_ext_override(c, mlip_planner_override_pct(c->planner));
	go(c, out, MLIP_STATE_RUNNING, reason(MLIP_WHY_START, 0, 0));
	return 1;
}

/* A stop (mlip-ctl stop, exit): the braking run, then IDLE; the stop stays
 * the reason. */
void mlip_ct_ext_stop(struct mlip_ctl *c, struct mlip_ctl_out *out, uint32_t why)
{
	c->ext.stopping = 1;
	c->hold.op = 0; /* as the planner's stop ends a hold */
	if (c->state == MLIP_STATE_FAULT) {
		return;
	}
	mlip_ct_brake_begin(c);
	go(c, out, MLIP_STATE_STOPPING, reason(why, 0, 0));
}

static uint32_t held_why(const struct mlip_ctl *c)
{
	if (c->hold.stall) {
		return MLIP_WHY_STALL;
	}
	if (c->hold.bus) {
		return c->hold.bus_why;
	}
	if (!c->hold.op && mlip_planner_override_pct(c->planner) == 0.0) {
		return MLIP_WHY_OVERRIDE_ZERO;
	}
	return MLIP_WHY_HOLD;
}

/* At rest on the queue's state (its braking run done, or waiting). */
static int at_rest(const struct mlip_planq *q, int mode)
{
	return mode != MLIP_PLANQ_PLAN && q->c.st.v == 0.0 && q->c.st.a == 0.0;
}

/* The period's step while a program follows the queue. */
void mlip_ct_ext_step(struct mlip_ctl *c, struct mlip_ctl_out *out)
{
	struct mlip_planq *q = c->ext.q;
	int hold = c->hold.op || c->hold.bus || c->hold.stall || c->ext.stopping || c->io.estop ||
	           c->state == MLIP_STATE_FAULT || mlip_planner_override_pct(c->planner) == 0.0;
	double prev[MLIP_MAX_AXES];
	memcpy(prev, c->pos, sizeof(prev));
	int mode = mlip_planq_step(q, hold, c->pos);
	int rest = mode >= 0 && at_rest(q, mode);
	if (c->brake.on) {
		mlip_ct_brake_step(c, prev, rest ? MLIP_RUN_IDLE : MLIP_RUN_MOVING);
	}
	if (q->c.mark.done_seq > c->prog.exec.seq) {
		/* completed: its last record at rest once dropped */
		c->prog.exec.seq = q->c.mark.done_seq;
		c->prog.exec.line = q->c.mark.done_line;
	}
	int still = memcmp(prev, c->pos, sizeof(prev)) == 0;
	c->power.still_periods = still ? c->power.still_periods + 1 : 0;
	if (mode < 0) {
		/* a state the plan did not certify: a defect; the setpoint held */
		memcpy(c->pos, prev, sizeof(prev));
		c->ext.stopping = 1;
		struct mlip_ctl_reason r = reason(MLIP_WHY_POSITION_RANGE, 0, 0);
		mlip_ct_progress(c, &r.seq, &r.line); /* the block it came in */
		mlip_ct_fault(c, out, r);
		mlip_ct_ext_drop(c);
		return;
	}
	switch (c->state) {
	case MLIP_STATE_RUNNING:
	case MLIP_STATE_HELD:
		if (mode == MLIP_PLANQ_DONE) {
			/* the program done: its END (as a program of records),
			 * else its last block */
			struct mlip_ctl_mark end = {q->end_seq, q->end_line};
			if (end.seq == 0) {
				end = (struct mlip_ctl_mark){q->c.mark.seq, q->c.mark.line};
			}
			if (end.seq > c->prog.exec.seq) {
				c->prog.exec = end;
			}
			mlip_ct_ext_drop(c);
			go(c, out, MLIP_STATE_IDLE,
			   reason(MLIP_WHY_END, c->prog.exec.seq, c->prog.exec.line));
		} else if (hold && rest &&
		           (c->state == MLIP_STATE_RUNNING || c->why.why != held_why(c))) {
			go(c, out, MLIP_STATE_HELD, reason(held_why(c), 0, 0));
		} else if (!hold && mode == MLIP_PLANQ_PLAN && c->state == MLIP_STATE_HELD) {
			go(c, out, MLIP_STATE_RUNNING, reason(MLIP_WHY_RESUME, 0, 0));
		}
		return;
	case MLIP_STATE_STOPPING:
		if (rest || mode == MLIP_PLANQ_DONE) {
			mlip_ct_ext_drop(c);
			go(c, out, MLIP_STATE_IDLE, c->why); /* the stop stays the reason */
		}
		return;
	default: /* FAULT, ESTOP without drives: dropped at rest */
		if (rest || mode == MLIP_PLANQ_DONE) {
			mlip_ct_ext_drop(c);
		}
		return;
	}
}
