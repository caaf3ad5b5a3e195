/*
 * test_rtloop.c - the periodic loop tells each period how many deadlines
 * passed unserved, wherever the stall was: in the period's work (the
 * deadlines it overran are told to the next period) or between the work and
 * the next wake-up (the wake-up's lateness). The sum told equals the loop's
 * overrun count plus the current lateness, every period, exactly, and the
 * deadline index steps by one plus what was missed.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <time.h>

#include <cmocka.h>

#include "rt.h"

#define PERIOD_NS   1000000LL
#define STALL_NS    30000000LL /* 30 periods */
#define STALL_WORK  5          /* the work of this cycle stalls */
#define STALL_AFTER 12         /* the statistics call after this cycle stalls */
#define LAST        20

struct rec {
	uint64_t missed[LAST + 1];
	uint64_t index[LAST + 1];
	uint64_t sum;
	int bad_cycle; /* -1, or the first cycle whose sum was off */
	uint64_t bad_sum, bad_expect;
};

static void stall(void)
{
	struct timespec ts = {0, STALL_NS};
	while (nanosleep(&ts, &ts) != 0) {
	}
}

static int work(void *ctx, const struct mlip_rt_tick *t)
{
	struct rec *r = ctx;
	r->missed[t->cycle] = t->missed;
	r->index[t->cycle] = t->index;
	r->sum += t->missed;
	/* every deadline skipped so far was told, and this wake-up's lateness */
	uint64_t expect = t->overruns + (uint64_t)t->latency_ns / PERIOD_NS;
	if (r->sum != expect && r->bad_cycle < 0) {
		r->bad_cycle = (int)t->cycle;
		r->bad_sum = r->sum;
		r->bad_expect = expect;
	}
	if (t->cycle == STALL_WORK) {
		stall();
	}
	return t->cycle >= LAST;
}

static void after(void *ctx, const struct mlip_rt_tick *t, int64_t compute_ns)
{
	(void)ctx;
	(void)compute_ns;
	if (t->cycle == STALL_AFTER) {
		stall();
	}
}

static void test_stalls_told_wherever_they_are(void **state)
{
	(void)state;
	struct rec r;
	memset(&r, 0, sizeof(r));
	r.bad_cycle = -1;
	struct mlip_rt_opts o = {.period_ns = PERIOD_NS, .priority = 0, .cpu = -1};
	struct mlip_rt_report rep;
	memset(&rep, 0, sizeof(rep));
	assert_int_equal(mlip_rt_run(&o, work, after, &r, &rep), 1); /* the work ended it */
	if (r.bad_cycle >= 0) {
		print_error("cycle %d: %llu told, %llu skipped or late\n", r.bad_cycle,
		            (unsigned long long)r.bad_sum, (unsigned long long)r.bad_expect);
		fail();
	}
	/* a 30 ms stall is at least 29 whole periods passed unserved (at most
	 * 30 of it, and whatever a loaded machine adds: the sum above is exact) */
	assert_true(r.missed[STALL_WORK + 1] >= 29);
	assert_true(r.missed[STALL_AFTER + 1] >= 29);
	/* the deadline indices: a hole of exactly what was missed, never a
	 * step back (the record's periods, mlip-check's time axis) */
	for (int c = 1; c <= LAST; c++) {
		assert_int_equal(r.index[c], r.index[c - 1] + 1 + r.missed[c]);
	}
	assert_int_equal(r.index[0], r.missed[0]);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_stalls_told_wherever_they_are),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
