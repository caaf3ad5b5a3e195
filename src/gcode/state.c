/*
 * state.c - the modal state: init and setters of mlip/gcode/gcode.h, the
 * notices (words accepted without effect, reported once), the commit of a
 * line's modes, and the feed of a block (G94 and G93).
 */
#include <math.h>
#include <string.h>

#include "gc.h"

void mlip_gcode_offsets_init(struct mlip_gcode_offsets *o, const struct mlip_machine *m)
{
	int i;

	memset(o, 0, sizeof *o);
	for (i = 0; i < m->n_axes && i < MLIP_MAX_AXES; i++) {
		o->g28[i] = m->axis[i].home;
		o->g30[i] = m->axis[i].home;
	}
}

const char *mlip_gcode_coord_name(int select)
{
	static const char *const names[MLIP_GCODE_N_COORD] = {
	    "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3"};

	return select >= 0 && select < MLIP_GCODE_N_COORD ? names[select] : "?";
}

void mlip_gcode_init(struct mlip_gcode *g, const struct mlip_machine *m)
{
	int i;

	memset(g, 0, sizeof *g);
	g->m = m;
	g->motion = -1;
	g->plane = 17;
	g->absolute = 1;
	g->tol_mm = m->tolerance_mm;
	for (i = 0; i < m->n_axes && i < MLIP_MAX_AXES; i++) {
		g->pos[i] = m->axis[i].home;
		g->cur[i] = m->axis[i].home;
	}
	mlip_gcode_offsets_init(&g->off, m);
	g->s_rpm = -1;
	g->tool_sel = -1;
	g->tlo_mode = 490;
}

void mlip_gcode_set_io(struct mlip_gcode *g, const struct mlip_gcode_io *io)
{
	g->io = io;
}

void mlip_gcode_set_initial_feed(struct mlip_gcode *g, double f_word)
{
	g->initial_feed_word = f_word > 0 && isfinite(f_word) ? f_word : 0.0;
}

void mlip_gcode_set_strict(struct mlip_gcode *g, int on)
{
	g->strict = on != 0;
}

void mlip_gcode_set_offsets(struct mlip_gcode *g, const struct mlip_gcode_offsets *o)
{
	g->off = *o;
	if (g->off.select < 0 || g->off.select >= MLIP_GCODE_N_COORD) {
		g->off.select = 0;
	}
	g->off.g92_on = g->off.g92_on != 0;
	if (g->off.tool < 0) {
		g->off.tool = 0;
	}
}

void mlip_gc_notice(struct mlip_gcode *g, const char *word, uint32_t line)
{
	mlip_gc_notice_text(g, word, 0, line);
}

void mlip_gc_notice_text(struct mlip_gcode *g, const char *word, const char *text, uint32_t line)
{
	struct mlip_gcode_notice *n;
	uint32_t k;

	for (k = 0; k < g->n_notices; k++) {
		if (strcmp(g->notices[k].word, word) == 0 && g->notices[k].text == text) {
			g->notices[k].count++;
			return;
		}
	}
	if (g->n_notices < MLIP_GCODE_MAX_NOTICES) {
		n = &g->notices[g->n_notices++];
		memset(n->word, 0, sizeof n->word);
		strncpy(n->word, word, sizeof n->word - 1);
		n->first_line = line;
		n->count = 1;
		n->text = text;
	}
}

/* Texts of the notices that are not "ignored": what mlip did instead. */
static const struct {
	const char *word, *text;
} notice_texts[] = {
    {"G28", "rapid to the G28 position (through the intermediate point, if any): HOME of "
            "the config or G28.1 in the offsets file"},
    {"G30", "rapid to the G30 position (through the intermediate point, if any): HOME of "
            "the config or G30.1 in the offsets file"},
    {"F", "missing before a feed move: the initial feed was used"},
    {"G0", "axis words before any G0/G1/G2/G3 moved as G0, Grbl's start-up motion mode "
           "(--strict refuses them)"},
    {"G64P", "tolerance larger than the machine's CONTOUR_TOLERANCE: capped to it"},
    {"G64Q", "(LinuxCNC's naive-CAM merge tolerance) ignored: every segment is kept and "
             "corners blend within P"},
    {"M60", "pauses as M0 (no pallet shuttle)"},
    {"M2", "program end (LinuxCNC: G54 selected, G92 offsets off); later lines are not run"},
    {"M30", "program end (LinuxCNC: G54 selected, G92 offsets off); later lines are not run"},
    {"/", "block delete: the line was skipped (the block-delete switch is on, as LinuxCNC "
          "starts)"},
    {"$J", "(Grbl jog) run as a G1 move at its own F; the modal state is left as it was "
           "(Grbl 1.1)"},
    {"$H", "(Grbl homing cycle) skipped: mlip does not home; home the machine with the "
           "drives before starting mlip-rt and check HOME in the config"},
    {"$X", "(Grbl alarm unlock) skipped: mlip has no alarm lock (mlip-rt restarts a "
           "faulted machine)"},
    {"$C", "(Grbl check mode) skipped: mlip checks every program before it moves"},
    {"$SLP", "(Grbl sleep) skipped: stop mlip-rt instead"},
    {"$", "(Grbl settings or report) skipped: mlip's settings are in its config file"},
    {"?", "(Grbl status request) skipped: mlip-ctl status reports the machine"},
    {"~", "(Grbl cycle start) skipped: mlip-ctl resume continues a held or paused machine"},
    {"!", "(Grbl feed hold) skipped: a pause in a program is M0; mlip-ctl hold holds"},
};

const char *mlip_gcode_notice_text(const struct mlip_gcode_notice *n)
{
	size_t k;

	if (n->text != NULL) {
		return n->text;
	}
	for (k = 0; k < sizeof notice_texts / sizeof notice_texts[0]; k++) {
		if (strcmp(n->word, notice_texts[k].word) == 0 ||
		    (n->word[0] == '$' && notice_texts[k].word[1] == '\0' &&
		     notice_texts[k].word[0] == '$')) {
			return notice_texts[k].text;
		}
	}
	return "ignored (no effect on motion)";
}

int mlip_gc_axis_index(const struct mlip_machine *m, char letter)
{
	int i;

	for (i = 0; i < m->n_axes; i++) {
		if (mlip_upper(m->axis[i].letter) == letter) {
			return i;
		}
	}
	return -1;
}

void mlip_gc_commit_modal(struct mlip_gcode *g, const struct blk *b, const struct plan *pl,
                          uint32_t line)
{
	double tol;
	int i;

	if (b->units) {
		g->inches = b->units == 20;
	}
	if (b->dist) {
		g->absolute = b->dist == 90;
	}
	if (b->plane) {
		g->plane = b->plane;
	}
	if (b->motion >= 0) {
		g->motion = b->motion;
	}
	if (pl->g0_default) {
		g->motion = 0;
		mlip_gc_notice(g, "G0", line);
	}
	if (b->feedmode && (b->feedmode == 93) != g->inverse_time) {
		g->inverse_time = b->feedmode == 93;
		g->feed_mm_s = 0;
		g->feed_word = 0;
		g->feed_reset = 1;
	}
	if (b->has_f && !g->inverse_time) {
		g->feed_word = b->f;
		g->feed_mm_s = b->f * (g->inches ? MM_PER_INCH : 1.0) / 60.0;
		g->feed_reset = 0;
	}
	if (b->coord >= 0) {
		g->off.select = b->coord;
	}
	if (b->path == 610 || b->path == 611) {
		g->exact_stop = 1; /* rest at the end of every move (corners exact) */
		g->tol_mm = g->m->tolerance_mm;
	} else if (b->path == 640) {
		g->exact_stop = 0;
		tol = b->has_p && b->p > 0 ? b->p * (g->inches ? MM_PER_INCH : 1.0) : 0;
		g->tol_mm = tol > 0 && tol < g->m->tolerance_mm ? tol : g->m->tolerance_mm;
		if (tol > g->m->tolerance_mm) {
			mlip_gc_notice(g, "G64P", line);
		}
		if (b->has_q) {
			mlip_gc_notice(g, "G64Q", line);
		}
	}
	for (i = 0; i < b->n_notes; i++) {
		mlip_gc_notice(g, b->notes[i], line);
	}
}

/* The block feed: F as a path speed when a linear axis moves, else in deg/min
 * (G94). Before any F: the initial feed if one was set, else an error. */
mlip_status mlip_gc_block_feed(struct mlip_gcode *g, const struct plan *pl, const double *s,
                               const double *t, uint32_t line, double *feed_mm_s,
                               struct mlip_gcode_error *e)
{
	const struct mlip_machine *m = g->m;
	double fmm = g->feed_mm_s, fword = g->feed_word;
	int i, linear = 0;

	if (!(fmm > 0)) {
		if (g->feed_reset) {
			return mlip_gc_fail(
			    e, line, pl->mcol, MLIP_E_SYNTAX,
			    "missing feed: a change between G93 and G94 needs a new F");
		}
		if (!(g->initial_feed_word > 0)) {
			return mlip_gc_fail(
			    e, line, pl->mcol, MLIP_E_SYNTAX,
			    "missing feed: no F before the first feed move (a program with "
			    "none runs with --default-feed F)");
		}
		fword = g->initial_feed_word;
		fmm = fword * (g->inches ? MM_PER_INCH : 1.0) / 60.0;
		mlip_gc_notice(g, "F", line);
	}
	for (i = 0; i < m->n_axes; i++) {
		if (m->axis[i].kind != MLIP_AXIS_ROTARY &&
		    (pl->motion >= 2 || fabs(t[i] - s[i]) >= MLIP_GCODE_MERGE_MM)) {
			linear = 1;
		}
	}
	*feed_mm_s = linear ? fmm : fword / 60.0;
	return MLIP_OK;
}

/* G93: the move takes 1/F minutes, so its speed is its length times F/60:
 * the linear axes' path length (the arc's, for G2/G3), or the rotary axes'
 * (deg/s) when no linear axis moves. */
double mlip_gc_inverse_time_feed(const struct mlip_gcode *g, double f, const double *s,
                                 const double *t, const struct arc *arc)
{
	const struct mlip_machine *m = g->m;
	double lin = 0, rot = 0, d, len;
	int i;

	for (i = 0; i < m->n_axes; i++) {
		d = arc && (i == arc->iu || i == arc->iv) ? 0 : t[i] - s[i];
		if (m->axis[i].kind == MLIP_AXIS_ROTARY) {
			rot += d * d;
		} else {
			lin += d * d;
		}
	}
	if (arc) {
		d = fabs(arc->sweep) * (arc->r0 + arc->r1) / 2;
		if (m->axis[arc->iu].kind == MLIP_AXIS_ROTARY) {
			rot += d * d;
		} else {
			lin += d * d;
		}
	}
	len = sqrt(lin) >= MLIP_GCODE_MERGE_MM ? sqrt(lin) : sqrt(rot);
	return len * f / 60.0;
}
