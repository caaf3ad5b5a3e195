/*
 * test_io.c - the machine's I/O (issue 19) as a program meets it: S,
 * M3/M4/M5, T, M6, M61, G43/G43.1/G49, M7/M8/M9 in the G-code reader
 * against the machine's [SPINDLE], [TOOL], [COOLANT] (each word refused at
 * its column when the machine cannot do it, or ignored on purpose with a
 * notice), the events they emit in LinuxCNC's order, the tool length offset
 * on Z in machine coordinates and the soft limits with it; the config
 * sections; the tool table file (LinuxCNC's format on the state file).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "mlip/gcode/gcode.h"
#include "mlip/machine/config.h"
#include "tooltable.h"

#include "gcode_run.h"

static struct mlip_machine gr_machine(void)
{
	struct mlip_machine m;
	int i;

	memset(&m, 0, sizeof m);
	m.n_axes = 3;
	for (i = 0; i < 3; i++) {
		m.axis[i].letter = "XYZ"[i];
		m.axis[i].max_accel = 1000;
		m.axis[i].max_vel = 200;
		m.axis[i].min_limit = -500;
		m.axis[i].max_limit = 500;
	}
	m.max_feed_mm_s = 200;
	m.max_rot_feed_deg_s = 360;
	m.tolerance_mm = 0.01;
	m.period_s = 0.001;
	return m;
}

static const struct mlip_tool tools[] = {
    {1, 1, 10.0, 6.0},
    {2, 2, 30.5, 3.0},
    {7, 5, -2.0, 0.0},
};

/* A mill with a manual spindle 1000..24000 rpm, a manual tool change at
 * Z100, manual coolant, the table above. */
static struct mlip_gcode_io io_manual(void)
{
	struct mlip_gcode_io io;

	memset(&io, 0, sizeof io);
	io.spindle = MLIP_IO_MANUAL;
	io.min_rpm = 1000;
	io.max_rpm = 24000;
	io.tool_change = MLIP_IO_MANUAL;
	io.change_mask = 1u << 2;
	io.change_pos[2] = 100;
	io.coolant = MLIP_IO_MANUAL;
	io.tools = tools;
	io.n_tools = 3;
	return io;
}

/* The events of r (kind, value) in order, as "S12000 T1 C2 ..." */
static void events(const struct run *r, char *out, size_t len)
{
	size_t n = 0;

	out[0] = '\0';
	for (int i = 0; i < r->s.n && n < len; i++) {
		const struct mlip_block *b = &r->s.b[i];
		if (b->kind == MLIP_BLOCK_SPINDLE) {
			n += (size_t)snprintf(out + n, len - n, "%sS%g", n ? " " : "", b->value);
		} else if (b->kind == MLIP_BLOCK_TOOL) {
			n += (size_t)snprintf(out + n, len - n, "%sT%g", n ? " " : "", b->value);
		} else if (b->kind == MLIP_BLOCK_COOLANT) {
			n += (size_t)snprintf(out + n, len - n, "%sC%g", n ? " " : "", b->value);
		} else if (b->kind == MLIP_BLOCK_SPEED) {
			n += (size_t)snprintf(out + n, len - n, "%sV%g", n ? " " : "", b->value);
		} else if (b->kind == MLIP_BLOCK_MOVE) {
			n += (size_t)snprintf(out + n, len - n, "%sm", n ? " " : "");
		}
	}
}

static const struct mlip_gcode_notice *notice(const struct run *r, const char *word)
{
	for (uint32_t k = 0; k < r->g.n_notices; k++) {
		if (strcmp(r->g.notices[k].word, word) == 0) {
			return &r->g.notices[k];
		}
	}
	return NULL;
}

/* ---- the spindle ---------------------------------------------------------- */

static void test_spindle_none(void **state)
{
	struct mlip_gcode_io io = io_manual();
	struct run *r = malloc(sizeof *r);
	char ev[256];

	(void)state;
	io.spindle = MLIP_IO_NONE;
	expect_err(&io, "G1 X1 F100\nG0 X2 S1000 M3\n", 2, 7, "no spindle ([SPINDLE] TYPE = none)");
	expect_err(&io, "M4\n", 1, 1, "M4: this machine has no spindle");
	/* M5 stops nothing: accepted, noted */
	run(r, &io, "M5\nG1 X1 F100\n");
	assert_int_equal(r->errors, 0);
	assert_non_null(notice(r, "M5"));
	/* on purpose: a notice, no event */
	io.ignore_spindle = 1;
	run(r, &io, "S1000 M3\nG1 X1 F100\nM5\n");
	assert_int_equal(r->errors, 0);
	events(r, ev, sizeof ev);
	assert_string_equal(ev, "m");
	assert_non_null(strstr(mlip_gcode_notice_text(notice(r, "M3")), "--ignore-spindle"));
	assert_non_null(notice(r, "S"));
	free(r);
}

static void test_spindle_manual(void **state)
{
	struct mlip_gcode_io io = io_manual();
	struct run *r = malloc(sizeof *r);
	char ev[256];

	(void)state;
	/* LinuxCNC's order on one line: S, then M3, then the motion */
	run(r, &io,
	    "G1 X1 S12000 M3 F100\n"
	    "S14000\n"    /* a change while it turns */
	    "S14000 M3\n" /* nothing new */
	    "M4\n"        /* reversal */
	    "M3 S13000\n" /* both at once: one event */
	    "G1 X2\n"
	    "M5\n"
	    "S9000\n" /* stopped: only remembered */
	    "M3\n"
	    "M2\n");
	assert_int_equal(r->errors, 0);
	events(r, ev, sizeof ev);
	assert_string_equal(ev, "S12000 m S14000 S-14000 S13000 m S0 S9000 S0");
	/* the events stand where the machine is */
	assert_true(r->s.b[0].target[0] == 0.0 && r->s.b[2].target[0] == 1.0);
	/* LinuxCNC's order: the spindle before the dwell, the dwell before the motion */
	run(r, &io, "G4 P0.5 S1000 M3 G0 X3\n");
	assert_int_equal(r->errors, 0);
	assert_int_equal(r->s.n, 3);
	assert_int_equal(r->s.b[0].kind, MLIP_BLOCK_SPINDLE);
	assert_int_equal(r->s.b[1].kind, MLIP_BLOCK_DWELL);
	assert_int_equal(r->s.b[2].kind, MLIP_BLOCK_MOVE);
	free(r);
}

/* text runs without an error and emits the events want (events()). */
static void expect_events(const struct mlip_gcode_io *io, const char *text, const char *want)
{
	struct run *r = malloc(sizeof *r);
	char ev[256];

	assert_non_null(r);
	run(r, io, text);
	events(r, ev, sizeof ev);
	if (r->errors != 0 || strcmp(ev, want) != 0) {
		fprintf(stderr, "for \"%s\": %d errors (%s), events \"%s\"; expected \"%s\"\n",
		        text, r->errors, r->first_msg, ev, want);
		fail();
	}
	free(r);
}

/* MDI lines (each mdi a fresh reader): M5 and M9 always reach the
 * controller, which keeps an earlier line's M3/M8 on; a program's redundant
 * M5 stays nothing (a manual spindle would pause for it). */
static void test_mdi_stop_words(void **state)
{
	struct mlip_gcode_io io = io_manual();

	(void)state;
	gr_mdi = 1;
	expect_events(&io, "M5\n", "S0");
	expect_events(&io, "M9\n", "C0");
	io.coolant = MLIP_IO_NONE;
	expect_events(&io, "M9\n", "");
	gr_mdi = 0;
	io = io_manual();
	expect_events(&io, "M5 M9\nG1 X1 F100\n", "m");
}

/* An MDI S alone (a fresh reader: an earlier MDI M3 may keep it turning):
 * a CiA 402 spindle gets a SPEED event (the controller keeps its direction);
 * a manual one is refused (mlip cannot see it); once the lines said M3/M4/M5
 * the reader knows, as in a program. M6 and M2 in MDI stop it first. */
static void test_mdi_speed(void **state)
{
	struct mlip_gcode_io io = io_manual();

	(void)state;
	gr_mdi = 1;
	io.spindle = MLIP_IO_CIA402;
	expect_events(&io, "S8000\n", "V8000");
	expect_events(&io, "S0\nS9000 G1 X1 F100\n", "V0 V9000 m");
	expect_events(&io, "M4 S2000\nS3000\nM5\nS4000\n", "S-2000 S-3000 S0");
	expect_events(&io, "T2 M6\n", "S0 m T2");
	expect_events(&io, "M2\n", "S0 C0");
	expect_err(&io, "S30000\n", 1, 1, "S30000 beyond the spindle's MAX_RPM 24000");
	io.ignore_spindle = 1;
	expect_events(&io, "S8000\nT2 M6\n", "m T2");
	io = io_manual();
	expect_err(&io, "G0 X1\nS8000\n", 2, 1,
	           "S8000 alone in MDI with a manual spindle: mlip cannot tell whether it turns");
	expect_events(&io, "M5\nS8000\n", "S0");
	gr_mdi = 0; /* a program (mlip-sim: no MDI before it, none turns) */
	io.spindle = MLIP_IO_CIA402;
	expect_events(&io, "S8000\nG1 X1 F100\nT2 M6\nM2\n", "m m T2");
	/* a program for a running controller (mlip-feed): an MDI M3/M4 may keep
	 * the spindle turning into it (LinuxCNC: modal), so its S before its own
	 * M3 reaches the spindle in the direction it turns and its M6 stops it
	 * first; once it said M3/M4/M5 it knows */
	io.live = 1;
	expect_events(&io, "S8000\nG1 X1 F100\nT2 M6\nM2\n", "V8000 m S0 m T2");
	expect_events(&io, "S8000\nS9000 M3\nS10000\nM5\nS11000\nM2\n", "V8000 S9000 S10000 S0");
	io.ignore_spindle = 1;
	expect_events(&io, "S8000\nT2 M6\n", "m T2");
	io = io_manual();
	io.live = 1; /* a manual spindle: a program says M3 before it matters */
	expect_events(&io, "S8000\nG1 X1 F100\n", "m");
}

static void test_spindle_bad(void **state)
{
	struct mlip_gcode_io io = io_manual();

	(void)state;
	expect_err(&io, "G0 X1\nM3\n", 2, 1, "M3 with no S: the spindle speed was never set");
	expect_err(&io, "S30000 M3\n", 1, 1, "S30000 beyond the spindle's MAX_RPM 24000: refused");
	expect_err(&io, "M3 S500\n", 1, 4, "S500 below the spindle's MIN_RPM 1000");
	expect_err(&io, "S-5\n", 1, 1, "S must be >= 0");
	expect_err(&io, "M3 M5 S100\n", 1, 4, "M3 and M5 on one line: same modal group");
	/* a line with an error emits nothing: not its spindle, not its tool change */
	{
		struct run *q = malloc(sizeof *q);
		run(q, &io, "S12000 M3 G0 X5000\n");
		assert_int_equal(q->errors, 1);
		assert_int_equal(q->s.n, 0);
		run(q, &io, "T1 M6 M8 G4 P1 G0 Y-600\n");
		assert_int_equal(q->errors, 1);
		assert_int_equal(q->s.n, 0);
		free(q);
	}
	/* S0 is a stopped spindle (LinuxCNC): fine */
	struct run *r = malloc(sizeof *r);
	run(r, &io, "S0 M3\nG1 X1 F100\n");
	assert_int_equal(r->errors, 0);
	free(r);
}

/* ---- tools ---------------------------------------------------------------- */

static void test_tool_change(void **state)
{
	struct mlip_gcode_io io = io_manual();
	struct run *r = malloc(sizeof *r);
	char ev[256];

	(void)state;
	run(r, &io,
	    "S12000 M3\n"
	    "G0 X5 Y5 Z5\n"
	    "T2 M6\n" /* spindle stopped, Z to 100, then the change */
	    "G43\n"
	    "G0 Z5\n"
	    "T2 M6\n" /* already in the spindle: nothing */
	    "M61 Q1\n"
	    "G43 H7\n"
	    "G0 Z5\n");
	assert_int_equal(r->errors, 0);
	events(r, ev, sizeof ev);
	assert_string_equal(ev, "S12000 m S0 m T2 m m");
	/* the change position: Z only, in machine coordinates, rapid */
	assert_true(r->s.b[3].target[2] == 100.0 && r->s.b[3].target[0] == 5.0);
	assert_true(r->s.b[3].rapid);
	/* G43 (tool 2): Z5 is 5 + 30.5 in machine coordinates */
	assert_true(fabs(r->s.b[5].target[2] - 35.5) < 1e-12);
	/* M61 Q1 names the tool in it; G43 H7 takes tool 7's offset: -2 */
	assert_true(fabs(r->s.b[6].target[2] - 3.0) < 1e-12);
	assert_int_equal(r->g.off.tool, 1);
	assert_non_null(strstr(mlip_gcode_notice_text(notice(r, "M6")), "already in the spindle"));
	free(r);
}

static void test_tool_bad(void **state)
{
	struct mlip_gcode_io io = io_manual();

	(void)state;
	expect_err(&io, "G0 X1\nT3 M6\n", 2, 1, "T3: tool 3 is not in the tool table");
	expect_err(&io, "M6\n", 1, 1, "M6 with no T");
	expect_err(&io, "G43 H4\n", 1, 5, "H4: tool 4 is not in the tool table");
	expect_err(&io, "G43\n", 1, 1, "G43 with no tool in the spindle");
	expect_err(&io, "T1.5\n", 1, 1, "a tool is a whole number");
	expect_err(&io, "M61\n", 1, 1, "M61 without Q");
	expect_err(&io, "M61 Q9\n", 1, 5, "Q9: tool 9 is not in the tool table");
	expect_err(&io, "G43.1 Z5 G1\n", 1, 10, "G43.1 and G1 on one line: both use axis words");
	expect_err(&io, "G43.1 X5\n", 1, 7, "only a length along Z");
	expect_err(&io, "G43.1\n", 1, 1, "G43.1 without Z");
	expect_err(&io, "H2\n", 1, 1, "H word without G43");
	expect_err(&io, "G43.2 H1\n", 1, 1, "G43.2");
	expect_err(&io, "M6 M61 Q1\n", 1, 4, "M6 and M61 on one line");
	io.tools = NULL;
	io.n_tools = 0;
	expect_err(&io, "T1 M6\n", 1, 1, "T1: no tool table given (--tools FILE)");
	io = io_manual();
	io.tool_change = MLIP_IO_NONE;
	io.change_mask = 0;
	expect_err(&io, "T1 M6\n", 1, 1, "T: this machine has no tool change");
	expect_err(&io, "G0 X1\nM6\n", 2, 1, "M6: this machine has no tool change");
}

/* The length offset moves Z in machine coordinates and the soft limits hold
 * with it: a target inside the limits without it is refused with it. */
static void test_length_offset(void **state)
{
	struct mlip_gcode_io io = io_manual();
	struct run *r = malloc(sizeof *r);

	(void)state;
	expect_err(&io, "M61 Q2\nG43\nG0 Z480\n", 3, 4, "Z 510.500 beyond soft limit 500.000");
	run(r, &io,
	    "M61 Q2\nG43\n"
	    "G91 G0 Z-10\n" /* incremental: from where Z stands (no jump, LinuxCNC) */
	    "G90 G43.1 Z2.5\n"
	    "G0 Z0\n"
	    "G20 G43.1 Z1\n" /* the line's units */
	    "G0 Z0\n"
	    "G21 G49\n"
	    "G0 Z3\n"
	    "G43 H1\n"
	    "G53 G0 Z0\n"     /* machine coordinates: no offset (LinuxCNC) */
	    "G10 L20 P1 Z0\n" /* the tip reads 0 here: G54 Z = -10 */
	    "G0 Z1\n");
	assert_int_equal(r->errors, 0);
	assert_true(r->s.b[0].target[2] == -10.0);
	assert_true(r->s.b[1].target[2] == 2.5);
	assert_true(fabs(r->s.b[2].target[2] - 25.4) < 1e-12);
	assert_true(r->s.b[3].target[2] == 3.0);
	assert_true(r->s.b[4].target[2] == 0.0);
	assert_true(fabs(r->g.off.coord[0][2] - (-10.0)) < 1e-12);
	assert_true(fabs(r->s.b[5].target[2] - 1.0) < 1e-12); /* -10 + 10 + 1 */
	free(r);
}

/* ---- coolant, program end --------------------------------------------------- */

static void test_coolant(void **state)
{
	struct mlip_gcode_io io = io_manual();
	struct run *r = malloc(sizeof *r);
	char ev[256];

	(void)state;
	run(r, &io, "M8\nM8\nM7\nG1 X1 F100\nM9\nM7 M8\nS2000 M4\nM30\nM8\n");
	assert_int_equal(r->errors, 0);
	events(r, ev, sizeof ev);
	/* M30 stops the spindle and the coolant; nothing after it is read */
	assert_string_equal(ev, "C2 C3 m C0 C3 S-2000 S0 C0");
	expect_err(&io, "M9 M8\n", 1, 4, "M9 with M7 or M8 on one line");
	io.coolant = MLIP_IO_NONE;
	expect_err(&io, "G0 X1\nM8\n", 2, 1, "M8: this machine has no coolant");
	run(r, &io, "M9\nG0 X1\n"); /* nothing to stop */
	assert_int_equal(r->errors, 0);
	io.ignore_coolant = 1;
	run(r, &io, "M7\nG0 X1\nM9\n");
	assert_int_equal(r->errors, 0);
	events(r, ev, sizeof ev);
	assert_string_equal(ev, "m");
	assert_non_null(strstr(mlip_gcode_notice_text(notice(r, "M7")), "--ignore-coolant"));
	free(r);
}

/* Without set_io (a motion check): the words are notices, G43 refused. */
static void test_no_io(void **state)
{
	struct run *r = malloc(sizeof *r);
	char ev[256];

	(void)state;
	run(r, NULL, "T1 M6\nS1000 M3\nM8\nG1 X1 F100\nM2\n");
	assert_int_equal(r->errors, 0);
	events(r, ev, sizeof ev);
	assert_string_equal(ev, "m");
	assert_string_equal(mlip_gcode_notice_text(notice(r, "M3")),
	                    "ignored (no effect on motion)");
	expect_err(NULL, "G43 H1\n", 1, 1, "needs the machine's config");
	free(r);
}

/* ---- the config ------------------------------------------------------------- */

static const char base_ini[] = "[TRAJ]\nCOORDINATES = X Y Z\nMAX_LINEAR_VELOCITY = 200\n"
                               "CONTOUR_TOLERANCE = 0.01\n"
                               "[AXIS_X]\nMAX_VELOCITY = 200\nMAX_ACCELERATION = 1000\n"
                               "[AXIS_Y]\nMAX_VELOCITY = 200\nMAX_ACCELERATION = 1000\n"
                               "[AXIS_Z]\nMAX_VELOCITY = 200\nMAX_ACCELERATION = 1000\n"
                               "MIN_LIMIT = -100\nMAX_LIMIT = 150\n";

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

static void test_config_sections(void **state)
{
	struct mlip_config c;
	struct mlip_config_error e;

	(void)state;
	/* none of them: none of it */
	assert_int_equal(parse_cfg("", &c, &e), MLIP_OK);
	assert_int_equal(c.io.spindle, MLIP_IO_NONE);
	assert_int_equal(c.io.tool_change, MLIP_IO_NONE);
	assert_int_equal(c.io.coolant, MLIP_IO_NONE);
	assert_int_equal(parse_cfg("[SPINDLE]\nTYPE = manual\nMIN_RPM = 100\nMAX_RPM = 24000\n"
	                           "[TOOL]\nCHANGE = manual\nCHANGE_Z = 140\nCHANGE_X = -5\n"
	                           "[COOLANT]\nTYPE = manual\n",
	                           &c, &e),
	                 MLIP_OK);
	assert_int_equal(c.io.spindle, MLIP_IO_MANUAL);
	assert_true(c.io.min_rpm == 100 && c.io.max_rpm == 24000);
	assert_int_equal(c.io.change_mask, 0x5u);
	assert_true(c.io.change_pos[2] == 140 && c.io.change_pos[0] == -5);
	assert_int_equal(c.io.coolant, MLIP_IO_MANUAL);
	/* each at the key (line:col of the value or the key) */
	cfg_err("[SPINDLE]\nTYPE = auto\n", 17, 8,
	        "TYPE must be none, manual or cia402, got 'auto'");
	cfg_err("[COOLANT]\nTYPE = cia402\n", 17, 8,
	        "TYPE must be none, manual or io (the I/O module's outputs), got 'cia402'");
	/* a CiA 402 spindle drive on the bus: its keys, defaults from the speeds */
	assert_int_equal(parse_cfg("[SPINDLE]\nTYPE = cia402\nMAX_RPM = 12000\nNODE = 9\n"
	                           "COUNTS_PER_REV = 4096\nACCELERATION = 10000\n",
	                           &c, &e),
	                 MLIP_OK);
	assert_int_equal(c.io.spindle, MLIP_IO_CIA402);
	assert_int_equal(c.spindle.node, 9);
	assert_true(c.spindle.counts_per_rev == 4096 && c.spindle.accel_rpm_s == 10000);
	assert_true(fabs(c.spindle.band_rpm - 240) < 1e-9);  /* 2 % of MAX_RPM */
	assert_true(fabs(c.spindle.timeout_s - 3.4) < 1e-9); /* 2 x 1.2 s + 1 s */
	assert_true(fabs(c.spindle.band_time_s - 0.2) < 1e-9);
	assert_true(c.spindle.max_rpm == 12000 && c.spindle.min_rpm == 0);
	cfg_err("[SPINDLE]\nTYPE = cia402\nMAX_RPM = 12000\nCOUNTS_PER_REV = 4096\n"
	        "ACCELERATION = 10000\n",
	        16, 0, "missing NODE in [SPINDLE]");
	cfg_err("[SPINDLE]\nTYPE = cia402\nMAX_RPM = 12000\nNODE = 9\nACCELERATION = 10000\n", 16,
	        0, "missing COUNTS_PER_REV");
	cfg_err("[SPINDLE]\nTYPE = cia402\nMAX_RPM = 12000\nNODE = 127\nCOUNTS_PER_REV = 4096\n"
	        "ACCELERATION = 10000\n",
	        19, 1, "NODE 127 is also [DRIVES] MASTER_NODE");
	cfg_err("[SPINDLE]\nTYPE = cia402\nMAX_RPM = 12000\nNODE = 9\nCOUNTS_PER_REV = 4096\n"
	        "ACCELERATION = 10000\nAT_SPEED_TIMEOUT = 2\n",
	        22, 1, "shorter than a reversal at full speed");
	cfg_err("[SPINDLE]\nTYPE = cia402\nMAX_RPM = 12000\nNODE = 9\nCOUNTS_PER_REV = 1e9\n"
	        "ACCELERATION = 10000\n",
	        20, 1, "beyond the drive's 0x60FF");
	cfg_err("[SPINDLE]\nTYPE = manual\nMAX_RPM = 12000\nACCELERATION = 10000\n", 19, 1,
	        "ACCELERATION is for a spindle drive on the bus");
	cfg_err("[SPINDLE]\nTYPE = manual\n", 16, 0, "missing MAX_RPM in [SPINDLE]");
	cfg_err("[SPINDLE]\nTYPE = manual\nMAX_RPM = 1000\nMIN_RPM = 2000\n", 19, 1,
	        "MIN_RPM must be <= MAX_RPM");
	cfg_err("[SPINDLE]\nMAX_RPM = 1000\n", 17, 1, "TYPE = none has none");
	cfg_err("[SPINDLE]\nTYPE = manual\nMAX_RPM = -3\n", 18, 11, "within 0..1000000 rpm");
	/* in range but not > 0: placed on MAX_RPM alone (no second key: UBSan
	 * caught a shift by -1 here, found by fuzz_config) */
	cfg_err("[SPINDLE]\nTYPE = manual\nMAX_RPM = 0\n", 18, 1, "MAX_RPM must be > 0");
	cfg_err("[TOOL]\nCHANGE = manual\nCHANGE_Z = 151\n", 18, 1,
	        "CHANGE_Z 151 is beyond the soft limits of AXIS_Z");
	cfg_err("[TOOL]\nCHANGE = manual\nCHANGE_A = 0\n", 18, 1, "axis A is not in COORDINATES");
	cfg_err("[TOOL]\nCHANGE_Z = 10\n", 17, 1, "CHANGE = none has none");
	cfg_err("[TOOL]\nCHANGE = manual\nCHANGE_W = 1\n", 18, 1, "unknown key CHANGE_W in [TOOL]");
	cfg_err("[COOLANT]\nSPRAY = 1\n", 17, 1, "unknown key SPRAY in [COOLANT]");
}

/* ---- the tool table ----------------------------------------------------------- */

static char dir[64], path[128];

static int setup(void **state)
{
	(void)state;
	snprintf(dir, sizeof(dir), "/tmp/mlip-tt-XXXXXX");
	assert_non_null(mkdtemp(dir));
	snprintf(path, sizeof(path), "%s/tool.tbl", dir);
	return 0;
}

static int teardown(void **state)
{
	DIR *d = opendir(dir);
	struct dirent *e;
	char p[512];

	(void)state;
	while (d != NULL && (e = readdir(d)) != NULL) {
		if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) {
			snprintf(p, sizeof(p), "%s/%s", dir, e->d_name);
			unlink(p);
		}
	}
	if (d != NULL) {
		closedir(d);
	}
	rmdir(dir);
	return 0;
}

static void write_text(const char *text)
{
	FILE *f = fopen(path, "w");

	assert_non_null(f);
	fputs(text, f);
	fclose(f);
}

/* Load path (unsealed: as --accept does); 0, or -1 with the message. */
static int load(struct mlip_tooltable *t, unsigned flags, char *msg, size_t len)
{
	FILE *f = fmemopen(msg, len, "w");
	int rc;

	assert_non_null(f);
	rc = mlip_tooltable_load(t, path, flags, "t", f);
	fclose(f);
	return rc;
}

static void table_err(const char *text, const char *where, const char *part)
{
	struct mlip_tooltable t;
	char msg[1024] = "", at[160];

	write_text(text);
	snprintf(at, sizeof at, "%s:%s: ", path, where);
	if (load(&t, MLIP_SF_UNSEALED, msg, sizeof msg) == 0 || strstr(msg, at) == NULL ||
	    strstr(msg, part) == NULL) {
		fprintf(stderr, "for \"%s\": got \"%s\"; expected \"%s\" and \"%s\"\n", text, msg,
		        at, part);
		fail();
	}
}

static void test_table(void **state)
{
	struct mlip_tooltable t;
	struct mlip_sf_kind k;
	struct mlip_sf sf;
	char msg[1024] = "", why[MLIP_SF_WHY], note[256];

	(void)state;
	/* LinuxCNC's tooledit writes every column; zeros are fine */
	write_text("; from LinuxCNC\n"
	           "T7 P3 X0 Y0 Z+0.511000 A0 B0 C0 U0 V0 W0 D0.125000 I0 J0 Q0 ;1/8 end mill\n"
	           "T1 P1 Z12.5 D6 ;6 mm flat\n"
	           "t2 p2 z30.25\n");
	/* not sealed: refused until accepted */
	assert_int_equal(load(&t, 0, msg, sizeof msg), -1);
	assert_non_null(strstr(msg, "mlip-tools --accept"));
	assert_int_equal(load(&t, MLIP_SF_UNSEALED, msg, sizeof msg), 0);
	assert_int_equal(t.n, 3);
	/* sorted by number, for the reader's search */
	assert_int_equal(t.tools[0].number, 1);
	assert_int_equal(t.tools[1].number, 2);
	assert_int_equal(t.tools[2].number, 7);
	assert_true(t.tools[2].z_mm == 0.511 && t.tools[2].d_mm == 0.125 && t.tools[2].pocket == 3);
	assert_string_equal(mlip_tooltable_comment(&t, 7), "1/8 end mill");
	assert_string_equal(mlip_tooltable_comment(&t, 2), "");
	assert_int_equal(t.line[2], 2);
	mlip_tooltable_free(&t);
	/* accepted: sealed, canonical, then read as mlip wrote it */
	mlip_tooltable_kind(&k);
	assert_int_equal(mlip_sf_load(&sf, path, &k, MLIP_SF_UNSEALED, why, sizeof why), 0);
	assert_true(mlip_sf_save(path, &k, &sf, &sf, note, sizeof note, why, sizeof why) >= 0);
	mlip_sf_free(&sf);
	assert_int_equal(load(&t, 0, msg, sizeof msg), 0);
	assert_int_equal(t.n, 3);
	mlip_tooltable_free(&t);
	/* each error at its line and column */
	table_err("T1 P1 Z1\nT2 P2 Zabc\n", "2:7", "'Zabc': not a number");
	table_err("T1 P1 Z1\nT1 P2 Z3\n", "2:1", "tool 1 a second time (first on line 1)");
	table_err("T1 P1 Z1\nT2 P1 Z3\n", "2:4", "pocket 1 a second time");
	table_err("T1 P1 X2.5 Z1\n", "1:7", "along Z only");
	table_err("T1 Z1\n", "1:6", "no P (pocket) column");
	table_err("T01 P1\n", "1:1", "without leading zeros");
	table_err("T0 P1\n", "1:1", "T and a whole number >= 1");
	table_err("T3 P1 R4\n", "1:7", "not a column of a tool line");
	table_err("T3 P1 Z1 Z2\n", "1:10", "that column a second time");
	table_err("T3 P1 D-1\n", "1:7", "a diameter is >= 0");
	table_err("T3 P1001\n", "1:4", "pocket is a whole number 0..1000");
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_spindle_none),
	    cmocka_unit_test(test_spindle_manual),
	    cmocka_unit_test(test_spindle_bad),
	    cmocka_unit_test(test_mdi_stop_words),
	    cmocka_unit_test(test_mdi_speed),
	    cmocka_unit_test(test_tool_change),
	    cmocka_unit_test(test_tool_bad),
	    cmocka_unit_test(test_length_offset),
	    cmocka_unit_test(test_coolant),
	    cmocka_unit_test(test_no_io),
	    cmocka_unit_test(test_config_sections),
	    cmocka_unit_test_setup_teardown(test_table, setup, teardown),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
