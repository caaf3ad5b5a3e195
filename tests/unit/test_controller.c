/*
 * test_controller.c - the controller's period (rt/controller.c) on a ring in
 * ordinary memory, driven tick by tick without CAN: what it takes from the
 * ring when a feeder dies or a continuation does not continue.
 */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "rt.h"

#define CAP 64u

static struct mlip_machine mach;
static struct mlip_planner planner;
static struct mlip_controller ctl;
static struct mlip_ring *ring;
static void *mem;
static uint64_t cycle;

static int setup(void **state)
{
	(void)state;
	memset(&mach, 0, sizeof(mach));
	mach.n_axes = 2;
	mach.max_feed_mm_s = 200.0;
	mach.max_rot_feed_deg_s = 360.0;
	mach.tolerance_mm = 0.01;
	mach.period_s = 0.001;
	for (int k = 0; k < 2; k++) {
		mach.axis[k].letter = "XY"[k];
		mach.axis[k].kind = MLIP_AXIS_LINEAR;
		mach.axis[k].max_accel = 1000.0;
		mach.axis[k].max_vel = 200.0;
		mach.axis[k].min_limit = -1000.0;
		mach.axis[k].max_limit = 1000.0;
		mach.axis[k].can_node = k + 1;
		mach.axis[k].counts_per_unit = 1000.0;
	}
	size_t bytes = mlip_ring_bytes(CAP);
	assert_int_equal(posix_memalign(&mem, MLIP_RING_LINE, bytes), 0);
	assert_int_equal(mlip_ring_format_machine(mem, bytes, CAP, &mach), MLIP_OK);
	assert_int_equal(mlip_ring_attach(mem, bytes, 2, &ring, NULL), MLIP_OK);
	/* look-ahead 16: smaller than the programs below, so the pre-read ends
	 * on a full look-ahead unless a feeder dies first */
	assert_int_equal(mlip_controller_init(&ctl, &planner, &mach, NULL, MLIP_STRATEGY_MPCT, 16,
	                                      ring, NULL),
	                 0);
	cycle = 0;
	return 0;
}

static int teardown(void **state)
{
	(void)state;
	free(mem);
	return 0;
}

static void tick(int n)
{
	for (int i = 0; i < n; i++) {
		struct mlip_rt_tick t = {.cycle = cycle++};
		mlip_controller_tick(&ctl, &t);
	}
}

/* Blocks from..to of a program of 1 mm steps along X (seq k ends at X = k). */
static void push(uint64_t from, uint64_t to)
{
	for (uint64_t k = from; k <= to; k++) {
		struct mlip_block b = {.feed_mm_s = 100.0, .tol_mm = 0.01, .line = (uint32_t)k + 1};
		b.target[0] = (double)k;
		struct mlip_ring_rec rec;
		mlip_ring_rec_from_block(&rec, &b, k);
		assert_int_equal(mlip_ring_push(ring, &rec), MLIP_OK);
	}
}

/* The feeder area as a live feeder (age 0) or one gone for 1 s. */
static void feeder(int alive)
{
	struct mlip_ring_feeder f = {.pid = 4242, .heartbeat = 1};
	f.heartbeat_ns = mlip_now_ns() - (alive ? 0 : 1000000000ull);
	mlip_ring_feeder_write(ring, &f);
}

static uint32_t state(void)
{
	struct mlip_ring_status s;
	assert_int_equal(mlip_ring_status_read(ring, &s), MLIP_OK);
	return s.state;
}

/* A feeder that dies during the pre-read: what it sent runs, to rest at the
 * end of the last block, and the controller reports the underrun. */
static void test_feeder_dead_in_preread_runs_what_came(void **st)
{
	(void)st;
	feeder(1);
	push(1, 10); /* 10 < look-ahead 16, no END */
	tick(50);
	assert_int_equal(state(), MLIP_STATE_RUNNING);
	assert_true(ctl.preread); /* a live feeder may still send: wait */
	assert_true(ctl.pos[0] == 0.0);
	feeder(0);
	tick(3000);
	assert_int_equal(state(), MLIP_STATE_STARVED);
	assert_true(ctl.pos[0] == 10.0 && ctl.pos[1] == 0.0);
	assert_int_equal(ctl.exec_seq, 10);
}

/* After an underrun only seq 1 (a new program) or the block after the last
 * one completed continue; any other record is dropped, the machine stays. */
static void test_starved_takes_only_the_next_block(void **st)
{
	(void)st;
	feeder(1);
	push(1, 20);
	tick(20);
	feeder(0);
	tick(3000);
	assert_int_equal(state(), MLIP_STATE_STARVED);
	assert_int_equal(ctl.exec_seq, 20);
	feeder(1);
	push(25, 30); /* skips 21..24 */
	tick(100);
	assert_int_equal(ctl.refused, 1);
	assert_int_equal(mlip_ring_count(ring), 0); /* dropped */
	assert_true(ctl.pos[0] == 20.0);
	assert_int_equal(state(), MLIP_STATE_STARVED);
	feeder(0); /* that feeder gone: the dropping ends */
	tick(2);
	feeder(1);
	push(20, 22); /* repeats 20 */
	tick(100);
	assert_int_equal(ctl.refused, 2);
	assert_true(ctl.pos[0] == 20.0);
	feeder(0);
	tick(2);
	feeder(1);
	push(21, 24); /* continues */
	struct mlip_ring_rec end;
	mlip_ring_rec_end(&end, 25, 26);
	assert_int_equal(mlip_ring_push(ring, &end), MLIP_OK);
	tick(3000);
	assert_int_equal(state(), MLIP_STATE_IDLE);
	assert_true(ctl.pos[0] == 24.0);
	assert_int_equal(ctl.exec_seq, 25);
	assert_int_equal(ctl.refused, 2);
}

/* A hold at full speed on a straight line: the controller measures the path
 * from the request to rest and publishes it. At v = 100 mm/s with A = 1000
 * mm/s^2 braking takes v^2 / 2A = 5 mm; the request lands between two
 * periods, so up to one period at v (0.1 mm) more. */
static void test_stop_distance_published(void **st)
{
	(void)st;
	feeder(1);
	struct mlip_block b = {.feed_mm_s = 100.0, .tol_mm = 0.01, .line = 2};
	b.target[0] = 100.0;
	struct mlip_ring_rec rec, end;
	mlip_ring_rec_from_block(&rec, &b, 1);
	mlip_ring_rec_end(&end, 2, 3);
	assert_int_equal(mlip_ring_push(ring, &rec), MLIP_OK);
	assert_int_equal(mlip_ring_push(ring, &end), MLIP_OK);
	tick(400); /* at 100 mm/s after 100 ms of acceleration */
	double x0 = ctl.pos[0];
	assert_true(x0 > 20.0 && x0 < 50.0);
	uint32_t seq;
	assert_int_equal(mlip_ring_cmd_post(ring, MLIP_CMD_HOLD, 0, &seq), MLIP_OK);
	tick(300);
	struct mlip_ring_status s;
	assert_int_equal(mlip_ring_status_read(ring, &s), MLIP_OK);
	assert_int_equal(s.state, MLIP_STATE_HELD);
	assert_int_equal(s.stops, 1);
	double d = (double)s.stop_nm * 1e-6;
	assert_true(fabs(d - (ctl.pos[0] - x0)) <= 1e-6); /* the path it measured is the move */
	assert_true(d >= 5.0 - 1e-6 && d <= 5.0 + 0.1 + 1e-6);
	assert_true(s.stop_periods >= 100 && s.stop_periods <= 102);
	/* resumed, then stopped: a second stop, to rest on the line */
	assert_int_equal(mlip_ring_cmd_post(ring, MLIP_CMD_RESUME, 0, &seq), MLIP_OK);
	tick(200);
	assert_int_equal(mlip_ring_cmd_post(ring, MLIP_CMD_STOP, 0, &seq), MLIP_OK);
	tick(300);
	assert_int_equal(mlip_ring_status_read(ring, &s), MLIP_OK);
	assert_int_equal(s.state, MLIP_STATE_IDLE);
	assert_int_equal(s.stops, 2);
	d = (double)s.stop_nm * 1e-6;
	assert_true(d >= 5.0 - 1e-6 && d <= 5.0 + 0.1 + 1e-6);
	assert_true(ctl.pos[0] < 100.0);
}

/* A program stopped before its first block ends has completed nothing: the
 * status must not show the previous program's last block (a --start-seq
 * after it would continue the wrong program). */
static void test_stop_before_first_block_completes(void **st)
{
	(void)st;
	feeder(1);
	push(1, 5);
	struct mlip_ring_rec end;
	mlip_ring_rec_end(&end, 6, 7);
	assert_int_equal(mlip_ring_push(ring, &end), MLIP_OK);
	tick(3000);
	assert_int_equal(state(), MLIP_STATE_IDLE);
	assert_int_equal(ctl.exec_seq, 6);
	/* the next program: back to X = 0, 5 mm, stopped at once */
	struct mlip_block b = {.feed_mm_s = 100.0, .tol_mm = 0.01, .line = 2};
	struct mlip_ring_rec rec;
	mlip_ring_rec_from_block(&rec, &b, 1);
	assert_int_equal(mlip_ring_push(ring, &rec), MLIP_OK);
	mlip_ring_rec_end(&end, 2, 3);
	assert_int_equal(mlip_ring_push(ring, &end), MLIP_OK);
	tick(20);
	uint32_t seq;
	assert_int_equal(mlip_ring_cmd_post(ring, MLIP_CMD_STOP, 0, &seq), MLIP_OK);
	tick(300);
	assert_int_equal(state(), MLIP_STATE_IDLE);
	assert_true(ctl.pos[0] > 0.0 && ctl.pos[0] < 5.0); /* stopped inside block 1 */
	assert_int_equal(ctl.exec_seq, 0);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test_setup_teardown(test_feeder_dead_in_preread_runs_what_came, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_starved_takes_only_the_next_block, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_stop_distance_published, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_stop_before_first_block_completes, setup, teardown),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
