/*
 * test_check.c - the contour and order measures of tools/lib/check.c
 * against brute force: on dense paths that come back near themselves (a
 * zigzag raster whose teeth nearly touch, a spiral whose turns are closer
 * than eps, a loop run three times and then backwards, random walks), the
 * streamed, windowed, box-pruned distance of every sample equals the minimum
 * over every segment of the whole polyline to 1e-12 mm; traces that follow
 * the path have no sample out of order; a step back or a skip is caught.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "../../tools/lib/check.h"
#include "mlip/motion/planner.h"

#define EPS      0.01
#define EXACT_MM 1e-12

static uint64_t rng = 0x9E3779B97F4A7C15ULL;
static double urand(void)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return (double)(rng >> 11) / 9007199254740992.0;
}

struct path {
	int n;
	size_t np, cap;
	double *pts;
	double *arc; /* path position of each point */
};

static void path_add(struct path *p, const double *x)
{
	if (p->np == p->cap) {
		p->cap = p->cap ? 2 * p->cap : 1024;
		p->pts = realloc(p->pts, sizeof(double) * (size_t)p->n * p->cap);
		p->arc = realloc(p->arc, sizeof(double) * p->cap);
		assert_non_null(p->pts);
		assert_non_null(p->arc);
	}
	double s = 0.0;
	if (p->np > 0) {
		const double *q = p->pts + (p->np - 1) * (size_t)p->n;
		for (int k = 0; k < p->n; k++) {
			s += (x[k] - q[k]) * (x[k] - q[k]);
		}
		s = p->arc[p->np - 1] + sqrt(s);
	}
	memcpy(p->pts + p->np * (size_t)p->n, x, sizeof(double) * (size_t)p->n);
	p->arc[p->np++] = s;
}

static void path_free(struct path *p)
{
	free(p->pts);
	free(p->arc);
}

/* Raster of rows along x, each a sawtooth of `seg` mm segments at +-60
 * degrees (sharp corners), rows `gap` mm further apart than the teeth are
 * high, so that a row's teeth come within gap of the next row's. */
static struct path zigzag(int rows, double row_mm, double seg, double gap)
{
	struct path p = {.n = 2};
	double dx = seg * 0.5, dy = seg * sqrt(3.0) / 2.0;
	int teeth = (int)(row_mm / dx);
	double x[2] = {0.0, 0.0};
	path_add(&p, x);
	for (int r = 0; r < rows; r++) {
		double dir = r % 2 ? -1.0 : 1.0, y0 = r * (dy + gap);
		for (int i = 1; i <= teeth; i++) {
			x[0] += dir * dx;
			x[1] = y0 + (i % 2 ? dy : 0.0);
			path_add(&p, x);
		}
		if (r + 1 < rows) {
			x[1] = (r + 1) * (dy + gap); /* up to the next row */
			path_add(&p, x);
		}
	}
	return p;
}

/* Archimedean spiral: turns `pitch` apart, chords of `seg` mm. */
static struct path spiral(double r0, double pitch, double turns, double seg)
{
	struct path p = {.n = 2};
	double th = 0.0;
	while (th < 2.0 * M_PI * turns) {
		double r = r0 + pitch * th / (2.0 * M_PI);
		double x[2] = {r * cos(th), r * sin(th)};
		path_add(&p, x);
		th += seg / r;
	}
	return p;
}

/* A 5 mm square in 0.25 mm segments, three times round, then back along
 * itself to the start: every pass lies on every other one. */
static struct path retrace(void)
{
	struct path p = {.n = 3};
	double c[5][2] = {{0, 0}, {5, 0}, {5, 5}, {0, 5}, {0, 0}};
	double x[3] = {0, 0, 1};
	path_add(&p, x);
	for (int lap = 0; lap < 3; lap++) {
		for (int e = 0; e < 4; e++) {
			for (int i = 1; i <= 20; i++) {
				x[0] = c[e][0] + (c[e + 1][0] - c[e][0]) * i / 20.0;
				x[1] = c[e][1] + (c[e + 1][1] - c[e][1]) * i / 20.0;
				path_add(&p, x);
			}
		}
	}
	size_t fwd = p.np;
	for (size_t i = fwd - 1; i-- > 0;) {
		double y[3];
		memcpy(y, p.pts + i * 3, sizeof(y));
		path_add(&p, y);
	}
	return p;
}

/* n-D random walk in a box of `box` mm (reflected at its walls): crosses
 * and touches itself everywhere. */
static struct path random_walk(int n, size_t segs, double box)
{
	struct path p = {.n = n};
	double x[MLIP_MAX_AXES] = {0};
	path_add(&p, x);
	for (size_t i = 0; i < segs; i++) {
		double len = 0.02 + 0.5 * urand();
		for (int k = 0; k < n; k++) {
			x[k] += len * (2.0 * urand() - 1.0);
			if (fabs(x[k]) > box) {
				x[k] = copysign(2.0 * box - fabs(x[k]), x[k]);
			}
		}
		path_add(&p, x);
	}
	return p;
}

/* The point at path position s. */
static void path_at(const struct path *p, double s, double *x)
{
	size_t lo = 0, hi = p->np - 1;
	while (hi - lo > 1) {
		size_t mid = (lo + hi) / 2;
		if (p->arc[mid] <= s) {
			lo = mid;
		} else {
			hi = mid;
		}
	}
	double len = p->arc[hi] - p->arc[lo];
	double t = len > 0.0 ? fmin(fmax((s - p->arc[lo]) / len, 0.0), 1.0) : 0.0;
	for (int k = 0; k < p->n; k++) {
		x[k] = p->pts[lo * (size_t)p->n + k] +
		       t * (p->pts[hi * (size_t)p->n + k] - p->pts[lo * (size_t)p->n + k]);
	}
}

/* Brute force, written independently of check.c: min over every segment of
 * |(x - a) - t (b - a)|, t the clamped projection. */
static double brute(const struct path *p, const double *x)
{
	int n = p->n;
	double best = INFINITY;
	for (size_t j = 0; j + 1 < p->np; j++) {
		const double *a = p->pts + j * (size_t)n, *b = a + n;
		double ab[MLIP_MAX_AXES], ax[MLIP_MAX_AXES], num = 0.0, den = 0.0;
		for (int k = 0; k < n; k++) {
			ab[k] = b[k] - a[k];
			ax[k] = x[k] - a[k];
			num += ax[k] * ab[k];
			den += ab[k] * ab[k];
		}
		double t = den > 0.0 ? num / den : 0.0;
		t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
		double d2 = 0.0;
		for (int k = 0; k < n; k++) {
			double e = ax[k] - t * ab[k];
			d2 += e * e;
		}
		best = fmin(best, d2);
	}
	return sqrt(best);
}

static struct mlip_check_limits limits(int n, double window_mm)
{
	struct mlip_check_limits lim = {.n = n,
	                                .vmax_mm_s = 200.0,
	                                .vmax_rot_deg_s = 0.0,
	                                .eps_mm = EPS,
	                                .period_s = 0.001,
	                                .window_mm = window_mm};
	for (int k = 0; k < n; k++) {
		lim.accel[k] = 1000.0;
		lim.vel[k] = 200.0;
	}
	return lim;
}

/* The polyline as a streaming source, one point per call. */
struct src {
	const struct path *p;
	size_t i;
};

static int src_next(void *ctx, double *pt, uint32_t *line)
{
	struct src *s = ctx;
	if (s->i >= s->p->np) {
		return 0;
	}
	memcpy(pt, s->p->pts + s->i * (size_t)s->p->n, sizeof(double) * (size_t)s->p->n);
	*line = (uint32_t)s->i + 1;
	s->i++;
	return 1;
}

static struct mlip_check chk; /* ~0.3 MB */

/* Walk the path forwards by random steps of at most step_mm (a hold now and
 * then), each sample off the path by up to off_mm in a random direction;
 * every `far` samples (0: never) one sample off by up to 3 eps. With
 * exact, asserts each sample's contour error against brute force. Returns
 * the samples made. */
static size_t walk(const struct path *p, double window_mm, double step_mm, double off_mm,
                   size_t far, int exact)
{
	int n = p->n;
	struct mlip_check_limits lim = limits(n, window_mm);
	struct src s = {.p = p};
	mlip_check_init_source(&chk, &lim, src_next, &s);
	double end = p->arc[p->np - 1], pos = 0.0;
	size_t i = 0;
	for (;; i++) {
		double x[MLIP_MAX_AXES], e[MLIP_MAX_AXES], r2 = 0.0;
		path_at(p, pos, x);
		double off = (far && i % far == far - 1) ? 3.0 * EPS * urand() : off_mm * urand();
		if (pos >= end) {
			off = 0.0; /* ends on the last point */
		}
		for (int k = 0; k < n; k++) {
			e[k] = 2.0 * urand() - 1.0;
			r2 += e[k] * e[k];
		}
		for (int k = 0; k < n; k++) {
			x[k] += off * e[k] / sqrt(r2);
		}
		mlip_check_sample(&chk, x);
		double want = exact ? brute(p, x) : chk.last_contour_mm;
		if (!(fabs(chk.last_contour_mm - want) <= EXACT_MM)) {
			fail_msg(
			    "sample %zu at path position %.6f: contour %.17g, brute force %.17g", i,
			    pos, chk.last_contour_mm, want);
		}
		if (pos >= end) {
			break;
		}
		double u = urand();
		pos = fmin(end, pos + (u < 0.05 ? 0.0 : step_mm * u));
	}
	mlip_check_finish(&chk);
	return i + 1;
}

/* Contour within eps (both sides: the offsets reach into the band) and the
 * end on the last point. (The walks' random offsets make no sense as
 * accelerations.) */
static void assert_contour(size_t samples, double used)
{
	if (!(chk.max_contour_mm <= EPS)) {
		fail_msg("%zu samples: contour %.17g at sample %zu", samples, chk.max_contour_mm,
		         chk.max_contour_at);
	}
	assert_true(chk.max_contour_mm > used * EPS);
	assert_true(mlip_check_end_error(&chk) <= 1e-12);
}

/* Exact on every sample (steps of up to 0.05 mm, off by up to 0.9 eps);
 * then a walk a machine could make (steps of up to 8 um, so that a chord
 * cuts a corner by at most 4 um, off by up to 0.5 eps): in order. */
static void exact_and_in_order(const struct path *p, double window_mm)
{
	size_t n = walk(p, window_mm, 0.05, 0.9 * EPS, 0, 1);
	assert_contour(n, 0.5);
	n = walk(p, window_mm, 0.008, 0.5 * EPS, 0, 0);
	assert_contour(n, 0.3);
	if (chk.order_errors != 0) {
		fail_msg("%zu samples, %zu out of order, the first at %zu", n, chk.order_errors,
		         chk.order_at);
	}
}

static void test_zigzag_teeth_nearly_touch(void **state)
{
	(void)state;
	/* 0.3 mm segments, sharp corners, rows 6 mm long whose teeth come within
	 * 0.004 mm of the next row's; 5000+ points: more than the ring holds */
	struct path p = zigzag(128, 6.0, 0.3, 0.004);
	assert_true(p.np > MLIP_CHECK_RING + 1000);
	exact_and_in_order(&p, 0.0);
	path_free(&p);
}

static void test_spiral_turns_closer_than_eps(void **state)
{
	(void)state;
	/* turns 0.004 mm apart: every sample is within eps of 5 turns */
	struct path p = spiral(1.0, 0.004, 24.0, 0.02);
	assert_true(p.np > MLIP_CHECK_RING);
	exact_and_in_order(&p, 0.0);
	path_free(&p);
}

static void test_path_back_over_itself(void **state)
{
	(void)state;
	struct path p = retrace();
	exact_and_in_order(&p, 0.0);
	/* with samples off by up to 3 eps now and then: still exact */
	walk(&p, 0.0, 0.03, 0.9 * EPS, 97, 1);
	assert_true(chk.max_contour_mm > EPS);
	path_free(&p);
}

static void test_random_walks_whole_polyline(void **state)
{
	(void)state;
	/* a window larger than the path: the contour error is the distance to
	 * the whole polyline (the walks fit the ring) */
	for (int n = 2; n <= 4; n++) {
		struct path p = random_walk(n, 1500, 1.0);
		assert_true(p.np <= MLIP_CHECK_RING);
		exact_and_in_order(&p, 1e9);
		walk(&p, 1e9, 0.04, 0.9 * EPS, 53, 1);
		assert_true(chk.max_contour_mm > EPS);
		path_free(&p);
	}
}

/* A real trace: the planner (mpct, 1000 mm/s^2, 200 mm/s, eps 0.01) on the
 * zigzag raster, every setpoint against brute force. */
static struct mlip_planner planner;

static void test_planner_trace_on_zigzag(void **state)
{
	(void)state;
	struct path p = zigzag(24, 8.0, 0.3, 0.004);
	struct mlip_machine m;
	memset(&m, 0, sizeof(m));
	m.n_axes = 2;
	m.max_feed_mm_s = 200.0;
	m.tolerance_mm = EPS;
	m.period_s = 0.001;
	for (int k = 0; k < 2; k++) {
		m.axis[k].letter = "XY"[k];
		m.axis[k].max_accel = 1000.0;
		m.axis[k].max_vel = 200.0;
		m.axis[k].min_limit = -1e9;
		m.axis[k].max_limit = 1e9;
	}
	struct mlip_check_limits lim = limits(2, 0.0);
	struct src s = {.p = &p};
	mlip_check_init_source(&chk, &lim, src_next, &s);
	assert_int_equal(mlip_planner_init(&planner, &m, MLIP_STRATEGY_MPCT, 0, p.pts, NULL),
	                 MLIP_OK);
	mlip_check_sample(&chk, p.pts);
	size_t next = 1, samples = 1;
	double x[MLIP_MAX_AXES];
	for (;;) {
		while (next < p.np && mlip_planner_space(&planner) > 0) {
			struct mlip_block b = {
			    .feed_mm_s = 200.0, .tol_mm = EPS, .line = (uint32_t)next};
			memcpy(b.target, p.pts + next * 2, sizeof(double) * 2);
			assert_int_equal(mlip_planner_push(&planner, &b), MLIP_OK);
			next++;
		}
		mlip_run_state rs = mlip_planner_step(&planner, x);
		mlip_check_sample(&chk, x);
		samples++;
		double want = brute(&p, x);
		if (!(fabs(chk.last_contour_mm - want) <= EXACT_MM)) {
			fail_msg("setpoint %zu: contour %.17g, brute force %.17g", samples,
			         chk.last_contour_mm, want);
		}
		if (rs == MLIP_RUN_IDLE && next == p.np) {
			break;
		}
		assert_true(samples < 10000000);
	}
	mlip_check_finish(&chk);
	char msg[1024];
	int bad = mlip_check_verdict(&chk, 1e-9, mlip_check_rounding_floor(&chk), 0.0, 1e-9, msg,
	                             sizeof(msg));
	if (bad) {
		fail_msg("%s", msg);
	}
	assert_int_equal(chk.order_errors, 0);
	/* both sides: mpct's corners fill half of each 0.3 mm segment (19) */
	assert_true(chk.max_contour_mm > 0.4 * EPS);
	path_free(&p);
}

/* Samples on the path itself, except where the test says. */
static void sample_at(const struct path *p, double pos)
{
	double x[MLIP_MAX_AXES];
	path_at(p, pos, x);
	mlip_check_sample(&chk, x);
}

static void test_order_step_back_and_skip(void **state)
{
	(void)state;
	struct path p = zigzag(8, 8.0, 0.3, 0.004);
	struct mlip_check_limits lim = limits(2, 0.0);
	double pos = 0.0;

	/* forwards at 20 mm/s, then 1 mm back across a 10-period hole (100 mm/s:
	 * no speed limit broken), then on */
	struct src s = {.p = &p};
	mlip_check_init_source(&chk, &lim, src_next, &s);
	for (; pos < 5.0; pos += 0.02) {
		sample_at(&p, pos);
	}
	assert_int_equal(chk.order_errors, 0);
	mlip_check_gap(&chk, 10);
	pos -= 1.0;
	sample_at(&p, pos);
	assert_int_equal(chk.order_errors, 1);
	assert_true(chk.last_contour_mm <= 1e-12); /* on the path: only order sees it */
	for (pos += 0.02; pos < 10.0; pos += 0.02) {
		sample_at(&p, pos);
	}
	assert_int_equal(chk.order_errors, 1); /* starts again from there */

	/* from near the end of row 0 across to the nearest point of row 1 in a
	 * 3-period hole: at most 0.3 mm in 3 ms (100 mm/s), but 4 mm of path
	 * skipped, within the window (further is a contour error) */
	s.i = 0;
	mlip_check_init_source(&chk, &lim, src_next, &s);
	for (pos = 0.0; pos < 14.0; pos += 0.02) {
		sample_at(&p, pos);
	}
	double x[2], y[2], jump = 0.0, best = INFINITY;
	path_at(&p, pos - 0.02, x);
	struct path row0 = p;
	row0.np = 54; /* the start and row 0 */
	for (double s2 = p.arc[54]; s2 < p.arc[108]; s2 += 0.0005) {
		path_at(&p, s2, y);
		double d = hypot(y[0] - x[0], y[1] - x[1]);
		if (d < best && brute(&row0, y) > 0.1) { /* a point of row 1 only */
			best = d;
			jump = s2;
		}
	}
	assert_true(best < 0.3 && jump - pos > 3.0);
	mlip_check_gap(&chk, 3);
	sample_at(&p, jump);
	assert_true(chk.last_contour_mm <= 1e-12);
	assert_int_equal(chk.order_errors, 1);
	char msg[1024];
	/* (the corners, taken at 20 mm/s in one period, break the acceleration
	 * limit: only speed and contour matter here) */
	assert_true(mlip_check_verdict(&chk, 1e-9, 0.0, 0.0, INFINITY, msg, sizeof(msg)) >= 1);
	assert_non_null(strstr(msg, "order: 1 sample(s)"));
	assert_null(strstr(msg, "speed"));
	assert_null(strstr(msg, "contour"));
	path_free(&p);
}

/* Order follows the chords between samples, not a reach: a trace that
 * runs straight through a zigzag narrower than eps (as a smoothing strategy
 * may: 5 um segments, +-9 um, the polyline 3.7 times longer than the
 * trace) is in order at 200 mm/s; the same straight trace cutting from one
 * row of a raster to the next (no hole, 0.2 mm in one period) skips the
 * row's end, and is out of order. */
static void test_order_follows_chords(void **state)
{
	(void)state;
	struct path p = {.n = 2};
	for (int i = 0; i <= 4000; i++) {
		double x[2] = {0.005 * i, i % 2 ? 0.009 : -0.009};
		path_add(&p, x);
	}
	p.pts[1] = 0.0; /* start and end on the centre line */
	p.pts[2 * 4000 + 1] = 0.0;
	assert_true(p.arc[p.np - 1] > 3.5 * 20.0);
	struct mlip_check_limits lim = limits(2, 0.0);
	struct src s = {.p = &p};
	mlip_check_init_source(&chk, &lim, src_next, &s);
	for (int i = 0; i <= 100; i++) {
		double x[2] = {0.2 * i, 0.0};
		mlip_check_sample(&chk, x);
	}
	mlip_check_finish(&chk);
	char msg[1024];
	int bad = mlip_check_verdict(&chk, 1e-9, 0.0, 0.0, 1e-9, msg, sizeof(msg));
	if (bad) {
		fail_msg("%s", msg);
	}
	/* (the zigzag crosses the trace: each sample is within 2.5 um of it;
	 * a reach of step + 8 tol = 0.28 mm per sample, the old rule, would
	 * have lost it: 0.76 mm of polyline go by per sample) */
	assert_true(chk.max_contour_mm <= 0.0025 + 1e-12);
	path_free(&p);

	/* two rows 0.15 mm apart joined at x = 10: along row 0, then straight
	 * across to row 1 at x = 9.6 */
	struct path q = {.n = 2};
	double a[2] = {0, 0}, b[2] = {10, 0}, e[2] = {10, 0.15}, f[2] = {0, 0.15};
	path_add(&q, a);
	path_add(&q, b);
	path_add(&q, e);
	path_add(&q, f);
	s.p = &q;
	s.i = 0;
	mlip_check_init_source(&chk, &lim, src_next, &s);
	double x[2] = {0, 0};
	for (; x[0] < 9.5; x[0] += 0.1) {
		mlip_check_sample(&chk, x);
	}
	assert_int_equal(chk.order_errors, 0);
	x[1] = 0.15; /* 0.15 mm in 1 ms: 150 mm/s */
	mlip_check_sample(&chk, x);
	assert_true(chk.last_contour_mm <= 1e-12);
	assert_int_equal(chk.order_errors, 1);
	for (x[0] -= 0.1; x[0] > 0.0; x[0] -= 0.1) {
		mlip_check_sample(&chk, x);
	}
	assert_int_equal(chk.order_errors, 1); /* and on from there */
	path_free(&q);
}

/* The window keeps the memory fixed: a path of 27000 points streams
 * through a 4096-point ring, and the end is its last point. */
static void test_long_path_streams(void **state)
{
	(void)state;
	struct path p = zigzag(500, 8.0, 0.3, 0.004);
	assert_true(p.np > 6 * MLIP_CHECK_RING);
	struct mlip_check_limits lim = limits(2, 0.0);
	struct src s = {.p = &p};
	mlip_check_init_source(&chk, &lim, src_next, &s);
	double end = p.arc[p.np - 1];
	for (double pos = 0.0;; pos = fmin(end, pos + 0.008)) {
		sample_at(&p, pos);
		assert_true(chk.last_contour_mm <= 1e-12);
		if (pos >= end) {
			break;
		}
	}
	mlip_check_finish(&chk);
	assert_int_equal(chk.order_errors, 0);
	assert_true(chk.hi - chk.lo <= MLIP_CHECK_RING);
	assert_true(mlip_check_end_error(&chk) <= 1e-12);
	assert_true(fabs(chk.prog_mm - end) <= 1e-9 * end);
	path_free(&p);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_zigzag_teeth_nearly_touch),
	    cmocka_unit_test(test_spiral_turns_closer_than_eps),
	    cmocka_unit_test(test_path_back_over_itself),
	    cmocka_unit_test(test_random_walks_whole_polyline),
	    cmocka_unit_test(test_planner_trace_on_zigzag),
	    cmocka_unit_test(test_order_step_back_and_skip),
	    cmocka_unit_test(test_order_follows_chords),
	    cmocka_unit_test(test_long_path_streams),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
