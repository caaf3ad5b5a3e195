/*
 * mlip/canopen/io401.h - a CiA 401 digital I/O module as mlip runs it (issue
 * 18): the objects written to it at bring-up, and the input functions
 * (E-stop, hold, cycle start, probe, limit and home switches) evaluated
 * from what the bus said. Pure: rt/drives.c sends the frames and feeds back
 * what the module and the drives sent.
 *
 *   TPDO1 0x180 + n  module -> mlip: 0x6000:1..in_bytes (8 inputs each),
 *                    transmission type 255: sent on change (CiA 401 default)
 *   RPDO1 0x200 + n  mlip -> module: 0x6200:1..out_bytes (8 outputs each),
 *                    type 255: applied on reception
 *   heartbeat 0x700 + n, EMCY 0x080 + n, SDO 0x600 / 0x580 + n (CiA 301)
 */
#ifndef MLIP_IO401_H
#define MLIP_IO401_H

#include <stdint.h>

#include "mlip/canopen/drive.h"
#include "mlip/machine/config.h"
#include "mlip/types.h"

#define MLIP_IO401_SETUP_MAX 32
#define MLIP_IO401_DEVICE    401 /* 0x1000 low word */

struct mlip_io401_setup {
	uint8_t node;
	uint8_t in_bytes;  /* 0x6000:1..in_bytes in TPDO1 (1..8) */
	uint8_t out_bytes; /* 0x6200:1..out_bytes in RPDO1 (0: no RPDO) */
	uint16_t heartbeat_ms;
	uint8_t master_node; /* 0x1016:01: the module watches the master's heartbeat */
	uint16_t master_timeout_ms;
};

/* The set-up of the module, in the order it is written (each read back):
 * TPDO1 (disabled, type 255, mapping, enabled), RPDO1 likewise when
 * out_bytes > 0, heartbeat producer and consumer. The count, or -1 when cap
 * is too small or a byte count is out of range. */
int mlip_io401_setup_entries(const struct mlip_io401_setup *s, struct mlip_sdo_entry *out, int cap);

/* What the bus said of the inputs: the module's input bytes (0x6000:1..8),
 * each drive's 0x60FD (by machine axis), and which of them were read. */
struct mlip_io_image {
	uint8_t in[MLIP_IO_IN_BYTES];
	uint32_t di[MLIP_MAX_AXES];
	int module_read;      /* in[] came from the module (SDO at bring-up, or a TPDO) */
	uint32_t drives_read; /* bit k: di[k] came from drive k */
};

/* The functions that are on (bit f: MLIP_IN_*, polarity applied), and in
 * *known those whose input was read (an unread input is off). */
uint32_t mlip_io_eval(const struct mlip_io_config *io, const struct mlip_machine *m,
                      const struct mlip_io_image *img, uint32_t *known);

#endif
