/*
 * mlip/types.h - types shared by every module of mlip: the machine model, the
 * motion block, and the status codes.
 *
 * Units: lengths in mm, angles in degrees, time in seconds, unless a name says
 * otherwise (_ns, _pct). Positions are in joint space: one coordinate per
 * configured axis, in config order (Sec. 1.4 of the paper plans rotary axes
 * as if they were linear, degrees standing in for mm).
 */
#ifndef MLIP_TYPES_H
#define MLIP_TYPES_H

#include <stdint.h>

#define MLIP_MAX_AXES 6
/* Blocks the look-ahead holds: the planner's ring (mlip/motion/planner.h)
 * and the largest [TRAJ] LOOKAHEAD a configuration may ask for. A build-time
 * capacity like MLIP_MAX_AXES, a power of two; a build may set its own. */
#ifndef MLIP_LOOKAHEAD
#define MLIP_LOOKAHEAD 4096
#endif
/* Two points closer than this (joint-space distance) are one: the G-code
 * reader merges them, smooth and the planner skip such a block, so no
 * zero-length segment is ever planned. */
#define MLIP_MERGE_MM 1e-6

typedef enum {
	MLIP_OK = 0,
	MLIP_E_FULL,       /* fixed-capacity buffer has no room */
	MLIP_E_EMPTY,      /* nothing to take */
	MLIP_E_INVALID,    /* argument outside its documented domain */
	MLIP_E_SYNTAX,     /* input text does not parse */
	MLIP_E_RANGE,      /* value parses but is out of range (limits, NaN, inf) */
	MLIP_E_UNSUPPORTED /* well-formed but not something mlip can execute */
} mlip_status;

typedef enum { MLIP_AXIS_LINEAR = 0, MLIP_AXIS_ROTARY = 1 } mlip_axis_kind;

/* One machine axis. Field units follow the axis kind: mm or degrees. */
struct mlip_axis {
	char letter; /* 'X','Y','Z','A','B','C' */
	mlip_axis_kind kind;
	/* dynamics */
	double max_accel; /* A_k, mm/s^2 or deg/s^2, same in + and - */
	double max_vel;   /* mm/s or deg/s */
	double max_jerk;  /* J_k, mm/s^3 or deg/s^3; 0: none (mlip/motion/jerk.h) */
	/* travel */
	double min_limit; /* soft limits, mm or deg; checked on every target */
	double max_limit;
	double home; /* position at start-up, mm or deg */
	/* CAN output (used by rt/, ignored by the planner) */
	int can_node;           /* CANopen node id 1..127 */
	double counts_per_unit; /* drive counts per mm or per degree */
};

struct mlip_machine {
	int n_axes;                           /* 2..6 */
	struct mlip_axis axis[MLIP_MAX_AXES]; /* in config order */
	double max_feed_mm_s;                 /* v_m: tool speed cap (linear path, G94 sense) */
	double max_rot_feed_deg_s;            /* cap for moves of rotary axes only */
	double tolerance_mm;                  /* eps: contour tolerance at corners */
	double period_s;                      /* T: interpolation period */
	uint8_t smooth;    /* the controller runs strategy `smooth`: a feeder sends
	                      the program through the path filter (mlip/motion/smooth.h)
	                      first; 0 in segments of older builds */
	uint8_t path_plan; /* the controller plans the path speed ([TRAJ] JERK_PLAN =
	                      path, tools/rtplan.c): a feeder runs the plan's refusals
	                      and smooths on the plan's controller's machine (no J, eps
	                      less the band: mlip_simpath_machine); 0 in older segments */
	/* with path_plan or smooth: the (plan's) controller's look-ahead ([TRAJ]
	 * LOOKAHEAD), which a feeder's run of the plan, or its count of smooth's
	 * and mpct's runs (tools/lib/simcount.h), takes too; 0: MLIP_LOOKAHEAD
	 * (older segments) */
	uint32_t plan_lookahead;
};

/* What a block asks for. Only MOVE blocks reach the planner; the others are
 * program events that the controller executes between moves, with the
 * machine at rest at the end of the move before them (target ignored). */
typedef enum {
	MLIP_BLOCK_MOVE = 0,       /* G0/G1 (arcs arrive as chords) */
	MLIP_BLOCK_DWELL,          /* G4 P: wait dwell_s, to the period */
	MLIP_BLOCK_PAUSE,          /* M0/M60: wait for the operator's resume */
	MLIP_BLOCK_OPTIONAL_PAUSE, /* M1: as M0 when the optional-stop switch is on */
	MLIP_BLOCK_SPINDLE,        /* M3/M4/M5, an S change while it turns, M2/M30:
	                              value = rpm, > 0 clockwise (M3), < 0 counter-
	                              clockwise (M4), 0 stopped */
	MLIP_BLOCK_TOOL,           /* M6: value = the tool to put in the spindle (0:
	                              none), the spindle stopped by a SPINDLE before */
	MLIP_BLOCK_COOLANT,        /* M7/M8/M9, M2/M30: value = the outlets on, bits
	                              MLIP_COOLANT_MIST | MLIP_COOLANT_FLOOD (0: off) */
	MLIP_BLOCK_OUTPUT,         /* M64/M65 Pn: value = n + 1 to switch digital output n
	                              on (M64), -(n + 1) off (M65); n < MLIP_DOUT_MAX; M62/M63
	                              (with the next move): +-(n + 1 + MLIP_DOUT_SYNC) */
	MLIP_BLOCK_PROBE,          /* G38.2..G38.5: a feed move toward target that stops
	                              at the acceleration limit when the probe input
	                              changes; value = MLIP_PROBE_* */
	MLIP_BLOCK_SPEED           /* an MDI S alone (no M3/M4/M5): value = rpm >= 0 for
	                              the spindle the controller keeps turning, in its
	                              direction; a stopped one stays stopped (the reader of
	                              an MDI line cannot know whether it turns) */
} mlip_block_kind;

#define MLIP_DOUT_MAX  8  /* digital outputs M64/M65 P0..P7 ([IO] OUTPUT_0..7) */
#define MLIP_DOUT_SYNC 16 /* an OUTPUT value beyond it: M62/M63, switched with the next move */

/* A PROBE block's value: bit 0 the probe must trip (G38.2, G38.4: a move
 * that ends without a trip is an error), bit 1 toward release (G38.4, G38.5:
 * the probe must be on at the start and stops when it goes off). */
#define MLIP_PROBE_MUST_TRIP 0x1u
#define MLIP_PROBE_AWAY      0x2u

#define MLIP_COOLANT_MIST  0x1u /* M7 */
#define MLIP_COOLANT_FLOOD 0x2u /* M8 */

/* One G01-style block: an absolute target in joint space. Produced by the
 * G-code front end (arcs arrive as several chord blocks). A zeroed block is
 * a MOVE with no exact stop. */
struct mlip_block {
	double target[MLIP_MAX_AXES]; /* absolute, in config axis order */
	double feed_mm_s;             /* programmed feed: linear path speed, or deg/s for
	                                 rotary-only moves (G94); ignored when rapid */
	double tol_mm;                /* contour budget of the corner at the END of this
	                                 block: eps, or less inside a chorded arc */
	uint32_t line;                /* source line, 1-based */
	uint8_t rapid;                /* G0: runs at the machine's maximum feed */
	uint64_t seq;                 /* caller's sequence number in program order (0: none);
	                                 the planner reports the block it executes by it */
	uint8_t kind;                 /* mlip_block_kind */
	uint8_t exact_stop;           /* G61: come to rest at the end of this move */
	double dwell_s;               /* DWELL: seconds (>= 0) */
	double value;                 /* SPINDLE, TOOL, COOLANT: what it asks (see the kind) */
};

/*
 * What a block may ask: one rule set, kept by the G-code reader (a program
 * that breaks it is refused before anything moves, at the word to blame) and
 * by the controller's validation of every record it takes (a record that
 * breaks it is a fault), so nothing a checked program sends can fault the
 * controller. The machine's own ranges (CONTOUR_TOLERANCE, COUNTS_PER_UNIT,
 * ...) are refused when its configuration is loaded (mlip/machine/config.h).
 */
#define MLIP_FEED_MIN_MM_S                                                                         \
	1e-3                       /* a feed move's feed, mm/s (deg/s rotary only):                \
	                              0.06 mm/min; slower is no cut, and a move                    \
	                              that never ends */
#define MLIP_FEED_MAX_MM_S 1e6     /* 60 km/min: a larger feed is not a feed */
#define MLIP_DWELL_MAX_S   86400.0 /* a dwell (G4 P, seconds): a day */
#define MLIP_TOL_MAX_MM    1000.0  /* a block's contour tolerance, and CONTOUR_TOLERANCE */

/* The rule a block breaks (mlip_block_check); MLIP_RULE_OK: none. */
enum {
	MLIP_RULE_OK = 0,
	MLIP_RULE_DWELL,                                   /* dwell_s outside 0..DWELL_MAX */
	MLIP_RULE_TARGET,                                  /* + axis k: not finite,
	                                                      outside the soft limits, or
	                                                      beyond the drive's 32-bit
	                                                      count (COUNTS_PER_UNIT) */
	MLIP_RULE_FEED = MLIP_RULE_TARGET + MLIP_MAX_AXES, /* a feed move outside
	                                                      FEED_MIN..FEED_MAX, a rapid
	                                                      outside 0..FEED_MAX */
	MLIP_RULE_TOL                                      /* tol_mm outside 0..TOL_MAX */
};

/* The first rule b breaks on machine m, in the order above. Bounded (a few
 * comparisons an axis), so the controller runs it on every record in its
 * period. NaN fails every comparison: each test passes only a good value. */
static inline int mlip_block_check(const struct mlip_machine *m, const struct mlip_block *b)
{
	int k;

	if (b->kind == MLIP_BLOCK_DWELL && !(b->dwell_s >= 0.0 && b->dwell_s <= MLIP_DWELL_MAX_S)) {
		return MLIP_RULE_DWELL;
	}
	if (b->kind != MLIP_BLOCK_MOVE && b->kind != MLIP_BLOCK_PROBE) {
		return MLIP_RULE_OK; /* a probe move keeps a move's rules */
	}
	for (k = 0; k < m->n_axes; k++) {
		/* the count as mlip_can_counts rounds it: within int32 (0x607A) */
		double counts = b->target[k] * m->axis[k].counts_per_unit;
		if (!(b->target[k] >= m->axis[k].min_limit &&
		      b->target[k] <= m->axis[k].max_limit && counts > -2147483648.5 &&
		      counts < 2147483647.5)) {
			return MLIP_RULE_TARGET + k;
		}
	}
	if (!(b->feed_mm_s >= (b->rapid ? 0.0 : MLIP_FEED_MIN_MM_S) &&
	      b->feed_mm_s <= MLIP_FEED_MAX_MM_S)) {
		return MLIP_RULE_FEED;
	}
	if (!(b->tol_mm >= 0.0 && b->tol_mm <= MLIP_TOL_MAX_MM)) {
		return MLIP_RULE_TOL;
	}
	return MLIP_RULE_OK;
}

#endif
