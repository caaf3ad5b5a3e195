/*
 * bench_validate.c - the cost of the controller's record check
 * (mlip_ctl_check_record, done for every record where it is taken):
 * a valid 6-axis MOVE, the worst case (every test runs). Prints ns per
 * record; for instructions run it under callgrind:
 *   valgrind --tool=callgrind --toggle-collect=mlip_ctl_check_record \
 *     build/bench_validate 100000   (Ir / 100000 = instructions per record)
 */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "mlip/ctl/controller.h"

int main(int argc, char **argv)
{
	long n = argc > 1 ? atol(argv[1]) : 10000000L;
	struct mlip_machine m = {.n_axes = MLIP_MAX_AXES};
	struct mlip_ring_rec rec = {
	    .seq = 1, .type = MLIP_REC_MOVE, .feed_mm_s = 100.0, .tol_mm = 0.01};
	for (int k = 0; k < MLIP_MAX_AXES; k++) {
		m.axis[k].min_limit = -1000.0;
		m.axis[k].max_limit = 1000.0;
		rec.target[k] = 0.5 * k;
	}
	struct timespec t0, t1;
	long bad = 0;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	for (long i = 0; i < n; i++) {
		rec.seq = (uint64_t)i + 1;
		bad += mlip_ctl_check_record(&m, &rec, (uint64_t)i + 1, NULL) != MLIP_OK;
	}
	clock_gettime(CLOCK_MONOTONIC, &t1);
	double ns = (double)(t1.tv_sec - t0.tv_sec) * 1e9 + (double)(t1.tv_nsec - t0.tv_nsec);
	printf("bench_validate: %ld records, %.2f ns each, %ld refused\n", n, ns / (double)n, bad);
	return bad != 0;
}
