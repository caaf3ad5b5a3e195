/*
 * canconf.c - the CAN id rules of mlip/can/canconf.h.
 */
#include "mlip/can/canconf.h"

#include <string.h>

#include "mlip/can/canenc.h"
#include "mlip/text/format.h"

static void at(struct mlip_can_issue *is, int k1, int a1, int k2, int a2, int k3, int a3)
{
	const int key[3] = {k1, k2, k3}, axis[3] = {a1, a2, a3};
	int i;

	is->n_keys = 0;
	for (i = 0; i < 3 && key[i] >= 0; i++) {
		is->at[i].key = key[i];
		is->at[i].axis = axis[i];
		is->n_keys++;
	}
}

/* "RPDO_BASE 0x200 + CAN_NODE 3 of AXIS_Z" (the id's sum follows) */
static void tb_rpdo(struct mlip_tb *b, const struct mlip_can_config *can, const struct mlip_axis *a)
{
	mlip_tb_puts(b, "RPDO_BASE ");
	mlip_tb_hex(b, can->rpdo_base, 3);
	mlip_tb_puts(b, " + CAN_NODE ");
	mlip_tb_uint(b, (uint64_t)a->can_node);
	mlip_tb_puts(b, " of AXIS_");
	mlip_tb_putc(b, a->letter);
}

mlip_status mlip_can_rules(const struct mlip_can_config *can, const struct mlip_machine *m,
                           struct mlip_can_issue *is)
{
	const uint32_t other[2] = {can->sync_id, can->status_id};
	static const char *const other_name[2] = {"SYNC_ID", "STATUS_ID"};
	const int other_key[2] = {MLIP_CAN_KEY_SYNC_ID, MLIP_CAN_KEY_STATUS_ID};
	char name[sizeof can->profile + 1];
	struct mlip_can_issue dummy;
	mlip_can_profile p;
	struct mlip_tb b;
	int i, j, prof;

	if (is == NULL) {
		is = &dummy;
	}
	mlip_tb_init(&b, is->msg, sizeof is->msg);
	at(is, -1, 0, -1, 0, -1, 0);
	memcpy(name, can->profile, sizeof can->profile);
	name[sizeof can->profile] = '\0';
	if (mlip_can_profile_parse(name, &p) != MLIP_OK) {
		mlip_tb_puts(&b, "PROFILE '");
		mlip_tb_token(&b, name, strlen(name));
		mlip_tb_puts(&b, "' must be cia402, packed or fd");
		at(is, MLIP_CAN_KEY_PROFILE, 0, -1, 0, -1, 0);
		return MLIP_E_INVALID;
	}
	prof = (int)p;
	if (m->n_axes < 1 || m->n_axes > MLIP_MAX_AXES) {
		mlip_tb_puts(&b, "CAN output needs 1 to 6 axes");
		return MLIP_E_INVALID;
	}
	for (i = 0; prof == MLIP_CAN_CIA402 && i < m->n_axes; i++) {
		const struct mlip_axis *a = &m->axis[i];
		uint64_t id = (uint64_t)can->rpdo_base + (uint64_t)a->can_node;
		if (a->can_node < 1 || a->can_node > MLIP_CAN_NODE_MAX) {
			mlip_tb_puts(&b, "AXIS_");
			mlip_tb_putc(&b, a->letter);
			mlip_tb_puts(&b, " CAN_NODE must be within 1..127 with PROFILE cia402");
			at(is, MLIP_CAN_KEY_NODE, i, MLIP_CAN_KEY_PROFILE, 0, -1, 0);
			return MLIP_E_RANGE;
		}
		if (id > MLIP_CAN_ID_MAX) {
			tb_rpdo(&b, can, a);
			mlip_tb_puts(&b, " = ");
			mlip_tb_hex(&b, (uint32_t)(id > 0xFFFFFFFFu ? 0xFFFFFFFFu : id), 3);
			mlip_tb_puts(&b, " is not an 11-bit id (at most 0x7FF)");
			at(is, MLIP_CAN_KEY_RPDO_BASE, 0, MLIP_CAN_KEY_NODE, i, -1, 0);
			return MLIP_E_RANGE;
		}
		for (j = 0; j < 2; j++) {
			if (other[j] == id) {
				mlip_tb_puts(&b, other_name[j]);
				mlip_tb_putc(&b, ' ');
				mlip_tb_hex(&b, other[j], 3);
				mlip_tb_puts(&b, " is also the RPDO of AXIS_");
				mlip_tb_putc(&b, a->letter);
				mlip_tb_puts(&b, " (RPDO_BASE + CAN_NODE ");
				mlip_tb_uint(&b, (uint64_t)a->can_node);
				mlip_tb_putc(&b, ')');
				at(is, other_key[j], 0, MLIP_CAN_KEY_RPDO_BASE, 0,
				   MLIP_CAN_KEY_NODE, i);
				return MLIP_E_RANGE;
			}
		}
		for (j = 0; j < i; j++) {
			if (m->axis[j].can_node == a->can_node) {
				tb_rpdo(&b, can, a);
				mlip_tb_puts(&b, " is also the RPDO of AXIS_");
				mlip_tb_putc(&b, m->axis[j].letter);
				at(is, MLIP_CAN_KEY_NODE, i, MLIP_CAN_KEY_NODE, j, -1, 0);
				return MLIP_E_RANGE;
			}
		}
	}
	if (can->sync_id == can->status_id) {
		mlip_tb_puts(&b, "STATUS_ID ");
		mlip_tb_hex(&b, can->status_id, 3);
		mlip_tb_puts(&b, " is also the SYNC_ID");
		at(is, MLIP_CAN_KEY_STATUS_ID, 0, MLIP_CAN_KEY_SYNC_ID, 0, -1, 0);
		return MLIP_E_RANGE;
	}
	if (prof == MLIP_CAN_PACKED) {
		/* ceil(n/2) position frames, then the commit frame */
		int nf = (m->n_axes + 1) / 2;
		for (i = 0; i <= nf; i++) {
			uint64_t id = (uint64_t)can->packed_base + (uint64_t)i;
			int over = id > MLIP_CAN_ID_MAX;
			if (!over && id != can->status_id) {
				continue;
			}
			mlip_tb_puts(&b, "PACKED_BASE ");
			mlip_tb_hex(&b, can->packed_base, 3);
			mlip_tb_puts(&b, " + ");
			mlip_tb_uint(&b, (uint64_t)i);
			mlip_tb_puts(&b, " = ");
			mlip_tb_hex(&b, (uint32_t)(id > 0xFFFFFFFFu ? 0xFFFFFFFFu : id), 3);
			mlip_tb_puts(&b, i < nf ? " (position frame " : " (the commit frame");
			if (i < nf) {
				mlip_tb_uint(&b, (uint64_t)i);
			}
			mlip_tb_puts(&b, " of ");
			mlip_tb_uint(&b, (uint64_t)m->n_axes);
			mlip_tb_puts(&b, over ? " axes) is not an 11-bit id (at most 0x7FF)"
			                      : " axes) is also the STATUS_ID");
			at(is, MLIP_CAN_KEY_PACKED_BASE, 0,
			   over ? MLIP_CAN_KEY_PROFILE : MLIP_CAN_KEY_STATUS_ID, 0,
			   MLIP_CAN_KEY_PROFILE, 0);
			return MLIP_E_RANGE;
		}
	}
	if (prof == MLIP_CAN_FD && (can->fd_id > MLIP_CAN_ID_MAX || can->fd_id == can->status_id)) {
		mlip_tb_puts(&b, "FD_ID ");
		mlip_tb_hex(&b, can->fd_id, 3);
		mlip_tb_puts(&b, can->fd_id > MLIP_CAN_ID_MAX
		                     ? " is not an 11-bit id (at most 0x7FF)"
		                     : " is also the STATUS_ID");
		at(is, MLIP_CAN_KEY_FD_ID, 0, MLIP_CAN_KEY_STATUS_ID, 0, MLIP_CAN_KEY_PROFILE, 0);
		return MLIP_E_RANGE;
	}
	if (prof == MLIP_CAN_FD && can->data_bitrate < can->bitrate) {
		mlip_tb_puts(&b, "DATA_BITRATE ");
		mlip_tb_uint(&b, can->data_bitrate);
		mlip_tb_puts(&b, " must be >= BITRATE ");
		mlip_tb_uint(&b, can->bitrate);
		mlip_tb_puts(&b, " with PROFILE fd");
		at(is, MLIP_CAN_KEY_DATA_BITRATE, 0, MLIP_CAN_KEY_BITRATE, 0, MLIP_CAN_KEY_PROFILE,
		   0);
		return MLIP_E_RANGE;
	}
	return MLIP_OK;
}
