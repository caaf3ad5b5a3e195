/*
 * feedtell.c - what the feeder says (feedstate.h) when the controller dies,
 * faults or waits, and what a program that did not complete leaves on.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>

#include "cli.h"
#include "feedstate.h"
#include "mlip/ipc/ring.h"
#include "mlip/machine/config.h"
#include "offsetfile.h"

/* Once the controller is at rest after a stop: the block to continue from,
 * the one after the last it completed (its status says so when idle), within
 * what we sent; else where we were. */
uint64_t rest_seq(const struct feed *f)
{
	uint64_t next = f->st.exec_seq + 1;
	if ((f->st.state == MLIP_STATE_IDLE || f->st.state == MLIP_STATE_STARVED) &&
	    next >= f->first_seq && next < f->next_seq && next <= f->n) {
		return next;
	}
	return resume_seq(f) > f->n ? f->n : resume_seq(f); /* END: its last block */
}

int controller_dead(struct feed *f)
{
	close_line(f);
	if (f->exec) {
		say(": controller stopped responding; last executed line %u (block %llu)\n",
		    resume_line(f), (unsigned long long)resume_seq(f));
	} else {
		say(": controller stopped responding before block %llu (line %u) moved\n",
		    (unsigned long long)resume_seq(f), resume_line(f));
	}
	/* a new mlip-rt starts at HOME and has run none of this program: it
	 * cannot continue it (check_continues) */
	say(": the machine stands where the controller left it, not at a known "
	    "point: bring it to a safe position, restart mlip-rt and send the program "
	    "from its start\n");
	return EXIT_CTRL_DEAD;
}

int controller_fault(struct feed *f)
{
	close_line(f);
	if (f->st.reason == MLIP_WHY_BAD_RECORD) {
		say(": controller fault: bad record %llu (line %u): %s = %.17g; the machine "
		    "comes to rest before it and runs nothing from it on (where: mlip-ctl "
		    "status); the program is NOT complete (restart mlip-rt to clear)\n",
		    (unsigned long long)f->st.reason_seq, (unsigned)f->st.reason_line,
		    mlip_rec_field_name(f->st.reason_field), f->st.reason_value);
	} else if (f->st.reason == MLIP_WHY_DRIVE) {
		char what[160];
		mlip_cli_drive_fault_text(f->st.reason_field, (int64_t)f->st.reason_value, what,
		                          sizeof(what));
		say(": controller fault: drive node %u, %s: %s, in block %llu (line %u): "
		    "every axis stopped on the path; the program is NOT complete (restart "
		    "mlip-rt to clear)\n",
		    (unsigned)f->st.reason_node,
		    mlip_drive_fault_name((mlip_drive_fault)f->st.reason_field), what,
		    (unsigned long long)f->st.reason_seq, (unsigned)f->st.reason_line);
	} else if (f->st.state == MLIP_STATE_ESTOP || f->st.reason == MLIP_WHY_LIMIT) {
		char name[24];
		say(": %s (%s, node %u) at line %u (block %llu): quick stop of every axis; "
		    "the program is NOT complete (release the input, then mlip-ctl reset)\n",
		    f->st.state == MLIP_STATE_ESTOP ? "E-stop" : "limit switch",
		    f->st.reason == MLIP_WHY_IO_LOST
		        ? "I/O module lost"
		        : mlip_io_function_name(f->st.reason_field, &f->mp, name, sizeof(name)),
		    (unsigned)f->st.reason_node, resume_line(f), (unsigned long long)resume_seq(f));
	} else {
		say(": controller fault (%s) at line %u (block %llu): the program is NOT "
		    "complete; see mlip-rt's messages and mlip-ctl status\n",
		    mlip_state_why_name(f->st.reason), resume_line(f),
		    (unsigned long long)resume_seq(f));
	}
	return EXIT_FAULT;
}

/* Held where the program's first record was taken: it never moved. */
static int unmoved(const struct feed *f)
{
	for (int k = 0; k < f->mp.n_axes; k++) {
		if (f->st.pos[k] != f->st.prog_start[k]) {
			return 0;
		}
	}
	return f->st.exec_seq == f->first_seq;
}

/* Tell the operator once per state what the machine waits for and how to
 * continue: the same words as mlip-rt's log and mlip-ctl status. */
void explain(struct feed *f)
{
	const struct mlip_ring_status *st = &f->st;
	if (st->state == MLIP_STATE_PAUSED &&
	    (st->reason == MLIP_WHY_SPINDLE || st->reason == MLIP_WHY_TOOL ||
	     st->reason == MLIP_WHY_COOLANT)) {
		f->io_wait_seq = st->reason_seq; /* the operator's part, not done yet */
	} else if (st->state != MLIP_STATE_STOPPING && st->state != MLIP_STATE_IDLE &&
	           st->state != MLIP_STATE_FAULT) {
		f->io_wait_seq = 0; /* moved on: it was done */
	}
	if (st->state == f->told_state && st->reason == f->told_why) {
		return;
	}
	f->told_state = st->state;
	f->told_why = st->reason;
	if (f->quiet) {
		return;
	}
	if (st->state == MLIP_STATE_PAUSED &&
	    (st->reason == MLIP_WHY_SPINDLE || st->reason == MLIP_WHY_TOOL ||
	     st->reason == MLIP_WHY_COOLANT)) {
		char what[200];
		mlip_cli_io_message(st->reason, st->reason_value, f->table_ok ? &f->table : NULL,
		                    what, sizeof(what));
		close_line(f);
		say(": paused at line %u, %s: %s (mlip-ctl resume)\n", (unsigned)st->reason_line,
		    mlip_state_why_name(st->reason), what);
	} else if (st->state == MLIP_STATE_PAUSED) {
		close_line(f);
		say(": paused (%s) at line %u: mlip-ctl resume continues\n",
		    mlip_state_why_name(st->reason), (unsigned)st->reason_line);
	} else if (st->state == MLIP_STATE_HELD && st->reason == MLIP_WHY_HOLD && unmoved(f)) {
		/* never moved: a hold latched at rest before it came (Grbl 1.1's
		 * Hold:0 from Idle), not a program that is stuck */
		close_line(f);
		say(": held before its first move: a hold was latched while the machine was idle "
		    "(mlip-ctl hold, the hold input, Grbl's !); to start: mlip-ctl resume (or "
		    "cycle "
		    "start)\n");
	} else if (st->state == MLIP_STATE_HELD && st->reason == MLIP_WHY_HOLD) {
		close_line(f);
		say(": held (feed hold) at line %u: mlip-ctl resume (or cycle start) continues\n",
		    (unsigned)st->exec_line);
	} else if (st->state == MLIP_STATE_HELD && st->reason == MLIP_WHY_OVERRIDE_ZERO) {
		close_line(f);
		say(": held at line %u: the feed override is 0 %%: raise it to continue "
		    "(mlip-ctl override PCT); a resume does not end it\n",
		    (unsigned)st->exec_line);
	} else if (st->state == MLIP_STATE_HELD && st->reason == MLIP_WHY_STALL) {
		close_line(f);
		say(": stall: the controller missed %.0f periods; held at rest at the last "
		    "setpoint sent, line %u; to continue: mlip-ctl resume\n",
		    st->reason_value, (unsigned)st->exec_line);
	}
}

/* The last event of kind kd (0 spindle, 1 tool, 2 coolant) the machine
 * completed: 1 with it in *at, 0 none of ours, -1 not known (the history
 * does not reach back that far). *waiting: the one it was paused at for the
 * operator when it stopped (done or not: only the operator knows). */
static int io_done(const struct feed *f, int kd, uint64_t done, int *at, int *waiting)
{
	uint64_t n = f->ioev_n[kd], lo = n > IO_HIST ? n - IO_HIST : 0;

	*waiting = -1;
	for (uint64_t i = n; i-- > lo;) {
		uint64_t seq = f->ioev[kd][i % IO_HIST].seq;
		if (seq == f->io_wait_seq) {
			*waiting = (int)(i % IO_HIST);
			continue;
		}
		if (seq <= done) {
			*at = (int)(i % IO_HIST);
			return 1;
		}
	}
	return lo > 0 ? -1 : 0;
}

/* A program that did not complete may leave the spindle turning, coolant
 * on, or another tool in the spindle: say so (whatever -q says), and keep
 * the tool the machine holds in the offsets file (the work offsets as they
 * were: the program's changes to them are not written). */
void io_after_stop(struct feed *f, const struct mlip_machine *m)
{
	static const char *const kind[3] = {"spindle", "tool change", "coolant"};
	uint64_t done = f->exec;
	int at, waiting, tool = -1, unsure = 0;

	for (int kd = 0; kd < 3; kd++) {
		int r = io_done(f, kd, done, &at, &waiting);
		if (waiting >= 0) {
			char what[200];
			mlip_cli_io_message(kd == 0   ? MLIP_WHY_SPINDLE
			                    : kd == 1 ? MLIP_WHY_TOOL
			                              : MLIP_WHY_COOLANT,
			                    f->ioev[kd][waiting].value,
			                    f->table_ok ? &f->table : NULL, what, sizeof(what));
			say(": stopped while the machine waited at line %u for the %s (%s): "
			    "check whether it was done\n",
			    (unsigned)f->ioev[kd][waiting].line, kind[kd], what);
			unsure |= kd == 1;
		}
		if (r < 0) {
			say(": the %s's state is not known: check it\n", kind[kd]);
			unsure |= kd == 1;
			continue;
		}
		if (r == 0 || waiting >= 0) {
			continue;
		}
		double v = f->ioev[kd][at].value;
		unsigned line = f->ioev[kd][at].line;
		if (kd == 0 && v != 0) {
			say(": the spindle turns since line %u (%g rpm %s): the program did "
			    "not stop it\n",
			    line, fabs(v), v > 0 ? "clockwise" : "counter-clockwise");
		} else if (kd == 2 && v != 0 && f->io.coolant == MLIP_IO_MODULE) {
			/* the module's outputs: the controller switched them off */
			say(": coolant on since line %u: switched off by the stop\n", line);
		} else if (kd == 2 && v != 0) {
			say(": coolant on since line %u: the program did not stop it\n", line);
		} else if (kd == 1) {
			tool = (int)v;
			say(": tool %d is in the spindle since line %u\n", tool, line);
		}
	}
	if ((tool >= 0 || unsure) && f->offsets != NULL) {
		struct mlip_gcode_offsets o = f->prog.offsets_start;
		o.tool = unsure ? 0 : tool; /* not known: no tool, G43 then needs an H */
		if (mlip_offsets_save(&f->offsets_file, m, &o, prog_name, stderr) == 0) {
			say(": %s: TOOL %d written%s\n", f->offsets, (int)o.tool,
			    unsure ? " (not known: say which with mlip-offsets --set \"TOOL n\")"
			           : "");
		}
	} else if (tool >= 0 || unsure) {
		say(": no --offsets: the next program does not know which tool is in the "
		    "spindle\n");
	}
}
