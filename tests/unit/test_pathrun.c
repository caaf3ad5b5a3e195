/*
 * test_pathrun.c - the path-speed plan over a stream of setpoints
 * (src/motion/pathrun.c): a piece, once fixed, never changes while points
 * are appended and the window is compacted (bit for bit); fixed pieces
 * meet with the same position and x' and an x'' within 1e-9 of |x''|;
 * every state the plan enters is certified on the pieces fixed then, and
 * stays certified after the next points are appended (the window's end
 * acts as a stop point); the output keeps J and A (third and second
 * differences) and uses them, and comes to rest exactly on the last point;
 * a sharp reversal is refused by (P6); a setpoint at rest is skipped;
 * the fairing (F1)(F2) damps a polygon's curvature ripple within its
 * bound and keeps a line a line.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "mlip/motion/pathrun.h"

#define T    1e-3
#define JERK 1e4
#define ACC  1000.0

/* The setpoints of a move along a helix (radius 10 mm, rising 1 mm a
 * radian) from rest to rest at up to V mm/s, 1000 mm/s^2 (a trapezoid in
 * arc length, sampled every T): what `smooth` without J would give. */
#define HR 10.0
#define HC 1.0
#define V  60.0

static double arc_at(double t, double len)
{
	double ta = V / ACC, da = 0.5 * V * ta, tc = (len - 2.0 * da) / V;
	if (t <= ta) {
		return 0.5 * ACC * t * t;
	}
	if (t <= ta + tc) {
		return da + V * (t - ta);
	}
	double u = t - ta - tc;
	if (u >= ta) {
		return len;
	}
	return da + V * tc + V * u - 0.5 * ACC * u * u;
}

static void helix_at(double s, double *x)
{
	double L = sqrt(HR * HR + HC * HC), th = s / L;
	x[0] = HR * cos(th);
	x[1] = HR * sin(th);
	x[2] = HC * th;
}

static void limits(struct mlip_path_limits *lim)
{
	*lim = (struct mlip_path_limits){0};
	lim->n = 3;
	for (int k = 0; k < 3; k++) {
		lim->accel[k] = 0.98 * ACC;
		lim->jerk[k] = 0.95 * JERK;
	}
	lim->vmax = 0.995 * 200.0;
	lim->a_brake[0] = 900.0;
	lim->a_brake[1] = 300.0;
	lim->n_brake = 2;
	lim->period = T;
}

/* Every fixed piece ever seen, by its index from the program's start. */
#define HIST 8000
struct piece {
	double s, s1, p[3], b[3], m[3], t3[3];
};
static struct piece hist[HIST];
static long n_hist;

static void piece_of(const struct mlip_pathrun *pr, int i, struct piece *q)
{
	memset(q, 0, sizeof(*q));
	q->s = pr->s[i];
	q->s1 = pr->s[i + 1];
	for (int k = 0; k < 3; k++) {
		q->p[k] = pr->p[i][k];
		q->b[k] = pr->b[i][k];
		q->m[k] = pr->m[i][k];
		q->t3[k] = pr->t3[i][k];
	}
}

/* The fixed pieces against their first sight: the same bits. */
static void check_fixed(const struct mlip_pathrun *pr)
{
	for (int i = 0; i < pr->fixed; i++) {
		long g = pr->dropped + i;
		assert_true(g < HIST);
		struct piece q;
		piece_of(pr, i, &q);
		if (g < n_hist) {
			assert_memory_equal(&q, &hist[g], sizeof(q));
		} else {
			assert_int_equal(g, n_hist); /* fixed in order, none skipped */
			hist[n_hist++] = q;
		}
	}
}

static struct mlip_pathrun pr;

static void test_stream_helix(void **state)
{
	(void)state;
	struct mlip_path_limits lim;
	limits(&lim);
	lim.vmax = 0.995 * V; /* the feed the input ran at (the plan's cap) */
	double len = 400.0, x[3], start[3];
	helix_at(0.0, start);
	assert_int_equal(mlip_pathrun_init(&pr, &lim, 1e-3, 3000, start), 0);
	n_hist = 0;
	double out[4][3];
	memcpy(out[0], start, sizeof(start));
	long n_out = 1, uncertified = 0, lost = 0, checked = 0;
	double max_j = 0.0, max_a = 0.0, end_pt[3];
	int done = 0;
	/* the input every period, and a rest of 5 periods at the end (repeats) */
	for (long k = 1; !done; k++) {
		double t = (double)k * T, in[3];
		int last = arc_at(t - 5 * T, len) >= len;
		helix_at(arc_at(t, len), in);
		memcpy(end_pt, in, sizeof(in));
		int r;
		struct mlip_path_state before = pr.st;
		double end_before = pr.s[pr.fixed];
		while (!done && (r = mlip_pathrun_push(&pr, in)) == 1) {
			int q = mlip_pathrun_step(&pr, x);
			assert_int_equal(q, 1);
			check_fixed(&pr);
			struct mlip_path_curve cv;
			mlip_pathrun_curve(&pr, &cv);
			if (n_out % 5 == 0) {
				checked++;
				uncertified += !mlip_path_certified(&cv, &lim, pr.st,
				                                    pr.s[pr.fixed], 3000, NULL);
			}
			memmove(out[1], out[0], sizeof(out[0]) * 3);
			memcpy(out[0], x, sizeof(x));
			if (++n_out >= 4) {
				for (int a = 0; a < 3; a++) {
					double j = fabs(out[0][a] - 3 * out[1][a] + 3 * out[2][a] -
					                out[3][a]);
					double ac = fabs(out[0][a] - 2 * out[1][a] + out[2][a]);
					max_j = fmax(max_j, j / (T * T * T));
					max_a = fmax(max_a, ac / (T * T));
				}
			}
			before = pr.st;
			end_before = pr.s[pr.fixed];
		}
		assert_int_equal(r, 0);
		check_fixed(&pr);
		if (pr.s[pr.fixed] > end_before && k % 7 == 0) {
			/* the window grew: the state certified before still is */
			struct mlip_path_curve cv;
			mlip_pathrun_curve(&pr, &cv);
			lost += !mlip_path_certified(&cv, &lim, before, pr.s[pr.fixed], 3000, NULL);
		}
		done = last;
	}
	assert_int_equal(mlip_pathrun_finish(&pr), 0);
	check_fixed(&pr);
	assert_true(pr.dropped > 0); /* the window was compacted */
	assert_true(pr.peak_count <= MLIP_PATHRUN_CAP);
	int q;
	while ((q = mlip_pathrun_step(&pr, x)) >= 1) {
		check_fixed(&pr);
		memmove(out[1], out[0], sizeof(out[0]) * 3);
		memcpy(out[0], x, sizeof(x));
		n_out++;
		for (int a = 0; a < 3; a++) {
			double j = fabs(out[0][a] - 3 * out[1][a] + 3 * out[2][a] - out[3][a]);
			max_j = fmax(max_j, j / (T * T * T));
			max_a = fmax(max_a, fabs(out[0][a] - 2 * out[1][a] + out[2][a]) / (T * T));
		}
		if (q == 2) {
			break;
		}
	}
	assert_int_equal(q, 2);
	assert_memory_equal(x, end_pt, sizeof(end_pt)); /* at rest on the last point exactly */
	assert_int_equal(uncertified, 0);
	assert_true(checked > 100);
	assert_int_equal(lost, 0);
	/* J and A kept, and used: 0.95 J planned */
	assert_true(max_j <= JERK * (1.0 + 1e-6));
	assert_true(max_j >= 0.8 * JERK);
	assert_true(max_a <= ACC * (1.0 + 1e-6));
	assert_true(max_a >= 0.3 * ACC);
	/* (P6): the longest piece (V T) on the helix's curvature, h^2 / 8 kappa */
	double sag = (V * T) * (V * T) / 8.0 * HR / (HR * HR + HC * HC);
	assert_true(fabs(pr.max_sag_mm / sag - 1.0) < 0.02);
	/* time: the trapezoid takes len / V + V / A = 6.73 s; the plan under
	 * J, from rest to rest, a little more, and not far */
	double t_in = len / V + V / ACC, t_out = (double)n_out * T;
	assert_true(t_out > t_in && t_out < 1.15 * t_in);
}

/* Fixed pieces meet with the same position and x', x'' within 1e-9 of
 * its size (the fits' natural ends, SETTLE knots away). */
static void test_joins(void **state)
{
	(void)state;
	struct mlip_path_limits lim;
	limits(&lim);
	double p[3];
	helix_at(0.0, p);
	assert_int_equal(mlip_pathrun_init(&pr, &lim, 1e-3, 3000, p), 0);
	for (int i = 1; i < 600; i++) {
		/* uneven spacing: 0.01 .. 0.19 mm */
		helix_at(0.1 * i + 0.09 * sin(0.7 * i), p);
		assert_int_equal(mlip_pathrun_push(&pr, p), 0);
	}
	assert_true(pr.fixed == 599 - MLIP_PATHRUN_SETTLE);
	double worst_d1 = 0.0, worst_d2 = 0.0;
	for (int i = 1; i < pr.fixed; i++) {
		double h = pr.s[i] - pr.s[i - 1];
		for (int k = 0; k < 3; k++) {
			double d1 =
			    pr.b[i - 1][k] + pr.m[i - 1][k] * h + 0.5 * pr.t3[i - 1][k] * h * h;
			double d2 = pr.m[i - 1][k] + pr.t3[i - 1][k] * h;
			double x = pr.p[i - 1][k] + pr.b[i - 1][k] * h +
			           0.5 * pr.m[i - 1][k] * h * h + pr.t3[i - 1][k] * h * h * h / 6.0;
			assert_true(fabs(x - pr.p[i][k]) < 1e-12);
			worst_d1 = fmax(worst_d1, fabs(d1 - pr.b[i][k]));
			worst_d2 = fmax(worst_d2, fabs(d2 - pr.m[i][k]));
		}
	}
	assert_true(worst_d1 < 1e-12);
	assert_true(worst_d2 < 1e-9 * (1.0 / HR)); /* |x''| ~ 1 / R */
	/* and the curvature is the helix's: R / (R^2 + c^2) */
	double kap = sqrt(pr.m[300][0] * pr.m[300][0] + pr.m[300][1] * pr.m[300][1] +
	                  pr.m[300][2] * pr.m[300][2]);
	assert_true(fabs(kap - HR / (HR * HR + HC * HC)) < 1e-4);
}

/* A reversal (the path turns back on itself) is refused: the spline there
 * strays far from its chords. */
static void test_reversal_refused(void **state)
{
	(void)state;
	struct mlip_path_limits lim;
	limits(&lim);
	double p[3] = {0, 0, 0};
	assert_int_equal(mlip_pathrun_init(&pr, &lim, 1e-3, 3000, p), 0);
	int r = 0;
	for (int i = 1; i < 200 && r == 0; i++) {
		p[0] = i < 100 ? 0.1 * i : 0.1 * (200 - i); /* out and back */
		p[1] = i < 100 ? 0.0 : 0.001 * (i - 100);
		r = mlip_pathrun_push(&pr, p);
	}
	assert_int_equal(r, -1);
	assert_non_null(pr.why);
	assert_non_null(strstr(pr.why, "(P6)"));
	assert_true(pr.why_mm > 1e-3);
	assert_true(pr.why_s > 9.0 && pr.why_s < 10.1); /* at the turn (10 mm) */
}

/* A setpoint at rest (repeated) adds no piece; the last input, within
 * MIN_STEP of the last point kept, is where the plan ends. */
static void test_rest_skipped(void **state)
{
	(void)state;
	struct mlip_path_limits lim;
	limits(&lim);
	double p[3] = {0, 0, 0}, x[3];
	assert_int_equal(mlip_pathrun_init(&pr, &lim, 1e-3, 3000, p), 0);
	for (int i = 1; i <= 100; i++) {
		p[0] = 0.05 * i;
		assert_int_equal(mlip_pathrun_push(&pr, p), 0);
		assert_int_equal(mlip_pathrun_push(&pr, p), 0); /* the same again */
	}
	assert_int_equal(pr.count, 101);
	p[0] += 0.5 * MLIP_PATHRUN_MIN_STEP;
	assert_int_equal(mlip_pathrun_push(&pr, p), 0);
	assert_int_equal(pr.count, 101);
	assert_int_equal(mlip_pathrun_finish(&pr), 0);
	assert_int_equal(pr.fixed, 100);
	int q, steps = 0;
	while ((q = mlip_pathrun_step(&pr, x)) == 1 && steps < 100000) {
		steps++;
	}
	assert_int_equal(q, 2);
	assert_memory_equal(x, p, sizeof(p));
	/* 5 mm on a line from rest to rest under J 1e4, A 1000: ~0.1 s at least */
	assert_true(steps > 100 && steps < 1000);
}

/* A polygon of a circle (radius 10 mm, 2 degree chords) walked at 0.1 mm
 * a period, 3/4 of a turn: the input whose spline ripples in curvature
 * with the chords. Point i in x; its count. */
#define CR    10.0
#define CSTEP 0.1
static void polygon_s(double s, double *x)
{
	double ch = 2.0 * CR * sin(M_PI / 180.0);
	int c = (int)(s / ch);
	double u = s / ch - c, a0 = c * M_PI / 90.0, a1 = (c + 1) * M_PI / 90.0;
	x[0] = CR * ((1.0 - u) * cos(a0) + u * cos(a1));
	x[1] = CR * ((1.0 - u) * sin(a0) + u * sin(a1));
	x[2] = 0.0;
}

static int polygon_at(int i, double *x)
{
	polygon_s(CSTEP * i, x);
	return (int)(135.0 * 2.0 * CR * sin(M_PI / 180.0) / CSTEP); /* 3/4 of the 180 chords */
}

/* The largest |curvature - 1/CR| at the knots between 60 and 200 degrees
 * (|x''| by chord length there: |x_t| is 1 within 1e-6). */
static double ripple(const struct mlip_pathrun *r)
{
	double worst = 0.0;
	for (int i = 0; i <= r->fixed; i++) {
		double a = atan2(r->p[i][1], r->p[i][0]);
		a = a < 0.0 ? a + 2.0 * M_PI : a;
		if (a > M_PI / 3.0 && a < 10.0 * M_PI / 9.0) {
			double k = hypot(r->m[i][0], r->m[i][1]);
			worst = fmax(worst, fabs(k - 1.0 / CR));
		}
	}
	return worst;
}

/* (F1)(F2) on the polygon: every knot within fair_mm of its input point,
 * the first and last knots the input's own, no piece refused; the
 * curvature's largest departure from 1/CR at the knots measured 0.039 /mm
 * faired, 0.49 unfaired (the polygon's vertices are sharp, not rounded as
 * smooth's setpoints are; (F2) holds the vertices' moves below the 1.5 um
 * the circle is from them): asserted below 0.06, above 0.3. */
static void test_fair_polygon(void **state)
{
	(void)state;
	struct mlip_path_limits lim;
	limits(&lim);
	double x[3], first[3], band = 2e-3, fair = 0.6 * band, got[2];
	int n = polygon_at(0, first);
	for (int f = 0; f < 2; f++) {
		assert_int_equal(mlip_pathrun_init(&pr, &lim, band, 3000, first), 0);
		if (f) {
			assert_int_equal(mlip_pathrun_fair(&pr, -1.0, 8, fair), -1);
			assert_int_equal(mlip_pathrun_fair(&pr, 3.0, 8, band), -1);
			assert_int_equal(mlip_pathrun_fair(&pr, 3.0, 8, fair), 0);
		}
		for (int i = 1; i <= n; i++) {
			polygon_at(i, x);
			assert_int_equal(mlip_pathrun_push(&pr, x), 0);
		}
		assert_int_equal(mlip_pathrun_finish(&pr), 0);
		assert_true(pr.finished && pr.fixed == pr.count - 1 && pr.count == n + 1);
		assert_memory_equal(pr.p[0], first, sizeof(first));
		assert_memory_equal(pr.p[pr.fixed], x, sizeof(x));
		assert_true(pr.max_dev_mm < fair && (f == 0) == (pr.max_dev_mm == 0.0));
		for (int i = 0; i <= pr.fixed; i++) {
			assert_true(pr.dev[i] <= pr.max_dev_mm);
		}
		got[f] = ripple(&pr);
	}
	assert_true(got[0] > 0.3);
	assert_true(got[1] > 0.0 && got[1] < 0.06);
}

/* The polygon after a slow stretch (300 points 5 um apart: more than the
 * fairing's ring of 256 within its 3 mm), then at 0.1 mm a period: the
 * knots far past it are faired as on the polygon alone (ripple below
 * 0.06 /mm; a full ring of points behind once forced every later knot
 * with an empty window, the input itself: 0.49). */
static void test_fair_after_a_slow_stretch(void **state)
{
	(void)state;
	struct mlip_path_limits lim;
	limits(&lim);
	double x[3], s = 0.0, band = 2e-3;
	int n = polygon_at(0, x);
	assert_int_equal(mlip_pathrun_init(&pr, &lim, band, 3000, x), 0);
	assert_int_equal(mlip_pathrun_fair(&pr, 3.0, 8, 0.6 * band), 0);
	for (int i = 1; s < n * CSTEP; i++) {
		s += i <= 300 ? 0.005 : CSTEP;
		polygon_s(s, x);
		assert_int_equal(mlip_pathrun_push(&pr, x), 0);
	}
	assert_int_equal(mlip_pathrun_finish(&pr), 0);
	double r = ripple(&pr);
	print_message("ripple after a slow stretch: %.3f /mm\n", r);
	assert_true(r > 0.0 && r < 0.06);
}

/* A line sampled unevenly stays the line (the window is symmetric: the
 * fit of a linear input is itself), its knots' moves at the rounding. */
static void test_fair_line(void **state)
{
	(void)state;
	struct mlip_path_limits lim;
	limits(&lim);
	double p[3] = {1.0, 2.0, 3.0}, d[3] = {0.6, -0.48, 0.64}, s = 0.0, x[3];
	assert_int_equal(mlip_pathrun_init(&pr, &lim, 2e-3, 3000, p), 0);
	assert_int_equal(mlip_pathrun_fair(&pr, 3.0, 8, 1.2e-3), 0);
	for (int i = 1; i <= 300; i++) {
		s += 0.02 + 0.15 * (i % 7) / 7.0;
		for (int k = 0; k < 3; k++) {
			x[k] = p[k] + s * d[k];
		}
		assert_int_equal(mlip_pathrun_push(&pr, x), 0);
	}
	assert_int_equal(mlip_pathrun_finish(&pr), 0);
	assert_true(pr.max_dev_mm < 1e-12);
	for (int i = 0; i <= pr.fixed; i++) {
		double t = (pr.p[i][0] - p[0]) / d[0];
		assert_true(fabs(pr.p[i][1] - (p[1] + t * d[1])) < 1e-12);
		assert_true(fabs(pr.p[i][2] - (p[2] + t * d[2])) < 1e-12);
	}
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_stream_helix),
	    cmocka_unit_test(test_joins),
	    cmocka_unit_test(test_reversal_refused),
	    cmocka_unit_test(test_rest_skipped),
	    cmocka_unit_test(test_fair_polygon),
	    cmocka_unit_test(test_fair_line),
	    cmocka_unit_test(test_fair_after_a_slow_stretch),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
