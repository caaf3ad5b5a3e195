/*
 * mlip-feed - send a G-code program to a running mlip-rt through the ring of
 * its shared-memory segment (mlip/ipc/ring.h) and follow it to the end: the
 * options; the feeder itself is tools/feed.c (shared with mlip-ctl mdi).
 */
#include <errno.h>
#include <getopt.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "cli.h"
#include "feed.h"
#include "rt.h"

#define PROG "mlip-feed"

static void usage(FILE *f)
{
	fprintf(f,
	        "usage: " PROG " [options] FILE.ngc\n"
	        "Check a G-code program against the machine of the running mlip-rt, send it\n"
	        "through the shared-memory ring and follow it until the machine is at rest.\n\n"
	        "  --shm NAME        controller's shared-memory segment (default " MLIP_SHM_DEFAULT
	        ")\n"
	        "  --rate N          send at most N blocks per second (to try underruns)\n"
	        "  --start-seq N     continue the program from block N (1-based): the block\n"
	        "                    after the last one the controller completed (mlip-ctl\n"
	        "                    status: 'completed block B', N = B + 1), after a feeder\n"
	        "                    crash or a stop (default 1: the whole program); with a\n"
	        "                    `smooth` controller, blocks are the smoothed records\n"
	        "  --offsets FILE    work offsets, G92, G28/G30 positions: read before the\n"
	        "                    program, written back when it completes (docs/gcode.md)\n"
	        "  --default-feed F  feed (units/min) for a program that sets no F at all\n"
	        "  --strict          refuse Grbl '$' lines and axis words before G0/G1/G2/G3\n"
	        "  --tools FILE      the tool table (T P Z D ;comment, LinuxCNC's format): M6,\n"
	        "                    G43 H; the tool in the spindle is in the offsets file\n"
	        "  --ignore-spindle  run S/M3/M4/M5 as nothing, on purpose (the machine's\n"
	        "                    [SPINDLE] is mlip-rt's config; TYPE none refuses them)\n"
	        "  --ignore-coolant  run M7/M8/M9 as nothing, on purpose\n"
	        "  --ignore-tools    run T/M6/M61/G43/G49 as nothing, on purpose\n"
	        "  -q, --quiet       no notes, no progress, no summary: errors only\n"
	        "  -h, --help        this help\n\n"
	        "exit status: 0 program complete, machine at rest; 1 nothing sent (program\n"
	        "errors, no controller, another feeder); 2 usage; 3 controller stopped\n"
	        "responding; 4 stopped on the path (mlip-ctl stop, or mlip-rt told to exit by\n"
	        "a signal), or mlip-ctl stop before the program started (nothing moved);\n"
	        "5 controller fault, or a probe error (G38: no trip, tripped at the start);\n"
	        "128+N interrupted by signal N (130 SIGINT, 143 SIGTERM, 129 SIGHUP, 131\n"
	        "SIGQUIT): the machine was stopped on the path\n");
}

/* Strict positive integer. */
static int parse_seq(const char *s, uint64_t *out)
{
	char *end;
	unsigned long long v;

	if (s == NULL || s[0] < '0' || s[0] > '9') {
		return -1;
	}
	errno = 0;
	v = strtoull(s, &end, 10);
	if (*end != '\0' || errno != 0 || v == 0) {
		return -1;
	}
	*out = v;
	return 0;
}

int main(int argc, char **argv)
{
	static const struct option opts[] = {{"shm", required_argument, 0, 's'},
	                                     {"start-seq", required_argument, 0, 'S'},
	                                     {"rate", required_argument, 0, 'r'},
	                                     {"quiet", no_argument, 0, 'q'},
	                                     MLIP_CLI_GCODE_OPTIONS,
	                                     {"help", no_argument, 0, 'h'},
	                                     {0, 0, 0, 0}};
	struct mlip_feed_opts o = {0};
	int c;

	o.prog = PROG;
	o.shm = MLIP_SHM_DEFAULT;
	o.first_seq = 1;
	while ((c = getopt_long(argc, argv, "qh", opts, NULL)) != -1) {
		int taken = mlip_cli_gcode_option(c, optarg, &o.gc, PROG, stderr);
		if (taken != 0) {
			if (taken < 0) {
				return MLIP_FEED_USAGE;
			}
			continue;
		}
		switch (c) {
		case 's':
			o.shm = optarg;
			break;
		case 'S':
			if (parse_seq(optarg, &o.first_seq) != 0) {
				fprintf(stderr,
				        PROG ": --start-seq: '%s' is not a block number >= 1\n",
				        optarg);
				return MLIP_FEED_USAGE;
			}
			break;
		case 'r': {
			char *end;
			o.rate = strtod(optarg, &end);
			if (*end != '\0' || !(o.rate > 0.0)) {
				fprintf(stderr,
				        PROG
				        ": --rate: '%s' is not a positive number of blocks/s\n",
				        optarg);
				return MLIP_FEED_USAGE;
			}
			break;
		}
		case 'q':
			o.quiet = 1;
			break;
		case 'h':
			usage(stdout);
			return MLIP_FEED_DONE;
		default:
			usage(stderr);
			return MLIP_FEED_USAGE;
		}
	}
	if (optind != argc - 1) {
		usage(stderr);
		return MLIP_FEED_USAGE;
	}
	o.path = argv[optind];
	return mlip_feed_run(&o);
}
