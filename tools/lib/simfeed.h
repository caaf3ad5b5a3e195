/*
 * simfeed.h - mlip-sim's feeder: the checked program streamed (through
 * smooth's filter with --strategy smooth) into the queue of records the
 * controller takes from, as mlip-feed fills mlip-rt's ring.
 */
#ifndef MLIP_TOOLS_SIMFEED_H
#define MLIP_TOOLS_SIMFEED_H

#include <stdint.h>

#include "blockiter.h"
#include "mlip/ipc/ring.h"
#include "mlip/motion/smooth.h"
#include "program.h"

/* Where the blocks come from: the checked program, streamed (never held,
 * program.h), through the smoothing filter with --strategy smooth (fixed
 * memory, blockiter.h). 1 with the next block in *b, 0 at the end or on an
 * error of the stream (rc < 0, the program's msg says why). */
struct source {
	struct mlip_program *p;
	int rc;
	double feed;               /* --feed: > 0 replaces every F and G0 */
	struct mlip_block_iter it; /* the program's blocks, or smooth's over them */
	struct mlip_smooth_iter si;
};

/* The records between the feeder and the controller: a FIFO of the ring's
 * capacity, shown to the controller as the ring shows itself (two spans). */
#define QUEUE_CAP MLIP_RING_CAPACITY

struct queue {
	struct mlip_ring_rec rec[QUEUE_CAP];
	uint32_t head, tail; /* free-running */
};

/* The feeder's step before each period: the queue filled as far as it
 * goes, records numbered as mlip-feed numbers them (blocks 1..n, then END;
 * with smooth, the filter's output blocks 1..n, each with its source line). */
struct feeder {
	struct source src;
	uint64_t seq; /* last record pushed */
	uint32_t end_line;
	int end_pushed;
};

void source_init(struct source *src, const struct mlip_machine *m, int smooth);
void queue_view(const struct queue *q, struct mlip_rec_view *v);
void feed_step(struct feeder *f, struct queue *q);

#endif
