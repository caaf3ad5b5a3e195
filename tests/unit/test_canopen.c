/*
 * test_canopen.c - the pure CANopen master (mlip/canopen/canopen.h): NMT and
 * heartbeat bytes, frame classification, the SDO client against answers
 * written from CiA 301's tables (expedited both ways, segmented upload with
 * its toggle, aborts, wrong answers), abort texts, 0x60C2, the drive's
 * set-up list, and its supervision (mlip/canopen/drive.h). The CiA 402
 * states and the power sequencer: test_cia402.c.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "mlip/canopen/drive.h"
#include "mlip/canopen/io401.h"

static void answer(struct mlip_can_frame *f, uint8_t node, const uint8_t b[8])
{
	memset(f, 0, sizeof(*f));
	f->id = 0x580u + node;
	f->len = 8;
	memcpy(f->data, b, 8);
}

static void test_nmt_heartbeat(void **state)
{
	struct mlip_can_frame f;
	struct mlip_co_msg m;
	(void)state;
	mlip_nmt_encode(MLIP_NMT_RESET_COMM, 3, &f);
	assert_int_equal(f.id, 0x000);
	assert_int_equal(f.len, 2);
	assert_int_equal(f.data[0], 0x82);
	assert_int_equal(f.data[1], 3);
	mlip_nmt_encode(MLIP_NMT_START, 0, &f);
	assert_int_equal(f.data[0], 0x01);
	assert_int_equal(f.data[1], 0);
	mlip_co_heartbeat_encode(127, MLIP_NMT_OPERATIONAL, &f);
	assert_int_equal(f.id, 0x77F);
	assert_int_equal(f.len, 1);
	assert_int_equal(f.data[0], 5);
	assert_int_equal(mlip_co_classify(&f, &m), MLIP_OK);
	assert_int_equal(m.kind, MLIP_CO_HEARTBEAT);
	assert_int_equal(m.node, 127);
	assert_int_equal(m.nmt_state, 5);
	assert_string_equal(mlip_nmt_state_name(127), "pre-operational");
	assert_string_equal(mlip_nmt_state_name(0), "boot-up");
	/* a heartbeat of 2 bytes is malformed, not a heartbeat */
	f.len = 2;
	assert_int_equal(mlip_co_classify(&f, &m), MLIP_E_SYNTAX);
	assert_int_equal(m.kind, MLIP_CO_OTHER);
}

static void test_classify(void **state)
{
	struct mlip_can_frame f;
	struct mlip_co_msg m;
	(void)state;
	/* TPDO1 of node 2: statusword 0x1237, position -5 counts */
	mlip_co_pdo_encode(0x182, 0x1237, -5, &f);
	assert_int_equal(f.len, 6);
	assert_memory_equal(f.data, ((uint8_t[]){0x37, 0x12, 0xFB, 0xFF, 0xFF, 0xFF}), 6);
	assert_int_equal(mlip_co_classify(&f, &m), MLIP_OK);
	assert_int_equal(m.kind, MLIP_CO_TPDO);
	assert_int_equal(m.node, 2);
	assert_int_equal(m.statusword, 0x1237);
	assert_int_equal(m.position_counts, -5);
	/* EMCY of node 3: 0x8611 following error, register 0x81 */
	memset(&f, 0, sizeof(f));
	f.id = 0x083;
	f.len = 8;
	f.data[0] = 0x11;
	f.data[1] = 0x86;
	f.data[2] = 0x81;
	assert_int_equal(mlip_co_classify(&f, &m), MLIP_OK);
	assert_int_equal(m.kind, MLIP_CO_EMCY);
	assert_int_equal(m.node, 3);
	assert_int_equal(m.emcy.code, 0x8611);
	assert_int_equal(m.emcy.reg, 0x81);
	assert_string_equal(mlip_emcy_text(0x8611), "following error");
	assert_string_equal(mlip_emcy_text(0x2310), "current");
	assert_string_equal(mlip_emcy_text(0x0000), "error reset or no error");
	/* SYNC (0x080, node 0) and an RPDO are not for the master */
	f.id = 0x080;
	f.len = 0;
	assert_int_equal(mlip_co_classify(&f, &m), MLIP_OK);
	assert_int_equal(m.kind, MLIP_CO_OTHER);
	mlip_co_pdo_encode(0x201, 0x000F, 0, &f);
	assert_int_equal(mlip_co_classify(&f, &m), MLIP_OK);
	assert_int_equal(m.kind, MLIP_CO_OTHER);
	/* a 4-byte TPDO is not the mapping mlip wrote */
	mlip_co_pdo_encode(0x181, 0x0027, 0, &f);
	f.len = 4;
	assert_int_equal(mlip_co_classify(&f, &m), MLIP_E_SYNTAX);
}

static void test_sdo_download(void **state)
{
	struct mlip_sdo s;
	struct mlip_can_frame req, ans;
	(void)state;
	/* 0x6060:00 = 8, one byte: command 0x2F (CiA 301 expedited, n = 3) */
	mlip_sdo_download_begin(&s, 2, 0x6060, 0, 8, 1, &req);
	assert_int_equal(req.id, 0x602);
	assert_int_equal(req.len, 8);
	assert_memory_equal(req.data, ((uint8_t[]){0x2F, 0x60, 0x60, 0x00, 8, 0, 0, 0}), 8);
	/* 2 and 4 bytes: 0x2B, 0x23 */
	mlip_sdo_download_begin(&s, 2, 0x6040, 0, 0x000F, 2, &req);
	assert_int_equal(req.data[0], 0x2B);
	mlip_sdo_download_begin(&s, 2, 0x1600, 1, 0x60400010u, 4, &req);
	assert_memory_equal(req.data, ((uint8_t[]){0x23, 0x00, 0x16, 0x01, 0x10, 0x00, 0x40, 0x60}),
	                    8);
	/* another node's answer is ignored; the right one completes */
	answer(&ans, 3, (uint8_t[]){0x60, 0x00, 0x16, 0x01, 0, 0, 0, 0});
	assert_int_equal(mlip_sdo_feed(&s, &ans, &req), MLIP_SDO_IGNORED);
	answer(&ans, 2, (uint8_t[]){0x60, 0x00, 0x16, 0x01, 0, 0, 0, 0});
	assert_int_equal(mlip_sdo_feed(&s, &ans, &req), MLIP_SDO_DONE);
	/* an abort: code 0x06090011 */
	mlip_sdo_download_begin(&s, 2, 0x6060, 0, 8, 1, &req);
	answer(&ans, 2, (uint8_t[]){0x80, 0x60, 0x60, 0x00, 0x11, 0x00, 0x09, 0x06});
	assert_int_equal(mlip_sdo_feed(&s, &ans, &req), MLIP_SDO_ABORTED);
	assert_int_equal(s.abort_code, 0x06090011u);
	assert_string_equal(mlip_sdo_abort_text(s.abort_code), "sub-index does not exist");
	assert_string_equal(mlip_sdo_abort_text(0x06020000u),
	                    "object does not exist in the object dictionary");
	assert_string_equal(mlip_sdo_abort_text(0x12345678u), "unknown abort code");
	/* an answer about another object: our abort, general error */
	mlip_sdo_download_begin(&s, 2, 0x6060, 0, 8, 1, &req);
	answer(&ans, 2, (uint8_t[]){0x60, 0x61, 0x60, 0x00, 0, 0, 0, 0});
	assert_int_equal(mlip_sdo_feed(&s, &ans, &req), MLIP_SDO_PROTOCOL);
	assert_int_equal(req.id, 0x602);
	assert_int_equal(req.data[0], 0x80);
	assert_int_equal(s.abort_code, MLIP_SDO_ABORT_GENERAL);
	/* an upload answer to a download: wrong command specifier */
	mlip_sdo_download_begin(&s, 2, 0x6060, 0, 8, 1, &req);
	answer(&ans, 2, (uint8_t[]){0x4F, 0x60, 0x60, 0x00, 8, 0, 0, 0});
	assert_int_equal(mlip_sdo_feed(&s, &ans, &req), MLIP_SDO_PROTOCOL);
	assert_int_equal(s.abort_code, MLIP_SDO_ABORT_COMMAND);
}

static void test_sdo_upload(void **state)
{
	struct mlip_sdo s;
	struct mlip_can_frame req, ans;
	(void)state;
	mlip_sdo_upload_begin(&s, 1, 0x6064, 0, &req);
	assert_memory_equal(req.data, ((uint8_t[]){0x40, 0x64, 0x60, 0x00, 0, 0, 0, 0}), 8);
	/* expedited 4 bytes, size indicated (0x43): -1000 */
	answer(&ans, 1, (uint8_t[]){0x43, 0x64, 0x60, 0x00, 0x18, 0xFC, 0xFF, 0xFF});
	assert_int_equal(mlip_sdo_feed(&s, &ans, &req), MLIP_SDO_DONE);
	assert_int_equal((int32_t)s.value, -1000);
	assert_int_equal(s.len, 4);
	/* expedited 2 bytes (0x4B): statusword; the bytes beyond are not data */
	mlip_sdo_upload_begin(&s, 1, 0x6041, 0, &req);
	answer(&ans, 1, (uint8_t[]){0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0xAA, 0xBB});
	assert_int_equal(mlip_sdo_feed(&s, &ans, &req), MLIP_SDO_DONE);
	assert_int_equal(s.value, 0x0237);
	assert_int_equal(s.len, 2);
	/* segmented: 0x1008 device name "mlip drive 1" (12 bytes) */
	mlip_sdo_upload_begin(&s, 1, 0x1008, 0, &req);
	answer(&ans, 1, (uint8_t[]){0x41, 0x08, 0x10, 0x00, 12, 0, 0, 0});
	assert_int_equal(mlip_sdo_feed(&s, &ans, &req), MLIP_SDO_SEND);
	assert_int_equal(req.data[0], 0x60); /* toggle 0 */
	answer(&ans, 1, (uint8_t[]){0x00, 'm', 'l', 'i', 'p', ' ', 'd', 'r'});
	assert_int_equal(mlip_sdo_feed(&s, &ans, &req), MLIP_SDO_SEND);
	assert_int_equal(req.data[0], 0x70); /* toggle 1 */
	/* last segment, toggle 1, 5 bytes (n = 2 unused), c = 1: 0x10|0x04|0x01 */
	answer(&ans, 1, (uint8_t[]){0x15, 'i', 'v', 'e', ' ', '1', 0, 0});
	assert_int_equal(mlip_sdo_feed(&s, &ans, &req), MLIP_SDO_DONE);
	assert_int_equal(s.len, 12);
	assert_memory_equal(s.data, "mlip drive 1", 12);
	/* a segment with the toggle not alternated: our abort 0x05030000 */
	mlip_sdo_upload_begin(&s, 1, 0x1008, 0, &req);
	answer(&ans, 1, (uint8_t[]){0x41, 0x08, 0x10, 0x00, 12, 0, 0, 0});
	assert_int_equal(mlip_sdo_feed(&s, &ans, &req), MLIP_SDO_SEND);
	answer(&ans, 1, (uint8_t[]){0x10, 'm', 'l', 'i', 'p', ' ', 'd', 'r'});
	assert_int_equal(mlip_sdo_feed(&s, &ans, &req), MLIP_SDO_PROTOCOL);
	assert_int_equal(s.abort_code, MLIP_SDO_ABORT_TOGGLE);
	assert_memory_equal(req.data, ((uint8_t[]){0x80, 0x08, 0x10, 0x00, 0x00, 0x00, 0x03, 0x05}),
	                    8);
	assert_string_equal(mlip_sdo_abort_text(MLIP_SDO_ABORT_TOGGLE),
	                    "toggle bit not alternated");
}

static void test_interp_period(void **state)
{
	uint8_t v;
	int8_t ix;
	(void)state;
	assert_int_equal(mlip_co_interp_period(0.001, &v, &ix), MLIP_OK);
	assert_int_equal(v, 1);
	assert_int_equal(ix, -3);
	assert_int_equal(mlip_co_interp_period(0.0025, &v, &ix), MLIP_OK);
	assert_int_equal(v, 25);
	assert_int_equal(ix, -4);
	assert_int_equal(mlip_co_interp_period(0.1, &v, &ix), MLIP_OK);
	assert_int_equal(v, 1);
	assert_int_equal(ix, -1);
	assert_int_equal(mlip_co_interp_period(0.000125, &v, &ix), MLIP_OK);
	assert_int_equal(v, 125);
	assert_int_equal(ix, -6);
	/* 1/3 ms has no exact value * 10^index */
	assert_int_equal(mlip_co_interp_period(1.0 / 3000.0, &v, &ix), MLIP_E_RANGE);
	assert_int_equal(mlip_co_interp_period(0.0, &v, &ix), MLIP_E_RANGE);
}

/* Node 2 at 1 ms, the pre-defined connection set's COB-IDs. */
static struct mlip_drive_setup drive2(void)
{
	struct mlip_drive_setup d = {.node = 2,
	                             .sync_id = 0x080,
	                             .rpdo_cob = 0x202,
	                             .tpdo_cob = 0x182,
	                             .period_s = 0.001,
	                             .following_window_counts = 1000,
	                             .heartbeat_ms = 100,
	                             .master_node = 127,
	                             .master_timeout_ms = 300};
	return d;
}

static void test_setup_entries(void **state)
{
	struct mlip_drive_setup d = drive2();
	struct mlip_sdo_entry e[MLIP_DRIVE_SETUP_MAX];
	int n, i, found = 0;
	(void)state;
	n = mlip_drive_setup_entries(&d, e, MLIP_DRIVE_SETUP_MAX);
	assert_true(n > 0 && n <= MLIP_DRIVE_SETUP_MAX);
	assert_int_equal(mlip_drive_setup_entries(&d, e, n - 1), -1);
	/* the mapping is written while the PDO is invalid (bit 31), then enabled */
	assert_int_equal(e[0].index, 0x1400);
	assert_int_equal(e[0].value, 0x80000202u);
	for (i = 0; i < n; i++) {
		uint32_t key = (uint32_t)e[i].index << 8 | e[i].sub;
		switch (key) {
		case 0x160001:
			assert_int_equal(e[i].value, 0x60400010u);
			found |= 1;
			break;
		case 0x160002:
			assert_int_equal(e[i].value, 0x607A0020u);
			found |= 2;
			break;
		case 0x1A0001:
			assert_int_equal(e[i].value, 0x60410010u);
			found |= 4;
			break;
		case 0x1A0002:
			assert_int_equal(e[i].value, 0x60640020u);
			found |= 8;
			break;
		case 0x606000:
			assert_int_equal(e[i].value, 8);
			assert_int_equal(e[i].size, 1);
			assert_int_equal(e[i].read_only, 0);
			found |= 16;
			break;
		case 0x606100:
			assert_int_equal(e[i].read_only, 1);
			found |= 32;
			break;
		case 0x60C202:
			assert_int_equal(e[i].value, 0xFD); /* -3 */
			found |= 64;
			break;
		case 0x606500:
			assert_int_equal(e[i].value, 1000);
			found |= 128;
			break;
		case 0x101601:
			assert_int_equal(e[i].value, (127u << 16) | 300u);
			found |= 256;
			break;
		case 0x180002:
			assert_int_equal(e[i].value, 1); /* synchronous, every SYNC */
			found |= 512;
			break;
		case 0x100500:
			assert_int_equal(e[i].value, 0x080);
			found |= 1024;
			break;
		}
	}
	assert_int_equal(found, 2047);
	/* the last COB-ID writes enable the PDOs: bit 31 clear */
	for (i = n - 1; i >= 0 && !(e[i].index == 0x1800 && e[i].sub == 1); i--) {
	}
	assert_int_equal(e[i].value, 0x40000182u);
	d.period_s = 1.0 / 3000.0;
	assert_int_equal(mlip_drive_setup_entries(&d, e, MLIP_DRIVE_SETUP_MAX), -1);
}

/* An axis with its switches on the drive (issue 18): TPDO3 carries 0x60FD on
 * change with an event timer, mapped while invalid, then enabled; the quick
 * stop deceleration 0x6085 is the axis' acceleration limit. With the touch
 * probe too, TPDO2 keeps its latched positions and TPDO3 the inputs. */
static void test_setup_entries_inputs(void **state)
{
	struct mlip_drive_setup d = {.node = 2,
	                             .sync_id = 0x080,
	                             .rpdo_cob = 0x202,
	                             .tpdo_cob = 0x182,
	                             .period_s = 0.001,
	                             .following_window_counts = 1000,
	                             .heartbeat_ms = 100,
	                             .master_node = 127,
	                             .master_timeout_ms = 300,
	                             .quick_stop_counts_s2 = 1000000,
	                             .di_tpdo_cob = 0x382,
	                             .di_event_ms = 100};
	struct mlip_sdo_entry e[MLIP_DRIVE_SETUP_MAX];
	int n, i, first = -1, last = -1, map = -1, count = -1, qs = 0;
	(void)state;
	n = mlip_drive_setup_entries(&d, e, MLIP_DRIVE_SETUP_MAX);
	assert_true(n > 0 && n <= MLIP_DRIVE_SETUP_MAX);
	for (i = 0; i < n; i++) {
		uint32_t key = (uint32_t)e[i].index << 8 | e[i].sub;
		assert_true(e[i].index != 0x1801 && e[i].index != 0x1A01); /* TPDO2 untouched */
		if (key == 0x180201) {
			if (first < 0) {
				first = i;
			}
			last = i;
		} else if (key == 0x1A0201) {
			map = i;
			assert_int_equal(e[i].value, 0x60FD0020u);
		} else if (key == 0x1A0200) {
			count = i;
		} else if (key == 0x180202) {
			assert_int_equal(e[i].value, 255);
		} else if (key == 0x180205) {
			assert_int_equal(e[i].value, 100);
			assert_int_equal(e[i].size, 2);
		} else if (key == 0x608500) {
			assert_int_equal(e[i].value, 1000000);
			qs++;
		} else if (key == 0x605A00) {
			/* the ramp, then held in quick stop active (INTEGER16) */
			assert_int_equal(e[i].value, 6);
			assert_int_equal(e[i].size, 2);
			qs += 10;
		}
	}
	assert_int_equal(qs, 11);
	assert_true(first >= 0 && first < map && map < count && count < last);
	assert_int_equal(e[first].value, 0xC0000382u); /* invalid while mapped */
	assert_int_equal(e[count].value, 1);
	assert_int_equal(e[last].value, 0x40000382u);
	/* the touch probe as well: 10 more entries, TPDO2 = 0x60BA + 0x60BB and
	 * TPDO3 = 0x60FD alone, each enabled after its own mapping */
	d.touch_probe = 1;
	d.tpdo2_cob = 0x282;
	int b = mlip_drive_setup_entries(&d, e, MLIP_DRIVE_SETUP_MAX);
	assert_int_equal(b, n + 10);
	int tp2_on = -1, tp3_on = -1, tp2_maps = 0, tp3_maps = 0;
	for (i = 0; i < b; i++) {
		uint32_t key = (uint32_t)e[i].index << 8 | e[i].sub;
		if (e[i].index == 0x1A01 && e[i].sub >= 1) {
			assert_true(e[i].value == 0x60BA0020u || e[i].value == 0x60BB0020u);
			tp2_maps++;
		} else if (e[i].index == 0x1A02 && e[i].sub >= 1) {
			assert_int_equal(e[i].value, 0x60FD0020u);
			tp3_maps++;
		} else if (key == 0x180101 && e[i].value == 0x40000282u) {
			tp2_on = i;
		} else if (key == 0x180201 && e[i].value == 0x40000382u) {
			tp3_on = i;
		}
	}
	assert_int_equal(tp2_maps, 2);
	assert_int_equal(tp3_maps, 1);
	assert_true(tp2_on > 0 && tp3_on > 0);
	/* none of them without switches on the drive (nor 0x6085/0x605A unset) */
	d.touch_probe = 0;
	d.di_tpdo_cob = 0;
	d.quick_stop_counts_s2 = 0;
	int m = mlip_drive_setup_entries(&d, e, MLIP_DRIVE_SETUP_MAX);
	assert_int_equal(m, n - 9);
	for (i = 0; i < m; i++) {
		assert_true(e[i].index != 0x1802 && e[i].index != 0x1A02 && e[i].index != 0x6085 &&
		            e[i].index != 0x605A);
	}
}

/* The input functions from what the bus said: a module byte's bit and a
 * drive's 0x60FD bit, each with its polarity; unread ones are neither on nor
 * known. */
static void test_io_eval_drive_inputs(void **state)
{
	struct mlip_machine m;
	struct mlip_io_config io;
	struct mlip_io_image img;
	uint32_t known = 0, on;
	(void)state;
	memset(&m, 0, sizeof(m));
	memset(&io, 0, sizeof(io));
	memset(&img, 0, sizeof(img));
	m.n_axes = 2;
	m.axis[0].can_node = 1;
	m.axis[1].can_node = 2;
	io.node = 10;
	io.in[MLIP_IN_ESTOP] = (struct mlip_io_bit){10, 1, 0x6000, 0, 1, 3};
	io.in[MLIP_IN_LIMIT_NEG(0)] = (struct mlip_io_bit){1, 0, 0x60FD, 0, 0, 4};
	io.in[MLIP_IN_LIMIT_POS(0)] = (struct mlip_io_bit){1, 0, 0x60FD, 1, 0, 5};
	io.in[MLIP_IN_HOME_SW(1)] = (struct mlip_io_bit){2, 0, 0x60FD, 2, 0, 6};
	io.in[MLIP_IN_LIMIT_POS(1)] = (struct mlip_io_bit){2, 0, 0x60FD, 17, 1, 7}; /* mfr, LOW */
	io.mapped = 1u << MLIP_IN_ESTOP | 1u << MLIP_IN_LIMIT_NEG(0) | 1u << MLIP_IN_LIMIT_POS(0) |
	            1u << MLIP_IN_HOME_SW(1) | 1u << MLIP_IN_LIMIT_POS(1);
	/* nothing read yet: nothing on, nothing known (a broken wire is not
	 * assumed before the first frame) */
	assert_int_equal(mlip_io_eval(&io, &m, &img, &known), 0);
	assert_int_equal(known, 0);
	img.drives_read = 1u; /* drive 1 read: 0x60FD bit 1, the positive limit */
	img.di[0] = 0x2u;
	img.di[1] = 0xFFFFFFFFu; /* not read: ignored */
	on = mlip_io_eval(&io, &m, &img, &known);
	assert_int_equal(on, 1u << MLIP_IN_LIMIT_POS(0));
	assert_int_equal(known, 1u << MLIP_IN_LIMIT_NEG(0) | 1u << MLIP_IN_LIMIT_POS(0));
	img.drives_read = 3u;
	img.di[1] = 0x4u; /* home switch on, bit 17 = 0: the LOW limit is on */
	img.module_read = 1;
	img.in[0] = 0x1u; /* E-stop circuit closed: off */
	on = mlip_io_eval(&io, &m, &img, &known);
	assert_int_equal(known, io.mapped);
	assert_int_equal(on, 1u << MLIP_IN_LIMIT_POS(0) | 1u << MLIP_IN_HOME_SW(1) |
	                         1u << MLIP_IN_LIMIT_POS(1));
	img.di[1] = 1u << 17;
	img.di[0] = 0x1u;
	on = mlip_io_eval(&io, &m, &img, &known);
	assert_int_equal(on, 1u << MLIP_IN_LIMIT_NEG(0));
}

static void test_supervise(void **state)
{
	struct mlip_drive_obs o;
	struct mlip_drive_expect x;
	int64_t det;
	(void)state;
	memset(&o, 0, sizeof(o));
	memset(&x, 0, sizeof(x));
	o.statusword = 0x1237;
	o.tpdo_cycle = 100;
	o.nmt_state = MLIP_NMT_OPERATIONAL;
	o.hb_ns = 1000000000u;
	x.now_ns = 1000000000u + 300000000u; /* exactly the timeout: not yet lost */
	x.cycle = 100;
	x.hb_timeout_ns = 300000000u;
	x.tpdo_timeout = 10;
	x.window_counts = 1000;
	x.following_counts = 1000; /* at the window: fine */
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_OK);
	x.following_counts = 1001;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_FOLLOWING_ERROR);
	assert_int_equal(det, 1001);
	x.following_counts = -1;
	x.now_ns++;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_HEARTBEAT_LOST);
	assert_int_equal(det, 300);
	x.now_ns--;
	x.cycle = 110;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_OK);
	x.cycle = 111;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_TPDO_LOST);
	assert_int_equal(det, 11);
	/* TPDOs arriving, but answering SYNCs 10 and then 11 periods old */
	x.cycle = 100;
	o.tpdo_count = 90;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_OK);
	o.tpdo_count = 89;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_TPDO_LOST);
	assert_int_equal(det, 11);
	o.tpdo_count = 0;
	x.cycle = 100;
	o.statusword = 0x0233; /* switched on: left operation enabled */
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_LEFT_ENABLED);
	assert_int_equal(det, 0x0233);
	o.statusword = 0x0218; /* fault: the fault bit comes first */
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_FAULT_BIT);
	/* the master disabling, off or enabling: any state is right but fault */
	x.any_state = 1;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_FAULT_BIT);
	o.statusword = 0x0231; /* ready to switch on */
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_OK);
	o.statusword = 0x0233;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_OK);
	x.any_state = 0;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_LEFT_ENABLED);
	o.statusword = 0x0218;
	o.statusword = 0x1237;
	o.nmt_state = MLIP_NMT_PREOPERATIONAL;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_NOT_OPERATIONAL);
	assert_int_equal(det, 127);
	o.nmt_state = MLIP_NMT_OPERATIONAL;
	o.emcy.code = 0x2310;
	o.emcy_count = 1;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_EMCY);
	assert_int_equal(det, 0x2310);
	assert_string_equal(mlip_drive_fault_name(MLIP_DRIVE_EMCY), "emergency");
	/* its digital inputs (TPDO3) unread for longer than the timeout; a
	 * drive's own failures come first */
	o.emcy_count = 0;
	o.di_ns = 1000000000u;
	x.di_timeout_ns = 300000000u;
	x.now_ns = o.di_ns + 300000000u;
	o.hb_ns = x.now_ns;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_OK);
	x.now_ns += 1000000u;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_INPUTS_LOST);
	assert_int_equal(det, 301);
	assert_string_equal(mlip_drive_fault_name(MLIP_DRIVE_INPUTS_LOST), "digital inputs lost");
	o.nmt_state = MLIP_NMT_PREOPERATIONAL;
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_NOT_OPERATIONAL);
	o.nmt_state = MLIP_NMT_OPERATIONAL;
	x.di_timeout_ns = 0; /* no inputs on it: not watched */
	assert_int_equal(mlip_drive_supervise(&o, &x, &det), MLIP_DRIVE_OK);
}

static void test_following_error(void **state)
{
	/* newest first: the drive lags by about two periods at 10 counts/period */
	int32_t t[5] = {100, 90, 80, 70, 60};
	(void)state;
	assert_int_equal(mlip_drive_following_error(t, 5, 80), 0);
	assert_int_equal(mlip_drive_following_error(t, 5, 77), 3);
	assert_int_equal(mlip_drive_following_error(t, 5, 10), 50);
	assert_int_equal(mlip_drive_following_error(t, 5, 150), 50);
	assert_int_equal(mlip_drive_following_error(t, 0, 150), -1);
	/* no overflow across the int32 range */
	int32_t w[1] = {INT32_MIN};
	assert_true(mlip_drive_following_error(w, 1, INT32_MAX) == 4294967295LL);
}

/* The touch probe ([PROBE] SOURCE = drive): 0x60B8 the third object of
 * RPDO1, 0x60B9 of TPDO1, TPDO2 = 0x60BA + 0x60BB (written while invalid,
 * synchronous), 0x60B8 = 0; the 8-byte TPDO1 and the TPDO2 classified. */
static void test_touch_probe_setup_and_pdos(void **state)
{
	struct mlip_drive_setup d = drive2();
	struct mlip_sdo_entry e[MLIP_DRIVE_SETUP_MAX];
	uint32_t want[][2] = {{0x160003, 0x60B80010u}, {0x160000, 3},
	                      {0x1A0003, 0x60B90010u}, {0x1A0000, 3},
	                      {0x180101, 0xC0000282u}, {0x180102, 1},
	                      {0x1A0101, 0x60BA0020u}, {0x1A0102, 0x60BB0020u},
	                      {0x1A0100, 2},           {0x60B800, 0}};
	int n, found = 0, last_cob = -1, last_map = -1;
	struct mlip_can_frame f;
	struct mlip_co_msg m;
	(void)state;
	d.touch_probe = 1;
	d.tpdo2_cob = 0x282;
	n = mlip_drive_setup_entries(&d, e, MLIP_DRIVE_SETUP_MAX);
	assert_true(n > 0 && n <= MLIP_DRIVE_SETUP_MAX);
	for (int i = 0; i < n; i++) {
		uint32_t key = (uint32_t)e[i].index << 8 | e[i].sub;
		for (size_t w = 0; w < sizeof(want) / sizeof(want[0]); w++) {
			if (key == want[w][0] && e[i].value == want[w][1]) {
				found |= 1 << w;
			}
		}
		if (key == 0x180101 && e[i].value == 0x40000282u) {
			last_cob = i; /* valid again: after its mapping */
		}
		if (e[i].index == 0x1A01) {
			last_map = i;
		}
	}
	assert_int_equal(found, (1 << 10) - 1);
	assert_true(last_cob > last_map && last_map > 0);
	/* TPDO1 of 8 bytes: statusword, position, touch probe status */
	memset(&f, 0, sizeof(f));
	f.id = 0x182;
	f.len = 8;
	f.data[0] = 0x37;
	f.data[2] = 0xFB;
	f.data[3] = f.data[4] = f.data[5] = 0xFF;
	f.data[6] = 0x03;
	assert_int_equal(mlip_co_classify(&f, &m), MLIP_OK);
	assert_int_equal(m.kind, MLIP_CO_TPDO);
	assert_int_equal(m.position_counts, -5);
	assert_int_equal(m.has_probe, 1);
	assert_int_equal(m.probe_status, 0x0003);
	f.len = 7;
	assert_int_equal(mlip_co_classify(&f, &m), MLIP_E_SYNTAX);
	/* TPDO2: 0x60BA = -1000, 0x60BB = 70000 */
	f.id = 0x282;
	f.len = 8;
	f.data[0] = 0x18;
	f.data[1] = 0xFC;
	f.data[2] = f.data[3] = 0xFF;
	f.data[4] = 0x70;
	f.data[5] = 0x11;
	f.data[6] = 0x01;
	f.data[7] = 0x00;
	assert_int_equal(mlip_co_classify(&f, &m), MLIP_OK);
	assert_int_equal(m.kind, MLIP_CO_TPDO2);
	assert_int_equal(m.node, 2);
	assert_int_equal(m.probe_pos, -1000);
	assert_int_equal(m.probe_neg, 70000);
	f.len = 6;
	assert_int_equal(mlip_co_classify(&f, &m), MLIP_E_SYNTAX);
}

/* One PDO's mapping sequence (CiA 301: changed only while not valid): a
 * TPDO (bit 30: no RTR) with its event timer, an RPDO without; the indices
 * follow the PDO's number; out-of-range numbers and counts add nothing. */
static void test_sdo_add_pdo(void **state)
{
	static const uint32_t map[2] = {0x60000108u, 0x60FD0020u};
	static const char *const what[2] = {"in 1", "inputs"};
	struct mlip_sdo_entry e[16];
	struct mlip_sdo_list l = {e, 16, 0};
	struct mlip_pdo_map p = {.tpdo = 1,
	                         .num = 4,
	                         .cob_id = 0x485,
	                         .type = 254,
	                         .type_what = "type",
	                         .event_what = "timer",
	                         .event_ms = 50,
	                         .n = 2,
	                         .map = map,
	                         .what = what};
	static const struct {
		uint16_t index;
		uint8_t sub, size;
		uint32_t value;
		const char *what;
	} want[] = {{0x1803, 1, 4, 0xC0000485u, "TPDO4 COB-ID (disabled while mapping)"},
	            {0x1803, 2, 1, 254, "type"},
	            {0x1803, 5, 2, 50, "timer"},
	            {0x1A03, 0, 1, 0, "TPDO4 mapping count (cleared)"},
	            {0x1A03, 1, 4, 0x60000108u, "in 1"},
	            {0x1A03, 2, 4, 0x60FD0020u, "inputs"},
	            {0x1A03, 0, 1, 2, "TPDO4 mapping count"},
	            {0x1803, 1, 4, 0x40000485u, "TPDO4 COB-ID"},
	            {0x1401, 1, 4, 0x80000305u, "RPDO2 COB-ID (disabled while mapping)"},
	            {0x1401, 2, 1, 1, "type"},
	            {0x1601, 0, 1, 0, "RPDO2 mapping count (cleared)"},
	            {0x1601, 1, 4, 0x60000108u, "in 1"},
	            {0x1601, 0, 1, 1, "RPDO2 mapping count"},
	            {0x1401, 1, 4, 0x305u, "RPDO2 COB-ID"}};
	int i;
	(void)state;
	assert_int_equal(mlip_sdo_add_pdo(&l, &p), MLIP_OK);
	p = (struct mlip_pdo_map){.num = 2,
	                          .cob_id = 0x305,
	                          .type = 1,
	                          .type_what = "type",
	                          .n = 1,
	                          .map = map,
	                          .what = what};
	assert_int_equal(mlip_sdo_add_pdo(&l, &p), MLIP_OK);
	assert_int_equal(l.n, 14);
	for (i = 0; i < 14; i++) {
		assert_int_equal(e[i].index, want[i].index);
		assert_int_equal(e[i].sub, want[i].sub);
		assert_int_equal(e[i].size, want[i].size);
		assert_int_equal(e[i].value, want[i].value);
		assert_int_equal(e[i].read_only, 0);
		assert_string_equal(e[i].what, want[i].what);
	}
	p.num = 0;
	assert_int_equal(mlip_sdo_add_pdo(&l, &p), MLIP_E_RANGE);
	p.num = 5;
	assert_int_equal(mlip_sdo_add_pdo(&l, &p), MLIP_E_RANGE);
	p.num = 1;
	p.n = 0;
	assert_int_equal(mlip_sdo_add_pdo(&l, &p), MLIP_E_RANGE);
	p.n = 9;
	assert_int_equal(mlip_sdo_add_pdo(&l, &p), MLIP_E_RANGE);
	assert_int_equal(l.n, 14);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_nmt_heartbeat),
	    cmocka_unit_test(test_classify),
	    cmocka_unit_test(test_sdo_download),
	    cmocka_unit_test(test_sdo_upload),
	    cmocka_unit_test(test_interp_period),
	    cmocka_unit_test(test_setup_entries),
	    cmocka_unit_test(test_sdo_add_pdo),
	    cmocka_unit_test(test_touch_probe_setup_and_pdos),
	    cmocka_unit_test(test_supervise),
	    cmocka_unit_test(test_setup_entries_inputs),
	    cmocka_unit_test(test_io_eval_drive_inputs),
	    cmocka_unit_test(test_following_error),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
