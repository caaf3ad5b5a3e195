/*
 * blockiter.c - see blockiter.h.
 */
#include "blockiter.h"

#include <stdlib.h>

static int array_next(void *ctx, struct mlip_block *out)
{
	struct mlip_array_iter *a = ctx;
	if (a->i >= a->n) {
		return 0;
	}
	*out = a->blocks[a->i++];
	return 1;
}

struct mlip_block_iter mlip_array_iter(struct mlip_array_iter *a, const struct mlip_block *b,
                                       size_t n)
{
	a->blocks = b;
	a->n = n;
	a->i = 0;
	return (struct mlip_block_iter){array_next, a};
}

void mlip_smooth_stream_start(struct mlip_smooth_stream *ss, struct mlip_smooth *sm,
                              const struct mlip_machine *m)
{
	ss->sm = sm;
	ss->m = m;
	ss->has_pass = 0;
	ss->started = 0;
	ss->finished = 0;
}

int mlip_smooth_stream_push(struct mlip_smooth_stream *ss, const struct mlip_block *b)
{
	if (ss->finished) {
		return -1;
	}
	if (ss->has_pass) {
		return 0;
	}
	if (!ss->started) {
		ss->pass = *b;
		ss->has_pass = 1;
		if (b->kind == MLIP_BLOCK_MOVE || b->kind == MLIP_BLOCK_PROBE) {
			if (mlip_smooth_init(ss->sm, ss->m, b->target) != MLIP_OK) {
				ss->has_pass = 0;
				return -1;
			}
			/* as the filter passes a rapid: the run that starts at its end
			 * deviates at most rho b / 2 on the half of its first segment
			 * next to it (smooth.c), so its corner keeps (1 - rho / 2) b */
			double bud = ss->sm->eps_mm;
			if (b->tol_mm > 0.0 && b->tol_mm < bud) {
				bud = b->tol_mm;
			}
			ss->pass.tol_mm = (1.0 - 0.5 * ss->sm->rho) * bud;
			ss->sm->last_b = bud;
			ss->started = 1;
		}
		return 1; /* everything up to the first move passes unchanged */
	}
	mlip_status st = mlip_smooth_push(ss->sm, b);
	return st == MLIP_OK ? 1 : st == MLIP_E_FULL ? 0 : -1;
}

int mlip_smooth_stream_pop(struct mlip_smooth_stream *ss, struct mlip_block *out)
{
	if (ss->has_pass) {
		*out = ss->pass;
		ss->has_pass = 0;
		return 1;
	}
	return ss->started && mlip_smooth_pop(ss->sm, out) == MLIP_OK;
}

void mlip_smooth_stream_finish(struct mlip_smooth_stream *ss)
{
	if (ss->started && !ss->finished) {
		mlip_smooth_finish(ss->sm);
	}
	ss->finished = 1;
}

static int smooth_next(void *ctx, struct mlip_block *out)
{
	struct mlip_smooth_iter *si = ctx;
	int stuck = 0;
	for (;;) {
		if (mlip_smooth_stream_pop(&si->ss, out)) {
			return 1;
		}
		if (si->ended) {
			return 0;
		}
		if (!si->has_pending) {
			int r = si->in.next(si->in.ctx, &si->pending);
			if (r < 0) {
				return r;
			}
			if (r == 0) {
				mlip_smooth_stream_finish(&si->ss);
				si->ended = 1;
				continue;
			}
			si->has_pending = 1;
		}
		int st = mlip_smooth_stream_push(&si->ss, &si->pending);
		if (st > 0) {
			si->has_pending = 0;
			stuck = 0;
		} else if (st < 0 || ++stuck > 2) {
			return -1; /* a non-finite target, or no progress (cannot happen) */
		}
	}
}

struct mlip_block_iter mlip_smooth_iter(struct mlip_smooth_iter *si, struct mlip_smooth *sm,
                                        const struct mlip_machine *m, struct mlip_block_iter in)
{
	si->in = in;
	mlip_smooth_stream_start(&si->ss, sm, m);
	si->has_pending = 0;
	si->ended = 0;
	return (struct mlip_block_iter){smooth_next, si};
}

int mlip_smooth_program(const struct mlip_machine *m, const struct mlip_block *b, size_t n,
                        struct mlip_block **out, size_t *nout)
{
	static struct mlip_smooth sm;
	struct mlip_array_iter a;
	struct mlip_smooth_iter si;
	size_t cap = n + n / 2 + 16, k = 0;
	struct mlip_block *o = malloc(cap * sizeof(*o));

	*out = NULL;
	*nout = 0;
	if (o == NULL) {
		return -1;
	}
	struct mlip_block_iter it = mlip_smooth_iter(&si, &sm, m, mlip_array_iter(&a, b, n));
	for (;;) {
		if (k == cap) {
			cap *= 2;
			struct mlip_block *q = realloc(o, cap * sizeof(*o));
			if (q == NULL) {
				free(o);
				return -1;
			}
			o = q;
		}
		int r = it.next(it.ctx, &o[k]);
		if (r < 0) {
			free(o);
			return -1;
		}
		if (r == 0) {
			break;
		}
		k++;
	}
	*out = o;
	*nout = k;
	return 0;
}
