/* simpath.c - see simpath.h */
#include "simpath.h"

#include <math.h>

#include "mlip/ctl/state.h"

/* The plan's band (of eps): what the spline and its fairing may add to the
 * controller's contour, which runs at eps less it. 0.2: at 0.1 the fairing
 * and (P6) shared 1 um and the plan refused MB-2.3, the pocket and
 * SheepTile ((P6) at a sharp corner). */
#define BAND_SHARE  0.2
/* The fairing (pathrun.h, F1 F2): +-3 mm at most, 8 input periods either
 * side, each knot moved at most 0.6 of the band (the rest is (P6)'s).
 * Measured on the first 4,000 lines of the shared CAM files (docs/benchmarks.md):
 * 8 periods beat 6, 10, 12, 15 and 0.6 beat 0.4 */
#define FAIR_H_MM   3.0
#define FAIR_K      8
#define FAIR_SHARE  0.6
/* The plan's share of each speed cap (the machine's, each block's) */
#define CAP_SHARE   0.995
/* The plan's share of each axis's A and J. The setpoints keep the plan's
 * limits to 1e-6 of them (its checks hold at every instant of a period,
 * pathplan.h), so this is a margin for rounding, not for the method: 0.98
 * A and 0.95 J (the design study's) cost the flower spiral 0.95 % at 1e5 */
#define LIMIT_SHARE 0.995
/* The braking policies (pathplan.h, Q3): path decelerations, shares of
 * the largest axis's A ((P1) holds each to what the axes moving allow),
 * the hardest first: a state keeps the first whose run certifies it (a
 * hold brakes by it). Each certifies states the others do not (0.6: MB-2.3
 * at 1e5 397.38 -> 395.05 s; 0.1, on tight curves, where 3 x'' v a takes
 * the jerk budget: docs/benchmarks.md) */
#define BRAKES      4
static const double brake_share[BRAKES] = {0.9, 0.6, 0.3, 0.1};

int mlip_simpath_fair(struct mlip_pathrun *pr)
{
	return mlip_pathrun_fair(pr, FAIR_H_MM, FAIR_K, FAIR_SHARE * pr->band_mm);
}

int mlip_simpath_limits(const struct mlip_machine *m, double feed, struct mlip_path_limits *lim,
                        double *band_mm, const char **why)
{
	*lim = (struct mlip_path_limits){0};
	lim->n = m->n_axes;
	double cap = m->max_feed_mm_s;
	if (feed > 0.0 && feed < cap) {
		cap = feed;
	}
	double amax = 0.0;
	for (int k = 0; k < m->n_axes; k++) {
		const struct mlip_axis *ax = &m->axis[k];
		if (!(ax->max_jerk > 0.0)) {
			*why = "every axis needs a jerk limit (MAX_JERK, --jerk)";
			return -1;
		}
		lim->accel[k] = LIMIT_SHARE * ax->max_accel;
		lim->jerk[k] = LIMIT_SHARE * ax->max_jerk;
		amax = ax->max_accel > amax ? ax->max_accel : amax;
		if (ax->max_vel > 0.0 && ax->max_vel < cap) {
			cap = ax->max_vel; /* |x'| <= 1 by chord length: each axis within */
		}
	}
	lim->vmax = CAP_SHARE * cap;
	for (int i = 0; i < BRAKES; i++) {
		lim->a_brake[i] = brake_share[i] * amax;
	}
	lim->n_brake = BRAKES;
	lim->period = m->period_s;
	*band_mm = BAND_SHARE * m->tolerance_mm;
	return 0;
}

void mlip_simpath_machine(const struct mlip_machine *m, struct mlip_machine *cm)
{
	*cm = *m;
	double band = BAND_SHARE * m->tolerance_mm; /* mlip_simpath_limits' band */
	/* smooth's setpoints are the spline's knots: at acceleration a (a
	 * curve's v^2 / r) a period's chord sags a T^2 / 8 from the arc, and
	 * the spline through them strays by more where the curvature steps.
	 * Above band / T^2 (2000 mm/s^2 at eps 0.01, T 1 ms) it strayed past
	 * the band (P6) and the plan refused every curve it was given (the
	 * spiral at A 3000: 2.02 um, the band 2 um). The plan re-times the
	 * curve at the machine's A: the input only gives the shape, and
	 * smooth at a lower A gives it in denser knots. */
	double cap = band / (m->period_s * m->period_s);
	for (int k = 0; k < m->n_axes; k++) {
		cm->axis[k].max_jerk = 0.0;
		if (cm->axis[k].max_accel > cap) {
			cm->axis[k].max_accel = cap;
		}
	}
	cm->tolerance_mm -= band;
}

void mlip_simpath_tag(struct mlip_pathrun_tag *t, const struct mlip_planner *pl)
{
	double c = mlip_planner_cap(pl);
	if (c > 0.0) {
		t->cap = CAP_SHARE * c; /* as the machine's in mlip_simpath_limits */
	}
}

void mlip_simpath_tag_mean(struct mlip_simpath *sp, const struct mlip_planner *pl)
{
	struct mlip_pathrun_tag t = {0};
	mlip_simpath_tag(&t, pl);
	sp->caps[sp->ncaps++ % MLIP_JERK_MAX_TAPS] = t.cap;
	double c = 0.0;
	for (unsigned i = 0; i < MLIP_JERK_MAX_TAPS && i < sp->ncaps; i++) {
		double x = sp->caps[i];
		c = x > 0.0 && (c == 0.0 || x < c) ? x : c;
	}
	if (c > 0.0) {
		sp->run.tag_in.cap = c;
	}
}

int mlip_simpath_prescan(struct mlip_program *p, double fixed, double *feed, const char *prog,
                         const char *file, const char *how, FILE *err)
{
	struct mlip_block b;
	int r;
	*feed = fixed > 0.0 ? fixed : 0.0;
	mlip_program_rewind(p);
	while ((r = mlip_program_next(p, &b)) > 0) {
		const char *why = mlip_pathrun_refusal(&b);
		if (why != NULL) {
			fprintf(err, "%s: %s:%u: %s: the path plan cannot run it yet (%s)\n", prog,
			        file, (unsigned)b.line, why, how);
			mlip_program_rewind(p);
			return -1;
		}
	}
	mlip_program_rewind(p);
	if (r < 0) {
		fprintf(err, "%s: %s: %s\n", prog, file, p->msg);
		return -1;
	}
	return 0;
}

/* The plan's braking runs: up to 3,000 periods each (3 s: a stop from
 * 200 mm/s at 300 mm/s^2 and its jerk ramps take ~0.8 s). */
#define SIM_RUN_PERIODS 3000

int mlip_simpath_begin(struct mlip_simpath *sp, const struct mlip_path_limits *lim, double band_mm,
                       int fair, struct mlip_trace *trace, struct mlip_check *chk,
                       const double *start)
{
	sp->trace = trace;
	sp->chk = chk;
	sp->k = 0;
	sp->started = 1;
	sp->done = 0;
	sp->ncaps = 0;
	if (mlip_pathrun_init(&sp->run, lim, band_mm, SIM_RUN_PERIODS, start) != 0) {
		return -1;
	}
	return fair ? mlip_simpath_fair(&sp->run) : 0;
}

static void emit(struct mlip_simpath *sp, const double *x, int last)
{
	const double *start;
	if (mlip_trace_sample_at(sp->trace, ++sp->k, last ? MLIP_STATE_IDLE : MLIP_STATE_RUNNING, x,
	                         &start)) {
		if (start != NULL) {
			mlip_check_sample(sp->chk, start);
		}
		mlip_check_sample(sp->chk, x);
	}
	sp->done = last;
}

static int refused(const struct mlip_simpath *sp, const char *prog, const char *file, FILE *err)
{
	const struct mlip_pathrun *r = &sp->run;
	fprintf(err, "%s: %s: --jerk-plan path: %s at %.6f mm of the path", prog, file,
	        r->why ? r->why : "refused", r->why_s);
	if (r->why_mm > 0.0) {
		fprintf(err, " (%.6f mm, the band %.6f mm)", r->why_mm, r->band_mm);
	} else if (r->why_v > 0.0 || r->why_a != 0.0) {
		fprintf(err, " (speed %.6g, acceleration %.6g)", r->why_v, r->why_a);
	}
	fputc('\n', err);
	return -1;
}

/* Plan periods while the plan has what it needs: 0, or -1. */
static int drain(struct mlip_simpath *sp, const char *prog, const char *file, FILE *err)
{
	double x[MLIP_MAX_AXES];
	for (;;) {
		int r = mlip_pathrun_step(&sp->run, x);
		if (r < 0) {
			return refused(sp, prog, file, err);
		}
		if (r == 0) {
			return 0;
		}
		emit(sp, x, r == 2);
		if (r == 2) {
			return 0;
		}
	}
}

int mlip_simpath_sample(struct mlip_simpath *sp, const double *pos, const char *prog,
                        const char *file, FILE *err)
{
	int r;
	double x[MLIP_MAX_AXES];
	while ((r = mlip_pathrun_push(&sp->run, pos)) == 1) {
		/* the window is full: one period makes room */
		int q = mlip_pathrun_step(&sp->run, x);
		if (q < 0) {
			return refused(sp, prog, file, err);
		}
		if (q == 0 || q == 2) {
			sp->run.why = "the plan ended with its window full";
			return refused(sp, prog, file, err);
		}
		emit(sp, x, 0);
	}
	return r < 0 ? refused(sp, prog, file, err) : 0;
}

int mlip_simpath_end(struct mlip_simpath *sp, const char *prog, const char *file, FILE *err)
{
	if (mlip_pathrun_finish(&sp->run) != 0) {
		return refused(sp, prog, file, err);
	}
	if (drain(sp, prog, file, err) != 0) {
		return -1;
	}
	if (!sp->done) {
		sp->run.why = "the plan did not come to rest at the end";
		return refused(sp, prog, file, err);
	}
	return 0;
}
