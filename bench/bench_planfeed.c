/*
 * bench_planfeed - mlip-rt's planning thread for [TRAJ] JERK_PLAN = path,
 * run on this host (issue 21; tools/lib/planfeed.h): a producer thread
 * (SCHED_OTHER) reads the program as mlip-feed sends it (the smoothed
 * blocks as ring records), runs the plan's controller and the streaming
 * plan, and fills the planned queue; the main thread is the period: one
 * mlip_planq_step a period.
 *
 *   build/bench_planfeed --config CFG [--trace OUT.csv] [--paced] FILE.ngc
 *   build/bench_planfeed --config CFG [--trace OUT.csv] --lag N [--starve K] FILE.ngc
 *
 * Without --paced the period waits for each entry (the thread always keeps
 * up): the trace must equal `mlip-sim --config CFG --strategy smooth
 * --trace` (JERK_PLAN = path in CFG) byte for byte. With --paced the period
 * runs on a 1 ms clock (clock_nanosleep, SCHED_OTHER: no real-time claim)
 * and a dry queue brakes, as mlip-rt's period would. Prints JSON: periods,
 * the planning thread's CPU per planned period (median, p99, max, us:
 * CLOCK_THREAD_CPUTIME_ID around mlip_planfeed_work, the controller
 * periods and pushes before the entry included; the program's reading and
 * smoothing, mlip-feed's share in mlip-rt, not), the queue's low-water mark after
 * its first fill, brakes and starvings.
 *
 * --lag N: one thread, deterministic: before each period the producer
 * fills the queue to N entries ahead (N > MLIP_PLANQ_LEN: a fill that
 * wanders over 1..LEN); --starve K: not before the period K (the queue
 * runs dry there: its braking run). The trace has every period from the
 * first entry on: with no --starve it must equal mlip-sim's (the plan
 * does not depend on the consumer's lag); a starving's trace is what the
 * bus carries when mlip-rt's planning thread is late.
 */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "blockiter.h"
#include "cli.h"
#include "mlip/ctl/state.h"
#include "planfeed.h"
#include "program.h"
#include "simpath.h"

static struct mlip_planner planner;
static struct mlip_smooth_store store;
static struct mlip_ctl ctl;
static struct mlip_pathrun run;
static struct mlip_planq queue;
static struct mlip_planfeed pf;
static struct mlip_config cfg;
static struct mlip_program prog;
static struct mlip_smooth sm;
static struct mlip_smooth_iter si;

#define MAX_SAMPLES (1u << 22)
static float cpu_us[MAX_SAMPLES];
static uint32_t n_cpu;
static int producer_rc, producer_done;

static int program_next(void *ctx, struct mlip_block *b)
{
	return mlip_program_next(ctx, b);
}

static double thread_cpu_us(void)
{
	struct timespec t;
	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
	return (double)t.tv_sec * 1e6 + (double)t.tv_nsec / 1e3;
}

/* Records into the plan's FIFO while it has room (as mlip-feed numbers
 * them: the smoothed blocks 1..n, then END): 0, -1 the program unread. */
static int offer(struct mlip_block_iter *it, uint64_t *seq, int *in_done)
{
	while (!*in_done && mlip_planfeed_room(&pf) > 0) {
		struct mlip_block b;
		struct mlip_ring_rec rec;
		int r = it->next(it->ctx, &b);
		if (r < 0) {
			return -1;
		}
		if (r > 0) {
			mlip_ring_rec_from_block(&rec, &b, ++*seq);
		} else {
			mlip_ring_rec_end(&rec, ++*seq, prog.lines);
			*in_done = 1;
		}
		mlip_planfeed_offer(&pf, &rec);
	}
	return 0;
}

/* The setpoints' trace (to tf, NULL: none) from the machine's home. */
static void trace_open(struct mlip_trace *tr, FILE *tf)
{
	const struct mlip_machine *m = &cfg.machine;
	double home[MLIP_MAX_AXES] = {0};
	for (int k = 0; k < m->n_axes; k++) {
		home[k] = m->axis[k].home;
	}
	mlip_trace_open(tr, tf, m, home);
}

/* The planning thread: records in (as mlip-feed numbers them: the smoothed
 * blocks 1..n, then END), work until the last entry is queued. */
static void *producer(void *arg)
{
	struct mlip_block_iter it = *(struct mlip_block_iter *)arg;
	uint64_t seq = 0;
	int in_done = 0;
	double acc = 0.0; /* the work's CPU since the last planned period */
	for (;;) {
		if (offer(&it, &seq, &in_done) != 0) {
			producer_rc = -2;
			goto out;
		}
		uint64_t before = pf.planned;
		double w0 = thread_cpu_us();
		int r = mlip_planfeed_work(&pf);
		acc += thread_cpu_us() - w0;
		if (pf.planned != before && n_cpu < MAX_SAMPLES) {
			cpu_us[n_cpu++] = (float)acc;
			acc = 0.0;
		}
		if (r < 0 || r == 2) {
			producer_rc = r;
			break;
		}
		if (r == 0) {
			/* the queue is full: sleep a fifth of a period (not spin: the
			 * CPU figure is the work's) */
			struct timespec ts = {0, 200000};
			nanosleep(&ts, NULL);
		}
	}
out:
	__atomic_store_n(&producer_done, 1, __ATOMIC_RELEASE);
	return NULL;
}

static int cmp_float(const void *a, const void *b)
{
	float x = *(const float *)a, y = *(const float *)b;
	return (x > y) - (x < y);
}

static void sleep_until(struct timespec *t, long ns)
{
	t->tv_nsec += ns;
	while (t->tv_nsec >= 1000000000L) {
		t->tv_nsec -= 1000000000L;
		t->tv_sec++;
	}
	while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, t, NULL) == EINTR) {
	}
}

/* --lag N: one thread, deterministic: the producer fills the queue to N
 * entries ahead of the period (N 0: one), then the period pops one. */
static int lagged(struct mlip_block_iter *itp, int lag, long starve, const char *trace_path)
{
	struct mlip_block_iter it = *itp;
	uint64_t seq = 0;
	int in_done = 0, mode = MLIP_PLANQ_WAIT, pdone = 0;
	const struct mlip_machine *m = &cfg.machine;
	FILE *tf = trace_path ? fopen(trace_path, "w") : NULL;
	struct mlip_trace tr;
	double x[MLIP_MAX_AXES];
	trace_open(&tr, tf);
	long k = 0, brakes = 0;
	int want = lag < 1 ? 1 : lag;
	uint64_t rnd = 0x9e3779b97f4a7c15ull * (uint64_t)(lag + 1);
	while (mode != MLIP_PLANQ_DONE) {
		if (lag >
		    MLIP_PLANQ_LEN) { /* a lag that wanders: 1..LEN, new every 1..64 periods */
			rnd ^= rnd << 13;
			rnd ^= rnd >> 7;
			rnd ^= rnd << 17;
			if ((rnd & 63u) == 0u) {
				want = 1 + (int)((rnd >> 8) % MLIP_PLANQ_LEN);
			}
		}
		while (!pdone && k != starve) {
			if (pf.started && (int)(queue.head - queue.tail) >= want) {
				break;
			}
			if (offer(&it, &seq, &in_done) != 0) {
				return 1;
			}
			int r = mlip_planfeed_work(&pf);
			if (r < 0) {
				fprintf(stderr, "bench_planfeed: %s\n", pf.why);
				return 1;
			}
			pdone = r == 2;
			if (r == 0) {
				break;
			}
		}
		if (k == 0 && tr.have_pending == 0) {
			memcpy(tr.pending, pf.start, sizeof(double) * (size_t)m->n_axes);
			tr.have_pending = 1;
		}
		mode = mlip_planq_step(&queue, 0, x);
		if (mode < 0) {
			return 1;
		}
		brakes += mode == MLIP_PLANQ_BRAKE;
		if (mode == MLIP_PLANQ_PLAN || mode == MLIP_PLANQ_DONE || k > 0) {
			mlip_trace_sample_at(&tr, (uint64_t)++k,
			                     mode == MLIP_PLANQ_DONE ? MLIP_STATE_IDLE
			                                             : MLIP_STATE_RUNNING,
			                     x, NULL);
		}
	}
	if (tf != NULL) {
		fclose(tf);
	}
	printf("{\"periods\": %ld, \"brakes\": %ld, \"lag\": %d, \"dropped\": %ld, "
	       "\"peak_count\": %d, \"ctl_periods\": %llu}\n",
	       k, brakes, lag, run.dropped, run.peak_count, (unsigned long long)pf.ctl_periods);
	return 0;
}

int main(int argc, char **argv)
{
	struct mlip_cli_machine mo = {0};
	const char *trace_path = NULL, *path = NULL;
	int paced = 0, lag = -1;
	long starve = -1;
	for (int i = 1; i < argc; i++) {
		if (strcmp(argv[i], "--config") == 0 && i + 1 < argc) {
			mo.config = argv[++i];
		} else if (strcmp(argv[i], "--trace") == 0 && i + 1 < argc) {
			trace_path = argv[++i];
		} else if (strcmp(argv[i], "--paced") == 0) {
			paced = 1;
		} else if (strcmp(argv[i], "--lag") == 0 && i + 1 < argc) {
			lag = atoi(argv[++i]);
		} else if (strcmp(argv[i], "--starve") == 0 && i + 1 < argc) {
			starve = atol(argv[++i]);
		} else if (path == NULL && argv[i][0] != '-') {
			path = argv[i];
		} else {
			fprintf(stderr, "usage: bench_planfeed --config CFG [--trace OUT.csv] "
			                "[--paced] FILE.ngc\n");
			return 2;
		}
	}
	if (path == NULL || mo.config == NULL) {
		fprintf(stderr, "bench_planfeed: --config CFG and FILE.ngc are required\n");
		return 2;
	}
	if (mlip_cli_open_program(path, &mo, &cfg, &prog, "bench_planfeed", stderr) != 0) {
		return 1;
	}
	double feed;
	const char *why = NULL;
	if (mlip_simpath_prescan(&prog, 0.0, &feed, "bench_planfeed", path, "JERK_PLAN = path",
	                         stderr) != 0) {
		return 2;
	}
	if (mlip_planfeed_init(&pf, &cfg, feed, cfg.lookahead, &ctl, &planner, &store, &run, &queue,
	                       &why) != 0) {
		fprintf(stderr, "bench_planfeed: %s\n", why);
		return 2;
	}
	const struct mlip_machine *m = &cfg.machine;
	/* the feeder's smoothing runs on the plan's controller's machine */
	struct mlip_block_iter it = {program_next, &prog};
	it = mlip_smooth_iter(&si, &sm, mlip_planfeed_machine(&pf), it);
	pthread_t th;
	if (lag >= 0) {
		return lagged(&it, lag, starve, trace_path);
	}
	if (pthread_create(&th, NULL, producer, &it) != 0) {
		return 1;
	}
	FILE *tf = trace_path ? fopen(trace_path, "w") : NULL;
	struct mlip_trace tr;
	double x[MLIP_MAX_AXES];
	trace_open(&tr, tf);
	/* wait for the plan's start (the controller's first motion) */
	while (!__atomic_load_n(&pf.started, __ATOMIC_ACQUIRE) &&
	       !__atomic_load_n(&producer_done, __ATOMIC_ACQUIRE)) {
		sched_yield();
	}
	memcpy(tr.pending, pf.start, sizeof(double) * (size_t)m->n_axes);
	tr.have_pending = 1;
	struct timespec clk;
	clock_gettime(CLOCK_MONOTONIC, &clk);
	long period_ns = (long)(m->period_s * 1e9 + 0.5), k = 0, brakes = 0;
	uint32_t low = MLIP_PLANQ_LEN, filled = 0;
	int mode = MLIP_PLANQ_WAIT;
	while (mode != MLIP_PLANQ_DONE && __atomic_load_n(&pf.started, __ATOMIC_ACQUIRE)) {
		if (__atomic_load_n(&producer_done, __ATOMIC_ACQUIRE) && producer_rc < 0) {
			break; /* refused after its start: no entry comes (the queue waited for
			          ever) */
		}
		if (paced) {
			sleep_until(&clk, period_ns);
		} else {
			while (__atomic_load_n(&queue.head, __ATOMIC_ACQUIRE) == queue.tail &&
			       !__atomic_load_n(&producer_done, __ATOMIC_ACQUIRE)) {
				sched_yield();
			}
		}
		uint32_t fill = __atomic_load_n(&queue.head, __ATOMIC_ACQUIRE) - queue.tail;
		filled |= fill == MLIP_PLANQ_LEN;
		if (filled && !__atomic_load_n(&producer_done, __ATOMIC_ACQUIRE) && fill < low) {
			low = fill; /* until the last entry is queued (the queue then drains) */
		}
		mode = mlip_planq_step(&queue, 0, x);
		if (mode < 0 || (!paced && mode == MLIP_PLANQ_BRAKE)) {
			break;
		}
		brakes += mode == MLIP_PLANQ_BRAKE;
		if (mode == MLIP_PLANQ_PLAN || mode == MLIP_PLANQ_DONE) {
			mlip_trace_sample_at(&tr, (uint64_t)++k,
			                     mode == MLIP_PLANQ_DONE ? MLIP_STATE_IDLE
			                                             : MLIP_STATE_RUNNING,
			                     x, NULL);
		}
	}
	pthread_join(th, NULL);
	if (tf != NULL && fclose(tf) != 0) {
		perror(trace_path);
		return 1;
	}
	if (producer_rc < 0) {
		fprintf(stderr, "bench_planfeed: %s: %s at t = %.3f s of the plan's controller\n",
		        path, pf.why ? pf.why : "the program could not be read", pf.why_t);
		return 1;
	}
	if (mode != MLIP_PLANQ_DONE) {
		fprintf(stderr, "bench_planfeed: the period did not end at rest (mode %d)\n", mode);
		return 1;
	}
	qsort(cpu_us, n_cpu, sizeof(cpu_us[0]), cmp_float);
	printf(
	    "{\"periods\": %ld, \"planned\": %llu, \"ctl_periods\": %llu, \"paced\": %d, "
	    "\"cpu_us_per_planned\": {\"median\": %.1f, \"p99\": %.1f, \"max\": %.1f}, "
	    "\"queue_low_water\": %u, \"queue_filled\": %u, \"brakes\": %ld, \"starved\": %ld}\n",
	    k, (unsigned long long)pf.planned, (unsigned long long)pf.ctl_periods, paced,
	    n_cpu ? cpu_us[n_cpu / 2] : 0.0, n_cpu ? cpu_us[(size_t)(n_cpu * 0.99)] : 0.0,
	    n_cpu ? cpu_us[n_cpu - 1] : 0.0, filled ? low : 0u, filled, brakes, queue.c.starved);
	return 0;
}
