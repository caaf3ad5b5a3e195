/*
 * feedsend.c - the feeder's loop (feedstate.h): wait for an idle
 * controller, push the records, follow them to rest; stops, signals.
 */
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"
#include "feedstate.h"
#include "mlip/ipc/ring.h"
#include "rt.h"

/* Relative sleep; a signal ends it early (no SA_RESTART), the caller looks at
 * got_signal. clock_nanosleep returns its error, it does not set errno. */
static void sleep_ns(long ns)
{
	struct timespec ts = {0, ns};

	(void)clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, NULL);
}

/* After a stop, the END record alone: the controller drops a stopped
 * program's records up to its END (rt.h), and without it would also drop the
 * records of a continuation (--start-seq) sent later. It never moves: the
 * controller is discarding when it arrives. */
static void push_end(struct feed *f)
{
	struct mlip_ring_rec rec;

	if (f->end_pushed || f->tx.r == NULL) {
		return; /* nothing sent yet: no port */
	}
	mlip_ring_rec_end(&rec, f->n + 1, f->end_line);
	rec.flags |= f->mpct ? MLIP_REC_MPCT : 0u;
	uint32_t got = 0;
	mlip_ring_port_push_n(&f->tx, &rec, 1, &got);
	if (got == 1) { /* full: the discard frees room */
		f->end_pushed = 1;
		f->next_seq = f->n + 2;
	}
}

/* After a stop: keep beating until the controller is idle and our END is in
 * (or t_max passes, or another signal arrives). 0 at rest, -1 dead, 1 time-out.
 * A stop that reached an idle controller before it took our first record is
 * latched for our program (our stop_base is older): it never starts. */
static int wait_rest(struct feed *f, uint64_t t_max)
{
	uint64_t t0 = mlip_now_ns();
	sig_atomic_t sig_seen = n_signals;

	for (;;) {
		push_end(f);
		beat(f);
		if (poll_controller(f) != 0) {
			return -1;
		}
		if ((f->st.state == MLIP_STATE_IDLE || f->st.state == MLIP_STATE_FAULT) &&
		    f->end_pushed) {
			return 0;
		}
		if (mlip_now_ns() - t0 > t_max || n_signals != sig_seen) {
			return 1;
		}
		progress(f, 0);
		sleep_ns(WAIT_SLEEP_NS);
	}
}

/* SIGINT/SIGTERM/SIGHUP/SIGQUIT: stop pushing, stop the machine on its path,
 * report. */
static int interrupted(struct feed *f)
{
	int sig = got_signal, w;
	int code = 128 + sig;
	uint64_t t0;
	uint32_t ticket;

	close_line(f);
	if (f->next_seq == f->first_seq) {
		say(": interrupted by %s: nothing was sent\n", mlip_cli_signal_name(sig));
		return code;
	}
	say(": %s: stopping the machine on the path\n", mlip_cli_signal_name(sig));
	/* the stop counter: never refused, never behind mlip-ctl's mailbox */
	ticket = mlip_ring_stop_post(f->r);
	leave(f); /* nothing more will come: the rest of the program is dropped */
	/* once the controller has applied the stop, "idle" means at rest */
	t0 = mlip_now_ns();
	while (mlip_now_ns() - t0 < CMD_WAIT_NS) {
		if (poll_controller(f) != 0 || mlip_ring_stop_applied(f->st.stop_seen, ticket)) {
			break;
		}
		beat(f);
		sleep_ns(FULL_SLEEP_NS);
	}
	w = wait_rest(f, STOP_WAIT_NS);
	if (w < 0) {
		say(": interrupted: stop posted, but the controller stopped "
		    "responding\n");
	} else if (w > 0) {
		say(": interrupted: stop posted; controller still %s at line %u: check "
		    "mlip-ctl status\n",
		    mlip_ctl_state_name(f->st.state), resume_line(f));
	} else {
		uint64_t next = rest_seq(f);
		say(": interrupted: machine stopped on the path at line %u (block %llu of "
		    "%llu); resume with --start-seq %llu\n",
		    line_of(f, next), (unsigned long long)next, (unsigned long long)f->n,
		    (unsigned long long)next);
	}
	return code;
}

static int operator_stop(struct feed *f)
{
	int w;

	leave(f); /* no more records: pid 0 says so */
	/* wait for rest so the line reported is where the machine is */
	w = wait_rest(f, STOP_WAIT_NS);

	close_line(f);
	if (w < 0) {
		return controller_dead(f);
	}
	if (f->exec == 0 && f->st.reason == MLIP_WHY_STOP_EARLY) {
		say(": %s: mlip-ctl stop came before the program started: the controller "
		    "dropped it, nothing moved\n",
		    f->path);
		return EXIT_OPERATOR;
	}
	if (f->exec == 0 && f->st.reason == MLIP_WHY_NOT_HOMED) {
		char axes[2 * MLIP_MAX_AXES + 1] = "";
		for (int k = 0, n = 0; k < f->mp.n_axes; k++) {
			if (!((f->st.homed >> k) & 1u)) {
				n += snprintf(axes + n, sizeof(axes) - (size_t)n, "%s%c",
				              n ? " " : "", f->mp.axis[k].letter);
			}
		}
		say(": %s: refused by the controller: HOMING_REQUIRED and not every axis is "
		    "homed (not homed: %s): mlip-ctl home first; nothing moved\n",
		    f->path, axes);
		return EXIT_FAIL;
	}
	if (f->st.reason == MLIP_WHY_PROBE_NO_TRIP || f->st.reason == MLIP_WHY_PROBE_AT_START ||
	    f->st.reason == MLIP_WHY_PROBE_OFF_AT_START || f->st.reason == MLIP_WHY_PROBE_INPUT) {
		/* a probe error ends the program at rest (LinuxCNC) */
		say(": %s:%u: %s: the program stopped there, at rest\n", f->path,
		    (unsigned)f->st.reason_line, mlip_state_why_name(f->st.reason));
		return EXIT_FAULT;
	}
	uint64_t next = rest_seq(f);
	say(": program stopped on the path at line %u (block %llu of %llu): mlip-ctl "
	    "stop, or mlip-rt was told to exit\n",
	    line_of(f, next), (unsigned long long)next, (unsigned long long)f->n);
	return EXIT_OPERATOR;
}

/* Fill up to max records from f->next_seq on. */
static uint32_t fill(struct feed *f, struct mlip_ring_rec *recs, uint32_t max)
{
	uint32_t k = 0;
	uint64_t seq = f->next_seq;

	for (; k < max && seq <= f->n + 1; k++, seq++) {
		if (seq <= f->n) {
			struct mlip_block b;
			if (next_block(f, &b) < 0) {
				break; /* the caller sees fewer records, then the stream's error */
			}
			mlip_ring_rec_from_block(&recs[k], &b, seq);
			if (b.kind >= MLIP_BLOCK_SPINDLE && b.kind <= MLIP_BLOCK_COOLANT) {
				int kd = b.kind - MLIP_BLOCK_SPINDLE;
				uint64_t i = f->ioev_n[kd]++ % IO_HIST;
				f->ioev[kd][i].seq = seq;
				f->ioev[kd][i].line = b.line;
				f->ioev[kd][i].value = b.value;
			}
		} else {
			mlip_ring_rec_end(&recs[k], seq, f->end_line);
		}
		recs[k].flags |= f->mpct ? MLIP_REC_MPCT : 0u;
	}
	return k;
}

/* --start-seq N continues only the block after the last one the controller
 * completed: from anywhere else the first move would cut a straight line
 * across the part to block N's end (the controller drops it too). */
static int check_continues(struct feed *f)
{
	uint64_t done = f->st.exec_seq;
	if (f->first_seq == done + 1 && done > 0) {
		return -1;
	}
	if (done == 0) {
		say(": --start-seq %llu: the controller on %s has run no block of a program "
		    "(state %s): it cannot continue one; nothing was sent (send the program "
		    "from its start)\n",
		    (unsigned long long)f->first_seq, f->shm.name,
		    mlip_ctl_state_name(f->st.state));
	} else {
		say(": --start-seq %llu: the controller on %s completed block %llu (line %u) "
		    "last, so only --start-seq %llu continues it; nothing was sent\n",
		    (unsigned long long)f->first_seq, f->shm.name, (unsigned long long)done,
		    (unsigned)f->st.exec_line, (unsigned long long)done + 1);
	}
	return EXIT_FAIL;
}

/* Wait for an idle controller with an empty ring before the first record:
 * our records must never be appended to another program's. The ring count
 * is live but the status is published once a period, so "idle and empty" must
 * hold again in a status written after the empty ring was seen: then its
 * blocks_consumed counts every earlier record and taken() counts only ours. */
static int wait_start(struct feed *f)
{
	uint64_t t0 = mlip_now_ns(), empty_at = 0;
	uint32_t count;
	int noted = 0, empty = 0;

	/* no feeder heartbeat yet: the area still describes the previous feeder
	 * (gone), which a controller finishing its program may be waiting on;
	 * the producer lock already keeps other feeders out */
	for (;;) {
		if (got_signal) {
			return interrupted(f);
		}
		if (mlip_ring_stop_after(mlip_ring_stop_count(f->r), f->fa.stop_base)) {
			say(": %s: mlip-ctl stop came while the program was checked or "
			    "waited: nothing was sent\n",
			    f->path);
			return EXIT_OPERATOR;
		}
		count = mlip_ring_count(f->r); /* before the status: see above */
		if (poll_controller(f) != 0) {
			say(": controller stopped responding while we waited for it "
			    "to be idle: nothing was sent\n");
			return EXIT_CTRL_DEAD;
		}
		if (f->st.state == MLIP_STATE_FAULT || f->st.state == MLIP_STATE_ESTOP) {
			say(": controller on %s is in %s (%s): nothing was sent; %s\n", f->shm.name,
			    mlip_ctl_state_name(f->st.state), mlip_state_why_name(f->st.reason),
			    f->st.state == MLIP_STATE_ESTOP || f->st.reason == MLIP_WHY_LIMIT
			        ? "release the input, then mlip-ctl reset"
			        : "see mlip-rt's messages (restart it to clear the fault)");
			return EXIT_FAIL;
		}
		/* idle, or starved (a feeder died): our records continue or replace
		 * that program */
		if ((f->st.state == MLIP_STATE_IDLE || f->st.state == MLIP_STATE_STARVED) &&
		    count == 0) {
			if (empty && f->st.heartbeat > empty_at) {
				return f->first_seq == 1 ? -1 : check_continues(f); /* go */
			}
			if (!empty) {
				empty = 1;
				empty_at = f->st.heartbeat;
			}
		} else {
			empty = 0;
		}
		if (!noted && mlip_now_ns() - t0 > IDLE_NOTE_NS) {
			noted = 1;
			if (!f->quiet) {
				say(": waiting for the controller to be idle (state %s, line %u, "
				    "%u records queued): a previous program is still running; "
				    "mlip-ctl stop ends it\n",
				    mlip_ctl_state_name(f->st.state), (unsigned)f->st.exec_line,
				    (unsigned)count);
			}
		}
		sleep_ns(WAIT_SLEEP_NS);
	}
}

int run(struct feed *f)
{
	static struct mlip_ring_rec recs[BATCH];
	uint64_t total = f->n + 1;
	uint32_t k, got;
	int rc;

	rc = wait_start(f);
	if (rc >= 0) {
		return rc;
	}
	rc = start_moved(f);
	if (rc != 0) {
		return rc;
	}
	if (f->n == 0) {
		/* nothing for the machine to do (a touch-off, G92, or MDI modes):
		 * checked from where it stands at rest; the caller keeps the effect */
		if (!f->quiet) {
			say(": %s: no motion: %s\n", f->path,
			    f->mdi ? "modes and offsets only" : "only the offsets change");
		}
		return EXIT_DONE;
	}
	/* the producer's view, taken now that we hold the producer lock */
	if (mlip_ring_port_open(&f->tx, f->r, 1) != MLIP_OK) {
		say(": %s: the ring's header is not valid any more: restart mlip-rt\n",
		    f->shm.name);
		return EXIT_FAIL;
	}
	f->consumed0 = f->st.blocks_consumed;
	f->exec0 = f->st.exec_seq;
	f->fa.pid = (int32_t)getpid();
	f->fa.total_blocks = total;
	f->t_start = mlip_now_ns();
	f->t_report = f->t_start; /* first line after one interval */
	for (;;) {
		beat(f);
		if (got_signal) {
			return interrupted(f);
		}
		if (poll_controller(f) != 0) {
			return controller_dead(f);
		}
		if (f->st.state == MLIP_STATE_FAULT || f->st.state == MLIP_STATE_ESTOP) {
			return controller_fault(f);
		}
		explain(f);
		/* done: END executed (exec_seq = its seq) and at rest; taken() >= our
		 * blocks rules out an exec_seq left by an equally long previous program */
		if (f->end_pushed && f->st.state == MLIP_STATE_IDLE && f->st.exec_seq == total &&
		    taken(f) >= f->n + 1 - f->first_seq) {
			break;
		}
		/* stopped by someone else: STOPPING, or IDLE once ours had started
		 * (the controller reports RUNNING from its first record on) */
		if (f->st.state == MLIP_STATE_STOPPING ||
		    (f->st.state == MLIP_STATE_IDLE && taken(f) > 0)) {
			return operator_stop(f);
		}
		got = 0;
		uint32_t apart = 0;
		if (mlip_ring_port_count(&f->tx, &k, &apart) != MLIP_OK) {
			close_line(f);
			say(": %s is corrupted: its tail is %u records from our head, beyond "
			    "the capacity %u (another process writes into it?); stopping the "
			    "feed: mlip-ctl stop, then restart mlip-rt\n",
			    f->shm.name, (unsigned)apart, (unsigned)f->tx.capacity);
			return EXIT_FAULT;
		}
		if (f->rate > 0.0) {
			/* a throttled feeder (tests of underruns): no more than rate x
			 * elapsed records so far */
			double allowed = f->rate * (double)(mlip_now_ns() - f->t_start) * 1e-9 -
			                 (double)f->pushed;
			k = allowed < 1.0 ? 0 : (allowed < (double)k ? (uint32_t)allowed : k);
		}
		if (!f->end_pushed && k > 0) {
			k = fill(f, recs, k < BATCH ? k : BATCH);
			if (f->prog.done == 1) {
				mlip_ring_port_push_n(&f->tx, recs, k, &got);
				f->next_seq += got;
				leave(f); /* no END: the controller stops at rest after the last */
				close_line(f);
				say(": %s: %s; the machine stops at rest after block %llu: "
				    "continue with --start-seq %llu once the file is right\n",
				    f->path, f->prog.msg, (unsigned long long)(f->next_seq - 1),
				    (unsigned long long)f->next_seq);
				return EXIT_FAIL;
			}
			mlip_ring_port_push_n(&f->tx, recs, k, &got); /* all k: only we add */
			f->next_seq += got;
			f->pushed += got;
			if (f->next_seq > total) {
				f->end_pushed = 1;
				beat(f); /* publish program_end at once */
			}
		}
		progress(f, 0);
		if (f->end_pushed) {
			sleep_ns(WAIT_SLEEP_NS);
		} else if (got < BATCH) {
			sleep_ns(FULL_SLEEP_NS); /* ring full: back-pressure */
		}
	}
	if (f->tty) {
		progress(f, 1); /* leave the bar at 100 % */
	}
	close_line(f);
	if (!f->quiet) {
		say(": %s: %llu blocks, %.3f s, program complete\n", f->path,
		    (unsigned long long)(f->n - f->first_seq + 1),
		    (double)(mlip_now_ns() - f->t_start) / 1e9);
	}
	return EXIT_DONE;
}
