/*
 * grbl.h - the Grbl 1.1 serial protocol (gnea/grbl doc/markdown/interface.md,
 * commands.md, jogging.md; the error and alarm tables of doc/csv), pure:
 * bytes in, lines and real-time commands out; every report and message
 * formatted into a caller's buffer. No I/O, no allocation, no clock: the
 * server (tools/mlip-grbl.c) owns the sockets, the ring and the time.
 *
 * Receiving (interface.md "Streaming Protocol: Character-Counting"): a
 * sender keeps at most GRBL_RX_SIZE bytes of lines it has not had an `ok` or
 * `error:` for. Real-time bytes (commands.md "Realtime commands") are picked
 * off as they arrive, wherever they are, and never stored; every other byte
 * goes to the line being assembled, or, while a complete line waits to be
 * processed, into the receive buffer. A byte that finds that buffer full is
 * a sender that did not count: Grbl drops it silently and the lines around
 * it merge into one that was never sent; here the line it belonged to is
 * dropped whole and answered (GRBL_LINE_LOST), so the answers stay one per
 * line and no line is ever run that the sender did not send. A line longer
 * than GRBL_LINE_MAX bytes is kept to that length and answered error:11.
 * Each CR or LF ends a line (an empty line is answered `ok`, as Grbl does).
 */
#ifndef MLIP_TOOLS_GRBL_H
#define MLIP_TOOLS_GRBL_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/gcode/gcode.h"
#include "mlip/types.h"

#define GRBL_VERSION   "1.1h"
#define GRBL_BUILD     "20190830"
#define GRBL_WELCOME   "Grbl " GRBL_VERSION " ['$' for help]"
#define GRBL_RX_SIZE   128 /* the receive buffer senders count against */
#define GRBL_LINE_MAX  255 /* longer lines: error:11 */
#define GRBL_RX_MARKS  8   /* lost-line marks beyond the buffer's bytes */
#define GRBL_MSG_BYTES 512 /* one formatted message or report, at most */

/* Grbl error codes used here (doc/csv/error_codes_en_US.csv). */
enum {
	GRBL_E_EXPECTED_LETTER = 1,
	GRBL_E_BAD_NUMBER = 2,
	GRBL_E_INVALID_STATEMENT = 3,
	GRBL_E_NEGATIVE = 4,
	GRBL_E_SETTING_DISABLED = 5,
	GRBL_E_IDLE = 8,
	GRBL_E_LOCK = 9,
	GRBL_E_OVERFLOW = 11,
	GRBL_E_TRAVEL = 15,
	GRBL_E_JOG = 16,
	GRBL_E_UNSUPPORTED = 20,
	GRBL_E_MODAL_GROUP = 21,
	GRBL_E_FEED = 22,
	GRBL_E_AXIS_CONFLICT = 24,
	GRBL_E_WORD_REPEATED = 25,
	GRBL_E_NO_AXIS_WORDS = 26,
	GRBL_E_VALUE_MISSING = 28,
	GRBL_E_G53 = 30,
	GRBL_E_UNUSED_AXIS = 31,
	GRBL_E_TARGET = 33,
	GRBL_E_ARC_RADIUS = 34,
	GRBL_E_NO_OFFSETS = 35,
	GRBL_E_UNUSED_WORDS = 36
};

/* Real-time commands (grbl/config.h CMD_*; commands.md). */
typedef enum {
	GRBL_RT_NONE = 0,
	GRBL_RT_RESET,         /* 0x18 ctrl-x */
	GRBL_RT_STATUS,        /* ? */
	GRBL_RT_CYCLE_START,   /* ~ */
	GRBL_RT_FEED_HOLD,     /* ! */
	GRBL_RT_SAFETY_DOOR,   /* 0x84 */
	GRBL_RT_JOG_CANCEL,    /* 0x85 */
	GRBL_RT_FEED_100,      /* 0x90 */
	GRBL_RT_FEED_PLUS_10,  /* 0x91 */
	GRBL_RT_FEED_MINUS_10, /* 0x92 */
	GRBL_RT_FEED_PLUS_1,   /* 0x93 */
	GRBL_RT_FEED_MINUS_1,  /* 0x94 */
	GRBL_RT_RAPID_100,     /* 0x95 */
	GRBL_RT_RAPID_50,      /* 0x96 */
	GRBL_RT_RAPID_25,      /* 0x97 */
	GRBL_RT_SPINDLE_100,   /* 0x99 */
	GRBL_RT_SPINDLE_PLUS_10,
	GRBL_RT_SPINDLE_MINUS_10,
	GRBL_RT_SPINDLE_PLUS_1,
	GRBL_RT_SPINDLE_MINUS_1, /* 0x9D */
	GRBL_RT_SPINDLE_STOP,    /* 0x9E */
	GRBL_RT_FLOOD,           /* 0xA0 */
	GRBL_RT_MIST,            /* 0xA1 */
	GRBL_RT_COUNT
} grbl_rt;

/* The real-time command of byte c, or GRBL_RT_NONE (then it is line data;
 * other bytes above 0x7F are line data too: the G-code reader refuses them
 * outside comments with their column). */
grbl_rt grbl_rt_of(unsigned char c);
const char *grbl_rt_name(grbl_rt rt);

/* Overrides as Grbl steps them (config.h DEFAULT_*_OVERRIDE, MAX/MIN, the
 * increments): feed and spindle 10..200 %, rapid 100/50/25. Returns the new
 * value for command rt applied to pct (pct itself when rt does not act on it). */
int grbl_override_step(grbl_rt rt, int pct);

typedef enum {
	GRBL_LINE_TEXT = 0, /* text, len bytes (no CR/LF) */
	GRBL_LINE_TOO_LONG, /* more than GRBL_LINE_MAX bytes: text holds the first ones */
	GRBL_LINE_LOST      /* lost to a receive-buffer overflow: lost lines */
} grbl_line_kind;

struct grbl_line {
	grbl_line_kind kind;
	const char *text;
	size_t len;
	uint32_t lost;     /* LOST: how many lines */
	uint32_t overflow; /* bytes the overflow dropped (LOST) */
};

/* The receiver: the line being assembled (or waiting) and the buffer behind it. */
struct grbl_rx {
	char line[GRBL_LINE_MAX + 1];
	size_t len;       /* bytes in line */
	int over;         /* the line went past GRBL_LINE_MAX */
	int ready;        /* line is complete and waits for grbl_rx_done */
	uint32_t lost;    /* ready line is a LOST mark of this many lines */
	uint32_t dropped; /* its bytes dropped */
	/* receive buffer: bytes (0..255) and lost-line marks (256 + count) */
	uint16_t buf[GRBL_RX_SIZE + GRBL_RX_MARKS];
	uint32_t head, tail; /* free-running indices */
	uint32_t bytes;      /* data bytes in buf (marks not counted) */
	uint32_t marks;      /* marks in buf */
	int dropping;        /* dropping the rest of an overflowed line */
	uint32_t drop_bytes; /* bytes dropped since the mark was made */
	uint64_t overflows;  /* bytes ever dropped */
	int lead;            /* a UTF-8 lead byte 0xC2 waits for the next byte */
};

void grbl_rx_init(struct grbl_rx *rx);
/* Take n bytes; each real-time command is passed to rt(ctx, cmd) in the
 * order it came, before the next byte is looked at. A real-time byte above
 * 0x7F written as UTF-8 text (0xC2 then the byte: CNCjs's JavaScript
 * strings) is that command, the 0xC2 dropped as Grbl drops every unknown
 * byte above 0x7F (serial.c); a 0xC2 before anything else is line data. */
void grbl_rx_feed(struct grbl_rx *rx, const unsigned char *b, size_t n,
                  void (*rt)(void *ctx, grbl_rt cmd), void *ctx);
/* The complete line waiting to be processed: 1 and *out, or 0. */
int grbl_rx_line(const struct grbl_rx *rx, struct grbl_line *out);
/* That line is answered: assemble the next one from the buffer. */
void grbl_rx_done(struct grbl_rx *rx);
/* Bytes a sender may still send (Bf's second value). */
uint32_t grbl_rx_available(const struct grbl_rx *rx);
/* Anything received and not answered (a partial line included). */
int grbl_rx_pending(const struct grbl_rx *rx);
/* Soft reset: forget everything received. */
void grbl_rx_reset(struct grbl_rx *rx);

/* ---- the `$` system lines (commands.md) -------------------------------- */

typedef enum {
	GRBL_SYS_HELP = 0, /* $ */
	GRBL_SYS_SETTINGS, /* $$ */
	GRBL_SYS_PARAMS,   /* $# */
	GRBL_SYS_GCODE,    /* $G */
	GRBL_SYS_INFO,     /* $I */
	GRBL_SYS_INFO_SET, /* $I=... */
	GRBL_SYS_STARTUP,  /* $N */
	GRBL_SYS_STARTUP_SET /* $Nx=line */,
	GRBL_SYS_CHECK,   /* $C */
	GRBL_SYS_UNLOCK,  /* $X */
	GRBL_SYS_HOME,    /* $H, $HX ... */
	GRBL_SYS_JOG,     /* $J=line (text: after the '=', as received) */
	GRBL_SYS_SLEEP,   /* $SLP */
	GRBL_SYS_RESTORE, /* $RST=$ / # / * */
	GRBL_SYS_SET,     /* $x=val: number, value */
	GRBL_SYS_BAD      /* not a system command: error (code) */
} grbl_sys_kind;

struct grbl_sys {
	grbl_sys_kind kind;
	int code;     /* BAD: the Grbl error */
	int number;   /* SET: setting number; STARTUP_SET: line number */
	double value; /* SET */
	char axis;    /* HOME: single axis letter, or 0 */
	size_t arg;   /* JOG, STARTUP_SET, INFO_SET: offset of the text after '=' in the raw line */
};

/* Classify a line starting with '$' as Grbl's system_execute_line does, on
 * the line as Grbl pre-parses it (spaces, control bytes and comments
 * removed, letters upper-cased). */
void grbl_sys_parse(const char *text, size_t len, struct grbl_sys *out);

/* ---- reports ------------------------------------------------------------- */

/* Grbl's axis order X Y Z A B C: index k of that order -> the machine axis
 * of that letter, or -1. n: values reported (3, or up to the last of A B C
 * the machine has). */
struct grbl_axes {
	int n;
	int of[MLIP_MAX_AXES];
};
void grbl_axes_of(const struct mlip_machine *m, struct grbl_axes *ax);

/* The status mask ($10) and units ($13) in force. */
struct grbl_fmt {
	int mask;   /* bit 0: MPos (1) or WPos (0); bit 1: Bf */
	int inches; /* $13 */
};

/* What one status report shows (values in machine axis order, mm). */
struct grbl_status {
	const char
	    *state; /* "Idle", "Run", "Hold:0", "Hold:1", "Jog", "Alarm", "Home", "Check", ... */
	double mpos[MLIP_MAX_AXES];
	double wco[MLIP_MAX_AXES];
	double feed_mm_min;
	double spindle_rpm;
	int ov_feed, ov_rapid, ov_spindle;
	int busy;                /* homing, cycle, hold, jog: the slow refresh counts */
	int bf_blocks;           /* Bf: planner blocks free */
	int bf_bytes;            /* Bf: receive buffer bytes free */
	uint32_t line;           /* Ln (0: not shown) */
	const char *pins;        /* Pn letters, "" or NULL: none */
	const char *accessories; /* A letters, "" or NULL: none */
};

/* When WCO and Ov are shown (grbl/report.c report_realtime_status; config.h
 * REPORT_WCO_REFRESH_* 30/10, REPORT_OVR_REFRESH_* 20/10): zero at a reset,
 * so the first report has WCO and the second Ov. */
struct grbl_refresh {
	int wco, ovr;
};
/* An offset changed: WCO in the next report. */
void grbl_refresh_wco(struct grbl_refresh *r);
/* An override or accessory changed: Ov in the next report (one later when
 * that one shows WCO). */
void grbl_refresh_ovr(struct grbl_refresh *r);

/* "<State|MPos:...|...>" without the line end; returns its length. */
size_t grbl_status_format(char *buf, size_t len, const struct grbl_status *s,
                          const struct grbl_axes *ax, const struct grbl_fmt *fmt,
                          struct grbl_refresh *refresh);

/* Axis values as Grbl prints them: comma-separated, 3 decimals in mm or 4
 * in inches ($13). */
size_t grbl_axis_values(char *buf, size_t len, const double *v, const struct grbl_axes *ax,
                        const struct grbl_fmt *fmt);

/* The limit switches and homing, as the machine has them (settings.md
 * $21..$25): from the controller's status (limit inputs mapped) and the
 * machine's configuration (HOME_* of each axis, mlip-grbl --config). */
struct grbl_homing {
	int hard_limits; /* $21: a limit switch input is mapped */
	int enabled;     /* $22: an axis has a HOME_METHOD ($23..$25 listed then) */
	int dir_mask;    /* $23: bit k of Grbl's X Y Z A B C: homes toward negative */
	double feed_mm_min, seek_mm_min; /* $24 (latch), $25 (search): the slowest axis' */
};

/* The `$$` lines for machine m, one "$n=v" per call: index 0, 1, ... ;
 * returns the line's length, 0 after the last. h: NULL, no limits nor
 * homing. */
size_t grbl_setting_line(char *buf, size_t len, const struct mlip_machine *m,
                         const struct grbl_fmt *fmt, const struct grbl_homing *h, int index);

/* The `$G` line "[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]" of parser g;
 * program: 0 none, or 0/2/30 for M0/M2/M30 when active (-1: none). */
size_t grbl_gcode_state(char *buf, size_t len, const struct mlip_gcode *g, int program);

/* The `$#` lines, index 0, 1, ...; 0 after the last. tlo_mm: the tool
 * length offset in force (G43, G43.1; 0 with G49). */
size_t grbl_param_line(char *buf, size_t len, const struct mlip_gcode_offsets *o, double tlo_mm,
                       const struct grbl_axes *ax, const struct grbl_fmt *fmt, int index);

/* The work coordinate offset in force (coordinate system + G92, and on
 * axis z the tool length offset, as report.c adds it; z < 0: none), machine
 * axis order: WPos = MPos - WCO. */
void grbl_wco(const struct mlip_gcode_offsets *o, int n_axes, int z, double tlo_mm, double *wco);

/* The Grbl error code for a G-code reader error (by what it says: the
 * reader's messages are the contract, tests/unit/test_grbl.c checks each
 * kind); jog: the line was a $J= jog (a soft limit is then error:15). */
int grbl_error_code(const struct mlip_gcode_error *e, int jog);
/* The reader's error is a target beyond the soft limits (a G-code line:
 * Grbl's ALARM:2, not an error). */
int grbl_error_travel(const struct mlip_gcode_error *e);

/* Keep a message printable inside "[MSG:...]": no CR/LF, no ']' (Grbl's
 * message grammar ends at the first ']'), ASCII only. */
void grbl_msg_clean(char *s);

#endif
