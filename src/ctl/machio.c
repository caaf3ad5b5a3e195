/*
 * machio.c - the machine's outputs and probing in the controller (issue 19;
 * see machio.h). Pure, bounded: a few comparisons an output or an axis.
 */
#include "machio.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "mlip/canopen/drive.h"

/* The drives' touch probe ([PROBE] SOURCE = drive): 0x60B8 off until every
 * drive reports it off (a switch-on is then an edge that clears what an
 * earlier G38 stored), on until every drive reports it on with nothing
 * stored, then the move; a phase not confirmed within TP_CONFIRM_PERIODS: a
 * probe error naming the drive. */
enum { TP_NONE = 0, TP_OFF, TP_ARM, TP_MOVE };
#define TP_CONFIRM_PERIODS 500u

static int tp_drive(const struct mlip_ctl *c)
{
	return c->io.cfg.probe_source == MLIP_PROBE_SRC_DRIVE;
}

static uint16_t tp_stored_bit(const struct mlip_ctl *c)
{
	return (c->mio.probe_flags & MLIP_PROBE_AWAY) ? MLIP_TP_NEG_STORED : MLIP_TP_POS_STORED;
}

/* Drive k's TPDO shows the 0x60B8 of the phase: the RPDO sent in period t0
 * is applied at the SYNC of period t0 + 1, whose TPDO was sampled before. */
static int tp_fresh(const struct mlip_ctl *c, const struct mlip_ctl_in *in, int k)
{
	uint64_t p = in->drives.tpdo_period[k];
	return p != UINT64_MAX && p >= c->mio.tp_t0 + 2u;
}

/* The latches of this period's TPDOs: the first one trips the probe. */
static void tp_latches(struct mlip_ctl *c, const struct mlip_ctl_in *in)
{
	struct mlip_ctl_probe_result *r = &c->mio.result;
	uint16_t stored = tp_stored_bit(c);
	for (int k = 0; k < c->m.n_axes; k++) {
		uint16_t st = in->drives.tp_status[k];
		uint64_t p1 = in->drives.tpdo_period[k], p2 = in->drives.tp_latch_period[k];
		if ((r->latched >> k & 1u) || !tp_fresh(c, in, k) || !(st & MLIP_TP_ENABLE) ||
		    !(st & stored) || p2 == UINT64_MAX || p2 < p1) {
			continue; /* the position latched comes in the TPDO2 of the same SYNC */
		}
		if (!c->mio.probe_tripped) {
			c->mio.probe_tripped = 1;
			memcpy(r->pos, c->pos,
			       sizeof(r->pos));        /* an axis whose latch never comes */
			mlip_planner_stop(c->planner); /* on the path, at the acceleration limit */
		}
		r->pos[k] = (c->mio.probe_flags & MLIP_PROBE_AWAY) ? in->drives.tp_neg[k]
		                                                   : in->drives.tp_pos[k];
		r->latched |= 1u << k;
	}
}

static void set_bit(struct mlip_ctl *c, uint32_t o, int on)
{
	const struct mlip_io_out *x = &c->io.cfg.out[o];
	(void)mlip_ctl_set_output(c, x->sub, x->bit, on);
}

int mlip_mio_coolant_io(const struct mlip_ctl *c)
{
	return (c->io.cfg.out_mapped & (1u << MLIP_OUT_MIST | 1u << MLIP_OUT_FLOOD)) != 0;
}

void mlip_mio_all_off(struct mlip_ctl *c)
{
	memset(c->io.outputs, 0, sizeof(c->io.outputs));
	c->mio.coolant = 0;
	c->mio.probe_on = 0;
	c->mio.tp_phase = TP_NONE;
	c->mio.tp_fn = 0;
	c->mio.n_sync = 0;
}

void mlip_mio_period(struct mlip_ctl *c, const struct mlip_ctl_in *in)
{
	uint32_t bit = 1u << MLIP_IN_PROBE;
	int on;

	c->mio.active = in->io.active & c->io.cfg.mapped;
	c->mio.known = in->io.known & c->io.cfg.mapped;
	c->mio.actual_mask = in->drives.actual_mask;
	memcpy(c->mio.actual, in->drives.pos_actual, sizeof(c->mio.actual));
	if (c->mio.probe_on && c->mio.tp_phase == TP_MOVE) {
		tp_latches(c, in); /* every drive's, after the first too */
		return;
	}
	if (!c->mio.probe_on || c->mio.probe_tripped || tp_drive(c)) {
		return;
	}
	on = (c->mio.active & bit) != 0;
	if (!(c->mio.known & bit) || on == ((c->mio.probe_flags & MLIP_PROBE_AWAY) != 0)) {
		return; /* not yet (an unread input trips nothing: the module lost is an E-stop) */
	}
	/* the position of the period the input's frame arrived in: the drives'
	 * positions actual when each reports one, else the setpoint sent last */
	uint32_t all = (1u << c->m.n_axes) - 1u;
	for (int k = 0; k < c->m.n_axes; k++) {
		c->mio.result.pos[k] =
		    (c->mio.actual_mask & all) == all ? c->mio.actual[k] : c->pos[k];
	}
	c->mio.probe_tripped = 1;
	mlip_planner_stop(c->planner); /* on the path, at the acceleration limit */
}

mlip_status mlip_mio_switch(struct mlip_ctl *c, const struct mlip_ring_rec *rec,
                            struct mlip_ctl_reason *why)
{
	memset(why, 0, sizeof(*why));
	why->why = MLIP_WHY_BAD_RECORD;
	why->field = MLIP_FIELD_DWELL;
	why->seq = rec->seq;
	why->line = rec->line;
	why->value = rec->dwell_s;
	if (rec->type == MLIP_REC_COOLANT) {
		uint32_t want = (uint32_t)rec->dwell_s; /* 0..3: checked with the record */
		if ((want & ~c->io.cfg.out_mapped & 3u) != 0) {
			return MLIP_E_RANGE; /* an outlet that is not there */
		}
		if (c->prog.mdi && want != 0) {
			/* MDI M7/M8: a fresh reader that cannot see an earlier MDI's
			 * outlet, which stays on (LinuxCNC: M7 and M8 both on) */
			want |= c->mio.coolant;
		}
		for (uint32_t o = MLIP_OUT_MIST; o <= MLIP_OUT_FLOOD; o++) {
			if (c->io.cfg.out_mapped >> o & 1u) {
				set_bit(c, o, (want >> o) & 1u);
			}
		}
		c->mio.coolant = want;
		return MLIP_OK;
	}
	/* OUTPUT: +-(n + 1), a whole number checked with the record */
	uint32_t n = (uint32_t)fabs(rec->dwell_s) - 1u, o = MLIP_OUT_DOUT0 + n;
	if (n >= MLIP_DOUT_MAX || !(c->io.cfg.out_mapped >> o & 1u)) {
		return MLIP_E_RANGE;
	}
	set_bit(c, o, rec->dwell_s > 0);
	return MLIP_OK;
}

mlip_status mlip_mio_sync_add(struct mlip_ctl *c, const struct mlip_ring_rec *rec)
{
	if (c->mio.n_sync >= MLIP_SYNC_OUT_MAX) {
		return MLIP_E_FULL;
	}
	c->mio.sync_after[c->mio.n_sync] = rec->seq;
	c->mio.sync_value[c->mio.n_sync] = rec->dwell_s;
	c->mio.n_sync++;
	return MLIP_OK;
}

mlip_status mlip_mio_sync_step(struct mlip_ctl *c, struct mlip_ctl_reason *why)
{
	uint32_t k = 0, left = 0;
	int moving = mlip_planner_queued(c->planner) > 0;
	if (c->mio.n_sync == 0) {
		return MLIP_OK;
	}
	uint64_t seq = moving ? mlip_planner_motion_seq(c->planner) : 0;
	for (; k < c->mio.n_sync; k++) {
		if (moving && seq <= c->mio.sync_after[k]) {
			c->mio.sync_after[left] = c->mio.sync_after[k]; /* its move not yet */
			c->mio.sync_value[left++] = c->mio.sync_value[k];
			continue;
		}
		struct mlip_ring_rec r = {.type = MLIP_REC_OUTPUT, .seq = c->mio.sync_after[k]};
		double v = c->mio.sync_value[k];
		r.dwell_s = v > 0 ? v - MLIP_DOUT_SYNC : v + MLIP_DOUT_SYNC;
		if (mlip_mio_switch(c, &r, why) != MLIP_OK) {
			c->mio.n_sync = 0;
			return MLIP_E_RANGE;
		}
	}
	c->mio.n_sync = left;
	return MLIP_OK;
}

mlip_status mlip_mio_probe_start(struct mlip_ctl *c, const struct mlip_ring_rec *rec,
                                 struct mlip_ctl_reason *why)
{
	uint32_t bit = 1u << MLIP_IN_PROBE, flags = (uint32_t)rec->dwell_s;
	struct mlip_block b;

	memset(why, 0, sizeof(*why));
	why->seq = rec->seq;
	why->line = rec->line;
	if (tp_drive(c) && !(c->io.cfg.mapped & bit)) {
		/* the drives' touch probe alone: no level to check here (0x60B9
		 * has none); an edge stored while it is armed at rest is one */
	} else if (!(c->io.cfg.mapped & bit) || !(c->mio.known & bit)) {
		why->why = MLIP_WHY_PROBE_INPUT;
		return MLIP_E_RANGE;
	} else if (((c->mio.active & bit) != 0) != ((flags & MLIP_PROBE_AWAY) != 0)) {
		/* G38.2/.3 with the probe already on, G38.4/.5 with it off */
		why->why = MLIP_WHY_PROBE_AT_START;
		why->value = (c->mio.active & bit) ? 1.0 : 0.0;
		return MLIP_E_RANGE;
	}
	(void)mlip_ring_rec_to_block(rec, &b);
	b.kind = MLIP_BLOCK_MOVE;
	b.exact_stop = 1;
	c->mio.result.latched = 0;
	if (tp_drive(c)) {
		c->mio.tp_block = b; /* pushed once the drives' latches are armed */
		c->mio.tp_phase = TP_OFF;
		c->mio.tp_fn = 0;
		c->mio.tp_t0 = c->period;
	} else if (mlip_planner_push(c->planner, &b) != MLIP_OK) {
		why->why = MLIP_WHY_BAD_RECORD;
		return MLIP_E_RANGE;
	}
	c->mio.probe_on = 1;
	c->mio.probe_tripped = 0;
	c->mio.probe_flags = flags;
	c->mio.probe.seq = rec->seq;
	c->mio.probe.line = rec->line;
	why->why = MLIP_WHY_PROBE;
	why->value = (double)flags;
	return MLIP_OK;
}

int mlip_mio_probe_arming(struct mlip_ctl *c, const struct mlip_ctl_in *in,
                          struct mlip_ctl_reason *why)
{
	int phase = c->mio.tp_phase;
	uint16_t want = phase == TP_ARM ? MLIP_TP_ENABLE : 0;
	if (phase != TP_OFF && phase != TP_ARM) {
		return 0;
	}
	memset(why, 0, sizeof(*why));
	why->seq = c->mio.probe.seq;
	why->line = c->mio.probe.line;
	for (int k = 0; k < c->m.n_axes; k++) {
		uint16_t st = in->drives.tp_status[k];
		if (phase == TP_ARM && tp_fresh(c, in, k) &&
		    (st & (MLIP_TP_POS_STORED | MLIP_TP_NEG_STORED) & tp_stored_bit(c))) {
			/* an edge while armed at rest: the probe switched already */
			why->why = MLIP_WHY_PROBE_AT_START;
			why->node = (uint32_t)c->m.axis[k].can_node;
			why->value = st;
			return -1;
		}
		if (!tp_fresh(c, in, k) || (st & MLIP_TP_ENABLE) != want) {
			if (c->period - c->mio.tp_t0 > TP_CONFIRM_PERIODS) {
				why->why = MLIP_WHY_PROBE_INPUT;
				why->node = (uint32_t)c->m.axis[k].can_node;
				why->value = st;
				return -1;
			}
			return 1; /* not yet */
		}
	}
	c->mio.tp_t0 = c->period;
	if (phase == TP_OFF) {
		/* the latch on for the edge the move looks for, its first event */
		c->mio.tp_fn = (uint16_t)(MLIP_TP_ENABLE | ((c->mio.probe_flags & MLIP_PROBE_AWAY)
		                                                ? MLIP_TP_NEG_EDGE
		                                                : MLIP_TP_POS_EDGE));
		c->mio.tp_phase = TP_ARM;
		return 1;
	}
	if (mlip_planner_push(c->planner, &c->mio.tp_block) != MLIP_OK) {
		why->why = MLIP_WHY_BAD_RECORD;
		return -1;
	}
	c->mio.tp_phase = TP_MOVE;
	return 1;
}

mlip_status mlip_mio_probe_end(struct mlip_ctl *c, struct mlip_ctl_reason *why)
{
	struct mlip_ctl_probe_result *r = &c->mio.result;

	c->mio.probe_on = 0;
	c->mio.tp_phase = TP_NONE;
	c->mio.tp_fn = 0; /* the latch off: the next G38 switches it on again */
	memset(why, 0, sizeof(*why));
	why->seq = c->mio.probe.seq;
	why->line = c->mio.probe.line;
	r->count++;
	r->seq = c->mio.probe.seq;
	r->line = c->mio.probe.line;
	r->tripped = (uint32_t)c->mio.probe_tripped;
	if (!c->mio.probe_tripped) {
		r->latched = 0;
		memcpy(r->pos, c->pos, sizeof(r->pos)); /* LinuxCNC: the target */
		if (c->mio.probe_flags & MLIP_PROBE_MUST_TRIP) {
			why->why = MLIP_WHY_PROBE_NO_TRIP;
			return MLIP_E_RANGE;
		}
	}
	why->why = MLIP_WHY_PROBED;
	why->value = (double)r->tripped;
	return MLIP_OK;
}

void mlip_mio_publish(const struct mlip_ctl *c, struct mlip_ring_status *s)
{
	uint64_t o = 0;
	for (int k = MLIP_IO_IN_BYTES - 1; k >= 0; k--) {
		o = o << 8 | c->io.outputs[k];
	}
	s->outputs = o;
	s->coolant = c->mio.coolant;
	s->probe_count = c->mio.result.count;
	s->probe_tripped = c->mio.result.tripped;
	s->probe_line = c->mio.result.line;
	memcpy(s->probe_pos, c->mio.result.pos, sizeof(s->probe_pos));
}
