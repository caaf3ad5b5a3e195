/*
 * ctlstatus.c - mlip-ctl status (ctltool.h): the controller's and the
 * feeder's seqlocked areas, as text or one JSON object (--json).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "cli.h"
#include "ctltool.h"
#include "iostatus.h"
#include "json.h"
#include "mlip/ipc/ring.h"
#include "mlip/machine/config.h"
#include "rt.h"

/* status.spindle_state (mlip_spindle_phase + 1) */
static const char *spindle_state_name(uint32_t v)
{
	static const char *const names[] = {"none",     "stopped", "to speed",
	                                    "at speed", "braking", "fault"};
	return v < sizeof(names) / sizeof(names[0]) ? names[v] : "?";
}

/* Age in ns of a CLOCK_MONOTONIC stamp; -1 when never stamped. */
static int64_t age_ns(uint64_t stamp_ns)
{
	return mlip_peer_age_ns(stamp_ns, mlip_now_ns());
}

/* Seqlock reads fail only while a writer is mid-update for 1000 tries in a
 * row (or died there): retry for 10 ms before giving up. */
int read_status(const struct mlip_ring *r, struct mlip_ring_status *st)
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

/* Feed override 0 holds the path (held, or at rest: the next program
 * starts held); a higher override ends it, a resume does not. */
static int override_holds(const struct mlip_ring_status *st)
{
	int rest = st->state == MLIP_STATE_IDLE || st->state == MLIP_STATE_STARVED;
	return mlip_state_held_by(st->held_by) == MLIP_WHY_OVERRIDE_ZERO &&
	       (rest || (st->state == MLIP_STATE_HELD && st->reason == MLIP_WHY_OVERRIDE_ZERO));
}

/* A hold latched at rest (Grbl 1.1's Hold:0 from Idle): the next program
 * waits for a resume, which moves nothing by itself; or override 0 at
 * rest: it waits for a higher override. "" when none. */
static const char *latched_text(const struct mlip_ring_status *st, char *buf, size_t len)
{
	uint32_t why = mlip_state_held_by(st->held_by);
	const char *go = st->state == MLIP_STATE_IDLE ? "start" : "go on";
	if (st->state != MLIP_STATE_HELD && override_holds(st)) {
		snprintf(buf, len, " (feed override 0 %%: raise the override to %s)", go);
		return buf;
	}
	if (!mlip_state_hold_latched(st->state, st->held_by)) {
		return "";
	}
	if (why == MLIP_WHY_HOLD) {
		snprintf(buf, len, " (hold latched: resume to %s)", go);
	} else if (why == MLIP_WHY_BUS_TX || why == MLIP_WHY_BUS_ERROR) {
		snprintf(buf, len, " (held latched: %s; resume to %s once the bus is clean)",
		         mlip_state_why_name(why), go);
	} else {
		snprintf(buf, len, " (held latched: %s; resume to %s)", mlip_state_why_name(why),
		         go);
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
	/* the hold in force (null: none); latched: at rest, the next program
	 * starts held until a resume */
	if (mlip_state_held_by(st->held_by) != 0) {
		mlip_json_string(&j, "held_by", mlip_state_why_name(st->held_by));
	} else {
		mlip_json_null(&j, "held_by");
	}
	mlip_json_bool(&j, "hold_latched", mlip_state_hold_latched(st->state, st->held_by));
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

int cmd_status(struct mlip_shm *s, int json)
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

	char latched[120];
	if (alive) {
		printf("controller  %s: %s%s, alive (heartbeat ", s->name,
		       mlip_ctl_state_name(st.state), latched_text(&st, latched, sizeof(latched)));
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
	} else if (alive && override_holds(&st)) {
		printf("to continue raise the feed override (mlip-ctl override PCT, 1..200); it "
		       "is 0 %%: resume does not end it\n");
	} else if (alive && mlip_state_hold_latched(st.state, st.held_by)) {
		printf("to continue mlip-ctl resume (or cycle start) releases the hold, moving "
		       "nothing; a program sent meanwhile waits held; stop clears it too\n");
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
