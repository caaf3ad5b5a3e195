/*
 * blockiter.h - blocks in program order through a small iterator, and the
 * `smooth` strategy's filter (src/motion/smooth.c) as one: the host glue mlip-sim
 * and mlip-feed share. Any reader of blocks (an array, the streaming program
 * reader of program.h) plugs in as a struct mlip_block_iter.
 */
#ifndef MLIP_BLOCKITER_H
#define MLIP_BLOCKITER_H

#include <stddef.h>

#include "mlip/motion/smooth.h"
#include "mlip/types.h"

/* next(): 1 and *out filled, 0 at the program's end, < 0 on an error. */
struct mlip_block_iter {
	int (*next)(void *ctx, struct mlip_block *out);
	void *ctx;
};

/* An array of blocks as an iterator. */
struct mlip_array_iter {
	const struct mlip_block *blocks;
	size_t n, i;
};
struct mlip_block_iter mlip_array_iter(struct mlip_array_iter *a, const struct mlip_block *b,
                                       size_t n);

/* The smoothing filter fed block by block (a stream whose end is not known
 * ahead, mlip-grbl): push blocks in program order, pop after each push until
 * it gives nothing, finish at the end (or at any point where the program is
 * cut: the rest is a new stream), then pop the rest. The blocks up to and
 * including the first move pass unchanged, and the filter starts at that
 * move's target (see mlip_smooth_iter, which is this over an iterator). */
struct mlip_smooth_stream {
	struct mlip_smooth *sm;
	const struct mlip_machine *m;
	struct mlip_block pass; /* a block passed through unchanged, not popped yet */
	int has_pass, started, finished;
};
void mlip_smooth_stream_start(struct mlip_smooth_stream *ss, struct mlip_smooth *sm,
                              const struct mlip_machine *m);
/* 1 taken; 0 pop first (nothing taken); < 0 a block the filter refuses (a
 * non-finite target) or a push after finish. */
int mlip_smooth_stream_push(struct mlip_smooth_stream *ss, const struct mlip_block *b);
/* 1 and *out, or 0: nothing to give until the next push or finish. */
int mlip_smooth_stream_pop(struct mlip_smooth_stream *ss, struct mlip_block *out);
void mlip_smooth_stream_finish(struct mlip_smooth_stream *ss);

/* The smoothing filter over another iterator for machine m; sm is large
 * (keep it static). The blocks up to and including the program's first move
 * pass unchanged, and the filter starts at that move's target: so the output
 * depends on the program alone, not on where the machine stands when it
 * starts. A feeder numbering the output 1, 2, ... then gives the same record
 * the same number in every run, which --start-seq continuation needs. */
struct mlip_smooth_iter {
	struct mlip_block_iter in;
	struct mlip_smooth_stream ss;
	struct mlip_block pending;
	int has_pending, ended;
};
struct mlip_block_iter mlip_smooth_iter(struct mlip_smooth_iter *si, struct mlip_smooth *sm,
                                        const struct mlip_machine *m, struct mlip_block_iter in);

/* Smooth a whole program for machine m (benchmarks, tests): *out
 * (malloc'ed, the caller frees) gets *nout blocks. 0, or -1 (out of memory,
 * bad input). */
int mlip_smooth_program(const struct mlip_machine *m, const struct mlip_block *b, size_t n,
                        struct mlip_block **out, size_t *nout);

#endif
