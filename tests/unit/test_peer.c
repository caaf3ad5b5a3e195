/*
 * test_peer.c - the liveness rule (src/ipc/peer.c, mlip/ipc/peer.h) on a virtual
 * clock: alive while the stamp is younger than MLIP_PEER_TIMEOUT_NS or the
 * counter moved between our reads; dead when it is not and the process is
 * gone (or the peer said goodbye); late when the process is there (or was not
 * asked), reported after MLIP_PEER_LATE_NS of quiet that we watched, never
 * counting our own pauses.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "mlip/ipc/peer.h"

#define MS 1000000ull
#define T0 (1000 * MS) /* the virtual clock starts here: 0 means "never" */

static mlip_peer_verdict judge(uint64_t beat, uint64_t stamp, int process, uint64_t now)
{
	struct mlip_peer_seen s = {beat, stamp, 0, process};

	return mlip_peer_judge(&s, NULL, now, NULL);
}

static void test_never_beat(void **state)
{
	struct mlip_peer_seen s = {0, 0, 0, 0};
	int64_t q = 7;

	(void)state;
	assert_int_equal(mlip_peer_judge(&s, NULL, T0, &q), MLIP_PEER_DEAD);
	assert_int_equal(q, -1);
	assert_int_equal(judge(0, 0, 1, T0), MLIP_PEER_LATE);  /* starting up */
	assert_int_equal(judge(0, 0, -1, T0), MLIP_PEER_LATE); /* not asked: never dead */
}

/* The stamp alone, on both sides of the timeout. */
static void test_stamp_age(void **state)
{
	const uint64_t t = T0 - MLIP_PEER_TIMEOUT_NS; /* beat 100 ms before T0 */
	int p;

	(void)state;
	for (p = -1; p <= 1; p++) {
		/* a fresh stamp is alive whatever the process says: we may not see
		 * its pid (another pid namespace), it beats */
		assert_int_equal(judge(1, t, p, t), MLIP_PEER_ALIVE);
		assert_int_equal(judge(1, t, p, T0 - 1), MLIP_PEER_ALIVE);
		assert_int_equal(judge(1, t + 5 * MS, p, t), MLIP_PEER_ALIVE); /* stamp ahead */
	}
	assert_int_equal(judge(1, t, 0, T0), MLIP_PEER_DEAD);
	assert_int_equal(judge(1, t, 1, T0), MLIP_PEER_LATE);
	assert_int_equal(judge(1, t, -1, T0), MLIP_PEER_LATE);
}

/* A feeder that left (pid 0) is dead at once, fresh stamp or not. */
static void test_left(void **state)
{
	struct mlip_peer_seen s = {9, T0, 1, 1};

	(void)state;
	assert_int_equal(mlip_peer_judge(&s, NULL, T0, NULL), MLIP_PEER_DEAD);
}

/* The controller is killed: its stamp stops at T0, its process is gone 30 ms
 * later; we read every ms. Alive for exactly MLIP_PEER_TIMEOUT_NS, then dead. */
static void test_killed(void **state)
{
	struct mlip_peer_watch w = {0, 0, 0};
	struct mlip_peer_seen s = {42, T0, 0, 1};
	uint64_t now;

	(void)state;
	for (now = T0; now <= T0 + 200 * MS; now += MS) {
		s.process = now < T0 + 30 * MS;
		mlip_peer_verdict v = mlip_peer_judge(&s, &w, now, NULL);
		assert_int_equal(v, now < T0 + (uint64_t)MLIP_PEER_TIMEOUT_NS ? MLIP_PEER_ALIVE
		                                                              : MLIP_PEER_DEAD);
		mlip_peer_note(&w, &s, now);
	}
}

/* The controller is stopped (SIGSTOP) at T0: late from 100 ms on, and its
 * quiet time, as we watched it, reaches MLIP_PEER_LATE_NS (1 s) at T0 + 1 s
 * (+- one 1 ms read). It runs again at T0 + 1.5 s: alive at our next read. */
static void test_stopped(void **state)
{
	struct mlip_peer_watch w = {0, 0, 0};
	struct mlip_peer_seen s = {42, T0, 0, 1};
	uint64_t now, told = 0;
	int64_t q;

	(void)state;
	for (now = T0; now < T0 + 1500 * MS; now += MS) {
		mlip_peer_verdict v = mlip_peer_judge(&s, &w, now, &q);
		assert_int_equal(v, now < T0 + (uint64_t)MLIP_PEER_TIMEOUT_NS ? MLIP_PEER_ALIVE
		                                                              : MLIP_PEER_LATE);
		assert_true(q >= 0 && (uint64_t)q <= now - T0);
		if (told == 0 && q >= MLIP_PEER_LATE_NS) {
			told = now;
		}
		mlip_peer_note(&w, &s, now);
	}
	assert_true(told >= T0 + MLIP_PEER_LATE_NS && told <= T0 + MLIP_PEER_LATE_NS + MS);
	s.beat++;
	s.stamp_ns = now - 1;
	assert_int_equal(mlip_peer_judge(&s, &w, now, &q), MLIP_PEER_ALIVE);
	assert_int_equal(q, 0);
}

/* Both processes stopped, we first, for 5 s; we run again first. The peer's
 * stamp is 5 s old but we did not watch that: late (process there), quiet
 * counted from our return, so "late" is reported 1 s after it, not at once. */
static void test_our_pause_not_blamed(void **state)
{
	struct mlip_peer_watch w = {0, 0, 0};
	struct mlip_peer_seen s = {42, T0, 0, 1};
	uint64_t now = T0 + MS, back = T0 + 5000 * MS;
	int64_t q;

	(void)state;
	assert_int_equal(mlip_peer_judge(&s, &w, now, &q), MLIP_PEER_ALIVE);
	mlip_peer_note(&w, &s, now);
	/* the pause: our next read is 5 s later */
	assert_int_equal(mlip_peer_judge(&s, &w, back, &q), MLIP_PEER_LATE);
	assert_int_equal(q, 0);
	mlip_peer_note(&w, &s, back);
	for (now = back + MS; now < back + 999 * MS; now += MS) {
		assert_int_equal(mlip_peer_judge(&s, &w, now, &q), MLIP_PEER_LATE);
		assert_true(q < MLIP_PEER_LATE_NS);
		assert_true((uint64_t)q == now - back);
		mlip_peer_note(&w, &s, now);
	}
	/* a gap of exactly half the timeout still counts as watched; more does not */
	now = w.read_ns + MLIP_PEER_TIMEOUT_NS / 2;
	mlip_peer_judge(&s, &w, now, &q);
	assert_true((uint64_t)q == now - back);
	mlip_peer_note(&w, &s, now);
	now += MLIP_PEER_TIMEOUT_NS / 2 + 1;
	mlip_peer_judge(&s, &w, now, &q);
	assert_int_equal(q, 0);
}

/* mlip-ctl's second look: the stamp was old at our first read (we were
 * paused before it), the counter moved by the second: alive. Unmoved: not. */
static void test_second_look(void **state)
{
	struct mlip_peer_watch w = {0, 0, 0};
	struct mlip_peer_seen s = {42, T0, 0, 0};
	uint64_t now = T0 + 3000 * MS;

	(void)state;
	assert_int_equal(mlip_peer_judge(&s, &w, now, NULL), MLIP_PEER_DEAD);
	mlip_peer_note(&w, &s, now);
	now += MLIP_PEER_TIMEOUT_NS;
	assert_int_equal(mlip_peer_judge(&s, &w, now, NULL), MLIP_PEER_DEAD);
	s.beat = 43; /* moved: however old the stamp, it ran since our last look */
	assert_int_equal(mlip_peer_judge(&s, &w, now, NULL), MLIP_PEER_ALIVE);
	/* the judge reads the history only: the same question, the same answer */
	assert_int_equal(mlip_peer_judge(&s, &w, now, NULL), MLIP_PEER_ALIVE);
	mlip_peer_note(&w, &s, now);
	assert_int_equal(w.quiet_since_ns, now);
	assert_int_equal(w.beat, 43);
}

static void test_names(void **state)
{
	(void)state;
	assert_int_equal(mlip_peer_age_ns(0, T0), -1); /* never stamped */
	assert_int_equal(mlip_peer_age_ns(T0 - 5, T0), 5);
	assert_int_equal(mlip_peer_age_ns(T0 + 5, T0), 0); /* ahead: counts as now */
	assert_string_equal(mlip_peer_verdict_name(MLIP_PEER_ALIVE), "alive");
	assert_string_equal(mlip_peer_verdict_name(MLIP_PEER_LATE), "late");
	assert_string_equal(mlip_peer_verdict_name(MLIP_PEER_DEAD), "dead");
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_never_beat),  cmocka_unit_test(test_stamp_age),
	    cmocka_unit_test(test_left),        cmocka_unit_test(test_killed),
	    cmocka_unit_test(test_stopped),     cmocka_unit_test(test_our_pause_not_blamed),
	    cmocka_unit_test(test_second_look), cmocka_unit_test(test_names),
	};

	return cmocka_run_group_tests_name("peer", tests, NULL, NULL);
}
