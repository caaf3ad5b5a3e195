/*
 * jog.c - the controller's jog (ctl.h, issue 18): one axis or several along
 * one straight line, continuous (toward the soft limit) or incremental (a
 * distance per axis), through the planner and its limits, renewed by its
 * command, stopped by its release or its dead-man.
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

/* Axis k's end toward neg: its soft limit, and never beyond what the
 * drives' int32 counts can carry; an axis to be homed and not yet has no
 * soft limit (machine zero is not known yet: LinuxCNC), only that range. */
static double axis_end(const struct mlip_ctl *c, int k, int neg)
{
	const struct mlip_axis *a = &c->m.axis[k];
	double range = a->counts_per_unit > 0.0 ? 2147483000.0 / a->counts_per_unit : 1e9;
	double end = neg ? a->min_limit : a->max_limit;
	if (unhomed(c, k)) {
		end = neg ? -range : range;
	}
	return end > range ? range : end < -range ? -range : end;
}

static int incremental(const struct mlip_ctl *c)
{
	for (int k = 0; k < c->m.n_axes; k++) {
		if (c->jog.dist[k] > 0.0) {
			return 1;
		}
	}
	return 0;
}

/* The jog's target from where the machine is: each distance (incremental),
 * or along the jog's line until its first axis reaches its end
 * (continuous). 0, or -1 when it leaves the travel: an incremental target
 * beyond a soft limit, an axis at its end that way already (Grbl's error
 * 15: the jog target exceeds the machine's travel). */
static int jog_target(const struct mlip_ctl *c, double *target)
{
	double room = 1e300;
	int inc = incremental(c);
	memcpy(target, c->pos, sizeof(c->pos));
	for (int k = 0; k < c->m.n_axes; k++) {
		if (!(c->jog.axes & (1u << k))) {
			continue;
		}
		int neg = (c->jog.negs >> k) & 1u;
		double end = axis_end(c, k, neg), here = c->pos[k];
		double left = neg ? here - end : end - here;
		if (inc && !(c->jog.dist[k] <= left)) {
			return -1;
		}
		if (!inc && !(left > 0.0)) {
			return -1;
		}
		room = left < room ? left : room;
	}
	for (int k = 0; k < c->m.n_axes; k++) {
		if (c->jog.axes & (1u << k)) {
			double d = inc ? c->jog.dist[k] : room;
			target[k] = c->pos[k] + ((c->jog.negs >> k) & 1u ? -d : d);
		}
	}
	return 0;
}

/* Drives enabled (or none): the jog's block, from where the machine is to
 * its target at the jog's speed (the path speed of the line): the planner
 * plans it to rest there, so the jog stops exactly at the soft limit or
 * the distance. */
static void jog_start(struct mlip_ctl *c, struct mlip_ctl_out *out)
{
	struct mlip_block b;
	memset(&b, 0, sizeof(b));
	b.feed_mm_s = c->jog.speed;
	b.tol_mm = c->m.tolerance_mm;
	b.kind = MLIP_BLOCK_MOVE;
	if (jog_target(c, b.target) != 0 || mlip_planner_push(c->planner, &b) != MLIP_OK) {
		/* the planner is not at rest, or the drives were enabled where the
		 * target leaves the travel: nothing moves */
		c->jog.on = 0;
		go(c, out, MLIP_STATE_IDLE, reason(MLIP_WHY_JOG_END, 0, 0));
		return;
	}
	c->jog.moving = 1;
}

/* MLIP_CMD_JOG_AXIS: one more axis, or a distance, for the next jog. */
int32_t mlip_ct_jog_axis_command(struct mlip_ctl *c, int32_t arg)
{
	uint32_t u = (uint32_t)arg, axis = u & 7u, um = (u >> 4) & 0xFFFFFu;
	if ((int)axis >= c->m.n_axes) {
		return MLIP_E_RANGE;
	}
	if (c->jog.on) {
		return MLIP_E_INVALID; /* a jog's axes are set before it starts */
	}
	if (c->period - c->jog.pend_at > c->jog.deadman) {
		c->jog.pend_axes = c->jog.pend_negs = 0; /* stale: another client's */
	}
	c->jog.pend_axes |= 1u << axis;
	c->jog.pend_negs = (c->jog.pend_negs & ~(1u << axis)) | ((u & 8u) ? 1u << axis : 0u);
	c->jog.pend_dist[axis] = (double)um * 1e-3;
	c->jog.pend_at = c->period;
	return MLIP_OK;
}

/* The next jog's axes: its own and the fresh JOG_AXIS ones. 0, or
 * MLIP_E_SYNTAX (its axis given the other way, distances on some axes
 * only). */
static int32_t jog_axes(struct mlip_ctl *c, uint32_t axis, int neg)
{
	uint32_t axes = 0, negs = 0, with = 0, n = 0;
	if (c->period - c->jog.pend_at <= c->jog.deadman) {
		axes = c->jog.pend_axes;
		negs = c->jog.pend_negs;
	}
	c->jog.pend_axes = c->jog.pend_negs = 0; /* taken, whatever happens */
	if ((axes & (1u << axis)) && ((negs >> axis) & 1u) != (uint32_t)neg) {
		return MLIP_E_SYNTAX;
	}
	if (!(axes & (1u << axis))) {
		c->jog.pend_dist[axis] = 0.0;
	}
	axes |= 1u << axis;
	negs |= neg ? 1u << axis : 0u;
	for (int k = 0; k < c->m.n_axes; k++) {
		c->jog.dist[k] = (axes & (1u << k)) ? c->jog.pend_dist[k] : 0.0;
		with += c->jog.dist[k] > 0.0;
		n += (axes >> k) & 1u;
	}
	if (with != 0 && with != n) {
		return MLIP_E_SYNTAX; /* continuous and incremental at once */
	}
	c->jog.axes = axes;
	c->jog.negs = negs;
	return MLIP_OK;
}

/* MLIP_CMD_JOG: start, renew or release. MLIP_E_RANGE: an axis not in the
 * machine, or a target out of the travel (Grbl's error 15: an incremental
 * target beyond a soft limit, an axis at its limit that way already);
 * MLIP_E_SYNTAX: the JOG_AXIS before it disagree with it; MLIP_E_INVALID:
 * not at rest and idle (a program, a stop, a fault, an E-stop), or another
 * jog moving. */
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
	int32_t rc = jog_axes(c, axis, neg);
	if (rc != MLIP_OK) {
		return rc;
	}
	if (c->state == MLIP_STATE_FAULT && c->why.why == MLIP_WHY_LIMIT && c->io.estop &&
	    !c->home.on) {
		/* stopped on a limit switch: only a jog of that axis alone away
		 * from it, which leaves the quick stop (the switch does not trip
		 * again until released) */
		uint32_t f = c->why.field, k = (f - MLIP_IN_AXIS0) / 3;
		int away_neg = f == MLIP_IN_LIMIT_POS(k);
		if (axis != k || neg != away_neg || c->jog.axes != 1u << k) {
			return MLIP_E_RANGE; /* toward the switch, or another axis */
		}
		if (!mlip_ct_estop_at_rest(c)) {
			return MLIP_E_FULL; /* still braking on the drives' ramps */
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
	    rx_count(c) > 0 || mlip_planner_held(c->planner)) {
		/* a hold latched at rest too: Grbl 1.1 refuses $J in Hold (error
		 * 8); a resume releases it, moving nothing */
		return MLIP_E_INVALID;
	}
	c->jog.axis = axis;
	c->jog.neg = neg;
	double target[MLIP_MAX_AXES];
	if (jog_target(c, target) != 0) {
		return MLIP_E_RANGE;
	}
	c->jog.on = 1;
	c->jog.moving = 0;
	c->jog.stopping = 0;
	c->jog.speed = (double)mm_min / 60.0;
	c->jog.renewed = c->period;
	c->jog.end_why = incremental(c) ? MLIP_WHY_JOG_DONE : MLIP_WHY_JOG_END;
	struct mlip_ctl_reason r = reason(MLIP_WHY_JOG, 0, 0);
	r.field = MLIP_JOG_FIELD(axis, c->jog.axes, c->jog.negs, incremental(c));
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
