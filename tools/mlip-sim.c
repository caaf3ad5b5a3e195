/*
 * mlip-sim - the offline simulator: runs a G-code program through the very
 * same planner calls the real-time controller makes, on a virtual clock, and
 * writes the setpoints it would send (--trace) and a summary (--summary).
 *
 * Ingest follows the controller's rule (planner.h): fill the look-ahead
 * before the first period, then at most MLIP_INGEST_PER_PERIOD blocks per
 * period, so that both produce the same motion for the same program.
 */
#include <getopt.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "cli.h"
#include "mlip/gcode.h"
#include "mlip/planner.h"
#include "blockiter.h"
#include "program.h"

#define PROG "mlip-sim"
#define MAX_PERIODS 200000000ULL /* 55 h of machining at 1 ms: a runaway */

static struct mlip_planner planner; /* ~1.5 MB: static, like on the controller */

static void usage(FILE *f)
{
	fprintf(f,
	        "usage: " PROG " [options] FILE.ngc\n"
	        "Simulate a G-code program on the mlip interpolator and report its motion.\n\n"
	        "  --config FILE         machine INI (default: the axes the program uses, linear)\n"
	        "  --strategy NAME       mpct (default, the paper), bisector, stop, smooth (mpct on\n"
	        "                        the path smoothed within the tolerance, mlip/smooth.h)\n"
	        "  --accel A[,A...]      per-axis acceleration, mm/s^2 (one for all, or per axis)\n"
	        "  --vmax MM_S           maximum feed v_m, mm/s (default 200 without --config)\n"
	        "  --eps MM              contour tolerance (default 0.01 without --config)\n"
	        "  --period S            interpolation period T (default 0.001)\n"
	        "  --feed MM_S           ignore the program's F words, run every block at this feed\n"
	        "  --override PCT        feed override from the start, 0..200 (default 100)\n"
	        "  --storm SEED          random override changes, holds and resumes every 5-200\n"
	        "                        periods (a test of online override)\n"
	        "  --lookahead N         look-ahead capacity in blocks, power of two (default %d)\n"
	        "  --trace OUT.csv       setpoints: t,x,y,... one row per period, t = 0 to rest\n"
	        "  --summary OUT.json    totals and measured physics (JSON)\n"
	        "  --no-notes            do not list the words accepted without effect\n"
	        "  -q, --quiet           neither notes nor the summary line on stderr\n"
	        "  -h, --help            this help\n",
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
	uint64_t events;
};

/* Change the override or hold state at random periods; never leaves the
 * machine stopped for more than one event, so every program finishes. */
static void storm_tick(struct storm *st, uint64_t period)
{
	if (!st->active || period < st->next_at) {
		return;
	}
	st->next_at = period + 5 + rng_next(&st->state) % 196;
	st->events++;
	double r = rng_unit(&st->state);
	if (planner.hold) {
		mlip_planner_hold(&planner, 0);
	} else if (planner.override == 0.0) {
		mlip_planner_set_override(&planner, 10.0 + 190.0 * rng_unit(&st->state));
	} else if (r < 0.1) {
		mlip_planner_hold(&planner, 1);
	} else if (r < 0.2) {
		mlip_planner_set_override(&planner, 0.0);
	} else {
		mlip_planner_set_override(&planner, 10.0 + 190.0 * rng_unit(&st->state));
	}
}

static void write_row(FILE *f, uint64_t k, double T, int n, const double *x)
{
	fprintf(f, "%.17g", (double)k * T);
	for (int i = 0; i < n; i++) {
		fprintf(f, ",%.17g", x[i]);
	}
	fputc('\n', f);
}

int main(int argc, char **argv)
{
	struct mlip_cli_machine mo = {0};
	const char *strategy = "mpct", *trace_path = NULL, *summary_path = NULL;
	double feed = -1.0, override = 100.0;
	long long storm_seed = -1;
	unsigned long lookahead = 0;
	int quiet = 0, notes = 1;

	static const struct option opts[] = {
		{"config", required_argument, 0, 'c'},   {"strategy", required_argument, 0, 's'},
		{"accel", required_argument, 0, 'a'},    {"vmax", required_argument, 0, 'v'},
		{"eps", required_argument, 0, 'e'},      {"period", required_argument, 0, 'p'},
		{"feed", required_argument, 0, 'f'},     {"override", required_argument, 0, 'o'},
		{"storm", required_argument, 0, 'S'},    {"lookahead", required_argument, 0, 'L'},
		{"trace", required_argument, 0, 't'},    {"summary", required_argument, 0, 'j'},
		{"quiet", no_argument, 0, 'q'},          {"help", no_argument, 0, 'h'},
		{"no-notes", no_argument, 0, 'N'},
		{0, 0, 0, 0}};
	int c;
	while ((c = getopt_long(argc, argv, "qh", opts, NULL)) != -1) {
		double v;
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
			if (mlip_cli_number(optarg, &v) != 0 || !(v > 0.0 || (c == 'o' && v == 0.0))) {
				fprintf(stderr, PROG ": --%s: '%s' is not a positive number\n",
				        c == 'v' ? "vmax" : c == 'e' ? "eps" : c == 'p' ? "period" : c == 'f' ? "feed" : "override",
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
		fprintf(stderr, PROG ": --strategy: '%s' is not one of mpct, bisector, stop, smooth\n", strategy);
		return 2;
	}
	if (override > 200.0) {
		fprintf(stderr, PROG ": --override: %g is above 200 %%\n", override);
		return 2;
	}

	char *text;
	size_t len;
	struct mlip_config cfg;
	if (mlip_cli_open_program(path, &mo, &cfg, &text, &len, PROG, stderr) != 0) {
		return 1;
	}
	int rc;
	const struct mlip_machine *m = &cfg.machine;
	int n = m->n_axes;
	if (lookahead == 0) {
		lookahead = cfg.lookahead ? cfg.lookahead : MLIP_LOOKAHEAD;
	}

	/* the whole program is checked before anything moves */
	struct mlip_program prog;
	rc = mlip_program_parse(text, len, m, &prog);
	free(text);
	if (rc != 0) {
		mlip_program_print_errors(&prog, path, stderr);
		mlip_program_free(&prog);
		return 1;
	}
	if (notes) {
		mlip_program_print_notices(&prog, path, stderr);
	}
	for (size_t i = 0; i < prog.n; i++) {
		prog.blocks[i].seq = i + 1; /* as mlip-feed numbers ring records */
	}
	if (feed > 0.0) {
		for (size_t i = 0; i < prog.n; i++) {
			prog.blocks[i].feed_mm_s = feed;
			prog.blocks[i].rapid = 0;
		}
	}

	double start[MLIP_MAX_AXES];
	for (int k = 0; k < n; k++) {
		start[k] = m->axis[k].home;
	}
	if (mlip_planner_init(&planner, m, (mlip_strategy)st, (uint32_t)lookahead, start) != MLIP_OK) {
		fprintf(stderr, PROG ": look-ahead %lu must be a power of two in 2..%d\n", lookahead,
		        MLIP_LOOKAHEAD);
		return 1;
	}
	mlip_planner_set_override(&planner, override);

	size_t npts;
	/* judged against the ORIGINAL program's polyline, whatever runs */
	double *pts = mlip_cli_polyline(m, prog.blocks, prog.n, &npts);
	const struct mlip_block *run_blocks = prog.blocks;
	size_t run_n = prog.n;
	struct mlip_block *smoothed = NULL;
	if (st == MLIP_STRATEGY_SMOOTH) {
		if (mlip_smooth_program(m, start, prog.blocks, prog.n, &smoothed, &run_n) != 0) {
			fprintf(stderr, PROG ": out of memory smoothing the program\n");
			return 1;
		}
		for (size_t i = 0; i < run_n; i++) {
			smoothed[i].seq = i + 1;
		}
		run_blocks = smoothed;
	}
	struct mlip_check_limits lim;
	mlip_cli_check_limits(m, &lim);
	static struct mlip_check chk;
	mlip_check_init(&chk, &lim, pts, npts);

	FILE *tf = NULL;
	static char tbuf[1 << 20];
	if (trace_path != NULL) {
		tf = strcmp(trace_path, "-") == 0 ? stdout : fopen(trace_path, "w");
		if (tf == NULL) {
			perror(trace_path);
			return 1;
		}
		setvbuf(tf, tbuf, _IOFBF, sizeof(tbuf));
		fputc('t', tf);
		for (int k = 0; k < n; k++) {
			fprintf(tf, ",%c", m->axis[k].letter + ('a' - 'A'));
		}
		fputc('\n', tf);
		write_row(tf, 0, m->period_s, n, start);
	}
	mlip_check_sample(&chk, start);

	struct storm storm = {.state = (uint64_t)storm_seed * 0x9E3779B97F4A7C15ULL + 1,
	                      .next_at = 1,
	                      .active = storm_seed >= 0};
	size_t next = 0;
	/* pre-read (Sec. 2.1 step 1): fill the look-ahead before moving */
	next += mlip_planner_push_n(&planner, run_blocks, run_n, NULL);
	uint64_t k = 0;
	double x[MLIP_MAX_AXES];
	for (;;) {
		size_t take = run_n - next < MLIP_INGEST_PER_PERIOD ? run_n - next : MLIP_INGEST_PER_PERIOD;
		if (take > 0) {
			next += mlip_planner_push_n(&planner, run_blocks + next, take, NULL);
		}
		storm_tick(&storm, k);
		mlip_run_state rs = mlip_planner_step(&planner, x);
		k++;
		mlip_check_sample(&chk, x);
		if (tf != NULL) {
			write_row(tf, k, m->period_s, n, x);
		}
		if (rs == MLIP_RUN_IDLE && next == run_n) {
			break;
		}
		if (k > MAX_PERIODS) {
			fprintf(stderr, PROG ": no end after %llu periods: aborting\n",
			        (unsigned long long)k);
			return 3;
		}
	}
	if (tf != NULL && tf != stdout && fclose(tf) != 0) {
		perror(trace_path);
		return 1;
	}
	if (tf == stdout) {
		fflush(stdout);
	}

	double total = (double)k * m->period_s;
	double path_mm = 0.0;
	for (size_t i = 1; i < npts; i++) {
		double s = 0.0;
		for (int a = 0; a < n; a++) {
			if (m->axis[a].kind == MLIP_AXIS_LINEAR) {
				double d = pts[i * (size_t)n + a] - pts[(i - 1) * (size_t)n + a];
				s += d * d;
			}
		}
		path_mm += sqrt(s);
	}
	double visits = planner.stats.pushes ? (double)planner.stats.backward_visits / (double)planner.stats.pushes : 0.0;

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
		        (unsigned long long)planner.stats.pushes);
		fprintf(sf, "  \"blocks_run\": %zu,\n", run_n); /* smooth: the filter's output */
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
		fprintf(sf, "  \"override_events\": %llu\n}\n", (unsigned long long)storm.events);
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
	free(pts);
	free(smoothed);
	mlip_program_free(&prog);
	return 0;
}
