/*
 * pathrun.c - the path-speed plan over a stream of setpoints (see
 * mlip/motion/pathrun.h).
 */
#include "mlip/motion/pathrun.h"

#include <math.h>
#include <string.h>

static double chord(int n, const double *a, const double *b)
{
	double q = 0.0;
	for (int k = 0; k < n; k++) {
		q += (b[k] - a[k]) * (b[k] - a[k]);
	}
	return sqrt(q);
}

void mlip_pathrun_curve(const struct mlip_pathrun *pr, struct mlip_path_curve *cv)
{
	typedef const double(*row)[MLIP_MAX_AXES];
	*cv = (struct mlip_path_curve){pr->lim.n,  pr->fixed + 1, pr->s,       (row)pr->p,
	                               (row)pr->m, (row)pr->b,    (row)pr->t3, pr->cap};
}

int mlip_pathrun_init(struct mlip_pathrun *pr, const struct mlip_path_limits *lim, double band_mm,
                      int max_periods, const double *start)
{
	int n = lim->n;
	if (n < 1 || n > MLIP_MAX_AXES || !(band_mm > 0.0) || !(lim->period > 0.0) ||
	    !(lim->vmax > 0.0) || max_periods < 1) {
		return -1;
	}
	for (int k = 0; k < n; k++) {
		if (!(lim->accel[k] > 0.0) || !(lim->jerk[k] > 0.0) || !isfinite(start[k])) {
			return -1;
		}
	}
	memset(pr, 0, sizeof(*pr));
	pr->lim = *lim;
	if (!(pr->lim.vfull > 0.0)) {
		pr->lim.vfull = lim->vmax; /* (Q5) a later cap (planq.h) scales the knots' */
	}
	pr->band_mm = band_mm;
	pr->max_periods = max_periods;
	memcpy(pr->p[0], start, sizeof(double) * (size_t)n);
	memcpy(pr->last_in, start, sizeof(double) * (size_t)n);
	pr->count = 1;
	pr->peak_count = 1;
	pr->keep_s = INFINITY;
	memcpy(pr->fr_p[0], start, sizeof(double) * (size_t)n);
	pr->fr_hi = 1; /* the start, the first knot already */
	pr->fr_c = 1;
	return 0;
}

/* (P5) over knots fixed..count-1, clamped at `fixed` to the fixed piece's
 * x' there (natural at the program's start), natural at the newest point;
 * then fix the pieces up to `upto` (their b, t3; the knots' m) and check
 * each by (P6). */
static int settle(struct mlip_pathrun *pr, int upto)
{
	int n = pr->lim.n, f = pr->fixed, last = pr->count - 1;
	double *c = pr->c, (*m)[MLIP_MAX_AXES] = pr->m;
	const double *s = pr->s;
	const double(*p)[MLIP_MAX_AXES] = (const double(*)[MLIP_MAX_AXES])pr->p;
	/* row f */
	double h0 = s[f + 1] - s[f];
	if (f == 0) {
		c[f] = 0.0;
		for (int k = 0; k < n; k++) {
			m[f][k] = 0.0;
		}
	} else {
		/* 2 h M_f + h M_f+1 = 6 ((p_f+1 - p_f) / h - x'_f), x'_f the fixed
		 * piece f - 1's at its end */
		double hl = s[f] - s[f - 1];
		c[f] = 0.5;
		for (int k = 0; k < n; k++) {
			double d = pr->b[f - 1][k] + pr->m[f - 1][k] * hl +
			           0.5 * pr->t3[f - 1][k] * hl * hl;
			m[f][k] = 6.0 * ((p[f + 1][k] - p[f][k]) / h0 - d) / (2.0 * h0);
		}
	}
	mlip_path_tridiag(n, s, p, c, m, f, last);
	struct mlip_path_curve cv;
	for (int i = f; i < upto; i++) {
		double h = s[i + 1] - s[i];
		for (int k = 0; k < n; k++) {
			pr->b[i][k] =
			    (p[i + 1][k] - p[i][k]) / h - h * (2.0 * m[i][k] + m[i + 1][k]) / 6.0;
			pr->t3[i][k] = (m[i + 1][k] - m[i][k]) / h;
		}
		pr->fixed = i + 1;
		mlip_pathrun_curve(pr, &cv);
		double g = mlip_path_piece_sag(&cv, i);
		pr->max_sag_mm = fmax(pr->max_sag_mm, g);
		/* the chord between two knots lies within the larger of their
		 * moves of the input's chord: the band less it is the spline's */
		if (!(g + fmax(pr->dev[i], pr->dev[i + 1]) <= pr->band_mm)) {
			pr->fixed = i; /* not taken */
			pr->why =
			    "a spline piece strays from its chord by more than the band (P6), "
			    "its sag and its knots' fairing moves together";
			pr->why_s = s[i];
			pr->why_mm =
			    g + fmax(pr->dev[i], pr->dev[i + 1]); /* what the band is held to */
			return -1;
		}
	}
	return 0;
}

long mlip_pathrun_lag_knot(const struct mlip_pathrun *pr)
{
	if (pr->lag_n < MLIP_PATHRUN_LAG) {
		return 0;
	}
	/* the oldest period held: lag_n - LAG + 1 (its slot, the next written) */
	long k = pr->lag_piece[pr->lag_n % MLIP_PATHRUN_LAG] - MLIP_PATHRUN_BEHIND;
	return k > 0 ? k : 0;
}

/* A planned period's piece (global) into the lag's history. */
static void note_period(struct mlip_pathrun *pr)
{
	long piece = (long)pr->dropped + pr->hint;
	pr->lag_max = piece > pr->lag_max ? piece : pr->lag_max;
	pr->lag_piece[pr->lag_n % MLIP_PATHRUN_LAG] = pr->lag_max;
	pr->lag_n++;
}

/* Drop the pieces the plan has passed when it is a quarter of the window
 * in: 1 when room was made. s stays global: the plan's state is unmoved.
 * What it keeps is a function of the plan's own periods (the lag's knot),
 * never of a consumer's timing, so that every consumer sees the plan
 * mlip-sim runs. */
static int compact(struct mlip_pathrun *pr)
{
	struct mlip_path_curve cv;
	mlip_pathrun_curve(pr, &cv);
	/* keep_s: a planned queue's consumer may still brake there (planq.h) */
	double from = pr->st.s < pr->keep_s ? pr->st.s : pr->keep_s;
	int i = pr->fixed > 0 ? mlip_path_spline_piece(&cv, from, pr->hint) : 0;
	long lag = mlip_pathrun_lag_knot(pr) - pr->dropped;
	i = lag < i ? (lag > 0 ? (int)lag : 0) : i;
	if (i < MLIP_PATHRUN_CAP / 4) {
		return 0;
	}
	int keep = pr->count - i;
	size_t row = sizeof(pr->p[0]);
	memmove(pr->s, pr->s + i, sizeof(double) * (size_t)keep);
	memmove(pr->p, pr->p + i, row * (size_t)keep);
	memmove(pr->m, pr->m + i, row * (size_t)keep);
	memmove(pr->b, pr->b + i, row * (size_t)keep);
	memmove(pr->t3, pr->t3 + i, row * (size_t)keep);
	memmove(pr->tag, pr->tag + i, sizeof(pr->tag[0]) * (size_t)keep);
	memmove(pr->dev, pr->dev + i, sizeof(double) * (size_t)keep);
	memmove(pr->cap, pr->cap + i, sizeof(double) * (size_t)keep);
	pr->count = keep;
	pr->fixed -= i;
	pr->hint = 0;
	pr->dropped += i;
	return 1;
}

/* A knot at pos, dev mm from its input point, the caller's mark tag: 0
 * taken (or skipped: within MIN_STEP of the last), 1 the window is full,
 * -1 refused. */
static int append(struct mlip_pathrun *pr, const double *pos, double dev,
                  const struct mlip_pathrun_tag *tag)
{
	int n = pr->lim.n;
	double h = chord(n, pr->p[pr->count - 1], pos);
	if (h < MLIP_PATHRUN_MIN_STEP) {
		return 0; /* at rest, or nearly: finish takes the last one */
	}
	if (pr->count == MLIP_PATHRUN_CAP && !compact(pr)) {
		return 1;
	}
	int i = pr->count++;
	memcpy(pr->p[i], pos, sizeof(double) * (size_t)n);
	pr->s[i] = pr->s[i - 1] + h;
	pr->tag[i] = *tag;
	pr->cap[i] = tag->cap;
	pr->dev[i] = dev;
	pr->max_dev_mm = fmax(pr->max_dev_mm, dev);
	pr->peak_count = pr->count > pr->peak_count ? pr->count : pr->peak_count;
	int upto = pr->count - 1 - MLIP_PATHRUN_SETTLE;
	return upto > pr->fixed ? settle(pr, upto) : 0;
}

int mlip_pathrun_fair(struct mlip_pathrun *pr, double h_mm, int k, double fair_mm)
{
	if (!(h_mm >= 0.0) || k < 0 || !(fair_mm > 0.0 && fair_mm < pr->band_mm) || pr->fr_hi > 1) {
		return -1;
	}
	pr->fair_h = h_mm;
	pr->fair_k = k;
	pr->fair_mm = fair_mm;
	return 0;
}

#define FR(i) ((int)((i) % MLIP_PATHRUN_FAIR_CAP))

/* (F1) the knot of input point c: per axis the value at c of the quadratic
 * in u = (s - s_c) / hc fitted by least squares to the points within hc of
 * it, weighted (1 - u^2)^3 (zero with its first two derivatives at the
 * window's edges, so a knot moves smoothly as points enter and leave) times
 * the point's share of the arc (half its two chords: dense input, a slow
 * stretch, weighs no more than sparse). It reproduces a quadratic exactly
 * (no pull towards the centre of curvature, which a weighted average has:
 * kappa h^2 / 18 on an arc with these weights) and damps the ripple of a
 * polyline's corners. The move from the input point in d; 0 when the
 * window holds too few points for the fit. */
static int fair_fit(const struct mlip_pathrun *pr, long c, double hc, double *d)
{
	int n = pr->lim.n;
	const double *pc = pr->fr_p[FR(c)];
	double sc = pr->fr_s[FR(c)], mom[5] = {0, 0, 0, 0, 0}, r[3][MLIP_MAX_AXES] = {{0}};
	if (!(hc > 0.0)) {
		return 0;
	}
	for (long j = pr->fr_lo; j < pr->fr_hi; j++) {
		double u = (pr->fr_s[FR(j)] - sc) / hc;
		if (!(u > -1.0 && u < 1.0)) {
			continue;
		}
		double a = j > pr->fr_lo ? pr->fr_s[FR(j)] - pr->fr_s[FR(j - 1)] : 0.0;
		double b = j + 1 < pr->fr_hi ? pr->fr_s[FR(j + 1)] - pr->fr_s[FR(j)] : 0.0;
		double w = (1.0 - u * u), uu = u * u;
		w = w * w * w * 0.5 * (a + b) / hc;
		mom[0] += w;
		mom[1] += w * u;
		mom[2] += w * uu;
		mom[3] += w * uu * u;
		mom[4] += w * uu * uu;
		for (int k = 0; k < n; k++) {
			double x = pr->fr_p[FR(j)][k] - pc[k]; /* relative: no cancellation */
			r[0][k] += w * x;
			r[1][k] += w * u * x;
			r[2][k] += w * uu * x;
		}
	}
	/* the first row of the inverse of the moments' matrix (Cramer) */
	double m0 = mom[0], m1 = mom[1], m2 = mom[2], m3 = mom[3], m4 = mom[4];
	double c0 = m2 * m4 - m3 * m3, c1 = m2 * m3 - m1 * m4, c2 = m1 * m3 - m2 * m2;
	double det = m0 * c0 + m1 * c1 + m2 * c2;
	if (!(det > 1e-12 * m0 * m0 * m0) || !(m0 > 0.0)) {
		return 0; /* too few points in the window */
	}
	for (int k = 0; k < n; k++) {
		d[k] = (c0 * r[0][k] + c1 * r[1][k] + c2 * r[2][k]) / det;
	}
	return 1;
}

/* The knot of input point c, window hc, in q (n axes); its distance from
 * the point in *dev. */
static void fair_point(const struct mlip_pathrun *pr, long c, double hc, double *q, double *dev)
{
	int n = pr->lim.n;
	double d[MLIP_MAX_AXES], d2 = 0.0;
	memcpy(q, pr->fr_p[FR(c)], sizeof(double) * (size_t)n);
	*dev = 0.0;
	if (!fair_fit(pr, c, hc, d)) {
		return; /* too few points in its window: the input point */
	}
	for (int k = 0; k < n; k++) {
		d2 += d[k] * d[k];
	}
	/* (F2) the move's length cut smoothly below fair_mm: len / (1 + (len
	 * / fair_mm)^4)^(1/4). A hard cut min(len, fair_mm) has a kink in the
	 * knots' offset, a step in x'': the circle at 1e5 1.352 s against
	 * 1.340 (2.129 against 2.101 at 1e4; the CAM files' heads within
	 * 0.8 % either way). */
	double len = sqrt(d2), x = len / pr->fair_mm, f = 1.0 / sqrt(sqrt(1.0 + x * x * x * x));
	for (int k = 0; k < n; k++) {
		q[k] += f * d[k];
	}
	*dev = f * len;
}

/* The half-width of input point c's window: fair_h, cut to what the ring
 * holds either side (symmetric: a line stays a line) and to the K-th input
 * point either side (the input is one point a period: where the motion is
 * slow, at a corner, the window is K periods). -1 when the window is not
 * yet in. */
static double fair_width(const struct mlip_pathrun *pr, long c, int forced)
{
	double sc = pr->fr_s[FR(c)], ahead = pr->fr_s[FR(pr->fr_hi - 1)] - sc;
	double behind = sc - pr->fr_s[FR(pr->fr_lo)], hc = pr->fair_h;
	long K = pr->fair_k;
	if (K > 0 && c + K < pr->fr_hi) {
		hc = fmin(hc, pr->fr_s[FR(c + K)] - sc);
	} else if (!forced && !pr->ended && ahead < hc) {
		return -1.0;
	}
	if (K > 0 && c - K >= pr->fr_lo) {
		hc = fmin(hc, sc - pr->fr_s[FR(c - K)]);
	}
	return fmin(hc, fmin(ahead, behind));
}

/* Knots from the ring while their windows are in (all when the input has
 * ended): 0, 1 the spline's window is full (the knot waits), -1 refused. */
static int fair_drain(struct mlip_pathrun *pr)
{
	while (pr->fr_c < pr->fr_hi) {
		long c = pr->fr_c;
		/* a full ring forces the knot only when its input is dense
		 * ahead (fair_push's case); with half of it or more behind the
		 * knot waits and the next push drops the oldest point: forced
		 * there, a knot with no point ahead got no window (hc 0), and
		 * so did every later one (the ring stayed full, one point in
		 * and one out): after 256 points within fair_h (a stretch at
		 * 10 mm/s) the fairing was off for the rest of the program */
		int forced = pr->fr_hi - pr->fr_lo == MLIP_PATHRUN_FAIR_CAP &&
		             c - pr->fr_lo < MLIP_PATHRUN_FAIR_CAP / 2;
		double hc = fair_width(pr, c, forced);
		if (hc < 0.0) {
			return 0; /* its window is not yet in */
		}
		double q[MLIP_MAX_AXES], dev;
		fair_point(pr, c, hc, q, &dev);
		int r = append(pr, q, dev, &pr->fr_tag[FR(c)]);
		if (r != 0) {
			return r;
		}
		pr->fr_c++;
		/* points no later knot's window reaches */
		while (pr->fr_lo < pr->fr_c && pr->fr_c < pr->fr_hi &&
		       pr->fr_s[FR(pr->fr_lo + 1)] <= pr->fr_s[FR(pr->fr_c)] - pr->fair_h) {
			pr->fr_lo++;
		}
	}
	return 0;
}

/* An input point into the ring (made room for: the oldest point behind
 * the next knot's centre dropped, that knot's window cut to the ring):
 * 0 taken, 1 the spline's window is full (step first), -1 refused. */
static int fair_push(struct mlip_pathrun *pr, const double *pos)
{
	int n = pr->lim.n;
	int r = fair_drain(pr);
	if (r != 0) {
		return r;
	}
	double h = chord(n, pr->fr_p[FR(pr->fr_hi - 1)], pos);
	if (h < MLIP_PATHRUN_MIN_STEP) {
		return 0; /* as the spline skips it: finish takes the last one */
	}
	while (pr->fr_hi - pr->fr_lo == MLIP_PATHRUN_FAIR_CAP) {
		if (pr->fr_c - pr->fr_lo < MLIP_PATHRUN_FAIR_CAP / 2) {
			/* dense input: the knot's window cut to half the ring */
			double q[MLIP_MAX_AXES], dev;
			fair_point(pr, pr->fr_c, fair_width(pr, pr->fr_c, 1), q, &dev);
			r = append(pr, q, dev, &pr->fr_tag[FR(pr->fr_c)]);
			if (r != 0) {
				return r;
			}
			pr->fr_c++;
		} else {
			pr->fr_lo++;
		}
	}
	long i = pr->fr_hi++;
	pr->fr_s[FR(i)] = pr->fr_s[FR(i - 1)] + h;
	memcpy(pr->fr_p[FR(i)], pos, sizeof(double) * (size_t)n);
	pr->fr_tag[FR(i)] = pr->last_tag;
	r = fair_drain(pr);
	return r < 0 ? r : 0;
}

int mlip_pathrun_push(struct mlip_pathrun *pr, const double *pos)
{
	int n = pr->lim.n;
	if (pr->finished || pr->ended) {
		pr->why = "a setpoint after the end";
		return -1;
	}
	for (int k = 0; k < n; k++) {
		if (!isfinite(pos[k])) {
			pr->why = "a setpoint not finite";
			return -1;
		}
	}
	memcpy(pr->last_in, pos, sizeof(double) * (size_t)n);
	pr->last_tag = pr->tag_in;
	return pr->fair_h > 0.0 ? fair_push(pr, pos) : append(pr, pos, 0.0, &pr->last_tag);
}

int mlip_pathrun_finish(struct mlip_pathrun *pr)
{
	int n = pr->lim.n, last = pr->count - 1;
	if (pr->finished) {
		return 0;
	}
	if (pr->fair_h > 0.0) {
		if (!pr->ended) {
			/* the last input exactly the ring's last point (its knot's
			 * window is empty: the knot is the point) */
			long i = pr->fr_hi - 1;
			double h = chord(n, pr->fr_p[FR(i)], pr->last_in);
			if (h > 0.0 && i >= pr->fr_c) {
				memcpy(pr->fr_p[FR(i)], pr->last_in, sizeof(double) * (size_t)n);
				pr->fr_tag[FR(i)] = pr->last_tag;
				pr->fr_s[FR(i)] = pr->fr_s[FR(i - 1)] +
				                  chord(n, pr->fr_p[FR(i - 1)], pr->last_in);
			} else if (h > 0.0) {
				pr->fr_s[FR(i + 1)] = pr->fr_s[FR(i)] + h;
				memcpy(pr->fr_p[FR(i + 1)], pr->last_in,
				       sizeof(double) * (size_t)n);
				pr->fr_tag[FR(i + 1)] = pr->last_tag;
				pr->fr_hi++;
			}
			pr->ended = 1;
		}
		int r = fair_drain(pr);
		if (r != 0) {
			return r < 0 ? r : 0; /* the window is full: step finishes it */
		}
		last = pr->count - 1;
	}
	pr->finished = 1;
	if (chord(n, pr->p[last], pr->last_in) > 0.0) {
		/* the last input was skipped (within MIN_STEP of the last point):
		 * end on it exactly, the last point moved there (not yet fixed) */
		if (last > pr->fixed) {
			double h = chord(n, pr->p[last - 1], pr->last_in);
			if (h > 0.0) {
				memcpy(pr->p[last], pr->last_in, sizeof(double) * (size_t)n);
				pr->s[last] = pr->s[last - 1] + h;
				pr->tag[last] = pr->last_tag;
				pr->cap[last] = pr->last_tag.cap;
				pr->dev[last] = 0.0;
			}
		} else if (pr->count < MLIP_PATHRUN_CAP || compact(pr)) {
			last = pr->count++;
			memcpy(pr->p[last], pr->last_in, sizeof(double) * (size_t)n);
			pr->s[last] = pr->s[last - 1] + chord(n, pr->p[last - 1], pr->last_in);
			pr->tag[last] = pr->last_tag;
			pr->cap[last] = pr->last_tag.cap;
			pr->dev[last] = 0.0;
		}
	}
	return last > pr->fixed ? settle(pr, last) : 0;
}

/* Periods at rest in a row after which the plan is taken as stuck (it
 * starts from rest with its largest jerk halved up to 40 times: one of
 * them moves unless the window ends where it stands). */
#define STUCK_PERIODS  100000
/* mlip_path_plan_period stays at rest within this of `end` (pathplan.h) */
#define END_REACHED_MM 1e-8

int mlip_pathrun_step(struct mlip_pathrun *pr, double *x)
{
	struct mlip_path_curve cv;
	if (pr->ended && !pr->finished && mlip_pathrun_finish(pr) != 0) {
		return -1; /* the fairing's last knots, as room is made */
	}
	if (!pr->finished && pr->count < MLIP_PATHRUN_CAP) {
		return 0; /* the look-ahead is not yet full */
	}
	if (pr->fixed < 1) {
		/* a program of one point, or of pieces all refused before */
		memcpy(x, pr->p[0], sizeof(double) * (size_t)pr->lim.n);
		return pr->finished ? 2 : 0;
	}
	mlip_pathrun_curve(pr, &cv);
	double end = pr->s[pr->fixed];
	struct mlip_path_state st = pr->st;
	if (pr->finished && end - st.s <= END_REACHED_MM && st.v == 0.0 && st.a == 0.0) {
		/* at rest on the last point (the plan brakes to rest at `end`
		 * itself, Q4, and stays within END_REACHED_MM of it): the point
		 * exactly */
		memcpy(x, pr->p[pr->fixed], sizeof(double) * (size_t)pr->lim.n);
		pr->st.s = end;
		pr->periods++;
		note_period(pr);
		return 2;
	}
	int r = mlip_path_plan_period(&cv, &pr->lim, &st, end, pr->max_periods, &pr->work);
	if (r < 0) {
		pr->why = "the plan left its certified states";
		pr->why_s = st.s;
		pr->why_v = st.v;
		pr->why_a = st.a;
		return -1;
	}
	pr->rested = st.v == 0.0 && st.a == 0.0 ? pr->rested + 1 : 0;
	if (pr->rested > STUCK_PERIODS) {
		pr->why = "the plan stays at rest short of the end";
		pr->why_s = st.s;
		return -1;
	}
	pr->periods++;
	pr->st = st;
	struct mlip_path_point d;
	pr->hint = mlip_path_spline_piece(&cv, st.s, pr->hint);
	mlip_path_spline_eval_piece(&cv, pr->hint, st.s, x, &d);
	note_period(pr);
	return 1;
}

const char *mlip_pathrun_refusal(const struct mlip_block *b)
{
	static const char *const at_rest[] = {
	    [MLIP_BLOCK_DWELL] = "a dwell (G4)",
	    [MLIP_BLOCK_PAUSE] = "a pause (M0/M60)",
	    [MLIP_BLOCK_OPTIONAL_PAUSE] = "an optional pause (M1)",
	    [MLIP_BLOCK_SPINDLE] = "a spindle change (M3/M4/M5, S)",
	    [MLIP_BLOCK_TOOL] = "a tool change (M6)",
	    [MLIP_BLOCK_COOLANT] = "a coolant change (M7/M8/M9)",
	    [MLIP_BLOCK_OUTPUT] = "an output (M62..M65)",
	    [MLIP_BLOCK_PROBE] = "a probe move (G38)",
	    [MLIP_BLOCK_SPEED] = "a spindle speed (S)"};
	if (b->kind != MLIP_BLOCK_MOVE) {
		return b->kind < sizeof(at_rest) / sizeof(at_rest[0]) && at_rest[b->kind]
		           ? at_rest[b->kind]
		           : "an event the plan does not know";
	}
	if (b->exact_stop) {
		return "an exact stop (G61 or a canned cycle)";
	}
	return NULL; /* a feed or a rapid: its block's cap (Q5) */
}
