/*
 * test_grbl.c - the Grbl 1.1 protocol (tools/lib/grbl.c) and the line stream
 * (tools/lib/grblstream.c), pure: real-time bytes picked off anywhere, lines
 * assembled, a receive-buffer overflow answered line for line, `$` lines
 * classified as Grbl's system_execute_line does, status reports with
 * report.c's refresh counts, settings, the error codes the reader's messages
 * map to; a stream gives the records mlip-feed gives for the same program
 * (smooth included), a refused line changes nothing, a long arc comes out in
 * parts equal to the whole, M2 ends the program with Grbl's modal reset;
 * the controller's spindle and the homing settings as reports show them; the
 * server's reset against a controller whose status lags its ring.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "mlip/canopen/spindle.h"
#include "mlip/ctl/state.h"
#include "mlip/ipc/ring.h"
#include "mlip/machine/config.h"

#include "../../tools/lib/blockiter.h"
#include "../../tools/lib/grbl.h"
#include "../../tools/lib/grblmach.h"
#include "../../tools/lib/grblsrv.h"
#include "../../tools/lib/grblstream.h"
#include "../../tools/lib/program.h"

static struct mlip_machine machine(void)
{
	struct mlip_machine m;
	memset(&m, 0, sizeof m);
	m.n_axes = 3;
	for (int i = 0; i < 3; i++) {
		m.axis[i].letter = "XYZ"[i];
		m.axis[i].max_accel = 1000;
		m.axis[i].max_vel = 200;
		m.axis[i].min_limit = -1000;
		m.axis[i].max_limit = 1000;
		m.axis[i].counts_per_unit = 1000;
	}
	m.max_feed_mm_s = 200;
	m.max_rot_feed_deg_s = 360;
	m.tolerance_mm = 0.01;
	m.period_s = 0.001;
	return m;
}

/* ---- receiving ---- */

static grbl_rt seen[64];
static int n_seen;
static void on_rt(void *ctx, grbl_rt c)
{
	(void)ctx;
	if (n_seen < 64) {
		seen[n_seen++] = c;
	}
}

static void feed(struct grbl_rx *rx, const char *s, size_t n)
{
	grbl_rx_feed(rx, (const unsigned char *)s, n, on_rt, NULL);
}

static void next_line(struct grbl_rx *rx, const char *want)
{
	struct grbl_line l;
	assert_true(grbl_rx_line(rx, &l));
	assert_int_equal(l.kind, GRBL_LINE_TEXT);
	assert_int_equal(l.len, strlen(want));
	assert_memory_equal(l.text, want, l.len);
	grbl_rx_done(rx);
}

static void test_realtime_bytes_anywhere(void **state)
{
	(void)state;
	static struct grbl_rx rx;
	grbl_rx_init(&rx);
	n_seen = 0;
	/* serial.c: every real-time byte acts and never reaches a line */
	static const char in[] = "G1 X1?0\x91 Y2!\n~\x18";
	feed(&rx, in, sizeof(in) - 1); /* was 17 for these 15 bytes: ASan */
	assert_int_equal(n_seen, 5);
	assert_int_equal(seen[0], GRBL_RT_STATUS);
	assert_int_equal(seen[1], GRBL_RT_FEED_PLUS_10);
	assert_int_equal(seen[2], GRBL_RT_FEED_HOLD);
	assert_int_equal(seen[3], GRBL_RT_CYCLE_START);
	assert_int_equal(seen[4], GRBL_RT_RESET);
	next_line(&rx, "G1 X10 Y2");
	for (int c = 0; c < 256; c++) {
		grbl_rt r = grbl_rt_of((unsigned char)c);
		int want = c == 0x18 || c == '?' || c == '~' || c == '!' || c == 0x84 ||
		           c == 0x85 || (c >= 0x90 && c <= 0x97) || (c >= 0x99 && c <= 0x9E) ||
		           c == 0xA0 || c == 0xA1;
		assert_int_equal(r != GRBL_RT_NONE, want);
	}
}

static void test_utf8_realtime_bytes(void **state)
{
	(void)state;
	static struct grbl_rx rx;
	grbl_rx_init(&rx);
	n_seen = 0;
	/* CNCjs writes 0x92 as the JavaScript string '\x92': UTF-8 C2 92, here
	 * split across two reads and inside a line; the C2 is dropped as Grbl
	 * drops every unknown byte above 0x7F, the 0x92 acts. A C2 before
	 * another byte (the degree sign C2 B0 in a comment) is line data. */
	feed(&rx, "G1 X1\xc2", 6);
	feed(&rx, "\x92 Y2 (5\xc2\xb0)\xc2\x85\n", 13);
	assert_int_equal(n_seen, 2);
	assert_int_equal(seen[0], GRBL_RT_FEED_MINUS_10);
	assert_int_equal(seen[1], GRBL_RT_JOG_CANCEL);
	next_line(&rx, "G1 X1 Y2 (5\xc2\xb0)");
	/* a C2 at a line end is data, the end still ends it */
	feed(&rx, "X\xc2\n", 3);
	next_line(&rx, "X\xc2");
	assert_false(grbl_rx_pending(&rx));
	feed(&rx, "\xc2", 1);
	assert_true(grbl_rx_pending(&rx));
	grbl_rx_reset(&rx);
	assert_false(grbl_rx_pending(&rx));
}

static void test_lines_cr_lf_and_buffer(void **state)
{
	(void)state;
	static struct grbl_rx rx;
	grbl_rx_init(&rx);
	feed(&rx, "G0 X1\r\nG0 X2\n", 13);
	/* protocol.c: CR and LF each end a line; the empty one is answered too */
	next_line(&rx, "G0 X1");
	next_line(&rx, "");
	next_line(&rx, "G0 X2");
	struct grbl_line l;
	assert_false(grbl_rx_line(&rx, &l));
	assert_int_equal(grbl_rx_available(&rx), GRBL_RX_SIZE);
	/* while a line waits, the rest counts against the 128 bytes */
	feed(&rx, "G0 X3\nG0 X4\n", 12);
	assert_int_equal(grbl_rx_available(&rx), GRBL_RX_SIZE - 6);
	next_line(&rx, "G0 X3");
	assert_int_equal(grbl_rx_available(&rx), GRBL_RX_SIZE);
	next_line(&rx, "G0 X4");
}

static void test_too_long_line(void **state)
{
	(void)state;
	static struct grbl_rx rx;
	char big[400];
	grbl_rx_init(&rx);
	memset(big, 'X', sizeof big);
	feed(&rx, big, sizeof big);
	feed(&rx, "\nG0\n", 4);
	struct grbl_line l;
	assert_true(grbl_rx_line(&rx, &l));
	assert_int_equal(l.kind, GRBL_LINE_TOO_LONG);
	assert_int_equal(l.len, GRBL_LINE_MAX);
	grbl_rx_done(&rx);
	next_line(&rx, "G0");
}

static void test_overflow_answers_each_line(void **state)
{
	(void)state;
	static struct grbl_rx rx;
	char flood[2000];
	size_t n = 0;
	int lines = 0;
	grbl_rx_init(&rx);
	while (n + 12 < sizeof flood) {
		n += (size_t)snprintf(flood + n, sizeof flood - n, "G0 X%d\n", lines % 100);
		lines++;
	}
	feed(&rx, flood, n); /* never waiting for ok */
	int answered = 0, lost = 0;
	struct grbl_line l;
	while (grbl_rx_line(&rx, &l)) {
		if (l.kind == GRBL_LINE_LOST) {
			lost += (int)l.lost;
			answered += (int)l.lost;
		} else {
			/* every line kept is a line that was sent, whole */
			assert_true(l.len >= 4 && memcmp(l.text, "G0 X", 4) == 0);
			answered++;
		}
		grbl_rx_done(&rx);
	}
	assert_int_equal(answered, lines);
	assert_true(lost > 0);
	assert_true(rx.overflows > 0);
	/* a line cut by the overflow in its middle is lost whole */
	grbl_rx_init(&rx);
	feed(&rx, "G0 X1\n", 6); /* waits: not answered */
	char fill[GRBL_RX_SIZE];
	memset(fill, ' ', sizeof fill);
	memcpy(fill, "G0 X2\n", 6);
	feed(&rx, fill, sizeof fill - 10);
	feed(&rx, "G0 X12345678901234\nG0 X3\n", 25);
	next_line(&rx, "G0 X1");
	next_line(&rx, "G0 X2");
	assert_true(grbl_rx_line(&rx, &l));
	assert_int_equal(l.kind, GRBL_LINE_LOST);
	assert_int_equal(l.lost, 1);
	grbl_rx_done(&rx);
	next_line(&rx, "G0 X3");
}

/* ---- system lines ---- */

static grbl_sys_kind sys_kind(const char *s, int *code)
{
	struct grbl_sys c;
	grbl_sys_parse(s, strlen(s), &c);
	if (code) {
		*code = c.code;
	}
	return c.kind;
}

static void test_system_lines(void **state)
{
	(void)state;
	int code;
	assert_int_equal(sys_kind("$", NULL), GRBL_SYS_HELP);
	assert_int_equal(sys_kind("$$", NULL), GRBL_SYS_SETTINGS);
	assert_int_equal(sys_kind(" $ # ", NULL), GRBL_SYS_PARAMS);
	assert_int_equal(sys_kind("$g", NULL), GRBL_SYS_GCODE);
	assert_int_equal(sys_kind("$C", NULL), GRBL_SYS_CHECK);
	assert_int_equal(sys_kind("$X", NULL), GRBL_SYS_UNLOCK);
	assert_int_equal(sys_kind("$H", NULL), GRBL_SYS_HOME);
	assert_int_equal(sys_kind("$HZ", NULL), GRBL_SYS_HOME);
	assert_int_equal(sys_kind("$I", NULL), GRBL_SYS_INFO);
	assert_int_equal(sys_kind("$N", NULL), GRBL_SYS_STARTUP);
	assert_int_equal(sys_kind("$N0=G54", NULL), GRBL_SYS_STARTUP_SET);
	assert_int_equal(sys_kind("$SLP", NULL), GRBL_SYS_SLEEP);
	assert_int_equal(sys_kind("$RST=$", NULL), GRBL_SYS_RESTORE);
	assert_int_equal(sys_kind("$J=G91 X1 F100", NULL), GRBL_SYS_JOG);
	struct grbl_sys c;
	grbl_sys_parse("$110 = 500.5", 12, &c);
	assert_int_equal(c.kind, GRBL_SYS_SET);
	assert_int_equal(c.number, 110);
	assert_true(c.value == 500.5);
	/* system.c's answers to what it does not know */
	assert_int_equal(sys_kind("$Q", &code), GRBL_SYS_BAD);
	assert_int_equal(code, GRBL_E_BAD_NUMBER);
	assert_int_equal(sys_kind("$GG", &code), GRBL_SYS_BAD);
	assert_int_equal(code, GRBL_E_INVALID_STATEMENT);
	assert_int_equal(sys_kind("$J", &code), GRBL_SYS_BAD);
	assert_int_equal(code, GRBL_E_INVALID_STATEMENT);
	assert_int_equal(sys_kind("$300=1", &code), GRBL_SYS_BAD);
	assert_int_equal(code, GRBL_E_INVALID_STATEMENT);
	assert_int_equal(sys_kind("$10=x", &code), GRBL_SYS_BAD);
	assert_int_equal(code, GRBL_E_BAD_NUMBER);
}

/* ---- reports ---- */

static void test_status_report_and_refresh(void **state)
{
	(void)state;
	struct mlip_machine m = machine();
	struct grbl_axes ax;
	struct grbl_fmt fmt = {1, 0};
	struct grbl_refresh rf = {0, 0};
	struct grbl_status s;
	char b[GRBL_MSG_BYTES];
	grbl_axes_of(&m, &ax);
	memset(&s, 0, sizeof s);
	s.state = "Idle";
	s.mpos[0] = 1.23456;
	s.mpos[1] = -0.0001;
	s.wco[0] = 1.0;
	s.ov_feed = s.ov_rapid = s.ov_spindle = 100;
	s.feed_mm_min = 499.6;
	grbl_status_format(b, sizeof b, &s, &ax, &fmt, &rf);
	assert_string_equal(b, "<Idle|MPos:1.235,0.000,0.000|FS:500,0|WCO:1.000,0.000,0.000>");
	grbl_status_format(b, sizeof b, &s, &ax, &fmt, &rf);
	assert_string_equal(b, "<Idle|MPos:1.235,0.000,0.000|FS:500,0|Ov:100,100,100>");
	int wco = 0, ov = 0;
	for (int i = 0; i < 30; i++) {
		grbl_status_format(b, sizeof b, &s, &ax, &fmt, &rf);
		wco += strstr(b, "WCO:") != NULL;
		ov += strstr(b, "Ov:") != NULL;
	}
	assert_int_equal(wco, 3); /* every 10 idle */
	assert_int_equal(ov, 3);
	s.busy = 1;
	s.state = "Run";
	grbl_refresh_ovr(&rf);
	grbl_status_format(b, sizeof b, &s, &ax, &fmt, &rf);
	assert_non_null(strstr(b, "|Ov:"));
	fmt.mask = 0; /* WPos = MPos - WCO */
	fmt.inches = 1;
	s.line = 42;
	grbl_status_format(b, sizeof b, &s, &ax, &fmt, &rf);
	assert_true(strncmp(b, "<Run|WPos:0.0092,0.0000,0.0000|Ln:42|FS:19.7,0", 46) == 0);
}

static void test_settings_and_params(void **state)
{
	(void)state;
	struct mlip_machine m = machine();
	struct grbl_fmt fmt = {1, 0};
	char b[GRBL_MSG_BYTES];
	int n = 0, found = 0;
	for (; grbl_setting_line(b, sizeof b, &m, &fmt, NULL, n) > 0; n++) {
		found += strcmp(b, "$11=0.010") == 0 || strcmp(b, "$110=12000.000") == 0 ||
		         strcmp(b, "$122=1000.000") == 0 || strcmp(b, "$132=2000.000") == 0 ||
		         strcmp(b, "$100=1000.000") == 0;
	}
	assert_int_equal(found, 5);
	assert_int_equal(n, 7 + 4 * 3);
	struct mlip_gcode g;
	mlip_gcode_init(&g, &m);
	grbl_gcode_state(b, sizeof b, &g, -1);
	assert_string_equal(b, "[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]");
	struct grbl_axes ax;
	grbl_axes_of(&m, &ax);
	grbl_param_line(b, sizeof b, &g.off, 0.0, &ax, &fmt, 10);
	assert_string_equal(b, "[PRB:0.000,0.000,0.000:0]");
	assert_int_equal(grbl_param_line(b, sizeof b, &g.off, 0.0, &ax, &fmt, 11), 0);
	grbl_param_line(b, sizeof b, &g.off, 38.1, &ax, &fmt, 9);
	assert_string_equal(b, "[TLO:38.100]");
	double wco[MLIP_MAX_AXES];
	grbl_wco(&g.off, 3, 2, 38.1, wco);
	assert_true(wco[0] == 0.0 && wco[2] == 38.1);
	assert_int_equal(grbl_override_step(GRBL_RT_FEED_PLUS_10, 195), 200);
	assert_int_equal(grbl_override_step(GRBL_RT_FEED_MINUS_1, 10), 10);
	assert_int_equal(grbl_override_step(GRBL_RT_RAPID_25, 100), 25);
}

/* The reader's messages, as the stream gets them, and Grbl's codes. */
static void test_error_codes(void **state)
{
	(void)state;
	static const struct {
		const char *line;
		int code;
	} cases[] = {{"G1 X10", GRBL_E_FEED},
	             {"G0 X1 X2", GRBL_E_WORD_REPEATED},
	             {"G0 G1 X1", GRBL_E_MODAL_GROUP},
	             {"G0 X5000", GRBL_E_TARGET},
	             {"G2 X10 F100", GRBL_E_NO_OFFSETS},
	             {"G0 X", GRBL_E_BAD_NUMBER},
	             {"G0 X1.2.3", GRBL_E_BAD_NUMBER},
	             {"G4", GRBL_E_VALUE_MISSING},
	             {"G4 P-1", GRBL_E_NEGATIVE},
	             {"G0 X1 Q2", GRBL_E_UNUSED_WORDS},
	             {"G5 X1", GRBL_E_UNSUPPORTED},
	             {"G0 X1\x01", GRBL_E_EXPECTED_LETTER},
	             {"G0 X1 \xc3\xa9", GRBL_E_EXPECTED_LETTER},
	             {"G53 G2 X1 I1", GRBL_E_G53},
	             {"$J=G91 X1", GRBL_E_FEED}, /* a jog's F is not modal */
	             {"$J=G91 G1 X1 F100", GRBL_E_JOG},
	             {"$J=G91 X1 S100 F100", GRBL_E_JOG}};
	struct mlip_machine m = machine();
	static struct grbl_stream st;
	double zero[MLIP_MAX_AXES] = {0};
	grbl_stream_init(&st, &m, zero, NULL);
	for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
		struct mlip_gcode_error e;
		mlip_status rc =
		    grbl_stream_check(&st, cases[i].line, strlen(cases[i].line), 1, &e);
		assert_int_not_equal(rc, MLIP_OK);
		if (grbl_error_code(&e, 0) != cases[i].code) {
			fail_msg("%s: '%s' -> error:%d, want %d", cases[i].line, e.msg,
			         grbl_error_code(&e, 0), cases[i].code);
		}
	}
	struct mlip_gcode_error e;
	assert_int_not_equal(grbl_stream_check(&st, "G0 X5000", 8, 1, &e), MLIP_OK);
	assert_int_equal(grbl_error_code(&e, 1), GRBL_E_TRAVEL);
	assert_true(grbl_error_travel(&e)); /* a G-code line: ALARM:2 */
	assert_int_not_equal(grbl_stream_check(&st, "G0 X", 4, 1, &e), MLIP_OK);
	assert_false(grbl_error_travel(&e));
	/* N is a jog's line number (jogging.md) */
	assert_int_equal(grbl_stream_check(&st, "$J=N5 G91 X1 F100", 17, 1, &e), MLIP_OK);
}

/* ---- the stream ---- */

static struct grbl_stream st;
static struct mlip_smooth sm_mem;

/* Every record the stream gives for lines (one program, END last). */
static size_t stream_all(const char *text, const struct mlip_machine *m, int smooth,
                         struct mlip_ring_rec *out, size_t cap, uint32_t stage_take)
{
	struct mlip_machine mm = *m;
	double zero[MLIP_MAX_AXES] = {0};
	size_t n = 0;
	mm.smooth = (uint8_t)smooth;
	grbl_stream_init(&st, &mm, zero, &sm_mem);
	const char *p = text;
	uint32_t lineno = 0;
	while (*p) {
		const char *e = strchr(p, '\n');
		size_t len = (size_t)(e - p);
		struct mlip_gcode_error err;
		lineno++;
		int rc = grbl_stream_line(&st, p, len, lineno, &err);
		assert_true(rc >= 0);
		while (rc == 0 || grbl_stream_staged(&st) > 0) {
			uint32_t k = grbl_stream_staged(&st);
			if (k > stage_take) {
				k = stage_take; /* a slow ring */
			}
			assert_true(n + k <= cap);
			memcpy(out + n, grbl_stream_peek(&st), k * sizeof(*out));
			grbl_stream_take(&st, k);
			n += k;
			if (rc == 0) {
				rc = grbl_stream_more(&st);
			}
		}
		p = e + 1;
	}
	while (!grbl_stream_end(&st) || grbl_stream_staged(&st) > 0) {
		uint32_t k = grbl_stream_staged(&st);
		memcpy(out + n, grbl_stream_peek(&st), k * sizeof(*out));
		grbl_stream_take(&st, k);
		n += k;
	}
	return n;
}

static const char *PROG_TEXT = "G21 G90\n"
                               "G0 X1 Y1\n"
                               "G1 X2 Y1.1 F1200\n"
                               "G2 X12 Y1.1 I5 J0\n"
                               "G1 X12.1 Y1.3\n"
                               "G1 X12.2 Y1.35\n"
                               "G1 X12.3 Y1.38\n"
                               "G4 P0.5\n"
                               "G1 X20 Y5\n";

static void same_as_feed(int smooth, uint32_t take)
{
	struct mlip_machine m = machine();
	static struct mlip_ring_rec got[20000], want[20000];
	struct mlip_program_list l;
	m.smooth = (uint8_t)smooth;
	size_t n = stream_all(PROG_TEXT, &m, smooth, got, 20000, take);
	/* what mlip-feed sends: the program's blocks (through the filter), 1..n, END */
	assert_int_equal(mlip_program_list_parse(PROG_TEXT, strlen(PROG_TEXT), &m, &l), 0);
	struct mlip_block *blocks = l.blocks;
	size_t nb = l.n;
	if (smooth) {
		assert_int_equal(mlip_smooth_program(&m, l.blocks, l.n, &blocks, &nb), 0);
	}
	for (size_t i = 0; i < nb; i++) {
		mlip_ring_rec_from_block(&want[i], &blocks[i], i + 1);
	}
	mlip_ring_rec_end(&want[nb], nb + 1, 9);
	assert_int_equal(n, nb + 1);
	for (size_t i = 0; i < n; i++) {
		if (memcmp(&got[i], &want[i], sizeof got[i]) != 0) {
			fail_msg("record %zu differs (smooth %d)", i, smooth);
		}
	}
	assert_true(nb > 50); /* the arc's chords */
	if (smooth) {
		free(blocks);
	}
	mlip_program_list_free(&l);
}

static void test_stream_equals_program(void **state)
{
	(void)state;
	same_as_feed(0, GRBL_STAGE);
	same_as_feed(0, 3); /* the arc in parts, parsed again each time */
	same_as_feed(1, GRBL_STAGE);
	same_as_feed(1, 7);
}

static void test_refused_line_changes_nothing(void **state)
{
	(void)state;
	struct mlip_machine m = machine();
	double zero[MLIP_MAX_AXES] = {0};
	struct mlip_gcode_error e;
	grbl_stream_init(&st, &m, zero, NULL);
	assert_int_equal(grbl_stream_line(&st, "G91 G1 X1 F600", 14, 1, &e), 1);
	struct mlip_gcode before = st.g;
	uint32_t staged = grbl_stream_staged(&st);
	assert_true(grbl_stream_line(&st, "G90 G0 X2 Y5000", 15, 2, &e) < 0);
	assert_int_equal(e.line, 2);
	assert_int_equal(e.col, 11);
	assert_memory_equal(&before, &st.g, sizeof before); /* still G91, G1 */
	assert_int_equal(grbl_stream_staged(&st), staged);
	assert_int_equal(grbl_stream_line(&st, "X1", 2, 3, &e), 1);
	assert_true(fabs(grbl_stream_pos(&st)[0] - 2.0) < 1e-12); /* relative, as before */
}

static void test_m2_ends_program_with_grbl_reset(void **state)
{
	(void)state;
	struct mlip_machine m = machine();
	double zero[MLIP_MAX_AXES] = {0};
	struct mlip_gcode_error e;
	grbl_stream_init(&st, &m, zero, NULL);
	assert_int_equal(grbl_stream_line(&st, "G91 G0 X1", 9, 1, &e), 1);
	assert_int_equal(grbl_stream_line(&st, "G55 M2", 6, 2, &e), 1);
	assert_true(grbl_stream_ended(&st));
	uint32_t n = grbl_stream_staged(&st);
	const struct mlip_ring_rec *r = grbl_stream_peek(&st);
	assert_int_equal(n, 2);
	assert_int_equal(r[1].type, MLIP_REC_END);
	assert_int_equal(r[1].seq, 2);
	grbl_stream_take(&st, n);
	/* gcode.c's program end: G1 G17 G90 G94 G54; the next line starts program 2 */
	assert_int_equal(st.g.motion, 1);
	assert_int_equal(st.g.absolute, 1);
	assert_int_equal(st.g.off.select, 0);
	assert_int_equal(grbl_stream_line(&st, "X5 F600", 7, 3, &e), 1);
	assert_false(grbl_stream_ended(&st));
	r = grbl_stream_peek(&st);
	assert_int_equal(r[0].seq, 1);
	assert_true(r[0].target[0] == 5.0 && !(r[0].flags & MLIP_REC_RAPID));
}

/* Pn: in Grbl's order (report.c: P, the axes, R, H, S); an axis shows for
 * either limit or its home switch. */
static void test_pins(void **state)
{
	(void)state;
	struct mlip_machine m = machine();
	char b[16];
	grbl_pins(b, sizeof b, 0, &m);
	assert_string_equal(b, "");
	grbl_pins(b, sizeof b,
	          (1u << MLIP_IN_ESTOP) | (1u << MLIP_IN_PROBE) | (1u << MLIP_IN_LIMIT_POS(0)) |
	              (1u << MLIP_IN_HOME_SW(2)) | (1u << MLIP_IN_CYCLE_START) |
	              (1u << MLIP_IN_HOLD),
	          &m);
	assert_string_equal(b, "PXZRHS");
	grbl_pins(b, sizeof b, 1u << MLIP_IN_LIMIT_NEG(1), &m);
	assert_string_equal(b, "Y");
	grbl_pins(b, 3, (1u << MLIP_IN_PROBE) | (1u << MLIP_IN_ESTOP) | (1u << MLIP_IN_HOLD), &m);
	assert_string_equal(b, "PR"); /* cut to the buffer, terminated */
}

static void test_accessories_and_alarms(void **state)
{
	(void)state;
	char b[8];
	grbl_accessories(b, sizeof b, 12000, MLIP_COOLANT_FLOOD | MLIP_COOLANT_MIST);
	assert_string_equal(b, "SFM");
	grbl_accessories(b, sizeof b, -500, 0);
	assert_string_equal(b, "C");
	grbl_accessories(b, sizeof b, 0, MLIP_COOLANT_MIST);
	assert_string_equal(b, "M");
	grbl_accessories(b, sizeof b, 0, 0);
	assert_string_equal(b, "");
	assert_int_equal(grbl_alarm_of(MLIP_STATE_IDLE, MLIP_WHY_END, MLIP_STATE_RUNNING), 0);
	assert_int_equal(grbl_alarm_of(MLIP_STATE_ESTOP, MLIP_WHY_ESTOP, MLIP_STATE_RUNNING), 3);
	assert_int_equal(grbl_alarm_of(MLIP_STATE_ESTOP, MLIP_WHY_ESTOP, MLIP_STATE_HOMING), 6);
	assert_int_equal(grbl_alarm_of(MLIP_STATE_FAULT, MLIP_WHY_LIMIT, MLIP_STATE_RUNNING), 1);
	assert_int_equal(
	    grbl_alarm_of(MLIP_STATE_FAULT, MLIP_WHY_HOMING_TIMEOUT, MLIP_STATE_HOMING), 9);
	assert_int_equal(grbl_alarm_of(MLIP_STATE_FAULT, MLIP_WHY_DRIVE, MLIP_STATE_RUNNING), 3);
	assert_true(grbl_resettable(MLIP_STATE_ESTOP, MLIP_WHY_ESTOP));
	assert_true(grbl_resettable(MLIP_STATE_FAULT, MLIP_WHY_LIMIT));
	assert_true(grbl_resettable(MLIP_STATE_FAULT, MLIP_WHY_HOMING_ERROR));
	assert_false(grbl_resettable(MLIP_STATE_FAULT, MLIP_WHY_BAD_RECORD));
	assert_false(grbl_resettable(MLIP_STATE_IDLE, MLIP_WHY_NONE));
}

/* A manual spindle's or coolant's event is done when its pause is left by
 * a resume, whatever follows; not when a stop or an E-stop ends it. */
static void test_accessory_tracking(void **state)
{
	(void)state;
	struct grbl_acc a;
	memset(&a, 0, sizeof a);
	grbl_acc_update(&a, MLIP_STATE_RUNNING, MLIP_WHY_START, 1, 0);
	grbl_acc_update(&a, MLIP_STATE_PAUSED, MLIP_WHY_SPINDLE, 3, 12000);
	grbl_acc_update(&a, MLIP_STATE_PAUSED, MLIP_WHY_SPINDLE, 3, 12000);
	assert_true(a.rpm == 0.0 && a.changes == 0); /* waiting for the operator */
	grbl_acc_update(&a, MLIP_STATE_RUNNING, MLIP_WHY_RESUME, 3, 0);
	assert_true(a.rpm == 12000.0 && a.changes == 1);
	/* two events in a row: the second pause means the first was resumed */
	grbl_acc_update(&a, MLIP_STATE_PAUSED, MLIP_WHY_COOLANT, 5, MLIP_COOLANT_FLOOD);
	grbl_acc_update(&a, MLIP_STATE_PAUSED, MLIP_WHY_SPINDLE, 6, -8000);
	assert_int_equal(a.coolant, MLIP_COOLANT_FLOOD);
	/* resumed, and the program's end came before the next status was read */
	grbl_acc_update(&a, MLIP_STATE_IDLE, MLIP_WHY_END, 7, 0);
	assert_true(a.rpm == -8000.0 && a.changes == 3);
	/* a stop while paused: not done */
	grbl_acc_update(&a, MLIP_STATE_PAUSED, MLIP_WHY_SPINDLE, 2, 0);
	grbl_acc_update(&a, MLIP_STATE_IDLE, MLIP_WHY_STOP, 2, 0);
	assert_true(a.rpm == -8000.0 && a.pending == 0);
	grbl_acc_update(&a, MLIP_STATE_PAUSED, MLIP_WHY_COOLANT, 4, 0);
	grbl_acc_update(&a, MLIP_STATE_ESTOP, MLIP_WHY_ESTOP, 4, 0);
	assert_int_equal(a.coolant, MLIP_COOLANT_FLOOD);
}

/* The controller's spindle (status layout 10) as A:, FS and Ov take it:
 * only values the controller can publish; the override bytes step within
 * its 50..200 %. */
static void test_bus_spindle(void **state)
{
	(void)state;
	double rpm = 1;
	int ov = 0;
	char b[8];
	assert_int_equal(grbl_spindle_of(MLIP_SPINDLE_AT_SPEED + 1, -6600, 110, 24000, &rpm, &ov),
	                 0);
	assert_true(rpm == -6600 && ov == 110);
	grbl_accessories(b, sizeof b, rpm, 0);
	assert_string_equal(b, "C");
	assert_int_equal(grbl_spindle_of(MLIP_SPINDLE_STOPPED + 1, 0, 100, 24000, &rpm, &ov), 0);
	assert_true(rpm == 0 && ov == 100);
	/* refused, nothing taken: no phase, a phase beyond FAULT, a speed
	 * beyond MAX_RPM or not a number, an override outside 50..200 */
	rpm = 7;
	ov = 7;
	assert_int_equal(grbl_spindle_of(0, 0, 100, 24000, &rpm, &ov), -1);
	assert_int_equal(grbl_spindle_of(MLIP_SPINDLE_FAULT + 2, 0, 100, 24000, &rpm, &ov), -1);
	assert_int_equal(grbl_spindle_of(3, 24000.1, 100, 24000, &rpm, &ov), -1);
	assert_int_equal(grbl_spindle_of(3, NAN, 100, 24000, &rpm, &ov), -1);
	assert_int_equal(grbl_spindle_of(3, 1000, 49, 24000, &rpm, &ov), -1);
	assert_int_equal(grbl_spindle_of(3, 1000, 201, 24000, &rpm, &ov), -1);
	assert_true(rpm == 7 && ov == 7);
	/* commands.md: 0x99 100 %, 0x9A +10, 0x9B -10, 0x9C +1, 0x9D -1 */
	assert_int_equal(grbl_spindle_ov_step(grbl_rt_of(0x9A), 100), 110);
	assert_int_equal(grbl_spindle_ov_step(grbl_rt_of(0x9B), 100), 90);
	assert_int_equal(grbl_spindle_ov_step(grbl_rt_of(0x9C), 100), 101);
	assert_int_equal(grbl_spindle_ov_step(grbl_rt_of(0x9D), 100), 99);
	assert_int_equal(grbl_spindle_ov_step(grbl_rt_of(0x99), 170), 100);
	assert_int_equal(grbl_spindle_ov_step(grbl_rt_of(0x9B), 55), 50); /* not Grbl's 10 */
	assert_int_equal(grbl_spindle_ov_step(grbl_rt_of(0x9D), 50), 50);
	assert_int_equal(grbl_spindle_ov_step(grbl_rt_of(0x9A), 195), 200);
	assert_int_equal(grbl_spindle_ov_step(grbl_rt_of(0x91), 120), 120); /* a feed byte */
}

/* $21..$25 from the machine: homing directions from the CiA 402 methods,
 * the slowest axis' speeds, listed only where homing is configured. */
static void test_homing_settings(void **state)
{
	(void)state;
	static struct mlip_config c;
	memset(&c, 0, sizeof c);
	c.machine = machine();
	assert_int_equal(grbl_home_negative(17), 1); /* negative limit switch */
	assert_int_equal(grbl_home_negative(18), 0);
	assert_int_equal(grbl_home_negative(1), 1);
	assert_int_equal(grbl_home_negative(21), 1); /* negative home switch */
	assert_int_equal(grbl_home_negative(19), 0);
	assert_int_equal(grbl_home_negative(27), 1);
	assert_int_equal(grbl_home_negative(33), 1);
	assert_int_equal(grbl_home_negative(34), 0);
	assert_int_equal(grbl_home_negative(35), -1); /* the current position */
	assert_int_equal(grbl_home_negative(37), -1);
	struct grbl_homing h;
	grbl_homing_of(&c, &h);
	assert_false(h.enabled);
	c.home.axis[0] = (struct mlip_axis_home){1, 17, 10, 1, 100, 0, 1, 60};
	c.home.axis[2] = (struct mlip_axis_home){1, 18, 5, 2, 100, 0, 0, 60};
	grbl_homing_of(&c, &h);
	assert_true(h.enabled && h.dir_mask == 1);
	assert_true(h.feed_mm_min == 60.0 && h.seek_mm_min == 300.0);
	h.hard_limits = 1;
	struct grbl_fmt fmt = {1, 0};
	char b[GRBL_MSG_BYTES];
	const char *want[] = {"$21=1",      "$22=1",       "$23=1",
	                      "$24=60.000", "$25=300.000", "$100=1000.000"};
	int n = 0, at = 0;
	for (; grbl_setting_line(b, sizeof b, &c.machine, &fmt, &h, n) > 0; n++) {
		if (at < 6 && strcmp(b, want[at]) == 0) {
			at++;
		}
	}
	assert_int_equal(at, 6);
	assert_int_equal(n, 10 + 4 * 3);
	/* a --config that is not the controller's machine */
	struct mlip_machine m2 = c.machine;
	assert_false(grbl_machine_differs(&c.machine, &m2, b, sizeof b));
	m2.axis[1].max_accel = 999;
	assert_true(grbl_machine_differs(&c.machine, &m2, b, sizeof b));
	assert_non_null(strstr(b, "axis 1"));
}

/* $G shows the parser's spindle, coolant, tool and speed (report.c: M7 and
 * M8 both when both are on). */
static void test_gcode_state_io(void **state)
{
	(void)state;
	struct mlip_machine m = machine();
	struct mlip_gcode g;
	char b[GRBL_MSG_BYTES];
	mlip_gcode_init(&g, &m);
	g.spindle = 4;
	g.s_rpm = 9000;
	g.coolant = MLIP_COOLANT_MIST | MLIP_COOLANT_FLOOD;
	g.tool_sel = 2;
	grbl_gcode_state(b, sizeof b, &g, -1);
	assert_string_equal(b, "[GC:G0 G54 G17 G21 G90 G94 M4 M7 M8 T2 F0 S9000]");
}

/* ---- the server's parts (tools/lib/grblsrv.h) on a ring in memory, the
 * controller played by the test: what a reset (0x18) does when the
 * controller has taken the queued records but its last status still says
 * idle (it publishes its status at the end of the period that took them) */

/* mlip-grbl.c's lock on the segment (rt/): the test owns the ring */
static int take_producer(void)
{
	return 0;
}

#define CAP 64
static unsigned char mem[1 << 16] MLIP_RING_ALIGNED;

static void serve(void)
{
	struct mlip_machine m = machine();
	double home[MLIP_MAX_AXES] = {0};
	memset(&S, 0, sizeof S);
	assert_true(mlip_ring_bytes(CAP) <= sizeof mem);
	assert_int_equal(mlip_ring_format_machine(mem, sizeof mem, CAP, &m), MLIP_OK);
	S.r = (struct mlip_ring *)mem;
	S.m = m;
	S.shm_name = "/test";
	S.take_producer = take_producer;
	S.ov_feed = S.ov_rapid = S.ov_spindle = 100;
	S.ov_post = S.sp_post = -1;
	assert_int_equal(mlip_ring_port_open(&S.tx, S.r, 1), MLIP_OK);
	S.port_open = S.locked = 1;
	grbl_stream_init(&S.st, &m, home, NULL);
	S.cs.state = MLIP_STATE_IDLE;
	S.cs.heartbeat = 100;
	S.cs_ok = 1;
}

/* A line is queued (its program open: the sender sends on); the controller
 * takes its records (pre-read) and, before its status says so, the sender
 * resets: the reset must stop what the controller holds (the stop counter)
 * and end its program (an END), or the controller pre-reads it for ever
 * (Run until the sender gives up: the race seen in test_grbl.py's
 * test_jog_moves_without_touching_the_modal_state). */
static void test_reset_stops_records_the_status_does_not_show_yet(void **state)
{
	(void)state;
	struct mlip_gcode_error e;
	struct mlip_ring_rec rec;
	serve();
	assert_int_equal(grbl_stream_line(&S.st, "G1 X100 F600", 12, 1, &e), 1);
	push_records();
	uint32_t queued = mlip_ring_count(S.r);
	assert_true(queued > 0);
	for (uint32_t k = 0; k < queued; k++) {
		assert_int_equal(mlip_ring_pop(S.r, &rec), MLIP_OK); /* the controller's period */
	}
	uint32_t stops = mlip_ring_stop_count(S.r);
	soft_reset();
	assert_int_equal(mlip_ring_stop_count(S.r), stops + 1);
	assert_true(S.reset_wait); /* the welcome once the controller is at rest */
	assert_int_equal(mlip_ring_pop(S.r, &rec), MLIP_OK);
	assert_int_equal(rec.type, MLIP_REC_END);
}

/* Once a status of a later period says idle with nothing queued, the
 * machine is at rest: a reset then posts no stop and welcomes at once. */
static void test_reset_of_an_idle_machine_posts_nothing(void **state)
{
	(void)state;
	struct mlip_gcode_error e;
	struct mlip_ring_rec rec;
	serve();
	assert_int_equal(grbl_stream_line(&S.st, "G1 X1 F600", 10, 1, &e), 1);
	assert_int_equal(grbl_stream_end(&S.st), 1);
	push_records();
	while (mlip_ring_pop(S.r, &rec) == MLIP_OK) {
	}
	S.cs.heartbeat += 2; /* run and ended: its status is from after the push */
	S.program_live = 0;
	uint32_t stops = mlip_ring_stop_count(S.r);
	soft_reset();
	assert_int_equal(mlip_ring_stop_count(S.r), stops);
	assert_false(S.reset_wait);
	assert_int_equal(mlip_ring_count(S.r), 0);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_realtime_bytes_anywhere),
	    cmocka_unit_test(test_utf8_realtime_bytes),
	    cmocka_unit_test(test_lines_cr_lf_and_buffer),
	    cmocka_unit_test(test_too_long_line),
	    cmocka_unit_test(test_overflow_answers_each_line),
	    cmocka_unit_test(test_system_lines),
	    cmocka_unit_test(test_status_report_and_refresh),
	    cmocka_unit_test(test_settings_and_params),
	    cmocka_unit_test(test_error_codes),
	    cmocka_unit_test(test_stream_equals_program),
	    cmocka_unit_test(test_refused_line_changes_nothing),
	    cmocka_unit_test(test_m2_ends_program_with_grbl_reset),
	    cmocka_unit_test(test_pins),
	    cmocka_unit_test(test_accessories_and_alarms),
	    cmocka_unit_test(test_accessory_tracking),
	    cmocka_unit_test(test_bus_spindle),
	    cmocka_unit_test(test_homing_settings),
	    cmocka_unit_test(test_reset_stops_records_the_status_does_not_show_yet),
	    cmocka_unit_test(test_reset_of_an_idle_machine_posts_nothing),
	    cmocka_unit_test(test_gcode_state_io),
	};
	return cmocka_run_group_tests_name("grbl", tests, NULL, NULL);
}
