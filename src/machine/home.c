/*
 * home.c - the axes' HOME_* keys and [DRIVES] HOMING_REQUIRED (issue 18:
 * homing with the drives' own homing mode) into mlip_home_config, checked
 * against the machine.
 */
#include <math.h>
#include <string.h>

#include "keys.h"

static mlip_status home_err(const struct pstate *ps, struct mlip_config_error *err, int sec,
                            int key)
{
	mlip_mc_place(ps, err, sec, key, -1, 0, -1, 0);
	return MLIP_E_RANGE;
}

mlip_status mlip_mc_fill_home(const struct pstate *ps, struct mlip_config *c,
                              struct mlip_config_error *err)
{
	struct mlip_home_config *h = &c->home;
	const struct mlip_machine *m = &c->machine;
	struct mlip_tb b;
	int i, k;

	memset(h, 0, sizeof *h);
	if (has(ps, SEC_DRIVES, DK_HOMING_REQUIRED)) {
		h->required = (int)ps->sec[SEC_DRIVES].ival[DK_HOMING_REQUIRED];
	}
	for (i = 0; i < m->n_axes; i++) {
		const struct mlip_axis *a = &m->axis[i];
		int sec = SEC_AXIS0 + letter_index(a->letter);
		const struct sec *st = &ps->sec[sec];
		struct mlip_axis_home *x = &h->axis[i];
		double cpu = a->counts_per_unit;
		x->configured = has(ps, sec, AK_HOME_METHOD);
		if (!x->configured) {
			for (k = AK_HOME_SEARCH_VEL; k <= AK_HOME_TIMEOUT; k++) {
				if (has(ps, sec, k)) {
					err_at(err, &b, 0, 0);
					mlip_tb_puts(&b, "AXIS_");
					mlip_tb_putc(&b, a->letter);
					mlip_tb_putc(&b, ' ');
					mlip_tb_puts(&b, mlip_mc_keytab[K_AXIS][k].name);
					mlip_tb_puts(
					    &b, " without HOME_METHOD (homing is configured by "
					        "the drive's method, 0x6098)");
					return home_err(ps, err, sec, k);
				}
			}
			continue;
		}
		x->method = (int)st->ival[AK_HOME_METHOD];
		x->search_vel = has(ps, sec, AK_HOME_SEARCH_VEL) ? st->num[AK_HOME_SEARCH_VEL]
		                                                 : a->max_vel * 0.1;
		x->latch_vel = has(ps, sec, AK_HOME_LATCH_VEL) ? st->num[AK_HOME_LATCH_VEL]
		                                               : x->search_vel * 0.1;
		x->accel = has(ps, sec, AK_HOME_ACCEL) ? st->num[AK_HOME_ACCEL] : a->max_accel;
		x->offset = has(ps, sec, AK_HOME_OFFSET) ? st->num[AK_HOME_OFFSET] : 0.0;
		x->sequence = has(ps, sec, AK_HOME_SEQUENCE) ? (int)st->ival[AK_HOME_SEQUENCE]
		              : a->letter == 'Z'             ? 0
		                                             : 1;
		x->timeout_s = has(ps, sec, AK_HOME_TIMEOUT) ? st->num[AK_HOME_TIMEOUT] : 60.0;
		if (!(x->offset >= a->min_limit && x->offset <= a->max_limit)) {
			err_at(err, &b, 0, 0);
			mlip_tb_puts(&b, "AXIS_");
			mlip_tb_putc(&b, a->letter);
			mlip_tb_puts(&b, " HOME_OFFSET ");
			mlip_tb_double(&b, x->offset);
			mlip_tb_puts(&b, " is outside MIN_LIMIT..MAX_LIMIT: the axis would stand "
			                 "beyond its soft limits after homing");
			return home_err(ps, err, sec,
			                has(ps, sec, AK_HOME_OFFSET) ? AK_HOME_OFFSET
			                                             : AK_HOME_METHOD);
		}
		{
			/* the drive's objects: UNSIGNED32 counts/s and counts/s^2,
			 * INTEGER32 counts */
			const double v[4] = {x->search_vel * cpu, x->latch_vel * cpu,
			                     x->accel * cpu, fabs(x->offset) * cpu};
			const int key[4] = {AK_HOME_SEARCH_VEL, AK_HOME_LATCH_VEL, AK_HOME_ACCEL,
			                    AK_HOME_OFFSET};
			const double max[4] = {4294967295.0, 4294967295.0, 4294967295.0,
			                       2147483647.0};
			for (k = 0; k < 4; k++) {
				if (!(v[k] >= (k < 3 ? 1.0 : 0.0) && v[k] <= max[k])) {
					err_at(err, &b, 0, 0);
					mlip_tb_puts(&b, "AXIS_");
					mlip_tb_putc(&b, a->letter);
					mlip_tb_putc(&b, ' ');
					mlip_tb_puts(&b, mlip_mc_keytab[K_AXIS][key[k]].name);
					mlip_tb_puts(&b, " is ");
					mlip_tb_double(&b, v[k]);
					mlip_tb_puts(
					    &b, k < 3 ? " counts/s: not 1..2^32-1 (0x6099, 0x609A)"
					              : " counts: beyond 0x607C's INTEGER32");
					return home_err(ps, err, sec,
					                has(ps, sec, key[k]) ? key[k]
					                                     : AK_HOME_METHOD);
				}
			}
		}
	}
	return MLIP_OK;
}
