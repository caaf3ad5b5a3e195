/*
 * controller.c - the thin, system-call side of the controller's period: the
 * clock, the feeder's liveness, the command mailbox, the CAN send and poll,
 * the status write, and the queues to the monitor thread. Every decision is
 * the pure mlip_ctl_period (src/ctl/controller.c), which mlip-sim runs too.
 * Nothing here allocates, prints, locks or blocks.
 */
#include <errno.h>
#include <string.h>
#include <unistd.h>

#include "rt.h"

#define LD(p)    __atomic_load_n((p), __ATOMIC_ACQUIRE)
#define ST(p, v) __atomic_store_n((p), (v), __ATOMIC_RELEASE)

int mlip_controller_init(struct mlip_controller *c, struct mlip_planner *p,
                         const struct mlip_machine *m, const struct mlip_ctl_opts *o,
                         struct mlip_ring *ring, struct mlip_canio *io)
{
	struct mlip_rt_sample *rec = c->rec;
	uint32_t rec_cap = c->rec_cap;
	memset((char *)c + offsetof(struct mlip_controller, ring), 0,
	       sizeof(*c) - offsetof(struct mlip_controller, ring));
	c->rec = rec; /* a record buffer given before init stays */
	c->rec_cap = rec_cap;
	if (mlip_ctl_init(&c->core, p, m, o, ring) != MLIP_OK) {
		return -EINVAL;
	}
	c->ring = ring;
	c->can = io;
	c->period_ns = (int64_t)(m->period_s * 1e9 + 0.5);
	c->pid = (uint32_t)getpid();
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
}

static void log_push(struct mlip_controller *c, const struct mlip_ctl_event *ev)
{
	uint32_t h = c->log_head;
	if (h - LD(&c->log_tail) >= MLIP_LOG_QUEUE) {
		c->log_lost++;
		return;
	}
	c->log[h % MLIP_LOG_QUEUE] = *ev;
	ST(&c->log_head, h + 1);
}

int mlip_controller_log_pop(struct mlip_controller *c, struct mlip_ctl_event *ev)
{
	uint32_t t = c->log_tail;
	if (t == LD(&c->log_head)) {
		return 0;
	}
	*ev = c->log[t % MLIP_LOG_QUEUE];
	ST(&c->log_tail, t + 1);
	return 1;
}

/* The period's setpoint with the deadline it went out at: a late period
 * (missed deadlines) leaves a hole in the indices, as on the bus. */
static void rec_push(struct mlip_controller *c, const struct mlip_ctl_out *o, uint64_t index)
{
	uint32_t h = c->rec_head;
	if (h - LD(&c->rec_tail) >= c->rec_cap) {
		c->rec_lost++;
		return;
	}
	struct mlip_rt_sample *s = &c->rec[h & (c->rec_cap - 1)];
	s->period = index;
	s->state = o->status.state;
	memcpy(s->pos, o->pos, sizeof(s->pos));
	ST(&c->rec_head, h + 1);
}

int mlip_controller_rec_pop(struct mlip_controller *c, struct mlip_rt_sample *s)
{
	uint32_t t = c->rec_tail;
	if (c->rec == NULL || t == LD(&c->rec_head)) {
		return 0;
	}
	*s = c->rec[t & (c->rec_cap - 1)];
	ST(&c->rec_tail, t + 1);
	return 1;
}

int mlip_controller_tick(void *ctx, const struct mlip_rt_tick *t)
{
	return mlip_controller_period(ctx, t, NULL);
}

int mlip_controller_period(struct mlip_controller *c, const struct mlip_rt_tick *t,
                           const struct mlip_ctl_in *drv)
{
	struct mlip_ctl_out *o = &c->out;
	struct mlip_ring_cmd cmd;
	struct mlip_ctl_in in;

	memset(&in, 0, sizeof(in));
	if (drv != NULL) {
		in.drive_mute = drv->drive_mute;
		memcpy(in.drive_sw, drv->drive_sw, sizeof(in.drive_sw));
		in.drive_fault = drv->drive_fault;
		in.actual_mask = drv->actual_mask;
		memcpy(in.pos_actual, drv->pos_actual, sizeof(in.pos_actual));
	}
	c->cycles = t->cycle + 1;
	in.period = t->cycle;
	/* deadlines passed before this wake-up (the loop counts them in
	 * t->overruns only after this period's work) */
	int64_t late = t->latency_ns / c->period_ns;
	in.missed = late > (int64_t)UINT32_MAX ? UINT32_MAX : (uint32_t)late;
	int have_cmd = mlip_ring_cmd_take(c->ring, &cmd) == MLIP_OK;
	in.cmd = have_cmd ? &cmd : NULL;
	in.stop_requests = mlip_ring_stop_count(c->ring);
	feeder_in(c->ring, &in);
	in.exit_request = c->exit_request != 0;
	if (c->can != NULL) {
		in.can_tx_refused = c->can->tx_dropped;
		in.can_error_frames = c->can->bus_errors;
		in.bus_off = c->can->bus_off;
	}

	mlip_ctl_period(&c->core, &in, o);

	if (have_cmd) {
		mlip_ring_cmd_done(c->ring, cmd.seq, o->cmd_result);
	}
	c->send_ns = 0;
	if (c->can != NULL && o->n_frames > 0) {
		uint64_t t0 = mlip_now_ns();
		mlip_canio_poll(c->can);
		for (int i = 0; i < o->n_frames; i++) {
			if (mlip_canio_send(c->can, &o->frames[i]) == 0) {
				c->frames_sent++;
			}
		}
		c->send_ns = (int64_t)(mlip_now_ns() - t0);
	}
	o->status.overruns = t->overruns; /* the loop's count, which also has overruns */
	o->status.heartbeat_ns = mlip_now_ns();
	o->status.reserved = c->pid; /* who the controller is, for refusals and status */
	o->status.frames_sent = c->frames_sent;
	if (c->can != NULL) {
		o->status.can_tx_errors = c->can->tx_dropped;
		o->status.can_bus_errors = c->can->bus_errors;
	}
	mlip_ring_status_write(c->ring, &o->status);
	for (uint32_t i = 0; i < o->n_events; i++) {
		log_push(c, &o->events[i]);
	}
	if (c->rec != NULL) {
		if (t->cycle == 0) {
			c->first_deadline_ns = t->deadline_ns;
		}
		rec_push(c, o,
		         (t->deadline_ns - c->first_deadline_ns) / (uint64_t)c->period_ns +
		             in.missed);
	}
	return o->done;
}
