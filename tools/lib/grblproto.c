/*
 * grblproto.c - mlip-grbl's protocol and flow control (grblsrv.h): what goes
 * to the sender (answers, messages, alarms, bounded per client), the
 * real-time bytes and the controller's mailbox they post to, and the lines
 * taken in order, each answered once.
 */
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"
#include "grbl.h"
#include "grblmach.h"
#include "grblsrv.h"
#include "grblstream.h"
#include "mlip/ctl/state.h"
#include "mlip/ipc/ring.h"
#include "mlip/machine/config.h"

struct srv S;

uint64_t now_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts); /* mlip_now_ns's clock */
	return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

/* ---- output -------------------------------------------------------------- */

void send_raw(struct peer *p, const char *s, size_t n)
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

void send_line(struct peer *p, const char *s)
{
	send_raw(p, s, strlen(s));
	send_raw(p, "\r\n", 2);
}

void send_msg(struct peer *p, const char *fmt, ...)
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

void answer(int code)
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
void alarm_push(int code, const char *why)
{
	char b[16];
	snprintf(b, sizeof(b), "ALARM:%d", code);
	send_line(S.ctl, b);
	if (why != NULL) {
		send_msg(S.ctl, "%s", why);
	}
}

void flush_peer(struct peer *p)
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

void logf_(const char *fmt, ...)
{
	va_list ap;
	fputs(PROG ": ", stderr);
	va_start(ap, fmt);
	vfprintf(stderr, fmt, ap);
	va_end(ap);
	fputc('\n', stderr);
}

void cmd_push(uint32_t op, int32_t arg)
{
	if (S.qn < CMDQ) {
		S.q[S.qn++] = (struct cmd){op, arg};
	}
}

void cmd_pump(void)
{
	if (S.ov_post >= 0 && S.qn < CMDQ) {
		cmd_push(MLIP_CMD_OVERRIDE, S.ov_post);
		S.ov_post = -1;
	}
	if (S.sp_post >= 0 && S.qn < CMDQ) {
		cmd_push(MLIP_CMD_SPINDLE_OVERRIDE, S.sp_post);
		S.sp_post = -1;
	}
	int sp_queued = 0, ov_queued = 0;
	for (int i = 0; i < S.qn; i++) {
		sp_queued |= S.q[i].op == MLIP_CMD_SPINDLE_OVERRIDE;
		ov_queued |= S.q[i].op == MLIP_CMD_OVERRIDE;
	}
	if (S.cs_ok && !S.dead && !ov_queued && S.ov_post < 0 && S.cs.heartbeat >= S.ov_hb + 2 &&
	    S.cs.override_pct <= 200 && (int)S.cs.override_pct != S.ov_feed) {
		/* the controller's feed override (mlip-ctl override too): Ov shows
		 * it and the next step starts from it (0: override_zero; 0x90 then
		 * ends it) */
		S.ov_feed = (int)S.cs.override_pct;
		grbl_refresh_ovr(&S.refresh);
	}
	if (S.sp_bus && !sp_queued && S.sp_post < 0 && S.cs.heartbeat >= S.sp_hb + 2) {
		/* the controller's value (mlip-ctl spindle-override too) is what
		 * the next step starts from */
		S.ov_spindle = S.sp_ov;
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
		} else if (S.q[0].op == MLIP_CMD_SPINDLE_OVERRIDE) {
			S.sp_hb = S.cs.heartbeat;
		} else if (S.q[0].op == MLIP_CMD_OVERRIDE) {
			S.ov_hb = S.cs.heartbeat;
		}
		memmove(S.q, S.q + 1, (size_t)(S.qn - 1) * sizeof(S.q[0]));
		S.qn--;
	}
}

/* A controlled stop on the path (the stop counter: never refused, never
 * behind the mailbox); the controller drops what is queued. */
void stop_post(void)
{
	S.stop_ticket = mlip_ring_stop_post(S.r);
	S.stop_ours = 1;
	S.hold_req = 0;
}

/* ---- real-time commands -------------------------------------------------------- */

/* Grbl switches its own outputs; mlip's spindle and coolant are the
 * program's (on the bus: no command switches them outside it; the spindle
 * stop in a hold excepted), the operator's (manual) or absent: say so,
 * switch nothing */
static void not_switched(grbl_rt c)
{
	if (S.ctl) {
		int sp = c == GRBL_RT_SPINDLE_STOP;
		int type = sp ? S.io.spindle : S.io.coolant;
		send_msg(S.ctl, "%s: %s: nothing switched", grbl_rt_name(c),
		         type == MLIP_IO_NONE
		             ? (sp ? "this machine has no spindle" : "this machine has no coolant")
		         : type != MLIP_IO_MANUAL
		             ? (sp ? "the spindle on the bus follows the program: M5, or a stop "
		                     "(ctrl-x) stops it"
		                   : "the coolant follows the program: M9, or a stop (ctrl-x) "
		                     "switches it off")
		         : sp ? "the spindle is the operator's here (manual): stop it by hand, "
		                "or M5 in the program"
		              : "the coolant is the operator's here (manual): switch it by "
		                "hand, or M7/M8/M9 in the program");
	}
}

/* Grbl's Hold: asked (a `!` just before, still in the mailbox queue, too) or held */
int in_hold(void)
{
	int queued = 0;
	for (int i = 0; i < S.qn; i++) {
		queued |= S.q[i].op == MLIP_CMD_HOLD;
	}
	/* override 0 is Run (override_zero): Grbl ignores 0x9E outside Hold */
	return queued || S.hold_req || S.hold_idle ||
	       (S.cs.state == MLIP_STATE_HELD && S.cs.reason != MLIP_WHY_OVERRIDE_ZERO) ||
	       ctl_holds();
}

void rt_cmd(void *ctx, grbl_rt c)
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
			if (S.hold_req || S.hold_idle || cs->state == MLIP_STATE_HELD ||
			    ctl_holds()) {
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
		    cs->state == MLIP_STATE_PAUSED || ctl_holds()) {
			/* a hold latched at rest (mlip-ctl hold, the hold input
			 * too): the resume ends it, moving nothing */
			if (S.sp_stopped && S.ctl) {
				/* the controller restores it and goes on at speed */
				send_msg(S.ctl, "Restoring spindle");
			}
			S.sp_stopped = 0;
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
		if (S.sp_bus) {
			/* the controller's spindle override (50..200 %), stepped from
			 * what was last asked so a burst of bytes adds up */
			int v = grbl_spindle_ov_step(c, S.ov_spindle);
			if (v != S.ov_spindle) {
				S.ov_spindle = v;
				S.sp_post = v;
			}
			return;
		}
		/* a manual spindle's speed is the operator's: kept and shown as
		 * Grbl does with the spindle off, applied to nothing */
		int v = grbl_override_step(c, S.ov_spindle);
		if (v != S.ov_spindle) {
			S.ov_spindle = v;
			grbl_refresh_ovr(&S.refresh);
		}
		return;
	}
	case GRBL_RT_SPINDLE_STOP:
		/* Grbl (protocol.c): in Hold only, elsewhere ignored; the first
		 * stops the spindle once the hold is at rest, the next restores
		 * it ([MSG:Restoring spindle]), as does ~ (the motion then waits
		 * until it is at speed: the controller's) */
		if (!in_hold() || S.door || S.jog || S.alarm) {
			return;
		}
		if (S.sp_bus) {
			S.sp_stopped = !S.sp_stopped;
			cmd_push(MLIP_CMD_SPINDLE_STOP, S.sp_stopped);
			if (!S.sp_stopped && S.ctl) {
				send_msg(S.ctl, "Restoring spindle");
			}
			return;
		}
		not_switched(c); /* a manual spindle or none: said */
		return;
	case GRBL_RT_FLOOD:
	case GRBL_RT_MIST:
		not_switched(c);
		return;
	default:
		return;
	}
}

/* A `$` line that moves nothing and changes no program: answered even while
 * a refused line holds the stream ($X also releases that hold). */
int is_query(const char *t, size_t len)
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

static int is_system(const char *t, size_t len)
{
	size_t i = 0;
	while (i < len && (unsigned char)t[i] <= ' ') {
		i++;
	}
	return i < len && t[i] == '$';
}

/* Ln and the records' line numbers count a program's lines as mlip-feed
 * counts its file's: `$` lines (a sender's $$, $G polls, $J= jogs) are not
 * program lines, and a new program numbers from 1: the first line after a
 * program ended (its END given) once it ended by M2/M30 or the machine came
 * to rest (a sender's next file; a sender that merely paused mid-file while
 * the machine still runs keeps counting). */
static void count_line(void)
{
	if (!S.st.open && S.st.programs != S.ln_programs &&
	    (grbl_stream_ended(&S.st) || S.cs.state == MLIP_STATE_IDLE)) {
		S.lineno = 0;
		S.ln_programs = S.st.programs;
	}
	S.lineno++;
}

/* The next complete line, if nothing holds it back. */
void process_lines(void)
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
		if (!is_system(l.text, l.len)) {
			count_line();
		}
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
