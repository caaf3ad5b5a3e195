/*
 * spindlectl.c - the controller's CiA 402 spindle (mlip/ctl/spindlectl.h): the
 * program's speed and the operator's override into the profile velocity
 * phases of mlip/canopen/spindle.h, one period at a time.
 */
#include "mlip/ctl/spindlectl.h"

#include <math.h>
#include <string.h>

#include "mlip/canopen/drive.h"

#include "ctl.h"

mlip_status mlip_ctl_spindle_init(struct mlip_ctl_spindle *s, const struct mlip_spindle_config *cfg,
                                  double period_s)
{
	struct mlip_spindle_cfg dc;

	memset(s, 0, sizeof(*s));
	s->override_pct = 100;
	s->stop_req = -1;
	if (cfg == NULL || cfg->node == 0) {
		return MLIP_OK;
	}
	if (!(period_s > 0) || !(cfg->timeout_s > 0 && cfg->timeout_s <= 3600.0) ||
	    !(cfg->band_time_s >= 0 && cfg->band_time_s <= 60.0) ||
	    !(cfg->max_rpm > 0 && cfg->min_rpm >= 0 && cfg->min_rpm <= cfg->max_rpm)) {
		return MLIP_E_INVALID;
	}
	dc.counts_per_rev = cfg->counts_per_rev;
	dc.band_rpm = cfg->band_rpm;
	dc.timeout_periods = (uint32_t)ceil(cfg->timeout_s / period_s - 1e-9);
	dc.band_periods = (uint32_t)floor(cfg->band_time_s / period_s + 1e-9);
	if (mlip_spindle_init(&s->drive, &dc) != MLIP_OK) {
		return MLIP_E_INVALID;
	}
	s->on = 1;
	s->node = cfg->node;
	s->min_rpm = cfg->min_rpm;
	s->max_rpm = cfg->max_rpm;
	s->ready = 1; /* stopped, asked 0 */
	return MLIP_OK;
}

/* The program's speed with the override, within what the spindle can do. */
static void apply(struct mlip_ctl_spindle *s, uint64_t period)
{
	double rpm = s->stopped ? 0.0 : s->program_rpm, mag = fabs(rpm) * s->override_pct / 100.0;
	if (rpm != 0) {
		mag = mag > s->max_rpm ? s->max_rpm : mag < s->min_rpm ? s->min_rpm : mag;
		rpm = rpm > 0 ? mag : -mag;
	}
	if (rpm != s->drive.cmd_rpm) {
		s->asked = period;
	}
	mlip_spindle_command(&s->drive, rpm, period);
	if (s->drive.phase != MLIP_SPINDLE_FAULT) {
		/* sent from this period on (a stop's 0 at once, not a period late) */
		double v = floor(mlip_spindle_counts(&s->drive.cfg, s->drive.target_rpm) + 0.5);
		s->target = (int32_t)v; /* within INTEGER32: MAX_RPM was checked */
	}
}

void mlip_ctl_spindle_ask(struct mlip_ctl_spindle *s, double rpm, uint64_t period)
{
	if (!s->on) {
		return;
	}
	s->program_rpm = rpm;
	s->stopped = 0; /* a program's word: its hold has ended */
	s->stop_req = -1;
	apply(s, period);
}

void mlip_ctl_spindle_stop(struct mlip_ctl_spindle *s, int on, uint64_t period)
{
	if (!s->on) {
		return;
	}
	s->stopped = on != 0;
	apply(s, period);
}

mlip_status mlip_ctl_spindle_override(struct mlip_ctl_spindle *s, int32_t pct, uint64_t period)
{
	if (!s->on) {
		return MLIP_E_INVALID;
	}
	if (pct < MLIP_SPINDLE_OVERRIDE_MIN || pct > MLIP_SPINDLE_OVERRIDE_MAX) {
		return MLIP_E_RANGE;
	}
	s->override_pct = (uint32_t)pct;
	apply(s, period);
	return MLIP_OK;
}

int mlip_ctl_spindle_step(struct mlip_ctl_spindle *s, uint16_t sw, int32_t vel_actual,
                          uint64_t period, uint32_t *event, double *value)
{
	int was = s->ready, rc;

	if (!s->on) {
		return 1;
	}
	rc = mlip_spindle_step(&s->drive, sw, vel_actual, period, &s->target);
	s->ready = rc;
	if (rc == 1 && was == 0) {
		s->ready_after = period - s->asked;
	}
	if (rc >= 0) {
		return rc;
	}
	if (s->reported) {
		return -2;
	}
	s->reported = 1;
	*event = s->drive.fault == MLIP_SPINDLE_TIMEOUT       ? MLIP_DRIVE_SPINDLE_TIMEOUT
	         : s->drive.fault == MLIP_SPINDLE_OUT_OF_BAND ? MLIP_DRIVE_SPINDLE_OUT_OF_BAND
	                                                      : MLIP_DRIVE_FAULT_BIT;
	*value = s->drive.fault_value;
	return -1;
}

int mlip_ctl_spindle_at_rest(const struct mlip_ctl_spindle *s)
{
	/* faulted (its own fault reaction, or not heard within the timeout):
	 * nothing to wait for */
	return !s->on || s->drive.phase == MLIP_SPINDLE_FAULT ||
	       (s->drive.cmd_rpm == 0 && fabs(s->drive.actual_rpm) <= s->drive.cfg.band_rpm);
}

double mlip_ctl_spindle_cmd_rpm(const struct mlip_ctl_spindle *s)
{
	return s->on && s->drive.phase != MLIP_SPINDLE_FAULT ? s->drive.cmd_rpm : 0.0;
}

/* ---- in the controller's period (ctl.h) ----------------------------------- */

/* An operator's hold at rest (held mid-program; starved, a sender's open
 * program waiting for its next line, as an M3 typed in mlip-grbl's console
 * leaves it; or asked while idle as Grbl holds): where Grbl's spindle stop
 * acts. */
int mlip_ct_spindle_held(const struct mlip_ctl *c)
{
	return c->hold.op && (c->state == MLIP_STATE_HELD || c->state == MLIP_STATE_STARVED ||
	                      c->state == MLIP_STATE_IDLE);
}

/* Its phase from its TPDO; a fault stops the feed on the path (state FAULT,
 * the spindle named); a wait for it ends when it is at speed (or at rest). */
void mlip_ct_spindle_period(struct mlip_ctl *c, const struct mlip_ctl_in *in,
                            struct mlip_ctl_out *out)
{
	struct mlip_ctl_drive_fault f = {0, c->spindle.node, 0.0};
	int rc;

	if (!c->spindle.on) {
		return;
	}
	rc = mlip_ctl_spindle_step(&c->spindle, in->spindle.sw, in->spindle.vel_counts, c->period,
	                           &f.event, &f.value);
	if (c->spindle.stop_req >= 0 && mlip_ct_spindle_held(c)) {
		/* Grbl's spindle stop: once the hold is at rest */
		mlip_ctl_spindle_stop(&c->spindle, c->spindle.stop_req, c->period);
		c->spindle.stop_req = -1;
	}
	if (rc == -1 && !c->drive_faulted) {
		mlip_ct_drive_fault(c, out, &f);
	} else if (rc == 1 && c->hold.spindle) {
		/* resumed with the spindle restored: on once it is at speed */
		c->hold.spindle = 0;
		if (!c->hold.op && !c->hold.stall && !c->hold.bus) {
			mlip_planner_hold(c->planner, 0);
		}
	} else if (rc == 1 && c->state == MLIP_STATE_DWELLING &&
	           c->why.why == MLIP_WHY_SPINDLE_WAIT) {
		c->wait.dwell_left = 0; /* at speed: the wait ends in the records' part */
	}
}

/* Its RPDO (the group's controlword, quick stop in an E-stop; its target),
 * sent by rt/ after the axes' frames, and the status. */
void mlip_ct_spindle_out(const struct mlip_ctl *c, const struct mlip_ctl_in *in,
                         struct mlip_ctl_out *out)
{
	const struct mlip_ctl_spindle *sp = &c->spindle;
	struct mlip_ring_status *s = &out->status;
	s->spindle_override = sp->override_pct;
	if (!sp->on) {
		return;
	}
	out->spindle.send = !in->spindle.mute && c->power.seq.cw >= 0;
	out->spindle.cw =
	    c->io.estop ? (uint16_t)MLIP_402_CW_QUICK_STOP : (uint16_t)c->power.seq.cw;
	out->spindle.target = c->io.estop ? 0 : sp->target;
	out->spindle.rpm_actual = sp->drive.actual_rpm;
	s->spindle_state = sp->drive.phase + 1u;
	s->spindle_cmd_rpm = mlip_ctl_spindle_cmd_rpm(sp);
	s->spindle_actual_rpm = sp->drive.actual_rpm;
	s->spindle_node = sp->node;
}
