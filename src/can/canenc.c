/*
 * canenc.c - setpoints -> CAN frames (cia402, packed, fd), frames -> setpoints,
 * and worst-case bus load. Frame layouts and the bit-count formulas, with
 * their sources, are in mlip/can/canenc.h; the formulas are implemented in
 * mlip_can_frame_bits() below, and every profile's frame shapes come from the
 * one function shapes(), so encoder and bus load cannot disagree.
 */
#include "mlip/can/canenc.h"

#include <math.h>
#include <string.h>

/* ---- little-endian fields ------------------------------------------------ */

static void put_u32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)(v & 0xFFu);
	p[1] = (uint8_t)((v >> 8) & 0xFFu);
	p[2] = (uint8_t)((v >> 16) & 0xFFu);
	p[3] = (uint8_t)((v >> 24) & 0xFFu);
}

static uint32_t get_u32(const uint8_t *p)
{
	return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
	       ((uint32_t)p[3] << 24);
}

/* two's complement without implementation-defined conversions */
static void put_i32(uint8_t *p, int32_t v)
{
	put_u32(p, v < 0 ? (uint32_t)0xFFFFFFFFu - (uint32_t)(-(v + 1)) : (uint32_t)v);
}

static int32_t get_i32(const uint8_t *p)
{
	uint32_t u = get_u32(p);

	return u <= 0x7FFFFFFFu ? (int32_t)u : -(int32_t)(0xFFFFFFFFu - u) - 1;
}

/* ---- names, lengths, counts ------------------------------------------------ */

static const char *const profile_names[] = {"cia402", "packed", "fd"};

mlip_status mlip_can_profile_parse(const char *name, mlip_can_profile *out)
{
	int i;

	if (name == NULL) {
		return MLIP_E_INVALID;
	}
	for (i = 0; i < 3; i++) {
		if (strcmp(name, profile_names[i]) == 0) {
			*out = (mlip_can_profile)i;
			return MLIP_OK;
		}
	}
	return MLIP_E_INVALID;
}

const char *mlip_can_profile_name(mlip_can_profile p)
{
	return (int)p >= 0 && (int)p < 3 ? profile_names[p] : "?";
}

int mlip_can_fd_len(size_t n)
{
	static const uint8_t sizes[] = {12, 16, 20, 24, 32, 48, 64};
	size_t i;

	if (n <= 8) {
		return (int)n;
	}
	for (i = 0; i < sizeof(sizes); i++) {
		if (n <= sizes[i]) {
			return sizes[i];
		}
	}
	return -1;
}

mlip_status mlip_can_counts(double pos, double counts_per_unit, int32_t *counts)
{
	double x = pos * counts_per_unit;

	/* round() is ties-away-from-zero, so round(x) fits int32 exactly when
	 * -2^31 - 0.5 < x < 2^31 - 0.5 (both bounds are exact doubles) */
	if (x != x) {
		*counts = 0;
		return MLIP_E_RANGE;
	}
	if (!(x > -2147483648.5)) {
		*counts = INT32_MIN;
		return MLIP_E_RANGE;
	}
	if (!(x < 2147483647.5)) {
		*counts = INT32_MAX;
		return MLIP_E_RANGE;
	}
	*counts = (int32_t)round(x);
	return MLIP_OK;
}

/* ---- frame shapes of one period ---------------------------------------------- */

static int pos_frames(int n_axes)
{
	return (n_axes + 1) / 2;
}

/* flags and length of each frame a profile sends per period, in send order;
 * returns the frame count, or -1 for an unknown profile */
static int shapes(mlip_can_profile p, int n_axes, uint8_t fd_flags, uint8_t *flags, uint8_t *len)
{
	int k, m;

	switch (p) {
	case MLIP_CAN_CIA402:
		flags[0] = 0;
		len[0] = 0; /* SYNC */
		for (k = 0; k < n_axes; k++) {
			flags[1 + k] = 0;
			len[1 + k] = 4;
		}
		return 1 + n_axes;
	case MLIP_CAN_PACKED:
		m = pos_frames(n_axes);
		for (k = 0; k < m; k++) {
			flags[k] = 0;
			len[k] = 2 * k + 1 < n_axes ? 8 : 4;
		}
		flags[m] = 0;
		len[m] = 4; /* COMMIT */
		return m + 1;
	case MLIP_CAN_FD:
		flags[0] = fd_flags;
		len[0] = (uint8_t)mlip_can_fd_len(4u + 4u * (unsigned)n_axes);
		return 1;
	}
	return -1;
}

static uint8_t fd_flags_for(uint32_t bitrate, uint32_t data_bitrate)
{
	return (uint8_t)(MLIP_CAN_FLAG_FD | (data_bitrate > bitrate ? MLIP_CAN_FLAG_BRS : 0u));
}

/* ---- encoder ---------------------------------------------------------------- */

mlip_status mlip_canenc_init(struct mlip_canenc *e, const struct mlip_can_config *can,
                             const struct mlip_machine *m)
{
	char name[sizeof(can->profile) + 1];
	int i, n;

	memset(e, 0, sizeof(*e));
	memcpy(name, can->profile, sizeof(can->profile));
	name[sizeof(can->profile)] = '\0';
	if (mlip_can_profile_parse(name, &e->profile) != MLIP_OK) {
		return MLIP_E_INVALID;
	}
	n = m->n_axes;
	if (n < 1 || n > MLIP_MAX_AXES) {
		return MLIP_E_INVALID;
	}
	/* the identifiers: one set of rules, the INI reader's (mlip/can/canconf.h) */
	if (mlip_can_rules(can, m, NULL) != MLIP_OK) {
		return MLIP_E_INVALID;
	}
	e->n_axes = n;
	e->fd_flags = fd_flags_for(can->bitrate, can->data_bitrate);
	e->sync_id = can->sync_id;
	e->rpdo_base = can->rpdo_base;
	e->packed_base = can->packed_base;
	e->fd_id = can->fd_id;
	for (i = 0; i < n; i++) {
		const struct mlip_axis *a = &m->axis[i];

		if (!isfinite(a->counts_per_unit) || !(a->counts_per_unit > 0.0)) {
			return MLIP_E_INVALID;
		}
		e->counts_per_unit[i] = a->counts_per_unit;
		e->node[i] = (uint8_t)(a->can_node >= 0 && a->can_node <= 255 ? a->can_node : 0);
	}
	return MLIP_OK;
}

int mlip_canenc_frames(const struct mlip_canenc *e)
{
	uint8_t flags[MLIP_CAN_MAX_FRAMES], len[MLIP_CAN_MAX_FRAMES];

	return shapes(e->profile, e->n_axes, e->fd_flags, flags, len);
}

mlip_status mlip_canenc_encode(const struct mlip_canenc *e, uint32_t cycle, const double *pos,
                               struct mlip_can_frame *out, int cap, int *n_out, uint32_t *saturated)
{
	uint8_t flags[MLIP_CAN_MAX_FRAMES], len[MLIP_CAN_MAX_FRAMES];
	int32_t counts[MLIP_MAX_AXES];
	uint32_t sat = 0;
	int i, k, nf;

	*n_out = 0;
	if (saturated != NULL) {
		*saturated = 0;
	}
	nf = shapes(e->profile, e->n_axes, e->fd_flags, flags, len);
	if (nf < 0) {
		return MLIP_E_INVALID;
	}
	if (cap < nf) {
		return MLIP_E_FULL;
	}
	for (i = 0; i < e->n_axes; i++) {
		if (mlip_can_counts(pos[i], e->counts_per_unit[i], &counts[i]) != MLIP_OK) {
			sat |= 1u << i;
		}
	}
	for (k = 0; k < nf; k++) {
		memset(&out[k], 0, sizeof(out[k]));
		out[k].flags = flags[k];
		out[k].len = len[k];
	}
	switch (e->profile) {
	case MLIP_CAN_CIA402:
		out[0].id = e->sync_id;
		for (i = 0; i < e->n_axes; i++) {
			out[1 + i].id = e->rpdo_base + e->node[i];
			if (e->rpdo_controlword) {
				out[1 + i].len = 6;
				out[1 + i].data[0] = (uint8_t)(e->controlword[i] & 0xFFu);
				out[1 + i].data[1] = (uint8_t)(e->controlword[i] >> 8);
				put_i32(out[1 + i].data + 2, counts[i]);
				if (e->rpdo_probe) {
					out[1 + i].len = 8;
					out[1 + i].data[6] = (uint8_t)(e->probe_fn[i] & 0xFFu);
					out[1 + i].data[7] = (uint8_t)(e->probe_fn[i] >> 8);
				}
			} else {
				put_i32(out[1 + i].data, counts[i]);
			}
		}
		break;
	case MLIP_CAN_PACKED:
		for (i = 0; i < e->n_axes; i++) {
			out[i / 2].id = e->packed_base + (uint32_t)(i / 2);
			put_i32(out[i / 2].data + 4 * (i % 2), counts[i]);
		}
		out[nf - 1].id = e->packed_base + (uint32_t)(nf - 1);
		put_u32(out[nf - 1].data, cycle);
		break;
	case MLIP_CAN_FD:
		out[0].id = e->fd_id;
		put_u32(out[0].data, cycle);
		for (i = 0; i < e->n_axes; i++) {
			put_i32(out[0].data + 4 + 4 * i, counts[i]);
		}
		break;
	}
	if (e->profile == MLIP_CAN_CIA402 && e->rpdo_mute != 0) {
		for (i = 0, k = 1; i < e->n_axes; i++) {
			if (!(e->rpdo_mute & (1u << i))) {
				out[k++] = out[1 + i];
			}
		}
		nf = k;
	}
	*n_out = nf;
	if (saturated != NULL) {
		*saturated = sat;
	}
	return sat != 0 ? MLIP_E_RANGE : MLIP_OK;
}

/* ---- decoder ------------------------------------------------------------------ */

void mlip_candec_init(struct mlip_candec *d, const struct mlip_canenc *e)
{
	memset(d, 0, sizeof(*d));
	d->enc = *e;
}

static uint32_t all_bits(int n)
{
	return n >= 32 ? 0xFFFFFFFFu : (1u << n) - 1u;
}

static void deliver(struct mlip_candec *d, uint32_t cycle, struct mlip_can_setpoint *out)
{
	int i;

	out->cycle = cycle;
	out->n_axes = d->enc.n_axes;
	for (i = 0; i < MLIP_MAX_AXES; i++) {
		out->counts[i] = i < d->enc.n_axes ? d->counts[i] : 0;
		out->pos[i] = i < d->enc.n_axes ? d->counts[i] / d->enc.counts_per_unit[i] : 0.0;
	}
	d->complete++;
	d->open = 0;
	d->seen = 0;
}

/* a counter-carrying period closed (complete or not): count skipped ones */
static void counter_step(struct mlip_candec *d, uint32_t cycle)
{
	if (d->have_last && cycle - d->last_cycle - 1u < 0x80000000u) {
		d->lost += cycle - d->last_cycle - 1u;
	}
	d->last_cycle = cycle;
	d->have_last = 1;
}

static mlip_status feed_cia402(struct mlip_candec *d, const struct mlip_can_frame *f,
                               struct mlip_can_setpoint *out)
{
	const struct mlip_canenc *e = &d->enc;
	int i;

	if (f->id == e->sync_id) {
		if (f->len != 0 || f->flags != 0) {
			d->malformed++;
			return MLIP_E_SYNTAX;
		}
		if (d->open) {
			d->incomplete++; /* the previous period never completed */
		}
		d->syncs++;
		d->open = 1;
		d->seen = 0;
		return MLIP_E_EMPTY;
	}
	for (i = 0; i < e->n_axes; i++) {
		if (f->id == e->rpdo_base + e->node[i]) {
			break;
		}
	}
	if (i == e->n_axes) {
		d->foreign++;
		return MLIP_E_EMPTY;
	}
	if (f->len != (e->rpdo_controlword ? (e->rpdo_probe ? 8 : 6) : 4) || f->flags != 0) {
		d->malformed++;
		return MLIP_E_SYNTAX;
	}
	if (!d->open) {
		d->stray++;
		return MLIP_E_EMPTY;
	}
	if (d->seen & (1u << i)) { /* twice in one period: the SYNC between was lost */
		d->incomplete++;
		d->open = 0;
		d->seen = 0;
		return MLIP_E_EMPTY;
	}
	d->seen |= 1u << i;
	d->counts[i] = get_i32(f->data + (e->rpdo_controlword ? 2 : 0));
	if (d->seen == all_bits(e->n_axes)) {
		deliver(d, d->syncs - 1u, out);
		return MLIP_OK;
	}
	return MLIP_E_EMPTY;
}

static mlip_status feed_packed(struct mlip_candec *d, const struct mlip_can_frame *f,
                               struct mlip_can_setpoint *out)
{
	const struct mlip_canenc *e = &d->enc;
	int m = pos_frames(e->n_axes);
	uint32_t k = f->id - e->packed_base, cycle;
	uint8_t want;

	if (f->id < e->packed_base || k > (uint32_t)m) {
		d->foreign++;
		return MLIP_E_EMPTY;
	}
	want = k == (uint32_t)m ? 4 : (2 * (int)k + 1 < e->n_axes ? 8 : 4);
	if (f->len != want || f->flags != 0) {
		d->malformed++;
		return MLIP_E_SYNTAX;
	}
	if (k < (uint32_t)m) {             /* POS frame */
		if (d->seen & (1u << k)) { /* the COMMIT of the open period was lost */
			d->incomplete++;
			d->seen = 0;
		}
		d->seen |= 1u << k;
		d->open = 1;
		d->counts[2 * k] = get_i32(f->data);
		if (2 * (int)k + 1 < e->n_axes) {
			d->counts[2 * k + 1] = get_i32(f->data + 4);
		}
		return MLIP_E_EMPTY;
	}
	cycle = get_u32(f->data); /* COMMIT */
	counter_step(d, cycle);
	if (d->seen != all_bits(m)) {
		d->incomplete++;
		d->open = 0;
		d->seen = 0;
		return MLIP_E_EMPTY;
	}
	deliver(d, cycle, out);
	return MLIP_OK;
}

static mlip_status feed_fd(struct mlip_candec *d, const struct mlip_can_frame *f,
                           struct mlip_can_setpoint *out)
{
	const struct mlip_canenc *e = &d->enc;
	uint32_t cycle;
	int i;

	if (f->id != e->fd_id) {
		d->foreign++;
		return MLIP_E_EMPTY;
	}
	if (!(f->flags & MLIP_CAN_FLAG_FD) || (f->flags & MLIP_CAN_FLAG_EFF) ||
	    f->len != mlip_can_fd_len(4u + 4u * (unsigned)e->n_axes)) {
		d->malformed++;
		return MLIP_E_SYNTAX;
	}
	cycle = get_u32(f->data);
	counter_step(d, cycle);
	for (i = 0; i < e->n_axes; i++) {
		d->counts[i] = get_i32(f->data + 4 + 4 * i);
	}
	deliver(d, cycle, out);
	return MLIP_OK;
}

mlip_status mlip_candec_feed(struct mlip_candec *d, const struct mlip_can_frame *f,
                             struct mlip_can_setpoint *out)
{
	if (f->flags & MLIP_CAN_FLAG_EFF) { /* mlip sends base-format ids only */
		d->foreign++;
		return MLIP_E_EMPTY;
	}
	switch (d->enc.profile) {
	case MLIP_CAN_CIA402:
		return feed_cia402(d, f, out);
	case MLIP_CAN_PACKED:
		return feed_packed(d, f, out);
	case MLIP_CAN_FD:
		return feed_fd(d, f, out);
	}
	return MLIP_E_INVALID;
}

mlip_status mlip_canenc_decode(const struct mlip_canenc *e, const struct mlip_can_frame *f, int n,
                               struct mlip_can_setpoint *out)
{
	struct mlip_candec d;
	mlip_status st = MLIP_E_SYNTAX;
	int i;

	mlip_candec_init(&d, e);
	for (i = 0; i < n; i++) {
		st = mlip_candec_feed(&d, &f[i], out);
		if (d.foreign || d.malformed || d.incomplete || d.stray || d.lost ||
		    (st == MLIP_OK) != (i == n - 1)) {
			return MLIP_E_SYNTAX;
		}
	}
	return st == MLIP_OK ? MLIP_OK : MLIP_E_SYNTAX;
}

/* ---- bus load ------------------------------------------------------------------- */

#define UNSTUFFED_TAIL 13 /* CRC delimiter 1, ACK slot 1, ACK delimiter 1, EOF 7, IFS 3 */

struct mlip_can_bits mlip_can_frame_bits(uint8_t flags, uint8_t len)
{
	struct mlip_can_bits b;
	uint32_t n, g, hdr, arb, stuff, stuff_arb, crc, fsb;
	int fdlen;

	if (!(flags & MLIP_CAN_FLAG_FD)) {
		/* Davis et al. 2007, eq. (1): g + 8n + 13 + floor((g + 8n - 1) / 4) */
		n = len > 8 ? 8u : len;
		g = (flags & MLIP_CAN_FLAG_EFF) ? 54u : 34u;
		b.nominal = g + 8u * n + UNSTUFFED_TAIL + (g + 8u * n - 1u) / 4u;
		b.data = 0;
		return b;
	}
	/* ISO 11898-1:2015 FD frame; see the table in mlip/can/canenc.h */
	fdlen = mlip_can_fd_len(len);
	n = fdlen < 0 ? 64u : (uint32_t)fdlen;
	hdr = (flags & MLIP_CAN_FLAG_EFF) ? 41u : 22u; /* SOF .. DLC */
	arb = hdr - 5u;                                /* SOF .. BRS */
	stuff = (hdr + 8u * n - 1u) / 4u;              /* dynamic, SOF .. data */
	stuff_arb = (arb - 2u) / 4u;                   /* those sent before BRS */
	crc = n <= 16u ? 17u : 21u;
	fsb = n <= 16u ? 6u : 7u;
	b.nominal = arb + stuff_arb + UNSTUFFED_TAIL;
	b.data = 5u + 8u * n + (stuff - stuff_arb) + 4u + crc + fsb;
	if (!(flags & MLIP_CAN_FLAG_BRS)) {
		b.nominal += b.data;
		b.data = 0;
	}
	return b;
}

mlip_status mlip_can_load_breakdown(mlip_can_profile profile, int n_axes, uint32_t bitrate,
                                    uint32_t data_bitrate, double period_s,
                                    struct mlip_can_load *out)
{
	uint8_t flags[MLIP_CAN_MAX_FRAMES], len[MLIP_CAN_MAX_FRAMES];
	uint8_t fdf;
	double data_rate;
	int k, nf;

	memset(out, 0, sizeof(*out));
	if (n_axes < 1 || n_axes > MLIP_MAX_AXES || bitrate == 0 || !isfinite(period_s) ||
	    !(period_s > 0.0)) {
		return MLIP_E_INVALID;
	}
	fdf = fd_flags_for(bitrate, data_bitrate);
	nf = shapes(profile, n_axes, fdf, flags, len);
	if (nf < 0) {
		return MLIP_E_INVALID;
	}
	data_rate = (fdf & MLIP_CAN_FLAG_BRS) ? (double)data_bitrate : (double)bitrate;
	out->frames = nf;
	for (k = 0; k < nf; k++) {
		struct mlip_can_bits b = mlip_can_frame_bits(flags[k], len[k]);

		out->frame[k].flags = flags[k];
		out->frame[k].len = len[k];
		out->frame[k].bits = b;
		out->frame[k].time_s = b.nominal / (double)bitrate + b.data / data_rate;
		out->data_bytes += len[k];
		out->bits_nominal += b.nominal;
		out->bits_data += b.data;
	}
	out->busy_s = out->bits_nominal / (double)bitrate + out->bits_data / data_rate;
	out->load = out->busy_s / period_s;
	out->load_pct = 100.0 * out->load;
	return MLIP_OK;
}

double mlip_can_bus_load(mlip_can_profile profile, int n_axes, uint32_t bitrate,
                         uint32_t data_bitrate, double period_s)
{
	struct mlip_can_load l;

	if (mlip_can_load_breakdown(profile, n_axes, bitrate, data_bitrate, period_s, &l) !=
	    MLIP_OK) {
		return -1.0;
	}
	return l.load;
}
