/*
 * mlip-offsets - the operator's tool for the offsets file (tools/lib/offsets.h,
 * a state file: tools/lib/statefile.h): show it, change values without an
 * editor, accept a hand edit, make a new file, convert an old one.
 *
 * What a machinist expects: the file is plain text they can read and edit;
 * mlip refuses to run on a file it did not write (or whose values it has
 * not been shown to be accepted): after an edit, `--accept` checks every
 * line, prints the values as mlip will use them and seals the file (its end
 * marker); `--set` changes a value and seals at once. Every write goes
 * through the state file's rules (new file, fsync, rename; never through a
 * link; merged per key with a change made meanwhile).
 */
#include <ctype.h>
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "offsets.h"
#include "statefile.h"

#define PROG     "mlip-offsets"
#define MAX_SETS 32

enum { EXIT_DONE = 0, EXIT_FAIL = 1, EXIT_USAGE = 2 };

static void usage(FILE *f)
{
	fprintf(
	    f, "usage: " PROG " [--config FILE.ini] [ACTION] OFFSETS\n"
	       "Show, change, accept, make or convert an mlip offsets file (the work offsets\n"
	       "G54..G59.3, G92 and the G28/G30 positions; docs/gcode.md).\n\n"
	       "  (no action)       check OFFSETS and show its values; exit 1 if mlip would\n"
	       "                    refuse it (and why)\n"
	       "  --set \"KEY ...\"   change values and seal the file, e.g. --set \"G55 X10 Y20\"\n"
	       "                    (the axes not named keep their values), --set \"SELECT G55\",\n"
	       "                    --set \"G92_ON 0\"; may be given several times\n"
	       "  --accept          after a hand edit: check every line, show the values as\n"
	       "                    mlip will use them, and seal the file (its end marker)\n"
	       "  --init            a new file: every offset zero, G54, G92 off, G28/G30 at\n"
	       "                    the config's HOME (needs --config; refuses an existing file)\n"
	       "  --convert         a file of the old format (KEY = values in config order) to\n"
	       "                    this one, its values read in --config's axis order: check\n"
	       "                    what it shows\n"
	       "  --config FILE.ini the machine: its axes are checked against the file's\n"
	       "  -h, --help\n\n"
	       "exit status: 0 done (valid); 1 refused (the reason and what to do); 2 usage\n");
}

static void show(const struct mlip_sf *sf, const char *path)
{
	printf("%s:\n", path);
	for (size_t i = 0; i < sf->n; i++) {
		printf("  %-7s %s\n", sf->rec[i].key, sf->rec[i].value);
	}
}

/* "G55 X10 Z-5" over the current value of G55 in sf (the axes named
 * replace theirs), through the kind's check. 0, or -1 with a message. */
static int apply_set(struct mlip_sf *sf, const struct mlip_sf_kind *k, const char *arg)
{
	char buf[MLIP_SF_MAX_LINE], key[MLIP_SF_KEY], merged[MLIP_SF_MAX_LINE];
	char canon[MLIP_SF_MAX_LINE], why[MLIP_SF_WHY];
	const char *cur;
	snprintf(buf, sizeof(buf), "%s", arg);
	char *save = NULL, *w = strtok_r(buf, " \t", &save);
	if (w == NULL || strlen(w) >= sizeof(key)) {
		fprintf(stderr, PROG ": --set '%s': expected KEY VALUE...\n", arg);
		return -1;
	}
	strcpy(key, w);
	char *rest = save ? save + strspn(save, " \t") : NULL;
	if (rest == NULL || *rest == '\0') {
		fprintf(stderr, PROG ": --set '%s': no value\n", arg);
		return -1;
	}
	snprintf(merged, sizeof(merged), "%s", rest);
	cur = mlip_sf_get(sf, key);
	if (cur != NULL && isalpha((unsigned char)rest[0]) && strchr(cur, ' ') != NULL) {
		/* axis words: start from the current ones, replace those named */
		char words[MLIP_SF_MAX_LINE], *s2 = NULL, out[MLIP_SF_MAX_LINE] = "";
		snprintf(words, sizeof(words), "%s", cur);
		for (char *cw = strtok_r(words, " \t", &s2); cw != NULL;
		     cw = strtok_r(NULL, " \t", &s2)) {
			const char *named = NULL;
			char given[MLIP_SF_MAX_LINE], *s3 = NULL;
			snprintf(given, sizeof(given), "%s", rest);
			for (char *gw = strtok_r(given, " \t", &s3); gw != NULL;
			     gw = strtok_r(NULL, " \t", &s3)) {
				if (toupper((unsigned char)gw[0]) == cw[0]) {
					named = rest + (gw - given);
					break;
				}
			}
			size_t n = strlen(out);
			if (named != NULL) {
				size_t wl = strcspn(named, " \t");
				snprintf(out + n, sizeof(out) - n, "%s%.*s", n ? " " : "", (int)wl,
				         named);
			} else {
				snprintf(out + n, sizeof(out) - n, "%s%s", n ? " " : "", cw);
			}
		}
		/* a letter given that the file does not have: let the check name it */
		char given[MLIP_SF_MAX_LINE], *s3 = NULL;
		snprintf(given, sizeof(given), "%s", rest);
		for (char *gw = strtok_r(given, " \t", &s3); gw != NULL;
		     gw = strtok_r(NULL, " \t", &s3)) {
			char l = (char)toupper((unsigned char)gw[0]);
			int have = 0;
			for (const char *c = cur; *c; c++) {
				have |= (c == cur || c[-1] == ' ') && *c == l;
			}
			if (!have) {
				size_t n = strlen(out);
				snprintf(out + n, sizeof(out) - n, " %s", gw);
			}
		}
		snprintf(merged, sizeof(merged), "%s", out);
	}
	if (k->canon(k->ctx, key, merged, canon, sizeof(canon), why, sizeof(why)) != 0) {
		fprintf(stderr, PROG ": --set '%s': %s\n", arg, why);
		return -1;
	}
	if (cur == NULL) {
		fprintf(stderr, PROG ": --set '%s': %s is not a key of the file\n", arg, key);
		return -1;
	}
	return mlip_sf_put(sf, key, canon);
}

static int save(const char *path, const struct mlip_sf_kind *k, const struct mlip_sf *ours,
                const struct mlip_sf *base)
{
	char why[MLIP_SF_WHY], note[MLIP_SF_WHY / 2];
	int rc = mlip_sf_save(path, k, ours, base, note, sizeof(note), why, sizeof(why));
	if (rc < 0) {
		fprintf(stderr, PROG ": error: %s\n", why);
		return EXIT_FAIL;
	}
	if (rc == 1) {
		fprintf(stderr,
		        PROG ": %s: merged with a change made meanwhile: %s as the file had it\n",
		        path, note);
	}
	return EXIT_DONE;
}

int main(int argc, char **argv)
{
	enum { SHOW, SET, ACCEPT, INIT, CONVERT } action = SHOW;
	static const struct option opts[] = {{"set", required_argument, 0, 's'},
	                                     {"accept", no_argument, 0, 'a'},
	                                     {"init", no_argument, 0, 'i'},
	                                     {"convert", no_argument, 0, 'c'},
	                                     {"config", required_argument, 0, 'C'},
	                                     {"help", no_argument, 0, 'h'},
	                                     {0, 0, 0, 0}};
	static struct mlip_config cfg;
	struct mlip_cli_machine mo = {0};
	const char *sets[MAX_SETS];
	int n_sets = 0, c, actions = 0;
	char axes[MLIP_MAX_AXES + 1] = "", why[MLIP_SF_WHY];

	while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
		switch (c) {
		case 's':
			if (n_sets == MAX_SETS) {
				fprintf(stderr, PROG ": at most %d --set\n", MAX_SETS);
				return EXIT_USAGE;
			}
			sets[n_sets++] = optarg;
			actions += n_sets == 1;
			action = SET;
			break;
		case 'a':
			action = ACCEPT;
			actions++;
			break;
		case 'i':
			action = INIT;
			actions++;
			break;
		case 'c':
			action = CONVERT;
			actions++;
			break;
		case 'C':
			mo.config = optarg;
			break;
		case 'h':
			usage(stdout);
			return EXIT_DONE;
		default:
			usage(stderr);
			return EXIT_USAGE;
		}
	}
	if (optind != argc - 1 || actions > 1) {
		usage(stderr);
		return EXIT_USAGE;
	}
	const char *path = argv[optind];
	if ((action == INIT || action == CONVERT) && mo.config == NULL) {
		fprintf(stderr, PROG ": --%s needs --config FILE.ini (the machine's axes%s)\n",
		        action == INIT ? "init" : "convert", action == INIT ? " and HOME" : "");
		return EXIT_USAGE;
	}
	if (mo.config != NULL) {
		if (mlip_cli_build_machine(&mo, NULL, &cfg, PROG, stderr) != 0) {
			return EXIT_FAIL;
		}
		for (int k = 0; k < cfg.machine.n_axes; k++) {
			axes[k] = cfg.machine.axis[k].letter;
		}
		axes[cfg.machine.n_axes] = '\0';
	}
	struct mlip_offsets_kind_ctx ctx;
	struct mlip_sf_kind kind;
	struct mlip_sf sf, ours;
	mlip_offsets_kind(&ctx, axes, &kind);
	mlip_sf_init(&ours);

	if (action == INIT || action == CONVERT) {
		struct mlip_gcode_offsets o;
		struct stat st;
		if (action == INIT && lstat(path, &st) == 0) {
			fprintf(stderr, PROG ": --init: %s exists: it is left as it is\n", path);
			return EXIT_FAIL;
		}
		if (action == CONVERT) {
			if (!mlip_offsets_is_old(path)) {
				fprintf(stderr,
				        PROG ": --convert: %s is not an offsets file of the old "
				             "format (KEY = values)\n",
				        path);
				return EXIT_FAIL;
			}
			if (mlip_offsets_read_old(path, &cfg.machine, &o, why, sizeof(why)) != 0) {
				fprintf(stderr, PROG ": --convert: %s\n", why);
				return EXIT_FAIL;
			}
		} else {
			mlip_gcode_offsets_init(&o, &cfg.machine);
		}
		if (mlip_offsets_to_records(&cfg.machine, &o, &ours) != 0) {
			return EXIT_FAIL;
		}
		int rc = save(path, &kind, &ours, NULL);
		if (rc == EXIT_DONE) {
			show(&ours, path);
			if (action == CONVERT) {
				printf(
				    "converted: the old file's values were read in the axis order "
				    "%s of %s; check each against the machine\n",
				    axes, mo.config);
			}
		}
		mlip_sf_free(&ours);
		return rc;
	}

	int rc = mlip_sf_load(&sf, path, &kind, action == ACCEPT ? MLIP_SF_UNSEALED : 0, why,
	                      sizeof(why));
	if (rc != 0) {
		if (rc != -ENOENT && mlip_offsets_is_old(path)) {
			fprintf(stderr,
			        PROG ": %s: the old format (KEY = values in config order): "
			             "mlip-offsets --convert --config CONFIG %s\n",
			        path, path);
		} else if (rc == -ENOENT) {
			fprintf(stderr,
			        PROG ": %s: no such file (mlip-offsets --init --config CONFIG "
			             "%s makes one)\n",
			        path, path);
		} else {
			fprintf(stderr, PROG ": error: %s\n", why);
		}
		return EXIT_FAIL;
	}
	if (action == SHOW) {
		show(&sf, path);
		mlip_sf_free(&sf);
		return EXIT_DONE;
	}
	/* accept, set: ours = the file's records (canonical), changed */
	for (size_t i = 0; i < sf.n; i++) {
		if (mlip_sf_put(&ours, sf.rec[i].key, sf.rec[i].value) != 0) {
			return EXIT_FAIL;
		}
	}
	for (int i = 0; i < n_sets; i++) {
		if (apply_set(&ours, &kind, sets[i]) != 0) {
			mlip_sf_free(&sf);
			mlip_sf_free(&ours);
			return EXIT_FAIL;
		}
	}
	rc = save(path, &kind, &ours, &sf);
	if (rc == EXIT_DONE) {
		show(&ours, path);
		if (action == ACCEPT) {
			printf("accepted and sealed: mlip uses these values\n");
		}
	}
	mlip_sf_free(&sf);
	mlip_sf_free(&ours);
	return rc;
}
