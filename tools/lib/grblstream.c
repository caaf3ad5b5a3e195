/*
 * grblstream.c - lines to records, one line at a time (grblstream.h).
 */
#include "grblstream.h"

#include <math.h>
#include <string.h>

static void stage_compact(struct grbl_stream *st)
{
	if (st->taken == 0) {
		return;
	}
	memmove(st->stage, st->stage + st->taken, (st->staged - st->taken) * sizeof(st->stage[0]));
	st->staged -= st->taken;
	st->taken = 0;
}

static int stage_room(struct grbl_stream *st)
{
	if (st->staged == GRBL_STAGE) {
		stage_compact(st);
	}
	return st->staged < GRBL_STAGE;
}

static void stage_block(struct grbl_stream *st, const struct mlip_block *b)
{
	st->seq++;
	mlip_ring_rec_from_block(&st->stage[st->staged++], b, st->seq);
	st->last_line = b->line;
	st->open = 1;
}

/* The filter's output into the stage, as far as it fits. */
static void drain(struct grbl_stream *st)
{
	struct mlip_block b;
	while (st->sm != NULL && stage_room(st) && mlip_smooth_stream_pop(&st->ss, &b)) {
		stage_block(st, &b);
	}
}

/* One block of a line into the program: 1 taken, 0 no room now. */
static int give(struct grbl_stream *st, const struct mlip_block *b)
{
	if (st->sm == NULL) {
		if (!stage_room(st)) {
			return 0;
		}
		stage_block(st, b);
		return 1;
	}
	drain(st);
	int r = mlip_smooth_stream_push(&st->ss, b);
	if (r == 0) {
		drain(st);
		r = mlip_smooth_stream_push(&st->ss, b);
	}
	if (r <= 0) {
		return 0; /* the filter's output waits for room in the stage */
	}
	st->open = 1;
	drain(st);
	return 1;
}

void grbl_stream_init(struct grbl_stream *st, const struct mlip_machine *m, const double *pos,
                      struct mlip_smooth *sm)
{
	memset(st, 0, offsetof(struct grbl_stream, stage));
	st->staged = st->taken = 0;
	st->m = *m;
	for (int k = 0; k < m->n_axes; k++) {
		st->m.axis[k].home = pos[k];
	}
	st->sm = m->smooth ? sm : NULL;
	mlip_gcode_init(&st->g, &st->m);
	if (st->sm != NULL) {
		mlip_smooth_stream_start(&st->ss, st->sm, &st->m);
	}
}

void grbl_stream_restart(struct grbl_stream *st, const double *pos, int keep_modes)
{
	struct mlip_gcode old = st->g;
	for (int k = 0; k < st->m.n_axes; k++) {
		st->m.axis[k].home = pos[k];
	}
	if (keep_modes) {
		memcpy(st->g.pos, pos, sizeof(double) * (size_t)st->m.n_axes);
		memcpy(st->g.cur, pos, sizeof(double) * (size_t)st->m.n_axes);
	} else {
		/* Grbl's gc_init at a reset: the parser's defaults; the work
		 * coordinate systems and G28/G30 stay (EEPROM), G92 does not */
		mlip_gcode_init(&st->g, &st->m);
		mlip_gcode_set_io(&st->g, old.io);
		st->g.off = old.off;
		st->g.off.select = 0;
		st->g.off.g92_on = 0;
		memset(st->g.off.g92, 0, sizeof(st->g.off.g92));
		st->g.initial_feed_word = old.initial_feed_word;
	}
	st->open = 0;
	st->seq = 0;
	st->partial = 0;
	st->end_pending = 0;
	st->flush_end = 0;
	st->m2 = 0;
	st->staged = st->taken = 0;
	if (st->sm != NULL) {
		mlip_smooth_stream_start(&st->ss, st->sm, &st->m);
	}
}

static int count_sink(void *ctx, const struct mlip_block *b)
{
	(void)b;
	(*(size_t *)ctx)++;
	return 0;
}

mlip_status grbl_stream_check(const struct grbl_stream *st, const char *text, size_t len,
                              uint32_t lineno, struct mlip_gcode_error *err)
{
	struct mlip_gcode g = st->g;
	size_t n = 0;
	return mlip_gcode_line(&g, text, len, lineno, count_sink, &n, err);
}

mlip_status grbl_stream_dry(struct grbl_stream *st, const char *text, size_t len, uint32_t lineno,
                            struct mlip_gcode_error *err)
{
	struct mlip_gcode g = st->g;
	size_t n = 0;
	mlip_status rc = mlip_gcode_line(&g, text, len, lineno, count_sink, &n, err);
	if (rc == MLIP_OK) {
		st->g = g;
		if (st->g.ended) {
			st->g.ended = 0; /* check mode runs on after M2/M30, as Grbl */
		}
	}
	return rc;
}

static int emit_sink(void *ctx, const struct mlip_block *b)
{
	struct grbl_stream *st = ctx;
	if (st->count++ < st->given) {
		return 0; /* given by an earlier part of this line */
	}
	if (!give(st, b)) {
		st->full = 1;
		return 1;
	}
	st->given++;
	return 0;
}

/* Grbl's M2/M30 (gcode.c, "program end"): motion G1, G17, G90, G94, G54;
 * units, F and G92 stay. The next line starts a new program. */
static void program_end_modes(struct grbl_stream *st)
{
	st->g.ended = 0;
	st->g.motion = 1;
	st->g.cycle = 0;
	st->g.cycle_off = 0;
	st->g.plane = 17;
	st->g.absolute = 1;
	st->g.inverse_time = 0;
	st->g.off.select = 0;
}

static int emit(struct grbl_stream *st)
{
	struct mlip_gcode_error err;
	st->g = st->before;
	st->count = 0;
	st->full = 0;
	mlip_status rc =
	    mlip_gcode_line(&st->g, st->text, st->len, st->lineno, emit_sink, st, &err);
	if (st->full) {
		st->g = st->before;
		return 0;
	}
	(void)rc; /* checked before: the same line from the same state */
	st->g = st->after;
	st->partial = 0;
	if (st->g.ended) {
		program_end_modes(st);
		st->m2 = 1;
		return grbl_stream_end(st);
	}
	return 1;
}

int grbl_stream_line(struct grbl_stream *st, const char *text, size_t len, uint32_t lineno,
                     struct mlip_gcode_error *err)
{
	struct mlip_gcode g = st->g;
	size_t n = 0;
	st->m2 = 0;
	if (len > MLIP_GCODE_MAX_LINE) {
		len = MLIP_GCODE_MAX_LINE + 1; /* the reader refuses it by its length */
	}
	if (mlip_gcode_line(&g, text, len, lineno, count_sink, &n, err) != MLIP_OK) {
		return -1;
	}
	st->before = st->g;
	st->after = g;
	memcpy(st->text, text, len);
	st->len = len;
	st->lineno = lineno;
	st->given = 0;
	st->partial = 1;
	return emit(st);
}

int grbl_stream_more(struct grbl_stream *st)
{
	if (st->end_pending) {
		if (!grbl_stream_flush(st, 0)) {
			return 0;
		}
	}
	return st->partial ? emit(st) : 1;
}

int grbl_stream_ended(const struct grbl_stream *st)
{
	return st->m2;
}

int grbl_stream_flush(struct grbl_stream *st, int with_end)
{
	if (st->sm != NULL && st->ss.started && !st->ss.finished) {
		mlip_smooth_stream_finish(&st->ss);
	}
	st->flush_end |= with_end;
	drain(st);
	if (!stage_room(st)) {
		st->end_pending = 1; /* the filter's rest, or END, waits for room */
		return 0;
	}
	st->end_pending = 0;
	if (st->flush_end && st->open) {
		mlip_ring_rec_end(&st->stage[st->staged++], st->seq + 1, st->last_line);
		st->open = 0;
		st->seq = 0;
		st->programs++;
		for (int k = 0; k < st->m.n_axes; k++) {
			st->m.axis[k].home = st->g.pos[k];
		}
	}
	st->flush_end = 0;
	if (st->sm != NULL) {
		mlip_smooth_stream_start(&st->ss, st->sm, &st->m);
	}
	return 1;
}

int grbl_stream_end(struct grbl_stream *st)
{
	return grbl_stream_flush(st, 1);
}

int grbl_stream_holding(const struct grbl_stream *st)
{
	return st->sm != NULL && st->ss.started && !st->ss.finished;
}

uint32_t grbl_stream_staged(const struct grbl_stream *st)
{
	return st->staged - st->taken;
}

const struct mlip_ring_rec *grbl_stream_peek(const struct grbl_stream *st)
{
	return &st->stage[st->taken];
}

void grbl_stream_take(struct grbl_stream *st, uint32_t n)
{
	st->taken += n;
	if (st->taken >= st->staged) {
		st->staged = st->taken = 0;
	}
	drain(st);
}

const double *grbl_stream_pos(const struct grbl_stream *st)
{
	return st->g.pos;
}

void grbl_stream_set_io(struct grbl_stream *st, const struct mlip_gcode_io *io)
{
	mlip_gcode_set_io(&st->g, io);
}

void grbl_stream_machine_io(struct grbl_stream *st, double rpm, unsigned coolant)
{
	st->g.spindle = rpm > 0.0 ? 3 : rpm < 0.0 ? 4 : 0;
	if (rpm != 0.0) {
		st->g.s_rpm = fabs(rpm);
	}
	st->g.coolant = coolant;
}
