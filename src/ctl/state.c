/*
 * state.c - the names of the controller's states and reasons
 * (mlip/ctl/state.h), for the tools and the log.
 */
#include "mlip/ctl/state.h"

#include <stddef.h>

#define NAME_OF(names, v) ((v) < sizeof(names) / sizeof((names)[0]) ? (names)[v] : "?")

const char *mlip_ctl_state_name(uint32_t state)
{
	static const char *const names[] = {"idle",     "running", "held",   "stopping",
	                                    "fault",    "starved", "paused", "dwelling",
	                                    "pre-read", "estop",   "jog",    "homing"};

	return NAME_OF(names, state);
}

const char *mlip_state_why_name(uint32_t why)
{
	static const char *const names[] = {"none",
	                                    "program start",
	                                    "continuation",
	                                    "pre-read done",
	                                    "program end",
	                                    "underrun",
	                                    "feeder gone",
	                                    "hold",
	                                    "override 0",
	                                    "resume",
	                                    "CAN tx refused",
	                                    "CAN error frames",
	                                    "stall",
	                                    "dwell",
	                                    "dwell done",
	                                    "pause (M0)",
	                                    "optional pause (M1)",
	                                    "stop",
	                                    "exit signal",
	                                    "bad record",
	                                    "ring corrupt",
	                                    "position beyond the drives' range",
	                                    "drive fault",
	                                    "stop before the start",
	                                    "spindle (manual)",
	                                    "tool change (manual)",
	                                    "coolant (manual)",

	                                    "E-stop input",
	                                    "I/O module lost",
	                                    "limit switch",
	                                    "reset",
	                                    "jog",
	                                    "jog released",
	                                    "jog not renewed",
	                                    "jog at the soft limit",
	                                    "homing",
	                                    "homed",
	                                    "homing error",
	                                    "homing timeout",
	                                    "homing object refused",
	                                    "not homed",
	                                    "jog done",
	                                    "outputs switched",
	                                    "probing (G38)",
	                                    "probe move done",
	                                    "probe not tripped (G38.2/G38.4)",
	                                    "probe already tripped at the start",
	                                    "no probe input",
	                                    "spindle to speed",
	                                    "spindle fault",
	                                    "probe not in contact at the start (G38.4/G38.5)",
	                                    "path plan refused"};

	return NAME_OF(names, why);
}

uint32_t mlip_state_held_by(uint32_t held_by)
{
	switch (held_by) {
	case MLIP_WHY_HOLD:
	case MLIP_WHY_STALL:
	case MLIP_WHY_BUS_TX:
	case MLIP_WHY_BUS_ERROR:
	case MLIP_WHY_SPINDLE_WAIT:
	case MLIP_WHY_OVERRIDE_ZERO:
		return held_by;
	default:
		return 0;
	}
}

int mlip_state_hold_latched(uint32_t state, uint32_t held_by)
{
	uint32_t why = mlip_state_held_by(held_by);
	return (state == MLIP_STATE_IDLE || state == MLIP_STATE_STARVED) && why != 0 &&
	       why != MLIP_WHY_SPINDLE_WAIT && why != MLIP_WHY_OVERRIDE_ZERO;
}
