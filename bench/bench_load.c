/*
 * bench_load - program loading as mlip-feed does it: check the whole file
 * (every error listed), then stream its blocks, in memory bounded by a
 * constant (tools/lib/program.h). Prints one JSON line: blocks, lines, the
 * time of each pass and the peak resident set size (getrusage), so that
 * bench/rss.py can show the RSS does not grow with the program.
 *
 *   bench_load [--config FILE] PROGRAM.ngc
 */
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "cli.h"
#include "program.h"

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
	struct mlip_cli_machine mo = {0};
	static struct mlip_config cfg;
	static struct mlip_program prog;
	struct mlip_block b;
	struct rusage ru;
	const char *path = NULL;
	double t0, t1, t2, sum = 0.0;
	size_t n = 0;
	int rc;

	for (int a = 1; a < argc; a++) {
		if (strcmp(argv[a], "--config") == 0 && a + 1 < argc) {
			mo.config = argv[++a];
		} else {
			path = argv[a];
		}
	}
	if (path == NULL) {
		fprintf(stderr, "usage: bench_load [--config FILE] PROGRAM.ngc\n");
		return 2;
	}
	t0 = now_s();
	if (mlip_cli_open_program(path, &mo, &cfg, &prog, "bench_load", stderr) != 0) {
		return 1;
	}
	t1 = now_s();
	while ((rc = mlip_program_next(&prog, &b)) > 0) {
		sum += b.target[0]; /* use every block */
		n++;
	}
	t2 = now_s();
	if (rc < 0) {
		fprintf(stderr, "bench_load: %s: %s\n", path, prog.msg);
		return 1;
	}
	getrusage(RUSAGE_SELF, &ru);
	printf("{\"blocks\": %zu, \"lines\": %u, \"check_s\": %.3f, \"stream_s\": %.3f, "
	       "\"max_rss_kb\": %ld, \"checksum\": %.6g}\n",
	       n, (unsigned)prog.lines, t1 - t0, t2 - t1, ru.ru_maxrss, sum);
	mlip_program_close(&prog);
	return 0;
}
