/*
 * test_feed_timing.c - the controller's setpoints do not depend on the
 * feeder's timing. mlip-sim keeps the ring full before every period;
 * mlip-feed writes as its reader and the smoothing filter produce, in
 * bursts, so the controller takes fewer records in some periods, in other
 * batches (the pre-read, MLIP_PREREAD_PER_PERIOD, and MLIP_INGEST_PER_PERIOD
 * a period after it). As long as the look-ahead stays ahead of the braking
 * distance (no underrun), every strategy must give the same setpoints to the
 * bit from the first motion on: the CAN tests compare the bus with mlip-sim
 * to the count (a smooth run once differed by one count: the corners'
 * shapes depended on the planner's batches).
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "blockiter.h"
#include "mlip/ctl/controller.h"
#include "mlip/motion/smooth.h"

#define SEGS      6000
#define LOOKAHEAD 4096u /* the default: 80 mm of 0.02 mm segments, far beyond braking */
#define MAX_ROWS  400000

static struct mlip_machine mach;
static struct mlip_planner planner;
static struct mlip_smooth_store store;
static struct mlip_ctl ctl;
static struct mlip_block prog[SEGS + 8];
static size_t nprog;

static void make_machine(void)
{
	memset(&mach, 0, sizeof(mach));
	mach.n_axes = 2;
	mach.max_feed_mm_s = 200.0;
	mach.max_rot_feed_deg_s = 360.0;
	mach.tolerance_mm = 0.01;
	mach.period_s = 0.001;
	for (int k = 0; k < 2; k++) {
		mach.axis[k].letter = "XY"[k];
		mach.axis[k].max_accel = 1000.0;
		mach.axis[k].max_vel = 200.0;
		mach.axis[k].min_limit = -1000.0;
		mach.axis[k].max_limit = 1000.0;
	}
}

/* A Lissajous figure in 0.02 mm segments, rounded to 4 decimals as CAM
 * output is (where smooth's braking shapes matter), from the origin. */
static size_t make_program(struct mlip_block *b)
{
	double t = 0.0;
	for (size_t i = 0; i < SEGS; i++) {
		double x = 40.0 * cos(3.0 * t) - 40.0, y = 30.0 * sin(4.0 * t);
		b[i] = (struct mlip_block){
		    .feed_mm_s = 200.0, .tol_mm = 0.01, .line = (uint32_t)i + 1};
		b[i].target[0] = round(x * 1e4) / 1e4;
		b[i].target[1] = round(y * 1e4) / 1e4;
		t += 0.02 / fmax(hypot(120.0 * sin(3.0 * t), 120.0 * cos(4.0 * t)), 1.0);
	}
	return SEGS;
}

/* The feeder: how many records it writes before period k (kind 0: as many
 * as fit, as mlip-sim; 1: a random 0..48, 24 on average; 2: bursts, nothing
 * for 40 periods then 900 at once). */
static uint32_t offer(int kind, uint64_t k, uint64_t *rng)
{
	*rng = *rng * 6364136223846793005ULL + 1442695040888963407ULL;
	if (kind == 0) {
		return UINT32_MAX;
	}
	if (kind == 1) {
		return (uint32_t)((*rng >> 33) % 49);
	}
	return k % 41 == 40 ? 900u : 0u;
}

/* Run the program; rows[] gets the setpoints from the first motion on. */
static size_t run(mlip_strategy st, int kind, double *rows)
{
	size_t bytes = mlip_ring_bytes(MLIP_RING_CAPACITY);
	void *mem = NULL;
	struct mlip_ring *ring = NULL;
	assert_int_equal(posix_memalign(&mem, MLIP_RING_LINE, bytes), 0);
	assert_int_equal(mlip_ring_format_machine(mem, bytes, MLIP_RING_CAPACITY, &mach), MLIP_OK);
	assert_int_equal(mlip_ring_attach(mem, bytes, 2, &ring, NULL), MLIP_OK);
	struct mlip_ctl_opts o = {.strategy = st,
	                          .smooth = st == MLIP_STRATEGY_SMOOTH ? &store : NULL,
	                          .lookahead = LOOKAHEAD};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
	struct mlip_ring_port rx; /* the controller's records: a view of it each period */
	assert_int_equal(mlip_ring_port_open(&rx, ring, 0), MLIP_OK);
	uint64_t rng = 0x243F6A8885A308D3ULL, seq = 0;
	size_t next = 0, nrows = 0;
	int moved = 0;
	double home[2] = {0.0, 0.0};
	struct mlip_ctl_out out;
	for (uint64_t k = 0; k < 10 * MAX_ROWS; k++) {
		uint32_t n = offer(kind, k, &rng), space = mlip_ring_space(ring);
		for (uint32_t i = 0; i < n && i < space && seq <= nprog; i++) {
			struct mlip_ring_rec rec;
			if (next < nprog) {
				mlip_ring_rec_from_block(&rec, &prog[next++], ++seq);
			} else {
				mlip_ring_rec_end(&rec, ++seq, (uint32_t)nprog + 1);
			}
			assert_int_equal(mlip_ring_push_n(ring, &rec, 1), 1);
		}
		struct mlip_ctl_in in = {.period = k, .feeder_alive = 1};
		assert_int_equal(mlip_ring_port_view(&rx, &in.recs, &in.recs_corrupt), MLIP_OK);
		in.recs_corrupt = 0;
		mlip_ctl_period(&ctl, &in, &out);
		assert_int_equal(mlip_ring_port_pop_n(&rx, out.taken), MLIP_OK);
		assert_int_not_equal(out.status.state, MLIP_STATE_FAULT);
		moved |= out.pos[0] != home[0] || out.pos[1] != home[1];
		if (moved) {
			assert_true(nrows < MAX_ROWS);
			memcpy(rows + 2 * nrows++, out.pos, sizeof(double) * 2);
		}
		if (moved && out.status.state == MLIP_STATE_IDLE) {
			free(mem);
			return nrows;
		}
	}
	fail_msg("no end");
	return 0;
}

static void test_same_setpoints_whatever_the_feeder(void **state)
{
	(void)state;
	make_machine();
	static struct mlip_block raw[SEGS];
	size_t nraw = make_program(raw);
	double *ref = malloc(2 * MAX_ROWS * sizeof(double)),
	       *got = malloc(2 * MAX_ROWS * sizeof(double));
	for (int st = 0; st < MLIP_STRATEGY_COUNT; st++) {
		struct mlip_block *b = raw;
		nprog = nraw;
		if (st == MLIP_STRATEGY_SMOOTH) { /* the records mlip-feed sends */
			assert_int_equal(mlip_smooth_program(&mach, raw, nraw, &b, &nprog), 0);
			assert_true(nprog <= SEGS + 8);
		}
		memcpy(prog, b, nprog * sizeof(*b));
		if (b != raw) {
			free(b);
		}
		size_t n0 = run((mlip_strategy)st, 0, ref);
		for (int kind = 1; kind <= 2; kind++) {
			size_t n1 = run((mlip_strategy)st, kind, got), same = 0;
			while (same < n0 && same < n1 && ref[2 * same] == got[2 * same] &&
			       ref[2 * same + 1] == got[2 * same + 1]) {
				same++;
			}
			if (n0 != n1 || same != n0) {
				fail_msg("strategy %s, feeder %d: %zu / %zu setpoints, the first "
				         "differs at %zu",
				         mlip_strategy_name((mlip_strategy)st), kind, n0, n1, same);
			}
		}
	}
	free(ref);
	free(got);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_same_setpoints_whatever_the_feeder),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
