/*
 * simcount.h - a program's run on the controller counted, not written (the
 * periods from its start to rest: mlip-sim's trace rows), and with it the
 * choice a smooth controller's program makes between smooth's corners and
 * mpct's: the one whose run ends sooner, so smooth is never slower than mpct
 * on any program, by construction (docs/algorithm.md "Smooth never slower
 * than mpct, per program").
 *
 * mlip-sim and mlip-feed make the choice with the same code, from the same
 * records (the program from where the machine stands, at 100 % override, a
 * pause resumed at once, every output there), so they choose alike and
 * mlip-rt's setpoints stay mlip-sim's. Fixed memory (~3 MB, static,
 * touched only when counting), whatever the program's length.
 */
#ifndef MLIP_TOOLS_SIMCOUNT_H
#define MLIP_TOOLS_SIMCOUNT_H

#include <stdint.h>

#include "mlip/machine/config.h"
#include "mlip/motion/planner.h"
#include "program.h"

#define MLIP_SIM_MAX_PERIODS 200000000ULL /* 55 h of machining at 1 ms: a runaway */

enum {
	MLIP_SIMCOUNT_DONE = 0, /* ran to rest at its end: *rows */
	MLIP_SIMCOUNT_OVER = 1, /* reached budget rows first (not sooner) */
	MLIP_SIMCOUNT_NONE = -1 /* cannot be counted: a probe move (its end depends on
	                           where it trips), a fault, a refusal, no end */
};

/* Machine m from its HOME, look-ahead (0: MLIP_LOOKAHEAD), strategy st;
 * feed > 0 replaces every F and G0 (mlip-sim --feed); budget rows (0:
 * none). prog is rewound before and after. */
int mlip_simcount(const struct mlip_machine *m, uint32_t lookahead, struct mlip_program *prog,
                  mlip_strategy st, double feed, uint64_t budget, uint64_t *rows);

struct mlip_corner_choice {
	int mpct;                        /* 1: mpct's corners end it sooner: run those */
	uint64_t smooth_rows, mpct_rows; /* the counts (mpct_rows 0: not sooner) */
	const char *why;                 /* no choice made (smooth's corners), why; else NULL */
};

/* The choice for a program on a smooth controller: smooth's run counted,
 * then mpct's up to it; mpct's only when it ends strictly sooner. */
void mlip_corner_choose(const struct mlip_machine *m, uint32_t lookahead, struct mlip_program *prog,
                        double feed, struct mlip_corner_choice *ch);

#endif
