/*
 * test_cia402.c - the CiA 402 power state machine (mlip/canopen/cia402.h):
 * statusword decoding from the standard's bit patterns, and the one power
 * sequencer, on a virtual clock, against drives modelled here from the CiA
 * 402-2 state machine (their own transitions from the controlword bits, not
 * mlip's): from every power-up state to "switched on" and "operation
 * enabled" (bring-up, one drive), a group in step (the loop), late and
 * failing drives, a muted drive, a want that changes on the way, a drive
 * that is not ready yet.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "mlip/canopen/cia402.h"

/* ---- a drive, from CiA 402-2 ------------------------------------------------------ */

enum { D_NRTSO, D_SOD, D_RTSO, D_SO, D_OE, D_QSA, D_FRA, D_FAULT };
static const uint16_t d_sw[] = {0x0200, 0x0250, 0x0231, 0x0233, 0x1237, 0x0217, 0x021F, 0x0218};

struct drive {
	int state;
	uint16_t cw;     /* the last controlword applied */
	int stubborn;    /* never leaves the state it is in */
	int ready_after; /* NRTSO: goes to SOD by itself after this many ticks */
	int ticks;
};

/* The controlword's command, decoded from bits 0-3 and 7 (CiA 402-2). */
static void apply(struct drive *d, uint16_t cw)
{
	int rising7 = (cw & 0x80) && !(d->cw & 0x80);
	d->cw = cw;
	if (d->stubborn) {
		return;
	}
	switch (d->state) {
	case D_FAULT:
		if (rising7) {
			d->state = D_SOD; /* transition 15 */
		}
		return;
	case D_NRTSO:
	case D_FRA:
		return; /* the drive's own transitions */
	case D_QSA:
		if ((cw & 0x02) == 0) {
			d->state = D_SOD; /* 12: disable voltage */
		}
		return;
	default:
		break;
	}
	if ((cw & 0x02) == 0) {
		d->state = D_SOD; /* 7, 9, 10, 12: disable voltage */
	} else if ((cw & 0x04) == 0) {
		d->state = d->state == D_OE ? D_QSA : D_SOD; /* quick stop */
	} else if ((cw & 0x0F) == 0x06) {
		d->state = D_RTSO; /* 2, 6, 8: shutdown */
	} else if ((cw & 0x0F) == 0x07) {
		if (d->state == D_RTSO || d->state == D_OE || d->state == D_SO) {
			d->state = D_SO; /* 3, 5: switch on, disable operation */
		}
	} else if ((cw & 0x0F) == 0x0F) {
		if (d->state == D_SO || d->state == D_OE) {
			d->state = D_OE; /* 4: enable operation */
		} else if (d->state == D_RTSO) {
			d->state = D_OE; /* 3 then 4 in one (allowed by the standard) */
		}
	}
}

static void drive_tick(struct drive *d)
{
	d->ticks++;
	if (d->state == D_NRTSO && d->ticks >= d->ready_after) {
		d->state = D_SOD; /* transition 1 */
	}
	if (d->state == D_FRA && d->ticks >= d->ready_after) {
		d->state = D_FAULT; /* 14 */
	}
}

/* ---- a run -------------------------------------------------------------------------- */

#define N 3
static struct drive dv[N];
static struct mlip_402_seq seq;
static uint64_t now;
static int32_t sent[64]; /* controlwords as they changed */
static int n_sent;
static struct mlip_402_change changes[32];
static int n_changes;

static void reset(int n, int state)
{
	memset(dv, 0, sizeof(dv));
	for (int i = 0; i < n; i++) {
		dv[i].state = state;
	}
	now = 1000;
	n_sent = n_changes = 0;
}

/* One tick: the drives apply the controlword (if any) and report their
 * statusword; the sequencer looks at them. 1 when a step ended. */
static int tick(int n, mlip_drive_power want, uint32_t mute)
{
	uint16_t sw[N];
	struct mlip_402_change ch;
	for (int i = 0; i < n; i++) {
		drive_tick(&dv[i]);
		sw[i] = d_sw[dv[i].state];
	}
	int r = mlip_402_seq_run(&seq, want, sw, n, mute, now, &ch);
	if (r) {
		assert_true(n_changes < 32);
		changes[n_changes++] = ch;
	}
	if (seq.cw >= 0) {
		if (n_sent == 0 || sent[n_sent - 1] != seq.cw) {
			assert_true(n_sent < 64);
			sent[n_sent++] = seq.cw;
		}
		for (int i = 0; i < n; i++) {
			apply(&dv[i], (uint16_t)seq.cw);
		}
	}
	now++;
	return r;
}

/* Ticks until the sequencer rests (at most max); how many it took. */
static int run_to_rest(int n, mlip_drive_power want, uint32_t mute, int max)
{
	for (int k = 1; k <= max; k++) {
		tick(n, want, mute);
		if (mlip_402_power_is_rest(seq.step) && seq.step != MLIP_POWER_NONE) {
			return k;
		}
	}
	fail_msg("no rest within %d ticks (step %s)", max, mlip_drive_power_name(seq.step));
	return -1;
}

static void assert_sent(const int32_t *want, int n)
{
	if (n_sent != n) {
		fail_msg("%d controlwords sent, expected %d", n_sent, n);
	}
	for (int i = 0; i < n; i++) {
		assert_int_equal(sent[i], want[i]);
	}
}

/* ---- tests -------------------------------------------------------------------------- */

static void test_states(void **state)
{
	(void)state;
	/* the statusword patterns of CiA 402-2, with other bits set around them */
	assert_int_equal(mlip_402_state_of(0x0000), MLIP_402_NOT_READY);
	assert_int_equal(mlip_402_state_of(0x0250), MLIP_402_SWITCH_ON_DISABLED);
	assert_int_equal(mlip_402_state_of(0x0231), MLIP_402_READY_TO_SWITCH_ON);
	assert_int_equal(mlip_402_state_of(0x0233), MLIP_402_SWITCHED_ON);
	assert_int_equal(mlip_402_state_of(0x1237), MLIP_402_OPERATION_ENABLED);
	assert_int_equal(mlip_402_state_of(0x0217), MLIP_402_QUICK_STOP_ACTIVE);
	assert_int_equal(mlip_402_state_of(0x021F), MLIP_402_FAULT_REACTION_ACTIVE);
	assert_int_equal(mlip_402_state_of(0x0218), MLIP_402_FAULT);
	/* fault bit with "operation enabled" bits: fault reaction active, not enabled */
	assert_int_equal(mlip_402_state_of(0x003F), MLIP_402_FAULT_REACTION_ACTIVE);
	assert_string_equal(mlip_402_state_name(MLIP_402_OPERATION_ENABLED), "operation enabled");
	for (int i = 0; i <= D_FAULT; i++) {
		assert_int_not_equal(mlip_402_state_of(d_sw[i]), MLIP_402_UNKNOWN);
	}
}

/* Bring-up, one drive: from each power-up state to "switched on" (never
 * enabled on the way), then to "operation enabled"; the controlwords are
 * the standard's shortest path. */
static void test_up_from_each_state(void **state)
{
	static const struct {
		int from;
		int32_t cws[5];
		int n;
	} cases[] = {
	    {D_SOD, {0x06, 0x07}, 2},
	    {D_RTSO, {0x07}, 1},
	    {D_SO, {0x07}, 1},                      /* already there: held */
	    {D_OE, {0x07}, 1},                      /* enabled before we came: disable operation */
	    {D_FAULT, {0x00, 0x80, 0x06, 0x07}, 4}, /* the reset on a rising edge */
	    {D_QSA, {0x00, 0x06, 0x07}, 3},
	};
	(void)state;
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		reset(1, cases[c].from);
		mlip_402_seq_init(&seq, MLIP_POWER_NONE, 50, now);
		run_to_rest(1, MLIP_POWER_SWITCHED_ON, 0, 100);
		assert_int_equal(seq.step, MLIP_POWER_SWITCHED_ON);
		assert_int_equal(dv[0].state, D_SO);
		assert_sent(cases[c].cws, cases[c].n);
		/* every step after the first look was confirmed, none late */
		for (int i = 1; i < n_changes; i++) {
			assert_int_equal(changes[i].late, -1);
			assert_int_equal(changes[i].failed, 0);
		}
		assert_int_equal(changes[0].from, MLIP_POWER_NONE);
		/* then enable operation, confirmed */
		n_sent = 0;
		run_to_rest(1, MLIP_POWER_ENABLED, 0, 100);
		assert_int_equal(dv[0].state, D_OE);
		assert_sent((const int32_t[]){0x0F}, 1);
		assert_int_equal(changes[n_changes - 1].from, MLIP_POWER_ENABLING);
		assert_int_equal(changes[n_changes - 1].reached, MLIP_402_OPERATION_ENABLED);
	}
}

/* Not ready to switch on: nothing is sent while the drive readies itself;
 * then on from where it went. Not ready for too long: failed. */
static void test_waiting(void **state)
{
	(void)state;
	reset(1, D_NRTSO);
	dv[0].ready_after = 20;
	mlip_402_seq_init(&seq, MLIP_POWER_NONE, 50, now);
	for (int k = 0; k < 10; k++) {
		tick(1, MLIP_POWER_SWITCHED_ON, 0);
	}
	assert_int_equal(seq.step, MLIP_POWER_WAITING);
	assert_int_equal(seq.cw, -1);
	assert_int_equal(n_sent, 0);
	run_to_rest(1, MLIP_POWER_SWITCHED_ON, 0, 100);
	assert_sent((const int32_t[]){0x06, 0x07}, 2);

	reset(1, D_FRA);
	dv[0].ready_after = 1000; /* a fault reaction that never ends */
	mlip_402_seq_init(&seq, MLIP_POWER_NONE, 50, now);
	int k;
	for (k = 0; k < 100 && !(n_changes > 1 && changes[n_changes - 1].failed); k++) {
		tick(1, MLIP_POWER_SWITCHED_ON, 0);
	}
	assert_int_equal(changes[n_changes - 1].failed, 1);
	assert_int_equal(changes[n_changes - 1].from, MLIP_POWER_WAITING);
	assert_int_equal(changes[n_changes - 1].in_step, 50); /* the timeout, to the tick */
	assert_int_equal(n_sent, 1); /* nothing while waiting; then the way down */
}

/* The loop: three drives in step from OFF to ENABLED and back, each step
 * held until every drive shows it (one drive slower), timed. */
static void test_group_in_step(void **state)
{
	(void)state;
	reset(N, D_RTSO);
	mlip_402_seq_init(&seq, MLIP_POWER_OFF, 100, now);
	tick(N, MLIP_POWER_OFF, 0);
	assert_int_equal(n_changes, 0); /* at rest: nothing to do */
	dv[2].stubborn = 1;             /* Z takes 5 ticks to switch on */
	int k = 0;
	while (seq.step != MLIP_POWER_ENABLED && k++ < 100) {
		if (k == 6) {
			dv[2].stubborn = 0;
			apply(&dv[2], dv[2].cw);
		}
		tick(N, MLIP_POWER_ENABLED, 0);
	}
	assert_sent((const int32_t[]){0x06, 0x07, 0x0F}, 3);
	assert_int_equal(n_changes, 3);
	assert_int_equal(changes[0].from, MLIP_POWER_OFF);
	assert_int_equal(changes[0].to, MLIP_POWER_SWITCHING_ON);
	assert_int_equal(changes[0].in_sequence, 0); /* a sequence begins */
	assert_int_equal(changes[1].to, MLIP_POWER_ENABLING);
	assert_int_equal(changes[1].in_step, 5); /* until Z came */
	assert_int_equal(changes[2].to, MLIP_POWER_ENABLED);
	assert_int_equal(changes[2].in_step, 1);
	assert_int_equal(changes[2].in_sequence, 6);
	assert_int_equal(seq.took, 6);
	for (int i = 0; i < N; i++) {
		assert_int_equal(dv[i].state, D_OE);
	}
	/* and down: disable operation, then shutdown, confirmed: in order */
	n_changes = 0;
	run_to_rest(N, MLIP_POWER_OFF, 0, 100);
	assert_int_equal(n_changes, 3);
	assert_int_equal(changes[0].to, MLIP_POWER_DISABLING);
	assert_int_equal(changes[1].to, MLIP_POWER_SHUTTING_DOWN);
	assert_int_equal(changes[2].to, MLIP_POWER_OFF);
	assert_int_equal(seq.ok, 1);
	assert_int_equal(seq.took, 2);
	for (int i = 0; i < N; i++) {
		assert_int_equal(dv[i].state, D_RTSO);
	}
}

/* Toward OFF a drive that does not confirm is noted and passed: the others
 * are not kept powered for it. */
static void test_down_late_goes_on(void **state)
{
	(void)state;
	reset(N, D_OE);
	mlip_402_seq_init(&seq, MLIP_POWER_ENABLED, 30, now);
	dv[1].stubborn = 1;
	run_to_rest(N, MLIP_POWER_OFF, 0, 200);
	assert_int_equal(changes[1].from, MLIP_POWER_DISABLING);
	assert_int_equal(changes[1].to, MLIP_POWER_SHUTTING_DOWN);
	assert_int_equal(changes[1].late, 1);
	assert_int_equal(changes[1].late_sw, d_sw[D_OE]);
	assert_int_equal(changes[1].in_step, 30);
	assert_int_equal(changes[1].failed, 0);
	assert_int_equal(seq.ok, 0);
	assert_int_equal(seq.late, 1);
	assert_int_equal(seq.late_step, MLIP_POWER_SHUTTING_DOWN);
	assert_int_equal(dv[0].state, D_RTSO);
	assert_int_equal(dv[2].state, D_RTSO);
}

/* Toward power a drive that does not confirm in time fails the sequence:
 * reported with the drive and its word, and the group goes back down. */
static void test_up_fails(void **state)
{
	(void)state;
	reset(N, D_RTSO);
	mlip_402_seq_init(&seq, MLIP_POWER_OFF, 40, now);
	int k;
	tick(N, MLIP_POWER_ENABLED, 0); /* switch on: all switched on */
	dv[2].stubborn = 1;             /* and Z stays there */
	tick(N, MLIP_POWER_ENABLED, 0);
	assert_int_equal(seq.step, MLIP_POWER_ENABLING);
	assert_int_equal(dv[2].state, D_SO);
	for (k = 0; k < 100 && !changes[n_changes - 1].failed; k++) {
		tick(N, MLIP_POWER_ENABLED, 0);
	}
	const struct mlip_402_change *f = &changes[n_changes - 1];
	assert_int_equal(f->failed, 1);
	assert_int_equal(f->from, MLIP_POWER_ENABLING);
	assert_int_equal(f->to, MLIP_POWER_DISABLING);
	assert_int_equal(f->late, 2);
	assert_int_equal(f->late_sw, d_sw[D_SO]);
	assert_int_equal(f->in_step, 40);
	assert_int_equal(f->in_sequence, 0); /* the way down is a sequence of its own */
	assert_int_equal(seq.want, MLIP_POWER_OFF);
	/* still wanted: it is not tried again until the sequence down is done */
	dv[2].stubborn = 0;
	run_to_rest(N, MLIP_POWER_ENABLED, 0, 200);
	assert_int_equal(seq.step, MLIP_POWER_OFF);
	assert_int_equal(seq.ok, 1);
}

/* A drive not followed (faulted: its own fault reaction) does not hold the
 * others. */
static void test_muted(void **state)
{
	(void)state;
	reset(N, D_OE);
	dv[0].state = D_FAULT;
	dv[0].stubborn = 1;
	mlip_402_seq_init(&seq, MLIP_POWER_ENABLED, 1000, now);
	int k = run_to_rest(N, MLIP_POWER_OFF, 1u << 0, 100);
	assert_true(k <= 4);
	assert_int_equal(seq.ok, 1);
	assert_int_equal(dv[0].state, D_FAULT);
	assert_int_equal(dv[1].state, D_RTSO);
}

/* The want drops on the way up: down at once, a new sequence; it rises on
 * the way down: the way down ends first. */
static void test_want_changes(void **state)
{
	(void)state;
	reset(N, D_RTSO);
	mlip_402_seq_init(&seq, MLIP_POWER_OFF, 100, now);
	dv[1].stubborn = 1;
	tick(N, MLIP_POWER_ENABLED, 0);
	tick(N, MLIP_POWER_ENABLED, 0);
	assert_int_equal(seq.step, MLIP_POWER_SWITCHING_ON);
	tick(N, MLIP_POWER_OFF, 0);
	assert_int_equal(changes[n_changes - 1].from, MLIP_POWER_SWITCHING_ON);
	assert_int_equal(changes[n_changes - 1].to, MLIP_POWER_DISABLING);
	assert_int_equal(changes[n_changes - 1].in_sequence, 0);
	dv[1].stubborn = 0;
	apply(&dv[1], 0x07);
	tick(N, MLIP_POWER_ENABLED, 0); /* wanted again: DISABLING goes on */
	assert_int_equal(seq.step, MLIP_POWER_SHUTTING_DOWN);
	tick(N, MLIP_POWER_ENABLED, 0);
	assert_int_equal(seq.step, MLIP_POWER_OFF);
	tick(N, MLIP_POWER_ENABLED, 0);
	assert_int_equal(seq.step, MLIP_POWER_SWITCHING_ON);
}

/* After a quick stop the group shows mixed states (one drive already
 * "switch on disabled", one still in "quick stop active", one "ready"):
 * toward OFF each step is a command valid for all and confirmed by all
 * (0x0000, then 0x0006 to "ready": OFF is "ready to switch on", never
 * assumed); from there switch on is valid for each. Toward power from the
 * same states: the same way up, never 0x0007 to a drive that is not
 * "ready". */
static void test_mixed_after_quick_stop(void **state)
{
	(void)state;
	reset(N, D_SOD);
	dv[1].state = D_QSA;
	dv[2].state = D_RTSO;
	mlip_402_seq_init(&seq, MLIP_POWER_NONE, 100, now);
	run_to_rest(N, MLIP_POWER_OFF, 0, 50);
	assert_int_equal(seq.step, MLIP_POWER_OFF);
	assert_int_equal(seq.ok, 1);
	for (int i = 0; i < N; i++) {
		assert_int_equal(dv[i].state, D_RTSO);
	}
	run_to_rest(N, MLIP_POWER_ENABLED, 0, 50);
	assert_int_equal(seq.step, MLIP_POWER_ENABLED);
	static const int32_t down_up[] = {0x0000, 0x0006, 0x0007, 0x000F};
	assert_sent(down_up, 4);

	reset(N, D_SOD);
	dv[1].state = D_QSA;
	mlip_402_seq_init(&seq, MLIP_POWER_NONE, 100, now);
	run_to_rest(N, MLIP_POWER_ENABLED, 0, 50);
	assert_sent(down_up, 4);
	for (int i = 0; i < N; i++) {
		assert_int_equal(dv[i].state, D_OE);
	}
	/* at OFF a drive dropped to "switch on disabled" by itself: the way up
	 * starts with shutdown again */
	run_to_rest(N, MLIP_POWER_OFF, 0, 50);
	dv[0].state = D_SOD;
	n_sent = 0;
	run_to_rest(N, MLIP_POWER_ENABLED, 0, 50);
	static const int32_t up[] = {0x0006, 0x0007, 0x000F};
	assert_sent(up, 3);
}

/* Toward power a drive that never leaves "switch on disabled": shutdown
 * fails naming it and its statusword; nothing was switched on, so the way
 * down sends no 0x0007 (it would switch on the drives that are "ready"). */
static void test_up_stuck_disabled(void **state)
{
	(void)state;
	reset(N, D_SOD);
	dv[1].stubborn = 1;
	mlip_402_seq_init(&seq, MLIP_POWER_NONE, 40, now);
	for (int k = 0; k < 100 && (n_changes == 0 || !changes[n_changes - 1].failed); k++) {
		tick(N, MLIP_POWER_ENABLED, 0);
	}
	const struct mlip_402_change *f = &changes[n_changes - 1];
	assert_int_equal(f->failed, 1);
	assert_int_equal(f->from, MLIP_POWER_SHUTTING_DOWN);
	assert_int_equal(f->late, 1);
	assert_int_equal(f->late_sw, d_sw[D_SOD]);
	assert_int_equal(f->in_step, 40);
	run_to_rest(N, MLIP_POWER_OFF, 0, 100);
	for (int i = 0; i < n_sent; i++) {
		assert_int_not_equal(sent[i], 0x0007);
	}
	assert_int_equal(dv[0].state, D_RTSO);
}

static void test_names(void **state)
{
	(void)state;
	assert_string_equal(mlip_drive_power_name(MLIP_POWER_NONE), "none");
	assert_string_equal(mlip_drive_power_name(MLIP_POWER_SHUTTING_DOWN), "shutting down");
	assert_string_equal(mlip_drive_power_name(MLIP_POWER_ENABLING), "enabling");
	assert_string_equal(mlip_drive_power_name(MLIP_POWER_COUNT), "?");
	assert_string_equal(mlip_402_step_command(MLIP_POWER_DISABLING), "disable operation");
	assert_int_equal(mlip_402_step_cw(MLIP_POWER_DISABLING), 0x0007);
	assert_int_equal(mlip_402_step_expects(MLIP_POWER_DISABLING), MLIP_402_SWITCHED_ON);
	assert_string_equal(mlip_402_step_command(MLIP_POWER_RESETTING), "fault reset");
	assert_int_equal(mlip_402_step_cw(MLIP_POWER_RESETTING), 0x0080);
	assert_int_equal(mlip_402_step_cw(MLIP_POWER_WAITING), -1);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_states),
	    cmocka_unit_test(test_up_from_each_state),
	    cmocka_unit_test(test_waiting),
	    cmocka_unit_test(test_group_in_step),
	    cmocka_unit_test(test_down_late_goes_on),
	    cmocka_unit_test(test_up_fails),
	    cmocka_unit_test(test_muted),
	    cmocka_unit_test(test_want_changes),
	    cmocka_unit_test(test_mixed_after_quick_stop),
	    cmocka_unit_test(test_up_stuck_disabled),
	    cmocka_unit_test(test_names),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
