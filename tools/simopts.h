/*
 * simopts.h - mlip-sim's options (tools/simopts.c parses them; mlip-sim.c
 * runs them).
 */
#ifndef MLIP_TOOLS_SIMOPTS_H
#define MLIP_TOOLS_SIMOPTS_H

#include "cli.h"

#define PROG "mlip-sim"
enum { JERK_MEAN, JERK_PATH, JERK_PATH_MEAN, JERK_AUTO };
extern const char *const plan_name[]; /* mean, path, path-mean */

struct options {
	struct mlip_cli_machine mo;
	const char *path, *strategy_name, *trace_path, *summary_path, *probe_surface;
	int strategy;
	double feed, override, resume_after;
	long long storm_seed;
	unsigned long lookahead;
	int quiet, notes, optional_stop, save_offsets;
	int smooth_only; /* --smooth-only: no choice of corners (simcount.h) */
	int jerk_plan;   /* JERK_MEAN, JERK_PATH, JERK_PATH_MEAN, JERK_AUTO; -1: not given
	                  * (then [TRAJ] JERK_PLAN) */
};

/* 0, or the exit status (-1: --help, exit 0). */
int parse_options(int argc, char **argv, struct options *o);

#endif
