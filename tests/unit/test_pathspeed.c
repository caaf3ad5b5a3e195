/*
 * test_pathspeed.c - the per-axis limits of a path-speed plan along a curve
 * (src/motion/pathspeed.c, P1-P4): (P1)(P2) are the chain rule (finite
 * differences of a helix traversed at a path jerk), the ranges are tight on
 * both sides, (P3) on a circle is sqrt(A R) and cbrt(J R^2), and (P4) reads
 * a sampled helix's derivatives to the order it states.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "mlip/motion/pathspeed.h"

static uint64_t rng = 0x9E3779B97F4A7C15ull;

static double uni(double lo, double hi)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return lo + (hi - lo) * (double)(rng >> 11) * (1.0 / 9007199254740992.0);
}

/* A helix of radius R and pitch c per radian, by arc length: x(s) and its
 * derivatives (theta = s / L, L = sqrt(R^2 + c^2)). */
static const double HR = 4.0, HC = 1.5;

static void helix(double s, double *x, struct mlip_path_point *d)
{
	double L = sqrt(HR * HR + HC * HC), th = s / L, cs = cos(th), sn = sin(th);
	if (x) {
		x[0] = HR * cs;
		x[1] = HR * sn;
		x[2] = HC * th;
	}
	if (d) {
		for (int k = 0; k < MLIP_MAX_AXES; k++) {
			d->d1[k] = d->d2[k] = d->d3[k] = 0.0;
		}
		d->d1[0] = -HR * sn / L;
		d->d1[1] = HR * cs / L;
		d->d1[2] = HC / L;
		d->d2[0] = -HR * cs / (L * L);
		d->d2[1] = -HR * sn / (L * L);
		d->d3[0] = HR * sn / (L * L * L);
		d->d3[1] = -HR * cs / (L * L * L);
	}
}

/* (P1)(P2) against the 2nd and 3rd derivatives in time of x(s(t)),
 * s(t) = s0 + v t + a t^2 / 2 + j t^3 / 6, by central differences at t = 0
 * (step 1e-3 s: truncation ~1e-6 relative, rounding ~1e-8). */
static void test_chain_rule(void **state)
{
	(void)state;
	for (int it = 0; it < 200; it++) {
		double s0 = uni(0.0, 40.0), v = uni(0.0, 200.0), a = uni(-2000.0, 2000.0);
		double j = uni(-1e5, 1e5), h = 1e-3;
		struct mlip_path_point d;
		helix(s0, NULL, &d);
		double x[5][3];
		for (int i = 0; i < 5; i++) {
			double t = (i - 2) * h;
			helix(s0 + v * t + a * t * t / 2.0 + j * t * t * t / 6.0, x[i], NULL);
		}
		for (int k = 0; k < 3; k++) {
			double acc = (x[3][k] - 2.0 * x[2][k] + x[1][k]) / (h * h);
			double jrk =
			    (x[4][k] - 2.0 * x[3][k] + 2.0 * x[1][k] - x[0][k]) / (2.0 * h * h * h);
			double p1 = d.d1[k] * a + d.d2[k] * v * v;
			double p2 = d.d1[k] * j + 3.0 * d.d2[k] * v * a + d.d3[k] * v * v * v;
			/* the differences' truncation: h^2 / 12 x'''' (accel) and
			 * h^2 / 4 x''''' (jerk) in time; bounded here by the scales */
			double sa = 1.0 + fabs(a) + v * v / HR,
			       sj = 1.0 + fabs(j) + v * fabs(a) + v * v * v / (HR * HR);
			assert_true(fabs(acc - p1) <= 1e-3 * sa + 1e-4 * sj * h);
			assert_true(fabs(jrk - p2) <= 2e-2 * sj);
		}
	}
}

/* The ranges hold every axis within its limit at both ends and are tight:
 * a hair outside either end, some axis exceeds. */
static void test_ranges_tight(void **state)
{
	(void)state;
	int n = 3, checked = 0;
	double A[3] = {1000.0, 600.0, 1500.0}, J[3] = {1e5, 3e4, 1e4};
	for (int it = 0; it < 20000; it++) {
		struct mlip_path_point c;
		double nn = 0.0;
		for (int k = 0; k < MLIP_MAX_AXES; k++) {
			c.d1[k] = k < n ? uni(-1.0, 1.0) : 0.0;
			c.d2[k] = k < n ? uni(-2.0, 2.0) : 0.0;
			c.d3[k] = k < n ? uni(-4.0, 4.0) : 0.0;
			nn += c.d1[k] * c.d1[k];
		}
		if (it % 7 == 0) {
			c.d1[it % 3] = 0.0; /* an axis the path does not move along */
		}
		for (int k = 0; k < n; k++) {
			c.d1[k] /= sqrt(nn);
		}
		double v = uni(0.0, 60.0), lo, hi;
		if (!mlip_path_accel_range(n, &c, A, v, &lo, &hi)) {
			/* empty: the normal term alone exceeds some axis, or the
			 * axes' intervals are disjoint: no a in a wide grid fits */
			for (double a = -1e4; a <= 1e4; a += 1.0) {
				int ok = 1;
				for (int k = 0; k < n; k++) {
					ok &= fabs(c.d1[k] * a + c.d2[k] * v * v) <= A[k];
				}
				assert_false(ok);
			}
			continue;
		}
		for (int e = 0; e < 2; e++) {
			double a = e ? hi : lo, worst = 0.0;
			for (int k = 0; k < n; k++) {
				worst = fmax(worst, fabs(c.d1[k] * a + c.d2[k] * v * v) / A[k]);
			}
			assert_true(worst <= 1.0 + 1e-12);
			double out = a + (e ? 1.0 : -1.0) * 1e-6 * (1.0 + fabs(a));
			worst = 0.0;
			for (int k = 0; k < n; k++) {
				worst = fmax(worst, fabs(c.d1[k] * out + c.d2[k] * v * v) / A[k]);
			}
			assert_true(worst > 1.0);
		}
		double a = lo + uni(0.0, 1.0) * (hi - lo), jl, jh;
		if (!mlip_path_jerk_range(n, &c, J, v, a, &jl, &jh)) {
			continue;
		}
		for (int e = 0; e < 2; e++) {
			double j = e ? jh : jl, worst = 0.0;
			for (int k = 0; k < n; k++) {
				double q =
				    c.d1[k] * j + 3.0 * c.d2[k] * v * a + c.d3[k] * v * v * v;
				worst = fmax(worst, fabs(q) / J[k]);
			}
			assert_true(worst <= 1.0 + 1e-12);
			double out = j + (e ? 1.0 : -1.0) * 1e-6 * (1.0 + fabs(j));
			worst = 0.0;
			for (int k = 0; k < n; k++) {
				double q =
				    c.d1[k] * out + 3.0 * c.d2[k] * v * a + c.d3[k] * v * v * v;
				worst = fmax(worst, fabs(q) / J[k]);
			}
			assert_true(worst > 1.0);
		}
		checked++;
	}
	assert_true(checked > 5000); /* most draws have both ranges */
}

/* (P3) on a circle of radius R at angle 0: x'' = (-1/R, 0), x''' = (0, -1/R^2). */
static void test_vmax_circle(void **state)
{
	(void)state;
	const double Rs[] = {0.1, 1.0, 5.0, 50.0};
	for (size_t i = 0; i < sizeof(Rs) / sizeof(Rs[0]); i++) {
		double R = Rs[i], A[2] = {1000.0, 1000.0}, J[2] = {1e4, 1e4};
		struct mlip_path_point c = {{0.0, 1.0}, {-1.0 / R, 0.0}, {0.0, -1.0 / (R * R)}};
		double va = mlip_path_vmax(2, &c, A, NULL, 200.0);
		double vj = mlip_path_vmax(2, &c, A, J, 200.0);
		double ea = fmin(200.0, sqrt(1000.0 * R)), ej = fmin(ea, cbrt(1e4 * R * R));
		assert_true(fabs(va - ea) <= 1e-12 * ea);
		assert_true(fabs(vj - ej) <= 1e-12 * ej);
		/* steady at vj: accel and jerk ranges contain 0 */
		double lo, hi;
		assert_true(mlip_path_accel_range(2, &c, A, vj, &lo, &hi));
		assert_true(lo <= 0.0 && 0.0 <= hi);
		assert_true(mlip_path_jerk_range(2, &c, J, vj * (1.0 - 1e-9), 0.0, &lo, &hi));
		assert_true(lo <= 0.0 && 0.0 <= hi);
	}
}

/* The largest error of (P4) over a helix sampled at steps h (1 +- 30 %
 * random), each estimate taken in the middle interval: {d1, d2, d3}. */
static void p4_errors(double h, double *err)
{
	err[0] = err[1] = err[2] = 0.0;
	double p[4][MLIP_MAX_AXES] = {{0}}, sp[4];
	double s = 0.0;
	for (int i = 0; i < 4; i++) {
		sp[i] = s;
		helix(s, p[i], NULL);
		s += h * uni(0.7, 1.3);
	}
	for (int it = 0; it < 400; it++) {
		double t = 0.0;
		for (int k = 0; k < 3; k++) { /* chord length to the middle of p1 p2 */
			t += (p[1][k] - p[0][k]) * (p[1][k] - p[0][k]);
		}
		t = sqrt(t);
		double c12 = 0.0;
		for (int k = 0; k < 3; k++) {
			c12 += (p[2][k] - p[1][k]) * (p[2][k] - p[1][k]);
		}
		t += 0.5 * sqrt(c12);
		struct mlip_path_point est, ex;
		assert_int_equal(
		    mlip_path_from_points(3, (const double(*)[MLIP_MAX_AXES])p, t, &est), 0);
		helix(0.5 * (sp[1] + sp[2]), NULL, &ex);
		for (int k = 0; k < 3; k++) {
			err[0] = fmax(err[0], fabs(est.d1[k] - ex.d1[k]));
			err[1] = fmax(err[1], fabs(est.d2[k] - ex.d2[k]));
			err[2] = fmax(err[2], fabs(est.d3[k] - ex.d3[k]));
		}
		for (int i = 0; i < 3; i++) {
			sp[i] = sp[i + 1];
			for (int k = 0; k < 3; k++) {
				p[i][k] = p[i + 1][k];
			}
		}
		sp[3] = s;
		helix(s, p[3], NULL);
		s += h * uni(0.7, 1.3);
	}
}

static void test_from_points(void **state)
{
	(void)state;
	/* |x''| = R / L^2 = 0.219, |x'''| = R / L^3 = 0.0512 (1/mm, 1/mm^2) */
	double e1[3], e2[3];
	p4_errors(0.05, e1);
	p4_errors(0.025, e2);
	assert_true(e1[0] < 1e-5 && e1[1] < 1e-4 && e1[2] < 5e-3);
	/* the orders stated: x' and x'' O(h^2) (halving h: at least 3x
	 * smaller), x''' O(h) (at least 1.6x smaller) */
	assert_true(e2[0] * 3.0 < e1[0] && e2[1] * 3.0 < e1[1] && e2[2] * 1.6 < e1[2]);
	assert_true(e2[2] > 0.0);

	/* a straight line: x'' and x''' vanish (to rounding) */
	double p[4][MLIP_MAX_AXES] = {{0}};
	const double st[4] = {0.0, 0.1, 0.35, 0.4};
	for (int i = 0; i < 4; i++) {
		p[i][0] = 1.0 + 0.6 * st[i];
		p[i][1] = -2.0 + 0.8 * st[i];
	}
	struct mlip_path_point c;
	assert_int_equal(mlip_path_from_points(2, (const double(*)[MLIP_MAX_AXES])p, 0.2, &c), 0);
	assert_true(fabs(c.d1[0] - 0.6) < 1e-12 && fabs(c.d1[1] - 0.8) < 1e-12);
	for (int k = 0; k < 2; k++) {
		assert_true(fabs(c.d2[k]) < 1e-9 && fabs(c.d3[k]) < 1e-6);
	}
	/* two points coincide: no curve */
	p[2][0] = p[1][0];
	p[2][1] = p[1][1];
	assert_int_equal(mlip_path_from_points(2, (const double(*)[MLIP_MAX_AXES])p, 0.2, &c), -1);
}

/* Points on the helix from arc length s0, steps h (1 +- 30 % random). */
static void helix_points(double s0, double h, int count, double pts[][MLIP_MAX_AXES], double *sp)
{
	double s = s0;
	for (int i = 0; i < count; i++) {
		for (int k = 0; k < MLIP_MAX_AXES; k++) {
			pts[i][k] = 0.0;
		}
		helix(s, pts[i], NULL);
		sp[i] = s;
		s += h * uni(0.7, 1.3);
	}
}

/* (P5): the spline passes through its points, is C2 at them, reads the
 * helix to the orders of a cubic spline in the window's middle, and a window
 * moved along the stream gives the same spline in its middle (the ends'
 * influence, 0.268^k). */
static struct mlip_path_spline spa, spb;
static double pts[MLIP_PATH_WIN + 16][MLIP_MAX_AXES], arc[MLIP_PATH_WIN + 16];

static void spline_errors(double h, double *err)
{
	helix_points(1.0, h, MLIP_PATH_WIN, pts, arc);
	assert_int_equal(
	    mlip_path_spline_fit(&spa, 3, (const double(*)[MLIP_MAX_AXES])pts, MLIP_PATH_WIN), 0);
	err[0] = err[1] = err[2] = 0.0;
	for (int i = 20; i < MLIP_PATH_WIN - 20; i++) {
		for (int q = 0; q < 4; q++) { /* at the knot and inside the segment */
			double f = q / 4.0, x[MLIP_MAX_AXES], ex[3];
			struct mlip_path_point d, e;
			double u = spa.s[i] + f * (spa.s[i + 1] - spa.s[i]);
			assert_int_equal(mlip_path_spline_eval(&spa, u, 1, x, &d), 0);
			/* chord and arc length differ by O(h^3): compare at the arc
			 * length of the same fraction */
			helix(arc[i] + f * (arc[i + 1] - arc[i]), ex, &e);
			for (int k = 0; k < 3; k++) {
				err[0] = fmax(err[0], fabs(d.d1[k] - e.d1[k]));
				err[1] = fmax(err[1], fabs(d.d2[k] - e.d2[k]));
				err[2] = fmax(err[2], fabs(d.d3[k] - e.d3[k]));
			}
		}
	}
}

static void test_spline(void **state)
{
	(void)state;
	double e1[3], e2[3];
	spline_errors(0.05, e1);
	spline_errors(0.025, e2);
	/* |x''| = 0.219 / mm, |x'''| = 0.0512 / mm^2 */
	assert_true(e1[0] < 1e-4 && e1[1] < 1e-3 && e1[2] < 0.03);
	assert_true(e2[0] < e1[0] && e2[1] < e1[1] && e2[2] < e1[2]);
	assert_true(e2[2] > 0.0);

	helix_points(0.0, 0.05, MLIP_PATH_WIN + 16, pts, arc);
	assert_int_equal(
	    mlip_path_spline_fit(&spa, 3, (const double(*)[MLIP_MAX_AXES])pts, MLIP_PATH_WIN), 0);
	assert_int_equal(mlip_path_spline_fit(&spb, 3, (const double(*)[MLIP_MAX_AXES])(pts + 16),
	                                      MLIP_PATH_WIN),
	                 0);
	double jump = 0.0;
	for (int i = 1; i < MLIP_PATH_WIN - 1; i++) {
		double x[MLIP_MAX_AXES], xl[MLIP_MAX_AXES], xr[MLIP_MAX_AXES];
		struct mlip_path_point l, r;
		assert_int_equal(mlip_path_spline_eval(&spa, spa.s[i], 1, x, &l), 0);
		for (int k = 0; k < 3; k++) {
			assert_true(fabs(x[k] - pts[i][k]) < 1e-12); /* through the points */
		}
		/* C2: either side of a knot by 1e-7 mm, x' and x'' continuous (the local
		 * cubics of P4 meet with a kink) */
		assert_int_equal(mlip_path_spline_eval(&spa, spa.s[i] - 1e-7, 1, xl, &l), 0);
		assert_int_equal(mlip_path_spline_eval(&spa, spa.s[i] + 1e-7, 1, xr, &r), 0);
		for (int k = 0; k < 3; k++) {
			assert_true(fabs(l.d1[k] - r.d1[k]) < 1e-7); /* |x"| 2e-7 = 4.4e-8 */
			assert_true(fabs(l.d2[k] - r.d2[k]) < 1e-6);
			jump = fmax(jump, fabs(l.d3[k] - r.d3[k]));
		}
	}
	assert_true(jump > 0.0); /* the third derivative is piecewise constant */
	/* the window moved by 16 points: the same spline 16 points from every end */
	for (int i = 32; i < MLIP_PATH_WIN - 16; i++) {
		double xa[MLIP_MAX_AXES], xb[MLIP_MAX_AXES];
		struct mlip_path_point a, b;
		double u = spa.s[i] + 0.3 * (spa.s[i + 1] - spa.s[i]);
		assert_int_equal(mlip_path_spline_eval(&spa, u, 1, xa, &a), 0);
		assert_int_equal(mlip_path_spline_eval(&spb, u - spa.s[16], 1, xb, &b), 0);
		for (int k = 0; k < 3; k++) {
			assert_true(fabs(xa[k] - xb[k]) < 1e-12);
			assert_true(fabs(a.d2[k] - b.d2[k]) < 1e-8);
			assert_true(fabs(a.d3[k] - b.d3[k]) < 1e-6);
		}
	}
	/* by the parameter: the position's own derivatives (central differences
	 * by 1e-4 mm inside a segment: x' within 1e-9, x'' within 1e-6) */
	for (int i = 10; i < 20; i++) {
		double u = spa.s[i] + 0.4 * (spa.s[i + 1] - spa.s[i]), x0[MLIP_MAX_AXES];
		double xm[MLIP_MAX_AXES], xp[MLIP_MAX_AXES], e = 1e-4;
		struct mlip_path_point d;
		assert_int_equal(mlip_path_spline_eval(&spa, u, 0, x0, &d), 0);
		assert_int_equal(mlip_path_spline_eval(&spa, u - e, 0, xm, &d), 0);
		assert_int_equal(mlip_path_spline_eval(&spa, u + e, 0, xp, &d), 0);
		struct mlip_path_point c0;
		assert_int_equal(mlip_path_spline_eval(&spa, u, 0, x0, &c0), 0);
		for (int k = 0; k < 3; k++) {
			assert_true(fabs((xp[k] - xm[k]) / (2.0 * e) - c0.d1[k]) < 1e-9);
			assert_true(fabs((xp[k] - 2.0 * x0[k] + xm[k]) / (e * e) - c0.d2[k]) <
			            1e-6);
		}
	}
	/* refused: too few points, coincident points, a non-finite one */
	assert_int_equal(mlip_path_spline_fit(&spa, 3, (const double(*)[MLIP_MAX_AXES])pts, 1), -1);
	pts[5][0] = pts[4][0];
	pts[5][1] = pts[4][1];
	pts[5][2] = pts[4][2];
	assert_int_equal(mlip_path_spline_fit(&spa, 3, (const double(*)[MLIP_MAX_AXES])pts, 10),
	                 -1);
	pts[5][0] = NAN;
	assert_int_equal(mlip_path_spline_fit(&spa, 3, (const double(*)[MLIP_MAX_AXES])pts, 10),
	                 -1);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_chain_rule),  cmocka_unit_test(test_ranges_tight),
	    cmocka_unit_test(test_vmax_circle), cmocka_unit_test(test_from_points),
	    cmocka_unit_test(test_spline),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
