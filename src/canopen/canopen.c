/*
 * canopen.c - CANopen master frames and decisions (mlip/canopen/canopen.h): NMT,
 * heartbeat, EMCY, SDO client, CiA 402 states, the drive set-up list and
 * the supervision of one drive. Pure: no I/O, no clock, no allocation.
 *
 * SDO (CiA 301 7.2.4.3), byte 0 of every SDO frame is the command specifier:
 *   client: 0x40 initiate upload; 0x23/0x27/0x2B/0x2F expedited download of
 *           4/3/2/1 bytes (0x20 | (4 - n) << 2 | e=1 | s=1); 0x60/0x70
 *           upload segment with toggle 0/1; 0x80 abort
 *   server: 0x60 download done; 0x4F/0x4B/0x47/0x43 expedited upload of
 *           1/2/3/4 bytes; 0x41 segmented upload follows (size in 4..7);
 *           0x00-0x1F upload segment (t = bit 4, n = bits 1-3, c = bit 0);
 *           0x80 abort (code in bytes 4..7)
 * bytes 1-2 index, 3 sub-index; an answer for another index/sub-index is a
 * protocol error.
 */
#include "mlip/canopen/canopen.h"

#include <math.h>
#include <string.h>

static void put_u16(uint8_t *p, uint16_t v)
{
	p[0] = (uint8_t)(v & 0xFFu);
	p[1] = (uint8_t)(v >> 8);
}

static uint16_t get_u16(const uint8_t *p)
{
	return (uint16_t)(p[0] | (p[1] << 8));
}

static void put_u32(uint8_t *p, uint32_t v)
{
	put_u16(p, (uint16_t)(v & 0xFFFFu));
	put_u16(p + 2, (uint16_t)(v >> 16));
}

static uint32_t get_u32(const uint8_t *p)
{
	return (uint32_t)get_u16(p) | ((uint32_t)get_u16(p + 2) << 16);
}

static void frame(struct mlip_can_frame *f, uint32_t id, uint8_t len)
{
	memset(f, 0, sizeof(*f));
	f->id = id;
	f->len = len;
}

/* ---- NMT, heartbeat, EMCY ------------------------------------------------------ */

void mlip_nmt_encode(uint8_t cmd, uint8_t node, struct mlip_can_frame *f)
{
	frame(f, MLIP_CO_NMT_ID, 2);
	f->data[0] = cmd;
	f->data[1] = node;
}

void mlip_co_heartbeat_encode(uint8_t node, uint8_t state, struct mlip_can_frame *f)
{
	frame(f, MLIP_CO_HB_BASE + node, 1);
	f->data[0] = state;
}

const char *mlip_nmt_state_name(uint8_t state)
{
	switch (state) {
	case MLIP_NMT_BOOTUP:
		return "boot-up";
	case MLIP_NMT_STOPPED:
		return "stopped";
	case MLIP_NMT_OPERATIONAL:
		return "operational";
	case MLIP_NMT_PREOPERATIONAL:
		return "pre-operational";
	}
	return "unknown";
}

const char *mlip_emcy_text(uint16_t code)
{
	/* CiA 402 codes first where they say more than the class */
	switch (code) {
	case 0x0000:
		return "error reset or no error";
	case 0x8611:
		return "following error";
	case 0x8612:
		return "reference limit";
	case 0x8130:
		return "life guard or heartbeat error";
	case 0x8140:
		return "recovered from bus-off";
	case 0x7300:
		return "sensor (encoder)";
	case 0x5441:
	case 0x5442:
		return "enable input lost";
	}
	switch (code >> 12) {
	case 0x1:
		return "generic error";
	case 0x2:
		return "current";
	case 0x3:
		return "voltage";
	case 0x4:
		return "temperature";
	case 0x5:
		return "device hardware";
	case 0x6:
		return "device software";
	case 0x7:
		return "additional modules";
	case 0x8:
		return "monitoring (communication or control)";
	case 0x9:
		return "external error";
	case 0xF:
		return code >> 8 == 0xFF ? "device specific" : "additional functions";
	}
	return "unknown error code";
}

/* ---- classification --------------------------------------------------------------- */

mlip_status mlip_co_classify(const struct mlip_can_frame *f, struct mlip_co_msg *m)
{
	uint32_t base = f->id & 0x780u, node = f->id & 0x7Fu;

	memset(m, 0, sizeof(*m));
	if ((f->flags & (MLIP_CAN_FLAG_EFF | MLIP_CAN_FLAG_FD)) || node < 1 ||
	    node > MLIP_CO_NODE_MAX || f->id > MLIP_CAN_SFF_MAX) {
		return MLIP_OK;
	}
	m->node = (uint8_t)node;
	switch (base) {
	case MLIP_CO_HB_BASE:
		if (f->len != 1) {
			return MLIP_E_SYNTAX;
		}
		m->kind = MLIP_CO_HEARTBEAT;
		m->nmt_state = f->data[0] & 0x7Fu; /* bit 7: the old toggle of node guarding */
		return MLIP_OK;
	case MLIP_CO_EMCY_BASE:
		if (f->len != 8) {
			return MLIP_E_SYNTAX;
		}
		m->kind = MLIP_CO_EMCY;
		m->emcy.code = get_u16(f->data);
		m->emcy.reg = f->data[2];
		memcpy(m->emcy.vendor, f->data + 3, 5);
		return MLIP_OK;
	case MLIP_CO_TPDO1_BASE:
		if (f->len != 6) {
			return MLIP_E_SYNTAX;
		}
		m->kind = MLIP_CO_TPDO;
		m->statusword = get_u16(f->data);
		m->position_counts = (int32_t)get_u32(f->data + 2);
		return MLIP_OK;
	case MLIP_CO_SDO_TX_BASE:
		if (f->len != 8) {
			return MLIP_E_SYNTAX;
		}
		m->kind = MLIP_CO_SDO;
		return MLIP_OK;
	}
	m->node = 0;
	return MLIP_OK;
}

void mlip_co_pdo_encode(uint32_t id, uint16_t word, int32_t counts, struct mlip_can_frame *f)
{
	frame(f, id, 6);
	put_u16(f->data, word);
	put_u32(f->data + 2, (uint32_t)counts);
}

/* ---- SDO client ---------------------------------------------------------------------- */

static void sdo_req(struct mlip_can_frame *f, uint8_t node, uint8_t cs, uint16_t index, uint8_t sub)
{
	frame(f, MLIP_CO_SDO_RX_BASE + node, 8);
	f->data[0] = cs;
	put_u16(f->data + 1, index);
	f->data[3] = sub;
}

static void sdo_begin(struct mlip_sdo *s, uint8_t node, uint16_t index, uint8_t sub)
{
	memset(s, 0, sizeof(*s));
	s->node = node;
	s->index = index;
	s->sub = sub;
}

void mlip_sdo_download_begin(struct mlip_sdo *s, uint8_t node, uint16_t index, uint8_t sub,
                             uint32_t value, uint8_t size, struct mlip_can_frame *req)
{
	sdo_begin(s, node, index, sub);
	s->size = size >= 1 && size <= 4 ? size : 4;
	s->value = value;
	sdo_req(req, node, (uint8_t)(0x23u | ((4u - s->size) << 2)), index, sub);
	put_u32(req->data + 4, s->size == 4 ? value : value & ((1u << (8 * s->size)) - 1u));
}

void mlip_sdo_upload_begin(struct mlip_sdo *s, uint8_t node, uint16_t index, uint8_t sub,
                           struct mlip_can_frame *req)
{
	sdo_begin(s, node, index, sub);
	s->upload = 1;
	sdo_req(req, node, 0x40, index, sub);
}

void mlip_sdo_abort_encode(uint8_t node, uint16_t index, uint8_t sub, uint32_t code,
                           struct mlip_can_frame *f)
{
	sdo_req(f, node, 0x80, index, sub);
	put_u32(f->data + 4, code);
}

static mlip_sdo_step protocol(struct mlip_sdo *s, uint32_t code, struct mlip_can_frame *req)
{
	s->abort_code = code;
	mlip_sdo_abort_encode(s->node, s->index, s->sub, code, req);
	return MLIP_SDO_PROTOCOL;
}

static void upload_value(struct mlip_sdo *s)
{
	uint8_t b[4] = {0, 0, 0, 0};
	memcpy(b, s->data, s->len < 4 ? s->len : 4);
	s->value = get_u32(b);
}

mlip_sdo_step mlip_sdo_feed(struct mlip_sdo *s, const struct mlip_can_frame *ans,
                            struct mlip_can_frame *req)
{
	const uint8_t *d = ans->data;
	uint8_t cs;

	if (ans->id != MLIP_CO_SDO_TX_BASE + s->node || ans->len != 8 || ans->flags != 0) {
		return MLIP_SDO_IGNORED;
	}
	cs = d[0];
	if (cs == 0x80) {
		/* an abort names the object it is about; one for another object is stale */
		if (get_u16(d + 1) != s->index || d[3] != s->sub) {
			return MLIP_SDO_IGNORED;
		}
		s->abort_code = get_u32(d + 4);
		return MLIP_SDO_ABORTED;
	}
	if (s->segmented) {
		uint32_t n;
		if ((cs & 0xE0u) != 0x00u) {
			return protocol(s, MLIP_SDO_ABORT_COMMAND, req);
		}
		if (((cs >> 4) & 1u) != s->toggle) {
			return protocol(s, MLIP_SDO_ABORT_TOGGLE, req);
		}
		n = 7u - ((cs >> 1) & 7u);
		if (s->len + n > MLIP_SDO_MAX_DATA) {
			return protocol(s, MLIP_SDO_ABORT_MEMORY, req);
		}
		memcpy(s->data + s->len, d + 1, n);
		s->len += n;
		if (cs & 1u) {
			upload_value(s);
			return MLIP_SDO_DONE;
		}
		s->toggle ^= 1u;
		sdo_req(req, s->node, (uint8_t)(0x60u | (s->toggle << 4)), 0, 0);
		memset(req->data + 1, 0, 7);
		return MLIP_SDO_SEND;
	}
	if (get_u16(d + 1) != s->index || d[3] != s->sub) {
		return protocol(s, MLIP_SDO_ABORT_GENERAL, req);
	}
	if (!s->upload) {
		return cs == 0x60 ? MLIP_SDO_DONE : protocol(s, MLIP_SDO_ABORT_COMMAND, req);
	}
	if ((cs & 0xE0u) != 0x40u) {
		return protocol(s, MLIP_SDO_ABORT_COMMAND, req);
	}
	if (cs & 0x02u) { /* expedited: n given when s = 1, else 4 bytes */
		s->len = (cs & 0x01u) ? 4u - ((cs >> 2) & 3u) : 4u;
		memcpy(s->data, d + 4, s->len);
		upload_value(s);
		return MLIP_SDO_DONE;
	}
	/* segmented: ask for the first segment, toggle 0 */
	s->segmented = 1;
	s->toggle = 0;
	sdo_req(req, s->node, 0x60, 0, 0);
	memset(req->data + 1, 0, 7);
	return MLIP_SDO_SEND;
}

const char *mlip_sdo_abort_text(uint32_t code)
{
	static const struct {
		uint32_t code;
		const char *text;
	} t[] = {
	    {0x05030000u, "toggle bit not alternated"},
	    {0x05040000u, "SDO protocol timed out"},
	    {0x05040001u, "client/server command specifier not valid or unknown"},
	    {0x05040002u, "invalid block size"},
	    {0x05040003u, "invalid sequence number"},
	    {0x05040004u, "CRC error"},
	    {0x05040005u, "out of memory"},
	    {0x06010000u, "unsupported access to an object"},
	    {0x06010001u, "attempt to read a write only object"},
	    {0x06010002u, "attempt to write a read only object"},
	    {0x06020000u, "object does not exist in the object dictionary"},
	    {0x06040041u, "object cannot be mapped to the PDO"},
	    {0x06040042u,
	     "the number and length of the objects to be mapped would exceed PDO length"},
	    {0x06040043u, "general parameter incompatibility"},
	    {0x06040047u, "general internal incompatibility in the device"},
	    {0x06060000u, "access failed due to a hardware error"},
	    {0x06070010u, "data type does not match, length of service parameter does not match"},
	    {0x06070012u, "data type does not match, length of service parameter too high"},
	    {0x06070013u, "data type does not match, length of service parameter too low"},
	    {0x06090011u, "sub-index does not exist"},
	    {0x06090030u, "invalid value for parameter (download only)"},
	    {0x06090031u, "value of parameter written too high (download only)"},
	    {0x06090032u, "value of parameter written too low (download only)"},
	    {0x06090036u, "maximum value is less than minimum value"},
	    {0x060A0023u, "resource not available: SDO connection"},
	    {0x08000000u, "general error"},
	    {0x08000020u, "data cannot be transferred or stored to the application"},
	    {0x08000021u, "data cannot be transferred or stored to the application because of "
	                  "local control"},
	    {0x08000022u, "data cannot be transferred or stored to the application because of the "
	                  "present device state"},
	    {0x08000023u, "object dictionary dynamic generation fails or no object dictionary is "
	                  "present"},
	    {0x08000024u, "no data available"},
	};
	size_t i;

	for (i = 0; i < sizeof(t) / sizeof(t[0]); i++) {
		if (t[i].code == code) {
			return t[i].text;
		}
	}
	return "unknown abort code";
}

/* ---- CiA 402 ------------------------------------------------------------------------------ */

mlip_402_state mlip_402_state_of(uint16_t sw)
{
	/* CiA 402-2 table "statusword state coding": bits 0-3 and 6 (mask 0x4F)
	 * for the first and last states, 0-3, 5, 6 (mask 0x6F) for the others */
	switch (sw & 0x4Fu) {
	case 0x00:
		return MLIP_402_NOT_READY;
	case 0x40:
		return MLIP_402_SWITCH_ON_DISABLED;
	case 0x0F:
		return MLIP_402_FAULT_REACTION_ACTIVE;
	case 0x08:
		return MLIP_402_FAULT;
	}
	switch (sw & 0x6Fu) {
	case 0x21:
		return MLIP_402_READY_TO_SWITCH_ON;
	case 0x23:
		return MLIP_402_SWITCHED_ON;
	case 0x27:
		return MLIP_402_OPERATION_ENABLED;
	case 0x07:
		return MLIP_402_QUICK_STOP_ACTIVE;
	}
	return MLIP_402_UNKNOWN;
}

const char *mlip_402_state_name(mlip_402_state s)
{
	static const char *const names[] = {"not ready to switch on",
	                                    "switch on disabled",
	                                    "ready to switch on",
	                                    "switched on",
	                                    "operation enabled",
	                                    "quick stop active",
	                                    "fault reaction active",
	                                    "fault",
	                                    "unknown"};
	return (int)s >= 0 && s <= MLIP_402_UNKNOWN ? names[s] : "unknown";
}

int mlip_402_step_up(mlip_402_state s)
{
	switch (s) {
	case MLIP_402_FAULT:
		return MLIP_402_CW_FAULT_RESET;
	case MLIP_402_SWITCH_ON_DISABLED:
	case MLIP_402_QUICK_STOP_ACTIVE: /* through "switch on disabled" (disable voltage) */
		return s == MLIP_402_QUICK_STOP_ACTIVE ? MLIP_402_CW_DISABLE_VOLTAGE
		                                       : MLIP_402_CW_SHUTDOWN;
	case MLIP_402_READY_TO_SWITCH_ON:
		return MLIP_402_CW_SWITCH_ON;
	case MLIP_402_SWITCHED_ON:
	case MLIP_402_OPERATION_ENABLED:
		return MLIP_402_CW_ENABLE_OPERATION;
	default:
		return -1;
	}
}

mlip_402_state mlip_402_after(mlip_402_state s, uint16_t cw)
{
	/* the command is decoded from bits 0-3 and 7 (CiA 402-2 controlword table) */
	if ((cw & 0x80u) && s == MLIP_402_FAULT) {
		return MLIP_402_SWITCH_ON_DISABLED;
	}
	if ((cw & 0x02u) == 0) { /* disable voltage */
		return s == MLIP_402_FAULT ? s : MLIP_402_SWITCH_ON_DISABLED;
	}
	if ((cw & 0x04u) == 0) { /* quick stop */
		return s == MLIP_402_OPERATION_ENABLED ? MLIP_402_QUICK_STOP_ACTIVE
		       : s == MLIP_402_FAULT           ? s
		                                       : MLIP_402_SWITCH_ON_DISABLED;
	}
	switch (cw & 0x0Fu) {
	case MLIP_402_CW_SHUTDOWN:
		return s == MLIP_402_FAULT ? s : MLIP_402_READY_TO_SWITCH_ON;
	case MLIP_402_CW_SWITCH_ON:
		return s == MLIP_402_READY_TO_SWITCH_ON || s == MLIP_402_SWITCHED_ON ||
		               s == MLIP_402_OPERATION_ENABLED
		           ? MLIP_402_SWITCHED_ON
		           : s;
	case MLIP_402_CW_ENABLE_OPERATION:
		return s == MLIP_402_SWITCHED_ON || s == MLIP_402_OPERATION_ENABLED
		           ? MLIP_402_OPERATION_ENABLED
		       : s == MLIP_402_READY_TO_SWITCH_ON ? MLIP_402_SWITCHED_ON /* 3 then 4 */
		                                          : s;
	}
	return s;
}

/* ---- the set-up list ------------------------------------------------------------------------ */

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
	struct mlip_sdo_entry e[MLIP_DRIVE_SETUP_MAX];
	int n = 0;

	if (mlip_co_interp_period(d->period_s, &pv, &pi) != MLIP_OK) {
		return -1;
	}
#define ADD(ix, sb, sz, val, w)                                                                    \
	do {                                                                                       \
		e[n].index = (ix);                                                                 \
		e[n].sub = (sb);                                                                   \
		e[n].size = (sz);                                                                  \
		e[n].value = (val);                                                                \
		e[n].read_only = 0;                                                                \
		e[n].what = (w);                                                                   \
		n++;                                                                               \
	} while (0)
	ADD(0x1400, 1, 4, off | d->rpdo_cob, "RPDO1 COB-ID (disabled while mapping)");
	ADD(0x1400, 2, 1, 1, "RPDO1 transmission type (synchronous)");
	ADD(0x1600, 0, 1, 0, "RPDO1 mapping count (cleared)");
	ADD(0x1600, 1, 4, 0x60400010u, "RPDO1 mapping 1: controlword 0x6040");
	ADD(0x1600, 2, 4, 0x607A0020u, "RPDO1 mapping 2: target position 0x607A");
	ADD(0x1600, 0, 1, 2, "RPDO1 mapping count");
	ADD(0x1400, 1, 4, d->rpdo_cob, "RPDO1 COB-ID");
	ADD(0x1800, 1, 4, off | no_rtr | d->tpdo_cob, "TPDO1 COB-ID (disabled while mapping)");
	ADD(0x1800, 2, 1, 1, "TPDO1 transmission type (synchronous, every SYNC)");
	ADD(0x1A00, 0, 1, 0, "TPDO1 mapping count (cleared)");
	ADD(0x1A00, 1, 4, 0x60410010u, "TPDO1 mapping 1: statusword 0x6041");
	ADD(0x1A00, 2, 4, 0x60640020u, "TPDO1 mapping 2: position actual value 0x6064");
	ADD(0x1A00, 0, 1, 2, "TPDO1 mapping count");
	ADD(0x1800, 1, 4, no_rtr | d->tpdo_cob, "TPDO1 COB-ID");
	ADD(0x1005, 0, 4, d->sync_id, "COB-ID SYNC (consumer)");
	ADD(0x6060, 0, 1, MLIP_402_MODE_CSP, "modes of operation (8: cyclic synchronous position)");
	ADD(0x6061, 0, 1, MLIP_402_MODE_CSP, "modes of operation display");
	e[n - 1].read_only = 1;
	ADD(0x60C2, 1, 1, pv, "interpolation time period value");
	ADD(0x60C2, 2, 1, (uint8_t)pi, "interpolation time index");
	ADD(0x6065, 0, 4, d->following_window_counts, "following error window");
	ADD(0x1017, 0, 2, d->heartbeat_ms, "producer heartbeat time (ms)");
	ADD(0x1016, 1, 4, ((uint32_t)d->master_node << 16) | d->master_timeout_ms,
	    "consumer heartbeat time: the master's node and timeout (ms)");
#undef ADD
	if (n > cap) {
		return -1;
	}
	memcpy(out, e, (size_t)n * sizeof(e[0]));
	return n;
}

/* ---- supervision ------------------------------------------------------------------------------
 */

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
	                                    "beyond a soft limit"};
	return (int)f >= 0 && f <= MLIP_DRIVE_BEYOND_LIMIT ? names[f] : "?";
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
