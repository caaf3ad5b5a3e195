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

/* "mpct" | "bisector" | "stop" -> strategy; -1 when unknown. */
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

/* A program's blocks in order: 1 (*b filled), 0 at the end, < 0 on error. A
 * streaming reader of the program plugs in here. */
typedef int (*mlip_cli_block_fn)(void *ctx, struct mlip_block *b);

/* The blocks of an array, as an mlip_cli_block_fn (ctx: this struct). */
struct mlip_cli_block_array {
	const struct mlip_block *blocks;
	size_t n, i;
};
int mlip_cli_block_array_next(void *ctx, struct mlip_block *b);

/* The same polyline point by point, from blocks taken one at a time (fixed
 * memory): an mlip_check_source_fn (ctx: this struct). The home point comes
 * first, with line 0. */
struct mlip_cli_points {
	const struct mlip_machine *m;
	mlip_cli_block_fn next;
	void *ctx;
	int started;
	double last[MLIP_MAX_AXES];
};
void mlip_cli_points_init(struct mlip_cli_points *it, const struct mlip_machine *m,
                          mlip_cli_block_fn next, void *ctx);
int mlip_cli_points_next(void *ctx, double *pt, uint32_t *line);

#endif
