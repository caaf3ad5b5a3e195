/*
 * mlip/canopen/canopen.h - the CANopen master's frames (CiA 301), pure: NMT,
 * heartbeat, EMCY, the classification of what the drives send, the PDO
 * payload and the SDO client. No sockets, no clock: rt/drives.c sends the
 * frames this builds and feeds back the frames it receives; tests feed
 * scripted ones. The CiA 402 power state machine is mlip/canopen/cia402.h,
 * the drive's set-up and supervision mlip/canopen/drive.h.
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
#define MLIP_CO_TPDO2_BASE  0x280u
#define MLIP_CO_TPDO3_BASE  0x380u /* a drive's digital inputs 0x60FD (issue 18) */
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
	MLIP_CO_TPDO,      /* node, statusword, position_counts (8 bytes: probe_status too) */
	MLIP_CO_SDO,       /* node: an SDO answer, for mlip_sdo_feed */
	MLIP_CO_TPDO2      /* node, probe_pos, probe_neg (a drive's touch probe) */
} mlip_co_kind;

struct mlip_co_msg {
	mlip_co_kind kind;
	uint8_t node;
	uint8_t nmt_state;
	uint16_t statusword;
	int32_t position_counts;
	struct mlip_emcy emcy;
	/* a drive's touch probe 1 (CiA 402; [PROBE] SOURCE = drive) */
	uint8_t has_probe;     /* TPDO1 was 8 bytes: probe_status follows the position */
	uint16_t probe_status; /* 0x60B9 */
	int32_t probe_pos;     /* TPDO2: 0x60BA, positive edge position (counts) */
	int32_t probe_neg;     /* TPDO2: 0x60BB, negative edge position */
};

/* Classify a frame by its identifier and check its length (a TPDO1 must be 6
 * bytes, or 8 with the touch probe status; a TPDO2 8: the mappings mlip
 * writes). Nodes outside 1..127 are OTHER; so are
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

/* ---- a node's set-up by SDO (a drive's, an I/O module's) ------------------- */

/* One SDO step of the set-up: write then read back (or only read and compare). */
struct mlip_sdo_entry {
	uint16_t index;
	uint8_t sub;
	uint8_t size;      /* bytes: 1, 2 or 4 */
	uint32_t value;    /* as written (an INTEGER8 as its two's complement byte) */
	uint8_t read_only; /* 1: read and compare only (0x6061) */
	const char *what;  /* "modes of operation", ... for messages and the README */
};

/* A set-up list being built in order into e[cap]: n counts every entry
 * added, those past cap are not stored (n > cap: it did not fit). */
struct mlip_sdo_list {
	struct mlip_sdo_entry *e;
	int cap;
	int n;
};

/* The next entry: written, then read back. */
void mlip_sdo_add(struct mlip_sdo_list *l, uint16_t index, uint8_t sub, uint8_t size,
                  uint32_t value, const char *what);
/* The next entry: only read, and compared with value. */
void mlip_sdo_add_check(struct mlip_sdo_list *l, uint16_t index, uint8_t sub, uint8_t size,
                        uint32_t value, const char *what);

/* One PDO's mapping for a set-up list (CiA 301: a PDO is changed only while
 * not valid). RPDOn/TPDOn: communication 0x1400/0x1800 + n - 1, mapping
 * 0x1600/0x1A00 + n - 1. */
struct mlip_pdo_map {
	uint8_t tpdo;            /* 1: a TPDO (the node sends it; bit 30: no RTR), 0: an RPDO */
	uint8_t num;             /* n: 1..4 */
	uint32_t cob_id;         /* its COB-ID (bits 0..10) */
	uint8_t type;            /* transmission type, sub 2 */
	const char *type_what;   /* e.g. "TPDO1 transmission type (synchronous, every SYNC)" */
	const char *event_what;  /* a TPDO's event timer (sub 5), NULL: not written */
	uint16_t event_ms;       /* idem, ms */
	uint8_t n;               /* mapped objects, 1..8 */
	const uint32_t *map;     /* each: index << 16 | sub << 8 | length in bits */
	const char *const *what; /* each entry's text */
};

/* The next entries: the PDO disabled (COB-ID bit 31), its transmission type
 * (and event timer), the mapping count cleared, each mapping entry, the count,
 * the PDO enabled; each written and read back. MLIP_E_RANGE (nothing added)
 * when num or n is out of range. */
mlip_status mlip_sdo_add_pdo(struct mlip_sdo_list *l, const struct mlip_pdo_map *p);

#endif
