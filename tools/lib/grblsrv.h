/*
 * grblsrv.h - the parts of mlip-grbl (tools/mlip-grbl.c), a Grbl 1.1 server
 * for a running mlip-rt, over one state (S): grblproto.c the protocol and
 * flow control, grblreport.c the controller's status and the reports,
 * grblsetting.c the `$` lines, grblfeed.c the streaming; mlip-grbl.c the
 * sockets, the pseudo-terminal, the segment (rt/) and the loop. Not a
 * library: only mlip-grbl links these.
 */
#ifndef MLIP_TOOLS_GRBLSRV_H
#define MLIP_TOOLS_GRBLSRV_H

#include <stddef.h>
#include <stdint.h>

#include "grbl.h"
#include "grblmach.h"
#include "grblstream.h"
#include "mlip/ipc/ring.h"
#include "mlip/machine/config.h"
#include "tooltable.h"

#define PROG          "mlip-grbl"
#define TX_CAP        65536        /* bytes waiting for a client that reads slowly */
#define TX_STATUS_MIN 1024         /* a status report needs this much room (else skipped) */
#define MAX_PEERS     8            /* connections at once (the others are refused) */
#define DEAD_NS       500000000ull /* no controller beat this long: not responding */
#define PTY_CHECK_NS  20000000ull  /* look for a sender on the pseudo-terminal */
#define CMDQ          32           /* real-time commands waiting for the mailbox */

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
	const char *shm_name; /* the controller's segment (its struct mlip_shm: mlip-grbl.c) */
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
	uint32_t lineno;      /* the program's lines received (count_line) */
	uint64_t ln_programs; /* S.st.programs when lineno last restarted */
	uint64_t last_rx_ns;  /* last line byte received */
	uint64_t held_ns;     /* an operator's hold last seen (quiet_end) */
	int status_req;
	int check_mode;
	int err_hold;  /* a refused line: nothing more taken until ~ or reset */
	int hold_idle; /* ! while idle: Hold:0 until the controller says it (held_by) */
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
	uint64_t pushed_seq;        /* last record of the open program in the ring */
	int (*take_producer)(void); /* the producer side's lock on the segment (rt/:
	                               mlip-grbl.c): 0, or a refusal said */
	uint64_t push_hb;           /* the controller's period (its last status) at our last push */
	int program_live;           /* records of ours in the ring or the controller's hands */
	struct mlip_ring_feeder fa;
	struct mlip_ring_status cs; /* the controller's last status */
	int cs_ok;
	uint64_t cs_beat, cs_beat_ns;
	int dead;
	struct cmd q[CMDQ];
	int qn;
	int ov_post;    /* an override value waits for the mailbox (-1: none) */
	uint64_t ov_hb; /* the controller's period when the last one was posted */
	/* the machine's I/O, as mlip-feed takes it from the controller */
	struct mlip_gcode_io io;
	struct mlip_tooltable table; /* --tools: M6, M61, G43 (as mlip-feed --tools) */
	int have_table;
	int z_index;               /* the machine's Z (the tool length offset's axis), or -1 */
	struct grbl_homing homing; /* $22..$25 from --config's HOME_* */
	struct grbl_acc acc;       /* what its manual spindle and coolant do now */
	uint32_t acc_changes;      /* acc.changes last shown */
	/* the controller's own spindle ([SPINDLE] TYPE = cia402): the status is
	 * the source of truth for A:, FS and Ov; 0x99..0x9D go to its override */
	int sp_bus;
	double sp_rpm;       /* commanded, the override in (the last valid status) */
	int sp_ov;           /* its override, percent (idem) */
	int sp_bad;          /* an invalid spindle status was told (once until valid) */
	int sp_post;         /* a spindle override waits for the mailbox (-1: none) */
	int sp_stopped;      /* 0x9E stopped the controller's spindle in this hold */
	uint64_t sp_hb;      /* the controller's period when it was posted */
	char acc_last[8];    /* A: last shown */
	int ovs_last;        /* Ov's spindle value last shown */
	uint32_t prev_state; /* the controller's state before its current one */
	int ov_zero_told;    /* feed override 0 was told in a [MSG] (until it ends) */
	/* a $H or $X waiting for the controller: Grbl answers it when done
	 * and takes no line meanwhile */
	uint32_t await_op;  /* MLIP_CMD_HOME, MLIP_CMD_RESET; 0: none */
	int await_stage;    /* 0 to post, 1 posted (its result), 2 under way */
	uint32_t await_seq; /* its mailbox ticket */
	uint64_t await_hb;  /* the controller's period when it was accepted */
	uint64_t await_ns;
	uint64_t await_t0; /* await_start: a $X waits this long for the axes to stop */
};

extern struct srv S;

/* grblproto.c, grblreport.c, grblsetting.c, grblfeed.c */
uint64_t now_ns(void);
void send_raw(struct peer *p, const char *s, size_t n);
void send_line(struct peer *p, const char *s);
void send_msg(struct peer *p, const char *fmt, ...);
void answer(int code);
void alarm_push(int code, const char *why);
void flush_peer(struct peer *p);
void logf_(const char *fmt, ...);
void cmd_push(uint32_t op, int32_t arg);
void cmd_pump(void);
void stop_post(void);
void rt_cmd(void *ctx, grbl_rt c);
int in_hold(void);
int ctl_holds(void);
int override_zero(void);
int is_query(const char *t, size_t len);
void process_lines(void);
void poll_controller(void);
int at_rest_state(uint32_t s);
int locked_state(uint32_t s);
int quiet_controller(void);
const char *grbl_state(void);
int busy_state(const char *s);
void status_report(void);
void locked_why(char *why, size_t n);
void say_locked(void);
void follow_controller(void);
void await_start(uint32_t op);
void await_end(int code);
void await_pump(void);
void settings_list(void);
int idle_or_alarm(void);
int system_line(const char *t, size_t len);
void beat(void);
void push_records(void);
void push_end_alone(void);
void welcome(void);
void restart_at(const double *pos, int keep_modes);
void resync(int keep_modes);
void soft_reset(void);
void jog_cancel(const char *why);
void jog_done(void);
void soft_limit_alarm(const struct mlip_gcode_error *e);
void say_error(const struct mlip_gcode_error *e, int code);
void refuse_hold(void);
void notices_since(uint32_t before);
int gcode_line(const char *t, size_t len);
int jog_line(const char *t, size_t len, const char *state);
void quiet_end(void);

#endif
