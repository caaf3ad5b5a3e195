/*
 * power.c - the drives' power (ctl.h, CiA 402, opts.drives): enabled for a
 * program or a jog, disabled at rest after it, never out of ENABLED while
 * the planner moves.
 */
#include <string.h>

#include "ctl.h"

#include "mlip/canopen/drive.h"

/* The first axis beyond a soft limit, or -1 (an axis still to be homed has
 * none yet: machine zero is wherever its drive powered up). */
static int beyond_limit(const struct mlip_ctl *c)
{
	for (int k = 0; k < c->m.n_axes; k++) {
		const struct mlip_axis *a = &c->m.axis[k];
		if (!unhomed(c, k) && !(c->pos[k] >= a->min_limit && c->pos[k] <= a->max_limit)) {
			return k;
		}
	}
	return -1;
}

/* At rest where the drives are to be disabled: after a program or a stop
 * (not the idle of a fresh start: the bring-up enabled them to hold the
 * start position), in a fault, or on exit. */
static int power_rest(const struct mlip_ctl *c)
{
	/* the last setpoint sent twice: every drive has applied it at a SYNC
	 * before it is told to disable operation */
	if (mlip_planner_queued(c->planner) > 0 || mlip_planner_moving(c->planner) ||
	    c->power.still_periods < 2 || !mlip_ctl_spindle_at_rest(&c->spindle)) {
		return 0; /* and a spindle on the bus at standstill */
	}
	return c->state == MLIP_STATE_FAULT || c->op.exiting ||
	       (c->state == MLIP_STATE_IDLE && c->why.why != MLIP_WHY_NONE);
}

/* A step of the drives' power ended: the event, with the drive that did
 * not confirm it in time (its node and statusword). */
static void power_event(struct mlip_ctl *c, struct mlip_ctl_out *out,
                        const struct mlip_402_change *ch)
{
	struct mlip_ctl_reason r = reason(MLIP_WHY_NONE, ch->in_sequence, 0);
	r.value = (double)ch->in_step;
	if (ch->late >= 0) {
		r.node = mlip_ct_node_of(c, ch->late);
		r.field = ch->late_sw;
	}
	if (out->n_events < MLIP_CTL_MAX_EVENTS) {
		struct mlip_ctl_event *e = &out->events[out->n_events++];
		e->kind = MLIP_EV_POWER;
		e->from = ch->from;
		e->state = ch->to;
		e->r = r;
		e->period = c->period;
		mlip_ct_progress(c, &e->exec_seq, &e->exec_line);
	}
}

/* One period of the drives' power, after the step (the sequencer of
 * mlip/canopen/cia402.h, all drives in step): never out of ENABLED while the
 * planner moves, never moving out of it (records are taken only when
 * ENABLED). A program waiting enables them (from where they stand, inside
 * the soft limits); at rest after it, a stop or a fault, or on exit, they are
 * disabled. Enabling not confirmed in time is a fault naming the drive. */
void mlip_ct_power_period(struct mlip_ctl *c, const struct mlip_ctl_in *in,
                          struct mlip_ctl_out *out)
{
	uint32_t power = c->power.seq.step;
	int want = c->power.want;
	struct mlip_402_change ch;

	if (c->io.estop) {
		c->power.seq.cw = MLIP_402_CW_QUICK_STOP; /* to every drive, until the reset */
		return;
	}
	if (power == MLIP_POWER_OFF || power == MLIP_POWER_SWITCHING_ON) {
		/* no holding torque: the commanded position is where the drives are */
		for (int k = 0; k < c->m.n_axes; k++) {
			if (in->drives.actual_mask & (1u << k)) {
				c->pos[k] = in->drives.pos_actual[k];
			}
		}
		mlip_planner_rest_at(c->planner, c->pos);
		int k = want ? beyond_limit(c) : -1;
		if (k >= 0) {
			int32_t counts = 0;
			mlip_can_counts(c->pos[k], c->m.axis[k].counts_per_unit, &counts);
			struct mlip_ctl_drive_fault f = {MLIP_DRIVE_BEYOND_LIMIT,
			                                 (uint32_t)c->m.axis[k].can_node,
			                                 (double)counts};
			mlip_ct_drive_fault(c, out, &f);
			want = 0;
		}
	} else if (power == MLIP_POWER_ENABLED) {
		want = !power_rest(c);
	}
	/* a spindle on the bus is one more drive of the group */
	uint16_t sw[MLIP_MAX_AXES + 1];
	uint32_t mute = in->drives.mute;
	int n = c->m.n_axes;
	memcpy(sw, in->drives.sw, sizeof(in->drives.sw));
	if (c->spindle.on) {
		sw[n] = in->spindle.sw;
		mute |= in->spindle.mute ? 1u << n : 0u;
		n++;
	}
	if (!mlip_402_seq_run(&c->power.seq, want ? MLIP_POWER_ENABLED : MLIP_POWER_OFF, sw, n,
	                      mute, c->period, &ch)) {
		return;
	}
	if (ch.failed) {
		/* a step toward power not confirmed in time: a fault naming the
		 * drive, the step and its statusword, the program is dropped, the
		 * drives go down again; nothing has moved */
		struct mlip_ctl_drive_fault f = {
		    ch.from == MLIP_POWER_SWITCHING_ON ? MLIP_DRIVE_NOT_SWITCHED_ON
		    : ch.from == MLIP_POWER_ENABLING   ? MLIP_DRIVE_NOT_ENABLED
		                                       : MLIP_DRIVE_POWER_STEP,
		    mlip_ct_node_of(c, ch.late),
		    ch.from == MLIP_POWER_SWITCHING_ON || ch.from == MLIP_POWER_ENABLING
		        ? (double)ch.late_sw
		        : (double)ch.from * 65536.0 + (double)ch.late_sw};
		mlip_ct_drive_fault(c, out, &f);
	}
	power_event(c, out, &ch);
}
