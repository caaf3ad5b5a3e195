/*
 * mlip/ctl/state.h - the controller's state and the reason it is in it, as the
 * status in the segment publishes them (status.state, status.reason) and the
 * controller's events carry them. The values are wire values: shared memory
 * read by mlip-ctl, mlip-feed and the Python tools; a new one is appended.
 */
#ifndef MLIP_CTL_STATE_H
#define MLIP_CTL_STATE_H

#include <stdint.h>

/* The controller's state (status.state). Values 0..5 keep their numbers of
 * layout version 2. */
typedef enum {
	MLIP_STATE_IDLE = 0, /* no program running, ring may be empty */
	MLIP_STATE_RUNNING,  /* moving (or about to), taking records as it goes */
	MLIP_STATE_HELD,     /* feed hold, override 0, a CAN fault or a stall:
	                        decelerated (or frozen) to rest on the path; resume */
	MLIP_STATE_STOPPING, /* stop requested: decelerating, ring being flushed */
	MLIP_STATE_FAULT,    /* stopped on an error that needs a restart of mlip-rt:
	                        a bad record (at rest at the end of the last good
	                        block), a corrupt segment, a position the drives
	                        cannot represent; status.reason says which */
	MLIP_STATE_STARVED,  /* the program's blocks ran out before its END: at rest
	                        at the end of the last block received (underrun);
	                        continues when blocks come (mlip-feed --start-seq) */
	MLIP_STATE_PAUSED,   /* M0/M60 (or M1 with optional stop on), or the
	                        operator's part of a manual spindle, tool change or
	                        coolant (reason SPINDLE, TOOL, COOLANT): at rest;
	                        mlip-ctl resume continues */
	MLIP_STATE_DWELLING, /* G4: at rest for the dwell's periods */
	MLIP_STATE_PREREAD,  /* taking a program's records before moving */
	MLIP_STATE_ESTOP,    /* E-stop (issue 18): an E-stop input, or the I/O module lost
	                        (heartbeat, fault): quick stop to every drive in that period,
	                        the program dropped; left only by a reset (mlip-ctl reset)
	                        once the input is released; wins over every other state */
	MLIP_STATE_JOGGING,  /* a jog (mlip-ctl jog): one axis or several along one line,
	                        toward the soft limit or a distance, at the jog's speed
	                        through the planner, while renewed */
	MLIP_STATE_HOMING,   /* homing with the drives' homing mode (mlip-ctl home) */
	MLIP_STATE_COUNT
} mlip_ctl_state;

/* Why the controller is in its state (status.reason): the cause of the last
 * transition. */
typedef enum {
	MLIP_WHY_NONE = 0,
	MLIP_WHY_START,         /* a program's first record (seq 1) */
	MLIP_WHY_CONTINUE,      /* the record after the last completed (--start-seq) */
	MLIP_WHY_PREREAD_DONE,  /* look-ahead full, END in, or an event next */
	MLIP_WHY_END,           /* the program's END executed, at rest */
	MLIP_WHY_UNDERRUN,      /* the ring ran dry before END */
	MLIP_WHY_FEEDER_GONE,   /* the feeder's heartbeat stopped (or none attached) */
	MLIP_WHY_HOLD,          /* mlip-ctl hold */
	MLIP_WHY_OVERRIDE_ZERO, /* feed override 0 */
	MLIP_WHY_RESUME,        /* mlip-ctl resume */
	MLIP_WHY_BUS_TX,        /* CAN frames refused by the tx queue */
	MLIP_WHY_BUS_ERROR,     /* CAN error frames or bus-off */
	MLIP_WHY_STALL,         /* the loop missed more periods than allowed (value) */
	MLIP_WHY_DWELL,         /* G4 record (value: seconds) */
	MLIP_WHY_DWELL_DONE,
	MLIP_WHY_PAUSE,          /* M0/M60 record */
	MLIP_WHY_OPTIONAL_PAUSE, /* M1 record with optional stop on */
	MLIP_WHY_STOP,           /* mlip-ctl stop */
	MLIP_WHY_EXIT,           /* SIGINT/SIGTERM/SIGHUP to mlip-rt */
	MLIP_WHY_BAD_RECORD,     /* reason_seq, reason_field, reason_value */
	MLIP_WHY_RING_CORRUPT,   /* head - tail beyond the capacity (value: count) */
	MLIP_WHY_POSITION_RANGE, /* a setpoint beyond the drives' int32 counts */
	MLIP_WHY_DRIVE,          /* a CiA 402 drive faulted (mlip-rt --drives): reason_node,
	                            reason_field the event (mlip_drive_fault, mlip/canopen/drive.h),
	                            reason_value its detail (statusword, EMCY code, ...) */
	MLIP_WHY_STOP_EARLY,     /* a stop came after the feeder began, before its program
	                            started: the program is dropped unmoved (reason_seq, line:
	                            its first record) */
	MLIP_WHY_SPINDLE,        /* a manual spindle: start it (reason_value rpm, > 0
	                            clockwise, < 0 counter-clockwise) or stop it (0), resume */
	MLIP_WHY_TOOL,           /* a manual tool change: insert tool reason_value, resume */
	MLIP_WHY_COOLANT,        /* manual coolant: switch it to reason_value (MLIP_COOLANT_*) */
	MLIP_WHY_ESTOP,          /* an E-stop input (reason_field: the function MLIP_IN_ESTOP,
	                            reason_node: its node, reason_value: the object's index) */
	MLIP_WHY_IO_LOST,        /* the I/O module failed: reason_node, reason_field the event
	                            (mlip_drive_fault: heartbeat lost, EMCY, not operational),
	                            reason_value its detail */
	MLIP_WHY_LIMIT,          /* a limit input while moving: state FAULT, reason_field the
	                            function (MLIP_IN_LIMIT_NEG/POS(k): axis and direction),
	                            reason_node its node */
	MLIP_WHY_RESET,          /* mlip-ctl reset after an E-stop or a limit */
	MLIP_WHY_JOG,            /* a jog started (reason_field: MLIP_JOG_FIELD, mlip/ipc/
	                            ring.h: its axes and directions; reason_value: the
	                            speed, mm/s or deg/s, negative toward MIN_LIMIT) */
	MLIP_WHY_JOG_RELEASED,   /* its client stopped it: at rest at the acceleration limit */
	MLIP_WHY_JOG_DEADMAN,    /* its client stopped renewing it (MLIP_JOG_DEADMAN_S) */
	MLIP_WHY_JOG_END,        /* at rest at the soft limit it was heading to */
	MLIP_WHY_HOMING,         /* homing started (reason_field: the axes, a mask) */
	MLIP_WHY_HOMED,          /* every axis asked for is homed, back in CSP */
	MLIP_WHY_HOMING_ERROR,   /* a drive reported homing error (statusword bit 13):
	                            reason_node, reason_field its method, reason_value the
	                            statusword; state FAULT, quick stop */
	MLIP_WHY_HOMING_TIMEOUT, /* homing not attained within HOME_TIMEOUT: reason_node,
	                            reason_field its method, reason_value the statusword */
	MLIP_WHY_HOMING_SDO,     /* the drive refused a homing object: reason_node,
	                            reason_field index << 8 | sub, reason_value the abort
	                            code (or the value read back when it differs) */
	MLIP_WHY_NOT_HOMED,      /* HOMING_REQUIRED: a program refused before every axis
	                            is homed (reason_seq, line: its first record) */
	MLIP_WHY_JOG_DONE,       /* an incremental jog at rest at its target */
	/* the machine's outputs and probing (issue 19) */
	MLIP_WHY_OUTPUT, /* M7/M8/M9 ([COOLANT] TYPE = io) or M64/M65 switched the
	                    I/O module's outputs at rest (reason_field: the record
	                    type, reason_value its value) */
	MLIP_WHY_PROBE,  /* a G38 move started (reason_value: MLIP_PROBE_* bits) */
	MLIP_WHY_PROBED, /* it ended at rest (reason_value 1: the probe tripped,
	                    0: G38.3/G38.5 reached the target without a trip) */
	/* a probe error stops the program at rest (IDLE, the rest dropped): */
	MLIP_WHY_PROBE_NO_TRIP,      /* G38.2/G38.4 reached its target without a trip */
	MLIP_WHY_PROBE_AT_START,     /* the probe was already tripped (G38.2/.3) when the
	                                move was to start (G38.4/.5: PROBE_OFF_AT_START) */
	MLIP_WHY_PROBE_INPUT,        /* a G38 with no probe input mapped or read, or the drives'
	                                touch probe not switched on/off in time (reason_node:
	                                the drive, reason_value: its 0x60B9) */
	MLIP_WHY_SPINDLE_WAIT,       /* a CiA 402 spindle's M3/M4/S/M5: at rest (state DWELLING)
	                                until it is at speed, or at standstill (reason_value:
	                                the rpm asked) */
	MLIP_WHY_SPINDLE_FAULT,      /* the spindle drive: state FAULT, the feed stopped on the
	                                path; reason_node its node, reason_field the event
	                                (mlip_drive_fault: fault bit, EMCY, heartbeat lost, ...,
	                                SPINDLE_TIMEOUT, SPINDLE_OUT_OF_BAND), reason_value
	                                its detail (statusword, code, ms, actual rpm) */
	MLIP_WHY_PROBE_OFF_AT_START, /* G38.4/.5 (away): the probe was not in contact
	                                when the move was to start (a probe error
	                                as PROBE_AT_START; last, so the numbers of
	                                the reasons before it stay) */
	MLIP_WHY_PLAN_REFUSED,       /* [TRAJ] JERK_PLAN = path: the planning thread refused
	                                the program (a piece its plan cannot certify, or its
	                                controller left RUNNING): state FAULT, the queue's
	                                braking run to rest */
	MLIP_WHY_COUNT
} mlip_state_why;

/* "idle", "running", ...; "program end", "stall", ...; "?" out of range.
 * Never NULL. */
const char *mlip_ctl_state_name(uint32_t state);
const char *mlip_state_why_name(uint32_t why);

/* The status' held_by (mlip/ipc/ring.h) as a reader trusts it: the cause
 * when it is one that holds the path (hold, stall, CAN tx refused, CAN
 * error frames, the spindle coming to speed, feed override 0), else 0
 * (none, or a value no controller of this layout writes; a reader built
 * before override 0 was written there reads it as none). */
uint32_t mlip_state_held_by(uint32_t held_by);
/* A hold latched at rest: idle or starved with a hold in force (held_by,
 * as above) that a resume ends: not the spindle's wait, not override 0 (a
 * higher override ends it); the next records start held until a resume
 * (Grbl 1.1's Hold:0 from Idle). */
int mlip_state_hold_latched(uint32_t state, uint32_t held_by);

#endif
