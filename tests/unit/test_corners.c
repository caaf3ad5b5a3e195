/*
 * test_corners.c - a smooth controller's program with mpct's corners
 * (MLIP_REC_MPCT, tools/lib/simcount.h): its setpoints are a fresh mpct
 * controller's to the bit, the next program's without the flag a fresh
 * smooth controller's from where the first ended, and the flag where it
 * does not belong is a bad record before anything moves.
 */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <string.h>

#include <cmocka.h>

#include "mlip/ctl/controller.h"
#include "mlip/motion/smooth.h"

#define MOVES    40
#define MAX_ROWS 20000

static struct mlip_machine mach;
static struct mlip_planner planner;
static struct mlip_smooth_store store;
static struct mlip_ctl ctl;
static struct mlip_ctl_out out;
static struct mlip_ring_rec recs[MOVES + 1];
static double rows[2][MAX_ROWS][2]; /* two runs' setpoints */

static void machine(const double *home)
{
	memset(&mach, 0, sizeof(mach));
	mach.n_axes = 2;
	mach.max_feed_mm_s = 200.0;
	mach.tolerance_mm = 0.01;
	mach.period_s = 0.001;
	for (int k = 0; k < 2; k++) {
		mach.axis[k].letter = "XY"[k];
		mach.axis[k].max_accel = 1000.0;
		mach.axis[k].max_vel = 200.0;
		mach.axis[k].min_limit = -1000.0;
		mach.axis[k].max_limit = 1000.0;
		mach.axis[k].home = home[k];
	}
}

static void init(mlip_strategy st, const double *home)
{
	machine(home);
	struct mlip_ctl_opts o = {
	    .strategy = st, .smooth = st == MLIP_STRATEGY_SMOOTH ? &store : NULL, .lookahead = 16};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
}

/* A wave from (x0, 0), chords of about 0.3 mm turning up to 10 degrees
 * (where smooth's corners differ from mpct's), then END; every record's
 * flags |= flags. */
static void wave(double x0, uint16_t flags)
{
	for (int i = 0; i < MOVES; i++) {
		struct mlip_block b = {.feed_mm_s = 150.0, .tol_mm = 0.01, .line = (uint32_t)i + 1};
		b.target[0] = x0 + 0.25 * (i + 1);
		b.target[1] = 0.5 * sin(0.35 * (i + 1));
		mlip_ring_rec_from_block(&recs[i], &b, (uint64_t)i + 1);
		recs[i].flags |= flags;
	}
	mlip_ring_rec_end(&recs[MOVES], MOVES + 1, MOVES + 1);
	recs[MOVES].flags |= flags;
}

/* The records run from idle back to idle (or a fault): the setpoints of
 * every period after the program left idle into r; the count. */
/* A late feeder: records from index late_from on reach the controller in
 * the run's period late_at (and a run ends once starved, with stop_starved:
 * starved_at its period). */
static uint32_t late_from = MOVES + 1, late_at;
static int stop_starved, starved_at = -1;

static int run(double (*r)[2], uint64_t *period)
{
	uint32_t tail = 0;
	int n = 0, started = 0;
	for (int i = 0; i < 10 * MAX_ROWS; i++) {
		struct mlip_ctl_in in = {.period = (*period)++, .feeder_alive = 1};
		uint32_t visible = (uint32_t)i >= late_at ? MOVES + 1 : late_from;
		in.recs.span[0] = recs + tail;
		in.recs.len[0] = visible - tail;
		mlip_ctl_period(&ctl, &in, &out);
		tail += out.taken;
		uint32_t s = out.status.state;
		if (s == MLIP_STATE_STARVED && starved_at < 0) {
			starved_at = i;
			if (stop_starved) {
				return n;
			}
		}
		started |= s != MLIP_STATE_IDLE;
		if (started && s != MLIP_STATE_PREREAD) {
			assert_true(n < MAX_ROWS);
			memcpy(r[n++], out.pos, sizeof(r[0]));
		}
		if (s == MLIP_STATE_FAULT || (started && s == MLIP_STATE_IDLE)) {
			return n;
		}
	}
	fail_msg("no end");
	return -1;
}

static int same(double (*a)[2], int na, double (*b)[2], int nb)
{
	return na == nb && memcmp(a, b, sizeof(a[0]) * (size_t)na) == 0;
}

static void test_flagged_program_runs_mpct_then_smooth_again(void **state)
{
	(void)state;
	const double home[2] = {0.0, 0.0};
	uint64_t p = 0;
	/* the smooth controller, the program flagged: mpct's corners */
	init(MLIP_STRATEGY_SMOOTH, home);
	wave(0.0, MLIP_REC_MPCT);
	int n_flag = run(rows[0], &p);
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	double end[2] = {out.pos[0], out.pos[1]};
	assert_float_equal(end[0], 0.25 * MOVES, 1e-9);
	/* then a program without the flag, from there */
	wave(end[0], 0);
	int n_next = run(rows[1], &p);
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);

	/* a fresh mpct controller: the flagged run to the bit */
	static double ref[MAX_ROWS][2];
	uint64_t q = 0;
	init(MLIP_STRATEGY_MPCT, home);
	wave(0.0, 0);
	int n_mpct = run(ref, &q);
	assert_true(same(rows[0], n_flag, ref, n_mpct));
	/* a fresh smooth controller: not that run (the flag did something) */
	q = 0;
	init(MLIP_STRATEGY_SMOOTH, home);
	int n_smooth = run(ref, &q);
	assert_false(same(rows[0], n_flag, ref, n_smooth));
	/* ... and, from where the flagged one ended, the next program to the bit */
	q = 0;
	init(MLIP_STRATEGY_SMOOTH, end);
	wave(end[0], 0);
	n_smooth = run(ref, &q);
	assert_true(same(rows[1], n_next, ref, n_smooth));
}

/* The run ended in a fault: bad record seq, its flags. */
static void flags_fault_at(uint64_t seq)
{
	assert_int_equal(out.status.state, MLIP_STATE_FAULT);
	assert_int_equal(out.status.reason, MLIP_WHY_BAD_RECORD);
	assert_int_equal(out.status.reason_field, MLIP_FIELD_FLAGS);
	assert_int_equal(out.status.reason_seq, seq);
}

static void test_flag_where_it_does_not_belong(void **state)
{
	(void)state;
	const double home[2] = {0.0, 0.0};
	uint64_t p = 0;
	/* on a controller not running smooth: its first record is bad */
	init(MLIP_STRATEGY_MPCT, home);
	wave(0.0, MLIP_REC_MPCT);
	(void)run(rows[0], &p);
	assert_int_equal(out.status.state, MLIP_STATE_FAULT);
	assert_int_equal(out.status.reason, MLIP_WHY_BAD_RECORD);
	assert_int_equal(out.status.reason_field, MLIP_FIELD_FLAGS);
	assert_int_equal(out.status.reason_seq, 1);
	assert_true(out.pos[0] == 0.0 && out.pos[1] == 0.0); /* nothing moved */

	/* smooth, a program whose records differ: the first that differs is
	 * bad, the motion before it brakes on the path */
	p = 0;
	init(MLIP_STRATEGY_SMOOTH, home);
	wave(0.0, 0);
	recs[30].flags |= MLIP_REC_MPCT;
	(void)run(rows[0], &p);
	flags_fault_at(31);
	/* ... an event that reaches the controller as it comes to rest before it
	 * (a late feeder), taken at rest by its own path: a dwell here */
	p = 0;
	init(MLIP_STRATEGY_SMOOTH, home);
	wave(0.0, MLIP_REC_MPCT);
	recs[30].type = MLIP_REC_DWELL;
	recs[30].dwell_s = 0.01;
	recs[30].flags = 0;
	late_from = 30; /* more than the look-ahead: it moves */
	late_at = 1u << 30;
	stop_starved = 1;
	(void)run(rows[0], &p); /* the period it comes to rest after record 30 */
	assert_true(starved_at > 0);
	p = 0;
	init(MLIP_STRATEGY_SMOOTH, home);
	late_at = (uint32_t)starved_at;
	stop_starved = 0;
	(void)run(rows[0], &p);
	late_from = MOVES + 1;
	late_at = 0;
	flags_fault_at(31);
	/* ... an event too, taken at rest by its own path (a dwell here) */
	p = 0;
	init(MLIP_STRATEGY_SMOOTH, home);
	wave(0.0, MLIP_REC_MPCT);
	recs[12].type = MLIP_REC_DWELL;
	recs[12].dwell_s = 0.01;
	recs[12].flags = 0;
	(void)run(rows[0], &p);
	flags_fault_at(13);
	p = 0;
	init(MLIP_STRATEGY_SMOOTH, home);
	wave(0.0, MLIP_REC_MPCT);
	recs[5].flags &= (uint16_t)~MLIP_REC_MPCT;
	(void)run(rows[0], &p);
	flags_fault_at(6);
}

static void test_planner_strategy_only_when_empty(void **state)
{
	(void)state;
	const double home[2] = {0.0, 0.0};
	init(MLIP_STRATEGY_MPCT, home); /* no store: smooth cannot be set */
	assert_int_equal(mlip_planner_set_strategy(&planner, MLIP_STRATEGY_SMOOTH), MLIP_E_INVALID);
	assert_int_equal(mlip_planner_set_strategy(&planner, MLIP_STRATEGY_COUNT), MLIP_E_INVALID);
	init(MLIP_STRATEGY_SMOOTH, home);
	struct mlip_block b = {.feed_mm_s = 100.0, .tol_mm = 0.01, .seq = 1, .line = 1};
	b.target[0] = 5.0;
	assert_int_equal(mlip_planner_push(&planner, &b), MLIP_OK);
	assert_int_equal(mlip_planner_set_strategy(&planner, MLIP_STRATEGY_MPCT), MLIP_E_INVALID);
	assert_int_equal(planner.strategy, MLIP_STRATEGY_SMOOTH);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_flagged_program_runs_mpct_then_smooth_again),
	    cmocka_unit_test(test_flag_where_it_does_not_belong),
	    cmocka_unit_test(test_planner_strategy_only_when_empty),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
