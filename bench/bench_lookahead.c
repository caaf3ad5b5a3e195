/*
 * bench_lookahead - Table 1 of the paper, redone: the cost of pre-reading
 * N blocks (corner planning of each, eqs 1-20, and backward reachability
 * with the termination condition, Sec. 2.1), and of adding one block while
 * running, with how many corners each re-run visits before terminating.
 *
 * Medians of many runs on windows taken across the program. Timings are
 * CLOCK_MONOTONIC; on a shared, noisy machine, read the instruction counts
 * (`--mode` under `valgrind --tool=callgrind --toggle-collect=bench_*`)
 * rather than single timings. bench/run.py drives both.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cli.h"
#include "mlip/motion/planner.h"
#include "program.h"

static struct mlip_planner P;
static struct mlip_program_list prog;
static struct mlip_machine machine;

static uint64_t now_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000000ULL + (uint64_t)ts.tv_nsec;
}

static int cmp_u64(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return x < y ? -1 : x > y;
}

static uint64_t median(uint64_t *v, size_t n)
{
	qsort(v, n, sizeof(*v), cmp_u64);
	return v[n / 2];
}

static void start_at(size_t i)
{
	double start[MLIP_MAX_AXES];
	const double *from = i > 0 ? prog.blocks[i - 1].target : NULL;
	for (int k = 0; k < machine.n_axes; k++) {
		start[k] = from ? from[k] : machine.axis[k].home;
	}
	mlip_planner_init(&P, &machine, MLIP_STRATEGY_MPCT, 0, start, NULL);
}

/* Pre-read n blocks from offset i (the machine at rest). Named for
 * callgrind's --toggle-collect. */
__attribute__((noinline)) void bench_preread(size_t i, size_t n);
void bench_preread(size_t i, size_t n)
{
	mlip_planner_push_n(&P, prog.blocks + i, n, NULL);
}

/* One corner's parameters (eqs 1-20) for every block of a window. */
__attribute__((noinline)) double bench_corners(size_t i, size_t n);
double bench_corners(size_t i, size_t n)
{
	double acc = 0.0, A[MLIP_MAX_AXES];
	for (int k = 0; k < machine.n_axes; k++) {
		A[k] = machine.axis[k].max_accel;
	}
	for (size_t j = 0; j + 2 < n; j++) {
		const double *p0 = prog.blocks[i + j].target, *p1 = prog.blocks[i + j + 1].target,
		             *p2 = prog.blocks[i + j + 2].target;
		double es[MLIP_MAX_AXES], ee[MLIP_MAX_AXES], ds = 0, de = 0;
		for (int k = 0; k < machine.n_axes; k++) {
			es[k] = p1[k] - p0[k];
			ee[k] = p2[k] - p1[k];
			ds += es[k] * es[k];
			de += ee[k] * ee[k];
		}
		ds = sqrt(ds);
		de = sqrt(de);
		if (ds == 0.0 || de == 0.0) {
			continue;
		}
		for (int k = 0; k < machine.n_axes; k++) {
			es[k] /= ds;
			ee[k] /= de;
		}
		struct mlip_corner c;
		mlip_corner_plan(machine.n_axes, MLIP_STRATEGY_MPCT, es, ee, ds, de, A,
		                 machine.tolerance_mm, 200.0, 200.0, machine.period_s, &c);
		acc += c.t_s;
	}
	return acc;
}

/* Running: one period's work, split so the push alone can be timed. */
__attribute__((noinline)) void bench_push_one(const struct mlip_block *b);
void bench_push_one(const struct mlip_block *b)
{
	mlip_planner_push(&P, b);
}

int main(int argc, char **argv)
{
	if (argc < 2) {
		fprintf(stderr, "usage: bench_lookahead FILE.ngc [--accel A] [--mode "
		                "preread|corners|push N] [--reps R]\n");
		return 2;
	}
	const char *path = argv[1], *mode = NULL, *accel = "1000";
	size_t mode_n = 4000;
	int reps = 41;
	for (int a = 2; a < argc; a++) {
		if (strcmp(argv[a], "--accel") == 0 && a + 1 < argc) {
			accel = argv[++a];
		} else if (strcmp(argv[a], "--mode") == 0 && a + 2 < argc) {
			mode = argv[++a];
			mode_n = strtoul(argv[++a], NULL, 10);
		} else if (strcmp(argv[a], "--reps") == 0 && a + 1 < argc) {
			reps = atoi(argv[++a]);
		}
	}
	struct mlip_cli_machine mo = {
	    .accel = accel, .vmax_mm_s = 200, .eps_mm = 0.01, .period_s = 0.001};
	static struct mlip_config cfg;
	if (mlip_cli_build_machine(&mo, path, &cfg, "bench", stderr) != 0 ||
	    mlip_program_list_load(path, &cfg.machine, &prog) != 0) {
		return 1;
	}
	machine = cfg.machine;
	for (size_t i = 0; i < prog.n; i++) {
		prog.blocks[i].feed_mm_s = 200.0; /* the paper's setting */
		prog.blocks[i].rapid = 0;
	}
	if (prog.n < 20000) {
		fprintf(stderr, "bench: %s has %zu blocks; need 20000\n", path, prog.n);
		return 1;
	}
	/* windows spread over the program, the same for every size */
	size_t span = prog.n - 4100;

	if (mode != NULL) {
		/* one measured operation for callgrind: the caller divides */
		if (strcmp(mode, "preread") == 0) {
			for (int r = 0; r < reps; r++) {
				start_at(span * (size_t)r / (size_t)reps);
				bench_preread(span * (size_t)r / (size_t)reps, mode_n);
			}
		} else if (strcmp(mode, "corners") == 0) {
			double s = 0;
			for (int r = 0; r < reps; r++) {
				s += bench_corners(span * (size_t)r / (size_t)reps, mode_n);
			}
			printf("%g\n", s);
		} else if (strcmp(mode, "push") == 0) {
			start_at(0);
			bench_preread(0, 4000);
			double x[MLIP_MAX_AXES];
			size_t next = 4000;
			uint64_t pushes = 0;
			while (pushes < mode_n && next < prog.n) {
				while (mlip_planner_space(&P) > 0 && next < prog.n &&
				       pushes < mode_n) {
					bench_push_one(&prog.blocks[next++]);
					pushes++;
				}
				mlip_planner_step(&P, x);
			}
		}
		return 0;
	}

	printf("{\n  \"file\": \"%s\",\n  \"accel\": \"%s\",\n  \"preread\": [\n", path, accel);
	static const size_t sizes[] = {1000, 2000, 3000, 4000};
	uint64_t *t = malloc(sizeof(uint64_t) * (size_t)reps);
	for (int si = 0; si < 4; si++) {
		size_t n = sizes[si];
		uint64_t visits = 0;
		for (int r = 0; r < reps; r++) {
			size_t i = span * (size_t)r / (size_t)reps;
			start_at(i);
			uint64_t t0 = now_ns();
			bench_preread(i, n);
			t[r] = now_ns() - t0;
			visits += P.stats.backward_visits;
		}
		uint64_t tp = median(t, (size_t)reps);
		/* a full backward pass alone over the same n blocks */
		for (int r = 0; r < reps; r++) {
			size_t i = span * (size_t)r / (size_t)reps;
			start_at(i);
			bench_preread(i, n);
			uint64_t t0 = now_ns();
			mlip_planner_set_override(&P, 100.0);
			t[r] = now_ns() - t0;
		}
		uint64_t tf = median(t, (size_t)reps);
		for (int r = 0; r < reps; r++) {
			uint64_t t0 = now_ns();
			bench_corners(span * (size_t)r / (size_t)reps, n);
			t[r] = now_ns() - t0;
		}
		uint64_t tc = median(t, (size_t)reps);
		printf("    {\"blocks\": %zu, \"preread_us\": %.2f, \"full_pass_us\": %.2f, "
		       "\"corners_us\": %.2f, \"visits_per_block\": %.2f}%s\n",
		       n, tp / 1e3, tf / 1e3, tc / 1e3, (double)visits / ((double)reps * (double)n),
		       si < 3 ? "," : "");
	}
	free(t);

	/* Running: the look-ahead full (4096), one period's ingest at a time. */
	size_t maxp = prog.n - 4000;
	uint64_t *tp = malloc(sizeof(uint64_t) * maxp);
	start_at(0);
	bench_preread(0, 4000);
	uint64_t v0 = P.stats.backward_visits, p0 = P.stats.pushes;
	double x[MLIP_MAX_AXES];
	size_t next = 4000, np = 0;
	while (next < prog.n) {
		while (mlip_planner_space(&P) > 0 && next < prog.n) {
			uint64_t t0 = now_ns();
			bench_push_one(&prog.blocks[next++]);
			tp[np++] = now_ns() - t0;
		}
		mlip_planner_step(&P, x);
	}
	double vis = (double)(P.stats.backward_visits - v0) / (double)(P.stats.pushes - p0);
	qsort(tp, np, sizeof(*tp), cmp_u64);
	printf(
	    "  ],\n  \"add_one_block\": {\"pushes\": %zu, \"median_ns\": %llu, \"p99_ns\": %llu, "
	    "\"max_ns\": %llu, \"visits_per_block\": %.1f}\n}\n",
	    np, (unsigned long long)tp[np / 2], (unsigned long long)tp[np * 99 / 100],
	    (unsigned long long)tp[np - 1], vis);
	free(tp);
	return 0;
}
