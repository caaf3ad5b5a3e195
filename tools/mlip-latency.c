/*
 * mlip-latency - the latency test of the controller's own periodic loop.
 *
 * It runs the loop that mlip-rt runs (mlip_rt_prepare + mlip_rt_run: the same
 * thread, priority, memory locking and absolute CLOCK_MONOTONIC schedule) with
 * one of three loads:
 *
 *   --idle        wake and sleep only (cyclictest's measurement)
 *   --plan FILE   the real controller period (mlip_period_tick, as
 *                 `mlip-rt --can none` runs it) on the program, fed into a
 *                 private ring by a feeder thread in this process (what
 *                 mlip-feed does through shared memory), plus the CAN
 *                 encoding of every period's setpoints, frames discarded
 *   --can IFACE   the same, and the frames really sent on IFACE; the send is
 *                 timed on its own
 *
 * The program restarts when it ends, so the load lasts the whole run.
 *
 * Per period (samples in preallocated histograms, nothing printed, allocated,
 * locked or blocked on the periodic path):
 *
 *   wake-up latency  actual wake - scheduled wake            (>= 0, cyclictest)
 *   period jitter    |interval between wakes - scheduled interval|
 *                    (two-sided, LinuxCNC latency-test; the scheduled
 *                    interval is the period unless deadlines were skipped)
 *   compute          the period's work, from wake to done (the loop's own
 *                    `after` figure; includes the send)
 *   send             --can only: the socket sends of the period
 *   overruns         deadlines missed: floor((latency + compute) / period)
 *                    per period, the rule by which the loop skips them
 *
 * Statistics: tools/lib/latstats.h (1 us bins, nearest-rank percentiles).
 * Command line after cyclictest's where they overlap (-p -i -D -l -a -m -h -q
 * --json); the JSON is a superset of cyclictest's --json file.
 */
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/utsname.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "blockiter.h"
#include "cli.h"
#include "confload.h"
#include "json.h"
#include "latcyclic.h"
#include "latopts.h"
#include "latreport.h"
#include "latstats.h"
#include "mlip/can/canenc.h"
#include "mlip/ipc/ring.h"
#include "mlip/motion/smooth.h"
#include "program.h"
#include "rt.h"

#define VERSION       "1"
#define KEEP_HIST_US  100000      /* histogram kept for percentiles: 0..100 ms at least */
#define FEED_BATCH    256u        /* records per push */
#define FEED_SLEEP_NS 1000000L    /* feeder: ring full, look again in 1 ms */
#define LIVE_NS       1000000000L /* live line refresh */
#define MAX_BUS_LOAD  0.70        /* mlip-rt's budget */

static const char *const mode_name[] = {"idle", "plan", "can"};

enum { S_LAT, S_JIT, S_COMP, S_SEND, S_N };
static const char *const series_key[S_N] = {"wakeup_latency", "period_jitter", "compute", "send"};
static const char *const series_label[S_N] = {"wake-up latency", "period jitter", "compute",
                                              "CAN send"};

/* ---- what the periodic path touches: all allocated and touched before ---- */

struct run {
	/* settings */
	int mode;
	int64_t period_ns;
	int64_t duration_ns; /* 0: no limit */
	uint64_t loops;      /* 0: no limit */
	/* schedule bookkeeping */
	uint64_t first_deadline_ns, prev_deadline_ns;
	uint64_t periods;
	/* statistics */
	struct mlip_latstats s[S_N];
	uint64_t max_at[S_N]; /* period (cycle) of each series' max */
	uint64_t overruns, overrun_periods;
	int64_t send_ns; /* this period's send time, for `after` */
	/* the load */
	struct mlip_period *ctl;
	struct mlip_canbus *io; /* MODE_CAN */
	int encode;             /* encode frames each period */
	uint64_t frames_encoded, encode_faults;
	uint64_t passes, moving_periods;
	uint32_t last_state;
	/* live view for the display thread: relaxed atomics */
	uint64_t live_cycles, live_act_ns, live_max_ns, live_overruns;
};

static struct run R;
static struct mlip_planner planner; /* static, as in mlip-rt: locked and prefaulted */
static struct mlip_period ctl;
static struct mlip_canbus bus = {.fd = -1};
static struct mlip_can_port port;

/* The period's work. */
static int lat_tick(void *ctx, const struct mlip_rt_tick *t)
{
	struct run *r = ctx;
	if (t->cycle == 0) {
		r->first_deadline_ns = t->deadline_ns;
	}
	r->send_ns = 0;
	if (r->mode != MODE_IDLE) {
		struct mlip_period *c = r->ctl;
		(void)mlip_period_tick(c, t); /* never asked to exit: no exit_request */
		uint32_t state = c->out.status.state;
		if (state == MLIP_STATE_RUNNING) {
			r->moving_periods++;
		}
		if (state == MLIP_STATE_IDLE && r->last_state != MLIP_STATE_IDLE) {
			r->passes++; /* a program run ended: the next one is in the ring */
		}
		r->last_state = state;
		/* the controller encodes (and with --can sends) its own frames */
		r->send_ns = c->send_ns;
		r->frames_encoded = c->out.counts.frames_encoded;
		r->encode_faults = c->out.status.reason == MLIP_WHY_POSITION_RANGE;
	}
	if (r->loops != 0 && t->cycle + 1 >= r->loops) {
		return 1;
	}
	if (r->duration_ns != 0 &&
	    (int64_t)(t->deadline_ns - r->first_deadline_ns) + r->period_ns >= r->duration_ns) {
		return 1;
	}
	return 0;
}

static void sample(struct run *r, int k, int64_t ns, uint64_t cycle)
{
	int64_t before = r->s[k].max_ns;
	mlip_latstats_add(&r->s[k], ns);
	if (r->s[k].max_ns != before || r->s[k].count == 1) {
		r->max_at[k] = cycle;
	}
}

/* After each period: the samples. */
static void lat_after(void *ctx, const struct mlip_rt_tick *t, int64_t compute_ns)
{
	struct run *r = ctx;
	sample(r, S_LAT, t->latency_ns, t->cycle);
	if (t->cycle > 0) {
		int64_t expected = (int64_t)(t->deadline_ns - r->prev_deadline_ns);
		int64_t d = t->interval_ns - expected;
		sample(r, S_JIT, d < 0 ? -d : d, t->cycle);
	}
	r->prev_deadline_ns = t->deadline_ns;
	sample(r, S_COMP, compute_ns, t->cycle);
	if (r->mode == MODE_CAN) {
		sample(r, S_SEND, r->send_ns, t->cycle);
	}
	uint64_t missed = (uint64_t)((t->latency_ns + compute_ns) / r->period_ns);
	if (missed > 0) {
		r->overruns += missed;
		r->overrun_periods++;
	}
	r->periods = t->cycle + 1;
	__atomic_store_n(&r->live_cycles, t->cycle + 1, __ATOMIC_RELAXED);
	__atomic_store_n(&r->live_act_ns, (uint64_t)t->latency_ns, __ATOMIC_RELAXED);
	__atomic_store_n(&r->live_max_ns, (uint64_t)r->s[S_LAT].max_ns, __ATOMIC_RELAXED);
	__atomic_store_n(&r->live_overruns, r->overruns, __ATOMIC_RELAXED);
}

/* ---- the feeder thread: keeps the private ring full, program after program */

struct feeder {
	struct mlip_ring *ring;
	const struct mlip_program_list *prog;
	uint32_t end_line;
	size_t next; /* 0..n-1: block next, n: the END record */
	int stop;    /* atomic */
	struct mlip_ring_rec recs[FEED_BATCH];
};

/* Push as many records as fit (at most FEED_BATCH); returns how many. */
static uint32_t feed_some(struct feeder *f)
{
	uint32_t space = mlip_ring_space(f->ring), k = 0;
	size_t n = f->prog->n, idx = f->next;
	for (; k < space && k < FEED_BATCH; k++) {
		if (idx < n) {
			mlip_ring_rec_from_block(&f->recs[k], &f->prog->blocks[idx], idx + 1);
		} else {
			mlip_ring_rec_end(&f->recs[k], n + 1, f->end_line);
		}
		idx = idx < n ? idx + 1 : 0;
	}
	uint32_t got = k > 0 ? mlip_ring_push_n(f->ring, f->recs, k) : 0;
	f->next = (f->next + got) % (n + 1);
	return got;
}

static void *feeder_main(void *arg)
{
	struct feeder *f = arg;
	while (!__atomic_load_n(&f->stop, __ATOMIC_ACQUIRE)) {
		if (feed_some(f) < FEED_BATCH) {
			struct timespec ts = {0, FEED_SLEEP_NS};
			(void)clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, NULL);
		}
	}
	return NULL;
}

/* ---- the live line (a terminal, not -q) ------------------------------------ */

static int live_stop;

static void *live_main(void *arg)
{
	(void)arg;
	while (!__atomic_load_n(&live_stop, __ATOMIC_ACQUIRE)) {
		struct timespec ts = {LIVE_NS / 1000000000L, LIVE_NS % 1000000000L};
		(void)clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, NULL);
		uint64_t c = __atomic_load_n(&R.live_cycles, __ATOMIC_RELAXED);
		uint64_t act = __atomic_load_n(&R.live_act_ns, __ATOMIC_RELAXED);
		uint64_t max = __atomic_load_n(&R.live_max_ns, __ATOMIC_RELAXED);
		uint64_t ovr = __atomic_load_n(&R.live_overruns, __ATOMIC_RELAXED);
		fprintf(stderr,
		        "\r" PROG
		        ": C:%10llu Act:%8.1f Max:%8.1f us (wake-up latency), %llu overruns",
		        (unsigned long long)c, act / 1e3, max / 1e3, (unsigned long long)ovr);
		fflush(stderr);
	}
	fputs("\r\033[K", stderr);
	return NULL;
}

/* ---- signals ------------------------------------------------------------- */

static void on_signal(int sig)
{
	(void)sig;
	mlip_rt_request_stop(); /* async-signal-safe: the loop ends after this period */
}

/* ---- report ---------------------------------------------------------------- */

/* cyclictest's -h output, one column per series. */
static void print_histogram(FILE *f, int nseries, uint32_t hist_us)
{
	fprintf(f, "# Histogram (us; columns:");
	for (int k = 0; k < nseries; k++) {
		fprintf(f, " %s", series_key[k]);
	}
	fprintf(f, ")\n");
	for (uint32_t b = 0; b < hist_us; b++) {
		fprintf(f, "%06u", b);
		for (int k = 0; k < nseries; k++) {
			fprintf(f, " %06llu",
			        (unsigned long long)(b < R.s[k].nbins ? R.s[k].bins[b] : 0));
		}
		fputc('\n', f);
	}
	const char *rows[] = {"Total", "Min", "Avg", "Max", "Histogram Overflows"};
	for (int r = 0; r < 5; r++) {
		fprintf(f, "# %s%s:", rows[r], r >= 1 && r <= 3 ? " Latencies" : "");
		for (int k = 0; k < nseries; k++) {
			const struct mlip_latstats *s = &R.s[k];
			uint64_t below = mlip_latstats_count_below(s, hist_us);
			unsigned long long v =
			    r == 0   ? below
			    : r == 1 ? (unsigned long long)(mlip_latstats_min_ns(s) / 1000)
			    : r == 2 ? (unsigned long long)(mlip_latstats_mean_ns(s) / 1e3)
			    : r == 3 ? (unsigned long long)(s->max_ns / 1000)
			             : s->count - below;
			fprintf(f, " %05llu", v);
		}
		fputc('\n', f);
	}
}

/* ---- set up --------------------------------------------------------------------- */

/* Everything a test holds besides R (the loop's own). */
struct app {
	struct mlip_config cfg;
	struct mlip_program_list prog;
	struct feeder feed;
	void *ring_mem;
	struct mlip_smooth_store *smooth; /* the smooth strategy's planner data, NULL otherwise */
	int64_t period_ns;
	mlip_can_profile prof;
	pthread_attr_t small;
	pthread_t feeder_th, live_th;
	int feeder_started, live_started;
	struct mlip_rt_opts ro;
	struct mlip_rt_report rep, run;
	char chosen[256];                                       /* what was chosen away */
	char warnings[256 + 2 * sizeof(struct mlip_rt_report)]; /* every warning, for the JSON */
	time_t t_start, t_end;
	uint64_t t0_ns, t1_ns;
	struct lat_sysinfo sys;
	char summary[768];
	struct lat_ct_result ct;
};

/* The load: config (its period, or -i's), program (smoothed with
 * --strategy smooth, as mlip-feed sends it), the CAN interface. 0, or the
 * exit status. */
static int load(const struct lat_opts *o, struct app *a)
{
	char info[256];
	if (mlip_config_load(o->config, &a->cfg, stderr) != 0) {
		if (!o->config_given) {
			fprintf(stderr,
			        PROG ": hint: run from the repository root, or pass --config\n");
		}
		return 1;
	}
	if (o->interval_us) {
		a->cfg.machine.period_s = (double)o->interval_us * 1e-6;
		struct mlip_config_error e;
		if (mlip_machine_check(&a->cfg.machine, &e) != MLIP_OK) {
			mlip_config_perror(stderr, PROG, &e);
			return 2;
		}
	}
	a->period_ns = (int64_t)(a->cfg.machine.period_s * 1e9 + 0.5);
	int rc = mlip_program_list_load(o->program, &a->cfg.machine, &a->prog);
	if (rc < 0) {
		fprintf(stderr, PROG ": %s: %s\n", o->program, a->prog.r.msg);
		return 1;
	}
	if (rc > 0) {
		mlip_program_print_errors(&a->prog.r, o->program, stderr);
		return 1;
	}
	if (a->prog.n == 0) {
		fprintf(stderr, PROG ": %s: no motion to run\n", o->program);
		return 1;
	}
	if (o->strategy == MLIP_STRATEGY_SMOOTH) {
		/* the ring carries the smoothed blocks, as from mlip-feed */
		struct mlip_block *sb;
		size_t sn;
		if (mlip_smooth_program(&a->cfg.machine, a->prog.blocks, a->prog.n, &sb, &sn) !=
		    0) {
			fprintf(stderr, PROG ": %s: out of memory smoothing the program\n",
			        o->program);
			return 1;
		}
		free(a->prog.blocks);
		a->prog.blocks = sb;
		a->prog.n = a->prog.cap = sn;
	}
	if (mlip_can_profile_parse(a->cfg.can.profile, &a->prof) != MLIP_OK) {
		a->prof = MLIP_CAN_CIA402;
	}
	if (o->mode != MODE_CAN) {
		return 0;
	}
	struct mlip_can_load l;
	if (mlip_can_load_breakdown(a->prof, a->cfg.machine.n_axes, a->cfg.can.bitrate,
	                            a->cfg.can.data_bitrate, a->cfg.machine.period_s,
	                            &l) == MLIP_OK &&
	    l.load > MAX_BUS_LOAD) {
		fprintf(stderr,
		        PROG
		        ": warning: bus load %.1f %% is above mlip-rt's %.0f %% budget (mlip-rt "
		        "would refuse this configuration)\n",
		        l.load * 100.0, MAX_BUS_LOAD * 100.0);
	}
	if (mlip_canbus_check(o->iface, info, sizeof(info)) != 0) {
		fprintf(stderr, PROG ": %s\n", info);
		return 1;
	}
	if (!o->quiet) {
		fprintf(stderr, PROG ": %s\n", info);
	}
	if (mlip_canbus_open(&bus, o->iface, a->prof == MLIP_CAN_FD, NULL, 0, info, sizeof(info)) !=
	    0) {
		fprintf(stderr, PROG ": %s\n", info);
		return 1;
	}
	mlip_canbus_port(&bus, &port);
	return 0;
}

/* The controller's period on a private ring, filled by a feeder thread
 * (what mlip-feed does through shared memory). 0, or the exit status. */
static int start_load(const struct lat_opts *o, struct app *a)
{
	uint32_t cap = MLIP_RING_CAPACITY;
	size_t bytes = mlip_ring_bytes(cap);
	if (posix_memalign(&a->ring_mem, MLIP_RING_LINE, bytes) != 0) {
		fprintf(stderr, PROG ": out of memory for the ring\n");
		return 1;
	}
	memset(a->ring_mem, 0, bytes);
	if (mlip_ring_format_machine(a->ring_mem, bytes, cap, &a->cfg.machine) != MLIP_OK) {
		fprintf(stderr, PROG ": cannot format the ring\n");
		return 1;
	}
	struct mlip_ring *ring = a->ring_mem;
	/* the smooth strategy's planner data, as mlip-rt: only smooth has it */
	if (o->strategy == MLIP_STRATEGY_SMOOTH &&
	    (a->smooth = calloc(1, sizeof(*a->smooth))) == NULL) {
		fprintf(stderr, PROG ": out of memory for the smooth strategy's look-ahead\n");
		return 1;
	}
	/* the latency test counts missed periods; it does not hold on them */
	struct mlip_ctl_opts co = {.strategy = (mlip_strategy)o->strategy,
	                           .smooth = a->smooth,
	                           .lookahead = a->cfg.lookahead,
	                           .stall_periods = UINT32_MAX,
	                           .can = &a->cfg.can};
	const struct mlip_can_port *bp = o->mode == MODE_CAN ? &port : NULL;
	if (mlip_period_init(&ctl, &planner, &a->cfg.machine, &co, ring, bp, NULL) != 0) {
		co.can = NULL;
		if (o->mode == MODE_CAN ||
		    mlip_period_init(&ctl, &planner, &a->cfg.machine, &co, ring, NULL, NULL) != 0) {
			fprintf(stderr, PROG ": the [CAN] settings of %s do not fit this machine\n",
			        o->config);
			return 1;
		}
		fprintf(stderr, PROG ": note: [CAN] settings do not fit: frames not encoded\n");
	} else {
		R.encode = 1;
	}
	memset(&planner.seg, 0, sizeof(planner.seg)); /* prefault the look-ahead, as mlip-rt */
	if (a->smooth != NULL) {
		memset(a->smooth, 0, sizeof(*a->smooth));
	}
	R.ctl = &ctl;
	R.io = o->mode == MODE_CAN ? &bus : NULL;
	R.last_state = MLIP_STATE_IDLE;
	a->feed.ring = ring;
	a->feed.prog = &a->prog;
	a->feed.end_line = a->prog.lines;
	while (feed_some(&a->feed) > 0) { /* the ring full before the first period */
	}
	if (pthread_create(&a->feeder_th, &a->small, feeder_main, &a->feed) != 0) {
		fprintf(stderr, PROG ": cannot start the feeder thread\n");
		return 1;
	}
	a->feeder_started = 1;
	return 0;
}

/* The load, the histograms, the real-time set-up as mlip-rt's (after every
 * allocation, so that mlip_rt_prepare's memlock check sees what is really
 * locked), the warnings. 0, or the exit status. */
static int set_up(const struct lat_opts *o, struct app *a)
{
	a->t_start = time(NULL);
	a->period_ns = (o->interval_us ? o->interval_us : DEFAULT_INTERVAL_US) * 1000;
	a->prof = MLIP_CAN_CIA402;
	memset(&R, 0, sizeof(R));
	R.mode = o->mode;
	int rc = o->mode != MODE_IDLE ? load(o, a) : 0;
	if (rc != 0) {
		return rc;
	}
	/* histograms: allocated and touched now, before mlockall (MCL_CURRENT covers
	 * them, and its RLIMIT_MEMLOCK check counts them) */
	uint32_t keep = o->hist_us > KEEP_HIST_US ? o->hist_us : KEEP_HIST_US;
	uint32_t four = (uint32_t)(4 * (a->period_ns / BIN_NS));
	keep = keep < four ? four : keep;
	for (int k = 0; k < S_N; k++) {
		uint64_t *b = malloc((size_t)keep * sizeof(uint64_t));
		if (b == NULL) {
			fprintf(stderr, PROG ": out of memory for the histograms\n");
			return 1;
		}
		mlip_latstats_init(&R.s[k], b, keep, BIN_NS); /* zeroes: every page touched */
	}
	R.period_ns = a->period_ns;
	R.duration_ns = (int64_t)(o->duration_s * 1e9 + 0.5);
	R.loops = o->loops;
	/* helper threads: small stacks (the default, often 8 MiB, would be locked
	 * whole and exhaust an unprivileged RLIMIT_MEMLOCK) */
	pthread_attr_init(&a->small);
	pthread_attr_setstacksize(&a->small, 256 * 1024);
	if (o->mode != MODE_IDLE && (rc = start_load(o, a)) != 0) {
		return rc;
	}
	a->ro = (struct mlip_rt_opts){.period_ns = a->period_ns,
	                              .priority = o->priority,
	                              .cpu = o->cpu,
	                              .lock_memory = o->lock_memory};
	mlip_rt_prepare(&a->ro, &a->rep);
	/* what was chosen away: mlip_rt_prepare warns only about what failed */
	if (o->priority == 0) {
		snprintf(
		    a->chosen, sizeof(a->chosen), "%s",
		    "priority 0: the loop runs SCHED_OTHER, not real-time; mlip-rt runs -p 80\n");
	}
	if (!o->lock_memory) {
		size_t used = strlen(a->chosen);
		snprintf(
		    a->chosen + used, sizeof(a->chosen) - used, "%s",
		    "memory not locked (--no-mlockall): page faults can stall the loop; mlip-rt "
		    "locks it\n");
	}
	mlip_cli_on_stop_signals(on_signal);
	/* what is being measured, and what is not real-time about it */
	if (!o->quiet) {
		char lim[64] = "until Ctrl-C";
		if (o->duration_s > 0) {
			snprintf(lim, sizeof(lim), "for %g s", o->duration_s);
		} else if (o->loops) {
			snprintf(lim, sizeof(lim), "for %llu periods",
			         (unsigned long long)o->loops);
		}
		fprintf(stderr, PROG ": %s load%s%s%s%s, period %lld us, %s\n", mode_name[o->mode],
		        o->mode == MODE_IDLE ? "" : " ", o->mode == MODE_IDLE ? "" : o->program,
		        o->mode == MODE_CAN ? " on " : "", o->mode == MODE_CAN ? o->iface : "",
		        (long long)(a->period_ns / 1000), lim);
	}
	fprintf(stderr, "%s%s", a->chosen, a->rep.warnings);
	return 0;
}

/* ---- run -------------------------------------------------------------------------- */

/* The loop (and the live line on a terminal); 0, or 1 when it did not start. */
static int run(const struct lat_opts *o, struct app *a)
{
	if (!o->quiet && isatty(STDERR_FILENO)) {
		a->live_started = pthread_create(&a->live_th, &a->small, live_main, NULL) == 0;
	}
	memset(&a->run, 0, sizeof(a->run));
	a->t0_ns = mlip_now_ns();
	int rc = mlip_rt_run(&a->ro, lat_tick, lat_after, &R, &a->run);
	a->t1_ns = mlip_now_ns();
	a->t_end = time(NULL);
	if (a->live_started) {
		__atomic_store_n(&live_stop, 1, __ATOMIC_RELEASE);
		pthread_join(a->live_th, NULL);
	}
	if (a->feeder_started) {
		__atomic_store_n(&a->feed.stop, 1, __ATOMIC_RELEASE);
		pthread_join(a->feeder_th, NULL);
	}
	if (rc < 0) {
		fprintf(stderr, PROG ": cannot start the loop: %s\n", strerror(-rc));
		return 1;
	}
	if (a->run.warnings[0]) {
		fprintf(stderr, "%s", a->run.warnings);
	}
	snprintf(a->warnings, sizeof(a->warnings), "%s%s%s", a->chosen, a->rep.warnings,
	         a->run.warnings);
	lat_sys_probe(&a->sys);
	return 0;
}

/* ---- report ----------------------------------------------------------------------- */

/* The tables, the load and the summary line (on out). */
static void print_results(const struct lat_opts *o, struct app *a, FILE *out)
{
	char info[64], where[32] = "";
	int nseries = o->mode == MODE_CAN ? S_N : S_SEND;
	double elapsed_s = R.periods ? (double)(a->t1_ns - a->t0_ns) / 1e9 : 0.0;
	if (o->hist_given) {
		print_histogram(out, nseries, o->hist_us);
	}
	if (a->run.pinned) {
		snprintf(where, sizeof(where), " on CPU %d", o->cpu);
	}
	fprintf(out, PROG ": %s%s%s, %llu periods of %lld us (%.1f s)\n", mode_name[o->mode],
	        o->mode == MODE_IDLE ? "" : " ", o->mode == MODE_IDLE ? "" : o->program,
	        (unsigned long long)R.periods, (long long)(a->period_ns / 1000), elapsed_s);
	if (a->run.fifo) {
		snprintf(info, sizeof(info), "SCHED_FIFO priority %d", o->priority);
	} else {
		snprintf(info, sizeof(info), "SCHED_OTHER (not real-time)");
	}
	fprintf(out, "  %s%s, memory %s, kernel %s %s, isolated CPUs: %s\n", info, where,
	        a->rep.locked ? "locked" : "not locked", a->sys.u.release,
	        a->sys.preempt_rt ? "PREEMPT_RT" : "(not PREEMPT_RT)",
	        a->sys.isolated[0] ? a->sys.isolated : "none");
	lat_print_table_head(out, "us", 1);
	for (int k = 0; k < nseries; k++) {
		lat_print_table(out, series_label[k], &R.s[k], (long long)R.max_at[k]);
	}
	if (o->mode != MODE_IDLE) {
		const struct mlip_ctl_counts *n = &ctl.out.counts;
		fprintf(
		    out,
		    "  load: %s, %llu runs of the program finished, %llu blocks taken, %.1f %% of "
		    "periods moving, %llu underruns, %llu frames %s",
		    o->program, (unsigned long long)R.passes,
		    (unsigned long long)n->blocks_consumed,
		    R.periods ? 100.0 * (double)R.moving_periods / (double)R.periods : 0.0,
		    (unsigned long long)n->underruns, (unsigned long long)R.frames_encoded,
		    o->mode == MODE_CAN ? "encoded" : "encoded and discarded");
		if (o->mode == MODE_CAN) {
			fprintf(out,
			        ", %llu sent, %llu dropped (tx queue full), %llu bus errors on %s",
			        (unsigned long long)ctl.can.tx_ok,
			        (unsigned long long)ctl.can.tx_dropped,
			        (unsigned long long)ctl.can.bus_errors, o->iface);
		}
		if (R.encode_faults) {
			fprintf(out, ", %llu periods not encodable",
			        (unsigned long long)R.encode_faults);
		}
		fputc('\n', out);
	}
	/* the summary line: the figures a person looks at */
	const struct mlip_latstats *L = &R.s[S_LAT], *J = &R.s[S_JIT], *C = &R.s[S_COMP];
	double worst_us = lat_us(L->max_ns) + lat_us(C->max_ns);
	char *sm = a->summary;
	size_t cap = sizeof(a->summary);
	int sl = snprintf(sm, cap,
	                  PROG " %s: wake-up p99 %.0f us, p99.99 %.0f us, max %.0f us | jitter max "
	                       "%.0f us (%s) | compute p99 %.0f us, max %.0f us",
	                  mode_name[o->mode], lat_us(mlip_latstats_percentile_ns(L, 99, NULL)),
	                  lat_us(mlip_latstats_percentile_ns(L, 99.99, NULL)), lat_us(L->max_ns),
	                  lat_us(J->max_ns), lat_jitter_grade(lat_us(J->max_ns)),
	                  lat_us(mlip_latstats_percentile_ns(C, 99, NULL)), lat_us(C->max_ns));
	if (o->mode == MODE_CAN && sl > 0 && (size_t)sl < cap) {
		sl += snprintf(sm + sl, cap - (size_t)sl, " | send max %.0f us",
		               lat_us(R.s[S_SEND].max_ns));
	}
	if (sl > 0 && (size_t)sl < cap) {
		int nw = 0;
		for (const char *w = a->warnings; *w; w++) {
			nw += *w == '\n';
		}
		snprintf(sm + sl, cap - (size_t)sl,
		         " | %llu overruns | worst wake-up + compute %.0f of %lld us%s",
		         (unsigned long long)R.overruns, worst_us, (long long)(a->period_ns / 1000),
		         nw ? " | NOT REAL-TIME, see the warnings" : "");
	}
	fprintf(out, "%s\n", sm);
	fflush(out);
}

/* cyclictest with the same settings, after us, in one table with ours. */
static void compare(const struct lat_opts *o, struct app *a, FILE *out)
{
	uint32_t ct_hist = o->hist_us > DEFAULT_HIST_US ? o->hist_us : DEFAULT_HIST_US;
	double elapsed_s = R.periods ? (double)(a->t1_ns - a->t0_ns) / 1e9 : 0.0;
	char name[40];
	if (!o->quiet) {
		fprintf(stderr, PROG ": now cyclictest with the same settings...\n");
	}
	if (lat_run_cyclictest(o, a->period_ns, elapsed_s, ct_hist, &a->ct) != 0) {
		return;
	}
	fprintf(out, "\nwake-up latency, us (the same loop settings, one run after the other)\n");
	lat_print_table_head(out, "", 0);
	snprintf(name, sizeof(name), "mlip-latency %s", mode_name[o->mode]);
	lat_print_table(out, name, &R.s[S_LAT], -1);
	lat_print_table(out, "cyclictest", &a->ct.s, -1);
	fprintf(out, "  cyclictest: %s\n", a->ct.cmd);
	fprintf(out,
	        "  (cyclictest whole us, its avg %.2f; percentiles from its histogram, same rule "
	        "as ours)\n",
	        a->ct.avg_us);
}

/* The results as JSON: cyclictest's keys first (its "cmdline:" and
 * "rt_test_version:" keep their colon), then ours under "mlip". */
static int write_json(const struct lat_opts *o, struct app *a, int argc, char **argv)
{
	FILE *f = strcmp(o->json, "-") == 0 ? stdout : fopen(o->json, "w");
	if (f == NULL) {
		perror(o->json);
		return -1;
	}
	const struct mlip_latstats *L = &R.s[S_LAT];
	int nseries = o->mode == MODE_CAN ? S_N : S_SEND;
	double elapsed_s = R.periods ? (double)(a->t1_ns - a->t0_ns) / 1e9 : 0.0;
	char ts0[64], ts1[64], cmdline[2048];
	size_t used = 0;
	for (int k = 0; k < argc && used < sizeof(cmdline); k++) {
		used += (size_t)snprintf(cmdline + used, sizeof(cmdline) - used, "%s%s",
		                         k ? " " : "", argv[k]);
	}
	lat_fmt_time(ts0, sizeof(ts0), a->t_start);
	lat_fmt_time(ts1, sizeof(ts1), a->t_end);
	struct timespec res;
	clock_getres(CLOCK_MONOTONIC, &res);
	struct mlip_json j;
	mlip_json_begin(&j, f);
	mlip_json_uint(&j, "file_version", 1);
	mlip_json_string(&j, "cmdline:", cmdline);
	mlip_json_string(&j, "rt_test_version:", "mlip-latency " VERSION);
	mlip_json_string(&j, "start_time", ts0);
	mlip_json_string(&j, "end_time", ts1);
	mlip_json_int(&j, "return_code", 0);
	mlip_json_object(&j, "sysinfo", 0);
	mlip_json_string(&j, "sysname", a->sys.u.sysname);
	mlip_json_string(&j, "nodename", a->sys.u.nodename);
	mlip_json_string(&j, "release", a->sys.u.release);
	mlip_json_string(&j, "version", a->sys.u.version);
	mlip_json_string(&j, "machine", a->sys.u.machine);
	mlip_json_int(&j, "realtime", a->sys.sys_realtime);
	mlip_json_close(&j);
	mlip_json_int(&j, "num_threads", 1);
	mlip_json_int(&j, "resolution_in_ns", (int64_t)res.tv_sec * 1000000000 + res.tv_nsec);
	mlip_json_object(&j, "thread", 0);
	mlip_json_object(&j, "0", 0);
	lat_json_hist(&j, "histogram", L, o->hist_us);
	mlip_json_uint(&j, "cycles", L->count);
	mlip_json_int(&j, "min", mlip_latstats_min_ns(L) / 1000);
	mlip_json_int(&j, "max", L->max_ns / 1000);
	mlip_json_number(&j, "avg", "%.2f", mlip_latstats_mean_ns(L) / 1e3);
	mlip_json_int(&j, "cpu", a->run.pinned ? o->cpu : -1);
	mlip_json_int(&j, "node", 0);
	mlip_json_uint(&j, "overflow", L->count - mlip_latstats_count_below(L, o->hist_us));
	for (int k = 0; k < LAT_NPCT; k++) {
		mlip_json_number(&j, lat_pct_key[k], "%.3f",
		                 lat_us(mlip_latstats_percentile_ns(L, lat_pcts[k], NULL)));
	}
	mlip_json_close(&j);
	mlip_json_close(&j);
	/* ours */
	mlip_json_object(&j, "mlip", 0);
	mlip_json_string(&j, "tool", PROG);
	mlip_json_string(&j, "version", VERSION);
	mlip_json_string(&j, "mode", mode_name[o->mode]);
	if (o->mode != MODE_IDLE) {
		mlip_json_string(&j, "program", o->program);
		mlip_json_string(&j, "config", o->config);
	}
	if (o->mode == MODE_CAN) {
		mlip_json_string(&j, "interface", o->iface);
		mlip_json_string(&j, "can_profile", mlip_can_profile_name(a->prof));
	}
	mlip_json_number(&j, "period_us", "%.3f", (double)a->period_ns / 1e3);
	mlip_json_number(&j, "duration_s", "%.3f", o->duration_s);
	mlip_json_uint(&j, "loops", o->loops);
	mlip_json_number(&j, "elapsed_s", "%.3f", elapsed_s);
	mlip_json_uint(&j, "periods", R.periods);
	mlip_json_uint(&j, "overruns", R.overruns);
	mlip_json_uint(&j, "overrun_periods", R.overrun_periods);
	mlip_json_object(&j, "realtime", 0);
	mlip_json_int(&j, "priority", o->priority);
	mlip_json_bool(&j, "sched_fifo", a->run.fifo);
	mlip_json_bool(&j, "mlockall", a->rep.locked);
	mlip_json_int(&j, "cpu", o->cpu);
	mlip_json_bool(&j, "pinned", a->run.pinned);
	mlip_json_string(&j, "kernel", a->sys.u.release);
	mlip_json_string(&j, "kernel_version", a->sys.u.version);
	mlip_json_bool(&j, "preempt_rt", a->sys.preempt_rt);
	mlip_json_string(&j, "isolated_cpus", a->sys.isolated);
	mlip_json_int(&j, "cpus", a->sys.ncpu);
	lat_json_warnings(&j, "warnings", a->warnings);
	mlip_json_close(&j);
	for (int k = 0; k < nseries; k++) {
		lat_json_series(&j, series_key[k], &R.s[k], (long long)R.max_at[k], o->hist_us);
	}
	if (o->mode != MODE_IDLE) {
		const struct mlip_ctl_counts *n = &ctl.out.counts;
		mlip_json_object(&j, "load", 0);
		mlip_json_uint(&j, "program_blocks", a->prog.n);
		mlip_json_uint(&j, "runs_finished", R.passes);
		mlip_json_uint(&j, "blocks_taken", n->blocks_consumed);
		mlip_json_uint(&j, "moving_periods", R.moving_periods);
		mlip_json_uint(&j, "underruns", n->underruns);
		mlip_json_uint(&j, "frames_encoded", R.frames_encoded);
		mlip_json_uint(&j, "encode_faults", R.encode_faults);
		if (o->mode == MODE_CAN) {
			mlip_json_uint(&j, "frames_sent", ctl.can.tx_ok);
			mlip_json_uint(&j, "frames_dropped", ctl.can.tx_dropped);
			mlip_json_uint(&j, "bus_errors", ctl.can.bus_errors);
		}
		mlip_json_close(&j);
	}
	mlip_json_string(&j, "summary", a->summary);
	mlip_json_close(&j);
	if (a->ct.ran) {
		mlip_json_object(&j, "cyclictest", 0);
		mlip_json_string(&j, "cmdline", a->ct.cmd);
		lat_json_series(&j, "wakeup_latency", &a->ct.s, -1, a->ct.s.nbins);
		mlip_json_raw(&j, "json", a->ct.json != NULL ? a->ct.json : "null");
		mlip_json_close(&j);
	}
	int rc = mlip_json_end(&j);
	if (f != stdout && fclose(f) != 0) {
		rc = -1;
	}
	if (rc != 0) {
		perror(o->json);
	}
	return rc;
}

/* Tables, the comparison, the JSON; then everything freed. The exit status. */
static int report(const struct lat_opts *o, struct app *a, int argc, char **argv)
{
	/* results on stdout, unless the JSON goes there */
	FILE *out = o->json != NULL && strcmp(o->json, "-") == 0 ? stderr : stdout;
	int rc = 0;
	print_results(o, a, out);
	if (o->compare) {
		compare(o, a, out);
	}
	if (o->json != NULL && write_json(o, a, argc, argv) != 0) {
		rc = 1;
	}
	mlip_canbus_close(&bus);
	if (o->mode != MODE_IDLE) {
		mlip_program_list_free(&a->prog);
		free(a->ring_mem);
		free(a->smooth);
	}
	for (int k = 0; k < S_N; k++) {
		free(R.s[k].bins);
	}
	free(a->ct.bins);
	free(a->ct.json);
	return rc;
}

int main(int argc, char **argv)
{
	static struct lat_opts o;
	static struct app a;
	int rc = lat_parse_opts(argc, argv, &o);
	if (rc != 0) {
		return rc < 0 ? 0 : rc;
	}
	rc = set_up(&o, &a);
	if (rc != 0) {
		return rc;
	}
	if (run(&o, &a) != 0) {
		return 1;
	}
	return report(&o, &a, argc, argv);
}
