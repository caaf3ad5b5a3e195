/*
 * test_program_pin.c - a program is pinned between its check and its run
 * (tools/lib/program.h): every pass compares each chunk's SHA-256 with the
 * first pass's before it parses a byte of it. A byte changed in place, a
 * file grown or cut, a second reader of a changed file: the stream ends at
 * the first chunk that differs, every block given out before it from bytes
 * that were checked. A file replaced by rename is not the one open: the
 * checked bytes run.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "program.h"

static char dir[64], path[128];

static int setup(void **state)
{
	(void)state;
	snprintf(dir, sizeof(dir), "/tmp/mlip-pin-XXXXXX");
	assert_non_null(mkdtemp(dir));
	snprintf(path, sizeof(path), "%s/p.ngc", dir);
	return 0;
}

static int teardown(void **state)
{
	(void)state;
	char p[160];
	snprintf(p, sizeof(p), "%s.new", path);
	unlink(p);
	unlink(path);
	rmdir(dir);
	return 0;
}

static struct mlip_machine machine(void)
{
	struct mlip_machine m;
	memset(&m, 0, sizeof(m));
	m.n_axes = 2;
	m.max_feed_mm_s = 200;
	m.tolerance_mm = 0.01;
	m.period_s = 0.001;
	for (int k = 0; k < 2; k++) {
		m.axis[k].letter = "XY"[k];
		m.axis[k].max_vel = 200;
		m.axis[k].max_accel = 1000;
		m.axis[k].min_limit = -1000;
		m.axis[k].max_limit = 1000;
	}
	return m;
}

/* n lines "X1xx.xxx Y0\n", each 12 bytes (X within 100..149): line k at
 * byte 11 + 12 (k - 2) after the first line "G1 F6000 X1\n" (12 bytes). */
#define LINE 12
static void write_program(const char *p, int n)
{
	FILE *f = fopen(p, "w");
	assert_non_null(f);
	fputs("G1 F6000 X1\n", f);
	for (int k = 1; k < n; k++) {
		fprintf(f, "X%07.3f Y0\n", 100.0 + (k % 50));
	}
	fclose(f);
}

/* rewrite line `line` (1-based) in place with text of the same length */
static void rewrite_line(const char *p, int line, const char *text)
{
	FILE *f = fopen(p, "r+");
	assert_non_null(f);
	assert_int_equal(fseek(f, (long)(line - 1) * LINE, SEEK_SET), 0);
	assert_int_equal(fwrite(text, 1, strlen(text), f), strlen(text));
	fclose(f);
}

/* Blocks given out until the stream ends; *rc its last return. */
static size_t stream(struct mlip_program *r, double *max_x, int *rc)
{
	struct mlip_block b;
	size_t n = 0;
	*max_x = 0;
	while ((*rc = mlip_program_next(r, &b)) > 0) {
		n++;
		*max_x = b.target[0] > *max_x ? b.target[0] : *max_x;
	}
	return n;
}

/* The probe of issue 17 item 4 at scale: 20000 lines (240 kB, 4 chunks),
 * one X rewritten to X900.000 in the fourth chunk after the check. */
static void test_in_place_change_stops_before_its_chunk(void **state)
{
	(void)state;
	struct mlip_machine m = machine();
	struct mlip_program r;
	double max_x;
	int rc, line = 18000; /* byte 215988: chunk 3 (196608 .. 262143) */
	write_program(path, 20000);
	assert_int_equal(mlip_program_open(&r, path, &m, NULL), 0);
	assert_int_equal(r.n, 20000);
	rewrite_line(path, line, "X900.000 Y0\n");
	size_t n = stream(&r, &max_x, &rc);
	assert_true(rc < 0);
	assert_true(max_x <= 149.0); /* X900 never given out */
	/* every line wholly in chunks 0..2 (bytes < 196608) given, no more */
	size_t whole = (196608 - LINE) / LINE + 1;
	assert_int_equal(n, whole);
	assert_string_equal(r.msg,
	                    "the file changed after it was checked (bytes 196608 to 239999 "
	                    "differ from the ones checked, line 16385): the rest is not run");
	mlip_program_close(&r);
}

/* Grown, cut short, and the copy another program wrote over it (cp keeps
 * the inode, the block count the same): each refused at its chunk. */
static void test_grown_cut_or_copied_over(void **state)
{
	(void)state;
	struct mlip_machine m = machine();
	struct mlip_program r;
	double max_x;
	int rc;

	write_program(path, 8000); /* 96000 bytes: chunks 0, 1 */
	assert_int_equal(mlip_program_open(&r, path, &m, NULL), 0);
	FILE *f = fopen(path, "a");
	fputs("X140 Y0\n", f);
	fclose(f);
	stream(&r, &max_x, &rc);
	assert_true(rc < 0);
	assert_non_null(strstr(r.msg, "(bytes 65536 to 96007 differ from the ones checked"));
	mlip_program_close(&r);

	write_program(path, 8000);
	assert_int_equal(mlip_program_open(&r, path, &m, NULL), 0);
	assert_int_equal(truncate(path, 65536), 0); /* exactly chunk 0 left */
	size_t n = stream(&r, &max_x, &rc);
	assert_true(rc < 0);
	assert_non_null(strstr(r.msg, "it ends at byte 65536, before the 2 chunks that were"));
	assert_int_equal(n, 65536 / LINE); /* the lines wholly in chunk 0 */
	mlip_program_close(&r);

	write_program(path, 8000);
	assert_int_equal(mlip_program_open(&r, path, &m, NULL), 0);
	f = fopen(path, "w"); /* cp other.ngc p.ngc: same lines, other values */
	fputs("G1 F6000 X1\n", f);
	for (int k = 1; k < 8000; k++) {
		fprintf(f, "X%07.3f Y0\n", k == 7000 ? 900.0 : 100.0 + (k % 50));
	}
	fclose(f);
	n = stream(&r, &max_x, &rc);
	assert_true(rc < 0 && max_x <= 149.0);
	assert_int_equal(n, (65536 - LINE) / LINE + 1);
	mlip_program_close(&r);
}

/* A second reader (mlip-sim's check behind its feeder) verifies too; a file
 * replaced by rename leaves the open one as it was: what was checked runs. */
static void test_second_reader_and_rename(void **state)
{
	(void)state;
	struct mlip_machine m = machine();
	struct mlip_program r, second;
	double max_x;
	int rc;
	char repl[160];

	write_program(path, 8000);
	assert_int_equal(mlip_program_open(&r, path, &m, NULL), 0);
	assert_int_equal(mlip_program_open_reader(&second, &r, path), 0);
	rewrite_line(path, 7000, "X900.000 Y0\n");
	stream(&second, &max_x, &rc);
	assert_true(rc < 0 && max_x <= 149.0);
	assert_non_null(strstr(second.msg, "the file changed after it was checked (bytes 65536"));
	mlip_program_close(&second);
	mlip_program_close(&r);

	write_program(path, 8000);
	assert_int_equal(mlip_program_open(&r, path, &m, NULL), 0);
	snprintf(repl, sizeof(repl), "%s.new", path);
	write_program(repl, 9000);
	assert_int_equal(rename(repl, path), 0); /* an editor's save */
	size_t n = stream(&r, &max_x, &rc);
	assert_int_equal(rc, 0);
	assert_int_equal(n, 8000); /* the program that was checked, whole */
	mlip_program_close(&r);
}

/* The same file, unchanged: every pass equal, rewind too (smooth's count). */
static void test_unchanged_streams_whole(void **state)
{
	(void)state;
	struct mlip_machine m = machine();
	struct mlip_program r;
	double max_x;
	int rc;
	write_program(path, 20000);
	assert_int_equal(mlip_program_open(&r, path, &m, NULL), 0);
	assert_int_equal(stream(&r, &max_x, &rc), 20000);
	assert_int_equal(rc, 0);
	mlip_program_rewind(&r);
	assert_int_equal(stream(&r, &max_x, &rc), 20000);
	assert_int_equal(rc, 0);
	mlip_program_close(&r);
}

#define T(f) cmocka_unit_test_setup_teardown(f, setup, teardown)

int main(void)
{
	const struct CMUnitTest tests[] = {
	    T(test_in_place_change_stops_before_its_chunk),
	    T(test_grown_cut_or_copied_over),
	    T(test_second_reader_and_rename),
	    T(test_unchanged_streams_whole),
	};
	return cmocka_run_group_tests_name("program pin", tests, NULL, NULL);
}
