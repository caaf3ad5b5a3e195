/*
 * mlip-rt - the controller: G-code blocks come in through a shared-memory
 * ring (mlip-feed), axis setpoints go out as CAN frames, every period, from
 * one SCHED_FIFO thread. Start-up does everything that may fail or block:
 * config, bus-load budget, CAN interface, shared memory, memory locking.
 */
#include <errno.h>
#include <getopt.h>
#include <grp.h>
#include <pthread.h>
#include <time.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "confload.h"
#include "mlip/can/canenc.h"
#include "mlip/motion/smooth.h"
#include "rt.h"
#include "rtparts.h"
#include "trace.h"

#define PROG "mlip-rt"

static struct mlip_planner planner; /* static: locked and prefaulted with the rest */
static struct mlip_period per;
static struct mlip_drives drives; /* --drives: the CiA 402 master (rt/drives.c) */
static struct mlip_canbus bus;    /* the one socket */
static struct mlip_can_port port; /* and the bus as a port */

/* A start-up that fails after the bring-up: the drives disabled by SDO and
 * released (they stop watching our heartbeat); ds NULL: no drives. */
static void drives_down(struct mlip_drives *ds)
{
	if (ds != NULL) {
		mlip_drives_disable(ds);
		mlip_drives_release(ds);
	}
}

static volatile sig_atomic_t got_exit;

static void on_signal(int sig)
{
	got_exit = sig;       /* SIGINT, SIGTERM, SIGHUP or SIGQUIT */
	per.exit_request = 1; /* a controlled stop on the path, then exit 0 */
}

/* Outside the loop (an ordinary thread, every 50 ms): tell the operator what
 * the loop did, from the status it publishes (state changes with the line,
 * underruns, frames the CAN queue refused, error frames), and after a bus-off
 * ask the driver to restart the controller (libsocketcan can_do_restart; with
 * restart-ms set the kernel does it by itself, and vcan has no controller to
 * restart). The loop meanwhile holds the machine; the operator resumes once
 * the bus is clean. */
struct monitor {
	const char *iface;
	struct mlip_bus_counts *can; /* NULL: --can none */
	struct mlip_ring *ring;
	const struct mlip_machine *m;
	uint32_t stall_periods;
	struct mlip_trace trace; /* --record */
	FILE *rec;
	struct mlip_drives *ds;     /* NULL: no drives brought up */
	const struct mlip_shm *shm; /* the segment: who holds its producer side */
	volatile int done;
};

static void drive_log(void *ctx, const char *line)
{
	(void)ctx;
	fprintf(stderr, PROG ": %s\n", line);
}

/* The controller's state says a drive faulted (reason DRIVE: node, event,
 * value): which axis, what the bus showed, where in the program. */
static void report_drive_fault(const struct monitor *mo, const struct mlip_ctl_event *e)
{
	const struct mlip_ctl_reason *r = &e->r;
	char what[160];
	char axis = '?';
	const struct mlip_drives *ds = mo->ds;
	const struct mlip_drive *d = NULL;
	char who[16] = "axis ?";
	for (int i = 0; ds != NULL && i < ds->n + ds->sp; i++) {
		if (ds->d[i].node == r->node) {
			d = &ds->d[i];
			axis = d->letter;
			snprintf(who, sizeof(who), i == ds->n ? "spindle" : "axis %c", axis);
		}
	}
	mlip_cli_drive_fault_text(r->field, (int64_t)r->value, what, sizeof(what));
	size_t n = strlen(what);
	/* what the master knows besides: the timeout, the window, the register */
	if (r->field == MLIP_DRIVE_HEARTBEAT_LOST && ds != NULL) {
		snprintf(what + n, sizeof(what) - n, " (timeout %u ms)",
		         (unsigned)ds->cfg.heartbeat_timeout_ms);
	} else if (r->field == MLIP_DRIVE_FOLLOWING_ERROR && d != NULL) {
		snprintf(what + n, sizeof(what) - n, " (window 0x6065 %u)",
		         d->setup.following_window_counts);
	} else if (r->field == MLIP_DRIVE_EMCY && d != NULL) {
		snprintf(what + n, sizeof(what) - n, ", error register 0x%02X", d->obs.emcy.reg);
	}
	fprintf(stderr,
	        PROG ": %s fault: node %u (%s): %s: %s, period %llu, block %llu (line %u): "
	             "every axis stops on the path; state fault until mlip-rt restarts\n",
	        r->why == MLIP_WHY_SPINDLE_FAULT ? "spindle" : "drive", (unsigned)r->node, who,
	        mlip_drive_fault_name((mlip_drive_fault)r->field), what,
	        (unsigned long long)e->period, (unsigned long long)r->seq, (unsigned)r->line);
}

/* One line per event: a counter that starts rising again after a quiet
 * second (20 monitor ticks), or a state change. */
static int rising(uint64_t was, uint64_t is, unsigned *quiet)
{
	int start = is > was && *quiet >= 20;
	*quiet = is > was ? 0 : *quiet + 1;
	return start;
}

static void report(const struct mlip_ring_status *a, const struct mlip_ring_status *b)
{
	static unsigned quiet_tx = 20, quiet_err = 20, quiet_under = 20;
	unsigned long long seq = (unsigned long long)b->exec_seq;
	if (rising(a->can_tx_errors, b->can_tx_errors, &quiet_tx)) {
		fprintf(stderr,
		        PROG ": CAN: the tx queue refuses frames (%llu so far) in block %llu "
		             "(line %u): holding the machine on the path\n",
		        (unsigned long long)b->can_tx_errors, seq, b->exec_line);
	}
	if (rising(a->can_bus_errors, b->can_bus_errors, &quiet_err)) {
		fprintf(stderr,
		        PROG ": CAN: error frames (%llu so far) in block %llu (line %u): "
		             "holding the machine on the path\n",
		        (unsigned long long)b->can_bus_errors, seq, b->exec_line);
	}
	if (rising(a->underruns, b->underruns, &quiet_under)) {
		fprintf(stderr,
		        PROG ": underrun: the ring ran dry in block %llu (line %u); the "
		             "look-ahead runs to rest at the end of what came\n",
		        seq, b->exec_line);
	}
	if (b->stops > a->stops) {
		fprintf(stderr,
		        PROG ": stopped on the path: %.3f mm in %u periods from the request to "
		             "rest\n",
		        (double)b->stop_nm * 1e-6, (unsigned)b->stop_periods);
	}
	int la = mlip_state_hold_latched(a->state, a->held_by);
	if (mlip_state_hold_latched(b->state, b->held_by) && !la) {
		fprintf(stderr,
		        PROG
		        ": a hold at rest while %s (%s): latched, the next program starts held "
		        "until mlip-ctl resume (cycle start)\n",
		        mlip_ctl_state_name(b->state), mlip_state_why_name(b->held_by));
	} else if (la && !mlip_state_hold_latched(b->state, b->held_by) && b->state == a->state) {
		/* (an override of 0 may still hold: mlip-ctl status says it) */
		fprintf(stderr, PROG ": the hold latched at rest ended (resume, stop or E-stop)\n");
	}
}

/* One line per event of the loop (its log queue), with the reason. */
static void log_event(const struct monitor *mo, const struct mlip_ctl_event *e)
{
	unsigned long long seq = (unsigned long long)e->exec_seq;
	unsigned line = e->exec_line;
	const struct mlip_ctl_reason *r = &e->r;
	char fld[32];
	if (e->kind == MLIP_EV_POWER) {
		char text[256];
		if (mo->ds != NULL) {
			mlip_drives_power_text(mo->ds, e, text, sizeof(text));
			fprintf(stderr, PROG ": %s\n", text);
		}
		return;
	}
	if (e->kind == MLIP_EV_REFUSED) {
		fprintf(stderr,
		        PROG ": refused records from block %llu (line %u): they do not continue "
		             "the program (block %.0f expected); dropped\n",
		        (unsigned long long)r->seq, r->line, r->value);
		return;
	}
	switch (e->state) {
	case MLIP_STATE_STARVED: {
		/* a feeder that still holds the ring (mlip-feed behind, mlip-grbl
		 * between a sender's lines) continues the program or ends it: a
		 * new mlip-feed could not take the ring; only once none holds it
		 * is --start-seq the way on */
		int32_t holder = mo->shm != NULL ? mlip_shm_feeder_holder(mo->shm) : 0;
		char name[32];
		if (holder > 0) {
			mlip_rt_process_name(holder, name, sizeof(name));
			fprintf(stderr,
			        PROG ": underrun: no block came after block %llu (line %u) yet; at "
			             "rest at its end, the program open: its feeder (%s, pid %d) "
			             "continues it or ends it\n",
			        seq, line, name, (int)holder);
			return;
		}
		fprintf(stderr,
		        PROG
		        ": underrun: no block came after block %llu (line %u); at rest at its end; "
		        "to continue: mlip-feed --start-seq %llu\n",
		        seq, line, seq + 1);
		return;
	}
	case MLIP_STATE_HELD:
		if (r->why == MLIP_WHY_STALL) {
			fprintf(
			    stderr,
			    PROG
			    ": stall: the loop missed %.0f periods (more than %u) in block %llu "
			    "(line %u): held at rest at the last setpoint sent, no jump; to "
			    "continue: mlip-ctl resume\n",
			    r->value, mo->stall_periods, seq, line);
		} else if (r->why == MLIP_WHY_BUS_TX || r->why == MLIP_WHY_BUS_ERROR) {
			struct mlip_ring_status st;
			if (mlip_ring_status_read(mo->ring, &st) != MLIP_OK) {
				memset(&st, 0, sizeof(st));
			}
			fprintf(stderr,
			        PROG
			        ": held: at rest in block %llu (line %u); %llu CAN frames refused, "
			        "%llu error frames so far; mlip-ctl resume once the bus is clean\n",
			        seq, line, (unsigned long long)st.can_tx_errors,
			        (unsigned long long)st.can_bus_errors);
		} else {
			fprintf(stderr,
			        PROG
			        ": held (%s): at rest in block %llu (line %u); mlip-ctl resume "
			        "continues\n",
			        mlip_state_why_name(r->why), seq, line);
		}
		return;
	case MLIP_STATE_ESTOP:
		if (r->why == MLIP_WHY_IO_LOST) {
			char what[160];
			mlip_cli_drive_fault_text(r->field, (int64_t)r->value, what, sizeof(what));
			fprintf(
			    stderr,
			    PROG ": E-stop: the I/O module (node %u) is lost: %s: %s, period %llu, "
			         "block %llu (line %u): quick stop to every drive, the program "
			         "dropped; once it is heard again mlip configures it anew, then "
			         "mlip-ctl reset\n",
			    (unsigned)r->node, mlip_drive_fault_name((mlip_drive_fault)r->field),
			    what, (unsigned long long)e->period, seq, line);
		} else {
			fprintf(stderr,
			        PROG
			        ": E-stop: input %s (node %u) at period %llu, block %llu (line "
			        "%u): quick stop to every drive, the program dropped; release it, "
			        "then mlip-ctl reset\n",
			        mlip_io_function_name(r->field, mo->m, fld, sizeof(fld)),
			        (unsigned)r->node, (unsigned long long)e->period, seq, line);
		}
		return;
	case MLIP_STATE_FAULT:
		if (r->why == MLIP_WHY_LIMIT) {
			fprintf(stderr,
			        PROG
			        ": limit switch: %s (node %u) while moving, period %llu, block "
			        "%llu (line %u): quick stop to every drive; move off the switch, "
			        "then mlip-ctl reset\n",
			        mlip_io_function_name(r->field, mo->m, fld, sizeof(fld)),
			        (unsigned)r->node, (unsigned long long)e->period, seq, line);
		} else if (r->why == MLIP_WHY_DRIVE || r->why == MLIP_WHY_SPINDLE_FAULT) {
			report_drive_fault(mo, e);
		} else if (r->why == MLIP_WHY_BAD_RECORD) {
			/* moving: what was taken runs to rest, up to the record
			 * before the bad one; not moving (a dwell, a pause, the
			 * pre-read): nothing pre-read starts, the machine stays at
			 * the end of the block it rests after (e->exec_seq) */
			int moving = e->from == MLIP_STATE_RUNNING || e->from == MLIP_STATE_HELD;
			uint64_t at = moving ? (r->seq ? r->seq - 1 : 0) : e->exec_seq;
			char where[64];
			if (at == 0) {
				snprintf(where, sizeof(where),
				         "where the program started (nothing of it moved)");
			} else {
				snprintf(where, sizeof(where), "at the end of block %llu",
				         (unsigned long long)at);
			}
			mlip_cli_field_name(mo->m, r->field, fld, sizeof(fld));
			fprintf(stderr,
			        PROG
			        ": fault: bad record %llu (line %u): %s = %.17g; nothing after it "
			        "is taken, the machine %s at rest %s; restart mlip-rt to clear\n",
			        (unsigned long long)r->seq, r->line, fld, r->value,
			        moving ? "stops" : "stays", where);
		} else {
			fprintf(stderr,
			        PROG ": fault: %s in block %llu (line %u); stopping on the path; "
			             "restart mlip-rt to clear\n",
			        mlip_state_why_name(r->why), seq, line);
		}
		return;
	case MLIP_STATE_DWELLING:
		if (r->why == MLIP_WHY_OUTPUT) {
			/* M7/M8/M9 (coolant io), M64/M65: switched at rest (issue 19) */
			if (r->field == MLIP_REC_COOLANT) {
				fprintf(stderr, PROG ": coolant %s at line %u (block %llu)\n",
				        r->value == 0   ? "off"
				        : r->value == 1 ? "mist"
				        : r->value == 2 ? "flood"
				                        : "mist+flood",
				        r->line, (unsigned long long)r->seq);
			} else {
				fprintf(stderr, PROG ": output %d %s at line %u (block %llu)\n",
				        (int)(r->value > 0 ? r->value : -r->value) - 1,
				        r->value > 0 ? "on (M64)" : "off (M65)", r->line,
				        (unsigned long long)r->seq);
			}
			return;
		}
		if (r->why == MLIP_WHY_OPTIONAL_PAUSE) {
			fprintf(stderr,
			        PROG ": M1 at line %u (block %llu) passed: optional stop off\n",
			        r->line, (unsigned long long)r->seq);
			return;
		}
		if (r->why == MLIP_WHY_SPINDLE_WAIT) {
			fprintf(stderr,
			        PROG
			        ": spindle to %g rpm%s at line %u (block %llu): at rest until it "
			        "is %s\n",
			        r->value < 0 ? -r->value : r->value,
			        r->value < 0 ? " counter-clockwise" : "", r->line,
			        (unsigned long long)r->seq,
			        r->value == 0 ? "at standstill" : "at speed");
			return;
		}
		fprintf(stderr, PROG ": dwell %.3f s at line %u (block %llu)\n", r->value, r->line,
		        (unsigned long long)r->seq);
		return;
	case MLIP_STATE_PAUSED:
		fprintf(stderr,
		        PROG ": paused (%s) at line %u (block %llu): mlip-ctl resume continues\n",
		        mlip_state_why_name(r->why), r->line, (unsigned long long)r->seq);
		return;
	case MLIP_STATE_IDLE:
		if (r->why == MLIP_WHY_PROBE_NO_TRIP || r->why == MLIP_WHY_PROBE_AT_START ||
		    r->why == MLIP_WHY_PROBE_OFF_AT_START || r->why == MLIP_WHY_PROBE_INPUT) {
			fprintf(stderr,
			        PROG
			        ": G38 at line %u (block %llu): %s: the program stopped at rest, "
			        "the rest of it dropped\n",
			        r->line, (unsigned long long)r->seq, mlip_state_why_name(r->why));
			return;
		}
		if (r->why == MLIP_WHY_STOP_EARLY) {
			fprintf(stderr,
			        PROG
			        ": stop before the start: the program from block %llu (line %u) "
			        "is dropped unmoved (its mlip-feed began before the stop)\n",
			        (unsigned long long)r->seq, r->line);
			return;
		}
		fprintf(stderr,
		        PROG ": %s -> idle (%s): at rest, block %llu (line %u) the last "
		             "completed\n",
		        mlip_ctl_state_name(e->from), mlip_state_why_name(r->why), seq, line);
		return;
	default:
		if (r->why == MLIP_WHY_PREREAD_DONE || r->why == MLIP_WHY_CONTINUE ||
		    r->why == MLIP_WHY_DWELL_DONE) {
			return; /* implied by the line before (start, underrun, dwell) */
		}
		if (r->why == MLIP_WHY_PROBED) {
			struct mlip_ring_status st;
			if (mlip_ring_status_read(mo->ring, &st) == MLIP_OK && st.probe_count > 0) {
				fprintf(stderr, PROG ": G38 at line %u (block %llu): %s at",
				        r->line, (unsigned long long)r->seq,
				        st.probe_tripped ? "tripped" : "not tripped, ended");
				for (int k = 0; k < mo->m->n_axes; k++) {
					fprintf(stderr, " %c %.4f", mo->m->axis[k].letter,
					        st.probe_pos[k]);
				}
				fprintf(stderr, " (#5070 = %u)\n", st.probe_tripped ? 1u : 0u);
				return;
			}
		}
		fprintf(stderr, PROG ": %s -> %s (%s), block %llu (line %u)\n",
		        mlip_ctl_state_name(e->from), mlip_ctl_state_name(e->state),
		        mlip_state_why_name(r->why), seq, line);
	}
}

/* The loop's queues: events to the log, setpoints to --record. */
static void drain(struct monitor *mo)
{
	struct mlip_ctl_event e;
	struct mlip_rt_sample smp;
	while (mlip_period_log_pop(&per, &e)) {
		log_event(mo, &e);
	}
	while (mlip_period_rec_pop(&per, &smp)) {
		mlip_trace_sample_at(&mo->trace, smp.period, smp.state, smp.pos, NULL);
	}
}

static void *monitor(void *arg)
{
	struct monitor *mo = arg;
	struct mlip_ring_status a, b;
	int have = 0, told = 0;
	for (unsigned tick = 1; !mo->done; tick++) {
		struct timespec ts = {0, 50000000L};
		nanosleep(&ts, NULL);
		drain(mo);
		if (mlip_ring_status_read(mo->ring, &b) == MLIP_OK) {
			if (have) {
				report(&a, &b);
			}
			a = b;
			have = 1;
		}
		if (mo->can == NULL || tick % 2 ||
		    !__atomic_load_n(&mo->can->bus_off, __ATOMIC_RELAXED)) {
			continue;
		}
		int rc = mlip_canbus_restart(mo->iface);
		if (rc == 0) {
			fprintf(stderr, PROG ": %s was bus-off: controller restarted\n", mo->iface);
			told = 0;
		} else if (!told) {
			fprintf(stderr,
			        PROG ": %s is bus-off and cannot be restarted here (%s): "
			             "check the wiring and termination, then ip link set %s "
			             "type can restart\n",
			        mo->iface, strerror(-rc), mo->iface);
			told = 1;
		}
	}
	drain(mo);
	if (have && mlip_ring_status_read(mo->ring, &b) == MLIP_OK) {
		report(&a, &b);
	}
	return NULL;
}

static void usage(FILE *f)
{
	fprintf(
	    f,
	    "usage: " PROG " --config FILE --can IFACE [options]\n"
	    "Run the controller: blocks from the shared-memory ring, setpoints to CAN.\n\n"
	    "  --config FILE       machine INI (axes, limits, [CAN] section)\n"
	    "  --can IFACE         SocketCAN interface, e.g. can0 or vcan0; 'none': no CAN\n"
	    "                      output (the ring, planner and commands only: for trials)\n"
	    "  --profile P         cia402 (default), packed or fd (overrides [CAN] PROFILE)\n"
	    "  --bitrate BPS       bus bit rate for the load budget (default [CAN] BITRATE;\n"
	    "                      vcan has none, so the configured one is used)\n"
	    "  --shm NAME          shared-memory segment (default %s); mode 0600: only\n"
	    "                      this user (and root) may feed and command\n"
	    "  --shm-group GROUP   mode 0660 and this group: its members may feed and\n"
	    "                      command too (they set MLIP_SHM_OWNER=<this user>)\n"
	    "  --priority N        SCHED_FIFO priority 1..99 (default 80; 0: SCHED_OTHER)\n"
	    "  --cpu N             pin the loop to CPU N (default: no pinning)\n"
	    "  --strategy S        mpct (default), bisector, stop or smooth (mpct on the path\n"
	    "                      mlip-feed smooths within the tolerance: mlip/motion/smooth.h)\n"
	    "  --capacity N        ring records, power of two (default %u)\n"
	    "  --stall-periods N   more missed periods than N is a stall: hold at rest at\n"
	    "                      the last setpoint until mlip-ctl resume (default %d)\n"
	    "  --record FILE       write the setpoints of the first program, as mlip-sim\n"
	    "                      --trace does (from the monitor thread, not the loop)\n"
	    "  --drives            bring up CiA 402 drives first (NMT, SDO set-up, power state\n"
	    "                      machine), start where they are, supervise and shut them\n"
	    "                      down (also [DRIVES] ENABLE = 1; docs/cia402.md)\n"
	    "  -h, --help\n",
	    MLIP_SHM_DEFAULT, MLIP_RING_CAPACITY, MLIP_STALL_PERIODS_DEFAULT);
}

/* ---- parse -------------------------------------------------------------------- */

struct options {
	const char *config, *iface, *shm_name, *profile, *strategy, *record;
	long shm_gid; /* --shm-group; -1: none */
	double bitrate;
	struct mlip_rt_opts ro;
	unsigned long capacity;
	double stall_periods;
	int want_drives;
};

/* 0, or the exit status of a usage error (or of --help: -1, exit 0). */
static int parse_options(int argc, char **argv, struct options *o)
{
	static const struct option opts[] = {{"shm-group", required_argument, 0, 'G'},
	                                     {"config", required_argument, 0, 'c'},
	                                     {"can", required_argument, 0, 'i'},
	                                     {"profile", required_argument, 0, 'P'},
	                                     {"bitrate", required_argument, 0, 'b'},
	                                     {"shm", required_argument, 0, 's'},
	                                     {"priority", required_argument, 0, 'p'},
	                                     {"cpu", required_argument, 0, 'C'},
	                                     {"strategy", required_argument, 0, 'S'},
	                                     {"capacity", required_argument, 0, 'n'},
	                                     {"help", no_argument, 0, 'h'},
	                                     {"stall-periods", required_argument, 0, 'T'},
	                                     {"record", required_argument, 0, 'R'},
	                                     {"drives", no_argument, 0, 'D'},
	                                     {0, 0, 0, 0}};
	double v;
	int c;
	memset(o, 0, sizeof(*o));
	o->shm_name = MLIP_SHM_DEFAULT;
	o->shm_gid = -1;
	o->strategy = "mpct";
	o->ro = (struct mlip_rt_opts){.priority = 80, .cpu = -1, .lock_memory = 1};
	o->capacity = MLIP_RING_CAPACITY;
	o->stall_periods = MLIP_STALL_PERIODS_DEFAULT;
	while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
		switch (c) {
		case 'G': {
			struct group *g = getgrnam(optarg);
			if (g == NULL) {
				fprintf(stderr, PROG ": --shm-group: no group '%s'\n", optarg);
				return 2;
			}
			o->shm_gid = (long)g->gr_gid;
			break;
		}
		case 'c':
			o->config = optarg;
			break;
		case 'i':
			o->iface = optarg;
			break;
		case 'P':
			o->profile = optarg;
			break;
		case 'b':
			if (mlip_cli_number(optarg, &o->bitrate) != 0 || o->bitrate < 10000 ||
			    o->bitrate > 1e6) {
				fprintf(stderr,
				        PROG ": --bitrate: '%s' is not 10000..1000000 bit/s\n",
				        optarg);
				return 2;
			}
			break;
		case 's':
			o->shm_name = optarg;
			break;
		case 'p':
			if (mlip_cli_number(optarg, &v) != 0 || v < 0 || v > 99) {
				fprintf(stderr, PROG ": --priority: '%s' is not 0..99\n", optarg);
				return 2;
			}
			o->ro.priority = (int)v;
			break;
		case 'C':
			if (mlip_cli_number(optarg, &v) != 0 || v < 0) {
				fprintf(stderr, PROG ": --cpu: '%s' is not a CPU number\n", optarg);
				return 2;
			}
			o->ro.cpu = (int)v;
			break;
		case 'S':
			o->strategy = optarg;
			break;
		case 'n':
			o->capacity = strtoul(optarg, NULL, 0);
			break;
		case 'T':
			if (mlip_cli_number(optarg, &o->stall_periods) != 0 ||
			    o->stall_periods < 1 || o->stall_periods > 100000 ||
			    o->stall_periods != (double)(uint32_t)o->stall_periods) {
				fprintf(stderr,
				        PROG
				        ": --stall-periods: '%s' is not a whole number 1..100000\n",
				        optarg);
				return 2;
			}
			break;
		case 'R':
			o->record = optarg;
			break;
		case 'D':
			o->want_drives = 1;
			break;
		case 'h':
			usage(stdout);
			return -1;
		default:
			usage(stderr);
			return 2;
		}
	}
	if (o->config == NULL || o->iface == NULL || optind != argc) {
		usage(stderr);
		return 2;
	}
	return 0;
}

/* ---- set up ------------------------------------------------------------------- */

/* Everything the run holds; static (locked and prefaulted with the rest). */
struct app {
	struct mlip_config cfg;
	mlip_can_profile prof;
	int strategy;
	int use_can, drives_up; /* the bus is open; the drives are brought up */
	struct mlip_rt_report rep;
	struct mlip_shm shm;
	struct monitor mon;
	struct mlip_ctl_opts co;
	struct mlip_smooth_store *smooth; /* the smooth strategy's planner data, NULL otherwise */
	struct mlip_rtplan plan;          /* JERK_PLAN = path: the planning thread */
};

/* The bus, opened once: with CiA 402 drives it receives what they send. */
static int open_bus(struct app *a, const char *iface)
{
	char info[256];
	uint32_t ids[MLIP_CANBUS_MAX_IDS];
	int n_ids = 0;
	if (mlip_canbus_check(iface, info, sizeof(info)) != 0) {
		fprintf(stderr, PROG ": %s\n", info);
		return -1;
	}
	fprintf(stderr, PROG ": %s\n", info);
	if (a->cfg.drives.enable) {
		n_ids = mlip_drives_rx_ids(&a->cfg.machine, a->cfg.inputs.node,
		                           a->cfg.io.spindle == MLIP_IO_CIA402 ? a->cfg.spindle.node
		                                                               : 0,
		                           a->cfg.inputs.probe_source == MLIP_PROBE_SRC_DRIVE,
		                           mlip_drives_di_axes(&a->cfg), ids, MLIP_CANBUS_MAX_IDS);
	}
	if (mlip_canbus_open(&bus, iface, a->prof == MLIP_CAN_FD, ids, n_ids, info, sizeof(info)) !=
	    0) {
		fprintf(stderr, PROG ": %s\n", info);
		return -1;
	}
	mlip_canbus_port(&bus, &port);
	a->use_can = 1;
	return 0;
}

/* Bring the drives up, before the first period: nothing moves on any error;
 * the machine then starts where they are (published as HOME, so mlip-feed
 * parses programs from there; the first setpoint is the position actual). */
static int bring_up(struct app *a, const char *shm_name)
{
	char info[256], why[320];
	double start[MLIP_MAX_AXES];
	static struct mlip_shm peek;
	/* never reset the drives of a controller that runs */
	if (mlip_shm_attach(&peek, shm_name, info, sizeof(info)) == 0) {
		int alive = mlip_shm_controller_alive(peek.ring);
		mlip_shm_close(&peek);
		if (alive) {
			fprintf(stderr,
			        PROG ": a live controller runs on %s: its drives are left alone\n",
			        shm_name);
			return -1;
		}
	}
	if (mlip_drives_init(&drives, &a->cfg, &port, drive_log, NULL, why, sizeof(why)) != 0 ||
	    mlip_drives_bringup(&drives, start, why, sizeof(why)) != 0) {
		fprintf(stderr, PROG ": drives not brought up: %s; nothing moves\n", why);
		if (drives.n > 0) {
			mlip_drives_release(&drives); /* they stop watching our heartbeat */
		}
		return -1;
	}
	a->drives_up = 1;
	fprintf(stderr, PROG ": start position");
	for (int k = 0; k < a->cfg.machine.n_axes; k++) {
		a->cfg.machine.axis[k].home = start[k];
		fprintf(stderr, " %c %.4f", a->cfg.machine.axis[k].letter, start[k]);
	}
	fprintf(stderr, " (position actual of the drives, published as HOME)\n");
	return 0;
}

/* Undo what set_up did, in reverse. */
static void tear_down(struct app *a)
{
	if (a->mon.rec != NULL) {
		fclose(a->mon.rec);
		a->mon.rec = NULL;
	}
	if (a->shm.ring != NULL) {
		mlip_shm_close(&a->shm);
	}
	if (a->drives_up) {
		drives_down(&drives);
	}
	if (a->use_can) {
		mlip_canbus_close(&bus);
	}
	free(a->smooth);
	a->smooth = NULL;
}

/* Config, bus budget, bus, real-time preparation, drives, segment, record
 * buffer, the period: 0, or the exit status. */
static int set_up(const struct options *o, struct app *a)
{
	char info[256];
	a->strategy = mlip_cli_strategy(o->strategy);
	if (a->strategy < 0) {
		fprintf(stderr,
		        PROG ": --strategy: '%s' is not one of mpct, bisector, stop, smooth\n",
		        o->strategy);
		return 2;
	}
	if (mlip_ring_bytes((uint32_t)o->capacity) == 0) {
		fprintf(stderr, PROG ": --capacity: %lu is not a power of two\n", o->capacity);
		return 2;
	}
	if (mlip_config_load(o->config, &a->cfg, stderr) != 0) {
		return 1;
	}
	if (a->cfg.jerk_plan == MLIP_JERK_PLAN_PATH && a->strategy != MLIP_STRATEGY_SMOOTH) {
		/* the planning thread (tools/rtplan.c) re-times smooth's path */
		fprintf(stderr, PROG ": %s:%u: JERK_PLAN = path needs --strategy smooth\n",
		        o->config, (unsigned)a->cfg.jerk_plan_line);
		return 2;
	}
	const char *warn = mlip_io_probe_warning(&a->cfg.inputs);
	if (warn != NULL) {
		fprintf(stderr, PROG ": %s: warning: %s\n", o->config, warn);
	}
	int rc = mlip_cli_can_override(&a->cfg, o->config, o->profile, o->bitrate, &a->prof, PROG,
	                               stderr);
	if (rc != 0) {
		return rc;
	}
	int use_can = strcmp(o->iface, "none") != 0;
	if (o->want_drives) {
		a->cfg.drives.enable = 1;
	}
	if (a->cfg.drives.enable && (!use_can || a->prof != MLIP_CAN_CIA402)) {
		fprintf(stderr,
		        PROG ": CiA 402 drives need a CAN interface and the cia402 profile\n");
		return 2;
	}
	if (a->cfg.io.spindle == MLIP_IO_CIA402 && !a->cfg.drives.enable) {
		/* a spindle that is not driven must never look like one that is */
		fprintf(stderr,
		        PROG ": [SPINDLE] TYPE = cia402 needs the CANopen master ([DRIVES] "
		             "ENABLE = 1 or --drives): the spindle drive is brought up by it\n");
		return 2;
	}
	if (a->cfg.inputs.probe_source == MLIP_PROBE_SRC_DRIVE && !a->cfg.drives.enable) {
		fprintf(stderr, PROG ": [PROBE] SOURCE = drive needs the CANopen master ([DRIVES] "
		                     "ENABLE = 1 or --drives): the drives' touch probe is set up "
		                     "and read by it\n");
		return 2;
	}
	if ((a->cfg.inputs.node != 0 || a->cfg.inputs.mapped != 0) && !a->cfg.drives.enable) {
		/* an E-stop that is not read must never look like one that is */
		fprintf(stderr, PROG ": [IO] needs the CANopen master ([DRIVES] ENABLE = 1 or "
		                     "--drives): the inputs are read by it\n");
		return 2;
	}
	if (use_can && mlip_rt_bus_budget(&a->cfg, a->prof) != 0) {
		return 1;
	}
	if (use_can && open_bus(a, o->iface) != 0) {
		return 1;
	}
	if (!use_can) {
		fprintf(stderr,
		        PROG ": no CAN output (--can none): setpoints are computed, not sent\n");
	}
	struct mlip_rt_opts ro = o->ro;
	ro.period_ns = (int64_t)(a->cfg.machine.period_s * 1e9 + 0.5);
	mlip_rt_prepare(&ro, &a->rep);
	if (a->rep.warnings[0]) {
		fprintf(stderr, "%s", a->rep.warnings);
	}
	if (a->cfg.drives.enable && bring_up(a, o->shm_name) != 0) {
		tear_down(a);
		return 1;
	}
	/* published with the machine: feeders then send the smoothed path */
	a->cfg.machine.smooth = a->strategy == MLIP_STRATEGY_SMOOTH;
	a->cfg.machine.path_plan = a->cfg.jerk_plan == MLIP_JERK_PLAN_PATH;
	a->cfg.machine.plan_lookahead =
	    a->cfg.machine.path_plan || a->cfg.machine.smooth ? a->cfg.lookahead : 0u;
	if (mlip_shm_create_group(&a->shm, o->shm_name, (uint32_t)o->capacity, &a->cfg.machine,
	                          o->shm_gid, info, sizeof(info)) != 0) {
		fprintf(stderr, PROG ": %s\n", info);
		tear_down(a);
		return 1;
	}
	{ /* the machine's I/O, for the feeders' checks ([SPINDLE], [TOOL], [COOLANT]) */
		struct mlip_ring_io rio;
		mlip_cli_io_to_ring(&a->cfg.io, &a->cfg.machine, &rio);
		mlip_ring_io_publish(a->shm.ring, &rio);
	}
	if (o->record != NULL) {
		/* 2^15 periods (32 s at 1 ms) of slack for the monitor thread,
		 * which drains it every 50 ms; 2 MB, locked with the rest */
		per.rec_cap = 1u << 15;
		per.rec = calloc(per.rec_cap, sizeof(*per.rec));
		a->mon.rec = fopen(o->record, "w");
		if (per.rec == NULL || a->mon.rec == NULL) {
			fprintf(stderr, PROG ": --record %s: %s\n", o->record, strerror(errno));
			tear_down(a);
			return 1;
		}
	}
	mlip_trace_open(&a->mon.trace, a->mon.rec, &a->cfg.machine, NULL);
	/* the smooth strategy's planner data: only smooth carries it (locked
	 * with the rest, prefaulted below) */
	if (a->strategy == MLIP_STRATEGY_SMOOTH &&
	    (a->smooth = calloc(1, sizeof(*a->smooth))) == NULL) {
		fprintf(stderr, PROG ": out of memory for the smooth strategy's look-ahead\n");
		tear_down(a);
		return 1;
	}
	a->co = (struct mlip_ctl_opts){
	    .strategy = (mlip_strategy)a->strategy,
	    .smooth = a->smooth,
	    .lookahead = a->cfg.lookahead,
	    .stall_periods = (uint32_t)o->stall_periods,
	    .can = &a->cfg.can,
	    .drives = a->cfg.drives.enable,
	    .io = &a->cfg.inputs,
	    .home = &a->cfg.home,
	    .spindle = a->cfg.io.spindle == MLIP_IO_CIA402 ? &a->cfg.spindle : NULL};
	/* each power step in the loop is given STATE_TIMEOUT_MS, in periods */
	a->co.drive_state_periods =
	    (uint32_t)(a->cfg.drives.state_timeout_ms * 1e-3 / a->cfg.machine.period_s + 0.999);
	struct mlip_period_hooks hooks;
	if (a->drives_up) {
		mlip_drives_hooks(&drives, &hooks);
	}
	if (mlip_period_init(&per, &planner, &a->cfg.machine, &a->co, a->shm.ring,
	                     a->use_can ? &port : NULL, a->drives_up ? &hooks : NULL) != 0) {
		fprintf(stderr,
		        PROG ": the [CAN] settings do not fit this machine (node ids, ids)\n");
		tear_down(a);
		return 1;
	}
	memset(&planner.seg, 0, sizeof(planner.seg)); /* prefault the look-ahead */
	if (a->smooth != NULL) {
		memset(a->smooth, 0, sizeof(*a->smooth));
	}
	per.exit_request = got_exit; /* init cleared it: keep a stop asked during start-up */
	fprintf(stderr, PROG ": ready on %s, segment %s, period %.3f ms, %s, priority %d%s\n",
	        o->iface, o->shm_name, a->cfg.machine.period_s * 1e3,
	        mlip_can_profile_name(a->prof), o->ro.priority,
	        a->rep.locked ? ", memory locked" : "");
	return 0;
}

/* ---- run ------------------------------------------------------------------------- */

/* The loop, with the monitor thread beside it; the loop's result. */
static int run(const struct options *o, struct app *a)
{
	struct mlip_rt_opts ro = o->ro;
	struct mlip_rt_report rep;
	pthread_t mon_th;
	pthread_attr_t attr;
	ro.period_ns = (int64_t)(a->cfg.machine.period_s * 1e9 + 0.5);
	memset(&rep, 0, sizeof(rep));
	a->mon.m = &a->cfg.machine;
	a->mon.stall_periods = a->co.stall_periods;
	a->mon.iface = o->iface;
	a->mon.can = a->use_can ? &per.can : NULL;
	a->mon.ring = a->shm.ring;
	a->mon.ds = a->drives_up ? &drives : NULL;
	a->mon.shm = &a->shm;
	pthread_attr_init(&attr);
	pthread_attr_setstacksize(&attr, 64 * 1024); /* memory is locked: keep it small */
	int mon_ok = pthread_create(&mon_th, &attr, monitor, &a->mon) == 0;
	pthread_attr_destroy(&attr);
	if (a->cfg.machine.path_plan) { /* the records are the planning thread's */
		if (mlip_rtplan_start(&a->plan, &a->cfg, a->shm.ring) != 0) {
			return -EAGAIN;
		}
		per.plan = &a->plan.pp;
	}
	int rc = mlip_rt_run(&ro, mlip_period_tick, NULL, &per, &rep);
	mlip_rtplan_stop(&a->plan);
	if (mon_ok) {
		a->mon.done = 1;
		pthread_join(mon_th, NULL);
	}
	return rc;
}

/* ---- report ------------------------------------------------------------------- */

/* The drives after the loop: the faulted ones, the shut-down (by SDO when
 * the loop could not finish it), released. */
static void drives_report(void)
{
	char faulted[64] = "", note[192];
	size_t k = 0;
	for (int i = 0; i < drives.n && k < sizeof(faulted); i++) {
		if (drives.mute & (1u << i)) {
			k += (size_t)snprintf(faulted + k, sizeof(faulted) - k, " %u",
			                      drives.d[i].node);
		}
	}
	if (faulted[0]) {
		fprintf(stderr,
		        PROG ": drives: node%s faulted: left in the drive's own fault reaction\n",
		        faulted);
	}
	if (drives.io.re.count > 0 || drives.io.re.failed > 0) {
		char reg[64];
		snprintf(reg, sizeof(reg), "reads 0x%02X: the module still reports a fault",
		         drives.io.re.fail_reg);
		fprintf(stderr,
		        PROG ": I/O module node %u: reconfigured %u time(s) after a loss, %u "
		             "attempt(s) failed (last: 0x%04X:%02X, %s)\n",
		        drives.io.node, drives.io.re.count, drives.io.re.failed,
		        drives.io.re.fail_index, drives.io.re.fail_sub,
		        drives.io.re.failed == 0     ? "-"
		        : drives.io.re.fail_reg != 0 ? reg
		        : drives.io.re.fail_abort == 0
		            ? "no answer in time"
		            : mlip_sdo_abort_text(drives.io.re.fail_abort));
	}
	if (drives.io.re.wrong) {
		fprintf(stderr,
		        PROG ": I/O module node %u: came back as another device: 0x%04X:%02X reads "
		             "0x%08X, 0x%08X at bring-up; left unconfigured, in the E-stop\n",
		        drives.io.node, drives.io.re.wrong_index, drives.io.re.wrong_sub,
		        drives.io.re.wrong_got, drives.io.re.wrong_want);
	}
	if (drives.shutdown_ok) {
		fprintf(stderr, PROG ": drives disabled in order (disable operation, shutdown) "
		                     "with the SYNC running, then the SYNC stopped\n");
	} else {
		mlip_drives_shutdown_text(&drives, note, sizeof(note));
		fprintf(stderr,
		        PROG ": drives: in-loop shut-down incomplete (%s): shutting down by SDO\n",
		        note[0] ? note : "the loop ended early");
		mlip_drives_disable(&drives);
	}
	mlip_drives_release(&drives);
	drives.n = 0; /* released: tear_down leaves them */
}

static int report_run(const char *record, struct app *a, int rc)
{
	struct mlip_ring_status s;
	if (a->mon.rec != NULL && (fclose(a->mon.rec) != 0 || per.rec_lost > 0)) {
		fprintf(stderr, PROG ": --record %s: incomplete (%llu setpoints lost)\n", record,
		        (unsigned long long)per.rec_lost);
	}
	a->mon.rec = NULL;
	if (a->drives_up) {
		drives_report();
		a->drives_up = 0;
	}
	if (rc < 0) {
		fprintf(stderr, PROG ": cannot start the loop: %s\n", strerror(-rc));
	}
	if (got_exit) {
		fprintf(stderr, PROG ": %s: stopped on the path, exiting\n",
		        mlip_cli_signal_name(got_exit));
	}
	mlip_ring_status_read(a->shm.ring, &s);
	fprintf(stderr,
	        PROG
	        ": stopped after %llu periods: %llu frames sent, %llu dropped (tx queue), "
	        "%llu bus errors, %llu overruns, %llu underruns, %llu records taken, %llu programs "
	        "refused; last line %u\n",
	        (unsigned long long)per.cycles, (unsigned long long)per.can.tx_ok,
	        (unsigned long long)per.can.tx_dropped, (unsigned long long)per.can.bus_errors,
	        (unsigned long long)s.overruns, (unsigned long long)per.out.counts.underruns,
	        (unsigned long long)per.out.counts.blocks_consumed,
	        (unsigned long long)per.out.counts.refused, (unsigned)s.exec_line);
	tear_down(a);
	return rc < 0 ? 1 : 0;
}

int main(int argc, char **argv)
{
	static struct options o;
	static struct app a;
	int rc = parse_options(argc, argv, &o);
	if (rc != 0) {
		return rc < 0 ? 0 : rc;
	}
	/* first: a stop asked for while starting up must not kill us blind */
	mlip_cli_on_stop_signals(on_signal);
	rc = set_up(&o, &a);
	if (rc != 0) {
		return rc;
	}
	return report_run(o.record, &a, run(&o, &a));
}
