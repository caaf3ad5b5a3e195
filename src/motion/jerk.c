/*
 * jerk.c - the moving average's parameters for a jerk limit (see
 * mlip/motion/jerk.h: equations J1-J5).
 */
#include "mlip/motion/jerk.h"

#include <math.h>

double mlip_jerk_filter_mm(int n, const double *accel, int taps, double period_s)
{
	double a2 = 0.0;
	for (int k = 0; k < n; k++) {
		a2 += accel[k] * accel[k];
	}
	double m = (double)taps;
	return sqrt(a2) * period_s * period_s * (m * m - 1.0) / 24.0; /* (J5) */
}

/* A'_k (J4) for m taps; an axis without a limit keeps A_k. */
static void accel_for(const struct mlip_machine *mc, int taps, double *a)
{
	for (int k = 0; k < mc->n_axes; k++) {
		const struct mlip_axis *ax = &mc->axis[k];
		a[k] = ax->max_accel;
		if (ax->max_jerk > 0.0) {
			/* a hair below: rounding of the positions (~1e-8 of J at 100 mm)
			 * must not show as an excess in third differences */
			double lim =
			    0.5 * ax->max_jerk * (double)taps * mc->period_s * (1.0 - 1e-6);
			a[k] = lim < a[k] ? lim : a[k];
		}
	}
}

int mlip_jerk_plan(const struct mlip_machine *mc, struct mlip_jerk_plan *out)
{
	int n = mc->n_axes, limited = 0;
	for (int k = 0; k < n; k++) {
		limited |= mc->axis[k].max_jerk > 0.0;
	}
	out->taps = 1;
	out->filter_mm = 0.0;
	accel_for(mc, 1, out->accel);
	if (!limited) {
		for (int k = 0; k < n; k++) {
			out->accel[k] = mc->axis[k].max_accel;
		}
		return 0;
	}
	/* the longest window (the most acceleration, J4) whose E_f takes at
	 * most half of eps (J5): half for the mean, half for the corners; none
	 * longer than it takes every axis to A */
	double eps = mc->tolerance_mm;
	for (int m = 1; m <= MLIP_JERK_MAX_TAPS - 1; m += 2) { /* odd: the centre is a sample */
		double a[MLIP_MAX_AXES];
		accel_for(mc, m, a);
		double ef = mlip_jerk_filter_mm(n, a, m, mc->period_s);
		if (!(ef <= 0.5 * eps)) {
			break; /* E_f only grows with m */
		}
		int gain = m == 1;
		for (int k = 0; k < n; k++) {
			gain |= a[k] > out->accel[k];
		}
		if (!gain) {
			break; /* every axis at A already: a longer mean buys nothing */
		}
		out->taps = m;
		out->filter_mm = ef;
		for (int k = 0; k < n; k++) {
			out->accel[k] = a[k];
		}
	}
	return 1;
}
