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
 */
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "blockiter.h"
#include "cli.h"
#include "feed.h"
#include "mlip/machine/config.h"
#include "mlip/canopen/canopen.h"
#include "mlip/ipc/ring.h"
#include "offsetfile.h"
#include "program.h"
#include "rt.h"
#include "tooltable.h"

#define BATCH         256u          /* records per mlip_ring_push_n */
#define FULL_SLEEP_NS 1000000L      /* ring full: retry after 1 ms */
#define WAIT_SLEEP_NS 5000000L      /* only waiting: poll every 5 ms (heartbeat < 10 ms) */
#define TTY_EVERY_NS  100000000ull  /* progress line on a terminal: 10 per second */
#define LOG_EVERY_NS  2000000000ull /* progress line otherwise: every 2 s */
#define IDLE_NOTE_NS  1000000000ull /* say why we wait after 1 s */
#define STOP_WAIT_NS  5000000000ull /* after a stop: wait at most 5 s for rest */
#define CMD_WAIT_NS   1000000000ull /* mailbox busy: retry for 1 s */

enum {
	EXIT_DONE = MLIP_FEED_DONE,
	EXIT_FAIL = MLIP_FEED_FAIL,
	EXIT_USAGE = MLIP_FEED_USAGE,
	EXIT_CTRL_DEAD = MLIP_FEED_CTRL_DEAD,
	EXIT_OPERATOR = MLIP_FEED_OPERATOR,
	EXIT_FAULT = MLIP_FEED_FAULT
};

static volatile sig_atomic_t got_signal; /* the last one: SIGINT/TERM/HUP/QUIT */
static volatile sig_atomic_t n_signals;  /* a second one cuts the stop wait short */

static void on_signal(int sig)
{
	got_signal = sig;
	n_signals++;
}

static const char *prog_name = "mlip-feed"; /* the messages' prefix (feed.h) */

/* "PROG: ..." on stderr: fmt starts with ": ". */
static void say(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static void say(const char *fmt, ...)
{
	va_list ap;

	fputs(prog_name, stderr);
	va_start(ap, fmt);
	vfprintf(stderr, fmt, ap);
	va_end(ap);
}

/* Relative sleep; a signal ends it early (no SA_RESTART), the caller looks at
 * got_signal. clock_nanosleep returns its error, it does not set errno. */
static void sleep_ns(long ns)
{
	struct timespec ts = {0, ns};

	(void)clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, NULL);
}

/* Age in ns of a CLOCK_MONOTONIC stamp; -1 when never stamped. */
static int64_t age_ns(uint64_t stamp_ns)
{
	return mlip_peer_age_ns(stamp_ns, mlip_now_ns());
}

/* Source lines of the last blocks sent, for messages about the block being
 * executed or resumed from: those are within the controller's look-ahead and
 * the ring's capacity of the last one sent. */
#define LINE_WINDOW (1u << 16)
#define IO_HIST     256u /* spindle, tool, coolant events remembered per kind */

struct feed {
	/* wiring */
	struct mlip_shm shm;
	struct mlip_ring *r;
	struct mlip_ring_port tx; /* producer: capacity, mask and head kept private */
	const char *path;
	const char *text; /* MDI: the lines (NULL: path is a file) */
	size_t text_len;
	int mdi;
	int quiet, tty;
	/* program: checked whole, then streamed (never held) */
	struct mlip_program prog;
	uint64_t n; /* blocks; the END record is n + 1 */
	uint32_t end_line;
	uint64_t read_seq;           /* blocks taken from the stream so far */
	uint32_t lines[LINE_WINDOW]; /* source line of seq, for seq % LINE_WINDOW */
	struct mlip_block_iter it;   /* the program's blocks, or smooth's over them */
	struct mlip_smooth_iter si;
	const char *offsets;                   /* --offsets FILE, or NULL */
	struct mlip_offsets_file offsets_file; /* as loaded: the write-back's merge base */
	int strict;
	double default_feed;    /* --default-feed */
	struct mlip_machine mp; /* the controller's machine, HOME = where the program starts */
	struct mlip_program_options popt;
	/* the machine's I/O: mlip-rt's, the tool table, the --ignore-* choices */
	struct mlip_gcode_io io;
	const char *tools; /* --tools FILE */
	struct mlip_tooltable table;
	int table_ok;
	/* the I/O events sent (the last IO_HIST of each kind), and the one the
	 * machine last paused at for the operator: what to say after a stop */
	struct {
		uint64_t seq;
		uint32_t line;
		double value;
	} ioev[3][IO_HIST];
	uint64_t ioev_n[3];
	uint64_t io_wait_seq;
	int from_controller; /* mp's HOME is the idle controller's position */
	/* progress */
	struct mlip_ring_feeder fa;   /* what we publish */
	struct mlip_ring_status st;   /* last consistent controller status */
	uint64_t last_hb;             /* controller period counter: must not go back */
	struct mlip_peer_watch watch; /* our reads of the controller's heartbeat */
	uint64_t consumed0;           /* controller's blocks_consumed before our first push */
	uint64_t next_seq;            /* next record to push, 1..n + 1 */
	uint64_t first_seq;           /* --start-seq */
	double rate;                  /* --rate: blocks per second at most (0: no limit) */
	uint64_t pushed;              /* records pushed by this run */
	uint64_t exec0;               /* exec_seq before our program: not ours */
	uint64_t exec;                /* our block being executed (0: none yet) */
	uint32_t exec_line;           /* its source line */
	int end_pushed;
	int late_told;                 /* "the controller has not run" said */
	uint32_t told_state, told_why; /* the last state explained to the operator */
	int line_open;                 /* a "\r" progress line is on the terminal */
	uint64_t t_start, t_report;
};

/* Publish the feeder area with a fresh heartbeat (every loop). */
static void beat(struct feed *f)
{
	f->fa.heartbeat++;
	f->fa.heartbeat_ns = mlip_now_ns();
	f->fa.program_end = (uint32_t)f->end_pushed;
	mlip_ring_feeder_write(f->r, &f->fa);
}

/* Say "no more records from a feeder" (pid 0), keeping the totals: a
 * controller dropping a stopped program's records stops waiting for its END.
 * We keep the producer lock until we exit, so no other feeder slips in. */
static void leave(struct feed *f)
{
	f->fa.pid = 0;
	beat(f);
}

/* End a progress line before any other message. */
static void close_line(struct feed *f)
{
	if (f->line_open) {
		fputc('\n', stderr);
		f->line_open = 0;
	}
}

/* Our records the controller has taken (our program has started when > 0). */
static uint64_t taken(const struct feed *f)
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
static int poll_controller(struct feed *f)
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
static void progress(struct feed *f, int force)
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
static uint64_t resume_seq(const struct feed *f)
{
	return f->exec ? f->exec : f->first_seq;
}

/* Source line of block seq (sent, or the next to send), 0 when unknown. */
static unsigned line_of(const struct feed *f, uint64_t seq)
{
	if (seq == f->exec && f->exec) {
		return f->exec_line;
	}
	if (seq >= 1 && seq <= f->read_seq && f->read_seq - seq < LINE_WINDOW) {
		return f->lines[seq % LINE_WINDOW];
	}
	return 0;
}

static unsigned resume_line(const struct feed *f)
{
	return f->exec ? f->exec_line : line_of(f, f->first_seq);
}

static int program_next(void *ctx, struct mlip_block *b)
{
	struct feed *f = ctx;
	return mlip_program_next(&f->prog, b);
}

/* Blocks from the stream's start: the program's, or smooth's over them. */
static void stream_start(struct feed *f, const struct mlip_machine *m)
{
	static struct mlip_smooth sm; /* ~1 MB */
	f->it = (struct mlip_block_iter){program_next, f};
	if (m->smooth) {
		f->it = mlip_smooth_iter(&f->si, &sm, m, f->it);
	}
}

/* The next block from the stream into *b: 1, or < 0 (the file changed). */
static int next_block(struct feed *f, struct mlip_block *b)
{
	f->prog.msg[0] = '\0';
	int rc = f->it.next(f->it.ctx, b);
	if (rc < 0 && f->prog.msg[0] == '\0') {
		snprintf(f->prog.msg, sizeof(f->prog.msg), "the smoothing filter refused a block");
	}
	if (rc > 0) {
		f->read_seq++;
		f->lines[f->read_seq % LINE_WINDOW] = b->line;
	}
	return rc > 0 ? 1 : rc == 0 ? -EIO : rc;
}

/* " X1.0000 Y2.0000 ..." of the machine's HOME (where a program starts) */
static const char *position_text(const struct mlip_machine *m, char *buf, size_t len)
{
	size_t k = 0;
	buf[0] = '\0';
	for (int i = 0; i < m->n_axes && k < len; i++) {
		k += (size_t)snprintf(buf + k, len - k, " %c%.4f", m->axis[i].letter,
		                      m->axis[i].home);
	}
	return buf;
}

/*
 * Check the whole program (first pass) from the machine f->mp, whose HOME is
 * where the program starts: the controller's commanded position when it is
 * idle (a G90 move that leaves an axis out keeps it where it stands, not at
 * the configured HOME: after another program, or with drives whose axes were
 * moved while disabled), then position the stream at --start-seq. 0, or an
 * exit code (nothing sent).
 */
static int load(struct feed *f, int notes)
{
	const struct mlip_machine *m = &f->mp;
	int rc = f->text != NULL
	             ? mlip_program_open_mem(&f->prog, f->text, f->text_len, m, &f->popt)
	             : mlip_program_open(&f->prog, f->path, m, &f->popt);
	if (rc < 0) {
		say(": %s: %s\n", f->path, f->prog.msg);
		return EXIT_FAIL;
	}
	if (rc > 0) {
		mlip_program_print_errors(&f->prog, f->path, stderr);
		return EXIT_FAIL;
	}
	if (notes && !f->quiet) {
		char offs[512];
		mlip_program_print_notices(&f->prog, f->path, stderr);
		if (f->from_controller) {
			say(": checked from where the %s:%s\n",
			    f->first_seq > 1 ? "program began" : "machine stands",
			    position_text(m, offs, sizeof(offs)));
		}
		mlip_offsets_describe(m, &f->prog.offsets_start, offs, sizeof(offs));
		say(": offsets: %s (%s)\n", offs,
		    f->offsets ? f->offsets : "no --offsets: defaults");
	}
	f->n = f->prog.n;
	f->read_seq = 0;
	stream_start(f, m);
	if (m->smooth) {
		/* the controller runs `smooth`: send the path smoothed within the
		 * tolerance, as mlip-sim does, so that the setpoints are the
		 * simulator's. One pass counts the records (END is n + 1). */
		struct mlip_block b;
		for (f->n = 0; (rc = f->it.next(f->it.ctx, &b)) > 0;) {
			f->n++;
		}
		if (rc < 0) {
			say(": %s: %s\n", f->path,
			    f->prog.msg[0] ? f->prog.msg : "the smoothing filter refused a block");
			return EXIT_FAIL;
		}
		mlip_program_rewind(&f->prog);
		stream_start(f, m);
	}
	f->end_line = f->prog.lines;
	if (f->first_seq > f->n && f->first_seq > 1) { /* n = 0: nothing to move (run) */
		say(": --start-seq %llu: %s has %llu blocks\n", (unsigned long long)f->first_seq,
		    f->path, (unsigned long long)f->n);
		return EXIT_USAGE;
	}
	f->next_seq = f->first_seq;
	for (uint64_t k = 1; k < f->first_seq; k++) {
		struct mlip_block b;
		if (next_block(f, &b) < 0) {
			say(": %s: %s\n", f->path, f->prog.msg);
			return EXIT_FAIL;
		}
	}
	if (f->first_seq > 1) {
		f->lines[f->first_seq % LINE_WINDOW] = 0; /* not read yet */
	}
	return 0;
}

/* Once the controller is idle: checked from where it stands? Else check the
 * program again from there (nothing is sent yet). 0, or an exit code. */
static int start_moved(struct feed *f)
{
	char at[256];
	int moved = 0;
	/* a continuation is read from where its program began (the same
	 * records: the merge of a first block that moves nothing and the
	 * smoothing depend on the start), a new program from where we stand */
	const double *from = f->first_seq > 1 ? f->st.prog_start : f->st.pos;
	for (int k = 0; k < f->mp.n_axes; k++) {
		double p = from[k];
		if (!isfinite(p)) {
			say(": the controller publishes no position for axis %c: "
			    "nothing was sent\n",
			    f->mp.axis[k].letter);
			return EXIT_FAIL;
		}
		moved |= fabs(p - f->mp.axis[k].home) > 1e-9;
		f->mp.axis[k].home = p;
	}
	if (!moved) {
		return 0;
	}
	if (!f->quiet) {
		say(": %s at%s: checking %s again from there\n",
		    f->first_seq > 1 ? "the program began" : "the machine now stands",
		    position_text(&f->mp, at, sizeof(at)), f->path);
	}
	mlip_program_close(&f->prog);
	return load(f, 0);
}

/* Once the controller is at rest after a stop: the block to continue from,
 * the one after the last it completed (its status says so when idle), within
 * what we sent; else where we were. */
static uint64_t rest_seq(const struct feed *f)
{
	uint64_t next = f->st.exec_seq + 1;
	if ((f->st.state == MLIP_STATE_IDLE || f->st.state == MLIP_STATE_STARVED) &&
	    next >= f->first_seq && next < f->next_seq && next <= f->n) {
		return next;
	}
	return resume_seq(f) > f->n ? f->n : resume_seq(f); /* END: its last block */
}

static int controller_dead(struct feed *f)
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

static int controller_fault(struct feed *f)
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

/* Tell the operator once per state what the machine waits for and how to
 * continue: the same words as mlip-rt's log and mlip-ctl status. */
static void explain(struct feed *f)
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
static void io_after_stop(struct feed *f, const struct mlip_machine *m)
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
	    f->st.reason == MLIP_WHY_PROBE_INPUT) {
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

/* MDI runs only on an idle machine: a program (running, held, paused), a
 * jog or homing is never queued behind. 1 after saying why, else 0. */
static int mdi_busy(struct feed *f, const char *shm)
{
	if (mlip_ring_status_read(f->r, &f->st) != MLIP_OK || f->st.heartbeat == 0) {
		return 0; /* not running: said after the check */
	}
	if (f->st.state == MLIP_STATE_IDLE && mlip_ring_count(f->r) == 0) {
		return 0;
	}
	say(": refused: the controller on %s is %s%s: MDI runs only when the machine is "
	    "idle (mlip-ctl stop ends a program or a jog)\n",
	    shm, mlip_ctl_state_name(f->st.state),
	    f->st.state == MLIP_STATE_JOGGING  ? " (a jog)"
	    : f->st.state == MLIP_STATE_HOMING ? " (homing)"
	    : f->st.state == MLIP_STATE_IDLE   ? " (records of a program queued)"
	    : f->st.state == MLIP_STATE_ESTOP  ? " (release the input, then mlip-ctl reset)"
	    : f->st.state == MLIP_STATE_FAULT  ? ""
	                                       : " (a program)");
	return 1;
}

/* Offsets a, b differ on machine m's axes (value by value). */
static int offsets_differ(const struct mlip_gcode_offsets *a, const struct mlip_gcode_offsets *b,
                          const struct mlip_machine *m)
{
	int d = a->g92_on != b->g92_on || a->select != b->select;
	for (int i = 0; i < m->n_axes; i++) {
		d |= a->g92[i] != b->g92[i] || a->g28[i] != b->g28[i] || a->g30[i] != b->g30[i];
		for (int k = 0; k < MLIP_GCODE_N_COORD; k++) {
			d |= a->coord[k][i] != b->coord[k][i];
		}
	}
	return d;
}

static int run(struct feed *f)
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
