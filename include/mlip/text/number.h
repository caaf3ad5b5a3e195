/*
 * mlip/text/number.h - the one number lexer of both readers (G-code words,
 * INI values): locale-free, no strtod (which takes "nan", "inf", hex floats
 * and, under some locales, a decimal comma).
 *
 * A decimal is [+-] D* [. D*] with at least one digit D, and with
 * MLIP_NUM_EXPONENT an exponent [(e|E) [+-] D+] (INI values; G-code has
 * none). The lexer keeps the first 19 significant digits as an integer
 * mantissa and the rest as a power of ten; mlip_number_value rounds once:
 * with a mantissa up to 2^53 and |e10| <= 22 both factors are exact doubles,
 * so the result is the correctly rounded one, as from strtod (Clinger's fast
 * path); beyond that within a few ulps. Plain double arithmetic, so valgrind
 * (which runs long double as double) sees the same numbers.
 */
#ifndef MLIP_TEXT_NUMBER_H
#define MLIP_TEXT_NUMBER_H

#include <stddef.h>
#include <stdint.h>

#define MLIP_NUM_EXPONENT 1u /* lex an exponent part */

struct mlip_number {
	uint64_t mant; /* the first 19 significant digits */
	long e10;      /* value = mant * 10^e10 */
	int neg;       /* a leading '-' */
	int ndig;      /* digits before any exponent: 0 means no number */
	int exp_bad;   /* an exponent marker without digits ("1e", "2e+") */
};

/* Lex a decimal at s[i..n): returns the index after it (i when nothing of
 * it is there). The caller decides what may follow. */
size_t mlip_number_lex(const char *s, size_t n, size_t i, unsigned flags, struct mlip_number *num);

/* Its value, signed; +-HUGE_VAL when it overflows a double. */
double mlip_number_value(const struct mlip_number *num);

/* The whole of s[0..n) as an integer: [+-] (D+ | 0x H+), decimal even with a
 * leading 0. Returns 0 with *out (saturated at +-2^40, far outside every
 * range a reader checks), -1 when malformed. */
int mlip_number_int(const char *s, size_t n, int64_t *out);

#endif
