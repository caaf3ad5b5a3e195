/*
 * spindle.c - a spindle drive in profile velocity mode: the phases of
 * mlip/canopen/spindle.h, one period at a time.
 */
#include "mlip/canopen/spindle.h"

#include <math.h>
#include <string.h>

#include "mlip/canopen/cia402.h"

mlip_status mlip_spindle_init(struct mlip_spindle *s, const struct mlip_spindle_cfg *cfg)
{
	if (s == NULL || cfg == NULL || !(cfg->counts_per_rev > 0 && cfg->counts_per_rev <= 1e9) ||
	    !(cfg->band_rpm >= 0 && cfg->band_rpm <= 1e6) || cfg->timeout_periods == 0) {
		return MLIP_E_INVALID;
	}
	memset(s, 0, sizeof(*s));
	s->cfg = *cfg;
	s->phase = MLIP_SPINDLE_STOPPED;
	return MLIP_OK;
}

double mlip_spindle_counts(const struct mlip_spindle_cfg *cfg, double rpm)
{
	return rpm * cfg->counts_per_rev / 60.0;
}

double mlip_spindle_rpm(const struct mlip_spindle_cfg *cfg, double counts_s)
{
	return counts_s * 60.0 / cfg->counts_per_rev;
}

void mlip_spindle_command(struct mlip_spindle *s, double rpm, uint64_t period)
{
	if (s->phase == MLIP_SPINDLE_FAULT || !isfinite(rpm) || rpm == s->cmd_rpm) {
		return;
	}
	s->cmd_rpm = rpm;
	s->since = period;
	s->out = 0;
	/* a reversal (or a start while still turning the other way): to rest
	 * first, as the issue asks (a drive may reverse through 0 itself, but
	 * the feed must see the spindle stop) */
	if (rpm != 0 && s->actual_rpm * rpm < 0 && fabs(s->actual_rpm) > s->cfg.band_rpm) {
		s->target_rpm = 0;
		s->phase = MLIP_SPINDLE_BRAKING;
	} else {
		s->target_rpm = rpm;
		s->phase = MLIP_SPINDLE_RAMPING;
	}
}

static int fail(struct mlip_spindle *s, uint32_t why, double value, int32_t *target)
{
	s->phase = MLIP_SPINDLE_FAULT;
	s->fault = why;
	s->fault_value = value;
	s->target_rpm = 0;
	*target = 0;
	return -1;
}

int mlip_spindle_step(struct mlip_spindle *s, uint16_t statusword, int32_t vel_actual,
                      uint64_t period, int32_t *target)
{
	const struct mlip_spindle_cfg *c = &s->cfg;
	int standstill, at_speed;
	double v;

	s->actual_rpm = mlip_spindle_rpm(c, (double)vel_actual); /* faulted too: shown */
	if (s->phase == MLIP_SPINDLE_FAULT) {
		*target = 0;
		return -1;
	}
	if (statusword & MLIP_402_SW_FAULT) {
		return fail(s, MLIP_SPINDLE_DRIVE_FAULT, (double)statusword, target);
	}
	standstill = fabs(s->actual_rpm) <= c->band_rpm;
	at_speed = (statusword & MLIP_SPINDLE_SW_TARGET_REACHED) &&
	           fabs(s->actual_rpm - s->target_rpm) <= c->band_rpm;
	switch (s->phase) {
	case MLIP_SPINDLE_BRAKING:
		if (standstill) {
			s->target_rpm = s->cmd_rpm; /* the new way */
			s->phase = MLIP_SPINDLE_RAMPING;
		}
		break;
	case MLIP_SPINDLE_RAMPING:
		if (s->cmd_rpm == 0 ? standstill : at_speed) {
			s->phase = s->cmd_rpm == 0 ? MLIP_SPINDLE_STOPPED : MLIP_SPINDLE_AT_SPEED;
		}
		break;
	case MLIP_SPINDLE_AT_SPEED:
		/* the band, not bit 10: a drive may drop target reached on a load
		 * step it recovers from within band_periods */
		if (fabs(s->actual_rpm - s->target_rpm) > c->band_rpm) {
			if (++s->out > c->band_periods) {
				return fail(s, MLIP_SPINDLE_OUT_OF_BAND, s->actual_rpm, target);
			}
		} else {
			s->out = 0;
		}
		break;
	default: /* STOPPED */
		break;
	}
	if ((s->phase == MLIP_SPINDLE_RAMPING || s->phase == MLIP_SPINDLE_BRAKING) &&
	    period - s->since > c->timeout_periods) {
		return fail(s, MLIP_SPINDLE_TIMEOUT, s->actual_rpm, target);
	}
	v = floor(mlip_spindle_counts(c, s->target_rpm) + 0.5);
	*target = v > 2147483647.0 ? 2147483647 : v < -2147483647.0 ? -2147483647 : (int32_t)v;
	return s->phase == MLIP_SPINDLE_AT_SPEED || s->phase == MLIP_SPINDLE_STOPPED;
}

const char *mlip_spindle_fault_name(uint32_t fault)
{
	static const char *const names[] = {"none", "timeout", "drive fault", "out of band"};

	return fault < sizeof(names) / sizeof(names[0]) ? names[fault] : "?";
}
