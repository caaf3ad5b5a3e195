/*
 * smooth.c - the `smooth` strategy's path filter (see mlip/motion/smooth.h).
 *
 * Why: on CAM output the paper's corners are limited by their locality, not
 * by eps: each corner fits in half of each neighbouring segment (19), so on a
 * path sampled every d mm whose vertices turn by theta the corner speed is
 * about sqrt(A d / theta) = sqrt(A R) with R = d / theta the radius the
 * VERTICES describe. Coordinates rounded to 3-4 decimals make theta mostly
 * noise (0.0001 mm on a 0.02 mm segment is a 0.3 degree kink), and a real
 * turn stays on the few segments CAM put it on. A curve that stays within
 * delta of the polyline but bends as little as delta allows, sampled finely,
 * lets the same corners run at sqrt(A R) of the smoothed curve.
 *
 * Where the time goes (MB-2.3, 1000 mm/s^2, measured against the original
 * polyline): the smoothed stretches run 1.4-1.5x faster than mpct and the
 * time left there is set by the REAL curvature of the part (a time-optimal
 * follow of the filter's output under the per-axis limits, tangential plus
 * normal acceleration, takes 319 s where the simulator took 321 s); a
 * quarter of the time is next to turns over 20 degrees, mostly the raster's
 * reversals, that no band of 0.01 mm can round. Giving the spline more
 * freedom (a longer L0, an Lp bending norm, the whole band at sub-samples)
 * made the time-optimal follow of its output slower, not faster: bending
 * energy gathers the curvature where the curve touches the band.
 *
 * How, per run of feed moves between exact points:
 *  1. Samples: every original vertex. Where the curvature changes
 *     erratically from vertex to vertex (a running mean of |k_i - k_{i-1}| /
 *     (|k_i| + |k_{i-1}|) above JITTER_MIN, k_i the turn vector at vertex i
 *     over the mean length of its two segments: CAM noise), each segment
 *     also gets sub-samples every step_mm so the spline can bend inside it;
 *     segments longer than 5 steps get them at 1, 2, 4, ... steps from each
 *     end, where a turn can spread. Where the path is clean (the running
 *     mean, kept over about 30 vertices, below JITTER_PIN) and both segments
 *     of a vertex are at least 3 steps long, it stays exact (x = p):
 *     smoothing would only take the corners' eps there (their (18) bound),
 *     and sub-samples would halve their legs (19). So a clean program in
 *     long segments runs exactly as mpct; shorter clean segments are
 *     smoothed without sub-samples (the spline spreads their turns a little).
 *  2. A smoothing spline over the window: minimise
 *         sum_i w_i |x_i - p_i|^2 + sum_i g_i |x''_i|^2
 *     (x'' the second divided difference in the original arc length u), a
 *     pentadiagonal system per axis, solved by LDL^T. The weights w_i grow
 *     where |x_i - p_i| exceeds the radius r_i and relax inside it (never
 *     below w0: iteratively reweighted), so the spline bends only where the
 *     band forces it; then x_i is clamped into the ball |x_i - p_i| <= r_i.
 *     r_i = min(rho b, b - 0.15 h^2 k): each corner keeps what it needs on
 *     the smoothed curve (a corner using half of segments of h at curvature
 *     k deviates about h^2 k / 8, (17)(19); more reserve costs the spline
 *     band: 0.25 and 0.1 are both slower on MB-2.3).
 *     Then MLIP_SMOOTH_POLISH more solves hold each sample still beyond
 *     its radius on the band's edge (a fixed value), so the spline passes
 *     there smoothly; the clamp then only trims what is left (alone, a
 *     clamped sample is a kink the corners must slow down for).
 *  3. A vertex turning by more than sharp_deg is pinned (x = p) with its
 *     neighbours, and the sub-samples in the halves of its segments next to
 *     it are dropped: an isolated corner is passed fastest by the paper's
 *     own corner with the whole budget (its parabola is as fast as an arc
 *     using the whole band, sqrt(8 eps |a|) / theta either way), and noise
 *     next to it is smoothed into the straight legs.
 *  4. Windows: solve when 1024 samples wait beyond the frozen ones; freeze
 *     all but the last MLIP_SMOOTH_KEEP (they lack right-hand context); the
 *     next solve takes the last two frozen samples as fixed boundary values.
 *
 * The deviation bound (rigorous, for every point of every output segment,
 * not only the vertices): sample i is matched to the point p_i of the
 * original polyline at arc length u_i. Every original vertex is a sample
 * (dropped samples are sub-samples only), so between two consecutive
 * emitted samples i, j the original polyline p(u), u in [u_i, u_j], is ONE
 * straight segment. On the output segment x(u) = x_i + (u - u_i) / (u_j -
 * u_i) (x_j - x_i) both x(u) and p(u) are affine in u, so |x(u) - p(u)| is
 * convex in u and at most max(|x_i - p_i|, |x_j - p_j|) = max(dev_i, dev_j).
 * Hence dist(x(u), original polyline) <= max(dev_i, dev_j).
 *
 * The tolerance split: the planner's corner at output vertex j is the
 * parabola (14) from S on segment j to E on segment j+1, a quadratic Bezier
 * with control points S, x_j, E (x_j is where its tangents meet, (5)). Its
 * point at t, B(t) = (1-t)^2 S + 2t(1-t) x_j + t^2 E, is t^2 (S + E - 2 x_j)
 * away from the leg point S + 2t (x_j - S) for t <= 1/2 (and (1-t)^2 (...)
 * from x_j + (2t - 1)(E - x_j) after), and |S + E - 2 x_j| / 4 = eps_c <=
 * tol_j (17)(18): the corner stays within tol_j of its legs [S, x_j] and
 * [x_j, E]. The legs lie in the halves of segments j and j+1 next to x_j
 * (19), where by the convexity above the smoothing deviates at most
 * max(dev_j, (dev_{j-1} + dev_j) / 2, (dev_j + dev_{j+1}) / 2). So with
 *     tol_j = min(b_{j-1}, b_j, b_{j+1}) - that
 * the motion stays within the budget b (min(eps, the blocks' own tol_mm)).
 * tol_j > 0 because r_i = rho min(b_{i-2..i+2}) <= rho min(b_{j-1..j+1}).
 * At an exact point (a run's end) whatever follows is exact (a rapid) or
 * starts at the exact point and ends within rho b of the original (the next
 * run's first segment): dev_{j+1} counts as rho b. A rapid that ends where
 * a run starts gets (1 - rho / 2) b.
 */
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "mlip/motion/smooth.h"

#define SOLVE_BATCH     1024 /* samples frozen per solve */
#define UNIFORM_STEPS   5    /* segments up to this many steps are sampled uniformly */
#define GEOM_LEVELS     7    /* else at 1, 2, ... 64 steps from each end */
#define WEIGHT_UP_MAX   16.0
#define WEIGHT_DOWN_MAX 0.25
#define WEIGHT_TARGET   0.95

enum { ROLE_START = 0, ROLE_SUB, ROLE_VERTEX, ROLE_PASS };

/* Tuning (mm). The spline's initial smoothing length L0 sets the weights
 * w = h / L0^4 against a unit bending weight: curves shorter than about L0
 * are flattened unless the band forbids it. */
#define STEP_MM     0.1
#define L0_MM       1.0
#define GAP_STEPS   4.0
#define CORNER_NEED 0.15
#define JITTER_KEEP 0.97
#define JITTER_MIN  0.4
#define JITTER_PIN  0.4
#define SHORT_FRAC  3.0

static double dmin(double a, double b)
{
	return a < b ? a : b;
}

static double dmax(double a, double b)
{
	return a > b ? a : b;
}

/* What the smoothing and the corner of a block may share: min(eps, its own
 * tol_mm), less what a jerk limit's mean takes (E_f, mlip/motion/jerk.h). */
static double budget(const struct mlip_smooth *sm, const struct mlip_block *b)
{
	double bb = b->tol_mm > 0.0 ? dmin(b->tol_mm, sm->eps_mm) : sm->eps_mm;
	return sm->filter_mm > 0.0 ? dmax(bb - sm->filter_mm, 0.0) : bb;
}

/* An output block's tol_mm: the corner's share, plus E_f, which the planner
 * takes from every block's budget (it cannot tell ours from others). */
static double emit_tol(const struct mlip_smooth *sm, double tol)
{
	return sm->filter_mm > 0.0 ? tol + sm->filter_mm : tol;
}

mlip_status mlip_smooth_init(struct mlip_smooth *sm, const struct mlip_machine *m,
                             const double *start)
{
	if (m->n_axes < 2 || m->n_axes > MLIP_MAX_AXES || !(m->tolerance_mm > 0.0)) {
		return MLIP_E_INVALID;
	}
	memset(sm, 0, offsetof(struct mlip_smooth, s));
	sm->n = m->n_axes;
	sm->eps_mm = m->tolerance_mm;
	struct mlip_jerk_plan jp;
	mlip_jerk_plan(m, &jp);
	sm->filter_mm = jp.filter_mm;
	sm->step_mm = STEP_MM;
	sm->sharp_cos = MLIP_SMOOTH_SHARP_COS;
	sm->gap_mm = GAP_STEPS * STEP_MM;
	sm->l0_mm = L0_MM;
	sm->rho = MLIP_SMOOTH_RHO;
	sm->corner_need = CORNER_NEED;
	sm->jitter_min = JITTER_MIN;
	sm->pin_clean = 1;
	sm->jitter_pin = JITTER_PIN;
	for (int k = 0; k < sm->n; k++) {
		if (!isfinite(start[k])) {
			return MLIP_E_INVALID;
		}
		sm->last[k] = start[k];
	}
	sm->last_b = sm->eps_mm;
	return MLIP_OK;
}

/* ---- the spline --------------------------------------------------------- */

static int is_fixed(const struct mlip_smooth *sm, uint32_t i)
{
	return i < sm->frozen || sm->s[i].pinned || sm->s[i].hold;
}

/* Solve the window [a, count) and freeze up to `upto`. */
static void solve(struct mlip_smooth *sm, uint32_t upto)
{
	uint32_t a = sm->frozen >= 2 ? sm->frozen - 2 : 0;
	if (a < sm->run0) {
		a = sm->run0;
	}
	uint32_t m = sm->count - a;
	int n = sm->n;
	struct mlip_smooth_sample *s = sm->s + a;
	double *a0 = sm->a0, *a1 = sm->a1, *a2 = sm->a2, *l1 = sm->l1, *l2 = sm->l2;
	double *rhs = sm->rhs;
	sm->solves++;

	/* radii: rho times the smallest budget within two samples (see top) */
	for (uint32_t i = 0; i < m; i++) {
		if (s[i].pinned || a + i < sm->frozen) {
			s[i].r = 0.0;
			continue;
		}
		double b = s[i].b;
		for (uint32_t j = i >= 2 ? i - 2 : 0; j <= i + 2 && j < m; j++) {
			b = dmin(b, s[j].b);
		}
		if (a + i >= 2 && i < 2 && a + i - 2 >= sm->run0) {
			b = dmin(b, sm->s[a + i - 2].b); /* frozen neighbours before the window */
		}
		s[i].bmin = b;
		s[i].r = sm->rho * b;
	}

	int iters = m >= 3 ? MLIP_SMOOTH_ITER : 0, polish = m >= 3 ? MLIP_SMOOTH_POLISH : 0;
	for (int it = 0; it < iters + polish; it++) {
		/* polish: a sample still beyond its radius is held on the band's
		 * edge and the spline solved again around it, so the curve passes
		 * there smoothly; clamped alone it would be a kink, a spike of
		 * curvature the corners must slow down for */
		for (uint32_t i = 0; it >= iters && i < m; i++) {
			if (is_fixed(sm, a + i)) {
				continue;
			}
			double d2 = 0.0;
			for (int k = 0; k < n; k++) {
				double d = s[i].x[k] - s[i].p[k];
				d2 += d * d;
			}
			if (d2 > s[i].r * s[i].r) {
				double f = s[i].r > 0.0 ? s[i].r / sqrt(d2) : 0.0;
				for (int k = 0; k < n; k++) {
					s[i].x[k] = s[i].p[k] + (s[i].x[k] - s[i].p[k]) * f;
				}
				s[i].hold = 1;
			}
		}
		for (uint32_t i = 0; i < m; i++) {
			a0[i] = is_fixed(sm, a + i) ? 0.0 : s[i].w;
			a1[i] = 0.0;
			a2[i] = 0.0;
		}
		/* bending: g |c0 x_{i-1} + c1 x_i + c2 x_{i+1}|^2, the second divided
		 * difference on the original arc length, weighted by its length */
		for (uint32_t i = 1; i + 1 < m; i++) {
			double h1 = s[i].h, h2 = s[i + 1].h, hs = h1 + h2;
			double c0 = 2.0 / (hs * h1), c2 = 2.0 / (hs * h2), c1 = -(c0 + c2);
			double g = 0.5 * hs;
			a0[i - 1] += g * c0 * c0;
			a0[i] += g * c1 * c1;
			a0[i + 1] += g * c2 * c2;
			a1[i - 1] += g * c0 * c1;
			a1[i] += g * c1 * c2;
			a2[i - 1] += g * c0 * c2;
		}
		/* right-hand sides, fixed samples moved to the right */
		for (uint32_t i = 0; i < m; i++) {
			int fi = is_fixed(sm, a + i);
			for (int k = 0; k < n; k++) {
				rhs[i * (uint32_t)n + (uint32_t)k] =
				    fi ? s[i].x[k] : s[i].w * s[i].p[k];
			}
		}
		for (uint32_t j = 0; j < m; j++) {
			if (!is_fixed(sm, a + j)) {
				continue;
			}
			for (uint32_t i = j >= 2 ? j - 2 : 0; i <= j + 2 && i < m; i++) {
				if (i == j || is_fixed(sm, a + i)) {
					continue;
				}
				uint32_t lo = i < j ? i : j;
				double aij = (i > j ? i - j : j - i) == 1 ? a1[lo] : a2[lo];
				for (int k = 0; k < n; k++) {
					rhs[i * (uint32_t)n + (uint32_t)k] -= aij * s[j].x[k];
				}
			}
		}
		for (uint32_t j = 0; j < m; j++) {
			if (!is_fixed(sm, a + j)) {
				continue;
			}
			a0[j] = 1.0;
			a1[j] = 0.0;
			a2[j] = 0.0;
			if (j >= 1) {
				a1[j - 1] = 0.0;
			}
			if (j >= 2) {
				a2[j - 2] = 0.0;
			}
		}
		/* LDL^T of the pentadiagonal matrix: a0 becomes D */
		for (uint32_t i = 0; i < m; i++) {
			double L2 = i >= 2 ? a2[i - 2] / a0[i - 2] : 0.0;
			double L1 = 0.0;
			if (i >= 1) {
				L1 = (a1[i - 1] - (i >= 2 ? L2 * l1[i - 1] * a0[i - 2] : 0.0)) /
				     a0[i - 1];
			}
			l1[i] = L1;
			l2[i] = L2;
			a0[i] -= L1 * L1 * (i >= 1 ? a0[i - 1] : 0.0) +
			         L2 * L2 * (i >= 2 ? a0[i - 2] : 0.0);
		}
		for (int k = 0; k < n; k++) {
			double *r = rhs + k;
			for (uint32_t i = 1; i < m; i++) {
				r[i * (uint32_t)n] -=
				    l1[i] * r[(i - 1) * (uint32_t)n] +
				    (i >= 2 ? l2[i] * r[(i - 2) * (uint32_t)n] : 0.0);
			}
			for (uint32_t i = 0; i < m; i++) {
				r[i * (uint32_t)n] /= a0[i];
			}
			for (uint32_t i = m - 1; i-- > 0;) {
				r[i * (uint32_t)n] -=
				    l1[i + 1] * r[(i + 1) * (uint32_t)n] +
				    (i + 2 < m ? l2[i + 2] * r[(i + 2) * (uint32_t)n] : 0.0);
			}
		}
		/* leave each corner what it needs on the smoothed curve: a corner
		 * cut into segments of h at curvature k deviates about h^2 k / 8
		 * when it uses half of each (17)(19) */
		for (uint32_t i = 1; i + 1 < m && sm->corner_need > 0.0; i++) {
			if (s[i].r == 0.0) {
				continue;
			}
			double h1 = s[i].h, h2 = s[i + 1].h, hs = h1 + h2, k2 = 0.0;
			for (int k = 0; k < n; k++) {
				double c =
				    rhs[(i + 1) * (uint32_t)n + (uint32_t)k] * (2.0 / (hs * h2)) +
				    rhs[(i - 1) * (uint32_t)n + (uint32_t)k] * (2.0 / (hs * h1)) -
				    rhs[i * (uint32_t)n + (uint32_t)k] *
				        (2.0 / (hs * h1) + 2.0 / (hs * h2));
				k2 += c * c;
			}
			double hm = dmax(h1, h2);
			s[i].r = dmax(dmin(sm->rho * s[i].bmin,
			                   s[i].bmin - sm->corner_need * hm * hm * sqrt(k2)),
			              0.0);
		}
		/* take the solution; grow the weights where the band is left */
		for (uint32_t i = 0; i < m; i++) {
			if (is_fixed(sm, a + i)) {
				continue;
			}
			double d2 = 0.0;
			for (int k = 0; k < n; k++) {
				s[i].x[k] = rhs[i * (uint32_t)n + (uint32_t)k];
				double d = s[i].x[k] - s[i].p[k];
				d2 += d * d;
			}
			/* towards touching the band: up outside, down inside, by
			 * (d / r)^1.5: with (d / r)^2 the weights of loops cut inside
			 * (trochoidal clearing) flipped between two states from one
			 * iteration to the next and the result depended on the count's
			 * parity (13.7 or 15.6 s); damped, it converges */
			double r2 = s[i].r * s[i].r * (WEIGHT_TARGET * WEIGHT_TARGET);
			double q = r2 > 0.0 ? sqrt(d2 / r2) : 0.0;
			double f = r2 > 0.0 ? q * sqrt(q) : WEIGHT_UP_MAX;
			s[i].w =
			    dmax(s[i].w * dmin(dmax(f, WEIGHT_DOWN_MAX), WEIGHT_UP_MAX), s[i].w0);
		}
	}

	/* clamp into the band and freeze */
	for (uint32_t i = 0; i < m; i++) {
		s[i].hold = 0;
	}
	for (uint32_t i = 0; i < m; i++) {
		if (a + i < sm->frozen) {
			continue;
		}
		double d2 = 0.0;
		if (s[i].pinned || iters == 0) {
			memcpy(s[i].x, s[i].p, sizeof(double) * (size_t)n);
		}
		for (int k = 0; k < n; k++) {
			double d = s[i].x[k] - s[i].p[k];
			d2 += d * d;
		}
		double dev = sqrt(d2);
		if (dev > s[i].r) {
			double f = s[i].r > 0.0 ? s[i].r / dev : 0.0;
			d2 = 0.0;
			for (int k = 0; k < n; k++) {
				s[i].x[k] = s[i].p[k] + (s[i].x[k] - s[i].p[k]) * f;
				double d = s[i].x[k] - s[i].p[k];
				d2 += d * d;
			}
			dev = sqrt(d2);
		}
		/* the planner skips a block closer than MLIP_MERGE_MM to the previous
		 * point, which would change the polyline the bound speaks of: a
		 * sample pulled that close to its predecessor goes back to p */
		double g2 = 0.0;
		for (int k = 0; i > 0 && k < n; k++) {
			double g = s[i].x[k] - s[i - 1].x[k];
			g2 += g * g;
		}
		if (i > 0 && dev > 0.0 && g2 < (4.0 * MLIP_MERGE_MM) * (4.0 * MLIP_MERGE_MM)) {
			memcpy(s[i].x, s[i].p, sizeof(double) * (size_t)n);
			dev = 0.0;
		}
		s[i].dev = dev;
	}
	if (upto > sm->frozen) {
		for (uint32_t i = sm->frozen; i < upto; i++) {
			sm->max_dev = dmax(sm->max_dev, sm->s[i].dev);
		}
		sm->frozen = upto;
	}
}

/* ---- the window --------------------------------------------------------- */

/* Drop samples no longer needed: emitted, and not a boundary of the solve. */
static void compact(struct mlip_smooth *sm)
{
	uint32_t d = sm->emit;
	uint32_t keep_from = sm->frozen >= 2 ? sm->frozen - 2 : 0;
	if (d > keep_from) {
		d = keep_from;
	}
	if (d == 0) {
		return;
	}
	memmove(sm->s, sm->s + d, sizeof(sm->s[0]) * (size_t)(sm->count - d));
	sm->count -= d;
	sm->frozen -= d;
	sm->emit -= d;
	for (int i = 0; i < sm->n_lone; i++) {
		sm->lone[i] = sm->lone[i] >= d ? sm->lone[i] - d : 0u; /* 0: <= run0, passed over */
	}
	sm->run0 = sm->run0 > d ? sm->run0 - d : 0;
}

static struct mlip_smooth_sample *append(struct mlip_smooth *sm)
{
	struct mlip_smooth_sample *s = &sm->s[sm->count++];
	memset(s, 0, sizeof(*s));
	return s;
}

/* Keep vertex v exact: pin it, drop the sub-samples in the half of its
 * segment before it (at least gap_mm), and pin the nearest sample kept too
 * when `neighbours` (a sharp corner then has its whole budget). */
static void pin_vertex(struct mlip_smooth *sm, uint32_t v, int neighbours)
{
	if (v < sm->frozen) {
		return; /* already final: its corner gets what its devs leave */
	}
	sm->s[v].pinned = 1;
	/* the segment into v: its length, to drop the sub-samples of its half */
	double seg = 0.0;
	for (uint32_t i = v; i > sm->run0; i--) {
		seg += sm->s[i].h;
		if (sm->s[i - 1].role != ROLE_SUB) {
			break;
		}
	}
	double gap = dmax(sm->gap_mm, 0.5 * seg), u = 0.0;
	for (uint32_t i = v; i > sm->run0 && i - 1 >= sm->frozen;) {
		u += sm->s[i].h;
		i--;
		if (sm->s[i].role != ROLE_SUB || u >= gap) {
			sm->s[i].pinned = (uint8_t)(sm->s[i].pinned | neighbours);
			break;
		}
		sm->s[i].pinned = 1;
		sm->s[i].drop = 1;
	}
}

/* The newest vertex (its segment after it is not there yet). */
static void pin_corner(struct mlip_smooth *sm, int neighbours)
{
	pin_vertex(sm, sm->count - 1, neighbours);
}

/*
 * One or two turns below sharp_deg between sharp vertices (or a run's ends)
 * have nothing to spread over but their own short legs: the paper's corners
 * with the whole budget pass them fastest, as they pass a sharp one (3.
 * above), so they are pinned like one, from both sides (the sub-samples in
 * the halves of both their segments next to them dropped, the nearest kept
 * pinned), and the path there is the program's, as mpct runs it. Smoothed,
 * they took part of their budget and their neighbours' for nothing: random
 * zigzags of 0.05-0.6 mm segments turning up to 150 degrees (tools/
 * gen_zigzag.py --random) ran 0.25-0.30 % slower than mpct; pinned alone
 * (one turn) still 0.03-0.06 %, one or two 0.05-0.2 % faster than mpct.
 */
static void pin_lone_at(struct mlip_smooth *sm, uint32_t v)
{
	if (v < sm->frozen || v <= sm->run0) {
		return;
	}
	pin_vertex(sm, v, 1);
	double seg = 0.0, u = 0.0;
	for (uint32_t i = v + 1; i < sm->count; i++) {
		seg += sm->s[i].h;
		if (sm->s[i].role != ROLE_SUB) {
			break;
		}
	}
	double gap = dmax(sm->gap_mm, 0.5 * seg);
	for (uint32_t i = v + 1; i < sm->count; i++) {
		u += sm->s[i].h;
		sm->s[i].pinned = 1;
		if (sm->s[i].role != ROLE_SUB || u >= gap) {
			break;
		}
		sm->s[i].drop = 1;
	}
}

static void pin_lone(struct mlip_smooth *sm)
{
	for (int i = 0; i < sm->n_lone; i++) {
		pin_lone_at(sm, sm->lone[i]);
	}
	sm->n_lone = 0;
}

static void close_run(struct mlip_smooth *sm)
{
	if (!sm->run_open) {
		return;
	}
	sm->run_open = 0;
	if (sm->count == sm->run0 + 1 && sm->s[sm->run0].role == ROLE_START) {
		sm->count--; /* a run without a segment */
		return;
	}
	pin_lone(sm);      /* the run's end is exact */
	pin_corner(sm, 0); /* an exact point, and its segment's last half whole */
	solve(sm, sm->count);
}

static void open_run(struct mlip_smooth *sm, double feed)
{
	struct mlip_smooth_sample *s = append(sm);
	memcpy(s->p, sm->last, sizeof(double) * (size_t)sm->n);
	memcpy(s->x, sm->last, sizeof(double) * (size_t)sm->n);
	s->b = sm->last_b;
	s->role = ROLE_START;
	s->pinned = 1;
	sm->run0 = sm->count - 1;
	sm->frozen = sm->count;
	sm->run_open = 1;
	sm->run_feed = feed;
	sm->have_dir = 0;
	sm->n_lone = 0; /* the run's start is exact */
	sm->pend = 0;
}

/* Cut the newest segment (one vertex sample, not final) into pieces of at
 * most step_mm: sub-samples on the original segment before its vertex. */
static void subdivide_last(struct mlip_smooth *sm)
{
	uint32_t v = sm->count - 1;
	struct mlip_smooth_sample *s = &sm->s[v];
	double d = s->h;
	int k = (int)ceil(d / sm->step_mm);
	if (v < sm->frozen || k < 2 || k > UNIFORM_STEPS) {
		return;
	}
	sm->s[v + (uint32_t)k - 1] = *s;
	double l4 = sm->l0_mm * sm->l0_mm * sm->l0_mm * sm->l0_mm;
	for (int i = 1; i < k; i++) {
		struct mlip_smooth_sample *u = &sm->s[v + (uint32_t)i - 1];
		*u = sm->s[v + (uint32_t)k - 1];
		double back = d * (double)(k - i) / (double)k; /* from the vertex */
		for (int j = 0; j < sm->n; j++) {
			u->p[j] = u->p[j] - sm->last_dir[j] * back;
			u->x[j] = u->p[j];
		}
		u->role = ROLE_SUB;
		u->b = dmin(u->b, sm->s[v - 1].b);
		u->pinned = 0;
		u->drop = 0;
	}
	for (int i = 0; i < k; i++) {
		struct mlip_smooth_sample *u = &sm->s[v + (uint32_t)i];
		u->h = d / (double)k;
		u->w0 = u->h / l4;
		u->w = u->w0;
	}
	sm->count += (uint32_t)k - 1;
}

static mlip_status room(struct mlip_smooth *sm, uint32_t need)
{
	if (sm->count + need <= MLIP_SMOOTH_CAP) {
		return MLIP_OK;
	}
	compact(sm);
	if (sm->count + need <= MLIP_SMOOTH_CAP) {
		return MLIP_OK;
	}
	if (sm->run_open && sm->count - sm->frozen > MLIP_SMOOTH_KEEP) {
		solve(sm, sm->count - MLIP_SMOOTH_KEEP);
	}
	return MLIP_E_FULL; /* pop, then push again */
}

static mlip_status push_move(struct mlip_smooth *sm, const struct mlip_block *b)
{
	int n = sm->n;
	double d2 = 0.0, dir[MLIP_MAX_AXES];
	for (int k = 0; k < n; k++) {
		double dk = b->target[k] - sm->last[k];
		d2 += dk * dk;
	}
	double d = sqrt(d2);
	if (d < MLIP_MERGE_MM) {
		if (b->exact_stop) {
			close_run(sm);
		}
		return MLIP_OK; /* the planner ignores it too */
	}
	if (sm->run_open && b->feed_mm_s != sm->run_feed) {
		close_run(sm);
	}
	if (!sm->run_open) {
		open_run(sm, b->feed_mm_s);
	}
	for (int k = 0; k < n; k++) {
		dir[k] = (b->target[k] - sm->last[k]) / d;
	}
	int pin_ahead = !sm->have_dir, sharp = 0, clean = 0; /* a run starts exact */
	double kv[MLIP_MAX_AXES];
	if (sm->have_dir) {
		double c = 0.0;
		for (int k = 0; k < n; k++) {
			c += dir[k] * sm->last_dir[k];
			/* curvature vector at the vertex: the turn over the mean length
			 * of its segments (a clean curve in uneven segments turns by
			 * uneven angles, but its curvature changes steadily) */
			kv[k] = (dir[k] - sm->last_dir[k]) / (0.5 * (sm->last_d_mm + d));
		}
		sharp = c < sm->sharp_cos;
		/* How erratically the turns change from vertex to vertex (a
		 * running mean): CAM noise makes them jump, a clean curve turns
		 * steadily. Where it is noisy the spline gets room to bend inside
		 * each segment (sub-samples); where it is clean the vertices stay
		 * exact, as mpct runs them: smoothing would only take the corners'
		 * eps there, and sub-samples would halve their legs (19). */
		if (sm->pend_kv_ok) {
			double dj = 0.0, a1 = 0.0, a2 = 0.0;
			for (int k = 0; k < n; k++) {
				dj += (kv[k] - sm->pend_kv[k]) * (kv[k] - sm->pend_kv[k]);
				a1 += kv[k] * kv[k];
				a2 += sm->pend_kv[k] * sm->pend_kv[k];
			}
			double j = sqrt(dj) / (sqrt(a1) + sqrt(a2) + 1e-12);
			sm->jitter = JITTER_KEEP * sm->jitter + (1.0 - JITTER_KEEP) * j;
		}
		if (!sharp && sm->jitter > sm->jitter_min) {
			if (sm->pend) {
				subdivide_last(sm);
			}
		} else if (!sharp && sm->pin_clean && sm->jitter <= sm->jitter_pin &&
		           dmin(d, sm->last_d_mm) >= SHORT_FRAC * sm->step_mm) {
			clean = 1;
		}
		if (sharp || clean) {
			pin_corner(sm, sharp);
			pin_ahead = 1 + sharp;
		}
		if (sharp) {
			pin_lone(sm); /* the turns before this one, if they were alone */
		} else if (clean || sm->n_lone < 0 || sm->n_lone == MLIP_SMOOTH_LONE) {
			sm->n_lone = -1;
		} else {
			sm->lone[sm->n_lone++] = sm->count - 1;
		}
	}

	/* arc positions of the new samples along the segment */
	double t[MLIP_SMOOTH_MAX_PIECES];
	int np = 0;
	double step = sm->step_mm;
	int pend = d <= UNIFORM_STEPS * step;
	if (pend) {
		t[np++] = d; /* one sample; subdivided when the next block shows a zigzag */
	} else {
		double g[GEOM_LEVELS];
		int ng = 0;
		for (int i = 0; i < GEOM_LEVELS && step * (double)(1 << i) < 0.5 * d; i++) {
			g[ng++] = step * (double)(1 << i);
		}
		for (int i = 0; i < ng; i++) {
			t[np++] = g[i];
		}
		for (int i = ng; i-- > 0;) {
			t[np++] = d - g[i];
		}
		t[np++] = d;
	}

	double bb = budget(sm, b), prev = 0.0;
	for (int i = 0; i < np; i++) {
		struct mlip_smooth_sample *s = append(sm);
		for (int k = 0; k < n; k++) {
			s->p[k] = i == np - 1 ? b->target[k] : sm->last[k] + dir[k] * t[i];
			s->x[k] = s->p[k];
		}
		s->h = t[i] - prev;
		prev = t[i];
		s->role = i == np - 1 ? ROLE_VERTEX : ROLE_SUB;
		s->b = i == np - 1 ? bb : dmin(bb, sm->last_b);
		s->w0 = s->h / (sm->l0_mm * sm->l0_mm * sm->l0_mm * sm->l0_mm);
		s->w = s->w0;
		s->blk = *b;
		if (pin_ahead) {
			/* sub-samples in the first half of the segment after a pinned
			 * vertex are dropped; the first kept one is pinned too after a
			 * sharp one, so its corner has the whole budget */
			if (t[i] >= dmax(sm->gap_mm, 0.5 * d) || s->role == ROLE_VERTEX) {
				s->pinned = (uint8_t)(pin_ahead == 2);
				pin_ahead = 0;
			} else {
				s->pinned = 1;
				s->drop = 1;
			}
		}
	}
	memcpy(sm->last, b->target, sizeof(double) * (size_t)n);
	memcpy(sm->last_dir, dir, sizeof(double) * (size_t)n);
	sm->last_d_mm = d;
	sm->pend = pend && !sharp && !sm->s[sm->count - 1].pinned;
	sm->pend_kv_ok = sm->have_dir;
	if (sm->have_dir) {
		memcpy(sm->pend_kv, kv, sizeof(double) * (size_t)n);
	}
	sm->last_b = bb;
	sm->have_dir = 1;
	if (b->exact_stop) {
		close_run(sm);
	} else if (sm->count - sm->frozen >= SOLVE_BATCH + MLIP_SMOOTH_KEEP) {
		solve(sm, sm->count - MLIP_SMOOTH_KEEP);
	}
	return MLIP_OK;
}

mlip_status mlip_smooth_push(struct mlip_smooth *sm, const struct mlip_block *b)
{
	/* a probe move (G38) passes as a rapid does: exact, never smoothed */
	int is_move = b->kind == MLIP_BLOCK_MOVE || b->kind == MLIP_BLOCK_PROBE;
	if (is_move) {
		for (int k = 0; k < sm->n; k++) {
			if (!isfinite(b->target[k])) {
				return MLIP_E_RANGE;
			}
		}
	}
	mlip_status st = room(sm, MLIP_SMOOTH_MAX_PIECES + UNIFORM_STEPS + 2);
	if (st != MLIP_OK) {
		return st;
	}
	sm->in_blocks++;
	if (b->kind == MLIP_BLOCK_MOVE && !b->rapid) {
		return push_move(sm, b);
	}
	/* pass through, exact: a rapid or a program event */
	close_run(sm);
	struct mlip_smooth_sample *s = append(sm);
	s->role = ROLE_PASS;
	s->blk = *b;
	if (is_move) {
		double bb = budget(sm, b);
		/* the run that may start at its end is within rho bb of it */
		s->blk.tol_mm = emit_tol(sm, (1.0 - 0.5 * sm->rho) * bb);
		memcpy(sm->last, b->target, sizeof(double) * (size_t)sm->n);
		sm->last_b = bb;
	}
	sm->frozen = sm->count;
	return MLIP_OK;
}

void mlip_smooth_finish(struct mlip_smooth *sm)
{
	close_run(sm);
}

mlip_status mlip_smooth_pop(struct mlip_smooth *sm, struct mlip_block *out)
{
	while (sm->emit < sm->frozen) {
		uint32_t e = sm->emit;
		struct mlip_smooth_sample *s = &sm->s[e];
		if (s->role == ROLE_START) {
			sm->prev_dev = 0.0;
			sm->prev_b = s->b;
			sm->emit++;
			continue;
		}
		if (s->role == ROLE_PASS) {
			*out = s->blk;
			sm->emit++;
			sm->out_blocks++;
			return MLIP_OK;
		}
		if (s->drop) {
			sm->emit++;
			continue;
		}
		uint32_t j = e + 1;
		while (j < sm->count && sm->s[j].drop) {
			j++;
		}
		double next_dev, next_b;
		int run_end;
		if (j < sm->count && (sm->s[j].role == ROLE_SUB || sm->s[j].role == ROLE_VERTEX)) {
			if (j >= sm->frozen) {
				return MLIP_E_EMPTY; /* its neighbour is not final yet */
			}
			next_dev = sm->s[j].dev;
			next_b = sm->s[j].b;
			run_end = 0;
		} else if (j >= sm->count && sm->run_open) {
			return MLIP_E_EMPTY;
		} else {
			/* an exact point: what follows is exact or within rho b */
			next_dev = sm->rho * s->b;
			next_b = s->b;
			run_end = 1;
		}
		double b = dmin(dmin(sm->prev_b, s->b), next_b);
		/* the corner's legs lie in the halves of its segments next to it
		 * (19), where the smoothing deviates at most the mean of the two
		 * ends' (see top) */
		double tol = b - dmax(s->dev, 0.5 * (s->dev + dmax(sm->prev_dev, next_dev)));
		*out = s->blk;
		memcpy(out->target, s->x, sizeof(double) * (size_t)sm->n);
		out->tol_mm = emit_tol(sm, dmax(tol, 1e-12));
		out->rapid = 0;
		out->exact_stop = run_end ? s->blk.exact_stop : 0;
		sm->prev_dev = s->dev;
		sm->prev_b = s->b;
		sm->emit++;
		sm->out_blocks++;
		return MLIP_OK;
	}
	return MLIP_E_EMPTY;
}
