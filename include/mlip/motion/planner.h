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

#include "mlip/motion/jerk.h"
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
	MLIP_STRATEGY_SMOOTH,   /* the host's smoothed path (mlip/motion/smooth.h), corners chosen
	                           on the acceleration polygon's boundary (smoothplan.c) */
	MLIP_STRATEGY_COUNT
} mlip_strategy;

/* Command-line name of a strategy ("mpct", ...), NULL when st is none;
 * the strategy of a name, -1 when none has it. */
const char *mlip_strategy_name(mlip_strategy st);
int mlip_strategy_from_name(const char *name);

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

/* ---- the planner ------------------------------------------------------- */

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
};

struct mlip_strategy_ops;
struct mlip_smooth_seg;   /* smooth's own data of a segment (mlip/motion/smooth.h) */
struct mlip_smooth_store; /* ... for every slot: storage only smooth needs */

/* A line's speed profile (35)(36): from v0 to vc at a1, cruise, to v1 at a3. */
struct mlip_profile {
	double v0, vc, v1; /* mm/s */
	double a1, a3;     /* mm/s^2, signed */
	double t1, t2, t3; /* s; t2 may be infinite (feed hold) */
	double d1, d2;     /* mm */
};

/* A backward pass that may run in pieces (planner.c, mlip_planner_work). */
struct mlip_pass {
	int on, full;    /* running; a full pass (override, hold) */
	uint32_t i;      /* it visits corner i - 1 next (segment i its successor) */
	uint32_t visits; /* corners visited so far */
	uint32_t fresh;  /* the newest corners linked since a pass completed */
	double q_next;   /* q of corner i */
	int has_reach;   /* a pass given up left the corners below reach - 1 stale: */
	uint32_t reach;  /* no termination at a corner >= reach */
};

/* Bounded work (mlip_planner_set_async): units a period, and what things
 * cost in them (a corner a pass visits: 1, about 6 ns on this host). Beyond
 * them, a period appends as many queued blocks as the executor finished
 * segments, at most MLIP_INGEST_PER_PERIOD, also while a pass runs (the
 * next pass plans them all): the look-ahead keeps up with the motion. A
 * batch's pass visits every corner within braking distance of the old end
 * (at 200 mm/s and 1000 mm/s^2, 20 mm: 1000 corners of 0.02 mm, more than
 * a period's units with smooth), so the passes run back to back, each for
 * all that was appended during the one before. */
#define MLIP_WORK_PER_PERIOD    1200u
#define MLIP_WORK_CHOOSE        4u   /* a visit with smooth's shape choice */
#define MLIP_WORK_APPEND        40u  /* a block appended and its corner planned */
#define MLIP_WORK_APPEND_SHAPES 150u /* ... with smooth's six shapes */
/* Blocks pushed, not yet appended (a power of two): what a driver takes
 * in a period is what this queue has room for, so it bounds the records
 * checked and queued a period (the pre-read's first period took 512, 5x
 * any other period's work). At least what a period can append (the keep-up
 * and the units' appends), so the queue never makes the work wait: the
 * appends, hence the plan, are those of a deeper queue. */
#define MLIP_INPUT_CAP          64u
typedef char mlip_input_pow2_check[(MLIP_INPUT_CAP & (MLIP_INPUT_CAP - 1)) == 0 ? 1 : -1];
typedef char mlip_input_cap_check
    [MLIP_INPUT_CAP >= MLIP_INGEST_PER_PERIOD + MLIP_WORK_PER_PERIOD / MLIP_WORK_APPEND ? 1 : -1];

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
	/* configuration, fixed at init (the strategy: or between programs,
	 * mlip_planner_set_strategy) */
	int n; /* axes */
	mlip_strategy strategy;
	double accel[MLIP_MAX_AXES]; /* A_k with MLIP_ACCEL_MARGIN applied */
	double vaxis[MLIP_MAX_AXES]; /* per-axis velocity limits */
	uint8_t rotary[MLIP_MAX_AXES];
	double vmax_mm_s, vmax_rot_deg_s, eps_mm, period_s;
	const struct mlip_strategy_ops *ops; /* the strategy's entry (mlip/motion/strategy.h) */
	struct mlip_smooth_seg *sm;          /* smooth: its data, slot for slot with seg */
	struct mlip_smooth_seg *sm_store;    /* the store given at init (NULL: none) */
	/* look-ahead ring: segments [tail, head) are queued, seg[tail] is the
	 * one being executed (its line or its end corner) */
	uint32_t head, tail;              /* free-running; index & (cap-1) */
	uint32_t cap;                     /* <= MLIP_LOOKAHEAD, power of two */
	uint64_t seq;                     /* seq of the newest segment */
	double override;                  /* feed override, 0..2 */
	int hold;                         /* feed hold: plan as if override were 0 */
	int stopping;                     /* stop: hold, then drop the queue at rest */
	double last_point[MLIP_MAX_AXES]; /* end of the newest segment (or start) */
	/* the look-ahead's work, a bounded amount a period (async) */
	int async;                      /* 0: push_n and the commands do all of it at once */
	struct mlip_pass pass;          /* the backward pass in progress */
	uint32_t in_head, in_tail;      /* input queue: blocks pushed, not yet appended */
	uint32_t retired, retired_seen; /* segments finished (free-running), and those
	                                   replaced by appends (mlip_planner_work) */
	uint32_t pending;               /* blocks appended since the running pass started (async):
	                                   the next pass plans them */
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
	/* the jerk limit (mlip/motion/jerk.h): the setpoint is the mean of the
	 * plan's last `taps` positions (pos is the plan's; taps 1: no limit) */
	int taps;
	double filter_mm;          /* E_f (J5), taken from every corner's budget */
	uint32_t dwell;            /* periods still to stand at an exact corner */
	uint32_t still;            /* periods the plan has not moved */
	uint32_t fir_n;            /* samples taken (free-running) */
	double out[MLIP_MAX_AXES]; /* the setpoint: the mean */
	double fir[MLIP_JERK_MAX_TAPS][MLIP_MAX_AXES]; /* the plan's last positions */
	struct mlip_exec_mark {                        /* where each of them was on the path */
		uint32_t tail;
		int in_corner;
		uint64_t done_seq;
		uint32_t done_line;
	} mark[MLIP_JERK_MAX_TAPS];
	struct mlip_block in[MLIP_INPUT_CAP]; /* the input queue (async) */
	struct mlip_seg seg[MLIP_LOOKAHEAD];
};

/* Initialise at rest at start[] (n joint coordinates). cap = look-ahead
 * capacity (0 means MLIP_LOOKAHEAD; else a power of two <= MLIP_LOOKAHEAD).
 * store: the smooth strategy's data (mlip/motion/smooth.h), required with
 * MLIP_STRATEGY_SMOOTH and ignored otherwise, so that the other strategies
 * carry none of it. Returns MLIP_E_INVALID for an inconsistent machine or
 * capacity, or smooth without store. */
mlip_status mlip_planner_init(struct mlip_planner *p, const struct mlip_machine *m,
                              mlip_strategy st, uint32_t cap, const double *start,
                              struct mlip_smooth_store *store);

/* Another strategy for the next program (a smooth controller whose feeder
 * counted mpct's run of a program sooner, docs/algorithm.md "Smooth never
 * slower than mpct"): only with nothing queued, at rest, and a strategy
 * that needs storage only when init was given it. MLIP_E_INVALID else
 * (nothing changes). */
mlip_status mlip_planner_set_strategy(struct mlip_planner *p, mlip_strategy st);

/* Free slots for push. */
uint32_t mlip_planner_space(const struct mlip_planner *p);
/* Queued blocks not yet completed (including the one executing; with a
 * jerk limit, the last one until the mean has come to rest on it). */
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

/* Bounded work: with on = 1, push_n only queues the blocks (at most
 * MLIP_INPUT_CAP waiting) and the commands only ask for their backward
 * pass; mlip_planner_work does the look-ahead's work, at most
 * MLIP_WORK_PER_PERIOD units of it a call, so that a period's cost does
 * not grow with the look-ahead's depth (the pre-read's 4096 blocks, an
 * override's pass over all of them). Until a pass has reached a corner the
 * executor follows the plan it replaces, which brakes to rest where it was
 * planned to: safe, and only slower. Off (0, the default): all of it at
 * once, as push_n and the commands always did. */
void mlip_planner_set_async(struct mlip_planner *p, int on);
/* One period's look-ahead work (async; nothing otherwise). */
void mlip_planner_work(struct mlip_planner *p);
/* Look-ahead work is pending: blocks not yet appended, or a pass not done. */
int mlip_planner_busy(const struct mlip_planner *p);

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

/* As mlip_planner_rest_here, at `at`: the setpoint of one period before,
 * the last the drives got when the stall came between a period's work and
 * its send. From there the rest of the executing segment is a straight line
 * to its end: `at` lies within A T^2 / 2 of that segment's line (the motion
 * leaves a corner tangent to it, |a| <= A over the one period), so the line
 * keeps that close to the path. */
void mlip_planner_rest_back(struct mlip_planner *p, const double *at);

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
 * Returns the run state after the period (with a jerk limit, IDLE and HELD
 * once the mean has come to rest too). */
mlip_run_state mlip_planner_step(struct mlip_planner *p, double *pos_out);

/* Current speed along the path (joint units/s), for status displays. */
double mlip_planner_speed(const struct mlip_planner *p);

/* What others read; the struct's fields are the planner's own. */
/* Not at rest: a block queued and a speed, or inside a corner. */
int mlip_planner_moving(const struct mlip_planner *p);
/* The feed hold is on (mlip_planner_hold, a stall's rest), not a stop's:
 * at rest with nothing queued it holds the next block pushed. */
int mlip_planner_held(const struct mlip_planner *p);
/* The block being executed (seq 0, line 0: none queued). */
void mlip_planner_executing(const struct mlip_planner *p, uint64_t *seq, uint32_t *line);
/* The speed cap (mm/s, at a 100 % override) of the blocks whose motion
 * the last setpoint contains: min(v_m and the axes' limits, the feed; a
 * rapid's is the machine's) of the one executing, and in a corner of the
 * block after it too; 0 when none is queued. The path plan's knot cap
 * (mlip/motion/pathrun.h tag.cap). */
double mlip_planner_cap(const struct mlip_planner *p);
/* The newest block whose motion the last setpoint contains: in a corner
 * the block after it (its motion has begun), else the one executing (0:
 * none queued). M62/M63 switch with it (issue 19). */
uint64_t mlip_planner_motion_seq(const struct mlip_planner *p);
/* The last block completed (or, pushed at rest, the block before it). */
void mlip_planner_done(const struct mlip_planner *p, uint64_t *seq, uint32_t *line);
/* The last block completed as a rest at the last setpoint would leave it
 * (without the mean): in a corner, once the setpoint is nearer to the next
 * segment, the corner's block (mlip_planner_rest_here's rule), so a
 * continuation from there goes on, not back to the corner point. */
void mlip_planner_resume_done(const struct mlip_planner *p, uint64_t *seq, uint32_t *line);
/* Feed override in effect, percent. */
double mlip_planner_override_pct(const struct mlip_planner *p);
const struct mlip_planner_stats *mlip_planner_get_stats(const struct mlip_planner *p);

#endif
