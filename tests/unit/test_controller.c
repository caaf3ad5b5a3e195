/*
 * test_controller.c - the pure controller (src/ctl/controller.c) period by
 * period on a ring in ordinary memory, no clock, no CAN: the ingest rule,
 * every state transition and its reason, program events (dwell, pause,
 * optional pause, exact stop), record validation and stalls.
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

#include "mlip/canopen/drive.h"
#include "mlip/machine/config.h"
#include "mlip/ctl/controller.h"
#include "cli.h"

#define CAP 64u

static struct mlip_machine mach;
static struct mlip_planner planner;
static struct mlip_ctl ctl;
static struct mlip_ctl_out out;
static struct mlip_ring *ring;
static struct mlip_ring_port rx; /* the controller's records: a view of it each period */
static void *mem;
static uint64_t period;
static int feeder_alive;
/* the drives' inputs of the next period (rt/drives.c's part): a fault is
 * given for one period, as the supervision reports it once */
static struct mlip_ctl_drive_fault drv_fault;
static uint32_t drv_actual_mask;
static double drv_actual[MLIP_MAX_AXES];
static uint16_t drv_sw[MLIP_MAX_AXES]; /* the statusword of each drive's TPDO */
/* the inputs on the bus of the next period (issue 18) */
static struct mlip_ctl_io io_in;
static struct mlip_ctl_sdo_res sdo_res_in; /* the drives' SDO answer (homing) */
static struct mlip_ctl_spindle_in sp_in;   /* the spindle drive's TPDO (issue 19) */
/* the segment's stop counter and the feeder's stop_base (mlip/ipc/ring.h) */
static uint32_t stop_count, feeder_base;
static int feeder_mdi; /* the records are MDI lines (mlip-ctl mdi) */
/* every transition seen since setup: state entered and why */
static uint32_t seen_state[256], seen_why[256];
static int n_seen;

static void machine(void)
{
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
}

static int setup(void **state)
{
	feeder_mdi = 0;
	(void)state;
	machine();
	size_t bytes = mlip_ring_bytes(CAP);
	assert_int_equal(posix_memalign(&mem, MLIP_RING_LINE, bytes), 0);
	assert_int_equal(mlip_ring_format_machine(mem, bytes, CAP, &mach), MLIP_OK);
	assert_int_equal(mlip_ring_attach(mem, bytes, 2, &ring, NULL), MLIP_OK);
	/* look-ahead 16: smaller than the programs below, so the pre-read ends
	 * on a full look-ahead unless a feeder dies first */
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT, .lookahead = 16};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
	assert_int_equal(mlip_ring_port_open(&rx, ring, 0), MLIP_OK);
	period = 0;
	feeder_alive = 1;
	stop_count = feeder_base = 0;
	n_seen = 0;
	memset(&drv_fault, 0, sizeof(drv_fault));
	memset(&io_in, 0, sizeof(io_in));
	memset(&sp_in, 0, sizeof(sp_in));
	drv_actual_mask = 0;
	return 0;
}

static int teardown(void **state)
{
	(void)state;
	free(mem);
	return 0;
}

/* One period on in, its records the ring's; what it took popped. */
static void run_period(struct mlip_ctl_in *in)
{
	if (mlip_ring_port_view(&rx, &in->recs, &in->recs_corrupt) == MLIP_OK) {
		in->recs_corrupt = 0;
	}
	mlip_ctl_period(&ctl, in, &out);
	assert_int_equal(mlip_ring_port_pop_n(&rx, out.taken), MLIP_OK);
}

static int unsent_in; /* the next period's in.unsent (then 0 again) */

/* One period with a command (op 0: none) after `missed` missed periods. */
static int32_t period_cmd(uint32_t op, int32_t arg, uint32_t missed)
{
	struct mlip_ring_cmd cmd = {.seq = 2, .op = op, .arg = arg};
	struct mlip_ctl_in in = {.period = period++,
	                         .missed = missed,
	                         .feeder_alive = feeder_alive,
	                         .feeder_mdi = feeder_mdi,
	                         .stop_requests = stop_count,
	                         .feeder_stop_base = feeder_base};
	in.cmd = op ? &cmd : NULL;
	in.drives.fault = drv_fault;
	in.drives.actual_mask = drv_actual_mask;
	memcpy(in.drives.pos_actual, drv_actual, sizeof(in.drives.pos_actual));
	memcpy(in.drives.sw, drv_sw, sizeof(in.drives.sw));
	for (int k = 0; k < MLIP_MAX_AXES; k++) {
		in.drives.tpdo_period[k] = period > 0 ? period - 1 : UINT64_MAX;
	}
	in.sdo = sdo_res_in;
	in.io = io_in;
	in.spindle = sp_in;
	in.unsent = unsent_in;
	unsent_in = 0;
	memset(&drv_fault, 0, sizeof(drv_fault));
	run_period(&in);
	for (uint32_t i = 0; i < out.n_events; i++) {
		if (out.events[i].kind == MLIP_EV_STATE && n_seen < 256) {
			seen_state[n_seen] = out.events[i].state;
			seen_why[n_seen++] = out.events[i].r.why;
		}
	}
	return out.cmd_result;
}

static void tick(int n)
{
	for (int i = 0; i < n; i++) {
		period_cmd(0, 0, 0);
	}
}

/* Ticks (at least one) until the state is s (at most n); returns the periods
 * it took. */
static int until(uint32_t s, int n)
{
	for (int i = 1; i <= n; i++) {
		tick(1);
		if (out.status.state == s) {
			return i;
		}
	}
	fail_msg("state %s not reached in %d periods (now %s)", mlip_ctl_state_name(s), n,
	         mlip_ctl_state_name(out.status.state));
	return -1;
}

static int saw(uint32_t state, uint32_t why)
{
	for (int i = 0; i < n_seen; i++) {
		if (seen_state[i] == state && seen_why[i] == why) {
			return 1;
		}
	}
	return 0;
}

static void push_rec(const struct mlip_ring_rec *rec)
{
	assert_int_equal(mlip_ring_push(ring, rec), MLIP_OK);
}

/* Block k of a program of 1 mm steps along X (ends at X = x). */
static void move(uint64_t seq, double x, double y)
{
	struct mlip_block b = {.feed_mm_s = 100.0, .tol_mm = 0.01, .line = (uint32_t)seq + 1};
	b.target[0] = x;
	b.target[1] = y;
	struct mlip_ring_rec rec;
	mlip_ring_rec_from_block(&rec, &b, seq);
	push_rec(&rec);
}

static void push(uint64_t from, uint64_t to)
{
	for (uint64_t k = from; k <= to; k++) {
		move(k, (double)k, 0.0);
	}
}

static void end(uint64_t seq)
{
	struct mlip_ring_rec rec;
	mlip_ring_rec_end(&rec, seq, (uint32_t)seq + 1);
	push_rec(&rec);
}

static void event(uint64_t seq, uint8_t kind, double dwell_s)
{
	struct mlip_block b = {
	    .kind = kind, .dwell_s = dwell_s, .value = dwell_s, .line = (uint32_t)seq + 1};
	struct mlip_ring_rec rec;
	mlip_ring_rec_from_block(&rec, &b, seq);
	push_rec(&rec);
}

static struct mlip_ring_status status(void)
{
	return out.status;
}

/* ---- the ingest rule and its states ------------------------------------ */

/* A feeder that dies during the pre-read: what it sent runs, to rest at the
 * end of the last block, and the controller reports the underrun. */
static void test_feeder_dead_in_preread_runs_what_came(void **st)
{
	(void)st;
	push(1, 10); /* 10 < look-ahead 16, no END */
	tick(50);
	assert_int_equal(out.status.state, MLIP_STATE_PREREAD); /* a live feeder may still send */
	assert_true(out.pos[0] == 0.0);
	feeder_alive = 0;
	until(MLIP_STATE_STARVED, 3000);
	assert_true(out.pos[0] == 10.0 && out.pos[1] == 0.0);
	assert_int_equal(status().exec_seq, 10);
	assert_int_equal(status().reason, MLIP_WHY_UNDERRUN);
	assert_true(saw(MLIP_STATE_PREREAD, MLIP_WHY_START));
	assert_true(saw(MLIP_STATE_RUNNING, MLIP_WHY_PREREAD_DONE));
}

/* After an underrun only seq 1 (a new program) or the block after the last
 * one completed continue; any other record is dropped, the machine stays. */
static void test_starved_takes_only_the_next_block(void **st)
{
	(void)st;
	push(1, 20);
	tick(20);
	feeder_alive = 0;
	until(MLIP_STATE_STARVED, 3000);
	assert_int_equal(out.status.exec_seq, 20);
	feeder_alive = 1;
	push(25, 30); /* skips 21..24 */
	tick(100);
	assert_int_equal(out.counts.refused, 1);
	assert_int_equal(mlip_ring_count(ring), 0); /* dropped */
	assert_true(out.pos[0] == 20.0);
	assert_int_equal(out.status.state, MLIP_STATE_STARVED);
	feeder_alive = 0; /* that feeder gone: the dropping ends */
	tick(2);
	feeder_alive = 1;
	push(20, 22); /* repeats 20 */
	tick(100);
	assert_int_equal(out.counts.refused, 2);
	assert_true(out.pos[0] == 20.0);
	feeder_alive = 0;
	tick(2);
	feeder_alive = 1;
	push(21, 24); /* continues */
	end(25);
	until(MLIP_STATE_IDLE, 3000);
	assert_true(out.pos[0] == 24.0);
	assert_int_equal(out.status.exec_seq, 25);
	assert_int_equal(out.counts.refused, 2);
	assert_true(saw(MLIP_STATE_PREREAD, MLIP_WHY_CONTINUE));
	assert_true(saw(MLIP_STATE_IDLE, MLIP_WHY_END));
}

/* A hold at full speed on a straight line: the controller measures the path
 * from the request to rest and publishes it. At v = 100 mm/s with A = 1000
 * mm/s^2 braking takes v^2 / 2A = 5 mm; the request lands between two
 * periods, so up to one period at v (0.1 mm) more. */
static void test_stop_distance_published(void **st)
{
	(void)st;
	move(1, 100.0, 0.0);
	end(2);
	tick(400); /* at 100 mm/s after 100 ms of acceleration */
	double x0 = out.pos[0];
	assert_true(x0 > 20.0 && x0 < 50.0);
	assert_int_equal(period_cmd(MLIP_CMD_HOLD, 0, 0), MLIP_OK);
	tick(300);
	struct mlip_ring_status s = status();
	assert_int_equal(s.state, MLIP_STATE_HELD);
	assert_int_equal(s.reason, MLIP_WHY_HOLD);
	assert_int_equal(s.stops, 1);
	double d = (double)s.stop_nm * 1e-6;
	assert_true(fabs(d - (out.pos[0] - x0)) <= 1e-6); /* the path it measured is the move */
	assert_true(d >= 5.0 - 1e-6 && d <= 5.0 + 0.1 + 1e-6);
	assert_true(s.stop_periods >= 100 && s.stop_periods <= 102);
	/* resumed, then stopped: a second stop, to rest on the line */
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK);
	tick(200);
	assert_int_equal(out.status.state, MLIP_STATE_RUNNING);
	assert_true(saw(MLIP_STATE_RUNNING, MLIP_WHY_RESUME));
	assert_int_equal(period_cmd(MLIP_CMD_STOP, 0, 0), MLIP_OK);
	assert_int_equal(out.status.state, MLIP_STATE_STOPPING);
	tick(300);
	s = status();
	assert_int_equal(s.state, MLIP_STATE_IDLE);
	assert_int_equal(s.reason, MLIP_WHY_STOP);
	assert_int_equal(s.stops, 2);
	d = (double)s.stop_nm * 1e-6;
	assert_true(d >= 5.0 - 1e-6 && d <= 5.0 + 0.1 + 1e-6);
	assert_true(out.pos[0] < 100.0);
}

/* A hold at rest (idle: the I/O module's hold button, mlip-ctl hold)
 * brakes nothing: no stop is counted and the last stop's figures stay in
 * the status; the hold is latched for the next program (Grbl's Hold:0),
 * which starts held, unmoved, until a resume. */
static void test_hold_at_rest_counts_no_stop(void **st)
{
	(void)st;
	move(1, 100.0, 0.0);
	end(2);
	tick(400);
	assert_int_equal(period_cmd(MLIP_CMD_HOLD, 0, 0), MLIP_OK);
	until(MLIP_STATE_HELD, 300);
	tick(300);
	struct mlip_ring_status s = status();
	assert_int_equal(s.stops, 1);
	uint64_t nm = s.stop_nm;
	uint32_t periods = s.stop_periods;
	assert_true(nm > 4000000); /* about v^2/2A = 5 mm */
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK);
	until(MLIP_STATE_IDLE, 3000);
	assert_true(out.pos[0] == 100.0);
	assert_int_equal(period_cmd(MLIP_CMD_HOLD, 0, 0), MLIP_OK); /* at rest */
	tick(10);
	s = status();
	assert_int_equal(s.state, MLIP_STATE_IDLE);
	assert_int_equal(s.held_by, MLIP_WHY_HOLD); /* latched, and said so */
	assert_int_equal(s.stops, 1);
	assert_true(s.stop_nm == nm && s.stop_periods == periods);
	move(1, 110.0, 0.0); /* the next program */
	end(2);
	until(MLIP_STATE_HELD, 3000);
	tick(100);
	assert_true(out.pos[0] == 100.0);
	assert_int_equal(status().reason, MLIP_WHY_HOLD);
	assert_int_equal(status().stops, 1);
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK);
	until(MLIP_STATE_IDLE, 3000);
	assert_true(out.pos[0] == 110.0);
	assert_int_equal(status().stops, 1);
}

/* A one-line program to X = x: it runs to its end, no hold in force. */
static void line_unheld(double x)
{
	move(1, x, 0.0);
	end(2);
	until(MLIP_STATE_RUNNING, 3000);
	while (status().state != MLIP_STATE_IDLE) {
		assert_int_equal(status().held_by, 0);
		assert_true(period < 1000000);
		tick(1);
	}
	assert_int_equal(status().reason, MLIP_WHY_END);
	assert_true(out.pos[0] == x);
}

/* A hold latched at rest is in the status (held_by, issue 18's left-over:
 * idle read "idle" while the next program would wait held); a resume at
 * rest ends it moving nothing; the next program then runs; a stop at rest
 * ends it too (Grbl 1.1's reset leaves Hold for Idle); a jog is refused
 * while it lasts (Grbl refuses $J in Hold, error 8). */
static void test_hold_latched_at_rest(void **st)
{
	(void)st;
	tick(5);
	assert_int_equal(status().held_by, 0);
	assert_int_equal(period_cmd(MLIP_CMD_HOLD, 0, 0), MLIP_OK);
	tick(5);
	struct mlip_ring_status s = status();
	assert_int_equal(s.state, MLIP_STATE_IDLE);
	assert_int_equal(s.held_by, MLIP_WHY_HOLD);
	assert_true(mlip_state_hold_latched(s.state, s.held_by));
	assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 0, 600), 0), MLIP_E_INVALID);
	tick(50);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_true(out.pos[0] == 0.0);
	/* resumed at rest: no latch, nothing moved, no stop counted */
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK);
	tick(20);
	s = status();
	assert_int_equal(s.state, MLIP_STATE_IDLE);
	assert_int_equal(s.held_by, 0);
	assert_false(mlip_state_hold_latched(s.state, s.held_by));
	assert_true(out.pos[0] == 0.0 && out.pos[1] == 0.0);
	assert_int_equal(s.stops, 0);
	line_unheld(5.0);
	/* latched again, then a stop at rest clears it: the next program runs */
	assert_int_equal(period_cmd(MLIP_CMD_HOLD, 0, 0), MLIP_OK);
	tick(5);
	assert_int_equal(status().held_by, MLIP_WHY_HOLD);
	stop_count++;
	tick(5);
	assert_int_equal(status().stop_seen, stop_count);
	s = status();
	assert_int_equal(s.state, MLIP_STATE_IDLE);
	assert_int_equal(s.held_by, 0);
	feeder_base = stop_count; /* the next feeder began after that stop */
	line_unheld(10.0);
	/* latched, the next program pre-reads and waits held, unmoved, the
	 * hold in the status all along; a resume starts it */
	assert_int_equal(period_cmd(MLIP_CMD_HOLD, 0, 0), MLIP_OK);
	move(1, 12.0, 0.0);
	end(2);
	for (int k = 0; k < 300; k++) {
		tick(1);
		assert_int_equal(status().held_by, MLIP_WHY_HOLD);
		assert_true(out.pos[0] == 10.0);
	}
	assert_int_equal(status().state, MLIP_STATE_HELD);
	assert_int_equal(status().reason, MLIP_WHY_HOLD);
	assert_false(
	    mlip_state_hold_latched(MLIP_STATE_HELD, MLIP_WHY_HOLD)); /* held: its reason */
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK);
	until(MLIP_STATE_IDLE, 5000);
	assert_int_equal(status().held_by, 0);
	assert_true(out.pos[0] == 12.0);
}

/* Feed override 0 holds the path and is in the status as what holds it
 * (held_by override 0), at rest too: the next program starts held, unmoved,
 * until a higher override, never until a resume. It is not a latched hold
 * (a resume does not end it; mlip-ctl status and mlip-grbl said "hold
 * latched: resume" or bare idle). A hold latched with it is the hold until
 * a resume, then the override again. */
static void test_override_zero_holds_in_the_status(void **st)
{
	(void)st;
	tick(5);
	assert_int_equal(period_cmd(MLIP_CMD_OVERRIDE, 0, 0), MLIP_OK);
	tick(5);
	struct mlip_ring_status s = status();
	assert_int_equal(s.state, MLIP_STATE_IDLE);
	assert_int_equal(s.held_by, MLIP_WHY_OVERRIDE_ZERO);
	assert_int_equal(mlip_state_held_by(s.held_by), MLIP_WHY_OVERRIDE_ZERO);
	assert_false(mlip_state_hold_latched(s.state, s.held_by)); /* a resume does not end it */
	/* a resume at rest changes nothing */
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK);
	tick(5);
	assert_int_equal(status().held_by, MLIP_WHY_OVERRIDE_ZERO);
	/* the next program: held before its first move, said so all along */
	move(1, 5.0, 0.0);
	end(2);
	until(MLIP_STATE_HELD, 3000);
	assert_int_equal(status().reason, MLIP_WHY_OVERRIDE_ZERO);
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK);
	for (int k = 0; k < 300; k++) {
		tick(1);
		assert_int_equal(status().state, MLIP_STATE_HELD);
		assert_int_equal(status().held_by, MLIP_WHY_OVERRIDE_ZERO);
		assert_true(out.pos[0] == 0.0);
	}
	/* a hold on top: the hold is what a resume ends, then the override */
	assert_int_equal(period_cmd(MLIP_CMD_HOLD, 0, 0), MLIP_OK);
	tick(2);
	assert_int_equal(status().held_by, MLIP_WHY_HOLD);
	assert_int_equal(status().reason, MLIP_WHY_HOLD);
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK);
	tick(2);
	assert_int_equal(status().held_by, MLIP_WHY_OVERRIDE_ZERO);
	assert_int_equal(status().reason, MLIP_WHY_OVERRIDE_ZERO);
	assert_true(out.pos[0] == 0.0);
	/* a higher override ends it: the program runs to its end, nothing holds */
	assert_int_equal(period_cmd(MLIP_CMD_OVERRIDE, 100, 0), MLIP_OK);
	until(MLIP_STATE_IDLE, 5000);
	assert_int_equal(status().reason, MLIP_WHY_END);
	assert_int_equal(status().held_by, 0);
	assert_true(out.pos[0] == 5.0);
}

/* A program stopped before its first block ends has completed nothing: the
 * status must not show the previous program's last block. */
static void test_stop_before_first_block_completes(void **st)
{
	(void)st;
	push(1, 5);
	end(6);
	until(MLIP_STATE_IDLE, 3000);
	assert_int_equal(status().exec_seq, 6);
	move(1, 0.0, 0.0); /* the next program: back to X = 0, 5 mm, stopped at once */
	end(2);
	tick(20);
	period_cmd(MLIP_CMD_STOP, 0, 0);
	tick(300);
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	assert_true(out.pos[0] > 0.0 && out.pos[0] < 5.0); /* stopped inside block 1 */
	assert_int_equal(status().exec_seq, 0);
}

/* mlip-ctl stop while the feeder still checks its program (issue 17: the
 * controller was idle, stop was a no-op, the program ran 1.5 s later): the
 * stop is latched for the program whose feeder began before it, which is
 * dropped unmoved and named; a stop older than the feeder (stale) does not
 * touch the next program; a feeder area mid-update starts nothing. */
static void test_stop_latched_for_the_program_about_to_start(void **st)
{
	(void)st;
	feeder_base = 3; /* the feeder began when the counter was 3 */
	stop_count = 3;
	tick(5);
	stop_count = 4; /* mlip-ctl stop during its check pass */
	tick(5);
	assert_int_equal(status().stop_seen, 4); /* acknowledged */
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	push(1, 5);
	end(6);
	tick(300);
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	assert_true(out.pos[0] == 0.0 && out.pos[1] == 0.0); /* nothing moved */
	assert_int_equal(status().reason, MLIP_WHY_STOP_EARLY);
	assert_int_equal(status().reason_seq, 1);
	assert_int_equal(status().reason_line, 2);
	assert_int_equal(mlip_ring_count(ring), 0); /* its records dropped, END too */
	assert_int_equal(status().exec_seq, 0);
	assert_true(saw(MLIP_STATE_IDLE, MLIP_WHY_STOP_EARLY));
	/* the next feeder began after that stop: its program runs */
	feeder_base = 4;
	push(1, 5);
	end(6);
	until(MLIP_STATE_IDLE, 3000);
	assert_true(out.pos[0] == 5.0);
	assert_int_equal(status().reason, MLIP_WHY_END);
	/* a stop while idle with nothing about to start, then a feeder that
	 * begins after it: stale for it, the program runs */
	stop_count = 5;
	tick(5);
	feeder_base = 5;
	move(1, 0.0, 0.0);
	end(2);
	until(MLIP_STATE_IDLE, 3000);
	assert_true(out.pos[0] == 0.0);
	assert_int_equal(status().reason, MLIP_WHY_END);
	/* whose program it is unknown (feeder area mid-update): it waits */
	stop_count = 6;
	tick(2);
	move(1, 3.0, 0.0);
	end(2);
	struct mlip_ctl_in in = {.period = period++,
	                         .feeder_alive = 1,
	                         .feeder_unread = 1,
	                         .stop_requests = stop_count,
	                         .feeder_stop_base = 6};
	run_period(&in);
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	assert_int_equal(mlip_ring_count(ring), 2);
	feeder_base = 6;
	until(MLIP_STATE_IDLE, 3000);
	assert_true(out.pos[0] == 3.0);
}

/* A stop request (the counter) while running: the same stop as the
 * command, never behind the mailbox. */
static void test_stop_counter_stops_a_running_program(void **st)
{
	(void)st;
	move(1, 100.0, 0.0);
	end(2);
	tick(300);
	assert_int_equal(out.status.state, MLIP_STATE_RUNNING);
	stop_count++;
	tick(1);
	assert_int_equal(out.status.state, MLIP_STATE_STOPPING);
	assert_int_equal(status().stop_seen, stop_count);
	until(MLIP_STATE_IDLE, 500);
	assert_int_equal(status().reason, MLIP_WHY_STOP);
	assert_true(out.pos[0] > 10.0 && out.pos[0] < 100.0);
}

/* The reason follows the state (issue 17: after override 0, hold, override
 * 100 the status said "held, override 0" at 100 %). */
static void test_hold_reason_follows_the_causes(void **st)
{
	(void)st;
	move(1, 500.0, 0.0);
	end(2);
	tick(200);
	period_cmd(MLIP_CMD_OVERRIDE, 0, 0);
	until(MLIP_STATE_HELD, 500);
	assert_int_equal(status().reason, MLIP_WHY_OVERRIDE_ZERO);
	period_cmd(MLIP_CMD_HOLD, 0, 0);
	tick(1);
	assert_int_equal(status().reason, MLIP_WHY_HOLD);
	period_cmd(MLIP_CMD_OVERRIDE, 100, 0);
	tick(50);
	double x = out.pos[0];
	assert_int_equal(status().state, MLIP_STATE_HELD);
	assert_int_equal(status().reason, MLIP_WHY_HOLD); /* not "override 0" at 100 % */
	assert_int_equal(status().override_pct, 100);
	assert_true(out.pos[0] == x); /* and held indeed */
	/* hold, then override 0, then resume: held by the override now */
	period_cmd(MLIP_CMD_OVERRIDE, 0, 0);
	period_cmd(MLIP_CMD_RESUME, 0, 0);
	tick(2);
	assert_int_equal(status().state, MLIP_STATE_HELD);
	assert_int_equal(status().reason, MLIP_WHY_OVERRIDE_ZERO);
	assert_true(out.pos[0] == x);
	period_cmd(MLIP_CMD_OVERRIDE, 100, 0);
	until(MLIP_STATE_RUNNING, 10);
	assert_int_equal(status().reason, MLIP_WHY_RESUME);
}

/* A stop (or an exit signal) in a dwell or a pause: the wait is not done;
 * the block completed is the move before it, with its line (issue 17:
 * line 0), and the status and the events say so. */
static void stop_in_wait(uint8_t kind, int exit_signal)
{
	push(1, 3);
	event(4, kind, 10.0); /* line 5 */
	push(5, 8);
	end(9);
	until(kind == MLIP_BLOCK_DWELL ? MLIP_STATE_DWELLING : MLIP_STATE_PAUSED, 3000);
	tick(20);
	assert_int_equal(status().exec_seq, 4);
	assert_int_equal(status().exec_line, 5);
	if (exit_signal) {
		struct mlip_ctl_in in = {.period = period++, .feeder_alive = 1, .exit_request = 1};
		run_period(&in);
	} else {
		stop_count++;
		tick(1);
	}
	for (uint32_t i = 0; i < out.n_events; i++) {
		if (out.events[i].kind == MLIP_EV_STATE) {
			assert_int_equal(out.events[i].exec_seq, 3);
			assert_int_equal(out.events[i].exec_line, 4);
		}
	}
	until(MLIP_STATE_IDLE, 100);
	assert_true(out.pos[0] == 3.0); /* nothing after the wait moved */
	assert_int_equal(status().exec_seq, 3);
	assert_int_equal(status().exec_line, 4);
	assert_int_equal(status().reason, exit_signal ? MLIP_WHY_EXIT : MLIP_WHY_STOP);
}

static void test_stop_in_dwell_names_the_block_before(void **st)
{
	(void)st;
	stop_in_wait(MLIP_BLOCK_DWELL, 0);
}

static void test_stop_in_pause_names_the_block_before(void **st)
{
	(void)st;
	stop_in_wait(MLIP_BLOCK_PAUSE, 0);
}

static void test_exit_in_dwell_names_the_block_before(void **st)
{
	(void)st;
	stop_in_wait(MLIP_BLOCK_DWELL, 1);
}

/* Override 0 holds with its own reason; an exit request stops and reports
 * done at rest. */
static void test_override_zero_and_exit(void **st)
{
	(void)st;
	move(1, 100.0, 0.0);
	end(2);
	tick(200);
	period_cmd(MLIP_CMD_OVERRIDE, 0, 0);
	until(MLIP_STATE_HELD, 500);
	assert_int_equal(status().reason, MLIP_WHY_OVERRIDE_ZERO);
	assert_int_equal(period_cmd(MLIP_CMD_OVERRIDE, 300, 0), MLIP_E_RANGE);
	period_cmd(MLIP_CMD_OVERRIDE, 100, 0);
	until(MLIP_STATE_RUNNING, 10);
	struct mlip_ctl_in in = {.period = period++, .feeder_alive = 1, .exit_request = 1};
	run_period(&in);
	assert_int_equal(out.status.state, MLIP_STATE_STOPPING);
	assert_int_equal(out.status.reason, MLIP_WHY_EXIT);
	int done = 0;
	for (int i = 0; i < 500 && !done; i++) {
		in.period = period++;
		run_period(&in);
		done = out.done;
	}
	assert_true(done);
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	assert_true(out.pos[0] < 100.0);
}

/* ---- program events ------------------------------------------------------ */

/* A dwell: at rest at the end of the move before it, exactly
 * round(dwell / T) periods, then on (the next block pre-read meanwhile).
 * The move to x: 5 mm ends on a period; 10 mm a rounding-size remainder
 * after one (the planner reports rest a period after the point is reached):
 * the wait counts from the arrival either way. */
static void dwell_at(double x)
{
	move(1, x, 0.0);
	event(2, MLIP_BLOCK_DWELL, 0.2504); /* 250.4 periods: 250 */
	move(3, 2.0 * x, 0.0);
	end(4);
	double last = NAN;
	int run = 0, longest = 0, dwelling = 0;
	for (int i = 0; i < 5000 && !(out.status.state == MLIP_STATE_IDLE && i > 0); i++) {
		tick(1);
		dwelling += out.status.state == MLIP_STATE_DWELLING;
		if (out.status.state == MLIP_STATE_DWELLING) {
			assert_int_equal(status().exec_seq, 2);
			assert_true(out.pos[0] == x);
		}
		run = out.pos[0] == last ? run + 1 : 0;
		if (out.pos[0] == x && run > longest) {
			longest = run;
		}
		last = out.pos[0];
	}
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	assert_true(out.pos[0] == 2.0 * x);
	assert_true(dwelling == 249 || dwelling == 250);
	/* the arrival at x and 250 periods more at it: 250 periods of rest */
	assert_int_equal(longest, 250);
	assert_true(saw(MLIP_STATE_DWELLING, MLIP_WHY_DWELL));
	assert_true(saw(MLIP_STATE_RUNNING, MLIP_WHY_DWELL_DONE));
}

static void test_dwell_exact_periods(void **st)
{
	(void)st;
	dwell_at(5.0);
	teardown(NULL);
	setup(NULL);
	dwell_at(10.0);
}

/* A dwell at the program's start and a dwell of 0: nothing to move first. */
static void test_dwell_first_and_zero(void **st)
{
	(void)st;
	event(1, MLIP_BLOCK_DWELL, 0.01);
	event(2, MLIP_BLOCK_DWELL, 0.0);
	move(3, 1.0, 0.0);
	end(4);
	int dwelling = 0;
	for (int i = 0; i < 2000 && !(out.status.state == MLIP_STATE_IDLE && i > 0); i++) {
		tick(1);
		dwelling += out.status.state == MLIP_STATE_DWELLING;
	}
	assert_int_equal(dwelling, 10);
	assert_true(out.pos[0] == 1.0);
	assert_int_equal(status().exec_seq, 4);
}

/* M0: at rest, paused, on at resume; a resume is refused in no state but
 * fault. M1: a pause only with the optional-stop switch on. */
static void test_pause_and_optional_pause(void **st)
{
	(void)st;
	move(1, 5.0, 0.0);
	event(2, MLIP_BLOCK_PAUSE, 0.0);
	move(3, 10.0, 0.0);
	event(4, MLIP_BLOCK_OPTIONAL_PAUSE, 0.0); /* switch off: no stop */
	move(5, 15.0, 0.0);
	end(6);
	until(MLIP_STATE_PAUSED, 3000);
	assert_true(out.pos[0] == 5.0);
	assert_int_equal(status().reason, MLIP_WHY_PAUSE);
	assert_int_equal(status().exec_seq, 2);
	tick(1000);
	assert_int_equal(out.status.state, MLIP_STATE_PAUSED);
	assert_true(out.pos[0] == 5.0);
	assert_int_equal(period_cmd(MLIP_CMD_HOLD, 0, 0), MLIP_OK); /* a hold meanwhile */
	tick(10);
	assert_int_equal(out.status.state, MLIP_STATE_PAUSED);
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK); /* one resume: both */
	tick(1);
	assert_true(out.pos[0] > 5.0); /* pre-read during the pause: moves at once */
	until(MLIP_STATE_IDLE, 3000);
	assert_true(out.pos[0] == 15.0);
	assert_false(saw(MLIP_STATE_PAUSED, MLIP_WHY_OPTIONAL_PAUSE));

	/* the same program with the switch on: M1 pauses */
	assert_int_equal(period_cmd(MLIP_CMD_OPTIONAL_STOP, 2, 0), MLIP_E_RANGE);
	assert_int_equal(period_cmd(MLIP_CMD_OPTIONAL_STOP, 1, 0), MLIP_OK);
	assert_int_equal(status().optional_stop, 1);
	move(1, 5.0, 0.0);
	event(2, MLIP_BLOCK_PAUSE, 0.0);
	move(3, 10.0, 0.0);
	event(4, MLIP_BLOCK_OPTIONAL_PAUSE, 0.0);
	move(5, 15.0, 0.0);
	end(6);
	until(MLIP_STATE_PAUSED, 3000);
	period_cmd(MLIP_CMD_RESUME, 0, 0);
	tick(2);
	until(MLIP_STATE_PAUSED, 3000);
	assert_true(out.pos[0] == 10.0);
	assert_int_equal(status().reason, MLIP_WHY_OPTIONAL_PAUSE);
	/* a stop in a pause: the pre-read blocks are dropped, nothing moves */
	period_cmd(MLIP_CMD_STOP, 0, 0);
	until(MLIP_STATE_IDLE, 10);
	tick(10);
	assert_true(out.pos[0] == 10.0);
}

/* Exact stop: the corner at the end of that move is taken at rest (Y moves
 * only once X is done); without it the same corner is rounded. Returns the
 * samples inside the corner (x short of 10 and y past 0). */
static int corner_samples(int exact)
{
	struct mlip_block b = {
	    .feed_mm_s = 100.0, .tol_mm = 0.01, .line = 2, .exact_stop = (uint8_t)exact};
	struct mlip_ring_rec rec;
	b.target[0] = 10.0;
	mlip_ring_rec_from_block(&rec, &b, 1);
	push_rec(&rec);
	move(2, 10.0, 10.0);
	end(3);
	int inside = 0;
	for (int i = 0; i < 3000 && !(out.status.state == MLIP_STATE_IDLE && i > 0); i++) {
		tick(1);
		inside += out.pos[0] < 10.0 - 1e-12 && out.pos[1] > 1e-12;
	}
	assert_true(out.pos[0] == 10.0 && out.pos[1] == 10.0);
	return inside;
}

static void test_exact_stop_corner_at_rest(void **st)
{
	(void)st;
	assert_int_equal(corner_samples(1), 0);
	teardown(NULL);
	setup(NULL);
	/* a 90 degree corner at eps 0.01, A 1000: t_m = sqrt(8 eps / |a|) ~ 7.5 ms (18) */
	int n = corner_samples(0);
	assert_true(n >= 5 && n <= 10);
}

/* ---- records are validated where they are taken ------------------------- */

/* A NaN target in the middle of a program: the blocks before it run to rest
 * at the end of the last good one, nothing after it is taken (nor reported
 * complete), the state is fault with the record, field and value. */
static void check_bad(void (*corrupt)(struct mlip_ring_rec *), uint32_t field, int value_nan)
{
	push(1, 30); /* more than the look-ahead: the bad one is taken while moving */
	struct mlip_block b = {.feed_mm_s = 100.0, .tol_mm = 0.01, .line = 32};
	b.target[0] = 31.0;
	struct mlip_ring_rec rec;
	mlip_ring_rec_from_block(&rec, &b, 31);
	corrupt(&rec);
	push_rec(&rec);
	push(32, 34);
	end(35);
	tick(3000);
	struct mlip_ring_status s = status();
	assert_int_equal(s.state, MLIP_STATE_FAULT);
	assert_int_equal(s.reason, MLIP_WHY_BAD_RECORD);
	assert_int_equal(s.reason_seq, 31);
	assert_int_equal(s.reason_line, 32);
	assert_int_equal(s.reason_field, field);
	assert_true(value_nan ? isnan(s.reason_value) : !isnan(s.reason_value));
	assert_true(out.pos[0] == 30.0 && out.pos[1] == 0.0); /* at the end of block 30 */
	assert_true(mlip_planner_queued(&planner) == 0);
	assert_int_equal(mlip_ring_count(ring), 0); /* the rest dropped */
	assert_int_equal(s.exec_seq, 30);           /* never "complete" (35) */
	int faults = 0;
	for (int i = 0; i < n_seen; i++) {
		faults += seen_state[i] == MLIP_STATE_FAULT;
	}
	assert_int_equal(faults, 1); /* logged once */
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_E_INVALID);
}

static void nan_target(struct mlip_ring_rec *r)
{
	r->target[1] = NAN;
}
static void beyond_limit(struct mlip_ring_rec *r)
{
	r->target[0] = 1500.0;
}
static void nan_feed(struct mlip_ring_rec *r)
{
	r->feed_mm_s = NAN;
}
static void negative_feed(struct mlip_ring_rec *r)
{
	r->feed_mm_s = -5.0;
}
static void unknown_type(struct mlip_ring_rec *r)
{
	r->type = 77;
}
static void wrong_seq(struct mlip_ring_rec *r)
{
	r->seq = 33;
}
static void bad_dwell(struct mlip_ring_rec *r)
{
	r->type = MLIP_REC_DWELL;
	r->dwell_s = -1.0;
}
static void bad_flags(struct mlip_ring_rec *r)
{
	r->flags = 0x80;
}

static void test_bad_nan_target(void **st)
{
	(void)st;
	check_bad(nan_target, MLIP_FIELD_TARGET + 1, 1);
}
static void test_bad_beyond_soft_limit(void **st)
{
	(void)st;
	check_bad(beyond_limit, MLIP_FIELD_TARGET, 0);
	assert_true(status().reason_value == 1500.0);
}
static void test_bad_feed(void **st)
{
	(void)st;
	check_bad(nan_feed, MLIP_FIELD_FEED, 1);
	teardown(NULL);
	setup(NULL);
	check_bad(negative_feed, MLIP_FIELD_FEED, 0);
}
static void test_bad_type_seq_dwell_flags(void **st)
{
	(void)st;
	check_bad(unknown_type, MLIP_FIELD_TYPE, 0);
	teardown(NULL);
	setup(NULL);
	check_bad(wrong_seq, MLIP_FIELD_SEQ, 0);
	assert_true(status().reason_value == 33.0);
	teardown(NULL);
	setup(NULL);
	check_bad(bad_dwell, MLIP_FIELD_DWELL, 0);
	teardown(NULL);
	setup(NULL);
	check_bad(bad_flags, MLIP_FIELD_FLAGS, 0);
}

/* One test per rule of the record validation (issue 22): each rule's
 * mutant (the rule removed, or its bound moved) fails one of these. The
 * bounds are those of mlip_block_check (mlip/types.h), which the G-code
 * reader keeps too: issue 17. */
static void below_limit(struct mlip_ring_rec *r)
{
	r->target[0] = -1000.5;
}
static void feed_above_max(struct mlip_ring_rec *r)
{
	r->feed_mm_s = nextafter(MLIP_FEED_MAX_MM_S, INFINITY);
}
static void feed_below_min(struct mlip_ring_rec *r)
{
	r->feed_mm_s = nextafter(MLIP_FEED_MIN_MM_S, 0.0);
}
static void rapid_negative_feed(struct mlip_ring_rec *r)
{
	r->flags |= MLIP_REC_RAPID;
	r->feed_mm_s = -1.0;
}
static void rapid_feed_above_max(struct mlip_ring_rec *r)
{
	r->flags |= MLIP_REC_RAPID;
	r->feed_mm_s = 2e6;
}
static void tol_negative(struct mlip_ring_rec *r)
{
	r->tol_mm = -1e-9;
}
static void tol_nan(struct mlip_ring_rec *r)
{
	r->tol_mm = NAN;
}
static void tol_above_max(struct mlip_ring_rec *r)
{
	r->tol_mm = 2e6; /* CONTOUR_TOLERANCE = 2000000 passed mlip-config before */
}
static void dwell_above_max(struct mlip_ring_rec *r)
{
	r->type = MLIP_REC_DWELL;
	r->dwell_s = 100000.0; /* G4 P100000 passed the program check before */
}
static void dwell_nan(struct mlip_ring_rec *r)
{
	r->type = MLIP_REC_DWELL;
	r->dwell_s = NAN;
}

static void test_bad_below_soft_limit(void **st)
{
	(void)st;
	check_bad(below_limit, MLIP_FIELD_TARGET, 0);
	assert_true(status().reason_value == -1000.5);
}
static void test_bad_feed_above_max(void **st)
{
	(void)st;
	check_bad(feed_above_max, MLIP_FIELD_FEED, 0);
}
static void test_bad_feed_below_min(void **st)
{
	(void)st;
	check_bad(feed_below_min, MLIP_FIELD_FEED, 0);
}
static void test_bad_rapid_feed(void **st)
{
	(void)st;
	check_bad(rapid_negative_feed, MLIP_FIELD_FEED, 0);
	teardown(NULL);
	setup(NULL);
	check_bad(rapid_feed_above_max, MLIP_FIELD_FEED, 0);
}
static void test_bad_tol_negative(void **st)
{
	(void)st;
	check_bad(tol_negative, MLIP_FIELD_TOL, 0);
}
static void test_bad_tol_nan(void **st)
{
	(void)st;
	check_bad(tol_nan, MLIP_FIELD_TOL, 1);
}
static void test_bad_tol_above_max(void **st)
{
	(void)st;
	check_bad(tol_above_max, MLIP_FIELD_TOL, 0);
	assert_true(status().reason_value == 2e6);
}
static void test_bad_dwell_above_max(void **st)
{
	(void)st;
	check_bad(dwell_above_max, MLIP_FIELD_DWELL, 0);
	assert_true(status().reason_value == 100000.0);
}
static void test_bad_dwell_nan(void **st)
{
	(void)st;
	check_bad(dwell_nan, MLIP_FIELD_DWELL, 1);
}

/* Each bound itself is good: a rule is no stricter than the reader's. */
static void test_record_bounds_accepted(void **st)
{
	(void)st;
	struct mlip_block b = {
	    .feed_mm_s = MLIP_FEED_MAX_MM_S, .tol_mm = MLIP_TOL_MAX_MM, .line = 2};
	b.target[0] = 1000.0;
	b.target[1] = -1000.0;
	struct mlip_ring_rec rec;
	struct mlip_ctl_reason why;
	mlip_ring_rec_from_block(&rec, &b, 1);
	assert_int_equal(mlip_ctl_check_record(&mach, &rec, 1, &why), MLIP_OK);
	rec.feed_mm_s = MLIP_FEED_MIN_MM_S;
	rec.tol_mm = 0.0;
	assert_int_equal(mlip_ctl_check_record(&mach, &rec, 1, &why), MLIP_OK);
	rec.flags |= MLIP_REC_RAPID;
	rec.feed_mm_s = 0.0;
	assert_int_equal(mlip_ctl_check_record(&mach, &rec, 1, &why), MLIP_OK);
	struct mlip_block d = {.kind = MLIP_BLOCK_DWELL, .dwell_s = MLIP_DWELL_MAX_S, .line = 3};
	mlip_ring_rec_from_block(&rec, &d, 2);
	assert_int_equal(mlip_ctl_check_record(&mach, &rec, 2, &why), MLIP_OK);
	rec.dwell_s = 0.0;
	assert_int_equal(mlip_ctl_check_record(&mach, &rec, 2, &why), MLIP_OK);
	/* and the same records through mlip_block_check, the reader's side */
	assert_int_equal(mlip_block_check(&mach, &b), MLIP_RULE_OK);
	assert_int_equal(mlip_block_check(&mach, &d), MLIP_RULE_OK);
}

/* A target inside the soft limits but beyond the drive's 32-bit position
 * (COUNTS_PER_UNIT): refused where the record is taken, before anything
 * moves; it faulted the controller once the machine got there. */
static void test_bad_beyond_drive_count(void **st)
{
	(void)st;
	struct mlip_machine m2 = mach;
	m2.axis[0].counts_per_unit = 1e7; /* 0.1 nm: +-214.7483647 mm in an int32 */
	struct mlip_block b = {.feed_mm_s = 100.0, .tol_mm = 0.01, .line = 2};
	struct mlip_ring_rec rec;
	struct mlip_ctl_reason why;
	b.target[0] = 214.7483647;
	mlip_ring_rec_from_block(&rec, &b, 1);
	assert_int_equal(mlip_ctl_check_record(&m2, &rec, 1, &why), MLIP_OK);
	b.target[0] = -214.7483648;
	mlip_ring_rec_from_block(&rec, &b, 1);
	assert_int_equal(mlip_ctl_check_record(&m2, &rec, 1, &why), MLIP_OK);
	b.target[0] = 214.75;
	mlip_ring_rec_from_block(&rec, &b, 1);
	assert_int_equal(mlip_ctl_check_record(&m2, &rec, 1, &why), MLIP_E_RANGE);
	assert_int_equal(why.field, MLIP_FIELD_TARGET);
	assert_true(why.value == 214.75);
	b.target[0] = -214.75;
	mlip_ring_rec_from_block(&rec, &b, 1);
	assert_int_equal(mlip_ctl_check_record(&m2, &rec, 1, &why), MLIP_E_RANGE);
}

/* The I/O records' rules (issue 19), one case each side of each bound: a
 * spindle speed within +-MLIP_REC_RPM_MAX, a whole tool number in
 * 0..MLIP_REC_TOOL_MAX, coolant as MLIP_COOLANT_* bits. */
static mlip_status io_record(uint16_t type, double v)
{
	struct mlip_ring_rec rec = {.seq = 1, .line = 2, .type = type, .dwell_s = v};
	struct mlip_ctl_reason why;
	mlip_status st = mlip_ctl_check_record(&mach, &rec, 1, &why);
	if (st != MLIP_OK) {
		assert_int_equal(why.field, MLIP_FIELD_DWELL);
	}
	return st;
}

static void test_bad_spindle_speed(void **st)
{
	(void)st;
	assert_int_equal(io_record(MLIP_REC_SPINDLE, MLIP_REC_RPM_MAX), MLIP_OK);
	assert_int_equal(io_record(MLIP_REC_SPINDLE, -MLIP_REC_RPM_MAX), MLIP_OK);
	assert_int_equal(io_record(MLIP_REC_SPINDLE, 0.0), MLIP_OK);
	assert_int_equal(io_record(MLIP_REC_SPINDLE, nextafter(MLIP_REC_RPM_MAX, INFINITY)),
	                 MLIP_E_RANGE);
	assert_int_equal(io_record(MLIP_REC_SPINDLE, -nextafter(MLIP_REC_RPM_MAX, INFINITY)),
	                 MLIP_E_RANGE);
	assert_int_equal(io_record(MLIP_REC_SPINDLE, NAN), MLIP_E_RANGE);
	/* an MDI S alone: a speed, no direction */
	assert_int_equal(io_record(MLIP_REC_SPEED, 0.0), MLIP_OK);
	assert_int_equal(io_record(MLIP_REC_SPEED, MLIP_REC_RPM_MAX), MLIP_OK);
	assert_int_equal(io_record(MLIP_REC_SPEED, -1.0), MLIP_E_RANGE);
	assert_int_equal(io_record(MLIP_REC_SPEED, nextafter(MLIP_REC_RPM_MAX, INFINITY)),
	                 MLIP_E_RANGE);
	assert_int_equal(io_record(MLIP_REC_SPEED, NAN), MLIP_E_RANGE);
}

/* An MDI S alone on a machine whose controller drives no spindle: not a
 * record mlip's reader sends (it refuses the line): a bad record, nothing
 * after it runs. */
static void test_speed_without_spindle(void **st)
{
	(void)st;
	event(1, MLIP_BLOCK_SPEED, 3000.0);
	move(2, 5.0, 0.0);
	end(3);
	until(MLIP_STATE_FAULT, 100);
	assert_int_equal(status().reason, MLIP_WHY_BAD_RECORD);
	assert_int_equal(status().reason_field, MLIP_FIELD_TYPE);
	assert_true(status().reason_value == MLIP_REC_SPEED);
	tick(200);
	assert_true(out.pos[0] == 0.0); /* the move after it never ran */
}

static void test_bad_tool_number(void **st)
{
	(void)st;
	assert_int_equal(io_record(MLIP_REC_TOOL, 0.0), MLIP_OK);
	assert_int_equal(io_record(MLIP_REC_TOOL, MLIP_REC_TOOL_MAX), MLIP_OK);
	assert_int_equal(io_record(MLIP_REC_TOOL, -1.0), MLIP_E_RANGE);
	assert_int_equal(io_record(MLIP_REC_TOOL, MLIP_REC_TOOL_MAX + 1.0), MLIP_E_RANGE);
	assert_int_equal(io_record(MLIP_REC_TOOL, 2.5), MLIP_E_RANGE);
	assert_int_equal(io_record(MLIP_REC_TOOL, NAN), MLIP_E_RANGE);
}

static void test_bad_coolant_bits(void **st)
{
	(void)st;
	for (unsigned b = 0; b <= (MLIP_COOLANT_MIST | MLIP_COOLANT_FLOOD); b++) {
		assert_int_equal(io_record(MLIP_REC_COOLANT, (double)b), MLIP_OK);
	}
	assert_int_equal(io_record(MLIP_REC_COOLANT, 4.0), MLIP_E_RANGE);
	assert_int_equal(io_record(MLIP_REC_COOLANT, 1.5), MLIP_E_RANGE);
	assert_int_equal(io_record(MLIP_REC_COOLANT, -1.0), MLIP_E_RANGE);
	assert_int_equal(io_record(MLIP_REC_COOLANT, NAN), MLIP_E_RANGE);
}

/* Issue 17 item 8, the dwell case: a bad record found while the machine
 * dwells (the pre-read of what follows the dwell) starts nothing after the
 * dwell; the fault names the block the machine rests at the end of (3, the
 * move before the dwell), not the one before the bad record (6). */
static void test_bad_record_in_dwell_rests_before_it(void **st)
{
	(void)st;
	push(1, 3);
	event(4, MLIP_BLOCK_DWELL, 10.0);
	push(5, 6);
	struct mlip_block d = {.kind = MLIP_BLOCK_DWELL, .dwell_s = 100000.0, .line = 8};
	struct mlip_ring_rec rec;
	mlip_ring_rec_from_block(&rec, &d, 7);
	push_rec(&rec);
	push(8, 9);
	end(10);
	until(MLIP_STATE_FAULT, 5000);
	const struct mlip_ctl_event *f = NULL;
	for (uint32_t i = 0; i < out.n_events; i++) {
		if (out.events[i].kind == MLIP_EV_STATE &&
		    out.events[i].state == MLIP_STATE_FAULT) {
			f = &out.events[i];
		}
	}
	assert_non_null(f);
	assert_int_equal(f->from, MLIP_STATE_DWELLING);
	assert_int_equal(f->r.seq, 7);
	assert_int_equal(f->r.field, MLIP_FIELD_DWELL);
	assert_int_equal(f->exec_seq, 3);
	assert_int_equal(f->exec_line, 4);
	tick(2000);
	assert_true(out.pos[0] == 3.0 && out.pos[1] == 0.0); /* 5 and 6 never started */
	assert_int_equal(status().exec_seq, 3);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
}

/* A bad record found while nothing moves (the pre-read): nothing moves. */
static void test_bad_record_in_preread_never_moves(void **st)
{
	(void)st;
	push(1, 3);
	struct mlip_block b = {.feed_mm_s = 100.0, .line = 5};
	b.target[0] = INFINITY;
	struct mlip_ring_rec rec;
	mlip_ring_rec_from_block(&rec, &b, 4);
	push_rec(&rec);
	tick(500);
	assert_int_equal(out.status.state, MLIP_STATE_FAULT);
	assert_true(out.pos[0] == 0.0);
}

/* ---- a corrupted segment header ------------------------------------------ */

/* Capacity, mask and the consumer's tail as the segment says them after
 * start-up are not used: the program runs as if nothing happened. */
static void test_corrupt_sizes_ignored(void **st)
{
	(void)st;
	push(1, 40);
	end(41);
	ring->capacity = 1u << 30;
	ring->mask = 0xFFFFFFFFu;
	ring->n_axes = 77;
	until(MLIP_STATE_IDLE, 5000);
	assert_true(out.pos[0] == 40.0);
	assert_int_equal(status().exec_seq, 41);
}

/* head - tail beyond the capacity: a fault with the distance, at rest at the
 * end of what was taken, nothing read past it, no crash. */
static void test_corrupt_head_is_a_fault(void **st)
{
	(void)st;
	push(1, 40);
	end(41);
	tick(200); /* moving, look-ahead of 16 taken */
	assert_int_equal(out.status.state, MLIP_STATE_RUNNING);
	uint32_t tail = __atomic_load_n(&ring->tail, __ATOMIC_ACQUIRE);
	__atomic_store_n(&ring->head, tail + 3 * CAP + 5, __ATOMIC_RELEASE);
	tick(5000);
	struct mlip_ring_status s = status();
	assert_int_equal(s.state, MLIP_STATE_FAULT);
	assert_int_equal(s.reason, MLIP_WHY_RING_CORRUPT);
	assert_int_equal(s.reason_field, MLIP_FIELD_HEAD);
	assert_true(s.reason_value == 3.0 * CAP + 5.0);
	assert_true(s.speed_mm_s == 0.0 && out.pos[0] < 40.0 && out.pos[0] == floor(out.pos[0]));
	assert_int_equal(s.exec_seq, (uint64_t)out.pos[0]); /* at the end of the last block taken */
}

/* ---- stalls ------------------------------------------------------------- */

/* Held at rest at x = at (y 0) on the line to (100, 0), then (100, 50):
 * resumed, the first steps within A T^2 (a margin of 1e-9), on to the end. */
static void resume_from_rest(double at)
{
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK);
	double x1 = out.pos[0];
	tick(1);
	double x2 = out.pos[0];
	assert_true(x1 - at <= 1000.0 * 1e-6 * (1.0 + 1e-9));
	assert_true(x2 - 2.0 * x1 + at <= 1000.0 * 1e-6 * (1.0 + 1e-9));
	assert_true(x2 > x1);
	until(MLIP_STATE_IDLE, 5000);
	assert_true(out.pos[0] == 100.0 && out.pos[1] == 50.0);
}

/* Missed periods beyond the limit: the next setpoints repeat the last one
 * sent (no jump), state held with reason stall; resume moves from rest
 * within the acceleration limit. */
static void test_stall_holds_at_last_setpoint(void **st)
{
	(void)st;
	move(1, 100.0, 0.0);
	move(2, 100.0, 50.0);
	end(3);
	tick(150);
	double before = out.pos[0];
	assert_true(status().speed_mm_s > 50.0);
	period_cmd(0, 0, 3); /* at the limit: not a stall */
	assert_int_equal(out.status.state, MLIP_STATE_RUNNING);
	assert_true(out.pos[0] > before);
	before = out.pos[0];
	period_cmd(0, 0, 2000); /* 2 s */
	assert_int_equal(out.status.state, MLIP_STATE_HELD);
	assert_int_equal(status().reason, MLIP_WHY_STALL);
	assert_true(status().reason_value == 2000.0);
	assert_true(out.pos[0] == before);
	for (int i = 0; i < 500; i++) {
		tick(1);
		assert_true(fabs(out.pos[0] - before) <= 1e-9 && fabs(out.pos[1]) <= 1e-9);
	}
	assert_int_equal(out.status.state, MLIP_STATE_HELD);
	assert_true(status().speed_mm_s == 0.0);
	resume_from_rest(before);
}

/* A stall between a period's work and its send (in.unsent: its setpoint
 * never went out): held at the setpoint before, the last one sent, exactly,
 * with reason stall; resume moves from rest within the acceleration limit
 * (a margin of 1e-9) and ends on the program's last point. */
static void test_stall_before_the_send(void **st)
{
	(void)st;
	move(1, 100.0, 0.0);
	move(2, 100.0, 50.0);
	end(3);
	tick(150);
	double sent = out.pos[0];
	tick(1);                               /* this period's setpoint is withheld */
	assert_true(out.pos[0] > sent + 0.05); /* at speed: a step of > 50 mm/s */
	unsent_in = 1;
	tick(1);
	assert_int_equal(out.status.state, MLIP_STATE_HELD);
	assert_int_equal(status().reason, MLIP_WHY_STALL);
	assert_true(out.pos[0] == sent && out.pos[1] == 0.0);
	for (int i = 0; i < 100; i++) {
		tick(1);
		assert_true(out.pos[0] == sent && out.pos[1] == 0.0);
	}
	resume_from_rest(sent);
}

/* A stall inside a corner: rest there, then a straight line to the next
 * segment's end, within the corner's tolerance of the path. */
static void test_stall_in_corner(void **st)
{
	(void)st;
	move(1, 10.0, 0.0);
	move(2, 10.0, 10.0);
	end(3);
	int k;
	/* inside the corner: x short of 10 and y past 0 (the rounded corner) */
	for (k = 0; k < 3000 && !(out.pos[0] < 10.0 - 1e-12 && out.pos[1] > 1e-12); k++) {
		tick(1);
	}
	assert_true(out.pos[0] < 10.0 - 1e-12 && out.pos[1] > 1e-12);
	double p0[2] = {out.pos[0], out.pos[1]};
	period_cmd(0, 0, 50);
	assert_int_equal(out.status.state, MLIP_STATE_HELD);
	tick(10);
	assert_true(fabs(out.pos[0] - p0[0]) <= 1e-9 && fabs(out.pos[1] - p0[1]) <= 1e-9);
	period_cmd(MLIP_CMD_RESUME, 0, 0);
	double worst = 0.0;
	for (k = 0; k < 3000 && out.status.state != MLIP_STATE_IDLE; k++) {
		tick(1);
		/* distance to the polyline (0,0)-(10,0)-(10,10) */
		double dx = out.pos[0] <= 10.0 ? fabs(out.pos[1]) : INFINITY;
		double dy = out.pos[1] >= 0.0 ? fabs(out.pos[0] - 10.0) : INFINITY;
		double d = dx < dy ? dx : dy;
		worst = d > worst ? d : worst;
	}
	assert_true(worst <= 0.01 + 1e-9);
	assert_true(out.pos[0] == 10.0 && out.pos[1] == 10.0);
}

/* ---- records <-> blocks ------------------------------------------------- */

static void test_record_roundtrip(void **st)
{
	(void)st;
	struct mlip_block b = {.feed_mm_s = 10.0,
	                       .tol_mm = 0.005,
	                       .line = 9,
	                       .rapid = 1,
	                       .exact_stop = 1,
	                       .kind = MLIP_BLOCK_MOVE},
	                  c;
	struct mlip_ring_rec rec;
	mlip_ring_rec_from_block(&rec, &b, 4);
	assert_int_equal(rec.type, MLIP_REC_MOVE);
	assert_int_equal(rec.flags, MLIP_REC_RAPID | MLIP_REC_EXACT);
	assert_int_equal(mlip_ring_rec_to_block(&rec, &c), MLIP_OK);
	assert_int_equal(c.exact_stop, 1);
	assert_int_equal(c.rapid, 1);
	b = (struct mlip_block){.kind = MLIP_BLOCK_DWELL, .dwell_s = 1.5};
	mlip_ring_rec_from_block(&rec, &b, 5);
	assert_int_equal(rec.type, MLIP_REC_DWELL);
	assert_int_equal(mlip_ring_rec_to_block(&rec, &c), MLIP_OK);
	assert_int_equal(c.kind, MLIP_BLOCK_DWELL);
	assert_true(c.dwell_s == 1.5);
	b.kind = MLIP_BLOCK_OPTIONAL_PAUSE;
	mlip_ring_rec_from_block(&rec, &b, 6);
	assert_int_equal(rec.type, MLIP_REC_OPTIONAL_PAUSE);
	b = (struct mlip_block){.kind = MLIP_BLOCK_SPEED, .value = 4500.0};
	mlip_ring_rec_from_block(&rec, &b, 6);
	assert_int_equal(rec.type, MLIP_REC_SPEED);
	assert_int_equal(mlip_ring_rec_to_block(&rec, &c), MLIP_OK);
	assert_true(c.kind == MLIP_BLOCK_SPEED && c.value == 4500.0);
	b.kind = MLIP_BLOCK_SPEED + 1; /* unknown: stays unknown, refused by the controller */
	mlip_ring_rec_from_block(&rec, &b, 6);
	assert_int_equal(mlip_ring_rec_to_block(&rec, &c), MLIP_E_INVALID);
	mlip_ring_rec_end(&rec, 7, 8);
	assert_int_equal(mlip_ring_rec_to_block(&rec, &c), MLIP_E_EMPTY);
}

/* Every state, reason, field and record type has a name for the log and
 * the status (a new enum value without one shows as "?"). */
static void test_every_name(void **st)
{
	(void)st;
	for (uint32_t v = 0; v < MLIP_STATE_COUNT; v++) {
		assert_string_not_equal(mlip_ctl_state_name(v), "?");
	}
	for (uint32_t v = 0; v < MLIP_WHY_COUNT; v++) {
		assert_string_not_equal(mlip_state_why_name(v), "?");
	}
	for (uint32_t v = 0; v < MLIP_FIELD_COUNT; v++) {
		assert_string_not_equal(mlip_rec_field_name(v), "?");
	}
	for (uint32_t v = 0; v < MLIP_REC_TYPES; v++) {
		assert_string_not_equal(mlip_rec_type_name(v), "?");
	}
	for (uint32_t v = 0; v < MLIP_CMD_COUNT; v++) {
		assert_string_not_equal(mlip_ring_cmd_name(v), "?");
	}
	assert_string_equal(mlip_ctl_state_name(MLIP_STATE_COUNT), "?");
	assert_string_equal(mlip_state_why_name(MLIP_WHY_COUNT), "?");
}

/* ---- CiA 402 drive faults (an input of the period) ---------------------- */

static int saw_event(uint32_t state, uint32_t why, const struct mlip_ctl_out *o)
{
	for (uint32_t i = 0; i < o->n_events; i++) {
		if (o->events[i].kind == MLIP_EV_STATE && o->events[i].state == state &&
		    o->events[i].r.why == why) {
			return 1;
		}
	}
	return 0;
}

/* A drive faults at speed in the middle of a program: state fault with the
 * node, the event, its value and the block and line; every axis stops on
 * the path (Y stays 0, X never goes back) within the braking distance
 * v^2 / 2a = 100^2 / 2000 = 5 mm; nothing more is taken, the program never
 * completes, a later fault does not replace the first. */
static void test_drive_fault_stops_on_the_path(void **st)
{
	(void)st;
	push(1, 50); /* 1 mm blocks along X at 100 mm/s */
	end(51);
	tick(300); /* 0.3 s: past the 0.1 s ramp to 100 mm/s, about X = 25 */
	assert_int_equal(out.status.state, MLIP_STATE_RUNNING);
	double v0 = status().speed_mm_s, x0 = out.pos[0];
	assert_true(v0 > 99.0 && v0 < 100.0 + 1e-6);
	uint64_t executing = status().exec_seq;
	assert_true(executing > 10 && executing < 40);

	drv_fault.event = 1; /* MLIP_DRIVE_FAULT_BIT (mlip/canopen/canopen.h) */
	drv_fault.node = 2;
	drv_fault.value = 0x0218;
	tick(1);
	assert_true(saw_event(MLIP_STATE_FAULT, MLIP_WHY_DRIVE, &out));
	struct mlip_ring_status s = status();
	assert_int_equal(s.state, MLIP_STATE_FAULT);
	assert_int_equal(s.reason, MLIP_WHY_DRIVE);
	assert_int_equal(s.reason_node, 2);
	assert_int_equal(s.reason_field, 1);
	assert_true(s.reason_value == 0x0218);
	assert_true(s.reason_seq == executing || s.reason_seq == executing + 1);
	assert_int_equal(s.reason_line, s.reason_seq + 1); /* line = seq + 1 in move() */

	/* a second drive's fault later: the first stays the reason */
	drv_fault.event = 3; /* heartbeat lost */
	drv_fault.node = 1;
	drv_fault.value = 120.0;
	double prev = out.pos[0];
	int k;
	for (k = 0; k < 2000 && (k == 0 || status().speed_mm_s > 0.0); k++) {
		tick(1);
		assert_true(out.pos[1] == 0.0);
		assert_true(out.pos[0] >= prev);
		assert_true(out.pos[0] - prev <= 100.0 * 0.001 + 1e-9); /* never faster */
		prev = out.pos[0];
	}
	assert_true(k < 2000);
	/* at rest on the path, short of the program's end, within the braking
	 * distance (5 mm, plus one period at speed for the reaction) */
	double travelled = out.pos[0] - x0;
	assert_true(travelled > 0.0);
	assert_true(travelled <= 5.0 + 0.1 + 1e-6);
	assert_true(out.pos[0] < 50.0);
	tick(500);
	s = status();
	assert_int_equal(s.state, MLIP_STATE_FAULT);
	assert_int_equal(s.reason, MLIP_WHY_DRIVE);
	assert_int_equal(s.reason_node, 2);
	assert_true(out.pos[0] == prev); /* still at rest: nothing more runs */
	/* the rest of the program was dropped, not run: the last block done is
	 * the one the stop ended in */
	assert_true(status().exec_seq >= executing && status().exec_seq <= executing + 6);
	assert_true(fabs(out.pos[0] - (double)status().exec_seq) < 1.0);
	assert_true(!saw(MLIP_STATE_IDLE, MLIP_WHY_END)); /* never "complete" */
	/* an exit request ends at once: at rest, the program's records up to
	 * its END dropped */
	assert_int_equal(mlip_ring_count(ring), 0);
	struct mlip_ctl_in in = {.period = period++, .exit_request = 1, .feeder_alive = 1};
	run_period(&in);
	assert_int_equal(out.done, 1);
}

/* A drive fault with the machine idle: state fault at once, nothing moves;
 * the drives' positions actual are published as given. */
static void test_drive_fault_idle_and_actual_positions(void **st)
{
	(void)st;
	drv_actual_mask = 3u;
	drv_actual[0] = 0.001;
	drv_actual[1] = -0.002;
	tick(5);
	assert_int_equal(status().actual_mask, 3u);
	assert_true(status().pos_actual[0] == 0.001 && status().pos_actual[1] == -0.002);
	assert_int_equal(status().reason_node, 0);
	drv_fault.event = 2; /* EMCY */
	drv_fault.node = 3;
	drv_fault.value = 0x2310;
	tick(1);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_int_equal(status().reason, MLIP_WHY_DRIVE);
	assert_int_equal(status().reason_node, 3);
	assert_int_equal(status().reason_field, 2);
	assert_true(status().reason_value == 0x2310);
	/* a program sent now never starts */
	push(1, 5);
	end(6);
	tick(200);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_true(out.pos[0] == 0.0 && out.pos[1] == 0.0);
}

/* ---- CiA 402 drives: their power, decided here (opts.drives) ------------- */

static struct mlip_can_config can_cia402 = {"cia402", 1000000, 5000000, 0x080,
                                            0x200,    0x300,   0x400,   0x180};
static int drv_deaf; /* bit k: drive k ignores enable operation (stays "switched on") */
static int lag[2], qs_stay[2], sod_stuck; /* ltick's drives */
static uint64_t lt_start;                 /* ltick's first period */

static int setup_drives(void **state)
{
	setup(state);
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT,
	                          .lookahead = 16,
	                          .can = &can_cia402,
	                          .drives = 1,
	                          .drive_state_periods = 50};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
	drv_actual_mask = 3u;
	drv_actual[0] = drv_actual[1] = 0.0;
	drv_sw[0] = drv_sw[1] = 0x0237; /* enabled by the bring-up */
	drv_deaf = 0;
	lag[0] = lag[1] = qs_stay[0] = qs_stay[1] = sod_stuck = 0;
	lt_start = UINT64_MAX;
	return 0;
}

/* The controlword of this period's RPDO to axis k's drive. */
static uint16_t cw_of(int k)
{
	for (int i = 0; i < out.n_frames; i++) {
		if (out.frames[i].id == 0x200u + (uint32_t)mach.axis[k].can_node) {
			return (uint16_t)(out.frames[i].data[0] | out.frames[i].data[1] << 8);
		}
	}
	fail_msg("no RPDO to axis %d", k);
	return 0;
}

/* n periods; after each, every drive takes its RPDO at once (its TPDO of
 * the next period shows it): the controlword's state, and the target when
 * enabled. */
static void dtick(int n)
{
	for (int i = 0; i < n; i++) {
		tick(1);
		for (int k = 0; k < 2; k++) {
			uint16_t cw = cw_of(k);
			int enabled = drv_sw[k] == 0x0237;
			if (cw == 0x0F && (drv_sw[k] == 0x0233 || enabled) &&
			    !(drv_deaf & (1 << k))) {
				drv_sw[k] = 0x0237;
				drv_actual[k] = out.pos[k];
			} else if (cw == 0x07 && drv_sw[k] != 0x0250) {
				drv_sw[k] = 0x0233;
			} else if (cw == 0x06) {
				drv_sw[k] = 0x0231;
			} else if (cw == 0x02 && enabled) {
				/* quick stop, option code 2: then switch on disabled */
				drv_sw[k] = 0x0250;
			}
		}
	}
}

/* Periods until the drives' power is p (at most n). */
static int until_power(uint32_t p, int n)
{
	for (int i = 1; i <= n; i++) {
		dtick(1);
		if (status().drive_power == p) {
			return i;
		}
	}
	fail_msg("power %s not reached in %d periods (now %s)", mlip_drive_power_name(p), n,
	         mlip_drive_power_name(status().drive_power));
	return -1;
}

/* Pause (M0) and feed hold keep the drives enabled, holding position; the
 * program's end disables them at rest: 0x07, then 0x06. */
static void test_drives_pause_hold_then_disabled(void **st)
{
	(void)st;
	dtick(10);
	assert_int_equal(status().drive_power, MLIP_POWER_ENABLED); /* idle after bring-up */
	push(1, 3);
	event(4, MLIP_BLOCK_PAUSE, 0.0);
	for (uint64_t k = 5; k <= 40; k++) {
		move(k, 10.0 * (double)k, 0.0); /* 370 mm at 100 mm/s */
	}
	end(41);
	until(MLIP_STATE_PAUSED, 5000);
	dtick(200);
	assert_int_equal(status().state, MLIP_STATE_PAUSED);
	assert_int_equal(status().drive_power, MLIP_POWER_ENABLED);
	assert_int_equal(cw_of(0), 0x000F);
	period_cmd(MLIP_CMD_RESUME, 0, 0);
	dtick(300);
	assert_int_equal(status().state, MLIP_STATE_RUNNING);
	period_cmd(MLIP_CMD_HOLD, 0, 0);
	until(MLIP_STATE_HELD, 2000);
	dtick(200);
	assert_int_equal(status().drive_power, MLIP_POWER_ENABLED);
	assert_int_equal(cw_of(1), 0x000F);
	period_cmd(MLIP_CMD_RESUME, 0, 0);
	until(MLIP_STATE_IDLE, 20000);
	assert_int_equal(status().reason, MLIP_WHY_END);
	double end_x = out.pos[0];
	/* at rest: the last setpoint twice, then disable operation, shutdown */
	int k = until_power(MLIP_POWER_DISABLING, 10);
	assert_true(k >= 1 && k <= 3);
	assert_int_equal(cw_of(0), 0x0007);
	assert_int_equal(until_power(MLIP_POWER_SHUTTING_DOWN, 10), 1);
	assert_int_equal(cw_of(0), 0x0006);
	assert_int_equal(until_power(MLIP_POWER_OFF, 10), 1);
	assert_int_equal(status().drive_power_periods, 2);
	assert_true(out.pos[0] == end_x && end_x == 400.0);
}

/* Off, the commanded position follows the drives (moved by hand); the next
 * program finds Y beyond its soft limit: a fault naming node and counts, the
 * drives never switched on, nothing moves. */
static void test_drives_beyond_limit_when_enabling(void **st)
{
	(void)st;
	push(1, 2);
	end(3);
	until(MLIP_STATE_IDLE, 5000);
	until_power(MLIP_POWER_OFF, 20);
	drv_actual[0] = 2.5; /* X pushed back by hand */
	dtick(1);
	assert_true(status().pos[0] == 2.5 && out.pos[0] == 2.5);
	drv_actual[1] = 1000.25; /* Y beyond MAX_LIMIT 1000 */
	push(1, 5);
	end(6);
	dtick(1);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_int_equal(status().reason, MLIP_WHY_DRIVE);
	assert_int_equal(status().reason_node, 2);
	assert_int_equal(status().reason_field, MLIP_DRIVE_BEYOND_LIMIT);
	assert_true(status().reason_value == 1000250.0);
	assert_int_equal(cw_of(0), 0x0006);
	dtick(300);
	assert_int_equal(status().drive_power, MLIP_POWER_OFF);
	assert_int_equal(drv_sw[0], 0x0231);
	assert_true(out.pos[0] == 2.5);
}

/* A stop while the drives are being enabled (one never confirms): the
 * program is dropped, the drives go back off, no fault, nothing moves. */
static void test_drives_stop_while_enabling(void **st)
{
	(void)st;
	push(1, 2);
	end(3);
	until(MLIP_STATE_IDLE, 5000);
	until_power(MLIP_POWER_OFF, 20);
	drv_deaf = 2;
	push(1, 5);
	end(6);
	until_power(MLIP_POWER_ENABLING, 10);
	dtick(20);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	period_cmd(MLIP_CMD_STOP, 0, 0);
	until_power(MLIP_POWER_OFF, 20);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(mlip_ring_count(ring), 0);
	assert_true(out.pos[0] == 2.0);
	/* the deaf drive, at once: the next program's enable times out, a fault */
	push(1, 5);
	end(6);
	until_power(MLIP_POWER_ENABLING, 10);
	int k = until(MLIP_STATE_FAULT, 100);
	assert_true(k >= 49 && k <= 51); /* drive_state_periods 50 */
	assert_int_equal(status().reason_field, MLIP_DRIVE_NOT_ENABLED);
	assert_int_equal(status().reason_node, 2);
	assert_true(status().reason_value == 0x0233);
	until_power(MLIP_POWER_OFF, 20);
	assert_true(out.pos[0] == 2.0);
}

/* ---- the inputs on the bus: E-stop, limits, hold (issue 18) --------------- */

static struct mlip_io_config io_cfg;

#define BIT(f) (1u << (f))

static void io_config(void)
{
	memset(&io_cfg, 0, sizeof(io_cfg));
	io_cfg.node = 10;
	io_cfg.in_bytes = 1;
	uint32_t fs[5] = {MLIP_IN_ESTOP, MLIP_IN_HOLD, MLIP_IN_CYCLE_START, MLIP_IN_LIMIT_NEG(0),
	                  MLIP_IN_LIMIT_POS(0)};
	for (int i = 0; i < 5; i++) {
		struct mlip_io_bit *b = &io_cfg.in[fs[i]];
		b->node = 10;
		b->index = 0x6000;
		b->sub = 1;
		b->bit = (uint8_t)i;
		b->active_low = fs[i] == MLIP_IN_ESTOP;
		io_cfg.mapped |= BIT(fs[i]);
	}
}

static int drive_limits; /* setup_io: X's limits on drive 1's 0x60FD (bits 0, 1) */

static int setup_io(void **state)
{
	setup_drives(state);
	io_config();
	for (int i = 0; i < 2 && drive_limits; i++) {
		struct mlip_io_bit *b = &io_cfg.in[MLIP_IN_LIMIT_NEG(0) + (uint32_t)i];
		*b = (struct mlip_io_bit){
		    (uint8_t)mach.axis[0].can_node, 0, 0x60FD, (uint8_t)i, 0, 0};
	}
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT,
	                          .lookahead = 16,
	                          .can = &can_cia402,
	                          .drives = 1,
	                          .drive_state_periods = 50,
	                          .io = &io_cfg};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
	io_in.known = io_cfg.mapped; /* every input read, all off */
	return 0;
}

/* A long program along X, running at speed. */
static void run_long(void)
{
	for (uint64_t k = 1; k <= 40; k++) {
		move(k, 10.0 * (double)k, 0.0);
	}
	end(41);
	until(MLIP_STATE_RUNNING, 5000);
	dtick(300);
	assert_true(status().speed_mm_s > 50.0);
}

/* The E-stop input: in that very period quick stop (0x0002) to every drive,
 * state estop naming the input, every output off, the program dropped; the
 * commanded position follows the drives as they brake on their own ramp. */
static void test_estop_same_period(void **st)
{
	(void)st;
	assert_int_equal(mlip_ctl_set_output(&ctl, 1, 3, 1), MLIP_OK);
	assert_int_equal(mlip_ctl_set_output(&ctl, 9, 0, 1), MLIP_E_RANGE);
	run_long();
	assert_int_equal(out.outputs[0], 0x08);
	io_in.active = BIT(MLIP_IN_ESTOP);
	dtick(1);
	assert_int_equal(status().state, MLIP_STATE_ESTOP);
	assert_int_equal(status().reason, MLIP_WHY_ESTOP);
	assert_int_equal(status().reason_field, MLIP_IN_ESTOP);
	assert_int_equal(status().reason_node, 10);
	assert_int_equal(cw_of(0), 0x0002);
	assert_int_equal(cw_of(1), 0x0002);
	assert_int_equal(status().drive_power, MLIP_POWER_QUICK_STOP);
	assert_int_equal(out.outputs[0], 0);
	assert_int_equal(status().io_inputs, BIT(MLIP_IN_ESTOP));
	/* the drives brake by themselves: the setpoint is where they are */
	drv_actual[0] += 0.75;
	dtick(5);
	assert_true(out.pos[0] == drv_actual[0]);
	assert_int_equal(mlip_ring_count(ring), 0); /* the program dropped */
	assert_int_equal(mlip_ctl_set_output(&ctl, 1, 3, 1), MLIP_OK);
	dtick(1);
	assert_int_equal(out.outputs[0], 0); /* stays off until the reset */
	/* nothing but a reset: hold, resume refused, stop does nothing */
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_E_INVALID);
	stop_count++;
	dtick(3);
	assert_int_equal(status().state, MLIP_STATE_ESTOP);
	assert_int_equal(cw_of(1), 0x0002);
}

/* Reset: refused while the input is on; once released, idle, the drives
 * brought down from where the quick stop left them, and the next program
 * enables them from where they stand and runs to its end. */
static void test_estop_reset(void **st)
{
	(void)st;
	run_long();
	io_in.active = BIT(MLIP_IN_ESTOP);
	dtick(1);
	drv_actual[0] = 123.5; /* where its quick stop ramp ended */
	dtick(10);
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_E_RANGE);
	assert_int_equal(status().state, MLIP_STATE_ESTOP);
	io_in.known &= ~BIT(MLIP_IN_ESTOP); /* released but not read: still refused */
	io_in.active = 0;
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_E_RANGE);
	io_in.known = io_cfg.mapped;
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_OK);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(status().reason, MLIP_WHY_RESET);
	until_power(MLIP_POWER_OFF, 20);
	assert_true(out.pos[0] == 123.5);
	push(1, 2);
	move(3, 130.0, 0.0);
	end(4);
	until_power(MLIP_POWER_ENABLED, 20);
	until(MLIP_STATE_IDLE, 20000);
	assert_int_equal(status().reason, MLIP_WHY_END);
	assert_true(out.pos[0] == 130.0);
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_E_INVALID); /* nothing to reset */
}

/* Drives that answer late: drive k applies the controlword it was sent
 * lag[k] periods before (0: as dtick, seen in the next period's TPDO), by
 * CiA 402-2's transitions; on quick stop, option code qs_stay[k] ? 6 (stays
 * in "quick stop active") : 2 (then "switch on disabled"); bit k of
 * sod_stuck: never leaves "switch on disabled" (its safe torque off still
 * on). cws[] records every controlword drive 0 was sent, changes only. */
static uint16_t cw_hist[2][8];
static uint16_t cws[32];
static int n_cws;

static void cia402_apply(int k, uint16_t cw)
{
	uint16_t s = drv_sw[k];
	int sod = s == 0x0250, rtso = s == 0x0231, so = s == 0x0233, oe = s == 0x0237,
	    qsa = s == 0x0217;
	if ((cw & 0x02) == 0) { /* disable voltage */
		if (rtso || so || oe || qsa) {
			drv_sw[k] = 0x0250;
		}
	} else if ((cw & 0x07) == 0x02) { /* quick stop */
		if (oe) {
			drv_sw[k] = qs_stay[k] ? 0x0217 : 0x0250;
		} else if (rtso || so) {
			drv_sw[k] = 0x0250;
		}
	} else if ((cw & 0x0F) == 0x06) { /* shutdown */
		if ((sod && !(sod_stuck & (1 << k))) || so || oe) {
			drv_sw[k] = 0x0231;
		}
	} else if ((cw & 0x0F) == 0x07) { /* switch on, disable operation */
		if (rtso || oe) {
			drv_sw[k] = 0x0233;
		}
	} else if ((cw & 0x0F) == 0x0F) { /* enable operation */
		if (so) {
			drv_sw[k] = 0x0237;
		}
	}
	if (drv_sw[k] == 0x0237) {
		drv_actual[k] = out.pos[k];
	}
}

static void ltick(int n)
{
	for (int i = 0; i < n; i++) {
		uint64_t p = period;
		if (lt_start == UINT64_MAX) {
			lt_start = p; /* before it: dtick's drives, the history unknown */
		}
		tick(1);
		for (int k = 0; k < 2; k++) {
			uint16_t cw = cw_of(k);
			assert_int_equal(cw, cw_of(0)); /* all in step */
			cw_hist[k][p % 8] = cw;
			if (p >= lt_start + (uint64_t)lag[k]) {
				cia402_apply(k, cw_hist[k][(p - (uint64_t)lag[k]) % 8]);
			}
		}
		if ((n_cws == 0 || cws[n_cws - 1] != cw_of(0)) && n_cws < 32) {
			cws[n_cws++] = cw_of(0);
		}
	}
}

/* E-stop, quick stop: X's drive then "switch on disabled", Y's stays in
 * "quick stop active"; released, reset, and a program in the very next
 * period. The drives answer 1 and 3 periods late: every step is confirmed
 * by both statuswords before the next (0x0000 out of quick stop, 0x0006 to
 * "ready", 0x0007, 0x000F), the program waits for them and runs to its
 * end. */
static void test_estop_reset_program_next_period(void **st)
{
	(void)st;
	lag[0] = 1;
	lag[1] = 3;
	qs_stay[1] = 1;
	run_long();
	io_in.active = BIT(MLIP_IN_ESTOP);
	ltick(20);
	assert_int_equal(drv_sw[0], 0x0250);
	assert_int_equal(drv_sw[1], 0x0217);
	double x = drv_actual[0];
	io_in.active = 0;
	n_cws = 0;
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_OK);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	move(1, x + 5.0, 0.0);
	move(2, x + 5.0, 3.0);
	end(3);
	for (int i = 0;
	     i < 20000 && !(status().state == MLIP_STATE_IDLE && status().reason == MLIP_WHY_END);
	     i++) {
		ltick(1);
		assert_int_not_equal(status().state, MLIP_STATE_FAULT);
	}
	assert_int_equal(status().reason, MLIP_WHY_END);
	assert_true(out.pos[0] == x + 5.0 && out.pos[1] == 3.0);
	/* the controlwords since the reset, in order (then the rest after
	 * the program: disable operation, shutdown) */
	static const uint16_t want[] = {0x0000, 0x0006, 0x0007, 0x000F, 0x0007, 0x0006};
	ltick(20);
	assert_int_equal(n_cws, 6);
	for (int i = 0; i < 6; i++) {
		assert_int_equal(cws[i], want[i]);
	}
	assert_int_equal(status().drive_power, MLIP_POWER_OFF);
}

/* A drive that never leaves "switch on disabled" after the reset (its safe
 * torque off still on): the program waits, then a fault naming its node,
 * the step (shutdown) and its statusword; nothing moves. */
static void test_estop_reset_drive_stays_disabled(void **st)
{
	(void)st;
	run_long();
	io_in.active = BIT(MLIP_IN_ESTOP);
	ltick(20);
	double x = drv_actual[0];
	io_in.active = 0;
	sod_stuck = 2;
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_OK);
	move(1, x + 5.0, 0.0);
	end(2);
	int k;
	for (k = 1; k <= 500 && status().state != MLIP_STATE_FAULT; k++) {
		ltick(1);
		assert_true(status().drive_power != MLIP_POWER_SWITCHING_ON);
	}
	/* shutdown late toward OFF (noted, 50 periods), then toward power:
	 * failed after 50 more */
	assert_true(k >= 99 && k <= 104);
	assert_int_equal(status().reason, MLIP_WHY_DRIVE);
	assert_int_equal(status().reason_node, 2);
	assert_int_equal(status().reason_field, MLIP_DRIVE_POWER_STEP);
	assert_true(status().reason_value == MLIP_POWER_SHUTTING_DOWN * 65536.0 + 0x0250);
	char text[160];
	mlip_cli_drive_fault_text(status().reason_field, (int64_t)status().reason_value, text,
	                          sizeof(text));
	assert_non_null(strstr(text, "shutdown (controlword 0x0006) not confirmed"));
	assert_non_null(strstr(text, "0x0250 (switch on disabled)"));
	ltick(200);
	assert_true(out.pos[0] == x);
	assert_int_equal(drv_sw[1], 0x0250);
}

/* E-stop wins over every state: a hold, a pause, a drive fault (which comes
 * back after the reset: a restart clears it). */
static void test_estop_wins(void **st)
{
	(void)st;
	run_long();
	period_cmd(MLIP_CMD_HOLD, 0, 0);
	until(MLIP_STATE_HELD, 2000);
	drv_fault = (struct mlip_ctl_drive_fault){MLIP_DRIVE_FOLLOWING_ERROR, 2, 4000.0};
	dtick(1);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	io_in.active = BIT(MLIP_IN_ESTOP);
	dtick(1);
	assert_int_equal(status().state, MLIP_STATE_ESTOP);
	assert_int_equal(cw_of(0), 0x0002);
	io_in.active = 0;
	dtick(3); /* at rest: 3 TPDOs of every drive at the same place */
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_OK);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_int_equal(status().reason, MLIP_WHY_DRIVE);
	assert_int_equal(status().reason_node, 2);
}

/* The I/O module lost (heartbeat): an E-stop, and no reset while it is. */
static void test_io_lost(void **st)
{
	(void)st;
	run_long();
	io_in.lost = (struct mlip_ctl_drive_fault){MLIP_DRIVE_HEARTBEAT_LOST, 10, 350.0};
	dtick(1);
	assert_int_equal(status().state, MLIP_STATE_ESTOP);
	assert_int_equal(status().reason, MLIP_WHY_IO_LOST);
	assert_int_equal(status().reason_node, 10);
	assert_int_equal(status().reason_field, MLIP_DRIVE_HEARTBEAT_LOST);
	assert_int_equal(cw_of(0), 0x0002);
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_E_RANGE);
}

/* A limit input while moving: quick stop, fault naming axis and direction;
 * at rest the same input stops nothing; reset once it is released. */
static void test_limit(void **st)
{
	(void)st;
	io_in.active = BIT(MLIP_IN_LIMIT_POS(0));
	dtick(20);
	assert_int_equal(status().state, MLIP_STATE_IDLE); /* not moving: nothing to stop */
	io_in.active = 0;
	run_long();
	io_in.active = BIT(MLIP_IN_LIMIT_POS(0));
	dtick(1);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_int_equal(status().reason, MLIP_WHY_LIMIT);
	assert_int_equal(status().reason_field, MLIP_IN_LIMIT_POS(0));
	assert_int_equal(cw_of(0), 0x0002);
	assert_int_equal(cw_of(1), 0x0002);
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_E_RANGE);
	io_in.active = 0;
	/* released, but X still brakes on its drive's ramp: leaving the quick
	 * stop would disable it at speed (CiA 402 transition 12) */
	for (int i = 0; i < 4; i++) {
		drv_actual[0] += 0.05;
		assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_E_FULL);
		assert_int_equal(cw_of(0), 0x0002);
	}
	/* at rest: refused until 3 fresh TPDOs of every drive show it */
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_E_FULL);
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_E_FULL);
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_OK);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
}

/* The same with X's switches wired to its drive (0x60FD): the controller
 * decides alike, the reason names the drive's node. */
static int setup_io_drive(void **state)
{
	drive_limits = 1;
	int r = setup_io(state);
	drive_limits = 0;
	return r;
}

static void test_limit_drive_input(void **st)
{
	(void)st;
	run_long();
	double x0 = out.pos[0];
	io_in.active = BIT(MLIP_IN_LIMIT_POS(0));
	dtick(1);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_int_equal(status().reason, MLIP_WHY_LIMIT);
	assert_int_equal(status().reason_field, MLIP_IN_LIMIT_POS(0));
	assert_int_equal(status().reason_node, mach.axis[0].can_node);
	assert_true(status().reason_value >= x0);
	assert_int_equal(cw_of(0), 0x0002);
	assert_int_equal(cw_of(1), 0x0002);
	/* only a jog of X away from it (negative) leaves the stop: an
	 * incremental one, renewed as mlip-ctl does, runs its distance once the
	 * drives are enabled again. Posted while the drives still brake on
	 * their quick stop ramp ("quick stop active", X still moving): refused,
	 * as leaving the quick stop disables them (transition 12) */
	for (int k = 0; k < 2; k++) {
		drv_sw[k] = 0x0217;
	}
	for (int i = 0; i < 3; i++) {
		tick(1);
		drv_actual[0] += 0.05;
	}
	assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 0, 600), 0), MLIP_E_RANGE);
	drv_actual[0] += 0.05;
	assert_int_equal(period_cmd(MLIP_CMD_JOG_AXIS, MLIP_JOG_AXIS_ARG(0, 1, 5000), 0), MLIP_OK);
	drv_actual[0] += 0.05;
	assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 1, 1200), 0), MLIP_E_FULL);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_int_equal(cw_of(0), 0x0002);
	tick(3); /* at rest */
	assert_int_equal(period_cmd(MLIP_CMD_JOG_AXIS, MLIP_JOG_AXIS_ARG(0, 1, 5000), 0), MLIP_OK);
	assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 1, 1200), 0), MLIP_OK);
	assert_int_equal(status().state, MLIP_STATE_JOGGING);
	for (int i = 0; i < 5; i++) {
		tick(1);
		for (int k = 0; k < 2; k++) {
			if (cw_of(k) == 0x0000) {
				drv_sw[k] = 0x0250; /* disable voltage */
			}
		}
	}
	for (int k = 0; k < 2; k++) {
		drv_sw[k] = 0x0250; /* at rest: switch on disabled */
	}
	tick(1);
	double x1 = drv_actual[0];
	for (int i = 0; i < 2000 && status().state == MLIP_STATE_JOGGING; i++) {
		dtick(1);
		if (i % 100 == 99 && status().state == MLIP_STATE_JOGGING) {
			assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 1, 1200), 0),
			                 MLIP_OK);
		}
	}
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(status().reason, MLIP_WHY_JOG_DONE);
	assert_true(fabs(out.pos[0] - (x1 - 5.0)) < 1e-9);
}

/* Stopped on a limit switch that stays on: a jog toward it (or another
 * axis) is refused, a jog away from it leaves the stop; the switch does not
 * trip again until released, then it does. */
static void test_limit_jog_away(void **st)
{
	(void)st;
	run_long();
	io_in.active = BIT(MLIP_IN_LIMIT_POS(0));
	dtick(1);
	assert_int_equal(status().reason, MLIP_WHY_LIMIT);
	dtick(5);
	double x = out.pos[0];
	assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 0, 600), 0), MLIP_E_RANGE);
	assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(1, 1, 600), 0), MLIP_E_RANGE);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 1, 600), 0), MLIP_OK);
	assert_int_equal(status().state, MLIP_STATE_JOGGING);
	for (int i = 0; i < 5; i++) {
		dtick(50);
		assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 1, 600), 0), MLIP_OK);
	}
	assert_int_equal(status().state, MLIP_STATE_JOGGING); /* the switch, still on, ignored */
	assert_true(out.pos[0] < x);
	io_in.active = 0; /* off the switch */
	dtick(1);
	assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 1, 0), 0), MLIP_OK);
	for (int i = 0; i < 500 && status().state != MLIP_STATE_IDLE; i++) {
		dtick(1);
	}
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	/* re-armed: it trips the next move again */
	assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 0, 600), 0), MLIP_OK);
	until_power(MLIP_POWER_ENABLED, 50);
	dtick(20);
	io_in.active = BIT(MLIP_IN_LIMIT_POS(0));
	dtick(1);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_int_equal(status().reason, MLIP_WHY_LIMIT);
}

/* Hold and cycle start act on their rising edge, as the commands. */
static void test_hold_cycle_start_inputs(void **st)
{
	(void)st;
	run_long();
	io_in.active = BIT(MLIP_IN_HOLD);
	until(MLIP_STATE_HELD, 2000);
	dtick(50);
	io_in.active = 0;
	dtick(50);
	assert_int_equal(status().state, MLIP_STATE_HELD); /* releasing it is no resume */
	io_in.active = BIT(MLIP_IN_CYCLE_START);
	until(MLIP_STATE_RUNNING, 10);
	io_in.active = 0;
	until(MLIP_STATE_IDLE, 20000);
	assert_int_equal(status().reason, MLIP_WHY_END);
}

/* The inputs on the bus, no drives: nothing to quick stop. */
static void io_without_drives(void)
{
	io_config();
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT, .lookahead = 16, .io = &io_cfg};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
	io_in.known = io_cfg.mapped;
}

/* An E-stop ends a hold latched at rest (a reset in Grbl 1.1's words):
 * after the reset the next program runs unheld. Without drives the planner
 * had nothing queued to stop, so only the E-stop's clearing ends it. */
static void test_estop_clears_latched_hold(void **st)
{
	(void)st;
	io_without_drives();
	tick(5);
	assert_int_equal(period_cmd(MLIP_CMD_HOLD, 0, 0), MLIP_OK);
	tick(5);
	assert_int_equal(status().held_by, MLIP_WHY_HOLD);
	io_in.active = BIT(MLIP_IN_ESTOP);
	tick(2);
	assert_int_equal(status().state, MLIP_STATE_ESTOP);
	assert_int_equal(status().held_by, 0);
	io_in.active = 0;
	tick(2);
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_OK);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(status().held_by, 0);
	line_unheld(5.0);
}

/* Without drives (nothing to quick stop) the planner stops on the path at
 * the acceleration limit: never faster. */
static void test_estop_without_drives(void **st)
{
	(void)st;
	io_without_drives();
	for (uint64_t k = 1; k <= 40; k++) {
		move(k, 10.0 * (double)k, 0.0);
	}
	end(41);
	until(MLIP_STATE_RUNNING, 5000);
	tick(300);
	double x0 = out.pos[0], v0 = status().speed_mm_s;
	io_in.active = BIT(MLIP_IN_ESTOP);
	tick(1);
	assert_int_equal(status().state, MLIP_STATE_ESTOP);
	double prev = out.pos[0], v = (out.pos[0] - x0) / mach.period_s;
	int n = 0;
	while (status().speed_mm_s > 0.0 && n < 10000) {
		tick(1);
		double v1 = (out.pos[0] - prev) / mach.period_s;
		assert_true(fabs(v1 - v) / mach.period_s <= 1000.0 * (1.0 + 1e-9) + 1e-6);
		v = v1;
		prev = out.pos[0];
		n++;
	}
	/* braking distance v^2 / 2A, within 2 % */
	double d = out.pos[0] - x0, want = v0 * v0 / (2.0 * 1000.0);
	assert_true(d >= 0.98 * want && d <= 1.02 * want + 0.1);
}

/* ---- continuous jog (issue 18) -------------------------------------------- */

static int32_t jog(uint32_t axis, int neg, uint32_t mm_min)
{
	return period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(axis, neg, mm_min), 0);
}

/* n periods renewing the jog every `every` periods (0: never); the largest
 * |a| of axis k's setpoints; *v_last: its speed, carried between calls. */
static double jog_ticks(int n, int every, uint32_t axis, int neg, uint32_t mm_min, int k,
                        double *v_last)
{
	double amax = 0.0, prev = out.pos[k], v = *v_last;
	for (int i = 0; i < n; i++) {
		if (every > 0 && i % every == every - 1 && status().state == MLIP_STATE_JOGGING) {
			assert_int_equal(jog(axis, neg, mm_min), MLIP_OK);
		} else {
			tick(1);
		}
		double v1 = (out.pos[k] - prev) / mach.period_s;
		double a = fabs(v1 - v) / mach.period_s;
		amax = a > amax ? a : amax;
		v = v1;
		prev = out.pos[k];
	}
	*v_last = v;
	return amax;
}

/* Released: a stop on the path at the acceleration limit, v^2 / 2A long. */
static void test_jog_release(void **st)
{
	(void)st;
	double v = 0.0;
	assert_int_equal(jog(0, 0, 6000), MLIP_OK); /* X+ at 100 mm/s */
	assert_int_equal(status().state, MLIP_STATE_JOGGING);
	assert_int_equal(status().reason, MLIP_WHY_JOG);
	v = out.pos[0] / mach.period_s; /* its first period: from 0 */
	double amax = jog_ticks(1000, 100, 0, 0, 6000, 0, &v);
	assert_true(fabs(v - 100.0) < 1e-6);
	assert_true(amax <= 1000.0 * (1.0 + 1e-9));
	double x0 = out.pos[0];
	assert_int_equal(jog(0, 0, 0), MLIP_OK); /* released */
	double v_rel = (out.pos[0] - x0) / mach.period_s;
	assert_true(fabs(v_rel - v) / mach.period_s <= 1000.0 * (1.0 + 1e-9));
	v = v_rel;
	amax = jog_ticks(200, 0, 0, 0, 0, 0, &v);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(status().reason, MLIP_WHY_JOG_RELEASED);
	assert_true(amax <= 1000.0 * (1.0 + 1e-9));
	double d = out.pos[0] - x0, want = 100.0 * 100.0 / (2.0 * 1000.0); /* 5 mm */
	/* the planner brakes a margin below A: a little longer, never shorter */
	print_message("jog released at 100 mm/s: %.4f mm to rest, v^2/2A = %.4f mm\n", d, want);
	assert_true(d >= want * 0.999 && d <= want * 1.03);
	assert_true(status().stop_nm > 0);
	assert_true(out.pos[1] == 0.0);
}

/* Not renewed: the stop begins MLIP_JOG_DEADMAN_S after the last renewal
 * (250 periods of 1 ms), at the acceleration limit. */
static void test_jog_deadman(void **st)
{
	(void)st;
	double v = 0.0;
	assert_int_equal(jog(1, 1, 3000), MLIP_OK); /* Y- at 50 mm/s */
	jog_ticks(500, 50, 1, 1, 3000, 1, &v);
	assert_true(fabs(v + 50.0) < 1e-6);
	/* the last renewal was the last period: silence from now on */
	jog_ticks(250, 0, 1, 1, 0, 1, &v);
	assert_true(fabs(v + 50.0) < 1e-6); /* still at speed for 250 periods */
	assert_int_equal(status().state, MLIP_STATE_JOGGING);
	double y0 = out.pos[1];
	double amax = jog_ticks(2, 0, 1, 1, 0, 1, &v);
	assert_true(v > -50.0 + 1e-9); /* braking */
	amax = fmax(amax, jog_ticks(200, 0, 1, 1, 0, 1, &v));
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(status().reason, MLIP_WHY_JOG_DEADMAN);
	assert_true(amax <= 1000.0 * (1.0 + 1e-9));
	double d = y0 - out.pos[1], want = 50.0 * 50.0 / 2000.0;
	print_message("jog not renewed at 50 mm/s: %.4f mm to rest, v^2/2A = %.4f mm\n", d, want);
	assert_true(d >= want * 0.99 && d <= want * 1.05);
}

/* Toward a soft limit: it stops exactly at the limit; a jog further that way
 * is refused (Grbl's error 15: the target lies beyond the travel). */
static void test_jog_soft_limit(void **st)
{
	(void)st;
	mach.axis[0].max_limit = 20.0;
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT, .lookahead = 16};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
	double v = 0.0;
	assert_int_equal(jog(0, 0, 6000), MLIP_OK);
	jog_ticks(1000, 100, 0, 0, 6000, 0, &v);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(status().reason, MLIP_WHY_JOG_END);
	assert_true(out.pos[0] == 20.0);
	assert_int_equal(jog(0, 0, 6000), MLIP_E_RANGE);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(jog(0, 1, 600), MLIP_OK); /* away from it: fine */
	assert_int_equal(jog(0, 1, 0), MLIP_OK);
	until(MLIP_STATE_IDLE, 1000);
	assert_true(out.pos[0] < 20.0);
}

static int32_t jog_axis(uint32_t axis, int neg, uint32_t um)
{
	return period_cmd(MLIP_CMD_JOG_AXIS, MLIP_JOG_AXIS_ARG(axis, neg, um), 0);
}

/* X's MAX_LIMIT 20 mm, the controller started again on it. */
static void x_max_limit_20(void)
{
	mach.axis[0].max_limit = 20.0;
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT, .lookahead = 16};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
}

/* The speeds of the period a jog started in, from p0 (where it stood). */
static void jog_v0(const double *p0, double *v)
{
	for (int k = 0; k < 2; k++) {
		v[k] = (out.pos[k] - p0[k]) / mach.period_s;
	}
}

/* The largest |a| of each axis over n periods, renewing the jog (axis 0,
 * neg, mm_min) every 100; v carries the speeds between calls. */
static double jog2_ticks(int n, int neg, uint32_t mm_min, double *v)
{
	double amax = 0.0, prev[2] = {out.pos[0], out.pos[1]};
	for (int i = 0; i < n; i++) {
		if (i % 100 == 99 && status().state == MLIP_STATE_JOGGING) {
			assert_int_equal(jog(0, neg, mm_min), MLIP_OK);
		} else {
			tick(1);
		}
		for (int k = 0; k < 2; k++) {
			double v1 = (out.pos[k] - prev[k]) / mach.period_s;
			amax = fmax(amax, fabs(v1 - v[k]) / mach.period_s);
			v[k] = v1;
			prev[k] = out.pos[k];
		}
	}
	return amax;
}

/* Incremental: a distance per axis, at rest exactly there (reason "jog
 * done"), within the acceleration limit; a target beyond a soft limit is
 * refused whole (Grbl's error 15) and nothing moves. */
static void test_jog_incremental(void **st)
{
	(void)st;
	x_max_limit_20();
	double v[2] = {0.0, 0.0};
	double p0[2] = {0.0, 0.0};
	assert_int_equal(jog_axis(0, 0, 1500), MLIP_OK); /* X+ 1.5 mm */
	assert_int_equal(jog(0, 0, 600), MLIP_OK);       /* at 10 mm/s */
	assert_int_equal(status().state, MLIP_STATE_JOGGING);
	jog_v0(p0, v);
	double amax = jog2_ticks(600, 0, 600, v);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(status().reason, MLIP_WHY_JOG_DONE);
	assert_true(out.pos[0] == 1.5 && out.pos[1] == 0.0);
	assert_true(amax <= 1000.0 * (1.0 + 1e-9));
	/* X- 0.25 and Y+ 2 at once: one line, both exactly there */
	assert_int_equal(jog_axis(1, 0, 2000), MLIP_OK);
	assert_int_equal(jog_axis(0, 1, 250), MLIP_OK);
	p0[0] = out.pos[0];
	p0[1] = out.pos[1];
	assert_int_equal(jog(0, 1, 1200), MLIP_OK);
	jog_v0(p0, v);
	amax = jog2_ticks(1000, 1, 1200, v);
	assert_int_equal(status().reason, MLIP_WHY_JOG_DONE);
	assert_true(out.pos[0] == 1.25 && out.pos[1] == 2.0);
	assert_true(amax <= 1000.0 * (1.0 + 1e-9));
	/* 1.25 + 18.75 = 20: to the limit exactly is fine; 1 um more is not */
	assert_int_equal(jog_axis(0, 0, 18751), MLIP_OK);
	assert_int_equal(jog(0, 0, 6000), MLIP_E_RANGE);
	tick(10);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_true(out.pos[0] == 1.25);
	assert_int_equal(jog_axis(0, 0, 18750), MLIP_OK);
	assert_int_equal(jog(0, 0, 6000), MLIP_OK);
	jog2_ticks(1000, 0, 6000, v);
	assert_int_equal(status().reason, MLIP_WHY_JOG_DONE);
	assert_true(out.pos[0] == 20.0);
	/* continuous and incremental at once, a direction that disagrees:
	 * malformed; JOG_AXIS during a jog: not now */
	assert_int_equal(jog_axis(1, 0, 1000), MLIP_OK);
	assert_int_equal(jog(0, 1, 600), MLIP_E_SYNTAX);
	assert_int_equal(jog_axis(0, 0, 1000), MLIP_OK);
	assert_int_equal(jog(0, 1, 600), MLIP_E_SYNTAX);
	assert_int_equal(jog(0, 1, 600), MLIP_OK); /* nothing pending: X- alone */
	assert_int_equal(jog_axis(1, 0, 0), MLIP_E_INVALID);
	assert_int_equal(jog(0, 1, 0), MLIP_OK);
	until(MLIP_STATE_IDLE, 1000);
}

/* Several axes continuously: one line at the jog's speed (the path speed),
 * until the first axis reaches its soft limit (exactly) or the release;
 * a JOG_AXIS older than the dead-man is not taken. */
static void test_jog_multi_axis(void **st)
{
	(void)st;
	x_max_limit_20();
	double v[2] = {0.0, 0.0};
	double p0[2] = {0.0, 0.0};
	assert_int_equal(jog_axis(1, 1, 0), MLIP_OK); /* Y- ... */
	assert_int_equal(jog(0, 0, 6000), MLIP_OK);   /* ... with X+ at 100 mm/s */
	jog_v0(p0, v);
	double amax = jog2_ticks(150, 0, 6000, v);
	double path = hypot(v[0], v[1]);
	print_message("jog X+ Y- at 100 mm/s: %.6f mm/s along the line (%.6f, %.6f)\n", path, v[0],
	              v[1]);
	assert_true(fabs(path - 100.0) < 1e-6 && fabs(v[0] + v[1]) < 1e-9);
	amax = fmax(amax, jog2_ticks(1000, 0, 6000, v));
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(status().reason, MLIP_WHY_JOG_END);
	assert_true(out.pos[0] == 20.0 && out.pos[1] == -20.0); /* X's limit first */
	assert_true(amax <= 1000.0 * (1.0 + 1e-9));
	assert_int_equal(jog_axis(1, 1, 0), MLIP_OK);
	assert_int_equal(jog(0, 0, 600), MLIP_E_RANGE); /* X at its limit that way */
	/* a stale JOG_AXIS (another client's, older than 250 ms): X alone */
	assert_int_equal(jog_axis(1, 0, 0), MLIP_OK);
	tick(300);
	assert_int_equal(jog(0, 1, 600), MLIP_OK);
	jog2_ticks(300, 1, 600, v);
	assert_true(out.pos[1] == -20.0 && out.pos[0] < 20.0);
	assert_int_equal(jog(0, 1, 0), MLIP_OK);
	until(MLIP_STATE_IDLE, 1000);
}

/* X+ Y- released at 100 mm/s along the line: braking on the line at the
 * per-axis limit, A sqrt(2) along it: v^2 / (2 A sqrt(2)) to rest. */
static void test_jog_multi_release(void **st)
{
	(void)st;
	double v[2] = {0.0, 0.0}, p0[2] = {0.0, 0.0};
	assert_int_equal(jog_axis(1, 1, 0), MLIP_OK);
	assert_int_equal(jog(0, 0, 6000), MLIP_OK);
	jog_v0(p0, v);
	jog2_ticks(400, 0, 6000, v);
	assert_true(fabs(hypot(v[0], v[1]) - 100.0) < 1e-6);
	double x0 = out.pos[0], y0 = out.pos[1];
	assert_int_equal(jog(0, 0, 0), MLIP_OK); /* released */
	double v_rel[2];
	p0[0] = x0;
	p0[1] = y0;
	jog_v0(p0, v_rel); /* the release period's speeds: braking from it on */
	double amax = fmax(fabs(v_rel[0] - v[0]), fabs(v_rel[1] - v[1])) / mach.period_s;
	v[0] = v_rel[0];
	v[1] = v_rel[1];
	amax = fmax(amax, jog2_ticks(300, 0, 0, v));
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(status().reason, MLIP_WHY_JOG_RELEASED);
	assert_true(amax <= 1000.0 * (1.0 + 1e-9));
	double d = hypot(out.pos[0] - x0, out.pos[1] - y0);
	double want = 100.0 * 100.0 / (2.0 * 1000.0 * sqrt(2.0));
	print_message(
	    "jog X+ Y- released at 100 mm/s: %.4f mm to rest, v^2/(2 A sqrt 2) = %.4f mm\n", d,
	    want);
	assert_true(d >= want * 0.999 && d <= want * 1.03);
	assert_true(out.pos[0] == -out.pos[1]); /* on the line */
}

/* Refused: an axis not in the machine, a jog during a program, a second
 * axis during a jog; a hold ends a jog. */
static void test_jog_refused(void **st)
{
	(void)st;
	assert_int_equal(jog(2, 0, 600), MLIP_E_RANGE); /* a 2-axis machine */
	assert_int_equal(jog(7, 0, 600), MLIP_E_RANGE);
	push(1, 5);
	end(6);
	until(MLIP_STATE_RUNNING, 100);
	assert_int_equal(jog(0, 0, 600), MLIP_E_INVALID);
	until(MLIP_STATE_IDLE, 20000);
	assert_int_equal(jog(0, 0, 600), MLIP_OK);
	assert_int_equal(jog(1, 0, 600), MLIP_E_INVALID);
	assert_int_equal(jog(0, 1, 600), MLIP_E_INVALID);
	assert_int_equal(jog(0, 0, 600), MLIP_OK); /* the renewal */
	period_cmd(MLIP_CMD_HOLD, 0, 0);           /* a hold cancels a jog */
	until(MLIP_STATE_IDLE, 1000);
	assert_int_equal(status().reason, MLIP_WHY_JOG_RELEASED);
}

/* With drives switched off after a program: the jog enables them first, from
 * where they stand, then moves; at rest after it they go off again. */
static void test_jog_drives(void **st)
{
	(void)st;
	push(1, 2);
	end(3);
	until(MLIP_STATE_IDLE, 5000);
	until_power(MLIP_POWER_OFF, 20);
	assert_int_equal(jog(0, 0, 600), MLIP_OK);
	assert_int_equal(status().state, MLIP_STATE_JOGGING);
	until_power(MLIP_POWER_ENABLED, 20);
	for (int i = 0; i < 10; i++) {
		assert_int_equal(jog(0, 0, 600), MLIP_OK);
		dtick(99);
	}
	assert_true(out.pos[0] > 2.0 + 9.0 && out.pos[0] < 2.0 + 10.1);
	assert_int_equal(jog(0, 0, 0), MLIP_OK);
	for (int i = 0; i < 200 && status().state != MLIP_STATE_IDLE; i++) {
		dtick(1);
	}
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	until_power(MLIP_POWER_OFF, 20);
}

/* ---- homing with the drives' homing mode (issue 18) ------------------------ */

static struct mlip_home_config home_cfg;
#define sdo_res sdo_res_in
static uint32_t sdo_refuse; /* an index the drives refuse to write (0: none) */
static int drv_mode[2] = {8, 8};
static int drv_homing[2];
static uint16_t drv_cw_prev[2];
/* 1: bit 4's rise is applied a period late (as a drive whose TPDO at the
 * SYNC that applies the RPDO was sampled before it) */
static int drv_start_late;
static int drv_start_pending[2];
static uint32_t drv_obj[2][8]; /* 0x6098, 0x6099:1, 0x6099:2, 0x609A, 0x607C */
static int sdo_log_n;
static uint16_t sdo_log[64];

static int obj_slot(uint16_t index, uint8_t sub)
{
	return index == 0x6098   ? 0
	       : index == 0x6099 ? sub
	       : index == 0x609A ? 3
	       : index == 0x607C ? 4
	                         : -1;
}

/* The drives' side after a period: the SDO request answered (seen by the
 * controller in the next period), the homing mode run. */
static void drive_model(void)
{
	const struct mlip_ctl_sdo_req *r = &out.sdo;
	if (r->seq != 0 && r->seq != sdo_res.seq) {
		int k = r->node - 1, slot = obj_slot(r->index, r->sub);
		sdo_res.seq = r->seq;
		sdo_res.abort = 0;
		if (sdo_log_n < 64 && !r->upload) {
			sdo_log[sdo_log_n++] = r->index;
		}
		if (r->upload) {
			sdo_res.value = r->index == 0x6061 ? (uint32_t)drv_mode[k]
			                : slot >= 0        ? drv_obj[k][slot]
			                                   : 0;
		} else if (r->index == sdo_refuse) {
			sdo_res.abort = 0x06090030;
		} else if (r->index == 0x6060) {
			drv_mode[k] = (int)r->value;
		} else if (slot >= 0) {
			drv_obj[k][slot] = r->value;
		}
	}
	for (int k = 0; k < 2; k++) {
		uint16_t cw = cw_of(k);
		int8_t method = (int8_t)drv_obj[k][0];
		int rise = drv_mode[k] == 6 && drv_sw[k] & 0x0004 && (cw & 0x10) &&
		           !(drv_cw_prev[k] & 0x10);
		if (rise && drv_start_late) {
			drv_start_pending[k] = 1; /* the statusword of now is still the old */
		} else if (rise || drv_start_pending[k]) {
			drv_start_pending[k] = 0;
			drv_homing[k] = 1; /* bit 4's rising edge */
			drv_sw[k] &= (uint16_t)~0x3400u;
		}
		drv_cw_prev[k] = cw;
		if (!drv_homing[k]) {
			continue;
		}
		double offset = (int32_t)drv_obj[k][4] / 1000.0;
		if (method == 35 || method == 37) {
			drv_actual[k] = offset; /* the current position is home */
		} else if (method == 17) {
			/* toward the negative limit switch at 0 at the search speed */
			drv_actual[k] -= drv_obj[k][1] / 1000.0 * mach.period_s;
			if (drv_actual[k] > 0.0) {
				continue;
			}
			drv_actual[k] = offset;
		} else if (method == 1) {
			drv_sw[k] |= 0x2000; /* homing error */
			drv_homing[k] = 0;
			continue;
		} else {
			continue; /* never done: a timeout */
		}
		drv_sw[k] |= 0x1400;
		drv_homing[k] = 0;
	}
}

static void htick(int n)
{
	for (int i = 0; i < n; i++) {
		dtick(1);
		drive_model();
	}
}

static int32_t hcmd(uint32_t op, int32_t arg)
{
	int32_t r = period_cmd(op, arg, 0);
	drive_model();
	return r;
}

/* The controller started again on home_cfg, with two CiA 402 drives. */
static void home_init(void)
{
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT,
	                          .lookahead = 16,
	                          .can = &can_cia402,
	                          .drives = 1,
	                          .drive_state_periods = 50,
	                          .home = &home_cfg};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
}

static int setup_home(void **state)
{
	setup_drives(state);
	memset(&home_cfg, 0, sizeof(home_cfg));
	for (int k = 0; k < 2; k++) {
		struct mlip_axis_home *h = &home_cfg.axis[k];
		h->configured = 1;
		h->method = k == 0 ? 35 : 17;
		h->search_vel = 10.0;
		h->latch_vel = 1.0;
		h->accel = 100.0;
		h->offset = k == 0 ? -2.5 : 1.25;
		h->sequence = k == 0 ? 1 : 0; /* Y first */
		h->timeout_s = 2.0;
	}
	home_cfg.required = 1;
	home_init();
	memset(&sdo_res, 0, sizeof(sdo_res));
	memset(drv_obj, 0, sizeof(drv_obj));
	drv_mode[0] = drv_mode[1] = 8;
	drv_homing[0] = drv_homing[1] = 0;
	drv_cw_prev[0] = drv_cw_prev[1] = 0x0F;
	drv_start_late = 0;
	drv_start_pending[0] = drv_start_pending[1] = 0;
	sdo_refuse = 0;
	sdo_log_n = 0;
	drv_actual[0] = 3.7; /* powered up anywhere */
	drv_actual[1] = 5.0;
	return 0;
}

/* In HOME_SEQUENCE order (Y, then X), every object written and read back,
 * mode 6, bit 4, bits 10 and 12, back to mode 8: the positions are the home
 * offsets to the count and the setpoint never steps away from the drive. */
static void test_home_sequence(void **st)
{
	(void)st;
	htick(5);
	push(1, 2);
	end(3);
	htick(5);
	assert_int_equal(status().state, MLIP_STATE_IDLE); /* HOMING_REQUIRED */
	assert_int_equal(status().reason, MLIP_WHY_NOT_HOMED);
	assert_true(status().pos[0] == 0.0); /* nothing moved */
	assert_int_equal(hcmd(MLIP_CMD_HOME, 0), MLIP_OK);
	assert_int_equal(status().state, MLIP_STATE_HOMING);
	int n = 0, prev_mode[2] = {8, 8}, back = 0;
	while (status().state == MLIP_STATE_HOMING && n++ < 5000) {
		htick(1);
		for (int k = 0; k < 2; k++) {
			if (drv_mode[k] == 8 && prev_mode[k] == 6) {
				/* back in CSP: the target is the position actual, to the count */
				assert_true(out.pos[k] == drv_actual[k]);
				back++;
			}
			prev_mode[k] = drv_mode[k];
		}
	}
	assert_int_equal(back, 2);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(status().reason, MLIP_WHY_HOMED);
	assert_int_equal(status().homed, 3u);
	assert_true(out.pos[0] == -2.5 && out.pos[1] == 1.25); /* the offsets, exactly */
	assert_true(drv_mode[0] == 8 && drv_mode[1] == 8);
	/* Y's objects first, then X's: 0x6098 0x6099 0x6099 0x609A 0x607C 0x6060 */
	static const uint16_t want[6] = {0x6098, 0x6099, 0x6099, 0x609A, 0x607C, 0x6060};
	assert_int_equal(sdo_log_n, 14);
	for (int i = 0; i < 6; i++) {
		assert_int_equal(sdo_log[i], want[i]);     /* Y's set-up */
		assert_int_equal(sdo_log[7 + i], want[i]); /* X's, after Y's return to CSP */
	}
	assert_int_equal(sdo_log[6], 0x6060);
	assert_int_equal(drv_obj[1][1], 10000); /* 10 mm/s in counts/s */
	assert_int_equal((int32_t)drv_obj[0][4], -2500);
	/* a program now runs, from the home position */
	push(1, 2);
	end(3);
	for (int i = 0; i < 20000 && status().reason != MLIP_WHY_END; i++) {
		htick(1);
	}
	assert_int_equal(status().reason, MLIP_WHY_END);
	assert_true(out.pos[0] == 2.0);
}

/* A home is refused while a hold is latched at rest (as a jog is; Grbl
 * refuses $H in Hold): the drives' homing motion would leave the path of
 * the program the hold is kept for. It was accepted. And while a program
 * is held on its path. A resume at rest releases the latch: then it homes. */
static void test_home_refused_in_a_hold(void **st)
{
	(void)st;
	htick(5);
	assert_int_equal(hcmd(MLIP_CMD_HOLD, 0), MLIP_OK);
	htick(5);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_true(mlip_state_hold_latched(status().state, status().held_by));
	double x = out.pos[0], y = out.pos[1];
	assert_int_equal(hcmd(MLIP_CMD_HOME, 0), MLIP_E_INVALID);
	htick(50);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(status().held_by, MLIP_WHY_HOLD);
	assert_true(out.pos[0] == x && out.pos[1] == y);
	assert_int_equal(sdo_log_n, 0); /* no homing object written */
	assert_int_equal(hcmd(MLIP_CMD_RESUME, 0), MLIP_OK);
	htick(5);
	assert_int_equal(status().held_by, 0);
	assert_int_equal(hcmd(MLIP_CMD_HOME, 0), MLIP_OK);
	for (int n = 0; status().state == MLIP_STATE_HOMING && n < 5000; n++) {
		htick(1);
	}
	assert_int_equal(status().reason, MLIP_WHY_HOMED);
	assert_int_equal(status().homed, 3u);
	/* a program held on its path: refused too, the homing kept */
	int logged = sdo_log_n;
	move(1, 50.0, 1.25);
	end(2);
	for (int n = 0; status().state != MLIP_STATE_RUNNING && n < 3000; n++) {
		htick(1);
	}
	htick(100);
	assert_int_equal(hcmd(MLIP_CMD_HOLD, 0), MLIP_OK);
	for (int n = 0; status().state != MLIP_STATE_HELD && n < 3000; n++) {
		htick(1);
	}
	assert_int_equal(status().state, MLIP_STATE_HELD);
	x = out.pos[0];
	assert_true(x > -2.5 && x < 50.0);
	assert_int_equal(hcmd(MLIP_CMD_HOME, 0), MLIP_E_INVALID);
	htick(50);
	assert_int_equal(status().state, MLIP_STATE_HELD);
	assert_true(out.pos[0] == x);
	assert_int_equal(status().homed, 3u);
	assert_int_equal(sdo_log_n, logged);
	assert_int_equal(hcmd(MLIP_CMD_RESUME, 0), MLIP_OK);
	for (int n = 0; status().reason != MLIP_WHY_END && n < 20000; n++) {
		htick(1);
	}
	assert_int_equal(status().reason, MLIP_WHY_END);
	assert_true(out.pos[0] == 50.0);
}

/* A homing object the drive refuses (SDO abort): a fault naming the node
 * and the object, every axis quick-stopped, the drive back in mode 8; a
 * reset, then nothing homed. */
static void test_home_sdo_refused(void **st)
{
	(void)st;
	sdo_refuse = 0x6098;
	assert_int_equal(hcmd(MLIP_CMD_HOME, 1), MLIP_OK); /* X only */
	for (int i = 0; i < 200 && status().state == MLIP_STATE_HOMING; i++) {
		htick(1);
	}
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_int_equal(status().reason, MLIP_WHY_HOMING_SDO);
	assert_int_equal(status().reason_node, 1);
	assert_int_equal(status().reason_field, 0x609800u);
	assert_true(status().reason_value == (double)0x06090030);
	assert_int_equal(cw_of(0), 0x0002);
	htick(10);
	assert_int_equal(drv_mode[0], 8);
	assert_int_equal(hcmd(MLIP_CMD_RESET, 0), MLIP_OK);
	assert_int_equal(status().homed, 0u);
	assert_int_equal(hcmd(MLIP_CMD_HOME, 4), MLIP_E_RANGE); /* no axis 2 */
}

/* An axis is homed only while its drive keeps its home: "homing attained"
 * (bit 12) dropping while its group waits makes it wait for that drive
 * again (no return to CSP on a stale attained); a drive fault, and a reboot
 * (its NMT state left operational: the boot-up), leave its axis not homed,
 * the others homed. */
static void test_home_lost(void **st)
{
	(void)st;
	home_cfg.axis[0].sequence = 0; /* X (method 35: at once) with Y */
	home_cfg.axis[1].method = 19;  /* the model never ends it: the test does */
	home_init();
	assert_int_equal(hcmd(MLIP_CMD_HOME, 0), MLIP_OK);
	int i;
	for (i = 0; i < 2000 && !drv_homing[1]; i++) {
		htick(1); /* until bit 4's edge: Y searches, X (35) is home at once */
	}
	assert_true(i < 2000 && !drv_homing[0] && (drv_sw[0] & 0x1400) == 0x1400);
	htick(20);
	assert_true(drv_mode[0] == 6 && drv_mode[1] == 6); /* X waits for Y */
	drv_sw[0] &= (uint16_t)~0x1000u;                   /* X's drive lost it */
	htick(5);
	drv_sw[1] |= 0x1400; /* Y attained */
	drv_homing[1] = 0;
	htick(50);
	assert_int_equal(status().state, MLIP_STATE_HOMING); /* waiting for X again */
	assert_true(drv_mode[0] == 6 && drv_mode[1] == 6);
	assert_int_equal(status().homed, 0u);
	drv_sw[0] |= 0x1000; /* attained again */
	for (i = 0; i < 500 && status().state == MLIP_STATE_HOMING; i++) {
		htick(1);
	}
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	assert_int_equal(status().reason, MLIP_WHY_HOMED);
	assert_int_equal(status().homed, 3u);
	assert_true(drv_mode[0] == 8 && drv_mode[1] == 8);
	/* X's drive reboots: its boot-up leaves NMT operational (rt/ reports it
	 * as a drive fault) */
	drv_fault.event = MLIP_DRIVE_NOT_OPERATIONAL;
	drv_fault.node = 1;
	drv_fault.value = 0; /* NMT boot-up */
	htick(1);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_int_equal(status().reason, MLIP_WHY_DRIVE);
	assert_int_equal(status().homed, 2u); /* Y keeps its home */
}

/* Homing again a drive homed before, whose TPDO at the SYNC that applies
 * bit 4's rise still shows the last homing's bits 10 and 12 (sampled before
 * it, CiA 301): not taken as homed; this homing's result decides (here a
 * homing error, method 1 in the model). */
static void test_home_again_stale_attained(void **st)
{
	(void)st;
	assert_int_equal(hcmd(MLIP_CMD_HOME, 1), MLIP_OK); /* X (35) */
	for (int i = 0; i < 2000 && status().state == MLIP_STATE_HOMING; i++) {
		htick(1);
	}
	assert_int_equal(status().homed, 1u);
	home_cfg.axis[0].method = 1; /* the model: a homing error */
	home_init();
	htick(5);
	drv_sw[0] |= 0x1400; /* in mode 6 again it shows the last homing's bits */
	drv_start_late = 1;
	assert_int_equal(hcmd(MLIP_CMD_HOME, 1), MLIP_OK);
	for (int i = 0; i < 2000 && status().state == MLIP_STATE_HOMING; i++) {
		htick(1);
	}
	if (status().state != MLIP_STATE_FAULT || status().reason != MLIP_WHY_HOMING_ERROR ||
	    (status().homed & 1u) != 0) {
		fail_msg("state %u reason %u homed %u sw 0x%04X mode %d", status().state,
		         status().reason, status().homed, drv_sw[0], drv_mode[0]);
	}
}

/* A fault of Y's drive (statusword bit 3) after homing: Y not homed. */
static void test_home_lost_fault(void **st)
{
	(void)st;
	assert_int_equal(hcmd(MLIP_CMD_HOME, 0), MLIP_OK);
	for (int i = 0; i < 5000 && status().state == MLIP_STATE_HOMING; i++) {
		htick(1);
	}
	assert_int_equal(status().homed, 3u);
	drv_fault.event = MLIP_DRIVE_FAULT_BIT;
	drv_fault.node = 2;
	drv_fault.value = 0x0218;
	htick(1);
	assert_int_equal(status().reason, MLIP_WHY_DRIVE);
	assert_int_equal(status().homed, 1u);
}

/* Homing error (bit 13) and a timeout: a fault naming node, method and
 * statusword, quick stop, CSP back. */
static void test_home_error_and_timeout(void **st)
{
	(void)st;
	home_cfg.axis[1].method = 1;
	home_cfg.axis[0].method = 36;
	home_cfg.axis[0].timeout_s = 0.5;
	home_init();
	assert_int_equal(hcmd(MLIP_CMD_HOME, 2), MLIP_OK);
	for (int i = 0; i < 500 && status().state == MLIP_STATE_HOMING; i++) {
		htick(1);
	}
	assert_int_equal(status().reason, MLIP_WHY_HOMING_ERROR);
	assert_int_equal(status().reason_node, 2);
	assert_int_equal(status().reason_field, 1);
	assert_true(((uint32_t)status().reason_value & 0x2000u) != 0);
	assert_int_equal(cw_of(1), 0x0002);
	htick(10);
	assert_int_equal(drv_mode[1], 8);
	assert_int_equal(hcmd(MLIP_CMD_RESET, 0), MLIP_OK);
	until_power(MLIP_POWER_OFF, 50);
	assert_int_equal(hcmd(MLIP_CMD_HOME, 1), MLIP_OK);
	int n = 0;
	while (status().state == MLIP_STATE_HOMING && n++ < 2000) {
		htick(1);
	}
	assert_int_equal(status().reason, MLIP_WHY_HOMING_TIMEOUT);
	assert_int_equal(status().reason_node, 1);
	assert_int_equal(status().reason_field, 36);
	assert_true(n > 500 && n < 600); /* 0.5 s after bit 4, plus the set-up */
}

#define T(f)   cmocka_unit_test_setup_teardown(f, setup, teardown)
#define TD(f)  cmocka_unit_test_setup_teardown(f, setup_drives, teardown)
#define TIO(f) cmocka_unit_test_setup_teardown(f, setup_io, teardown)
#define TH(f)  cmocka_unit_test_setup_teardown(f, setup_home, teardown)
#define TS(f)  cmocka_unit_test_setup_teardown(f, setup_spindle, teardown)

/* ---- a CiA 402 spindle on the bus (issue 19) ------------------------------ */

/* The spindle drive of these tests: node 9, 4096 counts/rev; it follows the
 * group's controlword as the axes' drives do, and in "operation enabled"
 * ramps its velocity to the target at its own acceleration (10000 rpm/s),
 * target reached (bit 10) within 20 rpm; not enabled it brakes at the same
 * rate. Its TPDO of the next period shows it. */
static struct mlip_spindle_config sp_cfg = {9, 0, 12000, 4096, 10000, 240, 3.4, 0.2};
static struct {
	double rpm, target_rpm, accel, load;
	int fault;
	uint16_t sw;
	uint64_t reached; /* the first period its TPDO said target reached (0: not yet) */
} spd;

static int setup_spindle(void **state)
{
	setup_drives(state);
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT,
	                          .lookahead = 16,
	                          .can = &can_cia402,
	                          .drives = 1,
	                          .drive_state_periods = 50,
	                          .spindle = &sp_cfg};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
	memset(&spd, 0, sizeof(spd));
	spd.accel = 10000;
	spd.sw = 0x0237;
	sp_in.sw = spd.sw;
	return 0;
}

static void spindle_drive(void)
{
	double step = spd.accel * mach.period_s, err;
	uint16_t cw = out.spindle.cw;
	int enabled = (spd.sw & 0x6F) == 0x27;
	assert_true(out.spindle.send);
	int st = spd.sw & 0x6F; /* CiA 402's transitions, from the state it is in */
	if (spd.fault) {
		spd.sw = 0x0218; /* fault */
	} else if (cw == 0x0F && (st == 0x21 || st == 0x23 || enabled)) {
		spd.sw = 0x0237;
	} else if (cw == 0x07 && (st == 0x21 || enabled)) {
		spd.sw = 0x0233;
	} else if (cw == 0x06 && (st == 0x40 || st == 0x23 || enabled)) {
		spd.sw = 0x0231;
	} else if (cw == 0x02 && st != 0x40) {
		spd.sw = 0x0250; /* quick stop (option 2): then switch on disabled */
	}
	enabled = (spd.sw & 0x6F) == 0x27;
	spd.target_rpm = enabled ? out.spindle.target * 60.0 / 4096.0 : 0.0;
	err = spd.target_rpm - spd.rpm;
	spd.rpm += fabs(err) <= step ? err : err > 0 ? step : -step;
	if (enabled && fabs(spd.target_rpm - spd.rpm) <= 20) {
		spd.sw |= 0x0400;
	}
	sp_in.sw = spd.sw;
	/* a load slows it, whichever way it turns */
	double rpm = spd.rpm - (spd.rpm < 0 ? -spd.load : spd.load);
	sp_in.vel_counts = (int32_t)floor(rpm * 4096.0 / 60.0 + 0.5);
	if ((spd.sw & 0x0400) && spd.target_rpm != 0 && spd.reached == 0) {
		spd.reached = period; /* the period that reads this TPDO */
	}
}

static void stick(int n)
{
	for (int i = 0; i < n; i++) {
		dtick(1);
		spindle_drive();
	}
}

/* stick until the state is st (at most n periods): the periods it took */
static int suntil(uint32_t st, int n)
{
	for (int i = 1; i <= n; i++) {
		stick(1);
		if (status().state == st) {
			return i;
		}
	}
	fail_msg("state %s not reached (now %s)", mlip_ctl_state_name(st),
	         mlip_ctl_state_name(status().state));
	return -1;
}

/* G0 X5, M3 S12000, G1 along X to 40: nothing moves from the M3 until the
 * drive's TPDO said target reached and its speed is in the band; the wait is
 * the ramp (1.2 s at 10000 rpm/s) plus the bus' periods; the program's end
 * stops it (target 0 in the period after) and the drives are disabled only at
 * its standstill. */
static void test_spindle_feed_waits_for_speed(void **st)
{
	(void)st;
	stick(5);
	move(1, 5.0, 0.0);
	event(2, MLIP_BLOCK_SPINDLE, 12000.0);
	for (uint64_t k = 3; k <= 10; k++) {
		move(k, 5.0 * (double)k, 0.0);
	}
	end(11);
	suntil(MLIP_STATE_DWELLING, 5000);
	assert_int_equal(status().reason, MLIP_WHY_SPINDLE_WAIT);
	assert_true(out.pos[0] == 5.0);
	uint64_t asked = period;
	double x = out.pos[0];
	uint64_t moved = 0;
	for (int i = 0; i < 3000 && moved == 0; i++) {
		stick(1);
		if (out.pos[0] != x) {
			moved = period;
		}
		assert_true(status().spindle_state != 0);
	}
	assert_true(moved != 0 && spd.reached != 0);
	assert_true(moved > spd.reached); /* never before the drive said so */
	assert_true(fabs(spd.rpm - 12000) <= 20);
	/* the ramp into the drive's 20 rpm window: 1198 periods; the bus: its
	 * RPDO and its TPDO a period each (the first TPDO read counts from the
	 * ask's period) */
	uint64_t wait = moved - asked;
	print_message("spindle start to feed: %llu periods (ramp 1198)\n",
	              (unsigned long long)wait);
	assert_true(wait >= 1198 && wait <= 1202);
	assert_true(status().spindle_cmd_rpm == 12000 &&
	            fabs(status().spindle_actual_rpm - 12000) <= 20);
	assert_true(out.spindle.target == 819200);
	/* the spindle override: 150 % is clamped to MAX_RPM 12000, 50 % halves it */
	assert_int_equal(period_cmd(MLIP_CMD_SPINDLE_OVERRIDE, 40, 0), MLIP_E_RANGE);
	assert_int_equal(period_cmd(MLIP_CMD_SPINDLE_OVERRIDE, 50, 0), MLIP_OK);
	spindle_drive();
	assert_true(status().spindle_override == 50 && status().spindle_cmd_rpm == 6000);
	assert_int_equal(period_cmd(MLIP_CMD_SPINDLE_OVERRIDE, 100, 0), MLIP_OK);
	spindle_drive();
	/* the end: target 0 in the period after it, the drives held until standstill */
	suntil(MLIP_STATE_IDLE, 5000);
	assert_int_equal(status().reason, MLIP_WHY_END);
	assert_int_equal(out.spindle.target, 0);
	assert_true(spd.rpm > 1000);
	int k = 0;
	while (status().drive_power == MLIP_POWER_ENABLED && k < 3000) {
		stick(1);
		k++;
		assert_int_equal(out.spindle.target, 0);
	}
	assert_true(fabs(spd.rpm) <= 240); /* disabled at standstill (the band), not before */
	assert_int_equal(status().drive_power, MLIP_POWER_DISABLING);
}

/* A stop mid-cut: target 0 in the period after the stop; a fault of the
 * spindle drive mid-cut: the feed stops on the path (no jump: each period's
 * step within the acceleration), state FAULT naming the spindle. */
static void start_cut(void)
{
	stick(5);
	event(1, MLIP_BLOCK_SPINDLE, -6000.0); /* M4 */
	for (uint64_t k = 2; k <= 40; k++) {
		move(k, 10.0 * (double)k, 0.0);
	}
	end(41);
	suntil(MLIP_STATE_RUNNING, 5000);
	assert_true(spd.rpm < -5970);
	stick(100);
	assert_int_equal(status().state, MLIP_STATE_RUNNING);
}

static void test_spindle_stop_and_fault_mid_cut(void **st)
{
	(void)st;
	start_cut();
	stop_count++;
	stick(1);
	assert_int_equal(status().state, MLIP_STATE_STOPPING);
	assert_int_equal(out.spindle.target, 0);
	suntil(MLIP_STATE_IDLE, 5000);
	/* again, and the drive faults */
	stick(3000);
	teardown(st);
	setup_spindle(st);
	start_cut();
	double x0 = out.pos[0], prev = out.pos[0], dv_max = 0;
	double v_prev;
	stick(1);
	v_prev = (out.pos[0] - prev) / mach.period_s; /* at feed: 100 mm/s */
	prev = out.pos[0];
	spd.fault = 1;
	int k;
	for (k = 0; k < 2000; k++) {
		stick(1);
		double v = (out.pos[0] - prev) / mach.period_s;
		dv_max = fabs(v - v_prev) > dv_max ? fabs(v - v_prev) : dv_max;
		v_prev = v;
		if (out.pos[0] == prev) {
			break;
		}
		prev = out.pos[0];
	}
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_int_equal(status().reason, MLIP_WHY_SPINDLE_FAULT);
	assert_int_equal(status().reason_node, 9);
	assert_int_equal(status().reason_field, MLIP_DRIVE_FAULT_BIT);
	/* on the path, 100 mm/s braked at 1000 mm/s^2: about 5 mm, 100 periods */
	assert_true(out.pos[0] - x0 > 4.0 && out.pos[0] - x0 < 6.5 && k >= 100 && k <= 104);
	print_message("spindle fault mid-cut: %d periods to rest, largest speed step %g mm/s\n", k,
	              dv_max);
	assert_true(dv_max <= 1000.0 * mach.period_s * 1.001);
	assert_int_equal(out.spindle.target, 0);
	/* a faulted spindle stops by its own fault reaction: the axes are
	 * disabled at rest without waiting for it (an exit would hang on a
	 * spindle whose TPDOs stopped) */
	int p;
	for (p = 0; p < 500 && status().drive_power != MLIP_POWER_OFF; p++) {
		stick(1);
	}
	assert_int_equal(status().drive_power, MLIP_POWER_OFF);
	assert_int_equal(status().spindle_state, MLIP_SPINDLE_FAULT + 1u);
}

/* Grbl's spindle stop (0x9E) in an operator's hold: refused outside one;
 * asked while the hold brakes it waits for rest (the tool is still in the
 * cut), then the spindle's target is 0, the axes still; a resume restores
 * the program's speed and the axes move only once the drive said it is at
 * speed again. The second time the restore comes first (a second 0x9E),
 * the resume follows while it still ramps: the same wait. */
static void resume_waits_for_speed(const char *what)
{
	double x = out.pos[0];
	uint64_t moved = 0;
	assert_int_equal(status().state, MLIP_STATE_HELD);
	for (int i = 0; i < 5000 && moved == 0; i++) {
		stick(1);
		if (out.pos[0] != x) {
			moved = period;
		} else if (spd.reached == 0) {
			assert_int_equal(status().state, MLIP_STATE_HELD);
			assert_int_equal(status().reason, MLIP_WHY_SPINDLE_WAIT);
		}
	}
	assert_true(moved != 0 && spd.reached != 0);
	assert_true(moved > spd.reached);
	assert_true(fabs(spd.rpm + 6000) <= 20);
	print_message("%s: the feed %llu periods after target reached\n", what,
	              (unsigned long long)(moved - spd.reached));
}

static void test_spindle_stop_in_a_hold(void **st)
{
	(void)st;
	start_cut(); /* M4 S6000, cutting */
	assert_int_equal(period_cmd(MLIP_CMD_SPINDLE_STOP, 1, 0), MLIP_E_INVALID);
	spindle_drive();
	assert_int_equal(period_cmd(MLIP_CMD_HOLD, 0, 0), MLIP_OK);
	spindle_drive();
	assert_int_equal(period_cmd(MLIP_CMD_SPINDLE_STOP, 2, 0), MLIP_E_RANGE);
	spindle_drive();
	assert_int_equal(period_cmd(MLIP_CMD_SPINDLE_STOP, 1, 0), MLIP_OK);
	spindle_drive();
	int k = 0;
	while (status().state != MLIP_STATE_HELD && k++ < 2000) {
		assert_true(out.spindle.target == -409600); /* braking: still turning */
		stick(1);
	}
	assert_int_equal(status().state, MLIP_STATE_HELD);
	stick(1);
	assert_int_equal(out.spindle.target, 0);
	assert_true(status().spindle_cmd_rpm == 0);
	double x = out.pos[0];
	stick(1500);
	assert_true(fabs(spd.rpm) <= 20 && out.pos[0] == x);
	assert_int_equal(status().state, MLIP_STATE_HELD);
	/* the resume: restored, then the wait */
	spd.reached = 0;
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK);
	spindle_drive();
	assert_true(out.spindle.target == -409600 && status().spindle_cmd_rpm == -6000);
	resume_waits_for_speed("0x9E, resume");
	/* again: 0x9E twice in the hold, the resume while it ramps */
	assert_int_equal(period_cmd(MLIP_CMD_HOLD, 0, 0), MLIP_OK);
	spindle_drive();
	suntil(MLIP_STATE_HELD, 2000);
	assert_int_equal(period_cmd(MLIP_CMD_SPINDLE_STOP, 1, 0), MLIP_OK);
	spindle_drive();
	stick(1500);
	assert_true(fabs(spd.rpm) <= 20);
	assert_int_equal(period_cmd(MLIP_CMD_SPINDLE_STOP, 0, 0), MLIP_OK);
	spindle_drive();
	stick(2);
	assert_true(out.spindle.target == -409600);
	assert_int_equal(status().state, MLIP_STATE_HELD);
	spd.reached = 0;
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK);
	spindle_drive();
	resume_waits_for_speed("0x9E twice, resume while ramping");
}

/* The same between a sender's lines (mlip-grbl: an M3 typed in its console
 * is a program left open, the controller starved at rest waiting for the
 * next line): the hold at rest there is where 0x9E acts too. Lines that come
 * in the hold are taken (held, the spindle kept stopped); the resume
 * restores the spindle wherever the program stands, and the axes move only
 * once it is at speed again. */
static void test_spindle_stop_in_a_hold_between_lines(void **st)
{
	(void)st;
	stick(5);
	event(1, MLIP_BLOCK_SPINDLE, -6000.0); /* M4 S6000, and no end */
	suntil(MLIP_STATE_STARVED, 5000);
	assert_true(fabs(spd.rpm + 6000) <= 20);
	assert_int_equal(period_cmd(MLIP_CMD_HOLD, 0, 0), MLIP_OK);
	spindle_drive();
	stick(2);
	assert_int_equal(status().state, MLIP_STATE_STARVED);
	assert_int_equal(period_cmd(MLIP_CMD_SPINDLE_STOP, 1, 0), MLIP_OK);
	spindle_drive();
	stick(1);
	assert_int_equal(out.spindle.target, 0);
	assert_true(status().spindle_cmd_rpm == 0);
	stick(1500);
	assert_true(fabs(spd.rpm) <= 20);
	/* a second 0x9E restores it, a third stops it again */
	assert_int_equal(period_cmd(MLIP_CMD_SPINDLE_STOP, 0, 0), MLIP_OK);
	spindle_drive();
	stick(1);
	assert_true(out.spindle.target == -409600 && status().spindle_cmd_rpm == -6000);
	stick(1500);
	assert_true(fabs(spd.rpm + 6000) <= 20);
	assert_int_equal(period_cmd(MLIP_CMD_SPINDLE_STOP, 1, 0), MLIP_OK);
	spindle_drive();
	stick(1500);
	assert_true(fabs(spd.rpm) <= 20 && out.spindle.target == 0);
	/* the sender's next lines, taken in the hold: nothing moves, the
	 * spindle stays stopped */
	double x = out.pos[0];
	for (uint64_t k = 2; k <= 10; k++) {
		move(k, 5.0 * (double)k, 0.0);
	}
	end(11);
	stick(200);
	assert_true(out.pos[0] == x && out.spindle.target == 0);
	/* the resume: restored, the feed once at speed */
	spd.reached = 0;
	assert_int_equal(period_cmd(MLIP_CMD_RESUME, 0, 0), MLIP_OK);
	spindle_drive();
	assert_true(out.spindle.target == -409600 && status().spindle_cmd_rpm == -6000);
	uint64_t moved = 0;
	for (int i = 0; i < 5000 && moved == 0; i++) {
		stick(1);
		if (out.pos[0] != x) {
			moved = period;
		}
	}
	assert_true(moved != 0 && spd.reached != 0 && moved > spd.reached);
	suntil(MLIP_STATE_IDLE, 5000);
	assert_true(out.pos[0] == 50.0);
}

/* The spindle drive's heartbeat lost mid-cut (rt/'s supervision reports it
 * with its node): state FAULT naming the spindle, the feed stopped on the
 * path, the spindle asked 0. */
static void test_spindle_heartbeat_lost(void **st)
{
	(void)st;
	start_cut();
	double x0 = out.pos[0];
	drv_fault = (struct mlip_ctl_drive_fault){MLIP_DRIVE_HEARTBEAT_LOST, 9, 310.0};
	stick(1);
	assert_int_equal(status().state, MLIP_STATE_FAULT);
	assert_int_equal(status().reason, MLIP_WHY_SPINDLE_FAULT);
	assert_int_equal(status().reason_field, MLIP_DRIVE_HEARTBEAT_LOST);
	assert_int_equal(status().reason_node, 9);
	assert_int_equal(out.spindle.target, 0);
	for (int k = 0; k < 500 && status().speed_mm_s > 0; k++) {
		stick(1);
	}
	assert_true(status().speed_mm_s == 0 && out.pos[0] - x0 < 6.5 && out.pos[1] == 0.0);
	/* an axis drive's fault stays a drive fault */
	teardown(st);
	setup_spindle(st);
	start_cut();
	drv_fault = (struct mlip_ctl_drive_fault){MLIP_DRIVE_FOLLOWING_ERROR, 2, 4000.0};
	stick(1);
	assert_int_equal(status().reason, MLIP_WHY_DRIVE);
	assert_int_equal(out.spindle.target, 0);
}

/* At speed, then a load it cannot hold: out of the band longer than
 * BAND_TIME (200 periods) is a fault; a spindle slower than the timeout
 * (3.4 s) is one too. */
static void test_spindle_band_and_timeout(void **st)
{
	(void)st;
	start_cut();
	spd.load = 500; /* rpm */
	int k = suntil(MLIP_STATE_FAULT, 1000);
	assert_true(k >= 200 && k <= 203);
	assert_int_equal(status().reason, MLIP_WHY_SPINDLE_FAULT);
	assert_int_equal(status().reason_field, MLIP_DRIVE_SPINDLE_OUT_OF_BAND);
	assert_true(fabs(status().reason_value + 5500) < 1); /* the actual rpm, M4 */
	teardown(st);
	setup_spindle(st);
	spd.accel = 3000; /* 12000 rpm takes 4 s */
	stick(5);
	event(1, MLIP_BLOCK_SPINDLE, 12000.0);
	move(2, 5.0, 0.0);
	end(3);
	suntil(MLIP_STATE_DWELLING, 100);
	k = suntil(MLIP_STATE_FAULT, 5000);
	assert_true(k >= 3399 && k <= 3403);
	assert_int_equal(status().reason_field, MLIP_DRIVE_SPINDLE_TIMEOUT);
	assert_true(out.pos[0] == 0.0); /* nothing moved */
}

/* E-stop mid-cut: quick stop (0x0002) to the spindle with the axes in the
 * period of the input, its target 0; after the reset and standstill a new
 * M3 waits for speed again. */
static void test_spindle_estop(void **st)
{
	(void)st;
	io_config();
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT,
	                          .lookahead = 16,
	                          .can = &can_cia402,
	                          .drives = 1,
	                          .drive_state_periods = 50,
	                          .io = &io_cfg,
	                          .spindle = &sp_cfg};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
	io_in.known = io_cfg.mapped;
	start_cut();
	io_in.active = BIT(MLIP_IN_ESTOP);
	stick(1);
	assert_int_equal(status().state, MLIP_STATE_ESTOP);
	assert_int_equal(out.spindle.cw, 0x0002);
	assert_int_equal(cw_of(0), 0x0002);
	assert_int_equal(out.spindle.target, 0);
	assert_true(status().spindle_cmd_rpm == 0);
	stick(1000); /* the drive brakes by itself */
	assert_true(fabs(spd.rpm) <= 20);
	io_in.active = 0;
	assert_int_equal(period_cmd(MLIP_CMD_RESET, 0, 0), MLIP_OK);
	assert_int_equal(status().state, MLIP_STATE_IDLE);
	/* the program in the very period after the reset: it waits until the
	 * drives (the spindle's too) are out of "switch on disabled", "ready"
	 * confirmed, then switched on and enabled */
	spd.reached = 0;
	event(1, MLIP_BLOCK_SPINDLE, 3000.0);
	move(2, 5.0, 0.0);
	end(3);
	suntil(MLIP_STATE_RUNNING, 5000);
	assert_true(spd.reached != 0 && fabs(spd.rpm - 3000) <= 20);
}

/* MDI M3 S (mlip-ctl mdi: the feeder says so): the spindle stays on at
 * speed when the line is done, the drives enabled for it, through an
 * incremental jog (LinuxCNC: the operator starts it, then jogs and touches
 * off); MDI M5 stops it (the drives disabled at its standstill); a stop at
 * rest stops it in the same period; a program's end (not MDI) too. */
static void mdi_m3(double rpm)
{
	feeder_mdi = 1;
	event(1, MLIP_BLOCK_SPINDLE, rpm);
	end(2);
	suntil(MLIP_STATE_DWELLING, 100);
	suntil(MLIP_STATE_IDLE, 5000);
	assert_int_equal(status().reason, MLIP_WHY_END);
}

static void test_spindle_mdi_stays_on(void **st)
{
	(void)st;
	stick(5);
	mdi_m3(6000.0);
	stick(500);
	assert_true(status().spindle_cmd_rpm == 6000 && fabs(spd.rpm - 6000) <= 20);
	assert_int_equal(out.spindle.target, 409600);
	assert_int_equal(status().drive_power, MLIP_POWER_ENABLED);
	/* a 5 mm jog along X, renewed as mlip-ctl does: the spindle turns on */
	assert_int_equal(period_cmd(MLIP_CMD_JOG_AXIS, MLIP_JOG_AXIS_ARG(0, 0, 5000), 0), MLIP_OK);
	assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 0, 1200), 0), MLIP_OK);
	for (int i = 0; i < 3000 && status().state == MLIP_STATE_JOGGING; i++) {
		stick(1);
		if (i % 100 == 99 && status().state == MLIP_STATE_JOGGING) {
			assert_int_equal(period_cmd(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 0, 1200), 0),
			                 MLIP_OK);
			spindle_drive();
		}
		assert_int_equal(out.spindle.target, 409600);
	}
	assert_int_equal(status().reason, MLIP_WHY_JOG_DONE);
	assert_true(fabs(out.pos[0] - 5.0) < 1e-9);
	stick(100);
	assert_true(status().spindle_cmd_rpm == 6000 && fabs(spd.rpm - 6000) <= 20);
	assert_int_equal(status().drive_power, MLIP_POWER_ENABLED);
	/* MDI M5: it stops; the drives are disabled once it stands still */
	event(1, MLIP_BLOCK_SPINDLE, 0.0);
	end(2);
	suntil(MLIP_STATE_IDLE, 5000);
	assert_int_equal(out.spindle.target, 0);
	assert_true(fabs(spd.rpm) <= 240);
	for (int i = 0; i < 100 && status().drive_power == MLIP_POWER_ENABLED; i++) {
		stick(1);
	}
	assert_true(status().drive_power != MLIP_POWER_ENABLED);
	/* again; a stop at rest: target 0 in the stop's own period */
	mdi_m3(-3000.0);
	stick(10);
	assert_int_equal(out.spindle.target, -204800);
	stop_count++;
	stick(1);
	assert_int_equal(out.spindle.target, 0);
	assert_true(status().spindle_cmd_rpm == 0);
	/* again; then a program: its end stops it */
	feeder_base = stop_count;
	mdi_m3(3000.0);
	feeder_mdi = 0;
	move(1, 10.0, 0.0);
	end(2);
	suntil(MLIP_STATE_RUNNING, 100);
	assert_int_equal(out.spindle.target, 204800); /* it turned through the program */
	suntil(MLIP_STATE_IDLE, 5000);
	assert_int_equal(status().reason, MLIP_WHY_END);
	assert_int_equal(out.spindle.target, 0);
}

/* MDI S alone (SPEED): the speed of the spindle an earlier MDI M4 keeps
 * turning, in its direction, at rest until it is at the new speed; once M5
 * stopped it, an S leaves it stopped (the S is for the next M3/M4). */
static void test_spindle_mdi_speed(void **st)
{
	(void)st;
	stick(5);
	mdi_m3(-3000.0);
	stick(100);
	assert_int_equal(out.spindle.target, -204800);
	feeder_base = stop_count;
	event(1, MLIP_BLOCK_SPEED, 4500.0);
	end(2);
	suntil(MLIP_STATE_DWELLING, 100);
	assert_int_equal(status().reason, MLIP_WHY_SPINDLE_WAIT);
	assert_true(status().reason_value == -4500.0);
	assert_int_equal(out.spindle.target, -307200); /* 4500 rpm * 4096 / 60, reversed */
	suntil(MLIP_STATE_IDLE, 5000);
	assert_int_equal(status().reason, MLIP_WHY_END);
	assert_true(status().spindle_cmd_rpm == -4500 && fabs(spd.rpm + 4500) <= 20);
	/* M5, then an S alone: it stays stopped */
	event(1, MLIP_BLOCK_SPINDLE, 0.0);
	end(2);
	suntil(MLIP_STATE_IDLE, 5000);
	event(1, MLIP_BLOCK_SPEED, 2000.0);
	end(2);
	suntil(MLIP_STATE_DWELLING, 100);
	suntil(MLIP_STATE_IDLE, 100);
	stick(100);
	assert_int_equal(out.spindle.target, 0);
	assert_true(status().spindle_cmd_rpm == 0);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    T(test_feeder_dead_in_preread_runs_what_came),
	    T(test_starved_takes_only_the_next_block),
	    T(test_stop_distance_published),
	    T(test_hold_at_rest_counts_no_stop),
	    T(test_hold_latched_at_rest),
	    T(test_override_zero_holds_in_the_status),
	    T(test_stop_before_first_block_completes),
	    T(test_override_zero_and_exit),
	    T(test_stop_latched_for_the_program_about_to_start),
	    T(test_stop_counter_stops_a_running_program),
	    T(test_hold_reason_follows_the_causes),
	    T(test_stop_in_dwell_names_the_block_before),
	    T(test_stop_in_pause_names_the_block_before),
	    T(test_exit_in_dwell_names_the_block_before),
	    T(test_dwell_exact_periods),
	    T(test_dwell_first_and_zero),
	    T(test_pause_and_optional_pause),
	    T(test_exact_stop_corner_at_rest),
	    T(test_bad_nan_target),
	    T(test_bad_beyond_soft_limit),
	    T(test_bad_feed),
	    T(test_bad_type_seq_dwell_flags),
	    T(test_bad_below_soft_limit),
	    T(test_bad_feed_above_max),
	    T(test_bad_feed_below_min),
	    T(test_bad_rapid_feed),
	    T(test_bad_tol_negative),
	    T(test_bad_tol_nan),
	    T(test_bad_tol_above_max),
	    T(test_bad_dwell_above_max),
	    T(test_bad_dwell_nan),
	    T(test_record_bounds_accepted),
	    T(test_bad_beyond_drive_count),
	    T(test_bad_spindle_speed),
	    T(test_speed_without_spindle),
	    T(test_bad_tool_number),
	    T(test_bad_coolant_bits),
	    T(test_bad_record_in_dwell_rests_before_it),
	    T(test_bad_record_in_preread_never_moves),
	    T(test_stall_holds_at_last_setpoint),
	    T(test_stall_in_corner),
	    T(test_stall_before_the_send),
	    T(test_record_roundtrip),
	    T(test_every_name),
	    T(test_corrupt_sizes_ignored),
	    T(test_corrupt_head_is_a_fault),
	    T(test_drive_fault_stops_on_the_path),
	    T(test_drive_fault_idle_and_actual_positions),
	    TD(test_drives_pause_hold_then_disabled),
	    TD(test_drives_beyond_limit_when_enabling),
	    TD(test_drives_stop_while_enabling),
	    TIO(test_estop_same_period),
	    TIO(test_estop_reset),
	    TIO(test_estop_reset_program_next_period),
	    TIO(test_estop_reset_drive_stays_disabled),
	    TIO(test_estop_wins),
	    TIO(test_io_lost),
	    TIO(test_limit),
	    cmocka_unit_test_setup_teardown(test_limit_drive_input, setup_io_drive, teardown),
	    TIO(test_hold_cycle_start_inputs),
	    TIO(test_limit_jog_away),
	    TIO(test_estop_without_drives),
	    TIO(test_estop_clears_latched_hold),
	    T(test_jog_release),
	    T(test_jog_deadman),
	    T(test_jog_soft_limit),
	    T(test_jog_refused),
	    T(test_jog_incremental),
	    T(test_jog_multi_axis),
	    T(test_jog_multi_release),
	    TD(test_jog_drives),
	    TH(test_home_sequence),
	    TH(test_home_sdo_refused),
	    TH(test_home_refused_in_a_hold),
	    TH(test_home_error_and_timeout),
	    TH(test_home_lost),
	    TH(test_home_lost_fault),
	    TH(test_home_again_stale_attained),
	    TS(test_spindle_feed_waits_for_speed),
	    TS(test_spindle_stop_and_fault_mid_cut),
	    TS(test_spindle_stop_in_a_hold),
	    TS(test_spindle_stop_in_a_hold_between_lines),
	    TS(test_spindle_band_and_timeout),
	    TS(test_spindle_estop),
	    TS(test_spindle_mdi_stays_on),
	    TS(test_spindle_mdi_speed),
	    TS(test_spindle_heartbeat_lost),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
