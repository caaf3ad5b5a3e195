/*
 * drives.c - the [DRIVES] section (CiA 402 drives brought up by mlip-rt)
 * into its struct, and against the rest of the file.
 */
#include "keys.h"

void mlip_mc_fill_drives(const struct pstate *ps, struct mlip_drives_config *d)
{
	const struct sec *st = &ps->sec[SEC_DRIVES];
	uint32_t *const dst[NKEYS] = {NULL,
	                              NULL,
	                              &d->heartbeat_ms,
	                              &d->heartbeat_timeout_ms,
	                              NULL,
	                              &d->sdo_timeout_ms,
	                              &d->boot_timeout_ms,
	                              &d->state_timeout_ms};
	int k;

	for (k = 0; k < NKEYS; k++) {
		if (has(ps, SEC_DRIVES, k) && dst[k] != NULL) {
			*dst[k] = (uint32_t)st->ival[k];
		}
	}
	if (has(ps, SEC_DRIVES, DK_ENABLE)) {
		d->enable = (int)st->ival[DK_ENABLE];
	}
	if (has(ps, SEC_DRIVES, DK_MASTER)) {
		d->master_node = (uint8_t)st->ival[DK_MASTER];
	}
	if (has(ps, SEC_DRIVES, DK_FERR)) {
		d->following_error = st->num[DK_FERR];
	}
}

/* [DRIVES] against the rest: the drives' heartbeat is lost only after it is
 * due; the master's node is none of the drives'. */
mlip_status mlip_mc_check_drives(const struct pstate *ps, const struct mlip_config *c,
                                 struct mlip_config_error *err)
{
	const struct mlip_drives_config *d = &c->drives;
	struct mlip_tb b;
	int i;

	if (ps->sec[SEC_DRIVES].at.line == 0) {
		return MLIP_OK; /* mlip-rt --drives checks the defaults against the nodes */
	}
	if (d->heartbeat_timeout_ms <= d->heartbeat_ms) {
		err_at(err, &b, 0, 0);
		mlip_tb_puts(&b, "HEARTBEAT_TIMEOUT_MS ");
		mlip_tb_uint(&b, d->heartbeat_timeout_ms);
		mlip_tb_puts(&b, " must be > HEARTBEAT_MS ");
		mlip_tb_uint(&b, d->heartbeat_ms);
		mlip_tb_puts(&b, " (a heartbeat is lost only after it is due)");
		mlip_mc_place(ps, err, SEC_DRIVES, DK_HB_TIMEOUT, SEC_DRIVES, DK_HB, -1, 0);
		return MLIP_E_RANGE;
	}
	for (i = 0; i < c->machine.n_axes; i++) {
		if (c->machine.axis[i].can_node == d->master_node) {
			int sec = SEC_AXIS0 + letter_index(c->machine.axis[i].letter);
			err_at(err, &b, 0, 0);
			mlip_tb_puts(&b, "MASTER_NODE ");
			mlip_tb_uint(&b, d->master_node);
			mlip_tb_puts(&b, " is also the CAN_NODE of AXIS_");
			mlip_tb_putc(&b, c->machine.axis[i].letter);
			mlip_mc_place(ps, err, SEC_DRIVES, DK_MASTER, sec, AK_NODE, -1, 0);
			return MLIP_E_RANGE;
		}
	}
	return MLIP_OK;
}
