/*
 * test_ctl_start.c - a stop or a bad record in a program's first periods
 * (issue 17): the pure controller on a virtual clock, the look-ahead at its
 * full depth (4096, as mlip-rt runs it) so that the pre-read and the first
 * look-ahead's work span many periods (the planner's bounded work a period,
 * mlip_planner_set_async). For every period of that window the stop (or the
 * bad record) is injected in a fresh run, and the setpoints are judged
 * against a run without it:
 *   - latched before the first motion period (a pre-read of a new program,
 *     or the pre-read during a wait): no setpoint ever changes;
 *   - a stop after motion began: the setpoints before it are the reference's,
 *     then the machine brakes on the path to rest, within the limits, braking
 *     from at most LAG_MAX periods after the stop (the planner's stop);
 *   - a bad record met after motion began: the setpoints before it are the
 *     reference's, and the machine comes to rest exactly at the end of the
 *     last good block (the look-ahead always plans its newest block to rest,
 *     so braking can always make it);
 *   - the feeder gone (mlip-feed found its file changed): the machine comes
 *     to rest exactly at the end of the last block it sent.
 * Every run stays within the acceleration limits (second differences).
 */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "mlip/ctl/controller.h"
#include "mlip/machine/config.h"
#include "mlip/motion/smooth.h"

#define RING_CAP 8192u
#define ROW      300 /* 0.1 mm segments a row, then a 0.5 mm step in Y */
#define MAXP     40000
#define ACCEL    1000.0
#define FEED     200.0
#define TOL      0.01
#define DWELL_S  0.1
#define LAG_MAX  5 /* periods from a stop to braking (see the stop's test) */

static struct mlip_machine mach;
static struct mlip_planner planner;
static struct mlip_ctl ctl;
static struct mlip_ctl_out out;
static struct mlip_ring *ring;
static struct mlip_ring_port rx;
static void *mem;
static uint64_t period;
static uint32_t stop_count;
static int exit_request; /* SIGTERM to mlip-rt */

/* the program: n_moves blocks (with a dwell after block 1: wait = 1), END */
static uint64_t n_moves, next_seq;
static int wait_prog;
/* the feeder: records a period (0: as many as fit), whether it is alive, and
 * the last record it has (0: all of them; it lags behind, alive): set
 * before start, reset by the teardown */
static uint32_t feed_rate;
static int feeder_alive;
static uint64_t feed_upto;
/* the controller: strategy, look-ahead depth (0: 4096) and every axis's
 * MAX_JERK (0: none); set before start, reset by the teardown */
static mlip_strategy strategy = MLIP_STRATEGY_MPCT;
static uint32_t lookahead;
static double jerk;
static struct mlip_smooth_store store;

/* a run: the setpoint and the state after each period */
struct run {
	int n;
	double x[MAXP], y[MAXP];
	uint32_t state[MAXP];
};
static struct run ref, cur;

static void machine(void)
{
	memset(&mach, 0, sizeof(mach));
	mach.n_axes = 2;
	mach.max_feed_mm_s = FEED;
	mach.max_rot_feed_deg_s = 360.0;
	mach.tolerance_mm = TOL;
	mach.period_s = 0.001;
	for (int k = 0; k < 2; k++) {
		mach.axis[k].letter = "XY"[k];
		mach.axis[k].kind = MLIP_AXIS_LINEAR;
		mach.axis[k].max_accel = ACCEL;
		mach.axis[k].max_vel = FEED;
		mach.axis[k].min_limit = -1000.0;
		mach.axis[k].max_limit = 1000.0;
		mach.axis[k].can_node = k + 1;
		mach.axis[k].counts_per_unit = 1000.0;
		mach.axis[k].max_jerk = jerk;
	}
}

/* Block seq's end point: a zigzag of 0.1 mm segments (a turn every 30 mm) */
static void target(uint64_t seq, double *x, double *y)
{
	uint64_t k = seq - 1, r = k / (ROW + 1), i = k % (ROW + 1);
	if (i == ROW) {
		*x = r % 2 == 0 ? ROW * 0.1 : 0.0;
		*y = (double)(r + 1) * 0.5;
	} else {
		*x = (double)(r % 2 == 0 ? i + 1 : ROW - 1 - i) * 0.1;
		*y = (double)r * 0.5;
	}
}

/* Record seq of the program (after block 1, the dwell when wait_prog). */
static void record(uint64_t seq, struct mlip_ring_rec *rec)
{
	uint64_t block = wait_prog && seq > 2 ? seq - 1 : seq;
	if (seq > n_moves + (wait_prog ? 1u : 0u)) {
		mlip_ring_rec_end(rec, seq, (uint32_t)seq + 1);
		return;
	}
	struct mlip_block b = {.feed_mm_s = FEED, .tol_mm = TOL, .line = (uint32_t)seq + 1};
	if (wait_prog && seq == 2) {
		b.kind = MLIP_BLOCK_DWELL;
		b.dwell_s = DWELL_S;
	} else {
		target(block, &b.target[0], &b.target[1]);
	}
	mlip_ring_rec_from_block(rec, &b, seq);
}

/* The feeder: as many records as the ring has room for. */
static void feed(void)
{
	uint64_t last = n_moves + (wait_prog ? 2u : 1u); /* the END */
	struct mlip_ring_rec rec;
	for (uint32_t k = 0;
	     feeder_alive && next_seq <= last && mlip_ring_space(ring) > 0 &&
	     (feed_rate == 0 || k < feed_rate) && (feed_upto == 0 || next_seq <= feed_upto);
	     k++) {
		record(next_seq, &rec);
		assert_int_equal(mlip_ring_push(ring, &rec), MLIP_OK);
		next_seq++;
	}
}

static void start(uint64_t moves, int wait)
{
	machine();
	size_t bytes = mlip_ring_bytes(RING_CAP);
	if (mem == NULL) {
		assert_int_equal(posix_memalign(&mem, MLIP_RING_LINE, bytes), 0);
	}
	assert_int_equal(mlip_ring_format_machine(mem, bytes, RING_CAP, &mach), MLIP_OK);
	assert_int_equal(mlip_ring_attach(mem, bytes, 2, &ring, NULL), MLIP_OK);
	struct mlip_ctl_opts o = {.strategy = strategy,
	                          .smooth = strategy == MLIP_STRATEGY_SMOOTH ? &store : NULL,
	                          .lookahead = lookahead}; /* 0: 4096 */
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
	assert_int_equal(mlip_ring_port_open(&rx, ring, 0), MLIP_OK);
	period = 0;
	stop_count = 0;
	exit_request = 0;
	feeder_alive = 1;
	n_moves = moves;
	wait_prog = wait;
	next_seq = 1;
	feed();
}

/* One period, its result into r. */
static void step(struct run *r)
{
	struct mlip_ctl_in in = {.period = period++,
	                         .feeder_alive = feeder_alive,
	                         .stop_requests = stop_count,
	                         .feeder_stop_base = 0,
	                         .exit_request = exit_request};
	feed();
	assert_int_equal(mlip_ring_port_view(&rx, &in.recs, &in.recs_corrupt), MLIP_OK);
	mlip_ctl_period(&ctl, &in, &out);
	assert_int_equal(mlip_ring_port_pop_n(&rx, out.taken), MLIP_OK);
	assert_true(r->n < MAXP);
	r->x[r->n] = out.pos[0];
	r->y[r->n] = out.pos[1];
	r->state[r->n] = out.status.state;
	r->n++;
}

/* A fresh run of the program (start's arguments), its first n periods. */
static void run_to(uint64_t moves, int wait, int n)
{
	start(moves, wait);
	cur.n = 0;
	for (int i = 0; i < n; i++) {
		step(&cur);
	}
}

/* The next record the controller takes gets a NaN target: the bad record. */
static uint64_t corrupt_next(void)
{
	struct mlip_rec_view v;
	uint32_t apart = 0;
	assert_int_equal(mlip_ring_port_view(&rx, &v, &apart), MLIP_OK);
	assert_true(v.len[0] > 0);
	struct mlip_ring_rec *rec = (struct mlip_ring_rec *)&v.span[0][0];
	rec->target[0] = NAN;
	return rec->seq;
}

static int ended(void)
{
	uint32_t s = out.status.state;
	return (s == MLIP_STATE_IDLE || s == MLIP_STATE_FAULT) && out.status.speed_mm_s == 0.0 &&
	       mlip_planner_queued(&planner) == 0;
}

/* Periods (ticks at least one) until at rest in IDLE or FAULT, then ten more
 * (nothing may move after it); the FAULT event's state left, if one came, and
 * its period in fault_period. */
static int fault_period;
static uint32_t settle(struct run *r)
{
	uint32_t from = MLIP_STATE_COUNT;
	fault_period = -1;
	do {
		step(r);
		for (uint32_t i = 0; i < out.n_events; i++) {
			if (out.events[i].kind == MLIP_EV_STATE &&
			    out.events[i].state == MLIP_STATE_FAULT) {
				from = out.events[i].from;
				fault_period = (int)out.events[i].period;
			}
		}
	} while (!ended());
	for (int i = 0; i < 10; i++) {
		step(r);
	}
	return from;
}

/* The reference run: the program without a stop, to its end. */
static void reference(uint64_t moves, int wait)
{
	start(moves, wait);
	ref.n = 0;
	settle(&ref);
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
}

/* The first period in state s of run r (-1: none). */
static int first(const struct run *r, uint32_t s)
{
	for (int i = 0; i < r->n; i++) {
		if (r->state[i] == s) {
			return i;
		}
	}
	return -1;
}

/* Run r's setpoints of periods [from, to) are the reference's, bit for bit. */
static void same_as_reference(const struct run *r, int from, int to)
{
	for (int i = from; i < to; i++) {
		if (r->x[i] != ref.x[i] || r->y[i] != ref.y[i]) {
			fail_msg("period %d: (%.9f, %.9f), the reference (%.9f, %.9f)", i, r->x[i],
			         r->y[i], ref.x[i], ref.y[i]);
		}
	}
}

/* Every setpoint of r from period `from` on is (x, y), bit for bit. */
static void rests_at(const struct run *r, int from, double x, double y)
{
	for (int i = from; i < r->n; i++) {
		if (r->x[i] != x || r->y[i] != y) {
			fail_msg("period %d: (%.9f, %.9f) moved from (%.9f, %.9f)", i, r->x[i],
			         r->y[i], x, y);
		}
	}
}

/* Every axis' second difference within A T^2 (the limits, the planner's
 * margin below them: relative 1e-9, plus rounding of positions ~1e-12). */
static void within_limits(const struct run *r)
{
	double lim = ACCEL * mach.period_s * mach.period_s * (1.0 + 1e-9) + 1e-12;
	for (int i = 2; i < r->n; i++) {
		double ax = r->x[i] - 2.0 * r->x[i - 1] + r->x[i - 2];
		double ay = r->y[i] - 2.0 * r->y[i - 1] + r->y[i - 2];
		if (!(fabs(ax) <= lim && fabs(ay) <= lim)) {
			fail_msg("period %d: second differences %.3g %.3g beyond A T^2 = %.3g", i,
			         ax, ay, lim);
		}
	}
}

/* ---- a stop in each of the program's first periods ---------------------- */

/* The stop posted before period n (the segment's counter), for every n from
 * the program's first period to 40 periods after its first motion period. A
 * stop seen in the pre-read (the motion's first period included: commands
 * are applied before the records) is latched for the program, as for one
 * still being checked: it is dropped unmoved (STOP_EARLY), no setpoint ever
 * changes. Seen after that, the machine brakes on the path within the
 * limits, and the setpoints before the stop are the reference's. */
static void test_stop_in_each_of_the_first_periods(void **st)
{
	(void)st;
	reference(6000, 0);
	int p1 = first(&ref, MLIP_STATE_RUNNING); /* the first motion period */
	/* the window is long: the pre-read of 4096 blocks is bounded work a period */
	assert_true(p1 >= 50 && ref.x[p1] > 0.0 && ref.x[p1 - 1] == 0.0);
	int worst_lag = 0, moved = 0;
	for (int n = 0; n <= p1 + 40; n++) {
		run_to(6000, 0, n);
		stop_count++;
		settle(&cur);
		assert_int_equal(out.status.state, MLIP_STATE_IDLE);
		assert_int_equal(out.status.stop_seen, stop_count);
		within_limits(&cur);
		same_as_reference(&cur, 0, n);
		if (n <= p1) {
			rests_at(&cur, 0, 0.0, 0.0); /* no setpoint ever changed */
			assert_int_equal(out.status.exec_seq, 0);
			assert_int_equal(out.status.stops, 0);
			if (n > 0) { /* taken by then: the program named */
				assert_int_equal(out.status.reason, MLIP_WHY_STOP_EARLY);
				assert_int_equal(out.status.reason_seq, 1);
				assert_int_equal(out.status.reason_line, 2);
			}
			continue;
		}
		moved++;
		/* on the path (the first row: y = 0, x forward), to rest from the
		 * speed v it had: at least v^2 / 2A (no faster than the limits) */
		assert_int_equal(out.status.reason, MLIP_WHY_STOP);
		assert_int_equal(out.status.stops, 1);
		double v = (cur.x[n - 1] - cur.x[n - 2]) / mach.period_s;
		double d = cur.x[cur.n - 1] - cur.x[n - 1];
		for (int i = n; i < cur.n; i++) {
			if (!(fabs(cur.y[i]) <= 1e-12 && cur.x[i] >= cur.x[i - 1] - 1e-12)) {
				fail_msg("n %d p1 %d period %d: (%.12f, %g) after %.12f (%g)", n,
				         p1, i, cur.x[i], cur.y[i], cur.x[i - 1],
				         cur.x[i] - cur.x[i - 1]);
			}
		}
		assert_true(d >= v * v / (2.0 * ACCEL) * (1.0 - 1e-9) - 1e-12);
		/* braking begins within LAG_MAX periods: the planner's stop is its
		 * hold, a full backward pass done as bounded work (1200 corners a
		 * period of the 4096), the plan in force followed until it lands */
		int i = n;
		while (i < cur.n && cur.x[i] - cur.x[i - 1] >= cur.x[i - 1] - cur.x[i - 2]) {
			i++;
		}
		worst_lag = i - n > worst_lag ? i - n : worst_lag;
		assert_true(i - n <= LAG_MAX);
		rests_at(&cur, cur.n - 10, cur.x[cur.n - 1], 0.0);
	}
	assert_int_equal(moved, 40);
	print_message("first motion period %d; a stop after it brakes from the %dth period on\n",
	              p1, worst_lag + 1);
}

/* mlip-rt told to exit (SIGTERM) in each period of the pre-read, its first
 * motion period included: nothing moves, and the exit completes (at rest). */
static void test_exit_in_each_period_of_the_preread(void **st)
{
	(void)st;
	reference(6000, 0);
	int p1 = first(&ref, MLIP_STATE_RUNNING);
	for (int n = 1; n <= p1; n++) {
		run_to(6000, 0, n);
		exit_request = 1;
		for (int i = 0; i < 100 && !out.done; i++) {
			step(&cur);
		}
		assert_true(out.done);
		assert_int_equal(out.status.state, MLIP_STATE_IDLE);
		assert_int_equal(out.status.reason, MLIP_WHY_EXIT);
		rests_at(&cur, 0, 0.0, 0.0);
	}
}

/* ---- a bad record met in each of the program's first periods -------------- */

/* The next record the controller takes is made bad (a NaN target) before
 * period n, for every n up to 40 periods after the first motion period: met
 * in the pre-read, nothing moves (exec_seq 0); met once the motion began,
 * the machine stops at rest exactly at the end of the last good block, the
 * setpoints before it the reference's. */
static void test_bad_record_in_each_of_the_first_periods(void **st)
{
	(void)st;
	reference(6000, 0);
	int p1 = first(&ref, MLIP_STATE_RUNNING);
	int in_preread = 0, moving = 0;
	for (int n = 0; n <= p1 + 40; n++) {
		run_to(6000, 0, n);
		uint64_t seq = corrupt_next();
		uint32_t from = settle(&cur);
		assert_int_equal(out.status.state, MLIP_STATE_FAULT);
		assert_int_equal(out.status.reason, MLIP_WHY_BAD_RECORD);
		assert_int_equal(out.status.reason_seq, seq);
		assert_int_equal(out.status.reason_field, MLIP_FIELD_TARGET);
		within_limits(&cur);
		same_as_reference(&cur, 0, n);
		if (from == MLIP_STATE_PREREAD) {
			assert_true(fault_period <=
			            p1); /* met in the pre-read: before any motion */
			in_preread++;
			rests_at(&cur, 0, 0.0, 0.0);
			assert_int_equal(out.status.exec_seq, 0);
			continue;
		}
		assert_int_equal(from, MLIP_STATE_RUNNING);
		assert_true(fault_period > p1); /* met once the motion began */
		moving++;
		double x, y;
		target(seq - 1, &x, &y);
		rests_at(&cur, cur.n - 10, x, y); /* exactly at its end */
		assert_int_equal(out.status.exec_seq, seq - 1);
		same_as_reference(&cur, 0, fault_period + 1); /* nothing changed at once */
	}
	assert_true(in_preread > 50 && moving > 30);
}

/* ---- the file changed: the feeder leaves in each of the first periods ----- */

/* mlip-feed that finds its file changed sends nothing more and leaves (no
 * END): the controller runs what it took to rest exactly at the end of the
 * last block, never beyond. The feeder here sends 32 records a period (the
 * pre-read takes more) and leaves before period n, for every n up to 40
 * periods after the first motion period of that feed. */
static void test_feeder_gone_in_each_of_the_first_periods(void **st)
{
	(void)st;
	int tried = 0;
	feed_rate = 32;
	reference(12000, 0);
	int p1 = first(&ref, MLIP_STATE_RUNNING);
	assert_true(p1 >= 50);
	for (int n = 1; n <= p1 + 40; n++) {
		run_to(12000, 0, n);
		uint64_t sent = next_seq - 1;
		if (sent > n_moves) {
			break; /* its END sent: the program completes */
		}
		feeder_alive = 0;
		for (int i = 0; i < 20000 && out.status.state != MLIP_STATE_STARVED; i++) {
			step(&cur);
		}
		assert_int_equal(out.status.state, MLIP_STATE_STARVED);
		assert_int_equal(out.status.reason, MLIP_WHY_UNDERRUN);
		for (int i = 0; i < 10; i++) {
			step(&cur);
		}
		within_limits(&cur);
		same_as_reference(&cur, 0, n < p1 ? n : p1); /* nothing moved before the start */
		double x, y;
		target(sent, &x, &y);
		rests_at(&cur, cur.n - 11, x, y);
		assert_int_equal(out.status.exec_seq, sent);
		tried++;
	}
	assert_true(tried > p1);
	print_message("feeder gone: first motion period %d, %d periods tried\n", p1, tried);
	feed_rate = 0;
}

/* ---- the pre-read after an underrun --------------------------------------- */

/* The feeder lags (alive): the machine runs its first UPTO blocks to rest,
 * starved; then the rest comes, pre-read again before it moves (CONTINUE).
 * A stop in each period of that pre-read: nothing moves from the end of
 * block UPTO, the status names it (the stop, block UPTO the last done). */
#define UPTO 4500
static void test_stop_in_the_preread_after_an_underrun(void **st)
{
	(void)st;
	feed_upto = UPTO;
	start(6000, 0);
	cur.n = 0;
	do {
		step(&cur);
	} while (out.status.state != MLIP_STATE_STARVED);
	int s0 = cur.n;
	feed_upto = 0;
	ref = cur;
	do {
		step(&ref);
	} while (ref.state[ref.n - 1] != MLIP_STATE_RUNNING);
	int p1 = ref.n - 1; /* the motion's first period after the underrun */
	double x, y;
	target(UPTO, &x, &y);
	print_message("underrun at %d, moving again at %d\n", s0, p1);
	assert_true(p1 > s0 + 50 && ref.x[p1 - 1] == x && ref.y[p1 - 1] == y);
	for (int n = s0; n <= p1; n++) {
		feed_upto = UPTO;
		start(6000, 0);
		cur.n = 0;
		while (cur.n < s0) {
			step(&cur);
		}
		feed_upto = 0;
		while (cur.n < n) {
			step(&cur);
		}
		stop_count++;
		settle(&cur);
		within_limits(&cur);
		rests_at(&cur, s0 - 1, x, y);
		assert_int_equal(out.status.state, MLIP_STATE_IDLE);
		assert_int_equal(out.status.reason, MLIP_WHY_STOP);
		assert_int_equal(out.status.exec_seq, UPTO);
	}
}

/* ---- the pre-read during a wait --------------------------------------------- */

/* Block 1, a dwell (the pre-read of what follows runs during it), the
 * zigzag. A stop in each period from the dwell's first to the motion's
 * first after it (that one included: the stop is seen before the dwell
 * ends): no setpoint changes from the end of block 1, and the status names
 * block 1, the block before the dwell that was not done. A bad record made
 * the next one read in each of those periods: met in the dwell, the same;
 * met once the motion after it began, the machine stops at rest exactly at
 * the end of the last good block. */
static void test_stop_or_bad_record_in_a_wait(void **st)
{
	(void)st;
	reference(6000, 1);
	int d0 = first(&ref, MLIP_STATE_DWELLING);
	int p1 = d0;
	while (p1 < ref.n && ref.state[p1] != MLIP_STATE_RUNNING) {
		p1++;
	}
	/* at rest at block 1's end for the dwell's round(dwell / T) periods */
	assert_true(d0 > 0 && ref.x[d0 - 1] == 0.1 && ref.y[d0 - 1] == 0.0);
	assert_int_equal(p1 - d0, (int)(DWELL_S / mach.period_s + 0.5));
	assert_true(ref.x[p1] > 0.1);
	int in_wait = 0, moving = 0;
	for (int n = d0 + 1; n <= p1 + 20; n++) {
		run_to(6000, 1, n);
		stop_count++;
		settle(&cur);
		within_limits(&cur);
		same_as_reference(&cur, 0, n);
		assert_int_equal(out.status.state, MLIP_STATE_IDLE);
		assert_int_equal(out.status.reason, MLIP_WHY_STOP);
		if (n <= p1) {
			rests_at(&cur, n - 1, 0.1, 0.0);
			assert_int_equal(out.status.exec_seq, 1);
		} else {
			assert_true(cur.x[cur.n - 1] > 0.1); /* on the path after it */
		}

		run_to(6000, 1, n);
		uint64_t seq = corrupt_next();
		uint32_t from = settle(&cur);
		within_limits(&cur);
		same_as_reference(&cur, 0, n);
		assert_int_equal(out.status.state, MLIP_STATE_FAULT);
		assert_int_equal(out.status.reason_seq, seq);
		if (from == MLIP_STATE_DWELLING) {
			in_wait++;
			assert_true(fault_period <= p1);
			rests_at(&cur, n - 1, 0.1, 0.0);
			assert_int_equal(out.status.exec_seq, 1);
		} else {
			moving++;
			assert_int_equal(from, MLIP_STATE_RUNNING);
			assert_true(fault_period > p1);
			double x, y;
			target(seq - 2, &x, &y); /* the block of record seq - 1 (2: the dwell) */
			rests_at(&cur, cur.n - 10, x, y);
			assert_int_equal(out.status.exec_seq, seq - 1);
		}
	}
	assert_true(in_wait > 50 && moving > 10);
}

/* ---- the work of every period is bounded ------------------------------- */

/*
 * What a period does beyond its fixed work, counted, in every period of a
 * whole program (the pre-read, the first motion, a dwell's refill, the
 * end), for every strategy, with and without a jerk limit, at look-ahead
 * depths 256 to 4096: records taken and checked (about 500 instructions
 * each), blocks appended with their corner (40 units of the look-ahead's
 * work, smooth's 150), corners visited by the backward passes (1 unit,
 * smooth's 4). The bounds are constants, not the depth: a depth's pre-read
 * spreads over more periods, each no dearer. The pre-read's first period
 * once took 512 records at once (242,000 instructions on MB-2.3, 44,000 in
 * any other period: bench/period_insns.py), and before the bounded work
 * the first look-ahead pass visited every block of the depth.
 */
#define TAKEN_MAX   64u /* x 500 instructions: about a period's look-ahead units */
#define APPENDS_MAX (MLIP_INGEST_PER_PERIOD + MLIP_WORK_PER_PERIOD / MLIP_WORK_APPEND)
#define VISITS_MAX  MLIP_WORK_PER_PERIOD

static void test_work_bounded_every_period(void **st)
{
	(void)st;
	static const mlip_strategy sts[] = {MLIP_STRATEGY_MPCT, MLIP_STRATEGY_BISECTOR,
	                                    MLIP_STRATEGY_STOP, MLIP_STRATEGY_SMOOTH};
	static const uint32_t depths[] = {256u, 1024u, 4096u};
	static const double jerks[] = {0.0, 1e5};
	for (size_t si = 0; si < sizeof(sts) / sizeof(sts[0]); si++) {
		for (size_t di = 0; di < sizeof(depths) / sizeof(depths[0]); di++) {
			for (size_t ji = 0; ji < sizeof(jerks) / sizeof(jerks[0]); ji++) {
				strategy = sts[si];
				lookahead = depths[di];
				jerk = jerks[ji];
				/* blocks of 0.1 mm, a dwell after the first (stop: at rest
				 * at every corner, 20 ms a block) */
				uint32_t moves = strategy == MLIP_STRATEGY_STOP ? 1000u : 6000u;
				start(moves, 1);
				uint32_t taken_max = 0, appends_max = 0, visits_max = 0, total = 0;
				uint64_t pushes = 0, visits = 0;
				cur.n = 0;
				do {
					step(&cur);
					const struct mlip_planner_stats *s =
					    mlip_planner_get_stats(&planner);
					uint32_t a = (uint32_t)(s->pushes - pushes);
					uint32_t v = (uint32_t)(s->backward_visits - visits);
					pushes = s->pushes;
					visits = s->backward_visits;
					total += out.taken;
					if (out.taken > TAKEN_MAX || a > APPENDS_MAX ||
					    v > VISITS_MAX) {
						fail_msg("%s, depth %u, J %g, period %d: %u "
						         "records taken "
						         "(<= %u), %u appended (<= %u), %u corners "
						         "visited "
						         "(<= %u)",
						         mlip_strategy_name(strategy), lookahead,
						         jerk, cur.n - 1, out.taken, TAKEN_MAX, a,
						         (uint32_t)APPENDS_MAX, v, VISITS_MAX);
					}
					taken_max = out.taken > taken_max ? out.taken : taken_max;
					appends_max = a > appends_max ? a : appends_max;
					visits_max = v > visits_max ? v : visits_max;
				} while (!ended() && cur.n < MAXP);
				/* the program ran to its end: every record taken, and the
				 * bounds were reached (the counts are real work) */
				if (!ended()) {
					fail_msg("%s, depth %u, J %g: state %u reason %u after %d "
					         "periods at "
					         "(%g, %g)",
					         mlip_strategy_name(strategy), lookahead, jerk,
					         out.status.state, out.status.reason, cur.n,
					         out.pos[0], out.pos[1]);
				}
				assert_int_equal(out.status.reason, MLIP_WHY_END);
				assert_int_equal(total, moves + 2u);
				assert_true(taken_max >= MLIP_INGEST_PER_PERIOD);
				if (appends_max < 8u || visits_max < 50u) {
					fail_msg(
					    "%s, depth %u, J %g: at most %u appended, %u visited a "
					    "period",
					    mlip_strategy_name(strategy), lookahead, jerk,
					    appends_max, visits_max);
				}
			}
		}
	}
}

static int teardown(void **st)
{
	(void)st;
	free(mem);
	mem = NULL;
	feed_upto = 0;
	feed_rate = 0;
	strategy = MLIP_STRATEGY_MPCT;
	lookahead = 0;
	jerk = 0.0;
	return 0;
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test_teardown(test_stop_in_each_of_the_first_periods, teardown),
	    cmocka_unit_test_teardown(test_exit_in_each_period_of_the_preread, teardown),
	    cmocka_unit_test_teardown(test_bad_record_in_each_of_the_first_periods, teardown),
	    cmocka_unit_test_teardown(test_feeder_gone_in_each_of_the_first_periods, teardown),
	    cmocka_unit_test_teardown(test_stop_in_the_preread_after_an_underrun, teardown),
	    cmocka_unit_test_teardown(test_stop_or_bad_record_in_a_wait, teardown),
	    cmocka_unit_test_teardown(test_work_bounded_every_period, teardown),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
