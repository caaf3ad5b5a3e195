/*
 * mlip-grbl - a Grbl 1.1 front-end for a running mlip-rt: G-code senders
 * (CNCjs, bCNC, UGS, gSender, ...) drive mlip over TCP or a pseudo-terminal
 * as they drive a Grbl board. The protocol is tools/lib/grbl.h (pure); the
 * lines become the ring's records as mlip-feed makes them
 * (tools/lib/grblstream.h); this file owns the sockets, the ring's producer
 * side, the command mailbox and the time.
 *
 * One loop, never blocking: poll the sockets (1 ms while anything is under
 * way), take real-time bytes at once (commands posted to the mailbox in the
 * same pass: the controller applies them in its next period; `?` answered
 * from the status of the last period), then the lines in order: each checked
 * whole by the G-code reader, its records staged and pushed to the ring, and
 * `ok` sent as soon as they are queued, so a character-counting sender keeps
 * the controller's look-ahead full. A line the reader refuses is answered
 * "[MSG:line N col C: ...]" and error:N, and nothing after it is taken until
 * the sender resumes (~) or resets (ctrl-x): the machine stops at rest at the
 * end of the last good line.
 *
 * A program, for the controller, is what runs between two END records. The
 * stream is cut into programs where it must be: at M2/M30, at a refused line,
 * and when the sender has gone quiet (no line for --quiet-ms) while the
 * controller waits for more (pre-reading, or starved at rest): then the
 * smoothing filter is finished and END sent, so a single MDI line runs at
 * once. A sender streaming a file never goes quiet while the controller
 * runs, so the file runs as one program, as mlip-feed would run it.
 *
 * One controlling client: the first to connect (TCP) or to open the
 * pseudo-terminal. Another gets a clear refusal and is closed. The
 * controlling client's disconnect finishes what was acknowledged (the
 * machine stops at rest after it, as after a lost feeder) and cancels a jog.
 */
#define _XOPEN_SOURCE 700 /* posix_openpt, grantpt, unlockpt, ptsname */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <math.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"
#include "grbl.h"
#include "grblmach.h"
#include "grblstream.h"
#include "mlip/ctl/state.h"
#include "mlip/ipc/ring.h"
#include "mlip/machine/config.h"
#include "rt.h"

#define PROG          "mlip-grbl"
#define TX_CAP        65536        /* bytes waiting for a client that reads slowly */
#define TX_STATUS_MIN 1024         /* a status report needs this much room (else skipped) */
#define MAX_PEERS     8            /* connections at once (the others are refused) */
#define DEAD_NS       500000000ull /* no controller beat this long: not responding */
#define PTY_CHECK_NS  20000000ull  /* look for a sender on the pseudo-terminal */
#define CMDQ          32           /* real-time commands waiting for the mailbox */
#define DEFAULT_QUIET 100          /* ms */
#define DEFAULT_PORT  "2323"

static volatile sig_atomic_t got_signal;
static void on_signal(int sig)
{
	got_signal = sig;
}

struct peer {
	int fd;
	int pty;
	char name[80];
	char tx[TX_CAP];
	size_t tx_len;
};

/* A command for the controller's mailbox. */
struct cmd {
	uint32_t op;
	int32_t arg;
};

struct srv {
	/* wiring */
	struct mlip_shm shm;
	struct mlip_ring *r;
	struct mlip_ring_port tx;
	int port_open, locked;
	struct mlip_machine m;
	struct grbl_axes ax;
	struct grbl_fmt fmt;
	struct grbl_refresh refresh;
	int listen_fd;
	int pty_fd;
	char pty_link[256];
	char pty_name[64];
	int pty_open; /* a process has the pseudo-terminal's other side open */
	uint64_t pty_checked;
	struct peer *peers[MAX_PEERS];
	struct peer *ctl; /* the controlling client */
	uint64_t quiet_ns;
	double default_feed;
	int verbose;
	/* protocol */
	struct grbl_rx rx;
	uint32_t lineno;     /* lines received since the welcome */
	uint64_t last_rx_ns; /* last line byte received */
	int status_req;
	int check_mode;
	int err_hold;  /* a refused line: nothing more taken until ~ or reset */
	int hold_idle; /* ! while idle: Hold:0 until ~ */
	int door;      /* 0x84: a safety-door hold (Door:2 stopping, Door:0 until ~) */
	int sleeping;  /* $SLP: until reset */
	int alarm;     /* our own alarm latch (a stop by someone else, a soft limit):
	                  kept through a reset, cleared by $X, as Grbl's */
	int critical;  /* ALARM:2 (a soft limit): no line taken until a reset */
	char alarm_why[200];
	int reset_wait;  /* a reset waits for rest before the welcome */
	int hold_req;    /* we asked for a feed hold (the controller says held only at rest) */
	int jog;         /* a jog ($J=) is queued or moving: Grbl's Jog state */
	int jog_cancel;  /* a jog cancel is stopping it: Jog until at rest */
	uint64_t cmd_hb; /* the controller's period when we last posted a command */
	uint64_t cmd_ns;
	int stop_ours;        /* we posted a stop (a reset) */
	uint32_t stop_ticket; /* its ticket (mlip_ring_stop_post) */
	uint32_t stop_seen;   /* the controller's stop_seen when we last looked */
	int partial;          /* the current line's blocks are not all staged */
	int ov_feed, ov_rapid, ov_spindle;
	double wco_last[MLIP_MAX_AXES];
	int fault_told;
	/* the stream and the controller */
	struct grbl_stream st;
	uint64_t pushed_seq; /* last record of the open program in the ring */
	int program_live;    /* records of ours in the ring or the controller's hands */
	struct mlip_ring_feeder fa;
	struct mlip_ring_status cs; /* the controller's last status */
	int cs_ok;
	uint64_t cs_beat, cs_beat_ns;
	int dead;
	struct cmd q[CMDQ];
	int qn;
	int ov_post; /* an override value waits for the mailbox (-1: none) */
	/* the machine's I/O, as mlip-feed takes it from the controller */
	struct mlip_gcode_io io;
	struct grbl_acc acc;  /* what its manual spindle and coolant do now */
	uint32_t acc_changes; /* acc.changes last shown */
	uint32_t prev_state;  /* the controller's state before its current one */
	/* a $H or $X waiting for the controller: Grbl answers it when done
	 * and takes no line meanwhile */
	uint32_t await_op;  /* MLIP_CMD_HOME, MLIP_CMD_RESET; 0: none */
	int await_stage;    /* 0 to post, 1 posted (its result), 2 under way */
	uint32_t await_seq; /* its mailbox ticket */
	uint64_t await_hb;  /* the controller's period when it was accepted */
	uint64_t await_ns;
};

static struct srv S;
static struct mlip_smooth smooth_mem; /* ~1 MB: the smoothing filter's window */

static uint64_t now_ns(void)
{
	return mlip_now_ns();
}

/* ---- output -------------------------------------------------------------- */

static void send_raw(struct peer *p, const char *s, size_t n)
{
	if (p == NULL || p->fd < 0) {
		return;
	}
	if (p->tx_len + n > TX_CAP) {
		return; /* the client does not read: drop (bounded memory) */
	}
	memcpy(p->tx + p->tx_len, s, n);
	p->tx_len += n;
}

static void send_line(struct peer *p, const char *s)
{
	send_raw(p, s, strlen(s));
	send_raw(p, "\r\n", 2);
}

static void send_msg(struct peer *p, const char *fmt, ...)
{
	char m[GRBL_MSG_BYTES], l[GRBL_MSG_BYTES + 8];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(m, sizeof(m), fmt, ap);
	va_end(ap);
	grbl_msg_clean(m);
	snprintf(l, sizeof(l), "[MSG:%s]", m);
	send_line(p, l);
}

static void answer(int code)
{
	char b[32];
	if (code == 0) {
		send_line(S.ctl, "ok");
	} else {
		snprintf(b, sizeof(b), "error:%d", code);
		send_line(S.ctl, b);
	}
}

/* Grbl's alarm push (interface.md: ALARM:x; the codes of doc/csv/
 * alarm_codes_en_US.csv), then why, in mlip's words. */
static void alarm_push(int code, const char *why)
{
	char b[16];
	snprintf(b, sizeof(b), "ALARM:%d", code);
	send_line(S.ctl, b);
	if (why != NULL) {
		send_msg(S.ctl, "%s", why);
	}
}

static void flush_peer(struct peer *p)
{
	while (p->tx_len > 0) {
		ssize_t n = write(p->fd, p->tx, p->tx_len);
		if (n <= 0) {
			return; /* EAGAIN: later; an error shows at the next read */
		}
		memmove(p->tx, p->tx + n, p->tx_len - (size_t)n);
		p->tx_len -= (size_t)n;
	}
}

static void logf_(const char *fmt, ...)
{
	va_list ap;
	fputs(PROG ": ", stderr);
	va_start(ap, fmt);
	vfprintf(stderr, fmt, ap);
	va_end(ap);
	fputc('\n', stderr);
}

/* ---- the controller -------------------------------------------------------- */

static void poll_controller(void)
{
	struct mlip_ring_status st;
	if (mlip_ring_status_read(S.r, &st) == MLIP_OK) {
		if (S.cs_ok && st.state != S.cs.state) {
			S.prev_state = S.cs.state;
		}
		grbl_acc_update(&S.acc, st.state, st.reason, st.reason_seq, st.reason_value);
		if (st.state == MLIP_STATE_PAUSED && S.cs.state != MLIP_STATE_PAUSED && S.ctl &&
		    (st.reason == MLIP_WHY_SPINDLE || st.reason == MLIP_WHY_COOLANT ||
		     st.reason == MLIP_WHY_TOOL)) {
			/* the operator's part (Hold:0 until ~) */
			char what[200];
			mlip_cli_io_message(st.reason, st.reason_value, NULL, what, sizeof(what));
			send_msg(S.ctl, "line %u: %s, then resume (~)", (unsigned)st.reason_line,
			         what);
		}
		S.cs = st;
		S.cs_ok = 1;
		if (st.heartbeat != S.cs_beat) {
			S.cs_beat = st.heartbeat;
			S.cs_beat_ns = now_ns();
		}
	}
	int dead = S.cs_beat_ns == 0 || now_ns() - S.cs_beat_ns > DEAD_NS;
	if (dead && !S.dead && S.cs_beat_ns != 0) {
		logf_("the controller on %s stopped responding", S.shm.name);
		if (S.ctl) {
			char why[160];
			snprintf(
			    why, sizeof(why),
			    "the controller on %s stopped responding (mlip-rt gone or stalled): "
			    "nothing runs",
			    S.shm.name);
			alarm_push(3, why); /* what it did last is not known */
		}
	}
	S.dead = dead;
}

static int at_rest_state(uint32_t s)
{
	return s == MLIP_STATE_IDLE || s == MLIP_STATE_STARVED || s == MLIP_STATE_FAULT ||
	       s == MLIP_STATE_ESTOP;
}

/* The controller holds the machine until a reset or a restart. */
static int locked_state(uint32_t s)
{
	return s == MLIP_STATE_FAULT || s == MLIP_STATE_ESTOP;
}

static void locked_why(char *why, size_t n);
static void say_locked(void);

/* Nothing of ours is queued or moving. */
static int quiet_controller(void)
{
	return at_rest_state(S.cs.state) && mlip_ring_count(S.r) == 0 &&
	       grbl_stream_staged(&S.st) == 0 && !S.st.end_pending;
}

static void cmd_push(uint32_t op, int32_t arg)
{
	if (S.qn < CMDQ) {
		S.q[S.qn++] = (struct cmd){op, arg};
	}
}

static void cmd_pump(void)
{
	if (S.ov_post >= 0 && S.qn < CMDQ) {
		cmd_push(MLIP_CMD_OVERRIDE, S.ov_post);
		S.ov_post = -1;
	}
	if (S.qn == 0) {
		return;
	}
	if (mlip_ring_cmd_post(S.r, (mlip_ring_cmd_op)S.q[0].op, S.q[0].arg, NULL) == MLIP_OK) {
		S.cmd_hb = S.cs.heartbeat;
		S.cmd_ns = now_ns();
		if (S.q[0].op == MLIP_CMD_HOLD) {
			S.hold_req = 1;
		} else if (S.q[0].op == MLIP_CMD_RESUME) {
			S.hold_req = 0;
		}
		memmove(S.q, S.q + 1, (size_t)(S.qn - 1) * sizeof(S.q[0]));
		S.qn--;
	}
}

/* A controlled stop on the path (the stop counter: never refused, never
 * behind the mailbox); the controller drops what is queued. */
static void stop_post(void)
{
	S.stop_ticket = mlip_ring_stop_post(S.r);
	S.stop_ours = 1;
	S.hold_req = 0;
}

/* ---- the ring's producer side ------------------------------------------------ */

static void producer_unlock(void)
{
	struct flock fl;
	memset(&fl, 0, sizeof(fl));
	fl.l_type = F_UNLCK;
	fl.l_whence = SEEK_SET;
	fl.l_start = (off_t)offsetof(struct mlip_ring, head);
	fl.l_len = MLIP_RING_LINE;
	(void)fcntl(S.shm.fd, F_SETLK, &fl);
	S.locked = 0;
	S.port_open = 0;
}

static void beat(void)
{
	S.fa.heartbeat++;
	S.fa.heartbeat_ns = now_ns();
	mlip_ring_feeder_write(S.r, &S.fa);
}

/* Take the producer side for a line that moves: 0, or a refusal said. */
static int take_producer(void)
{
	int32_t holder = 0;
	struct mlip_ring_feeder other;
	if (S.locked) {
		return 0;
	}
	if (mlip_shm_feeder_lock(&S.shm, &holder) != 0) {
		send_msg(S.ctl,
		         "another feeder (pid %d) is feeding %s: wait for it to finish, or stop "
		         "it (mlip-ctl stop)",
		         (int)holder, S.shm.name);
		return -1;
	}
	if (mlip_ring_feeder_read(S.r, &other) == MLIP_OK && other.pid != 0 &&
	    other.pid != (int32_t)getpid() && mlip_peer_feeder(&other) == MLIP_PEER_ALIVE) {
		send_msg(S.ctl, "another feeder (pid %d) is feeding %s", (int)other.pid,
		         S.shm.name);
		producer_unlock();
		return -1;
	}
	if (mlip_ring_port_open(&S.tx, S.r, 1) != MLIP_OK) {
		send_msg(S.ctl, "%s: the ring's header is not valid: restart mlip-rt", S.shm.name);
		producer_unlock();
		return -1;
	}
	S.locked = 1;
	S.port_open = 1;
	S.fa.pid = (int32_t)getpid();
	S.fa.total_blocks = 0;
	S.fa.program_end = 0;
	beat();
	return 0;
}

/* Staged records into the ring, as many as fit. */
static void push_records(void)
{
	if (S.port_open && grbl_stream_staged(&S.st) > 0 && S.fa.pid == 0) {
		S.fa.pid = (int32_t)getpid(); /* feeding again (after a quiet pre-read) */
		beat();
	}
	while (S.port_open && grbl_stream_staged(&S.st) > 0) {
		uint32_t n = grbl_stream_staged(&S.st), got = 0;
		const struct mlip_ring_rec *recs = grbl_stream_peek(&S.st);
		if (mlip_ring_port_push_n(&S.tx, recs, n, &got) != MLIP_OK || got == 0) {
			return;
		}
		for (uint32_t i = 0; i < got; i++) {
			S.pushed_seq = recs[i].type == MLIP_REC_END ? 0 : recs[i].seq;
		}
		S.program_live = 1;
		grbl_stream_take(&S.st, got);
	}
}

/* An END alone (after a stop: the controller drops the stopped program's
 * records up to it). */
static void push_end_alone(void)
{
	struct mlip_ring_rec rec;
	uint32_t got = 0;
	if (!S.port_open || S.pushed_seq == 0) {
		return;
	}
	mlip_ring_rec_end(&rec, S.pushed_seq + 1, S.lineno);
	mlip_ring_port_push_n(&S.tx, &rec, 1, &got);
	if (got == 1) {
		S.pushed_seq = 0;
	}
}

/* ---- state ---------------------------------------------------------------- */

static const char *grbl_state(void)
{
	const struct mlip_ring_status *c = &S.cs;
	int ours_queued = grbl_stream_staged(&S.st) > 0 || mlip_ring_count(S.r) > 0 || S.st.open ||
	                  S.st.end_pending;
	int moving = c->speed_mm_s > 0.0;
	/* a soft-limit alarm while what was acknowledged still runs: Alarm once
	 * at rest (Grbl: Hold, then Alarm) */
	int settling = S.critical && !quiet_controller();
	if (!S.dead && (c->state == MLIP_STATE_HOMING || S.await_op == MLIP_CMD_HOME)) {
		return "Home"; /* $H (Grbl: also from Alarm) or mlip-ctl home */
	}
	if (S.dead || locked_state(c->state) || (S.alarm && !settling)) {
		return "Alarm";
	}
	if (S.sleeping) {
		return "Sleep";
	}
	if (S.check_mode) {
		return "Check";
	}
	if (S.door) {
		/* mlip has no door switch: the door reads closed once at rest */
		return moving || c->state == MLIP_STATE_STOPPING ? "Door:2" : "Door:0";
	}
	if (S.jog) {
		return "Jog"; /* Grbl: Jog also while a jog cancel decelerates */
	}
	switch (c->state) {
	case MLIP_STATE_HELD:
		return moving ? "Hold:1" : "Hold:0";
	case MLIP_STATE_STOPPING:
		return "Hold:1";
	case MLIP_STATE_PAUSED:
		return "Hold:0";
	case MLIP_STATE_RUNNING:
	case MLIP_STATE_PREREAD:
	case MLIP_STATE_DWELLING:
		/* a hold decelerates in RUNNING: Grbl's Hold:1 */
		return S.hold_req ? (moving ? "Hold:1" : "Hold:0") : "Run";
	case MLIP_STATE_IDLE:
	case MLIP_STATE_STARVED:
		if (S.hold_req || S.hold_idle) {
			return "Hold:0";
		}
		if (S.err_hold) {
			int ring = mlip_ring_count(S.r) > 0 || grbl_stream_staged(&S.st) > 0;
			return ring || moving ? "Run" : "Hold:0";
		}
		return ours_queued ? "Run" : "Idle";
	case MLIP_STATE_JOGGING:
		return "Jog"; /* mlip-ctl jog (a continuous jog, issue 18) */
	case MLIP_STATE_HOMING:
		return "Home"; /* mlip-ctl home */
	default:
		/* E-stop, and a state this build does not know: never "Idle" */
		return "Alarm";
	}
}

static int busy_state(const char *s)
{
	return strcmp(s, "Idle") != 0 && strcmp(s, "Alarm") != 0 && strcmp(s, "Check") != 0 &&
	       strcmp(s, "Sleep") != 0;
}

static void status_report(void)
{
	struct grbl_status s;
	char b[GRBL_MSG_BYTES];
	if (S.ctl == NULL || TX_CAP - S.ctl->tx_len < TX_STATUS_MIN) {
		return; /* the sender does not read: a report is not owed (interface.md) */
	}
	memset(&s, 0, sizeof(s));
	s.state = grbl_state();
	memcpy(s.mpos, S.cs.pos, sizeof(s.mpos));
	grbl_wco(&S.st.g.off, S.m.n_axes, s.wco);
	if (memcmp(s.wco, S.wco_last, sizeof(s.wco)) != 0) {
		memcpy(S.wco_last, s.wco, sizeof(s.wco));
		grbl_refresh_wco(&S.refresh);
	}
	s.feed_mm_min = S.cs.speed_mm_s * 60.0;
	s.spindle_rpm = fabs(S.acc.rpm); /* the manual spindle as the operator set it */
	s.ov_feed = S.ov_feed;
	s.ov_rapid = S.ov_rapid;
	s.ov_spindle = S.ov_spindle;
	s.busy = busy_state(s.state);
	s.bf_blocks = (int)mlip_ring_space(S.r);
	s.bf_bytes = (int)grbl_rx_available(&S.rx);
	s.line =
	    strcmp(s.state, "Run") == 0 || strncmp(s.state, "Hold", 4) == 0 ? S.cs.exec_line : 0;
	char pins[16], acc[8];
	grbl_pins(pins, sizeof(pins), S.cs.io_inputs & S.cs.io_mapped, &S.m);
	grbl_accessories(acc, sizeof(acc), S.acc.rpm, S.acc.coolant);
	if (S.acc.changes != S.acc_changes) {
		S.acc_changes = S.acc.changes;
		grbl_refresh_ovr(&S.refresh); /* report.c: A: at once after a change */
	}
	s.pins = pins;
	s.accessories = acc;
	grbl_status_format(b, sizeof(b), &s, &S.ax, &S.fmt, &S.refresh);
	send_line(S.ctl, b);
}

/* ---- resets and welcome -------------------------------------------------------- */

static void welcome(void)
{
	send_raw(S.ctl, "\r\n", 2);
	send_line(S.ctl, GRBL_WELCOME);
	send_msg(S.ctl, "mlip-grbl: mlip on %s, %d axes, %s", S.shm.name, S.m.n_axes,
	         S.m.smooth ? "strategy smooth" : "planner look-ahead");
	if (S.dead || locked_state(S.cs.state) || S.alarm) {
		send_msg(S.ctl, "'$H'|'$X' to unlock");
	}
	memset(&S.refresh, 0, sizeof(S.refresh));
	S.lineno = 0;
}

/* Where the machine stands, for a new program. */
static void restart_at(const double *pos, int keep_modes)
{
	grbl_stream_restart(&S.st, pos, keep_modes);
	/* what was queued and dropped never ran: the spindle and coolant are
	 * what the machine does (an M5 then still asks the operator) */
	grbl_stream_machine_io(&S.st, S.acc.rpm, S.acc.coolant);
}

static void resync(int keep_modes)
{
	restart_at(S.cs.pos, keep_modes);
	S.partial = 0;
	if (!keep_modes) {
		memset(S.wco_last, 0, sizeof(S.wco_last));
	}
}

static void soft_reset(void)
{
	grbl_rx_reset(&S.rx);
	S.status_req = 0;
	S.check_mode = 0;
	S.err_hold = 0;
	S.hold_idle = 0;
	S.hold_req = 0;
	S.door = 0;
	S.jog = 0;
	S.jog_cancel = 0;
	S.critical = 0;
	if (S.sleeping) {
		S.alarm = 1; /* Grbl: out of sleep into alarm */
		snprintf(S.alarm_why, sizeof(S.alarm_why), "after sleep ($SLP)");
	}
	S.sleeping = 0;
	S.partial = 0;
	/* overrides back to 100 % (Grbl's reset) */
	if (S.ov_feed != 100) {
		S.ov_feed = 100;
		S.ov_post = 100;
	}
	S.ov_rapid = S.ov_spindle = 100;
	/* a program of ours in the ring and not ended (pushed_seq, the stream
	 * open) is stopped too, even if the status read last still says idle:
	 * the controller may have taken its first records since. Without the
	 * stop it would wait for the rest of that program for ever. */
	int ours_open = S.pushed_seq != 0 || S.st.open;
	if ((!quiet_controller() || ours_open) && !locked_state(S.cs.state)) {
		stop_post();
		S.reset_wait = 1;
		restart_at(S.cs.pos, 0);
		push_end_alone();
		return;
	}
	resync(0);
	welcome();
}

/* ---- jogging -------------------------------------------------------------------- */

/* Grbl's jog ($J=, jogging.md) as a program of its own: each $J= line is a
 * G1 move at its own F through the same planner and limits as a program
 * (the G-code reader runs it with the modal state left as it was), queued
 * behind the last, and given to the controller at once (no waiting for more
 * look-ahead); the program ends as soon as the controller has run it. A
 * cancel (0x85, a feed hold, the sender gone) is the controller's stop on
 * the path: it decelerates at the acceleration limit and drops what is
 * queued. This is the one mapping to move onto the controller's own jog
 * (issue 18: a continuous jog with a dead-man) when it lands: jog_line,
 * jog_cancel and jog_done are all that know how a jog runs. */
static void jog_cancel(const char *why)
{
	if (!S.jog || S.jog_cancel) {
		return;
	}
	if (S.verbose) {
		logf_("jog cancelled (%s)", why);
	}
	S.jog_cancel = 1;
	if (quiet_controller() && !S.st.open) {
		return; /* it has ended at rest already: jog_done says Idle */
	}
	stop_post();
	restart_at(S.cs.pos, 1);
	S.partial = 0;
	push_end_alone();
}

/* The jog has ended (run to its end, or cancelled and at rest). */
static void jog_done(void)
{
	if (!S.jog || S.st.open || S.st.end_pending || grbl_stream_staged(&S.st) > 0 ||
	    !quiet_controller() || S.cs.state == MLIP_STATE_STOPPING) {
		return;
	}
	if (S.jog_cancel && S.stop_ours && !mlip_ring_stop_applied(S.cs.stop_seen, S.stop_ticket)) {
		return;
	}
	if (S.jog_cancel) {
		S.stop_ours = 0;
		resync(1); /* where it stopped, on the jog's path */
	}
	S.jog = 0;
	S.jog_cancel = 0;
	S.program_live = 0;
}

/* ---- real-time commands -------------------------------------------------------- */

static void rt_cmd(void *ctx, grbl_rt c)
{
	(void)ctx;
	const struct mlip_ring_status *cs = &S.cs;
	switch (c) {
	case GRBL_RT_STATUS:
		S.status_req = 1;
		return;
	case GRBL_RT_RESET:
		soft_reset();
		return;
	case GRBL_RT_FEED_HOLD:
		if (S.check_mode || S.alarm || S.sleeping) {
			return;
		}
		if (S.jog) {
			jog_cancel("feed hold"); /* Grbl: any hold cancels a jog */
			return;
		}
		if (at_rest_state(cs->state) && quiet_controller()) {
			S.hold_idle = 1; /* Grbl: a hold while idle suspends too */
		}
		cmd_push(MLIP_CMD_HOLD, 0);
		return;
	case GRBL_RT_CYCLE_START:
		if (S.door) {
			S.door = 0; /* the door is closed (no switch says otherwise) */
			if (S.hold_req || cs->state == MLIP_STATE_HELD) {
				cmd_push(MLIP_CMD_RESUME, 0);
			}
			S.hold_idle = 0;
			return;
		}
		if (S.jog) {
			return; /* nothing to resume: a jog is cancelled, not held */
		}
		if (S.err_hold) {
			S.err_hold = 0; /* the sender goes on after a refused line */
		}
		if (S.hold_idle || S.hold_req || cs->state == MLIP_STATE_HELD ||
		    cs->state == MLIP_STATE_PAUSED) {
			cmd_push(MLIP_CMD_RESUME, 0);
		}
		S.hold_idle = 0;
		return;
	case GRBL_RT_JOG_CANCEL:
		jog_cancel("jog cancel"); /* outside the Jog state: ignored, as Grbl */
		return;
	case GRBL_RT_SAFETY_DOOR:
		/* Grbl's door as a command: a feed hold (a jog is cancelled), Door
		 * until ~; mlip has no door switch and no spindle to stop yet */
		if (S.check_mode || S.alarm || S.sleeping || S.door) {
			return;
		}
		S.door = 1;
		if (S.jog) {
			jog_cancel("safety door");
			return;
		}
		if (at_rest_state(cs->state) && quiet_controller()) {
			S.hold_idle = 1;
		}
		cmd_push(MLIP_CMD_HOLD, 0);
		return;
	case GRBL_RT_FEED_100:
	case GRBL_RT_FEED_PLUS_10:
	case GRBL_RT_FEED_MINUS_10:
	case GRBL_RT_FEED_PLUS_1:
	case GRBL_RT_FEED_MINUS_1: {
		int v = grbl_override_step(c, S.ov_feed);
		if (v != S.ov_feed) {
			S.ov_feed = v;
			S.ov_post = v;
			grbl_refresh_ovr(&S.refresh);
		}
		return;
	}
	case GRBL_RT_RAPID_100:
	case GRBL_RT_RAPID_50:
	case GRBL_RT_RAPID_25:
		if (c != GRBL_RT_RAPID_100 && S.ctl) {
			send_msg(S.ctl, "rapid override: mlip has one override, the feed override, "
			                "which scales rapids too; rapids stay at 100 %%");
		}
		return;
	case GRBL_RT_SPINDLE_100:
	case GRBL_RT_SPINDLE_PLUS_10:
	case GRBL_RT_SPINDLE_MINUS_10:
	case GRBL_RT_SPINDLE_PLUS_1:
	case GRBL_RT_SPINDLE_MINUS_1: {
		/* kept and shown as Grbl does with the spindle off; applied once
		 * mlip drives a spindle (issue 19) */
		int v = grbl_override_step(c, S.ov_spindle);
		if (v != S.ov_spindle) {
			S.ov_spindle = v;
			grbl_refresh_ovr(&S.refresh);
		}
		return;
	}
	case GRBL_RT_SPINDLE_STOP:
	case GRBL_RT_FLOOD:
	case GRBL_RT_MIST:
		/* Grbl switches its own outputs; mlip's spindle and coolant are
		 * the operator's (manual) or absent: say so, switch nothing */
		if (S.ctl) {
			int sp = c == GRBL_RT_SPINDLE_STOP;
			int type = sp ? S.io.spindle : S.io.coolant;
			send_msg(
			    S.ctl, "%s: %s: nothing switched", grbl_rt_name(c),
			    type == MLIP_IO_NONE ? (sp ? "this machine has no spindle"
			                               : "this machine has no coolant")
			    : sp ? "the spindle is the operator's here (manual): stop it by hand, "
			           "or M5 in the program"
			         : "the coolant is the operator's here (manual): switch it by "
			           "hand, or M7/M8/M9 in the program");
		}
		return;
	default:
		return;
	}
}

/* ---- lines ------------------------------------------------------------------- */

static int idle_or_alarm(void)
{
	const char *s = grbl_state();
	return strcmp(s, "Idle") == 0 || strcmp(s, "Alarm") == 0;
}

/* A target beyond the soft limits: Grbl's ALARM:2 (limits.c: the line is
 * not run, not answered, and nothing is taken until a reset; after it the
 * alarm stays until $X). The machine runs what was acknowledged and stops
 * at rest there. */
static void soft_limit_alarm(const struct mlip_gcode_error *e)
{
	send_msg(S.ctl, "line %u col %u: %s", (unsigned)e->line, (unsigned)e->col, e->msg);
	S.alarm = 1;
	S.critical = 1;
	snprintf(S.alarm_why, sizeof(S.alarm_why), "soft limit (line %u)", (unsigned)e->line);
	alarm_push(2, NULL);
	send_msg(S.ctl, "Reset to continue");
}

static void say_error(const struct mlip_gcode_error *e, int code)
{
	if (e->col) {
		send_msg(S.ctl, "line %u col %u: %s", (unsigned)e->line, (unsigned)e->col, e->msg);
	} else {
		send_msg(S.ctl, "line %u: %s", (unsigned)e->line, e->msg);
	}
	answer(code);
}

/* A refused line in a stream: the machine runs what was acknowledged and
 * stops at rest there; nothing more is taken until ~ or reset. A line
 * refused with nothing of ours queued and no line behind it (typed in a
 * console: the sender waits for its answer) holds nothing: the next line
 * is taken, as Grbl takes it. */
static void refuse_hold(void)
{
	if (S.st.open || S.program_live || grbl_stream_staged(&S.st) > 0 || S.rx.bytes > 0 ||
	    S.rx.marks > 0) {
		S.err_hold = 1;
	}
	grbl_stream_end(&S.st);
}

static void notices_since(uint32_t before)
{
	for (uint32_t k = before; k < S.st.g.n_notices; k++) {
		const struct mlip_gcode_notice *n = &S.st.g.notices[k];
		send_msg(S.ctl, "line %u: %s %s", (unsigned)n->first_line, n->word,
		         mlip_gcode_notice_text(n));
	}
}

/* A G-code line: 1 answered, 0 waits (its records do not fit yet, or the
 * controller is being reset). */
static int gcode_line(const char *t, size_t len)
{
	struct mlip_gcode_error e;
	uint32_t nn = S.st.g.n_notices;
	if (S.dead) {
		send_msg(S.ctl, "the controller on %s is not responding: nothing runs", S.shm.name);
		answer(GRBL_E_LOCK);
		return 1;
	}
	if (locked_state(S.cs.state) || S.alarm || S.sleeping) {
		if (locked_state(S.cs.state)) {
			say_locked();
		} else {
			send_msg(S.ctl, "alarm: %s; reset (ctrl-x) or $X first",
			         S.sleeping ? "sleeping" : S.alarm_why);
		}
		answer(GRBL_E_LOCK);
		return 1;
	}
	if (S.jog) {
		send_msg(S.ctl,
		         "jogging: G-code waits until the jog has ended (or 0x85 cancels it)");
		answer(GRBL_E_LOCK);
		return 1;
	}
	if (S.check_mode) {
		if (grbl_stream_dry(&S.st, t, len, S.lineno, &e) != MLIP_OK) {
			if (grbl_error_travel(&e)) {
				soft_limit_alarm(&e); /* "soft limits still work" in check mode */
				return 1;
			}
			say_error(&e, grbl_error_code(&e, 0));
			return 1;
		}
		notices_since(nn);
		answer(0);
		return 1;
	}
	if (!S.st.open && grbl_stream_staged(&S.st) == 0) {
		/* a new program: a stop from now on is meant for it (the
		 * controller refuses it, were it still to start) */
		S.fa.stop_base = mlip_ring_stop_count(S.r);
		if (quiet_controller() && !S.program_live) {
			resync(1); /* it starts where the machine stands now */
		}
	}
	if (grbl_stream_check(&S.st, t, len, S.lineno, &e) != MLIP_OK) {
		if (grbl_error_travel(&e)) {
			soft_limit_alarm(&e);
		} else {
			say_error(&e, grbl_error_code(&e, 0));
		}
		refuse_hold();
		return 1;
	}
	if (take_producer() != 0) {
		answer(GRBL_E_LOCK);
		return 1;
	}
	int rc = grbl_stream_line(&S.st, t, len, S.lineno, &e);
	if (rc < 0) { /* cannot happen: checked above */
		say_error(&e, grbl_error_code(&e, 0));
		refuse_hold();
		return 1;
	}
	notices_since(nn);
	if (rc == 0) {
		S.partial = 1;
		return 0;
	}
	if (grbl_stream_ended(&S.st)) {
		send_msg(S.ctl, "Pgm End");
	}
	answer(0);
	return 1;
}

/* ---- $H and $X: the controller's homing and reset ----------------------------- */

static void await_start(uint32_t op)
{
	S.await_op = op;
	S.await_stage = 0;
	S.await_ns = now_ns();
}

static void await_end(int code)
{
	S.await_op = 0;
	answer(code);
}

/* Post the command, take its result, follow it to its end, answer. */
static void await_pump(void)
{
	int32_t res = 0;
	if (S.await_op == 0) {
		return;
	}
	if (S.ctl == NULL) {
		S.await_op = 0; /* its sender left: homing goes on, nobody to answer */
		return;
	}
	if (S.await_stage == 0) {
		if (S.qn > 0 || S.ov_post >= 0) {
			return; /* real-time commands first: they came before */
		}
		if (mlip_ring_cmd_post(S.r, (mlip_ring_cmd_op)S.await_op, 0, &S.await_seq) ==
		    MLIP_OK) {
			S.await_stage = 1;
			S.await_ns = now_ns();
		} else if (now_ns() - S.await_ns > 5000000000ull) {
			send_msg(S.ctl, "the controller's mailbox stayed busy for 5 s (another "
			                "mlip-ctl?): try again");
			await_end(S.await_op == MLIP_CMD_HOME ? GRBL_E_IDLE : GRBL_E_LOCK);
		}
		return;
	}
	if (S.await_stage == 1) {
		mlip_status rc = mlip_ring_cmd_result(S.r, S.await_seq, &res);
		if (rc == MLIP_E_EMPTY && !S.dead) {
			return;
		}
		if (rc != MLIP_OK) {
			send_msg(S.ctl, "the controller did not answer %s",
			         S.await_op == MLIP_CMD_HOME ? "$H" : "$X");
			await_end(S.await_op == MLIP_CMD_HOME ? GRBL_E_IDLE : GRBL_E_LOCK);
			return;
		}
		if (S.await_op == MLIP_CMD_HOME && res == MLIP_E_RANGE) {
			send_msg(S.ctl, "homing is not configured: no HOME_METHOD in the machine's "
			                "configuration (or no CiA 402 drives: mlip-rt --drives)");
			await_end(GRBL_E_SETTING_DISABLED);
			return;
		}
		if (S.await_op == MLIP_CMD_HOME && res != MLIP_OK) {
			char why[240] = "the controller is not idle";
			if (locked_state(S.cs.state)) {
				locked_why(why, sizeof(why));
			}
			send_msg(S.ctl, "$H refused: %s", why);
			await_end(GRBL_E_IDLE);
			return;
		}
		if (S.await_op == MLIP_CMD_RESET && res == MLIP_E_RANGE) {
			send_msg(S.ctl,
			         "$X refused: the input that stopped the machine is still on "
			         "(release the E-stop, move the axis off its limit switch; a "
			         "lost I/O module needs a restart of mlip-rt)");
			await_end(GRBL_E_LOCK);
			return;
		}
		S.await_stage = 2; /* accepted (or nothing left to reset) */
		S.await_hb = S.cs.heartbeat;
		return;
	}
	/* under way: the status of a later period says how it ended */
	if (S.cs.heartbeat < S.await_hb + 2 && !S.dead) {
		return;
	}
	if (S.await_op == MLIP_CMD_HOME) {
		if (S.cs.state == MLIP_STATE_HOMING && !S.dead) {
			return;
		}
		if (S.cs.state == MLIP_STATE_IDLE && S.cs.reason == MLIP_WHY_HOMED) {
			S.alarm = 0; /* Grbl: homing unlocks */
			S.critical = 0;
			resync(1); /* where homing left the axes */
		}
		/* a failure was pushed as an alarm (follow_controller); Grbl
		 * answers the line ok after its homing cycle either way */
		await_end(0);
		return;
	}
	if (locked_state(S.cs.state) && !S.dead) {
		if (!grbl_resettable(S.cs.state, S.cs.reason)) {
			/* reset into what came before it (a drive fault) */
			say_locked();
			await_end(GRBL_E_LOCK);
			return;
		}
		if (now_ns() - S.await_ns > 5000000000ull) {
			send_msg(S.ctl, "$X: the controller is still in %s",
			         mlip_ctl_state_name(S.cs.state));
			await_end(GRBL_E_LOCK);
		}
		return;
	}
	S.alarm = 0;
	S.critical = 0;
	resync(1);
	send_msg(S.ctl, "Caution: Unlocked");
	await_end(0);
}

static void settings_list(void)
{
	char b[GRBL_MSG_BYTES];
	for (int i = 0; grbl_setting_line(b, sizeof(b), &S.m, &S.fmt, i) > 0; i++) {
		send_line(S.ctl, b);
	}
}

/* A $J= line: 1 answered, 0 waits (a cancel still decelerating). */
static int jog_line(const char *t, size_t len, const char *state)
{
	struct mlip_gcode_error e;
	if (S.jog_cancel) {
		return 0; /* Grbl takes no line until the cancel has ended */
	}
	if (S.dead) {
		send_msg(S.ctl, "the controller on %s is not responding: nothing runs", S.shm.name);
		answer(GRBL_E_IDLE);
		return 1;
	}
	if (strcmp(state, "Idle") != 0 && strcmp(state, "Jog") != 0) {
		if (strcmp(state, "Alarm") == 0) {
			send_msg(S.ctl, "alarm: no jog until it is cleared ($X, or a restart of "
			                "mlip-rt for a fault)");
		}
		answer(GRBL_E_IDLE); /* jogging.md: only in Idle or Jog */
		return 1;
	}
	int first = !S.jog;
	if (first) {
		/* a jog program of its own, from where the machine stands */
		S.fa.stop_base = mlip_ring_stop_count(S.r);
		resync(1);
	}
	if (grbl_stream_check(&S.st, t, len, S.lineno, &e) != MLIP_OK) {
		/* not run, and nothing else changes (no hold: jogging.md) */
		say_error(&e, grbl_error_code(&e, 1));
		return 1;
	}
	if (take_producer() != 0) {
		answer(GRBL_E_IDLE);
		return 1;
	}
	S.jog = 1;
	int rc = grbl_stream_line(&S.st, t, len, S.lineno, &e);
	if (rc < 0) { /* cannot happen: checked above */
		say_error(&e, grbl_error_code(&e, 1));
		return 1;
	}
	if (rc == 0) {
		S.partial = 1;
		return 0;
	}
	/* at once: the smoothing filter's rest, and the controller told to
	 * start with what it has (quiet_end) */
	grbl_stream_flush(&S.st, 0);
	answer(0);
	return 1;
}

/* A `$` line: 1 answered. */
static int system_line(const char *t, size_t len)
{
	struct grbl_sys c;
	char b[GRBL_MSG_BYTES];
	grbl_sys_parse(t, len, &c);
	const char *state = grbl_state();
	switch (c.kind) {
	case GRBL_SYS_HELP:
		send_line(S.ctl, "[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? "
		                 "ctrl-x]");
		answer(0);
		return 1;
	case GRBL_SYS_SETTINGS:
		/* system.c: not during a cycle or a hold (it takes too long to print) */
		if (strcmp(state, "Run") == 0 || strncmp(state, "Hold", 4) == 0) {
			answer(GRBL_E_IDLE);
			return 1;
		}
		settings_list();
		answer(0);
		return 1;
	case GRBL_SYS_GCODE:
		grbl_gcode_state(b, sizeof(b), &S.st.g, -1);
		send_line(S.ctl, b);
		answer(0);
		return 1;
	case GRBL_SYS_CHECK:
		if (S.check_mode) {
			send_msg(S.ctl, "Disabled");
			answer(0);
			soft_reset(); /* Grbl resets when check mode ends */
			return 1;
		}
		if (strcmp(state, "Idle") != 0) {
			answer(GRBL_E_IDLE);
			return 1;
		}
		S.check_mode = 1;
		send_msg(S.ctl, "Enabled");
		answer(0);
		return 1;
	case GRBL_SYS_UNLOCK:
		if (locked_state(S.cs.state) && !S.dead) {
			if (!grbl_resettable(S.cs.state, S.cs.reason)) {
				say_locked();
				answer(GRBL_E_LOCK);
				return 1;
			}
			/* the controller's reset (mlip-ctl reset): answered once it
			 * has left the E-stop or the limit (await_pump) */
			S.err_hold = 0;
			await_start(MLIP_CMD_RESET);
			return 1;
		}
		if (S.alarm) {
			S.alarm = 0;
			send_msg(S.ctl, "Caution: Unlocked");
		}
		S.err_hold = 0; /* and a refused line's hold */
		answer(0);
		return 1;
	case GRBL_SYS_JOG:
		return jog_line(t, len, state);
	default:
		break;
	}
	/* the rest: Idle or Alarm only (system.c) */
	if (!idle_or_alarm()) {
		answer(c.kind == GRBL_SYS_BAD ? c.code : GRBL_E_IDLE);
		return 1;
	}
	switch (c.kind) {
	case GRBL_SYS_PARAMS:
		for (int i = 0; grbl_param_line(b, sizeof(b), &S.st.g.off, &S.ax, &S.fmt, i) > 0;
		     i++) {
			send_line(S.ctl, b);
		}
		answer(0);
		return 1;
	case GRBL_SYS_INFO:
		snprintf(b, sizeof(b), "[VER:%s.%s:mlip-grbl on %s]", GRBL_VERSION, GRBL_BUILD,
		         S.shm.name);
		send_line(S.ctl, b);
		snprintf(b, sizeof(b), "[OPT:N,%u,%d]", (unsigned)S.r->capacity, GRBL_RX_SIZE);
		send_line(S.ctl, b);
		answer(0);
		return 1;
	case GRBL_SYS_STARTUP:
		send_line(S.ctl, "$N0=");
		send_line(S.ctl, "$N1=");
		answer(0);
		return 1;
	case GRBL_SYS_HOME:
		if (S.dead) {
			send_msg(S.ctl, "the controller on %s is not responding", S.shm.name);
			answer(GRBL_E_IDLE);
			return 1;
		}
		/* the drives' homing (mlip-ctl home): every axis with a
		 * HOME_METHOD, in HOME_SEQUENCE order; answered at its end */
		await_start(MLIP_CMD_HOME);
		return 1;
	case GRBL_SYS_SLEEP:
		S.sleeping = 1;
		send_msg(S.ctl, "Sleeping");
		answer(0);
		return 1;
	case GRBL_SYS_SET:
		if (c.number == 10 && c.value >= 0 && c.value <= 255 && c.value == floor(c.value)) {
			S.fmt.mask =
			    (int)c.value; /* how reports look: this server's, not the machine's */
			answer(0);
			return 1;
		}
		if (c.number == 13 && (c.value == 0 || c.value == 1)) {
			S.fmt.inches = (int)c.value;
			grbl_refresh_wco(&S.refresh);
			answer(0);
			return 1;
		}
		/* fall through */
	case GRBL_SYS_STARTUP_SET:
	case GRBL_SYS_INFO_SET:
	case GRBL_SYS_RESTORE:
		send_msg(S.ctl,
		         "settings live in the machine configuration file (mlip-rt --config); "
		         "mlip never writes it from the network ($10 and $13, how reports "
		         "look, are the only ones set here)");
		answer(GRBL_E_INVALID_STATEMENT);
		return 1;
	default:
		answer(c.code);
		return 1;
	}
}

/* A `$` line that moves nothing and changes no program: answered even while
 * a refused line holds the stream ($X also releases that hold). */
static int is_query(const char *t, size_t len)
{
	struct grbl_sys c;
	size_t i = 0;
	while (i < len && (unsigned char)t[i] <= ' ') {
		i++;
	}
	if (i == len || t[i] != '$') {
		return 0;
	}
	grbl_sys_parse(t, len, &c);
	return c.kind == GRBL_SYS_HELP || c.kind == GRBL_SYS_SETTINGS ||
	       c.kind == GRBL_SYS_PARAMS || c.kind == GRBL_SYS_GCODE || c.kind == GRBL_SYS_INFO ||
	       c.kind == GRBL_SYS_STARTUP || c.kind == GRBL_SYS_UNLOCK;
}

/* The next complete line, if nothing holds it back. */
static void process_lines(void)
{
	struct grbl_line l;
	if (S.ctl == NULL || S.reset_wait || S.critical || S.await_op) {
		return;
	}
	if (S.partial) {
		if (!grbl_stream_more(&S.st)) {
			return;
		}
		S.partial = 0;
		if (grbl_stream_ended(&S.st)) {
			send_msg(S.ctl, "Pgm End");
		}
		answer(0);
		grbl_rx_done(&S.rx);
	}
	while (grbl_rx_line(&S.rx, &l)) {
		int sys_query = l.kind == GRBL_LINE_TEXT && is_query(l.text, l.len);
		if ((S.err_hold && !sys_query) || S.st.end_pending ||
		    TX_CAP - S.ctl->tx_len < 2 * GRBL_MSG_BYTES) {
			if (S.st.end_pending) {
				grbl_stream_flush(&S.st, 0);
			}
			return;
		}
		S.lineno++;
		if (l.kind == GRBL_LINE_LOST) {
			send_msg(S.ctl,
			         "receive buffer overflow: the sender sent more than %d bytes "
			         "without waiting for ok; %u line(s) lost (%u bytes): not run",
			         GRBL_RX_SIZE, (unsigned)l.lost, (unsigned)l.overflow);
			for (uint32_t k = 0; k < l.lost; k++) {
				answer(GRBL_E_OVERFLOW);
			}
			S.lineno += l.lost - 1;
			refuse_hold();
			S.err_hold = 1; /* lines were lost: always */
			grbl_rx_done(&S.rx);
			continue;
		}
		if (l.kind == GRBL_LINE_TOO_LONG) {
			send_msg(S.ctl, "line %u: longer than %d bytes: not run",
			         (unsigned)S.lineno, GRBL_LINE_MAX);
			answer(GRBL_E_OVERFLOW);
			if (!S.check_mode) {
				refuse_hold();
			}
			grbl_rx_done(&S.rx);
			continue;
		}
		/* what Grbl would see: empty after its pre-parse -> ok */
		size_t i = 0;
		while (i < l.len && ((unsigned char)l.text[i] <= ' ')) {
			i++;
		}
		int done;
		if (i < l.len && l.text[i] == '$') {
			done = system_line(l.text, l.len);
		} else {
			done = gcode_line(l.text, l.len);
		}
		if (!done) {
			return; /* its records wait for room */
		}
		grbl_rx_done(&S.rx);
	}
}

/* The sender went quiet: what it sent must not wait for lines that may not
 * come. The smoothing filter gives what it holds (the program goes on).
 * A controller still pre-reading is told "nothing more for now" (the
 * feeder area's pid 0, as a feeder that left): it starts with what it has,
 * and lines that come later continue the same program, so a sender that
 * pauses for a while (CNCjs does, while it draws) costs no stop. A program
 * whose controller is at rest waiting for more ends there (END): it is
 * complete, the controller idle. A file streamed without pauses is one
 * program, as mlip-feed runs it. */
static void quiet_end(void)
{
	if (S.partial) {
		return;
	}
	if (S.st.end_pending) {
		grbl_stream_flush(&S.st, 0);
		return;
	}
	if (S.err_hold && S.st.open) {
		grbl_stream_end(&S.st);
		return;
	}
	if (grbl_rx_pending(&S.rx) || (!S.jog && now_ns() - S.last_rx_ns < S.quiet_ns)) {
		return; /* a jog runs at once (jogging.md's joystick: no waiting for more) */
	}
	if (grbl_stream_holding(&S.st)) {
		if (S.verbose) {
			logf_("quiet: the smoothing filter gives its rest (line %u)",
			      (unsigned)S.lineno);
		}
		grbl_stream_flush(&S.st, 0);
	}
	if (!S.st.open || S.st.end_pending || grbl_stream_staged(&S.st) > 0) {
		return;
	}
	if (S.cs.state == MLIP_STATE_PREREAD && S.fa.pid != 0) {
		if (S.verbose) {
			logf_("quiet, controller pre-reading: it starts with what it has (line %u)",
			      (unsigned)S.lineno);
		}
		S.fa.pid = 0; /* beat() publishes it */
	} else if ((S.cs.state == MLIP_STATE_STARVED || S.cs.state == MLIP_STATE_IDLE) &&
	           (!S.jog || mlip_ring_count(S.r) == 0)) {
		/* (a jog's records just pushed may not be taken yet: the
		 * controller is idle until its next period) */
		if (S.verbose) {
			logf_("quiet, controller %s: program ends at line %u",
			      mlip_ctl_state_name(S.cs.state), (unsigned)S.lineno);
		}
		grbl_stream_end(&S.st);
	}
}

/* Why the controller holds the machine (E-stop, a limit, a failed homing,
 * a fault) and what clears it, in mlip's words. */
static void locked_why(char *why, size_t n)
{
	char fn[32];
	const struct mlip_ring_status *c = &S.cs;
	mlip_io_function_name(c->reason_field, &S.m, fn, sizeof(fn));
	if (c->state == MLIP_STATE_ESTOP && c->reason == MLIP_WHY_ESTOP) {
		snprintf(why, n,
		         "E-stop: input %s (node %u) at line %u: quick stop to every drive, the "
		         "program dropped; release it, then $X",
		         fn, (unsigned)c->reason_node, (unsigned)c->reason_line);
	} else if (c->state == MLIP_STATE_ESTOP) {
		snprintf(why, n,
		         "E-stop: the I/O module (node %u) is lost (%s): quick stop to every "
		         "drive; restart mlip-rt",
		         (unsigned)c->reason_node, mlip_state_why_name(c->reason));
	} else if (c->reason == MLIP_WHY_LIMIT) {
		snprintf(why, n,
		         "limit switch: %s (node %u) at line %u: quick stop to every drive; "
		         "move the axis off the switch, then $X",
		         fn, (unsigned)c->reason_node, (unsigned)c->reason_line);
	} else if (grbl_resettable(c->state, c->reason)) {
		snprintf(why, n,
		         "homing failed: %s (node %u, statusword 0x%04X): every axis stopped; $X, "
		         "then check the axis' HOME_* settings",
		         mlip_state_why_name(c->reason), (unsigned)c->reason_node,
		         (unsigned)c->reason_value);
	} else {
		/* Grbl has no code for a drive or bus fault: 3, "position not
		 * guaranteed", is what a stop by a fault means */
		snprintf(why, n,
		         "mlip-rt fault: %s at line %u: every axis stopped; restart mlip-rt to "
		         "clear",
		         mlip_state_why_name(c->reason), (unsigned)c->reason_line);
	}
}

static void say_locked(void)
{
	char why[240];
	locked_why(why, sizeof(why));
	send_msg(S.ctl, "%s", why);
}

/* What the controller did on its own (a stop by mlip-ctl, a fault), and
 * the end of a reset. */
static void follow_controller(void)
{
	int stop_done = !S.stop_ours || mlip_ring_stop_applied(S.cs.stop_seen, S.stop_ticket);
	/* a stop the controller applied that is not ours (mlip-ctl stop) */
	int foreign =
	    S.cs.stop_seen != S.stop_seen && !(S.stop_ours && S.cs.stop_seen == S.stop_ticket);
	S.stop_seen = S.cs.stop_seen;
	if (S.reset_wait && stop_done && quiet_controller() && S.cs.state != MLIP_STATE_STOPPING) {
		S.reset_wait = 0;
		S.stop_ours = 0;
		S.program_live = 0;
		resync(0);
		welcome();
	}
	jog_done();
	if (S.program_live && quiet_controller()) {
		S.program_live = 0;
	}
	if (S.hold_req && S.cs.state == MLIP_STATE_HELD) {
		S.hold_req = 0; /* the controller says held itself from now on */
	}
	if ((foreign || (!S.stop_ours && S.cs.state == MLIP_STATE_STOPPING)) &&
	    (S.st.open || S.program_live || grbl_stream_staged(&S.st) > 0)) {
		/* stopped by someone else (mlip-ctl stop, a signal to mlip-rt) */
		S.alarm = 1;
		snprintf(
		    S.alarm_why, sizeof(S.alarm_why),
		    "stopped by mlip-ctl stop (or mlip-rt exiting) at line %u: the rest of the "
		    "program was dropped",
		    (unsigned)S.cs.exec_line);
		if (S.ctl) {
			/* Grbl's nearest: an abort in motion (a reset); mlip kept
			 * the position (a stop on the path) */
			alarm_push(3, S.alarm_why);
		}
		restart_at(S.cs.pos, 1);
		S.partial = 0;
		push_end_alone();
		S.program_live = 0;
	}
	int code = grbl_alarm_of(S.cs.state, S.cs.reason, S.prev_state);
	if (code == 0) {
		S.fault_told = 0;
	} else if (!S.fault_told) {
		S.fault_told = 1;
		if (S.ctl) {
			char why[240];
			locked_why(why, sizeof(why));
			alarm_push(code, why);
		}
		/* the controller drops the rest of the program up to its END */
		restart_at(S.cs.pos, 1);
		S.partial = 0;
		push_end_alone();
		S.program_live = 0;
	}
}

/* ---- connections -------------------------------------------------------------- */

static void peer_close(struct peer *p)
{
	for (int i = 0; i < MAX_PEERS; i++) {
		if (S.peers[i] == p) {
			S.peers[i] = NULL;
		}
	}
	if (!p->pty) {
		close(p->fd);
	}
	free(p);
}

/* The controlling client left: what it was told is queued runs to its end
 * (the machine stops at rest after it, as after a lost feeder); the rest of
 * what it sent is dropped. */
static void lose_controller(const char *why)
{
	if (S.jog) {
		/* a jog is the operator's hand on the machine: it stops with them */
		logf_("%s %s mid-jog: the jog is cancelled (a stop on its path)", S.ctl->name, why);
		jog_cancel("the sender left");
		grbl_rx_reset(&S.rx);
		S.check_mode = 0;
		S.err_hold = 0;
		S.hold_idle = 0;
		struct peer *p = S.ctl;
		S.ctl = NULL;
		if (!p->pty) {
			peer_close(p);
		}
		return;
	}
	if (S.st.open || S.program_live || S.partial) {
		logf_("%s %s mid-program (line %u): the machine runs what was acknowledged to its "
		      "end and stops at rest there; lines not acknowledged are dropped",
		      S.ctl->name, why, (unsigned)S.lineno);
	} else {
		logf_("%s %s (line %u)", S.ctl->name, why, (unsigned)S.lineno);
	}
	if (S.partial) {
		/* its line was not acknowledged: none of it runs */
		grbl_stream_restart(&S.st, grbl_stream_pos(&S.st), 1);
		S.partial = 0;
	}
	if (S.st.open) {
		grbl_stream_end(&S.st);
	}
	grbl_rx_reset(&S.rx);
	S.check_mode = 0;
	S.err_hold = 0;
	S.hold_idle = 0;
	if (S.ctl->pty) {
		S.ctl = NULL; /* the pseudo-terminal stays ours */
		return;
	}
	struct peer *p = S.ctl;
	S.ctl = NULL;
	peer_close(p);
}

static void take_control(struct peer *p)
{
	S.ctl = p;
	S.last_rx_ns = now_ns();
	logf_("%s is the controlling sender", p->name);
	/* a new sender finds Grbl as after a reset: the parser's defaults, from
	 * where the machine stands (or will, once what was queued has run) */
	if (grbl_stream_staged(&S.st) == 0 && !S.st.end_pending && !S.st.open) {
		if (quiet_controller() && !S.program_live) {
			resync(0);
		} else {
			/* what is queued still runs: its spindle and coolant too */
			double at[MLIP_MAX_AXES];
			const struct mlip_gcode *g = &S.st.g;
			double rpm = g->spindle == 3 ? g->s_rpm : g->spindle == 4 ? -g->s_rpm : 0.0;
			unsigned cool = g->coolant;
			memcpy(at, grbl_stream_pos(&S.st), sizeof(at));
			grbl_stream_restart(&S.st, at, 0);
			grbl_stream_machine_io(&S.st, rpm, cool);
		}
	}
	welcome();
}

static void refuse(int fd, const char *who)
{
	char b[256];
	int n = snprintf(b, sizeof(b),
	                 "\r\n[MSG:mlip-grbl: %s already controls this machine: one sender at a "
	                 "time; this connection is closed]\r\n",
	                 who);
	if (n > 0) {
		(void)!write(fd, b, (size_t)n);
	}
}

static void accept_peer(void)
{
	struct sockaddr_storage sa;
	socklen_t sl = sizeof(sa);
	int fd = accept(S.listen_fd, (struct sockaddr *)&sa, &sl);
	if (fd < 0) {
		return;
	}
	char host[64] = "?", serv[16] = "?";
	getnameinfo((struct sockaddr *)&sa, sl, host, sizeof(host), serv, sizeof(serv),
	            NI_NUMERICHOST | NI_NUMERICSERV);
	if (S.ctl != NULL) {
		refuse(fd, S.ctl->name);
		logf_("refused %s:%s: %s controls the machine", host, serv, S.ctl->name);
		close(fd);
		return;
	}
	int slot = -1;
	for (int i = 0; i < MAX_PEERS; i++) {
		if (S.peers[i] == NULL) {
			slot = i;
			break;
		}
	}
	struct peer *p = slot >= 0 ? calloc(1, sizeof(*p)) : NULL;
	if (p == NULL) {
		close(fd);
		return;
	}
	int one = 1;
	setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
	fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK);
	p->fd = fd;
	snprintf(p->name, sizeof(p->name), "%s:%s", host, serv);
	S.peers[slot] = p;
	take_control(p);
}

static void read_peer(struct peer *p)
{
	unsigned char b[4096];
	for (;;) {
		ssize_t n = read(p->fd, b, sizeof(b));
		if (n > 0) {
			if (p != S.ctl) {
				continue; /* not in control: nothing it says is taken */
			}
			for (ssize_t i = 0; i < n; i++) {
				if (grbl_rt_of(b[i]) == GRBL_RT_NONE) {
					S.last_rx_ns =
					    now_ns(); /* a line byte: the sender is not quiet */
					break;
				}
			}
			grbl_rx_feed(&S.rx, b, (size_t)n, rt_cmd, NULL);
			if ((size_t)n < sizeof(b)) {
				return;
			}
			continue;
		}
		if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
			return;
		}
		/* closed (or EIO: the pseudo-terminal's other side closed); a
		 * socket's peer is freed here (lose_controller, peer_close):
		 * nothing of it is read after */
		int pty = p->pty;
		if (p == S.ctl) {
			lose_controller("disconnected");
		} else if (!pty) {
			peer_close(p);
		}
		if (pty) {
			S.pty_open = 0;
		}
		return;
	}
}

/* ---- the pseudo-terminal ---------------------------------------------------------- */

static int pty_setup(const char *link)
{
	int fd = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK);
	if (fd < 0 || grantpt(fd) != 0 || unlockpt(fd) != 0) {
		logf_("pseudo-terminal: %s", strerror(errno));
		return -1;
	}
	const char *name = ptsname(fd);
	if (name == NULL) {
		return -1;
	}
	snprintf(S.pty_name, sizeof(S.pty_name), "%s", name);
	/* raw: no echo, no line editing, no signals from ^C/^X, 8 bits clean */
	int sfd = open(name, O_RDWR | O_NOCTTY);
	if (sfd >= 0) {
		struct termios t;
		if (tcgetattr(sfd, &t) == 0) {
			cfmakeraw(&t);
			cfsetispeed(&t, B115200);
			cfsetospeed(&t, B115200);
			tcsetattr(sfd, TCSANOW, &t);
		}
		close(sfd); /* from now on the master sees POLLHUP until a sender opens it */
	}
	/* the stable path: a symlink made beside it and renamed over the old one */
	char tmp[300];
	snprintf(tmp, sizeof(tmp), "%s.%d.tmp", link, (int)getpid());
	unlink(tmp);
	if (symlink(name, tmp) != 0 || rename(tmp, link) != 0) {
		logf_("pseudo-terminal: cannot make %s -> %s: %s", link, name, strerror(errno));
		unlink(tmp);
		close(fd);
		return -1;
	}
	snprintf(S.pty_link, sizeof(S.pty_link), "%s", link);
	S.pty_fd = fd;
	struct peer *p = calloc(1, sizeof(*p));
	if (p == NULL) {
		return -1;
	}
	p->fd = fd;
	p->pty = 1;
	snprintf(p->name, sizeof(p->name), "pseudo-terminal %.60s", link);
	S.peers[MAX_PEERS - 1] = p;
	return 0;
}

/* A sender opened (or closed) the pseudo-terminal's other side. */
static void pty_check(void)
{
	struct peer *p = S.peers[MAX_PEERS - 1];
	if (S.pty_fd < 0 || p == NULL) {
		return;
	}
	struct pollfd pf = {S.pty_fd, POLLIN, 0};
	if (poll(&pf, 1, 0) < 0) {
		return;
	}
	int open_now = !(pf.revents & POLLHUP);
	if (open_now && !S.pty_open) {
		S.pty_open = 1;
		if (S.ctl == NULL) {
			take_control(p);
		} else {
			char b[256];
			snprintf(
			    b, sizeof(b),
			    "\r\n[MSG:mlip-grbl: %s already controls this machine: one sender at a "
			    "time]\r\n",
			    S.ctl->name);
			(void)!write(S.pty_fd, b, strlen(b));
		}
	} else if (!open_now && S.pty_open) {
		S.pty_open = 0;
		if (S.ctl == p) {
			lose_controller("closed the pseudo-terminal");
		}
		p->tx_len = 0;
	}
}

/* ---- setup -------------------------------------------------------------------------- */

static int listen_on(const char *spec)
{
	char host[128] = "127.0.0.1", port[16] = DEFAULT_PORT;
	const char *colon = strrchr(spec, ':');
	if (colon == NULL) {
		snprintf(port, sizeof(port), "%s", spec);
	} else {
		size_t hl = (size_t)(colon - spec);
		if (hl > 0) {
			if (spec[0] == '[' && hl >= 2 && spec[hl - 1] == ']') {
				snprintf(host, sizeof(host), "%.*s", (int)(hl - 2), spec + 1);
			} else {
				snprintf(host, sizeof(host), "%.*s", (int)hl, spec);
			}
		}
		snprintf(port, sizeof(port), "%s", colon + 1);
	}
	struct addrinfo hints, *ai = NULL;
	memset(&hints, 0, sizeof(hints));
	hints.ai_socktype = SOCK_STREAM;
	hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
	int rc = getaddrinfo(host, port, &hints, &ai);
	if (rc != 0) {
		logf_("--listen %s: %s", spec, gai_strerror(rc));
		return -1;
	}
	int fd = socket(ai->ai_family, ai->ai_socktype | SOCK_CLOEXEC, 0);
	int one = 1;
	if (fd >= 0) {
		setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
	}
	if (fd < 0 || bind(fd, ai->ai_addr, ai->ai_addrlen) != 0 || listen(fd, 4) != 0) {
		logf_("--listen %s: %s", spec, strerror(errno));
		freeaddrinfo(ai);
		if (fd >= 0) {
			close(fd);
		}
		return -1;
	}
	freeaddrinfo(ai);
	fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK);
	S.listen_fd = fd;
	struct sockaddr_storage sa;
	socklen_t sl = sizeof(sa);
	char h[64] = "?", sv[16] = "?";
	if (getsockname(fd, (struct sockaddr *)&sa, &sl) == 0) {
		getnameinfo((struct sockaddr *)&sa, sl, h, sizeof(h), sv, sizeof(sv),
		            NI_NUMERICHOST | NI_NUMERICSERV);
	}
	logf_("listening on %s:%s", h, sv); /* the port bound (port 0: the kernel's choice) */
	return 0;
}

static void usage(FILE *f)
{
	fprintf(
	    f,
	    "usage: " PROG " [options]\n"
	    "Speak Grbl 1.1 to G-code senders (CNCjs, bCNC, UGS, gSender) for a running\n"
	    "mlip-rt: status, overrides, hold/resume/reset, and programs streamed line by line,\n"
	    "each line checked as mlip-feed checks a file.\n\n"
	    "  --shm NAME          controller's shared-memory segment (default " MLIP_SHM_DEFAULT
	    ")\n"
	    "  --listen [ADDR:]PORT  TCP address (default 127.0.0.1:" DEFAULT_PORT
	    "; another address\n"
	    "                      only when given, e.g. 0.0.0.0:2323)\n"
	    "  --pty PATH          also a pseudo-terminal for serial-only senders, linked at\n"
	    "                      PATH (default /tmp/mlip-grbl-NAME.tty; 'none': no terminal)\n"
	    "  --quiet-ms N        a sender quiet this long while the controller waits ends\n"
	    "                      the program there, so it runs (default %d)\n"
	    "  --default-feed F    feed (units/min) for feed moves before any F\n"
	    "  -v, --verbose       log each connection's lines to stderr\n"
	    "  -h, --help          this help\n",
	    DEFAULT_QUIET);
}

int main(int argc, char **argv)
{
	static const struct option opts[] = {{"shm", required_argument, 0, 's'},
	                                     {"listen", required_argument, 0, 'l'},
	                                     {"pty", required_argument, 0, 'p'},
	                                     {"quiet-ms", required_argument, 0, 'Q'},
	                                     {"default-feed", required_argument, 0, 'D'},
	                                     {"verbose", no_argument, 0, 'v'},
	                                     {"help", no_argument, 0, 'h'},
	                                     {0, 0, 0, 0}};
	const char *shm = MLIP_SHM_DEFAULT, *listen_spec = "127.0.0.1:" DEFAULT_PORT;
	const char *pty = NULL;
	char why[256], pty_default[200];
	struct mlip_config_error cerr;
	int c, quiet_ms = DEFAULT_QUIET;

	while ((c = getopt_long(argc, argv, "vh", opts, NULL)) != -1) {
		switch (c) {
		case 's':
			shm = optarg;
			break;
		case 'l':
			listen_spec = optarg;
			break;
		case 'p':
			pty = optarg;
			break;
		case 'Q': {
			char *end;
			long v = strtol(optarg, &end, 10);
			if (*end != '\0' || v < 1 || v > 60000) {
				logf_("--quiet-ms: '%s' is not 1..60000", optarg);
				return 2;
			}
			quiet_ms = (int)v;
			break;
		}
		case 'D': {
			char *end;
			S.default_feed = strtod(optarg, &end);
			if (*end != '\0' || !(S.default_feed > 0.0) || S.default_feed > 1e9) {
				logf_("--default-feed: '%s' is not a positive number", optarg);
				return 2;
			}
			break;
		}
		case 'v':
			S.verbose = 1;
			break;
		case 'h':
			usage(stdout);
			return 0;
		default:
			usage(stderr);
			return 2;
		}
	}
	if (optind != argc) {
		usage(stderr);
		return 2;
	}
	S.quiet_ns = (uint64_t)quiet_ms * 1000000ull;
	S.listen_fd = S.pty_fd = -1;
	S.ov_feed = S.ov_rapid = S.ov_spindle = 100;
	S.ov_post = -1;
	S.fmt.mask = 1; /* Grbl's default $10=1: MPos */
	grbl_rx_init(&S.rx);

	if (mlip_shm_attach(&S.shm, shm, why, sizeof(why)) != 0) {
		logf_("%s", why);
		return 1;
	}
	S.r = S.shm.ring;
	mlip_ring_machine(S.r, &S.m);
	if (mlip_machine_check(&S.m, &cerr) != MLIP_OK) {
		logf_("%s publishes no usable machine (%s): restart mlip-rt", shm, cerr.msg);
		return 1;
	}
	grbl_axes_of(&S.m, &S.ax);
	poll_controller();
	S.stop_seen = S.cs.stop_seen;
	if (!S.cs_ok || S.cs.heartbeat == 0) {
		logf_("controller not running on %s: start mlip-rt", shm);
		return 1;
	}
	grbl_stream_init(&S.st, &S.m, S.cs.pos, &smooth_mem);
	{ /* the machine's I/O is the controller's ([SPINDLE], [TOOL], [COOLANT]) */
		struct mlip_ring_io rio;
		if (mlip_ring_io_read(S.r, &rio) != MLIP_OK) {
			logf_("%s publishes no machine I/O yet (mlip-rt starting?): try again",
			      shm);
			return 1;
		}
		if (mlip_cli_io_from_ring(&rio, &S.m, &S.io) != 0) {
			logf_(
			    "%s publishes a machine I/O this mlip-grbl cannot use: restart mlip-rt",
			    shm);
			return 1;
		}
		grbl_stream_set_io(&S.st, &S.io);
	}
	if (S.default_feed > 0.0) {
		mlip_gcode_set_initial_feed(&S.st.g, S.default_feed);
	}
	if (listen_on(listen_spec) != 0) {
		return 1;
	}
	if (pty == NULL) {
		const char *base = shm[0] == '/' ? shm + 1 : shm;
		snprintf(pty_default, sizeof(pty_default), "/tmp/mlip-grbl-%s.tty", base);
		pty = pty_default;
	}
	if (strcmp(pty, "none") != 0) {
		if (pty_setup(pty) != 0) {
			return 1;
		}
		logf_("pseudo-terminal %s -> %s", S.pty_link, S.pty_name);
	}
	signal(SIGPIPE, SIG_IGN);
	mlip_cli_on_stop_signals(on_signal);

	while (!got_signal) {
		struct pollfd pf[MAX_PEERS + 2];
		struct peer *who[MAX_PEERS + 2];
		int n = 0;
		pf[n] = (struct pollfd){S.listen_fd, POLLIN, 0};
		who[n++] = NULL;
		for (int i = 0; i < MAX_PEERS; i++) {
			struct peer *p = S.peers[i];
			if (p == NULL || (p->pty && !S.pty_open)) {
				continue; /* a closed terminal polls as hung up: looked at by time
				           */
			}
			pf[n] =
			    (struct pollfd){p->fd, (short)(POLLIN | (p->tx_len ? POLLOUT : 0)), 0};
			who[n++] = p;
		}
		int busy = S.ctl != NULL &&
		           (grbl_rx_pending(&S.rx) || S.st.open || grbl_stream_staged(&S.st) > 0 ||
		            S.qn > 0 || S.ov_post >= 0 || S.reset_wait || S.program_live);
		(void)poll(pf, (nfds_t)n, busy ? 1 : 10);
		if (pf[0].revents & POLLIN) {
			accept_peer();
		}
		for (int i = 1; i < n; i++) {
			if (pf[i].revents & (POLLIN | POLLHUP | POLLERR)) {
				read_peer(who[i]);
			}
		}
		if (S.pty_fd >= 0 && now_ns() - S.pty_checked > PTY_CHECK_NS) {
			S.pty_checked = now_ns();
			pty_check();
		}
		poll_controller();
		follow_controller();
		cmd_pump();
		await_pump();
		/* a report after a command shows its effect: the controller applies
		 * it in its next period (at most 50 ms waited) */
		int applied = S.cs.heartbeat >= S.cmd_hb + 2 || now_ns() - S.cmd_ns > 50000000ull;
		if (S.status_req && S.ctl != NULL && S.qn == 0 && S.ov_post < 0 && applied) {
			S.status_req = 0;
			status_report();
		}
		process_lines();
		quiet_end();
		push_records();
		if (S.locked) {
			if (S.ctl == NULL && !S.program_live && !S.st.open &&
			    grbl_stream_staged(&S.st) == 0) {
				S.fa.pid = 0; /* nobody feeds: mlip-feed may */
				beat();
				producer_unlock();
			} else {
				beat();
			}
		}
		for (int i = 0; i < MAX_PEERS; i++) {
			if (S.peers[i] != NULL && S.peers[i]->tx_len > 0) {
				flush_peer(S.peers[i]);
			}
		}
	}
	logf_("%s: leaving", mlip_cli_signal_name(got_signal));
	if (S.locked) {
		if (S.st.open) {
			grbl_stream_end(&S.st);
			push_records();
		}
		S.fa.pid = 0;
		beat();
	}
	if (S.pty_link[0]) {
		unlink(S.pty_link);
	}
	mlip_shm_close(&S.shm);
	return 0;
}
