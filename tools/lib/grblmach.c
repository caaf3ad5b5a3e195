/* grblmach.c - see grblmach.h */
#include "grblmach.h"

#include <math.h>
#include <string.h>

#include "grbl.h"
#include "mlip/canopen/spindle.h"
#include "mlip/ctl/spindlectl.h"
#include "mlip/ctl/state.h"
#include "mlip/machine/config.h"

static void put(char *out, size_t n, size_t *k, char c)
{
	if (*k + 1 < n) {
		out[(*k)++] = c;
		out[*k] = '\0';
	}
}

void grbl_pins(char *out, size_t n, uint32_t inputs, const struct mlip_machine *m)
{
	size_t k = 0;
	if (n == 0) {
		return;
	}
	out[0] = '\0';
	if (inputs & (1u << MLIP_IN_PROBE)) {
		put(out, n, &k, 'P');
	}
	for (int a = 0; a < m->n_axes && a < MLIP_MAX_AXES; a++) {
		uint32_t bits = (1u << MLIP_IN_LIMIT_NEG(a)) | (1u << MLIP_IN_LIMIT_POS(a)) |
		                (1u << MLIP_IN_HOME_SW(a));
		if (inputs & bits) {
			put(out, n, &k, m->axis[a].letter);
		}
	}
	if (inputs & (1u << MLIP_IN_ESTOP)) {
		put(out, n, &k, 'R');
	}
	if (inputs & (1u << MLIP_IN_HOLD)) {
		put(out, n, &k, 'H');
	}
	if (inputs & (1u << MLIP_IN_CYCLE_START)) {
		put(out, n, &k, 'S');
	}
}

void grbl_accessories(char *out, size_t n, double rpm, uint32_t coolant)
{
	size_t k = 0;
	if (n == 0) {
		return;
	}
	out[0] = '\0';
	if (rpm > 0.0) {
		put(out, n, &k, 'S');
	} else if (rpm < 0.0) {
		put(out, n, &k, 'C');
	}
	if (coolant & MLIP_COOLANT_FLOOD) {
		put(out, n, &k, 'F');
	}
	if (coolant & MLIP_COOLANT_MIST) {
		put(out, n, &k, 'M');
	}
}

static int homing_reason(uint32_t reason)
{
	return reason == MLIP_WHY_HOMING_ERROR || reason == MLIP_WHY_HOMING_TIMEOUT ||
	       reason == MLIP_WHY_HOMING_SDO;
}

int grbl_alarm_of(uint32_t state, uint32_t reason, uint32_t was)
{
	if (state == MLIP_STATE_ESTOP) {
		return was == MLIP_STATE_HOMING ? GRBL_ALARM_HOMING_RESET : GRBL_ALARM_ABORT;
	}
	if (state != MLIP_STATE_FAULT) {
		return 0;
	}
	if (reason == MLIP_WHY_LIMIT) {
		return GRBL_ALARM_HARD_LIMIT;
	}
	if (homing_reason(reason)) {
		return GRBL_ALARM_HOMING_FAIL;
	}
	return GRBL_ALARM_ABORT;
}

int grbl_resettable(uint32_t state, uint32_t reason)
{
	return state == MLIP_STATE_ESTOP ||
	       (state == MLIP_STATE_FAULT && (reason == MLIP_WHY_LIMIT || homing_reason(reason)));
}

static void apply(struct grbl_acc *a)
{
	if (a->pending == MLIP_WHY_SPINDLE) {
		a->rpm = a->value;
	} else if (a->pending == MLIP_WHY_COOLANT) {
		a->coolant = (uint32_t)a->value;
	}
	a->pending = 0;
	a->changes++;
}

void grbl_acc_update(struct grbl_acc *a, uint32_t state, uint32_t reason, uint64_t seq,
                     double value)
{
	int io_pause = state == MLIP_STATE_PAUSED &&
	               (reason == MLIP_WHY_SPINDLE || reason == MLIP_WHY_COOLANT);
	if (a->pending) {
		if (io_pause && seq == a->seq) {
			return; /* still waiting for the operator */
		}
		/* left: a pause is left by a resume (then whatever follows:
		 * running, the next event's pause, the program's end) or by a
		 * stop, an E-stop or a fault (the event not done) */
		int stopped = state == MLIP_STATE_STOPPING || state == MLIP_STATE_ESTOP ||
		              state == MLIP_STATE_FAULT || reason == MLIP_WHY_STOP ||
		              reason == MLIP_WHY_EXIT || reason == MLIP_WHY_STOP_EARLY;
		if (stopped) {
			a->pending = 0;
		} else {
			apply(a);
		}
	}
	if (io_pause) {
		a->pending = (int)reason;
		a->seq = seq;
		a->value = value;
	}
}

int grbl_spindle_of(uint32_t spindle_state, double cmd_rpm, uint32_t override_pct, double max_rpm,
                    double *rpm, int *ov)
{
	/* max_rpm is the machine's (mlip_ring_io, checked by the caller); the
	 * commanded speed never exceeds it: the controller clamps the override */
	if (spindle_state < 1 || spindle_state > MLIP_SPINDLE_FAULT + 1u || !isfinite(cmd_rpm) ||
	    fabs(cmd_rpm) > max_rpm * (1.0 + 1e-9) || override_pct < MLIP_SPINDLE_OVERRIDE_MIN ||
	    override_pct > MLIP_SPINDLE_OVERRIDE_MAX) {
		return -1;
	}
	*rpm = cmd_rpm;
	*ov = (int)override_pct;
	return 0;
}

int grbl_spindle_ov_step(int rt, int pct)
{
	if (rt < GRBL_RT_SPINDLE_100 || rt > GRBL_RT_SPINDLE_MINUS_1) {
		return pct;
	}
	int v = grbl_override_step((grbl_rt)rt, pct);
	return v < MLIP_SPINDLE_OVERRIDE_MIN   ? MLIP_SPINDLE_OVERRIDE_MIN
	       : v > MLIP_SPINDLE_OVERRIDE_MAX ? MLIP_SPINDLE_OVERRIDE_MAX
	                                       : v;
}
