/*
 * test_pathplan.c - one period of the path-speed plan along a spline
 * (src/motion/pathplan.c, Q1-Q4): the whole-period jerk interval (Q2) holds
 * every axis within J over the whole period and is tight on both sides;
 * the greedy plan along a helix keeps J and A at every sample (third and
 * second differences of the positions), never leaves the certified states,
 * and uses them (0.95 J planned is reached), its peak speed at least 0.8 of
 * the quasi-static speed (P3); the same along 80 mm of it in 0.05 mm pieces
 * (one spline in the caller's arrays, several pieces crossed a period);
 * with two braking policies, both used; under each block's own cap (Q5).
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "mlip/motion/pathplan.h"

#define XORSHIFT_SEED 0x2545F4914F6CDD1Dull
#include "xorshift.h"

/* A helix of radius R, rising c a radian, sampled every `step` mm of arc:
 * a spline of MLIP_PATH_WIN points. */
static const double HR = 4.0, HC = 0.5;

static void helix_spline(struct mlip_path_spline *sp, struct mlip_path_curve *cv, double step)
{
	double pts[MLIP_PATH_WIN][MLIP_MAX_AXES] = {{0}};
	double L = sqrt(HR * HR + HC * HC);
	for (int i = 0; i < MLIP_PATH_WIN; i++) {
		double th = i * step / L;
		pts[i][0] = HR * cos(th);
		pts[i][1] = HR * sin(th);
		pts[i][2] = HC * th;
	}
	assert_int_equal(
	    mlip_path_spline_fit(sp, 3, (const double(*)[MLIP_MAX_AXES])pts, MLIP_PATH_WIN), 0);
	mlip_path_spline_curve(sp, cv);
}

static void limits(struct mlip_path_limits *lim, double J)
{
	*lim = (struct mlip_path_limits){0};
	lim->n = 3;
	for (int k = 0; k < 3; k++) {
		lim->accel[k] = 0.98 * 1000.0; /* the model's margins */
		lim->jerk[k] = 0.95 * J;
	}
	lim->vmax = 0.995 * 200.0;
	lim->a_brake[0] = 300.0;
	lim->n_brake = 1;
	lim->v_crawl = 2.0;
	lim->period = 1e-3;
}

/* Two braking policies, 900 and 300 mm/s^2, the hardest first (Q3, Q4) */
static void two_policies(struct mlip_path_limits *lim)
{
	lim->a_brake[0] = 900.0;
	lim->a_brake[1] = 300.0;
	lim->n_brake = 2;
}

/* The worst |P2| / J (accel 0) or |P1| / A (accel 1) over the step of
 * jerk j from st, at 400 instants. */
static double worst_of(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                       struct mlip_path_state st, double j, int accel)
{
	double w = 0.0;
	for (int i = 0; i <= 400; i++) {
		struct mlip_path_state at = mlip_path_advance(st, j, lim->period * i / 400.0);
		struct mlip_path_point d;
		mlip_path_spline_eval(sp, at.s, 0, NULL, &d);
		for (int k = 0; k < lim->n; k++) {
			double p = accel ? d.d1[k] * at.a + d.d2[k] * at.v * at.v /* (P1) */
			                 : d.d1[k] * j + 3.0 * d.d2[k] * at.v * at.a +
			                       d.d3[k] * at.v * at.v * at.v; /* (P2) */
			w = fmax(w, fabs(p) / (accel ? lim->accel[k] : lim->jerk[k]));
		}
	}
	return w;
}

static double worst_jerk(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                         struct mlip_path_state st, double j)
{
	return worst_of(sp, lim, st, j, 0);
}

static double worst_accel(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                          struct mlip_path_state st, double j)
{
	return worst_of(sp, lim, st, j, 1);
}

/* A random state on the helix (s 0.5-5.5 mm, v 0-60 mm/s, a within 300
 * mm/s^2) and its (P2) interval in [*jl, *jh]; 0 when that is empty. */
static int random_state(const struct mlip_path_spline *sp, const struct mlip_path_limits *lim,
                        struct mlip_path_state *st, double *jl, double *jh)
{
	struct mlip_path_point d;
	st->s = uni(0.5, 5.5);
	st->v = uni(0.0, 60.0);
	st->a = uni(-300.0, 300.0);
	st->brake = 0;
	st->share = 0;
	mlip_path_spline_eval(sp, st->s, 0, NULL, &d);
	return mlip_path_jerk_range(lim->n, &d, lim->jerk, st->v, st->a, jl, jh);
}

/* (Q2): a jerk in the interval keeps every axis within J over the whole
 * period (a bound over each piece the step crosses: at 400 instants, never
 * above J); the bound is tight: a jerk 1 % of the interval's span outside
 * either end exceeds J at some instant in at least 90 % of the ends, 10 %
 * outside in 99 % (where a step spans a whole piece or the speed nears
 * zero the bound is looser). The start's interval alone is not enough:
 * some of its ends break J within the period. */
static void test_period_range(void **state)
{
	(void)state;
	struct mlip_path_spline sp;
	struct mlip_path_curve cv;
	struct mlip_path_limits lim;
	helix_spline(&sp, &cv, 0.1);
	limits(&lim, 1e4);
	int checked = 0, start_only_breaks = 0, tight1 = 0, tight10 = 0;
	for (int it = 0; it < 3000; it++) {
		struct mlip_path_state st;
		double lo, hi, jl, jh;
		if (!random_state(&sp, &lim, &st, &jl, &jh)) {
			continue;
		}
		for (int e = 0; e < 2; e++) {
			if (worst_jerk(&sp, &lim, st, e ? jh : jl) > 1.0 + 1e-6) {
				start_only_breaks++;
			}
		}
		double j = jl + uni(0.0, 1.0) * (jh - jl);
		if (!mlip_path_period_range(&cv, &lim, st, j, &lo, &hi) || !(lo <= j && j <= hi)) {
			continue;
		}
		/* each end of the interval, as the end of its own step's interval
		 * (the interval moves with the jerk through Q1: a fixed point, a
		 * few rounds), a hair in and a little out */
		for (int e = 0; e < 2; e++) {
			double x = e ? hi : lo, l2 = lo, h2 = hi;
			int ok = 1;
			for (int r = 0; r < 8 && ok; r++) {
				ok = mlip_path_period_range(&cv, &lim, st, x, &l2, &h2);
				x = e ? h2 : l2;
			}
			if (!ok || !mlip_path_period_range(&cv, &lim, st, x, &l2, &h2) ||
			    fabs((e ? h2 : l2) - x) > 1e-6 * (1.0 + fabs(x))) {
				continue;
			}
			double span = h2 - l2, dir = e ? 1.0 : -1.0;
			double in = x - dir * 1e-9 * span;
			assert_true(worst_jerk(&sp, &lim, st, in) <= 1.0 + 1e-9);
			tight1 += worst_jerk(&sp, &lim, st, x + dir * 0.01 * (span + 1.0)) > 1.0;
			tight10 += worst_jerk(&sp, &lim, st, x + dir * 0.1 * (span + 1.0)) > 1.0;
			checked++;
		}
	}
	print_message("%d ends checked (J broken 1 %% of the span further out: %d, 10 %%: %d); "
	              "%d ends of the start's interval break J\n",
	              checked, tight1, tight10, start_only_breaks);
	assert_true(checked > 1000);
	assert_true(tight1 >= checked * 9 / 10);
	assert_true(tight10 >= checked * 99 / 100);
	assert_true(start_only_breaks > 0);
}

/* (Q2) the acceleration over the step: a jerk the period's interval
 * admits keeps every axis within A at every instant (400), not only at the
 * states: near the (P1) bound (v about the helix's sqrt(A / |x''|), a of
 * either sign) the speed and the curve's terms peak inside the period,
 * where steps whose both ends are within A broke it. The bound is not
 * loose: of the steps whose every instant keeps 0.99 A, at least 90 % are
 * admitted. */
static void test_period_accel(void **state)
{
	(void)state;
	struct mlip_path_spline sp;
	struct mlip_path_curve cv;
	struct mlip_path_limits lim;
	helix_spline(&sp, &cv, 0.1);
	limits(&lim, 1e5);
	int admitted = 0, well_inside = 0, well_inside_admitted = 0, mid_only = 0, end_out = 0;
	double worst_mid = 0.0;
	for (int it = 0; it < 20000; it++) {
		struct mlip_path_state st;
		double lo, hi, jl, jh;
		if (!random_state(&sp, &lim, &st, &jl, &jh)) {
			continue;
		}
		st.v = uni(55.0, 66.0); /* around the helix's (P1) speed, 63 mm/s */
		struct mlip_path_point d;
		mlip_path_spline_eval(&sp, st.s, 0, NULL, &d);
		double al, ah;
		if (!mlip_path_accel_range(lim.n, &d, lim.accel, st.v, &al, &ah) ||
		    !mlip_path_jerk_range(lim.n, &d, lim.jerk, st.v, st.a, &jl, &jh)) {
			continue;
		}
		/* the state within A; every other one on its bound, with a jerk
		 * that turns the bound axis's acceleration outward (P2 > 0 at
		 * +A) by up to 3 % of J at the start: the curve's terms may turn
		 * it back within the period (the end within A) */
		int edge = it & 1;
		st.a = edge ? (it & 2 ? ah : al) : uni(al, ah);
		if (!mlip_path_jerk_range(lim.n, &d, lim.jerk, st.v, st.a, &jl, &jh)) {
			continue;
		}
		double j = uni(jl, jh);
		for (int k = 0; edge && k < lim.n; k++) {
			double p1 = d.d1[k] * st.a + d.d2[k] * st.v * st.v;
			if (fabs(fabs(p1) - lim.accel[k]) < 1e-6 && d.d1[k] != 0.0) {
				double c =
				    3.0 * d.d2[k] * st.v * st.a + d.d3[k] * st.v * st.v * st.v;
				double out = (p1 > 0.0 ? 1.0 : -1.0) * uni(0.0, 0.03 * lim.jerk[k]);
				j = (out - c) / d.d1[k]; /* P2_k = out at the start */
			}
		}
		double w = worst_accel(&sp, &lim, st, j);
		int ok = mlip_path_period_range(&cv, &lim, st, j, &lo, &hi) && lo <= j && j <= hi;
		/* the states' check: both ends within A (the end's own (P1)) */
		struct mlip_path_state e = mlip_path_advance(st, j, lim.period);
		mlip_path_spline_eval(&sp, e.s, 0, NULL, &d);
		int ends_in = mlip_path_accel_range(lim.n, &d, lim.accel, e.v, &al, &ah) &&
		              al - 1e-9 <= e.a && e.a <= ah + 1e-9;
		mid_only += ok && ends_in && w > 1.0 + 1e-9;
		if (ok && ends_in) {
			assert_true(w <= 1.0 + 1e-9); /* no instant between them over A */
		}
		worst_mid = fmax(worst_mid, ok && ends_in ? w : 0.0);
		admitted += ok;
		end_out += ok && !ends_in;
		if (w <= 0.99 && worst_jerk(&sp, &lim, st, j) <= 0.99) {
			well_inside++;
			well_inside_admitted += ok;
		}
	}
	print_message("accel over the step: %d admitted (%d over A between ends within it, "
	              "worst %.6f A; %d with an end over A); of %d steps within 0.99 A and 0.99 J "
	              "at every instant, %d admitted\n",
	              admitted, mid_only, worst_mid, end_out, well_inside, well_inside_admitted);
	assert_int_equal(end_out, 0); /* the end's (P1) is the step's too */
	assert_true(admitted > 1000);
	assert_true(well_inside_admitted >= well_inside * 9 / 10);
}

/* (Q2) pick toward a target beyond either end: the interval's end moves
 * with the step's own jerk, so the jerk wanted is its fixed point. Pick
 * finds an admissible jerk wherever the step at the start's end has an
 * interval at all (four rounds of plain clamping often did not: it nears
 * the fixed point from outside), and mostly at the end: within 0.1 % of
 * the interval's span (a jerk that far further out is outside its own
 * step's interval) in at least 90 % of the cases (where the binding
 * checkpoint changes with the jerk, its secant step lands further in). */
static void test_pick_at_the_end(void **state)
{
	(void)state;
	struct mlip_path_spline sp;
	struct mlip_path_curve cv;
	struct mlip_path_limits lim;
	helix_spline(&sp, &cv, 0.1);
	limits(&lim, 1e4);
	int tried = 0, found = 0, at_end = 0;
	for (int it = 0; it < 2000; it++) {
		struct mlip_path_state st;
		double lo, hi, jl, jh, j;
		if (!random_state(&sp, &lim, &st, &jl, &jh)) {
			continue;
		}
		int up = it & 1;
		if (!mlip_path_period_range(&cv, &lim, st, up ? jh : jl, &lo, &hi)) {
			continue;
		}
		tried++;
		if (!mlip_path_pick(&cv, &lim, st, up ? 1e9 : -1e9, &j)) {
			continue;
		}
		found++;
		assert_true(mlip_path_period_range(&cv, &lim, st, j, &lo, &hi));
		assert_true(lo <= j && j <= hi);
		double out = j + (up ? 1.0 : -1.0) * 1e-3 * (hi - lo + 1.0), l2 = 0.0, h2 = 0.0;
		int ok = mlip_path_period_range(&cv, &lim, st, out, &l2, &h2);
		at_end += !ok || out < l2 || out > h2;
	}
	print_message("pick at an end: %d of %d found, %d within 0.1 %% of it\n", found, tried,
	              at_end);
	assert_true(tried > 500);
	assert_true(found >= tried * 99 / 100);
	assert_true(at_end >= found * 9 / 10);
}

/* The curve's position and derivatives at s (by its own parameter). */
static void at_s(const struct mlip_path_curve *cv, double s, double *x, struct mlip_path_point *d)
{
	mlip_path_spline_eval_piece(cv, mlip_path_spline_piece(cv, s, 0), s, x, d);
}

/* The plan along a curve from rest: every sample's jerk (third difference /
 * T^3) within J and acceleration (second difference / T^2) within A on
 * every axis, the plan within the certified states (the fallback always
 * has a jerk), at rest at the end; its peak speed at least 0.8 of
 * the quasi-static speed (P3) at the planned limits (not at most: with a
 * path acceleration the per-axis box lets the plan pass it for a while). */
static int plan_curve_lim(const struct mlip_path_curve *cv, double J,
                          const struct mlip_path_limits *limp, int *policies)
{
	struct mlip_path_limits lim = *limp;
	double end = cv->s[cv->count - 1];
	struct mlip_path_state st = {0.0, 0.0, 0.0, 0, 0};
	static double x[40000][MLIP_MAX_AXES];
	int n = 0, moved = 0;
	long work = 0;
	double vpeak = 0.0;
	struct mlip_path_point d;
	at_s(cv, 0.0, x[n++], &d);
	double stalled = -1.0;
	while (!(st.v == 0.0 && st.a == 0.0 && st.s == stalled)) {
		stalled = st.v == 0.0 && st.a == 0.0 ? st.s : -1.0;
		int r = mlip_path_plan_period(cv, &lim, &st, end, 3000, &work);
		assert_true(r >= 0);
		moved += r;
		vpeak = fmax(vpeak, st.v);
		*policies |= 1 << st.brake;
		at_s(cv, st.s, x[n++], &d);
		assert_true(n < 40000);
	}
	double T = lim.period, wj = 0.0, wa = 0.0;
	for (int i = 3; i < n; i++) {
		for (int k = 0; k < lim.n; k++) {
			double j3 =
			    (x[i][k] - 3.0 * x[i - 1][k] + 3.0 * x[i - 2][k] - x[i - 3][k]) /
			    (T * T * T);
			double a2 = (x[i][k] - 2.0 * x[i - 1][k] + x[i - 2][k]) / (T * T);
			wj = fmax(wj, fabs(j3) / J);
			wa = fmax(wa, fabs(a2) / 1000.0);
		}
	}
	/* the quasi-static speed of the curve's middle (P3), by its parameter;
	 * on a short curve, at most what a rest-to-rest move reaches at the
	 * path jerk J (four jerk phases of tau: d = 2 J tau^3, v = J tau^2) */
	double tau = cbrt(end / (2.0 * lim.jerk[0])), vq = lim.jerk[0] * tau * tau;
	for (double s = 0.25 * end; s <= 0.75 * end; s += 0.01) {
		at_s(cv, s, NULL, &d);
		vq = fmin(vq, mlip_path_vmax(lim.n, &d, lim.accel, lim.jerk, lim.vmax));
	}
	print_message("J %g, %d points: %d periods, %d faster than braking, %ld run periods; "
	              "jerk %.3f J, accel %.3f A, peak %.2f of vq %.2f\n",
	              J, cv->count, n, moved, work, wj, wa, vpeak, vq);
	assert_true(wj <= 1.0);
	assert_true(wj >= 0.9); /* the plan uses the limit (0.95 J planned) */
	assert_true(wa <= 1.0);
	assert_true(vpeak >= 0.8 * vq);
	/* at rest at the end (the plan's own last states: no tail) */
	assert_true(fabs(end - st.s) < 1e-6);
	return n;
}

static void plan_curve(const struct mlip_path_curve *cv, double J)
{
	struct mlip_path_limits lim;
	int policies = 0;
	limits(&lim, J);
	plan_curve_lim(cv, J, &lim, &policies);
	assert_int_equal(policies, 1);
}

static void plan_helix(double J)
{
	struct mlip_path_spline sp;
	struct mlip_path_curve cv;
	helix_spline(&sp, &cv, 0.4);
	plan_curve(&cv, J);
}

static void test_plan_helix_1e4(void **state)
{
	(void)state;
	plan_helix(1e4);
}

static void test_plan_helix_1e5(void **state)
{
	(void)state;
	plan_helix(1e5);
}

/* A long curve in fine pieces, as `smooth` hands them (0.05 mm, several
 * crossed a period at speed): the same helix over 1,600 points fitted as one
 * spline in the caller's arrays (mlip_path_fit), planned at J = 1e5 from
 * rest to rest with the same checks. */
#define LONG_N 1600
static double lp[LONG_N][MLIP_MAX_AXES], ls[LONG_N], lpp[LONG_N][MLIP_MAX_AXES];
static double lm[LONG_N][MLIP_MAX_AXES], lb[LONG_N][MLIP_MAX_AXES], lt[LONG_N][MLIP_MAX_AXES],
    lc[LONG_N];

static void test_plan_long_fine_helix(void **state)
{
	(void)state;
	double L = sqrt(HR * HR + HC * HC);
	for (int i = 0; i < LONG_N; i++) {
		double th = i * 0.05 / L;
		lp[i][0] = HR * cos(th);
		lp[i][1] = HR * sin(th);
		lp[i][2] = HC * th;
	}
	struct mlip_path_curve cv;
	assert_int_equal(mlip_path_fit(3, (const double(*)[MLIP_MAX_AXES])lp, LONG_N, ls, lpp, lm,
	                               lb, lt, lc, &cv),
	                 0);
	assert_int_equal(cv.count, LONG_N);
	plan_curve(&cv, 1e5);
}

/* Two braking policies (Q3, Q4: a state certified by either's run, the
 * fallback following the one that certified it): the same checks, and
 * both policies used (the greedy is not monotone in what it may certify:
 * on this helix one policy took 536 periods and two 678 with every
 * candidate tried each period, 763 and 591 from one above the last; on the
 * benchmark's curves two are faster, docs/benchmarks.md). */
static void test_plan_helix_two_policies(void **state)
{
	(void)state;
	struct mlip_path_spline sp;
	struct mlip_path_curve cv;
	struct mlip_path_limits lim;
	helix_spline(&sp, &cv, 0.4);
	limits(&lim, 1e5);
	int one = 0, two = 0;
	int n1 = plan_curve_lim(&cv, 1e5, &lim, &one);
	two_policies(&lim);
	int n2 = plan_curve_lim(&cv, 1e5, &lim, &two);
	print_message("periods: %d with 300 mm/s^2, %d with 900 and 300\n", n1, n2);
	assert_int_equal(one, 1);
	assert_int_equal(two, 3);
}

/* A state keeps the hardest policy whose run certifies it (the first of
 * a_brake, hardest first), so a hold brakes as hard as the policies allow
 * from there: on the helix with 900 and 300, every state the plan enters
 * labelled 300 is one whose 900 run fails, and some are. Before, a state
 * tried its predecessor's policy first and kept 300 where 900 would do
 * (a hold on a straight stretch after a tight curve braked gently). */
static void test_plan_keeps_the_hardest_policy(void **state)
{
	(void)state;
	struct mlip_path_spline sp;
	struct mlip_path_curve cv;
	struct mlip_path_limits lim;
	helix_spline(&sp, &cv, 0.4);
	limits(&lim, 1e5);
	two_policies(&lim);
	double end = cv.s[cv.count - 1];
	struct mlip_path_state st = {0.0, 0.0, 0.0, 0, 0};
	long work = 0;
	int gentle = 0, hard = 0;
	for (int n = 0; n < 20000 && !(n > 0 && st.v == 0.0 && st.a == 0.0); n++) {
		int r = mlip_path_plan_period(&cv, &lim, &st, end, 3000, &work);
		assert_true(r >= 0);
		if (r == 1 && st.brake == 1) { /* entered, labelled 300 */
			struct mlip_path_state h = st;
			h.brake = 0;
			assert_false(mlip_path_certified(&cv, &lim, h, end, 3000, NULL));
			gentle++;
		}
		hard += r == 1 && st.brake == 0;
	}
	print_message("states entered: %d by 900, %d by 300 only\n", hard, gentle);
	assert_true(gentle > 0 && hard > 0);
}

/* A hook, as on tball-pocket's part of stations 5,316-5,340 (0.79 mm): a
 * line at slope -0.3 in pieces of 0.001-0.08 mm with a step of 0.0002 mm
 * across it after 0.62 mm. The spline's x''' there is so large that no
 * jerk is admissible above about 1 mm/s (x''' v^3 alone exceeds J): the
 * plan must pass it slower, from the states it certified (Q4: a run that
 * ended at a crawl of 2 mm/s left them here at s 0.62, at 1e4 and 1e5),
 * and end at rest at the end, inside J and A at every sample. */
static void plan_hook(double J)
{
	static const double h[] = {0.08,  0.034, 0.075, 0.075, 0.075, 0.0037, 0.0014, 0.03,
	                           0.023, 0.011, 0.05,  0.012, 0.08,  0.011,  0.06,   0.005,
	                           0.01,  0.018, 0.03,  0.015, 0.07,  0.002,  0.006};
	enum { NH = sizeof h / sizeof h[0], HOOK = 15 };
	static double pts[NH + 2][MLIP_MAX_AXES], s[NH + 2], p[NH + 2][MLIP_MAX_AXES];
	static double m[NH + 2][MLIP_MAX_AXES], b[NH + 2][MLIP_MAX_AXES], t3[NH + 2][MLIP_MAX_AXES],
	    c[NH + 2];
	double ux = 1.0 / sqrt(1.09), uy = -0.3 / sqrt(1.09), u = 0.0;
	int n = 0;
	for (int i = 0; i <= NH; i++) {
		double dy = i > HOOK ? -0.0002 : 0.0;
		pts[n][0] = u * ux;
		pts[n++][1] = u * uy + dy;
		if (i == HOOK) {
			pts[n][0] = u * ux;
			pts[n++][1] = u * uy - 0.0002;
		}
		u += i < NH ? h[i] : 0.0;
	}
	struct mlip_path_curve cv;
	assert_int_equal(
	    mlip_path_fit(3, (const double(*)[MLIP_MAX_AXES])pts, n, s, p, m, b, t3, c, &cv), 0);
	struct mlip_path_limits lim;
	limits(&lim, J);
	two_policies(&lim);
	int policies = 0;
	plan_curve_lim(&cv, J, &lim, &policies);
}

static void test_plan_hook(void **state)
{
	(void)state;
	plan_hook(1e4);
	plan_hook(1e5);
}

/* A line of 0.17 mm (a part of the random zigzag between two rests): the
 * plan's stop by a candidate jerk (not the policy's in-period stop) landed
 * a rounding from rest (v 8.5e-15, a 1.1e-13), where a jerk of 0 stayed
 * certified for ever; it must reach the end at rest. */
static void test_plan_short_line(void **state)
{
	(void)state;
	static const double pts[2][MLIP_MAX_AXES] = {{-2.3728, -2.4917}, {-2.3596, -2.6653}};
	static double s[2], p[2][MLIP_MAX_AXES], m[2][MLIP_MAX_AXES], b[2][MLIP_MAX_AXES],
	    t3[2][MLIP_MAX_AXES], c[2];
	struct mlip_path_curve cv;
	assert_int_equal(mlip_path_fit(2, pts, 2, s, p, m, b, t3, c, &cv), 0);
	struct mlip_path_limits lim;
	limits(&lim, 1e5);
	lim.n = 2;
	two_policies(&lim);
	int policies = 0;
	plan_curve_lim(&cv, 1e5, &lim, &policies);
}

/* The plan from rest at s0 on cv to its end: each move from rest leaves
 * it, the end is reached at rest; the worst jerk / J and acceleration / A
 * of its samples (third and second differences) in *wj, *wa. */
static void plan_from(const struct mlip_path_curve *cv, const struct mlip_path_limits *lim,
                      double s0, double *wj, double *wa)
{
	static double x[20000][MLIP_MAX_AXES];
	double end = cv->s[cv->count - 1], T = lim->period;
	struct mlip_path_state st = {s0, 0.0, 0.0, 1, 0};
	struct mlip_path_point d;
	long work = 0;
	int n = 0;
	at_s(cv, st.s, x[n++], &d);
	while (n < 20000 && !(st.v == 0.0 && st.a == 0.0 && end - st.s <= 1e-8)) {
		struct mlip_path_state was = st;
		int r = mlip_path_plan_period(cv, lim, &st, end, 3000, &work);
		assert_true(r >= 0);
		if (was.v == 0.0 && was.a == 0.0 && r == 1) {
			assert_true(st.s > was.s); /* a move from rest moves */
		}
		at_s(cv, st.s, x[n++], &d);
	}
	assert_true(fabs(end - st.s) <= 1e-8); /* at rest at the end */
	assert_true(st.v == 0.0 && st.a == 0.0);
	for (int i = 3; i < n; i++) {
		for (int k = 0; k < lim->n; k++) {
			double j3 =
			    (x[i][k] - 3.0 * x[i - 1][k] + 3.0 * x[i - 2][k] - x[i - 3][k]) /
			    (T * T * T);
			double a2 = (x[i][k] - 2.0 * x[i - 1][k] + x[i - 2][k]) / (T * T);
			*wj = fmax(*wj, fabs(j3) / (lim->jerk[k] / 0.95));
			*wa = fmax(*wa, fabs(a2) / (lim->accel[k] / 0.98));
		}
	}
}

/* A near-cusp, as the random zigzag (seed 1) has at 118.6 mm: smooth's
 * setpoints into a vertex and out of it at y'' -1000 mm/s^2 (y's speed 0
 * at the vertex, 0.68 of a period after sample 8), along x = 0.4738 y in
 * and x = -0.2665 y out, so the spline's pieces there are of 0.2-0.9 um
 * (x''' up to 2.6e7). At rest 0.12 um past the short piece the first jerk
 * the plan tried from rest (its largest, halved once) let only [-194514,
 * 3.8e-5] over its own step; pick_at clamped to 3.8e-5, whose step ends
 * at rest (REST_V, REST_A): a move that stayed, for ever. From rest at
 * points around the vertex the plan must move and reach the end at rest,
 * within J and A. */
static void test_plan_from_rest_at_cusp(void **state)
{
	(void)state;
	enum { N = 22 };
	static double pts[N][MLIP_MAX_AXES], s[N], p[N][MLIP_MAX_AXES], m[N][MLIP_MAX_AXES],
	    b[N][MLIP_MAX_AXES], t3[N][MLIP_MAX_AXES], c[N];
	const double tv = 8.678822303;
	for (int k = 0; k < N; k++) {
		double y = -0.0005 * (k - tv) * (k - tv);
		pts[k][0] = (k < tv ? 0.473804100 : -0.266534653) * y;
		pts[k][1] = y;
	}
	struct mlip_path_curve cv;
	assert_int_equal(
	    mlip_path_fit(2, (const double(*)[MLIP_MAX_AXES])pts, N, s, p, m, b, t3, c, &cv), 0);
	struct mlip_path_limits lim;
	limits(&lim, 1e5);
	lim.n = 2;
	two_policies(&lim);
	double wj = 0.0, wa = 0.0;
	for (int q = -40; q <= 40; q++) {
		plan_from(&cv, &lim, s[9] + q * 0.01e-3, &wj, &wa);
	}
	print_message("cusp: pieces %.2g, %.2g um; jerk %.3f J, accel %.3f A\n",
	              (s[9] - s[8]) * 1e3, (s[10] - s[9]) * 1e3, wj, wa);
	assert_true(wj <= 1.0);
	assert_true(wj >= 0.5); /* it moved under the limit, not at a creep */
	assert_true(wa <= 1.0);
}

/* Each block's own feed (Q5): the fine helix's knots capped 50, 10, 40
 * mm/s and none (vmax) in runs of 400, planned from rest to rest at 1e5:
 * every state within its piece's cap, every step's ends within the cap of
 * each piece it touches (so the lower cap ahead is braked for in time and a
 * higher one taken only past the piece that joins them), each sample's
 * chord a period within the lower cap of its ends' pieces (1e-3 over: a
 * period's mean speed is within |j| T^2 / 12 of its ends', 8e-4 of 10
 * mm/s at 0.95e5; measured 6.1e-4), each cap
 * reached to 0.9 inside its run, J and A at every sample. An override's
 * share (vfull) scales the knots' caps, not the machine's vmax. */
static double lcap[LONG_N];

static void test_plan_feed_caps(void **state)
{
	(void)state;
	static const double run_cap[4] = {50.0, 10.0, 40.0, 0.0};
	static double x[40000][MLIP_MAX_AXES];
	static int piece[40000];
	double L = sqrt(HR * HR + HC * HC), T = 1e-3, top[4] = {0};
	for (int i = 0; i < LONG_N; i++) {
		double th = i * 0.05 / L;
		lp[i][0] = HR * cos(th);
		lp[i][1] = HR * sin(th);
		lp[i][2] = HC * th;
		lcap[i] = run_cap[i / 400];
	}
	struct mlip_path_curve cv;
	assert_int_equal(mlip_path_fit(3, (const double(*)[MLIP_MAX_AXES])lp, LONG_N, ls, lpp, lm,
	                               lb, lt, lc, &cv),
	                 0);
	cv.cap = lcap;
	struct mlip_path_limits lim;
	limits(&lim, 1e5);
	two_policies(&lim);
	assert_true(mlip_path_piece_cap(&cv, &lim, 399) == 10.0); /* the joining piece: the lower */
	assert_true(mlip_path_piece_cap(&cv, &lim, 1300) == lim.vmax);
	double end = cv.s[LONG_N - 1], wj = 0.0, wa = 0.0, over = 0.0;
	struct mlip_path_state st = {0.0, 0.0, 0.0, 0, 0};
	struct mlip_path_point d;
	long work = 0;
	int n = 0;
	at_s(&cv, 0.0, x[n], &d);
	piece[n++] = 0;
	while (n < 40000 && !(st.v == 0.0 && st.a == 0.0 && end - st.s <= 1e-8)) {
		double v0 = st.v;
		assert_true(mlip_path_plan_period(&cv, &lim, &st, end, 3000, &work) >= 0);
		int p = mlip_path_spline_piece(&cv, st.s, piece[n - 1]), lo = piece[n - 1];
		at_s(&cv, st.s, x[n], &d);
		piece[n] = p;
		double cap = INFINITY, chord = 0.0;
		for (int i = lo < p ? lo : p; i <= (lo < p ? p : lo); i++) {
			cap = fmin(cap, mlip_path_piece_cap(&cv, &lim, i));
		}
		assert_true(st.v <= mlip_path_piece_cap(&cv, &lim, p));
		assert_true(fmax(v0, st.v) <= cap);
		for (int k = 0; k < 3; k++) {
			chord += (x[n][k] - x[n - 1][k]) * (x[n][k] - x[n - 1][k]);
		}
		over = fmax(over, sqrt(chord) / T / cap);
		if (p % 400 > 0 && p % 400 < 399) {
			top[p / 400] = fmax(top[p / 400], st.v);
		}
		n++;
	}
	assert_true(st.v == 0.0 && st.a == 0.0 && fabs(end - st.s) <= 1e-8);
	for (int i = 3; i < n; i++) {
		for (int k = 0; k < 3; k++) {
			double j3 =
			    (x[i][k] - 3.0 * x[i - 1][k] + 3.0 * x[i - 2][k] - x[i - 3][k]) /
			    (T * T * T);
			double a2 = (x[i][k] - 2.0 * x[i - 1][k] + x[i - 2][k]) / (T * T);
			wj = fmax(wj, fabs(j3) / 1e5);
			wa = fmax(wa, fabs(a2) / 1000.0);
		}
	}
	print_message("caps 50, 10, 40, none: %d periods, tops %.2f %.2f %.2f %.2f, chord speed "
	              "%.5f of the cap, jerk %.3f J, accel %.3f A\n",
	              n, top[0], top[1], top[2], top[3], over, wj, wa);
	assert_true(over <= 1.0 + 1e-3);
	for (int r = 0; r < 3; r++) {
		assert_true(top[r] >= 0.9 * run_cap[r]);
	}
	assert_true(wj <= 1.0 && wa <= 1.0);
	lim.vfull = 2.0 * lim.vmax; /* an override of 50 %: the knots' caps halved */
	assert_true(fabs(mlip_path_piece_cap(&cv, &lim, 100) - 25.0) < 1e-12);
	assert_true(mlip_path_piece_cap(&cv, &lim, 1300) == lim.vmax);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_period_range),
	    cmocka_unit_test(test_pick_at_the_end),
	    cmocka_unit_test(test_period_accel),
	    cmocka_unit_test(test_plan_helix_1e4),
	    cmocka_unit_test(test_plan_helix_1e5),
	    cmocka_unit_test(test_plan_long_fine_helix),
	    cmocka_unit_test(test_plan_helix_two_policies),
	    cmocka_unit_test(test_plan_keeps_the_hardest_policy),
	    cmocka_unit_test(test_plan_hook),
	    cmocka_unit_test(test_plan_short_line),
	    cmocka_unit_test(test_plan_from_rest_at_cusp),
	    cmocka_unit_test(test_plan_feed_caps),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
