/*
 * bench_pathplan - the path-speed plan's cost per planned period
 * (src/motion/pathplan.c, Q1-Q4; docs/algorithm.md "The path-speed plan"):
 * the greedy plan from rest to rest along a helix of radius 4 mm rising
 * 0.5 mm a radian (the one test_pathplan plans), sampled every STEP mm of
 * arc into a spline of MLIP_PATH_WIN points, at jerk limit J on every axis
 * (A 1000 mm/s^2, 200 mm/s, the model's margins). Prints the planned
 * periods and the braking-run periods simulated, as JSON. For instructions
 * run it under callgrind and divide by the periods:
 *
 *   valgrind --tool=callgrind --toggle-collect=bench_plan_period \
 *       build/bench_pathplan 1e4 0.4
 *
 *   build/bench_pathplan J [STEP]     (STEP default 0.4)
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mlip/motion/pathplan.h"

static struct mlip_path_spline sp;

/* FNV-1a over the states' bits: two builds plan the same periods exactly
 * when their hashes agree (a cheaper period must not change the plan). */
static uint64_t fnv(uint64_t h, double x)
{
	unsigned char b[sizeof x];
	memcpy(b, &x, sizeof x);
	for (size_t i = 0; i < sizeof x; i++) {
		h = (h ^ b[i]) * 1099511628211ull;
	}
	return h;
}

/* One planned period. Named for callgrind's --toggle-collect. */
__attribute__((noinline)) int bench_plan_period(const struct mlip_path_limits *lim,
                                                struct mlip_path_state *st, double end, long *work);
int bench_plan_period(const struct mlip_path_limits *lim, struct mlip_path_state *st, double end,
                      long *work)
{
	return mlip_path_plan_period(&sp, lim, st, end, 3000, work);
}

int main(int argc, char **argv)
{
	if (argc < 2 || argc > 3) {
		fprintf(stderr, "usage: bench_pathplan J [STEP]\n");
		return 2;
	}
	double J = atof(argv[1]), step = argc > 2 ? atof(argv[2]) : 0.4;
	if (!(J > 0.0) || !(step > 0.0)) {
		fprintf(stderr, "bench_pathplan: J and STEP must be > 0\n");
		return 2;
	}
	static double pts[MLIP_PATH_WIN][MLIP_MAX_AXES];
	double R = 4.0, c = 0.5, L = sqrt(R * R + c * c);
	for (int i = 0; i < MLIP_PATH_WIN; i++) {
		double th = i * step / L;
		pts[i][0] = R * cos(th);
		pts[i][1] = R * sin(th);
		pts[i][2] = c * th;
	}
	if (mlip_path_spline_fit(&sp, 3, (const double(*)[MLIP_MAX_AXES])pts, MLIP_PATH_WIN) != 0) {
		fprintf(stderr, "bench_pathplan: the spline does not fit\n");
		return 1;
	}
	struct mlip_path_limits lim = {0};
	lim.n = 3;
	for (int k = 0; k < 3; k++) {
		lim.accel[k] = 0.98 * 1000.0;
		lim.jerk[k] = 0.95 * J;
	}
	lim.vmax = 0.995 * 200.0;
	lim.a_brake = 300.0;
	lim.v_crawl = 2.0;
	lim.period = 1e-3;
	double end = sp.s[MLIP_PATH_WIN - 1], vpeak = 0.0;
	struct mlip_path_state st = {0.0, 0.0, 0.0};
	long work = 0, periods = 0, moved = 0;
	uint64_t hash = 14695981039346656037ull;
	while (!(st.v <= lim.v_crawl && fabs(st.a) < 1.0 && end - st.s < 1.0 && periods > 10)) {
		int r = bench_plan_period(&lim, &st, end, &work);
		if (r < 0 || periods > 1000000) {
			fprintf(stderr, "bench_pathplan: the plan left the certified states\n");
			return 1;
		}
		moved += r;
		periods++;
		vpeak = fmax(vpeak, st.v);
		hash = fnv(fnv(fnv(hash, st.s), st.v), st.a);
	}
	printf(
	    "{\"jerk\": %g, \"step\": %g, \"periods\": %ld, \"faster\": %ld, "
	    "\"run_periods\": %ld, \"peak_speed\": %.3f, \"s\": %.6f, \"states\": \"%016llx\"}\n",
	    J, step, periods, moved, work, vpeak, st.s, (unsigned long long)hash);
	return 0;
}
