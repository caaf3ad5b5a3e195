/*
 * check.h - physics of a setpoint stream, measured from the samples alone:
 * per-axis acceleration from second differences, per-axis velocity and tool
 * speed from first differences, contour error as the distance of each sample
 * to the programmed polyline. It trusts nothing of the planner's internals;
 * the tests, the simulator's summary and mlip-check all use it.
 */
#ifndef MLIP_CHECK_H
#define MLIP_CHECK_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/types.h"

struct mlip_check_limits {
	int n;
	double accel[MLIP_MAX_AXES];   /* A_k */
	double vel[MLIP_MAX_AXES];     /* V_k */
	uint8_t rotary[MLIP_MAX_AXES];
	double vmax_mm_s;              /* tool speed (linear axes) */
	double vmax_rot_deg_s;         /* speed of moves of rotary axes only */
	double eps_mm;                 /* contour tolerance, sets the search reach */
	double period_s;
};

struct mlip_check {
	struct mlip_check_limits lim;
	const double *pts;      /* polyline: npts points of n coordinates, start first */
	size_t npts;
	size_t cursor;          /* segment nearest to the last sample */
	double x1[MLIP_MAX_AXES], x2[MLIP_MAX_AXES]; /* last two samples */
	size_t count;           /* samples seen */
	size_t run;             /* samples since the last gap (differences need 2, 3) */
	size_t gap;             /* periods between the last sample and the next (1: none) */
	/* results */
	double max_acc[MLIP_MAX_AXES];   /* max |second difference| / T^2 */
	size_t max_acc_at[MLIP_MAX_AXES];
	double max_vel[MLIP_MAX_AXES];   /* max |first difference| / T */
	double max_speed_mm_s;           /* linear part of the path speed */
	double max_rot_speed_deg_s;      /* on samples where no linear axis moved */
	double max_contour_mm;
	size_t max_contour_at;
	double path_mm;                  /* length of the sampled path, linear axes */
	double max_abs_coord;            /* largest |coordinate| seen */
};

void mlip_check_init(struct mlip_check *c, const struct mlip_check_limits *lim,
                     const double *pts, size_t npts);
void mlip_check_sample(struct mlip_check *c, const double *x);
/* The next sample comes `periods` periods after the last one (samples lost,
 * e.g. CAN frames the bus never carried): velocities across the hole are its
 * mean (which cannot exceed the limit either), no acceleration is taken
 * across it, and the contour search reaches as far as v_max allows. */
void mlip_check_gap(struct mlip_check *c, size_t periods);
/* Distance of the last sample to the last point of the polyline. */
double mlip_check_end_error(const struct mlip_check *c);
/* Speed implied by the last two samples (joint units / s). */
double mlip_check_end_speed(const struct mlip_check *c);

/* The acceleration a second difference can show from rounding alone: samples
 * are doubles, each within half an ulp of its value, so 8 max|x| DBL_EPSILON
 * / T^2 (about 1e-10 of 1000 mm/s^2 at T = 1 ms and 500 mm). */
double mlip_check_rounding_floor(const struct mlip_check *c);

/* Verdict with stated tolerances: acceleration and velocity within the limit
 * times (1 + rel_tol) + abs_acc (quantisation floor, 0 for double traces),
 * contour within eps (1 + rel_tol) + abs_mm, end within end_mm of the last
 * point. Writes one line per violation into msg (NUL-terminated, truncated
 * to len) and returns the number of violations. */
int mlip_check_verdict(const struct mlip_check *c, double rel_tol, double abs_acc,
                       double abs_mm, double end_mm, char *msg, size_t len);

#endif
