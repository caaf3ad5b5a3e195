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
		case MLIP_402_SWITCH_ON_DISABLED:
			/* OFF is "ready to switch on", confirmed: a program coming
			 * next switches on from there */
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

/* The state that decides the group's next step (all drives get the same
 * controlword, so it must be a valid command for each of them): toward
 * power the one furthest behind (a transient state, fault, quick stop
 * active, switch on disabled, ready, switched on, enabled); toward OFF the
 * one with the most power (operation enabled only when all are switched on
 * or enabled: 0x0007 would switch on a drive that is not; then quick stop
 * active, whose only way out is 0x0000; then switched on or switch on
 * disabled, both taken to "ready" by 0x0006). UNKNOWN: no drive followed. */
static mlip_402_state group_state(const uint16_t *sw, int n, uint32_t mute, uint32_t want)
{
	static const int rank[MLIP_402_UNKNOWN + 1] = {[MLIP_402_NOT_READY] = 0,
	                                               [MLIP_402_FAULT_REACTION_ACTIVE] = 0,
	                                               [MLIP_402_UNKNOWN] = 0,
	                                               [MLIP_402_FAULT] = 1,
	                                               [MLIP_402_QUICK_STOP_ACTIVE] = 2,
	                                               [MLIP_402_SWITCH_ON_DISABLED] = 3,
	                                               [MLIP_402_READY_TO_SWITCH_ON] = 4,
	                                               [MLIP_402_SWITCHED_ON] = 5,
	                                               [MLIP_402_OPERATION_ENABLED] = 6};
	uint32_t seen = 0;
	mlip_402_state low = MLIP_402_UNKNOWN;
	for (int k = 0; k < n; k++) {
		if (mute & (1u << k)) {
			continue;
		}
		mlip_402_state x = mlip_402_state_of(sw[k]);
		if (seen == 0 || rank[x] < rank[low]) {
			low = x;
		}
		seen |= 1u << x;
	}
	if (want != MLIP_POWER_OFF || seen == 0) {
		return low;
	}
	uint32_t up = (1u << MLIP_402_OPERATION_ENABLED) | (1u << MLIP_402_SWITCHED_ON);
	if ((seen & (1u << MLIP_402_OPERATION_ENABLED)) && (seen & ~up) == 0) {
		return MLIP_402_OPERATION_ENABLED;
	}
	if (seen & (1u << MLIP_402_QUICK_STOP_ACTIVE)) {
		return MLIP_402_QUICK_STOP_ACTIVE;
	}
	if (seen & (up | (1u << MLIP_402_SWITCH_ON_DISABLED))) {
		return MLIP_402_SWITCH_ON_DISABLED; /* 0x0006 for each */
	}
	return low;
}

/* The next step of the group from the states its drives show. */
static uint32_t choose_group(const uint16_t *sw, int n, uint32_t mute, uint32_t want,
                             mlip_402_state *x)
{
	*x = group_state(sw, n, mute, want);
	uint32_t to = choose(*x, want);
	if (to == MLIP_POWER_SWITCHED_ON) {
		/* the furthest behind is switched on: any drive enabled goes back */
		for (int k = 0; k < n; k++) {
			if (!(mute & (1u << k)) &&
			    mlip_402_state_of(sw[k]) == MLIP_402_OPERATION_ENABLED) {
				return MLIP_POWER_DISABLING;
			}
		}
	}
	return to;
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
		return go(s, choose_group(sw, n, mute, want, &ch->reached), want, now, ch);
	}
	if (mlip_402_power_is_rest(s->step)) {
		if (want == s->step) {
			return 0;
		}
		uint32_t to;
		if (s->step == MLIP_POWER_OFF) {
			/* no torque at OFF: a drive may have left "ready" by itself
			 * (its safe torque off, its DC bus): from what they show */
			to = choose_group(sw, n, mute, want, &ch->reached);
		} else {
			ch->reached = rest_state(s->step);
			to = choose(ch->reached, want);
		}
		return to == s->step ? 0 : go(s, to, want, now, ch);
	}
	if (s->want != MLIP_POWER_OFF && want == MLIP_POWER_OFF) {
		/* given up on the way to power: down at once; a step that cannot
		 * have switched anything on (shutdown, disable voltage, fault
		 * reset, waiting) leads toward OFF too and goes on */
		if (s->step == MLIP_POWER_SWITCHING_ON || s->step == MLIP_POWER_ENABLING) {
			return go(s, MLIP_POWER_DISABLING, want, now, ch);
		}
		s->want = want;
		s->t0 = now;
		s->ok = 1;
	}
	int late = first_late(s, sw, n, mute);
	if (late < 0) {
		if (s->step == MLIP_POWER_WAITING) {
			return go(s, choose_group(sw, n, mute, s->want, &ch->reached), s->want, now,
			          ch);
		}
		ch->reached = mlip_402_step_expects(s->step);
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
	if (s->step == MLIP_POWER_SWITCHING_ON || s->step == MLIP_POWER_ENABLING) {
		return go(s, MLIP_POWER_DISABLING, MLIP_POWER_OFF, now, ch);
	}
	/* nothing was switched on: down from what the drives show (0x0007
	 * would switch on a drive that is "ready") */
	mlip_402_state x;
	return go(s, choose_group(sw, n, mute, MLIP_POWER_OFF, &x), MLIP_POWER_OFF, now, ch);
}
