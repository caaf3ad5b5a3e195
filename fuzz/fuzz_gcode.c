/*
 * fuzz_gcode.c - libFuzzer target for the G-code front end (src/gcode/),
 * with the whole-program wrapper of the tools (tools/lib/program.c) as a
 * second opinion. The checks: fuzz/invariants.h (inv_gcode_program). Built
 * and run by fuzz/run.sh.
 *
 * Input: one selector byte, then the program text.
 *   bit 0     machine: 0 = config/mill-3axis.ini (XYZ), 1 = rotary-4axis.ini (XYZA)
 *   bit 1     feed moves before the first F use the program's first F, as the
 *             tools do (mlip_gcode_scan_feed + mlip_gcode_set_initial_feed);
 *             then, unless bit 2, the blocks and errors must be exactly those
 *             of mlip_program_parse
 *   bit 2     the sink refuses every n-th block, n = 2 + (byte >> 3), so that
 *             MLIP_E_FULL and the resume after it are exercised
 */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "invariants.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static struct mlip_machine machines[2];

static void violation(const char *what, const char *why)
{
	fprintf(stderr, "fuzz_gcode: invariant violated: %s\n  %s\n", what, why ? why : "");
	abort();
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
	(void)argc;
	(void)argv;
	if (inv_machine(inv_mill_ini, &machines[0]) != 0 ||
	    inv_machine(inv_rotary_ini, &machines[1]) != 0) {
		violation("the built-in machines do not parse", NULL);
	}
	return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	struct inv_gcode_result r;
	const char *w;

	if (size < 1) {
		return 0;
	}
	/* bit 7: with the machine's I/O (a manual spindle, tool change and
	 * coolant, a tool table) */
	w = inv_gcode_program(&machines[data[0] & 1], (const char *)data + 1, size - 1,
	                      data[0] | ((data[0] & 0x80) ? INV_IO : 0), &r);
	if (w) {
		violation(w, r.why);
	}
	return 0;
}
