/*
 * bench_period - the controller's compute time per period, with the noise of
 * a shared machine taken out: the same program run R times from the start
 * (every run does the same work in the same period: the records are offered
 * as mlip-sim offers them, all that fit), each period timed around
 * mlip_ctl_period, and each period's least time over the runs kept; then
 * percentiles of those least times and where the largest is. Preemption,
 * interrupts and the other engineers' jobs only add time, to some runs and
 * not others, so the least of several runs is the work's own cost (cache
 * effects of a tight loop included: warmer than the 1 ms loop's, which
 * mlip-latency measures). The first period (the pre-read's first batch and
 * the look-ahead's first work) is reported apart.
 *
 *   build/bench_period CONFIG PROGRAM STRATEGY [PERIODS [RUNS [JERK [FLAGS [LOOKAHEAD]]]]]
 *   e.g. build/bench_period config/mill-3axis.ini \
 *            ../shared/toolpaths/MB-2.3_test.nc smooth 60000 5 1e5
 *
 * PERIODS (default 60000: a minute of machining) bounds the memory and the
 * time; JERK > 0 sets every axis's MAX_JERK; `sync`: the look-ahead's work
 * all at once in the period that asks for it (mlip_planner_set_async 0, the
 * planner before bounded work), for the figures before and after.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#if defined(__has_include)
#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#endif
#endif
#ifndef CALLGRIND_TOGGLE_COLLECT /* no valgrind headers: `insns` counts nothing */
#define CALLGRIND_TOGGLE_COLLECT
#define CALLGRIND_DUMP_STATS_AT(s) ((void)(s))
#endif

#include "blockiter.h"
#include "cli.h"
#include "confload.h"
#include "mlip/ctl/controller.h"
#include "mlip/motion/smooth.h"
#include "program.h"

static struct mlip_planner planner;
static struct mlip_smooth_store store;
static struct mlip_ctl ctl;

static double now_us(void)
{
	struct timespec t;
	clock_gettime(CLOCK_MONOTONIC, &t);
	return (double)t.tv_sec * 1e6 + (double)t.tv_nsec * 1e-3;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

/* One run from the start: the least time of each period into best[]. */
static int run(const struct mlip_machine *m, mlip_strategy st, uint32_t lookahead,
               const struct mlip_block *prog, size_t n, double *best, size_t periods, int sync,
               int insns, size_t *moved)
{
	size_t bytes = mlip_ring_bytes(MLIP_RING_CAPACITY);
	void *mem = NULL;
	struct mlip_ring *ring = NULL;
	struct mlip_ring_port rx;
	if (posix_memalign(&mem, MLIP_RING_LINE, bytes) != 0 ||
	    mlip_ring_format_machine(mem, bytes, MLIP_RING_CAPACITY, m) != MLIP_OK ||
	    mlip_ring_attach(mem, bytes, m->n_axes, &ring, NULL) != MLIP_OK ||
	    mlip_ring_port_open(&rx, ring, 0) != MLIP_OK) {
		free(mem);
		return -1;
	}
	struct mlip_ctl_opts o = {.strategy = st,
	                          .smooth = st == MLIP_STRATEGY_SMOOTH ? &store : NULL,
	                          .lookahead = lookahead,
	                          .stall_periods = UINT32_MAX};
	if (mlip_ctl_init(&ctl, &planner, m, &o) != MLIP_OK) {
		free(mem);
		return -1;
	}
	mlip_planner_set_async(&planner, !sync);
	uint64_t seq = 0;
	size_t next = 0, moving = 0;
	struct mlip_ctl_out out;
	double last[MLIP_MAX_AXES] = {0};
	for (size_t k = 0; k < periods; k++) {
		while (mlip_ring_space(ring) > 0 && seq <= n) {
			struct mlip_ring_rec rec;
			if (next < n) {
				mlip_ring_rec_from_block(&rec, &prog[next++], ++seq);
			} else {
				mlip_ring_rec_end(&rec, ++seq, 0);
			}
			mlip_ring_push_n(ring, &rec, 1);
		}
		struct mlip_ctl_in in = {.period = k, .feeder_alive = 1};
		CALLGRIND_TOGGLE_COLLECT;
		double t0 = now_us();
		if (mlip_ring_port_view(&rx, &in.recs, &in.recs_corrupt) == MLIP_OK) {
			in.recs_corrupt = 0;
		}
		mlip_ctl_period(&ctl, &in, &out);
		mlip_ring_port_pop_n(&rx, out.taken);
		double dt = now_us() - t0;
		CALLGRIND_TOGGLE_COLLECT;
		if (insns) {
			CALLGRIND_DUMP_STATS_AT("period"); /* one part a period: its instructions */
		}
		best[k] = dt < best[k] ? dt : best[k];
		moving += memcmp(out.pos, last, sizeof(last)) != 0;
		memcpy(last, out.pos, sizeof(last));
	}
	*moved = moving;
	free(mem);
	return 0;
}

int main(int argc, char **argv)
{
	if (argc < 4) {
		fprintf(stderr,
		        "usage: bench_period CONFIG PROGRAM STRATEGY [PERIODS [RUNS [JERK]]]\n");
		return 2;
	}
	size_t periods = argc > 4 ? strtoul(argv[4], NULL, 0) : 60000;
	int runs = argc > 5 ? atoi(argv[5]) : 5;
	double jerk = argc > 6 ? strtod(argv[6], NULL) : 0.0;
	const char *flags = argc > 7 ? argv[7] : "";

	int sync = strstr(flags, "sync") != NULL, insns = strstr(flags, "insns") != NULL;
	int st = mlip_cli_strategy(argv[3]);
	static struct mlip_config cfg;
	static struct mlip_program_list prog;
	if (st < 0 || periods < 2 || runs < 1 || mlip_config_load(argv[1], &cfg, stderr) != 0) {
		fprintf(stderr, "bench_period: bad strategy, periods, runs or config\n");
		return 2;
	}
	for (int k = 0; jerk > 0.0 && k < cfg.machine.n_axes; k++) {
		cfg.machine.axis[k].max_jerk = jerk;
	}
	if (argc > 8) {
		cfg.lookahead = (uint32_t)strtoul(argv[8], NULL, 0); /* a power of two */
	}
	if (mlip_program_list_load(argv[2], &cfg.machine, &prog) != 0 || prog.n == 0) {
		fprintf(stderr, "bench_period: %s: no program\n", argv[2]);
		return 1;
	}
	if (st == MLIP_STRATEGY_SMOOTH) { /* the records mlip-feed sends */
		struct mlip_block *sb;
		size_t sn;
		if (mlip_smooth_program(&cfg.machine, prog.blocks, prog.n, &sb, &sn) != 0) {
			return 1;
		}
		free(prog.blocks);
		prog.blocks = sb;
		prog.n = prog.cap = sn;
	}
	double *best = malloc(periods * sizeof(double));
	if (best == NULL) {
		return 1;
	}
	for (size_t k = 0; k < periods; k++) {
		best[k] = INFINITY;
	}
	size_t moved = 0;
	for (int r = 0; r < runs; r++) {
		if (run(&cfg.machine, (mlip_strategy)st, cfg.lookahead, prog.blocks, prog.n, best,
		        periods, sync, insns, &moved) != 0) {
			fprintf(stderr, "bench_period: the controller refused the machine\n");
			return 1;
		}
	}
	size_t at = 0;
	for (size_t k = 1; k < periods; k++) {
		at = best[k] > best[at] ? k : at;
	}
	double first = best[0], worst = best[at];
	qsort(best, periods, sizeof(double), cmp_double);
	static const double q[] = {0.5, 0.99, 0.999, 0.9999};
	printf("%s %s J %g%s: %zu periods (%zu moving), least of %d runs, us: first %.1f", argv[2],
	       argv[3], jerk, sync ? " all at once" : "", periods, moved, runs, first);
	for (int i = 0; i < 4; i++) {
		printf(" p%g %.1f", q[i] * 100.0, best[(size_t)(q[i] * (double)(periods - 1))]);
	}
	printf(" max %.1f at %zu\n", worst, at);
	free(best);
	mlip_program_list_free(&prog);
	return 0;
}
