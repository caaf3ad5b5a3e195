/*
 * mlip/motion/smooth.h - the `smooth` strategy's path filter: a stream filter with a
 * fixed-size sliding window that replaces CAM micro-segments by a smoothed,
 * finely resampled polyline inside the contour tolerance, and gives each
 * output block the part of the tolerance its corner may still use. The
 * planner then runs the paper's corners (mpct) on the output.
 *
 * Contract: every point of every output segment lies within
 *     dev <= rho * budget        (rho = MLIP_SMOOTH_RHO)
 * of the ORIGINAL polyline, and each output block's tol_mm is
 *     tol = budget - (largest dev of the two segments its end corner touches),
 * so a corner's deviation (17)(18) plus the smoothing's stays within the budget:
 * min(eps, the block's own tol_mm) of the original blocks around it. With a
 * jerk limit the budget is that less E_f (mlip/motion/jerk.h, J5), and tol_mm
 * carries E_f back, which the planner takes from every block.
 *
 * Fixed memory (the struct, owned by the caller) and bounded work per block:
 * a block adds at most MLIP_SMOOTH_MAX_PIECES samples, and each sample is
 * solved over at most MLIP_SMOOTH_ITER + MLIP_SMOOTH_POLISH banded solves in at
 * most two windows.
 * Pure C, no allocation, no I/O: the same code runs in every host tool.
 *
 * Use: push input blocks in program order; after each push, pop until
 * MLIP_E_EMPTY; at the program's end call finish, then pop the rest. Exact
 * points (a run of feed moves ends there and the next one starts there):
 * the start, a rapid, a feed change, a non-move block, an exact stop, the
 * end. Non-move blocks and rapids pass through unchanged, in order.
 */
#ifndef MLIP_SMOOTH_H
#define MLIP_SMOOTH_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/motion/jerk.h"
#include "mlip/motion/planner.h"
#include "mlip/types.h"

#define MLIP_SMOOTH_CAP 4096 /* samples in the window */
#define MLIP_SMOOTH_KEEP                                                                           \
	512 /* samples left unsolved after a solve: the                                            \
	       right-hand context of the frozen ones */
#define MLIP_SMOOTH_MAX_PIECES                                                                     \
	16                      /* samples a block adds, at most (and up to 4 more                 \
	                           sub-samples of the segment before it) */
#define MLIP_SMOOTH_ITER   24   /* reweighting iterations per solve */
#define MLIP_SMOOTH_POLISH 3    /* then solves holding the samples beyond their radius */
#define MLIP_SMOOTH_RHO    0.95 /* share of the budget the smoothing may take */
#define MLIP_SMOOTH_LONE   2    /* turns between two sharp ones that stay exact (smooth.c) */
#define MLIP_SMOOTH_SHARP_COS                                                                      \
	0.76604444311897804 /* cos 40 deg: a vertex turning more                                   \
	       stays sharp (the filter pins it, the planner                                        \
	       takes the paper's corner there) */

struct mlip_smooth_sample {
	double p[MLIP_MAX_AXES]; /* point of the original polyline at this sample */
	double x[MLIP_MAX_AXES]; /* smoothed point */
	double h;                /* original arc length from the previous sample */
	double b;                /* budget: min(eps, tol_mm) of the nearby corners */
	double r;                /* radius allowed: |x - p| <= r */
	double bmin;             /* smallest budget within two samples */
	double w;                /* data weight of the spline (reweighted) */
	double w0;               /* its floor */
	double dev;              /* |x - p| once frozen */
	struct mlip_block blk;   /* block to emit (target = x), or a pass-through */
	uint8_t role;            /* SMOOTH_* in smooth.c */
	uint8_t pinned;          /* x = p exactly */
	uint8_t drop;            /* not emitted (a sub-sample next to a sharp corner) */
	uint8_t hold;            /* held on the band's edge while a solve polishes */
};

struct mlip_smooth {
	int n;                      /* axes */
	double eps_mm;              /* machine tolerance */
	double filter_mm;           /* what a jerk limit's mean takes of it (E_f, jerk.h) */
	double step_mm;             /* resampling step */
	double sharp_cos;           /* cos of the turn above which a vertex stays sharp */
	double gap_mm;              /* sub-samples this close to a sharp vertex are dropped */
	double l0_mm;               /* the spline's initial smoothing length */
	double rho;                 /* MLIP_SMOOTH_RHO */
	double corner_need;         /* share of h^2 k the corners keep (0: none) */
	double last[MLIP_MAX_AXES]; /* last original point */
	double last_dir[MLIP_MAX_AXES];
	double last_d_mm;              /* length of the last original segment */
	double last_b;                 /* budget of the corner at last[] */
	double run_feed;               /* feed of the open run */
	int run_open;                  /* a run of feed moves is open */
	int have_dir;                  /* last_dir valid (the run has a segment) */
	int pend;                      /* the newest segment is one sample, not yet subdivided */
	int pend_kv_ok;                /* pend_kv is valid */
	double pend_kv[MLIP_MAX_AXES]; /* curvature at the pending segment's first vertex */
	double jitter;                 /* running mean of how erratically the curvature changes */
	double jitter_min;             /* subdivide where jitter is above this */
	int pin_clean;                 /* keep vertices exact where it is below jitter_pin */
	double jitter_pin;
	uint32_t run0;                   /* index of the open run's start sample */
	int n_lone;                      /* turns below sharp_deg since the last sharp vertex
	                                    or the run's start, up to MLIP_SMOOTH_LONE
	                                    (more, or a clean one: -1) */
	uint32_t lone[MLIP_SMOOTH_LONE]; /* their samples */
	uint32_t frozen;                 /* samples [0, frozen) are final */
	uint32_t emit;                   /* next sample to emit */
	uint32_t count;                  /* samples in the window */
	double prev_dev, prev_b;         /* last emitted sample of the run */
	/* statistics */
	uint64_t in_blocks, out_blocks, solves;
	double max_dev;
	struct mlip_smooth_sample s[MLIP_SMOOTH_CAP];
	/* banded solver scratch: pentadiagonal LDL^T */
	double a0[MLIP_SMOOTH_CAP], a1[MLIP_SMOOTH_CAP], a2[MLIP_SMOOTH_CAP];
	double l1[MLIP_SMOOTH_CAP], l2[MLIP_SMOOTH_CAP];
	double rhs[MLIP_SMOOTH_CAP * MLIP_MAX_AXES];
};

/* Start at rest at start[] on machine m (its tolerance is eps). */
mlip_status mlip_smooth_init(struct mlip_smooth *sm, const struct mlip_machine *m,
                             const double *start);

/* Take one input block. MLIP_E_FULL when the output must be popped first
 * (never after popping until MLIP_E_EMPTY). MLIP_E_RANGE on a non-finite
 * target. */
mlip_status mlip_smooth_push(struct mlip_smooth *sm, const struct mlip_block *b);

/* The program ended: everything pushed becomes poppable. */
void mlip_smooth_finish(struct mlip_smooth *sm);

/* Next output block, or MLIP_E_EMPTY. */
mlip_status mlip_smooth_pop(struct mlip_smooth *sm, struct mlip_block *out);

/* ---- the smooth strategy's corners in the planner (smoothplan.c) -------- */

/* The smooth strategy's corner with a = (w e_e - (1 - w) e_s) / g on the
 * acceleration polygon's boundary (g the largest |a_k| / A_k of the
 * unscaled vector), t from (18)(19)(20). -1 when a is 0. */
int mlip_corner_smooth_w(int n, const double *e_s, const double *e_e, double ds_mm, double de_mm,
                         const double *accel, double eps_mm, double vcap_s_mm_s, double vcap_e_mm_s,
                         double w, struct mlip_corner *c);
/* 1 when the turn from e_s to e_e is sharper than MLIP_SMOOTH_SHARP_COS:
 * the smooth strategy takes the paper's corner there. */
int mlip_corner_smooth_sharp(int n, const double *e_s, const double *e_e);

/* The smooth strategy's corner shapes: out[0] is mlip_corner_plan's, then
 * up to MLIP_SMOOTH_SHAPES - 1 braking shapes on the acceleration polygon's
 * boundary (v_e < v_s) that the backward pass chooses where braking limits
 * the corner, with their w (shapes 1..: the corner is mlip_corner_smooth_w's
 * at that w). Returns how many. */
#define MLIP_SMOOTH_SHAPES 6
int mlip_corner_smooth_shapes(int n, const double *e_s, const double *e_e, double ds_mm,
                              double de_mm, const double *accel, double eps_mm, double vcap_s_mm_s,
                              double vcap_e_mm_s, struct mlip_corner *out, double *w_out);

/* A corner shape as the backward pass weighs it: its w (for
 * mlip_corner_smooth_w) and, at q = 1, 1/v_s^2, 1/v_e^2, B = v_s^2 - 2 a l_s,
 * C = v_e^2 + 2 a' l_e and 1/C (0 when C is 0), as the planner's
 * look-ahead coefficients have them. */
struct mlip_shape {
	double w, inv_vs2, inv_ve2, b, c, inv_c;
};

/* What the smooth strategy keeps of a segment's end corner, beside the
 * planner's struct mlip_seg: the shapes its corner is chosen among, which
 * one it is (or MLIP_SHAPE_FIXED once the executor chose the corner), and
 * what the plans a full pass replaced promised it: the largest q B and q C,
 * and the shape the last one left (anchor). */
struct mlip_smooth_seg {
	uint8_t n_shapes, shape, anchor;
	double commit_in, commit_out;
	struct mlip_corner shape0; /* shapes[0]'s corner; the others from w */
	struct mlip_shape shapes[MLIP_SMOOTH_SHAPES];
};
#define MLIP_SHAPE_FIXED 255

/* The storage mlip_planner_init needs with MLIP_STRATEGY_SMOOTH (owned by
 * the caller, like the planner: about 1.5 MB, only for smooth). */
struct mlip_smooth_store {
	struct mlip_smooth_seg seg[MLIP_LOOKAHEAD];
};

#endif
