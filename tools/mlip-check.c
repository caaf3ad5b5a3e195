/*
 * mlip-check - judge a setpoint trace by its physics alone: per-axis jerk
 * (third differences, on axes with a limit), acceleration (second
 * differences), per-axis velocity and tool speed (first
 * differences), contour error against the program's polyline, and whether it
 * ends on the program's last point. Reads the CSV that mlip-sim --trace
 * writes (t,x,y,...), or positions decoded from the CAN bus; t steps by one
 * period, or by several where setpoints were lost (see mlip_check_gap).
 */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "cli.h"
#include "program.h"

#define PROG "mlip-check"

static void usage(FILE *f)
{
	fprintf(f,
	        "usage: " PROG
	        " [machine options] [--quantum MM] [--json OUT] PROGRAM.ngc TRACE.csv\n"
	        "Check a trace (t,x,y,... one row per period) against the machine's limits.\n"
	        "Rows further apart in t than one period follow a hole (lost setpoints): no\n"
	        "acceleration is taken across it, velocities are its mean.\n\n"
	        "  --config FILE / --accel A[,A..] / --vmax MM_S / --eps MM / --period S\n"
	        "  --jerk J            the machine, as for mlip-sim (--jerk: every axis's\n"
	        "                      MAX_JERK, mm/s^3; a trace is judged on the third\n"
	        "                      difference / T^3 of each axis that has one)\n"
	        "  --offsets FILE / --strict / --default-feed F   as for mlip-sim\n"
	        "  --quantum MM        position resolution of the trace (e.g. 0.001 for\n"
	        "                      1000 counts/mm): adds 4 quantum / T^2 to the acceleration\n"
	        "                      bound, 8 quantum / T^3 to the jerk bound and quantum to\n"
	        "                      the contour and end bounds\n"
	        "  --rel R             relative tolerance on every limit (default 1e-9)\n"
	        "  --no-end            the trace need not end on the program's last point\n"
	        "                      (a run stopped by the operator)\n"
	        "  --json OUT          measured values as JSON ('-' for stdout)\n"
	        "  --errors OUT.csv    each sample's contour error: t,contour_mm\n"
	        "exit status: 0 within limits, 1 violation, 2 usage or input error\n");
}

int main(int argc, char **argv)
{
	struct mlip_cli_machine mo = {0};
	const char *json = NULL, *errors = NULL;
	double quantum = 0.0, rel = 1e-9;
	int no_end = 0;
	static const struct option opts[] = {{"config", required_argument, 0, 'c'},
	                                     {"accel", required_argument, 0, 'a'},
	                                     {"vmax", required_argument, 0, 'v'},
	                                     {"eps", required_argument, 0, 'e'},
	                                     {"period", required_argument, 0, 'p'},
	                                     {"jerk", required_argument, 0, 'J'},
	                                     {"quantum", required_argument, 0, 'Q'},
	                                     {"rel", required_argument, 0, 'r'},
	                                     {"json", required_argument, 0, 'j'},
	                                     {"no-end", no_argument, 0, 'E'},
	                                     MLIP_CLI_GCODE_OPTIONS,
	                                     {"errors", required_argument, 0, 'O'},
	                                     {"help", no_argument, 0, 'h'},
	                                     {0, 0, 0, 0}};
	int c;
	while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
		double v = 0.0;
		int g = mlip_cli_gcode_option(c, optarg, &mo, PROG, stderr);
		if (g != 0) {
			if (g < 0) {
				return 2;
			}
			continue;
		}
		if (c > 0 && c < 128 && strchr("vepJQr", c) &&
		    (mlip_cli_number(optarg, &v) != 0 || v < 0.0)) {
			fprintf(stderr, PROG ": '%s' is not a non-negative number\n", optarg);
			return 2;
		}
		switch (c) {
		case 'c':
			mo.config = optarg;
			break;
		case 'a':
			mo.accel = optarg;
			break;
		case 'v':
			mo.vmax_mm_s = v;
			break;
		case 'e':
			mo.eps_mm = v;
			break;
		case 'p':
			mo.period_s = v;
			break;
		case 'J':
			mo.jerk = v;
			break;
		case 'Q':
			quantum = v;
			break;
		case 'r':
			rel = v;
			break;
		case 'j':
			json = optarg;
			break;
		case 'E':
			no_end = 1;
			break;
		case 'O':
			errors = optarg;
			break;
		case 'h':
			usage(stdout);
			return 0;
		default:
			usage(stderr);
			return 2;
		}
	}
	if (optind != argc - 2) {
		usage(stderr);
		return 2;
	}
	const char *ppath = argv[optind], *tpath = argv[optind + 1];
	static struct mlip_config cfg;
	static struct mlip_program prog;
	if (mlip_cli_open_program(ppath, &mo, &cfg, &prog, PROG, stderr) != 0) {
		return 2;
	}
	const struct mlip_machine *m = &cfg.machine;
	int n = m->n_axes;
	/* the polyline is streamed from the program as the trace needs it, the
	 * trace row by row: the check's memory is fixed */
	struct mlip_cli_path src;
	mlip_cli_path_start(&src, &prog, m);
	struct mlip_check_limits lim;
	mlip_cli_check_limits(m, &lim);
	lim.tol_mm = m->tolerance_mm * (1.0 + rel) + quantum; /* the contour bound, for order */
	static struct mlip_check chk;
	mlip_check_init_source(&chk, &lim, mlip_cli_path_next, &src);

	FILE *tf = strcmp(tpath, "-") == 0 ? stdin : fopen(tpath, "r");
	if (tf == NULL) {
		perror(tpath);
		mlip_program_close(&prog);
		return 2;
	}
	FILE *ef = NULL;
	if (errors != NULL && (ef = fopen(errors, "w")) == NULL) {
		perror(errors);
		if (tf != stdin) {
			fclose(tf);
		}
		mlip_program_close(&prog);
		return 2;
	}
	char line[1024];
	size_t lineno = 0;
	double t_prev = 0.0;
	size_t rows = 0;
	int input_error = 0;
	while (fgets(line, sizeof(line), tf) != NULL) {
		lineno++;
		if (lineno == 1 && line[0] == 't') {
			continue; /* header */
		}
		double x[MLIP_MAX_AXES + 1];
		char *p = line;
		int cols = 0;
		while (cols <= n) {
			char *end;
			x[cols++] = strtod(p, &end);
			if (end == p) {
				fprintf(stderr, PROG ": %s:%zu: expected %d numbers\n", tpath,
				        lineno, n + 1);
				input_error = 1;
				break;
			}
			p = end;
			if (*p == ',') {
				p++;
			}
		}
		if (input_error) {
			break;
		}
		/* column 0 is t: a row more than one period after the last one
		 * follows a hole (setpoints lost on the bus) */
		if (rows > 0) {
			double k = nearbyint((x[0] - t_prev) / m->period_s);
			if (!(k >= 1.0)) {
				fprintf(stderr,
				        PROG
				        ": %s:%zu: t %.9g is not at least one period after %.9g\n",
				        tpath, lineno, x[0], t_prev);
				input_error = 1;
				break;
			}
			mlip_check_gap(&chk, (size_t)k);
		}
		t_prev = x[0];
		rows++;
		mlip_check_sample(&chk, x + 1);
		if (ef != NULL) {
			fprintf(ef, "%.17g,%.17g\n", x[0], chk.last_contour_mm);
		}
	}
	if (tf != stdin) {
		fclose(tf);
	}
	if (ef != NULL && fclose(ef) != 0) {
		perror(errors);
		input_error = 1;
	}
	if (input_error) {
		mlip_program_close(&prog);
		return 2;
	}
	mlip_check_finish(&chk);
	if (src.rc < 0) { /* the file changed since it was checked, or I/O */
		fprintf(stderr, PROG ": %s: %s\n", ppath, prog.msg);
		mlip_program_close(&prog);
		return 2;
	}
	double T = m->period_s;
	double abs_acc = mlip_check_rounding_floor(&chk) + 4.0 * quantum / (T * T);
	char msg[4096];
	int bad = mlip_check_verdict(&chk, rel, abs_acc, quantum,
	                             no_end ? INFINITY : 1e-9 + quantum, msg, sizeof(msg));

	FILE *jf = json == NULL ? NULL : strcmp(json, "-") == 0 ? stdout : fopen(json, "w");
	if (jf != NULL) {
		fprintf(jf, "{\n  \"samples\": %zu,\n  \"max_axis_accel\": [", chk.count);
		for (int k = 0; k < n; k++) {
			fprintf(jf, "%s%.12g", k ? ", " : "", chk.max_acc[k]);
		}
		fprintf(jf, "],\n  \"max_axis_jerk\": [");
		for (int k = 0; k < n; k++) {
			fprintf(jf, "%s%.12g", k ? ", " : "", chk.max_jerk[k]);
		}
		fprintf(jf, "],\n  \"max_axis_vel\": [");
		for (int k = 0; k < n; k++) {
			fprintf(jf, "%s%.12g", k ? ", " : "", chk.max_vel[k]);
		}
		fprintf(jf, "],\n  \"max_speed_mm_s\": %.12g,\n", chk.max_speed_mm_s);
		fprintf(jf, "  \"max_rot_speed_deg_s\": %.12g,\n", chk.max_rot_speed_deg_s);
		fprintf(jf, "  \"max_contour_error_mm\": %.12g,\n", chk.max_contour_mm);
		fprintf(jf, "  \"order_errors\": %zu,\n", chk.order_errors);
		fprintf(jf, "  \"window_drops\": %zu,\n", chk.window_drops);
		fprintf(jf, "  \"end_error_mm\": %.3g,\n", mlip_check_end_error(&chk));
		fprintf(jf, "  \"violations\": %d\n}\n", bad);
		if (jf != stdout) {
			fclose(jf);
		}
	}
	if (bad) {
		fprintf(stderr, PROG ": %s: %d violation(s):\n%s", tpath, bad, msg);
	} else {
		fprintf(stderr, PROG ": %s: %zu samples within limits (max contour %.6f mm)\n",
		        tpath, chk.count, chk.max_contour_mm);
	}
	mlip_program_close(&prog);
	return bad ? 1 : 0;
}
