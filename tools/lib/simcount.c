/* simcount.c - see simcount.h */
#include "simcount.h"

#include <string.h>

#include "mlip/ctl/controller.h"
#include "mlip/motion/smooth.h"
#include "simfeed.h"
#include "trace.h"

static struct {
	struct mlip_planner planner;           /* ~1.1 MB */
	struct mlip_smooth_store smooth_store; /* ~1.5 MB, smooth only */
	struct mlip_ctl ctl;
	struct mlip_ctl_out out;
	struct queue q;
	struct feeder fdr;
	struct mlip_trace trace;
} S;

int mlip_simcount(const struct mlip_machine *m, uint32_t lookahead, struct mlip_program *prog,
                  mlip_strategy st, double feed, uint64_t budget, uint64_t *rows)
{
	/* every output there, so an M64 or coolant switches (no pause) on
	 * either run alike: an event at rest costs both runs the same */
	struct mlip_io_config io = {.out_mapped = ~0u};
	struct mlip_ctl_opts co = {.strategy = st,
	                           .smooth = st == MLIP_STRATEGY_SMOOTH ? &S.smooth_store : NULL,
	                           .lookahead = lookahead,
	                           .io = &io};
	double home[MLIP_MAX_AXES] = {0};
	int rc = MLIP_SIMCOUNT_NONE;
	*rows = 0;
	mlip_program_rewind(prog);
	if (mlip_ctl_init(&S.ctl, &S.planner, m, &co) != MLIP_OK) {
		return MLIP_SIMCOUNT_NONE;
	}
	for (int k = 0; k < m->n_axes; k++) {
		home[k] = m->axis[k].home;
	}
	memset(&S.out, 0, sizeof(S.out));
	S.q.head = S.q.tail = 0;
	S.fdr = (struct feeder){.src = {.p = prog, .feed = feed}, .end_line = prog->lines};
	source_init(&S.fdr.src, m, st == MLIP_STRATEGY_SMOOTH);
	mlip_trace_open(&S.trace, NULL, m, home);
	for (uint64_t period = 0; period <= MLIP_SIM_MAX_PERIODS; period++) {
		struct mlip_ring_cmd cmd = {.seq = 2, .op = MLIP_CMD_RESUME};
		struct mlip_ctl_in in = {.period = period, .feeder_alive = 1};
		uint32_t was = S.q.head;
		feed_step(&S.fdr, &S.q);
		if (S.fdr.src.rc < 0) {
			break;
		}
		for (uint32_t i = was; i != S.q.head; i++) {
			if (S.q.rec[i & (QUEUE_CAP - 1u)].type == MLIP_REC_PROBE) {
				goto out; /* where it trips decides the rest */
			}
		}
		if (S.out.status.state == MLIP_STATE_PAUSED) {
			in.cmd = &cmd; /* the operator resumes at once */
		}
		queue_view(&S.q, &in.recs);
		mlip_ctl_period(&S.ctl, &in, &S.out);
		S.q.tail += S.out.taken;
		if (mlip_trace_sample(&S.trace, S.out.status.state, S.out.pos, NULL)) {
			*rows = S.trace.rows;
		}
		if (budget > 0 && S.trace.rows >= budget) {
			rc = MLIP_SIMCOUNT_OVER;
			break;
		}
		if (S.trace.ended) {
			rc = MLIP_SIMCOUNT_DONE;
			break;
		}
		if (S.out.status.state == MLIP_STATE_FAULT) {
			break;
		}
	}
out:
	mlip_program_rewind(prog);
	return rc;
}

void mlip_corner_choose(const struct mlip_machine *m, uint32_t lookahead, struct mlip_program *prog,
                        double feed, struct mlip_corner_choice *ch)
{
	memset(ch, 0, sizeof(*ch));
	if (mlip_simcount(m, lookahead, prog, MLIP_STRATEGY_SMOOTH, feed, 0, &ch->smooth_rows) !=
	    MLIP_SIMCOUNT_DONE) {
		ch->why = "smooth's run not counted (a probe move, or a fault)";
		ch->smooth_rows = 0;
		return;
	}
	uint64_t rows = 0;
	if (mlip_simcount(m, lookahead, prog, MLIP_STRATEGY_MPCT, feed, ch->smooth_rows, &rows) ==
	        MLIP_SIMCOUNT_DONE &&
	    rows < ch->smooth_rows) {
		ch->mpct = 1;
		ch->mpct_rows = rows;
	}
}
