/*
 * feed.h - the feeder of mlip-feed and mlip-ctl mdi: check a program (a
 * file, or MDI lines in memory) against the machine the running mlip-rt
 * publishes, send it through the ring of its shared-memory segment and
 * follow it to rest (tools/feed.c says how). One run per process (the
 * signal handlers and the feeder's state are the process's).
 */
#ifndef MLIP_TOOLS_FEED_H
#define MLIP_TOOLS_FEED_H

#include <stddef.h>
#include <stdint.h>

#include "cli.h"
#include "mlip/gcode/gcode.h"

enum {
	MLIP_FEED_DONE = 0,
	MLIP_FEED_FAIL = 1, /* nothing sent: bad program, no controller, another feeder, busy */
	MLIP_FEED_USAGE = 2,
	MLIP_FEED_CTRL_DEAD = 3, /* controller stopped responding (or restarted) mid-program */
	MLIP_FEED_OPERATOR = 4,  /* stopped by mlip-ctl stop */
	MLIP_FEED_FAULT = 5      /* controller went to FAULT */
};

struct mlip_feed_opts {
	const char *prog; /* the messages' prefix: "mlip-feed", "mlip-ctl mdi" */
	const char *shm;  /* the controller's segment */
	const char *path; /* the program file; with text: the lines' name in messages */
	const char *text; /* MDI: the lines, text_len bytes (NULL: path is a file) */
	size_t text_len;
	uint64_t first_seq; /* --start-seq (1: the whole program) */
	double rate;        /* --rate: blocks per second at most (0: no limit) */
	int quiet;
	/* the G-code options (cli.h, mlip_cli_gcode_option): offsets (read
	 * before, written after; NULL: none), strict, default_feed, tools,
	 * ignore_*; the machine is the controller's (the rest is not used) */
	struct mlip_cli_machine gc;
	/* MDI (mlip-ctl mdi): refused at once unless the controller is idle (a
	 * program, a jog, homing, a hold run); lines without motion are no
	 * error; the modal state starts at *modal (NULL: a program's) */
	int mdi;
	const struct mlip_gcode_modal *modal;
	/* out */
	int checked;                       /* the lines passed the check */
	struct mlip_gcode_modal modal_end; /* the modal state they leave (when checked) */
};

/* Check, send, follow: an exit status (MLIP_FEED_*, or 128 + a signal). */
int mlip_feed_run(struct mlip_feed_opts *o);

#endif
