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
#include "json.h"
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

struct options {
	struct mlip_cli_machine mo;
	const char *json, *errors, *ppath, *tpath;
	double quantum, rel;
	int no_end;
};

/* 0, or the exit status (-1: --help, exit 0). */
static int parse_options(int argc, char **argv, struct options *o)
{
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
	memset(o, 0, sizeof(*o));
	o->rel = 1e-9;
	while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
		double v = 0.0;
		int g = mlip_cli_gcode_option(c, optarg, &o->mo, PROG, stderr);
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
			o->mo.config = optarg;
			break;
		case 'a':
			o->mo.accel = optarg;
			break;
		case 'v':
			o->mo.vmax_mm_s = v;
			break;
		case 'e':
			o->mo.eps_mm = v;
			break;
		case 'p':
			o->mo.period_s = v;
			break;
		case 'J':
			o->mo.jerk = v;
			break;
		case 'Q':
			o->quantum = v;
			break;
		case 'r':
			o->rel = v;
			break;
		case 'j':
			o->json = optarg;
			break;
		case 'E':
			o->no_end = 1;
			break;
		case 'O':
			o->errors = optarg;
			break;
		case 'h':
			usage(stdout);
			return -1;
		default:
			usage(stderr);
			return 2;
		}
	}
	if (optind != argc - 2) {
		usage(stderr);
		return 2;
	}
	o->ppath = argv[optind];
	o->tpath = argv[optind + 1];
	return 0;
}

/* The program, the check streaming its polyline, the trace and the errors
 * file open. */
struct run {
	struct mlip_config cfg;
	struct mlip_program prog;
	struct mlip_cli_path src;
	struct mlip_check chk;
	FILE *tf, *ef;
};

static void close_files(struct run *r)
{
	if (r->tf != NULL && r->tf != stdin) {
		fclose(r->tf);
	}
	r->tf = NULL;
	if (r->ef != NULL) {
		fclose(r->ef);
		r->ef = NULL;
	}
}

/* 0, or the exit status. */
static int set_up(const struct options *o, struct run *r)
{
	if (mlip_cli_open_program(o->ppath, &o->mo, &r->cfg, &r->prog, PROG, stderr) != 0) {
		return 2;
	}
	const struct mlip_machine *m = &r->cfg.machine;
	/* the polyline is streamed from the program as the trace needs it, the
	 * trace row by row: the check's memory is fixed */
	mlip_cli_path_start(&r->src, &r->prog, m);
	struct mlip_check_limits lim;
	mlip_cli_check_limits(m, &lim);
	lim.tol_mm =
	    m->tolerance_mm * (1.0 + o->rel) + o->quantum; /* the contour bound, for order */
	mlip_check_init_source(&r->chk, &lim, mlip_cli_path_next, &r->src);
	r->tf = strcmp(o->tpath, "-") == 0 ? stdin : fopen(o->tpath, "r");
	if (r->tf == NULL) {
		perror(o->tpath);
		mlip_program_close(&r->prog);
		return 2;
	}
	if (o->errors != NULL && (r->ef = fopen(o->errors, "w")) == NULL) {
		perror(o->errors);
		close_files(r);
		mlip_program_close(&r->prog);
		return 2;
	}
	return 0;
}

/* Every row of the trace into the check: 0, or 2 for a row that is not one. */
static int run(const struct options *o, struct run *r)
{
	const struct mlip_machine *m = &r->cfg.machine;
	int n = m->n_axes;
	char line[1024];
	size_t lineno = 0, rows = 0;
	double t_prev = 0.0;
	while (fgets(line, sizeof(line), r->tf) != NULL) {
		lineno++;
		if (lineno == 1 && line[0] == 't') {
			continue; /* header */
		}
		double x[MLIP_MAX_AXES + 1];
		char *p = line;
		for (int cols = 0; cols <= n; cols++) {
			char *end;
			x[cols] = strtod(p, &end);
			if (end == p) {
				fprintf(stderr, PROG ": %s:%zu: expected %d numbers\n", o->tpath,
				        lineno, n + 1);
				return 2;
			}
			p = end;
			if (*p == ',') {
				p++;
			}
		}
		/* column 0 is t: a row more than one period after the last one
		 * follows a hole (setpoints lost on the bus) */
		if (rows > 0) {
			double k = nearbyint((x[0] - t_prev) / m->period_s);
			if (!(k >= 1.0)) {
				fprintf(stderr,
				        PROG
				        ": %s:%zu: t %.9g is not at least one period after %.9g\n",
				        o->tpath, lineno, x[0], t_prev);
				return 2;
			}
			mlip_check_gap(&r->chk, (size_t)k);
		}
		t_prev = x[0];
		rows++;
		mlip_check_sample(&r->chk, x + 1);
		if (r->ef != NULL) {
			fprintf(r->ef, "%.17g,%.17g\n", x[0], r->chk.last_contour_mm);
		}
	}
	return 0;
}

static int write_json(const char *path, const struct mlip_check *chk, int n, int bad)
{
	FILE *jf = strcmp(path, "-") == 0 ? stdout : fopen(path, "w");
	struct mlip_json j;
	if (jf == NULL) {
		perror(path);
		return -1;
	}
	mlip_json_begin(&j, jf);
	mlip_json_uint(&j, "samples", chk->count);
	mlip_json_numbers(&j, "max_axis_accel", "%.12g", chk->max_acc, n);
	mlip_json_numbers(&j, "max_axis_jerk", "%.12g", chk->max_jerk, n);
	mlip_json_numbers(&j, "max_axis_vel", "%.12g", chk->max_vel, n);
	mlip_json_number(&j, "max_speed_mm_s", "%.12g", chk->max_speed_mm_s);
	mlip_json_number(&j, "max_rot_speed_deg_s", "%.12g", chk->max_rot_speed_deg_s);
	mlip_json_number(&j, "max_contour_error_mm", "%.12g", chk->max_contour_mm);
	mlip_json_uint(&j, "order_errors", chk->order_errors);
	mlip_json_uint(&j, "window_drops", chk->window_drops);
	mlip_json_number(&j, "end_error_mm", "%.3g", mlip_check_end_error(chk));
	mlip_json_int(&j, "violations", bad);
	int rc = mlip_json_end(&j);
	if (jf != stdout && fclose(jf) != 0) {
		rc = -1;
	}
	if (rc != 0) {
		perror(path);
	}
	return rc;
}

/* The verdict: 0 within limits, 1 a violation, 2 an input error. */
static int report(const struct options *o, struct run *r, int input_error)
{
	struct mlip_check *chk = &r->chk;
	if (r->ef != NULL && fclose(r->ef) != 0) {
		perror(o->errors);
		input_error = 1;
	}
	r->ef = NULL;
	close_files(r);
	if (input_error) {
		mlip_program_close(&r->prog);
		return 2;
	}
	mlip_check_finish(chk);
	if (r->src.rc < 0) { /* the file changed since it was checked, or I/O */
		fprintf(stderr, PROG ": %s: %s\n", o->ppath, r->prog.msg);
		mlip_program_close(&r->prog);
		return 2;
	}
	double T = r->cfg.machine.period_s;
	double abs_acc = mlip_check_rounding_floor(chk) + 4.0 * o->quantum / (T * T);
	char msg[4096];
	int bad = mlip_check_verdict(chk, o->rel, abs_acc, o->quantum,
	                             o->no_end ? INFINITY : 1e-9 + o->quantum, msg, sizeof(msg));
	if (o->json != NULL) {
		write_json(o->json, chk, r->cfg.machine.n_axes, bad);
	}
	if (bad) {
		fprintf(stderr, PROG ": %s: %d violation(s):\n%s", o->tpath, bad, msg);
	} else {
		fprintf(stderr, PROG ": %s: %zu samples within limits (max contour %.6f mm)\n",
		        o->tpath, chk->count, chk->max_contour_mm);
	}
	mlip_program_close(&r->prog);
	return bad ? 1 : 0;
}

int main(int argc, char **argv)
{
	static struct options o;
	static struct run r;
	int rc = parse_options(argc, argv, &o);
	if (rc != 0) {
		return rc < 0 ? 0 : rc;
	}
	rc = set_up(&o, &r);
	if (rc != 0) {
		return rc;
	}
	return report(&o, &r, run(&o, &r) != 0);
}
