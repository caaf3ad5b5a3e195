/*
 * mlip/motion/strategy.h - the corner strategies behind one table, for the
 * motion folder's own files (corner.c, planner.c, interp.c, smoothplan.c,
 * strategy.c).
 * Not an interface for other folders: they choose a strategy by its
 * mlip_strategy value and the planner looks its entry up.
 *
 * A strategy is its corner (mlip_corner_plan: how the acceleration polygon
 * is used, or not) and, optionally, hooks where the planner lets it
 * reconsider a corner: when the corner is linked (its data made), inside the
 * backward pass (before the corner's q, Sec. 2.1) and when the executor
 * starts the line before it (Sec. 4). A strategy with no hooks is the
 * paper's planner with its own corner; the data a hook keeps is the
 * strategy's own (smooth: struct mlip_smooth_seg, beside the planner, in
 * storage the caller gives only to smooth).
 */
#ifndef MLIP_STRATEGY_H
#define MLIP_STRATEGY_H

#include <stdint.h>

#include "mlip/motion/planner.h"
#include "mlip/motion/smooth.h"

/* The corner of a strategy, with mlip_corner_plan's arguments. */
typedef void (*mlip_corner_fn)(int n, const double *e_s, const double *e_e, double ds_mm,
                               double de_mm, const double *accel, double eps_mm, double vcap_s_mm_s,
                               double vcap_e_mm_s, double period_s, struct mlip_corner *c);

struct mlip_strategy_ops {
	const char *name; /* as on command lines: mpct, bisector, stop, smooth */
	mlip_corner_fn corner;
	/* The corner at pr's end towards nx (not an exact stop): make pr->c
	 * and the strategy's own data of slot i (pr = slot i). NULL: corner
	 * above. The planner then computes pr's look-ahead coefficients. */
	void (*link)(struct mlip_planner *p, uint32_t i, struct mlip_seg *pr,
	             const struct mlip_seg *nx);
	/* Backward pass (early-terminated passes only), before pr's q is
	 * computed from rhs = q_next B + 2 a d (25)(26): may change pr's corner
	 * (then relinks it). Returns 1 when it did. NULL: never. */
	int (*choose)(struct mlip_planner *p, uint32_t i, struct mlip_seg *pr,
	              const struct mlip_seg *nx, double rhs);
	/* Full backward pass (an override or hold change): pr's q is about to
	 * be replaced; pr still holds the plan in effect. NULL: nothing. */
	void (*commit)(struct mlip_planner *p, uint32_t i, const struct mlip_seg *pr);
	/* Executor: the line of slot tail (s) is about to be planned from speed v
	 * with rem to its corner point, a next segment queued. NULL: nothing. */
	void (*line_start)(struct mlip_planner *p, struct mlip_seg *s, double rem, double v);
	/* The strategy needs storage beside the planner (mlip_planner_init). */
	int needs_store;
};

/* The table, indexed by mlip_strategy. */
extern const struct mlip_strategy_ops mlip_strategies[MLIP_STRATEGY_COUNT];

/* The strategies' corners (corner.c, smoothplan.c). */
void mlip_corner_mpct(int n, const double *e_s, const double *e_e, double ds_mm, double de_mm,
                      const double *accel, double eps_mm, double vcap_s_mm_s, double vcap_e_mm_s,
                      double period_s, struct mlip_corner *c);
void mlip_corner_bisector(int n, const double *e_s, const double *e_e, double ds_mm, double de_mm,
                          const double *accel, double eps_mm, double vcap_s_mm_s,
                          double vcap_e_mm_s, double period_s, struct mlip_corner *c);
void mlip_corner_stop(int n, const double *e_s, const double *e_e, double ds_mm, double de_mm,
                      const double *accel, double eps_mm, double vcap_s_mm_s, double vcap_e_mm_s,
                      double period_s, struct mlip_corner *c);
void mlip_corner_smooth(int n, const double *e_s, const double *e_e, double ds_mm, double de_mm,
                        const double *accel, double eps_mm, double vcap_s_mm_s, double vcap_e_mm_s,
                        double period_s, struct mlip_corner *c);

/* Pieces of corner.c the smooth strategy builds on. */
#define MLIP_COLLINEAR_EPS 1e-12 /* |e_e - e_s| below this: no turn, no acceleration */
void mlip_corner_straight(double vcap_s_mm_s, double vcap_e_mm_s, struct mlip_corner *c);
void mlip_corner_from_t(double alpha, double beta, double t, struct mlip_corner *c);
double mlip_corner_t2(int n, const double *e_s, const double *e_e, double alpha, double beta,
                      double ds_mm, double de_mm, double eps_mm, double vcap_s_mm_s,
                      double vcap_e_mm_s);

/* smooth's hooks (smoothplan.c) */
void mlip_smooth_link(struct mlip_planner *p, uint32_t i, struct mlip_seg *pr,
                      const struct mlip_seg *nx);
int mlip_smooth_choose(struct mlip_planner *p, uint32_t i, struct mlip_seg *pr,
                       const struct mlip_seg *nx, double rhs);
void mlip_smooth_commit(struct mlip_planner *p, uint32_t i, const struct mlip_seg *pr);
void mlip_smooth_line_start(struct mlip_planner *p, struct mlip_seg *s, double rem, double v);

/* ---- the planner's pieces the hooks use (planner.c) ---------------------- */

static inline double mlip_sq(double x)
{
	return x * x;
}

/* fmin/fmax are out-of-line libm calls under strict IEEE flags; every value
 * here is finite, so plain comparisons do. */
static inline double mlip_dmin(double a, double b)
{
	return a < b ? a : b;
}

static inline double mlip_dmax(double a, double b)
{
	return a > b ? a : b;
}

static inline struct mlip_seg *mlip_seg_at(struct mlip_planner *p, uint32_t i)
{
	return &p->seg[i & (p->cap - 1)];
}

static inline struct mlip_smooth_seg *mlip_smooth_at(struct mlip_planner *p, uint32_t i)
{
	return &p->sm[i & (p->cap - 1)];
}

/* Speed the line of s aims at: programmed feed times override, never above
 * the hard caps. */
static inline double mlip_line_target(const struct mlip_planner *p, const struct mlip_seg *s)
{
	return mlip_dmin(s->vfeed_mm_s * (p->hold ? 0.0 : p->override), s->vhard_mm_s);
}

/* Precompute pr's look-ahead coefficients from its corner pr->c. */
void mlip_planner_link_coeffs(struct mlip_planner *p, struct mlip_seg *pr,
                              const struct mlip_seg *nx);

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
static inline double mlip_corner_q_at(const struct mlip_corner *c, double a, double q_plan,
                                      double rem, double v, int *brakeable)
{
	double vs2 = mlip_sq(c->vs_mm_s), ls = c->ls_mm;
	double geom = ls > 0.0 ? mlip_dmin(1.0, rem / ls) : 1.0;
	double lo = 0.0, hi = geom;

	double grow = vs2 + 2.0 * a * ls;
	if (grow > 0.0) {
		hi = mlip_dmin(hi, (v * v + 2.0 * a * rem) / grow);
	}
	/* k = 0 (beta equal to the line's a) is common and makes the brake
	 * condition independent of q: do not let rounding turn it into a bound */
	double k = vs2 - 2.0 * a * ls, need = v * v - 2.0 * a * rem;
	if (k > 1e-12 * grow) {
		lo = need / k;
	} else if (k < -1e-12 * grow) {
		hi = mlip_dmin(hi, need / k); /* bigger corners brake worse here */
	}
	double q = mlip_dmin(mlip_dmax(q_plan, lo), hi);
	*brakeable = !(lo > hi);
	if (lo > hi) {
		q = mlip_dmin(lo, geom); /* only by rounding: keep the state brakeable */
	}
	return mlip_dmax(q, 0.0);
}

#endif
