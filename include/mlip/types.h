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
	uint8_t smooth; /* the controller runs strategy `smooth`: a feeder sends
	                   the program through the path filter (mlip/motion/smooth.h)
	                   first; 0 in segments of older builds */
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
	MLIP_BLOCK_COOLANT         /* M7/M8/M9, M2/M30: value = the outlets on, bits
	                              MLIP_COOLANT_MIST | MLIP_COOLANT_FLOOD (0: off) */
} mlip_block_kind;

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

#endif
