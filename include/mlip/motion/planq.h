/*
 * mlip/motion/planq.h - the path-speed plan run ahead of the 1 ms period
 * (issue 21; the design: docs/algorithm.md "The planning thread and its
 * queue"). mlip-rt's planning thread (tools/rtplan.c) fills it.
 *
 * The plan (mlip/motion/pathrun.h) costs ~1e6 instructions a planned
 * period: a planning thread (the producer) runs it ahead and fills a
 * fixed-memory single-producer single-consumer queue of planned periods;
 * the period (the consumer) pops one a period. Each entry is a state the
 * plan certified (Q4: its policy's braking run reaches rest inside every
 * limit before the `end` the plan saw), its setpoint, and that `end` (a
 * knot). Beside the entries the producer publishes the fixed spline
 * pieces (knots) into a second ring, which the consumer frees behind
 * itself. So the consumer always holds what its state's braking run reads
 * (the pieces from its own to that `end`), and it leaves the queue for
 * that run, one policy step a period (mlip_path_brake_step, the same
 * arithmetic the certification ran):
 *   - on a hold or a stop (this period's setpoint is already the run's);
 *   - when the queue is empty (the thread fell behind).
 * It never enters a period whose braking run it does not hold: an entry
 * is pushed only after the knots to its `end`.
 *
 * At rest (the one state certified on any curve, Q4) the consumer asks
 * for a new plan from its point: a new generation, which the producer
 * takes before its next period (the pathrun's state reset to that rest;
 * the entries of the old generation are dropped, at most one a period).
 * At rest time does not matter, so the hand-over needs no clock.
 *
 * A lower feed (mlip_planq_feed) leaves the plan for the braking run at
 * once and asks for a plan at the new cap from the state that run reaches
 * MLIP_PLANQ_LEAD periods later: the run is deterministic (the same
 * policy step on the same pieces), so the producer computes that state
 * itself. The consumer takes an entry only when it continues its own
 * state bit for bit (the entry's `from`) at the next period index (or
 * from rest); a differing plan is not taken and the run goes on to rest,
 * where the plan starts again from rest (a late one is taken where it
 * still continues the run: its first states brake on the same policy
 * while above the new cap). A higher feed keeps the plan and asks for a
 * plan at the new cap from the queued state MLIP_PLANQ_LEAD periods on
 * (the producer keeps the states it queued): the consumer takes the old
 * plan's entries up to that period and skips to the new plan's (the
 * producer's reply: the period and the queue index it starts at; at least
 * MLIP_PLANQ_LEAD periods after the consumer's index when it reads the
 * request, so a late producer moves the switch, not misses it). A reply
 * read after its period leaves the old plan's queued entries, then a dry
 * queue (the braking run); the cap word also makes the producer plan at
 * the new cap from its next period.
 *
 * Lock-free as mlip/ipc/ring.h: free-running indices, the writer stores
 * its index with release after the data, the reader loads it with
 * acquire; every shared index and the request are accessed with __atomic
 * builtins. The knots are stored twice (slot g & mask and + MLIP_PLANQ_KNOTS)
 * so that any run of up to MLIP_PLANQ_KNOTS consecutive knots is one
 * contiguous struct mlip_path_curve (no copy, no wrap in the period).
 *
 * Memory: one struct, 909 KiB at 6 axes (819 KB the mirrored knots),
 * whatever the program's length. The consumer's step: a pop (O(1)) or
 * one braking step (a pick over the pieces a period crosses, as each
 * certification period; measured in docs/algorithm.md). No allocation,
 * no I/O, no lock.
 */
#ifndef MLIP_PLANQ_H
#define MLIP_PLANQ_H

#include <stdint.h>

#include "mlip/motion/pathrun.h"

/* Planned periods queued (a power of two): 256 ms ahead at 1 ms. */
#define MLIP_PLANQ_LEN        256
/* Knots held (a power of two): the pathrun's window (1,024) plus the
 * queue's span (a knot a period at most where `smooth` feeds one point a
 * period) with room. */
#define MLIP_PLANQ_KNOTS      2048
/* Periods between a lower feed and the state its new plan starts from:
 * the producer's latency (a request read before its next period, one
 * planned period) with room. */
#define MLIP_PLANQ_LEAD       16
/* A hold's plan (mlip_planq_step): the speed it brakes to, a share of the
 * plan's full cap. From there the state's own run stops in microns
 * (1 mm/s at 200 mm/s: 5 um at 0.1 A). */
#define MLIP_PLANQ_HOLD_SHARE 0.005
/* Knots kept behind the consumer's piece: a step whose speed crosses 0
 * reads pieces behind its start (pathplan.c range_at). The pathrun's
 * compaction keeps as many behind its state MLIP_PATHRUN_LAG periods back,
 * at least this queue's length plus one (the consumer's largest lag: its
 * state is the entry before its tail, and the producer queues only within
 * MLIP_PLANQ_LEN of the tail). */
#define MLIP_PLANQ_BEHIND     MLIP_PATHRUN_BEHIND
_Static_assert(MLIP_PATHRUN_LAG >= MLIP_PLANQ_LEN + 1, "the pathrun keeps the consumer's knots");

struct mlip_planq_entry {
	struct mlip_path_state st; /* at the period's end: certified (st.brake) */
	double from[3];            /* s, v, a at the period's start (the last state) */
	double x[MLIP_MAX_AXES];   /* its setpoint */
	uint64_t period;           /* the period's index (the consumer's clock) */
	uint64_t end;              /* the knot that was `end` when st was certified */
	uint64_t piece;            /* the knot starting st's piece */
	uint32_t gen;              /* the plan it belongs to */
	int last;                  /* the program's last setpoint (at rest on its point) */
};

/* The consumer's mode. */
enum mlip_planq_mode {
	MLIP_PLANQ_WAIT,  /* at rest, waiting for its plan's first entry */
	MLIP_PLANQ_PLAN,  /* popping the plan */
	MLIP_PLANQ_BRAKE, /* the braking run of its last state */
	MLIP_PLANQ_DONE,  /* at rest on the program's last point */
};

struct mlip_planq {
	struct mlip_path_limits lim;
	int n;
	/* producer's line: entries and knots published (free-running) */
	uint32_t head __attribute__((aligned(64)));
	uint64_t knots;    /* knots 0..knots-1 published (the last: s and p only) */
	uint32_t p_gen;    /* producer only: the generation it plans */
	uint64_t p_period; /* producer only: the index of its last period */
	int p_done;        /* producer only: the last entry queued */
	/* producer only: the states it queued, by period (a higher cap's
	 * plan starts from one of them) */
	struct {
		struct mlip_path_state st;
		uint64_t period;
	} p_hist[MLIP_PLANQ_LEN];
	uint64_t p_tail; /* producer only: its copy of `tail` */
	/* consumer's line */
	uint32_t tail __attribute__((aligned(64)));
	uint64_t freed; /* knots below this are no longer read by the consumer */
	/* atomic: set (before the tail passes an entry it did not pop) once
	 * the consumer has left its plan's chain (a braking step, a request):
	 * from then on the plan is mlip-rt's own and the producer's
	 * compaction may be held by `freed` (else that is a defect) */
	uint32_t left;
	uint64_t pidx; /* its period's index (atomic, a hint for a switch) */
	/* the request: the consumer writes the fields, then want_gen with
	 * release; the producer reads them after want_gen (acquire), then
	 * stores ack (release): the consumer writes a new request only once
	 * ack is its generation (the fields are never written while read) */
	uint32_t want_gen __attribute__((aligned(64)));
	uint32_t ack;
	struct mlip_path_state req_st; /* the state to plan from ... */
	uint64_t req_period;           /* ... its period's index ... */
	uint64_t req_end;              /* ... its braking run's end (knot) */
	int req_lead;                  /* its braking steps first (0: at rest;
	                                * -1: the queued state of req_period) */
	/* the producer's reply (before ack): its new plan follows the queued
	 * period sw_period, its entries from queue index sw_head on */
	uint64_t sw_period;
	uint32_t sw_head;
	/* the consumer's speed cap (atomic): the producer plans at it from
	 * its next period (a higher cap needs no hand-over: the states it
	 * certified stay certified) */
	double cap;
	/* consumer only */
	struct {
		enum mlip_planq_mode mode;
		struct mlip_path_state st;
		uint64_t end, piece;
		uint64_t pidx; /* the index of the period of st */
		uint32_t gen;
		double vmax, want_vmax; /* the cap planned, the cap asked */
		int to_ask;             /* a plan is to be asked (the last unread) */
		int to_ask_hold;        /* ... a hold's (at the hold's cap) */
		int held;               /* the hold seen (its first period acted on) */
		uint32_t hold_gen;      /* the hold's plan (0: none) */
		uint32_t took_gen;      /* the plan of the last entry taken */
		int sw;                 /* a queued switch: 1 asked, 2 its reply read */
		uint64_t sw_period;
		uint32_t sw_head;
		double x[MLIP_MAX_AXES];
		/* the state, setpoint and piece a period back (mlip_planq_rest:
		 * its frames withheld, that setpoint is where the drives stand) */
		struct mlip_path_state prev_st;
		double prev_x[MLIP_MAX_AXES];
		uint64_t prev_piece;
		/* where st lies: the record executing (seq, line: the mark of
		 * its piece's far knot, the record whose motion made that piece)
		 * and the last one completed (done_seq, done_line: its near
		 * knot's); each never goes back (0: none yet) */
		struct mlip_pathrun_tag mark;
		long starved, brakes, periods; /* figures */
		int left;                      /* its copy of `left` */
	} c __attribute__((aligned(64)));
	struct mlip_planq_entry e[MLIP_PLANQ_LEN];
	/* the program's first record (the producer's, before its first
	 * entry): 1 its start, N > 1 a continuation after record N - 1 */
	uint64_t first_seq;
	/* its END record (written before the last entry is queued; 0: not
	 * known), which no knot carries: the follower's at the last entry */
	uint64_t end_seq;
	uint32_t end_line;
	/* knot g's record marks (the pathrun's tags) at g & mask: the
	 * consumer reads two at a time, never as a curve */
	struct mlip_pathrun_tag tag[MLIP_PLANQ_KNOTS];
	/* knots g at g & mask and (g & mask) + MLIP_PLANQ_KNOTS */
	double s[2 * MLIP_PLANQ_KNOTS];
	double p[2 * MLIP_PLANQ_KNOTS][MLIP_MAX_AXES];
	double m[2 * MLIP_PLANQ_KNOTS][MLIP_MAX_AXES];
	double b[2 * MLIP_PLANQ_KNOTS][MLIP_MAX_AXES];
	double t3[2 * MLIP_PLANQ_KNOTS][MLIP_MAX_AXES];
};

/* Before either side runs: empty, the consumer at rest at pr's start
 * (WAIT, generation 0, which the producer plans first). pr as after
 * mlip_pathrun_init. */
void mlip_planq_init(struct mlip_planq *q, const struct mlip_pathrun *pr);

/* The producer (the planning thread): one planned period from pr into
 * the queue. 1 queued, 2 the last is queued (nothing more until a new
 * request), 0 no room (queue or knots full: try later), 3 pr needs input
 * first (push, or finish), -1 refused (pr->why). It takes the consumer's
 * request first (a new plan from rest at its point). */
int mlip_planq_produce(struct mlip_planq *q, struct mlip_pathrun *pr);

/* The consumer: a new speed cap (the feed override's: vmax of the limits'
 * vfull; the knots' caps scale with it, pathplan.h Q5). A lower one acts
 * in the next step (the braking run, then the plan at that cap); a higher
 * one from the queued state MLIP_PLANQ_LEAD periods on. -1 (ignored) when
 * not positive and finite (a zero feed is a hold). */
int mlip_planq_feed(struct mlip_planq *q, double vmax);

/* The consumer: a stall (the period missed, the drives stood at its last
 * setpoint while the plan's clock ran). Its state becomes a rest there
 * and a plan from it is asked, as at the end of a braking run: the next
 * setpoints repeat the last one (never a step from where the drives
 * stood), and motion continues from rest. back: the last step's frames
 * were withheld (a stall between the period's work and its send), the
 * rest is at the state a period before it. Nothing when at rest. */
void mlip_planq_rest(struct mlip_planq *q, int back);

/* The consumer (the period): this period's setpoint in x (n axes); hold
 * non-zero: leave the plan for the braking run now, stay at rest while it
 * holds. Returns the mode after the step. Pure apart from the queue: O(1)
 * in the plan, one braking step when braking. -1 when the braking policy
 * has no jerk (a state not certified: a defect; the setpoint held).
 *
 * A hold brakes by its state's policy at once, which on a tight curve may
 * be the gentlest (0.1 A: the harder ones' runs break a limit there), and
 * asks for a hold's plan: from the run's state MLIP_PLANQ_LEAD periods on,
 * at MLIP_PLANQ_HOLD_SHARE of the cap. The producer's plan above its cap
 * is that run, each state taking the hardest policy that certifies it
 * (mlip_path_plan_period), so once past the curve it brakes hard; the
 * consumer takes it where it continues its run, down to that speed, and
 * from there brakes to rest on its own. A hold's plan that comes after its
 * first period (a late producer) is asked again from the run's state then,
 * as is a lower feed's. A queue run dry (the producer late) brakes the
 * same way and asks for a plan from the run's state MLIP_PLANQ_LEAD
 * periods on: back in time, the producer takes the run up again.
 * A lower feed while held and moving is the resumed plan's cap (asked at
 * rest), never a plan that replaces the hold's. */
int mlip_planq_step(struct mlip_planq *q, int hold, double *x);

#endif
