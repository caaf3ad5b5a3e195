/*
 * mlip/canopen/drive.h - a CiA 402 drive as mlip runs it, in cyclic synchronous
 * position mode: the objects written to it at bring-up (PDO mapping, SYNC,
 * mode, interpolation period, following window, heartbeats) and its
 * supervision in the loop (statusword, EMCY, heartbeat, NMT state, following
 * error, TPDOs). Pure: rt/drives.c feeds what the bus said and the time.
 */
#ifndef MLIP_DRIVE_H
#define MLIP_DRIVE_H

#include <stdint.h>

#include "mlip/canopen/canopen.h"
#include "mlip/canopen/cia402.h"
#include "mlip/types.h"

/* ---- the objects mlip writes to a drive ------------------------------------------ */

struct mlip_drive_setup {
	uint8_t node;
	uint32_t sync_id;                 /* 0x1005 */
	uint32_t rpdo_cob;                /* RPDO1 COB-ID, 0x1400:01 */
	uint32_t tpdo_cob;                /* TPDO1 COB-ID, 0x1800:01 */
	double period_s;                  /* 0x60C2 */
	uint32_t following_window_counts; /* 0x6065 */
	uint16_t heartbeat_ms;            /* 0x1017, the drive's producer time */
	uint8_t master_node;              /* 0x1016:01: the drive watches the master's heartbeat */
	uint16_t master_timeout_ms;
	/* a spindle (issue 19): profile velocity mode (3) instead of CSP: the
	 * RPDO carries target velocity 0x60FF, the TPDO velocity actual 0x606C,
	 * 0x6083/0x6084 its ramp, 0x60FF = 0 before it is enabled; no 0x60C2,
	 * no 0x6065 */
	int velocity;
	uint32_t accel_counts_s2; /* 0x6083 profile acceleration = 0x6084 deceleration */
	/* the touch probe ([PROBE] SOURCE = drive, issue 19): RPDO1 also carries
	 * the touch probe function 0x60B8, TPDO1 the touch probe status 0x60B9,
	 * TPDO2 (synchronous, every SYNC) the positions latched at touch probe
	 * 1's positive and negative edges 0x60BA, 0x60BB; 0x60B8 = 0 (off) */
	int touch_probe;
	uint32_t tpdo2_cob; /* TPDO2 COB-ID, 0x1801:01 */
	/* an axis: 0x6085 quick stop deceleration (counts/s^2, the axis'
	 * MAX_ACCELERATION): an E-stop or a limit brakes each axis within its
	 * acceleration limit on the drive's own ramp, with 0x605A quick stop
	 * option code MLIP_DRIVE_QUICK_STOP_OPTION; 0: neither written */
	uint32_t quick_stop_counts_s2;
	/* the drive's digital inputs 0x60FD (issue 18: limit and home switches
	 * wired to the drive) in TPDO3 on change, and at least every di_event_ms
	 * (event timer 0x1802:05: a silent TPDO3 is a lost one); 0: no TPDO3.
	 * TPDO3, not TPDO2: a drive may carry the touch probe's TPDO2 as well */
	uint32_t di_tpdo_cob;
	uint16_t di_event_ms;
};

/* 0x60B8 touch probe function / 0x60B9 status, touch probe 1 (CiA 402) */
#define MLIP_TP_ENABLE     0x0001u /* function bit 0: switch touch probe 1 on; status bit 0 */
#define MLIP_TP_CONTINUOUS 0x0002u /* function bit 1: every event (0: the first only) */
#define MLIP_TP_POS_EDGE   0x0010u /* function bit 4: latch at the positive edge */
#define MLIP_TP_NEG_EDGE   0x0020u /* function bit 5: latch at the negative edge */
#define MLIP_TP_POS_STORED 0x0002u /* status bit 1: a positive edge position is stored */
#define MLIP_TP_NEG_STORED 0x0004u /* status bit 2: a negative edge position is stored */

/* 0x605A quick stop option code (CiA 402): 6 = slow down on the quick stop
 * ramp (0x6085) and stay in "quick stop active": at rest the axis is held
 * in position until the master's "disable voltage" after the reset */
#define MLIP_DRIVE_QUICK_STOP_OPTION 6

#define MLIP_DRIVE_SETUP_MAX 48

/* The interpolation time period 0x60C2 as value * 10^index s: value 1..255,
 * index -6..0, exact to 1e-9 relative. MLIP_E_RANGE when no such pair. */
mlip_status mlip_co_interp_period(double period_s, uint8_t *value, int8_t *index);

/* The set-up of one drive, in the order it is written: RPDO1 (disabled,
 * transmission type, mapping 0x6040 + 0x607A, enabled), TPDO1 (disabled,
 * synchronous every SYNC, mapping 0x6041 + 0x6064, enabled), with touch_probe
 * TPDO2 (synchronous, mapping 0x60BA + 0x60BB, enabled), with di_tpdo_cob
 * TPDO3 (disabled, type 255 on change, event timer, mapping 0x60FD,
 * enabled), SYNC COB-ID, modes of operation = CSP and its display,
 * interpolation period, following error window, quick stop deceleration
 * and option code (when set), heartbeat producer and consumer; with touch_probe also 0x60B8
 * in RPDO1, 0x60B9 in TPDO1 and 0x60B8 = 0. Returns the count, or -1
 * when cap is too small or the period cannot be written. */
int mlip_drive_setup_entries(const struct mlip_drive_setup *d, struct mlip_sdo_entry *out, int cap);

/* ---- supervision in the loop ------------------------------------------------------- */

typedef enum {
	MLIP_DRIVE_OK = 0,
	MLIP_DRIVE_FAULT_BIT,       /* statusword bit 3 (fault or fault reaction) */
	MLIP_DRIVE_EMCY,            /* an emergency with a non-zero code */
	MLIP_DRIVE_HEARTBEAT_LOST,  /* no heartbeat within the consumer time */
	MLIP_DRIVE_NOT_OPERATIONAL, /* its heartbeat says it left NMT operational */
	MLIP_DRIVE_LEFT_ENABLED,    /* statusword no longer "operation enabled" */
	MLIP_DRIVE_FOLLOWING_ERROR, /* |target sent - position actual| beyond the window */
	MLIP_DRIVE_TPDO_LOST,       /* no TPDO for tpdo_timeout periods, or the last one
	                               answers a SYNC that many periods old */
	/* re-enabling for the next program (the controller, src/ctl/controller.c) */
	MLIP_DRIVE_NOT_SWITCHED_ON, /* switch on (0x0007) not confirmed in time (statusword) */
	MLIP_DRIVE_NOT_ENABLED,     /* enable operation (0x000F) not confirmed in time */
	MLIP_DRIVE_BEYOND_LIMIT,    /* its position actual is beyond a soft limit (mm, deg) */
	/* a spindle (issue 19, mlip/ctl/spindlectl.h): value its actual rpm */
	MLIP_DRIVE_SPINDLE_TIMEOUT,     /* not at speed (or at rest) within AT_SPEED_TIMEOUT */
	MLIP_DRIVE_SPINDLE_OUT_OF_BAND, /* at speed, then out of AT_SPEED_BAND for BAND_TIME */
	MLIP_DRIVE_POWER_STEP,  /* another step toward power (shutdown, disable voltage, fault
	                           reset, waiting) not confirmed in time; value step
	                           (mlip_drive_power) * 65536 + statusword */
	MLIP_DRIVE_INPUTS_LOST, /* no TPDO3 (digital inputs 0x60FD) within the heartbeat
	                           timeout: its limit switches cannot be read; value ms */
	MLIP_DRIVE_WRONG_DEVICE /* back after a loss as another device: its 0x1000 or
	                           0x1018 differs from bring-up; value index * 256 + sub */
} mlip_drive_fault;

/* What the bus last said about one drive (filled from mlip_co_classify). */
struct mlip_drive_obs {
	uint16_t statusword;
	int32_t position_counts;
	uint64_t tpdo_cycle; /* period of the last TPDO; 0: none yet */
	uint64_t tpdo_count; /* TPDOs since the first SYNC: the n-th answers SYNC n */
	uint8_t nmt_state;
	uint64_t hb_ns; /* time of the last heartbeat */
	struct mlip_emcy emcy;
	uint32_t emcy_count; /* EMCYs with a non-zero code */
	/* the touch probe (setup.touch_probe): 0x60B9 of the last TPDO1, the
	 * latched positions 0x60BA/0x60BB of the last TPDO2, TPDO2s since the
	 * first SYNC (the n-th answers SYNC n) */
	uint16_t probe_status;
	int32_t probe_pos, probe_neg;
	uint64_t tpdo2_count;
	uint64_t di_ns; /* time its digital inputs 0x60FD were last read (TPDO3) */
};

/* What the drive must be doing now. */
struct mlip_drive_expect {
	uint64_t now_ns;
	uint64_t cycle;           /* this period */
	uint64_t hb_timeout_ns;   /* 0: heartbeat not watched */
	uint64_t di_timeout_ns;   /* 0: its digital inputs not read (no TPDO3) */
	uint32_t tpdo_timeout;    /* periods without a TPDO that make it lost */
	uint32_t window_counts;   /* 0x6065 */
	int64_t following_counts; /* mlip_drive_following_error, or -1: unknown */
	int any_state;            /* 1: the master is disabling, has disabled or is enabling
	                             the drive: any state without the fault bit is right */
};

/* The first fault found, in the order of the enum (the drive's own word
 * first); *detail gets the figure (statusword, EMCY code, age in ms, counts). */
mlip_drive_fault mlip_drive_supervise(const struct mlip_drive_obs *o,
                                      const struct mlip_drive_expect *x, int64_t *detail);
const char *mlip_drive_fault_name(mlip_drive_fault f);

/* The following error of a position actual against the n targets sent
 * before the SYNC its TPDO answers (targets[0] the last one): the smallest
 * distance, since a drive applies a target at the SYNC after it is sent,
 * reports the position it sampled at a SYNC, and lags by a few periods more
 * while it moves. */
int64_t mlip_drive_following_error(const int32_t *targets, int n, int32_t actual);

#endif
