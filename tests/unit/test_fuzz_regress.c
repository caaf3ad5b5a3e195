/*
 * test_fuzz_regress.c - every input in fuzz/regress/ through both text
 * front ends, with the very checks the fuzz targets make (fuzz/invariants.h)
 * plus an expected outcome per input: blocks, errors and the first error for
 * the G-code front end on the 3-axis mill (initial feed as the tools use it),
 * status, line and a message fragment for the config reader. The same G-code
 * also runs on the 4-axis machine, without the initial feed, and with a sink
 * that refuses every third block, under the invariants alone.
 *
 * The inputs are small, hand-picked nasty texts (long numbers, nested
 * comments, NUL bytes, truncated UTF-8, huge radii, 1e308, -0, exponent
 * forms) and whatever the fuzzers found (fuzz/run.sh). A file without a row
 * below, or a row without its file, fails the test. Tests run from the
 * repository root; MLIP_REGRESS_PRINT=1 prints each file's outcome as a row.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>

#include <cmocka.h>

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mlip/machine/config.h"
#include "mlip/gcode/gcode.h"

#include "../../fuzz/invariants.h"

#define REGRESS_DIR "fuzz/regress"

/* One input and what it gives. G-code: on the mill, with the initial feed;
 * errors count every line error, plus "empty program" when no block came.
 * Config: parsed into the defaults. A fragment is looked for in the message. */
struct expect {
	const char *file;
	size_t blocks, errors;
	uint32_t g_line, g_col; /* first G-code error, when errors > 0 */
	const char *g_frag;
	mlip_status c_st;
	uint32_t c_line, c_col;
	const char *c_frag; /* NULL when c_st is MLIP_OK */
};

#define OK  MLIP_OK
#define SYN MLIP_E_SYNTAX
#define RNG MLIP_E_RANGE

static const struct expect table[] = {
    /* ---- G-code inputs (through the config reader: line 1 is no KEY = VALUE) */
    /* ((((...)))): comments do not nest, the first ')' ends one; "(a (b) c)" too */
    {"gcode-comment-nesting.ngc", 0, 3, 2, 128, "unexpected character ')'", SYN, 1, 5,
     "expected '=' after key G21"},
    /* BOM and CRLF accepted on line 1; a lone CR ends a line (old Mac files)
     * so "G1 X2\rY2" is two lines; a BOM on line 5 is not accepted */
    {"gcode-crlf-bom.ngc", 3, 1, 5, 1, "non-ASCII byte 0xEF outside a comment", SYN, 1, 5,
     "expected '=' after key G21"},
    /* no exponents in G-code: 1e308, 1E5, .5e-3 malformed; "X1e" is X1 and a
     * word E without number; 250 nines read as a finite, out-of-limit value */
    {"gcode-e308.ngc", 0, 6, 1, 5, "malformed number '1e308'", SYN, 1, 4,
     "expected '=' after key G1"},
    /* issue 11's words in one file, lone CRs among LFs: Grbl lines skipped,
     * G10/G55/G92 offsets, a dwell before its move, M0 after it, a deleted
     * block, G28 through Y2, G64 P Q, G61, G93; G94 forgets F (the error);
     * nothing after M2 is read */
    {"gcode-events-offsets.ngc", 9, 1, 15, 1,
     "missing feed: a change between G93 and G94 needs a new F", SYN, 1, 8,
     "control character 0x0D (a CR not followed by LF)"},
    /* the machine's I/O words, good and bad: without a machine's I/O (here)
     * G43 is refused and the rest are notices; with it (INV_IO, the replay)
     * the events, the refusals and the change moves under the invariants */
    {"gcode-io-words.ngc", 5, 6, 3, 7, "G43: a tool length offset needs the machine's config", 4, 1,
     1, "expected KEY = VALUE, a [SECTION] or a comment, got '('"},
    {"gcode-exponent-forms.ngc", 0, 11, 1, 5, "malformed number '1.5e+2'", SYN, 1, 4,
     "expected '=' after key G1"},
    /* R 1e200, R 1e20 and I 1e200: rejected, nothing emitted. (The message
     * is misleading: the start and end angles round to the same value, the
     * zero sweep becomes a full turn of a huge circle. Safe, but worth a
     * better message; see the fuzzing report.) R 1e6 is a near-straight arc,
     * one chord. */
    {"gcode-huge-radius.ngc", 1, 4, 3, 1, "arc too long: more than 1000000 chords", SYN, 1, 5,
     "expected '=' after key G21"},
    /* 240 zeros then 1: a value of 1e-241, merged with home; 40 digits read */
    {"gcode-long-fraction.ngc", 2, 0, 0, 0, NULL, SYN, 1, 4, "expected '=' after key G1"},
    /* 256 bytes after the CR is stripped: fine; 257 and 5005: too long */
    /* control characters quoted from the line are shown as '?' (fuzz_gcode) */
    {"gcode-grbl-tab.ngc", 1, 1, 1, 1, "unknown Grbl system command '$32Y???5 I5 J0 F2/0 Y0 Z'", 4,
     1, 1, "expected KEY = VALUE, a [SECTION] or a comment, got '$'"},
    /* a long line's F (cut off by the tools' bounded reader) is never the
     * program's first F: the F of line 3 feeds line 2 (fuzz_gcode found the
     * two front ends disagreeing) */
    {"gcode-long-line-feed.ngc", 3, 1, 1, 257, "line too long: 272 bytes, at most 256", 4, 1, 4,
     "expected '=' after key G1, got 'X'"},
    {"gcode-long-line.ngc", 1, 2, 3, 257, "line too long: 257 bytes, at most 256", SYN, 1, 5,
     "expected '=' after key G21"},
    /* 250 digits: finite, beyond the soft limit ("huge" in the message) */
    {"gcode-long-number.ngc", 1, 2, 3, 4, "X huge beyond soft limit 1000.000", SYN, 1, 5,
     "expected '=' after key G21"},
    /* nan, INF, -inf, infinity, "F nan": malformed numbers, as strtod would
     * have taken them */
    {"gcode-nan-inf.ngc", 1, 5, 2, 5, "malformed number 'nan'", SYN, 1, 4,
     "expected '=' after key G1"},
    /* X-0, Y-0.0, Z-.0 are home (no block); F-0 and F0 are not positive */
    {"gcode-negative-zero.ngc", 2, 2, 5, 1, "feed F must be positive", SYN, 1, 5,
     "expected '=' after key G21"},
    /* NUL after a word, inside a comment, alone */
    {"gcode-nul.ngc", 1, 3, 2, 6, "NUL byte in line", SYN, 1, 4, "expected '=' after key G1"},
    /* no motion, but offsets set (G10 L2) and selected (G55): a program
     * (mlip_gcode_finish), which the invariants once called empty */
    {"gcode-offsets-only.ngc", 0, 0, 0, 0, NULL, SYN, 1, 1,
     "expected KEY = VALUE, a [SECTION] or a comment, got '('"},
    /* a truncated 2-byte and 3-byte sequence, a surrogate, an overlong NUL in
     * comments; a byte >= 0x80 outside one; a valid comment with an emoji */
    {"gcode-utf8-truncated.ngc", 1, 5, 1, 16, "invalid UTF-8 in comment", SYN, 1, 16,
     "invalid UTF-8 byte 0xC3"},

    /* ---- config inputs (through the G-code front end: '[' is no word) ---- */
    /* [[[[[[TRAJ]]]]]]: the name ends at the first ']', the rest is junk */
    {"config-deep-brackets.ini", 0, 2, 1, 1, "unexpected character '['", SYN, 1, 12,
     "unexpected ']' after section header"},
    /* -1e308, DBL_MAX typed out, 1e-320 (subnormal), 4.9e-324: all read as
     * numbers, then refused by the machine's bounds (MLIP_CONFIG_*_MAX) */
    {"config-e308.ini", 0, 15, 1, 1, "unexpected character '['", RNG, 3, 1,
     "TRAJ MAX_LINEAR_VELOCITY must be at most 100000, got 1e308"},
    {"config-exponent-bad.ini", 0, 5, 1, 1, "unexpected character '['", SYN, 4, 21,
     "malformed number '1e' for CONTOUR_TOLERANCE"},
    /* +2E+2, 1.e-3, .1e4, 000001e3, -0e0, 0x0080, 0X7fF, 0010 (decimal) */
    {"config-exponent-forms.ini", 0, 19, 1, 1, "unexpected character '['", OK, 0, 0, NULL},
    /* 0.(300 zeros)2 is fine; 1 and 400 zeros overflows a double */
    {"config-long-number.ini", 0, 8, 1, 1, "unexpected character '['", RNG, 7, 20,
     "number out of range '10000000000000000000000000000000...'"},
    /* MIN_LIMIT -0 is not below MAX_LIMIT 0 */
    {"config-negative-zero.ini", 0, 14, 1, 1, "unexpected character '['", RNG, 10, 1,
     "AXIS_X MIN_LIMIT must be < MAX_LIMIT, got 0 >= 0"},
    {"config-nul.ini", 0, 3, 1, 1, "unexpected character '['", SYN, 2, 16, "NUL byte"},
    /* 1.8e308 is beyond DBL_MAX */
    {"config-overflow.ini", 0, 12, 1, 1, "unexpected character '['", RNG, 8, 13,
     "number out of range '1.8e308' for MAX_LIMIT"},
    /* a section name of 4-byte characters, quoted cut on a character boundary */
    {"config-utf8-section.ini", 0, 3, 1, 1, "unexpected character '['", SYN, 2, 2,
     "unknown section [AXIS_\xF0\x9F\x98\x80\xF0\x9F\x98\x80"},
    {"config-utf8-truncated.ini", 0, 2, 1, 1, "unexpected character '['", SYN, 1, 13,
     "invalid UTF-8 byte 0xC3"},
};

static int print_mode;
static struct mlip_machine mill, rotary;
static struct mlip_config mill_config;

static int setup(void **state)
{
	(void)state;
	print_mode = getenv("MLIP_REGRESS_PRINT") != NULL;
	mlip_config_defaults(&mill_config);
	if (inv_machine(inv_mill_ini, &mill) != 0 || inv_machine(inv_rotary_ini, &rotary) != 0 ||
	    mlip_config_parse(&mill_config, inv_mill_ini, strlen(inv_mill_ini), NULL) != MLIP_OK) {
		return -1;
	}
	return 0;
}

static const struct expect *row_of(const char *name)
{
	size_t k;

	for (k = 0; k < sizeof table / sizeof table[0]; k++) {
		if (strcmp(table[k].file, name) == 0) {
			return &table[k];
		}
	}
	return NULL;
}

static int is_input(const char *name)
{
	return name[0] != '.';
}

/* Every file has a row and every row a file. */
static void test_table_matches_directory(void **state)
{
	DIR *d = opendir(REGRESS_DIR);
	struct dirent *e;
	size_t files = 0;

	(void)state;
	if (d == NULL) {
		fail_msg("%s: cannot open (tests run from the repository root)", REGRESS_DIR);
		return;
	}
	while ((e = readdir(d)) != NULL) {
		if (!is_input(e->d_name)) {
			continue;
		}
		files++;
		if (row_of(e->d_name) == NULL && !print_mode) {
			closedir(d);
			fail_msg("%s/%s has no expected outcome in test_fuzz_regress.c",
			         REGRESS_DIR, e->d_name);
			return;
		}
	}
	closedir(d);
	if (!print_mode) {
		assert_int_equal(files, sizeof table / sizeof table[0]);
	}
}

static void print_row(const char *name, const struct inv_gcode_result *g,
                      const struct inv_config_result *c)
{
	printf("\t{\"%s\", %zu, %zu, %u, %u, ", name, g->blocks, g->errors,
	       g->errors ? (unsigned)g->first.line : 0u, g->errors ? (unsigned)g->first.col : 0u);
	if (g->errors) {
		printf("\"%s\",\n", g->first.msg);
	} else {
		printf("NULL,\n");
	}
	printf("\t %d, %u, %u, ", (int)c->st, c->st ? (unsigned)c->err.line : 0u,
	       c->st ? (unsigned)c->err.col : 0u);
	if (c->st) {
		printf("\"%s\"},\n", c->err.msg);
	} else {
		printf("NULL},\n");
	}
}

static void check_file(const char *name)
{
	const struct expect *x = row_of(name);
	struct inv_gcode_result g, other;
	struct inv_config_result c;
	char path[512];
	const char *w;
	char *buf;
	size_t len;
	int rc, flags[5] = {INV_INITIAL_FEED, 0, INV_INITIAL_FEED | INV_REFUSE | (1 << 3),
	                    INV_INITIAL_FEED | INV_IO, INV_IO | INV_REFUSE | (2 << 3)};
	int k;

	if (snprintf(path, sizeof path, "%s/%s", REGRESS_DIR, name) >= (int)sizeof path) {
		fail_msg("%s: name too long", name);
		return;
	}
	rc = mlip_read_file(path, &buf, &len);
	if (rc != 0) {
		fail_msg("%s: cannot read (%d)", path, rc);
		return;
	}
	/* the invariants, on both machines and in every mode */
	w = inv_gcode_program(&mill, buf, len, INV_INITIAL_FEED, &g);
	if (w) {
		free(buf);
		fail_msg("%s: G-code on the mill: %s (%s)", path, w, g.why);
		return;
	}
	for (k = 0; k < 5; k++) {
		w = inv_gcode_program(&rotary, buf, len, flags[k], &other);
		if (!w && k > 0) {
			w = inv_gcode_program(&mill, buf, len, flags[k], &other);
		}
		if (w) {
			free(buf);
			fail_msg("%s: G-code, flags %d: %s (%s)", path, flags[k], w, other.why);
			return;
		}
	}
	w = inv_config_text(&mill_config, buf, len, &c);
	free(buf);
	if (w) {
		fail_msg("%s: config: %s", path, w);
		return;
	}
	if (print_mode) {
		print_row(name, &g, &c);
		return;
	}
	/* the expected outcome */
	if (g.blocks != x->blocks || g.errors != x->errors ||
	    (x->errors && (g.first.line != x->g_line || g.first.col != x->g_col ||
	                   strstr(g.first.msg, x->g_frag) == NULL))) {
		fail_msg("%s: G-code gave %zu blocks, %zu errors, first %u:%u \"%s\"\n"
		         "  expected %zu blocks, %zu errors, first %u:%u \"...%s...\"",
		         path, g.blocks, g.errors, (unsigned)g.first.line, (unsigned)g.first.col,
		         g.errors ? g.first.msg : "", x->blocks, x->errors, (unsigned)x->g_line,
		         (unsigned)x->g_col, x->g_frag ? x->g_frag : "");
	}
	if (c.st != x->c_st ||
	    (c.st != MLIP_OK && (c.err.line != x->c_line || c.err.col != x->c_col ||
	                         strstr(c.err.msg, x->c_frag) == NULL))) {
		fail_msg("%s: config gave status %d at %u:%u \"%s\"\n"
		         "  expected status %d at %u:%u \"...%s...\"",
		         path, (int)c.st, (unsigned)c.err.line, (unsigned)c.err.col,
		         c.st != MLIP_OK ? c.err.msg : "", (int)x->c_st, (unsigned)x->c_line,
		         (unsigned)x->c_col, x->c_frag ? x->c_frag : "");
	}
}

static int by_name(const void *a, const void *b)
{
	return strcmp(a, b);
}

static void test_replay(void **state)
{
	DIR *d = opendir(REGRESS_DIR);
	struct dirent *e;
	char names[256][128];
	size_t n = 0, k;

	(void)state;
	if (d == NULL) {
		fail_msg("%s: cannot open (tests run from the repository root)", REGRESS_DIR);
		return;
	}
	while ((e = readdir(d)) != NULL && n < 256) {
		if (is_input(e->d_name) && strlen(e->d_name) < sizeof names[0]) {
			strcpy(names[n++], e->d_name);
		}
	}
	closedir(d);
	qsort(names, n, sizeof names[0], by_name);
	for (k = 0; k < n; k++) {
		if (print_mode || row_of(names[k]) != NULL) {
			check_file(names[k]);
		}
	}
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_table_matches_directory),
	    cmocka_unit_test(test_replay),
	};

	return cmocka_run_group_tests(tests, setup, NULL);
}
