/*
 * mlip/canopen/cia402.h - the CiA 402 power state machine of a drive (CiA 402-2
 * "drive state machine"): the statusword's states, the controlwords, and the
 * one sequencer that takes a group of drives from the state they are in to
 * the power the master wants. rt/drives.c runs it at bring-up (controlword
 * 0x6040 written and statusword 0x6041 read by SDO, one drive at a time, on
 * a clock in ns) and the controller in its period (the RPDOs' controlword,
 * every TPDO's statusword, all drives in step, on the period count). Pure:
 * no clock, no I/O; the caller passes the time in its own unit.
 *
 * The steps (mlip_drive_power, published as the status' drive_power), each
 * one controlword held until every drive followed shows its state:
 *
 *   power-up state     toward ENABLED / SWITCHED_ON         toward OFF
 *   fault              RESETTING 0x0000, 0x0080 (the rising  OFF (left alone)
 *                      edge) -> switch on disabled
 *   quick stop active  VOLTAGE_OFF 0x0000 -> switch on disabled  VOLTAGE_OFF
 *   not ready, fault   WAITING (nothing sent: the drive goes   OFF
 *   reaction           on by itself)
 *   switch on disabled SHUTTING_DOWN 0x0006 -> ready          SHUTTING_DOWN
 *   ready to switch on SWITCHING_ON 0x0007 -> switched on     OFF (rest, 0x0006)
 *   switched on        ENABLING 0x000F -> operation enabled   SHUTTING_DOWN 0x0006
 *                      (SWITCHED_ON: rest, 0x0007)
 *   operation enabled  ENABLED (rest, 0x000F)                 DISABLING 0x0007 ->
 *                      (SWITCHED_ON: DISABLING)               switched on
 *
 * OFF is "ready to switch on" confirmed by every drive followed, so that
 * switch on from it is a valid command. The drives of a group may show
 * different states (one still in quick stop, another already switch on
 * disabled): each step is chosen from all of them, a command valid for each
 * (toward power the one furthest behind, toward OFF the one with the most
 * power), and confirmed only when every drive followed shows its state.
 * Leaving OFF reads the drives again (at rest without torque a drive may
 * drop to "switch on disabled" by itself).
 *
 * A step not confirmed within the timeout: toward OFF the sequence goes on
 * as if it had been (the late drive is noted: nothing is gained by holding
 * power on), toward power it has failed: reported, and the group goes back
 * down (DISABLING). A sequence toward power is given up when the want drops
 * to OFF (from switching on or enabling DISABLING at once, else the step
 * goes on toward OFF); one toward OFF always ends at OFF first.
 */
#ifndef MLIP_CIA402_H
#define MLIP_CIA402_H

#include <stdint.h>

#include "mlip/types.h"

/* ---- states and words ------------------------------------------------------------- */

typedef enum {
	MLIP_402_NOT_READY = 0,
	MLIP_402_SWITCH_ON_DISABLED,
	MLIP_402_READY_TO_SWITCH_ON,
	MLIP_402_SWITCHED_ON,
	MLIP_402_OPERATION_ENABLED,
	MLIP_402_QUICK_STOP_ACTIVE,
	MLIP_402_FAULT_REACTION_ACTIVE,
	MLIP_402_FAULT,
	MLIP_402_UNKNOWN
} mlip_402_state;

#define MLIP_402_SW_FAULT            0x0008u /* statusword bit 3 */
#define MLIP_402_SW_FOLLOWING_ERROR  0x2000u /* bit 13 in CSP */
#define MLIP_402_CW_DISABLE_VOLTAGE  0x0000u
#define MLIP_402_CW_SHUTDOWN         0x0006u
#define MLIP_402_CW_SWITCH_ON        0x0007u /* also "disable operation" from enabled */
#define MLIP_402_CW_ENABLE_OPERATION 0x000Fu
#define MLIP_402_CW_FAULT_RESET      0x0080u /* on its rising edge */
#define MLIP_402_CW_QUICK_STOP       0x0002u /* operation enabled -> quick stop active */
#define MLIP_402_MODE_CSP            8       /* 0x6060 / 0x6061 */
#define MLIP_402_MODE_PV             3       /* profile velocity (a spindle) */

/* The state a statusword shows (CiA 402 table of statusword bits 0-3, 5, 6). */
mlip_402_state mlip_402_state_of(uint16_t statusword);
const char *mlip_402_state_name(mlip_402_state s);

/* ---- the sequencer ------------------------------------------------------------------ */

/* The drives' power: a rest (NONE, ENABLED, OFF, SWITCHED_ON) or a step
 * toward one. Values 0..6 are the status' drive_power of layout version 4. */
typedef enum {
	MLIP_POWER_NONE = 0,      /* no drives brought up by mlip; for the sequencer: not
	                             known yet (its first run reads the drives' state) */
	MLIP_POWER_ENABLED,       /* rest: operation enabled (0x000F): the planner may move */
	MLIP_POWER_DISABLING,     /* disable operation (0x0007) until "switched on" */
	MLIP_POWER_SHUTTING_DOWN, /* shutdown (0x0006) until "ready to switch on" */
	MLIP_POWER_OFF,           /* rest: ready to switch on (0x0006): no torque, nothing moves */
	MLIP_POWER_SWITCHING_ON,  /* switch on (0x0007) until "switched on" */
	MLIP_POWER_ENABLING,      /* enable operation (0x000F) until "operation enabled" */
	MLIP_POWER_SWITCHED_ON,   /* rest: switched on (0x0007): voltage, no torque */
	MLIP_POWER_RESETTING,     /* fault reset: 0x0000, then 0x0080, until "switch on disabled" */
	MLIP_POWER_VOLTAGE_OFF,   /* disable voltage (0x0000) until "switch on disabled" */
	MLIP_POWER_WAITING,       /* not ready, fault reaction: nothing sent until it moves on */
	MLIP_POWER_QUICK_STOP,    /* the controller's E-stop (or a limit): quick stop (0x0002) to
	                             every drive, held until a reset; not a step of the sequencer,
	                             which reads the drives' states again after it */
	MLIP_POWER_COUNT
} mlip_drive_power;

struct mlip_402_seq {
	uint32_t step;    /* mlip_drive_power */
	uint32_t want;    /* the rest the sequence goes to: OFF, SWITCHED_ON or ENABLED */
	int32_t cw;       /* the controlword of the step; -1: none yet (WAITING first) */
	uint64_t timeout; /* a step not confirmed this long has timed out (caller's unit) */
	uint64_t since;   /* the step began */
	uint64_t t0;      /* the sequence began (it left a rest, or turned back) */
	/* the last sequence */
	uint64_t took;      /* to its rest (OFF, ENABLED, SWITCHED_ON) */
	int ok;             /* toward OFF: every step confirmed in time */
	int late;           /* the last step not confirmed in time: the drive's index; -1 none */
	uint16_t late_sw;   /* its statusword then */
	uint32_t late_step; /* that step */
};

/* A step ended (mlip_402_seq_run returned 1). */
struct mlip_402_change {
	uint32_t from, to;      /* mlip_drive_power */
	uint64_t in_step;       /* how long `from` took */
	uint64_t in_sequence;   /* since the sequence began; 0: `to` begins one */
	int late;               /* -1, or the first drive followed that did not show `from`'s
	                           state in time (the sequence went on without it) */
	uint16_t late_sw;       /* its statusword */
	int failed;             /* `from` led toward power and timed out: `to` is DISABLING */
	mlip_402_state reached; /* the state `from` asked for (confirmed, or assumed when late) */
};

/* At `rest` (NONE: not known: the first run reads it) at time now; a step
 * not confirmed within timeout is late (toward OFF) or failed. */
void mlip_402_seq_init(struct mlip_402_seq *s, mlip_drive_power rest, uint64_t timeout,
                       uint64_t now);
/* One look at the n drives' statuswords sw[] (bit k of mute: drive k is not
 * followed, e.g. faulted: its word is ignored) at time now, wanting `want`
 * (OFF, SWITCHED_ON or ENABLED): 1 when a step ended and the next began
 * (*ch says which and how), else 0. Then s->cw is the controlword to send
 * (-1: none). At most one step a call. */
int mlip_402_seq_run(struct mlip_402_seq *s, mlip_drive_power want, const uint16_t *sw, int n,
                     uint32_t mute, uint64_t now, struct mlip_402_change *ch);
/* 1 for a rest (NONE, ENABLED, OFF, SWITCHED_ON). */
int mlip_402_power_is_rest(uint32_t power);
/* "enabled", "disabling", "shutting down", "off", "switching on", "enabling",
 * ...; "none" without drives; "?" out of range. */
const char *mlip_drive_power_name(uint32_t power);
/* The command a step sends, as CiA 402 names it ("disable operation",
 * "shutdown", "switch on", "enable operation", "fault reset", "disable
 * voltage"; "" for a rest or WAITING), its controlword (-1: none), and the
 * state it waits for (MLIP_402_UNKNOWN for a rest or WAITING). */
const char *mlip_402_step_command(uint32_t step);
int32_t mlip_402_step_cw(uint32_t step);
mlip_402_state mlip_402_step_expects(uint32_t step);

#endif
