/*
 * homing.c - the controller's homing (ctl.h, issue 18): each HOME_SEQUENCE
 * group set up by SDO, run in the drives' homing mode (CiA 402 mode 6),
 * returned to CSP.
 */
#include "ctl.h"

#define SW_TARGET_REACHED 0x0400u /* statusword bit 10 */
#define SW_HOMING_DONE    0x1000u /* bit 12 in mode 6: homing attained */
#define SW_HOMING_ERROR   0x2000u /* bit 13 in mode 6: homing error */
#define CW_HOMING_START   0x0010u /* controlword bit 4: homing operation start */
#define MODE_HOMING       6

/* Object e of axis k's homing set-up (0x6098, 0x6099:1/2, 0x609A, 0x607C,
 * then 0x6060 = 6), or of its return (0x6060 = 8): 0 when there is none.
 * *rb: the object read back (0x6061 for 0x6060). */
static int home_object(const struct mlip_ctl *c, int k, int e, int back, struct mlip_ctl_sdo_req *r,
                       uint16_t *rb)
{
	const struct mlip_axis_home *h = &c->home.cfg.axis[k];
	double cpu = c->m.axis[k].counts_per_unit;
	r->node = (uint8_t)c->m.axis[k].can_node;
	r->upload = 0;
	r->sub = 0;
	r->size = 4;
	if (back) {
		if (e > 0) {
			return 0; /* the return is one object: 0x6060 = 8 */
		}
		e = 5;
	}
	switch (e) {
	case 0:
		r->index = 0x6098;
		r->size = 1;
		r->value = (uint8_t)(int8_t)h->method;
		break;
	case 1:
	case 2:
		r->index = 0x6099;
		r->sub = (uint8_t)e;
		r->value = (uint32_t)((e == 1 ? h->search_vel : h->latch_vel) * cpu + 0.5);
		break;
	case 3:
		r->index = 0x609A;
		r->value = (uint32_t)(h->accel * cpu + 0.5);
		break;
	case 4: {
		int32_t counts = 0;
		mlip_can_counts(h->offset, cpu, &counts);
		r->index = 0x607C;
		r->value = (uint32_t)counts;
		break;
	}
	case 5:
		r->index = 0x6060;
		r->size = 1;
		r->value = back ? MLIP_402_MODE_CSP : MODE_HOMING;
		break;
	default:
		return 0;
	}
	*rb = r->index == 0x6060 ? 0x6061 : r->index;
	return 1;
}

static void home_request(struct mlip_ctl *c, const struct mlip_ctl_sdo_req *r)
{
	c->home.req = *r;
	c->home.requests = c->home.requests + 1 ? c->home.requests + 1 : 1; /* never 0 */
	c->home.req.seq = c->home.sdo_seq = c->home.requests;
}

/* The first axis of the group at or after axis k, or -1. */
static int group_axis(const struct mlip_ctl *c, int k)
{
	for (; k < c->m.n_axes; k++) {
		if (c->home.group & (1u << k)) {
			return k;
		}
	}
	return -1;
}

/* Ask for the current object of the current axis (or go on to the next
 * axis); 0 when the group's list is done. */
static int home_issue(struct mlip_ctl *c, int back)
{
	struct mlip_ctl_sdo_req r;
	uint16_t rb;
	while (c->home.axis >= 0) {
		if (home_object(c, c->home.axis, c->home.entry, back, &r, &rb)) {
			home_request(c, &r);
			c->home.readback = 0;
			return 1;
		}
		c->home.axis = group_axis(c, c->home.axis + 1);
		c->home.entry = 0;
	}
	return 0;
}

/* The next group: the lowest HOME_SEQUENCE among the axes still to home. */
static int home_next_group(struct mlip_ctl *c)
{
	int best = 100;
	c->home.group = 0;
	for (int k = 0; k < c->m.n_axes; k++) {
		if ((c->home.todo & (1u << k)) && c->home.cfg.axis[k].sequence < best) {
			best = c->home.cfg.axis[k].sequence;
		}
	}
	for (int k = 0; k < c->m.n_axes; k++) {
		if ((c->home.todo & (1u << k)) && c->home.cfg.axis[k].sequence == best) {
			c->home.group |= 1u << k;
		}
	}
	c->home.todo &= ~c->home.group;
	c->home.attained = 0;
	c->home.axis = group_axis(c, 0);
	c->home.entry = 0;
	return c->home.group != 0;
}

/* Homing given up (a failure, an E-stop, a drive fault, a stop): the group
 * goes back to CSP (best effort: SDO 0x6060 = 8), nothing more is homed. */
void mlip_ct_home_abort(struct mlip_ctl *c)
{
	if (!c->home.on || c->home.failed) {
		return;
	}
	c->home.failed = 1;
	c->home.todo = 0;
	c->home.cw = MLIP_402_CW_ENABLE_OPERATION;
	if (c->home.step < HS_SETUP || c->home.group == 0) {
		c->home.on = 0; /* nothing was written yet */
		return;
	}
	c->home.step = HS_BACK;
	c->home.axis = group_axis(c, 0);
	c->home.entry = 0;
	home_issue(c, 1);
}

/* A failure: every axis stops (quick stop), the reason names the drive;
 * the group is still returned to CSP (best effort) so that a reset leaves
 * drives that follow targets again. */
static void home_fail(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out,
                      uint32_t why, int k, uint32_t field, double value)
{
	struct mlip_ctl_reason r = reason(why, 0, 0);
	r.node = (uint32_t)c->m.axis[k].can_node;
	r.field = field;
	r.value = value;
	mlip_ct_quick_stop(c, in, out, MLIP_STATE_FAULT, r); /* and home_abort */
}

/* MLIP_CMD_HOME: axes (mask; 0: every configured one). */
int32_t mlip_ct_home_command(struct mlip_ctl *c, struct mlip_ctl_out *out, int32_t arg)
{
	uint32_t want = (uint32_t)arg & ((1u << c->m.n_axes) - 1u);
	if (arg == 0) {
		want = c->home.configured;
	}
	if (!c->drives || want == 0 || (want & ~c->home.configured) != 0 ||
	    ((uint32_t)arg >> c->m.n_axes) != 0) {
		return MLIP_E_RANGE; /* an axis without HOME_METHOD (or no drives) */
	}
	if (c->state != MLIP_STATE_IDLE || c->io.estop || c->home.on ||
	    mlip_planner_queued(c->planner) > 0 || rx_count(c) > 0 ||
	    mlip_planner_held(c->planner)) {
		/* a hold latched at rest too, as a jog (Grbl refuses $H in Hold):
		 * the drives' own motion would leave the held program's path;
		 * a resume (moving nothing) or a stop releases it first */
		return MLIP_E_INVALID;
	}
	c->home.on = 1;
	c->home.failed = 0;
	c->home.todo = want;
	c->home.homed &= ~want; /* homing again: not homed until it is done */
	c->home.step = HS_ENABLE;
	c->home.cw = MLIP_402_CW_ENABLE_OPERATION;
	struct mlip_ctl_reason r = reason(MLIP_WHY_HOMING, 0, 0);
	r.field = want;
	go(c, out, MLIP_STATE_HOMING, r);
	return MLIP_OK;
}

/* One period of homing, after the commands and inputs. */
void mlip_ct_home_period(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out)
{
	if (!c->home.on) {
		return;
	}
	/* the group's axes: the target is where the drive is, to the count, so
	 * that the return to CSP is no step */
	if (c->home.step >= HS_ARM && !c->io.estop) {
		for (int k = 0; k < c->m.n_axes; k++) {
			if ((c->home.group & (1u << k)) && (in->drives.actual_mask & (1u << k))) {
				c->pos[k] = in->drives.pos_actual[k];
			}
		}
		mlip_planner_rest_at(c->planner, c->pos);
	}
	switch (c->home.step) {
	case HS_ENABLE:
		if (c->power.seq.step != MLIP_POWER_ENABLED) {
			c->power.want = 1; /* from where the drives stand */
			return;
		}
		home_next_group(c);
		c->home.step = HS_SETUP;
		home_issue(c, 0);
		return;
	case HS_SETUP:
	case HS_BACK: {
		int back = c->home.step == HS_BACK;
		if (c->home.sdo_seq == 0 || in->sdo.seq != c->home.sdo_seq) {
			return; /* its answer is not there yet */
		}
		struct mlip_ctl_sdo_req r = c->home.req;
		uint32_t field = (uint32_t)r.index << 8 | r.sub;
		uint16_t rb;
		c->home.sdo_seq = 0;
		if (in->sdo.abort != 0 && !c->home.failed) {
			home_fail(c, in, out, MLIP_WHY_HOMING_SDO, c->home.axis, field,
			          (double)in->sdo.abort);
			return;
		}
		if (in->sdo.abort == 0 && !c->home.readback) {
			home_object(c, c->home.axis, c->home.entry, back, &r, &rb);
			r.index = rb;
			r.upload = 1;
			home_request(c, &r);
			c->home.readback = 1;
			return;
		}
		if (in->sdo.abort == 0 && !c->home.failed) {
			uint32_t mask = r.size >= 4 ? 0xFFFFFFFFu : (1u << (8 * r.size)) - 1u;
			home_object(c, c->home.axis, c->home.entry, back, &r, &rb);
			if ((in->sdo.value & mask) != (r.value & mask)) {
				home_fail(c, in, out, MLIP_WHY_HOMING_SDO, c->home.axis,
				          (uint32_t)rb << 8 | r.sub,
				          (double)(in->sdo.value & mask));
				return;
			}
		}
		c->home.entry++;
		if (home_issue(c, back)) {
			return;
		}
		if (!back) {
			c->home.step = HS_ARM;
			return;
		}
		/* back in CSP: where the drives are is where the machine is */
		if (!c->home.failed) {
			c->home.homed |= c->home.group;
		}
		c->home.step = HS_NEXT;
		return;
	}
	case HS_ARM:
		c->home.cw = MLIP_402_CW_ENABLE_OPERATION; /* bit 4 low: its rise starts it */
		c->home.step = HS_RUN;
		c->home.t0 = c->period + 1;
		return;
	case HS_RUN:
		c->home.cw = MLIP_402_CW_ENABLE_OPERATION | CW_HOMING_START;
		for (int k = 0; k < c->m.n_axes; k++) {
			uint16_t sw = in->drives.sw[k];
			uint64_t when = in->drives.tpdo_period[k];
			uint32_t bit = 1u << k;
			/* only a TPDO that answers a SYNC after the start was applied:
			 * bit 4's rise goes in period t0's RPDO, applied at the SYNC of
			 * t0 + 1, whose TPDO the drive sampled before applying it (CiA
			 * 301); the first that can show the start answers the SYNC of
			 * t0 + 2. Before it a drive homed earlier still shows that
			 * homing's bits 10 and 12 (or 13) */
			int fresh = when != UINT64_MAX && when >= c->home.t0 + 2;
			if (!(c->home.group & bit)) {
				continue;
			}
			if (c->home.attained & bit) {
				/* waiting for the rest of its group: a drive whose "homing
				 * attained" (bit 12) drops has lost its home (it started
				 * homing again, or lost its position): wait for it again */
				if (fresh && !(sw & SW_HOMING_DONE)) {
					c->home.attained &= ~bit;
				}
				continue;
			}
			if (fresh && (sw & SW_HOMING_ERROR)) {
				home_fail(c, in, out, MLIP_WHY_HOMING_ERROR, k,
				          (uint32_t)c->home.cfg.axis[k].method, (double)sw);
				return;
			}
			if (fresh && (sw & (SW_HOMING_DONE | SW_TARGET_REACHED)) ==
			                 (SW_HOMING_DONE | SW_TARGET_REACHED)) {
				c->home.attained |= bit;
			} else if ((double)(c->period - c->home.t0) * c->m.period_s >
			           c->home.cfg.axis[k].timeout_s) {
				home_fail(c, in, out, MLIP_WHY_HOMING_TIMEOUT, k,
				          (uint32_t)c->home.cfg.axis[k].method, (double)sw);
				return;
			}
		}
		if (c->home.attained == c->home.group) {
			c->home.cw = MLIP_402_CW_ENABLE_OPERATION;
			c->home.step = HS_BACK;
			c->home.axis = group_axis(c, 0);
			c->home.entry = 0;
			home_issue(c, 1);
		}
		return;
	case HS_NEXT:
		if (!c->home.failed && c->home.todo != 0) {
			home_next_group(c);
			c->home.step = HS_SETUP;
			home_issue(c, 0);
			return;
		}
		c->home.on = 0;
		c->home.group = 0;
		if (!c->home.failed) {
			go(c, out, MLIP_STATE_IDLE, reason(MLIP_WHY_HOMED, 0, 0));
		} else if (c->state == MLIP_STATE_HOMING) {
			go(c, out, MLIP_STATE_IDLE, reason(c->home.stop_why, 0, 0)); /* a stop */
		}
		return;
	default:
		return;
	}
}
