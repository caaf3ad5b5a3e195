/*
 * test_ctl_follow.c - the controller's run mode for [TRAJ] JERK_PLAN = path
 * (src/ctl/follow.c): its setpoints come from a planned queue
 * (mlip/motion/planq.h) that a test producer fills ahead of each period (the
 * planning thread's work, in line). The program runs to its last point with
 * the queue's setpoints to the bit; a hold, a stop and an E-stop mid-move
 * brake on the queue's braking run from the period they arrive, inside A and
 * J (second and third differences, within 1e-6 relative, and used: at least
 * 0.3 A and 0.5 J), and come to rest on the path; the E-stop wins over a
 * resume of the same period; a lower override caps the speed.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "mlip/canopen/drive.h"
#include "mlip/ctl/controller.h"
#include "mlip/motion/planq.h"

#define T            1e-3
#define JERK         1e4
#define ACC          1000.0
#define V            60.0
/* the path: a circle of radius R from the origin (home), arc U_END */
#define R            10.0
#define U_END        4.0
/* the spline through points V T apart stays this close to the circle */
#define PATH_TOL     1e-4
/* a stop from V at 300 mm/s^2 with its jerk ramps takes well under this */
#define STOP_PERIODS 600
/* the program's blocks: BLOCKS of BLOCK_U of arc each, block b on line
 * LINE(b); the input's step in u (V T / R) bounds how far a block's
 * attribution may lag or lead the position */
#define BLOCKS       8
#define BLOCK_U      (U_END / BLOCKS)
#define LINE(b)      (10u * (uint32_t)(b) + 3u)
#define STEP_U       (1.01 * V * T / R)
#define MAX_PERIODS  20000

static struct mlip_machine mach;
static struct mlip_planner planner;
static struct mlip_ctl ctl;
static struct mlip_ctl_out out;
static struct mlip_pathrun pr;
static struct mlip_planq q;
static struct mlip_io_config io_cfg;
static struct mlip_ctl_io io_in;
static uint64_t period;
static uint32_t prog = 1;
/* CiA 402 drives (setup_drives): enabled, following each setpoint at once;
 * a fault reported for one period; the exit request (a signal) */
static int drives;
static struct mlip_ctl_drive_fault fault_next;
static int exit_req;
static uint32_t plan_fault;  /* the programs the planning thread refused (a count, as mlip-rt's) */
static uint32_t missed_next; /* deadlines missed before the next period */
static int unsent_next;      /* the last period's frames withheld (a late send) */
static struct mlip_can_config can_cia402 = {"cia402", 1000000, 5000000, 0x080,
                                            0x200,    0x300,   0x400,   0x180};

static void curve_at(double u, double *x)
{
	x[0] = R * sin(u);
	x[1] = R * (1.0 - cos(u));
}

/* ---- the producer: the planning thread's work, in line --------------------- */

static struct {
	double u, t, in[2], last[2];
	int pending, finished, fail;
} f;

static void feed_init(void)
{
	memset(&f, 0, sizeof(f));
	struct mlip_path_limits lim = {0};
	lim.n = 2;
	for (int k = 0; k < 2; k++) {
		lim.accel[k] = 0.98 * ACC;
		lim.jerk[k] = 0.95 * JERK;
	}
	lim.vmax = 0.995 * V;
	lim.a_brake[0] = 900.0;
	lim.a_brake[1] = 300.0;
	lim.n_brake = 2;
	lim.period = T;
	double start[2];
	curve_at(0.0, start);
	f.fail |= mlip_pathrun_init(&pr, &lim, 1e-3, 3000, start) != 0;
	mlip_planq_init(&q, &pr);
}

/* An input point, the end, or one planned period (mlip_planq_produce's
 * result; 4: input). */
static int unit(void)
{
	if (f.pending) {
		int r = mlip_pathrun_push(&pr, f.in);
		f.fail |= r < 0;
		if (r != 1) {
			f.pending = 0;
			return 4;
		}
	} else if (!f.finished) {
		if (f.u >= U_END) {
			f.fail |= mlip_pathrun_finish(&pr) != 0;
			f.finished = 1;
			return 4;
		}
		f.t += T;
		f.u = fmin(U_END, f.u + fmin(V, ACC * f.t) * T / R);
		curve_at(f.u, f.in);
		/* the record its motion belongs to (a block is BLOCK_U of arc)
		 * and the last one completed, as the plan's controller tags it */
		int b = (int)ceil(f.u / BLOCK_U);
		pr.tag_in = (struct mlip_pathrun_tag){(uint64_t)b, (uint64_t)b - 1, LINE(b),
		                                      LINE(b - 1), 0.0};
		memcpy(f.last, f.in, sizeof(f.in));
		f.pending = 1;
		return 4;
	}
	int r = mlip_planq_produce(&q, &pr);
	f.fail |= r < 0 || r == 3;
	return r;
}

/* Up to two planned periods per consumer period: it runs ahead. */
static void produce_some(void)
{
	int planned = 0;
	for (int i = 0; i < 2 * MLIP_PATHRUN_CAP && planned < 2 && !f.fail; i++) {
		int r = unit();
		if (r == 0 || r == 2) {
			break;
		}
		planned += r == 1;
	}
	assert_int_equal(f.fail, 0);
}

/* ---- the setpoints' physics ---------------------------------------------- */

static struct {
	double x[4][2];
	long n;
	double max_j, max_a, max_off, max_v;
} chk;

static void check_init(void)
{
	memset(&chk, 0, sizeof(chk));
	chk.n = 3; /* at rest at the origin before the start */
}

/* From here on: the maxima again, the samples kept (differences across). */
static void check_reset(void)
{
	chk.max_j = chk.max_a = chk.max_off = chk.max_v = 0.0;
}

static void check_point(const double *x)
{
	memmove(chk.x[1], chk.x[0], sizeof(chk.x[0]) * 3);
	memcpy(chk.x[0], x, sizeof(chk.x[0]));
	chk.n++;
	double v2 = 0.0;
	for (int k = 0; k < 2; k++) {
		double j = chk.x[0][k] - 3 * chk.x[1][k] + 3 * chk.x[2][k] - chk.x[3][k];
		double a = chk.x[0][k] - 2 * chk.x[1][k] + chk.x[2][k];
		double v = chk.x[0][k] - chk.x[1][k];
		chk.max_j = fmax(chk.max_j, fabs(j) / (T * T * T));
		chk.max_a = fmax(chk.max_a, fabs(a) / (T * T));
		v2 += v * v;
	}
	chk.max_v = fmax(chk.max_v, sqrt(v2) / T);
	double r = hypot(x[0], x[1] - R);
	chk.max_off = fmax(chk.max_off, fabs(r - R));
}

static void check_limits(void)
{
	assert_true(chk.max_j <= JERK * (1.0 + 1e-6));
	assert_true(chk.max_a <= ACC * (1.0 + 1e-6));
	assert_true(chk.max_off <= PATH_TOL);
}

/* ---- the controller -------------------------------------------------------- */

static int setup_opts(const struct mlip_io_config *io)
{
	memset(&mach, 0, sizeof(mach));
	mach.n_axes = 2;
	mach.max_feed_mm_s = 200.0;
	mach.max_rot_feed_deg_s = 360.0;
	mach.tolerance_mm = 0.01;
	mach.period_s = T;
	for (int k = 0; k < 2; k++) {
		mach.axis[k].letter = "XY"[k];
		mach.axis[k].kind = MLIP_AXIS_LINEAR;
		mach.axis[k].max_accel = ACC;
		mach.axis[k].max_jerk = JERK;
		mach.axis[k].max_vel = 200.0;
		mach.axis[k].min_limit = -1000.0;
		mach.axis[k].max_limit = 1000.0;
		mach.axis[k].can_node = drives ? k + 1 : 0;
		mach.axis[k].counts_per_unit = drives ? 1000.0 : 0.0;
	}
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT,
	                          .lookahead = 16,
	                          .io = io,
	                          .can = drives ? &can_cia402 : NULL,
	                          .drives = drives,
	                          .drive_state_periods = 50};
	memset(&fault_next, 0, sizeof(fault_next));
	missed_next = 0;
	unsent_next = 0;
	plan_fault = 0;
	memset(&out, 0, sizeof(out));
	exit_req = 0;
	if (mlip_ctl_init(&ctl, &planner, &mach, &o) != MLIP_OK) {
		return -1;
	}
	period = 0;
	prog++;
	memset(&io_in, 0, sizeof(io_in));
	io_in.known = io != NULL ? io->mapped : 0;
	feed_init();
	check_init();
	return f.fail ? -1 : 0;
}

static int setup(void **state)
{
	(void)state;
	drives = 0;
	return setup_opts(NULL);
}

static int setup_drives(void **state)
{
	(void)state;
	drives = 1;
	return setup_opts(NULL);
}

#define BIT(fn) (1u << (fn))

/* an E-stop input mapped (no drives: the controller stops on the path) */
static int setup_io(void **state)
{
	(void)state;
	memset(&io_cfg, 0, sizeof(io_cfg));
	io_cfg.node = 10;
	io_cfg.in_bytes = 1;
	struct mlip_io_bit *b = &io_cfg.in[MLIP_IN_ESTOP];
	b->node = 10;
	b->index = 0x6000;
	b->sub = 1;
	b->active_low = 1;
	io_cfg.mapped = BIT(MLIP_IN_ESTOP);
	return setup_opts(&io_cfg);
}

/* One period: the producer's share, then the controller with a command
 * (op 0: none). Its result. */
static int32_t tick(uint32_t op, int32_t arg)
{
	produce_some();
	struct mlip_ring_cmd cmd = {.seq = 2, .op = op, .arg = arg};
	struct mlip_ctl_in in = {
	    .period = period++, .feeder_alive = 1, .plan = &q, .plan_prog = prog, .io = io_in};
	in.cmd = op ? &cmd : NULL;
	in.exit_request = exit_req;
	in.plan_fault = plan_fault;
	in.missed = missed_next;
	in.unsent = unsent_next;
	missed_next = 0;
	unsent_next = 0;
	for (int k = 0; k < 2 && drives; k++) {
		/* enabled (quick stop active in an E-stop), at the last setpoint */
		in.drives.sw[k] = out.status.drive_power == MLIP_POWER_QUICK_STOP ? 0x0217 : 0x0237;
		in.drives.pos_actual[k] = out.pos[k];
		in.drives.tpdo_period[k] = period > 1 ? period - 2 : UINT64_MAX;
	}
	in.drives.actual_mask = drives ? 3u : 0u;
	in.drives.fault = fault_next;
	memset(&fault_next, 0, sizeof(fault_next));
	mlip_ctl_period(&ctl, &in, &out);
	check_point(out.pos);
	return out.cmd_result;
}

/* Periods until the state is s (or n periods): how many. */
static long until(uint32_t s, long n)
{
	long k = 0;
	while (out.status.state != s && k < n) {
		tick(0, 0);
		k++;
	}
	assert_int_equal(out.status.state, s);
	return k;
}

/* The queue's setpoints alone (a consumer without a controller). */
static double ref[MAX_PERIODS][2];

static long reference(void)
{
	feed_init();
	long n = 0;
	int mode = MLIP_PLANQ_WAIT;
	while (mode != MLIP_PLANQ_DONE && n < MAX_PERIODS) {
		produce_some();
		mode = mlip_planq_step(&q, 0, ref[n++]);
		assert_true(mode >= 0);
	}
	assert_int_equal(mode, MLIP_PLANQ_DONE);
	feed_init();
	return n;
}

/* The program runs to its last point, its setpoints the queue's to the
 * bit, inside A and J; it ends in IDLE (END) and does not start again. */
static void test_runs_to_end(void **state)
{
	(void)state;
	long n = reference();
	tick(0, 0);
	assert_int_equal(out.status.state, MLIP_STATE_RUNNING);
	assert_int_equal(out.status.reason, MLIP_WHY_START);
	long k = 0;
	for (; out.status.state == MLIP_STATE_RUNNING && k < n; k++) {
		if (memcmp(out.pos, ref[k], sizeof(ref[k])) != 0) {
			print_message("k %ld: %.17g %.17g vs %.17g %.17g\n", k, out.pos[0],
			              out.pos[1], ref[k][0], ref[k][1]);
		}
		assert_memory_equal(out.pos, ref[k], sizeof(ref[k]));
		tick(0, 0);
	}
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_int_equal(k + 1, n); /* the END in the period of the last entry */
	assert_memory_equal(out.pos, f.last, sizeof(f.last));
	assert_null(ctl.ext.q);
	check_limits();
	assert_true(chk.max_j >= 0.5 * JERK && chk.max_a >= 0.3 * ACC);
	assert_true(chk.max_v >= 0.9 * V && chk.max_v <= V);
	for (int i = 0; i < 50; i++) {
		tick(0, 0); /* the same program number: never again */
	}
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	assert_memory_equal(out.pos, f.last, sizeof(f.last));
	print_message("%ld periods, J %.4f, A %.4f, v %.2f mm/s, off %.1e mm\n", n,
	              chk.max_j / JERK, chk.max_a / ACC, chk.max_v, chk.max_off);
}

/* Until the speed is at least v (mm/s, the status's). */
static void until_speed(double v)
{
	for (long k = 0; k < 2000 && out.status.speed_mm_s < v; k++) {
		tick(0, 0);
	}
	assert_true(out.status.speed_mm_s >= v);
}

/* Braking from the period it arrives to rest: the physics of that run
 * alone, the periods it took. */
static long brake_to(uint32_t s)
{
	check_reset();
	long k = until(s, STOP_PERIODS);
	assert_true(k > 10);
	check_limits();
	assert_true(chk.max_j >= 0.5 * JERK && chk.max_a >= 0.3 * ACC);
	return k;
}

/* n periods on, the setpoint stays where it is, the state s: the point
 * the braking run reached. */
static void stays(int n, uint32_t s, double *at)
{
	memcpy(at, out.pos, sizeof(out.pos[0]) * 2);
	for (int i = 0; i < n; i++) {
		tick(0, 0);
		assert_memory_equal(out.pos, at, sizeof(out.pos[0]) * 2);
	}
	assert_int_equal(out.status.state, s);
	assert_true(fabs(hypot(at[0], at[1] - R) - R) <= PATH_TOL); /* on the path */
}

/* The braking run of a fault or an E-stop, to rest where the program is
 * dropped: inside A and J (its samples alone); the periods it took. */
static long brake_dropped(void)
{
	check_reset();
	long k = 0;
	for (; ctl.ext.q != NULL && k < STOP_PERIODS; k++) {
		tick(0, 0);
	}
	assert_null(ctl.ext.q);
	assert_true(k > 10);
	check_limits();
	return k;
}

/* A hold mid-move: the braking run from that period, inside A and J, to
 * rest (HELD, HOLD) within STOP_PERIODS; the point stays while held;
 * resumed, the program ends on its last point. */
static void test_hold(void **state)
{
	(void)state;
	until_speed(0.9 * V);
	double before[2];
	memcpy(before, out.pos, sizeof(before));
	assert_int_equal(tick(MLIP_CMD_HOLD, 0), MLIP_OK);
	assert_true(memcmp(before, out.pos, sizeof(before)) != 0); /* still moving */
	check_reset();
	long k = until(MLIP_STATE_HELD, STOP_PERIODS);
	assert_true(k > 10);
	check_limits();
	assert_true(chk.max_j >= 0.5 * JERK && chk.max_a >= 0.3 * ACC);
	assert_int_equal(out.status.reason, MLIP_WHY_HOLD);
	assert_true(out.status.stops == 1 && out.status.stop_nm > 0);
	double held[2];
	stays(200, MLIP_STATE_HELD, held);
	assert_int_equal(tick(MLIP_CMD_RESUME, 0), MLIP_OK);
	until(MLIP_STATE_RUNNING, 50);
	assert_int_equal(out.status.reason, MLIP_WHY_RESUME);
	until(MLIP_STATE_IDLE, MAX_PERIODS);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_memory_equal(out.pos, f.last, sizeof(f.last));
	check_limits();
	print_message("hold: rest after %ld periods, %.3f mm\n", k,
	              (double)out.status.stop_nm * 1e-6);
}

/* mlip-ctl stop mid-move: STOPPING in that period, the braking run to
 * rest, IDLE (STOP) on the path; the program does not start again. */
static void test_stop(void **state)
{
	(void)state;
	until_speed(0.9 * V);
	tick(MLIP_CMD_STOP, 0);
	assert_int_equal(out.status.state, MLIP_STATE_STOPPING);
	long k = brake_to(MLIP_STATE_IDLE);
	assert_int_equal(out.status.reason, MLIP_WHY_STOP);
	assert_null(ctl.ext.q);
	double rest[2];
	stays(200, MLIP_STATE_IDLE, rest);
	print_message("stop: rest after %ld periods\n", k);
}

/* The position's arc on the circle (the path within PATH_TOL of it). */
static double u_now(void)
{
	double u = atan2(out.pos[0], R - out.pos[1]);
	return u < -1.0 ? u + 2.0 * M_PI : u; /* the arc goes past pi */
}

/* The status names the block the position lies in: exec_seq never goes
 * back, the position within that block's arc (one input step either
 * side), its line; every block is named in turn, and the END is the
 * END's record (the producer's end_seq), as a program of records'. */
static void test_exec_follows_the_blocks(void **state)
{
	(void)state;
	uint64_t last = 0;
	int named = 0;
	long k = 0;
	q.end_seq = BLOCKS + 1; /* the producer's, before the last entry */
	q.end_line = LINE(BLOCKS + 1);
	tick(0, 0);
	for (; out.status.state == MLIP_STATE_RUNNING && k < MAX_PERIODS; k++) {
		uint64_t e = out.status.exec_seq;
		double u = u_now();
		assert_true(e >= last);
		named += e != last;
		last = e;
		if (e == 0) {
			assert_true(u <= STEP_U); /* not yet in the first piece */
		} else {
			assert_true(e <= BLOCKS);
			assert_int_equal(out.status.exec_line, LINE(e));
			if (!(u >= (double)(e - 1) * BLOCK_U - STEP_U &&
			      u <= e * BLOCK_U + STEP_U)) {
				print_message("k %ld: u %.6f in block %llu?\n", k, u,
				              (unsigned long long)e);
			}
			assert_true(u >= (double)(e - 1) * BLOCK_U - STEP_U);
			assert_true(u <= (double)e * BLOCK_U + STEP_U);
		}
		tick(0, 0);
	}
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_int_equal(named, BLOCKS);
	assert_int_equal(out.status.exec_seq, BLOCKS + 1); /* the END's */
	assert_int_equal(out.status.exec_line, LINE(BLOCKS + 1));
	assert_int_equal(out.status.reason_seq, BLOCKS + 1);
}

/* A stop mid-program: while braking the status names the block the
 * position lies in; at rest the last block completed, which the position
 * has passed (within an input step), the next one not (so restarting from
 * it skips no motion). A queue continuing from any other record is
 * refused (as a program of records); one continuing from the next passes
 * that check (this one then fails on its start point, another check). */
static void test_stop_names_the_block_to_resume(void **state)
{
	(void)state;
	while (out.status.exec_seq < BLOCKS / 2) {
		tick(0, 0);
	}
	tick(MLIP_CMD_STOP, 0);
	uint64_t braking = out.status.exec_seq;
	brake_to(MLIP_STATE_IDLE);
	uint64_t done = out.status.exec_seq;
	double u = u_now();
	print_message("stop: in block %llu, at rest at u %.4f, done %llu\n",
	              (unsigned long long)braking, u, (unsigned long long)done);
	assert_true(done >= braking - 1 && done <= braking);
	assert_true(done >= 1 && done < BLOCKS);
	assert_int_equal(out.status.exec_line, LINE(done));
	assert_true(u >= (double)done * BLOCK_U - STEP_U);
	assert_true(u <= (double)(done + 1) * BLOCK_U + STEP_U);
	for (int next = 0; next < 2; next++) {
		feed_init();
		q.first_seq = done + (next ? 1 : 3);
		prog++;
		long refused = ctl.counts.refused;
		tick(0, 0);
		assert_int_equal(out.status.state, MLIP_STATE_IDLE);
		assert_int_equal(ctl.counts.refused, refused + 1);
		assert_int_equal(out.n_events, 1);
		assert_int_equal(out.events[0].kind, MLIP_EV_REFUSED);
		/* the wrong record named, or (the right one) the start point */
		assert_int_equal(out.events[0].r.why, next ? MLIP_WHY_BAD_RECORD : MLIP_WHY_NONE);
		assert_int_equal(out.events[0].r.seq, next ? 0 : done + 3);
		assert_int_equal(out.status.exec_seq, done);
	}
}

/* The E-stop input with a resume in the same period: the E-stop wins (the
 * resume refused), the braking run on the path (no drives to quick stop),
 * the program dropped at rest; the input released, still nothing moves. */
static void test_estop_wins(void **state)
{
	(void)state;
	until_speed(0.9 * V);
	io_in.active = BIT(MLIP_IN_ESTOP);
	assert_int_not_equal(tick(MLIP_CMD_RESUME, 0), MLIP_OK);
	assert_int_equal(out.status.state, MLIP_STATE_ESTOP);
	assert_int_equal(out.status.reason, MLIP_WHY_ESTOP);
	long k = brake_dropped();
	assert_true(chk.max_j >= 0.5 * JERK);
	io_in.active = 0;
	double rest[2];
	stays(100, MLIP_STATE_ESTOP, rest);
	print_message("E-stop: rest after %ld periods, J %.4f, A %.4f\n", k, chk.max_j / JERK,
	              chk.max_a / ACC);
}

/* Override 50 % mid-move: the speed comes down to half the plan's cap
 * (the chord's speed by differences, within 1e-3) and the program ends. */
static void test_override(void **state)
{
	(void)state;
	until_speed(0.9 * V);
	assert_int_equal(tick(MLIP_CMD_OVERRIDE, 50), MLIP_OK);
	for (int i = 0; i < STOP_PERIODS; i++) {
		tick(0, 0);
	}
	assert_int_equal(out.status.state, MLIP_STATE_RUNNING);
	check_reset();
	until(MLIP_STATE_IDLE, MAX_PERIODS);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_true(chk.max_v <= 0.5 * 0.995 * V * (1.0 + 1e-3));
	assert_true(chk.max_v >= 0.45 * V);
	assert_memory_equal(out.pos, f.last, sizeof(f.last));
}

/* FAULT with reason why in this period: every axis on the queue's braking
 * run inside A and J, the program dropped at rest, the point held. */
static void faults_on_the_run(uint32_t why, const char *what)
{
	uint64_t at = out.status.exec_seq;
	tick(0, 0);
	assert_int_equal(out.status.state, MLIP_STATE_FAULT);
	assert_int_equal(out.status.reason, why);
	/* the block it came in (that period's, one on at most) */
	assert_true(at >= 1 && out.status.reason_seq >= at && out.status.reason_seq <= at + 1);
	assert_int_equal(out.status.reason_line, LINE(out.status.reason_seq));
	long k = brake_dropped();
	assert_true(chk.max_j >= 0.5 * JERK && chk.max_a >= 0.3 * ACC);
	double rest[2];
	stays(100, MLIP_STATE_FAULT, rest);
	print_message("%s: rest after %ld periods\n", what, k);
}

/* A drive fault mid-move (its node named). */
static void test_drive_fault(void **state)
{
	(void)state;
	until_speed(0.9 * V);
	fault_next = (struct mlip_ctl_drive_fault){.event = MLIP_DRIVE_FAULT_BIT, .node = 2};
	faults_on_the_run(MLIP_WHY_DRIVE, "drive fault");
	assert_int_equal(out.status.reason_node, 2);
}

/* The planning thread refuses the plan mid-move (in->plan_fault counts). */
static void test_plan_refused(void **state)
{
	(void)state;
	until_speed(0.9 * V);
	plan_fault = 1;
	faults_on_the_run(MLIP_WHY_PLAN_REFUSED, "plan refused");
	plan_fault = 0;
}

/* A refused plan is a fault on the path, left as every such fault is by a
 * reset after an E-stop (a reset alone leaves a quick stop only). The
 * refused program, published but not started, never starts after it (it
 * did: its queue ran once the controller was idle); the next program runs
 * to its end; a later refusal faults again (in->plan_fault was a flag seen
 * once: the second went unheard). */
static void test_plan_refused_left_by_a_reset(void **state)
{
	(void)state;
	plan_fault = 1;
	tick(0, 0);
	assert_int_equal(out.status.state, MLIP_STATE_FAULT);
	assert_int_equal(out.status.reason, MLIP_WHY_PLAN_REFUSED);
	assert_null(ctl.ext.q);
	assert_int_not_equal(tick(MLIP_CMD_RESET, 0), MLIP_OK);
	io_in.active = BIT(MLIP_IN_ESTOP);
	tick(0, 0);
	assert_int_equal(out.status.state, MLIP_STATE_ESTOP);
	io_in.active = 0;
	tick(0, 0);
	assert_int_equal(tick(MLIP_CMD_RESET, 0), MLIP_OK);
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	for (int i = 0; i < 200; i++) {
		tick(0, 0);
		assert_int_equal(out.status.state, MLIP_STATE_IDLE);
		assert_true(out.pos[0] == 0.0 && out.pos[1] == 0.0);
	}
	assert_null(ctl.ext.q);
	/* the next program (a new number, as the thread publishes it) */
	prog++;
	feed_init();
	check_init();
	tick(0, 0);
	assert_int_equal(out.status.state, MLIP_STATE_RUNNING);
	assert_int_equal(out.status.reason, MLIP_WHY_START);
	until(MLIP_STATE_IDLE, MAX_PERIODS);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_memory_equal(out.pos, f.last, sizeof(f.last));
	check_limits();
	plan_fault = 2;
	tick(0, 0);
	assert_int_equal(out.status.state, MLIP_STATE_FAULT);
	assert_int_equal(out.status.reason, MLIP_WHY_PLAN_REFUSED);
	assert_memory_equal(out.pos, f.last, sizeof(f.last));
}

/* The E-stop with drives: quick stop in that very period, the program
 * dropped at once, the setpoint where the drives are (as today). */
static void test_estop_drives(void **state)
{
	(void)state;
	until_speed(0.9 * V);
	io_in.active = BIT(MLIP_IN_ESTOP);
	tick(0, 0);
	assert_int_equal(out.status.state, MLIP_STATE_ESTOP);
	assert_int_equal(out.status.drive_power, MLIP_POWER_QUICK_STOP);
	assert_null(ctl.ext.q);
}

/* An exit request (a signal to mlip-rt) mid-move: STOPPING (EXIT), the
 * braking run, IDLE at rest, then done once the drives are disabled. */
static void test_exit(void **state)
{
	(void)state;
	until_speed(0.9 * V);
	exit_req = 1;
	tick(0, 0);
	assert_int_equal(out.status.state, MLIP_STATE_STOPPING);
	assert_int_equal(out.status.reason, MLIP_WHY_EXIT);
	brake_to(MLIP_STATE_IDLE);
	assert_false(out.done);
	for (long k = 0; k < 2000 && !out.done; k++) {
		tick(0, 0);
	}
	assert_true(out.done);
	assert_int_equal(out.status.drive_power, MLIP_POWER_OFF);
}

/* The drives stood at x (a stall): the samples from rest there. */
static void check_rest_at(const double *x)
{
	for (int i = 0; i < 4; i++) {
		memcpy(chk.x[i], x, sizeof(chk.x[0]));
	}
	check_reset();
}

/* A stall (more missed periods than allowed) mid-move, the drives standing
 * at the last setpoint meanwhile: HELD (STALL) in that period, at that
 * setpoint to the bit (never a step from where the drives stood), held
 * until resumed; then from rest there inside A and J (its samples from
 * rest), on the path, the program ends on its last point. Frames
 * withheld (a stall after the period's work): at the setpoint before.
 * A stall during a stop ends the stop where the drives stood. */
static void test_stall(void **state)
{
	(void)state;
	until_speed(0.9 * V);
	double sent[2], held[2];
	memcpy(sent, out.pos, sizeof(sent));
	missed_next = 10;
	tick(0, 0);
	assert_int_equal(out.status.state, MLIP_STATE_HELD);
	assert_int_equal(out.status.reason, MLIP_WHY_STALL);
	assert_memory_equal(out.pos, sent, sizeof(sent));
	assert_true(out.status.speed_mm_s == 0.0);
	check_rest_at(sent);
	stays(100, MLIP_STATE_HELD, held);
	assert_memory_equal(held, sent, sizeof(sent));
	assert_int_equal(tick(MLIP_CMD_RESUME, 0), MLIP_OK);
	until(MLIP_STATE_RUNNING, 50);
	until_speed(0.9 * V); /* it moves on at the plan's speed again */
	check_limits();
	assert_true(chk.max_j >= 0.5 * JERK && chk.max_a >= 0.3 * ACC);
	until(MLIP_STATE_IDLE, MAX_PERIODS);
	check_limits();
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_memory_equal(out.pos, f.last, sizeof(f.last));

	/* a stall between a period's work and its send (its frames withheld):
	 * the same, at the setpoint before it, the last the drives got */
	assert_int_equal(setup(NULL), 0);
	until_speed(0.9 * V);
	memcpy(sent, out.pos, sizeof(sent));
	tick(0, 0); /* its frames withheld */
	assert_true(fabs(out.pos[0] - sent[0]) + fabs(out.pos[1] - sent[1]) > 0.5 * V * T);
	unsent_next = 1;
	tick(0, 0);
	assert_int_equal(out.status.state, MLIP_STATE_HELD);
	assert_int_equal(out.status.reason, MLIP_WHY_STALL);
	assert_memory_equal(out.pos, sent, sizeof(sent));
	check_rest_at(sent);
	stays(100, MLIP_STATE_HELD, held);
	assert_int_equal(tick(MLIP_CMD_RESUME, 0), MLIP_OK);
	until(MLIP_STATE_IDLE, MAX_PERIODS);
	check_limits();
	assert_true(chk.max_j >= 0.5 * JERK && chk.max_a >= 0.3 * ACC);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_memory_equal(out.pos, f.last, sizeof(f.last));

	/* a stall during a stop: IDLE (STOP) at the last setpoint */
	assert_int_equal(setup(NULL), 0);
	until_speed(0.9 * V);
	tick(MLIP_CMD_STOP, 0);
	assert_int_equal(out.status.state, MLIP_STATE_STOPPING);
	for (int i = 0; i < 5; i++) {
		tick(0, 0); /* braking */
	}
	memcpy(sent, out.pos, sizeof(sent));
	missed_next = 10;
	tick(0, 0);
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	assert_int_equal(out.status.reason, MLIP_WHY_STOP);
	assert_memory_equal(out.pos, sent, sizeof(sent));
	stays(100, MLIP_STATE_IDLE, held);
}

static int setup_io_drives(void **state)
{
	drives = 1;
	return setup_io(state);
}

static int setup_io_alone(void **state)
{
	drives = 0;
	return setup_io(state);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test_setup(test_runs_to_end, setup),
	    cmocka_unit_test_setup(test_hold, setup),
	    cmocka_unit_test_setup(test_stop, setup),
	    cmocka_unit_test_setup(test_estop_wins, setup_io_alone),
	    cmocka_unit_test_setup(test_override, setup),
	    cmocka_unit_test_setup(test_drive_fault, setup_drives),
	    cmocka_unit_test_setup(test_estop_drives, setup_io_drives),
	    cmocka_unit_test_setup(test_exit, setup_drives),
	    cmocka_unit_test_setup(test_stall, setup),
	    cmocka_unit_test_setup(test_plan_refused, setup),
	    cmocka_unit_test_setup(test_exec_follows_the_blocks, setup),
	    cmocka_unit_test_setup(test_stop_names_the_block_to_resume, setup),
	    cmocka_unit_test_setup(test_plan_refused_left_by_a_reset, setup_io_alone),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
