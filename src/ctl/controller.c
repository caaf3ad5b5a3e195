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

/* Axis k is to be homed (HOME_METHOD) and is not yet: its soft limits mean
 * nothing so far. */
static int unhomed(const struct mlip_ctl *c, int k)
{
	return ((c->home.configured & ~c->home.homed) >> k) & 1u;
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
	if (state == MLIP_STATE_IDLE || state == MLIP_STATE_STOPPING || state == MLIP_STATE_FAULT ||
	    state == MLIP_STATE_ESTOP) {
		mlip_ctl_spindle_ask(&c->spindle, 0.0, c->period); /* every end stops it */
	}
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
	if (mlip_planner_init(p, &c->m, o->strategy, o->lookahead, c->pos, o->smooth) != MLIP_OK) {
		return MLIP_E_INVALID;
	}
	/* the look-ahead's work a bounded amount a period (mlip_planner_work):
	 * a period's cost does not grow with the look-ahead's depth */
	mlip_planner_set_async(p, 1);
	if (o->can != NULL) {
		if (mlip_canenc_init(&c->enc, o->can, &c->m) != MLIP_OK) {
			return MLIP_E_INVALID;
		}
		c->encode = 1;
		c->enc.rpdo_controlword = o->drives ? 1 : 0;
	} else if (o->drives) {
		return MLIP_E_INVALID; /* drives without frames to send them */
	}
	if (o->io != NULL) {
		c->io.cfg = *o->io;
	}
	if (o->home != NULL) {
		c->home.cfg = *o->home;
		for (int k = 0; k < m->n_axes; k++) {
			c->home.configured |= o->home->axis[k].configured ? 1u << k : 0u;
		}
	}
	if (mlip_ctl_spindle_init(&c->spindle, o->spindle, m->period_s) != MLIP_OK ||
	    (c->spindle.on && !o->drives)) {
		return MLIP_E_INVALID; /* a spindle on the bus needs the drives' master */
	}
	c->stall_periods = o->stall_periods ? o->stall_periods : MLIP_STALL_PERIODS_DEFAULT;
	c->jog.deadman = (uint64_t)floor(MLIP_JOG_DEADMAN_S / m->period_s + 1e-9);
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
	/* the rule set the G-code reader keeps too (mlip/types.h), on the
	 * fields it reads (a whole mlip_ring_rec_to_block doubled the cost) */
	struct mlip_block b;
	b.kind = rec->type == MLIP_REC_MOVE    ? MLIP_BLOCK_MOVE
	         : rec->type == MLIP_REC_DWELL ? MLIP_BLOCK_DWELL
	                                       : MLIP_BLOCK_PAUSE; /* END, pauses: no rule */
	b.dwell_s = rec->dwell_s;
	for (int k = 0; k < m->n_axes; k++) {
		b.target[k] = rec->target[k];
	}
	b.feed_mm_s = rec->feed_mm_s;
	b.tol_mm = rec->tol_mm;
	b.rapid = (rec->flags & MLIP_REC_RAPID) ? 1 : 0;
	int rule = mlip_block_check(m, &b);
	if (rule == MLIP_RULE_DWELL) {
		return bad(why, rec, MLIP_FIELD_DWELL, rec->dwell_s);
	}
	/* the machine's I/O: a speed, a whole tool number, coolant bits */
	if (rec->type == MLIP_REC_SPINDLE &&
	    !(rec->dwell_s >= -MLIP_REC_RPM_MAX && rec->dwell_s <= MLIP_REC_RPM_MAX)) {
		return bad(why, rec, MLIP_FIELD_DWELL, rec->dwell_s);
	}
	if (rec->type == MLIP_REC_TOOL &&
	    !(rec->dwell_s >= 0.0 && rec->dwell_s <= MLIP_REC_TOOL_MAX &&
	      rec->dwell_s == floor(rec->dwell_s))) {
		return bad(why, rec, MLIP_FIELD_DWELL, rec->dwell_s);
	}
	if (rec->type == MLIP_REC_COOLANT &&
	    !(rec->dwell_s == 0.0 || rec->dwell_s == MLIP_COOLANT_MIST ||
	      rec->dwell_s == MLIP_COOLANT_FLOOD ||
	      rec->dwell_s == (MLIP_COOLANT_MIST | MLIP_COOLANT_FLOOD))) {
		return bad(why, rec, MLIP_FIELD_DWELL, rec->dwell_s);
	}
	if (rule >= MLIP_RULE_TARGET && rule < MLIP_RULE_TARGET + MLIP_MAX_AXES) {
		int k = rule - MLIP_RULE_TARGET;
		return bad(why, rec, MLIP_FIELD_TARGET + (uint32_t)k, rec->target[k]);
	}
	if (rule == MLIP_RULE_FEED) {
		return bad(why, rec, MLIP_FIELD_FEED, rec->feed_mm_s);
	}
	if (rule == MLIP_RULE_TOL) {
		return bad(why, rec, MLIP_FIELD_TOL, rec->tol_mm);
	}
	return MLIP_OK;
}

static int is_event(const struct mlip_ring_rec *rec)
{
	return rec->type == MLIP_REC_DWELL || rec->type == MLIP_REC_PAUSE ||
	       rec->type == MLIP_REC_OPTIONAL_PAUSE || rec->type == MLIP_REC_SPINDLE ||
	       rec->type == MLIP_REC_TOOL || rec->type == MLIP_REC_COOLANT;
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
static void jog_release(struct mlip_ctl *c, uint32_t why);
static void home_abort(struct mlip_ctl *c);

/* A CiA 402 drive faulted (rt/drives.c's supervision): never go on blind.
 * Every axis stops on the path (the planner's stop: the other drives follow
 * it to rest; the faulted drive, muted by rt/, is in its own fault reaction),
 * nothing more of the program is taken, and the state says which node, which
 * event, in which block and line. The first drive fault stays the reason. */
static void drive_fault(struct mlip_ctl *c, struct mlip_ctl_out *out,
                        const struct mlip_ctl_drive_fault *f)
{
	struct mlip_ctl_reason r = reason(
	    c->spindle.on && f->node == c->spindle.node ? MLIP_WHY_SPINDLE_FAULT : MLIP_WHY_DRIVE,
	    0, 0);
	progress(c, &r.seq, &r.line);
	r.field = f->event;
	r.node = f->node;
	r.value = f->value;
	c->drive_faulted = 1;
	c->jog.on = 0;
	for (int k = 0; k < c->m.n_axes; k++) {
		if ((uint32_t)c->m.axis[k].can_node == f->node) {
			c->home.homed &=
			    ~(1u << k); /* a faulted drive may have lost its position */
		}
	}
	home_abort(c);
	if (c->io.estop) {
		/* the quick stop goes on; the fault comes back after the reset */
		if (!c->io.fault_kept) {
			c->io.fault_kept = 1;
			c->io.kept = r;
		}
		return;
	}
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
	if (c->io.estop) {
		return; /* stopped already, harder */
	}
	if (c->home.on) {
		home_abort(c); /* the drives move by themselves: back to CSP, then idle */
		if (c->home.on) {
			c->home.stop_why = why;
		} else if (c->state == MLIP_STATE_HOMING) {
			go(c, out, MLIP_STATE_IDLE, reason(why, 0, 0));
		}
		return;
	}
	if (c->jog.on) {
		jog_release(c, MLIP_WHY_JOG_RELEASED); /* a stop ends a jog on the path */
		if (why != MLIP_WHY_EXIT) {
			return;
		}
	}
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

static int32_t reset(struct mlip_ctl *c, struct mlip_ctl_out *out, const struct mlip_ctl_in *in);
static int32_t jog_command(struct mlip_ctl *c, struct mlip_ctl_out *out, int32_t arg);
static int32_t home_command(struct mlip_ctl *c, struct mlip_ctl_out *out, int32_t arg);
static void quick_stop(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out,
                       uint32_t state, struct mlip_ctl_reason r);

static int32_t apply_command(struct mlip_ctl *c, struct mlip_ctl_out *out,
                             const struct mlip_ctl_in *in, const struct mlip_ring_cmd *cmd)
{
	struct mlip_planner *p = c->planner;
	if (cmd->op == MLIP_CMD_RESET) {
		return reset(c, out, in);
	}
	if (cmd->op == MLIP_CMD_JOG) {
		return jog_command(c, out, cmd->arg);
	}
	if (cmd->op == MLIP_CMD_HOME) {
		return home_command(c, out, cmd->arg);
	}
	if (cmd->op == MLIP_CMD_HOLD && c->jog.on) {
		jog_release(c, MLIP_WHY_JOG_RELEASED); /* Grbl: a hold cancels a jog */
		return MLIP_OK;
	}
	if (c->io.estop && (cmd->op == MLIP_CMD_HOLD || cmd->op == MLIP_CMD_RESUME)) {
		return MLIP_E_INVALID; /* nothing to hold or resume: a reset first */
	}
	switch (cmd->op) {
	case MLIP_CMD_OVERRIDE:
		return mlip_planner_set_override(p, (double)cmd->arg);
	case MLIP_CMD_SPINDLE_OVERRIDE:
		return mlip_ctl_spindle_override(&c->spindle, cmd->arg, c->period);
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

/* ---- continuous jog (issue 18) -------------------------------------------- */

/* The jog ends braking on the path at the acceleration limit (the planner's
 * stop), the reason kept for the state it ends in. */
static void jog_release(struct mlip_ctl *c, uint32_t why)
{
	if (!c->jog.on || c->jog.stopping) {
		return;
	}
	c->jog.end_why = why;
	if (!c->jog.moving) {
		c->jog.on = 0; /* still waiting for the drives: nothing moved */
		return;
	}
	c->jog.stopping = 1;
	mlip_planner_stop(c->planner);
	brake_begin(c);
}

/* The axis' end in the jog's direction: its soft limit, and never beyond
 * what the drives' int32 counts can carry. */
static double jog_end(const struct mlip_ctl *c)
{
	const struct mlip_axis *a = &c->m.axis[c->jog.axis];
	double range = a->counts_per_unit > 0.0 ? 2147483000.0 / a->counts_per_unit : 1e9;
	double end = c->jog.neg ? a->min_limit : a->max_limit;
	if (unhomed(c, (int)c->jog.axis)) {
		end = c->jog.neg ? -range : range; /* machine zero is not known yet (LinuxCNC) */
	}
	return end > range ? range : end < -range ? -range : end;
}

/* Drives enabled (or none): the jog's block, from where the machine is to the
 * soft limit, at the jog's speed: the planner plans it to rest there, so the
 * jog stops exactly at the limit. */
static void jog_start(struct mlip_ctl *c, struct mlip_ctl_out *out)
{
	struct mlip_block b;
	memset(&b, 0, sizeof(b));
	memcpy(b.target, c->pos, sizeof(b.target));
	b.target[c->jog.axis] = jog_end(c);
	b.feed_mm_s = c->jog.speed;
	b.tol_mm = c->m.tolerance_mm;
	b.kind = MLIP_BLOCK_MOVE;
	if (mlip_planner_push(c->planner, &b) != MLIP_OK) {
		c->jog.on = 0; /* the planner is not at rest: nothing moves */
		go(c, out, MLIP_STATE_IDLE, reason(MLIP_WHY_JOG_RELEASED, 0, 0));
		return;
	}
	c->jog.moving = 1;
}

/* MLIP_CMD_JOG: start, renew or release. MLIP_E_RANGE: an axis not in the
 * machine, or no room toward the soft limit (Grbl's error 15: the jog
 * would leave the machine's travel); MLIP_E_INVALID: not at rest and idle
 * (a program, a stop, a fault, an E-stop), or another jog moving. */
static int32_t jog_command(struct mlip_ctl *c, struct mlip_ctl_out *out, int32_t arg)
{
	uint32_t u = (uint32_t)arg, axis = u & 7u, mm_min = (u >> 4) & 0xFFFFFu;
	int neg = (u & 8u) != 0;
	if ((int)axis >= c->m.n_axes) {
		return MLIP_E_RANGE;
	}
	if (mm_min == 0) {
		if (c->jog.on && axis == c->jog.axis) {
			jog_release(c, MLIP_WHY_JOG_RELEASED);
		}
		return MLIP_OK; /* a release after the end is no error */
	}
	if (c->jog.on) {
		if (axis != c->jog.axis || neg != c->jog.neg || c->jog.stopping) {
			return MLIP_E_INVALID; /* one jog at a time: release it first */
		}
		c->jog.renewed = c->period;
		return MLIP_OK;
	}
	if (c->state == MLIP_STATE_FAULT && c->why.why == MLIP_WHY_LIMIT && c->io.estop &&
	    !c->home.on) {
		/* stopped on a limit switch: only a jog away from it, which leaves
		 * the quick stop (the switch does not trip again until released) */
		uint32_t f = c->why.field, k = (f - MLIP_IN_AXIS0) / 3;
		int away_neg = f == MLIP_IN_LIMIT_POS(k);
		if (axis != k || neg != away_neg) {
			return MLIP_E_RANGE; /* toward the switch, or another axis */
		}
		c->io.limit_ignore |= 1u << f;
		c->io.estop = 0;
		c->prog.bad = 0;
		c->prog.discard = rx_count(c) > 0;
		c->prog.discard_waiting = c->prog.discard;
		if (c->drives) {
			mlip_402_seq_init(&c->power.seq, MLIP_POWER_NONE,
			                  c->power.seq.timeout ? c->power.seq.timeout : 1000,
			                  c->period);
		}
		go(c, out, MLIP_STATE_IDLE, reason(MLIP_WHY_RESET, 0, 0));
	}
	if (c->state != MLIP_STATE_IDLE || c->io.estop || mlip_planner_queued(c->planner) > 0 ||
	    rx_count(c) > 0) {
		return MLIP_E_INVALID;
	}
	c->jog.axis = axis;
	c->jog.neg = neg;
	double end = jog_end(c), here = c->pos[axis];
	if (neg ? !(end < here) : !(end > here)) {
		return MLIP_E_RANGE; /* at (or beyond) the soft limit that way already */
	}
	c->jog.on = 1;
	c->jog.moving = 0;
	c->jog.stopping = 0;
	c->jog.speed = (double)mm_min / 60.0;
	c->jog.renewed = c->period;
	c->jog.end_why = MLIP_WHY_JOG_END;
	struct mlip_ctl_reason r = reason(MLIP_WHY_JOG, 0, 0);
	r.field = axis;
	r.value = neg ? -c->jog.speed : c->jog.speed;
	go(c, out, MLIP_STATE_JOGGING, r);
	return MLIP_OK;
}

/* Each period of a jog: start once the drives are enabled, stop when not
 * renewed. */
static void jog_period(struct mlip_ctl *c, struct mlip_ctl_out *out)
{
	if (!c->jog.on) {
		return;
	}
	if (!c->jog.moving) {
		if (!c->drives || c->power.seq.step == MLIP_POWER_ENABLED) {
			jog_start(c, out);
		} else {
			c->power.want = 1; /* enable the drives first, from where they are */
		}
	}
	if (c->period - c->jog.renewed > c->jog.deadman) {
		jog_release(c, MLIP_WHY_JOG_DEADMAN);
	}
	if (!c->jog.on && c->state == MLIP_STATE_JOGGING) {
		go(c, out, MLIP_STATE_IDLE, reason(c->jog.end_why, 0, 0)); /* never moved */
	}
}

/* ---- homing with the drives' homing mode (issue 18, CiA 402 mode 6) ------- */

enum { HS_ENABLE = 1, HS_SETUP, HS_ARM, HS_RUN, HS_BACK, HS_NEXT };

#define SW_TARGET_REACHED 0x0400u /* statusword bit 10 */
#define SW_HOMING_DONE    0x1000u /* bit 12 in mode 6: homing attained */
#define SW_HOMING_ERROR   0x2000u /* bit 13 in mode 6: homing error */
#define CW_HOMING_START   0x0010u /* controlword bit 4: homing operation start */
#define MODE_HOMING       6

/* Object e of axis k's homing set-up (0x6098, 0x6099:1/2, 0x609A, 0x607C,
 * then 0x6060 = 6), or of its return (0x6060 = 8): 0 when there is none.
 * *rb: the object read back (0x6061 for 0x6060). */
static int home_object(const struct mlip_ctl *c, int k, int e, int back, struct mlip_ctl_sdo_req *r,
                       uint16_t *rb)
{
	const struct mlip_axis_home *h = &c->home.cfg.axis[k];
	double cpu = c->m.axis[k].counts_per_unit;
	r->node = (uint8_t)c->m.axis[k].can_node;
	r->upload = 0;
	r->sub = 0;
	r->size = 4;
	if (back) {
		if (e > 0) {
			return 0; /* the return is one object: 0x6060 = 8 */
		}
		e = 5;
	}
	switch (e) {
	case 0:
		r->index = 0x6098;
		r->size = 1;
		r->value = (uint8_t)(int8_t)h->method;
		break;
	case 1:
	case 2:
		r->index = 0x6099;
		r->sub = (uint8_t)e;
		r->value = (uint32_t)((e == 1 ? h->search_vel : h->latch_vel) * cpu + 0.5);
		break;
	case 3:
		r->index = 0x609A;
		r->value = (uint32_t)(h->accel * cpu + 0.5);
		break;
	case 4: {
		int32_t counts = 0;
		mlip_can_counts(h->offset, cpu, &counts);
		r->index = 0x607C;
		r->value = (uint32_t)counts;
		break;
	}
	case 5:
		r->index = 0x6060;
		r->size = 1;
		r->value = back ? MLIP_402_MODE_CSP : MODE_HOMING;
		break;
	default:
		return 0;
	}
	*rb = r->index == 0x6060 ? 0x6061 : r->index;
	return 1;
}

static void home_request(struct mlip_ctl *c, const struct mlip_ctl_sdo_req *r)
{
	c->home.req = *r;
	c->home.requests = c->home.requests + 1 ? c->home.requests + 1 : 1; /* never 0 */
	c->home.req.seq = c->home.sdo_seq = c->home.requests;
}

/* The first axis of the group at or after axis k, or -1. */
static int group_axis(const struct mlip_ctl *c, int k)
{
	for (; k < c->m.n_axes; k++) {
		if (c->home.group & (1u << k)) {
			return k;
		}
	}
	return -1;
}

/* Ask for the current object of the current axis (or go on to the next
 * axis); 0 when the group's list is done. */
static int home_issue(struct mlip_ctl *c, int back)
{
	struct mlip_ctl_sdo_req r;
	uint16_t rb;
	while (c->home.axis >= 0) {
		if (home_object(c, c->home.axis, c->home.entry, back, &r, &rb)) {
			home_request(c, &r);
			c->home.readback = 0;
			return 1;
		}
		c->home.axis = group_axis(c, c->home.axis + 1);
		c->home.entry = 0;
	}
	return 0;
}

/* The next group: the lowest HOME_SEQUENCE among the axes still to home. */
static int home_next_group(struct mlip_ctl *c)
{
	int best = 100;
	c->home.group = 0;
	for (int k = 0; k < c->m.n_axes; k++) {
		if ((c->home.todo & (1u << k)) && c->home.cfg.axis[k].sequence < best) {
			best = c->home.cfg.axis[k].sequence;
		}
	}
	for (int k = 0; k < c->m.n_axes; k++) {
		if ((c->home.todo & (1u << k)) && c->home.cfg.axis[k].sequence == best) {
			c->home.group |= 1u << k;
		}
	}
	c->home.todo &= ~c->home.group;
	c->home.attained = 0;
	c->home.axis = group_axis(c, 0);
	c->home.entry = 0;
	return c->home.group != 0;
}

/* Homing given up (a failure, an E-stop, a drive fault, a stop): the group
 * goes back to CSP (best effort: SDO 0x6060 = 8), nothing more is homed. */
static void home_abort(struct mlip_ctl *c)
{
	if (!c->home.on || c->home.failed) {
		return;
	}
	c->home.failed = 1;
	c->home.todo = 0;
	c->home.cw = MLIP_402_CW_ENABLE_OPERATION;
	if (c->home.step < HS_SETUP || c->home.group == 0) {
		c->home.on = 0; /* nothing was written yet */
		return;
	}
	c->home.step = HS_BACK;
	c->home.axis = group_axis(c, 0);
	c->home.entry = 0;
	home_issue(c, 1);
}

/* A failure: every axis stops (quick stop), the reason names the drive;
 * the group is still returned to CSP (best effort) so that a reset leaves
 * drives that follow targets again. */
static void home_fail(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out,
                      uint32_t why, int k, uint32_t field, double value)
{
	struct mlip_ctl_reason r = reason(why, 0, 0);
	r.node = (uint32_t)c->m.axis[k].can_node;
	r.field = field;
	r.value = value;
	quick_stop(c, in, out, MLIP_STATE_FAULT, r); /* and home_abort */
}

/* MLIP_CMD_HOME: axes (mask; 0: every configured one). */
static int32_t home_command(struct mlip_ctl *c, struct mlip_ctl_out *out, int32_t arg)
{
	uint32_t want = (uint32_t)arg & ((1u << c->m.n_axes) - 1u);
	if (arg == 0) {
		want = c->home.configured;
	}
	if (!c->drives || want == 0 || (want & ~c->home.configured) != 0 ||
	    ((uint32_t)arg >> c->m.n_axes) != 0) {
		return MLIP_E_RANGE; /* an axis without HOME_METHOD (or no drives) */
	}
	if (c->state != MLIP_STATE_IDLE || c->io.estop || c->home.on ||
	    mlip_planner_queued(c->planner) > 0 || rx_count(c) > 0) {
		return MLIP_E_INVALID;
	}
	c->home.on = 1;
	c->home.failed = 0;
	c->home.todo = want;
	c->home.homed &= ~want; /* homing again: not homed until it is done */
	c->home.step = HS_ENABLE;
	c->home.cw = MLIP_402_CW_ENABLE_OPERATION;
	struct mlip_ctl_reason r = reason(MLIP_WHY_HOMING, 0, 0);
	r.field = want;
	go(c, out, MLIP_STATE_HOMING, r);
	return MLIP_OK;
}

/* One period of homing, after the commands and inputs. */
static void home_period(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out)
{
	if (!c->home.on) {
		return;
	}
	/* the group's axes: the target is where the drive is, to the count, so
	 * that the return to CSP is no step */
	if (c->home.step >= HS_ARM && !c->io.estop) {
		for (int k = 0; k < c->m.n_axes; k++) {
			if ((c->home.group & (1u << k)) && (in->drives.actual_mask & (1u << k))) {
				c->pos[k] = in->drives.pos_actual[k];
			}
		}
		mlip_planner_rest_at(c->planner, c->pos);
	}
	switch (c->home.step) {
	case HS_ENABLE:
		if (c->power.seq.step != MLIP_POWER_ENABLED) {
			c->power.want = 1; /* from where the drives stand */
			return;
		}
		home_next_group(c);
		c->home.step = HS_SETUP;
		home_issue(c, 0);
		return;
	case HS_SETUP:
	case HS_BACK: {
		int back = c->home.step == HS_BACK;
		if (c->home.sdo_seq == 0 || in->sdo.seq != c->home.sdo_seq) {
			return; /* its answer is not there yet */
		}
		struct mlip_ctl_sdo_req r = c->home.req;
		uint32_t field = (uint32_t)r.index << 8 | r.sub;
		uint16_t rb;
		c->home.sdo_seq = 0;
		if (in->sdo.abort != 0 && !c->home.failed) {
			home_fail(c, in, out, MLIP_WHY_HOMING_SDO, c->home.axis, field,
			          (double)in->sdo.abort);
			return;
		}
		if (in->sdo.abort == 0 && !c->home.readback) {
			home_object(c, c->home.axis, c->home.entry, back, &r, &rb);
			r.index = rb;
			r.upload = 1;
			home_request(c, &r);
			c->home.readback = 1;
			return;
		}
		if (in->sdo.abort == 0 && !c->home.failed) {
			uint32_t mask = r.size >= 4 ? 0xFFFFFFFFu : (1u << (8 * r.size)) - 1u;
			home_object(c, c->home.axis, c->home.entry, back, &r, &rb);
			if ((in->sdo.value & mask) != (r.value & mask)) {
				home_fail(c, in, out, MLIP_WHY_HOMING_SDO, c->home.axis,
				          (uint32_t)rb << 8 | r.sub,
				          (double)(in->sdo.value & mask));
				return;
			}
		}
		c->home.entry++;
		if (home_issue(c, back)) {
			return;
		}
		if (!back) {
			c->home.step = HS_ARM;
			return;
		}
		/* back in CSP: where the drives are is where the machine is */
		if (!c->home.failed) {
			c->home.homed |= c->home.group;
		}
		c->home.step = HS_NEXT;
		return;
	}
	case HS_ARM:
		c->home.cw = MLIP_402_CW_ENABLE_OPERATION; /* bit 4 low: its rise starts it */
		c->home.step = HS_RUN;
		c->home.t0 = c->period + 1;
		return;
	case HS_RUN:
		c->home.cw = MLIP_402_CW_ENABLE_OPERATION | CW_HOMING_START;
		for (int k = 0; k < c->m.n_axes; k++) {
			uint16_t sw = in->drives.sw[k];
			uint64_t when = in->drives.tpdo_period[k];
			uint32_t bit = 1u << k;
			if (!(c->home.group & bit) || (c->home.attained & bit)) {
				continue;
			}
			/* only a TPDO that answers a SYNC after the start was applied */
			int fresh = when != UINT64_MAX && when >= c->home.t0 + 1;
			if (fresh && (sw & SW_HOMING_ERROR)) {
				home_fail(c, in, out, MLIP_WHY_HOMING_ERROR, k,
				          (uint32_t)c->home.cfg.axis[k].method, (double)sw);
				return;
			}
			if (fresh && (sw & (SW_HOMING_DONE | SW_TARGET_REACHED)) ==
			                 (SW_HOMING_DONE | SW_TARGET_REACHED)) {
				c->home.attained |= bit;
			} else if ((double)(c->period - c->home.t0) * c->m.period_s >
			           c->home.cfg.axis[k].timeout_s) {
				home_fail(c, in, out, MLIP_WHY_HOMING_TIMEOUT, k,
				          (uint32_t)c->home.cfg.axis[k].method, (double)sw);
				return;
			}
		}
		if (c->home.attained == c->home.group) {
			c->home.cw = MLIP_402_CW_ENABLE_OPERATION;
			c->home.step = HS_BACK;
			c->home.axis = group_axis(c, 0);
			c->home.entry = 0;
			home_issue(c, 1);
		}
		return;
	case HS_NEXT:
		if (!c->home.failed && c->home.todo != 0) {
			home_next_group(c);
			c->home.step = HS_SETUP;
			home_issue(c, 0);
			return;
		}
		c->home.on = 0;
		c->home.group = 0;
		if (!c->home.failed) {
			go(c, out, MLIP_STATE_IDLE, reason(MLIP_WHY_HOMED, 0, 0));
		} else if (c->state == MLIP_STATE_HOMING) {
			go(c, out, MLIP_STATE_IDLE, reason(c->home.stop_why, 0, 0)); /* a stop */
		}
		return;
	default:
		return;
	}
}

/* ---- the inputs on the bus: E-stop, limits, hold, cycle start (issue 18) ---- */

mlip_status mlip_ctl_set_output(struct mlip_ctl *c, uint32_t sub, uint32_t bit, int on)
{
	if (sub < 1 || sub > MLIP_IO_IN_BYTES || bit > 7) {
		return MLIP_E_RANGE;
	}
	if (c->io.estop) {
		return MLIP_OK; /* every output stays off until the reset */
	}
	if (on) {
		c->io.outputs[sub - 1] |= (uint8_t)(1u << bit);
	} else {
		c->io.outputs[sub - 1] &= (uint8_t) ~(1u << bit);
	}
	return MLIP_OK;
}

/* The commanded position is where the drives are (they have no holding
 * torque, or stop by themselves), the planner at rest there. */
static void follow_actual(struct mlip_ctl *c, const struct mlip_ctl_in *in)
{
	for (int k = 0; k < c->m.n_axes; k++) {
		if (in->drives.actual_mask & (1u << k)) {
			c->pos[k] = in->drives.pos_actual[k];
		}
	}
	mlip_planner_abort(c->planner, c->pos);
}

/* Quick stop (E-stop, limit): with drives, controlword 0x0002 to every drive
 * in this very period (power_period) and the planner dropped at once where
 * they are (each drive brakes on its own quick stop ramp, 0x6085); without
 * drives (nothing to quick stop) the planner stops on the path at the
 * acceleration limit. The program is dropped; every output goes off. */
static void quick_stop(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out,
                       uint32_t state, struct mlip_ctl_reason r)
{
	progress(c, &r.seq, &r.line);
	if (c->state == MLIP_STATE_FAULT && c->why.why == MLIP_WHY_DRIVE && !c->io.fault_kept) {
		c->io.fault_kept = 1; /* a drive fault comes back after the reset */
		c->io.kept = c->why;
	}
	c->io.estop = 1;
	c->jog.on = 0;
	home_abort(c);
	if (c->drives) {
		follow_actual(c, in);
	} else if (mlip_planner_queued(c->planner) > 0) {
		mlip_planner_stop(c->planner);
	}
	c->wait.dwell_left = 0;
	c->wait.stopped = 0;
	c->hold.op = 0;
	c->hold.stall = 0;
	c->brake.on = 0;
	c->prog.end.seq = 0;
	c->prog.bad = 1;     /* nothing more is taken until the reset */
	c->prog.discard = 1; /* the rest of the program is dropped */
	memset(c->io.outputs, 0, sizeof(c->io.outputs));
	go(c, out, state, r);
}

/* mlip-ctl reset: leave an E-stop or a limit fault once the inputs that
 * caused it are released (and the I/O module is back): IDLE, or the drive
 * fault that came before. The drives' power sequence starts again from the
 * states they are in (toward OFF; a program enables them). */
static int32_t reset(struct mlip_ctl *c, struct mlip_ctl_out *out, const struct mlip_ctl_in *in)
{
	uint32_t limits = 0;
	for (int k = 0; k < c->m.n_axes; k++) {
		limits |= (1u << MLIP_IN_LIMIT_NEG(k)) | (1u << MLIP_IN_LIMIT_POS(k));
	}
	if (!c->io.estop || c->home.on) {
		return MLIP_E_INVALID; /* nothing to reset (or homing still restores CSP) */
	}
	if ((in->io.active & (1u << MLIP_IN_ESTOP)) || in->io.lost.event != 0 ||
	    ((c->io.cfg.mapped & (1u << MLIP_IN_ESTOP)) &&
	     !(in->io.known & (1u << MLIP_IN_ESTOP)))) {
		return MLIP_E_RANGE; /* the E-stop is still on (or cannot be read) */
	}
	if (c->why.why == MLIP_WHY_LIMIT && (in->io.active & limits)) {
		return MLIP_E_RANGE; /* still on the limit switch */
	}
	c->io.estop = 0;
	c->io.prev = in->io.active; /* a hold still pressed is not a new edge */
	if (c->drives) {
		mlip_402_seq_init(&c->power.seq, MLIP_POWER_NONE,
		                  c->power.seq.timeout ? c->power.seq.timeout : 1000, c->period);
	}
	c->prog.bad = 0;
	c->prog.discard = rx_count(c) > 0;
	c->prog.discard_waiting = c->prog.discard;
	if (c->io.fault_kept) {
		c->prog.bad = 1;
		go(c, out, MLIP_STATE_FAULT, c->io.kept);
		return MLIP_OK;
	}
	go(c, out, MLIP_STATE_IDLE, reason(MLIP_WHY_RESET, 0, 0));
	return MLIP_OK;
}

/* The inputs of this period, before any command: E-stop wins over every
 * state; a limit while moving stops everything; hold and cycle start act on
 * their rising edge, as the commands would. */
static void io_period(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out)
{
	uint32_t on = in->io.active & c->io.cfg.mapped, rise = on & ~c->io.prev;
	struct mlip_ctl_reason r = reason(MLIP_WHY_NONE, 0, 0);

	c->io.prev = on;
	if (in->io.lost.event != 0 && c->state != MLIP_STATE_ESTOP) {
		r.why = MLIP_WHY_IO_LOST;
		r.field = in->io.lost.event;
		r.node = in->io.lost.node;
		r.value = in->io.lost.value;
		quick_stop(c, in, out, MLIP_STATE_ESTOP, r);
		return;
	}
	if ((on & (1u << MLIP_IN_ESTOP)) && c->state != MLIP_STATE_ESTOP) {
		r.why = MLIP_WHY_ESTOP;
		r.field = MLIP_IN_ESTOP;
		r.node = c->io.cfg.in[MLIP_IN_ESTOP].node;
		r.value = (double)c->io.cfg.in[MLIP_IN_ESTOP].index;
		quick_stop(c, in, out, MLIP_STATE_ESTOP, r);
		return;
	}
	if (c->io.estop) {
		return;
	}
	c->io.limit_ignore &= on; /* a released limit trips again */
	for (int k = 0; k < c->m.n_axes; k++) {
		uint32_t f = MLIP_IN_LIMIT_NEG(k);
		uint32_t hit = on & ((1u << f) | (1u << (f + 1))) & ~c->io.limit_ignore;
		if (hit &&
		    (mlip_planner_moving(c->planner) || mlip_planner_queued(c->planner) > 0)) {
			r.why = MLIP_WHY_LIMIT;
			r.field = (hit & (1u << f)) ? f : f + 1;
			r.node = c->io.cfg.in[r.field].node;
			r.value = c->pos[k];
			quick_stop(c, in, out, MLIP_STATE_FAULT, r);
			return;
		}
	}
	if (rise & (1u << MLIP_IN_HOLD)) {
		struct mlip_ring_cmd h = {0};
		h.op = MLIP_CMD_HOLD;
		apply_command(c, out, in, &h);
	}
	if (rise & (1u << MLIP_IN_CYCLE_START)) {
		struct mlip_ring_cmd h = {0};
		h.op = MLIP_CMD_RESUME;
		apply_command(c, out, in, &h);
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
	} else if (rec->type == MLIP_REC_SPINDLE && c->spindle.on) {
		/* a spindle on the bus: at rest until it is at speed (or at
		 * standstill); its timeout is a fault before this wait ends */
		mlip_ctl_spindle_ask(&c->spindle, rec->dwell_s, c->period);
		c->wait.dwell_left = (uint64_t)c->spindle.drive.cfg.timeout_periods + 2u;
		r.why = MLIP_WHY_SPINDLE_WAIT;
		r.value = rec->dwell_s;
		go(c, out, MLIP_STATE_DWELLING, r);
	} else if (rec->type == MLIP_REC_SPINDLE || rec->type == MLIP_REC_TOOL ||
	           rec->type == MLIP_REC_COOLANT) {
		/* a manual spindle, tool change or coolant: the operator does it
		 * with the machine at rest, then resumes (status: what, value) */
		r.why = rec->type == MLIP_REC_SPINDLE ? MLIP_WHY_SPINDLE
		        : rec->type == MLIP_REC_TOOL  ? MLIP_WHY_TOOL
		                                      : MLIP_WHY_COOLANT;
		r.value = rec->dwell_s;
		go(c, out, MLIP_STATE_PAUSED, r);
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

/* The first axis beyond a soft limit, or -1 (an axis still to be homed has
 * none yet: machine zero is wherever its drive powered up). */
static int beyond_limit(const struct mlip_ctl *c)
{
	for (int k = 0; k < c->m.n_axes; k++) {
		const struct mlip_axis *a = &c->m.axis[k];
		if (!unhomed(c, k) && !(c->pos[k] >= a->min_limit && c->pos[k] <= a->max_limit)) {
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
	    c->power.still_periods < 2 || !mlip_ctl_spindle_at_rest(&c->spindle)) {
		return 0; /* and a spindle on the bus at standstill */
	}
	return c->state == MLIP_STATE_FAULT || c->op.exiting ||
	       (c->state == MLIP_STATE_IDLE && c->why.why != MLIP_WHY_NONE);
}

/* The node of drive i of the power sequencer's group: the axes, then the
 * spindle. */
static uint32_t node_of(const struct mlip_ctl *c, int i)
{
	return i < c->m.n_axes ? (uint32_t)c->m.axis[i].can_node : c->spindle.node;
}

/* A step of the drives' power ended: the event, with the drive that did
 * not confirm it in time (its node and statusword). */
static void power_event(struct mlip_ctl *c, struct mlip_ctl_out *out,
                        const struct mlip_402_change *ch)
{
	struct mlip_ctl_reason r = reason(MLIP_WHY_NONE, ch->in_sequence, 0);
	r.value = (double)ch->in_step;
	if (ch->late >= 0) {
		r.node = node_of(c, ch->late);
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

	if (c->io.estop) {
		c->power.seq.cw = MLIP_402_CW_QUICK_STOP; /* to every drive, until the reset */
		return;
	}
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
	/* a spindle on the bus is one more drive of the group */
	uint16_t sw[MLIP_MAX_AXES + 1];
	uint32_t mute = in->drives.mute;
	int n = c->m.n_axes;
	memcpy(sw, in->drives.sw, sizeof(in->drives.sw));
	if (c->spindle.on) {
		sw[n] = in->spindle.sw;
		mute |= in->spindle.mute ? 1u << n : 0u;
		n++;
	}
	if (!mlip_402_seq_run(&c->power.seq, want ? MLIP_POWER_ENABLED : MLIP_POWER_OFF, sw, n,
	                      mute, c->period, &ch)) {
		return;
	}
	if (ch.failed) {
		/* not switched on or not enabled in time: a fault, the program is
		 * dropped, the drives go down again; nothing has moved */
		struct mlip_ctl_drive_fault f = {ch.from == MLIP_POWER_SWITCHING_ON
		                                     ? MLIP_DRIVE_NOT_SWITCHED_ON
		                                     : MLIP_DRIVE_NOT_ENABLED,
		                                 node_of(c, ch.late), (double)ch.late_sw};
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

	if (c->io.estop) {
		/* E-stop or limit: every program is dropped unmoved until the reset */
		for (int i = 0; i < MLIP_PREREAD_PER_PERIOD && rx_peek(c, head); i++) {
			rx_pop(c);
		}
		return;
	}
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
		if (c->home.cfg.required &&
		    (c->home.homed & c->home.configured) != c->home.configured) {
			/* HOMING_REQUIRED: no program before every axis is homed */
			c->prog.discard = 1;
			c->prog.discard_waiting = 1;
			c->counts.refused++;
			if (c->why.why == MLIP_WHY_NOT_HOMED) {
				c->why.why = MLIP_WHY_NONE; /* a second refusal is named too */
			}
			go(c, out, MLIP_STATE_IDLE,
			   reason(MLIP_WHY_NOT_HOMED, head->seq, head->line));
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
		} else if (c->state == MLIP_STATE_PREREAD && preread_done(c, in, ev) &&
		           !mlip_planner_busy(c->planner)) { /* and all of it planned */
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
	if ((line == 0 && seq == c->prog.exec.seq) || seq < c->prog.exec.seq) {
		/* never back: an event after the planner's last block (a pause,
		 * a manual tool change) is done once its wait ended */
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
	case MLIP_STATE_JOGGING:
		if (rs == MLIP_RUN_IDLE && c->jog.moving) {
			c->jog.on = 0;
			c->jog.moving = 0;
			go(c, out, MLIP_STATE_IDLE, reason(c->jog.end_why, 0, 0));
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
	s->drive_power = c->drives && c->io.estop ? MLIP_POWER_QUICK_STOP : c->power.seq.step;
	s->drive_power_periods = (uint32_t)c->power.seq.took;
	memcpy(s->prog_start, c->prog.start, sizeof(s->prog_start));
	s->stop_seen = c->op.stop_seen;
	s->io_mapped = c->io.cfg.mapped;
}

/* A CiA 402 spindle's period: its phase from its TPDO; a fault stops the
 * feed on the path (state FAULT, the spindle named); a wait for it ends
 * when it is at speed (or at rest). The output: its target and the group's
 * controlword, sent by rt/ after the axes' frames. */
static void spindle_period(struct mlip_ctl *c, const struct mlip_ctl_in *in,
                           struct mlip_ctl_out *out)
{
	struct mlip_ctl_drive_fault f = {0, c->spindle.node, 0.0};
	int rc;

	if (!c->spindle.on) {
		return;
	}
	rc = mlip_ctl_spindle_step(&c->spindle, in->spindle.sw, in->spindle.vel_counts, c->period,
	                           &f.event, &f.value);
	if (rc == -1 && !c->drive_faulted) {
		drive_fault(c, out, &f);
	} else if (rc == 1 && c->state == MLIP_STATE_DWELLING &&
	           c->why.why == MLIP_WHY_SPINDLE_WAIT) {
		c->wait.dwell_left = 0; /* at speed: the wait ends in blocks_in */
	}
}

static void spindle_out(const struct mlip_ctl *c, const struct mlip_ctl_in *in,
                        struct mlip_ctl_out *out, struct mlip_ring_status *s)
{
	const struct mlip_ctl_spindle *sp = &c->spindle;
	s->spindle_override = sp->override_pct;
	if (!sp->on) {
		return;
	}
	out->spindle.send = !in->spindle.mute && c->power.seq.cw >= 0;
	out->spindle.cw =
	    c->io.estop ? (uint16_t)MLIP_402_CW_QUICK_STOP : (uint16_t)c->power.seq.cw;
	out->spindle.target = c->io.estop ? 0 : sp->target;
	out->spindle.rpm_actual = sp->drive.actual_rpm;
	s->spindle_state = sp->drive.phase + 1u;
	s->spindle_cmd_rpm = mlip_ctl_spindle_cmd_rpm(sp);
	s->spindle_actual_rpm = sp->drive.actual_rpm;
	s->spindle_node = sp->node;
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
	/* the inputs first: an E-stop wins over every command of this period */
	io_period(c, in, out);
	if (in->cmd != NULL) {
		out->cmd_result = apply_command(c, out, in, in->cmd);
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

	spindle_period(c, in, out);
	jog_period(c, out);
	home_period(c, in, out);
	blocks_in(c, in, out);
	mlip_planner_work(p); /* the look-ahead's share of the period, bounded */
	if (c->rx.corrupt && !c->prog.bad) {
		struct mlip_ctl_reason r = reason(MLIP_WHY_RING_CORRUPT, c->prog.next_seq, 0);
		r.field = MLIP_FIELD_HEAD;
		r.value = (double)c->rx.corrupt;
		fault(c, out, r);
		c->prog.discard = 0; /* nothing is read from that ring again */
	}

	/* one step; a pre-read or a wait does not move, nor the stall's period */
	if (c->io.estop && c->drives) {
		follow_actual(c, in); /* the drives brake by themselves */
	} else if (c->state == MLIP_STATE_DWELLING) {
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
		for (int k = 0; k < MLIP_MAX_AXES && c->power.seq.cw >= 0; k++) {
			c->enc.controlword[k] = (uint16_t)c->power.seq.cw; /* -1: what was sent */
			if (c->home.on && (c->home.group & (1u << k)) && !c->io.estop &&
			    c->power.seq.step == MLIP_POWER_ENABLED && c->home.step >= HS_ARM) {
				c->enc.controlword[k] = c->home.cw; /* bit 4: homing start */
			}
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
	out->power.state = out->status.drive_power;
	out->status.io_inputs = in->io.active & c->io.cfg.mapped;
	out->status.io_known = in->io.known & c->io.cfg.mapped;
	memcpy(out->outputs, c->io.outputs, sizeof(out->outputs));
	out->sdo = c->home.req;
	spindle_out(c, in, out, &out->status);
	out->homing = c->home.on && c->home.step >= HS_ARM ? c->home.group : 0;
	out->status.homed = c->home.homed;
	out->power.ok = c->power.seq.ok;
	out->power.late_node = c->power.seq.late >= 0 ? node_of(c, c->power.seq.late) : 0;
	out->power.late_sw = c->power.seq.late_sw;
	out->power.late_step = c->power.seq.late_step;
	out->status.actual_mask = in->drives.actual_mask;
	memcpy(out->status.pos_actual, in->drives.pos_actual, sizeof(out->status.pos_actual));
	/* an exit request ends once the machine is at rest */
	if (c->home.on) {
		out->done = 0; /* the drives go back to CSP first */
	} else if (c->io.estop) {
		/* quick stopped (the drives are not enabled), or at rest without drives */
		out->done = c->op.exiting && (c->drives || !mlip_planner_moving(p));
	} else {
		out->done = c->op.exiting && !c->prog.discard &&
		            (c->state == MLIP_STATE_IDLE ||
		             (c->state == MLIP_STATE_FAULT && mlip_planner_queued(p) == 0)) &&
		            (!c->drives ||
		             c->power.seq.step == MLIP_POWER_OFF); /* and the drives disabled */
	}
	out->taken = c->rx.taken;
	out->counts = c->counts;
	c->rx.view = NULL; /* the caller's, for this period only */
}
