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
	*cv = (struct mlip_path_curve){pr->lim.n,  pr->fixed + 1, pr->s,      (row)pr->p,
	                               (row)pr->m, (row)pr->b,    (row)pr->t3};
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
	pr->band_mm = band_mm;
	pr->max_periods = max_periods;
	memcpy(pr->p[0], start, sizeof(double) * (size_t)n);
	memcpy(pr->last_in, start, sizeof(double) * (size_t)n);
	pr->count = 1;
	pr->peak_count = 1;
	pr->keep_s = INFINITY;
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
		if (!(g <= pr->band_mm)) {
			pr->fixed = i; /* not taken */
			pr->why = "a spline piece strays from its chord by more than the band (P6)";
			pr->why_s = s[i];
			pr->why_mm = g;
			return -1;
		}
	}
	return 0;
}

/* Drop the pieces the plan has passed when it is a quarter of the window
 * in: 1 when room was made. s stays global: the plan's state is unmoved. */
static int compact(struct mlip_pathrun *pr)
{
	struct mlip_path_curve cv;
	mlip_pathrun_curve(pr, &cv);
	/* keep_s: a planned queue's consumer may still brake there (planq.h) */
	double from = pr->st.s < pr->keep_s ? pr->st.s : pr->keep_s;
	int i = pr->fixed > 0 ? mlip_path_spline_piece(&cv, from, pr->hint) : 0;
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
	pr->count = keep;
	pr->fixed -= i;
	pr->hint = 0;
	pr->dropped += i;
	return 1;
}

int mlip_pathrun_push(struct mlip_pathrun *pr, const double *pos)
{
	int n = pr->lim.n;
	if (pr->finished) {
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
	pr->tag[i] = pr->last_tag;
	pr->peak_count = pr->count > pr->peak_count ? pr->count : pr->peak_count;
	int upto = pr->count - 1 - MLIP_PATHRUN_SETTLE;
	return upto > pr->fixed ? settle(pr, upto) : 0;
}

int mlip_pathrun_finish(struct mlip_pathrun *pr)
{
	int n = pr->lim.n, last = pr->count - 1;
	if (pr->finished) {
		return 0;
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
			}
		} else if (pr->count < MLIP_PATHRUN_CAP || compact(pr)) {
			last = pr->count++;
			memcpy(pr->p[last], pr->last_in, sizeof(double) * (size_t)n);
			pr->s[last] = pr->s[last - 1] + chord(n, pr->p[last - 1], pr->last_in);
			pr->tag[last] = pr->last_tag;
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
	return 1;
}

const char *mlip_pathrun_refusal(const struct mlip_block *b, double *feed)
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
		return "an exact stop (G61)";
	}
	if (feed == NULL) {
		return NULL; /* the caller runs every move at its own feed */
	}
	if (b->rapid) {
		return "a rapid (G0 runs at the machine's maximum feed; the plan runs one feed)";
	}
	if (*feed == 0.0) {
		*feed = b->feed_mm_s;
	} else if (b->feed_mm_s != *feed) {
		return "a second feed (the plan runs the program's first F under one speed cap)";
	}
	return NULL;
}
