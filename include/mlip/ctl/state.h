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
	MLIP_STATE_PAUSED,   /* M0/M60 (or M1 with optional stop on): at rest;
	                        mlip-ctl resume continues */
	MLIP_STATE_DWELLING, /* G4: at rest for the dwell's periods */
	MLIP_STATE_PREREAD,  /* taking a program's records before moving */
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
	MLIP_WHY_COUNT
} mlip_state_why;

/* "idle", "running", ...; "program end", "stall", ...; "?" out of range.
 * Never NULL. */
const char *mlip_ctl_state_name(uint32_t state);
const char *mlip_state_why_name(uint32_t why);

#endif
