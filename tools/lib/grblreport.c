/*
 * grblreport.c - mlip-grbl's view of the controller (grblsrv.h): its status
 * read each pass, Grbl's state and status report made from it, the alarms
 * and stops it did on its own, and why it holds the machine.
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

/* ---- the controller -------------------------------------------------------- */

void poll_controller(void)
{
	struct mlip_ring_status st;
	if (mlip_ring_status_read(S.r, &st) == MLIP_OK) {
		if (S.cs_ok && st.state != S.cs.state) {
			S.prev_state = S.cs.state;
		}
		grbl_acc_update(&S.acc, st.state, st.reason, st.reason_seq, st.reason_value);
		if (st.state == MLIP_STATE_PAUSED && S.cs.state != MLIP_STATE_PAUSED && S.ctl &&
		    (st.reason == MLIP_WHY_SPINDLE || st.reason == MLIP_WHY_COOLANT ||
		     st.reason == MLIP_WHY_TOOL)) {
			/* the operator's part (Hold:0 until ~) */
			char what[200];
			mlip_cli_io_message(st.reason, st.reason_value,
			                    S.have_table ? &S.table : NULL, what, sizeof(what));
			send_msg(S.ctl, "line %u: %s (~)", (unsigned)st.reason_line, what);
		}
		S.cs = st;
		S.cs_ok = 1;
		if (S.sp_bus) {
			double rpm;
			int ov;
			if (grbl_spindle_of(st.spindle_state, st.spindle_cmd_rpm,
			                    st.spindle_override, S.io.max_rpm, &rpm, &ov) == 0) {
				S.sp_rpm = rpm;
				S.sp_ov = ov;
				S.sp_bad = 0;
			} else if (!S.sp_bad) {
				/* keep what was last valid; say it once */
				S.sp_bad = 1;
				logf_("%s publishes a spindle status no controller of this layout "
				      "can "
				      "(state %u, %g rpm, override %u %%): ignored",
				      S.shm_name, (unsigned)st.spindle_state, st.spindle_cmd_rpm,
				      (unsigned)st.spindle_override);
				if (S.ctl) {
					send_msg(
					    S.ctl,
					    "the controller's spindle status is not valid (state "
					    "%u, "
					    "%g rpm, override %u %%): A:, FS and Ov show the last "
					    "valid one",
					    (unsigned)st.spindle_state, st.spindle_cmd_rpm,
					    (unsigned)st.spindle_override);
				}
			}
		}
		if (st.heartbeat != S.cs_beat) {
			S.cs_beat = st.heartbeat;
			S.cs_beat_ns = now_ns();
		}
	}
	int dead = S.cs_beat_ns == 0 || now_ns() - S.cs_beat_ns > DEAD_NS;
	if (dead && !S.dead && S.cs_beat_ns != 0) {
		logf_("the controller on %s stopped responding", S.shm_name);
		if (S.ctl) {
			char why[160];
			snprintf(
			    why, sizeof(why),
			    "the controller on %s stopped responding (mlip-rt gone or stalled): "
			    "nothing runs",
			    S.shm_name);
			alarm_push(3, why); /* what it did last is not known */
		}
	}
	S.dead = dead;
}

/* The controller's hold in force (status held_by, whoever asked: `!`,
 * mlip-ctl hold, the hold input; a stall, the bus): at rest it is latched
 * for the next program (Grbl's Hold:0) and only a resume (~) ends it. The
 * spindle coming to speed after a resume is not one, nor feed override 0
 * (see override_zero). */
int ctl_holds(void)
{
	uint32_t why = mlip_state_held_by(S.cs.held_by);
	return why != 0 && why != MLIP_WHY_SPINDLE_WAIT && why != MLIP_WHY_OVERRIDE_ZERO;
}

/* Feed override 0 (mlip-ctl override 0: Grbl's bytes go no lower than 10 %)
 * holds the program on its path, and `~` does not end it. Grbl 1.1 has no
 * state for it: Hold:0 is "Hold complete. Ready to resume." and `~`
 * "resumes a feed hold" (interface.md, realtime_cmds.md), so a sender
 * (CNCjs, UGS, bCNC) would offer cycle start, which would do nothing. It
 * stays Run: the program's cycle, at the feed the override allows (FS:0),
 * as Grbl's 10 % is a slow Run; a [MSG] says what ends it. */
int override_zero(void)
{
	return mlip_state_held_by(S.cs.held_by) == MLIP_WHY_OVERRIDE_ZERO;
}

int at_rest_state(uint32_t s)
{
	return s == MLIP_STATE_IDLE || s == MLIP_STATE_STARVED || s == MLIP_STATE_FAULT ||
	       s == MLIP_STATE_ESTOP;
}

/* The controller holds the machine until a reset or a restart. */
int locked_state(uint32_t s)
{
	return s == MLIP_STATE_FAULT || s == MLIP_STATE_ESTOP;
}

/* Nothing of ours is queued or moving. The controller publishes its status
 * at the end of the period that took our records from the ring: an empty
 * ring with the status of a period before it says idle while it pre-reads
 * them, so only a status at least two periods after the last push counts
 * (a dead controller's, or a restarted one's, counts: nothing will come). */
int quiet_controller(void)
{
	return at_rest_state(S.cs.state) && mlip_ring_count(S.r) == 0 &&
	       grbl_stream_staged(&S.st) == 0 && !S.st.end_pending &&
	       (S.dead || S.cs.heartbeat >= S.push_hb + 2 || S.cs.heartbeat < S.push_hb);
}

/* ---- state ---------------------------------------------------------------- */

const char *grbl_state(void)
{
	const struct mlip_ring_status *c = &S.cs;
	int ours_queued = grbl_stream_staged(&S.st) > 0 || mlip_ring_count(S.r) > 0 || S.st.open ||
	                  S.st.end_pending;
	int moving = c->speed_mm_s > 0.0;
	/* a soft-limit alarm while what was acknowledged still runs: Alarm once
	 * at rest (Grbl: Hold, then Alarm) */
	int settling = S.critical && !quiet_controller();
	if (!S.dead && (c->state == MLIP_STATE_HOMING || S.await_op == MLIP_CMD_HOME)) {
		return "Home"; /* $H (Grbl: also from Alarm) or mlip-ctl home */
	}
	if (S.dead || locked_state(c->state) || (S.alarm && !settling)) {
		return "Alarm";
	}
	if (S.sleeping) {
		return "Sleep";
	}
	if (S.check_mode) {
		return "Check";
	}
	if (S.door) {
		/* mlip has no door switch: the door reads closed once at rest */
		return moving || c->state == MLIP_STATE_STOPPING ? "Door:2" : "Door:0";
	}
	if (S.jog) {
		return "Jog"; /* Grbl: Jog also while a jog cancel decelerates */
	}
	switch (c->state) {
	case MLIP_STATE_HELD:
		if (c->reason == MLIP_WHY_OVERRIDE_ZERO && !S.hold_req) {
			return "Run"; /* override_zero: `~` would not end it */
		}
		return moving ? "Hold:1" : "Hold:0";
	case MLIP_STATE_STOPPING:
		return "Hold:1";
	case MLIP_STATE_PAUSED:
		return "Hold:0";
	case MLIP_STATE_RUNNING:
	case MLIP_STATE_PREREAD:
	case MLIP_STATE_DWELLING:
		/* a hold decelerates in RUNNING: Grbl's Hold:1; a program sent
		 * with a hold latched pre-reads held: Hold:0 until ~ */
		return S.hold_req || ctl_holds() ? (moving ? "Hold:1" : "Hold:0") : "Run";
	case MLIP_STATE_IDLE:
	case MLIP_STATE_STARVED:
		/* a hold at rest stays latched (Grbl 1.1: Hold:0 from Idle) */
		if (S.hold_req || S.hold_idle || ctl_holds()) {
			return "Hold:0";
		}
		if (S.err_hold) {
			/* at rest past what was acknowledged: judged on a status at
			 * least two periods after our last push (an empty ring with an
			 * older status's idle is a pre-read not yet reported) */
			return quiet_controller() && !moving ? "Hold:0" : "Run";
		}
		return ours_queued ? "Run" : "Idle";
	case MLIP_STATE_JOGGING:
		return "Jog"; /* mlip-ctl jog (a continuous jog, issue 18) */
	case MLIP_STATE_HOMING:
		return "Home"; /* mlip-ctl home */
	default:
		/* E-stop, and a state this build does not know: never "Idle" */
		return "Alarm";
	}
}

int busy_state(const char *s)
{
	return strcmp(s, "Idle") != 0 && strcmp(s, "Alarm") != 0 && strcmp(s, "Check") != 0 &&
	       strcmp(s, "Sleep") != 0;
}

void status_report(void)
{
	struct grbl_status s;
	char b[GRBL_MSG_BYTES];
	if (S.ctl == NULL || TX_CAP - S.ctl->tx_len < TX_STATUS_MIN) {
		return; /* the sender does not read: a report is not owed (interface.md) */
	}
	memset(&s, 0, sizeof(s));
	s.state = grbl_state();
	memcpy(s.mpos, S.cs.pos, sizeof(s.mpos));
	grbl_wco(&S.st.g.off, S.m.n_axes, S.z_index, S.st.g.tlo_mm, s.wco);
	if (memcmp(s.wco, S.wco_last, sizeof(s.wco)) != 0) {
		memcpy(S.wco_last, s.wco, sizeof(s.wco));
		grbl_refresh_wco(&S.refresh);
	}
	s.feed_mm_min = S.cs.speed_mm_s * 60.0;
	/* a spindle on the bus: what the controller commands (Grbl's FS shows
	 * the speed set, override in); a manual one: as the operator set it */
	double rpm = S.sp_bus ? S.sp_rpm : S.acc.rpm;
	uint32_t coolant = S.io.coolant == MLIP_IO_MODULE
	                       ? S.cs.coolant & (MLIP_COOLANT_FLOOD | MLIP_COOLANT_MIST)
	                       : S.acc.coolant;
	s.spindle_rpm = fabs(rpm);
	s.ov_feed = S.ov_feed;
	s.ov_rapid = S.ov_rapid;
	s.ov_spindle = S.sp_bus ? S.sp_ov : S.ov_spindle;
	s.busy = busy_state(s.state);
	s.bf_blocks = (int)mlip_ring_space(S.r);
	s.bf_bytes = (int)grbl_rx_available(&S.rx);
	s.line =
	    strcmp(s.state, "Run") == 0 || strncmp(s.state, "Hold", 4) == 0 ? S.cs.exec_line : 0;
	char pins[16], acc[8];
	grbl_pins(pins, sizeof(pins), S.cs.io_inputs & S.cs.io_mapped, &S.m);
	grbl_accessories(acc, sizeof(acc), rpm, coolant);
	if (S.acc.changes != S.acc_changes || strcmp(acc, S.acc_last) != 0 ||
	    s.ov_spindle != S.ovs_last) {
		S.acc_changes = S.acc.changes;
		snprintf(S.acc_last, sizeof(S.acc_last), "%s", acc);
		S.ovs_last = s.ov_spindle;
		grbl_refresh_ovr(&S.refresh); /* report.c: A: at once after a change */
	}
	s.pins = pins;
	s.accessories = acc;
	grbl_status_format(b, sizeof(b), &s, &S.ax, &S.fmt, &S.refresh);
	send_line(S.ctl, b);
}

/* Why the controller holds the machine (E-stop, a limit, a failed homing,
 * a fault) and what clears it, in mlip's words. */
void locked_why(char *why, size_t n)
{
	char fn[32];
	const struct mlip_ring_status *c = &S.cs;
	mlip_io_function_name(c->reason_field, &S.m, fn, sizeof(fn));
	if (c->state == MLIP_STATE_ESTOP && c->reason == MLIP_WHY_ESTOP) {
		snprintf(why, n,
		         "E-stop: input %s (node %u) at line %u: quick stop to every drive, the "
		         "program dropped; release it, then $X",
		         fn, (unsigned)c->reason_node, (unsigned)c->reason_line);
	} else if (c->state == MLIP_STATE_ESTOP) {
		snprintf(why, n,
		         "E-stop: the I/O module (node %u) is lost (%s): quick stop to every "
		         "drive; restart mlip-rt",
		         (unsigned)c->reason_node, mlip_state_why_name(c->reason));
	} else if (c->reason == MLIP_WHY_LIMIT) {
		snprintf(why, n,
		         "limit switch: %s (node %u) at line %u: quick stop to every drive; "
		         "move the axis off the switch, then $X",
		         fn, (unsigned)c->reason_node, (unsigned)c->reason_line);
	} else if (grbl_resettable(c->state, c->reason)) {
		snprintf(why, n,
		         "homing failed: %s (node %u, statusword 0x%04X): every axis stopped; $X, "
		         "then check the axis' HOME_* settings",
		         mlip_state_why_name(c->reason), (unsigned)c->reason_node,
		         (unsigned)c->reason_value);
	} else {
		/* Grbl has no code for a drive or bus fault: 3, "position not
		 * guaranteed", is what a stop by a fault means */
		snprintf(why, n,
		         "mlip-rt fault: %s at line %u: every axis stopped; restart mlip-rt to "
		         "clear",
		         mlip_state_why_name(c->reason), (unsigned)c->reason_line);
	}
}

void say_locked(void)
{
	char why[240];
	locked_why(why, sizeof(why));
	send_msg(S.ctl, "%s", why);
}

/* What the controller did on its own (a stop by mlip-ctl, a fault), and
 * the end of a reset. */
void follow_controller(void)
{
	int stop_done = !S.stop_ours || mlip_ring_stop_applied(S.cs.stop_seen, S.stop_ticket);
	/* a stop the controller applied that is not ours (mlip-ctl stop) */
	int foreign =
	    S.cs.stop_seen != S.stop_seen && !(S.stop_ours && S.cs.stop_seen == S.stop_ticket);
	S.stop_seen = S.cs.stop_seen;
	if (S.reset_wait && stop_done && quiet_controller() && S.cs.state != MLIP_STATE_STOPPING) {
		S.reset_wait = 0;
		S.stop_ours = 0;
		S.program_live = 0;
		resync(0);
		welcome();
	}
	jog_done();
	if (S.program_live && quiet_controller()) {
		S.program_live = 0;
	}
	if (S.hold_req && S.cs.state == MLIP_STATE_HELD) {
		S.hold_req = 0; /* the controller says held itself from now on */
	}
	if (S.hold_idle && mlip_state_held_by(S.cs.held_by) == MLIP_WHY_HOLD) {
		S.hold_idle = 0; /* so does a latched one: a resume by anyone ends it */
	}
	if (override_zero() != S.ov_zero_told && S.ctl) {
		S.ov_zero_told = override_zero();
		if (S.ov_zero_told) {
			send_msg(S.ctl, "feed override 0 %% (mlip-ctl override): nothing moves; "
			                "raise the feed override to go on (~ does not)");
		}
	}
	if ((foreign || (!S.stop_ours && S.cs.state == MLIP_STATE_STOPPING)) &&
	    (S.st.open || S.program_live || grbl_stream_staged(&S.st) > 0)) {
		/* stopped by someone else (mlip-ctl stop, a signal to mlip-rt) */
		S.alarm = 1;
		snprintf(
		    S.alarm_why, sizeof(S.alarm_why),
		    "stopped by mlip-ctl stop (or mlip-rt exiting) at line %u: the rest of the "
		    "program was dropped",
		    (unsigned)S.cs.exec_line);
		if (S.ctl) {
			/* Grbl's nearest: an abort in motion (a reset); mlip kept
			 * the position (a stop on the path) */
			alarm_push(3, S.alarm_why);
		}
		restart_at(S.cs.pos, 1);
		S.partial = 0;
		push_end_alone();
		S.program_live = 0;
	}
	int code = grbl_alarm_of(S.cs.state, S.cs.reason, S.prev_state);
	if (code == 0) {
		S.fault_told = 0;
	} else if (!S.fault_told) {
		S.fault_told = 1;
		if (S.ctl) {
			char why[240];
			locked_why(why, sizeof(why));
			alarm_push(code, why);
		}
		/* the controller drops the rest of the program up to its END */
		restart_at(S.cs.pos, 1);
		S.partial = 0;
		push_end_alone();
		S.program_live = 0;
	}
}
