/*
 * check.h - physics of a setpoint stream, measured from the samples alone:
 * per-axis acceleration from second differences, per-axis velocity and tool
 * speed from first differences, contour error as the distance of each sample
 * to the programmed polyline, and order (the samples visit the polyline
 * forwards). It trusts nothing of the planner's internals; the tests, the
 * simulator's summary and mlip-check all use it.
 *
 * Streaming, fixed memory: the polyline's points arrive in program order
 * from a source (a callback, pulled as the samples need them) and the check
 * keeps a window of at most MLIP_CHECK_RING of them, whatever the program's
 * length; the samples arrive one by one.
 *
 * What is measured, exactly (in the n coordinates of the machine):
 * - the contour error of sample i: its exact distance to the polyline
 *   restricted to the segments from path distance W (window_mm, default
 *   MLIP_CHECK_WINDOW_MM) before R_{i-1} (below) to W beyond the furthest
 *   position the order sweep for sample i reached: both directions along
 *   the path, found through bounding boxes of MLIP_CHECK_CHUNK segments and
 *   per-segment axis bounds (a segment is skipped only when it is farther
 *   than both the best distance so far and tol, so the minimum is exact).
 *   Never below the distance to the whole polyline, and equal to it
 *   wherever the polyline's nearest point lies in that window (tested
 *   against brute force in tests/unit/test_check.c).
 * - order: R_i, the path positions sample i can be at, such that the trace,
 *   its samples joined by straight lines, follows the polyline forwards
 *   within tol + chord_mm from the start (the free-space propagation of
 *   Alt and Godau's Frechet-distance decision, one trace segment at a
 *   time). chord_mm = |A| T^2 / 8 is how far a motion within the
 *   acceleration limits strays from the chord between samples T apart, so
 *   a trace within the limits whose motion stays within tol of the path,
 *   in order, always has its position in R_i, however close the path comes
 *   back to itself and however many segments go by in one period. Across
 *   a hole (mlip_check_gap) the way is unknown: R_i is then the positions
 *   within tol of the sample at most 2 v_max dt + 8 tol ahead of R_{i-1}.
 *   R_i empty: the sample stepped back, skipped part of the path, or cut
 *   across it (counted in order_errors); R_i then restarts at the sample's
 *   nearest point. A sample beyond tol is a contour error and leaves R as
 *   it was; the next one is judged as after a hole from the last good one.
 * Limits of the window: when R and the windows need more than
 *   MLIP_CHECK_RING points, the positions of R furthest behind are dropped
 *   first, then the sweep stops short (counted in window_drops).
 */
#ifndef MLIP_CHECK_H
#define MLIP_CHECK_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/types.h"

#define MLIP_CHECK_RING      4096 /* polyline points kept, power of two */
#define MLIP_CHECK_CHUNK     16   /* segments under one bounding box, power of two */
#define MLIP_CHECK_WINDOW_MM 20.0 /* path distance searched beyond R, both ways */
#define MLIP_CHECK_MAX_SET   32   /* intervals of R kept (more: merged, R only grows) */

/* Next point of the programmed polyline, in order, the start first: returns
 * 1 (pt and line filled: the source line of the block ending there), 0 at
 * the end, < 0 on error (the check then treats the polyline as ended). */
typedef int (*mlip_check_source_fn)(void *ctx, double *pt, uint32_t *line);

struct mlip_check_limits {
	int n;
	double accel[MLIP_MAX_AXES]; /* A_k */
	double jerk[MLIP_MAX_AXES];  /* J_k; 0: measured, not judged */
	double vel[MLIP_MAX_AXES];   /* V_k */
	uint8_t rotary[MLIP_MAX_AXES];
	double vmax_mm_s;      /* tool speed (linear axes) */
	double vmax_rot_deg_s; /* speed of moves of rotary axes only */
	double eps_mm;         /* contour tolerance */
	double period_s;
	double tol_mm;    /* order tolerance; 0: eps_mm (1 + 1e-9) */
	double window_mm; /* path distance searched beyond R; 0: MLIP_CHECK_WINDOW_MM */
};

struct mlip_check_iv {
	double lo_mm, hi_mm; /* path positions */
};

struct mlip_check {
	struct mlip_check_limits lim;
	/* the polyline's source */
	mlip_check_source_fn src;
	void *src_ctx;
	const double *arr; /* array source of mlip_check_init */
	size_t arr_n, arr_i;
	int src_done;  /* no more points */
	int src_error; /* the source failed */
	/* the window: points [lo, hi) of the polyline at slot p % MLIP_CHECK_RING */
	double pt[MLIP_CHECK_RING][MLIP_MAX_AXES];
	double arc_mm[MLIP_CHECK_RING]; /* path position of each point */
	uint32_t line[MLIP_CHECK_RING];
	double box_lo[MLIP_CHECK_RING / MLIP_CHECK_CHUNK][MLIP_MAX_AXES];
	double box_hi[MLIP_CHECK_RING / MLIP_CHECK_CHUNK][MLIP_MAX_AXES];
	uint64_t lo, hi;
	uint64_t hint[3];              /* the last points searched for, by kind */
	double last_pt[MLIP_MAX_AXES]; /* the last point pulled */
	double prog_mm;                /* polyline length pulled, linear axes */
	/* where the samples are on it */
	struct mlip_check_iv set[MLIP_CHECK_MAX_SET]; /* R, sorted, disjoint */
	int nset;
	double chord_mm;      /* how far a motion within the limits strays from a chord */
	int restart;          /* the last sample was beyond tol */
	uint64_t good_period; /* time of the last sample within tol */
	double near_mm;       /* path position of the last nearest point */
	/* the samples */
	double x1[MLIP_MAX_AXES], x2[MLIP_MAX_AXES], x3[MLIP_MAX_AXES]; /* last three samples */
	size_t count;                                                   /* samples seen */
	size_t run;       /* samples since the last gap (differences need 2, 3, 4) */
	size_t gap;       /* periods between the last sample and the next (1: none) */
	uint64_t periods; /* periods from the first sample to the last */
	/* results */
	uint32_t cur_line;             /* line of the block nearest to the last sample */
	double max_acc[MLIP_MAX_AXES]; /* max |second difference| / T^2 */
	size_t max_acc_at[MLIP_MAX_AXES];
	uint64_t max_acc_period[MLIP_MAX_AXES];
	uint32_t max_acc_line[MLIP_MAX_AXES];
	double max_jerk[MLIP_MAX_AXES]; /* max |third difference| / T^3 */
	size_t max_jerk_at[MLIP_MAX_AXES];
	uint64_t max_jerk_period[MLIP_MAX_AXES];
	uint32_t max_jerk_line[MLIP_MAX_AXES];
	double max_vel[MLIP_MAX_AXES]; /* max |first difference| / T */
	size_t max_vel_at[MLIP_MAX_AXES];
	double max_speed_mm_s; /* linear part of the path speed */
	size_t max_speed_at;
	double max_rot_speed_deg_s; /* on samples where no linear axis moved */
	double last_contour_mm;     /* contour error of the last sample */
	double max_contour_mm;
	size_t max_contour_at;       /* sample */
	uint64_t max_contour_period; /* its time, in periods from the first sample */
	uint32_t max_contour_line;   /* line of the block of its nearest segment */
	size_t order_errors;         /* samples out of order */
	size_t order_at;             /* the first of them */
	uint64_t order_period;
	uint32_t order_line;  /* line of the block nearest to it */
	size_t window_drops;  /* positions of R dropped for room */
	double path_mm;       /* length of the sampled path, linear axes */
	double max_abs_coord; /* largest |coordinate| seen */
};

/* A check of a polyline held in an array of npts points (must outlive c);
 * the points' lines are their indices. */
void mlip_check_init(struct mlip_check *c, const struct mlip_check_limits *lim, const double *pts,
                     size_t npts);
/* A check pulling the polyline from src as the samples need it. */
void mlip_check_init_source(struct mlip_check *c, const struct mlip_check_limits *lim,
                            mlip_check_source_fn src, void *ctx);
void mlip_check_sample(struct mlip_check *c, const double *x);
/* The next sample comes `periods` periods after the last one (samples lost,
 * e.g. CAN frames the bus never carried): velocities across the hole are its
 * mean (which cannot exceed the limit either), no acceleration is taken
 * across it, and the reach along the path is v_max times the hole. */
void mlip_check_gap(struct mlip_check *c, size_t periods);
/* After the last sample: pull the rest of the polyline (for its last point
 * and length). */
void mlip_check_finish(struct mlip_check *c);
/* Distance of the last sample to the last point of the polyline pulled. */
double mlip_check_end_error(const struct mlip_check *c);
/* Speed implied by the last two samples (joint units / s). */
double mlip_check_end_speed(const struct mlip_check *c);

/* The acceleration a second difference can show from rounding alone: samples
 * are doubles, each within half an ulp of its value, so 8 max|x| DBL_EPSILON
 * / T^2 (about 1e-10 of 1000 mm/s^2 at T = 1 ms and 500 mm). */
double mlip_check_rounding_floor(const struct mlip_check *c);

/* Verdict with stated tolerances: acceleration and velocity within the limit
 * times (1 + rel_tol) + abs_acc (quantisation floor, 0 for double traces),
 * jerk (on axes with a limit) within it times (1 + rel_tol) + 2 abs_acc / T
 * (a third difference weighs the samples 1, 3, 3, 1 where a second weighs
 * them 1, 2, 1: twice the floor, over one more T), contour within eps (1 +
 * rel_tol) + abs_mm, no sample out of order, end within end_mm of the last
 * point. Writes one line per violation (with its
 * sample, time and source line) into msg (NUL-terminated, truncated to len)
 * and returns the number of violations. */
int mlip_check_verdict(const struct mlip_check *c, double rel_tol, double abs_acc, double abs_mm,
                       double end_mm, char *msg, size_t len);

#endif
