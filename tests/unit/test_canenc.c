/*
 * test_canenc.c - CAN encoding of setpoints: golden bytes (shared with
 * tests/py/test_dbc.py), round trips for every profile and 2..6 axes,
 * rounding and saturation on both sides of each bound, FD lengths, the
 * streaming decoder's gap detection, and bus-load figures computed by hand.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "mlip/can/canenc.h"

/* cmocka 1.1.5 has no assert_double_equal (its float one casts to float) */
#define assert_near(a, b, tol) assert_near_at((a), (b), (tol), __FILE__, __LINE__)
static void assert_near_at(double a, double b, double tol, const char *file, int line)
{
	if (!(fabs(a - b) <= tol)) {
		print_error("%.17g != %.17g (tol %g)\n", a, b, tol);
		_fail(file, line);
	}
}

/* ---- fixtures --------------------------------------------------------------- */

static void can_defaults(struct mlip_can_config *c, const char *profile)
{
	memset(c, 0, sizeof(*c));
	strncpy(c->profile, profile, sizeof(c->profile) - 1);
	c->bitrate = 1000000;
	c->data_bitrate = 5000000;
	c->sync_id = 0x080;
	c->rpdo_base = 0x200;
	c->packed_base = 0x300;
	c->fd_id = 0x400;
	c->status_id = 0x180;
}

static void machine(struct mlip_machine *m, int n)
{
	static const char letters[] = "XYZABC";
	int i;

	memset(m, 0, sizeof(*m));
	m->n_axes = n;
	for (i = 0; i < n; i++) {
		m->axis[i].letter = letters[i];
		m->axis[i].kind = i < 3 ? MLIP_AXIS_LINEAR : MLIP_AXIS_ROTARY;
		m->axis[i].can_node = i + 1;
		m->axis[i].counts_per_unit = 1000.0;
	}
}

static void encoder(struct mlip_canenc *e, const char *profile, int n)
{
	struct mlip_can_config c;
	struct mlip_machine m;

	can_defaults(&c, profile);
	machine(&m, n);
	assert_int_equal(mlip_canenc_init(e, &c, &m), MLIP_OK);
}

/* ---- golden vectors (same as tests/py/test_dbc.py) ---------------------------- */

static const double golden_pos[6] = {12.345, -0.001, -250.5, 90.0, 1000.0, -2147483.648};
static const uint8_t golden_le[6][4] = {
    {0x39, 0x30, 0x00, 0x00}, /* 12345 */
    {0xff, 0xff, 0xff, 0xff}, /* -1 */
    {0x7c, 0x2d, 0xfc, 0xff}, /* -250500 */
    {0x90, 0x5f, 0x01, 0x00}, /* 90000 */
    {0x40, 0x42, 0x0f, 0x00}, /* 1000000 */
    {0x00, 0x00, 0x00, 0x80}, /* INT32_MIN */
};
static const uint8_t golden_cycle[4] = {0x78, 0x56, 0x34, 0x12};
#define GOLDEN_CYCLE 0x12345678u

static void test_golden_cia402(void **state)
{
	struct mlip_canenc e;
	struct mlip_can_frame f[MLIP_CAN_MAX_FRAMES];
	int n, i;

	(void)state;
	encoder(&e, "cia402", 6);
	assert_int_equal(
	    mlip_canenc_encode(&e, GOLDEN_CYCLE, golden_pos, f, MLIP_CAN_MAX_FRAMES, &n, NULL),
	    MLIP_OK);
	assert_int_equal(n, 7);
	assert_int_equal(f[0].id, 0x080);
	assert_int_equal(f[0].len, 0);
	assert_int_equal(f[0].flags, 0);
	for (i = 0; i < 6; i++) {
		assert_int_equal(f[1 + i].id, 0x201 + i);
		assert_int_equal(f[1 + i].len, 4);
		assert_int_equal(f[1 + i].flags, 0);
		assert_memory_equal(f[1 + i].data, golden_le[i], 4);
	}
}

static void test_golden_packed(void **state)
{
	struct mlip_canenc e;
	struct mlip_can_frame f[MLIP_CAN_MAX_FRAMES];
	int n, k;

	(void)state;
	encoder(&e, "packed", 6);
	assert_int_equal(
	    mlip_canenc_encode(&e, GOLDEN_CYCLE, golden_pos, f, MLIP_CAN_MAX_FRAMES, &n, NULL),
	    MLIP_OK);
	assert_int_equal(n, 4);
	for (k = 0; k < 3; k++) {
		assert_int_equal(f[k].id, 0x300 + k);
		assert_int_equal(f[k].len, 8);
		assert_int_equal(f[k].flags, 0);
		assert_memory_equal(f[k].data, golden_le[2 * k], 4);
		assert_memory_equal(f[k].data + 4, golden_le[2 * k + 1], 4);
	}
	assert_int_equal(f[3].id, 0x303);
	assert_int_equal(f[3].len, 4);
	assert_memory_equal(f[3].data, golden_cycle, 4);
}

static void test_golden_fd(void **state)
{
	static const uint8_t zero[4] = {0, 0, 0, 0};
	struct mlip_canenc e;
	struct mlip_can_frame f[MLIP_CAN_MAX_FRAMES];
	int n, i;

	(void)state;
	encoder(&e, "fd", 6);
	assert_int_equal(
	    mlip_canenc_encode(&e, GOLDEN_CYCLE, golden_pos, f, MLIP_CAN_MAX_FRAMES, &n, NULL),
	    MLIP_OK);
	assert_int_equal(n, 1);
	assert_int_equal(f[0].id, 0x400);
	assert_int_equal(f[0].flags, MLIP_CAN_FLAG_FD | MLIP_CAN_FLAG_BRS);
	assert_int_equal(f[0].len, 32);
	assert_memory_equal(f[0].data, golden_cycle, 4);
	for (i = 0; i < 6; i++) {
		assert_memory_equal(f[0].data + 4 + 4 * i, golden_le[i], 4);
	}
	assert_memory_equal(f[0].data + 28, zero, 4); /* padding */
}

/* ---- round trips -------------------------------------------------------------- */

static uint64_t rng_state;

static double uniform(double lo, double hi)
{
	rng_state = rng_state * 6364136223846793005ull + 1442695040888963407ull;
	return lo + (hi - lo) * (double)(rng_state >> 11) / 9007199254740992.0;
}

static void roundtrip(const char *profile)
{
	struct mlip_canenc e;
	struct mlip_can_frame f[MLIP_CAN_MAX_FRAMES];
	struct mlip_can_setpoint sp;
	double pos[MLIP_MAX_AXES];
	int32_t want;
	int n_axes, trial, i, n;
	uint32_t cycle;

	rng_state = 12345;
	for (n_axes = 2; n_axes <= 6; n_axes++) {
		encoder(&e, profile, n_axes);
		for (trial = 0; trial < 2000; trial++) {
			/* mostly small, some near the int32 ends (+-2.1e6 mm at 1000/mm) */
			double span = trial % 10 == 0 ? 2147483.0 : 1000.0;

			for (i = 0; i < n_axes; i++) {
				pos[i] = uniform(-span, span);
			}
			cycle = (uint32_t)(0xFFFFFFF0u + (uint32_t)trial); /* wraps too */
			assert_int_equal(
			    mlip_canenc_encode(&e, cycle, pos, f, MLIP_CAN_MAX_FRAMES, &n, NULL),
			    MLIP_OK);
			assert_int_equal(n, mlip_canenc_frames(&e));
			assert_int_equal(mlip_canenc_decode(&e, f, n, &sp), MLIP_OK);
			assert_int_equal(sp.n_axes, n_axes);
			if (e.profile != MLIP_CAN_CIA402) {
				assert_int_equal(sp.cycle, cycle);
			}
			for (i = 0; i < n_axes; i++) {
				assert_int_equal(mlip_can_counts(pos[i], 1000.0, &want), MLIP_OK);
				assert_int_equal(sp.counts[i], want);
				/* quantisation: within half a count, both sides */
				assert_true(fabs(sp.pos[i] - pos[i]) <= 0.0005 + 1e-9);
			}
		}
	}
}

static void test_roundtrip_cia402(void **state)
{
	(void)state;
	roundtrip("cia402");
}

static void test_roundtrip_packed(void **state)
{
	(void)state;
	roundtrip("packed");
}

static void test_roundtrip_fd(void **state)
{
	(void)state;
	roundtrip("fd");
}

/* odd axis counts: the last packed POS frame carries one axis, len 4 */
static void test_packed_odd(void **state)
{
	struct mlip_canenc e;
	struct mlip_can_frame f[MLIP_CAN_MAX_FRAMES];
	const double pos[5] = {1, 2, 3, 4, -5};
	int n;

	(void)state;
	encoder(&e, "packed", 5);
	assert_int_equal(mlip_canenc_encode(&e, 7, pos, f, MLIP_CAN_MAX_FRAMES, &n, NULL), MLIP_OK);
	assert_int_equal(n, 4);
	assert_int_equal(f[2].id, 0x302);
	assert_int_equal(f[2].len, 4);
	assert_int_equal(f[3].id, 0x303);
	assert_int_equal(f[3].len, 4);
	assert_int_equal(f[3].data[0], 7);
	encoder(&e, "packed", 1);
	assert_int_equal(mlip_canenc_frames(&e), 2);
}

/* ---- counts: rounding and saturation ------------------------------------------ */

static void test_counts_rounding(void **state)
{
	int32_t c;

	(void)state;
	/* ties away from zero (exact binary values) */
	assert_int_equal(mlip_can_counts(0.125, 4.0, &c), MLIP_OK);
	assert_int_equal(c, 1);
	assert_int_equal(mlip_can_counts(-0.125, 4.0, &c), MLIP_OK);
	assert_int_equal(c, -1);
	assert_int_equal(mlip_can_counts(0.375, 4.0, &c), MLIP_OK);
	assert_int_equal(c, 2);
	/* both sides of a half count */
	assert_int_equal(mlip_can_counts(0.0024999, 1000.0, &c), MLIP_OK);
	assert_int_equal(c, 2);
	assert_int_equal(mlip_can_counts(0.0025001, 1000.0, &c), MLIP_OK);
	assert_int_equal(c, 3);
	assert_int_equal(mlip_can_counts(-0.0024999, 1000.0, &c), MLIP_OK);
	assert_int_equal(c, -2);
	assert_int_equal(mlip_can_counts(-0.0025001, 1000.0, &c), MLIP_OK);
	assert_int_equal(c, -3);
	assert_int_equal(mlip_can_counts(0.0, 1000.0, &c), MLIP_OK);
	assert_int_equal(c, 0);
	assert_int_equal(mlip_can_counts(-0.0, 1000.0, &c), MLIP_OK);
	assert_int_equal(c, 0);
	/* rotary: 8 counts per degree, -359.9375 deg = -2879.5 counts exactly */
	assert_int_equal(mlip_can_counts(-359.9375, 8.0, &c), MLIP_OK);
	assert_int_equal(c, -2880);
}

static void test_counts_saturation(void **state)
{
	int32_t c;

	(void)state;
	/* upper end: largest value that rounds into int32, then the first that does not */
	assert_int_equal(mlip_can_counts(2147483647.4, 1.0, &c), MLIP_OK);
	assert_int_equal(c, INT32_MAX);
	assert_int_equal(mlip_can_counts(2147483647.5, 1.0, &c), MLIP_E_RANGE);
	assert_int_equal(c, INT32_MAX);
	assert_int_equal(mlip_can_counts(1e300, 1.0, &c), MLIP_E_RANGE);
	assert_int_equal(c, INT32_MAX);
	assert_int_equal(mlip_can_counts(INFINITY, 1.0, &c), MLIP_E_RANGE);
	assert_int_equal(c, INT32_MAX);
	/* lower end */
	assert_int_equal(mlip_can_counts(-2147483648.4, 1.0, &c), MLIP_OK);
	assert_int_equal(c, INT32_MIN);
	assert_int_equal(mlip_can_counts(-2147483648.5, 1.0, &c), MLIP_E_RANGE);
	assert_int_equal(c, INT32_MIN);
	assert_int_equal(mlip_can_counts(-INFINITY, 1.0, &c), MLIP_E_RANGE);
	assert_int_equal(c, INT32_MIN);
	/* in mm at 1000 counts/mm: 2147483.647 mm fits, 2147483.648 does not */
	assert_int_equal(mlip_can_counts(2147483.647, 1000.0, &c), MLIP_OK);
	assert_int_equal(c, INT32_MAX);
	assert_int_equal(mlip_can_counts(2147483.648, 1000.0, &c), MLIP_E_RANGE);
	assert_int_equal(mlip_can_counts(NAN, 1000.0, &c), MLIP_E_RANGE);
	assert_int_equal(c, 0);
}

static void test_encode_saturation_reported(void **state)
{
	struct mlip_canenc e;
	struct mlip_can_frame f[MLIP_CAN_MAX_FRAMES];
	struct mlip_can_setpoint sp;
	double pos[3] = {1.0, 3e6, -3e6};
	uint32_t sat = 0;
	int n;

	(void)state;
	encoder(&e, "fd", 3);
	assert_int_equal(mlip_canenc_encode(&e, 1, pos, f, MLIP_CAN_MAX_FRAMES, &n, &sat),
	                 MLIP_E_RANGE);
	assert_int_equal(sat, 0x6);
	assert_int_equal(n, 1); /* frames complete, for diagnosis; not to be sent */
	assert_int_equal(mlip_canenc_decode(&e, f, n, &sp), MLIP_OK);
	assert_int_equal(sp.counts[0], 1000);
	assert_int_equal(sp.counts[1], INT32_MAX);
	assert_int_equal(sp.counts[2], INT32_MIN);
	pos[1] = NAN;
	pos[2] = 0.0;
	assert_int_equal(mlip_canenc_encode(&e, 1, pos, f, MLIP_CAN_MAX_FRAMES, &n, &sat),
	                 MLIP_E_RANGE);
	assert_int_equal(sat, 0x2);
	pos[1] = 2147483.647; /* just inside */
	assert_int_equal(mlip_canenc_encode(&e, 1, pos, f, MLIP_CAN_MAX_FRAMES, &n, &sat), MLIP_OK);
	assert_int_equal(sat, 0);
	/* too small an output array: nothing written */
	encoder(&e, "cia402", 6);
	assert_int_equal(mlip_canenc_encode(&e, 1, golden_pos, f, 6, &n, NULL), MLIP_E_FULL);
	assert_int_equal(n, 0);
}

/* ---- lengths, names, init ------------------------------------------------------ */

static void test_fd_len(void **state)
{
	static const int want[65] = {
	    0,  1,  2,  3,  4,  5,  6,  7,  8,  12, 12, 12, 12, 16, 16, 16, 16, 20, 20, 20, 20, 24,
	    24, 24, 24, 32, 32, 32, 32, 32, 32, 32, 32, 48, 48, 48, 48, 48, 48, 48, 48, 48, 48, 48,
	    48, 48, 48, 48, 48, 64, 64, 64, 64, 64, 64, 64, 64, 64, 64, 64, 64, 64, 64, 64, 64};
	struct mlip_canenc e;
	size_t n;
	int axes;

	(void)state;
	for (n = 0; n <= 64; n++) {
		assert_int_equal(mlip_can_fd_len(n), want[n]);
	}
	assert_int_equal(mlip_can_fd_len(65), -1);
	/* the fd profile: 4 + 4n bytes, rounded up */
	for (axes = 1; axes <= 6; axes++) {
		static const int len[7] = {0, 8, 12, 16, 20, 24, 32};
		struct mlip_can_frame f[1];
		double pos[MLIP_MAX_AXES] = {0};
		int nf;

		encoder(&e, "fd", axes);
		assert_int_equal(mlip_canenc_encode(&e, 0, pos, f, 1, &nf, NULL), MLIP_OK);
		assert_int_equal(f[0].len, len[axes]);
	}
}

static void test_profile_names(void **state)
{
	mlip_can_profile p;

	(void)state;
	assert_int_equal(mlip_can_profile_parse("cia402", &p), MLIP_OK);
	assert_int_equal(p, MLIP_CAN_CIA402);
	assert_int_equal(mlip_can_profile_parse("packed", &p), MLIP_OK);
	assert_int_equal(p, MLIP_CAN_PACKED);
	assert_int_equal(mlip_can_profile_parse("fd", &p), MLIP_OK);
	assert_int_equal(p, MLIP_CAN_FD);
	assert_int_equal(mlip_can_profile_parse("CiA402", &p), MLIP_E_INVALID);
	assert_int_equal(mlip_can_profile_parse("", &p), MLIP_E_INVALID);
	assert_int_equal(mlip_can_profile_parse(NULL, &p), MLIP_E_INVALID);
	assert_string_equal(mlip_can_profile_name(MLIP_CAN_PACKED), "packed");
	assert_string_equal(mlip_can_profile_name((mlip_can_profile)7), "?");
}

static void test_init_rejects(void **state)
{
	struct mlip_can_config c;
	struct mlip_machine m;
	struct mlip_canenc e;

	(void)state;
	can_defaults(&c, "cia402");
	machine(&m, 3);
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_OK);
	strcpy(c.profile, "canopen");
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	memcpy(c.profile, "cia402xx", 8); /* no terminator in the 8 bytes */
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	can_defaults(&c, "cia402");
	/* node ids: 1..127, distinct */
	m.axis[1].can_node = 0;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	m.axis[1].can_node = 128;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	m.axis[1].can_node = 127;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_OK);
	m.axis[1].can_node = 1;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	machine(&m, 3);
	/* ids beyond 11 bits, or colliding with SYNC / status */
	c.rpdo_base = 0x7FD; /* node 3 -> 0x800 */
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	c.rpdo_base = 0x7FC; /* node 3 -> 0x7FF: fits */
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_OK);
	c.rpdo_base = 0xFFFFFFFFu; /* would wrap to 0, 1, 2 */
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	c.rpdo_base = 0x07F; /* node 1 -> 0x080 = SYNC */
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	c.rpdo_base = 0x17F; /* node 1 -> 0x180 = status */
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	/* node ids do not matter to packed and fd */
	can_defaults(&c, "packed");
	m.axis[0].can_node = 0;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_OK);
	c.packed_base = 0x7FD; /* 3 axes: 0x7FD, 0x7FE (pos), 0x7FF (commit) */
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_OK);
	c.packed_base = 0x7FE;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	can_defaults(&c, "fd");
	c.fd_id = 0x800;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	c.fd_id = 0x180;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	/* no bit-rate switch unless the data phase is faster */
	can_defaults(&c, "fd");
	c.data_bitrate = c.bitrate;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_OK);
	assert_int_equal(e.fd_flags, MLIP_CAN_FLAG_FD);
	/* axes and scales */
	can_defaults(&c, "fd");
	m.n_axes = 0;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	m.n_axes = MLIP_MAX_AXES + 1;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	machine(&m, 3);
	m.axis[2].counts_per_unit = 0.0;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	m.axis[2].counts_per_unit = -1000.0;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	m.axis[2].counts_per_unit = NAN;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
	m.axis[2].counts_per_unit = INFINITY;
	assert_int_equal(mlip_canenc_init(&e, &c, &m), MLIP_E_INVALID);
}

/* ---- streaming decoder: gaps ------------------------------------------------------- */

static void test_decoder_packed_gaps(void **state)
{
	struct mlip_canenc e;
	struct mlip_candec d;
	struct mlip_can_frame f[MLIP_CAN_MAX_FRAMES], other;
	struct mlip_can_setpoint sp;
	double pos[6] = {1, 2, 3, 4, 5, 6};
	int n, k;

	(void)state;
	encoder(&e, "packed", 6);
	mlip_candec_init(&d, &e);
	memset(&other, 0, sizeof(other));
	other.id = 0x181; /* someone else's frame */
	other.len = 8;
	/* cycle 10: complete, with a foreign frame in between */
	mlip_canenc_encode(&e, 10, pos, f, MLIP_CAN_MAX_FRAMES, &n, NULL);
	assert_int_equal(mlip_candec_feed(&d, &f[0], &sp), MLIP_E_EMPTY);
	assert_int_equal(mlip_candec_feed(&d, &other, &sp), MLIP_E_EMPTY);
	for (k = 1; k < n - 1; k++) {
		assert_int_equal(mlip_candec_feed(&d, &f[k], &sp), MLIP_E_EMPTY);
	}
	assert_int_equal(mlip_candec_feed(&d, &f[n - 1], &sp), MLIP_OK);
	assert_int_equal(sp.cycle, 10);
	assert_int_equal(sp.counts[5], 6000);
	assert_int_equal(d.foreign, 1);
	/* cycle 11: POS1 lost -> incomplete at COMMIT */
	mlip_canenc_encode(&e, 11, pos, f, MLIP_CAN_MAX_FRAMES, &n, NULL);
	assert_int_equal(mlip_candec_feed(&d, &f[0], &sp), MLIP_E_EMPTY);
	assert_int_equal(mlip_candec_feed(&d, &f[2], &sp), MLIP_E_EMPTY);
	assert_int_equal(mlip_candec_feed(&d, &f[3], &sp), MLIP_E_EMPTY);
	assert_int_equal(d.incomplete, 1);
	assert_int_equal(d.lost, 0);
	/* cycle 12: COMMIT lost; cycle 13 complete -> one more incomplete, one lost */
	mlip_canenc_encode(&e, 12, pos, f, MLIP_CAN_MAX_FRAMES, &n, NULL);
	for (k = 0; k < n - 1; k++) {
		assert_int_equal(mlip_candec_feed(&d, &f[k], &sp), MLIP_E_EMPTY);
	}
	pos[0] = -7.5;
	mlip_canenc_encode(&e, 13, pos, f, MLIP_CAN_MAX_FRAMES, &n, NULL);
	for (k = 0; k < n - 1; k++) {
		assert_int_equal(mlip_candec_feed(&d, &f[k], &sp), MLIP_E_EMPTY);
	}
	assert_int_equal(d.incomplete, 2);
	assert_int_equal(mlip_candec_feed(&d, &f[n - 1], &sp), MLIP_OK);
	assert_int_equal(sp.cycle, 13);
	assert_near(sp.pos[0], -7.5, 1e-12);
	assert_int_equal(d.lost, 1);
	/* cycles 14..16 lost entirely, 17 arrives */
	mlip_canenc_encode(&e, 17, pos, f, MLIP_CAN_MAX_FRAMES, &n, NULL);
	for (k = 0; k < n; k++) {
		mlip_candec_feed(&d, &f[k], &sp);
	}
	assert_int_equal(d.lost, 4);
	assert_int_equal(d.complete, 3);
	/* malformed: our id, wrong length */
	f[1].len = 7;
	assert_int_equal(mlip_candec_feed(&d, &f[1], &sp), MLIP_E_SYNTAX);
	assert_int_equal(d.malformed, 1);
	assert_int_equal(mlip_canenc_decode(&e, f, n, &sp), MLIP_E_SYNTAX);
}

static void test_decoder_fd_gaps(void **state)
{
	struct mlip_canenc e;
	struct mlip_candec d;
	struct mlip_can_frame f[1];
	struct mlip_can_setpoint sp;
	const double pos[2] = {0.5, -0.5};
	/* wraps, and skips 0, 3 and 4 */
	const uint32_t cycles[5] = {0xFFFFFFFEu, 0xFFFFFFFFu, 1u, 2u, 5u};
	int n, k;

	(void)state;
	encoder(&e, "fd", 2);
	mlip_candec_init(&d, &e);
	for (k = 0; k < 5; k++) {
		mlip_canenc_encode(&e, cycles[k], pos, f, 1, &n, NULL);
		assert_int_equal(mlip_candec_feed(&d, &f[0], &sp), MLIP_OK);
		assert_int_equal(sp.cycle, cycles[k]);
		assert_int_equal(sp.counts[1], -500);
	}
	assert_int_equal(d.lost, 3);
	assert_int_equal(d.complete, 5);
	f[0].flags = 0; /* not an FD frame */
	assert_int_equal(mlip_candec_feed(&d, &f[0], &sp), MLIP_E_SYNTAX);
	f[0].flags = MLIP_CAN_FLAG_FD;
	f[0].len = 16;
	assert_int_equal(mlip_candec_feed(&d, &f[0], &sp), MLIP_E_SYNTAX);
	f[0].len = 12;
	assert_int_equal(mlip_candec_feed(&d, &f[0], &sp), MLIP_OK); /* BRS optional */
	f[0].flags = MLIP_CAN_FLAG_FD | MLIP_CAN_FLAG_EFF;           /* 29-bit: not ours */
	assert_int_equal(mlip_candec_feed(&d, &f[0], &sp), MLIP_E_EMPTY);
	assert_int_equal(d.foreign, 1);
}

static void test_decoder_cia402_gaps(void **state)
{
	struct mlip_canenc e;
	struct mlip_candec d;
	struct mlip_can_frame f[2 * MLIP_CAN_MAX_FRAMES];
	struct mlip_can_setpoint sp;
	const double pos[3] = {1, -2, 3};
	int n, k;

	(void)state;
	encoder(&e, "cia402", 3);
	mlip_candec_init(&d, &e);
	mlip_canenc_encode(&e, 0, pos, f, MLIP_CAN_MAX_FRAMES, &n, NULL);
	/* an RPDO before any SYNC is stray */
	assert_int_equal(mlip_candec_feed(&d, &f[2], &sp), MLIP_E_EMPTY);
	assert_int_equal(d.stray, 1);
	/* SYNC + 2 of 3 RPDOs, then SYNC: incomplete */
	assert_int_equal(mlip_candec_feed(&d, &f[0], &sp), MLIP_E_EMPTY);
	assert_int_equal(mlip_candec_feed(&d, &f[1], &sp), MLIP_E_EMPTY);
	assert_int_equal(mlip_candec_feed(&d, &f[3], &sp), MLIP_E_EMPTY);
	assert_int_equal(d.incomplete, 0);
	assert_int_equal(mlip_candec_feed(&d, &f[0], &sp), MLIP_E_EMPTY);
	assert_int_equal(d.incomplete, 1);
	/* complete period, RPDOs in any order */
	assert_int_equal(mlip_candec_feed(&d, &f[3], &sp), MLIP_E_EMPTY);
	assert_int_equal(mlip_candec_feed(&d, &f[1], &sp), MLIP_E_EMPTY);
	assert_int_equal(mlip_candec_feed(&d, &f[2], &sp), MLIP_OK);
	assert_int_equal(sp.cycle, 1); /* second SYNC seen */
	assert_int_equal(sp.counts[1], -2000);
	/* an extra RPDO after completion: stray; lost SYNC: RPDO twice */
	assert_int_equal(mlip_candec_feed(&d, &f[1], &sp), MLIP_E_EMPTY);
	assert_int_equal(d.stray, 2);
	assert_int_equal(mlip_candec_feed(&d, &f[0], &sp), MLIP_E_EMPTY);
	assert_int_equal(mlip_candec_feed(&d, &f[1], &sp), MLIP_E_EMPTY);
	assert_int_equal(mlip_candec_feed(&d, &f[1], &sp), MLIP_E_EMPTY);
	assert_int_equal(d.incomplete, 2);
	/* malformed SYNC */
	f[0].len = 1;
	assert_int_equal(mlip_candec_feed(&d, &f[0], &sp), MLIP_E_SYNTAX);
	/* one-shot decode refuses partial or padded input */
	f[0].len = 0;
	assert_int_equal(mlip_canenc_decode(&e, f, n - 1, &sp), MLIP_E_SYNTAX);
	assert_int_equal(mlip_canenc_decode(&e, f + 1, n - 1, &sp), MLIP_E_SYNTAX);
	assert_int_equal(mlip_canenc_decode(&e, f, n, &sp), MLIP_OK);
	for (k = 0; k < n; k++) {
		f[n + k] = f[k];
	}
	assert_int_equal(mlip_canenc_decode(&e, f, 2 * n, &sp), MLIP_E_SYNTAX);
}

/* ---- bus load, computed by hand --------------------------------------------------------- */

static void test_frame_bits(void **state)
{
	struct mlip_can_bits b;

	(void)state;
	/* classic base: 8n + 47 + floor((33 + 8n) / 4) */
	b = mlip_can_frame_bits(0, 0);
	assert_int_equal(b.nominal, 55); /* 47 + 8 */
	assert_int_equal(b.data, 0);
	assert_int_equal(mlip_can_frame_bits(0, 4).nominal, 95);   /* 32 + 47 + 16 */
	assert_int_equal(mlip_can_frame_bits(0, 8).nominal, 135);  /* 64 + 47 + 24 */
	assert_int_equal(mlip_can_frame_bits(0, 1).nominal, 65);   /* 8 + 47 + 10 */
	assert_int_equal(mlip_can_frame_bits(0, 15).nominal, 135); /* classic: at most 8 */
	/* classic extended: 8n + 67 + floor((53 + 8n) / 4); 160 is Davis' 8-byte figure */
	assert_int_equal(mlip_can_frame_bits(MLIP_CAN_FLAG_EFF, 8).nominal, 160);
	assert_int_equal(mlip_can_frame_bits(MLIP_CAN_FLAG_EFF, 0).nominal, 80);
	/* FD base with BRS, 32 bytes: nominal 17 + 3 + 13 = 33;
	 * data 5 + 256 + (floor(277/4) - 3 = 66) + 4 + 21 + 7 = 359 */
	b = mlip_can_frame_bits(MLIP_CAN_FLAG_FD | MLIP_CAN_FLAG_BRS, 32);
	assert_int_equal(b.nominal, 33);
	assert_int_equal(b.data, 359);
	/* 12 bytes: 5 + 96 + (29 - 3) + 4 + 17 + 6 = 154 */
	b = mlip_can_frame_bits(MLIP_CAN_FLAG_FD | MLIP_CAN_FLAG_BRS, 12);
	assert_int_equal(b.nominal, 33);
	assert_int_equal(b.data, 154);
	/* CRC-17 up to 16 bytes, CRC-21 from 20: 16 -> 20 adds 32 data + 4 CRC + 1 FSB + 8 stuff */
	assert_int_equal(mlip_can_frame_bits(MLIP_CAN_FLAG_FD | MLIP_CAN_FLAG_BRS, 16).data,
	                 5 + 128 + (37 - 3) + 4 + 17 + 6);
	assert_int_equal(mlip_can_frame_bits(MLIP_CAN_FLAG_FD | MLIP_CAN_FLAG_BRS, 20).data,
	                 5 + 160 + (45 - 3) + 4 + 21 + 7);
	/* totals equal Linux can_frame_bits(fd, sff, stuffing, intermission): 0 -> 67, 64 -> 712 */
	b = mlip_can_frame_bits(MLIP_CAN_FLAG_FD | MLIP_CAN_FLAG_BRS, 0);
	assert_int_equal(b.nominal + b.data, 67);
	b = mlip_can_frame_bits(MLIP_CAN_FLAG_FD | MLIP_CAN_FLAG_BRS, 64);
	assert_int_equal(b.nominal + b.data, 712);
	/* without BRS every bit is nominal */
	b = mlip_can_frame_bits(MLIP_CAN_FLAG_FD, 32);
	assert_int_equal(b.nominal, 392);
	assert_int_equal(b.data, 0);
	/* FD invalid length counted as the next valid one */
	assert_int_equal(mlip_can_frame_bits(MLIP_CAN_FLAG_FD | MLIP_CAN_FLAG_BRS, 10).data,
	                 mlip_can_frame_bits(MLIP_CAN_FLAG_FD | MLIP_CAN_FLAG_BRS, 12).data);
	/* FD extended: header 41, 36 bits before BRS with 8 stuff bits there */
	b = mlip_can_frame_bits(MLIP_CAN_FLAG_FD | MLIP_CAN_FLAG_BRS | MLIP_CAN_FLAG_EFF, 8);
	assert_int_equal(b.nominal, 36 + 8 + 13);
	assert_int_equal(b.data, 5 + 64 + (26 - 8) + 4 + 17 + 6);
}

static void test_bus_load_by_hand(void **state)
{
	struct mlip_can_load l;

	(void)state;
	/* the brief's example: cia402, 3 axes, 1 Mbit/s, 1 ms:
	 * SYNC 55 + 3 x 95 = 340 bits = 340 us -> 0.34 */
	assert_near(mlip_can_bus_load(MLIP_CAN_CIA402, 3, 1000000, 5000000, 0.001), 0.340, 1e-9);
	/* 6 axes: 55 + 6 x 95 = 625 */
	assert_near(mlip_can_bus_load(MLIP_CAN_CIA402, 6, 1000000, 0, 0.001), 0.625, 1e-9);
	/* 500 kbit/s doubles it, 2 ms halves it */
	assert_near(mlip_can_bus_load(MLIP_CAN_CIA402, 3, 500000, 0, 0.002), 0.340, 1e-9);
	/* packed 6 axes: 3 x 135 + COMMIT 95 = 500; 5 axes: 2 x 135 + 95 + 95 = 460 */
	assert_near(mlip_can_bus_load(MLIP_CAN_PACKED, 6, 1000000, 0, 0.001), 0.500, 1e-9);
	assert_near(mlip_can_bus_load(MLIP_CAN_PACKED, 5, 1000000, 0, 0.001), 0.460, 1e-9);
	/* fd 6 axes, 1 / 5 Mbit/s: 33 us + 359 / 5 us = 104.8 us */
	assert_near(mlip_can_bus_load(MLIP_CAN_FD, 6, 1000000, 5000000, 0.001), 0.1048, 1e-9);
	/* fd without a faster data phase: 392 bits at 1 Mbit/s */
	assert_near(mlip_can_bus_load(MLIP_CAN_FD, 6, 1000000, 1000000, 0.001), 0.392, 1e-9);
	/* fd 2 axes (12 bytes), 500 k / 2 M: 33 / 0.5 + 154 / 2 = 66 + 77 = 143 us per 0.5 ms */
	assert_near(mlip_can_bus_load(MLIP_CAN_FD, 2, 500000, 2000000, 0.0005), 0.286, 1e-9);
	/* over 1: does not fit */
	assert_near(mlip_can_bus_load(MLIP_CAN_CIA402, 6, 125000, 0, 0.001), 5.0, 1e-9);

	/* breakdown */
	assert_int_equal(mlip_can_load_breakdown(MLIP_CAN_CIA402, 3, 1000000, 5000000, 0.001, &l),
	                 MLIP_OK);
	assert_int_equal(l.frames, 4);
	assert_int_equal(l.data_bytes, 12);
	assert_int_equal(l.bits_nominal, 340);
	assert_int_equal(l.bits_data, 0);
	assert_near(l.busy_s, 340e-6, 1e-15);
	assert_near(l.load_pct, 34.0, 1e-9);
	assert_int_equal(l.frame[0].len, 0);
	assert_int_equal(l.frame[0].bits.nominal, 55);
	assert_near(l.frame[0].time_s, 55e-6, 1e-15);
	assert_int_equal(l.frame[3].bits.nominal, 95);
	assert_int_equal(mlip_can_load_breakdown(MLIP_CAN_FD, 6, 1000000, 5000000, 0.001, &l),
	                 MLIP_OK);
	assert_int_equal(l.frames, 1);
	assert_int_equal(l.data_bytes, 32);
	assert_int_equal(l.bits_nominal, 33);
	assert_int_equal(l.bits_data, 359);
	assert_int_equal(l.frame[0].flags, MLIP_CAN_FLAG_FD | MLIP_CAN_FLAG_BRS);

	/* invalid arguments */
	assert_near(mlip_can_bus_load(MLIP_CAN_CIA402, 0, 1000000, 0, 0.001), -1.0, 0.0);
	assert_near(mlip_can_bus_load(MLIP_CAN_CIA402, 7, 1000000, 0, 0.001), -1.0, 0.0);
	assert_near(mlip_can_bus_load(MLIP_CAN_CIA402, 3, 0, 0, 0.001), -1.0, 0.0);
	assert_near(mlip_can_bus_load(MLIP_CAN_CIA402, 3, 1000000, 0, 0.0), -1.0, 0.0);
	assert_near(mlip_can_bus_load(MLIP_CAN_CIA402, 3, 1000000, 0, NAN), -1.0, 0.0);
	assert_near(mlip_can_bus_load((mlip_can_profile)9, 3, 1000000, 0, 0.001), -1.0, 0.0);
}

/* the load breakdown describes exactly the frames the encoder sends */
static void test_load_matches_encoder(void **state)
{
	static const char *const names[] = {"cia402", "packed", "fd"};
	struct mlip_canenc e;
	struct mlip_can_frame f[MLIP_CAN_MAX_FRAMES];
	struct mlip_can_load l;
	double pos[MLIP_MAX_AXES] = {0};
	mlip_status st;
	int p, axes, n, k;

	(void)state;
	for (p = 0; p < 3; p++) {
		for (axes = 1; axes <= MLIP_MAX_AXES; axes++) {
			encoder(&e, names[p], axes);
			st = mlip_canenc_encode(&e, 0, pos, f, MLIP_CAN_MAX_FRAMES, &n, NULL);
			assert_int_equal(st, MLIP_OK);
			assert_int_equal(
			    mlip_can_load_breakdown(e.profile, axes, 1000000, 5000000, 0.001, &l),
			    MLIP_OK);
			assert_int_equal(l.frames, n);
			for (k = 0; k < n; k++) {
				assert_int_equal(l.frame[k].len, f[k].len);
				assert_int_equal(l.frame[k].flags, f[k].flags);
			}
		}
	}
}

int main(void)
{
	const struct CMUnitTest tests[] = {
	    cmocka_unit_test(test_golden_cia402),
	    cmocka_unit_test(test_golden_packed),
	    cmocka_unit_test(test_golden_fd),
	    cmocka_unit_test(test_roundtrip_cia402),
	    cmocka_unit_test(test_roundtrip_packed),
	    cmocka_unit_test(test_roundtrip_fd),
	    cmocka_unit_test(test_packed_odd),
	    cmocka_unit_test(test_counts_rounding),
	    cmocka_unit_test(test_counts_saturation),
	    cmocka_unit_test(test_encode_saturation_reported),
	    cmocka_unit_test(test_fd_len),
	    cmocka_unit_test(test_profile_names),
	    cmocka_unit_test(test_init_rejects),
	    cmocka_unit_test(test_decoder_packed_gaps),
	    cmocka_unit_test(test_decoder_fd_gaps),
	    cmocka_unit_test(test_decoder_cia402_gaps),
	    cmocka_unit_test(test_frame_bits),
	    cmocka_unit_test(test_bus_load_by_hand),
	    cmocka_unit_test(test_load_matches_encoder),
	};

	return cmocka_run_group_tests_name("canenc", tests, NULL, NULL);
}
