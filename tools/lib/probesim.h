/*
 * probesim.h - a probe touching a surface, for running G38 off-line
 * (mlip-sim --probe-surface): the controller's probe inputs computed from
 * its own setpoints, as the machine's devices would give them.
 *
 *   [PROBE] SOURCE = io: the module's probe input is on from the period after
 *     the setpoint reached the surface (a module that reads the axis one
 *     period late); the controller takes the position of that period.
 *   [PROBE] SOURCE = drive: every axis drive's touch probe 1 with CiA 402's
 *     timing (the RPDO of period j applied at the SYNC of period j + 1, the
 *     TPDOs of that SYNC sampled before it): 0x60B8 switched on arms it, the
 *     drives move linearly between SYNCs and latch where they are at the
 *     instant the axis crosses the surface; the result is that crossing,
 *     exactly, as the machine's drives latch it.
 * Without a surface the probe never touches (G38.2/.4 end "not tripped").
 */
#ifndef MLIP_PROBESIM_H
#define MLIP_PROBESIM_H

#include <stdint.h>

#include "mlip/ctl/controller.h"

struct mlip_probesim {
	int axis;  /* the surface's axis (-1: no surface) */
	double at; /* its position (mm, machine coordinates) */
	int below; /* the probe is on at and below it (else at and above) */
	int drive; /* [PROBE] SOURCE = drive: model the drives' touch probe */
	int n_axes;
	uint64_t n; /* periods seen */
	/* the last four periods' 0x60B8 and setpoints (ring by period % 4) */
	uint16_t fn[4];
	double pos[4][MLIP_MAX_AXES];
	uint16_t fn_now, status; /* the drives': in force, 0x60B9 */
	double latched[MLIP_MAX_AXES];
	uint32_t latches; /* edges latched */
};

/* "Z=-5" or "Z=-5,below" / "X=100,above" against the machine's axis letters:
 * 0, or -1 with *why (a static text). */
int mlip_probesim_parse(struct mlip_probesim *p, const char *arg, const char *letters,
                        const char **why);

/* Before the first period: the source, the axes, where they stand (the
 * module's input of the first period reads it: a probe already on there is
 * on from the start, as the module's first TPDO says on the machine). */
void mlip_probesim_start(struct mlip_probesim *p, int drive, int n_axes, const double *start);

/* The probe's inputs of this period into *in (its io.active probe bit,
 * or its drives' touch probe fields), from the periods before it. */
void mlip_probesim_in(struct mlip_probesim *p, struct mlip_ctl_in *in);

/* After the period: its setpoint and the 0x60B8 it sends (ctl.mio.tp_fn). */
void mlip_probesim_out(struct mlip_probesim *p, const double *pos, uint16_t tp_fn);

#endif
