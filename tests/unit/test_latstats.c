/*
 * test_latstats.c - the statistics of mlip-latency on known data: bins and
 * their edges, overflow, min/mean/max, nearest-rank percentiles (the bin's
 * upper edge capped at max), and seeded random data checked against an exact
 * sort, both sides of the one-bin bound.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "latstats.h"

/* cmocka 1.1.5 has no assert_double_equal (assert_float_equal casts to float) */
#define assert_near(a, b, tol) assert_near_at((a), (b), (tol), __FILE__, __LINE__)
static void assert_near_at(double a, double b, double tol, const char *file, int line)
{
	if (!(fabs(a - b) <= tol)) {
		print_error("%.17g != %.17g (tol %g)\n", a, b, tol);
		_fail(file, line);
	}
}

#define US 1000 /* ns: 1 us bins, as the tool uses */
#define NB 200
static uint64_t bins[NB];

static uint64_t binned(const struct mlip_latstats *s)
{
	uint64_t c = 0;
	for (uint32_t b = 0; b < s->nbins; b++) {
		c += s->bins[b];
	}
	return c;
}

static void test_empty(void **state)
{
	(void)state;
	struct mlip_latstats s;
	bins[3] = 42; /* init zeroes the caller's storage */
	mlip_latstats_init(&s, bins, NB, US);
	assert_int_equal(bins[3], 0);
	assert_int_equal(s.count, 0);
	assert_int_equal(s.overflow, 0);
	assert_int_equal(mlip_latstats_min_ns(&s), 0);
	assert_int_equal(s.max_ns, 0);
	assert_near(mlip_latstats_mean_ns(&s), 0.0, 0.0);
	int ov = 7;
	assert_int_equal(mlip_latstats_percentile_ns(&s, 50.0, &ov), 0);
	assert_int_equal(ov, 0);
	assert_int_equal(mlip_latstats_count_below(&s, NB), 0);
}

/* A sample on a bin edge belongs to the bin above it: truncation, as
 * cyclictest's whole microseconds. */
static void test_bin_edges(void **state)
{
	(void)state;
	struct mlip_latstats s;
	mlip_latstats_init(&s, bins, NB, US);
	mlip_latstats_add(&s, 0);
	mlip_latstats_add(&s, 999);
	mlip_latstats_add(&s, 1000);
	mlip_latstats_add(&s, 1999);
	mlip_latstats_add(&s, 2000);
	assert_int_equal(bins[0], 2);
	assert_int_equal(bins[1], 2);
	assert_int_equal(bins[2], 1);
	assert_int_equal(bins[3], 0);
	assert_int_equal(s.count, 5);
	assert_int_equal(mlip_latstats_min_ns(&s), 0);
	assert_int_equal(s.max_ns, 2000);
	/* last bin and first overflow */
	mlip_latstats_add(&s, (int64_t)NB * US - 1);
	assert_int_equal(bins[NB - 1], 1);
	assert_int_equal(s.overflow, 0);
	mlip_latstats_add(&s, (int64_t)NB * US);
	assert_int_equal(s.overflow, 1);
	assert_int_equal(binned(&s) + s.overflow, s.count);
}

/* 100 samples in the middle of bins 0..99: (k + 0.5) us. */
static void test_known_percentiles(void **state)
{
	(void)state;
	struct mlip_latstats s;
	mlip_latstats_init(&s, bins, NB, US);
	for (int k = 0; k < 100; k++) {
		mlip_latstats_add(&s, k * US + 500);
	}
	assert_int_equal(s.count, 100);
	assert_int_equal(mlip_latstats_min_ns(&s), 500);
	assert_int_equal(s.max_ns, 99500);
	assert_near(mlip_latstats_mean_ns(&s), 50000.0, 1e-9);
	int ov = 1;
	/* rank 50 is 49.5 us, in bin 49: reported as its upper edge 50 us */
	assert_int_equal(mlip_latstats_percentile_ns(&s, 50.0, &ov), 50000);
	assert_int_equal(ov, 0);
	/* rank 99: 98.5 us -> 99 us */
	assert_int_equal(mlip_latstats_percentile_ns(&s, 99.0, NULL), 99000);
	/* rank 100 (any p > 99): bin 99, upper edge 100 us, capped at max 99.5 */
	assert_int_equal(mlip_latstats_percentile_ns(&s, 99.9, NULL), 99500);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 99.99, NULL), 99500);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 100.0, NULL), 99500);
	/* p0 and below are rank 1: 0.5 us -> 1 us; above 100 is 100 */
	assert_int_equal(mlip_latstats_percentile_ns(&s, 0.0, NULL), 1000);
	assert_int_equal(mlip_latstats_percentile_ns(&s, -5.0, NULL), 1000);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 250.0, NULL), 99500);
	/* rank = ceil(p n / 100): 50.5 % of 100 is rank 51 -> 50.5 us -> 51 us */
	assert_int_equal(mlip_latstats_percentile_ns(&s, 50.5, NULL), 51000);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 50.01, NULL), 51000);
}

/* 99.99 % of 10000 samples is rank 9999 exactly: no rounding up to 10000. */
static void test_rank_rounding(void **state)
{
	(void)state;
	struct mlip_latstats s;
	mlip_latstats_init(&s, bins, NB, US);
	mlip_latstats_add_n(&s, 1500, 9999);
	mlip_latstats_add(&s, 7500);
	assert_int_equal(s.count, 10000);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 99.99, NULL), 2000);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 99.999, NULL), 7500);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 99.9, NULL), 2000);
	/* a single sample: every percentile is that sample's bound, capped */
	mlip_latstats_init(&s, bins, NB, US);
	mlip_latstats_add(&s, 12345);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 50.0, NULL), 12345);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 99.99, NULL), 12345);
	assert_int_equal(mlip_latstats_min_ns(&s), 12345);
}

/* Samples beyond the last bin: counted, never binned; a percentile whose
 * rank falls there is max, flagged. */
static void test_overflow(void **state)
{
	(void)state;
	struct mlip_latstats s;
	mlip_latstats_init(&s, bins, 10, US); /* 0..10 us */
	for (int k = 0; k < 5; k++) {
		mlip_latstats_add(&s, k * US + 100);
	}
	mlip_latstats_add(&s, 10 * US); /* first value past the last bin */
	mlip_latstats_add(&s, 25 * US);
	mlip_latstats_add(&s, 40 * US);
	mlip_latstats_add(&s, 1000 * US);
	mlip_latstats_add(&s, 30 * US);
	assert_int_equal(s.count, 10);
	assert_int_equal(s.overflow, 5);
	assert_int_equal(binned(&s), 5);
	assert_int_equal(bins[10], 0); /* storage past nbins untouched */
	assert_int_equal(mlip_latstats_count_below(&s, 10), 5);
	assert_int_equal(mlip_latstats_count_below(&s, 1000), 5);
	assert_int_equal(s.max_ns, 1000 * US);
	int ov = 1;
	assert_int_equal(mlip_latstats_percentile_ns(&s, 50.0, &ov), 5 * US); /* rank 5 */
	assert_int_equal(ov, 0);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 60.0, &ov), 1000 * US); /* rank 6 */
	assert_int_equal(ov, 1);
	double sum = 0;
	for (int k = 0; k < 5; k++) {
		sum += k * US + 100;
	}
	sum += 10 * US + 25 * US + 40 * US + 1000 * US + 30 * US;
	assert_near(mlip_latstats_mean_ns(&s), sum / 10.0, 1e-9);
}

/* A histogram shown with fewer bins than kept: its overflow is the rest. */
static void test_count_below(void **state)
{
	(void)state;
	struct mlip_latstats s;
	mlip_latstats_init(&s, bins, NB, US);
	for (int k = 0; k < 50; k++) {
		mlip_latstats_add(&s, k * US);
	}
	assert_int_equal(mlip_latstats_count_below(&s, 0), 0);
	assert_int_equal(mlip_latstats_count_below(&s, 1), 1);
	assert_int_equal(mlip_latstats_count_below(&s, 20), 20);
	assert_int_equal(s.count - mlip_latstats_count_below(&s, 20), 30);
	assert_int_equal(mlip_latstats_count_below(&s, 50), 50);
	assert_int_equal(mlip_latstats_count_below(&s, UINT32_MAX), 50);
}

static void test_negative_and_add_n(void **state)
{
	(void)state;
	struct mlip_latstats a, b;
	static uint64_t bins_b[NB];
	mlip_latstats_init(&a, bins, NB, US);
	mlip_latstats_init(&b, bins_b, NB, US);
	mlip_latstats_add(&a, -300); /* clock oddity: taken as 0 */
	assert_int_equal(bins[0], 1);
	assert_int_equal(mlip_latstats_min_ns(&a), 0);
	mlip_latstats_add_n(&a, 3300, 0); /* nothing */
	assert_int_equal(a.count, 1);
	for (int i = 0; i < 3; i++) {
		mlip_latstats_add(&a, 3300);
	}
	mlip_latstats_add(&b, -1);
	mlip_latstats_add_n(&b, 3300, 3);
	assert_int_equal(a.count, b.count);
	assert_int_equal(a.sum_ns, b.sum_ns);
	assert_int_equal(a.max_ns, b.max_ns);
	assert_memory_equal(bins, bins_b, sizeof(bins));
}

/* Other bin widths: 10 us bins. */
static void test_bin_width(void **state)
{
	(void)state;
	struct mlip_latstats s;
	mlip_latstats_init(&s, bins, NB, 10 * US);
	mlip_latstats_add(&s, 9999);
	mlip_latstats_add(&s, 10000);
	mlip_latstats_add(&s, 55000);
	assert_int_equal(bins[0], 1);
	assert_int_equal(bins[1], 1);
	assert_int_equal(bins[5], 1);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 33.0, NULL), 10000);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 34.0, NULL), 20000);
	assert_int_equal(mlip_latstats_percentile_ns(&s, 100.0, NULL), 55000);
}

static int cmp_i64(const void *x, const void *y)
{
	int64_t a = *(const int64_t *)x, b = *(const int64_t *)y;
	return (a > b) - (a < b);
}

/* Seeded random data against an exact sort: min, max, mean exact; every
 * percentile P satisfies exact <= P < exact + one bin (both sides), P <= max,
 * and P never decreases with p. */
static void test_random_against_sort(void **state)
{
	(void)state;
	enum { N = 20011 };
	static int64_t v[N];
	static const double ps[] = {0, 1, 10, 25, 50, 75, 90, 99, 99.5, 99.9, 99.99, 99.999, 100};
	uint64_t x = 88172645463325252ULL;
	for (int trial = 0; trial < 8; trial++) {
		struct mlip_latstats s;
		mlip_latstats_init(&s, bins, NB, US);
		int n = N - trial * 1237;
		double sum = 0;
		for (int i = 0; i < n; i++) {
			x ^= x << 13;
			x ^= x >> 7;
			x ^= x << 17;
			/* long-tailed, like latency: mostly small, some large, some past the bins
			 */
			uint64_t u = x % 1000000;
			int64_t ns = u < 900000 ? (int64_t)(u % 20000)
			                        : (int64_t)(u * (uint64_t)(trial + 1) / 4);
			v[i] = ns;
			sum += (double)ns;
			mlip_latstats_add(&s, ns);
		}
		qsort(v, (size_t)n, sizeof(v[0]), cmp_i64);
		assert_int_equal(s.count, n);
		assert_int_equal(binned(&s) + s.overflow, s.count);
		assert_int_equal(mlip_latstats_min_ns(&s), v[0]);
		assert_int_equal(s.max_ns, v[n - 1]);
		assert_near(mlip_latstats_mean_ns(&s), sum / n, 1e-6);
		int64_t prev = 0;
		for (size_t k = 0; k < sizeof(ps) / sizeof(ps[0]); k++) {
			int ov;
			int64_t p = mlip_latstats_percentile_ns(&s, ps[k], &ov);
			uint64_t r = (uint64_t)ceil(ps[k] / 100.0 * n - 1e-9);
			if (r < 1) {
				r = 1;
			}
			int64_t exact = v[r - 1];
			assert_true(p >= exact);
			assert_true(p <= s.max_ns);
			assert_true(p >= prev);
			if (ov) {
				assert_true(exact >= (int64_t)NB * US);
				assert_int_equal(p, s.max_ns);
			} else {
				assert_true(p - exact <= US);
				assert_true(exact < (int64_t)NB * US);
			}
			prev = p;
		}
	}
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_empty),
	    cmocka_unit_test(test_bin_edges),
	    cmocka_unit_test(test_known_percentiles),
	    cmocka_unit_test(test_rank_rounding),
	    cmocka_unit_test(test_overflow),
	    cmocka_unit_test(test_count_below),
	    cmocka_unit_test(test_negative_and_add_n),
	    cmocka_unit_test(test_bin_width),
	    cmocka_unit_test(test_random_against_sort),
	};
	return cmocka_run_group_tests_name("latstats", tests, NULL, NULL);
}
