/*
 * canopen.c - CANopen master frames (mlip/canopen/canopen.h): NMT, heartbeat,
 * EMCY, classification, PDO payload, SDO client. Pure: no I/O, no clock, no
 * allocation.
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
		if (f->len != 6 && f->len != 8) {
			return MLIP_E_SYNTAX;
		}
		m->kind = MLIP_CO_TPDO;
		m->statusword = get_u16(f->data);
		m->position_counts = (int32_t)get_u32(f->data + 2);
		if (f->len == 8) {
			m->has_probe = 1;
			m->probe_status = get_u16(f->data + 6);
		}
		return MLIP_OK;
	case MLIP_CO_TPDO2_BASE:
		if (f->len != 8) {
			return MLIP_E_SYNTAX;
		}
		m->kind = MLIP_CO_TPDO2;
		m->probe_pos = (int32_t)get_u32(f->data);
		m->probe_neg = (int32_t)get_u32(f->data + 4);
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

static void sdo_add(struct mlip_sdo_list *l, uint16_t index, uint8_t sub, uint8_t size,
                    uint32_t value, uint8_t read_only, const char *what)
{
	if (l->n < l->cap) {
		struct mlip_sdo_entry *e = &l->e[l->n];
		e->index = index;
		e->sub = sub;
		e->size = size;
		e->value = value;
		e->read_only = read_only;
		e->what = what;
	}
	l->n++;
}

void mlip_sdo_add(struct mlip_sdo_list *l, uint16_t index, uint8_t sub, uint8_t size,
                  uint32_t value, const char *what)
{
	sdo_add(l, index, sub, size, value, 0, what);
}

void mlip_sdo_add_check(struct mlip_sdo_list *l, uint16_t index, uint8_t sub, uint8_t size,
                        uint32_t value, const char *what)
{
	sdo_add(l, index, sub, size, value, 1, what);
}

/* "RPDOn ..." / "TPDOn ..." for the steps every PDO takes (entries keep the
 * pointer: static text) */
#define PDO_TEXTS(P)                                                                               \
	{                                                                                          \
		P " COB-ID (disabled while mapping)", P " mapping count (cleared)",                \
		    P " mapping count", P " COB-ID"                                                \
	}
static const char *const pdo_texts[2][4][4] = {
    {PDO_TEXTS("RPDO1"), PDO_TEXTS("RPDO2"), PDO_TEXTS("RPDO3"), PDO_TEXTS("RPDO4")},
    {PDO_TEXTS("TPDO1"), PDO_TEXTS("TPDO2"), PDO_TEXTS("TPDO3"), PDO_TEXTS("TPDO4")}};

mlip_status mlip_sdo_add_pdo(struct mlip_sdo_list *l, const struct mlip_pdo_map *p)
{
	/* COB-ID bit 31: PDO not valid (disabled while it is mapped); bit 30 of
	 * a TPDO: no RTR allowed */
	const uint32_t off = 0x80000000u, no_rtr = p->tpdo ? 0x40000000u : 0u;
	const char *const *t;
	uint16_t comm, map;
	uint8_t k;

	if (p->num < 1 || p->num > 4 || p->n < 1 || p->n > 8) {
		return MLIP_E_RANGE;
	}
	t = pdo_texts[p->tpdo ? 1 : 0][p->num - 1];
	comm = (uint16_t)((p->tpdo ? 0x1800u : 0x1400u) + p->num - 1u);
	map = (uint16_t)(comm + 0x200u);
	mlip_sdo_add(l, comm, 1, 4, off | no_rtr | p->cob_id, t[0]);
	mlip_sdo_add(l, comm, 2, 1, p->type, p->type_what);
	if (p->event_what != NULL) {
		mlip_sdo_add(l, comm, 5, 2, p->event_ms, p->event_what);
	}
	mlip_sdo_add(l, map, 0, 1, 0, t[1]);
	for (k = 0; k < p->n; k++) {
		mlip_sdo_add(l, map, (uint8_t)(k + 1u), 4, p->map[k], p->what[k]);
	}
	mlip_sdo_add(l, map, 0, 1, p->n, t[2]);
	mlip_sdo_add(l, comm, 1, 4, no_rtr | p->cob_id, t[3]);
	return MLIP_OK;
}
