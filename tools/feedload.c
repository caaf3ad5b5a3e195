/*
 * feedload.c - the feeder's program (feedstate.h): checked whole from where
 * the machine stands, then streamed (the program's blocks or smooth's).
 */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>

#include "blockiter.h"
#include "feedstate.h"
#include "mlip/machine/config.h"
#include "mlip/motion/planq.h"
#include "offsetfile.h"
#include "planfeed.h"
#include "program.h"
#include "simcount.h"
#include "simpath.h"

static int program_next(void *ctx, struct mlip_block *b)
{
	struct feed *f = ctx;
	return mlip_program_next(&f->prog, b);
}

/* Blocks from the stream's start: the program's, or smooth's over them. */
static void stream_start(struct feed *f, const struct mlip_machine *m)
{
	static struct mlip_smooth sm;  /* ~1 MB */
	static struct mlip_machine pm; /* JERK_PLAN = path: the plan's controller's */
	f->it = (struct mlip_block_iter){program_next, f};
	if (m->path_plan) {
		mlip_simpath_machine(m, &pm); /* smoothed as mlip-sim does for the plan */
		m = &pm;
	}
	if (m->smooth && !f->mpct) {
		f->it = mlip_smooth_iter(&f->si, &sm, m, f->it);
	}
}

/* The next block from the stream into *b: 1, or < 0 (the file changed). */
int next_block(struct feed *f, struct mlip_block *b)
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

/* The plan's controller and plan for the check below: large (4.5 MB),
 * fixed, touched only on a controller with JERK_PLAN = path */
static struct plan_check {
	struct mlip_planner planner;
	struct mlip_smooth_store store;
	struct mlip_ctl ctl;
	struct mlip_pathrun run;
	struct mlip_planq queue;
	struct mlip_config cfg;
	struct mlip_planfeed pf;
} P;

/*
 * The controller plans the path speed (JERK_PLAN = path): its plan run here
 * first, to the program's end, as its planning thread will run it (the same
 * records from where the machine stands, the same code: planfeed.h, its
 * queue drained as the period pops it), so that what the plan refuses (a
 * spline piece past the band, (P6); a state it cannot certify) is refused
 * before anything is sent, as mlip-sim refuses it. The plan is deterministic
 * (mlip-rt's setpoints are mlip-sim's to the byte): without the check the
 * refusal came mid-run, a fault on the path that cut the program short.
 * A continuation (--start-seq) was checked as a whole program before.
 * 0, or an exit code after saying why.
 */
static int plan_check(struct feed *f, const struct mlip_machine *m)
{
	P.cfg = (struct mlip_config){0};
	P.cfg.machine = *m; /* HOME: where the program starts, as the thread's */
	P.cfg.lookahead = m->plan_lookahead ? m->plan_lookahead : MLIP_LOOKAHEAD;
	const char *why = NULL;
	if (mlip_planfeed_init(&P.pf, &P.cfg, 0.0, P.cfg.lookahead, &P.ctl, &P.planner, &P.store,
	                       &P.run, &P.queue, &why) != 0) {
		say(": the controller's JERK_PLAN = path: %s: nothing was sent\n", why);
		return EXIT_FAIL;
	}
	stream_start(f, m);
	uint64_t seq = 0;
	int in_done = 0, done = 0, r = 0, mode = MLIP_PLANQ_WAIT;
	double x[MLIP_MAX_AXES];
	while (mode != MLIP_PLANQ_DONE) {
		while (!done && !(P.pf.started && P.queue.head - P.queue.tail >= MLIP_PLANQ_LEN)) {
			while (!in_done && mlip_planfeed_room(&P.pf) > 0) {
				struct mlip_block b;
				struct mlip_ring_rec rec;
				int k = f->it.next(f->it.ctx, &b);
				if (k < 0) {
					say(": %s: %s\n", f->path,
					    f->prog.msg[0]
					        ? f->prog.msg
					        : "the smoothing filter refused a block");
					return EXIT_FAIL;
				}
				if (k > 0) {
					mlip_ring_rec_from_block(&rec, &b, ++seq);
				} else {
					mlip_ring_rec_end(&rec, ++seq, f->prog.lines);
					in_done = 1;
				}
				mlip_planfeed_offer(&P.pf, &rec);
			}
			r = mlip_planfeed_work(&P.pf);
			if (r < 0) {
				const struct mlip_pathrun *pr = &P.run;
				char at[160] = "";
				if (pr->why != NULL && pr->why_mm > 0.0) {
					snprintf(
					    at, sizeof(at),
					    " at %.6f mm of the path (%.6f mm, the band %.6f mm)",
					    pr->why_s, pr->why_mm, pr->band_mm);
				} else if (pr->why != NULL) {
					snprintf(at, sizeof(at),
					         " at %.6f mm of the path (speed %.6g, "
					         "acceleration %.6g)",
					         pr->why_s, pr->why_v, pr->why_a);
				}
				say(": %s: the controller's JERK_PLAN = path cannot run this "
				    "program: %s%s; "
				    "nothing was sent (mlip-sim --config refuses it too; [TRAJ] "
				    "JERK_PLAN = "
				    "mean runs it)\n",
				    f->path, P.pf.why ? P.pf.why : "?", at);
				return EXIT_FAIL;
			}
			done = r == 2;
			if (r == 0) {
				break;
			}
		}
		if (!P.pf.started) {
			if (done || r == 0) {
				break; /* nothing to move (or nothing more to read) */
			}
			continue;
		}
		mode = mlip_planq_step(&P.queue, 0, x);
		if (mode < 0) {
			say(": %s: the controller's JERK_PLAN = path: its plan's queue failed "
			    "(mode %d); nothing was sent\n",
			    f->path, mode);
			return EXIT_FAIL;
		}
	}
	mlip_program_rewind(&f->prog);
	return 0;
}

/*
 * Check the whole program (first pass) from the machine f->mp, whose HOME is
 * where the program starts: the controller's commanded position when it is
 * idle (a G90 move that leaves an axis out keeps it where it stands, not at
 * the configured HOME: after another program, or with drives whose axes were
 * moved while disabled), then position the stream at --start-seq. 0, or an
 * exit code (nothing sent).
 */
int load(struct feed *f, int notes)
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
	/* the controller plans the path speed: what its plan cannot run yet is
	 * refused before anything is sent, as mlip-sim refuses it */
	double feed;
	if (m->path_plan &&
	    mlip_simpath_prescan(&f->prog, 0.0, &feed, prog_name, f->path,
	                         "the controller's JERK_PLAN = path", stderr) != 0) {
		return EXIT_FAIL;
	}
	if (m->path_plan && f->first_seq <= 1 && (rc = plan_check(f, m)) != 0) {
		return rc;
	}
	/* a smooth controller: mpct's corners when their run ends the program
	 * sooner, as mlip-sim chooses (never slower than mpct). Counted from
	 * where the program begins: a continuation chooses as it did */
	f->mpct = 0;
	if (m->smooth && !m->path_plan) {
		struct mlip_corner_choice ch;
		mlip_corner_choose(m, m->plan_lookahead, &f->prog, 0.0, &ch);
		f->mpct = ch.mpct;
		if (ch.mpct && !f->quiet) {
			say(": %s: mpct's corners end it sooner (%.3f s; smooth's %.3f s): the "
			    "controller runs it with them\n",
			    f->path, (double)ch.mpct_rows * m->period_s,
			    (double)ch.smooth_rows * m->period_s);
		}
	}
	f->n = f->prog.n;
	f->read_seq = 0;
	stream_start(f, m);
	if (m->smooth && !f->mpct) {
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
int start_moved(struct feed *f)
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

/* MDI runs only on an idle machine: a program (running, held, paused), a
 * jog or homing is never queued behind. 1 after saying why, else 0. */
int mdi_busy(struct feed *f, const char *shm)
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
int offsets_differ(const struct mlip_gcode_offsets *a, const struct mlip_gcode_offsets *b,
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
