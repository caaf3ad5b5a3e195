/*
 * drives.c - the CANopen master of mlip-rt for CiA 402 drives in cyclic
 * synchronous position mode: bring-up before the first period, supervision
 * in the loop (as the period's hooks), shut-down by SDO when the loop could
 * not do it. The frames and decisions are the pure ones of mlip/canopen/
 * (canopen.h, cia402.h, drive.h); this file sequences them on a port (the
 * bus of rt/canbus.c, or a scripted peer in tests/unit/test_drives.c).
 *
 * Bring-up (outside the loop; may wait, print through ds->log):
 *   1. NMT reset communication to each node; wait for every boot-up
 *   2. per drive, by SDO, each write read back: the list of
 *      mlip_drive_setup_entries (PDO mapping, SYNC, CSP, 0x60C2, 0x6065,
 *      heartbeats)
 *   3. NMT start; wait for each heartbeat to say operational
 *   4. CiA 402 by SDO (0x6040 written, 0x6041 polled), the steps of the
 *      power sequencer (mlip/canopen/cia402.h) from whatever state the
 *      drive is in up to "switched on" (fault reset, shutdown, switch on,
 *      or disable operation), each confirmed within STATE_TIMEOUT_MS
 *   5. position actual 0x6064 of every drive, checked against the soft
 *      limits; 0x607A = that position; enable operation, confirmed; the
 *      position read again: the planner starts there
 * The master's heartbeat is produced from step 1 on (every wait serves it),
 * then by the loop.
 *
 * In the loop the master is the period's hooks (rt/drivehooks.c, what they
 * share with this file: rt/drives.h).
 */
#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "drives.h"

#define STATE_POLL_NS 5000000LL /* 0x6041 read every 5 ms while waiting */

/* ---- helpers ------------------------------------------------------------------ */

static void say(struct mlip_drives *ds, const char *fmt, ...)
{
	char line[256];
	va_list ap;
	if (ds->log == NULL) {
		return;
	}
	va_start(ap, fmt);
	vsnprintf(line, sizeof(line), fmt, ap);
	va_end(ap);
	ds->log(ds->log_ctx, line);
}

/* Wait up to timeout for a frame, serving the master's heartbeat. 1, 0
 * (timeout) or -errno. EMCYs are logged as they come. */
static int wait_frame(struct mlip_drives *ds, uint64_t deadline, struct mlip_can_frame *f,
                      struct mlip_co_msg *m)
{
	for (;;) {
		uint64_t now = ds->port.now_ns(ds->port.ctx);
		mlip_drives_serve_heartbeat(ds, now);
		if (now >= deadline) {
			return 0;
		}
		uint64_t until = deadline < ds->hb_next_ns ? deadline : ds->hb_next_ns;
		int r = ds->port.recv(ds->port.ctx, f, (int64_t)(until - now));
		if (r < 0) {
			return r;
		}
		if (r != MLIP_CAN_RX_FRAME) {
			continue; /* none yet, or an error frame (the period counts those) */
		}
		mlip_drives_observe(ds, f, ds->port.now_ns(ds->port.ctx), 0, m);
		if (m->kind == MLIP_CO_EMCY) {
			say(ds, "node %u: EMCY 0x%04X (%s), error register 0x%02X", m->node,
			    m->emcy.code, mlip_emcy_text(m->emcy.code), m->emcy.reg);
		}
		return 1;
	}
}

/* i < 0: the I/O module */
static const char *axis_of(const struct mlip_drives *ds, int i, char *buf, size_t n)
{
	if (i < 0) {
		snprintf(buf, n, "node %u (I/O module)", ds->io.node);
	} else if (i == ds->n) {
		snprintf(buf, n, "node %u (spindle)", ds->d[i].node);
	} else {
		snprintf(buf, n, "node %u (axis %c)", ds->d[i].node, ds->d[i].letter);
	}
	return buf;
}

/* One SDO transfer to drive i: 0, or -errno with why naming node, object,
 * abort code and its meaning. */
static int sdo(struct mlip_drives *ds, int i, int upload, uint16_t index, uint8_t sub,
               uint32_t value, uint8_t size, const char *what, uint32_t *out, char *why,
               size_t why_len)
{
	struct mlip_sdo s;
	struct mlip_can_frame req, f;
	struct mlip_co_msg m;
	char who[32];
	const char *verb = upload ? "reading" : "writing";
	uint8_t node = i < 0 ? ds->io.node : ds->d[i].node;

	if (upload) {
		mlip_sdo_upload_begin(&s, node, index, sub, &req);
	} else {
		mlip_sdo_download_begin(&s, node, index, sub, value, size, &req);
	}
	axis_of(ds, i, who, sizeof(who));
	uint64_t timeout = (uint64_t)ds->cfg.sdo_timeout_ms * 1000000u;
	uint64_t deadline = ds->port.now_ns(ds->port.ctx) + timeout;
	if (ds->port.send(ds->port.ctx, &req) != 0) {
		snprintf(why, why_len, "%s: cannot send the SDO request %s 0x%04X:%02X", who, verb,
		         index, sub);
		return -EIO;
	}
	for (;;) {
		int r = wait_frame(ds, deadline, &f, &m);
		if (r < 0) {
			snprintf(why, why_len, "%s: bus read failed: %s", who, strerror(-r));
			return r;
		}
		if (r == 0) {
			mlip_sdo_abort_encode(node, index, sub, MLIP_SDO_ABORT_TIMEOUT, &req);
			ds->port.send(ds->port.ctx, &req);
			snprintf(
			    why, why_len,
			    "%s: no SDO answer %s 0x%04X:%02X (%s) within %u ms: is the drive on "
			    "the bus with this node id?",
			    who, verb, index, sub, what, (unsigned)ds->cfg.sdo_timeout_ms);
			return -ETIMEDOUT;
		}
		if (m.kind != MLIP_CO_SDO || m.node != node) {
			continue;
		}
		switch (mlip_sdo_feed(&s, &f, &req)) {
		case MLIP_SDO_IGNORED:
			continue;
		case MLIP_SDO_SEND:
			ds->port.send(ds->port.ctx, &req);
			deadline = ds->port.now_ns(ds->port.ctx) + timeout;
			continue;
		case MLIP_SDO_DONE:
			if (out != NULL) {
				*out = s.value;
			}
			return 0;
		case MLIP_SDO_ABORTED:
			snprintf(why, why_len, "%s: SDO abort 0x%08X %s 0x%04X:%02X (%s) - %s", who,
			         s.abort_code, verb, index, sub, mlip_sdo_abort_text(s.abort_code),
			         what);
			return -EPROTO;
		case MLIP_SDO_PROTOCOL:
			ds->port.send(ds->port.ctx, &req);
			snprintf(
			    why, why_len,
			    "%s: wrong SDO answer %s 0x%04X:%02X (%s): aborted with 0x%08X (%s)",
			    who, verb, index, sub, what, s.abort_code,
			    mlip_sdo_abort_text(s.abort_code));
			return -EPROTO;
		}
	}
}

static uint32_t mask_of(uint8_t size)
{
	return size >= 4 ? 0xFFFFFFFFu : (1u << (8 * size)) - 1u;
}

/* Write and read back (or only read and compare). */
static int sdo_entry(struct mlip_drives *ds, int i, const struct mlip_sdo_entry *e, char *why,
                     size_t why_len)
{
	uint32_t got = 0;
	int rc;
	if (!e->read_only) {
		rc =
		    sdo(ds, i, 0, e->index, e->sub, e->value, e->size, e->what, NULL, why, why_len);
		if (rc != 0) {
			return rc;
		}
	}
	rc = sdo(ds, i, 1, e->index, e->sub, 0, 0, e->what, &got, why, why_len);
	if (rc != 0) {
		return rc;
	}
	if ((got & mask_of(e->size)) != (e->value & mask_of(e->size))) {
		char who[32];
		snprintf(why, why_len, "%s: 0x%04X:%02X (%s) reads back 0x%X, written 0x%X",
		         axis_of(ds, i, who, sizeof(who)), e->index, e->sub, e->what,
		         (unsigned)(got & mask_of(e->size)), (unsigned)e->value);
		return -EPROTO;
	}
	return 0;
}

/* ---- bring-up ------------------------------------------------------------------- */

int mlip_drives_init(struct mlip_drives *ds, const struct mlip_config *cfg,
                     const struct mlip_can_port *port, void (*log)(void *, const char *),
                     void *log_ctx, char *why, size_t why_len)
{
	const struct mlip_machine *m = &cfg->machine;
	memset(ds, 0, sizeof(*ds));
	ds->port = *port;
	ds->cfg = cfg->drives;
	ds->m = m;
	ds->log = log;
	ds->log_ctx = log_ctx;
	ds->n = m->n_axes;
	ds->io_cfg = cfg->inputs;
	ds->io.node = cfg->inputs.node;
	for (int k = 0; k < m->n_axes; k++) {
		ds->home_axes |= cfg->home.axis[k].configured ? 1u << k : 0u;
	}
	/* every input function is on the module or on an axis' drive (the
	 * config's check): the drives' are read from their TPDO3 */
	ds->di_axes = mlip_drives_di_axes(cfg);
	if (ds->io.node != 0) {
		ds->io.setup.node = ds->io.node;
		ds->io.setup.in_bytes = cfg->inputs.in_bytes ? cfg->inputs.in_bytes : 1;
		ds->io.setup.out_bytes = cfg->inputs.out_bytes;
		ds->io.setup.heartbeat_ms = (uint16_t)cfg->drives.heartbeat_ms;
		ds->io.setup.master_node = cfg->drives.master_node;
		ds->io.setup.master_timeout_ms = (uint16_t)cfg->drives.heartbeat_timeout_ms;
		/* what a reconfiguration writes after a loss (rt/iomodule.c) */
		ds->io.re.n =
		    mlip_io401_setup_entries(&ds->io.setup, ds->io.re.e, MLIP_IO401_SETUP_MAX);
		if (ds->io.re.n < 0) {
			snprintf(why, why_len,
			         "[IO]: %u input and %u output bytes: not 1..8 and 0..8",
			         ds->io.setup.in_bytes, ds->io.setup.out_bytes);
			return -EINVAL;
		}
	}
	if (cfg->io.spindle == MLIP_IO_CIA402) {
		/* the spindle: d[n], one more drive of the group (issue 19) */
		const struct mlip_spindle_config *sc = &cfg->spindle;
		struct mlip_drive *d = &ds->d[m->n_axes];
		double acc = sc->accel_rpm_s * sc->counts_per_rev / 60.0;
		ds->sp = 1;
		d->node = sc->node;
		d->letter = 'S';
		d->counts_per_unit = sc->counts_per_rev / 60.0; /* counts/s per rpm */
		d->setup.node = d->node;
		d->setup.sync_id = cfg->can.sync_id;
		d->setup.rpdo_cob = cfg->can.rpdo_base + d->node;
		d->setup.tpdo_cob = MLIP_CO_TPDO1_BASE + d->node;
		d->setup.period_s = m->period_s;
		d->setup.heartbeat_ms = (uint16_t)ds->cfg.heartbeat_ms;
		d->setup.master_node = ds->cfg.master_node;
		d->setup.master_timeout_ms = (uint16_t)ds->cfg.heartbeat_timeout_ms;
		d->setup.velocity = 1;
		d->setup.accel_counts_s2 = acc > 4294967295.0 ? 4294967295u : (uint32_t)(acc + 0.5);
		if (sc->node == ds->cfg.master_node) {
			snprintf(why, why_len, "[DRIVES] MASTER_NODE %u is also the spindle's NODE",
			         ds->cfg.master_node);
			return -EINVAL;
		}
	}
	if (strcmp(cfg->can.profile, "cia402") != 0) {
		snprintf(why, why_len, "CiA 402 drives need [CAN] PROFILE = cia402, not %s",
		         cfg->can.profile);
		return -EINVAL;
	}
	for (int i = 0; i < m->n_axes; i++) {
		const struct mlip_axis *a = &m->axis[i];
		struct mlip_drive *d = &ds->d[i];
		if (a->can_node == ds->cfg.master_node) {
			snprintf(why, why_len,
			         "[DRIVES] MASTER_NODE %u is also the CAN_NODE of AXIS_%c",
			         ds->cfg.master_node, a->letter);
			return -EINVAL;
		}
		d->node = (uint8_t)a->can_node;
		d->letter = a->letter;
		d->counts_per_unit = a->counts_per_unit;
		double w = ds->cfg.following_error * a->counts_per_unit;
		if (!(w >= 1.0 && w <= 2147483647.0)) {
			snprintf(
			    why, why_len,
			    "[DRIVES] FOLLOWING_ERROR %g is %g counts on AXIS_%c: not 1..2^31-1",
			    ds->cfg.following_error, w, a->letter);
			return -EINVAL;
		}
		d->setup.node = d->node;
		d->setup.sync_id = cfg->can.sync_id;
		d->setup.rpdo_cob = cfg->can.rpdo_base + d->node;
		d->setup.tpdo_cob = MLIP_CO_TPDO1_BASE + d->node;
		d->setup.period_s = m->period_s;
		d->setup.following_window_counts = (uint32_t)(w + 0.5);
		d->setup.touch_probe = cfg->inputs.probe_source == MLIP_PROBE_SRC_DRIVE;
		d->setup.tpdo2_cob = MLIP_CO_TPDO2_BASE + d->node;
		d->setup.heartbeat_ms = (uint16_t)ds->cfg.heartbeat_ms;
		d->setup.master_node = ds->cfg.master_node;
		d->setup.master_timeout_ms = (uint16_t)ds->cfg.heartbeat_timeout_ms;
		double qs = a->max_accel * a->counts_per_unit;
		d->setup.quick_stop_counts_s2 = qs >= 4294967295.0 ? 4294967295u
		                                : qs < 1.0         ? 1u
		                                                   : (uint32_t)(qs + 0.5);
		if (ds->di_axes & (1u << i)) {
			uint32_t id = MLIP_CO_TPDO3_BASE + d->node;
			if (id == cfg->can.sync_id || id == cfg->can.status_id) {
				snprintf(why, why_len,
				         "AXIS_%c's drive inputs: its TPDO3 0x%03X is also the %s",
				         a->letter, (unsigned)id,
				         id == cfg->can.sync_id ? "SYNC_ID" : "STATUS_ID");
				return -EINVAL;
			}
			for (int j = 0; j < m->n_axes; j++) {
				if (cfg->can.rpdo_base + (uint32_t)m->axis[j].can_node == id) {
					snprintf(why, why_len,
					         "AXIS_%c's drive inputs: its TPDO3 0x%03X is also "
					         "AXIS_%c's RPDO (RPDO_BASE + CAN_NODE)",
					         a->letter, (unsigned)id, m->axis[j].letter);
					return -EINVAL;
				}
			}
			d->setup.di_tpdo_cob = id;
			d->setup.di_event_ms = (uint16_t)ds->cfg.heartbeat_ms;
		}
		struct mlip_sdo_entry e[MLIP_DRIVE_SETUP_MAX];
		if (mlip_drive_setup_entries(&d->setup, e, MLIP_DRIVE_SETUP_MAX) < 0) {
			snprintf(
			    why, why_len,
			    "[TRAJ] PERIOD %g s cannot be written to 0x60C2 (value 1..255 times "
			    "10^-6..10^0 s)",
			    m->period_s);
			return -EINVAL;
		}
	}
	return 0;
}

static int read_sw(struct mlip_drives *ds, int i, uint16_t *sw, char *why, size_t why_len)
{
	uint32_t v = 0;
	int rc = sdo(ds, i, 1, 0x6041, 0, 0, 0, "statusword", &v, why, why_len);
	*sw = (uint16_t)v;
	return rc;
}

/* Let the drive work for a while (frames read, the heartbeat served). */
static void pause_poll(struct mlip_drives *ds)
{
	struct mlip_can_frame f;
	struct mlip_co_msg m;
	uint64_t until = ds->port.now_ns(ds->port.ctx) + STATE_POLL_NS;
	while (wait_frame(ds, until, &f, &m) > 0) {
	}
}

/* "disable operation (0x0007)": a step's command and controlword. */
static const char *step_text(uint32_t step, char *buf, size_t n)
{
	snprintf(buf, n, "%s (0x%04X)", mlip_402_step_command(step),
	         (unsigned)mlip_402_step_cw(step));
	return buf;
}

/* Drive i to `want` (SWITCHED_ON, ENABLED or OFF) by SDO: the power
 * sequencer (mlip/canopen/cia402.h) decides each controlword, 0x6040 is
 * written when it changes, 0x6041 read at once and then every
 * STATE_POLL_NS; each step confirmed is logged with its time. One not
 * confirmed within STATE_TIMEOUT_MS: toward power an error naming the
 * drive's state (-ETIMEDOUT), toward OFF logged and gone on from. */
static int power_to(struct mlip_drives *ds, int i, mlip_drive_power want, int log_start, char *why,
                    size_t why_len)
{
	struct mlip_402_seq s;
	struct mlip_402_change ch;
	char who[32], cmd[48];
	uint16_t sw = 0;
	int32_t written = -1;
	int steps = 0;

	axis_of(ds, i, who, sizeof(who));
	mlip_402_seq_init(&s, MLIP_POWER_NONE, (uint64_t)ds->cfg.state_timeout_ms * 1000000u,
	                  ds->port.now_ns(ds->port.ctx));
	for (;;) {
		int rc = read_sw(ds, i, &sw, why, why_len);
		if (rc != 0) {
			return rc;
		}
		if (mlip_402_seq_run(&s, want, &sw, 1, 0, ds->port.now_ns(ds->port.ctx), &ch)) {
			mlip_402_state now_in = mlip_402_state_of(sw);
			if (ch.from == MLIP_POWER_NONE && log_start) {
				say(ds, "%s: power-up state \"%s\", statusword 0x%04X", who,
				    mlip_402_state_name(now_in), sw);
			} else if (ch.failed && ch.from == MLIP_POWER_WAITING) {
				snprintf(why, why_len, "%s: stays \"%s\" (statusword 0x%04X)", who,
				         mlip_402_state_name(now_in), sw);
				return -ETIMEDOUT;
			} else if (ch.failed || ch.late >= 0) {
				const struct mlip_drive_obs *o = &ds->d[i].obs;
				char emcy[64] = "";
				if (o->emcy_count > 0) {
					snprintf(emcy, sizeof(emcy), "; last EMCY 0x%04X (%s)",
					         o->emcy.code, mlip_emcy_text(o->emcy.code));
				}
				snprintf(why, why_len,
				         "%s: still \"%s\" (statusword 0x%04X) %u ms after %s "
				         "(controlword 0x%04X), expected \"%s\"%s",
				         who, mlip_402_state_name(now_in), sw,
				         (unsigned)ds->cfg.state_timeout_ms,
				         mlip_402_step_command(ch.from),
				         (unsigned)mlip_402_step_cw(ch.from),
				         mlip_402_state_name(ch.reached), emcy);
				if (ch.failed) {
					return -ETIMEDOUT;
				}
				say(ds, "%s; going on", why); /* toward OFF */
			} else if (ch.from != MLIP_POWER_NONE && ch.from != MLIP_POWER_WAITING) {
				say(ds, "%s: %s: %s, statusword 0x%04X after %.1f ms", who,
				    step_text(ch.from, cmd, sizeof(cmd)),
				    mlip_402_state_name(ch.reached), sw, (double)ch.in_step * 1e-6);
			}
			if (++steps > 8) {
				snprintf(why, why_len, "%s: does not reach \"%s\"", who,
				         mlip_drive_power_name(want));
				return -ETIMEDOUT;
			}
		}
		if (mlip_402_power_is_rest(s.step)) {
			return 0;
		}
		if (s.cw >= 0 && s.cw != written) {
			rc = sdo(ds, i, 0, 0x6040, 0, (uint32_t)s.cw, 2, "controlword", NULL, why,
			         why_len);
			if (rc != 0) {
				return rc;
			}
			written = s.cw;
			continue; /* read back at once */
		}
		pause_poll(ds);
	}
}

static int nmt_wait_all(struct mlip_drives *ds, uint8_t cmd, uint8_t state, const char *what,
                        char *why, size_t why_len)
{
	int n_all = ds->n + ds->sp;
	uint32_t seen = 0, all = (1u << n_all) - 1u;
	struct mlip_can_frame f;
	struct mlip_co_msg m;
	uint64_t t0 = ds->port.now_ns(ds->port.ctx);
	uint64_t deadline = t0 + (uint64_t)ds->cfg.boot_timeout_ms * 1000000u;
	for (int i = 0; i < n_all; i++) {
		mlip_nmt_encode(cmd, ds->d[i].node, &f);
		if (ds->port.send(ds->port.ctx, &f) != 0) {
			snprintf(why, why_len, "cannot send the NMT command 0x%02X", cmd);
			return -EIO;
		}
	}
	while (seen != all) {
		int r = wait_frame(ds, deadline, &f, &m);
		if (r < 0) {
			snprintf(why, why_len, "bus read failed: %s", strerror(-r));
			return r;
		}
		if (r == 0) {
			char list[96] = "";
			size_t k = 0;
			for (int i = 0; i < n_all; i++) {
				char who[32];
				if (!(seen & (1u << i)) && k < sizeof(list)) {
					k += (size_t)snprintf(list + k, sizeof(list) - k, "%s%s",
					                      k ? ", " : "",
					                      axis_of(ds, i, who, sizeof(who)));
				}
			}
			snprintf(why, why_len,
			         "%s: no %s within %u ms (powered? node id? bit rate? "
			         "wiring and termination?)",
			         list, what, (unsigned)ds->cfg.boot_timeout_ms);
			return -ETIMEDOUT;
		}
		if (m.kind == MLIP_CO_HEARTBEAT && m.nmt_state == state) {
			int i = mlip_drives_find_node(ds, m.node);
			if (i >= 0 && !(seen & (1u << i))) {
				char who[32];
				seen |= 1u << i;
				say(ds, "%s: %s after %.1f ms", axis_of(ds, i, who, sizeof(who)),
				    what, (double)(ds->port.now_ns(ds->port.ctx) - t0) * 1e-6);
			}
		}
	}
	return 0;
}

/* Every drive up to "switched on" (from whatever state) or on to
 * "operation enabled", then every position actual 0x6064, by SDO. */
static int all_drives_to(struct mlip_drives *ds, mlip_drive_power want, int32_t *counts, char *why,
                         size_t why_len)
{
	int rc;
	for (int i = 0; i < ds->n + ds->sp; i++) {
		rc = power_to(ds, i, want, want == MLIP_POWER_SWITCHED_ON, why, why_len);
		if (rc != 0) {
			return rc;
		}
	}
	for (int i = 0; i < ds->n; i++) {
		uint32_t v = 0;
		rc = sdo(ds, i, 1, 0x6064, 0, 0, 0, "position actual value", &v, why, why_len);
		if (rc != 0) {
			return rc;
		}
		counts[i] = (int32_t)v;
	}
	return 0;
}

/* The I/O module (issue 18), before the drives: NMT reset communication and
 * its boot-up, device type 401, the PDOs and heartbeats by SDO (each read
 * back), the inputs read once by SDO (0x6000:1..n), NMT start. An E-stop
 * that is on refuses the start: nothing is enabled under it. */
static int io_bringup(struct mlip_drives *ds, char *why, size_t why_len)
{
	struct mlip_sdo_entry e[MLIP_IO401_SETUP_MAX];
	struct mlip_can_frame f;
	struct mlip_co_msg m;
	char who[32];
	uint32_t v = 0, known = 0;
	int rc, n, stage;
	static const uint8_t cmds[2] = {MLIP_NMT_RESET_COMM, MLIP_NMT_START};
	static const uint8_t states[2] = {MLIP_NMT_BOOTUP, MLIP_NMT_OPERATIONAL};
	static const char *const what[2] = {"boot-up after NMT reset communication",
	                                    "operational after NMT start"};

	if (ds->io.node == 0) {
		return 0;
	}
	axis_of(ds, -1, who, sizeof(who));
	for (stage = 0; stage < 2; stage++) {
		uint64_t t0 = ds->port.now_ns(ds->port.ctx);
		uint64_t deadline = t0 + (uint64_t)ds->cfg.boot_timeout_ms * 1000000u;
		if (stage == 1) {
			rc = sdo(ds, -1, 1, 0x1000, 0, 0, 0, "device type", &v, why, why_len);
			if (rc != 0) {
				return rc;
			}
			if ((v & 0xFFFFu) != MLIP_IO401_DEVICE) {
				snprintf(
				    why, why_len,
				    "%s: device type 0x%08X is not a CiA 401 I/O module (0x1000 "
				    "low word 401)",
				    who, v);
				return -EPROTO;
			}
			/* what it is: a module that comes back after a loss must be
			 * this one (rt/iomodule.c). The product code is optional
			 * (CiA 301): refused, it is not compared */
			ds->io.id.type = v;
			rc = sdo(ds, -1, 1, 0x1018, 1, 0, 0, "identity: vendor-ID",
			         &ds->io.id.vendor, why, why_len);
			if (rc != 0) {
				return rc;
			}
			rc = sdo(ds, -1, 1, 0x1018, 2, 0, 0, "identity: product code",
			         &ds->io.id.product, why, why_len);
			if (rc != 0 && rc != -EPROTO) {
				return rc;
			}
			ds->io.id.has_product = rc == 0;
			say(ds, "%s: vendor-ID 0x%08X, product code %s0x%08X", who,
			    ds->io.id.vendor, rc == 0 ? "" : "(none) ", ds->io.id.product);
			/* a module that reports a fault is an E-stop: never started */
			rc = sdo(ds, -1, 1, 0x1001, 0, 0, 0, "error register", &v, why, why_len);
			if (rc != 0) {
				return rc;
			}
			if ((v & 0xFFu) != 0) {
				snprintf(why, why_len,
				         "%s: its error register 0x1001 reads 0x%02X: the module "
				         "reports a fault (CiA 301); clear it before starting",
				         who, v & 0xFFu);
				return -EPROTO;
			}
			n = mlip_io401_setup_entries(&ds->io.setup, e, MLIP_IO401_SETUP_MAX);
			for (int k = 0; k < n; k++) {
				rc = sdo_entry(ds, -1, &e[k], why, why_len);
				if (rc != 0) {
					return rc;
				}
			}
			for (int k = 1; k <= ds->io.setup.in_bytes; k++) {
				rc = sdo(ds, -1, 1, 0x6000, (uint8_t)k, 0, 0, "digital inputs", &v,
				         why, why_len);
				if (rc != 0) {
					return rc;
				}
				ds->io.img.in[k - 1] = (uint8_t)v;
			}
			ds->io.img.module_read = 1;
			say(ds,
			    "%s: CiA 401 I/O module, %d objects written and read back: TPDO 0x%03X "
			    "(0x6000:1..%u on change), %u output bytes, heartbeat %u ms",
			    who, n, MLIP_CO_TPDO1_BASE + ds->io.node, ds->io.setup.in_bytes,
			    ds->io.setup.out_bytes, ds->io.setup.heartbeat_ms);
		}
		mlip_nmt_encode(cmds[stage], ds->io.node, &f);
		if (ds->port.send(ds->port.ctx, &f) != 0) {
			snprintf(why, why_len, "cannot send the NMT command 0x%02X", cmds[stage]);
			return -EIO;
		}
		for (;;) {
			int r = wait_frame(ds, deadline, &f, &m);
			if (r < 0) {
				snprintf(why, why_len, "bus read failed: %s", strerror(-r));
				return r;
			}
			if (r == 0) {
				snprintf(
				    why, why_len,
				    "%s: no %s within %u ms (powered? node id? bit rate? wiring "
				    "and termination?)",
				    who, what[stage], (unsigned)ds->cfg.boot_timeout_ms);
				return -ETIMEDOUT;
			}
			if (m.kind == MLIP_CO_HEARTBEAT && m.node == ds->io.node &&
			    m.nmt_state == states[stage]) {
				say(ds, "%s: %s after %.1f ms", who, what[stage],
				    (double)(ds->port.now_ns(ds->port.ctx) - t0) * 1e-6);
				break;
			}
		}
	}
	ds->io.obs.hb_ns = ds->port.now_ns(ds->port.ctx);
	ds->io.obs.nmt_state = MLIP_NMT_OPERATIONAL;
	if (mlip_io_eval(&ds->io_cfg, ds->m, &ds->io.img, &known) & (1u << MLIP_IN_ESTOP)) {
		const struct mlip_io_bit *b = &ds->io_cfg.in[MLIP_IN_ESTOP];
		snprintf(why, why_len,
		         "E-stop is on (%s 0x%04X:%u bit %u reads %u): release it before starting",
		         who, b->index, b->sub, b->bit, b->active_low ? 0u : 1u);
		return -EAGAIN;
	}
	return 0;
}

int mlip_drives_bringup(struct mlip_drives *ds, double *start_pos, char *why, size_t why_len)
{
	struct mlip_sdo_entry e[MLIP_DRIVE_SETUP_MAX];
	int32_t pos_counts[MLIP_MAX_AXES];
	char who[32];
	int rc;

	ds->hb_next_ns = 0;
	rc = io_bringup(ds, why, why_len);
	if (rc != 0) {
		return rc;
	}
	rc = nmt_wait_all(ds, MLIP_NMT_RESET_COMM, MLIP_NMT_BOOTUP,
	                  "boot-up after NMT reset communication", why, why_len);
	if (rc != 0) {
		return rc;
	}
	for (int i = 0; i < ds->n + ds->sp; i++) {
		uint32_t type = 0;
		rc = sdo(ds, i, 1, 0x1000, 0, 0, 0, "device type", &type, why, why_len);
		if (rc != 0) {
			goto fail;
		}
		if ((type & 0xFFFFu) != 402) {
			snprintf(
			    why, why_len,
			    "%s: device type 0x%08X is not a CiA 402 drive (0x1000 low word 402)",
			    axis_of(ds, i, who, sizeof(who)), type);
			rc = -EPROTO;
			goto fail;
		}
		int n = mlip_drive_setup_entries(&ds->d[i].setup, e, MLIP_DRIVE_SETUP_MAX);
		for (int k = 0; k < n; k++) {
			rc = sdo_entry(ds, i, &e[k], why, why_len);
			if (rc != 0) {
				goto fail;
			}
		}
		if (ds->d[i].setup.velocity) {
			say(ds,
			    "%s: CiA 402 drive (0x1000 = 0x%08X), %d objects written and read "
			    "back: "
			    "profile velocity, RPDO 0x%03X (0x6040, 0x60FF), TPDO 0x%03X (0x6041, "
			    "0x606C), 0x6083/0x6084 %u counts/s^2, heartbeat %u ms",
			    axis_of(ds, i, who, sizeof(who)), type, n, ds->d[i].setup.rpdo_cob,
			    ds->d[i].setup.tpdo_cob, ds->d[i].setup.accel_counts_s2,
			    ds->d[i].setup.heartbeat_ms);
			continue;
		}
		say(ds,
		    "%s: CiA 402 drive (0x1000 = 0x%08X), %d objects written and read back: "
		    "CSP, RPDO 0x%03X, TPDO 0x%03X, 0x60C2 %g s, 0x6065 %u counts, 0x6085 %u "
		    "counts/s^2, heartbeat %u ms%s",
		    axis_of(ds, i, who, sizeof(who)), type, n, ds->d[i].setup.rpdo_cob,
		    ds->d[i].setup.tpdo_cob, ds->d[i].setup.period_s,
		    ds->d[i].setup.following_window_counts, ds->d[i].setup.quick_stop_counts_s2,
		    ds->d[i].setup.heartbeat_ms,
		    ds->d[i].setup.touch_probe ? ", touch probe (0x60B8 in the RPDO, 0x60B9 in the "
		                                 "TPDO, TPDO2 0x60BA/0x60BB)"
		                               : "");
		if (ds->di_axes & (1u << i)) {
			/* the switches once by SDO (as the module's inputs), then TPDO3 */
			uint32_t v = 0;
			rc = sdo(ds, i, 1, 0x60FD, 0, 0, 0, "digital inputs", &v, why, why_len);
			if (rc != 0) {
				goto fail;
			}
			ds->io.img.di[i] = v;
			ds->io.img.drives_read |= 1u << i;
			say(ds,
			    "%s: digital inputs 0x60FD = 0x%08X, TPDO3 0x%03X on change, at least "
			    "every %u ms",
			    axis_of(ds, i, who, sizeof(who)), v, ds->d[i].setup.di_tpdo_cob,
			    ds->d[i].setup.di_event_ms);
		}
	}
	rc = nmt_wait_all(ds, MLIP_NMT_START, MLIP_NMT_OPERATIONAL, "operational after NMT start",
	                  why, why_len);
	if (rc != 0) {
		goto fail;
	}
	/* where the machine is, before anything is enabled */
	rc = all_drives_to(ds, MLIP_POWER_SWITCHED_ON, pos_counts, why, why_len);
	if (rc != 0) {
		goto fail;
	}
	for (int i = 0; i < ds->n; i++) {
		const struct mlip_axis *a = &ds->m->axis[i];
		int32_t v = pos_counts[i];
		ds->d[i].start_counts = v;
		double pos = v / ds->d[i].counts_per_unit;
		const char *unit = a->kind == MLIP_AXIS_ROTARY ? "deg" : "mm";
		if (!(ds->home_axes & (1u << i)) && (pos < a->min_limit || pos > a->max_limit)) {
			snprintf(
			    why, why_len,
			    "%s is at %.4f %s (%d counts), beyond its soft limit %s %g: bring it "
			    "back within %g..%g by hand before starting",
			    axis_of(ds, i, who, sizeof(who)), pos, unit, v,
			    pos < a->min_limit ? "MIN_LIMIT" : "MAX_LIMIT",
			    pos < a->min_limit ? a->min_limit : a->max_limit, a->min_limit,
			    a->max_limit);
			rc = -ERANGE;
			goto fail;
		}
		rc =
		    sdo(ds, i, 0, 0x607A, 0, (uint32_t)v, 4, "target position", NULL, why, why_len);
		if (rc != 0) {
			goto fail;
		}
	}
	rc = all_drives_to(ds, MLIP_POWER_ENABLED, pos_counts, why, why_len);
	if (rc != 0) {
		goto fail;
	}
	for (int i = 0; i < ds->n; i++) {
		const struct mlip_axis *a = &ds->m->axis[i];
		int32_t v = pos_counts[i];
		int64_t moved = (int64_t)v - ds->d[i].start_counts;
		if (moved > (int64_t)ds->d[i].setup.following_window_counts ||
		    -moved > (int64_t)ds->d[i].setup.following_window_counts) {
			snprintf(why, why_len,
			         "%s moved %lld counts while being enabled (window 0x6065 %u)",
			         axis_of(ds, i, who, sizeof(who)), (long long)moved,
			         ds->d[i].setup.following_window_counts);
			rc = -ERANGE;
			goto fail;
		}
		ds->d[i].start_counts = v;
		start_pos[i] = v / ds->d[i].counts_per_unit;
		ds->d[i].obs.nmt_state = MLIP_NMT_OPERATIONAL;
		ds->d[i].obs.hb_ns = ds->port.now_ns(ds->port.ctx);
		ds->d[i].obs.di_ns = ds->d[i].obs.hb_ns; /* read by SDO, TPDO3s since */
		for (int k = 0; k < MLIP_DRIVE_HIST; k++) {
			ds->d[i].targets[k] = v; /* before the first period: here */
		}
		ds->d[i].obs.tpdo_count = 0;
		ds->d[i].obs.tpdo2_count = 0;
		say(ds, "%s: operation enabled at %.4f %s (%d counts): the planner starts there",
		    axis_of(ds, i, who, sizeof(who)), start_pos[i],
		    a->kind == MLIP_AXIS_ROTARY ? "deg" : "mm", v);
	}
	if (ds->sp) {
		struct mlip_drive *d = &ds->d[ds->n];
		d->obs.nmt_state = MLIP_NMT_OPERATIONAL;
		d->obs.hb_ns = ds->port.now_ns(ds->port.ctx);
		d->obs.tpdo_count = 0;
		say(ds, "%s: operation enabled, target velocity 0",
		    axis_of(ds, ds->n, who, sizeof(who)));
	}
	ds->phase = MLIP_DRIVES_RUN;
	ds->power = MLIP_POWER_ENABLED;
	return 0;
fail:
	mlip_drives_disable(ds);
	return rc;
}

void mlip_drives_disable(struct mlip_drives *ds)
{
	char why[256];
	uint16_t sw;
	for (int i = ds->n + ds->sp - 1; i >= 0; i--) {           /* the spindle first */
		if (read_sw(ds, i, &sw, why, sizeof(why)) == 0) { /* else gone or never there */
			power_to(ds, i, MLIP_POWER_OFF, 0, why, sizeof(why));
		}
	}
}

void mlip_drives_shutdown_text(const struct mlip_drives *ds, char *buf, size_t len)
{
	const struct mlip_ctl_power *p = &ds->shutdown;
	buf[0] = '\0';
	if (ds->phase == MLIP_DRIVES_OFF && !ds->shutdown_ok) {
		snprintf(buf, len,
		         "node %u did not confirm \"%s\" within %u ms after %s: statusword "
		         "0x%04X",
		         (unsigned)p->late_node,
		         mlip_402_state_name(mlip_402_step_expects(p->late_step)),
		         (unsigned)ds->cfg.state_timeout_ms, mlip_402_step_command(p->late_step),
		         (unsigned)p->late_sw);
	}
}

uint32_t mlip_drives_di_axes(const struct mlip_config *cfg)
{
	uint32_t axes = 0;
	for (uint32_t f = 0; f < MLIP_IN_COUNT; f++) {
		const struct mlip_io_bit *b = &cfg->inputs.in[f];
		if (!(cfg->inputs.mapped & (1u << f)) || b->index != 0x60FD) {
			continue;
		}
		for (int k = 0; k < cfg->machine.n_axes; k++) {
			if (cfg->machine.axis[k].can_node == b->node) {
				axes |= 1u << k;
			}
		}
	}
	return axes;
}

int mlip_drives_rx_ids(const struct mlip_machine *m, uint8_t io_node, uint8_t spindle_node,
                       int touch_probe, uint32_t di_axes, uint32_t *ids, int cap)
{
	static const uint32_t bases[4] = {MLIP_CO_SDO_TX_BASE, MLIP_CO_HB_BASE, MLIP_CO_EMCY_BASE,
	                                  MLIP_CO_TPDO1_BASE};
	int n = 0;
	for (int i = 0; i <= m->n_axes + 1; i++) {
		uint32_t node = i < m->n_axes    ? (uint32_t)m->axis[i].can_node
		                : i == m->n_axes ? io_node
		                                 : spindle_node;
		for (int b = 0; b < 4 && n < cap && node != 0; b++) {
			ids[n++] = bases[b] + node;
		}
		if (touch_probe && i < m->n_axes && n < cap) {
			ids[n++] = MLIP_CO_TPDO2_BASE + node; /* the latched positions */
		}
		if (i < m->n_axes && (di_axes & (1u << i)) && n < cap) {
			ids[n++] = MLIP_CO_TPDO3_BASE + node; /* the digital inputs 0x60FD */
		}
	}
	return n;
}

/* The text of a power event (MLIP_EV_POWER) for the log, outside the loop. */
void mlip_drives_power_text(const struct mlip_drives *ds, const struct mlip_ctl_event *e, char *buf,
                            size_t len)
{
	char cw[48], cw_to[48];
	const char *want = mlip_402_state_name(mlip_402_step_expects(e->from));
	double ms = ds->m->period_s * 1e3;
	step_text(e->from, cw, sizeof(cw));
	step_text(e->state, cw_to, sizeof(cw_to));
	if (e->r.node != 0) {
		int i = mlip_drives_find_node(ds, (uint8_t)e->r.node);
		snprintf(
		    buf, len,
		    "drives: node %u (axis %c) still \"%s\" (statusword 0x%04X) %.0f periods after "
		    "%s, expected \"%s\"",
		    (unsigned)e->r.node, i >= 0 ? ds->d[i].letter : '?',
		    mlip_402_state_name(mlip_402_state_of((uint16_t)e->r.field)),
		    (unsigned)e->r.field, e->r.value, cw, want);
		return;
	}
	switch (e->state) {
	case MLIP_POWER_DISABLING:
	case MLIP_POWER_SWITCHING_ON:
		snprintf(buf, len, "drives: %s, period %llu, block %llu (line %u): %s",
		         e->state == MLIP_POWER_DISABLING ? "at rest: disabling"
		                                          : "a program waits: enabling",
		         (unsigned long long)e->period, (unsigned long long)e->exec_seq,
		         (unsigned)e->exec_line, cw_to);
		return;
	case MLIP_POWER_OFF:
	case MLIP_POWER_ENABLED:
		snprintf(buf, len,
		         "drives: %s: \"%s\" after %.0f periods, %s in %llu periods (%.1f ms)", cw,
		         want, e->r.value, e->state == MLIP_POWER_OFF ? "disabled" : "enabled",
		         (unsigned long long)e->r.seq, (double)e->r.seq * ms);
		return;
	default:
		snprintf(buf, len, "drives: %s: \"%s\" after %.0f periods", cw, want, e->r.value);
	}
}

void mlip_drives_release(struct mlip_drives *ds)
{
	char why[256];
	struct mlip_can_frame f;
	for (int i = 0; i < ds->n + ds->sp; i++) {
		if (sdo(ds, i, 0, 0x1016, 1, 0, 4, "consumer heartbeat time (off)", NULL, why,
		        sizeof(why)) != 0) {
			say(ds, "%s", why);
		}
		mlip_nmt_encode(MLIP_NMT_PREOP, ds->d[i].node, &f);
		ds->port.send(ds->port.ctx, &f);
	}
	if (ds->io.node != 0 && ds->io.lost == 0) {
		/* outputs off, then the module stops watching us */
		if (ds->io.setup.out_bytes > 0) {
			memset(&f, 0, sizeof(f));
			f.id = 0x200u + ds->io.node;
			f.len = ds->io.setup.out_bytes;
			ds->port.send(ds->port.ctx, &f);
		}
		if (sdo(ds, -1, 0, 0x1016, 1, 0, 4, "consumer heartbeat time (off)", NULL, why,
		        sizeof(why)) != 0) {
			say(ds, "%s", why);
		}
		mlip_nmt_encode(MLIP_NMT_PREOP, ds->io.node, &f);
		ds->port.send(ds->port.ctx, &f);
	}
	say(ds, "drives released: heartbeat consumers off, NMT pre-operational");
}
