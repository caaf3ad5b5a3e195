/*
 * gc.h - private to src/gcode/: what the steps of one line share (see
 * gcode.c for the steps). A line goes
 *   lex.c      bytes -> words (struct lexed)
 *   words.c    words -> one block description (struct blk), each word alone
 *   gcode.c    words against the machine and the modal state (struct plan),
 *              then the line executed in LinuxCNC's order
 *   modal.c    the modal state and the notices; the feed of a block
 *   offsets.c  G10, G92, G28.1/G30.1 and G28/G30
 *   arc.c      G2/G3 into chords
 *   emit.c     blocks out, soft limits
 *   io.c       S, T, M6, M3-M5, M7-M9, G43/G49: the tool and I/O words
 *   grblsys.c  Grbl's '$' system lines and "$J=" jogs
 *   scan.c     whole-program scans (no machine needed)
 */
#ifndef MLIP_GCODE_GC_H
#define MLIP_GCODE_GC_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/gcode/gcode.h"
#include "mlip/text/chars.h"

#define MAX_WORDS   (MLIP_GCODE_MAX_LINE / 2 + 1) /* a word takes two bytes at least */
#define MAX_CHORDS  1000000u
#define MAX_TURNS   1000000u /* G2/G3 P: more is past MAX_CHORDS anyway */
#define PI          3.14159265358979323846
#define MM_PER_INCH 25.4
#define GC_AXES     "XYZABC" /* axis words, in the order of struct blk's arrays */

/* Index of an axis letter in GC_AXES, or -1. */
static inline int mlip_gc_axis_slot(char c)
{
	int k;

	for (k = 0; k < 6; k++) {
		if (GC_AXES[k] == c) {
			return k;
		}
	}
	return -1;
}

static inline int mlip_gc_starts_number(int c)
{
	return mlip_is_digit(c) || c == '.' || c == '+' || c == '-';
}

/* ---- lex.c ---- */

struct word {
	char letter;  /* upper case */
	uint32_t col; /* 1-based column of the letter */
	double value;
};

/* A parameter setting "#n = value" or "#<name> = value" (expr.c): applied
 * after every value on its line was read (LinuxCNC). */
#define MAX_SETTINGS (MLIP_GCODE_MAX_LINE / 4 + 1) /* "#1=1" takes four bytes */
struct gc_setting {
	int num;                        /* 1..MLIP_GCODE_PARAMS, 0: named */
	char name[MLIP_GCODE_NAME_LEN]; /* named: lower case, blanks removed */
	double value;
	uint32_t col;
};

struct lexed {
	struct word w[MAX_WORDS];
	int n;
	struct gc_setting set[MAX_SETTINGS];
	int n_set;
	uint32_t first_col; /* first non-blank column, 0 for a blank line */
	int percent;        /* the line is a '%' delimiter (alone, comments aside) */
};

/* Fill *e and return st; fmt as mlip_tb_format (mlip/text/format.h). */
mlip_status mlip_gc_fail(struct mlip_gcode_error *e, uint32_t line, uint32_t col, mlip_status st,
                         const char *fmt, ...);
/* g: the reader whose parameters the values read (NULL: none, a Grbl jog). */
mlip_status mlip_gc_lex_line(struct mlip_gcode *g, const char *text, size_t len, uint32_t line,
                             struct lexed *lx, struct mlip_gcode_error *e);

/* ---- expr.c ---- */

#define MLIP_GC_N_FUNCTIONS 14
extern const char *const mlip_gc_functions[MLIP_GC_N_FUNCTIONS]; /* "ABS" .. "EXISTS" */

/* The number at t[j] into *v, *end past it (in_expr: a sign after it is an
 * operator, not a malformed number). */
mlip_status mlip_gc_number(const char *t, size_t n, size_t j, int in_expr, uint32_t line,
                           double *v, size_t *end, struct mlip_gcode_error *e);
/* A word's value at t[*pi]: a number, #parameter, [expression], unary
 * function, signed; *pi past it. */
mlip_status mlip_gc_real_value(struct mlip_gcode *g, const char *t, size_t n, size_t *pi,
                               uint32_t line, double *v, struct mlip_gcode_error *e);
/* A setting "#.. = value" at t[*pi] ('#') into lx->set. */
mlip_status mlip_gc_setting(struct mlip_gcode *g, const char *t, size_t n, size_t *pi,
                            uint32_t line, struct lexed *lx, struct mlip_gcode_error *e);
/* The line's settings, in order (the last of one parameter wins). */
mlip_status mlip_gc_apply_settings(struct mlip_gcode *g, const struct lexed *lx, uint32_t line,
                                   struct mlip_gcode_error *e);

/* ---- words.c ---- */

/* Everything one line says, each word checked alone. */
struct blk {
	int motion;                 /* G0..G3 on this line, -1 none */
	int plane, units, dist;     /* 0 when not on this line, else 17..19, 20/21, 90/91 */
	int home;                   /* 28 or 30, 0 none */
	int g53, g64, g4, g10, g92; /* g92: 920..923 (value*10), 0 none */
	int homeset;                /* 28 or 30 for G28.1/G30.1, 0 none */
	int coord;                  /* 0..8 for G54..G59.3, -1 none */
	int path;                   /* 610, 611, 640, 0 none */
	int feedmode;               /* 93, 94, 0 none */
	int pause;                  /* M0/M60: 1, M1: 2, 0 none */
	int end;                    /* M2/M30 */
	uint32_t motion_col, home_col, g53_col, g4_col, g10_col, g92_col, homeset_col, end_col;
	int has_ax[6];
	double ax[6]; /* as written, indexed like GC_AXES */
	uint32_t ax_col[6];
	int has_ijk[3];
	double ijk[3];
	uint32_t ijk_col[3];
	int has_r, has_f, has_p, has_q, has_l;
	double r, f, p, q, l;
	uint32_t r_col, p_col, q_col, l_col, f_col;
	char notes[MAX_WORDS][8]; /* notices to record once the line is accepted */
	int n_notes;
	/* the machine's I/O (io.c) */
	int has_s, has_t, has_h;
	double s, t, h;
	uint32_t s_col, t_col, h_col;
	int spindle_m;      /* 3, 4, 5 for M3/M4/M5, 0 none */
	int m6, m61;        /* M6, M61 on the line */
	unsigned coolant_m; /* M7: MLIP_COOLANT_MIST, M8: MLIP_COOLANT_FLOOD */
	int m9;
	int g43;     /* 430 G43, 431 G43.1, 490 G49, 0 none */
	int dout;    /* 64 M64, 65 M65 (output P on / off), 0 none */
	int probe;   /* 382..385 for G38.2..G38.5 (a motion: motion_col), 0 none */
	int cycle;   /* 73, 81, 82, 83, 85, 89: a canned cycle (a motion: motion_col), 0 none */
	int g80;     /* G80: the canned cycle cancelled */
	int retract; /* 98 or 99 (G98/G99), 0 none */
	uint32_t spindle_col, m6_col, m61_col, coolant_col, m9_col, g43_col, dout_col;
	char io_notes[MAX_WORDS][8]; /* those words in order: notices without set_io */
	int n_io_notes;
};

/* value*10 as an int when value is a non-negative multiple of 0.1, else -1 */
int mlip_gc_code_of(double v);
mlip_status mlip_gc_classify(const struct lexed *lx, uint32_t line, struct blk *b,
                             struct mlip_gcode_error *e);

/* ---- gcode.c ---- */

/* What the checks found out about a line, for its motion. */
struct plan {
	int motion;     /* in effect for this line, -1 none */
	int moves;      /* the line moves: axis words, or a center-only arc */
	int has_axes;   /* axis words on the line */
	int axis_use;   /* they are not motion: G10, G92, G28/G30 */
	int g0_default; /* they move as G0: no motion mode yet (Grbl) */
	int probe;      /* G38.2..G38.5 (382..385): a probe move (motion 1), 0 none */
	uint32_t mcol;  /* column to blame for the motion: its G word, else the line */
	int cycle;      /* the canned cycle this line runs (cycle.c), 0 none */
};

/* ---- modal.c ---- */

void mlip_gc_notice(struct mlip_gcode *g, const char *word, uint32_t line);
/* The same with its own text (a static string), e.g. "ignored on purpose". */
void mlip_gc_notice_text(struct mlip_gcode *g, const char *word, const char *text, uint32_t line);
/* Config index of the axis with that (upper-case) letter, or -1. */
int mlip_gc_axis_index(const struct mlip_machine *m, char letter);
void mlip_gc_commit_modal(struct mlip_gcode *g, const struct blk *b, const struct plan *pl,
                          uint32_t line);
mlip_status mlip_gc_block_feed(struct mlip_gcode *g, const struct plan *pl, const double *s,
                               const double *t, uint32_t line, double *feed_mm_s,
                               struct mlip_gcode_error *e);

/* ---- emit.c ---- */

/* What a line's blocks share, besides target and tolerance. */
struct emit_ctx {
	mlip_block_sink sink;
	void *ctx;
	uint32_t line;
	uint8_t rapid;
	double feed_mm_s;
	int dwell_pending; /* G4: its DWELL goes first, once the line is known good */
	double dwell_s;
	/* the line's I/O events (io.c), before its dwell, once the line is known
	 * good: kind MLIP_BLOCK_SPINDLE, _TOOL, _COOLANT, or IO_CHANGE (M6's moves
	 * to the change position) */
	struct {
		uint8_t kind;
		double value;
	} io[8];
	int n_io;
};
#define IO_CHANGE 255

int mlip_gc_flush_dwell(struct mlip_gcode *g, struct emit_ctx *c);
int mlip_gc_emit(struct mlip_gcode *g, struct emit_ctx *c, const double *t, double tol_mm);
int mlip_gc_emit_event(struct mlip_gcode *g, mlip_block_sink sink, void *ctx, uint32_t line,
                       mlip_block_kind kind, double dwell_s);
mlip_status mlip_gc_check_limits(const struct mlip_gcode *g, const double *t,
                                 const uint32_t *col_of, uint32_t line, int on_arc,
                                 struct mlip_gcode_error *e);

/* ---- arc.c ---- */

struct arc {
	int iu, iv;       /* config indices of the plane axes */
	double cu, cv;    /* center */
	double r0, r1;    /* radius at start and at end: a slight spiral, as LinuxCNC */
	double a0, sweep; /* start angle and signed sweep, rad; G3 > 0 */
	uint32_t n;       /* chords */
	double sag_mm;    /* sagitta of each chord */
};

mlip_status mlip_gc_arc_setup(const struct mlip_gcode *g, const struct blk *b, int motion,
                              double scale, const double *s, const double *t, uint32_t line,
                              uint32_t col, struct arc *a, struct mlip_gcode_error *e);
mlip_status mlip_gc_emit_arc(struct mlip_gcode *g, struct emit_ctx *ec, const struct arc *arc,
                             const double *s, const double *t, const uint32_t *col_of,
                             struct mlip_gcode_error *e);

/* A feed move's feed (G93: its length times F/60) against the rule set
 * of mlip/types.h, the error on the F word or the motion (arc: may be NULL). */
mlip_status mlip_gc_move_feed(const struct mlip_gcode *g, const struct blk *b,
                              const struct plan *pl, const double *s, const double *t,
                              const struct arc *arc, uint32_t line, double *feed_mm_s,
                              struct mlip_gcode_error *e);

/* ---- offsets.c ---- */

/* Work offset plus G92 offset of axis i: machine = program + this. */
double mlip_gc_offset_of(const struct mlip_gcode *g, int i);
void mlip_gc_set_offsets(struct mlip_gcode *g, const struct blk *b, double scale);
mlip_status mlip_gc_go_home(struct mlip_gcode *g, const struct blk *b, const struct plan *pl,
                            struct emit_ctx *ec, const double *t, const uint32_t *col_of,
                            uint32_t line, struct mlip_gcode_error *e);

/* ---- io.c ---- */

/* The line's I/O words against the machine (set_io) and the state, before
 * anything of the line is executed. */
mlip_status mlip_gc_check_io(const struct mlip_gcode *g, const struct blk *b, uint32_t line,
                             struct mlip_gcode_error *e);
/* Execute them (S, T, M6, M3/M4/M5, M7/M8/M9, in LinuxCNC's order), then
 * G43, G43.1, G49: the state now, the events (and M6's moves to the change
 * position) queued in ec->io, emitted by mlip_gc_flush_io once the line is
 * known good. */
void mlip_gc_exec_io(struct mlip_gcode *g, const struct blk *b, double scale, struct emit_ctx *ec);
/* The queued events at the last point: 0, or -1 when the sink refused one. */
int mlip_gc_flush_io(struct mlip_gcode *g, struct emit_ctx *ec);
/* M2/M30: the spindle and the coolant stop (events when they were on). */
mlip_status mlip_gc_end_io(struct mlip_gcode *g, mlip_block_sink sink, void *ctx, uint32_t line);
/* Config index of Z, or -1. */
int mlip_gc_z_index(const struct mlip_machine *m);
/* G38.2..G38.5 (pl->probe): checked, then a PROBE block toward t. */
mlip_status mlip_gc_probe(struct mlip_gcode *g, const struct blk *b, const struct plan *pl,
                          struct emit_ctx *ec, const double *s, const double *t,
                          const uint32_t *col_of, uint32_t line, struct mlip_gcode_error *e);

/* ---- cycle.c ---- */

/* The words of a line that runs a canned cycle (pl->cycle), against the
 * cycle and the sticky numbers (LinuxCNC's rules). */
mlip_status mlip_gc_cycle_check(const struct mlip_gcode *g, const struct blk *b,
                                const struct plan *pl, uint32_t line, struct mlip_gcode_error *e);
/* Its moves and dwells: every point checked against the limits before any
 * is emitted; the state (position, sticky numbers) after it. */
mlip_status mlip_gc_cycle(struct mlip_gcode *g, const struct blk *b, const struct plan *pl,
                          struct emit_ctx *ec, double scale, uint32_t line,
                          struct mlip_gcode_error *e);

/* ---- grblsys.c ---- */

mlip_status mlip_gc_system_line(struct mlip_gcode *g, const char *t, size_t len, size_t i0,
                                uint32_t line, mlip_block_sink sink, void *ctx,
                                struct mlip_gcode_error *e);

#endif
