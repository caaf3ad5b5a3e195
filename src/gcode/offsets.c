/*
 * offsets.c - the offsets state (G10 L2/L20, G92 and its variants,
 * G28.1/G30.1) and the moves to stored positions (G28/G30), as LinuxCNC.
 */
#include <string.h>

#include "gc.h"

/* The tool length offset on axis i (Z only). */
static double tlo_of(const struct mlip_gcode *g, int i)
{
	return g->tlo_mm != 0.0 && i == mlip_gc_z_index(g->m) ? g->tlo_mm : 0.0;
}

double mlip_gc_offset_of(const struct mlip_gcode *g, int i)
{
	return g->off.coord[g->off.select][i] + (g->off.g92_on ? g->off.g92[i] : 0.0) +
	       tlo_of(g, i);
}

/* G10 L2/L20, G92 and its variants, G28.1/G30.1: the offsets state, in
 * LinuxCNC's order (after the modes, before the motion). Values are in the
 * line's units; G91 does not apply to them. */
void mlip_gc_set_offsets(struct mlip_gcode *g, const struct blk *b, double scale)
{
	struct mlip_gcode_offsets *o = &g->off;
	const struct mlip_machine *m = g->m;
	int i, a, sys;
	double v, k;

	for (i = 0; i < m->n_axes; i++) {
		a = mlip_gc_axis_slot(mlip_upper(m->axis[i].letter));
		k = m->axis[i].kind == MLIP_AXIS_ROTARY ? 1.0 : scale;
		v = a >= 0 && b->has_ax[a] ? b->ax[a] * k : 0;
		if (b->g10 && a >= 0 && b->has_ax[a]) {
			sys = b->p == 0 ? o->select : (int)b->p - 1;
			/* L2: the origin in machine coordinates; L20: the origin that
			 * makes the current point read v */
			o->coord[sys][i] = b->l == 2 ? v
			                             : g->cur[i] - (o->g92_on ? o->g92[i] : 0.0) -
			                                   tlo_of(g, i) - v;
		}
		if (b->g92 == 920) {
			o->g92[i] = a >= 0 && b->has_ax[a]
			                ? g->cur[i] - o->coord[o->select][i] - tlo_of(g, i) - v
			                : (o->g92_on ? o->g92[i] : 0.0);
		} else if (b->g92 == 921) {
			o->g92[i] = 0;
		}
		if (b->homeset == 28) {
			o->g28[i] = g->cur[i];
		} else if (b->homeset == 30) {
			o->g30[i] = g->cur[i];
		}
	}
	if (b->g92) {
		o->g92_on = b->g92 == 920 || b->g92 == 923;
	}
}

/* G28/G30: rapid to the intermediate point t (when axis words were given,
 * those axes only), then to the stored position (those axes, or all). */
mlip_status mlip_gc_go_home(struct mlip_gcode *g, const struct blk *b, const struct plan *pl,
                            struct emit_ctx *ec, const double *t, const uint32_t *col_of,
                            uint32_t line, struct mlip_gcode_error *e)
{
	const struct mlip_machine *m = g->m;
	const double *stored = b->home == 28 ? g->off.g28 : g->off.g30;
	double dest[MLIP_MAX_AXES];
	uint32_t col[MLIP_MAX_AXES];
	mlip_status st;
	int i, a;

	for (i = 0; i < m->n_axes; i++) {
		a = mlip_gc_axis_slot(mlip_upper(m->axis[i].letter));
		dest[i] = !pl->has_axes || (a >= 0 && b->has_ax[a]) ? stored[i] : t[i];
		col[i] = b->home_col;
	}
	st = mlip_gc_check_limits(g, t, col_of, line, 0, e);
	if (st == MLIP_OK) {
		st = mlip_gc_check_limits(g, dest, col, line, 0, e);
	}
	if (st != MLIP_OK) {
		return st;
	}
	ec->rapid = 1;
	ec->feed_mm_s = m->max_feed_mm_s;
	if (mlip_gc_emit(g, ec, t, g->tol_mm) != 0 || mlip_gc_emit(g, ec, dest, g->tol_mm) != 0) {
		return MLIP_E_FULL;
	}
	memcpy(g->cur, dest, sizeof dest);
	mlip_gc_notice(g, b->home == 28 ? "G28" : "G30", line);
	return MLIP_OK;
}
