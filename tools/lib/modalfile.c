/*
 * modalfile.c - the MDI modal state file (modalfile.h) on statefile.h.
 */
#include "modalfile.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "offsetfile.h"

static const char *const required[] = {"MOTION",    "PLANE", "DISTANCE",    "UNITS",
                                       "FEED_MODE", "F",     "PATH",        "TOLERANCE",
                                       "S",         "T",     "TOOL_OFFSET", NULL};

static const char *const header[] = {
    "mlip MDI modal state: what one mlip-ctl mdi command leaves for the next",
    "(as LinuxCNC's interpreter keeps it). Written by mlip-ctl mdi; after a hand",
    "edit, accept it with mlip-ctl mdi --accept FILE, or delete it to start MDI",
    "from a program's defaults (G17 G90 G21 G94 G64, no F).", NULL};

/* The words a key takes, its value index in the order written. */
/* MOTION: none, G0..G3, or G80: none after a canned cycle (motion -2) */
static const char *const w_motion[] = {"none", "G0", "G1", "G2", "G3", "G80", NULL};
static const char *const w_plane[] = {"G17", "G18", "G19", NULL};
static const char *const w_dist[] = {"G91", "G90", NULL};
static const char *const w_units[] = {"G21", "G20", NULL};
static const char *const w_feed[] = {"G94", "G93", NULL};
static const char *const w_path[] = {"G64", "G61", NULL};

static int word_index(const char *const *words, const char *v)
{
	for (int i = 0; words[i] != NULL; i++) {
		if (strcmp(words[i], v) == 0) {
			return i;
		}
	}
	return -1;
}

static const char *const *words_of(const char *key)
{
	return strcmp(key, "MOTION") == 0      ? w_motion
	       : strcmp(key, "PLANE") == 0     ? w_plane
	       : strcmp(key, "DISTANCE") == 0  ? w_dist
	       : strcmp(key, "UNITS") == 0     ? w_units
	       : strcmp(key, "FEED_MODE") == 0 ? w_feed
	       : strcmp(key, "PATH") == 0      ? w_path
	                                       : NULL;
}

/* A strict decimal number (a sign, digits, a point, an exponent), finite. */
static int number(const char *s, double *v)
{
	char *end;
	if (s[0] == '\0' || s[0] == ' ' || s[0] == '\t') {
		return -1;
	}
	errno = 0;
	*v = strtod(s, &end);
	if (*end != '\0' || errno != 0 || !isfinite(*v) || strchr(s, 'x') || strchr(s, 'X') ||
	    strchr(s, 'n') || strchr(s, 'N') || strchr(s, 'i') || strchr(s, 'I')) {
		return -1;
	}
	return 0;
}

static void num_text(double v, char *out, size_t len)
{
	mlip_offsets_number(v, out, len);
}

/* F, S, T, TOLERANCE: "none" (not TOLERANCE) or a number in range. */
static int canon(const void *ctx, const char *key, const char *value, char *out, size_t out_len,
                 char *why, size_t why_len)
{
	const char *const *words = words_of(key);
	double v;
	(void)ctx;

	if (words != NULL) {
		if (word_index(words, value) < 0) {
			char list[64] = "";
			for (int i = 0; words[i] != NULL; i++) {
				strncat(list, i ? ", " : "", sizeof(list) - strlen(list) - 1);
				strncat(list, words[i], sizeof(list) - strlen(list) - 1);
			}
			snprintf(why, why_len, "%s '%s': one of %s", key, value, list);
			return -1;
		}
		snprintf(out, out_len, "%s", value);
		return 0;
	}
	if (strcmp(key, "TOOL_OFFSET") == 0) {
		if (strcmp(value, "G49") == 0) {
			snprintf(out, out_len, "G49");
			return 0;
		}
		int g431 = strncmp(value, "G43.1 ", 6) == 0;
		if ((g431 || strncmp(value, "G43 ", 4) == 0) &&
		    number(value + (g431 ? 6 : 4), &v) == 0 && fabs(v) <= MLIP_OFFSETS_MAX_ABS) {
			char n[40];
			num_text(v, n, sizeof(n));
			snprintf(out, out_len, "%s %s", g431 ? "G43.1" : "G43", n);
			return 0;
		}
		snprintf(why, why_len,
		         "TOOL_OFFSET '%s': G49, or G43 or G43.1 and the offset in mm (|v| <= "
		         "1e6)",
		         value);
		return -1;
	}
	if (strcmp(key, "F") == 0 || strcmp(key, "S") == 0 || strcmp(key, "T") == 0 ||
	    strcmp(key, "TOLERANCE") == 0) {
		int tol = strcmp(key, "TOLERANCE") == 0, t = strcmp(key, "T") == 0;
		if (!tol && strcmp(value, "none") == 0) {
			snprintf(out, out_len, "none");
			return 0;
		}
		if (number(value, &v) == 0 && (tol ? v > 0 && v <= 1e3
		                               : t ? v >= 0 && v <= 2147483647.0 && v == floor(v)
		                                   : v > 0 && v <= 1e9)) {
			num_text(v, out, out_len);
			return 0;
		}
		snprintf(why, why_len, "%s '%s': %s", key, value,
		         tol ? "a tolerance in mm, > 0"
		         : t ? "a tool number (0 or more), or none"
		             : "a positive number, or none");
		return -1;
	}
	snprintf(why, why_len,
	         "unknown key %s (MOTION, PLANE, DISTANCE, UNITS, FEED_MODE, F, PATH, "
	         "TOLERANCE, S, T, TOOL_OFFSET)",
	         key);
	return -1;
}

void mlip_modal_kind(struct mlip_sf_kind *k)
{
	memset(k, 0, sizeof(*k));
	k->what = "MDI modal state file";
	k->comment = '#';
	k->accept = "mlip-ctl mdi --accept";
	k->repair = "delete it: the next mlip-ctl mdi starts from a program's defaults (G17 G90 "
	            "G21 G94 G64, no F); give the modes it needs in its line";
	k->required = required;
	k->header = header;
	k->canon = canon;
	k->ctx = NULL;
}

int mlip_modal_to_records(const struct mlip_gcode_modal *md, struct mlip_sf *sf)
{
	char v[64], n[40];
	int rc = 0;

	rc |= mlip_sf_put(sf, "MOTION", w_motion[md->motion == -2 ? 5 : md->motion + 1]);
	rc |= mlip_sf_put(sf, "PLANE", w_plane[md->plane - 17]);
	rc |= mlip_sf_put(sf, "DISTANCE", w_dist[md->absolute != 0]);
	rc |= mlip_sf_put(sf, "UNITS", w_units[md->inches != 0]);
	rc |= mlip_sf_put(sf, "FEED_MODE", w_feed[md->inverse_time != 0]);
	if (md->feed_word > 0) {
		num_text(md->feed_word, v, sizeof(v));
	} else {
		snprintf(v, sizeof(v), "none");
	}
	rc |= mlip_sf_put(sf, "F", v);
	rc |= mlip_sf_put(sf, "PATH", w_path[md->exact_stop != 0]);
	num_text(md->tol_mm, v, sizeof(v));
	rc |= mlip_sf_put(sf, "TOLERANCE", v);
	if (md->s_rpm >= 0) {
		num_text(md->s_rpm, v, sizeof(v));
	} else {
		snprintf(v, sizeof(v), "none");
	}
	rc |= mlip_sf_put(sf, "S", v);
	if (md->tool_sel >= 0) {
		snprintf(v, sizeof(v), "%ld", (long)md->tool_sel);
	} else {
		snprintf(v, sizeof(v), "none");
	}
	rc |= mlip_sf_put(sf, "T", v);
	if (md->tlo_mode == 490) {
		snprintf(v, sizeof(v), "G49");
	} else {
		num_text(md->tlo_mm, n, sizeof(n));
		snprintf(v, sizeof(v), "%s %s", md->tlo_mode == 431 ? "G43.1" : "G43", n);
	}
	rc |= mlip_sf_put(sf, "TOOL_OFFSET", v);
	return rc;
}

int mlip_modal_from_records(const struct mlip_sf *sf, const struct mlip_machine *m,
                            struct mlip_gcode_modal *md, char *why, size_t why_len)
{
	const char *v;
	struct mlip_gcode g;

	mlip_gcode_modal_init(md, m);
	for (int i = 0; required[i] != NULL; i++) {
		if (mlip_sf_get(sf, required[i]) == NULL) {
			snprintf(why, why_len, "no %s record", required[i]);
			return -1;
		}
	}
	/* every record passed canon (mlip_sf_load): the words are known */
	md->motion = word_index(w_motion, mlip_sf_get(sf, "MOTION")) - 1;
	md->motion = md->motion == 4 ? -2 : md->motion; /* G80 */
	md->plane = 17 + word_index(w_plane, mlip_sf_get(sf, "PLANE"));
	md->absolute = word_index(w_dist, mlip_sf_get(sf, "DISTANCE"));
	md->inches = word_index(w_units, mlip_sf_get(sf, "UNITS"));
	md->inverse_time = word_index(w_feed, mlip_sf_get(sf, "FEED_MODE"));
	v = mlip_sf_get(sf, "F");
	md->feed_word = strcmp(v, "none") == 0 ? 0.0 : strtod(v, NULL);
	md->exact_stop = word_index(w_path, mlip_sf_get(sf, "PATH"));
	md->tol_mm = strtod(mlip_sf_get(sf, "TOLERANCE"), NULL);
	v = mlip_sf_get(sf, "S");
	md->s_rpm = strcmp(v, "none") == 0 ? -1.0 : strtod(v, NULL);
	v = mlip_sf_get(sf, "T");
	md->tool_sel = strcmp(v, "none") == 0 ? -1 : (int32_t)strtol(v, NULL, 10);
	v = mlip_sf_get(sf, "TOOL_OFFSET");
	md->tlo_mode = strcmp(v, "G49") == 0 ? 490 : strncmp(v, "G43.1 ", 6) == 0 ? 431 : 430;
	md->tlo_mm = md->tlo_mode == 490 ? 0.0 : strtod(strchr(v, ' ') + 1, NULL);
	if (md->tol_mm > m->tolerance_mm) {
		snprintf(why, why_len,
		         "TOLERANCE %g mm: more than this machine's CONTOUR_TOLERANCE %g mm",
		         md->tol_mm, m->tolerance_mm);
		return -1;
	}
	mlip_gcode_init(&g, m);
	if (mlip_gcode_set_modal(&g, md) != MLIP_OK) {
		snprintf(why, why_len,
		         "F %g %s/min: out of the feed range of every block (0.06 mm/min .. 60 "
		         "m/min), or F with G93",
		         md->feed_word, md->inches ? "in" : "mm");
		return -1;
	}
	return 0;
}

int mlip_modal_load(struct mlip_modal_file *f, const char *path, const struct mlip_machine *m,
                    struct mlip_gcode_modal *md, int *missing, const char *prog, FILE *err)
{
	struct mlip_sf_kind k;
	struct mlip_sf sf;
	char why[MLIP_SF_WHY], why2[256];

	memset(f, 0, sizeof(*f));
	f->path = path;
	*missing = 0;
	mlip_gcode_modal_init(md, m);
	mlip_modal_kind(&k);
	int rc = mlip_sf_load(&sf, path, &k, 0, why, sizeof(why));
	if (rc == -ENOENT) {
		*missing = 1;
		return 0;
	}
	if (rc != 0) {
		fprintf(err, "%s: error: %s\n", prog, why);
		return -1;
	}
	if (mlip_modal_from_records(&sf, m, md, why2, sizeof(why2)) != 0) {
		fprintf(err, "%s: error: %s: %s; %s\n", prog, path, why2, k.repair);
		mlip_sf_free(&sf);
		return -1;
	}
	f->loaded = sf;
	f->ok = 1;
	return 0;
}

int mlip_modal_save(struct mlip_modal_file *f, const struct mlip_gcode_modal *md, const char *prog,
                    FILE *err)
{
	struct mlip_sf_kind k;
	struct mlip_sf ours;

	mlip_modal_kind(&k);
	mlip_sf_init(&ours);
	int rc = mlip_modal_to_records(md, &ours);
	if (rc == 0) {
		rc = mlip_sf_save_told(f->path, &k, &ours, f->ok ? &f->loaded : NULL, "modal state",
		                       "MDI", prog, err);
	} else {
		fprintf(err, "%s: error: %s: %s\n", prog, f->path, strerror(ENOMEM));
		rc = -1;
	}
	mlip_sf_free(&ours);
	return rc;
}

void mlip_modal_file_free(struct mlip_modal_file *f)
{
	if (f->ok) {
		mlip_sf_free(&f->loaded);
	}
	f->ok = 0;
}

void mlip_modal_describe(const struct mlip_gcode_modal *md, char *buf, size_t len)
{
	char motion[16] = "", path[48] = "G61", f[48] = "", tlo[64] = "G49", n[40];
	if (md->motion >= 0 || md->motion == -2) {
		snprintf(motion, sizeof(motion), "G%d ", md->motion >= 0 ? md->motion : 80);
	}
	if (!md->exact_stop) {
		mlip_offsets_number(md->tol_mm, n, sizeof(n));
		snprintf(path, sizeof(path), "G64 P%s", n);
	}
	if (md->feed_word > 0) {
		mlip_offsets_number(md->feed_word, n, sizeof(n));
		snprintf(f, sizeof(f), " F%s", n);
	}
	if (md->tlo_mode != 490) {
		mlip_offsets_number(md->tlo_mm, n, sizeof(n));
		snprintf(tlo, sizeof(tlo), "%s (Z %s mm)", md->tlo_mode == 431 ? "G43.1" : "G43",
		         n);
	}
	snprintf(buf, len, "%sG%d G%d G%d G%d %s%s %s", motion, md->plane, md->absolute ? 90 : 91,
	         md->inches ? 20 : 21, md->inverse_time ? 93 : 94, path, f, tlo);
}

/* --accept: a hand-edited file checked and sealed again. */
int mlip_modal_accept(const char *path, const char *prog, FILE *err)
{
	struct mlip_sf_kind k;
	struct mlip_sf sf;
	char why[MLIP_SF_WHY], note[MLIP_SF_WHY / 2];

	mlip_modal_kind(&k);
	if (mlip_sf_load(&sf, path, &k, MLIP_SF_UNSEALED, why, sizeof(why)) != 0) {
		fprintf(err, "%s: error: %s\n", prog, why);
		return -1;
	}
	for (int i = 0; required[i] != NULL; i++) {
		if (mlip_sf_get(&sf, required[i]) == NULL) {
			fprintf(err, "%s: error: %s: no %s record\n", prog, path, required[i]);
			mlip_sf_free(&sf);
			return -1;
		}
	}
	int rc = mlip_sf_save(path, &k, &sf, NULL, note, sizeof(note), why, sizeof(why));
	if (rc < 0) {
		fprintf(err, "%s: error: %s\n", prog, why);
	}
	mlip_sf_free(&sf);
	return rc < 0 ? -1 : 0;
}
