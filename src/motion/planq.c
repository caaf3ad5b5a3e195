/*
 * planq.c - the path-speed plan run ahead of the period through a
 * single-producer single-consumer queue (see mlip/motion/planq.h).
 */
#include "mlip/motion/planq.h"

#include <math.h>
#include <string.h>

#define EMASK ((uint32_t)MLIP_PLANQ_LEN - 1u)
#define KMASK ((uint64_t)MLIP_PLANQ_KNOTS - 1u)

/* Entries of an old generation the consumer drops a period at most: after
 * its flush the producer pushes at most one it planned before it saw the
 * request. */
#define DROPS 2

void mlip_planq_init(struct mlip_planq *q, const struct mlip_pathrun *pr)
{
	memset(q, 0, sizeof(*q));
	q->lim = pr->lim;
	q->n = pr->lim.n;
	q->c.mode = MLIP_PLANQ_WAIT;
	q->c.st = (struct mlip_path_state){pr->s[0], 0.0, 0.0, 0, 0};
	q->c.vmax = q->c.want_vmax = q->cap = pr->lim.vmax;
	memcpy(q->c.x, pr->p[0], sizeof(double) * (size_t)q->n);
	q->c.prev_st = q->c.st;
	memcpy(q->c.prev_x, q->c.x, sizeof(q->c.x));
}

/* Knot g (global) from pr's window into both its slots: s and p (its
 * point), or its piece's m, b, t3 (once the piece is fixed). */
static void put_knot(struct mlip_planq *q, const struct mlip_pathrun *pr, uint64_t g, int piece)
{
	int i = (int)(g - (uint64_t)pr->dropped);
	size_t n = sizeof(double) * (size_t)q->n;
	uint64_t a = g & KMASK, b = a + MLIP_PLANQ_KNOTS;
	if (!piece) {
		q->tag[a] = pr->tag[i];
		q->s[a] = q->s[b] = pr->s[i];
		memcpy(q->p[a], pr->p[i], n);
		memcpy(q->p[b], pr->p[i], n);
		return;
	}
	memcpy(q->m[a], pr->m[i], n);
	memcpy(q->m[b], pr->m[i], n);
	memcpy(q->b[a], pr->b[i], n);
	memcpy(q->b[b], pr->b[i], n);
	memcpy(q->t3[a], pr->t3[i], n);
	memcpy(q->t3[b], pr->t3[i], n);
}

/* The consumer's request: a plan from its state (after req_lead steps of
 * that state's braking run, on the pieces to its end) at its cap. A run
 * that fails leaves the generation without entries: the consumer brakes
 * to rest and asks again from there. */
static void take_request(struct mlip_planq *q, struct mlip_pathrun *pr)
{
	uint32_t g = __atomic_load_n(&q->want_gen, __ATOMIC_ACQUIRE);
	if (g == q->p_gen) {
		return;
	}
	struct mlip_path_state st = q->req_st;
	uint64_t idx = q->req_period, end = q->req_end;
	int lead = q->req_lead, ok = 1;
	struct mlip_path_curve cv;
	mlip_pathrun_curve(pr, &cv);
	if (lead < 0) {
		/* a higher cap: from the state queued for idx (at least LEAD
		 * periods ahead of the consumer now), if it is kept; else from
		 * the producer's own last (already queued) */
		uint64_t now = __atomic_load_n(&q->pidx, __ATOMIC_RELAXED) + MLIP_PLANQ_LEAD;
		idx = idx > now ? idx : now;
		if (idx <= q->p_period && q->p_period - idx < MLIP_PLANQ_LEN &&
		    q->p_hist[idx & (MLIP_PLANQ_LEN - 1)].period == idx) {
			st = q->p_hist[idx & (MLIP_PLANQ_LEN - 1)].st;
		} else {
			st = pr->st;
			idx = q->p_period;
		}
		q->sw_period = idx;
		q->sw_head = q->head;
	}
	if (lead > 0) {
		/* the consumer's run on the same pieces and the same end */
		ok = end >= (uint64_t)pr->dropped && end <= (uint64_t)(pr->dropped + pr->fixed);
		if (ok) {
			cv.count = (int)(end - (uint64_t)pr->dropped) + 1;
		}
		for (int i = 0; ok && i < lead && !(st.v == 0.0 && st.a == 0.0); i++) {
			ok = mlip_path_brake_step(&cv, &pr->lim, &st, NULL);
			idx++;
		}
		mlip_pathrun_curve(pr, &cv);
	}
	pr->st = st;
	pr->rested = 0;
	pr->hint = mlip_path_spline_piece(&cv, st.s, 0);
	q->p_gen = g;
	q->p_period = idx;
	q->p_done = !ok;
	__atomic_store_n(&q->ack, g, __ATOMIC_RELEASE);
}

int mlip_planq_produce(struct mlip_planq *q, struct mlip_pathrun *pr)
{
	take_request(q, pr);
	__atomic_load(&q->cap, &pr->lim.vmax, __ATOMIC_RELAXED);
	if (q->p_done) {
		return 2;
	}
	uint32_t head = q->head;
	if (head - (uint32_t)q->p_tail >= MLIP_PLANQ_LEN) {
		q->p_tail = __atomic_load_n(&q->tail, __ATOMIC_ACQUIRE);
		if (head - (uint32_t)q->p_tail >= MLIP_PLANQ_LEN) {
			return 0; /* the queue is full */
		}
	}
	uint64_t freed = __atomic_load_n(&q->freed, __ATOMIC_ACQUIRE);
	uint64_t end = (uint64_t)pr->dropped + (uint64_t)pr->fixed, old = q->knots;
	if (end + 1 - freed > MLIP_PLANQ_KNOTS) {
		return 0; /* the consumer still reads the slots the next knots take */
	}
	if (old > 0 && old - 1 < (uint64_t)pr->dropped) {
		pr->why = "a fixed piece was dropped before the queue had it";
		return -1;
	}
	for (uint64_t g = old > 0 ? old - 1 : 0; g <= end; g++) {
		if (g >= old) {
			put_knot(q, pr, g, 0);
		}
		if (g < end) {
			put_knot(q, pr, g, 1);
		}
	}
	__atomic_store_n(&q->knots, end + 1, __ATOMIC_RELEASE);
	if (freed < end + 1) { /* compaction keeps what the consumer may brake on */
		pr->keep_s = q->s[freed & KMASK];
	}
	struct mlip_planq_entry *e = &q->e[head & EMASK];
	e->from[0] = pr->st.s;
	e->from[1] = pr->st.v;
	e->from[2] = pr->st.a;
	int r = mlip_pathrun_step(pr, e->x);
	if (r == 0) {
		return 3;
	}
	if (r < 0) {
		return -1;
	}
	/* the pathrun's compaction keeps its own lag's knots (the plan
	 * mlip-sim runs): never above the consumer's freed while it follows
	 * the chain (it popped every entry up to p_tail - 1, at least
	 * MLIP_PLANQ_LEN + 1 periods behind this one, and its freed was
	 * stored before that tail); after it left, keep_s holds the
	 * compaction instead (its own run, no mlip-sim twin) */
	if ((uint64_t)mlip_pathrun_lag_knot(pr) > freed &&
	    !__atomic_load_n(&q->left, __ATOMIC_ACQUIRE)) {
		pr->why = "the plan's compaction would pass the consumer's knots (a defect)";
		return -1;
	}
	e->st = pr->st;
	e->end = end;
	e->piece = (uint64_t)pr->dropped + (uint64_t)pr->hint;
	e->gen = q->p_gen;
	e->period = ++q->p_period;
	q->p_hist[e->period & (MLIP_PLANQ_LEN - 1)].st = e->st;
	q->p_hist[e->period & (MLIP_PLANQ_LEN - 1)].period = e->period;
	e->last = r == 2;
	q->p_done = e->last;
	__atomic_store_n(&q->head, head + 1, __ATOMIC_RELEASE);
	return e->last ? 2 : 1;
}

/* The consumer: knots below piece - BEHIND are free. */
static void release_knots(struct mlip_planq *q)
{
	uint64_t piece = q->c.piece, f = q->freed;
	if (piece > MLIP_PLANQ_BEHIND && piece - MLIP_PLANQ_BEHIND > f) {
		__atomic_store_n(&q->freed, piece - MLIP_PLANQ_BEHIND, __ATOMIC_RELEASE);
	}
}

/* The consumer's marks from its piece's knots (both published: piece + 1
 * <= end; neither freed: the producer reuses a slot only KNOTS on). */
static void mark(struct mlip_planq *q)
{
	const struct mlip_pathrun_tag *at = &q->tag[q->c.piece & KMASK];
	const struct mlip_pathrun_tag *to = &q->tag[(q->c.piece + 1u) & KMASK];
	struct mlip_pathrun_tag *m = &q->c.mark;
	if (to->seq > m->seq) {
		m->seq = to->seq;
		m->line = to->line;
	}
	if (at->done_seq > m->done_seq) {
		m->done_seq = at->done_seq;
		m->done_line = at->done_line;
	}
}

/* The consumer leaves its plan's chain (before its tail passes an entry it
 * does not pop): once, the producer's compaction is then held by freed. */
static void leave(struct mlip_planq *q)
{
	if (!q->c.left) {
		q->c.left = 1;
		__atomic_store_n(&q->left, 1u, __ATOMIC_RELEASE);
	}
}

/* The entry continues the consumer's state: from it bit for bit, at the
 * next period (at rest any period: time does not matter there). */
static int continues(const struct mlip_planq *q, const struct mlip_planq_entry *e)
{
	const struct mlip_path_state *st = &q->c.st;
	int rest = st->v == 0.0 && st->a == 0.0;
	return e->from[0] == st->s && e->from[1] == st->v && e->from[2] == st->a &&
	       (rest || e->period == q->c.pidx + 1);
}

/* The next entry of the consumer's generation that continues its state,
 * copied out and its slot released; others of old generations, or of its
 * own behind its clock, dropped (DROPS at most). 0 when there is none (an
 * entry ahead of its clock stays). */
static int pop(struct mlip_planq *q)
{
	uint32_t tail = q->tail, head = __atomic_load_n(&q->head, __ATOMIC_ACQUIRE);
	for (int d = 0; d <= DROPS && tail != head; d++) {
		const struct mlip_planq_entry *e = &q->e[tail & EMASK];
		/* during a queued switch the old plan's entries up to its period */
		int old = q->c.sw && e->gen == q->c.gen - 1 &&
		          (q->c.sw == 1 || e->period <= q->c.sw_period);
		int mine = (e->gen == q->c.gen || old) && continues(q, e);
		if (!mine && e->gen == q->c.gen && e->period > q->c.pidx) {
			return 0; /* its plan, not yet its period */
		}
		if (mine) {
			q->c.st = e->st;
			q->c.end = e->end;
			q->c.piece = e->piece;
			q->c.pidx = e->period;
			q->c.took_gen = e->gen;
			memcpy(q->c.x, e->x, sizeof(double) * (size_t)q->n);
			q->c.mode = e->last ? MLIP_PLANQ_DONE : MLIP_PLANQ_PLAN;
			mark(q); /* freed before the tail: the producer's bound (produce) */
			release_knots(q);
		} else {
			leave(q);
		}
		__atomic_store_n(&q->tail, ++tail, __ATOMIC_RELEASE);
		if (mine) {
			return 1;
		}
	}
	return 0;
}

/* The speed a hold's plan brakes to (planq.h). */
static double hold_cap(const struct mlip_planq *q)
{
	return MLIP_PLANQ_HOLD_SHARE * q->lim.vmax;
}

/* The consumer's generation is its hold's plan (until the next request). */
static int on_hold_plan(const struct mlip_planq *q)
{
	return q->c.hold_gen != 0u && q->c.gen == q->c.hold_gen;
}

/* The plan asked from the run's state LEAD on (a hold's, a lower feed's)
 * read by the producer but its first period passed with nothing of it
 * taken (a producer late by more than its lead: its entries no longer
 * continue the run): asked again from the run's state MLIP_PLANQ_LEAD on,
 * else the run would brake on its gentle run to rest. */
static int plan_late(const struct mlip_planq *q)
{
	return q->c.sw == 0 && q->req_lead > 0 && q->c.took_gen != q->c.gen &&
	       __atomic_load_n(&q->ack, __ATOMIC_ACQUIRE) == q->c.gen &&
	       q->c.pidx > q->req_period + (uint64_t)q->req_lead;
}

/* Ask for a plan from the consumer's state (lead: after that many steps
 * of its braking run; 0 at rest) at its cap, the queue flushed (what is in
 * it continues a plan the consumer left). Only once the last request was
 * read: else asked again next period (to_ask). */
static void request(struct mlip_planq *q, int lead, int hold)
{
	if (__atomic_load_n(&q->ack, __ATOMIC_ACQUIRE) != q->c.gen) {
		q->c.to_ask = lead >= 0;
		q->c.to_ask_hold = hold;
		return;
	}
	leave(q);
	if (lead >= 0) {
		uint32_t head = __atomic_load_n(&q->head, __ATOMIC_ACQUIRE);
		__atomic_store_n(&q->tail, head, __ATOMIC_RELEASE);
		q->c.sw = 0;
	} else {
		q->c.sw = 1; /* the queue kept: the plan goes on to the switch */
	}
	q->c.gen++;
	q->c.to_ask = 0;
	q->c.to_ask_hold = 0;
	q->c.hold_gen = hold ? q->c.gen : 0u;
	/* the producer's cap, read after the request (before its next period) */
	double cap = hold ? hold_cap(q) : q->c.vmax;
	__atomic_store(&q->cap, &cap, __ATOMIC_RELAXED);
	q->req_st = q->c.st;
	q->req_period = lead < 0 ? q->c.pidx + MLIP_PLANQ_LEAD : q->c.pidx;
	q->req_end = q->c.end;
	q->req_lead = lead;
	__atomic_store_n(&q->want_gen, q->c.gen, __ATOMIC_RELEASE);
}

/* A queued switch: the producer's reply read once it is there; at its
 * period the old plan's entries beyond it are skipped (they stand before
 * the new plan's in the queue). Late: the switch is given up (the old
 * plan's entries are dropped, the queue runs dry, the run brakes). */
static void switch_over(struct mlip_planq *q)
{
	if (q->c.sw == 1 && __atomic_load_n(&q->ack, __ATOMIC_ACQUIRE) == q->c.gen) {
		q->c.sw_period = q->sw_period;
		q->c.sw_head = q->sw_head;
		q->c.sw = 2;
	}
	if (q->c.sw == 2 && q->c.pidx >= q->c.sw_period) {
		if (q->c.pidx == q->c.sw_period && q->c.mode == MLIP_PLANQ_PLAN &&
		    (int32_t)(q->c.sw_head - q->tail) >= 0) {
			__atomic_store_n(&q->tail, q->c.sw_head, __ATOMIC_RELEASE);
		}
		q->c.sw = 0;
	}
}

/* One step of the consumer's braking run on the knots freed..end. */
static int brake(struct mlip_planq *q)
{
	typedef const double(*row)[MLIP_MAX_AXES];
	uint64_t base = q->freed, a = base & KMASK;
	leave(q);
	if (q->c.st.v == 0.0 && q->c.st.a == 0.0) {
		request(q, 0, 0); /* at rest already (the last request unread) */
		q->c.mode = q->c.to_ask ? MLIP_PLANQ_BRAKE : MLIP_PLANQ_WAIT;
		return 0;
	}
	struct mlip_path_curve cv = {.n = q->n,
	                             .count = (int)(q->c.end - base + 1),
	                             .s = &q->s[a],
	                             .p = (row)q->p[a],
	                             .m = (row)q->m[a],
	                             .b = (row)q->b[a],
	                             .t3 = (row)q->t3[a]};
	if (!mlip_path_brake_step(&cv, &q->lim, &q->c.st, NULL)) {
		return -1;
	}
	int i = mlip_path_spline_piece(&cv, q->c.st.s, (int)(q->c.piece - base));
	struct mlip_path_point d;
	mlip_path_spline_eval_piece(&cv, i, q->c.st.s, q->c.x, &d);
	q->c.piece = base + (uint64_t)i;
	q->c.pidx++;
	mark(q);
	release_knots(q);
	if (q->c.st.v == 0.0 && q->c.st.a == 0.0) {
		request(q, 0, 0); /* at rest: a plan from here */
		q->c.mode = q->c.to_ask ? MLIP_PLANQ_BRAKE : MLIP_PLANQ_WAIT;
	}
	return 0;
}

void mlip_planq_rest(struct mlip_planq *q, int back)
{
	if (q->c.mode == MLIP_PLANQ_DONE) {
		return; /* the program's end: the controller has left the queue */
	}
	if (back) {
		/* its piece's knots are kept (BEHIND of the piece after it), and
		 * the producer's (MLIP_PATHRUN_LAG: the queue's length and 7) */
		q->c.st = q->c.prev_st;
		q->c.piece = q->c.prev_piece;
		memcpy(q->c.x, q->c.prev_x, sizeof(q->c.x));
	}
	if (q->c.mode == MLIP_PLANQ_WAIT && q->c.st.v == 0.0 && q->c.st.a == 0.0) {
		return; /* at rest, its plan asked already */
	}
	/* what the drives did: no plan can undo it, the plan starts again
	 * from it (time does not matter at rest) */
	q->c.st.v = 0.0;
	q->c.st.a = 0.0;
	q->c.sw = 0; /* a queued switch continued the old state */
	request(q, 0, 0);
	q->c.mode = q->c.to_ask ? MLIP_PLANQ_BRAKE : MLIP_PLANQ_WAIT;
}

int mlip_planq_feed(struct mlip_planq *q, double vmax)
{
	if (!(vmax > 0.0) || !isfinite(vmax)) {
		return -1; /* a zero feed is a hold */
	}
	q->c.want_vmax = vmax;
	return 0;
}

int mlip_planq_step(struct mlip_planq *q, int hold, double *x)
{
	int r = 0, lower = q->c.want_vmax < q->c.vmax, starved = 0;
	int hold_edge = hold && !q->c.held;
	q->c.held = hold != 0;
	q->c.periods++;
	q->c.prev_st = q->c.st;
	q->c.prev_piece = q->c.piece;
	memcpy(q->c.prev_x, q->c.x, sizeof(q->c.x));
	if (q->c.want_vmax != q->c.vmax) { /* the producer's from its next period */
		q->c.vmax = q->c.want_vmax;
		if (!on_hold_plan(q)) {
			__atomic_store(&q->cap, &q->c.vmax, __ATOMIC_RELAXED);
		}
		if (!lower && !hold && q->c.mode == MLIP_PLANQ_PLAN) {
			request(q, -1, 0); /* higher: from the queued state LEAD on */
		}
	}
	if (!hold && on_hold_plan(q) && q->c.mode == MLIP_PLANQ_PLAN) {
		/* released on it: a plan at the cap from its state LEAD on (a
		 * higher cap's switch); else its run to rest, a plan from there
		 * (never its crawl at the hold's cap) */
		request(q, -1, 0);
	}
	switch_over(q);
	int held_plan = on_hold_plan(q);
	/* held: its hold's plan while above that plan's cap */
	int plan_on = hold ? held_plan && q->c.st.v > hold_cap(q) : !lower && !held_plan;
	switch (q->c.mode) {
	case MLIP_PLANQ_WAIT:
		if (!hold) {
			pop(q);
		}
		break;
	case MLIP_PLANQ_PLAN:
		if (plan_on && pop(q)) {
			break;
		}
		starved = !hold && !lower;
		q->c.starved += starved;
		q->c.brakes += !(hold && held_plan); /* its hold's plan ends: the same hold */
		q->c.mode = MLIP_PLANQ_BRAKE;
		r = brake(q);
		break;
	case MLIP_PLANQ_BRAKE:
		/* a plan that continues the run (a lower feed's, a hold's) takes over */
		if (!plan_on || !pop(q)) {
			r = brake(q);
		}
		break;
	case MLIP_PLANQ_DONE:
		break;
	}
	int waits = q->c.mode == MLIP_PLANQ_WAIT, brakes = q->c.mode == MLIP_PLANQ_BRAKE;
	int rest = q->c.st.v == 0.0 && q->c.st.a == 0.0;
	/* a hold's plan only from a gentler policy's state (none is harder
	 * than the first) */
	int hold_ask = hold && brakes && !rest && q->c.st.v > hold_cap(q) && q->c.st.brake > 0 &&
	               (hold_edge || q->c.to_ask_hold || (on_hold_plan(q) && plan_late(q)));
	/* the queue ran dry (the producer late, not its plan): a plan from the
	 * run LEAD periods on, as for a lower feed, not the run to rest; one
	 * late (a lower feed's, a starved run's) is asked again (a hold's is
	 * hold_ask's) */
	int late_ask = !hold && brakes && !rest && !on_hold_plan(q) && (starved || plan_late(q));
	/* held while moving, a lower cap is the resumed plan's (at rest brake()
	 * asks at it): a plan for it now would replace the hold's */
	int lower_ask = lower && !(hold && !rest);
	if (r == 0 && (waits || brakes) && (lower_ask || q->c.to_ask || hold_ask || late_ask)) {
		/* a plan at the lower cap (a hold's: planq.h): from rest, or from
		 * the run's state MLIP_PLANQ_LEAD periods on */
		request(q, rest ? 0 : MLIP_PLANQ_LEAD, hold_ask);
		if (rest && !q->c.to_ask) {
			q->c.mode = MLIP_PLANQ_WAIT;
		}
	}
	__atomic_store_n(&q->pidx, q->c.pidx, __ATOMIC_RELAXED);
	memcpy(x, q->c.x, sizeof(double) * (size_t)q->n);
	return r < 0 ? -1 : (int)q->c.mode;
}
