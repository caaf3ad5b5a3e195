/*
 * mlip/motion/pathspeed.h - the per-axis limits of a path-speed plan along a
 * curve (issue 21): the pieces a planner that moves along `smooth`'s curve at
 * a jerk-limited path speed is built from (docs/benchmarks.md, "The jerk
 * limit": bench/pathspeed.py is the modelled plan). Not yet used by the
 * planner: no trace changes.
 *
 * A point moves along x(s) (s the arc length, |x'| = 1) at path speed v,
 * path acceleration a and path jerk j. Per axis k (the chain rule):
 *
 *     acceleration   x'_k a + x''_k v^2                               (P1)
 *     jerk           x'_k j + 3 x''_k v a + x'''_k v^3                (P2)
 *
 * The plan keeps |P1| <= A_k and |P2| <= J_k on every axis jointly (no fixed
 * share between the tangential and the normal terms). For a given v, (P1) is
 * linear in a: one interval per axis, the allowed a their intersection; for
 * given v and a, (P2) is linear in j the same way. An axis the path does not
 * move along (x'_k = 0) allows every a (every j) or none.
 *
 * The quasi-static speed (a = j = 0 held: the steady speed the curve's own
 * acceleration and jerk allow at a point, bench/topp.py's bound):
 *
 *     v_q = min(vmax, min_k sqrt(A_k / |x''_k|), min_k cbrt(J_k / |x'''_k|))   (P3)
 *
 * The curve from a polyline (`smooth`'s output, or any sampled curve): the
 * cubic x(t) through four consecutive points, t their cumulative chord
 * length, and its derivatives turned into arc-length ones (sigma = |x_t|):
 *
 *     x'   = x_t / sigma
 *     x''  = x_tt / sigma^2 - x_t sigma_t / sigma^3                     (P4)
 *     x''' = (x_ttt / sigma^2 - 3 x_tt sigma_t / sigma^3 - x_t sigma_tt / sigma^3
 *             + 3 x_t sigma_t^2 / sigma^4) / sigma
 *
 * with sigma_t = x_t . x_tt / sigma and sigma_tt = (|x_tt|^2 + x_t . x_ttt) / sigma
 * - sigma_t^2 / sigma. On a curve sampled every h the error is O(h^2) in x''
 * and O(h) in x''' (the cubic's third derivative is constant between the
 * points): x''' read from a polyline is only as smooth as its samples are.
 *
 * Positions need more than (P4): the cubics of consecutive windows meet with
 * a kink (C0 only), which a plan passing it at speed v shows as a jerk of
 * about v |kink| / T^2 (bench/pathspeed.py --poly on trochoid, whose
 * smoothed start turns by 0.07 rad at one point: 1.01 J at 7 mm/s; 0.97 J
 * with the spline). The plan's positions and derivatives come instead from the
 * natural cubic spline through the points by chord length (C2), its second
 * derivatives M_i (per axis) from
 *
 *     h_{i-1} M_{i-1} + 2 (h_{i-1} + h_i) M_i + h_i M_{i+1}
 *         = 6 ((p_{i+1} - p_i) / h_i - (p_i - p_{i-1}) / h_{i-1}),  M at the ends 0   (P5)
 *
 * solved over a window of points (tridiagonal, Thomas' algorithm). The
 * window's ends move the spline inside it by about (2 - sqrt 3)^k, k the
 * points between (0.268^k: 1e-9 at 16 points), so a stream fitted over
 * sliding windows and read only in their middle is the spline of the whole
 * stream to that accuracy; the same (P4) conversion gives its arc-length
 * derivatives.
 *
 * Pure C, no allocation, bounded work (O(n^2) at most per call, n <= MLIP_MAX_AXES).
 */
#ifndef MLIP_PATHSPEED_H
#define MLIP_PATHSPEED_H

#include <math.h>

#include "mlip/types.h"

/* The curve's arc-length derivatives at one point. */
struct mlip_path_point {
	double d1[MLIP_MAX_AXES]; /* x'   (unit) */
	double d2[MLIP_MAX_AXES]; /* x''  (the curvature vector) */
	double d3[MLIP_MAX_AXES]; /* x''' */
};

/* One axis of (P1)(P2): [*l, *h] narrowed to the x with |p x + c| <= lim
 * (p = 0: every x, or none). 0 when this axis alone exceeds lim whatever x
 * (then [*l, *h] is as it was). Inline: the plan's inner checkpoints call it
 * per axis. */
static inline int mlip_path_axis_cut(double p, double c, double lim, double *l, double *h)
{
	if (p == 0.0) {
		return fabs(c) <= lim;
	}
	double x1 = (-lim - c) / p, x2 = (lim - c) / p;
	if (x1 > x2) {
		double t = x1;
		x1 = x2;
		x2 = t;
	}
	*l = x1 > *l ? x1 : *l;
	*h = x2 < *h ? x2 : *h;
	return 1;
}

/* (P1): the path accelerations a in [*lo, *hi] that keep every axis within
 * accel[k] at speed v. 0 when none does (the speed alone exceeds a limit). */
int mlip_path_accel_range(int n, const struct mlip_path_point *c, const double *accel, double v,
                          double *lo, double *hi);

/* (P2): the path jerks j in [*lo, *hi] that keep every axis within jerk[k]
 * at speed v and path acceleration a. 0 when none does. */
int mlip_path_jerk_range(int n, const struct mlip_path_point *c, const double *jerk, double v,
                         double a, double *lo, double *hi);

/* (P3): the quasi-static speed; jerk NULL: the acceleration alone. */
double mlip_path_vmax(int n, const struct mlip_path_point *c, const double *accel,
                      const double *jerk, double vmax);

/* (P4): the derivatives at chord parameter t (0 at p[0]; t between the
 * middle two points for the best estimate) of the cubic through the four
 * points p[0..3] (each n coordinates). -1 when two consecutive points
 * coincide or the cubic stops there (sigma = 0). */
int mlip_path_from_points(int n, const double p[4][MLIP_MAX_AXES], double t,
                          struct mlip_path_point *out);

/* (P5) The natural cubic spline through up to MLIP_PATH_WIN points. */
#define MLIP_PATH_WIN 64
struct mlip_path_spline {
	int n;                                   /* axes */
	int count;                               /* points */
	double s[MLIP_PATH_WIN];                 /* chord length from the first point */
	double p[MLIP_PATH_WIN][MLIP_MAX_AXES];  /* the points */
	double m[MLIP_PATH_WIN][MLIP_MAX_AXES];  /* second derivatives by chord length */
	double b[MLIP_PATH_WIN][MLIP_MAX_AXES];  /* x_t at each piece's start */
	double t3[MLIP_PATH_WIN][MLIP_MAX_AXES]; /* x_ttt on each piece (constant) */
	double c[MLIP_PATH_WIN];                 /* the solve's scratch */
};

/* Fit the spline through pts[0..count-1] (2 <= count <= MLIP_PATH_WIN).
 * -1 when count is out of range, a point is not finite or two consecutive
 * points coincide. */
int mlip_path_spline_fit(struct mlip_path_spline *sp, int n, const double pts[][MLIP_MAX_AXES],
                         int count);

/* The spline at chord length s (clamped to its span): position x[n] (may be
 * NULL) and derivatives, by arc length (by_arc 1: P4's conversion, for speed
 * caps in mm/s) or by the spline's own parameter (by_arc 0: what a plan that
 * advances s takes in (P1)(P2), which hold for any parameter; its speed is
 * then v |x_t|). -1 where the spline stops (sigma = 0). */
int mlip_path_spline_eval(const struct mlip_path_spline *sp, double s, int by_arc, double *x,
                          struct mlip_path_point *d);

/* A piecewise cubic by chord length as the plan reads it: a view of a
 * fitted spline's arrays (count points, count - 1 pieces), whoever holds
 * them (a struct mlip_path_spline, or a caller's own arrays fitted by
 * mlip_path_fit). cap (NULL: none): each knot's speed cap, mm/s (0: none),
 * the feed of the block its point belongs to; a piece's is the lower of
 * its two knots' (mlip/motion/pathplan.h). */
struct mlip_path_curve {
	int n, count;
	const double *s;
	const double (*p)[MLIP_MAX_AXES];
	const double (*m)[MLIP_MAX_AXES];
	const double (*b)[MLIP_MAX_AXES];
	const double (*t3)[MLIP_MAX_AXES];
	const double *cap;
};

/* The view of sp. */
void mlip_path_spline_curve(const struct mlip_path_spline *sp, struct mlip_path_curve *cv);

/* (P5)'s tridiagonal system by Thomas' algorithm over knots f..last, row
 * f already in c[f] and m[f] (the caller's end condition), natural (M = 0)
 * at `last`: forward elimination, then back substitution into m. */
void mlip_path_tridiag(int n, const double *s, const double p[][MLIP_MAX_AXES], double *c,
                       double (*m)[MLIP_MAX_AXES], int f, int last);

/* (P5) over the caller's arrays of count entries each (count >= 2; c is
 * scratch): what mlip_path_spline_fit does for its window, for a curve of
 * any length (the benchmarks fit a whole program's `smooth` output);
 * fills *cv with the view. -1 as mlip_path_spline_fit. */
int mlip_path_fit(int n, const double pts[][MLIP_MAX_AXES], int count, double *s,
                  double (*p)[MLIP_MAX_AXES], double (*m)[MLIP_MAX_AXES],
                  double (*b)[MLIP_MAX_AXES], double (*t3)[MLIP_MAX_AXES], double *c,
                  struct mlip_path_curve *cv);

/* The piece i holding chord length s (s_i <= s < s_i+1, the last piece for
 * s at or past the end, 0 before the start: what mlip_path_spline_eval
 * reads), searched from piece `hint` (a plan moves forward piece by piece:
 * O(1) steps, no binary search). */
int mlip_path_spline_piece(const struct mlip_path_curve *cv, double s, int hint);

/* How far piece i of the spline may stray from its chord (the straight
 * segment between its points), a bound: |x(u) - chord(u)| <= u (h - u) / 2
 * max |x''| on the piece (the interpolation error of a line through the
 * ends, x'' linear so its norm is largest at an end), so at most
 *
 *     sag_i = h_i^2 / 8 max(|M_i|, |M_i+1|)                              (P6)
 *
 * The plan may take the spline only where this stays within what the
 * block's tolerance leaves (docs/algorithm.md, the hand-over): a natural
 * spline through a sharp vertex overshoots by far more. */
double mlip_path_piece_sag(const struct mlip_path_curve *cv, int i);

/* mlip_path_spline_eval by the spline's own parameter (by_arc 0) on piece
 * i (from mlip_path_spline_piece; s clamped as there): the same values,
 * from the piece's coefficients kept by the fit; axes n and beyond are left
 * as they are (the plan's hot path reads only the first n). */
void mlip_path_spline_eval_piece(const struct mlip_path_curve *cv, int i, double s, double *x,
                                 struct mlip_path_point *d);

#endif
