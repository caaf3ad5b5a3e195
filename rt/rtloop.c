/*
 * rtloop.c - the periodic real-time loop (rt-tests cyclictest's recipe):
 * mlockall and prefault, a SCHED_FIFO thread (a clear warning and
 * SCHED_OTHER when not permitted), wake-ups on an absolute CLOCK_MONOTONIC
 * schedule with clock_nanosleep (which returns its error rather than setting
 * errno), overruns counted, never hidden: a period that ends after the next
 * deadline skips the deadlines it missed, so the work runs once per wake-up
 * and never in a burst.
 */
#define _GNU_SOURCE /* pthread_attr_setaffinity_np, CPU_SET */

#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/utsname.h>
#include <time.h>
#include <unistd.h>

#include "rt.h"

#define NS             1000000000LL
/* The loop thread's stack, sized explicitly: the default (RLIMIT_STACK, often
 * 8 MiB) under mlockall(MCL_FUTURE) is locked whole and alone exhausts a
 * typical 8 MiB RLIMIT_MEMLOCK of an unprivileged user (pthread_create then
 * fails with EAGAIN). The loop needs a few KiB; half of it is prefaulted. */
#define LOOP_STACK     (512 * 1024)
#define STACK_PREFAULT (256 * 1024)
/* Locked memory that must still fit after mlockall: the loop's stack, the
 * tools' other small threads, stdio and libc's first allocations, and
 * mlip-rt's segment (656 KiB at the default capacity), mapped afterwards. */
#define LOCK_HEADROOM  (LOOP_STACK + 1024 * 1024)

static volatile sig_atomic_t stop_flag;
static int dma_latency_fd = -1; /* held open: the request lasts while it is */

void mlip_rt_request_stop(void)
{
	stop_flag = 1;
}

int mlip_rt_stop_requested(void)
{
	return stop_flag != 0;
}

static void warn(struct mlip_rt_report *rep, const char *line)
{
	size_t used = strlen(rep->warnings);
	snprintf(rep->warnings + used, sizeof(rep->warnings) - used, "%s\n", line);
}

static int read_flag_file(const char *path, char *buf, size_t len)
{
	FILE *f = fopen(path, "r");
	if (f == NULL) {
		return -1;
	}
	size_t n = fread(buf, 1, len - 1, f);
	buf[n] = '\0';
	fclose(f);
	return (int)n;
}

/* RLIMIT_MEMLOCK in KiB for messages; -1 when unlimited. */
static long memlock_kib(void)
{
	struct rlimit rl;

	if (getrlimit(RLIMIT_MEMLOCK, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY) {
		return -1;
	}
	return (long)(rl.rlim_cur / 1024);
}

/* mlockall, then check that what the loop still has to map fits the limit
 * (a trial mapping of LOCK_HEADROOM under MCL_FUTURE fails with EAGAIN when it
 * would not). When it does not fit, unlock and say which limit to raise:
 * better a loop that runs unlocked with a warning than one that cannot
 * start. Root (CAP_IPC_LOCK) is not bound by the limit. */
static void lock_memory(struct mlip_rt_report *rep)
{
	char line[320];
	long lim = memlock_kib();
	void *probe;

	if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
		snprintf(
		    line, sizeof(line),
		    "memory not locked (mlockall: %s; RLIMIT_MEMLOCK %ld KiB): page faults can "
		    "stall the loop; run as root, or raise the limit (ulimit -l unlimited, "
		    "LimitMEMLOCK=infinity, memlock in /etc/security/limits.conf)",
		    strerror(errno), lim);
		warn(rep, line);
		return;
	}
	probe =
	    mmap(NULL, LOCK_HEADROOM, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
	if (probe != MAP_FAILED) {
		munmap(probe, LOCK_HEADROOM);
		rep->locked = 1;
		return;
	}
	munlockall();
	snprintf(line, sizeof(line),
	         "memory not locked: RLIMIT_MEMLOCK (%ld KiB) leaves less than the %d KiB the "
	         "loop still needs locked; page faults can stall the loop; run as root, or raise "
	         "the limit (ulimit -l unlimited, LimitMEMLOCK=infinity, memlock in "
	         "/etc/security/limits.conf)",
	         lim, LOCK_HEADROOM / 1024);
	warn(rep, line);
}

int mlip_rt_prepare(const struct mlip_rt_opts *o, struct mlip_rt_report *rep)
{
	memset(rep, 0, sizeof(*rep));
	if (o->lock_memory) {
		lock_memory(rep);
	}
	if (o->priority > 0) {
		/* ask now, so the warning comes before the loop starts */
		struct sched_param sp = {.sched_priority = o->priority},
		                   zero = {.sched_priority = 0};
		if (sched_setscheduler(0, SCHED_FIFO, &sp) == 0) {
			sched_setscheduler(0, SCHED_OTHER, &zero);
		} else {
			warn(rep, "no SCHED_FIFO (not permitted): the loop runs SCHED_OTHER and "
			          "will miss "
			          "deadlines under load; run as root, or grant CAP_SYS_NICE / an "
			          "rtprio limit");
		}
	}
	/* keep the CPUs out of deep C-states, as cyclictest does: waking from
	 * them costs tens to hundreds of microseconds */
	if (dma_latency_fd < 0) {
		int32_t zero = 0;
		dma_latency_fd = open("/dev/cpu_dma_latency", O_RDWR | O_CLOEXEC);
		if (dma_latency_fd >= 0 &&
		    write(dma_latency_fd, &zero, sizeof(zero)) != sizeof(zero)) {
			close(dma_latency_fd);
			dma_latency_fd = -1;
		}
		if (dma_latency_fd < 0 && errno == EACCES) {
			warn(
			    rep,
			    "cannot hold /dev/cpu_dma_latency at 0 (not permitted): deep CPU sleep "
			    "states add wake-up latency; run as root");
		}
	}
	/* the kernel: PREEMPT_RT bounds scheduling latency, a stock kernel does not */
	struct utsname u;
	char buf[64];
	int rt = (uname(&u) == 0 && strstr(u.version, "PREEMPT_RT") != NULL) ||
	         (read_flag_file("/sys/kernel/realtime", buf, sizeof(buf)) > 0 && buf[0] == '1');
	if (!rt) {
		warn(rep,
		     "kernel is not PREEMPT_RT: expect latency spikes; on a controller install a "
		     "PREEMPT_RT kernel (Debian: linux-image-rt-amd64)");
	}
	if (read_flag_file("/sys/devices/system/cpu/isolated", buf, sizeof(buf)) <= 1) {
		warn(rep, "no isolated CPU: other tasks share the loop's CPU; boot with isolcpus=N "
		          "(and nohz_full=N rcu_nocbs=N) and pass --cpu N");
	}
	return 0;
}

struct loop {
	const struct mlip_rt_opts *o;
	mlip_rt_fn fn;
	mlip_rt_after_fn after;
	void *ctx;
	int rc;
};

static struct timespec ns_ts(uint64_t ns)
{
	struct timespec t = {.tv_sec = (time_t)(ns / (uint64_t)NS),
	                     .tv_nsec = (long)(ns % (uint64_t)NS)};
	return t;
}

static void prefault_stack(void)
{
	volatile char buf[STACK_PREFAULT];
	memset((char *)buf, 0, sizeof(buf));
}

static void *loop_thread(void *arg)
{
	struct loop *l = arg;
	uint64_t period = (uint64_t)l->o->period_ns;
	struct mlip_rt_tick t;
	memset(&t, 0, sizeof(t));
	prefault_stack();

	uint64_t next = mlip_now_ns() + period, first = next, prev_wake = 0;
	uint64_t carried = 0; /* deadlines the last work overran, not yet told */
	while (!stop_flag) {
		struct timespec ts = ns_ts(next);
		int r;
		do {
			r = clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL);
		} while (r == EINTR && !stop_flag);
		uint64_t wake = mlip_now_ns();
		t.deadline_ns = next;
		t.latency_ns = wake > next ? (int64_t)(wake - next) : 0;
		t.interval_ns = prev_wake ? (int64_t)(wake - prev_wake) : 0;
		prev_wake = wake;
		uint64_t late = (uint64_t)t.latency_ns / period;
		t.missed = carried + late;
		t.index = (next - first) / period + late;
		int rc = l->fn(l->ctx, &t);
		uint64_t end = mlip_now_ns();
		if (l->after != NULL) {
			l->after(l->ctx, &t, (int64_t)(end - wake));
		}
		if (rc != 0) {
			l->rc = rc;
			break;
		}
		t.cycle++;
		next += period;
		/* missed deadlines are counted and skipped, not caught up; the
		 * late ones were told in t.missed already, the rest are told next */
		uint64_t skipped = 0;
		while (next <= end) {
			next += period;
			skipped++;
		}
		t.overruns += skipped;
		carried = skipped > late ? skipped - late : 0;
	}
	return NULL;
}

int mlip_rt_run(const struct mlip_rt_opts *o, mlip_rt_fn fn, mlip_rt_after_fn after, void *ctx,
                struct mlip_rt_report *rep)
{
	struct loop l = {.o = o, .fn = fn, .after = after, .ctx = ctx};
	pthread_attr_t attr;
	pthread_t th;
	int r;

	if (o->period_ns <= 0) {
		return -EINVAL;
	}
	pthread_attr_init(&attr);
	pthread_attr_setstacksize(&attr, LOOP_STACK);
	if (o->priority > 0) {
		struct sched_param sp = {.sched_priority = o->priority};
		pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED);
		pthread_attr_setschedpolicy(&attr, SCHED_FIFO);
		pthread_attr_setschedparam(&attr, &sp);
	}
	if (o->cpu >= 0) {
		cpu_set_t set;
		CPU_ZERO(&set);
		CPU_SET(o->cpu, &set);
		if (pthread_attr_setaffinity_np(&attr, sizeof(set), &set) == 0) {
			rep->pinned = 1;
		}
	}
	r = pthread_create(&th, &attr, loop_thread, &l);
	if (r == EPERM && o->priority > 0) {
		if (strstr(rep->warnings, "SCHED_FIFO") == NULL) {
			warn(rep, "no SCHED_FIFO (not permitted): the loop runs SCHED_OTHER");
		}
		pthread_attr_setinheritsched(&attr, PTHREAD_INHERIT_SCHED);
		r = pthread_create(&th, &attr, loop_thread, &l);
	} else if (r == 0 && o->priority > 0) {
		rep->fifo = 1;
	}
	if (r == EINVAL && o->cpu >= 0) {
		rep->pinned = 0;
		warn(rep, "CPU pinning refused: that CPU does not exist or is not allowed");
		pthread_attr_destroy(&attr);
		pthread_attr_init(&attr);
		pthread_attr_setstacksize(&attr, LOOP_STACK);
		r = pthread_create(&th, &attr, loop_thread, &l);
	}
	pthread_attr_destroy(&attr);
	if (r != 0) {
		return -r;
	}
	pthread_join(th, NULL);
	return l.rc;
}
