/*
 * test_spindle.c - the profile velocity spindle's decisions
 * (mlip/canopen/spindle.h) against a model drive on a virtual clock: it
 * ramps its velocity at its own acceleration toward the target and sets
 * "target reached" within its window, as a CiA 402 drive in pv mode does.
 * The feed is released only at speed; M5 and a reversal wait for
 * standstill; a slow drive, a drive fault and a speed lost while cutting
 * are faults; the target sent is in counts/s.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <string.h>

#include <cmocka.h>

#include "mlip/canopen/cia402.h"
#include "mlip/canopen/drive.h"
#include "mlip/canopen/spindle.h"
#include "mlip/ctl/spindlectl.h"

#define T 0.001 /* s per period */

struct drive {
	double counts_per_rev, accel_rpm_s, window_rpm;
	double target_rpm, actual_rpm;
	uint16_t sw;
	int fault;
	double load_drop_rpm; /* subtracted from actual: a load step */
};

/* One period of the model: the target from the master, then the ramp. */
static void drive_step(struct drive *d, int32_t target_counts)
{
	double step = d->accel_rpm_s * T, err;

	d->target_rpm = target_counts * 60.0 / d->counts_per_rev;
	err = d->target_rpm - d->actual_rpm;
	d->actual_rpm += fabs(err) <= step ? err : (err > 0 ? step : -step);
	d->sw = 0x0027; /* operation enabled */
	if (fabs(d->target_rpm - d->actual_rpm) <= d->window_rpm) {
		d->sw |= MLIP_SPINDLE_SW_TARGET_REACHED;
	}
	if (fabs(d->actual_rpm) < 1e-9) {
		d->sw |= MLIP_SPINDLE_SW_SPEED_ZERO;
	}
	if (d->fault) {
		d->sw = 0x0008 | 0x0020;
	}
}

static int32_t actual_counts(const struct drive *d)
{
	return (int32_t)floor((d->actual_rpm - d->load_drop_rpm) * d->counts_per_rev / 60.0 + 0.5);
}

struct rig {
	struct drive d;
	struct mlip_spindle s;
	uint64_t period;
	int32_t target;
};

static void rig_init(struct rig *r, double drive_accel)
{
	struct mlip_spindle_cfg cfg = {4096, 30, 2000, 50}; /* 2 s to a target at most */

	memset(r, 0, sizeof(*r));
	r->d.counts_per_rev = 4096;
	r->d.accel_rpm_s = drive_accel;
	r->d.window_rpm = 20;
	assert_int_equal(mlip_spindle_init(&r->s, &cfg), MLIP_OK);
}

/* Periods until step() says ready (or faults: -1 - periods), at most max. */
static long until_ready(struct rig *r, long max)
{
	for (long k = 0; k < max; k++) {
		int rc =
		    mlip_spindle_step(&r->s, r->d.sw, actual_counts(&r->d), r->period, &r->target);
		r->period++;
		if (rc != 0) {
			return rc > 0 ? k : -1 - k;
		}
		drive_step(&r->d, r->target);
	}
	return max;
}

static void test_start_waits_for_speed(void **state)
{
	struct rig r;
	long k;

	(void)state;
	rig_init(&r, 10000);                      /* 10000 rpm/s */
	assert_int_equal(until_ready(&r, 10), 0); /* stopped, asked 0: ready */
	mlip_spindle_command(&r.s, 12000, r.period);
	k = until_ready(&r, 5000);
	/* 1.2 s of ramp at 10000 rpm/s, then the window: released then, not before */
	assert_true(k >= 1198 && k <= 1202);
	assert_true(fabs(r.d.actual_rpm - 12000) <= 30);
	/* the target sent: 12000 rpm at 4096 counts/rev = 819200 counts/s */
	assert_int_equal(r.target, 819200);
	assert_int_equal(r.s.phase, MLIP_SPINDLE_AT_SPEED);
}

static void test_stop_and_reversal_wait_for_standstill(void **state)
{
	struct rig r;
	long k;

	(void)state;
	rig_init(&r, 10000);
	mlip_spindle_command(&r.s, 6000, r.period);
	assert_true(until_ready(&r, 5000) > 0);
	/* M4: brake to rest first (target 0), then the other way */
	mlip_spindle_command(&r.s, -6000, r.period);
	int saw_zero_target = 0, reversed_before_rest = 0;
	for (k = 0; k < 3000; k++) {
		int rc =
		    mlip_spindle_step(&r.s, r.d.sw, actual_counts(&r.d), r.period++, &r.target);
		assert_true(rc >= 0);
		saw_zero_target |= r.target == 0;
		reversed_before_rest |= r.target < 0 && r.d.actual_rpm > 30;
		if (rc == 1) {
			break;
		}
		drive_step(&r.d, r.target);
	}
	assert_true(saw_zero_target && !reversed_before_rest);
	/* down to the band (6000 - 30 rpm at 10000 rpm/s: 0.597 s), then up into
	 * it the other way (the same), each to the period */
	assert_true(k >= 1192 && k <= 1198);
	assert_true(r.d.actual_rpm < -5970);
	/* M5: ready only at standstill */
	mlip_spindle_command(&r.s, 0, r.period);
	k = until_ready(&r, 3000);
	assert_true(k >= 595 && k <= 600); /* (6000 - 30) / 10000 s */
	assert_true(fabs(r.d.actual_rpm) <= 30);
	assert_int_equal(r.s.phase, MLIP_SPINDLE_STOPPED);
}

static void test_faults(void **state)
{
	struct rig r;
	long k;

	(void)state;
	/* a drive slower than the timeout allows: 12000 rpm needs 3 s at 4000
	 * rpm/s, the timeout is 2 s */
	rig_init(&r, 4000);
	mlip_spindle_command(&r.s, 12000, r.period);
	k = until_ready(&r, 5000);
	assert_true(k <= -2000 && k >= -2003);
	assert_int_equal(r.s.fault, MLIP_SPINDLE_TIMEOUT);
	assert_int_equal(r.target, 0);
	assert_true(r.s.fault_value > 7900 && r.s.fault_value < 8100);
	/* latched: a new command changes nothing */
	mlip_spindle_command(&r.s, 1000, r.period);
	assert_int_equal(until_ready(&r, 10), -1);
	/* the drive's fault bit */
	rig_init(&r, 10000);
	mlip_spindle_command(&r.s, 3000, r.period);
	assert_true(until_ready(&r, 5000) > 0);
	r.d.fault = 1;
	drive_step(&r.d, r.target);
	assert_int_equal(until_ready(&r, 10), -1);
	assert_int_equal(r.s.fault, MLIP_SPINDLE_DRIVE_FAULT);
	/* at speed, a load step it recovers from within band_periods: none;
	 * one it does not: out of band */
	rig_init(&r, 10000);
	mlip_spindle_command(&r.s, 3000, r.period);
	assert_true(until_ready(&r, 5000) > 0);
	r.d.load_drop_rpm = 100;
	for (k = 0; k < 50; k++) {
		assert_int_equal(
		    mlip_spindle_step(&r.s, r.d.sw, actual_counts(&r.d), r.period++, &r.target), 1);
	}
	r.d.load_drop_rpm = 0;
	assert_int_equal(
	    mlip_spindle_step(&r.s, r.d.sw, actual_counts(&r.d), r.period++, &r.target), 1);
	r.d.load_drop_rpm = 100;
	for (k = 0; k <= 50; k++) {
		assert_int_equal(
		    mlip_spindle_step(&r.s, r.d.sw, actual_counts(&r.d), r.period++, &r.target),
		    k < 50 ? 1 : -1);
	}
	assert_int_equal(r.s.fault, MLIP_SPINDLE_OUT_OF_BAND);
	assert_string_equal(mlip_spindle_fault_name(r.s.fault), "out of band");
}

static void test_bad_config(void **state)
{
	struct mlip_spindle s;
	struct mlip_spindle_cfg c = {0, 30, 2000, 50};

	(void)state;
	assert_int_equal(mlip_spindle_init(&s, &c), MLIP_E_INVALID);
	c.counts_per_rev = NAN;
	assert_int_equal(mlip_spindle_init(&s, &c), MLIP_E_INVALID);
	c.counts_per_rev = 4096;
	c.timeout_periods = 0;
	assert_int_equal(mlip_spindle_init(&s, &c), MLIP_E_INVALID);
	c.timeout_periods = 1;
	c.band_rpm = -1;
	assert_int_equal(mlip_spindle_init(&s, &c), MLIP_E_INVALID);
}

/* The controller's part: the override within 50..200 % and within MIN_RPM ..
 * MAX_RPM (the program's S was checked at its line; the operator's choice is
 * clamped), the direction kept; a fault reported once, as the event the
 * controller names; the wait measured. */
static void test_ctl_override_and_fault(void **state)
{
	struct mlip_spindle_config cfg = {9, 1000, 12000, 4096, 10000, 240, 3.4, 0.2};
	struct mlip_ctl_spindle s;
	struct drive d = {4096, 10000, 20, 0, 0, 0x0027, 0, 0};
	uint32_t ev = 0;
	double val = 0;
	uint64_t k;
	int rc = 0;

	(void)state;
	assert_int_equal(mlip_ctl_spindle_init(&s, NULL, 0.001), MLIP_OK);
	assert_false(s.on);
	assert_int_equal(mlip_ctl_spindle_override(&s, 100, 0), MLIP_E_INVALID);
	assert_int_equal(mlip_ctl_spindle_init(&s, &cfg, 0.001), MLIP_OK);
	assert_true(s.on && s.drive.cfg.timeout_periods == 3400 && s.drive.cfg.band_periods == 200);
	assert_true(mlip_ctl_spindle_at_rest(&s));
	mlip_ctl_spindle_ask(&s, -8000, 0); /* M4 S8000 */
	assert_true(mlip_ctl_spindle_cmd_rpm(&s) == -8000);
	assert_int_equal(mlip_ctl_spindle_override(&s, 49, 0), MLIP_E_RANGE);
	assert_int_equal(mlip_ctl_spindle_override(&s, 201, 0), MLIP_E_RANGE);
	assert_int_equal(mlip_ctl_spindle_override(&s, 200, 0), MLIP_OK);
	assert_true(mlip_ctl_spindle_cmd_rpm(&s) == -12000); /* 16000 clamped to MAX_RPM */
	assert_int_equal(mlip_ctl_spindle_override(&s, 50, 0), MLIP_OK);
	assert_true(mlip_ctl_spindle_cmd_rpm(&s) == -4000);
	mlip_ctl_spindle_ask(&s, 1500, 0);
	assert_true(mlip_ctl_spindle_cmd_rpm(&s) == 1000); /* 750 raised to MIN_RPM */
	assert_int_equal(mlip_ctl_spindle_override(&s, 100, 0), MLIP_OK);
	for (k = 0; k < 1000 && rc != 1; k++) {
		rc = mlip_ctl_spindle_step(&s, d.sw, actual_counts(&d), k, &ev, &val);
		drive_step(&d, s.target);
	}
	assert_int_equal(rc, 1);
	/* 1500 rpm at 10000 rpm/s: 150 periods, then the window (20 rpm) */
	assert_true(s.ready_after >= 147 && s.ready_after <= 152);
	d.fault = 1;
	drive_step(&d, s.target);
	assert_int_equal(mlip_ctl_spindle_step(&s, d.sw, actual_counts(&d), k, &ev, &val), -1);
	assert_int_equal(ev, MLIP_DRIVE_FAULT_BIT);
	assert_int_equal(mlip_ctl_spindle_step(&s, d.sw, actual_counts(&d), k + 1, &ev, &val), -2);
	assert_int_equal(s.target, 0);
	assert_true(mlip_ctl_spindle_cmd_rpm(&s) == 0);
	assert_string_equal(mlip_drive_fault_name(MLIP_DRIVE_SPINDLE_OUT_OF_BAND),
	                    "spindle speed out of its band");
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_start_waits_for_speed),
	    cmocka_unit_test(test_stop_and_reversal_wait_for_standstill),
	    cmocka_unit_test(test_faults),
	    cmocka_unit_test(test_bad_config),
	    cmocka_unit_test(test_ctl_override_and_fault),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
