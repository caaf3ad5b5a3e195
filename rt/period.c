/*
 * period.c - one period of mlip-rt, the system-call side around the pure
 * controller (src/ctl/controller.c, which mlip-sim runs too): inputs in
 * (the clock, the feeder's liveness, the command mailbox, the bus read
 * once, the drives' part from the CANopen master's hooks), the controller,
 * outputs out (its frames sent, the drives' hooks told, the status written,
 * events and setpoints queued for the monitor thread). Nothing here
 * allocates, prints, formats, locks or blocks.
 */
#include <errno.h>
#include <string.h>
#include <unistd.h>

#include "rt.h"

#define LD(p)    __atomic_load_n((p), __ATOMIC_ACQUIRE)
#define ST(p, v) __atomic_store_n((p), (v), __ATOMIC_RELEASE)

#define RX_MAX_DEFAULT 64 /* frames read a period without hooks (error frames only) */

int mlip_period_init(struct mlip_period *p, struct mlip_planner *pl, const struct mlip_machine *m,
                     const struct mlip_ctl_opts *o, struct mlip_ring *ring,
                     const struct mlip_can_port *bus, const struct mlip_period_hooks *hooks)
{
	struct mlip_rt_sample *rec = p->rec;
	uint32_t rec_cap = p->rec_cap;
	memset((char *)p + offsetof(struct mlip_period, ring), 0,
	       sizeof(*p) - offsetof(struct mlip_period, ring));
	p->rec = rec; /* a record buffer given before init stays */
	p->rec_cap = rec_cap;
	if (mlip_ctl_init(&p->core, pl, m, o) != MLIP_OK ||
	    mlip_ring_port_open(&p->rx, ring, 0) != MLIP_OK) {
		return -EINVAL;
	}
	p->ring = ring;
	p->bus = bus;
	if (hooks != NULL) {
		p->hooks = *hooks;
	}
	p->period_ns = (int64_t)(m->period_s * 1e9 + 0.5);
	/* the controller's stall: so late, a period's frames are withheld */
	p->late_ns = (uint64_t)(o->stall_periods ? o->stall_periods : MLIP_STALL_PERIODS_DEFAULT) *
	             (uint64_t)p->period_ns;
	p->pid = (uint32_t)getpid();
	return 0;
}

/* The feeder into in: the ring is fed (a feeder attached and alive,
 * mlip/ipc/peer.h, on its stamp: late or dead, it feeds nothing) and the stop
 * counter when it began. A feeder area mid-update counts as alive (it is
 * being written), and its stop_base as unknown (no program starts). */
static void feeder_in(const struct mlip_ring *r, struct mlip_ctl_in *in)
{
	struct mlip_ring_feeder f;
	if (mlip_ring_feeder_read(r, &f) != MLIP_OK) {
		in->feeder_alive = 1;
		in->feeder_unread = 1;
		return;
	}
	struct mlip_peer_seen s = {f.heartbeat, f.heartbeat_ns, f.pid == 0,
	                           -1}; /* pid 0: it left */
	in->feeder_alive = mlip_peer_judge(&s, NULL, mlip_now_ns(), NULL) == MLIP_PEER_ALIVE;
	in->feeder_stop_base = f.stop_base;
	in->feeder_mdi = f.mdi != 0;
}

static void log_push(struct mlip_period *p, const struct mlip_ctl_event *ev)
{
	uint32_t h = p->log_head;
	if (h - LD(&p->log_tail) >= MLIP_LOG_QUEUE) {
		p->log_lost++;
		return;
	}
	p->log[h % MLIP_LOG_QUEUE] = *ev;
	ST(&p->log_head, h + 1);
}

int mlip_period_log_pop(struct mlip_period *p, struct mlip_ctl_event *ev)
{
	uint32_t t = p->log_tail;
	if (t == LD(&p->log_head)) {
		return 0;
	}
	*ev = p->log[t % MLIP_LOG_QUEUE];
	ST(&p->log_tail, t + 1);
	return 1;
}

/* The period's setpoint with the deadline it went out at: a late period
 * (missed deadlines) leaves a hole in the indices, as on the bus. */
static void rec_push(struct mlip_period *p, const struct mlip_ctl_out *o, uint64_t index)
{
	uint32_t h = p->rec_head;
	if (h - LD(&p->rec_tail) >= p->rec_cap) {
		p->rec_lost++;
		return;
	}
	struct mlip_rt_sample *s = &p->rec[h & (p->rec_cap - 1)];
	s->period = index;
	s->state = o->status.state;
	memcpy(s->pos, o->pos, sizeof(s->pos));
	ST(&p->rec_head, h + 1);
}

int mlip_period_rec_pop(struct mlip_period *p, struct mlip_rt_sample *s)
{
	uint32_t t = p->rec_tail;
	if (p->rec == NULL || t == LD(&p->rec_head)) {
		return 0;
	}
	*s = p->rec[t & (p->rec_cap - 1)];
	ST(&p->rec_tail, t + 1);
	return 1;
}

/* What came on the bus since the last period, bounded: error frames
 * counted (a bus-off noted), data frames to the hooks. */
static void bus_read(struct mlip_period *p, uint64_t cycle, uint64_t now)
{
	struct mlip_can_frame f;
	int max = p->hooks.rx_max > 0 ? p->hooks.rx_max : RX_MAX_DEFAULT;
	for (int k = 0; k < max; k++) {
		int r = p->bus->recv(p->bus->ctx, &f, 0);
		if (r == MLIP_CAN_RX_ERROR) {
			int off = mlip_canbus_error_bus_off(f.id);
			p->can.bus_errors++;
			if (off >= 0) {
				__atomic_store_n(&p->can.bus_off, off, __ATOMIC_RELAXED);
			}
		} else if (r == MLIP_CAN_RX_FRAME) {
			p->can.rx_frames++;
			if (p->hooks.rx != NULL) {
				p->hooks.rx(p->hooks.ctx, &f, cycle, now);
			}
		} else if (r != MLIP_CAN_RX_OTHER) {
			break; /* none left (or a read error: tried again next period) */
		}
	}
}

/* The controller's frames, each sent once without waiting: a refused one
 * is counted (the controller holds the machine on it). */
static void bus_send(struct mlip_period *p, const struct mlip_ctl_out *o)
{
	uint64_t t0 = mlip_now_ns();
	for (int i = 0; i < o->n_frames; i++) {
		int r = p->bus->send(p->bus->ctx, &o->frames[i]);
		if (r == 0) {
			p->can.tx_ok++;
		} else if (r == -EAGAIN || r == -ENOBUFS) {
			p->can.tx_dropped++;
		}
	}
	p->send_ns = (int64_t)(mlip_now_ns() - t0);
}

/* JERK_PLAN = path: the thread's records in the status as a feeder reads
 * them (blocks_consumed from the program's start on, exec_seq its END once
 * ended), and the program the controller is done with (ended, stopped,
 * dropped or refused at its start) back to the thread. */
static void plan_status(struct mlip_period_plan *pp, const struct mlip_ctl *c, uint32_t prog,
                        struct mlip_ring_status *s)
{
	int ours = prog != 0 && c->ext.last == prog; /* started (or refused) */
	s->blocks_consumed = ours ? LD(&pp->taken) : LD(&pp->taken_base);
	if (ours && c->ext.q == NULL) {
		/* kept once the thread moves on: it resets end_seq to 0 once it
		 * sees done, which may fall between this period's load of prog
		 * and this load (0 then is not this program's END) */
		uint64_t e = LD(&pp->end_seq);
		if (s->reason == MLIP_WHY_END && e != 0) {
			pp->end_shown = e;
		}
		ST(&pp->done, prog);
	}
	if (s->state == MLIP_STATE_IDLE && s->reason == MLIP_WHY_END) {
		s->exec_seq = pp->end_shown;
	}
	if (c->ext.refused != 0 && c->ext.q == NULL && s->state != MLIP_STATE_FAULT &&
	    s->state != MLIP_STATE_ESTOP) {
		/* the refusal applied (FAULT) and left since: the fault's way
		 * out is the controller's (a reset after an E-stop, as for every
		 * fault on the path), the thread follows it */
		ST(&pp->fault_left, c->ext.refused);
	}
}

int mlip_period_tick(void *ctx, const struct mlip_rt_tick *t)
{
	struct mlip_period *p = ctx;
	struct mlip_ctl_out *o = &p->out;
	struct mlip_ring_cmd cmd;
	struct mlip_ctl_in in;
	uint64_t now = p->bus != NULL ? p->bus->now_ns(p->bus->ctx) : mlip_now_ns();

	memset(&in, 0, sizeof(in));
	p->cycles = t->cycle + 1;
	if (p->bus != NULL) {
		bus_read(p, t->cycle, now);
	}
	if (p->hooks.before != NULL) {
		p->hooks.before(p->hooks.ctx, t->cycle, now, &in);
	}
	in.period = t->cycle;
	/* the records queued: the controller's to take; a segment whose indices
	 * are more than a capacity apart is corrupt (it faults on it). With
	 * the planning thread they are its own: the queue instead */
	struct mlip_period_plan *pp = p->plan;
	uint32_t prog = 0;
	if (pp != NULL) {
		/* the refusal first: the program it refused is published before it */
		in.plan_fault = LD(&pp->fault);
		prog = LD(&pp->prog);
		in.plan = prog != 0 ? pp->q : NULL;
		in.plan_prog = prog;
	} else if (mlip_ring_port_view(&p->rx, &in.recs, &in.recs_corrupt) == MLIP_OK) {
		in.recs_corrupt = 0;
	}
	/* deadlines passed unserved: a stall in the last period's work as in
	 * the sleep before this one */
	in.missed = t->missed > UINT32_MAX ? UINT32_MAX : (uint32_t)t->missed;
	in.unsent = p->unsent;
	int have_cmd = mlip_ring_cmd_take(p->ring, &cmd) == MLIP_OK;
	in.cmd = have_cmd ? &cmd : NULL;
	in.stop_requests = mlip_ring_stop_count(p->ring);
	feeder_in(p->ring, &in);
	in.exit_request = p->exit_request != 0;
	in.bus.tx_refused = p->can.tx_dropped;
	in.bus.off = __atomic_load_n(&p->can.bus_off, __ATOMIC_RELAXED);

	mlip_ctl_period(&p->core, &in, o);

	if (pp == NULL) {
		mlip_ring_port_pop_n(&p->rx, o->taken); /* their slots back to the feeder */
	} else {
		plan_status(pp, &p->core, prog, &o->status);
	}
	if (have_cmd) {
		mlip_ring_cmd_done(p->ring, cmd.seq, o->cmd_result);
	}
	p->send_ns = 0;
	/* a stall since this period began (SIGSTOP, a debugger) and these
	 * setpoints are stale: sent now, the drives that stood still meanwhile
	 * would step a period's travel at once. None go out; the controller
	 * rests at the one before (in.unsent) */
	int late =
	    p->bus != NULL && o->n_frames > 0 && p->bus->now_ns(p->bus->ctx) - now > p->late_ns;
	p->unsent = late;
	if (p->bus != NULL && o->n_frames > 0 && !late) {
		bus_send(p, o);
	}
	if (p->hooks.after != NULL) {
		p->hooks.after(p->hooks.ctx, t->cycle, now, o);
	}
	o->status.overruns = t->overruns; /* the loop's count, which also has overruns */
	o->status.heartbeat_ns = mlip_now_ns();
	o->status.reserved = p->pid; /* who the controller is, for refusals and status */
	o->status.frames_sent = p->can.tx_ok;
	o->status.can_tx_errors = p->can.tx_dropped;
	o->status.can_bus_errors = p->can.bus_errors;
	mlip_ring_status_write(p->ring, &o->status);
	for (uint32_t i = 0; i < o->n_events; i++) {
		log_push(p, &o->events[i]);
	}
	if (p->rec != NULL && !p->unsent) {
		rec_push(p, o, t->index);
	}
	return o->done;
}
