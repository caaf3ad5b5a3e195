/*
 * cycle.c - the canned cycles as LinuxCNC documents them (G73, G81, G82,
 * G83, G85, G89; G98/G99; G80): a line in a cycle becomes rapids, feeds
 * and dwells along the selected plane's normal axis. In the G17 plane
 * (G18: Z X along Y; G19: Y Z along X):
 *
 *  - preliminary: below R, a rapid up to R (once, whatever L);
 *  - each of L repeats (G91: X and Y added again each time): a rapid in
 *    the plane at the current height (the first) or at the clear height,
 *    then down to R;
 *  - the cycle's own moves, ending at the clear height: R with G99, with
 *    G98 the height where the line began when that is above R.
 *
 * G90: X, Y, R, Z positions in the current coordinate system; G91: X, Y
 * increments, R from where the line began, Z from R. R, Z, Q and the dwell P
 * are sticky while the same cycle goes on. Every move ends at rest (LinuxCNC
 * runs cycles in exact-path mode). Pecks (G73, G83) back off 0.254 mm (0.010
 * inch) before the next feed, or P line units.
 */
#include <math.h>
#include <string.h>

#include "gc.h"

#define CYCLE_MOVES_MAX 1000000u /* moves of one line, as an arc's chords */
#define PECK_BACK_MM    0.254

/* The plane's axes: a, b in the plane, c its normal (config indices). */
static void plane_axes(const struct mlip_gcode *g, int *ia, int *ib, int *ic)
{
	static const char u[3] = {'X', 'Z', 'Y'}, v[3] = {'Y', 'X', 'Z'}, n[3] = {'Z', 'Y', 'X'};
	int p = g->plane - 17;
	*ia = mlip_gc_axis_index(g->m, u[p]);
	*ib = mlip_gc_axis_index(g->m, v[p]);
	*ic = mlip_gc_axis_index(g->m, n[p]);
}

static int uses_q(int cycle)
{
	return cycle == 73 || cycle == 83;
}

static int dwells(int cycle)
{
	return cycle == 82 || cycle == 89;
}

mlip_status mlip_gc_cycle_check(const struct mlip_gcode *g, const struct blk *b,
                                const struct plan *pl, uint32_t line, struct mlip_gcode_error *e)
{
	/* the same cycle named again keeps its sticky numbers (LinuxCNC: only
	 * another motion mode needs them all again) */
	int c = pl->cycle, fresh = c != g->cycle, ia, ib, ic, i;
	uint32_t col = pl->mcol;

	if (g->unknown) {
		return mlip_gc_fail(e, line, col, MLIP_E_UNSUPPORTED,
		                    "a canned cycle right after the G38 of line %u: where the "
		                    "probe stopped is known only when the program runs; move with "
		                    "G0/G1 first",
		                    g->probe_line);
	}
	plane_axes(g, &ia, &ib, &ic);
	if (ia < 0 || ib < 0 || ic < 0) {
		return mlip_gc_fail(e, line, col, MLIP_E_UNSUPPORTED,
		                    "G%u in G%u needs axes %s configured", (unsigned)c,
		                    (unsigned)g->plane,
		                    g->plane == 17   ? "X, Y and Z"
		                    : g->plane == 18 ? "Z, X and Y"
		                                     : "Y, Z and X");
	}
	for (i = 0; i < g->m->n_axes; i++) {
		int a = mlip_gc_axis_slot(mlip_upper(g->m->axis[i].letter));
		if (i != ia && i != ib && i != ic && a >= 0 && b->has_ax[a]) {
			return mlip_gc_fail(
			    e, line, b->ax_col[a], MLIP_E_SYNTAX,
			    "%c word in a canned cycle: it moves %c, %c and %c only "
			    "(LinuxCNC)",
			    mlip_upper(g->m->axis[i].letter), mlip_upper(g->m->axis[ia].letter),
			    mlip_upper(g->m->axis[ib].letter), mlip_upper(g->m->axis[ic].letter));
		}
	}
	if (b->cycle && !pl->has_axes) {
		return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX,
		                    "G%u without axis words: give the hole's position or depth",
		                    (unsigned)c);
	}
	for (i = 0; i < 3; i++) {
		if (b->has_ijk[i]) {
			return mlip_gc_fail(e, line, b->ijk_col[i], MLIP_E_SYNTAX,
			                    "%c word in a canned cycle (G%u takes none)", 'I' + i,
			                    (unsigned)c);
		}
	}
	if (b->g53) {
		return mlip_gc_fail(e, line, b->g53_col, MLIP_E_SYNTAX, "G53 needs G0 or G1");
	}
	if (b->feedmode ? b->feedmode == 93 : g->inverse_time) {
		return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX,
		                    "G%u with G93 inverse time: a canned cycle feeds in units per "
		                    "minute (G94, LinuxCNC)",
		                    (unsigned)c);
	}
	{
		int a = mlip_gc_axis_slot(mlip_upper(g->m->axis[ic].letter));
		if (fresh && !b->has_ax[a]) {
			return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX,
			                    "G%u without %c: the depth of the hole", (unsigned)c,
			                    mlip_upper(g->m->axis[ic].letter));
		}
	}
	if (fresh && !b->has_r) {
		return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX,
		                    "G%u without R: the retract height above the hole",
		                    (unsigned)c);
	}
	if (b->has_q && !uses_q(c) && !b->g64 && !b->m61) {
		return mlip_gc_fail(e, line, b->q_col, MLIP_E_SYNTAX, "Q word with G%u (no pecks)",
		                    (unsigned)c);
	}
	if (uses_q(c)) {
		if (fresh && !b->has_q) {
			return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX,
			                    "G%u without Q: the depth of each peck", (unsigned)c);
		}
		if (b->has_q && (b->g64 || b->m61)) {
			return mlip_gc_fail(
			    e, line, b->q_col, MLIP_E_SYNTAX,
			    "Q word with G%u and %s: both use Q, put them on separate "
			    "lines",
			    (unsigned)c, b->g64 ? "G64" : "M61");
		}
		if (b->has_q && !(b->q > 0)) {
			return mlip_gc_fail(e, line, b->q_col, MLIP_E_RANGE,
			                    "G%u Q%g: the peck depth must be positive", (unsigned)c,
			                    b->q);
		}
	}
	if (b->has_p && (dwells(c) || uses_q(c)) && (b->g4 || b->g10 || b->g64 || b->dout)) {
		return mlip_gc_fail(
		    e, line, b->p_col, MLIP_E_SYNTAX,
		    "P word with G%u and %s: both use P, put them on separate lines", (unsigned)c,
		    b->g4    ? "G4"
		    : b->g10 ? "G10"
		    : b->g64 ? "G64"
		             : "M64/M65");
	}
	if (b->has_p && !dwells(c) && !uses_q(c) && !(b->g4 || b->g10 || b->g64 || b->dout)) {
		return mlip_gc_fail(e, line, b->p_col, MLIP_E_SYNTAX, "P word with G%u (no dwell)",
		                    (unsigned)c);
	}
	if (dwells(c) && fresh && !b->has_p) {
		return mlip_gc_fail(e, line, col, MLIP_E_SYNTAX,
		                    "G%u without P: the dwell at the bottom, in seconds",
		                    (unsigned)c);
	}
	if (b->has_p && dwells(c) && !(b->p >= 0 && b->p <= MLIP_DWELL_MAX_S)) {
		return mlip_gc_fail(e, line, b->p_col, MLIP_E_RANGE,
		                    "G%u P%g: the dwell is 0..%g seconds", (unsigned)c, b->p,
		                    MLIP_DWELL_MAX_S);
	}
	if (b->has_p && uses_q(c) && !(b->p > 0)) {
		return mlip_gc_fail(e, line, b->p_col, MLIP_E_RANGE,
		                    "G%u P%g: the peck clearance must be positive", (unsigned)c,
		                    b->p);
	}
	if (b->has_l && !(b->l >= 1 && b->l <= CYCLE_MOVES_MAX && b->l == floor(b->l))) {
		return mlip_gc_fail(e, line, b->l_col, MLIP_E_RANGE,
		                    "G%u L%g: the repeats are a whole number, 1 or more",
		                    (unsigned)c, b->l);
	}
	return MLIP_OK;
}

/* One move of a cycle: checked (emit 0) or emitted. */
struct cyc {
	struct mlip_gcode *g;
	struct emit_ctx *ec;
	double p[MLIP_MAX_AXES];
	double feed_mm_s;
	int emit, ic;
	uint32_t moves, line, col;
	uint32_t col_of[MLIP_MAX_AXES];
	struct mlip_gcode_error *e;
};

static mlip_status go(struct cyc *k, int ia, double a, int ib, double b, double c, int rapid)
{
	if (ia >= 0) {
		k->p[ia] = a;
		k->p[ib] = b;
	}
	k->p[k->ic] = c;
	if (++k->moves > CYCLE_MOVES_MAX) {
		return mlip_gc_fail(k->e, k->line, k->col, MLIP_E_RANGE,
		                    "canned cycle too long: more than %u moves on one line",
		                    CYCLE_MOVES_MAX);
	}
	if (!k->emit) {
		return mlip_gc_check_limits(k->g, k->p, k->col_of, k->line, 0, k->e);
	}
	k->ec->rapid = (uint8_t)rapid;
	k->ec->feed_mm_s = rapid ? k->g->m->max_feed_mm_s : k->feed_mm_s;
	return mlip_gc_emit(k->g, k->ec, k->p, k->g->tol_mm) != 0 ? MLIP_E_FULL : MLIP_OK;
}

static mlip_status dwell(struct cyc *k, double s)
{
	if (!k->emit) {
		return MLIP_OK;
	}
	if (mlip_gc_flush_dwell(k->g, k->ec) != 0 ||
	    mlip_gc_emit_event(k->g, k->ec->sink, k->ec->ctx, k->line, MLIP_BLOCK_DWELL, s) != 0) {
		return MLIP_E_FULL;
	}
	return MLIP_OK;
}

#define GO(...)                                                                                    \
	do {                                                                                       \
		st = go(__VA_ARGS__);                                                              \
		if (st != MLIP_OK) {                                                               \
			return st;                                                                 \
		}                                                                                  \
	} while (0)

/* The line's moves (one pass: checked, or emitted). */
static mlip_status run(struct cyc *k, int c, int ia, int ib, double a0, double b0, double da,
                       double db, double r, double bottom, double q, double back, double p_s,
                       uint32_t reps)
{
	mlip_status st;
	double cur = k->p[k->ic];
	double a = a0, b = b0;
	if (cur < r) {
		GO(k, -1, 0, -1, 0, r, 1); /* preliminary: up to R */
		cur = r;
	}
	double clear = k->g->retract_r ? r : cur;
	for (uint32_t n = 0; n < reps; n++) {
		a += da;
		b += db;
		double at = n == 0 ? cur : clear;
		GO(k, ia, a, ib, b, at, 1);
		if (at > r) {
			GO(k, ia, a, ib, b, r, 1);
		}
		if (uses_q(c)) {
			for (double d = r - q; d > bottom; d -= q) {
				GO(k, ia, a, ib, b, d, 0);
				if (c == 83) {
					GO(k, ia, a, ib, b, r, 1); /* out to R: the chips */
				}
				GO(k, ia, a, ib, b, d + back, 1);
			}
		}
		GO(k, ia, a, ib, b, bottom, 0);
		if (dwells(c)) {
			st = dwell(k, p_s);
			if (st != MLIP_OK) {
				return st;
			}
		}
		if (c == 85) {
			GO(k, ia, a, ib, b, r, 0); /* fed out to R, then a rapid */
			if (clear > r) {
				GO(k, ia, a, ib, b, clear, 1);
			}
		} else {
			GO(k, ia, a, ib, b, clear, c != 89);
		}
	}
	return MLIP_OK;
}

mlip_status mlip_gc_cycle(struct mlip_gcode *g, const struct blk *b, const struct plan *pl,
                          struct emit_ctx *ec, double scale, uint32_t line,
                          struct mlip_gcode_error *e)
{
	const struct mlip_machine *m = g->m;
	int c = pl->cycle, ia, ib, ic, sa, sb, sc;
	plane_axes(g, &ia, &ib, &ic);
	sa = mlip_gc_axis_slot(mlip_upper(m->axis[ia].letter));
	sb = mlip_gc_axis_slot(mlip_upper(m->axis[ib].letter));
	sc = mlip_gc_axis_slot(mlip_upper(m->axis[ic].letter));
	/* the sticky numbers, as written (this line's units) */
	double zw = b->has_ax[sc] ? b->ax[sc] : g->cyc_z;
	double rw = b->has_r ? b->r : g->cyc_r;
	double qw = b->has_q ? b->q : g->cyc_q;
	double pw = b->has_p && dwells(c) ? b->p : g->cyc_p;
	double back = b->has_p && uses_q(c) ? b->p * scale : PECK_BACK_MM;
	uint32_t reps = b->has_l ? (uint32_t)b->l : 1u;
	double cur = g->cur[ic], a0 = g->cur[ia], b0 = g->cur[ib], da = 0, db = 0, r, bottom;
	(void)cur;
	if (g->absolute) {
		r = rw * scale + mlip_gc_offset_of(g, ic);
		bottom = zw * scale + mlip_gc_offset_of(g, ic);
		/* L > 1 in G90: the same hole again (LinuxCNC) */
		a0 = b->has_ax[sa] ? b->ax[sa] * scale + mlip_gc_offset_of(g, ia) : a0;
		b0 = b->has_ax[sb] ? b->ax[sb] * scale + mlip_gc_offset_of(g, ib) : b0;
	} else {
		r = cur + rw * scale;
		bottom = r + zw * scale;
		da = b->has_ax[sa] ? b->ax[sa] * scale : 0;
		db = b->has_ax[sb] ? b->ax[sb] * scale : 0;
	}
	if (r < bottom) {
		return mlip_gc_fail(
		    e, line, b->has_r ? b->r_col : pl->mcol, MLIP_E_RANGE,
		    "G%u: R (%g) below the hole's bottom %c (%g): R must be above it", (unsigned)c,
		    rw, mlip_upper(m->axis[ic].letter), zw);
	}
	if (uses_q(c) && (r - bottom) / (qw * scale) > CYCLE_MOVES_MAX) {
		return mlip_gc_fail(e, line, b->has_q ? b->q_col : pl->mcol, MLIP_E_RANGE,
		                    "G%u Q%g: more than %u pecks for the hole", (unsigned)c, qw,
		                    CYCLE_MOVES_MAX);
	}
	struct cyc k = {.g = g, .ec = ec, .ic = ic, .line = line, .col = pl->mcol, .e = e};
	memcpy(k.p, g->cur, sizeof(k.p));
	for (int i = 0; i < m->n_axes; i++) {
		int s = mlip_gc_axis_slot(mlip_upper(m->axis[i].letter));
		k.col_of[i] = s >= 0 && b->has_ax[s] ? b->ax_col[s] : pl->mcol;
	}
	/* the feed moves' F (the normal axis alone), checked on the longest,
	 * from R to the bottom */
	double s[MLIP_MAX_AXES], t[MLIP_MAX_AXES];
	memcpy(s, g->cur, sizeof(s));
	memcpy(t, g->cur, sizeof(t));
	s[ic] = r;
	t[ic] = bottom;
	struct plan fp = *pl;
	fp.motion = 1;
	mlip_status st = mlip_gc_block_feed(g, &fp, s, t, line, &k.feed_mm_s, e);
	if (st == MLIP_OK) {
		st = mlip_gc_move_feed(g, b, &fp, s, t, NULL, line, &k.feed_mm_s, e);
	}
	if (st != MLIP_OK) {
		return st;
	}
	double qmm = qw * scale;
	/* every point checked first: a refused line emits nothing */
	st = run(&k, c, ia, ib, a0, b0, da, db, r, bottom, qmm, back, pw, reps);
	if (st != MLIP_OK) {
		return st;
	}
	memcpy(k.p, g->cur, sizeof(k.p));
	k.moves = 0;
	k.emit = 1;
	int exact = g->exact_stop;
	g->exact_stop = 1; /* LinuxCNC runs a cycle in exact-path mode */
	st = run(&k, c, ia, ib, a0, b0, da, db, r, bottom, qmm, back, pw, reps);
	g->exact_stop = exact;
	if (st != MLIP_OK) {
		return st;
	}
	memcpy(g->cur, k.p, sizeof(g->cur)); /* the line's dwell, if no move took it: its caller */
	g->cyc_z = zw;
	g->cyc_r = rw;
	g->cyc_q = qw;
	g->cyc_p = pw;
	g->unknown = 0;
	return MLIP_OK;
}
