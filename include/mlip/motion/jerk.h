/*
 * mlip/motion/jerk.h - the per-axis jerk limit (MAX_JERK) as the planner
 * honours it: an acceleration-limited plan whose accelerations change slowly
 * enough, followed by a moving average of the last m setpoints.
 *
 * The average. The planner's motion p(t) (mlip/motion/planner.h: C1, its
 * acceleration piecewise constant, |p''_k| <= A_k at every instant) is
 * sampled every T; the setpoint sent is the mean of the last m samples:
 *
 *     y_n = (1/m) sum_{i=0}^{m-1} x_{n-i},  x_j = p(j T)                 (J1)
 *
 * Its differences are means of the plan's:
 *
 *     y_n - y_{n-1}     = (x_n - x_{n-m}) / m                             (J2)
 *     Delta^2 y_n       = (Delta x_n - Delta x_{n-m}) / m     -> |.| / T^2 <= A_k
 *     Delta^3 y_n       = (Delta^2 x_n - Delta^2 x_{n-m}) / m             (J3)
 *
 * so velocity and acceleration keep the plan's limits at every sample, and
 * since every second difference of the plan is within A'_k T^2 (a weighted
 * mean of p''), |Delta^3 y_n| / T^3 <= 2 A'_k / (m T): the jerk limit J_k
 * holds at every sample when the plan's accelerations are within
 *
 *     A'_k = min(A_k, J_k m T / 2)                                        (J4)
 *
 * (less 1e-6 of it: rounding of the positions must not show as an excess).
 *
 * The contour. With u_i = (i - (m-1)/2) T the offsets around the window's
 * centre t_c, sum u_i = 0 and Taylor's formula with integral remainder give
 *
 *     y_n - p(t_c) = (1/m) sum_i int_0^{u_i} (u_i - s) p''(t_c + s) ds,
 *     |y_n - p(t_c)| <= |p''|max (1/m) sum_i u_i^2 / 2
 *                    = |p''|max T^2 (m^2 - 1) / 24 = E_f                  (J5)
 *
 * (|p''| the Euclidean norm, at most sqrt(sum_k A'_k^2)). The plan is
 * within its corners' budgets of the polyline, so the setpoints are within
 * tol - E_f + E_f: the planner and the smoothing filter give every corner
 * its budget less E_f. On a straight line the mean of collinear points is
 * on the line (E_f bounds only the distance along it), so E_f is spent near
 * corners only. A corner whose budget is not above E_f (a G64 P smaller, or
 * G61's exact stop) is passed at rest, resting m - 1 periods: every sample
 * of the window is then the corner point, so the setpoint is exactly there.
 *
 * m is odd, so the window's centre is a sample: after a stall the plan goes
 * on from where it was then (mlip_planner_rest_here), a straight line from
 * the last setpoint, within E_f of it, away.
 *
 * What it costs: the plan's accelerations (J4) and the budget E_f, both
 * growing with m in opposite ways; mlip_jerk_plan takes the longest window
 * whose E_f is at most half of eps (on smooth curves the acceleration
 * counts, at sharp corners the budget: MB-2.3 at J = 1e5 took 29 s with
 * 11 taps, 211 s with 15, where E_f is 99 % of eps). Time: the mean lags
 * the plan by (m - 1) T / 2 and ends (m - 1) periods after it, once per
 * program.
 * Every part of the motion goes through (J1): lines, corners, the
 * look-ahead's stops, override changes, hold and resume, a stop, the start
 * and the end; the look-ahead is the acceleration-limited one, exact as it
 * is, at A' and the reduced budgets.
 */
#ifndef MLIP_JERK_H
#define MLIP_JERK_H

#include "mlip/types.h"

#define MLIP_JERK_MAX_TAPS 64 /* the window's storage (m <= 63, odd: its centre a sample) */

struct mlip_jerk_plan {
	int taps;                    /* m: setpoints averaged (1: no jerk limit) */
	double accel[MLIP_MAX_AXES]; /* A'_k (J4), before the planner's margin */
	double filter_mm;            /* E_f (J5): what the mean takes of a corner's budget */
};

/* The plan for machine m: taps 1, accel = max_accel, filter 0 when no axis
 * has a jerk limit (max_jerk <= 0 on every axis), so that the planner and
 * the smoothing filter do exactly what they do without one. Returns 1 when
 * a jerk limit applies. */
int mlip_jerk_plan(const struct mlip_machine *m, struct mlip_jerk_plan *out);

/* E_f (J5) for m taps and per-axis accelerations accel[n], period T. */
double mlip_jerk_filter_mm(int n, const double *accel, int taps, double period_s);

#endif
