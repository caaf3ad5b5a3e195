/*
 * planner.c - adaptive look-ahead (Sec. 2) and feed override (Sec. 3) of
 * Zhang, Sun, Gao, Li (2011), and the planner's commands (push, override,
 * hold, stop, rest, abort); the interpolation (Sec. 4) is interp.c.
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
 */
#include <math.h>
#include <string.h>

#include "interp.h"
#include "mlip/motion/strategy.h"

/* ---- initialisation ----------------------------------------------------- */

mlip_status mlip_planner_init(struct mlip_planner *p, const struct mlip_machine *m,
                              mlip_strategy st, uint32_t cap, const double *start,
                              struct mlip_smooth_store *store)
{
	if (cap == 0) {
		cap = MLIP_LOOKAHEAD;
	}
	if (m->n_axes < 2 || m->n_axes > MLIP_MAX_AXES || cap < 2 || cap > MLIP_LOOKAHEAD ||
	    (cap & (cap - 1)) != 0 || !(m->period_s > 0.0) || !(m->tolerance_mm > 0.0) ||
	    !(m->max_feed_mm_s > 0.0) || (unsigned)st >= MLIP_STRATEGY_COUNT ||
	    (mlip_strategies[st].needs_store && store == NULL)) {
		return MLIP_E_INVALID;
	}
	/* the struct is large (the ring); clear only the header part */
	memset(p, 0, offsetof(struct mlip_planner, seg));
	p->n = m->n_axes;
	p->strategy = st;
	p->ops = &mlip_strategies[st];
	p->sm = p->ops->needs_store ? store->seg : NULL;
	p->sm_store = store != NULL ? store->seg : NULL;
	struct mlip_jerk_plan jp;
	mlip_jerk_plan(m, &jp);
	p->taps = jp.taps;
	p->filter_mm = jp.filter_mm;
	for (int k = 0; k < p->n; k++) {
		const struct mlip_axis *ax = &m->axis[k];
		if (!(ax->max_accel > 0.0) || !(ax->max_vel > 0.0) || !isfinite(start[k])) {
			return MLIP_E_INVALID;
		}
		p->accel[k] = jp.accel[k] * (1.0 - MLIP_ACCEL_MARGIN); /* A' (J4), A without */
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
	mlip_filter_reset(p);
	return MLIP_OK;
}

mlip_status mlip_planner_set_strategy(struct mlip_planner *p, mlip_strategy st)
{
	if ((unsigned)st >= MLIP_STRATEGY_COUNT ||
	    (mlip_strategies[st].needs_store && p->sm_store == NULL) ||
	    mlip_planner_queued(p) != 0 || mlip_planner_busy(p)) {
		return MLIP_E_INVALID;
	}
	/* the strategies differ only in their entry and smooth's data, which
	 * an empty ring does not hold */
	p->strategy = st;
	p->ops = &mlip_strategies[st];
	p->sm = p->ops->needs_store ? p->sm_store : NULL;
	return MLIP_OK;
}

/* Free slots of the segment ring. */
static uint32_t ring_space(const struct mlip_planner *p)
{
	/* with a jerk limit, the segments the mean's centre is still on stay */
	uint32_t keep = p->taps > 1 ? mlip_centre_mark(p)->tail : p->tail;
	return p->cap - (p->head - keep);
}

uint32_t mlip_planner_space(const struct mlip_planner *p)
{
	uint32_t ring = ring_space(p), inputs = p->in_head - p->in_tail;
	if (!p->async) {
		return ring;
	}
	ring = ring > inputs ? ring - inputs : 0u;
	return ring < MLIP_INPUT_CAP - inputs ? ring : MLIP_INPUT_CAP - inputs;
}

uint32_t mlip_planner_queued(const struct mlip_planner *p)
{
	uint32_t inputs = p->in_head - p->in_tail;
	return p->head - p->tail + inputs +
	       (p->head == p->tail && inputs == 0 && !mlip_settled(p) ? 1u : 0u);
}

void mlip_planner_set_async(struct mlip_planner *p, int on)
{
	p->async = on != 0;
}

int mlip_planner_busy(const struct mlip_planner *p)
{
	return p->pass.on || p->pending > 0 || p->in_head != p->in_tail;
}

/* ---- look-ahead --------------------------------------------------------- */

/* Largest q corner pr (between pr and nx) may have under the override: v_s
 * within pr's target, v_e within nx's (Sec. 3). */
static double corner_soft_cap(const struct mlip_planner *p, const struct mlip_seg *pr,
                              const struct mlip_seg *nx)
{
	double q = 1.0;
	/* a side whose speed is 0 at q = 1 (v_s or v_e of a sharp corner's
	 * optimum, Theorem 2) is 0 for every q: it bounds nothing */
	if (pr->inv_vs2 > 0.0) {
		q = mlip_dmin(q, mlip_sq(mlip_line_target(p, pr)) * pr->inv_vs2);
	}
	if (pr->inv_ve2 > 0.0) {
		q = mlip_dmin(q, mlip_sq(mlip_line_target(p, nx)) * pr->inv_ve2);
	}
	return q;
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
 *
 * A pass may run in pieces (mlip_planner_work: a bounded amount of work a
 * period): it keeps where it is (p->pass). Meanwhile the executor follows
 * the values the pass has not reached yet, which the last complete pass
 * left: a plan that brakes to rest where it was planned to, safe, only
 * slower than the new one. A pass given up for another (an override change
 * while a pass runs) leaves the corners below the point it reached stale:
 * the next pass may not stop above that point (pass.reach).
 */
static void pass_start(struct mlip_planner *p, int full, uint32_t fresh)
{
	struct mlip_pass *ps = &p->pass;
	if (ps->on) {
		/* given up: what it left below i - 1 is stale */
		if (!ps->has_reach || (int32_t)(ps->i - ps->reach) < 0) {
			ps->reach = ps->i;
		}
		ps->has_reach = 1;
		full |= ps->full;
		fresh += ps->fresh; /* every corner linked since a pass completed */
	}
	fresh += p->pending; /* appended while the last one ran: this one plans them */
	p->pending = 0;
	ps->on = 1;
	ps->full = full;
	ps->fresh = fresh;
	ps->i = p->head - 1; /* newest: ends at rest, q = 0 */
	ps->visits = 0;
	ps->q_next = 0.0;
}

/* Run the pass until it ends or `budget` work units are spent (1 a corner,
 * more with a strategy's choice); returns the units left. */
static uint32_t pass_run(struct mlip_planner *p, uint32_t budget)
{
	struct mlip_pass *ps = &p->pass;
	uint32_t unit = p->ops->choose != NULL ? MLIP_WORK_CHOOSE : 1u;
	uint32_t first = first_mutable(p);
	uint32_t i = ps->i, visits = 0;
	double q_next = ps->q_next;
	int full = ps->full, done = 0;
	if ((uint32_t)(p->head - first) < 2u || (int32_t)(i - first) <= 0) {
		done = 1; /* no mutable corner before (the executor passed it) */
	}
	while (!done && budget >= unit) {
		const struct mlip_seg *s = seg_at(p, i);
		struct mlip_seg *pr = seg_at(p, i - 1);
		budget -= unit;
		if (full) {
			if (p->ops->commit != NULL) {
				p->ops->commit(p, i - 1,
				               pr); /* the plan in effect, before it goes */
			}
			pr->qcap = corner_soft_cap(p, pr, s);
		}
		/* (25)(26): q_{i-1} C <= q_i B + 2 a d */
		double rhs = q_next * s->brake_b + s->two_a_d;
		int changed = 0; /* the strategy changed the corner */
		if (!full && p->ops->choose != NULL && i - 1 != p->tail) {
			changed = p->ops->choose(p, i - 1, pr, s, rhs);
		}
		double q = pr->qcap;
		if (pr->inv_brake_c > 0.0) {
			q = mlip_dmin(q, rhs * pr->inv_brake_c);
		}
		q = mlip_dmax(q, 0.0);
		visits++;
		if (!full && ps->visits + visits > ps->fresh && q == pr->q && !changed &&
		    (!ps->has_reach || (int32_t)(i - 1 - ps->reach) < 0)) {
			done = 1; /* termination condition: nothing older can change */
			break;
		}
		pr->q = q;
		q_next = q;
		i--;
		done = i == first;
	}
	p->stats.backward_visits += visits;
	ps->i = i;
	ps->q_next = q_next;
	ps->visits += visits;
	if (done) {
		ps->on = 0;
		ps->has_reach = 0; /* every corner consistent again */
	}
	return budget;
}

static void backward_pass(struct mlip_planner *p, int full, uint32_t fresh)
{
	pass_start(p, full, fresh);
	if (!p->async) {
		pass_run(p, UINT32_MAX);
	}
}

/* Precompute the look-ahead coefficients of the corner between pr and nx. */
void mlip_planner_link_coeffs(struct mlip_planner *p, struct mlip_seg *pr,
                              const struct mlip_seg *nx)
{
	const struct mlip_corner *c = &pr->c;
	pr->inv_vs2 = c->vs_mm_s > 0.0 ? 1.0 / mlip_sq(c->vs_mm_s) : 0.0;
	pr->inv_ve2 = c->ve_mm_s > 0.0 ? 1.0 / mlip_sq(c->ve_mm_s) : 0.0;
	pr->brake_b = mlip_sq(c->vs_mm_s) - 2.0 * pr->a_mm_s2 * c->ls_mm;
	double brake_c = mlip_sq(c->ve_mm_s) + 2.0 * nx->a_mm_s2 * c->le_mm;
	/* C = 0 (the next line starts at rest whatever q is): no constraint */
	pr->inv_brake_c = brake_c > 0.0 ? 1.0 / brake_c : 0.0;
	pr->qcap = corner_soft_cap(p, pr, nx);
}

/* The corner at slot i's end (pr) towards nx: the strategy's, or at rest
 * for an exact stop; then its look-ahead coefficients, planned to rest. */
static void link_corner(struct mlip_planner *p, uint32_t i, struct mlip_seg *pr,
                        const struct mlip_seg *nx)
{
	if (p->ops->link != NULL) {
		p->ops->link(p, i, pr, nx);
	} else if (pr->exact) {
		pr->c = (struct mlip_corner){0}; /* G61: as the stop strategy, at rest */
	} else {
		p->ops->corner(p->n, pr->e, nx->e, pr->d_mm, nx->d_mm, p->accel, pr->tol_mm,
		               pr->vhard_mm_s, nx->vhard_mm_s, p->period_s, &pr->c);
	}
	mlip_planner_link_coeffs(p, pr, nx);
	pr->q = 0.0;
}

static mlip_status append(struct mlip_planner *p, const struct mlip_block *b)
{
	if (ring_space(p) == 0) {
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
			a = mlip_dmin(a, p->accel[k] / ek); /* a_{i,m}, Sec. 2.1 */
			vaxis = mlip_dmin(vaxis, p->vaxis[k] / ek);
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
	s->vhard_mm_s = mlip_dmin(vmax_tool * joint_per_tool, vaxis);
	s->vfeed_mm_s = b->rapid ? s->vhard_mm_s : b->feed_mm_s * joint_per_tool;
	s->tol_mm = b->tol_mm > 0.0 ? mlip_dmin(b->tol_mm, p->eps_mm) : p->eps_mm;
	s->exact = b->exact_stop != 0;
	if (p->taps > 1) {
		/* the mean takes E_f of the budget (J5); none left: at rest, exactly */
		s->tol_mm -= p->filter_mm;
		if (!(s->tol_mm > 0.0)) {
			s->tol_mm = 0.0;
			s->exact = 1;
		}
	}
	s->line = b->line;
	s->seq = b->seq ? b->seq : p->seq + 1; /* the caller's number, if any */
	p->seq = s->seq;
	s->q = 0.0; /* the newest block always plans to rest */
	s->qcap = 0.0;
	s->inv_brake_c = 0.0;
	s->brake_b = 0.0;
	s->c = (struct mlip_corner){0};

	if (p->head != p->tail) {
		link_corner(p, p->head - 1, seg_at(p, p->head - 1), s);
	}
	p->head++;
	memcpy(p->last_point, b->target, sizeof(double) * (size_t)p->n);
	p->stats.pushes++;
	return MLIP_OK;
}

mlip_status mlip_planner_push(struct mlip_planner *p, const struct mlip_block *b)
{
	if (p->async) {
		mlip_status err = MLIP_OK;
		size_t got = mlip_planner_push_n(p, b, 1, &err);
		return got == 1 ? MLIP_OK : err != MLIP_OK ? err : MLIP_E_FULL;
	}
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
/* The checks append makes at once, for a block queued (async). */
static mlip_status check_block(const struct mlip_planner *p, const struct mlip_block *b)
{
	if (p->stopping) {
		return MLIP_E_INVALID;
	}
	for (int k = 0; k < p->n; k++) {
		if (!isfinite(b->target[k])) {
			return MLIP_E_RANGE;
		}
	}
	return !b->rapid && !(b->feed_mm_s > 0.0) ? MLIP_E_RANGE : MLIP_OK;
}

size_t mlip_planner_push_n(struct mlip_planner *p, const struct mlip_block *b, size_t n,
                           mlip_status *err)
{
	size_t done = 0;
	mlip_status st = MLIP_OK;
	if (p->async) {
		/* queued: mlip_planner_work appends them, a bounded amount a period */
		while (done < n && mlip_planner_space(p) > 0) {
			st = check_block(p, &b[done]);
			if (st != MLIP_OK) {
				break;
			}
			p->in[p->in_head & (MLIP_INPUT_CAP - 1u)] = b[done];
			p->in_head++;
			done++;
		}
		if (err != NULL) {
			*err = st;
		}
		return done;
	}
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
	p->in_tail = p->in_head; /* what was not appended yet goes too */
	mlip_planner_hold(p, 1);
}

/*
 * The look-ahead's work of one period (async): the pass in progress, then
 * the queued blocks (appended and their corners planned, a batch at a
 * time, each batch followed by its pass), until MLIP_WORK_PER_PERIOD units
 * are spent. The plan a batch makes does not depend on how the blocks were
 * batched, so work done in pieces ends in the plan push_n makes at once.
 */
void mlip_planner_work(struct mlip_planner *p)
{
	uint32_t budget = MLIP_WORK_PER_PERIOD;
	uint32_t cost = p->ops->link != NULL ? MLIP_WORK_APPEND_SHAPES : MLIP_WORK_APPEND;
	/* what the executor used up is replaced first, beyond the budget if need
	 * be (at most the ingest's rate a period), so that the plan does not
	 * fall behind */
	uint32_t owed = p->retired - p->retired_seen;
	if (owed > p->cap) {
		p->retired_seen = p->retired - p->cap;
		owed = p->cap;
	}
	uint32_t keep_up = owed < MLIP_INGEST_PER_PERIOD ? owed : MLIP_INGEST_PER_PERIOD;
	while (keep_up > 0 && p->in_head != p->in_tail && ring_space(p) > 0) {
		append(p, &p->in[p->in_tail & (MLIP_INPUT_CAP - 1u)]); /* checked at push */
		p->in_tail++;
		p->pending++;
		p->retired_seen++;
		keep_up--;
		/* ... and counted: the passes then take longer, in larger batches,
		 * but never less than a quarter of the units */
		budget = budget >= MLIP_WORK_PER_PERIOD / 4u + cost ? budget - cost
		                                                    : MLIP_WORK_PER_PERIOD / 4u;
	}
	/* then the budget's appends, half of it when a pass waits too (the
	 * passes cost the braking distance's depth whatever the batch: the
	 * pre-read appends while they run, not only between them) */
	uint32_t share = p->pass.on || p->pending > 0 ? budget / 2u : budget;
	while (p->in_head != p->in_tail && share >= cost && ring_space(p) > 0) {
		append(p, &p->in[p->in_tail & (MLIP_INPUT_CAP - 1u)]); /* checked at push */
		p->in_tail++;
		p->pending++; /* merged blocks only add fewer */
		share -= cost;
		budget -= cost;
	}
	for (;;) {
		if (p->pass.on) {
			budget = pass_run(p, budget);
			if (p->pass.on) {
				return; /* the rest next period */
			}
		}
		if (p->pending > 0) {
			pass_start(p, 0, 0); /* for what was appended meanwhile */
			continue;
		}
		while (p->in_head != p->in_tail && budget >= cost && ring_space(p) > 0) {
			append(p, &p->in[p->in_tail & (MLIP_INPUT_CAP - 1u)]); /* checked at push */
			p->in_tail++;
			p->pending++; /* merged blocks only add fewer */
			budget -= cost;
		}
		if (p->pending == 0) {
			return;
		}
	}
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
		d2 += mlip_sq(x[k] - P[k] - along * e[k]);
	}
	return sqrt(d2);
}

mlip_status mlip_planner_rest_at(struct mlip_planner *p, const double *pos)
{
	if (p->head != p->tail || p->stopping || p->in_corner || !mlip_settled(p) ||
	    mlip_planner_busy(p)) {
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
	mlip_filter_reset(p);
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
	p->in_tail = p->in_head; /* the blocks queued for the bounded work too */
	p->pending = 0;
	p->pass.on = 0;
	p->pass.has_reach = 0;
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
	mlip_filter_reset(p); /* a jerk limit's mean rests at pos too, its window with it */
	return MLIP_OK;
}

/* At rest at `at` (the last setpoint the drives got), on from there. */
static void rest_from(struct mlip_planner *p, const double *at)
{
	double here[MLIP_MAX_AXES];
	memcpy(here, at, sizeof(double) * (size_t)p->n);
	if (p->taps > 1) {
		/* the last setpoint is the mean: within E_f of where the plan was
		 * at the window's centre (J5, m odd), so the path goes on from
		 * there, and a straight line from the setpoint to the end of that
		 * segment stays within the corner's budget plus E_f (convexity) */
		const struct mlip_exec_mark *mk = mlip_centre_mark(p);
		p->tail = mk->tail;
		p->in_corner = mk->in_corner;
		p->done_seq = mk->done_seq;
		p->done_line = mk->done_line;
		p->dwell = 0;
	}
	if (p->head == p->tail && !p->stopping &&
	    memcmp(here, p->last_point, sizeof(double) * (size_t)p->n) != 0) {
		/* the plan had reached its last point, the setpoint not yet (the
		 * mean, or one period back): the rest of the last block, a
		 * straight line from the setpoint */
		struct mlip_block b = {.rapid = 1, .seq = p->seq, .line = p->done_line};
		memcpy(b.target, p->last_point, sizeof(double) * (size_t)p->n);
		memcpy(p->last_point, here, sizeof(double) * (size_t)p->n);
		append(p, &b);
	}
	memcpy(p->pos, here, sizeof(double) * (size_t)p->n);
	if (p->in_corner) {
		/* in a corner: on to whichever of its two segments is nearer (the
		 * distance to one segment is convex along a straight line); to the
		 * corner point first, at rest there, when that is the one before */
		struct mlip_seg *s = seg_at(p, p->tail);
		const struct mlip_seg *nx = seg_at(p, p->tail + 1);
		if (line_dist(p->n, p->pos, s->end, nx->e) <=
		    line_dist(p->n, p->pos, s->end, s->e)) {
			mlip_retire(p);
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
			mlip_retire(p); /* at its end already */
			continue;
		}
		double a = INFINITY, vaxis = INFINITY, jpt0 = joint_per_tool(p, s->e);
		for (int k = 0; k < p->n; k++) {
			e[k] /= d;
			if (e[k] != 0.0) {
				a = mlip_dmin(a, p->accel[k] / fabs(e[k]));
				vaxis = mlip_dmin(vaxis, p->vaxis[k] / fabs(e[k]));
			}
		}
		double jpt = joint_per_tool(p, e);
		int rapid = s->vfeed_mm_s == s->vhard_mm_s;
		memcpy(s->e, e, sizeof(e));
		s->d_mm = d;
		s->a_mm_s2 = a;
		s->two_a_d = 2.0 * a * d;
		s->vhard_mm_s = mlip_dmin(s->vhard_mm_s / jpt0 * jpt, vaxis);
		s->vfeed_mm_s = rapid ? s->vhard_mm_s : s->vfeed_mm_s / jpt0 * jpt;
		if (p->head - p->tail > 1) {
			link_corner(p, p->tail, s, seg_at(p, p->tail + 1));
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
	mlip_filter_reset(p);    /* at rest on the last setpoint */
	mlip_planner_hold(p, 1); /* full backward pass from the new geometry */
}

void mlip_planner_rest_here(struct mlip_planner *p)
{
	rest_from(p, p->taps > 1 ? p->out : p->pos);
}

void mlip_planner_rest_back(struct mlip_planner *p, const double *at)
{
	rest_from(p, at);
}

int mlip_planner_moving(const struct mlip_planner *p)
{
	return (p->head != p->tail && (p->v_mm_s > 0.0 || p->in_corner)) || !mlip_settled(p);
}

int mlip_planner_held(const struct mlip_planner *p)
{
	return p->hold && !p->stopping;
}

void mlip_planner_executing(const struct mlip_planner *p, uint64_t *seq, uint32_t *line)
{
	const struct mlip_seg *s = cseg_at(p, p->tail);
	*seq = p->head != p->tail ? s->seq : 0;
	*line = p->head != p->tail ? s->line : 0;
}

double mlip_planner_cap(const struct mlip_planner *p)
{
	if (p->head == p->tail) {
		return 0.0;
	}
	const struct mlip_seg *s = cseg_at(p, p->tail);
	double v = mlip_dmin(s->vhard_mm_s, s->vfeed_mm_s);
	if (p->in_corner && p->tail + 1u != p->head) {
		s = cseg_at(p, p->tail + 1u);
		v = mlip_dmin(v, mlip_dmin(s->vhard_mm_s, s->vfeed_mm_s));
	}
	return v;
}

uint64_t mlip_planner_motion_seq(const struct mlip_planner *p)
{
	if (p->head == p->tail) {
		return 0;
	}
	if (p->in_corner && p->tail + 1u != p->head) {
		return cseg_at(p, p->tail + 1u)->seq;
	}
	return cseg_at(p, p->tail)->seq;
}

void mlip_planner_done(const struct mlip_planner *p, uint64_t *seq, uint32_t *line)
{
	*seq = p->done_seq;
	*line = p->done_line;
}

void mlip_planner_resume_done(const struct mlip_planner *p, uint64_t *seq, uint32_t *line)
{
	*seq = p->done_seq;
	*line = p->done_line;
	if (p->taps > 1 || !p->in_corner || p->head - p->tail < 2) {
		return;
	}
	/* in a corner: done with its block once nearer to the next segment,
	 * as mlip_planner_rest_here decides for a rest there */
	const struct mlip_seg *s = cseg_at(p, p->tail), *nx = cseg_at(p, p->tail + 1);
	if (line_dist(p->n, p->pos, s->end, nx->e) <= line_dist(p->n, p->pos, s->end, s->e)) {
		*seq = s->seq;
		*line = s->line;
	}
}

double mlip_planner_override_pct(const struct mlip_planner *p)
{
	return p->override * 100.0;
}

const struct mlip_planner_stats *mlip_planner_get_stats(const struct mlip_planner *p)
{
	return &p->stats;
}
