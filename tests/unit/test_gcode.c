/*
 * test_gcode.c - the G-code front end: lexing, every error class with its
 * line and column, modal state, units, arcs in the three planes, merging,
 * notices, the axis scan, and the real toolpaths of /work/shared.
 */
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <errno.h>

#include <cmocka.h>

#include "mlip/gcode/gcode.h"
#include "../../tools/lib/offsetfile.h"
#include "../../tools/lib/program.h"

#include <sys/stat.h>
#include <unistd.h>

#define M_PI_VALUE 3.14159265358979323846
#define PI_2       (M_PI_VALUE / 2)
#define EPS        0.01                            /* machine contour tolerance in these tests */
#define SAG        (MLIP_GCODE_ARC_FRACTION * EPS) /* chord sagitta allowed */

/* cmocka 1.1.5 has no double comparison: keep our own */
#define assert_near(a, b, tol) near_impl((a), (b), (tol), #a, __FILE__, __LINE__)
static void near_impl(double a, double b, double tol, const char *what, const char *file, int line)
{
	if (!(fabs(a - b) <= tol)) {
		print_error("%s = %.12g, expected %.12g +- %g\n", what, a, b, tol);
		_fail(file, line);
	}
}

static struct mlip_machine machine(const char *axes)
{
	struct mlip_machine m;
	int i;

	memset(&m, 0, sizeof m);
	m.n_axes = (int)strlen(axes);
	for (i = 0; i < m.n_axes; i++) {
		m.axis[i].letter = axes[i];
		m.axis[i].kind = strchr("ABC", axes[i]) ? MLIP_AXIS_ROTARY : MLIP_AXIS_LINEAR;
		m.axis[i].max_accel = 1000;
		m.axis[i].max_vel = 200;
		m.axis[i].min_limit = -1000;
		m.axis[i].max_limit = 1000;
	}
	m.max_feed_mm_s = 200;
	m.max_rot_feed_deg_s = 360;
	m.tolerance_mm = EPS;
	m.period_s = 0.001;
	return m;
}

/* Parse text that must be valid. */
static void parse_ok(const char *text, const struct mlip_machine *m, struct mlip_program_list *p)
{
	int rc = mlip_program_list_parse(text, strlen(text), m, p);

	if (rc != 0) {
		mlip_program_print_errors(&p->r, "<test>", stderr);
	}
	assert_int_equal(rc, 0);
}

/* The first error of text is at line:col and its message contains part. */
static void check_err_m(const char *text, const struct mlip_machine *m, uint32_t line, uint32_t col,
                        const char *part)
{
	struct mlip_program_list p;
	int rc = mlip_program_list_parse(text, strlen(text), m, &p);

	assert_int_equal(rc, 1);
	assert_true(p.n_errors >= 1);
	if (!strstr(p.errors[0].msg, part) || p.errors[0].line != line || p.errors[0].col != col) {
		print_error("for \"%s\": got %u:%u \"%s\", expected %u:%u \"%s\"\n", text,
		            (unsigned)p.errors[0].line, (unsigned)p.errors[0].col, p.errors[0].msg,
		            (unsigned)line, (unsigned)col, part);
		mlip_program_list_free(&p);
		fail();
	}
	mlip_program_list_free(&p);
}

static void check_err(const char *text, uint32_t line, uint32_t col, const char *part)
{
	struct mlip_machine m = machine("XYZ");

	check_err_m(text, &m, line, col, part);
}

static struct mlip_machine big_machine(const char *axes)
{
	struct mlip_machine m = machine(axes);
	int i;

	for (i = 0; i < m.n_axes; i++) {
		m.axis[i].min_limit = -1e6;
		m.axis[i].max_limit = 1e6;
	}
	return m;
}

/* ---- sink for direct calls ---- */

struct cap {
	struct mlip_block b[64];
	size_t n;
	size_t limit; /* refuse blocks beyond this many */
};

static int cap_sink(void *ctx, const struct mlip_block *b)
{
	struct cap *c = ctx;

	if (c->n >= c->limit || c->n >= 64) {
		return 1;
	}
	c->b[c->n++] = *b;
	return 0;
}

static mlip_status line(struct mlip_gcode *g, const char *s, uint32_t no, struct cap *c,
                        struct mlip_gcode_error *e)
{
	return mlip_gcode_line(g, s, strlen(s), no, cap_sink, c, e);
}

/* ---- lexing ---- */

static void test_numbers(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;

	(void)state;
	parse_ok("G1 X-.5 Y5. Z+3 F100\n"
	         "g1x40.0781y-0.0001 z 2\n" /* lower case, no spaces, space in word */
	         "G1 X 1.5 Y -2 Z -1\n"     /* blanks between letter and number */
	         "G0x10\n",                 /* "0x10" is G0 X10, not hex */
	         &m, &p);
	assert_int_equal(p.n, 4);
	assert_near(p.blocks[0].target[0], -0.5, 0);
	assert_near(p.blocks[0].target[1], 5.0, 0);
	assert_near(p.blocks[0].target[2], 3.0, 0);
	assert_true(p.blocks[1].target[0] == strtod("40.0781", NULL)); /* correctly rounded */
	assert_true(p.blocks[1].target[1] == -0.0001);
	assert_near(p.blocks[1].target[2], 2.0, 0);
	assert_near(p.blocks[2].target[0], 1.5, 0);
	assert_near(p.blocks[2].target[1], -2.0, 0);
	assert_near(p.blocks[2].target[2], -1.0, 0);
	assert_near(p.blocks[3].target[0], 10.0, 0);
	assert_int_equal(p.blocks[3].rapid, 1);
	mlip_program_list_free(&p);
}

static void test_malformed_numbers(void **state)
{
	(void)state;
	check_err("G1 X1.2.3 F100", 1, 5, "malformed number '1.2.3'");
	check_err("G1 X1e5 F100", 1, 5, "malformed number '1e5'");
	check_err("G1 X1E-5 F100", 1, 5, "malformed number '1E-5'");
	check_err("G1 Xnan F100", 1, 5, "malformed number 'nan'");
	check_err("G1 X INF F100", 1, 6, "malformed number 'INF'");
	check_err("G1 X--1 F100", 1, 5, "malformed number '--1'");
	check_err("G1 X. F100", 1, 5, "malformed number '.'");
	check_err("G1 X- F100", 1, 5, "malformed number '-'");
	check_err("G1 X1-2 F100", 1, 5, "malformed number '1-2'");
	check_err("G1 F100\nX1 .5", 2, 4, "number '.5' without a word letter");
	check_err("G1 X F100", 1, 4, "word X has no number");
	check_err("G1 F100 X", 1, 9, "word X has no number");
	check_err("G F100", 1, 1, "word G has no number");
	check_err("G1 X1 E5 F100", 1, 7, "unknown word letter E");
	check_err("G1 U1 F100", 1, 4, "axis U not supported");
	/* parameters and expressions: tests/unit/test_expr.c */
	check_err("G1 X#<nope> F100", 1, 5, "named parameter #<nope> is not set");
	check_err("O100 sub\nG1 X1 F100", 1, 1,
	          "O-words (subroutines, loops, conditions) not "
	          "supported: have the CAM expand them");
	check_err("G1 X1 F100\n  o<x> call", 2, 3, "O-words");
	check_err("G1 X1 \x01 F100", 1, 7, "unexpected character 0x01");
}

static void test_bytes_and_comments(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	static const char nul[] = "G1 X1 F100\nG1 X2\0 Y1\n";

	(void)state;
	parse_ok("\xEF\xBB\xBF%\n"                   /* a byte order mark is skipped */
	         "(T1 \xC3\x98 6mm flat end mill)\n" /* well-formed UTF-8 in a comment */
	         "G1 X1 F100 ; caf\xC3\xA9 \xE2\x82\xAC\n"
	         "G1 X2 (mid-line comment) Y1\r\n" /* CRLF */
	         "  \t\n"
	         "N10 G1 X3\n"
	         "%\n",
	         &m, &p);
	assert_int_equal(p.n, 3);
	assert_near(p.blocks[1].target[1], 1.0, 0);
	assert_int_equal(p.blocks[2].line, 6);
	assert_int_equal(p.lines, 7);
	mlip_program_list_free(&p);

	check_err("G1 X1 F100 \xC3\x98", 1, 12, "non-ASCII byte 0xC3 outside a comment");
	check_err("G1 X1 F100 (bad \xC3\x28 utf8)", 1, 17, "invalid UTF-8 in comment");
	check_err("G1 X1 F100 ; \xE0\x80\x80 overlong", 1, 14, "invalid UTF-8 in comment");
	check_err("G1 X1 F100 (\xED\xA0\x80 surrogate)", 1, 13, "invalid UTF-8 in comment");
	check_err("G1 X1 F100 (no end", 1, 12, "unterminated comment");
	check_err("G1 F100\n% X1", 2, 3, "'%' must be alone on its line");
	check_err("G1 F100\n X1 G1 X2", 2, 8, "duplicate X word (first at column 2)");
	check_err("G1 F100 F200 X1", 1, 9, "duplicate F word");

	/* NUL bytes, in and out of comments */
	{
		struct mlip_program_list q;
		int rc = mlip_program_list_parse(nul, sizeof nul - 1, &m, &q);

		assert_int_equal(rc, 1);
		assert_int_equal(q.errors[0].line, 2);
		assert_int_equal(q.errors[0].col, 6);
		assert_string_equal(q.errors[0].msg, "NUL byte in line");
		mlip_program_list_free(&q);
	}
	{
		static const char c[] = "G1 X1 F100 (a\0b)";
		struct mlip_program_list q;

		assert_int_equal(mlip_program_list_parse(c, sizeof c - 1, &m, &q), 1);
		assert_int_equal(q.errors[0].col, 14);
		assert_string_equal(q.errors[0].msg, "NUL byte in line");
		mlip_program_list_free(&q);
	}
}

static void test_line_too_long(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	char text[600];

	(void)state;
	/* exactly MLIP_GCODE_MAX_LINE is fine (trailing comment pads it) */
	memset(text, 0, sizeof text);
	strcpy(text, "G1 X1 F100 (");
	memset(text + strlen(text), 'a', MLIP_GCODE_MAX_LINE - strlen(text) - 1);
	strcat(text, ")");
	assert_int_equal(strlen(text), MLIP_GCODE_MAX_LINE);
	parse_ok(text, &m, &p);
	mlip_program_list_free(&p);

	strcpy(text + MLIP_GCODE_MAX_LINE - 1, "a)\nG1 X2");
	check_err(text, 1, MLIP_GCODE_MAX_LINE + 1, "line too long: 257 bytes, at most 256");
}

/* ---- codes ---- */

static void test_unsupported_codes(void **state)
{
	(void)state;
	check_err("G1 X1 F100\nG41 D1 X2", 2, 1,
	          "unsupported G code G41: cutter radius compensation");
	check_err("G43 H1", 1, 1, "G43: a tool length offset needs the machine's config");
	check_err("G43.2 H1", 1, 1, "unsupported G code G43.2: an additional tool length offset");
	check_err("G38.2 Z-10 F10", 1, 1,
	          "G38.2: probing needs the machine's config (--config) with a probe input "
	          "([IO] PROBE)");
	check_err("G84 X1 Y1 Z-1 R1 F10", 1, 1, "unsupported G code G84: tapping cycle");
	check_err("G52 X1", 1, 1, "unsupported G code G52: local offsets (use G92 or G10 L2)");
	check_err("G59.4", 1, 1, "unsupported G code G59.4");
	check_err("G54.1 P2", 1, 1, "unsupported G code G54.1");
	check_err("G93.1", 1, 1, "unsupported G code G93.1");
	check_err("G90.1", 1, 1, "unsupported G code G90.1: absolute arc centers");
	check_err("G10 L1 P1 Z5", 1, 5, "G10 without L2 or L20: only work offsets");
	check_err("G10 P1 X5", 1, 1, "G10 without L2 or L20");
	check_err("G10 L2 P10 X5", 1, 8, "G10 L2 needs P0..P9");
	check_err("G10 L20 P1.5 X5", 1, 9, "G10 L20 needs P0..P9");
	check_err("G10 L2 X5", 1, 1, "G10 L2 needs P0..P9");
	check_err("G10 L2 P1 R30 X5", 1, 11, "G10 R (rotated coordinate system) not supported");
	check_err("G10 L2 P1 G1 X5 F10", 1, 11, "G10 and G1 on one line: both use axis words");
	check_err("G92 G0 X5", 1, 5, "G92 and G0 on one line: both use axis words");
	check_err("G92", 1, 1, "G92 without axis words");
	check_err("G92.1 X0", 1, 7, "G92.1 takes no axis words");
	check_err("G28.1 X0", 1, 7, "G28.1 takes no axis words");
	check_err("G4", 1, 1, "G4 without P: write the dwell in seconds");
	check_err("G4 P-1", 1, 4, "G4 P must be >= 0 seconds");
	check_err("G4 G10 L2 P1 X0", 1, 4, "G4 and G10 on one line: same modal group");
	check_err("G4 G64 P1", 1, 8, "P word with two of G4, G10, G64");
	check_err("G1 X1 F10 L2", 1, 11, "L word without G10");
	check_err("G1 X1 F10 Q2", 1, 11, "Q word without G64");
	check_err("G1 X1 F10\nG12 X1", 2, 1, "unsupported G code G12");
	check_err("G1.5 X1 F10", 1, 1, "unsupported G code G1.5");
	check_err("G1 X1 F10 M98 P100", 1, 11, "unsupported M code M98");
	check_err("G1 X1 F10 M62.1", 1, 11, "unsupported M code M62.1");
	check_err("G1 X1 F10 M66 P1", 1, 11, "unsupported M code M66: a wait for an input");
	check_err("G1 X1 F10 M67 E1", 1, 11, "unsupported M code M67: a wait for an input");
	check_err("M70\nG1 X1 F10", 1, 1, "unsupported M code M70: saving and restoring");
	check_err("M200\nG1 X1 F10", 1, 1, "unsupported M code M200");
	check_err("M99\nG1 X1 F10", 1, 1, "unsupported M code M99: subprogram calls");
	check_err("G1 G2 X1 F10", 1, 4, "two motion codes on one line: G1 and G2");
	check_err("G1 X1 F10 G0", 1, 11, "two motion codes on one line: G1 and G0");
	check_err("G90 G91 G1 X1 F10", 1, 5, "G90 and G91 on one line: same modal group");
	check_err("G1 X1 F10 P2", 1, 11, "P word without G2/G3, G4, G10, G64 or M64/M65");
	check_err("G53 G91 G0 X1", 1, 1, "G53 with G91");
	check_err("G1 X1 F10\nG53 G2 X0 I-1", 2, 1, "G53 needs G0 or G1");
}

static void test_notices(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	uint32_t k;
	int seen = 0;

	(void)state;
	parse_ok("G90 G94 G17 G21 G40 G49 G80 G91.1\n"
	         "T1 M6 G61.1\n"
	         "S5000 M3\n"
	         "G54 G64 P0.01\n"
	         "M8 G61\n"
	         "G53 G0 Z-3\n"
	         "S6000 M4\n"
	         "G1 X1 F100\n"
	         "M5 M9\n"
	         "G53 G0 Z-2\n"
	         "M2 M30\n",
	         &m, &p);
	assert_int_equal(p.n, 3);
	for (k = 0; k < p.n_notices; k++) {
		const struct mlip_gcode_notice *n = &p.notices[k];

		/* modes that act on motion or offsets: never notices */
		assert_true(
		    strcmp(n->word, "G17") && strcmp(n->word, "G21") && strcmp(n->word, "G90") &&
		    strcmp(n->word, "G91.1") && strcmp(n->word, "G53") && strcmp(n->word, "G54") &&
		    strcmp(n->word, "G61") && strcmp(n->word, "G64") && strcmp(n->word, "G94"));
		if (strcmp(n->word, "S") == 0) {
			assert_int_equal(n->first_line, 3);
			assert_int_equal(n->count, 2);
			seen++;
		} else if (strcmp(n->word, "M3") == 0 || strcmp(n->word, "G40") == 0) {
			assert_int_equal(n->count, 1);
			assert_string_equal(mlip_gcode_notice_text(n),
			                    "ignored (no effect on motion)");
			seen++;
		} else if (strcmp(n->word, "M2") == 0 || strcmp(n->word, "M30") == 0) {
			assert_int_equal(n->first_line, 11);
			assert_non_null(strstr(mlip_gcode_notice_text(n), "program end"));
			seen++;
		}
	}
	assert_int_equal(seen, 5);
	/* G40 G49 G80 T M6 S M3 M8 M4 M5 M9 M2 M30 */
	assert_int_equal(p.n_notices, 13);
	mlip_program_list_free(&p);
}

static void test_notice_overflow(void **state)
{
	struct mlip_gcode g;
	struct mlip_machine m = machine("XY");
	struct mlip_gcode_error e;
	struct cap c = {.n = 0, .limit = 64};
	char w[8];
	uint32_t k;

	(void)state;
	mlip_gcode_init(&g, &m);
	for (k = 0; k < MLIP_GCODE_MAX_NOTICES; k++) {
		/* M3 .. M9, then Grbl settings lines $10=1, $11=1, ...: all notices */
		if (k < 7) {
			snprintf(w, sizeof w, "M%u", (unsigned)(k + 3));
		} else {
			snprintf(w, sizeof w, "$%u=1", (unsigned)(k + 3));
		}
		assert_int_equal(line(&g, w, k + 1, &c, &e), MLIP_OK);
		assert_int_equal(line(&g, w, k + 100, &c, &e), MLIP_OK);
	}
	assert_int_equal(g.n_notices, MLIP_GCODE_MAX_NOTICES);
	for (k = 0; k < g.n_notices; k++) {
		assert_int_equal(g.notices[k].count, 2);
		assert_int_equal(g.notices[k].first_line, k + 1);
	}
	/* one more distinct word ("F": initial feed used) is dropped, not overflowed */
	mlip_gcode_set_initial_feed(&g, 100);
	assert_int_equal(line(&g, "G1 X1", 203, &c, &e), MLIP_OK);
	assert_int_equal(g.n_notices, MLIP_GCODE_MAX_NOTICES);
	assert_int_equal(c.n, 1);
}

/* ---- modal state, units, frames ---- */

static void test_modal(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;

	(void)state;
	parse_ok("G0 X1 Y1\n"
	         "X2\n" /* still G0 */
	         "G1 Z-1 F600\n"
	         "X3\n" /* still G1, F600 */
	         "Y3 F1200\n"
	         "G0 Z5 F30\n" /* F on a rapid: set, not used */
	         "X4\n"
	         "G1 X5\n",
	         &m, &p);
	assert_int_equal(p.n, 8);
	assert_int_equal(p.blocks[0].rapid, 1);
	assert_near(p.blocks[0].feed_mm_s, 200, 0); /* rapids: the machine's maximum */
	assert_int_equal(p.blocks[1].rapid, 1);
	assert_near(p.blocks[1].target[0], 2, 0);
	assert_near(p.blocks[1].target[1], 1, 0); /* unmentioned axes keep their value */
	assert_int_equal(p.blocks[2].rapid, 0);
	assert_near(p.blocks[2].feed_mm_s, 10.0, 1e-12);
	assert_int_equal(p.blocks[3].rapid, 0);
	assert_near(p.blocks[3].feed_mm_s, 10.0, 1e-12);
	assert_near(p.blocks[4].feed_mm_s, 20.0, 1e-12);
	assert_int_equal(p.blocks[5].rapid, 1);
	assert_int_equal(p.blocks[6].rapid, 1);
	assert_int_equal(p.blocks[7].rapid, 0);
	assert_near(p.blocks[7].feed_mm_s, 0.5, 1e-12);
	for (size_t k = 0; k < p.n; k++) {
		assert_near(p.blocks[k].tol_mm, EPS, 0);
		assert_int_equal(p.blocks[k].line, k + 1);
	}
	mlip_program_list_free(&p);

	/* Grbl starts in G0: axis words before any motion mode are a rapid, with
	 * a note; strict mode refuses them */
	parse_ok("X1 Y1\nY2\nG1 X2 F100\n", &m, &p);
	assert_int_equal(p.n, 3);
	assert_int_equal(p.blocks[0].rapid, 1);
	assert_int_equal(p.blocks[1].rapid, 1);
	assert_int_equal(p.blocks[2].rapid, 0);
	assert_int_equal(p.n_notices, 1);
	assert_string_equal(p.notices[0].word, "G0");
	assert_int_equal(p.notices[0].count, 1);
	mlip_program_list_free(&p);
	{
		struct mlip_gcode g;
		struct mlip_gcode_error e;
		struct cap c = {.n = 0, .limit = 64};

		mlip_gcode_init(&g, &m);
		mlip_gcode_set_strict(&g, 1);
		assert_int_equal(line(&g, "X1 Y1", 1, &c, &e), MLIP_E_SYNTAX);
		assert_int_equal(e.col, 1);
		assert_non_null(strstr(e.msg, "axis words with no motion mode"));
		assert_int_equal(c.n, 0);
	}
	check_err("G1 F100\nG1 X1 F0", 2, 7, "feed F must be positive");
	check_err("G1 X1 F-5", 1, 7, "feed F must be positive");
}

static void test_missing_feed(void **state)
{
	struct mlip_gcode g;
	struct mlip_machine m = machine("XYZ");
	struct mlip_gcode_error e;
	struct cap c = {.n = 0, .limit = 64};

	(void)state;
	/* the core, strict by default */
	mlip_gcode_init(&g, &m);
	assert_int_equal(line(&g, "G0 X1", 1, &c, &e), MLIP_OK);
	assert_int_equal(line(&g, "G1", 2, &c, &e), MLIP_OK); /* mode only: no move */
	assert_int_equal(line(&g, "  Y1", 3, &c, &e), MLIP_E_SYNTAX);
	assert_string_equal(e.msg, "missing feed: no F before the first feed move (a program with "
	                           "none runs with --default-feed F)");
	assert_int_equal(e.line, 3);
	assert_int_equal(e.col, 3);
	assert_int_equal(line(&g, "X2 G2 I1 J0", 4, &c, &e), MLIP_E_SYNTAX);
	assert_int_equal(e.col, 4); /* the motion word */
	assert_int_equal(c.n, 1);

	/* with an initial feed (what the tools pass: the program's first F) */
	mlip_gcode_init(&g, &m);
	mlip_gcode_set_initial_feed(&g, 120);
	c.n = 0;
	assert_int_equal(line(&g, "G1 X1", 1, &c, &e), MLIP_OK);
	assert_int_equal(line(&g, "G20 X1", 2, &c, &e), MLIP_OK);
	assert_int_equal(line(&g, "G21 F60 X2", 3, &c, &e), MLIP_OK);
	assert_int_equal(c.n, 3);
	assert_near(c.b[0].feed_mm_s, 2.0, 1e-12);
	assert_near(c.b[1].feed_mm_s, 2.0 * 25.4, 1e-12); /* F120 read in inches */
	assert_near(c.b[2].feed_mm_s, 1.0, 1e-12);
	assert_string_equal(g.notices[0].word, "F");
	assert_int_equal(g.notices[0].count, 2);
	assert_int_equal(g.notices[0].first_line, 1);

	/* the program helpers: no F anywhere is an error, a late F is used */
	check_err("G21\nG1 X1\nG0 Z1", 2, 1, "missing feed");
	{
		struct mlip_program_list p;

		parse_ok("G1 X1 Y2\nZ3\nG1 Z2 F333.3\n", &m, &p);
		assert_int_equal(p.n, 3);
		assert_near(p.blocks[0].feed_mm_s, 333.3 / 60, 1e-12);
		assert_near(p.r.initial_feed_word, 333.3, 0);
		assert_int_equal(p.r.initial_feed_line, 3);
		mlip_program_list_free(&p);
	}
	{
		double f = -1;

		assert_int_equal(mlip_gcode_scan_feed("(F10)\n;F20\nG1 F0\nX1 f 5.5\n", 26, &f), 4);
		assert_near(f, 5.5, 0);
		assert_int_equal(mlip_gcode_scan_feed("G1 X1 (F10)", 11, &f), 0);
	}
}

static void test_incremental_and_home(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;

	(void)state;
	m.axis[0].home = 5;
	m.axis[2].home = 100;
	parse_ok("G91 G1 X1 F60\n"
	         "X1 Y-2\n"
	         "G90 X1\n"
	         "G91 Z-10\n",
	         &m, &p);
	assert_int_equal(p.n, 4);
	assert_near(p.blocks[0].target[0], 6, 0);
	assert_near(p.blocks[0].target[2], 100, 0); /* start is home */
	assert_near(p.blocks[1].target[0], 7, 0);
	assert_near(p.blocks[1].target[1], -2, 0);
	assert_near(p.blocks[2].target[0], 1, 0);
	assert_near(p.blocks[3].target[2], 90, 0);
	mlip_program_list_free(&p);
}

static void test_inches_and_rotary(void **state)
{
	struct mlip_machine m = machine("XYZA");
	struct mlip_program_list p;

	(void)state;
	parse_ok("G20 G1 X1 A10 F10\n" /* mixed move: F is a path speed, in/min */
	         "A20\n"               /* rotary only: F is deg/min, not scaled */
	         "G91 Y0.5 A-5\n"
	         "G21 G90 X1\n"
	         "G20 G91 G1 X1 F1\n",
	         &m, &p);
	assert_int_equal(p.n, 5);
	assert_near(p.blocks[0].target[0], 25.4, 1e-12);
	assert_near(p.blocks[0].target[3], 10, 0);
	assert_near(p.blocks[0].feed_mm_s, 10 * 25.4 / 60, 1e-12);
	assert_near(p.blocks[1].target[3], 20, 0);
	assert_near(p.blocks[1].feed_mm_s, 10.0 / 60, 1e-12);
	assert_near(p.blocks[2].target[1], 12.7, 1e-12);
	assert_near(p.blocks[2].target[3], 15, 0);
	assert_near(p.blocks[3].target[0], 1, 0);
	assert_near(p.blocks[3].feed_mm_s, 10 * 25.4 / 60, 1e-12); /* speed kept across G21 */
	assert_near(p.blocks[4].target[0], 26.4, 1e-12);
	mlip_program_list_free(&p);
}

static void test_config_order_and_axes(void **state)
{
	struct mlip_machine m = machine("ZYX");
	struct mlip_machine xy = machine("XY");
	struct mlip_program_list p;

	(void)state;
	parse_ok("G1 X1 Y2 Z3 F100\n", &m, &p);
	assert_int_equal(p.n, 1);
	assert_near(p.blocks[0].target[0], 3, 0);
	assert_near(p.blocks[0].target[1], 2, 0);
	assert_near(p.blocks[0].target[2], 1, 0);
	assert_near(p.blocks[0].target[3], 0, 0); /* unused slots zeroed */
	mlip_program_list_free(&p);

	check_err_m("G1 X1 F100\nG1 X2 Z1 Y1", &xy, 2, 7, "axis Z not configured");
	check_err_m("G1 X1 F100\nG1 B1", &xy, 2, 4, "axis B not configured");
	check_err_m("G1 X1 F100\nG19 G2 Y1 J1", &xy, 2, 5,
	            "G2 in G19 needs axes Y and Z configured");
	check_err_m("G1 X1 F100\nG18 G3 X0 I-1", &xy, 2, 5,
	            "G3 in G18 needs axes Z and X configured");
}

static void test_soft_limits(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	int rc;

	(void)state;
	check_err("G1 Y2 F100\nX1200 Y3", 2, 1, "X 1200.000 beyond soft limit 1000.000");
	check_err("G1 F100\nG1 Y3 Z-1000.5", 2, 7, "Z -1000.500 beyond soft limit -1000.000");
	check_err("G91 G0 X600\nX600", 2, 1, "X 1200.000 beyond soft limit 1000.000");
	check_err("G20 G0 Y40", 1, 8, "Y 1016.000 beyond soft limit 1000.000");
	/* exactly on the limit is inside */
	parse_ok("G0 X1000 Y-1000\n", &m, &p);
	mlip_program_list_free(&p);
	/* an arc whose ends are inside but whose bulge is not: blamed on the motion
	 * word when the bulging axis has no word, and the line emits nothing */
	check_err("G0 X998 Y5\nG2 Y-5 I0 J-5 F100", 2, 1, "beyond soft limit 1000.000 on the arc");
	check_err("G0 X998 Y5\nG2 X998 Y-5 I0 J-5 F100", 2, 4,
	          "beyond soft limit 1000.000 on the arc");
	{
		static const char t[] = "G0 X998 Y5\nG2 Y-5 J-5 F100\nG1 X1\n";

		rc = mlip_program_list_parse(t, sizeof t - 1, &m, &p);
	}
	assert_int_equal(rc, 1);
	assert_int_equal(p.n_errors, 1);
	assert_int_equal(p.errors[0].col, 1);
	assert_int_equal(p.n, 2);                              /* the G0 and the G1 only */
	assert_near(p.blocks[1].feed_mm_s, 100.0 / 60, 1e-12); /* F of the bad line kept */
	mlip_program_list_free(&p);
	/* the small arc stays inside */
	parse_ok("G0 X998 Y5\nG3 Y-5 J-5 F100\n", &m, &p);
	mlip_program_list_free(&p);

	/* guard against non-finite values (a NaN home here) */
	m.axis[0].home = NAN;
	check_err_m("G1 Y1 F100", &m, 1, 1, "X value is not finite");
}

static void test_home_codes(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;

	(void)state;
	m.axis[2].home = 50; /* G28/G30 positions default to HOME */
	/* G28 G91 Z0 (SheepTile): intermediate point here, then Z to its G28
	 * position; the other axes stay */
	parse_ok("G1 X5 Y2 Z10 F100\n"
	         "G28 G91 Z0\n"
	         "G90 G28 X1\n" /* rapid to X1, then X to 0 */
	         "G28\n"        /* every axis to the G28 position */
	         "G1 X3 Y3 Z3\n"
	         "G30.1\n" /* store (3,3,3) */
	         "G0 X9\n"
	         "G30\n",
	         &m, &p);
	assert_int_equal(p.n, 8);
	assert_near(p.blocks[1].target[0], 5, 0);
	assert_near(p.blocks[1].target[2], 50, 0);
	assert_int_equal(p.blocks[1].rapid, 1);
	assert_near(p.blocks[2].target[0], 1, 0); /* intermediate */
	assert_near(p.blocks[3].target[0], 0, 0);
	assert_near(p.blocks[3].target[1], 2, 0);
	assert_near(p.blocks[4].target[1], 0, 0); /* G28 alone: Y too */
	assert_near(p.blocks[4].target[2], 50, 0);
	assert_near(p.blocks[7].target[0], 3, 0);
	assert_near(p.blocks[7].target[1], 3, 0);
	assert_near(p.blocks[7].target[2], 3, 0);
	assert_near(p.r.offsets_end.g30[0], 3, 0);
	mlip_program_list_free(&p);

	/* G28.1 stores, G28 goes there; the stored position is checked against
	 * the soft limits before anything moves */
	{
		struct mlip_program r;
		struct mlip_gcode_offsets o;
		struct mlip_program_options opt = {0, &o, 0, NULL, NULL, 0};
		static const char t[] = "G0 X1\nG28 Y5\n";

		mlip_gcode_offsets_init(&o, &m);
		o.g28[1] = 2000;
		assert_int_equal(mlip_program_open_mem(&r, t, sizeof t - 1, &m, &opt), 1);
		assert_int_equal(r.errors[0].line, 2);
		assert_int_equal(r.errors[0].col, 1);
		assert_non_null(strstr(r.errors[0].msg, "Y 2000.000 beyond soft limit 1000.000"));
		mlip_program_close(&r);
	}
	check_err("G1 X5 F100\nG28 G1 X5", 2, 5, "G28 and G1 on one line: both use axis words");
	check_err("G1 X5 F100\nG28 X2000", 2, 5, "X 2000.000 beyond soft limit 1000.000");
}

static void test_merge(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;

	(void)state;
	parse_ok("G1 X1 F100\n"
	         "X1.0000005\n" /* < MERGE from the last emitted point: dropped */
	         "X1\n"
	         "G91 X0.0000004\n" /* tiny steps accumulate from the last emitted point */
	         "X0.0000004\n"
	         "X0.0000004\n"
	         "X0.0000004\n"
	         "G90 X1.0000012\n",
	         &m, &p);
	assert_int_equal(p.n, 2);
	assert_near(p.blocks[1].target[0], 1.0000012, 1e-12);
	assert_int_equal(p.blocks[1].line, 6);
	mlip_program_list_free(&p);

	/* just above the threshold is kept */
	parse_ok("G1 X1 F100\nX1.0000011\n", &m, &p);
	assert_int_equal(p.n, 2);
	mlip_program_list_free(&p);
}

static void test_sink_full_and_empty(void **state)
{
	struct mlip_gcode g;
	struct mlip_machine m = machine("XY");
	struct mlip_gcode_error e;
	struct cap c = {.n = 0, .limit = 3};

	(void)state;
	mlip_gcode_init(&g, &m);
	assert_int_equal(mlip_gcode_finish(&g, 7, &e), MLIP_E_SYNTAX);
	assert_string_equal(e.msg, "empty program: no motion");
	assert_int_equal(e.line, 7);
	assert_int_equal(e.col, 0);
	assert_int_equal(line(&g, "G1 X1 F100", 1, &c, &e), MLIP_OK);
	assert_int_equal(line(&g, "G2 X-1 I-1", 2, &c, &e), MLIP_E_FULL); /* a half circle */
	assert_int_equal(c.n, 3);
	assert_int_equal(e.line, 2);
	assert_int_equal(mlip_gcode_finish(&g, 2, &e), MLIP_OK);
	/* the parser resumes from the last emitted point */
	c.limit = 64;
	assert_int_equal(line(&g, "G1 X1 Y0", 3, &c, &e), MLIP_OK);
	assert_near(c.b[3].target[0], 1, 0);

	check_err("G21 (nothing)\n\n", 2, 0, "empty program: no motion");
	check_err("", 1, 0, "empty program: no motion");
}

/* ---- arcs ---- */

/* Every block of p from index `from` on: a chord of the circle (cu, cv, r) in
 * axes (iu, iv), turning in direction dir (+1 CCW); the sagitta of each chord
 * within SAG and the corner tolerances as promised. Returns the swept angle. */
static double check_arc_tol(const struct mlip_program_list *p, size_t from, const double *start,
                            int iu, int iv, double cu, double cv, double r, int dir, double rtol)
{
	double pu = start[iu], pv = start[iv], swept = 0, sag_max = 0;
	size_t k, n;
	int inner;

	for (k = from; k < p->n; k++) {
		double u = p->blocks[k].target[iu], v = p->blocks[k].target[iv];
		double mu = (pu + u) / 2, mv = (pv + v) / 2;
		double sag = r - hypot(mu - cu, mv - cv);
		double da = atan2(v - cv, u - cu) - atan2(pv - cv, pu - cu);

		while (da > M_PI) {
			da -= 2 * M_PI;
		}
		while (da < -M_PI) {
			da += 2 * M_PI;
		}
		assert_near(hypot(u - cu, v - cv), r, rtol);
		assert_true(sag <= SAG + 1e-12 + rtol);
		assert_true(da * dir > 0);
		if (sag > sag_max) {
			sag_max = sag;
		}
		/* the corner inside the arc gets what the chord left; the last gets eps */
		inner = k + 1 < p->n && p->blocks[k + 1].line == p->blocks[k].line;
		assert_near(p->blocks[k].tol_mm, inner ? EPS - sag : EPS, 1e-9 + rtol);
		swept += da;
		pu = u;
		pv = v;
	}
	/* both sides of the bound: one chord fewer would exceed it (unless the
	 * quarter-turn cap on small arcs set the count) */
	n = p->n - from;
	if (n >= 2 && p->blocks[from].line == p->blocks[p->n - 1].line &&
	    fabs(swept) / (double)(n - 1) <= M_PI / 2) {
		assert_true(r * (1 - cos(fabs(swept) / (double)(n - 1) / 2)) > SAG * (1 - 1e-6));
	}
	assert_true(sag_max <= SAG + 1e-12 + rtol);
	return swept;
}

static double check_arc(const struct mlip_program_list *p, size_t from, const double *start, int iu,
                        int iv, double cu, double cv, double r, int dir)
{
	return check_arc_tol(p, from, start, iu, iv, cu, cv, r, dir, 1e-9);
}

static void test_arc_g17(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	double s[3] = {10, 0, 0}, sw;
	size_t n;

	(void)state;
	/* CCW quarter: (10,0) -> (0,10) about the origin */
	parse_ok("G1 X10 Y0 F600\nG3 X0 Y10 I-10 J0\n", &m, &p);
	sw = check_arc(&p, 1, s, 0, 1, 0, 0, 10, 1);
	assert_near(sw, M_PI / 2, 1e-9);
	n = p.n - 1;
	/* chords of equal angle, as few as the sagitta bound allows */
	assert_int_equal(n, (size_t)ceil((M_PI / 2) / (4 * asin(sqrt(SAG / 20)))));
	assert_near(p.blocks[p.n - 1].target[0], 0, 0);
	assert_near(p.blocks[p.n - 1].target[1], 10, 0);
	assert_near(p.blocks[1].feed_mm_s, 10, 1e-12);
	assert_int_equal(p.blocks[1].rapid, 0);
	mlip_program_list_free(&p);

	/* CW, same ends: the long way round (270 degrees) */
	parse_ok("G1 X10 Y0 F600\nG2 X0 Y10 I-10 J0\n", &m, &p);
	sw = check_arc(&p, 1, s, 0, 1, 0, 0, 10, -1);
	assert_near(sw, -1.5 * M_PI, 1e-9);
	assert_true(p.blocks[1].target[1] < 0); /* leaves downwards */
	mlip_program_list_free(&p);

	/* CW quarter with the center given by J only; modal G2 on the next line */
	parse_ok("G1 X10 Y0 F600\nG2 X0 Y-10 I-10\nX-10 Y0 J10\n", &m, &p);
	for (n = 1; n < p.n && p.blocks[n].line == 2; n++) {
	}
	sw = check_arc(&p, 1, s, 0, 1, 0, 0, 10, -1);
	assert_near(sw, -M_PI, 1e-9);
	assert_near(p.blocks[n - 1].target[1], -10, 0);
	mlip_program_list_free(&p);

	/* tiny arc (radius below the sagitta bound): still a few chords */
	parse_ok("G1 X0.0005 Y0 F600\nG3 X-0.0005 Y0 I-0.0005\n", &m, &p);
	assert_int_equal(p.n, 3);
	mlip_program_list_free(&p);
}

static void test_arc_g18_g19(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	double s18[3] = {10, 0, 0}, s19[3] = {0, 10, 0};

	(void)state;
	/* G18 is the ZX plane (u = Z, v = X): G3 turns from Z toward X, so from
	 * X10 Z0 about the origin the CCW quarter ends at Z-10 */
	parse_ok("G1 X10 F600\nG18 G3 X0 Z-10 I-10 K0\n", &m, &p);
	assert_near(check_arc(&p, 1, s18, 2, 0, 0, 0, 10, 1), M_PI / 2, 1e-9);
	assert_true(p.blocks[p.n / 2].target[2] < 0 && p.blocks[p.n / 2].target[0] > 0);
	mlip_program_list_free(&p);
	parse_ok("G1 X10 F600\nG18 G2 X0 Z-10 I-10\n", &m, &p);
	assert_near(check_arc(&p, 1, s18, 2, 0, 0, 0, 10, -1), -1.5 * M_PI, 1e-9);
	assert_true(p.blocks[1].target[2] > 0); /* the long way, through Z > 0 */
	mlip_program_list_free(&p);

	/* G19 is the YZ plane (u = Y, v = Z) with J K */
	parse_ok("G1 Y10 F600\nG19 G3 Y0 Z10 J-10 K0\n", &m, &p);
	assert_near(check_arc(&p, 1, s19, 1, 2, 0, 0, 10, 1), M_PI / 2, 1e-9);
	assert_true(p.blocks[p.n / 2].target[1] > 0 && p.blocks[p.n / 2].target[2] > 0);
	mlip_program_list_free(&p);
	parse_ok("G1 Y10 F600\nG19 G2 Y0 Z-10 K0 J-10\n", &m, &p);
	assert_near(check_arc(&p, 1, s19, 1, 2, 0, 0, 10, -1), -M_PI / 2, 1e-9);
	mlip_program_list_free(&p);

	/* the offset word of the normal axis is an error; so are missing centers */
	check_err("G1 X10 F600\nG3 X0 Y10 I-10 K1", 2, 16,
	          "K word not used by an arc in the G17 plane");
	check_err("G1 X10 F600\nG18 G3 X0 Z10 J1 I-10", 2, 15,
	          "J word not used by an arc in the G18 plane");
	check_err("G1 X10 F600\nG19 G3 Y1 I1", 2, 11, "I word not used by an arc in the G19 plane");
	check_err("G1 X10 F600\nG3 X0 Y10", 2, 1, "arc with no I/J/K or R");
	check_err("G1 X10 F600\nG3\nX0 Y10", 3, 1, "arc with no I/J/K or R");
	check_err("G1 X10 F600\nG1 X0 Y10 I-10", 2, 11, "I word without an arc (G2/G3)");
	check_err("G1 X10 F600\nG0 X0 R5", 2, 7, "R word without an arc (G2/G3)");
	check_err("G1 X10 F600\nG3 X0 Y10 I-10 R10", 2, 16, "arc with both R and I/J/K");
	check_err("G1 X10 F600\nG3 X0 Y10 I-10 J-10", 2, 1,
	          "arc radius to start 14.142 differs from radius to end 20.000 mm");
	check_err("G1 X10 F600\nG3 X0 Y10 I0 J0", 2, 1, "arc with zero radius");
	{
		struct mlip_machine fine = machine("XYZ");

		fine.tolerance_mm = 1e-11; /* a full circle of r 10 would need ~7e6 chords */
		check_err_m("G1 X10 Y0 F600\nG3 I-10", &fine, 2, 1,
		            "arc too long: more than 1000000 chords");
	}
}

static void test_arc_radius_tolerance(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;

	(void)state;
	/* r = 10: allowed difference max(0.002, 0.01) = 0.01 */
	parse_ok("G1 X10 Y0 F600\nG3 X0 Y10.009 I-10\n", &m, &p);
	assert_near(p.blocks[p.n - 1].target[1], 10.009, 0); /* the end is exact */
	mlip_program_list_free(&p);
	check_err("G1 X10 Y0 F600\nG3 X0 Y10.011 I-10", 2, 1, "differs from radius to end 10.011");
	/* small radius: the absolute 0.002 applies */
	parse_ok("G1 X1 Y0 F600\nG3 X0 Y1.0019 I-1\n", &m, &p);
	mlip_program_list_free(&p);
	check_err("G1 X1 Y0 F600\nG3 X0 Y1.0021 I-1", 2, 1, "arc radius to start 1.000");
}

static void test_full_circle_and_helix(void **state)
{
	struct mlip_machine m = machine("XYZA");
	struct mlip_program_list p;
	double s[4] = {10, 0, 0, 0}, swept;
	size_t k;

	(void)state;
	parse_ok("G1 X10 Y0 F600\nG2 X10 Y0 I-10 J0\n", &m, &p);
	assert_near(check_arc(&p, 1, s, 0, 1, 0, 0, 10, -1), -2 * M_PI, 1e-9);
	assert_true(p.blocks[1].target[1] < 0); /* CW: first goes down */
	assert_near(p.blocks[p.n - 1].target[0], 10, 0);
	assert_near(p.blocks[p.n - 1].target[1], 0, 0);
	mlip_program_list_free(&p);

	/* full circle from I J only, no axis words, modal G3 */
	parse_ok("G1 X10 Y0 F600\nG3 I-10\n", &m, &p);
	assert_near(check_arc(&p, 1, s, 0, 1, 0, 0, 10, 1), 2 * M_PI, 1e-9);
	mlip_program_list_free(&p);

	/* helix: Z and A move linearly with the angle */
	parse_ok("G1 X10 Y0 F600\nG3 X-10 Y0 Z5 A90 I-10 J0\n", &m, &p);
	assert_near(check_arc(&p, 1, s, 0, 1, 0, 0, 10, 1), M_PI, 1e-9);
	for (k = 1; k < p.n; k++) {
		double ang = atan2(p.blocks[k].target[1], p.blocks[k].target[0]);

		if (ang < 0) {
			ang += 2 * M_PI;
		}
		if (k == p.n - 1) {
			ang = M_PI;
		}
		assert_near(p.blocks[k].target[2], 5 * ang / M_PI, 1e-9);
		assert_near(p.blocks[k].target[3], 90 * ang / M_PI, 1e-9);
	}
	assert_near(p.blocks[p.n - 1].target[2], 5, 0);
	mlip_program_list_free(&p);

	/* P turns (LinuxCNC): the programmed arc plus P - 1 full circles, the
	 * helix axis linear in the whole angle; P within 0.001 of a whole number */
	parse_ok("G1 X10 Y0 F600\nG3 X0 Y10 Z-5 I-10 J0 P3\n", &m, &p);
	assert_near(check_arc(&p, 1, s, 0, 1, 0, 0, 10, 1), 4.5 * M_PI, 1e-9);
	for (k = 1, swept = 0; k < p.n; k++) { /* the angle swept so far */
		double da = atan2(p.blocks[k].target[1], p.blocks[k].target[0]) -
		            atan2(p.blocks[k - 1].target[1], p.blocks[k - 1].target[0]);
		swept += da < -1e-12 ? da + 2 * M_PI : da;
		assert_near(p.blocks[k].target[2], -5 * swept / (4.5 * M_PI), 1e-9);
	}
	assert_near(p.blocks[p.n - 1].target[1], 10, 0);
	mlip_program_list_free(&p);
	parse_ok("G1 X10 Y0 F600\nG2 I-10 P2.0004\n", &m, &p);
	assert_near(check_arc(&p, 1, s, 0, 1, 0, 0, 10, -1), -4 * M_PI, 1e-9);
	mlip_program_list_free(&p);
	parse_ok("G1 X10 Y0 F600\nG2 X-10 Y0 R10 P2\n", &m, &p); /* R: the short arc, once more */
	assert_near(check_arc(&p, 1, s, 0, 1, 0, 0, 10, -1), -3 * M_PI, 1e-9);
	mlip_program_list_free(&p);
	check_err("G1 X10 F600\nG2 I-10 P0", 2, 9, "G2 P0: the number of turns is a whole number");
	check_err("G1 X10 F600\nG3 I-10 P1.5", 2, 9, "G3 P1.5: the number of turns");
	check_err("G1 X10 F600\nG3 I-10 P-2", 2, 9, "G3 P-2: the number of turns");
	check_err("G1 X10 F600\nG2 I-10 P2000000", 2, 9, "G2 P2000000: the number of turns");
	check_err("G1 X10 F600\nG4 P1 G2 I-10", 2, 4, "P word with G2 and G4: both use P");
	check_err("G1 X10 F600\nG64 P1 G2 I-10", 2, 5, "P word with G2 and G64: both use P");
	check_err("G1 X10 F600\nG2 P2", 2, 4, "P word without G2/G3, G4"); /* no arc moves */
	check_err("G1 X10 F600\nG2 I-10 P1000000", 2, 1, "arc too long: more than");

	/* helical full circle in G91 (a thread-milling pass) */
	parse_ok("G1 X10 Y0 F600\nG91 G2 Z-1 I-10\n", &m, &p);
	assert_near(check_arc(&p, 1, s, 0, 1, 0, 0, 10, -1), -2 * M_PI, 1e-9);
	assert_near(p.blocks[p.n - 1].target[2], -1, 0);
	mlip_program_list_free(&p);
}

/* Block k of p: a move to (x, y, z), rapid or fed, ending at rest. */
static void expect_move(const struct mlip_program_list *p, size_t k, double x, double y, double z,
                        int rapid)
{
	if (k >= p->n || p->blocks[k].kind != MLIP_BLOCK_MOVE ||
	    fabs(p->blocks[k].target[0] - x) > 1e-9 || fabs(p->blocks[k].target[1] - y) > 1e-9 ||
	    fabs(p->blocks[k].target[2] - z) > 1e-9 || p->blocks[k].rapid != rapid ||
	    !p->blocks[k].exact_stop) {
		print_error("block %u: expected %s to %g %g %g at rest\n", (unsigned)k,
		            rapid ? "a rapid" : "a feed", x, y, z);
		if (k < p->n) {
			print_error("  got kind %u %s to %g %g %g (exact %u)\n",
			            (unsigned)p->blocks[k].kind,
			            p->blocks[k].rapid ? "rapid" : "feed", p->blocks[k].target[0],
			            p->blocks[k].target[1], p->blocks[k].target[2],
			            (unsigned)p->blocks[k].exact_stop);
		}
		fail();
	}
}

/* G81..G89 as LinuxCNC's documentation gives them: its examples' moves. */
static void test_canned_cycles(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;

	(void)state;
	/* Example 1: from (1, 2, 3), G90 G98 G81 X4 Y5 Z1.5 R2.8 */
	parse_ok("G0 X1 Y2 Z3\nG90 G98 G81 X4 Y5 Z1.5 R2.8 F60\n", &m, &p);
	assert_int_equal(p.n, 5);
	expect_move(&p, 1, 4, 5, 3, 1);
	expect_move(&p, 2, 4, 5, 2.8, 1);
	expect_move(&p, 3, 4, 5, 1.5, 0);
	expect_move(&p, 4, 4, 5, 3, 1);
	assert_near(p.blocks[3].feed_mm_s, 1.0, 1e-12);
	mlip_program_list_free(&p);
	/* Example 2: from (1, 2, 3), G91 G98 G81 X4 Y5 Z-0.6 R1.8 L3: up to 4.8
	 * first, then three holes 4 5 apart, 0.6 deep from R */
	parse_ok("G0 X1 Y2 Z3\nG91 G98 G81 X4 Y5 Z-0.6 R1.8 L3 F60\n", &m, &p);
	assert_int_equal(p.n, 11);
	expect_move(&p, 1, 1, 2, 4.8, 1);
	for (int h = 0; h < 3; h++) {
		expect_move(&p, 2 + 3 * (size_t)h, 5 + 4 * h, 7 + 5 * h, 4.8, 1);
		expect_move(&p, 3 + 3 * (size_t)h, 5 + 4 * h, 7 + 5 * h, 4.2, 0);
		expect_move(&p, 4 + 3 * (size_t)h, 5 + 4 * h, 7 + 5 * h, 4.8, 1);
	}
	mlip_program_list_free(&p);
	/* G99 retracts to R; sticky R and Z on the next lines; G80 ends it */
	parse_ok("G0 X0 Y0 Z10\nG99 G81 X1 Z-2 R1 F60\nX2\nY3 Z-4\nG80\nG0 Z10\n", &m, &p);
	expect_move(&p, 1, 1, 0, 10, 1);
	expect_move(&p, 2, 1, 0, 1, 1);
	expect_move(&p, 3, 1, 0, -2, 0);
	expect_move(&p, 4, 1, 0, 1, 1);
	expect_move(&p, 5, 2, 0, 1, 1); /* at R: the clear height of G99 */
	expect_move(&p, 6, 2, 0, -2, 0);
	expect_move(&p, 7, 2, 0, 1, 1);
	expect_move(&p, 8, 2, 3, 1, 1);
	expect_move(&p, 9, 2, 3, -4, 0);
	expect_move(&p, 10, 2, 3, 1, 1);
	assert_near(p.blocks[11].target[2], 10, 0);
	assert_int_equal(p.n, 12);
	mlip_program_list_free(&p);
	/* G82: the dwell at the bottom; G83: pecks of Q, out to R, back down to
	 * 0.254 mm above the last depth; G73: 0.254 mm back only */
	parse_ok("G0 X0 Y0 Z5\nG98 G82 X1 Z-1 R1 P0.5 F60\n", &m, &p);
	expect_move(&p, 3, 1, 0, -1, 0);
	assert_int_equal(p.blocks[4].kind, MLIP_BLOCK_DWELL);
	assert_near(p.blocks[4].dwell_s, 0.5, 0);
	expect_move(&p, 5, 1, 0, 5, 1);
	mlip_program_list_free(&p);
	parse_ok("G0 X0 Y0 Z5\nG98 G83 X1 Z-2.5 R1 Q1.5 F60\n", &m, &p);
	expect_move(&p, 1, 1, 0, 5, 1);
	expect_move(&p, 2, 1, 0, 1, 1);
	expect_move(&p, 3, 1, 0, -0.5, 0);
	expect_move(&p, 4, 1, 0, 1, 1);
	expect_move(&p, 5, 1, 0, -0.5 + 0.254, 1);
	expect_move(&p, 6, 1, 0, -2, 0);
	expect_move(&p, 7, 1, 0, 1, 1);
	expect_move(&p, 8, 1, 0, 0.254 - 2, 1);
	expect_move(&p, 9, 1, 0, -2.5, 0);
	expect_move(&p, 10, 1, 0, 5, 1);
	assert_int_equal(p.n, 11);
	mlip_program_list_free(&p);
	parse_ok("G0 X0 Y0 Z5\nG99 G73 X1 Z-2.5 R1 Q1.5 F60\n", &m, &p);
	expect_move(&p, 3, 1, 0, -0.5, 0);
	expect_move(&p, 4, 1, 0, -0.5 + 0.254, 1);
	expect_move(&p, 5, 1, 0, -2, 0);
	expect_move(&p, 6, 1, 0, -2 + 0.254, 1);
	expect_move(&p, 7, 1, 0, -2.5, 0);
	expect_move(&p, 8, 1, 0, 1, 1);
	assert_int_equal(p.n, 9);
	mlip_program_list_free(&p);
	/* G85: fed out to R, a rapid to the clear height; G89: the dwell, then
	 * fed out to it */
	parse_ok("G0 X0 Y0 Z5\nG98 G85 X1 Z-1 R1 F60\n", &m, &p);
	expect_move(&p, 3, 1, 0, -1, 0);
	expect_move(&p, 4, 1, 0, 1, 0);
	expect_move(&p, 5, 1, 0, 5, 1);
	mlip_program_list_free(&p);
	parse_ok("G0 X0 Y0 Z5\nG98 G89 X1 Z-1 R1 P2 F60\n", &m, &p);
	assert_int_equal(p.blocks[4].kind, MLIP_BLOCK_DWELL);
	expect_move(&p, 5, 1, 0, 5, 0);
	mlip_program_list_free(&p);
	/* below R at the start: up to R first; inches; a work offset; G18 */
	parse_ok("G0 X0 Y1 Z0\nG99 G81 X1 Z-1 R2 F60\n", &m, &p);
	expect_move(&p, 1, 0, 1, 2, 1);
	expect_move(&p, 2, 1, 1, 2, 1);
	expect_move(&p, 3, 1, 1, -1, 0);
	expect_move(&p, 4, 1, 1, 2, 1);
	mlip_program_list_free(&p);
	parse_ok("G10 L2 P1 X10 Z-1\nG0 X0 Y0 Z1\nG20 G99 G81 X1 Z-0.5 R0.1 F6\n", &m, &p);
	expect_move(&p, 2, 10 + 25.4, 0, 25.4 * 0.1 - 1, 1);
	expect_move(&p, 3, 10 + 25.4, 0, -25.4 * 0.5 - 1, 0);
	assert_near(p.blocks[3].feed_mm_s, 6 * 25.4 / 60, 1e-12);
	mlip_program_list_free(&p);
	parse_ok("G0 X0 Y5 Z0\nG18 G98 G81 Z1 X2 Y-1 R3 F60\n", &m, &p);
	expect_move(&p, 1, 2, 5, 1, 1); /* at Y5, above R3: in the plane first */
	expect_move(&p, 2, 2, 3, 1, 1);
	expect_move(&p, 3, 2, -1, 1, 0);
	expect_move(&p, 4, 2, 5, 1, 1);
	assert_int_equal(p.n, 5);
	mlip_program_list_free(&p);

	check_err("G0 Z5\nG81 X1 R1 F60", 2, 1, "G81 without Z: the depth of the hole");
	check_err("G0 Z5\nG81 X1 Z-1 F60", 2, 1, "G81 without R");
	check_err("G0 Z5\nG83 X1 Z-1 R1 F60", 2, 1, "G83 without Q: the depth of each peck");
	check_err("G0 Z5\nG83 X1 Z-1 R1 Q0 F60", 2, 15, "G83 Q0: the peck depth must be positive");
	check_err("G0 Z5\nG82 X1 Z-1 R1 F60", 2, 1, "G82 without P: the dwell at the bottom");
	check_err("G0 Z5\nG81 X1 Z-1 R-2 F60", 2, 12, "R (-2) below the hole's bottom Z (-1)");
	check_err("G0 Z5\nG81 X1 Z-1 R1 L0 F60", 2, 15, "G81 L0: the repeats are a whole number");
	check_err("G0 Z5\nG81 X1 Z-1 R1 I2 F60", 2, 15, "I word in a canned cycle");
	check_err("G0 Z5\nG81 R1 F60", 2, 1, "G81 without axis words");
	check_err("G0 Z5\nG81 X1 Z-1 R1 Q1 F60", 2, 15, "Q word with G81 (no pecks)");
	check_err("G0 Z5\nG81 X1 Z-1 R1 P1 F60", 2, 15, "P word with G81 (no dwell)");
	check_err("G0 Z5\nG93 G81 X1 Z-1 R1 F60", 2, 5, "G81 with G93 inverse time");
	check_err("G0 Z5\nG81 X1 Z-1 R1 F60\nG80 X2", 3, 5, "axis words with G80");
	check_err("G0 Z5\nG81 X1 Z-1 R1 F60\nG80\nX2", 4, 1,
	          "axis words with no motion code after a canned cycle ended");
	check_err("G0 Z5\nG84 X1 Z-1 R1 F60", 2, 1, "unsupported G code G84: tapping cycle");
	check_err("G0 Z5\nG86 X1 Z-1 R1 P1 F60", 2, 1, "unsupported G code G86: boring cycles");
	check_err("G0 Z5\nG81 G1 X1 Z-1 R1 F60", 2, 5, "two motion codes on one line: G81 and G1");
	check_err("G0 Z5\nG81 X1 Z-1 R1 F60 L2.5", 2, 19, "G81 L2.5");
	check_err("G1 X1 F10 L2", 1, 11, "L word without G10 or a canned cycle");
	check_err("G1 X1 F10 Q2", 1, 11, "Q word without G64, G73, G83 or M61");
	check_err("G0 Z5\nG83 X1 Z-1000 R1 Q0.000001 F60", 2, 18, "more than 1000000 pecks");
	check_err("G0 Z5\nG81 X1 Z-1200 R1 F60", 2, 8, "Z -1200.000 beyond soft limit");
}

static void test_r_arcs(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	double s[3] = {10, 0, 0};

	(void)state;
	parse_ok("G1 X10 Y0 F600\nG3 X0 Y10 R10\n", &m, &p); /* short CCW: center origin */
	assert_near(check_arc(&p, 1, s, 0, 1, 0, 0, 10, 1), M_PI / 2, 1e-9);
	mlip_program_list_free(&p);
	parse_ok("G1 X10 Y0 F600\nG3 X0 Y10 R-10\n", &m, &p); /* long CCW: center (10,10) */
	assert_near(check_arc(&p, 1, s, 0, 1, 10, 10, 10, 1), 1.5 * M_PI, 1e-9);
	mlip_program_list_free(&p);
	parse_ok("G1 X10 Y0 F600\nG2 X0 Y10 R10\n", &m, &p); /* short CW: center (10,10) */
	assert_near(check_arc(&p, 1, s, 0, 1, 10, 10, 10, -1), -M_PI / 2, 1e-9);
	mlip_program_list_free(&p);
	parse_ok("G1 X10 Y0 F600\nG2 X0 Y10 R-10\n", &m, &p); /* long CW: center origin */
	assert_near(check_arc(&p, 1, s, 0, 1, 0, 0, 10, -1), -1.5 * M_PI, 1e-9);
	mlip_program_list_free(&p);
	/* half circle: endpoints exactly 2R apart */
	parse_ok("G1 X10 Y0 F600\nG3 X-10 Y0 R10\n", &m, &p);
	assert_near(check_arc(&p, 1, s, 0, 1, 0, 0, 10, 1), M_PI, 1e-9);
	mlip_program_list_free(&p);
	/* R in inches */
	{
		double si[3] = {25.4, 0, 0};

		parse_ok("G20 G1 X1 Y0 F10\nG3 X0 Y1 R1\n", &m, &p);
		assert_near(check_arc(&p, 1, si, 0, 1, 0, 0, 25.4, 1), M_PI / 2, 1e-9);
		mlip_program_list_free(&p);
	}

	check_err("G1 X10 Y0 F600\nG3 X30 Y0 R5", 2, 11,
	          "R arc: endpoints 20.000 mm apart, more than 2R = 10.000 mm");
	check_err("G1 X10 Y0 F600\nG3 X10 Y0 R5", 2, 11, "R arc with end equal to start");
	check_err("G1 X10 Y0 F600\nG3 X0 Y10 R0", 2, 11, "R arc with zero radius");
}

/* Seeded random arcs in every plane and direction, center and R format, some
 * helical: chords on the circle, sagitta within the bound, the right sweep. */
static uint64_t rng = 0x9E3779B97F4A7C15u;
static double urand(double lo, double hi)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return lo + (hi - lo) * (double)(rng >> 11) / 9007199254740992.0;
}

static void test_arc_random(void **state)
{
	static const char U[3] = {'X', 'Z', 'Y'}, V[3] = {'Y', 'X', 'Z'}, N[3] = {'Z', 'Y', 'X'};
	static const char OU[3] = {'I', 'K', 'J'}, OV[3] = {'J', 'I', 'K'};
	static const int iu_of[3] = {0, 2, 1}, iv_of[3] = {1, 0, 2}, in_of[3] = {2, 1, 0};
	struct mlip_machine m = big_machine("XYZ");
	int it, checked = 0;

	(void)state;
	for (it = 0; it < 600; it++) {
		int p = it % 3, cw = (it / 3) % 2, use_r = it % 5 == 0, helix = it % 4 == 0;
		int iu = iu_of[p], iv = iv_of[p], in = in_of[p];
		double r = exp(urand(log(0.005), log(500))), a0 = urand(-M_PI, M_PI);
		double sweep = it % 7 == 0 ? 2 * M_PI : urand(0.01, 2 * M_PI - 0.01);
		double cu = urand(-100, 100), cv = urand(-100, 100), s[3], e[3], sw;
		struct mlip_program_list prog;
		char text[512];
		size_t n;

		if (use_r) {
			sweep = fmin(sweep, 2 * M_PI - 0.05); /* R can't do a full circle */
			if (fabs(sweep - M_PI) < 0.05) {
				continue; /* near a half circle the R center is ill-conditioned */
			}
		}
		s[iu] = cu + r * cos(a0);
		s[iv] = cv + r * sin(a0);
		s[in] = urand(-10, 10);
		e[iu] = sweep == 2 * M_PI ? s[iu] : cu + r * cos(a0 + (cw ? -sweep : sweep));
		e[iv] = sweep == 2 * M_PI ? s[iv] : cv + r * sin(a0 + (cw ? -sweep : sweep));
		e[in] = helix ? s[in] + urand(-5, 5) : s[in];
		n = (size_t)snprintf(text, sizeof text, "G1 X%.9f Y%.9f Z%.9f F600\n", s[0], s[1],
		                     s[2]);
		n += (size_t)snprintf(text + n, sizeof text - n, "G%d G%d %c%.9f %c%.9f %c%.9f ",
		                      17 + p, cw ? 2 : 3, U[p], e[iu], V[p], e[iv], N[p], e[in]);
		if (use_r) {
			snprintf(text + n, sizeof text - n, "R%.9f\n", sweep > M_PI ? -r : r);
		} else {
			snprintf(text + n, sizeof text - n, "%c%.9f %c%.9f\n", OU[p], cu - s[iu],
			         OV[p], cv - s[iv]);
		}
		parse_ok(text, &m, &prog);
		/* the text rounds to 1e-9: hence the looser radius tolerance */
		sw = check_arc_tol(&prog, 1, s, iu, iv, cu, cv, r, cw ? -1 : 1, 1e-7);
		assert_near(fabs(sw), sweep, 1e-6);
		assert_near(prog.blocks[prog.n - 1].target[in], e[in], 1e-8);
		mlip_program_list_free(&prog);
		checked++;
	}
	assert_true(checked > 500);
}

/* ---- program helpers ---- */

static void test_program_errors_and_print(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	char *out = NULL;
	size_t len = 0;
	FILE *f;
	int rc;
	static const char text[] = "G1 X1 F100\n"
	                           "G1 X1.2.3\n"
	                           "X2\n"
	                           "G41\n"
	                           "M3 S100\n"
	                           "M3\n"
	                           "X2000 (too far)\n";

	(void)state;
	rc = mlip_program_list_parse(text, sizeof text - 1, &m, &p);
	assert_int_equal(rc, 1);
	assert_int_equal(p.n_errors, 3);
	assert_int_equal(p.n_errors_total, 3);
	assert_int_equal(p.lines, 7);
	assert_int_equal(p.n, 2);
	f = open_memstream(&out, &len);
	assert_non_null(f);
	mlip_program_print_errors(&p.r, "a.nc", f);
	mlip_program_print_notices(&p.r, "a.nc", f);
	fclose(f);
	assert_string_equal(out,
	                    "a.nc:2:5: error: malformed number '1.2.3'\n"
	                    "a.nc:4:1: error: unsupported G code G41: cutter radius compensation\n"
	                    "a.nc:7:1: error: X 2000.000 beyond soft limit 1000.000\n"
	                    "a.nc: 3 errors, program rejected: nothing was run\n"
	                    "a.nc:5: note: M3 ignored (no effect on motion) (2 times)\n"
	                    "a.nc:5: note: S ignored (no effect on motion)\n");
	free(out);
	mlip_program_list_free(&p);

	/* a valid program prints no errors; whole-file errors have no column */
	parse_ok("G0 X1\n", &m, &p);
	f = open_memstream(&out, &len);
	mlip_program_print_errors(&p.r, "b.nc", f);
	fclose(f);
	assert_string_equal(out, "");
	free(out);
	mlip_program_list_free(&p);
	rc = mlip_program_list_parse("G21\n", 4, &m, &p);
	assert_int_equal(rc, 1);
	f = open_memstream(&out, &len);
	mlip_program_print_errors(&p.r, "c.nc", f);
	fclose(f);
	assert_string_equal(out, "c.nc:1: error: empty program: no motion\n"
	                         "c.nc: 1 error, program rejected: nothing was run\n");
	free(out);
	mlip_program_list_free(&p);
}

static void test_program_error_cap(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	size_t n = 1500, k;
	char *text = malloc(n * 6 + 16);
	int rc;

	(void)state;
	assert_non_null(text);
	strcpy(text, "G0 X1\n");
	for (k = 0; k < n; k++) {
		strcat(text + k * 5, "X1 E\n");
	}
	rc = mlip_program_list_parse(text, strlen(text), &m, &p);
	assert_int_equal(rc, 1);
	assert_int_equal(p.n_errors, MLIP_PROGRAM_MAX_ERRORS);
	assert_int_equal(p.n_errors_total, n);
	assert_int_equal(p.errors[999].line, 1001);
	mlip_program_list_free(&p);
	free(text);
}

static void test_read_file_errors(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	char *buf;
	size_t len;

	(void)state;
	assert_int_equal(mlip_read_file("/nonexistent/x.nc", &buf, &len), -ENOENT);
	assert_true(mlip_program_list_load("/nonexistent/x.nc", &m, &p) < 0);
	assert_non_null(strstr(p.r.msg, "No such file"));
	mlip_program_list_free(&p);
	assert_int_equal(p.n, 0);
	mlip_program_list_free(&p);
}

static void test_scan_axes(void **state)
{
	char L[8];
	static const char a[] = "G0 x1 y2 (Z3 ; C1)\n; A4\nG1 b 5 F100 (unterminated C1\nM3 S100";

	(void)state;
	assert_int_equal(mlip_gcode_scan_axes(a, sizeof a - 1, L), 3);
	assert_string_equal(L, "XYB");
	assert_int_equal(mlip_gcode_scan_axes("C1 A2 Z3 Y4 X5 B6", 17, L), 6);
	assert_string_equal(L, "XYZABC");
	assert_int_equal(mlip_gcode_scan_axes("G1 Z-1 F100 ; X1", 16, L), 1);
	assert_string_equal(L, "Z");
	assert_int_equal(mlip_gcode_scan_axes("(X1)\n%\n", 7, L), 0);
	assert_string_equal(L, "");
	/* letters only count with a number: "Xnan" is no axis A */
	assert_int_equal(mlip_gcode_scan_axes("Xnan Y.5", 8, L), 1);
	assert_string_equal(L, "Y");
}

/* ---- the real toolpaths ---- */

static char *shared_path(const char *file)
{
	static char buf[4096];
	const char *dir = getenv("MLIP_SHARED");

	snprintf(buf, sizeof buf, "%s/toolpaths/%s", dir && *dir ? dir : "../shared", file);
	return buf;
}

static void load_file(const char *file, const char *axes, size_t min_blocks,
                      struct mlip_program_list *p)
{
	struct mlip_machine m = big_machine(axes);
	char L[8], *buf;
	size_t len;
	const char *path = shared_path(file);
	int rc;

	rc = mlip_read_file(path, &buf, &len);
	if (rc) {
		print_error("%s: %s (set MLIP_SHARED)\n", path, strerror(-rc));
	}
	assert_int_equal(rc, 0);
	assert_int_equal(mlip_gcode_scan_axes(buf, len, L), (int)strlen(axes));
	assert_string_equal(L, axes);
	free(buf);
	rc = mlip_program_list_load(path, &m, p);
	if (rc) {
		mlip_program_print_errors(&p->r, path, stderr);
	}
	assert_int_equal(rc, 0);
	assert_true(p->n >= min_blocks);
	/* what a real program sends passes the controller's record rules */
	for (size_t i = 0; i < p->n; i++) {
		assert_int_equal(mlip_block_check(&m, &p->blocks[i]), MLIP_RULE_OK);
	}
}

static void test_toolpaths(void **state)
{
	struct mlip_program_list p;
	size_t k;

	(void)state;
	load_file("MB-2.3_test.nc", "XYZ", 112000, &p);
	mlip_program_list_free(&p);
	load_file("tball-pocket.gcode", "XYZ", 40000, &p);
	mlip_program_list_free(&p);
	load_file("4006.nc", "XYZA", 16000, &p);
	for (k = 0; k < p.n; k++) {
		assert_true(isfinite(p.blocks[k].target[3]));
	}
	mlip_program_list_free(&p);
	load_file("flower-spiral-2d.ngc", "XY", 87000, &p);
	assert_near(p.blocks[0].feed_mm_s, 200, 1e-9); /* F12000 mm/min */
	mlip_program_list_free(&p);
	load_file("SheepTile-v2.nc", "XYZ", 10000, &p);
	mlip_program_list_free(&p);
}

/* SheepTile through the core line by line: the chords of every arc lie on
 * their circle, with each chord's sagitta within the bound. */
struct per_line {
	struct mlip_block *b;
	size_t n, cap;
};

static int grow_sink(void *ctx, const struct mlip_block *b)
{
	struct per_line *pl = ctx;

	if (pl->n == pl->cap) {
		pl->cap = pl->cap ? 2 * pl->cap : 256;
		pl->b = realloc(pl->b, pl->cap * sizeof *pl->b);
		if (!pl->b) {
			return 1;
		}
	}
	pl->b[pl->n++] = *b;
	return 0;
}

/* the value of word L in s (comments are whole lines in this file), or 0 */
static int word_value(const char *s, size_t n, char L, double *v)
{
	size_t k;

	for (k = 0; k < n; k++) {
		if (s[k] == '(') {
			return 0;
		}
		if (s[k] == L) {
			*v = strtod(s + k + 1, NULL);
			return 1;
		}
	}
	return 0;
}

static void test_sheeptile_arcs(void **state)
{
	struct mlip_machine m = big_machine("XYZ");
	struct mlip_gcode g;
	struct mlip_gcode_error e;
	struct per_line pl = {NULL, 0, 0};
	char *buf;
	size_t len, i = 0, k;
	uint32_t no = 0;
	int arcs = 0, g18 = 0;

	(void)state;
	assert_int_equal(mlip_read_file(shared_path("SheepTile-v2.nc"), &buf, &len), 0);
	mlip_gcode_init(&g, &m);
	mlip_gcode_set_initial_feed(&g, 333.3);
	while (i < len) {
		const char *s = buf + i, *nl = memchr(s, '\n', len - i);
		size_t n = nl ? (size_t)(nl - s) : len - i;
		double start[MLIP_MAX_AXES], off[3] = {0, 0, 0}, c[3], r0, r1;
		int has = 0, iu, iv, p;

		memcpy(start, g.cur, sizeof start);
		pl.n = 0;
		no++;
		assert_int_equal(mlip_gcode_line(&g, s, n, no, grow_sink, &pl, &e), MLIP_OK);
		i += n + 1;
		for (k = 0; k < 3; k++) {
			has |= word_value(s, n, (char)('I' + k), &off[k]);
		}
		if (!has || g.motion < 2) {
			continue;
		}
		/* (u, v) of the plane, as in G17 / G18 (Z, X) / G19 */
		p = g.plane - 17;
		iu = p == 0 ? 0 : p == 1 ? 2 : 1;
		iv = p == 0 ? 1 : p == 1 ? 0 : 2;
		for (k = 0; k < 3; k++) {
			c[k] = start[k] + off[k];
		}
		assert_true(pl.n >= 1);
		r0 = hypot(start[iu] - c[iu], start[iv] - c[iv]);
		r1 = hypot(pl.b[pl.n - 1].target[iu] - c[iu], pl.b[pl.n - 1].target[iv] - c[iv]);
		for (k = 0; k < pl.n; k++) {
			const double *t = pl.b[k].target, *q = k ? pl.b[k - 1].target : start;
			double r = hypot(t[iu] - c[iu], t[iv] - c[iv]);
			double mu = (t[iu] + q[iu]) / 2, mv = (t[iv] + q[iv]) / 2;
			double mid = hypot(mu - c[iu], mv - c[iv]);

			/* on the circle (a slight spiral from r0 to r1, as programmed) */
			assert_true(r >= fmin(r0, r1) - 1e-9 && r <= fmax(r0, r1) + 1e-9);
			/* chord sagitta within the bound */
			assert_true(fmin(r0, r1) - mid <= SAG + 1e-9);
			assert_true(pl.b[k].tol_mm >= EPS - SAG - 1e-12 && pl.b[k].tol_mm <= EPS);
		}
		assert_near(pl.b[pl.n - 1].tol_mm, EPS, 0);
		arcs++;
		g18 += g.plane == 18;
	}
	assert_int_equal(mlip_gcode_finish(&g, no, &e), MLIP_OK);
	assert_true(arcs > 600);
	assert_true(g18 >= 19);
	free(pl.b);
	free(buf);
}

/* ---- program events, offsets, path modes, feed modes, Grbl (issue 11) ---- */

/* Parse text with the given start offsets (NULL: defaults), must be valid. */
static void parse_off(const char *text, const struct mlip_machine *m,
                      const struct mlip_gcode_offsets *o, struct mlip_program_list *p)
{
	struct mlip_program_options opt = {0, o, 0, NULL, NULL, 0};
	struct mlip_block b;
	int rc;

	memset(p, 0, sizeof *p);
	rc = mlip_program_open_mem(&p->r, text, strlen(text), m, &opt);
	if (rc != 0) {
		mlip_program_print_errors(&p->r, "<test>", stderr);
	}
	assert_int_equal(rc, 0);
	p->blocks = malloc(sizeof *p->blocks * (p->r.n + 1));
	assert_non_null(p->blocks);
	while (mlip_program_next(&p->r, &b) > 0) {
		p->blocks[p->n++] = b;
	}
	assert_int_equal(p->n, p->r.n);
	p->notices = p->r.notices;
	p->n_notices = p->r.n_notices;
}

static const struct mlip_gcode_notice *find_notice(const struct mlip_program_list *p,
                                                   const char *word)
{
	uint32_t k;

	for (k = 0; k < p->n_notices; k++) {
		if (strcmp(p->notices[k].word, word) == 0) {
			return &p->notices[k];
		}
	}
	return NULL;
}

static void test_dwell(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;

	(void)state;
	/* G4 P is seconds (LinuxCNC, Grbl 1.1); it comes before the motion of
	 * its line (LinuxCNC's order of execution) */
	parse_ok("G1 X1 F60\nG4 P0.5\nG4 P1 G1 X2\nG04P3\nG4 P0\n", &m, &p);
	assert_int_equal(p.n, 6);
	assert_int_equal(p.blocks[0].kind, MLIP_BLOCK_MOVE);
	assert_int_equal(p.blocks[1].kind, MLIP_BLOCK_DWELL);
	assert_near(p.blocks[1].dwell_s, 0.5, 0);
	assert_int_equal(p.blocks[1].line, 2);
	assert_near(p.blocks[1].target[0], 1, 0); /* where the machine rests */
	assert_int_equal(p.blocks[2].kind, MLIP_BLOCK_DWELL);
	assert_near(p.blocks[2].dwell_s, 1, 0);
	assert_near(p.blocks[2].target[0], 1, 0);
	assert_int_equal(p.blocks[3].kind, MLIP_BLOCK_MOVE);
	assert_near(p.blocks[3].target[0], 2, 0);
	assert_near(p.blocks[4].dwell_s, 3, 0);
	assert_near(p.blocks[5].dwell_s, 0, 0);
	mlip_program_list_free(&p);
	/* a dwell alone is no motion */
	check_err("G4 P1\n", 1, 0, "empty program: no motion");
	/* a line with an error emits nothing, its dwell neither */
	{
		static const char t[] = "G1 X1 F60\nG4 P1 G1 X2000\n";

		assert_int_equal(mlip_program_list_parse(t, sizeof t - 1, &m, &p), 1);
		assert_int_equal(p.errors[0].line, 2);
		assert_int_equal(p.n, 1);
		mlip_program_list_free(&p);
	}
}

/* Every block of a program passes the rule set the controller validates its
 * records by (mlip_block_check, mlip/types.h). */
static void all_blocks_keep_the_rules(const struct mlip_machine *m,
                                      const struct mlip_program_list *p)
{
	for (size_t i = 0; i < p->n; i++) {
		assert_int_equal(mlip_block_check(m, &p->blocks[i]), MLIP_RULE_OK);
	}
}

/* Issue 17 item 8: what the controller refuses is refused by the reader,
 * at the word to blame, boundaries included: a dwell of at most a day, a
 * feed move's feed within MLIP_FEED_MIN_MM_S..MLIP_FEED_MAX_MM_S (G94 and
 * G93, mm and inch), no move longer than a day. Before, G4 P100000 and
 * F99999999 passed the check and faulted the controller mid-run; G93
 * F0.0000001 made mlip-sim run for ever. */
static void test_block_rule_set(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;

	(void)state;
	parse_ok("G1 X1 F60\nG4 P86400\nG1 X2\n", &m, &p);
	assert_near(p.blocks[1].dwell_s, MLIP_DWELL_MAX_S, 0);
	all_blocks_keep_the_rules(&m, &p);
	mlip_program_list_free(&p);
	check_err("G1 X1 F60\nG4 P86400.001\n", 2, 4, "G4 P86400.001: a dwell of at most 86400 s");
	check_err("G1 X1 F60\nG4 P100000 G1 X2\n", 2, 4, "a dwell of at most 86400 s (a day)");

	/* F is mm/min: 6e7 is 1e6 mm/s exactly, the largest */
	parse_ok("G1 X1 F60000000\nG1 X2 F0.06\n", &m, &p);
	assert_near(p.blocks[0].feed_mm_s, MLIP_FEED_MAX_MM_S, 0);
	assert_near(p.blocks[1].feed_mm_s, MLIP_FEED_MIN_MM_S, 1e-18);
	all_blocks_keep_the_rules(&m, &p);
	mlip_program_list_free(&p);
	check_err("G1 X1 F99999999\n", 1, 7, "F99999999 makes this move's feed 1666666.65 mm/s");
	check_err("G1 X1 F60000001\n", 1, 7, "at most 1000000 mm/s");
	check_err("G1 X1 F0.0599\n", 1, 7, "at least 0.001 mm/s");
	/* the F of an earlier line: blamed on the move's own line */
	check_err("F99999999\nG1 X1\n", 2, 1, "F99999999 makes this move's feed");
	check_err("G20 G1 X1 F2400000\n", 1, 11, "F2400000 makes this move's feed 1016000 mm/s");
	/* G93: the move takes 1/F minutes */
	check_err("G93 G1 X1 F0.0000001\n", 1, 11, "G93 F1e-7 makes this move's feed");
	check_err("G93 G1 X1 F100000000\n", 1, 11, "at most 1000000 mm/s");
	check_err("G1 X10 F60\nG93 G3 X-10 I-10 F0.00000001\n", 2, 18, "at least 0.001 mm/s");
	/* slow enough to take more than a day: 1000 mm at 0.0012 mm/s */
	check_err("G1 X1000 F0.07\n", 1, 10, "this move takes 238.095238 h");
	parse_ok("G1 X86 F0.06\n", &m, &p); /* 86 mm at 0.001 mm/s: 23.9 h */
	mlip_program_list_free(&p);
	check_err("G1 X87 F0.06\n", 1, 8, "at most 24 h, as a dwell");
	/* a target the drive cannot count (a 32-bit position, 0x607A) */
	{
		struct mlip_machine w = big_machine("XYZ");
		w.axis[0].min_limit = -1e9;
		w.axis[0].max_limit = 1e9;
		w.axis[0].counts_per_unit = 1000;
		w.axis[1].min_limit = -1e9;
		w.axis[1].max_limit = 1e9;
		parse_ok("G0 X2147483.647\nG0 X-2147483.648\n", &w, &p);
		all_blocks_keep_the_rules(&w, &p);
		mlip_program_list_free(&p);
		check_err_m("G1 X1 F600\nG1 X2147483.648\n", &w, 2, 4,
		            "X 2147483.648 beyond the drive's 32-bit position: "
		            "-2147483.648..2147483.647 at COUNTS_PER_UNIT 1000");
		check_err_m("G0 X1\nG2 X2 I1100000 F6000000\n", &w, 2, 4,
		            "at COUNTS_PER_UNIT 1000 on the arc");
	}
	/* G64 P is a distance (LinuxCNC): P-1 is no tolerance, not the default */
	check_err("G64 P-1\nG1 X1 F60\n", 1, 5, "G64 P-1: the path tolerance must be >= 0");
	/* G53 in G91 (LinuxCNC: NCE_CANNOT_USE_G53_INCREMENTAL), modal as on the line */
	check_err("G91\nG53 G0 X10\n", 2, 1, "G53 with G91 in effect");
	check_err("G91 G1 X1 F60\nG53 X10\n", 2, 1, "G53 with G91 in effect");
	parse_ok("G91\nG90 G53 G0 X10\n", &m, &p);
	assert_near(p.blocks[0].target[0], 10, 0);
	mlip_program_list_free(&p);
	/* a Grbl G53 jog is in machine coordinates, in a G91 program too */
	parse_ok("G91 G0 X5\n$J=G53 X10 F600\nX1\n", &m, &p);
	assert_int_equal(p.n, 3);
	assert_near(p.blocks[1].target[0], 10, 0);
	assert_near(p.blocks[2].target[0], 11, 0); /* G91 again after the jog */
	mlip_program_list_free(&p);
}

/* The reader's last line of defence: a block that would break the rule set
 * in spite of the line's checks (here a machine handed to the reader without
 * mlip_machine_check, its tolerance beyond what a block may carry) fails its
 * line; nothing reaches the sink. */
static void test_block_rule_backstop(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_gcode g;
	struct mlip_gcode_error e;
	struct cap c = {.limit = 64};

	(void)state;
	m.tolerance_mm = 2 * MLIP_TOL_MAX_MM;
	mlip_gcode_init(&g, &m);
	assert_int_equal(line(&g, "G1 X1 F60", 1, &c, &e), MLIP_E_RANGE);
	assert_int_equal(e.line, 1);
	assert_int_equal(e.col, 1);
	assert_non_null(strstr(e.msg, "breaks the rule set of every block"));
	assert_int_equal(c.n, 0);
	m.tolerance_mm = MLIP_TOL_MAX_MM;
	mlip_gcode_init(&g, &m);
	assert_int_equal(line(&g, "G1 X1 F60", 1, &c, &e), MLIP_OK);
	assert_int_equal(c.n, 1);
}

/* Issue 17 item 9: '%' delimits a program as LinuxCNC documents it. */
static void test_percent_delimiters(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;

	(void)state;
	/* everything after the second '%' is ignored: before, G1 X500 ran */
	parse_ok("%\nG1 X10 F600\n%\nG1 X500\n", &m, &p);
	assert_int_equal(p.n, 1);
	assert_near(p.blocks[0].target[0], 10, 0);
	assert_int_equal(p.n_notices, 1);
	assert_string_equal(p.notices[0].word, "%");
	assert_int_equal(p.notices[0].first_line, 3);
	mlip_program_list_free(&p);
	/* comments and blank lines before the opening '%'; garbage after the end */
	parse_ok("(a CAM header)\n\n  %  \nG1 X10 F600\n % (end)\nG1 X500\nnot G-code\n", &m, &p);
	assert_int_equal(p.n, 1);
	mlip_program_list_free(&p);
	/* a '%' after the program started, without an opening one, ends it too */
	parse_ok("G1 X10 F600\n%\nG1 X500\n", &m, &p);
	assert_int_equal(p.n, 1);
	mlip_program_list_free(&p);
	/* opened, then M2 (the file's own end) or a '%' at the end */
	parse_ok("%\nG1 X10 F600\nM2\nG1 X500\n", &m, &p);
	assert_int_equal(p.n, 1);
	mlip_program_list_free(&p);
	/* opened and never closed: the file may be cut short (LinuxCNC refuses) */
	check_err("%\nG1 X10 F600\nG1 X20\n", 3, 0,
	          "opens with '%' but ends without the closing '%' or M2/M30");
	check_err("%\n%\nG1 X500\n", 3, 0, "empty program: no motion");
	check_err("%\nG1 X10 F600 %\n", 2, 13, "unexpected character '%'");
}

static void test_pauses_and_end(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	struct mlip_gcode_offsets o;

	(void)state;
	mlip_gcode_offsets_init(&o, &m);
	o.select = 2;
	o.g92_on = 1;
	o.g92[0] = 1;
	/* M0/M60 pause, M1 optional pause, after the motion of their line;
	 * after M2 nothing is read, not even a bad line (LinuxCNC) */
	parse_off("G1 X1 F60 M0\nM1\nG1 X2 M60\nM2\nG1 X3\nthis is not G-code\n", &m, &o, &p);
	assert_int_equal(p.n, 5);
	assert_int_equal(p.blocks[0].kind, MLIP_BLOCK_MOVE);
	assert_int_equal(p.blocks[1].kind, MLIP_BLOCK_PAUSE);
	assert_int_equal(p.blocks[1].line, 1);
	assert_int_equal(p.blocks[2].kind, MLIP_BLOCK_OPTIONAL_PAUSE);
	assert_int_equal(p.blocks[3].kind, MLIP_BLOCK_MOVE);
	assert_near(p.blocks[3].target[0], 3, 0); /* X2 + G92 offset 1 */
	assert_int_equal(p.blocks[4].kind, MLIP_BLOCK_PAUSE);
	assert_non_null(find_notice(&p, "M60"));
	assert_non_null(find_notice(&p, "M2"));
	/* M2: G54 and G92 off for the next program, the G92 values kept */
	assert_int_equal(p.r.offsets_end.select, 0);
	assert_int_equal(p.r.offsets_end.g92_on, 0);
	assert_near(p.r.offsets_end.g92[0], 1, 0);
	mlip_program_list_free(&p);
	/* without M2 the state stays as the program left it */
	parse_off("G56 G1 X1 F60\n", &m, NULL, &p);
	assert_int_equal(p.r.offsets_end.select, 2);
	mlip_program_list_free(&p);
}

static void test_work_offsets(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	struct mlip_gcode_offsets o;

	(void)state;
	mlip_gcode_offsets_init(&o, &m);
	o.coord[1][0] = 10; /* G55 */
	o.coord[1][1] = 20;
	o.coord[8][2] = -5;          /* G59.3 */
	parse_off("G0 X1 Y1\n"       /* G54: machine = program */
	          "G55 X1 Y1\n"      /* (11, 21) */
	          "G91 X1\n"         /* incremental: offsets do not apply (12) */
	          "G90 G53 X1\n"     /* machine coordinates, this line only */
	          "X2\n"             /* G55 again: 12 */
	          "G59.3 Z1\n"       /* -4 */
	          "G10 L2 P2 X100\n" /* G55's X origin := 100 (machine) */
	          "G55 X0\n"         /* 100 */
	          "G10 L20 P0 X5\n"  /* current X (100) reads 5 in G55 */
	          "X5\n"             /* stays: 100 */
	          "X6\n"             /* 101 */
	          "G92 X0\n"         /* current X reads 0: G92 offset 6 */
	          "X1\n"             /* 102 */
	          "G92.2\n"          /* G92 off (kept) */
	          "X1\n"             /* 96 */
	          "G92.3\n"          /* on again */
	          "X0\n"             /* 101 */
	          "G92.1\n"          /* zero and off */
	          "X0\n",            /* 95 */
	          &m, &o, &p);
	{
		static const double x[] = {1, 11, 12, 1, 12, 12, 100, 101, 102, 96, 101, 95};
		size_t k;

		/* merged points emit nothing: compare the X of the moves given */
		assert_int_equal(p.n, 12);
		for (k = 0; k < 12; k++) {
			assert_near(p.blocks[k].target[0], x[k], 1e-12);
		}
		assert_near(p.blocks[1].target[1], 21, 0);
		assert_near(p.blocks[5].target[2], -4, 0);
	}
	assert_int_equal(p.r.offsets_end.select, 1);
	assert_near(p.r.offsets_end.coord[1][0], 95, 1e-12);
	assert_int_equal(p.r.offsets_end.g92_on, 0);
	assert_near(p.r.offsets_end.g92[0], 0, 0);
	mlip_program_list_free(&p);

	/* G10 values are in the line's units, G91 does not apply to them */
	parse_off("G20 G91 G10 L2 P1 X1\nG90 G0 X0\n", &m, NULL, &p);
	assert_near(p.blocks[0].target[0], 25.4, 1e-12);
	mlip_program_list_free(&p);

	/* soft limits are in machine coordinates */
	{
		struct mlip_program r;
		struct mlip_program_options opt = {0, &o, 0, NULL, NULL, 0};
		static const char t[] = "G55 G0 X995\n";

		assert_int_equal(mlip_program_open_mem(&r, t, sizeof t - 1, &m, &opt), 1);
		assert_int_equal(r.errors[0].col, 8);
		assert_string_equal(r.errors[0].msg, "X 1005.000 beyond soft limit 1000.000");
		mlip_program_close(&r);
	}
	check_err("G92 X-1000\nG0 X1\n", 2, 4, "X 1001.000 beyond soft limit 1000.000");
	check_err("G55 G56 X1", 1, 5, "G55 and G56 on one line: same modal group");
}

static void test_path_modes(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;

	(void)state;
	parse_ok("G1 X1 F60\n"
	         "G61 X2\n" /* exact stop from here */
	         "G61.1 X3\n"
	         "G64 X4\n"         /* blending within eps */
	         "G64 P0.005 X5\n"  /* tighter */
	         "G64 P0.5 X6\n"    /* looser than the machine: capped */
	         "G64 P0 Q0.1 X7\n" /* P0: as G64; Q: noted */
	         "G20 G64 P0.0001 X1\n",
	         &m, &p);
	assert_int_equal(p.n, 8);
	assert_int_equal(p.blocks[0].exact_stop, 0);
	assert_int_equal(p.blocks[1].exact_stop, 1);
	assert_int_equal(p.blocks[2].exact_stop, 1);
	assert_int_equal(p.blocks[3].exact_stop, 0);
	assert_near(p.blocks[3].tol_mm, EPS, 0);
	assert_near(p.blocks[4].tol_mm, 0.005, 1e-15);
	assert_near(p.blocks[5].tol_mm, EPS, 0);
	assert_near(p.blocks[6].tol_mm, EPS, 0);
	assert_near(p.blocks[7].tol_mm, 0.00254, 1e-15);
	assert_int_equal(find_notice(&p, "G64P")->first_line, 6);
	assert_int_equal(find_notice(&p, "G64Q")->first_line, 7);
	mlip_program_list_free(&p);

	/* an arc in a G64 P region: chords within a tenth of P, corners in the rest */
	parse_ok("G64 P0.002\nG0 X10\nG3 X-10 I-10 F600\n", &m, &p);
	assert_true(p.n > 10);
	for (size_t k = 1; k + 1 < p.n; k++) {
		assert_true(p.blocks[k].tol_mm <= 0.002 && p.blocks[k].tol_mm >= 0.0018);
	}
	assert_near(p.blocks[p.n - 1].tol_mm, 0.002, 0);
	mlip_program_list_free(&p);
}

static void test_inverse_time(void **state)
{
	struct mlip_machine m = machine("XYZA");
	struct mlip_program_list p;

	(void)state;
	/* G93: the move takes 1/F minutes (LinuxCNC) */
	parse_ok("G0 X10\n"
	         "G93 G1 X20 F6\n"        /* 10 mm in 10 s */
	         "A90 F60\n"              /* rotary only: 90 deg in 1 s */
	         "G0 X0\n"                /* rapids need no F */
	         "G3 X-10 Y10 I-10 F60\n" /* quarter circle, 15.7 mm in 1 s */
	         "G94 G1 X0 F600\n",
	         &m, &p);
	assert_near(p.blocks[1].feed_mm_s, 1.0, 1e-12);
	assert_near(p.blocks[2].feed_mm_s, 90.0, 1e-12);
	assert_int_equal(p.blocks[3].rapid, 1);
	assert_near(p.blocks[4].feed_mm_s, 10 * PI_2, 1e-9);
	assert_near(p.blocks[p.n - 1].feed_mm_s, 10, 1e-12);
	mlip_program_list_free(&p);
	check_err("G93 G1 X1 F10\nX2\n", 2, 1, "G93 inverse time: every feed move needs its own F");
	check_err("G1 X1 F100\nG93\nG94 G1 X2\n", 3, 5,
	          "missing feed: a change between G93 and G94 needs a new F");
}

static void test_grbl_lines(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	static const char *const words[] = {"$H",   "$X",   "$$", "$#", "$32=", "$N",
	                                    "$RST", "$SLP", "$C", "$G", "$I",   "$"};
	size_t k;

	(void)state;
	parse_ok("$H\n$X\n$$\n$#\n$32=1\n$N0=G20\n$RST=*\n$SLP\n$C\n$G\n$I\n$\n  $h  \n"
	         "G1 X1 F60\n/G1 X50\n",
	         &m, &p);
	assert_int_equal(p.n, 1);
	for (k = 0; k < sizeof words / sizeof words[0]; k++) {
		const struct mlip_gcode_notice *n = find_notice(&p, words[k]);

		assert_non_null(n);
		assert_int_equal(n->first_line, k + 1);
		assert_non_null(strstr(mlip_gcode_notice_text(n), "skipped"));
	}
	assert_int_equal(find_notice(&p, "$H")->count, 2);
	assert_non_null(strstr(mlip_gcode_notice_text(find_notice(&p, "$H")), "does not home"));
	assert_int_equal(find_notice(&p, "/")->first_line, 15); /* block delete */
	mlip_program_list_free(&p);

	/* M codes that do not move the tool: notes (M29, a printer fan, overrides) */
	parse_ok("M29\nM106 S255\nM48\nG1 X1 F60 M107\nM29\n", &m, &p);
	assert_int_equal(p.n, 1);
	assert_int_equal(find_notice(&p, "M29")->count, 2);
	assert_string_equal(mlip_gcode_notice_text(find_notice(&p, "M106")),
	                    "ignored (no effect on motion)");
	assert_non_null(find_notice(&p, "M48"));
	assert_non_null(find_notice(&p, "M107"));
	mlip_program_list_free(&p);

	/* a jog runs as G1 at its own F, its G91/G20 for itself only (Grbl) */
	parse_ok("G0 X5\n$J=G91 G20 X1 F60\nX1\n$J=G53 Y2 F600\nY1\n", &m, &p);
	assert_int_equal(p.n, 5);
	assert_near(p.blocks[1].target[0], 5 + 25.4, 1e-12);
	assert_int_equal(p.blocks[1].rapid, 0);
	assert_near(p.blocks[1].feed_mm_s, 25.4, 1e-12); /* 60 in/min */
	assert_near(p.blocks[2].target[0], 1, 0);        /* G0 G90 G21 again */
	assert_int_equal(p.blocks[2].rapid, 1);
	assert_near(p.blocks[3].target[1], 2, 0);
	assert_int_equal(p.blocks[3].line, 4);
	assert_int_equal(find_notice(&p, "$J")->count, 2);
	mlip_program_list_free(&p);
	check_err("G1 X1 F60\n$J=G91 X10\n", 2, 1, "Grbl jog without F");
	check_err("G1 X1 F60\n$J=G2 X10 I1 F60\n", 2, 4, "Grbl jog: only G20, G21, G90, G91, G53");
	check_err("G1 X1 F60\n$J=X2000 F60\n", 2, 4, "X 2000.000 beyond soft limit");
	check_err("G1 X1 F60\n$J=X1.2.3 F60\n", 2, 5, "malformed number '1.2.3'");
	check_err("$FOO\nG1 X1 F60\n", 1, 1, "unknown Grbl system command '$FOO'");
	/* Grbl's real-time characters alone on a line: noted */
	parse_ok("?\n ~ \nG1 X1 F60\n!\n", &m, &p);
	assert_int_equal(p.n, 1);
	assert_int_equal(find_notice(&p, "?")->first_line, 1);
	assert_int_equal(find_notice(&p, "~")->first_line, 2);
	assert_non_null(strstr(mlip_gcode_notice_text(find_notice(&p, "!")), "M0"));
	mlip_program_list_free(&p);
	check_err("G1 X1 F60 ~\n", 1, 11, "unexpected character '~'");
	check_err("$H (home)\nG1 X1 F60\n", 1, 1, "unknown Grbl system command");
	check_err("$N0=G20 \xE9\nG1 X1 F60\n", 1, 9, "unexpected character 0xE9");
	{
		struct mlip_gcode g;
		struct mlip_gcode_error e;
		struct cap c = {.n = 0, .limit = 64};

		mlip_gcode_init(&g, &m);
		mlip_gcode_set_strict(&g, 1);
		assert_int_equal(line(&g, "$H", 1, &c, &e), MLIP_E_UNSUPPORTED);
		assert_non_null(strstr(e.msg, "Grbl system line '$H' is not G-code (strict mode)"));
	}
}

static void test_line_ends_and_stream(void **state)
{
	struct mlip_machine m = big_machine("XYZ");
	struct mlip_program_list p;
	double r = 5000, ang, prev = -1;
	size_t k;

	(void)state;
	/* LF, CRLF and lone CR end lines; CR CR LF is two */
	parse_ok("G1 X1 F60\rX2\r\nX3\nX4\r\r\nX5", &m, &p);
	assert_int_equal(p.n, 5);
	assert_int_equal(p.blocks[3].line, 4);
	assert_int_equal(p.blocks[4].line, 6);
	mlip_program_list_free(&p);

	/* an arc of more chords than a batch comes out whole, in order */
	parse_ok("G0 X5000\nG3 I-5000 F6000\n", &m, &p);
	assert_true(p.n > 1 + 2 * MLIP_PROGRAM_BATCH / 2);
	assert_true(p.n - 1 > MLIP_PROGRAM_BATCH);
	for (k = 1; k < p.n; k++) {
		assert_near(hypot(p.blocks[k].target[0], p.blocks[k].target[1]), r, 1e-6);
		ang = atan2(p.blocks[k].target[1], p.blocks[k].target[0]);
		ang = ang < 0 ? ang + 2 * M_PI_VALUE : ang;
		if (k + 1 < p.n) {
			assert_true(ang > prev); /* counter-clockwise, no repeat, no gap */
		}
		prev = ang;
	}
	assert_near(p.blocks[p.n - 1].target[0], 5000, 0);
	mlip_program_list_free(&p);
}

static void test_files(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program r;
	struct mlip_block b;
	char dir[] = "/tmp/mlip-test-XXXXXX", path[64], fifo[64];
	FILE *f;
	int rc;

	(void)state;
	/* not regular files: refused at once, never read (nor blocked on) */
	assert_true(mlip_program_open(&r, "/dev/zero", &m, NULL) < 0);
	assert_non_null(strstr(r.msg, "a character device"));
	mlip_program_close(&r);
	assert_non_null(mkdtemp(dir));
	assert_true(mlip_program_open(&r, dir, &m, NULL) < 0);
	assert_non_null(strstr(r.msg, "a directory"));
	mlip_program_close(&r);
	snprintf(fifo, sizeof fifo, "%s/fifo", dir);
	assert_int_equal(mkfifo(fifo, 0600), 0);
	assert_true(mlip_program_open(&r, fifo, &m, NULL) < 0);
	assert_non_null(strstr(r.msg, "a FIFO"));
	mlip_program_close(&r);
	remove(fifo);

	/* a file changed between the check and the run stops the stream */
	snprintf(path, sizeof path, "%s/p.ngc", dir);
	f = fopen(path, "w");
	assert_non_null(f);
	fputs("G1 X1 F60\nX2\nX3\n", f);
	fclose(f);
	assert_int_equal(mlip_program_open(&r, path, &m, NULL), 0);
	assert_int_equal(r.n, 3);
	f = fopen(path, "w");
	assert_non_null(f);
	fputs("G1 X1 F60\nX2 X7\nX3\n", f);
	fclose(f);
	/* its chunk differs from the one checked: not a block of it is given */
	rc = mlip_program_next(&r, &b);
	assert_true(rc < 0);
	assert_string_equal(r.msg, "the file changed after it was checked (bytes 0 to 18 differ "
	                           "from the ones checked, line 1): the rest is not run");
	mlip_program_close(&r);

	/* a very long line: an error with its length, only a line's worth kept */
	f = fopen(path, "w");
	assert_non_null(f);
	fputs("G1 X1 F60\n(", f);
	for (rc = 0; rc < 100000; rc++) {
		fputc('x', f);
	}
	fputs(")\n", f);
	fclose(f);
	assert_int_equal(mlip_program_open(&r, path, &m, NULL), 1);
	assert_string_equal(r.errors[0].msg, "line too long: 100002 bytes, at most 256");
	mlip_program_close(&r);
	remove(path);
	rmdir(dir);
}

/* ---- MDI: the modal state carried, lines without motion (issue 18) ---- */

/* A program whose only effect is an offsets change (a touch-off) is one;
 * lines that change nothing still are "empty". */
static void test_offsets_only_program(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_program_list p;
	struct mlip_gcode g;
	struct mlip_gcode_error e;
	struct cap c = {.limit = 64};

	(void)state;
	m.axis[0].home = 12.5; /* where the machine stands */
	parse_ok("G10 L20 P1 X0 Y0\n", &m, &p);
	assert_int_equal(p.n, 0);
	assert_near(p.r.offsets_end.coord[0][0], 12.5, 0);
	assert_near(p.r.offsets_end.coord[0][1], 0.0, 0);
	mlip_program_list_free(&p);
	parse_ok("G92 X0\n", &m, &p);
	assert_int_equal(p.r.offsets_end.g92_on, 1);
	assert_near(p.r.offsets_end.g92[0], 12.5, 0);
	mlip_program_list_free(&p);
	parse_ok("G10 L2 P2 Z-5\nM2\n", &m, &p);
	assert_near(p.r.offsets_end.coord[1][2], -5.0, 0);
	mlip_program_list_free(&p);
	check_err("G21 G90\n", 1, 0, "empty program: no motion");
	check_err("G10 L2 P1 X0\n", 1, 0, "empty program: no motion"); /* the same values */
	check_err("G4 P1\n", 1, 0, "empty program: no motion");
	/* MDI: modes alone are lines */
	mlip_gcode_init(&g, &m);
	mlip_gcode_set_mdi(&g, 1);
	assert_int_equal(line(&g, "G91 F300", 1, &c, &e), MLIP_OK);
	assert_int_equal(mlip_gcode_finish(&g, 1, &e), MLIP_OK);
	assert_int_equal(c.n, 0);
}

/* The modal state one MDI leaves is where the next starts: G91, G20, F, G0
 * motion, G64 P, G43.1; a state out of range is refused whole. */
static void test_modal_carry(void **state)
{
	struct mlip_machine m = machine("XYZ");
	struct mlip_gcode g;
	struct mlip_gcode_error e;
	struct mlip_gcode_modal md, back, bad;
	struct cap c = {.limit = 64};

	(void)state;
	mlip_gcode_init(&g, &m);
	mlip_gcode_get_modal(&g, &md);
	mlip_gcode_modal_init(&back, &m);
	assert_int_equal(md.motion, back.motion);
	assert_int_equal(md.absolute, 1);
	assert_near(md.tol_mm, EPS, 0);
	assert_near(md.feed_word, 0, 0);
	/* first MDI (G43.1 needs the machine's I/O: without it, a notice) */
	static const struct mlip_gcode_io io = {0};
	mlip_gcode_set_io(&g, &io);
	assert_int_equal(line(&g, "G20 G91 G1 F10 G64 P0.0001", 1, &c, &e), MLIP_OK);
	if (line(&g, "G43.1 Z0.5", 2, &c, &e) != MLIP_OK) {
		print_error("%s\n", e.msg);
		fail();
	}
	mlip_gcode_get_modal(&g, &md);
	assert_int_equal(md.inches, 1);
	assert_int_equal(md.absolute, 0);
	assert_int_equal(md.motion, 1);
	assert_near(md.feed_word, 10, 0);
	assert_near(md.tol_mm, 0.0001 * 25.4, 1e-15);
	assert_int_equal(md.tlo_mode, 431);
	assert_near(md.tlo_mm, 0.5 * 25.4, 1e-12);
	/* the next: a fresh reader from that state; X1 is 1 inch more at 10 in/min */
	mlip_gcode_init(&g, &m);
	assert_int_equal(mlip_gcode_set_modal(&g, &md), MLIP_OK);
	c.n = 0;
	assert_int_equal(line(&g, "X1", 1, &c, &e), MLIP_OK);
	assert_int_equal(c.n, 1);
	assert_near(c.b[0].target[0], 25.4, 1e-12);
	assert_int_equal(c.b[0].rapid, 0);
	assert_near(c.b[0].feed_mm_s, 10 * 25.4 / 60, 1e-12);
	assert_near(c.b[0].tol_mm, 0.0001 * 25.4, 1e-15);
	mlip_gcode_get_modal(&g, &back);
	assert_memory_equal(&back, &md, sizeof md);
	/* out of range: each refused, g unchanged */
	bad = md;
	bad.tol_mm = 2 * EPS;
	assert_int_equal(mlip_gcode_set_modal(&g, &bad), MLIP_E_RANGE);
	bad = md;
	bad.plane = 16;
	assert_int_equal(mlip_gcode_set_modal(&g, &bad), MLIP_E_RANGE);
	bad = md;
	bad.feed_word = -1;
	assert_int_equal(mlip_gcode_set_modal(&g, &bad), MLIP_E_RANGE);
	bad = md;
	bad.feed_word = NAN;
	assert_int_equal(mlip_gcode_set_modal(&g, &bad), MLIP_E_RANGE);
	bad = md;
	bad.tlo_mode = 490; /* G49 with an offset */
	assert_int_equal(mlip_gcode_set_modal(&g, &bad), MLIP_E_RANGE);
	bad = md;
	bad.inverse_time = 1; /* a G93 F is never carried */
	assert_int_equal(mlip_gcode_set_modal(&g, &bad), MLIP_E_RANGE);
	mlip_gcode_get_modal(&g, &back);
	assert_memory_equal(&back, &md, sizeof md);
	{
		struct mlip_gcode_modal cyc;
		/* a canned cycle's mode ends with its MDI line: the next refuses axis
		 * words alone (motion -2), as after G80; G1 moves again */
		mlip_gcode_init(&g, &m);
		c.n = 0;
		assert_int_equal(line(&g, "G0 Z5", 1, &c, &e), MLIP_OK);
		assert_int_equal(line(&g, "G81 X1 Z-1 R1 F60", 2, &c, &e), MLIP_OK);
		mlip_gcode_get_modal(&g, &cyc);
		assert_int_equal(cyc.motion, -2);
		mlip_gcode_init(&g, &m);
		assert_int_equal(mlip_gcode_set_modal(&g, &cyc), MLIP_OK);
		assert_int_equal(line(&g, "X2", 1, &c, &e), MLIP_E_SYNTAX);
		assert_non_null(strstr(e.msg, "after a canned cycle ended"));
		assert_int_equal(line(&g, "G1 X2", 2, &c, &e), MLIP_OK);
		mlip_gcode_get_modal(&g, &cyc);
		assert_int_equal(cyc.motion, 1);
	}
	/* through the program reader, as mlip-ctl mdi reads lines */
	{
		struct mlip_program prog;
		struct mlip_program_options opt = {0, NULL, 0, NULL, &md, 1};
		const char *t = "G90\n";
		assert_int_equal(mlip_program_open_mem(&prog, t, strlen(t), &m, &opt), 0);
		assert_int_equal(prog.n, 0);
		assert_int_equal(prog.modal_end.absolute, 1);
		assert_int_equal(prog.modal_end.inches, 1);
		assert_near(prog.modal_end.feed_word, 10, 0);
		mlip_program_close(&prog);
		bad = md;
		bad.tol_mm = 1;
		opt.modal = &bad;
		assert_true(mlip_program_open_mem(&prog, t, strlen(t), &m, &opt) < 0);
		mlip_program_close(&prog);
	}
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_numbers),
	    cmocka_unit_test(test_malformed_numbers),
	    cmocka_unit_test(test_bytes_and_comments),
	    cmocka_unit_test(test_line_too_long),
	    cmocka_unit_test(test_unsupported_codes),
	    cmocka_unit_test(test_notices),
	    cmocka_unit_test(test_notice_overflow),
	    cmocka_unit_test(test_modal),
	    cmocka_unit_test(test_missing_feed),
	    cmocka_unit_test(test_incremental_and_home),
	    cmocka_unit_test(test_inches_and_rotary),
	    cmocka_unit_test(test_config_order_and_axes),
	    cmocka_unit_test(test_soft_limits),
	    cmocka_unit_test(test_home_codes),
	    cmocka_unit_test(test_merge),
	    cmocka_unit_test(test_sink_full_and_empty),
	    cmocka_unit_test(test_arc_g17),
	    cmocka_unit_test(test_arc_g18_g19),
	    cmocka_unit_test(test_arc_radius_tolerance),
	    cmocka_unit_test(test_full_circle_and_helix),
	    cmocka_unit_test(test_canned_cycles),
	    cmocka_unit_test(test_r_arcs),
	    cmocka_unit_test(test_arc_random),
	    cmocka_unit_test(test_program_errors_and_print),
	    cmocka_unit_test(test_program_error_cap),
	    cmocka_unit_test(test_read_file_errors),
	    cmocka_unit_test(test_scan_axes),
	    cmocka_unit_test(test_toolpaths),
	    cmocka_unit_test(test_sheeptile_arcs),
	    cmocka_unit_test(test_dwell),
	    cmocka_unit_test(test_block_rule_set),
	    cmocka_unit_test(test_percent_delimiters),
	    cmocka_unit_test(test_block_rule_backstop),
	    cmocka_unit_test(test_pauses_and_end),
	    cmocka_unit_test(test_work_offsets),
	    cmocka_unit_test(test_path_modes),
	    cmocka_unit_test(test_inverse_time),
	    cmocka_unit_test(test_grbl_lines),
	    cmocka_unit_test(test_line_ends_and_stream),
	    cmocka_unit_test(test_files),
	    cmocka_unit_test(test_offsets_only_program),
	    cmocka_unit_test(test_modal_carry),
	};

	return cmocka_run_group_tests(tests, NULL, NULL);
}
