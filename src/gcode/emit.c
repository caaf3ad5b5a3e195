/*
 * emit.c - blocks out: moves (points closer than MLIP_GCODE_MERGE_MM to the
 * last one merged), program events, and the soft limits of a target.
 */
#include <math.h>
#include <string.h>

#include "gc.h"

/* The line's dwell, before its first move (LinuxCNC: dwell, then motion). */
int mlip_gc_flush_dwell(struct mlip_gcode *g, struct emit_ctx *c)
{
	if (c->n_io > 0 && mlip_gc_flush_io(g, c) != 0) {
		return -1; /* the line's I/O first (LinuxCNC: before the dwell) */
	}
	if (c->dwell_pending) {
		if (mlip_gc_emit_event(g, c->sink, c->ctx, c->line, MLIP_BLOCK_DWELL, c->dwell_s) !=
		    0) {
			return -1;
		}
		c->dwell_pending = 0;
	}
	return 0;
}

/* Emit t unless it is within MLIP_GCODE_MERGE_MM of the last emitted point
 * (no zero-length segment for the planner). Returns 0, or -1 when the sink
 * refused the block. */
int mlip_gc_emit(struct mlip_gcode *g, struct emit_ctx *c, const double *t, double tol_mm)
{
	struct mlip_block b;
	double d2 = 0;
	int i, n = g->m->n_axes;

	if (mlip_gc_flush_dwell(g, c) != 0) {
		return -1;
	}
	for (i = 0; i < n; i++) {
		d2 += (t[i] - g->pos[i]) * (t[i] - g->pos[i]);
	}
	if (d2 < MLIP_GCODE_MERGE_MM * MLIP_GCODE_MERGE_MM) {
		return 0;
	}
	memset(&b, 0, sizeof b);
	for (i = 0; i < n; i++) {
		b.target[i] = t[i];
	}
	b.feed_mm_s = c->feed_mm_s;
	b.tol_mm = tol_mm;
	b.line = c->line;
	b.rapid = c->rapid;
	b.exact_stop = (uint8_t)g->exact_stop;
	if (c->sink(c->ctx, &b) != 0) {
		return -1;
	}
	for (i = 0; i < n; i++) {
		g->pos[i] = t[i];
	}
	g->blocks++;
	g->moves++;
	return 0;
}

/* A program event (dwell, pause; the machine's I/O: value is then the
 * event's, else the dwell) at the last emitted point. 0, or -1 when the sink
 * refused it. */
int mlip_gc_emit_event(struct mlip_gcode *g, mlip_block_sink sink, void *ctx, uint32_t line,
                       mlip_block_kind kind, double dwell_s)
{
	struct mlip_block b;

	memset(&b, 0, sizeof b);
	memcpy(b.target, g->pos, sizeof b.target);
	b.feed_mm_s = g->m->max_feed_mm_s;
	b.tol_mm = g->tol_mm;
	b.line = line;
	b.kind = (uint8_t)kind;
	if (kind >= MLIP_BLOCK_SPINDLE) {
		b.value = dwell_s;
	} else {
		b.dwell_s = dwell_s;
	}
	if (sink(ctx, &b) != 0) {
		return -1;
	}
	g->blocks++;
	return 0;
}

/* Soft limits (and finiteness) of a target; col_of[i] is the column to blame
 * for axis i. */
mlip_status mlip_gc_check_limits(const struct mlip_gcode *g, const double *t,
                                 const uint32_t *col_of, uint32_t line, int on_arc,
                                 struct mlip_gcode_error *e)
{
	const struct mlip_machine *m = g->m;
	int i;

	for (i = 0; i < m->n_axes; i++) {
		const struct mlip_axis *ax = &m->axis[i];

		if (!isfinite(t[i])) {
			return mlip_gc_fail(e, line, col_of[i], MLIP_E_RANGE,
			                    "%c value is not finite", mlip_upper(ax->letter));
		}
		if (!(t[i] >= ax->min_limit && t[i] <= ax->max_limit)) {
			return mlip_gc_fail(e, line, col_of[i], MLIP_E_RANGE,
			                    "%c %f beyond soft limit %f%s", mlip_upper(ax->letter),
			                    t[i],
			                    t[i] < ax->min_limit ? ax->min_limit : ax->max_limit,
			                    on_arc ? " on the arc" : "");
		}
	}
	return MLIP_OK;
}
