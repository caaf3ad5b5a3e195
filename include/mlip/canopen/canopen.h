/*
 * mlip/canopen/canopen.h - the CANopen master's frames and decisions, pure: NMT,
 * heartbeat, EMCY, the SDO client (CiA 301), the CiA 402 power state machine
 * and the drive supervision. No sockets, no clock: rt/drives.c sends the
 * frames this builds and feeds back the frames it receives; tests feed
 * scripted ones.
 *
 * Identifiers (CiA 301 predefined connection set, node n = 1..127):
 *   NMT        0x000          [0] command, [1] node (0: all)
 *   SYNC       [CAN] SYNC_ID  (0x080) len 0
 *   EMCY       0x080 + n      [0..1] error code, [2] error register 0x1001, [3..7] vendor
 *   TPDO1      0x180 + n      drive -> mlip: [0..1] statusword 0x6041, [2..5] position
 *                             actual value 0x6064 (counts), sent at every SYNC
 *   RPDO1      RPDO_BASE + n  mlip -> drive: [0..1] controlword 0x6040, [2..5] target
 *                             position 0x607A (counts), applied at the next SYNC
 *   SDO        0x600 + n request (mlip -> drive), 0x580 + n answer
 *   heartbeat  0x700 + n      [0] NMT state (0 = boot-up)
 * Every multi-byte field is little-endian.
 */
#ifndef MLIP_CANOPEN_H
#define MLIP_CANOPEN_H

#include <stdint.h>

#include "mlip/can/canenc.h"
#include "mlip/types.h"

#define MLIP_CO_NMT_ID      0x000u
#define MLIP_CO_EMCY_BASE   0x080u
#define MLIP_CO_TPDO1_BASE  0x180u
#define MLIP_CO_SDO_TX_BASE 0x580u /* server (drive) -> client (mlip) */
#define MLIP_CO_SDO_RX_BASE 0x600u /* client -> server */
#define MLIP_CO_HB_BASE     0x700u
#define MLIP_CO_NODE_MAX    127

/* ---- NMT and heartbeat ------------------------------------------------------ */

enum {
	MLIP_NMT_START = 0x01,
	MLIP_NMT_STOP = 0x02,
	MLIP_NMT_PREOP = 0x80,
	MLIP_NMT_RESET_NODE = 0x81,
	MLIP_NMT_RESET_COMM = 0x82
};
/* NMT states as a heartbeat carries them */
enum {
	MLIP_NMT_BOOTUP = 0,
	MLIP_NMT_STOPPED = 4,
	MLIP_NMT_OPERATIONAL = 5,
	MLIP_NMT_PREOPERATIONAL = 127
};

/* NMT command cmd to node (0: every node). */
void mlip_nmt_encode(uint8_t cmd, uint8_t node, struct mlip_can_frame *f);
/* Heartbeat (or boot-up, state 0) of node. */
void mlip_co_heartbeat_encode(uint8_t node, uint8_t state, struct mlip_can_frame *f);
/* "boot-up", "stopped", "operational", "pre-operational", "unknown". */
const char *mlip_nmt_state_name(uint8_t state);

/* ---- EMCY ------------------------------------------------------------------- */

struct mlip_emcy {
	uint16_t code; /* 0x0000: error reset or no error */
	uint8_t reg;   /* error register 0x1001 */
	uint8_t vendor[5];
};
/* The class of an emergency error code (CiA 301 table 21, CiA 402 codes
 * where they are more precise): "following error", "current", ... */
const char *mlip_emcy_text(uint16_t code);

/* ---- a received frame, classified -------------------------------------------- */

typedef enum {
	MLIP_CO_OTHER = 0, /* not for the master (or malformed: counted by the caller) */
	MLIP_CO_HEARTBEAT, /* node, nmt_state (0: boot-up) */
	MLIP_CO_EMCY,      /* node, emcy */
	MLIP_CO_TPDO,      /* node, statusword, position_counts */
	MLIP_CO_SDO        /* node: an SDO answer, for mlip_sdo_feed */
} mlip_co_kind;

struct mlip_co_msg {
	mlip_co_kind kind;
	uint8_t node;
	uint8_t nmt_state;
	uint16_t statusword;
	int32_t position_counts;
	struct mlip_emcy emcy;
};

/* Classify a frame by its identifier and check its length (a TPDO must be 6
 * bytes: the mapping mlip writes). Nodes outside 1..127 are OTHER; so are
 * frames with the wrong length (MLIP_E_SYNTAX then, else MLIP_OK). */
mlip_status mlip_co_classify(const struct mlip_can_frame *f, struct mlip_co_msg *m);

/* The 6-byte TPDO/RPDO payload: a 16-bit word then an int32 position. */
void mlip_co_pdo_encode(uint32_t id, uint16_t word, int32_t counts, struct mlip_can_frame *f);

/* ---- SDO client (expedited, and segmented upload) ------------------------------ */

#define MLIP_SDO_MAX_DATA 32 /* bytes a segmented upload may bring (device name) */

/* Abort codes mlip itself sends (CiA 301 table 22). */
#define MLIP_SDO_ABORT_TOGGLE  0x05030000u
#define MLIP_SDO_ABORT_TIMEOUT 0x05040000u
#define MLIP_SDO_ABORT_COMMAND 0x05040001u
#define MLIP_SDO_ABORT_MEMORY  0x05040005u
#define MLIP_SDO_ABORT_GENERAL 0x08000000u

/* One transfer. Fill with mlip_sdo_download_begin / mlip_sdo_upload_begin,
 * send the request they give, then feed every SDO answer of the node to
 * mlip_sdo_feed until it says DONE, ABORTED or PROTOCOL. */
struct mlip_sdo {
	uint8_t node;
	uint16_t index;
	uint8_t sub;
	uint8_t upload; /* 1: read (upload), 0: write (download) */
	uint8_t size;   /* download: bytes written (1..4) */
	uint32_t value; /* download: the value; upload: the first 4 bytes, little-endian */
	uint8_t data[MLIP_SDO_MAX_DATA];
	uint32_t len;   /* upload: bytes received */
	uint8_t toggle; /* segmented upload: the toggle bit of the next segment */
	uint8_t segmented;
	uint32_t abort_code; /* ABORTED (from the drive) or PROTOCOL (sent by us) */
};

typedef enum {
	MLIP_SDO_IGNORED = 0, /* not an answer to this transfer: keep waiting */
	MLIP_SDO_DONE,        /* complete: upload data in value/data/len */
	MLIP_SDO_SEND,        /* send *req (the next segment request) and keep waiting */
	MLIP_SDO_ABORTED,     /* the drive aborted: abort_code */
	MLIP_SDO_PROTOCOL     /* a wrong answer: send *req (our abort, abort_code) */
} mlip_sdo_step;

void mlip_sdo_download_begin(struct mlip_sdo *s, uint8_t node, uint16_t index, uint8_t sub,
                             uint32_t value, uint8_t size, struct mlip_can_frame *req);
void mlip_sdo_upload_begin(struct mlip_sdo *s, uint8_t node, uint16_t index, uint8_t sub,
                           struct mlip_can_frame *req);
mlip_sdo_step mlip_sdo_feed(struct mlip_sdo *s, const struct mlip_can_frame *ans,
                            struct mlip_can_frame *req);
/* The abort request a client sends (e.g. MLIP_SDO_ABORT_TIMEOUT). */
void mlip_sdo_abort_encode(uint8_t node, uint16_t index, uint8_t sub, uint32_t code,
                           struct mlip_can_frame *f);
/* CiA 301's meaning of an abort code: "sub-index does not exist", ...;
 * "unknown abort code" otherwise. */
const char *mlip_sdo_abort_text(uint32_t code);

/* ---- CiA 402 power state machine ------------------------------------------------ */

typedef enum {
	MLIP_402_NOT_READY = 0,
	MLIP_402_SWITCH_ON_DISABLED,
	MLIP_402_READY_TO_SWITCH_ON,
	MLIP_402_SWITCHED_ON,
	MLIP_402_OPERATION_ENABLED,
	MLIP_402_QUICK_STOP_ACTIVE,
	MLIP_402_FAULT_REACTION_ACTIVE,
	MLIP_402_FAULT,
	MLIP_402_UNKNOWN
} mlip_402_state;

#define MLIP_402_SW_FAULT            0x0008u /* statusword bit 3 */
#define MLIP_402_SW_FOLLOWING_ERROR  0x2000u /* bit 13 in CSP */
#define MLIP_402_CW_DISABLE_VOLTAGE  0x0000u
#define MLIP_402_CW_SHUTDOWN         0x0006u
#define MLIP_402_CW_SWITCH_ON        0x0007u /* also "disable operation" from enabled */
#define MLIP_402_CW_ENABLE_OPERATION 0x000Fu
#define MLIP_402_CW_FAULT_RESET      0x0080u /* on its rising edge */
#define MLIP_402_MODE_CSP            8       /* 0x6060 / 0x6061 */

/* The state a statusword shows (CiA 402 table of statusword bits 0-3, 5, 6). */
mlip_402_state mlip_402_state_of(uint16_t statusword);
const char *mlip_402_state_name(mlip_402_state s);
/* The controlword that takes a drive in state s one transition toward
 * "operation enabled": fault reset, shutdown, switch on, enable operation
 * (enable operation when already there); -1 where the drive must be waited
 * for (not ready, fault reaction active) or the state is unknown. */
int mlip_402_step_up(mlip_402_state s);
/* The state that controlword cw leads to from s (the transition the drive
 * makes on its own is not modelled): what bring-up waits for. */
mlip_402_state mlip_402_after(mlip_402_state s, uint16_t cw);

/* ---- the objects mlip writes to a drive ------------------------------------------ */

struct mlip_drive_setup {
	uint8_t node;
	uint32_t sync_id;                 /* 0x1005 */
	uint32_t rpdo_cob;                /* RPDO1 COB-ID, 0x1400:01 */
	uint32_t tpdo_cob;                /* TPDO1 COB-ID, 0x1800:01 */
	double period_s;                  /* 0x60C2 */
	uint32_t following_window_counts; /* 0x6065 */
	uint16_t heartbeat_ms;            /* 0x1017, the drive's producer time */
	uint8_t master_node;              /* 0x1016:01: the drive watches the master's heartbeat */
	uint16_t master_timeout_ms;
};

/* One SDO step of the set-up: write then read back (or only read and compare). */
struct mlip_sdo_entry {
	uint16_t index;
	uint8_t sub;
	uint8_t size;      /* bytes: 1, 2 or 4 */
	uint32_t value;    /* as written (an INTEGER8 as its two's complement byte) */
	uint8_t read_only; /* 1: read and compare only (0x6061) */
	const char *what;  /* "modes of operation", ... for messages and the README */
};

#define MLIP_DRIVE_SETUP_MAX 24

/* The interpolation time period 0x60C2 as value * 10^index s: value 1..255,
 * index -6..0, exact to 1e-9 relative. MLIP_E_RANGE when no such pair. */
mlip_status mlip_co_interp_period(double period_s, uint8_t *value, int8_t *index);

/* The set-up of one drive, in the order it is written: RPDO1 (disabled,
 * transmission type, mapping 0x6040 + 0x607A, enabled), TPDO1 (disabled,
 * synchronous every SYNC, mapping 0x6041 + 0x6064, enabled), SYNC COB-ID,
 * modes of operation = CSP and its display, interpolation period, following
 * error window, heartbeat producer and consumer. Returns the count, or -1
 * when cap is too small or the period cannot be written. */
int mlip_drive_setup_entries(const struct mlip_drive_setup *d, struct mlip_sdo_entry *out, int cap);

/* ---- supervision in the loop ------------------------------------------------------- */

typedef enum {
	MLIP_DRIVE_OK = 0,
	MLIP_DRIVE_FAULT_BIT,       /* statusword bit 3 (fault or fault reaction) */
	MLIP_DRIVE_EMCY,            /* an emergency with a non-zero code */
	MLIP_DRIVE_HEARTBEAT_LOST,  /* no heartbeat within the consumer time */
	MLIP_DRIVE_NOT_OPERATIONAL, /* its heartbeat says it left NMT operational */
	MLIP_DRIVE_LEFT_ENABLED,    /* statusword no longer "operation enabled" */
	MLIP_DRIVE_FOLLOWING_ERROR, /* |target sent - position actual| beyond the window */
	MLIP_DRIVE_TPDO_LOST,       /* no TPDO for tpdo_timeout periods, or the last one
	                               answers a SYNC that many periods old */
	/* re-enabling for the next program (the controller, src/ctl/controller.c) */
	MLIP_DRIVE_NOT_SWITCHED_ON, /* switch on (0x0007) not confirmed in time (statusword) */
	MLIP_DRIVE_NOT_ENABLED,     /* enable operation (0x000F) not confirmed in time */
	MLIP_DRIVE_BEYOND_LIMIT     /* its position actual is beyond a soft limit (mm, deg) */
} mlip_drive_fault;

/* What the bus last said about one drive (filled from mlip_co_classify). */
struct mlip_drive_obs {
	uint16_t statusword;
	int32_t position_counts;
	uint64_t tpdo_cycle; /* period of the last TPDO; 0: none yet */
	uint64_t tpdo_count; /* TPDOs since the first SYNC: the n-th answers SYNC n */
	uint8_t nmt_state;
	uint64_t hb_ns; /* time of the last heartbeat */
	struct mlip_emcy emcy;
	uint32_t emcy_count; /* EMCYs with a non-zero code */
};

/* What the drive must be doing now. */
struct mlip_drive_expect {
	uint64_t now_ns;
	uint64_t cycle;           /* this period */
	uint64_t hb_timeout_ns;   /* 0: heartbeat not watched */
	uint32_t tpdo_timeout;    /* periods without a TPDO that make it lost */
	uint32_t window_counts;   /* 0x6065 */
	int64_t following_counts; /* mlip_drive_following_error, or -1: unknown */
	int any_state;            /* 1: the master is disabling, has disabled or is enabling
	                             the drive: any state without the fault bit is right */
};

/* The first fault found, in the order of the enum (the drive's own word
 * first); *detail gets the figure (statusword, EMCY code, age in ms, counts). */
mlip_drive_fault mlip_drive_supervise(const struct mlip_drive_obs *o,
                                      const struct mlip_drive_expect *x, int64_t *detail);
const char *mlip_drive_fault_name(mlip_drive_fault f);

/* The following error of a position actual against the n targets sent
 * before the SYNC its TPDO answers (targets[0] the last one): the smallest
 * distance, since a drive applies a target at the SYNC after it is sent,
 * reports the position it sampled at a SYNC, and lags by a few periods more
 * while it moves. */
int64_t mlip_drive_following_error(const int32_t *targets, int n, int32_t actual);

#endif
