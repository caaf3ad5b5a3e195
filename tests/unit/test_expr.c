/*
 * test_expr.c - parameters and expressions (src/gcode/expr.c) against
 * LinuxCNC's G-code overview: its examples' values, the precedence, the
 * functions, a line's settings after its reads, the machine's parameters
 * (#5220, #5420.., the offsets), and every error at its line and column.
 */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "mlip/gcode/gcode.h"

#define assert_near(a, b, tol) near_impl((a), (b), (tol), #a, __FILE__, __LINE__)
static void near_impl(double a, double b, double tol, const char *what, const char *file, int line)
{
	if (!(fabs(a - b) <= tol)) {
		print_error("%s = %.15g, expected %.15g +- %g\n", what, a, b, tol);
		_fail(file, line);
	}
}

static struct mlip_machine mach;
static struct mlip_gcode g;
static struct mlip_block last; /* the last block the line emitted */
static int n_blocks;

static int sink(void *ctx, const struct mlip_block *b)
{
	(void)ctx;
	last = *b;
	n_blocks++;
	return 0;
}

static int setup(void **state)
{
	(void)state;
	memset(&mach, 0, sizeof mach);
	mach.n_axes = 3;
	for (int i = 0; i < 3; i++) {
		mach.axis[i].letter = "XYZ"[i];
		mach.axis[i].max_accel = 1000;
		mach.axis[i].max_vel = 200;
		mach.axis[i].min_limit = -1000;
		mach.axis[i].max_limit = 1000;
	}
	mach.max_feed_mm_s = 200;
	mach.tolerance_mm = 0.01;
	mach.period_s = 0.001;
	mlip_gcode_init(&g, &mach);
	n_blocks = 0;
	return 0;
}

static void ok(const char *s, uint32_t no)
{
	struct mlip_gcode_error e;
	mlip_status st = mlip_gcode_line(&g, s, strlen(s), no, sink, NULL, &e);
	if (st != MLIP_OK) {
		print_error("\"%s\": %u:%u %s\n", s, (unsigned)e.line, (unsigned)e.col, e.msg);
	}
	assert_int_equal(st, MLIP_OK);
}

/* The X of "G1 X<value>" (a fresh move from X = -100). */
static double x_of(const char *value)
{
	char buf[300];
	ok("G90 G1 X-100 F600", 1);
	snprintf(buf, sizeof buf, "G1 X%s", value);
	ok(buf, 2);
	return last.target[0];
}

static void err(const char *s, uint32_t col, const char *part)
{
	struct mlip_gcode_error e;
	mlip_status st = mlip_gcode_line(&g, s, strlen(s), 7, sink, NULL, &e);
	if (st == MLIP_OK || e.line != 7 || e.col != col || strstr(e.msg, part) == NULL) {
		print_error("\"%s\": got %d %u:%u \"%s\", expected 7:%u \"%s\"\n", s, (int)st,
		            (unsigned)e.line, (unsigned)e.col, e.msg, (unsigned)col, part);
		fail();
	}
}

static void test_expressions(void **state)
{
	(void)state;
	ok("#3 = 2", 1);
	/* the overview's examples */
	assert_near(x_of("[1 + acos[0] - [#3 ** [4.0/2]]]"), 87.0, 1e-12);
	assert_near(x_of("[2.0 / 3 * 1.5 - 5.5 / 11.0]"), 0.5, 1e-12);
	/* precedence: ** over * / MOD over + - over EQ.. over AND OR XOR */
	assert_near(x_of("[2 + 3 * 4 ** 2]"), 50.0, 0);
	assert_near(x_of("[10 - 4 - 3]"), 3.0, 0); /* left to right */
	assert_near(x_of("[2 ** 3 ** 2]"), 64.0, 0);
	assert_near(x_of("[1 + 1 EQ 2]"), 1.0, 0);
	assert_near(x_of("[0 OR 1 AND 0]"), 0.0, 0); /* one group, left to right */
	assert_near(x_of("[1 XOR 1]"), 0.0, 0);
	assert_near(x_of("[1 EQ 1.0000005]"), 1.0, 0); /* within 1e-6 */
	assert_near(x_of("[1 NE 1.00001]"), 1.0, 0);
	assert_near(x_of("[3 GT 2] "), 1.0, 0);
	assert_near(x_of("[3 le 2]"), 0.0, 0); /* case-insensitive */
	assert_near(x_of("[7 MOD 3]"), 1.0, 0);
	assert_near(x_of("[-7 MOD 3]"), 2.0, 1e-12); /* LinuxCNC: 0 <= r < |d| */
	/* functions: degrees; FIX down, FUP up, ROUND half away from zero */
	assert_near(x_of("[SIN[30]]"), 0.5, 1e-15);
	assert_near(x_of("[cos[60] + tan[45]]"), 1.5, 1e-15);
	assert_near(x_of("[ATAN[1]/[-1]]"), 135.0, 1e-12);
	assert_near(x_of("[asin[1]]"), 90.0, 1e-12);
	assert_near(x_of("[FIX[2.8] + FIX[-2.8]]"), -1.0, 0);
	assert_near(x_of("[FUP[2.8] + FUP[-2.8]]"), 1.0, 0);
	assert_near(x_of("[ROUND[2.5] + ROUND[-2.5] + ROUND[0.49]]"), 0.0, 0);
	assert_near(x_of("[ABS[-4] + SQRT[16] + LN[EXP[2]]]"), 10.0, 1e-12);
	assert_near(x_of("SIN[90]"), 1.0, 0); /* a word's value may be a function */
	assert_near(x_of("-[2 * 3]"), -6.0, 0);
	assert_near(x_of("-#3"), -2.0, 0);
	assert_near(x_of(" [ 1 + 2 ] "), 3.0, 0);
}

static void test_parameters(void **state)
{
	(void)state;
	/* a setting takes effect after every value on its line is read */
	ok("#3 = 15", 1);
	assert_near(x_of("#3"), 15.0, 0);
	ok("#3=6 G1 X#3", 3);
	assert_near(last.target[0], 15.0, 0);
	assert_near(x_of("#3"), 6.0, 0);
	ok("#3=15 #3=6", 4); /* the last setting wins */
	assert_near(x_of("#3"), 6.0, 0);
	/* '#' before '+': #1+2 is #1 plus 2; #[1+2] is #3; ##2 */
	ok("#1 = 10 #2 = 3", 5);
	assert_near(x_of("[#1+2]"), 12.0, 0);
	assert_near(x_of("#[1+2]"), 6.0, 0);
	assert_near(x_of("##2"), 6.0, 0);
	assert_near(x_of("#4999"), 0.0, 0); /* never set: 0, with a notice */
	/* named: lower case, blanks removed; global and local alike here */
	ok("#<_endmill_dia> = 0.049", 6);
	ok("#<_endmill_rad> = [#<_endmill_dia>/2.0]", 7);
	assert_near(x_of("#<_ENDMILL_RAD>"), 0.0245, 1e-15);
	ok("#<P a R am > = 4", 8);
	assert_near(x_of("#<param>"), 4.0, 0);
	assert_near(x_of("[EXISTS[#<param>] + EXISTS[#<nope>] * 10 + EXISTS[#<_x>] * 100]"), 101.0,
	            0);
}

static void test_machine_parameters(void **state)
{
	(void)state;
	/* G55 at X 10, Y 20: a move's target is machine coordinates, the
	 * parameters the program's */
	ok("G10 L2 P2 X10 Y20", 1);
	ok("G55 G90 G1 X1 Y2 Z3 F600", 2);
	assert_near(last.target[0], 11.0, 1e-12);
	ok("G1 X#5220 Y#<_coord_system>", 3);
	assert_near(last.target[0], 10.0 + 2.0, 0);
	assert_near(last.target[1], 20.0 + 550.0, 0);
	ok("G1 X[#5420 + 1] Y[#5421 + 1] Z[#5422 + 1]", 4); /* from X2 Y550 Z3 of G55 */
	assert_near(last.target[0], 10.0 + 3.0, 1e-12);
	assert_near(last.target[1], 20.0 + 551.0, 1e-12);
	assert_near(last.target[2], 4.0, 1e-12);
	ok("G1 X[#5241 + #5242] Y[#<_metric> * 10 + #<_absolute>] Z#5221", 5);
	assert_near(last.target[0], 10.0 + 30.0, 0); /* G55's origin */
	assert_near(last.target[1], 20.0 + 11.0, 0);
	assert_near(last.target[2], 0.0, 0); /* G54's X */
	ok("G1 X5 Y0 Z0", 6);                /* program X5: machine 15 */
	ok("G20", 7);                        /* the parameters in inches */
	ok("G1 Y[#5420 * 25.4]", 8);
	assert_near(last.target[1], 20.0 + 5.0 * 25.4, 1e-9);
	ok("G1 Y[#<_abs_x> * 25.4] Z[#<_imperial> / 25.4]", 9);
	assert_near(last.target[1], 20.0 + 15.0 * 25.4, 1e-9);
	assert_near(last.target[2], 1.0, 1e-12);
}

static void test_errors(void **state)
{
	(void)state;
	ok("G90 G1 X0 F600", 1);
	err("G1 X[1+]", 8, "a number, #parameter or [expression] expected");
	err("G1 X[1", 5, "no closing ']'");
	err("G1 X[1 BAD 2]", 8, "no closing ']' here (or an unknown operator)");
	err("G1 X#0", 6, "a parameter's number is a whole number 1..5602");
	err("G1 X#1.5", 6, "whole number");
	err("G1 X#5063", 5, "a probe's result is known only when the program runs");
	err("G1 X#5399", 5, "#5399 is not a parameter mlip keeps");
	err("#5221 = 1", 1, "read-only here");
	err("#<_x> = 1", 1, "#<_x> is read-only");
	err("G1 X#<nope>", 5, "named parameter #<nope> is not set");
	err("G1 X[SQRT[-1]]", 6, "SQRT of a negative number");
	err("G1 X[1/0]", 7, "division by zero");
	err("G1 X[1 MOD 0]", 8, "division by zero");
	err("G1 X[ACOS[2]]", 6, "the argument of ACOS is outside -1..1");
	err("G1 X[LN[0]]", 6, "LN of a number not above 0");
	err("G1 X[-2 ** 0.5]", 9, "a negative number to a non-integer power");
	err("G1 X[EXP[1000]]", 6, "not finite");
	err("G1 X[FOO[1]]", 6, "unknown function or word 'FOO'");
	err("G1 X[ATAN[1]]", 13, "ATAN is ATAN[y]/[x]");
	err("G1 X[EXISTS[#1]]", 13, "EXISTS takes one named parameter");
	err("#1", 1, "a parameter on its own is a setting");
	err("#1=", 4, "a value is missing");
	err("#<a", 2, "'>' missing");
	err("G1 X[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]", 37,
	    "nested too deep");
	err("G1 X1.2.3", 5, "malformed number '1.2.3'");
	err("G1 X--1", 5, "malformed number '--1'");
	/* a failed line sets nothing */
	err("#9 = 1 G1 X[1/0]", 14, "division by zero");
	assert_near(x_of("#9"), 0.0, 0);
	/* MDI: a parameter not set on these lines is refused, not read as 0 */
	mlip_gcode_init(&g, &mach);
	mlip_gcode_set_mdi(&g, 1);
	err("G1 X#7 F600", 5, "#7 is not set on this line: mlip keeps no parameters between MDI");
	ok("#7 = 2", 1);
	ok("G1 X#7 F600", 2);
	assert_near(last.target[0], 2.0, 0);
}

/* The axes a program uses (mlip-sim without a config): words whose value
 * is an expression count, letters of functions and operators do not. */
static void test_scan_axes(void **state)
{
	static const char text[] = "G1 X[FIX[1.5] MOD 2] Y#1 F100\n"
	                           "Z SIN[30] (A1)\n"
	                           "#<b> = [ATAN[1]/[1] + ABS[-1] + EXP[0] XOR 1]\n";
	char axes[8];
	(void)state;
	assert_int_equal(mlip_gcode_scan_axes(text, sizeof text - 1, axes), 3);
	assert_string_equal(axes, "XYZ");
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test_setup(test_expressions, setup),
	    cmocka_unit_test_setup(test_parameters, setup),
	    cmocka_unit_test_setup(test_machine_parameters, setup),
	    cmocka_unit_test_setup(test_errors, setup),
	    cmocka_unit_test(test_scan_axes),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
