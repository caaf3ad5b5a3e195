/*
 * controller.c - one period of the real-time controller: commands in, blocks
 * in, one interpolation step, frames out, status published.
 *
 * It drives the planner exactly as mlip-sim does (the ingest rule of
 * planner.h): a program's records are taken without moving until the
 * look-ahead is full or the program's END is in (the pre-read, a bounded
 * number per period), then at most MLIP_INGEST_PER_PERIOD per period before
 * each step. So the setpoints sent equal the simulator's for the same program
 * and machine, whatever the timing, as long as the feeder keeps ahead.
 * Nothing here allocates, prints, locks or blocks.
 */
#include <errno.h>
#include <math.h>
#include <string.h>
#include <unistd.h>

#include "rt.h"

static struct mlip_ring_rec recs[MLIP_PREREAD_PER_PERIOD];
static struct mlip_block blocks[MLIP_PREREAD_PER_PERIOD];
static struct mlip_can_frame frames[2 * MLIP_MAX_AXES + 2];

int mlip_controller_init(struct mlip_controller *c, struct mlip_planner *p,
                         const struct mlip_machine *m, const struct mlip_can_config *can,
                         mlip_strategy st, uint32_t lookahead, struct mlip_ring *ring,
                         struct mlip_canio *io)
{
	memset(c, 0, sizeof(*c));
	c->planner = p;
	c->ring = ring;
	c->can = io;
	c->m = m;
	for (int k = 0; k < m->n_axes; k++) {
		c->pos[k] = m->axis[k].home;
	}
	if (mlip_planner_init(p, m, st, lookahead, c->pos) != MLIP_OK) {
		return -EINVAL;
	}
	if (can != NULL) {
		if (mlip_canenc_init(&c->enc, can, m) != MLIP_OK) {
			return -EINVAL;
		}
		c->encode = 1;
	}
	c->state = MLIP_STATE_IDLE;
	c->pid = (uint32_t)getpid();
	return 0;
}

/* A stop or hold was asked for: measure the path to rest (published as the
 * status' stop_*). A stop asked while one is being measured is the same. */
static void brake_begin(struct mlip_controller *c)
{
	if (!c->braking) {
		c->braking = 1;
		c->brake_mm = 0.0;
		c->brake_periods = 0;
	}
}

/* The period's step from prev to c->pos, while a stop is measured; rs says
 * whether the machine came to rest. */
static void brake_step(struct mlip_controller *c, const double *prev, mlip_run_state rs)
{
	double d2 = 0.0;
	for (int k = 0; k < c->m->n_axes; k++) {
		if (c->m->axis[k].kind == MLIP_AXIS_LINEAR) {
			d2 += (c->pos[k] - prev[k]) * (c->pos[k] - prev[k]);
		}
	}
	c->brake_mm += sqrt(d2);
	c->brake_periods++;
	if (rs != MLIP_RUN_MOVING) {
		c->braking = 0;
		c->stop_nm = (uint64_t)(c->brake_mm * 1e6 + 0.5);
		c->stop_periods = c->brake_periods;
		c->stops++;
	}
}

static int32_t apply_command(struct mlip_controller *c, const struct mlip_ring_cmd *cmd)
{
	struct mlip_planner *p = c->planner;
	switch (cmd->op) {
	case MLIP_CMD_OVERRIDE:
		return mlip_planner_set_override(p, (double)cmd->arg);
	case MLIP_CMD_HOLD:
		mlip_planner_hold(p, 1);
		brake_begin(c);
		return MLIP_OK;
	case MLIP_CMD_RESUME:
		if (c->bus_hold) {
			/* held by the bus: only once it has been clean for a while */
			if (c->can->bus_off || c->cycles - c->bus_bad_cycle < MLIP_BUS_CLEAN_PERIODS) {
				return MLIP_E_INVALID;
			}
			c->bus_hold = 0;
		}
		mlip_planner_hold(p, 0);
		c->braking = 0; /* resumed before rest: no stop to measure */
		return MLIP_OK;
	case MLIP_CMD_STOP:
		c->stop_request = 1;
		return MLIP_OK;
	default:
		return MLIP_E_INVALID;
	}
}

/* Stop: decelerate on the path (the planner's controlled stop) and drop the
 * rest of the program, up to its END record. */
static void begin_stop(struct mlip_controller *c)
{
	if (c->state == MLIP_STATE_IDLE && mlip_planner_queued(c->planner) == 0 && !c->preread) {
		/* nothing moving; a program already waiting in the ring is dropped */
		c->discard = mlip_ring_count(c->ring) > 0;
		return;
	}
	mlip_planner_stop(c->planner);
	brake_begin(c);
	c->preread = 0;
	c->discard = !c->end_seen;
	c->end_seen = 0;
	c->state = MLIP_STATE_STOPPING;
}

/* Take up to max records of the current program: END ends the taking. */
static void ingest(struct mlip_controller *c, uint32_t max)
{
	struct mlip_planner *p = c->planner;
	uint32_t n = 0;
	while (n < max && !c->end_seen && mlip_ring_peek(c->ring, &recs[n]) == MLIP_OK) {
		mlip_ring_pop(c->ring, &recs[n]);
		c->blocks_consumed++;
		if (recs[n].flags & MLIP_REC_END) {
			c->end_seen = 1;
			c->end_seq = recs[n].seq;
			c->end_line = recs[n].line;
			break;
		}
		mlip_ring_rec_to_block(&recs[n], &blocks[n]);
		n++;
	}
	if (n > 0) {
		mlip_planner_push_n(p, blocks, n, NULL);
	}
}

/* The ring is empty and no feeder will fill it: none attached, or its
 * heartbeat is older than MLIP_PEER_TIMEOUT_NS. */
static int ring_dry(struct mlip_controller *c)
{
	struct mlip_ring_feeder f;
	return mlip_ring_count(c->ring) == 0 && mlip_ring_feeder_read(c->ring, &f) == MLIP_OK &&
	       (f.pid == 0 || (int64_t)(mlip_now_ns() - f.heartbeat_ns) > MLIP_PEER_TIMEOUT_NS);
}

/* A stopped program's remaining records: drop them, up to its END. A feeder
 * that was stopped may never send that END; every program numbers its
 * records from 1, so a record with seq 1 is the next program: keep it. */
static void discard(struct mlip_controller *c)
{
	struct mlip_ring_rec rec;
	if (ring_dry(c)) {
		c->discard = 0; /* the stopped program's feeder is gone: nothing more will come */
		return;
	}
	for (int i = 0; i < MLIP_PREREAD_PER_PERIOD && mlip_ring_peek(c->ring, &rec) == MLIP_OK; i++) {
		if (rec.seq == 1) {
			c->discard = 0;
			break;
		}
		mlip_ring_pop(c->ring, &rec);
		c->blocks_consumed++;
		if (rec.flags & MLIP_REC_END) {
			c->discard = 0;
			break;
		}
	}
}

/* Encode the period's frames (always: it is part of the period's work) and
 * send them when there is a bus; the send is timed for the latency tool. */
static void send_frames(struct mlip_controller *c, uint32_t cycle)
{
	int n = 0;
	uint32_t sat = 0;
	c->send_ns = 0;
	if (mlip_canenc_encode(&c->enc, cycle, c->pos, frames, (int)(sizeof(frames) / sizeof(frames[0])),
	                       &n, &sat) != MLIP_OK) {
		/* a position beyond the drive's int32 range: never send it */
		if (!c->fault) {
			c->fault = 1;
			begin_stop(c);
		}
		return;
	}
	c->frames_encoded += (uint64_t)n;
	if (c->can == NULL) {
		return;
	}
	uint64_t t0 = mlip_now_ns();
	mlip_canio_poll(c->can);
	for (int i = 0; i < n; i++) {
		if (mlip_canio_send(c->can, &frames[i]) == 0) {
			c->frames_sent++;
		}
	}
	c->send_ns = (int64_t)(mlip_now_ns() - t0);
	/* frames the drives did not get, or a bus that is off: do not go on
	 * blind; hold (decelerate on the path) until the operator resumes on a
	 * recovered bus */
	if (c->can->tx_dropped != c->bus_drops_seen || c->can->bus_off) {
		c->bus_drops_seen = c->can->tx_dropped;
		c->bus_bad_cycle = c->cycles;
		if (!c->bus_hold) {
			c->bus_hold = 1;
			mlip_planner_hold(c->planner, 1);
			brake_begin(c);
		}
	}
}

static void publish(struct mlip_controller *c, const struct mlip_rt_tick *t)
{
	const struct mlip_planner *p = c->planner;
	struct mlip_ring_status s;
	memset(&s, 0, sizeof(s));
	s.heartbeat = t->cycle + 1;
	s.heartbeat_ns = mlip_now_ns();
	if (mlip_planner_queued(p) > 0 && !c->preread) {
		const struct mlip_seg *g = &p->seg[p->tail & (p->cap - 1)];
		s.exec_seq = g->seq;
		s.exec_line = g->line;
	} else {
		s.exec_seq = c->exec_seq;
		s.exec_line = c->exec_line;
	}
	s.state = c->fault ? MLIP_STATE_FAULT : c->state;
	s.reserved = c->pid; /* who the controller is, for refusals and status */
	s.override_pct = (uint32_t)(p->override * 100.0 + 0.5);
	s.overruns = t->overruns;
	s.underruns = c->underruns;
	if (c->can != NULL) {
		s.can_tx_errors = c->can->tx_dropped;
		s.can_bus_errors = c->can->bus_errors;
	}
	s.frames_sent = c->frames_sent;
	s.blocks_consumed = c->blocks_consumed;
	s.stop_nm = c->stop_nm;
	s.stop_periods = c->stop_periods;
	s.stops = c->stops;
	mlip_ring_status_write(c->ring, &s);
}

int mlip_controller_tick(void *ctx, const struct mlip_rt_tick *t)
{
	struct mlip_controller *c = ctx;
	struct mlip_planner *p = c->planner;
	struct mlip_ring_cmd cmd;

	c->cycles = t->cycle + 1;
	if (mlip_ring_cmd_take(c->ring, &cmd) == MLIP_OK) {
		mlip_ring_cmd_done(c->ring, cmd.seq, apply_command(c, &cmd));
	}
	if (c->exit_request && !c->exiting) {
		c->exiting = 1; /* SIGINT/SIGTERM: a controlled stop, then exit */
		c->stop_request = 1;
	}
	if (c->stop_request) {
		c->stop_request = 0;
		begin_stop(c);
	}
	/* blocks in */
	if (c->discard) {
		discard(c);
	} else if ((c->state == MLIP_STATE_IDLE || c->state == MLIP_STATE_STARVED) &&
	           mlip_ring_peek(c->ring, &recs[0]) == MLIP_OK) {
		if (recs[0].seq != 1 && recs[0].seq != c->exec_seq + 1) {
			/* neither a program's start nor the block after the last one
			 * completed here: running it would cut a straight line from
			 * where the machine is to that block's end. Drop that program
			 * (mlip-feed refuses such a --start-seq before sending). */
			c->discard = 1;
			c->refused++;
		} else {
			c->refill = c->state == MLIP_STATE_STARVED && recs[0].seq != 1;
			if (!c->refill) {
				c->exec_seq = 0; /* a new program (a starved one is given up) */
				c->exec_line = 0;
			}
			c->state = MLIP_STATE_RUNNING; /* pre-read before moving (again) */
			c->preread = 1;
			c->end_seen = 0;
		}
	}
	if (c->preread) {
		uint32_t room = mlip_planner_space(p);
		ingest(c, room < MLIP_PREREAD_PER_PERIOD ? room : MLIP_PREREAD_PER_PERIOD);
		/* a program starts when the look-ahead is full or its END is in, as
		 * mlip-sim does; after an underrun, with whatever has come, so that
		 * a slow feeder is not made to wait for a full look-ahead; and when
		 * its feeder died, with what it has (planned to rest, like any
		 * look-ahead): what a killed feeder sent is run, whenever it died */
		if (mlip_planner_space(p) == 0 || c->end_seen ||
		    (c->refill && mlip_ring_count(c->ring) == 0) || ring_dry(c)) {
			c->preread = 0;
		}
	} else if (c->state == MLIP_STATE_RUNNING || c->state == MLIP_STATE_HELD) {
		uint32_t room = mlip_planner_space(p);
		if (!c->end_seen && room > 0 && mlip_ring_count(c->ring) == 0) {
			c->underruns++; /* the feeder is behind: the plan runs to rest */
		}
		ingest(c, room < MLIP_INGEST_PER_PERIOD ? room : MLIP_INGEST_PER_PERIOD);
	}

	/* one step; the pre-read does not move */
	if (!c->preread) {
		double prev[MLIP_MAX_AXES];
		memcpy(prev, c->pos, sizeof(prev));
		mlip_run_state rs = mlip_planner_step(p, c->pos);
		if (c->braking) {
			brake_step(c, prev, rs);
		}
		if (c->state != MLIP_STATE_IDLE && rs == MLIP_RUN_IDLE &&
		    (c->end_seen || c->state == MLIP_STATE_STOPPING)) {
			if (c->end_seen) {
				c->exec_seq = c->end_seq; /* the program is done, at rest */
				c->exec_line = (uint32_t)c->end_line;
			} else {
				c->exec_seq = p->done_seq;
				c->exec_line = p->done_line;
			}
			c->end_seen = 0;
			c->state = MLIP_STATE_IDLE;
		} else if (c->state == MLIP_STATE_RUNNING && rs == MLIP_RUN_IDLE && !c->end_seen) {
			c->state = MLIP_STATE_STARVED; /* underrun: at rest, program unfinished */
			c->exec_seq = p->done_seq;
			c->exec_line = p->done_line;
		} else if (c->state == MLIP_STATE_RUNNING && rs == MLIP_RUN_HELD) {
			c->state = MLIP_STATE_HELD;
		} else if (c->state == MLIP_STATE_HELD && rs == MLIP_RUN_MOVING) {
			c->state = MLIP_STATE_RUNNING;
		}
	}

	if (c->encode) {
		send_frames(c, (uint32_t)t->cycle);
	}
	publish(c, t);
	/* an exit request ends the loop once the machine is at rest */
	return c->exiting && c->state == MLIP_STATE_IDLE && !c->discard;
}
