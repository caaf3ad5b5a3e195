/*
 * probesim.c - a probe touching a surface, off-line (probesim.h).
 */
#include "probesim.h"

#include <stdlib.h>
#include <string.h>

int mlip_probesim_parse(struct mlip_probesim *p, const char *arg, const char *letters,
                        const char **why)
{
	const char *l = arg[0] != '\0' ? strchr(letters, arg[0]) : NULL;
	char *end;
	memset(p, 0, sizeof(*p));
	p->axis = -1;
	if (l == NULL || arg[1] != '=') {
		*why = "expected AXIS=POS[,below|above] with an axis of the machine (Z=-5)";
		return -1;
	}
	p->at = strtod(arg + 2, &end);
	if (end == arg + 2 || (*end != '\0' && *end != ',')) {
		*why = "POS must be a number (mm, machine coordinates)";
		return -1;
	}
	p->below = 1;
	if (*end == ',') {
		if (strcmp(end + 1, "above") == 0) {
			p->below = 0;
		} else if (strcmp(end + 1, "below") != 0) {
			*why = "the side must be below (on at and below POS) or above";
			return -1;
		}
	}
	p->axis = (int)(l - letters);
	return 0;
}

void mlip_probesim_start(struct mlip_probesim *p, int drive, int n_axes, const double *start)
{
	p->drive = drive;
	p->n_axes = n_axes;
	p->n = 0;
	p->fn_now = p->status = 0;
	p->latches = 0;
	memset(p->fn, 0, sizeof(p->fn));
	memset(p->pos, 0, sizeof(p->pos));
	if (!drive) {
		/* the module: period q reads the position of slot q - 1 */
		memcpy(p->pos[0], start, sizeof(double) * (size_t)n_axes);
		p->n = 1;
	}
}

static int touching(const struct mlip_probesim *p, double x)
{
	return p->below ? x <= p->at : x >= p->at;
}

/* The drives at the SYNC of period q - 1: the RPDO of q - 3 applied at the
 * SYNC of q - 2, the move from the target of q - 4 to it since. */
static void drives_in(struct mlip_probesim *p, struct mlip_ctl_in *in)
{
	uint64_t q = p->n;
	for (int k = 0; k < MLIP_MAX_AXES; k++) {
		in->drives.tpdo_period[k] = UINT64_MAX;
		in->drives.tp_latch_period[k] = UINT64_MAX;
	}
	if (q < 4) {
		return;
	}
	uint16_t fn = p->fn[(q - 3) % 4];
	if (!(fn & 1u)) {
		p->status = 0;
	} else if (!(p->fn_now & 1u)) {
		p->status = 1; /* switched on: armed, nothing stored */
	}
	p->fn_now = fn;
	const double *a = p->pos[(q - 4) % 4], *b = p->pos[(q - 3) % 4];
	if (p->axis >= 0 && touching(p, a[p->axis]) != touching(p, b[p->axis])) {
		int on = touching(p, b[p->axis]);
		uint16_t edge = on ? 0x10u : 0x20u, stored = on ? 2u : 4u;
		if ((fn & 1u) && (fn & edge) && !(p->status & stored)) {
			double f = (p->at - a[p->axis]) / (b[p->axis] - a[p->axis]);
			for (int k = 0; k < p->n_axes; k++) {
				p->latched[k] = k == p->axis ? p->at : a[k] + f * (b[k] - a[k]);
			}
			p->status |= stored;
			p->latches++;
		}
	}
	for (int k = 0; k < p->n_axes; k++) {
		in->drives.tpdo_period[k] = q - 1;
		in->drives.tp_latch_period[k] = q - 1;
		in->drives.tp_status[k] = p->status;
		in->drives.tp_pos[k] = p->latched[k];
		in->drives.tp_neg[k] = p->latched[k];
	}
}

void mlip_probesim_in(struct mlip_probesim *p, struct mlip_ctl_in *in)
{
	if (p->drive) {
		drives_in(p, in);
		return;
	}
	/* the module: on from the period after the setpoint reached it (the
	 * first period: where the axes stood) */
	uint32_t bit = 1u << MLIP_IN_PROBE;
	in->io.active &= ~bit;
	if (p->axis >= 0 && touching(p, p->pos[(p->n - 1) % 4][p->axis])) {
		in->io.active |= bit;
	}
}

void mlip_probesim_out(struct mlip_probesim *p, const double *pos, uint16_t tp_fn)
{
	p->fn[p->n % 4] = tp_fn;
	memcpy(p->pos[p->n % 4], pos, sizeof(p->pos[0]));
	p->n++;
}
