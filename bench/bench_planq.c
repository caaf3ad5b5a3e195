/*
 * bench_planq - the path-speed plan through its queue (mlip/motion/planq.h)
 * on a real program: `smooth`'s setpoints without J (mlip-sim --strategy
 * smooth --feed F --trace OUT.csv) fed to the pathrun, one planned period
 * queued per period and sometimes two (the thread ahead), the producer
 * stalled at random, the period holding and lowering its feed at random.
 * The setpoints are judged by their differences (A, J per axis). Prints
 * JSON: periods, starvings, holds, the largest A and J over their limits.
 * The period's instructions per call, one callgrind part a call:
 *
 *   valgrind --tool=callgrind --toggle-collect=mlip_planq_step \
 *       --dump-after=mlip_planq_step --combine-dumps=yes \
 *       build/bench_planq OUT.csv --jerk 1e5
 *
 *   build/bench_planq TRACE.csv --jerk J [--accel A] [--feed F] [--seed S]
 *                     [--stall P] [--hold P]
 *
 * A 1000 mm/s^2, F 200 mm/s by default (the trace's own); P: the chance a
 * period starts a stall of 20-700 periods (1/500) or a hold or a lower
 * feed (1/2000 each). The band (P6) is 0.001 mm.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mlip/motion/planq.h"

static struct mlip_pathrun run;
static struct mlip_planq queue;
static uint64_t seed = 88172645463325252ull;

static double draw(void)
{
	seed ^= seed << 13;
	seed ^= seed >> 7;
	seed ^= seed << 17;
	return (double)(seed >> 11) / 9007199254740992.0;
}

/* The trace's next row's positions (t first): its axes, 0 at the end. */
static int row(FILE *f, double *x)
{
	char line[512];
	while (fgets(line, sizeof(line), f)) {
		if (line[0] < '0' || line[0] > '9') {
			continue; /* the header */
		}
		int n = 0;
		char *p = strchr(line, ',');
		while (p && n < MLIP_MAX_AXES) {
			x[n++] = strtod(p + 1, &p);
			p = *p == ',' ? p : NULL;
		}
		return n;
	}
	return 0;
}

int main(int argc, char **argv)
{
	double jerk = 0.0, accel = 1000.0, feed = 200.0, p_stall = 1.0 / 500, p_hold = 1.0 / 2000;
	if (argc < 2) {
		fprintf(stderr, "usage: bench_planq TRACE.csv --jerk J [--accel A] [--feed F] "
		                "[--seed S] [--stall P] [--hold P]\n");
		return 2;
	}
	for (int a = 2; a + 1 < argc; a += 2) {
		double v = atof(argv[a + 1]);
		if (!strcmp(argv[a], "--jerk")) {
			jerk = v;
		} else if (!strcmp(argv[a], "--accel")) {
			accel = v;
		} else if (!strcmp(argv[a], "--feed")) {
			feed = v;
		} else if (!strcmp(argv[a], "--seed")) {
			seed = (uint64_t)v + 1;
		} else if (!strcmp(argv[a], "--stall")) {
			p_stall = v;
		} else if (!strcmp(argv[a], "--hold")) {
			p_hold = v;
		} else {
			fprintf(stderr, "bench_planq: unknown option %s\n", argv[a]);
			return 2;
		}
	}
	FILE *f = fopen(argv[1], "r");
	if (!f || !(jerk > 0.0)) {
		fprintf(stderr, "bench_planq: %s: %s\n", argv[1],
		        f ? "--jerk J > 0 needed" : "cannot open");
		return 2;
	}
	double in[MLIP_MAX_AXES], x[MLIP_MAX_AXES], out[4][MLIP_MAX_AXES];
	int n = row(f, in);
	struct mlip_path_limits lim = {.n = n, .vmax = 0.995 * feed, .period = 1e-3, .n_brake = 2};
	lim.a_brake[0] = 900.0;
	lim.a_brake[1] = 300.0;
	for (int k = 0; k < n; k++) {
		lim.accel[k] = 0.98 * accel;
		lim.jerk[k] = 0.95 * jerk;
	}
	if (n < 1 || mlip_pathrun_init(&run, &lim, 1e-3, 3000, in) != 0) {
		fprintf(stderr, "bench_planq: %s: no setpoints\n", argv[1]);
		return 2;
	}
	mlip_planq_init(&queue, &run);
	for (int i = 0; i < 4; i++) {
		memcpy(out[i], in, sizeof(in));
	}
	int pending = 0, ended = 0, mode = MLIP_PLANQ_WAIT;
	long stall = 0, holding = 0, periods = 0, holds = 0, feeds = 0;
	double max_a = 0.0, max_j = 0.0;
	while (mode != MLIP_PLANQ_DONE && periods < 100000000L) {
		/* the producer: two planned periods at most, their input first */
		for (int planned = 0; stall == 0 && planned < 2;) {
			if (!pending && !ended) {
				pending = row(f, in) == n;
				if (!pending && mlip_pathrun_finish(&run) != 0) {
					break;
				}
				ended = !pending;
				continue;
			}
			int r = pending ? mlip_pathrun_push(&run, in) : 1;
			if (r == 0) {
				pending = 0;
				continue;
			}
			r = r == 1 ? mlip_planq_produce(&queue, &run) : r;
			if (r <= 0 || r == 2 || r == 3) {
				if (r < 0) {
					fprintf(stderr, "bench_planq: %s: %s at %.3f mm\n", argv[1],
					        run.why, run.why_s);
					return 1;
				}
				break;
			}
			planned++;
		}
		stall = stall > 0 ? stall - 1 : (draw() < p_stall ? (long)(20 + 680 * draw()) : 0);
		if (holding == 0 && draw() < p_hold) {
			holding = (long)(1 + 1000 * draw());
			holds++;
		}
		if (draw() < p_hold) {
			mlip_planq_feed(&queue, (0.3 + 0.7 * draw()) * lim.vmax);
			feeds++;
		}
		mode = mlip_planq_step(&queue, holding > 0, x);
		holding -= holding > 0;
		if (mode < 0) {
			fprintf(stderr, "bench_planq: %s: the braking run had no jerk\n", argv[1]);
			return 1;
		}
		memmove(out[1], out[0], sizeof(out[0]) * 3);
		memcpy(out[0], x, sizeof(x));
		for (int k = 0; k < n; k++) {
			double j = out[0][k] - 3 * out[1][k] + 3 * out[2][k] - out[3][k];
			max_j = fmax(max_j, fabs(j) / 1e-9 / jerk);
			max_a =
			    fmax(max_a, fabs(out[0][k] - 2 * out[1][k] + out[2][k]) / 1e-6 / accel);
		}
		periods++;
	}
	fclose(f);
	printf(
	    "{\"periods\": %ld, \"done\": %d, \"starved\": %ld, \"brakes\": %ld, \"holds\": %ld, "
	    "\"feeds\": %ld, \"a_over_A\": %.6f, \"j_over_J\": %.6f}\n",
	    periods, mode == MLIP_PLANQ_DONE, queue.c.starved, queue.c.brakes, holds, feeds, max_a,
	    max_j);
	return mode == MLIP_PLANQ_DONE && max_a <= 1.0 + 1e-6 && max_j <= 1.0 + 1e-6 ? 0 : 1;
}
