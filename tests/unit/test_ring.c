/*
 * test_ring.c - SPSC ring, attach checks, status seqlocks and command mailbox.
 * The stress tests use two pthreads (producer / consumer, ctl / controller).
 */
#include <pthread.h>
#include <sched.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "mlip/ctl/state.h"
#include "mlip/ipc/ring.h"

/* records through the ring in the stress test: 10 M (about 0.5 s at -O2);
 * 2 M under ASan/TSan, which are there for races and overflows, not volume
 * (10 M take about 10 s there: build with -DSTRESS_RECORDS=10000000u for it) */
#ifndef STRESS_RECORDS
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define STRESS_RECORDS 2000000u
#else
#define STRESS_RECORDS 10000000u
#endif
#endif
#define STRESS_CAPACITY 1024u
#define CAP             8u

/* one aligned buffer big enough for every test but the stress one */
static unsigned char seg[4096] __attribute__((aligned(MLIP_RING_LINE)));

static struct mlip_ring *fresh(uint32_t capacity, int n_axes)
{
	struct mlip_ring *r = NULL;

	assert_int_equal(mlip_ring_format(seg, sizeof(seg), capacity, n_axes), MLIP_OK);
	assert_int_equal(mlip_ring_attach(seg, sizeof(seg), n_axes, &r, NULL), MLIP_OK);
	assert_non_null(r);
	return r;
}

/* a record whose every field is a function of k, so content can be checked */
static void make_rec(struct mlip_ring_rec *rec, uint64_t k)
{
	int i;

	memset(rec, 0, sizeof(*rec));
	rec->seq = k;
	rec->line = (uint32_t)(k * 7u + 1u);
	rec->flags = (uint16_t)(k & 1u);
	for (i = 0; i < MLIP_MAX_AXES; i++) {
		rec->target[i] = (double)k + 0.25 * i;
	}
	rec->feed_mm_s = (double)(k % 1000u);
	rec->tol_mm = 0.01;
}

static int rec_ok(const struct mlip_ring_rec *rec, uint64_t k)
{
	struct mlip_ring_rec want;

	make_rec(&want, k);
	return memcmp(rec, &want, sizeof(want)) == 0;
}

/* ---- layout and format ------------------------------------------------ */

static void test_layout(void **state)
{
	(void)state;
	assert_int_equal(sizeof(struct mlip_ring_rec), 88);
	assert_int_equal(sizeof(struct mlip_ring), 1472);
	assert_int_equal(mlip_ring_bytes(1), 1472 + 88);
	assert_int_equal(mlip_ring_bytes(8), 1472 + 8 * 88);
	assert_int_equal(mlip_ring_bytes(0), 0);
	assert_int_equal(mlip_ring_bytes(12), 0);
	assert_int_equal(mlip_ring_bytes(MLIP_RING_MAX_CAPACITY * 2u), 0);
	assert_true(mlip_ring_bytes(MLIP_RING_MAX_CAPACITY) > 0);
}

static void test_format_rejects(void **state)
{
	(void)state;
	assert_int_equal(mlip_ring_format(NULL, sizeof(seg), CAP, 3), MLIP_E_INVALID);
	assert_int_equal(mlip_ring_format(seg + 8, sizeof(seg) - 8, CAP, 3), MLIP_E_INVALID);
	assert_int_equal(mlip_ring_format(seg, sizeof(seg), 0, 3), MLIP_E_INVALID);
	assert_int_equal(mlip_ring_format(seg, sizeof(seg), 12, 3), MLIP_E_INVALID);
	assert_int_equal(mlip_ring_format(seg, sizeof(seg), CAP, 0), MLIP_E_INVALID);
	assert_int_equal(mlip_ring_format(seg, sizeof(seg), CAP, MLIP_MAX_AXES + 1),
	                 MLIP_E_INVALID);
	/* one byte short of header + records, then exactly enough */
	assert_int_equal(mlip_ring_format(seg, mlip_ring_bytes(CAP) - 1, CAP, 3), MLIP_E_INVALID);
	assert_int_equal(mlip_ring_format(seg, mlip_ring_bytes(CAP), CAP, 3), MLIP_OK);
}

static void test_format_fresh_state(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);
	struct mlip_ring_status st;
	struct mlip_ring_feeder fd;
	struct mlip_ring_cmd cmd;

	(void)state;
	assert_memory_equal(seg, MLIP_RING_MAGIC, 8);
	assert_int_equal(r->capacity, CAP);
	assert_int_equal(r->n_axes, 3);
	assert_int_equal(mlip_ring_count(r), 0);
	assert_int_equal(mlip_ring_space(r), CAP);
	assert_int_equal(mlip_ring_status_read(r, &st), MLIP_OK);
	assert_int_equal(st.state, MLIP_STATE_IDLE);
	assert_int_equal(st.override_pct, 100);
	assert_int_equal(st.heartbeat, 0);
	assert_int_equal(mlip_ring_feeder_read(r, &fd), MLIP_OK);
	assert_int_equal(fd.pid, 0);
	assert_int_equal(fd.program_end, 0);
	assert_int_equal(mlip_ring_cmd_take(r, &cmd), MLIP_E_EMPTY);
}

/* ---- push / pop --------------------------------------------------------- */

static void test_push_pop_order(void **state)
{
	struct mlip_ring *r = fresh(CAP, 6);
	struct mlip_ring_rec rec;
	uint64_t k;

	(void)state;
	for (k = 1; k <= 5; k++) {
		make_rec(&rec, k);
		assert_int_equal(mlip_ring_push(r, &rec), MLIP_OK);
	}
	assert_int_equal(mlip_ring_count(r), 5);
	for (k = 1; k <= 5; k++) {
		assert_int_equal(mlip_ring_peek(r, &rec), MLIP_OK);
		assert_true(rec_ok(&rec, k));
		memset(&rec, 0, sizeof(rec));
		assert_int_equal(mlip_ring_pop(r, &rec), MLIP_OK);
		assert_true(rec_ok(&rec, k));
	}
	assert_int_equal(mlip_ring_pop(r, &rec), MLIP_E_EMPTY);
}

static void test_full_empty(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);
	struct mlip_ring_rec rec;
	uint32_t k;

	(void)state;
	assert_int_equal(mlip_ring_peek(r, &rec), MLIP_E_EMPTY);
	assert_int_equal(mlip_ring_pop(r, &rec), MLIP_E_EMPTY);
	assert_int_equal(mlip_ring_pop(r, NULL), MLIP_E_EMPTY);
	for (k = 0; k < CAP; k++) {
		assert_int_equal(mlip_ring_space(r), CAP - k);
		make_rec(&rec, k);
		assert_int_equal(mlip_ring_push(r, &rec), MLIP_OK);
		assert_int_equal(mlip_ring_count(r), k + 1);
	}
	make_rec(&rec, 99);
	assert_int_equal(mlip_ring_push(r, &rec), MLIP_E_FULL);
	assert_int_equal(mlip_ring_count(r), CAP);
	assert_int_equal(mlip_ring_space(r), 0);
	/* one slot freed: exactly one push fits again */
	assert_int_equal(mlip_ring_pop(r, NULL), MLIP_OK);
	assert_int_equal(mlip_ring_push(r, &rec), MLIP_OK);
	assert_int_equal(mlip_ring_push(r, &rec), MLIP_E_FULL);
	for (k = 1; k < CAP; k++) {
		assert_int_equal(mlip_ring_pop(r, &rec), MLIP_OK);
		assert_true(rec_ok(&rec, k));
	}
	assert_int_equal(mlip_ring_pop(r, &rec), MLIP_OK);
	assert_true(rec_ok(&rec, 99));
	assert_int_equal(mlip_ring_count(r), 0);
	assert_int_equal(mlip_ring_pop(r, &rec), MLIP_E_EMPTY);
}

/* free-running indices cross UINT32_MAX -> 0 while the ring is in use */
static void test_wraparound(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);
	struct mlip_ring_rec rec, batch[5];
	uint64_t next_in = 0, next_out = 0;
	uint32_t round, i, n;

	(void)state;
	mlip_ring_reset(r, UINT32_MAX - 5u);
	assert_int_equal(mlip_ring_count(r), 0);
	for (round = 0; round < 40; round++) {
		/* fill up to full, checking count on the way */
		while (mlip_ring_space(r) > 0) {
			make_rec(&rec, next_in);
			assert_int_equal(mlip_ring_push(r, &rec), MLIP_OK);
			next_in++;
			assert_int_equal(mlip_ring_count(r), (uint32_t)(next_in - next_out));
		}
		make_rec(&rec, 12345);
		assert_int_equal(mlip_ring_push(r, &rec), MLIP_E_FULL);
		/* drain a varying amount */
		n = 1u + round % CAP;
		for (i = 0; i < n; i++) {
			assert_int_equal(mlip_ring_pop(r, &rec), MLIP_OK);
			assert_true(rec_ok(&rec, next_out));
			next_out++;
		}
	}
	/* indices really did wrap */
	assert_true(r->head < 1000u && r->tail < 1000u);
	/* batch pop across the wrap, then drain */
	while ((n = mlip_ring_pop_n(r, batch, 5)) > 0) {
		for (i = 0; i < n; i++) {
			assert_true(rec_ok(&batch[i], next_out));
			next_out++;
		}
	}
	assert_int_equal(next_out, next_in);
	assert_int_equal(mlip_ring_count(r), 0);
}

static void test_batch(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);
	struct mlip_ring_rec in[2 * CAP], out[2 * CAP];
	uint32_t k;

	(void)state;
	for (k = 0; k < 2 * CAP; k++) {
		make_rec(&in[k], k);
	}
	mlip_ring_reset(r, UINT32_MAX - 2u); /* the batch copy splits at the array end too */
	assert_int_equal(mlip_ring_push_n(r, in, 3), 3);
	assert_int_equal(mlip_ring_push_n(r, in + 3, 2 * CAP - 3), CAP - 3); /* only what fits */
	assert_int_equal(mlip_ring_push_n(r, in, 1), 0);
	assert_int_equal(mlip_ring_push_n(r, in, 0), 0);
	assert_int_equal(mlip_ring_pop_n(r, out, 0), 0);
	assert_int_equal(mlip_ring_pop_n(r, out, 5), 5);
	for (k = 0; k < 5; k++) {
		assert_true(rec_ok(&out[k], k));
	}
	assert_int_equal(mlip_ring_push_n(r, in + CAP, 2 * CAP), 5);
	assert_int_equal(mlip_ring_pop_n(r, out, 2 * CAP), CAP);
	for (k = 0; k < CAP; k++) {
		assert_true(rec_ok(&out[k], k + 5));
	}
	/* discard with a NULL destination */
	assert_int_equal(mlip_ring_push_n(r, in, 4), 4);
	assert_int_equal(mlip_ring_pop_n(r, NULL, 100), 4);
	assert_int_equal(mlip_ring_count(r), 0);
}

static void test_rec_block(void **state)
{
	struct mlip_block b, back;
	struct mlip_ring_rec rec;
	int i;

	(void)state;
	memset(&b, 0, sizeof(b));
	for (i = 0; i < MLIP_MAX_AXES; i++) {
		b.target[i] = -1.5 * i;
	}
	b.feed_mm_s = 50.0;
	b.tol_mm = 0.002;
	b.line = 42;
	b.rapid = 1;
	mlip_ring_rec_from_block(&rec, &b, 7);
	assert_int_equal(rec.seq, 7);
	assert_int_equal(rec.flags, MLIP_REC_RAPID);
	assert_int_equal(mlip_ring_rec_to_block(&rec, &back), MLIP_OK);
	b.seq = 7; /* the record number travels back in the block */
	assert_memory_equal(&b, &back, sizeof(b));
	b.rapid = 0;
	mlip_ring_rec_from_block(&rec, &b, 8);
	assert_int_equal(rec.flags, 0);
	mlip_ring_rec_end(&rec, 9, 100);
	assert_int_equal(rec.type, MLIP_REC_END);
	assert_int_equal(rec.seq, 9);
	assert_int_equal(rec.line, 100);
	assert_int_equal(mlip_ring_rec_to_block(&rec, &back), MLIP_E_EMPTY);
}

/* ---- attach mismatches ---------------------------------------------------- */

static void expect_refused(size_t bytes, int n_axes, mlip_ring_reason reason, uint64_t found,
                           uint64_t expected)
{
	struct mlip_ring *r = (struct mlip_ring *)(void *)1; /* must be cleared */
	struct mlip_ring_mismatch why;

	assert_int_equal(mlip_ring_attach(seg, bytes, n_axes, &r, &why), MLIP_E_INVALID);
	assert_null(r);
	assert_int_equal(why.reason, reason);
	assert_int_equal(why.found, found);
	assert_int_equal(why.expected, expected);
}

static void test_attach_ok(void **state)
{
	struct mlip_ring *r = NULL;
	struct mlip_ring_mismatch why;

	(void)state;
	assert_int_equal(mlip_ring_format(seg, sizeof(seg), CAP, 4), MLIP_OK);
	assert_int_equal(mlip_ring_attach(seg, mlip_ring_bytes(CAP), 4, &r, &why), MLIP_OK);
	assert_ptr_equal(r, seg);
	assert_int_equal(why.reason, MLIP_RING_MATCH);
	/* n_axes 0: any */
	assert_int_equal(mlip_ring_attach(seg, sizeof(seg), 0, &r, NULL), MLIP_OK);
	/* bad arguments */
	assert_int_equal(mlip_ring_attach(seg, sizeof(seg), 0, NULL, &why), MLIP_E_INVALID);
	assert_int_equal(why.reason, MLIP_RING_BAD_ARG);
	assert_int_equal(mlip_ring_attach(NULL, sizeof(seg), 0, &r, &why), MLIP_E_INVALID);
	assert_int_equal(why.reason, MLIP_RING_BAD_ARG);
	assert_int_equal(mlip_ring_attach(seg + 16, sizeof(seg) - 16, 0, &r, &why), MLIP_E_INVALID);
	assert_int_equal(why.reason, MLIP_RING_BAD_ALIGN);
	assert_int_equal(why.found, 16);
}

static void test_attach_bad_magic(void **state)
{
	uint64_t want;

	(void)state;
	memcpy(&want, MLIP_RING_MAGIC, 8);
	memset(seg, 0, sizeof(seg)); /* never formatted */
	expect_refused(sizeof(seg), 0, MLIP_RING_BAD_MAGIC, 0, want);
	assert_int_equal(mlip_ring_format(seg, sizeof(seg), CAP, 3), MLIP_OK);
	seg[7] = 'X';
	assert_int_equal(mlip_ring_attach(seg, sizeof(seg), 0, &(struct mlip_ring *){NULL}, NULL),
	                 MLIP_E_INVALID);
}

static void test_attach_bad_version(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);

	(void)state;
	r->version = MLIP_RING_VERSION + 1u;
	expect_refused(sizeof(seg), 3, MLIP_RING_BAD_VERSION, MLIP_RING_VERSION + 1u,
	               MLIP_RING_VERSION);
}

static void test_attach_bad_record(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);

	(void)state;
	r->rec_bytes = 72;
	expect_refused(sizeof(seg), 3, MLIP_RING_BAD_RECORD, 72, 88);
	r->rec_bytes = 88;
	r->hdr_bytes = 512;
	expect_refused(sizeof(seg), 3, MLIP_RING_BAD_HEADER, 512, 1472);
}

static void test_attach_bad_capacity(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);

	(void)state;
	r->capacity = 6; /* not a power of two */
	r->mask = 5;
	expect_refused(sizeof(seg), 3, MLIP_RING_BAD_CAPACITY, 6, MLIP_RING_MAX_CAPACITY);
	r->capacity = 0;
	r->mask = UINT32_MAX;
	expect_refused(sizeof(seg), 3, MLIP_RING_BAD_CAPACITY, 0, MLIP_RING_MAX_CAPACITY);
	r->capacity = 8; /* mask inconsistent */
	r->mask = 3;
	expect_refused(sizeof(seg), 3, MLIP_RING_BAD_CAPACITY, 8, MLIP_RING_MAX_CAPACITY);
}

static void test_attach_bad_axes(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);

	(void)state;
	expect_refused(sizeof(seg), 5, MLIP_RING_BAD_AXES, 3, 5); /* feeder configured for 5 */
	r->n_axes = 0;
	expect_refused(sizeof(seg), 0, MLIP_RING_BAD_AXES, 0, MLIP_MAX_AXES);
	r->n_axes = MLIP_MAX_AXES + 1;
	expect_refused(sizeof(seg), 0, MLIP_RING_BAD_AXES, MLIP_MAX_AXES + 1, MLIP_MAX_AXES);
}

static void test_attach_too_small(void **state)
{
	(void)state;
	fresh(CAP, 3);
	expect_refused(100, 3, MLIP_RING_SHORT, 100, 1472);
	expect_refused(1023, 3, MLIP_RING_SHORT, 1023, 1472);
	/* header fits, records do not: one byte short, then exactly enough */
	expect_refused(mlip_ring_bytes(CAP) - 1, 3, MLIP_RING_TRUNCATED, mlip_ring_bytes(CAP) - 1,
	               mlip_ring_bytes(CAP));
	expect_refused(1472, 3, MLIP_RING_TRUNCATED, 1472, mlip_ring_bytes(CAP));
	assert_int_equal(
	    mlip_ring_attach(seg, mlip_ring_bytes(CAP), 3, &(struct mlip_ring *){NULL}, NULL),
	    MLIP_OK);
}

static void test_reason_strings(void **state)
{
	int k;

	(void)state;
	assert_string_equal(mlip_ring_reason_str(MLIP_RING_BAD_VERSION), "layout version");
	assert_string_equal(mlip_ring_reason_str(MLIP_RING_BAD_AXES), "axis count");
	for (k = MLIP_RING_MATCH; k <= MLIP_RING_TRUNCATED; k++) {
		assert_non_null(mlip_ring_reason_str((mlip_ring_reason)k));
		assert_string_not_equal(mlip_ring_reason_str((mlip_ring_reason)k), "?");
	}
	assert_string_equal(mlip_ring_reason_str((mlip_ring_reason)99), "?");
	assert_string_equal(mlip_ctl_state_name(MLIP_STATE_HELD), "held");
	assert_string_equal(mlip_ctl_state_name(77), "?");
	assert_string_equal(mlip_ring_cmd_name(MLIP_CMD_OVERRIDE), "override");
	assert_string_equal(mlip_ring_cmd_name(MLIP_CMD_COUNT), "?");
}

/* ---- status, feeder, mailbox ------------------------------------------- */

static void test_status_feeder(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);
	struct mlip_ring_status s, got;
	struct mlip_ring_feeder f, fgot;

	(void)state;
	memset(&s, 0, sizeof(s));
	s.heartbeat = 123456789012ull;
	s.heartbeat_ns = 0xfedcba9876543210ull;
	s.exec_seq = 77;
	s.exec_line = 1234;
	s.state = MLIP_STATE_RUNNING;
	s.override_pct = 150;
	s.overruns = 1;
	s.underruns = 2;
	s.can_tx_errors = 3;
	s.can_bus_errors = 4;
	s.frames_sent = 5;
	s.blocks_consumed = 6;
	s.prog_start[0] = -12.5;
	s.prog_start[MLIP_MAX_AXES - 1] = 7.25;
	s.stop_seen = 0xfffffffeu;
	s.held_by = MLIP_WHY_HOLD; /* the last field, carried too */
	mlip_ring_status_write(r, &s);
	assert_int_equal(r->status_gen, 2);
	assert_int_equal(mlip_ring_status_read(r, &got), MLIP_OK);
	assert_memory_equal(&s, &got, sizeof(s));
	/* a writer that died mid-update: readers give up instead of spinning */
	r->status_gen = 3;
	assert_int_equal(mlip_ring_status_read(r, &got), MLIP_E_EMPTY);

	f.heartbeat = 9;
	f.heartbeat_ns = 10;
	f.total_blocks = 11;
	f.program_end = 1;
	f.pid = 4242;
	f.stop_base = 77;
	f.mdi = 0;
	mlip_ring_feeder_write(r, &f);
	assert_int_equal(mlip_ring_feeder_read(r, &fgot), MLIP_OK);
	assert_memory_equal(&f, &fgot, sizeof(f));
	r->feeder_gen = 5;
	assert_int_equal(mlip_ring_feeder_read(r, &fgot), MLIP_E_EMPTY);
}

static void test_mailbox(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);
	struct mlip_ring_cmd cmd;
	uint32_t s1, s2;
	int32_t res;

	(void)state;
	assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_NONE, 0, &s1), MLIP_E_INVALID);
	assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_COUNT, 0, &s1), MLIP_E_INVALID);
	assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_STOP, 0, &s1), MLIP_E_INVALID);
	assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_OVERRIDE, MLIP_RING_CMD_ARG_MAX + 1, &s1),
	                 MLIP_E_RANGE);
	assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_OVERRIDE, 80, &s1), MLIP_OK);
	assert_int_equal(s1, 1);
	assert_int_equal(mlip_ring_cmd_result(r, s1, &res), MLIP_E_EMPTY);
	/* never lost: a second post is refused until the first is completed */
	assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_HOLD, 0, &s2), MLIP_E_FULL);
	assert_int_equal(mlip_ring_cmd_take(r, &cmd), MLIP_OK);
	assert_int_equal(cmd.seq, s1);
	assert_int_equal(cmd.op, MLIP_CMD_OVERRIDE);
	assert_int_equal(cmd.arg, 80);
	/* never twice: taken once, nothing new until the next post */
	assert_int_equal(mlip_ring_cmd_take(r, &cmd), MLIP_E_EMPTY);
	/* taken but not completed: still refused */
	assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_HOLD, 0, &s2), MLIP_E_FULL);
	mlip_ring_cmd_done(r, s1, MLIP_OK);
	assert_int_equal(mlip_ring_cmd_result(r, s1, &res), MLIP_OK);
	assert_int_equal(res, MLIP_OK);
	assert_int_equal(mlip_ring_cmd_take(r, &cmd), MLIP_E_EMPTY);

	assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_OVERRIDE, 900, &s2), MLIP_OK);
	assert_int_equal(s2, 2);
	assert_int_equal(mlip_ring_cmd_take(r, &cmd), MLIP_OK);
	assert_int_equal(cmd.arg, 900);
	mlip_ring_cmd_done(r, cmd.seq, MLIP_E_RANGE); /* refused by the controller */
	assert_int_equal(mlip_ring_cmd_result(r, s2, &res), MLIP_OK);
	assert_int_equal(res, MLIP_E_RANGE);
	/* an earlier command keeps its own result (another mlip-ctl posted
	 * after it before it read it) */
	assert_int_equal(mlip_ring_cmd_result(r, s1, &res), MLIP_OK);
	assert_int_equal(res, MLIP_OK);

	/* the argument's sign survives the packing, at both ends of its range */
	int32_t args[] = {MLIP_RING_CMD_ARG_MIN, -1, 0, MLIP_RING_CMD_ARG_MAX};
	for (unsigned k = 0; k < sizeof(args) / sizeof(args[0]); k++) {
		assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_OPTIONAL_STOP, args[k], &s1),
		                 MLIP_OK);
		assert_int_equal(mlip_ring_cmd_take(r, &cmd), MLIP_OK);
		assert_int_equal(cmd.arg, args[k]);
		assert_int_equal(cmd.op, MLIP_CMD_OPTIONAL_STOP);
		mlip_ring_cmd_done(r, cmd.seq, MLIP_OK);
	}

	/* whatever a dead or hostile poster left in the word (an old layout's
	 * claim: an odd sequence, no op) is one command: taken, refused by the
	 * controller as unknown, completed; the mailbox is free again */
	__atomic_store_n(&r->cmd_word, (uint64_t)12345, __ATOMIC_RELEASE);
	assert_int_equal(mlip_ring_cmd_take(r, &cmd), MLIP_OK);
	assert_int_equal(cmd.seq, 12345);
	assert_int_equal(cmd.op, MLIP_CMD_NONE);
	mlip_ring_cmd_done(r, cmd.seq, MLIP_E_INVALID);
	assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_HOLD, 0, &s1), MLIP_OK);
	assert_int_equal(s1, 12346);
	/* the sequence wraps past 0 (0: nothing taken yet) */
	mlip_ring_cmd_take(r, &cmd);
	mlip_ring_cmd_done(r, cmd.seq, MLIP_OK);
	__atomic_store_n(&r->cmd_word, (uint64_t)UINT32_MAX, __ATOMIC_RELEASE);
	r->cmd_done = UINT32_MAX;
	r->cmd_taken = UINT32_MAX;
	assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_HOLD, 0, &s1), MLIP_OK);
	assert_int_equal(s1, 1);
	assert_int_equal(mlip_ring_cmd_take(r, &cmd), MLIP_OK);
	assert_int_equal(cmd.seq, 1);
}

/* Stop has its own path: a counter, never refused, never behind the
 * mailbox; applied and "after a feeder's start" are modular. */
static void test_stop_counter(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);
	uint32_t seq;

	(void)state;
	assert_int_equal(mlip_ring_stop_count(r), 0);
	/* the mailbox busy (posted, never completed): stop still goes in */
	assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_HOLD, 0, &seq), MLIP_OK);
	assert_int_equal(mlip_ring_cmd_post(r, MLIP_CMD_RESUME, 0, &seq), MLIP_E_FULL);
	assert_int_equal(mlip_ring_stop_post(r), 1);
	assert_int_equal(mlip_ring_stop_post(r), 2);
	assert_int_equal(mlip_ring_stop_count(r), 2);
	assert_false(mlip_ring_stop_applied(1, 2));
	assert_true(mlip_ring_stop_applied(2, 2));
	assert_true(mlip_ring_stop_applied(3, 2));
	assert_true(mlip_ring_stop_applied(1, UINT32_MAX)); /* wrapped past it */
	assert_false(mlip_ring_stop_applied(UINT32_MAX, 1));
	/* a feeder that began at count b: only a stop seen after it counts */
	assert_false(mlip_ring_stop_after(5, 5));
	assert_true(mlip_ring_stop_after(6, 5));
	assert_false(mlip_ring_stop_after(4, 5));
	assert_true(mlip_ring_stop_after(0, UINT32_MAX));
}

/* ---- two-thread tests --------------------------------------------------- */

struct stress {
	struct mlip_ring *r;
	uint64_t n;
	uint64_t bad; /* consumer: records out of order or corrupted */
	uint64_t got;
};

static void *producer(void *arg)
{
	struct stress *t = arg;
	struct mlip_ring_rec batch[16];
	uint64_t next = 1;
	uint32_t want, i, done;
	unsigned spins = 0;

	while (next <= t->n) {
		if (next & 1u) { /* single pushes and batches, alternately */
			make_rec(&batch[0], next);
			if (mlip_ring_push(t->r, &batch[0]) == MLIP_OK) {
				next++;
				spins = 0;
			} else if (++spins > 64u) {
				sched_yield();
			}
			continue;
		}
		want = (uint32_t)(1u + next % 16u);
		if (want > t->n - next + 1u) {
			want = (uint32_t)(t->n - next + 1u);
		}
		for (i = 0; i < want; i++) {
			make_rec(&batch[i], next + i);
		}
		done = 0;
		while (done < want) {
			i = mlip_ring_push_n(t->r, batch + done, want - done);
			done += i;
			if (i == 0 && ++spins > 64u) {
				sched_yield();
			}
		}
		next += want;
		spins = 0;
	}
	return NULL;
}

static void *consumer(void *arg)
{
	struct stress *t = arg;
	struct mlip_ring_rec batch[24];
	uint64_t expect = 1;
	uint32_t n, i;
	unsigned spins = 0;

	while (expect <= t->n) {
		n = mlip_ring_pop_n(t->r, batch, (uint32_t)(1u + expect % 24u));
		if (n == 0) {
			if (++spins > 64u) {
				sched_yield();
			}
			continue;
		}
		spins = 0;
		for (i = 0; i < n; i++) {
			if (!rec_ok(&batch[i], expect)) {
				t->bad++;
			}
			expect++;
		}
		t->got += n;
	}
	return NULL;
}

static void test_stress_spsc(void **state)
{
	size_t bytes = mlip_ring_bytes(STRESS_CAPACITY);
	void *mem = NULL;
	struct stress t;
	pthread_t p, c;

	(void)state;
	assert_int_equal(posix_memalign(&mem, MLIP_RING_LINE, bytes), 0);
	assert_int_equal(mlip_ring_format(mem, bytes, STRESS_CAPACITY, MLIP_MAX_AXES), MLIP_OK);
	memset(&t, 0, sizeof(t));
	assert_int_equal(mlip_ring_attach(mem, bytes, MLIP_MAX_AXES, &t.r, NULL), MLIP_OK);
	mlip_ring_reset(t.r, UINT32_MAX - 100000u); /* wrap mid-run */
	t.n = STRESS_RECORDS;
	assert_int_equal(pthread_create(&c, NULL, consumer, &t), 0);
	assert_int_equal(pthread_create(&p, NULL, producer, &t), 0);
	assert_int_equal(pthread_join(p, NULL), 0);
	assert_int_equal(pthread_join(c, NULL), 0);
	assert_int_equal(t.bad, 0);
	assert_int_equal(t.got, STRESS_RECORDS);
	assert_int_equal(mlip_ring_count(t.r), 0);
	free(mem);
}

/* ctl thread posts N commands, controller thread takes and completes them:
 * each applied exactly once, in order; status snapshots never torn. */
#define MAILBOX_CMDS 20000

struct box {
	struct mlip_ring *r;
	int stop; /* atomic */
	uint64_t applied_sum;
	int applied;
	int order_bad;
	int torn;
};

static void *controller(void *arg)
{
	struct box *b = arg;
	struct mlip_ring_cmd cmd;
	struct mlip_ring_status s;
	int32_t last = -1;
	uint64_t k = 0;

	memset(&s, 0, sizeof(s));
	while (!__atomic_load_n(&b->stop, __ATOMIC_ACQUIRE)) {
		if (mlip_ring_cmd_take(b->r, &cmd) == MLIP_OK) {
			if (cmd.arg != last + 1 || cmd.op != MLIP_CMD_OVERRIDE) {
				b->order_bad++;
			}
			last = cmd.arg;
			b->applied++;
			b->applied_sum += (uint64_t)cmd.arg;
			mlip_ring_cmd_done(b->r, cmd.seq, cmd.arg % 2 ? MLIP_E_RANGE : MLIP_OK);
		}
		/* every field of the snapshot equal to k: a torn read would mix */
		k++;
		s.heartbeat = s.heartbeat_ns = s.exec_seq = s.overruns = s.underruns = k;
		s.can_tx_errors = s.can_bus_errors = s.frames_sent = s.blocks_consumed = k;
		s.exec_line = s.state = s.override_pct = s.reserved = (uint32_t)k;
		mlip_ring_status_write(b->r, &s);
	}
	return NULL;
}

static void test_stress_mailbox(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);
	struct mlip_ring_status s;
	struct box b;
	pthread_t c;
	uint32_t seq;
	int32_t res;
	int i, reads = 0;

	(void)state;
	memset(&b, 0, sizeof(b));
	b.r = r;
	assert_int_equal(pthread_create(&c, NULL, controller, &b), 0);
	for (i = 0; i < MAILBOX_CMDS; i++) {
		while (mlip_ring_cmd_post(r, MLIP_CMD_OVERRIDE, i, &seq) != MLIP_OK) {
			sched_yield();
		}
		while (mlip_ring_cmd_result(r, seq, &res) != MLIP_OK) {
			if (mlip_ring_status_read(r, &s) == MLIP_OK) {
				reads++;
				if (s.heartbeat_ns != s.heartbeat ||
				    s.blocks_consumed != s.heartbeat ||
				    s.reserved != (uint32_t)s.heartbeat) {
					b.torn++;
				}
			}
		}
		assert_int_equal(res, i % 2 ? MLIP_E_RANGE : MLIP_OK);
	}
	__atomic_store_n(&b.stop, 1, __ATOMIC_RELEASE);
	assert_int_equal(pthread_join(c, NULL), 0);
	assert_int_equal(b.applied, MAILBOX_CMDS);
	assert_int_equal(b.applied_sum, (uint64_t)MAILBOX_CMDS * (MAILBOX_CMDS - 1) / 2);
	assert_int_equal(b.order_bad, 0);
	assert_int_equal(b.torn, 0);
	assert_true(reads > 0);
}

/* Two mlip-ctl race for the mailbox (a CAS decides): every post that
 * returned MLIP_OK is applied exactly once, with its own op and argument. */
#define RACE_CMDS 5000

struct racer {
	struct mlip_ring *r;
	int id; /* 1 or 2: the argument is id * 100000 + i */
};

static void *racer(void *arg)
{
	struct racer *t = arg;
	uint32_t seq;
	int32_t res;
	for (int i = 0; i < RACE_CMDS; i++) {
		while (mlip_ring_cmd_post(t->r, MLIP_CMD_OVERRIDE, t->id * 100000 + i, &seq) !=
		       MLIP_OK) {
			sched_yield();
		}
		mlip_status st;
		while ((st = mlip_ring_cmd_result(t->r, seq, &res)) == MLIP_E_EMPTY) {
			sched_yield();
		}
		/* MLIP_E_RANGE: done, but 8 of the other's completed since */
		if (st == MLIP_OK && res != t->id) {
			return (void *)1; /* another command's result */
		}
	}
	return NULL;
}

static void test_stress_two_posters(void **state)
{
	struct mlip_ring *r = fresh(CAP, 3);
	struct racer a = {r, 1}, b = {r, 2};
	pthread_t ta, tb;
	void *ra, *rb;
	int next[3] = {0, 0, 0}, bad = 0, n = 0;
	struct mlip_ring_cmd cmd;

	(void)state;
	assert_int_equal(pthread_create(&ta, NULL, racer, &a), 0);
	assert_int_equal(pthread_create(&tb, NULL, racer, &b), 0);
	while (n < 2 * RACE_CMDS) {
		if (mlip_ring_cmd_take(r, &cmd) != MLIP_OK) {
			sched_yield();
			continue;
		}
		int id = cmd.arg / 100000, i = cmd.arg % 100000;
		/* each poster's commands in its order, none twice, none lost */
		if (cmd.op != MLIP_CMD_OVERRIDE || id < 1 || id > 2 || i != next[id]) {
			bad++;
		} else {
			next[id]++;
		}
		n++;
		mlip_ring_cmd_done(r, cmd.seq, id); /* the result names the poster */
	}
	assert_int_equal(pthread_join(ta, &ra), 0);
	assert_int_equal(pthread_join(tb, &rb), 0);
	assert_null(ra);
	assert_null(rb);
	assert_int_equal(bad, 0);
	assert_int_equal(next[1], RACE_CMDS);
	assert_int_equal(next[2], RACE_CMDS);
	assert_int_equal(mlip_ring_cmd_take(r, &cmd), MLIP_E_EMPTY);
}

/* Ports keep the sizes and their own index; the other side's index is
 * range-checked, never trusted. */
static void test_port_corrupt_header(void **state)
{
	(void)state;
	struct mlip_ring *r = fresh(CAP, 3);
	struct mlip_ring_port tx, rx;
	struct mlip_ring_rec in[4], out;
	uint32_t n, apart = 0;

	for (uint32_t k = 0; k < 4; k++) {
		make_rec(&in[k], k);
	}
	assert_int_equal(mlip_ring_port_open(&tx, r, 1), MLIP_OK);
	assert_int_equal(mlip_ring_port_open(&rx, r, 0), MLIP_OK);
	assert_int_equal(mlip_ring_port_push_n(&tx, in, 4, &n), MLIP_OK);
	assert_int_equal(n, 4);
	r->mask = 0xFFFFFFFFu; /* not used after open */
	r->capacity = 0;
	struct mlip_rec_view v;
	assert_int_equal(mlip_ring_port_view(&rx, &v, NULL), MLIP_OK);
	assert_int_equal(v.len[0] + v.len[1], 4);
	out = v.span[0][0];
	assert_true(rec_ok(&out, 0));
	assert_int_equal(mlip_ring_port_pop_n(&rx, 1), MLIP_OK);
	assert_int_equal(mlip_ring_port_count(&rx, &n, NULL), MLIP_OK);
	assert_int_equal(n, 3);
	/* a head a lap and more ahead of the consumer */
	__atomic_store_n(&r->head, rx.own + CAP + 1, __ATOMIC_RELEASE);
	assert_int_equal(mlip_ring_port_count(&rx, &n, &apart), MLIP_E_RANGE);
	assert_int_equal(n, 0);
	assert_int_equal(apart, CAP + 1);
	apart = 0;
	assert_int_equal(mlip_ring_port_view(&rx, &v, &apart), MLIP_E_RANGE);
	assert_int_equal(v.len[0] + v.len[1], 0);
	assert_int_equal(apart, CAP + 1);
	/* what was seen can still be popped, not more */
	assert_int_equal(mlip_ring_port_pop_n(&rx, 4), MLIP_E_RANGE);
	assert_int_equal(mlip_ring_port_pop_n(&rx, 3), MLIP_OK);
	__atomic_store_n(&r->head, rx.own - 1, __ATOMIC_RELEASE); /* behind the consumer */
	assert_int_equal(mlip_ring_port_view(&rx, &v, NULL), MLIP_E_RANGE);
	/* a tail behind the producer by more than a lap (or ahead of it) */
	__atomic_store_n(&r->tail, tx.own + 7, __ATOMIC_RELEASE);
	assert_int_equal(mlip_ring_port_push_n(&tx, in, 1, &n), MLIP_E_RANGE);
	assert_int_equal(n, 0);
	/* a ring whose header is not one: no port */
	r->capacity = 12;
	assert_int_equal(mlip_ring_port_open(&rx, r, 0), MLIP_E_INVALID);
}

/* The consumer's view across the end of the slots: two spans, in order,
 * and a pop of what was taken hands exactly those slots back. */
static void test_port_view_wraps(void **state)
{
	(void)state;
	struct mlip_ring *r = fresh(CAP, 3);
	struct mlip_ring_port tx, rx;
	struct mlip_ring_rec in[5];
	struct mlip_rec_view v;
	uint32_t n;

	mlip_ring_reset(r, 0xFFFFFFFFu - 1u); /* indices about to wrap, too */
	for (uint32_t k = 0; k < 5; k++) {
		make_rec(&in[k], k);
	}
	assert_int_equal(mlip_ring_port_open(&tx, r, 1), MLIP_OK);
	assert_int_equal(mlip_ring_port_open(&rx, r, 0), MLIP_OK);
	assert_int_equal(mlip_ring_port_push_n(&tx, in, 5, &n), MLIP_OK);
	assert_int_equal(mlip_ring_port_view(&rx, &v, NULL), MLIP_OK);
	assert_int_equal(v.len[0], 2); /* the last two slots, then from slot 0 */
	assert_int_equal(v.len[1], 3);
	for (uint32_t k = 0; k < 5; k++) {
		assert_true(rec_ok(k < 2 ? &v.span[0][k] : &v.span[1][k - 2], k));
	}
	assert_int_equal(mlip_ring_port_pop_n(&rx, 3), MLIP_OK);
	assert_int_equal(mlip_ring_space(r), CAP - 2);
	assert_int_equal(mlip_ring_port_view(&rx, &v, NULL), MLIP_OK);
	assert_int_equal(v.len[0], 2);
	assert_int_equal(v.len[1], 0);
	assert_true(rec_ok(&v.span[0][0], 3));
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_port_corrupt_header),
	    cmocka_unit_test(test_port_view_wraps),
	    cmocka_unit_test(test_layout),
	    cmocka_unit_test(test_format_rejects),
	    cmocka_unit_test(test_format_fresh_state),
	    cmocka_unit_test(test_push_pop_order),
	    cmocka_unit_test(test_full_empty),
	    cmocka_unit_test(test_wraparound),
	    cmocka_unit_test(test_batch),
	    cmocka_unit_test(test_rec_block),
	    cmocka_unit_test(test_attach_ok),
	    cmocka_unit_test(test_attach_bad_magic),
	    cmocka_unit_test(test_attach_bad_version),
	    cmocka_unit_test(test_attach_bad_record),
	    cmocka_unit_test(test_attach_bad_capacity),
	    cmocka_unit_test(test_attach_bad_axes),
	    cmocka_unit_test(test_attach_too_small),
	    cmocka_unit_test(test_reason_strings),
	    cmocka_unit_test(test_status_feeder),
	    cmocka_unit_test(test_mailbox),
	    cmocka_unit_test(test_stop_counter),
	    cmocka_unit_test(test_stress_spsc),
	    cmocka_unit_test(test_stress_mailbox),
	    cmocka_unit_test(test_stress_two_posters),
	};

	return cmocka_run_group_tests_name("ring", tests, NULL, NULL);
}
