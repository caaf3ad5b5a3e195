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
 *
 * Each strategy's corner is an entry of the table (mlip/motion/strategy.h):
 * mpct (the LP vertex), bisector (10), stop; smooth's is in smoothplan.c.
 */
#include <math.h>

#include "mlip/motion/strategy.h"

#define COLLINEAR_EPS MLIP_COLLINEAR_EPS

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
		scale = mlip_dmax(scale, fabs(c[m]) + fabs(d[m]));
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
			g = mlip_dmax(g, fabs(c[k] * w - d[k]));
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

void mlip_corner_straight(double vcap_s, double vcap_e, struct mlip_corner *c)
{
	/* no turn: the speed is continuous and only the caps bound it */
	double v = mlip_dmin(vcap_s, vcap_e);
	*c = (struct mlip_corner){0};
	c->vs_mm_s = v;
	c->ve_mm_s = v;
}

/* Fill speeds and distances from a and t_m (eqs 2, 3, 5, 6). */
void mlip_corner_from_t(double alpha, double beta, double t, struct mlip_corner *c)
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
double mlip_corner_t2(int n, const double *e_s, const double *e_e, double alpha, double beta,
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
		t2 = mlip_dmin(
		    t2, mlip_dmin(ds_mm / beta, (vcap_s_mm_s / beta) * (vcap_s_mm_s / beta)));
	}
	if (alpha > 0.0) {
		t2 = mlip_dmin(
		    t2, mlip_dmin(de_mm / alpha, (vcap_e_mm_s / alpha) * (vcap_e_mm_s / alpha)));
	}
	return t2;
}

/* |e_e - e_s|^2: the turn, below COLLINEAR_EPS^2 none */
static double turn2_of(int n, const double *e_s, const double *e_e)
{
	double turn2 = 0.0;
	for (int k = 0; k < n; k++) {
		double dk = e_e[k] - e_s[k];
		turn2 += dk * dk;
	}
	return turn2;
}

/* stop: speed 0 at every corner */
void mlip_corner_stop(int n, const double *e_s, const double *e_e, double ds_mm, double de_mm,
                      const double *accel, double eps_mm, double vcap_s_mm_s, double vcap_e_mm_s,
                      double period_s, struct mlip_corner *c)
{
	(void)n, (void)e_s, (void)e_e, (void)ds_mm, (void)de_mm, (void)accel, (void)eps_mm;
	(void)vcap_s_mm_s, (void)vcap_e_mm_s, (void)period_s;
	*c = (struct mlip_corner){0};
}

/* bisector: equal speeds, one period, a along e_e - e_s (10) */
void mlip_corner_bisector(int n, const double *e_s, const double *e_e, double ds_mm, double de_mm,
                          const double *accel, double eps_mm, double vcap_s_mm_s,
                          double vcap_e_mm_s, double period_s, struct mlip_corner *c)
{
	double turn2 = turn2_of(n, e_s, e_e);
	if (turn2 < COLLINEAR_EPS * COLLINEAR_EPS) {
		mlip_corner_straight(vcap_s_mm_s, vcap_e_mm_s, c);
		return;
	}
	/* (10): v (e_e - e_s) = a T, a on the bisector, one period */
	double T = period_s;
	double amax = INFINITY;
	for (int k = 0; k < n; k++) {
		double dk = e_e[k] - e_s[k];
		if (dk != 0.0) {
			amax = mlip_dmin(amax, accel[k] / fabs(dk));
		}
	}
	double v = T * amax;
	v = mlip_dmin(v, 8.0 * eps_mm / (sqrt(turn2) * T)); /* (17), |a| = v |e_e - e_s| / T */
	v = mlip_dmin(v, mlip_dmin(ds_mm, de_mm) / T);      /* l = v T / 2 <= d / 2 */
	v = mlip_dmin(v, mlip_dmin(vcap_s_mm_s, vcap_e_mm_s));
	mlip_corner_from_t(v / T, v / T, T, c);
}

/* mpct, the paper: the acceleration polygon's LP vertex (Theorem 2), t_m
 * from (18)(19)(20) */
void mlip_corner_mpct(int n, const double *e_s, const double *e_e, double ds_mm, double de_mm,
                      const double *accel, double eps_mm, double vcap_s_mm_s, double vcap_e_mm_s,
                      double period_s, struct mlip_corner *c)
{
	(void)period_s;
	double alpha, beta;
	if (turn2_of(n, e_s, e_e) < COLLINEAR_EPS * COLLINEAR_EPS ||
	    mlip_corner_lp(n, e_s, e_e, accel, &alpha, &beta) != 0) {
		mlip_corner_straight(vcap_s_mm_s, vcap_e_mm_s, c);
		return;
	}
	double t2 = mlip_corner_t2(n, e_s, e_e, alpha, beta, ds_mm, de_mm, eps_mm, vcap_s_mm_s,
	                           vcap_e_mm_s);
	mlip_corner_from_t(alpha, beta, sqrt(t2), c);
}

void mlip_corner_plan(int n, mlip_strategy st, const double *e_s, const double *e_e, double ds_mm,
                      double de_mm, const double *accel, double eps_mm, double vcap_s_mm_s,
                      double vcap_e_mm_s, double period_s, struct mlip_corner *c)
{
	mlip_corner_fn f =
	    (unsigned)st < MLIP_STRATEGY_COUNT ? mlip_strategies[st].corner : mlip_corner_stop;
	f(n, e_s, e_e, ds_mm, de_mm, accel, eps_mm, vcap_s_mm_s, vcap_e_mm_s, period_s, c);
}
