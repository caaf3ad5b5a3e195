/*
 * test_planq.c - the path-speed plan run ahead of the period through its
 * queue (src/motion/planq.c): the consumer, fed by a producer that stalls
 * at random, keeps A and J at every sample (second and third differences
 * of its setpoints over T^2, T^3, within 1e-6 relative, and uses them),
 * stays on the path (within 1e-4 mm of the input curve), brakes to rest
 * whenever the queue runs dry, plans again from that rest and ends exactly
 * on the last point; a hold at a random period brakes the same way from
 * that very period and holds the point; a producer thread beside the
 * consumer (make tsan: no data race) gives the same guarantees.
 */
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "mlip/motion/planq.h"

#define XORSHIFT_SEED 0x2545f4914f6cdd1dull
#include "xorshift.h"

#define T        1e-3
#define JERK     1e4
#define ACC      1000.0
#define V        60.0
/* the input curve: x = R cos u, y = R sin(2u) / 2, z = H u (its curvature
 * varies: 0.05 .. 0.5 / mm) */
#define R        10.0
#define H        1.0
/* on the path: the spline through the input points, sampled every V T at
 * most, stays this close to the curve (its own error is ~h^4 |x''''|) */
#define PATH_TOL 1e-4

/* The lag's test (test_lag_independent) runs a long gentle curve at
 * FAST_V instead: x = u, y = FAST_Y sin(u / FAST_L), z = 0 (mm), where the
 * window's look-ahead is near a stop's length (from 995 mm/s at 900 mm/s^2,
 * 550 mm; the window 1,024 points 1 mm apart) */
#define FAST_V 1000.0
#define FAST_Y 50.0
#define FAST_L 500.0
static int fast; /* the lag test's curve and speed */

static void curve_at(double u, double *x)
{
	if (fast) {
		x[0] = u;
		x[1] = FAST_Y * sin(u / FAST_L);
		x[2] = 0.0;
		return;
	}
	x[0] = R * cos(u);
	x[1] = R * sin(2.0 * u) / 2.0;
	x[2] = H * u;
}

static double curve_speed(double u) /* |dx/du| */
{
	if (fast) {
		double b = FAST_Y / FAST_L * cos(u / FAST_L);
		return sqrt(1.0 + b * b);
	}
	double a = R * sin(u), b = R * cos(2.0 * u);
	return sqrt(a * a + b * b + H * H);
}

static double gentle; /* the second policy's braking when not 0 (test_hold_brakes_hard) */

static void limits(struct mlip_path_limits *lim)
{
	*lim = (struct mlip_path_limits){0};
	lim->n = 3;
	for (int k = 0; k < 3; k++) {
		lim->accel[k] = 0.98 * ACC;
		lim->jerk[k] = 0.95 * JERK;
	}
	lim->vmax = 0.995 * (fast ? FAST_V : V);
	lim->a_brake[0] = 900.0;
	lim->a_brake[1] = gentle > 0.0 ? gentle : 300.0;
	lim->n_brake = 2;
	lim->period = T;
}

static struct mlip_pathrun pr;
static struct mlip_planq q;

/* The producer's input: the curve from u = 0 to u_end in steps of v T
 * (v ramping from rest at ACC to V: what `smooth` without J gives, near
 * enough), then the end. */
struct feed {
	double u, u_end, t, in[3], last[3];
	int pending, finished;
	int fail; /* a thread's failure (no cmocka outside the main thread) */
};

static void feed_init(struct feed *f, double u_end)
{
	memset(f, 0, sizeof(*f));
	f->u_end = u_end;
	struct mlip_path_limits lim;
	limits(&lim);
	double start[3];
	curve_at(0.0, start);
	f->fail |= mlip_pathrun_init(&pr, &lim, 1e-3, 3000, start) != 0;
	mlip_planq_init(&q, &pr);
}

/* One unit of the producer's work: an input point, or the end, or one
 * planned period. What mlip_planq_produce returned (1, 2, 0 no room), or
 * 4 for input. */
static int unit(struct feed *f)
{
	if (f->pending) {
		int r = mlip_pathrun_push(&pr, f->in);
		f->fail |= r < 0;
		if (r != 1) {
			f->pending = 0;
			return 4;
		}
	} else if (!f->finished) {
		if (f->u >= f->u_end) {
			f->fail |= mlip_pathrun_finish(&pr) != 0;
			f->finished = 1;
			return 4;
		}
		f->t += T;
		double v = fmin(fast ? FAST_V : V, ACC * f->t);
		f->u = fmin(f->u_end, f->u + v * T / curve_speed(f->u));
		curve_at(f->u, f->in);
		memcpy(f->last, f->in, sizeof(f->in));
		f->pending = 1;
		return 4;
	}
	int r = mlip_planq_produce(&q, &pr);
	f->fail |= r < 0 || r == 3;
	return r;
}

/* The producer's share of one consumer period: up to two planned periods
 * (it runs ahead and fills the queue), the input they need in between
 * (after a compaction of the window, a quarter of it: pushes are cheap). */
static void produce_some(struct feed *f)
{
	int planned = 0;
	for (int i = 0; i < 2 * MLIP_PATHRUN_CAP && planned < 2 && !f->fail; i++) {
		int r = unit(f);
		if (r == 0 || r == 2) {
			break;
		}
		planned += r == 1;
	}
}

/* The setpoints' physics: A and J per axis by differences; on the path. */
struct check {
	double out[4][3];
	long n;
	double max_j, max_a, max_off;
};

static void check_point(struct check *c, const double *x)
{
	memmove(c->out[1], c->out[0], sizeof(c->out[0]) * 3);
	memcpy(c->out[0], x, sizeof(c->out[0]));
	if (++c->n >= 4) {
		for (int k = 0; k < 3; k++) {
			double j =
			    c->out[0][k] - 3 * c->out[1][k] + 3 * c->out[2][k] - c->out[3][k];
			double a = c->out[0][k] - 2 * c->out[1][k] + c->out[2][k];
			c->max_j = fmax(c->max_j, fabs(j) / (T * T * T));
			c->max_a = fmax(c->max_a, fabs(a) / (T * T));
		}
	}
	double on[3];
	curve_at(x[2] / H, on); /* z = H u: the curve's point at this height */
	c->max_off = fmax(c->max_off, fmax(fabs(x[0] - on[0]), fabs(x[1] - on[1])));
}

static void check_init(struct check *c)
{
	memset(c, 0, sizeof(*c));
	curve_at(0.0, c->out[0]);
	memcpy(c->out[1], c->out[0], sizeof(c->out[0]));
	memcpy(c->out[2], c->out[0], sizeof(c->out[0]));
	c->n = 3; /* at rest before the start */
}

static void check_physics(const struct check *c)
{
	assert_true(c->max_j <= JERK * (1.0 + 1e-6));
	assert_true(c->max_j >= 0.5 * JERK); /* and used */
	assert_true(c->max_a <= ACC * (1.0 + 1e-6));
	assert_true(c->max_a >= 0.3 * ACC);
	assert_true(c->max_off <= PATH_TOL);
}

/* A stop from V at 300 mm/s^2 with its jerk ramps takes well under this. */
#define STOP_PERIODS 600

/* The producer stalls at random (20..700 periods; the queue holds 256):
 * short stalls are absorbed; a longer one runs the queue dry, the run
 * brakes and asks for a plan from its state MLIP_PLANQ_LEAD periods on:
 * back before the run's end, the plan takes the run up again (no rest);
 * else the run rests on the path and the plan starts again from there.
 * The end is the last point exactly. */
static void test_stalls(void **state)
{
	(void)state;
	struct feed f;
	struct check c;
	feed_init(&f, 16.0);
	assert_int_equal(f.fail, 0);
	check_init(&c);
	long stall = 0, stalls = 0, braking = 0, max_braking = 0, rests = 0, resumed = 0;
	double x[3], prev_x[3], v_min = INFINITY, v_run = INFINITY;
	curve_at(0.0, prev_x);
	int mode = MLIP_PLANQ_WAIT;
	for (long k = 0; k < 200000 && mode != MLIP_PLANQ_DONE; k++) {
		if (stall > 0) {
			stall--;
		} else if (uni(0.0, 1.0) < 1.0 / 150.0) {
			stall = (long)uni(20.0, 700.0);
			stalls++;
		} else {
			produce_some(&f);
			assert_int_equal(f.fail, 0);
		}
		int prev = mode;
		mode = mlip_planq_step(&q, 0, x);
		assert_true(mode >= 0);
		check_point(&c, x);
		rests += prev == MLIP_PLANQ_BRAKE && mode == MLIP_PLANQ_WAIT;
		double d = 0.0;
		for (int a = 0; a < 3; a++) {
			d += (x[a] - prev_x[a]) * (x[a] - prev_x[a]);
		}
		memcpy(prev_x, x, sizeof(x));
		/* the braking run's length (at rest it may wait in BRAKE for a
		 * stalled producer to read its request) */
		braking = mode == MLIP_PLANQ_BRAKE && d > 0.0 ? braking + 1 : 0;
		max_braking = braking > max_braking ? braking : max_braking;
		v_run = mode == MLIP_PLANQ_BRAKE ? fmin(v_run, sqrt(d) / T) : v_run;
		if (prev == MLIP_PLANQ_BRAKE && mode == MLIP_PLANQ_PLAN) {
			resumed++; /* taken up again while moving */
			assert_true(v_run > 0.0);
			v_min = fmin(v_min, v_run);
		}
		v_run = mode == MLIP_PLANQ_BRAKE ? v_run : INFINITY;
	}
	assert_int_equal(mode, MLIP_PLANQ_DONE);
	assert_memory_equal(x, f.last, sizeof(x)); /* at rest on the last point */
	check_physics(&c);
	/* the stalls starved it, not every one; each starving ended at rest
	 * or was taken up again, and both happened */
	assert_true(q.c.starved >= 2);
	assert_true(q.c.starved < stalls);
	assert_int_equal(rests + resumed, q.c.brakes);
	assert_true(rests >= 1 && resumed >= 1);
	assert_true(max_braking > 10 && max_braking < STOP_PERIODS);
	print_message(
	    "stalls %ld, starved %ld (%ld taken up again, slowest %.1f mm/s; %ld at rest), "
	    "longest run %ld, periods %ld, J %.4f, A %.4f, off %.2e mm\n",
	    stalls, q.c.starved, resumed, v_min, rests, max_braking, c.n, c.max_j / JERK,
	    c.max_a / ACC, c.max_off);
}

/* A hold at random periods: the braking run starts in that very period (its
 * setpoint already the run's), comes to rest within STOP_PERIODS, the point
 * stays while held; released, the plan goes on and ends on the last point. */
static void test_hold(void **state)
{
	(void)state;
	struct feed f;
	struct check c;
	feed_init(&f, 16.0);
	check_init(&c);
	double x[3], held[3];
	int mode = MLIP_PLANQ_WAIT, holds = 0;
	long hold_at = (long)uni(200.0, 600.0), hold_len = 0, rest_at = -1;
	for (long k = 0; k < 200000 && mode != MLIP_PLANQ_DONE; k++) {
		produce_some(&f);
		assert_int_equal(f.fail, 0);
		int hold = 0;
		if (k == hold_at) {
			hold_len = (long)uni(STOP_PERIODS, 2000.0);
			rest_at = -1;
			holds++;
		}
		if (hold_len > 0) {
			hold = 1;
			hold_len--;
		}
		int prev = mode;
		mode = mlip_planq_step(&q, hold, x);
		assert_true(mode >= 0);
		check_point(&c, x);
		if (k == hold_at) {
			assert_int_equal(prev, MLIP_PLANQ_PLAN);
			assert_int_equal(mode, MLIP_PLANQ_BRAKE);
		}
		if (hold && mode == MLIP_PLANQ_WAIT) {
			if (rest_at < 0) {
				rest_at = k;
				memcpy(held, x, sizeof(x));
				assert_true(rest_at - hold_at < STOP_PERIODS);
			}
			assert_memory_equal(x, held, sizeof(x)); /* held there */
		}
		if (hold && hold_len == 0) {
			assert_true(rest_at >= 0); /* at rest before the hold's end */
		}
		if (hold_len == 0 && k > hold_at && holds < 4) {
			hold_at = k + (long)uni(100.0, 800.0);
		}
	}
	assert_int_equal(mode, MLIP_PLANQ_DONE);
	assert_true(holds >= 2);
	assert_memory_equal(x, f.last, sizeof(x));
	check_physics(&c);
	assert_int_equal(q.c.starved, 0); /* only the holds braked */
	assert_int_equal(q.c.brakes, holds);
}

/* Holds at random periods on a curve that binds the plan (its normal
 * acceleration at V reaches 1.8 A), with a gentle second policy (100
 * mm/s^2): a state only it certifies begins a hold at 0.1 A, and the hold's
 * plan (planq.h) then brakes as hard as the states allow. Each hold is run
 * twice from the same state: by the consumer's own run alone (a copy of
 * the queue with no producer: the old hold) and with the hold's plan. The
 * plan's stop is never later than the own run's (one period's rounding
 * aside) and far sooner after the gentle policy; every limit and the path
 * hold throughout. */
static struct mlip_planq own;

static void test_hold_brakes_hard(void **state)
{
	(void)state;
	struct feed f;
	struct check c, co;
	gentle = 100.0;
	feed_init(&f, 40.0);
	check_init(&c);
	double x[3];
	int mode = MLIP_PLANQ_WAIT, holds = 0, gentle_holds = 0, faster = 0;
	long hold_at = (long)uni(200.0, 400.0), worst_extra = -1000000;
	double best = 1.0;
	for (long k = 0; k < 400000 && mode != MLIP_PLANQ_DONE; k++) {
		produce_some(&f);
		assert_int_equal(f.fail, 0);
		if (k == hold_at && mode == MLIP_PLANQ_PLAN && q.c.st.v > 10.0) {
			/* the old hold: the own run from this state, alone */
			own = q;
			co = c;
			long own_n = 0;
			int m;
			/* at rest: v and a 0 (its request from there stays unread) */
			for (m = mode; own_n < 100000 && !(own.c.st.v == 0.0 && own.c.st.a == 0.0);
			     own_n++) {
				m = mlip_planq_step(&own, 1, x);
				assert_true(m >= 0);
				check_point(&co, x);
			}
			assert_true(own.c.st.v == 0.0 && own.c.st.a == 0.0);
			int policy = q.c.st.brake;
			long n = 0, popped = 0;
			for (m = mode; n < 100000 && !(q.c.st.v == 0.0 && q.c.st.a == 0.0); n++) {
				m = mlip_planq_step(&q, 1, x);
				popped += m == MLIP_PLANQ_PLAN;
				assert_true(m >= 0);
				check_point(&c, x);
				produce_some(&f);
				assert_int_equal(f.fail, 0);
			}
			assert_true(q.c.st.v == 0.0 && q.c.st.a == 0.0);
			/* the hold's plan is asked only from a gentler policy's state */
			assert_true(policy == 1 ? popped > 0 : popped == 0);
			holds++;
			gentle_holds += policy == 1;
			worst_extra = n - own_n > worst_extra ? n - own_n : worst_extra;
			if (policy == 1) {
				best = fmin(best, (double)n / (double)own_n);
				faster += n < own_n / 2;
			}
			mode = mlip_planq_step(&q, 0, x); /* released */
			check_point(&c, x);
			k += n;
			hold_at = k + (long)uni(100.0, 400.0);
			continue;
		}
		mode = mlip_planq_step(&q, 0, x);
		assert_true(mode >= 0);
		check_point(&c, x);
		if (k >= hold_at && mode != MLIP_PLANQ_PLAN) {
			hold_at = k + 1;
		}
	}
	gentle = 0.0;
	print_message("holds %d (%d from the gentle policy, %d of those in under half the own "
	              "run's periods, the best %.2f of it); the plan's stop at most %ld periods "
	              "after the own run's; J %.4f, A %.4f, off %.2e mm\n",
	              holds, gentle_holds, faster, best, worst_extra, c.max_j / JERK, c.max_a / ACC,
	              c.max_off);
	assert_int_equal(mode, MLIP_PLANQ_DONE);
	assert_memory_equal(x, f.last, sizeof(x));
	check_physics(&c);
	assert_true(holds >= 20);
	assert_true(worst_extra <= 1);
	assert_true(gentle_holds >= 3 && faster >= 1);
}

/* A lower feed during a hold from a gentle policy's state, before the
 * hold's plan is taken (LOWER_AT periods in; it is taken MLIP_PLANQ_LEAD
 * on): the hold's run is the hold's alone, setpoint for setpoint, and the
 * lower cap is the resumed plan's. Each of HF_TRIES states on the curve
 * that only the gentle policy certifies is held twice from a copy of the
 * queue, the plan and the input (all deterministic): without and with the
 * lower feed. Before, the lower feed's plan replaced the hold's and the
 * hold braked at the gentle policy to rest. Released, the plan runs at the
 * lower cap (1000 periods, then the full cap again). */
#define LOWER_AT 3
#define HF_TRIES 4
#define HF_MAX   20000
static struct mlip_pathrun pr_copy;
static struct mlip_planq q_copy;
static struct feed f_copy;
static struct check c_copy;

/* The hold tests' point to try from: a gentle policy's state at speed. */
static int gentle_at_speed(int mode)
{
	return mode == MLIP_PLANQ_PLAN && q.c.st.brake == 1 && q.c.st.v > 10.0;
}

/* The run (producer, queue, feed, checks) kept to try again from. */
static void snap_save(const struct feed *f, const struct check *c)
{
	pr_copy = pr;
	q_copy = q;
	f_copy = *f;
	c_copy = *c;
}

static void snap_restore(struct feed *f, struct check *c)
{
	pr = pr_copy;
	q = q_copy;
	*f = f_copy;
	*c = c_copy;
}
static double hf_x[2][HF_MAX][3];

/* Held from here to rest (the copy's state), a lower feed `cap` LOWER_AT
 * periods in when cap > 0: its setpoints in xs, how many; popped: periods
 * the hold's plan gave. */
static long held_run(struct feed *f, struct check *c, double cap, double (*xs)[3], long *popped)
{
	long n = 0;
	*popped = 0;
	for (; n < HF_MAX && !(n > 0 && q.c.st.v == 0.0 && q.c.st.a == 0.0); n++) {
		if (cap > 0.0 && n == LOWER_AT) {
			assert_int_equal(mlip_planq_feed(&q, cap), 0);
		}
		int m = mlip_planq_step(&q, 1, xs[n]);
		assert_true(m >= 0);
		*popped += m == MLIP_PLANQ_PLAN;
		check_point(c, xs[n]);
		produce_some(f);
		assert_int_equal(f->fail, 0);
	}
	assert_true(n < HF_MAX);
	return n;
}

static void test_hold_keeps_its_plan_under_a_lower_feed(void **state)
{
	(void)state;
	struct feed f;
	struct check c;
	gentle = 100.0;
	feed_init(&f, 40.0);
	check_init(&c);
	double x[3], cap = 0.5 * 0.995 * V, max_v = 0.0, max_sv = 0.0;
	int mode = MLIP_PLANQ_WAIT, tries = 0;
	long next = 200, faster = 0, lowered = -1;
	for (long k = 0; k < 400000 && mode != MLIP_PLANQ_DONE; k++) {
		produce_some(&f);
		assert_int_equal(f.fail, 0);
		if (tries < HF_TRIES && k >= next && gentle_at_speed(mode)) {
			snap_save(&f, &c);
			long pa, pb, own_n = 0;
			double v0 = q.c.st.v;
			long na = held_run(&f, &c, 0.0, hf_x[0], &pa);
			snap_restore(&f, &c);
			long nb = held_run(&f, &c, cap, hf_x[1], &pb);
			assert_true(pa > 0); /* the hold's plan took over */
			assert_int_equal(nb, na);
			assert_memory_equal(hf_x[1], hf_x[0], sizeof(hf_x[0][0]) * (size_t)na);
			/* the gentle policy's own run (a copy of the queue alone) is longer */
			q_copy.c.held = 1;
			for (; own_n < HF_MAX && !(q_copy.c.st.v == 0.0 && q_copy.c.st.a == 0.0);
			     own_n++) {
				assert_true(mlip_planq_step(&q_copy, 1, x) >= 0);
			}
			print_message(
			    "hold at %ld (%.1f mm/s): %ld periods to rest, %ld of them the "
			    "hold's plan; with the lower feed %ld (%ld); the gentle run %ld\n",
			    k, v0, na, pa, nb, pb, own_n);
			faster += na < own_n;
			tries++;
			mode = mlip_planq_step(&q, 0, x); /* released: at the lower cap */
			check_point(&c, x);
			next = k + 2000;
			lowered = k + 1000;
			continue;
		}
		if (k == lowered) { /* the full cap again: the next hold's state */
			assert_int_equal(mlip_planq_feed(&q, 0.995 * V), 0);
		}
		double prev[3];
		memcpy(prev, x, sizeof(prev));
		mode = mlip_planq_step(&q, 0, x);
		assert_true(mode >= 0);
		check_point(&c, x);
		if (k < lowered) { /* the resumed plan, at the lower cap */
			max_sv = fmax(max_sv, q.c.st.v);
			max_v = fmax(max_v, sqrt((x[0] - prev[0]) * (x[0] - prev[0]) +
			                         (x[1] - prev[1]) * (x[1] - prev[1]) +
			                         (x[2] - prev[2]) * (x[2] - prev[2])) /
			                        T);
		}
	}
	gentle = 0.0;
	print_message("%d holds, %ld sooner than the gentle policy's run; resumed at most "
	              "%.4f mm/s on the plan, %.4f by the chord (cap %.4f)\n",
	              tries, faster, max_sv, max_v, cap);
	assert_int_equal(mode, MLIP_PLANQ_DONE);
	assert_memory_equal(x, f.last, sizeof(x));
	check_physics(&c);
	assert_int_equal(tries, HF_TRIES);
	assert_int_equal(faster, HF_TRIES);
	/* the cap is on the plan's speed; the chord's within 1 % (as test_override) */
	assert_true(max_sv <= cap * (1.0 + 1e-12));
	assert_true(max_v <= 1.01 * cap && max_v >= 0.9 * cap);
}

/* Released on the hold's plan after a lower feed (the case above, the
 * hold let go RELEASE_AT periods in, still moving): up to the release the
 * setpoints are the hold's alone, bit for bit; the plan asked at the
 * release (from the hold's state MLIP_PLANQ_LEAD on, at the lower cap)
 * takes over without a rest, and runs at the lower cap; every sample
 * within A and J, on the curve. */
#define RELEASE_AT (LOWER_AT + MLIP_PLANQ_LEAD + 12)
static void test_release_on_the_hold_plan_after_a_lower_feed(void **state)
{
	(void)state;
	struct feed f;
	struct check c;
	gentle = 100.0;
	feed_init(&f, 40.0);
	check_init(&c);
	double x[3], prev[3], cap = 0.5 * 0.995 * V, max_sv = 0.0, min_v = 1e9;
	int mode = MLIP_PLANQ_WAIT, tries = 0;
	long next = 200, lowered = -1, held_out = -1, settled = -1;
	double worst_settle = 0.0;
	for (long k = 0; k < 400000 && mode != MLIP_PLANQ_DONE; k++) {
		produce_some(&f);
		assert_int_equal(f.fail, 0);
		if (tries < HF_TRIES && k >= next && gentle_at_speed(mode)) {
			snap_save(&f, &c);
			long pa;
			(void)held_run(&f, &c, 0.0, hf_x[0],
			               &pa); /* the hold alone, for reference */
			assert_true(pa > 0);
			snap_restore(&f, &c);
			long n = 0, popped = 0;
			for (; n < RELEASE_AT; n++) {
				if (n == LOWER_AT) {
					assert_int_equal(mlip_planq_feed(&q, cap), 0);
				}
				int m = mlip_planq_step(&q, 1, x);
				assert_true(m >= 0);
				popped += m == MLIP_PLANQ_PLAN;
				check_point(&c, x);
				assert_memory_equal(x, hf_x[0][n], sizeof(x));
				produce_some(&f);
				assert_int_equal(f.fail, 0);
			}
			/* on the hold's plan, not yet at its crawl */
			assert_true(popped > 0 && mode >= 0);
			assert_true(q.c.st.v > 1.0);
			print_message("hold at %ld: released %d periods in at %.2f mm/s\n", k,
			              RELEASE_AT, q.c.st.v);
			tries++;
			k += n;
			held_out = k + 1; /* from here: no rest before the program's end */
			settled = -1;
			next = k + 2000;
			lowered = k + 1000;
			memcpy(prev, x, sizeof(prev));
			continue;
		}
		if (k == lowered) { /* the full cap again: the next hold's state */
			assert_int_equal(mlip_planq_feed(&q, 0.995 * V), 0);
		}
		mode = mlip_planq_step(&q, 0, x);
		assert_true(mode >= 0);
		check_point(&c, x);
		if (held_out >= 0 && k < lowered) {
			/* released above the lower cap: down to it, then within it */
			if (settled < 0 && q.c.st.v <= cap) {
				settled = k;
				worst_settle = fmax(worst_settle, (double)(k - held_out));
			}
			if (settled >= 0) {
				max_sv = fmax(max_sv, q.c.st.v);
			}
			min_v = fmin(min_v, q.c.st.v);
		}
		memcpy(prev, x, sizeof(prev));
	}
	gentle = 0.0;
	print_message("%d releases; after each, down to the lower cap in %.0f periods at most, "
	              "then at most %.4f mm/s (cap %.4f); at least %.4f mm/s from the release to "
	              "the full cap again\n",
	              tries, worst_settle, max_sv, cap, min_v);
	assert_int_equal(mode, MLIP_PLANQ_DONE);
	assert_memory_equal(x, f.last, sizeof(x));
	check_physics(&c);
	assert_int_equal(tries, HF_TRIES);
	/* 42 -> 29.85 mm/s at 0.25 A or more takes 49 periods, plus the lead */
	assert_true(worst_settle > 0.0 && worst_settle <= 49 + 2 * MLIP_PLANQ_LEAD);
	assert_true(max_sv <= cap * (1.0 + 1e-12));
	assert_true(min_v > 1.0); /* it never came to rest: the released plan took over */
}

/* A hold from a gentle policy's state while the producer is late by
 * late[i] periods (it does nothing from the hold on for that long): the
 * hold's plan comes late or never, and the hold still ends at rest within A
 * and J, never later than the state's own run. A plan that comes in time
 * (late < MLIP_PLANQ_LEAD) gives the hold on time's setpoints bit for bit;
 * one that comes after the run passed the state it was asked from is not
 * taken, and asked again from the run's state then: the own run's
 * setpoints up to the producer's return at least, then the hold's plan,
 * at rest sooner than the own run (before, the own run all the way); a
 * producer back only after the own run ended leaves it the own run's. A
 * producer that stops STALL_LEN periods from STALL_AT on, once the hold's
 * plan is taken, runs the queue dry on it: the run brakes by its state's
 * policy, the plan's own there (it takes the hardest that certifies the
 * state), and the plan's entries continue it once the producer is back:
 * the on-time hold's setpoints. */
#define STALL_AT  (MLIP_PLANQ_LEAD + 2)
#define STALL_LEN 60

static void test_hold_under_a_late_producer(void **state)
{
	(void)state;
	static const long late[] = {2, MLIP_PLANQ_LEAD / 2, 2 * MLIP_PLANQ_LEAD, 1000, -1};
	enum { N_LATE = sizeof(late) / sizeof(late[0]) };
	struct feed f;
	struct check c;
	gentle = 100.0;
	feed_init(&f, 40.0);
	check_init(&c);
	double x[3];
	int mode = MLIP_PLANQ_WAIT, tries = 0, same_on_time = 0, same_own = 0, sooner = 0,
	    retaken = 0;
	long worst_late = 0, best_own = HF_MAX;
	long next = 200;
	for (long k = 0; k < 400000 && mode != MLIP_PLANQ_DONE; k++) {
		produce_some(&f);
		assert_int_equal(f.fail, 0);
		if (tries < 3 && k >= next && gentle_at_speed(mode)) {
			snap_save(&f, &c);
			long pa, own_n = 0;
			long na = held_run(&f, &c, 0.0, hf_x[0], &pa); /* the producer on time */
			assert_true(pa > 0);
			own = q_copy; /* the state's own run, alone */
			own.c.held = 1;
			for (; own_n < HF_MAX && !(own.c.st.v == 0.0 && own.c.st.a == 0.0);
			     own_n++) {
				assert_true(mlip_planq_step(&own, 1, hf_x[1][own_n]) >= 0);
			}
			for (int i = 0; i < N_LATE; i++) {
				snap_restore(&f, &c);
				long n = 0, own_upto = -1; /* the own run's setpoints to here */
				int differs_on_time = 0, differs_own = 0, m = MLIP_PLANQ_PLAN,
				    takes = 0;
				for (; n < HF_MAX && !(n > 0 && q.c.st.v == 0.0 && q.c.st.a == 0.0);
				     n++) {
					int before = m;
					m = mlip_planq_step(&q, 1, x);
					assert_true(m >= 0);
					takes += before == MLIP_PLANQ_BRAKE && m == MLIP_PLANQ_PLAN;
					check_point(&c, x);
					differs_on_time |=
					    n >= na || memcmp(x, hf_x[0][n], sizeof(x)) != 0;
					differs_own |=
					    n >= own_n || memcmp(x, hf_x[1][n], sizeof(x)) != 0;
					own_upto = differs_own ? own_upto : n;
					if (late[i] < 0 ? n < STALL_AT || n >= STALL_AT + STALL_LEN
					                : n >= late[i]) {
						produce_some(&f);
						assert_int_equal(f.fail, 0);
					}
				}
				assert_true(n < HF_MAX);
				differs_on_time |= n != na;
				differs_own |= n != own_n;
				char how[64];
				if (late[i] < 0) {
					snprintf(how, sizeof(how), "stopped %d periods from %d on",
					         STALL_LEN, STALL_AT);
				} else {
					snprintf(how, sizeof(how), "%ld periods late", late[i]);
				}
				print_message(
				    "hold at %ld, the producer %s: %ld periods to "
				    "rest (on time %ld, the own run %ld), plans taken %d%s\n",
				    k, how, n, na, own_n, takes,
				    !differs_on_time ? ": the hold on time's"
				    : !differs_own   ? ": the own run's"
				                     : "");
				assert_true(n <= own_n);
				if (late[i] < 0) {
					/* the hold's plan, the queue dry on it, the plan again */
					assert_false(differs_on_time);
					assert_int_equal(takes, 2);
					retaken++;
				} else if (late[i] < MLIP_PLANQ_LEAD) {
					assert_false(differs_on_time);
					same_on_time++;
				} else if (late[i] >= own_n) {
					assert_false(differs_own);
					same_own++;
				} else { /* asked again once the producer is back */
					assert_true(own_upto >= late[i]);
					assert_true(n >= na && n < own_n);
					sooner++;
					worst_late = n > worst_late ? n : worst_late;
					best_own = own_n < best_own ? own_n : best_own;
				}
			}
			tries++;
			mode = mlip_planq_step(&q, 0, x); /* released from the last: at rest */
			check_point(&c, x);
			next = k + 2000;
			continue;
		}
		mode = mlip_planq_step(&q, 0, x);
		assert_true(mode >= 0);
		check_point(&c, x);
	}
	gentle = 0.0;
	assert_int_equal(mode, MLIP_PLANQ_DONE);
	assert_memory_equal(x, f.last, sizeof(x));
	check_physics(&c);
	assert_int_equal(tries, 3);
	/* each case is met: a plan in time, one asked again, one too late */
	print_message("late producer: %d holds on time's, %d asked again (at rest in %ld periods "
	              "at most, the own run %ld at least), %d the own run's; a stall on the "
	              "hold's plan: taken up again %d times of 3\n",
	              same_on_time, sooner, worst_late, best_own, same_own, retaken);
	assert_true(same_on_time == 6 && sooner == 3 && same_own == 3);
	assert_int_equal(retaken, 3);
}

/* A lower feed at a random period: the braking run starts in that period
 * and the plan at the new cap takes over MLIP_PLANQ_LEAD periods later,
 * continuing the run bit for bit (no stop); the speed then stays within
 * the cap; a higher feed then keeps the plan up to the queued state
 * MLIP_PLANQ_LEAD periods on, the plan at the new cap from there. When the producer stalls past the
 * whole run, the run ends at rest and the plan starts again from there, at the new cap. (A plan a
 * little late is still taken where it continues the run: while it brakes
 * on the same policy, its states are the run's. One read after its first
 * period passed is asked again from the run LEAD periods on: late by
 * LATE_PERIODS, less than the run to rest, the run never rests.) */
#define LATE_PERIODS 80 /* a producer late by more than the lead, less than the run to rest */

static void run_override(int stall_after)
{
	struct feed f;
	struct check c;
	feed_init(&f, 16.0);
	check_init(&c);
	/* late by LATE_PERIODS: a first cap close to the speed (the run to
	 * rest from it is longer than the lateness) */
	double x[3], prev[3],
	    caps[2] = {(stall_after == 2 ? 0.9 : 0.7) * 0.995 * V, 0.4 * 0.995 * V};
	int mode = MLIP_PLANQ_WAIT, n_cap = 0, rests = 0;
	long at = (long)uni(300.0, 600.0), stall = 0, took = -1, settled = -1, raised = -1,
	     faster = -1, late_took[2] = {-1, -1};
	double cap = 0.995 * V, max_v_after = 0.0, max_v_raised = 0.0;
	memcpy(prev, f.last, sizeof(prev));
	curve_at(0.0, prev);
	for (long k = 0; k < 200000 && mode != MLIP_PLANQ_DONE; k++) {
		if (stall > 0) {
			stall--;
		} else {
			produce_some(&f);
			assert_int_equal(f.fail, 0);
		}
		if (k == at) {
			cap = caps[n_cap++];
			assert_int_equal(mlip_planq_feed(&q, cap), 0);
			assert_int_equal(mlip_planq_feed(&q, 0.0), -1); /* ignored */
			assert_int_equal(mlip_planq_feed(&q, NAN), -1);
			stall = stall_after == 1   ? STOP_PERIODS
			        : stall_after == 2 ? LATE_PERIODS
			                           : 0;
			took = -1;
		}
		int before = mode;
		mode = mlip_planq_step(&q, 0, x);
		assert_true(mode >= 0);
		check_point(&c, x);
		rests += before == MLIP_PLANQ_BRAKE && mode == MLIP_PLANQ_WAIT;
		if (k == at) {
			assert_int_equal(before, MLIP_PLANQ_PLAN);
			assert_int_equal(mode, MLIP_PLANQ_BRAKE); /* in that period */
		}
		if (k > at && took < 0 && before == MLIP_PLANQ_BRAKE && mode == MLIP_PLANQ_PLAN) {
			took = k; /* the new plan continued the run */
			if (!stall_after) {
				assert_int_equal(took - at, MLIP_PLANQ_LEAD + 1);
			}
			if (stall_after == 2) {
				/* asked again once read late, from LEAD on */
				assert_in_range(took - at, LATE_PERIODS + MLIP_PLANQ_LEAD + 1,
				                LATE_PERIODS + 2 * MLIP_PLANQ_LEAD);
				late_took[n_cap - 1] = took - at;
			}
		}
		if (k > at && took < 0 && mode == MLIP_PLANQ_WAIT) {
			took = k; /* at rest: the plan from there */
		}
		double d = 0.0;
		for (int a = 0; a < 3; a++) {
			d += (x[a] - prev[a]) * (x[a] - prev[a]);
		}
		if (n_cap == 2 && took > 0 && k > took + 400 && raised < 0) {
			settled = k;
			max_v_after = fmax(max_v_after, sqrt(d) / T);
		}
		if (n_cap == 2 && took > 0 && k == took + 700) {
			raised = k; /* the feed back up: no stop, faster within the queue */
			mlip_planq_feed(&q, 0.995 * V);
		}
		if (raised > 0 && k <= raised + MLIP_PLANQ_LEN + 200) {
			max_v_raised = fmax(max_v_raised, sqrt(d) / T);
			if (faster < 0 && sqrt(d) / T > 1.01 * caps[1]) {
				faster = k - raised;
			}
		}
		if (n_cap == 1 && took > 0 && k == took + 600) {
			at = k + (long)uni(1.0, 300.0); /* the second, lower still */
		}
		memcpy(prev, x, sizeof(x));
	}
	assert_int_equal(mode, MLIP_PLANQ_DONE);
	assert_memory_equal(x, f.last, sizeof(x));
	check_physics(&c);
	assert_int_equal(n_cap, 2);
	assert_true(settled > 0);
	assert_int_equal(q.c.starved, 0);
	assert_int_equal(q.c.brakes, 2);
	/* stopped only when late past the run to rest */
	assert_int_equal(rests, stall_after == 1 ? 2 : 0);
	/* the last cap kept (the chord's speed, the spline's parameter within
	 * 1 % of the arc's) and reached */
	assert_true(max_v_after <= 1.01 * caps[1]);
	assert_true(max_v_after >= 0.8 * caps[1]);
	assert_true(raised > 0);
	assert_true(max_v_raised >= 1.3 * caps[1]);
	/* from the queued state LEAD periods on, then the ramp */
	assert_true(faster > MLIP_PLANQ_LEAD && faster <= MLIP_PLANQ_LEAD + 20);
	print_message("override%s: speed after %.3f of the cap; raised: %.3f, above the cap after "
	              "%ld periods; plans taken %ld, %ld periods after the feed\n",
	              stall_after == 1   ? " (late)"
	              : stall_after == 2 ? " (a little late)"
	                                 : "",
	              max_v_after / caps[1], max_v_raised / caps[1], faster, late_took[0],
	              late_took[1]);
}

static void test_override(void **state)
{
	(void)state;
	run_override(0);
}

static void test_override_late(void **state)
{
	(void)state;
	run_override(1);
	run_override(2); /* late, asked again: no rest */
}

/* A producer thread beside the consumer (make tsan checks the queue's
 * accesses): the consumer steps as soon as an entry is there, and now and
 * then without waiting (it starves), with a hold or a new feed. */
static struct feed tf;
static int consumer_done, producer_failed;

static void *producer(void *arg)
{
	(void)arg;
	while (!__atomic_load_n(&consumer_done, __ATOMIC_ACQUIRE) && !tf.fail) {
		int r = unit(&tf);
		if (r == 0 || r == 2) {
			sched_yield();
		}
	}
	__atomic_store_n(&producer_failed, tf.fail, __ATOMIC_RELEASE);
	return NULL;
}

static void test_thread(void **state)
{
	(void)state;
	struct check c;
	feed_init(&tf, 4.0);
	check_init(&c);
	consumer_done = 0;
	producer_failed = 0;
	pthread_t th;
	assert_int_equal(pthread_create(&th, NULL, producer, NULL), 0);
	double x[3];
	int mode = MLIP_PLANQ_WAIT;
	long hold = 0, k;
	for (k = 0; k < 1000000 && mode != MLIP_PLANQ_DONE &&
	            !__atomic_load_n(&producer_failed, __ATOMIC_ACQUIRE);
	     k++) {
		int eager = uni(0.0, 1.0) < 0.01;
		/* wait for an entry (a generous bound: the producer is slow under tsan) */
		for (long spin = 0; !eager && mode != MLIP_PLANQ_BRAKE && spin < 100000000;
		     spin++) {
			if (__atomic_load_n(&q.head, __ATOMIC_ACQUIRE) != q.tail) {
				break;
			}
			sched_yield();
		}
		if (hold == 0 && uni(0.0, 1.0) < 0.005) {
			hold = (long)uni(1.0, 300.0);
		}
		if (uni(0.0, 1.0) < 0.005) { /* a feed override, lower or higher */
			mlip_planq_feed(&q, uni(0.3, 1.0) * 0.995 * V);
		}
		mode = mlip_planq_step(&q, hold > 0, x);
		hold -= hold > 0;
		assert_true(mode >= 0);
		check_point(&c, x);
	}
	__atomic_store_n(&consumer_done, 1, __ATOMIC_RELEASE);
	pthread_join(th, NULL);
	assert_int_equal(tf.fail, 0);
	assert_int_equal(mode, MLIP_PLANQ_DONE);
	assert_memory_equal(x, tf.last, sizeof(x));
	assert_true(c.max_j <= JERK * (1.0 + 1e-6));
	assert_true(c.max_a <= ACC * (1.0 + 1e-6));
	assert_true(c.max_off <= PATH_TOL);
	print_message("thread: %ld periods, %ld brakes (%ld starved)\n", k, q.c.brakes,
	              q.c.starved);
}

/* Deterministic: the consumer's setpoints, when the queue never runs dry
 * and nothing holds, are the plan's own (mlip_pathrun_step alone, as
 * mlip-sim --jerk-plan path runs it, tools/lib/simpath.c) bit for bit,
 * whether the consumer follows the producer closely, a whole queue behind,
 * at a lag that wanders, or pops in bursts: what the compaction of the
 * window keeps is the plan's own (its state MLIP_PATHRUN_LAG periods
 * back), never the consumer's. On the fast curve the window's look-ahead
 * binds the plan (a compaction from the consumer's knot, as before,
 * changed its setpoints with the lag). */
#define LAG_MAX 20000
static double lag_ref[LAG_MAX][3], lag_got[LAG_MAX][3];

enum { LAG_FIXED, LAG_WANDER, LAG_BURST };

/* The queue's fill the producer keeps before the consumer's period k. */
static int lag_fill(int how, int lag, long k, int ahead)
{
	static int want;
	if (how == LAG_FIXED) {
		return lag < 1 ? 1 : lag;
	}
	if (how == LAG_WANDER) {
		if (k == 0 || uni(0.0, 1.0) < 1.0 / 32.0) {
			want = (int)uni(1.0, MLIP_PLANQ_LEN + 0.999);
		}
		return want;
	}
	/* bursts: the producer fills the whole queue, then nothing while the
	 * consumer pops lag entries (it never runs dry: lag < LEN) */
	return ahead <= MLIP_PLANQ_LEN - lag ? MLIP_PLANQ_LEN : 0;
}

static long lag_run(int how, int lag, double (*out)[3])
{
	struct feed f;
	feed_init(&f, 3000.0);
	long n = 0;
	int mode = MLIP_PLANQ_WAIT;
	while (mode != MLIP_PLANQ_DONE && n < LAG_MAX && !f.fail) {
		uint32_t ahead = __atomic_load_n(&q.head, __ATOMIC_ACQUIRE) - q.tail;
		int want = lag_fill(how, lag, n, (int)ahead);
		for (long i = 0; i < 1000000 && !f.fail; i++) {
			ahead = __atomic_load_n(&q.head, __ATOMIC_ACQUIRE) - q.tail;
			if ((int)ahead >= want || q.p_done) {
				break;
			}
			int r = unit(&f);
			if (r == 0 || r == 2) {
				break;
			}
		}
		mode = mlip_planq_step(&q, 0, out[n]);
		n += mode == MLIP_PLANQ_PLAN || mode == MLIP_PLANQ_DONE;
		assert_true(mode != MLIP_PLANQ_BRAKE);
	}
	assert_int_equal(f.fail, 0);
	assert_int_equal(mode, MLIP_PLANQ_DONE);
	assert_int_equal(q.c.left, 0); /* it followed the chain: the bound held */
	return n;
}

static void test_lag_independent(void **state)
{
	(void)state;
	struct feed f;
	fast = 1;
	feed_init(&f, 3000.0);
	long n = 0;
	for (long i = 0; n < LAG_MAX && !f.fail; i++) {
		/* the reference: input until the window is full, then a period */
		if (f.pending || !f.finished) {
			if (f.pending) {
				int r = mlip_pathrun_push(&pr, f.in);
				f.fail |= r < 0;
				if (r != 1) {
					f.pending = 0;
					continue;
				}
			} else {
				(void)unit(&f); /* the next input point, or the end */
				continue;
			}
		}
		int r = mlip_pathrun_step(&pr, lag_ref[n]);
		assert_true(r >= 0);
		n += r > 0;
		if (r == 2) {
			break;
		}
	}
	assert_int_equal(f.fail, 0);
	/* the window bound it: the plan compacted and its speed stayed below
	 * the cap on the straight (a stop from the cap takes more than the
	 * window's look-ahead less the lag's) */
	double vmax = 0.0;
	for (long k = 1; k < n; k++) {
		double dx = lag_ref[k][0] - lag_ref[k - 1][0],
		       dy = lag_ref[k][1] - lag_ref[k - 1][1];
		vmax = fmax(vmax, sqrt(dx * dx + dy * dy) / T);
	}
	assert_true(pr.dropped >= 4 * MLIP_PATHRUN_CAP / 4);
	assert_true(vmax > 0.3 * FAST_V && vmax < 0.99 * 0.995 * FAST_V);
	static const struct {
		int how, lag;
	} runs[] = {{LAG_FIXED, 0},   {LAG_FIXED, 4},   {LAG_FIXED, 100},
	            {LAG_FIXED, 255}, {LAG_FIXED, 256}, {LAG_WANDER, 0},
	            {LAG_BURST, 50},  {LAG_BURST, 200}, {LAG_BURST, 255}};
	for (size_t li = 0; li < sizeof(runs) / sizeof(runs[0]); li++) {
		long m = lag_run(runs[li].how, runs[li].lag, lag_got);
		long first = -1;
		for (long k = 0; k < (m < n ? m : n) && first < 0; k++) {
			if (memcmp(lag_ref[k], lag_got[k], sizeof(lag_ref[k])) != 0) {
				first = k;
			}
		}
		print_message("lag %d (%s): %ld periods (alone %ld, top speed %.1f mm/s), first "
		              "differing %ld\n",
		              runs[li].lag,
		              runs[li].how == LAG_FIXED    ? "fixed"
		              : runs[li].how == LAG_WANDER ? "wandering"
		                                           : "bursts",
		              m, n, vmax, first);
		assert_int_equal(m, n);
		assert_int_equal(first, -1);
	}
	fast = 0;
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_stalls),
	    cmocka_unit_test(test_hold),
	    cmocka_unit_test(test_hold_brakes_hard),
	    cmocka_unit_test(test_hold_keeps_its_plan_under_a_lower_feed),
	    cmocka_unit_test(test_release_on_the_hold_plan_after_a_lower_feed),
	    cmocka_unit_test(test_hold_under_a_late_producer),
	    cmocka_unit_test(test_override),
	    cmocka_unit_test(test_override_late),
	    cmocka_unit_test(test_thread),
	    cmocka_unit_test(test_lag_independent),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
