/* offsetfile.c - see offsetfile.h */
#include "offsetfile.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define KEY_G92 (MLIP_GCODE_N_COORD)
#define KEY_G28 (MLIP_GCODE_N_COORD + 1)
#define KEY_G30 (MLIP_GCODE_N_COORD + 2)
#define N_VEC   (KEY_G30 + 1) /* keys with a value per axis */

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

static const char *const required[] = {"SELECT", "G92_ON", "G54", "G55",   "G56",
                                       "G57",    "G58",    "G59", "G59.1", "G59.2",
                                       "G59.3",  "G92",    "G28", "G30",   NULL};

static const char *const header[] = {
    "mlip offsets: the work offsets G54..G59.3, G92 and the G28/G30 positions, in",
    "machine units (mm, degrees), each value named by its axis letter. mlip writes",
    "this file after every program (through a new file, fsync and rename) and",
    "checks all of it before one; the last line seals it. After a hand edit run",
    "`mlip-offsets --accept FILE`: it checks every line, shows the values and",
    "seals the file; `mlip-offsets --set \"G55 X10 Y20\" FILE` changes values",
    "without an editor.",
    NULL};

void mlip_offsets_number(double v, char *buf, size_t len)
{
	if (v == 0.0) {
		snprintf(buf, len, "0"); /* never "-0" */
		return;
	}
	for (int prec = 15; prec <= 17; prec++) {
		snprintf(buf, len, "%.*g", prec, v);
		if (strtod(buf, NULL) == v) {
			return;
		}
	}
}

/* A whole word as a number: [+-] digits [. digits] [e [+-] digits], at
 * least one digit before the exponent; finite, within MLIP_OFFSETS_MAX_ABS. */
static int strict_number(const char *s, double *out)
{
	const char *p = s;
	int digits = 0;
	if (*p == '+' || *p == '-') {
		p++;
	}
	while (isdigit((unsigned char)*p)) {
		p++, digits++;
	}
	if (*p == '.') {
		p++;
		while (isdigit((unsigned char)*p)) {
			p++, digits++;
		}
	}
	if (digits == 0) {
		return -1;
	}
	if (*p == 'e' || *p == 'E') {
		p++;
		if (*p == '+' || *p == '-') {
			p++;
		}
		if (!isdigit((unsigned char)*p)) {
			return -1;
		}
		while (isdigit((unsigned char)*p)) {
			p++;
		}
	}
	if (*p != '\0') {
		return -1;
	}
	errno = 0;
	double v = strtod(s, NULL);
	if (errno != 0 || !isfinite(v) || fabs(v) > MLIP_OFFSETS_MAX_ABS) {
		return -1;
	}
	*out = v;
	return 0;
}

/* "X10 Y20 Z-5" for the axes `axes` (each once, any order) into v (in the
 * order of axes). 0, or -1 with why. */
static int parse_axes(const char *key, const char *value, const char *axes, double *v, char *why,
                      size_t len)
{
	char buf[MLIP_SF_MAX_LINE], *save = NULL;
	int seen[MLIP_MAX_AXES] = {0};
	size_t n = strlen(axes);

	snprintf(buf, sizeof(buf), "%s", value);
	for (char *w = strtok_r(buf, " \t", &save); w != NULL; w = strtok_r(NULL, " \t", &save)) {
		char letter = (char)toupper((unsigned char)w[0]);
		const char *at = letter ? strchr(axes, letter) : NULL;
		if (!isalpha((unsigned char)w[0]) || at == NULL) {
			snprintf(
			    why, len,
			    "%s: '%s' is not a value of this machine's axes (%s: each as a letter "
			    "and a number, e.g. %c0)",
			    key, w, axes, axes[0]);
			return -1;
		}
		size_t k = (size_t)(at - axes);
		if (seen[k]) {
			snprintf(why, len, "%s: axis %c twice", key, letter);
			return -1;
		}
		if (strict_number(w + 1, &v[k]) != 0) {
			snprintf(
			    why, len,
			    "%s: %c '%s' is not a number (digits, a sign, a point, an exponent; "
			    "at most %g)",
			    key, letter, w + 1, MLIP_OFFSETS_MAX_ABS);
			return -1;
		}
		seen[k] = 1;
	}
	for (size_t k = 0; k < n; k++) {
		if (!seen[k]) {
			snprintf(
			    why, len,
			    "%s: no value for axis %c (this machine's axes: %s; the file may be "
			    "from a machine with other axes)",
			    key, axes[k], axes);
			return -1;
		}
	}
	return 0;
}

static int vec_key(const char *key)
{
	for (int k = 0; k < N_VEC; k++) {
		if (strcmp(key, key_name(k)) == 0) {
			return k;
		}
	}
	return -1;
}

static void format_axes(const char *axes, const double *v, char *out, size_t len)
{
	size_t n = 0;
	out[0] = '\0';
	for (size_t k = 0; axes[k] && n < len; k++) {
		char num[40];
		mlip_offsets_number(v[k], num, sizeof(num));
		n += (size_t)snprintf(out + n, len - n, "%s%c%s", k ? " " : "", axes[k], num);
	}
}

/* statefile.h's canon: one record of the offsets file. */
static int canon(const void *ctx, const char *key, const char *value, char *out, size_t out_len,
                 char *why, size_t why_len)
{
	struct mlip_offsets_kind_ctx *c = (struct mlip_offsets_kind_ctx *)ctx;
	if (strcmp(key, "SELECT") == 0) {
		for (int k = 0; k < MLIP_GCODE_N_COORD; k++) {
			if (strcmp(value, mlip_gcode_coord_name(k)) == 0) {
				snprintf(out, out_len, "%s", value);
				return 0;
			}
		}
		snprintf(why, why_len, "SELECT must be one of G54..G59.3, got '%s'", value);
		return -1;
	}
	if (strcmp(key, "G92_ON") == 0) {
		if (strcmp(value, "0") != 0 && strcmp(value, "1") != 0) {
			snprintf(why, why_len, "G92_ON must be 0 or 1, got '%s'", value);
			return -1;
		}
		snprintf(out, out_len, "%s", value);
		return 0;
	}
	if (strcmp(key, "TOOL") == 0) { /* the tool in the spindle: 0 none */
		size_t n = strlen(value);
		if (n == 0 || n > 10 || strspn(value, "0123456789") != n ||
		    (n > 1 && value[0] == '0') || strtoll(value, NULL, 10) > 2147483647LL) {
			snprintf(
			    why, why_len,
			    "TOOL must be the tool in the spindle, a whole number (0: none), got "
			    "'%s'",
			    value);
			return -1;
		}
		snprintf(out, out_len, "%s", value);
		return 0;
	}
	if (vec_key(key) < 0) {
		snprintf(why, why_len,
		         "unknown key '%s' (SELECT, G92_ON, G54..G59.3, G92, G28, G30, TOOL)", key);
		return -1;
	}
	if (c->axes[0] == '\0') {
		/* no machine given: the first coordinate line names the axes */
		size_t n = 0;
		char buf[MLIP_SF_MAX_LINE], *save = NULL;
		snprintf(buf, sizeof(buf), "%s", value);
		for (char *w = strtok_r(buf, " \t", &save); w != NULL && n < MLIP_MAX_AXES;
		     w = strtok_r(NULL, " \t", &save)) {
			c->axes[n++] = (char)toupper((unsigned char)w[0]);
		}
		c->axes[n] = '\0';
	}
	double v[MLIP_MAX_AXES];
	if (parse_axes(key, value, c->axes, v, why, why_len) != 0) {
		return -1;
	}
	format_axes(c->axes, v, out, out_len);
	return 0;
}

void mlip_offsets_kind(struct mlip_offsets_kind_ctx *ctx, const char *letters,
                       struct mlip_sf_kind *k)
{
	snprintf(ctx->axes, sizeof(ctx->axes), "%s", letters);
	memset(k, 0, sizeof(*k));
	k->what = "offsets file";
	k->comment = '#';
	k->accept = "mlip-offsets --accept";
	k->repair = "measure the offsets again and enter them (mlip-offsets --set, see "
	            "mlip-offsets --help), or restore the file from a backup";
	k->required = required;
	k->header = header;
	k->canon = canon;
	k->ctx = ctx;
}

static void machine_axes(const struct mlip_machine *m, char *axes)
{
	int i;
	for (i = 0; i < m->n_axes && i < MLIP_MAX_AXES; i++) {
		axes[i] = m->axis[i].letter;
	}
	axes[i] = '\0';
}

int mlip_offsets_to_records(const struct mlip_machine *m, const struct mlip_gcode_offsets *o,
                            struct mlip_sf *sf)
{
	char axes[MLIP_MAX_AXES + 1], val[MLIP_SF_MAX_LINE];
	int rc = 0;
	machine_axes(m, axes);
	rc |= mlip_sf_put(sf, "SELECT", mlip_gcode_coord_name(o->select));
	rc |= mlip_sf_put(sf, "G92_ON", o->g92_on ? "1" : "0");
	for (int k = 0; k < N_VEC; k++) {
		format_axes(axes, key_values((struct mlip_gcode_offsets *)o, k), val, sizeof(val));
		rc |= mlip_sf_put(sf, key_name(k), val);
	}
	snprintf(val, sizeof(val), "%d", (int)o->tool);
	rc |= mlip_sf_put(sf, "TOOL", val);
	return rc;
}

void mlip_offsets_from_records(const struct mlip_machine *m, const struct mlip_sf *sf,
                               struct mlip_gcode_offsets *o)
{
	char axes[MLIP_MAX_AXES + 1], why[160];
	const char *v;
	machine_axes(m, axes);
	mlip_gcode_offsets_init(o, m);
	if ((v = mlip_sf_get(sf, "SELECT")) != NULL) {
		for (int k = 0; k < MLIP_GCODE_N_COORD; k++) {
			if (strcmp(v, mlip_gcode_coord_name(k)) == 0) {
				o->select = k;
			}
		}
	}
	if ((v = mlip_sf_get(sf, "G92_ON")) != NULL) {
		o->g92_on = strcmp(v, "1") == 0;
	}
	if ((v = mlip_sf_get(sf, "TOOL")) != NULL) {
		o->tool = (int32_t)strtol(v, NULL, 10);
	}
	for (int k = 0; k < N_VEC; k++) {
		double x[MLIP_MAX_AXES];
		if ((v = mlip_sf_get(sf, key_name(k))) != NULL &&
		    parse_axes(key_name(k), v, axes, x, why, sizeof(why)) == 0) {
			memcpy(key_values(o, k), x, sizeof(double) * strlen(axes));
		}
	}
}

/* ---- the old format: KEY = values in config order ---- */

static char *trim(char *s)
{
	while (*s == ' ' || *s == '\t') {
		s++;
	}
	char *e = s + strlen(s);
	while (e > s && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\n' || e[-1] == '\r')) {
		*--e = '\0';
	}
	return s;
}

static int old_key(const char *key)
{
	return strcmp(key, "SELECT") == 0 || strcmp(key, "G92_ON") == 0 || vec_key(key) >= 0;
}

int mlip_offsets_is_old(const char *path)
{
	char buf[MLIP_SF_MAX_LINE];
	FILE *f = fopen(path, "r");
	int old = 0;
	if (f == NULL) {
		return 0;
	}
	while (!old && fgets(buf, sizeof(buf), f)) {
		char *s = trim(buf), *eq = strchr(s, '=');
		if (*s == '#' || eq == NULL) {
			continue;
		}
		*eq = '\0';
		old = old_key(trim(s));
	}
	fclose(f);
	return old;
}

int mlip_offsets_read_old(const char *path, const struct mlip_machine *m,
                          struct mlip_gcode_offsets *o, char *why, size_t why_len)
{
	char buf[MLIP_SF_MAX_LINE];
	unsigned line = 0;
	int seen[N_VEC + 2] = {0};
	FILE *f = fopen(path, "r");
	if (f == NULL) {
		snprintf(why, why_len, "%s: %s", path, strerror(errno));
		return -1;
	}
	mlip_gcode_offsets_init(o, m);
	while (fgets(buf, sizeof(buf), f)) {
		char *s = trim(buf), *eq = strchr(s, '='), *key, *val, *save = NULL;
		int k, n = 0;
		double v[MLIP_MAX_AXES];
		line++;
		if (*s == '\0' || *s == '#' || *s == ';') {
			continue;
		}
		if (eq == NULL) {
			snprintf(why, why_len, "%s:%u: expected KEY = VALUE", path, line);
			goto bad;
		}
		*eq = '\0';
		key = trim(s);
		val = trim(eq + 1);
		k = strcmp(key, "SELECT") == 0   ? N_VEC
		    : strcmp(key, "G92_ON") == 0 ? N_VEC + 1
		                                 : vec_key(key);
		if (k < 0 || seen[k]) {
			snprintf(why, why_len, "%s:%u: %s '%s'", path, line,
			         k < 0 ? "unknown key" : "a second", key);
			goto bad;
		}
		seen[k] = 1;
		if (k == N_VEC || k == N_VEC + 1) {
			char c[32];
			struct mlip_offsets_kind_ctx ctx = {""};
			if (canon(&ctx, key, val, c, sizeof(c), why, why_len) != 0) {
				goto bad;
			}
			if (k == N_VEC) {
				for (int j = 0; j < MLIP_GCODE_N_COORD; j++) {
					if (strcmp(c, mlip_gcode_coord_name(j)) == 0) {
						o->select = j;
					}
				}
			} else {
				o->g92_on = c[0] == '1';
			}
			continue;
		}
		for (char *w = strtok_r(val, " \t", &save); w != NULL;
		     w = strtok_r(NULL, " \t", &save)) {
			if (n == m->n_axes || strict_number(w, &v[n]) != 0) {
				snprintf(why, why_len, "%s:%u: %s needs %d numbers", path, line,
				         key, m->n_axes);
				goto bad;
			}
			n++;
		}
		if (n != m->n_axes) {
			snprintf(why, why_len, "%s:%u: %s needs %d numbers, got %d", path, line,
			         key, m->n_axes, n);
			goto bad;
		}
		memcpy(key_values(o, k), v, sizeof(double) * (size_t)n);
	}
	fclose(f);
	return 0;
bad:
	fclose(f);
	return -1;
}

/* ---- load, save ---- */

int mlip_offsets_load(struct mlip_offsets_file *f, const char *path, const struct mlip_machine *m,
                      struct mlip_gcode_offsets *o, const char *prog, FILE *err)
{
	struct mlip_offsets_kind_ctx ctx;
	struct mlip_sf_kind k;
	struct mlip_sf sf;
	char axes[MLIP_MAX_AXES + 1], why[MLIP_SF_WHY];

	mlip_gcode_offsets_init(o, m);
	machine_axes(m, axes);
	mlip_offsets_kind(&ctx, axes, &k);
	int rc = mlip_sf_load(&sf, path, &k, 0, why, sizeof(why));
	if (rc == -ENOENT) {
		fprintf(err,
		        "%s: %s: no such offsets file: check the path (a program never runs on "
		        "offsets it assumed); a new file (all zero, G54, G28/G30 at HOME): "
		        "mlip-offsets --init --config CONFIG %s\n",
		        prog, path, path);
		return -1;
	}
	if (rc != 0) {
		if (mlip_offsets_is_old(path)) {
			fprintf(
			    err,
			    "%s: %s: an offsets file of the old format (KEY = values in config "
			    "order, no axis letters, no end marker: it cannot be told from a file "
			    "cut short): convert it once with mlip-offsets --convert --config "
			    "CONFIG %s, then check the values it shows (this machine's axis "
			    "order: %s)\n",
			    prog, path, path, axes);
		} else {
			fprintf(err, "%s: error: %s\n", prog, why);
		}
		return -1;
	}
	mlip_offsets_from_records(m, &sf, o);
	if (f != NULL) {
		f->path = path;
		f->loaded = sf;
		f->ok = 1;
	} else {
		mlip_sf_free(&sf);
	}
	return 0;
}

int mlip_offsets_save(struct mlip_offsets_file *f, const struct mlip_machine *m,
                      const struct mlip_gcode_offsets *o, const char *prog, FILE *err)
{
	struct mlip_offsets_kind_ctx ctx;
	struct mlip_sf_kind k;
	struct mlip_sf ours;
	char axes[MLIP_MAX_AXES + 1];

	machine_axes(m, axes);
	mlip_offsets_kind(&ctx, axes, &k);
	mlip_sf_init(&ours);
	int rc = mlip_offsets_to_records(m, o, &ours);
	if (rc == 0) {
		rc = mlip_sf_save_told(f->path, &k, &ours, f->ok ? &f->loaded : NULL, "offsets",
		                       "program", prog, err);
	} else {
		fprintf(err, "%s: error: %s: %s\n", prog, f->path, strerror(ENOMEM));
		rc = -1;
	}
	mlip_sf_free(&ours);
	return rc;
}

void mlip_offsets_file_free(struct mlip_offsets_file *f)
{
	if (f != NULL && f->ok) {
		mlip_sf_free(&f->loaded);
		f->ok = 0;
	}
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
	if (o->tool > 0 && n < len) {
		snprintf(buf + n, len - n, ", tool %d in the spindle", (int)o->tool);
	}
}
