/*
 * ring.c - SPSC block ring, status seqlocks and command mailbox in a
 * caller-provided (shared) memory segment. See mlip/ipc/ring.h for the layout and
 * the protocol; this file only adds the memory-ordering arguments.
 *
 * Ring (kfifo / DPDK rte_ring, one producer and one consumer):
 *
 *     tail          head                       free-running uint32_t
 *      |             |                         slot = index & mask
 *   ...[ r r r r r r ][ . . . . . . . . ]...   count = head - tail (mod 2^32)
 *      consumer reads  producer writes          space = capacity - count
 *
 *   producer: write records [head, head+n)      then store head+n  (release)
 *   consumer: load head (acquire), copy records then store tail+n  (release)
 *   producer: load tail (acquire) before reusing a slot the consumer freed.
 *
 * Each side keeps a private cached copy of the other side's index on its own
 * cache line (tail_cache, head_cache) and reloads the shared one only when the
 * cache says there is not enough, as in Rigtorp's SPSCQueue: the cached value
 * never runs ahead of the real one, so the check is conservative.
 *
 * Seqlock (status, feeder areas), all accesses atomic:
 *   writer: gen = g+1 (relaxed); fields (release); gen = g+2 (release)
 *   reader: g1 = gen (acquire), even; fields (acquire); g2 = gen; g1 == g2
 * The release stores of the fields order the odd generation before them, and
 * the acquire loads of the fields order the second generation load after them,
 * so no standalone fence is needed (TSan does not model fences).
 */
#include "mlip/ipc/ring.h"

#include <stddef.h>
#include <string.h>

/* ---- compile-time layout checks (Linux kfifo's negative array size) ---- */
#define MLIP_RING_CHECK(name, cond) typedef char mlip_ring_check_##name[(cond) ? 1 : -1]

MLIP_RING_CHECK(rec_size, sizeof(struct mlip_ring_rec) == 88);
MLIP_RING_CHECK(rec_align, sizeof(struct mlip_ring_rec) % 8 == 0);
MLIP_RING_CHECK(rec_target, offsetof(struct mlip_ring_rec, target) == 16);
MLIP_RING_CHECK(hdr_size, sizeof(struct mlip_ring) == 1472);
MLIP_RING_CHECK(off_io, offsetof(struct mlip_ring, io) == 1344);
MLIP_RING_CHECK(io_size, sizeof(struct mlip_ring_io) == 88);
MLIP_RING_CHECK(hdr_lines, sizeof(struct mlip_ring) % MLIP_RING_LINE == 0);
MLIP_RING_CHECK(line_pow2, MLIP_RING_IS_POW2(MLIP_RING_LINE));
MLIP_RING_CHECK(max_pow2, MLIP_RING_IS_POW2(MLIP_RING_MAX_CAPACITY));
MLIP_RING_CHECK(off_head, offsetof(struct mlip_ring, head) == 64);
MLIP_RING_CHECK(off_tail, offsetof(struct mlip_ring, tail) == 128);
MLIP_RING_CHECK(off_status_gen, offsetof(struct mlip_ring, status_gen) == 192);
MLIP_RING_CHECK(off_status, offsetof(struct mlip_ring, status) == 208);
MLIP_RING_CHECK(status_size, sizeof(struct mlip_ring_status) == 440);
MLIP_RING_CHECK(off_feeder_gen, offsetof(struct mlip_ring, feeder_gen) == 704);
MLIP_RING_CHECK(off_feeder, offsetof(struct mlip_ring, feeder) == 712);
MLIP_RING_CHECK(feeder_size, sizeof(struct mlip_ring_feeder) == 40);
MLIP_RING_CHECK(off_cmd, offsetof(struct mlip_ring, cmd_word) == 768);
MLIP_RING_CHECK(off_stop, offsetof(struct mlip_ring, stop_req) == 776);
MLIP_RING_CHECK(off_machine, offsetof(struct mlip_ring, machine) == 832);

/* shared-memory atomics must not fall back to a process-local lock */
#if !defined(__GCC_ATOMIC_LLONG_LOCK_FREE) || __GCC_ATOMIC_LLONG_LOCK_FREE != 2 ||                 \
    !defined(__GCC_ATOMIC_INT_LOCK_FREE) || __GCC_ATOMIC_INT_LOCK_FREE != 2
#error "mlip ring needs always lock-free 32- and 64-bit atomics"
#endif

#define LD(p, mo)    __atomic_load_n((p), (mo))
#define ST(p, v, mo) __atomic_store_n((p), (v), (mo))
/* doubles: the generic builtins (8 bytes, lock-free like the integers) */
#define STD(p, v)    __atomic_store((p), (v), __ATOMIC_RELEASE)
#define LDD(p, v)    __atomic_load((p), (v), __ATOMIC_ACQUIRE)
#define ACQ          __ATOMIC_ACQUIRE
#define REL          __ATOMIC_RELEASE
#define RLX          __ATOMIC_RELAXED

static uint64_t ring_magic(void)
{
	uint64_t m;

	memcpy(&m, MLIP_RING_MAGIC, sizeof(m));
	return m;
}

const char *mlip_ring_reason_str(mlip_ring_reason reason)
{
	switch (reason) {
	case MLIP_RING_MATCH:
		return "match";
	case MLIP_RING_BAD_ARG:
		return "null argument";
	case MLIP_RING_BAD_ALIGN:
		return "segment alignment";
	case MLIP_RING_SHORT:
		return "segment size (header)";
	case MLIP_RING_BAD_MAGIC:
		return "magic";
	case MLIP_RING_BAD_VERSION:
		return "layout version";
	case MLIP_RING_BAD_RECORD:
		return "record size";
	case MLIP_RING_BAD_HEADER:
		return "header size";
	case MLIP_RING_BAD_CAPACITY:
		return "capacity";
	case MLIP_RING_BAD_AXES:
		return "axis count";
	case MLIP_RING_TRUNCATED:
		return "segment size (records)";
	}
	return "?";
}

static int capacity_ok(uint32_t capacity)
{
	return capacity != 0 && (capacity & (capacity - 1u)) == 0 &&
	       capacity <= MLIP_RING_MAX_CAPACITY;
}

size_t mlip_ring_bytes(uint32_t capacity)
{
	if (!capacity_ok(capacity)) {
		return 0;
	}
	return sizeof(struct mlip_ring) + (size_t)capacity * sizeof(struct mlip_ring_rec);
}

static struct mlip_ring_rec *slot(struct mlip_ring *r, uint32_t index)
{
	return (struct mlip_ring_rec *)(void *)(r + 1) + (index & r->mask);
}

static mlip_status format(void *mem, size_t bytes, uint32_t capacity, int n_axes,
                          const struct mlip_machine *m)
{
	struct mlip_ring *r = mem;

	if (mem == NULL || ((uintptr_t)mem & (MLIP_RING_LINE - 1)) != 0 || !capacity_ok(capacity) ||
	    n_axes < 1 || n_axes > MLIP_MAX_AXES || bytes < mlip_ring_bytes(capacity)) {
		return MLIP_E_INVALID;
	}
	ST(&r->magic, 0, REL); /* unformatted while we write */
	memset((char *)mem + sizeof(r->magic), 0, sizeof(*r) - sizeof(r->magic));
	r->version = MLIP_RING_VERSION;
	r->capacity = capacity;
	r->mask = capacity - 1;
	r->rec_bytes = (uint32_t)sizeof(struct mlip_ring_rec);
	r->hdr_bytes = (uint32_t)sizeof(struct mlip_ring);
	r->n_axes = (uint32_t)n_axes;
	r->status.override_pct = 100;
	if (m != NULL) {
		r->machine = *m;
	}
	ST(&r->magic, ring_magic(), REL);
	return MLIP_OK;
}

mlip_status mlip_ring_format(void *mem, size_t bytes, uint32_t capacity, int n_axes)
{
	return format(mem, bytes, capacity, n_axes, NULL);
}

mlip_status mlip_ring_format_machine(void *mem, size_t bytes, uint32_t capacity,
                                     const struct mlip_machine *m)
{
	if (m == NULL) {
		return MLIP_E_INVALID;
	}
	return format(mem, bytes, capacity, m->n_axes, m);
}

void mlip_ring_machine(const struct mlip_ring *r, struct mlip_machine *out)
{
	*out = r->machine; /* immutable once the magic is published */
}

void mlip_ring_io_publish(struct mlip_ring *r, const struct mlip_ring_io *io)
{
	struct mlip_ring_io *d = &r->io;
	int i;

	ST(&d->spindle, io->spindle, RLX);
	ST(&d->tool_change, io->tool_change, RLX);
	ST(&d->coolant, io->coolant, RLX);
	ST(&d->change_mask, io->change_mask, RLX);
	ST(&d->outputs, io->outputs, RLX);
	STD(&d->min_rpm, &io->min_rpm);
	STD(&d->max_rpm, &io->max_rpm);
	for (i = 0; i < MLIP_MAX_AXES; i++) {
		STD(&d->change_pos[i], &io->change_pos[i]);
	}
	ST(&d->published, 1u, REL);
}

mlip_status mlip_ring_io_read(const struct mlip_ring *r, struct mlip_ring_io *out)
{
	const struct mlip_ring_io *d = &r->io;
	int i;

	memset(out, 0, sizeof(*out));
	if (LD(&d->published, ACQ) != 1u) {
		return MLIP_E_EMPTY;
	}
	out->published = 1;
	out->spindle = LD(&d->spindle, RLX);
	out->tool_change = LD(&d->tool_change, RLX);
	out->coolant = LD(&d->coolant, RLX);
	out->change_mask = LD(&d->change_mask, RLX);
	out->outputs = LD(&d->outputs, RLX);
	LDD(&d->min_rpm, &out->min_rpm);
	LDD(&d->max_rpm, &out->max_rpm);
	for (i = 0; i < MLIP_MAX_AXES; i++) {
		LDD(&d->change_pos[i], &out->change_pos[i]);
	}
	return MLIP_OK;
}

static mlip_status refuse(struct mlip_ring_mismatch *why, mlip_ring_reason reason, uint64_t found,
                          uint64_t expected)
{
	if (why != NULL) {
		why->reason = reason;
		why->found = found;
		why->expected = expected;
	}
	return MLIP_E_INVALID;
}

mlip_status mlip_ring_attach(void *mem, size_t bytes, int n_axes, struct mlip_ring **out,
                             struct mlip_ring_mismatch *why)
{
	struct mlip_ring *r = mem;
	uint64_t magic;

	if (out == NULL) {
		return refuse(why, MLIP_RING_BAD_ARG, 0, 0);
	}
	*out = NULL;
	if (mem == NULL) {
		return refuse(why, MLIP_RING_BAD_ARG, 0, 0);
	}
	if (((uintptr_t)mem & (MLIP_RING_LINE - 1)) != 0) {
		return refuse(why, MLIP_RING_BAD_ALIGN, (uintptr_t)mem & (MLIP_RING_LINE - 1), 0);
	}
	if (bytes < sizeof(struct mlip_ring)) {
		return refuse(why, MLIP_RING_SHORT, bytes, sizeof(struct mlip_ring));
	}
	magic = LD(&r->magic, ACQ); /* pairs with the release in format */
	if (magic != ring_magic()) {
		return refuse(why, MLIP_RING_BAD_MAGIC, magic, ring_magic());
	}
	if (r->version != MLIP_RING_VERSION) {
		return refuse(why, MLIP_RING_BAD_VERSION, r->version, MLIP_RING_VERSION);
	}
	if (r->rec_bytes != sizeof(struct mlip_ring_rec)) {
		return refuse(why, MLIP_RING_BAD_RECORD, r->rec_bytes,
		              sizeof(struct mlip_ring_rec));
	}
	if (r->hdr_bytes != sizeof(struct mlip_ring)) {
		return refuse(why, MLIP_RING_BAD_HEADER, r->hdr_bytes, sizeof(struct mlip_ring));
	}
	if (!capacity_ok(r->capacity) || r->mask != r->capacity - 1) {
		return refuse(why, MLIP_RING_BAD_CAPACITY, r->capacity, MLIP_RING_MAX_CAPACITY);
	}
	if (r->n_axes < 1 || r->n_axes > MLIP_MAX_AXES ||
	    (n_axes != 0 && r->n_axes != (uint32_t)n_axes)) {
		return refuse(why, MLIP_RING_BAD_AXES, r->n_axes,
		              n_axes != 0 ? (uint64_t)n_axes : MLIP_MAX_AXES);
	}
	if (bytes < mlip_ring_bytes(r->capacity)) {
		return refuse(why, MLIP_RING_TRUNCATED, bytes, mlip_ring_bytes(r->capacity));
	}
	if (why != NULL) {
		why->reason = MLIP_RING_MATCH;
		why->found = 0;
		why->expected = 0;
	}
	*out = r;
	return MLIP_OK;
}

/* ---- ring ------------------------------------------------------------ */

uint32_t mlip_ring_push_n(struct mlip_ring *r, const struct mlip_ring_rec *recs, uint32_t n)
{
	uint32_t head = LD(&r->head, RLX); /* ours */
	uint32_t space = r->capacity - (head - r->tail_cache);
	uint32_t first;

	if (space < n) {
		r->tail_cache = LD(&r->tail, ACQ); /* slots before tail are free */
		space = r->capacity - (head - r->tail_cache);
	}
	if (n > space) {
		n = space;
	}
	if (n == 0) {
		return 0;
	}
	/* copy in at most two runs: up to the end of the array, then from 0 */
	first = r->capacity - (head & r->mask);
	if (first > n) {
		first = n;
	}
	memcpy(slot(r, head), recs, first * sizeof(*recs));
	if (n > first) {
		memcpy(slot(r, head + first), recs + first, (n - first) * sizeof(*recs));
	}
	ST(&r->head, head + n, REL); /* publishes the records */
	return n;
}

mlip_status mlip_ring_push(struct mlip_ring *r, const struct mlip_ring_rec *rec)
{
	return mlip_ring_push_n(r, rec, 1) == 1 ? MLIP_OK : MLIP_E_FULL;
}

/* Consumer: records available, reloading head only when the cache is short. */
static uint32_t avail(struct mlip_ring *r, uint32_t tail, uint32_t want)
{
	uint32_t n = r->head_cache - tail;

	if (n < want) {
		r->head_cache = LD(&r->head, ACQ); /* records before head are written */
		n = r->head_cache - tail;
	}
	if (n > r->capacity) { /* a broken producer: never read past a lap */
		n = r->capacity;
	}
	return n;
}

uint32_t mlip_ring_pop_n(struct mlip_ring *r, struct mlip_ring_rec *out, uint32_t max)
{
	uint32_t tail = LD(&r->tail, RLX); /* ours */
	uint32_t n = avail(r, tail, max);
	uint32_t first;

	if (n > max) {
		n = max;
	}
	if (n == 0) {
		return 0;
	}
	if (out != NULL) {
		first = r->capacity - (tail & r->mask);
		if (first > n) {
			first = n;
		}
		memcpy(out, slot(r, tail), first * sizeof(*out));
		if (n > first) {
			memcpy(out + first, slot(r, tail + first), (n - first) * sizeof(*out));
		}
	}
	ST(&r->tail, tail + n, REL); /* hands the slots back to the producer */
	return n;
}

mlip_status mlip_ring_pop(struct mlip_ring *r, struct mlip_ring_rec *out)
{
	return mlip_ring_pop_n(r, out, 1) == 1 ? MLIP_OK : MLIP_E_EMPTY;
}

mlip_status mlip_ring_peek(struct mlip_ring *r, struct mlip_ring_rec *out)
{
	uint32_t tail = LD(&r->tail, RLX);

	if (avail(r, tail, 1) == 0) {
		return MLIP_E_EMPTY;
	}
	*out = *slot(r, tail);
	return MLIP_OK;
}

uint32_t mlip_ring_count(const struct mlip_ring *r)
{
	/* tail first: head read later is >= the head of that moment, so the
	 * difference is never negative; it may exceed a lap, hence the clamp */
	uint32_t tail = LD(&r->tail, ACQ);
	uint32_t head = LD(&r->head, ACQ);
	uint32_t n = head - tail;

	return n > r->capacity ? r->capacity : n;
}

uint32_t mlip_ring_space(const struct mlip_ring *r)
{
	return r->capacity - mlip_ring_count(r);
}

void mlip_ring_reset(struct mlip_ring *r, uint32_t index)
{
	ST(&r->head, index, REL);
	ST(&r->tail, index, REL);
	r->tail_cache = index;
	r->head_cache = index;
}

/* ---- ports ------------------------------------------------------------ */

mlip_status mlip_ring_port_open(struct mlip_ring_port *p, struct mlip_ring *r, int producer)
{
	uint32_t cap = r->capacity;

	memset(p, 0, sizeof(*p));
	if (!capacity_ok(cap) || r->n_axes < 1 || r->n_axes > MLIP_MAX_AXES) {
		return MLIP_E_INVALID;
	}
	p->r = r;
	p->capacity = cap;
	p->mask = cap - 1u;
	p->n_axes = r->n_axes;
	p->producer = producer != 0;
	p->own = LD(producer ? &r->head : &r->tail, ACQ);
	p->other = LD(producer ? &r->tail : &r->head, ACQ);
	return MLIP_OK;
}

/* Reload the other side's index; the distance between the two must be a
 * count in 0..capacity. */
static mlip_status port_reload(struct mlip_ring_port *p, uint32_t *apart)
{
	uint32_t other = LD(p->producer ? &p->r->tail : &p->r->head, ACQ);
	uint32_t n = p->producer ? p->own - other : other - p->own;

	if (n > p->capacity) {
		if (apart != NULL) {
			*apart = n;
		}
		return MLIP_E_RANGE;
	}
	p->other = other;
	return MLIP_OK;
}

mlip_status mlip_ring_port_count(struct mlip_ring_port *p, uint32_t *n, uint32_t *apart)
{
	*n = 0;
	if (port_reload(p, apart) != MLIP_OK) {
		return MLIP_E_RANGE;
	}
	*n = p->producer ? p->capacity - (p->own - p->other) : p->other - p->own;
	return MLIP_OK;
}

mlip_status mlip_ring_port_view(struct mlip_ring_port *p, struct mlip_rec_view *v, uint32_t *apart)
{
	const struct mlip_ring_rec *recs = (const struct mlip_ring_rec *)(const void *)(p->r + 1);

	memset(v, 0, sizeof(*v));
	if (port_reload(p, apart) != MLIP_OK) {
		return MLIP_E_RANGE;
	}
	uint32_t n = p->other - p->own, at = p->own & p->mask;
	uint32_t first = n < p->capacity - at ? n : p->capacity - at;
	v->span[0] = recs + at;
	v->len[0] = first;
	v->span[1] = recs;
	v->len[1] = n - first;
	return MLIP_OK;
}

mlip_status mlip_ring_port_pop_n(struct mlip_ring_port *p, uint32_t n)
{
	if (n > p->other - p->own) {
		return MLIP_E_RANGE; /* more than were there */
	}
	p->own += n;
	ST(&p->r->tail, p->own, REL); /* hands the slots back to the producer */
	return MLIP_OK;
}

mlip_status mlip_ring_port_push_n(struct mlip_ring_port *p, const struct mlip_ring_rec *recs,
                                  uint32_t n, uint32_t *pushed)
{
	struct mlip_ring_rec *slots = (struct mlip_ring_rec *)(void *)(p->r + 1);
	uint32_t space;

	*pushed = 0;
	if (mlip_ring_port_count(p, &space, NULL) != MLIP_OK) {
		return MLIP_E_RANGE;
	}
	if (n > space) {
		n = space;
	}
	for (uint32_t i = 0; i < n; i++) {
		slots[(p->own + i) & p->mask] = recs[i];
	}
	p->own += n;
	ST(&p->r->head, p->own, REL); /* publishes the records */
	*pushed = n;
	return MLIP_OK;
}

/* block kind <-> record type: the same events in both (types.h) */
static const uint16_t kind_type[] = {
    MLIP_REC_MOVE, MLIP_REC_DWELL,   MLIP_REC_PAUSE,  MLIP_REC_OPTIONAL_PAUSE, MLIP_REC_SPINDLE,
    MLIP_REC_TOOL, MLIP_REC_COOLANT, MLIP_REC_OUTPUT, MLIP_REC_PROBE,          MLIP_REC_SPEED};

void mlip_ring_rec_from_block(struct mlip_ring_rec *rec, const struct mlip_block *b, uint64_t seq)
{
	int i;

	memset(rec, 0, sizeof(*rec));
	rec->seq = seq;
	rec->line = b->line;
	/* an unknown kind stays unknown: the controller refuses it */
	rec->type = b->kind < sizeof(kind_type) / sizeof(kind_type[0]) ? kind_type[b->kind]
	                                                               : (uint16_t)MLIP_REC_TYPES;
	rec->flags =
	    (uint16_t)((b->rapid ? MLIP_REC_RAPID : 0u) | (b->exact_stop ? MLIP_REC_EXACT : 0u));
	for (i = 0; i < MLIP_MAX_AXES; i++) {
		rec->target[i] = b->target[i];
	}
	rec->feed_mm_s = b->feed_mm_s;
	rec->tol_mm = b->tol_mm;
	rec->dwell_s = b->kind >= MLIP_BLOCK_SPINDLE ? b->value : b->dwell_s;
}

void mlip_ring_rec_end(struct mlip_ring_rec *rec, uint64_t seq, uint32_t line)
{
	memset(rec, 0, sizeof(*rec));
	rec->seq = seq;
	rec->line = line;
	rec->type = MLIP_REC_END;
}

mlip_status mlip_ring_rec_to_block(const struct mlip_ring_rec *rec, struct mlip_block *b)
{
	int i;
	uint8_t kind;

	switch (rec->type) {
	case MLIP_REC_END:
		return MLIP_E_EMPTY;
	case MLIP_REC_MOVE:
		kind = MLIP_BLOCK_MOVE;
		break;
	case MLIP_REC_DWELL:
		kind = MLIP_BLOCK_DWELL;
		break;
	case MLIP_REC_PAUSE:
		kind = MLIP_BLOCK_PAUSE;
		break;
	case MLIP_REC_OPTIONAL_PAUSE:
		kind = MLIP_BLOCK_OPTIONAL_PAUSE;
		break;
	case MLIP_REC_SPINDLE:
		kind = MLIP_BLOCK_SPINDLE;
		break;
	case MLIP_REC_TOOL:
		kind = MLIP_BLOCK_TOOL;
		break;
	case MLIP_REC_COOLANT:
		kind = MLIP_BLOCK_COOLANT;
		break;
	case MLIP_REC_OUTPUT:
		kind = MLIP_BLOCK_OUTPUT;
		break;
	case MLIP_REC_PROBE:
		kind = MLIP_BLOCK_PROBE;
		break;
	case MLIP_REC_SPEED:
		kind = MLIP_BLOCK_SPEED;
		break;
	default:
		return MLIP_E_INVALID;
	}
	memset(b, 0, sizeof(*b));
	for (i = 0; i < MLIP_MAX_AXES; i++) {
		b->target[i] = rec->target[i];
	}
	b->feed_mm_s = rec->feed_mm_s;
	b->tol_mm = rec->tol_mm;
	b->seq = rec->seq;
	b->line = rec->line;
	b->rapid = (rec->flags & MLIP_REC_RAPID) ? 1 : 0;
	b->kind = kind;
	b->exact_stop = (rec->flags & MLIP_REC_EXACT) ? 1 : 0;
	if (kind >= MLIP_BLOCK_SPINDLE) {
		b->value = rec->dwell_s;
	} else {
		b->dwell_s = rec->dwell_s;
	}
	return MLIP_OK;
}

/* ---- status and feeder seqlocks -------------------------------------- */

void mlip_ring_status_write(struct mlip_ring *r, const struct mlip_ring_status *s)
{
	struct mlip_ring_status *d = &r->status;
	uint32_t g = LD(&r->status_gen, RLX); /* only we write it */

	ST(&r->status_gen, g + 1, RLX);
	ST(&d->heartbeat, s->heartbeat, REL);
	ST(&d->heartbeat_ns, s->heartbeat_ns, REL);
	ST(&d->exec_seq, s->exec_seq, REL);
	ST(&d->exec_line, s->exec_line, REL);
	ST(&d->state, s->state, REL);
	ST(&d->override_pct, s->override_pct, REL);
	ST(&d->reserved, s->reserved, REL);
	ST(&d->overruns, s->overruns, REL);
	ST(&d->underruns, s->underruns, REL);
	ST(&d->can_tx_errors, s->can_tx_errors, REL);
	ST(&d->can_bus_errors, s->can_bus_errors, REL);
	ST(&d->frames_sent, s->frames_sent, REL);
	ST(&d->blocks_consumed, s->blocks_consumed, REL);
	ST(&d->stop_nm, s->stop_nm, REL);
	ST(&d->stop_periods, s->stop_periods, REL);
	ST(&d->stops, s->stops, REL);
	ST(&d->reason, s->reason, REL);
	ST(&d->reason_field, s->reason_field, REL);
	ST(&d->reason_seq, s->reason_seq, REL);
	ST(&d->reason_line, s->reason_line, REL);
	ST(&d->optional_stop, s->optional_stop, REL);
	STD(&d->reason_value, &s->reason_value);
	for (int k = 0; k < MLIP_MAX_AXES; k++) {
		STD(&d->pos[k], &s->pos[k]);
	}
	STD(&d->speed_mm_s, &s->speed_mm_s);
	ST(&d->dwell_left, s->dwell_left, REL);
	ST(&d->reason_node, s->reason_node, REL);
	ST(&d->actual_mask, s->actual_mask, REL);
	for (int k = 0; k < MLIP_MAX_AXES; k++) {
		STD(&d->pos_actual[k], &s->pos_actual[k]);
	}
	ST(&d->drive_power, s->drive_power, REL);
	ST(&d->drive_power_periods, s->drive_power_periods, REL);
	for (int k = 0; k < MLIP_MAX_AXES; k++) {
		STD(&d->prog_start[k], &s->prog_start[k]);
	}
	ST(&d->stop_seen, s->stop_seen, REL);
	ST(&d->io_inputs, s->io_inputs, REL);
	ST(&d->io_mapped, s->io_mapped, REL);
	ST(&d->io_known, s->io_known, REL);
	ST(&d->homed, s->homed, REL);
	ST(&d->coolant, s->coolant, REL);
	ST(&d->outputs, s->outputs, REL);
	ST(&d->probe_count, s->probe_count, REL);
	ST(&d->probe_tripped, s->probe_tripped, REL);
	ST(&d->probe_line, s->probe_line, REL);
	for (int k = 0; k < MLIP_MAX_AXES; k++) {
		STD(&d->probe_pos[k], &s->probe_pos[k]);
	}
	ST(&d->spindle_state, s->spindle_state, REL);
	STD(&d->spindle_cmd_rpm, &s->spindle_cmd_rpm);
	STD(&d->spindle_actual_rpm, &s->spindle_actual_rpm);
	ST(&d->spindle_override, s->spindle_override, REL);
	ST(&d->spindle_node, s->spindle_node, REL);
	ST(&d->held_by, s->held_by, REL);
	ST(&d->spare12, s->spare12, REL);
	ST(&r->status_gen, g + 2, REL);
}

mlip_status mlip_ring_status_read(const struct mlip_ring *r, struct mlip_ring_status *s)
{
	const struct mlip_ring_status *d = &r->status;
	uint32_t g1, g2;
	int tries;

	for (tries = 0; tries < MLIP_RING_READ_TRIES; tries++) {
		g1 = LD(&r->status_gen, ACQ);
		if (g1 & 1u) {
			continue;
		}
		s->heartbeat = LD(&d->heartbeat, ACQ);
		s->heartbeat_ns = LD(&d->heartbeat_ns, ACQ);
		s->exec_seq = LD(&d->exec_seq, ACQ);
		s->exec_line = LD(&d->exec_line, ACQ);
		s->state = LD(&d->state, ACQ);
		s->override_pct = LD(&d->override_pct, ACQ);
		s->reserved = LD(&d->reserved, ACQ);
		s->overruns = LD(&d->overruns, ACQ);
		s->underruns = LD(&d->underruns, ACQ);
		s->can_tx_errors = LD(&d->can_tx_errors, ACQ);
		s->can_bus_errors = LD(&d->can_bus_errors, ACQ);
		s->frames_sent = LD(&d->frames_sent, ACQ);
		s->blocks_consumed = LD(&d->blocks_consumed, ACQ);
		s->stop_nm = LD(&d->stop_nm, ACQ);
		s->stop_periods = LD(&d->stop_periods, ACQ);
		s->stops = LD(&d->stops, ACQ);
		s->reason = LD(&d->reason, ACQ);
		s->reason_field = LD(&d->reason_field, ACQ);
		s->reason_seq = LD(&d->reason_seq, ACQ);
		s->reason_line = LD(&d->reason_line, ACQ);
		s->optional_stop = LD(&d->optional_stop, ACQ);
		LDD(&d->reason_value, &s->reason_value);
		for (int k = 0; k < MLIP_MAX_AXES; k++) {
			LDD(&d->pos[k], &s->pos[k]);
		}
		LDD(&d->speed_mm_s, &s->speed_mm_s);
		s->dwell_left = LD(&d->dwell_left, ACQ);
		s->reason_node = LD(&d->reason_node, ACQ);
		s->actual_mask = LD(&d->actual_mask, ACQ);
		for (int k = 0; k < MLIP_MAX_AXES; k++) {
			LDD(&d->pos_actual[k], &s->pos_actual[k]);
		}
		s->drive_power = LD(&d->drive_power, ACQ);
		s->drive_power_periods = LD(&d->drive_power_periods, ACQ);
		for (int k = 0; k < MLIP_MAX_AXES; k++) {
			LDD(&d->prog_start[k], &s->prog_start[k]);
		}
		s->stop_seen = LD(&d->stop_seen, ACQ);
		s->io_inputs = LD(&d->io_inputs, ACQ);
		s->io_mapped = LD(&d->io_mapped, ACQ);
		s->io_known = LD(&d->io_known, ACQ);
		s->homed = LD(&d->homed, ACQ);
		s->coolant = LD(&d->coolant, ACQ);
		s->outputs = LD(&d->outputs, ACQ);
		s->probe_count = LD(&d->probe_count, ACQ);
		s->probe_tripped = LD(&d->probe_tripped, ACQ);
		s->probe_line = LD(&d->probe_line, ACQ);
		for (int k = 0; k < MLIP_MAX_AXES; k++) {
			LDD(&d->probe_pos[k], &s->probe_pos[k]);
		}
		s->spindle_state = LD(&d->spindle_state, ACQ);
		LDD(&d->spindle_cmd_rpm, &s->spindle_cmd_rpm);
		LDD(&d->spindle_actual_rpm, &s->spindle_actual_rpm);
		s->spindle_override = LD(&d->spindle_override, ACQ);
		s->spindle_node = LD(&d->spindle_node, ACQ);
		s->held_by = LD(&d->held_by, ACQ);
		s->spare12 = LD(&d->spare12, ACQ);
		g2 = LD(&r->status_gen, RLX);
		if (g1 == g2) {
			return MLIP_OK;
		}
	}
	return MLIP_E_EMPTY;
}

void mlip_ring_feeder_write(struct mlip_ring *r, const struct mlip_ring_feeder *f)
{
	struct mlip_ring_feeder *d = &r->feeder;
	uint32_t g = LD(&r->feeder_gen, RLX);

	ST(&r->feeder_gen, g + 1, RLX);
	ST(&d->heartbeat, f->heartbeat, REL);
	ST(&d->heartbeat_ns, f->heartbeat_ns, REL);
	ST(&d->total_blocks, f->total_blocks, REL);
	ST(&d->program_end, f->program_end, REL);
	ST(&d->pid, f->pid, REL);
	ST(&d->stop_base, f->stop_base, REL);
	ST(&d->mdi, f->mdi, REL);
	ST(&r->feeder_gen, g + 2, REL);
}

mlip_status mlip_ring_feeder_read(const struct mlip_ring *r, struct mlip_ring_feeder *f)
{
	const struct mlip_ring_feeder *d = &r->feeder;
	uint32_t g1, g2;
	int tries;

	for (tries = 0; tries < MLIP_RING_READ_TRIES; tries++) {
		g1 = LD(&r->feeder_gen, ACQ);
		if (g1 & 1u) {
			continue;
		}
		f->heartbeat = LD(&d->heartbeat, ACQ);
		f->heartbeat_ns = LD(&d->heartbeat_ns, ACQ);
		f->total_blocks = LD(&d->total_blocks, ACQ);
		f->program_end = LD(&d->program_end, ACQ);
		f->pid = LD(&d->pid, ACQ);
		f->stop_base = LD(&d->stop_base, ACQ);
		f->mdi = LD(&d->mdi, ACQ);
		g2 = LD(&r->feeder_gen, RLX);
		if (g1 == g2) {
			return MLIP_OK;
		}
	}
	return MLIP_E_EMPTY;
}

/* ---- command mailbox --------------------------------------------------- */

#define CMD_SEQ(w) ((uint32_t)(w))
#define CMD_OP(w)  ((uint32_t)((w) >> 32) & 0xffu)
/* the 24-bit field back to a signed value */
#define CMD_ARG(w) ((int32_t)((uint32_t)((w) >> 40) ^ 0x800000u) - 0x800000)

mlip_status mlip_ring_cmd_post(struct mlip_ring *r, mlip_ring_cmd_op op, int32_t arg, uint32_t *seq)
{
	uint64_t w, nw;
	uint32_t s;

	if ((int)op <= (int)MLIP_CMD_NONE || (int)op >= (int)MLIP_CMD_COUNT ||
	    op == MLIP_CMD_STOP) {
		return MLIP_E_INVALID;
	}
	if (arg < MLIP_RING_CMD_ARG_MIN || arg > MLIP_RING_CMD_ARG_MAX) {
		return MLIP_E_RANGE;
	}
	w = LD(&r->cmd_word, ACQ);
	s = CMD_SEQ(w);
	if (s != LD(&r->cmd_done, ACQ)) {
		return MLIP_E_FULL; /* the controller has not completed the last one */
	}
	s = s + 1 == 0 ? 1 : s + 1; /* 0 is "none taken yet" */
	nw = (uint64_t)s | (uint64_t)op << 32 | (uint64_t)((uint32_t)arg & 0xffffffu) << 40;
	/* one word: posted whole or not at all (another mlip-ctl won) */
	if (!__atomic_compare_exchange_n(&r->cmd_word, &w, nw, 0, __ATOMIC_ACQ_REL, ACQ)) {
		return MLIP_E_FULL;
	}
	if (seq != NULL) {
		*seq = s;
	}
	return MLIP_OK;
}

/* commands completed after seq (done - seq, modular), or -1 when seq is not
 * completed yet */
static int64_t done_since(uint32_t done, uint32_t seq)
{
	int32_t d = (int32_t)(done - seq);
	return d < 0 ? -1 : (int64_t)d;
}

mlip_status mlip_ring_cmd_result(const struct mlip_ring *r, uint32_t seq, int32_t *result)
{
	int64_t since = done_since(LD(&r->cmd_done, ACQ), seq);
	if (since < 0) {
		return MLIP_E_EMPTY;
	}
	/* stored before done (release); still ours if no 8 more completed since */
	int32_t res = LD(&r->cmd_results[seq % MLIP_RING_CMD_HISTORY], ACQ);
	since = done_since(LD(&r->cmd_done, ACQ), seq);
	if (since >= (int64_t)MLIP_RING_CMD_HISTORY - 1) {
		return MLIP_E_RANGE;
	}
	*result = res;
	return MLIP_OK;
}

mlip_status mlip_ring_cmd_take(struct mlip_ring *r, struct mlip_ring_cmd *out)
{
	uint64_t w = LD(&r->cmd_word, ACQ);
	uint32_t s = CMD_SEQ(w);

	if (s == LD(&r->cmd_taken, RLX)) {
		return MLIP_E_EMPTY;
	}
	out->seq = s;
	out->op = CMD_OP(w);
	out->arg = CMD_ARG(w);
	ST(&r->cmd_taken, s, RLX);
	return MLIP_OK;
}

void mlip_ring_cmd_done(struct mlip_ring *r, uint32_t seq, int32_t result)
{
	ST(&r->cmd_result, result, RLX);
	ST(&r->cmd_results[seq % MLIP_RING_CMD_HISTORY], result, REL);
	ST(&r->cmd_done, seq, REL); /* lets the next post in */
}

uint32_t mlip_ring_stop_post(struct mlip_ring *r)
{
	return __atomic_add_fetch(&r->stop_req, 1u, __ATOMIC_ACQ_REL);
}

uint32_t mlip_ring_stop_count(const struct mlip_ring *r)
{
	return LD(&r->stop_req, ACQ);
}

int mlip_ring_stop_applied(uint32_t seen, uint32_t ticket)
{
	return (int32_t)(seen - ticket) >= 0;
}

int mlip_ring_stop_after(uint32_t seen, uint32_t stop_base)
{
	return (int32_t)(seen - stop_base) > 0;
}

#define NAME_OF(names, v) ((v) < sizeof(names) / sizeof((names)[0]) ? (names)[v] : "?")

const char *mlip_ring_cmd_name(uint32_t op)
{
	static const char *const names[] = {"none",
	                                    "override",
	                                    "hold",
	                                    "resume",
	                                    "stop",
	                                    "optional-stop",
	                                    "reset",
	                                    "jog",
	                                    "home",
	                                    "jog-axis",
	                                    "spindle-override",
	                                    "spindle-stop"};

	return NAME_OF(names, op);
}

const char *mlip_rec_field_name(uint32_t field)
{
	static const char *const names[] = {
	    "none", "seq",       "type",      "flags",     "feed",      "tol",       "dwell/value",
	    "head", "target[0]", "target[1]", "target[2]", "target[3]", "target[4]", "target[5]"};

	return NAME_OF(names, field);
}

const char *mlip_rec_type_name(uint32_t type)
{
	static const char *const names[] = {"move",           "end",     "dwell", "pause",
	                                    "optional pause", "spindle", "tool",  "coolant",
	                                    "output",         "probe",   "speed"};

	return NAME_OF(names, type);
}
