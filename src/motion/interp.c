/*
 * interp.c - interpolation (Sec. 4) of Zhang, Sun, Gao, Li (2011): the
 * executor that follows the look-ahead's plan (planner.c) one period at a
 * time, and the jerk limit's mean of its samples (mlip/motion/jerk.h).
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

#include "interp.h"
#include "mlip/motion/strategy.h"

/* ---- the jerk limit's mean (mlip/motion/jerk.h) ---------------------------- */

#define FIR_MASK (MLIP_JERK_MAX_TAPS - 1u)
typedef char mlip_fir_pow2[(MLIP_JERK_MAX_TAPS & FIR_MASK) == 0 ? 1 : -1];

const struct mlip_exec_mark *mlip_centre_mark(const struct mlip_planner *p)
{
	return &p->mark[(p->fir_n - 1u - (uint32_t)(p->taps - 1) / 2u) & FIR_MASK];
}

int mlip_settled(const struct mlip_planner *p)
{
	return p->still + 1u >= (uint32_t)p->taps;
}

void mlip_filter_reset(struct mlip_planner *p)
{
	struct mlip_exec_mark mk = {p->tail, p->in_corner, p->done_seq, p->done_line};
	for (uint32_t i = 0; i < MLIP_JERK_MAX_TAPS; i++) {
		memcpy(p->fir[i], p->pos, sizeof(p->fir[i]));
		p->mark[i] = mk;
	}
	memcpy(p->out, p->pos, sizeof(p->out));
	p->fir_n = MLIP_JERK_MAX_TAPS;
	p->still = (uint32_t)p->taps;
	p->dwell = 0;
}

/* Take this period's plan position: the setpoint is the mean of the last
 * taps ones (J1), summed as offsets from the newest so that a window at
 * rest gives exactly its point. */
static void filter_step(struct mlip_planner *p, double *pos_out)
{
	const double *last = p->fir[(p->fir_n - 1u) & FIR_MASK];
	int moved = memcmp(last, p->pos, sizeof(double) * (size_t)p->n) != 0;
	p->still = moved ? 0u : p->still + 1u;
	uint32_t i0 = p->fir_n & FIR_MASK;
	memcpy(p->fir[i0], p->pos, sizeof(p->fir[i0]));
	p->mark[i0] = (struct mlip_exec_mark){p->tail, p->in_corner, p->done_seq, p->done_line};
	p->fir_n++;
	for (int k = 0; k < p->n; k++) {
		double sum = 0.0;
		for (uint32_t j = 1; j < (uint32_t)p->taps; j++) {
			sum += p->fir[(p->fir_n - 1u - j) & FIR_MASK][k] - p->pos[k];
		}
		p->out[k] = p->pos[k] + sum / (double)p->taps;
	}
	memcpy(pos_out, p->out, sizeof(double) * (size_t)p->n);
}

/* ---- execution ---------------------------------------------------------- */

/*
 * The executing line's end corner. Held (a hold, a stop, override 0), every
 * corner with a speed is planned to rest: the full backward pass the hold
 * started sets q = 0 (its soft cap, Sec. 3) on each, but with bounded work
 * a period (mlip_planner_set_async) it starts from the newest block and
 * reaches this corner only periods later, which the executor would spend
 * still following the plan being replaced (on 0.02 mm blocks at 200 mm/s,
 * 4 periods and 1 mm past v^2 / 2a). Taking the pass's value here at once
 * brakes from the next period: q then is the least the state allows (the
 * line brakes at a to the corner, (34) and Sec. 3.2 case b), never below
 * what the old plan could brake to, so the corners after it stay reachable
 * and brakeable with the values they hold.
 */
static double end_corner_q(const struct mlip_planner *p, const struct mlip_seg *s, double rem,
                           double v)
{
	int ok;
	double q_plan = s->q;
	if (effective_override(p) == 0.0 && (s->inv_vs2 > 0.0 || s->inv_ve2 > 0.0)) {
		q_plan = 0.0;
	}
	return mlip_corner_q_at(&s->c, s->a_mm_s2, q_plan, rem, v, &ok);
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
	if (vtarget >= mlip_dmax(v, v1)) {
		double vtri2 = 0.5 * (2.0 * a * rem + v * v + v1 * v1); /* (36) */
		/* never below max(v, v1): only rounding could put vtri there */
		vc = mlip_dmin(vtarget,
		               mlip_dmax(sqrt(mlip_dmax(vtri2, 0.0)), mlip_dmax(v, v1))); /* (35) */
	} else {
		/* above the target (override cut): come down as far as rem allows */
		double vlo2 = 0.5 * (v * v + v1 * v1 - 2.0 * a * rem);
		vc = mlip_dmax(vtarget, sqrt(mlip_dmax(vlo2, 0.0)));
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
	f->d2 = mlip_dmax(rem - f->d1 - d3, 0.0);
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

void mlip_retire(struct mlip_planner *p)
{
	struct mlip_seg *s = seg_at(p, p->tail);
	p->done_seq = s->seq;
	p->done_line = s->line;
	p->tail++;
	p->retired++;
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
	double ws = 0.5 * s->c.beta_mm_s2 * mlip_sq(tm - t);
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
			if (p->dwell > 0) {
				p->dwell--; /* at rest on an exact corner, for the mean (jerk.h) */
				tau = 0.0;
				break;
			}
			double tm = sqrt(p->q_exec) * s->c.t_s;
			double left = tm - p->tc_s;
			if (left > tau) {
				p->tc_s += tau;
				tau = 0.0;
				break;
			}
			tau -= mlip_dmax(left, 0.0);
			/* onto the next line at E with speed v_e */
			p->l_start_mm = p->q_exec * s->c.le_mm;
			p->v_mm_s = sqrt(p->q_exec) * s->c.ve_mm_s;
			p->s_mm = 0.0;
			p->in_corner = 0;
			mlip_retire(p);
			continue;
		}

		double rem = s->d_mm - p->l_start_mm - p->s_mm; /* to the corner point */
		if (p->ops->line_start != NULL && has_next && !p->prof_valid) {
			p->ops->line_start(p, s, rem, p->v_mm_s);
		}
		double q = has_next ? end_corner_q(p, s, rem, p->v_mm_s) : 0.0;
		double vt = mlip_line_target(p, s);
		struct mlip_profile *f = &p->prof;
		if (!p->prof_valid || q != p->prof_q || vt != p->prof_vt) {
			/* re-plan from the actual state only when an input changed;
			 * otherwise keep evaluating one profile in closed form, so
			 * no rounding accumulates along a long line */
			double left = mlip_dmax(rem - q * s->c.ls_mm, 0.0);
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
			mlip_retire(p);
			p->l_start_mm = 0.0;
			p->s_mm = 0.0;
			p->v_mm_s = 0.0;
			continue;
		}
		p->in_corner = 1;
		p->q_exec = q;
		p->tc_s = 0.0;
		if (p->taps > 1 && s->exact) {
			/* the corner point is this period's sample and the next
			 * taps - 2 ones: no window then holds both legs (jerk.h) */
			p->dwell = (uint32_t)p->taps - 2u;
			tau = 0.0;
			break;
		}
	}

	/* controlled stop: once at rest on the path (and the mean with it),
	 * drop what is queued */
	if (p->stopping && p->v_mm_s == 0.0 && !p->in_corner &&
	    (p->taps <= 1 || p->still + 2u >= (uint32_t)p->taps)) {
		if (p->head != p->tail) {
			line_position(p, seg_at(p, p->tail), p->pos);
			p->head = p->tail;
			p->pass.on = 0; /* nothing left to plan */
			p->pending = 0;
			p->pass.has_reach = 0;
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
	mlip_run_state rs = MLIP_RUN_MOVING;
	if (p->head == p->tail) {
		rs = MLIP_RUN_IDLE;
	} else if (effective_override(p) == 0.0 && p->v_mm_s == 0.0 && !p->in_corner) {
		rs = MLIP_RUN_HELD;
	}
	if (p->taps <= 1) {
		memcpy(pos_out, p->pos, sizeof(double) * (size_t)p->n);
		return rs;
	}
	filter_step(p, pos_out);
	return mlip_settled(p) ? rs : MLIP_RUN_MOVING; /* at rest once the mean is */
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
