/*
 * test_smooth.c - the `smooth` filter (src/motion/smooth.c) against a brute-force
 * distance to the ORIGINAL polyline: every output segment, densely sampled,
 * stays within rho * budget of it, and each corner's tol_mm plus the
 * deviation of its legs (the halves of its two segments next to it, (19))
 * stays within the budget. Exact points stay exact, pass-through blocks
 * pass unchanged and in order, and the noise is really filtered.
 */
#include <float.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "../../tools/lib/blockiter.h"
#include "mlip/motion/planner.h"
#include "mlip/motion/smooth.h"

#define EPS         0.01
#define TIGHT       0.003 /* a run with its own, smaller tol_mm */
#define MAXB        20000
#define TIGHT_FIRST 1543 /* lines of the run with tol_mm = TIGHT */
#define TIGHT_LAST  1842

static struct mlip_block in[MAXB];
static size_t n_in;
static struct mlip_smooth SM;

static struct mlip_machine machine(void)
{
	struct mlip_machine m = {0};
	m.n_axes = 3;
	for (int k = 0; k < 3; k++) {
		m.axis[k].letter = (char)("XYZ"[k]);
		m.axis[k].max_accel = 1000.0;
		m.axis[k].max_vel = 200.0;
	}
	m.max_feed_mm_s = 200.0;
	m.tolerance_mm = EPS;
	m.period_s = 0.001;
	return m;
}

static double round4(double x)
{
	return round(x * 1e4) / 1e4;
}

static void add(double x, double y, double z, double feed, double tol, int rapid)
{
	struct mlip_block *b = &in[n_in];
	memset(b, 0, sizeof(*b));
	b->target[0] = x;
	b->target[1] = y;
	b->target[2] = z;
	b->feed_mm_s = feed;
	b->tol_mm = tol;
	b->rapid = (uint8_t)rapid;
	b->line = (uint32_t)n_in + 1;
	b->seq = n_in + 1;
	n_in++;
}

/* A CAM-like program: a helix in 0.02 mm chords rounded to 4 decimals, a
 * 90 degree corner, a rapid, a dwell, a wavy line in 0.15 mm steps with
 * noise of 0.01 mm (a run with its own tol), an exact stop, a feed change. */
static void program(void)
{
	n_in = 0;
	double R = 3.0;
	for (int i = 1; i <= 1500; i++) {
		double a = i * 0.02 / R;
		add(round4(R * cos(a)), round4(R * sin(a)), round4(0.0008 * i), 100.0, 0.0, 0);
	}
	double x0 = in[n_in - 1].target[0], y0 = in[n_in - 1].target[1],
	       z0 = in[n_in - 1].target[2];
	for (int i = 1; i <= 20; i++) {
		add(x0 + 0.1 * i, y0, z0, 100.0, 0.0, 0); /* then a 90 degree corner */
	}
	for (int i = 1; i <= 20; i++) {
		add(x0 + 2.0, y0 + 0.1 * i, z0, 100.0, 0.0, 0);
	}
	add(10.0, 10.0, 5.0, 100.0, 0.0, 1); /* rapid */
	in[n_in].kind = MLIP_BLOCK_DWELL;    /* dwell, at rest */
	in[n_in].dwell_s = 0.5;
	in[n_in].line = (uint32_t)n_in + 1;
	in[n_in].seq = n_in + 1;
	n_in++;
	uint64_t s = 12345;
	for (int i = 1; i <= 600; i++) {
		s = s * 6364136223846793005ULL + 1442695040888963407ULL;
		double noise = ((double)(s >> 11) / 9007199254740992.0 - 0.5) * 0.01;
		add(10.0 + 0.15 * i, 10.0, round4(5.0 + 0.3 * sin(0.02 * i) + noise), 100.0,
		    i <= 300 ? TIGHT : 0.0, 0);
		if (i == 450) {
			in[n_in - 1].exact_stop = 1;
		}
	}
	for (int i = 1; i <= 300; i++) {
		add(100.0, 10.0 + 0.1 * i, 5.0, 50.0, 0.0, 0);
	}
}

static struct mlip_block *smooth_all(size_t *n_out)
{
	struct mlip_machine m = machine();
	struct mlip_block *out;
	assert_int_equal(mlip_smooth_program(&m, in, n_in, &out, n_out), 0);
	return out;
}

/* distance from x to the original polyline (start + every move target) */
static double dist_to_original(const double *x)
{
	double best = INFINITY;
	double a[3] = {3.0, 0.0, 0.0};
	for (size_t i = 0; i < n_in; i++) {
		if (in[i].kind != MLIP_BLOCK_MOVE) {
			continue;
		}
		const double *b = in[i].target;
		double ab[3], ax[3], l2 = 0.0, t = 0.0;
		for (int k = 0; k < 3; k++) {
			ab[k] = b[k] - a[k];
			ax[k] = x[k] - a[k];
			l2 += ab[k] * ab[k];
			t += ab[k] * ax[k];
		}
		t = l2 > 0.0 ? fmin(fmax(t / l2, 0.0), 1.0) : 0.0;
		double d2 = 0.0;
		for (int k = 0; k < 3; k++) {
			double d = ax[k] - t * ab[k];
			d2 += d * d;
		}
		best = fmin(best, sqrt(d2));
		memcpy(a, b, sizeof(a));
	}
	return best;
}

static void test_within_band_brute_force(void **state)
{
	(void)state;
	program();
	size_t n;
	struct mlip_block *out = smooth_all(&n);
	assert_true(n > n_in); /* resampled */

	/* the deviation of each output segment, sampled every 1/16, and of its
	 * halves (a corner's legs lie in the halves next to its vertex, (19)) */
	double *dev = calloc(n, sizeof(double));
	double *dev0 = calloc(n, sizeof(double)), *dev1 = calloc(n, sizeof(double));
	double prev[3] = {3.0, 0.0, 0.0};
	double worst = 0.0, worst_tight = 0.0;
	for (size_t j = 0; j < n; j++) {
		if (out[j].kind != MLIP_BLOCK_MOVE) {
			continue;
		}
		for (int q = 0; q <= 16; q++) {
			double x[3];
			for (int k = 0; k < 3; k++) {
				x[k] = prev[k] + (out[j].target[k] - prev[k]) * q / 16.0;
			}
			double d = dist_to_original(x);
			dev[j] = fmax(dev[j], d);
			dev0[j] = q <= 8 ? fmax(dev0[j], d) : dev0[j];
			dev1[j] = q >= 8 ? fmax(dev1[j], d) : dev1[j];
		}
		memcpy(prev, out[j].target, sizeof(prev));
		worst = fmax(worst, dev[j]);
		if (out[j].line >= TIGHT_FIRST && out[j].line <= TIGHT_LAST) {
			worst_tight = fmax(worst_tight, dev[j]);
		}
	}
	/* inside the band, and the band is used (the noise is cut) */
	assert_true(worst <= MLIP_SMOOTH_RHO * EPS * (1 + 1e-9));
	assert_true(worst >= 0.5 * MLIP_SMOOTH_RHO * EPS);
	assert_true(worst_tight <= MLIP_SMOOTH_RHO * TIGHT * (1 + 1e-9));
	assert_true(worst_tight >= 0.3 * MLIP_SMOOTH_RHO * TIGHT);
	/* corner budget + smoothing of its legs' halves within the budget */
	for (size_t j = 0; j + 1 < n; j++) {
		if (out[j].kind != MLIP_BLOCK_MOVE || out[j + 1].kind != MLIP_BLOCK_MOVE) {
			continue;
		}
		double b = (out[j].line >= TIGHT_FIRST && out[j].line <= TIGHT_LAST) ? TIGHT : EPS;
		assert_true(out[j].tol_mm > 0.0);
		assert_true(out[j].tol_mm + fmax(dev1[j], dev0[j + 1]) <= b * (1 + 1e-9));
	}
	free(dev);
	free(dev0);
	free(dev1);
	free(out);
}

/* exact points stay exact, pass-through blocks are unchanged, in order */
static void test_exact_points_and_events(void **state)
{
	(void)state;
	program();
	size_t n;
	struct mlip_block *out = smooth_all(&n);
	size_t j = 0;
	for (size_t i = 0; i < n_in; i++) {
		const struct mlip_block *b = &in[i];
		int exact =
		    b->rapid || b->kind != MLIP_BLOCK_MOVE || b->exact_stop || i + 1 == n_in ||
		    (i + 1 < n_in && (in[i + 1].rapid || in[i + 1].kind != MLIP_BLOCK_MOVE ||
		                      in[i + 1].feed_mm_s != b->feed_mm_s));
		if (!exact) {
			continue;
		}
		/* find it in the output, in order */
		while (j < n && !(out[j].kind == b->kind &&
		                  (b->kind != MLIP_BLOCK_MOVE ||
		                   memcmp(out[j].target, b->target, sizeof(double) * 3) == 0))) {
			j++;
		}
		assert_true(j < n);
		assert_int_equal(out[j].rapid, b->rapid);
		assert_int_equal(out[j].exact_stop, b->exact_stop);
		if (b->kind == MLIP_BLOCK_DWELL) {
			assert_true(out[j].dwell_s == b->dwell_s);
		}
		j++;
	}
	assert_memory_equal(out[n - 1].target, in[n_in - 1].target, sizeof(double) * 3);
	free(out);
}

/* the helix's rounding noise is filtered: its vertices turn smoothly */
static void test_noise_filtered(void **state)
{
	(void)state;
	program();
	size_t n;
	struct mlip_block *out = smooth_all(&n);
	/* largest change of turning angle between consecutive vertices, on
	 * the helix (lines 100..1400), before and after */
	double worst_in = 0.0, worst_out = 0.0;
	for (int pass = 0; pass < 2; pass++) {
		const struct mlip_block *b = pass ? out : in;
		size_t m = pass ? n : n_in;
		double last_turn = -1.0;
		for (size_t i = 2; i < m; i++) {
			if (b[i].line < 100 || b[i].line > 1400) {
				continue;
			}
			double u[3], v[3], lu = 0.0, lv = 0.0, c = 0.0;
			for (int k = 0; k < 3; k++) {
				u[k] = b[i - 1].target[k] - b[i - 2].target[k];
				v[k] = b[i].target[k] - b[i - 1].target[k];
				lu += u[k] * u[k];
				lv += v[k] * v[k];
				c += u[k] * v[k];
			}
			/* curvature at the vertex: turn / mean length */
			double turn =
			    acos(fmin(1.0, c / sqrt(lu * lv))) / (0.5 * (sqrt(lu) + sqrt(lv)));
			if (last_turn >= 0.0) {
				double *w = pass ? &worst_out : &worst_in;
				*w = fmax(*w, fabs(turn - last_turn));
			}
			last_turn = turn;
		}
	}
	/* true curvature 1/3 mm^-1: rounding makes it jump by 0.8, smoothing by 0.04 */
	print_message("curvature jumps: %g before, %g after\n", worst_in, worst_out);
	assert_true(worst_in > 0.5);
	assert_true(worst_out < 0.1 * worst_in);
	free(out);
}

/* Random programs, for the general case: segments from 0.0001 to 5 mm,
 * turns from noise to reversals, rapids, arcs' smaller budgets; the bound
 * checked by brute force on every output segment. */
static void test_random_programs(void **state)
{
	(void)state;
	uint64_t s = 777;
	for (int seed = 0; seed < 2; seed++) {
		n_in = 0;
		double x[3] = {3.0, 0.0, 0.0}, e[3] = {1.0, 0.0, 0.0};
		for (int i = 0; i < 2000; i++) {
			double r[4];
			for (int k = 0; k < 4; k++) {
				s = s * 6364136223846793005ULL + 1442695040888963407ULL;
				r[k] = (double)(s >> 11) / 9007199254740992.0;
			}
			double len = 1e-4 * pow(5e4, r[0]); /* 0.0001 .. 5 mm */
			double turn = r[1] < 0.7 ? 0.01 : r[1] < 0.95 ? 0.3 : 3.0; /* rad, scale */
			for (int k = 0; k < 3; k++) {
				e[k] += turn * (r[(k + 2) % 4] - 0.5);
			}
			double n2 = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
			for (int k = 0; k < 3; k++) {
				e[k] /= n2;
				x[k] += len * e[k];
			}
			double tol = r[3] < 0.2 ? 0.9 * EPS : r[3] < 0.25 ? TIGHT : 0.0;
			add(round4(x[0]), round4(x[1]), round4(x[2]), 100.0, tol, i % 700 == 699);
		}
		size_t n;
		struct mlip_block *out = smooth_all(&n);
		double *dev = calloc(n, sizeof(double));
		double *dev0 = calloc(n, sizeof(double)), *dev1 = calloc(n, sizeof(double));
		double prev[3] = {3.0, 0.0, 0.0}, worst = 0.0;
		for (size_t j = 0; j < n; j++) {
			for (int q = 0; q <= 8; q++) {
				double y[3];
				for (int k = 0; k < 3; k++) {
					y[k] = prev[k] + (out[j].target[k] - prev[k]) * q / 8.0;
				}
				double d = dist_to_original(y);
				dev[j] = fmax(dev[j], d);
				dev0[j] = q <= 4 ? fmax(dev0[j], d) : dev0[j];
				dev1[j] = q >= 4 ? fmax(dev1[j], d) : dev1[j];
			}
			memcpy(prev, out[j].target, sizeof(prev));
			assert_true(dev[j] <= MLIP_SMOOTH_RHO * EPS * (1 + 1e-9));
			worst = fmax(worst, dev[j]);
		}
		assert_true(worst >= 0.3 * MLIP_SMOOTH_RHO * EPS); /* it did smooth */
		for (size_t j = 0; j + 1 < n; j++) {
			assert_true(out[j].tol_mm > 0.0);
			assert_true(out[j].tol_mm + fmax(dev1[j], dev0[j + 1]) <= EPS * (1 + 1e-9));
		}
		assert_memory_equal(out[n - 1].target, in[n_in - 1].target, sizeof(double) * 3);
		free(dev);
		free(dev0);
		free(dev1);
		free(out);
	}
}

/* The smooth strategy's corner (corner.c): any acceleration in the polygon
 * keeps the paper's guarantees, so check them on random corners: |a_k| <=
 * A_k, deviation |a| t^2 / 8 <= eps (17)(18), l <= d / 2 (19), v <= caps
 * (20), a on the polygon's boundary, its slower end never slower than
 * the LP vertex's (mpct's corner is one of the candidates), and beta above
 * the line's limit unless it is the LP vertex. Relative
 * tolerance 1e-12 on each bound. */
static void test_corner_choice(void **state)
{
	(void)state;
	uint64_t s = 12345;
	int sym = 0, tested = 0;
	for (int it = 0; it < 20000; it++) {
		double r[16];
		for (int k = 0; k < 16; k++) {
			s = s * 6364136223846793005ULL + 1442695040888963407ULL;
			r[k] = (double)(s >> 11) / 9007199254740992.0;
		}
		int n = 2 + (int)(r[0] * 2.0);
		double es[3] = {0}, ee[3] = {0}, A[3], ns = 0.0, ne = 0.0;
		double turn = r[1] < 0.5 ? 0.02 : r[1] < 0.8 ? 0.5 : 4.0;
		for (int k = 0; k < n; k++) {
			es[k] = r[2 + k] - 0.5;
			ee[k] = es[k] + turn * (r[5 + k] - 0.5);
			ns += es[k] * es[k];
			A[k] = 500.0 + 5500.0 * r[8 + k];
		}
		ns = sqrt(ns);
		for (int k = 0; k < n; k++) {
			es[k] /= ns;
		}
		for (int k = 0; k < n; k++) {
			ne += ee[k] * ee[k];
		}
		ne = sqrt(ne);
		for (int k = 0; k < n; k++) {
			ee[k] /= ne;
		}
		double ds = 1e-3 * pow(1e4, r[11]), de = 1e-3 * pow(1e4, r[12]);
		double eps = 0.001 + 0.01 * r[13], vs = 10.0 + 200.0 * r[14],
		       ve = 10.0 + 200.0 * r[15];
		struct mlip_corner c, m;
		mlip_corner_plan(n, MLIP_STRATEGY_SMOOTH, es, ee, ds, de, A, eps, vs, ve, 0.001,
		                 &c);
		mlip_corner_plan(n, MLIP_STRATEGY_MPCT, es, ee, ds, de, A, eps, vs, ve, 0.001, &m);
		if (m.t_s == 0.0) {
			continue; /* collinear: both pass straight */
		}
		tested++;
		double a2 = 0.0, amax = 0.0;
		for (int k = 0; k < n; k++) {
			double ak = c.alpha_mm_s2 * ee[k] - c.beta_mm_s2 * es[k];
			/* plus the rounding of a difference of two terms of size alpha */
			double round_off = 8.0 * DBL_EPSILON * (c.alpha_mm_s2 + c.beta_mm_s2);
			assert_true(fabs(ak) <= A[k] * (1.0 + 1e-12) + round_off);
			amax = fmax(amax, fabs(ak) / A[k]);
			a2 += ak * ak;
		}
		assert_true(amax >= 1.0 - 1e-9);
		assert_true(sqrt(a2) * c.t_s * c.t_s / 8.0 <= eps * (1.0 + 1e-12));
		assert_true(c.ls_mm <= 0.5 * ds * (1.0 + 1e-12) &&
		            c.le_mm <= 0.5 * de * (1.0 + 1e-12));
		assert_true(c.vs_mm_s <= vs * (1.0 + 1e-12) && c.ve_mm_s <= ve * (1.0 + 1e-12));
		/* 1e-9: the LP vertex recomputed in another order, and the choice's own margin */
		assert_true(fmin(c.vs_mm_s, c.ve_mm_s) >=
		            fmin(m.vs_mm_s, m.ve_mm_s) * (1.0 - 1e-9));
		sym += fabs(c.alpha_mm_s2 - c.beta_mm_s2) <= 1e-9 * c.alpha_mm_s2;
		/* B = v_s^2 - 2 a l_s > 0 (beta above the line's own limit), or the
		 * LP vertex itself: the corner can take what a line fails to shed */
		double a_line = INFINITY;
		for (int k = 0; k < n; k++) {
			a_line = es[k] != 0.0 ? fmin(a_line, A[k] / fabs(es[k])) : a_line;
		}
		assert_true(c.beta_mm_s2 > a_line ||
		            (fabs(c.beta_mm_s2 - m.beta_mm_s2) <= 1e-9 * m.beta_mm_s2 &&
		             fabs(c.alpha_mm_s2 - m.alpha_mm_s2) <= 1e-9 * m.alpha_mm_s2));
	}
	assert_true(tested > 15000);
	assert_true(sym > 100); /* it does pick the symmetric corner */
}

static void test_full_and_bad_input(void **state)
{
	(void)state;
	struct mlip_machine m = machine();
	double start[MLIP_MAX_AXES] = {0};
	assert_int_equal(mlip_smooth_init(&SM, &m, start), MLIP_OK);
	struct mlip_block b = {0};
	b.feed_mm_s = 100.0;
	int full_at = -1;
	for (int i = 1; i < 10 * MLIP_SMOOTH_CAP; i++) {
		b.target[0] = 0.05 * i;
		b.target[1] = 0.001 * sin(i);
		if (mlip_smooth_push(&SM, &b) == MLIP_E_FULL) {
			full_at = i;
			break;
		}
	}
	/* bounded memory: the window fills when nobody pops */
	assert_true(full_at > 0 && full_at <= MLIP_SMOOTH_CAP);
	struct mlip_block o;
	int popped = 0;
	while (mlip_smooth_pop(&SM, &o) == MLIP_OK) {
		popped++;
	}
	assert_true(popped > 0);
	assert_int_equal(mlip_smooth_push(&SM, &b), MLIP_OK);
	b.target[2] = NAN;
	assert_int_equal(mlip_smooth_push(&SM, &b), MLIP_E_RANGE);
	m.tolerance_mm = 0.0;
	assert_int_equal(mlip_smooth_init(&SM, &m, start), MLIP_E_INVALID);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_within_band_brute_force),
	    cmocka_unit_test(test_exact_points_and_events),
	    cmocka_unit_test(test_noise_filtered),
	    cmocka_unit_test(test_random_programs),
	    cmocka_unit_test(test_corner_choice),
	    cmocka_unit_test(test_full_and_bad_input),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
