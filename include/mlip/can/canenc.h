/*
 * mlip/can/canenc.h - one period's axis setpoints as CAN frames, the way back
 * (decoding, for tests and tools), and the bus load of each output profile.
 *
 * Pure: no sockets, no linux/can.h; struct mlip_can_frame is converted to
 * struct can_frame / canfd_frame by rt/. All identifiers are 11-bit (base
 * format); every multi-byte field is little-endian (CANopen byte order).
 * Positions cross this interface in mm (deg for rotary axes) and leave it as
 * int32 drive counts: counts = round(pos * counts_per_unit), ties away from
 * zero; a value outside int32 is saturated AND reported (MLIP_E_RANGE): it is
 * a fault, the frames must not be sent.
 *
 * Profiles (ids are the [CAN] defaults of mlip/machine/config.h; n = axes, node =
 * CAN_NODE of the axis):
 *
 * cia402 (default) - CiA 301 SYNC + one RPDO per drive, for CiA 402 drives in
 *   cyclic synchronous position mode (RPDO mapped to object 0x607A, target
 *   position, INTEGER32):
 *     SYNC       id sync_id (0x080)            len 0
 *     RPDO axis  id rpdo_base + node (0x201..)  len 4   [0..3] int32 counts
 *   SYNC first, then the RPDOs in axis order: a drive latches the RPDO and
 *   applies it at the next SYNC (one period of transport delay, as CiA 402
 *   CSP intends). There is no cycle counter on the wire (SYNC has len 0).
 *
 * packed - two axes per 8-byte frame, then a commit frame with a counter:
 *     POS k      id packed_base + k (0x300..), k = 0..ceil(n/2)-1
 *                len 8: [0..3] int32 axis 2k, [4..7] int32 axis 2k+1
 *                (len 4 for the last frame when n is odd: axis 2k only)
 *     COMMIT     id packed_base + ceil(n/2)     len 4   [0..3] uint32 cycle
 *   Why a trailing commit: 8 bytes hold exactly two int32, so no position
 *   frame has room for a counter, and 24-bit positions would limit travel to
 *   +-8.4 m at 1 count/um (less with finer counts). A receiver collects the
 *   POS frames and applies them when the COMMIT arrives (no extra period of
 *   delay). It detects every gap: a POS frame missing at COMMIT -> that
 *   cycle is incomplete; a POS id seen twice before a COMMIT -> the COMMIT
 *   was lost; the counter stepping by more than 1 -> whole cycles lost. The
 *   COMMIT has the highest id of the cycle, so even a controller that sends
 *   queued frames in id-priority order sends it last.
 *
 * fd - one CAN FD frame (bit-rate switch when data_bitrate > bitrate):
 *     id fd_id (0x400), len = smallest FD length >= 4 + 4n (12..32)
 *     [0..3] uint32 cycle, [4+4i .. 7+4i] int32 axis i, padding bytes 0
 *
 * Bus load: worst-case bits per frame (every bit that can be stuffed is),
 * including the 3-bit intermission, since the bus cannot carry the next frame
 * during it. n = data bytes.
 *   Classic base frame (Davis, Burns, Bril, Lukkien, "Controller Area Network
 *   (CAN) schedulability analysis: refuted, revisited and revised", Real-Time
 *   Systems 35(3), 2007, eq. 1, g = 34):
 *     bits = 8n + 47 + floor((34 + 8n - 1) / 4)
 *            (47 = 34 stuffable header/CRC bits + 13 unstuffed: CRC delimiter,
 *             ACK slot and delimiter, 7 EOF, 3 intermission)
 *     e.g. len 0: 55, len 4: 95, len 8: 135.
 *   Extended (29-bit) classic frame: the same with g = 54.
 *   CAN FD base frame (ISO 11898-1:2015 frame format; same field count as
 *   Linux include/linux/can/length.h can_frame_bits()):
 *     arbitration phase, at bitrate:
 *       SOF, 11 id, RRS, IDE, FDF, res, BRS          17
 *       dynamic stuff bits sent before BRS            3 (after bits 5, 9, 13)
 *       CRC delimiter, ACK slot, ACK delim, 7 EOF,
 *       3 intermission                               13      -> 33 bits
 *     data phase, at data_bitrate:
 *       ESI, 4 DLC, 8n data                           5 + 8n
 *       remaining dynamic stuff bits                  floor((22 + 8n - 1) / 4) - 3
 *       stuff count (3 Gray + parity)                 4
 *       CRC: 17 bits if n <= 16, else 21              17 | 21
 *       fixed stuff bits: one before the stuff count,
 *       one after every 4 bits of the CRC field       6 | 7
 *   BRS and the CRC delimiter (where the rate switches) are counted whole at
 *   the slower rate: an upper bound. Without BRS every bit is at bitrate.
 *   Extended FD frames: header 41 bits, 36 before BRS (8 stuff bits there).
 *
 *   Worked example, cia402 with 3 axes at 1 Mbit/s, T = 1 ms:
 *     SYNC 55 + 3 RPDOs x 95 = 340 bits = 340 us per 1000 us -> load 0.340.
 */
#ifndef MLIP_CANENC_H
#define MLIP_CANENC_H

#include <stddef.h>
#include <stdint.h>

#include "mlip/can/canconf.h"
#include "mlip/types.h"

#define MLIP_CAN_FLAG_EFF   0x1u /* 29-bit identifier (never produced by the encoder) */
#define MLIP_CAN_FLAG_FD    0x2u /* CAN FD frame */
#define MLIP_CAN_FLAG_BRS   0x4u /* CAN FD bit-rate switch: data phase at data_bitrate */
#define MLIP_CAN_MAX_LEN    64
#define MLIP_CAN_SFF_MAX    0x7FFu              /* largest 11-bit identifier */
#define MLIP_CAN_MAX_FRAMES (1 + MLIP_MAX_AXES) /* frames per period, any profile */

typedef enum { MLIP_CAN_CIA402 = 0, MLIP_CAN_PACKED = 1, MLIP_CAN_FD = 2 } mlip_can_profile;

/* One frame (converted to struct can_frame / canfd_frame by rt/). */
struct mlip_can_frame {
	uint32_t id;   /* 11-bit (29-bit with MLIP_CAN_FLAG_EFF), no flag bits */
	uint8_t flags; /* MLIP_CAN_FLAG_* */
	uint8_t len;   /* data bytes: 0..8 classic; FD: 0..8,12,16,20,24,32,48,64 */
	uint8_t data[MLIP_CAN_MAX_LEN];
};

/* Encoder settings, checked once by mlip_canenc_init. */
struct mlip_canenc {
	mlip_can_profile profile;
	int n_axes;       /* 1..MLIP_MAX_AXES */
	uint8_t fd_flags; /* FD, plus BRS if data_bitrate > bitrate */
	uint32_t sync_id, rpdo_base, packed_base, fd_id;
	uint8_t node[MLIP_MAX_AXES];           /* CANopen node id per axis (cia402) */
	double counts_per_unit[MLIP_MAX_AXES]; /* counts per mm or per degree */
	/* cia402 with drives brought up by mlip (mlip-rt --drives): each RPDO is
	 * 6 bytes, [0..1] controlword 0x6040 (below, set by the caller every
	 * period), [2..5] target position 0x607A. 0: the 4-byte RPDO above. */
	uint8_t rpdo_controlword;
	uint16_t controlword[MLIP_MAX_AXES];
	/* with rpdo_controlword and a touch probe on the drives ([PROBE] SOURCE
	 * = drive): each RPDO is 8 bytes, [6..7] touch probe function 0x60B8 */
	uint8_t rpdo_probe;
	uint16_t probe_fn[MLIP_MAX_AXES];
	uint32_t rpdo_mute; /* cia402: bit i set, no RPDO for axis i (a drive not
	                       in "operation enabled" is sent no target) */
};

/* A decoded period. */
struct mlip_can_setpoint {
	uint32_t cycle; /* packed, fd: from the wire; cia402: SYNCs counted
	                   by the decoder since its start, from 0 */
	int n_axes;
	int32_t counts[MLIP_MAX_AXES];
	double pos[MLIP_MAX_AXES]; /* counts / counts_per_unit: mm or deg */
};

/* "cia402" / "packed" / "fd" <-> enum. parse: MLIP_E_INVALID for anything
 * else. name: "?" out of range. */
mlip_status mlip_can_profile_parse(const char *name, mlip_can_profile *out);
const char *mlip_can_profile_name(mlip_can_profile p);

/* Valid CAN FD data length >= n (0-8, 12, 16, 20, 24, 32, 48, 64), or -1 when
 * n > 64. */
int mlip_can_fd_len(size_t n);

/* pos * counts_per_unit rounded to nearest (ties away from zero) into *counts.
 * MLIP_E_RANGE, with *counts saturated to INT32_MIN / INT32_MAX (0 for NaN),
 * when the rounded value is outside int32 or the input is not finite. */
mlip_status mlip_can_counts(double pos, double counts_per_unit, int32_t *counts);

/* Build an encoder from the [CAN] section and the machine. MLIP_E_INVALID
 * when: the profile name is unknown; n_axes is outside 1..MLIP_MAX_AXES;
 * counts_per_unit is not finite and > 0; the identifiers break the rules of
 * mlip_can_rules (mlip/can/canconf.h: its message says which and why). */
mlip_status mlip_canenc_init(struct mlip_canenc *e, const struct mlip_can_config *can,
                             const struct mlip_machine *m);

/* Frames per period: cia402 1 + n, packed ceil(n/2) + 1, fd 1. */
int mlip_canenc_frames(const struct mlip_canenc *e);

/* Encode one period: positions pos[0..n_axes-1] (mm or deg), cycle counter
 * (carried by packed and fd; the caller increments it every period, wrapping
 * at 2^32) into out[0..cap-1]; *n_out frames written. Returns MLIP_OK;
 * MLIP_E_FULL when cap < mlip_canenc_frames(e) (nothing written);
 * MLIP_E_RANGE when a position saturated: frames are complete, with the
 * saturated counts, but must not be sent; *saturated (may be NULL) gets bit i
 * set for each axis i that saturated. */
mlip_status mlip_canenc_encode(const struct mlip_canenc *e, uint32_t cycle, const double *pos,
                               struct mlip_can_frame *out, int cap, int *n_out,
                               uint32_t *saturated);

/* ---- decoding ------------------------------------------------------------ */

/* Streaming decoder: feed it every frame seen on the bus, in order. The
 * first group of fields is its working state; the counters are for tools. */
struct mlip_candec {
	struct mlip_canenc enc;
	int open;      /* a period is being collected */
	uint32_t seen; /* bit per position frame received in the open period */
	int32_t counts[MLIP_MAX_AXES];
	uint32_t syncs;      /* cia402: SYNCs seen */
	uint32_t last_cycle; /* packed, fd: counter of the last period closed */
	int have_last;
	/* statistics since init */
	uint64_t complete;   /* periods delivered */
	uint64_t incomplete; /* periods dropped because a frame was missing or repeated */
	uint64_t lost;       /* periods missing altogether (counter jumps: packed, fd) */
	uint64_t stray;      /* our position frames outside any period (cia402: before
	                        the first SYNC or after the period completed) */
	uint64_t malformed;  /* one of our ids with the wrong length or flags */
	uint64_t foreign;    /* other ids, ignored */
};

void mlip_candec_init(struct mlip_candec *d, const struct mlip_canenc *e);

/* Feed one frame. MLIP_OK: *out holds a complete period (this frame completed
 * it). MLIP_E_EMPTY: frame absorbed (or foreign, ignored), no period
 * completed. MLIP_E_SYNTAX: one of our ids but malformed; counted, ignored.
 * Completion: cia402 when all RPDOs after a SYNC are in (a SYNC before that
 * counts the open period incomplete; an RPDO twice in a period, too); packed
 * at COMMIT with every POS frame in; fd at every frame. */
mlip_status mlip_candec_feed(struct mlip_candec *d, const struct mlip_can_frame *f,
                             struct mlip_can_setpoint *out);

/* Decode exactly one encoded period (as mlip_canenc_encode made it): MLIP_OK
 * when the frames form one complete period ending at the last frame, with no
 * foreign, malformed or left-over frame; MLIP_E_SYNTAX otherwise. */
mlip_status mlip_canenc_decode(const struct mlip_canenc *e, const struct mlip_can_frame *f, int n,
                               struct mlip_can_setpoint *out);

/* ---- bus load -------------------------------------------------------------- */

/* Worst-case bits of one frame (see the header comment), split by bit rate:
 * nominal at bitrate, data at data_bitrate (non-zero only for FD with BRS). */
struct mlip_can_bits {
	uint32_t nominal;
	uint32_t data;
};
struct mlip_can_bits mlip_can_frame_bits(uint8_t flags, uint8_t len);

/* Per-period breakdown, for a tool to print. */
struct mlip_can_load {
	int frames;            /* frames per period */
	uint32_t data_bytes;   /* payload bytes per period */
	uint32_t bits_nominal; /* worst-case bits per period at bitrate */
	uint32_t bits_data;    /* ... at data_bitrate (fd with BRS) */
	double busy_s;         /* bus time per period, s */
	double load;           /* busy_s / period_s: fraction, > 1: does not fit */
	double load_pct;       /* 100 * load */
	struct {
		uint8_t flags;
		uint8_t len;
		struct mlip_can_bits bits;
		double time_s;        /* on the bus, worst case */
	} frame[MLIP_CAN_MAX_FRAMES]; /* in send order */
};

/* Fill *out for profile with n_axes axes at bitrate (and data_bitrate for the
 * FD data phase; 0 or <= bitrate: no bit-rate switch), one period of
 * period_s. MLIP_E_INVALID for n_axes outside 1..MLIP_MAX_AXES, a zero
 * bitrate, a period not finite and > 0, or an unknown profile. */
mlip_status mlip_can_load_breakdown(mlip_can_profile profile, int n_axes, uint32_t bitrate,
                                    uint32_t data_bitrate, double period_s,
                                    struct mlip_can_load *out);

/* Fraction of bus time used per period (the load field above); -1.0 for
 * invalid arguments. */
double mlip_can_bus_load(mlip_can_profile profile, int n_axes, uint32_t bitrate,
                         uint32_t data_bitrate, double period_s);

#endif
