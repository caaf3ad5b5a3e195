/*
 * bench_pathplan - the path-speed plan's cost per planned period
 * (src/motion/pathplan.c, Q1-Q4; docs/algorithm.md "The path-speed plan"):
 * the greedy plan from rest to rest along a helix of radius 4 mm rising
 * 0.5 mm a radian (the one test_pathplan plans), sampled every STEP mm of
 * arc into a spline of MLIP_PATH_WIN points, at jerk limit J on every axis
 * (A 1000 mm/s^2, 200 mm/s, the model's margins). Prints the planned
 * periods and the braking-run periods simulated, as JSON. For instructions
 * run it under callgrind and divide by the periods:
 *
 *   valgrind --tool=callgrind --toggle-collect=bench_plan_period \
 *       build/bench_pathplan 1e4 0.4
 *
 *   build/bench_pathplan J [STEP]     (STEP default 0.4)
 *
 * --band B: count the pieces whose (P6) bound on the distance from their
 * chord exceeds B mm (default 0.001); the JSON gives it and the largest.
 *
 * --points CSV: the plan along the natural spline through the points (one
 * a line, the axes' coordinates; bench/pathspeed.py --c writes `smooth`'s
 * output there) at J exactly (the caller's margin applied), the braking
 * policies' decelerations --brake B[,B2...] (300; a state is certified by
 * any of their runs, Q4); --out FILE: each planned period's
 * path position and its braking-run periods, for the model to sample the
 * positions and have mlip-check judge them. The plan runs from rest to rest
 * at the end (within 1e-8 of it, pathplan.h; fails if it stops short or leaves the
 * certified states).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mlip/motion/pathplan.h"

static struct mlip_path_spline sp;
static struct mlip_path_curve cv;

/* FNV-1a over the states' bits: two builds plan the same periods exactly
 * when their hashes agree (a cheaper period must not change the plan). */
static uint64_t fnv(uint64_t h, double x)
{
	unsigned char b[sizeof x];
	memcpy(b, &x, sizeof x);
	for (size_t i = 0; i < sizeof x; i++) {
		h = (h ^ b[i]) * 1099511628211ull;
	}
	return h;
}

/* One planned period. Named for callgrind's --toggle-collect. */
__attribute__((noinline)) int bench_plan_period(const struct mlip_path_limits *lim,
                                                struct mlip_path_state *st, double end, long *work);
int bench_plan_period(const struct mlip_path_limits *lim, struct mlip_path_state *st, double end,
                      long *work)
{
	return mlip_path_plan_period(&cv, lim, st, end, 3000, work);
}

/* --points: the whole curve's spline, in the caller's (host) memory. */
static int fit_points(const char *path, int *n_axes)
{
	FILE *f = fopen(path, "r");
	if (!f) {
		perror(path);
		return -1;
	}
	int cap = 1024, count = 0, n = 0;
	double(*pts)[MLIP_MAX_AXES] = malloc(sizeof(*pts) * (size_t)cap);
	char line[512];
	while (pts && fgets(line, sizeof line, f)) {
		double row[MLIP_MAX_AXES];
		int k = 0;
		char *c = line, *e;
		while (k < MLIP_MAX_AXES) {
			row[k] = strtod(c, &e);
			if (e == c) {
				break;
			}
			k++;
			c = e + strspn(e, ", \t");
		}
		if (k == 0) {
			continue;
		}
		if (n == 0) {
			n = k;
		}
		if (k != n) {
			fprintf(stderr, "%s:%d: %d coordinates, the first line had %d\n", path,
			        count + 1, k, n);
			fclose(f);
			free(pts);
			return -1;
		}
		if (count == cap) {
			cap *= 2;
			void *q = realloc(pts, sizeof(*pts) * (size_t)cap);
			if (!q) {
				free(pts);
				pts = NULL;
				break;
			}
			pts = q;
		}
		memcpy(pts[count++], row, sizeof row);
	}
	fclose(f);
	size_t z = sizeof(double) * (size_t)(count > 0 ? count : 1);
	double *s = malloc(z), *c = malloc(z);
	double(*p)[MLIP_MAX_AXES] = malloc(z * MLIP_MAX_AXES),
	(*m)[MLIP_MAX_AXES] = malloc(z * MLIP_MAX_AXES);
	double(*b)[MLIP_MAX_AXES] = malloc(z * MLIP_MAX_AXES),
	(*t3)[MLIP_MAX_AXES] = malloc(z * MLIP_MAX_AXES);
	if (!pts || !s || !c || !p || !m || !b || !t3 ||
	    mlip_path_fit(n, (const double(*)[MLIP_MAX_AXES])pts, count, s, p, m, b, t3, c, &cv) !=
	        0) {
		fprintf(stderr, "%s: no spline through its %d points\n", path, count);
		return -1; /* a benchmark: the process ends here */
	}
	free(pts);
	free(c); /* scratch of the fit; the others are the curve's */
	*n_axes = n;
	return 0; /* the arrays live as long as the process */
}

int main(int argc, char **argv)
{
	const char *points = NULL, *out = NULL;
	double J = 0.0, step = 0.4, brake = 300.0, band = 0.001, brakes[MLIP_PATH_BRAKES] = {300.0};
	int nbrake = 1;
	for (int i = 1; i < argc; i++) {
		if (!strcmp(argv[i], "--points") && i + 1 < argc) {
			points = argv[++i];
		} else if (!strcmp(argv[i], "--out") && i + 1 < argc) {
			out = argv[++i];
		} else if (!strcmp(argv[i], "--band") && i + 1 < argc) {
			band = atof(argv[++i]);
		} else if (!strcmp(argv[i], "--brake") && i + 1 < argc) {
			/* B[,B2...]: the policies' decelerations (Q3) */
			char *c = argv[++i], *e;
			nbrake = 0;
			while (nbrake < MLIP_PATH_BRAKES) {
				brakes[nbrake] = strtod(c, &e);
				if (e == c || !(brakes[nbrake] > 0.0)) {
					brake = -1.0; /* usage */
					break;
				}
				nbrake++;
				if (*e != ',') {
					break;
				}
				c = e + 1;
			}
		} else if (J == 0.0) {
			J = atof(argv[i]);
		} else {
			step = atof(argv[i]);
		}
	}
	if (!(J > 0.0) || !(step > 0.0) || !(brake > 0.0)) {
		fprintf(stderr, "usage: bench_pathplan J [STEP]\n"
		                "       bench_pathplan J --points CSV [--brake B[,B2..]] [--out "
		                "FILE] [--band B]\n");
		return 2;
	}
	int n = 3;
	if (points) {
		if (fit_points(points, &n) != 0) {
			return 1;
		}
	} else {
		static double pts[MLIP_PATH_WIN][MLIP_MAX_AXES];
		double R = 4.0, c = 0.5, L = sqrt(R * R + c * c);
		for (int i = 0; i < MLIP_PATH_WIN; i++) {
			double th = i * step / L;
			pts[i][0] = R * cos(th);
			pts[i][1] = R * sin(th);
			pts[i][2] = c * th;
		}
		if (mlip_path_spline_fit(&sp, 3, (const double(*)[MLIP_MAX_AXES])pts,
		                         MLIP_PATH_WIN) != 0) {
			fprintf(stderr, "bench_pathplan: the spline does not fit\n");
			return 1;
		}
		mlip_path_spline_curve(&sp, &cv);
	}
	/* the model's settings (bench/pathspeed.py): J as given (the caller
	 * applies its margin), 0.98 A, 0.995 vmax, the crawl 2 mm/s */
	struct mlip_path_limits lim = {0};
	lim.n = n;
	for (int k = 0; k < n; k++) {
		lim.accel[k] = 0.98 * 1000.0;
		lim.jerk[k] = points ? J : 0.95 * J;
	}
	lim.vmax = 0.995 * 200.0;
	for (int i = 0; i < nbrake; i++) {
		lim.a_brake[i] = brakes[i];
	}
	lim.n_brake = nbrake;
	lim.v_crawl = 2.0;
	lim.period = 1e-3;
	/* (P6): how far the spline strays from the polyline it was fitted to */
	double max_sag = 0.0;
	long over = 0;
	for (int i = 0; i + 1 < cv.count; i++) {
		double g = mlip_path_piece_sag(&cv, i);
		max_sag = fmax(max_sag, g);
		over += g > band;
	}
	double end = cv.s[cv.count - 1], vpeak = 0.0;
	struct mlip_path_state st = {0.0, 0.0, 0.0, 0, 0};
	long work = 0, periods = 0, moved = 0;
	uint64_t hash = 14695981039346656037ull;
	FILE *fo = out ? fopen(out, "w") : NULL;
	if (out && !fo) {
		perror(out);
		return 1;
	}
	/* to the end: the plan's own last state is at rest there (no tail) */
	while (!(st.v == 0.0 && st.a == 0.0 && end - st.s <= 1e-8 && periods > 0)) {
		long w0 = work;
		struct mlip_path_state s0 = st;
		int r = bench_plan_period(&lim, &st, end, &work);
		/* at rest a whole period short of the end: stopped */
		int stalled = s0.v == 0.0 && s0.a == 0.0 && st.v == 0.0 && st.a == 0.0 &&
		              st.s == s0.s && periods > 0;
		if (r < 0 || periods > 1000000 || stalled) {
			fprintf(stderr, "bench_pathplan: the plan %s at s %.9f of %.9f\n",
			        r < 0 ? "left the certified states" : "stopped short", st.s, end);
			return 1;
		}
		moved += r;
		periods++;
		vpeak = fmax(vpeak, st.v);
		hash = fnv(fnv(fnv(hash, st.s), st.v), st.a);
		if (fo) {
			fprintf(fo, "%.17g,%ld\n", st.s, work - w0);
		}
	}
	if (fo && fclose(fo) != 0) {
		perror(out);
		return 1;
	}
	printf(
	    "{\"jerk\": %g, \"step\": %g, \"periods\": %ld, \"faster\": %ld, "
	    "\"run_periods\": %ld, \"peak_speed\": %.3f, \"s\": %.17g, \"v\": %.17g, "
	    "\"a\": %.17g, \"length\": %.17g, \"states\": \"%016llx\", "
	    "\"pieces\": %d, \"max_sag_mm\": %.3g, \"band_mm\": %g, \"pieces_over_band\": %ld}\n",
	    J, points ? 0.0 : step, periods, moved, work, vpeak, st.s, st.v, st.a, end,
	    (unsigned long long)hash, cv.count - 1, max_sag, band, over);
	return 0;
}
