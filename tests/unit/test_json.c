/*
 * test_json.c - the tools' one JSON writer (tools/lib/json.h): layout,
 * commas and nesting, numbers that are not finite, and strings escaped as
 * RFC 8259 says, bytes that are not UTF-8 as \udcXX (surrogateescape).
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "json.h"

static char *buf;
static size_t len;

static FILE *open_buf(void)
{
	FILE *f = open_memstream(&buf, &len);
	assert_non_null(f);
	return f;
}

static void assert_written(FILE *f, const char *want)
{
	fclose(f);
	if (strcmp(buf, want) != 0) {
		fail_msg("wrote\n%s\nexpected\n%s", buf, want);
	}
	free(buf);
	buf = NULL;
}

static void test_layout(void **state)
{
	struct mlip_json j;
	double v[3] = {1.5, -2.0, 1e-3};
	(void)state;
	FILE *f = open_buf();
	mlip_json_begin(&j, f);
	mlip_json_string(&j, "a", "x");
	mlip_json_numbers(&j, "v", "%g", v, 3);
	mlip_json_object(&j, "o", 0);
	mlip_json_uint(&j, "u", 18446744073709551615ULL);
	mlip_json_int(&j, "i", -7);
	mlip_json_bool(&j, "t", 1);
	mlip_json_null(&j, "n");
	mlip_json_array(&j, "e", 0);
	mlip_json_close(&j);
	mlip_json_object(&j, "h", 1);
	mlip_json_uint(&j, "0", 12);
	mlip_json_uint(&j, "3", 4);
	mlip_json_close(&j);
	mlip_json_close(&j);
	mlip_json_raw(&j, "r", "{\"k\": [1]}");
	assert_int_equal(mlip_json_end(&j), 0);
	assert_written(f, "{\n"
	                  "  \"a\": \"x\",\n"
	                  "  \"v\": [1.5, -2, 0.001],\n"
	                  "  \"o\": {\n"
	                  "    \"u\": 18446744073709551615,\n"
	                  "    \"i\": -7,\n"
	                  "    \"t\": true,\n"
	                  "    \"n\": null,\n"
	                  "    \"e\": [],\n"
	                  "    \"h\": {\"0\": 12, \"3\": 4}\n"
	                  "  },\n"
	                  "  \"r\": {\"k\": [1]}\n"
	                  "}\n");
}

static void test_not_finite(void **state)
{
	struct mlip_json j;
	double v[2] = {NAN, INFINITY};
	(void)state;
	FILE *f = open_buf();
	mlip_json_begin(&j, f);
	mlip_json_number(&j, "x", "%.17g", -INFINITY);
	mlip_json_numbers(&j, "v", "%g", v, 2);
	mlip_json_end(&j);
	assert_written(f, "{\n  \"x\": null,\n  \"v\": [null, null]\n}\n");
}

static void test_escapes(void **state)
{
	(void)state;
	static const struct {
		const char *in, *out;
	} cases[] = {
	    {"plain/path.ngc", "\"plain/path.ngc\""},
	    {"a \"b\" \\c", "\"a \\\"b\\\" \\\\c\""},
	    {"l1\nl2\tt\x01\x1f", "\"l1\\nl2\\tt\\u0001\\u001f\""},
	    {"caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80",
	     "\"caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80\""},
	    {"\xff", "\"\\udcff\""},                                  /* never UTF-8 */
	    {"\xc0\x80", "\"\\udcc0\\udc80\""},                       /* overlong NUL */
	    {"\xed\xa0\x80", "\"\\udced\\udca0\\udc80\""},            /* a surrogate, encoded */
	    {"x\xe2\x82", "\"x\\udce2\\udc82\""},                     /* cut short at the end */
	    {"\xf4\x90\x80\x80", "\"\\udcf4\\udc90\\udc80\\udc80\""}, /* above U+10FFFF */
	    {"\x7f", "\"\x7f\""},
	};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		FILE *f = open_buf();
		mlip_json_str(f, cases[i].in);
		assert_written(f, cases[i].out);
	}
}

static void test_too_deep(void **state)
{
	struct mlip_json j;
	(void)state;
	FILE *f = open_buf();
	mlip_json_begin(&j, f);
	for (int i = 0; i < MLIP_JSON_DEPTH + 2; i++) {
		mlip_json_array(&j, NULL, 1);
	}
	assert_int_equal(mlip_json_end(&j), -1);
	fclose(f);
	free(buf);
	buf = NULL;
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_layout),
	    cmocka_unit_test(test_not_finite),
	    cmocka_unit_test(test_escapes),
	    cmocka_unit_test(test_too_deep),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
