/*
 * drive.c - a CiA 402 drive in cyclic synchronous position mode as mlip sets it
 * up and supervises it (mlip/canopen/drive.h). Pure.
 */
#include "mlip/canopen/drive.h"

#include <math.h>
#include <string.h>

/* ---- the set-up list -------------------------------------------------------------------- */

mlip_status mlip_co_interp_period(double period_s, uint8_t *value, int8_t *index)
{
	double scale = 1.0;
	int idx;

	if (!isfinite(period_s) || !(period_s > 0.0)) {
		return MLIP_E_RANGE;
	}
	/* the largest exponent whose mantissa is a whole 1..255 */
	for (idx = 0; idx >= -6; idx--, scale *= 10.0) {
		double v = period_s * scale, r = round(v);
		if (r >= 1.0 && r <= 255.0 && fabs(v - r) <= 1e-9 * r) {
			*value = (uint8_t)r;
			*index = (int8_t)idx;
			return MLIP_OK;
		}
	}
	return MLIP_E_RANGE;
}

int mlip_drive_setup_entries(const struct mlip_drive_setup *d, struct mlip_sdo_entry *out, int cap)
{
	/* COB-ID bit 31: PDO not valid (disabled while it is mapped); bit 30 of
	 * a TPDO: no RTR allowed */
	const uint32_t off = 0x80000000u, no_rtr = 0x40000000u;
	uint8_t pv;
	int8_t pi;
	struct mlip_sdo_list l = {out, cap, 0};

	if (mlip_co_interp_period(d->period_s, &pv, &pi) != MLIP_OK) {
		return -1;
	}
	mlip_sdo_add(&l, 0x1400, 1, 4, off | d->rpdo_cob, "RPDO1 COB-ID (disabled while mapping)");
	mlip_sdo_add(&l, 0x1400, 2, 1, 1, "RPDO1 transmission type (synchronous)");
	mlip_sdo_add(&l, 0x1600, 0, 1, 0, "RPDO1 mapping count (cleared)");
	mlip_sdo_add(&l, 0x1600, 1, 4, 0x60400010u, "RPDO1 mapping 1: controlword 0x6040");
	if (d->velocity) {
		mlip_sdo_add(&l, 0x1600, 2, 4, 0x60FF0020u,
		             "RPDO1 mapping 2: target velocity 0x60FF");
	} else {
		mlip_sdo_add(&l, 0x1600, 2, 4, 0x607A0020u,
		             "RPDO1 mapping 2: target position 0x607A");
	}
	if (d->touch_probe) {
		mlip_sdo_add(&l, 0x1600, 3, 4, 0x60B80010u,
		             "RPDO1 mapping 3: touch probe function 0x60B8");
	}
	mlip_sdo_add(&l, 0x1600, 0, 1, d->touch_probe ? 3 : 2, "RPDO1 mapping count");
	mlip_sdo_add(&l, 0x1400, 1, 4, d->rpdo_cob, "RPDO1 COB-ID");
	mlip_sdo_add(&l, 0x1800, 1, 4, off | no_rtr | d->tpdo_cob,
	             "TPDO1 COB-ID (disabled while mapping)");
	mlip_sdo_add(&l, 0x1800, 2, 1, 1, "TPDO1 transmission type (synchronous, every SYNC)");
	mlip_sdo_add(&l, 0x1A00, 0, 1, 0, "TPDO1 mapping count (cleared)");
	mlip_sdo_add(&l, 0x1A00, 1, 4, 0x60410010u, "TPDO1 mapping 1: statusword 0x6041");
	if (d->velocity) {
		mlip_sdo_add(&l, 0x1A00, 2, 4, 0x606C0020u,
		             "TPDO1 mapping 2: velocity actual value 0x606C");
	} else {
		mlip_sdo_add(&l, 0x1A00, 2, 4, 0x60640020u,
		             "TPDO1 mapping 2: position actual value 0x6064");
	}
	if (d->touch_probe) {
		mlip_sdo_add(&l, 0x1A00, 3, 4, 0x60B90010u,
		             "TPDO1 mapping 3: touch probe status 0x60B9");
	}
	mlip_sdo_add(&l, 0x1A00, 0, 1, d->touch_probe ? 3 : 2, "TPDO1 mapping count");
	mlip_sdo_add(&l, 0x1800, 1, 4, no_rtr | d->tpdo_cob, "TPDO1 COB-ID");
	if (d->touch_probe) {
		/* the latched positions, sampled at the same SYNC as TPDO1 */
		mlip_sdo_add(&l, 0x1801, 1, 4, off | no_rtr | d->tpdo2_cob,
		             "TPDO2 COB-ID (disabled while mapping)");
		mlip_sdo_add(&l, 0x1801, 2, 1, 1,
		             "TPDO2 transmission type (synchronous, every SYNC)");
		mlip_sdo_add(&l, 0x1A01, 0, 1, 0, "TPDO2 mapping count (cleared)");
		mlip_sdo_add(&l, 0x1A01, 1, 4, 0x60BA0020u,
		             "TPDO2 mapping 1: touch probe 1 positive edge position 0x60BA");
		mlip_sdo_add(&l, 0x1A01, 2, 4, 0x60BB0020u,
		             "TPDO2 mapping 2: touch probe 1 negative edge position 0x60BB");
		mlip_sdo_add(&l, 0x1A01, 0, 1, 2, "TPDO2 mapping count");
		mlip_sdo_add(&l, 0x1801, 1, 4, no_rtr | d->tpdo2_cob, "TPDO2 COB-ID");
		mlip_sdo_add(&l, 0x60B8, 0, 2, 0, "touch probe function (off until a G38)");
	}
	if (d->di_tpdo_cob != 0) {
		/* TPDO3: TPDO2 may be the touch probe's */
		mlip_sdo_add(&l, 0x1802, 1, 4, off | no_rtr | d->di_tpdo_cob,
		             "TPDO3 COB-ID (disabled while mapping)");
		mlip_sdo_add(&l, 0x1802, 2, 1, 255, "TPDO3 transmission type (255: on change)");
		mlip_sdo_add(&l, 0x1802, 5, 2, d->di_event_ms,
		             "TPDO3 event timer (ms): the inputs at least this often");
		mlip_sdo_add(&l, 0x1A02, 0, 1, 0, "TPDO3 mapping count (cleared)");
		mlip_sdo_add(&l, 0x1A02, 1, 4, 0x60FD0020u,
		             "TPDO3 mapping 1: digital inputs 0x60FD");
		mlip_sdo_add(&l, 0x1A02, 0, 1, 1, "TPDO3 mapping count");
		mlip_sdo_add(&l, 0x1802, 1, 4, no_rtr | d->di_tpdo_cob, "TPDO3 COB-ID");
	}
	mlip_sdo_add(&l, 0x1005, 0, 4, d->sync_id, "COB-ID SYNC (consumer)");
	if (d->velocity) {
		mlip_sdo_add(&l, 0x6060, 0, 1, MLIP_402_MODE_PV,
		             "modes of operation (3: profile velocity)");
		mlip_sdo_add_check(&l, 0x6061, 0, 1, MLIP_402_MODE_PV,
		                   "modes of operation display");
		mlip_sdo_add(&l, 0x60FF, 0, 4, 0,
		             "target velocity (0 until the spindle is asked to turn)");
		mlip_sdo_add(&l, 0x6083, 0, 4, d->accel_counts_s2,
		             "profile acceleration (counts/s^2)");
		mlip_sdo_add(&l, 0x6084, 0, 4, d->accel_counts_s2,
		             "profile deceleration (counts/s^2)");
	} else {
		mlip_sdo_add(&l, 0x6060, 0, 1, MLIP_402_MODE_CSP,
		             "modes of operation (8: cyclic synchronous position)");
		mlip_sdo_add_check(&l, 0x6061, 0, 1, MLIP_402_MODE_CSP,
		                   "modes of operation display");
	}
	/* the SYNC period (a spindle's ramp is its own, but its TPDO timing is
	 * the SYNC's) */
	mlip_sdo_add(&l, 0x60C2, 1, 1, pv, "interpolation time period value");
	mlip_sdo_add(&l, 0x60C2, 2, 1, (uint8_t)pi, "interpolation time index");
	if (!d->velocity) {
		mlip_sdo_add(&l, 0x6065, 0, 4, d->following_window_counts,
		             "following error window");
	}
	if (d->quick_stop_counts_s2 != 0) {
		mlip_sdo_add(&l, 0x6085, 0, 4, d->quick_stop_counts_s2,
		             "quick stop deceleration (counts/s^2)");
	}
	mlip_sdo_add(&l, 0x1017, 0, 2, d->heartbeat_ms, "producer heartbeat time (ms)");
	mlip_sdo_add(&l, 0x1016, 1, 4, ((uint32_t)d->master_node << 16) | d->master_timeout_ms,
	             "consumer heartbeat time: the master's node and timeout (ms)");
	return l.n > cap ? -1 : l.n;
}

/* ---- supervision ------------------------------------------------------------------------ */

mlip_drive_fault mlip_drive_supervise(const struct mlip_drive_obs *o,
                                      const struct mlip_drive_expect *x, int64_t *detail)
{
	*detail = 0;
	if (o->tpdo_cycle != 0 && (o->statusword & MLIP_402_SW_FAULT)) {
		*detail = o->statusword;
		return MLIP_DRIVE_FAULT_BIT;
	}
	if (o->emcy_count > 0) {
		*detail = o->emcy.code;
		return MLIP_DRIVE_EMCY;
	}
	if (x->hb_timeout_ns > 0 && x->now_ns > o->hb_ns &&
	    x->now_ns - o->hb_ns > x->hb_timeout_ns) {
		*detail = (int64_t)((x->now_ns - o->hb_ns) / 1000000u);
		return MLIP_DRIVE_HEARTBEAT_LOST;
	}
	if (o->nmt_state != MLIP_NMT_OPERATIONAL) {
		*detail = o->nmt_state;
		return MLIP_DRIVE_NOT_OPERATIONAL;
	}
	if (o->tpdo_cycle != 0 && !x->any_state &&
	    mlip_402_state_of(o->statusword) != MLIP_402_OPERATION_ENABLED) {
		*detail = o->statusword;
		return MLIP_DRIVE_LEFT_ENABLED;
	}
	if (x->following_counts >= 0 && (uint64_t)x->following_counts > x->window_counts) {
		*detail = x->following_counts;
		return MLIP_DRIVE_FOLLOWING_ERROR;
	}
	if (x->tpdo_timeout > 0 && x->cycle > o->tpdo_cycle + x->tpdo_timeout) {
		*detail = (int64_t)(x->cycle - o->tpdo_cycle);
		return MLIP_DRIVE_TPDO_LOST;
	}
	/* TPDOs that come, but answer a SYNC that old: the drive is that far behind */
	if (x->tpdo_timeout > 0 && o->tpdo_count > 0 &&
	    x->cycle > o->tpdo_count + x->tpdo_timeout) {
		*detail = (int64_t)(x->cycle - o->tpdo_count);
		return MLIP_DRIVE_TPDO_LOST;
	}
	/* its limit switches unread for longer than a heartbeat: moving on
	 * would be moving blind */
	if (x->di_timeout_ns > 0 && x->now_ns > o->di_ns &&
	    x->now_ns - o->di_ns > x->di_timeout_ns) {
		*detail = (int64_t)((x->now_ns - o->di_ns) / 1000000u);
		return MLIP_DRIVE_INPUTS_LOST;
	}
	return MLIP_DRIVE_OK;
}

const char *mlip_drive_fault_name(mlip_drive_fault f)
{
	static const char *const names[] = {"ok",
	                                    "statusword fault bit",
	                                    "emergency",
	                                    "heartbeat lost",
	                                    "left NMT operational",
	                                    "left operation enabled",
	                                    "following error",
	                                    "TPDOs lost or late",
	                                    "not switched on",
	                                    "not enabled",
	                                    "beyond a soft limit",
	                                    "spindle not at speed in time",
	                                    "spindle speed out of its band",
	                                    "power step not confirmed",
	                                    "digital inputs lost"};
	return (int)f >= 0 && f <= MLIP_DRIVE_INPUTS_LOST ? names[f] : "?";
}

int64_t mlip_drive_following_error(const int32_t *targets, int n, int32_t actual)
{
	int64_t best = -1;
	int i;

	for (i = 0; i < n; i++) {
		int64_t e = (int64_t)actual - targets[i];
		if (e < 0) {
			e = -e;
		}
		if (best < 0 || e < best) {
			best = e;
		}
	}
	return best;
}
