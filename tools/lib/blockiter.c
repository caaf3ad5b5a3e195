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

static int smooth_next(void *ctx, struct mlip_block *out)
{
	struct mlip_smooth_iter *si = ctx;
	int stuck = 0;
	if (!si->started) {
		int r = si->in.next(si->in.ctx, out);
		if (r <= 0) {
			return r;
		}
		if (out->kind == MLIP_BLOCK_MOVE) {
			if (mlip_smooth_init(si->sm, si->m, out->target) != MLIP_OK) {
				return -1;
			}
			/* as the filter passes a rapid: the run that starts at its end
			 * deviates at most rho b / 2 on the half of its first segment
			 * next to it (smooth.c), so its corner keeps (1 - rho / 2) b */
			double b = si->sm->eps_mm;
			if (out->tol_mm > 0.0 && out->tol_mm < b) {
				b = out->tol_mm;
			}
			out->tol_mm = (1.0 - 0.5 * si->sm->rho) * b;
			si->sm->last_b = b;
			si->started = 1;
		}
		return 1; /* everything up to the first move passes unchanged */
	}
	for (;;) {
		if (mlip_smooth_pop(si->sm, out) == MLIP_OK) {
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
				mlip_smooth_finish(si->sm);
				si->ended = 1;
				continue;
			}
			si->has_pending = 1;
		}
		mlip_status st = mlip_smooth_push(si->sm, &si->pending);
		if (st == MLIP_OK) {
			si->has_pending = 0;
			stuck = 0;
		} else if (st != MLIP_E_FULL || ++stuck > 2) {
			return -1; /* a non-finite target, or no progress (cannot happen) */
		}
	}
}

struct mlip_block_iter mlip_smooth_iter(struct mlip_smooth_iter *si, struct mlip_smooth *sm,
                                        const struct mlip_machine *m, struct mlip_block_iter in)
{
	si->in = in;
	si->sm = sm;
	si->m = m;
	si->has_pending = 0;
	si->ended = 0;
	si->started = 0;
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
