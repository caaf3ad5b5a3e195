/*
 * grblfeed.c - mlip-grbl's streaming (grblsrv.h): G-code and $J= lines
 * checked and staged into the ring's records (grblstream.h), the programs
 * they make cut where they must be (M2/M30, a refused line, a quiet
 * sender), resets, jogs and their cancel.
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

void beat(void)
{
	S.fa.heartbeat++;
	S.fa.heartbeat_ns = now_ns();
	mlip_ring_feeder_write(S.r, &S.fa);
}

/* Staged records into the ring, as many as fit. */
void push_records(void)
{
	if (S.port_open && grbl_stream_staged(&S.st) > 0 && S.fa.pid == 0) {
		S.fa.pid = (int32_t)getpid(); /* feeding again (after a quiet pre-read) */
		beat();
	}
	while (S.port_open && grbl_stream_staged(&S.st) > 0) {
		uint32_t n = grbl_stream_staged(&S.st), got = 0;
		const struct mlip_ring_rec *recs = grbl_stream_peek(&S.st);
		if (mlip_ring_port_push_n(&S.tx, recs, n, &got) != MLIP_OK || got == 0) {
			return;
		}
		for (uint32_t i = 0; i < got; i++) {
			S.pushed_seq = recs[i].type == MLIP_REC_END ? 0 : recs[i].seq;
		}
		S.program_live = 1;
		S.push_hb = S.cs.heartbeat;
		grbl_stream_take(&S.st, got);
	}
}

/* An END alone (after a stop: the controller drops the stopped program's
 * records up to it). */
void push_end_alone(void)
{
	struct mlip_ring_rec rec;
	uint32_t got = 0;
	if (!S.port_open || S.pushed_seq == 0) {
		return;
	}
	mlip_ring_rec_end(&rec, S.pushed_seq + 1, S.lineno);
	mlip_ring_port_push_n(&S.tx, &rec, 1, &got);
	if (got == 1) {
		S.pushed_seq = 0;
		S.push_hb = S.cs.heartbeat;
	}
}

/* ---- resets and welcome -------------------------------------------------------- */

void welcome(void)
{
	send_raw(S.ctl, "\r\n", 2);
	send_line(S.ctl, GRBL_WELCOME);
	send_msg(S.ctl, "mlip-grbl: mlip on %s, %d axes, %s", S.shm_name, S.m.n_axes,
	         S.m.smooth ? "strategy smooth" : "planner look-ahead");
	if (S.dead || locked_state(S.cs.state) || S.alarm) {
		send_msg(S.ctl, "'$H'|'$X' to unlock");
	}
	memset(&S.refresh, 0, sizeof(S.refresh));
	S.lineno = 0;
	S.ln_programs = S.st.programs;
}

/* Where the machine stands, for a new program. */
void restart_at(const double *pos, int keep_modes)
{
	grbl_stream_restart(&S.st, pos, keep_modes);
	/* what was queued and dropped never ran: the spindle and coolant are
	 * what the machine does (an M5 then still asks the operator) */
	grbl_stream_machine_io(&S.st, S.acc.rpm, S.acc.coolant);
}

void resync(int keep_modes)
{
	restart_at(S.cs.pos, keep_modes);
	S.partial = 0;
	if (!keep_modes) {
		memset(S.wco_last, 0, sizeof(S.wco_last));
	}
}

void soft_reset(void)
{
	grbl_rx_reset(&S.rx);
	S.status_req = 0;
	S.check_mode = 0;
	S.err_hold = 0;
	S.hold_idle = 0;
	S.hold_req = 0;
	S.sp_stopped = 0;
	S.door = 0;
	S.jog = 0;
	S.jog_cancel = 0;
	S.critical = 0;
	if (S.sleeping) {
		S.alarm = 1; /* Grbl: out of sleep into alarm */
		snprintf(S.alarm_why, sizeof(S.alarm_why), "after sleep ($SLP)");
	}
	S.sleeping = 0;
	S.partial = 0;
	/* overrides back to 100 % (Grbl's reset) */
	if (S.ov_feed != 100) {
		S.ov_feed = 100;
		S.ov_post = 100;
	}
	S.ov_rapid = S.ov_spindle = 100;
	if (S.sp_bus && S.sp_ov != 100) {
		S.sp_post = 100; /* the controller's spindle override too */
	}
	/* a program of ours still open in the ring (records given, no END:
	 * pushed_seq, the stream open) is stopped too, even at rest between a
	 * sender's lines: without the stop and its END the controller would
	 * wait for the rest of that program for ever */
	int ours_open = S.pushed_seq != 0 || S.st.open;
	if ((!quiet_controller() || ours_open) && !locked_state(S.cs.state)) {
		stop_post();
		S.reset_wait = 1;
		restart_at(S.cs.pos, 0);
		push_end_alone();
		return;
	}
	if (ctl_holds() && !locked_state(S.cs.state)) {
		/* Grbl 1.1's reset leaves Hold:0 for Idle: the hold latched at
		 * rest ends (a resume at rest moves nothing) */
		cmd_push(MLIP_CMD_RESUME, 0);
	}
	resync(0);
	welcome();
}

/* ---- jogging -------------------------------------------------------------------- */

/* Grbl's jog ($J=, jogging.md) as a program of its own: each $J= line is a
 * G1 move at its own F through the same planner and limits as a program
 * (the G-code reader runs it with the modal state left as it was), queued
 * behind the last, and given to the controller at once (no waiting for more
 * look-ahead); the program ends as soon as the controller has run it. A
 * cancel (0x85, a feed hold, the sender gone) is the controller's stop on
 * the path: it decelerates at the acceleration limit and drops what is
 * queued. This is the one mapping to move onto the controller's own jog
 * (issue 18: a continuous jog with a dead-man) when it lands: jog_line,
 * jog_cancel and jog_done are all that know how a jog runs. */
void jog_cancel(const char *why)
{
	if (!S.jog || S.jog_cancel) {
		return;
	}
	if (S.verbose) {
		logf_("jog cancelled (%s)", why);
	}
	S.jog_cancel = 1;
	if (quiet_controller() && !S.st.open) {
		return; /* it has ended at rest already: jog_done says Idle */
	}
	stop_post();
	restart_at(S.cs.pos, 1);
	S.partial = 0;
	push_end_alone();
}

/* The jog has ended (run to its end, or cancelled and at rest). */
void jog_done(void)
{
	if (!S.jog || S.st.open || S.st.end_pending || grbl_stream_staged(&S.st) > 0 ||
	    !quiet_controller() || S.cs.state == MLIP_STATE_STOPPING) {
		return;
	}
	if (S.jog_cancel && S.stop_ours && !mlip_ring_stop_applied(S.cs.stop_seen, S.stop_ticket)) {
		return;
	}
	if (S.jog_cancel) {
		S.stop_ours = 0;
		resync(1); /* where it stopped, on the jog's path */
	}
	S.jog = 0;
	S.jog_cancel = 0;
	S.program_live = 0;
}

/* A target beyond the soft limits: Grbl's ALARM:2 (limits.c: the line is
 * not run, not answered, and nothing is taken until a reset; after it the
 * alarm stays until $X). The machine runs what was acknowledged and stops
 * at rest there. */
void soft_limit_alarm(const struct mlip_gcode_error *e)
{
	send_msg(S.ctl, "line %u col %u: %s", (unsigned)e->line, (unsigned)e->col, e->msg);
	S.alarm = 1;
	S.critical = 1;
	snprintf(S.alarm_why, sizeof(S.alarm_why), "soft limit (line %u)", (unsigned)e->line);
	alarm_push(2, NULL);
	send_msg(S.ctl, "Reset to continue");
}

void say_error(const struct mlip_gcode_error *e, int code)
{
	if (e->col) {
		send_msg(S.ctl, "line %u col %u: %s", (unsigned)e->line, (unsigned)e->col, e->msg);
	} else {
		send_msg(S.ctl, "line %u: %s", (unsigned)e->line, e->msg);
	}
	answer(code);
}

/* A refused line in a stream: the machine runs what was acknowledged and
 * stops at rest there; nothing more is taken until ~ or reset. A line
 * refused with nothing of ours queued and no line behind it (typed in a
 * console: the sender waits for its answer) holds nothing: the next line
 * is taken, as Grbl takes it. */
void refuse_hold(void)
{
	if (S.st.open || S.program_live || grbl_stream_staged(&S.st) > 0 || S.rx.bytes > 0 ||
	    S.rx.marks > 0) {
		S.err_hold = 1;
	}
	grbl_stream_end(&S.st);
}

void notices_since(uint32_t before)
{
	for (uint32_t k = before; k < S.st.g.n_notices; k++) {
		const struct mlip_gcode_notice *n = &S.st.g.notices[k];
		send_msg(S.ctl, "line %u: %s %s", (unsigned)n->first_line, n->word,
		         mlip_gcode_notice_text(n));
	}
}

/* A G-code line: 1 answered, 0 waits (its records do not fit yet, or the
 * controller is being reset). */
int gcode_line(const char *t, size_t len)
{
	struct mlip_gcode_error e;
	uint32_t nn = S.st.g.n_notices;
	if (S.dead) {
		send_msg(S.ctl, "the controller on %s is not responding: nothing runs", S.shm_name);
		answer(GRBL_E_LOCK);
		return 1;
	}
	if (locked_state(S.cs.state) || S.alarm || S.sleeping) {
		if (locked_state(S.cs.state)) {
			say_locked();
		} else {
			send_msg(S.ctl, "alarm: %s; reset (ctrl-x) or $X first",
			         S.sleeping ? "sleeping" : S.alarm_why);
		}
		answer(GRBL_E_LOCK);
		return 1;
	}
	if (S.jog) {
		send_msg(S.ctl,
		         "jogging: G-code waits until the jog has ended (or 0x85 cancels it)");
		answer(GRBL_E_LOCK);
		return 1;
	}
	if (S.check_mode) {
		if (grbl_stream_dry(&S.st, t, len, S.lineno, &e) != MLIP_OK) {
			if (grbl_error_travel(&e)) {
				soft_limit_alarm(&e); /* "soft limits still work" in check mode */
				return 1;
			}
			say_error(&e, grbl_error_code(&e, 0));
			return 1;
		}
		notices_since(nn);
		answer(0);
		return 1;
	}
	if (!S.st.open && grbl_stream_staged(&S.st) == 0) {
		/* a new program: a stop from now on is meant for it (the
		 * controller refuses it, were it still to start) */
		S.fa.stop_base = mlip_ring_stop_count(S.r);
		if (quiet_controller() && !S.program_live) {
			resync(1); /* it starts where the machine stands now */
		}
	}
	if (grbl_stream_check(&S.st, t, len, S.lineno, &e) != MLIP_OK) {
		if (grbl_error_travel(&e)) {
			soft_limit_alarm(&e);
		} else {
			say_error(&e, grbl_error_code(&e, 0));
		}
		refuse_hold();
		return 1;
	}
	if (S.take_producer() != 0) {
		answer(GRBL_E_LOCK);
		return 1;
	}
	int rc = grbl_stream_line(&S.st, t, len, S.lineno, &e);
	if (rc < 0) { /* cannot happen: checked above */
		say_error(&e, grbl_error_code(&e, 0));
		refuse_hold();
		return 1;
	}
	notices_since(nn);
	if (rc == 0) {
		S.partial = 1;
		return 0;
	}
	if (grbl_stream_ended(&S.st)) {
		send_msg(S.ctl, "Pgm End");
	}
	answer(0);
	return 1;
}

/* A $J= line: 1 answered, 0 waits (a cancel still decelerating). */
int jog_line(const char *t, size_t len, const char *state)
{
	struct mlip_gcode_error e;
	if (S.jog_cancel) {
		return 0; /* Grbl takes no line until the cancel has ended */
	}
	if (S.dead) {
		send_msg(S.ctl, "the controller on %s is not responding: nothing runs", S.shm_name);
		answer(GRBL_E_IDLE);
		return 1;
	}
	if (strcmp(state, "Idle") != 0 && strcmp(state, "Jog") != 0) {
		if (strcmp(state, "Alarm") == 0) {
			send_msg(S.ctl, "alarm: no jog until it is cleared ($X, or a restart of "
			                "mlip-rt for a fault)");
		}
		answer(GRBL_E_IDLE); /* jogging.md: only in Idle or Jog */
		return 1;
	}
	int first = !S.jog;
	if (first) {
		/* a jog program of its own, from where the machine stands */
		S.fa.stop_base = mlip_ring_stop_count(S.r);
		resync(1);
	}
	if (grbl_stream_check(&S.st, t, len, S.lineno, &e) != MLIP_OK) {
		/* not run, and nothing else changes (no hold: jogging.md) */
		say_error(&e, grbl_error_code(&e, 1));
		return 1;
	}
	if (S.take_producer() != 0) {
		answer(GRBL_E_IDLE);
		return 1;
	}
	S.jog = 1;
	int rc = grbl_stream_line(&S.st, t, len, S.lineno, &e);
	if (rc < 0) { /* cannot happen: checked above */
		say_error(&e, grbl_error_code(&e, 1));
		return 1;
	}
	if (rc == 0) {
		S.partial = 1;
		return 0;
	}
	/* at once: the smoothing filter's rest, and the controller told to
	 * start with what it has (quiet_end) */
	grbl_stream_flush(&S.st, 0);
	answer(0);
	return 1;
}

/* The sender went quiet: what it sent must not wait for lines that may not
 * come. The smoothing filter gives what it holds (the program goes on).
 * A controller still pre-reading is told "nothing more for now" (the
 * feeder area's pid 0, as a feeder that left): it starts with what it has,
 * and lines that come later continue the same program, so a sender that
 * pauses for a while (CNCjs does, while it draws) costs no stop. A program
 * whose controller is at rest waiting for more ends there (END): it is
 * complete, the controller idle; not in an operator's hold, whose end the
 * quiet counts from. A file streamed without pauses is one program, as
 * mlip-feed runs it. */
void quiet_end(void)
{
	if (in_hold()) {
		/* the operator's hold (`!`): the controller waits for the
		 * operator, not for the sender, and the program stays open (an
		 * M3 typed before it keeps turning, for 0x9E to stop and
		 * restore); the quiet that ends it counts from the hold's end */
		S.held_ns = now_ns();
	}
	if (S.partial) {
		return;
	}
	if (S.st.end_pending) {
		grbl_stream_flush(&S.st, 0);
		return;
	}
	if (S.err_hold && S.st.open) {
		grbl_stream_end(&S.st);
		return;
	}
	if (grbl_rx_pending(&S.rx) || (!S.jog && now_ns() - S.last_rx_ns < S.quiet_ns)) {
		return; /* a jog runs at once (jogging.md's joystick: no waiting for more) */
	}
	if (grbl_stream_holding(&S.st)) {
		if (S.verbose) {
			logf_("quiet: the smoothing filter gives its rest (line %u)",
			      (unsigned)S.lineno);
		}
		grbl_stream_flush(&S.st, 0);
	}
	if (!S.st.open || S.st.end_pending || grbl_stream_staged(&S.st) > 0) {
		return;
	}
	if (S.cs.state == MLIP_STATE_PREREAD && S.fa.pid != 0) {
		if (S.verbose) {
			logf_("quiet, controller pre-reading: it starts with what it has (line %u)",
			      (unsigned)S.lineno);
		}
		S.fa.pid = 0; /* beat() publishes it */
	} else if ((S.cs.state == MLIP_STATE_STARVED || S.cs.state == MLIP_STATE_IDLE) &&
	           (!S.jog || mlip_ring_count(S.r) == 0) && now_ns() - S.held_ns >= S.quiet_ns) {
		/* (a jog's records just pushed may not be taken yet: the
		 * controller is idle until its next period) */
		if (S.verbose) {
			logf_("quiet, controller %s: program ends at line %u",
			      mlip_ctl_state_name(S.cs.state), (unsigned)S.lineno);
		}
		grbl_stream_end(&S.st);
	}
}
