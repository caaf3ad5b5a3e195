/*
 * latstats.h - statistics of one timing series (wake-up latency, period
 * jitter, compute time, send time) for mlip-latency: count, min, mean, max,
 * a histogram of fixed-width bins with an overflow count, and percentiles
 * read off that histogram.
 *
 * Pure and real-time safe: the bins are storage the caller passes in
 * (allocated and touched before the loop), mlip_latstats_add is a few
 * integer operations; nothing here allocates, prints or makes a system call.
 *
 * Histogram (cyclictest's convention): bin i holds the samples v with
 * i * bin_ns <= v < (i + 1) * bin_ns, i.e. the value truncated to whole bins
 * (1 us bins: whole microseconds); samples >= nbins * bin_ns are counted in
 * overflow only. Negative samples are taken as 0.
 *
 * Percentile p (nearest rank): the r-th smallest sample, r = ceil(p/100 * n)
 * (at least 1). The histogram knows only its bin, so the value reported is the
 * bin's UPPER edge, never above the exact max:
 *
 *      P(p) = min((b + 1) * bin_ns, max)    b: bin of the r-th smallest sample
 *
 * an upper bound within one bin of the exact value: at least p % of the
 * samples are <= P(p). It is monotonic in p and min <= P(p) <= max. When the
 * r-th sample lies in the overflow its bin is unknown and P(p) = max, with
 * the overflow flagged.
 */
#ifndef MLIP_LATSTATS_H
#define MLIP_LATSTATS_H

#include <stdint.h>

struct mlip_latstats {
	/* histogram: caller storage */
	uint64_t *bins; /* nbins counters */
	uint32_t nbins; /* bins; samples >= nbins * bin_ns go to overflow */
	int64_t bin_ns; /* bin width, ns (1000: 1 us bins) */
	/* totals */
	uint64_t count;    /* samples */
	uint64_t overflow; /* samples beyond the last bin */
	uint64_t sum_ns;   /* sum of the samples, ns (584 years before it wraps) */
	int64_t min_ns;    /* smallest sample (INT64_MAX while count == 0) */
	int64_t max_ns;    /* largest sample (0 while count == 0) */
};

/* Start empty on bins[0..nbins-1] (zeroed here), bin width bin_ns > 0. */
void mlip_latstats_init(struct mlip_latstats *s, uint64_t *bins, uint32_t nbins, int64_t bin_ns);

/* Add one sample, ns. Constant time; real-time safe. */
void mlip_latstats_add(struct mlip_latstats *s, int64_t ns);

/* Add n samples of the same value (a histogram read from elsewhere, e.g.
 * cyclictest's: each bin's count at the bin's lower edge). */
void mlip_latstats_add_n(struct mlip_latstats *s, int64_t ns, uint64_t n);

/* Mean, ns; 0 when empty. */
double mlip_latstats_mean_ns(const struct mlip_latstats *s);

/* Smallest sample, ns; 0 when empty. */
int64_t mlip_latstats_min_ns(const struct mlip_latstats *s);

/* P(p) above, ns, for 0 <= pct <= 100 (outside: clamped); 0 when empty.
 * *in_overflow (may be NULL) is set to 1 when the rank fell in the overflow
 * (the value is then max), else 0. */
int64_t mlip_latstats_percentile_ns(const struct mlip_latstats *s, double pct, int *in_overflow);

/* Samples in bins [0, nbins_out) (nbins_out > nbins: all binned samples):
 * for a histogram shown with fewer bins than kept, whose overflow is then
 * count - mlip_latstats_count_below(s, nbins_out). */
uint64_t mlip_latstats_count_below(const struct mlip_latstats *s, uint32_t nbins_out);

#endif
