/*
 * mlip/canopen/spindle.h - a spindle on a CiA 402 drive in profile velocity
 * mode (0x6060 = 3; issue 19, [SPINDLE] TYPE = cia402): what the master
 * sends and when the feed may move, decided period by period from the
 * drive's statusword and velocity actual. Pure: no clock (the period count),
 * no I/O; the caller (the controller) puts the target velocity 0x60FF in the
 * spindle's RPDO with the power sequencer's controlword (mlip/canopen/
 * cia402.h) and passes what its TPDO said.
 *
 * Units: speeds in rpm, signed (> 0 clockwise, M3; < 0 counter-clockwise,
 * M4); the drive's velocity objects (0x60FF target, 0x606C actual) in counts
 * per second, counts_per_rev counts a revolution: v = rpm * counts / 60.
 *
 *   command(rpm)  a new speed (M3/M4/S, M5 = 0, the spindle override)
 *   step(...)     each period: the target to send; whether the spindle is
 *                 where the program needs it (ready); a fault
 *
 * Phases:
 *   STOPPED   target 0, at standstill            ready when asked 0
 *   RAMPING   target the command, not at speed   not ready
 *   AT_SPEED  at speed (below)                   ready
 *   BRAKING   a reversal: target 0 until standstill, then RAMPING the new way
 *   FAULT     latched until init: the timeout, the drive's fault bit, or
 *             out of the band while at speed for longer than band_periods
 * At speed: the statusword's target reached (bit 10) and |actual - target|
 * <= band_rpm. Standstill: |actual| <= band_rpm (with target 0; bit 12 in pv
 * mode is the drive's own "speed 0", taken as standstill too). A change of
 * speed must reach its target within timeout_periods (the config makes that
 * longer than the ramp at accel_rpm_s: a slower spindle is a fault, not a
 * wait forever); M5 and a reversal wait for standstill within it too.
 */
#ifndef MLIP_SPINDLE_H
#define MLIP_SPINDLE_H

#include <stdint.h>

#include "mlip/types.h"

#define MLIP_SPINDLE_SW_TARGET_REACHED 0x0400u /* statusword bit 10 */
#define MLIP_SPINDLE_SW_SPEED_ZERO     0x1000u /* bit 12 in profile velocity mode */
#define MLIP_SPINDLE_MODE_PV           3       /* 0x6060 */

typedef enum {
	MLIP_SPINDLE_STOPPED = 0,
	MLIP_SPINDLE_RAMPING,
	MLIP_SPINDLE_AT_SPEED,
	MLIP_SPINDLE_BRAKING,
	MLIP_SPINDLE_FAULT
} mlip_spindle_phase;

typedef enum {
	MLIP_SPINDLE_OK = 0,
	MLIP_SPINDLE_TIMEOUT,     /* not at speed (or not stopped) in time: value = actual rpm */
	MLIP_SPINDLE_DRIVE_FAULT, /* the statusword's fault bit: value = statusword */
	MLIP_SPINDLE_OUT_OF_BAND  /* at speed, then away from it too long: value = actual rpm */
} mlip_spindle_fault;

struct mlip_spindle_cfg {
	double counts_per_rev;    /* > 0 */
	double band_rpm;          /* >= 0: how close is "at speed" */
	uint32_t timeout_periods; /* a change reaches its target within this (> 0) */
	uint32_t band_periods;    /* at speed, then outside the band this long: a fault */
};

struct mlip_spindle {
	struct mlip_spindle_cfg cfg;
	double cmd_rpm;    /* what is asked */
	double target_rpm; /* what is sent (0 while braking for a reversal) */
	double actual_rpm; /* the last velocity actual */
	uint32_t phase;    /* mlip_spindle_phase */
	uint64_t since;    /* period of the command (the timeout runs from it) */
	uint32_t out;      /* periods outside the band while at speed */
	uint32_t fault;    /* mlip_spindle_fault */
	double fault_value;
};

/* Stopped, asked 0. MLIP_E_INVALID for a config out of its domain. */
mlip_status mlip_spindle_init(struct mlip_spindle *s, const struct mlip_spindle_cfg *cfg);

/* Ask rpm from period on (no effect once faulted). */
void mlip_spindle_command(struct mlip_spindle *s, double rpm, uint64_t period);

/* One period with the drive's statusword and velocity actual (counts/s):
 * the target velocity to send (counts/s, rounded) in *target; returns 1
 * when the spindle is as the program needs it (at speed, or stopped when
 * asked 0), 0 while it is not (yet), -1 once faulted (s->fault, value;
 * the target is then 0). */
int mlip_spindle_step(struct mlip_spindle *s, uint16_t statusword, int32_t vel_actual,
                      uint64_t period, int32_t *target);

/* rpm <-> counts/s at counts_per_rev. */
double mlip_spindle_counts(const struct mlip_spindle_cfg *cfg, double rpm);
double mlip_spindle_rpm(const struct mlip_spindle_cfg *cfg, double counts_s);

/* "timeout", "drive fault", "out of band", "none". */
const char *mlip_spindle_fault_name(uint32_t fault);

#endif
