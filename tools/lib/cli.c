/* cli.c - see cli.h */
#include "cli.h"

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "confload.h"
#include "mlip/gcode.h"
#include "program.h"

int mlip_cli_number(const char *s, double *out)
{
	char *end;
	if (s == NULL || *s == '\0') {
		return -1;
	}
	errno = 0;
	double v = strtod(s, &end);
	if (*end != '\0' || errno != 0 || !isfinite(v)) {
		return -1;
	}
	*out = v;
	return 0;
}

int mlip_cli_strategy(const char *name)
{
	if (strcmp(name, "mpct") == 0) {
		return MLIP_STRATEGY_MPCT;
	}
	if (strcmp(name, "bisector") == 0) {
		return MLIP_STRATEGY_BISECTOR;
	}
	if (strcmp(name, "stop") == 0) {
		return MLIP_STRATEGY_STOP;
	}
	if (strcmp(name, "smooth") == 0) {
		return MLIP_STRATEGY_SMOOTH;
	}
	return -1;
}

const char *mlip_cli_strategy_name(mlip_strategy st)
{
	switch (st) {
	case MLIP_STRATEGY_MPCT:
		return "mpct";
	case MLIP_STRATEGY_BISECTOR:
		return "bisector";
	case MLIP_STRATEGY_STOP:
		return "stop";
	case MLIP_STRATEGY_SMOOTH:
		return "smooth";
	}
	return "?";
}

static int apply_accel(struct mlip_machine *m, const char *list, const char *prog, FILE *err)
{
	double v[MLIP_MAX_AXES];
	int count = 0;
	char buf[256];
	if (strlen(list) >= sizeof(buf)) {
		fprintf(err, "%s: --accel: list too long\n", prog);
		return -1;
	}
	strcpy(buf, list);
	for (char *tok = strtok(buf, ","); tok != NULL; tok = strtok(NULL, ",")) {
		if (count == MLIP_MAX_AXES || mlip_cli_number(tok, &v[count]) != 0 || !(v[count] > 0.0)) {
			fprintf(err, "%s: --accel: '%s' is not a positive number (mm/s^2)\n", prog, tok);
			return -1;
		}
		count++;
	}
	if (count != 1 && count != m->n_axes) {
		fprintf(err, "%s: --accel: %d values for %d axes (give one for all, or one per axis)\n",
		        prog, count, m->n_axes);
		return -1;
	}
	for (int k = 0; k < m->n_axes; k++) {
		m->axis[k].max_accel = v[count == 1 ? 0 : k];
	}
	return 0;
}

int mlip_cli_build_machine(const struct mlip_cli_machine *o, const char *program_text,
                           size_t len, struct mlip_config *cfg, const char *prog, FILE *err)
{
	mlip_config_defaults(cfg);
	struct mlip_machine *m = &cfg->machine;
	if (o->config != NULL) {
		if (mlip_config_load(o->config, cfg, err) != 0) {
			return -1;
		}
	} else {
		char letters[MLIP_MAX_AXES + 1] = "";
		int n = program_text ? mlip_gcode_scan_axes(program_text, len, letters) : 0;
		if (n < 2) {
			/* a program using one axis still runs on a 2-axis machine */
			const char *fill = "XYZ";
			for (int i = 0; n < 2 && fill[i]; i++) {
				if (strchr(letters, fill[i]) == NULL) {
					letters[n++] = fill[i];
					letters[n] = '\0';
				}
			}
			/* keep canonical order XYZABC */
			char sorted[MLIP_MAX_AXES + 1];
			int j = 0;
			for (const char *c = "XYZABC"; *c; c++) {
				if (strchr(letters, *c)) {
					sorted[j++] = *c;
				}
			}
			sorted[j] = '\0';
			strcpy(letters, sorted);
		}
		double vmax = o->vmax_mm_s > 0.0 ? o->vmax_mm_s : 200.0;
		m->n_axes = n;
		m->max_feed_mm_s = vmax;
		m->max_rot_feed_deg_s = 360.0;
		m->tolerance_mm = 0.01;
		m->period_s = 0.001;
		for (int k = 0; k < n; k++) {
			struct mlip_axis *ax = &m->axis[k];
			ax->letter = letters[k];
			ax->kind = MLIP_AXIS_LINEAR; /* no config: every axis linear */
			ax->max_accel = 1000.0;
			ax->max_vel = vmax;
			ax->min_limit = -1e9;
			ax->max_limit = 1e9;
			ax->home = 0.0;
			ax->can_node = k + 1;
			ax->counts_per_unit = 1000.0;
		}
	}
	if (o->accel != NULL && apply_accel(m, o->accel, prog, err) != 0) {
		return -1;
	}
	if (o->vmax_mm_s > 0.0) {
		m->max_feed_mm_s = o->vmax_mm_s;
	}
	if (o->eps_mm > 0.0) {
		m->tolerance_mm = o->eps_mm;
	}
	if (o->period_s > 0.0) {
		m->period_s = o->period_s;
	}
	struct mlip_config_error e;
	if (mlip_machine_check(m, &e) != MLIP_OK) {
		fprintf(err, "%s: machine: %s\n", prog, e.msg);
		return -1;
	}
	return 0;
}

double *mlip_cli_polyline(const struct mlip_machine *m, const struct mlip_block *blocks,
                          size_t nblocks, size_t *npts)
{
	int n = m->n_axes;
	double *pts = malloc(sizeof(double) * (size_t)n * (nblocks + 1));
	if (pts == NULL) {
		return NULL;
	}
	for (int k = 0; k < n; k++) {
		pts[k] = m->axis[k].home;
	}
	size_t np = 1;
	for (size_t i = 0; i < nblocks; i++) {
		const double *last = pts + (np - 1) * (size_t)n;
		double d2 = 0.0;
		for (int k = 0; k < n; k++) {
			d2 += (blocks[i].target[k] - last[k]) * (blocks[i].target[k] - last[k]);
		}
		if (sqrt(d2) < MLIP_GCODE_MERGE_MM) {
			continue;
		}
		memcpy(pts + np * (size_t)n, blocks[i].target, sizeof(double) * (size_t)n);
		np++;
	}
	*npts = np;
	return pts;
}

void mlip_cli_check_limits(const struct mlip_machine *m, struct mlip_check_limits *lim)
{
	memset(lim, 0, sizeof(*lim));
	lim->n = m->n_axes;
	lim->vmax_mm_s = m->max_feed_mm_s;
	lim->vmax_rot_deg_s = m->max_rot_feed_deg_s;
	lim->eps_mm = m->tolerance_mm;
	lim->period_s = m->period_s;
	for (int k = 0; k < m->n_axes; k++) {
		lim->accel[k] = m->axis[k].max_accel;
		lim->vel[k] = m->axis[k].max_vel;
		lim->rotary[k] = m->axis[k].kind == MLIP_AXIS_ROTARY;
	}
}

int mlip_cli_open_program(const char *path, const struct mlip_cli_machine *o,
                          struct mlip_config *cfg, char **text, size_t *len, const char *prog,
                          FILE *err)
{
	int rc = mlip_read_file(path, text, len);
	if (rc != 0) {
		fprintf(err, "%s: %s: %s\n", prog, path, strerror(-rc));
		return -1;
	}
	if (mlip_cli_build_machine(o, *text, *len, cfg, prog, err) != 0) {
		free(*text);
		*text = NULL;
		return -1;
	}
	return 0;
}

void mlip_cli_on_stop_signals(void (*handler)(int))
{
	struct sigaction sa;
	memset(&sa, 0, sizeof(sa));
	sa.sa_handler = handler;
	sigemptyset(&sa.sa_mask);
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGTERM, &sa, NULL);
}
