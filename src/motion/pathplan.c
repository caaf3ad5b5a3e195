/*
 * pathplan.c - one period of the path-speed plan along a spline
 * (mlip/motion/pathplan.h: Q1-Q4; the model: bench/pathspeed.py).
 */
#include "mlip/motion/pathplan.h"

#include <math.h>
#include <stddef.h>

/* The policy's release: a back to 0 as v reaches 0, at this share of the
 * jerk the start allows (Q3). A run ends at rest (v = a = 0), the one
 * state that is safe on any curve: a run that ended at a crawl assumed the
 * rest of the curve allowed it, and a hook of 0.0002 mm (tball-pocket's
 * stations 5,316-5,340) allows no jerk at 1.2 mm/s (x''' v^3 alone
 * exceeds J), so the crawl it certified had no next step. A run that
 * passes the end fails (inside()): the run itself proves it stops before
 * it. */
#define RELEASE_SHARE 0.8

/* A step's end this close to rest is rest (mm/s, mm/s^2): a stop by the
 * greedy's candidate rather than stop_at lands a rounding away from it
 * (v 8.5e-15, a 1.1e-13 on a line of 0.17 mm at 1e5), where a jerk of 0
 * was certified for ever (a creep of 1e-14 mm/s). The snap moves a by at
 * most 1e-6 mm/s^2 within a period: a jerk of 1e-3 mm/s^3. */
#define REST_V 1e-9
#define REST_A 1e-6

/* (Q2) rounds of pick_at's search for a jerk inside its own step's
 * interval. */
#define PICK_ROUNDS 4

struct mlip_path_state mlip_path_advance(struct mlip_path_state st, double j, double h)
{
	struct mlip_path_state r; /* (Q1) */
	r.s = st.s + st.v * h + st.a * h * h / 2.0 + j * h * h * h / 6.0;
	r.v = st.v + st.a * h + j * h * h / 2.0;
	r.a = st.a + j * h;
	r.brake = st.brake;
	r.share = st.share;
	return r;
}

/* A state with what every step from it reads there: the piece holding
 * st.s, the curve's derivatives at st.s and the (P2) interval at (v, a)
 * (ok 0: empty). A step's end is the next state's point, so a run
 * evaluates each point once (Q2's end checkpoint is the next start). */
struct at {
	struct mlip_path_state st;
	struct mlip_path_point d;
	int piece, ok;
	double jl, jh;
};

static void at_make(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                    struct at *a, struct mlip_path_state st, int hint)
{
	a->st = st;
	a->piece = mlip_path_spline_piece(sp, st.s, hint);
	mlip_path_spline_eval_piece(sp, a->piece, st.s, NULL, &a->d);
	a->ok = mlip_path_jerk_range(lim->n, &a->d, lim->jerk, st.v, st.a, &a->jl, &a->jh);
}

/* The (P2) interval at the point d (on piece *piece, searched from it), at
 * the speed and acceleration the step of jerk j from st has at time h,
 * intersected into [*lo, *hi]; the point's own interval in *own: the step's
 * end, whose point and interval the next state keeps. */
static void cut(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                struct mlip_path_state st, double j, double h, double s, int *piece,
                struct mlip_path_point *d, double *lo, double *hi, struct at *own)
{
	struct mlip_path_state at = mlip_path_advance(st, j, h);
	double l, u;
	*piece = mlip_path_spline_piece(sp, s, *piece);
	mlip_path_spline_eval_piece(sp, *piece, s, NULL, d);
	int ok = mlip_path_jerk_range(lim->n, d, lim->jerk, at.v, at.a, &l, &u);
	own->ok = ok;
	own->jl = l;
	own->jh = u;
	if (!ok) {
		*lo = 1.0; /* no jerk at all here */
		*hi = -1.0;
		return;
	}
	*lo = l > *lo ? l : *lo;
	*hi = u < *hi ? u : *hi;
}

/* The speed's range over [h0, h1] of the step of jerk j from st (its ends,
 * and its extremum where a + j h = 0 inside). */
static void speed_range(struct mlip_path_state st, double j, double h0, double h1, double *lo,
                        double *hi)
{
	double v0 = st.v + st.a * h0 + j * h0 * h0 / 2.0, v1 = st.v + st.a * h1 + j * h1 * h1 / 2.0;
	*lo = v0 < v1 ? v0 : v1;
	*hi = v0 < v1 ? v1 : v0;
	if (j != 0.0) {
		double hs = -st.a / j;
		if (hs > h0 && hs < h1) {
			double vs = st.v + st.a * hs + j * hs * hs / 2.0;
			*lo = vs < *lo ? vs : *lo;
			*hi = vs > *hi ? vs : *hi;
		}
	}
}

/* The range of a product of two ranges. */
static void mul_range(double al, double ah, double bl, double bh, double *lo, double *hi)
{
	double p[4] = {al * bl, al * bh, ah * bl, ah * bh};
	*lo = *hi = p[0];
	for (int i = 1; i < 4; i++) {
		*lo = p[i] < *lo ? p[i] : *lo;
		*hi = p[i] > *hi ? p[i] : *hi;
	}
}

/* (Q2) on piece i over parameters [ua, ub], passed within [ha, hb] of the
 * step of jerk j from st, a bound: per axis x' (quadratic on the piece)
 * within [pl, ph], x'' (linear) within its ends, x''' constant, v and a
 * within their ranges over [ha, hb], so (P2) is p j + c with p in [pl, ph]
 * and c in [cm - cr, cm + cr]: a j with |p j + cm| <= J - cr at both ends
 * of p's range holds J at every point of the piece the step passes (affine
 * in p and c: the box's corners bound it). Into [*lo, *hi]; 0 when empty.
 * The range of (P2) at j itself widens [pm[k], pM[k]] per axis: the rate
 * of the axis's acceleration (P1) over the step (accel_over). */
static int piece_cut(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim, int i,
                     double ua, double ub, struct mlip_path_state st, double j, double ha,
                     double hb, double *lo, double *hi, double *pm, double *pM)
{
	double vl, vh, al = st.a + j * ha, ah = st.a + j * hb, val, vah;
	if (al > ah) {
		double t = al;
		al = ah;
		ah = t;
	}
	speed_range(st, j, ha, hb, &vl, &vh);
	mul_range(vl, vh, al, ah, &val, &vah);
	double v3l = vl * vl * vl, v3h = vh * vh * vh, wa = ua - sp->s[i], wb = ub - sp->s[i];
	for (int k = 0; k < lim->n; k++) {
		double m0 = sp->m[i][k], t3 = sp->t3[i][k], b = sp->b[i][k];
		double pa = b + m0 * wa + 0.5 * t3 * wa * wa, pb = b + m0 * wb + 0.5 * t3 * wb * wb;
		double pl = pa < pb ? pa : pb, ph = pa < pb ? pb : pa;
		if (t3 != 0.0) {
			double ws = -m0 / t3; /* where x'' = 0: x' at its extremum */
			if (ws > wa && ws < wb) {
				double ps = b + m0 * ws + 0.5 * t3 * ws * ws;
				pl = ps < pl ? ps : pl;
				ph = ps > ph ? ps : ph;
			}
		}
		double qa = 3.0 * (m0 + t3 * wa), qb = 3.0 * (m0 + t3 * wb), ql, qh;
		mul_range(qa < qb ? qa : qb, qa < qb ? qb : qa, val, vah, &ql, &qh);
		double cl = ql + (t3 >= 0.0 ? t3 * v3l : t3 * v3h);
		double ch = qh + (t3 >= 0.0 ? t3 * v3h : t3 * v3l);
		double cm = 0.5 * (cl + ch), J = lim->jerk[k] - 0.5 * (ch - cl);
		double jl = pl * j < ph * j ? pl * j : ph * j,
		       jh = pl * j < ph * j ? ph * j : pl * j;
		pm[k] = jl + cl < pm[k] ? jl + cl : pm[k];
		pM[k] = jh + ch > pM[k] ? jh + ch : pM[k];
		if (!(J >= 0.0) || !mlip_path_axis_cut(pl, cm, J, lo, hi) ||
		    !mlip_path_axis_cut(ph, cm, J, lo, hi)) {
			return 0;
		}
	}
	return *lo <= *hi;
}

static double clamp(double x, double lo, double hi)
{
	return x < lo ? lo : (x > hi ? hi : x);
}

/* (P1) at every instant of a step of T: per axis the acceleration f(h) =
 * x' a + x'' v^2 goes from f0 to fT with its rate f' = (P2) within [m, M]
 * (the pieces' bounds), so f(h) <= min(f0 + M h, fT - m (T - h)) and f(h)
 * >= max(f0 + m h, fT - M (T - h)): their extremes at h = 0, T or where the
 * two lines meet. The states alone let 1.0006 A through between two ends
 * within it (test_pathplan). 1 when every axis keeps A. */
static int accel_over(const struct mlip_path_limits *lim, const struct at *a, const struct at *e,
                      double T, const double *pm, const double *pM)
{
	struct mlip_path_state s0 = a->st, s1 = e->st;
	for (int k = 0; k < lim->n; k++) {
		double f0 = a->d.d1[k] * s0.a + a->d.d2[k] * s0.v * s0.v;
		double f1 = e->d.d1[k] * s1.a + e->d.d2[k] * s1.v * s1.v, m = pm[k], M = pM[k];
		double up = f0 > f1 ? f0 : f1, dn = f0 < f1 ? f0 : f1;
		if (M > m) {
			double h = clamp((f1 - f0 - m * T) / (M - m), 0.0, T), x = f0 + M * h;
			x = x < f1 - m * (T - h) ? x : f1 - m * (T - h);
			up = x > up ? x : up;
			h = clamp((f0 - f1 + M * T) / (M - m), 0.0, T);
			x = f0 + m * h > f1 - M * (T - h) ? f0 + m * h : f1 - M * (T - h);
			dn = x < dn ? x : dn;
		}
		if (!(up <= lim->accel[k] + 1e-9 && dn >= -lim->accel[k] - 1e-9)) {
			return 0;
		}
	}
	return 1;
}

/* (Q2) from the state a over a step of T (the period, or a stop's part of
 * it); the step's end (the next state, its point and interval) in *next
 * when next is not NULL. Every point of the step lies
 * on a piece it crosses, passed at a time h with (u - s) / vmax <= h <=
 * (u - s) / vmin (v within [vmin, vmax] over the step), so a bound per
 * piece over those times (piece_cut) holds the whole step: no knot's time,
 * one bound a piece where three checkpoints a knot sampled it. */
static int range_at(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                    const struct at *a, double j, double T, double *lo, double *hi, struct at *next)
{
	double l = a->jl, u = a->jh, pm[MLIP_MAX_AXES], pM[MLIP_MAX_AXES];
	struct mlip_path_state st = a->st, end = mlip_path_advance(st, j, T);
	for (int k = 0; k < lim->n; k++) {
		pm[k] = INFINITY;
		pM[k] = -INFINITY;
	}
	double s1 = end.s, last = sp->s[sp->count - 1], vmin, vmax;
	*lo = 1.0; /* until the whole step is checked: empty */
	*hi = -1.0;
	if (!a->ok) {
		return 0;
	}
	speed_range(st, j, 0.0, T, &vmin, &vmax);
	double slo = st.s, shi = s1;
	if (!(vmin > 0.0)) { /* s need not be monotone: what v allows */
		slo = st.s + (vmin < 0.0 ? vmin * T : 0.0);
		shi = st.s + (vmax > 0.0 ? vmax * T : 0.0);
	}
	slo = slo < 0.0 ? 0.0 : slo;
	shi = shi > last ? last : shi;
	int piece = mlip_path_spline_piece(sp, slo, a->piece);
	for (int i = piece; i < sp->count - 1 && sp->s[i] <= shi; i++) {
		double ua = sp->s[i] > slo ? sp->s[i] : slo;
		double ub = sp->s[i + 1] < shi ? sp->s[i + 1] : shi, ha = 0.0, hb = T;
		if (vmin > 0.0) {
			ha = (ua - st.s) / vmax;
			hb = (ub - st.s) / vmin;
			ha = ha < 0.0 ? 0.0 : (ha > T ? T : ha);
			hb = hb < ha ? ha : (hb > T ? T : hb);
		}
		if (!piece_cut(sp, lim, i, ua, ub, st, j, ha, hb, &l, &u, pm, pM)) {
			return 0;
		}
		piece = i;
	}
	struct at scratch, *e = next ? next : &scratch;
	cut(sp, lim, st, j, T, s1 < last ? s1 : last, &piece, &e->d, &l, &u, e);
	if (fabs(end.v) <= REST_V && fabs(end.a) <= REST_A) {
		end.v = 0.0; /* rest, to the rounding (Q4) */
		end.a = 0.0;
	}
	e->st = end;
	e->piece = mlip_path_spline_piece(sp, end.s, piece);
	if (!accel_over(lim, a, e, T, pm, pM)) {
		return 0; /* (P1) broken within the step: no jerk near j keeps it */
	}
	*lo = l;
	*hi = u;
	return l <= u;
}

int mlip_path_period_range(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                           struct mlip_path_state st, double j, double *lo, double *hi)
{
	struct at a;
	at_make(sp, lim, &a, st, 0);
	return range_at(sp, lim, &a, j, lim->period, lo, hi, NULL);
}

/* The admissible jerk nearest jt from a (Q2); its step's end in *next.
 * The interval's end e(x) moves with the step's own jerk x (Q1), with a
 * slope s below 1 near the end jt is clamped to, so x = e(x) is reached
 * from outside the interval geometrically (x - x* shrinks by s a round)
 * and a round limit rejected jerks that exist: with 4 rounds of plain
 * clamping, lissajous at J 1e4 took 7.7 s, with 8 rounds 5.0 s. From the
 * second round the clamp takes a secant step to the fixed point of e
 * through the last two rounds, a hair inside the interval; a jerk is still
 * accepted only inside its own step's interval. */
static int pick_at(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                   const struct at *a, double jt, double *j, struct at *next)
{
	double lo, hi, px = 0.0, pe = 0.0;
	if (!a->ok) {
		return 0;
	}
	double x = clamp(jt, a->jl, a->jh);
	for (int i = 0; i < PICK_ROUNDS; i++) {
		if (!range_at(sp, lim, a, x, lim->period, &lo, &hi, next)) {
			return 0;
		}
		if (lo <= x && x <= hi) {
			*j = x;
			return 1;
		}
		double e = clamp(jt, lo, hi), y = e;
		if (i > 0 && x != px) {
			double s = (e - pe) / (x - px);
			if (s < 0.9) { /* the fixed point of e(x) = pe + s (x - px) */
				double f = (e - s * x) / (1.0 - s);
				y = f + (e < x ? -1.0 : 1.0) * 1e-7 * (fabs(f) + 1.0);
			}
		}
		px = x;
		pe = e;
		x = y;
	}
	return 0;
}

int mlip_path_pick(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                   struct mlip_path_state st, double jt, double *j)
{
	struct at a, next;
	at_make(sp, lim, &a, st, 0);
	return pick_at(sp, lim, &a, jt, j, &next);
}

/* The policy i, within the limits' (0 when out of range). */
static int policy(const struct mlip_path_limits *lim, int i)
{
	int n = lim->n_brake < 1
	            ? 1
	            : (lim->n_brake > MLIP_PATH_BRAKES ? MLIP_PATH_BRAKES : lim->n_brake);
	return i >= 0 && i < n ? i : 0;
}

/* (Q3) the stop: from v > 0, a < 0 the jerk a^2 / (2 v) brings v and a to
 * 0 together after h = -2 v / a; when that is within the period and the
 * jerk admissible over [0, h] (Q2), *next is that rest (the period's
 * remainder held there). 0 otherwise. */
static int stop_at(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                   const struct at *a, double *j, struct at *next)
{
	struct mlip_path_state st = a->st;
	double lo, hi, h = -2.0 * st.v / st.a, js = st.a * st.a / (2.0 * st.v);
	if (!(h > 0.0 && h <= lim->period) || !range_at(sp, lim, a, js, h, &lo, &hi, next) ||
	    !(lo <= js && js <= hi)) {
		return 0;
	}
	next->st.v = 0.0;
	next->st.a = 0.0;
	*j = js;
	return 1;
}

/* (Q3) from a, alo the low end of the (P1) interval at its point and speed
 * (NAN: not yet computed); the step's end in *next. */
static int brake_at(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                    const struct at *a, double alo, double *j, struct at *next)
{
	double T = lim->period, jh = a->jh;
	struct mlip_path_state st = a->st;
	if (!a->ok) {
		return 0;
	}
	if (st.v <= 0.0 && st.a == 0.0) {
		return pick_at(sp, lim, a, 0.0, j, next); /* at rest: stay */
	}
	if (st.a < 0.0 && st.v > 0.0 && stop_at(sp, lim, a, j, next)) {
		return 1;
	}
	double ahi;
	if (isnan(alo) && !mlip_path_accel_range(lim->n, &a->d, lim->accel, st.v, &alo, &ahi)) {
		return 0;
	}
	double ab = lim->a_brake[policy(lim, st.brake)];
	double target = alo > -ab ? alo : -ab, jt = a->jl;
	if (st.a + a->jl * T < target) {
		jt = (target - st.a) / T; /* (Q3) reach the target, not past it */
	}
	/* (Q3) release: brake no harder than leaves the next state (v1, a1) its
	 * stop at the release jerk jr (v1 >= a1^2 / (2 jr) where a1 < 0; the
	 * triangle a1 -> 0 as v1 -> 0, which keeps the bound with equality):
	 * with v1 = v + (a + a1) T / 2, a1 >= (jr T - sqrt(jr^2 T^2 + 8 jr (v
	 * + a T / 2))) / 2 */
	double jr = RELEASE_SHARE * jh, q = jr * jr * T * T + 8.0 * jr * (st.v + st.a * T / 2.0);
	if (jr > 0.0 && q >= 0.0) {
		double jmin = ((jr * T - sqrt(q)) / 2.0 - st.a) / T;
		jt = jt > jmin ? jt : jmin;
	}
	return pick_at(sp, lim, a, jt, j, next);
}

int mlip_path_brake(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                    struct mlip_path_state st, double *j)
{
	struct at a, next;
	at_make(sp, lim, &a, st, 0);
	return brake_at(sp, lim, &a, NAN, j, &next);
}

int mlip_path_brake_step(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                         struct mlip_path_state *st, double *j)
{
	struct at a, next;
	double jj;
	at_make(sp, lim, &a, *st, 0);
	if (!brake_at(sp, lim, &a, NAN, &jj, &next)) {
		return 0;
	}
	*st = next.st;
	if (j) {
		*j = jj;
	}
	return 1;
}

double mlip_path_piece_cap(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                           int i)
{
	double c = lim->vmax, r = lim->vfull > 0.0 ? lim->vmax / lim->vfull : 1.0;
	if (sp->cap == NULL || sp->count < 2) {
		return c;
	}
	i = i < 0 ? 0 : (i > sp->count - 2 ? sp->count - 2 : i);
	for (int k = i; k <= i + 1; k++) { /* (Q5): the lower of its two knots' */
		double f = sp->cap[k] * r;
		c = sp->cap[k] > 0.0 && f < c ? f : c;
	}
	return c;
}

/* (Q5) the step from (v0 on piece p0) to the state a keeps both ends'
 * speeds within the cap of every piece it touches. */
static int capped(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim, double v0,
                  int p0, const struct at *a)
{
	double v = v0 > a->st.v ? v0 : a->st.v;
	int lo = p0 < a->piece ? p0 : a->piece, hi = p0 < a->piece ? a->piece : p0;
	for (int i = lo; i <= hi; i++) {
		if (!(v <= mlip_path_piece_cap(sp, lim, i))) {
			return 0;
		}
	}
	return 1;
}

/* Within the speed cap (Q5, at its piece), (P1) (its interval's low end in
 * *alo), a non-empty (P2) interval, before the end. */
static int inside(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                  const struct at *a, double end, double *alo)
{
	double hi;
	struct mlip_path_state st = a->st;
	if (!(st.v >= 0.0 && st.v <= mlip_path_piece_cap(sp, lim, a->piece) &&
	      st.s <= end + 1e-9)) {
		return 0;
	}
	if (!mlip_path_accel_range(lim->n, &a->d, lim->accel, st.v, alo, &hi) ||
	    !(*alo - 1e-9 <= st.a && st.a <= hi + 1e-9)) {
		return 0;
	}
	return a->ok;
}

/* (Q4) the run from start; from (may be NULL): the state whose step led
 * to it, checked as the run's (Q5). */
static int certified_at(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                        const struct at *start, const struct at *from, double end, int max_periods,
                        long *work)
{
	struct at buf[2];
	const struct at *a = start;
	double v0 = from ? from->st.v : 0.0; /* the last step's start */
	int p0 = from ? from->piece : start->piece, caps = sp->cap != NULL;
	for (int i = 0; i < max_periods; i++) {
		if (work) {
			(*work)++;
		}
		double alo, j;
		struct mlip_path_state st = a->st;
		if (!inside(sp, lim, a, end, &alo) || (caps && !capped(sp, lim, v0, p0, a))) {
			return 0;
		}
		if (st.v == 0.0 && st.a == 0.0) {
			return 1; /* (Q4) at rest before the end */
		}
		struct at *next = &buf[i & 1];
		if (!brake_at(sp, lim, a, alo, &j, next)) {
			return 0;
		}
		v0 = st.v;
		p0 = a->piece;
		a = next;
	}
	return 0;
}

int mlip_path_certified(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                        struct mlip_path_state st, double end, int max_periods, long *work)
{
	struct at a;
	at_make(sp, lim, &a, st, 0);
	return certified_at(sp, lim, &a, NULL, end, max_periods, work);
}

/* The step of the jerk nearest jt from a (Q2) into *st when some policy
 * certifies its end (Q4), tried in their order, the hardest first: the new
 * state keeps the first that certifies it, so a hold from it brakes as hard
 * as any policy can (st's own first let a gentle policy, once taken, carry
 * on down a straight line at speed: a hold there braked at 0.3 A in mlip-rt
 * after a 1 mm circle, test_rtplan_host), and the candidate i. */
static int take(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                const struct at *a, double jt, int i, struct mlip_path_state *st, double end,
                int max_periods, long *work)
{
	struct at nx;
	double j;
	if (!pick_at(sp, lim, a, jt, &j, &nx)) {
		return -1;
	}
	if (a->st.v == 0.0 && a->st.a == 0.0 && nx.st.v == 0.0 && nx.st.a == 0.0) {
		/* from rest a jerk whose step ends at rest (REST_V, REST_A) does
		 * not move: pick_at clamps to the interval of the larger jerk it
		 * tried first, whose step reaches pieces that allow only j near 0
		 * (a random zigzag's 0.2 um piece, x''' 2.6e7: [-194514, 3.8e-5]
		 * at 118482). Taken, it was a move that stayed, for ever; the
		 * halved jerk next moves. */
		return -1;
	}
	int nb = lim->n_brake < 1 ? 1 : lim->n_brake;
	nb = nb > MLIP_PATH_BRAKES ? MLIP_PATH_BRAKES : nb;
	for (int q = 0; q < nb; q++) {
		nx.st.brake = q;
		if (certified_at(sp, lim, &nx, a, end, max_periods, work)) {
			nx.st.share = i;
			*st = nx.st;
			return 1;
		}
	}
	return 0;
}

/* Above its cap (a lower feed's or a hold's, planq.h) the plan is its
 * braking run: its next state nx (from a) takes the hardest policy whose
 * run certifies it, so a run that began gently (on a tight curve the
 * harder ones break a limit) brakes hard once they no longer do. The cap
 * aside: it only chooses the plan's speed, and these states are above it
 * (the pieces' feed caps alike: the run only slows). */
static void harder(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                   const struct at *a, struct at *nx, double end, int max_periods, long *work)
{
	struct mlip_path_curve uncapped = *sp;
	struct mlip_path_limits unlim = *lim;
	uncapped.cap = NULL;
	unlim.vmax = INFINITY;
	struct at h = *nx;
	for (int q = 0; q < nx->st.brake; q++) {
		h.st.brake = q;
		if (certified_at(&uncapped, &unlim, &h, a, end, max_periods, work)) {
			nx->st.brake = q;
			return;
		}
	}
}

/* The landing jerks land[q] (mlip_path_plan_period) above the given jerk inside
 * the (P2) interval and not yet tried: 1 when one's step is taken. */
static int land_take(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                     const struct at *a, const double land[2], int tried[2], double above, int i,
                     struct mlip_path_state *st, double end, int max_periods, long *work)
{
	for (int q = 0; q < 2; q++) {
		if (!tried[q] && land[q] > above && land[q] > a->jl && land[q] < a->jh) {
			tried[q] = 1;
			if (take(sp, lim, a, land[q], i, st, end, max_periods, work) == 1) {
				return 1;
			}
		}
	}
	return 0;
}

/* From rest the plan tries the jerk the start allows halved up to this many
 * times: near the end only a small move still stops before it, and each
 * such move (its run to rest certified) closes at least part of the gap,
 * so the plan reaches the end itself (no crawl, no tail). */
#define REST_HALVINGS 40

/* At rest this close to the end (mm, or the curve's own parameter) the plan
 * has arrived: it stays (a machine's resolution is far coarser; a jump of
 * it in one sample is a jerk of 20 mm/s^3). At 1e-9 the halved moves of a
 * helix 25 mm long at 1e5 stalled 1.6e-9 short (their runs' rounding). */
#define END_REACHED 1e-8

/* The cap landing's target below the cap (its share): far above the
 * rounding of a step's speed (1e-16), far below what a cruise loses (1e-9
 * of a 200 mm/s cap is 2e-7 mm/s). */
#define LAND_BELOW 1e-9

int mlip_path_plan_period(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                          struct mlip_path_state *st, double end, int max_periods, long *work)
{
	static const double share[5] = {1.0, 0.75, 0.5, 0.25, 0.0};
	struct at a, nx;
	double j;
	at_make(sp, lim, &a, *st, 0);
	if (a.ok && st->v == 0.0 && st->a == 0.0) {
		if (end - st->s <= END_REACHED) {
			return brake_at(sp, lim, &a, NAN, &j, &nx) ? 0 : -1; /* arrived: stay */
		}
		double jt = a.jh; /* at rest: a jerk below 0 would go back, 0 stays */
		for (int i = 0; i <= REST_HALVINGS && jt > 0.0; i++, jt *= 0.5) {
			if (take(sp, lim, &a, jt, 0, st, end, max_periods, work) == 1) {
				return 1;
			}
		}
	} else if (a.ok) {
		int i0 = st->share > 0 && st->share < 5 ? st->share - 1 : 0;
		double T = lim->period, cap = mlip_path_piece_cap(sp, lim, a.piece);
		/* Landing candidates, each tried just before the first of the
		 * five below it: the jerk whose step and a next step of -a1/T
		 * end at the cap (Q5) with a = 0 (v + 1.5 a T + j T^2 = cap), and
		 * the jerk that zeroes a. The five alone missed both: a 5 mm
		 * line at F100 cruised in a sawtooth of 0.84-0.99 of its cap
		 * (3.262 -> 3.058 s at 1e5). No zero-a landing while braking
		 * below J T^2 (one period's jerk's worth of speed): there a = 0
		 * is a creep, not a cruise (MB-2.3 at 1e4 crept 1.8 s into a
		 * corner at under 0.01 mm/s; NAN is never tried). */
		int creep = st->a < 0.0 && st->v < a.jh * T * T;
		/* the cap landing aims LAND_BELOW under it: one exactly at it
		 * lands an ulp above as often as not, is refused (Q5), and the
		 * cruise became a sawtooth again (F100 at 1e5 with the limits at
		 * 0.995: 0.98-0.995 of its cap) */
		double land[2] = {(cap * (1.0 - LAND_BELOW) - st->v - 1.5 * st->a * T) / (T * T),
		                  creep ? NAN : -st->a / T};
		int tried[2] = {0, 0};
		for (int i = i0; i < 5; i++) {
			double jc = a.jl + share[i] * (a.jh - a.jl);
			if (land_take(sp, lim, &a, land, tried, jc, i, st, end, max_periods,
			              work)) {
				return 1;
			}
			int r = take(sp, lim, &a, jc, i, st, end, max_periods, work);
			if (r == 1) {
				return 1;
			}
			/* no jerk near jc (Q2): the landings below it may still
			 * have one, the second step of a landing above all (-a1/T
			 * where jc's step would pass A). Braking instead, F100 at
			 * 1e6 landed and braked by turns: 10.2 s (4.24 s without
			 * the landings, 3.03 s with this). */
			if (r != 0) {
				if (land_take(sp, lim, &a, land, tried, a.jl, i, st, end,
				              max_periods, work)) {
					return 1;
				}
				break;
			}
		}
	}
	/* the braking run's first step: st's run was certified (Q4) */
	if (!brake_at(sp, lim, &a, NAN, &j, &nx)) {
		return -1;
	}
	if (a.ok && nx.st.v > 0.0 && nx.st.brake > 0 &&
	    st->v > mlip_path_piece_cap(sp, lim, a.piece)) {
		harder(sp, lim, &a, &nx, end, max_periods, work);
	}
	struct mlip_path_state n = nx.st;
	if (n.v < 0.0) {
		n.s = st->s;
		n.v = 0.0;
		n.a = 0.0;
	}
	n.share = 0; /* after braking: every candidate again */
	*st = n;
	return 0;
}
