/*
 * pathspeed.c - the per-axis limits of a path-speed plan along a curve
 * (mlip/motion/pathspeed.h: P1-P4).
 */
#include "mlip/motion/pathspeed.h"

#include <math.h>

/* The x with |p x + c| <= lim for every axis (p, c per axis): an
 * intersection of one interval per axis. 0 when empty. */
static int intersect(int n, const double *p, const double *c, const double *lim, double *lo,
                     double *hi)
{
	double l = -INFINITY, h = INFINITY;
	for (int k = 0; k < n; k++) {
		if (p[k] == 0.0) {
			if (!(fabs(c[k]) <= lim[k])) {
				return 0; /* this axis alone exceeds its limit, whatever x */
			}
			continue;
		}
		double x1 = (-lim[k] - c[k]) / p[k], x2 = (lim[k] - c[k]) / p[k];
		if (x1 > x2) {
			double t = x1;
			x1 = x2;
			x2 = t;
		}
		l = x1 > l ? x1 : l;
		h = x2 < h ? x2 : h;
	}
	*lo = l;
	*hi = h;
	return l <= h;
}

int mlip_path_accel_range(int n, const struct mlip_path_point *c, const double *accel, double v,
                          double *lo, double *hi)
{
	double q[MLIP_MAX_AXES];
	for (int k = 0; k < n; k++) {
		q[k] = c->d2[k] * v * v; /* (P1): the normal term */
	}
	return intersect(n, c->d1, q, accel, lo, hi);
}

int mlip_path_jerk_range(int n, const struct mlip_path_point *c, const double *jerk, double v,
                         double a, double *lo, double *hi)
{
	double q[MLIP_MAX_AXES];
	for (int k = 0; k < n; k++) {
		q[k] = 3.0 * c->d2[k] * v * a + c->d3[k] * v * v * v; /* (P2) but x'_k j */
	}
	return intersect(n, c->d1, q, jerk, lo, hi);
}

double mlip_path_vmax(int n, const struct mlip_path_point *c, const double *accel,
                      const double *jerk, double vmax)
{
	double v = vmax;
	for (int k = 0; k < n; k++) {
		double q = fabs(c->d2[k]);
		if (q * v * v > accel[k]) {
			v = sqrt(accel[k] / q); /* (P3) */
		}
		if (jerk) {
			double r = fabs(c->d3[k]);
			if (r * v * v * v > jerk[k]) {
				v = cbrt(jerk[k] / r);
			}
		}
	}
	return v;
}

static double dot(int n, const double *x, const double *y)
{
	double s = 0.0;
	for (int k = 0; k < n; k++) {
		s += x[k] * y[k];
	}
	return s;
}

/* (P4): derivatives by a parameter t (x_t, x_tt, x_ttt) turned into
 * derivatives by arc length. -1 where the curve stops (sigma = 0). */
static int to_arc(int n, const double *x1, const double *x2, const double *x3,
                  struct mlip_path_point *out)
{
	double sg = sqrt(dot(n, x1, x1));
	if (!(sg > 0.0)) {
		return -1;
	}
	double st = dot(n, x1, x2) / sg;
	double stt = (dot(n, x2, x2) + dot(n, x1, x3)) / sg - st * st / sg;
	double s2 = sg * sg, s3 = s2 * sg, s4 = s3 * sg;
	for (int k = 0; k < n; k++) { /* (P4) */
		out->d1[k] = x1[k] / sg;
		out->d2[k] = x2[k] / s2 - x1[k] * st / s3;
		out->d3[k] = (x3[k] / s2 - 3.0 * x2[k] * st / s3 - x1[k] * stt / s3 +
		              3.0 * x1[k] * st * st / s4) /
		             sg;
	}
	for (int k = n; k < MLIP_MAX_AXES; k++) {
		out->d1[k] = out->d2[k] = out->d3[k] = 0.0;
	}
	return 0;
}

int mlip_path_from_points(int n, const double p[4][MLIP_MAX_AXES], double t,
                          struct mlip_path_point *out)
{
	double s[4] = {0.0, 0.0, 0.0, 0.0};
	for (int i = 1; i < 4; i++) {
		double d2 = 0.0;
		for (int k = 0; k < n; k++) {
			double d = p[i][k] - p[i - 1][k];
			d2 += d * d;
		}
		if (!(d2 > 0.0)) {
			return -1;
		}
		s[i] = s[i - 1] + sqrt(d2);
	}
	double x1[MLIP_MAX_AXES], x2[MLIP_MAX_AXES], x3[MLIP_MAX_AXES];
	for (int k = 0; k < n; k++) {
		/* Newton's divided differences: x = c0 + c1 (t - s0) + c2 (t - s0)(t - s1)
		 * + c3 (t - s0)(t - s1)(t - s2) */
		double f01 = (p[1][k] - p[0][k]) / (s[1] - s[0]);
		double f12 = (p[2][k] - p[1][k]) / (s[2] - s[1]);
		double f23 = (p[3][k] - p[2][k]) / (s[3] - s[2]);
		double f012 = (f12 - f01) / (s[2] - s[0]);
		double f123 = (f23 - f12) / (s[3] - s[1]);
		double c3 = (f123 - f012) / (s[3] - s[0]);
		double u0 = t - s[0], u1 = t - s[1], u2 = t - s[2];
		x1[k] = f01 + f012 * (u0 + u1) + c3 * (u0 * u1 + u0 * u2 + u1 * u2);
		x2[k] = 2.0 * f012 + 2.0 * c3 * (u0 + u1 + u2);
		x3[k] = 6.0 * c3;
	}
	return to_arc(n, x1, x2, x3, out);
}

int mlip_path_spline_fit(struct mlip_path_spline *sp, int n, const double pts[][MLIP_MAX_AXES],
                         int count)
{
	if (count < 2 || count > MLIP_PATH_WIN || n < 1 || n > MLIP_MAX_AXES) {
		return -1;
	}
	sp->n = n;
	sp->count = count;
	sp->s[0] = 0.0;
	for (int i = 0; i < count; i++) {
		for (int k = 0; k < n; k++) {
			if (!isfinite(pts[i][k])) {
				return -1;
			}
			sp->p[i][k] = pts[i][k];
		}
		if (i > 0) {
			double d2 = 0.0;
			for (int k = 0; k < n; k++) {
				double d = pts[i][k] - pts[i - 1][k];
				d2 += d * d;
			}
			if (!(d2 > 0.0)) {
				return -1;
			}
			sp->s[i] = sp->s[i - 1] + sqrt(d2);
		}
	}
	/* (P5) by Thomas' algorithm: forward elimination into c (the
	 * super-diagonal over the pivot) and m (the right-hand side), rows 0
	 * and count - 1 the natural ends (M = 0) */
	int last = count - 1;
	sp->c[0] = 0.0;
	for (int k = 0; k < n; k++) {
		sp->m[0][k] = 0.0;
		sp->m[last][k] = 0.0;
	}
	for (int i = 1; i < last; i++) {
		double hl = sp->s[i] - sp->s[i - 1], hr = sp->s[i + 1] - sp->s[i];
		double piv = 2.0 * (hl + hr) - hl * sp->c[i - 1];
		sp->c[i] = hr / piv;
		for (int k = 0; k < n; k++) {
			double r = 6.0 * ((sp->p[i + 1][k] - sp->p[i][k]) / hr -
			                  (sp->p[i][k] - sp->p[i - 1][k]) / hl);
			sp->m[i][k] = (r - hl * sp->m[i - 1][k]) / piv;
		}
	}
	for (int i = last - 1; i >= 1; i--) { /* back substitution */
		for (int k = 0; k < n; k++) {
			sp->m[i][k] -= sp->c[i] * sp->m[i + 1][k];
		}
	}
	return 0;
}

int mlip_path_spline_eval(const struct mlip_path_spline *sp, double s, int by_arc, double *x,
                          struct mlip_path_point *d)
{
	int last = sp->count - 1, n = sp->n;
	s = s < 0.0 ? 0.0 : (s > sp->s[last] ? sp->s[last] : s);
	int lo = 0, hi = last; /* the segment [s_lo, s_lo+1] holding s */
	while (hi - lo > 1) {
		int mid = (lo + hi) / 2;
		if (sp->s[mid] <= s) {
			lo = mid;
		} else {
			hi = mid;
		}
	}
	double h = sp->s[lo + 1] - sp->s[lo], u = s - sp->s[lo];
	double x1[MLIP_MAX_AXES], x2[MLIP_MAX_AXES], x3[MLIP_MAX_AXES];
	for (int k = 0; k < n; k++) {
		double m0 = sp->m[lo][k], m1 = sp->m[lo + 1][k];
		double b = (sp->p[lo + 1][k] - sp->p[lo][k]) / h - h * (2.0 * m0 + m1) / 6.0;
		x3[k] = (m1 - m0) / h;
		x2[k] = m0 + x3[k] * u;
		x1[k] = b + m0 * u + 0.5 * x3[k] * u * u;
		if (x) {
			x[k] = sp->p[lo][k] + b * u + 0.5 * m0 * u * u + x3[k] * u * u * u / 6.0;
		}
	}
	if (by_arc) {
		return to_arc(n, x1, x2, x3, d);
	}
	for (int k = 0; k < MLIP_MAX_AXES; k++) {
		d->d1[k] = k < n ? x1[k] : 0.0;
		d->d2[k] = k < n ? x2[k] : 0.0;
		d->d3[k] = k < n ? x3[k] : 0.0;
	}
	return 0;
}
