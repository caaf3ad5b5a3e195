/*
 * mlip/can/canconf.h - the [CAN] section of the machine configuration (read
 * by mlip/machine/config.h, used by the encoder and rt/) and the CAN id
 * rules, the one home of them: the INI reader (which places a broken rule
 * on the keys involved), mlip_canenc_init and mlip-rt after --profile all
 * use mlip_can_rules, so that what the reader accepts the encoder accepts,
 * and the reverse.
 *
 * The rules, for the profile can->profile names: every identifier sent each
 * period (cia402: SYNC_ID and RPDO_BASE + CAN_NODE of each axis, nodes
 * 1..127, distinct; packed: PACKED_BASE + k for the ceil(n/2) position
 * frames and the commit frame; fd: FD_ID) is an 11-bit id and not
 * STATUS_ID; SYNC_ID != STATUS_ID; with fd, DATA_BITRATE >= BITRATE.
 */
#ifndef MLIP_CANCONF_H
#define MLIP_CANCONF_H

#include <stdint.h>

#include "mlip/types.h"

#define MLIP_CAN_ID_MAX   0x7FFu /* largest 11-bit (base format) id */
#define MLIP_CAN_NODE_MAX 127    /* CANopen node ids 1..127 */
#define MLIP_CAN_MSG      256

/* [CAN] section: output settings for the real-time controller. */
struct mlip_can_config {
	char profile[8];       /* "cia402" (default), "packed", "fd" */
	uint32_t bitrate;      /* bit/s, default 1000000 */
	uint32_t data_bitrate; /* CAN FD data phase bit/s, default 5000000 */
	uint32_t sync_id;      /* default 0x080 */
	uint32_t rpdo_base;    /* default 0x200 (+ node id) */
	uint32_t packed_base;  /* default 0x300 (+ frame index) */
	uint32_t fd_id;        /* default 0x400 */
	uint32_t status_id;    /* default 0x180: controller status frame */
};

/* The keys a broken rule involves: the [CAN] keys in the section's order,
 * and the CAN_NODE of an axis. */
enum mlip_can_key {
	MLIP_CAN_KEY_PROFILE,
	MLIP_CAN_KEY_BITRATE,
	MLIP_CAN_KEY_DATA_BITRATE,
	MLIP_CAN_KEY_SYNC_ID,
	MLIP_CAN_KEY_RPDO_BASE,
	MLIP_CAN_KEY_PACKED_BASE,
	MLIP_CAN_KEY_FD_ID,
	MLIP_CAN_KEY_STATUS_ID,
	MLIP_CAN_KEY_NODE /* CAN_NODE of [AXIS_<letter of axis>] */
};

/* Why the rules refuse a configuration: the message (e.g. "PACKED_BASE
 * 0x17F + 1 = 0x180 (position frame 1 of 3 axes) is also the STATUS_ID")
 * and the keys involved, the one to blame first. */
struct mlip_can_issue {
	char msg[MLIP_CAN_MSG];
	int n_keys; /* 0..3 */
	struct {
		int key;  /* enum mlip_can_key */
		int axis; /* MLIP_CAN_KEY_NODE: index of the axis in the machine */
	} at[3];
};

/* MLIP_OK, or the error (MLIP_E_INVALID: unknown profile, axis count
 * outside 1..6; MLIP_E_RANGE: an id rule) with *is filled (is may be NULL). */
mlip_status mlip_can_rules(const struct mlip_can_config *can, const struct mlip_machine *m,
                           struct mlip_can_issue *is);

#endif
