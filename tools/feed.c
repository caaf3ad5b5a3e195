/*
 * feed.c - the feeder (feed.h) of mlip-feed and mlip-ctl mdi: send a G-code
 * program, or MDI lines, to a running mlip-rt through the ring of its
 * shared-memory segment (mlip/ipc/ring.h) and follow it to the end.
 *
 * The whole program is parsed and checked against the machine the controller
 * publishes in the segment before anything is sent: a program with any error
 * never starts. Records are numbered as mlip-sim numbers blocks (seq 1..n,
 * then the END record n + 1), so the controller's exec_seq maps to a block.
 * A controller running `smooth` (struct mlip_machine.smooth) gets the
 * program through the smoothing filter (blockiter.h, fixed memory): records
 * 1..n are then the filter's output blocks, each with its source line, and
 * n is counted by one filtering pass before the first is sent. The output
 * depends on the program alone, so --start-seq means the same record in
 * every run.
 *
 * The feeder is the ring's single producer. Two feeders would corrupt it, so
 * the producer line is guarded by a POSIX record lock on the segment (the
 * kernel drops it when a feeder dies), on top of the pid/heartbeat check;
 * it is taken before the program is checked, so mlip-ctl sees a feeder that
 * is still checking.
 *
 * A stop is latched for our program (mlip/ipc/ring.h): the stop counter is
 * read at attach (feeder.stop_base, published with our first heartbeat); a
 * mlip-ctl stop during the check or the wait for an idle controller ends
 * the run before anything is sent, and one that races our first records is
 * refused by the controller (state idle, reason "stop before the start").
 *
 * Life of a run; every loop polls the controller, and from the first push on
 * refreshes the feeder heartbeat (pid 0 in the feeder area: no feeder):
 *
 *   checks -> wait IDLE -> push (ring full: sleep 1 ms) -> END -> wait done: 0
 *                 |               |                               |
 *                 +-- controller stale: 3 ----------------+-------+   FAULT: 5
 *                                 +-- STOPPING/IDLE early: END alone, wait rest, 4
 *                                 +-- SIGINT/SIGTERM: STOP, END alone, wait rest, 130/143
 *            +-- mlip-ctl stop before the start: nothing sent (or dropped unmoved): 4
 *
 * Its parts (feedstate.h, over one struct feed): this file the state, the
 * controller's status, the progress and mlip_feed_run; feedload.c the check
 * and the stream; feedsend.c the loop and the stops it takes; feedtell.c
 * what the operator is told after a stop, a fault or a dead controller.
 */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "feed.h"
#include "feedstate.h"
#include "mlip/ipc/ring.h"
#include "mlip/machine/config.h"
#include "offsetfile.h"
#include "program.h"
#include "rt.h"
#include "tooltable.h"

volatile sig_atomic_t got_signal; /* the last one: SIGINT/TERM/HUP/QUIT */
volatile sig_atomic_t n_signals;  /* a second one cuts the stop wait short */

static void on_signal(int sig)
{
	got_signal = sig;
	n_signals++;
}

const char *prog_name = "mlip-feed"; /* the messages' prefix (feed.h) */

/* "PROG: ..." on stderr: fmt starts with ": ". */
void say(const char *fmt, ...)
{
	va_list ap;

	fputs(prog_name, stderr);
	va_start(ap, fmt);
	vfprintf(stderr, fmt, ap);
	va_end(ap);
}

/* Age in ns of a CLOCK_MONOTONIC stamp; -1 when never stamped. */
static int64_t age_ns(uint64_t stamp_ns)
{
	return mlip_peer_age_ns(stamp_ns, mlip_now_ns());
}

/* Publish the feeder area with a fresh heartbeat (every loop). */
void beat(struct feed *f)
{
	f->fa.heartbeat++;
	f->fa.heartbeat_ns = mlip_now_ns();
	f->fa.program_end = (uint32_t)f->end_pushed;
	mlip_ring_feeder_write(f->r, &f->fa);
}

/* Say "no more records from a feeder" (pid 0), keeping the totals: a
 * controller dropping a stopped program's records stops waiting for its END.
 * We keep the producer lock until we exit, so no other feeder slips in. */
void leave(struct feed *f)
{
	f->fa.pid = 0;
	beat(f);
}

/* End a progress line before any other message. */
void close_line(struct feed *f)
{
	if (f->line_open) {
		fputc('\n', stderr);
		f->line_open = 0;
	}
}

/* Our records the controller has taken (our program has started when > 0). */
uint64_t taken(const struct feed *f)
{
	return f->st.blocks_consumed - f->consumed0;
}

/* Follow exec_seq for the resume hint. Until a block of ours moves, the
 * controller reports the value the previous program left (exec0): during the
 * pre-read, and whenever its planner is empty; and on becoming idle after a
 * stop it reports the last block its planner finished, which is the previous
 * program's if none of ours was. A stale value in our range would send a
 * --start-seq past blocks never run, so only values other than exec0, within
 * the records we sent, seen while the controller is on a program, count.
 * Execution is in order: keep the furthest. */
static void track_exec(struct feed *f)
{
	uint64_t e = f->st.exec_seq;

	if (f->t_start == 0 || taken(f) == 0 || e == f->exec0 || e < f->first_seq ||
	    e >= f->next_seq || e < f->exec ||
	    (f->st.state != MLIP_STATE_RUNNING && f->st.state != MLIP_STATE_HELD &&
	     f->st.state != MLIP_STATE_STOPPING && f->st.state != MLIP_STATE_STARVED &&
	     f->st.state != MLIP_STATE_PAUSED && f->st.state != MLIP_STATE_DWELLING)) {
		return;
	}
	f->exec = e;
	f->exec_line = f->st.exec_line;
}

/* Read the controller status; 0 while it is alive or late, -1 when it is
 * dead (mlip/ipc/peer.h: no beat for MLIP_PEER_TIMEOUT_NS across our own reads
 * and its process gone) or restarted (the period counter went back). Late,
 * its process there but not running (stopped, or starved of CPU), it is not
 * dead, and when it runs again it holds at rest (a stall): we wait, and say
 * so once it has been quiet MLIP_PEER_LATE_NS while we watched. */
int poll_controller(struct feed *f)
{
	struct mlip_ring_status st;
	struct mlip_peer_seen seen;
	int64_t quiet;

	if (mlip_ring_status_read(f->r, &st) == MLIP_OK) {
		if (st.heartbeat < f->last_hb) {
			return -1; /* a new controller formatted the segment */
		}
		f->last_hb = st.heartbeat;
		f->st = st;
		track_exec(f);
	}
	seen = (struct mlip_peer_seen){f->st.heartbeat, f->st.heartbeat_ns, 0, -1};
	switch (mlip_peer_check(&seen, f->st.reserved, &f->watch, &quiet)) {
	case MLIP_PEER_ALIVE:
		return 0;
	case MLIP_PEER_LATE:
		if (quiet >= MLIP_PEER_LATE_NS && !f->late_told) {
			f->late_told = 1;
			close_line(f);
			say(": the controller (pid %u) has not run for %.1f s (stopped or "
			    "starved of CPU); waiting: when it runs again it holds the machine "
			    "at rest (stall) and mlip-ctl resume continues\n",
			    (unsigned)f->st.reserved, (double)quiet / 1e9);
		}
		return 0;
	case MLIP_PEER_DEAD:
		break;
	}
	return -1;
}

/* Counts shown to the user are program blocks (END excluded), as mlip-sim's. */
void progress(struct feed *f, int force)
{
	uint64_t now = mlip_now_ns(), total = f->n;
	uint64_t done = f->exec > f->n ? f->n : f->exec; /* END counts as the last */
	uint64_t queued = f->next_seq > f->n ? f->n : f->next_seq - 1;
	int pct, bar, i;
	char b[21];

	if (f->quiet || (!force && now - f->t_report < (f->tty ? TTY_EVERY_NS : LOG_EVERY_NS))) {
		return;
	}
	f->t_report = now;
	pct = (int)(done * 100 / total);
	if (f->tty) {
		bar = (int)(done * 20 / total);
		for (i = 0; i < 20; i++) {
			b[i] = i < bar ? '#' : '.';
		}
		b[20] = '\0';
		fprintf(
		    stderr,
		    "\r[%s] %3d%%  block %llu/%llu  queued %llu  line %u  override %u %%  %s\033[K",
		    b, pct, (unsigned long long)done, (unsigned long long)total,
		    (unsigned long long)queued, (unsigned)(done ? f->exec_line : 0),
		    (unsigned)f->st.override_pct, mlip_ctl_state_name(f->st.state));
		f->line_open = 1;
	} else {
		say(": %llu/%llu blocks executed (%d %%), %llu queued, line %u, override %u "
		    "%%, %s\n",
		    (unsigned long long)done, (unsigned long long)total, pct,
		    (unsigned long long)queued, (unsigned)(done ? f->exec_line : 0),
		    (unsigned)f->st.override_pct, mlip_ctl_state_name(f->st.state));
	}
	fflush(stderr);
}

/* Where the machine is in the program: the block being executed, or the
 * first one sent when none has moved yet (the place to resume from). */
uint64_t resume_seq(const struct feed *f)
{
	return f->exec ? f->exec : f->first_seq;
}

/* Source line of block seq (sent, or the next to send), 0 when unknown. */
unsigned line_of(const struct feed *f, uint64_t seq)
{
	if (seq == f->exec && f->exec) {
		return f->exec_line;
	}
	if (seq >= 1 && seq <= f->read_seq && f->read_seq - seq < LINE_WINDOW) {
		return f->lines[seq % LINE_WINDOW];
	}
	return 0;
}

unsigned resume_line(const struct feed *f)
{
	return f->exec ? f->exec_line : line_of(f, f->first_seq);
}

int mlip_feed_run(struct mlip_feed_opts *o)
{
	static struct feed f;
	const char *shm = o->shm ? o->shm : MLIP_SHM_DEFAULT;
	struct mlip_machine m;
	struct mlip_config_error cerr;
	struct mlip_ring_feeder other;
	char why[256];
	struct mlip_gcode_offsets offsets;
	struct mlip_program_options popt = {0};
	int32_t holder;
	int rc, code = EXIT_FAIL;

	prog_name = o->prog ? o->prog : "mlip-feed";
	f.first_seq = o->first_seq ? o->first_seq : 1;
	f.rate = o->rate;
	f.quiet = o->quiet;
	f.offsets = o->gc.offsets;
	f.strict = o->gc.strict;
	f.default_feed = o->gc.default_feed;
	f.tools = o->gc.tools;
	f.io.ignore_spindle = o->gc.ignore_spindle;
	f.io.ignore_coolant = o->gc.ignore_coolant;
	f.io.ignore_tools = o->gc.ignore_tools;
	f.path = o->path;
	f.text = o->text;
	f.text_len = o->text_len;
	f.mdi = o->mdi;
	f.fa.mdi = (uint32_t)(o->mdi != 0);
	o->checked = 0;
	f.tty = isatty(STDERR_FILENO);

	/* the file first: a typo is reported as such, controller or not */
	if (f.text == NULL && mlip_program_check_file(f.path, why, sizeof(why)) != 0) {
		say(": %s: %s\n", f.path, why);
		return EXIT_FAIL;
	}
	rc = mlip_shm_attach(&f.shm, shm, why, sizeof(why));
	if (rc != 0) {
		say(": %s\n", why);
		return EXIT_FAIL;
	}
	f.r = f.shm.ring;

	/* the limits in force are the controller's, not a config file's */
	mlip_ring_machine(f.r, &m);
	if (mlip_machine_check(&m, &cerr) != MLIP_OK) {
		say(": %s publishes no usable machine (%s): restart mlip-rt\n", shm, cerr.msg);
		goto out;
	}
	/* the stop counter now, before mlip-ctl can see us (the lock): a stop
	 * from here on is meant for our program */
	f.fa.stop_base = mlip_ring_stop_count(f.r);
	/* one producer only, from before the check on: mlip-ctl sees us */
	rc = mlip_shm_feeder_lock(&f.shm, &holder);
	if (rc != 0) {
		if (rc == -EBUSY) {
			say(": another mlip-feed (pid %d) is checking or feeding a program "
			    "on %s: wait for it to finish, or stop it (mlip-ctl stop)\n",
			    (int)holder, shm);
		} else {
			say(": %s: locking the producer side: %s\n", shm, strerror(-rc));
		}
		goto out;
	}
	if (mlip_ring_feeder_read(f.r, &other) == MLIP_OK && other.pid != (int32_t)getpid() &&
	    mlip_peer_feeder(&other) == MLIP_PEER_ALIVE) {
		say(": another feeder (pid %d) is feeding %s: wait for it to finish, or "
		    "stop it (mlip-ctl stop)\n",
		    (int)other.pid, shm);
		goto out;
	}
	/* the whole program is checked before anything is sent, then streamed */
	mlip_gcode_offsets_init(&offsets, &m);
	if (f.offsets != NULL &&
	    mlip_offsets_load(&f.offsets_file, f.offsets, &m, &offsets, prog_name, stderr) != 0) {
		goto out;
	}
	/* the machine's I/O is the controller's too ([SPINDLE], [TOOL], [COOLANT]) */
	{
		struct mlip_ring_io rio;
		int ig[3] = {f.io.ignore_spindle, f.io.ignore_coolant, f.io.ignore_tools};
		if (mlip_ring_io_read(f.r, &rio) != MLIP_OK) {
			say(": %s publishes no machine I/O yet (mlip-rt starting?): try "
			    "again\n",
			    shm);
			goto out;
		}
		if (mlip_cli_io_from_ring(&rio, &m, &f.io) != 0) {
			say(": %s publishes a machine I/O this mlip-feed cannot use (types, "
			    "speeds or a change position beyond the soft limits): restart "
			    "mlip-rt\n",
			    shm);
			goto out;
		}
		/* a running controller's: its spindle may turn before the
		 * program says (mlip-grbl hands the state over line by line) */
		f.io.live = 1;
		f.io.ignore_spindle = ig[0];
		f.io.ignore_coolant = ig[1];
		f.io.ignore_tools = ig[2];
	}
	if (f.tools != NULL) {
		if (mlip_tooltable_load(&f.table, f.tools, 0, prog_name, stderr) != 0) {
			goto out;
		}
		f.table_ok = 1;
		f.io.tools = f.table.tools;
		f.io.n_tools = f.table.n;
	}
	popt.strict = f.strict;
	popt.default_feed = f.default_feed;
	popt.offsets = &offsets;
	popt.io = &f.io;
	popt.modal = o->modal;
	popt.mdi = o->mdi;
	if (f.mdi && mdi_busy(&f, shm)) {
		goto out;
	}
	/* from where the controller stands when it is idle now (else from
	 * HOME; run() checks again once it is idle: start_moved) */
	f.popt = popt;
	f.mp = m;
	if (mlip_ring_status_read(f.r, &f.st) == MLIP_OK && f.st.heartbeat > 0 &&
	    (f.st.state == MLIP_STATE_IDLE || f.first_seq > 1)) {
		const double *from = f.first_seq > 1 ? f.st.prog_start : f.st.pos;
		for (int k = 0; k < m.n_axes; k++) {
			if (isfinite(from[k])) {
				f.mp.axis[k].home = from[k];
				f.from_controller |= fabs(from[k] - m.axis[k].home) > 1e-9;
			}
		}
	}
	code = load(&f, 1);
	if (code != 0) {
		goto out;
	}
	o->checked = 1;
	o->modal_end = f.prog.modal_end;
	code = EXIT_FAIL;

	if (poll_controller(&f) != 0) {
		int64_t a = age_ns(f.st.heartbeat_ns);

		if (a < 0) {
			say(": controller not running on %s (it never beat): start "
			    "mlip-rt\n",
			    shm);
		} else {
			say(": controller not running on %s (last heartbeat %.*f %s ago): "
			    "start mlip-rt\n",
			    shm, a < 1000000000LL ? 0 : 1,
			    a < 1000000000LL ? (double)a / 1e6 : (double)a / 1e9,
			    a < 1000000000LL ? "ms" : "s");
		}
		goto out;
	}

	mlip_cli_on_stop_signals(on_signal); /* a signal ends the current sleep at once */

	code = run(&f);
	if (f.fa.heartbeat != 0) {
		leave(&f); /* we published: now say we are gone */
	}
	if (code == EXIT_DONE && f.offsets != NULL &&
	    mlip_offsets_save(&f.offsets_file, &m, &f.prog.offsets_end, prog_name, stderr) != 0) {
		code = EXIT_FAIL;
	}
	if (code == EXIT_DONE && offsets_differ(&f.prog.offsets_start, &f.prog.offsets_end, &m)) {
		char offs[512];
		mlip_offsets_describe(&m, &f.prog.offsets_end, offs, sizeof(offs));
		if (f.offsets != NULL) {
			say(": offsets now %s: written to %s\n", offs, f.offsets);
		} else {
			say(": the offsets the %s set (%s) are NOT kept: no --offsets FILE\n",
			    f.mdi ? "MDI" : "program", offs);
		}
	}
	if (code == EXIT_DONE && f.prog.offsets_end.tool != f.prog.offsets_start.tool) {
		say(": tool %d in the spindle now%s%s%s\n", (int)f.prog.offsets_end.tool,
		    f.offsets ? " (" : "",
		    f.offsets ? f.offsets : " (no --offsets: the next program does not know it)",
		    f.offsets ? ")" : "");
	}
	if (code != EXIT_DONE && f.pushed > 0) {
		io_after_stop(&f, &m);
	}
out:
	mlip_offsets_file_free(&f.offsets_file);
	if (f.table_ok) {
		mlip_tooltable_free(&f.table);
	}
	mlip_program_close(&f.prog);
	mlip_shm_close(&f.shm); /* closing the fd drops the producer lock */
	return code;
}
