/*
 * test_planner.c - the interpolation core against the paper's theorems and
 * against physics measured from the setpoints alone (tools/lib/check.c).
 * Every physical bound is asserted on both sides, with its tolerance.
 */
#include <float.h>
#include <inttypes.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "../../tools/lib/blockiter.h"
#include "../../tools/lib/check.h"
#include "mlip/motion/planner.h"
#include "mlip/motion/smooth.h"

#define REL 1e-9 /* stated tolerance on every physical limit */

#define assert_near(a, b, tol)                                                                     \
	do {                                                                                       \
		double a_ = (a), b_ = (b), t_ = (tol);                                             \
		if (!(fabs(a_ - b_) <= t_)) {                                                      \
			fail_msg("%s = %.17g, expected %.17g within %.3g", #a, a_, b_, t_);        \
		}                                                                                  \
	} while (0)
#define assert_le(a, b)                                                                            \
	do {                                                                                       \
		double a_ = (a), b_ = (b);                                                         \
		if (!(a_ <= b_)) {                                                                 \
			fail_msg("%s = %.17g is not <= %s = %.17g", #a, a_, #b, b_);               \
		}                                                                                  \
	} while (0)

static struct mlip_planner P;
static struct mlip_smooth_store SM; /* the smooth strategy's planner data */

static uint64_t rng = 88172645463325252ULL;
static double urand(void)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return (double)(rng >> 11) / 9007199254740992.0;
}

static void random_unit(int n, double *e)
{
	double s;
	do {
		s = 0.0;
		for (int k = 0; k < n; k++) {
			e[k] = 2.0 * urand() - 1.0;
			s += e[k] * e[k];
		}
	} while (s < 1e-6 || s > 1.0);
	s = sqrt(s);
	for (int k = 0; k < n; k++) {
		e[k] /= s;
	}
}

/* ---- Theorems 1 and 2: the LP optimum ------------------------------------ */

/* Largest feasible radius along (alpha, beta) = (cos th, sin th). */
static double boundary_radius(int n, const double *es, const double *ee, const double *A, double th)
{
	double r = INFINITY;
	for (int k = 0; k < n; k++) {
		double g = fabs(cos(th) * ee[k] - sin(th) * es[k]);
		if (g > 0.0) {
			r = fmin(r, A[k] / g);
		}
	}
	return r;
}

static void lp_check(int n)
{
	for (int trial = 0; trial < 400; trial++) {
		double es[MLIP_MAX_AXES], ee[MLIP_MAX_AXES], A[MLIP_MAX_AXES];
		random_unit(n, es);
		random_unit(n, ee);
		int same = 1;
		for (int k = 0; k < n; k++) {
			A[k] = 300.0 + 6000.0 * urand();
			same &= es[k] * ee[k] >= 0.0;
		}
		double al, be;
		assert_int_equal(mlip_corner_lp(n, es, ee, A, &al, &be), 0);
		assert_true(al >= 0.0 && be >= 0.0);
		/* feasible, and on the polygon's boundary */
		double worst = 0.0;
		for (int k = 0; k < n; k++) {
			double u = fabs(al * ee[k] - be * es[k]) / A[k];
			assert_le(u, 1.0 + 1e-12);
			worst = fmax(worst, u);
		}
		assert_near(worst, 1.0, 1e-9);
		/* beats or equals a dense sample of the feasible polygon: its
		 * boundary (where a linear objective peaks) and its interior */
		double max_a = 0.0, max_b = 0.0;
		for (int i = 0; i <= 4000; i++) {
			double th = (M_PI / 2.0) * i / 4000.0;
			double r = boundary_radius(n, es, ee, A, th);
			if (!isfinite(r)) {
				continue;
			}
			double a = r * cos(th), b = r * sin(th);
			assert_le(a + b, (al + be) * (1.0 + 1e-12));
			double f = urand();
			assert_le(f * (a + b), al + be);
			max_a = fmax(max_a, a);
			max_b = fmax(max_b, b);
		}
		if (same) {
			/* Theorem 1: a same-direction corner's optimum maximises
			 * v_s and v_e at once (the feasible set is closed under
			 * component-wise max, in any number of axes) */
			assert_le(max_a, al * (1.0 + 1e-6));
			assert_le(max_b, be * (1.0 + 1e-6));
		}
	}
}

static void test_lp_optimal_2axes(void **state)
{
	(void)state;
	lp_check(2);
}
static void test_lp_optimal_3axes(void **state)
{
	(void)state;
	lp_check(3);
}
static void test_lp_optimal_5axes(void **state)
{
	(void)state;
	lp_check(5);
}

static void test_lp_paper_example(void **state)
{
	/* Sec. 1.2's 2-axis example: A_x = 2.9, A_y = 1 m/s^2, incoming
	 * segment at -pi/6. For a same-direction corner the optimum is a
	 * half-diagonal of the rectangle: |a_x| = A_x and |a_y| = A_y. */
	(void)state;
	double A[2] = {2900.0, 1000.0};
	double es[2] = {cos(-M_PI / 6), sin(-M_PI / 6)};
	double th = -M_PI / 18; /* outgoing direction inside (-pi/6, 0) */
	double ee[2] = {cos(th), sin(th)};
	double al, be;
	assert_int_equal(mlip_corner_lp(2, es, ee, A, &al, &be), 0);
	assert_near(fabs(al * ee[0] - be * es[0]), A[0], 1e-9);
	assert_near(fabs(al * ee[1] - be * es[1]), A[1], 1e-9);
}

/* ---- degenerate corners --------------------------------------------------- */

static void test_corner_collinear_and_reversal(void **state)
{
	(void)state;
	double A[3] = {1000, 2000, 3000};
	double e[3] = {0.6, 0.8, 0.0}, r[3] = {-0.6, -0.8, 0.0};
	struct mlip_corner c;
	for (int st = 0; st < 3; st++) {
		mlip_corner_plan(3, (mlip_strategy)st, e, e, 0.2, 0.3, A, 0.01, 150, 120, 0.001,
		                 &c);
		assert_true(isfinite(c.vs_mm_s) && isfinite(c.t_s) && isfinite(c.alpha_mm_s2));
		assert_near(c.t_s, 0.0, 0.0);
		assert_near(c.vs_mm_s, st == MLIP_STRATEGY_STOP ? 0.0 : 120.0, 0.0);
		assert_near(c.vs_mm_s, c.ve_mm_s, 0.0);

		mlip_corner_plan(3, (mlip_strategy)st, e, r, 0.2, 0.3, A, 0.01, 150, 120, 0.001,
		                 &c);
		assert_true(isfinite(c.vs_mm_s) && isfinite(c.t_s));
		assert_near(c.vs_mm_s, c.ve_mm_s,
		            1e-9 * c.vs_mm_s); /* tie broken to alpha = beta */
		/* a reversal turns back before P, by at most eps (17) */
		if (c.t_s > 0.0) {
			double turn = c.ls_mm - c.vs_mm_s * c.vs_mm_s /
			                            (2.0 * (c.alpha_mm_s2 + c.beta_mm_s2));
			assert_le(turn, 0.01 * (1.0 + REL));
		}
	}
	double al, be;
	assert_int_equal(mlip_corner_lp(3, e, e, A, &al, &be), -1);
}

/* ---- Eq 17 and Prop. 4 on the corner parabola ----------------------------- */

static double dist_to_segment(int n, const double *x, const double *a, const double *b)
{
	double ab2 = 0, t = 0;
	for (int k = 0; k < n; k++) {
		ab2 += (b[k] - a[k]) * (b[k] - a[k]);
		t += (x[k] - a[k]) * (b[k] - a[k]);
	}
	t = fmin(fmax(t / ab2, 0.0), 1.0);
	double s = 0;
	for (int k = 0; k < n; k++) {
		double d = x[k] - a[k] - t * (b[k] - a[k]);
		s += d * d;
	}
	return sqrt(s);
}

static void test_corner_contour_and_peak_speed(void **state)
{
	(void)state;
	for (int trial = 0; trial < 300; trial++) {
		int n = 2 + trial % 4;
		double es[MLIP_MAX_AXES], ee[MLIP_MAX_AXES], A[MLIP_MAX_AXES];
		random_unit(n, es);
		/* turning angle from 0.5 to 170 degrees */
		double turn = (0.5 + 169.5 * urand()) * M_PI / 180.0, w[MLIP_MAX_AXES];
		random_unit(n, w);
		double dot = 0;
		for (int k = 0; k < n; k++) {
			dot += w[k] * es[k];
		}
		double nw = 0;
		for (int k = 0; k < n; k++) {
			w[k] -= dot * es[k];
			nw += w[k] * w[k];
		}
		nw = sqrt(nw);
		for (int k = 0; k < n; k++) {
			ee[k] = cos(turn) * es[k] + sin(turn) * w[k] / nw;
			A[k] = 500.0 + 5000.0 * urand();
		}
		double eps = 0.01;
		struct mlip_corner c;
		/* long segments, no speed cap: eps (18) is what binds */
		mlip_corner_plan(n, MLIP_STRATEGY_MPCT, es, ee, 1e3, 1e3, A, eps, 1e9, 1e9, 0.001,
		                 &c);
		double C0[MLIP_MAX_AXES] = {0}, S[MLIP_MAX_AXES], E[MLIP_MAX_AXES];
		for (int k = 0; k < n; k++) {
			S[k] = -1e3 * es[k];
			E[k] = 1e3 * ee[k];
		}
		double worst = 0.0, vpeak = 0.0, pm = 0.0;
		for (int i = 0; i <= 2000; i++) {
			double t = c.t_s * i / 2000.0, x[MLIP_MAX_AXES], v2 = 0, r2 = 0;
			for (int k = 0; k < n; k++) {
				double a = c.alpha_mm_s2 * ee[k] - c.beta_mm_s2 * es[k];
				x[k] = C0[k] - c.ls_mm * es[k] + c.vs_mm_s * es[k] * t +
				       0.5 * a * t * t; /* (14) */
				double v = c.vs_mm_s * es[k] + a * t;
				v2 += v * v;
				r2 += (x[k] - C0[k]) * (x[k] - C0[k]);
			}
			double d = fmin(dist_to_segment(n, x, S, C0), dist_to_segment(n, x, C0, E));
			worst = fmax(worst, d);
			vpeak = fmax(vpeak, sqrt(v2));
			if (i == 1000) {
				pm = sqrt(r2); /* |PM|, M the parabola's middle (16) */
			}
		}
		/* (17)(18): the paper's error |PM| is eps when eps binds, and bounds
		 * the real deviation from the polyline, which never exceeds eps */
		assert_near(pm, eps, 1e-9 * eps);
		assert_le(worst, eps * (1.0 + REL));
		/* Prop. 4: the corner's peak speed is max(v_s, v_e) */
		double vmax = fmax(c.vs_mm_s, c.ve_mm_s);
		assert_le(vpeak, vmax * (1.0 + 1e-12));
		assert_true(vpeak >= vmax * (1.0 - 1e-12));
	}
}

static void test_corner_caps_19_20(void **state)
{
	(void)state;
	double A[2] = {1000, 1000}, es[2] = {1, 0}, ee[2] = {0, 1};
	struct mlip_corner c;
	/* short segments: (19) l_s <= d/2 */
	mlip_corner_plan(2, MLIP_STRATEGY_MPCT, es, ee, 0.01, 0.02, A, 0.01, 1e9, 1e9, 0.001, &c);
	assert_le(c.ls_mm, 0.005 * (1 + 1e-12));
	assert_le(c.le_mm, 0.01 * (1 + 1e-12));
	assert_true(c.ls_mm >= 0.005 * (1 - 1e-12) || c.le_mm >= 0.01 * (1 - 1e-12));
	/* speed caps: (20) per neighbour */
	double es2[2] = {1, 0}, ee2[2] = {cos(0.05), sin(0.05)};
	mlip_corner_plan(2, MLIP_STRATEGY_MPCT, es2, ee2, 10, 10, A, 0.01, 50, 40, 0.001, &c);
	assert_le(c.vs_mm_s, 50 * (1 + 1e-12));
	assert_le(c.ve_mm_s, 40 * (1 + 1e-12));
	assert_true(c.vs_mm_s >= 50 * (1 - 1e-12) || c.ve_mm_s >= 40 * (1 - 1e-12));
}

/* ---- whole runs, measured from the setpoints ------------------------------ */

struct path {
	int n;
	size_t np;
	double *pts; /* np points, start first */
};

static struct mlip_machine machine(int n, double A, double vmax, double eps)
{
	struct mlip_machine m;
	memset(&m, 0, sizeof(m));
	m.n_axes = n;
	m.max_feed_mm_s = vmax;
	m.max_rot_feed_deg_s = 360;
	m.tolerance_mm = eps;
	m.period_s = 0.001;
	for (int k = 0; k < n; k++) {
		m.axis[k].letter = "XYZABC"[k];
		m.axis[k].max_accel = A * (1.0 + 0.5 * k); /* unequal on purpose */
		m.axis[k].max_vel = 10 * vmax;
		m.axis[k].min_limit = -1e9;
		m.axis[k].max_limit = 1e9;
	}
	return m;
}

enum { EV_NONE, EV_STORM, EV_HOLD_RESUME, EV_STOP, EV_DRIP };

struct run {
	struct mlip_check chk;
	uint64_t periods;
	size_t pushed;
	int stopped_idle;
	double hold_drift; /* largest movement while held and at rest */
};

/* run_path with bounded look-ahead work (mlip_planner_set_async): the
 * pre-read as the controller's (push what fits, work, until the look-ahead
 * is full or the path is in and the work done), then a period's pushes,
 * its work, its step. */
static int g_async;
/* every setpoint run_path produced, when not NULL */
static double *g_rows;
static size_t g_nrows, g_maxrows;

/* A check of p against m's limits. */
static void check_begin(struct mlip_check *c, const struct mlip_machine *m, const struct path *p)
{
	struct mlip_check_limits lim = {.n = m->n_axes,
	                                .vmax_mm_s = m->max_feed_mm_s,
	                                .vmax_rot_deg_s = m->max_rot_feed_deg_s,
	                                .eps_mm = m->tolerance_mm,
	                                .period_s = m->period_s};
	for (int k = 0; k < m->n_axes; k++) {
		lim.accel[k] = m->axis[k].max_accel;
		lim.vel[k] = m->axis[k].max_vel;
		lim.jerk[k] = m->axis[k].max_jerk;
	}
	mlip_check_init(c, &lim, p->pts, p->np);
}

/* Point i of p as a block at the machine's feed and tolerance. */
static struct mlip_block path_block(const struct mlip_machine *m, const struct path *p, size_t i)
{
	struct mlip_block b = {
	    .feed_mm_s = m->max_feed_mm_s, .tol_mm = m->tolerance_mm, .line = (uint32_t)i};
	memcpy(b.target, p->pts + i * (size_t)p->n, sizeof(double) * (size_t)p->n);
	return b;
}

/* The pre-read, as the controller's: no step until the look-ahead is full
 * (or the path is in) and planned. Returns the next point to push. */
static size_t preread(const struct mlip_machine *m, const struct path *p)
{
	size_t next = 1;
	for (;;) {
		for (uint32_t sp = mlip_planner_space(&P); sp > 0 && next < p->np; sp--) {
			struct mlip_block b = path_block(m, p, next);
			assert_int_equal(mlip_planner_push(&P, &b), MLIP_OK);
			next++;
		}
		mlip_planner_work(&P);
		if (!mlip_planner_busy(&P) && (next >= p->np || mlip_planner_space(&P) == 0)) {
			return next;
		}
	}
}

static void run_path(const struct mlip_machine *m, mlip_strategy st, const struct path *p,
                     int events, struct run *r)
{
	memset(r, 0, sizeof(*r));
	check_begin(&r->chk, m, p);
	/* only smooth gets its storage: the others plan without it */
	assert_int_equal(
	    mlip_planner_init(&P, m, st, 0, p->pts, st == MLIP_STRATEGY_SMOOTH ? &SM : NULL),
	    MLIP_OK);
	mlip_check_sample(&r->chk, p->pts);
	size_t next = 1;
	int n = m->n_axes;
	double x[MLIP_MAX_AXES], held_at[MLIP_MAX_AXES];
	int held = 0;
	uint64_t next_event = 20;
	g_nrows = 0;
	mlip_planner_set_async(&P, g_async);
	if (g_async && events != EV_DRIP) {
		next = preread(m, p);
	}
	for (;;) {
		int budget = events == EV_DRIP ? (r->periods % 7 == 0) : MLIP_INGEST_PER_PERIOD;
		if (r->periods == 0 && events != EV_DRIP && !g_async) {
			budget = MLIP_LOOKAHEAD;
		}
		for (int i = 0; i < budget && next < p->np && mlip_planner_space(&P) > 0; i++) {
			struct mlip_block b = path_block(m, p, next);
			if (mlip_planner_push(&P, &b) == MLIP_E_INVALID) {
				break; /* stopping */
			}
			next++;
		}
		if (r->periods == next_event) {
			next_event += 3 + (uint64_t)(urand() * 120);
			if (events == EV_STORM) {
				double u = urand();
				if (P.hold || P.override == 0.0) {
					mlip_planner_hold(&P, 0);
					mlip_planner_set_override(&P, 20 + 180 * urand());
				} else if (u < 0.15) {
					mlip_planner_hold(&P, 1);
				} else if (u < 0.25) {
					mlip_planner_set_override(&P, 0.0);
				} else {
					mlip_planner_set_override(&P, 200.0 * urand());
				}
			} else if (events == EV_HOLD_RESUME) {
				/* toggles until 20,000 periods, then resumed for good
				 * (an odd number of toggles left it held forever) */
				mlip_planner_hold(&P, r->periods < 20000 ? !P.hold : 0);
			} else if (events == EV_STOP && r->periods >= 1500 && !P.stopping) {
				mlip_planner_stop(&P);
				next = p->np; /* the operator's stop ends the program */
			}
		}
		mlip_planner_work(&P);
		mlip_run_state rs = mlip_planner_step(&P, x);
		r->periods++;
		mlip_check_sample(&r->chk, x);
		if (g_rows != NULL && g_nrows < g_maxrows) {
			memcpy(g_rows + g_nrows * (size_t)n, x, sizeof(double) * (size_t)n);
			g_nrows++;
		}
		if (rs == MLIP_RUN_HELD) {
			if (!held) {
				memcpy(held_at, x, sizeof(held_at));
				held = 1;
			}
			for (int k = 0; k < n; k++) {
				r->hold_drift = fmax(r->hold_drift, fabs(x[k] - held_at[k]));
			}
		} else {
			held = 0;
		}
		if (rs == MLIP_RUN_IDLE && next >= p->np) {
			break;
		}
		assert_true(r->periods < 50000000);
	}
	r->pushed = next;
	r->stopped_idle = mlip_planner_queued(&P) == 0;
}

/* Assert the physics: every limit within REL above, and used (>= lower) below. */
static void assert_physics(const struct mlip_machine *m, const struct run *r, double used_min,
                           int ends_on_last)
{
	char msg[1024];
	int bad = mlip_check_verdict(&r->chk, REL, mlip_check_rounding_floor(&r->chk), 0.0,
	                             ends_on_last ? 1e-9 : INFINITY, msg, sizeof(msg));
	if (bad) {
		fail_msg("%s", msg);
	}
	double best = 0.0;
	for (int k = 0; k < m->n_axes; k++) {
		best = fmax(best, r->chk.max_acc[k] / m->axis[k].max_accel);
	}
	assert_true(best >= used_min);
	/* the trace ends at rest: the last period decelerates at most A T */
	double amax = 0;
	for (int k = 0; k < m->n_axes; k++) {
		amax = fmax(amax, m->axis[k].max_accel);
	}
	assert_le(mlip_check_end_speed(&r->chk), amax * m->period_s);
}

static struct path make_path(int n, int kind, size_t segs)
{
	struct path p = {.n = n, .np = segs + 1};
	p.pts = calloc(p.np * (size_t)n, sizeof(double));
	double dir[MLIP_MAX_AXES];
	random_unit(n, dir);
	for (size_t i = 1; i < p.np; i++) {
		double *x = p.pts + i * (size_t)n, *prev = x - n;
		if (kind == 0) { /* spiral in the first two axes, ramps on the others */
			double t = 0.004 * (double)i, r = 10 + t;
			x[0] = r * cos(t) - 10;
			x[1] = r * sin(t);
			for (int k = 2; k < n; k++) {
				x[k] = 0.01 * (double)i * (k % 2 ? 1 : -1);
			}
		} else if (kind == 1) { /* random walk with 0.05-0.5 mm steps */
			double step[MLIP_MAX_AXES], len = 0.05 + 0.45 * urand();
			random_unit(n, step);
			for (int k = 0; k < n; k++) {
				dir[k] = 0.8 * dir[k] + 0.6 * step[k];
			}
			double s = 0;
			for (int k = 0; k < n; k++) {
				s += dir[k] * dir[k];
			}
			for (int k = 0; k < n; k++) {
				dir[k] /= sqrt(s);
				x[k] = prev[k] + len * dir[k];
			}
		} else { /* raster: back and forth with exact reversals and collinear runs */
			size_t row = (i - 1) / 40, col = (i - 1) % 40;
			x[0] = (row % 2 ? 40.0 - (double)col : (double)col + 1.0) * 0.25;
			x[1] = (double)(row / 3) * 0.2;
			for (int k = 2; k < n; k++) {
				x[k] = 0.1 * sin(0.3 * (double)i);
			}
		}
	}
	return p;
}

static void test_run_all_strategies(void **state)
{
	(void)state;
	static const int axes[] = {2, 3, 5};
	for (int ai = 0; ai < 3; ai++) {
		for (int kind = 0; kind < 3; kind++) {
			struct path p = make_path(axes[ai], kind, 3000);
			struct mlip_machine m = machine(axes[ai], 1000, 200, 0.01);
			for (int st = 0; st < 3; st++) {
				struct run r;
				run_path(&m, (mlip_strategy)st, &p, EV_NONE, &r);
				print_message("%d axes, path %d, strategy %d: %.3f s\n", axes[ai],
				              kind, st, (double)r.periods * m.period_s);
				assert_physics(&m, &r, 0.5, 1);
			}
			free(p.pts);
		}
	}
}

static void test_mpct_faster_than_baselines(void **state)
{
	(void)state;
	struct path p = make_path(2, 0, 6000);
	struct mlip_machine m = machine(2, 1000, 400, 0.01);
	uint64_t t[3];
	for (int st = 0; st < 3; st++) {
		struct run r;
		run_path(&m, (mlip_strategy)st, &p, EV_NONE, &r);
		t[st] = r.periods;
	}
	assert_true(t[MLIP_STRATEGY_MPCT] < t[MLIP_STRATEGY_BISECTOR]);
	assert_true(t[MLIP_STRATEGY_BISECTOR] < t[MLIP_STRATEGY_STOP]);
	free(p.pts);
}

static void test_eps_binds_end_to_end(void **state)
{
	/* two long segments with a shallow turn, a fine period so the samples
	 * resolve the corner: the measured contour error reaches eps within
	 * 1 % and never exceeds it */
	(void)state;
	struct mlip_machine m = machine(2, 1000, 2000, 0.01);
	m.period_s = 1e-5;
	m.axis[1].max_accel = m.axis[0].max_accel;
	/* symmetric about the X axis with equal limits, so alpha = beta and
	 * the deviation from the polyline is eps cos(turn / 2) (17): 0.1 rad */
	double pts[6] = {0, 0, 100 * cos(0.05), -100 * sin(0.05), 200 * cos(0.05), 0};
	struct path p = {.n = 2, .np = 3, .pts = pts};
	struct run r;
	run_path(&m, MLIP_STRATEGY_MPCT, &p, EV_NONE, &r);
	assert_le(r.chk.max_contour_mm, 0.01 * (1 + REL));
	assert_true(r.chk.max_contour_mm >= 0.99 * 0.01 * cos(0.05));
	assert_physics(&m, &r, 0.99, 1);
}

/* Push a path block by block (running when full); every `every` blocks a
 * full pass must leave every q (and shape) as the early-terminated passes
 * left them. Returns how many braking shapes (smooth) it saw. */
static int plan_equals_full_pass(const struct path *p, const struct mlip_machine *m,
                                 mlip_strategy st, uint32_t cap, size_t every)
{
	static double q[MLIP_LOOKAHEAD];
	static uint8_t sh[MLIP_LOOKAHEAD];
	int n = p->n, braking = 0;
	assert_int_equal(
	    mlip_planner_init(&P, m, st, cap, p->pts, st == MLIP_STRATEGY_SMOOTH ? &SM : NULL),
	    MLIP_OK);
	double x[MLIP_MAX_AXES];
	for (size_t i = 1; i < p->np; i++) {
		struct mlip_block b = {.feed_mm_s = 200, .tol_mm = 0.01, .line = (uint32_t)i};
		memcpy(b.target, p->pts + i * (size_t)n, sizeof(double) * (size_t)n);
		while (mlip_planner_space(&P) == 0) {
			mlip_planner_step(&P, x);
		}
		assert_int_equal(mlip_planner_push(&P, &b), MLIP_OK);
		if (i % every == 0) {
			for (uint32_t j = P.tail; j != P.head; j++) {
				const struct mlip_seg *g = &P.seg[j & (P.cap - 1)];
				uint8_t shape = P.sm != NULL ? P.sm[j & (P.cap - 1)].shape : 0;
				q[j & (P.cap - 1)] = g->q;
				sh[j & (P.cap - 1)] = shape;
				braking += shape > 0 && shape != MLIP_SHAPE_FIXED;
			}
			mlip_planner_set_override(&P, 100.0); /* full pass */
			for (uint32_t j = P.tail; j != P.head; j++) {
				assert_true(q[j & (P.cap - 1)] == P.seg[j & (P.cap - 1)].q);
				assert_int_equal(sh[j & (P.cap - 1)],
				                 P.sm != NULL ? P.sm[j & (P.cap - 1)].shape : 0);
			}
		}
	}
	return braking;
}

static void test_termination_condition_is_exact(void **state)
{
	/* the early-terminated backward pass leaves exactly what a full pass
	 * computes (Sec. 2.1's termination condition loses nothing) */
	(void)state;
	struct path p = make_path(3, 1, 3000);
	struct mlip_machine m = machine(3, 1000, 200, 0.01);
	plan_equals_full_pass(&p, &m, MLIP_STRATEGY_MPCT, 1024, 97);
	free(p.pts);
}

static void push_n_same_plan(int n, int kind, int zigzag)
{
	struct path p = make_path(n, kind, 3000);
	if (zigzag) {
		/* sharp zigzag: corners whose optimum has v_e = 0 (alpha = 0) */
		for (size_t i = 1; i < p.np; i++) {
			p.pts[i * (size_t)n] = 0.15 * (double)i;
			p.pts[i * (size_t)n + 1] = (i / 50 % 2) ? 5.0 * sin(0.3 * (double)i) : 0.0;
		}
	}
	struct mlip_machine m = machine(n, 1000, 200, 0.01);
	static struct mlip_block b[3000];
	static double q1[MLIP_LOOKAHEAD];
	for (size_t i = 0; i < 3000; i++) {
		b[i] = (struct mlip_block){.feed_mm_s = 150, .tol_mm = 0.01, .line = (uint32_t)i};
		memcpy(b[i].target, p.pts + (i + 1) * (size_t)n, sizeof(double) * (size_t)n);
	}
	assert_int_equal(mlip_planner_init(&P, &m, MLIP_STRATEGY_MPCT, 0, p.pts, NULL), MLIP_OK);
	for (size_t i = 0; i < 3000; i++) {
		assert_int_equal(mlip_planner_push(&P, &b[i]), MLIP_OK);
	}
	for (uint32_t j = 0; j < P.head; j++) {
		q1[j] = P.seg[j].q;
	}
	/* and single pushes equal a full pass */
	mlip_planner_set_override(&P, 100.0);
	for (uint32_t j = 0; j < P.head; j++) {
		assert_true(q1[j] == P.seg[j].q);
	}
	assert_int_equal(mlip_planner_init(&P, &m, MLIP_STRATEGY_MPCT, 0, p.pts, NULL), MLIP_OK);
	size_t done = 0;
	while (done < 3000) {
		size_t k = 1 + (done * 7) % 23;
		k = k < 3000 - done ? k : 3000 - done;
		assert_int_equal(mlip_planner_push_n(&P, b + done, k, NULL), k);
		done += k;
	}
	for (uint32_t j = 0; j < P.head; j++) {
		assert_true(q1[j] == P.seg[j].q);
	}
	free(p.pts);
}

static void test_push_n_same_plan(void **state)
{
	/* one backward pass per batch leaves the plan n single pushes leave,
	 * which is the plan a full pass computes */
	(void)state;
	push_n_same_plan(3, 1, 0);
	push_n_same_plan(2, 2, 0);
	push_n_same_plan(2, 0, 1);
}

static void test_sharp_corner_zero_side_does_not_stop(void **state)
{
	/* a corner whose optimum has v_e = 0 still passes at v_s > 0 */
	(void)state;
	double A[2] = {1000, 1000}, es[2] = {0.573708, -0.81906}, ee[2] = {0.542164, 0.840273};
	double ne = hypot(es[0], es[1]), nn = hypot(ee[0], ee[1]);
	es[0] /= ne;
	es[1] /= ne;
	ee[0] /= nn;
	ee[1] /= nn;
	struct mlip_corner c;
	mlip_corner_plan(2, MLIP_STRATEGY_MPCT, es, ee, 1, 1, A, 0.01, 200, 200, 0.001, &c);
	assert_true(c.ve_mm_s == 0.0 && c.vs_mm_s > 1.0);
	struct mlip_machine m = machine(2, 1000, 200, 0.01);
	m.axis[1].max_accel = 1000;
	double start[2] = {0, 0};
	assert_int_equal(mlip_planner_init(&P, &m, MLIP_STRATEGY_MPCT, 0, start, NULL), MLIP_OK);
	struct mlip_block b1 = {
	    .target = {es[0] * 20, es[1] * 20}, .feed_mm_s = 200, .tol_mm = 0.01};
	struct mlip_block b2 = {.target = {es[0] * 20 + ee[0] * 20, es[1] * 20 + ee[1] * 20},
	                        .feed_mm_s = 200,
	                        .tol_mm = 0.01};
	mlip_planner_push(&P, &b1);
	mlip_planner_push(&P, &b2);
	assert_true(P.seg[0].q > 0.99); /* limited by nothing but its geometry */
}

static void test_override_storm(void **state)
{
	(void)state;
	for (int kind = 0; kind < 3; kind++) {
		struct path p = make_path(3, kind, 4000);
		struct mlip_machine m = machine(3, 1500, 250, 0.01);
		for (int st = 0; st < 3; st++) {
			struct run r;
			run_path(&m, (mlip_strategy)st, &p, EV_STORM, &r);
			assert_physics(&m, &r, 0.5, 1);
			assert_le(r.hold_drift, 1e-12); /* the same vertex seen from two segments */
		}
		free(p.pts);
	}
}

static void test_hold_resume_on_path(void **state)
{
	(void)state;
	struct path p = make_path(2, 1, 3000);
	struct mlip_machine m = machine(2, 800, 200, 0.01);
	struct run r;
	run_path(&m, MLIP_STRATEGY_MPCT, &p, EV_HOLD_RESUME, &r);
	assert_physics(&m, &r, 0.5, 1);
	assert_le(r.hold_drift, 1e-12); /* held means not moving (1e-12: rounding) */
	free(p.pts);
}

static void test_stop_is_controlled(void **state)
{
	(void)state;
	struct path p = make_path(3, 0, 5000);
	struct mlip_machine m = machine(3, 1000, 200, 0.01);
	struct run r;
	run_path(&m, MLIP_STRATEGY_MPCT, &p, EV_STOP, &r);
	/* stops on the path, inside the limits, then idle with nothing queued */
	assert_physics(&m, &r, 0.5, 0);
	assert_true(r.stopped_idle);
	assert_true(mlip_check_end_error(&r.chk) > 1.0); /* well before the end */
	/* and stays where it stopped */
	double x[3];
	assert_int_equal(mlip_planner_step(&P, x), MLIP_RUN_IDLE);
	for (int k = 0; k < 3; k++) {
		assert_near(x[k], r.chk.x1[k], 0.0);
	}
	free(p.pts);
}

static void test_running_dry_is_safe(void **state)
{
	/* blocks arrive slower than they are consumed: the newest block always
	 * plans to rest, so the machine slows, stops if it must, and resumes */
	(void)state;
	struct path p = make_path(2, 0, 1500);
	struct mlip_machine m = machine(2, 2000, 300, 0.01);
	struct run r;
	run_path(&m, MLIP_STRATEGY_MPCT, &p, EV_DRIP, &r);
	assert_physics(&m, &r, 0.5, 1);
	free(p.pts);
}

/* ---- smooth: braking shapes (beyond the paper) ---------------------------- */

/* Every shape mlip_corner_smooth_shapes offers keeps the corner's
 * guarantees on random corners, gentle to sharp: |a_k| <= A_k, a on the
 * polygon's boundary, (18) deviation <= eps, (19) l <= d / 2, (20) v <=
 * caps, beta above the line's limit (B > 0); shapes 1.. brake harder than
 * shape 0 (v_e / v_s smaller, so a tilts toward -e). Relative 1e-12. */
static void test_smooth_shapes_keep_guarantees(void **state)
{
	(void)state;
	int offered = 0, corners = 0;
	for (int it = 0; it < 4000; it++) {
		int n = 2 + it % 3;
		double es[MLIP_MAX_AXES], ee[MLIP_MAX_AXES], A[MLIP_MAX_AXES], turn[MLIP_MAX_AXES];
		random_unit(n, es);
		random_unit(n, turn);
		double th = it % 4 == 0 ? 1.0 : 1e-3 * pow(100.0, urand()); /* gentle: CAM curves */
		double ne = 0.0;
		for (int k = 0; k < n; k++) {
			ee[k] = es[k] + th * turn[k];
			ne += ee[k] * ee[k];
			A[k] = 500.0 + 5500.0 * urand();
		}
		for (int k = 0; k < n; k++) {
			ee[k] /= sqrt(ne);
		}
		double ds = 0.005 + 0.5 * urand(), de = 0.005 + 0.5 * urand();
		double eps = 0.001 + 0.01 * urand();
		double vs = 10.0 + 200.0 * urand(), ve = 10.0 + 200.0 * urand();
		struct mlip_corner sh[MLIP_SMOOTH_SHAPES];
		double w[MLIP_SMOOTH_SHAPES];
		int m = mlip_corner_smooth_shapes(n, es, ee, ds, de, A, eps, vs, ve, sh, w);
		assert_true(m >= 1 && m <= MLIP_SMOOTH_SHAPES);
		if (sh[0].t_s == 0.0) {
			assert_int_equal(m, 1);
			continue;
		}
		corners++;
		offered += m > 1;
		double a_line = INFINITY;
		for (int k = 0; k < n; k++) {
			a_line = fmin(a_line, A[k] / fabs(es[k]));
		}
		for (int j = 0; j < m; j++) {
			const struct mlip_corner *c = &sh[j];
			double a2 = 0.0, amax = 0.0;
			for (int k = 0; k < n; k++) {
				double ak = c->alpha_mm_s2 * ee[k] - c->beta_mm_s2 * es[k];
				double round_off =
				    8.0 * DBL_EPSILON * (c->alpha_mm_s2 + c->beta_mm_s2);
				assert_le(fabs(ak), A[k] * (1.0 + 1e-12) + round_off);
				amax = fmax(amax, fabs(ak) / A[k]);
				a2 += ak * ak;
			}
			assert_true(amax >= 1.0 - 1e-9);
			assert_le(sqrt(a2) * c->t_s * c->t_s / 8.0, eps * (1.0 + 1e-12));
			assert_le(c->ls_mm, 0.5 * ds * (1.0 + 1e-12));
			assert_le(c->le_mm, 0.5 * de * (1.0 + 1e-12));
			assert_le(c->vs_mm_s, vs * (1.0 + 1e-12));
			assert_le(c->ve_mm_s, ve * (1.0 + 1e-12));
			assert_near(c->vs_mm_s, c->beta_mm_s2 * c->t_s, 1e-9 * c->vs_mm_s);
			assert_near(c->ls_mm, 0.5 * c->vs_mm_s * c->t_s, 1e-9 * c->ls_mm); /* (5) */
			if (j > 0) {
				/* the planner rebuilds it from w: the very same corner */
				struct mlip_corner r;
				int rc = mlip_corner_smooth_w(n, es, ee, ds, de, A, eps, vs, ve,
				                              w[j], &r);
				assert_int_equal(rc, 0);
				assert_true(memcmp(&r, c, sizeof(r)) == 0);
				assert_true(c->beta_mm_s2 > a_line);
				assert_true(c->alpha_mm_s2 * sh[0].beta_mm_s2 <
				            sh[0].alpha_mm_s2 * c->beta_mm_s2);
			}
		}
	}
	assert_true(corners > 3000);
	assert_true(offered > corners / 2); /* the gentle corners do get braking shapes */
}

/* A smooth curve in 0.02 mm segments rounded to 4 decimals (where the
 * braking shapes matter): positions of a Lissajous figure. */
static struct path make_fine_curve(size_t segs)
{
	struct path p = {.n = 2, .np = segs + 1};
	p.pts = calloc(p.np * 2, sizeof(double));
	double t = 0.0;
	for (size_t i = 0; i < p.np; i++) {
		/* |x'(t)| <= 180: steps of 0.02 / 180 ... in t, refined by arc length */
		double x = 40.0 * cos(3.0 * t), y = 30.0 * sin(4.0 * t);
		p.pts[2 * i] = round(x * 1e4) / 1e4;
		p.pts[2 * i + 1] = round(y * 1e4) / 1e4;
		double sp = hypot(120.0 * sin(3.0 * t), 120.0 * cos(4.0 * t));
		t += 0.02 / fmax(sp, 1.0);
	}
	return p;
}

/* The path mlip-feed sends with the smooth strategy: the filter's output
 * (mlip_smooth_program) for p, from its first point. */
static struct path smoothed_path(const struct path *p, const struct mlip_machine *m)
{
	size_t n = p->np - 1, nout = 0, w = (size_t)p->n;
	struct mlip_machine mh = *m;
	struct mlip_block *b = calloc(n, sizeof(*b)), *out = NULL;
	for (int k = 0; k < p->n; k++) {
		mh.axis[k].home = p->pts[k];
	}
	for (size_t i = 0; i < n; i++) {
		b[i] = (struct mlip_block){.feed_mm_s = m->max_feed_mm_s,
		                           .tol_mm = m->tolerance_mm,
		                           .line = (uint32_t)i + 1};
		memcpy(b[i].target, p->pts + (i + 1) * w, sizeof(double) * w);
	}
	assert_int_equal(mlip_smooth_program(&mh, b, n, &out, &nout), 0);
	struct path q = {.n = p->n, .np = nout + 1};
	q.pts = calloc(q.np * w, sizeof(double));
	memcpy(q.pts, p->pts, sizeof(double) * w);
	for (size_t i = 0; i < nout; i++) {
		memcpy(q.pts + (i + 1) * w, out[i].target, sizeof(double) * w);
	}
	free(b);
	free(out);
	return q;
}

/*
 * The motion depends on which blocks are queued when, never on how they
 * were pushed: the same blocks per period, pushed as one batch, one by one
 * or in random sub-batches (a feeder's timing: the controller takes what
 * the ring holds, up to MLIP_PREREAD_PER_PERIOD or MLIP_INGEST_PER_PERIOD),
 * give the same setpoints to the bit. The pre-read (everything until the
 * look-ahead is full) is split the same ways. A smooth corner's shape once
 * depended on the passes its batches made: a CAN run's bus differed from
 * mlip-sim by one count (tests/can, test_mb23_smooth_exact).
 */
static size_t run_batched(const struct path *p, const struct mlip_machine *m, mlip_strategy st,
                          uint32_t cap, int split, double *out, size_t max)
{
	int n = p->n;
	uint64_t counts = 0x9E3779B97F4A7C15ULL, splits = 0xD1B54A32D192ED03ULL;
	assert_int_equal(
	    mlip_planner_init(&P, m, st, cap, p->pts, st == MLIP_STRATEGY_SMOOTH ? &SM : NULL),
	    MLIP_OK);
	static struct mlip_block b[40000];
	assert_true(p->np - 1 <= 40000);
	for (size_t i = 1; i < p->np; i++) {
		b[i - 1] =
		    (struct mlip_block){.feed_mm_s = 200, .tol_mm = 0.01, .line = (uint32_t)i};
		memcpy(b[i - 1].target, p->pts + i * (size_t)n, sizeof(double) * (size_t)n);
	}
	size_t next = 0, total = p->np - 1, k = 0;
	for (int pre = 1;; pre = 0) {
		/* how many this period: the same in every run */
		counts = counts * 6364136223846793005ULL + 1442695040888963407ULL;
		size_t want = pre ? 4096 : (size_t)(counts >> 33) % 17;
		want = want < total - next ? want : total - next;
		want = want < mlip_planner_space(&P) ? want : mlip_planner_space(&P);
		while (want > 0) {
			size_t k1 = want;
			if (split == 1) {
				k1 = 1;
			} else if (split == 2) {
				splits = splits * 6364136223846793005ULL + 1442695040888963407ULL;
				k1 = 1 + (size_t)(splits >> 33) % 97;
				k1 = k1 < want ? k1 : want;
			}
			assert_int_equal(mlip_planner_push_n(&P, b + next, k1, NULL), k1);
			next += k1;
			want -= k1;
		}
		double x[MLIP_MAX_AXES];
		mlip_run_state rs = mlip_planner_step(&P, x);
		assert_true(k < max);
		memcpy(out + k * (size_t)n, x, sizeof(double) * (size_t)n);
		k++;
		if (rs == MLIP_RUN_IDLE && next == total) {
			return k;
		}
	}
}

static void test_batches_same_setpoints(void **state)
{
	(void)state;
	struct path curve = make_fine_curve(6000);
	struct path walk = make_path(3, 1, 3000);
	const struct path *paths[2] = {&curve, &walk};
	size_t max = 200000;
	double *ref = malloc(max * 3 * sizeof(double)), *got = malloc(max * 3 * sizeof(double));
	for (int pi = 0; pi < 2; pi++) {
		const struct path *p = paths[pi];
		struct mlip_machine m = machine(p->n, 1000, 200, 0.01);
		for (int st = 0; st < MLIP_STRATEGY_COUNT; st++) {
			for (uint32_t cap = 1024; cap <= 4096; cap *= 4) {
				size_t n0 = run_batched(p, &m, (mlip_strategy)st, cap, 0, ref, max);
				for (int split = 1; split <= 2; split++) {
					size_t n1 = run_batched(p, &m, (mlip_strategy)st, cap,
					                        split, got, max);
					size_t bad = 0;
					while (bad < n0 && bad < n1 &&
					       memcmp(ref + bad * (size_t)p->n,
					              got + bad * (size_t)p->n,
					              sizeof(double) * (size_t)p->n) == 0) {
						bad++;
					}
					if (n0 != n1 || bad != n0) {
						fail_msg(
						    "path %d, strategy %s, look-ahead %u, batches "
						    "%d: "
						    "%zu / %zu setpoints, the first differs at %zu",
						    pi, mlip_strategy_name((mlip_strategy)st), cap,
						    split, n0, n1, bad);
					}
				}
			}
		}
	}
	free(ref);
	free(got);
	free(curve.pts);
	free(walk.pts);
}

/* ---- bounded work a period (mlip_planner_set_async) ----------------------- */

/* The look-ahead's work done a bounded amount a period ends in the plan
 * done at once: with every block at hand and no command, the same
 * setpoints to the bit, every strategy, with and without a jerk limit, on
 * a fine curve longer than the look-ahead (the plan keeps up with the
 * motion) and a random walk; under override storms, holds, a stop and
 * blocks dripping in (the work then lags the commands by periods) every
 * limit holds. */
static void test_bounded_work(void **state)
{
	(void)state;
	/* the curve's 20,000 segments of 0.02 mm are five look-aheads, and
	 * smoothed (as mlip-feed sends them to smooth) it is run at up to
	 * 200 mm/s: the work has to keep up with 10 segments a period */
	struct path walk = make_path(3, 1, 2500), curve = make_fine_curve(20000);
	const struct path *paths[2] = {&walk, &curve};
	g_maxrows = 400000;
	double *ref = malloc(g_maxrows * 3 * sizeof(double));
	double *got = malloc(g_maxrows * 3 * sizeof(double));
	static const int events[] = {EV_STORM, EV_HOLD_RESUME, EV_STOP, EV_DRIP};
	for (int pi = 0; pi < 2; pi++) {
		const struct path *raw = paths[pi];
		for (int jerk = 0; jerk < 2; jerk++) {
			struct mlip_machine m = machine(raw->n, 1000, 200, 0.01);
			for (int k = 0; jerk && k < raw->n; k++) {
				m.axis[k].max_jerk = 1e5;
			}
			struct path sp = smoothed_path(raw, &m);
			for (int st = 0; st < MLIP_STRATEGY_COUNT; st++) {
				const struct path *p = st == MLIP_STRATEGY_SMOOTH ? &sp : raw;
				struct run r;
				g_async = 0;
				g_rows = ref;
				run_path(&m, (mlip_strategy)st, p, EV_NONE, &r);
				size_t n0 = g_nrows;
				g_async = 1;
				g_rows = got;
				run_path(&m, (mlip_strategy)st, p, EV_NONE, &r);
				g_rows = NULL;
				size_t same = 0;
				while (same < n0 && same < g_nrows &&
				       memcmp(ref + same * (size_t)p->n, got + same * (size_t)p->n,
				              sizeof(double) * (size_t)p->n) == 0) {
					same++;
				}
				if (same != n0 || n0 != g_nrows) {
					fail_msg(
					    "path %d, jerk %d, %s: %zu / %zu setpoints, the first "
					    "differs at %zu",
					    pi, jerk, mlip_strategy_name((mlip_strategy)st), n0,
					    g_nrows, same);
				}
				assert_physics(&m, &r, jerk ? 0.01 : 0.5, 1);
				for (int e = 0; e < 4; e++) {
					run_path(&m, (mlip_strategy)st, p, events[e], &r);
					char msg[1024];
					if (mlip_check_verdict(
					        &r.chk, REL, mlip_check_rounding_floor(&r.chk), 0.0,
					        events[e] == EV_STOP ? INFINITY : 1e-9, msg,
					        sizeof(msg))) {
						fail_msg("path %d, jerk %d, %s, events %d: %s", pi,
						         jerk,
						         mlip_strategy_name((mlip_strategy)st),
						         events[e], msg);
					}
				}
				g_async = 0;
			}
			free(sp.pts);
		}
	}
	free(ref);
	free(got);
	free(walk.pts);
	free(curve.pts);
}

/* ---- the jerk limit (mlip/motion/jerk.h) ---------------------------------- */

/* The mean's parameters (J4, J5): an odd window, the longest whose E_f
 * takes at most half of eps; the plan's accelerations min(A, J m T / 2);
 * nothing at all without a limit (the planner then is the paper's). */
static void test_jerk_plan(void **state)
{
	(void)state;
	struct mlip_machine m = machine(3, 1000, 200, 0.01);
	struct mlip_jerk_plan jp;
	assert_int_equal(mlip_jerk_plan(&m, &jp), 0);
	assert_int_equal(jp.taps, 1);
	assert_true(jp.filter_mm == 0.0);
	for (int k = 0; k < 3; k++) {
		assert_true(jp.accel[k] == m.axis[k].max_accel);
	}
	static const double jerks[] = {1e3, 1e4, 1e5, 1e6, 1e9};
	for (int i = 0; i < 5; i++) {
		for (int k = 0; k < 3; k++) {
			m.axis[k].max_jerk = k == 2 ? 0.0 : jerks[i]; /* Z without a limit */
		}
		assert_int_equal(mlip_jerk_plan(&m, &jp), 1);
		assert_true(jp.taps >= 1 && jp.taps < MLIP_JERK_MAX_TAPS && jp.taps % 2 == 1);
		double a2 = 0.0, mt = (double)jp.taps;
		for (int k = 0; k < 3; k++) {
			double want = k == 2 ? m.axis[k].max_accel
			                     : fmin(m.axis[k].max_accel,
			                            0.5 * jerks[i] * mt * 1e-3 * (1.0 - 1e-6));
			assert_near(jp.accel[k], want, 1e-12 * want);
			a2 += jp.accel[k] * jp.accel[k];
		}
		double ef = sqrt(a2) * 1e-6 * (mt * mt - 1.0) / 24.0;
		assert_near(jp.filter_mm, ef, 1e-15);
		assert_le(jp.filter_mm, 0.5 * m.tolerance_mm);
		/* the next window (2 more) would take more than half, or gain
		 * nothing (every axis at A) */
		if (jp.taps + 2 < MLIP_JERK_MAX_TAPS && jp.accel[0] < m.axis[0].max_accel) {
			double a[MLIP_MAX_AXES];
			for (int k = 0; k < 3; k++) {
				a[k] = k == 2
				           ? m.axis[k].max_accel
				           : fmin(m.axis[k].max_accel,
				                  0.5 * jerks[i] * (mt + 2) * 1e-3 * (1.0 - 1e-6));
			}
			assert_true(mlip_jerk_filter_mm(3, a, jp.taps + 2, 1e-3) >
			            0.5 * m.tolerance_mm);
		}
		print_message("J %g: %d taps, A' %.1f, E_f %.5f mm\n", jerks[i], jp.taps,
		              jp.accel[0], jp.filter_mm);
	}
}

/* Every part of the motion keeps each axis's jerk limit at every sample
 * (third difference / T^3 within J (1 + REL) + the rounding floor), with
 * every other limit and the contour: lines, corners, the look-ahead's stops,
 * override storms, hold and resume, a stop, blocks arriving too slowly, the
 * start and the end, every strategy; and the limit is used (above half of J
 * on some axis, with every block at hand: a bound asserted from both sides). */
static void test_jerk_every_part(void **state)
{
	(void)state;
	struct path walk = make_path(3, 1, 1500), curve = make_fine_curve(4000);
	const struct path *paths[2] = {&walk, &curve};
	static const int events[] = {EV_NONE, EV_STORM, EV_HOLD_RESUME, EV_STOP, EV_DRIP};
	for (int pi = 0; pi < 2; pi++) {
		const struct path *p = paths[pi];
		for (int ji = 0; ji < 2; ji++) {
			double J = ji == 0 ? 1e4 : 1e5;
			struct mlip_machine m = machine(p->n, 1000, 200, 0.01);
			for (int k = 0; k < p->n; k++) {
				m.axis[k].max_jerk = J * (1.0 + 0.25 * k); /* unequal on purpose */
			}
			for (int st = 0; st < MLIP_STRATEGY_COUNT; st++) {
				for (int e = 0; e < 5; e++) {
					struct run r;
					run_path(&m, (mlip_strategy)st, p, events[e], &r);
					char msg[1024];
					int bad = mlip_check_verdict(
					    &r.chk, REL, mlip_check_rounding_floor(&r.chk), 0.0,
					    events[e] == EV_STOP ? INFINITY : 1e-9, msg,
					    sizeof(msg));
					if (bad) {
						fail_msg("path %d, J %g, %s, events %d: %s", pi, J,
						         mlip_strategy_name((mlip_strategy)st),
						         events[e], msg);
					}
					double used = 0.0;
					for (int k = 0; k < p->n; k++) {
						used = fmax(used,
						            r.chk.max_jerk[k] / m.axis[k].max_jerk);
					}
					if (events[e] == EV_NONE || events[e] == EV_STORM) {
						assert_true(used > 0.5); /* blocks dripping in
						                            move gently */
					}
					if (e == 0) {
						print_message(
						    "path %d, J %g, %s: %.3f s, jerk used %.4f\n",
						    pi, J, mlip_strategy_name((mlip_strategy)st),
						    (double)r.periods * m.period_s, used);
					}
				}
			}
		}
	}
	free(walk.pts);
	free(curve.pts);
}

/* Stalls every 61 periods on make_path(2, 1, 600) scaled 5x (0.25-2.5 mm
 * steps: fast, a mean lags by a segment), every strategy, each checked for
 * every limit (the jerk's when m has one) and eps: back 0, the loop missed
 * periods (mlip_planner_rest_here); back 1, the period's setpoint was
 * computed but never sent, the drives stand at the one before
 * (mlip_planner_rest_back). */
static void stall_runs(const struct mlip_machine *mach, int back)
{
	struct path p = make_path(2, 1, 600);
	for (size_t i = 0; i < 2 * p.np; i++) {
		p.pts[i] *= 5.0;
	}
	struct mlip_machine m = *mach;
	struct mlip_check_limits lim = {
	    .n = 2, .vmax_mm_s = 200, .vmax_rot_deg_s = 360, .eps_mm = 0.01, .period_s = 0.001};
	for (int k = 0; k < 2; k++) {
		lim.accel[k] = m.axis[k].max_accel;
		lim.vel[k] = m.axis[k].max_vel;
		lim.jerk[k] = m.axis[k].max_jerk;
	}
	static struct mlip_check chk;
	for (int st = 0; st < MLIP_STRATEGY_COUNT; st++) {
		mlip_check_init(&chk, &lim, p.pts, p.np);
		assert_int_equal(mlip_planner_init(&P, &m, (mlip_strategy)st, 0, p.pts,
		                                   st == MLIP_STRATEGY_SMOOTH ? &SM : NULL),
		                 MLIP_OK);
		mlip_check_sample(&chk, p.pts);
		size_t next = 1;
		int stalls = 0, resume_at = -1;
		double sent[2] = {p.pts[0], p.pts[1]};
		for (int k = 0; k < 2000000; k++) {
			for (int i = 0; i < 16 && next < p.np && mlip_planner_space(&P) > 0; i++) {
				struct mlip_block b = {.feed_mm_s = 200, .tol_mm = 0.01};
				memcpy(b.target, p.pts + next * 2, sizeof(double) * 2);
				assert_int_equal(mlip_planner_push(&P, &b), MLIP_OK);
				next++;
			}
			int stall = k % 61 == 30 && mlip_planner_moving(&P);
			if (stall && !back) {
				mlip_planner_rest_here(&P); /* 3 periods missed */
				mlip_check_gap(&chk, 4);
			}
			if (stall) {
				stalls++;
				resume_at = k + 5;
			}
			if (k == resume_at) {
				mlip_planner_hold(&P, 0);
			}
			double x[2];
			mlip_run_state rs = mlip_planner_step(&P, x);
			if (stall && back) {
				/* x never went out: the drives stand at `sent` */
				mlip_planner_rest_back(&P, sent);
				mlip_check_gap(&chk, 4);
				continue;
			}
			if (stall || k == resume_at + 1 - 5) {
				/* the first sample after the hole: where the drives stood */
				assert_true(fabs(x[0] - sent[0]) <= 1e-12 &&
				            fabs(x[1] - sent[1]) <= 1e-12);
			}
			mlip_check_sample(&chk, x);
			memcpy(sent, x, sizeof(sent));
			if (rs == MLIP_RUN_IDLE && next >= p.np && k > resume_at) {
				break;
			}
		}
		char msg[1024];
		if (mlip_check_verdict(&chk, REL, mlip_check_rounding_floor(&chk), 0.0, 1e-9, msg,
		                       sizeof(msg))) {
			fail_msg("%s, %d stalls (back %d): %s",
			         mlip_strategy_name((mlip_strategy)st), stalls, back, msg);
		}
		assert_true(stalls > 100);
	}
	free(p.pts);
}

/* A stall (the loop missed periods: the drives stood at the last setpoint,
 * which is the mean) is a point of rest, and the motion goes on from it
 * within every limit, the jerk's included, and within eps of the path: the
 * plan goes back to where it was at the window's centre, within E_f of the
 * setpoint (mlip_planner_rest_here). Stalls in lines, in corners, in a
 * smooth run and while the mean settles at the end; every strategy. */
static void test_jerk_stall(void **state)
{
	(void)state;
	struct mlip_machine m = machine(2, 1000, 200, 0.01);
	m.axis[0].max_jerk = m.axis[1].max_jerk = 1e5;
	stall_runs(&m, 0);
}

/* A stall between a period's work and its send: the setpoint computed never
 * went out, and the rest is the one before (mlip_planner_rest_back), in
 * lines, in corners, leaving a corner and at the end; without a jerk limit
 * and with one, every strategy: every limit and eps hold, and no sample
 * steps from the last one sent. */
static void test_stall_before_the_send(void **state)
{
	(void)state;
	struct mlip_machine m = machine(2, 1000, 200, 0.01);
	stall_runs(&m, 1);
	m.axis[0].max_jerk = m.axis[1].max_jerk = 1e5;
	stall_runs(&m, 1);
}

/* With shape choices the early-terminated passes leave the q a full pass
 * computes (a full pass keeps the shapes), braking shapes are chosen, and
 * the motion keeps every limit with override storms (several: a shape
 * changed after a cut once left a corner unable to take the speed the
 * machine still carried, 24x the limit), hold/resume, a stop, and blocks
 * arriving too slowly. */
static void test_smooth_shapes_plan(void **state)
{
	(void)state;
	struct path p = make_fine_curve(30000);
	struct mlip_machine m = machine(2, 1000, 200, 0.01);
	int braking = plan_equals_full_pass(&p, &m, MLIP_STRATEGY_SMOOTH, 0, 997);
	assert_true(braking > 1000);
	static const int events[] = {EV_NONE,  EV_STORM, EV_STORM,       EV_STORM, EV_STORM,
	                             EV_STORM, EV_STORM, EV_HOLD_RESUME, EV_STOP,  EV_DRIP};
	for (int e = 0; e < 10; e++) {
		struct run r;
		run_path(&m, MLIP_STRATEGY_SMOOTH, &p, events[e], &r);
		print_message("smooth, events %d: %.3f s\n", events[e],
		              (double)r.periods * m.period_s);
		assert_physics(&m, &r, 0.5, events[e] != EV_STOP);
		assert_le(r.hold_drift, 1e-12);
		if (events[e] == EV_STOP) {
			assert_true(r.stopped_idle);
		}
	}
	free(p.pts);
}

/* An abort (E-stop, mlip_planner_abort) mid-run with bounded work and a
 * jerk limit drops everything, the blocks still queued for the work and the
 * pass in progress too, and rests exactly at the given point (the mean's
 * window with it); a block pushed then starts from there. */
static void test_abort_drops_the_queue(void **state)
{
	(void)state;
	struct path p = make_path(2, 1, 600);
	struct mlip_machine m = machine(2, 1000, 200, 0.01);
	m.axis[0].max_jerk = m.axis[1].max_jerk = 1e5;
	assert_int_equal(mlip_planner_init(&P, &m, MLIP_STRATEGY_MPCT, 0, p.pts, NULL), MLIP_OK);
	mlip_planner_set_async(&P, 1);
	size_t next = 1;
	double x[MLIP_MAX_AXES];
	for (int k = 0; k < 300; k++) {
		for (; next < p.np && mlip_planner_space(&P) > 0; next++) {
			struct mlip_block b = {
			    .feed_mm_s = 200, .tol_mm = 0.01, .line = (uint32_t)next};
			memcpy(b.target, p.pts + 2 * next, sizeof(double) * 2);
			assert_int_equal(mlip_planner_push(&P, &b), MLIP_OK);
		}
		mlip_planner_work(&P);
		mlip_planner_step(&P, x);
	}
	/* moving, and blocks queued that the work has not appended yet */
	struct mlip_block more = {.feed_mm_s = 200, .tol_mm = 0.01, .line = 9999};
	more.target[0] = p.pts[2 * (p.np - 1)] + 1.0;
	more.target[1] = p.pts[2 * (p.np - 1) + 1];
	assert_int_equal(mlip_planner_push(&P, &more), MLIP_OK);
	assert_true(mlip_planner_busy(&P) && mlip_planner_queued(&P) > 0);
	assert_true(x[0] != p.pts[0] || x[1] != p.pts[1]);
	double at[2] = {x[0] + 0.5, x[1] - 0.25}; /* where the drives stopped */
	assert_int_equal(mlip_planner_abort(&P, at), MLIP_OK);
	assert_false(mlip_planner_busy(&P));
	assert_int_equal(mlip_planner_queued(&P), 0);
	for (int k = 0; k < 50; k++) {
		mlip_planner_work(&P);
		assert_int_equal(mlip_planner_step(&P, x), MLIP_RUN_IDLE);
		assert_true(x[0] == at[0] && x[1] == at[1]);
	}
	struct mlip_block b = {.feed_mm_s = 100, .tol_mm = 0.01, .line = 1};
	b.target[0] = at[0] + 1.0;
	b.target[1] = at[1];
	assert_int_equal(mlip_planner_push(&P, &b), MLIP_OK);
	mlip_run_state rs;
	int k = 0;
	do {
		mlip_planner_work(&P);
		rs = mlip_planner_step(&P, x);
		assert_true(fabs(x[1] - at[1]) < 1e-12 && x[0] >= at[0] - 1e-12);
	} while (rs != MLIP_RUN_IDLE && ++k < 10000);
	assert_true(x[0] == b.target[0] && x[1] == b.target[1]);
	free(p.pts);
}

static void test_push_full_and_bad_input(void **state)
{
	(void)state;
	struct mlip_machine m = machine(2, 1000, 200, 0.01);
	double start[2] = {0, 0};
	assert_int_equal(mlip_planner_init(&P, &m, MLIP_STRATEGY_MPCT, 8, start, NULL), MLIP_OK);
	assert_int_equal(mlip_planner_init(&P, &m, MLIP_STRATEGY_MPCT, 12, start, NULL),
	                 MLIP_E_INVALID);
	/* smooth keeps its own data beside the planner: not without it */
	assert_int_equal(mlip_planner_init(&P, &m, MLIP_STRATEGY_SMOOTH, 8, start, NULL),
	                 MLIP_E_INVALID);
	assert_int_equal(mlip_planner_init(&P, &m, MLIP_STRATEGY_SMOOTH, 8, start, &SM), MLIP_OK);
	assert_int_equal(mlip_planner_init(&P, &m, MLIP_STRATEGY_COUNT, 8, start, &SM),
	                 MLIP_E_INVALID);
	assert_int_equal(mlip_planner_init(&P, &m, MLIP_STRATEGY_MPCT, 8, start, NULL), MLIP_OK);
	for (int i = 1; i <= 8; i++) {
		struct mlip_block b = {.target = {i * 0.1, 0}, .feed_mm_s = 100, .tol_mm = 0.01};
		assert_int_equal(mlip_planner_push(&P, &b), MLIP_OK);
	}
	struct mlip_block b = {.target = {1, 1}, .feed_mm_s = 100, .tol_mm = 0.01};
	assert_int_equal(mlip_planner_push(&P, &b), MLIP_E_FULL);
	assert_int_equal(mlip_planner_init(&P, &m, MLIP_STRATEGY_MPCT, 8, start, NULL), MLIP_OK);
	b.target[0] = NAN;
	assert_int_equal(mlip_planner_push(&P, &b), MLIP_E_RANGE);
	b.target[0] = 1;
	b.feed_mm_s = 0;
	assert_int_equal(mlip_planner_push(&P, &b), MLIP_E_RANGE);
	assert_int_equal(mlip_planner_set_override(&P, 201), MLIP_E_RANGE);
	assert_int_equal(mlip_planner_set_override(&P, -1), MLIP_E_RANGE);
	/* a zero-length block is merged away, not planned */
	b.target[0] = 0;
	b.target[1] = 0;
	b.feed_mm_s = 100;
	assert_int_equal(mlip_planner_push(&P, &b), MLIP_OK);
	assert_int_equal(mlip_planner_queued(&P), 0);
}

/* run_path's switches back to their defaults (a failed test may leave them set) */
static int reset(void **state)
{
	(void)state;
	g_async = 0;
	g_rows = NULL;
	return 0;
}

/* ---- a stop acts in the next period (issue 21) ----------------------------- */

/* One stop, requested before period k (0-based) of a run with bounded work
 * a period (the controller's async look-ahead, pre-read full): what the
 * plan did from then on. */
struct stop_at {
	uint64_t first_brake; /* first period whose plan speed fell by a T / 2 */
	double v_req;         /* plan speed at the request */
	double a_req;         /* the executing line's acceleration a then */
	double d_plan;        /* plan's path length from the request to rest */
	int bad;              /* a limit or the contour broken */
	char msg[512];
};

/* bounded work (1) or all of it at once (0); every setpoint when rows */
static int g_stop_async = 1;
static double *g_stop_rows;
static size_t g_stop_n, g_stop_max;

static void stop_run(const struct mlip_machine *m, mlip_strategy st, const struct path *p,
                     uint64_t k, double a_line, struct stop_at *out)
{
	static struct mlip_check chk;
	check_begin(&chk, m, p);
	assert_int_equal(
	    mlip_planner_init(&P, m, st, 0, p->pts, st == MLIP_STRATEGY_SMOOTH ? &SM : NULL),
	    MLIP_OK);
	mlip_planner_set_async(&P, g_stop_async);
	mlip_check_sample(&chk, p->pts);
	int n = m->n_axes;
	size_t next = preread(m, p);
	memset(out, 0, sizeof(*out));
	out->first_brake = UINT64_MAX;
	g_stop_n = 0;
	double x[MLIP_MAX_AXES], prev[MLIP_MAX_AXES], v_prev = 0.0;
	for (uint64_t t = 0;; t++) {
		for (int i = 0; i < MLIP_INGEST_PER_PERIOD && t < k && next < p->np &&
		                mlip_planner_space(&P) > 0;
		     i++) {
			struct mlip_block b = path_block(m, p, next);
			assert_int_equal(mlip_planner_push(&P, &b), MLIP_OK);
			next++;
		}
		if (t == k) {
			out->v_req = mlip_planner_speed(&P);
			out->a_req = P.seg[P.tail & (P.cap - 1u)].a_mm_s2;
			memcpy(prev, P.pos, sizeof(prev));
			mlip_planner_stop(&P);
		}
		mlip_planner_work(&P);
		mlip_run_state rs = mlip_planner_step(&P, x);
		mlip_check_sample(&chk, x);
		if (g_stop_rows != NULL && g_stop_n < g_stop_max) {
			memcpy(g_stop_rows + g_stop_n * (size_t)n, x, sizeof(double) * (size_t)n);
			g_stop_n++;
		}
		double v = mlip_planner_speed(&P);
		if (t >= k) {
			double d2 = 0.0;
			for (int j = 0; j < n; j++) {
				d2 += (P.pos[j] - prev[j]) * (P.pos[j] - prev[j]);
			}
			out->d_plan += sqrt(d2);
			memcpy(prev, P.pos, sizeof(prev));
			if (out->first_brake == UINT64_MAX &&
			    v <= fmax(v_prev - 0.5 * a_line * m->period_s, 0.0)) {
				out->first_brake = t;
			}
			if (rs == MLIP_RUN_IDLE) {
				break;
			}
		}
		v_prev = v;
		assert_true(t < k + 100000);
	}
	out->bad = mlip_check_verdict(&chk, REL, mlip_check_rounding_floor(&chk), 0.0, INFINITY,
	                              out->msg, sizeof(out->msg));
}

/* A straight line of `segs` pieces of `seg_mm` along a fixed skew direction,
 * the first piece `first_mm` long. */
static struct path make_line(size_t segs, double first_mm, double seg_mm)
{
	static const double dir[3] = {0.48, -0.64, 0.6};
	struct path p = {.n = 3, .np = segs + 1};
	p.pts = calloc(p.np * 3, sizeof(double));
	double s = 0.0;
	for (size_t i = 1; i < p.np; i++) {
		s += i == 1 ? first_mm : seg_mm;
		for (int j = 0; j < 3; j++) {
			p.pts[3 * i + (size_t)j] = s * dir[j];
		}
	}
	return p;
}

/*
 * Issue 21: a stop (a hold with it) acts within one period, however deep
 * the look-ahead (4096) and however far the bounded backward pass
 * (mlip_planner_set_async) is from the executing corner. A stop is
 * requested before every period of the acceleration ramp and of 40 periods
 * of cruise, every strategy, with and without a jerk limit:
 *  - on a long straight (a 300 mm block, then 0.02 mm ones) and a dense
 *    polyline (0.02 mm blocks, ten a period at 200 mm/s) along one line:
 *    the plan's speed falls from the first period after the request (by at
 *    least a_lo T / 2, a_lo the least line acceleration: A' (J4) with a
 *    jerk limit), and it comes to rest within one period's travel of
 *    v^2 / 2a past where it was, v its speed at the request and a the
 *    line's acceleration, and not before v^2 / 2a (the limit);
 *  - on a fine curve (0.02 mm blocks, every 4th period; smooth on its
 *    smoothed path), where
 *    the corners' geometry sets how fast the plan can brake: the setpoints
 *    are, to the bit, those of the planner doing all its work at once (the
 *    hold's full pass done before the next period);
 * and every setpoint keeps every limit, the jerk's included, and the path.
 */
static void test_stop_within_a_period(void **state)
{
	(void)state;
	struct path straight = make_line(6000, 300.0, 0.02), dense = make_line(12000, 0.02, 0.02);
	struct path curve = make_fine_curve(20000);
	const struct path *paths[3] = {&straight, &dense, &curve};
	char fails[512] = ""; /* the first failure; reported after every figure */
	g_stop_max = 4000;
	double *ref = malloc(g_stop_max * 3 * sizeof(double));
	double *got = malloc(g_stop_max * 3 * sizeof(double));
	for (int pi = 0; pi < 3; pi++) {
		int n = paths[pi]->n;
		for (int jerk = 0; jerk < 2; jerk++) {
			struct mlip_machine m = machine(n, 1000, 200, 0.01);
			for (int j = 0; jerk && j < n; j++) {
				m.axis[j].max_jerk = 1e5;
			}
			struct mlip_jerk_plan jp;
			mlip_jerk_plan(&m, &jp);
			double a_lo = INFINITY;
			for (int j = 0; j < n; j++) {
				a_lo = fmin(a_lo, jp.accel[j] * (1.0 - MLIP_ACCEL_MARGIN));
			}
			/* the ramp to 200 mm/s and the mean's window, then cruise */
			uint64_t ramp =
			    (uint64_t)ceil(200.0 / (a_lo * m.period_s)) + (uint64_t)jp.taps;
			struct path sp = smoothed_path(paths[pi], &m);
			for (int st = 0; st < MLIP_STRATEGY_COUNT; st++) {
				const char *name = mlip_strategy_name((mlip_strategy)st);
				const struct path *p = st == MLIP_STRATEGY_SMOOTH ? &sp : paths[pi];
				double late = 0.0, over_hi = -INFINITY, over_lo = INFINITY;
				/* every period on the lines; every 4th on the curve,
				 * run twice */
				for (uint64_t k = 1; k < ramp + 40; k += pi == 2 ? 4u : 1u) {
					struct stop_at r, r0;
					if (pi == 2) {
						g_stop_async = 0;
						g_stop_rows = ref;
						stop_run(&m, (mlip_strategy)st, p, k, a_lo, &r0);
						g_stop_async = 1;
						g_stop_rows = got;
					}
					size_t n0 = g_stop_n;
					stop_run(&m, (mlip_strategy)st, p, k, a_lo, &r);
					g_stop_rows = NULL;
					if (r.bad) {
						fail_msg("path %d, jerk %d, %s, stop before period "
						         "%" PRIu64 ": %s",
						         pi, jerk, name, k, r.msg);
					}
					double ideal = r.v_req * r.v_req / (2.0 * r.a_req);
					double over = r.d_plan - ideal,
					       travel = r.v_req * m.period_s;
					late = fmax(late, (double)(r.first_brake - k));
					over_hi = fmax(over_hi, over);
					over_lo = fmin(over_lo, over);
					if (fails[0]) {
						continue;
					}
					if (pi == 2 &&
					    (n0 != g_stop_n ||
					     memcmp(ref, got, n0 * (size_t)n * sizeof(double)) !=
					         0)) {
						snprintf(
						    fails, sizeof(fails),
						    "curve, jerk %d, %s, stop before period "
						    "%" PRIu64
						    ": the setpoints differ from those of the work "
						    "done at once",
						    jerk, name, k);
					} else if (pi < 2 && (r.first_brake != k ||
					                      !(over <= travel + 1e-9) ||
					                      !(over >= -1e-9 * (1.0 + ideal)))) {
						snprintf(
						    fails, sizeof(fails),
						    "path %d, jerk %d, %s, stop before period "
						    "%" PRIu64
						    " at %.3f mm/s: braking from period %" PRIu64
						    ", %.6f mm to rest, v^2/2a %.6f mm, one period "
						    "%.6f mm",
						    pi, jerk, name, k, r.v_req, r.first_brake,
						    r.d_plan, ideal, travel);
					}
				}
				print_message(
				    "path %d, jerk %d, %s: stops before periods 1-%" PRIu64
				    ": braking %g periods late at most, distance - v^2/2a "
				    "in [%.3g, %.3g] mm\n",
				    pi, jerk, name, ramp + 39, late, over_lo, over_hi);
			}
			free(sp.pts);
		}
	}
	free(ref);
	free(got);
	free(straight.pts);
	free(dense.pts);
	free(curve.pts);
	if (fails[0]) {
		fail_msg("%s", fails);
	}
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test_setup(test_lp_optimal_2axes, reset),
	    cmocka_unit_test_setup(test_lp_optimal_3axes, reset),
	    cmocka_unit_test_setup(test_lp_optimal_5axes, reset),
	    cmocka_unit_test_setup(test_lp_paper_example, reset),
	    cmocka_unit_test_setup(test_corner_collinear_and_reversal, reset),
	    cmocka_unit_test_setup(test_corner_contour_and_peak_speed, reset),
	    cmocka_unit_test_setup(test_corner_caps_19_20, reset),
	    cmocka_unit_test_setup(test_run_all_strategies, reset),
	    cmocka_unit_test_setup(test_mpct_faster_than_baselines, reset),
	    cmocka_unit_test_setup(test_eps_binds_end_to_end, reset),
	    cmocka_unit_test_setup(test_termination_condition_is_exact, reset),
	    cmocka_unit_test_setup(test_push_n_same_plan, reset),
	    cmocka_unit_test_setup(test_batches_same_setpoints, reset),
	    cmocka_unit_test_setup(test_sharp_corner_zero_side_does_not_stop, reset),
	    cmocka_unit_test_setup(test_override_storm, reset),
	    cmocka_unit_test_setup(test_hold_resume_on_path, reset),
	    cmocka_unit_test_setup(test_stop_is_controlled, reset),
	    cmocka_unit_test_setup(test_running_dry_is_safe, reset),
	    cmocka_unit_test_setup(test_smooth_shapes_keep_guarantees, reset),
	    cmocka_unit_test_setup(test_smooth_shapes_plan, reset),
	    cmocka_unit_test_setup(test_bounded_work, reset),
	    cmocka_unit_test_setup(test_jerk_plan, reset),
	    cmocka_unit_test_setup(test_jerk_every_part, reset),
	    cmocka_unit_test_setup(test_jerk_stall, reset),
	    cmocka_unit_test_setup(test_stall_before_the_send, reset),
	    cmocka_unit_test_setup(test_abort_drops_the_queue, reset),
	    cmocka_unit_test_setup(test_push_full_and_bad_input, reset),
	    cmocka_unit_test_setup(test_stop_within_a_period, reset),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
