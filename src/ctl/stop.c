/*
 * stop.c - the controller's stops on the path (ctl.h): a stop request, a
 * drive fault, and the measure of a stop from its request to rest.
 */
#include "ctl.h"

#include <math.h>

/* A CiA 402 drive faulted (rt/drivehooks.c's supervision): never go on blind.
 * Every axis stops on the path (the planner's stop: the other drives follow
 * it to rest; the faulted drive, muted by rt/, is in its own fault reaction),
 * nothing more of the program is taken, and the state says which node, which
 * event, in which block and line. The first drive fault stays the reason. */
void mlip_ct_drive_fault(struct mlip_ctl *c, struct mlip_ctl_out *out,
                         const struct mlip_ctl_drive_fault *f)
{
	struct mlip_ctl_reason r = reason(
	    c->spindle.on && f->node == c->spindle.node ? MLIP_WHY_SPINDLE_FAULT : MLIP_WHY_DRIVE,
	    0, 0);
	mlip_ct_progress(c, &r.seq, &r.line);
	r.field = f->event;
	r.node = f->node;
	r.value = f->value;
	c->drive_faulted = 1;
	c->jog.on = 0;
	for (int k = 0; k < c->m.n_axes; k++) {
		if ((uint32_t)c->m.axis[k].can_node == f->node) {
			c->home.homed &=
			    ~(1u << k); /* a faulted drive may have lost its position */
		}
	}
	mlip_ct_home_abort(c);
	if (c->io.estop) {
		/* the quick stop goes on; the fault comes back after the reset */
		if (!c->io.fault_kept) {
			c->io.fault_kept = 1;
			c->io.kept = r;
		}
		return;
	}
	if (c->state == MLIP_STATE_DWELLING || c->state == MLIP_STATE_PAUSED) {
		c->wait.stopped = 1; /* the wait is not done */
	}
	if (mlip_planner_queued(c->planner) > 0) {
		mlip_ct_planner_stop(c);
		mlip_ct_brake_begin(c);
	}
	c->wait.dwell_left = 0;
	c->prog.bad = 1;     /* nothing more is taken */
	c->prog.discard = 1; /* the rest of the program is dropped */
	go(c, out, MLIP_STATE_FAULT, r);
}

/* A stop or hold was asked for: measure the path to rest (status stop_*). */
void mlip_ct_brake_begin(struct mlip_ctl *c)
{
	if (!c->brake.on) {
		c->brake.on = 1;
		c->brake.mm = 0.0;
		c->brake.periods = 0;
	}
}

void mlip_ct_brake_step(struct mlip_ctl *c, const double *prev, mlip_run_state rs)
{
	double d2 = 0.0;
	for (int k = 0; k < c->m.n_axes; k++) {
		if (c->m.axis[k].kind == MLIP_AXIS_LINEAR) {
			d2 += (c->pos[k] - prev[k]) * (c->pos[k] - prev[k]);
		}
	}
	c->brake.mm += sqrt(d2);
	c->brake.periods++;
	if (rs != MLIP_RUN_MOVING) {
		c->brake.on = 0;
		c->brake.last_nm = (uint64_t)(c->brake.mm * 1e6 + 0.5);
		c->brake.last_periods = c->brake.periods;
		c->brake.count++;
	}
}

/* Nothing has moved since the machine last came to rest: a pre-read (of a
 * new program, or after an underrun or a wait) or a wait. The planner is
 * not stepped in these states, so it rests at the last setpoint and what it
 * holds has never run. */
static int unmoved(const struct mlip_ctl *c)
{
	return c->state == MLIP_STATE_PREREAD || c->state == MLIP_STATE_DWELLING ||
	       c->state == MLIP_STATE_PAUSED;
}

/* Stop the planner. Moving: on the path at the acceleration limit (the
 * planner's stop). Unmoved: what it holds is dropped where it rests, and no
 * setpoint changes. (The planner's stop would follow the plan in force until
 * its backward pass, a bounded amount of work a period, had come back to the
 * first corner: several periods at the look-ahead's depth, in which that
 * plan accelerates from rest into the program's first block.) */
void mlip_ct_planner_stop(struct mlip_ctl *c)
{
	if (unmoved(c)) {
		mlip_planner_abort(c->planner, c->pos); /* finite: the last setpoint */
	} else {
		mlip_planner_stop(c->planner);
	}
}

/* A hold latched at rest ends (a stop at rest, an E-stop): Grbl 1.1's
 * reset leaves Hold for Idle. A bus still bad holds again next period. */
void mlip_ct_hold_clear(struct mlip_ctl *c)
{
	c->hold.op = 0;
	c->hold.stall = 0;
	c->hold.bus = 0;
	mlip_planner_hold(c->planner, 0);
}

/* Stop: decelerate on the path and drop the rest of the program. */
void mlip_ct_begin_stop(struct mlip_ctl *c, struct mlip_ctl_out *out, uint32_t why)
{
	if (c->io.estop) {
		return; /* stopped already, harder */
	}
	if (c->home.on) {
		mlip_ct_home_abort(c); /* the drives move by themselves: back to CSP, then idle */
		if (c->home.on) {
			c->home.stop_why = why;
		} else if (c->state == MLIP_STATE_HOMING) {
			go(c, out, MLIP_STATE_IDLE, reason(why, 0, 0));
		}
		return;
	}
	if (c->ext.q != NULL) {
		mlip_ct_ext_stop(c, out, why); /* the queue's braking run */
		return;
	}
	if (c->jog.on) {
		mlip_ct_jog_release(c, MLIP_WHY_JOG_RELEASED); /* a stop ends a jog on the path */
		all_off(c);                                    /* and what an MDI line left on */
		if (why != MLIP_WHY_EXIT) {
			return;
		}
	}
	if (c->state == MLIP_STATE_IDLE && mlip_planner_queued(c->planner) == 0) {
		/* nothing moving; a program already waiting in the ring (for the
		 * drives to be enabled) is dropped, its first record too */
		c->prog.discard = rx_count(c) > 0;
		c->prog.discard_waiting = c->prog.discard;
		all_off(c); /* what an MDI line left on (issue 19) */
		mlip_ct_hold_clear(c);
		return;
	}
	if (c->state == MLIP_STATE_PREREAD && !c->prog.refill && why == MLIP_WHY_STOP) {
		/* the program's pre-read: it has not started, the stop is latched
		 * for it as for one still being checked (STOP_EARLY): dropped
		 * unmoved, its first record named (the reason of its pre-read) */
		struct mlip_ctl_reason r = reason(MLIP_WHY_STOP_EARLY, c->why.seq, c->why.line);
		mlip_ct_planner_stop(c);
		c->hold.op = 0; /* as the planner's stop ends a hold */
		c->prog.discard = c->prog.end.seq == 0;
		c->prog.end.seq = 0;
		c->counts.refused++;
		go(c, out, MLIP_STATE_IDLE, r);
		return;
	}
	/* in a dwell or a pause the wait is not done: the block completed is
	 * the one before it (the pre-read after it never moved) */
	c->wait.stopped = c->state == MLIP_STATE_DWELLING || c->state == MLIP_STATE_PAUSED;
	mlip_ct_planner_stop(c);
	c->wait.dwell_left = 0;
	c->hold.op = 0; /* the planner's stop ends a hold too */
	if (c->state == MLIP_STATE_FAULT) {
		return; /* the fault stays the reason */
	}
	mlip_ct_brake_begin(c);
	c->prog.discard = c->prog.end.seq == 0;
	c->prog.end.seq = 0;
	go(c, out, MLIP_STATE_STOPPING, reason(why, 0, 0));
}
