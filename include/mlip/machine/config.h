/*
 * mlip/machine/config.h - machine configuration from an INI file in the spirit of
 * LinuxCNC's ([TRAJ], [AXIS_X], ...), parsed from a buffer.
 *
 * Pure: no allocation, no I/O; the caller reads the file. Unknown sections or
 * keys, missing required values, malformed numbers and non-positive limits are
 * errors naming line, column and key.
 *
 *   [TRAJ]
 *   COORDINATES = X Y Z        ; axis letters in output order, 2..6 of XYZABC
 *   MAX_LINEAR_VELOCITY = 200  ; mm/s, v_m
 *   MAX_ANGULAR_VELOCITY = 360 ; deg/s, rotary-only moves (optional, default 360)
 *   CONTOUR_TOLERANCE = 0.01   ; mm, eps
 *   PERIOD = 0.001             ; s, T (optional, default 0.001, 1e-4..0.1)
 *   LINEAR_UNITS = mm          ; optional, only mm ("inch" is refused)
 *   ANGULAR_UNITS = degree     ; optional, only degree
 *   LOOKAHEAD = 4096           ; blocks, power of two 2..MLIP_LOOKAHEAD (optional)
 *   JERK_PLAN = mean           ; how MAX_JERK is kept (optional, default mean): mean
 *                              ;   (the moving mean, in the period) or path (the
 *                              ;   path-speed plan, mlip/motion/pathrun.h: needs
 *                              ;   MAX_JERK on every axis; the tools refuse what it
 *                              ;   cannot run yet)
 *   [AXIS_X]                   ; one per letter of COORDINATES, no other
 *   TYPE = LINEAR              ; LINEAR or ANGULAR (optional: XYZ linear, ABC angular)
 *   MAX_VELOCITY = 200         ; mm/s or deg/s
 *   MAX_ACCELERATION = 1000    ; mm/s^2 or deg/s^2
 *   MIN_LIMIT = -1000          ; soft limits (optional, default -1e9/1e9)
 *   MAX_LIMIT = 1000
 *   HOME = 0                   ; start position (optional, default 0)
 *   CAN_NODE = 1               ; CANopen node id 1..127 (optional, default index+1)
 *   COUNTS_PER_UNIT = 1000     ; drive counts per mm or degree (optional, default 1000)
 *   MAX_JERK = 100000          ; mm/s^3 or deg/s^3 (optional, default none): every
 *                              ;   sample keeps it (mlip/motion/jerk.h)
 *   [CAN]                      ; optional, read by rt/ (mlip/can/canconf.h)
 *   PROFILE = cia402           ; cia402, packed or fd
 *   BITRATE = 1000000          ; bit/s, 10000..1000000
 *   DATA_BITRATE = 5000000     ; bit/s, 10000..12000000, >= BITRATE with fd
 *   SYNC_ID = 0x080            ; 11-bit ids 0..0x7FF, decimal or 0x hex;
 *   RPDO_BASE = 0x200          ;   RPDO_BASE + every CAN_NODE <= 0x7FF
 *   PACKED_BASE = 0x300
 *   FD_ID = 0x400
 *   STATUS_ID = 0x180
 *   [DRIVES]                   ; optional: CiA 402 drives (mlip_drives_config)
 *   ENABLE = 1                 ; 0 or 1: bring the drives up (also mlip-rt --drives)
 *   MASTER_NODE = 127          ; mlip's node id for its heartbeat, none of the CAN_NODEs
 *   HEARTBEAT_MS = 100         ; 1..65535 ms: producer time of drives and master
 *   HEARTBEAT_TIMEOUT_MS = 300 ; > HEARTBEAT_MS: a heartbeat older is lost (both ways)
 *   FOLLOWING_ERROR = 1        ; mm (deg): following error window 0x6065, per axis
 *   SDO_TIMEOUT_MS = 200       ; one SDO answer
 *   BOOT_TIMEOUT_MS = 3000     ; boot-up after NMT reset communication
 *   STATE_TIMEOUT_MS = 1000    ; one CiA 402 transition confirmed by the statusword
 *   [SPINDLE]                  ; optional (issue 19; docs/machine.md)
 *   TYPE = manual              ; none (default: M3/M4/S refused) or manual (the
 *                              ;   program pauses for the operator)
 *   MIN_RPM = 6000             ; rpm, 0..MAX_RPM (optional, default 0)
 *   MAX_RPM = 24000            ; rpm, > 0, required with manual; an S beyond is refused
 *   ; TYPE = cia402: a CiA 402 drive on the bus, profile velocity mode (3), with
 *   NODE = 5                   ; its node id, none of the axes', [IO] NODE, MASTER_NODE
 *   COUNTS_PER_REV = 4096      ; > 0: 0x60FF/0x606C counts per revolution
 *   ACCELERATION = 10000       ; rpm/s > 0: 0x6083/0x6084
 *   AT_SPEED_BAND = 480        ; rpm: at speed within this (default 2 % of MAX_RPM)
 *   AT_SPEED_TIMEOUT = 6       ; s: not at speed (or at rest) by then: a fault
 *                              ;   (default 2 MAX_RPM / ACCELERATION + 1; no shorter)
 *   BAND_TIME = 0.2            ; s: out of the band this long while cutting: a fault
 *   [TOOL]                     ; optional
 *   CHANGE = manual            ; none (default: M6 refused) or manual (pause: "insert
 *                              ;   tool n"); the tool table is a file (--tools FILE)
 *   CHANGE_Z = 50              ; optional change position, machine coordinates, per
 *   CHANGE_X = 0               ;   axis of COORDINATES, inside its soft limits; M6
 *                              ;   rapids there (Z first) before the pause
 *   [COOLANT]                  ; optional
 *   TYPE = manual              ; none (default: M7/M8 refused), manual, or io (the
 *                              ;   I/O module's outputs MIST / FLOOD, below)
 *
 * Syntax. Section names and keys are upper case and case-sensitive, as in
 * LinuxCNC; enumerated values are case-sensitive too. A line is blank, a
 * comment ('#' or ';' first), "[SECTION]" or "KEY = VALUE", with spaces or
 * tabs anywhere around the tokens. After a value, '#' or ';' starts a comment
 * only when preceded by a space or tab. Every section and key at most once;
 * sections in any order. Numbers are plain decimals, [+-]d[.d][e[+-]d]: no
 * units, no "nan"/"inf", no hex floats; integer keys take decimal digits or
 * 0x hex (a leading 0 is still decimal). The text must be UTF-8 (an initial
 * BOM is skipped) without NUL or control characters other than tab; lines end
 * in LF or CRLF and hold at most MLIP_CONFIG_MAX_LINE bytes. Columns count
 * bytes from 1; a tab is one column.
 *
 * Checks across keys, once the whole text is read: every letter of
 * COORDINATES has its [AXIS_L] and no other [AXIS_L] exists; MIN_LIMIT <
 * MAX_LIMIT; MIN_LIMIT <= HOME <= MAX_LIMIT; CAN_NODEs distinct; RPDO_BASE +
 * CAN_NODE <= 0x7FF; SYNC_ID != STATUS_ID and, with cia402, neither equal to
 * an RPDO id; with fd, DATA_BITRATE >= BITRATE. Such an error is placed on
 * whichever of the keys involved comes last in the file.
 *
 * Errors. MLIP_E_SYNTAX: bytes, lines, sections, keys, malformed values,
 * missing sections or keys. MLIP_E_RANGE: a value out of its range or
 * inconsistent with another. MLIP_E_UNSUPPORTED: units other than mm and
 * degree. A missing required key is reported at its section's header line
 * (column 0), a missing section at line 0 or at the COORDINATES letter that
 * needs it. Only the first error is reported.
 */
#ifndef MLIP_CONFIG_H
#define MLIP_CONFIG_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/can/canconf.h"
#include "mlip/gcode/gcode.h"
#include "mlip/types.h"

#define MLIP_CONFIG_MSG          256
#define MLIP_CONFIG_MAX_LINE     512  /* bytes per line, line ending excluded */
#define MLIP_CONFIG_PERIOD_MIN_S 1e-4 /* PERIOD range, inclusive */
#define MLIP_CONFIG_PERIOD_MAX_S 0.1
/* Largest values a machine may have (mlip_machine_check): beyond any real
 * machine, small enough that positions, speeds and drive counts computed
 * from them stay far from overflow and keep their precision in a double. */
#define MLIP_CONFIG_ACCEL_MAX    1e6  /* MAX_ACCELERATION, mm/s^2 or deg/s^2 (100 g) */
#define MLIP_CONFIG_JERK_MAX     1e9  /* MAX_JERK, mm/s^3 or deg/s^3 */
#define MLIP_CONFIG_VEL_MAX      1e5  /* MAX_VELOCITY, MAX_*_VELOCITY: mm/s or deg/s */
#define MLIP_CONFIG_LIMIT_MAX    1e9  /* |MIN_LIMIT|, |MAX_LIMIT|, |HOME|, mm or deg */
#define MLIP_CONFIG_COUNTS_MAX   1e7  /* COUNTS_PER_UNIT (0.1 nm per count) */
#define MLIP_CONFIG_TOL_MIN      1e-6 /* CONTOUR_TOLERANCE, mm: 1 nm */
/* COUNTS_PER_UNIT at least: 10 mm or 10 degrees per count (a full-step
 * motor on a rotary axis has 1.8); CONTOUR_TOLERANCE at most: the largest a
 * block may carry (mlip/types.h) */
#define MLIP_CONFIG_COUNTS_MIN   0.1
#define MLIP_CONFIG_TOL_MAX      MLIP_TOL_MAX_MM

struct mlip_config_error {
	uint32_t line; /* 1-based; 0 for a whole-file error (e.g. missing key) */
	uint32_t col;  /* 1-based; 0 when not applicable */
	char msg[MLIP_CONFIG_MSG];
};

/* [DRIVES] section: CiA 402 drives brought up, watched and shut down by
 * mlip-rt (rt/drives.c; docs/cia402.md). */
struct mlip_drives_config {
	int enable;                    /* ENABLE = 1 (or mlip-rt --drives); default 0 */
	uint8_t master_node;           /* MASTER_NODE: mlip's own node id, default 127 */
	uint32_t heartbeat_ms;         /* HEARTBEAT_MS: producer time, drives and master, 100 */
	uint32_t heartbeat_timeout_ms; /* HEARTBEAT_TIMEOUT_MS: consumer time both ways, 300 */
	double following_error;        /* FOLLOWING_ERROR: window 0x6065, mm or deg, 1.0 */
	uint32_t sdo_timeout_ms;       /* SDO_TIMEOUT_MS: one SDO answer, 200 */
	uint32_t boot_timeout_ms;      /* BOOT_TIMEOUT_MS: boot-up after reset, 3000 */
	uint32_t state_timeout_ms;     /* STATE_TIMEOUT_MS: one CiA 402 transition, 1000 */
};

/* Digital inputs on the bus (issue 18; mlip-rt reads them, src/canopen/io401.c
 * evaluates them). Each function is one bit of one object of one node,
 * mapped in the INI as NODE INDEX:SUB BIT HIGH|LOW:
 *   [IO]
 *   NODE = 10                    ; the CiA 401 I/O module's node id (optional)
 *   ESTOP = 10 0x6000:1 0 LOW    ; module input byte 1 bit 0, on when it reads 0
 *   HOLD = 10 0x6000:1 1 HIGH    ; feed hold (as mlip-ctl hold), on its rising edge
 *   CYCLE_START = 10 0x6000:1 2 HIGH  ; resume (as mlip-ctl resume), rising edge
 *   PROBE = 10 0x6000:1 3 HIGH
 *   [AXIS_X]
 *   LIMIT_NEG = 1 0x60FD:0 0 HIGH   ; a drive's digital inputs 0x60FD (CiA 402:
 *   LIMIT_POS = 1 0x60FD:0 1 HIGH   ; bit 0 negative limit, 1 positive, 2 home),
 *   HOME_SWITCH = 1 0x60FD:0 2 HIGH ; or any bit of the module
 * The module's inputs are 0x6000:1..8 (8 bits each), a drive's 0x60FD:0 (32
 * bits). LOW (active low) suits a normally closed contact: a broken wire
 * reads 0 and trips the function, as an E-stop circuit must. A node must be
 * [IO] NODE or an axis' CAN_NODE; one bit carries one function. */
enum {
	MLIP_IN_ESTOP = 0,
	MLIP_IN_HOLD,
	MLIP_IN_CYCLE_START,
	MLIP_IN_PROBE,
	MLIP_IN_AXIS0 /* axis k (machine order): + 3k limit neg, + 3k + 1 limit pos, + 3k + 2 home
	               */
};
#define MLIP_IN_LIMIT_NEG(k) (MLIP_IN_AXIS0 + 3 * (k))
#define MLIP_IN_LIMIT_POS(k) (MLIP_IN_AXIS0 + 3 * (k) + 1)
#define MLIP_IN_HOME_SW(k)   (MLIP_IN_AXIS0 + 3 * (k) + 2)
#define MLIP_IN_COUNT        (MLIP_IN_AXIS0 + 3 * MLIP_MAX_AXES) /* 22: a bit each in a uint32_t */
#define MLIP_IO_IN_BYTES     8                                   /* 0x6000:1..8 / 0x6200:1..8 */

struct mlip_io_bit {
	uint8_t node;       /* 0: not mapped */
	uint8_t sub;        /* 0x6000:1..8, 0x60FD:0 */
	uint16_t index;     /* 0x6000 (module inputs), 0x60FD (drive inputs) */
	uint8_t bit;        /* 0..7 in a module byte, 0..31 in 0x60FD */
	uint8_t active_low; /* LOW: on when the bit reads 0 */
	uint32_t line;      /* where the INI maps it (0: not mapped) */
};

/* The module's outputs (issue 19), each one bit of 0x6200:1..8, active high
 * (an output the module switches off by itself, at power-up or when it
 * loses the master, is off):
 *   [COOLANT]
 *   TYPE = io                    ; M7/M8/M9 switch the outlets below
 *   MIST = 10 0x6200:1 0         ; M7: NODE INDEX:SUB BIT ([HIGH])
 *   FLOOD = 10 0x6200:1 1        ; M8
 *   [IO]
 *   OUTPUT_0 = 10 0x6200:1 2     ; M64 P0 / M65 P0 .. OUTPUT_7
 * NODE must be [IO] NODE; one bit carries one output (or input function). */
enum {
	MLIP_OUT_MIST = 0,
	MLIP_OUT_FLOOD,
	MLIP_OUT_DOUT0, /* + n: OUTPUT_n (M64/M65 Pn) */
	MLIP_OUT_COUNT = MLIP_OUT_DOUT0 + MLIP_DOUT_MAX
};

struct mlip_io_out {
	uint8_t sub;   /* 0x6200:1..8 */
	uint8_t bit;   /* 0..7 */
	uint32_t line; /* where the INI maps it (0: not mapped) */
};

struct mlip_io_config {
	uint8_t node;      /* [IO] NODE: the CiA 401 module; 0: none */
	uint8_t in_bytes;  /* module input bytes the functions use (0x6000:1..n) */
	uint8_t out_bytes; /* module output bytes mapped (0x6200:1..n; 0: none) */
	uint32_t mapped;   /* bit f: function f is mapped */
	struct mlip_io_bit in[MLIP_IN_COUNT]; /* by function (MLIP_IN_*) */
	uint32_t out_mapped;                  /* bit o: output o (MLIP_OUT_*) is mapped */
	struct mlip_io_out out[MLIP_OUT_COUNT];
	uint8_t probe_source; /* [PROBE] SOURCE: MLIP_PROBE_SRC_* */
};

/* Where G38's trip and position come from (issue 19):
 *   [PROBE]
 *   SOURCE = io       ; default: the [IO] PROBE input; the position of the
 *                     ; period its frame arrived
 *   SOURCE = drive    ; every axis drive's touch probe 1 (CiA 402 0x60B8
 *                     ; function in RPDO1, 0x60B9 status in TPDO1, 0x60BA /
 *                     ; 0x60BB positive / negative edge position in TPDO2):
 *                     ; the position each drive latched at the edge
 * With SOURCE = drive an [IO] PROBE input, when mapped too (the same switch),
 * gives the level for "already tripped at the start". */
#define MLIP_PROBE_SRC_IO    0
#define MLIP_PROBE_SRC_DRIVE 1

/* "estop", "hold", "cycle start", "probe", "X limit -", "X limit +", "X home
 * switch" (the letter from m; NULL: the axis index), "?" out of range. Writes
 * into buf (16 bytes suffice) and returns it. */
const char *mlip_io_function_name(uint32_t f, const struct mlip_machine *m, char *buf, size_t n);

/* A warning for a valid but risky probe setup, or NULL: [PROBE] SOURCE = drive
 * with no [IO] PROBE level mapped (0x60B9 has no level: a probe already on when
 * a G38 starts gives no edge, so nothing stops the move). Static text. */
const char *mlip_io_probe_warning(const struct mlip_io_config *io);

/* Homing with the drives' own homing mode (issue 18; CiA 402 mode 6), per
 * axis in [AXIS_L]:
 *   HOME_METHOD = 35        ; 0x6098: any method the drive supports (35/37: the
 *                           ; current position; 17/18: a limit switch; 19..30:
 *                           ; a home switch); homing is configured by this key
 *   HOME_SEARCH_VEL = 10    ; mm/s (deg/s): 0x6099:01, in counts/s
 *   HOME_LATCH_VEL = 1      ; mm/s (deg/s): 0x6099:02
 *   HOME_ACCEL = 100        ; mm/s^2: 0x609A (default MAX_ACCELERATION)
 *   HOME_OFFSET = 0         ; mm: 0x607C, the position at home (inside the limits)
 *   HOME_SEQUENCE = 1       ; 0..9: axes with the same number home together, lower
 *                           ; first (default: Z 0, the others 1, as LinuxCNC)
 *   HOME_TIMEOUT = 60       ; s: homing not done by then is a fault
 * and [DRIVES] HOMING_REQUIRED = 1: programs are refused until every axis
 * with a HOME_METHOD is homed (jogging stays allowed). */
struct mlip_axis_home {
	int configured;                              /* HOME_METHOD given */
	int method;                                  /* 0x6098 */
	double search_vel, latch_vel, accel, offset; /* axis units */
	int sequence;
	double timeout_s;
};

struct mlip_home_config {
	int required;                              /* HOMING_REQUIRED */
	struct mlip_axis_home axis[MLIP_MAX_AXES]; /* machine order */
};

/* [SPINDLE] TYPE = cia402 (issue 19): a CiA 402 drive (or a VFD with a CiA 402
 * profile) on the bus in profile velocity mode; src/canopen/spindle.c decides
 * its periods. Speeds in rpm, the drive's in counts/s at counts_per_rev. */
struct mlip_spindle_config {
	uint8_t node;            /* NODE: its CANopen node id (none of the others) */
	double min_rpm, max_rpm; /* MIN_RPM, MAX_RPM (as io.min_rpm, io.max_rpm) */
	double counts_per_rev;   /* COUNTS_PER_REV: 0x60FF / 0x606C counts a revolution */
	double accel_rpm_s;      /* ACCELERATION: rpm/s, 0x6083 and 0x6084 */
	double band_rpm;         /* AT_SPEED_BAND: |actual - target| <= this is at speed;
	                            default 2 % of MAX_RPM */
	double timeout_s;        /* AT_SPEED_TIMEOUT: a change reaches its target within
	                            this or it is a fault; default 2 MAX_RPM / ACCELERATION
	                            + 1 s (a reversal at full speed, and a margin) */
	double band_time_s;      /* BAND_TIME: at speed, then outside the band this long
	                            while cutting is a fault; default 0.2 s */
};

/* [TRAJ] JERK_PLAN */
enum { MLIP_JERK_PLAN_MEAN = 0, MLIP_JERK_PLAN_PATH = 1 };

struct mlip_config {
	struct mlip_machine machine;
	struct mlip_can_config can;
	struct mlip_drives_config drives;
	struct mlip_io_config inputs; /* the inputs on the bus (issue 18) */
	struct mlip_home_config home;
	uint32_t lookahead;      /* [TRAJ] LOOKAHEAD blocks, default MLIP_LOOKAHEAD */
	uint8_t jerk_plan;       /* [TRAJ] JERK_PLAN: MLIP_JERK_PLAN_*, default mean */
	uint32_t jerk_plan_line; /* where the file sets it (0: not set), for messages */
	/* [SPINDLE], [TOOL], [COOLANT]: what the program's I/O words meet (the
	 * tools add the tool table and the --ignore-* choices); default none */
	struct mlip_gcode_io io;
	struct mlip_spindle_config spindle; /* io.spindle == MLIP_IO_CIA402 */
};

/* Fill *c with defaults (no axes): MAX_ANGULAR_VELOCITY 360, PERIOD 0.001,
 * LOOKAHEAD MLIP_LOOKAHEAD, the [CAN] defaults above; v_m and eps 0 (they are
 * required). */
void mlip_config_defaults(struct mlip_config *c);

/* Parse an INI text of len bytes (need not be NUL-terminated) into *c, which
 * must hold defaults first: an optional [TRAJ] or [CAN] key absent from the
 * text keeps the value *c holds; axes come from the text alone. Returns MLIP_OK with *c filled
 * and passing mlip_machine_check, or an error with *err filled (err may be
 * NULL) and *c unchanged. */
mlip_status mlip_config_parse(struct mlip_config *c, const char *text, size_t len,
                              struct mlip_config_error *err);

/* Check a machine for consistency (2..6 distinct axes, positive limits,
 * min_limit < max_limit, home within limits, ...) and for the ranges that
 * keep the guarantees: the MLIP_CONFIG_*_MAX bounds above, and the period
 * against the tolerance: |A| T^2 / 8 <= eps, with |A| the norm of the
 * per-axis MAX_ACCELERATION vector (see check_period in config.c). Used after command-line
 * overrides too. Messages name the field with its INI name, e.g.
 * "AXIS_Z MAX_ACCELERATION must be > 0, got -5"; err->line = err->col = 0.
 * MLIP_E_INVALID for the axis set (count, letters, kind), else MLIP_E_RANGE. */
mlip_status mlip_machine_check(const struct mlip_machine *m, struct mlip_config_error *err);

/* The CAN id rules (mlip_can_rules of mlip/can/canconf.h, their one home)
 * with the reason in err (may be NULL; line = col = 0), e.g. "PACKED_BASE
 * 0x17F + 1 = 0x180 (position frame 1 of 3 axes) is also the STATUS_ID".
 * MLIP_E_INVALID for NULL arguments. */
mlip_status mlip_can_config_check(const struct mlip_can_config *can, const struct mlip_machine *m,
                                  struct mlip_config_error *err);

#endif
