/* grblmach.c - see grblmach.h */
#include "grblmach.h"

#include <math.h>
#include <stdio.h>
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

int grbl_home_negative(int m)
{
	/* CiA 402 (IEC 61800-7-201) 6.4: 1-14 with the index pulse, 17-30 the
	 * same without; 33/34 the index pulse alone */
	int b = m >= 17 && m <= 30 ? m - 16 : m;
	if (b == 1 || b == 5 || b == 6 || (b >= 11 && b <= 14) || m == 33) {
		return 1;
	}
	if (b == 2 || b == 3 || b == 4 || (b >= 7 && b <= 10) || m == 34) {
		return 0;
	}
	return -1;
}

int grbl_machine_differs(const struct mlip_machine *a, const struct mlip_machine *b, char *why,
                         size_t n)
{
	if (a->n_axes != b->n_axes) {
		snprintf(why, n, "%d axes, mlip-rt's %d", a->n_axes, b->n_axes);
		return 1;
	}
	if (a->period_s != b->period_s || a->tolerance_mm != b->tolerance_mm) {
		snprintf(why, n, "PERIOD %g, CONTOUR_TOLERANCE %g; mlip-rt's %g, %g", a->period_s,
		         a->tolerance_mm, b->period_s, b->tolerance_mm);
		return 1;
	}
	for (int k = 0; k < a->n_axes && k < MLIP_MAX_AXES; k++) {
		const struct mlip_axis *x = &a->axis[k], *y = &b->axis[k];
		if (x->letter != y->letter || x->min_limit != y->min_limit ||
		    x->max_limit != y->max_limit || x->max_vel != y->max_vel ||
		    x->max_accel != y->max_accel || x->counts_per_unit != y->counts_per_unit) {
			snprintf(why, n,
			         "axis %d: %c, limits %g..%g, %g/s, %g/s^2; mlip-rt's %c, %g..%g, "
			         "%g/s, %g/s^2",
			         k, x->letter, x->min_limit, x->max_limit, x->max_vel, x->max_accel,
			         y->letter, y->min_limit, y->max_limit, y->max_vel, y->max_accel);
			return 1;
		}
	}
	return 0;
}

void grbl_homing_of(const struct mlip_config *c, struct grbl_homing *h)
{
	static const char letters[] = "XYZABC";
	const struct mlip_machine *m = &c->machine;
	h->enabled = 0;
	h->dir_mask = 0;
	h->feed_mm_min = h->seek_mm_min = 0.0;
	for (int a = 0; a < m->n_axes && a < MLIP_MAX_AXES; a++) {
		const struct mlip_axis_home *x = &c->home.axis[a];
		if (!x->configured) {
			continue;
		}
		const char *l = strchr(letters, m->axis[a].letter);
		if (l != NULL && grbl_home_negative(x->method) == 1) {
			h->dir_mask |= 1 << (l - letters);
		}
		/* Grbl has one speed for all axes: the slowest one says how long
		 * homing takes at least */
		if (!h->enabled || x->latch_vel * 60.0 < h->feed_mm_min) {
			h->feed_mm_min = x->latch_vel * 60.0;
		}
		if (!h->enabled || x->search_vel * 60.0 < h->seek_mm_min) {
			h->seek_mm_min = x->search_vel * 60.0;
		}
		h->enabled = 1;
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
