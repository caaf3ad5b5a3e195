/*
 * mlip/ctl/controller.h - the controller's period as a pure function, in the
 * shape of Ruckig's update(input, output): mlip_ctl_period(c, in, out).
 *
 * Everything the period needs arrives in `in`: the period index and how
 * many periods the loop missed before it, the records it may take (a view
 * of the caller's queue: the segment's ring in mlip-rt, an array in
 * mlip-sim; nothing is removed from it here), the command, the feeder's
 * liveness (a boolean the caller computes from its clock), the bus counters
 * of the last send, and what the drives said. Everything it decides leaves
 * in `out`: how many records it took (the caller pops them), the setpoint,
 * the CAN frames to send (encoded, not sent), the status to publish, the
 * events to log, the drives' power and the counters. No allocation, no I/O,
 * no clock: rt/period.c runs it on the SCHED_FIFO loop, mlip-sim on a
 * virtual clock, so both produce the same setpoints by construction.
 *
 *   in:  period, missed        the clock: index, deadlines missed before it
 *        recs, recs_corrupt    the records it may take (mlip_rec_view)
 *        cmd, exit_request     the operator: a mailbox command, a signal
 *        feeder_alive          the peer: is a feeder attached and beating
 *        bus                   tx refused, bus-off
 *        drives                muted drives, statuswords, a new fault,
 *                              positions actual (rt/drives.c's hooks)
 *   out: taken                 records to pop from the front of recs
 *        pos, frames           the setpoint, and its CAN frames to send
 *        cmd_result            the mailbox command's result
 *        status, events        what to publish and what to log
 *        power, counts         the drives' power, the counters since init
 *        done                  an exit request is complete (at rest, drives off)
 * A new input (an I/O module's inputs, a jog command) is a group of `in`,
 * a new output (a spindle's controlword) a group of `out`.
 *
 * One state (mlip_ctl_state, mlip/ctl/state.h), every transition named with its reason
 * (mlip_state_why + record seq, line, field, value), kept in the status:
 *
 *   IDLE --record seq 1 (or the one after the last completed)--> PREREAD
 *   PREREAD --look-ahead full | END in | event next | refill and ring empty
 *             | feeder gone--> RUNNING            (up to 64 records a period)
 *   RUNNING --at rest, END executed--> IDLE       (up to 16 records a period)
 *   RUNNING --at rest, nothing came--> STARVED --next record--> PREREAD
 *   RUNNING --hold | override 0 | CAN fault, at rest--> HELD --resume--> RUNNING
 *   RUNNING|HELD|STOPPING --missed > stall periods--> HELD (stall: frozen at
 *             the last setpoint sent, planned again from rest there; resume)
 *   RUNNING --at rest, DWELL next--> DWELLING --round(dwell/T) periods--> RUNNING
 *   RUNNING --at rest, PAUSE (or M1, switch on) next--> PAUSED --resume--> RUNNING
 *             (a wait pre-reads what follows; if that is not done at its
 *             end: PREREAD first)
 *   any --stop | exit signal--> STOPPING --at rest--> IDLE
 *   IDLE --a program whose feeder began before a stop seen--> IDLE (reason
 *             STOP_EARLY: the stop is latched for the program about to
 *             start; its records are dropped unmoved, its first one named)
 *   PREREAD (a new program's) --stop--> IDLE (STOP_EARLY, as above)
 *   any --bad record--> FAULT (moving: at rest at the end of the last good
 *             block: ingest stops, the look-ahead already plans it to rest)
 *   Nothing moved since the last rest (PREREAD, DWELLING, PAUSED: the
 *   planner is not stepped there): a stop, exit, bad record, drive fault or
 *   E-stop drops what the planner holds where it rests; no setpoint changes.
 *   any --position beyond the drives' range--> FAULT (stop on the path)
 *   any --a drive fault (in->drives.fault)--> FAULT (reason DRIVE: node, event,
 *             value; every axis stops on the path, nothing more is taken;
 *             the faulted drive's own fault reaction applies to it)
 *   any --E-stop input, or the I/O module lost (in->io)--> ESTOP (reason
 *             ESTOP or IO_LOST: quick stop 0x0002 to every drive in this
 *             period, the program dropped, the planner at rest where the
 *             drives are, every output off) --reset, input released--> IDLE
 *             (or FAULT again when a drive fault came before or in it)
 *   IDLE --jog command (MLIP_CMD_JOG: axis, direction, speed; the axes and
 *             distances of the MLIP_CMD_JOG_AXIS just before it)--> JOGGING
 *             (drives enabled first) along one line at that speed through
 *             the planner, toward the first soft limit (continuous) or each
 *             distance (incremental; a target beyond a soft limit refused);
 *             --released (speed 0), hold, or not renewed within
 *             MLIP_JOG_DEADMAN_S--> braking at the acceleration limit
 *             --at rest--> IDLE (reason JOG_RELEASED, JOG_DEADMAN, JOG_END,
 *             JOG_DONE)
 *   RUNNING|HELD|STOPPING|... --a limit input while moving--> FAULT (reason
 *             LIMIT: the axis and direction; quick stop as for an E-stop)
 *             --reset, input released--> IDLE
 *   HELD <--hold input (rising edge)-- ; cycle start input: resume
 *   IDLE --in->plan, a new in->plan_prog ([TRAJ] JERK_PLAN = path)-->
 *             RUNNING: the setpoints are the planned queue's (no record is
 *             taken; src/ctl/follow.c): hold, stop, exit, a fault, an
 *             E-stop without drives as its braking run, END at its last
 *             entry at rest, the override on its cap
 *
 * With CiA 402 drives (opts.drives) the controller also decides their power
 * (mlip_drive_power, mlip/ipc/ring.h), sent as the RPDOs' controlword and
 * confirmed by each drive's TPDO statusword (in->drives.sw), each step within
 * opts.drive_state_periods:
 *   ENABLED --at rest, IDLE after a program or a stop, FAULT, or exiting-->
 *     DISABLING (0x07) --all "switched on"--> SHUTTING_DOWN (0x06) --all
 *     "ready to switch on"--> OFF            (a timeout: reported, goes on)
 *   OFF --a program's records in the ring--> SWITCHING_ON (0x07) --all
 *     "switched on"--> ENABLING (0x0F) --all "operation enabled"--> ENABLED
 *     (a timeout: FAULT, reason DRIVE: not switched on / not enabled, node,
 *     statusword; the drives are shut down again and nothing moves)
 *   after an E-stop's reset: from what every drive's statusword shows,
 *     VOLTAGE_OFF (0x00) --all "switch on disabled"--> SHUTTING_DOWN (0x06)
 *     --all "ready to switch on"--> OFF; a program arriving meanwhile waits
 *     (toward power a step not confirmed: FAULT, DRIVE, POWER_STEP, value
 *     step * 65536 + statusword)
 * Records are taken (IDLE -> PREREAD) only with the drives ENABLED, so the
 * planner never moves otherwise; pause, dwell, hold and starved keep them
 * enabled, holding position. From OFF to ENABLING the commanded position
 * follows in->drives.pos_actual (a disabled axis may be moved by hand or gravity)
 * and must be inside the soft limits (else FAULT, BEYOND_LIMIT); ENABLING
 * sends it unchanged, so the target equals the position actual to the count
 * and the program starts there.
 *
 * Records are validated where they are taken, at bounded cost: the next
 * sequence number, a known type and flags, then the rule set of every block
 * (mlip_block_check, mlip/types.h, which the G-code reader keeps too):
 * targets inside the soft limits, a feed in MLIP_FEED_MIN_MM_S ..
 * MLIP_FEED_MAX_MM_S (a rapid's 0 ..), a tolerance in 0 .. MLIP_TOL_MAX_MM,
 * a dwell in 0 .. MLIP_DWELL_MAX_S.
 */
#ifndef MLIP_CONTROLLER_H
#define MLIP_CONTROLLER_H

#include <stdint.h>

#include "mlip/can/canenc.h"
#include "mlip/canopen/cia402.h"
#include "mlip/ctl/spindlectl.h"
#include "mlip/ctl/state.h"
#include "mlip/machine/config.h"
#include "mlip/motion/planner.h"
#include "mlip/motion/planq.h"
#include "mlip/ipc/ring.h"
#include "mlip/types.h"

/* records a period while not moving: what the look-ahead's queue has room
 * for (a record checked costs about 500 instructions; the pre-read's first
 * period once took 512); a dropped program's records (not checked), more */
#define MLIP_PREREAD_PER_PERIOD    MLIP_INPUT_CAP
#define MLIP_DROP_PER_PERIOD       512
#define MLIP_BUS_CLEAN_PERIODS     100 /* after a CAN fault, resume needs a clean bus this long */
#define MLIP_STALL_PERIODS_DEFAULT 3   /* more missed periods than this: a stall */
#define MLIP_CTL_MAX_EVENTS        8   /* events one period can report */
#define MLIP_SYNC_OUT_MAX          16  /* M62/M63 waiting for their move */

typedef enum {
	MLIP_EV_STATE = 1, /* a transition: from -> state, with its reason */
	MLIP_EV_REFUSED,   /* records that do not continue the program dropped
	                      (seq: the first one; value: the block expected) */
	MLIP_EV_POWER      /* the drives' power: from -> state (mlip_drive_power);
	                      r.value: periods the step left took, r.seq: periods
	                      since its sequence (disable or enable) began; r.node:
	                      0, or the first drive that did not confirm the step
	                      in time, r.field: its statusword */
} mlip_ctl_event_kind;

/* Why a state is what it is (kept in the status, carried by events). */
struct mlip_ctl_reason {
	uint32_t why;   /* mlip_state_why */
	uint32_t field; /* mlip_rec_field; DRIVE: the event (mlip_drive_fault) */
	uint32_t node;  /* DRIVE: the drive's CANopen node id */
	uint64_t seq;   /* record concerned (0: none) */
	uint32_t line;
	double value;
};

struct mlip_ctl_event {
	uint32_t kind;  /* mlip_ctl_event_kind */
	uint32_t from;  /* state left (STATE) */
	uint32_t state; /* state entered, or the current one */
	struct mlip_ctl_reason r;
	uint64_t period;
	uint64_t exec_seq; /* the record executing (or last completed) then */
	uint32_t exec_line;
};

/* A CiA 402 drive's fault, as rt/drives.c's supervision (mlip/canopen/drive.h,
 * mlip_drive_supervise) found it this period. */
struct mlip_ctl_drive_fault {
	uint32_t event; /* mlip_drive_fault: statusword fault bit, EMCY, heartbeat lost,
	                   left NMT operational, left operation enabled, following
	                   error, TPDOs lost or late; 0 (MLIP_DRIVE_OK): none */
	uint32_t node;  /* CANopen node id */
	double value;   /* statusword, EMCY code, ms without heartbeat, counts, periods */
};

/* The bus as of the last send. */
struct mlip_ctl_bus {
	uint64_t tx_refused; /* frames the tx queue refused (cumulative: a change holds) */
	int off;             /* the last error frame said bus-off */
};

/* What the CANopen master (rt/drives.c) saw of the drives this period. */
struct mlip_ctl_drives {
	uint32_t mute;                     /* bit k: no RPDO for axis k (its drive faulted) */
	uint16_t sw[MLIP_MAX_AXES];        /* statusword 0x6041 of drive k's last TPDO (0: none) */
	struct mlip_ctl_drive_fault fault; /* the first new fault, if any */
	uint32_t actual_mask;              /* bit k: pos_actual[k] is from drive k's TPDO */
	uint64_t tpdo_period[MLIP_MAX_AXES]; /* the period whose SYNC drive k's last TPDO
	                                        answers (UINT64_MAX: none yet) */
	double pos_actual[MLIP_MAX_AXES];    /* position actual 0x6064, joint units */
	/* the touch probe ([PROBE] SOURCE = drive): 0x60B9 of drive k's last
	 * TPDO1 (answering tpdo_period[k]), the positions latched at touch probe
	 * 1's positive / negative edge 0x60BA / 0x60BB (joint units) of its last
	 * TPDO2, and the period whose SYNC that TPDO2 answers (UINT64_MAX: none) */
	uint16_t tp_status[MLIP_MAX_AXES];
	uint64_t tp_latch_period[MLIP_MAX_AXES];
	double tp_pos[MLIP_MAX_AXES];
	double tp_neg[MLIP_MAX_AXES];
};

/* The inputs on the bus (issue 18): rt/drives.c reads the I/O module and the
 * drives, mlip_io_eval (mlip/canopen/io401.h) maps them to functions. */
struct mlip_ctl_io {
	uint32_t active;                  /* bit f: function f (MLIP_IN_*) is on */
	uint32_t known;                   /* bit f: its input has been read (else off) */
	struct mlip_ctl_drive_fault lost; /* the I/O module failed (event: heartbeat lost,
	                                     EMCY, left NMT operational; node; detail): an
	                                     E-stop; 0: fine */
};

/* An SDO transfer the controller asks the CANopen master for (homing):
 * rt/drives.c runs it over the next periods without waiting and reports its
 * end in in->sdo. One at a time; seq 0: none. */
struct mlip_ctl_sdo_req {
	uint32_t seq; /* a new request when it changes */
	uint8_t node;
	uint8_t sub;
	uint8_t size;   /* download: 1, 2 or 4 bytes */
	uint8_t upload; /* 1: read */
	uint16_t index;
	uint32_t value; /* download */
};

struct mlip_ctl_sdo_res {
	uint32_t seq;   /* the request it ends (0: none yet) */
	uint32_t abort; /* 0: done; else the abort code (the drive's, or mlip's timeout) */
	uint32_t value; /* upload: the value read */
};

/* The spindle drive's TPDO as of this period (opts.spindle; rt/drives.c).
 * Its bus faults (heartbeat, EMCY, NMT) come in drives.fault with its node. */
struct mlip_ctl_spindle_in {
	uint16_t sw;        /* statusword 0x6041 (0: none yet) */
	int32_t vel_counts; /* velocity actual 0x606C, counts/s */
	int mute;           /* it faulted: it is sent nothing */
};

/* What the spindle drive is sent after this period's frames (an RPDO:
 * controlword 0x6040, target velocity 0x60FF). */
struct mlip_ctl_spindle_out {
	int send;          /* 1: send it (a spindle on the bus, not muted) */
	uint16_t cw;       /* the axes' power sequencer's controlword (quick stop in an E-stop) */
	int32_t target;    /* counts/s */
	double rpm_actual; /* for the log */
};

struct mlip_ctl_in {
	uint64_t period;                    /* 0, 1, 2, ... one per call */
	uint32_t missed;                    /* deadlines the loop missed before this period */
	int unsent;                         /* the last period's frames never went out: a stall
	                                       between its work and its send (the drives stand
	                                       at the setpoint before) */
	struct mlip_rec_view recs;          /* the records it may take, oldest first (copied
	                                       before they are checked; out->taken: popped) */
	uint32_t recs_corrupt;              /* the queue's indices are this far apart, more than
	                                       its capacity (a corrupted segment); 0: fine */
	const struct mlip_ring_cmd *cmd;    /* this period's command; NULL: none */
	uint32_t stop_requests;             /* the stop counter (mlip_ring_stop_count): each
	                                       change is a stop (never lost behind a command) */
	uint32_t feeder_stop_base;          /* the feeder's stop_base: a program whose feeder
	                                       began before a stop seen never starts */
	int feeder_unread;                  /* the feeder area was mid-update: whose program it
	                                       is is not known, none starts this period */
	int feeder_alive;                   /* a feeder is attached and beating */
	int feeder_mdi;                     /* the feeder's program is MDI lines (mlip-ctl mdi):
	                                       its end leaves the outputs as they are */
	int exit_request;                   /* stop on the path, then report done */
	struct mlip_ctl_bus bus;            /* as of the last send */
	struct mlip_ctl_drives drives;      /* CiA 402 drives (opts.drives) */
	struct mlip_ctl_io io;              /* the inputs on the bus (opts.io) */
	struct mlip_ctl_sdo_res sdo;        /* the last SDO transfer done (out->sdo) */
	struct mlip_ctl_spindle_in spindle; /* opts.spindle */
	/* [TRAJ] JERK_PLAN = path (issue 21): the planned queue of the program
	 * the planning thread runs (NULL: none; mlip/motion/planq.h), and its
	 * number (a new one starts a program once, at rest in IDLE): while it
	 * runs the setpoints are the queue's (src/ctl/follow.c), no record is
	 * taken from recs */
	struct mlip_planq *plan;
	uint32_t plan_prog;
	uint32_t plan_fault; /* the programs the planning thread refused so far: a
	                        new count is FAULT (reason PLAN_REFUSED), once; a
	                        queue running brakes on its run */
};

/* The drives' power after the period (opts.drives; the sequencer's record). */
struct mlip_ctl_power {
	uint32_t state;     /* mlip_drive_power, as status.drive_power */
	int ok;             /* the last disable: every step confirmed in time */
	uint32_t late_node; /* the last step not confirmed in time: the drive (0: none), */
	uint16_t late_sw;   /* its statusword then, */
	uint32_t late_step; /* and the step (mlip_drive_power) */
};

/* Since init. */
struct mlip_ctl_counts {
	uint64_t blocks_consumed; /* records taken */
	uint64_t underruns;       /* periods that needed a record and found none */
	uint64_t refused;         /* programs dropped that did not continue the last */
	uint64_t frames_encoded;  /* CAN frames put in out->frames */
};

struct mlip_ctl_out {
	uint32_t taken;            /* records taken from the front of in->recs: pop them */
	double pos[MLIP_MAX_AXES]; /* the setpoint of this period */
	struct mlip_can_frame frames[MLIP_CAN_MAX_FRAMES];
	int n_frames;                   /* 0: nothing to send (no encoder, or a fault); late:
	                                   withheld, in->unsent next period */
	int32_t cmd_result;             /* mlip_status for in->cmd */
	struct mlip_ring_status status; /* all but heartbeat_ns, pid, CAN counters */
	struct mlip_ctl_event events[MLIP_CTL_MAX_EVENTS];
	uint32_t n_events;
	struct mlip_ctl_power power;
	struct mlip_ctl_counts counts;
	int done; /* an exit request has completed: at rest */
	/* the I/O module's outputs 0x6200:1..8 (mlip_ctl_set_output; all 0 in an
	 * E-stop): rt/drives.c sends them in its RPDO when they change */
	uint8_t outputs[MLIP_IO_IN_BYTES];
	struct mlip_ctl_sdo_req sdo;         /* an SDO transfer to run (homing) */
	uint32_t homing;                     /* bit k: drive k runs its homing mode: its following
	                                        error is its own business, not supervised */
	struct mlip_ctl_spindle_out spindle; /* opts.spindle */
};

struct mlip_ctl_opts {
	mlip_strategy strategy;
	struct mlip_smooth_store *smooth;  /* the smooth strategy's planner data (required with
	                                      it, NULL otherwise: mlip_planner_init) */
	uint32_t lookahead;                /* 0: MLIP_LOOKAHEAD */
	uint32_t stall_periods;            /* 0: MLIP_STALL_PERIODS_DEFAULT */
	const struct mlip_can_config *can; /* NULL: no frames */
	int drives;                        /* CiA 402 drives brought up (and enabled): 6-byte RPDOs
	                                      with the controlword of the drives' power, none to
	                                      in->drives.mute */
	uint32_t drive_state_periods;      /* a power step not confirmed this long: a timeout
	                                      (0: 1000) */
	const struct mlip_io_config *io;   /* the inputs' functions (NULL: none mapped) */
	const struct mlip_home_config *home;       /* homing (NULL: none configured) */
	const struct mlip_spindle_config *spindle; /* a CiA 402 spindle on the bus (with drives;
	                                              NULL: none) */
};

/* A record's place in the program: its seq (0: none) and source line. */
struct mlip_ctl_mark {
	uint64_t seq;
	uint32_t line;
};

/* The last G38's result, LinuxCNC's #5061..#5069 and #5070 (issue 19). */
struct mlip_ctl_probe_result {
	uint32_t count;   /* probe moves completed since init (0: none yet) */
	uint32_t tripped; /* #5070: 1 the probe tripped, 0 it did not (G38.3/.5) */
	uint64_t seq;     /* the G38's record, and its line */
	uint32_t line;
	double pos[MLIP_MAX_AXES]; /* #5061..: where the probe tripped (machine
	                              coordinates): [PROBE] SOURCE = drive: the
	                              position each drive latched at the edge; io:
	                              the position in the period its input frame
	                              arrived, the drives' positions actual when
	                              they report them (else the setpoint); the
	                              target when it did not trip */
	uint32_t latched;          /* bit k: pos[k] is drive k's touch probe latch */
};

/* The controller's own state: read it through out, never here. */
struct mlip_ctl {
	/* set at init */
	struct mlip_planner *planner;
	struct mlip_machine m;
	struct mlip_canenc enc; /* the period's frames, when encode (opts.can) */
	int encode;
	int drives; /* opts.drives */
	uint32_t stall_periods;
	mlip_strategy strategy; /* opts.strategy: a program's unless its records say
	                           mpct (MLIP_REC_MPCT, on a smooth controller) */
	/* the state and why */
	uint32_t state; /* mlip_ctl_state */
	struct mlip_ctl_reason why;
	int drive_faulted; /* a drive fault came: it stays the reason */
	/* what holds the planner, each cause until its own release */
	struct {
		int op;                  /* mlip-ctl hold: until resume (or a stop) */
		int stall;               /* more periods missed than allowed: until resume */
		int bus;                 /* frames refused, bus-off: until resume on a clean bus */
		uint32_t bus_why;        /* BUS_TX or BUS_ERROR */
		uint64_t bus_bad_period; /* the last period the bus was bad */
		uint64_t tx_seen;        /* in->bus.tx_refused as last seen */
		int spindle;             /* a resume waits for the restored spindle at speed */
	} hold;
	/* the operator */
	struct {
		uint32_t stop_seen; /* the stop counter applied (in->stop_requests) */
		int exiting;        /* an exit request: a stop on the path, then done */
		int optional_stop;  /* the M1 switch */
	} op;
	/* the program */
	struct {
		uint64_t next_seq;           /* the record expected next */
		struct mlip_ctl_mark exec;   /* the last record whose motion (or wait) is done */
		struct mlip_ctl_mark end;    /* its END, once taken (seq 0: not yet) */
		int refill;                  /* the pre-read continues a program */
		int bad;                     /* a bad record: nothing more is taken */
		int discard;                 /* dropping a stopped (or faulted) program's records */
		int discard_waiting;         /* ... a waiting one's, its first record (seq 1) too */
		int mdi;                     /* it is MDI lines (in->feeder_mdi at its start) */
		int mpct;                    /* its records carry MLIP_REC_MPCT (its first
		                                record's, at its start): mpct's corners */
		double start[MLIP_MAX_AXES]; /* pos when its first record was taken */
	} prog;
	/* a dwell or a pause */
	struct {
		struct mlip_ring_rec event; /* the event record ingest stopped in front of */
		struct mlip_ctl_mark at;    /* the dwell or pause being executed */
		uint64_t dwell_left;        /* periods */
		int resume;                 /* resume came during a pause */
		int stopped;                /* a stop came in it: the wait is not done */
	} wait;
	/* the planned queue followed (in->plan; src/ctl/follow.c) */
	struct {
		struct mlip_planq *q; /* the program's, while it runs (NULL: none) */
		uint32_t prog, last;  /* its number, the last one started */
		double vmax;          /* its plan's cap at override 100 */
		int stopping;         /* a stop (or fault): the braking run, then dropped */
		uint32_t refused;     /* in->plan_fault as last applied */
	} ext;
	/* the drives' power (opts.drives) */
	struct {
		struct mlip_402_seq seq; /* on the period count */
		int want;                /* this period: a program waits for the drives */
		uint32_t still_periods;  /* periods the setpoint has not changed */
	} power;
	/* this period's records (in->recs) */
	struct {
		const struct mlip_rec_view *view;
		uint32_t taken;
		uint32_t corrupt; /* the queue's indices were this far apart: nothing more is
		                     read from it (0: never) */
	} rx;
	/* a stop measured from its request to rest (status stop_*) */
	struct {
		int on;
		double mm;
		uint32_t periods;
		uint64_t last_nm; /* the last stop completed */
		uint32_t last_periods, count;
	} brake;
	uint64_t period, overruns;
	struct mlip_ctl_counts counts;
	double pos[MLIP_MAX_AXES];
	double carried[MLIP_MAX_AXES]; /* the setpoint the last period's frames carried */
	double sent[MLIP_MAX_AXES];    /* the last setpoint that went out */
	/* the inputs on the bus and the E-stop (issue 18) */
	struct {
		struct mlip_io_config cfg;      /* what is mapped where */
		uint32_t prev;                  /* the functions on in the last period (edges) */
		uint32_t limit_ignore;          /* limit inputs a jog away from them left on: they
		                                   do not trip until released */
		int estop;                      /* in an E-stop: quick stop until a reset */
		uint32_t rest;                  /* E-stop: fresh TPDOs in a row of every drive at
		                                   rest (a reset leaves the quick stop only then) */
		double rest_pos[MLIP_MAX_AXES]; /* each drive's last position judged */
		uint64_t rest_tpdo[MLIP_MAX_AXES]; /* and its TPDO (tpdo_period) */
		int fault_kept;              /* a drive fault came before (or in) it: it stays */
		struct mlip_ctl_reason kept; /* that fault's reason */
		uint8_t outputs[MLIP_IO_IN_BYTES];
	} io;
	/* a jog (MLIP_CMD_JOG, MLIP_CMD_JOG_AXIS): continuous or incremental,
	 * one axis or several along one line */
	struct {
		int on;                     /* jogging (or waiting for the drives to be enabled) */
		int moving;                 /* its block is in the planner */
		int stopping;               /* released or not renewed: braking on the path */
		uint32_t axis;              /* the axis of its MLIP_CMD_JOG (renewals name it) */
		int neg;                    /* toward MIN_LIMIT */
		uint32_t axes;              /* bit k: axis k moves */
		uint32_t negs;              /* bit k: axis k toward MIN_LIMIT */
		double dist[MLIP_MAX_AXES]; /* incremental: the distances; all 0: continuous */
		/* MLIP_CMD_JOG_AXIS posted for the next jog */
		uint32_t pend_axes, pend_negs;
		double pend_dist[MLIP_MAX_AXES];
		uint64_t pend_at; /* the period of the last one */
		double speed;     /* mm/s or deg/s */
		uint64_t renewed; /* the period of its last command */
		uint64_t deadman; /* periods without a renewal that stop it */
		uint32_t end_why; /* the reason it stopped (mlip_state_why) */
	} jog;
	/* homing with the drives' homing mode (MLIP_CMD_HOME) */
	struct {
		struct mlip_home_config cfg;
		uint32_t configured; /* bit k: axis k has a HOME_METHOD */
		uint32_t homed;      /* bit k: axis k is homed */
		int on;              /* homing (or restoring CSP after a failure) */
		int failed;          /* the group failed: CSP restored, then FAULT stays */
		uint32_t todo;       /* axes still to home */
		uint32_t group;      /* the axes homing now (one HOME_SEQUENCE) */
		uint32_t attained;   /* of those: homing attained */
		int step;            /* the sequencer's step (homing.c) */
		int axis;            /* the axis whose objects are being written */
		int entry;           /* its object */
		int readback;        /* 1: the object's read back is outstanding */
		uint32_t sdo_seq;    /* the SDO request outstanding (0: none) */
		uint32_t requests;   /* SDO requests so far (each a new seq) */
		uint32_t stop_why;   /* a stop during homing: its reason, once CSP is back */
		struct mlip_ctl_sdo_req req;
		uint64_t t0; /* the group's homing move began (period) */
		uint16_t cw; /* the group's controlword */
	} home;
	/* the machine's outputs and probing (issue 19; src/ctl/machio.c) */
	struct {
		uint32_t coolant; /* MLIP_COOLANT_* on ([COOLANT] TYPE = io) */
		uint32_t active;  /* this period's input functions on (in->io.active) */
		uint32_t known;   /* ... and read (in->io.known) */
		int probe_on;     /* a G38 move is executing */
		int probe_tripped;
		uint32_t probe_flags;         /* MLIP_PROBE_* */
		struct mlip_ctl_mark probe;   /* its record */
		double actual[MLIP_MAX_AXES]; /* this period's positions actual (drives) */
		uint32_t actual_mask;
		struct mlip_ctl_probe_result result; /* the last probe's */
		/* the drives' touch probe ([PROBE] SOURCE = drive) */
		int tp_phase;               /* MLIP_TP_PHASE_* (machio.c) */
		uint16_t tp_fn;             /* 0x60B8 sent to every axis drive */
		uint64_t tp_t0;             /* the period the phase began */
		struct mlip_block tp_block; /* the G38's move, pushed once armed */
		/* M62/M63 waiting for the next move (issue 19): its record's seq,
		 * the OUTPUT value */
		uint32_t n_sync;
		uint64_t sync_after[MLIP_SYNC_OUT_MAX];
		double sync_value[MLIP_SYNC_OUT_MAX];
	} mio;
	/* a CiA 402 spindle (issue 19, mlip/ctl/spindlectl.h) */
	struct mlip_ctl_spindle spindle;
	/* scratch for one period's blocks (no stack array of this size on RT) */
	struct mlip_block blocks[MLIP_PREREAD_PER_PERIOD];
};

/* At rest at the machine's HOME, state IDLE. The machine is copied;
 * MLIP_E_INVALID for a machine, look-ahead or [CAN] settings that do not fit. */
mlip_status mlip_ctl_init(struct mlip_ctl *c, struct mlip_planner *p, const struct mlip_machine *m,
                          const struct mlip_ctl_opts *o);

/* One period. */
void mlip_ctl_period(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out);

/* Set (on != 0) or clear bit `bit` (0..7) of the I/O module's output byte
 * 0x6200:sub (1..8), sent from the next period on (out->outputs). In an
 * E-stop every output is off and this does nothing. MLIP_E_RANGE for a sub or
 * bit out of range. For the controller's own use (M7/M8/M9, M64/M65). */
mlip_status mlip_ctl_set_output(struct mlip_ctl *c, uint32_t sub, uint32_t bit, int on);

/* Check one record as the controller does before taking it: MLIP_OK, or
 * MLIP_E_RANGE with *why (BAD_RECORD, field, seq, line, value). expect_seq 0:
 * the sequence number is not checked. */
mlip_status mlip_ctl_check_record(const struct mlip_machine *m, const struct mlip_ring_rec *rec,
                                  uint64_t expect_seq, struct mlip_ctl_reason *why);

#endif
