/* cyclictest run with mlip-latency's settings, side by side: its histogram
 * as a latstats series like ours. */
#ifndef MLIP_LATCYCLIC_H
#define MLIP_LATCYCLIC_H

#include <stdint.h>

#include "latopts.h"
#include "latstats.h"

struct lat_ct_result {
	int ran;
	char cmd[512];
	struct mlip_latstats s;
	uint64_t *bins;
	double avg_us; /* cyclictest's own average (its JSON), -1: not read */
	char *json;    /* its --json file, verbatim (NULL: none) */
};

/* Run cyclictest with our settings; its -h histogram (stdout) becomes a
 * latstats series like ours, overflow samples at its max. 0 or -1. */
int lat_run_cyclictest(const struct lat_opts *o, int64_t period_ns, double elapsed_s,
                       uint32_t hist_us, struct lat_ct_result *ct);

#endif
