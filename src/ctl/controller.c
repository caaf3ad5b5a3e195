/*
 * controller.c - the controller's period, pure (mlip/ctl/controller.h): commands
 * in, records in (validated), one interpolation step, frames encoded, status
 * and events out. The ingest rule of planner.h lives here once: records are
 * taken without moving until the look-ahead is full, the program's END is in
 * or an event (dwell, pause) is next (the pre-read, MLIP_PREREAD_PER_PERIOD a
 * period), then at most MLIP_INGEST_PER_PERIOD a period before each step.
 * An event is taken only when the planner is at rest at the end of the move
 * before it: the planner always plans its newest block to rest, so stopping
 * the ingest in front of an event is all it takes.
 */
#include "mlip/ctl/controller.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

#include "mlip/canopen/drive.h"

static void progress(const struct mlip_ctl *c, uint64_t *seq, uint32_t *line);

static void emit(struct mlip_ctl *c, struct mlip_ctl_out *out, uint32_t kind, uint32_t from,
                 const struct mlip_ctl_reason *r)
{
	if (out->n_events < MLIP_CTL_MAX_EVENTS) {
		struct mlip_ctl_event *e = &out->events[out->n_events++];
		e->kind = kind;
		e->from = from;
		e->state = c->state;
		e->r = *r;
		e->period = c->period;
		progress(c, &e->exec_seq, &e->exec_line);
	}
}

static struct mlip_ctl_reason reason(uint32_t why, uint64_t seq, uint32_t line)
{
	struct mlip_ctl_reason r = {.why = why, .seq = seq, .line = line};
	return r;
}

/* Every change of state goes through here: named, with its reason. */
static void go(struct mlip_ctl *c, struct mlip_ctl_out *out, uint32_t state,
               struct mlip_ctl_reason r)
{
	uint32_t from = c->state;
	if (from == state && c->why.why == r.why) {
		return;
	}
	c->state = state;
	c->why = r;
	emit(c, out, MLIP_EV_STATE, from, &r);
}

mlip_status mlip_ctl_init(struct mlip_ctl *c, struct mlip_planner *p, const struct mlip_machine *m,
                          const struct mlip_ctl_opts *o)
{
	memset(c, 0, offsetof(struct mlip_ctl, blocks));
	c->planner = p;
	c->m = *m;
	if (m->n_axes < 2 || m->n_axes > MLIP_MAX_AXES) {
		return MLIP_E_INVALID;
	}
	for (int k = 0; k < m->n_axes; k++) {
		c->pos[k] = c->prog.start[k] = m->axis[k].home;
	}
	if (mlip_planner_init(p, &c->m, o->strategy, o->lookahead, c->pos) != MLIP_OK) {
		return MLIP_E_INVALID;
	}
	if (o->can != NULL) {
		if (mlip_canenc_init(&c->enc, o->can, &c->m) != MLIP_OK) {
			return MLIP_E_INVALID;
		}
		c->encode = 1;
		c->enc.rpdo_controlword = o->drives ? 1 : 0;
	} else if (o->drives) {
		return MLIP_E_INVALID; /* drives without frames to send them */
	}
	c->stall_periods = o->stall_periods ? o->stall_periods : MLIP_STALL_PERIODS_DEFAULT;
	c->state = MLIP_STATE_IDLE;
	c->drives = o->drives != 0;
	/* enabled by the bring-up */
	mlip_402_seq_init(&c->power.seq, c->drives ? MLIP_POWER_ENABLED : MLIP_POWER_NONE,
	                  o->drive_state_periods ? o->drive_state_periods : 1000, 0);
	return MLIP_OK;
}

/* ---- the records of this period: in->recs, taken from the front ---------- */

/* A copy of the next record not taken yet (a queue in shared memory may be
 * written by a hostile feeder: what is checked is this copy). */
static int rx_peek(const struct mlip_ctl *c, struct mlip_ring_rec *rec)
{
	const struct mlip_rec_view *v = c->rx.view;
	uint32_t i = c->rx.taken;
	if (c->rx.corrupt) {
		return 0; /* nothing is read from that queue again */
	}
	if (i < v->len[0]) {
		*rec = v->span[0][i];
		return 1;
	}
	i -= v->len[0];
	if (i < v->len[1]) {
		*rec = v->span[1][i];
		return 1;
	}
	return 0;
}

/* Take it (the caller pops out->taken records after the period). */
static void rx_pop(struct mlip_ctl *c)
{
	c->rx.taken++;
	c->counts.blocks_consumed++;
}

static uint32_t rx_count(const struct mlip_ctl *c)
{
	return c->rx.corrupt ? 0 : c->rx.view->len[0] + c->rx.view->len[1] - c->rx.taken;
}

/* ---- records ------------------------------------------------------------ */

static mlip_status bad(struct mlip_ctl_reason *why, const struct mlip_ring_rec *rec, uint32_t field,
                       double value)
{
	if (why != NULL) {
		why->why = MLIP_WHY_BAD_RECORD;
		why->field = field;
		why->seq = rec->seq;
		why->line = rec->line;
		why->value = value;
	}
	return MLIP_E_RANGE;
}

/* Bounded: a few comparisons per axis. NaN fails every comparison, so each
 * test is written to pass only on a good value. */
mlip_status mlip_ctl_check_record(const struct mlip_machine *m, const struct mlip_ring_rec *rec,
                                  uint64_t expect_seq, struct mlip_ctl_reason *why)
{
	if (expect_seq != 0 && rec->seq != expect_seq) {
		mlip_status st = bad(why, rec, MLIP_FIELD_SEQ, (double)rec->seq);
		if (why != NULL) {
			why->seq = expect_seq; /* the record in that place; value: its seq */
		}
		return st;
	}
	if (rec->type >= MLIP_REC_TYPES) {
		return bad(why, rec, MLIP_FIELD_TYPE, (double)rec->type);
	}
	if ((rec->flags & ~MLIP_REC_FLAGS) != 0) {
		return bad(why, rec, MLIP_FIELD_FLAGS, (double)rec->flags);
	}
	if (rec->type == MLIP_REC_DWELL &&
	    !(rec->dwell_s >= 0.0 && rec->dwell_s <= MLIP_CTL_DWELL_MAX_S)) {
		return bad(why, rec, MLIP_FIELD_DWELL, rec->dwell_s);
	}
	if (rec->type != MLIP_REC_MOVE) {
		return MLIP_OK;
	}
	for (int k = 0; k < m->n_axes; k++) {
		double x = rec->target[k];
		if (!(x >= m->axis[k].min_limit && x <= m->axis[k].max_limit)) {
			return bad(why, rec, MLIP_FIELD_TARGET + (uint32_t)k, x);
		}
	}
	if ((rec->flags & MLIP_REC_RAPID)
	        ? !(rec->feed_mm_s >= 0.0 && rec->feed_mm_s <= MLIP_CTL_FEED_MAX_MM_S)
	        : !(rec->feed_mm_s > 0.0 && rec->feed_mm_s <= MLIP_CTL_FEED_MAX_MM_S)) {
		return bad(why, rec, MLIP_FIELD_FEED, rec->feed_mm_s);
	}
	if (!(rec->tol_mm >= 0.0 && rec->tol_mm <= 1e6)) {
		return bad(why, rec, MLIP_FIELD_TOL, rec->tol_mm);
	}
	return MLIP_OK;
}

static int is_event(const struct mlip_ring_rec *rec)
{
	return rec->type == MLIP_REC_DWELL || rec->type == MLIP_REC_PAUSE ||
	       rec->type == MLIP_REC_OPTIONAL_PAUSE;
}

/* The ring is empty and nothing will fill it. */
static int ring_dry(struct mlip_ctl *c, const struct mlip_ctl_in *in)
{
	return !in->feeder_alive && rx_count(c) == 0;
}

/* A bad record: take nothing more. The look-ahead already plans the last
 * good block to rest; the rest of the program is dropped. */
static void fault(struct mlip_ctl *c, struct mlip_ctl_out *out, struct mlip_ctl_reason r)
{
	c->prog.bad = 1;
	c->prog.discard = 1;
	if (c->state != MLIP_STATE_RUNNING && c->state != MLIP_STATE_HELD) {
		/* not moving (pre-read, a wait): what was pre-read never starts */
		mlip_planner_stop(c->planner);
		c->wait.dwell_left = 0;
	}
	go(c, out, MLIP_STATE_FAULT, r);
}

/* Take up to max records of the current program, stopping in front of an
 * event (it is taken at rest) and after END. Returns 1 when an event is next. */
static int ingest(struct mlip_ctl *c, struct mlip_ctl_out *out, uint32_t max)
{
	uint32_t n = 0;
	int event_next = 0;
	struct mlip_ring_rec rec;
	while (n < max && c->prog.end.seq == 0 && !c->prog.bad && rx_peek(c, &rec)) {
		struct mlip_ctl_reason r;
		if (mlip_ctl_check_record(&c->m, &rec, c->prog.next_seq, &r) != MLIP_OK) {
			fault(c, out, r);
			break;
		}
		if (is_event(&rec)) {
			if (rec.type == MLIP_REC_OPTIONAL_PAUSE && !c->op.optional_stop) {
				rx_pop(c); /* M1 with the switch off: no stop */
				c->prog.next_seq++;
				continue;
			}
			event_next = 1;
			c->wait.event = rec;
			break;
		}
		rx_pop(c);
		c->prog.next_seq++;
		if (rec.type == MLIP_REC_END) {
			c->prog.end.seq = rec.seq;
			c->prog.end.line = rec.line;
			break;
		}
		mlip_ring_rec_to_block(&rec, &c->blocks[n]);
		n++;
	}
	if (n > 0) {
		mlip_status err = MLIP_OK;
		size_t got = mlip_planner_push_n(c->planner, c->blocks, n, &err);
		if (got < n) {
			/* validated, so only a planner refusal (a stop raced it) */
			struct mlip_ctl_reason r =
			    reason(MLIP_WHY_BAD_RECORD, c->blocks[got].seq, c->blocks[got].line);
			r.value = (double)err;
			fault(c, out, r);
		}
	}
	return event_next;
}

/* The pre-read of a program (or a refill) is complete: move. */
static int preread_done(struct mlip_ctl *c, const struct mlip_ctl_in *in, int event_next)
{
	return mlip_planner_space(c->planner) == 0 || c->prog.end.seq != 0 || event_next ||
	       c->prog.bad || (c->prog.refill && rx_count(c) == 0) || ring_dry(c, in);
}

/* A stopped program's remaining records: drop them, up to its END. A feeder
 * that was stopped may never send that END; every program numbers its
 * records from 1, so a record with seq 1 is the next program: keep it. */
static void discard(struct mlip_ctl *c, const struct mlip_ctl_in *in)
{
	struct mlip_ring_rec rec;
	if (ring_dry(c, in)) {
		c->prog.discard = 0; /* the stopped program's feeder is gone */
		return;
	}
	for (int i = 0; i < MLIP_PREREAD_PER_PERIOD && rx_peek(c, &rec); i++) {
		if (rec.seq == 1 && !c->prog.bad && !c->prog.discard_waiting) {
			c->prog.discard = 0;
			break;
		}
		c->prog.discard_waiting = 0; /* its first record: the rest is its own */
		rx_pop(c);
		if (rec.type == MLIP_REC_END) {
			c->prog.discard = 0;
			break;
		}
	}
}

/* ---- stops -------------------------------------------------------------- */

static void brake_begin(struct mlip_ctl *c);

/* A CiA 402 drive faulted (rt/drives.c's supervision): never go on blind.
 * Every axis stops on the path (the planner's stop: the other drives follow
 * it to rest; the faulted drive, muted by rt/, is in its own fault reaction),
 * nothing more of the program is taken, and the state says which node, which
 * event, in which block and line. The first drive fault stays the reason. */
static void drive_fault(struct mlip_ctl *c, struct mlip_ctl_out *out,
                        const struct mlip_ctl_drive_fault *f)
{
	struct mlip_ctl_reason r = reason(MLIP_WHY_DRIVE, 0, 0);
	progress(c, &r.seq, &r.line);
	r.field = f->event;
	r.node = f->node;
	r.value = f->value;
	c->drive_faulted = 1;
	if (mlip_planner_queued(c->planner) > 0) {
		mlip_planner_stop(c->planner);
		brake_begin(c);
	}
	c->wait.dwell_left = 0;
	c->prog.bad = 1;     /* nothing more is taken */
	c->prog.discard = 1; /* the rest of the program is dropped */
	go(c, out, MLIP_STATE_FAULT, r);
}

/* A stop or hold was asked for: measure the path to rest (status stop_*). */
static void brake_begin(struct mlip_ctl *c)
{
	if (!c->brake.on) {
		c->brake.on = 1;
		c->brake.mm = 0.0;
		c->brake.periods = 0;
	}
}

static void brake_step(struct mlip_ctl *c, const double *prev, mlip_run_state rs)
{
	double d2 = 0.0;
	for (int k = 0; k < c->m.n_axes; k++) {
		if (c->m.axis[k].kind == MLIP_AXIS_LINEAR) {
			d2 += (c->pos[k] - prev[k]) * (c->pos[k] - prev[k]);
		}
	}
	c->brake.mm += sqrt(d2);
	c->brake.periods++;
	if (rs != MLIP_RUN_MOVING) {
		c->brake.on = 0;
		c->brake.last_nm = (uint64_t)(c->brake.mm * 1e6 + 0.5);
		c->brake.last_periods = c->brake.periods;
		c->brake.count++;
	}
}

/* Stop: decelerate on the path and drop the rest of the program. */
static void begin_stop(struct mlip_ctl *c, struct mlip_ctl_out *out, uint32_t why)
{
	if (c->state == MLIP_STATE_IDLE && mlip_planner_queued(c->planner) == 0) {
		/* nothing moving; a program already waiting in the ring (for the
		 * drives to be enabled) is dropped, its first record too */
		c->prog.discard = rx_count(c) > 0;
		c->prog.discard_waiting = c->prog.discard;
		return;
	}
	/* in a dwell or a pause the wait is not done: the block completed is
	 * the one before it (the pre-read after it never moved) */
	c->wait.stopped = c->state == MLIP_STATE_DWELLING || c->state == MLIP_STATE_PAUSED;
	mlip_planner_stop(c->planner);
	c->wait.dwell_left = 0;
	c->hold.op = 0; /* the planner's stop ends a hold too */
	if (c->state == MLIP_STATE_FAULT) {
		return; /* the fault stays the reason */
	}
	brake_begin(c);
	c->prog.discard = c->prog.end.seq == 0;
	c->prog.end.seq = 0;
	go(c, out, MLIP_STATE_STOPPING, reason(why, 0, 0));
}

static int32_t apply_command(struct mlip_ctl *c, struct mlip_ctl_out *out,
                             const struct mlip_ring_cmd *cmd)
{
	struct mlip_planner *p = c->planner;
	switch (cmd->op) {
	case MLIP_CMD_OVERRIDE:
		return mlip_planner_set_override(p, (double)cmd->arg);
	case MLIP_CMD_HOLD:
		mlip_planner_hold(p, 1);
		c->hold.op = 1;
		brake_begin(c);
		return MLIP_OK;
	case MLIP_CMD_RESUME:
		if (c->state == MLIP_STATE_FAULT) {
			return MLIP_E_INVALID;
		}
		if (c->hold.bus) {
			/* held by the bus: only once it has been clean for a while */
			if (c->period - c->hold.bus_bad_period < MLIP_BUS_CLEAN_PERIODS) {
				return MLIP_E_INVALID;
			}
			c->hold.bus = 0;
		}
		c->hold.stall = 0;
		c->hold.op = 0;
		mlip_planner_hold(p, 0);
		c->brake.on = 0; /* resumed before rest: no stop to measure */
		c->wait.resume = c->state == MLIP_STATE_PAUSED; /* and a pause ends */
		return MLIP_OK;
	case MLIP_CMD_STOP:
		begin_stop(c, out, MLIP_WHY_STOP);
		return MLIP_OK;
	case MLIP_CMD_OPTIONAL_STOP:
		if (cmd->arg != 0 && cmd->arg != 1) {
			return MLIP_E_RANGE;
		}
		c->op.optional_stop = cmd->arg;
		return MLIP_OK;
	default:
		return MLIP_E_INVALID;
	}
}

/* ---- waits: dwell, pause ------------------------------------------------- */

/* At rest with an event record next: take it. */
static void take_event(struct mlip_ctl *c, struct mlip_ctl_out *out,
                       const struct mlip_ring_rec *rec)
{
	rx_pop(c);
	c->prog.next_seq++;
	c->wait.at.seq = rec->seq;
	c->wait.at.line = rec->line;
	c->wait.resume = 0;
	struct mlip_ctl_reason r = reason(MLIP_WHY_DWELL, rec->seq, rec->line);
	if (rec->type == MLIP_REC_DWELL) {
		/* to the period: round(dwell / T) periods at rest */
		c->wait.dwell_left = (uint64_t)floor(rec->dwell_s / c->m.period_s + 0.5);
		r.value = rec->dwell_s;
		go(c, out, MLIP_STATE_DWELLING, r);
	} else if (rec->type == MLIP_REC_PAUSE || c->op.optional_stop) {
		r.why = rec->type == MLIP_REC_PAUSE ? MLIP_WHY_PAUSE : MLIP_WHY_OPTIONAL_PAUSE;
		go(c, out, MLIP_STATE_PAUSED, r);
	} else {
		c->wait.dwell_left = 0; /* M1, switched off since it was reached: no wait */
		r.why = MLIP_WHY_OPTIONAL_PAUSE;
		go(c, out, MLIP_STATE_DWELLING, r);
	}
}

/* The wait is over: the event is done; move on once the pre-read is. */
static void end_wait(struct mlip_ctl *c, struct mlip_ctl_out *out, const struct mlip_ctl_in *in,
                     int event_next, uint32_t why)
{
	c->prog.exec.seq = c->wait.at.seq;
	c->prog.exec.line = c->wait.at.line;
	c->prog.refill = 1;
	go(c, out, preread_done(c, in, event_next) ? MLIP_STATE_RUNNING : MLIP_STATE_PREREAD,
	   reason(why, c->wait.at.seq, c->wait.at.line));
}

/* Take the event and end a wait of 0 periods at once. */
static void start_event(struct mlip_ctl *c, struct mlip_ctl_out *out, const struct mlip_ctl_in *in,
                        const struct mlip_ring_rec *rec)
{
	take_event(c, out, rec);
	if (c->state == MLIP_STATE_DWELLING && c->wait.dwell_left == 0) {
		end_wait(c, out, in, 0, MLIP_WHY_DWELL_DONE);
	}
}

/* ---- the drives' power (CiA 402, opts.drives) ------------------------------ */

/* The first axis beyond a soft limit, or -1. */
static int beyond_limit(const struct mlip_ctl *c)
{
	for (int k = 0; k < c->m.n_axes; k++) {
		const struct mlip_axis *a = &c->m.axis[k];
		if (!(c->pos[k] >= a->min_limit && c->pos[k] <= a->max_limit)) {
			return k;
		}
	}
	return -1;
}

/* At rest where the drives are to be disabled: after a program or a stop
 * (not the idle of a fresh start: the bring-up enabled them to hold the
 * start position), in a fault, or on exit. */
static int power_rest(const struct mlip_ctl *c)
{
	/* the last setpoint sent twice: every drive has applied it at a SYNC
	 * before it is told to disable operation */
	if (mlip_planner_queued(c->planner) > 0 || mlip_planner_moving(c->planner) ||
	    c->power.still_periods < 2) {
		return 0;
	}
	return c->state == MLIP_STATE_FAULT || c->op.exiting ||
	       (c->state == MLIP_STATE_IDLE && c->why.why != MLIP_WHY_NONE);
}

/* A step of the drives' power ended: the event, with the drive that did
 * not confirm it in time (its node and statusword). */
static void power_event(struct mlip_ctl *c, struct mlip_ctl_out *out,
                        const struct mlip_402_change *ch)
{
	struct mlip_ctl_reason r = reason(MLIP_WHY_NONE, ch->in_sequence, 0);
	r.value = (double)ch->in_step;
	if (ch->late >= 0) {
		r.node = (uint32_t)c->m.axis[ch->late].can_node;
		r.field = ch->late_sw;
	}
	if (out->n_events < MLIP_CTL_MAX_EVENTS) {
		struct mlip_ctl_event *e = &out->events[out->n_events++];
		e->kind = MLIP_EV_POWER;
		e->from = ch->from;
		e->state = ch->to;
		e->r = r;
		e->period = c->period;
		progress(c, &e->exec_seq, &e->exec_line);
	}
}

/* One period of the drives' power, after the step (the sequencer of
 * mlip/canopen/cia402.h, all drives in step): never out of ENABLED while the
 * planner moves, never moving out of it (records are taken only when
 * ENABLED). A program waiting enables them (from where they stand, inside
 * the soft limits); at rest after it, a stop or a fault, or on exit, they are
 * disabled. Enabling not confirmed in time is a fault naming the drive. */
static void power_period(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out)
{
	uint32_t power = c->power.seq.step;
	int want = c->power.want;
	struct mlip_402_change ch;

	if (power == MLIP_POWER_OFF || power == MLIP_POWER_SWITCHING_ON) {
		/* no holding torque: the commanded position is where the drives are */
		for (int k = 0; k < c->m.n_axes; k++) {
			if (in->drives.actual_mask & (1u << k)) {
				c->pos[k] = in->drives.pos_actual[k];
			}
		}
		mlip_planner_rest_at(c->planner, c->pos);
		int k = want ? beyond_limit(c) : -1;
		if (k >= 0) {
			int32_t counts = 0;
			mlip_can_counts(c->pos[k], c->m.axis[k].counts_per_unit, &counts);
			struct mlip_ctl_drive_fault f = {MLIP_DRIVE_BEYOND_LIMIT,
			                                 (uint32_t)c->m.axis[k].can_node,
			                                 (double)counts};
			drive_fault(c, out, &f);
			want = 0;
		}
	} else if (power == MLIP_POWER_ENABLED) {
		want = !power_rest(c);
	}
	if (!mlip_402_seq_run(&c->power.seq, want ? MLIP_POWER_ENABLED : MLIP_POWER_OFF,
	                      in->drives.sw, c->m.n_axes, in->drives.mute, c->period, &ch)) {
		return;
	}
	if (ch.failed) {
		/* not switched on or not enabled in time: a fault, the program is
		 * dropped, the drives go down again; nothing has moved */
		struct mlip_ctl_drive_fault f = {
		    ch.from == MLIP_POWER_SWITCHING_ON ? MLIP_DRIVE_NOT_SWITCHED_ON
		                                       : MLIP_DRIVE_NOT_ENABLED,
		    (uint32_t)c->m.axis[ch.late].can_node, (double)ch.late_sw};
		drive_fault(c, out, &f);
	}
	power_event(c, out, &ch);
}

/* ---- the period ----------------------------------------------------------- */

/* Blocks in, by state. */
static void blocks_in(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out)
{
	struct mlip_ring_rec first, *head = &first;
	int have = rx_peek(c, head);

	if (c->prog.discard) {
		discard(c, in);
		return;
	}
	switch (c->state) {
	case MLIP_STATE_IDLE:
	case MLIP_STATE_STARVED:
		if (!have) {
			return;
		}
		if (head->seq != 1 && head->seq != c->prog.exec.seq + 1) {
			/* neither a program's start nor the block after the last one
			 * completed here: running it would cut a straight line from
			 * where the machine is to that block's end. Drop that program
			 * (mlip-feed refuses such a --start-seq before sending). */
			struct mlip_ctl_reason r = reason(MLIP_WHY_NONE, head->seq, head->line);
			r.value = (double)(c->prog.exec.seq + 1);
			emit(c, out, MLIP_EV_REFUSED, c->state, &r);
			c->prog.discard = 1;
			c->counts.refused++;
			return;
		}
		if (in->feeder_unread) {
			return; /* whose program this is: known next period */
		}
		if (mlip_ring_stop_after(c->op.stop_seen, in->feeder_stop_base)) {
			/* a stop came after this program's feeder began (during its
			 * check, say): latched for it, the program never starts */
			c->prog.discard = 1;
			c->prog.discard_waiting = 1; /* its first record too */
			c->counts.refused++;
			struct mlip_ctl_reason r =
			    reason(MLIP_WHY_STOP_EARLY, head->seq, head->line);
			if (c->state == MLIP_STATE_IDLE && c->why.why == MLIP_WHY_STOP_EARLY) {
				c->why.why = MLIP_WHY_NONE; /* a second refusal is named too */
			}
			go(c, out, MLIP_STATE_IDLE, r);
			return;
		}
		if (c->drives && c->power.seq.step != MLIP_POWER_ENABLED) {
			/* the drives are (being) shut down: enable them first, then
			 * take the program from where they are */
			c->power.want = !c->op.exiting;
			return;
		}
		c->prog.refill = c->state == MLIP_STATE_STARVED && head->seq != 1;
		if (!c->prog.refill) {
			c->prog.exec.seq = 0; /* a new program (a starved one is given up) */
			c->prog.exec.line = 0;
			memcpy(c->prog.start, c->pos, sizeof(c->prog.start));
		}
		c->prog.next_seq = head->seq;
		c->prog.end.seq = 0;
		go(c, out, MLIP_STATE_PREREAD,
		   reason(c->prog.refill ? MLIP_WHY_CONTINUE : MLIP_WHY_START, head->seq,
		          head->line));
		/* fall through - the pre-read starts in this period */
	case MLIP_STATE_PREREAD: {
		uint32_t room = mlip_planner_space(c->planner);
		int ev =
		    ingest(c, out, room < MLIP_PREREAD_PER_PERIOD ? room : MLIP_PREREAD_PER_PERIOD);
		if (ev && mlip_planner_queued(c->planner) == 0) {
			start_event(c, out, in, &c->wait.event); /* nothing to move first */
		} else if (c->state == MLIP_STATE_PREREAD && preread_done(c, in, ev)) {
			go(c, out, MLIP_STATE_RUNNING, reason(MLIP_WHY_PREREAD_DONE, 0, 0));
		}
		return;
	}
	case MLIP_STATE_RUNNING:
	case MLIP_STATE_HELD: {
		if (mlip_planner_queued(c->planner) == 0 && have && is_event(head) &&
		    mlip_ctl_check_record(&c->m, head, c->prog.next_seq, NULL) == MLIP_OK) {
			start_event(c, out, in, head);
			return;
		}
		uint32_t room = mlip_planner_space(c->planner);
		int dry = c->prog.end.seq == 0 && room > 0 && rx_count(c) == 0;
		if (dry) {
			c->counts.underruns++; /* the feeder is behind: the plan runs to rest */
		}
		ingest(c, out, room < MLIP_INGEST_PER_PERIOD ? room : MLIP_INGEST_PER_PERIOD);
		return;
	}
	case MLIP_STATE_DWELLING:
	case MLIP_STATE_PAUSED: {
		/* at rest: pre-read what follows, so motion starts at the end */
		uint32_t room = mlip_planner_space(c->planner);
		int ev =
		    ingest(c, out, room < MLIP_PREREAD_PER_PERIOD ? room : MLIP_PREREAD_PER_PERIOD);
		if (c->state == MLIP_STATE_DWELLING && c->wait.dwell_left == 0) {
			end_wait(c, out, in, ev, MLIP_WHY_DWELL_DONE);
		} else if (c->state == MLIP_STATE_PAUSED && c->wait.resume) {
			end_wait(c, out, in, ev, MLIP_WHY_RESUME);
		}
		return;
	}
	default:
		return; /* STOPPING, FAULT: nothing more is taken */
	}
}

/* The executing record, for the status. */
static void progress(const struct mlip_ctl *c, uint64_t *seq, uint32_t *line)
{
	const struct mlip_planner *p = c->planner;
	*seq = c->prog.exec.seq;
	*line = c->prog.exec.line;
	if (c->state == MLIP_STATE_DWELLING || c->state == MLIP_STATE_PAUSED) {
		*seq = c->wait.at.seq;
		*line = c->wait.at.line;
	} else if (c->wait.stopped) {
		return; /* stopping in a wait: the pre-read after it never moves */
	} else if (c->state != MLIP_STATE_PREREAD && mlip_planner_queued(p) > 0) {
		mlip_planner_executing(p, seq, line);
	}
}

/* Why the machine is held now, the strongest cause first: a stall and a bad
 * bus need a resume (and a clean bus), an operator's hold a resume, an
 * override of 0 a higher override. The reason follows the causes: after
 * override 0, hold, override 100 it is the hold, not the override. */
static uint32_t held_why(const struct mlip_ctl *c)
{
	if (c->hold.stall) {
		return MLIP_WHY_STALL;
	}
	if (c->hold.bus) {
		return c->hold.bus_why;
	}
	if (c->hold.op) {
		return MLIP_WHY_HOLD;
	}
	if (mlip_planner_override_pct(c->planner) == 0.0) {
		return MLIP_WHY_OVERRIDE_ZERO;
	}
	return MLIP_WHY_HOLD;
}

/* The planner's last completed block into exec_seq/line. At rest with
 * nothing queued the planner knows a new block's predecessor by its number
 * only (line 0): that is the block the controller already names. */
static void take_done(struct mlip_ctl *c)
{
	uint64_t seq;
	uint32_t line;
	mlip_planner_done(c->planner, &seq, &line);
	if (line == 0 && seq == c->prog.exec.seq) {
		return;
	}
	c->prog.exec.seq = seq;
	c->prog.exec.line = line;
}

/* After the step: the transitions the motion decides. still: this period's
 * setpoint is the last one's (the planner reached the point a period before
 * it reported idle, by a rounding-size remainder). */
static void after_step(struct mlip_ctl *c, struct mlip_ctl_out *out, const struct mlip_ctl_in *in,
                       mlip_run_state rs, int still)
{
	struct mlip_ring_rec next;
	switch (c->state) {
	case MLIP_STATE_RUNNING:
	case MLIP_STATE_HELD:
		if (rs == MLIP_RUN_IDLE && c->prog.end.seq != 0) {
			c->prog.exec = c->prog.end; /* the program is done, at rest */
			c->prog.end.seq = 0;
			go(c, out, MLIP_STATE_IDLE,
			   reason(MLIP_WHY_END, c->prog.exec.seq, c->prog.exec.line));
		} else if (rs == MLIP_RUN_IDLE) {
			take_done(c);
			if (rx_peek(c, &next) && is_event(&next)) {
				if (c->state == MLIP_STATE_HELD) {
					go(c, out, MLIP_STATE_RUNNING,
					   reason(MLIP_WHY_RESUME, 0, 0));
				}
				if (still && mlip_ctl_check_record(&c->m, &next, c->prog.next_seq,
				                                   NULL) == MLIP_OK) {
					/* at rest since the last period: this one is the
					 * wait's first, so the wait counts from the arrival */
					start_event(c, out, in, &next);
					if (c->state == MLIP_STATE_DWELLING) {
						c->wait.dwell_left--;
					}
				}
				return; /* else at rest in front of an event: taken next period */
			}
			go(c, out, MLIP_STATE_STARVED,
			   reason(MLIP_WHY_UNDERRUN, c->prog.exec.seq, c->prog.exec.line));
		} else if (rs == MLIP_RUN_HELD &&
		           (c->state == MLIP_STATE_RUNNING || c->why.why != held_why(c))) {
			go(c, out, MLIP_STATE_HELD, reason(held_why(c), 0, 0));
		} else if (rs == MLIP_RUN_MOVING && c->state == MLIP_STATE_HELD) {
			go(c, out, MLIP_STATE_RUNNING, reason(MLIP_WHY_RESUME, 0, 0));
		}
		return;
	case MLIP_STATE_STOPPING:
		if (rs == MLIP_RUN_IDLE) {
			if (!c->wait.stopped) {
				take_done(c);
			}
			c->wait.stopped = 0;
			c->hold.op = 0; /* the planner's stop released its hold */
			go(c, out, MLIP_STATE_IDLE, c->why); /* the stop stays the reason */
		}
		return;
	case MLIP_STATE_FAULT:
		if (rs == MLIP_RUN_IDLE && !c->wait.stopped) {
			take_done(c); /* the last good block */
		}
		return;
	default:
		return;
	}
}

static void publish(const struct mlip_ctl *c, struct mlip_ctl_out *out)
{
	struct mlip_ring_status *s = &out->status;
	const struct mlip_planner *p = c->planner;
	memset(s, 0, sizeof(*s));
	s->heartbeat = c->period + 1;
	progress(c, &s->exec_seq, &s->exec_line);
	s->state = c->state;
	s->override_pct = (uint32_t)(mlip_planner_override_pct(p) + 0.5);
	s->overruns = c->overruns;
	s->underruns = c->counts.underruns;
	s->blocks_consumed = c->counts.blocks_consumed;
	s->stop_nm = c->brake.last_nm;
	s->stop_periods = c->brake.last_periods;
	s->stops = c->brake.count;
	s->reason = c->why.why;
	s->reason_field = c->why.field;
	s->reason_seq = c->why.seq;
	s->reason_line = c->why.line;
	s->reason_value = c->why.value;
	s->reason_node = c->why.node;
	s->optional_stop = (uint32_t)c->op.optional_stop;
	memcpy(s->pos, c->pos, sizeof(s->pos));
	s->speed_mm_s = mlip_planner_speed(p);
	s->dwell_left = c->state == MLIP_STATE_DWELLING ? c->wait.dwell_left : 0;
	s->drive_power = c->power.seq.step;
	s->drive_power_periods = (uint32_t)c->power.seq.took;
	memcpy(s->prog_start, c->prog.start, sizeof(s->prog_start));
	s->stop_seen = c->op.stop_seen;
}

/* Still moving: a stall must freeze it. */
static int moving(const struct mlip_ctl *c)
{
	return mlip_planner_moving(c->planner) && c->state != MLIP_STATE_PREREAD &&
	       c->state != MLIP_STATE_DWELLING && c->state != MLIP_STATE_PAUSED;
}

void mlip_ctl_period(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out)
{
	struct mlip_planner *p = c->planner;
	int stalled = 0;

	out->n_events = 0;
	out->n_frames = 0;
	c->power.want = 0; /* blocks_in says again whether a program waits */
	out->cmd_result = MLIP_OK;
	out->done = 0;
	c->period = in->period;
	c->overruns += in->missed;
	c->rx.view = &in->recs;
	c->rx.taken = 0;
	if (in->recs_corrupt != 0 && c->rx.corrupt == 0) {
		c->rx.corrupt =
		    in->recs_corrupt; /* a corrupted segment: nothing more is read from it */
	}

	/* a stall: the drives stood at the last setpoint while the plan's clock
	 * ran on. Never jump: that setpoint becomes a point of rest, and motion
	 * continues from it only on the operator's resume. */
	if (in->missed > c->stall_periods && moving(c)) {
		mlip_planner_rest_here(p);
		if (c->state == MLIP_STATE_FAULT || c->state == MLIP_STATE_STOPPING) {
			mlip_planner_stop(p); /* a stop in progress ends here */
		} else {
			c->hold.stall = 1;
			c->brake.on = 0;
			struct mlip_ctl_reason r = reason(MLIP_WHY_STALL, 0, 0);
			progress(c, &r.seq, &r.line);
			r.value = (double)in->missed;
			go(c, out, MLIP_STATE_HELD, r);
		}
		stalled = 1;
	}
	if (in->cmd != NULL) {
		out->cmd_result = apply_command(c, out, in->cmd);
	}
	/* a stop request (the segment's counter): never behind a command */
	if (in->stop_requests != c->op.stop_seen) {
		c->op.stop_seen = in->stop_requests;
		begin_stop(c, out, MLIP_WHY_STOP);
	}
	if (in->exit_request && !c->op.exiting) {
		c->op.exiting = 1; /* a controlled stop on the path, then done */
		begin_stop(c, out, MLIP_WHY_EXIT);
	}
	/* frames the drives did not get, or a bus that is off: do not go on
	 * blind; hold on the path until the operator resumes on a clean bus */
	if (in->bus.tx_refused != c->hold.tx_seen || in->bus.off) {
		c->hold.bus_bad_period = c->period;
		if (!c->hold.bus) {
			c->hold.bus = 1;
			c->hold.bus_why = in->bus.off ? MLIP_WHY_BUS_ERROR : MLIP_WHY_BUS_TX;
			mlip_planner_hold(p, 1);
			brake_begin(c);
		}
	}
	c->hold.tx_seen = in->bus.tx_refused;
	if (in->drives.fault.event != 0 && !c->drive_faulted) {
		drive_fault(c, out, &in->drives.fault);
	}

	blocks_in(c, in, out);
	if (c->rx.corrupt && !c->prog.bad) {
		struct mlip_ctl_reason r = reason(MLIP_WHY_RING_CORRUPT, c->prog.next_seq, 0);
		r.field = MLIP_FIELD_HEAD;
		r.value = (double)c->rx.corrupt;
		fault(c, out, r);
		c->prog.discard = 0; /* nothing is read from that ring again */
	}

	/* one step; a pre-read or a wait does not move, nor the stall's period */
	if (c->state == MLIP_STATE_DWELLING) {
		c->wait.dwell_left--; /* >= 1 here: a wait of 0 ended in blocks_in */
	} else if (c->state != MLIP_STATE_PREREAD && c->state != MLIP_STATE_PAUSED && !stalled) {
		double prev[MLIP_MAX_AXES];
		memcpy(prev, c->pos, sizeof(prev));
		mlip_run_state rs = mlip_planner_step(p, c->pos);
		if (c->brake.on) {
			brake_step(c, prev, rs);
		}
		int still = memcmp(prev, c->pos, sizeof(prev)) == 0;
		c->power.still_periods = still ? c->power.still_periods + 1 : 0;
		after_step(c, out, in, rs, still);
	}

	if (c->drives) {
		power_period(c, in, out);
	}
	memcpy(out->pos, c->pos, sizeof(out->pos));
	if (c->encode) {
		uint32_t sat = 0;
		/* the drives' controlword, and no target to a drive faulted */
		for (int k = 0; k < MLIP_MAX_AXES; k++) {
			c->enc.controlword[k] = (uint16_t)c->power.seq.cw;
		}
		c->enc.rpdo_mute = in->drives.mute;
		if (mlip_canenc_encode(&c->enc, (uint32_t)c->period, c->pos, out->frames,
		                       MLIP_CAN_MAX_FRAMES, &out->n_frames, &sat) != MLIP_OK) {
			/* a position beyond the drive's int32 range: never send it */
			out->n_frames = 0;
			if (c->state != MLIP_STATE_FAULT) {
				begin_stop(c, out, MLIP_WHY_POSITION_RANGE);
				struct mlip_ctl_reason r = reason(MLIP_WHY_POSITION_RANGE, 0, 0);
				progress(c, &r.seq, &r.line);
				go(c, out, MLIP_STATE_FAULT, r);
			}
		}
		c->counts.frames_encoded += (uint64_t)out->n_frames;
	}
	publish(c, out);
	out->power.state = c->power.seq.step;
	out->power.ok = c->power.seq.ok;
	out->power.late_node =
	    c->power.seq.late >= 0 ? (uint32_t)c->m.axis[c->power.seq.late].can_node : 0;
	out->power.late_sw = c->power.seq.late_sw;
	out->power.late_step = c->power.seq.late_step;
	out->status.actual_mask = in->drives.actual_mask;
	memcpy(out->status.pos_actual, in->drives.pos_actual, sizeof(out->status.pos_actual));
	/* an exit request ends once the machine is at rest */
	out->done =
	    c->op.exiting && !c->prog.discard &&
	    (c->state == MLIP_STATE_IDLE ||
	     (c->state == MLIP_STATE_FAULT && mlip_planner_queued(p) == 0)) &&
	    (!c->drives || c->power.seq.step == MLIP_POWER_OFF); /* and the drives disabled */
	out->taken = c->rx.taken;
	out->counts = c->counts;
	c->rx.view = NULL; /* the caller's, for this period only */
}
