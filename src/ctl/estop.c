/*
 * estop.c - the controller's inputs on the bus (ctl.h, issue 18): E-stop,
 * limits, hold, cycle start; the quick stop, the reset, the outputs.
 */
#include "ctl.h"

#include <math.h>
#include <string.h>

#include "mlip/canopen/drive.h"

mlip_status mlip_ctl_set_output(struct mlip_ctl *c, uint32_t sub, uint32_t bit, int on)
{
	if (sub < 1 || sub > MLIP_IO_IN_BYTES || bit > 7) {
		return MLIP_E_RANGE;
	}
	if (c->io.estop) {
		return MLIP_OK; /* every output stays off until the reset */
	}
	if (on) {
		c->io.outputs[sub - 1] |= (uint8_t)(1u << bit);
	} else {
		c->io.outputs[sub - 1] &= (uint8_t) ~(1u << bit);
	}
	return MLIP_OK;
}

/* The commanded position is where the drives are (they have no holding
 * torque, or stop by themselves), the planner at rest there. */
void mlip_ct_follow_actual(struct mlip_ctl *c, const struct mlip_ctl_in *in)
{
	for (int k = 0; k < c->m.n_axes; k++) {
		if (in->drives.actual_mask & (1u << k)) {
			c->pos[k] = in->drives.pos_actual[k];
		}
	}
	mlip_planner_abort(c->planner, c->pos);
}

/* Rest after a quick stop: a drive moving less than this per period (0.5 %
 * of the axis's MAX_VELOCITY, at least 2 counts of position noise) ... */
#define REST_VEL_FRAC 0.005
#define REST_COUNTS   2.0
/* ... in this many fresh TPDOs in a row of every drive (a TPDO late or
 * lost repeats the last position: it proves nothing) */
#define REST_SAMPLES  3u

/* The first sample of the rest judgement: the positions at the quick stop. */
static void rest_begin(struct mlip_ctl *c, const struct mlip_ctl_in *in)
{
	c->io.rest = 0;
	for (int k = 0; k < c->m.n_axes; k++) {
		c->io.rest_pos[k] = in->drives.pos_actual[k];
		c->io.rest_tpdo[k] = in->drives.tpdo_period[k];
	}
}

/* Each period of an E-stop with drives, before following them: whether they
 * have come to rest on their quick stop ramps (0x6085). Leaving the quick
 * stop (a reset, a jog away from a limit) disables them on the way back to
 * operation (CiA 402 transition 12: quick stop active -> switch on disabled,
 * no torque): taken at speed, the axis would coast. */
void mlip_ct_estop_rest(struct mlip_ctl *c, const struct mlip_ctl_in *in)
{
	int fresh = 1, moved = 0;
	for (int k = 0; k < c->m.n_axes; k++) {
		uint64_t tp = in->drives.tpdo_period[k];
		if (in->drives.mute & (1u << k)) {
			continue; /* faulted: sent nothing, the quick stop's end changes nothing */
		}
		if (!(in->drives.actual_mask & (1u << k)) || tp == UINT64_MAX ||
		    tp == c->io.rest_tpdo[k]) {
			fresh = 0; /* no new TPDO of this drive in this period */
			continue;
		}
		const struct mlip_axis *a = &c->m.axis[k];
		double tol = a->max_vel * REST_VEL_FRAC * c->m.period_s;
		if (a->counts_per_unit > 0.0 && tol < REST_COUNTS / a->counts_per_unit) {
			tol = REST_COUNTS / a->counts_per_unit;
		}
		if (fabs(in->drives.pos_actual[k] - c->io.rest_pos[k]) > tol) {
			moved = 1;
		}
		c->io.rest_pos[k] = in->drives.pos_actual[k];
		c->io.rest_tpdo[k] = tp;
	}
	if (moved) {
		c->io.rest = 0;
	} else if (fresh && c->io.rest < REST_SAMPLES) {
		c->io.rest++;
	}
}

/* The drives (and a spindle on the bus) stand still: the quick stop may be
 * left. Without drives the planner stops on the path by itself. */
int mlip_ct_estop_at_rest(const struct mlip_ctl *c)
{
	return !c->drives || (c->io.rest >= REST_SAMPLES && mlip_ctl_spindle_at_rest(&c->spindle));
}

/* Quick stop (E-stop, limit): with drives, controlword 0x0002 to every drive
 * in this very period (power_period) and the planner dropped at once where
 * they are (each drive brakes on its own quick stop ramp, 0x6085); without
 * drives (nothing to quick stop) the planner stops on the path at the
 * acceleration limit. The program is dropped; every output goes off. */
void mlip_ct_quick_stop(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out,
                        uint32_t state, struct mlip_ctl_reason r)
{
	mlip_ct_progress(c, &r.seq, &r.line);
	if (c->state == MLIP_STATE_FAULT && c->why.why == MLIP_WHY_DRIVE && !c->io.fault_kept) {
		c->io.fault_kept = 1; /* a drive fault comes back after the reset */
		c->io.kept = c->why;
	}
	c->io.estop = 1;
	rest_begin(c, in);
	c->jog.on = 0;
	mlip_ct_home_abort(c);
	if (c->drives) {
		mlip_ct_follow_actual(c, in);
	} else if (mlip_planner_queued(c->planner) > 0) {
		mlip_ct_planner_stop(c);
	} else {
		mlip_ct_hold_clear(c); /* a hold latched at rest ends, as with drives */
	}
	c->wait.dwell_left = 0;
	c->wait.stopped = 0;
	c->hold.op = 0;
	c->hold.stall = 0;
	c->brake.on = 0;
	c->prog.end.seq = 0;
	c->prog.bad = 1;     /* nothing more is taken until the reset */
	c->prog.discard = 1; /* the rest of the program is dropped */
	memset(c->io.outputs, 0, sizeof(c->io.outputs));
	go(c, out, state, r);
}

/* mlip-ctl reset: leave an E-stop or a limit fault once the inputs that
 * caused it are released (and the I/O module is back): IDLE, or the drive
 * fault that came before. The drives' power sequence starts again from the
 * states they are in (toward OFF; a program enables them). */
int32_t mlip_ct_reset(struct mlip_ctl *c, struct mlip_ctl_out *out, const struct mlip_ctl_in *in)
{
	uint32_t limits = 0;
	for (int k = 0; k < c->m.n_axes; k++) {
		limits |= (1u << MLIP_IN_LIMIT_NEG(k)) | (1u << MLIP_IN_LIMIT_POS(k));
	}
	if (!c->io.estop || c->home.on) {
		return MLIP_E_INVALID; /* nothing to reset (or homing still restores CSP) */
	}
	if ((in->io.active & (1u << MLIP_IN_ESTOP)) || in->io.lost.event != 0 ||
	    ((c->io.cfg.mapped & (1u << MLIP_IN_ESTOP)) &&
	     !(in->io.known & (1u << MLIP_IN_ESTOP)))) {
		return MLIP_E_RANGE; /* the E-stop is still on (or cannot be read) */
	}
	if (c->why.why == MLIP_WHY_LIMIT && (in->io.active & limits)) {
		return MLIP_E_RANGE; /* still on the limit switch */
	}
	if (!mlip_ct_estop_at_rest(c)) {
		return MLIP_E_FULL; /* still braking on the drives' ramps */
	}
	c->io.estop = 0;
	c->io.prev = in->io.active; /* a hold still pressed is not a new edge */
	if (c->drives) {
		mlip_402_seq_init(&c->power.seq, MLIP_POWER_NONE,
		                  c->power.seq.timeout ? c->power.seq.timeout : 1000, c->period);
	}
	c->prog.bad = 0;
	c->prog.discard = rx_count(c) > 0;
	c->prog.discard_waiting = c->prog.discard;
	if (c->io.fault_kept) {
		c->prog.bad = 1;
		go(c, out, MLIP_STATE_FAULT, c->io.kept);
		return MLIP_OK;
	}
	go(c, out, MLIP_STATE_IDLE, reason(MLIP_WHY_RESET, 0, 0));
	return MLIP_OK;
}

/* The inputs of this period, before any command: E-stop wins over every
 * state; a limit while moving stops everything; hold and cycle start act on
 * their rising edge, as the commands would. */
void mlip_ct_io_period(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out)
{
	uint32_t on = in->io.active & c->io.cfg.mapped, rise = on & ~c->io.prev;
	struct mlip_ctl_reason r = reason(MLIP_WHY_NONE, 0, 0);

	c->io.prev = on;
	if (in->io.lost.event != 0 && c->state != MLIP_STATE_ESTOP) {
		r.why = MLIP_WHY_IO_LOST;
		r.field = in->io.lost.event;
		r.node = in->io.lost.node;
		r.value = in->io.lost.value;
		mlip_ct_quick_stop(c, in, out, MLIP_STATE_ESTOP, r);
		return;
	}
	if (in->io.lost.event == MLIP_DRIVE_WRONG_DEVICE && c->state == MLIP_STATE_ESTOP &&
	    !(c->why.why == MLIP_WHY_IO_LOST && c->why.field == MLIP_DRIVE_WRONG_DEVICE)) {
		/* the module came back as another device: the E-stop that its
		 * loss (or the button) began now says so (an event: the logs) */
		r.why = MLIP_WHY_IO_LOST;
		r.field = MLIP_DRIVE_WRONG_DEVICE;
		r.node = in->io.lost.node;
		r.value = in->io.lost.value;
		c->why = r;
		emit(c, out, MLIP_EV_STATE, c->state, &r);
		return;
	}
	if ((on & (1u << MLIP_IN_ESTOP)) && c->state != MLIP_STATE_ESTOP) {
		r.why = MLIP_WHY_ESTOP;
		r.field = MLIP_IN_ESTOP;
		r.node = c->io.cfg.in[MLIP_IN_ESTOP].node;
		r.value = (double)c->io.cfg.in[MLIP_IN_ESTOP].index;
		mlip_ct_quick_stop(c, in, out, MLIP_STATE_ESTOP, r);
		return;
	}
	if (c->io.estop) {
		return;
	}
	c->io.limit_ignore &= on; /* a released limit trips again */
	for (int k = 0; k < c->m.n_axes; k++) {
		uint32_t f = MLIP_IN_LIMIT_NEG(k);
		uint32_t hit = on & ((1u << f) | (1u << (f + 1))) & ~c->io.limit_ignore;
		if (hit &&
		    (mlip_planner_moving(c->planner) || mlip_planner_queued(c->planner) > 0)) {
			r.why = MLIP_WHY_LIMIT;
			r.field = (hit & (1u << f)) ? f : f + 1;
			r.node = c->io.cfg.in[r.field].node;
			r.value = c->pos[k];
			mlip_ct_quick_stop(c, in, out, MLIP_STATE_FAULT, r);
			return;
		}
	}
	if (rise & (1u << MLIP_IN_HOLD)) {
		struct mlip_ring_cmd h = {0};
		h.op = MLIP_CMD_HOLD;
		mlip_ct_apply_command(c, out, in, &h);
	}
	if (rise & (1u << MLIP_IN_CYCLE_START)) {
		struct mlip_ring_cmd h = {0};
		h.op = MLIP_CMD_RESUME;
		mlip_ct_apply_command(c, out, in, &h);
	}
}
