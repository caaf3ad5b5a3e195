/*
 * modal.c - the modal state: init and setters of mlip/gcode/gcode.h, the
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
	g->off_start = g->off;
	g->s_rpm = -1;
	g->tool_sel = -1;
	g->tlo_mode = 490;
}

void mlip_gcode_modal_init(struct mlip_gcode_modal *md, const struct mlip_machine *m)
{
	memset(md, 0, sizeof *md);
	md->motion = -1;
	md->plane = 17;
	md->absolute = 1;
	md->tol_mm = m->tolerance_mm;
	md->s_rpm = -1;
	md->tool_sel = -1;
	md->tlo_mode = 490;
}

void mlip_gcode_get_modal(const struct mlip_gcode *g, struct mlip_gcode_modal *md)
{
	memset(md, 0, sizeof *md); /* its padding too: a copy compares whole */
	/* a canned cycle's mode ends with its MDI line (its sticky numbers are
	 * not kept): axis words alone after it are refused, as after G80 */
	md->motion = g->cycle || g->cycle_off ? -2 : g->motion;
	md->plane = g->plane;
	md->absolute = g->absolute;
	md->inches = g->inches;
	md->inverse_time = g->inverse_time;
	/* G93's F is per move (a new one on each line): never carried */
	md->feed_word = !g->inverse_time && g->feed_mm_s > 0 ? g->feed_word : 0.0;
	md->exact_stop = g->exact_stop;
	md->tol_mm = g->tol_mm;
	md->s_rpm = g->s_rpm;
	md->tool_sel = g->tool_sel;
	md->tlo_mode = g->tlo_mode;
	md->tlo_mm = g->tlo_mode == 490 ? 0.0 : g->tlo_mm;
}

mlip_status mlip_gcode_set_modal(struct mlip_gcode *g, const struct mlip_gcode_modal *md)
{
	const struct mlip_machine *m = g->m;
	double fmm = md->feed_word * (md->inches ? MM_PER_INCH : 1.0) / 60.0;

	if (md->motion < -2 || md->motion > 3 || md->plane < 17 || md->plane > 19 ||
	    (md->absolute != 0 && md->absolute != 1) || (md->inches != 0 && md->inches != 1) ||
	    (md->inverse_time != 0 && md->inverse_time != 1) ||
	    (md->exact_stop != 0 && md->exact_stop != 1)) {
		return MLIP_E_RANGE;
	}
	if (!(md->feed_word == 0.0 ||
	      (!md->inverse_time && fmm >= MLIP_FEED_MIN_MM_S && fmm <= MLIP_FEED_MAX_MM_S))) {
		return MLIP_E_RANGE;
	}
	if (!(md->tol_mm > 0 && md->tol_mm <= m->tolerance_mm)) {
		return MLIP_E_RANGE;
	}
	if (!(md->s_rpm == -1.0 || (md->s_rpm >= 0 && md->s_rpm <= 1e6))) {
		return MLIP_E_RANGE;
	}
	if (md->tool_sel < -1) {
		return MLIP_E_RANGE;
	}
	if ((md->tlo_mode != 490 && md->tlo_mode != 430 && md->tlo_mode != 431) ||
	    !(fabs(md->tlo_mm) <= 1e6) || (md->tlo_mode == 490 && md->tlo_mm != 0.0)) {
		return MLIP_E_RANGE;
	}
	g->motion = md->motion < 0 ? -1 : md->motion;
	g->cycle_off = md->motion == -2;
	g->plane = md->plane;
	g->absolute = md->absolute;
	g->inches = md->inches;
	g->inverse_time = md->inverse_time;
	g->feed_word = md->feed_word;
	g->feed_mm_s = md->feed_word > 0 ? fmm : 0.0;
	g->feed_reset = 0;
	g->exact_stop = md->exact_stop;
	g->tol_mm = md->tol_mm;
	g->s_rpm = md->s_rpm;
	g->tool_sel = md->tool_sel;
	g->tlo_mode = md->tlo_mode;
	g->tlo_mm = md->tlo_mm;
	return MLIP_OK;
}

void mlip_gcode_set_mdi(struct mlip_gcode *g, int on)
{
	g->mdi = on != 0;
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
	g->off_start = g->off;
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
    {"%", "closing program delimiter (LinuxCNC): later lines are not run"},
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
		g->cycle = 0; /* another motion code ends the canned cycle */
		g->cycle_off = 0;
	}
	if (b->g80 && g->cycle) {
		g->cycle = 0;
		g->motion = -1; /* LinuxCNC: no motion mode after G80 */
		g->cycle_off = 1;
	} else if (b->g80) {
		mlip_gc_notice(g, "G80", line); /* no cycle: no effect on motion */
	}
	if (pl->cycle) {
		g->cycle = pl->cycle; /* its sticky numbers: mlip_gc_cycle */
		g->motion = -1;
		g->cycle_off = 0;
	}
	if (b->retract) {
		g->retract_r = b->retract == 99;
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

/* A move's length: the linear axes' path length (the arc's, for G2/G3), or
 * the rotary axes' (degrees) when no linear axis moves. */
static double move_length(const struct mlip_gcode *g, const double *s, const double *t,
                          const struct arc *arc)
{
	const struct mlip_machine *m = g->m;
	double lin = 0, rot = 0, d;
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
	return sqrt(lin) >= MLIP_GCODE_MERGE_MM ? sqrt(lin) : sqrt(rot);
}

/* The feed of a feed move against the rule set of every block (mlip/types.h),
 * blamed on the line's F word, else on its motion: at most
 * MLIP_FEED_MAX_MM_S, at least MLIP_FEED_MIN_MM_S, and no longer than a
 * day at that feed (as a dwell: a block that never ends is no program). */
mlip_status mlip_gc_move_feed(const struct mlip_gcode *g, const struct blk *b,
                              const struct plan *pl, const double *s, const double *t,
                              const struct arc *arc, uint32_t line, double *feed_mm_s,
                              struct mlip_gcode_error *e)
{
	uint32_t col = b->has_f ? b->f_col : pl->mcol;
	double len = move_length(g, s, t, arc), v;

	if (g->inverse_time) {
		*feed_mm_s = len * b->f / 60.0;
	}
	v = *feed_mm_s;
	if (!(v <= MLIP_FEED_MAX_MM_S)) {
		return mlip_gc_fail(
		    e, line, col, MLIP_E_RANGE,
		    "%s%g makes this move's feed %g mm/s: at most %g mm/s (60 km/min)",
		    g->inverse_time ? "G93 F" : "F", g->inverse_time ? b->f : g->feed_word, v,
		    MLIP_FEED_MAX_MM_S);
	}
	if (!(v >= MLIP_FEED_MIN_MM_S)) {
		return mlip_gc_fail(e, line, col, MLIP_E_RANGE,
		                    "%s%g makes this move's feed %g mm/s: at least %g mm/s "
		                    "(0.06 mm/min)",
		                    g->inverse_time ? "G93 F" : "F",
		                    g->inverse_time ? b->f : g->feed_word, v, MLIP_FEED_MIN_MM_S);
	}
	if (!(len / v <= MLIP_DWELL_MAX_S)) {
		return mlip_gc_fail(e, line, col, MLIP_E_RANGE,
		                    "this move takes %g h at its feed of %g mm/s (length %g): at "
		                    "most %g h, as a dwell",
		                    len / v / 3600.0, v, len, MLIP_DWELL_MAX_S / 3600.0);
	}
	return MLIP_OK;
}
