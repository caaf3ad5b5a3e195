/*
 * keys.h - private to src/machine/: the INI file's sections and keys, the
 * parse state, and what the parts of the reader share:
 *   ini.c       the INI reader: lines, sections, keys, single values, the
 *               second pass (presence, placement of errors), entry points
 *   keys.c      the key table
 *   suggest.c   "did you mean" for unknown sections and keys
 *   validate.c  the machine check (mlip_machine_check), shared by the
 *               reader and the command-line overrides
 *   driveconf.c the [DRIVES] section against the rest
 *   ioconf.c    the [SPINDLE], [TOOL], [COOLANT] sections against the rest
 * The CAN id rules are in src/can/canconf.c (mlip/can/canconf.h).
 */
#ifndef MLIP_MACHINE_KEYS_H
#define MLIP_MACHINE_KEYS_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/machine/config.h"
#include "mlip/text/format.h"

#define NKEYS            24 /* keys per section kind at most (a NULL name ends a kind's) */
#define BITRATE_MIN      10000
#define BITRATE_MAX      1000000  /* classical CAN, and the CAN FD arbitration phase */
#define DATA_BITRATE_MAX 12000000 /* CAN FD data phase */
#define LIMIT_DEFAULT    1e9      /* soft limits when not given: none, in practice */
#define AXIS_LETTERS     "XYZABC"

/* Sections by index: TRAJ, one per axis letter (XYZABC order), CAN, DRIVES, SPINDLE,
 * TOOL, COOLANT, IO, PROBE. */
enum {
	SEC_TRAJ = 0,
	SEC_AXIS0 = 1,
	SEC_CAN = SEC_AXIS0 + MLIP_MAX_AXES,
	SEC_DRIVES,
	SEC_SPINDLE,
	SEC_TOOL,
	SEC_COOLANT,
	SEC_IO,
	SEC_PROBE,
	N_SEC
};
enum { K_TRAJ, K_AXIS, K_CAN, K_DRIVES, K_SPINDLE, K_TOOL, K_COOLANT, K_IO, K_PROBE, N_KINDS };

enum { TK_COORDS, TK_VLIN, TK_VANG, TK_TOL, TK_PERIOD, TK_LUNITS, TK_AUNITS, TK_LOOKAHEAD, TK_JERK_PLAN };
enum {
	AK_TYPE,
	AK_VEL,
	AK_ACC,
	AK_MIN,
	AK_MAX,
	AK_HOME,
	AK_NODE,
	AK_CPU,
	AK_LIMIT_NEG, /* inputs (issue 18): a limit switch each way, the home switch */
	AK_LIMIT_POS,
	AK_HOME_SW,
	AK_HOME_METHOD, /* homing with the drive's homing mode (issue 18) */
	AK_HOME_SEARCH_VEL,
	AK_HOME_LATCH_VEL,
	AK_HOME_ACCEL,
	AK_HOME_OFFSET,
	AK_HOME_SEQUENCE,
	AK_HOME_TIMEOUT,
	AK_JERK,        /* the jerk limit (mlip/motion/jerk.h) */
	AK_LIMIT_INPUTS /* drive: LIMIT_NEG/LIMIT_POS/HOME_SWITCH = the drive's 0x60FD bits 0/1/2 */
};
/* [CAN] keys in the order of enum mlip_can_key (mlip/can/canconf.h) */
enum {
	CK_PROFILE = MLIP_CAN_KEY_PROFILE,
	CK_BITRATE = MLIP_CAN_KEY_BITRATE,
	CK_DBITRATE = MLIP_CAN_KEY_DATA_BITRATE,
	CK_SYNC = MLIP_CAN_KEY_SYNC_ID,
	CK_RPDO = MLIP_CAN_KEY_RPDO_BASE,
	CK_PACKED = MLIP_CAN_KEY_PACKED_BASE,
	CK_FD = MLIP_CAN_KEY_FD_ID,
	CK_STATUS = MLIP_CAN_KEY_STATUS_ID
};
enum {
	DK_ENABLE,
	DK_MASTER,
	DK_HB,
	DK_HB_TIMEOUT,
	DK_FERR,
	DK_SDO,
	DK_BOOT,
	DK_STATE,
	DK_HOMING_REQUIRED
};
/* [IO]: the CiA 401 module's node, then the inputs in the order of MLIP_IN_* */
enum { IK_NODE, IK_ESTOP, IK_HOLD, IK_CYCLE_START, IK_PROBE, IK_OUT0 /* OUTPUT_0..7 */ };
enum {
	SK_TYPE,
	SK_MIN_RPM,
	SK_MAX_RPM,
	SK_NODE, /* TYPE = cia402 (issue 19): the drive on the bus */
	SK_CPR,
	SK_ACCEL,
	SK_BAND,
	SK_TIMEOUT,
	SK_BAND_TIME
};
/* [TOOL]: CHANGE, then CHANGE_X .. CHANGE_C in AXIS_LETTERS order */
enum { OK_CHANGE, OK_POS0 };
enum { QK_TYPE, QK_MIST, QK_FLOOD };
enum { PK_SOURCE };

/* How a value is read and which single-value range it must meet. */
enum vtype {
	V_COORDS,    /* axis letters */
	V_POS,       /* decimal > 0 */
	V_REAL,      /* any decimal */
	V_PERIOD,    /* decimal in [PERIOD_MIN, PERIOD_MAX] */
	V_LUNITS,    /* "mm" */
	V_AUNITS,    /* "degree" */
	V_LOOKAHEAD, /* power of two in 2..MLIP_LOOKAHEAD */
	V_TYPE,      /* LINEAR | ANGULAR */
	V_NODE,      /* integer 1..127 */
	V_PROFILE,   /* cia402 | packed | fd */
	V_BITRATE,   /* integer BITRATE_MIN..BITRATE_MAX */
	V_DBITRATE,  /* integer BITRATE_MIN..DATA_BITRATE_MAX */
	V_ID,        /* integer 0..0x7FF */
	V_BOOL,      /* 0 | 1 */
	V_MS,        /* integer 1..65535 (CiA 301 heartbeat times are 16-bit ms) */
	V_IO,        /* none | manual (a spindle, a tool change, coolant); cia402 (a spindle) */
	V_RPM,       /* decimal >= 0 */
	V_IOBIT,     /* NODE INDEX:SUB BIT HIGH|LOW (io.c) */
	V_METHOD,    /* integer -128..127 (0x6098, INTEGER8) */
	V_SEQUENCE,  /* integer 0..9 (HOME_SEQUENCE) */
	V_COOLANT,   /* none | manual | io ([COOLANT] TYPE; outputs.c) */
	V_OUTBIT,    /* NODE 0x6200:SUB BIT [HIGH] (outputs.c) */
	V_PSOURCE,   /* io | drive ([PROBE] SOURCE) */
	V_LINPUTS,   /* drive ([AXIS_L] LIMIT_INPUTS) */
	V_JPLAN      /* mean | path ([TRAJ] JERK_PLAN) */
};

struct keydef {
	const char *name;
	unsigned char type;
	unsigned char required;
};

extern const struct keydef mlip_mc_keytab[N_KINDS][NKEYS];

static inline int sec_kind(int sec)
{
	return sec == SEC_TRAJ      ? K_TRAJ
	       : sec == SEC_CAN     ? K_CAN
	       : sec == SEC_DRIVES  ? K_DRIVES
	       : sec == SEC_SPINDLE ? K_SPINDLE
	       : sec == SEC_TOOL    ? K_TOOL
	       : sec == SEC_COOLANT ? K_COOLANT
	       : sec == SEC_IO      ? K_IO
	       : sec == SEC_PROBE   ? K_PROBE
	                            : K_AXIS;
}

static inline int letter_index(char l)
{
	int i;

	for (i = 0; i < MLIP_MAX_AXES; i++) {
		if (AXIS_LETTERS[i] == l) {
			return i;
		}
	}
	return -1;
}

/* "TRAJ", "CAN", "AXIS_X", ... */
void mlip_mc_secname(struct mlip_tb *b, int sec);

/* the CAN rules' message goes whole into a config error (C99 has no
 * _Static_assert: a negative array size otherwise) */
typedef char mlip_mc_msg_size_check[MLIP_CAN_MSG == MLIP_CONFIG_MSG ? 1 : -1];

/* Start an error message at line:col (0: not applicable). */
static inline void err_at(struct mlip_config_error *err, struct mlip_tb *b, uint32_t line,
                          uint32_t col)
{
	err->line = line;
	err->col = col;
	mlip_tb_init(b, err->msg, sizeof err->msg);
}

/* ---- the parse state ---- */

struct pos {
	uint32_t line, col; /* line 0: not given */
};

struct sec {
	struct pos at;         /* the header, at the section name */
	unsigned seen;         /* bit k: key k given */
	struct pos key[NKEYS]; /* where each given key stands */
	double num[NKEYS];     /* decimal values */
	int64_t ival[NKEYS];   /* integer and enumerated values */
};

struct pstate {
	struct sec sec[N_SEC];
	int cur; /* section of the lines read, -1 before any */
	int n_coords;
	char coords[MLIP_MAX_AXES]; /* COORDINATES, in order */
	uint32_t coord_col[MLIP_MAX_AXES];
};

static inline int has(const struct pstate *ps, int sec, int key)
{
	return (ps->sec[sec].seen >> key) & 1u;
}

/* Place err on the latest given of up to three keys (sec < 0: unused) (ini.c). */
void mlip_mc_place(const struct pstate *ps, struct mlip_config_error *err, int s1, int k1, int s2,
                   int k2, int s3, int k3);

/* ---- suggest.c ---- */

/* The candidate the user most likely meant by s[0..n), or NULL. */
const char *mlip_mc_suggest(const char *s, size_t n, const char *const *cand, int ncand);

/* ---- validate.c ---- */

/* What a failed check is about, so that the parser can point at the keys
 * that set the values: axis index (-1: TRAJ), key (AK_* or TK_*), the other
 * axis of a CAN_NODE clash. */
struct issue {
	int axis, key, axis2;
};

mlip_status mlip_mc_check_machine(const struct mlip_machine *m, struct mlip_config_error *err,
                                  struct issue *is);

/* Keys of a kind (its names before the first NULL). */
static inline int nkeys(int kind)
{
	int k = 0;

	while (k < NKEYS && mlip_mc_keytab[kind][k].name != NULL) {
		k++;
	}
	return k;
}

/* ---- ioconf.c ---- */

void mlip_mc_fill_io(const struct pstate *ps, struct mlip_config *c);
mlip_status mlip_mc_check_io(const struct pstate *ps, const struct mlip_config *c,
                             struct mlip_config_error *err);

/* ---- inputs.c ---- */

/* The next blank-separated token of v[*p..nv): its start and length. */
size_t mlip_mc_token(const char *v, size_t nv, size_t *p, size_t *start);
/* err at line, col: "KEY" what [", got 'TOK'"] (tok NULL: none); MLIP_E_SYNTAX. */
mlip_status mlip_mc_value_err(struct mlip_config_error *err, uint32_t line, uint32_t col,
                              const char *key, const char *what, const char *tok, size_t ntok);
/* The tokens t[0] (NODE, 1..127) and t[1] (INDEX:SUB) of a value at line, col. */
mlip_status mlip_mc_node_object(const char *v, const size_t *t, const size_t *n, uint32_t line,
                                uint32_t col, const char *key, int64_t *node, int64_t *index,
                                int64_t *sub, struct mlip_config_error *err);

/* A V_IOBIT value "NODE INDEX:SUB BIT HIGH|LOW" into *packed (mlip_mc_iobit
 * unpacks it); errors at line, col + the token's offset. */
mlip_status mlip_mc_parse_iobit(const char *v, size_t nv, uint32_t line, uint32_t col,
                                const char *key, int64_t *packed, struct mlip_config_error *err);
/* [IO] and the axes' input keys into c->inputs, then against the machine: every
 * node is the module's or an axis', the object fits the node, no bit carries
 * two functions. */
mlip_status mlip_mc_fill_inputs(const struct pstate *ps, struct mlip_config *c,
                                struct mlip_config_error *err);

/* ---- outputs.c ---- */

/* A V_COOLANT or V_OUTBIT value into st->ival[k] (V_OUTBIT packed as
 * V_IOBIT's); errors at line, col + the token's offset. */
mlip_status mlip_mc_parse_output(int type, const char *v, size_t nv, uint32_t line, uint32_t col,
                                 const char *key, int64_t *val, struct mlip_config_error *err);
/* [COOLANT] MIST / FLOOD and [IO] OUTPUT_n into c->inputs.out (and
 * out_bytes, c->io's outlets and outputs), checked: the I/O module's node,
 * 0x6200:1..8 bits 0..7, one function a bit, TYPE = io with an outlet. */
mlip_status mlip_mc_fill_outputs(const struct pstate *ps, struct mlip_config *c,
                                 struct mlip_config_error *err);

/* ---- home.c ---- */

/* The axes' HOME_* keys and HOMING_REQUIRED into c->home, checked: no
 * HOME_* without HOME_METHOD, HOME_OFFSET inside the soft limits, the
 * drives' units (counts/s, counts/s^2, counts) within their objects. */
mlip_status mlip_mc_fill_home(const struct pstate *ps, struct mlip_config *c,
                              struct mlip_config_error *err);

/* ---- driveconf.c ---- */

void mlip_mc_fill_drives(const struct pstate *ps, struct mlip_drives_config *d);
mlip_status mlip_mc_check_drives(const struct pstate *ps, const struct mlip_config *c,
                                 struct mlip_config_error *err);

#endif
