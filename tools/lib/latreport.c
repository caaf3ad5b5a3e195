/* mlip-latency's report pieces (latreport.h). */
#include "latreport.h"

#include <string.h>
#include <unistd.h>

/* ---- the system ------------------------------------------------------------ */

static void read_line(const char *path, char *buf, size_t len)
{
	buf[0] = '\0';
	FILE *f = fopen(path, "r");
	if (f == NULL) {
		return;
	}
	if (fgets(buf, (int)len, f) == NULL) {
		buf[0] = '\0';
	}
	fclose(f);
	buf[strcspn(buf, "\r\n")] = '\0';
}

void lat_sys_probe(struct lat_sysinfo *s)
{
	char buf[16];
	memset(s, 0, sizeof(*s));
	if (uname(&s->u) != 0) {
		memset(&s->u, 0, sizeof(s->u));
	}
	read_line("/sys/kernel/realtime", buf, sizeof(buf));
	s->sys_realtime = buf[0] == '1';
	s->preempt_rt = s->sys_realtime || strstr(s->u.version, "PREEMPT_RT") != NULL;
	read_line("/sys/devices/system/cpu/isolated", s->isolated, sizeof(s->isolated));
	s->ncpu = sysconf(_SC_NPROCESSORS_ONLN);
}

/* ---- JSON ------------------------------------------------------------------- */

const double lat_pcts[LAT_NPCT] = {50.0, 99.0, 99.9, 99.99};
const char *const lat_pct_key[LAT_NPCT] = {"p50", "p99", "p99_9", "p99_99"};

/* Sparse histogram of bins [0, hist_us): {"us": count, ...}, like cyclictest. */
void lat_json_hist(struct mlip_json *j, const char *key, const struct mlip_latstats *s,
                   uint32_t hist_us)
{
	char bin[16];
	uint32_t end = hist_us < s->nbins ? hist_us : s->nbins;
	mlip_json_object(j, key, 1);
	for (uint32_t b = 0; b < end; b++) {
		if (s->bins[b] != 0) {
			snprintf(bin, sizeof(bin), "%u", b);
			mlip_json_uint(j, bin, s->bins[b]);
		}
	}
	mlip_json_close(j);
}

/* max_at: the period of the max (-1: not known) */
void lat_json_series(struct mlip_json *j, const char *key, const struct mlip_latstats *s,
                     long long max_at, uint32_t hist_us)
{
	int capped = 0;
	mlip_json_object(j, key, 0);
	mlip_json_string(j, "unit", "us");
	mlip_json_uint(j, "samples", s->count);
	mlip_json_number(j, "min", "%.3f", lat_us(mlip_latstats_min_ns(s)));
	mlip_json_number(j, "avg", "%.3f", mlip_latstats_mean_ns(s) / 1e3);
	mlip_json_number(j, "max", "%.3f", lat_us(s->max_ns));
	for (int k = 0; k < LAT_NPCT; k++) {
		int ov;
		mlip_json_number(j, lat_pct_key[k], "%.3f",
		                 lat_us(mlip_latstats_percentile_ns(s, lat_pcts[k], &ov)));
		capped |= ov;
	}
	mlip_json_bool(j, "percentiles_in_overflow", capped);
	if (max_at >= 0) {
		mlip_json_int(j, "max_at_period", max_at);
	}
	mlip_json_uint(j, "histogram_us", hist_us);
	lat_json_hist(j, "histogram", s, hist_us);
	mlip_json_uint(j, "overflow", s->count - mlip_latstats_count_below(s, hist_us));
	mlip_json_close(j);
}

/* One string per line of w. */
void lat_json_warnings(struct mlip_json *j, const char *key, const char *w)
{
	mlip_json_array(j, key, 0);
	while (*w) {
		size_t n = strcspn(w, "\n");
		char line[512];
		snprintf(line, sizeof(line), "%.*s", (int)n, w);
		if (n > 0) {
			mlip_json_string(j, NULL, line);
		}
		w += n + (w[n] == '\n');
	}
	mlip_json_close(j);
}

/* ---- report ---------------------------------------------------------------- */

void lat_fmt_time(char *buf, size_t len, time_t t)
{
	struct tm tm;
	localtime_r(&t, &tm);
	strftime(buf, len, "%a, %d %b %Y %H:%M:%S %z", &tm);
}

const char *lat_jitter_grade(double max_us)
{
	/* LinuxCNC's reading of latency-test's max jitter */
	if (max_us < 20) {
		return "very good";
	}
	if (max_us <= 50) {
		return "good";
	}
	if (max_us <= 100) {
		return "fair";
	}
	return "poor";
}

void lat_print_table(FILE *f, const char *name, const struct mlip_latstats *s, long long max_at)
{
	char at[24] = "";
	if (max_at >= 0) {
		snprintf(at, sizeof(at), " %10lld", max_at);
	}
	fprintf(f, "  %-20s %10llu %8.1f %8.1f %8.1f %8.1f %8.1f %8.1f %8.1f%s\n", name,
	        (unsigned long long)s->count, lat_us(mlip_latstats_min_ns(s)),
	        mlip_latstats_mean_ns(s) / 1e3, lat_us(mlip_latstats_percentile_ns(s, 50, NULL)),
	        lat_us(mlip_latstats_percentile_ns(s, 99, NULL)),
	        lat_us(mlip_latstats_percentile_ns(s, 99.9, NULL)),
	        lat_us(mlip_latstats_percentile_ns(s, 99.99, NULL)), lat_us(s->max_ns), at);
}

void lat_print_table_head(FILE *f, const char *what, int with_at)
{
	fprintf(f, "  %-20s %10s %8s %8s %8s %8s %8s %8s %8s%s\n", what, "samples", "min", "avg",
	        "p50", "p99", "p99.9", "p99.99", "max", with_at ? "     max at" : "");
}
