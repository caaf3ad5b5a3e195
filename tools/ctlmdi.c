/*
 * ctlmdi.c - mlip-ctl mdi (ctltool.h): MDI lines checked and sent by the
 * feeder (feed.h), from the modal state the last MDI left (modalfile.h).
 */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "ctltool.h"
#include "feed.h"
#include "modalfile.h"

#define MDI_MAX_BYTES 65536 /* MDI lines at once: more is a program (mlip-feed) */

static void mdi_usage(FILE *f)
{
	fprintf(
	    f, "usage: " PROG " [--shm NAME] mdi [OPTIONS] LINE...\n"
	       "       " PROG " [--shm NAME] mdi [OPTIONS] -      (the lines from standard input)\n"
	       "       " PROG " mdi --accept FILE                 (seal a hand-edited modal file)\n"
	       "Run G-code lines typed at the machine (MDI) on the running mlip-rt: checked\n"
	       "together exactly as mlip-feed checks a program (every rule, the soft limits\n"
	       "from where the machine stands, the offsets file, the tool table), then run\n"
	       "through the same ring; refused unless the machine is idle (no program, jog or\n"
	       "homing). Lines without motion are fine (G91, F600, G10 L20 P1 X0 Y0, G92).\n"
	       "The modal state the lines leave (G0-G3, G17-G19, G90/G91, G20/G21, G93/G94,\n"
	       "F, G61/G64 P, S, T, G43/G49) is where the next mdi starts, as in LinuxCNC;\n"
	       "work offsets, G92 and the selected G54-G59.3 go to the offsets file.\n\n"
	       "  --offsets FILE    the offsets file (read before, written when the lines\n"
	       "                    complete: a touch-off is kept)\n"
	       "  --modal FILE      the modal state file (default: OFFSETS.modal beside the\n"
	       "                    offsets file; without either, every mdi starts from a\n"
	       "                    program's defaults: G17 G90 G21 G94 G64, no F)\n"
	       "  --tools FILE      the tool table (T6 M6, G43 H)\n"
	       "  --strict          refuse Grbl '$' lines and axis words before G0/G1/G2/G3\n"
	       "  --ignore-spindle, --ignore-coolant, --ignore-tools   as mlip-feed\n"
	       "  -q, --quiet       errors only\n\n"
	       "exit status: mlip-feed's (0 done, 1 refused or nothing sent, 2 usage, 3\n"
	       "controller gone, 4 stopped, 5 fault)\n");
}

/* The lines of argv (joined by newlines), or of stdin for "-": into a
 * malloc'ed buffer. 0, or an exit status after saying why. */
static int mdi_text(int n, char **lines, char **text, size_t *len)
{
	char *b = malloc(MDI_MAX_BYTES + 2);
	size_t k = 0;

	if (b == NULL) {
		fprintf(stderr, PROG ": mdi: out of memory\n");
		return EXIT_FAIL;
	}
	if (n == 1 && strcmp(lines[0], "-") == 0) {
		k = fread(b, 1, MDI_MAX_BYTES + 1, stdin);
		if (ferror(stdin)) {
			fprintf(stderr, PROG ": mdi: reading standard input: %s\n",
			        strerror(errno));
			free(b);
			return EXIT_FAIL;
		}
	} else {
		for (int i = 0; i < n && k <= MDI_MAX_BYTES; i++) {
			size_t l = strlen(lines[i]);
			if (k + l + 1 > MDI_MAX_BYTES + 1) {
				k = MDI_MAX_BYTES + 1;
				break;
			}
			memcpy(b + k, lines[i], l);
			k += l;
			b[k++] = '\n';
		}
	}
	if (k > MDI_MAX_BYTES) {
		fprintf(stderr,
		        PROG ": mdi: more than %d bytes of lines: that is a program: save it to a "
		             "file and run it with mlip-feed (nothing was sent)\n",
		        MDI_MAX_BYTES);
		free(b);
		return EXIT_USAGE;
	}
	b[k] = '\0';
	*text = b;
	*len = k;
	return 0;
}

int cmd_mdi(const char *shm, int argc, char **argv)
{
	static const struct option opts[] = {MLIP_CLI_GCODE_OPTIONS,
	                                     {"modal", required_argument, 0, 'M'},
	                                     {"accept", required_argument, 0, 'A'},
	                                     {"quiet", no_argument, 0, 'q'},
	                                     {"help", no_argument, 0, 'h'},
	                                     {0, 0, 0, 0}};
	struct mlip_feed_opts o = {0};
	struct mlip_modal_file mf = {0};
	struct mlip_gcode_modal md;
	struct mlip_machine m;
	const char *modal = NULL, *accept = NULL;
	char *modal_buf = NULL, *text = NULL;
	size_t len = 0;
	int c, rc, missing = 0;

	o.prog = PROG " mdi";
	o.shm = shm;
	o.path = "mdi";
	o.mdi = 1;
	o.first_seq = 1;
	optind = 0; /* glibc: a fresh scan of argv (argv[0] is "mdi") */
	/* '+': a line may start with '-' only as "-" itself; "--" ends the options */
	while ((c = getopt_long(argc, argv, "+qh", opts, NULL)) != -1) {
		int taken = mlip_cli_gcode_option(c, optarg, &o.gc, PROG " mdi", stderr);
		if (taken != 0) {
			if (taken < 0) {
				return EXIT_USAGE;
			}
			continue;
		}
		switch (c) {
		case 'M':
			modal = optarg;
			break;
		case 'A':
			accept = optarg;
			break;
		case 'q':
			o.quiet = 1;
			break;
		case 'h':
			mdi_usage(stdout);
			return EXIT_DONE;
		default:
			mdi_usage(stderr);
			return EXIT_USAGE;
		}
	}
	if (accept != NULL) {
		if (optind != argc) {
			fprintf(stderr, PROG ": mdi --accept FILE takes no lines\n");
			return EXIT_USAGE;
		}
		if (mlip_modal_accept(accept, PROG " mdi", stderr) != 0) {
			return EXIT_FAIL;
		}
		printf("%s: checked and sealed\n", accept);
		return EXIT_DONE;
	}
	if (optind >= argc) {
		fprintf(stderr, PROG ": mdi: no line given (mlip-ctl mdi 'G0 Z5', or - to read "
		                     "them from standard input)\n");
		return EXIT_USAGE;
	}
	if ((rc = mdi_text(argc - optind, argv + optind, &text, &len)) != 0) {
		return rc;
	}
	if (modal == NULL && o.gc.offsets != NULL) {
		size_t n = strlen(o.gc.offsets) + sizeof(".modal");
		modal_buf = malloc(n);
		if (modal_buf == NULL) {
			free(text);
			return EXIT_FAIL;
		}
		snprintf(modal_buf, n, "%s.modal", o.gc.offsets);
		modal = modal_buf;
	}
	o.text = text;
	o.text_len = len;
	if (modal != NULL) {
		/* the machine the controller publishes: the ranges the state must fit */
		struct mlip_shm s;
		char why[256];
		if (mlip_shm_attach(&s, shm, why, sizeof(why)) != 0) {
			fprintf(stderr, PROG " mdi: %s\n", why);
			rc = EXIT_FAIL;
			goto out;
		}
		mlip_ring_machine(s.ring, &m);
		mlip_shm_close(&s);
		if (mlip_modal_load(&mf, modal, &m, &md, &missing, PROG " mdi", stderr) != 0) {
			rc = EXIT_FAIL;
			goto out;
		}
		o.modal = &md;
	}
	rc = mlip_feed_run(&o);
	if (o.checked && !o.quiet) {
		char d[256];
		mlip_modal_describe(&o.modal_end, d, sizeof(d));
		fprintf(stderr, PROG " mdi: modal state: %s\n", d);
	}
	if (modal != NULL && o.checked && rc == EXIT_DONE) {
		if (mlip_modal_save(&mf, &o.modal_end, PROG " mdi", stderr) != 0) {
			rc = EXIT_FAIL;
		} else if (missing && !o.quiet) {
			fprintf(stderr, PROG " mdi: %s: the modal state file, made now\n", modal);
		}
	} else if (modal != NULL && o.checked) {
		fprintf(stderr,
		        PROG " mdi: the lines did not complete: the modal state in %s is left as "
		             "it was\n",
		        modal);
	} else if (modal == NULL && o.checked && rc == EXIT_DONE && !o.quiet) {
		fprintf(stderr, PROG " mdi: no --offsets or --modal: this modal state is not "
		                     "kept for the next mdi\n");
	}
out:
	mlip_modal_file_free(&mf);
	free(modal_buf);
	free(text);
	return rc;
}
