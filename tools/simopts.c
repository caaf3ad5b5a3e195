/* simopts.c - mlip-sim's options (simopts.h) */
#include "simopts.h"

#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mlip/motion/planner.h"

const char *const plan_name[] = {"mean", "path", "path-mean"};

static void usage(FILE *f)
{
	fprintf(
	    f,
	    "usage: " PROG " [options] FILE.ngc\n"
	    "Simulate a G-code program on the mlip interpolator and report its motion.\n\n"
	    "  --config FILE         machine INI (default: the axes the program uses, linear)\n"
	    "  --strategy NAME       mpct (default, the paper), bisector, stop, smooth (mpct on\n"
	    "                        the path smoothed within the tolerance, "
	    "mlip/motion/smooth.h;\n"
	    "                        a program whose run with mpct's corners ends sooner\n"
	    "                        runs with those: never slower than mpct)\n"
	    "  --smooth-only         smooth's corners on every program (a measurement)\n"
	    "  --accel A[,A...]      per-axis acceleration, mm/s^2 (one for all, or per axis)\n"
	    "  --jerk J              every axis's jerk limit (MAX_JERK), mm/s^3: the motion keeps\n"
	    "                        it at every sample (mlip/motion/jerk.h)\n"
	    "  --jerk-plan mean|path|path-mean|auto  how the jerk limit is kept: mean\n"
	    "                        (default), the moving mean of the setpoints; path,\n"
	    "                        smooth's setpoints without it re-timed along a spline\n"
	    "                        by the path-speed plan (mlip/motion/pathrun.h;\n"
	    "                        --strategy smooth, no override; each block at its\n"
	    "                        own F, a G0 at the machine's; refused before\n"
	    "                        anything moves: events at rest (G4, M0, M1, M3..M9,\n"
	    "                        M62..M65, G38) and G61); path-mean, the mean's\n"
	    "                        setpoints re-timed so; auto, whichever of the three\n"
	    "                        ends the program soonest (on smooth also mpct's run:\n"
	    "                        never slower than mpct). Default: [TRAJ] JERK_PLAN\n"
	    "                        (mean or path)\n"
	    "  --vmax MM_S           maximum feed v_m, mm/s (default 200 without --config)\n"
	    "  --eps MM              contour tolerance (default 0.01 without --config)\n"
	    "  --period S            interpolation period T (default 0.001)\n"
	    "  --feed MM_S           ignore the program's F words, run every block at this feed\n"
	    "  --override PCT        feed override from the start, 0..200 (default 100)\n"
	    "  --storm SEED          random override changes, holds and resumes every 5-200\n"
	    "                        periods (a test of online override)\n"
	    "  --lookahead N         look-ahead capacity in blocks, power of two (default %d)\n"
	    "  --resume-after S      a pause (M0, M60, M1 with --optional-stop) resumes after\n"
	    "                        S seconds at rest (default 0)\n"
	    "  --optional-stop       M1 pauses (the optional-stop switch on)\n"
	    "  --probe-surface AXIS=POS[,below|above]\n"
	    "                        G38's probe touches a surface: on at and below (above)\n"
	    "                        POS mm of AXIS (machine coordinates), as the config's\n"
	    "                        [PROBE] SOURCE gives it: io, the module's input from the\n"
	    "                        period after the setpoint reached it; drive, the drives'\n"
	    "                        touch probe latching the crossing itself (docs/gcode.md);\n"
	    "                        without it the probe never touches\n"
	    "  --trace OUT.csv       setpoints: t,x,y,... one row per period, t = 0 to rest\n"
	    "  --summary OUT.json    totals and measured physics (JSON)\n"
	    "  --offsets FILE        work offsets, G92 and G28/G30 positions (docs/gcode.md)\n"
	    "  --save-offsets        write the offsets the program leaves back to that FILE\n"
	    "  --default-feed F      feed (units/min) for a program that sets no F at all\n"
	    "  --strict              refuse Grbl '$' lines and axis words before G0/G1/G2/G3\n"
	    "  --no-notes            do not list the words accepted without effect\n"
	    "  -q, --quiet           neither notes nor the summary line on stderr\n"
	    "  -h, --help            this help\n"
	    "exit status: 0 done within every limit, 1 input error, 2 usage, 3 no end,\n"
	    "4 the trace breaks a limit (its own check, as mlip-check's: which, where),\n"
	    "5 a probe error stopped the program (G38.2/.4 without a trip, tripped at the start)\n",
	    MLIP_LOOKAHEAD);
}

/* see simopts.h */
int parse_options(int argc, char **argv, struct options *o)
{
	static const struct option opts[] = {{"config", required_argument, 0, 'c'},
	                                     {"strategy", required_argument, 0, 's'},
	                                     {"accel", required_argument, 0, 'a'},
	                                     {"jerk", required_argument, 0, 'J'},
	                                     {"vmax", required_argument, 0, 'v'},
	                                     {"eps", required_argument, 0, 'e'},
	                                     {"period", required_argument, 0, 'p'},
	                                     {"feed", required_argument, 0, 'f'},
	                                     {"override", required_argument, 0, 'o'},
	                                     {"storm", required_argument, 0, 'S'},
	                                     {"lookahead", required_argument, 0, 'L'},
	                                     {"trace", required_argument, 0, 't'},
	                                     {"summary", required_argument, 0, 'j'},
	                                     {"quiet", no_argument, 0, 'q'},
	                                     {"help", no_argument, 0, 'h'},
	                                     {"no-notes", no_argument, 0, 'N'},
	                                     {"resume-after", required_argument, 0, 'r'},
	                                     {"optional-stop", no_argument, 0, 'O'},
	                                     {"save-offsets", no_argument, 0, 'W'},
	                                     {"probe-surface", required_argument, 0, 'P'},
	                                     {"jerk-plan", required_argument, 0, 'K'},
	                                     {"smooth-only", no_argument, 0, 'C'},
	                                     MLIP_CLI_GCODE_OPTIONS,
	                                     {0, 0, 0, 0}};
	int c;
	memset(o, 0, sizeof(*o));
	o->strategy_name = "mpct";
	o->feed = -1.0;
	o->override = 100.0;
	o->storm_seed = -1;
	o->notes = 1;
	o->jerk_plan = -1;
	while ((c = getopt_long(argc, argv, "qh", opts, NULL)) != -1) {
		double v;
		int g = mlip_cli_gcode_option(c, optarg, &o->mo, PROG, stderr);
		if (g != 0) {
			if (g < 0) {
				return 2;
			}
			continue;
		}
		switch (c) {
		case 'c':
			o->mo.config = optarg;
			break;
		case 's':
			o->strategy_name = optarg;
			break;
		case 'a':
			o->mo.accel = optarg;
			break;
		case 'v':
		case 'e':
		case 'p':
		case 'f':
		case 'o':
		case 'J':
			if (mlip_cli_number(optarg, &v) != 0 ||
			    !(v > 0.0 || (c == 'o' && v == 0.0))) {
				fprintf(stderr, PROG ": --%s: '%s' is not a positive number\n",
				        c == 'v'   ? "vmax"
				        : c == 'e' ? "eps"
				        : c == 'p' ? "period"
				        : c == 'f' ? "feed"
				        : c == 'J' ? "jerk"
				                   : "override",
				        optarg);
				return 2;
			}
			if (c == 'J') {
				o->mo.jerk = v;
			} else if (c == 'v') {
				o->mo.vmax_mm_s = v;
			} else if (c == 'e') {
				o->mo.eps_mm = v;
			} else if (c == 'p') {
				o->mo.period_s = v;
			} else if (c == 'f') {
				o->feed = v;
			} else {
				o->override = v;
			}
			break;
		case 'S':
			o->storm_seed = strtoll(optarg, NULL, 0);
			break;
		case 'L':
			o->lookahead = strtoul(optarg, NULL, 0);
			break;
		case 't':
			o->trace_path = optarg;
			break;
		case 'j':
			o->summary_path = optarg;
			break;
		case 'q':
			o->quiet = 1;
			o->notes = 0;
			break;
		case 'N':
			o->notes = 0;
			break;
		case 'r':
			if (mlip_cli_number(optarg, &o->resume_after) != 0 ||
			    !(o->resume_after >= 0.0) || o->resume_after > 86400.0) {
				fprintf(stderr,
				        PROG ": --resume-after: '%s' is not 0..86400 seconds\n",
				        optarg);
				return 2;
			}
			break;
		case 'O':
			o->optional_stop = 1;
			break;
		case 'C':
			o->smooth_only = 1;
			break;
		case 'W':
			o->save_offsets = 1;
			break;
		case 'P':
			o->probe_surface = optarg;
			break;
		case 'K':
			o->jerk_plan = strcmp(optarg, "mean") == 0        ? JERK_MEAN
			               : strcmp(optarg, "path") == 0      ? JERK_PATH
			               : strcmp(optarg, "path-mean") == 0 ? JERK_PATH_MEAN
			               : strcmp(optarg, "auto") == 0      ? JERK_AUTO
			                                                  : -1;
			if (o->jerk_plan < 0) {
				fprintf(
				    stderr,
				    PROG
				    ": --jerk-plan: '%s' is not mean, path, path-mean or auto\n",
				    optarg);
				return 2;
			}
			break;
		case 'h':
			usage(stdout);
			return -1;
		default:
			usage(stderr);
			return 2;
		}
	}
	if (optind != argc - 1) {
		usage(stderr);
		return 2;
	}
	o->path = argv[optind];
	o->strategy = mlip_cli_strategy(o->strategy_name);
	if (o->strategy < 0) {
		fprintf(stderr,
		        PROG ": --strategy: '%s' is not one of mpct, bisector, stop, smooth\n",
		        o->strategy_name);
		return 2;
	}
	if (o->override > 200.0) {
		fprintf(stderr, PROG ": --override: %g is above 200 %%\n", o->override);
		return 2;
	}
	if (o->save_offsets && o->mo.offsets == NULL) {
		fprintf(stderr, PROG ": --save-offsets needs --offsets FILE\n");
		return 2;
	}
	return 0;
}
