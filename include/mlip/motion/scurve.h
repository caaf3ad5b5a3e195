/*
 * mlip/motion/scurve.h - jerk-limited speed changes along a path (S-curves):
 * the 1-D pieces a jerk-limited plan is made of (issue 21). Not yet used by
 * the planner: the building blocks for a path-speed planner whose
 * acceleration changes at J (docs/benchmarks.md, "The jerk limit").
 *
 * A speed change from v0 to v1 with zero acceleration at both ends, the
 * acceleration within a and the jerk within j, takes the least time
 *
 *     t(dv) = dv / a + a / j     when dv = |v1 - v0| >= a^2 / j     (S1)
 *           = 2 sqrt(dv / j)     otherwise (a triangle, a not reached)
 *
 * and, its acceleration point-symmetric about the middle, covers
 *
 *     d(v0, v1) = (v0 + v1) t(|v1 - v0|) / 2                          (S2)
 *
 * Inverse (the backward pass's braking bound): the largest v0 >= v1 with
 * d(v0, v1) <= d, in closed form (S3: a depressed cubic in sqrt(v0 - v1)
 * for the triangle, a quadratic in v0 - v1 beyond it), so a pass computes
 * it as a function of its inputs alone (exact early termination).
 *
 * A line profile goes from (v0, 0) over exactly d to (v1, 0): up to a peak
 * speed vp <= vmax, cruise, down (up to seven phases of constant jerk);
 * the stop from any state (v, a0) brakes at -j to -a, holds, and releases
 * to reach rest with zero acceleration (S4).
 *
 * Pure C, no allocation: the same code in the 1 ms loop and the host tools.
 */
#ifndef MLIP_SCURVE_H
#define MLIP_SCURVE_H

#define MLIP_SCURVE_PHASES 7

/* (S1): least time of a speed change dv >= 0 between zero accelerations. */
double mlip_scurve_dv_time(double dv, double a, double j);
/* (S2): its distance from v0 to v1 (>= 0). */
double mlip_scurve_dv_dist(double v0, double v1, double a, double j);
/* (S3): the largest v0 >= v1 that changes to v1 within d. */
double mlip_scurve_brake_v0(double v1, double d, double a, double j);

/* A profile of constant-jerk phases from (s = 0, v0, a0). */
struct mlip_scurve {
	int n;                         /* phases */
	double t[MLIP_SCURVE_PHASES];  /* durations */
	double j[MLIP_SCURVE_PHASES];  /* jerks */
	double s0[MLIP_SCURVE_PHASES]; /* distance, speed and acceleration */
	double v0[MLIP_SCURVE_PHASES]; /*   at each phase's start */
	double a0[MLIP_SCURVE_PHASES];
	double total_s, end_s, end_v, end_a; /* duration and end state */
};

/* The fastest profile from (v0, 0) over exactly d to (v1, 0), speed within
 * vmax: 0, or -1 when d is too short for v0 -> v1 (d < (S2)) or an input is
 * not finite and positive where it must be. */
int mlip_scurve_line(struct mlip_scurve *c, double v0, double v1, double d, double vmax, double a,
                     double j);
/* (S4) The shortest stop from (v >= 0, a0, |a0| <= a) to rest with zero
 * acceleration. When v is too small for the acceleration to come back to
 * zero before the speed does (v < a0^2 / 2j, a0 < 0), the profile ends where
 * the speed reaches zero, its acceleration then not zero. */
void mlip_scurve_stop(struct mlip_scurve *c, double v, double a0, double a, double j);
/* Distance, speed and acceleration at time t (clamped to [0, total_s]). */
void mlip_scurve_eval(const struct mlip_scurve *c, double t, double *s, double *v, double *acc);

#endif
