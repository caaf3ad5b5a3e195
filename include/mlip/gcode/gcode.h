/*
 * mlip/gcode/gcode.h - G-code front end: text in, joint-space blocks out.
 *
 * Pure: reads a line from a buffer, never a file; no allocation, no I/O.
 * The caller feeds a program line by line (mlip_gcode_line), then calls
 * mlip_gcode_finish. Every error names line and column (1-based column of
 * the offending character). After an error on a line the parser continues
 * with the next line, so a caller can list every error of a file; a program
 * with any error must be rejected as a whole (the tools do that).
 *
 * Supported (docs/gcode.md has the table, with the LinuxCNC or Grbl rule
 * each follows): G0/G1/G2/G3 (arcs in G17/G18/G19 with I J K or R, turned
 * into chords within a fraction of the contour tolerance), G4 P dwell,
 * G10 L2/L20, G20/G21, G28/G30 (+ .1), G53, G54-G59.3, G61/G61.1/G64 P Q,
 * G90/G91, G92/G92.1/G92.2/G92.3, G93/G94, M0/M1/M60 pauses, M2/M30 end,
 * F, comments in ( ) and after ';', '%' lines, N numbers, '/' block delete,
 * Grbl '$' system lines (skipped with a note, or errors: set_strict; a
 * "$J=" jog runs as a G1 move), Grbl's start-up G0 for axis words before
 * any motion mode. Lines after M2/M30 are not read; '%' delimits a program
 * as LinuxCNC: a '%' line before any other opens it, the next '%' line ends
 * it (later lines are not read), and a program opened by '%' that reaches
 * mlip_gcode_finish without its closing '%' or M2/M30 is refused (a file cut
 * short). Every block emitted keeps the rule set of mlip/types.h
 * (mlip_block_check): a dwell, a feed or a tolerance out of its range is an
 * error of its line, at the word to blame. G4, M0, M1 and M60
 * emit event blocks (kind DWELL, PAUSE, OPTIONAL_PAUSE) at the last point:
 * a line's dwell before its motion, its pause after.
 * Accepted without motion and reported once (see notices): G17-G19, G40,
 * G80 and other M codes that do not move. Everything else is an error.
 *
 * The machine's I/O (mlip_gcode_set_io; issue 19): S, M3/M4/M5, T, M6, M61,
 * G43 H / G43 / G43.1 Z / G49 and M7/M8/M9, checked against what the machine
 * has ([SPINDLE], [TOOL], [COOLANT] of the config, the tool table) and
 * executed in LinuxCNC's order (S, T, M6, M3/M4/M5, M7/M8/M9, then G4, the
 * modes, G43/G49, the offsets, the motion). What the machine must do emits
 * an event block at the last point: SPINDLE (M3/M4 with their S, an S
 * change while the spindle turns, M5), TOOL (M6 to a tool other than the one
 * in the spindle: the spindle stopped first, the axes of the change position
 * moved there by rapids in machine coordinates, Z first), COOLANT; M2/M30
 * stop the spindle and the coolant (LinuxCNC). A word the machine cannot
 * execute is an error at its column: M3/M4/S on a machine without a spindle,
 * S beyond MAX_RPM or (not 0) below MIN_RPM (refused, not clamped: the same
 * feed at a lower speed overloads the cutter, and the program is the place
 * to change it), M3/M4 with no S ever, M6 without a tool change or with no T,
 * a T, H or Q naming a tool not in the table, G43 with no tool, M7/M8
 * without coolant; unless the caller ignores that part on purpose (then a
 * notice). The tool length offset (G43: the table's Z of the tool; G43.1 Z:
 * the value) is added to Z in machine coordinates like a work offset (not to
 * G53 moves, as LinuxCNC), and every target is checked against the soft
 * limits with it. Without set_io (a pure motion check, a sender's stream) all
 * of these words are notices as before: nothing reaches a machine.
 *
 *
 * Coordinates: a program's X Y Z ... are in the selected work coordinate
 * system; targets are converted to machine coordinates (machine = program +
 * work offset + G92 offset, per axis, in config order) and the soft limits
 * are checked there. The offsets that outlive a program are in struct
 * mlip_gcode_offsets: the caller loads them before the first line and reads
 * them back after the last (the tools keep them in a file).
 */
#ifndef MLIP_GCODE_H
#define MLIP_GCODE_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/types.h"

#define MLIP_GCODE_MAX_LINE     256 /* longer lines are an error */
#define MLIP_GCODE_MSG          160
#define MLIP_GCODE_MAX_NOTICES  32
#define MLIP_GCODE_N_COORD      9 /* G54..G59, G59.1..G59.3 */
/* points closer than this to the previous one are merged (mlip/types.h) */
#define MLIP_GCODE_MERGE_MM     MLIP_MERGE_MM
/* chord sagitta allowed when turning an arc into chords, as a fraction of
 * the contour tolerance; the corner between chords gets the rest */
#define MLIP_GCODE_ARC_FRACTION 0.1

struct mlip_gcode_error {
	uint32_t line;            /* 1-based */
	uint32_t col;             /* 1-based; 0 when the error concerns the whole line/file */
	char msg[MLIP_GCODE_MSG]; /* one line, no trailing newline */
};

/* A word accepted but with no effect on motion, reported once. */
struct mlip_gcode_notice {
	char word[8]; /* e.g. "M3", "S", "G54", "T" */
	uint32_t first_line;
	uint32_t count;
	const char *text; /* what it means (static), or NULL: mlip_gcode_notice_text's */
};

/* Called for every block produced; return non-zero to abort parsing (the
 * line then fails with MLIP_E_FULL). */
typedef int (*mlip_block_sink)(void *ctx, const struct mlip_block *b);

/* What a spindle, a tool change or coolant is on this machine. */
typedef enum {
	MLIP_IO_NONE = 0, /* the machine has none: the words are refused */
	MLIP_IO_MANUAL,   /* the operator does it: the program pauses at rest */
	MLIP_IO_MODULE,   /* outputs of the CiA 401 I/O module (coolant: [COOLANT] TYPE = io) */
	MLIP_IO_CIA402    /* a CiA 402 drive on the bus (spindle) */
} mlip_io_type;

/* One tool of the tool table (LinuxCNC's T P Z D columns), machine units. */
struct mlip_tool {
	int32_t number; /* T, 1.. (0 is "no tool", never in a table) */
	int32_t pocket; /* P */
	double z_mm;    /* Z: the length offset G43 applies */
	double d_mm;    /* D: the diameter (0 when not given) */
};

/* The machine's I/O as a program meets it. The tool table is the caller's
 * (kept alive while the reader is), sorted by number, numbers distinct. */
struct mlip_gcode_io {
	int spindle;             /* mlip_io_type */
	double min_rpm, max_rpm; /* S of a turning spindle within these (0 < min <= max) */
	int tool_change;         /* MLIP_IO_NONE or MLIP_IO_MANUAL */
	uint32_t change_mask;    /* bit i: axis i (config order) goes to change_pos[i] for M6 */
	double change_pos[MLIP_MAX_AXES]; /* machine coordinates */
	int coolant;                      /* MLIP_IO_NONE, MLIP_IO_MANUAL or MLIP_IO_MODULE */
	const struct mlip_tool *tools;    /* the tool table; NULL: none given */
	uint32_t n_tools;
	/* on purpose (--ignore-spindle, --ignore-coolant, --ignore-tools): the
	 * words are accepted and do nothing (a notice), G43 offsets are 0 */
	int ignore_spindle, ignore_coolant, ignore_tools;
	unsigned coolant_outlets; /* MODULE: the MLIP_COOLANT_* outlets mapped (M7 needs
	                             MIST, M8 FLOOD); ignored otherwise */
	uint32_t dout_mask;       /* bit n: digital output n (M64/M65 Pn) is mapped */
	int probe;                /* a probe input is mapped: G38.2..G38.5 run */
	/* read for a running controller (mlip-feed): a program may begin with a
	 * CiA 402 spindle an earlier MDI M3/M4 keeps turning (LinuxCNC: the
	 * spindle is modal); before its own M3/M4/M5 an S reaches it and an M6
	 * stops it, through the controller, which knows (mlip-sim: none turns) */
	int live;
};

/* The tool numbered n in io's table, or NULL. */
const struct mlip_tool *mlip_gcode_find_tool(const struct mlip_gcode_io *io, int32_t n);

/* State that outlives a program (LinuxCNC keeps it in its parameter file,
 * #5161-#5386); all in machine units (mm, degrees), config axis order. */
struct mlip_gcode_offsets {
	double coord[MLIP_GCODE_N_COORD][MLIP_MAX_AXES]; /* G54..G59.3 origins */
	double g92[MLIP_MAX_AXES];                       /* G92 offset values (#5211-) */
	int g92_on;                                      /* G92 offset applied (#5210) */
	int select;                /* selected system, 0 = G54 .. 8 = G59.3 (#5220) */
	double g28[MLIP_MAX_AXES]; /* G28 / G30 positions, machine coordinates */
	double g30[MLIP_MAX_AXES];
	int32_t tool; /* the tool in the spindle, 0: none (LinuxCNC #5400) */
};

/* Defaults: every offset zero, G54, G92 off, G28/G30 at each axis' HOME. */
void mlip_gcode_offsets_init(struct mlip_gcode_offsets *o, const struct mlip_machine *m);

/* "G54" .. "G59.3" for select 0..8 (static string). */
const char *mlip_gcode_coord_name(int select);

/* A program's parameters (LinuxCNC's: src/gcode/expr.c). Numbered #1..#5000
 * are the program's; #5001..MLIP_GCODE_PARAM_MAX the machine's state (read
 * only); named ones are set by the program (lower case, blanks removed). */
#define MLIP_GCODE_PARAMS    5000
#define MLIP_GCODE_PARAM_MAX 5602
#define MLIP_GCODE_NAMED     128
#define MLIP_GCODE_NAME_LEN  48
struct mlip_gcode_params {
	double num[MLIP_GCODE_PARAMS + 1];
	uint8_t set[MLIP_GCODE_PARAMS + 1]; /* set by this program (or these MDI lines) */
	uint32_t n_named;
	struct {
		char name[MLIP_GCODE_NAME_LEN];
		double value;
	} named[MLIP_GCODE_NAMED];
};

/* Modal state: fixed size, owned by the caller. Fields are private. */
struct mlip_gcode {
	const struct mlip_machine *m;
	double pos[MLIP_MAX_AXES]; /* last emitted point, machine units */
	double cur[MLIP_MAX_AXES]; /* programmed point (pos lags it by < MERGE) */
	double feed_mm_s;          /* current F, converted; <= 0: none yet */
	double feed_word;          /* current F as written, units/min (deg/min
	                              for rotary-only moves) */
	double initial_feed_word;  /* F used by feed moves before any F; <= 0:
	                              none, such a move is an error */
	int motion;                /* 0,1,2,3 or -1 before any (or in a canned cycle) */
	int cycle;                 /* canned cycle in effect: 73, 81, 82, 83, 85, 89; 0 none */
	int retract_r;             /* G99: a cycle retracts to R; 0: G98, to where it began */
	double cyc_r, cyc_z, cyc_q, cyc_p; /* the cycle's sticky R, Z (its plane's normal
	                                      axis), Q, P, as written */
	int cycle_off;                     /* G80 ended a cycle, no motion code since */
	int plane;                         /* 17, 18, 19 */
	int absolute;                      /* G90 = 1, G91 = 0 */
	int inches;                        /* G20 = 1 */
	uint32_t blocks;                   /* blocks emitted so far (events included) */
	uint32_t moves;                    /* of which moves */
	struct mlip_gcode_offsets off;
	int g53;          /* this line is in machine coordinates */
	int exact_stop;   /* G61/G61.1 in effect */
	double tol_mm;    /* corner tolerance of G64 [P] in effect */
	int inverse_time; /* G93 */
	int feed_reset;   /* F forgotten by a G93/G94 change */
	int ended;        /* M2/M30 or the closing '%' seen: later lines are not run */
	int percent;      /* the program opened with a '%' line */
	int content;      /* a line with words (or a '%') seen */
	int broken_rule;  /* the rule (mlip_block_check) a block of this line broke */
	int strict;       /* refuse Grbl conveniences ($ lines, G0 default) */
	uint32_t n_notices;
	struct mlip_gcode_notice notices[MLIP_GCODE_MAX_NOTICES];
	/* the machine's I/O (set_io); NULL: its words are notices */
	const struct mlip_gcode_io *io;
	double s_rpm;     /* S in force; < 0: never set */
	int spindle;      /* 0 stopped, 3 clockwise (M3), 4 counter-clockwise (M4) */
	int spindle_said; /* an M3/M4/M5 was read: `spindle` is the machine's (MDI lines:
	                     before one, an earlier MDI may have left it turning) */
	unsigned coolant; /* MLIP_COOLANT_* on */
	int32_t tool_sel; /* the last T (selected for M6); -1: none */
	double tlo_mm;    /* tool length offset on Z in force (G43, G43.1); 0: G49 */
	int tlo_mode;     /* 490 G49, 430 G43, 431 G43.1 */
	/* what a program without motion may still be (mlip_gcode_finish) */
	int mdi;                             /* lines typed at the machine (set_mdi) */
	struct mlip_gcode_offsets off_start; /* the offsets at the first line */
	/* probing (G38.2..G38.5) */
	uint32_t unknown;    /* bit i: axis i stands where a probe stopped it, known only
	                        when the program runs: every move must give it in
	                        absolute coordinates until one does */
	int probe_mode;      /* the motion mode is a G38 (382..385): axis words alone are
	                        refused */
	uint32_t probe_line; /* the line of the last G38 */
	struct mlip_gcode_params params; /* #1, #<name> (expr.c) */
};

/* The modal state one MDI command leaves for the next (LinuxCNC's
 * interpreter keeps it between MDI commands): the modes and words a line
 * sets for the lines after it. Not in it: the position (the machine's), the
 * offsets and the selected system (struct mlip_gcode_offsets, the offsets
 * file), and the spindle's and the coolant's on/off (the machine's state:
 * every run starts with them off, as a program does). Machine units where a
 * unit applies, except feed_word (as written, in the units of `inches`). */
struct mlip_gcode_modal {
	int motion;       /* G0..G3 as 0..3; -1: none yet; -2: none after a canned
	                     cycle (G80, or its MDI line ended): axis words alone refused */
	int plane;        /* 17, 18, 19 */
	int absolute;     /* G90 1, G91 0 */
	int inches;       /* G20 1, G21 0 */
	int inverse_time; /* G93 1, G94 0 */
	double feed_word; /* F as written (units/min); 0: none (G93: never kept) */
	int exact_stop;   /* G61/G61.1 1, G64 0 */
	double tol_mm;    /* G64 P tolerance in force, mm (0 < tol <= CONTOUR_TOLERANCE) */
	double s_rpm;     /* S; -1: none yet */
	int32_t tool_sel; /* T selected for M6; -1: none */
	int tlo_mode;     /* 490 G49, 430 G43, 431 G43.1 */
	double tlo_mm;    /* the tool length offset of G43/G43.1 (0 for G49) */
};

/* A program's modal state at its first line (motion none, G17 G90 G21 G94
 * G64 at the machine's tolerance, no F, S or T, G49). */
void mlip_gcode_modal_init(struct mlip_gcode_modal *md, const struct mlip_machine *m);

/* The modal state g has reached. */
void mlip_gcode_get_modal(const struct mlip_gcode *g, struct mlip_gcode_modal *md);

/* Continue from md (normally before the first line): MLIP_OK, or
 * MLIP_E_RANGE when a field is out of its range for machine m (g unchanged;
 * the state comes from a file). */
mlip_status mlip_gcode_set_modal(struct mlip_gcode *g, const struct mlip_gcode_modal *md);

/* Lines typed at the machine (MDI, on != 0): mlip_gcode_finish accepts
 * lines without motion (a G91, an F, M3, a G4 dwell: LinuxCNC runs them). */
void mlip_gcode_set_mdi(struct mlip_gcode *g, int on);

/* Start a program at the machine's home position. */
void mlip_gcode_init(struct mlip_gcode *g, const struct mlip_machine *m);

/* Parse one line (without its newline; len bytes, need not be NUL-terminated).
 * Emits zero or more blocks through sink. Returns MLIP_OK or an error code
 * with *err filled (line, column, message). */
mlip_status mlip_gcode_line(struct mlip_gcode *g, const char *text, size_t len, uint32_t lineno,
                            mlip_block_sink sink, void *ctx, struct mlip_gcode_error *err);

/* End of program: MLIP_E_SYNTAX "empty program: no motion" when no move was
 * ever emitted, unless the program changed the offsets (a touch-off, G10
 * L20, G92: its only effect, which the caller keeps) or the lines are MDI
 * (set_mdi). */
mlip_status mlip_gcode_finish(struct mlip_gcode *g, uint32_t last_line,
                              struct mlip_gcode_error *err);

/* 1 when the program's offsets differ from those it started with (G10, G92,
 * G54..G59.3, a touch-off): such a program without motion still runs. */
int mlip_gcode_offsets_changed(const struct mlip_gcode *g);

/* Let feed moves before the program's first F run at f_word (an F value, in
 * the units in effect at the move) instead of failing with "missing feed";
 * each such line is counted in the notice "F". Real files do this (they
 * rely on the F a previous job left behind); the tools pass the program's
 * first F (see mlip_gcode_scan_feed), which is the conservative choice.
 * f_word <= 0 restores the default: such a move is an error. */
void mlip_gcode_set_initial_feed(struct mlip_gcode *g, double f_word);

/* Strict mode (on != 0): Grbl '$' system lines and axis words before any
 * motion mode are errors, instead of a note ('$' line skipped; the axis words
 * move as G0, Grbl's start-up motion mode). */
void mlip_gcode_set_strict(struct mlip_gcode *g, int on);

/* The machine's I/O from the next line on (normally before the first);
 * io is kept (not copied) and must outlive g. NULL: the words are notices. */
void mlip_gcode_set_io(struct mlip_gcode *g, const struct mlip_gcode_io *io);

/* Offsets in force from the next line on (normally before the first). */
void mlip_gcode_set_offsets(struct mlip_gcode *g, const struct mlip_gcode_offsets *o);

/* What a notice means, for printing after its word: "ignored (no effect on
 * motion)", or what mlip did instead (G28/G30, F, G0, G64 P/Q, M2, M30, M60,
 * '/', the Grbl '$' lines). Static string. */
const char *mlip_gcode_notice_text(const struct mlip_gcode_notice *n);

/* Axis letters among X Y Z A B C used as words outside comments in a whole
 * program (len bytes), written NUL-terminated in the order XYZABC to letters
 * (room for 7). Returns how many; the caller decides whether 0 or 1 is enough. */
int mlip_gcode_scan_axes(const char *text, size_t len, char *letters);

/* The same per line (no comment spans lines): axis letters used are or'ed into
 * *axes (bit k for "XYZABC"[k]); returns the first positive F word's value of
 * the line, or 0. */
double mlip_gcode_scan_line(const char *text, size_t len, unsigned *axes);

/* The first positive F word outside comments in a whole program: its value
 * (as written) in *f_word; returns its 1-based line, or 0 when there is none.
 * Lines longer than MLIP_GCODE_MAX_LINE (errors) are passed over, as the
 * tools' bounded reader does. */
uint32_t mlip_gcode_scan_feed(const char *text, size_t len, double *f_word);

#endif
