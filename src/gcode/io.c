/*
 * io.c - the machine's I/O words (issue 19): S, M3/M4/M5, T, M6, M61,
 * G43 / G43.1 / G49 and M7/M8/M9, checked against what the machine has
 * (mlip_gcode_set_io) and executed in LinuxCNC's order of execution: S,
 * T, M6/M61, M3/M4/M5, M7/M8/M9 (then the dwell, the modes), G43/G49.
 * What the machine must do leaves as an event block at the last point.
 */
#include <math.h>
#include <string.h>

#include "gc.h"

static const char IGN_SPINDLE[] = "ignored on purpose (--ignore-spindle): no spindle is driven";
static const char IGN_COOLANT[] = "ignored on purpose (--ignore-coolant): no coolant is switched";
static const char IGN_TOOLS[] = "ignored on purpose (--ignore-tools): no tool change, no length "
                                "offset (the tool in the spindle cuts)";
static const char SAME_TOOL[] = "asked for the tool already in the spindle: no change";
static const char NO_SPINDLE_M5[] = "the machine has no spindle: nothing to stop";

int mlip_gc_z_index(const struct mlip_machine *m)
{
	return mlip_gc_axis_index(m, 'Z');
}

const struct mlip_tool *mlip_gcode_find_tool(const struct mlip_gcode_io *io, int32_t n)
{
	uint32_t lo = 0, hi;

	if (io == NULL || io->tools == NULL) {
		return NULL;
	}
	hi = io->n_tools;
	while (lo < hi) { /* sorted by number */
		uint32_t mid = lo + (hi - lo) / 2;
		if (io->tools[mid].number == n) {
			return &io->tools[mid];
		}
		if (io->tools[mid].number < n) {
			lo = mid + 1;
		} else {
			hi = mid;
		}
	}
	return NULL;
}

/* A tool number as written: a whole number 0..2^31-1. */
static int tool_number(double v, int32_t *n)
{
	if (!(v >= 0 && v <= 2147483647.0) || v != floor(v)) {
		return -1;
	}
	*n = (int32_t)v;
	return 0;
}

/* The word letter c (T, H, Q) names tool v: a whole number, 0 or in the table. */
static mlip_status check_tool(const struct mlip_gcode *g, char c, double v, uint32_t line,
                              uint32_t col, struct mlip_gcode_error *e)
{
	int32_t n;

	if (tool_number(v, &n) != 0) {
		return mlip_gc_fail(e, line, col, MLIP_E_RANGE,
		                    "%c%g: a tool is a whole number >= 0 (0: no tool)", c, v);
	}
	if (n > 0 && mlip_gcode_find_tool(g->io, n) == NULL) {
		return mlip_gc_fail(e, line, col, MLIP_E_RANGE,
		                    g->io->tools == NULL
		                        ? "%c%u: no tool table given (--tools FILE)"
		                        : "%c%u: tool %u is not in the tool table",
		                    c, (unsigned)n, (unsigned)n);
	}
	return MLIP_OK;
}

/* The tool in the spindle once the line's M6 / M61 is done. */
static int32_t tool_after(const struct mlip_gcode *g, const struct blk *b)
{
	int32_t n = g->off.tool;

	if (b->m6) {
		if (b->has_t) {
			(void)tool_number(b->t, &n);
		} else {
			n = g->tool_sel;
		}
	} else if (b->m61) {
		(void)tool_number(b->q, &n);
	}
	return n;
}

static mlip_status check_spindle(const struct mlip_gcode *g, const struct blk *b, uint32_t line,
                                 struct mlip_gcode_error *e)
{
	const struct mlip_gcode_io *io = g->io;

	if (b->has_s && !(b->s >= 0)) {
		return mlip_gc_fail(e, line, b->s_col, MLIP_E_RANGE, "S must be >= 0 (rpm), got %g",
		                    b->s);
	}
	if (io->ignore_spindle) {
		return MLIP_OK;
	}
	if (io->spindle == MLIP_IO_NONE && (b->has_s || b->spindle_m == 3 || b->spindle_m == 4)) {
		return mlip_gc_fail(
		    e, line, b->has_s ? b->s_col : b->spindle_col, MLIP_E_UNSUPPORTED,
		    "%s: this machine has no spindle ([SPINDLE] TYPE = none); --ignore-spindle "
		    "runs the program without one",
		    b->has_s            ? "S"
		    : b->spindle_m == 3 ? "M3"
		                        : "M4");
	}
	if (b->has_s && b->s > io->max_rpm) {
		return mlip_gc_fail(e, line, b->s_col, MLIP_E_RANGE,
		                    "S%g beyond the spindle's MAX_RPM %g: refused, not clamped (a "
		                    "slower spindle at the programmed feed overloads the cutter); "
		                    "change S in the program",
		                    b->s, io->max_rpm);
	}
	if (b->has_s && b->s > 0 && b->s < io->min_rpm) {
		return mlip_gc_fail(e, line, b->s_col, MLIP_E_RANGE,
		                    "S%g below the spindle's MIN_RPM %g: it cannot turn that "
		                    "slowly; change S in the program",
		                    b->s, io->min_rpm);
	}
	if (g->mdi && io->spindle == MLIP_IO_MANUAL && b->has_s && !b->spindle_m &&
	    !g->spindle_said) {
		/* it may turn since an earlier MDI M3 (the operator's hand, which
		 * mlip cannot see): a silent S would leave it at the old speed */
		return mlip_gc_fail(
		    e, line, b->s_col, MLIP_E_UNSUPPORTED,
		    "S%g alone in MDI with a manual spindle: mlip cannot tell whether "
		    "it turns; give it with M3, M4 or M5 (e.g. M3 S%g)",
		    b->s, b->s);
	}
	if ((b->spindle_m == 3 || b->spindle_m == 4) && !b->has_s && g->s_rpm < 0) {
		return mlip_gc_fail(e, line, b->spindle_col, MLIP_E_SYNTAX,
		                    "M%u with no S: the spindle speed was never set (e.g. S12000 "
		                    "M%u)",
		                    (unsigned)b->spindle_m, (unsigned)b->spindle_m);
	}
	return MLIP_OK;
}

static mlip_status check_tools(const struct mlip_gcode *g, const struct blk *b, uint32_t line,
                               struct mlip_gcode_error *e);

mlip_status mlip_gc_check_io(const struct mlip_gcode *g, const struct blk *b, uint32_t line,
                             struct mlip_gcode_error *e)
{
	const struct mlip_gcode_io *io = g->io;
	mlip_status st;

	if (io == NULL) {
		if (b->g43 == 430 || b->g43 == 431) {
			return mlip_gc_fail(
			    e, line, b->g43_col, MLIP_E_UNSUPPORTED,
			    "%G: a tool length offset needs the machine's config (--config) and "
			    "its tool table (--tools FILE)",
			    b->g43);
		}
		return MLIP_OK;
	}
	st = check_spindle(g, b, line, e);
	if (st == MLIP_OK && !io->ignore_tools) {
		st = check_tools(g, b, line, e);
	}
	if (st == MLIP_OK && b->coolant_m && !io->ignore_coolant && io->coolant == MLIP_IO_NONE) {
		return mlip_gc_fail(e, line, b->coolant_col, MLIP_E_UNSUPPORTED,
		                    "M%u: this machine has no coolant ([COOLANT] TYPE = none); "
		                    "--ignore-coolant runs the program without it",
		                    b->coolant_m & MLIP_COOLANT_MIST ? 7u : 8u);
	}
	if (st == MLIP_OK && b->coolant_m && !io->ignore_coolant && io->coolant == MLIP_IO_MODULE &&
	    (b->coolant_m & ~io->coolant_outlets) != 0) {
		unsigned mist = (b->coolant_m & ~io->coolant_outlets) & MLIP_COOLANT_MIST;
		return mlip_gc_fail(e, line, b->coolant_col, MLIP_E_UNSUPPORTED,
		                    "M%u: this machine's coolant has no %s outlet ([COOLANT] %s is "
		                    "not mapped)",
		                    mist ? 7u : 8u, mist ? "mist" : "flood",
		                    mist ? "MIST" : "FLOOD");
	}
	if (st == MLIP_OK && b->dout && !(io->dout_mask >> (unsigned)b->p & 1u)) {
		return mlip_gc_fail(e, line, b->p_col, MLIP_E_UNSUPPORTED,
		                    "M%u P%u: digital output %u is not mapped ([IO] OUTPUT_%u)",
		                    (unsigned)b->dout, (unsigned)b->p, (unsigned)b->p,
		                    (unsigned)b->p);
	}
	return st;
}

static mlip_status check_tools(const struct mlip_gcode *g, const struct blk *b, uint32_t line,
                               struct mlip_gcode_error *e)
{
	const struct mlip_gcode_io *io = g->io;
	mlip_status st = MLIP_OK;
	int32_t n = 0;
	int a;

	if ((b->has_t || b->m6) && io->tool_change == MLIP_IO_NONE) {
		return mlip_gc_fail(e, line, b->has_t ? b->t_col : b->m6_col, MLIP_E_UNSUPPORTED,
		                    "%s: this machine has no tool change ([TOOL] CHANGE = none); "
		                    "--ignore-tools runs the program with the tool in the spindle",
		                    b->has_t ? "T" : "M6");
	}
	if (b->has_t) {
		st = check_tool(g, 'T', b->t, line, b->t_col, e);
	}
	if (st == MLIP_OK && b->m61) {
		st = check_tool(g, 'Q', b->q, line, b->q_col, e);
	}
	if (st != MLIP_OK) {
		return st;
	}
	if (b->m6 && !b->has_t && g->tool_sel < 0) {
		return mlip_gc_fail(e, line, b->m6_col, MLIP_E_SYNTAX,
		                    "M6 with no T: say which tool, e.g. T2 M6");
	}
	if (b->g43 == 430) {
		if (b->has_h) {
			st = check_tool(g, 'H', b->h, line, b->h_col, e);
			if (st != MLIP_OK) {
				return st;
			}
			(void)tool_number(b->h, &n);
		} else {
			n = 0;
		}
		if (n == 0) { /* G43, G43 H0: the tool in the spindle (a non-random changer) */
			n = tool_after(g, b);
			if (n == 0) {
				return mlip_gc_fail(
				    e, line, b->g43_col, MLIP_E_SYNTAX,
				    "G43 with no tool in the spindle: M6 T- first, M61 "
				    "Q- to say which one is in it, or G43 H-");
			}
			if (mlip_gcode_find_tool(io, n) == NULL) {
				return mlip_gc_fail(
				    e, line, b->g43_col, MLIP_E_RANGE,
				    "G43: tool %u in the spindle is not in the tool table",
				    (unsigned)n);
			}
		}
	}
	if (b->g43 == 431) {
		if (mlip_gc_z_index(g->m) < 0) {
			return mlip_gc_fail(e, line, b->g43_col, MLIP_E_UNSUPPORTED,
			                    "G43.1: this machine has no Z axis");
		}
		for (a = 0; a < 6; a++) {
			if (b->has_ax[a] && GC_AXES[a] != 'Z') {
				return mlip_gc_fail(e, line, b->ax_col[a], MLIP_E_UNSUPPORTED,
				                    "G43.1 %c: only a length along Z is supported",
				                    GC_AXES[a]);
			}
		}
		if (!b->has_ax[2]) {
			return mlip_gc_fail(e, line, b->g43_col, MLIP_E_SYNTAX,
			                    "G43.1 without Z: give the length, e.g. G43.1 Z12.5");
		}
	}
	if (b->g43 == 430 && mlip_gc_z_index(g->m) < 0) {
		return mlip_gc_fail(e, line, b->g43_col, MLIP_E_UNSUPPORTED,
		                    "G43: this machine has no Z axis");
	}
	return MLIP_OK;
}

/* An event for the line's end of checks (ec->io holds a line's at most). */
static void queue(struct emit_ctx *ec, int kind, double value)
{
	if (ec->n_io < (int)(sizeof ec->io / sizeof ec->io[0])) {
		ec->io[ec->n_io].kind = (uint8_t)kind;
		ec->io[ec->n_io].value = value;
		ec->n_io++;
	}
}

/* Lines that have not said yet what the spindle does, where an earlier MDI
 * M3/M4 may keep it turning: MDI lines, or a program read for a running
 * controller with a CiA 402 spindle (a manual one: mlip cannot tell, and
 * a program says M3/M4/M5 before it matters). */
static int unsaid(const struct mlip_gcode *g)
{
	const struct mlip_gcode_io *io = g->io;

	return !g->spindle_said && !io->ignore_spindle &&
	       (g->mdi ? io->spindle != MLIP_IO_NONE : io->live && io->spindle == MLIP_IO_CIA402);
}

/* The spindle may turn: this reader started it, or an earlier MDI line. */
static int may_turn(const struct mlip_gcode *g)
{
	return g->spindle || unsaid(g);
}

static double spindle_value(const struct mlip_gcode *g)
{
	return g->spindle == 3 ? g->s_rpm : g->spindle == 4 ? -g->s_rpm : 0.0;
}

/* M6's moves: rapids in machine coordinates from where the machine stands
 * to the change position, Z first (the tool leaves the work before
 * anything moves across it). */
static int go_change(struct mlip_gcode *g, const struct emit_ctx *line_ec)
{
	const struct mlip_gcode_io *io = g->io;
	const struct mlip_machine *m = g->m;
	struct emit_ctx ec;
	double t[MLIP_MAX_AXES];
	int i, z = mlip_gc_z_index(m);

	memset(&ec, 0, sizeof ec);
	ec.sink = line_ec->sink;
	ec.ctx = line_ec->ctx;
	ec.line = line_ec->line;
	ec.rapid = 1;
	ec.feed_mm_s = m->max_feed_mm_s;
	memcpy(t, g->pos, sizeof t);
	if (z >= 0 && (io->change_mask >> z & 1u)) {
		t[z] = io->change_pos[z];
		if (mlip_gc_emit(g, &ec, t, g->tol_mm) != 0) {
			return -1;
		}
	}
	for (i = 0; i < m->n_axes; i++) {
		if (io->change_mask >> i & 1u) {
			t[i] = io->change_pos[i];
		}
	}
	return mlip_gc_emit(g, &ec, t, g->tol_mm);
}

int mlip_gc_flush_io(struct mlip_gcode *g, struct emit_ctx *ec)
{
	int k, n = ec->n_io;

	ec->n_io = 0; /* once: go_change's moves flush nothing of this line */
	for (k = 0; k < n; k++) {
		int rc = ec->io[k].kind == IO_CHANGE
		             ? go_change(g, ec)
		             : mlip_gc_emit_event(g, ec->sink, ec->ctx, ec->line,
		                                  (mlip_block_kind)ec->io[k].kind, ec->io[k].value);
		if (rc != 0) {
			return -1;
		}
	}
	return 0;
}

static void legacy_notices(struct mlip_gcode *g, const struct blk *b, uint32_t line)
{
	int k;

	for (k = 0; k < b->n_io_notes; k++) {
		mlip_gc_notice(g, b->io_notes[k], line);
	}
}

static void exec_spindle(struct mlip_gcode *g, const struct blk *b, struct emit_ctx *ec,
                         uint32_t line, int before_m6, double s_before)
{
	const struct mlip_gcode_io *io = g->io;
	static const char *const sp[] = {"M3", "M4", "M5"};
	int was = g->spindle;

	if (io->ignore_spindle) {
		if (before_m6 && b->has_s) {
			mlip_gc_notice_text(g, "S", IGN_SPINDLE, line);
		}
		if (!before_m6 && b->spindle_m) {
			mlip_gc_notice_text(g, sp[b->spindle_m - 3], IGN_SPINDLE, line);
		}
		return;
	}
	if (before_m6) { /* S: a change while it turns (and no M3/M4/M5 here) */
		if (b->has_s) {
			double old = g->s_rpm;
			g->s_rpm = b->s;
			if (g->spindle && !b->spindle_m && old != b->s) {
				queue(ec, MLIP_BLOCK_SPINDLE, spindle_value(g));
			} else if (unsaid(g) && !b->spindle_m && io->spindle == MLIP_IO_CIA402) {
				/* MDI, or a program's S before its M3/M4/M5: an
				 * earlier MDI M3/M4 may keep it turning; the
				 * controller, which knows, applies the speed in its
				 * direction (a stopped spindle stays stopped) */
				queue(ec, MLIP_BLOCK_SPEED, b->s);
			}
		}
		return;
	}
	if (!b->spindle_m) {
		return;
	}
	if (b->spindle_m == 5 && io->spindle == MLIP_IO_NONE) {
		mlip_gc_notice_text(g, "M5", NO_SPINDLE_M5, line);
		return;
	}
	g->spindle = b->spindle_m == 5 ? 0 : b->spindle_m;
	g->spindle_said = 1;
	/* a new state, or M3/M4 repeated with a new S on this line; an MDI M5
	 * always: an earlier MDI line's M3 still turns it (the controller keeps
	 * it), whatever this reader's fresh state says */
	if (g->spindle != was || (g->spindle && g->s_rpm != s_before) ||
	    (g->mdi && b->spindle_m == 5)) {
		queue(ec, MLIP_BLOCK_SPINDLE, spindle_value(g));
	}
}

static void exec_tools(struct mlip_gcode *g, const struct blk *b, double scale, struct emit_ctx *ec,
                       uint32_t line, int length)
{
	const struct mlip_gcode_io *io = g->io;
	const struct mlip_tool *t;
	int32_t n;
	int i;

	if (io->ignore_tools) {
		if (!length && b->has_t) {
			mlip_gc_notice_text(g, "T", IGN_TOOLS, line);
		}
		if (!length && (b->m6 || b->m61)) {
			mlip_gc_notice_text(g, b->m6 ? "M6" : "M61", IGN_TOOLS, line);
		}
		if (length && b->g43) {
			mlip_gc_notice_text(g,
			                    b->g43 == 430   ? "G43"
			                    : b->g43 == 431 ? "G43.1"
			                                    : "G49",
			                    IGN_TOOLS, line);
		}
		return;
	}
	if (length) { /* G43, G43.1, G49 (after the modes: G43.1 Z in the line's units) */
		if (b->g43 == 430) {
			n = 0;
			if (b->has_h) {
				(void)tool_number(b->h, &n);
			}
			t = mlip_gcode_find_tool(io, n ? n : g->off.tool);
			g->tlo_mm = t != NULL ? t->z_mm : 0.0; /* found: checked */
		} else if (b->g43 == 431) {
			g->tlo_mm = b->ax[2] * scale;
		} else if (b->g43 == 490) {
			g->tlo_mm = 0.0;
		}
		if (b->g43) {
			g->tlo_mode = b->g43;
		}
		return;
	}
	if (b->has_t) {
		(void)tool_number(b->t, &g->tool_sel);
	}
	if (b->m61) {
		(void)tool_number(b->q, &g->off.tool);
	}
	if (!b->m6) {
		return;
	}
	if (g->tool_sel == g->off.tool) {
		mlip_gc_notice_text(g, "M6", SAME_TOOL, line);
		return;
	}
	/* LinuxCNC: after M6 the spindle is stopped (first: never a change
	 * beside a spindle an earlier MDI M3 left turning) */
	if (may_turn(g)) {
		g->spindle = 0;
		g->spindle_said = 1;
		queue(ec, MLIP_BLOCK_SPINDLE, 0.0);
	}
	if (io->change_mask != 0) { /* the line's motion starts there */
		queue(ec, IO_CHANGE, 0.0);
		for (i = 0; i < g->m->n_axes; i++) {
			if (io->change_mask >> i & 1u) {
				g->cur[i] = io->change_pos[i];
			}
		}
	}
	queue(ec, MLIP_BLOCK_TOOL, (double)g->tool_sel);
	g->off.tool = g->tool_sel;
}

static void exec_coolant(struct mlip_gcode *g, const struct blk *b, struct emit_ctx *ec,
                         uint32_t line)
{
	const struct mlip_gcode_io *io = g->io;
	unsigned want;

	if (!b->coolant_m && !b->m9) {
		return;
	}
	if (io->ignore_coolant) {
		if (b->coolant_m & MLIP_COOLANT_MIST) {
			mlip_gc_notice_text(g, "M7", IGN_COOLANT, line);
		}
		if (b->coolant_m & MLIP_COOLANT_FLOOD) {
			mlip_gc_notice_text(g, "M8", IGN_COOLANT, line);
		}
		if (b->m9) {
			mlip_gc_notice_text(g, "M9", IGN_COOLANT, line);
		}
		return;
	}
	want = b->m9 ? 0u : g->coolant | b->coolant_m;
	/* an MDI M9 always (an earlier MDI line's M7/M8 stays on) */
	if (want != g->coolant || (g->mdi && b->m9 && io->coolant != MLIP_IO_NONE)) {
		g->coolant = want;
		queue(ec, MLIP_BLOCK_COOLANT, (double)want);
	}
}

void mlip_gc_exec_io(struct mlip_gcode *g, const struct blk *b, double scale, struct emit_ctx *ec)
{
	double s_before = g->s_rpm;

	if (g->io == NULL) {
		legacy_notices(g, b, ec->line);
		return;
	}
	exec_spindle(g, b, ec, ec->line, 1, s_before); /* S */
	exec_tools(g, b, scale, ec, ec->line, 0);      /* T, M6, M61 */
	exec_spindle(g, b, ec, ec->line, 0, s_before); /* M3, M4, M5 */
	exec_coolant(g, b, ec, ec->line);              /* M7, M8, M9 */
	if (b->dout) {                                 /* M64, M65; M62, M63 with the next move */
		double v = b->p + 1.0 + (b->dout <= 63 ? MLIP_DOUT_SYNC : 0);
		queue(ec, MLIP_BLOCK_OUTPUT, b->dout == 64 || b->dout == 62 ? v : -v);
	}
	exec_tools(g, b, scale, ec, ec->line, 1); /* G43, G43.1, G49 */
}

mlip_status mlip_gc_end_io(struct mlip_gcode *g, mlip_block_sink sink, void *ctx, uint32_t line)
{
	if (g->io == NULL) {
		return MLIP_OK;
	}
	if (g->spindle || (g->mdi && unsaid(g))) { /* a program's end: the controller's */
		g->spindle = 0;
		g->spindle_said = 1;
		if (mlip_gc_emit_event(g, sink, ctx, line, MLIP_BLOCK_SPINDLE, 0.0) != 0) {
			return MLIP_E_FULL;
		}
	}
	if (g->coolant || (g->mdi && !g->io->ignore_coolant && g->io->coolant != MLIP_IO_NONE)) {
		g->coolant = 0; /* MDI M2: an earlier MDI M7/M8 may have left it on */
		if (mlip_gc_emit_event(g, sink, ctx, line, MLIP_BLOCK_COOLANT, 0.0) != 0) {
			return MLIP_E_FULL;
		}
	}
	return MLIP_OK;
}

/* G38.2..G38.5: a feed move toward t that the controller stops at the
 * acceleration limit when the probe input changes (issue 19). The feed is
 * the program's own F (never the --default-feed: a probe runs at a speed the
 * program chose); the move goes somewhere and moves no rotary axis
 * (LinuxCNC). Afterwards the moved axes stand where the probe stopped them:
 * unknown to the check (check_unknown in gcode.c). */
mlip_status mlip_gc_probe(struct mlip_gcode *g, const struct blk *b, const struct plan *pl,
                          struct emit_ctx *ec, const double *s, const double *t,
                          const uint32_t *col_of, uint32_t line, struct mlip_gcode_error *e)
{
	const struct mlip_machine *m = g->m;
	unsigned sub = (unsigned)(b->probe % 10);
	struct mlip_block blk;
	double d2 = 0;
	uint32_t moved = 0;
	mlip_status st;
	int i;

	if (!(g->feed_mm_s > 0)) {
		return mlip_gc_fail(
		    e, line, b->motion_col, MLIP_E_SYNTAX,
		    "G38.%u with no F: give the probing feed, e.g. G38.%u Z-10 F100", sub, sub);
	}
	for (i = 0; i < m->n_axes; i++) {
		if (fabs(t[i] - s[i]) < MLIP_GCODE_MERGE_MM) {
			continue;
		}
		if (m->axis[i].kind == MLIP_AXIS_ROTARY) {
			return mlip_gc_fail(e, line, col_of[i], MLIP_E_UNSUPPORTED,
			                    "G38.%u moves %c: a probe moves linear axes only", sub,
			                    mlip_upper(m->axis[i].letter));
		}
		moved |= 1u << i;
		d2 += (t[i] - s[i]) * (t[i] - s[i]);
	}
	if (moved == 0) {
		return mlip_gc_fail(e, line, b->motion_col, MLIP_E_RANGE,
		                    "G38.%u to the current position: the probe would not move",
		                    sub);
	}
	(void)d2;
	st = mlip_gc_block_feed(g, pl, s, t, line, &ec->feed_mm_s, e);
	if (st == MLIP_OK) {
		st = mlip_gc_check_limits(g, t, col_of, line, 0, e);
	}
	if (st == MLIP_OK) {
		st = mlip_gc_move_feed(g, b, pl, s, t, NULL, line, &ec->feed_mm_s, e);
	}
	if (st != MLIP_OK) {
		return st;
	}
	if (mlip_gc_flush_dwell(g, ec) != 0) {
		return MLIP_E_FULL;
	}
	memset(&blk, 0, sizeof blk);
	for (i = 0; i < m->n_axes; i++) {
		blk.target[i] = t[i];
	}
	blk.kind = MLIP_BLOCK_PROBE;
	blk.value = (b->probe == 382 || b->probe == 384 ? MLIP_PROBE_MUST_TRIP : 0u) |
	            (b->probe >= 384 ? MLIP_PROBE_AWAY : 0u);
	blk.feed_mm_s = ec->feed_mm_s;
	blk.tol_mm = g->tol_mm;
	blk.line = line;
	blk.exact_stop = 1; /* it starts and ends at rest */
	g->broken_rule = mlip_block_check(m, &blk);
	if (g->broken_rule != MLIP_RULE_OK || ec->sink(ec->ctx, &blk) != 0) {
		return MLIP_E_FULL;
	}
	for (i = 0; i < m->n_axes; i++) {
		g->pos[i] = g->cur[i] = t[i];
	}
	g->blocks++;
	g->moves++;
	g->unknown = moved; /* the others were given absolutely (check_unknown) */
	g->probe_mode = b->probe;
	g->probe_line = line;
	return MLIP_OK;
}
