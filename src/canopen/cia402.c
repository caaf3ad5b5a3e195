/*
 * cia402.c - the CiA 402 power state machine (mlip/canopen/cia402.h): the
 * statusword decoded, and the one sequencer of the drives' power, used by
 * the bring-up (by SDO) and the controller's period (by PDO). Pure.
 */
#include "mlip/canopen/cia402.h"

#include <stddef.h>

mlip_402_state mlip_402_state_of(uint16_t sw)
{
	/* CiA 402-2 table "statusword state coding": bits 0-3 and 6 (mask 0x4F)
	 * for the first and last states, 0-3, 5, 6 (mask 0x6F) for the others */
	switch (sw & 0x4Fu) {
	case 0x00:
		return MLIP_402_NOT_READY;
	case 0x40:
		return MLIP_402_SWITCH_ON_DISABLED;
	case 0x0F:
		return MLIP_402_FAULT_REACTION_ACTIVE;
	case 0x08:
		return MLIP_402_FAULT;
	}
	switch (sw & 0x6Fu) {
	case 0x21:
		return MLIP_402_READY_TO_SWITCH_ON;
	case 0x23:
		return MLIP_402_SWITCHED_ON;
	case 0x27:
		return MLIP_402_OPERATION_ENABLED;
	case 0x07:
		return MLIP_402_QUICK_STOP_ACTIVE;
	}
	return MLIP_402_UNKNOWN;
}

const char *mlip_402_state_name(mlip_402_state s)
{
	static const char *const names[] = {"not ready to switch on",
	                                    "switch on disabled",
	                                    "ready to switch on",
	                                    "switched on",
	                                    "operation enabled",
	                                    "quick stop active",
	                                    "fault reaction active",
	                                    "fault",
	                                    "unknown"};
	return (int)s >= 0 && s <= MLIP_402_UNKNOWN ? names[s] : "unknown";
}

/* ---- the steps ----------------------------------------------------------------------- */

static const struct step {
	const char *name;    /* status */
	const char *command; /* what is sent, as CiA 402 names it */
	int32_t cw;          /* -1: nothing (WAITING keeps what was sent) */
	mlip_402_state expects;
} steps[MLIP_POWER_COUNT] = {
    [MLIP_POWER_NONE] = {"none", "", -1, MLIP_402_UNKNOWN},
    [MLIP_POWER_ENABLED] = {"enabled", "", MLIP_402_CW_ENABLE_OPERATION, MLIP_402_UNKNOWN},
    [MLIP_POWER_DISABLING] = {"disabling", "disable operation", MLIP_402_CW_SWITCH_ON,
                              MLIP_402_SWITCHED_ON},
    [MLIP_POWER_SHUTTING_DOWN] = {"shutting down", "shutdown", MLIP_402_CW_SHUTDOWN,
                                  MLIP_402_READY_TO_SWITCH_ON},
    [MLIP_POWER_OFF] = {"off", "", MLIP_402_CW_SHUTDOWN, MLIP_402_UNKNOWN},
    [MLIP_POWER_SWITCHING_ON] = {"switching on", "switch on", MLIP_402_CW_SWITCH_ON,
                                 MLIP_402_SWITCHED_ON},
    [MLIP_POWER_ENABLING] = {"enabling", "enable operation", MLIP_402_CW_ENABLE_OPERATION,
                             MLIP_402_OPERATION_ENABLED},
    [MLIP_POWER_SWITCHED_ON] = {"switched on", "", MLIP_402_CW_SWITCH_ON, MLIP_402_UNKNOWN},
    [MLIP_POWER_RESETTING] = {"resetting", "fault reset", MLIP_402_CW_FAULT_RESET,
                              MLIP_402_SWITCH_ON_DISABLED},
    [MLIP_POWER_VOLTAGE_OFF] = {"voltage off", "disable voltage", MLIP_402_CW_DISABLE_VOLTAGE,
                                MLIP_402_SWITCH_ON_DISABLED},
    [MLIP_POWER_WAITING] = {"waiting", "", -1, MLIP_402_UNKNOWN},
    [MLIP_POWER_QUICK_STOP] = {"quick stop", "quick stop", MLIP_402_CW_QUICK_STOP,
                               MLIP_402_UNKNOWN},
};

const char *mlip_drive_power_name(uint32_t power)
{
	return power < MLIP_POWER_COUNT ? steps[power].name : "?";
}

const char *mlip_402_step_command(uint32_t step)
{
	return step < MLIP_POWER_COUNT ? steps[step].command : "";
}

int32_t mlip_402_step_cw(uint32_t step)
{
	return step < MLIP_POWER_COUNT ? steps[step].cw : -1;
}

mlip_402_state mlip_402_step_expects(uint32_t step)
{
	return step < MLIP_POWER_COUNT ? steps[step].expects : MLIP_402_UNKNOWN;
}

int mlip_402_power_is_rest(uint32_t power)
{
	return power == MLIP_POWER_NONE || power == MLIP_POWER_ENABLED || power == MLIP_POWER_OFF ||
	       power == MLIP_POWER_SWITCHED_ON;
}

/* A state the drive leaves by itself (the master can only wait). */
static int transient(mlip_402_state s)
{
	return s == MLIP_402_NOT_READY || s == MLIP_402_FAULT_REACTION_ACTIVE ||
	       s == MLIP_402_UNKNOWN;
}

/* The next step from drives in state x toward want (the table of the header). */
static uint32_t choose(mlip_402_state x, uint32_t want)
{
	if (want == MLIP_POWER_OFF) {
		switch (x) {
		case MLIP_402_OPERATION_ENABLED:
			return MLIP_POWER_DISABLING;
		case MLIP_402_SWITCHED_ON:
			return MLIP_POWER_SHUTTING_DOWN;
		case MLIP_402_QUICK_STOP_ACTIVE:
			return MLIP_POWER_VOLTAGE_OFF;
		default:
			return MLIP_POWER_OFF; /* no power stage on: left as it is */
		}
	}
	switch (x) {
	case MLIP_402_OPERATION_ENABLED:
		return want == MLIP_POWER_ENABLED ? MLIP_POWER_ENABLED : MLIP_POWER_DISABLING;
	case MLIP_402_SWITCHED_ON:
		return want == MLIP_POWER_ENABLED ? MLIP_POWER_ENABLING : MLIP_POWER_SWITCHED_ON;
	case MLIP_402_READY_TO_SWITCH_ON:
		return MLIP_POWER_SWITCHING_ON;
	case MLIP_402_SWITCH_ON_DISABLED:
		return MLIP_POWER_SHUTTING_DOWN;
	case MLIP_402_FAULT:
		return MLIP_POWER_RESETTING;
	case MLIP_402_QUICK_STOP_ACTIVE:
		return MLIP_POWER_VOLTAGE_OFF;
	default:
		return MLIP_POWER_WAITING;
	}
}

/* The state of a rest, as the drives show it. */
static mlip_402_state rest_state(uint32_t rest)
{
	switch (rest) {
	case MLIP_POWER_ENABLED:
		return MLIP_402_OPERATION_ENABLED;
	case MLIP_POWER_SWITCHED_ON:
		return MLIP_402_SWITCHED_ON;
	default:
		return MLIP_402_READY_TO_SWITCH_ON;
	}
}

void mlip_402_seq_init(struct mlip_402_seq *s, mlip_drive_power rest, uint64_t timeout,
                       uint64_t now)
{
	s->step = rest;
	s->want = rest == MLIP_POWER_NONE ? MLIP_POWER_OFF : rest;
	s->cw = mlip_402_step_cw(rest);
	s->timeout = timeout;
	s->since = s->t0 = now;
	s->took = 0;
	s->ok = 0;
	s->late = -1;
	s->late_sw = 0;
	s->late_step = MLIP_POWER_NONE;
}

/* The first drive followed that does not show what step waits for; -1. */
static int first_late(const struct mlip_402_seq *s, const uint16_t *sw, int n, uint32_t mute)
{
	mlip_402_state want = mlip_402_step_expects(s->step);
	for (int k = 0; k < n; k++) {
		mlip_402_state x = mlip_402_state_of(sw[k]);
		if (mute & (1u << k)) {
			continue;
		}
		if (s->step == MLIP_POWER_WAITING ? transient(x) : x != want) {
			return k;
		}
	}
	return -1;
}

/* The state of the first drive followed (what NONE and WAITING go by). */
static mlip_402_state first_state(const uint16_t *sw, int n, uint32_t mute)
{
	for (int k = 0; k < n; k++) {
		if (!(mute & (1u << k))) {
			return mlip_402_state_of(sw[k]);
		}
	}
	return MLIP_402_UNKNOWN;
}

static int go(struct mlip_402_seq *s, uint32_t to, uint32_t want, uint64_t now,
              struct mlip_402_change *ch)
{
	int begins = mlip_402_power_is_rest(s->step) || want != s->want || ch->failed;
	ch->from = s->step;
	ch->to = to;
	ch->in_step = now - s->since;
	ch->in_sequence = begins ? 0 : now - s->t0;
	if (ch->late >= 0) {
		s->late = ch->late;
		s->late_sw = ch->late_sw;
		s->late_step = s->step;
		if (want == MLIP_POWER_OFF && !ch->failed) {
			s->ok = 0; /* a step toward OFF went on without a drive */
		}
	}
	if (begins) {
		s->t0 = now;
		s->ok = want == MLIP_POWER_OFF;
	}
	if (mlip_402_power_is_rest(to)) {
		s->took = now - s->t0;
	}
	s->step = to;
	s->want = want;
	s->since = now;
	if (to == MLIP_POWER_RESETTING) {
		s->cw = MLIP_402_CW_DISABLE_VOLTAGE; /* bit 7 low first: the reset is its edge */
	} else if (to != MLIP_POWER_WAITING) {
		s->cw = mlip_402_step_cw(to);
	}
	return 1;
}

int mlip_402_seq_run(struct mlip_402_seq *s, mlip_drive_power want, const uint16_t *sw, int n,
                     uint32_t mute, uint64_t now, struct mlip_402_change *ch)
{
	ch->late = -1;
	ch->late_sw = 0;
	ch->failed = 0;
	ch->reached = MLIP_402_UNKNOWN;
	if (s->step == MLIP_POWER_NONE) {
		ch->reached = first_state(sw, n, mute);
		return go(s, choose(ch->reached, want), want, now, ch);
	}
	if (mlip_402_power_is_rest(s->step)) {
		if (want == s->step) {
			return 0;
		}
		ch->reached = rest_state(s->step);
		uint32_t to = choose(ch->reached, want);
		return to == s->step ? 0 : go(s, to, want, now, ch);
	}
	if (s->want != MLIP_POWER_OFF && want == MLIP_POWER_OFF) {
		/* given up on the way to power: down at once */
		return go(s, MLIP_POWER_DISABLING, want, now, ch);
	}
	int late = first_late(s, sw, n, mute);
	if (late < 0) {
		ch->reached = s->step == MLIP_POWER_WAITING ? first_state(sw, n, mute)
		                                            : mlip_402_step_expects(s->step);
		return go(s, choose(ch->reached, s->want), s->want, now, ch);
	}
	if (s->step == MLIP_POWER_RESETTING && s->cw == (int32_t)MLIP_402_CW_DISABLE_VOLTAGE) {
		s->cw = MLIP_402_CW_FAULT_RESET; /* the rising edge of bit 7 */
		return 0;
	}
	if (now - s->since < s->timeout) {
		return 0;
	}
	ch->late = late;
	ch->late_sw = sw[late];
	if (s->want == MLIP_POWER_OFF) {
		/* late toward OFF: on as if it had come, the drive noted */
		ch->reached = mlip_402_step_expects(s->step);
		return go(s, choose(ch->reached, MLIP_POWER_OFF), MLIP_POWER_OFF, now, ch);
	}
	ch->failed = 1;
	ch->reached = mlip_402_step_expects(s->step);
	return go(s, MLIP_POWER_DISABLING, MLIP_POWER_OFF, now, ch);
}
