/*
 * pathspeed.c - the per-axis limits of a path-speed plan along a curve
 * (mlip/motion/pathspeed.h: P1-P4).
 */
#include "mlip/motion/pathspeed.h"

#include <math.h>
#include <stddef.h>

/* The x with |p x + c| <= lim for every axis (p, c per axis): an
 * intersection of one interval per axis. 0 when empty. */
static int intersect(int n, const double *p, const double *c, const double *lim, double *lo,
                     double *hi)
{
	double l = -INFINITY, h = INFINITY;
	for (int k = 0; k < n; k++) {
		if (!mlip_path_axis_cut(p[k], c[k], lim[k], &l, &h)) {
			return 0; /* this axis alone exceeds its limit, whatever x */
		}
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

/* |b - a| over n axes: a chord, the parameter step between two points. */
static double chord(int n, const double *a, const double *b)
{
	double d2 = 0.0;
	for (int k = 0; k < n; k++) {
		double d = b[k] - a[k];
		d2 += d * d;
	}
	return sqrt(d2);
}

int mlip_path_from_points(int n, const double p[4][MLIP_MAX_AXES], double t,
                          struct mlip_path_point *out)
{
	double s[4] = {0.0, 0.0, 0.0, 0.0};
	for (int i = 1; i < 4; i++) {
		double h = chord(n, p[i - 1], p[i]);
		if (!(h > 0.0)) {
			return -1;
		}
		s[i] = s[i - 1] + h;
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

void mlip_path_tridiag(int n, const double *s, const double p[][MLIP_MAX_AXES], double *c,
                       double (*m)[MLIP_MAX_AXES], int f, int last)
{
	for (int i = f + 1; i < last; i++) { /* Thomas' forward elimination */
		double hl = s[i] - s[i - 1], hr = s[i + 1] - s[i];
		double piv = 2.0 * (hl + hr) - hl * c[i - 1];
		c[i] = hr / piv;
		for (int k = 0; k < n; k++) {
			double r =
			    6.0 * ((p[i + 1][k] - p[i][k]) / hr - (p[i][k] - p[i - 1][k]) / hl);
			m[i][k] = (r - hl * m[i - 1][k]) / piv;
		}
	}
	for (int k = 0; k < n; k++) {
		m[last][k] = 0.0; /* natural at the last knot */
	}
	for (int i = last - 1; i >= f; i--) { /* back substitution */
		for (int k = 0; k < n; k++) {
			m[i][k] -= c[i] * m[i + 1][k];
		}
	}
}

int mlip_path_fit(int n, const double pts[][MLIP_MAX_AXES], int count, double *s,
                  double (*p)[MLIP_MAX_AXES], double (*m)[MLIP_MAX_AXES],
                  double (*b)[MLIP_MAX_AXES], double (*t3)[MLIP_MAX_AXES], double *c,
                  struct mlip_path_curve *cv)
{
	if (count < 2 || n < 1 || n > MLIP_MAX_AXES) {
		return -1;
	}
	s[0] = 0.0;
	for (int i = 0; i < count; i++) {
		for (int k = 0; k < n; k++) {
			if (!isfinite(pts[i][k])) {
				return -1;
			}
			p[i][k] = pts[i][k];
		}
		if (i > 0) {
			double h = chord(n, pts[i - 1], pts[i]);
			if (!(h > 0.0)) {
				return -1;
			}
			s[i] = s[i - 1] + h;
		}
	}
	/* (P5) by Thomas' algorithm: forward elimination into c (the
	 * super-diagonal over the pivot) and m (the right-hand side), rows 0
	 * and count - 1 the natural ends (M = 0) */
	int last = count - 1;
	c[0] = 0.0;
	for (int k = 0; k < n; k++) {
		m[0][k] = 0.0;
	}
	mlip_path_tridiag(n, s, (const double(*)[MLIP_MAX_AXES])p, c, m, 0, last);
	/* each piece's cubic p + b u + m0 u^2 / 2 + t3 u^3 / 6 (u from its start) */
	for (int i = 0; i < last; i++) {
		double h = s[i + 1] - s[i];
		for (int k = 0; k < n; k++) {
			double m0 = m[i][k], m1 = m[i + 1][k];
			b[i][k] = (p[i + 1][k] - p[i][k]) / h - h * (2.0 * m0 + m1) / 6.0;
			t3[i][k] = (m1 - m0) / h;
		}
	}
	typedef const double(*row)[MLIP_MAX_AXES];
	*cv = (struct mlip_path_curve){n, count, s, (row)p, (row)m, (row)b, (row)t3, NULL};
	return 0;
}

void mlip_path_spline_curve(const struct mlip_path_spline *sp, struct mlip_path_curve *cv)
{
	*cv = (struct mlip_path_curve){sp->n, sp->count, sp->s, sp->p, sp->m, sp->b, sp->t3, NULL};
}

int mlip_path_spline_fit(struct mlip_path_spline *sp, int n, const double pts[][MLIP_MAX_AXES],
                         int count)
{
	struct mlip_path_curve cv;
	if (count > MLIP_PATH_WIN ||
	    mlip_path_fit(n, pts, count, sp->s, sp->p, sp->m, sp->b, sp->t3, sp->c, &cv) != 0) {
		return -1;
	}
	sp->n = n;
	sp->count = count;
	return 0;
}

int mlip_path_spline_piece(const struct mlip_path_curve *cv, double s, int hint)
{
	int last = cv->count - 1, i = hint < 0 ? 0 : (hint > last - 1 ? last - 1 : hint);
	for (int step = 0; step < 4; step++) { /* near the hint: a few steps */
		if (i < last - 1 && cv->s[i + 1] <= s) {
			i++;
		} else if (i > 0 && cv->s[i] > s) {
			i--;
		} else {
			return i;
		}
	}
	int lo = 0, hi = last; /* far from it: bisection, s_lo <= s < s_hi */
	if (cv->s[i] <= s) {
		lo = i;
	} else {
		hi = i;
	}
	while (hi - lo > 1) {
		int mid = (lo + hi) / 2;
		if (cv->s[mid] <= s) {
			lo = mid;
		} else {
			hi = mid;
		}
	}
	return lo;
}

void mlip_path_spline_eval_piece(const struct mlip_path_curve *cv, int i, double s, double *x,
                                 struct mlip_path_point *d)
{
	int last = cv->count - 1, n = cv->n;
	s = s < 0.0 ? 0.0 : (s > cv->s[last] ? cv->s[last] : s);
	double u = s - cv->s[i];
	for (int k = 0; k < n; k++) {
		double m0 = cv->m[i][k], t3 = cv->t3[i][k];
		d->d3[k] = t3;
		d->d2[k] = m0 + t3 * u;
		d->d1[k] = cv->b[i][k] + m0 * u + 0.5 * t3 * u * u;
		if (x) {
			x[k] =
			    cv->p[i][k] + cv->b[i][k] * u + 0.5 * m0 * u * u + t3 * u * u * u / 6.0;
		}
	}
}

double mlip_path_piece_sag(const struct mlip_path_curve *cv, int i)
{
	double h = cv->s[i + 1] - cv->s[i], q0 = 0.0, q1 = 0.0;
	for (int k = 0; k < cv->n; k++) {
		q0 += cv->m[i][k] * cv->m[i][k];
		q1 += cv->m[i + 1][k] * cv->m[i + 1][k];
	}
	return h * h / 8.0 * sqrt(q0 > q1 ? q0 : q1); /* (P6) */
}

int mlip_path_spline_eval(const struct mlip_path_spline *sp, double s, int by_arc, double *x,
                          struct mlip_path_point *d)
{
	int n = sp->n;
	struct mlip_path_point raw;
	struct mlip_path_curve cv;
	mlip_path_spline_curve(sp, &cv);
	mlip_path_spline_eval_piece(&cv, mlip_path_spline_piece(&cv, s, 0), s, x,
	                            by_arc ? &raw : d);
	if (by_arc) {
		return to_arc(n, raw.d1, raw.d2, raw.d3, d);
	}
	for (int k = n; k < MLIP_MAX_AXES; k++) {
		d->d1[k] = d->d2[k] = d->d3[k] = 0.0;
	}
	return 0;
}
