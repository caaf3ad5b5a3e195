/* cyclictest, side by side (latcyclic.h). */
#include "latcyclic.h"

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

/* ---- cyclictest, side by side ---------------------------------------------- */

static char *slurp(const char *path)
{
	FILE *f = fopen(path, "r");
	if (f == NULL) {
		return NULL;
	}
	size_t cap = 4096, n = 0;
	char *buf = malloc(cap);
	while (buf != NULL) {
		size_t got = fread(buf + n, 1, cap - n - 1, f);
		n += got;
		if (got == 0) {
			break;
		}
		if (cap - n - 1 == 0) {
			char *nb = realloc(buf, cap * 2);
			if (nb == NULL) {
				free(buf);
				buf = NULL;
				break;
			}
			buf = nb;
			cap *= 2;
		}
	}
	fclose(f);
	if (buf != NULL) {
		buf[n] = '\0';
	}
	return buf;
}

/* Run cyclictest with our settings; its -h histogram (stdout) becomes a
 * latstats series like ours, overflow samples at its max. 0 or -1. */
int lat_run_cyclictest(const struct lat_opts *o, int64_t period_ns, double elapsed_s,
                       uint32_t hist_us, struct lat_ct_result *ct)
{
	char a_i[32], a_p[32], a_a[32], a_h[32], a_d[32], a_l[32],
	    json_path[] = "/tmp/mlip-latency-ctXXXXXX";
	const char *argv[32];
	int n = 0;
	memset(ct, 0, sizeof(*ct));
	ct->avg_us = -1;
	int jfd = mkstemp(json_path);
	if (jfd >= 0) {
		close(jfd);
	}
	argv[n++] = "cyclictest";
	argv[n++] = "-q";
	snprintf(a_i, sizeof(a_i), "-i%lld", (long long)(period_ns / 1000));
	argv[n++] = a_i;
	if (o->priority > 0) {
		snprintf(a_p, sizeof(a_p), "-p%d", o->priority);
		argv[n++] = a_p;
	}
	if (o->lock_memory) {
		argv[n++] = "-m";
	}
	if (o->cpu >= 0) {
		snprintf(a_a, sizeof(a_a), "-a%d", o->cpu);
		argv[n++] = a_a;
	}
	snprintf(a_h, sizeof(a_h), "-h%u", hist_us);
	argv[n++] = a_h;
	if (o->loops != 0) {
		snprintf(a_l, sizeof(a_l), "-l%llu", (unsigned long long)o->loops);
		argv[n++] = a_l;
	}
	if (o->duration_s > 0 || o->loops == 0) {
		/* cyclictest takes whole seconds; an open-ended run of ours lasted elapsed_s */
		double d = o->duration_s > 0 ? o->duration_s : elapsed_s;
		snprintf(a_d, sizeof(a_d), "-D%.0f", ceil(d) < 1 ? 1 : ceil(d));
		argv[n++] = a_d;
	}
	size_t used = 0; /* the command as shown: without the temporary --json file */
	for (int k = 0; k < n && used < sizeof(ct->cmd); k++) {
		used += (size_t)snprintf(ct->cmd + used, sizeof(ct->cmd) - used, "%s%s",
		                         k ? " " : "", argv[k]);
	}
	if (jfd >= 0) {
		argv[n++] = "--json";
		argv[n++] = json_path;
	}
	argv[n] = NULL;

	int pfd[2];
	if (pipe(pfd) != 0) {
		perror(PROG ": pipe");
		unlink(json_path);
		return -1;
	}
	fflush(NULL);
	pid_t pid = fork();
	if (pid < 0) {
		perror(PROG ": fork");
		close(pfd[0]);
		close(pfd[1]);
		unlink(json_path);
		return -1;
	}
	if (pid == 0) {
		dup2(pfd[1], STDOUT_FILENO);
		close(pfd[0]);
		close(pfd[1]);
		execvp("cyclictest", (char *const *)argv);
		fprintf(stderr,
		        PROG ": cannot run cyclictest: %s (Debian: apt-get install rt-tests)\n",
		        strerror(errno));
		_exit(127);
	}
	close(pfd[1]);
	ct->bins = calloc(hist_us, sizeof(uint64_t));
	if (ct->bins == NULL) {
		fprintf(stderr, PROG ": out of memory\n");
		close(pfd[0]);
		waitpid(pid, NULL, 0);
		unlink(json_path);
		return -1;
	}
	mlip_latstats_init(&ct->s, ct->bins, hist_us, BIN_NS);
	FILE *f = fdopen(pfd[0], "r");
	char line[256];
	unsigned long long overflow = 0, maxv = 0, minv = 0, b, cnt;
	int have_max = 0, have_min = 0;
	while (f != NULL && fgets(line, sizeof(line), f) != NULL) {
		if (sscanf(line, "%llu %llu", &b, &cnt) == 2 && line[0] != '#') {
			if (cnt > 0) {
				mlip_latstats_add_n(&ct->s, (int64_t)b * BIN_NS, cnt);
			}
		} else if (sscanf(line, "# Histogram Overflows: %llu", &overflow) == 1) {
		} else if (sscanf(line, "# Max Latencies: %llu", &maxv) == 1) {
			have_max = 1;
		} else if (sscanf(line, "# Min Latencies: %llu", &minv) == 1) {
			have_min = 1;
		}
	}
	if (f != NULL) {
		fclose(f);
	} else {
		close(pfd[0]);
	}
	int status = 0;
	waitpid(pid, &status, 0);
	if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || !have_max) {
		fprintf(stderr, PROG ": cyclictest did not complete (%s)\n",
		        WIFEXITED(status) ? "exit status" : "killed");
		unlink(json_path);
		return -1;
	}
	/* the overflow samples lie above the histogram: at most its max */
	mlip_latstats_add_n(&ct->s, (int64_t)maxv * BIN_NS, overflow);
	if (have_min && ct->s.count > 0) {
		ct->s.min_ns = (int64_t)minv * BIN_NS;
	}
	if (jfd >= 0) {
		ct->json = slurp(json_path);
		unlink(json_path);
		const char *a = ct->json ? strstr(ct->json, "\"avg\":") : NULL;
		if (a != NULL) {
			ct->avg_us = strtod(a + 6, NULL);
		}
	}
	ct->ran = 1;
	return 0;
}
