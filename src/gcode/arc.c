/*
 * arc.c - G2/G3 into chords of equal angle. For a chord of angle d on a
 * circle of radius r the sagitta is  s = r (1 - cos(d/2)) = 2 r sin^2(d/4),
 * so the largest step with s <= S is  d = 4 asin(sqrt(S / (2 r))),  with
 * S = MLIP_GCODE_ARC_FRACTION * eps. The corner between two chords of one
 * arc then gets eps - s, so chord error plus corner error stays within eps.
 * Plane conventions follow RS274NGC/LinuxCNC: G17 (u,v) = (X,Y) with I,J;
 * G18 (u,v) = (Z,X) with K,I; G19 (u,v) = (Y,Z) with J,K; G3 turns from u
 * toward v (counter-clockwise seen from the positive normal axis).
 */
#include <math.h>
#include <string.h>

#include "gc.h"

/* Plane tables for G17, G18, G19: the (u, v) axes, their offset words (I=0,
 * J=1, K=2) and the offset word of the normal axis, which is not allowed. */
static const char plane_u[3] = {'X', 'Z', 'Y'}, plane_v[3] = {'Y', 'X', 'Z'};
static const int plane_ou[3] = {0, 2, 1}, plane_ov[3] = {1, 0, 2}, plane_off[3] = {2, 1, 0};

/* Point k of n along the arc; the last one is the programmed end exactly.
 * Axes other than the plane's move linearly with the angle (helix). */
static void arc_point(const struct arc *a, const double *s, const double *t, int n_axes, uint32_t k,
                      double *p)
{
	double f = (double)k / a->n, ang, r;
	int i;

	for (i = 0; i < n_axes; i++) {
		p[i] = k == a->n ? t[i] : s[i] + (t[i] - s[i]) * f;
	}
	if (k == a->n) {
		return;
	}
	ang = a->a0 + a->sweep * f;
	r = a->r0 + (a->r1 - a->r0) * f;
	p[a->iu] = a->cu + r * cos(ang);
	p[a->iv] = a->cv + r * sin(ang);
}

/* Center and radius of an R arc: on the left of start->end for a short G3,
 * mirrored for G2 and for the long arc (R < 0). */
static mlip_status arc_center_r(const struct blk *b, int cw, double scale, double su, double sv,
                                double eu, double ev, uint32_t line, struct arc *a,
                                struct mlip_gcode_error *e)
{
	double r = fabs(b->r) * scale, du = eu - su, dv = ev - sv;
	double d = sqrt(du * du + dv * dv), h, side;

	if (!(r > 0)) {
		return mlip_gc_fail(e, line, b->r_col, MLIP_E_RANGE, "R arc with zero radius");
	}
	if (d < 1e-9) {
		return mlip_gc_fail(e, line, b->r_col, MLIP_E_RANGE,
		                    "R arc with end equal to start: use I/J/K for a full circle");
	}
	if (d > 2 * r * (1 + 1e-9) + 1e-9) {
		return mlip_gc_fail(e, line, b->r_col, MLIP_E_RANGE,
		                    "R arc: endpoints %f mm apart, more than 2R = %f mm", d, 2 * r);
	}
	h = d >= 2 * r ? 0 : sqrt(r * r - d * d / 4);
	side = (cw ? -1.0 : 1.0) * (b->r > 0 ? 1.0 : -1.0);
	a->cu = (su + eu) / 2 - side * h * dv / d;
	a->cv = (sv + ev) / 2 + side * h * du / d;
	return MLIP_OK;
}

mlip_status mlip_gc_arc_setup(const struct mlip_gcode *g, const struct blk *b, int motion,
                              double scale, const double *s, const double *t, uint32_t line,
                              uint32_t col, struct arc *a, struct mlip_gcode_error *e)
{
	int p = g->plane - 17, cw = motion == 2;
	int has_uv = b->has_ijk[plane_ou[p]] || b->has_ijk[plane_ov[p]];
	double su, sv, eu, ev, sweep, rmax, smax, step;
	mlip_status st;

	memset(a, 0, sizeof *a);
	a->iu = mlip_gc_axis_index(g->m, plane_u[p]);
	a->iv = mlip_gc_axis_index(g->m, plane_v[p]);
	if (a->iu < 0 || a->iv < 0) {
		return mlip_gc_fail(e, line, col, MLIP_E_UNSUPPORTED,
		                    "%G in G%u needs axes %c and %c configured", motion * 10,
		                    (unsigned)g->plane, plane_u[p], plane_v[p]);
	}
	if (b->has_ijk[plane_off[p]]) {
		return mlip_gc_fail(e, line, b->ijk_col[plane_off[p]], MLIP_E_SYNTAX,
		                    "%c word not used by an arc in the G%u plane",
		                    'I' + plane_off[p], (unsigned)g->plane);
	}
	su = s[a->iu];
	sv = s[a->iv];
	eu = t[a->iu];
	ev = t[a->iv];
	if (b->has_r && has_uv) {
		return mlip_gc_fail(e, line, b->r_col, MLIP_E_SYNTAX, "arc with both R and I/J/K");
	}
	if (b->has_r) {
		st = arc_center_r(b, cw, scale, su, sv, eu, ev, line, a, e);
		if (st != MLIP_OK) {
			return st;
		}
	} else if (!has_uv) {
		return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX, "arc with no I/J/K or R");
	} else {
		/* I J K: offsets from the start (G91.1) */
		a->cu = su + b->ijk[plane_ou[p]] * scale;
		a->cv = sv + b->ijk[plane_ov[p]] * scale;
	}
	a->r0 = hypot(su - a->cu, sv - a->cv);
	a->r1 = hypot(eu - a->cu, ev - a->cv);
	if (a->r0 < 1e-9) {
		return mlip_gc_fail(e, line, col, MLIP_E_RANGE, "arc with zero radius");
	}
	if (fabs(a->r0 - a->r1) > fmax(0.002, 0.001 * a->r0)) { /* LinuxCNC's test */
		return mlip_gc_fail(e, line, col, MLIP_E_RANGE,
		                    "arc radius to start %f differs from radius to end %f mm",
		                    a->r0, a->r1);
	}
	a->a0 = atan2(sv - a->cv, su - a->cu);
	if (hypot(eu - su, ev - sv) < 1e-9) {
		sweep = 2 * PI; /* end = start with I/J/K: a full circle */
	} else {
		sweep = atan2(ev - a->cv, eu - a->cu) - a->a0;
		sweep = cw ? -sweep : sweep;
		while (sweep <= 0) {
			sweep += 2 * PI;
		}
		while (sweep > 2 * PI) {
			sweep -= 2 * PI;
		}
	}
	if (b->has_p) {
		sweep += (round(b->p) - 1) * 2 * PI; /* P turns (check_turns): P - 1 more circles */
	}
	a->sweep = cw ? -sweep : sweep;
	/* equal steps, each within the sagitta budget (header comment) */
	rmax = fmax(a->r0, a->r1);
	smax = MLIP_GCODE_ARC_FRACTION * g->tol_mm;
	step = smax >= 2 * rmax ? PI : 4 * asin(sqrt(smax / (2 * rmax)));
	step = fmin(step, PI / 2); /* some shape even on arcs smaller than the tolerance */
	if (!(step > 0) || sweep / step > MAX_CHORDS) {
		return mlip_gc_fail(e, line, col, MLIP_E_RANGE, "arc too long: more than %u chords",
		                    MAX_CHORDS);
	}
	a->n = (uint32_t)ceil(sweep / step - 1e-9);
	a->n = a->n < 1 ? 1 : a->n;
	step = sweep / a->n;
	a->sag_mm = 2 * rmax * sin(step / 4) * sin(step / 4);
	return MLIP_OK;
}

/* Chords of an arc: every point checked against the limits before any is
 * emitted (an arc may bulge past a limit its ends respect), so a rejected line
 * emits nothing. Inner corners get eps minus the chord's sagitta. */
mlip_status mlip_gc_emit_arc(struct mlip_gcode *g, struct emit_ctx *ec, const struct arc *arc,
                             const double *s, const double *t, const uint32_t *col_of,
                             struct mlip_gcode_error *e)
{
	const struct mlip_machine *m = g->m;
	double p[MLIP_MAX_AXES];
	mlip_status st;
	uint32_t k;

	for (k = 1; k < arc->n; k++) {
		arc_point(arc, s, t, m->n_axes, k, p);
		st = mlip_gc_check_limits(g, p, col_of, ec->line, 1, e);
		if (st != MLIP_OK) {
			return st;
		}
	}
	for (k = 1; k <= arc->n; k++) {
		arc_point(arc, s, t, m->n_axes, k, p);
		if (mlip_gc_emit(g, ec, p, k < arc->n ? g->tol_mm - arc->sag_mm : g->tol_mm)) {
			return MLIP_E_FULL;
		}
	}
	return MLIP_OK;
}
