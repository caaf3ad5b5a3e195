/*
 * cli.h - what every host tool shares: building the machine from --config
 * and the --accel/--vmax/--eps/--period overrides, and strategy names.
 */
#ifndef MLIP_CLI_H
#define MLIP_CLI_H

#include <stdio.h>

#include "mlip/config.h"
#include "mlip/planner.h"

struct mlip_cli_machine {
	const char *config;  /* INI path, or NULL: axes are those the program uses */
	const char *accel;   /* "A" or "A1,A2,..." in config order, or NULL */
	double vmax_mm_s;    /* <= 0: unset */
	double eps_mm;
	double period_s;
};

/* Build cfg from the options; program_text (may be NULL) names the axes when
 * there is no config. Prints "mlip-xxx: ..." errors to err. 0 or -1. */
int mlip_cli_build_machine(const struct mlip_cli_machine *o, const char *program_text,
                           size_t len, struct mlip_config *cfg, const char *prog, FILE *err);

/* Read the program at path and build its machine (cli_build_machine); on
 * failure print why and return -1. *text (NUL-terminated) is the caller's. */
int mlip_cli_open_program(const char *path, const struct mlip_cli_machine *o,
                          struct mlip_config *cfg, char **text, size_t *len, const char *prog,
                          FILE *err);

/* "mpct" | "bisector" | "stop" | "smooth" -> strategy; -1 when unknown. */
int mlip_cli_strategy(const char *name);
const char *mlip_cli_strategy_name(mlip_strategy st);

/* Strict number parsing for options: whole string, finite. 0 or -1. */
int mlip_cli_number(const char *s, double *out);

/* SIGINT and SIGTERM call handler; no SA_RESTART, so a signal ends a sleep
 * or a blocking call at once (the tools turn it into a controlled stop). */
void mlip_cli_on_stop_signals(void (*handler)(int));

/* The limits a trace of machine m is judged against. */
struct mlip_check_limits;
void mlip_cli_check_limits(const struct mlip_machine *m, struct mlip_check_limits *lim);

/* Polyline the planner will follow: home + every block target, with points
 * closer than MLIP_GCODE_MERGE_MM to the previous one dropped like the
 * planner does. Returns a malloc'ed array of *npts points of n coordinates. */
double *mlip_cli_polyline(const struct mlip_machine *m, const struct mlip_block *blocks,
                          size_t nblocks, size_t *npts);

#endif
