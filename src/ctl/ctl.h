/*
 * ctl.h - private to src/ctl/: what the parts of the controller's period
 * (mlip_ctl_period, mlip/ctl/controller.h) share. The controller is one
 * state (struct mlip_ctl) and one entry point; its parts, by concern:
 *   controller.c  init; the period in its order (stall, inputs, command,
 *                 stop requests, bus, drive fault, jog, homing, records,
 *                 one step, power, frames, status); the operator's commands
 *   estop.c       the inputs on the bus (E-stop, limits, hold, cycle start),
 *                 the quick stop, the reset, the outputs
 *   stop.c        stops on the path: a stop request, a drive fault, the
 *                 stop's measure (status stop_*)
 *   jog.c         continuous jog, its dead-man
 *   homing.c      homing with the drives' homing mode (SDO set-up, mode 6)
 *   run.c         the program: records checked and taken (pre-read,
 *                 ingest), waits (dwell, pause, manual I/O), the
 *                 transitions the motion decides
 *   power.c       the drives' power (CiA 402 sequencer, all drives in step)
 *   spindlectl.c  a CiA 402 spindle (mlip/ctl/spindlectl.h): its decisions, and
 *                 its part of the period (the wait for speed, its faults, its
 *                 RPDO and status)
 *   follow.c      JERK_PLAN = path: a program's setpoints from the planned
 *                 queue (hold, stop, override, its end)
 *   machio.c      the machine's outputs (coolant, M64/M65) and probing (G38),
 *                 its own header machio.h (issue 19)
 * Functions of one part that another calls are mlip_ct_*, declared here.
 */
#ifndef MLIP_CTL_CTL_H
#define MLIP_CTL_CTL_H

#include <stdint.h>

#include "machio.h"
#include "mlip/ctl/controller.h"

/* homing.c's steps; the period reads them for the controlword */
enum { HS_ENABLE = 1, HS_SETUP, HS_ARM, HS_RUN, HS_BACK, HS_NEXT };

void mlip_ct_progress(const struct mlip_ctl *c, uint64_t *seq, uint32_t *line);

static inline void emit(struct mlip_ctl *c, struct mlip_ctl_out *out, uint32_t kind, uint32_t from,
                        const struct mlip_ctl_reason *r)
{
	if (out->n_events < MLIP_CTL_MAX_EVENTS) {
		struct mlip_ctl_event *e = &out->events[out->n_events++];
		e->kind = kind;
		e->from = from;
		e->state = c->state;
		e->r = *r;
		e->period = c->period;
		mlip_ct_progress(c, &e->exec_seq, &e->exec_line);
	}
}

static inline struct mlip_ctl_reason reason(uint32_t why, uint64_t seq, uint32_t line)
{
	struct mlip_ctl_reason r = {.why = why, .seq = seq, .line = line};
	return r;
}

/* Axis k is to be homed (HOME_METHOD) and is not yet: its soft limits mean
 * nothing so far. */
static inline int unhomed(const struct mlip_ctl *c, int k)
{
	return ((c->home.configured & ~c->home.homed) >> k) & 1u;
}

/* Everything switched off: the outputs, the coolant, the spindle. */
static inline void all_off(struct mlip_ctl *c)
{
	mlip_mio_all_off(c);
	mlip_ctl_spindle_ask(&c->spindle, 0.0, c->period);
}

/* At rest for this reason, what the operator switched stays on: MDI lines
 * done, a jog or homing done (LinuxCNC: an MDI M3, M8 or M64 stays on while
 * the operator jogs and touches off, until M5/M9/M65, a program's end, a
 * stop, a fault, an E-stop). Every other end switches it all off. */
static inline int keeps_on(const struct mlip_ctl *c, uint32_t why)
{
	return (why == MLIP_WHY_END && c->prog.mdi) || why == MLIP_WHY_JOG_RELEASED ||
	       why == MLIP_WHY_JOG_END || why == MLIP_WHY_JOG_DONE || why == MLIP_WHY_HOMED;
}

/* Every change of state goes through here: named, with its reason. */
static inline void go(struct mlip_ctl *c, struct mlip_ctl_out *out, uint32_t state,
                      struct mlip_ctl_reason r)
{
	uint32_t from = c->state;
	if (from == state && c->why.why == r.why) {
		return;
	}
	c->state = state;
	c->why = r;
	if ((state == MLIP_STATE_IDLE && !keeps_on(c, r.why)) || state == MLIP_STATE_STOPPING ||
	    state == MLIP_STATE_FAULT || state == MLIP_STATE_ESTOP) {
		all_off(c); /* a program's end, a stop, a fault, an E-stop (issue 19) */
	}
	emit(c, out, MLIP_EV_STATE, from, &r);
}

/* Records of this period not taken yet (in->recs). */
static inline uint32_t rx_count(const struct mlip_ctl *c)
{
	return c->rx.corrupt ? 0 : c->rx.view->len[0] + c->rx.view->len[1] - c->rx.taken;
}

/* controller.c */
int32_t mlip_ct_apply_command(struct mlip_ctl *c, struct mlip_ctl_out *out,
                              const struct mlip_ctl_in *in, const struct mlip_ring_cmd *cmd);

/* run.c */
void mlip_ct_fault(struct mlip_ctl *c, struct mlip_ctl_out *out, struct mlip_ctl_reason r);
void mlip_ct_blocks_in(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out);
void mlip_ct_after_step(struct mlip_ctl *c, struct mlip_ctl_out *out, const struct mlip_ctl_in *in,
                        mlip_run_state rs, int still);
uint32_t mlip_ct_held_by(const struct mlip_ctl *c);

/* stop.c */
void mlip_ct_drive_fault(struct mlip_ctl *c, struct mlip_ctl_out *out,
                         const struct mlip_ctl_drive_fault *f);
void mlip_ct_brake_begin(struct mlip_ctl *c);
void mlip_ct_brake_step(struct mlip_ctl *c, const double *prev, mlip_run_state rs);
void mlip_ct_begin_stop(struct mlip_ctl *c, struct mlip_ctl_out *out, uint32_t why);
void mlip_ct_planner_stop(struct mlip_ctl *c);
void mlip_ct_hold_clear(struct mlip_ctl *c);

/* estop.c */
void mlip_ct_follow_actual(struct mlip_ctl *c, const struct mlip_ctl_in *in);
void mlip_ct_estop_rest(struct mlip_ctl *c, const struct mlip_ctl_in *in);
int mlip_ct_estop_at_rest(const struct mlip_ctl *c);
void mlip_ct_quick_stop(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out,
                        uint32_t state, struct mlip_ctl_reason r);
int32_t mlip_ct_reset(struct mlip_ctl *c, struct mlip_ctl_out *out, const struct mlip_ctl_in *in);
void mlip_ct_io_period(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out);

/* jog.c */
void mlip_ct_jog_release(struct mlip_ctl *c, uint32_t why);
int32_t mlip_ct_jog_command(struct mlip_ctl *c, struct mlip_ctl_out *out, int32_t arg);
int32_t mlip_ct_jog_axis_command(struct mlip_ctl *c, int32_t arg);
void mlip_ct_jog_period(struct mlip_ctl *c, struct mlip_ctl_out *out);

/* homing.c */
void mlip_ct_home_abort(struct mlip_ctl *c);
int32_t mlip_ct_home_command(struct mlip_ctl *c, struct mlip_ctl_out *out, int32_t arg);
void mlip_ct_home_period(struct mlip_ctl *c, const struct mlip_ctl_in *in,
                         struct mlip_ctl_out *out);

/* spindlectl.c: a CiA 402 spindle (mlip/ctl/spindlectl.h) in the period */
int mlip_ct_spindle_held(const struct mlip_ctl *c);
void mlip_ct_spindle_period(struct mlip_ctl *c, const struct mlip_ctl_in *in,
                            struct mlip_ctl_out *out);
void mlip_ct_spindle_out(const struct mlip_ctl *c, const struct mlip_ctl_in *in,
                         struct mlip_ctl_out *out);
/* the node of drive i of the power sequencer's group: the axes, then the spindle */
static inline uint32_t mlip_ct_node_of(const struct mlip_ctl *c, int i)
{
	return i < c->m.n_axes ? (uint32_t)c->m.axis[i].can_node : c->spindle.node;
}

/* follow.c: JERK_PLAN = path, the setpoints from the planned queue */
void mlip_ct_ext_drop(struct mlip_ctl *c);
void mlip_ct_ext_override(struct mlip_ctl *c, double pct);
int mlip_ct_ext_start(struct mlip_ctl *c, const struct mlip_ctl_in *in, struct mlip_ctl_out *out);
void mlip_ct_ext_stop(struct mlip_ctl *c, struct mlip_ctl_out *out, uint32_t why);
void mlip_ct_ext_step(struct mlip_ctl *c, struct mlip_ctl_out *out);

/* power.c */
void mlip_ct_power_period(struct mlip_ctl *c, const struct mlip_ctl_in *in,
                          struct mlip_ctl_out *out);

#endif
