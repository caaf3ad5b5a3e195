/*
 * corner.c - multi-period constant-acceleration corners, Sec. 1 of Zhang,
 * Sun, Gao, Li (2011), and the two baselines the paper measures against.
 *
 * A corner at P joins a segment of direction e_s to one of direction e_e.
 * The tool leaves the first at S = P - l_s e_s with speed v_s and joins the
 * second at E = P + l_e e_e with speed v_e under one constant acceleration
 * a for t_m seconds:
 *
 *     v_e e_e - v_s e_s = a t_m                                    (1)
 *     l_s = v_s t_m / 2,  l_e = v_e t_m / 2                        (5)(6)
 *     s(t) = P - l_s e_s + v_s e_s t + a t^2 / 2 = the parabola    (14)
 *
 *          S ---- l_s ---- P
 *              `-._         \
 *                  `-.  a    l_e
 *                     `.      \
 *                       `-.    E
 *
 * With a = alpha e_e - beta e_s we have v_e = alpha t_m, v_s = beta t_m:
 * choosing a is a 2-variable linear programme over the "acceleration
 * polygon" (Prop. 1, Theorem 2), the same in 2 to 6 axes (Sec. 1.4). Once a
 * is fixed, one parameter t_m scales v (linearly) and l (quadratically), and
 * is set in order by the contour tolerance (18), half of each neighbouring
 * segment (19) and the speed caps (20).
 */
#include <math.h>

#include "mlip/motion/planner.h"
#include "mlip/motion/smooth.h"

/* Turning angles below this (in |e_e - e_s|) need no acceleration at all. */
#define COLLINEAR_EPS 1e-12

/* fmin/fmax are out-of-line libm calls under strict IEEE flags */
static double dmin(double a, double b)
{
	return a < b ? a : b;
}

static double dmax(double a, double b)
{
	return a > b ? a : b;
}

/*
 * With s = alpha + beta and w = alpha / s, the constraints read
 *     s |c_k w - d_k| <= 1,   c_k = (e_e[k] + e_s[k]) / A_k,  d_k = e_s[k] / A_k,
 * so the optimum is s = 1 / min over w in [0,1] of g(w) = max_k |c_k w - d_k|.
 * g is convex and piecewise linear: its minimum lies at w = 0, w = 1 or where
 * two of its pieces cross, so those candidates are enough (a vertex of the
 * acceleration polygon, as the paper says). At most 6 axes: <= 33 candidates.
 */
int mlip_corner_lp(int n, const double *e_s, const double *e_e, const double *accel, double *alpha,
                   double *beta)
{
	double c[MLIP_MAX_AXES], d[MLIP_MAX_AXES];
	int m = 0;
	double scale = 0.0;

	for (int k = 0; k < n; k++) {
		if (e_s[k] == 0.0 && e_e[k] == 0.0) {
			continue; /* axis still in both segments: no constraint */
		}
		c[m] = (e_e[k] + e_s[k]) / accel[k];
		d[m] = e_s[k] / accel[k];
		scale = dmax(scale, fabs(c[m]) + fabs(d[m]));
		m++;
	}

	double cand[3 + MLIP_MAX_AXES * (MLIP_MAX_AXES - 1)];
	int nc = 0;
	cand[nc++] = 0.5; /* first, so ties (reversals) prefer alpha = beta */
	cand[nc++] = 0.0;
	cand[nc++] = 1.0;
	for (int i = 0; i < m; i++) {
		for (int j = i + 1; j < m; j++) {
			double den = c[i] - c[j];
			if (den != 0.0) {
				cand[nc++] = (d[i] - d[j]) / den;
			}
			den = c[i] + c[j];
			if (den != 0.0) {
				cand[nc++] = (d[i] + d[j]) / den;
			}
		}
	}

	double best_g = INFINITY, best_w = 0.5;
	for (int i = 0; i < nc; i++) {
		double w = cand[i];
		if (!(w >= 0.0 && w <= 1.0)) {
			continue;
		}
		double g = 0.0;
		for (int k = 0; k < m; k++) {
			g = dmax(g, fabs(c[k] * w - d[k]));
		}
		/* strictly better, or equal within rounding and closer to 1/2 */
		if (g < best_g * (1.0 - 1e-12) ||
		    (g <= best_g * (1.0 + 1e-12) && fabs(w - 0.5) < fabs(best_w - 0.5))) {
			best_g = g;
			best_w = w;
		}
	}
	if (!(best_g > COLLINEAR_EPS * scale)) {
		return -1; /* collinear: any speed passes without acceleration */
	}
	*alpha = best_w / best_g;
	*beta = (1.0 - best_w) / best_g;
	return 0;
}

static void corner_straight(double vcap_s, double vcap_e, struct mlip_corner *c)
{
	/* no turn: the speed is continuous and only the caps bound it */
	double v = dmin(vcap_s, vcap_e);
	*c = (struct mlip_corner){0};
	c->vs_mm_s = v;
	c->ve_mm_s = v;
}

/* Fill speeds and distances from a and t_m (eqs 2, 3, 5, 6). */
static void corner_from_t(double alpha, double beta, double t, struct mlip_corner *c)
{
	c->alpha_mm_s2 = alpha;
	c->beta_mm_s2 = beta;
	c->t_s = t;
	c->vs_mm_s = beta * t;
	c->ve_mm_s = alpha * t;
	c->ls_mm = 0.5 * beta * t * t;
	c->le_mm = 0.5 * alpha * t * t;
}

/* t^2 of a corner with acceleration alpha e_e - beta e_s. With l = beta t^2 / 2
 * (5)(6) and v = beta t (2)(3), the three bounds are minima in t^2:
 *   (18) t^2 <= 8 eps / |a|
 *   (19) l_s <= d_s / 2  <=>  t^2 <= d_s / beta   (and d_e / alpha)
 *   (20) v_s <= vcap_s   <=>  t^2 <= (vcap_s / beta)^2 (and e)   */
static double corner_t2(int n, const double *e_s, const double *e_e, double alpha, double beta,
                        double ds_mm, double de_mm, double eps_mm, double vcap_s_mm_s,
                        double vcap_e_mm_s)
{
	double a2 = 0.0;
	for (int k = 0; k < n; k++) {
		double ak = alpha * e_e[k] - beta * e_s[k];
		a2 += ak * ak;
	}
	double t2 = 8.0 * eps_mm / sqrt(a2);
	if (beta > 0.0) {
		t2 = dmin(t2, dmin(ds_mm / beta, (vcap_s_mm_s / beta) * (vcap_s_mm_s / beta)));
	}
	if (alpha > 0.0) {
		t2 = dmin(t2, dmin(de_mm / alpha, (vcap_e_mm_s / alpha) * (vcap_e_mm_s / alpha)));
	}
	return t2;
}

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
		g = dmax(g, fabs(w * e_e[k] - (1.0 - w) * e_s[k]) / accel[k]);
	}
	if (!(g > 0.0)) {
		return -1;
	}
	double al = w / g, be = (1.0 - w) / g;
	corner_from_t(
	    al, be,
	    sqrt(corner_t2(n, e_s, e_e, al, be, ds_mm, de_mm, eps_mm, vcap_s_mm_s, vcap_e_mm_s)),
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
			a_line = dmin(a_line, accel[k] / fabs(e_s[k]));
		}
	}
	/* the LP vertex itself first (the paper's corner), then towards 1/2 */
	corner_from_t(alpha, beta,
	              sqrt(corner_t2(n, e_s, e_e, alpha, beta, ds_mm, de_mm, eps_mm, vcap_s_mm_s,
	                             vcap_e_mm_s)),
	              c);
	double best_v = dmin(c->vs_mm_s, c->ve_mm_s);
	for (int i = 1; i <= SMOOTH_W_GRID; i++) {
		double w = w_lp + (0.5 - w_lp) * (double)i / (double)SMOOTH_W_GRID;
		struct mlip_corner cw;
		if (mlip_corner_smooth_w(n, e_s, e_e, ds_mm, de_mm, accel, eps_mm, vcap_s_mm_s,
		                         vcap_e_mm_s, w, &cw) != 0 ||
		    !(cw.beta_mm_s2 > a_line)) {
			continue;
		}
		if (dmin(cw.vs_mm_s, cw.ve_mm_s) > best_v * (1.0 + 1e-9)) {
			best_v = dmin(cw.vs_mm_s, cw.ve_mm_s);
			*c = cw;
		}
	}
	return 0;
}

/* The line's own acceleration limit a_{i,m} along e (Sec. 2.1). */
static double line_accel(int n, const double *e, const double *accel)
{
	double a = INFINITY;
	for (int k = 0; k < n; k++) {
		if (e[k] != 0.0) {
			a = dmin(a, accel[k] / fabs(e[k]));
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
	mlip_corner_plan(n, MLIP_STRATEGY_SMOOTH, e_s, e_e, ds_mm, de_mm, accel, eps_mm,
	                 vcap_s_mm_s, vcap_e_mm_s, 0.0, &out[0]);
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

void mlip_corner_plan(int n, mlip_strategy st, const double *e_s, const double *e_e, double ds_mm,
                      double de_mm, const double *accel, double eps_mm, double vcap_s_mm_s,
                      double vcap_e_mm_s, double period_s, struct mlip_corner *c)
{
	double de[MLIP_MAX_AXES];
	for (int k = 0; k < n; k++) {
		de[k] = e_e[k] - e_s[k];
	}
	double turn2 = 0.0;
	for (int k = 0; k < n; k++) {
		turn2 += de[k] * de[k];
	}

	if (st == MLIP_STRATEGY_STOP) {
		*c = (struct mlip_corner){0};
		return;
	}
	if (turn2 < COLLINEAR_EPS * COLLINEAR_EPS) {
		corner_straight(vcap_s_mm_s, vcap_e_mm_s, c);
		return;
	}

	if (st == MLIP_STRATEGY_BISECTOR) {
		/* (10): v (e_e - e_s) = a T, a on the bisector, one period */
		double T = period_s;
		double amax = INFINITY;
		for (int k = 0; k < n; k++) {
			if (de[k] != 0.0) {
				amax = dmin(amax, accel[k] / fabs(de[k]));
			}
		}
		double v = T * amax;
		v = dmin(v, 8.0 * eps_mm / (sqrt(turn2) * T)); /* (17), |a| = v |e_e - e_s| / T */
		v = dmin(v, dmin(ds_mm, de_mm) / T);           /* l = v T / 2 <= d / 2 */
		v = dmin(v, dmin(vcap_s_mm_s, vcap_e_mm_s));
		corner_from_t(v / T, v / T, T, c);
		return;
	}

	double alpha, beta;
	if (st == MLIP_STRATEGY_SMOOTH && !mlip_corner_smooth_sharp(n, e_s, e_e)) {
		if (corner_smooth(n, e_s, e_e, ds_mm, de_mm, accel, eps_mm, vcap_s_mm_s,
		                  vcap_e_mm_s, c) != 0) {
			corner_straight(vcap_s_mm_s, vcap_e_mm_s, c);
		}
		return;
	}
	if (mlip_corner_lp(n, e_s, e_e, accel, &alpha, &beta) != 0) {
		corner_straight(vcap_s_mm_s, vcap_e_mm_s, c);
		return;
	}
	double t2 =
	    corner_t2(n, e_s, e_e, alpha, beta, ds_mm, de_mm, eps_mm, vcap_s_mm_s, vcap_e_mm_s);
	double t = sqrt(t2);

	corner_from_t(alpha, beta, t, c);
}
