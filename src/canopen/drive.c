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
	/* RPDO1: controlword, the target, the touch probe function */
	const uint32_t rx[3] = {0x60400010u, d->velocity ? 0x60FF0020u : 0x607A0020u, 0x60B80010u};
	const char *const rx_what[3] = {"RPDO1 mapping 1: controlword 0x6040",
	                                d->velocity ? "RPDO1 mapping 2: target velocity 0x60FF"
	                                            : "RPDO1 mapping 2: target position 0x607A",
	                                "RPDO1 mapping 3: touch probe function 0x60B8"};
	/* TPDO1: statusword, the actual value, the touch probe status */
	const uint32_t tx[3] = {0x60410010u, d->velocity ? 0x606C0020u : 0x60640020u, 0x60B90010u};
	const char *const tx_what[3] = {"TPDO1 mapping 1: statusword 0x6041",
	                                d->velocity
	                                    ? "TPDO1 mapping 2: velocity actual value 0x606C"
	                                    : "TPDO1 mapping 2: position actual value 0x6064",
	                                "TPDO1 mapping 3: touch probe status 0x60B9"};
	/* TPDO2: the latched positions, sampled at the same SYNC as TPDO1 */
	static const uint32_t tp[2] = {0x60BA0020u, 0x60BB0020u};
	static const char *const tp_what[2] = {
	    "TPDO2 mapping 1: touch probe 1 positive edge position 0x60BA",
	    "TPDO2 mapping 2: touch probe 1 negative edge position 0x60BB"};
	/* TPDO3 (TPDO2 may be the touch probe's): the digital inputs */
	static const uint32_t di[1] = {0x60FD0020u};
	static const char *const di_what[1] = {"TPDO3 mapping 1: digital inputs 0x60FD"};
	const uint8_t n1 = d->touch_probe ? 3 : 2;
	const struct mlip_pdo_map pdo[4] = {
	    {.num = 1,
	     .cob_id = d->rpdo_cob,
	     .type = 1,
	     .type_what = "RPDO1 transmission type (synchronous)",
	     .n = n1,
	     .map = rx,
	     .what = rx_what},
	    {.tpdo = 1,
	     .num = 1,
	     .cob_id = d->tpdo_cob,
	     .type = 1,
	     .type_what = "TPDO1 transmission type (synchronous, every SYNC)",
	     .n = n1,
	     .map = tx,
	     .what = tx_what},
	    {.tpdo = 1,
	     .num = 2,
	     .cob_id = d->tpdo2_cob,
	     .type = 1,
	     .type_what = "TPDO2 transmission type (synchronous, every SYNC)",
	     .n = 2,
	     .map = tp,
	     .what = tp_what},
	    {.tpdo = 1,
	     .num = 3,
	     .cob_id = d->di_tpdo_cob,
	     .type = 255,
	     .type_what = "TPDO3 transmission type (255: on change)",
	     .event_what = "TPDO3 event timer (ms): the inputs at least this often",
	     .event_ms = d->di_event_ms,
	     .n = 1,
	     .map = di,
	     .what = di_what}};
	uint8_t pv;
	int8_t pi;
	struct mlip_sdo_list l = {out, cap, 0};

	if (mlip_co_interp_period(d->period_s, &pv, &pi) != MLIP_OK) {
		return -1;
	}
	if (mlip_sdo_add_pdo(&l, &pdo[0]) != MLIP_OK || mlip_sdo_add_pdo(&l, &pdo[1]) != MLIP_OK) {
		return -1;
	}
	if (d->touch_probe) {
		if (mlip_sdo_add_pdo(&l, &pdo[2]) != MLIP_OK) {
			return -1;
		}
		mlip_sdo_add(&l, 0x60B8, 0, 2, 0, "touch probe function (off until a G38)");
	}
	if (d->di_tpdo_cob != 0 && mlip_sdo_add_pdo(&l, &pdo[3]) != MLIP_OK) {
		return -1;
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
		/* the ramp is the drive's only with option 2 or 6; 6 also holds the
		 * axis under position control at rest (docs/cia402.md) */
		mlip_sdo_add(&l, 0x605A, 0, 2, MLIP_DRIVE_QUICK_STOP_OPTION,
		             "quick stop option code (6: the quick stop ramp, then hold in "
		             "quick stop active)");
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
	                                    "digital inputs lost",
	                                    "not the same device"};
	return (int)f >= 0 && f <= MLIP_DRIVE_WRONG_DEVICE ? names[f] : "?";
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
