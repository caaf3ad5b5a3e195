/*
 * utf8.c - the UTF-8 check of mlip/text/chars.h.
 */
#include "mlip/text/chars.h"

size_t mlip_utf8_len(const unsigned char *p, size_t n)
{
	unsigned lo = 0x80, hi = 0xBF;
	size_t len, k;

	if (p[0] < 0x80) {
		return 1;
	}
	if (p[0] >= 0xC2 && p[0] <= 0xDF) {
		len = 2;
	} else if (p[0] >= 0xE0 && p[0] <= 0xEF) {
		len = 3;
		lo = p[0] == 0xE0 ? 0xA0 : 0x80; /* no overlong 3-byte form */
		hi = p[0] == 0xED ? 0x9F : 0xBF; /* no surrogate */
	} else if (p[0] >= 0xF0 && p[0] <= 0xF4) {
		len = 4;
		lo = p[0] == 0xF0 ? 0x90 : 0x80; /* no overlong 4-byte form */
		hi = p[0] == 0xF4 ? 0x8F : 0xBF; /* nothing above U+10FFFF */
	} else {
		return 0;
	}
	if (n < len || p[1] < lo || p[1] > hi) {
		return 0;
	}
	for (k = 2; k < len; k++) {
		if (p[k] < 0x80 || p[k] > 0xBF) {
			return 0;
		}
	}
	return len;
}
