/* trace.c - see trace.h */
#include "trace.h"

#include <string.h>

#include "mlip/ctl/state.h"

static void row(struct mlip_trace *tr, uint64_t k, const double *x)
{
	if (tr->f == NULL) {
		return;
	}
	fprintf(tr->f, "%.17g", (double)k * tr->period_s);
	for (int i = 0; i < tr->n; i++) {
		fprintf(tr->f, ",%.17g", x[i]);
	}
	fputc('\n', tr->f);
}

void mlip_trace_open(struct mlip_trace *tr, FILE *f, const struct mlip_machine *m,
                     const double *start)
{
	memset(tr, 0, sizeof(*tr));
	tr->f = f;
	tr->n = m->n_axes;
	tr->period_s = m->period_s;
	if (start != NULL) {
		memcpy(tr->pending, start, sizeof(double) * (size_t)m->n_axes);
		tr->have_pending = 1;
	}
	if (f != NULL) {
		fputc('t', f);
		for (int k = 0; k < m->n_axes; k++) {
			fprintf(f, ",%c", m->axis[k].letter + ('a' - 'A'));
		}
		fputc('\n', f);
	}
}

int mlip_trace_sample(struct mlip_trace *tr, uint32_t state, const double *pos,
                      const double **start)
{
	return mlip_trace_sample_at(tr, tr->started ? tr->last + 1 : tr->t0 + 1, state, pos, start);
}

int mlip_trace_sample_at(struct mlip_trace *tr, uint64_t period, uint32_t state, const double *pos,
                         const double **start)
{
	if (start != NULL) {
		*start = NULL;
	}
	if (tr->ended) {
		return 0;
	}
	if (!tr->started) {
		if (state == MLIP_STATE_IDLE || state == MLIP_STATE_PREREAD) {
			memcpy(tr->pending, pos, sizeof(double) * (size_t)tr->n);
			tr->have_pending = 1;
			tr->t0 = period;
			return 0;
		}
		tr->started = 1;
		if (!tr->have_pending) {
			memcpy(tr->pending, pos, sizeof(double) * (size_t)tr->n);
			tr->t0 = period - 1;
		}
		row(tr, 0, tr->pending);
		if (start != NULL) {
			*start = tr->pending;
		}
	}
	tr->rows++;
	tr->last = period;
	row(tr, period - tr->t0, pos);
	tr->ended = state == MLIP_STATE_IDLE;
	return 1;
}
