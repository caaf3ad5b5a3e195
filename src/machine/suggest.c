/*
 * suggest.c - "did you mean": the key or section a user most likely meant
 * by an unknown one.
 */
#include <string.h>

#include "keys.h"
#include "mlip/text/chars.h"

#define SUGGEST_MAX 40 /* longer names get no suggestion */

/* Optimal-string-alignment distance (edits and swaps of neighbours),
 * ignoring case. */
static int edit_distance(const char *a, size_t na, const char *b, size_t nb)
{
	int row0[SUGGEST_MAX + 1], row1[SUGGEST_MAX + 1], row2[SUGGEST_MAX + 1];
	int *pp = row0, *pr = row1, *cur = row2;
	size_t i, j;

	for (j = 0; j <= nb; j++) {
		pr[j] = (int)j;
	}
	for (i = 1; i <= na; i++) {
		int *t;
		cur[0] = (int)i;
		for (j = 1; j <= nb; j++) {
			int sub = mlip_upper(a[i - 1]) != mlip_upper(b[j - 1]);
			int v = pr[j - 1] + sub;
			if (pr[j] + 1 < v) {
				v = pr[j] + 1;
			}
			if (cur[j - 1] + 1 < v) {
				v = cur[j - 1] + 1;
			}
			if (i > 1 && j > 1 && mlip_upper(a[i - 1]) == mlip_upper(b[j - 2]) &&
			    mlip_upper(a[i - 2]) == mlip_upper(b[j - 1]) && pp[j - 2] + 1 < v) {
				v = pp[j - 2] + 1;
			}
			cur[j] = v;
		}
		t = pp;
		pp = pr;
		pr = cur;
		cur = t;
	}
	return pr[nb];
}

static int prefix_fold(const char *a, size_t na, const char *b, size_t nb)
{
	size_t i, n = na < nb ? na : nb;

	for (i = 0; i < n; i++) {
		if (mlip_upper(a[i]) != mlip_upper(b[i])) {
			return 0;
		}
	}
	return 1;
}

/* The candidate the user most likely meant by s[0..n): the one equal
 * ignoring case, else the only one that s abbreviates or extends (4 letters
 * in common at least: MAX_ACCEL -> MAX_ACCELERATION), else the nearest within
 * a few edits. NULL when nothing is close. */
const char *mlip_mc_suggest(const char *s, size_t n, const char *const *cand, int ncand)
{
	const char *best = NULL, *pre = NULL;
	int i, npre = 0, bestd = n < 5 ? 2 : n < 10 ? 3 : 4; /* distance must be below */

	if (n > SUGGEST_MAX) {
		return NULL;
	}
	for (i = 0; i < ncand; i++) {
		size_t nc = strlen(cand[i]);
		if (nc <= SUGGEST_MAX && (n < nc ? n : nc) >= 4 && prefix_fold(s, n, cand[i], nc)) {
			pre = cand[i];
			npre++;
		}
	}
	for (i = 0; i < ncand; i++) {
		size_t nc = strlen(cand[i]);
		int d;
		if (nc > SUGGEST_MAX) {
			continue;
		}
		d = edit_distance(s, n, cand[i], nc);
		if (d == 0) {
			return cand[i];
		}
		if (d < bestd) {
			bestd = d;
			best = cand[i];
		}
	}
	return npre == 1 ? pre : best;
}
