/*
 * keys.h - private to src/machine/: the INI file's sections and keys, the
 * parse state, and what the parts of the reader share:
 *   ini.c      the INI reader: lines, sections, keys, single values, the
 *              second pass (presence, placement of errors), entry points
 *   keys.c     the key table
 *   suggest.c  "did you mean" for unknown sections and keys
 *   check.c    the machine check (mlip_machine_check), shared by the reader
 *              and the command-line overrides
 *   drives.c   the [DRIVES] section against the rest
 * The CAN id rules are in src/can/canconf.c (mlip/can/canconf.h).
 */
#ifndef MLIP_MACHINE_KEYS_H
#define MLIP_MACHINE_KEYS_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/machine/config.h"
#include "mlip/text/format.h"

#define NKEYS            8 /* keys per section kind (every kind has eight) */
#define BITRATE_MIN      10000
#define BITRATE_MAX      1000000  /* classical CAN, and the CAN FD arbitration phase */
#define DATA_BITRATE_MAX 12000000 /* CAN FD data phase */
#define LIMIT_DEFAULT    1e9      /* soft limits when not given: none, in practice */
#define AXIS_LETTERS     "XYZABC"

/* Sections by index: TRAJ, one per axis letter (XYZABC order), CAN, DRIVES. */
enum { SEC_TRAJ = 0, SEC_AXIS0 = 1, SEC_CAN = SEC_AXIS0 + MLIP_MAX_AXES, SEC_DRIVES, N_SEC };
enum { K_TRAJ, K_AXIS, K_CAN, K_DRIVES, N_KINDS };

enum { TK_COORDS, TK_VLIN, TK_VANG, TK_TOL, TK_PERIOD, TK_LUNITS, TK_AUNITS, TK_LOOKAHEAD };
enum { AK_TYPE, AK_VEL, AK_ACC, AK_MIN, AK_MAX, AK_HOME, AK_NODE, AK_CPU };
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
enum { DK_ENABLE, DK_MASTER, DK_HB, DK_HB_TIMEOUT, DK_FERR, DK_SDO, DK_BOOT, DK_STATE };

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
	V_MS         /* integer 1..65535 (CiA 301 heartbeat times are 16-bit ms) */
};

struct keydef {
	const char *name;
	unsigned char type;
	unsigned char required;
};

extern const struct keydef mlip_mc_keytab[N_KINDS][NKEYS];

static inline int sec_kind(int sec)
{
	return sec == SEC_TRAJ     ? K_TRAJ
	       : sec == SEC_CAN    ? K_CAN
	       : sec == SEC_DRIVES ? K_DRIVES
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

/* ---- check.c ---- */

/* What a failed check is about, so that the parser can point at the keys
 * that set the values: axis index (-1: TRAJ), key (AK_* or TK_*), the other
 * axis of a CAN_NODE clash. */
struct issue {
	int axis, key, axis2;
};

mlip_status mlip_mc_check_machine(const struct mlip_machine *m, struct mlip_config_error *err,
                                  struct issue *is);

/* ---- drives.c ---- */

void mlip_mc_fill_drives(const struct pstate *ps, struct mlip_drives_config *d);
mlip_status mlip_mc_check_drives(const struct pstate *ps, const struct mlip_config *c,
                                 struct mlip_config_error *err);

#endif
