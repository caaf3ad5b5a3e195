/*
 * test_statefile.c - the files mlip keeps for the operator (tools/lib/
 * statefile.h) and the offsets file on it (tools/lib/offsets.h): SHA-256
 * against FIPS 180-4's vectors; a file cut at any byte, emptied, filled
 * with NULs, edited without being accepted, holding a key twice or missing
 * one is refused; values named by axis letter land on their axis whatever
 * the machine's axis order; the write never goes through a link, keeps the
 * mode (and owner, as root), respects the umask, leaves no temporary file;
 * a change made between load and write-back is merged per key, or refused
 * when both sides changed one key.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <dirent.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "mlip/gcode/gcode.h"
#include "offsets.h"
#include "sha256.h"
#include "statefile.h"

static char dir[64], path[128];

static int setup(void **state)
{
	(void)state;
	snprintf(dir, sizeof(dir), "/tmp/mlip-sf-XXXXXX");
	assert_non_null(mkdtemp(dir));
	snprintf(path, sizeof(path), "%s/offsets", dir);
	return 0;
}

static int teardown(void **state)
{
	(void)state;
	DIR *d = opendir(dir);
	struct dirent *e;
	char p[512];
	while (d != NULL && (e = readdir(d)) != NULL) {
		if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) {
			snprintf(p, sizeof(p), "%s/%s", dir, e->d_name);
			if (unlink(p) != 0) {
				rmdir(p);
			}
		}
	}
	if (d != NULL) {
		closedir(d);
	}
	rmdir(dir);
	return 0;
}

static struct mlip_machine machine(const char *letters)
{
	struct mlip_machine m;
	memset(&m, 0, sizeof(m));
	m.n_axes = (int)strlen(letters);
	for (int k = 0; k < m.n_axes; k++) {
		m.axis[k].letter = letters[k];
		m.axis[k].home = 10.0 * (k + 1);
	}
	return m;
}

static void write_file(const char *p, const char *text, size_t len)
{
	FILE *f = fopen(p, "wb");
	assert_non_null(f);
	assert_int_equal(fwrite(text, 1, len, f), len);
	fclose(f);
}

static char *read_file(const char *p, size_t *len)
{
	FILE *f = fopen(p, "rb");
	assert_non_null(f);
	static char buf[1 << 16];
	*len = fread(buf, 1, sizeof(buf) - 1, f);
	buf[*len] = '\0';
	fclose(f);
	return buf;
}

/* load through the offsets module; 0 / -1, its message in msg */
static int load(const struct mlip_machine *m, struct mlip_gcode_offsets *o, char *msg, size_t len)
{
	char *out = NULL;
	size_t n = 0;
	FILE *err = open_memstream(&out, &n);
	int rc = mlip_offsets_load(NULL, path, m, o, "t", err);
	fclose(err);
	snprintf(msg, len, "%s", out);
	free(out);
	return rc;
}

static void save(const struct mlip_machine *m, const struct mlip_gcode_offsets *o)
{
	struct mlip_offsets_file f = {path, {0}, 0};
	assert_int_equal(mlip_offsets_save(&f, m, o, "t", stderr), 0);
}

static void test_sha256_vectors(void **state)
{
	(void)state;
	uint8_t d[MLIP_SHA256_BYTES];
	char hex[65];
	mlip_sha256("abc", 3, d);
	mlip_sha256_hex(d, hex, 64);
	assert_string_equal(hex,
	                    "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
	mlip_sha256("", 0, d);
	mlip_sha256_hex(d, hex, 64);
	assert_string_equal(hex,
	                    "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
	const char *two = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
	mlip_sha256(two, strlen(two), d);
	mlip_sha256_hex(d, hex, 64);
	assert_string_equal(hex,
	                    "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
	/* streamed in uneven pieces: the same as at once (a million 'a') */
	static char a[1000000];
	memset(a, 'a', sizeof(a));
	struct mlip_sha256 s;
	mlip_sha256_init(&s);
	for (size_t i = 0; i < sizeof(a); i += 997) {
		mlip_sha256_update(&s, a + i, i + 997 > sizeof(a) ? sizeof(a) - i : 997);
	}
	mlip_sha256_final(&s, d);
	mlip_sha256_hex(d, hex, 64);
	assert_string_equal(hex,
	                    "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

/* Every value back exactly, the describe line, the file as text. */
static void test_offsets_round_trip(void **state)
{
	(void)state;
	struct mlip_machine m = machine("XYZ");
	struct mlip_gcode_offsets o, back;
	char msg[2048], buf[256];
	size_t len;

	mlip_gcode_offsets_init(&o, &m);
	assert_true(o.g28[2] == 30.0); /* G28/G30 at HOME */
	o.select = 7;
	o.coord[7][1] = -12.5;
	o.g92_on = 1;
	o.g92[0] = 0.1;
	o.g30[0] = 1.0 / 3;
	o.coord[1][2] = -0.0;
	o.tool = 7; /* the tool in the spindle (M6, M61) */
	save(&m, &o);
	assert_int_equal(load(&m, &back, msg, sizeof(msg)), 0);
	o.coord[1][2] = 0.0;                       /* written "0" */
	assert_memory_equal(&o, &back, sizeof(o)); /* exact: the shortest text that reads back */
	mlip_offsets_describe(&m, &o, buf, sizeof(buf));
	assert_string_equal(buf, "G59.2 X0 Y-12.5 Z0, G92 on X0.1 Y0 Z0, tool 7 in the spindle");
	const char *text = read_file(path, &len);
	assert_non_null(strstr(text, "\nSELECT G59.2\nG92_ON 1\nG54 X0 Y0 Z0\n"));
	assert_non_null(strstr(text, "\nG59.2 X0 Y-12.5 Z0\n"));
	assert_non_null(strstr(text, "\nG30 X0.3333333333333333 Y20 Z30\n"));
	assert_non_null(strstr(text, "\nG30 X0.3333333333333333 Y20 Z30\nTOOL 7\n"));
	assert_non_null(strstr(text, "\n# end 22 lines sha256 "));
	/* no temporary file left beside it */
	DIR *d = opendir(dir);
	struct dirent *e;
	int files = 0;
	while ((e = readdir(d)) != NULL) {
		files += e->d_name[0] != '.';
	}
	closedir(d);
	assert_int_equal(files, 1);
}

/* A file cut at any byte (a power cut before fsync), one filled with NULs
 * of the same length, and the empty file: refused, never zeros. */
static void test_cut_anywhere_is_refused(void **state)
{
	(void)state;
	struct mlip_machine m = machine("XYZ");
	struct mlip_gcode_offsets o;
	char msg[2048], full[4096];
	size_t len;

	mlip_gcode_offsets_init(&o, &m);
	o.coord[1][0] = -20.0; /* "-20": cut after "-2" must not give -2 */
	o.coord[2][2] = 5.5;
	save(&m, &o);
	const char *saved = read_file(path, &len);
	memcpy(full, saved, len);
	for (size_t cut = 0; cut < len; cut++) {
		write_file(path, full, cut);
		assert_int_equal(load(&m, &o, msg, sizeof(msg)), -1);
		assert_non_null(strstr(msg, "t: error: "));
		assert_non_null(strstr(msg, cut == 0 ? "is empty" : "cut short"));
	}
	char zeros[4096] = {0};
	write_file(path, zeros, len);
	assert_int_equal(load(&m, &o, msg, sizeof(msg)), -1);
	assert_non_null(strstr(msg, ":1: a NUL byte (offset 0): what a power cut leaves"));
	/* NULs in the middle (a block of the file never written) */
	memcpy(zeros, full, len);
	memset(zeros + 200, 0, 100);
	write_file(path, zeros, len);
	assert_int_equal(load(&m, &o, msg, sizeof(msg)), -1);
	assert_non_null(strstr(msg, "a NUL byte (offset 200)"));
	/* the whole file again: fine */
	write_file(path, full, len);
	assert_int_equal(load(&m, &o, msg, sizeof(msg)), 0);
	assert_true(o.coord[1][0] == -20.0 && o.coord[2][2] == 5.5);
}

/* A byte changed (a hand edit not accepted, a damaged disk): refused with
 * the command that accepts it; accepted, it loads. */
static void test_edit_needs_accept(void **state)
{
	(void)state;
	struct mlip_machine m = machine("XYZ");
	struct mlip_gcode_offsets o;
	char msg[2048], text[4096];
	size_t len;

	mlip_gcode_offsets_init(&o, &m);
	save(&m, &o);
	const char *saved = read_file(path, &len);
	memcpy(text, saved, len + 1);
	char *g55 = strstr(text, "\nG55 X0 ");
	assert_non_null(g55);
	g55[6] = '7'; /* G55 X7 */
	write_file(path, text, len);
	assert_int_equal(load(&m, &o, msg, sizeof(msg)), -1);
	assert_non_null(strstr(msg, "changed after mlip wrote it"));
	assert_non_null(strstr(msg, "mlip-offsets --accept "));
	/* accept: check, seal; then it loads with the edit */
	struct mlip_offsets_kind_ctx ctx;
	struct mlip_sf_kind k;
	struct mlip_sf sf;
	char why[MLIP_SF_WHY], note[256];
	mlip_offsets_kind(&ctx, "", &k); /* the axes from the file */
	assert_int_equal(mlip_sf_load(&sf, path, &k, 0, why, sizeof(why)), -1);
	assert_int_equal(mlip_sf_load(&sf, path, &k, MLIP_SF_UNSEALED, why, sizeof(why)), 0);
	assert_int_equal(mlip_sf_save(path, &k, &sf, &sf, note, sizeof(note), why, sizeof(why)), 0);
	mlip_sf_free(&sf);
	assert_int_equal(load(&m, &o, msg, sizeof(msg)), 0);
	assert_true(o.coord[1][0] == 7.0);
}

static void expect_refused(const struct mlip_machine *m, const char *body, const char *want)
{
	/* a sealed file holding body (as mlip would seal it), then loaded */
	struct mlip_offsets_kind_ctx ctx;
	struct mlip_sf_kind k;
	char text[8192], hex[17], msg[2048];
	uint8_t d[MLIP_SHA256_BYTES];
	unsigned lines = 0;
	for (const char *p = body; *p; p++) {
		lines += *p == '\n';
	}
	mlip_offsets_kind(&ctx, "", &k);
	mlip_sha256(body, strlen(body), d);
	mlip_sha256_hex(d, hex, 16);
	snprintf(text, sizeof(text), "%s# end %u lines sha256 %s\n", body, lines, hex);
	write_file(path, text, strlen(text));
	struct mlip_gcode_offsets o;
	assert_int_equal(load(m, &o, msg, sizeof(msg)), -1);
	if (strstr(msg, want) == NULL) {
		fail_msg("expected '%s' in: %s", want, msg);
	}
}

#define ALL_BUT(k)                                                                                 \
	"SELECT G54\nG92_ON 0\n" k "G56 X0 Y0 Z0\nG57 X0 Y0 Z0\nG58 X0 Y0 Z0\nG59 X0 Y0 Z0\n"      \
	"G59.1 X0 Y0 Z0\nG59.2 X0 Y0 Z0\nG59.3 X0 Y0 Z0\nG92 X0 Y0 Z0\nG28 X0 Y0 Z0\nG30 X0 Y0 "   \
	"Z0\n"

/* Every key once, each axis by letter once, numbers strict. */
static void test_records_checked(void **state)
{
	(void)state;
	struct mlip_machine m = machine("XYZ");
	expect_refused(&m, ALL_BUT("G54 X0 Y0 Z0\n"), "no G55 line");
	expect_refused(&m, ALL_BUT("G54 X0 Y0 Z0\nG55 X1 Y0 Z0\nG55 X2 Y0 Z0\n"),
	               ":5: G55 a second time (first on line 4)");
	expect_refused(&m, ALL_BUT("G54 X0 Y0 Z0\nG55 X1 Y0\n"), "G55: no value for axis Z");
	expect_refused(&m, ALL_BUT("G54 X0 Y0 Z0\nG55 X1 Y0 Z0 A0\n"),
	               "G55: 'A0' is not a value of this machine's axes (XYZ");
	expect_refused(&m, ALL_BUT("G54 X0 Y0 Z0\nG55 X1 X2 Y0 Z0\n"), "G55: axis X twice");
	const char *bad[] = {"1.2.3", "--2", "0x10", "nan", "inf", "",
	                     "1e999", "2e6", "1,5",  "1e",  "."};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		char body[1024], want[128];
		snprintf(body, sizeof(body), ALL_BUT("G54 X0 Y0 Z0\nG55 X%s Y0 Z0\n"), bad[i]);
		snprintf(want, sizeof(want), "G55: X '%s' is not a number", bad[i]);
		expect_refused(&m, body, want);
	}
	expect_refused(&m, ALL_BUT("G54 X0 Y0 Z0\nG55 X0 Y0 Z0\nG53 X0 Y0 Z0\n"),
	               "unknown key 'G53'");
	expect_refused(&m, "SELECT G60\n", "SELECT must be one of G54..G59.3");
	expect_refused(&m, "G92_ON yes\n", "G92_ON must be 0 or 1");
	/* the same body, sealed and complete, loads (the helper is honest) */
	struct mlip_offsets_kind_ctx ctx;
	struct mlip_sf_kind k;
	struct mlip_sf sf;
	char why[MLIP_SF_WHY];
	const char *good = ALL_BUT("G54 X0 Y0 Z0\nG55 X+1.5e1 Y-.5 Z7.\n");
	char text[4096], hex[17];
	uint8_t d[MLIP_SHA256_BYTES];
	mlip_sha256(good, strlen(good), d);
	mlip_sha256_hex(d, hex, 16);
	snprintf(text, sizeof(text), "%s# end 14 lines sha256 %s\n", good, hex);
	write_file(path, text, strlen(text));
	mlip_offsets_kind(&ctx, "XYZ", &k);
	assert_int_equal(mlip_sf_load(&sf, path, &k, 0, why, sizeof(why)), 0);
	assert_string_equal(mlip_sf_get(&sf, "G55"), "X15 Y-0.5 Z7");
	mlip_sf_free(&sf);
}

/* Axis letters per value: a machine with COORDINATES X Z Y reads the Z
 * offset into Z (issue 17 item 7: it went to Y). */
static void test_axis_order_is_by_letter(void **state)
{
	(void)state;
	struct mlip_machine xyz = machine("XYZ"), xzy = machine("XZY");
	struct mlip_gcode_offsets o, back;
	char msg[2048];
	mlip_gcode_offsets_init(&o, &xyz);
	o.coord[0][0] = 1, o.coord[0][1] = 2, o.coord[0][2] = -70;
	save(&xyz, &o);
	assert_int_equal(load(&xzy, &back, msg, sizeof(msg)), 0);
	assert_true(back.coord[0][0] == 1 && back.coord[0][1] == -70 && back.coord[0][2] == 2);
	/* a machine with another axis: refused, naming it */
	struct mlip_machine xyza = machine("XYZA");
	assert_int_equal(load(&xyza, &back, msg, sizeof(msg)), -1);
	assert_non_null(strstr(msg, "no value for axis A"));
}

/* The write never goes through a link: FILE a link is refused (load and
 * save); a link planted at FILE.tmp (the old temporary name) is left alone. */
static void test_never_through_a_link(void **state)
{
	(void)state;
	struct mlip_machine m = machine("XYZ");
	struct mlip_gcode_offsets o;
	char msg[2048], victim[160], tmp[160];
	size_t len;
	snprintf(victim, sizeof(victim), "%s/victim", dir);
	write_file(victim, "secret\n", 7);
	chmod(victim, 0600);
	snprintf(tmp, sizeof(tmp), "%s.tmp", path);
	assert_int_equal(symlink(victim, tmp), 0);
	mlip_gcode_offsets_init(&o, &m);
	save(&m, &o);
	assert_string_equal(read_file(victim, &len), "secret\n");
	struct stat st;
	assert_int_equal(lstat(path, &st), 0);
	assert_true(S_ISREG(st.st_mode));
	/* FILE itself a link: refused both ways, the target untouched */
	unlink(path);
	assert_int_equal(symlink(victim, path), 0);
	assert_int_equal(load(&m, &o, msg, sizeof(msg)), -1);
	assert_non_null(strstr(msg, "is a symbolic link"));
	struct mlip_offsets_file f = {path, {0}, 0};
	char *out = NULL;
	size_t n = 0;
	FILE *err = open_memstream(&out, &n);
	assert_int_equal(mlip_offsets_save(&f, &m, &o, "t", err), -1);
	fclose(err);
	assert_non_null(strstr(out, "is a symbolic link"));
	assert_non_null(strstr(out, "the offsets the program left, not written:"));
	free(out);
	assert_string_equal(read_file(victim, &len), "secret\n");
	/* a directory */
	unlink(path);
	assert_int_equal(mkdir(path, 0700), 0);
	assert_int_equal(load(&m, &o, msg, sizeof(msg)), -1);
	assert_non_null(strstr(msg, "is a directory, not a regular file"));
}

/* The mode of the file replaced stays; a new one gets 0666 less the umask;
 * as root the owner stays too. */
static void test_mode_and_owner_kept(void **state)
{
	(void)state;
	struct mlip_machine m = machine("XYZ");
	struct mlip_gcode_offsets o;
	struct stat st;
	mlip_gcode_offsets_init(&o, &m);
	mode_t old = umask(027);
	save(&m, &o);
	assert_int_equal(stat(path, &st), 0);
	assert_int_equal(st.st_mode & 0777, 0640);
	umask(0);
	assert_int_equal(chmod(path, 0600), 0);
	save(&m, &o);
	assert_int_equal(stat(path, &st), 0);
	assert_int_equal(st.st_mode & 0777, 0600); /* not 0666 under umask 0 */
	umask(old);
	if (geteuid() == 0) {
		assert_int_equal(chown(path, 65534, 65534), 0);
		save(&m, &o);
		assert_int_equal(stat(path, &st), 0);
		assert_int_equal(st.st_uid, 65534);
		assert_int_equal(st.st_gid, 65534);
		assert_int_equal(st.st_mode & 0777, 0600);
	}
}

/* A change made between load and write-back: merged per key; both sides
 * changing one key refuses the write and keeps theirs. A missing file is
 * an error. */
static void test_merge_with_a_change_meanwhile(void **state)
{
	(void)state;
	struct mlip_machine m = machine("XYZ");
	struct mlip_gcode_offsets o, run, theirs, back;
	struct mlip_offsets_file f = {0};
	char msg[2048];

	assert_int_equal(load(&m, &o, msg, sizeof(msg)), -1);
	assert_non_null(strstr(msg, "no such offsets file: check the path"));
	mlip_gcode_offsets_init(&o, &m);
	save(&m, &o);
	/* a run loads it, changes G55 (G10 L2 P2) */
	assert_int_equal(mlip_offsets_load(&f, path, &m, &run, "t", stderr), 0);
	run.coord[1][0] = 5.0;
	/* meanwhile the operator enters G56 for the next fixture */
	theirs = o;
	theirs.coord[2][2] = -30.0;
	save(&m, &theirs);
	char *out = NULL;
	size_t n = 0;
	FILE *err = open_memstream(&out, &n);
	assert_int_equal(mlip_offsets_save(&f, &m, &run, "t", err), 0);
	fclose(err);
	assert_non_null(strstr(out, "merged with a change made during the program: G56 kept"));
	free(out);
	assert_int_equal(load(&m, &back, msg, sizeof(msg)), 0);
	assert_true(back.coord[1][0] == 5.0 && back.coord[2][2] == -30.0); /* both */
	mlip_offsets_file_free(&f);
	/* both change G55: refused, the file keeps the operator's value, the
	 * program's is shown */
	assert_int_equal(mlip_offsets_load(&f, path, &m, &run, "t", stderr), 0);
	run.coord[1][0] = 6.0;
	theirs = back;
	theirs.coord[1][0] = 9.0;
	save(&m, &theirs);
	out = NULL;
	err = open_memstream(&out, &n);
	assert_int_equal(mlip_offsets_save(&f, &m, &run, "t", err), -1);
	fclose(err);
	assert_non_null(strstr(out, "G55 changed both there and by the program"));
	assert_non_null(strstr(out, "t:   G55 X6 Y0 Z0\n"));
	free(out);
	assert_int_equal(load(&m, &back, msg, sizeof(msg)), 0);
	assert_true(back.coord[1][0] == 9.0);
	mlip_offsets_file_free(&f);
	/* deleted meanwhile: written again whole, and said */
	assert_int_equal(mlip_offsets_load(&f, path, &m, &run, "t", stderr), 0);
	unlink(path);
	out = NULL;
	err = open_memstream(&out, &n);
	assert_int_equal(mlip_offsets_save(&f, &m, &run, "t", err), 0);
	fclose(err);
	assert_non_null(strstr(out, "deleted during the program: written again"));
	free(out);
	assert_int_equal(load(&m, &back, msg, sizeof(msg)), 0);
	assert_memory_equal(&back, &run, sizeof(run));
	mlip_offsets_file_free(&f);
}

/* The old format is recognised (refused with the conversion) and read in
 * the machine's axis order. */
static void test_old_format(void **state)
{
	(void)state;
	struct mlip_machine m = machine("XYZ");
	struct mlip_gcode_offsets o;
	char msg[2048], why[256];
	const char *old = "# mlip offsets\nSELECT = G55\nG92_ON = 0\nG55 = 10 20 -5\n";
	write_file(path, old, strlen(old));
	assert_int_equal(load(&m, &o, msg, sizeof(msg)), -1);
	assert_non_null(strstr(msg, "the old format"));
	assert_non_null(strstr(msg, "mlip-offsets --convert --config CONFIG"));
	assert_int_equal(mlip_offsets_is_old(path), 1);
	assert_int_equal(mlip_offsets_read_old(path, &m, &o, why, sizeof(why)), 0);
	assert_int_equal(o.select, 1);
	assert_true(o.coord[1][0] == 10 && o.coord[1][1] == 20 && o.coord[1][2] == -5);
	const char *dup = "G55 = 1 2 3\nG55 = 4 5 6\n";
	write_file(path, dup, strlen(dup));
	assert_int_equal(mlip_offsets_read_old(path, &m, &o, why, sizeof(why)), -1);
	assert_non_null(strstr(why, ":2: a second 'G55'"));
}

#define T(f) cmocka_unit_test_setup_teardown(f, setup, teardown)

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_sha256_vectors),
	    T(test_offsets_round_trip),
	    T(test_cut_anywhere_is_refused),
	    T(test_edit_needs_accept),
	    T(test_records_checked),
	    T(test_axis_order_is_by_letter),
	    T(test_never_through_a_link),
	    T(test_mode_and_owner_kept),
	    T(test_merge_with_a_change_meanwhile),
	    T(test_old_format),
	};
	return cmocka_run_group_tests_name("statefile", tests, NULL, NULL);
}
