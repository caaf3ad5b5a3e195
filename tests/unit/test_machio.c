/*
 * test_machio.c - the machine's outputs and probing (issue 19): the G-code
 * reader's M64/M65, M7/M8 on the module, G38.2..G38.5 (each refusal at its
 * line:col), the config's MIST / FLOOD / OUTPUT_n (each error at file
 * line:col), and the pure controller on the virtual clock: outputs switched
 * at rest and off in the period of a program's end, a stop, a fault or an
 * E-stop; a probe move stopped on the path at the acceleration limit from
 * the period its input changed, the position of that period latched.
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
#include "mlip/gcode/gcode.h"
#include "mlip/machine/config.h"

/* ---- the reader ------------------------------------------------------------ */

#include "gcode_run.h"

/* X Y Z (mm) and A (degrees), limits -500..500. */
static struct mlip_machine gr_machine(void)
{
	struct mlip_machine m;

	memset(&m, 0, sizeof m);
	m.n_axes = 4;
	for (int i = 0; i < 4; i++) {
		m.axis[i].letter = "XYZA"[i];
		m.axis[i].kind = i == 3 ? MLIP_AXIS_ROTARY : MLIP_AXIS_LINEAR;
		m.axis[i].max_accel = 1000;
		m.axis[i].max_vel = 200;
		m.axis[i].min_limit = -500;
		m.axis[i].max_limit = 500;
		m.axis[i].counts_per_unit = 1000;
	}
	m.max_feed_mm_s = 200;
	m.max_rot_feed_deg_s = 360;
	m.tolerance_mm = 0.01;
	m.period_s = 0.001;
	return m;
}

/* Coolant on the module (flood only), outputs P0 and P3, a probe. */
static struct mlip_gcode_io io_module(void)
{
	struct mlip_gcode_io io;

	memset(&io, 0, sizeof io);
	io.coolant = MLIP_IO_MODULE;
	io.coolant_outlets = MLIP_COOLANT_FLOOD;
	io.dout_mask = 0x9u;
	io.probe = 1;
	return io;
}

static void expect_ok(const struct mlip_gcode_io *io, const char *text, struct run *r)
{
	run(r, io, text);
	if (r->errors != 0) {
		fprintf(stderr, "for \"%s\": %u:%u \"%s\"\n", text, r->first_line, r->first_col,
		        r->first_msg);
		fail();
	}
}

/* The blocks as "m" (move), "C2" (coolant), "O+1" (output), "P1@X-10" ... */
static void events(const struct run *r, char *out, size_t len)
{
	size_t n = 0;

	out[0] = '\0';
	for (int i = 0; i < r->s.n && n < len; i++) {
		const struct mlip_block *b = &r->s.b[i];
		const char *sp = n ? " " : "";
		if (b->kind == MLIP_BLOCK_COOLANT) {
			n += (size_t)snprintf(out + n, len - n, "%sC%g", sp, b->value);
		} else if (b->kind == MLIP_BLOCK_OUTPUT) {
			n += (size_t)snprintf(out + n, len - n, "%sO%+g", sp, b->value);
		} else if (b->kind == MLIP_BLOCK_PROBE) {
			n += (size_t)snprintf(out + n, len - n, "%sP%g@%g,%g,%g", sp, b->value,
			                      b->target[0], b->target[1], b->target[2]);
		} else if (b->kind == MLIP_BLOCK_MOVE) {
			n += (size_t)snprintf(out + n, len - n, "%sm", sp);
		}
	}
}

static void test_outputs_words(void **state)
{
	struct mlip_gcode_io io = io_module();
	struct run *r = malloc(sizeof *r);
	char ev[512];

	(void)state;
	expect_ok(&io, "M8\nM64 P0\nG1 X1 F100\nM65 P3\nM9\nM64 P3\nM2\n", r);
	events(r, ev, sizeof ev);
	assert_string_equal(ev, "C2 O+1 m O-4 C0 O+4");
	expect_err(&io, "G1 X1 F100\nM65 P0 M64 P3\n", 2, 8, "one output word a line");
	expect_err(&io, "G1 X1 F100\nM64 P1\n", 2, 5,
	           "digital output 1 is not mapped ([IO] OUTPUT_1)");
	expect_err(&io, "G1 X1 F100\nM64\n", 2, 1, "M64 without P");
	expect_err(&io, "G1 X1 F100\nM64 P8\n", 2, 5, "a whole number 0..7");
	expect_err(&io, "G1 X1 F100\nM64 P0.5\n", 2, 5, "a whole number 0..7");
	/* M62/M63: with the next move, an OUTPUT beyond MLIP_DOUT_SYNC */
	expect_ok(&io, "G1 X1 F100\nM62 P0\nG1 X2\nM63 P3\nG1 X3\nM2\n", r);
	events(r, ev, sizeof ev);
	assert_string_equal(ev, "m O+17 m O-20 m");
	expect_err(&io, "G1 X1 F100\nM62 P1\n", 2, 5,
	           "digital output 1 is not mapped ([IO] OUTPUT_1)");
	expect_err(&io, "G1 X1 F100\nM63\n", 2, 1, "M63 without P");
	expect_err(&io, "G1 X1 F100\nM7\n", 2, 1, "no mist outlet ([COOLANT] MIST is not mapped)");
	io.coolant_outlets = MLIP_COOLANT_MIST;
	expect_err(&io, "G1 X1 F100\nM8\n", 2, 1, "no flood outlet");
	/* without the machine's I/O (a motion check): a notice */
	expect_ok(NULL, "G1 X1 F100\nM64 P5\n", r);
	free(r);
}

static void test_probe_words(void **state)
{
	struct mlip_gcode_io io = io_module();
	struct run *r = malloc(sizeof *r);
	char ev[512];

	(void)state;
	expect_ok(&io,
	          "G1 X1 F100\nG38.2 Z-10 F50\nG0 Z5\nG38.3 X-3 Z5 F60\nG0 X0 Z0\n"
	          "G38.4 Z-1\nG38.5 Z2\nG0 X1 Z3\nG91 G0 X1\nM2\n",
	          r);
	events(r, ev, sizeof ev);
	assert_string_equal(ev, "m P1@1,0,-10 m P0@-3,0,5 m P3@0,0,-1 P2@0,0,2 m m");
	/* the probe feed: F50 mm/min */
	assert_true(fabs(r->s.b[1].feed_mm_s - 50.0 / 60.0) < 1e-12);
	assert_int_equal(r->s.b[1].exact_stop, 1);
	/* bad input, each at its column */
	struct mlip_gcode_io none = io;
	none.probe = 0;
	expect_err(&none, "G1 X1 F100\nG38.2 Z-10\n", 2, 1, "no probe input ([IO] PROBE)");
	expect_err(NULL, "G1 X1 F100\nG38.2 Z-10\n", 2, 1, "needs the machine's config");
	expect_err(&io, "G1 X1 F100\nG38.2 X1\n", 2, 1, "to the current position");
	expect_err(&io, "G1 X1 F100\nG38.2\n", 2, 1, "without axis words");
	expect_err(&io, "G1 X1 F100\nG38.2 A10\n", 2, 7, "moves A: a probe moves linear axes");
	expect_err(&io, "G1 X1 F100\nG38.3 Z-1 A10\n", 2, 11, "moves A");
	expect_err(&io, "G38.2 Z-10\n", 1, 1, "G38.2 with no F");
	expect_err(&io, "G1 X1 F100\nG38.2 Z-600\n", 2, 7, "beyond soft limit");
	expect_err(&io, "G1 X1 F100\nG93 G38.2 Z-1 F2\n", 2, 5, "inverse time");
	expect_err(&io, "G1 X1 F100\nG1 G38.2 Z-1\n", 2, 4, "two motion codes");
	expect_err(&io, "G1 X1 F100\nG38.1 Z-1\n", 2, 1, "unsupported G code G38.1");
	/* after a probe the probed axes stand where it stopped them */
	expect_err(&io, "G1 X1 F100\nG38.2 Z-10\nG91 G0 Z5\n", 3, 8, "must give Z in absolute");
	expect_err(&io, "G1 X1 F100\nG38.2 Z-10\nG0 X5\n", 3, 1, "must give Z in absolute");
	expect_err(&io, "G1 X1 F100\nG38.2 Z-10\nG10 L20 P1 Z0\n", 3, 12, "G10 Z after the G38");
	expect_err(&io, "G1 X1 F100\nG38.2 Z-10\nG92 Z0\n", 3, 5, "G92 Z after the G38");
	expect_err(&io, "G1 X1 F100\nG38.2 Z-10\nG2 X2 Z0 I1\n", 3, 1, "an arc right after");
	expect_err(&io, "G1 X1 F100\nG38.2 Z-10\nG28\n", 3, 1, "G28 right after the G38");
	expect_err(&io, "G1 X1 F100\nG38.2 Z-10\nZ-5\n", 3, 1, "axis words after G38.2");
	/* a G10 L20 of another axis, and moves that give Z absolutely */
	expect_ok(&io, "G1 X1 F100\nG38.2 Z-10\nG10 L20 P1 X0\nG53 G0 Z0\nG91 G0 Z1\n", r);
	free(r);
}

/* ---- the config ------------------------------------------------------------ */

static const char base_ini[] = "[TRAJ]\nCOORDINATES = X Y Z\nMAX_LINEAR_VELOCITY = 200\n"
                               "CONTOUR_TOLERANCE = 0.01\n"
                               "[AXIS_X]\nMAX_VELOCITY = 200\nMAX_ACCELERATION = 1000\n"
                               "[AXIS_Y]\nMAX_VELOCITY = 200\nMAX_ACCELERATION = 1000\n"
                               "[AXIS_Z]\nMAX_VELOCITY = 200\nMAX_ACCELERATION = 1000\n"
                               "[IO]\nNODE = 10\nPROBE = 10 0x6000:1 3 HIGH\n";

static mlip_status parse_cfg(const char *tail, struct mlip_config *c, struct mlip_config_error *e)
{
	char text[2048];

	snprintf(text, sizeof text, "%s%s", base_ini, tail);
	mlip_config_defaults(c);
	return mlip_config_parse(c, text, strlen(text), e);
}

static void cfg_err(const char *tail, uint32_t line, uint32_t col, const char *part)
{
	struct mlip_config c;
	struct mlip_config_error e;
	mlip_status st = parse_cfg(tail, &c, &e);

	if (st == MLIP_OK || e.line != line || e.col != col || strstr(e.msg, part) == NULL) {
		fprintf(stderr, "for \"%s\": %d at %u:%u \"%s\"; expected %u:%u \"%s\"\n", tail, st,
		        e.line, e.col, e.msg, line, col, part);
		fail();
	}
}

static void test_config_outputs(void **state)
{
	struct mlip_config c;
	struct mlip_config_error e;

	(void)state;
	assert_int_equal(parse_cfg("OUTPUT_0 = 10 0x6200:1 2\nOUTPUT_7 = 10 0x6200:3 7 HIGH\n"
	                           "[COOLANT]\nTYPE = io\nMIST = 10 0x6200:1 0\n"
	                           "FLOOD = 10 0x6200:1 1\n",
	                           &c, &e),
	                 MLIP_OK);
	assert_int_equal(c.io.coolant, MLIP_IO_MODULE);
	assert_int_equal(c.io.coolant_outlets, MLIP_COOLANT_MIST | MLIP_COOLANT_FLOOD);
	assert_int_equal(c.io.dout_mask, 0x81u);
	assert_int_equal(c.io.probe, 1);
	assert_int_equal(c.inputs.out_bytes, 3);
	assert_int_equal(c.inputs.out[MLIP_OUT_DOUT0 + 7].sub, 3);
	assert_int_equal(c.inputs.out[MLIP_OUT_DOUT0 + 7].bit, 7);
	assert_int_equal(c.inputs.out[MLIP_OUT_FLOOD].bit, 1);
	/* base_ini has 16 lines: the tail starts at line 17 */
	cfg_err("OUTPUT_0 = 11 0x6200:1 2\n", 17, 1,
	        "node 11 is not the I/O module ([IO] NODE 10)");
	cfg_err("OUTPUT_0 = 10 0x6200:9 2\n", 17, 15, "outputs are 0x6200:1..8");
	cfg_err("OUTPUT_0 = 10 0x6000:1 2\n", 17, 15, "outputs are 0x6200:1..8");
	cfg_err("OUTPUT_0 = 10 0x6200:1 8\n", 17, 24, "BIT must be 0..7");
	cfg_err("OUTPUT_0 = 10 0x6200:1 2 LOW\n", 17, 26, "outputs are active high");
	cfg_err("OUTPUT_0 = 10 0x6200:1\n", 17, 23, "must be NODE 0x6200:SUB BIT");
	cfg_err("OUTPUT_0 = 10 0x6200:1 2\nOUTPUT_1 = 10 0x6200:1 2\n", 18, 1,
	        "[IO] OUTPUT_1: output 0x6200:1 bit 2 is already [IO] OUTPUT_0");
	cfg_err("OUTPUT_3 = 10 0x6200:1 0\n[COOLANT]\nTYPE = io\nMIST = 10 0x6200:1 0\n", 20, 1,
	        "[COOLANT] MIST: output 0x6200:1 bit 0 is already [IO] OUTPUT_3");
	cfg_err("OUTPUT_8 = 10 0x6200:1 0\n", 17, 1, "unknown key OUTPUT_8 in [IO]");
	cfg_err("[COOLANT]\nTYPE = io\n", 18, 1, "TYPE = io needs MIST or FLOOD");
	cfg_err("[COOLANT]\nTYPE = manual\nMIST = 10 0x6200:1 0\n", 19, 1,
	        "switches coolant only with [COOLANT] TYPE = io");
	cfg_err("[COOLANT]\nTYPE = pump\n", 18, 8, "must be none, manual or io");
	/* [PROBE] SOURCE: the module's input (default) or the drives' touch probe */
	assert_int_equal(parse_cfg("", &c, &e), MLIP_OK);
	assert_int_equal(c.inputs.probe_source, MLIP_PROBE_SRC_IO);
	assert_int_equal(parse_cfg("[PROBE]\nSOURCE = drive\n", &c, &e), MLIP_OK);
	assert_int_equal(c.inputs.probe_source, MLIP_PROBE_SRC_DRIVE);
	assert_int_equal(c.io.probe, 1);
	cfg_err("[PROBE]\nSOURCE = laser\n", 18, 10, "SOURCE must be io");
	cfg_err("[PROBE]\nEDGE = 1\n", 18, 1, "unknown key EDGE in [PROBE]");
}

/* ---- the controller on the virtual clock ------------------------------------- */

#define CAP    64u
#define BIT(f) (1u << (f))

static struct mlip_machine mach;
static struct mlip_planner planner;
static struct mlip_ctl ctl;
static struct mlip_ctl_out out;
static struct mlip_ring *ring;
static struct mlip_ring_port rx;
static void *mem;
static uint64_t period;
static uint32_t stop_count;
static struct mlip_ctl_io io_in;
static struct mlip_io_config io_cfg;
/* the probe's surface along X: the input is on from the period after the
 * setpoint reached it (the input frame of a module that reads the axis'
 * position one period late); NAN: none */
static double surface_x;
static int surface_away; /* the input is on below the surface (G38.4/.5) */
/* every setpoint since the last reset, for the acceleration check */
static double trace_x[20000], trace_y[20000];
static int n_trace;
/* [PROBE] SOURCE = drive: two drives with touch probe 1 wired to the probe
 * that touches surface_x, modelled with CiA 402's timing: the RPDO of
 * period j (0x60B8, target) applied at the SYNC of period j + 1, the TPDOs
 * of that SYNC sampled before it; each drive moves linearly from one target
 * to the next between SYNCs and latches where it is at the instant X
 * crosses the surface (not a position of a SYNC) */
static int feeder_mdi;       /* the records are MDI lines (mlip-ctl mdi) */
static uint32_t feeder_base; /* the stop counter when the feeder began */
static int tp_model;
static int tp_deaf;             /* the drives never answer (a timeout) */
static int tp_edge_at_arm;      /* the probe switches as the latch is switched on */
static uint16_t fn_hist[20000]; /* 0x60B8 sent in each period */
static uint16_t tp_fn, tp_st;   /* in force, status */
static double tp_lat[2];        /* latched (the edge the function enables) */
static uint32_t tp_latches;

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
		mach.axis[k].max_accel = 1000.0;
		mach.axis[k].max_vel = 200.0;
		mach.axis[k].min_limit = -1000.0;
		mach.axis[k].max_limit = 1000.0;
		mach.axis[k].counts_per_unit = 1000.0;
	}
	memset(&io_cfg, 0, sizeof(io_cfg));
	io_cfg.node = 10;
	io_cfg.in_bytes = 1;
	io_cfg.in[MLIP_IN_ESTOP] = (struct mlip_io_bit){10, 1, 0x6000, 0, 1, 1};
	io_cfg.in[MLIP_IN_PROBE] = (struct mlip_io_bit){10, 1, 0x6000, 3, 0, 1};
	io_cfg.mapped = BIT(MLIP_IN_ESTOP) | BIT(MLIP_IN_PROBE);
	io_cfg.out[MLIP_OUT_MIST] = (struct mlip_io_out){1, 0, 1};
	io_cfg.out[MLIP_OUT_FLOOD] = (struct mlip_io_out){1, 1, 1};
	io_cfg.out[MLIP_OUT_DOUT0] = (struct mlip_io_out){1, 2, 1};
	io_cfg.out[MLIP_OUT_DOUT0 + 3] = (struct mlip_io_out){2, 7, 1};
	io_cfg.out_mapped = BIT(MLIP_OUT_MIST) | BIT(MLIP_OUT_FLOOD) | BIT(MLIP_OUT_DOUT0) |
	                    BIT(MLIP_OUT_DOUT0 + 3);
	io_cfg.out_bytes = 2;
	size_t bytes = mlip_ring_bytes(CAP);
	assert_int_equal(posix_memalign(&mem, MLIP_RING_LINE, bytes), 0);
	assert_int_equal(mlip_ring_format_machine(mem, bytes, CAP, &mach), MLIP_OK);
	assert_int_equal(mlip_ring_attach(mem, bytes, 2, &ring, NULL), MLIP_OK);
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT, .lookahead = 16, .io = &io_cfg};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
	assert_int_equal(mlip_ring_port_open(&rx, ring, 0), MLIP_OK);
	period = 0;
	stop_count = 0;
	memset(&io_in, 0, sizeof(io_in));
	io_in.known = io_cfg.mapped;
	io_in.active = 0; /* the E-stop input is active low: reads 1, off */
	surface_x = NAN;
	surface_away = 0;
	n_trace = 0;
	tp_model = tp_deaf = tp_edge_at_arm = 0;
	feeder_mdi = 0;
	tp_fn = tp_st = 0;
	tp_latches = 0;
	return 0;
}

/* The drives' touch probe instead of the module's input. */
static void use_drive_probe(void)
{
	io_cfg.probe_source = MLIP_PROBE_SRC_DRIVE;
	io_cfg.mapped &= ~BIT(MLIP_IN_PROBE);
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT, .lookahead = 16, .io = &io_cfg};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
	io_in.known = io_cfg.mapped;
	tp_model = 1;
}

/* Before period q: the TPDOs answering the SYNC of period q - 1, which
 * applied the RPDO of period q - 3 at the SYNC of q - 2 and moved to it. */
static void tp_drives(uint64_t q, struct mlip_ctl_in *in)
{
	for (int k = 0; k < 2; k++) {
		in->drives.tpdo_period[k] = UINT64_MAX;
		in->drives.tp_latch_period[k] = UINT64_MAX;
	}
	if (q < 4 || tp_deaf) {
		return;
	}
	uint16_t fn = fn_hist[q - 3];
	if (!(fn & 1u)) {
		tp_st = 0;
	} else if (!(tp_fn & 1u)) {
		tp_st = tp_edge_at_arm ? 3 : 1; /* switched on: armed, nothing stored */
	}
	tp_fn = fn;
	/* the move from the target of q - 4 to that of q - 3 */
	double a[2] = {trace_x[q - 4], trace_y[q - 4]}, b[2] = {trace_x[q - 3], trace_y[q - 3]};
	if (!isnan(surface_x) && (a[0] < surface_x) != (b[0] < surface_x) && b[0] != a[0]) {
		int positive = (b[0] >= surface_x) != surface_away; /* the probe goes on */
		uint16_t edge = positive ? 0x10 : 0x20, stored = positive ? 2 : 4;
		if ((fn & 1u) && (fn & edge) && !(tp_st & stored)) {
			double f = (surface_x - a[0]) / (b[0] - a[0]);
			for (int k = 0; k < 2; k++) {
				tp_lat[k] = a[k] + f * (b[k] - a[k]);
			}
			tp_st |= stored;
			tp_latches++;
		}
	}
	for (int k = 0; k < 2; k++) {
		in->drives.tpdo_period[k] = q - 1;
		in->drives.tp_latch_period[k] = q - 1;
		in->drives.tp_status[k] = tp_st;
		in->drives.tp_pos[k] = tp_lat[k];
		in->drives.tp_neg[k] = tp_lat[k];
	}
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
		struct mlip_ctl_in in = {.period = period++,
		                         .feeder_alive = 1,
		                         .stop_requests = stop_count,
		                         .feeder_mdi = feeder_mdi,
		                         .feeder_stop_base = feeder_base};
		if (tp_model) {
			tp_drives(in.period, &in);
		} else if (!isnan(surface_x)) {
			int past = out.pos[0] >= surface_x;
			io_in.active = (io_in.active & ~BIT(MLIP_IN_PROBE)) |
			               (past != surface_away ? BIT(MLIP_IN_PROBE) : 0u);
		}
		in.io = io_in;
		if (mlip_ring_port_view(&rx, &in.recs, &in.recs_corrupt) == MLIP_OK) {
			in.recs_corrupt = 0;
		}
		mlip_ctl_period(&ctl, &in, &out);
		assert_int_equal(mlip_ring_port_pop_n(&rx, out.taken), MLIP_OK);
		if (n_trace < 20000) {
			fn_hist[n_trace] = ctl.mio.tp_fn; /* what the RPDOs carry (out.frames) */
			trace_x[n_trace] = out.pos[0];
			trace_y[n_trace++] = out.pos[1];
		}
	}
}

static int until(uint32_t s, int n)
{
	for (int i = 1; i <= n; i++) {
		tick(1);
		if (out.status.state == s) {
			return i;
		}
	}
	fail_msg("state %s not reached in %d periods (now %s, %s)", mlip_ctl_state_name(s), n,
	         mlip_ctl_state_name(out.status.state), mlip_state_why_name(out.status.reason));
	return -1;
}

static void push_block(uint64_t seq, uint8_t kind, double x, double y, double feed, double value)
{
	struct mlip_block b = {
	    .kind = kind, .feed_mm_s = feed, .tol_mm = 0.01, .line = (uint32_t)seq + 1};
	b.target[0] = x;
	b.target[1] = y;
	b.value = value;
	b.exact_stop = kind == MLIP_BLOCK_PROBE;
	struct mlip_ring_rec rec;
	mlip_ring_rec_from_block(&rec, &b, seq);
	assert_int_equal(mlip_ring_push(ring, &rec), MLIP_OK);
}

static void end(uint64_t seq)
{
	struct mlip_ring_rec rec;
	mlip_ring_rec_end(&rec, seq, (uint32_t)seq + 1);
	assert_int_equal(mlip_ring_push(ring, &rec), MLIP_OK);
}

/* M8 M64 P0, a move, M65 P0, M64 P3, a move, END: each switch with the
 * machine at rest at the end of the move before it, in the period it is
 * taken; every output off in the period the program ends. */
static void test_outputs_at_rest_and_off_at_end(void **st)
{
	(void)st;
	push_block(1, MLIP_BLOCK_COOLANT, 0, 0, 0, MLIP_COOLANT_FLOOD);
	push_block(2, MLIP_BLOCK_OUTPUT, 0, 0, 0, 1);
	push_block(3, MLIP_BLOCK_MOVE, 10, 0, 50, 0);
	push_block(4, MLIP_BLOCK_OUTPUT, 0, 0, 0, -1);
	push_block(5, MLIP_BLOCK_OUTPUT, 0, 0, 0, 4);
	push_block(6, MLIP_BLOCK_MOVE, 10, 5, 50, 0);
	end(7);
	int on_at = -1, p0_off_at = -1, p3_on_at = -1, idle_at = -1;
	double x_at_p0_off = NAN, speed_at_p0_off = NAN;
	for (int i = 0; i < 5000 && idle_at < 0; i++) {
		uint8_t before0 = out.outputs[0], before1 = out.outputs[1];
		tick(1);
		if (on_at < 0 && (out.outputs[0] & 0x06) == 0x06) {
			on_at = i;
			assert_true(out.pos[0] == 0.0); /* before the first move */
		}
		if (p0_off_at < 0 && (before0 & 0x04) && !(out.outputs[0] & 0x04)) {
			p0_off_at = i;
			x_at_p0_off = out.pos[0];
			speed_at_p0_off = out.status.speed_mm_s;
		}
		if (p3_on_at < 0 && !(before1 & 0x80) && (out.outputs[1] & 0x80)) {
			p3_on_at = i;
		}
		if (out.status.state == MLIP_STATE_IDLE && out.status.reason == MLIP_WHY_END) {
			idle_at = i;
		}
	}
	assert_true(on_at >= 0 && p0_off_at > on_at && p3_on_at >= p0_off_at && idle_at > p3_on_at);
	assert_true(x_at_p0_off == 10.0 && speed_at_p0_off == 0.0); /* at rest at the end */
	assert_int_equal(out.status.coolant, 0);
	assert_int_equal(out.outputs[0], 0); /* the program's end: everything off */
	assert_int_equal(out.outputs[1], 0);
	assert_true(out.pos[1] == 5.0);
	print_message("[machio] outputs: M8+M64P0 in period %d, M65P0 %d periods after the "
	              "move's start, M64P3 %d, end %d\n",
	              on_at, p0_off_at, p3_on_at, idle_at);
}

/* A stop mid-move with coolant and an output on: both off in the stop's
 * own period (state stopping), the machine braking on the path. */
static void test_outputs_off_on_stop(void **st)
{
	(void)st;
	push_block(1, MLIP_BLOCK_COOLANT, 0, 0, 0, MLIP_COOLANT_MIST | MLIP_COOLANT_FLOOD);
	push_block(2, MLIP_BLOCK_OUTPUT, 0, 0, 0, 4);
	push_block(3, MLIP_BLOCK_MOVE, 100, 0, 100, 0);
	end(4);
	tick(300);
	assert_int_equal(out.status.state, MLIP_STATE_RUNNING);
	assert_int_equal(out.outputs[0], 0x03);
	assert_int_equal(out.outputs[1], 0x80);
	assert_int_equal(out.status.coolant, 3);
	assert_int_equal(out.status.outputs, 0x8003u);
	stop_count++;
	tick(1);
	assert_int_equal(out.status.state, MLIP_STATE_STOPPING);
	assert_true(out.status.speed_mm_s > 0.0); /* still braking */
	assert_int_equal(out.outputs[0], 0);
	assert_int_equal(out.outputs[1], 0);
	assert_int_equal(out.status.coolant, 0);
}

/* A bad record: a fault, everything off; an E-stop: the same. */
static void test_outputs_off_on_fault_and_estop(void **st)
{
	(void)st;
	push_block(1, MLIP_BLOCK_OUTPUT, 0, 0, 0, 1);
	push_block(2, MLIP_BLOCK_MOVE, 1, 0, 50, 0);
	push_block(3, MLIP_BLOCK_OUTPUT, 0, 0, 0, 2); /* output 1: not mapped */
	end(4);
	until(MLIP_STATE_FAULT, 5000);
	assert_int_equal(out.status.reason, MLIP_WHY_BAD_RECORD);
	assert_int_equal(out.status.reason_line, 4);
	assert_int_equal(out.outputs[0], 0);
	assert_true(out.pos[0] == 1.0);
	teardown(NULL);
	setup(NULL);
	push_block(1, MLIP_BLOCK_COOLANT, 0, 0, 0, MLIP_COOLANT_FLOOD);
	push_block(2, MLIP_BLOCK_MOVE, 100, 0, 100, 0);
	end(3);
	tick(200);
	assert_int_equal(out.outputs[0], 0x02);
	io_in.active |= BIT(MLIP_IN_ESTOP);
	tick(1);
	assert_int_equal(out.status.state, MLIP_STATE_ESTOP);
	assert_int_equal(out.outputs[0], 0);
}

/* MDI lines (mlip-ctl mdi: the feeder says so): M8 and M64 P0 stay on when
 * the lines are done (LinuxCNC: until M9/M65, a program's end, a stop); a
 * next MDI M7 adds mist to the flood; the next MDI M9 switches both off; a
 * stop at rest switches everything off; a program's end (not MDI) too. */
static void test_mdi_outputs_stay_on(void **st)
{
	(void)st;
	feeder_mdi = 1;
	push_block(1, MLIP_BLOCK_COOLANT, 0, 0, 0, MLIP_COOLANT_FLOOD);
	push_block(2, MLIP_BLOCK_OUTPUT, 0, 0, 0, 1);
	end(3);
	tick(1);
	until(MLIP_STATE_IDLE, 100);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	tick(10);
	assert_int_equal(out.status.coolant, MLIP_COOLANT_FLOOD);
	assert_int_equal(out.outputs[0], 0x06); /* flood (bit 1) and P0 (bit 2) */
	/* the next MDI M7 (its reader knows no flood): mist joins flood */
	push_block(1, MLIP_BLOCK_COOLANT, 0, 0, 0, MLIP_COOLANT_MIST);
	end(2);
	tick(1);
	until(MLIP_STATE_IDLE, 100);
	tick(2);
	assert_int_equal(out.status.coolant, MLIP_COOLANT_MIST | MLIP_COOLANT_FLOOD);
	assert_int_equal(out.outputs[0], 0x07);
	push_block(1, MLIP_BLOCK_COOLANT, 0, 0, 0, 0); /* M9 */
	end(2);
	tick(1);
	until(MLIP_STATE_IDLE, 100);
	tick(2);
	assert_int_equal(out.status.coolant, 0);
	assert_int_equal(out.outputs[0], 0x04); /* P0 stays */
	stop_count++;
	tick(2);
	assert_int_equal(out.outputs[0], 0); /* a stop: everything off */
	push_block(1, MLIP_BLOCK_COOLANT, 0, 0, 0, MLIP_COOLANT_FLOOD);
	end(2);
	feeder_mdi = 0; /* a program, begun after the stop */
	feeder_base = stop_count;
	tick(1);
	until(MLIP_STATE_IDLE, 100);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_int_equal(out.outputs[0], 0);
	assert_int_equal(out.status.coolant, 0);
}

/* M62 P0 between two moves with a stop between them, M63 P3 between two
 * moves through a corner: each output switches in the period whose
 * setpoint is the first of the move after it (not at rest before it). */
static void test_sync_outputs_with_the_next_move(void **st)
{
	(void)st;
	push_block(1, MLIP_BLOCK_MOVE, 5, 0, 50, 0);
	push_block(2, MLIP_BLOCK_OUTPUT, 0, 0, 0, 1 + MLIP_DOUT_SYNC); /* M62 P0 */
	push_block(3, MLIP_BLOCK_MOVE, 5, 5, 50, 0);
	push_block(4, MLIP_BLOCK_OUTPUT, 0, 0, 0, -(1 + MLIP_DOUT_SYNC)); /* M63 P0 */
	push_block(5, MLIP_BLOCK_MOVE, 10, 5, 50, 0);
	end(6);
	int on = -1, off = -1, y_moves = -1, x_moves = -1, idle = -1;
	for (int i = 0; i < 5000 && idle < 0; i++) {
		tick(1);
		if (y_moves < 0 && out.pos[1] > 0.0) {
			y_moves = i; /* the first setpoint with block 3's motion in it */
		}
		if (x_moves < 0 && out.pos[0] > 5.0) {
			x_moves = i; /* ... block 5's */
		}
		if (on < 0 && (out.outputs[0] & 0x04)) {
			on = i;
		}
		if (on >= 0 && off < 0 && !(out.outputs[0] & 0x04)) {
			off = i;
		}
		if (out.status.state == MLIP_STATE_IDLE && out.status.reason == MLIP_WHY_END) {
			idle = i;
		}
	}
	print_message("[machio] M62 P0: on in period %d (block 3's first setpoint: %d), M63 P0 "
	              "off in %d (block 5's first: %d), end %d\n",
	              on, y_moves, off, x_moves, idle);
	/* through the corners (blended, never at rest): in the period of the
	 * first setpoint with the next block's motion in it */
	assert_int_equal(on, y_moves);
	assert_int_equal(off, x_moves);
	assert_true(off < idle);
}

/* The largest |second difference| / T^2 of X and Y over the trace. */
static double max_accel(int from)
{
	double a = 0, T = mach.period_s;
	for (int i = from + 2; i < n_trace; i++) {
		for (int k = 0; k < 2; k++) {
			const double *t = k ? trace_y : trace_x;
			double d = fabs(t[i] - 2 * t[i - 1] + t[i - 2]) / (T * T);
			a = d > a ? d : a;
		}
	}
	return a;
}

/* G38.2 toward X = 20 at 600 mm/min, the surface at X = 7.3: the latched
 * position is the setpoint of the period the input came in (within one
 * period's travel past the surface), the machine stops on the path at the
 * acceleration limit within v^2/2A + vT of it, and the program goes on. */
static void test_probe_trips_and_stops_on_the_path(void **st)
{
	(void)st;
	double v = 10.0, A = 1000.0, T = mach.period_s, s = 7.3;
	surface_x = s;
	push_block(1, MLIP_BLOCK_MOVE, 0, 1e-3, 100, 0); /* Y is not probed: stays */
	push_block(2, MLIP_BLOCK_PROBE, 20, 1e-3, v, MLIP_PROBE_MUST_TRIP);
	push_block(3, MLIP_BLOCK_MOVE, 0, 1e-3, 100, 0);
	end(4);
	int trip_at = -1;
	double rest_x = NAN;
	for (int i = 0; i < 20000; i++) {
		tick(1);
		if (trip_at < 0 && out.status.probe_count == 1) {
			trip_at = i;
			rest_x = out.pos[0];
		}
		if (out.status.state == MLIP_STATE_IDLE && out.status.reason == MLIP_WHY_END) {
			break;
		}
	}
	assert_int_equal(out.status.state, MLIP_STATE_IDLE);
	assert_int_equal(out.status.probe_count, 1);
	assert_int_equal(out.status.probe_tripped, 1);
	assert_int_equal(out.status.probe_line, 3);
	double latched = out.status.probe_pos[0];
	/* past the surface by at most the travel of one period at the feed */
	assert_true(latched >= s && latched <= s + v * T * (1 + 1e-9));
	assert_true(out.status.probe_pos[1] == 1e-3);
	/* at rest within the braking distance (plus a period) past the latch */
	assert_true(rest_x > latched && rest_x <= latched + v * v / (2 * A) + v * T + 1e-12);
	/* every sample inside the acceleration limit, Y never moved */
	assert_true(max_accel(0) <= A * (1 + 1e-6));
	for (int i = 0; i < n_trace; i++) {
		assert_true(trace_y[i] == 1e-3 || i < 50);
	}
	assert_true(out.pos[0] == 0.0); /* the move after the probe ran */
	print_message("[machio] probe: surface X %.4f, latched %.6f (+%.1f um), rest %.6f "
	              "(braking %.1f um, v^2/2A = %.1f um)\n",
	              s, latched, (latched - s) * 1e3, rest_x, (rest_x - latched) * 1e3,
	              v * v / (2 * A) * 1e3);
}

/* G38.2 that reaches its target without a trip: the program stops there
 * (idle, the rest dropped, a new program runs); G38.3 the same: the
 * program goes on, #5070 = 0. */
static void test_probe_no_trip(void **st)
{
	(void)st;
	push_block(1, MLIP_BLOCK_PROBE, 2, 0, 10, MLIP_PROBE_MUST_TRIP);
	push_block(2, MLIP_BLOCK_MOVE, 0, 0, 100, 0);
	end(3);
	until(MLIP_STATE_IDLE, 5000);
	assert_int_equal(out.status.reason, MLIP_WHY_PROBE_NO_TRIP);
	assert_int_equal(out.status.reason_line, 2);
	assert_true(out.pos[0] == 2.0);
	assert_int_equal(out.status.probe_tripped, 0);
	tick(5);
	assert_true(out.pos[0] == 2.0);               /* the rest never ran */
	assert_int_equal(mlip_ring_count(ring), 0);   /* dropped */
	push_block(1, MLIP_BLOCK_MOVE, 3, 0, 100, 0); /* the next program runs */
	end(2);
	for (int i = 0; i < 5000 && out.status.reason != MLIP_WHY_END; i++) {
		tick(1);
	}
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_true(out.pos[0] == 3.0);
	teardown(NULL);
	setup(NULL);
	push_block(1, MLIP_BLOCK_PROBE, 2, 0, 10, 0);
	push_block(2, MLIP_BLOCK_MOVE, 0, 0, 100, 0);
	end(3);
	until(MLIP_STATE_IDLE, 5000);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_int_equal(out.status.probe_count, 1);
	assert_int_equal(out.status.probe_tripped, 0);
	assert_true(out.status.probe_pos[0] == 2.0);
	assert_true(out.pos[0] == 0.0);
}

/* Tripped at the start (G38.2/.3): the program stops, nothing moves; G38.4 (away)
 * with the probe off at the start: the same. G38.4 with it on trips when
 * it goes off. */
static void test_probe_at_start_and_away(void **st)
{
	(void)st;
	io_in.active |= BIT(MLIP_IN_PROBE);
	push_block(1, MLIP_BLOCK_PROBE, 5, 0, 10, 0);
	end(2);
	until(MLIP_STATE_IDLE, 100);
	assert_int_equal(out.status.reason, MLIP_WHY_PROBE_AT_START);
	assert_true(out.pos[0] == 0.0);
	teardown(NULL);
	setup(NULL);
	push_block(1, MLIP_BLOCK_PROBE, 5, 0, 10, MLIP_PROBE_AWAY | MLIP_PROBE_MUST_TRIP);
	end(2);
	until(MLIP_STATE_IDLE, 100);
	assert_int_equal(out.status.reason, MLIP_WHY_PROBE_AT_START);
	assert_true(out.pos[0] == 0.0);
	teardown(NULL);
	setup(NULL);
	surface_x = 1.5;
	surface_away = 1; /* on below X 1.5 */
	push_block(1, MLIP_BLOCK_PROBE, 5, 0, 10, MLIP_PROBE_AWAY | MLIP_PROBE_MUST_TRIP);
	end(2);
	until(MLIP_STATE_IDLE, 5000);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_int_equal(out.status.probe_tripped, 1);
	assert_true(out.status.probe_pos[0] >= 1.5 && out.status.probe_pos[0] <= 1.5 + 0.01);
}

/* No probe input read: a G38 stops the program before it moves. */
static void test_probe_input_unread(void **st)
{
	(void)st;
	io_in.known &= ~BIT(MLIP_IN_PROBE);
	push_block(1, MLIP_BLOCK_PROBE, 5, 0, 10, 0);
	end(2);
	until(MLIP_STATE_IDLE, 100);
	assert_int_equal(out.status.reason, MLIP_WHY_PROBE_INPUT);
	assert_true(out.pos[0] == 0.0);
}

/* A stop during the probe move: stopping on the path, idle, no result. */
static void test_probe_stopped(void **st)
{
	(void)st;
	push_block(1, MLIP_BLOCK_PROBE, 5, 0, 10, MLIP_PROBE_MUST_TRIP);
	end(2);
	tick(100);
	assert_int_equal(out.status.state, MLIP_STATE_RUNNING);
	assert_int_equal(out.status.reason, MLIP_WHY_PROBE);
	stop_count++;
	until(MLIP_STATE_IDLE, 1000);
	assert_int_equal(out.status.reason, MLIP_WHY_STOP);
	assert_int_equal(out.status.probe_count, 0);
	assert_true(max_accel(0) <= 1000.0 * (1 + 1e-6));
}

/* [PROBE] SOURCE = drive: G38.2 along X and Y toward (20, 2) at 600
 * mm/min, the surface at X = 7.3: the result is the position each drive
 * latched at the instant of the trip (X exactly on the surface, Y where the
 * line is there), not a setpoint of the 1 ms grid nor where the machine
 * came to rest (stopped on the path at the acceleration limit); the latch
 * is switched off, then on before the move, and off after it. */
static void test_drive_probe_latched_position(void **st)
{
	(void)st;
	use_drive_probe();
	double v = 10.0, A = 1000.0, s = 7.3;
	surface_x = s;
	push_block(1, MLIP_BLOCK_MOVE, 0, 0, 100, 0);
	push_block(2, MLIP_BLOCK_PROBE, 20, 2, v, MLIP_PROBE_MUST_TRIP);
	push_block(3, MLIP_BLOCK_MOVE, 0, 0, 100, 0);
	end(4);
	int trip_at = -1, armed_at = -1, moved_at = -1;
	double rest[2] = {NAN, NAN};
	for (int i = 0; i < 20000; i++) {
		tick(1);
		if (armed_at < 0 && ctl.mio.tp_fn != 0) {
			armed_at = n_trace - 1;
		}
		if (armed_at >= 0 && moved_at < 0 && out.pos[0] != 0.0) {
			moved_at = n_trace - 1;
		}
		if (trip_at < 0 && out.status.probe_count == 1) {
			trip_at = i;
			rest[0] = out.pos[0];
			rest[1] = out.pos[1];
			assert_int_equal(ctl.mio.tp_fn, 0); /* off again at its end */
		}
		if (out.status.state == MLIP_STATE_IDLE && out.status.reason == MLIP_WHY_END) {
			break;
		}
	}
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_int_equal(fn_hist[armed_at], 0x0011); /* on, first event, positive edge */
	/* the move began only once both drives reported the latch on */
	assert_true(moved_at >= armed_at + 3);
	assert_int_equal(tp_latches, 1);
	assert_int_equal(out.status.probe_tripped, 1);
	assert_int_equal(ctl.mio.result.latched, 3u);
	double x = out.status.probe_pos[0], y = out.status.probe_pos[1];
	assert_true(fabs(x - s) <= 1e-9);              /* the latch, exactly */
	assert_true(fabs(y - s * 2.0 / 20.0) <= 1e-9); /* the same instant on Y */
	int on_grid = 0;
	for (int i = 0; i < n_trace; i++) {
		on_grid |= trace_x[i] == x;
	}
	assert_false(on_grid); /* between two setpoints */
	double d = hypot(rest[0] - x, rest[1] - y);
	/* at rest past the latch: the drives reported it 3 periods on, then
	 * braking at the acceleration limit on the path */
	assert_true(rest[0] > x && d <= v * v / (2 * A) + 4 * v * 1e-3 + 1e-9);
	assert_true(max_accel(0) <= A * (1 + 1e-6) * sqrt(2.0));
	print_message("[machio] drive probe: surface X %.4f, latched (%.6f, %.6f), rest (%.6f, "
	              "%.6f), %.1f um past it\n",
	              s, x, y, rest[0], rest[1], d * 1e3);
}

/* The drives' touch probe: G38.3 without a trip goes on (#5070 = 0), G38.2
 * errs; an edge stored while armed at rest is "tripped at the start"; drives
 * that never report the latch on: "no probe input" after the timeout,
 * nothing moved. */
static void test_drive_probe_errors(void **st)
{
	(void)st;
	use_drive_probe();
	push_block(1, MLIP_BLOCK_PROBE, 2, 0, 10, 0);
	end(2);
	until(MLIP_STATE_IDLE, 5000);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_int_equal(out.status.probe_tripped, 0);
	assert_true(out.status.probe_pos[0] == 2.0);
	push_block(1, MLIP_BLOCK_PROBE, 3, 0, 10, MLIP_PROBE_MUST_TRIP);
	end(2);
	until(MLIP_STATE_IDLE, 5000);
	assert_int_equal(out.status.reason, MLIP_WHY_PROBE_NO_TRIP);
	teardown(NULL);
	setup(NULL);
	use_drive_probe();
	tp_deaf = 1;
	push_block(1, MLIP_BLOCK_PROBE, 2, 0, 10, MLIP_PROBE_MUST_TRIP);
	end(2);
	int n = until(MLIP_STATE_IDLE, 2000);
	assert_int_equal(out.status.reason, MLIP_WHY_PROBE_INPUT);
	assert_true(n > 500 && n < 520);
	assert_true(out.pos[0] == 0.0);
	assert_int_equal(ctl.mio.tp_fn, 0);
	teardown(NULL);
	setup(NULL);
	use_drive_probe();
	tp_st = 3; /* a latch left on from before: switched off first */
	tp_fn = 1;
	tp_edge_at_arm = 1;
	push_block(1, MLIP_BLOCK_PROBE, 2, 0, 10, 0);
	end(2);
	until(MLIP_STATE_IDLE, 100);
	assert_int_equal(out.status.reason, MLIP_WHY_PROBE_AT_START);
	assert_true(out.pos[0] == 0.0);
}

/* [PROBE] SOURCE = drive with the probe's level mapped too ([IO] PROBE on a
 * drive's digital inputs 0x60FD, a manufacturer bit: CiA 402's 0x60B9 has no
 * level, only the latch's state): a probe already on at the start of G38.2
 * is refused before anything moves or the latch is armed; off, the move
 * runs and the latch (not the level) gives the result. */
static void test_drive_probe_level_at_start(void **st)
{
	(void)st;
	use_drive_probe();
	io_cfg.in[MLIP_IN_PROBE] = (struct mlip_io_bit){1, 0, 0x60FD, 16, 0, 1};
	io_cfg.mapped |= BIT(MLIP_IN_PROBE);
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT, .lookahead = 16, .io = &io_cfg};
	assert_int_equal(mlip_ctl_init(&ctl, &planner, &mach, &o), MLIP_OK);
	io_in.known = io_cfg.mapped;
	io_in.active |= BIT(MLIP_IN_PROBE);
	push_block(1, MLIP_BLOCK_PROBE, 5, 0, 10, MLIP_PROBE_MUST_TRIP);
	end(2);
	until(MLIP_STATE_IDLE, 100);
	assert_int_equal(out.status.reason, MLIP_WHY_PROBE_AT_START);
	assert_true(out.pos[0] == 0.0);
	for (int i = 0; i < n_trace; i++) {
		assert_int_equal(fn_hist[i], 0); /* never armed */
	}
	/* off: the latch gives the result, the level no trip of its own */
	io_in.active &= ~BIT(MLIP_IN_PROBE);
	surface_x = 2.25;
	push_block(1, MLIP_BLOCK_PROBE, 5, 0, 10, MLIP_PROBE_MUST_TRIP);
	end(2);
	tick(1);
	until(MLIP_STATE_IDLE, 5000);
	assert_int_equal(out.status.reason, MLIP_WHY_END);
	assert_int_equal(out.status.probe_tripped, 1);
	assert_true(fabs(out.status.probe_pos[0] - 2.25) <= 1e-9);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_outputs_words),
	    cmocka_unit_test(test_probe_words),
	    cmocka_unit_test(test_config_outputs),
	    cmocka_unit_test_setup_teardown(test_outputs_at_rest_and_off_at_end, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_outputs_off_on_stop, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_outputs_off_on_fault_and_estop, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_probe_trips_and_stops_on_the_path, setup,
	                                    teardown),
	    cmocka_unit_test_setup_teardown(test_probe_no_trip, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_probe_at_start_and_away, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_probe_input_unread, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_drive_probe_level_at_start, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_probe_stopped, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_drive_probe_latched_position, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_drive_probe_errors, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_mdi_outputs_stay_on, setup, teardown),
	    cmocka_unit_test_setup_teardown(test_sync_outputs_with_the_next_move, setup, teardown),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
