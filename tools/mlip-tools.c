/*
 * mlip-tools - the operator's tool for the tool table (tools/lib/tooltable.h,
 * LinuxCNC's T P Z D format kept as a state file): show it, accept a hand
 * edit (or a table copied from LinuxCNC), make a new one.
 *
 * As for the offsets file: mlip runs only on a table it wrote or whose
 * values it has shown to the operator: after an edit, `--accept` checks
 * every line (FILE:LINE:COL for the first that is wrong), prints the tools
 * as mlip will use them and seals the file. Every write goes through the
 * state file's rules (new file, fsync, rename; never through a link; merged
 * with a change made meanwhile).
 */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

#include "statefile.h"
#include "tooltable.h"

#define PROG "mlip-tools"

enum { EXIT_DONE = 0, EXIT_FAIL = 1, EXIT_USAGE = 2 };

static void usage(FILE *f)
{
	fprintf(f, "usage: " PROG " [--accept | --init] TOOLTABLE\n"
	           "Show, accept or make an mlip tool table (LinuxCNC's format, one tool a line:\n"
	           "T2 P2 Z30.25 D3.175 ;comment; docs/gcode.md).\n\n"
	           "  (no action)   check TOOLTABLE and show its tools; exit 1 if mlip would\n"
	           "                refuse it (and why)\n"
	           "  --accept      after a hand edit (or a table from LinuxCNC): check every\n"
	           "                line, show the tools as mlip will use them, seal the file\n"
	           "  --init        a new table with no tools (refuses an existing file)\n"
	           "  -h, --help\n\n"
	           "exit status: 0 done (valid); 1 refused (the reason and what to do); 2 usage\n");
}

static void show(const struct mlip_tooltable *t)
{
	printf("%s: %u tool%s\n", t->path, (unsigned)t->n, t->n == 1 ? "" : "s");
	for (uint32_t i = 0; i < t->n; i++) {
		printf("  T%-5d P%-4d Z%-10g D%-8g %s\n", (int)t->tools[i].number,
		       (int)t->tools[i].pocket, t->tools[i].z_mm, t->tools[i].d_mm, t->comment[i]);
	}
}

int main(int argc, char **argv)
{
	enum { SHOW, ACCEPT, INIT } action = SHOW;
	static const struct option opts[] = {{"accept", no_argument, 0, 'a'},
	                                     {"init", no_argument, 0, 'i'},
	                                     {"help", no_argument, 0, 'h'},
	                                     {0, 0, 0, 0}};
	struct mlip_tooltable t;
	struct mlip_sf_kind k;
	struct mlip_sf sf, ours;
	char why[MLIP_SF_WHY], note[MLIP_SF_WHY / 2];
	struct stat stt;
	int c, rc;

	while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
		switch (c) {
		case 'a':
			action = ACCEPT;
			break;
		case 'i':
			action = INIT;
			break;
		case 'h':
			usage(stdout);
			return EXIT_DONE;
		default:
			usage(stderr);
			return EXIT_USAGE;
		}
	}
	if (optind != argc - 1) {
		usage(stderr);
		return EXIT_USAGE;
	}
	const char *path = argv[optind];
	mlip_tooltable_kind(&k);
	if (action == INIT) {
		if (lstat(path, &stt) == 0) {
			fprintf(stderr, PROG ": %s exists: --init makes a new table only\n", path);
			return EXIT_FAIL;
		}
		mlip_sf_init(&ours);
		rc = mlip_sf_save(path, &k, &ours, NULL, note, sizeof(note), why, sizeof(why));
		mlip_sf_free(&ours);
		if (rc < 0) {
			fprintf(stderr, PROG ": error: %s\n", why);
			return EXIT_FAIL;
		}
		printf("%s: a new tool table, no tools: write their lines (T P Z D ;comment), "
		       "then " PROG " --accept %s\n",
		       path, path);
		return EXIT_DONE;
	}
	if (mlip_tooltable_load(&t, path, action == ACCEPT ? MLIP_SF_UNSEALED : 0, PROG, stderr) !=
	    0) {
		return EXIT_FAIL;
	}
	if (action == SHOW) {
		show(&t);
		mlip_tooltable_free(&t);
		return EXIT_DONE;
	}
	/* accept: the records as checked (canonical), sealed; merged with a
	 * change made since the load */
	mlip_tooltable_free(&t);
	rc = mlip_sf_load(&sf, path, &k, MLIP_SF_UNSEALED, why, sizeof(why));
	if (rc != 0) {
		fprintf(stderr, PROG ": error: %s\n", why);
		return EXIT_FAIL;
	}
	mlip_sf_init(&ours);
	for (size_t i = 0; i < sf.n; i++) {
		if (mlip_sf_put(&ours, sf.rec[i].key, sf.rec[i].value) != 0) {
			fprintf(stderr, PROG ": %s: %s\n", path, strerror(ENOMEM));
			return EXIT_FAIL;
		}
	}
	rc = mlip_sf_save(path, &k, &ours, &sf, note, sizeof(note), why, sizeof(why));
	mlip_sf_free(&sf);
	mlip_sf_free(&ours);
	if (rc < 0) {
		fprintf(stderr, PROG ": error: %s\n", why);
		return EXIT_FAIL;
	}
	if (mlip_tooltable_load(&t, path, 0, PROG, stderr) != 0) {
		return EXIT_FAIL;
	}
	show(&t);
	mlip_tooltable_free(&t);
	printf("accepted and sealed: mlip uses these tools\n");
	return EXIT_DONE;
}
