/*
 * test_scurve.c - jerk-limited speed changes (src/motion/scurve.c, S1-S4):
 * the braking bound is the exact inverse of the distance, line profiles end
 * exactly where and how they must inside every limit at every instant and
 * at 1 ms samples, and the stop reaches rest from any state.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "mlip/motion/scurve.h"

static uint64_t rng = 88172645463325252ull;

static double uni(double lo, double hi)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return lo + (hi - lo) * (double)(rng >> 11) * (1.0 / 9007199254740992.0);
}

static const double AJ[][2] = {{1000.0, 1e5}, {1000.0, 1e4}, {300.0, 1e6}, {6000.0, 2e4}};

static void test_brake_inverse(void **state)
{
	(void)state;
	const double v1s[] = {0.0, 0.5, 5.0, 50.0, 200.0};
	const double ds[] = {1e-5, 1e-3, 0.01, 0.1, 1.0, 10.0, 300.0};
	for (size_t c = 0; c < sizeof(AJ) / sizeof(AJ[0]); c++) {
		double a = AJ[c][0], j = AJ[c][1];
		for (size_t i = 0; i < sizeof(v1s) / sizeof(v1s[0]); i++) {
			for (size_t k = 0; k < sizeof(ds) / sizeof(ds[0]); k++) {
				double v1 = v1s[i], d = ds[k];
				double v0 = mlip_scurve_brake_v0(v1, d, a, j);
				assert_true(v0 > v1);
				/* the exact inverse within rounding of the speed, both sides
				 * (near v1 the distance is steep in v0: compare speeds) */
				double dv = 1e-12 * (v0 > 1.0 ? v0 : 1.0);
				double lo = v0 - dv > v1 ? v0 - dv : v1;
				assert_true(mlip_scurve_dv_dist(lo, v1, a, j) <= d);
				assert_true(mlip_scurve_dv_dist(v0 + dv, v1, a, j) >= d);
				/* and the largest: a little more needs more room */
				assert_true(mlip_scurve_dv_dist(v0 + 1e3 * dv, v1, a, j) > d);
			}
		}
		assert_true(mlip_scurve_brake_v0(7.0, 0.0, a, j) == 7.0);
	}
}

/* Sample a profile finely: every limit at every instant, the end exact. */
static void check_profile(const struct mlip_scurve *c, double v0, double a, double j, double vtop)
{
	for (int k = 0; k < c->n; k++) {
		assert_true(fabs(c->j[k]) <= j);
		assert_true(c->t[k] > 0.0);
	}
	double prev_s = -1.0;
	for (int i = 0; i <= 4000; i++) {
		double s, v, acc;
		mlip_scurve_eval(c, c->total_s * i / 4000.0, &s, &v, &acc);
		assert_true(fabs(acc) <= a * (1.0 + 1e-9));
		assert_true(v >= -1e-9 * (v0 + vtop + 1.0));
		assert_true(v <= vtop * (1.0 + 1e-9) + 1e-12);
		assert_true(s >= prev_s - 1e-12); /* never backward */
		prev_s = s;
	}
}

static void test_line_profiles(void **state)
{
	(void)state;
	for (int it = 0; it < 20000; it++) {
		double a = uni(100.0, 6000.0), j = exp(uni(log(1e3), log(1e7)));
		double v0 = uni(0.0, 1.0) < 0.2 ? 0.0 : uni(0.0, 200.0);
		double v1 = uni(0.0, 1.0) < 0.2 ? 0.0 : uni(0.0, 200.0);
		double vmax = (v0 > v1 ? v0 : v1) + uni(0.0, 100.0);
		double need = mlip_scurve_dv_dist(v0, v1, a, j);
		double d = need * (1.0 + (uni(0.0, 1.0) < 0.1 ? 0.0 : exp(uni(-12.0, 4.0))));
		struct mlip_scurve c;
		assert_int_equal(mlip_scurve_line(&c, v0, v1, d, vmax, a, j), 0);
		double scale = d > 1.0 ? d : 1.0;
		assert_true(fabs(c.end_s - d) <= 1e-9 * scale);
		assert_true(fabs(c.end_v - v1) <= 1e-9 * (vmax + 1.0));
		assert_true(fabs(c.end_a) <= 1e-9 * a);
		check_profile(&c, v0, a, j, vmax);
		/* shorter than the change needs: refused */
		if (need > 1e-9) {
			assert_int_equal(
			    mlip_scurve_line(&c, v0, v1, need * (1.0 - 1e-6), vmax, a, j), -1);
		}
	}
	struct mlip_scurve c;
	assert_int_equal(mlip_scurve_line(&c, 1.0, 1.0, NAN, 10.0, 1000.0, 1e5), -1);
	assert_int_equal(mlip_scurve_line(&c, 1.0, 1.0, 1.0, 10.0, 0.0, 1e5), -1);
}

/* The third differences of 1 ms samples are means of the jerk: within j. */
static void test_samples_keep_jerk(void **state)
{
	(void)state;
	const double T = 1e-3;
	for (size_t k = 0; k < sizeof(AJ) / sizeof(AJ[0]); k++) {
		double a = AJ[k][0], j = AJ[k][1];
		struct mlip_scurve c;
		assert_int_equal(mlip_scurve_line(&c, 3.0, 0.0, 40.0, 200.0, a, j), 0);
		double x[4] = {0};
		double worst = 0.0;
		int n = (int)(c.total_s / T) + 4;
		for (int i = 0; i < n; i++) {
			double s, v, acc;
			mlip_scurve_eval(&c, i * T, &s, &v, &acc);
			x[0] = x[1], x[1] = x[2], x[2] = x[3], x[3] = s;
			if (i >= 3) {
				double d3 =
				    fabs(x[3] - 3.0 * x[2] + 3.0 * x[1] - x[0]) / (T * T * T);
				worst = d3 > worst ? d3 : worst;
			}
		}
		assert_true(worst <= j * (1.0 + 1e-6));
		if (a / j >= 3.0 * T) {
			/* a ramp of three periods or more: a sample sees all of j */
			assert_true(worst >= j * (1.0 - 1e-6));
		}
	}
}

static void test_stop(void **state)
{
	(void)state;
	for (int it = 0; it < 20000; it++) {
		double a = uni(100.0, 6000.0), j = exp(uni(log(1e3), log(1e7)));
		double v = uni(0.0, 1.0) < 0.1 ? 0.0 : uni(0.0, 200.0);
		double a0 = uni(-a, a);
		struct mlip_scurve c;
		mlip_scurve_stop(&c, v, a0, a, j);
		assert_true(fabs(c.end_v) <= 1e-9 * (v + 1.0));
		if (!(a0 < 0.0 && v <= a0 * a0 / (2.0 * j))) {
			assert_true(fabs(c.end_a) <= 1e-9 * a);
		}
		check_profile(&c, v, a, j, v + a0 * a0 / (2.0 * j) + 1e-9);
	}
	/* from a zero acceleration the stop is the speed change to 0 (S2) */
	struct mlip_scurve c;
	mlip_scurve_stop(&c, 120.0, 0.0, 1000.0, 1e5);
	assert_true(fabs(c.end_s - mlip_scurve_dv_dist(120.0, 0.0, 1000.0, 1e5)) <= 1e-9 * c.end_s);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_brake_inverse),
	    cmocka_unit_test(test_line_profiles),
	    cmocka_unit_test(test_samples_keep_jerk),
	    cmocka_unit_test(test_stop),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
