/*
 * check.c - see check.h for what is measured. The polyline's points live in
 * a ring; every MLIP_CHECK_CHUNK consecutive segments share an axis-aligned
 * bounding box (a one-level bounding-volume hierarchy that slides with the
 * ring). A sample's query visits the chunks whose path span meets its
 * window, skips those whose box is farther than max(best so far, tol), and
 * measures every segment of the others: the minimum over the window is exact
 * (a segment lies inside its box, so its distance is at least the box's).
 */
#include "check.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#define RING_MASK     ((uint64_t)MLIP_CHECK_RING - 1)
#define NCHUNK        (MLIP_CHECK_RING / MLIP_CHECK_CHUNK)
#define BOX_MARGIN_MM 1e-9       /* a box is skipped only when this much farther */
enum { HINT_A, HINT_R, HINT_B }; /* searches: window start, R, window end */

/* sizes must be powers of two (C99 has no _Static_assert) */
typedef char mlip_check_ring_pow2[(MLIP_CHECK_RING & (MLIP_CHECK_RING - 1)) == 0 ? 1 : -1];
typedef char mlip_check_chunk_pow2[(MLIP_CHECK_CHUNK & (MLIP_CHECK_CHUNK - 1)) == 0 &&
                                           MLIP_CHECK_CHUNK < MLIP_CHECK_RING
                                       ? 1
                                       : -1];

static double tol_of(const struct mlip_check *c)
{
	return c->lim.tol_mm > 0.0 ? c->lim.tol_mm : c->lim.eps_mm * (1.0 + 1e-9);
}

static double win_of(const struct mlip_check *c)
{
	return c->lim.window_mm > 0.0 ? c->lim.window_mm : MLIP_CHECK_WINDOW_MM;
}

static const double *pt_at(const struct mlip_check *c, uint64_t p)
{
	return c->pt[p & RING_MASK];
}

static double arc_at(const struct mlip_check *c, uint64_t p)
{
	return c->arc_mm[p & RING_MASK];
}

static void init_common(struct mlip_check *c, const struct mlip_check_limits *lim)
{
	memset(c, 0, sizeof(*c));
	c->lim = *lim;
	c->gap = 1;
	c->nset = 1; /* R_0: the start */
	/* a motion with |x''| <= A_k per axis is within A_k T^2 / 8 of the chord
	 * between its samples T apart */
	double a2 = 0.0;
	for (int k = 0; k < lim->n; k++) {
		a2 += lim->accel[k] * lim->accel[k];
	}
	c->chord_mm = sqrt(a2) * lim->period_s * lim->period_s / 8.0;
	for (int k = 0; k < lim->n; k++) {
		c->last_pt[k] = NAN; /* no point yet: no end */
	}
}

void mlip_check_init(struct mlip_check *c, const struct mlip_check_limits *lim, const double *pts,
                     size_t npts)
{
	init_common(c, lim);
	c->arr = pts;
	c->arr_n = npts;
	if (npts > 0) {
		memcpy(c->last_pt, pts + (npts - 1) * (size_t)lim->n,
		       sizeof(double) * (size_t)lim->n);
	}
}

void mlip_check_init_source(struct mlip_check *c, const struct mlip_check_limits *lim,
                            mlip_check_source_fn src, void *ctx)
{
	init_common(c, lim);
	c->src = src;
	c->src_ctx = ctx;
}

static void box_add(struct mlip_check *c, uint64_t chunk, const double *p, int fresh)
{
	size_t b = (size_t)(chunk % NCHUNK);
	for (int k = 0; k < c->lim.n; k++) {
		if (fresh) {
			c->box_lo[b][k] = p[k];
			c->box_hi[b][k] = p[k];
		} else {
			c->box_lo[b][k] = fmin(c->box_lo[b][k], p[k]);
			c->box_hi[b][k] = fmax(c->box_hi[b][k], p[k]);
		}
	}
}

/* Point hi of the polyline; the caller made room (hi - lo < RING). */
static void push_point(struct mlip_check *c, const double *p, uint32_t line)
{
	int n = c->lim.n;
	uint64_t k = c->hi;
	double arc = 0.0;
	if (k > 0) {
		const double *q = pt_at(c, k - 1);
		double d2 = 0.0, lin2 = 0.0;
		for (int a = 0; a < n; a++) {
			double d = p[a] - q[a];
			d2 += d * d;
			lin2 += c->lim.rotary[a] ? 0.0 : d * d;
		}
		arc = arc_at(c, k - 1) + sqrt(d2);
		c->prog_mm += sqrt(lin2);
		box_add(c, (k - 1) / MLIP_CHECK_CHUNK, p, 0); /* end of segment k - 1 */
	}
	box_add(c, k / MLIP_CHECK_CHUNK, p, k % MLIP_CHECK_CHUNK == 0); /* start of segment k */
	memcpy(c->pt[k & RING_MASK], p, sizeof(double) * (size_t)n);
	c->arc_mm[k & RING_MASK] = arc;
	c->line[k & RING_MASK] = line;
	if (c->src != NULL) {
		memcpy(c->last_pt, p, sizeof(double) * (size_t)n);
	}
	c->hi++;
}

/* Take the next point from the source: 1, or 0 when there is none. */
static int pull(struct mlip_check *c)
{
	double p[MLIP_MAX_AXES] = {0};
	uint32_t line = 0;
	int r = 0;
	if (c->src_done) {
		return 0;
	}
	if (c->src != NULL) {
		r = c->src(c->src_ctx, p, &line);
	} else if (c->arr_i < c->arr_n) {
		memcpy(p, c->arr + c->arr_i * (size_t)c->lim.n, sizeof(double) * (size_t)c->lim.n);
		line = (uint32_t)c->arr_i;
		c->arr_i++;
		r = 1;
	}
	if (r <= 0) {
		c->src_done = 1;
		c->src_error = r < 0;
		return 0;
	}
	push_point(c, p, line);
	return 1;
}

/* The ring is full: drop its oldest chunk if no window reaches it, else drop
 * the positions of R furthest behind (the samples' earliest possibilities)
 * so that it can go. 0 when R cannot give way (its whole hull is there). */
static int make_room(struct mlip_check *c, double *wa)
{
	double cut = arc_at(c, c->lo + MLIP_CHECK_CHUNK);
	if (cut > *wa) {
		double keep = cut + win_of(c);
		if (c->set[c->nset - 1].hi_mm < keep) {
			return 0;
		}
		int i = 0;
		while (c->set[i].hi_mm < keep) {
			i++;
		}
		memmove(c->set, c->set + i, sizeof(c->set[0]) * (size_t)(c->nset - i));
		c->nset -= i;
		c->set[0].lo_mm = fmax(c->set[0].lo_mm, keep);
		c->window_drops++;
		*wa = c->set[0].lo_mm - win_of(c);
	}
	c->lo += MLIP_CHECK_CHUNK;
	return 1;
}

static void set_add(struct mlip_check_iv *s, int *ns, double lo, double hi)
{
	if (*ns > 0 && lo <= s[*ns - 1].hi_mm) {
		s[*ns - 1].hi_mm = fmax(s[*ns - 1].hi_mm, hi);
	} else if (*ns == MLIP_CHECK_MAX_SET) {
		s[*ns - 1].hi_mm = fmax(s[*ns - 1].hi_mm, hi); /* hull: R only grows */
	} else {
		s[*ns].lo_mm = lo;
		s[*ns].hi_mm = hi;
		(*ns)++;
	}
}

/* One search of the window for a sample. */
struct query {
	const double *x;
	uint64_t ja, jb; /* segments of the window */
	double best2, best_s, near_mm;
	uint64_t best_j;
};

/* The first point at path position >= s in [lo, hi) (hi when none). The
 * searches of one sample land close to those of the last: gallop from the
 * last answer of the same kind (which: HINT_*), then bisect. */
static uint64_t point_at_or_after(struct mlip_check *c, double s, int which)
{
	uint64_t a = c->lo, b = c->hi, h = c->hint[which];
	if (h > a && h < b) {
		uint64_t step = 1;
		if (arc_at(c, h) < s) {
			while (h + step < b && arc_at(c, h + step) < s) {
				h += step;
				step *= 2;
			}
			a = h + 1;
			b = h + step < b ? h + step + 1 : b;
		} else {
			while (step < h - a && arc_at(c, h - step) >= s) {
				h -= step;
				step *= 2;
			}
			b = h;
			a = step < h - a ? h - step : a;
		}
	}
	while (a < b) {
		uint64_t m = a + (b - a) / 2;
		if (arc_at(c, m) < s) {
			a = m + 1;
		} else {
			b = m;
		}
	}
	c->hint[which] = a;
	return a;
}

/* The segment holding path position s (the first or last one beyond). */
static uint64_t segment_at(struct mlip_check *c, double s, int which)
{
	uint64_t p = point_at_or_after(c, s, which);
	return p > c->lo ? p - 1 : c->lo;
}

/* Measure every segment of the window in a chunk whose box is within
 * radius of x (radius < 0: within the best distance so far); keep the
 * nearest. */
static void scan(const struct mlip_check *c, struct query *q, double radius)
{
	const int n = c->lim.n;
	const double *x = q->x;
	for (uint64_t ch = q->ja / MLIP_CHECK_CHUNK; ch <= q->jb / MLIP_CHECK_CHUNK; ch++) {
		uint64_t a = ch * MLIP_CHECK_CHUNK, b = a + MLIP_CHECK_CHUNK - 1;
		a = a < q->ja ? q->ja : a;
		b = b > q->jb ? q->jb : b;
		const double *lo = c->box_lo[ch % NCHUNK], *hi = c->box_hi[ch % NCHUNK];
		double r = (radius < 0.0 ? sqrt(q->best2) : radius) + BOX_MARGIN_MM, box2 = 0.0;
		for (int k = 0; k < n && box2 <= r * r; k++) {
			double d = x[k] < lo[k] ? lo[k] - x[k] : x[k] > hi[k] ? x[k] - hi[k] : 0.0;
			box2 += d * d;
		}
		if (box2 > r * r) {
			continue;
		}
		for (uint64_t j = a; j <= b; j++) {
			const double *p = pt_at(c, j), *e = pt_at(c, j + 1);
			int far = 0; /* farther than r along one axis: farther than r */
			for (int k = 0; k < n && !far; k++) {
				double a0 = p[k] < e[k] ? p[k] : e[k],
				       a1 = p[k] < e[k] ? e[k] : p[k];
				far = x[k] < a0 - r || x[k] > a1 + r;
			}
			if (far) {
				continue;
			}
			double len2 = 0.0, dot = 0.0;
			for (int k = 0; k < n; k++) {
				double d = e[k] - p[k];
				len2 += d * d;
				dot += (x[k] - p[k]) * d;
			}
			double t = len2 > 0.0 ? fmin(fmax(dot / len2, 0.0), 1.0) : 0.0;
			double d2 = 0.0;
			for (int k = 0; k < n; k++) {
				double d = x[k] - (p[k] + t * (e[k] - p[k]));
				d2 += d * d;
			}
			double s0 = arc_at(c, j), s = s0 + t * (arc_at(c, j + 1) - s0);
			/* ties go to the position nearest the last one */
			if (d2 < q->best2 || (d2 == q->best2 && fabs(s - q->near_mm) <
			                                            fabs(q->best_s - q->near_mm))) {
				q->best2 = d2;
				q->best_s = s;
				q->best_j = j;
			}
		}
	}
}

/* The u in [0, 1] with |a + u (b - a) - x| <= tol (a convex set): 1 and
 * [*u0, *u1], or 0 when there is none. */
static int within(int n, const double *a, const double *b, const double *x, double tol2, double *u0,
                  double *u1)
{
	double len2 = 0.0, dot = 0.0, ax2 = 0.0;
	for (int k = 0; k < n; k++) {
		double d = b[k] - a[k], w = x[k] - a[k];
		len2 += d * d;
		dot += w * d;
		ax2 += w * w;
	}
	if (len2 == 0.0) {
		*u0 = 0.0;
		*u1 = 1.0;
		return ax2 <= tol2;
	}
	/* |a - x|^2 - 2 u dot + u^2 len2 <= tol^2 */
	double disc = dot * dot - len2 * (ax2 - tol2);
	if (disc < 0.0) {
		return 0;
	}
	double sq = sqrt(disc);
	*u0 = fmax((dot - sq) / len2, 0.0);
	*u1 = fmin((dot + sq) / len2, 1.0);
	return *u0 <= *u1;
}

/* Room for one more point without dropping anything from path position wa
 * on: 1, or 0 when the ring is full up to there. */
static int room_from(struct mlip_check *c, double wa)
{
	if (c->hi - c->lo < MLIP_CHECK_RING) {
		return 1;
	}
	if (arc_at(c, c->lo + MLIP_CHECK_CHUNK) <= wa) {
		c->lo += MLIP_CHECK_CHUNK;
		return 1;
	}
	return 0;
}

/* Pull points until point p is in the ring (keeping wa on): 1 when it is. */
static int reach_point(struct mlip_check *c, uint64_t p, double wa)
{
	while (c->hi <= p && !c->src_done && room_from(c, wa) && pull(c)) {
	}
	return p < c->hi;
}

/* R_i from R_{i-1} (c->set) as the trace goes from x0 to x1 in a straight
 * line (see check.h): the free space of a segment of the polyline against
 * the chord, {(u, tau): |P(u) - x(tau)| <= tol}, is convex, so a position u'
 * at tau = 1 is reachable from a reachable (u, 0) with u' >= u, or from any
 * reachable point of the segment's start (its left side), and the start of
 * the next segment from either (Alt and Godau's free-space propagation).
 * Returns the positions reached (*frontier: how far the sweep went). */
static int propagate(struct mlip_check *c, const double *x0, const double *x1, double tol2,
                     double wa, struct mlip_check_iv *out, double *frontier)
{
	const int n = c->lim.n;
	const struct mlip_check_iv *r = c->set;
	int nout = 0, k = 0, have_l = 0;
	double l = 0.0;
	uint64_t j = segment_at(c, r[0].lo_mm, HINT_R);
	*frontier = r[c->nset - 1].hi_mm;
	while (reach_point(c, j + 1, wa)) {
		double s0 = arc_at(c, j), s1 = arc_at(c, j + 1);
		while (k < c->nset && r[k].hi_mm < s0) {
			k++;
		}
		int have_b = k < c->nset && r[k].lo_mm <= s1; /* R_{i-1} on this segment */
		double b = have_b ? fmax(r[k].lo_mm, s0) : 0.0;
		if (!have_b && !have_l) {
			if (k >= c->nset) {
				break;
			}
			j = segment_at(c, r[k].lo_mm, HINT_R); /* on to the next part of R_{i-1} */
			continue;
		}
		const double *p = pt_at(c, j), *e = pt_at(c, j + 1);
		double u0, u1;
		if (within(n, p, e, x1, tol2, &u0, &u1)) {
			double lo = s0 + u0 * (s1 - s0), hi = s0 + u1 * (s1 - s0);
			lo = have_l ? lo : fmax(lo, b);
			if (lo <= hi) {
				set_add(out, &nout, lo, hi);
			}
		}
		double t0, t1, right = INFINITY;
		if (within(n, x0, x1, e, tol2, &t0, &t1)) {
			right = have_b ? t0 : right;
			if (have_l && fmax(t0, l) <= t1) {
				right = fmin(right, fmax(t0, l));
			}
		}
		*frontier = fmax(*frontier, s1);
		have_l = right < INFINITY;
		l = right;
		j++;
	}
	return nout;
}

/* Across a hole the way between the samples is unknown: R_i is what is
 * within tol of x1 at most reach ahead of R_{i-1}. */
static int jump(struct mlip_check *c, const double *x1, double tol2, double reach, double wa,
                struct mlip_check_iv *out, double *frontier)
{
	const double lo_mm = c->set[0].lo_mm, hi_mm = c->set[c->nset - 1].hi_mm + reach;
	int nout = 0;
	*frontier = hi_mm;
	for (uint64_t j = segment_at(c, lo_mm, HINT_R); reach_point(c, j + 1, wa); j++) {
		double s0 = arc_at(c, j), s1 = arc_at(c, j + 1), u0, u1;
		if (s0 > hi_mm) {
			break;
		}
		if (within(c->lim.n, pt_at(c, j), pt_at(c, j + 1), x1, tol2, &u0, &u1)) {
			double a = fmax(s0 + u0 * (s1 - s0), lo_mm),
			       b = fmin(s0 + u1 * (s1 - s0), hi_mm);
			if (a <= b) {
				set_add(out, &nout, a, b);
			}
		}
	}
	return nout;
}

/* Contour error of x and R_i (see check.h); hole_reach > 0: x follows a
 * hole in which the tool could go that far along the path. */
static void contour(struct mlip_check *c, const double *x, double hole_reach)
{
	const double tol = tol_of(c);
	const double win = win_of(c);
	double wa = c->set[0].lo_mm - win;

	/* the polyline as far as the window goes, before the sweep */
	while (c->hi < 2 ||
	       (!c->src_done && arc_at(c, c->hi - 1) < c->set[c->nset - 1].hi_mm + win)) {
		if (c->hi - c->lo == MLIP_CHECK_RING && !make_room(c, &wa)) {
			c->window_drops++;
			break;
		}
		if (!pull(c)) {
			break;
		}
	}
	if (c->hi - c->lo < 2) {
		return;
	}
	struct mlip_check_iv r[MLIP_CHECK_MAX_SET];
	int nr;
	double frontier;
	if (c->count == 0) {
		nr = jump(c, x, tol * tol, 0.0, wa, r, &frontier);
	} else if (hole_reach > 0.0 || c->restart) {
		/* after samples beyond tol, from where the last good one left R,
		 * as across a hole (the chords from them are not judged again) */
		double since = (double)(c->periods - c->good_period) * c->lim.period_s;
		double travel =
		    2.0 * (c->lim.vmax_mm_s + c->lim.vmax_rot_deg_s) * since + 8.0 * tol;
		nr = jump(c, x, tol * tol, fmax(hole_reach, travel), wa, r, &frontier);
	} else {
		double tf = tol + c->chord_mm;
		nr = propagate(c, c->x1, x, tf * tf, wa, r, &frontier);
	}
	/* the window: W before R_{i-1} to W beyond the sweep */
	double wb = frontier + win;
	while (!c->src_done && arc_at(c, c->hi - 1) < wb && room_from(c, wa) && pull(c)) {
	}
	uint64_t ja = segment_at(c, wa, HINT_A), pb = point_at_or_after(c, wb, HINT_B);
	uint64_t jb = pb < c->hi && arc_at(c, pb) == wb ? pb : pb > c->lo ? pb - 1 : c->lo;
	jb = jb > c->hi - 2 ? c->hi - 2 : jb;
	jb = jb < ja ? ja : jb;
	struct query q = {.x = x,
	                  .ja = ja,
	                  .jb = jb,
	                  .best2 = INFINITY,
	                  .best_s = c->near_mm,
	                  .near_mm = c->near_mm,
	                  .best_j = ja};
	/* within tol first; beyond it, the whole window pruned by the best */
	scan(c, &q, tol);
	if (!(q.best2 <= tol * tol)) {
		scan(c, &q, -1.0);
	}
	double err = sqrt(q.best2);
	c->cur_line = c->line[(q.best_j + 1) & RING_MASK];
	c->restart = !(err <= tol);
	if (c->restart) {
		nr = 0; /* a contour error: R stays where the last good sample left it */
	} else if (nr == 0) {
		if (c->order_errors++ == 0) {
			c->order_at = c->count;
			c->order_period = c->periods;
			c->order_line = c->cur_line;
		}
		r[0].lo_mm = q.best_s; /* start again from where the sample is */
		r[0].hi_mm = q.best_s;
		nr = 1;
	}
	if (nr > 0) {
		memcpy(c->set, r, sizeof(r[0]) * (size_t)nr);
		c->nset = nr;
		c->good_period = c->periods;
	}
	c->near_mm = q.best_s;
	c->last_contour_mm = err;
	if (err > c->max_contour_mm) {
		c->max_contour_mm = err;
		c->max_contour_at = c->count;
		c->max_contour_period = c->periods;
		c->max_contour_line = c->cur_line;
	}
}

void mlip_check_gap(struct mlip_check *c, size_t periods)
{
	if (periods > 1 && c->count > 0) {
		c->gap = periods;
		c->run = 0;
	}
}

void mlip_check_sample(struct mlip_check *c, const double *x)
{
	int n = c->lim.n;
	double dt = c->lim.period_s * (double)c->gap; /* the time since the last sample */
	double T = c->lim.period_s;
	double step = 0.0, lin2 = 0.0, rot2 = 0.0;

	if (c->count >= 1) {
		c->periods += c->gap;
		for (int k = 0; k < n; k++) {
			double d = x[k] - c->x1[k];
			step += d * d;
			if (c->lim.rotary[k]) {
				rot2 += d * d;
			} else {
				lin2 += d * d;
			}
		}
		step = sqrt(step);
	}
	/* across a hole the tool went at most v_max dt, which may be longer
	 * than the chord between the two samples; corners cut add to the way
	 * along the path (twice the travel, and 8 tol) */
	double hole = c->gap > 1
	                  ? 2.0 * fmax(step, (c->lim.vmax_mm_s + c->lim.vmax_rot_deg_s) * dt) +
	                        8.0 * tol_of(c)
	                  : 0.0;
	contour(c, x, hole);
	if (c->count >= 1) {
		for (int k = 0; k < n; k++) {
			double v = fabs(x[k] - c->x1[k]) / dt;
			if (v > c->max_vel[k]) {
				c->max_vel[k] = v;
				c->max_vel_at[k] = c->count;
			}
		}
		c->path_mm += sqrt(lin2);
		if (sqrt(lin2) / dt > c->max_speed_mm_s) {
			c->max_speed_mm_s = sqrt(lin2) / dt;
			c->max_speed_at = c->count;
		}
		if (lin2 == 0.0) {
			c->max_rot_speed_deg_s = fmax(c->max_rot_speed_deg_s, sqrt(rot2) / dt);
		}
	}
	if (c->run >= 3) {
		for (int k = 0; k < n; k++) {
			double jerk =
			    fabs(x[k] - 3.0 * c->x1[k] + 3.0 * c->x2[k] - c->x3[k]) / (T * T * T);
			if (jerk > c->max_jerk[k]) {
				c->max_jerk[k] = jerk;
				c->max_jerk_at[k] = c->count;
				c->max_jerk_period[k] = c->periods;
				c->max_jerk_line[k] = c->cur_line;
			}
		}
	}
	if (c->run >= 2) {
		for (int k = 0; k < n; k++) {
			double acc = fabs(x[k] - 2.0 * c->x1[k] + c->x2[k]) / (T * T);
			if (acc > c->max_acc[k]) {
				c->max_acc[k] = acc;
				c->max_acc_at[k] = c->count;
				c->max_acc_period[k] = c->periods;
				c->max_acc_line[k] = c->cur_line;
			}
		}
	}
	for (int k = 0; k < n; k++) {
		c->max_abs_coord = fmax(c->max_abs_coord, fabs(x[k]));
	}
	c->gap = 1;
	c->run++;
	memcpy(c->x3, c->x2, sizeof(c->x2));
	memcpy(c->x2, c->x1, sizeof(c->x1));
	memcpy(c->x1, x, sizeof(double) * (size_t)n);
	c->count++;
}

void mlip_check_finish(struct mlip_check *c)
{
	while (!c->src_done) {
		if (c->hi - c->lo == MLIP_CHECK_RING) {
			c->lo += MLIP_CHECK_CHUNK; /* no sample will look here again */
		}
		if (!pull(c)) {
			break;
		}
	}
}

double mlip_check_end_error(const struct mlip_check *c)
{
	if ((c->src != NULL && c->hi == 0) || (c->src == NULL && c->arr_n == 0) || c->count == 0) {
		return INFINITY;
	}
	double s = 0.0;
	for (int k = 0; k < c->lim.n; k++) {
		s += (c->x1[k] - c->last_pt[k]) * (c->x1[k] - c->last_pt[k]);
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

int mlip_check_verdict(const struct mlip_check *c, double rel_tol, double abs_acc, double abs_mm,
                       double end_mm, char *msg, size_t len)
{
	const struct mlip_check_limits *l = &c->lim;
	const double T = l->period_s;
	char line[256];
	size_t used = 0;
	int bad = 0;
	if (len > 0) {
		msg[0] = '\0';
	}
	for (int k = 0; k < l->n; k++) {
		if (c->max_acc[k] > l->accel[k] * (1.0 + rel_tol) + abs_acc) {
			snprintf(
			    line, sizeof(line),
			    "axis %d: acceleration %.12g exceeds %.12g at sample %zu (t = %.6f s), "
			    "block of line %u",
			    k, c->max_acc[k], l->accel[k], c->max_acc_at[k],
			    (double)c->max_acc_period[k] * T, (unsigned)c->max_acc_line[k]);
			add_msg(msg, len, &used, &bad, line);
		}
		if (l->jerk[k] > 0.0 &&
		    c->max_jerk[k] > l->jerk[k] * (1.0 + rel_tol) + 2.0 * abs_acc / T) {
			snprintf(line, sizeof(line),
			         "axis %d: jerk %.12g exceeds %.12g at sample %zu (t = %.6f s), "
			         "block of line %u",
			         k, c->max_jerk[k], l->jerk[k], c->max_jerk_at[k],
			         (double)c->max_jerk_period[k] * T, (unsigned)c->max_jerk_line[k]);
			add_msg(msg, len, &used, &bad, line);
		}
		if (c->max_vel[k] > l->vel[k] * (1.0 + rel_tol) + abs_acc * T) {
			snprintf(line, sizeof(line),
			         "axis %d: velocity %.12g exceeds %.12g at sample %zu", k,
			         c->max_vel[k], l->vel[k], c->max_vel_at[k]);
			add_msg(msg, len, &used, &bad, line);
		}
	}
	if (c->max_speed_mm_s > l->vmax_mm_s * (1.0 + rel_tol) + abs_acc * T) {
		snprintf(line, sizeof(line), "tool speed %.12g exceeds %.12g at sample %zu",
		         c->max_speed_mm_s, l->vmax_mm_s, c->max_speed_at);
		add_msg(msg, len, &used, &bad, line);
	}
	if (c->max_rot_speed_deg_s > l->vmax_rot_deg_s * (1.0 + rel_tol) + abs_acc * T) {
		snprintf(line, sizeof(line), "rotary speed %.12g exceeds %.12g",
		         c->max_rot_speed_deg_s, l->vmax_rot_deg_s);
		add_msg(msg, len, &used, &bad, line);
	}
	if (c->max_contour_mm > l->eps_mm * (1.0 + rel_tol) + abs_mm) {
		snprintf(line, sizeof(line),
		         "contour error %.12g exceeds %.12g at sample %zu (t = %.6f s), "
		         "nearest block: line %u",
		         c->max_contour_mm, l->eps_mm, c->max_contour_at,
		         (double)c->max_contour_period * T, (unsigned)c->max_contour_line);
		add_msg(msg, len, &used, &bad, line);
	}
	if (c->order_errors > 0) {
		snprintf(
		    line, sizeof(line),
		    "order: %zu sample(s) not reachable forwards along the path from the last, "
		    "the first at sample %zu (t = %.6f s), near the block of line %u",
		    c->order_errors, c->order_at, (double)c->order_period * T,
		    (unsigned)c->order_line);
		add_msg(msg, len, &used, &bad, line);
	}
	if (c->src_error) {
		add_msg(msg, len, &used, &bad,
		        "the program's polyline could not be read to its end");
	}
	double end = mlip_check_end_error(c);
	if (!(end <= end_mm)) {
		snprintf(line, sizeof(line), "trace ends %.12g from the last point", end);
		add_msg(msg, len, &used, &bad, line);
	}
	return bad;
}
