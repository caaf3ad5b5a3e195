/*
 * mlip-ctl - talk to a running mlip-rt through its shared-memory segment:
 * feed override, hold, resume (the command mailbox of mlip/ipc/ring.h), stop
 * (the stop counter: its own path, never behind the mailbox), and a status
 * report (the controller's and the feeder's seqlocked areas).
 *
 * A command is posted only once the previous one is completed (the mailbox
 * has one slot), then acknowledged by the controller with a result code; a
 * stop is acknowledged by the controller's stop_seen. Every wait is bounded
 * (1 s) so a dead controller never hangs the tool.
 *
 * Its parts (ctltool.h): the status report (ctlstatus.c), jog and home
 * (ctljog.c), MDI (ctlmdi.c, through the feeder of mlip-feed, feed.h).
 */
#include <errno.h>
#include <getopt.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cli.h"
#include "ctltool.h"
#include "mlip/ipc/ring.h"
#include "rt.h"

void usage(FILE *f)
{
	fprintf(
	    f,
	    "usage: " PROG " [--shm NAME] COMMAND\n"
	    "Send a command to the mlip-rt controller, or show its status.\n\n"
	    "commands:\n"
	    "  override PCT     feed override, percent, integer 0..200 (0 stops the feed)\n"
	    "  spindle-override PCT  spindle override, percent, 50..200 (a CiA 402 spindle;\n"
	    "                   within MIN_RPM..MAX_RPM)\n"
	    "  hold             feed hold: decelerate to rest on the path, keep the program\n"
	    "  resume           leave a feed hold, a stall hold or a pause (M0, M1, M60)\n"
	    "  stop             decelerate to rest on the path, drop the rest of the program\n"
	    "  optional-stop on|off  M1 pauses the program (on) or is passed (off)\n"
	    "  reset            leave an E-stop or a limit stop once its input is released\n"
	    "  home [AXES]      home the axes (every one with a HOME_METHOD) with their\n"
	    "                   drives' homing mode, in HOME_SEQUENCE order; waits for the end\n"
	    "  jog AXIS+|AXIS-[DIST]... [--distance D] SPEED [SECONDS]  jog at SPEED mm/min\n"
	    "                   (deg/min; several axes: along one line at that speed):\n"
	    "                   continuous until SECONDS pass, a signal (Ctrl-C, a dropped\n"
	    "                   session) or the soft limit, then a stop at the acceleration\n"
	    "                   limit; incremental with a distance (X+1.5, or --distance D\n"
	    "                   for every axis): refused when its target lies beyond a soft\n"
	    "                   limit; it stops by itself 250 ms after mlip-ctl stops\n"
	    "                   renewing it (killed)\n"
	    "  mdi [OPTIONS] LINE...  MDI: run G-code lines (or `-`: from standard input)\n"
	    "                   from where the machine stands, checked as a program is\n"
	    "                   (mlip-feed's rules, soft limits, offsets file, tool table);\n"
	    "                   refused unless the machine is idle; the modal state (G90/G91,\n"
	    "                   G20/G21, F, G43 ...) carries to the next mdi (mlip-ctl mdi\n"
	    "                   --help)\n"
	    "  status [--json]  controller and feeder state (--json: one object on stdout)\n"
	    "  -                commands from standard input, one per line, each answered\n"
	    "                   (on stdout, or stderr when refused) before the next is read\n\n"
	    "options:\n"
	    "  --shm NAME       shared-memory segment of the controller (default " MLIP_SHM_DEFAULT
	    ")\n"
	    "  --json           status as JSON\n"
	    "  -h, --help       this help\n\n"
	    "exit status: 0 done (status: controller alive, not in fault); 1 refused, no\n"
	    "answer within 1 s, controller not running (or, for status, in fault); 2 usage\n"
	    "error or no usable segment\n");
}

void sleep_ns(long ns)
{
	struct timespec ts = {0, ns};

	clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, NULL);
}

/* Strict percentage: decimal digits only, 0..200 (no sign, no spaces, no '%'). */
static int parse_pct(const char *s, int32_t *out)
{
	long v = 0;
	size_t i;

	if (s == NULL || s[0] == '\0' || strlen(s) > 3) {
		return -1;
	}
	for (i = 0; s[i] != '\0'; i++) {
		if (s[i] < '0' || s[i] > '9') {
			return -1;
		}
		v = v * 10 + (s[i] - '0');
	}
	if (v > 200) {
		return -1;
	}
	*out = (int32_t)v;
	return 0;
}

/* What a controller's refusal means, for the message. */
static const char *result_text(int32_t result)
{
	switch (result) {
	case MLIP_OK:
		return "done";
	case MLIP_E_FULL:
		return "busy";
	case MLIP_E_EMPTY:
		return "nothing to do";
	case MLIP_E_INVALID:
		return "not possible in this state";
	case MLIP_E_SYNTAX:
		return "malformed";
	case MLIP_E_RANGE:
		return "value out of range";
	case MLIP_E_UNSUPPORTED:
		return "not supported by this controller";
	}
	return "unknown result";
}

static void describe(char *buf, size_t len, mlip_ring_cmd_op op, int32_t arg)
{
	if (op == MLIP_CMD_OVERRIDE || op == MLIP_CMD_SPINDLE_OVERRIDE) {
		snprintf(buf, len, "%s %d %%",
		         op == MLIP_CMD_OVERRIDE ? "override" : "spindle-override", (int)arg);
	} else if (op == MLIP_CMD_OPTIONAL_STOP) {
		snprintf(buf, len, "optional-stop %s", arg ? "on" : "off");
	} else {
		snprintf(buf, len, "%s", mlip_ring_cmd_name(op));
	}
}

/* stop: the stop counter (never refused, never behind a busy mailbox or a
 * dead mlip-ctl), acknowledged by the controller's stop_seen. Posted even to
 * a controller that does not answer: a stop is latched for a program whose
 * mlip-feed began before it (it is being checked, or waits), which then
 * never starts. */
static int cmd_stop(struct mlip_shm *s)
{
	struct mlip_ring_status st, before;
	int alive = mlip_shm_controller_alive(s->ring);
	/* a program waiting at rest (a pause, a dwell, a manual spindle or tool
	 * change) ends in IDLE at once: it was not "idle" */
	int waiting = read_status(s->ring, &before) == 0 &&
	              (before.state == MLIP_STATE_PAUSED || before.state == MLIP_STATE_DWELLING);
	uint32_t ticket = mlip_ring_stop_post(s->ring);
	int32_t feeder = mlip_shm_feeder_holder(s);
	uint64_t t0 = mlip_now_ns();

	if (!alive) {
		fprintf(stderr, PROG ": stop: controller on %s is not running: start mlip-rt%s\n",
		        s->name,
		        feeder ? " (the stop is posted: the waiting mlip-feed will not start its "
		                 "program)"
		               : "");
		return EXIT_FAIL;
	}
	for (;;) {
		if (read_status(s->ring, &st) == 0 &&
		    mlip_ring_stop_applied(st.stop_seen, ticket)) {
			break;
		}
		if (mlip_now_ns() - t0 >= (uint64_t)WAIT_NS) {
			fprintf(stderr, PROG
			        ": stop: no answer from the controller within 1 s (posted: it is "
			        "applied when the controller runs again): check " PROG " status\n");
			return EXIT_FAIL;
		}
		sleep_ns(POLL_NS);
	}
	if (st.state == MLIP_STATE_IDLE && waiting) {
		printf("stop: done (the program waited at rest, line %u: it is dropped)\n",
		       (unsigned)before.reason_line);
	} else if (st.state == MLIP_STATE_IDLE && feeder != 0) {
		printf("stop: done (the machine was idle; the program of mlip-feed pid %d, "
		       "begun before this stop, will not start)\n",
		       (int)feeder);
	} else if (st.state == MLIP_STATE_IDLE) {
		printf("stop: done (the machine was idle)\n");
	} else {
		printf("stop: done\n");
	}
	return EXIT_DONE;
}

static int cmd_send(struct mlip_shm *s, mlip_ring_cmd_op op, int32_t arg)
{
	struct mlip_ring_status st;
	char what[32];
	uint32_t seq = 0;
	int32_t result;
	uint64_t t0;
	mlip_status rc;

	if (op == MLIP_CMD_STOP) {
		return cmd_stop(s);
	}
	describe(what, sizeof(what), op, arg);
	if (!mlip_shm_controller_alive(s->ring)) {
		fprintf(stderr, PROG ": %s: controller on %s is not running: start mlip-rt\n", what,
		        s->name);
		return EXIT_FAIL;
	}
	t0 = mlip_now_ns();
	while ((rc = mlip_ring_cmd_post(s->ring, op, arg, &seq)) == MLIP_E_FULL &&
	       mlip_now_ns() - t0 < (uint64_t)WAIT_NS) {
		sleep_ns(POLL_NS); /* a previous command is still being applied */
	}
	if (rc != MLIP_OK) {
		fprintf(stderr,
		        PROG ": %s: the command mailbox stayed busy for 1 s (the controller "
		             "completes a command each period: it is not running, or other "
		             "mlip-ctl keep it busy; stop has its own path): check " PROG
		             " status\n",
		        what);
		return EXIT_FAIL;
	}
	t0 = mlip_now_ns();
	while ((rc = mlip_ring_cmd_result(s->ring, seq, &result)) != MLIP_OK) {
		if (rc == MLIP_E_RANGE) {
			printf("%s: done (applied; its result was overwritten by later commands of "
			       "another mlip-ctl: check " PROG " status)\n",
			       what);
			return EXIT_DONE;
		}
		if (mlip_now_ns() - t0 >= (uint64_t)WAIT_NS) {
			fprintf(stderr,
			        PROG
			        ": %s: no answer from the controller within 1 s (posted; it may "
			        "still be applied): check " PROG " status\n",
			        what);
			return EXIT_FAIL;
		}
		sleep_ns(POLL_NS);
	}
	if (result != MLIP_OK && op == MLIP_CMD_RESET) {
		fprintf(stderr, PROG ": reset: refused by the controller: %s",
		        result == MLIP_E_RANGE
		            ? "the input that stopped the machine is still on (release the E-stop, "
		              "move the axis off its limit switch; a lost I/O module needs a "
		              "restart of mlip-rt)"
		            : "nothing to reset (no E-stop, no limit)");
		if (read_status(s->ring, &st) == 0) {
			fprintf(stderr, " (state %s)", mlip_ctl_state_name(st.state));
		}
		fputc('\n', stderr);
		return EXIT_FAIL;
	}
	if (result != MLIP_OK) {
		fprintf(stderr, PROG ": %s: refused by the controller: %s", what,
		        result_text(result));
		if (read_status(s->ring, &st) == 0) {
			fprintf(stderr, " (state %s)", mlip_ctl_state_name(st.state));
		}
		fputc('\n', stderr);
		return EXIT_FAIL;
	}
	printf("%s: done\n", what);
	return EXIT_DONE;
}

/* Commands with an argument word after them. */
static int op_takes_arg(const char *cmd)
{
	return strcmp(cmd, "override") == 0 || strcmp(cmd, "optional-stop") == 0 ||
	       strcmp(cmd, "spindle-override") == 0;
}

/* One command word (and PCT for override) -> op, arg; EXIT_USAGE with a
 * message when it is not one. */
static int parse_command(const char *cmd, const char *pct, mlip_ring_cmd_op *op, int32_t *arg)
{
	*arg = 0;
	if (strcmp(cmd, "override") == 0) {
		*op = MLIP_CMD_OVERRIDE;
		if (pct == NULL) {
			fprintf(stderr, PROG ": override: missing PCT (percent, 0..200)\n");
			return EXIT_USAGE;
		}
		if (parse_pct(pct, arg) != 0) {
			fprintf(stderr,
			        PROG ": override: '%s' is not a whole percentage in 0..200\n", pct);
			return EXIT_USAGE;
		}
	} else if (strcmp(cmd, "spindle-override") == 0) {
		*op = MLIP_CMD_SPINDLE_OVERRIDE;
		if (parse_pct(pct, arg) != 0 || *arg < 50) {
			fprintf(stderr,
			        PROG
			        ": spindle-override: '%s' is not a whole percentage in 50..200\n",
			        pct == NULL ? "" : pct);
			return EXIT_USAGE;
		}
	} else if (strcmp(cmd, "hold") == 0) {
		*op = MLIP_CMD_HOLD;
	} else if (strcmp(cmd, "resume") == 0) {
		*op = MLIP_CMD_RESUME;
	} else if (strcmp(cmd, "stop") == 0) {
		*op = MLIP_CMD_STOP;
	} else if (strcmp(cmd, "reset") == 0) {
		*op = MLIP_CMD_RESET;
	} else if (strcmp(cmd, "optional-stop") == 0) {
		*op = MLIP_CMD_OPTIONAL_STOP;
		if (pct == NULL || (strcmp(pct, "on") != 0 && strcmp(pct, "off") != 0)) {
			fprintf(stderr, PROG ": optional-stop: expected on or off\n");
			return EXIT_USAGE;
		}
		*arg = strcmp(pct, "on") == 0;
	} else {
		fprintf(stderr,
		        PROG ": unknown command '%s' (override, spindle-override, hold, resume, "
		             "stop, optional-stop, reset, status, -)\n",
		        cmd);
		return EXIT_USAGE;
	}
	return 0;
}

/* One line of f, whole: its first cap - 1 bytes into buf (NUL-terminated),
 * the rest read and counted, never split into another line. *len is the
 * line's full length (newline excluded); *nul is set when it holds a NUL.
 * 0 at the end of the input. */
static int read_line(FILE *f, char *buf, size_t cap, size_t *len, int *nul)
{
	size_t n = 0;
	int c, any = 0;

	*nul = 0;
	while ((c = getc(f)) != EOF) {
		any = 1;
		if (c == '\n') {
			break;
		}
		*nul |= c == '\0';
		if (n + 1 < cap) {
			buf[n] = (char)c;
		}
		n++;
	}
	buf[n + 1 < cap ? n : cap - 1] = '\0';
	*len = n;
	return any;
}

/* '-': commands from standard input, one per line, each applied (or refused)
 * before the next line is read: for a pendant or a script driving one
 * long-lived mlip-ctl. Lines are read whole, whatever their length: a
 * comment line (#) of any length is skipped, a command line longer than
 * LINE_MAX - 1 bytes (or with a NUL) is no command. Exit 0 when every
 * command was done, else 1 (2: a line that is not a command ends the input;
 * the lines before it were applied, nothing of it). */
static int cmd_stdin(struct mlip_shm *s)
{
	char line[LINE_MAX];
	size_t len;
	int rc = EXIT_DONE, nul;
	unsigned long lineno = 0;
	while (read_line(stdin, line, sizeof(line), &len, &nul)) {
		char *w[3] = {NULL, NULL, NULL}, *save = NULL;
		int n = 0;
		mlip_ring_cmd_op op;
		int32_t arg;
		lineno++;
		const char *first = line + strspn(line, " \t\r");
		if (*first == '#' || (len < sizeof(line) && !nul && *first == '\0')) {
			continue; /* a comment, whatever its length; a blank line */
		}
		if (len >= sizeof(line) || nul) {
			fprintf(stderr,
			        PROG ": stdin:%lu: %s: not a command (nothing of it was applied)\n",
			        lineno,
			        nul ? "a NUL byte in the line" : "line longer than 255 bytes");
			return EXIT_USAGE;
		}
		for (char *t = strtok_r(line, " \t\r", &save); t != NULL && n < 3;
		     t = strtok_r(NULL, " \t\r", &save)) {
			w[n++] = t;
		}
		int takes_arg = op_takes_arg(w[0]);
		if (parse_command(w[0], w[1], &op, &arg) != 0 || n > 1 + takes_arg) {
			fprintf(stderr,
			        PROG ": stdin:%lu: expected one of override PCT, hold, resume, "
			             "stop, optional-stop on|off\n",
			        lineno);
			return EXIT_USAGE;
		}
		if (cmd_send(s, op, arg) != EXIT_DONE) {
			rc = EXIT_FAIL;
		}
		fflush(stdout);
	}
	return rc;
}

int main(int argc, char **argv)
{
	static const struct option opts[] = {{"shm", required_argument, 0, 's'},
	                                     {"json", no_argument, 0, 'j'},
	                                     {"help", no_argument, 0, 'h'},
	                                     {0, 0, 0, 0}};
	const char *shm = MLIP_SHM_DEFAULT, *cmd, *jog_args[3] = {NULL, NULL, NULL};
	mlip_ring_cmd_op op = MLIP_CMD_NONE;
	int32_t arg = 0;
	int json = 0, c, i, rc, jog_argc = 0;
	char **jog_argv = NULL;
	struct mlip_shm s;
	char why[256];

	/* '+': stop at the command, so "override -5" reaches the PCT check */
	while ((c = getopt_long(argc, argv, "+h", opts, NULL)) != -1) {
		switch (c) {
		case 's':
			shm = optarg;
			break;
		case 'j':
			json = 1;
			break;
		case 'h':
			usage(stdout);
			return EXIT_DONE;
		default:
			usage(stderr);
			return EXIT_USAGE;
		}
	}
	if (optind >= argc) {
		usage(stderr);
		return EXIT_USAGE;
	}
	cmd = argv[optind++];
	if (strcmp(cmd, "mdi") == 0) {
		if (json) {
			fprintf(stderr, PROG ": --json goes with status only\n");
			return EXIT_USAGE;
		}
		return cmd_mdi(shm, argc - optind + 1, argv + optind - 1);
	}
	if (strcmp(cmd, "jog") == 0) {
		if (argc - optind < 2) {
			fprintf(stderr,
			        PROG ": jog: expected AXIS+|AXIS-[DIST]... [--distance D] SPEED "
			             "[SECONDS]\n");
			return EXIT_USAGE;
		}
		jog_argc = argc - optind;
		jog_argv = argv + optind;
		optind = argc;
	} else if (strcmp(cmd, "home") == 0) {
		if (argc - optind > 1) {
			fprintf(stderr, PROG ": home: expected [AXES] (e.g. XZ)\n");
			return EXIT_USAGE;
		}
		jog_args[0] = optind < argc ? argv[optind++] : NULL;
	} else if (strcmp(cmd, "status") == 0) {
		for (i = optind; i < argc; i++) {
			if (strcmp(argv[i], "--json") != 0) {
				fprintf(stderr, PROG ": status: unexpected '%s' (only --json)\n",
				        argv[i]);
				return EXIT_USAGE;
			}
			json = 1;
		}
	} else {
		if (strcmp(cmd, "-") != 0) {
			const char *pct = optind < argc ? argv[optind] : NULL;
			if ((rc = parse_command(cmd, pct, &op, &arg)) != 0) {
				return rc;
			}
			optind += op_takes_arg(cmd);
		}
		if (optind < argc) {
			fprintf(stderr, PROG ": %s: unexpected '%s'\n", cmd, argv[optind]);
			return EXIT_USAGE;
		}
		if (json) {
			fprintf(stderr, PROG ": --json goes with status only\n");
			return EXIT_USAGE;
		}
	}

	rc = mlip_shm_attach(&s, shm, why, sizeof(why));
	if (rc != 0) {
		fprintf(stderr, PROG ": %s\n", why);
		if (rc == -ENOENT) {
			fprintf(stderr,
			        PROG ": hint: start the controller (mlip-rt) first, or pass "
			             "its --shm NAME\n");
		}
		return EXIT_USAGE;
	}
	if (strcmp(cmd, "jog") == 0) {
		rc = cmd_jog(&s, jog_argc, jog_argv);
	} else if (strcmp(cmd, "home") == 0) {
		rc = cmd_home(&s, jog_args[0]);
	} else if (strcmp(cmd, "-") == 0) {
		rc = cmd_stdin(&s);
	} else {
		rc = op == MLIP_CMD_NONE ? cmd_status(&s, json) : cmd_send(&s, op, arg);
	}
	mlip_shm_close(&s);
	return rc;
}
