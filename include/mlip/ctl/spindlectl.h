/*
 * mlip/ctl/spindlectl.h - the controller's CiA 402 spindle ([SPINDLE] TYPE =
 * cia402, issue 19): what the program asked (M3/M4 S, S, M5), the operator's
 * spindle override, and the drive's periods decided by mlip/canopen/spindle.h.
 * Pure, on the period count; the controller (src/ctl/) glues it in:
 *
 *   a SPINDLE record   taken at rest (like every event): the speed asked,
 *                      then the program waits, at rest, until the spindle is
 *                      at speed (or at standstill for M5 and before a
 *                      reversal): state DWELLING, reason SPINDLE_WAIT. So no
 *                      feed move (nor rapid: stricter than LinuxCNC, which
 *                      lets G0 run while the spindle ramps) starts before it.
 *   every period       the drive's statusword and velocity actual in, the
 *                      target velocity out (an RPDO with the axes' power
 *                      sequencer's controlword); a timeout, the drive's
 *                      fault bit or the speed lost while cutting is a fault
 *                      (the feed stops on the path, state FAULT, reason
 *                      SPINDLE_FAULT naming the node)
 *   stop               asked 0 on entering IDLE, STOPPING, FAULT and ESTOP:
 *                      every program end, stop, fault and E-stop; the drives
 *                      are disabled only once it is at standstill
 *   override           50..200 % of the program's speed, within MIN_RPM and
 *                      MAX_RPM (an operator's choice is clamped to what the
 *                      spindle can do; a program's S beyond is refused at
 *                      its line instead, see src/gcode/io.c)
 */
#ifndef MLIP_CTL_SPINDLECTL_H
#define MLIP_CTL_SPINDLECTL_H

#include <stdint.h>

#include "mlip/canopen/spindle.h"
#include "mlip/machine/config.h"
#include "mlip/types.h"

#define MLIP_SPINDLE_OVERRIDE_MIN 50
#define MLIP_SPINDLE_OVERRIDE_MAX 200

struct mlip_ctl_spindle {
	int on;       /* a CiA 402 spindle is configured */
	uint8_t node; /* its node id */
	double min_rpm, max_rpm;
	struct mlip_spindle drive; /* the phases (mlip/canopen/spindle.h) */
	double program_rpm;        /* what the program asked (signed), before the override */
	uint32_t override_pct;     /* 50..200 */
	int32_t target;            /* the target velocity of this period, counts/s */
	int ready;                 /* the last period: 1 as needed, 0 not yet, -1 faulted */
	int reported;              /* its fault went to the controller */
	uint64_t asked;            /* the period of the last command */
	uint64_t ready_after;      /* periods the last wait took (asked -> ready) */
	int stopped;               /* the operator's stop in a hold (Grbl 0x9E): 0 rpm */
	int stop_req;              /* asked in a hold not yet at rest: 1 stop, 0 restore, -1 none */
};

/* Off when cfg is NULL or has no node; MLIP_E_INVALID for a config out of
 * its domain (the config reader checked it already). */
mlip_status mlip_ctl_spindle_init(struct mlip_ctl_spindle *s, const struct mlip_spindle_config *cfg,
                                  double period_s);

/* The program's speed (rpm, > 0 clockwise, 0 stop) from period on. */
void mlip_ctl_spindle_ask(struct mlip_ctl_spindle *s, double rpm, uint64_t period);

/* The operator's spindle stop (on 1) or its restore (on 0), from period on;
 * the program's speed and override are kept for the restore. */
void mlip_ctl_spindle_stop(struct mlip_ctl_spindle *s, int on, uint64_t period);

/* The operator's override, percent: MLIP_E_RANGE outside 50..200, MLIP_E_INVALID
 * without a spindle. Applied at once (the drive ramps). */
mlip_status mlip_ctl_spindle_override(struct mlip_ctl_spindle *s, int32_t pct, uint64_t period);

/* One period with the drive's statusword and velocity actual (counts/s):
 * 1 the spindle is as the program needs it, 0 not yet, -1 a new fault
 * (then *f is filled once: event MLIP_DRIVE_FAULT_BIT, _SPINDLE_TIMEOUT or
 * _SPINDLE_OUT_OF_BAND, the node, the statusword or rpm), -2 faulted
 * before. */
int mlip_ctl_spindle_step(struct mlip_ctl_spindle *s, uint16_t sw, int32_t vel_actual,
                          uint64_t period, uint32_t *event, double *value);

/* At standstill and asked 0, faulted (its own fault reaction stops it; a
 * spindle not heard from times out into a fault), or no spindle: the
 * drives may be disabled. */
int mlip_ctl_spindle_at_rest(const struct mlip_ctl_spindle *s);

/* The commanded rpm (with the override; 0 when stopped or faulted) and the
 * actual rpm. */
double mlip_ctl_spindle_cmd_rpm(const struct mlip_ctl_spindle *s);

#endif
