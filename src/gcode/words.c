/*
 * words.c - step 2 of a line: words -> one block description (struct blk):
 * G and M codes by modal group (LinuxCNC's table of modal groups), axis and
 * arc words, F, P, Q, L, the notices; every word checked alone.
 */
#include <math.h>
#include <string.h>

#include "gc.h"

enum gkind {
	GK_MOTION,   /* G0..G3 */
	GK_PLANE,    /* G17..G19 */
	GK_UNITS,    /* G20/G21 */
	GK_DIST,     /* G90/G91 */
	GK_HOME,     /* G28/G30 */
	GK_G53,      /* machine coordinates for this line */
	GK_DWELL,    /* G4 */
	GK_G10,      /* G10 L2 / L20 */
	GK_HOMESET,  /* G28.1/G30.1 */
	GK_COORD,    /* G54..G59.3 */
	GK_PATH,     /* G61, G61.1, G64 */
	GK_G92,      /* G92, G92.1, G92.2, G92.3 */
	GK_FEEDMODE, /* G93/G94 */
	GK_TOOLLEN,  /* G43, G43.1, G49 */
	GK_PROBE,    /* G38.2..G38.5 (io.c) */
	GK_CYCLE,    /* G73, G81..G83, G85, G89 (cycle.c) */
	GK_G80,      /* cancel the canned cycle */
	GK_RETRACT,  /* G98/G99 */
	GK_NOTICE,   /* accepted, no effect on motion */
	GK_SILENT,   /* accepted, it is what mlip does anyway (G91.1) */
	GK_UNSUP
};

/* modal groups, to refuse two codes of one group on a line */
enum {
	GR_NONE,
	GR_MOTION,
	GR_PLANE,
	GR_UNITS,
	GR_DIST,
	GR_NONMODAL,
	GR_FEEDMODE,
	GR_CUTTER,
	GR_TOOLLEN,
	GR_COORD,
	GR_PATH,
	GR_ARCDIST,
	GR_RETRACT,
	GR_N
};

/* G codes by value*10, as ranges [lo, hi] */
struct gdef {
	short lo, hi;
	unsigned char kind, group;
	const char *why; /* GK_UNSUP: what it is, for the message */
};

static const struct gdef gtab[] = {
    {0, 30, GK_MOTION, GR_MOTION, 0},
    {170, 190, GK_PLANE, GR_PLANE, 0},
    {200, 210, GK_UNITS, GR_UNITS, 0},
    {280, 280, GK_HOME, GR_NONMODAL, 0},
    {300, 300, GK_HOME, GR_NONMODAL, 0},
    {400, 400, GK_NOTICE, GR_CUTTER, 0},
    {430, 431, GK_TOOLLEN, GR_TOOLLEN, 0},
    {490, 490, GK_TOOLLEN, GR_TOOLLEN, 0},
    {530, 530, GK_G53, GR_NONMODAL, 0},
    {40, 40, GK_DWELL, GR_NONMODAL, 0},
    {100, 100, GK_G10, GR_NONMODAL, 0},
    {281, 281, GK_HOMESET, GR_NONMODAL, 0},
    {301, 301, GK_HOMESET, GR_NONMODAL, 0},
    {540, 540, GK_COORD, GR_COORD, 0},
    {550, 550, GK_COORD, GR_COORD, 0},
    {560, 560, GK_COORD, GR_COORD, 0},
    {570, 570, GK_COORD, GR_COORD, 0},
    {580, 580, GK_COORD, GR_COORD, 0},
    {590, 593, GK_COORD, GR_COORD, 0},
    {610, 611, GK_PATH, GR_PATH, 0},
    {640, 640, GK_PATH, GR_PATH, 0},
    {920, 923, GK_G92, GR_NONMODAL, 0},
    {930, 940, GK_FEEDMODE, GR_FEEDMODE, 0},
    {800, 800, GK_G80, GR_MOTION, 0},
    {730, 730, GK_CYCLE, GR_MOTION, 0},
    {810, 830, GK_CYCLE, GR_MOTION, 0},
    {850, 850, GK_CYCLE, GR_MOTION, 0},
    {890, 890, GK_CYCLE, GR_MOTION, 0},
    {980, 990, GK_RETRACT, GR_RETRACT, 0},
    {900, 900, GK_DIST, GR_DIST, 0},
    {910, 910, GK_DIST, GR_DIST, 0},
    {911, 911, GK_SILENT, GR_ARCDIST, 0},
    {50, 53, GK_UNSUP, 0, "splines"},
    {70, 80, GK_UNSUP, 0, "lathe diameter/radius mode"},
    {330, 331, GK_UNSUP, 0, "spindle-synchronized motion"},
    {760, 760, GK_UNSUP, 0, "threading cycle"},
    {382, 385, GK_PROBE, GR_MOTION, 0},
    {410, 421, GK_UNSUP, 0, "cutter radius compensation"},
    {432, 432, GK_UNSUP, 0, "an additional tool length offset (G43.2)"},
    {520, 520, GK_UNSUP, 0, "local offsets (use G92 or G10 L2)"},
    {840, 840, GK_UNSUP, 0, "tapping cycle (the spindle reversed at the bottom)"},
    {860, 880, GK_UNSUP, 0, "boring cycles that stop or orient the spindle"},
    {901, 901, GK_UNSUP, 0, "absolute arc centers"},
    {950, 950, GK_UNSUP, 0, "feed per revolution"},
    {960, 970, GK_UNSUP, 0, "constant surface speed"},
};

static const struct gdef *gfind(int code10)
{
	size_t k;

	for (k = 0; k < sizeof gtab / sizeof gtab[0]; k++) {
		/* motion and plane ranges hold whole codes only */
		if (code10 >= gtab[k].lo && code10 <= gtab[k].hi &&
		    !((gtab[k].kind <= GK_UNITS || gtab[k].kind == GK_FEEDMODE ||
		       gtab[k].kind == GK_CYCLE || gtab[k].kind == GK_RETRACT) &&
		      code10 % 10)) {
			return &gtab[k];
		}
	}
	return 0;
}

/* M codes that cannot be ignored, and why (LinuxCNC's meanings); every
 * other whole M code up to M199 is a notice: no effect on motion (spindle,
 * coolant, tool change, overrides, user M codes, printer fans, ...). */
static const char *m_refused(int code10)
{
	int m = code10 / 10;

	if (code10 % 10 || m > 199) {
		return "";
	}
	if (m == 98 || m == 99) {
		return ": subprogram calls (have the CAM expand them)";
	}
	if (m >= 66 && m <= 68) {
		return ": a wait for an input, or an analog output";
	}
	if (m >= 70 && m <= 73) {
		return ": saving and restoring the modal state";
	}
	return 0;
}

int mlip_gc_code_of(double v)
{
	double t = floor(v * 10.0 + 0.5);

	if (v < 0 || t > 10000 || fabs(v * 10.0 - t) > 1e-6) {
		return -1;
	}
	return (int)t;
}

/* Everything one line says, each word checked alone. */

static void word_text(char *w, char letter, int code10);

static void note_word(struct blk *b, char letter, int code10)
{
	word_text(b->notes[b->n_notes++], letter, code10);
}

/* An I/O word: a notice when the reader has no machine I/O (io.c). */
static void note_io(struct blk *b, char letter, int code10)
{
	word_text(b->io_notes[b->n_io_notes++], letter, code10);
}

static void word_text(char *w, char letter, int code10)
{
	int k = 0;

	w[k++] = letter;
	if (code10 >= 0) { /* at most "G61.1" or "M199" (code10 < 10000): fits */
		if (code10 >= 1000) {
			w[k++] = (char)('0' + code10 / 1000 % 10);
		}
		if (code10 >= 100) {
			w[k++] = (char)('0' + code10 / 100 % 10);
		}
		w[k++] = (char)('0' + code10 / 10 % 10);
		if (code10 % 10) {
			w[k++] = '.';
			w[k++] = (char)('0' + code10 % 10);
		}
	}
	w[k] = '\0';
}

static mlip_status classify_g(const struct word *w, uint32_t line, struct blk *b, int *group_code,
                              struct mlip_gcode_error *e)
{
	int c = mlip_gc_code_of(w->value);
	const struct gdef *d = c >= 0 ? gfind(c) : 0;

	if (c < 0) {
		return mlip_gc_fail(e, line, w->col, MLIP_E_UNSUPPORTED, "unsupported G code G%f",
		                    w->value);
	}
	if (!d || d->kind == GK_UNSUP) {
		return mlip_gc_fail(e, line, w->col, MLIP_E_UNSUPPORTED,
		                    "unsupported G code %G%s%s", c, d ? ": " : "", d ? d->why : "");
	}
	if (d->group != GR_NONE && group_code[d->group] >= 0 && group_code[d->group] != c) {
		return mlip_gc_fail(e, line, w->col, MLIP_E_SYNTAX,
		                    d->group == GR_MOTION
		                        ? "two motion codes on one line: %G and %G"
		                        : "%G and %G on one line: same modal group",
		                    group_code[d->group], c);
	}
	group_code[d->group] = c;
	switch (d->kind) {
	case GK_MOTION:
		b->motion = c / 10;
		b->motion_col = w->col;
		break;
	case GK_PLANE:
		b->plane = c / 10;
		break;
	case GK_UNITS:
		b->units = c / 10;
		break;
	case GK_DIST:
		b->dist = c / 10;
		break;
	case GK_HOME:
		b->home = c / 10;
		b->home_col = w->col;
		break;
	case GK_G53:
		b->g53 = 1;
		b->g53_col = w->col;
		break;
	case GK_DWELL:
		b->g4 = 1;
		b->g4_col = w->col;
		break;
	case GK_G10:
		b->g10 = 1;
		b->g10_col = w->col;
		break;
	case GK_HOMESET:
		b->homeset = c / 10;
		b->homeset_col = w->col;
		break;
	case GK_COORD:
		b->coord = c < 590 ? c / 10 - 54 : 5 + c % 10;
		break;
	case GK_PATH:
		b->path = c;
		b->g64 = c == 640;
		break;
	case GK_G92:
		b->g92 = c;
		b->g92_col = w->col;
		break;
	case GK_FEEDMODE:
		b->feedmode = c / 10;
		break;
	case GK_TOOLLEN:
		b->g43 = c;
		b->g43_col = w->col;
		if (c == 490) {
			note_io(b, 'G', c);
		}
		break;
	case GK_CYCLE:
		b->cycle = c / 10;
		b->motion_col = w->col;
		break;
	case GK_G80:
		b->g80 = 1;
		b->motion_col = w->col;
		break;
	case GK_RETRACT:
		b->retract = c / 10;
		break;
	case GK_PROBE:
		b->probe = c;
		b->motion_col = w->col;
		note_io(b, 'G', c);
		break;
	case GK_NOTICE:
		note_word(b, 'G', c);
		break;
	default:
		break;
	}
	return MLIP_OK;
}

static mlip_status classify_params(const struct blk *b, uint32_t line, struct mlip_gcode_error *e);

mlip_status mlip_gc_classify(const struct lexed *lx, uint32_t line, struct blk *b,
                             struct mlip_gcode_error *e)
{
	int group_code[GR_N], k, a, c;
	uint32_t seen[26] = {0}; /* column of the first word of each letter */
	mlip_status st;

	memset(b, 0, sizeof *b);
	b->motion = -1;
	b->coord = -1;
	for (k = 0; k < GR_N; k++) {
		group_code[k] = -1;
	}
	for (k = 0; k < lx->n; k++) {
		const struct word *w = &lx->w[k];
		char L = w->letter;

		if (!seen[L - 'A']) {
			seen[L - 'A'] = w->col;
		} else if (L != 'G' && L != 'M' && L != 'N') {
			return mlip_gc_fail(e, line, w->col, MLIP_E_SYNTAX,
			                    "duplicate %c word (first at column %u)", L,
			                    seen[L - 'A']);
		}
		switch (L) {
		case 'G':
			st = classify_g(w, line, b, group_code, e);
			if (st != MLIP_OK) {
				return st;
			}
			break;
		case 'M':
			c = mlip_gc_code_of(w->value);
			if (c < 0) {
				return mlip_gc_fail(e, line, w->col, MLIP_E_UNSUPPORTED,
				                    "unsupported M code M%f", w->value);
			}
			if (m_refused(c)) {
				return mlip_gc_fail(e, line, w->col, MLIP_E_UNSUPPORTED,
				                    "unsupported M code %M%s", c, m_refused(c));
			}
			if (c == 0 || c == 10 || c == 600) {
				b->pause = c == 10 ? 2 : 1;
				if (c == 600) {
					note_word(b, 'M', c);
				}
			} else if (c == 20 || c == 300) {
				b->end = 1;
				b->end_col = w->col;
				note_word(b, 'M', c);
			} else if (c == 30 || c == 40 || c == 50) {
				/* modal group 7 (LinuxCNC): one of them a line */
				if (b->spindle_m) {
					return mlip_gc_fail(
					    e, line, w->col, MLIP_E_SYNTAX,
					    "M%u and M%u on one line: same modal group (spindle)",
					    (unsigned)b->spindle_m, (unsigned)(c / 10));
				}
				b->spindle_m = c / 10;
				b->spindle_col = w->col;
				note_io(b, 'M', c);
			} else if (c == 60 || c == 610) {
				/* modal group 6: M6 or M61 */
				if (b->m6 || b->m61) {
					return mlip_gc_fail(
					    e, line, w->col, MLIP_E_SYNTAX,
					    "M6 and M61 on one line: same modal group "
					    "(tool change)");
				}
				b->m6 = c == 60;
				b->m61 = c == 610;
				b->m6_col = b->m61_col = w->col;
				note_io(b, 'M', c);
			} else if (c == 620 || c == 630 || c == 640 || c == 650) {
				/* M62/M63/M64/M65 Pn: one a line (they share the P word) */
				if (b->dout) {
					return mlip_gc_fail(e, line, w->col, MLIP_E_SYNTAX,
					                    "M%u and M%u on one line: one output "
					                    "word a line (they share P)",
					                    (unsigned)b->dout, (unsigned)(c / 10));
				}
				b->dout = c / 10;
				b->dout_col = w->col;
				note_io(b, 'M', c);
			} else if (c == 70 || c == 80 || c == 90) {
				/* group 8: M7 and M8 together turn both on; M9 alone */
				if ((c == 90 && b->coolant_m) || (c != 90 && b->m9)) {
					return mlip_gc_fail(e, line, w->col, MLIP_E_SYNTAX,
					                    "M9 with M7 or M8 on one line: coolant "
					                    "off and on at once");
				}
				note_io(b, 'M', c);
				if (c == 90) {
					b->m9 = 1;
					b->m9_col = w->col;
				} else {
					b->coolant_m |=
					    c == 70 ? MLIP_COOLANT_MIST : MLIP_COOLANT_FLOOD;
					b->coolant_col = b->coolant_col ? b->coolant_col : w->col;
				}
			} else {
				note_word(b, 'M', c);
			}
			break;
		case 'X':
		case 'Y':
		case 'Z':
		case 'A':
		case 'B':
		case 'C':
			a = mlip_gc_axis_slot(L);
			b->has_ax[a] = 1;
			b->ax[a] = w->value;
			b->ax_col[a] = w->col;
			break;
		case 'I':
		case 'J':
		case 'K':
			b->has_ijk[L - 'I'] = 1;
			b->ijk[L - 'I'] = w->value;
			b->ijk_col[L - 'I'] = w->col;
			break;
		case 'R':
			b->has_r = 1;
			b->r = w->value;
			b->r_col = w->col;
			break;
		case 'F':
			if (!(w->value > 0)) {
				return mlip_gc_fail(e, line, w->col, MLIP_E_RANGE,
				                    "feed F must be positive");
			}
			b->has_f = 1;
			b->f = w->value;
			b->f_col = w->col;
			break;
		case 'P':
			b->has_p = 1;
			b->p = w->value;
			b->p_col = w->col;
			break;
		case 'Q':
			b->has_q = 1;
			b->q = w->value;
			b->q_col = w->col;
			break;
		case 'L':
			b->has_l = 1;
			b->l = w->value;
			b->l_col = w->col;
			break;
		case 'S':
			b->has_s = 1;
			b->s = w->value;
			b->s_col = w->col;
			note_io(b, 'S', -1);
			break;
		case 'T':
			b->has_t = 1;
			b->t = w->value;
			b->t_col = w->col;
			note_io(b, 'T', -1);
			break;
		case 'H':
			b->has_h = 1;
			b->h = w->value;
			b->h_col = w->col;
			break;
		case 'N':
			break; /* line numbers: ignored */
		case 'U':
		case 'V':
		case 'W':
			return mlip_gc_fail(e, line, w->col, MLIP_E_UNSUPPORTED,
			                    "axis %c not supported: mlip axes are X Y Z A B C", L);
		default:
			return mlip_gc_fail(e, line, w->col, MLIP_E_SYNTAX,
			                    "unknown word letter %c", L);
		}
	}
	return classify_params(b, line, e);
}

/* P, Q, L and R words against the codes that take them (LinuxCNC's rules). */
static mlip_status classify_params(const struct blk *b, uint32_t line, struct mlip_gcode_error *e)
{
	int n = (b->g4 != 0) + (b->g10 != 0) + (b->g64 != 0) + (b->dout != 0);

	/* P alone may be an arc's number of turns: checked with the line's
	 * motion (gcode.c) */
	if (b->has_p && n > 1) {
		return mlip_gc_fail(
		    e, line, b->p_col, MLIP_E_SYNTAX,
		    "P word with two of G4, G10, G64, M64/M65: put them on separate lines");
	}
	if (b->dout && !b->has_p) {
		return mlip_gc_fail(e, line, b->dout_col, MLIP_E_SYNTAX,
		                    "M%u without P: give the output number, e.g. M%u P0",
		                    (unsigned)b->dout, (unsigned)b->dout);
	}
	if (b->dout && !(b->p >= 0 && b->p < MLIP_DOUT_MAX && b->p == floor(b->p))) {
		return mlip_gc_fail(e, line, b->p_col, MLIP_E_RANGE,
		                    "M%u P%g: the output number is a whole number 0..%u",
		                    (unsigned)b->dout, b->p, (unsigned)(MLIP_DOUT_MAX - 1));
	}
	/* Q without G64 or M61, L without G10: a canned cycle's (gcode.c) */
	if (b->has_q && b->g64 && b->m61) {
		return mlip_gc_fail(e, line, b->q_col, MLIP_E_SYNTAX,
		                    "Q word with both G64 and M61: put them on separate lines");
	}
	if (b->m61 && !b->has_q) {
		return mlip_gc_fail(e, line, b->m61_col, MLIP_E_SYNTAX,
		                    "M61 without Q: give the tool in the spindle, e.g. M61 Q2");
	}
	if (b->has_h && b->g43 != 430) {
		return mlip_gc_fail(e, line, b->h_col, MLIP_E_SYNTAX, "H word without G43");
	}
	if (b->g4 && !b->has_p) {
		return mlip_gc_fail(e, line, b->g4_col, MLIP_E_SYNTAX,
		                    "G4 without P: write the dwell in seconds, e.g. G4 P0.5");
	}
	if (b->g4 && !(b->p >= 0)) {
		return mlip_gc_fail(e, line, b->p_col, MLIP_E_RANGE, "G4 P must be >= 0 seconds");
	}
	if (b->g4 && !(b->p <= MLIP_DWELL_MAX_S)) {
		return mlip_gc_fail(e, line, b->p_col, MLIP_E_RANGE,
		                    "G4 P%g: a dwell of at most %g s (a day), in seconds", b->p,
		                    MLIP_DWELL_MAX_S);
	}
	if (b->g64 && b->has_p && !(b->p >= 0)) {
		/* LinuxCNC: P is the path tolerance, a distance */
		return mlip_gc_fail(e, line, b->p_col, MLIP_E_RANGE,
		                    "G64 P%g: the path tolerance must be >= 0", b->p);
	}
	if (b->g10) {
		if (!b->has_l || (b->l != 2 && b->l != 20)) {
			return mlip_gc_fail(
			    e, line, b->has_l ? b->l_col : b->g10_col, MLIP_E_UNSUPPORTED,
			    "G10 without L2 or L20: only work offsets can be set (the tool table "
			    "is a file: edit it, then mlip-tools --accept FILE)");
		}
		if (!b->has_p || b->p != floor(b->p) || b->p < 0 || b->p > 9) {
			return mlip_gc_fail(
			    e, line, b->has_p ? b->p_col : b->g10_col, MLIP_E_SYNTAX,
			    "G10 L%u needs P0..P9 (0: the system in use, 1..9: G54..G59.3)",
			    (unsigned)b->l);
		}
		if (b->has_r) {
			return mlip_gc_fail(e, line, b->r_col, MLIP_E_UNSUPPORTED,
			                    "G10 R (rotated coordinate system) not supported");
		}
	}
	if (b->g53 && b->dist == 91) {
		return mlip_gc_fail(e, line, b->g53_col, MLIP_E_SYNTAX,
		                    "G53 with G91: machine coordinates must be absolute");
	}
	return MLIP_OK;
}
