/*
 * mlip-sim - the offline simulator: runs a G-code program through the very
 * controller mlip-rt runs (mlip_ctl_period, src/ctl/controller.c) on a virtual
 * clock, and writes the setpoints it would send (--trace) and a summary
 * (--summary).
 *
 * The records reach the controller as in mlip-rt: through a ring (in this
 * process' memory), filled by a feeder step before every period, so the
 * ingest rule, the program events (dwell, pauses) and the states are the
 * controller's own, by construction.
 */
#include <getopt.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "blockiter.h"
#include "check.h"
#include "cli.h"
#include "mlip/ctl/controller.h"
#include "mlip/gcode/gcode.h"
#include "mlip/motion/planner.h"
#include "mlip/ipc/ring.h"
#include "offsets.h"
#include "program.h"
#include "trace.h"

#define PROG        "mlip-sim"
#define MAX_PERIODS 200000000ULL /* 55 h of machining at 1 ms: a runaway */

static struct mlip_planner planner; /* ~2.6 MB: static, like on the controller */
static struct mlip_ctl ctl;

static void usage(FILE *f)
{
	fprintf(
	    f,
	    "usage: " PROG " [options] FILE.ngc\n"
	    "Simulate a G-code program on the mlip interpolator and report its motion.\n\n"
	    "  --config FILE         machine INI (default: the axes the program uses, linear)\n"
	    "  --strategy NAME       mpct (default, the paper), bisector, stop, smooth (mpct on\n"
	    "                        the path smoothed within the tolerance, "
	    "mlip/motion/smooth.h)\n"
	    "  --accel A[,A...]      per-axis acceleration, mm/s^2 (one for all, or per axis)\n"
	    "  --vmax MM_S           maximum feed v_m, mm/s (default 200 without --config)\n"
	    "  --eps MM              contour tolerance (default 0.01 without --config)\n"
	    "  --period S            interpolation period T (default 0.001)\n"
	    "  --feed MM_S           ignore the program's F words, run every block at this feed\n"
	    "  --override PCT        feed override from the start, 0..200 (default 100)\n"
	    "  --storm SEED          random override changes, holds and resumes every 5-200\n"
	    "                        periods (a test of online override)\n"
	    "  --lookahead N         look-ahead capacity in blocks, power of two (default %d)\n"
	    "  --resume-after S      a pause (M0, M60, M1 with --optional-stop) resumes after\n"
	    "                        S seconds at rest (default 0)\n"
	    "  --optional-stop       M1 pauses (the optional-stop switch on)\n"
	    "  --trace OUT.csv       setpoints: t,x,y,... one row per period, t = 0 to rest\n"
	    "  --summary OUT.json    totals and measured physics (JSON)\n"
	    "  --offsets FILE        work offsets, G92 and G28/G30 positions (docs/gcode.md)\n"
	    "  --save-offsets        write the offsets the program leaves back to that FILE\n"
	    "  --default-feed F      feed (units/min) for a program that sets no F at all\n"
	    "  --strict              refuse Grbl '$' lines and axis words before G0/G1/G2/G3\n"
	    "  --no-notes            do not list the words accepted without effect\n"
	    "  -q, --quiet           neither notes nor the summary line on stderr\n"
	    "  -h, --help            this help\n"
	    "exit status: 0 done within every limit, 1 input error, 2 usage, 3 no end,\n"
	    "4 the trace breaks a limit (its own check, as mlip-check's: which, where)\n",
	    MLIP_LOOKAHEAD);
}

/* xorshift64*: a seeded, portable stream for --storm */
static uint64_t rng_next(uint64_t *s)
{
	*s ^= *s >> 12;
	*s ^= *s << 25;
	*s ^= *s >> 27;
	return *s * 2685821657736338717ULL;
}

static double rng_unit(uint64_t *s)
{
	return (double)(rng_next(s) >> 11) * (1.0 / 9007199254740992.0);
}

struct storm {
	uint64_t state;
	uint64_t next_at;
	int active;
	int held, zero; /* what the storm has done */
	uint64_t events;
};

/* Change the override or hold state at random periods, through the
 * controller's commands; never leaves the machine stopped for more than one
 * event, so every program finishes. Returns 1 with *cmd set, or 0. */
static int storm_tick(struct storm *st, uint64_t period, struct mlip_ring_cmd *cmd)
{
	if (!st->active || period < st->next_at) {
		return 0;
	}
	st->next_at = period + 5 + rng_next(&st->state) % 196;
	st->events++;
	double r = rng_unit(&st->state);
	cmd->arg = 0;
	if (st->held) {
		cmd->op = MLIP_CMD_RESUME;
		st->held = 0;
	} else if (st->zero) {
		cmd->op = MLIP_CMD_OVERRIDE;
		cmd->arg = (int32_t)(10.0 + 190.0 * rng_unit(&st->state));
		st->zero = 0;
	} else if (r < 0.1) {
		cmd->op = MLIP_CMD_HOLD;
		st->held = 1;
	} else if (r < 0.2) {
		cmd->op = MLIP_CMD_OVERRIDE;
		st->zero = 1;
	} else {
		cmd->op = MLIP_CMD_OVERRIDE;
		cmd->arg = (int32_t)(10.0 + 190.0 * rng_unit(&st->state));
	}
	return 1;
}

/* Where the blocks come from: the checked program, streamed (never held,
 * program.h), through the smoothing filter with --strategy smooth (fixed
 * memory, blockiter.h). 1 with the next block in *b, 0 at the end or on an
 * error of the stream (rc < 0, the program's msg says why). */
struct source {
	struct mlip_program *p;
	int rc;
	double feed;               /* --feed: > 0 replaces every F and G0 */
	struct mlip_block_iter it; /* the program's blocks, or smooth's over them */
	struct mlip_smooth_iter si;
};

static int program_next(void *ctx, struct mlip_block *b)
{
	struct source *src = ctx;
	if (src->rc < 0 || (src->rc = mlip_program_next(src->p, b)) <= 0) {
		return src->rc;
	}
	if (src->feed > 0.0 && b->kind == MLIP_BLOCK_MOVE) {
		b->feed_mm_s = src->feed;
		b->rapid = 0;
	}
	return 1;
}

static void source_init(struct source *src, const struct mlip_machine *m, int smooth)
{
	static struct mlip_smooth sm; /* ~1 MB */
	src->it = (struct mlip_block_iter){program_next, src};
	if (smooth) {
		src->it = mlip_smooth_iter(&src->si, &sm, m, src->it);
	}
}

static int source_next(struct source *src, struct mlip_block *b)
{
	int r = src->it.next(src->it.ctx, b);
	if (r < 0 && src->rc >= 0) {
		src->rc = -1; /* the filter refused a block (a non-finite target) */
		snprintf(src->p->msg, sizeof(src->p->msg), "the smoothing filter refused a block");
	}
	return r > 0;
}

/* The feeder's step before each period: the ring filled as far as it goes,
 * records numbered as mlip-feed numbers them (blocks 1..n, then END; with
 * smooth, the filter's output blocks 1..n, each with its source line). */
struct feeder {
	struct source src;
	uint64_t seq; /* last record pushed */
	uint32_t end_line;
	int end_pushed;
};

static void feed_step(struct feeder *f, struct mlip_ring *r)
{
	static struct mlip_ring_rec recs[256];
	struct mlip_block b;
	uint32_t space = mlip_ring_space(r);
	while (!f->end_pushed && space > 0) {
		uint32_t k = 0;
		for (; k < space && k < 256 && !f->end_pushed; k++) {
			if (source_next(&f->src, &b)) {
				mlip_ring_rec_from_block(&recs[k], &b, ++f->seq);
			} else if (f->src.rc < 0) {
				break; /* no END: the run stops, the caller says why */
			} else {
				mlip_ring_rec_end(&recs[k], ++f->seq, f->end_line);
				f->end_pushed = 1;
			}
		}
		space -= mlip_ring_push_n(r, recs, k); /* all k: only we add */
		if (f->src.rc < 0) {
			return;
		}
	}
}

int main(int argc, char **argv)
{
	struct mlip_cli_machine mo = {0};
	const char *strategy = "mpct", *trace_path = NULL, *summary_path = NULL;
	double feed = -1.0, override = 100.0;
	long long storm_seed = -1;
	unsigned long lookahead = 0;
	int quiet = 0, notes = 1, optional_stop = 0, save_offsets = 0;
	double resume_after = 0.0;

	static const struct option opts[] = {{"config", required_argument, 0, 'c'},
	                                     {"strategy", required_argument, 0, 's'},
	                                     {"accel", required_argument, 0, 'a'},
	                                     {"vmax", required_argument, 0, 'v'},
	                                     {"eps", required_argument, 0, 'e'},
	                                     {"period", required_argument, 0, 'p'},
	                                     {"feed", required_argument, 0, 'f'},
	                                     {"override", required_argument, 0, 'o'},
	                                     {"storm", required_argument, 0, 'S'},
	                                     {"lookahead", required_argument, 0, 'L'},
	                                     {"trace", required_argument, 0, 't'},
	                                     {"summary", required_argument, 0, 'j'},
	                                     {"quiet", no_argument, 0, 'q'},
	                                     {"help", no_argument, 0, 'h'},
	                                     {"no-notes", no_argument, 0, 'N'},
	                                     {"resume-after", required_argument, 0, 'r'},
	                                     {"optional-stop", no_argument, 0, 'O'},
	                                     {"save-offsets", no_argument, 0, 'W'},
	                                     MLIP_CLI_GCODE_OPTIONS,
	                                     {0, 0, 0, 0}};
	int c;
	while ((c = getopt_long(argc, argv, "qh", opts, NULL)) != -1) {
		double v;
		int g = mlip_cli_gcode_option(c, optarg, &mo, PROG, stderr);
		if (g != 0) {
			if (g < 0) {
				return 2;
			}
			continue;
		}
		switch (c) {
		case 'c':
			mo.config = optarg;
			break;
		case 's':
			strategy = optarg;
			break;
		case 'a':
			mo.accel = optarg;
			break;
		case 'v':
		case 'e':
		case 'p':
		case 'f':
		case 'o':
			if (mlip_cli_number(optarg, &v) != 0 ||
			    !(v > 0.0 || (c == 'o' && v == 0.0))) {
				fprintf(stderr, PROG ": --%s: '%s' is not a positive number\n",
				        c == 'v'   ? "vmax"
				        : c == 'e' ? "eps"
				        : c == 'p' ? "period"
				        : c == 'f' ? "feed"
				                   : "override",
				        optarg);
				return 2;
			}
			if (c == 'v') {
				mo.vmax_mm_s = v;
			} else if (c == 'e') {
				mo.eps_mm = v;
			} else if (c == 'p') {
				mo.period_s = v;
			} else if (c == 'f') {
				feed = v;
			} else {
				override = v;
			}
			break;
		case 'S':
			storm_seed = strtoll(optarg, NULL, 0);
			break;
		case 'L':
			lookahead = strtoul(optarg, NULL, 0);
			break;
		case 't':
			trace_path = optarg;
			break;
		case 'j':
			summary_path = optarg;
			break;
		case 'q':
			quiet = 1;
			notes = 0;
			break;
		case 'N':
			notes = 0;
			break;
		case 'r':
			if (mlip_cli_number(optarg, &resume_after) != 0 || !(resume_after >= 0.0) ||
			    resume_after > 86400.0) {
				fprintf(stderr,
				        PROG ": --resume-after: '%s' is not 0..86400 seconds\n",
				        optarg);
				return 2;
			}
			break;
		case 'O':
			optional_stop = 1;
			break;
		case 'W':
			save_offsets = 1;
			break;
		case 'h':
			usage(stdout);
			return 0;
		default:
			usage(stderr);
			return 2;
		}
	}
	if (optind != argc - 1) {
		usage(stderr);
		return 2;
	}
	const char *path = argv[optind];
	int st = mlip_cli_strategy(strategy);
	if (st < 0) {
		fprintf(stderr,
		        PROG ": --strategy: '%s' is not one of mpct, bisector, stop, smooth\n",
		        strategy);
		return 2;
	}
	if (override > 200.0) {
		fprintf(stderr, PROG ": --override: %g is above 200 %%\n", override);
		return 2;
	}

	if (save_offsets && mo.offsets == NULL) {
		fprintf(stderr, PROG ": --save-offsets needs --offsets FILE\n");
		return 2;
	}
	/* the whole program is checked before anything moves, then streamed */
	static struct mlip_config cfg;
	static struct mlip_program prog;
	if (mlip_cli_open_program(path, &mo, &cfg, &prog, PROG, stderr) != 0) {
		return 1;
	}
	const struct mlip_machine *m = &cfg.machine;
	int n = m->n_axes;
	if (lookahead == 0) {
		lookahead = cfg.lookahead ? cfg.lookahead : MLIP_LOOKAHEAD;
	}

	if (notes) {
		mlip_program_print_notices(&prog, path, stderr);
	}
	char offs[512];
	mlip_offsets_describe(m, &prog.offsets_start, offs, sizeof(offs));
	if (!quiet) {
		fprintf(stderr, PROG ": offsets: %s (%s)\n", offs,
		        mo.offsets ? mo.offsets : "no --offsets: defaults");
	}
	/* the controller, its ring and feeder, in this process */
	struct mlip_ctl_opts co = {.strategy = (mlip_strategy)st, .lookahead = (uint32_t)lookahead};
	size_t ring_bytes = mlip_ring_bytes(MLIP_RING_CAPACITY);
	void *ring_mem = NULL;
	struct mlip_ring *ring = NULL;
	if (posix_memalign(&ring_mem, MLIP_RING_LINE, ring_bytes) != 0 ||
	    mlip_ring_format_machine(ring_mem, ring_bytes, MLIP_RING_CAPACITY, m) != MLIP_OK ||
	    mlip_ring_attach(ring_mem, ring_bytes, n, &ring, NULL) != MLIP_OK) {
		fprintf(stderr, PROG ": cannot make the ring\n");
		return 1;
	}
	if (mlip_ctl_init(&ctl, &planner, m, &co, ring) != MLIP_OK) {
		fprintf(stderr, PROG ": look-ahead %lu must be a power of two in 2..%d\n",
		        lookahead, MLIP_LOOKAHEAD);
		return 1;
	}
	mlip_planner_set_override(&planner, override);
	struct feeder fdr = {.src = {.p = &prog, .feed = feed}, .end_line = prog.lines};

	/* the check streams the ORIGINAL program's polyline (whatever runs:
	 * smooth's output too) from a second reader of the file, behind the
	 * feeder's, as the samples need it: with the check's window, the ring
	 * and smooth's window, mlip-sim's memory is fixed whatever the length */
	static struct mlip_program cprog;
	if (mlip_program_open_reader(&cprog, &prog, path) != 0) {
		fprintf(stderr, PROG ": %s: %s\n", path, cprog.msg);
		mlip_program_close(&cprog);
		mlip_program_close(&prog);
		return 1;
	}
	struct mlip_cli_path csrc;
	mlip_cli_path_start(&csrc, &cprog, m);
	source_init(&fdr.src, m, st == MLIP_STRATEGY_SMOOTH);
	struct mlip_check_limits lim;
	mlip_cli_check_limits(m, &lim);
	static struct mlip_check chk;
	mlip_check_init_source(&chk, &lim, mlip_cli_path_next, &csrc);

	FILE *tf = NULL;
	static char tbuf[1 << 20];
	if (trace_path != NULL) {
		tf = strcmp(trace_path, "-") == 0 ? stdout : fopen(trace_path, "w");
		if (tf == NULL) {
			perror(trace_path);
			return 1;
		}
		setvbuf(tf, tbuf, _IOFBF, sizeof(tbuf));
	}
	struct mlip_trace trace;
	mlip_trace_open(&trace, tf, m, ctl.pos);

	struct storm storm = {.state = (uint64_t)storm_seed * 0x9E3779B97F4A7C15ULL + 1,
	                      .next_at = 1,
	                      .active = storm_seed >= 0};
	uint64_t resume_periods = (uint64_t)floor(resume_after / m->period_s + 0.5);
	uint64_t paused = 0, pauses = 0, dwells = 0, period = 0, k = 0;
	struct mlip_ctl_out out;
	for (;; period++) {
		struct mlip_ring_cmd cmd = {.seq = 2};
		struct mlip_ctl_in in = {.period = period, .feeder_alive = 1};
		feed_step(&fdr, ring);
		if (fdr.src.rc < 0) {
			fprintf(stderr, PROG ": %s: %s\n", path, prog.msg);
			return 1;
		}
		if (period == 0 && optional_stop) {
			cmd.op = MLIP_CMD_OPTIONAL_STOP;
			cmd.arg = 1;
			in.cmd = &cmd;
		} else if (ctl.state == MLIP_STATE_PAUSED && paused >= resume_periods) {
			cmd.op = MLIP_CMD_RESUME; /* --resume-after: the operator's resume */
			in.cmd = &cmd;
		} else if (k > 0 && storm_tick(&storm, k, &cmd)) {
			in.cmd = &cmd;
		}
		mlip_ctl_period(&ctl, &in, &out);
		paused = out.status.state == MLIP_STATE_PAUSED ? paused + 1 : 0;
		for (uint32_t i = 0; i < out.n_events; i++) {
			pauses += out.events[i].kind == MLIP_EV_STATE &&
			          out.events[i].state == MLIP_STATE_PAUSED;
			dwells += out.events[i].kind == MLIP_EV_STATE &&
			          out.events[i].state == MLIP_STATE_DWELLING;
		}
		const double *start;
#ifdef MLIP_SIM_TEST_FAULT_AT /* test builds only (tests/py): one setpoint off the path */
		if (trace.started && !trace.ended && trace.rows + 1 == MLIP_SIM_TEST_FAULT_AT) {
			for (int a = 0; a < n; a++) {
				out.pos[a] += 0.05;
			}
		}
#endif
		if (mlip_trace_sample(&trace, out.status.state, out.pos, &start)) {
			if (start != NULL) {
				mlip_check_sample(&chk, start);
			}
			mlip_check_sample(&chk, out.pos);
			k = trace.rows;
		}
		if (trace.ended) {
			break;
		}
		if (out.status.state == MLIP_STATE_FAULT) {
			fprintf(stderr, PROG ": controller fault (%s) at record %llu (line %u)\n",
			        mlip_state_why_name(out.status.reason),
			        (unsigned long long)out.status.reason_seq,
			        (unsigned)out.status.reason_line);
			return 1;
		}
		if (period > MAX_PERIODS) {
			fprintf(stderr, PROG ": no end after %llu periods: aborting\n",
			        (unsigned long long)period);
			return 3;
		}
	}
	free(ring_mem);
	if (tf != NULL && tf != stdout && fclose(tf) != 0) {
		perror(trace_path);
		return 1;
	}
	if (tf == stdout) {
		fflush(stdout);
	}

	double total = (double)k * m->period_s;
	mlip_check_finish(&chk);
	if (csrc.rc < 0) {
		fprintf(stderr, PROG ": %s: %s\n", path, cprog.msg);
		return 1;
	}
	double path_mm = chk.prog_mm;
	/* the same verdict as mlip-check on this trace: limits within 1e-9, the
	 * rounding floor of the second differences, the end on the last point */
	char vmsg[4096];
	int bad = mlip_check_verdict(&chk, 1e-9, mlip_check_rounding_floor(&chk), 0.0, 1e-9, vmsg,
	                             sizeof(vmsg));
	const struct mlip_planner_stats *ps = mlip_planner_get_stats(&planner);
	double visits = ps->pushes ? (double)ps->backward_visits / (double)ps->pushes : 0.0;

	if (summary_path != NULL) {
		FILE *sf = strcmp(summary_path, "-") == 0 ? stdout : fopen(summary_path, "w");
		if (sf == NULL) {
			perror(summary_path);
			return 1;
		}
		fprintf(sf, "{\n  \"file\": \"%s\",\n  \"strategy\": \"%s\",\n", path,
		        mlip_cli_strategy_name((mlip_strategy)st));
		fprintf(sf, "  \"total_time_s\": %.6f,\n  \"periods\": %llu,\n", total,
		        (unsigned long long)k);
		fprintf(sf, "  \"blocks\": %zu,\n  \"segments\": %llu,\n", prog.n,
		        (unsigned long long)ps->pushes);
		fprintf(sf, "  \"blocks_run\": %llu,\n", /* smooth: the filter's output */
		        (unsigned long long)(fdr.seq > 0 ? fdr.seq - 1 : 0));
		fprintf(sf, "  \"path_length_mm\": %.6f,\n", path_mm);
		fprintf(sf, "  \"max_speed_mm_s\": %.9g,\n", chk.max_speed_mm_s);
		fprintf(sf, "  \"axes\": \"");
		for (int a = 0; a < n; a++) {
			fputc(m->axis[a].letter, sf);
		}
		fprintf(sf, "\",\n  \"max_axis_accel\": [");
		for (int a = 0; a < n; a++) {
			fprintf(sf, "%s%.12g", a ? ", " : "", chk.max_acc[a]);
		}
		fprintf(sf, "],\n  \"max_axis_vel\": [");
		for (int a = 0; a < n; a++) {
			fprintf(sf, "%s%.12g", a ? ", " : "", chk.max_vel[a]);
		}
		fprintf(sf, "],\n  \"accel_limit\": [");
		for (int a = 0; a < n; a++) {
			fprintf(sf, "%s%.12g", a ? ", " : "", m->axis[a].max_accel);
		}
		fprintf(sf, "],\n  \"vel_limit\": [");
		for (int a = 0; a < n; a++) {
			fprintf(sf, "%s%.12g", a ? ", " : "", m->axis[a].max_vel);
		}
		fprintf(sf, "],\n  \"max_contour_error_mm\": %.9g,\n", chk.max_contour_mm);
		fprintf(sf, "  \"end_error_mm\": %.3g,\n", mlip_check_end_error(&chk));
		fprintf(sf, "  \"vmax_mm_s\": %.9g,\n  \"eps_mm\": %.9g,\n  \"period_s\": %.9g,\n",
		        m->max_feed_mm_s, m->tolerance_mm, m->period_s);
		fprintf(sf, "  \"lookahead\": %lu,\n  \"backward_visits_per_block\": %.3f,\n",
		        lookahead, visits);
		fprintf(sf, "  \"offsets\": \"%s\",\n", offs);
		fprintf(sf, "  \"override_events\": %llu,\n", (unsigned long long)storm.events);
		fprintf(sf, "  \"dwells\": %llu,\n  \"pauses\": %llu,\n",
		        (unsigned long long)dwells, (unsigned long long)pauses);
		fprintf(sf, "  \"order_errors\": %zu,\n  \"violations\": %d\n}\n", chk.order_errors,
		        bad);
		if (sf != stdout) {
			fclose(sf);
		}
	}
	if (!quiet) {
		fprintf(stderr,
		        PROG ": %s: %s %.3f s, %zu blocks, %.1f mm, max speed %.2f mm/s, "
		             "max contour error %.6f mm\n",
		        path, mlip_cli_strategy_name((mlip_strategy)st), total, prog.n, path_mm,
		        chk.max_speed_mm_s, chk.max_contour_mm);
	}
	mlip_program_close(&cprog);
	if (save_offsets &&
	    mlip_offsets_save(mo.offsets, m, &prog.offsets_end, PROG, stderr) != 0) {
		mlip_program_close(&prog);
		return 1;
	}
	mlip_program_close(&prog);
	if (bad) {
		fprintf(stderr,
		        PROG ": %s: the trace breaks the machine's limits (%d check(s)):\n%s", path,
		        bad, vmsg);
		return 4;
	}
	return 0;
}
