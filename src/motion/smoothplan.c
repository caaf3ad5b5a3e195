/*
 * smoothplan.c - the smooth strategy in the planner (beyond the paper): its
 * corners on the acceleration polygon's boundary, the braking shapes the
 * backward pass chooses among, and the reshaping of a corner when the line
 * before it starts (the hooks of mlip/motion/strategy.h). The path filter
 * that makes smooth's input is smooth.c; this file is what the planner does
 * with it. Its data (struct mlip_smooth_seg, one per look-ahead slot) lives
 * in storage only smooth gets, so the other strategies carry none of it.
 */
#include <math.h>

#include "mlip/motion/strategy.h"

/*
 * The smooth strategy's corner (beyond the paper): any a = alpha e_e - beta
 * e_s inside the acceleration polygon keeps every guarantee, (18)-(20) then
 * fix t. The LP vertex (Theorem 2) maximises alpha + beta, but on a finely
 * sampled curve every segment is taken whole by its two corners (19), so
 * the speed can only change inside corners, and v_e / v_s = alpha / beta != 1
 * makes it saw-tooth down a run of them. Choose instead, on the polygon's
 * boundary (w = alpha / (alpha + beta) over the LP's candidates, 1/2 and a
 * few between), the corner whose slower end is fastest: min(v_s, v_e).
 */
int mlip_corner_smooth_w(int n, const double *e_s, const double *e_e, double ds_mm, double de_mm,
                         const double *accel, double eps_mm, double vcap_s_mm_s, double vcap_e_mm_s,
                         double w, struct mlip_corner *c)
{
	double g = 0.0;
	for (int k = 0; k < n; k++) {
		g = mlip_dmax(g, fabs(w * e_e[k] - (1.0 - w) * e_s[k]) / accel[k]);
	}
	if (!(g > 0.0)) {
		return -1;
	}
	double al = w / g, be = (1.0 - w) / g;
	mlip_corner_from_t(al, be,
	                   sqrt(mlip_corner_t2(n, e_s, e_e, al, be, ds_mm, de_mm, eps_mm,
	                                       vcap_s_mm_s, vcap_e_mm_s)),
	                   c);
	return 0;
}

/* Turns beyond MLIP_SMOOTH_SHARP_COS are the filter's pinned corners:
 * there the paper's own LP-vertex corner, whose neighbours the filter left
 * exact, is kept (the boundary family was slower by a few ms on programs of
 * sharp corners only). Unit e_s, e_e: |e_e - e_s|^2 = 2 - 2 cos(turn). */
int mlip_corner_smooth_sharp(int n, const double *e_s, const double *e_e)
{
	double d2 = 0.0;
	for (int k = 0; k < n; k++) {
		d2 += (e_e[k] - e_s[k]) * (e_e[k] - e_s[k]);
	}
	return d2 > 2.0 - 2.0 * MLIP_SMOOTH_SHARP_COS;
}

#define SMOOTH_W_GRID 8
static int corner_smooth(int n, const double *e_s, const double *e_e, double ds_mm, double de_mm,
                         const double *accel, double eps_mm, double vcap_s_mm_s, double vcap_e_mm_s,
                         struct mlip_corner *c)
{
	double alpha, beta;
	if (mlip_corner_lp(n, e_s, e_e, accel, &alpha, &beta) != 0) {
		return -1;
	}
	double w_lp = alpha / (alpha + beta);
	/* the line's own acceleration limit a_{i,m} (Sec. 2.1): a corner with
	 * beta <= it has B = v_s^2 - 2 a l_s <= 0 and could not take the speed a
	 * line fails to shed after an override cut; keep such ones LP-only */
	double a_line = INFINITY;
	for (int k = 0; k < n; k++) {
		if (e_s[k] != 0.0) {
			a_line = mlip_dmin(a_line, accel[k] / fabs(e_s[k]));
		}
	}
	/* the LP vertex itself first (the paper's corner), then towards 1/2 */
	mlip_corner_from_t(alpha, beta,
	                   sqrt(mlip_corner_t2(n, e_s, e_e, alpha, beta, ds_mm, de_mm, eps_mm,
	                                       vcap_s_mm_s, vcap_e_mm_s)),
	                   c);
	double best_v = mlip_dmin(c->vs_mm_s, c->ve_mm_s);
	for (int i = 1; i <= SMOOTH_W_GRID; i++) {
		double w = w_lp + (0.5 - w_lp) * (double)i / (double)SMOOTH_W_GRID;
		struct mlip_corner cw;
		if (mlip_corner_smooth_w(n, e_s, e_e, ds_mm, de_mm, accel, eps_mm, vcap_s_mm_s,
		                         vcap_e_mm_s, w, &cw) != 0 ||
		    !(cw.beta_mm_s2 > a_line)) {
			continue;
		}
		if (mlip_dmin(cw.vs_mm_s, cw.ve_mm_s) > best_v * (1.0 + 1e-9)) {
			best_v = mlip_dmin(cw.vs_mm_s, cw.ve_mm_s);
			*c = cw;
		}
	}
	return 0;
}

/* The strategy's corner (mlip_corner_plan): the paper's corner where the
 * turn is sharp or the programme unbounded, else corner_smooth's. */
void mlip_corner_smooth(int n, const double *e_s, const double *e_e, double ds_mm, double de_mm,
                        const double *accel, double eps_mm, double vcap_s_mm_s, double vcap_e_mm_s,
                        double period_s, struct mlip_corner *c)
{
	double turn2 = 0.0;
	for (int k = 0; k < n; k++) {
		turn2 += (e_e[k] - e_s[k]) * (e_e[k] - e_s[k]);
	}
	if (turn2 < MLIP_COLLINEAR_EPS * MLIP_COLLINEAR_EPS) {
		mlip_corner_straight(vcap_s_mm_s, vcap_e_mm_s, c);
		return;
	}
	if (mlip_corner_smooth_sharp(n, e_s, e_e)) {
		mlip_corner_mpct(n, e_s, e_e, ds_mm, de_mm, accel, eps_mm, vcap_s_mm_s, vcap_e_mm_s,
		                 period_s, c);
		return;
	}
	if (corner_smooth(n, e_s, e_e, ds_mm, de_mm, accel, eps_mm, vcap_s_mm_s, vcap_e_mm_s, c) !=
	    0) {
		mlip_corner_straight(vcap_s_mm_s, vcap_e_mm_s, c);
	}
}

/* The line's own acceleration limit a_{i,m} along e (Sec. 2.1). */
static double line_accel(int n, const double *e, const double *accel)
{
	double a = INFINITY;
	for (int k = 0; k < n; k++) {
		if (e[k] != 0.0) {
			a = mlip_dmin(a, accel[k] / fabs(e[k]));
		}
	}
	return a;
}

/*
 * The smooth strategy's corner shapes (beyond the paper): out[0] is
 * mlip_corner_plan's (the one whose slower end is fastest), then braking
 * shapes on the polygon's boundary with w = alpha / (alpha + beta) below
 * its w0, so v_e / v_s = w / (1 - w) is smaller. For a turn by theta,
 * e_e,s = e +- (theta / 2) n, so a = (alpha + beta) ((2w - 1) e + (theta /
 * 2) n): w = 1/2 is the normal direction and w0 - w = theta / 4 tilts a by
 * about 45 degrees toward braking. The backward pass chooses among them
 * where braking limits the corner (planner.c). Each keeps (18)-(20) and
 * beta above the line's own limit (B > 0, see corner_smooth). Returns how
 * many (1 when the corner is straight or no braking shape qualifies).
 */
int mlip_corner_smooth_shapes(int n, const double *e_s, const double *e_e, double ds_mm,
                              double de_mm, const double *accel, double eps_mm, double vcap_s_mm_s,
                              double vcap_e_mm_s, struct mlip_corner *out, double *w_out)
{
	mlip_corner_smooth(n, e_s, e_e, ds_mm, de_mm, accel, eps_mm, vcap_s_mm_s, vcap_e_mm_s, 0.0,
	                   &out[0]);
	if (out[0].t_s == 0.0 || !(out[0].alpha_mm_s2 + out[0].beta_mm_s2 > 0.0)) {
		w_out[0] = 0.5;
		return 1;
	}
	double w0 = out[0].alpha_mm_s2 / (out[0].alpha_mm_s2 + out[0].beta_mm_s2);
	w_out[0] = w0;
	if (mlip_corner_smooth_sharp(n, e_s, e_e)) {
		return 1;
	}
	double th = 0.0;
	for (int k = 0; k < n; k++) {
		th += (e_e[k] - e_s[k]) * (e_e[k] - e_s[k]);
	}
	th = sqrt(th);
	double a_line = line_accel(n, e_s, accel);
	int m = 1;
	/* w0 - w = theta / 32 ... theta / 2, doubling (finer or more steps
	 * gain < 0.1 % on the bench's curves) */
	double dw = th / 32.0;
	for (int i = 1; i < MLIP_SMOOTH_SHAPES; i++, dw *= 2.0) {
		double w = w0 - dw;
		if (!(w >= 0.0) ||
		    mlip_corner_smooth_w(n, e_s, e_e, ds_mm, de_mm, accel, eps_mm, vcap_s_mm_s,
		                         vcap_e_mm_s, w, &out[m]) != 0 ||
		    !(out[m].beta_mm_s2 > a_line)) {
			continue;
		}
		w_out[m++] = w;
	}
	return m;
}

/* ---- the planner's hooks ------------------------------------------------ */

/* The corner at pr's end and its shapes (mlip_corner_smooth_shapes), each
 * with the numbers the backward pass weighs (the planner's look-ahead
 * coefficients of that corner); the corner is shape 0. */
void mlip_smooth_link(struct mlip_planner *p, uint32_t i, struct mlip_seg *pr,
                      const struct mlip_seg *nx)
{
	struct mlip_smooth_seg *g = mlip_smooth_at(p, i);
	g->n_shapes = 0;
	g->shape = 0;
	g->anchor = 0;
	g->commit_in = 0.0;
	g->commit_out = 0.0;
	if (pr->exact) {
		pr->c = (struct mlip_corner){0}; /* G61: as the stop strategy, at rest */
		return;
	}
	struct mlip_corner c[MLIP_SMOOTH_SHAPES];
	double w[MLIP_SMOOTH_SHAPES];
	int m = mlip_corner_smooth_shapes(p->n, pr->e, nx->e, pr->d_mm, nx->d_mm, p->accel,
	                                  pr->tol_mm, pr->vhard_mm_s, nx->vhard_mm_s, c, w);
	for (int j = 0; j < m; j++) {
		/* what the planner's link_coeffs computes, for each */
		struct mlip_shape *h = &g->shapes[j];
		h->w = w[j];
		h->inv_vs2 = c[j].vs_mm_s > 0.0 ? 1.0 / mlip_sq(c[j].vs_mm_s) : 0.0;
		h->inv_ve2 = c[j].ve_mm_s > 0.0 ? 1.0 / mlip_sq(c[j].ve_mm_s) : 0.0;
		h->b = mlip_sq(c[j].vs_mm_s) - 2.0 * pr->a_mm_s2 * c[j].ls_mm;
		h->c = mlip_sq(c[j].ve_mm_s) + 2.0 * nx->a_mm_s2 * c[j].le_mm;
		h->inv_c = h->c > 0.0 ? 1.0 / h->c : 0.0;
	}
	g->n_shapes = (uint8_t)m;
	g->shape0 = c[0];
	pr->c = c[0];
}

/*
 * The smooth strategy's shape choice (beyond the paper), inside backward
 * reachability: on a finely sampled curve corners abut and the speed can
 * only change inside them, where the constant acceleration a = alpha e_e -
 * beta e_s fixes v_e / v_s = alpha / beta. The plan's shape (shape0)
 * turns fastest at a steady speed; where braking to the next corner limits
 * it, a shape with v_e < v_s on the polygon's boundary brakes inside the
 * turn too (normal and tangential parts together, as a time-optimal
 * profile does). The measure is q B, the largest v^2 - 2 a l_s the line
 * before may arrive with (25), q as the pass computes it, the largest taken.
 *
 * The choice is a function of rhs and of the corner's own data only, never
 * of the shape an earlier pass left: so the plan is the same however the
 * blocks were batched (one pass per push_n), and the termination condition
 * stays exact (a corner that computes what it holds has successors that
 * compute what they hold). Ties go to the lowest shape. Between full passes
 * rhs only grows (new blocks relax every braking bound), each shape's q B =
 * min(qcap, rhs / C) B with it, and so their largest: a plan in effect never
 * promises less than an earlier one, and the chosen shape takes any entry
 * promised before (B >= q B) at a q no larger than its own, so it leaves
 * within this plan's exit (q C <= rhs). (Taking braking shapes only where
 * braking binds them, as before, made the largest q B drop when a shape
 * left that range: a corner then had to take more than its shape could, by
 * 3x the limit on a Lissajous at 200 mm/s^2.)
 *
 * What the machine may still carry into a corner is bounded by the plans
 * it followed, not only by this one: after an override cut or a hold (a
 * full pass) it brakes as it can, Sec. 3.2 case b, and relies on each
 * corner taking the speed the line cannot shed. The plan a full pass
 * replaces holds all that was promised since the last one: mlip_smooth_commit
 * keeps its q B and q C (commit_in, commit_out) and its shape (anchor). A shape is then chosen only
 * if it takes every entry promised (B at q = 1 >= commit_in) and leaves no faster than promised or
 * allowed now (commit_in / B C <= max(commit_out, rhs)); when none does, the anchor stays. Full
 * passes only recompute q.
 */
int mlip_smooth_choose(struct mlip_planner *p, uint32_t i, struct mlip_seg *pr,
                       const struct mlip_seg *nx, double rhs)
{
	struct mlip_smooth_seg *g = mlip_smooth_at(p, i);
	if (g->n_shapes <= 1 || g->shape == MLIP_SHAPE_FIXED) {
		return 0; /* one shape, or the executor chose it */
	}
	double ts2 = mlip_sq(mlip_line_target(p, pr)), te2 = mlip_sq(mlip_line_target(p, nx));
	int best = -1;
	double best_val = 0.0;
	for (int j = 0; j < g->n_shapes; j++) {
		const struct mlip_shape *h = &g->shapes[j];
		double q = 1.0;
		if (h->inv_vs2 > 0.0) {
			q = mlip_dmin(q, ts2 * h->inv_vs2);
		}
		if (h->inv_ve2 > 0.0) {
			q = mlip_dmin(q, te2 * h->inv_ve2);
		}
		if (h->inv_c > 0.0 && rhs < q * h->c) {
			q = mlip_dmax(rhs * h->inv_c, 0.0); /* braking binds it (25)(26) */
		}
		double val = q * h->b;
		if (!(h->b >= g->commit_in) ||
		    !(g->commit_in / h->b * h->c <= mlip_dmax(g->commit_out, rhs))) {
			continue;
		}
		if (best < 0 || val > best_val * (1.0 + 1e-12)) {
			best = j;
			best_val = val;
		}
	}
	if (best < 0) {
		best = g->anchor; /* none qualifies: what the last full pass left */
	}
	if (best == g->shape) {
		return 0;
	}
	g->shape = (uint8_t)best;
	if (best == 0) {
		pr->c = g->shape0;
	} else {
		mlip_corner_smooth_w(p->n, pr->e, nx->e, pr->d_mm, nx->d_mm, p->accel, pr->tol_mm,
		                     pr->vhard_mm_s, nx->vhard_mm_s, g->shapes[best].w, &pr->c);
	}
	mlip_planner_link_coeffs(p, pr, nx);
	return 1;
}

/* A full pass is about to replace pr's plan (its q, the plan in effect):
 * keep what that plan promised (see mlip_smooth_choose). */
void mlip_smooth_commit(struct mlip_planner *p, uint32_t i, const struct mlip_seg *pr)
{
	struct mlip_smooth_seg *g = mlip_smooth_at(p, i);
	if (g->n_shapes > 1 && g->shape != MLIP_SHAPE_FIXED) {
		g->commit_in = mlip_dmax(g->commit_in, pr->q * pr->brake_b);
		if (pr->inv_brake_c > 0.0) {
			g->commit_out = mlip_dmax(g->commit_out, pr->q / pr->inv_brake_c);
		}
		g->anchor = g->shape;
	}
}

/*
 * The smooth strategy (beyond the paper): when a line starts, choose its end
 * corner's acceleration again on the polygon's boundary, now knowing the
 * actual speed. The corner model has no tangential acceleration inside a
 * symmetric corner, and on finely sampled curves corners take nearly whole
 * segments (19), so the speed can only grow inside corners: where forward
 * reachability (34) caps the corner below its plan, a corner with v_e > v_s
 * leaves faster (elsewhere the plan stays, and costs nothing). Each candidate keeps every bound the
 * plan keeps: its q is within the override's caps, its exit can still brake to the next corner's
 * planned q (25)(26), and the line can reach or brake to its entry; the one
 * leaving fastest (then entering fastest) is taken.
 */
#define SMOOTH_EXEC_W     16
#define SMOOTH_EXEC_TILTS 9
void mlip_smooth_line_start(struct mlip_planner *p, struct mlip_seg *s, double rem, double v)
{
	struct mlip_seg *nx = mlip_seg_at(p, p->tail + 1);
	struct mlip_smooth_seg *g = mlip_smooth_at(p, p->tail);
	if (s->c.t_s == 0.0) {
		return; /* straight: nothing to shape */
	}
	double q_next = p->head - p->tail > 2 ? nx->q : 0.0;
	double lim = q_next * nx->brake_b + nx->two_a_d;
	int ok;
	double q0 = mlip_corner_q_at(&s->c, s->a_mm_s2, s->q, rem, v, &ok);
	if (q0 >= s->q || mlip_corner_smooth_sharp(p->n, s->e, nx->e)) {
		return; /* the plan is reached, or a pinned corner: keep it */
	}
	double best_ve = sqrt(q0) * s->c.ve_mm_s, best_vs = sqrt(q0) * s->c.vs_mm_s;
	struct mlip_corner best = s->c;
	double best_plan = s->q;
	int found = 0;
	/* the w grid, then tilts from the plan's shape toward acceleration as
	 * the braking shapes tilt the other way (mlip_corner_smooth_shapes) */
	double w0 = g->n_shapes > 0 ? g->shapes[0].w : 0.5, th = 0.0;
	for (int k = 0; k < p->n; k++) {
		th += mlip_sq(nx->e[k] - s->e[k]);
	}
	double dw = sqrt(th) / 64.0;
	for (int i = 1; i < SMOOTH_EXEC_W + SMOOTH_EXEC_TILTS; i++) {
		struct mlip_corner c;
		double w = (double)i / (double)SMOOTH_EXEC_W;
		if (i >= SMOOTH_EXEC_W) {
			w = w0 + dw;
			dw *= 2.0;
			if (!(w <= 1.0)) {
				continue;
			}
		}
		if (mlip_corner_smooth_w(p->n, s->e, nx->e, s->d_mm, nx->d_mm, p->accel, s->tol_mm,
		                         s->vhard_mm_s, nx->vhard_mm_s, w, &c) != 0) {
			continue;
		}
		if (!(c.beta_mm_s2 > s->a_mm_s2)) {
			continue; /* B = v_s^2 - 2 a l_s > 0: after an override cut the
			           * corner can still take the speed the line cannot shed
			           * (end_corner_q), as the LP vertex's usually can */
		}
		double plan = 1.0;
		if (c.vs_mm_s > 0.0) {
			plan =
			    mlip_dmin(plan, mlip_sq(mlip_line_target(p, s)) / mlip_sq(c.vs_mm_s));
		}
		if (c.ve_mm_s > 0.0) {
			plan =
			    mlip_dmin(plan, mlip_sq(mlip_line_target(p, nx)) / mlip_sq(c.ve_mm_s));
		}
		double cc = mlip_sq(c.ve_mm_s) + 2.0 * nx->a_mm_s2 * c.le_mm;
		if (cc > 0.0) {
			plan = mlip_dmin(plan, lim / cc);
		}
		plan = mlip_dmax(plan, 0.0);
		double q = mlip_corner_q_at(&c, s->a_mm_s2, plan, rem, v, &ok);
		if (!ok || q > plan) {
			continue;
		}
		double ve = sqrt(q) * c.ve_mm_s, vs = sqrt(q) * c.vs_mm_s;
		if (ve > best_ve * (1.0 + 1e-9) ||
		    (ve >= best_ve * (1.0 - 1e-12) && vs > best_vs * (1.0 + 1e-9))) {
			best_ve = ve;
			best_vs = vs;
			best = c;
			best_plan = plan;
			found = 1;
		}
	}
	if (found) {
		s->c = best;
		mlip_planner_link_coeffs(p, s, nx);
		s->q = best_plan;
		g->shape = MLIP_SHAPE_FIXED;
	}
}
