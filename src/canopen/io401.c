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
	uint32_t in[MLIP_IO_IN_BYTES], outs[MLIP_IO_IN_BYTES];
	const struct mlip_pdo_map tpdo = {.tpdo = 1,
	                                  .num = 1,
	                                  .cob_id = 0x180u + s->node,
	                                  .type = 255,
	                                  .type_what = "TPDO1 transmission type (255: on change)",
	                                  .n = s->in_bytes,
	                                  .map = in,
	                                  .what = in_map};
	const struct mlip_pdo_map rpdo = {.num = 1,
	                                  .cob_id = 0x200u + s->node,
	                                  .type = 255,
	                                  .type_what =
	                                      "RPDO1 transmission type (255: on reception)",
	                                  .n = s->out_bytes,
	                                  .map = outs,
	                                  .what = out_map};
	struct mlip_sdo_list l = {out, cap, 0};
	uint32_t k;

	if (s->in_bytes < 1 || s->in_bytes > MLIP_IO_IN_BYTES || s->out_bytes > MLIP_IO_IN_BYTES) {
		return -1;
	}
	/* 0x6000:k, 0x6200:k: 8 bits each */
	for (k = 1; k <= MLIP_IO_IN_BYTES; k++) {
		in[k - 1] = 0x60000008u | k << 8;
		outs[k - 1] = 0x62000008u | k << 8;
	}
	if (mlip_sdo_add_pdo(&l, &tpdo) != MLIP_OK ||
	    (s->out_bytes > 0 && mlip_sdo_add_pdo(&l, &rpdo) != MLIP_OK)) {
		return -1;
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
