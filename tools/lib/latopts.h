/* mlip-latency's command line (cyclictest's letters where they overlap):
 * the loads, the options and their defaults. */
#ifndef MLIP_LATOPTS_H
#define MLIP_LATOPTS_H

#include <stdint.h>
#include <stdio.h>

#define PROG                "mlip-latency"
#define DEFAULT_CONFIG      "config/mill-3axis.ini"
#define DEFAULT_CAN_PROGRAM "examples/demo.ngc" /* --can without --plan */
#define DEFAULT_PRIORITY    80                  /* mlip-rt's */
#define DEFAULT_INTERVAL_US 1000                /* --idle without -i */
#define DEFAULT_HIST_US     10000               /* histogram shown: 0..10 ms */
#define MAX_HIST_US         10000000            /* -h at most 10 s */
#define BIN_NS              1000                /* 1 us bins */
enum { MODE_IDLE, MODE_PLAN, MODE_CAN };

struct lat_opts {
	int mode;
	const char *program, *iface, *config, *json;
	int config_given;
	int priority, cpu, lock_memory, quiet, compare;
	int64_t interval_us; /* 0: the config's PERIOD (plan, can) or 1000 */
	double duration_s;   /* 0: none */
	const char *duration_arg;
	uint64_t loops;
	uint32_t hist_us;
	int hist_given;
	int strategy; /* mlip_strategy for --plan/--can */
};

void lat_usage(FILE *f);
/* o from the command line: 0 to run, -1 after --help, 2 on a usage error
 * (said on stderr). */
int lat_parse_opts(int argc, char **argv, struct lat_opts *o);

#endif
