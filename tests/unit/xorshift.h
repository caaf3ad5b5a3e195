/*
 * xorshift.h - the unit tests' random numbers: Marsaglia's xorshift64
 * (13, 7, 17), uniform doubles from its top 53 bits. A test file defines
 * XORSHIFT_SEED (non-zero) before including it: its draws are its own and
 * the same on every run, so a failure repeats.
 */
#ifndef MLIP_TEST_XORSHIFT_H
#define MLIP_TEST_XORSHIFT_H

#include <stdint.h>

#ifndef XORSHIFT_SEED
#error "define XORSHIFT_SEED (non-zero) before including xorshift.h"
#endif

static uint64_t rng = XORSHIFT_SEED;

/* Uniform in [lo, hi). */
static double uni(double lo, double hi)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return lo + (hi - lo) * (double)(rng >> 11) * (1.0 / 9007199254740992.0);
}

#endif
