/*
 * grblmach.h - the machine's side of Grbl 1.1's reports, pure: which of the
 * controller's inputs Grbl shows as pins (Pn:), what its spindle and coolant
 * are doing (A:, and FS's spindle speed), and which Grbl alarm a
 * controller's stop is (ALARM:x, doc/csv/alarm_codes_en_US.csv). From the
 * status mlip-rt publishes (mlip/ipc/ring.h, mlip/ctl/state.h); no I/O.
 */
#ifndef MLIP_TOOLS_GRBLMACH_H
#define MLIP_TOOLS_GRBLMACH_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/types.h"

/* Grbl's alarm codes used for the controller's stops. */
enum {
	GRBL_ALARM_HARD_LIMIT = 1,   /* a limit switch while moving */
	GRBL_ALARM_SOFT_LIMIT = 2,   /* a target beyond the travel */
	GRBL_ALARM_ABORT = 3,        /* stopped in motion: position not guaranteed */
	GRBL_ALARM_HOMING_RESET = 6, /* homing stopped (E-stop, a stop) */
	GRBL_ALARM_HOMING_FAIL = 9   /* homing failed (the drive's error, a timeout) */
};

/* The Pn: letters of the input functions that are on (status io_inputs,
 * bit f for MLIP_IN_f), in Grbl's order (report.c): P probe; each axis'
 * letter when one of its limit switches or its home switch is on (Grbl's
 * limit pins are its homing switches); R the E-stop (the reset/abort pin
 * a Grbl machine's E-stop is wired to); H feed hold; S cycle start. Grbl
 * 1.1 has no door input here (D: mlip has none). out gets "" when none. */
void grbl_pins(char *out, size_t n, uint32_t inputs, const struct mlip_machine *m);

/* The A: letters: S spindle clockwise or C counter-clockwise (rpm > 0 or
 * < 0), F flood, M mist (coolant MLIP_COOLANT_* bits); "" when all off. */
void grbl_accessories(char *out, size_t n, double rpm, uint32_t coolant);

/* The alarm a controller state is (state, its reason; was: the state
 * before it), 0 when it locks nothing: E-stop (an input, the I/O module
 * lost) 3, or 6 while homing; a limit switch 1; a homing failure 9; any
 * other fault (a drive, a bad record, ...) 3. */
int grbl_alarm_of(uint32_t state, uint32_t reason, uint32_t was);

/* 1 when the controller leaves the state with a reset (MLIP_CMD_RESET,
 * mlip-ctl reset) once its input is released: an E-stop, a limit switch,
 * a homing failure; 0 when only a restart of mlip-rt clears it. */
int grbl_resettable(uint32_t state, uint32_t reason);

/* What the machine's manual spindle and coolant are doing: the controller
 * pauses at each such event (state PAUSED, reason SPINDLE or COOLANT, value
 * the rpm or the coolant bits) until the operator has done it and resumes;
 * the event is done when the pause is left by a resume (whatever follows
 * it), not when it is left by a stop, an E-stop or a fault. */
struct grbl_acc {
	double rpm;       /* > 0 clockwise, < 0 counter-clockwise, 0 stopped */
	uint32_t coolant; /* MLIP_COOLANT_* */
	/* the pause being waited on */
	int pending;      /* 0 none, else its reason (MLIP_WHY_SPINDLE / _COOLANT) */
	uint64_t seq;     /* its record */
	double value;     /* what it asks for */
	uint32_t changes; /* counts each change (a report shows A: at once) */
};

/* Feed one status (state, reason, reason_seq, reason_value) as read; call
 * for every status read (a pause lasts until the operator acts). */
void grbl_acc_update(struct grbl_acc *a, uint32_t state, uint32_t reason, uint64_t seq,
                     double value);

/* CiA 402 homing method (0x6098) m's search direction: 1 toward negative
 * (a negative limit or home switch, the negative index pulse), 0 toward
 * positive, -1 none (35, 37: the current position; a manufacturer's). */
int grbl_home_negative(int method);

struct grbl_homing;
struct mlip_config;
/* 1 with what differs in why when machine a is not b (axes, limits,
 * speeds, period, tolerance): a --config that is not the controller's. */
int grbl_machine_differs(const struct mlip_machine *a, const struct mlip_machine *b, char *why,
                         size_t n);

/* $22..$25 of configuration c (homing configured, the axes homing toward
 * negative in Grbl's X Y Z A B C bits, the slowest latch and search speeds
 * in mm/min); $21 is the caller's (the limit inputs mapped). */
void grbl_homing_of(const struct mlip_config *c, struct grbl_homing *h);

/* The controller's own spindle ([SPINDLE] TYPE = cia402, status layout 10)
 * as A:, FS and Ov show it, checked as anything read from another process:
 * the phase (spindle_state: mlip_spindle_phase + 1, 1..5), the commanded
 * rpm (the override in, within the spindle's MAX_RPM: the controller clamps
 * it there) and the override (50..200 %). 0 and *rpm (> 0 clockwise, < 0
 * counter-clockwise, 0 stopped) and *ov, or -1: a value this controller
 * cannot publish (nothing is taken from it). */
int grbl_spindle_of(uint32_t spindle_state, double cmd_rpm, uint32_t override_pct, double max_rpm,
                    double *rpm, int *ov);

/* An override byte applied to the controller's spindle override: Grbl's
 * steps (grbl_override_step), within the controller's 50..200 %. */
int grbl_spindle_ov_step(int rt, int pct);

#endif
