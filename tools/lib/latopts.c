/* mlip-latency's command line: usage, the options parsed and checked. */
#include "latopts.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

/* ---- options ------------------------------------------------------------- */

void lat_usage(FILE *f)
{
	fprintf(
	    f,
	    "usage: " PROG " [--idle | --plan FILE.ngc | --can IFACE] [options]\n"
	    "Latency test of the controller's own periodic loop (mlip_rt_run: same thread,\n"
	    "priority and memory set-up as mlip-rt), idle or under the real per-period work.\n\n"
	    "Load (one; default --idle):\n"
	    "  --idle              wake up and sleep only, like cyclictest\n"
	    "  --plan FILE         the real controller tick on this program (as mlip-rt\n"
	    "                      --can none), frames encoded and discarded; restarts\n"
	    "                      the program whenever it ends\n"
	    "  --can IFACE         the same and the frames sent on IFACE, the send timed\n"
	    "                      apart; the program is --plan's (default " DEFAULT_CAN_PROGRAM
	    ")\n"
	    "  --config FILE       machine INI for --plan/--can (default " DEFAULT_CONFIG ")\n"
	    "  --strategy NAME     mpct (default), bisector, stop or smooth (the program\n"
	    "                      smoothed first, as mlip-feed sends it)\n\n"
	    "Loop (cyclictest's letters):\n"
	    "  -p, --priority N    SCHED_FIFO priority 1..99 (default %d, mlip-rt's;\n"
	    "                      0: SCHED_OTHER)\n"
	    "  -i, --interval US   period in microseconds (default: the config's PERIOD\n"
	    "                      for --plan/--can, which it then replaces; %d for --idle)\n"
	    "  -D, --duration T    run time: 10 or 10s (seconds), 1m, 2h, 1d (default: until\n"
	    "                      Ctrl-C or -l)\n"
	    "  -l, --loops N       stop after N periods (default: no limit)\n"
	    "  -a, --affinity CPU  pin the loop to this CPU (also --cpu; default: no pinning)\n"
	    "  -m, --mlockall      lock memory (the default, as mlip-rt does)\n"
	    "      --no-mlockall   do not lock memory\n"
	    "  -h, --histogram US  print 1 us histograms up to US (overflow above) on stdout,\n"
	    "                      and keep that range in the JSON (default %d)\n"
	    "  -q, --quiet         no live line, only the results\n"
	    "      --json FILE     results as JSON (a superset of cyclictest's --json)\n"
	    "      --compare-cyclictest\n"
	    "                      then run rt-tests' cyclictest with the same interval,\n"
	    "                      priority, affinity, memory locking and duration, and\n"
	    "                      print both in one table\n"
	    "      --help\n\n"
	    "Per period: wake-up latency (wake - scheduled, us), period jitter (|interval -\n"
	    "period|, us), compute time of the period's work (us), the send time (--can),\n"
	    "overruns (deadlines missed). Exit 0 when the test ran, 1 when it could not, 2 on\n"
	    "usage errors.\n",
	    DEFAULT_PRIORITY, DEFAULT_INTERVAL_US, DEFAULT_HIST_US);
}

/* cyclictest's -D forms: N (seconds), Ns, Nm, Nh, Nd. 0 or -1. */
static int parse_duration(const char *s, double *out)
{
	char *end;
	errno = 0;
	double v = strtod(s, &end);
	if (end == s || errno != 0 || !isfinite(v) || v <= 0) {
		return -1;
	}
	double mul = 1;
	if (*end != '\0') {
		switch (*end) {
		case 's':
			mul = 1;
			break;
		case 'm':
			mul = 60;
			break;
		case 'h':
			mul = 3600;
			break;
		case 'd':
			mul = 86400;
			break;
		default:
			return -1;
		}
		if (end[1] != '\0') {
			return -1;
		}
	}
	*out = v * mul;
	return *out < 1e9 ? 0 : -1;
}

static int parse_uint(const char *s, uint64_t max, uint64_t *out)
{
	char *end;
	if (*s == '\0' || *s == '-' || *s == '+') {
		return -1;
	}
	errno = 0;
	unsigned long long v = strtoull(s, &end, 10);
	if (*end != '\0' || errno != 0 || v > max) {
		return -1;
	}
	*out = v;
	return 0;
}

int lat_parse_opts(int argc, char **argv, struct lat_opts *o)
{
	enum {
		O_IDLE = 256,
		O_PLAN,
		O_CAN,
		O_CONFIG,
		O_JSON,
		O_COMPARE,
		O_NOLOCK,
		O_HELP,
		O_STRATEGY
	};
	static const struct option lo[] = {
	    {"idle", no_argument, 0, O_IDLE},
	    {"plan", required_argument, 0, O_PLAN},
	    {"can", required_argument, 0, O_CAN},
	    {"config", required_argument, 0, O_CONFIG},
	    {"strategy", required_argument, 0, O_STRATEGY},
	    {"priority", required_argument, 0, 'p'},
	    {"interval", required_argument, 0, 'i'},
	    {"duration", required_argument, 0, 'D'},
	    {"loops", required_argument, 0, 'l'},
	    {"affinity", required_argument, 0, 'a'},
	    {"cpu", required_argument, 0, 'a'}, /* mlip-rt's name, which its warnings use */
	    {"mlockall", no_argument, 0, 'm'},
	    {"no-mlockall", no_argument, 0, O_NOLOCK},
	    {"histogram", required_argument, 0, 'h'},
	    {"quiet", no_argument, 0, 'q'},
	    {"json", required_argument, 0, O_JSON},
	    {"compare-cyclictest", no_argument, 0, O_COMPARE},
	    {"help", no_argument, 0, O_HELP},
	    {0, 0, 0, 0}};
	int c, idle = 0;
	uint64_t u;

	memset(o, 0, sizeof(*o));
	o->config = DEFAULT_CONFIG;
	o->priority = DEFAULT_PRIORITY;
	o->cpu = -1;
	o->lock_memory = 1;
	o->hist_us = DEFAULT_HIST_US;
	while ((c = getopt_long(argc, argv, "p:i:D:l:a:mh:q", lo, NULL)) != -1) {
		switch (c) {
		case O_IDLE:
			idle = 1;
			break;
		case O_PLAN:
			o->program = optarg;
			break;
		case O_STRATEGY:
			o->strategy = mlip_cli_strategy(optarg);
			if (o->strategy < 0) {
				fprintf(stderr,
				        PROG ": --strategy: '%s' is not one of mpct, bisector, "
				             "stop, smooth\n",
				        optarg);
				return 2;
			}
			break;
		case O_CAN:
			o->iface = optarg;
			break;
		case O_CONFIG:
			o->config = optarg;
			o->config_given = 1;
			break;
		case 'p':
			if (parse_uint(optarg, 99, &u) != 0) {
				fprintf(stderr, PROG ": -p/--priority: '%s' is not 0..99\n",
				        optarg);
				return 2;
			}
			o->priority = (int)u;
			break;
		case 'i':
			if (parse_uint(optarg, 100000, &u) != 0 || u < 100) {
				fprintf(stderr,
				        PROG ": -i/--interval: '%s' is not 100..100000 us\n",
				        optarg);
				return 2;
			}
			o->interval_us = (int64_t)u;
			break;
		case 'D':
			if (parse_duration(optarg, &o->duration_s) != 0) {
				fprintf(
				    stderr,
				    PROG
				    ": -D/--duration: '%s' is not a duration such as 10, 10s, 1m, "
				    "2h or 1d\n",
				    optarg);
				return 2;
			}
			o->duration_arg = optarg;
			break;
		case 'l':
			if (parse_uint(optarg, UINT64_MAX / 2, &u) != 0 || u == 0) {
				fprintf(stderr, PROG ": -l/--loops: '%s' is not a positive count\n",
				        optarg);
				return 2;
			}
			o->loops = u;
			break;
		case 'a':
			if (parse_uint(optarg, 4095, &u) != 0) {
				fprintf(stderr,
				        PROG
				        ": -a/--affinity: '%s' is not one CPU number (e.g. -a 1)\n",
				        optarg);
				return 2;
			}
			o->cpu = (int)u;
			break;
		case 'm':
			o->lock_memory = 1;
			break;
		case O_NOLOCK:
			o->lock_memory = 0;
			break;
		case 'h':
			if (parse_uint(optarg, MAX_HIST_US, &u) != 0 || u == 0) {
				fprintf(stderr, PROG ": -h/--histogram: '%s' is not 1..%d us\n",
				        optarg, MAX_HIST_US);
				return 2;
			}
			o->hist_us = (uint32_t)u;
			o->hist_given = 1;
			break;
		case 'q':
			o->quiet = 1;
			break;
		case O_JSON:
			o->json = optarg;
			break;
		case O_COMPARE:
			o->compare = 1;
			break;
		case O_HELP:
			lat_usage(stdout);
			return -1;
		default:
			lat_usage(stderr);
			return 2;
		}
	}
	if (optind != argc) {
		fprintf(stderr, PROG ": unexpected argument '%s' (a program goes after --plan)\n",
		        argv[optind]);
		return 2;
	}
	if (idle && (o->program != NULL || o->iface != NULL)) {
		fprintf(stderr, PROG ": --idle is a load of its own: not with --plan or --can\n");
		return 2;
	}
	o->mode = o->iface != NULL ? MODE_CAN : o->program != NULL ? MODE_PLAN : MODE_IDLE;
	if (o->mode == MODE_CAN && o->program == NULL) {
		o->program = DEFAULT_CAN_PROGRAM;
	}
	if (o->mode == MODE_IDLE && o->config_given) {
		fprintf(stderr, PROG ": note: --config is not used with --idle\n");
	}
	return 0;
}
