/*
 * latstats.c - histogram statistics of a timing series (see latstats.h for
 * the bin convention and the percentile definition, nearest rank with the
 * bin's upper edge capped at the exact max).
 */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "latstats.h"

#define PPM 1000000ULL /* percentiles are resolved to 1e-4 % (99.9999 is exact) */

void mlip_latstats_init(struct mlip_latstats *s, uint64_t *bins, uint32_t nbins, int64_t bin_ns)
{
	s->bins = bins;
	s->nbins = nbins;
	s->bin_ns = bin_ns > 0 ? bin_ns : 1;
	s->count = 0;
	s->overflow = 0;
	s->sum_ns = 0;
	s->min_ns = INT64_MAX;
	s->max_ns = 0;
	if (bins != NULL && nbins > 0) {
		memset(bins, 0, (size_t)nbins * sizeof(bins[0]));
	}
}

void mlip_latstats_add_n(struct mlip_latstats *s, int64_t ns, uint64_t n)
{
	if (n == 0) {
		return;
	}
	if (ns < 0) {
		ns = 0;
	}
	s->count += n;
	s->sum_ns += (uint64_t)ns * n;
	if (ns < s->min_ns) {
		s->min_ns = ns;
	}
	if (ns > s->max_ns) {
		s->max_ns = ns;
	}
	int64_t b = ns / s->bin_ns;
	if (b < (int64_t)s->nbins) {
		s->bins[b] += n;
	} else {
		s->overflow += n;
	}
}

void mlip_latstats_add(struct mlip_latstats *s, int64_t ns)
{
	mlip_latstats_add_n(s, ns, 1);
}

double mlip_latstats_mean_ns(const struct mlip_latstats *s)
{
	return s->count ? (double)s->sum_ns / (double)s->count : 0.0;
}

int64_t mlip_latstats_min_ns(const struct mlip_latstats *s)
{
	return s->count ? s->min_ns : 0;
}

int64_t mlip_latstats_percentile_ns(const struct mlip_latstats *s, double pct, int *in_overflow)
{
	if (in_overflow != NULL) {
		*in_overflow = 0;
	}
	if (s->count == 0) {
		return 0;
	}
	if (!(pct > 0.0)) { /* also NaN */
		pct = 0.0;
	}
	if (pct > 100.0) {
		pct = 100.0;
	}
	/* rank r = ceil(pct/100 * n) in integers: pct in parts per million of
	 * 100 %, so that 99.99 % of 10000 samples is rank 9999, not 10000 from
	 * a rounding error */
	uint64_t ppm = (uint64_t)(pct * 1e4 + 0.5);
	uint64_t n = s->count;
	uint64_t r = (n / PPM) * ppm + ((n % PPM) * ppm + PPM - 1) / PPM;
	if (r < 1) {
		r = 1;
	}
	if (r > n) {
		r = n;
	}
	uint64_t seen = 0;
	for (uint32_t b = 0; b < s->nbins; b++) {
		seen += s->bins[b];
		if (seen >= r) {
			int64_t upper = ((int64_t)b + 1) * s->bin_ns;
			return upper < s->max_ns ? upper : s->max_ns;
		}
	}
	if (in_overflow != NULL) {
		*in_overflow = 1;
	}
	return s->max_ns;
}

uint64_t mlip_latstats_count_below(const struct mlip_latstats *s, uint32_t nbins_out)
{
	uint64_t c = 0;
	uint32_t end = nbins_out < s->nbins ? nbins_out : s->nbins;
	for (uint32_t b = 0; b < end; b++) {
		c += s->bins[b];
	}
	return c;
}
