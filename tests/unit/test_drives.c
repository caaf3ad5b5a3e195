/*
 * test_drives.c - the CANopen master of rt/drives.c against a scripted peer:
 * three CiA 402 drives written here from the standard's tables (their own
 * object dictionary, SDO server and power state machine, not mlip's), on a
 * virtual clock, so that timeouts take no time. Bring-up from power-up
 * states (switch on disabled, fault, operation enabled), a refused SDO, a
 * missing drive, a drive that never enables, an axis beyond its soft limit;
 * then the loop: supervision (fault bit, following error, lost heartbeat,
 * EMCY) and the shut-down in order with the SYNC running.
 * The same cases run against the canopen package's drives on vcan
 * (tests/can/).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "rt.h"

/* ---- the peer: one CiA 402 drive -------------------------------------------- */

enum { P_SOD, P_RTSO, P_SO, P_OE, P_FAULT, P_QS }; /* switch on disabled .. quick stop */
static const uint16_t p_sw[] = {0x0250, 0x0231, 0x0233, 0x1237, 0x0218, 0x0217};
static int qs_periods; /* > 0: a quick stop brakes that many periods in P_QS */

struct od {
	uint16_t index;
	uint8_t sub, size;
	uint32_t value;
};

struct wr {
	uint16_t index;
	uint8_t sub;
	uint32_t value;
};

struct peer {
	uint8_t node;
	int present, nmt, state, ever_enabled, no_enable, qs_left;
	uint16_t cw;
	int32_t pos;
	struct od od[32];
	int n_od;
	uint16_t refuse_index;
	uint32_t refuse_code;
	struct wr wr[64];
	int n_wr;
};

#define NP 3
static struct peer peers[NP + 1]; /* [NP]: a spindle drive, in its tests only */
static struct mlip_can_frame q[256];
static unsigned q_head, q_tail;
static uint64_t now_ns;

static void push(const struct mlip_can_frame *f)
{
	q[q_tail++ % 256] = *f;
}

static struct od *od_find(struct peer *p, uint16_t index, uint8_t sub)
{
	for (int i = 0; i < p->n_od; i++) {
		if (p->od[i].index == index && p->od[i].sub == sub) {
			return &p->od[i];
		}
	}
	return NULL;
}

/* The quick stop option code written (0x605A): 5..8 stay in quick stop
 * active at rest; 0..4 (or unwritten: this peer's default 2) go on to
 * switch on disabled. */
static int qs_holds(struct peer *p)
{
	struct od *o = od_find(p, 0x605A, 0);
	return o != NULL && o->value >= 5 && o->value <= 8;
}

static void od_add(struct peer *p, uint16_t index, uint8_t sub, uint8_t size, uint32_t v)
{
	p->od[p->n_od++] = (struct od){index, sub, size, v};
}

static void peer_init(struct peer *p, uint8_t node, int state, int32_t pos)
{
	static const struct {
		uint16_t i;
		uint8_t s, n;
	} objs[] = {{0x1400, 1, 4}, {0x1400, 2, 1}, {0x1600, 0, 1}, {0x1600, 1, 4}, {0x1600, 2, 4},
	            {0x1800, 1, 4}, {0x1800, 2, 1}, {0x1A00, 0, 1}, {0x1A00, 1, 4}, {0x1A00, 2, 4},
	            {0x1005, 0, 4}, {0x6060, 0, 1}, {0x6061, 0, 1}, {0x60C2, 1, 1}, {0x60C2, 2, 1},
	            {0x6065, 0, 4}, {0x1017, 0, 2}, {0x1016, 1, 4}, {0x6040, 0, 2}, {0x6041, 0, 2},
	            {0x6064, 0, 4}, {0x607A, 0, 4}, {0x6085, 0, 4}, {0x605A, 0, 2}};
	memset(p, 0, sizeof(*p));
	p->node = node;
	p->present = 1;
	p->nmt = MLIP_NMT_PREOPERATIONAL;
	p->state = state;
	p->pos = pos;
	od_add(p, 0x1000, 0, 4, 0x00020192u); /* CiA 402 servo */
	for (size_t k = 0; k < sizeof(objs) / sizeof(objs[0]); k++) {
		od_add(p, objs[k].i, objs[k].s, objs[k].n, 0);
	}
	od_add(p, 0x6061, 1, 1, 0);       /* placeholder, never read */
	od_find(p, 0x6060, 0)->value = 1; /* powered up in profile position mode */
}

/* CiA 402-2 transitions, from the controlword bits (not mlip's code) */
static void peer_cw(struct peer *p, uint16_t cw)
{
	int rising7 = (cw & 0x80) && !(p->cw & 0x80);
	p->cw = cw;
	switch (p->state) {
	case P_FAULT:
		if (rising7) {
			p->state = P_SOD;
		}
		break;
	case P_SOD:
		if ((cw & 0x87) == 0x06) {
			p->state = P_RTSO;
		}
		break;
	case P_RTSO:
		if ((cw & 0x02) == 0) {
			p->state = P_SOD;
		} else if ((cw & 0x8F) == 0x07) {
			p->state = P_SO;
		}
		break;
	case P_SO:
		if ((cw & 0x8F) == 0x0F && !p->no_enable) {
			p->state = P_OE;
		} else if ((cw & 0x87) == 0x06) {
			p->state = P_RTSO;
		} else if ((cw & 0x02) == 0) {
			p->state = P_SOD;
		}
		break;
	case P_QS:
		if ((cw & 0x02) == 0) {
			p->state = P_SOD; /* disable voltage (12) */
		} else if ((cw & 0x8F) == 0x0F) {
			p->state = P_OE; /* enable operation (16) */
		}
		break;
	case P_OE:
		if ((cw & 0x87) == 0x02) {
			/* quick stop: braking, then (option code 2) switch on disabled
			 * or (5..8, what mlip writes) held in quick stop active */
			p->state = qs_periods > 0 || qs_holds(p) ? P_QS : P_SOD;
			p->qs_left = qs_periods;
		} else if ((cw & 0x8F) == 0x07) {
			p->state = P_SO;
		} else if ((cw & 0x87) == 0x06) {
			p->state = P_RTSO;
		} else if ((cw & 0x02) == 0) {
			p->state = P_SOD;
		}
		break;
	}
	if (p->state == P_OE) {
		p->ever_enabled = 1;
	}
}

static void sdo_answer(struct peer *p, const uint8_t *rq, uint8_t cs, uint32_t v)
{
	struct mlip_can_frame f;
	memset(&f, 0, sizeof(f));
	f.id = 0x580u + p->node;
	f.len = 8;
	f.data[0] = cs;
	memcpy(f.data + 1, rq + 1, 3);
	f.data[4] = (uint8_t)v;
	f.data[5] = (uint8_t)(v >> 8);
	f.data[6] = (uint8_t)(v >> 16);
	f.data[7] = (uint8_t)(v >> 24);
	push(&f);
}

static void peer_sdo(struct peer *p, const uint8_t *rq)
{
	uint16_t index = (uint16_t)(rq[1] | rq[2] << 8);
	uint8_t sub = rq[3];
	uint32_t v =
	    (uint32_t)rq[4] | (uint32_t)rq[5] << 8 | (uint32_t)rq[6] << 16 | (uint32_t)rq[7] << 24;
	struct od *o = od_find(p, index, sub);
	if (rq[0] == 0x80) {
		return; /* the client's abort */
	}
	if (o == NULL) {
		sdo_answer(p, rq, 0x80, od_find(p, index, 0) ? 0x06090011u : 0x06020000u);
		return;
	}
	if (rq[0] == 0x40) {
		uint32_t val = o->value;
		if (index == 0x6041) {
			val = p_sw[p->state];
		} else if (index == 0x6064) {
			val = (uint32_t)p->pos;
		} else if (index == 0x6061) {
			val = od_find(p, 0x6060, 0)->value;
		}
		sdo_answer(p, rq, (uint8_t)(0x43 | ((4 - o->size) << 2)), val);
		return;
	}
	if ((rq[0] & 0xE3) == 0x23) {
		if (index == p->refuse_index && p->refuse_code) {
			sdo_answer(p, rq, 0x80, p->refuse_code);
			return;
		}
		uint8_t n = (uint8_t)(4 - ((rq[0] >> 2) & 3));
		if (n != o->size) {
			sdo_answer(p, rq, 0x80, 0x06070010u);
			return;
		}
		o->value = v;
		if (p->n_wr < 64) {
			p->wr[p->n_wr++] = (struct wr){index, sub, v};
		}
		if (index == 0x6040) {
			peer_cw(p, (uint16_t)v);
		}
		sdo_answer(p, rq, 0x60, 0);
		return;
	}
	sdo_answer(p, rq, 0x80, 0x05040001u);
}

static void peer_hb(struct peer *p)
{
	struct mlip_can_frame f;
	mlip_co_heartbeat_encode(p->node, (uint8_t)p->nmt, &f);
	push(&f);
}

/* ---- the port --------------------------------------------------------------- */

static struct mlip_can_frame module_out; /* the last RPDO to node 10 (the module) */
static int n_module_out;
static int n_module_reset, n_module_sdo; /* NMT reset communication / SDO requests to it */

static int32_t wire[NP]; /* the last target each drive's RPDO carried on the bus */
static uint64_t n_wire;  /* RPDOs to the drives put on the bus */

static int port_send(void *ctx, const struct mlip_can_frame *f)
{
	(void)ctx;
	for (int i = 0; i < NP; i++) {
		if (f->id == 0x200u + (uint32_t)(i + 1) && f->len == 6) {
			memcpy(&wire[i], f->data + 2, 4); /* little-endian host, as CANopen */
			n_wire++;
		}
	}
	if (f->id == 0x20Au) {
		module_out = *f;
		n_module_out++;
	}
	if (f->id == 0 && f->data[0] == MLIP_NMT_RESET_COMM && f->data[1] == 10) {
		n_module_reset++;
	} else if (f->id == 0x60Au) {
		n_module_sdo++;
	}
	for (int i = 0; i < NP + 1; i++) {
		struct peer *p = &peers[i];
		if (!p->present) {
			continue;
		}
		if (f->id == 0 && (f->data[1] == 0 || f->data[1] == p->node)) {
			switch (f->data[0]) {
			case MLIP_NMT_RESET_COMM:
				p->nmt = MLIP_NMT_BOOTUP;
				peer_hb(p);
				p->nmt = MLIP_NMT_PREOPERATIONAL;
				break;
			case MLIP_NMT_START:
				p->nmt = MLIP_NMT_OPERATIONAL;
				peer_hb(p);
				break;
			case MLIP_NMT_PREOP:
				p->nmt = MLIP_NMT_PREOPERATIONAL;
				break;
			}
		} else if (f->id == 0x600u + p->node && f->len == 8) {
			peer_sdo(p, f->data);
		}
	}
	return 0;
}

static int port_recv(void *ctx, struct mlip_can_frame *f, int64_t timeout_ns)
{
	(void)ctx;
	if (q_head != q_tail) {
		*f = q[q_head++ % 256];
		now_ns += 100000; /* 0.1 ms per answer */
		return 1;
	}
	if (timeout_ns > 0) {
		now_ns += (uint64_t)timeout_ns;
	}
	return 0;
}

static uint64_t port_now(void *ctx)
{
	(void)ctx;
	return now_ns;
}

static const struct mlip_can_port port = {NULL, port_send, port_recv, port_now};

/* ---- fixtures ------------------------------------------------------------------- */

static struct mlip_config cfg;
static int keep_queue;               /* answers sent in a period's hooks are read in the next */
static uint32_t di_send, di_val[NP]; /* drives sending TPDO3 (0x60FD) every 100 ms */
static struct mlip_drives ds;
static char why[320];
static char logbuf[8192];

static void log_line(void *ctx, const char *line)
{
	(void)ctx;
	strncat(logbuf, line, sizeof(logbuf) - strlen(logbuf) - 2);
	strcat(logbuf, "\n");
}

static int setup(void **state)
{
	(void)state;
	mlip_config_defaults(&cfg);
	struct mlip_machine *m = &cfg.machine;
	m->n_axes = NP;
	m->max_feed_mm_s = 200.0;
	m->tolerance_mm = 0.01;
	for (int k = 0; k < NP; k++) {
		m->axis[k].letter = "XYZ"[k];
		m->axis[k].kind = MLIP_AXIS_LINEAR;
		m->axis[k].max_accel = 1000.0;
		m->axis[k].max_vel = 200.0;
		m->axis[k].min_limit = -1000.0;
		m->axis[k].max_limit = 1000.0;
		m->axis[k].can_node = k + 1;
		m->axis[k].counts_per_unit = 1000.0;
	}
	cfg.drives.enable = 1;
	/* power-up states: switch on disabled, fault, already enabled */
	peer_init(&peers[0], 1, P_SOD, 1234);
	peer_init(&peers[1], 2, P_FAULT, -500);
	peer_init(&peers[2], 3, P_OE, 0);
	peers[2].ever_enabled = 0;
	memset(&peers[NP], 0, sizeof(peers[NP])); /* no spindle */
	q_head = q_tail = 0;
	di_send = 0;
	keep_queue = 0;
	qs_periods = 0;
	n_module_out = 0;
	memset(di_val, 0, sizeof(di_val));
	now_ns = 1000000000u;
	logbuf[0] = '\0';
	why[0] = '\0';
	return 0;
}

static int writes_of(const struct peer *p, uint16_t index, uint8_t sub, uint32_t *last)
{
	int n = 0;
	for (int i = 0; i < p->n_wr; i++) {
		if (p->wr[i].index == index && p->wr[i].sub == sub) {
			n++;
			*last = p->wr[i].value;
		}
	}
	return n;
}

static int bringup(double *start)
{
	assert_int_equal(mlip_drives_init(&ds, &cfg, &port, log_line, NULL, why, sizeof(why)), 0);
	return mlip_drives_bringup(&ds, start, why, sizeof(why));
}

/* ---- bring-up ---------------------------------------------------------------------- */

static void test_bringup_three(void **state)
{
	double start[NP];
	uint32_t v = 0;
	(void)state;
	int rc = bringup(start);
	if (rc != 0) {
		print_error("%s\n%s", why, logbuf);
	}
	assert_int_equal(rc, 0);
	/* the start is where each drive is, to the count */
	assert_true(start[0] * 1000.0 == 1234.0);
	assert_true(start[1] * 1000.0 == -500.0);
	assert_true(start[2] == 0.0);
	for (int i = 0; i < NP; i++) {
		struct peer *p = &peers[i];
		assert_int_equal(p->state, P_OE);
		assert_int_equal(p->nmt, MLIP_NMT_OPERATIONAL);
		/* written and read back */
		assert_int_equal(od_find(p, 0x6060, 0)->value, 8);
		assert_int_equal(od_find(p, 0x1600, 1)->value, 0x60400010u);
		assert_int_equal(od_find(p, 0x1600, 2)->value, 0x607A0020u);
		assert_int_equal(od_find(p, 0x1600, 0)->value, 2);
		assert_int_equal(od_find(p, 0x1A00, 1)->value, 0x60410010u);
		assert_int_equal(od_find(p, 0x1A00, 2)->value, 0x60640020u);
		assert_int_equal(od_find(p, 0x1800, 2)->value, 1);
		assert_int_equal(od_find(p, 0x1400, 1)->value, 0x200u + p->node);
		assert_int_equal(od_find(p, 0x1800, 1)->value, 0x40000180u + p->node);
		assert_int_equal(od_find(p, 0x60C2, 1)->value, 1);
		assert_int_equal(od_find(p, 0x60C2, 2)->value, 0xFD);
		assert_int_equal(od_find(p, 0x6065, 0)->value, 1000);
		/* quick stop on the drive's ramp at the axis' 1000 mm/s^2 */
		assert_int_equal(od_find(p, 0x6085, 0)->value, 1000000);
		/* and held there at rest (quick stop option code 6) */
		assert_int_equal(od_find(p, 0x605A, 0)->value, 6);
		assert_int_equal(od_find(p, 0x1017, 0)->value, 100);
		assert_int_equal(od_find(p, 0x1016, 1)->value, (127u << 16) | 300u);
		/* the target was set to the position before operation was enabled */
		int i607a = -1, ienable = -1;
		for (int k = 0; k < p->n_wr; k++) {
			if (p->wr[k].index == 0x607A) {
				i607a = k;
				assert_int_equal((int32_t)p->wr[k].value, p->pos);
			}
			if (p->wr[k].index == 0x6040 && p->wr[k].value == 0x000F) {
				ienable = k;
			}
		}
		assert_true(i607a >= 0 && ienable > i607a);
	}
	/* the fault was reset on a rising edge; the enabled drive disabled first */
	assert_true(writes_of(&peers[1], 0x6040, 0, &v) >= 4);
	assert_non_null(
	    strstr(logbuf, "node 2 (axis Y): fault reset (0x0080): switch on disabled"));
	assert_non_null(strstr(logbuf, "node 3 (axis Z): disable operation (0x0007): switched on"));
	assert_non_null(strstr(logbuf, "node 1 (axis X): operation enabled at 1.2340 mm"));
}

/* [SPINDLE] TYPE = cia402: the spindle's drive is brought up with the axes
 * in profile velocity mode (its own set-up list, read back), enabled with
 * target velocity 0; a spindle node that does not answer is named. */
static void test_bringup_spindle(void **state)
{
	double start[NP];
	struct peer *sp = &peers[NP];
	static const uint16_t extra[] = {0x60FF, 0x606C, 0x6083, 0x6084};
	(void)state;
	cfg.io.spindle = MLIP_IO_CIA402;
	cfg.io.max_rpm = cfg.spindle.max_rpm = 12000;
	cfg.spindle.node = 5;
	cfg.spindle.counts_per_rev = 4096;
	cfg.spindle.accel_rpm_s = 10000;
	cfg.spindle.band_rpm = 240;
	cfg.spindle.timeout_s = 3.4;
	cfg.spindle.band_time_s = 0.2;
	peer_init(sp, 5, P_FAULT, 0);
	for (size_t k = 0; k < sizeof(extra) / sizeof(extra[0]); k++) {
		od_add(sp, extra[k], 0, 4, 77);
	}
	int rc = bringup(start);
	if (rc != 0) {
		print_error("%s\n%s", why, logbuf);
	}
	assert_int_equal(rc, 0);
	assert_int_equal(ds.sp, 1);
	assert_int_equal(sp->state, P_OE);
	assert_int_equal(sp->nmt, MLIP_NMT_OPERATIONAL);
	assert_int_equal(od_find(sp, 0x6060, 0)->value, 3);
	assert_int_equal(od_find(sp, 0x1600, 2)->value, 0x60FF0020u);
	assert_int_equal(od_find(sp, 0x1A00, 2)->value, 0x606C0020u);
	assert_int_equal(od_find(sp, 0x60FF, 0)->value, 0);
	assert_int_equal(od_find(sp, 0x6083, 0)->value, 682667); /* 10000 rpm/s x 4096 / 60 */
	assert_int_equal(od_find(sp, 0x6084, 0)->value, 682667);
	assert_int_equal(od_find(sp, 0x6065, 0)->value, 0); /* no following error window */
	assert_int_equal(od_find(sp, 0x607A, 0)->value, 0); /* no target position */
	assert_non_null(strstr(logbuf, "node 5 (spindle): CiA 402 drive"));
	assert_non_null(strstr(logbuf, "node 5 (spindle): fault reset (0x0080)"));
	assert_non_null(strstr(logbuf, "node 5 (spindle): operation enabled, target velocity 0"));
	for (int i = 0; i < NP; i++) {
		assert_int_equal(peers[i].state, P_OE);
	}
	uint32_t ids[MLIP_CANBUS_MAX_IDS];
	int n = mlip_drives_rx_ids(&cfg.machine, 0, 5, 0, 0, ids, MLIP_CANBUS_MAX_IDS);
	assert_int_equal(n, 16);
	assert_int_equal(ids[12], 0x585u);
	assert_int_equal(ids[15], 0x185u);
	/* the touch probe: each axis drive's TPDO2 too (not the spindle's) */
	n = mlip_drives_rx_ids(&cfg.machine, 0, 5, 1, 0, ids, MLIP_CANBUS_MAX_IDS);
	assert_int_equal(n, 16 + cfg.machine.n_axes);
	assert_int_equal(ids[4], 0x281u);
	assert_int_equal(ids[15], 0x585u);
	/* and switches on X's and Z's drives: their TPDO3 besides TPDO2 */
	n = mlip_drives_rx_ids(&cfg.machine, 0, 5, 1, 5u, ids, MLIP_CANBUS_MAX_IDS);
	assert_int_equal(n, 16 + cfg.machine.n_axes + 2);
	assert_int_equal(ids[4], 0x281u);
	assert_int_equal(ids[5], 0x381u);
	assert_int_equal(ids[10], 0x282u);
	assert_int_equal(ids[15], 0x283u);
	assert_int_equal(ids[16], 0x383u);
	/* the filter's size: every axis with both, the I/O module, the spindle */
	struct mlip_machine big = cfg.machine;
	uint32_t many[MLIP_CANBUS_MAX_IDS + 1];
	big.n_axes = MLIP_MAX_AXES;
	for (int k = 0; k < MLIP_MAX_AXES; k++) {
		big.axis[k].can_node = (uint8_t)(20 + k);
	}
	n = mlip_drives_rx_ids(&big, 10, 5, 1, (1u << MLIP_MAX_AXES) - 1u, many,
	                       MLIP_CANBUS_MAX_IDS + 1);
	assert_int_equal(n, MLIP_CANBUS_MAX_IDS);
	/* the shut-down takes the spindle down first */
	mlip_drives_disable(&ds);
	assert_int_equal(sp->state, P_RTSO);
	/* absent: named as the spindle */
	setup(state);
	cfg.io.spindle = MLIP_IO_CIA402;
	cfg.io.max_rpm = cfg.spindle.max_rpm = 12000;
	cfg.spindle.node = 5;
	cfg.spindle.counts_per_rev = 4096;
	cfg.spindle.accel_rpm_s = 10000;
	assert_int_equal(bringup(start), -ETIMEDOUT);
	assert_non_null(strstr(why, "node 5 (spindle): no boot-up"));
	cfg.io.spindle = MLIP_IO_NONE;
}

static void assert_nothing_enabled(void)
{
	for (int i = 0; i < NP; i++) {
		assert_true(!peers[i].present || peers[i].state != P_OE);
	}
}

static void test_refused_sdo(void **state)
{
	double start[NP];
	(void)state;
	peers[1].refuse_index = 0x6060;
	peers[1].refuse_code = 0x06090030u;
	assert_int_equal(bringup(start), -EPROTO);
	assert_string_equal(why, "node 2 (axis Y): SDO abort 0x06090030 writing 0x6060:00 (invalid "
	                         "value for parameter (download only)) - modes of operation (8: "
	                         "cyclic synchronous position)");
	assert_nothing_enabled();
	for (int i = 0; i < NP; i++) {
		assert_int_equal(peers[i].ever_enabled, 0);
	}
}

static void test_missing_drive(void **state)
{
	double start[NP];
	uint32_t v;
	(void)state;
	peers[2].present = 0;
	uint64_t t0 = now_ns;
	assert_int_equal(bringup(start), -ETIMEDOUT);
	assert_non_null(strstr(why, "node 3 (axis Z): no boot-up after NMT reset communication "
	                            "within 3000 ms"));
	/* waited the whole boot timeout, and not much more (virtual clock) */
	assert_true(now_ns - t0 >= 3000000000u && now_ns - t0 < 3100000000u);
	assert_nothing_enabled();
	for (int i = 0; i < 2; i++) {
		assert_int_equal(peers[i].ever_enabled, 0);
		assert_int_equal(writes_of(&peers[i], 0x6040, 0, &v), 0);
	}
}

static void test_never_enabled(void **state)
{
	double start[NP];
	(void)state;
	peers[2].no_enable = 1;
	assert_int_equal(bringup(start), -ETIMEDOUT);
	assert_non_null(strstr(why, "node 3 (axis Z): still \"switched on\" (statusword 0x0233) "
	                            "1000 ms after enable operation (controlword 0x000F)"));
	/* the two that were enabled are shut down again */
	assert_nothing_enabled();
	assert_int_equal(peers[0].state, P_RTSO);
	assert_int_equal(peers[1].state, P_RTSO);
}

static void test_beyond_limit(void **state)
{
	double start[NP];
	(void)state;
	peers[1].pos = 1000001; /* 1000.001 mm, MAX_LIMIT 1000 */
	assert_int_equal(bringup(start), -ERANGE);
	assert_string_equal(why, "node 2 (axis Y) is at 1000.0010 mm (1000001 counts), beyond its "
	                         "soft limit MAX_LIMIT 1000: bring it back within -1000..1000 by "
	                         "hand before starting");
	for (int i = 0; i < NP; i++) {
		assert_int_equal(peers[i].ever_enabled, 0);
	}
	/* at the limit itself it starts */
	setup(NULL);
	peers[1].pos = 1000000;
	assert_int_equal(bringup(start), 0);
	assert_true(start[1] == 1000.0);
}

/* ---- the loop ------------------------------------------------------------------------ */

#define CAP 64u
static struct mlip_planner planner;
static struct mlip_period ctl; /* the period, with the master as its hooks */
static void *mem;
static uint64_t cycle;
static double home[NP]; /* where the bring-up found the drives */

static void loop_setup(double *start)
{
	struct mlip_ring *ring;
	assert_int_equal(bringup(start), 0);
	size_t bytes = mlip_ring_bytes(CAP);
	assert_int_equal(posix_memalign(&mem, MLIP_RING_LINE, bytes), 0);
	assert_int_equal(mlip_ring_format_machine(mem, bytes, CAP, &cfg.machine), MLIP_OK);
	assert_int_equal(mlip_ring_attach(mem, bytes, NP, &ring, NULL), MLIP_OK);
	/* as mlip-rt does: the drives' positions actual are the machine's HOME */
	struct mlip_machine m = cfg.machine;
	for (int k = 0; k < NP; k++) {
		m.axis[k].home = home[k] = start[k];
	}
	struct mlip_ctl_opts o = {.strategy = MLIP_STRATEGY_MPCT,
	                          .lookahead = 16,
	                          .can = &cfg.can,
	                          .drives = 1,
	                          .drive_state_periods = 1000,
	                          .io = &cfg.inputs};
	struct mlip_period_hooks hooks;
	mlip_drives_hooks(&ds, &hooks);
	assert_int_equal(mlip_period_init(&ctl, &planner, &m, &o, ring, &port, &hooks), 0);
	cycle = 0;
}

/* One period: the drives take the RPDO's controlword of the period before
 * (a drive applies it at the SYNC) and answer the SYNC with their TPDO;
 * heartbeats every 100 ms unless silenced. */
static uint32_t silent;
static int32_t offset[NP];

/* The RPDO the controller's last period sent to drive i (6 bytes:
 * controlword, target): 1, or 0 when it sent none (muted). */
static int rpdo_of(int i, uint16_t *cw, int32_t *target)
{
	for (int k = 0; k < ctl.out.n_frames; k++) {
		const struct mlip_can_frame *f = &ctl.out.frames[k];
		if (f->id == 0x200u + peers[i].node) {
			assert_int_equal(f->len, 6);
			*cw = (uint16_t)(f->data[0] | f->data[1] << 8);
			*target =
			    (int32_t)((uint32_t)f->data[2] | (uint32_t)f->data[3] << 8 |
			              (uint32_t)f->data[4] << 16 | (uint32_t)f->data[5] << 24);
			return 1;
		}
	}
	return 0;
}

/* The controlword the last period sent to drive 0. */
static uint16_t cw0(void)
{
	uint16_t cw = 0;
	int32_t t;
	assert_int_equal(rpdo_of(0, &cw, &t), 1);
	return cw;
}

static int period(void)
{
	struct mlip_can_frame f;
	for (int i = 0; i < NP; i++) {
		struct peer *p = &peers[i];
		uint16_t cw;
		int32_t c;
		if (p->state == P_QS && p->qs_left > 0) {
			p->pos += 1000; /* still braking */
			if (--p->qs_left <= 0 && !qs_holds(p)) {
				p->state = P_SOD;
			}
		}
		if (cycle > 0 && !ctl.unsent && rpdo_of(i, &cw, &c)) {
			peer_cw(p, cw);
			if (p->state == P_OE) { /* a disabled drive follows no target */
				p->pos = c + offset[i];
			}
		}
		mlip_co_pdo_encode(0x180u + p->node, p_sw[p->state], p->pos, &f);
		push(&f);
		if (cycle % 100 == 0 && !(silent & (1u << i))) {
			peer_hb(p);
		}
		if (cycle % 100 == 0 && (di_send & (1u << i))) {
			memset(&f, 0, sizeof(f));
			f.id = 0x380u + p->node;
			f.len = 4;
			memcpy(f.data, &di_val[i], 4); /* little-endian host, as CANopen */
			push(&f);
		}
	}
	if (peers[NP].present && peers[NP].node == 10 && cycle % 100 == 0) {
		peer_hb(&peers[NP]); /* the I/O module's heartbeat */
	}
	struct mlip_rt_tick t = {.cycle = cycle++};
	now_ns += 1000000;
	int r = mlip_period_tick(&ctl, &t);
	if (!keep_queue) {
		q_head = q_tail; /* what the master did not read is gone */
	}
	return r;
}

static void test_loop_shutdown(void **state)
{
	double start[NP];
	uint16_t seen[4] = {0};
	int ns = 0;
	(void)state;
	loop_setup(start);
	for (int k = 0; k < 200; k++) {
		assert_int_equal(period(), 0);
		assert_int_equal(cw0(), 0x000F);
	}
	assert_int_equal(__atomic_load_n(&ds.fault, __ATOMIC_ACQUIRE), 0);
	ctl.exit_request = 1;
	int k;
	for (k = 0; k < 3000 && period() == 0; k++) {
		if (ns == 0 || seen[ns - 1] != cw0()) {
			assert_true(ns < 4);
			seen[ns++] = cw0();
		}
	}
	assert_true(k < 3000);
	/* from the exit's period (at rest) disable operation, then shutdown */
	assert_int_equal(ns, 2);
	assert_int_equal(seen[0], 0x0007);
	assert_int_equal(seen[1], 0x0006);
	assert_int_equal(ds.shutdown_ok, 1);
	for (int i = 0; i < NP; i++) {
		assert_int_equal(peers[i].state, P_RTSO);
	}
	free(mem);
}

static void test_loop_fault_bit(void **state)
{
	double start[NP];
	(void)state;
	loop_setup(start);
	for (int k = 0; k < 50; k++) {
		period();
	}
	peers[1].state = P_FAULT; /* the drive faults between two SYNCs */
	period();
	assert_int_equal(__atomic_load_n(&ds.fault, __ATOMIC_ACQUIRE), 1);
	assert_int_equal(ds.fault_drive, 1);
	assert_int_equal(ds.fault_reason, MLIP_DRIVE_FAULT_BIT);
	assert_int_equal(ds.fault_detail, 0x0218);
	assert_int_equal(ds.fault_cycle, 51);
	/* an input of the controller: state fault, reason drive, node, event, value */
	assert_int_equal(ctl.out.status.state, MLIP_STATE_FAULT);
	assert_int_equal(ctl.out.status.reason, MLIP_WHY_DRIVE);
	assert_int_equal(ctl.out.status.reason_node, peers[1].node);
	assert_int_equal(ctl.out.status.reason_field, MLIP_DRIVE_FAULT_BIT);
	assert_true(ctl.out.status.reason_value == 0x0218);
	/* no more targets for it; the others keep theirs */
	uint16_t cw;
	int32_t t;
	assert_int_equal(rpdo_of(1, &cw, &t), 0);
	assert_int_equal(rpdo_of(0, &cw, &t), 1);
	assert_int_equal(rpdo_of(2, &cw, &t), 1);
	/* and the shut-down still ends, without waiting for the faulted drive */
	ctl.exit_request = 1;
	int k;
	for (k = 0; k < 3000 && period() == 0; k++) {
	}
	assert_true(k < 3000);
	assert_int_equal(peers[0].state, P_RTSO);
	assert_int_equal(peers[1].state, P_FAULT);
	free(mem);
}

static void test_loop_following_error(void **state)
{
	double start[NP];
	(void)state;
	loop_setup(start);
	for (int k = 0; k < 20; k++) {
		period();
	}
	offset[2] = 1000; /* at the window: fine */
	for (int k = 0; k < 20; k++) {
		period();
	}
	assert_int_equal(__atomic_load_n(&ds.fault, __ATOMIC_ACQUIRE), 0);
	offset[2] = -1001; /* one count beyond: found in the period it is reported */
	period();
	offset[2] = 0;
	assert_int_equal(__atomic_load_n(&ds.fault, __ATOMIC_ACQUIRE), 1);
	assert_int_equal(ds.fault_drive, 2);
	assert_int_equal(ds.fault_reason, MLIP_DRIVE_FOLLOWING_ERROR);
	assert_int_equal(ds.fault_detail, 1001);
	assert_int_equal(ds.fault_cycle, 41);
	free(mem);
}

static void test_loop_heartbeat_and_emcy(void **state)
{
	double start[NP];
	(void)state;
	loop_setup(start);
	silent = 1u; /* node 1 stops its heartbeat from period 1 on */
	uint64_t last_hb = now_ns;
	int k;
	for (k = 0; k < 1000 && !__atomic_load_n(&ds.fault, __ATOMIC_ACQUIRE); k++) {
		period();
	}
	silent = 0;
	assert_int_equal(ds.fault_reason, MLIP_DRIVE_HEARTBEAT_LOST);
	assert_int_equal(ds.fault_drive, 0);
	/* lost after the 300 ms consumer time, within a period of it (virtual clock) */
	assert_true(now_ns - last_hb > 300000000u && now_ns - last_hb <= 302000000u);
	free(mem);

	setup(NULL);
	loop_setup(start);
	period();
	struct mlip_can_frame f;
	memset(&f, 0, sizeof(f));
	f.id = 0x083;
	f.len = 8;
	f.data[0] = 0x10; /* 0x2310: current */
	f.data[1] = 0x23;
	f.data[2] = 0x03;
	push(&f);
	period();
	assert_int_equal(ds.fault_reason, MLIP_DRIVE_EMCY);
	assert_int_equal(ds.fault_drive, 2);
	assert_int_equal(ds.fault_detail, 0x2310);
	free(mem);
}

/* A drive that answers every SYNC 20 periods late (as the canopen drives do
 * in the emulated VM) while the machine moves, its position two periods
 * behind the target (as they follow): its TPDOs are judged against the
 * targets sent before the SYNC they answer, so no false following error;
 * the same drive falling 1001 counts beyond is caught at once. */
static int32_t sent[NP][2048];

/* 40 mm along X at 100 mm/s from start, four blocks (records 1-4). */
static void line_x(const double *start)
{
	for (uint64_t k = 1; k <= 4; k++) {
		struct mlip_block b = {.feed_mm_s = 100.0, .tol_mm = 0.01, .line = (uint32_t)k};
		memcpy(b.target, start, sizeof(double) * NP);
		b.target[0] = start[0] + 10.0 * (double)k;
		struct mlip_ring_rec rec;
		mlip_ring_rec_from_block(&rec, &b, k);
		assert_int_equal(mlip_ring_push(ctl.ring, &rec), MLIP_OK);
	}
}

static void period_late(int delay, int32_t behind_x)
{
	uint64_t c = cycle + 1;
	struct mlip_can_frame f;
	for (int i = 0; i < NP; i++) {
		struct peer *p = &peers[i];
		if (c > (uint64_t)delay) {
			uint64_t sy = c - (uint64_t)delay; /* the SYNC answered now */
			int32_t actual = sy > 2 ? sent[i][sy - 2] : p->pos;
			mlip_co_pdo_encode(0x180u + p->node, p_sw[p->state],
			                   actual - (i == 0 ? behind_x : 0), &f);
			push(&f);
		}
		if (cycle % 100 == 0) {
			peer_hb(p);
		}
	}
	struct mlip_rt_tick t = {.cycle = cycle++};
	now_ns += 1000000;
	mlip_period_tick(&ctl, &t);
	q_head = q_tail;
	for (int i = 0; i < NP; i++) {
		mlip_can_counts(ctl.out.pos[i], 1000.0, &sent[i][c]);
	}
}

static void test_loop_late_drive(void **state)
{
	double start[NP];
	(void)state;
	loop_setup(start);
	line_x(start); /* from where X is */
	int k;
	for (k = 0; k < 1000; k++) {
		period_late(20, 0);
	}
	/* it moved at full speed (100 counts a period) and ended there */
	assert_true(sent[0][1000] - sent[0][1] == 40000);
	assert_int_equal(__atomic_load_n(&ds.fault, __ATOMIC_ACQUIRE), 0);
	free(mem);

	/* again, X falling behind from period 300 (moving at 100 counts a period):
	 * 1001 counts beyond the target MLIP_DRIVE_LAG periods before the SYNC */
	setup(NULL);
	loop_setup(start);
	line_x(start);
	for (k = 0; k < 300; k++) {
		period_late(20, 0);
	}
	assert_int_equal(__atomic_load_n(&ds.fault, __ATOMIC_ACQUIRE), 0);
	for (k = 0; k < 100 && !__atomic_load_n(&ds.fault, __ATOMIC_ACQUIRE); k++) {
		period_late(20, 1001 + (MLIP_DRIVE_LAG - 2) * 100);
	}
	assert_int_equal(ds.fault_reason, MLIP_DRIVE_FOLLOWING_ERROR);
	assert_int_equal(ds.fault_drive, 0);
	assert_int_equal(ds.fault_detail, 1001);
	assert_int_equal(k, 1); /* the first late TPDO showing it */
	free(mem);
}

/* ---- between programs ------------------------------------------------------------ */

/* A program of n moves along X from where it is, 5 mm each at 100 mm/s,
 * and its END (records seq 1..n+1). */
static void program(int n, double dir)
{
	double at[NP];
	for (int k = 0; k < NP; k++) {
		at[k] = ctl.cycles > 0 ? ctl.out.pos[k] : home[k]; /* the last setpoint sent */
	}
	for (int i = 1; i <= n + 1; i++) {
		struct mlip_ring_rec rec;
		struct mlip_block b = {.feed_mm_s = 100.0, .tol_mm = 0.01, .line = (uint32_t)i};
		memcpy(b.target, at, sizeof(at));
		b.target[0] = at[0] + dir * 5.0 * i;
		mlip_ring_rec_from_block(&rec, &b, (uint64_t)i);
		if (i == n + 1) {
			memset(&rec, 0, sizeof(rec));
			rec.seq = (uint64_t)i;
			rec.type = MLIP_REC_END;
		}
		assert_int_equal(mlip_ring_push(ctl.ring, &rec), MLIP_OK);
	}
}

/* What the RPDOs of one drive did over a run of periods. */
struct run {
	int periods;
	int first_cw_period[16]; /* period of each change of controlword, in order */
	uint16_t cws[16];
	int n_cw;
	int last_move;               /* last period the target changed (-1: never) */
	int32_t first_target_of[16]; /* the target sent with each controlword's first RPDO */
};

/* Up to max periods (until the drives' power is `until` for the first time
 * after at least one other), recording drive i's RPDOs. */
static void run_until(int i, uint32_t until, int max, struct run *r)
{
	int32_t last = 0;
	memset(r, 0, sizeof(*r));
	r->last_move = -1;
	for (int k = 0; k < max; k++) {
		uint16_t cw = 0;
		int32_t t = 0;
		assert_int_equal(period(), 0);
		r->periods = k + 1;
		assert_int_equal(rpdo_of(i, &cw, &t), 1);
		if (k > 0 && t != last) {
			r->last_move = k;
		}
		last = t;
		if (r->n_cw == 0 || r->cws[r->n_cw - 1] != cw) {
			assert_true(r->n_cw < 16);
			r->first_cw_period[r->n_cw] = k;
			r->first_target_of[r->n_cw] = t;
			r->cws[r->n_cw++] = cw;
		}
		if (ctl.out.status.drive_power == until && k > 0) {
			return;
		}
	}
	fail_msg("drives' power %s not reached in %d periods (now %s)",
	         mlip_drive_power_name(until), max,
	         mlip_drive_power_name(ctl.out.status.drive_power));
}

/* Two programs on one controller: after the first, at rest, disable
 * operation then shutdown (each confirmed by the TPDOs); a disabled drive
 * is moved by hand and the commanded position follows it; the second
 * program enables them again (switch on, enable operation) with the target
 * equal to the moved position to the count, and starts there. */
static void test_loop_between_programs(void **state)
{
	double start[NP];
	struct run r;
	(void)state;
	loop_setup(start);
	program(2, 1.0);
	run_until(0, MLIP_POWER_OFF, 3000, &r);
	/* moved, came to rest, then 0x07, then 0x06: never disabled while moving */
	assert_int_equal(r.n_cw, 3);
	assert_int_equal(r.cws[0], 0x000F);
	assert_int_equal(r.cws[1], 0x0007);
	assert_int_equal(r.cws[2], 0x0006);
	assert_true(r.last_move > 0 && r.last_move < r.first_cw_period[1]);
	assert_int_equal(ctl.out.status.state, MLIP_STATE_IDLE);
	assert_int_equal(ctl.out.status.reason, MLIP_WHY_END);
	for (int i = 0; i < NP; i++) {
		assert_int_equal(peers[i].state, P_RTSO);
	}
	assert_true(peers[0].pos == 1234 + 10000);
	/* each step confirmed by the next TPDO (the peer answers at once): a
	 * period for disable operation, one for shutdown */
	assert_int_equal(ctl.out.status.drive_power_periods, 2);
	assert_int_equal(ds.shutdown_ok, 0); /* not the loop's end yet */
	assert_int_equal(ctl.out.power.ok, 1);

	/* disabled: Y is pushed by hand 0.777 mm; the commanded position follows */
	peers[1].pos += 777;
	for (int k = 0; k < 10; k++) {
		period();
	}
	uint16_t cw;
	int32_t t;
	assert_int_equal(rpdo_of(1, &cw, &t), 1);
	assert_int_equal(cw, 0x0006);
	assert_int_equal(t, -500 + 777);
	assert_true(ctl.out.status.pos[1] * 1000.0 == -500.0 + 777.0);
	assert_int_equal(ctl.out.status.drive_power, MLIP_POWER_OFF);

	/* the next program: switch on, enable operation, then it moves from there */
	program(2, -1.0);
	struct run y;
	run_until(1, MLIP_POWER_ENABLED, 3000, &y);
	/* switch on from the period the records came, then enable operation */
	assert_int_equal(y.n_cw, 2);
	assert_int_equal(y.cws[0], 0x0007);
	assert_int_equal(y.cws[1], 0x000F);
	assert_int_equal(y.first_target_of[0], -500 + 777);
	assert_int_equal(y.first_target_of[1], -500 + 777); /* to the count */
	assert_int_equal(y.last_move, -1);                  /* nothing moved meanwhile */
	assert_int_equal(ctl.out.status.drive_power_periods, 2);
	for (int i = 0; i < NP; i++) {
		assert_int_equal(peers[i].state, P_OE);
	}
	/* X moves back; Y and Z, not programmed to move, stay put */
	for (int k = 0; k < 3000 && ctl.out.status.drive_power == MLIP_POWER_ENABLED; k++) {
		period();
		assert_int_equal(rpdo_of(1, &cw, &t), 1);
		assert_int_equal(t, -500 + 777);
		assert_int_equal(rpdo_of(2, &cw, &t), 1);
		assert_int_equal(t, 0);
	}
	run_until(0, MLIP_POWER_OFF, 3000, &r);
	assert_true(peers[0].pos == 1234);       /* X went back */
	assert_true(peers[1].pos == -500 + 777); /* Y stayed where it was pushed */
	assert_int_equal(__atomic_load_n(&ds.fault, __ATOMIC_ACQUIRE), 0);
	/* and the exit ends at once: already disabled in order */
	ctl.exit_request = 1;
	assert_int_equal(period(), 1);
	assert_int_equal(ds.shutdown_ok, 1);
	free(mem);
}

/* A stop mid-program: on the path to rest with the drives enabled, then
 * disabled in order. */
static void test_loop_stop_disables(void **state)
{
	double start[NP];
	struct run r;
	(void)state;
	loop_setup(start);
	program(20, 1.0);
	for (int k = 0; k < 200; k++) {
		period();
	}
	assert_int_equal(ctl.out.status.state, MLIP_STATE_RUNNING);
	mlip_ring_stop_post(ctl.ring);
	run_until(0, MLIP_POWER_OFF, 3000, &r);
	assert_int_equal(r.n_cw, 3);
	assert_true(r.last_move > 10 && r.last_move < r.first_cw_period[1]);
	assert_int_equal(ctl.out.status.reason, MLIP_WHY_STOP);
	for (int i = 0; i < NP; i++) {
		assert_int_equal(peers[i].state, P_RTSO);
	}
	free(mem);
}

/* The second program's enable fails (a drive stays "switched on"): a fault
 * naming the node and the step after STATE_TIMEOUT_MS, nothing moved, the
 * drives shut down again, the program dropped. */
static void test_loop_enable_fails(void **state)
{
	double start[NP];
	struct run r;
	(void)state;
	loop_setup(start);
	program(1, 1.0);
	run_until(0, MLIP_POWER_OFF, 3000, &r);
	int32_t at[NP];
	for (int i = 0; i < NP; i++) {
		at[i] = peers[i].pos;
	}
	peers[2].no_enable = 1;
	program(3, -1.0);
	run_until(0, MLIP_POWER_ENABLING, 100, &r);
	int k0 = r.periods;
	run_until(0, MLIP_POWER_OFF, 3000, &r);
	/* 0x0F for the state timeout (1000 periods), then 0x07, 0x06 */
	assert_int_equal(r.n_cw, 3);
	assert_int_equal(r.cws[0], 0x000F);
	assert_true(r.first_cw_period[1] >= 999 && r.first_cw_period[1] <= 1001);
	assert_int_equal(r.last_move, -1);
	(void)k0;
	const struct mlip_ring_status *s = &ctl.out.status;
	assert_int_equal(s->state, MLIP_STATE_FAULT);
	assert_int_equal(s->reason, MLIP_WHY_DRIVE);
	assert_int_equal(s->reason_node, 3);
	assert_int_equal(s->reason_field, MLIP_DRIVE_NOT_ENABLED);
	assert_true(s->reason_value == 0x0233); /* "switched on" */
	for (int i = 0; i < NP; i++) {
		assert_int_equal(peers[i].pos, at[i]); /* nothing moved */
		assert_int_equal(peers[i].state, P_RTSO);
	}
	/* the program is dropped, never run */
	for (int k = 0; k < 200; k++) {
		period();
	}
	assert_int_equal(mlip_ring_count(ctl.ring), 0);
	assert_int_equal(s->state, MLIP_STATE_FAULT);
	for (int i = 0; i < NP; i++) {
		assert_int_equal(peers[i].pos, at[i]);
	}
	free(mem);
}

/* Switches on the drives (issue 18): X's positive limit on drive 1's 0x60FD
 * bit 1, Y's negative on drive 2's bit 0, no I/O module. At bring-up TPDO3
 * is mapped (each write read back) and 0x60FD read once by SDO; in the loop
 * a TPDO3 sets the input in the period it is read; a garbled one (3 bytes)
 * is counted and changes nothing; a drive whose TPDO3 stops is a fault
 * after the heartbeat timeout, its inputs unknown. */
static void test_loop_drive_inputs(void **state)
{
	double start[NP];
	(void)state;
	cfg.inputs.in[MLIP_IN_LIMIT_POS(0)] = (struct mlip_io_bit){1, 0, 0x60FD, 1, 0, 10};
	cfg.inputs.in[MLIP_IN_LIMIT_NEG(1)] = (struct mlip_io_bit){2, 0, 0x60FD, 0, 0, 11};
	cfg.inputs.mapped = 1u << MLIP_IN_LIMIT_POS(0) | 1u << MLIP_IN_LIMIT_NEG(1);
	for (int i = 0; i < 2; i++) {
		static const struct {
			uint16_t i;
			uint8_t s, n;
		} objs[] = {{0x1802, 1, 4}, {0x1802, 2, 1}, {0x1802, 5, 2},
		            {0x1A02, 0, 1}, {0x1A02, 1, 4}, {0x60FD, 0, 4}};
		for (size_t k = 0; k < sizeof(objs) / sizeof(objs[0]); k++) {
			od_add(&peers[i], objs[k].i, objs[k].s, objs[k].n, 0);
		}
	}
	od_find(&peers[1], 0x60FD, 0)->value = 0x00010001u; /* Y- on at power-up, a mfr bit */
	assert_int_equal(mlip_drives_di_axes(&cfg), 3u);
	loop_setup(start);
	for (int i = 0; i < 2; i++) {
		struct peer *p = &peers[i];
		assert_int_equal(od_find(p, 0x1802, 1)->value, 0x40000380u + p->node);
		assert_int_equal(od_find(p, 0x1802, 2)->value, 255);
		assert_int_equal(od_find(p, 0x1802, 5)->value, 100);
		assert_int_equal(od_find(p, 0x1A02, 0)->value, 1);
		assert_int_equal(od_find(p, 0x1A02, 1)->value, 0x60FD0020u);
	}
	uint32_t v = 0;
	assert_int_equal(writes_of(&peers[2], 0x1802, 1, &v), 0); /* Z: no switches on it */
	assert_non_null(strstr(logbuf, "node 2 (axis Y): digital inputs 0x60FD = 0x00010001"));
	uint32_t ids[MLIP_CANBUS_MAX_IDS];
	int n = mlip_drives_rx_ids(&cfg.machine, 0, 0, 0, 3u, ids, MLIP_CANBUS_MAX_IDS);
	assert_int_equal(n, 14);
	assert_int_equal(ids[4], 0x381u);
	assert_int_equal(ids[9], 0x382u);
	di_send = 3u;
	di_val[1] = 0x00010001u;
	period();
	const struct mlip_ring_status *st = &ctl.out.status;
	uint32_t xpos = 1u << MLIP_IN_LIMIT_POS(0), yneg = 1u << MLIP_IN_LIMIT_NEG(1);
	assert_int_equal(st->io_known, xpos | yneg);
	assert_int_equal(st->io_inputs, yneg); /* from the SDO read: at rest, no stop */
	for (int k = 0; k < 150; k++) {
		period();
	}
	di_val[1] = 0;
	di_val[0] = 0x2u;
	/* a TPDO3 read in this period: its input in this period's status */
	struct mlip_can_frame f;
	memset(&f, 0, sizeof(f));
	f.id = 0x381;
	f.len = 4;
	f.data[0] = 0x2;
	push(&f);
	period();
	assert_int_equal(st->io_inputs & xpos, xpos);
	uint64_t bad = ds.rx_malformed;
	f.len = 3;
	f.data[0] = 0x0; /* garbled: would release it */
	push(&f);
	period();
	assert_int_equal(ds.rx_malformed, bad + 1);
	assert_int_equal(st->io_inputs & xpos, xpos);
	assert_int_equal(__atomic_load_n(&ds.fault, __ATOMIC_ACQUIRE), 0);
	/* Y's drive stops sending its inputs */
	di_send = 1u;
	uint64_t last = ds.d[1].obs.di_ns;
	int k;
	for (k = 0; k < 1000 && !__atomic_load_n(&ds.fault, __ATOMIC_ACQUIRE); k++) {
		period();
	}
	assert_int_equal(ds.fault_reason, MLIP_DRIVE_INPUTS_LOST);
	assert_int_equal(ds.fault_drive, 1);
	assert_true(now_ns - last > 300000000u && now_ns - last <= 302000000u);
	assert_int_equal(st->state, MLIP_STATE_FAULT);
	assert_int_equal(st->reason, MLIP_WHY_DRIVE);
	assert_int_equal(st->reason_node, 2);
	assert_int_equal(st->reason_field, MLIP_DRIVE_INPUTS_LOST);
	assert_int_equal(st->io_known, xpos); /* Y's limit: unknown now */
	/* it still gets targets (the stop on the path): not muted */
	uint16_t cw;
	int32_t t;
	assert_int_equal(rpdo_of(1, &cw, &t), 1);
	free(mem);
}

/* A CiA 401 module as node 10 in peers[NP]: inputs byte 1 (bit 0: the
 * E-stop circuit, closed), outputs byte 1, its default PDOs. */
static void module_init(struct peer *p, int with_defaults)
{
	static const struct {
		uint16_t i;
		uint8_t s, n;
		uint32_t v;
	} objs[] = {
	    {0x1000, 0, 4, 0x00030191u}, {0x1400, 1, 4, 0x20Au},      {0x1400, 2, 1, 255},
	    {0x1600, 0, 1, 1},           {0x1600, 1, 4, 0x62000108u}, {0x1800, 1, 4, 0x18Au},
	    {0x1800, 2, 1, 255},         {0x1A00, 0, 1, 1},           {0x1A00, 1, 4, 0x60000108u},
	    {0x1017, 0, 2, 0},           {0x1016, 1, 4, 0},           {0x6000, 1, 1, 1},
	    {0x1018, 1, 4, 0x0000ABCDu}, {0x1018, 2, 4, 0x00000401u}, {0x1001, 0, 1, 0}};
	if (with_defaults) {
		memset(p, 0, sizeof(*p));
		p->node = 10;
		p->present = 1;
		p->nmt = MLIP_NMT_PREOPERATIONAL;
		for (size_t k = 0; k < sizeof(objs) / sizeof(objs[0]); k++) {
			od_add(p, objs[k].i, objs[k].s, objs[k].n, objs[k].v);
		}
		return;
	}
	for (size_t k = 0; k < sizeof(objs) / sizeof(objs[0]); k++) {
		od_find(p, objs[k].i, objs[k].s)->value = objs[k].v; /* power-up defaults */
	}
}

static int32_t post(mlip_ring_cmd_op op)
{
	uint32_t seq = 0;
	int32_t res = 0;
	assert_int_equal(mlip_ring_cmd_post(ctl.ring, op, 0, &seq), MLIP_OK);
	period();
	assert_int_equal(mlip_ring_cmd_result(ctl.ring, seq, &res), MLIP_OK);
	return res;
}

/* A stall inside a period's work, after its start (in the drives' hook,
 * before the controller) and before its send: 50 ms, beyond the stall's 3
 * periods. Its setpoints, one period's motion on, never go out; from the
 * next period on the RPDOs repeat the last target the bus carried, held
 * with reason stall, and the motion goes on from there on resume. */
static void (*drives_before)(void *ctx, uint64_t cycle, uint64_t now_ns, struct mlip_ctl_in *in);
static uint64_t stall_ns;

static void stalling_before(void *ctx, uint64_t c, uint64_t now, struct mlip_ctl_in *in)
{
	drives_before(ctx, c, now, in);
	now_ns += stall_ns;
	stall_ns = 0;
}

static void test_loop_stall_before_the_send(void **state)
{
	double start[NP];
	(void)state;
	loop_setup(start);
	drives_before = ctl.hooks.before;
	ctl.hooks.before = stalling_before;
	line_x(start);
	struct mlip_ring_rec end_rec = {.seq = 5, .type = MLIP_REC_END};
	assert_int_equal(mlip_ring_push(ctl.ring, &end_rec), MLIP_OK);
	for (int k = 0; k < 400; k++) {
		assert_int_equal(period(), 0);
	}
	assert_int_equal(ctl.out.status.state, MLIP_STATE_RUNNING);
	int32_t before = wire[0], y = wire[1];
	uint64_t n = n_wire;
	int32_t home0;
	mlip_can_counts(start[0], 1000.0, &home0);
	assert_true(before - home0 > 20000); /* on its way */
	stall_ns = 50000000u;
	period();
	assert_true(ctl.unsent && n_wire == n); /* nothing went out */
	int32_t computed;
	mlip_can_counts(ctl.out.pos[0], 1000.0, &computed);
	assert_true(computed - before >= 90 && computed - before <= 100); /* 90-100 mm/s on */
	for (int k = 0; k < 100; k++) {
		period();
		assert_int_equal(ctl.out.status.state, MLIP_STATE_HELD);
		assert_int_equal(ctl.out.status.reason, MLIP_WHY_STALL);
		assert_true(n_wire == n + NP * (uint64_t)(k + 1) && wire[0] == before &&
		            wire[1] == y);
	}
	if (__atomic_load_n(&ds.fault, __ATOMIC_ACQUIRE)) {
		fail_msg("drive fault %d on drive %d (%d): %s", (int)ds.fault_reason,
		         ds.fault_drive, (int)ds.fault_detail, why);
	}
	assert_int_equal(post(MLIP_CMD_RESUME), MLIP_OK);
	/* from rest: the first two targets within A T^2 = 1 count (and a count's rounding) */
	int32_t w1 = wire[0];
	period();
	int32_t w2 = wire[0];
	assert_true(w1 - before >= 0 && w1 - before <= 2 && w2 - 2 * w1 + before <= 2);
	for (int k = 0; k < 2000 && ctl.out.status.state != MLIP_STATE_IDLE; k++) {
		period();
	}
	assert_int_equal(ctl.out.status.state, MLIP_STATE_IDLE);
	int32_t end;
	mlip_can_counts(start[0] + 40.0, 1000.0, &end);
	assert_true(wire[0] == end && wire[1] == y);
	free(mem);
}

/* The loop with the I/O module as node 10 (E-stop input bit 0, output
 * bit 0), run `periods` periods: idle, the E-stop input read and released. */
static struct peer *module_loop(double *start, int periods)
{
	uint32_t estop = 1u << MLIP_IN_ESTOP;
	cfg.inputs.node = 10;
	cfg.inputs.in_bytes = 1;
	cfg.inputs.out_bytes = 1;
	cfg.inputs.in[MLIP_IN_ESTOP] = (struct mlip_io_bit){10, 1, 0x6000, 0, 1, 10};
	cfg.inputs.mapped = 1u << MLIP_IN_ESTOP;
	cfg.inputs.out[MLIP_OUT_DOUT0] = (struct mlip_io_out){1, 0, 11};
	cfg.inputs.out_mapped = 1u << MLIP_OUT_DOUT0;
	module_init(&peers[NP], 1);
	loop_setup(start);
	keep_queue = 1;
	for (int k = 0; k < periods; k++) {
		period();
	}
	assert_int_equal(ctl.out.status.state, MLIP_STATE_IDLE);
	assert_int_equal(ctl.out.status.io_known & estop, estop);
	assert_int_equal(ctl.out.status.io_inputs & estop, 0);
	return &peers[NP];
}

/* The I/O module reboots (its boot-up message, then pre-operational with
 * its default PDOs and no heartbeat consumer): an E-stop in that period,
 * its inputs no longer trusted (unknown), no RPDO sent to it; at its next
 * heartbeat mlip resets its communication, writes and reads back its
 * set-up again, reads its inputs and starts it; then its inputs are known
 * again, its outputs are sent (off) and mlip-ctl reset leaves the E-stop.
 * An SDO refused during the reconfiguration fails it; it is tried again at
 * the module's next heartbeat. */
static void test_loop_module_reboot(void **state)
{
	double start[NP];
	(void)state;
	struct peer *mod = module_loop(start, 120);
	const struct mlip_ring_status *st = &ctl.out.status;
	uint32_t estop = 1u << MLIP_IN_ESTOP;
	assert_true(n_module_out > 0);
	assert_int_equal(od_find(mod, 0x1016, 1)->value, (127u << 16) | 300u);
	/* it reboots: defaults, boot-up message, pre-operational */
	module_init(mod, 0);
	mod->nmt = MLIP_NMT_BOOTUP;
	peer_hb(mod);
	mod->nmt = MLIP_NMT_PREOPERATIONAL;
	period();
	assert_int_equal(st->state, MLIP_STATE_ESTOP);
	assert_int_equal(st->reason, MLIP_WHY_IO_LOST);
	assert_int_equal(st->reason_node, 10);
	assert_int_equal(st->reason_field, MLIP_DRIVE_NOT_OPERATIONAL);
	assert_int_equal(st->io_known & estop, 0); /* not trusted */
	int sent_before = n_module_out;
	assert_int_equal(post(MLIP_CMD_RESET), MLIP_E_RANGE);
	/* an SDO refused: the attempt fails, nothing is trusted */
	mod->refuse_index = 0x1A00;
	mod->refuse_code = 0x06010000u;
	int k;
	for (k = 0; k < 300 && ds.io.re.failed == 0; k++) {
		period();
	}
	assert_int_equal(ds.io.re.failed, 1);
	assert_int_equal(ds.io.re.fail_abort, 0x06010000u);
	assert_int_equal(ds.io.re.fail_index, 0x1A00);
	assert_int_equal(ds.io.lost, MLIP_DRIVE_NOT_OPERATIONAL);
	assert_int_equal(st->io_known & estop, 0);
	mod->refuse_index = 0;
	mod->refuse_code = 0;
	for (k = 0; k < 300 && ds.io.re.count == 0; k++) {
		period();
		if (ds.io.re.count == 0) {
			assert_int_equal(n_module_out, sent_before); /* none to it meanwhile */
			assert_int_equal(st->io_known & estop, 0);
		}
		assert_int_equal(st->state, MLIP_STATE_ESTOP);
	}
	assert_int_equal(ds.io.re.count, 1);
	/* configured again, as at bring-up: its PDO mapping and heartbeats */
	assert_int_equal(mod->nmt, MLIP_NMT_OPERATIONAL);
	assert_int_equal(od_find(mod, 0x1016, 1)->value, (127u << 16) | 300u);
	assert_int_equal(od_find(mod, 0x1017, 0)->value, 100);
	assert_int_equal(od_find(mod, 0x1800, 1)->value, 0x4000018Au);
	assert_int_equal(od_find(mod, 0x1A00, 1)->value, 0x60000108u);
	assert_int_equal(od_find(mod, 0x1600, 1)->value, 0x62000108u);
	period();
	assert_int_equal(st->io_known & estop, estop);
	assert_int_equal(st->io_inputs & estop, 0);
	/* its outputs at once, off */
	assert_true(n_module_out > sent_before);
	assert_int_equal(module_out.len, 1);
	assert_int_equal(module_out.data[0], 0);
	assert_int_equal(post(MLIP_CMD_RESET), MLIP_OK);
	assert_int_equal(st->state, MLIP_STATE_IDLE);
	free(mem);
}

/* The I/O module reboots as another device (swapped: another product code
 * in 0x1018:02, or another device type 0x1000): its identity is read after
 * the boot-up and compared with bring-up's; it is never configured (no SDO
 * write, no NMT start, no RPDO), its inputs never trusted, the E-stop stays
 * with the reason naming node and object, and mlip-ctl reset is refused. */
static void module_swapped(uint16_t index, uint8_t sub, uint32_t other)
{
	double start[NP];
	struct peer *mod = module_loop(start, 60);
	const struct mlip_ring_status *st = &ctl.out.status;
	uint32_t estop = 1u << MLIP_IN_ESTOP;
	assert_int_equal(ds.io.id.type, 0x00030191u);
	assert_int_equal(ds.io.id.vendor, 0xABCDu);
	assert_int_equal(ds.io.id.product, 0x401u);
	assert_int_equal(ds.io.id.has_product, 1);
	/* another module boots on its node */
	module_init(mod, 0);
	od_find(mod, index, sub)->value = other;
	mod->nmt = MLIP_NMT_BOOTUP;
	peer_hb(mod);
	mod->nmt = MLIP_NMT_PREOPERATIONAL;
	period();
	assert_int_equal(st->state, MLIP_STATE_ESTOP);
	int writes = mod->n_wr, out_before = n_module_out;
	for (int k = 0; k < 300 && !ds.io.re.wrong; k++) {
		period();
	}
	assert_int_equal(ds.io.re.wrong, 1);
	assert_int_equal(ds.io.re.wrong_index, index);
	assert_int_equal(ds.io.re.wrong_sub, sub);
	assert_int_equal(ds.io.re.wrong_got, other);
	for (int k = 0; k < 100; k++) { /* its heartbeats go on: never again */
		period();
		if (k % 10 == 0) {
			peer_hb(mod);
		}
	}
	assert_int_equal(st->state, MLIP_STATE_ESTOP);
	assert_int_equal(st->reason, MLIP_WHY_IO_LOST);
	assert_int_equal(st->reason_node, 10);
	assert_int_equal(st->reason_field, MLIP_DRIVE_WRONG_DEVICE);
	assert_int_equal((uint32_t)st->reason_value, (uint32_t)index << 8 | sub);
	assert_int_equal(st->io_known & estop, 0);
	assert_int_equal(mod->n_wr, writes); /* nothing written to it */
	assert_int_equal(mod->nmt, MLIP_NMT_PREOPERATIONAL);
	assert_int_equal(n_module_out, out_before);
	assert_int_equal(ds.io.re.count, 0);
	assert_int_equal(post(MLIP_CMD_RESET), MLIP_E_RANGE);
	assert_int_equal(st->state, MLIP_STATE_ESTOP);
	free(mem);
}

/* An EMCY of the module (node 10): code, error register. */
static void module_emcy(uint16_t code, uint8_t reg)
{
	struct mlip_can_frame f;
	memset(&f, 0, sizeof(f));
	f.id = 0x08A;
	f.len = 8;
	f.data[0] = (uint8_t)code;
	f.data[1] = (uint8_t)(code >> 8);
	f.data[2] = reg;
	push(&f);
}

/* The I/O module's fault (issue 18: fail-safe): its EMCY is an E-stop in
 * that period, its inputs unknown; at its next heartbeat mlip resets its
 * communication and reads its error register 0x1001 after its identity:
 * non-zero (the fault still there) the attempt fails before any write and
 * the E-stop stays, reset refused; once the fault is cleared the module is
 * configured and trusted again and reset leaves the E-stop. */
static void test_loop_module_fault(void **state)
{
	double start[NP];
	(void)state;
	struct peer *mod = module_loop(start, 60);
	const struct mlip_ring_status *st = &ctl.out.status;
	uint32_t estop = 1u << MLIP_IN_ESTOP;
	module_emcy(0x5000, 0x01); /* device hardware */
	od_find(mod, 0x1001, 0)->value = 0x01;
	period();
	assert_int_equal(st->state, MLIP_STATE_ESTOP);
	assert_int_equal(st->reason, MLIP_WHY_IO_LOST);
	assert_int_equal(st->reason_node, 10);
	assert_int_equal(st->reason_field, MLIP_DRIVE_EMCY);
	assert_int_equal(st->io_known & estop, 0);
	assert_int_equal(post(MLIP_CMD_RESET), MLIP_E_RANGE);
	int k, writes = mod->n_wr;
	for (k = 0; k < 300 && ds.io.re.failed < 2; k++) {
		period();
		assert_int_equal(st->state, MLIP_STATE_ESTOP);
		assert_int_equal(st->io_known & estop, 0);
	}
	assert_int_equal(ds.io.re.failed, 2); /* tried again at a later heartbeat */
	assert_int_equal(ds.io.re.fail_index, 0x1001);
	assert_int_equal(ds.io.re.fail_reg, 0x01);
	assert_int_equal(ds.io.re.count, 0);
	assert_int_equal(mod->n_wr, writes); /* nothing written to a faulted module */
	assert_int_equal(post(MLIP_CMD_RESET), MLIP_E_RANGE);
	od_find(mod, 0x1001, 0)->value = 0; /* the fault cleared */
	for (k = 0; k < 300 && ds.io.re.count == 0; k++) {
		period();
	}
	assert_int_equal(ds.io.re.count, 1);
	assert_int_equal(ds.io.lost, 0);
	period();
	assert_int_equal(st->io_known & estop, estop);
	assert_int_equal(post(MLIP_CMD_RESET), MLIP_OK);
	assert_int_equal(st->state, MLIP_STATE_IDLE);
	free(mem);
}

/* A module whose fault stays (0x1001 non-zero) is not reset and queried at
 * every heartbeat: attempts back off, 1, 2, 4 ... 32 heartbeats apart
 * (rt/iomodule.c), the E-stop kept all along; its EMCY 0000h (error reset,
 * CiA 301) is tried at once, between two heartbeats. Over 64 heartbeats
 * (100 periods apart): attempts at the 1st, 2nd, 4th, 8th, 16th, 32nd and
 * 64th, 7 (it was 64), each a reset and its identity and 0x1001 read. */
static void test_loop_module_fault_backoff(void **state)
{
	double start[NP];
	(void)state;
	struct peer *mod = module_loop(start, 60);
	const struct mlip_ring_status *st = &ctl.out.status;
	while (cycle % 100 != 50) {
		period();
	}
	module_emcy(0x5000, 0x01);
	od_find(mod, 0x1001, 0)->value = 0x01;
	period();
	assert_int_equal(st->state, MLIP_STATE_ESTOP);
	n_module_reset = n_module_sdo = 0;
	for (int k = 0; k < 64 * 100; k++) { /* 64 of its heartbeats */
		period();
		assert_int_equal(st->state, MLIP_STATE_ESTOP);
	}
	print_message("[io] fault for 64 heartbeats: %d NMT resets, %d SDO requests, %u attempts "
	              "failed\n",
	              n_module_reset, n_module_sdo, (unsigned)ds.io.re.failed);
	assert_int_equal(n_module_reset, 7);
	assert_int_equal(ds.io.re.failed, 7);
	assert_int_equal(n_module_sdo, 7 * 4); /* 0x1000, 0x1018:01, :02, 0x1001 */
	assert_int_equal(ds.io.re.fail_index, 0x1001);
	assert_int_equal(ds.io.re.count, 0);
	assert_int_equal(post(MLIP_CMD_RESET), MLIP_E_RANGE);
	/* the fault gone, said by its EMCY 0000h just after a heartbeat: the
	 * attempt at once, not at the heartbeat 32 further on */
	while (cycle % 100 != 2) {
		period();
	}
	od_find(mod, 0x1001, 0)->value = 0;
	module_emcy(0x0000, 0x00);
	int k;
	for (k = 0; k < 50 && ds.io.re.count == 0; k++) {
		period();
	}
	assert_int_equal(ds.io.re.count, 1);
	assert_int_equal(n_module_reset, 8);
	assert_int_equal(ds.io.lost, 0);
	period();
	assert_int_equal(post(MLIP_CMD_RESET), MLIP_OK);
	assert_int_equal(st->state, MLIP_STATE_IDLE);
	free(mem);
}

/* A module that reports a fault at bring-up (0x1001 non-zero): mlip-rt
 * does not start, naming node and object; no drive is ever enabled. */
static void test_module_fault_at_bringup(void **state)
{
	double start[NP];
	(void)state;
	cfg.inputs.node = 10;
	cfg.inputs.in_bytes = 1;
	cfg.inputs.in[MLIP_IN_ESTOP] = (struct mlip_io_bit){10, 1, 0x6000, 0, 1, 10};
	cfg.inputs.mapped = 1u << MLIP_IN_ESTOP;
	module_init(&peers[NP], 1);
	od_find(&peers[NP], 0x1001, 0)->value = 0x11;
	assert_int_equal(bringup(start), -EPROTO);
	assert_non_null(strstr(why, "its error register 0x1001 reads 0x11: the module reports a "
	                            "fault (CiA 301); clear it before starting"));
	for (int i = 0; i < NP; i++) {
		assert_int_equal(peers[i].ever_enabled, 0);
	}
	assert_int_equal(peers[NP].nmt, MLIP_NMT_PREOPERATIONAL); /* never started */
}

static void test_loop_module_swapped_product(void **state)
{
	(void)state;
	module_swapped(0x1018, 2, 0x00000402u);
}

static void test_loop_module_swapped_type(void **state)
{
	(void)state;
	module_swapped(0x1000, 0, 0x00020192u); /* a CiA 402 drive on the module's node */
}

static int32_t post_arg(mlip_ring_cmd_op op, int32_t arg)
{
	uint32_t seq = 0;
	int32_t res = 0;
	assert_int_equal(mlip_ring_cmd_post(ctl.ring, op, arg, &seq), MLIP_OK);
	period();
	assert_int_equal(mlip_ring_cmd_result(ctl.ring, seq, &res), MLIP_OK);
	return res;
}

/* Through the master's hooks: X jogging toward +, its drive's 0x60FD bit 1
 * comes in a TPDO3: quick stop to every drive in that period, fault naming
 * node 1 and X limit +; an incremental jog away (renewed as mlip-ctl does)
 * enables the drives again and runs its distance while the switch is
 * still on. */
static void drive_limit_jog_away(double period_s)
{
	double start[NP];
	if (period_s != 0.001) { /* as the VM test: 40 ms, X at 200 mm/s^2 */
		cfg.machine.period_s = period_s;
		cfg.machine.tolerance_mm = 0.5;
		cfg.machine.axis[0].max_accel = 200.0;
	}
	cfg.inputs.in[MLIP_IN_LIMIT_POS(0)] = (struct mlip_io_bit){1, 0, 0x60FD, 1, 0, 10};
	cfg.inputs.mapped = 1u << MLIP_IN_LIMIT_POS(0);
	static const struct {
		uint16_t i;
		uint8_t s, n;
	} objs[] = {{0x1802, 1, 4}, {0x1802, 2, 1}, {0x1802, 5, 2},
	            {0x1A02, 0, 1}, {0x1A02, 1, 4}, {0x60FD, 0, 4}};
	for (size_t k = 0; k < sizeof(objs) / sizeof(objs[0]); k++) {
		od_add(&peers[0], objs[k].i, objs[k].s, objs[k].n, 0);
	}
	loop_setup(start);
	keep_queue = 1;
	di_send = 1u;
	qs_periods = 30;
	const struct mlip_ring_status *st = &ctl.out.status;
	int32_t jog = MLIP_JOG_ARG(0, 0, 6000);
	int every = (int)(0.1 / cfg.machine.period_s + 0.5); /* mlip-ctl renews every 100 ms */
	assert_int_equal(post_arg(MLIP_CMD_JOG, jog), MLIP_OK);
	int n_jog = (int)(1.5 / cfg.machine.period_s); /* 1.5 s: at speed, far from the limit */
	for (int k = 0; k < n_jog; k++) {
		period();
		if (k % every == 0 && post_arg(MLIP_CMD_JOG, jog) != MLIP_OK) {
			fail_msg(
			    "renewal refused at %d: state %u reason %u field %u node %u value %g",
			    k, st->state, st->reason, st->reason_field, st->reason_node,
			    st->reason_value);
		}
	}
	assert_int_equal(st->state, MLIP_STATE_JOGGING);
	assert_true(st->speed_mm_s > 99.0);
	di_val[0] = 0x2u; /* the switch */
	struct mlip_can_frame f;
	memset(&f, 0, sizeof(f));
	f.id = 0x381;
	f.len = 4;
	f.data[0] = 0x2;
	push(&f);
	period();
	assert_int_equal(st->state, MLIP_STATE_FAULT);
	assert_int_equal(st->reason, MLIP_WHY_LIMIT);
	assert_int_equal(st->reason_node, 1);
	assert_int_equal(st->reason_field, MLIP_IN_LIMIT_POS(0));
	uint16_t cw;
	int32_t t;
	for (int i = 0; i < NP; i++) {
		assert_int_equal(rpdo_of(i, &cw, &t), 1);
		assert_int_equal(cw, 0x0002);
	}
	for (int k = 0; k < 2; k++) {
		period();
	}
	assert_int_equal(peers[0].state, P_QS); /* still braking */
	assert_int_equal(post_arg(MLIP_CMD_JOG, MLIP_JOG_ARG(0, 0, 1200)), MLIP_E_RANGE);
	/* away, but X still brakes on its drive's ramp: leaving the quick stop
	 * now would disable it at speed (transition 12): refused until at rest */
	int32_t away = MLIP_JOG_ARG(0, 1, 1200);
	int tries = 0;
	for (;;) {
		assert_int_equal(post_arg(MLIP_CMD_JOG_AXIS, MLIP_JOG_AXIS_ARG(0, 1, 40000)),
		                 MLIP_OK);
		int32_t r = post_arg(MLIP_CMD_JOG, away);
		if (r == MLIP_OK) {
			break;
		}
		assert_int_equal(r, MLIP_E_FULL);
		assert_int_equal(peers[0].state, P_QS);
		for (int i = 0; i < NP; i++) {
			assert_int_equal(rpdo_of(i, &cw, &t), 1);
			assert_int_equal(cw, 0x0002); /* still told to quick stop */
		}
		assert_true(++tries < 100);
	}
	/* accepted 3 TPDOs after the ramp's end (its 30 periods), not before */
	assert_int_equal(peers[0].qs_left, 0);
	assert_true(tries >= 30 / 2 - 2 && tries <= 30 / 2 + 4);
	int32_t x0 = 0;
	for (int k = 0; k < 200 && x0 == 0; k++) { /* where it was when enabled */
		if (peers[0].state == P_OE) {
			x0 = peers[0].pos;
		} else if (k % every == every - 1) {
			assert_int_equal(post_arg(MLIP_CMD_JOG, away), MLIP_OK); /* a period too */
		} else {
			period();
		}
	}
	int k;
	for (k = 0; k < 10000 && (st->state == MLIP_STATE_JOGGING ||
	                          st->drive_power != MLIP_POWER_OFF); /* disabled at rest */
	     k++) {
		period();
		if (k % every == every - 1 && st->state == MLIP_STATE_JOGGING) {
			int32_t r = post_arg(MLIP_CMD_JOG, away);
			if (r != MLIP_OK) {
				fail_msg(
				    "renewal %d refused (%d): state %u reason %u, X %d counts, "
				    "power %u",
				    k, r, st->state, st->reason, peers[0].pos, st->drive_power);
			}
		}
	}
	if (st->state != MLIP_STATE_IDLE || st->reason != MLIP_WHY_JOG_DONE ||
	    peers[0].pos != x0 - 40000) {
		fail_msg("state %u reason %u, X %d counts (from %d), setpoint %.4f, power %u",
		         st->state, st->reason, peers[0].pos, x0, st->pos[0], st->drive_power);
	}
	free(mem);
}

static void test_loop_drive_limit_jog_away(void **state)
{
	(void)state;
	drive_limit_jog_away(0.001);
}

/* The same at the VM tests' 40 ms period (the dead-man is 6 periods there,
 * the renewals every 2 or 3). */
static void test_loop_drive_limit_jog_away_40ms(void **state)
{
	(void)state;
	drive_limit_jog_away(0.04);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test_setup(test_bringup_three, setup),
	    cmocka_unit_test_setup(test_refused_sdo, setup),
	    cmocka_unit_test_setup(test_bringup_spindle, setup),
	    cmocka_unit_test_setup(test_missing_drive, setup),
	    cmocka_unit_test_setup(test_never_enabled, setup),
	    cmocka_unit_test_setup(test_beyond_limit, setup),
	    cmocka_unit_test_setup(test_loop_shutdown, setup),
	    cmocka_unit_test_setup(test_loop_drive_inputs, setup),
	    cmocka_unit_test_setup(test_loop_module_reboot, setup),
	    cmocka_unit_test_setup(test_loop_module_swapped_product, setup),
	    cmocka_unit_test_setup(test_loop_module_swapped_type, setup),
	    cmocka_unit_test_setup(test_loop_module_fault, setup),
	    cmocka_unit_test_setup(test_loop_module_fault_backoff, setup),
	    cmocka_unit_test_setup(test_module_fault_at_bringup, setup),
	    cmocka_unit_test_setup(test_loop_drive_limit_jog_away, setup),
	    cmocka_unit_test_setup(test_loop_drive_limit_jog_away_40ms, setup),
	    cmocka_unit_test_setup(test_loop_fault_bit, setup),
	    cmocka_unit_test_setup(test_loop_following_error, setup),
	    cmocka_unit_test_setup(test_loop_heartbeat_and_emcy, setup),
	    cmocka_unit_test_setup(test_loop_late_drive, setup),
	    cmocka_unit_test_setup(test_loop_stall_before_the_send, setup),
	    cmocka_unit_test_setup(test_loop_between_programs, setup),
	    cmocka_unit_test_setup(test_loop_stop_disables, setup),
	    cmocka_unit_test_setup(test_loop_enable_fails, setup),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
