/*
 * grblsetting.c - mlip-grbl's `$` lines (grblsrv.h): the settings and the
 * other system commands, and $H / $X, which wait for the controller's
 * homing and reset before they are answered.
 */
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"
#include "grbl.h"
#include "grblmach.h"
#include "grblsrv.h"
#include "grblstream.h"
#include "mlip/ctl/state.h"
#include "mlip/ipc/ring.h"
#include "mlip/machine/config.h"

/* ---- $H and $X: the controller's homing and reset ----------------------------- */

void await_start(uint32_t op)
{
	S.await_op = op;
	S.await_stage = 0;
	S.await_ns = now_ns();
	S.await_t0 = S.await_ns;
}

void await_end(int code)
{
	S.await_op = 0;
	answer(code);
}

/* Post the command, take its result, follow it to its end, answer. */
void await_pump(void)
{
	int32_t res = 0;
	if (S.await_op == 0) {
		return;
	}
	if (S.ctl == NULL) {
		S.await_op = 0; /* its sender left: homing goes on, nobody to answer */
		return;
	}
	if (S.await_stage == 0) {
		if (S.qn > 0 || S.ov_post >= 0 || S.sp_post >= 0) {
			return; /* real-time commands first: they came before */
		}
		if (mlip_ring_cmd_post(S.r, (mlip_ring_cmd_op)S.await_op, 0, &S.await_seq) ==
		    MLIP_OK) {
			S.await_stage = 1;
			S.await_ns = now_ns();
		} else if (now_ns() - S.await_ns > 5000000000ull) {
			send_msg(S.ctl, "the controller's mailbox stayed busy for 5 s (another "
			                "mlip-ctl?): try again");
			await_end(S.await_op == MLIP_CMD_HOME ? GRBL_E_IDLE : GRBL_E_LOCK);
		}
		return;
	}
	if (S.await_stage == 1) {
		mlip_status rc = mlip_ring_cmd_result(S.r, S.await_seq, &res);
		if (rc == MLIP_E_EMPTY && !S.dead) {
			return;
		}
		if (rc != MLIP_OK) {
			send_msg(S.ctl, "the controller did not answer %s",
			         S.await_op == MLIP_CMD_HOME ? "$H" : "$X");
			await_end(S.await_op == MLIP_CMD_HOME ? GRBL_E_IDLE : GRBL_E_LOCK);
			return;
		}
		if (S.await_op == MLIP_CMD_HOME && res == MLIP_E_RANGE) {
			send_msg(S.ctl, "homing is not configured: no HOME_METHOD in the machine's "
			                "configuration (or no CiA 402 drives: mlip-rt --drives)");
			await_end(GRBL_E_SETTING_DISABLED);
			return;
		}
		if (S.await_op == MLIP_CMD_HOME && res != MLIP_OK) {
			char why[240] = "the controller is not idle";
			if (locked_state(S.cs.state)) {
				locked_why(why, sizeof(why));
			}
			send_msg(S.ctl, "$H refused: %s", why);
			await_end(GRBL_E_IDLE);
			return;
		}
		if (S.await_op == MLIP_CMD_RESET && res == MLIP_E_RANGE) {
			send_msg(S.ctl,
			         "$X refused: the input that stopped the machine is still on "
			         "(release the E-stop, move the axis off its limit switch, or "
			         "wait for a lost I/O module to come back)");
			await_end(GRBL_E_LOCK);
			return;
		}
		if (S.await_op == MLIP_CMD_RESET && res == MLIP_E_FULL &&
		    now_ns() - S.await_t0 < 30000000000ull) {
			S.await_stage = 0; /* the axes still brake: posted again, at rest taken */
			S.await_ns = now_ns();
			return;
		}
		if (S.await_op == MLIP_CMD_RESET && res == MLIP_E_FULL) {
			send_msg(S.ctl,
			         "$X refused: the axes are still braking on their drives' "
			         "quick stop ramps for 30 s: unlock again once they stand still");
			await_end(GRBL_E_LOCK);
			return;
		}
		S.await_stage = 2; /* accepted (or nothing left to reset) */
		S.await_hb = S.cs.heartbeat;
		return;
	}
	/* under way: the status of a later period says how it ended */
	if (S.cs.heartbeat < S.await_hb + 2 && !S.dead) {
		return;
	}
	if (S.await_op == MLIP_CMD_HOME) {
		if (S.cs.state == MLIP_STATE_HOMING && !S.dead) {
			return;
		}
		if (S.cs.state == MLIP_STATE_IDLE && S.cs.reason == MLIP_WHY_HOMED) {
			S.alarm = 0; /* Grbl: homing unlocks */
			S.critical = 0;
			resync(1); /* where homing left the axes */
		}
		/* a failure was pushed as an alarm (follow_controller); Grbl
		 * answers the line ok after its homing cycle either way */
		await_end(0);
		return;
	}
	if (locked_state(S.cs.state) && !S.dead) {
		if (!grbl_resettable(S.cs.state, S.cs.reason)) {
			/* reset into what came before it (a drive fault) */
			say_locked();
			await_end(GRBL_E_LOCK);
			return;
		}
		if (now_ns() - S.await_ns > 5000000000ull) {
			send_msg(S.ctl, "$X: the controller is still in %s",
			         mlip_ctl_state_name(S.cs.state));
			await_end(GRBL_E_LOCK);
		}
		return;
	}
	S.alarm = 0;
	S.critical = 0;
	resync(1);
	send_msg(S.ctl, "Caution: Unlocked");
	await_end(0);
}

void settings_list(void)
{
	char b[GRBL_MSG_BYTES];
	uint32_t limits = 0;
	for (int a = 0; a < S.m.n_axes; a++) {
		limits |= (1u << MLIP_IN_LIMIT_NEG(a)) | (1u << MLIP_IN_LIMIT_POS(a));
	}
	S.homing.hard_limits = (S.cs.io_mapped & limits) != 0; /* the controller's inputs */
	for (int i = 0; grbl_setting_line(b, sizeof(b), &S.m, &S.fmt, &S.homing, i) > 0; i++) {
		send_line(S.ctl, b);
	}
}

/* ---- lines ------------------------------------------------------------------- */

int idle_or_alarm(void)
{
	const char *s = grbl_state();
	return strcmp(s, "Idle") == 0 || strcmp(s, "Alarm") == 0;
}

/* A `$` line: 1 answered. */
int system_line(const char *t, size_t len)
{
	struct grbl_sys c;
	char b[GRBL_MSG_BYTES];
	grbl_sys_parse(t, len, &c);
	const char *state = grbl_state();
	switch (c.kind) {
	case GRBL_SYS_HELP:
		send_line(S.ctl, "[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? "
		                 "ctrl-x]");
		answer(0);
		return 1;
	case GRBL_SYS_SETTINGS:
		/* system.c: not during a cycle or a hold (it takes too long to print) */
		if (strcmp(state, "Run") == 0 || strncmp(state, "Hold", 4) == 0) {
			answer(GRBL_E_IDLE);
			return 1;
		}
		settings_list();
		answer(0);
		return 1;
	case GRBL_SYS_GCODE:
		grbl_gcode_state(b, sizeof(b), &S.st.g, -1);
		send_line(S.ctl, b);
		answer(0);
		return 1;
	case GRBL_SYS_CHECK:
		if (S.check_mode) {
			send_msg(S.ctl, "Disabled");
			answer(0);
			soft_reset(); /* Grbl resets when check mode ends */
			return 1;
		}
		if (strcmp(state, "Idle") != 0) {
			answer(GRBL_E_IDLE);
			return 1;
		}
		S.check_mode = 1;
		send_msg(S.ctl, "Enabled");
		answer(0);
		return 1;
	case GRBL_SYS_UNLOCK:
		if (locked_state(S.cs.state) && !S.dead) {
			if (!grbl_resettable(S.cs.state, S.cs.reason)) {
				say_locked();
				answer(GRBL_E_LOCK);
				return 1;
			}
			/* the controller's reset (mlip-ctl reset): answered once it
			 * has left the E-stop or the limit (await_pump) */
			S.err_hold = 0;
			await_start(MLIP_CMD_RESET);
			return 1;
		}
		if (S.alarm) {
			S.alarm = 0;
			send_msg(S.ctl, "Caution: Unlocked");
		}
		S.err_hold = 0; /* and a refused line's hold */
		answer(0);
		return 1;
	case GRBL_SYS_JOG:
		return jog_line(t, len, state);
	default:
		break;
	}
	/* the rest: Idle or Alarm only (system.c) */
	if (!idle_or_alarm()) {
		answer(c.kind == GRBL_SYS_BAD ? c.code : GRBL_E_IDLE);
		return 1;
	}
	switch (c.kind) {
	case GRBL_SYS_PARAMS:
		for (int i = 0; grbl_param_line(b, sizeof(b), &S.st.g.off, S.st.g.tlo_mm, &S.ax,
		                                &S.fmt, i) > 0;
		     i++) {
			send_line(S.ctl, b);
		}
		answer(0);
		return 1;
	case GRBL_SYS_INFO:
		snprintf(b, sizeof(b), "[VER:%s.%s:mlip-grbl on %s]", GRBL_VERSION, GRBL_BUILD,
		         S.shm_name);
		send_line(S.ctl, b);
		snprintf(b, sizeof(b), "[OPT:N,%u,%d]", (unsigned)S.r->capacity, GRBL_RX_SIZE);
		send_line(S.ctl, b);
		answer(0);
		return 1;
	case GRBL_SYS_STARTUP:
		send_line(S.ctl, "$N0=");
		send_line(S.ctl, "$N1=");
		answer(0);
		return 1;
	case GRBL_SYS_HOME:
		if (S.dead) {
			send_msg(S.ctl, "the controller on %s is not responding", S.shm_name);
			answer(GRBL_E_IDLE);
			return 1;
		}
		/* the drives' homing (mlip-ctl home): every axis with a
		 * HOME_METHOD, in HOME_SEQUENCE order; answered at its end */
		await_start(MLIP_CMD_HOME);
		return 1;
	case GRBL_SYS_SLEEP:
		S.sleeping = 1;
		send_msg(S.ctl, "Sleeping");
		answer(0);
		return 1;
	case GRBL_SYS_SET:
		if (c.number == 10 && c.value >= 0 && c.value <= 255 && c.value == floor(c.value)) {
			S.fmt.mask =
			    (int)c.value; /* how reports look: this server's, not the machine's */
			answer(0);
			return 1;
		}
		if (c.number == 13 && (c.value == 0 || c.value == 1)) {
			S.fmt.inches = (int)c.value;
			grbl_refresh_wco(&S.refresh);
			answer(0);
			return 1;
		}
		/* fall through */
	case GRBL_SYS_STARTUP_SET:
	case GRBL_SYS_INFO_SET:
	case GRBL_SYS_RESTORE:
		send_msg(S.ctl,
		         "settings live in the machine configuration file (mlip-rt --config); "
		         "mlip never writes it from the network ($10 and $13, how reports "
		         "look, are the only ones set here)");
		answer(GRBL_E_INVALID_STATEMENT);
		return 1;
	default:
		answer(c.code);
		return 1;
	}
}
