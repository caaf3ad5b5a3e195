/*
 * profile.c - a line's speed profile (35)(36) of Zhang, Sun, Gao, Li (2011)
 * (mlip/motion/planner.h), made and followed by the planner's executor.
 */
#include "mlip/motion/strategy.h"

#include <math.h>

/* A line profile from (speed v) over distance rem to speed v1: change to vc,
 * cruise, change to v1, each change at +-a (35)(36), generalised to any
 * start speed so that it can be re-planned from the actual state.
 *
 *   v ^      ____vc____
 *     |     /          \
 *     | v0 /            \ v1
 *     +---------------------> t
 */
void mlip_profile_make(struct mlip_profile *f, double v, double rem, double v1, double a,
                       double vtarget)
{
	/* Plans make braking exactly tight, so rounding can leave v -> v1 short
	 * of room by ~1e-11: take the exact rate then (far inside the margin
	 * kept below the limits) rather than overshoot the corner and jump. */
	double need = fabs(v * v - v1 * v1);
	if (rem > 0.0 && need > 2.0 * a * rem && need <= 2.0 * a * rem * (1.0 + 1e-9)) {
		a = need / (2.0 * rem);
	}
	double vc;
	if (vtarget >= mlip_dmax(v, v1)) {
		double vtri2 = 0.5 * (2.0 * a * rem + v * v + v1 * v1); /* (36) */
		/* never below max(v, v1): only rounding could put vtri there */
		vc = mlip_dmin(vtarget,
		               mlip_dmax(sqrt(mlip_dmax(vtri2, 0.0)), mlip_dmax(v, v1))); /* (35) */
	} else {
		/* above the target (override cut): come down as far as rem allows */
		double vlo2 = 0.5 * (v * v + v1 * v1 - 2.0 * a * rem);
		vc = mlip_dmax(vtarget, sqrt(mlip_dmax(vlo2, 0.0)));
	}
	f->v0 = v;
	f->vc = vc;
	f->v1 = v1;
	f->a1 = vc >= v ? a : -a;
	f->a3 = v1 >= vc ? a : -a;
	f->t1 = fabs(vc - v) / a;
	f->t3 = fabs(v1 - vc) / a;
	f->d1 = fabs(vc * vc - v * v) / (2.0 * a);
	double d3 = fabs(vc * vc - v1 * v1) / (2.0 * a);
	f->d2 = mlip_dmax(rem - f->d1 - d3, 0.0);
	if (vc > 0.0) {
		f->t2 = f->d2 / vc;
	} else {
		f->t2 = f->d2 > 0.0 ? INFINITY : 0.0; /* feed hold: stopped on the line */
	}
}

/* Advance a profile by t < total: distance covered and speed reached. */
void mlip_profile_eval(const struct mlip_profile *f, double t, double *dist, double *v)
{
	if (t <= f->t1) {
		*dist = f->v0 * t + 0.5 * f->a1 * t * t;
		*v = f->v0 + f->a1 * t;
	} else if (t <= f->t1 + f->t2) {
		*dist = f->d1 + f->vc * (t - f->t1);
		*v = f->vc;
	} else {
		double u = t - f->t1 - f->t2;
		*dist = f->d1 + f->d2 + f->vc * u + 0.5 * f->a3 * u * u;
		*v = f->vc + f->a3 * u;
	}
}
