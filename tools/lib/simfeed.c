/* simfeed.c - see simfeed.h (moved from mlip-sim.c) */
#include "simfeed.h"

#include <stdio.h>

static int program_next(void *ctx, struct mlip_block *b)
{
	struct source *src = ctx;
	if (src->rc < 0 || (src->rc = mlip_program_next(src->p, b)) <= 0) {
		return src->rc;
	}
	if (src->feed > 0.0 && b->kind == MLIP_BLOCK_MOVE) {
		b->feed_mm_s = src->feed;
		b->rapid = 0;
	}
	return 1;
}

void source_init(struct source *src, const struct mlip_machine *m, int smooth)
{
	static struct mlip_smooth sm; /* ~1 MB */
	src->it = (struct mlip_block_iter){program_next, src};
	if (smooth) {
		src->it = mlip_smooth_iter(&src->si, &sm, m, src->it);
	}
}

static int source_next(struct source *src, struct mlip_block *b)
{
	int r = src->it.next(src->it.ctx, b);
	if (r < 0 && src->rc >= 0) {
		src->rc = -1; /* the filter refused a block (a non-finite target) */
		snprintf(src->p->msg, sizeof(src->p->msg), "the smoothing filter refused a block");
	}
	return r > 0;
}

static uint32_t queue_space(const struct queue *q)
{
	return QUEUE_CAP - (q->head - q->tail);
}

void queue_view(const struct queue *q, struct mlip_rec_view *v)
{
	uint32_t n = q->head - q->tail, at = q->tail & (QUEUE_CAP - 1u);
	v->span[0] = q->rec + at;
	v->len[0] = n < QUEUE_CAP - at ? n : QUEUE_CAP - at;
	v->span[1] = q->rec;
	v->len[1] = n - v->len[0];
}

void feed_step(struct feeder *f, struct queue *q)
{
	struct mlip_block b;
	while (!f->end_pushed && queue_space(q) > 0) {
		struct mlip_ring_rec *rec = &q->rec[q->head & (QUEUE_CAP - 1u)];
		if (source_next(&f->src, &b)) {
			mlip_ring_rec_from_block(rec, &b, ++f->seq);
		} else if (f->src.rc < 0) {
			return; /* no END: the run stops, the caller says why */
		} else {
			mlip_ring_rec_end(rec, ++f->seq, f->end_line);
			f->end_pushed = 1;
		}
		q->head++;
	}
}
