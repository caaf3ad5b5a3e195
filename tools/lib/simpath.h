/*
 * simpath.h - mlip-sim's --jerk-plan path (issue 21): the controller runs
 * `smooth` without the jerk limit (eps less the plan's band), and its
 * setpoints, from the program's start to its end at rest, go through the
 * streaming path-speed plan (mlip/motion/pathrun.h); the plan's setpoints
 * are the trace, judged by the check with the machine's J. Fixed memory.
 */
#ifndef MLIP_TOOLS_SIMPATH_H
#define MLIP_TOOLS_SIMPATH_H

#include <stdio.h>

#include "check.h"
#include "program.h"
#include "mlip/motion/pathrun.h"
#include "mlip/motion/jerk.h"
#include "mlip/motion/planner.h"
#include "trace.h"

struct mlip_simpath {
	struct mlip_pathrun run;
	struct mlip_trace *trace; /* the output trace (the plan's setpoints) */
	struct mlip_check *chk;
	uint64_t k; /* output periods after t = 0 */
	int started, done;
	/* path-mean: the knot caps of the last MLIP_JERK_MAX_TAPS periods (the
	 * mean's output averages the planner's positions over its window) */
	double caps[MLIP_JERK_MAX_TAPS];
	unsigned ncaps;
};

/* The plan's margins on machine m (which has J): 0.98 A, 0.95 J, 0.995 of
 * the path speed cap min(vmax, feed (> 0: mlip-sim --feed), each axis's
 * max_vel), the policies 900, 300 and 600 mm/s^2 (bench/pathspeed.py --c's
 * first two);
 * the band 0.2 eps (the spline's (P6) and its fairing's moves). Each
 * block's own feed is its knots' cap (mlip_simpath_tag). -1 when an axis
 * has no jerk limit (the plan needs J on every axis), with the reason in
 * *why. */
int mlip_simpath_limits(const struct mlip_machine *m, double feed, struct mlip_path_limits *lim,
                        double *band_mm, const char **why);

/* The plan's controller's machine: m without J, eps less the band (0.2
 * eps), each axis's A at most band / T^2 (denser knots where m is fast:
 * simpath.c), on which `smooth` runs (mlip-sim, the planning thread, a
 * feeder). */
void mlip_simpath_machine(const struct mlip_machine *m, struct mlip_machine *cm);

/* path-mean's band (of eps): the spline's (P6) alone */
#define MLIP_SIMPATH_MEAN_BAND 0.1

/* The plan's fairing of its input (mlip_pathrun_fair's F1 F2), on pr
 * just initialised with the band of mlip_simpath_limits: 0, or -1. */
int mlip_simpath_fair(struct mlip_pathrun *pr);

/* The plan's controller's planner pl after its period: the next input's
 * knot cap, 0.995 of its blocks' (mlip_planner_cap: the block executing,
 * and the next in a corner; kept while none is queued). mlip-sim and the
 * planning thread tag each setpoint alike (the same plan). */
void mlip_simpath_tag(struct mlip_pathrun_tag *t, const struct mlip_planner *pl);

/* As mlip_simpath_tag, for path-mean: the lowest cap of the periods the
 * mean's window can hold (its setpoint lies on their motion). */
void mlip_simpath_tag_mean(struct mlip_simpath *sp, const struct mlip_planner *pl);

/* Before anything moves: every block of prog is one the plan can run
 * (mlip_pathrun_refusal); prog is rewound after. *feed: the plan's cap
 * beside the blocks' own, fixed when > 0 (mlip-sim --feed, which replaces
 * every feed, rapids too), else 0 (the machine's). how names what asked
 * for the plan ("--jerk-plan path", "CFG:LINE: JERK_PLAN = path"). 0, or
 * -1 with a message on err: "prog: file:line: WHAT: the path plan cannot
 * run it yet (how)". */
int mlip_simpath_prescan(struct mlip_program *p, double fixed, double *feed, const char *prog,
                         const char *file, const char *how, FILE *err);

/* Begin: trace and chk opened by the caller (the trace's start: `start`);
 * fair: the input faired (mlip_simpath_fair: path; path-mean's mean is not,
 * with the band MLIP_SIMPATH_MEAN_BAND eps). -1 on bad limits. */
int mlip_simpath_begin(struct mlip_simpath *sp, const struct mlip_path_limits *lim, double band_mm,
                       int fair, struct mlip_trace *trace, struct mlip_check *chk,
                       const double *start);

/* The controller's next setpoint (no J): periods planned as the window
 * fills, each written to the trace and the check. 0, or -1 (a message on
 * err naming the file, prog). */
int mlip_simpath_sample(struct mlip_simpath *sp, const double *pos, const char *prog,
                        const char *file, FILE *err);

/* The controller is at rest at the program's end: the plan to its end. 0,
 * or -1 (a message on err). */
int mlip_simpath_end(struct mlip_simpath *sp, const char *prog, const char *file, FILE *err);

#endif
