/*
 * mlip/motion/planner.h - the interpolation core: corner planning (eqs 1-20),
 * adaptive look-ahead (Sec. 2, eqs 21-26, 34), feed override (Sec. 3) and
 * per-period interpolation (Sec. 4) of Zhang, Sun, Gao, Li (2011).
 *
 * Fixed memory: the planner is one struct with a fixed-capacity ring of
 * segments, owned by the caller. It owns no clock: mlip_planner_step() is
 * called once per period T and returns the next setpoint. The offline
 * simulator and the real-time controller drive the very same calls.
 *
 * Life of a block: mlip_planner_push() appends it (computing the corner at
 * the previous point and re-running backward reachability from the newest
 * block, which always plans to rest). mlip_planner_step() consumes blocks.
 */
#ifndef MLIP_PLANNER_H
#define MLIP_PLANNER_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/types.h"

/* MLIP_LOOKAHEAD (mlip/types.h): segments in the look-ahead ring; negative
 * array size if not a power of two (C99 has no _Static_assert) */
typedef char mlip_lookahead_pow2_check[(MLIP_LOOKAHEAD & (MLIP_LOOKAHEAD - 1)) == 0 ? 1 : -1];

/* Relative margin kept below every acceleration limit so that floating-point
 * rounding of positions never shows up as an excess in second differences. */
#define MLIP_ACCEL_MARGIN 1e-9

/* Ingest rule shared by every driver (controller and simulator), so that
 * both produce the same motion from the same program: before the first
 * period, push until the look-ahead is full or the program ends (the paper's
 * pre-read, Sec. 2.1 step 1); then, before each period, push at most this
 * many blocks. Bounded, so the cost of a period is bounded. */
#define MLIP_INGEST_PER_PERIOD 16

typedef enum {
	MLIP_STRATEGY_MPCT = 0, /* the paper: multi-period constant-acceleration corners */
	MLIP_STRATEGY_BISECTOR, /* equal speeds, one period, a along e_e - e_s (eq 10) */
	MLIP_STRATEGY_STOP,     /* speed 0 at every corner */
	MLIP_STRATEGY_SMOOTH /* mpct's corners on the host's smoothed path (mlip/motion/smooth.h):
	                        the planner treats it as MPCT */
} mlip_strategy;

/* ---- corner planning, exposed for tests and benchmarks ---------------- */

/* Acceleration-polygon linear programme (Theorem 2, Sec. 1.4): maximise
 * alpha + beta subject to |alpha e_e[k] - beta e_s[k]| <= A_k for all k,
 * alpha, beta >= 0. e_s, e_e unit vectors of n axes. Returns 0 and the
 * optimum, or -1 when the programme is unbounded (collinear corner: no
 * acceleration needed). Ties (reversals) are broken toward alpha = beta. */
int mlip_corner_lp(int n, const double *e_s, const double *e_e, const double *accel, double *alpha,
                   double *beta);

/* Geometry of one corner at its largest admissible size (q = 1). Speeds and
 * distances at q in [0,1] are v = sqrt(q) * v_g, l = q * l_g, t = sqrt(q) * t_g
 * (with a fixed, v scales with t_m and l with t_m^2: eqs 2,3,5,6). */
struct mlip_corner {
	double alpha_mm_s2, beta_mm_s2; /* a = alpha e_e - beta e_s (constant) */
	double vs_mm_s, ve_mm_s;        /* v_s, v_e at q = 1 */
	double ls_mm, le_mm;            /* l_s, l_e at q = 1 */
	double t_s;                     /* t_m at q = 1 */
};

/* Plan the corner between a segment of direction e_s and length ds_mm and one
 * of direction e_e and length de_mm, under strategy st, contour budget eps_mm,
 * per-axis limits accel[], hard speed caps vcap_s / vcap_e of the two
 * segments, period T (bisector). Implements (18), (19), (20). */
void mlip_corner_plan(int n, mlip_strategy st, const double *e_s, const double *e_e, double ds_mm,
                      double de_mm, const double *accel, double eps_mm, double vcap_s_mm_s,
                      double vcap_e_mm_s, double period_s, struct mlip_corner *c);

/* The smooth strategy's corner shapes (beyond the paper, corner.c): out[0]
 * is mlip_corner_plan's, then up to MLIP_SMOOTH_SHAPES - 1 braking shapes on
 * the acceleration polygon's boundary (v_e < v_s) that the backward pass
 * chooses where braking limits the corner, with their w (shapes 1..: the
 * corner is mlip_corner_smooth_w's at that w). Returns how many. */
#define MLIP_SMOOTH_SHAPES 6
int mlip_corner_smooth_shapes(int n, const double *e_s, const double *e_e, double ds_mm,
                              double de_mm, const double *accel, double eps_mm, double vcap_s_mm_s,
                              double vcap_e_mm_s, struct mlip_corner *out, double *w_out);
/* ---- the planner ------------------------------------------------------- */

/* A corner shape as the backward pass weighs it (smooth): its w (for
 * mlip_corner_smooth_w) and, at q = 1, 1/v_s^2, 1/v_e^2, B = v_s^2 - 2 a l_s,
 * C = v_e^2 + 2 a' l_e and 1/C (0 when C is 0), as link_coeffs has them. */
struct mlip_shape {
	double w, inv_vs2, inv_ve2, b, c, inv_c;
};

/* One segment of the look-ahead: the line from the previous point to end[],
 * and the corner at end[] towards the next segment. Private to the planner;
 * public only so the struct has a known size. Grouped by role. */
struct mlip_seg {
	/* geometry, set at push */
	double end[MLIP_MAX_AXES]; /* P_i */
	double e[MLIP_MAX_AXES];   /* unit direction in joint space */
	double d_mm;               /* d_i, joint-space length */
	double a_mm_s2;            /* a_{i,m}: line acceleration limit */
	double two_a_d;            /* 2 a_{i,m} d_i, reused by every pass */
	double vhard_mm_s;         /* hard speed cap of the line: v_m, axis limits */
	double vfeed_mm_s;         /* programmed feed in joint units (100 %) */
	double tol_mm;             /* eps budget of the corner at end[] */
	int exact;                 /* exact stop (G61): the corner at end[] at rest */
	uint32_t line;             /* source line */
	uint64_t seq;              /* the block's seq (or a push count, from 1) */
	/* corner at end[], valid once the next segment exists */
	struct mlip_corner c;
	double inv_vs2, inv_ve2; /* 1/v_s^2, 1/v_e^2 at q=1 (0 when v is 0) */
	double brake_b;          /* B = v_s^2 - 2 a_i l_s (this line's a) */
	double inv_brake_c;      /* 1 / C, C = v_e^2 + 2 a_{i+1} l_e (0: no bound) */
	double qcap;             /* largest q under the override (Sec. 3) */
	/* look-ahead state */
	double q; /* planned (t_m / t_g)^2 of the corner, in [0,1] */
	/* smooth: the shapes c is chosen among (mlip_corner_smooth_shapes),
	 * which one it is, or MLIP_SHAPE_FIXED once the executor chose c */
	uint8_t n_shapes, shape;
	double commit_in, commit_out; /* the largest q B and q C any plan gave it */
	struct mlip_corner shape0;    /* shapes[0]'s corner; the others from w */
	struct mlip_shape shapes[MLIP_SMOOTH_SHAPES];
};
#define MLIP_SHAPE_FIXED 255

/* A line's speed profile (35)(36): from v0 to vc at a1, cruise, to v1 at a3. */
struct mlip_profile {
	double v0, vc, v1; /* mm/s */
	double a1, a3;     /* mm/s^2, signed */
	double t1, t2, t3; /* s; t2 may be infinite (feed hold) */
	double d1, d2;     /* mm */
};

typedef enum {
	MLIP_RUN_IDLE = 0, /* at rest on the last point, nothing queued */
	MLIP_RUN_MOVING,   /* executing */
	MLIP_RUN_HELD      /* feed hold (override 0 or hold): at rest on the path */
} mlip_run_state;

struct mlip_planner_stats {
	uint64_t pushes;          /* blocks appended */
	uint64_t backward_visits; /* corners visited by backward passes of pushes */
	uint64_t full_passes;     /* full re-plans (override changes) */
	uint64_t periods;         /* calls to step */
};

struct mlip_planner {
	/* configuration, fixed at init */
	int n; /* axes */
	mlip_strategy strategy;
	double accel[MLIP_MAX_AXES]; /* A_k with MLIP_ACCEL_MARGIN applied */
	double vaxis[MLIP_MAX_AXES]; /* per-axis velocity limits */
	uint8_t rotary[MLIP_MAX_AXES];
	double vmax_mm_s, vmax_rot_deg_s, eps_mm, period_s;
	/* look-ahead ring: segments [tail, head) are queued, seg[tail] is the
	 * one being executed (its line or its end corner) */
	uint32_t head, tail;              /* free-running; index & (cap-1) */
	uint32_t cap;                     /* <= MLIP_LOOKAHEAD, power of two */
	uint64_t seq;                     /* seq of the newest segment */
	double override;                  /* feed override, 0..2 */
	int hold;                         /* feed hold: plan as if override were 0 */
	int stopping;                     /* stop: hold, then drop the queue at rest */
	double last_point[MLIP_MAX_AXES]; /* end of the newest segment (or start) */
	/* execution state */
	int in_corner;            /* 0: on the line of seg[tail]; 1: in its end corner */
	double l_start_mm;        /* line: where it starts along seg[tail] (l_e of
	                             the corner before, as executed) */
	double s_mm;              /* line: distance from the line's start */
	double v_mm_s;            /* line: current speed */
	double tc_s;              /* corner: time spent in it */
	struct mlip_profile prof; /* line: the profile being followed */
	int prof_valid;
	double prof_q, prof_vt;           /* its inputs: end-corner q, target speed */
	double prof_t, prof_s0, prof_len; /* time in it, s at its start, its length */
	double q_exec;                    /* corner: frozen q of seg[tail]'s end corner */
	double pos[MLIP_MAX_AXES];        /* last setpoint */
	uint64_t done_seq;                /* last completed block (a block pushed at
	                                     rest sets it to that block's seq - 1) */
	uint32_t done_line;
	struct mlip_planner_stats stats;
	struct mlip_seg seg[MLIP_LOOKAHEAD];
};

/* Initialise at rest at start[] (n joint coordinates). cap = look-ahead
 * capacity (0 means MLIP_LOOKAHEAD; else a power of two <= MLIP_LOOKAHEAD).
 * Returns MLIP_E_INVALID for an inconsistent machine or capacity. */
mlip_status mlip_planner_init(struct mlip_planner *p, const struct mlip_machine *m,
                              mlip_strategy st, uint32_t cap, const double *start);

/* Free slots for push. */
uint32_t mlip_planner_space(const struct mlip_planner *p);
/* Queued blocks not yet completed (including the one executing). */
uint32_t mlip_planner_queued(const struct mlip_planner *p);

/* Append one block. MLIP_E_FULL when no slot is free. A block closer than
 * MLIP_MERGE_MM to the previous point is ignored (MLIP_OK). */
mlip_status mlip_planner_push(struct mlip_planner *p, const struct mlip_block *b);

/* Push up to n blocks (as many as there is room for) with one backward
 * pass: the same plan as n pushes, cheaper. Returns how many were taken;
 * *err (may be NULL) gets the status of the first block refused for a
 * reason other than room. */
size_t mlip_planner_push_n(struct mlip_planner *p, const struct mlip_block *b, size_t n,
                           mlip_status *err);

/* Feed override, pct in [0, 200]; takes effect from the next step. 0 holds. */
mlip_status mlip_planner_set_override(struct mlip_planner *p, double pct);

/* Feed hold (on = 1) and resume (on = 0): stop on the path with the
 * acceleration limits, resume on the path. Independent of the override. */
void mlip_planner_hold(struct mlip_planner *p, int on);

/* Controlled stop: decelerate on the path as for a hold, then drop every
 * queued block; the planner is then idle where it stopped, and pushes are
 * refused until it is. */
void mlip_planner_stop(struct mlip_planner *p);

/* After a stall (the setpoints stood still while the plan went on): make the
 * last setpoint a point of rest. The rest of the executing segment becomes a
 * straight line from there to its end (from inside a corner: to the end of
 * the nearer of the corner's two segments, at rest at the corner point when
 * that is the one before; the distance to a segment being convex along a
 * line, the path stays within the corner's tolerance), planned again from
 * rest. Hold is set: motion resumes with
 * mlip_planner_hold(p, 0). */
void mlip_planner_rest_here(struct mlip_planner *p);

/* Idle (nothing queued, not stopping): rest at pos[] instead, e.g. where
 * disabled drives were moved by hand; the next block starts there.
 * MLIP_E_INVALID when not idle or a coordinate is not finite. */
mlip_status mlip_planner_rest_at(struct mlip_planner *p, const double *pos);

/* Abort (an E-stop, issue 18: the drives stop by themselves in their quick
 * stop, not on the path): drop every queued block at once, clear hold and
 * stop, and rest at pos[] (where the drives are). MLIP_E_INVALID, nothing
 * changed, when a coordinate is not finite. */
mlip_status mlip_planner_abort(struct mlip_planner *p, const double *pos);

/* Advance one period; writes the setpoint of every axis to pos_out[n].
 * Returns the run state after the period. */
mlip_run_state mlip_planner_step(struct mlip_planner *p, double *pos_out);

/* Current speed along the path (joint units/s), for status displays. */
double mlip_planner_speed(const struct mlip_planner *p);

/* What others read; the struct's fields are the planner's own. */
/* Not at rest: a block queued and a speed, or inside a corner. */
int mlip_planner_moving(const struct mlip_planner *p);
/* The block being executed (seq 0, line 0: none queued). */
void mlip_planner_executing(const struct mlip_planner *p, uint64_t *seq, uint32_t *line);
/* The last block completed (or, pushed at rest, the block before it). */
void mlip_planner_done(const struct mlip_planner *p, uint64_t *seq, uint32_t *line);
/* Feed override in effect, percent. */
double mlip_planner_override_pct(const struct mlip_planner *p);
const struct mlip_planner_stats *mlip_planner_get_stats(const struct mlip_planner *p);

#endif
