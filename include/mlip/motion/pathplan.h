/*
 * mlip/motion/pathplan.h - one period of the path-speed plan along a spline
 * (issue 21; the design: docs/algorithm.md "The path-speed plan"; the model
 * it follows: bench/pathspeed.py). Not yet used by the planner: no trace
 * changes.
 *
 * The plan advances the spline's own parameter s (P5: chord length; P1 and
 * P2 hold for any parameter) with a constant path jerk j a period from the
 * state (s, v, a):
 *
 *     s(h) = s + v h + a h^2 / 2 + j h^3 / 6,  v(h) = v + a h + j h^2 / 2,
 *     a(h) = a + j h,  0 <= h <= T                                      (Q1)
 *
 * j is admissible for the period when every point of the step keeps (P2)
 * at the step's own (v(h), a(h)) there (Q2): at its start and end exactly,
 * and over each piece it crosses by a bound from the piece's coefficients
 * (x' quadratic, x'' linear, x''' constant on a piece; v and a within their
 * ranges over the times the step can be on the piece: (u - s) / vmax <= h
 * <= (u - s) / vmin), so no instant of the period exceeds J. The interval
 * at the start alone is not enough: its ends move within the period (3 x''
 * v j T through a, and x''' from piece to piece): the model's trochoid
 * reached 1.036 J at J = 1e4 with it. The step is admissible only if (P1)
 * holds at every instant too: per axis the acceleration moves at the rate
 * (P2), within the pieces' bounds, from its value at the start to its value
 * at the end, which bounds it in between (the states alone let 1.0006 A
 * through). The interval depends on j only
 * through (Q1), weakly, so `mlip_path_pick` clamps into the interval of
 * its last choice's step (from the second round by a secant step to the
 * end's fixed point) and accepts only a j inside its own step's interval.
 *
 * A braking policy (Q3): brake as hard as the limits allow toward
 * max(the (P1) floor, -a_brake[i]), but no harder than leaves the next
 * state its stop at the release jerk jr = 0.8 j_hi (v >= a^2 / (2 jr)
 * where a < 0: a and v reach 0 together); once that stop fits in the
 * period (h = -2 v / a <= T) its jerk a^2 / (2 v) over h, then rest. Its
 * jerk is admissible for its whole step (Q2) or the state is not safe.
 *
 * A state is certified (Q4) when its braking run, simulated period by
 * period, stays within every limit (speed cap, (P1), a non-empty (P2)
 * interval, each jerk admissible) until it is at rest (v = a = 0, the one
 * state safe on any curve: a crawl is not, where a hook of 0.0002 mm allows
 * no jerk at 1 mm/s) at or before `end`. The policy depends on the
 * state alone, so the first step of a certified run leads to a state that
 * the same policy certifies: the plan that only enters certified states,
 * each with the policy that certified it, always has a way to brake (a
 * hold or a stop takes it), and its fallback step exists. Several policies
 * (a gentle one for tight curves, where 3 x'' v a takes the jerk budget, a
 * hard one for straight stretches and the end) certify more states than
 * any one of them.
 *
 * The speed cap is a function of the path position (Q5): piece i's is
 *
 *     c_i = min(vmax, r f_i, r f_{i+1}),  r = vmax / vfull              (Q5)
 *
 * f the knots' caps (the curve's cap: the feed of the block each knot's
 * point belongs to, 0 none; the piece that joins two blocks takes the
 * lower), r the feed override's share (1 when vfull is 0). A run is
 * inside it when each of its steps keeps the speed at both its ends within
 * c_i of every piece i the step touches (within a step v is a parabola:
 * its mean, what a setpoint shows, is within |j| T^2 / 12 of the ends'),
 * the greedy's step checked as its run's first. So a lower cap ahead is
 * braked for in time by construction, and a higher one is taken once the
 * state is past the piece that joins them. Without caps (NULL, or every
 * f_i at least vmax / r) this is the states' check v <= vmax alone.
 *
 * Pure C, no allocation; a certification is at most max_periods policy
 * steps (the caller bounds the work; it runs outside the 1 ms period).
 */
#ifndef MLIP_PATHPLAN_H
#define MLIP_PATHPLAN_H

#include "mlip/motion/pathspeed.h"

/* (Q3) braking policies at most. */
#define MLIP_PATH_BRAKES 4

struct mlip_path_limits {
	int n;                       /* axes */
	double accel[MLIP_MAX_AXES]; /* planned per-axis limits (margins applied) */
	double jerk[MLIP_MAX_AXES];
	double vmax; /* the path speed's cap (the spline's parameter a second) */
	/* (Q5) the cap at a 100 % feed override: the knots' caps scale by vmax
	 * / vfull (0: not scaled) */
	double vfull;
	/* (Q3) the policies' decelerations, each > 0, the hardest first: a
	 * state is certified by the run of any of the first n_brake (0 counts
	 * as 1), and keeps the first whose run does (a hold brakes by it) */
	double a_brake[MLIP_PATH_BRAKES];
	int n_brake;
	double v_crawl; /* not read: the runs end at rest (Q4) */
	double period;  /* T, s */
};

struct mlip_path_state {
	double s, v, a;
	int brake; /* (Q4) the policy whose run certified it (a_brake[brake]) */
	int share; /* the plan's last candidate taken (0 the largest jerk) */
};

/* (Q1): the state h after st under jerk j (its policy kept). */
struct mlip_path_state mlip_path_advance(struct mlip_path_state st, double j, double h);

/* (Q2): the path jerks admissible at every point of the step of jerk j
 * from st (each at that step's own state; a bound per piece crossed). 0
 * when none is. */
int mlip_path_period_range(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                           struct mlip_path_state st, double j, double *lo, double *hi);

/* The admissible jerk nearest jt (Q2), in *j; 0 when none was found. */
int mlip_path_pick(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                   struct mlip_path_state st, double jt, double *j);

/* (Q3): the jerk of st's braking policy (st.brake) at st, admissible for
 * its period; 0 when there is none. */
int mlip_path_brake(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                    struct mlip_path_state st, double *j);

/* (Q3) one period of st's braking run: *st becomes the next state exactly
 * as mlip_path_certified's run has it (a stop inside the period lands at
 * rest), its jerk in *j (may be NULL). 0 when the policy has no jerk (st
 * was not certified on this curve). What the 1 ms period runs when it
 * leaves a planned queue (mlip/motion/planq.h). */
int mlip_path_brake_step(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                         struct mlip_path_state *st, double *j);

/* (Q5): piece i's speed cap. */
double mlip_path_piece_cap(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                           int i);

/* (Q4): 1 when st is certified by its policy's run (st.brake) within
 * max_periods policy steps, the path ending at `end`; *work (may be NULL)
 * grows by the steps simulated. */
int mlip_path_certified(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                        struct mlip_path_state st, double end, int max_periods, long *work);

/* One period of the greedy plan from the certified state *st (the start:
 * at rest): the largest
 * of five jerks across the start's (P2) interval, from one above the last
 * period's (st->share: the candidates above it mostly fail, and their runs
 * were most of the work), and two landing jerks between them (the one
 * whose step and a next of -a1/T end at the piece's cap (Q5) with a = 0,
 * and the one that zeroes a, unless braking below J T^2, where a = 0
 * would creep: the five alone missed them, and the plan
 * cruised below a cap in a sawtooth; tried too, before braking, below a
 * candidate that has no admissible jerk), that is admissible (Q2)
 * and leads to a state certified by some policy (tried in their order; the
 * new state keeps the first that certified it), else the step of st's own
 * policy (the rest of its certified run). 1 when it moved faster than
 * braking, 0 when it braked, -1 when the policy had no jerk (st was not
 * certified). At rest the candidates are the start's largest jerk halved
 * up to 40 times (near the end only a small move stops before it; one
 * whose step ends at rest again is no move), so the plan reaches `end`
 * at rest itself; within 1e-8 of it, it stays. */
int mlip_path_plan_period(const struct mlip_path_curve *sp, const struct mlip_path_limits *lim,
                          struct mlip_path_state *st, double end, int max_periods, long *work);

#endif
