/* mlip-latency's report pieces: the system it ran on, a series as JSON
 * (cyclictest's --json shape) and as a table row, the jitter's grade. */
#ifndef MLIP_LATREPORT_H
#define MLIP_LATREPORT_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <sys/utsname.h>
#include <time.h>

#include "json.h"
#include "latstats.h"

struct lat_sysinfo {
	struct utsname u;
	int preempt_rt;     /* uname says PREEMPT_RT, or /sys/kernel/realtime is 1 */
	int sys_realtime;   /* /sys/kernel/realtime (cyclictest's sysinfo.realtime) */
	char isolated[128]; /* /sys/devices/system/cpu/isolated, "" when none */
	long ncpu;
};

void lat_sys_probe(struct lat_sysinfo *s);

/* the percentiles reported, and their JSON keys */
#define LAT_NPCT 4
extern const double lat_pcts[LAT_NPCT];
extern const char *const lat_pct_key[LAT_NPCT];

static inline double lat_us(int64_t ns)
{
	return (double)ns / 1e3;
}

/* Sparse histogram of bins [0, hist_us): {"us": count, ...}, like cyclictest. */
void lat_json_hist(struct mlip_json *j, const char *key, const struct mlip_latstats *s,
                   uint32_t hist_us);
/* max_at: the period of the max (-1: not known) */
void lat_json_series(struct mlip_json *j, const char *key, const struct mlip_latstats *s,
                     long long max_at, uint32_t hist_us);
/* One string per line of w. */
void lat_json_warnings(struct mlip_json *j, const char *key, const char *w);

void lat_fmt_time(char *buf, size_t len, time_t t);
const char *lat_jitter_grade(double max_us);
void lat_print_table(FILE *f, const char *name, const struct mlip_latstats *s, long long max_at);
void lat_print_table_head(FILE *f, const char *what, int with_at);

#endif
