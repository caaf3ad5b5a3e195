/*
 * mlip/ipc/ring.h - the block ring between mlip-feed and mlip-rt, and the status
 * and command areas that mlip-ctl reads and writes, all in one memory segment
 * (a POSIX shared-memory object mapped by every process).
 *
 * Pure: the segment is passed in by the caller (rt/ does shm_open + mmap);
 * nothing here allocates, prints or makes a system call.
 *
 * Segment layout (version MLIP_RING_VERSION, offsets in bytes, each area on
 * its own 64-byte cache line so that no two writers share a line):
 *
 *     0  identity   magic "MLIPRING", version, capacity, record size, n_axes
 *    64  producer   head (free-running), feeder's cached copy of tail
 *   128  consumer   tail (free-running), controller's cached copy of head
 *   192  status     seqlock generation, command reply, struct mlip_ring_status
 *                   (eight lines: state, reason, position of every axis,
 *                   the drives' positions actual, the program's start,
 *                   the outputs and the last probe, the spindle, the
 *                   hold in force)
 *   704  feeder     seqlock generation, struct mlip_ring_feeder
 *   768  mailbox    the command word (sequence, op, argument in one 64-bit
 *                   word, written by mlip-ctl) and the stop counter
 *   832  machine    the controller's struct mlip_machine, so that a feeder
 *                   checks programs against exactly the limits in force
 *                   (each axis's max_jerk, mlip/motion/jerk.h)
 *  1344  io         the controller's machine I/O (struct mlip_ring_io: its
 *                   spindle, tool change, coolant, outputs, probe), for the
 *                   same reason
 *  1472  records    capacity x struct mlip_ring_rec (88 bytes each)
 *
 * The magic (offset 0) and the version (offset 8) keep their places in every
 * layout version, so any version can tell any other that they differ.
 *
 * Who writes what (everything else only reads):
 *   mlip_ring_format() (controller, before anyone attaches): all of it, once,
 *                                  the machine area included (read-only after).
 *   feeder (the single producer):  head, tail_cache, feeder area, records.
 *   controller (the single consumer, the RT thread): tail, head_cache,
 *                                  status area and command reply; mlip-rt
 *                                  the io area, once, at its start.
 *   mlip-ctl: the command word (several mlip-ctl may race: a CAS decides);
 *   anyone attached (mlip-ctl stop, mlip-feed on a signal): the stop counter.
 *
 * The ring is single-producer single-consumer and lock-free (Linux kfifo,
 * DPDK rte_ring): head and tail are free-running uint32_t indices, a slot is
 * index & mask, count = head - tail in modular arithmetic (capacity is a power
 * of two <= 2^24, so head - tail never exceeds it). The producer writes a
 * record, then stores head with release; the consumer loads head with acquire
 * before reading records, and stores tail with release after copying them out
 * (GCC __atomic builtins, which compile under -std=c99). Records are POD.
 *
 * The status and feeder areas are seqlocks: the writer makes the generation
 * odd, stores every field (atomically, release), and makes it even again; a
 * reader retries until it sees the same even generation before and after.
 * Every field in shared memory is only ever accessed with __atomic builtins,
 * so 64-bit counters are never torn and readers are data-race free.
 *
 * Command mailbox (one slot, acknowledged): a command is one 64-bit word,
 * sequence | op << 32 | (arg & 0xffffff) << 40, posted by one compare-and-
 * swap: there is no half-posted state, so a poster killed or stopped at any
 * instruction leaves the mailbox either untouched or holding its whole
 * command (issue 17: a claim-then-publish slot stayed busy for good). A
 * poster may post only when the previous command has been completed
 * (sequence == cmd_done), so a command is never lost; the controller takes a
 * command only when its sequence differs from the last one it took, so it is
 * never applied twice.
 *
 *     ctl: post(op,arg) --CAS word(s) -> word(s+1, op, arg)--> mailbox
 *     rt:  take() sees seq != taken -> applies -> done(seq, result)
 *     ctl: result(seq) -> MLIP_OK once done == seq, with the result code
 *
 * Stop has its own path: a counter that every request increments (one
 * atomic add, never refused, never blocked by the mailbox, a dead poster or
 * a flood of other commands). The controller applies a stop whenever the
 * counter differs from the last value it saw, and publishes that value
 * (status.stop_seen): a request r (the counter's value after its add) is
 * applied once stop_seen - r >= 0 (mod 2^32). A stop is latched for the
 * program about to start: each feeder publishes the counter's value it read
 * at its start (feeder.stop_base, before it checks its program), and the
 * controller refuses a program whose feeder started before a stop it has
 * seen (stop_seen - stop_base > 0); a stop older than the feeder is stale
 * and does not touch its program.
 */
#ifndef MLIP_RING_H
#define MLIP_RING_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/types.h"

#define MLIP_RING_MAGIC        "MLIPRING" /* first 8 bytes of the segment */
#define MLIP_RING_VERSION      12u        /* bump on any change to the layout below */
#define MLIP_RING_LINE         64         /* bytes: cache line of every area */
#define MLIP_RING_MAX_CAPACITY (1u << 24) /* records; keeps sizes far from overflow */
#ifndef MLIP_RING_CAPACITY
#define MLIP_RING_CAPACITY 8192u /* default records in the ring: 8 s of 1 ms blocks */
#endif
#define MLIP_RING_READ_TRIES  1000 /* seqlock retries before a reader gives up */
#define MLIP_RING_CMD_HISTORY 8u   /* command results kept (a power of two) */

/* For constant expressions only (it evaluates x three times): power of two.
 * The checks below get a negative array size when false (C99 has no
 * _Static_assert; Linux kfifo.h). */
#define MLIP_RING_IS_POW2(x) ((x) != 0 && ((x) & ((x)-1)) == 0)
typedef char mlip_ring_capacity_pow2_check[MLIP_RING_IS_POW2(MLIP_RING_CAPACITY) ? 1 : -1];
typedef char mlip_ring_capacity_max_check[MLIP_RING_CAPACITY <= MLIP_RING_MAX_CAPACITY ? 1 : -1];

/* ---- records -------------------------------------------------------- */

/* What a record asks for (struct mlip_ring_rec.type). Only MOVE records
 * reach the planner; the others are program events (mlip_block_kind) that the
 * controller executes with the machine at rest, or the program's end. */
typedef enum {
	MLIP_REC_MOVE = 0,       /* G0/G1 (arcs as chords): target, feed, tol */
	MLIP_REC_END,            /* end-of-program marker: no motion, target ignored */
	MLIP_REC_DWELL,          /* G4 P: at rest, dwell_s seconds, to the period */
	MLIP_REC_PAUSE,          /* M0/M60: at rest until mlip-ctl resume */
	MLIP_REC_OPTIONAL_PAUSE, /* M1: as PAUSE when the optional-stop switch is on */
	MLIP_REC_SPINDLE,        /* M3/M4/M5, S: at rest, dwell_s = rpm (> 0 clockwise,
	                            < 0 counter-clockwise, 0 stop), |rpm| <= MLIP_REC_RPM_MAX */
	MLIP_REC_TOOL,           /* M6: at rest, dwell_s = the tool to insert (0 none) */
	MLIP_REC_COOLANT,        /* M7/M8/M9: at rest, dwell_s = MLIP_COOLANT_* bits on */
	MLIP_REC_OUTPUT,         /* M64/M65: at rest, dwell_s = n + 1 (output n on) or
	                            -(n + 1) (off), n < MLIP_DOUT_MAX */
	MLIP_REC_PROBE,          /* G38.x: a MOVE from rest to rest that stops when the
	                            probe input changes; dwell_s = MLIP_PROBE_* bits */
	MLIP_REC_SPEED,          /* MDI S alone: at rest, dwell_s = rpm (0..MLIP_REC_RPM_MAX)
	                            for a turning spindle, its direction kept (a CiA 402
	                            spindle only: on another machine a bad record) */
	MLIP_REC_TYPES
} mlip_rec_type;

#define MLIP_REC_RAPID    0x1u /* MOVE, G0: runs at the machine's maximum feed */
#define MLIP_REC_EXACT    0x2u /* MOVE, G61: the corner at its end is taken at rest */
/* Every record of a program a feeder runs with mpct's corners on a smooth
 * controller (it counted mpct's run of the program sooner than smooth's:
 * docs/algorithm.md "Smooth never slower than mpct"); the program's first
 * record says it for the program, any other differing is a bad record, as
 * is the flag on a controller not running smooth. */
#define MLIP_REC_MPCT     0x4u
#define MLIP_REC_FLAGS    (MLIP_REC_RAPID | MLIP_REC_EXACT | MLIP_REC_MPCT) /* other bits: bad */
#define MLIP_REC_RPM_MAX  1e6          /* a larger spindle speed is not one: a bad record */
#define MLIP_REC_TOOL_MAX 2147483647.0 /* tool numbers: whole, 0..this */

/* One block in the ring (POD, 88 bytes, no padding). Written by the feeder. */
struct mlip_ring_rec {
	uint64_t seq;                 /* 1, 2, 3, ... in program order (END included) */
	uint32_t line;                /* source line, 1-based (0: none) */
	uint16_t type;                /* mlip_rec_type */
	uint16_t flags;               /* MLIP_REC_RAPID, MLIP_REC_EXACT, MLIP_REC_MPCT */
	double target[MLIP_MAX_AXES]; /* MOVE: absolute, mm or deg, config axis order */
	double feed_mm_s;             /* MOVE: programmed feed (ignored when RAPID) */
	double tol_mm;                /* MOVE: contour budget at the end of the block */
	double dwell_s;               /* DWELL: seconds, >= 0; SPINDLE, TOOL, COOLANT: the
	                                 value the type says (the block's value) */
};

/* ---- status published by the controller ---------------------------- */

/* Which field of a record (or of the segment) a fault names. */
typedef enum {
	MLIP_FIELD_NONE = 0,
	MLIP_FIELD_SEQ,
	MLIP_FIELD_TYPE,
	MLIP_FIELD_FLAGS,
	MLIP_FIELD_FEED,
	MLIP_FIELD_TOL,
	MLIP_FIELD_DWELL,
	MLIP_FIELD_HEAD,   /* the ring's head index */
	MLIP_FIELD_TARGET, /* + axis index: target of axis k */
	MLIP_FIELD_COUNT = MLIP_FIELD_TARGET + MLIP_MAX_AXES
} mlip_rec_field;

/* Controller status (a plain value; the segment holds the same fields, each
 * accessed atomically). All written by mlip-rt, every period. */
struct mlip_ring_status {
	/* liveness */
	uint64_t heartbeat;    /* periods since start: +1 every period */
	uint64_t heartbeat_ns; /* CLOCK_MONOTONIC ns of the last heartbeat (rt/ fills) */
	/* progress */
	uint64_t exec_seq;     /* seq of the record being executed (0: none yet) */
	uint32_t exec_line;    /* its source line */
	uint32_t state;        /* mlip_ctl_state (mlip/ctl/state.h) */
	uint32_t override_pct; /* feed override in effect, percent */
	uint32_t reserved;     /* the controller's pid (mlip-rt fills it) */
	/* counters since start */
	uint64_t overruns;        /* periods that started late or ran over */
	uint64_t underruns;       /* periods that needed a block and found the ring empty */
	uint64_t can_tx_errors;   /* sends refused (ENOBUFS / EAGAIN) */
	uint64_t can_bus_errors;  /* error frames, error-passive or bus-off seen */
	uint64_t frames_sent;     /* CAN frames accepted by the socket */
	uint64_t blocks_consumed; /* records popped from the ring */
	/* the last stop (hold, stop, signal, bus fault) from its request to rest:
	 * in the status area's spare bytes, zero in segments of older builds */
	uint64_t stop_nm;      /* path travelled by the linear axes, nanometres */
	uint32_t stop_periods; /* periods it took */
	uint32_t stops;        /* stops completed since start */
	/* why the state is what it is (layout version 3) */
	uint32_t reason;        /* mlip_state_why */
	uint32_t reason_field;  /* mlip_rec_field (BAD_RECORD, RING_CORRUPT) */
	uint64_t reason_seq;    /* the record concerned (0: none) */
	uint32_t reason_line;   /* its source line */
	uint32_t optional_stop; /* the M1 switch: 1 on */
	double reason_value;    /* the offending value, the dwell, periods missed */
	/* where the machine is */
	double pos[MLIP_MAX_AXES]; /* commanded position of every axis (the setpoint) */
	double speed_mm_s;         /* path speed (joint units per second) */
	uint64_t dwell_left;       /* periods of the current dwell still to wait */
	/* CiA 402 drives (layout version 4; mlip-rt --drives) */
	uint32_t reason_node;             /* MLIP_WHY_DRIVE: the drive's CANopen node id */
	uint32_t actual_mask;             /* bit k: pos_actual[k] came from drive k's TPDO */
	double pos_actual[MLIP_MAX_AXES]; /* position actual 0x6064 (what the machine did) */
	/* in the status area's spare bytes, zero (none) in segments of older builds */
	uint32_t drive_power;         /* mlip_drive_power (mlip/canopen/cia402.h): the drives'
	                                 power, as one */
	uint32_t drive_power_periods; /* periods the last disable or enable took */
	/* layout version 5 */
	double prog_start[MLIP_MAX_AXES]; /* where the current (or last) program's first
	                                     record was taken: a continuation (mlip-feed
	                                     --start-seq) is read from there */
	/* layout version 6 */
	uint32_t stop_seen; /* the stop counter's value the controller has applied */
	/* layout version 8: operating the machine (issue 18) */
	uint32_t io_inputs; /* bit f: input function f (MLIP_IN_*, mlip/machine/config.h) is on */
	uint32_t io_mapped; /* bit f: function f is mapped in the configuration */
	uint32_t io_known;  /* bit f: its input has been read from the bus */
	uint32_t homed;     /* bit k: axis k is homed */
	uint32_t coolant;   /* layout version 9: MLIP_COOLANT_* on ([COOLANT] TYPE = io) */
	/* layout version 9: the machine's outputs and the last probe (issue 19) */
	uint64_t outputs;       /* the I/O module's outputs 0x6200:1..8, sub k in byte k-1 */
	uint32_t probe_count;   /* G38 moves completed since start (0: no result yet) */
	uint32_t probe_tripped; /* #5070: 1 the last one tripped, 0 it did not */
	uint32_t probe_line;    /* its source line */
	/* layout version 10: a CiA 402 spindle (issue 19) */
	uint32_t spindle_state;          /* mlip_spindle_phase + 1 (0: no spindle on the bus) */
	double probe_pos[MLIP_MAX_AXES]; /* #5061..: where it tripped, machine coordinates */
	double spindle_cmd_rpm;          /* commanded, the override in (> 0 clockwise) */
	double spindle_actual_rpm;       /* velocity actual 0x606C */
	uint32_t spindle_override;       /* percent */
	uint32_t spindle_node;           /* its node id */
	/* layout version 12: the hold in force, whatever the state: the
	 * mlip_state_why that holds the path (MLIP_WHY_HOLD an operator's hold,
	 * MLIP_WHY_STALL, MLIP_WHY_BUS_TX, MLIP_WHY_BUS_ERROR, MLIP_WHY_SPINDLE_WAIT,
	 * MLIP_WHY_OVERRIDE_ZERO; 0: none). At rest without a program (idle,
	 * starved) a hold is latched, as Grbl 1.1's Hold:0: the next records
	 * start held until a resume; a stop or an E-stop ends it. Override 0
	 * holds them too, until a higher override (a resume does not end it) */
	uint32_t held_by;
	uint32_t spare12; /* 0 */
};

/* Feeder status (plain value). All written by mlip-feed. */
struct mlip_ring_feeder {
	uint64_t heartbeat;    /* +1 every feeder loop */
	uint64_t heartbeat_ns; /* CLOCK_MONOTONIC ns of the last heartbeat */
	uint64_t total_blocks; /* records in the whole program (END included); 0: not known yet */
	uint32_t program_end;  /* 1 once the END record has been pushed */
	int32_t pid;           /* feeder process id (0: no feeder) */
	uint32_t stop_base;    /* the stop counter when this feeder began (layout 6): a
	                          later stop refuses its program before it starts */
	uint32_t mdi;          /* 1: the program is MDI lines (mlip-ctl mdi); 0 in older
	                          builds' segments */
};

/* ---- commands ------------------------------------------------------- */

typedef enum {
	MLIP_CMD_NONE = 0,
	MLIP_CMD_OVERRIDE,         /* arg: feed override, percent */
	MLIP_CMD_HOLD,             /* feed hold: decelerate to rest, keep the program */
	MLIP_CMD_RESUME,           /* leave a hold */
	MLIP_CMD_STOP,             /* decelerate to rest and drop the rest of the program
	                              (in the segment: the stop counter, mlip_ring_stop_post) */
	MLIP_CMD_OPTIONAL_STOP,    /* arg 1: M1 pauses; arg 0: M1 is ignored */
	MLIP_CMD_RESET,            /* leave estop (or a limit fault) once its input is released */
	MLIP_CMD_JOG,              /* continuous jog (issue 18): arg = MLIP_JOG_ARG(axis, neg,
	                              mm/min); renewed at least every MLIP_JOG_DEADMAN_S by the
	                              same command, else it stops; speed 0 stops it */
	MLIP_CMD_HOME,             /* home (issue 18): arg = axis mask (bit k: axis k; 0: every
	                              axis with a HOME_METHOD), in HOME_SEQUENCE order */
	MLIP_CMD_JOG_AXIS,         /* one more axis (or a distance) for the next MLIP_CMD_JOG
	                              (issue 18): arg = MLIP_JOG_AXIS_ARG(axis, neg, um); posted
	                              just before it (kept MLIP_JOG_DEADMAN_S) */
	MLIP_CMD_SPINDLE_OVERRIDE, /* arg: spindle override, percent (50..200; issue 19) */
	MLIP_CMD_SPINDLE_STOP,     /* arg 1: stop the spindle in a hold (Grbl's 0x9E), once at
	                              rest; arg 0: restore it; a resume restores it too and
	                              moves on once it is at speed */
	MLIP_CMD_COUNT
} mlip_ring_cmd_op;

/* MLIP_CMD_JOG's argument: axis index (bits 0-2), negative direction (bit 3),
 * speed in mm/min or deg/min (bits 4-23, 0..1048575; 0: stop the jog). */
#define MLIP_JOG_ARG(axis, neg, mm_min)                                                            \
	((int32_t)(((uint32_t)(axis)&7u) | ((neg) ? 8u : 0u) |                                     \
	           (((uint32_t)(mm_min)&0xFFFFFu) << 4)))
#define MLIP_JOG_SPEED_MAX 1048575u /* mm/min */
/* MLIP_CMD_JOG_AXIS's argument: axis index (bits 0-2), negative direction
 * (bit 3), distance in micrometres or millidegrees (bits 4-23, 0..1048575;
 * 0: continuous, to the soft limit). The jog that follows moves the axes of
 * the JOG_AXIS commands before it and its own axis together, along one
 * straight line at its speed: every distance given (incremental) or none
 * (continuous: until released, or the first axis at its soft limit). */
#define MLIP_JOG_AXIS_ARG(axis, neg, um)                                                           \
	((int32_t)(((uint32_t)(axis)&7u) | ((neg) ? 8u : 0u) | (((uint32_t)(um)&0xFFFFFu) << 4)))
#define MLIP_JOG_DIST_MAX  1048575u /* um (1.048575 m) or millidegrees */
#define MLIP_JOG_DEADMAN_S 0.25     /* a jog not renewed for this long stops */
/* The status' reason_field while a jog runs (reason MLIP_WHY_JOG): its
 * command's axis (bits 0-7), the axes that move (bits 8-15), those toward
 * their MIN_LIMIT (bits 16-23), incremental (bit 24). */
#define MLIP_JOG_FIELD(axis, axes, negs, inc)                                                      \
	(((uint32_t)(axis)&0xFFu) | ((uint32_t)(axes)&0xFFu) << 8 |                                \
	 ((uint32_t)(negs)&0xFFu) << 16 | ((inc) ? 1u << 24 : 0u))

struct mlip_ring_cmd {
	uint32_t seq; /* mailbox sequence number of this command (even, > 0) */
	uint32_t op;  /* mlip_ring_cmd_op */
	int32_t arg;  /* MLIP_CMD_OVERRIDE: percent; OPTIONAL_STOP: 0/1; else 0 */
};

/* ---- the machine's I/O (layout version 7) ----------------------------- */

/* What mlip-rt's config says the machine has ([SPINDLE], [TOOL],
 * [COOLANT]): a feeder checks a program's S, M3, M6, M8 ... against it, as
 * against the machine area's limits. Written once by mlip-rt after the
 * format (published last, release); a reader that finds it unpublished
 * (mlip-rt starting) tries again. */
struct mlip_ring_io {
	uint32_t published;   /* 1 once written */
	uint32_t spindle;     /* mlip_io_type (mlip/gcode/gcode.h) */
	uint32_t tool_change; /* mlip_io_type */
	uint32_t coolant;     /* mlip_io_type */
	uint32_t change_mask; /* bit i: axis i has a tool change position */
	uint32_t outputs;     /* issue 19 (0 in older builds): bits 0-1 the coolant
	                         outlets (MLIP_COOLANT_*, coolant io), bits 8-15
	                         the digital outputs mapped (M64/M65 P0..7), bit
	                         16 a probe input (G38) */
	double min_rpm, max_rpm;
	double change_pos[MLIP_MAX_AXES]; /* machine coordinates, config order */
};

/* ---- the segment header --------------------------------------------- */

#define MLIP_RING_ALIGNED __attribute__((aligned(MLIP_RING_LINE)))

/* The first bytes of the segment; records follow at hdr_bytes. Public so the
 * layout is the documented contract; use the functions below to access it. */
struct mlip_ring {
	/* identity: written once by mlip_ring_format, read-only afterwards */
	uint64_t magic;     /* MLIP_RING_MAGIC bytes; stored last (release) */
	uint32_t version;   /* MLIP_RING_VERSION */
	uint32_t capacity;  /* records, power of two */
	uint32_t mask;      /* capacity - 1 */
	uint32_t rec_bytes; /* sizeof(struct mlip_ring_rec) */
	uint32_t hdr_bytes; /* sizeof(struct mlip_ring): offset of record 0 */
	uint32_t n_axes;    /* coordinates used in each record, 1..MLIP_MAX_AXES */

	/* producer line: the feeder */
	uint32_t head MLIP_RING_ALIGNED; /* next slot to write, free-running */
	uint32_t tail_cache;             /* feeder's last view of tail (private) */

	/* consumer line: the controller */
	uint32_t tail MLIP_RING_ALIGNED; /* next slot to read, free-running */
	uint32_t head_cache;             /* controller's last view of head (private) */

	/* status: the controller */
	uint32_t status_gen MLIP_RING_ALIGNED; /* seqlock over status: odd while writing */
	uint32_t cmd_taken;                    /* seq of the last command taken */
	uint32_t cmd_done;                     /* seq of the last command completed */
	int32_t cmd_result;                    /* its result: an mlip_status value */
	struct mlip_ring_status status;
	int32_t cmd_results[MLIP_RING_CMD_HISTORY]; /* result of command seq at seq % 8:
	                                               a poster that lost the race to
	                                               read cmd_result still finds its own */

	/* feeder area: the feeder */
	uint32_t feeder_gen MLIP_RING_ALIGNED; /* seqlock over feeder */
	uint32_t feeder_reserved;
	struct mlip_ring_feeder feeder;

	/* command mailbox: mlip-ctl; the stop counter: anyone attached */
	uint64_t cmd_word MLIP_RING_ALIGNED; /* seq | op << 32 | (arg & 0xffffff) << 40 */
	uint32_t stop_req;                   /* stop requests so far (+1 each) */

	/* machine: written by mlip_ring_format_machine before the magic */
	struct mlip_machine machine MLIP_RING_ALIGNED;

	/* io: mlip-rt, once (mlip_ring_io_publish) */
	struct mlip_ring_io io MLIP_RING_ALIGNED;
};

/* Why an attach (or a format) was refused. */
typedef enum {
	MLIP_RING_MATCH = 0,
	MLIP_RING_BAD_ARG,      /* NULL pointer */
	MLIP_RING_BAD_ALIGN,    /* segment not aligned to MLIP_RING_LINE bytes */
	MLIP_RING_SHORT,        /* segment smaller than the header */
	MLIP_RING_BAD_MAGIC,    /* not an mlip ring, or not formatted yet */
	MLIP_RING_BAD_VERSION,  /* layout version differs */
	MLIP_RING_BAD_RECORD,   /* record size differs */
	MLIP_RING_BAD_HEADER,   /* header size differs */
	MLIP_RING_BAD_CAPACITY, /* 0, not a power of two, or above MLIP_RING_MAX_CAPACITY */
	MLIP_RING_BAD_AXES,     /* n_axes outside 1..MLIP_MAX_AXES or not the expected one */
	MLIP_RING_TRUNCATED     /* segment smaller than header + capacity records */
} mlip_ring_reason;

/* A refusal, with the two values a tool needs to say e.g. "segment layout
 * version 2, this program speaks 3": found in the segment, expected here. For
 * BAD_ALIGN found is the address modulo MLIP_RING_LINE; for SHORT and
 * TRUNCATED found is the segment size and expected the size needed. */
struct mlip_ring_mismatch {
	mlip_ring_reason reason;
	uint64_t found;
	uint64_t expected;
};

/* Short noun phrase for a reason ("layout version", "record size", ...),
 * never NULL. */
const char *mlip_ring_reason_str(mlip_ring_reason reason);

/* Bytes of a segment holding capacity records (header included); 0 when
 * capacity is not a power of two in 1..MLIP_RING_MAX_CAPACITY. */
size_t mlip_ring_bytes(uint32_t capacity);

/* Controller side: write a fresh header (empty ring, zeroed status, feeder and
 * mailbox areas, override 100 %) into mem, which must be MLIP_RING_LINE-aligned
 * and hold mlip_ring_bytes(capacity) bytes. The magic is stored last, with
 * release, so an attacher never sees a half-written header. Not safe while
 * other processes use the segment. MLIP_E_INVALID on bad arguments. */
mlip_status mlip_ring_format(void *mem, size_t bytes, uint32_t capacity, int n_axes);

/* Any side: check that mem (bytes long) holds a ring this program can use and
 * return it in *out. n_axes: the coordinates the caller will read or write,
 * or 0 to accept any. MLIP_E_INVALID with *why filled (why may be NULL) on a
 * mismatch; *out is then NULL. */
/* Format for machine m (n_axes = m->n_axes) and publish m in the segment. */
mlip_status mlip_ring_format_machine(void *mem, size_t bytes, uint32_t capacity,
                                     const struct mlip_machine *m);
/* The machine the controller published (zeroed if plain format was used). */
void mlip_ring_machine(const struct mlip_ring *r, struct mlip_machine *out);

/* The controller's process: publish the machine's I/O (once, at its start;
 * io->published is ignored). */
void mlip_ring_io_publish(struct mlip_ring *r, const struct mlip_ring_io *io);
/* Any side: the machine's I/O; MLIP_E_EMPTY while unpublished. */
mlip_status mlip_ring_io_read(const struct mlip_ring *r, struct mlip_ring_io *out);

mlip_status mlip_ring_attach(void *mem, size_t bytes, int n_axes, struct mlip_ring **out,
                             struct mlip_ring_mismatch *why);

/* ---- ring operations (producer: feeder; consumer: controller) -------- */

/* Producer: append one record. MLIP_E_FULL when there is no room. */
mlip_status mlip_ring_push(struct mlip_ring *r, const struct mlip_ring_rec *rec);

/* Producer: append up to n records in order, as many as fit; returns how
 * many were appended (0..n), published together with one store. */
uint32_t mlip_ring_push_n(struct mlip_ring *r, const struct mlip_ring_rec *recs, uint32_t n);

/* Consumer: copy the oldest record to *out without removing it.
 * MLIP_E_EMPTY when the ring is empty. */
mlip_status mlip_ring_peek(struct mlip_ring *r, struct mlip_ring_rec *out);

/* Consumer: remove the oldest record, copying it to *out (out may be NULL).
 * MLIP_E_EMPTY when the ring is empty. */
mlip_status mlip_ring_pop(struct mlip_ring *r, struct mlip_ring_rec *out);

/* Consumer: remove up to max records (a bounded budget per period), copying
 * them to out[0..] in order (out NULL: discard them, e.g. on stop); returns
 * how many were removed. */
uint32_t mlip_ring_pop_n(struct mlip_ring *r, struct mlip_ring_rec *out, uint32_t max);

/* Any side: records in the ring, 0..capacity (a snapshot: the other side may
 * change it at once). */
uint32_t mlip_ring_count(const struct mlip_ring *r);

/* Any side: free slots, capacity - count. */
uint32_t mlip_ring_space(const struct mlip_ring *r);

/* Empty the ring and restart both free-running indices at index (tests use
 * values near UINT32_MAX to exercise the wrap). Only while no producer or
 * consumer is active. */
void mlip_ring_reset(struct mlip_ring *r, uint32_t index);

/* ---- ports: one side's private view of the ring ------------------------ */

/* Made once, after mlip_ring_attach (or format) checked the header: the
 * capacity, mask and axes are copied and the side's own index is kept here,
 * so nothing read from the segment later steers an index or a size. The
 * other side's index is read from the segment and range-checked: head - tail
 * beyond the capacity is MLIP_E_RANGE (a corrupted or hostile segment), never
 * a read or write outside the records. */
struct mlip_ring_port {
	struct mlip_ring *r;
	uint32_t capacity, mask, n_axes;
	uint32_t own;   /* consumer: tail; producer: head (private master copy) */
	uint32_t other; /* the other side's index, last seen */
	int producer;
};

/* MLIP_E_INVALID when the header does not describe a ring (it was checked at
 * attach; a port is opened right after). */
mlip_status mlip_ring_port_open(struct mlip_ring_port *p, struct mlip_ring *r, int producer);
/* Records queued (consumer) or free slots (producer) in *n; MLIP_E_RANGE,
 * *n = 0, when the indices are more than a capacity apart (*n gets that
 * distance through `apart` when not NULL). */
mlip_status mlip_ring_port_count(struct mlip_ring_port *p, uint32_t *n, uint32_t *apart);
/* The records a consumer may take, oldest first, where they lie: at most
 * two spans of the segment's slots (the ring wraps). Read only; a reader
 * copies a record before it checks it, so a producer that does not keep to
 * the protocol cannot change what was checked. */
struct mlip_rec_view {
	const struct mlip_ring_rec *span[2];
	uint32_t len[2];
};
/* Consumer: every record queued now, without copying (MLIP_E_RANGE, an
 * empty view and *apart as mlip_ring_port_count, for a corrupted segment). */
mlip_status mlip_ring_port_view(struct mlip_ring_port *p, struct mlip_rec_view *v, uint32_t *apart);
/* Consumer: remove the n oldest records (at most those last viewed):
 * their slots go back to the producer. MLIP_E_RANGE for more. */
mlip_status mlip_ring_port_pop_n(struct mlip_ring_port *p, uint32_t n);
/* Producer: append up to n records; how many in *pushed (MLIP_E_RANGE: none). */
mlip_status mlip_ring_port_push_n(struct mlip_ring_port *p, const struct mlip_ring_rec *recs,
                                  uint32_t n, uint32_t *pushed);

/* Record <-> block: kind <-> type, exact_stop <-> MLIP_REC_EXACT, dwell_s.
 * An END record has no block: mlip_ring_rec_to_block returns MLIP_E_EMPTY for
 * it, and MLIP_E_INVALID for an unknown type. */
void mlip_ring_rec_from_block(struct mlip_ring_rec *rec, const struct mlip_block *b, uint64_t seq);
void mlip_ring_rec_end(struct mlip_ring_rec *rec, uint64_t seq, uint32_t line);
mlip_status mlip_ring_rec_to_block(const struct mlip_ring_rec *rec, struct mlip_block *b);

/* ---- status and feeder areas (seqlocks) ------------------------------ */

/* Controller: publish *s (every period). Wait-free. */
void mlip_ring_status_write(struct mlip_ring *r, const struct mlip_ring_status *s);

/* Any side: a consistent copy of the controller status. MLIP_E_EMPTY when no
 * consistent copy was seen in MLIP_RING_READ_TRIES attempts (the writer died
 * mid-update, or keeps preempting the reader); try again later. */
mlip_status mlip_ring_status_read(const struct mlip_ring *r, struct mlip_ring_status *s);

/* Feeder: publish *f. Wait-free. */
void mlip_ring_feeder_write(struct mlip_ring *r, const struct mlip_ring_feeder *f);

/* Any side: a consistent copy of the feeder area; MLIP_E_EMPTY as above. */
mlip_status mlip_ring_feeder_read(const struct mlip_ring *r, struct mlip_ring_feeder *f);

/* ---- command mailbox -------------------------------------------------- */

/* mlip-ctl: post a command. MLIP_E_FULL while the previous command is not
 * completed yet (or another mlip-ctl posted first): retry later;
 * MLIP_E_INVALID for an unknown op and for MLIP_CMD_STOP (the stop counter
 * is its path); MLIP_E_RANGE for an arg outside MLIP_RING_CMD_ARG_MIN..MAX.
 * On MLIP_OK *seq (may be NULL) is the command's sequence number, to pass
 * to mlip_ring_cmd_result. */
#define MLIP_RING_CMD_ARG_MIN (-(1 << 23))
#define MLIP_RING_CMD_ARG_MAX ((1 << 23) - 1)
mlip_status mlip_ring_cmd_post(struct mlip_ring *r, mlip_ring_cmd_op op, int32_t arg,
                               uint32_t *seq);

/* mlip-ctl: MLIP_OK with *result (an mlip_status the controller returned for
 * the command) once command seq is completed; MLIP_E_EMPTY while pending;
 * MLIP_E_RANGE when it was completed but MLIP_RING_CMD_HISTORY later commands
 * (other mlip-ctl's) have completed since, so its result is no longer kept. */
mlip_status mlip_ring_cmd_result(const struct mlip_ring *r, uint32_t seq, int32_t *result);

/* Controller: take a newly posted command (each exactly once). MLIP_E_EMPTY
 * when there is none. Then apply it and call mlip_ring_cmd_done. */
mlip_status mlip_ring_cmd_take(struct mlip_ring *r, struct mlip_ring_cmd *out);

/* Controller: report command seq completed with result (MLIP_OK, or e.g.
 * MLIP_E_RANGE for an override out of range). Lets mlip-ctl post again. */
void mlip_ring_cmd_done(struct mlip_ring *r, uint32_t seq, int32_t result);

/* Anyone attached: ask for a stop (mlip-ctl stop, mlip-feed on a signal).
 * One atomic add: never refused, never blocked. Returns the request's
 * ticket, applied once mlip_ring_stop_applied(status.stop_seen, ticket). */
uint32_t mlip_ring_stop_post(struct mlip_ring *r);

/* The stop counter: requests so far (a feeder's stop_base; the controller's
 * input every period). */
uint32_t mlip_ring_stop_count(const struct mlip_ring *r);

/* 1 when a controller that has seen the counter at `seen` has applied the
 * request with `ticket` (modular: the counter wraps). */
int mlip_ring_stop_applied(uint32_t seen, uint32_t ticket);

/* 1 when a stop newer than a feeder's start (stop_base) has been seen: its
 * program must not start. */
int mlip_ring_stop_after(uint32_t seen, uint32_t stop_base);

/* Names for tools: "override", "hold", ...; "feed", "target[0]", ... for a
 * field (target fields by axis letter need the machine: see tools); "?"
 * for values out of range. Never NULL. The state's and the reason's:
 * mlip/ctl/state.h. */
const char *mlip_ring_cmd_name(uint32_t op);
const char *mlip_rec_field_name(uint32_t field);
const char *mlip_rec_type_name(uint32_t type);

#endif
