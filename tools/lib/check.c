/*
 * check.c - see check.h. The contour search walks the polyline with the
 * samples: a sample's nearest segment is looked for from one segment behind
 * the previous one up to as far as the tool could have travelled (the
 * step plus a few eps, since corners cut inside). The distance found is to a
 * real segment of the polyline, so it can only over-state the true error.
 */
#include "check.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

static double seg_dist(int n, const double *x, const double *a, const double *b, double *len)
{
	double ab2 = 0.0, t = 0.0;
	for (int k = 0; k < n; k++) {
		double d = b[k] - a[k];
		ab2 += d * d;
		t += (x[k] - a[k]) * d;
	}
	*len = sqrt(ab2);
	t = ab2 > 0.0 ? fmin(fmax(t / ab2, 0.0), 1.0) : 0.0;
	double s = 0.0;
	for (int k = 0; k < n; k++) {
		double d = x[k] - (a[k] + t * (b[k] - a[k]));
		s += d * d;
	}
	return sqrt(s);
}

void mlip_check_init(struct mlip_check *c, const struct mlip_check_limits *lim,
                     const double *pts, size_t npts)
{
	memset(c, 0, sizeof(*c));
	c->lim = *lim;
	c->pts = pts;
	c->npts = npts;
	c->gap = 1;
}

void mlip_check_gap(struct mlip_check *c, size_t periods)
{
	if (periods > 1 && c->count > 0) {
		c->gap = periods;
		c->run = 0;
	}
}

static void contour(struct mlip_check *c, const double *x, double step)
{
	int n = c->lim.n;
	if (c->npts < 2) {
		return;
	}
	double reach = step + 8.0 * c->lim.eps_mm + 1e-6;
	size_t j = c->cursor >= 1 ? c->cursor - 1 : 0;
	size_t best_j = c->cursor;
	double best = INFINITY, ahead = 0.0;
	for (; j + 1 < c->npts; j++) {
		double len;
		double dist = seg_dist(n, x, c->pts + j * (size_t)n, c->pts + (j + 1) * (size_t)n, &len);
		/* ties go forward: a path that retraces itself must not pull the
		 * search back onto an earlier pass over the same line */
		if (dist <= best + 1e-9) {
			best = fmin(best, dist);
			best_j = j;
		}
		if (j > c->cursor) {
			ahead += len;
			if (ahead > reach) {
				break;
			}
		}
	}
	c->cursor = best_j;
	if (best > c->max_contour_mm) {
		c->max_contour_mm = best;
		c->max_contour_at = c->count;
	}
}

void mlip_check_sample(struct mlip_check *c, const double *x)
{
	int n = c->lim.n;
	double dt = c->lim.period_s * (double)c->gap; /* the time since the last sample */
	double T = c->lim.period_s;
	double step = 0.0, lin2 = 0.0, rot2 = 0.0;

	if (c->count >= 1) {
		for (int k = 0; k < n; k++) {
			double d = x[k] - c->x1[k];
			step += d * d;
			if (c->lim.rotary[k]) {
				rot2 += d * d;
			} else {
				lin2 += d * d;
			}
			double v = fabs(d) / dt;
			if (v > c->max_vel[k]) {
				c->max_vel[k] = v;
			}
		}
		step = sqrt(step);
		c->path_mm += sqrt(lin2);
		c->max_speed_mm_s = fmax(c->max_speed_mm_s, sqrt(lin2) / dt);
		if (lin2 == 0.0) {
			c->max_rot_speed_deg_s = fmax(c->max_rot_speed_deg_s, sqrt(rot2) / dt);
		}
	}
	if (c->run >= 2) {
		for (int k = 0; k < n; k++) {
			double acc = fabs(x[k] - 2.0 * c->x1[k] + c->x2[k]) / (T * T);
			if (acc > c->max_acc[k]) {
				c->max_acc[k] = acc;
				c->max_acc_at[k] = c->count;
			}
		}
	}
	for (int k = 0; k < n; k++) {
		c->max_abs_coord = fmax(c->max_abs_coord, fabs(x[k]));
	}
	/* across a hole the tool went at most v_max dt along the path, which
	 * may be longer than the chord between the two samples */
	contour(c, x, c->gap > 1 ? fmax(step, (c->lim.vmax_mm_s + c->lim.vmax_rot_deg_s) * dt) : step);
	c->gap = 1;
	c->run++;
	memcpy(c->x2, c->x1, sizeof(c->x1));
	memcpy(c->x1, x, sizeof(double) * (size_t)n);
	c->count++;
}

double mlip_check_end_error(const struct mlip_check *c)
{
	if (c->npts == 0 || c->count == 0) {
		return INFINITY;
	}
	const double *last = c->pts + (c->npts - 1) * (size_t)c->lim.n;
	double s = 0.0;
	for (int k = 0; k < c->lim.n; k++) {
		s += (c->x1[k] - last[k]) * (c->x1[k] - last[k]);
	}
	return sqrt(s);
}

double mlip_check_rounding_floor(const struct mlip_check *c)
{
	double T = c->lim.period_s;
	return 8.0 * c->max_abs_coord * DBL_EPSILON / (T * T);
}

double mlip_check_end_speed(const struct mlip_check *c)
{
	if (c->count < 2) {
		return 0.0;
	}
	double s = 0.0;
	for (int k = 0; k < c->lim.n; k++) {
		s += (c->x1[k] - c->x2[k]) * (c->x1[k] - c->x2[k]);
	}
	return sqrt(s) / c->lim.period_s;
}

static void add_msg(char *msg, size_t len, size_t *used, int *bad, const char *line)
{
	(*bad)++;
	if (*used < len) {
		int w = snprintf(msg + *used, len - *used, "%s\n", line);
		if (w > 0) {
			*used += (size_t)w;
		}
	}
}

int mlip_check_verdict(const struct mlip_check *c, double rel_tol, double abs_acc,
                       double abs_mm, double end_mm, char *msg, size_t len)
{
	const struct mlip_check_limits *l = &c->lim;
	char line[200];
	size_t used = 0;
	int bad = 0;
	if (len > 0) {
		msg[0] = '\0';
	}
	for (int k = 0; k < l->n; k++) {
		if (c->max_acc[k] > l->accel[k] * (1.0 + rel_tol) + abs_acc) {
			snprintf(line, sizeof(line),
			         "axis %d: acceleration %.12g exceeds %.12g at sample %zu", k,
			         c->max_acc[k], l->accel[k], c->max_acc_at[k]);
			add_msg(msg, len, &used, &bad, line);
		}
		if (c->max_vel[k] > l->vel[k] * (1.0 + rel_tol) + abs_acc * l->period_s) {
			snprintf(line, sizeof(line), "axis %d: velocity %.12g exceeds %.12g", k,
			         c->max_vel[k], l->vel[k]);
			add_msg(msg, len, &used, &bad, line);
		}
	}
	if (c->max_speed_mm_s > l->vmax_mm_s * (1.0 + rel_tol) + abs_acc * l->period_s) {
		snprintf(line, sizeof(line), "tool speed %.12g exceeds %.12g", c->max_speed_mm_s,
		         l->vmax_mm_s);
		add_msg(msg, len, &used, &bad, line);
	}
	if (c->max_rot_speed_deg_s > l->vmax_rot_deg_s * (1.0 + rel_tol) + abs_acc * l->period_s) {
		snprintf(line, sizeof(line), "rotary speed %.12g exceeds %.12g",
		         c->max_rot_speed_deg_s, l->vmax_rot_deg_s);
		add_msg(msg, len, &used, &bad, line);
	}
	if (c->max_contour_mm > l->eps_mm * (1.0 + rel_tol) + abs_mm) {
		snprintf(line, sizeof(line), "contour error %.12g exceeds %.12g at sample %zu",
		         c->max_contour_mm, l->eps_mm, c->max_contour_at);
		add_msg(msg, len, &used, &bad, line);
	}
	double end = mlip_check_end_error(c);
	if (!(end <= end_mm)) {
		snprintf(line, sizeof(line), "trace ends %.12g from the last point", end);
		add_msg(msg, len, &used, &bad, line);
	}
	return bad;
}
