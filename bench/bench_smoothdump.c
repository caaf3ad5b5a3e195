/*
 * bench_smoothdump - the polyline the `smooth` strategy hands the planner
 * (src/motion/smooth.c through blockiter's mlip_smooth_program, as mlip-sim runs
 * it), for bench/topp.py's time-optimal ceiling of that path.
 *
 *   bench_smoothdump FILE.ngc [--accel A[,A...]] [--raw]
 *
 * At the bench's settings (feed 200 mm/s for every move, G0 included, as
 * mlip-sim --feed; vmax 200, eps 0.01, T 1 ms). Prints CSV: one row per
 * point, the machine's start (home) first, then each move's target; the
 * last column is the block's tol_mm (the corner budget; 0 for the start).
 * --raw: the program's own polyline, unsmoothed.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "blockiter.h"
#include "cli.h"
#include "program.h"

int main(int argc, char **argv)
{
	if (argc < 2) {
		fprintf(stderr, "usage: bench_smoothdump FILE.ngc [--accel A[,A...]] [--raw]\n");
		return 2;
	}
	const char *path = argv[1], *accel = "1000";
	int raw = 0;
	for (int a = 2; a < argc; a++) {
		if (strcmp(argv[a], "--accel") == 0 && a + 1 < argc) {
			accel = argv[++a];
		} else if (strcmp(argv[a], "--raw") == 0) {
			raw = 1;
		}
	}
	struct mlip_cli_machine mo = {
	    .accel = accel, .vmax_mm_s = 200, .eps_mm = 0.01, .period_s = 0.001};
	static struct mlip_config cfg;
	static struct mlip_program_list prog;
	if (mlip_cli_build_machine(&mo, path, &cfg, "bench_smoothdump", stderr) != 0 ||
	    mlip_program_list_load(path, &cfg.machine, &prog) != 0) {
		return 1;
	}
	const struct mlip_machine *m = &cfg.machine;
	for (size_t i = 0; i < prog.n; i++) {
		prog.blocks[i].feed_mm_s = 200.0; /* mlip-sim --feed 200 */
		prog.blocks[i].rapid = 0;
	}
	struct mlip_block *out = prog.blocks;
	size_t nout = prog.n;
	if (!raw && mlip_smooth_program(m, prog.blocks, prog.n, &out, &nout) != 0) {
		fprintf(stderr, "bench_smoothdump: the filter refused %s\n", path);
		return 1;
	}
	for (int k = 0; k < m->n_axes; k++) {
		printf("%.17g,", m->axis[k].home);
	}
	printf("0\n");
	for (size_t i = 0; i < nout; i++) {
		if (out[i].kind != MLIP_BLOCK_MOVE) {
			continue;
		}
		for (int k = 0; k < m->n_axes; k++) {
			printf("%.17g,", out[i].target[k]);
		}
		printf("%.17g\n", out[i].tol_mm);
	}
	if (out != prog.blocks) {
		free(out);
	}
	mlip_program_list_free(&prog);
	return 0;
}
