/*
 * mlip/motion/pathrun.h - the path-speed plan (mlip/motion/pathplan.h) run
 * over a stream of setpoints in fixed memory (issue 21): it takes the
 * setpoints of `smooth` without a jerk limit one at a time, keeps a window
 * of them, and gives the jerk-limited setpoints, period by period: the
 * positions along a spline through the window at the planned s.
 *
 * The spline (P5 of pathspeed.h, by chord length) is built piece by piece
 * and a piece, once fixed, never changes: each new point refits the pieces
 * not yet fixed, from the last fixed knot (its position and x', the fixed
 * piece's, as the clamped end) to the newest point (a natural end), and
 * fixes the pieces at least MLIP_PATHRUN_SETTLE knots behind the newest
 * point. The fit's natural end moves a knot K behind it by at most 2^-K of
 * its own value (the tridiagonal's rows are diagonally dominant by 2; 0.268
 * a knot on even spacing), so a fixed piece meets the next one with the
 * same position and x' and an x'' that differs by ~2^-K of |x''|
 * (1e-12 at K = 40): no jerk a sample shows.
 *
 * The plan sees only the fixed pieces, and their far end is its `end`: a
 * state it certifies (Q4: a braking run to rest at or before `end`)
 * stays certified when more pieces are fixed (the run and the pieces it
 * crossed are the same; the room only grows). That is pathplan.h's
 * invariant across the window's growth. At the program's end
 * (mlip_pathrun_finish) every piece is fixed, the plan brakes to rest at
 * `end` itself, and the last setpoint is the last point exactly.
 *
 * Each fixed piece is checked by (P6) against the band the caller gives
 * (what the tolerance leaves after the setpoints' own contour error: the
 * caller runs `smooth` with eps less the band): a piece that strays from
 * its chord by more is refused (the spline through a sharp turn or a
 * reversal; the mean must take such a stretch: the hand-over is not yet
 * in the product).
 *
 * Memory: one struct, MLIP_PATHRUN_CAP points and the fairing's
 * MLIP_PATHRUN_FAIR_CAP (281 KiB at 6 axes),
 * whatever the program's length. No allocation, no I/O. A period's work is
 * bounded by the plan's max_periods (pathplan.h); it is not for the 1 ms
 * thread itself (mlip-rt runs it in its planning thread, tools/rtplan.c).
 */
#ifndef MLIP_PATHRUN_H
#define MLIP_PATHRUN_H

#include "mlip/motion/pathplan.h"

/* Points in the window (the look-ahead is at least 3/4 of it less
 * MLIP_PATHRUN_SETTLE input periods: 128 mm at 200 mm/s, more than a stop
 * from 200 mm/s at 300 mm/s^2 takes) and the knots behind the newest point
 * before a piece is fixed. */
#define MLIP_PATHRUN_CAP      1024
#define MLIP_PATHRUN_SETTLE   40
/* Input points nearer than this (mm of chord) to the last one kept are
 * skipped (a setpoint at rest repeats; a piece of 1e-9 mm would make
 * x'' of the positions' rounding) */
#define MLIP_PATHRUN_MIN_STEP 1e-6
/* Input points the fairing (mlip_pathrun_fair) holds: its window of
 * +-h mm is cut to what they span where the input is dense (a slow
 * stretch: a corner, a start), so the memory stays fixed */
#define MLIP_PATHRUN_FAIR_CAP 256
/* The compaction keeps the pieces of the plan's state MLIP_PATHRUN_LAG
 * periods back (the largest piece up to it) less MLIP_PATHRUN_BEHIND knots:
 * a planned queue's consumer is at most its length plus one periods behind
 * its producer and reads that far back (planq.h), and the rule, the plan's
 * own, runs the same in mlip-sim: the window at each period, so the plan,
 * does not depend on the consumer's timing */
#define MLIP_PATHRUN_LAG      264
#define MLIP_PATHRUN_BEHIND   8

/* The caller's mark of an input point, carried with it as a knot: a
 * planned queue's records (mlip/motion/planq.h), the one being executed
 * and the last completed when the point was made (never read by the
 * plan), and the speed cap of the block(s) it belongs to (the plan's
 * knot cap, pathplan.h Q5; mm/s, 0: none). */
struct mlip_pathrun_tag {
	uint64_t seq, done_seq;
	uint32_t line, done_line;
	double cap;
};

struct mlip_pathrun {
	struct mlip_path_limits lim;
	double band_mm;   /* (P6): a fixed piece's bound on its chord distance */
	int max_periods;  /* (Q4) a certification's braking-run periods at most */
	int count, fixed; /* points in the window; pieces fixed (knots 0..fixed) */
	int finished;     /* no more input: every piece fixed */
	int hint;         /* the plan's piece */
	/* the pieces: s global (chord length from the program's start) */
	double s[MLIP_PATHRUN_CAP];
	double p[MLIP_PATHRUN_CAP][MLIP_MAX_AXES];
	double m[MLIP_PATHRUN_CAP][MLIP_MAX_AXES];
	double b[MLIP_PATHRUN_CAP][MLIP_MAX_AXES];
	double t3[MLIP_PATHRUN_CAP][MLIP_MAX_AXES];
	double c[MLIP_PATHRUN_CAP];    /* the fit's scratch */
	double dev[MLIP_PATHRUN_CAP];  /* each knot's move from its input point (F2) */
	double cap[MLIP_PATHRUN_CAP];  /* each knot's speed cap (its tag's: Q5) */
	double last_in[MLIP_MAX_AXES]; /* the last input point (maybe skipped) */
	struct mlip_pathrun_tag tag[MLIP_PATHRUN_CAP]; /* each point's */
	struct mlip_pathrun_tag tag_in;                /* the caller's: the next input's */
	struct mlip_pathrun_tag last_tag;              /* last_in's */
	struct mlip_path_state st;
	/* compaction keeps the pieces from min(st.s, keep_s) on and from the
	 * lag's knot (lag_piece: the largest piece after each of the last
	 * MLIP_PATHRUN_LAG periods, lag_n periods so far). keep_s: INFINITY
	 * from init; a planned queue's producer holds it at its consumer's
	 * oldest knot (a safety bound: the lag's is never above it while the
	 * consumer follows the plan, planq.c) */
	double keep_s;
	long lag_piece[MLIP_PATHRUN_LAG];
	long lag_n, lag_max;
	long rested; /* periods at rest in a row */
	/* the fairing (mlip_pathrun_fair; fair_h 0: off, the knots are the
	 * input): a ring of input points, numbered fr_lo..fr_hi-1 from the
	 * start, fr_s their chord length, fr_c the next knot's input point;
	 * ended: no more input (finished once every knot is in the spline);
	 * max_dev_mm: the largest knot's move (F2) */
	double fair_h, fair_mm;
	long fair_k;
	double fr_s[MLIP_PATHRUN_FAIR_CAP];
	double fr_p[MLIP_PATHRUN_FAIR_CAP][MLIP_MAX_AXES];
	struct mlip_pathrun_tag fr_tag[MLIP_PATHRUN_FAIR_CAP]; /* each input point's mark */
	long fr_lo, fr_hi, fr_c;
	int ended;
	double max_dev_mm;
	/* figures */
	long periods, work, dropped;
	int peak_count;
	double max_sag_mm;
	/* the refusal, for the caller's message: the piece's start (mm of
	 * chord from the program's start) and its (P6) bound: sag plus fairing move */
	const char *why;
	double why_s, why_mm;
	double why_v, why_a; /* the plan's state there (speed, acceleration) */
};

/* Start at `start` (the program's start, at rest). lim as for
 * mlip_path_plan_period; band_mm > 0. -1 when a limit is not positive or
 * start not finite. */
int mlip_pathrun_init(struct mlip_pathrun *pr, const struct mlip_path_limits *lim, double band_mm,
                      int max_periods, const double *start);

/* Fair the input before the spline. A spline through points that ripple
 * at the program's chord length has an x'' and x''' that ripple with them,
 * and (P2)'s x''' v^3 then caps the speed far below the curve's own: a
 * circle r 10 mm cut into 2 degree chords, smooth's setpoints within 0.4 um
 * of a circle, the interpolating spline's curvature 0.069-0.129 /mm
 * (0.1 true), the plan at 40-70 mm/s where 100 is allowed. Each knot is
 * instead
 *
 *   (F1) the value at the input point c of the quadratic in s (chord
 *        length) fitted per axis by least squares to the input points
 *        within +-hc of it, weights (1 - u^2)^3 (u = (s - s_c) / hc) times
 *        each point's share of the arc, hc = min(h_mm, the k-th input
 *        point's distance either side, what the window holds either side);
 *   (F2) moved from the input point by the fit's move d cut smoothly:
 *        |d| / (1 + (|d| / fair_mm)^4)^(1/4) < fair_mm.
 *
 * The fit reproduces a quadratic (no pull to the centre of curvature) and
 * the window is symmetric (a line stays a line). k input points (one a
 * period) bound it where the motion is slow, at a corner, so it does not
 * reach across the corner. Each knot's move is kept (dev) and (P6) allows
 * a piece band_mm less the larger move of its two knots: the chord
 * between two knots is within that move of the chord between their input
 * points, so the spline stays within band_mm of the input's polyline. The
 * first and last knots are the input's first and last points.
 *
 * After init, before the first push; without the call the knots are the
 * input points. -1 when h_mm < 0, k < 0 or fair_mm not in (0, band_mm).
 * Memory: MLIP_PATHRUN_FAIR_CAP input points; work per knot: the points
 * in its window (at most that), times the axes. */
int mlip_pathrun_fair(struct mlip_pathrun *pr, double h_mm, int k, double fair_mm);

/* The next input setpoint: 0 taken, 1 the window is full (step first, then
 * push it again), -1 refused (pr->why). */
int mlip_pathrun_push(struct mlip_pathrun *pr, const double *pos);

/* No more input: the remaining pieces fixed (the last on the last input
 * point). 0, or -1 refused (pr->why). */
int mlip_pathrun_finish(struct mlip_pathrun *pr);

/* One period of the plan: 1 its setpoint in x (n axes), 0 it needs more
 * input first (the window is not full and not finished: nothing moved),
 * 2 the last setpoint (at rest on the last point), -1 refused (pr->why:
 * the plan left its certified states, or it stopped short of the end). */
int mlip_pathrun_step(struct mlip_pathrun *pr, double *x);

/* What the plan cannot run yet, asked of each block of a program before
 * anything moves (mlip-sim, mlip-feed with [TRAJ] JERK_PLAN = path): it
 * re-times one path from rest to rest, so an event taken at rest (a dwell,
 * M0/M1, spindle, tool, coolant, output, probe) and an exact stop (G61)
 * are refused. Feeds and rapids run: each block under its own cap, the
 * knots' (tag.cap, pathplan.h Q5). NULL: b is taken; else why (a phrase
 * for "LINE: ..."). */
const char *mlip_pathrun_refusal(const struct mlip_block *b);

/* The first knot (global) the compaction keeps by the lag's rule: 0 until
 * MLIP_PATHRUN_LAG periods are planned. */
long mlip_pathrun_lag_knot(const struct mlip_pathrun *pr);

/* The fixed pieces as the plan reads them (count = fixed + 1 knots). */
void mlip_pathrun_curve(const struct mlip_pathrun *pr, struct mlip_path_curve *cv);

#endif
