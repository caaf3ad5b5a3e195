/*
 * gcode.c - G-code front end: one line of RS274NGC text in, joint-space
 * G01-style blocks out (see mlip/gcode/gcode.h for what is supported).
 *
 * A line goes through four steps, so that a line with an error changes
 * nothing but what it validly said:
 *   1. lex:      bytes -> words (letter, number, column); comments skipped,
 *                malformed numbers, stray bytes and bad UTF-8 rejected
 *                (lex.c);
 *   2. classify: words -> one block description (G/M codes by modal group,
 *                axis and arc words, F, notices), every word checked alone
 *                (words.c);
 *   3. check:    words against the machine and the modal state (here);
 *   4. execute:  modal state committed (modal.c), offsets (offsets.c), then
 *                the motion (if any) turned into targets, checked against
 *                the soft limits, and emitted (emit.c, arc.c).
 *
 * Pure: libm, <string.h> and <stdarg.h> only; messages formatted by the
 * core's formatter (mlip/text/format.h).
 */
#include <math.h>
#include <string.h>

#include "gc.h"

/* G38.x's words: a probe input, axis words and nothing else that moves or
 * uses them, a feed per minute (LinuxCNC's rules for G38). */
static mlip_status check_probe(const struct mlip_gcode *g, const struct blk *b, int has_axes,
                               uint32_t line, struct mlip_gcode_error *e)
{
	unsigned sub = (unsigned)(b->probe % 10);

	if (g->io == NULL) {
		return mlip_gc_fail(e, line, b->motion_col, MLIP_E_UNSUPPORTED,
		                    "G38.%u: probing needs the machine's config (--config) with a "
		                    "probe input ([IO] PROBE)",
		                    sub);
	}
	if (!g->io->probe) {
		return mlip_gc_fail(e, line, b->motion_col, MLIP_E_UNSUPPORTED,
		                    "G38.%u: this machine has no probe input ([IO] PROBE)", sub);
	}
	if (!has_axes) {
		return mlip_gc_fail(e, line, b->motion_col, MLIP_E_SYNTAX,
		                    "G38.%u without axis words: give the point to probe toward, "
		                    "e.g. G38.%u Z-10 F100",
		                    sub, sub);
	}
	if (b->home || b->g10 || b->g92 == 920 || b->g43 == 431 || b->g53) {
		return mlip_gc_fail(e, line, b->motion_col, MLIP_E_SYNTAX,
		                    "G38.%u with %G on one line: put them on separate lines", sub,
		                    b->home         ? b->home * 10
		                    : b->g10        ? 100
		                    : b->g53        ? 530
		                    : b->g43 == 431 ? 431
		                                    : 920);
	}
	if (b->feedmode == 93 || (!b->feedmode && g->inverse_time)) {
		return mlip_gc_fail(e, line, b->motion_col, MLIP_E_SYNTAX,
		                    "G38.%u in inverse time (G93): probe with a feed per minute "
		                    "(G94)",
		                    sub);
	}
	return MLIP_OK;
}

/* After a G38 the probed axes stand where the probe stopped them, known
 * only when the program runs (the feeder checks it whole before): a line
 * that would use that position is refused. A move (or a probe) must give
 * every such axis in absolute coordinates (G90 or G53): its target is then
 * known, and the straight line to it from anywhere on the probe's path
 * stays inside the soft limits (a box). Arcs, G28/G30, G10 L20, G92 and a
 * tool change's moves on such an axis are refused. */
static mlip_status check_unknown(const struct mlip_gcode *g, const struct blk *b,
                                 const struct plan *pl, uint32_t first_col, uint32_t line,
                                 struct mlip_gcode_error *e)
{
	const struct mlip_machine *m = g->m;
	int i, a;

	for (i = 0; i < m->n_axes; i++) {
		char L = mlip_upper(m->axis[i].letter);
		uint32_t col;
		if (!(g->unknown >> i & 1u)) {
			continue;
		}
		a = mlip_gc_axis_slot(L);
		col = b->has_ax[a] ? b->ax_col[a] : 0;
		if (b->has_ax[a] && (b->g10 || b->g92 == 920)) {
			return mlip_gc_fail(
			    e, line, col, MLIP_E_UNSUPPORTED,
			    "%s %c after the G38 of line %u: where the probe stopped "
			    "%c is known only when the program runs; touch off by "
			    "MDI after the probe",
			    b->g10 ? "G10" : "G92", L, g->probe_line, L);
		}
		if ((pl->moves || pl->probe) && (!b->has_ax[a] || (!g->absolute && !b->g53))) {
			return mlip_gc_fail(e, line,
			                    col        ? col
			                    : pl->mcol ? pl->mcol
			                               : first_col,
			                    MLIP_E_UNSUPPORTED,
			                    "after the G38 of line %u this move must give %c in "
			                    "absolute coordinates (G90 or G53): where the probe "
			                    "stopped %c is known only when the program runs",
			                    g->probe_line, L, L);
		}
	}
	if (pl->moves && pl->motion >= 2) {
		return mlip_gc_fail(e, line, pl->mcol, MLIP_E_UNSUPPORTED,
		                    "an arc right after the G38 of line %u: its start is known "
		                    "only when the program runs; move with G0/G1 first",
		                    g->probe_line);
	}
	if (b->home || (b->m6 && g->io != NULL && g->io->change_mask != 0)) {
		return mlip_gc_fail(e, line, b->home ? b->home_col : b->m6_col, MLIP_E_UNSUPPORTED,
		                    "%s right after the G38 of line %u: the path from where the "
		                    "probe stopped is known only when the program runs; move "
		                    "with G0/G1 first",
		                    b->home == 28 ? "G28"
		                    : b->home     ? "G30"
		                                  : "M6",
		                    g->probe_line);
	}
	return MLIP_OK;
}

/* P without G4, G10, G64 or M64/M65 is an arc's number of turns (LinuxCNC:
 * the programmed arc plus P - 1 full circles, P a whole number from 1);
 * with one of them on an arc's line both would take it. */
static mlip_status check_turns(const struct blk *b, const struct plan *pl, uint32_t line,
                               struct mlip_gcode_error *e)
{
	int other = b->g4 || b->g10 || b->g64 || b->dout, arc = pl->moves && pl->motion >= 2;
	if (!b->has_p || (other && !arc)) {
		return MLIP_OK;
	}
	if (!arc) {
		return mlip_gc_fail(e, line, b->p_col, MLIP_E_SYNTAX,
		                    "P word without G2/G3, G4, G10, G64 or M64/M65");
	}
	if (other) {
		return mlip_gc_fail(
		    e, line, b->p_col, MLIP_E_SYNTAX,
		    "P word with G%u and %s: both use P, put them on separate lines",
		    (unsigned)pl->motion,
		    b->g4    ? "G4"
		    : b->g10 ? "G10"
		    : b->g64 ? "G64"
		             : "M64/M65");
	}
	if (!(fabs(b->p - round(b->p)) <= 0.001 && b->p >= 0.5 && b->p <= MAX_TURNS)) {
		return mlip_gc_fail(e, line, b->p_col, MLIP_E_RANGE,
		                    "G%u P%g: the number of turns is a whole number, 1..%u",
		                    (unsigned)pl->motion, b->p, MAX_TURNS);
	}
	return MLIP_OK;
}

/* Words against the machine and the modal state. */
static mlip_status check_line(const struct mlip_gcode *g, const struct blk *b,
                              const struct lexed *lx, uint32_t line, struct plan *pl,
                              struct mlip_gcode_error *e)
{
	uint32_t first_ax = 0, c;
	int a, i, has_axes = 0, arc_words, inverse;
	char L = 'R';
	mlip_status st;

	for (a = 0; a < 6; a++) {
		if (!b->has_ax[a]) {
			continue;
		}
		if (mlip_gc_axis_index(g->m, GC_AXES[a]) < 0) {
			return mlip_gc_fail(e, line, b->ax_col[a], MLIP_E_UNSUPPORTED,
			                    "axis %c not configured", GC_AXES[a]);
		}
		has_axes = 1;
		first_ax = !first_ax || b->ax_col[a] < first_ax ? b->ax_col[a] : first_ax;
	}
	pl->has_axes = has_axes;
	pl->axis_use = b->home || b->g10 || b->g92 == 920 || b->g43 == 431;
	pl->g0_default = 0;
	if (pl->axis_use && (b->motion >= 0 || b->cycle) && has_axes) {
		return mlip_gc_fail(e, line, b->motion_col, MLIP_E_SYNTAX,
		                    "%G and %G on one line: both use axis words",
		                    b->home         ? b->home * 10
		                    : b->g10        ? 100
		                    : b->g43 == 431 ? 431
		                                    : 920,
		                    b->cycle ? b->cycle * 10 : b->motion * 10);
	}
	if (b->g43 == 431 && (b->home || b->g10 || b->g92 == 920)) {
		return mlip_gc_fail(e, line, b->g43_col, MLIP_E_SYNTAX,
		                    "G43.1 and %G on one line: both use axis words",
		                    b->home  ? b->home * 10
		                    : b->g10 ? 100
		                             : 920);
	}
	if (b->homeset && has_axes) {
		return mlip_gc_fail(e, line, first_ax, MLIP_E_SYNTAX,
		                    "%G takes no axis words: it stores the current position",
		                    b->homeset * 10 + 1);
	}
	if (b->g92 > 920 && has_axes) {
		return mlip_gc_fail(e, line, first_ax, MLIP_E_SYNTAX, "%G takes no axis words",
		                    b->g92);
	}
	if (b->g92 == 920 && !has_axes) {
		return mlip_gc_fail(
		    e, line, b->g92_col, MLIP_E_SYNTAX,
		    "G92 without axis words: give the coordinates the current point "
		    "gets, e.g. G92 X0 Y0");
	}
	pl->motion = b->motion >= 0 ? b->motion : g->motion;
	pl->mcol = b->motion >= 0 ? b->motion_col : lx->first_col;
	pl->probe = b->probe;
	if (b->probe) {
		st = check_probe(g, b, has_axes, line, e);
		if (st != MLIP_OK) {
			return st;
		}
		pl->motion = 1; /* a feed move toward the target */
		pl->mcol = b->motion_col;
	} else if (b->motion < 0 && g->probe_mode && has_axes && !pl->axis_use) {
		/* LinuxCNC would probe again: say it on the line instead */
		return mlip_gc_fail(e, line, first_ax, MLIP_E_SYNTAX,
		                    "axis words after G38.%u with no motion code: write G0/G1 "
		                    "to move, or G38.%u again to probe again",
		                    (unsigned)(g->probe_mode % 10), (unsigned)(g->probe_mode % 10));
	}
	/* a canned cycle: named on the line, or the one in effect on a line
	 * with axis words and no other motion code (LinuxCNC) */
	pl->cycle = b->cycle                                                             ? b->cycle
	            : b->motion < 0 && !b->g80 && !b->probe && has_axes && !pl->axis_use ? g->cycle
	                                                                                 : 0;
	if (pl->cycle) {
		pl->motion = -1;
		pl->mcol = b->cycle ? b->motion_col : lx->first_col;
		return mlip_gc_cycle_check(g, b, pl, line, e);
	}
	if (b->g80 && has_axes && !pl->axis_use) {
		return mlip_gc_fail(e, line, first_ax, MLIP_E_SYNTAX,
		                    "axis words with G80: it cancels the canned cycle and moves "
		                    "nothing (LinuxCNC)");
	}
	arc_words = b->has_ijk[0] || b->has_ijk[1] || b->has_ijk[2] || (b->has_r && !b->g10);
	if (arc_words && (pl->motion < 2 || pl->axis_use)) {
		c = b->has_r ? b->r_col : 0;
		for (i = 0; i < 3; i++) {
			if (b->has_ijk[i] && (!c || b->ijk_col[i] < c)) {
				c = b->ijk_col[i];
				L = (char)('I' + i);
			}
		}
		return mlip_gc_fail(e, line, c, MLIP_E_SYNTAX, "%c word without an arc (G2/G3)", L);
	}
	if (has_axes && !pl->axis_use && pl->motion < 0 && g->cycle_off) {
		return mlip_gc_fail(e, line, first_ax, MLIP_E_SYNTAX,
		                    "axis words with no motion code after a canned cycle ended "
		                    "(G80, or the end of its MDI line): write G0, G1 or the cycle "
		                    "again");
	}
	if (has_axes && !pl->axis_use && pl->motion < 0) {
		if (g->strict) {
			return mlip_gc_fail(
			    e, line, first_ax, MLIP_E_SYNTAX,
			    "axis words with no motion mode: program G0, G1, G2 or G3 first");
		}
		pl->motion = 0; /* Grbl starts in G0 */
		pl->g0_default = 1;
	}
	if (b->g53 && b->dist != 90 && !g->absolute) {
		/* LinuxCNC: NCE_CANNOT_USE_G53_INCREMENTAL, G91 modal as on the line */
		return mlip_gc_fail(e, line, b->g53_col, MLIP_E_SYNTAX,
		                    "G53 with G91 in effect: machine coordinates must be absolute "
		                    "(G90 first, or G90 G53 on this line)");
	}
	if (b->g53 && pl->motion >= 2 && (has_axes || arc_words)) {
		return mlip_gc_fail(e, line, b->g53_col, MLIP_E_SYNTAX, "G53 needs G0 or G1");
	}
	pl->moves = !pl->axis_use && (has_axes || arc_words);
	if (b->has_q && !b->g64 && !b->m61) {
		return mlip_gc_fail(e, line, b->q_col, MLIP_E_SYNTAX,
		                    "Q word without G64, G73, G83 or M61");
	}
	if (b->has_l && !b->g10) {
		return mlip_gc_fail(e, line, b->l_col, MLIP_E_SYNTAX,
		                    "L word without G10 or a canned cycle");
	}
	st = check_turns(b, pl, line, e);
	if (st != MLIP_OK) {
		return st;
	}
	inverse = b->feedmode ? b->feedmode == 93 : g->inverse_time;
	if (inverse && pl->moves && pl->motion >= 1 && !b->has_f) {
		return mlip_gc_fail(
		    e, line, pl->mcol, MLIP_E_SYNTAX,
		    "G93 inverse time: every feed move needs its own F (the move takes "
		    "1/F minutes)");
	}
	return MLIP_OK;
}

/* Modal state, committed before the motion so that an error in the motion
 * does not cascade into every following line. F is kept both as written (for
 * rotary-only moves) and in mm/s, converted with the units of its own line.
 * In G93 an F belongs to its line only; a change of feed mode forgets F
 * (LinuxCNC). */

static size_t first_byte(const char *text, size_t len, uint32_t lineno)
{
	const unsigned char *t = (const unsigned char *)text;
	size_t i = 0;

	if (lineno == 1 && len >= 3 && t[0] == 0xEF && t[1] == 0xBB && t[2] == 0xBF) {
		i = 3;
	}
	while (i < len && mlip_is_blank(t[i])) {
		i++;
	}
	return i;
}

mlip_status mlip_gcode_line(struct mlip_gcode *g, const char *text, size_t len, uint32_t lineno,
                            mlip_block_sink sink, void *ctx, struct mlip_gcode_error *err)
{
	const struct mlip_machine *m = g->m;
	struct mlip_gcode_error dummy;
	struct lexed lx;
	struct blk b;
	struct plan pl = {-1, 0, 0, 0, 0, 0, 0, 0};
	struct emit_ctx ec;
	struct arc arc;
	double start[MLIP_MAX_AXES], t[MLIP_MAX_AXES], scale, k;
	uint32_t col_of[MLIP_MAX_AXES];
	size_t i0;
	int i, a;
	mlip_status st;

	if (!err) {
		err = &dummy;
	}
	if (m->n_axes < 1 || m->n_axes > MLIP_MAX_AXES) {
		return mlip_gc_fail(err, lineno, 0, MLIP_E_INVALID,
		                    "machine has no valid axis count");
	}
	/* checked before any byte is read: a caller may pass the length of a
	 * line it did not keep whole */
	if (len > MLIP_GCODE_MAX_LINE + 1 ||
	    (len == MLIP_GCODE_MAX_LINE + 1 && text[len - 1] != '\r')) {
		return mlip_gc_fail(err, lineno, MLIP_GCODE_MAX_LINE + 1, MLIP_E_SYNTAX,
		                    "line too long: %u bytes, at most %u",
		                    (unsigned)(len > 999999 ? 999999 : len), MLIP_GCODE_MAX_LINE);
	}
	if (len > 0 && text[len - 1] == '\r') {
		len--; /* CRLF line ends */
	}
	if (g->ended) {
		return MLIP_OK; /* after M2/M30: LinuxCNC reads no further */
	}
	i0 = first_byte(text, len, lineno);
	if (i0 < len && text[i0] == '$') {
		return mlip_gc_system_line(g, text, len, i0, lineno, sink, ctx, err);
	}
	if (i0 < len && (text[i0] == '?' || text[i0] == '~' || text[i0] == '!') &&
	    first_byte(text + i0 + 1, len - i0 - 1, 0) == len - i0 - 1) {
		/* Grbl's real-time commands, alone on a line: status, cycle
		 * start, feed hold (a sender's, never a program's) */
		if (g->strict) {
			return mlip_gc_fail(
			    err, lineno, (uint32_t)i0 + 1, MLIP_E_UNSUPPORTED,
			    "Grbl real-time command '%c' is not G-code (strict mode): delete "
			    "it",
			    text[i0]);
		}
		mlip_gc_notice(g, text[i0] == '?' ? "?" : text[i0] == '~' ? "~" : "!", lineno);
		return MLIP_OK;
	}
	if (i0 < len && mlip_upper(text[i0]) == 'O' && i0 + 1 < len &&
	    (mlip_is_digit(text[i0 + 1]) || text[i0 + 1] == '<')) {
		return mlip_gc_fail(
		    err, lineno, (uint32_t)i0 + 1, MLIP_E_UNSUPPORTED,
		    "O-words (subroutines, loops, conditions) not supported: have the CAM "
		    "expand them");
	}
	if (i0 < len && text[i0] == '/') {
		mlip_gc_notice(g, "/", lineno);
		return MLIP_OK;
	}
	g->broken_rule = 0;
	st = mlip_gc_lex_line(g, text, len, lineno, &lx, err);
	if (st == MLIP_OK) {
		/* every value of the line is read: its settings take effect */
		st = mlip_gc_apply_settings(g, &lx, lineno, err);
	}
	if (st == MLIP_OK && lx.percent) {
		/* LinuxCNC: a '%' before anything else opens the program; the
		 * next one closes it, and what follows is not read */
		if (g->content) {
			g->ended = 1;
			mlip_gc_notice(g, "%", lineno);
		} else {
			g->percent = 1;
			g->content = 1;
		}
		return MLIP_OK;
	}
	if (st == MLIP_OK && lx.n > 0) {
		g->content = 1;
	}
	if (st == MLIP_OK) {
		st = mlip_gc_classify(&lx, lineno, &b, err);
	}
	if (st == MLIP_OK) {
		st = check_line(g, &b, &lx, lineno, &pl, err);
	}
	if (st == MLIP_OK) {
		st = mlip_gc_check_io(g, &b, lineno, err);
	}
	if (st != MLIP_OK) {
		return st;
	}
	/* LinuxCNC's order of execution: dwell, modes, offsets, motion, stop;
	 * the dwell is emitted with the motion, once that is known good */
	mlip_gc_commit_modal(g, &b, &pl, lineno);
	scale = g->inches ? MM_PER_INCH : 1.0;
	/* S, T, M6, M3/M4/M5, M7/M8/M9 (events queued in ec, emitted with the
	 * dwell once the line is known good), G43/G49 (io.c) */
	ec.sink = sink;
	ec.ctx = ctx;
	ec.line = lineno;
	ec.n_io = 0;
	mlip_gc_exec_io(g, &b, scale, &ec);
	mlip_gc_set_offsets(g, &b, scale);

	/* target: absolute machine coordinates, config order, machine units
	 * (rotary axes: degrees) */
	for (i = 0; i < m->n_axes; i++) {
		a = mlip_gc_axis_slot(mlip_upper(m->axis[i].letter));
		start[i] = t[i] = g->cur[i];
		col_of[i] = pl.motion >= 2 ? pl.mcol : lx.first_col; /* arcs move wordless axes */
		if (a >= 0 && b.has_ax[a] && !b.g10 && b.g92 != 920 && b.g43 != 431) {
			k = m->axis[i].kind == MLIP_AXIS_ROTARY ? 1.0 : scale;
			t[i] = b.g53         ? b.ax[a] * k
			       : g->absolute ? b.ax[a] * k + mlip_gc_offset_of(g, i)
			                     : g->cur[i] + b.ax[a] * k;
			col_of[i] = b.ax_col[a];
		}
	}
	ec.sink = sink;
	ec.ctx = ctx;
	ec.line = lineno;
	ec.rapid = pl.motion == 0;
	ec.feed_mm_s = m->max_feed_mm_s; /* rapids: informative, the planner ignores it */
	ec.dwell_pending = b.g4;
	ec.dwell_s = b.p;
	st = g->unknown ? check_unknown(g, &b, &pl, lx.first_col, lineno, err) : MLIP_OK;
	if (st != MLIP_OK) {
		/* the modes and offsets of the line are committed: as any motion error */
	} else if (b.home) {
		st = mlip_gc_go_home(g, &b, &pl, &ec, t, col_of, lineno, err);
	} else if (pl.probe) {
		st = mlip_gc_probe(g, &b, &pl, &ec, start, t, col_of, lineno, err);
	} else if (pl.cycle) {
		st = mlip_gc_cycle(g, &b, &pl, &ec, scale, lineno, err);
	} else if (pl.moves) {
		st = pl.motion > 0 && !g->inverse_time
		         ? mlip_gc_block_feed(g, &pl, start, t, lineno, &ec.feed_mm_s, err)
		         : MLIP_OK;
		if (st == MLIP_OK) {
			st = mlip_gc_check_limits(g, t, col_of, lineno, 0, err);
		}
		if (st == MLIP_OK && pl.motion >= 2) {
			st = mlip_gc_arc_setup(g, &b, pl.motion, scale, start, t, lineno, pl.mcol,
			                       &arc, err);
		}
		if (st == MLIP_OK && pl.motion >= 1) {
			/* the feed (G93: from the move's length) against the rule set */
			st = mlip_gc_move_feed(g, &b, &pl, start, t, pl.motion >= 2 ? &arc : NULL,
			                       lineno, &ec.feed_mm_s, err);
		}
		if (st == MLIP_OK && pl.motion >= 2) {
			st = mlip_gc_emit_arc(g, &ec, &arc, start, t, col_of, err);
		} else if (st == MLIP_OK) {
			if (mlip_gc_emit(g, &ec, t, g->tol_mm) != 0) {
				st = MLIP_E_FULL;
			}
		}
		if (st == MLIP_OK) {
			memcpy(g->cur, t, sizeof g->cur);
			g->unknown = 0; /* every axis given absolutely (check_unknown) */
		}
	}
	if (st == MLIP_OK && (b.motion >= 0 || b.cycle)) {
		g->probe_mode = 0;
	}
	if (st == MLIP_OK && mlip_gc_flush_dwell(g, &ec) != 0) {
		st = MLIP_E_FULL;
	}
	if (st == MLIP_OK && b.pause &&
	    mlip_gc_emit_event(g, sink, ctx, lineno,
	                       b.pause == 2 ? MLIP_BLOCK_OPTIONAL_PAUSE : MLIP_BLOCK_PAUSE,
	                       0) != 0) {
		st = MLIP_E_FULL;
	}
	if (st == MLIP_E_FULL) {
		for (i = 0; i < m->n_axes; i++) {
			g->cur[i] = g->pos[i]; /* resume from what the sink holds */
		}
		if (g->broken_rule) {
			/* the line's own checks keep the rule set: never reached */
			return mlip_gc_fail(
			    err, lineno, lx.first_col, MLIP_E_RANGE,
			    "a block of this line breaks the rule set of every block "
			    "(rule %u, mlip_block_check)",
			    (unsigned)g->broken_rule);
		}
		return mlip_gc_fail(err, lineno, 0, MLIP_E_FULL,
		                    "block sink full: parsing stopped");
	}
	if (st == MLIP_OK && b.end && mlip_gc_end_io(g, sink, ctx, lineno) != MLIP_OK) {
		return mlip_gc_fail(err, lineno, 0, MLIP_E_FULL,
		                    "block sink full: parsing stopped");
	}
	if (b.end) {
		/* M2/M30 (LinuxCNC): G54 selected, G92 offsets off, values kept;
		 * the spindle and the coolant stopped (above) */
		g->ended = 1;
		g->off.select = 0;
		g->off.g92_on = 0;
		g->cycle = 0; /* a canned cycle ends with its program */
		g->cycle_off = 0;
	}
	return st;
}

/* Compared value by value: the structs hold padding. */
int mlip_gcode_offsets_changed(const struct mlip_gcode *g)
{
	const struct mlip_gcode_offsets *a = &g->off_start, *b = &g->off;
	int diff = a->g92_on != b->g92_on || a->select != b->select || a->tool != b->tool;

	for (int i = 0; i < MLIP_MAX_AXES; i++) {
		diff |= a->g92[i] != b->g92[i] || a->g28[i] != b->g28[i] || a->g30[i] != b->g30[i];
		for (int k = 0; k < MLIP_GCODE_N_COORD; k++) {
			diff |= a->coord[k][i] != b->coord[k][i];
		}
	}
	return diff;
}

mlip_status mlip_gcode_finish(struct mlip_gcode *g, uint32_t last_line,
                              struct mlip_gcode_error *err)
{
	struct mlip_gcode_error dummy;

	if (g->moves == 0 && !g->mdi && !mlip_gcode_offsets_changed(g)) {
		return mlip_gc_fail(err ? err : &dummy, last_line ? last_line : 1, 0, MLIP_E_SYNTAX,
		                    "empty program: no motion");
	}
	if (g->percent && !g->ended) {
		return mlip_gc_fail(
		    err ? err : &dummy, last_line ? last_line : 1, 0, MLIP_E_SYNTAX,
		    "the program opens with '%%' but ends without the closing "
		    "'%%' or M2/M30: the file may be cut short (LinuxCNC refuses it)");
	}
	return MLIP_OK;
}
