/*
 * scurve.c - jerk-limited speed changes (mlip/motion/scurve.h: S1-S4).
 */
#include "mlip/motion/scurve.h"

#include <math.h>
#include <string.h>

double mlip_scurve_dv_time(double dv, double a, double j)
{
	dv = fabs(dv);
	if (dv >= a * a / j) {
		return dv / a + a / j; /* (S1) */
	}
	return 2.0 * sqrt(dv / j);
}

double mlip_scurve_dv_dist(double v0, double v1, double a, double j)
{
	return 0.5 * (v0 + v1) * mlip_scurve_dv_time(v1 - v0, a, j); /* (S2) */
}

/* asinh(x), x >= 0, from log1p (the core's libm allow-list, tools/purity.sh) */
static double asinh_pos(double x)
{
	if (x > 1e8) {
		return log(2.0 * x); /* within 1 / (4 x^2) */
	}
	return log1p(x + x * x / (1.0 + sqrt(1.0 + x * x)));
}

double mlip_scurve_brake_v0(double v1, double d, double a, double j)
{
	if (!(d > 0.0)) {
		return v1;
	}
	double xb = a * a / j; /* the largest change of the triangle */
	double db = (2.0 * v1 + xb) * (a / j);
	if (d <= db) {
		/* (2 v1 + x) sqrt(x / j) = d: with u = sqrt(x), u^3 + p u = q */
		double p = 2.0 * v1, q = d * sqrt(j), u;
		if (p > 0.0) {
			/* the one real root, in the form free of cancellation */
			u = 2.0 * sqrt(p / 3.0) *
			    sinh(asinh_pos(1.5 * q / p * sqrt(3.0 / p)) / 3.0);
		} else {
			u = cbrt(q);
		}
		for (int i = 0; i < 2; i++) { /* polish: Newton on a monotone cubic */
			double den = 3.0 * u * u + p;
			if (den > 0.0) {
				u -= (u * u * u + p * u - q) / den;
			}
		}
		return v1 + u * u;
	}
	/* (2 v1 + x)(x / a + a / j) = 2 d:  x^2 + b x + c = 0, c < 0 here */
	double b = xb + 2.0 * v1, c = 2.0 * v1 * xb - 2.0 * a * d;
	return v1 + -2.0 * c / (b + sqrt(b * b - 4.0 * c));
}

static void push(struct mlip_scurve *c, double jerk, double t)
{
	if (t > 0.0 && c->n < MLIP_SCURVE_PHASES) {
		c->j[c->n] = jerk;
		c->t[c->n] = t;
		c->n++;
	}
}

/* The phases of a speed change va -> vb between zero accelerations (S1). */
static void push_change(struct mlip_scurve *c, double va, double vb, double a, double j)
{
	double dv = vb - va, sg = dv >= 0.0 ? 1.0 : -1.0;
	dv = fabs(dv);
	if (dv >= a * a / j) {
		push(c, sg * j, a / j);
		push(c, 0.0, dv / a - a / j);
		push(c, -sg * j, a / j);
	} else {
		double tr = sqrt(dv / j);
		push(c, sg * j, tr);
		push(c, -sg * j, tr);
	}
}

/* Start states of every phase, by exact integration, and the end state. */
static void integrate(struct mlip_scurve *c, double v0, double a0)
{
	double s = 0.0, v = v0, acc = a0, t = 0.0;
	for (int k = 0; k < c->n; k++) {
		double tau = c->t[k], jk = c->j[k];
		c->s0[k] = s;
		c->v0[k] = v;
		c->a0[k] = acc;
		s += v * tau + acc * tau * tau / 2.0 + jk * tau * tau * tau / 6.0;
		v += acc * tau + jk * tau * tau / 2.0;
		acc += jk * tau;
		t += tau;
	}
	c->total_s = t;
	c->end_s = s;
	c->end_v = v;
	c->end_a = acc;
}

static void reset(struct mlip_scurve *c)
{
	memset(c, 0, sizeof(*c));
}

int mlip_scurve_line(struct mlip_scurve *c, double v0, double v1, double d, double vmax, double a,
                     double j)
{
	reset(c);
	if (!(v0 >= 0.0 && v1 >= 0.0 && d >= 0.0 && a > 0.0 && j > 0.0 && isfinite(v0) &&
	      isfinite(v1) && isfinite(d) && isfinite(a) && isfinite(j) && vmax > 0.0)) {
		return -1;
	}
	double need = mlip_scurve_dv_dist(v0, v1, a, j);
	if (need > d * (1.0 + 1e-12) + 1e-15) {
		return -1;
	}
	double lo = v0 > v1 ? v0 : v1, hi = vmax > lo ? vmax : lo;
	double fhi = mlip_scurve_dv_dist(v0, hi, a, j) + mlip_scurve_dv_dist(hi, v1, a, j);
	double vp = hi;
	if (fhi > d) {
		/* the peak: the distance up and down grows with it (bounded work) */
		for (int i = 0; i < 64; i++) {
			double mid = 0.5 * (lo + hi);
			double f =
			    mlip_scurve_dv_dist(v0, mid, a, j) + mlip_scurve_dv_dist(mid, v1, a, j);
			if (f <= d) {
				lo = mid;
			} else {
				hi = mid;
			}
		}
		vp = lo;
	}
	double used = mlip_scurve_dv_dist(v0, vp, a, j) + mlip_scurve_dv_dist(vp, v1, a, j);
	push_change(c, v0, vp, a, j);
	if (vp > 0.0 && d > used) {
		push(c, 0.0, (d - used) / vp);
	}
	push_change(c, vp, v1, a, j);
	integrate(c, v0, 0.0);
	return 0;
}

void mlip_scurve_stop(struct mlip_scurve *c, double v, double a0, double a, double j)
{
	reset(c);
	if (a0 > a) {
		a0 = a;
	} else if (a0 < -a) {
		a0 = -a;
	}
	if (v < 0.0) {
		v = 0.0;
	}
	if (a0 < 0.0 && v <= a0 * a0 / (2.0 * j)) {
		/* releasing at once still reaches rest first: stop where v = 0 */
		double disc = a0 * a0 - 2.0 * j * v;
		push(c, j, (-a0 - sqrt(disc > 0.0 ? disc : 0.0)) / j);
		integrate(c, v, a0);
		return;
	}
	/* (S4) v + (a0^2 - 2 ap^2) / 2j - ap t2 = 0, ap <= a */
	double ap = sqrt(j * v + 0.5 * a0 * a0), hold = 0.0;
	if (ap > a) {
		ap = a;
		hold = (v + (a0 * a0 - 2.0 * a * a) / (2.0 * j)) / a;
	}
	push(c, -j, (a0 + ap) / j);
	push(c, 0.0, hold);
	push(c, j, ap / j);
	integrate(c, v, a0);
}

void mlip_scurve_eval(const struct mlip_scurve *c, double t, double *s, double *v, double *acc)
{
	if (c->n == 0 || !(t > 0.0)) {
		*s = 0.0;
		*v = c->n ? c->v0[0] : c->end_v;
		*acc = c->n ? c->a0[0] : c->end_a;
		return;
	}
	if (t >= c->total_s) {
		*s = c->end_s;
		*v = c->end_v;
		*acc = c->end_a;
		return;
	}
	int k = 0;
	while (k + 1 < c->n && t > c->t[k]) {
		t -= c->t[k];
		k++;
	}
	double jk = c->j[k];
	*s = c->s0[k] + c->v0[k] * t + c->a0[k] * t * t / 2.0 + jk * t * t * t / 6.0;
	*v = c->v0[k] + c->a0[k] * t + jk * t * t / 2.0;
	*acc = c->a0[k] + jk * t;
}
