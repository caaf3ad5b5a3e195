/*
 * iomodule.c - the CiA 401 I/O module in the loop (issue 18): its loss
 * (heartbeat lost, left NMT operational - a reboot's boot-up message says
 * so -, an EMCY) is an E-stop; once it is heard again it is reconfigured
 * before anything it says is trusted: a module that rebooted has its
 * default PDO mapping and consumes no heartbeat, one that was cut off may
 * have rebooted unseen. The steps, one SDO or NMT frame at a time, each
 * answered within its timeout or the attempt fails (and is tried again,
 * backing off: below):
 *   1. NMT reset communication, its boot-up message (BOOT_TIMEOUT_MS)
 *   1b. the same device: its 0x1000 device type and 0x1018 vendor-ID and
 *      product code read and compared with bring-up's; another module on
 *      that node (swapped, or a wrong node id set) is never configured nor
 *      trusted: the E-stop stays, its reason names node and object
 *      (MLIP_DRIVE_WRONG_DEVICE) until mlip-rt is restarted
 *   1c. its error register 0x1001 read: non-zero, the module still reports
 *      a fault (CiA 301: an EMCY told of it; a reset communication need not
 *      clear it nor send the EMCY again): the attempt fails, the E-stop stays
 *   2. the set-up entries of bring-up (mlip_io401_setup_entries), each
 *      written and read back (SDO_TIMEOUT_MS each)
 *   3. its inputs 0x6000:1..n read by SDO
 *   4. NMT start, its heartbeat saying operational
 * Then it is back: `lost` cleared, its inputs known (the E-stop input read
 * again decides whether mlip-ctl reset may leave the E-stop), its outputs
 * sent at once: off, as every output is in an E-stop (the program running
 * when it was lost was dropped by the E-stop). Until then its TPDOs are
 * ignored and no RPDO is sent to it.
 *
 * A failed attempt is tried again after 1, 2, 4 ... IO_RE_BACKOFF_MAX of
 * the module's heartbeats (each failure in a row doubles the wait), or at
 * once when the module says it changed: a boot-up message (it rebooted:
 * its fault may have gone with it) or an EMCY 0000h ("error reset or no
 * error", CiA 301: what a module sends when its error has gone). A module
 * that keeps reporting a fault (0x1001 non-zero) was reset and queried at
 * each of its heartbeats before: a reset communication and 3-4 SDOs every
 * producer time, for as long as the fault lasted. The back-off keeps the
 * bus quiet (at 100 ms heartbeats one attempt every 3.2 s at most) yet
 * retries on its own, bounded, for a module whose fault clears without
 * the EMCY (not every module sends it; 0x1015's inhibit time may hold it
 * back); the E-stop stays until an attempt succeeds.
 *
 * In the loop: no wait, no print, no allocation.
 */
#include <string.h>

#include "drives.h"

#define IO_RE_BACKOFF_MAX 32u /* heartbeats between two attempts at most */

static uint32_t mask_of(uint8_t size)
{
	return size >= 4 ? 0xFFFFFFFFu : (1u << (8 * size)) - 1u;
}

static void nmt(struct mlip_drives *ds, uint8_t cmd)
{
	struct mlip_can_frame f;
	mlip_nmt_encode(cmd, ds->io.node, &f);
	ds->port.send(ds->port.ctx, &f);
}

static void fail(struct mlip_drives *ds, uint64_t now, uint32_t abort, uint16_t index, uint8_t sub)
{
	ds->io.re.phase = MLIP_IO_RE_NONE;
	ds->io.re.busy = ds->io.re.done = 0;
	ds->io.re.failed++;
	ds->io.re.fail_abort = abort;
	ds->io.re.fail_index = index;
	ds->io.re.fail_sub = sub;
	ds->io.re.fail_reg = 0;
	ds->io.lost_ns = now; /* a boot-up or an error reset after this: tried again */
	uint32_t wait = ds->io.re.streak < 5 ? 1u << ds->io.re.streak : IO_RE_BACKOFF_MAX;
	ds->io.re.streak++;
	ds->io.re.retry_hb = ds->io.hb_count + wait;
}

static void sdo_start(struct mlip_drives *ds, uint64_t now, int upload, uint16_t index, uint8_t sub,
                      uint32_t value, uint8_t size)
{
	struct mlip_can_frame req;
	if (upload) {
		mlip_sdo_upload_begin(&ds->io.re.s, ds->io.node, index, sub, &req);
	} else {
		mlip_sdo_download_begin(&ds->io.re.s, ds->io.node, index, sub, value, size, &req);
	}
	ds->io.re.busy = 1;
	ds->io.re.done = 0;
	ds->io.re.deadline_ns = now + (uint64_t)ds->cfg.sdo_timeout_ms * 1000000u;
	if (ds->port.send(ds->port.ctx, &req) != 0) {
		fail(ds, now, MLIP_SDO_ABORT_GENERAL, index, sub);
	}
}

/* Entry k of the set-up: written (or, read-only, read), then read back. */
static void entry_start(struct mlip_drives *ds, uint64_t now)
{
	const struct mlip_sdo_entry *e = &ds->io.re.e[ds->io.re.k];
	ds->io.re.readback = e->read_only;
	sdo_start(ds, now, e->read_only, e->index, e->sub, e->value, e->size);
}

/* The identity objects compared after the boot-up: k = 0 device type, 1
 * vendor-ID, 2 product code (when it had one at bring-up). */
static void ident_start(struct mlip_drives *ds, uint64_t now)
{
	static const uint16_t index[3] = {0x1000, 0x1018, 0x1018};
	static const uint8_t sub[3] = {0, 1, 2};
	int k = ds->io.re.k;
	sdo_start(ds, now, 1, index[k], sub[k], 0, 0);
}

/* Not the module of bring-up: the E-stop stays, naming the object. */
static void wrong(struct mlip_drives *ds, uint32_t got, uint32_t want)
{
	ds->io.re.phase = MLIP_IO_RE_NONE;
	ds->io.re.wrong = 1;
	ds->io.re.wrong_index = ds->io.re.s.index;
	ds->io.re.wrong_sub = ds->io.re.s.sub;
	ds->io.re.wrong_got = got;
	ds->io.re.wrong_want = want;
	ds->io.lost = MLIP_DRIVE_WRONG_DEVICE;
	ds->io.lost_value = (double)((uint32_t)ds->io.re.s.index << 8 | ds->io.re.s.sub);
}

/* An SDO answer came: the next step. */
static void sdo_done(struct mlip_drives *ds, uint64_t now)
{
	uint32_t v = ds->io.re.value;
	ds->io.re.done = 0;
	if (ds->io.re.abort != 0) {
		fail(ds, now, ds->io.re.abort, ds->io.re.s.index, ds->io.re.s.sub);
		return;
	}
	if (ds->io.re.phase == MLIP_IO_RE_IDENT) {
		const uint32_t want[3] = {ds->io.id.type, ds->io.id.vendor, ds->io.id.product};
		if (v != want[ds->io.re.k]) {
			wrong(ds, v, want[ds->io.re.k]);
			return;
		}
		if (++ds->io.re.k < (ds->io.id.has_product ? 3 : 2)) {
			ident_start(ds, now);
			return;
		}
		ds->io.re.phase = MLIP_IO_RE_ERRREG;
		sdo_start(ds, now, 1, 0x1001, 0, 0, 0);
		return;
	}
	if (ds->io.re.phase == MLIP_IO_RE_ERRREG) {
		if ((v & 0xFFu) != 0) {
			fail(ds, now, 0, 0x1001, 0);
			ds->io.re.fail_reg = (uint8_t)v;
			return;
		}
		ds->io.re.phase = MLIP_IO_RE_SDO;
		ds->io.re.k = 0;
		entry_start(ds, now);
		return;
	}
	if (ds->io.re.phase == MLIP_IO_RE_SDO) {
		const struct mlip_sdo_entry *e = &ds->io.re.e[ds->io.re.k];
		if (!ds->io.re.readback) {
			ds->io.re.readback = 1;
			sdo_start(ds, now, 1, e->index, e->sub, 0, 0);
			return;
		}
		if ((v & mask_of(e->size)) != (e->value & mask_of(e->size))) {
			fail(ds, now, MLIP_SDO_ABORT_GENERAL, e->index, e->sub);
			return;
		}
		if (++ds->io.re.k < ds->io.re.n) {
			entry_start(ds, now);
			return;
		}
		ds->io.re.phase = MLIP_IO_RE_INPUTS;
		ds->io.re.k = 1;
		sdo_start(ds, now, 1, 0x6000, 1, 0, 0);
		return;
	}
	if (ds->io.re.phase == MLIP_IO_RE_INPUTS) {
		ds->io.img.in[ds->io.re.k - 1] = (uint8_t)v;
		if (++ds->io.re.k <= ds->io.setup.in_bytes) {
			sdo_start(ds, now, 1, 0x6000, (uint8_t)ds->io.re.k, 0, 0);
			return;
		}
		ds->io.re.phase = MLIP_IO_RE_START;
		ds->io.re.t0_ns = now;
		ds->io.re.deadline_ns = now + (uint64_t)ds->cfg.boot_timeout_ms * 1000000u;
		nmt(ds, MLIP_NMT_START);
	}
}

void mlip_io_module_sdo(struct mlip_drives *ds, const struct mlip_can_frame *f, uint64_t now)
{
	struct mlip_can_frame req;
	if (!ds->io.re.busy) {
		return;
	}
	switch (mlip_sdo_feed(&ds->io.re.s, f, &req)) {
	case MLIP_SDO_DONE:
		ds->io.re.value = ds->io.re.s.value;
		ds->io.re.abort = 0;
		break;
	case MLIP_SDO_SEND:
		ds->port.send(ds->port.ctx, &req);
		ds->io.re.deadline_ns = now + (uint64_t)ds->cfg.sdo_timeout_ms * 1000000u;
		return;
	case MLIP_SDO_PROTOCOL:
		ds->port.send(ds->port.ctx, &req);
		ds->io.re.abort =
		    ds->io.re.s.abort_code ? ds->io.re.s.abort_code : MLIP_SDO_ABORT_GENERAL;
		break;
	case MLIP_SDO_ABORTED:
		ds->io.re.abort =
		    ds->io.re.s.abort_code ? ds->io.re.s.abort_code : MLIP_SDO_ABORT_GENERAL;
		break;
	default:
		return;
	}
	ds->io.re.busy = 0;
	ds->io.re.done = 1;
}

/* The module back: trusted again. */
static void back(struct mlip_drives *ds, uint64_t now)
{
	ds->io.re.phase = MLIP_IO_RE_NONE;
	ds->io.re.count++;
	ds->io.re.streak = 0;
	ds->io.lost = 0;
	ds->io.lost_value = 0.0;
	ds->io.obs.emcy_count = 0; /* before the reset; a fault that stays is sent again */
	ds->io.obs.hb_ns = now;
	ds->io.img.module_read = 1; /* 0x6000:1..n just read */
	ds->io.sent_ns = 0;         /* the outputs at once (off in the E-stop) */
}

/* The reconfiguration, one step a period at most. */
static void reconfigure(struct mlip_drives *ds, uint64_t now)
{
	const struct mlip_drive_obs *o = &ds->io.obs;
	switch (ds->io.re.phase) {
	case MLIP_IO_RE_NONE:
		if (ds->io.re.n > 0 && !ds->io.re.wrong &&
		    (ds->io.hb_count >= ds->io.re.retry_hb || ds->io.bootup_ns > ds->io.lost_ns ||
		     ds->io.ereset_ns > ds->io.lost_ns)) {
			/* heard again: from a known state, whatever it did meanwhile */
			ds->io.re.phase = MLIP_IO_RE_BOOT;
			ds->io.re.t0_ns = now;
			ds->io.re.deadline_ns = now + (uint64_t)ds->cfg.boot_timeout_ms * 1000000u;
			nmt(ds, MLIP_NMT_RESET_COMM);
		}
		return;
	case MLIP_IO_RE_BOOT:
		if (ds->io.bootup_ns > ds->io.re.t0_ns) {
			ds->io.re.phase = MLIP_IO_RE_IDENT;
			ds->io.re.k = 0;
			ident_start(ds, now);
		} else if (now >= ds->io.re.deadline_ns) {
			fail(ds, now, 0, 0, 0);
		}
		return;
	case MLIP_IO_RE_START:
		if (o->nmt_state == MLIP_NMT_OPERATIONAL && o->hb_ns > ds->io.re.t0_ns) {
			back(ds, now);
		} else if (now >= ds->io.re.deadline_ns) {
			fail(ds, now, 0, 0, 0);
		}
		return;
	default: /* an SDO transfer */
		if (ds->io.re.done) {
			sdo_done(ds, now);
		} else if (ds->io.re.busy && now >= ds->io.re.deadline_ns) {
			struct mlip_can_frame req;
			mlip_sdo_abort_encode(ds->io.node, ds->io.re.s.index, ds->io.re.s.sub,
			                      MLIP_SDO_ABORT_TIMEOUT, &req);
			ds->port.send(ds->port.ctx, &req);
			fail(ds, now, 0, ds->io.re.s.index, ds->io.re.s.sub);
		}
	}
}

void mlip_io_module_period(struct mlip_drives *ds, uint64_t now)
{
	const struct mlip_drive_obs *o = &ds->io.obs;
	uint64_t timeout = (uint64_t)ds->cfg.heartbeat_timeout_ms * 1000000u;
	if (ds->io.lost != 0) {
		reconfigure(ds, now);
		return;
	}
	if (now > o->hb_ns && now - o->hb_ns > timeout) {
		ds->io.lost = MLIP_DRIVE_HEARTBEAT_LOST;
		ds->io.lost_value = (double)(now - o->hb_ns) * 1e-6;
	} else if (o->nmt_state != MLIP_NMT_OPERATIONAL) {
		ds->io.lost = MLIP_DRIVE_NOT_OPERATIONAL;
		ds->io.lost_value = o->nmt_state;
	} else if (o->emcy_count > 0) {
		ds->io.lost = MLIP_DRIVE_EMCY;
		ds->io.lost_value = o->emcy.code;
	} else {
		return;
	}
	/* nothing it said is trusted until it is configured again, from its
	 * next heartbeat on */
	ds->io.lost_ns = now;
	ds->io.re.retry_hb = ds->io.hb_count + 1;
	ds->io.img.module_read = 0;
}
