/*
 * number.c - the number lexer of mlip/text/number.h.
 */
#include "mlip/text/number.h"

#include <math.h>

#include "mlip/text/chars.h"

/* The one powers-of-ten table: every power an exact double. */
static const double p10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                               1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                               1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

size_t mlip_number_lex(const char *s, size_t n, size_t i, unsigned flags, struct mlip_number *num)
{
	int dot = 0, nsig = 0;

	num->mant = 0;
	num->e10 = 0;
	num->neg = 0;
	num->ndig = 0;
	num->exp_bad = 0;
	if (i < n && (s[i] == '+' || s[i] == '-')) {
		num->neg = s[i] == '-';
		i++;
	}
	for (; i < n; i++) {
		if (s[i] == '.' && !dot) {
			dot = 1;
			continue;
		}
		if (!mlip_is_digit(s[i])) {
			break;
		}
		num->ndig++;
		if (nsig < 19) {
			num->mant = num->mant * 10 + (uint64_t)(s[i] - '0');
			nsig += num->mant != 0; /* leading zeros are not significant */
			num->e10 -= dot;
		} else if (!dot) {
			num->e10++; /* integer digits beyond the 19th: a power of ten */
		}
	}
	if ((flags & MLIP_NUM_EXPONENT) && num->ndig > 0 && i < n && (s[i] == 'e' || s[i] == 'E')) {
		long x = 0;
		int eneg = 0, eany = 0;

		i++;
		if (i < n && (s[i] == '+' || s[i] == '-')) {
			eneg = s[i] == '-';
			i++;
		}
		for (; i < n && mlip_is_digit(s[i]); i++) {
			eany = 1;
			if (x < 100000) { /* saturate: 1e100000 is out of range anyway */
				x = x * 10 + (s[i] - '0');
			}
		}
		num->exp_bad = !eany;
		num->e10 += eneg ? -x : x;
	}
	return i;
}

double mlip_number_value(const struct mlip_number *num)
{
	uint64_t m = num->mant;
	long e10 = num->e10;
	double v;

	if (m == 0) {
		v = 0.0;
	} else if (m <= (1ull << 53) && e10 >= -22 && e10 <= 22) {
		v = e10 >= 0 ? (double)m * p10[e10] : (double)m / p10[-e10];
	} else {
		/* m = mant 10^d, mant in [1, 10): with the value's own exponent
		 * E = e10 + d, 10^E is a normal double wherever the value is */
		uint64_t t = m;
		long d = 0, ex;
		double mant;
		while (t >= 10) {
			t /= 10;
			d++;
		}
		mant = (double)m / p10[d];
		ex = e10 + d;
		if (ex > 308) {
			v = HUGE_VAL;
		} else if (ex < -340) {
			v = 0.0;
		} else if (ex < -300) { /* a subnormal result: scale in two steps */
			v = mant * pow(10.0, (double)(ex + 40)) * 1e-40;
		} else {
			v = mant * pow(10.0, (double)ex);
		}
	}
	return num->neg ? -v : v;
}

static int hex_val(char ch)
{
	if (mlip_is_digit(ch)) {
		return ch - '0';
	}
	if (ch >= 'a' && ch <= 'f') {
		return ch - 'a' + 10;
	}
	if (ch >= 'A' && ch <= 'F') {
		return ch - 'A' + 10;
	}
	return -1;
}

int mlip_number_int(const char *s, size_t n, int64_t *out)
{
	const int64_t cap = (int64_t)1 << 40;
	size_t i = 0;
	int64_t v = 0;
	int neg = 0, base = 10, any = 0;

	if (i < n && (s[i] == '+' || s[i] == '-')) {
		neg = s[i] == '-';
		i++;
	}
	if (i + 1 < n && s[i] == '0' && (s[i + 1] == 'x' || s[i + 1] == 'X')) {
		base = 16;
		i += 2;
	}
	for (; i < n; i++) {
		int d = hex_val(s[i]);
		if (d < 0 || d >= base) {
			return -1;
		}
		any = 1;
		if (v < cap) {
			v = v * base + d;
		}
	}
	if (!any) {
		return -1;
	}
	if (v > cap) {
		v = cap;
	}
	*out = neg ? -v : v;
	return 0;
}
