/*
 * io401.c - a CiA 401 I/O module's set-up and the input functions
 * (mlip/canopen/io401.h). Pure.
 */
#include "mlip/canopen/io401.h"

#include <string.h>

int mlip_io401_setup_entries(const struct mlip_io401_setup *s, struct mlip_sdo_entry *out, int cap)
{
	static const char *const in_map[MLIP_IO_IN_BYTES] = {
	    "TPDO1 mapping: digital inputs 0x6000:1", "TPDO1 mapping: digital inputs 0x6000:2",
	    "TPDO1 mapping: digital inputs 0x6000:3", "TPDO1 mapping: digital inputs 0x6000:4",
	    "TPDO1 mapping: digital inputs 0x6000:5", "TPDO1 mapping: digital inputs 0x6000:6",
	    "TPDO1 mapping: digital inputs 0x6000:7", "TPDO1 mapping: digital inputs 0x6000:8"};
	static const char *const out_map[MLIP_IO_IN_BYTES] = {
	    "RPDO1 mapping: digital outputs 0x6200:1", "RPDO1 mapping: digital outputs 0x6200:2",
	    "RPDO1 mapping: digital outputs 0x6200:3", "RPDO1 mapping: digital outputs 0x6200:4",
	    "RPDO1 mapping: digital outputs 0x6200:5", "RPDO1 mapping: digital outputs 0x6200:6",
	    "RPDO1 mapping: digital outputs 0x6200:7", "RPDO1 mapping: digital outputs 0x6200:8"};
	const uint32_t off = 0x80000000u, no_rtr = 0x40000000u;
	const uint32_t tpdo = 0x180u + s->node, rpdo = 0x200u + s->node;
	struct mlip_sdo_list l = {out, cap, 0};
	uint32_t k;

	if (s->in_bytes < 1 || s->in_bytes > MLIP_IO_IN_BYTES || s->out_bytes > MLIP_IO_IN_BYTES) {
		return -1;
	}
	mlip_sdo_add(&l, 0x1800, 1, 4, off | no_rtr | tpdo,
	             "TPDO1 COB-ID (disabled while mapping)");
	mlip_sdo_add(&l, 0x1800, 2, 1, 255, "TPDO1 transmission type (255: on change)");
	mlip_sdo_add(&l, 0x1A00, 0, 1, 0, "TPDO1 mapping count (cleared)");
	for (k = 1; k <= s->in_bytes; k++) {
		mlip_sdo_add(&l, 0x1A00, (uint8_t)k, 4, 0x60000008u | k << 8, in_map[k - 1]);
	}
	mlip_sdo_add(&l, 0x1A00, 0, 1, s->in_bytes, "TPDO1 mapping count");
	mlip_sdo_add(&l, 0x1800, 1, 4, no_rtr | tpdo, "TPDO1 COB-ID");
	if (s->out_bytes > 0) {
		mlip_sdo_add(&l, 0x1400, 1, 4, off | rpdo, "RPDO1 COB-ID (disabled while mapping)");
		mlip_sdo_add(&l, 0x1400, 2, 1, 255, "RPDO1 transmission type (255: on reception)");
		mlip_sdo_add(&l, 0x1600, 0, 1, 0, "RPDO1 mapping count (cleared)");
		for (k = 1; k <= s->out_bytes; k++) {
			mlip_sdo_add(&l, 0x1600, (uint8_t)k, 4, 0x62000008u | k << 8,
			             out_map[k - 1]);
		}
		mlip_sdo_add(&l, 0x1600, 0, 1, s->out_bytes, "RPDO1 mapping count");
		mlip_sdo_add(&l, 0x1400, 1, 4, rpdo, "RPDO1 COB-ID");
	}
	mlip_sdo_add(&l, 0x1017, 0, 2, s->heartbeat_ms, "producer heartbeat time (ms)");
	mlip_sdo_add(&l, 0x1016, 1, 4, ((uint32_t)s->master_node << 16) | s->master_timeout_ms,
	             "consumer heartbeat time: the master's node and timeout (ms)");
	return l.n > cap ? -1 : l.n;
}

uint32_t mlip_io_eval(const struct mlip_io_config *io, const struct mlip_machine *m,
                      const struct mlip_io_image *img, uint32_t *known)
{
	uint32_t on = 0, seen = 0, f;

	for (f = 0; f < MLIP_IN_COUNT; f++) {
		const struct mlip_io_bit *b = &io->in[f];
		uint32_t v;
		int k, read = 0;
		if (!(io->mapped & (1u << f))) {
			continue;
		}
		if (b->node == io->node && b->index == 0x6000 && b->sub >= 1 &&
		    b->sub <= MLIP_IO_IN_BYTES) {
			read = img->module_read;
			v = (img->in[b->sub - 1] >> (b->bit & 7)) & 1u;
		} else {
			v = 0;
			for (k = 0; k < m->n_axes; k++) {
				if (m->axis[k].can_node == b->node) {
					read = (img->drives_read >> k) & 1u;
					v = (img->di[k] >> (b->bit & 31)) & 1u;
				}
			}
		}
		if (!read) {
			continue;
		}
		seen |= 1u << f;
		if (v != b->active_low) {
			on |= 1u << f;
		}
	}
	if (known != NULL) {
		*known = seen;
	}
	return on;
}
