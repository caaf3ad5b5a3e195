/*
 * machio.h - private to src/ctl/: the machine's outputs and probing in the
 * controller (issue 19), called from the period (controller.c):
 *   - M7/M8/M9 with [COOLANT] TYPE = io and M64/M65 switch bits of the I/O
 *     module's outputs (out->outputs, sent in its RPDO by rt/drives.c) at
 *     rest; every output goes off on entering IDLE, STOPPING, FAULT or ESTOP
 *     (a program's end, a stop, a fault, an E-stop);
 *   - G38.2..G38.5: a move toward the target that stops on the path at the
 *     acceleration limit (mlip_planner_stop) in the period the probe input
 *     changes, the position of that period latched as the result; or, with
 *     [PROBE] SOURCE = drive, in the period the first drive's TPDOs report
 *     its touch probe latched, each drive's latched position the result; a probe
 *     error (no trip for G38.2/.4, tripped at the start, no input) stops the
 *     program at rest (idle, the reason named).
 */
#ifndef MLIP_CTL_MACHIO_H
#define MLIP_CTL_MACHIO_H

#include "mlip/ctl/controller.h"

/* The coolant is switched by the module's outputs (MIST or FLOOD mapped),
 * not by the operator. */
int mlip_mio_coolant_io(const struct mlip_ctl *c);

/* Every output off (and the coolant); a probe move is over. */
void mlip_mio_all_off(struct mlip_ctl *c);

/* This period's inputs and positions actual, and the probe's trip: the
 * latched position and a stop on the path. Before the records are taken. */
void mlip_mio_period(struct mlip_ctl *c, const struct mlip_ctl_in *in);

/* A COOLANT (io) or OUTPUT record taken at rest: MLIP_OK with the outputs
 * switched, or MLIP_E_RANGE with *why (a record the machine cannot do: an
 * outlet or output not mapped). */
mlip_status mlip_mio_switch(struct mlip_ctl *c, const struct mlip_ring_rec *rec,
                            struct mlip_ctl_reason *why);

/* A PROBE record taken at rest: MLIP_OK with its move in the planner, or
 * MLIP_E_RANGE with *why (no probe input, or the probe already in the state
 * the move looks for). */
mlip_status mlip_mio_probe_start(struct mlip_ctl *c, const struct mlip_ring_rec *rec,
                                 struct mlip_ctl_reason *why);

/* The drives' touch probe being switched off, then on, before a G38's move
 * ([PROBE] SOURCE = drive; called each period while the probe move is at
 * rest): 1 still arming (or its move pushed this period), 0 not arming (the
 * move is over), -1 with *why (a drive did not confirm in time, or latched
 * an edge while armed at rest). */
int mlip_mio_probe_arming(struct mlip_ctl *c, const struct mlip_ctl_in *in,
                          struct mlip_ctl_reason *why);

/* The probe move is at rest: the result recorded; MLIP_OK, or MLIP_E_RANGE
 * with *why when it had to trip and did not. */
mlip_status mlip_mio_probe_end(struct mlip_ctl *c, struct mlip_ctl_reason *why);

/* An M62/M63 record (an OUTPUT beyond MLIP_DOUT_SYNC) taken by the
 * ingest: switched in the period the move after it starts (MLIP_E_FULL:
 * MLIP_SYNC_OUT_MAX wait already, take it later). */
mlip_status mlip_mio_sync_add(struct mlip_ctl *c, const struct mlip_ring_rec *rec);

/* After the period's step: the M62/M63 whose move produced this setpoint
 * (the planner executes a block after theirs), or all at rest with nothing
 * queued, switched now; a switch the machine cannot do: MLIP_E_RANGE with
 * *why. */
mlip_status mlip_mio_sync_step(struct mlip_ctl *c, struct mlip_ctl_reason *why);

/* The status fields: outputs, coolant, the last probe. */
void mlip_mio_publish(const struct mlip_ctl *c, struct mlip_ring_status *s);

#endif
