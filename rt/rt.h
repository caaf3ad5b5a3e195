/*
 * rt/rt.h - the real-time runtime around the pure core: the POSIX shared
 * memory segment (ring, status, commands, machine), the one SocketCAN socket,
 * the periodic SCHED_FIFO loop, the period that runs the controller in it,
 * and the CANopen master of the CiA 402 drives.
 *
 * Functions return 0 or -errno and never print; a `why` buffer, when given,
 * receives one line a tool can show. Nothing called from the periodic loop
 * allocates, prints, locks or blocks.
 */
#ifndef MLIP_RT_H
#define MLIP_RT_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#include "mlip/can/canenc.h"
#include "mlip/machine/config.h"
#include "mlip/canopen/drive.h"
#include "mlip/canopen/io401.h"
#include "mlip/ctl/controller.h"
#include "mlip/ipc/peer.h"
#include "mlip/motion/planner.h"
#include "mlip/ipc/ring.h"

#define MLIP_SHM_DEFAULT "/mlip"
uint64_t mlip_now_ns(void); /* CLOCK_MONOTONIC */

/* ---- shared memory (rt/shm.c) ------------------------------------------ */

struct mlip_shm {
	struct mlip_ring *ring;
	void *mem;
	size_t bytes;
	int fd;
	int owner; /* created by us: unlinked on close */
	char name[64];
};

/* Controller side: create (O_EXCL, mode 0600) or take over a stale segment
 * `name` of our own user for machine m with `capacity` records, space
 * reserved (posix_fallocate: -ENOSPC when /dev/shm is full), formatted,
 * prefaulted. Refuses -EBUSY when a live controller already runs on it,
 * -EPERM when the name belongs to another user or is open to every user. */
int mlip_shm_create(struct mlip_shm *s, const char *name, uint32_t capacity,
                    const struct mlip_machine *m, char *why, size_t why_len);
/* The same with gid >= 0: mode 0660 and that group (mlip-rt --shm-group),
 * so its members may feed and command; gid < 0 is mlip_shm_create. */
int mlip_shm_create_group(struct mlip_shm *s, const char *name, uint32_t capacity,
                          const struct mlip_machine *m, long gid, char *why, size_t why_len);
/* Feeder/ctl side: attach to an existing segment, checking magic, layout
 * version and sizes (-ENOENT: no segment; -EPROTO: layout mismatch) and its
 * owner: ourselves, root, or the user the MLIP_SHM_OWNER environment
 * variable names, never an object every user may write (-EPERM). */
int mlip_shm_attach(struct mlip_shm *s, const char *name, char *why, size_t why_len);
void mlip_shm_close(struct mlip_shm *s);
/* 1 when the controller is alive by mlip_peer_judge on its status stamp
 * alone (beat within MLIP_PEER_TIMEOUT_NS); 0 also for no consistent status. */
int mlip_shm_controller_alive(const struct mlip_ring *r);

/* The ring's single producer: a POSIX record lock on the producer cache line
 * of the segment (the kernel drops it when the feeder dies). mlip-feed takes
 * it before it checks its program: 0, or -EBUSY with *holder (0 if unknown)
 * when another process has it, or -errno. */
int mlip_shm_feeder_lock(struct mlip_shm *s, int32_t *holder);
/* The pid of the process holding the producer lock (a feeder checking or
 * sending its program), 0 when none. */
int32_t mlip_shm_feeder_holder(const struct mlip_shm *s);

/* ---- peers (rt/liveness.c; the rule is mlip/ipc/peer.h) ------------------------ */

/* 1 when process pid exists and is not a zombie (EPERM counts: another
 * user's); 0 for pid 0 or a process gone. Reads /proc: not for the loop. */
int mlip_peer_process(uint32_t pid);
/* Judge s (read just now) at the current time, asking whether process pid
 * is there only when the verdict depends on it (s->process is set), and
 * record the read in w (may be NULL: the stamp alone). */
mlip_peer_verdict mlip_peer_check(struct mlip_peer_seen *s, uint32_t pid, struct mlip_peer_watch *w,
                                  int64_t *quiet_ns);
/* A feeder area judged on its stamp and its process (pid 0: it left). */
mlip_peer_verdict mlip_peer_feeder(const struct mlip_ring_feeder *f);

/* ---- CAN (rt/canbus.c): the one socket ------------------------------------ */

/* How the period and the CANopen master reach the bus: a SocketCAN socket
 * (mlip_canbus_port) or, in the unit tests, a scripted peer. */
enum {
	MLIP_CAN_RX_NONE = 0, /* nothing within the time given */
	MLIP_CAN_RX_FRAME,    /* a data frame */
	MLIP_CAN_RX_ERROR,    /* an error frame: f->id is its class (mlip_canbus_error_bus_off) */
	MLIP_CAN_RX_OTHER     /* something else (a remote request, a malformed read): skip it */
};

struct mlip_can_port {
	void *ctx;
	int (*send)(void *ctx, const struct mlip_can_frame *f); /* 0 or -errno, never waits */
	/* one frame (MLIP_CAN_RX_*) within timeout_ns (0: do not wait), or -errno */
	int (*recv)(void *ctx, struct mlip_can_frame *f, int64_t timeout_ns);
	uint64_t (*now_ns)(void *ctx);
};

/* identifiers a socket receives: per axis SDO answer, heartbeat, EMCY,
 * TPDO1, TPDO2 (touch probe), TPDO3 (digital inputs); the I/O module's and
 * the spindle drive's 4 each */
#define MLIP_CANBUS_MAX_IDS (6 * MLIP_MAX_AXES + 8)

struct mlip_canbus {
	int fd;
	int fd_frames; /* CAN FD enabled on the socket */
	char ifname[16];
};

/* Check the interface with libsocketcan outside the loop: exists, is up, its
 * state when the driver reports one (vcan does not). *info gets a line. */
int mlip_canbus_check(const char *ifname, char *info, size_t info_len);
/* A raw socket bound to ifname, non-blocking, receiving the standard
 * identifiers rx_ids[0..n_ids) (at most MLIP_CANBUS_MAX_IDS; none: error
 * frames only) and every error frame. */
int mlip_canbus_open(struct mlip_canbus *bus, const char *ifname, int fd_frames,
                     const uint32_t *rx_ids, int n_ids, char *why, size_t why_len);
/* Send one frame without waiting: 0, -EAGAIN/-ENOBUFS (the queue is full),
 * or another -errno. */
int mlip_canbus_send(struct mlip_canbus *bus, const struct mlip_can_frame *f);
/* One frame (MLIP_CAN_RX_*), waiting up to timeout_ns (0: not at all). */
int mlip_canbus_recv(struct mlip_canbus *bus, struct mlip_can_frame *f, int64_t timeout_ns);
/* An error frame's class: 1 says bus-off, 0 restarted, -1 neither. */
int mlip_canbus_error_bus_off(uint32_t err_class);
/* The bus as a port (its clock: mlip_now_ns). */
void mlip_canbus_port(struct mlip_canbus *bus, struct mlip_can_port *p);
/* Restart after bus-off where the driver supports it (-EOPNOTSUPP on vcan). */
int mlip_canbus_restart(const char *ifname);
void mlip_canbus_close(struct mlip_canbus *bus);

/* ---- the periodic loop (rt/rtloop.c) ------------------------------------- */

struct mlip_rt_opts {
	int64_t period_ns;
	uint64_t first_deadline_ns;
	int priority;    /* SCHED_FIFO priority 1..99; 0: SCHED_OTHER */
	int cpu;         /* pin the thread to this CPU; -1: no pinning */
	int lock_memory; /* mlockall + prefault */
};

/* What one wake-up looked like; passed to the period's work. */
struct mlip_rt_tick {
	uint64_t cycle;       /* 0, 1, 2, ... one per wake-up */
	uint64_t deadline_ns; /* the scheduled wake-up (absolute, monotonic) */
	int64_t latency_ns;   /* actual wake - scheduled, >= 0 */
	int64_t interval_ns;  /* actual wake - previous actual wake (0 first) */
	uint64_t overruns;    /* periods missed or overrun so far */
	/* deadlines passed unserved since the previous period's work began:
	 * those the previous work overran and those this wake-up is late by
	 * (a stall anywhere in the loop, in the work as in the sleep) */
	uint64_t missed;
	/* the last deadline passed at this wake-up, counted from the first:
	 * the previous period's plus 1 plus missed (holes where missed) */
	uint64_t index;
};

/* The period's work: return 0 to go on, non-zero to end the loop. */
typedef int (*mlip_rt_fn)(void *ctx, const struct mlip_rt_tick *t);
/* Called after each period's work with its compute time (for statistics). */
typedef void (*mlip_rt_after_fn)(void *ctx, const struct mlip_rt_tick *t, int64_t compute_ns);

struct mlip_rt_report {
	int fifo;            /* the thread really runs SCHED_FIFO */
	int locked;          /* mlockall succeeded */
	int pinned;          /* CPU affinity set */
	char warnings[1024]; /* what is not real-time and what to change, one per line */
};

/* Lock memory and prefault (call before creating the loop). */
int mlip_rt_prepare(const struct mlip_rt_opts *o, struct mlip_rt_report *rep);
/* Run fn every period in a new thread (SCHED_FIFO when permitted, else a
 * warning and SCHED_OTHER) on an absolute CLOCK_MONOTONIC schedule, until fn
 * returns non-zero or mlip_rt_request_stop(); then join. A wake-up after the
 * next deadline counts as an overrun and the schedule skips ahead: one call
 * of fn per wake-up, never a burst. */
int mlip_rt_run(const struct mlip_rt_opts *o, mlip_rt_fn fn, mlip_rt_after_fn after, void *ctx,
                struct mlip_rt_report *rep);
/* Async-signal-safe: ask the loop to end after the current period. */
void mlip_rt_request_stop(void);
int mlip_rt_stop_requested(void);

/* ---- the period (rt/period.c) ------------------------------------------- */

/* One period of mlip-rt around the pure controller (mlip/ctl/controller.h):
 * the clock, the feeder's liveness, the command mailbox, the bus read once
 * (error frames counted, the rest handed to the hooks), the controller, its
 * frames sent, the status written, and two queues read by an ordinary
 * thread, never by the loop: the events to log and (with a record buffer)
 * the setpoints of every period. */
#define MLIP_LOG_QUEUE 256 /* events; more in one burst are counted as lost */

struct mlip_rt_sample {
	uint64_t period; /* deadlines since the first (holes where missed) */
	uint32_t state;
	double pos[MLIP_MAX_AXES];
};

/* What the CANopen master (rt/drives.c) does in each period, called by the
 * period (never the other way round); cycle is the loop's, now_ns the bus
 * port's clock at the period's start. */
struct mlip_period_hooks {
	void *ctx;
	int rx_max; /* frames read from the bus a period, at most */
	/* a data frame from the bus */
	void (*rx)(void *ctx, const struct mlip_can_frame *f, uint64_t cycle, uint64_t now_ns);
	/* before the controller: the drives' part of its input */
	void (*before)(void *ctx, uint64_t cycle, uint64_t now_ns, struct mlip_ctl_in *in);
	/* after it (its frames sent): what it decided */
	void (*after)(void *ctx, uint64_t cycle, uint64_t now_ns, const struct mlip_ctl_out *out);
};

/* The bus as the loop saw it (written by the loop thread only). */
struct mlip_bus_counts {
	uint64_t tx_ok, tx_dropped; /* the controller's frames: sent, refused by a full queue */
	uint64_t rx_frames;         /* data frames handed to the hooks */
	uint64_t bus_errors;        /* error frames */
	int bus_off;                /* the last error frame said bus-off (atomic: the monitor
	                               thread reads it to restart the controller) */
};

/* [TRAJ] JERK_PLAN = path (tools/rtplan.c): a planning thread owns the
 * ring's records and fills the planned queue; the period passes the
 * controller no record, only the queue (in->plan). Each word is written by
 * one side, with release, and read with acquire. */
struct mlip_period_plan {
	struct mlip_planq *q; /* set before the loop */
	uint32_t prog;        /* thread: the program whose queue has started (0: none) */
	uint32_t fault;       /* thread: the programs it refused so far (in->plan_fault) */
	uint32_t done;        /* period: the last program the controller dropped or ended */
	uint32_t fault_left;  /* period: the last refusal (fault's count) the controller
	                         has left its FAULT for (an E-stop's reset), the queue
	                         dropped: the thread takes programs again */
	uint64_t taken;       /* thread: records taken from the ring so far */
	uint64_t taken_base;  /* thread: ... before the program prog (a refused or
	                         dropped program's at once: no program's to come;
	                         the status's count while none runs) */
	uint64_t end_seq;     /* thread: the END's seq of program prog (0: not taken yet) */
	uint64_t end_shown;   /* period only: the last ended program's, as status exec_seq */
};

struct mlip_period {
	/* set at init (the controller inside is read through out, never directly) */
	struct mlip_ctl core;
	struct mlip_ring *ring;
	struct mlip_ring_port rx;        /* the consumer's side of it */
	const struct mlip_can_port *bus; /* NULL: frames encoded, not sent */
	struct mlip_period_hooks hooks;  /* rx/before/after NULL: none */
	uint32_t pid;                    /* published as status.reserved */
	int64_t period_ns;
	uint64_t late_ns; /* a period's work so long: its frames are withheld */
	/* the one input from outside the loop: SIGINT/SIGTERM/SIGHUP: a stop,
	 * then the loop ends */
	volatile sig_atomic_t exit_request;
	/* results: the last period's output, the periods run, the bus, the
	 * sends' time (latency tool) */
	struct mlip_ctl_out out;
	uint64_t cycles;
	struct mlip_bus_counts can;
	int64_t send_ns;
	int unsent; /* the last period's frames were withheld (late) */
	/* event queue (SPSC: the loop produces, the monitor thread consumes) */
	struct mlip_ctl_event log[MLIP_LOG_QUEUE];
	uint32_t log_head, log_tail;
	uint64_t log_lost;
	/* setpoint queue (SPSC), when rec != NULL; rec_cap a power of two */
	struct mlip_rt_sample *rec;
	uint32_t rec_cap, rec_head, rec_tail;
	uint64_t rec_lost;
	/* JERK_PLAN = path: set after init, before the loop (NULL: the records
	 * are the controller's) */
	struct mlip_period_plan *plan;
};

/* o: strategy, look-ahead, stall periods, [CAN] settings (NULL: none), the
 * drives; bus NULL: no CAN; hooks NULL: none. A record buffer (rec, rec_cap)
 * set before stays. */
int mlip_period_init(struct mlip_period *p, struct mlip_planner *pl, const struct mlip_machine *m,
                     const struct mlip_ctl_opts *o, struct mlip_ring *ring,
                     const struct mlip_can_port *bus, const struct mlip_period_hooks *hooks);
/* The period's work (an mlip_rt_fn, ctx = p). Returns non-zero when a
 * requested stop has completed. */
int mlip_period_tick(void *ctx, const struct mlip_rt_tick *t);
/* Monitor thread: the next event (1) or none (0). */
int mlip_period_log_pop(struct mlip_period *p, struct mlip_ctl_event *ev);
/* Monitor thread: the next recorded setpoint (1) or none (0). */
int mlip_period_rec_pop(struct mlip_period *p, struct mlip_rt_sample *s);

/* ---- CiA 402 drives (rt/drives.c) ------------------------------------------ */

/* Targets kept per drive, by period: a TPDO is judged against the targets
 * sent before the SYNC it answers, so a drive that answers late (the
 * emulated VM) is judged as exactly as a prompt one, up to this lag. */
#define MLIP_DRIVE_HIST 1024 /* periods; a later TPDO is not judged */
#define MLIP_DRIVE_LAG  4    /* targets before that SYNC a position may follow */

struct mlip_drive {
	uint8_t node;
	char letter;
	double counts_per_unit;
	struct mlip_drive_setup setup;
	struct mlip_drive_obs obs;
	int32_t start_counts;             /* position actual at bring-up */
	int32_t targets[MLIP_DRIVE_HIST]; /* target sent in period c at c % MLIP_DRIVE_HIST */
};

enum { MLIP_DRIVES_RUN = 0, MLIP_DRIVES_OFF }; /* the loop runs; it ended, drives disabled */

struct mlip_drives {
	struct mlip_can_port port;
	struct mlip_drives_config cfg;
	const struct mlip_machine *m;
	int n;
	int sp; /* 1: d[n] is a CiA 402 spindle in profile velocity mode ([SPINDLE] TYPE =
	           cia402): brought up, supervised and shut down with the axes */
	struct mlip_drive d[MLIP_MAX_AXES + 1];
	uint64_t hb_next_ns;                      /* the master's next heartbeat */
	void (*log)(void *ctx, const char *line); /* bring-up and shut-down (outside the loop) */
	void *log_ctx;
	/* the loop */
	int phase;      /* MLIP_DRIVES_* */
	uint32_t power; /* the drives' power the controller's last period left (mlip_drive_power) */
	uint32_t mute;  /* drives sent no RPDO: not operation enabled */
	uint64_t rx_frames, rx_malformed;
	struct mlip_ctl_drive_fault new_fault; /* found this period, for the controller */
	/* the first fault (the controller's state and log carry it; kept here
	 * for the exit summary and the tests): `fault` set once, release */
	int fault;
	int fault_drive;
	mlip_drive_fault fault_reason;
	int64_t fault_detail;
	uint64_t fault_cycle;
	/* the in-loop shut-down, as the controller's last period reported it */
	int shutdown_ok;                /* the last disable in order within the timeouts */
	struct mlip_ctl_power shutdown; /* which drive did not confirm which step */
	/* the inputs (issue 18): the CiA 401 I/O module ([IO] NODE; node 0: none)
	 * and the functions mapped on it or on the drives' 0x60FD */
	struct mlip_io_config io_cfg;
	uint32_t di_axes; /* bit k: drive k's digital inputs 0x60FD carry a function:
	                     read in its TPDO3 (io.img.di[k]) */
	/* SDO transfers the controller asks for in the loop (homing): one at a
	 * time, never waited for: the request sent in a period's after hook,
	 * the answers fed as they come, the result to the next period */
	struct {
		uint32_t seq;         /* the request being run (0: none yet) */
		int busy;             /* its answer is awaited */
		struct mlip_sdo s;    /* the transfer */
		uint64_t deadline_ns; /* no answer by then: aborted (timeout) */
		struct mlip_ctl_sdo_res res;
	} sdo;
	uint32_t homing;    /* bit k: drive k runs its homing mode (not supervised for
	                       following error) */
	uint32_t home_axes; /* bit k: axis k has a HOME_METHOD: until homed its position at
	                       bring-up is not judged against the soft limits */
	struct {
		uint8_t node;
		struct mlip_io401_setup setup;
		struct mlip_drive_obs obs;
		struct mlip_io_image img;       /* what the bus said of the inputs */
		uint8_t sent[MLIP_IO_IN_BYTES]; /* the outputs last sent */
		uint64_t sent_ns;               /* when (0: never) */
		uint32_t lost; /* mlip_drive_fault: the module failed (an E-stop); its inputs
		                  are unknown and its TPDOs ignored until it is reconfigured */
		double lost_value;
		uint64_t lost_ns;   /* when (or when a reconfiguration last failed) */
		uint64_t bootup_ns; /* its last boot-up message */
		uint64_t ereset_ns; /* its last EMCY 0000h (error reset: a fault gone) */
		uint64_t hb_count;  /* its heartbeats heard (boot-up messages too) */
		uint64_t rx_frames;
		/* what it is, as read at bring-up: device type 0x1000, vendor-ID
		 * 0x1018:01, product code 0x1018:02 (optional in CiA 301:
		 * has_product 0 when the module has none). A module that comes
		 * back must be this one (rt/iomodule.c) */
		struct {
			uint32_t type, vendor, product;
			int has_product;
		} id;
		/* the module back after a loss (a heartbeat newer than it): NMT
		 * reset communication, its boot-up, the set-up entries written and
		 * read back, its inputs read, NMT start, operational: then `lost` is
		 * cleared (rt/iomodule.c). One SDO at a time, never waited for */
		struct {
			int phase; /* MLIP_IO_RE_*; 0: none */
			int k;     /* the entry (or input byte) being run */
			int readback;
			int busy, done; /* an SDO answer awaited / come */
			struct mlip_sdo s;
			uint32_t abort, value;
			uint64_t t0_ns, deadline_ns;
			struct mlip_sdo_entry e[MLIP_IO401_SETUP_MAX];
			int n;
			uint32_t count, failed; /* reconfigurations done / attempts failed */
			/* back-off: attempts failed in a row, and the heartbeat
			 * (hb_count) the next one waits for */
			uint32_t streak;
			uint64_t retry_hb;
			uint32_t fail_abort; /* the last failed one: abort code (0: timeout) */
			uint16_t fail_index; /* and object */
			uint8_t fail_sub;
			uint8_t fail_reg; /* its error register 0x1001 when that failed it
			                     (a fault it still reports), else 0 */
			/* not the module of bring-up: the object that differs, what it
			 * read and what it read at bring-up; never configured again */
			int wrong;
			uint16_t wrong_index;
			uint8_t wrong_sub;
			uint32_t wrong_got, wrong_want;
		} re;
	} io;
};

/* The steps of the I/O module's reconfiguration after a loss (io.re.phase) */
enum {
	MLIP_IO_RE_NONE,
	MLIP_IO_RE_BOOT,
	MLIP_IO_RE_IDENT,
	MLIP_IO_RE_ERRREG,
	MLIP_IO_RE_SDO,
	MLIP_IO_RE_INPUTS,
	MLIP_IO_RE_START
};

/* The I/O module after a loss (rt/iomodule.c), in the loop's before hook:
 * its reconfiguration stepped on (one frame out at most), then whether it
 * is lost. */
void mlip_io_module_period(struct mlip_drives *ds, uint64_t now);
/* An SDO answer from the module, in the loop's receive hook: fed to the
 * reconfiguration's transfer. */
void mlip_io_module_sdo(struct mlip_drives *ds, const struct mlip_can_frame *f, uint64_t now);

/* The identifiers the master receives from the drives of m (SDO answers,
 * heartbeats, EMCY, TPDO1; TPDO2 of the axes with touch_probe, TPDO3 of the
 * axes in di_axes) and from the I/O module io_node (0: none): the bus'
 * receive filter; returns how many. */
int mlip_drives_rx_ids(const struct mlip_machine *m, uint8_t io_node, uint8_t spindle_node,
                       int touch_probe, uint32_t di_axes, uint32_t *ids, int cap);
/* The axes whose drive's digital inputs 0x60FD carry an input function of
 * cfg (bit k: axis k). */
uint32_t mlip_drives_di_axes(const struct mlip_config *cfg);
/* Check the [DRIVES] settings against the machine (master node, following
 * window in counts, period) and fill ds; log gets one line per step. */
int mlip_drives_init(struct mlip_drives *ds, const struct mlip_config *cfg,
                     const struct mlip_can_port *port, void (*log)(void *, const char *),
                     void *log_ctx, char *why, size_t why_len);
/* Outside the loop: NMT reset communication and boot-up of every drive, the
 * SDO set-up (each write read back), NMT start, CiA 402 up to "operation
 * enabled" (the sequencer of mlip/canopen/cia402.h, by SDO) with 0x607A =
 * position actual; start_pos[] gets the positions in mm (deg), checked
 * against the soft limits. On any error: why names node, object, abort
 * code; the drives are shut down again; -errno. */
int mlip_drives_bringup(struct mlip_drives *ds, double *start_pos, char *why, size_t why_len);
/* The loop's part, as hooks of the period (after the bring-up; the period's
 * controller initialised with opts.drives and drive_state_periods): the
 * drives' frames observed, their supervision (any state but fault is right
 * while the controller's power is not ENABLED), the controller's inputs from
 * them (muted drives, a new fault, statuswords, positions actual), the
 * targets sent kept for the following error, the master's heartbeat. The
 * period ends the loop on exit once the controller is at rest with the
 * drives disabled (the SYNC still running until then). */
void mlip_drives_hooks(struct mlip_drives *ds, struct mlip_period_hooks *h);
/* Outside the loop (the monitor): one line for a power event (MLIP_EV_POWER)
 * with node, axis, controlwords, periods. */
void mlip_drives_power_text(const struct mlip_drives *ds, const struct mlip_ctl_event *e, char *buf,
                            size_t len);
/* Outside the loop, after it: what went wrong in the in-loop shut-down (a
 * drive that did not confirm a step in time), or "" when it was in order. */
void mlip_drives_shutdown_text(const struct mlip_drives *ds, char *buf, size_t len);
/* Outside the loop, by SDO: shutdown (0x0006) to every drive still enabled
 * (after a failed bring-up, or a loop that ended without its shut-down). */
void mlip_drives_disable(struct mlip_drives *ds);
/* On exit: the drives stop watching the master's heartbeat (0x1016:01 = 0)
 * and go to NMT pre-operational (no more PDOs), so that they do not fault
 * when the master's heartbeat stops. */
void mlip_drives_release(struct mlip_drives *ds);

#endif
