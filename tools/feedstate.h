/*
 * feedstate.h - the parts of the feeder (feed.h, tools/feed.c says how) over
 * one run's state (struct feed): feed.c the state, the controller's status
 * and the progress, and mlip_feed_run; feedload.c the program's check and
 * its stream; feedsend.c the records' loop and the stops it takes;
 * feedtell.c what a stop, a fault or a dead controller leave, said to the
 * operator. Not a library: only mlip-feed and mlip-ctl (mdi) link these.
 */
#ifndef MLIP_TOOLS_FEEDSTATE_H
#define MLIP_TOOLS_FEEDSTATE_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#include "blockiter.h"
#include "feed.h"
#include "mlip/gcode/gcode.h"
#include "mlip/ipc/ring.h"
#include "mlip/machine/config.h"
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

extern volatile sig_atomic_t got_signal; /* the last one: SIGINT/TERM/HUP/QUIT */
extern volatile sig_atomic_t n_signals;  /* a second one cuts the stop wait short */
extern const char *prog_name;            /* the messages' prefix (feed.h) */

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
	int mpct; /* a smooth controller runs it with mpct's corners (simcount.h):
	             its blocks unsmoothed, every record MLIP_REC_MPCT */
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

/* feed.c */
void say(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
void beat(struct feed *f);
void leave(struct feed *f);
void close_line(struct feed *f);
uint64_t taken(const struct feed *f);
int poll_controller(struct feed *f);
void progress(struct feed *f, int force);
uint64_t resume_seq(const struct feed *f);
unsigned line_of(const struct feed *f, uint64_t seq);
unsigned resume_line(const struct feed *f);
/* feedload.c */
int next_block(struct feed *f, struct mlip_block *b);
int load(struct feed *f, int notes);
int start_moved(struct feed *f);
int mdi_busy(struct feed *f, const char *shm);
int offsets_differ(const struct mlip_gcode_offsets *a, const struct mlip_gcode_offsets *b,
                   const struct mlip_machine *m);
/* feedtell.c */
uint64_t rest_seq(const struct feed *f);
int controller_dead(struct feed *f);
int controller_fault(struct feed *f);
void explain(struct feed *f);
void io_after_stop(struct feed *f, const struct mlip_machine *m);
/* feedsend.c */
int run(struct feed *f);

#endif
