/*
 * pathplan.c - one period of the path-speed plan along a spline
 * (mlip/motion/pathplan.h: Q1-Q4; the model: bench/pathspeed.py).
 */
#include "mlip/motion/pathplan.h"

#include <math.h>
#include <stddef.h>

/* The policy's release: a back to 0 as v reaches the crawl, at this share
 * of the jerk the start allows (Q3); the crawl's own stop needs this much
 * room (a speed over END_DECEL, plus END_TIME of it). The model's values. */
#define RELEASE_SHARE 0.8
#define END_DECEL     200.0
#define END_TIME      0.05

struct mlip_path_state mlip_path_advance(struct mlip_path_state st, double j, double h)
{
	struct mlip_path_state r; /* (Q1) */
	r.s = st.s + st.v * h + st.a * h * h / 2.0 + j * h * h * h / 6.0;
	r.v = st.v + st.a * h + j * h * h / 2.0;
	r.a = st.a + j * h;
	return r;
}

/* The (P2) interval where the curve's derivatives are d, at the speed and
 * acceleration the step of jerk j from st has at time h, intersected into
 * [*lo, *hi]. */
static void cut_at(const struct mlip_path_limits *lim, const struct mlip_path_point *d,
                   struct mlip_path_state st, double j, double h, double *lo, double *hi)
{
	struct mlip_path_state at = mlip_path_advance(st, j, h);
	double l, u;
	if (!mlip_path_jerk_range(lim->n, d, lim->jerk, at.v, at.a, &l, &u)) {
		*lo = 1.0; /* no jerk at all here */
		*hi = -1.0;
		return;
	}
	*lo = l > *lo ? l : *lo;
	*hi = u < *hi ? u : *hi;
}

/* The same at parameter s. */
static void cut(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                struct mlip_path_state st, double j, double h, double s, double *lo, double *hi)
{
	struct mlip_path_point d;
	mlip_path_spline_eval(sp, s, 0, NULL, &d);
	cut_at(lim, &d, st, j, h, lo, hi);
}

/* The time in [0, T] at which the step reaches parameter x (s(0) < x <=
 * s(T), s increasing over the step): bisection, bounded work. */
static double time_at(struct mlip_path_state st, double j, double T, double x)
{
	double lo = 0.0, hi = T;
	for (int i = 0; i < 40; i++) {
		double mid = 0.5 * (lo + hi);
		if (mlip_path_advance(st, j, mid).s < x) {
			lo = mid;
		} else {
			hi = mid;
		}
	}
	return 0.5 * (lo + hi);
}

/* (Q2), d0 the derivatives at st.s (each evaluated once a step: the policy,
 * the pick and the state check share it). */
static int range_d(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                   struct mlip_path_state st, const struct mlip_path_point *d0, double j,
                   double *lo, double *hi)
{
	double T = lim->period, l = -INFINITY, u = INFINITY;
	double s1 = mlip_path_advance(st, j, T).s, last = sp->s[sp->count - 1];
	cut_at(lim, d0, st, j, 0.0, &l, &u);
	/* the knots the step crosses, both sides, and the middle of every
	 * stretch between checkpoints (Q2) */
	int k = 0;
	while (k < sp->count && sp->s[k] <= st.s) {
		k++;
	}
	double hp = 0.0;
	for (; k < sp->count - 1 && sp->s[k] < s1 && l <= u; k++) {
		double hk = time_at(st, j, T, sp->s[k]), eps = 1e-12 * (1.0 + sp->s[k]);
		double hm = 0.5 * (hp + hk);
		cut(sp, lim, st, j, hm, mlip_path_advance(st, j, hm).s, &l, &u);
		cut(sp, lim, st, j, hk, sp->s[k] - eps, &l, &u);
		cut(sp, lim, st, j, hk, sp->s[k] + eps, &l, &u);
		hp = hk;
	}
	double hm = 0.5 * (hp + T);
	cut(sp, lim, st, j, hm, mlip_path_advance(st, j, hm).s, &l, &u);
	cut(sp, lim, st, j, T, s1 < last ? s1 : last, &l, &u);
	*lo = l;
	*hi = u;
	return l <= u;
}

int mlip_path_period_range(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                           struct mlip_path_state st, double j, double *lo, double *hi)
{
	struct mlip_path_point d0;
	mlip_path_spline_eval(sp, st.s, 0, NULL, &d0);
	return range_d(sp, lim, st, &d0, j, lo, hi);
}

static double clamp(double x, double lo, double hi)
{
	return x < lo ? lo : (x > hi ? hi : x);
}

static int pick_d(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                  struct mlip_path_state st, const struct mlip_path_point *d0, double jt, double *j)
{
	double lo, hi;
	if (!mlip_path_jerk_range(lim->n, d0, lim->jerk, st.v, st.a, &lo, &hi)) {
		return 0;
	}
	double x = clamp(jt, lo, hi);
	for (int i = 0; i < 4; i++) { /* (Q2) depends on x weakly: a few rounds */
		if (!range_d(sp, lim, st, d0, x, &lo, &hi)) {
			return 0;
		}
		if (lo <= x && x <= hi) {
			*j = x;
			return 1;
		}
		x = clamp(jt, lo, hi);
	}
	return 0;
}

int mlip_path_pick(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                   struct mlip_path_state st, double jt, double *j)
{
	struct mlip_path_point d0;
	mlip_path_spline_eval(sp, st.s, 0, NULL, &d0);
	return pick_d(sp, lim, st, &d0, jt, j);
}

static int brake_d(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                   struct mlip_path_state st, const struct mlip_path_point *d, double *j)
{
	double jl, jh, alo, ahi, T = lim->period;
	if (!mlip_path_jerk_range(lim->n, d, lim->jerk, st.v, st.a, &jl, &jh)) {
		return 0;
	}
	if (st.v <= lim->v_crawl ||
	    (st.a < 0.0 && jh > 0.0 &&
	     st.v - lim->v_crawl <= st.a * st.a / (2.0 * RELEASE_SHARE * jh))) {
		return pick_d(sp, lim, st, d, -st.a / T, j); /* (Q3) release */
	}
	if (!mlip_path_accel_range(lim->n, d, lim->accel, st.v, &alo, &ahi)) {
		return 0;
	}
	double target = alo > -lim->a_brake ? alo : -lim->a_brake, jt = jl;
	if (st.a + jl * T < target) {
		jt = (target - st.a) / T; /* (Q3) reach the target, not past it */
	}
	return pick_d(sp, lim, st, d, jt, j);
}

int mlip_path_brake(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                    struct mlip_path_state st, double *j)
{
	struct mlip_path_point d;
	mlip_path_spline_eval(sp, st.s, 0, NULL, &d);
	return brake_d(sp, lim, st, &d, j);
}

/* Within the speed cap, (P1), a non-empty (P2) interval, before the end. */
static int inside(const struct mlip_path_limits *lim, const struct mlip_path_point *d,
                  struct mlip_path_state st, double end)
{
	double lo, hi;
	if (!(st.v >= 0.0 && st.v <= lim->vmax && st.s <= end + 1e-9)) {
		return 0;
	}
	if (!mlip_path_accel_range(lim->n, d, lim->accel, st.v, &lo, &hi) ||
	    !(lo - 1e-9 <= st.a && st.a <= hi + 1e-9)) {
		return 0;
	}
	return mlip_path_jerk_range(lim->n, d, lim->jerk, st.v, st.a, &lo, &hi);
}

int mlip_path_certified(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                        struct mlip_path_state st, double end, int max_periods, long *work)
{
	for (int i = 0; i < max_periods; i++) {
		if (work) {
			(*work)++;
		}
		struct mlip_path_point d;
		mlip_path_spline_eval(sp, st.s, 0, NULL, &d);
		if (!inside(lim, &d, st, end)) {
			return 0;
		}
		if (st.v <= lim->v_crawl && fabs(st.a) < 1.0) {
			return end - st.s >= st.v * END_TIME; /* (Q4) crawling, room to stop */
		}
		if (end - st.s < st.v * st.v / (2.0 * END_DECEL) + st.v * END_TIME) {
			return 0;
		}
		double j;
		if (!brake_d(sp, lim, st, &d, &j)) {
			return 0;
		}
		st = mlip_path_advance(st, j, lim->period);
	}
	return 0;
}

int mlip_path_plan_period(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                          struct mlip_path_state *st, double end, int max_periods, long *work)
{
	static const double share[5] = {1.0, 0.75, 0.5, 0.25, 0.0};
	struct mlip_path_point d;
	double jl, jh, j;
	mlip_path_spline_eval(sp, st->s, 0, NULL, &d);
	if (mlip_path_jerk_range(lim->n, &d, lim->jerk, st->v, st->a, &jl, &jh)) {
		for (int i = 0; i < 5; i++) {
			if (!pick_d(sp, lim, *st, &d, jl + share[i] * (jh - jl), &j)) {
				break;
			}
			struct mlip_path_state nx = mlip_path_advance(*st, j, lim->period);
			if (mlip_path_certified(sp, lim, nx, end, max_periods, work)) {
				*st = nx;
				return 1;
			}
		}
	}
	/* the braking run's first step: st's run was certified (Q4) */
	if (!brake_d(sp, lim, *st, &d, &j)) {
		return -1;
	}
	struct mlip_path_state nx = mlip_path_advance(*st, j, lim->period);
	if (nx.v < 0.0) {
		nx.s = st->s;
		nx.v = 0.0;
		nx.a = 0.0;
	}
	*st = nx;
	return 0;
}
