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
 */
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <time.h>

#include "cli.h"
#include "feed.h"
#include "iostatus.h"
#include "json.h"
#include "mlip/canopen/canopen.h"
#include "mlip/ipc/ring.h"
#include "modalfile.h"
#include "rt.h"

#define PROG     "mlip-ctl"
#define WAIT_NS  1000000000LL /* post retries and answer wait: 1 s each */
#define POLL_NS  1000000L     /* poll the mailbox every 1 ms */
#define LINE_MAX 256          /* `-`: a longer command line is refused whole */

enum { EXIT_DONE = 0, EXIT_FAIL = 1, EXIT_USAGE = 2 };

static void usage(FILE *f)
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

static void sleep_ns(long ns)
{
	struct timespec ts = {0, ns};

	clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, NULL);
}

/* Strict percentage: decimal digits only, 0..200 (no sign, no spaces, no '%'). */
/* status.spindle_state (mlip_spindle_phase + 1) */
static const char *spindle_state_name(uint32_t v)
{
	static const char *const names[] = {"none",     "stopped", "to speed",
	                                    "at speed", "braking", "fault"};
	return v < sizeof(names) / sizeof(names[0]) ? names[v] : "?";
}

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

/* Age in ns of a CLOCK_MONOTONIC stamp; -1 when never stamped. */
static int64_t age_ns(uint64_t stamp_ns)
{
	return mlip_peer_age_ns(stamp_ns, mlip_now_ns());
}

/* Seqlock reads fail only while a writer is mid-update for 1000 tries in a
 * row (or died there): retry for 10 ms before giving up. */
static int read_status(const struct mlip_ring *r, struct mlip_ring_status *st)
{
	int i;

	for (i = 0; i < 10; i++) {
		if (mlip_ring_status_read(r, st) == MLIP_OK) {
			return 0;
		}
		sleep_ns(POLL_NS);
	}
	return -1;
}

static int read_feeder(const struct mlip_ring *r, struct mlip_ring_feeder *f)
{
	int i;

	for (i = 0; i < 10; i++) {
		if (mlip_ring_feeder_read(r, f) == MLIP_OK) {
			return 0;
		}
		sleep_ns(POLL_NS);
	}
	return -1;
}

static void print_age(FILE *f, int64_t a)
{
	if (a < 0) {
		fprintf(f, "never");
	} else if (a < 1000000000LL) {
		fprintf(f, "%.1f ms ago", (double)a / 1e6);
	} else {
		fprintf(f, "%.1f s ago", (double)a / 1e9);
	}
}

/* The state of a controller that does not beat (mlip/ipc/peer.h): its
 * process there but not running, or gone. */
static const char *dead_name(mlip_peer_verdict v)
{
	return v == MLIP_PEER_LATE ? "not responding" : "not running";
}

/* Axis letter -> value, for the axes in mask. */
static void json_axes(struct mlip_json *j, const char *key, const struct mlip_machine *m,
                      const double *v, uint32_t mask)
{
	mlip_json_object(j, key, 1);
	for (int k = 0; k < m->n_axes; k++) {
		if (mask & (1u << k)) {
			char letter[2] = {m->axis[k].letter, '\0'};
			mlip_json_number(j, letter, "%.17g", v[k]);
		}
	}
	mlip_json_close(j);
}

/* The jog in progress (reason JOG: MLIP_JOG_FIELD in reason_field): "X+ Y-",
 * "incremental X+"; NULL when none. */
static const char *jog_text(const struct mlip_ring_status *st, const struct mlip_machine *m,
                            char *buf, size_t len)
{
	uint32_t f = st->reason_field, axes = (f >> 8) & 0xFFu;
	if (st->state != MLIP_STATE_JOGGING || st->reason != MLIP_WHY_JOG) {
		return NULL;
	}
	if (axes == 0) {
		axes = 1u << (f & 7u); /* one axis: its direction is the speed's sign */
		f |= st->reason_value < 0 ? axes << 16 : 0u;
	}
	size_t n = (size_t)snprintf(buf, len, "%s", f & (1u << 24) ? "incremental" : "");
	for (int k = 0; k < m->n_axes && n < len; k++) {
		if (axes & (1u << k)) {
			n += (size_t)snprintf(buf + n, len - n, "%s%c%c", n ? " " : "",
			                      m->axis[k].letter, (f >> (16 + k)) & 1u ? '-' : '+');
		}
	}
	return buf;
}

/* status --json: one object on stdout. */
static void status_json(const struct mlip_shm *s, const struct mlip_ring_status *st,
                        const struct mlip_ring_feeder *fd, const struct mlip_machine *m,
                        mlip_peer_verdict v, int64_t age, int falive)
{
	struct mlip_json j;
	char fname[160];
	int alive = v == MLIP_PEER_ALIVE;
	uint32_t all = (1u << m->n_axes) - 1u;
	double home[MLIP_MAX_AXES];
	mlip_json_begin(&j, stdout);
	mlip_json_string(&j, "shm", s->name);
	/* a controller that does not beat is in no state of its own: say so,
	 * with the one it last published beside */
	mlip_json_string(&j, "state", alive ? mlip_ctl_state_name(st->state) : dead_name(v));
	mlip_json_string(&j, "last_state", mlip_ctl_state_name(st->state));
	mlip_json_bool(&j, "alive", alive);
	mlip_json_string(&j, "liveness", mlip_peer_verdict_name(v));
	mlip_json_uint(&j, "heartbeat", st->heartbeat);
	mlip_json_number(&j, "heartbeat_age_ms", "%.3f", age < 0 ? NAN : (double)age / 1e6);
	mlip_json_string(&j, "reason", mlip_state_why_name(st->reason));
	mlip_json_uint(&j, "reason_seq", st->reason_seq);
	mlip_json_uint(&j, "reason_line", st->reason_line);
	if (st->reason == MLIP_WHY_SPINDLE || st->reason == MLIP_WHY_TOOL ||
	    st->reason == MLIP_WHY_COOLANT) {
		char what[200];
		mlip_cli_io_message(st->reason, st->reason_value, NULL, what, sizeof(what));
		mlip_json_string(&j, "operator", what);
	}
	if (st->reason == MLIP_WHY_DRIVE || st->reason == MLIP_WHY_SPINDLE_FAULT) {
		/* a drive fault: the field is the event, with the drive's node */
		mlip_cli_drive_fault_text(st->reason_field, (int64_t)st->reason_value, fname,
		                          sizeof(fname));
		mlip_json_string(&j, "reason_field",
		                 mlip_drive_fault_name((mlip_drive_fault)st->reason_field));
		mlip_json_uint(&j, "reason_node", st->reason_node);
		mlip_json_string(&j, "reason_text", fname);
	} else if (st->reason_field == MLIP_FIELD_NONE || st->reason == MLIP_WHY_JOG) {
		mlip_json_null(&j, "reason_field"); /* a jog's: "jog" below */
	} else {
		mlip_cli_field_name(m, st->reason_field, fname, sizeof(fname));
		mlip_json_string(&j, "reason_field", fname);
	}
	mlip_json_number(&j, "reason_value", "%.17g", st->reason_value);
	char jw[64];
	if (jog_text(st, m, jw, sizeof(jw)) != NULL) {
		mlip_json_string(&j, "jog", jw);
	} else {
		mlip_json_null(&j, "jog");
	}
	json_axes(&j, "position", m, st->pos, all);
	/* where the current (or last) program began: a continuation's origin */
	json_axes(&j, "program_start", m, st->prog_start, all);
	/* the drives' position actual (mlip-rt --drives), and the machine's HOME:
	 * where they were at bring-up; null without drives */
	for (int k = 0; k < m->n_axes; k++) {
		home[k] = m->axis[k].home;
	}
	if (st->actual_mask == 0) {
		mlip_json_null(&j, "position_actual");
		mlip_json_null(&j, "start_position");
	} else {
		json_axes(&j, "position_actual", m, st->pos_actual, st->actual_mask);
		json_axes(&j, "start_position", m, home, all);
	}
	/* the drives' power (mlip-rt --drives): null without drives */
	if (st->drive_power == MLIP_POWER_NONE) {
		mlip_json_null(&j, "drives");
	} else {
		mlip_json_string(&j, "drives", mlip_drive_power_name(st->drive_power));
	}
	mlip_json_uint(&j, "drives_last_change_periods", st->drive_power_periods);
	/* a CiA 402 spindle (issue 19): null without one */
	if (st->spindle_state == 0) {
		mlip_json_null(&j, "spindle");
	} else {
		mlip_json_object(&j, "spindle", 0);
		mlip_json_string(&j, "state", spindle_state_name(st->spindle_state));
		mlip_json_number(&j, "commanded_rpm", "%.1f", st->spindle_cmd_rpm);
		mlip_json_number(&j, "actual_rpm", "%.1f", st->spindle_actual_rpm);
		mlip_json_uint(&j, "override_pct", st->spindle_override);
		mlip_json_uint(&j, "node", st->spindle_node);
		mlip_json_close(&j);
	}
	mlip_json_object(&j, "homed", 1);
	for (int k = 0; k < m->n_axes; k++) {
		char l[2] = {m->axis[k].letter, '\0'};
		mlip_json_bool(&j, l, (st->homed >> k) & 1u);
	}
	mlip_json_close(&j);
	/* the inputs on the bus (issue 18): each mapped function, on or off
	 * (null: not read yet) */
	mlip_json_object(&j, "inputs", 0);
	for (uint32_t f = 0; f < MLIP_IN_COUNT; f++) {
		if (st->io_mapped & (1u << f)) {
			mlip_io_function_name(f, m, fname, sizeof(fname));
			if (st->io_known & (1u << f)) {
				mlip_json_bool(&j, fname, (st->io_inputs >> f) & 1u);
			} else {
				mlip_json_null(&j, fname);
			}
		}
	}
	mlip_json_close(&j);
	mlip_iostatus_json(&j, m, st, s->ring); /* outputs, coolant, the last probe (issue 19) */
	if (st->reason == MLIP_WHY_ESTOP || st->reason == MLIP_WHY_LIMIT) {
		mlip_json_string(&j, "reason_input",
		                 mlip_io_function_name(st->reason_field, m, fname, sizeof(fname)));
		mlip_json_uint(&j, "reason_node", st->reason_node);
	} else if (st->reason == MLIP_WHY_IO_LOST) {
		mlip_json_string(&j, "reason_input",
		                 mlip_drive_fault_name((mlip_drive_fault)st->reason_field));
		mlip_json_uint(&j, "reason_node", st->reason_node);
	}
	/* not known without a controller */
	mlip_json_number(&j, "speed_mm_s", "%.17g", alive ? st->speed_mm_s : NAN);
	mlip_json_number(&j, "dwell_left_s", "%.6f", (double)st->dwell_left * m->period_s);
	mlip_json_bool(&j, "optional_stop", st->optional_stop);
	mlip_json_uint(&j, "exec_seq", st->exec_seq);
	mlip_json_uint(&j, "exec_line", st->exec_line);
	mlip_json_uint(&j, "override_pct", st->override_pct);
	mlip_json_uint(&j, "overruns", st->overruns);
	mlip_json_uint(&j, "underruns", st->underruns);
	mlip_json_uint(&j, "can_tx_errors", st->can_tx_errors);
	mlip_json_uint(&j, "can_bus_errors", st->can_bus_errors);
	mlip_json_uint(&j, "frames_sent", st->frames_sent);
	mlip_json_uint(&j, "blocks_consumed", st->blocks_consumed);
	mlip_json_uint(&j, "stops", st->stops);
	mlip_json_number(&j, "stop_mm", "%.6f", (double)st->stop_nm * 1e-6);
	mlip_json_uint(&j, "stop_periods", st->stop_periods);
	mlip_json_uint(&j, "queued", mlip_ring_count(s->ring));
	mlip_json_uint(&j, "capacity", s->ring->capacity);
	mlip_json_int(&j, "feeder_pid", fd->pid);
	mlip_json_bool(&j, "feeder_alive", falive);
	mlip_json_bool(&j, "mdi", fd->pid != 0 && falive && fd->mdi);
	mlip_json_uint(&j, "total_blocks", fd->total_blocks);
	mlip_json_bool(&j, "program_end", fd->program_end);
	mlip_json_end(&j);
}

static int cmd_status(struct mlip_shm *s, int json)
{
	struct mlip_ring_status st;
	struct mlip_ring_feeder fd;
	struct mlip_machine m;
	char fname[160];
	struct mlip_peer_watch watch = {0, 0, 0};
	struct mlip_peer_seen seen;
	mlip_peer_verdict v;
	int alive, falive;
	int64_t a, fa;

	if (read_status(s->ring, &st) != 0) {
		fprintf(stderr,
		        PROG ": %s: status area stays mid-update (controller died while "
		             "writing it?): restart mlip-rt\n",
		        s->name);
		return EXIT_FAIL;
	}
	if (read_feeder(s->ring, &fd) != 0) {
		memset(&fd, 0, sizeof(fd)); /* a feeder died mid-update: report none */
	}
	seen = (struct mlip_peer_seen){st.heartbeat, st.heartbeat_ns, 0, -1};
	v = mlip_peer_check(&seen, st.reserved, &watch, NULL);
	if (v != MLIP_PEER_ALIVE) {
		/* an old stamp may be ours to blame (we were paused): look again
		 * after the timeout; a heartbeat that moved is alive */
		struct mlip_ring_status again;
		struct timespec ts = {0, (long)MLIP_PEER_TIMEOUT_NS};
		nanosleep(&ts, NULL);
		if (read_status(s->ring, &again) == 0) {
			st = again;
			seen = (struct mlip_peer_seen){st.heartbeat, st.heartbeat_ns, 0, -1};
			v = mlip_peer_check(&seen, st.reserved, &watch, NULL);
		}
	}
	a = age_ns(st.heartbeat_ns);
	alive = v == MLIP_PEER_ALIVE;
	fa = age_ns(fd.heartbeat_ns);
	falive = mlip_peer_feeder(&fd) == MLIP_PEER_ALIVE;
	mlip_ring_machine(s->ring, &m);
	if (m.n_axes < 1 || m.n_axes > MLIP_MAX_AXES) {
		m.n_axes = 0; /* no machine published: no axes to show */
	}

	if (json) {
		status_json(s, &st, &fd, &m, v, a, falive);
		return alive && st.state != MLIP_STATE_FAULT ? EXIT_DONE : EXIT_FAIL;
	}

	if (alive) {
		printf("controller  %s: %s, alive (heartbeat ", s->name,
		       mlip_ctl_state_name(st.state));
	} else {
		printf("controller  %s: %s, last state %s (heartbeat ", s->name,
		       v == MLIP_PEER_LATE ? "NOT RESPONDING" : "NOT RUNNING",
		       mlip_ctl_state_name(st.state));
	}
	print_age(stdout, a);
	printf(", period %llu)\n", (unsigned long long)st.heartbeat);
	/* at rest (idle, starved): the last block completed, where a program
	 * continues from (mlip-feed --start-seq exec_seq + 1) */
	int rest = st.state == MLIP_STATE_IDLE || st.state == MLIP_STATE_STARVED;
	printf("%s block %llu, line %u\n", rest ? "completed  " : "executing  ",
	       (unsigned long long)st.exec_seq, (unsigned)st.exec_line);
	if (jog_text(&st, &m, fname, sizeof(fname)) != NULL) {
		printf("jog         %s\n", fname);
	}
	printf("why         %s", mlip_state_why_name(st.reason));
	if (st.reason == MLIP_WHY_DRIVE || st.reason == MLIP_WHY_SPINDLE_FAULT) {
		mlip_cli_drive_fault_text(st.reason_field, (int64_t)st.reason_value, fname,
		                          sizeof(fname));
		printf(": node %u, %s: %s, block %llu (line %u)", (unsigned)st.reason_node,
		       mlip_drive_fault_name((mlip_drive_fault)st.reason_field), fname,
		       (unsigned long long)st.reason_seq, (unsigned)st.reason_line);
	} else if (st.reason == MLIP_WHY_JOG) {
		printf(": %g mm/s (deg/s)", fabs(st.reason_value)); /* the axes: "jog" above */
	} else if (st.reason_field != MLIP_FIELD_NONE) {
		mlip_cli_field_name(&m, st.reason_field, fname, sizeof(fname));
		printf(": record %llu (line %u), %s = %.17g", (unsigned long long)st.reason_seq,
		       (unsigned)st.reason_line, fname, st.reason_value);
	} else if (st.reason_seq != 0) {
		printf(", block %llu (line %u)", (unsigned long long)st.reason_seq,
		       (unsigned)st.reason_line);
	}
	if (st.reason == MLIP_WHY_STALL) {
		printf(", %.0f periods missed", st.reason_value);
	}
	if (st.reason == MLIP_WHY_SPINDLE || st.reason == MLIP_WHY_TOOL ||
	    st.reason == MLIP_WHY_COOLANT) {
		/* the tool's comment is in the feeder's table: mlip-feed shows it */
		mlip_cli_io_message(st.reason, st.reason_value, NULL, fname, sizeof(fname));
		printf(": %s", fname);
	} else if (st.reason == MLIP_WHY_ESTOP || st.reason == MLIP_WHY_LIMIT) {
		printf(": %s, node %u",
		       mlip_io_function_name(st.reason_field, &m, fname, sizeof(fname)),
		       (unsigned)st.reason_node);
	} else if (st.reason == MLIP_WHY_IO_LOST) {
		mlip_cli_drive_fault_text(st.reason_field, (int64_t)st.reason_value, fname,
		                          sizeof(fname));
		printf(": node %u, %s: %s", (unsigned)st.reason_node,
		       mlip_drive_fault_name((mlip_drive_fault)st.reason_field), fname);
	}
	printf("\n");
	if (st.state == MLIP_STATE_PAUSED ||
	    (st.state == MLIP_STATE_HELD && st.reason != MLIP_WHY_OVERRIDE_ZERO)) {
		printf("to continue mlip-ctl resume\n");
	} else if (st.state == MLIP_STATE_ESTOP ||
	           (st.state == MLIP_STATE_FAULT && st.reason == MLIP_WHY_LIMIT)) {
		printf("to continue release the input, then mlip-ctl reset\n");
	} else if (st.state == MLIP_STATE_FAULT) {
		printf("to continue restart mlip-rt (the fault stays until then)\n");
	}
	printf("homed      ");
	for (int k = 0; k < m.n_axes; k++) {
		printf(" %c %s", m.axis[k].letter, (st.homed >> k) & 1u ? "yes" : "no");
	}
	printf("\n");
	if (st.io_mapped != 0) {
		printf("inputs     ");
		for (uint32_t f = 0; f < MLIP_IN_COUNT; f++) {
			if (st.io_mapped & (1u << f)) {
				printf(" %s %s", mlip_io_function_name(f, &m, fname, sizeof(fname)),
				       !(st.io_known & (1u << f))   ? "unread"
				       : (st.io_inputs & (1u << f)) ? "ON"
				                                    : "off");
				printf(f + 1 < MLIP_IN_COUNT && (st.io_mapped >> (f + 1)) ? ","
				                                                          : "");
			}
		}
		printf("\n");
	}
	mlip_iostatus_text(stdout, &m, &st, s->ring); /* outputs, coolant, the last probe */
	printf("position   ");
	for (int k = 0; k < m.n_axes; k++) {
		printf(" %c %.4f", m.axis[k].letter, st.pos[k]);
	}
	if (alive) {
		printf("  (%.3f mm/s)\n", st.speed_mm_s);
	} else {
		printf("  (the last setpoint; speed unknown)\n");
	}
	if (st.actual_mask != 0) {
		printf("actual     ");
		for (int k = 0; k < m.n_axes; k++) {
			if (st.actual_mask & (1u << k)) {
				printf(" %c %.4f", m.axis[k].letter, st.pos_actual[k]);
			}
		}
		printf("  (the drives' position actual 0x6064)\nstart      ");
		for (int k = 0; k < m.n_axes; k++) {
			printf(" %c %.4f", m.axis[k].letter, m.axis[k].home);
		}
		printf("  (the drives' position at bring-up)\n");
	}
	if (st.drive_power != MLIP_POWER_NONE) {
		static const char *const how[MLIP_POWER_COUNT] = {
		    "",
		    "operation enabled: they hold or follow the setpoints",
		    "disable operation 0x0007, at rest",
		    "shutdown 0x0006",
		    "ready to switch on: no torque; enabled again for the next program",
		    "switch on 0x0007 for the next program",
		    "enable operation 0x000F"};
		printf("drives      %s (%s)", mlip_drive_power_name(st.drive_power),
		       st.drive_power < MLIP_POWER_COUNT && how[st.drive_power] != NULL
		           ? how[st.drive_power]
		           : "?");
		if (st.drive_power_periods > 0 &&
		    (st.drive_power == MLIP_POWER_OFF || st.drive_power == MLIP_POWER_ENABLED)) {
			printf(", last change in %u periods", (unsigned)st.drive_power_periods);
		}
		printf("\n");
	}
	if (st.state == MLIP_STATE_DWELLING && st.reason == MLIP_WHY_SPINDLE_WAIT) {
		printf("spindle     waiting for it at most %.3f s more (AT_SPEED_TIMEOUT)\n",
		       (double)st.dwell_left * m.period_s);
	} else if (st.state == MLIP_STATE_DWELLING) {
		printf("dwell       %.3f s left\n", (double)st.dwell_left * m.period_s);
	}
	printf("override    %u %%, optional stop %s\n", (unsigned)st.override_pct,
	       st.optional_stop ? "on" : "off");
	if (st.spindle_state != 0) {
		printf("spindle     %s: commanded %.0f rpm, actual %.0f rpm, override %u %% (node "
		       "%u)\n",
		       spindle_state_name(st.spindle_state), st.spindle_cmd_rpm,
		       st.spindle_actual_rpm, (unsigned)st.spindle_override,
		       (unsigned)st.spindle_node);
	}
	if (st.stops > 0) {
		printf(
		    "last stop   %.3f mm on the path in %u periods, request to rest (%u so far)\n",
		    (double)st.stop_nm * 1e-6, (unsigned)st.stop_periods, (unsigned)st.stops);
	}
	printf("periods     %llu overruns, %llu underruns\n", (unsigned long long)st.overruns,
	       (unsigned long long)st.underruns);
	printf("CAN         %llu frames sent, %llu tx errors, %llu bus errors\n",
	       (unsigned long long)st.frames_sent, (unsigned long long)st.can_tx_errors,
	       (unsigned long long)st.can_bus_errors);
	printf("ring        %llu blocks consumed, %u queued of %u\n",
	       (unsigned long long)st.blocks_consumed, (unsigned)mlip_ring_count(s->ring),
	       (unsigned)s->ring->capacity);
	if (fd.pid == 0) {
		printf("feeder      none\n");
	} else {
		printf("feeder      pid %d%s, %s (heartbeat ", (int)fd.pid,
		       fd.mdi ? " (MDI: mlip-ctl mdi)" : "", falive ? "alive" : "gone");
		print_age(stdout, fa);
		printf("), ");
		if (fd.total_blocks == 0) {
			printf("program size not known yet\n");
		} else {
			printf("%llu blocks, %s\n", (unsigned long long)fd.total_blocks,
			       fd.program_end ? "all queued" : "queueing");
		}
	}
	if (v == MLIP_PEER_LATE) {
		fprintf(stderr,
		        PROG ": controller on %s is not responding, but its process (pid %u) is "
		             "there: stopped or starved of CPU\n",
		        s->name, (unsigned)st.reserved);
	} else if (!alive) {
		fprintf(stderr, PROG ": controller on %s is not running: start mlip-rt\n", s->name);
	} else if (st.state == MLIP_STATE_FAULT) {
		fprintf(stderr,
		        PROG ": controller on %s is in fault (%s): the program did not "
		             "complete; restart mlip-rt to clear it\n",
		        s->name, mlip_state_why_name(st.reason));
	}
	return alive && st.state != MLIP_STATE_FAULT ? EXIT_DONE : EXIT_FAIL;
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
/* ---- jog (issue 18) --------------------------------------------------------- */

static volatile sig_atomic_t jog_signal;

static void on_jog_signal(int sig)
{
	jog_signal = sig;
}

/* Post a command and wait for its result (1 s each): 0 with *result, or -1. */
static int post_wait(struct mlip_shm *s, mlip_ring_cmd_op op, int32_t arg, int32_t *result)
{
	uint32_t seq = 0;
	uint64_t t0 = mlip_now_ns();
	mlip_status rc;
	while ((rc = mlip_ring_cmd_post(s->ring, op, arg, &seq)) == MLIP_E_FULL &&
	       mlip_now_ns() - t0 < (uint64_t)WAIT_NS) {
		sleep_ns(POLL_NS);
	}
	if (rc != MLIP_OK) {
		return -1;
	}
	t0 = mlip_now_ns();
	while ((rc = mlip_ring_cmd_result(s->ring, seq, result)) != MLIP_OK) {
		if (rc == MLIP_E_RANGE || mlip_now_ns() - t0 >= (uint64_t)WAIT_NS) {
			return -1;
		}
		sleep_ns(POLL_NS);
	}
	return 0;
}

/* jog X+|X- SPEED [SECONDS]: a continuous jog at SPEED mm/min (deg/min),
 * renewed every 100 ms (the controller stops one not renewed within
 * MLIP_JOG_DEADMAN_S) until SECONDS pass, a signal comes (SIGINT, SIGTERM,
 * SIGHUP: a dropped ssh session), or the axis reaches its soft limit; then
 * released: a stop on the path at the acceleration limit. */
/* One axis of a jog: "X+", "z-", "X+1.5" (a distance: incremental). */
struct jog_axis {
	int axis, neg;
	double dist; /* 0: continuous */
};

static int jog_axis_word(const struct mlip_machine *m, const char *w, struct jog_axis *j)
{
	size_t n = strlen(w);
	j->axis = -1;
	for (int k = 0; k < m->n_axes && n >= 2; k++) {
		if (w[0] == m->axis[k].letter || w[0] == m->axis[k].letter + ('a' - 'A')) {
			j->axis = k;
		}
	}
	if (j->axis < 0 || (w[1] != '+' && w[1] != '-')) {
		return -1;
	}
	j->neg = w[1] == '-';
	j->dist = 0.0;
	if (n > 2 && (mlip_cli_number(w + 2, &j->dist) != 0 || !(j->dist > 0.0) || w[2] == '+' ||
	              w[2] == '-')) {
		return -1;
	}
	return 0;
}

/* jog AXIS+|AXIS-[DIST]... [--distance D] SPEED [SECONDS]: one axis or
 * several along one line, continuous (until SECONDS, a signal, or the soft
 * limit) or incremental (each a distance), renewed every 100 ms (the
 * controller's dead-man stops it 250 ms after the last renewal). */
static int cmd_jog(struct mlip_shm *s, int argc, char **argv)
{
	struct mlip_machine m;
	struct mlip_ring_status st;
	struct jog_axis ax[MLIP_MAX_AXES];
	double v = 0.0, dur = -1.0, dist = 0.0;
	const char *speed = NULL, *secs = NULL;
	char words[128] = "";
	int n = 0, with = 0;
	int32_t result;

	mlip_ring_machine(s->ring, &m);
	for (int i = 0; i < argc; i++) {
		const char *w = argv[i];
		if (strcmp(w, "--distance") == 0 || strncmp(w, "--distance=", 11) == 0) {
			const char *d = w[10] == '=' ? w + 11 : i + 1 < argc ? argv[++i] : "";
			if (mlip_cli_number(d, &dist) != 0 || !(dist > 0.0)) {
				fprintf(stderr,
				        PROG
				        ": jog: --distance must be a positive number, got '%s'\n",
				        d);
				return EXIT_USAGE;
			}
		} else if (speed == NULL && n < MLIP_MAX_AXES &&
		           jog_axis_word(&m, w, &ax[n]) == 0) {
			for (int k = 0; k < n; k++) {
				if (ax[k].axis == ax[n].axis) {
					fprintf(stderr, PROG ": jog: axis %c given twice\n", w[0]);
					return EXIT_USAGE;
				}
			}
			snprintf(words + strlen(words), sizeof(words) - strlen(words), "%s%s",
			         n ? " " : "", w);
			n++;
		} else if (n > 0 && speed == NULL) {
			speed = w;
		} else if (n > 0 && secs == NULL) {
			secs = w;
		} else {
			fprintf(stderr,
			        PROG
			        ": jog: '%s' is not an axis of this machine and a direction, with "
			        "a distance or not (e.g. X+, Z-, X+1.5)\n",
			        w);
			return EXIT_USAGE;
		}
	}
	if (n == 0) {
		fprintf(stderr, PROG ": jog: expected AXIS+|AXIS-[DIST]... [--distance D] SPEED "
		                     "[SECONDS]\n");
		return EXIT_USAGE;
	}
	for (int k = 0; k < n; k++) {
		ax[k].dist = ax[k].dist > 0.0 ? ax[k].dist : dist;
		with += ax[k].dist > 0.0;
		if (ax[k].dist > 0.0 && !(ax[k].dist * 1e3 + 0.5 <= (double)MLIP_JOG_DIST_MAX &&
		                          ax[k].dist * 1e3 >= 0.5)) {
			fprintf(stderr, PROG ": jog: a distance is 0.001 .. %.6g (mm or deg)\n",
			        MLIP_JOG_DIST_MAX * 1e-3);
			return EXIT_USAGE;
		}
	}
	if (with != 0 && with != n) {
		fprintf(stderr,
		        PROG ": jog: every axis a distance (incremental) or none (continuous)\n");
		return EXIT_USAGE;
	}
	if (speed == NULL || mlip_cli_number(speed, &v) != 0 || !(v >= 1.0) ||
	    v > (double)MLIP_JOG_SPEED_MAX) {
		fprintf(stderr,
		        PROG ": jog: the speed must be a number of mm/min (deg/min) in 1..%u, "
		             "got '%s'\n",
		        MLIP_JOG_SPEED_MAX, speed != NULL ? speed : "");
		return EXIT_USAGE;
	}
	if (secs != NULL && (mlip_cli_number(secs, &dur) != 0 || !(dur > 0.0) || dur > 86400.0)) {
		fprintf(stderr, PROG ": jog: SECONDS must be in (0, 86400], got '%s'\n", secs);
		return EXIT_USAGE;
	}
	const char *dir = words;
	int axis = ax[0].axis, neg = ax[0].neg;
	int32_t arg = MLIP_JOG_ARG(axis, neg, (uint32_t)(v + 0.5)),
	        stop = MLIP_JOG_ARG(axis, neg, 0);
	mlip_cli_on_stop_signals(on_jog_signal);
	/* the other axes (and the distances) first, then the jog itself */
	int bad = 0;
	for (int k = n - 1; k >= 0 && !bad; k--) {
		if (k == 0 && ax[0].dist == 0.0) {
			break;
		}
		int32_t a =
		    MLIP_JOG_AXIS_ARG(ax[k].axis, ax[k].neg, (uint32_t)(ax[k].dist * 1e3 + 0.5));
		bad = post_wait(s, MLIP_CMD_JOG_AXIS, a, &result) != 0 ? -1 : result != MLIP_OK;
	}
	if (bad < 0 || (!bad && post_wait(s, MLIP_CMD_JOG, arg, &result) != 0)) {
		fprintf(stderr, PROG ": jog: no answer from the controller on %s within 1 s\n",
		        s->name);
		return EXIT_FAIL;
	}
	if (bad || result != MLIP_OK) {
		read_status(s->ring, &st);
		if (!bad && result == MLIP_E_RANGE) {
			/* the axis that leaves the travel */
			int k0 = 0;
			double t = st.pos[ax[0].axis];
			for (int k = 0; k < n; k++) {
				const struct mlip_axis *a = &m.axis[ax[k].axis];
				double p = st.pos[ax[k].axis];
				double tk = p + (ax[k].neg ? -ax[k].dist : ax[k].dist);
				if (ax[k].neg ? tk <= a->min_limit : tk >= a->max_limit) {
					k0 = k;
					t = tk;
					break;
				}
			}
			const struct mlip_axis *a = &m.axis[ax[k0].axis];
			fprintf(stderr,
			        PROG
			        ": jog %s: refused: %c is at %.4f%s, %s its soft limit %s %g (Grbl "
			        "error 15: jog target exceeds machine travel)\n",
			        dir, a->letter, st.pos[ax[k0].axis], with ? ", its target" : "",
			        with ? "beyond" : "at or beyond",
			        ax[k0].neg ? "MIN_LIMIT" : "MAX_LIMIT",
			        ax[k0].neg ? a->min_limit : a->max_limit);
			if (with) {
				fprintf(stderr,
				        PROG ": jog %s: the target %c %.4f; nothing moved\n", dir,
				        a->letter, t);
			}
		} else if (!bad && result == MLIP_E_SYNTAX) {
			fprintf(stderr,
			        PROG
			        ": jog %s: refused: the controller got other axes for this jog "
			        "(another client jogging at the same moment?): try again\n",
			        dir);
		} else {
			fprintf(stderr,
			        PROG ": jog %s: refused: the controller is %s (%s), not idle\n",
			        dir, mlip_ctl_state_name(st.state), mlip_state_why_name(st.reason));
		}
		return EXIT_FAIL;
	}
	printf("jog %s at %.0f mm/min: started (renewed every 100 ms; Ctrl-C stops it)\n", dir, v);
	fflush(stdout);
	uint64_t t0 = mlip_now_ns();
	int rc = EXIT_DONE;
	for (;;) {
		sleep_ns(100000000L);
		if (jog_signal || (dur > 0.0 && (double)(mlip_now_ns() - t0) * 1e-9 >= dur)) {
			break;
		}
		if (read_status(s->ring, &st) != 0 || st.state != MLIP_STATE_JOGGING) {
			break; /* it ended (its target, a soft limit, a stop, an E-stop, a fault) */
		}
		if (post_wait(s, MLIP_CMD_JOG, arg, &result) != 0 || result != MLIP_OK) {
			break;
		}
	}
	post_wait(s, MLIP_CMD_JOG, stop, &result); /* released: a stop at the acceleration limit */
	uint64_t t1 = mlip_now_ns();
	while (read_status(s->ring, &st) == 0 && st.state == MLIP_STATE_JOGGING &&
	       mlip_now_ns() - t1 < 10ull * (uint64_t)WAIT_NS) {
		sleep_ns(5 * POLL_NS);
	}
	if (st.state == MLIP_STATE_IDLE) {
		printf("jog %s: at rest at", dir);
		for (int k = 0; k < n; k++) {
			printf(" %c %.4f", m.axis[ax[k].axis].letter, st.pos[ax[k].axis]);
		}
		printf(" (%s%s", mlip_state_why_name(st.reason), jog_signal ? ", on " : "");
		if (jog_signal) {
			printf("%s", mlip_cli_signal_name(jog_signal));
		}
		if (st.reason == MLIP_WHY_JOG_RELEASED || st.reason == MLIP_WHY_JOG_DEADMAN) {
			printf("; %.3f mm from the release to rest", (double)st.stop_nm * 1e-6);
		}
		printf(")\n");
	} else {
		fprintf(stderr, PROG ": jog %s: ended %s (%s)\n", dir,
		        mlip_ctl_state_name(st.state), mlip_state_why_name(st.reason));
		rc = EXIT_FAIL;
	}
	return rc;
}

/* home [AXES]: the axes (letters, e.g. XZ; none: every axis with a
 * HOME_METHOD) homed by their drives' homing mode, in HOME_SEQUENCE order;
 * waits for the end and says how it went. */
static int cmd_home(struct mlip_shm *s, const char *axes)
{
	struct mlip_machine m;
	struct mlip_ring_status st;
	uint32_t mask = 0;
	int32_t result;
	char fname[32];

	mlip_ring_machine(s->ring, &m);
	for (const char *p = axes; p != NULL && *p; p++) {
		int k = -1;
		for (int i = 0; i < m.n_axes; i++) {
			if (m.axis[i].letter == *p || m.axis[i].letter + ('a' - 'A') == *p) {
				k = i;
			}
		}
		if (k < 0) {
			fprintf(stderr, PROG ": home: '%c' is not an axis of this machine\n", *p);
			return EXIT_USAGE;
		}
		mask |= 1u << k;
	}
	if (post_wait(s, MLIP_CMD_HOME, (int32_t)mask, &result) != 0) {
		fprintf(stderr, PROG ": home: no answer from the controller on %s within 1 s\n",
		        s->name);
		return EXIT_FAIL;
	}
	read_status(s->ring, &st);
	if (result != MLIP_OK) {
		fprintf(stderr, PROG ": home: refused: %s\n",
		        result == MLIP_E_RANGE ? "an axis without HOME_METHOD in the machine's "
		                                 "configuration (or no CiA 402 drives)"
		                               : "the controller is not idle");
		return EXIT_FAIL;
	}
	/* the command's result comes before the status of its period: wait for
	 * a later one, then for the end (a controller late for a while, as in an
	 * emulated machine, is waited for; one gone for 5 s is not) */
	uint64_t t0 = mlip_now_ns(), hb0 = st.heartbeat, quiet = 0;
	while (read_status(s->ring, &st) == 0 && st.heartbeat <= hb0 + 1 &&
	       mlip_now_ns() - t0 < 2ull * (uint64_t)WAIT_NS) {
		sleep_ns(5 * POLL_NS);
	}
	while (read_status(s->ring, &st) == 0 && st.state == MLIP_STATE_HOMING) {
		if (mlip_shm_controller_alive(s->ring)) {
			quiet = 0;
		} else if (quiet == 0) {
			quiet = mlip_now_ns();
		} else if (mlip_now_ns() - quiet > 5ull * (uint64_t)WAIT_NS) {
			fprintf(stderr,
			        PROG ": home: the controller stopped answering while homing\n");
			return EXIT_FAIL;
		}
		sleep_ns(20 * POLL_NS);
	}
	double secs = (double)(mlip_now_ns() - t0) * 1e-9;
	if (st.state == MLIP_STATE_IDLE && st.reason == MLIP_WHY_HOMED) {
		printf("homed in %.2f s:", secs);
		for (int k = 0; k < m.n_axes; k++) {
			if (st.homed & (1u << k)) {
				printf(" %c %.4f", m.axis[k].letter, st.pos[k]);
			}
		}
		printf("\n");
		return EXIT_DONE;
	}
	if (st.reason == MLIP_WHY_HOMING_SDO) {
		fprintf(stderr,
		        PROG
		        ": home: node %u refused 0x%04X:%02X: %s (0x%08X): every axis stopped; "
		        "mlip-ctl reset, then check HOME_* of that axis\n",
		        (unsigned)st.reason_node, st.reason_field >> 8, st.reason_field & 0xFFu,
		        mlip_sdo_abort_text((uint32_t)st.reason_value), (uint32_t)st.reason_value);
	} else if (st.reason == MLIP_WHY_HOMING_ERROR || st.reason == MLIP_WHY_HOMING_TIMEOUT) {
		fprintf(stderr,
		        PROG
		        ": home: node %u, method %u: %s (statusword 0x%04X) after %.2f s: every "
		        "axis stopped; mlip-ctl reset\n",
		        (unsigned)st.reason_node, st.reason_field,
		        st.reason == MLIP_WHY_HOMING_ERROR ? "homing error (statusword bit 13)"
		                                           : "not attained within HOME_TIMEOUT",
		        (unsigned)st.reason_value, secs);
	} else {
		fprintf(stderr, PROG ": home: ended %s (%s)%s\n", mlip_ctl_state_name(st.state),
		        mlip_state_why_name(st.reason),
		        st.reason == MLIP_WHY_ESTOP
		            ? mlip_io_function_name(st.reason_field, &m, fname, sizeof(fname))
		            : "");
	}
	return EXIT_FAIL;
}

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

/* ---- mdi ---------------------------------------------------------------- */

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

static int cmd_mdi(const char *shm, int argc, char **argv)
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
