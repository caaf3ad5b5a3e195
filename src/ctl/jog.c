/*
 * jog.c - the controller's continuous jog (ctl.h, issue 18): toward the
 * soft limit through the planner, renewed by its command, stopped by its
 * release or its dead-man.
 */
#include "ctl.h"

#include <string.h>

/* The jog ends braking on the path at the acceleration limit (the planner's
 * stop), the reason kept for the state it ends in. */
void mlip_ct_jog_release(struct mlip_ctl *c, uint32_t why)
{
	if (!c->jog.on || c->jog.stopping) {
		return;
	}
	c->jog.end_why = why;
	if (!c->jog.moving) {
		c->jog.on = 0; /* still waiting for the drives: nothing moved */
		return;
	}
	c->jog.stopping = 1;
	mlip_planner_stop(c->planner);
	mlip_ct_brake_begin(c);
}

/* The axis' end in the jog's direction: its soft limit, and never beyond
 * what the drives' int32 counts can carry. */
static double jog_end(const struct mlip_ctl *c)
{
	const struct mlip_axis *a = &c->m.axis[c->jog.axis];
	double range = a->counts_per_unit > 0.0 ? 2147483000.0 / a->counts_per_unit : 1e9;
	double end = c->jog.neg ? a->min_limit : a->max_limit;
	if (unhomed(c, (int)c->jog.axis)) {
		end = c->jog.neg ? -range : range; /* machine zero is not known yet (LinuxCNC) */
	}
	return end > range ? range : end < -range ? -range : end;
}

/* Drives enabled (or none): the jog's block, from where the machine is to the
 * soft limit, at the jog's speed: the planner plans it to rest there, so the
 * jog stops exactly at the limit. */
static void jog_start(struct mlip_ctl *c, struct mlip_ctl_out *out)
{
	struct mlip_block b;
	memset(&b, 0, sizeof(b));
	memcpy(b.target, c->pos, sizeof(b.target));
	b.target[c->jog.axis] = jog_end(c);
	b.feed_mm_s = c->jog.speed;
	b.tol_mm = c->m.tolerance_mm;
	b.kind = MLIP_BLOCK_MOVE;
	if (mlip_planner_push(c->planner, &b) != MLIP_OK) {
		c->jog.on = 0; /* the planner is not at rest: nothing moves */
		go(c, out, MLIP_STATE_IDLE, reason(MLIP_WHY_JOG_RELEASED, 0, 0));
		return;
	}
	c->jog.moving = 1;
}

/* MLIP_CMD_JOG: start, renew or release. MLIP_E_RANGE: an axis not in the
 * machine, or no room toward the soft limit (Grbl's error 15: the jog
 * would leave the machine's travel); MLIP_E_INVALID: not at rest and idle
 * (a program, a stop, a fault, an E-stop), or another jog moving. */
int32_t mlip_ct_jog_command(struct mlip_ctl *c, struct mlip_ctl_out *out, int32_t arg)
{
	uint32_t u = (uint32_t)arg, axis = u & 7u, mm_min = (u >> 4) & 0xFFFFFu;
	int neg = (u & 8u) != 0;
	if ((int)axis >= c->m.n_axes) {
		return MLIP_E_RANGE;
	}
	if (mm_min == 0) {
		if (c->jog.on && axis == c->jog.axis) {
			mlip_ct_jog_release(c, MLIP_WHY_JOG_RELEASED);
		}
		return MLIP_OK; /* a release after the end is no error */
	}
	if (c->jog.on) {
		if (axis != c->jog.axis || neg != c->jog.neg || c->jog.stopping) {
			return MLIP_E_INVALID; /* one jog at a time: release it first */
		}
		c->jog.renewed = c->period;
		return MLIP_OK;
	}
	if (c->state == MLIP_STATE_FAULT && c->why.why == MLIP_WHY_LIMIT && c->io.estop &&
	    !c->home.on) {
		/* stopped on a limit switch: only a jog away from it, which leaves
		 * the quick stop (the switch does not trip again until released) */
		uint32_t f = c->why.field, k = (f - MLIP_IN_AXIS0) / 3;
		int away_neg = f == MLIP_IN_LIMIT_POS(k);
		if (axis != k || neg != away_neg) {
			return MLIP_E_RANGE; /* toward the switch, or another axis */
		}
		c->io.limit_ignore |= 1u << f;
		c->io.estop = 0;
		c->prog.bad = 0;
		c->prog.discard = rx_count(c) > 0;
		c->prog.discard_waiting = c->prog.discard;
		if (c->drives) {
			mlip_402_seq_init(&c->power.seq, MLIP_POWER_NONE,
			                  c->power.seq.timeout ? c->power.seq.timeout : 1000,
			                  c->period);
		}
		go(c, out, MLIP_STATE_IDLE, reason(MLIP_WHY_RESET, 0, 0));
	}
	if (c->state != MLIP_STATE_IDLE || c->io.estop || mlip_planner_queued(c->planner) > 0 ||
	    rx_count(c) > 0) {
		return MLIP_E_INVALID;
	}
	c->jog.axis = axis;
	c->jog.neg = neg;
	double end = jog_end(c), here = c->pos[axis];
	if (neg ? !(end < here) : !(end > here)) {
		return MLIP_E_RANGE; /* at (or beyond) the soft limit that way already */
	}
	c->jog.on = 1;
	c->jog.moving = 0;
	c->jog.stopping = 0;
	c->jog.speed = (double)mm_min / 60.0;
	c->jog.renewed = c->period;
	c->jog.end_why = MLIP_WHY_JOG_END;
	struct mlip_ctl_reason r = reason(MLIP_WHY_JOG, 0, 0);
	r.field = axis;
	r.value = neg ? -c->jog.speed : c->jog.speed;
	go(c, out, MLIP_STATE_JOGGING, r);
	return MLIP_OK;
}

/* Each period of a jog: start once the drives are enabled, stop when not
 * renewed. */
void mlip_ct_jog_period(struct mlip_ctl *c, struct mlip_ctl_out *out)
{
	if (!c->jog.on) {
		return;
	}
	if (!c->jog.moving) {
		if (!c->drives || c->power.seq.step == MLIP_POWER_ENABLED) {
			jog_start(c, out);
		} else {
			c->power.want = 1; /* enable the drives first, from where they are */
		}
	}
	if (c->period - c->jog.renewed > c->jog.deadman) {
		mlip_ct_jog_release(c, MLIP_WHY_JOG_DEADMAN);
	}
	if (!c->jog.on && c->state == MLIP_STATE_JOGGING) {
		go(c, out, MLIP_STATE_IDLE, reason(c->jog.end_why, 0, 0)); /* never moved */
	}
}
