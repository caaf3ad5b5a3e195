/*
 * planner.c - adaptive look-ahead (Sec. 2), feed override (Sec. 3) and
 * interpolation (Sec. 4) of Zhang, Sun, Gao, Li (2011).
 *
 * The state of corner j is one number q_j = (t_m / t_g)^2 in [0, 1], where
 * t_g is the corner's largest admissible t_m from (18)-(20): with a fixed,
 * v_s^2, v_e^2, l_s and l_e are all proportional to q. Segment i runs from
 * corner i-1 to corner i; its straight part (21) is
 *
 *     L_i = d_i - q_{i-1} l_e(i-1) - q_i l_s(i)
 *
 * and it can brake from the start speed to the end speed at its line
 * acceleration a = a_{i,m} when v0^2 <= v1^2 + 2 a L_i, i.e.
 *
 *     q_{i-1} (v_e^2 + 2a l_e)(i-1) <= q_i (v_s^2 - 2a l_s)(i) + 2 a d_i  (22)-(25)
 *
 * which is the paper's (25)/(26) written in q: linear, so no square roots in
 * the look-ahead. Backward reachability sets each q from its successor, from
 * the newest block (which plans to rest) back to the executing one, and stops
 * when a value equals the one the previous pass left (termination condition).
 * Forward reachability (34) and the cases of Sec. 3.2 are applied by the
 * executor to the segment it is on, from the actual state, every period.
 *
 * Interpolation samples one continuous C1 motion made of parabolic corners
 * (14) and trapezoidal lines (35)(36) at t = kT: any number of pieces may
 * fall in one period, and since each piece's acceleration is within the
 * per-axis limits, so is every second difference of the samples (a weighted
 * mean of the acceleration over two periods). That replaces the re-timing of
 * (37) exactly.
 */
#include <math.h>
#include <string.h>

#include "mlip/motion/planner.h"
#include "mlip/motion/smooth.h"

static double sq(double x)
{
	return x * x;
}

/* fmin/fmax are out-of-line libm calls under strict IEEE flags; every
 * value here is finite, so plain comparisons do. */
static double dmin(double a, double b)
{
	return a < b ? a : b;
}

static double dmax(double a, double b)
{
	return a > b ? a : b;
}

static struct mlip_seg *seg_at(struct mlip_planner *p, uint32_t i)
{
	return &p->seg[i & (p->cap - 1)];
}

static const struct mlip_seg *cseg_at(const struct mlip_planner *p, uint32_t i)
{
	return &p->seg[i & (p->cap - 1)];
}

/* ---- initialisation ----------------------------------------------------- */

mlip_status mlip_planner_init(struct mlip_planner *p, const struct mlip_machine *m,
                              mlip_strategy st, uint32_t cap, const double *start)
{
	if (cap == 0) {
		cap = MLIP_LOOKAHEAD;
	}
	if (m->n_axes < 2 || m->n_axes > MLIP_MAX_AXES || cap < 2 || cap > MLIP_LOOKAHEAD ||
	    (cap & (cap - 1)) != 0 || !(m->period_s > 0.0) || !(m->tolerance_mm > 0.0) ||
	    !(m->max_feed_mm_s > 0.0) || st > MLIP_STRATEGY_SMOOTH) {
		return MLIP_E_INVALID;
	}
	/* the struct is large (the ring); clear only the header part */
	memset(p, 0, offsetof(struct mlip_planner, seg));
	p->n = m->n_axes;
	p->strategy = st;
	for (int k = 0; k < p->n; k++) {
		const struct mlip_axis *ax = &m->axis[k];
		if (!(ax->max_accel > 0.0) || !(ax->max_vel > 0.0) || !isfinite(start[k])) {
			return MLIP_E_INVALID;
		}
		p->accel[k] = ax->max_accel * (1.0 - MLIP_ACCEL_MARGIN);
		p->vaxis[k] = ax->max_vel;
		p->rotary[k] = ax->kind == MLIP_AXIS_ROTARY;
		p->last_point[k] = start[k];
		p->pos[k] = start[k];
	}
	p->vmax_mm_s = m->max_feed_mm_s;
	p->vmax_rot_deg_s = m->max_rot_feed_deg_s > 0.0 ? m->max_rot_feed_deg_s : m->max_feed_mm_s;
	p->eps_mm = m->tolerance_mm;
	p->period_s = m->period_s;
	p->cap = cap;
	p->override = 1.0;
	return MLIP_OK;
}

uint32_t mlip_planner_space(const struct mlip_planner *p)
{
	return p->cap - (p->head - p->tail);
}

uint32_t mlip_planner_queued(const struct mlip_planner *p)
{
	return p->head - p->tail;
}

/* ---- look-ahead --------------------------------------------------------- */

static double effective_override(const struct mlip_planner *p)
{
	return p->hold ? 0.0 : p->override;
}

/* Speed the line of s aims at: programmed feed times override, never above
 * the hard caps. */
static double line_target(const struct mlip_planner *p, const struct mlip_seg *s)
{
	return dmin(s->vfeed_mm_s * effective_override(p), s->vhard_mm_s);
}

/* Largest q corner pr (between pr and nx) may have under the override: v_s
 * within pr's target, v_e within nx's (Sec. 3). */
static double corner_soft_cap(const struct mlip_planner *p, const struct mlip_seg *pr,
                              const struct mlip_seg *nx)
{
	double q = 1.0;
	/* a side whose speed is 0 at q = 1 (v_s or v_e of a sharp corner's
	 * optimum, Theorem 2) is 0 for every q: it bounds nothing */
	if (pr->inv_vs2 > 0.0) {
		q = dmin(q, sq(line_target(p, pr)) * pr->inv_vs2);
	}
	if (pr->inv_ve2 > 0.0) {
		q = dmin(q, sq(line_target(p, nx)) * pr->inv_ve2);
	}
	return q;
}

static void link_coeffs(struct mlip_planner *p, struct mlip_seg *pr, const struct mlip_seg *nx);

/*
 * The smooth strategy's shape choice (beyond the paper), inside backward
 * reachability: on a finely sampled curve corners abut and the speed can
 * only change inside them, where the constant acceleration a = alpha e_e -
 * beta e_s fixes v_e / v_s = alpha / beta. The plan's shape (shape0)
 * turns fastest at a steady speed; where braking to the next corner limits
 * it, a shape with v_e < v_s on the polygon's boundary brakes inside the
 * turn too (normal and tangential parts together, as a time-optimal
 * profile does). The measure is q B, the largest v^2 - 2 a l_s the line
 * before may arrive with (25), q as the pass computes it; a braking shape
 * only where its exit is at its bound (else it would leave slower than
 * allowed).
 *
 * What the machine may still carry into a corner is bounded by the plans
 * it followed, not only by this one (after an override cut or a hold it
 * brakes as it can, Sec. 3.2 case b, and relies on each corner taking the
 * speed the line cannot shed). So a corner changes shape only to a better
 * one (q B larger: sticky, so passes that change nothing keep it), that
 * takes every entry any plan promised it (B at q = 1 >= commit_in) and
 * then leaves no faster than promised or allowed now (commit_in / B C <=
 * max(commit_out, rhs)). Full passes (override, hold) only recompute q.
 */
static void choose_shape(struct mlip_planner *p, struct mlip_seg *pr, const struct mlip_seg *nx,
                         double rhs)
{
	/* the plan's shape where braking does not limit it: nothing to gain
	 * (and nothing to compute, the common case) */
	if (pr->shape == 0 && !(pr->inv_brake_c > 0.0 && rhs * pr->inv_brake_c < pr->qcap)) {
		return;
	}
	double ts2 = sq(line_target(p, pr)), te2 = sq(line_target(p, nx));
	double val[MLIP_SMOOTH_SHAPES];
	int lim[MLIP_SMOOTH_SHAPES];
	for (int j = 0; j < pr->n_shapes; j++) {
		const struct mlip_shape *h = &pr->shapes[j];
		double q = 1.0;
		if (h->inv_vs2 > 0.0) {
			q = dmin(q, ts2 * h->inv_vs2);
		}
		if (h->inv_ve2 > 0.0) {
			q = dmin(q, te2 * h->inv_ve2);
		}
		lim[j] = h->inv_c > 0.0 && rhs < q * h->c;
		if (lim[j]) {
			q = dmax(rhs * h->inv_c, 0.0);
		}
		val[j] = q * h->b;
	}
	int best = pr->shape;
	double best_val = val[best];
	for (int j = 0; j < pr->n_shapes; j++) {
		const struct mlip_shape *h = &pr->shapes[j];
		if (j == best || !(j == 0 || lim[j]) || !(val[j] > best_val * (1.0 + 1e-12)) ||
		    !(h->b >= pr->commit_in) ||
		    !(pr->commit_in / h->b * h->c <= dmax(pr->commit_out, rhs))) {
			continue;
		}
		best = j;
		best_val = val[j];
	}
	if (best != pr->shape) {
		pr->shape = (uint8_t)best;
		if (best == 0) {
			pr->c = pr->shape0;
		} else {
			mlip_corner_smooth_w(p->n, pr->e, nx->e, pr->d_mm, nx->d_mm, p->accel,
			                     pr->tol_mm, pr->vhard_mm_s, nx->vhard_mm_s,
			                     pr->shapes[best].w, &pr->c);
		}
		link_coeffs(p, pr, nx);
	}
}

/* Oldest corner the look-ahead may still change: the executing segment's end
 * corner, unless it is being executed. */
static uint32_t first_mutable(const struct mlip_planner *p)
{
	return p->tail + (p->in_corner ? 1u : 0u);
}

/*
 * Backward reachability (Sec. 2.1 step 2, eqs 25-26 in q form). full = 0:
 * stop at the termination condition (a value equal to last pass's); full = 1:
 * recompute everything (after an override change, when caps moved). The
 * condition is only meaningful for corners a previous pass computed: the
 * `fresh` newest corners (linked since the last pass, holding a placeholder
 * 0) are always visited. (A fresh corner computes to exactly 0 only under a
 * hold, which a full pass follows; the guard keeps batches exact without
 * relying on that.)
 */
static void backward_pass(struct mlip_planner *p, int full, uint32_t fresh)
{
	uint32_t first = first_mutable(p);
	if ((uint32_t)(p->head - first) < 2u) {
		return; /* no mutable corner before the newest segment's end */
	}
	uint32_t i = p->head - 1; /* newest: ends at rest, q = 0 */
	uint32_t visits = 0;
	double q_next = 0.0;
	while (i != first) {
		const struct mlip_seg *s = seg_at(p, i);
		struct mlip_seg *pr = seg_at(p, i - 1);
		if (full) {
			pr->qcap = corner_soft_cap(p, pr, s);
		}
		/* (25)(26): q_{i-1} C <= q_i B + 2 a d */
		double rhs = q_next * s->brake_b + s->two_a_d;
		uint8_t shape = pr->shape;
		if (!full && pr->n_shapes > 1 && pr->shape != MLIP_SHAPE_FIXED &&
		    i - 1 != p->tail) {
			choose_shape(p, pr, s, rhs);
		}
		double q = pr->qcap;
		if (pr->inv_brake_c > 0.0) {
			q = dmin(q, rhs * pr->inv_brake_c);
		}
		q = dmax(q, 0.0);
		visits++;
		if (!full && visits > fresh && q == pr->q && shape == pr->shape) {
			break; /* termination condition: nothing older can change */
		}
		pr->q = q;
		if (pr->n_shapes > 1) {
			pr->commit_in = dmax(pr->commit_in, q * pr->brake_b);
			if (pr->inv_brake_c > 0.0) {
				pr->commit_out = dmax(pr->commit_out, q / pr->inv_brake_c);
			}
		}
		q_next = q;
		i--;
	}
	p->stats.backward_visits += visits;
}

/* Precompute the corner between pr and nx and its look-ahead coefficients. */
static void link_coeffs(struct mlip_planner *p, struct mlip_seg *pr, const struct mlip_seg *nx)
{
	const struct mlip_corner *c = &pr->c;
	pr->inv_vs2 = c->vs_mm_s > 0.0 ? 1.0 / sq(c->vs_mm_s) : 0.0;
	pr->inv_ve2 = c->ve_mm_s > 0.0 ? 1.0 / sq(c->ve_mm_s) : 0.0;
	pr->brake_b = sq(c->vs_mm_s) - 2.0 * pr->a_mm_s2 * c->ls_mm;
	double brake_c = sq(c->ve_mm_s) + 2.0 * nx->a_mm_s2 * c->le_mm;
	/* C = 0 (the next line starts at rest whatever q is): no constraint */
	pr->inv_brake_c = brake_c > 0.0 ? 1.0 / brake_c : 0.0;
	pr->qcap = corner_soft_cap(p, pr, nx);
}

static void link_corner(struct mlip_planner *p, struct mlip_seg *pr, const struct mlip_seg *nx)
{
	pr->n_shapes = 0;
	pr->shape = 0;
	pr->commit_in = 0.0;
	pr->commit_out = 0.0;
	if (pr->exact) {
		pr->c = (struct mlip_corner){0}; /* G61: as the stop strategy, at rest */
	} else if (p->strategy == MLIP_STRATEGY_SMOOTH) {
		struct mlip_corner c[MLIP_SMOOTH_SHAPES];
		double w[MLIP_SMOOTH_SHAPES];
		int m = mlip_corner_smooth_shapes(p->n, pr->e, nx->e, pr->d_mm, nx->d_mm, p->accel,
		                                  pr->tol_mm, pr->vhard_mm_s, nx->vhard_mm_s, c, w);
		for (int j = 0; j < m; j++) {
			/* what link_coeffs computes, for each */
			struct mlip_shape *h = &pr->shapes[j];
			h->w = w[j];
			h->inv_vs2 = c[j].vs_mm_s > 0.0 ? 1.0 / sq(c[j].vs_mm_s) : 0.0;
			h->inv_ve2 = c[j].ve_mm_s > 0.0 ? 1.0 / sq(c[j].ve_mm_s) : 0.0;
			h->b = sq(c[j].vs_mm_s) - 2.0 * pr->a_mm_s2 * c[j].ls_mm;
			h->c = sq(c[j].ve_mm_s) + 2.0 * nx->a_mm_s2 * c[j].le_mm;
			h->inv_c = h->c > 0.0 ? 1.0 / h->c : 0.0;
		}
		pr->n_shapes = (uint8_t)m;
		pr->shape0 = c[0];
		pr->c = c[0];
	} else {
		mlip_corner_plan(p->n, p->strategy, pr->e, nx->e, pr->d_mm, nx->d_mm, p->accel,
		                 pr->tol_mm, pr->vhard_mm_s, nx->vhard_mm_s, p->period_s, &pr->c);
	}
	link_coeffs(p, pr, nx);
	pr->q = 0.0;
}

static mlip_status append(struct mlip_planner *p, const struct mlip_block *b)
{
	if (mlip_planner_space(p) == 0) {
		return MLIP_E_FULL;
	}
	if (p->stopping) {
		return MLIP_E_INVALID;
	}
	if (p->head == p->tail && b->seq > 0 && p->done_seq != b->seq - 1) {
		/* at rest with nothing queued: every block before this one is done
		 * (a new program has completed none; a continuation, up to it) */
		p->done_seq = b->seq - 1;
		p->done_line = 0;
	}
	struct mlip_seg *s = seg_at(p, p->head);
	double d2 = 0.0, lin2 = 0.0;
	for (int k = 0; k < p->n; k++) {
		if (!isfinite(b->target[k])) {
			return MLIP_E_RANGE;
		}
		double dk = b->target[k] - p->last_point[k];
		d2 += dk * dk;
		if (!p->rotary[k]) {
			lin2 += dk * dk;
		}
	}
	double d = sqrt(d2);
	if (d < MLIP_MERGE_MM) {
		return MLIP_OK; /* no zero-length segment reaches the corners */
	}
	if (!b->rapid && !(b->feed_mm_s > 0.0)) {
		return MLIP_E_RANGE;
	}

	double a = INFINITY, vaxis = INFINITY;
	for (int k = 0; k < p->n; k++) {
		s->end[k] = b->target[k];
		s->e[k] = (b->target[k] - p->last_point[k]) / d;
		double ek = fabs(s->e[k]);
		if (ek > 0.0) {
			a = dmin(a, p->accel[k] / ek); /* a_{i,m}, Sec. 2.1 */
			vaxis = dmin(vaxis, p->vaxis[k] / ek);
		}
	}
	/* F is the linear path speed when a linear axis moves, else the rotary
	 * speed (G94); the planner works in joint units, so scale by d / d_lin */
	double lin = sqrt(lin2);
	double joint_per_tool = lin > MLIP_MERGE_MM ? d / lin : 1.0;
	double vmax_tool = lin > MLIP_MERGE_MM ? p->vmax_mm_s : p->vmax_rot_deg_s;
	s->d_mm = d;
	s->a_mm_s2 = a;
	s->two_a_d = 2.0 * a * d;
	s->vhard_mm_s = dmin(vmax_tool * joint_per_tool, vaxis);
	s->vfeed_mm_s = b->rapid ? s->vhard_mm_s : b->feed_mm_s * joint_per_tool;
	s->tol_mm = b->tol_mm > 0.0 ? dmin(b->tol_mm, p->eps_mm) : p->eps_mm;
	s->exact = b->exact_stop != 0;
	s->line = b->line;
	s->seq = b->seq ? b->seq : p->seq + 1; /* the caller's number, if any */
	p->seq = s->seq;
	s->q = 0.0; /* the newest block always plans to rest */
	s->qcap = 0.0;
	s->inv_brake_c = 0.0;
	s->brake_b = 0.0;
	s->c = (struct mlip_corner){0};

	if (p->head != p->tail) {
		link_corner(p, seg_at(p, p->head - 1), s);
	}
	p->head++;
	memcpy(p->last_point, b->target, sizeof(double) * (size_t)p->n);
	p->stats.pushes++;
	return MLIP_OK;
}

mlip_status mlip_planner_push(struct mlip_planner *p, const struct mlip_block *b)
{
	uint32_t before = p->head;
	mlip_status st = append(p, b);
	if (st == MLIP_OK && p->head != before) {
		backward_pass(p, 0, 1);
	}
	return st;
}

/* Several blocks, one backward pass: the pass from the newest block stops
 * at the termination condition exactly as n single pushes would, so the
 * plan is the same, for a fraction of the visits (the pre-read, and each
 * period's ingest). */
size_t mlip_planner_push_n(struct mlip_planner *p, const struct mlip_block *b, size_t n,
                           mlip_status *err)
{
	size_t done = 0;
	mlip_status st = MLIP_OK;
	while (done < n && mlip_planner_space(p) > 0) {
		st = append(p, &b[done]);
		if (st != MLIP_OK) {
			break;
		}
		done++;
	}
	if (done > 0) {
		backward_pass(p, 0, (uint32_t)done); /* merged blocks only add fewer */
	}
	if (err != NULL) {
		*err = st;
	}
	return done;
}

mlip_status mlip_planner_set_override(struct mlip_planner *p, double pct)
{
	if (!(pct >= 0.0 && pct <= 200.0)) {
		return MLIP_E_RANGE;
	}
	p->override = pct / 100.0;
	p->stats.full_passes++;
	backward_pass(p, 1, 0); /* caps moved both ways (Sec. 3.1, 3.2) */
	return MLIP_OK;
}

void mlip_planner_hold(struct mlip_planner *p, int on)
{
	p->hold = on != 0;
	p->stats.full_passes++;
	backward_pass(p, 1, 0);
}

void mlip_planner_stop(struct mlip_planner *p)
{
	p->stopping = 1;
	mlip_planner_hold(p, 1);
}

/* ---- execution ---------------------------------------------------------- */

/*
 * Where the executing line must end: the planned q of its end corner,
 * clamped to what the actual state allows (s along the line, speed v):
 *   the corner cannot start behind us      q l_s <= rem
 *   forward reachability (34)              q v_s^2 <= v^2 + 2a (rem - q l_s)
 *   the line can brake (Sec. 3.2 case b)   v^2 <= q v_s^2 + 2a (rem - q l_s)
 * with rem = distance from here to the corner point. When an override cut
 * leaves the line unable to brake to the plan, the corner keeps the speed it
 * can reach and the following segments brake instead: acceleration limits
 * are never exceeded to respond faster.
 */
static inline double corner_q_at(const struct mlip_corner *c, double a, double q_plan, double rem,
                                 double v, int *brakeable)
{
	double vs2 = sq(c->vs_mm_s), ls = c->ls_mm;
	double geom = ls > 0.0 ? dmin(1.0, rem / ls) : 1.0;
	double lo = 0.0, hi = geom;

	double grow = vs2 + 2.0 * a * ls;
	if (grow > 0.0) {
		hi = dmin(hi, (v * v + 2.0 * a * rem) / grow);
	}
	/* k = 0 (beta equal to the line's a) is common and makes the brake
	 * condition independent of q: do not let rounding turn it into a bound */
	double k = vs2 - 2.0 * a * ls, need = v * v - 2.0 * a * rem;
	if (k > 1e-12 * grow) {
		lo = need / k;
	} else if (k < -1e-12 * grow) {
		hi = dmin(hi, need / k); /* bigger corners brake worse here */
	}
	double q = dmin(dmax(q_plan, lo), hi);
	*brakeable = !(lo > hi);
	if (lo > hi) {
		q = dmin(lo, geom); /* only by rounding: keep the state brakeable */
	}
	return dmax(q, 0.0);
}

static double end_corner_q(const struct mlip_seg *s, double rem, double v)
{
	int ok;
	return corner_q_at(&s->c, s->a_mm_s2, s->q, rem, v, &ok);
}

static void link_coeffs(struct mlip_planner *p, struct mlip_seg *pr, const struct mlip_seg *nx);

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
static void smooth_reshape(struct mlip_planner *p, struct mlip_seg *s, double rem, double v)
{
	struct mlip_seg *nx = seg_at(p, p->tail + 1);
	if (s->c.t_s == 0.0) {
		return; /* straight: nothing to shape */
	}
	double q_next = p->head - p->tail > 2 ? nx->q : 0.0;
	double lim = q_next * nx->brake_b + nx->two_a_d;
	int ok;
	double q0 = corner_q_at(&s->c, s->a_mm_s2, s->q, rem, v, &ok);
	if (q0 >= s->q || mlip_corner_smooth_sharp(p->n, s->e, nx->e)) {
		return; /* the plan is reached, or a pinned corner: keep it */
	}
	double best_ve = sqrt(q0) * s->c.ve_mm_s, best_vs = sqrt(q0) * s->c.vs_mm_s;
	struct mlip_corner best = s->c;
	double best_plan = s->q;
	int found = 0;
	/* the w grid, then tilts from the plan's shape toward acceleration as
	 * the braking shapes tilt the other way (mlip_corner_smooth_shapes) */
	double w0 = s->n_shapes > 0 ? s->shapes[0].w : 0.5, th = 0.0;
	for (int k = 0; k < p->n; k++) {
		th += sq(nx->e[k] - s->e[k]);
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
			plan = dmin(plan, sq(line_target(p, s)) / sq(c.vs_mm_s));
		}
		if (c.ve_mm_s > 0.0) {
			plan = dmin(plan, sq(line_target(p, nx)) / sq(c.ve_mm_s));
		}
		double cc = sq(c.ve_mm_s) + 2.0 * nx->a_mm_s2 * c.le_mm;
		if (cc > 0.0) {
			plan = dmin(plan, lim / cc);
		}
		plan = dmax(plan, 0.0);
		double q = corner_q_at(&c, s->a_mm_s2, plan, rem, v, &ok);
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
		link_coeffs(p, s, nx);
		s->q = best_plan;
		s->shape = MLIP_SHAPE_FIXED;
	}
}

/* A line profile from (speed v) over distance rem to speed v1: change to vc,
 * cruise, change to v1, each change at +-a (35)(36), generalised to any
 * start speed so that it can be re-planned from the actual state.
 *
 *   v ^      ____vc____
 *     |     /          \
 *     | v0 /            \ v1
 *     +---------------------> t
 */
static void profile_make(struct mlip_profile *f, double v, double rem, double v1, double a,
                         double vtarget)
{
	/* Plans make braking exactly tight, so rounding can leave v -> v1 short
	 * of room by ~1e-11: take the exact rate then (far inside the margin
	 * kept below the limits) rather than overshoot the corner and jump. */
	double need = fabs(v * v - v1 * v1);
	if (rem > 0.0 && need > 2.0 * a * rem && need <= 2.0 * a * rem * (1.0 + 1e-9)) {
		a = need / (2.0 * rem);
	}
	double vc;
	if (vtarget >= dmax(v, v1)) {
		double vtri2 = 0.5 * (2.0 * a * rem + v * v + v1 * v1); /* (36) */
		/* never below max(v, v1): only rounding could put vtri there */
		vc = dmin(vtarget, dmax(sqrt(dmax(vtri2, 0.0)), dmax(v, v1))); /* (35) */
	} else {
		/* above the target (override cut): come down as far as rem allows */
		double vlo2 = 0.5 * (v * v + v1 * v1 - 2.0 * a * rem);
		vc = dmax(vtarget, sqrt(dmax(vlo2, 0.0)));
	}
	f->v0 = v;
	f->vc = vc;
	f->v1 = v1;
	f->a1 = vc >= v ? a : -a;
	f->a3 = v1 >= vc ? a : -a;
	f->t1 = fabs(vc - v) / a;
	f->t3 = fabs(v1 - vc) / a;
	f->d1 = fabs(vc * vc - v * v) / (2.0 * a);
	double d3 = fabs(vc * vc - v1 * v1) / (2.0 * a);
	f->d2 = dmax(rem - f->d1 - d3, 0.0);
	if (vc > 0.0) {
		f->t2 = f->d2 / vc;
	} else {
		f->t2 = f->d2 > 0.0 ? INFINITY : 0.0; /* feed hold: stopped on the line */
	}
}

/* Advance a profile by t < total: distance covered and speed reached. */
static void profile_eval(const struct mlip_profile *f, double t, double *dist, double *v)
{
	if (t <= f->t1) {
		*dist = f->v0 * t + 0.5 * f->a1 * t * t;
		*v = f->v0 + f->a1 * t;
	} else if (t <= f->t1 + f->t2) {
		*dist = f->d1 + f->vc * (t - f->t1);
		*v = f->vc;
	} else {
		double u = t - f->t1 - f->t2;
		*dist = f->d1 + f->d2 + f->vc * u + 0.5 * f->a3 * u * u;
		*v = f->vc + f->a3 * u;
	}
}

/* Segment tail is finished: account for it and free its slot. */
static void retire(struct mlip_planner *p)
{
	struct mlip_seg *s = seg_at(p, p->tail);
	p->done_seq = s->seq;
	p->done_line = s->line;
	p->tail++;
}

static void line_position(const struct mlip_planner *p, const struct mlip_seg *s, double *out)
{
	/* anchored at the segment's end point so that arriving there is exact */
	double back = s->d_mm - p->l_start_mm - p->s_mm;
	for (int k = 0; k < p->n; k++) {
		out[k] = s->end[k] - s->e[k] * back;
	}
}

static void corner_position(const struct mlip_planner *p, const struct mlip_seg *s,
                            const struct mlip_seg *nx, double *out)
{
	/* (14) rewritten: P - beta (t_m - t)^2 / 2 e_s + alpha t^2 / 2 e_e, which
	 * is exact at both ends and free of cancellation */
	double tm = sqrt(p->q_exec) * s->c.t_s, t = p->tc_s;
	double ws = 0.5 * s->c.beta_mm_s2 * sq(tm - t);
	double we = 0.5 * s->c.alpha_mm_s2 * t * t;
	for (int k = 0; k < p->n; k++) {
		out[k] = s->end[k] - ws * s->e[k] + we * nx->e[k];
	}
}

mlip_run_state mlip_planner_step(struct mlip_planner *p, double *pos_out)
{
	double tau = p->period_s;
	p->stats.periods++;

	while (tau > 0.0 && p->head != p->tail) {
		struct mlip_seg *s = seg_at(p, p->tail);
		int has_next = p->head - p->tail > 1;

		if (p->in_corner) {
			double tm = sqrt(p->q_exec) * s->c.t_s;
			double left = tm - p->tc_s;
			if (left > tau) {
				p->tc_s += tau;
				tau = 0.0;
				break;
			}
			tau -= dmax(left, 0.0);
			/* onto the next line at E with speed v_e */
			p->l_start_mm = p->q_exec * s->c.le_mm;
			p->v_mm_s = sqrt(p->q_exec) * s->c.ve_mm_s;
			p->s_mm = 0.0;
			p->in_corner = 0;
			retire(p);
			continue;
		}

		double rem = s->d_mm - p->l_start_mm - p->s_mm; /* to the corner point */
		if (p->strategy == MLIP_STRATEGY_SMOOTH && has_next && !p->prof_valid) {
			smooth_reshape(p, s, rem, p->v_mm_s);
		}
		double q = has_next ? end_corner_q(s, rem, p->v_mm_s) : 0.0;
		double vt = line_target(p, s);
		struct mlip_profile *f = &p->prof;
		if (!p->prof_valid || q != p->prof_q || vt != p->prof_vt) {
			/* re-plan from the actual state only when an input changed;
			 * otherwise keep evaluating one profile in closed form, so
			 * no rounding accumulates along a long line */
			double left = dmax(rem - q * s->c.ls_mm, 0.0);
			profile_make(f, p->v_mm_s, left, sqrt(q) * s->c.vs_mm_s, s->a_mm_s2, vt);
			p->prof_valid = 1;
			p->prof_q = q;
			p->prof_vt = vt;
			p->prof_t = 0.0;
			p->prof_s0 = p->s_mm;
			p->prof_len = left;
		}
		double total = f->t1 + f->t2 + f->t3;
		if (total - p->prof_t > tau) {
			double dist, v;
			p->prof_t += tau;
			profile_eval(f, p->prof_t, &dist, &v);
			p->s_mm = p->prof_s0 + dist;
			p->v_mm_s = v;
			tau = 0.0;
			break;
		}
		tau -= total - p->prof_t;
		p->s_mm = p->prof_s0 + p->prof_len;
		p->v_mm_s = f->v1;
		p->prof_valid = 0;
		if (!has_next) {
			/* at rest on the newest point: nothing was queued behind it */
			retire(p);
			p->l_start_mm = 0.0;
			p->s_mm = 0.0;
			p->v_mm_s = 0.0;
			continue;
		}
		p->in_corner = 1;
		p->q_exec = q;
		p->tc_s = 0.0;
	}

	/* controlled stop: once at rest on the path, drop what is queued */
	if (p->stopping && p->v_mm_s == 0.0 && !p->in_corner) {
		if (p->head != p->tail) {
			line_position(p, seg_at(p, p->tail), p->pos);
			p->head = p->tail;
			memcpy(p->last_point, p->pos, sizeof(double) * (size_t)p->n);
			p->l_start_mm = 0.0;
			p->s_mm = 0.0;
		}
		p->stopping = 0;
		p->hold = 0;
	}

	if (p->head == p->tail) {
		memcpy(p->pos, p->last_point, sizeof(double) * (size_t)p->n);
	} else if (p->in_corner) {
		corner_position(p, seg_at(p, p->tail), seg_at(p, p->tail + 1), p->pos);
	} else {
		line_position(p, seg_at(p, p->tail), p->pos);
	}
	memcpy(pos_out, p->pos, sizeof(double) * (size_t)p->n);

	if (p->head == p->tail) {
		return MLIP_RUN_IDLE;
	}
	if (effective_override(p) == 0.0 && p->v_mm_s == 0.0 && !p->in_corner) {
		return MLIP_RUN_HELD;
	}
	return MLIP_RUN_MOVING;
}

double mlip_planner_speed(const struct mlip_planner *p)
{
	if (p->head == p->tail) {
		return 0.0;
	}
	if (!p->in_corner) {
		return p->v_mm_s;
	}
	/* |v_s e_s + a t| in the corner */
	const struct mlip_seg *s = cseg_at(p, p->tail);
	const struct mlip_seg *nx = cseg_at(p, p->tail + 1);
	double u = sqrt(p->q_exec), t = p->tc_s, v2 = 0.0;
	for (int k = 0; k < p->n; k++) {
		double vk = u * s->c.vs_mm_s * s->e[k] +
		            (s->c.alpha_mm_s2 * nx->e[k] - s->c.beta_mm_s2 * s->e[k]) * t;
		v2 += vk * vk;
	}
	return sqrt(v2);
}

/* 1 / |linear part of e|: joint length per tool length (G94 feed, append) */
static double joint_per_tool(const struct mlip_planner *p, const double *e)
{
	double lin2 = 0.0;
	for (int k = 0; k < p->n; k++) {
		lin2 += p->rotary[k] ? 0.0 : e[k] * e[k];
	}
	return lin2 > 0.0 ? 1.0 / sqrt(lin2) : 1.0;
}

/* Distance from x to the line through P with unit direction e. */
static double line_dist(int n, const double *x, const double *P, const double *e)
{
	double along = 0.0, d2 = 0.0;
	for (int k = 0; k < n; k++) {
		along += (x[k] - P[k]) * e[k];
	}
	for (int k = 0; k < n; k++) {
		d2 += sq(x[k] - P[k] - along * e[k]);
	}
	return sqrt(d2);
}

mlip_status mlip_planner_rest_at(struct mlip_planner *p, const double *pos)
{
	if (p->head != p->tail || p->stopping || p->in_corner) {
		return MLIP_E_INVALID;
	}
	for (int k = 0; k < p->n; k++) {
		if (!isfinite(pos[k])) {
			return MLIP_E_INVALID;
		}
	}
	memcpy(p->last_point, pos, sizeof(double) * (size_t)p->n);
	memcpy(p->pos, pos, sizeof(double) * (size_t)p->n);
	p->v_mm_s = 0.0;
	return MLIP_OK;
}

mlip_status mlip_planner_abort(struct mlip_planner *p, const double *pos)
{
	for (int k = 0; k < p->n; k++) {
		if (!isfinite(pos[k])) {
			return MLIP_E_INVALID;
		}
	}
	p->head = p->tail;
	p->in_corner = 0;
	p->stopping = 0;
	p->hold = 0;
	p->prof_valid = 0;
	p->l_start_mm = 0.0;
	p->s_mm = 0.0;
	p->v_mm_s = 0.0;
	p->tc_s = 0.0;
	memcpy(p->last_point, pos, sizeof(double) * (size_t)p->n);
	memcpy(p->pos, pos, sizeof(double) * (size_t)p->n);
	return MLIP_OK;
}

void mlip_planner_rest_here(struct mlip_planner *p)
{
	if (p->in_corner) {
		/* in a corner: on to whichever of its two segments is nearer (the
		 * distance to one segment is convex along a straight line); to the
		 * corner point first, at rest there, when that is the one before */
		struct mlip_seg *s = seg_at(p, p->tail);
		const struct mlip_seg *nx = seg_at(p, p->tail + 1);
		if (line_dist(p->n, p->pos, s->end, nx->e) <=
		    line_dist(p->n, p->pos, s->end, s->e)) {
			retire(p);
		} else {
			s->exact = 1;
		}
		p->in_corner = 0;
	}
	while (p->head != p->tail) {
		struct mlip_seg *s = seg_at(p, p->tail);
		double d2 = 0.0, e[MLIP_MAX_AXES];
		for (int k = 0; k < p->n; k++) {
			e[k] = s->end[k] - p->pos[k];
			d2 += e[k] * e[k];
		}
		double d = sqrt(d2);
		if (d < MLIP_MERGE_MM) {
			retire(p); /* at its end already */
			continue;
		}
		double a = INFINITY, vaxis = INFINITY, jpt0 = joint_per_tool(p, s->e);
		for (int k = 0; k < p->n; k++) {
			e[k] /= d;
			if (e[k] != 0.0) {
				a = dmin(a, p->accel[k] / fabs(e[k]));
				vaxis = dmin(vaxis, p->vaxis[k] / fabs(e[k]));
			}
		}
		double jpt = joint_per_tool(p, e);
		int rapid = s->vfeed_mm_s == s->vhard_mm_s;
		memcpy(s->e, e, sizeof(e));
		s->d_mm = d;
		s->a_mm_s2 = a;
		s->two_a_d = 2.0 * a * d;
		s->vhard_mm_s = dmin(s->vhard_mm_s / jpt0 * jpt, vaxis);
		s->vfeed_mm_s = rapid ? s->vhard_mm_s : s->vfeed_mm_s / jpt0 * jpt;
		if (p->head - p->tail > 1) {
			link_corner(p, s, seg_at(p, p->tail + 1));
		}
		break;
	}
	p->l_start_mm = 0.0;
	p->s_mm = 0.0;
	p->v_mm_s = 0.0;
	p->prof_valid = 0;
	if (p->head == p->tail) {
		memcpy(p->last_point, p->pos, sizeof(double) * (size_t)p->n);
	}
	mlip_planner_hold(p, 1); /* full backward pass from the new geometry */
}

int mlip_planner_moving(const struct mlip_planner *p)
{
	return p->head != p->tail && (p->v_mm_s > 0.0 || p->in_corner);
}

void mlip_planner_executing(const struct mlip_planner *p, uint64_t *seq, uint32_t *line)
{
	const struct mlip_seg *s = cseg_at(p, p->tail);
	*seq = p->head != p->tail ? s->seq : 0;
	*line = p->head != p->tail ? s->line : 0;
}

void mlip_planner_done(const struct mlip_planner *p, uint64_t *seq, uint32_t *line)
{
	*seq = p->done_seq;
	*line = p->done_line;
}

double mlip_planner_override_pct(const struct mlip_planner *p)
{
	return p->override * 100.0;
}

const struct mlip_planner_stats *mlip_planner_get_stats(const struct mlip_planner *p)
{
	return &p->stats;
}
