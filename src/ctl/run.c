/*
 * run.c - the program (mlip/ctl/controller.h): records checked and taken
 * from in->recs by state, waits, and the transitions the motion decides.
 * The ingest rule of planner.h lives here once: records are taken without
 * moving until the look-ahead is full, the program's END is in or an event
 * (dwell, pause) is next (the pre-read, MLIP_PREREAD_PER_PERIOD a period),
 * then at most MLIP_INGEST_PER_PERIOD a period before each step.
 * An event is taken only when the planner is at rest at the end of the move
 * before it: the planner always plans its newest block to rest, so stopping
 * the ingest in front of an event is all it takes.
 */
#include "ctl.h"

#include <math.h>
#include <string.h>

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
	b.kind = rec->type == MLIP_REC_MOVE || rec->type == MLIP_REC_PROBE ? MLIP_BLOCK_MOVE
	         : rec->type == MLIP_REC_DWELL                             ? MLIP_BLOCK_DWELL
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
	if (rec->type == MLIP_REC_SPEED &&
	    !(rec->dwell_s >= 0 && rec->dwell_s <= MLIP_REC_RPM_MAX)) {
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
	/* M64/M65: +-(n + 1) of an output n; G38: MLIP_PROBE_* bits (issue 19) */
	double dout = fabs(rec->dwell_s);
	dout -= dout > MLIP_DOUT_SYNC ? MLIP_DOUT_SYNC : 0; /* M62/M63 */
	if (rec->type == MLIP_REC_OUTPUT &&
	    !(dout >= 1.0 && dout <= MLIP_DOUT_MAX && rec->dwell_s == floor(rec->dwell_s))) {
		return bad(why, rec, MLIP_FIELD_DWELL, rec->dwell_s);
	}
	if (rec->type == MLIP_REC_PROBE &&
	    !(rec->dwell_s >= 0.0 && rec->dwell_s <= 3.0 && rec->dwell_s == floor(rec->dwell_s))) {
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
	if (rec->type == MLIP_REC_OUTPUT && fabs(rec->dwell_s) > MLIP_DOUT_SYNC) {
		return 0; /* M62/M63: with the motion, not at rest */
	}
	return rec->type == MLIP_REC_DWELL || rec->type == MLIP_REC_PAUSE ||
	       rec->type == MLIP_REC_OPTIONAL_PAUSE || rec->type == MLIP_REC_SPINDLE ||
	       rec->type == MLIP_REC_TOOL || rec->type == MLIP_REC_COOLANT ||
	       rec->type == MLIP_REC_OUTPUT || rec->type == MLIP_REC_PROBE ||
	       rec->type == MLIP_REC_SPEED;
}

/* The ring is empty and nothing will fill it. */
static int ring_dry(struct mlip_ctl *c, const struct mlip_ctl_in *in)
{
	return !in->feeder_alive && rx_count(c) == 0;
}

/* A bad record: take nothing more. Moving, the look-ahead already plans the
 * last good block to rest (its newest block always ends at rest, so braking
 * always makes it); the rest of the program is dropped. */
void mlip_ct_fault(struct mlip_ctl *c, struct mlip_ctl_out *out, struct mlip_ctl_reason r)
{
	c->prog.bad = 1;
	c->prog.discard = 1;
	if (c->state != MLIP_STATE_RUNNING && c->state != MLIP_STATE_HELD) {
		/* not moving (pre-read, a wait): what was pre-read never starts;
		 * a wait is not done (the block completed is the one before it) */
		c->wait.stopped = c->state == MLIP_STATE_DWELLING || c->state == MLIP_STATE_PAUSED;
		mlip_ct_planner_stop(c);
		c->wait.dwell_left = 0;
	}
	go(c, out, MLIP_STATE_FAULT, r);
}

/* The record expected next, checked, and its MLIP_REC_MPCT the program's
 * (the corners its feeder chose, taken at its start: corners()). */
static mlip_status record_ok(const struct mlip_ctl *c, const struct mlip_ring_rec *rec,
                             struct mlip_ctl_reason *why)
{
	if (mlip_ctl_check_record(&c->m, rec, c->prog.next_seq, why) != MLIP_OK) {
		return MLIP_E_RANGE;
	}
	if (((rec->flags & MLIP_REC_MPCT) != 0) != c->prog.mpct) {
		return bad(why, rec, MLIP_FIELD_FLAGS, (double)rec->flags);
	}
	return MLIP_OK;
}

/* Take up to max records of the current program, stopping in front of an
 * event (it is taken at rest) and after END. Returns 1 when an event is next. */
static int ingest(struct mlip_ctl *c, struct mlip_ctl_out *out, uint32_t max)
{
	uint32_t n = 0;
	int event_next = 0, bad_next = 0;
	struct mlip_ring_rec rec;
	struct mlip_ctl_reason bad_why;
	while (n < max && c->prog.end.seq == 0 && !c->prog.bad && rx_peek(c, &rec)) {
		if (record_ok(c, &rec, &bad_why) != MLIP_OK) {
			bad_next = 1; /* the fault after the good blocks before it are in */
			break;
		}
		if (rec.type == MLIP_REC_OUTPUT && fabs(rec.dwell_s) > MLIP_DOUT_SYNC) {
			/* M62/M63: switched in the period the next move starts */
			if (mlip_mio_sync_add(c, &rec) != MLIP_OK) {
				break; /* as many waiting as there is room for: later */
			}
			rx_pop(c);
			c->prog.next_seq++;
			continue;
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
			mlip_ct_fault(c, out, r);
		}
	}
	if (bad_next) {
		mlip_ct_fault(c, out, bad_why);
	}
	return event_next;
}

/* A new program's corners: mpct's when its first record says so on a smooth
 * controller (its feeder counted mpct's run sooner), else the controller's
 * strategy. The flag anywhere else, or on another controller, is taken as
 * not set: its record is bad (ingest). The planner is empty here (idle, or
 * a starved program given up, at rest). */
static void corners(struct mlip_ctl *c, const struct mlip_ring_rec *head)
{
	c->prog.mpct = (head->flags & MLIP_REC_MPCT) != 0 && c->strategy == MLIP_STRATEGY_SMOOTH;
	mlip_strategy st = c->prog.mpct ? MLIP_STRATEGY_MPCT : c->strategy;
	if (c->planner->strategy != st && mlip_planner_set_strategy(c->planner, st) != MLIP_OK) {
		c->prog.mpct = !c->prog.mpct; /* not possible: its first record is refused */
	}
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
	for (int i = 0; i < MLIP_DROP_PER_PERIOD && rx_peek(c, &rec); i++) {
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

/* ---- waits: dwell, pause ------------------------------------------------- */

/* A probe that cannot start or did not trip (G38.2/.4) stops the program
 * at rest, as LinuxCNC's probe errors end theirs: the rest of it is
 * dropped, the machine stays ready (idle, the reason named); a record the
 * planner refused is a fault as any. */
static void probe_abort(struct mlip_ctl *c, struct mlip_ctl_out *out, struct mlip_ctl_reason r)
{
	if (r.why == MLIP_WHY_BAD_RECORD) {
		mlip_ct_fault(c, out, r);
		return;
	}
	c->prog.discard = 1;
	c->prog.end.seq = 0;
	go(c, out, MLIP_STATE_IDLE, r);
}

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
	} else if ((rec->type == MLIP_REC_SPINDLE || rec->type == MLIP_REC_SPEED) &&
	           c->spindle.on) {
		/* a spindle on the bus: at rest until it is at speed (or at
		 * standstill); its timeout is a fault before this wait ends. An
		 * MDI S alone: the new speed in the direction it turns (0: it is
		 * stopped and stays so, the S waits for the next M3/M4) */
		double rpm = rec->dwell_s, was = c->spindle.program_rpm;
		if (rec->type == MLIP_REC_SPEED) {
			rpm = was > 0 ? rec->dwell_s : was < 0 ? -rec->dwell_s : 0.0;
		}
		mlip_ctl_spindle_ask(&c->spindle, rpm, c->period);
		c->wait.dwell_left = (uint64_t)c->spindle.drive.cfg.timeout_periods + 2u;
		r.why = MLIP_WHY_SPINDLE_WAIT;
		r.value = rpm;
		go(c, out, MLIP_STATE_DWELLING, r);
	} else if (rec->type == MLIP_REC_SPEED) {
		/* no spindle on the bus: the reader refuses an MDI S alone on
		 * such a machine, so this record is not one of ours */
		struct mlip_ctl_reason w;
		(void)bad(&w, rec, MLIP_FIELD_TYPE, (double)rec->type);
		mlip_ct_fault(c, out, w);
		return;
	} else if (rec->type == MLIP_REC_OUTPUT ||
	           (rec->type == MLIP_REC_COOLANT && mlip_mio_coolant_io(c))) {
		/* the module's outputs, at rest: a wait of no period (issue 19) */
		struct mlip_ctl_reason w;
		if (mlip_mio_switch(c, rec, &w) != MLIP_OK) {
			mlip_ct_fault(c, out, w);
			return;
		}
		c->wait.dwell_left = 0;
		r.why = MLIP_WHY_OUTPUT;
		r.field = rec->type;
		r.value = rec->dwell_s;
		go(c, out, MLIP_STATE_DWELLING, r);
	} else if (rec->type == MLIP_REC_PROBE) {
		/* G38: its move, watched by mlip_mio_period (issue 19) */
		struct mlip_ctl_reason w;
		if (mlip_mio_probe_start(c, rec, &w) != MLIP_OK) {
			probe_abort(c, out, w);
			return;
		}
		go(c, out, MLIP_STATE_RUNNING, w);
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

/* Blocks in, by state. */
void mlip_ct_blocks_in(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out)
{
	struct mlip_ring_rec first, *head = &first;
	int have = rx_peek(c, head);

	if (c->io.estop) {
		/* E-stop or limit: every program is dropped unmoved until the reset */
		for (int i = 0; i < MLIP_DROP_PER_PERIOD && rx_peek(c, head); i++) {
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
			c->prog.mdi = in->feeder_mdi;
			memcpy(c->prog.start, c->pos, sizeof(c->prog.start));
			corners(c, head);
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
		if (c->mio.probe_on) {
			return; /* a probe move: what follows is taken once it ended */
		}
		if (mlip_planner_queued(c->planner) == 0 && have && is_event(head) &&
		    record_ok(c, head, NULL) == MLIP_OK) {
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
	if (c->hold.spindle) {
		return MLIP_WHY_SPINDLE_WAIT;
	}
	if (mlip_planner_override_pct(c->planner) == 0.0) {
		return MLIP_WHY_OVERRIDE_ZERO;
	}
	return MLIP_WHY_HOLD;
}

/* What holds the path now (status held_by), 0 none: the planner's hold by
 * its cause, else an override of 0, which holds it as well (at rest: the
 * next program starts held) but ends with a higher override, never with a
 * resume: the readers say which (mlip_state_hold_latched). */
uint32_t mlip_ct_held_by(const struct mlip_ctl *c)
{
	if (mlip_planner_held(c->planner)) {
		return held_why(c);
	}
	return mlip_planner_override_pct(c->planner) == 0.0 ? MLIP_WHY_OVERRIDE_ZERO : 0;
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
void mlip_ct_after_step(struct mlip_ctl *c, struct mlip_ctl_out *out, const struct mlip_ctl_in *in,
                        mlip_run_state rs, int still)
{
	struct mlip_ring_rec next;
	switch (c->state) {
	case MLIP_STATE_RUNNING:
	case MLIP_STATE_HELD:
		if (rs == MLIP_RUN_IDLE && c->mio.probe_on) {
			/* the probe move at rest: its result, then the program goes on
			 * (the drives' touch probe: armed first) */
			struct mlip_ctl_reason w;
			int arming = mlip_mio_probe_arming(c, in, &w);
			if (arming != 0) {
				if (arming < 0) {
					probe_abort(c, out, w);
				}
				return;
			}
			c->prog.exec = c->wait.at;
			if (mlip_mio_probe_end(c, &w) != MLIP_OK) {
				probe_abort(c, out, w);
			} else {
				end_wait(c, out, in, 0, MLIP_WHY_PROBED);
			}
		} else if (rs == MLIP_RUN_IDLE && c->prog.end.seq != 0) {
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
				if (still && record_ok(c, &next, NULL) == MLIP_OK) {
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
