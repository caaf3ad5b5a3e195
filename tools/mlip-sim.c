/*
 * mlip-sim - the offline simulator: runs a G-code program through the very
 * controller mlip-rt runs (mlip_ctl_period, src/ctl/controller.c) on a virtual
 * clock, and writes the setpoints it would send (--trace) and a summary
 * (--summary).
 *
 * The records reach the controller as they do in mlip-rt: a queue (here an
 * array in this process, there the segment's ring), filled by a feeder step
 * before every period and shown to the controller as a view, of which it
 * takes what it takes; so the ingest rule, the program events (dwell,
 * pauses) and the states are the controller's own, by construction.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "blockiter.h"
#include "check.h"
#include "cli.h"
#include "json.h"
#include "mlip/ctl/controller.h"
#include "mlip/gcode/gcode.h"
#include "mlip/motion/planner.h"
#include "mlip/motion/smooth.h"
#include "mlip/ipc/ring.h"
#include "offsetfile.h"
#include "probesim.h"
#include "program.h"
#include "simcount.h"
#include "simfeed.h"
#include "simopts.h"
#include "simpath.h"
#include "simstorm.h"
#include "trace.h"

#define OVER_BUDGET 99 /* run(): auto's plan scout took as long as the mean */

static struct mlip_planner planner;           /* ~1.1 MB: static, like on the controller */
static struct mlip_smooth_store smooth_store; /* ~1.5 MB, touched only by smooth */
static struct mlip_ctl ctl;

/* The path plan re-times smooth's path under each block's own feed (or
 * --feed's); an override or a probe would change the motion it does not
 * see. */
static int path_runs(const struct options *o)
{
	return o->strategy == MLIP_STRATEGY_SMOOTH && o->override == 100.0 && o->storm_seed < 0 &&
	       !o->probe_surface;
}

/* --jerk-plan path or path-mean: the path plan re-times the controller's
 * setpoints */
static int plans(const struct options *o)
{
	return o->jerk_plan == JERK_PATH || o->jerk_plan == JERK_PATH_MEAN;
}

/* ---- set up ------------------------------------------------------------------- */

/* A run: the program (checked, then streamed), the controller fed by the
 * feeder through the queue, the trace, and the check of the trace against
 * the original program's polyline, streamed by a second reader. */
struct sim {
	struct mlip_offsets_file offsets_file; /* the offsets as read: the save's merge base */
	struct mlip_config cfg;
	struct mlip_program prog, cprog;
	unsigned long lookahead;
	char offsets[512];
	struct queue q;
	struct feeder fdr;
	struct mlip_cli_path csrc;
	struct mlip_check chk;
	FILE *tf;
	char tbuf[1 << 20];
	struct mlip_trace trace;
	struct mlip_simstorm storm;
	uint64_t rows, pauses, dwells; /* trace rows after t = 0 */
	struct mlip_probesim probe;    /* --probe-surface */
	uint64_t probe_trips;          /* G38s that tripped: stopped short of their target */
	uint32_t probe_trip_line;      /* the first one's */
	int probe_error;               /* a G38 ended the program (not tripped, at start) */
	/* --jerk-plan path: the controller's machine (no J, eps less the
	 * band), its setpoints' trace (not written) and the plan */
	struct mlip_machine plan_m;
	struct mlip_trace ctl_trace;
	struct mlip_path_limits plim;
	double band_mm;
	struct mlip_simpath path;
	FILE *err;       /* the plan's refusals (stderr, but for a quiet auto scout) */
	uint64_t budget; /* auto's plan scout: stop at this many rows (0: none) */
	uint64_t auto_rows[JERK_AUTO];   /* auto: a candidate's rows, when the soonest so far */
	const char *auto_why[JERK_AUTO]; /* auto: what became of each plan */
	uint64_t auto_mpct_rows;         /* auto on smooth: mpct's, when the soonest */
	const char *auto_mpct_why;       /* ... what became of it (NULL: not a candidate) */
	int chose;                       /* smooth's choice of corners was made */
	struct mlip_corner_choice choice;
};

static void close_trace(struct sim *s)
{
	if (s->tf != NULL && s->tf != stdout) {
		fclose(s->tf);
	}
	s->tf = NULL;
}

/* 0, or the exit status. */
static int set_up(struct options *o, struct sim *s)
{
	/* the whole program is checked before anything moves, then streamed */
	if (mlip_cli_open_program(o->path, &o->mo, &s->cfg, &s->prog, PROG, stderr) != 0) {
		return 1;
	}
	const struct mlip_machine *m = &s->cfg.machine, *cm = m; /* cm: the controller's */
	s->err = s->err != NULL ? s->err : stderr;
	int from_cfg = o->jerk_plan < 0; /* --jerk-plan overrides the machine's */
	if (from_cfg) {
		o->jerk_plan = s->cfg.jerk_plan == MLIP_JERK_PLAN_PATH ? JERK_PATH : JERK_MEAN;
	}
	if (plans(o)) {
		const char *why = NULL;
		char how[600];
		double feed;
		snprintf(how, sizeof(how), "--jerk-plan %s", plan_name[o->jerk_plan]);
		if (from_cfg) {
			snprintf(how, sizeof(how), "%s:%u: JERK_PLAN = path", o->mo.config,
			         (unsigned)s->cfg.jerk_plan_line);
		}
		if (!path_runs(o)) {
			fprintf(s->err,
			        PROG ": %s: the path plans need --strategy smooth and take no "
			             "--override, --storm or --probe-surface (yet)\n",
			        how);
			return 2;
		}
		if (mlip_simpath_prescan(&s->prog, o->feed, &feed, PROG, o->path, how, s->err) !=
		    0) {
			return 2;
		}
		if (mlip_simpath_limits(m, feed, &s->plim, &s->band_mm, &why) != 0) {
			fprintf(s->err, PROG ": %s: %s\n", how, why);
			return 2;
		}
		if (o->jerk_plan == JERK_PATH) {
			/* smooth without J at eps less the band, as mlip-feed and
			 * the planning thread run it */
			mlip_simpath_machine(m, &s->plan_m);
		} else {
			/* path-mean: the mean. Its samples are not faired: the
			 * spline's (P6) band alone (the fairing's band cost
			 * path-mean 1.9 % on the pocket at 1e4, docs/benchmarks.md) */
			s->plan_m = *m;
			s->band_mm = MLIP_SIMPATH_MEAN_BAND * m->tolerance_mm;
			s->plan_m.tolerance_mm -= s->band_mm; /* the band: the spline's */
		}
		cm = &s->plan_m;
	}
	s->lookahead = o->lookahead       ? o->lookahead
	               : s->cfg.lookahead ? s->cfg.lookahead
	                                  : MLIP_LOOKAHEAD;
	if (o->strategy == MLIP_STRATEGY_SMOOTH && !plans(o) && !o->smooth_only) {
		/* smooth is never slower than mpct: mpct's corners when its run
		 * ends sooner, counted as mlip-feed counts it for mlip-rt (at
		 * 100 %, whatever --override or --storm do then) */
		mlip_corner_choose(m, (uint32_t)s->lookahead, &s->prog, o->feed, &s->choice);
		s->chose = 1;
		if (s->choice.mpct) {
			o->strategy = MLIP_STRATEGY_MPCT;
			o->strategy_name = "mpct";
			if (!o->quiet) {
				fprintf(stderr,
				        PROG ": %s: mpct's corners end it sooner (%.3f s; smooth's "
				             "%.3f s): run with them\n",
				        o->path, (double)s->choice.mpct_rows * m->period_s,
				        (double)s->choice.smooth_rows * m->period_s);
			}
		}
	}
	if (o->notes) {
		mlip_program_print_notices(&s->prog, o->path, stderr);
	}
	mlip_offsets_describe(m, &s->prog.offsets_start, s->offsets, sizeof(s->offsets));
	if (!o->quiet) {
		fprintf(stderr, PROG ": offsets: %s (%s)\n", s->offsets,
		        o->mo.offsets ? o->mo.offsets : "no --offsets: defaults");
	}
	struct mlip_ctl_opts co = {.strategy = (mlip_strategy)o->strategy,
	                           .smooth =
	                               o->strategy == MLIP_STRATEGY_SMOOTH ? &smooth_store : NULL,
	                           .lookahead = (uint32_t)s->lookahead,
	                           .io = &s->cfg.inputs}; /* outputs switch (M64, coolant io) */
	if (mlip_ctl_init(&ctl, &planner, cm, &co) != MLIP_OK) {
		fprintf(stderr, PROG ": look-ahead %lu must be a power of two in 2..%d\n",
		        s->lookahead, MLIP_LOOKAHEAD);
		return 1;
	}
	mlip_planner_set_override(&planner, o->override);
	s->probe.axis = -1;
	if (o->probe_surface != NULL) {
		char letters[MLIP_MAX_AXES + 1] = {0};
		const char *why = NULL;
		for (int k = 0; k < m->n_axes; k++) {
			letters[k] = m->axis[k].letter;
		}
		if (mlip_probesim_parse(&s->probe, o->probe_surface, letters, &why) != 0) {
			fprintf(stderr, PROG ": --probe-surface '%s': %s\n", o->probe_surface, why);
			return 2;
		}
	}
	double at[MLIP_MAX_AXES] = {0};
	for (int k = 0; k < m->n_axes; k++) {
		at[k] = m->axis[k].home; /* where the controller starts */
	}
	mlip_probesim_start(&s->probe, s->cfg.inputs.probe_source == MLIP_PROBE_SRC_DRIVE,
	                    m->n_axes, at);
	s->fdr =
	    (struct feeder){.src = {.p = &s->prog, .feed = o->feed}, .end_line = s->prog.lines};

	/* the check streams the ORIGINAL program's polyline (whatever runs:
	 * smooth's output too) from a second reader of the file, behind the
	 * feeder's, as the samples need it: with the check's window, the queue
	 * and smooth's window, mlip-sim's memory is fixed whatever the length */
	if (mlip_program_open_reader(&s->cprog, &s->prog, o->path) != 0) {
		fprintf(stderr, PROG ": %s: %s\n", o->path, s->cprog.msg);
		mlip_program_close(&s->cprog);
		mlip_program_close(&s->prog);
		return 1;
	}
	mlip_cli_path_start(&s->csrc, &s->cprog, m);
	source_init(&s->fdr.src, cm, o->strategy == MLIP_STRATEGY_SMOOTH);
	struct mlip_check_limits lim;
	mlip_cli_check_limits(m, &lim);
	mlip_check_init_source(&s->chk, &lim, mlip_cli_path_next, &s->csrc);

	if (o->trace_path != NULL) {
		s->tf = strcmp(o->trace_path, "-") == 0 ? stdout : fopen(o->trace_path, "w");
		if (s->tf == NULL) {
			perror(o->trace_path);
			return 1;
		}
		setvbuf(s->tf, s->tbuf, _IOFBF, sizeof(s->tbuf));
	}
	double home[MLIP_MAX_AXES] = {0};
	for (int k = 0; k < m->n_axes; k++) {
		home[k] = m->axis[k].home; /* where the controller starts */
	}
	mlip_trace_open(&s->trace, s->tf, m, home);
	mlip_trace_open(&s->ctl_trace, NULL, m, home);
	s->storm =
	    (struct mlip_simstorm){.state = (uint64_t)o->storm_seed * 0x9E3779B97F4A7C15ULL + 1,
	                           .next_at = 1,
	                           .active = o->storm_seed >= 0};
	return 0;
}

/* ---- run ---------------------------------------------------------------------- */

/* This period's command of the operator: the optional-stop switch, a
 * resume after --resume-after at a pause, the override storm. */
static int operator_command(const struct options *o, struct sim *s, uint64_t period, uint32_t state,
                            uint64_t paused, struct mlip_ring_cmd *cmd)
{
	uint64_t resume_periods = (uint64_t)floor(o->resume_after / s->cfg.machine.period_s + 0.5);
	if (period == 0 && o->optional_stop) {
		cmd->op = MLIP_CMD_OPTIONAL_STOP;
		cmd->arg = 1;
		return 1;
	}
	if (state == MLIP_STATE_PAUSED && paused >= resume_periods) {
		cmd->op = MLIP_CMD_RESUME; /* --resume-after: the operator's resume */
		return 1;
	}
	return s->rows > 0 && mlip_simstorm_tick(&s->storm, s->rows, cmd);
}

/* A G38's end, as mlip-rt logs it: where it tripped (#5061..), or why not. */
static void print_probe(const struct options *o, const struct sim *s,
                        const struct mlip_ctl_out *out, const struct mlip_ctl_event *ev,
                        uint64_t period)
{
	const struct mlip_machine *m = &s->cfg.machine;
	const struct mlip_ring_status *st = &out->status;
	fprintf(stderr, PROG ": %s:%u: t = %.3f s, G38 %s", o->path, (unsigned)ev->r.line,
	        (double)period * m->period_s,
	        ev->r.why == MLIP_WHY_PROBED
	            ? (st->probe_tripped ? "tripped at" : "not tripped, at")
	            : mlip_state_why_name(ev->r.why));
	if (ev->r.why == MLIP_WHY_PROBED) {
		for (int k = 0; k < m->n_axes; k++) {
			fprintf(stderr, " %c%.6f", m->axis[k].letter, st->probe_pos[k]);
		}
		fprintf(stderr, " (#5070 = %u; %s)", st->probe_tripped ? 1u : 0u,
		        s->probe.drive ? "the drives' touch probe latch" : "the probe input");
	}
	fputc('\n', stderr);
}

/* --jerk-plan path: the controller's setpoint pos after this period into
 * the plan (from its start to its end at rest): 1 go on, 0 the trace has
 * ended, -1 an error (the exit status 1). */
static int path_period(const struct options *o, struct sim *s, uint32_t state, const double *pos)
{
	const double *start;
	if (!mlip_trace_sample(&s->ctl_trace, state, pos, &start)) {
		return 1;
	}
	if (start != NULL) {
		memcpy(s->trace.pending, start, sizeof(double) * (size_t)s->trace.n);
		s->trace.have_pending = 1;
		if (mlip_simpath_begin(&s->path, &s->plim, s->band_mm, o->jerk_plan == JERK_PATH,
		                       &s->trace, &s->chk, start) != 0) {
			fprintf(s->err, PROG ": --jerk-plan path: the limits are not positive\n");
			return -1;
		}
	}
	if (state == MLIP_STATE_RUNNING && o->jerk_plan == JERK_PATH) {
		mlip_simpath_tag(&s->path.run.tag_in, &planner); /* as the planning thread */
	} else if (state == MLIP_STATE_RUNNING) {
		mlip_simpath_tag_mean(&s->path, &planner);
	}
	if (state != MLIP_STATE_RUNNING && state != MLIP_STATE_IDLE) {
		fprintf(s->err,
		        PROG ": %s: --jerk-plan path: the program %s at t = %.3f s: the plan "
		             "takes no pause, dwell or hold yet\n",
		        o->path, mlip_ctl_state_name(state),
		        (double)s->ctl_trace.rows * s->cfg.machine.period_s);
		return -1;
	}
	if (mlip_simpath_sample(&s->path, pos, PROG, o->path, s->err) != 0) {
		return -1;
	}
	if (!s->ctl_trace.ended) {
		return 1;
	}
	if (mlip_simpath_end(&s->path, PROG, o->path, s->err) != 0) {
		return -1;
	}
	s->rows = s->trace.rows;
	return 0;
}

/* Period by period until the trace ends at rest: 0, or the exit status. */
static int run(const struct options *o, struct sim *s)
{
	static struct mlip_ctl_out out; /* the last period's: IDLE before the first */
	memset(&out, 0, sizeof(out));   /* a run after a run (--jerk-plan auto) */
	uint64_t paused = 0;
	for (uint64_t period = 0;; period++) {
		struct mlip_ring_cmd cmd = {.seq = 2};
		struct mlip_ctl_in in = {.period = period, .feeder_alive = 1};
		/* the inputs read and all off; the probe as --probe-surface has
		 * it touch (without one it never trips: G38.2 and G38.4 end "not
		 * tripped" at their target, as on a machine where it touches
		 * nothing) */
		in.io.known = s->cfg.inputs.mapped;
		mlip_probesim_in(&s->probe, &in);
		feed_step(&s->fdr, &s->q);
		if (s->fdr.src.rc < 0) {
			fprintf(stderr, PROG ": %s: %s\n", o->path, s->prog.msg);
			return 1;
		}
		if (operator_command(o, s, period, out.status.state, paused, &cmd)) {
			in.cmd = &cmd;
		}
		queue_view(&s->q, &in.recs);
		mlip_ctl_period(&ctl, &in, &out);
		mlip_probesim_out(&s->probe, out.pos, ctl.mio.tp_fn);
		s->q.tail += out.taken;
		paused = out.status.state == MLIP_STATE_PAUSED ? paused + 1 : 0;
		for (uint32_t i = 0; i < out.n_events; i++) {
			const struct mlip_ctl_event *ev = &out.events[i];
			s->pauses += out.events[i].kind == MLIP_EV_STATE &&
			             out.events[i].state == MLIP_STATE_PAUSED;
			if (ev->kind == MLIP_EV_STATE && ev->state == MLIP_STATE_PAUSED &&
			    !o->quiet &&
			    (ev->r.why == MLIP_WHY_SPINDLE || ev->r.why == MLIP_WHY_TOOL ||
			     ev->r.why == MLIP_WHY_COOLANT)) {
				/* what the operator is to do, at its time (the virtual
				 * operator resumes after --resume-after) */
				char what[200];
				mlip_cli_io_message(ev->r.why, ev->r.value, mlip_cli_tooltable(),
				                    what, sizeof(what));
				const char *label = mlip_state_why_name(ev->r.why);
				if (ev->r.why == MLIP_WHY_SPINDLE &&
				    s->cfg.io.spindle == MLIP_IO_CIA402) {
					/* no drive here: mlip-rt waits at rest until it is
					 * at speed (the ramp from rest is the least that
					 * takes) or stands still */
					label = "spindle (CiA 402, not simulated)";
					if (ev->r.value == 0) {
						snprintf(what, sizeof(what),
						         "stop: mlip-rt waits here until it stands "
						         "still");
					} else {
						snprintf(what, sizeof(what),
						         "to %g rpm: mlip-rt waits here until it "
						         "is at speed "
						         "(%.2f s from rest at ACCELERATION)",
						         ev->r.value,
						         fabs(ev->r.value) /
						             s->cfg.spindle.accel_rpm_s);
					}
				}
				fprintf(stderr, PROG ": %s:%u: t = %.3f s, %s: %s\n", o->path,
				        (unsigned)ev->r.line,
				        (double)period * s->cfg.machine.period_s, label, what);
			}
			s->dwells += out.events[i].kind == MLIP_EV_STATE &&
			             out.events[i].state == MLIP_STATE_DWELLING;
			s->probe_error |= ev->kind == MLIP_EV_STATE &&
			                  ev->state == MLIP_STATE_IDLE &&
			                  (ev->r.why == MLIP_WHY_PROBE_NO_TRIP ||
			                   ev->r.why == MLIP_WHY_PROBE_AT_START ||
			                   ev->r.why == MLIP_WHY_PROBE_OFF_AT_START ||
			                   ev->r.why == MLIP_WHY_PROBE_INPUT);
			if (ev->kind == MLIP_EV_STATE && ev->r.why == MLIP_WHY_PROBED &&
			    out.status.probe_tripped && s->probe_trips++ == 0) {
				s->probe_trip_line = ev->r.line;
			}
			if (ev->kind == MLIP_EV_STATE && !o->quiet &&
			    (ev->r.why == MLIP_WHY_PROBED || ev->r.why == MLIP_WHY_PROBE_NO_TRIP ||
			     ev->r.why == MLIP_WHY_PROBE_AT_START ||
			     ev->r.why == MLIP_WHY_PROBE_OFF_AT_START ||
			     ev->r.why == MLIP_WHY_PROBE_INPUT)) {
				print_probe(o, s, &out, ev, period);
			}
		}
		const double *start;
		if (plans(o)) {
			int r = path_period(o, s, out.status.state, out.pos);
			if (r <= 0) {
				return -r;
			}
		} else if (mlip_trace_sample(&s->trace, out.status.state, out.pos, &start)) {
			if (start != NULL) {
				mlip_check_sample(&s->chk, start);
			}
			mlip_check_sample(&s->chk, out.pos);
			s->rows = s->trace.rows;
		}
		if (s->budget > 0 && s->trace.rows >= s->budget) {
			return OVER_BUDGET; /* --jerk-plan auto: not sooner than the best so far */
		}
		if (s->trace.ended || (s->probe_error && out.status.state == MLIP_STATE_IDLE)) {
			return 0; /* a probe error before any motion (G38 first) ends it too */
		}
		if (out.status.state == MLIP_STATE_FAULT) {
			fprintf(stderr, PROG ": controller fault (%s) at record %llu (line %u)\n",
			        mlip_state_why_name(out.status.reason),
			        (unsigned long long)out.status.reason_seq,
			        (unsigned)out.status.reason_line);
			return 1;
		}
		if (period > MLIP_SIM_MAX_PERIODS) {
			fprintf(stderr, PROG ": no end after %llu periods: aborting\n",
			        (unsigned long long)period);
			return 3;
		}
	}
}

/* ---- report ------------------------------------------------------------------- */

/* The summary (--summary): totals and measured physics. */
static int write_summary(const struct options *o, const struct sim *s, int bad)
{
	const struct mlip_machine *m = &s->cfg.machine;
	const struct mlip_check *chk = &s->chk;
	const struct mlip_planner_stats *ps = mlip_planner_get_stats(&planner);
	double visits = ps->pushes ? (double)ps->backward_visits / (double)ps->pushes : 0.0;
	double acc_lim[MLIP_MAX_AXES], jerk_lim[MLIP_MAX_AXES], vel_lim[MLIP_MAX_AXES];
	char axes[MLIP_MAX_AXES + 1];
	int n = m->n_axes;
	for (int a = 0; a < n; a++) {
		axes[a] = m->axis[a].letter;
		acc_lim[a] = m->axis[a].max_accel;
		jerk_lim[a] = m->axis[a].max_jerk;
		vel_lim[a] = m->axis[a].max_vel;
	}
	axes[n] = '\0';
	FILE *sf = strcmp(o->summary_path, "-") == 0 ? stdout : fopen(o->summary_path, "w");
	if (sf == NULL) {
		perror(o->summary_path);
		return -1;
	}
	struct mlip_json j;
	mlip_json_begin(&j, sf);
	mlip_json_string(&j, "file", o->path);
	mlip_json_string(&j, "strategy", mlip_cli_strategy_name((mlip_strategy)o->strategy));
	mlip_json_number(&j, "total_time_s", "%.6f", (double)s->rows * m->period_s);
	mlip_json_uint(&j, "periods", s->rows);
	mlip_json_uint(&j, "blocks", s->prog.n);
	mlip_json_uint(&j, "segments", ps->pushes);
	/* smooth: the filter's output */
	mlip_json_uint(&j, "blocks_run", s->fdr.seq > 0 ? s->fdr.seq - 1 : 0);
	mlip_json_number(&j, "path_length_mm", "%.6f", chk->prog_mm);
	mlip_json_number(&j, "max_speed_mm_s", "%.9g", chk->max_speed_mm_s);
	mlip_json_string(&j, "axes", axes);
	mlip_json_numbers(&j, "max_axis_accel", "%.12g", chk->max_acc, n);
	mlip_json_numbers(&j, "max_axis_vel", "%.12g", chk->max_vel, n);
	mlip_json_numbers(&j, "max_axis_jerk", "%.12g", chk->max_jerk, n);
	mlip_json_numbers(&j, "jerk_limit", "%.12g", jerk_lim, n);
	mlip_json_numbers(&j, "accel_limit", "%.12g", acc_lim, n);
	mlip_json_numbers(&j, "vel_limit", "%.12g", vel_lim, n);
	mlip_json_number(&j, "max_contour_error_mm", "%.9g", chk->max_contour_mm);
	mlip_json_number(&j, "end_error_mm", "%.3g", mlip_check_end_error(chk));
	mlip_json_number(&j, "vmax_mm_s", "%.9g", m->max_feed_mm_s);
	mlip_json_number(&j, "eps_mm", "%.9g", m->tolerance_mm);
	mlip_json_number(&j, "period_s", "%.9g", m->period_s);
	mlip_json_uint(&j, "lookahead", s->lookahead);
	mlip_json_number(&j, "backward_visits_per_block", "%.3f", visits);
	mlip_json_string(&j, "offsets", s->offsets);
	mlip_json_uint(&j, "override_events", s->storm.events);
	mlip_json_uint(&j, "dwells", s->dwells);
	mlip_json_uint(&j, "pauses", s->pauses);
	mlip_json_uint(&j, "order_errors", chk->order_errors);
	if (s->chose) {
		/* smooth's choice of corners (simcount.h) */
		mlip_json_string(&j, "corners",
		                 s->choice.why    ? s->choice.why
		                 : s->choice.mpct ? "mpct (sooner)"
		                                  : "smooth");
		if (s->choice.smooth_rows > 0) {
			mlip_json_number(&j, "corners_smooth_s", "%.6f",
			                 (double)s->choice.smooth_rows * m->period_s);
		}
		if (s->choice.mpct_rows > 0) {
			mlip_json_number(&j, "corners_mpct_s", "%.6f",
			                 (double)s->choice.mpct_rows * m->period_s);
		}
	}
	if (s->auto_rows[JERK_MEAN] > 0) {
		/* --jerk-plan auto: the one taken, the candidates' times (a
		 * plan's when it ended the program sooner; else why not) */
		static const char *const key[][2] = {
		    {0, 0}, {"auto_path", "auto_path_s"}, {"auto_path_mean", "auto_path_mean_s"}};
		mlip_json_string(&j, "jerk_plan", plan_name[o->jerk_plan]);
		mlip_json_number(&j, "auto_mean_s", "%.6f",
		                 (double)s->auto_rows[JERK_MEAN] * m->period_s);
		for (int p = JERK_PATH; p <= JERK_PATH_MEAN; p++) {
			mlip_json_string(&j, key[p][0], s->auto_why[p]);
			if (s->auto_rows[p] > 0) {
				mlip_json_number(&j, key[p][1], "%.6f",
				                 (double)s->auto_rows[p] * m->period_s);
			}
		}
		if (s->auto_mpct_why != NULL) {
			mlip_json_string(&j, "auto_mpct", s->auto_mpct_why);
			if (s->auto_mpct_rows > 0) {
				mlip_json_number(&j, "auto_mpct_s", "%.6f",
				                 (double)s->auto_mpct_rows * m->period_s);
			}
		}
	}
	if (plans(o)) {
		/* the streaming plan's window (points, of MLIP_PATHRUN_CAP), the
		 * largest (P6) bound of its pieces and knot's move (F2), its
		 * braking-run periods */
		const struct mlip_pathrun *pr = &s->path.run;
		mlip_json_uint(&j, "path_window_peak", (uint64_t)pr->peak_count);
		mlip_json_uint(&j, "path_window_bytes", sizeof(*pr));
		mlip_json_number(&j, "path_max_sag_mm", "%.3g", pr->max_sag_mm);
		mlip_json_number(&j, "path_band_mm", "%.3g", pr->band_mm);
		mlip_json_number(&j, "path_max_fair_mm", "%.3g", pr->max_dev_mm);
		mlip_json_uint(&j, "path_run_periods", (uint64_t)pr->work);
	}
	mlip_json_int(&j, "violations", bad);
	int rc = mlip_json_end(&j);
	if (sf != stdout && fclose(sf) != 0) {
		rc = -1;
	}
	if (rc != 0) {
		perror(o->summary_path);
	}
	return rc;
}

/* The trace closed, the verdict of its own check (as mlip-check's), the
 * summary, the offsets written back: the exit status. */
static int report(const struct options *o, struct sim *s, int rc)
{
	if (rc != 0) {
		close_trace(s);
		return rc;
	}
	if (s->tf != NULL && s->tf != stdout && fclose(s->tf) != 0) {
		s->tf = NULL;
		perror(o->trace_path);
		return 1;
	}
	if (s->tf == stdout) {
		fflush(stdout);
	}
	s->tf = NULL;
	mlip_check_finish(&s->chk);
	if (s->csrc.rc < 0) {
		fprintf(stderr, PROG ": %s: %s\n", o->path, s->cprog.msg);
		return 1;
	}
	/* the same verdict as mlip-check on this trace: limits within 1e-9, the
	 * rounding floor of the second differences, the end on the last point */
	if (s->probe_error) {
		/* the program stopped at the probe, as on the machine (mlip-feed's 5) */
		mlip_program_close(&s->cprog);
		mlip_program_close(&s->prog);
		return 5;
	}
	char vmsg[4096];
	double abs_mm = 0.0, end_mm = 1e-9;
	if (s->probe_trips > 0) {
		/* a probe stopped short of its target: from there the path is not
		 * the programmed polyline (the next move starts where it stopped),
		 * so order, contour and end are not judged; the limits are */
		if (!o->quiet) {
			fprintf(stderr,
			        PROG
			        ": %s: %llu G38 tripped (first at line %u): the path leaves the "
			        "programmed polyline there; order, contour and end not judged "
			        "(%zu sample(s) out of order), the limits are\n",
			        o->path, (unsigned long long)s->probe_trips,
			        (unsigned)s->probe_trip_line, s->chk.order_errors);
		}
		s->chk.order_errors = 0;
		abs_mm = INFINITY;
		end_mm = INFINITY;
	}
	int bad = mlip_check_verdict(&s->chk, 1e-9, mlip_check_rounding_floor(&s->chk), abs_mm,
	                             end_mm, vmsg, sizeof(vmsg));
	if (o->summary_path != NULL && write_summary(o, s, bad) != 0) {
		return 1;
	}
	if (!o->quiet) {
		fprintf(stderr,
		        PROG ": %s: %s %.3f s, %zu blocks, %.1f mm, max speed %.2f mm/s, "
		             "max contour error %.6f mm\n",
		        o->path, mlip_cli_strategy_name((mlip_strategy)o->strategy),
		        (double)s->rows * s->cfg.machine.period_s, s->prog.n, s->chk.prog_mm,
		        s->chk.max_speed_mm_s, s->chk.max_contour_mm);
	}
	mlip_program_close(&s->cprog);
	if (o->save_offsets && mlip_offsets_save(&s->offsets_file, &s->cfg.machine,
	                                         &s->prog.offsets_end, PROG, stderr) != 0) {
		mlip_program_close(&s->prog);
		return 1;
	}
	mlip_program_close(&s->prog);
	if (bad) {
		fprintf(stderr,
		        PROG ": %s: the trace breaks the machine's limits (%d check(s)):\n%s",
		        o->path, bad, vmsg);
		return 4;
	}
	return 0;
}

/* One run counted, not written (trace, summary, offsets): 0 and its rows
 * in *rows, or its exit status (OVER_BUDGET: stopped at s->budget rows). */
static int scout(struct options *o, struct sim *s, uint64_t *rows)
{
	int rc = set_up(o, s);
	if (rc == 0) {
		rc = run(o, s);
		*rows = s->rows;
	}
	/* a refusal after the open too (the path plans' prescan): the next
	 * scout clears s */
	mlip_program_close(&s->cprog);
	mlip_program_close(&s->prog);
	return rc;
}

/* --jerk-plan auto: the program's start and end are rests every plan
 * shares, and each is a deterministic function of the program: the mean is
 * run counted, then each plan counted up to the fewest rows so far
 * (abandoned there, or at a refusal, a pause, a dwell: path-mean first,
 * the likelier winner, so path's budget is the tighter); the one that ends
 * soonest (the earlier on a tie, the mean first) is run again, written and
 * checked. Never slower than the mean, in the memory of one run: no window
 * of setpoints is kept. On --strategy smooth, mpct (the program's own
 * path, its mean) is the last candidate, counted up to the fewest rows so
 * far: smooth is never slower than mpct by construction, with J or
 * without. */
static int choose(struct options *o, struct sim *s)
{
	static struct sim sc;
	static FILE *quiet;
	static const int order[] = {JERK_PATH_MEAN, JERK_PATH, JERK_MEAN};
	static const char *const not_sooner[] = {"not sooner than the mean", "not sooner than path",
	                                         "not sooner than path-mean"};
	struct options q = *o;
	q.trace_path = q.summary_path = NULL;
	q.quiet = 1;
	q.notes = q.save_offsets = 0;
	q.jerk_plan = JERK_MEAN;
	uint64_t best = 0;
	int rc = scout(&q, &sc, &best);
	const char *why = NULL;
	struct mlip_path_limits lim;
	double band, t = sc.cfg.machine.period_s;
	if (rc != 0) {
		return rc; /* the mean's run fails: as --jerk-plan mean would */
	}
	s->auto_rows[JERK_MEAN] = best;
	o->jerk_plan = JERK_MEAN;
	/* each block under its own F (or --feed's): a scout's prescan refuses
	 * what the plan cannot run */
	int cand =
	    path_runs(o) && mlip_simpath_limits(&sc.cfg.machine, o->feed, &lim, &band, &why) == 0;
	for (int i = 0; i < 3; i++) {
		int p = order[i], mpct = i == 2; /* the last: mpct's mean, on smooth */
		uint64_t rows = 0;
		const char **fate = mpct ? &s->auto_mpct_why : &s->auto_why[p];
		*fate = mpct ? NULL : "not a candidate (--strategy smooth, --feed, a jerk limit)";
		if (mpct ? o->strategy != MLIP_STRATEGY_SMOOTH : !cand) {
			continue;
		}
		quiet = quiet != NULL || !o->quiet ? quiet : fopen("/dev/null", "w");
		memset(&sc, 0, sizeof(sc));
		sc.err = o->quiet ? quiet : stderr;
		sc.budget = best;
		q.jerk_plan = p;
		q.strategy = mpct ? MLIP_STRATEGY_MPCT : q.strategy;
		q.strategy_name = mpct ? "mpct" : q.strategy_name;
		rc = scout(&q, &sc, &rows);
		*fate = rc == 0 && rows < best         ? "sooner"
		        : rc != 0 && rc != OVER_BUDGET ? "refused"
		                                       : not_sooner[o->jerk_plan];
		if (rc == 0 && rows < best) {
			*(mpct ? &s->auto_mpct_rows : &s->auto_rows[p]) = best = rows;
			o->jerk_plan = p;
			o->strategy = q.strategy;
			o->strategy_name = q.strategy_name;
		}
	}
	if (!o->quiet) {
		fprintf(stderr, PROG ": %s: --jerk-plan auto: %s%s (the mean %.3f s", o->path,
		        s->auto_mpct_rows > 0 ? "mpct's " : "", plan_name[o->jerk_plan],
		        (double)s->auto_rows[JERK_MEAN] * t);
		for (int p = JERK_PATH; p <= JERK_PATH_MEAN; p++) {
			if (s->auto_rows[p] > 0) {
				fprintf(stderr, ", %s %.3f s", plan_name[p],
				        (double)s->auto_rows[p] * t);
			} else {
				fprintf(stderr, ", %s %s", plan_name[p], s->auto_why[p]);
			}
		}
		if (s->auto_mpct_rows > 0) {
			fprintf(stderr, ", mpct %.3f s", (double)s->auto_mpct_rows * t);
		} else if (s->auto_mpct_why != NULL) {
			fprintf(stderr, ", mpct %s", s->auto_mpct_why);
		}
		fprintf(stderr, ")\n");
	}
	rc = set_up(o, s);
	if (rc != 0) {
		return rc;
	}
	rc = run(o, s);
	if (rc == 0 && s->rows != best) {
		fprintf(stderr, PROG ": %s: --jerk-plan auto: the run differs from its count\n",
		        o->path);
		rc = 1;
	}
	return report(o, s, rc);
}

int main(int argc, char **argv)
{
	static struct options o;
	static struct sim s;
	int rc = parse_options(argc, argv, &o);
	if (rc != 0) {
		return rc < 0 ? 0 : rc;
	}
	o.mo.offsets_file = &s.offsets_file;
	if (o.jerk_plan == JERK_AUTO) {
		o.smooth_only = 1; /* auto counts mpct's run among its own */
		return choose(&o, &s);
	}
	rc = set_up(&o, &s);
	if (rc != 0) {
		return rc;
	}
	return report(&o, &s, run(&o, &s));
}
