/* offsets.c - see offsets.h */
#include "offsets.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define KEY_G92 (MLIP_GCODE_N_COORD)
#define KEY_G28 (MLIP_GCODE_N_COORD + 1)
#define KEY_G30 (MLIP_GCODE_N_COORD + 2)

static double *key_values(struct mlip_gcode_offsets *o, int k)
{
	return k < MLIP_GCODE_N_COORD ? o->coord[k]
	       : k == KEY_G92         ? o->g92
	       : k == KEY_G28         ? o->g28
	                              : o->g30;
}

static const char *key_name(int k)
{
	return k < MLIP_GCODE_N_COORD ? mlip_gcode_coord_name(k)
	       : k == KEY_G92         ? "G92"
	       : k == KEY_G28         ? "G28"
	                              : "G30";
}

static char *trim(char *s)
{
	char *e;

	while (*s == ' ' || *s == '\t') {
		s++;
	}
	e = s + strlen(s);
	while (e > s && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\n' || e[-1] == '\r')) {
		*--e = '\0';
	}
	return s;
}

static int parse_line(char *s, const struct mlip_machine *m, struct mlip_gcode_offsets *o,
                      char *why, size_t len)
{
	char *eq = strchr(s, '='), *key, *val, *end;
	double v[MLIP_MAX_AXES];
	int k, n = 0;

	if (!eq) {
		snprintf(why, len, "expected KEY = VALUE");
		return -1;
	}
	*eq = '\0';
	key = trim(s);
	val = trim(eq + 1);
	if (strcmp(key, "SELECT") == 0) {
		for (k = 0; k < MLIP_GCODE_N_COORD; k++) {
			if (strcmp(val, mlip_gcode_coord_name(k)) == 0) {
				o->select = k;
				return 0;
			}
		}
		snprintf(why, len, "SELECT must be one of G54..G59.3, got '%s'", val);
		return -1;
	}
	if (strcmp(key, "G92_ON") == 0) {
		if (strcmp(val, "0") && strcmp(val, "1")) {
			snprintf(why, len, "G92_ON must be 0 or 1, got '%s'", val);
			return -1;
		}
		o->g92_on = val[0] == '1';
		return 0;
	}
	for (k = 0; k <= KEY_G30; k++) {
		if (strcmp(key, key_name(k)) == 0) {
			break;
		}
	}
	if (k > KEY_G30) {
		snprintf(why, len, "unknown key '%s' (SELECT, G92_ON, G54..G59.3, G92, G28, G30)",
		         key);
		return -1;
	}
	while (*val) {
		errno = 0;
		double x = strtod(val, &end);
		if (end == val || errno || !isfinite(x) || n == m->n_axes) {
			snprintf(why, len, "%s needs %d numbers (one per axis, config order)", key,
			         m->n_axes);
			return -1;
		}
		v[n++] = x;
		val = trim(end);
	}
	if (n != m->n_axes) {
		snprintf(why, len, "%s needs %d numbers (one per axis, config order), got %d", key,
		         m->n_axes, n);
		return -1;
	}
	memcpy(key_values(o, k), v, sizeof(double) * (size_t)n);
	return 0;
}

int mlip_offsets_load(const char *path, const struct mlip_machine *m, struct mlip_gcode_offsets *o,
                      const char *prog, FILE *err)
{
	char buf[512], why[160];
	unsigned line = 0;
	FILE *f;

	mlip_gcode_offsets_init(o, m);
	f = fopen(path, "r");
	if (!f) {
		if (errno == ENOENT) {
			return 0; /* no state yet: the defaults */
		}
		fprintf(err, "%s: %s: %s\n", prog, path, strerror(errno));
		return -1;
	}
	while (fgets(buf, sizeof buf, f)) {
		char *s = trim(buf);

		line++;
		if (*s == '\0' || *s == '#' || *s == ';') {
			continue;
		}
		if (parse_line(s, m, o, why, sizeof why) != 0) {
			fprintf(err, "%s: %s:%u: error: %s\n", prog, path, line, why);
			fclose(f);
			return -1;
		}
	}
	fclose(f);
	return 0;
}

int mlip_offsets_save(const char *path, const struct mlip_machine *m,
                      const struct mlip_gcode_offsets *o, const char *prog, FILE *err)
{
	char tmp[4096];
	FILE *f;
	int k, i;

	snprintf(tmp, sizeof tmp, "%s.tmp", path);
	f = fopen(tmp, "w");
	if (!f) {
		fprintf(err, "%s: %s: %s\n", prog, tmp, strerror(errno));
		return -1;
	}
	fprintf(f, "# mlip offsets (work offsets, G92, G28/G30 positions), written by the tools\n"
	           "# after each program; machine units, axes in config order:");
	for (i = 0; i < m->n_axes; i++) {
		fprintf(f, " %c", m->axis[i].letter);
	}
	fprintf(f,
	        "\n# Edit with care; delete the file to reset (all zero, G54, G28/G30 at HOME).\n");
	fprintf(f, "SELECT = %s\nG92_ON = %d\n", mlip_gcode_coord_name(o->select), o->g92_on);
	for (k = 0; k <= KEY_G30; k++) {
		const double *v = key_values((struct mlip_gcode_offsets *)o, k);

		fprintf(f, "%s =", key_name(k));
		for (i = 0; i < m->n_axes; i++) {
			fprintf(f, " %.17g", v[i]);
		}
		fputc('\n', f);
	}
	if (fclose(f) != 0 || rename(tmp, path) != 0) {
		fprintf(err, "%s: %s: %s\n", prog, path, strerror(errno));
		remove(tmp);
		return -1;
	}
	return 0;
}

void mlip_offsets_describe(const struct mlip_machine *m, const struct mlip_gcode_offsets *o,
                           char *buf, size_t len)
{
	size_t n = 0;
	int i;

	n += (size_t)snprintf(buf + n, len - n, "%s", mlip_gcode_coord_name(o->select));
	for (i = 0; i < m->n_axes && n < len; i++) {
		n += (size_t)snprintf(buf + n, len - n, " %c%g", m->axis[i].letter,
		                      o->coord[o->select][i]);
	}
	if (n < len) {
		n += (size_t)snprintf(buf + n, len - n, ", G92 %s", o->g92_on ? "on" : "off");
	}
	for (i = 0; o->g92_on && i < m->n_axes && n < len; i++) {
		n += (size_t)snprintf(buf + n, len - n, " %c%g", m->axis[i].letter, o->g92[i]);
	}
}
