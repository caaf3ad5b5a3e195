/*
 * drivehooks.c - the CANopen master of mlip-rt in the loop: the period's
 * hooks (mlip_drives_hooks, rt.h) around the controller's period. Before it:
 * the drives' and the I/O module's supervision, the controller's inputs
 * from them; after it: the targets kept for the following error, the SDO
 * transfer the controller asked for (homing), the module's outputs, the
 * master's heartbeat. Bring-up and shut-down are rt/drives.c's.
 *
 * In the loop: no wait, no print, no text: the period reads the bus (at
 * most RX_PER_PERIOD frames) and calls the hooks.
 */
#include <string.h>

#include "drives.h"

/* per drive TPDO1, TPDO2 (touch probe), TPDO3 (digital inputs), heartbeat,
 * EMCY, an SDO answer; and margin */
#define RX_PER_PERIOD(n) (6 * (n) + 16)

int mlip_drives_find_node(const struct mlip_drives *ds, uint8_t node)
{
	for (int i = 0; i < ds->n + ds->sp; i++) {
		if (ds->d[i].node == node) {
			return i;
		}
	}
	return -1;
}

/* The master's heartbeat when it is due (both outside and in the loop). */
void mlip_drives_serve_heartbeat(struct mlip_drives *ds, uint64_t now)
{
	if (now >= ds->hb_next_ns) {
		struct mlip_can_frame f;
		mlip_co_heartbeat_encode(ds->cfg.master_node, MLIP_NMT_OPERATIONAL, &f);
		ds->port.send(ds->port.ctx, &f);
		ds->hb_next_ns = now + (uint64_t)ds->cfg.heartbeat_ms * 1000000u;
	}
}

/* Note what a heartbeat, EMCY or TPDO says about a drive (in and out of the
 * loop); returns the classified message. `cycle`: the period (0 outside). */
void mlip_drives_observe(struct mlip_drives *ds, const struct mlip_can_frame *f, uint64_t now,
                         uint64_t cycle, struct mlip_co_msg *m)
{
	if (ds->io.node != 0 && f->id == MLIP_CO_TPDO1_BASE + ds->io.node) {
		/* the module's inputs, on change: its own length (not a drive's) */
		m->kind = MLIP_CO_OTHER;
		if (ds->io.lost != 0 && ds->io.re.phase != MLIP_IO_RE_START) {
			return; /* lost: not trusted until it is configured again */
		}
		if (f->len != ds->io.setup.in_bytes) {
			ds->rx_malformed++;
			return;
		}
		memcpy(ds->io.img.in, f->data, f->len);
		ds->io.img.module_read = 1;
		ds->io.rx_frames++;
		return;
	}
	if (ds->di_axes != 0 && (f->id & 0x780u) == MLIP_CO_TPDO3_BASE) {
		/* a drive's digital inputs 0x60FD (TPDO3): 4 bytes, or not trusted */
		int i = mlip_drives_find_node(ds, (uint8_t)(f->id & 0x7Fu));
		if (i >= 0 && i < ds->n && (ds->di_axes & (1u << i))) {
			m->kind = MLIP_CO_OTHER;
			if (f->len != 4 || (f->flags & (MLIP_CAN_FLAG_EFF | MLIP_CAN_FLAG_FD))) {
				ds->rx_malformed++;
				return;
			}
			ds->io.img.di[i] = (uint32_t)f->data[0] | (uint32_t)f->data[1] << 8 |
			                   (uint32_t)f->data[2] << 16 | (uint32_t)f->data[3] << 24;
			ds->io.img.drives_read |= 1u << i;
			ds->d[i].obs.di_ns = now;
			return;
		}
	}
	if (mlip_co_classify(f, m) != MLIP_OK) {
		ds->rx_malformed++;
		m->kind = MLIP_CO_OTHER;
		return;
	}
	int i = mlip_drives_find_node(ds, m->node);
	if (i < 0 && (ds->io.node == 0 || m->node != ds->io.node || m->kind == MLIP_CO_TPDO)) {
		m->kind = MLIP_CO_OTHER;
		return;
	}
	struct mlip_drive_obs *o = i < 0 ? &ds->io.obs : &ds->d[i].obs;
	switch (m->kind) {
	case MLIP_CO_HEARTBEAT:
		o->nmt_state = m->nmt_state;
		o->hb_ns = now;
		if (i < 0) {
			ds->io.hb_count++;
			if (m->nmt_state == MLIP_NMT_BOOTUP) {
				ds->io.bootup_ns = now; /* the module (re)booted */
			}
		}
		break;
	case MLIP_CO_EMCY:
		if (m->emcy.code != 0) {
			o->emcy = m->emcy;
			o->emcy_count++;
		} else if (i < 0) {
			ds->io.ereset_ns = now; /* CiA 301: its error has gone */
		}
		break;
	case MLIP_CO_TPDO:
		o->statusword = m->statusword;
		o->position_counts = m->position_counts;
		o->tpdo_cycle = cycle;
		o->tpdo_count++;
		o->probe_status = m->has_probe ? m->probe_status : 0;
		break;
	case MLIP_CO_TPDO2:
		o->probe_pos = m->probe_pos;
		o->probe_neg = m->probe_neg;
		o->tpdo2_count++;
		break;
	default:
		break;
	}
}

/* ---- the loop: the period's hooks ---------------------------------------------- */

static void sdo_end(struct mlip_drives *ds, uint32_t abort, uint32_t value)
{
	ds->sdo.busy = 0;
	ds->sdo.res.seq = ds->sdo.seq;
	ds->sdo.res.abort = abort;
	ds->sdo.res.value = value;
}

static void hook_rx(void *ctx, const struct mlip_can_frame *f, uint64_t cycle, uint64_t now)
{
	struct mlip_drives *ds = ctx;
	struct mlip_co_msg m;
	struct mlip_can_frame req;
	ds->rx_frames++;
	mlip_drives_observe(ds, f, now, cycle + 1, &m);
	if (m.kind == MLIP_CO_SDO && ds->io.node != 0 && m.node == ds->io.node) {
		mlip_io_module_sdo(ds, f, now); /* its reconfiguration's transfer */
		return;
	}
	if (m.kind != MLIP_CO_SDO || !ds->sdo.busy || m.node != ds->sdo.s.node) {
		return;
	}
	switch (mlip_sdo_feed(&ds->sdo.s, f, &req)) {
	case MLIP_SDO_DONE:
		sdo_end(ds, 0, ds->sdo.s.value);
		return;
	case MLIP_SDO_SEND:
		ds->port.send(ds->port.ctx, &req);
		ds->sdo.deadline_ns = now + (uint64_t)ds->cfg.sdo_timeout_ms * 1000000u;
		return;
	case MLIP_SDO_ABORTED:
		sdo_end(ds, ds->sdo.s.abort_code, 0);
		return;
	case MLIP_SDO_PROTOCOL:
		ds->port.send(ds->port.ctx, &req);
		sdo_end(ds, ds->sdo.s.abort_code, 0);
		return;
	default:
		return;
	}
}

/* After the controller: its SDO request started when it is a new one; one
 * not answered within SDO_TIMEOUT_MS aborted (mlip's abort sent). */
static void sdo_after(struct mlip_drives *ds, uint64_t now, const struct mlip_ctl_out *out)
{
	struct mlip_can_frame req;
	const struct mlip_ctl_sdo_req *r = &out->sdo;
	if (ds->sdo.busy && now >= ds->sdo.deadline_ns) {
		mlip_sdo_abort_encode(ds->sdo.s.node, ds->sdo.s.index, ds->sdo.s.sub,
		                      MLIP_SDO_ABORT_TIMEOUT, &req);
		ds->port.send(ds->port.ctx, &req);
		sdo_end(ds, MLIP_SDO_ABORT_TIMEOUT, 0);
	}
	if (r->seq == 0 || r->seq == ds->sdo.seq) {
		return;
	}
	ds->sdo.seq = r->seq;
	if (r->upload) {
		mlip_sdo_upload_begin(&ds->sdo.s, r->node, r->index, r->sub, &req);
	} else {
		mlip_sdo_download_begin(&ds->sdo.s, r->node, r->index, r->sub, r->value, r->size,
		                        &req);
	}
	if (ds->port.send(ds->port.ctx, &req) != 0) {
		sdo_end(ds, MLIP_SDO_ABORT_GENERAL, 0);
		return;
	}
	ds->sdo.busy = 1;
	ds->sdo.deadline_ns = now + (uint64_t)ds->cfg.sdo_timeout_ms * 1000000u;
}

/* any_state: the controller is disabling, has disabled or is enabling the
 * drives (its power is not ENABLED): no state but fault is wrong, and they
 * follow no target. The first new fault goes to the controller's input. */
static void supervise(struct mlip_drives *ds, uint64_t cycle, uint64_t now, int any_state,
                      struct mlip_ctl_in *in)
{
	struct mlip_drive_expect x;
	uint64_t period_ns = (uint64_t)(ds->m->period_s * 1e9 + 0.5);
	memset(&x, 0, sizeof(x));
	x.now_ns = now;
	x.cycle = cycle;
	x.hb_timeout_ns = (uint64_t)ds->cfg.heartbeat_timeout_ms * 1000000u;
	x.tpdo_timeout = (uint32_t)(x.hb_timeout_ns / period_ns); /* as long as a heartbeat */
	x.any_state = any_state;
	for (int i = 0; i < ds->n + ds->sp; i++) {
		struct mlip_drive *d = &ds->d[i];
		int64_t detail;
		if (ds->mute & (1u << i)) {
			continue;
		}
		x.window_counts = d->setup.following_window_counts;
		x.di_timeout_ns = i < ds->n && (ds->di_axes & (1u << i)) ? x.hb_timeout_ns : 0;
		/* the newest TPDO answers SYNC j = tpdo_count, sent in period j */
		uint64_t j = d->obs.tpdo_count;
		x.following_counts = -1;
		if (i < ds->n && !any_state && !(ds->homing & (1u << i)) &&
		    d->obs.tpdo_cycle == cycle && j >= 1 &&
		    cycle - j + MLIP_DRIVE_LAG < MLIP_DRIVE_HIST) {
			int32_t t[MLIP_DRIVE_LAG];
			for (int k = 0; k < MLIP_DRIVE_LAG; k++) {
				t[k] = d->targets[(j - 1 - (uint64_t)k + MLIP_DRIVE_HIST) %
				                  MLIP_DRIVE_HIST];
			}
			x.following_counts =
			    mlip_drive_following_error(t, MLIP_DRIVE_LAG, d->obs.position_counts);
		}
		mlip_drive_fault f = mlip_drive_supervise(&d->obs, &x, &detail);
		if (f == MLIP_DRIVE_OK) {
			continue;
		}
		/* the drive no longer follows: no more targets for it. One whose
		 * heartbeat is lost may still listen (its TPDOs may even come): it
		 * keeps getting the stop on the path with the others, then the
		 * disable, instead of stopping dead at once (issue 18) */
		if (f != MLIP_DRIVE_FOLLOWING_ERROR && f != MLIP_DRIVE_TPDO_LOST &&
		    f != MLIP_DRIVE_HEARTBEAT_LOST && f != MLIP_DRIVE_INPUTS_LOST) {
			ds->mute |= 1u << i;
		}
		if (!__atomic_load_n(&ds->fault, __ATOMIC_ACQUIRE)) {
			ds->fault_drive = i;
			ds->fault_reason = f;
			ds->fault_detail = detail;
			ds->fault_cycle = cycle;
			__atomic_store_n(&ds->fault, 1, __ATOMIC_RELEASE);
			/* an input of the controller's period: it stops every axis on
			 * the path, state fault, reason drive (node, event, value) */
			in->drives.fault.event = (uint32_t)f;
			in->drives.fault.node = d->node;
			in->drives.fault.value = (double)detail;
		}
	}
}

/* The I/O module's supervision (its heartbeat, NMT state, EMCY: any failure
 * is an E-stop until it is reconfigured, rt/iomodule.c) and the input
 * functions of this period: a drive's
 * inputs not read within the heartbeat timeout are unknown (its supervision
 * makes that a fault). */
static void io_before(struct mlip_drives *ds, uint64_t now, struct mlip_ctl_in *in)
{
	uint64_t timeout = (uint64_t)ds->cfg.heartbeat_timeout_ms * 1000000u;
	for (int i = 0; i < ds->n; i++) {
		uint64_t at = ds->d[i].obs.di_ns;
		if ((ds->di_axes & (1u << i)) && now > at && now - at > timeout) {
			ds->io.img.drives_read &= ~(1u << i);
		}
	}
	if (ds->io.node == 0) {
		in->io.active = mlip_io_eval(&ds->io_cfg, ds->m, &ds->io.img, &in->io.known);
		return;
	}
	mlip_io_module_period(ds, now);
	if (ds->io.lost != 0) {
		in->io.lost.event = ds->io.lost;
		in->io.lost.node = ds->io.node;
		in->io.lost.value = ds->io.lost_value;
	}
	in->io.active = mlip_io_eval(&ds->io_cfg, ds->m, &ds->io.img, &in->io.known);
}

/* Before the controller: supervision against the power its last period
 * left, then its inputs from the drives: the faulted ones (no RPDO),
 * statuswords (its power steps are confirmed by them), positions actual. */
static void hook_before(void *ctx, uint64_t cycle, uint64_t now, struct mlip_ctl_in *in)
{
	struct mlip_drives *ds = ctx;
	io_before(ds, now, in);
	supervise(ds, cycle + 1, now, ds->power != MLIP_POWER_ENABLED, in);
	in->drives.mute = ds->mute & ((1u << ds->n) - 1u);
	in->drives.actual_mask = 0;
	if (ds->sp) {
		const struct mlip_drive *d = &ds->d[ds->n];
		in->spindle.sw = d->obs.tpdo_cycle != 0 ? d->obs.statusword : 0;
		in->spindle.vel_counts = d->obs.tpdo_count > 0 ? d->obs.position_counts : 0;
		in->spindle.mute = (ds->mute >> ds->n) & 1u;
	}
	for (int i = 0; i < ds->n; i++) {
		const struct mlip_drive *d = &ds->d[i];
		int32_t v = d->obs.tpdo_count > 0 ? d->obs.position_counts : d->start_counts;
		in->drives.sw[i] = d->obs.tpdo_cycle != 0 ? d->obs.statusword : 0;
		in->drives.pos_actual[i] = v / d->counts_per_unit;
		in->drives.actual_mask |= 1u << i;
		/* its newest TPDO answers SYNC tpdo_count, sent in the controller's
		 * period tpdo_count - 1 */
		in->drives.tpdo_period[i] =
		    d->obs.tpdo_count > 0 ? d->obs.tpdo_count - 1 : UINT64_MAX;
		in->drives.tp_status[i] = d->obs.tpdo_count > 0 ? d->obs.probe_status : 0;
		in->drives.tp_latch_period[i] =
		    d->obs.tpdo2_count > 0 ? d->obs.tpdo2_count - 1 : UINT64_MAX;
		in->drives.tp_pos[i] = d->obs.probe_pos / d->counts_per_unit;
		in->drives.tp_neg[i] = d->obs.probe_neg / d->counts_per_unit;
	}
	in->sdo = ds->sdo.res;
}

/* After it: the targets just sent (for the following error), the master's
 * heartbeat, and the loop's end once the controller is at rest with the
 * drives disabled (or faulted). */
static void hook_after(void *ctx, uint64_t cycle, uint64_t now, const struct mlip_ctl_out *out)
{
	struct mlip_drives *ds = ctx;
	for (int i = 0; i < ds->n; i++) {
		struct mlip_drive *d = &ds->d[i];
		int32_t counts;
		mlip_can_counts(out->pos[i], d->counts_per_unit, &counts);
		d->targets[(cycle + 1) % MLIP_DRIVE_HIST] = counts;
	}
	if (ds->sp && out->spindle.send) {
		/* after the SYNC and the axes' RPDOs: applied at the next SYNC */
		struct mlip_can_frame f;
		mlip_co_pdo_encode(ds->d[ds->n].setup.rpdo_cob, out->spindle.cw,
		                   out->spindle.target, &f);
		ds->port.send(ds->port.ctx, &f);
	}
	ds->power = out->power.state;
	ds->homing = out->homing;
	sdo_after(ds, now, out);
	/* the module's outputs: when they change, and every 100 ms (a module that
	 * missed one frame catches up) */
	if (ds->io.node != 0 && ds->io.setup.out_bytes > 0 && ds->io.lost == 0 &&
	    (ds->io.sent_ns == 0 || now - ds->io.sent_ns >= 100000000u ||
	     memcmp(ds->io.sent, out->outputs, ds->io.setup.out_bytes) != 0)) {
		struct mlip_can_frame f;
		memset(&f, 0, sizeof(f));
		f.id = 0x200u + ds->io.node;
		f.len = ds->io.setup.out_bytes;
		memcpy(f.data, out->outputs, f.len);
		if (ds->port.send(ds->port.ctx, &f) == 0) {
			memcpy(ds->io.sent, out->outputs, f.len);
			ds->io.sent_ns = now;
		}
	}
	mlip_drives_serve_heartbeat(ds, now);
	if (out->done && ds->phase == MLIP_DRIVES_RUN) {
		ds->phase = MLIP_DRIVES_OFF;
		ds->shutdown_ok = out->power.ok;
		ds->shutdown = out->power; /* its text: mlip_drives_shutdown_text, after the loop */
	}
}

void mlip_drives_hooks(struct mlip_drives *ds, struct mlip_period_hooks *h)
{
	memset(h, 0, sizeof(*h));
	h->ctx = ds;
	h->rx_max = RX_PER_PERIOD(ds->n);
	h->rx = hook_rx;
	h->before = hook_before;
	h->after = hook_after;
}
