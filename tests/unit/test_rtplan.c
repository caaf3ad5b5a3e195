/*
 * test_rtplan.c - mlip-rt's planning thread for [TRAJ] JERK_PLAN = path
 * (tools/rtplan.c, compiled in here) running on a ring in ordinary memory;
 * the test plays the period's side of struct mlip_period_plan (rt/rt.h):
 * it reads prog and fault, pops the published queue as the period does and
 * writes done and fault_left. A refused program (a NaN target, which
 * mlip-feed never sends) is the controller's FAULT; once the controller has
 * left it (a reset after an E-stop: fault_left) the next program plans and
 * runs to its end, nothing of the refused one is planned, and a later
 * refusal is counted (a FAULT again). Every wait has a deadline of 10 s.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cmocka.h>

#include "confload.h"
#include "rt.h"

#include "../../tools/rtplan.c"

#define CAP 64u

static struct mlip_config cfg;
static struct mlip_rtplan t;
static struct mlip_ring *ring;
static void *mem;

static void sleep_ms(long ms)
{
	struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
	nanosleep(&ts, NULL);
}

/* Until *w (the thread's, read with acquire) is v; 10 s at most. */
static void wait_u32(const uint32_t *w, uint32_t v)
{
	for (int i = 0; i < 10000 && LD(w) != v; i++) {
		sleep_ms(1);
	}
	assert_int_equal(LD(w), v);
}

static void wait_u64(const uint64_t *w, uint64_t v)
{
	for (int i = 0; i < 10000 && LD(w) != v; i++) {
		sleep_ms(1);
	}
	assert_int_equal(LD(w), v);
}

/* A program of moves to (x[k], y[k]) at 100 mm/s, then END: pushed at once
 * (the thread never sees it half sent). */
static void program(const double *x, const double *y, int n)
{
	struct mlip_ring_rec recs[8];
	for (int k = 0; k < n; k++) {
		struct mlip_block b = {.feed_mm_s = 100.0, .tol_mm = 0.01, .line = (uint32_t)k + 2};
		b.target[0] = x[k];
		b.target[1] = y[k];
		mlip_ring_rec_from_block(&recs[k], &b, (uint64_t)k + 1);
	}
	mlip_ring_rec_end(&recs[n], (uint64_t)n + 1, (uint32_t)n + 2);
	assert_int_equal(mlip_ring_push_n(ring, recs, (uint32_t)n + 1), (uint32_t)n + 1);
}

static int setup(void **state)
{
	(void)state;
	assert_int_equal(mlip_config_load("config/mill-3axis.ini", &cfg, stderr), 0);
	cfg.jerk_plan = MLIP_JERK_PLAN_PATH;
	for (int k = 0; k < cfg.machine.n_axes; k++) {
		cfg.machine.axis[k].max_jerk = 100000.0;
	}
	size_t bytes = mlip_ring_bytes(CAP);
	assert_int_equal(posix_memalign(&mem, MLIP_RING_LINE, bytes), 0);
	assert_int_equal(mlip_ring_format_machine(mem, bytes, CAP, &cfg.machine), MLIP_OK);
	assert_int_equal(mlip_ring_attach(mem, bytes, cfg.machine.n_axes, &ring, NULL), MLIP_OK);
	struct mlip_ring_status st;
	memset(&st, 0, sizeof(st));
	st.heartbeat = 1; /* the controller idle at the origin */
	mlip_ring_status_write(ring, &st);
	return mlip_rtplan_start(&t, &cfg, ring);
}

static int teardown(void **state)
{
	(void)state;
	mlip_rtplan_stop(&t);
	free(mem);
	return 0;
}

/* The queue popped as the period pops it, to its end (the whole program is
 * queued before it is published: shorter than MLIP_PLANQ_LEN periods); the
 * last setpoint in x, the largest X seen in *xmax. */
static void run_queue(double *x, double *xmax)
{
	int mode = MLIP_PLANQ_WAIT;
	*xmax = 0.0;
	for (int i = 0; i < 100000 && mode != MLIP_PLANQ_DONE; i++) {
		mode = mlip_planq_step(t.pp.q, 0, x);
		assert_true(mode == MLIP_PLANQ_PLAN || mode == MLIP_PLANQ_DONE);
		*xmax = fmax(*xmax, x[0]);
	}
	assert_int_equal(mode, MLIP_PLANQ_DONE);
}

/* Refused (pp.fault 1), the rest of the program dropped while the
 * controller is in FAULT; the controller leaves it (pp.fault_left 1): the
 * next program is published and runs to its last point, never near the
 * refused program's X 50 (it stayed dead: the next program was dropped
 * too); then a third, refused as well: pp.fault 2. */
static void test_refused_then_left_then_next(void **state)
{
	(void)state;
	const double xa[3] = {1.0, NAN, 50.0}, ya[3] = {0.0, 0.0, 0.0};
	program(xa, ya, 3);
	wait_u32(&t.pp.fault, 1);
	wait_u64(&t.pp.taken, 4);             /* its rest dropped (the records' slots back) */
	assert_int_equal(LD(&t.pp.prog), 0u); /* never published */
	/* no program the controller runs (prog 0): the status counts every
	 * record taken (taken_base), the refused ones too: the next feeder's
	 * base. Left at 0, the next program's first record moved it to 4 while
	 * the program waited to start (drives enabling): that feeder saw IDLE
	 * with records of its own taken, "stopped on the path" (exit 4) */
	wait_u64(&t.pp.taken_base, 4);
	sleep_ms(20);
	assert_int_equal(LD(&t.pp.fault), 1u);
	/* the controller has left its FAULT: the next program plans */
	ST(&t.pp.fault_left, 1u);
	sleep_ms(20);
	assert_int_equal(LD(&t.pp.taken_base), 4u);
	const double xb[1] = {2.0}, yb[1] = {1.0};
	program(xb, yb, 1);
	wait_u32(&t.pp.prog, 1);
	wait_u64(&t.pp.end_seq, 2);
	assert_int_equal(LD(&t.pp.taken_base), 4u); /* published, not yet started: 4 */
	double x[MLIP_MAX_AXES], xmax;
	run_queue(x, &xmax);
	assert_true(x[0] == 2.0 && x[1] == 1.0);
	assert_true(xmax <= 2.0 + 1e-9); /* a straight line: nothing beyond its end */
	ST(&t.pp.done, 1u);              /* the period: the controller ended it */
	wait_u32(&t.pp.prog, 0);
	assert_int_equal(LD(&t.pp.fault), 1u);
	/* the next refusal is a new count: the controller faults again */
	const double xc[2] = {3.0, NAN}, yc[2] = {0.0, 0.0};
	program(xc, yc, 2);
	wait_u32(&t.pp.fault, 2);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test_setup_teardown(test_refused_then_left_then_next, setup, teardown),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
