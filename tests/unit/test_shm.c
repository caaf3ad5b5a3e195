/*
 * test_shm.c - rt/shm.c on real POSIX shared-memory objects: create, attach
 * and close; one controller per name (the lock, the heartbeat on both sides
 * of MLIP_PEER_TIMEOUT_NS); take-over of a dead controller's segment; attach
 * refusals with messages naming what differs; ownership (a name another
 * user made is refused, attachers check the owner); a full /dev/shm
 * (posix_fallocate wrapped at link time to fail with ENOSPC; the real one is
 * in tests/py/test_rt_host.py, on a 64 KiB tmpfs).
 *
 * Each test uses its own name, /mlip-test-<pid>-<n>, and the teardown unlinks
 * it, so parallel runs and failed asserts leave nothing behind.
 */
#include <errno.h>
#include <fcntl.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>

#include "mlip/ipc/ring.h"
#include "rt.h"

#define CAP    64u
#define NOBODY 65534 /* a uid and gid that is not ours (the tests chown to it as root) */

/* posix_fallocate as rt/shm.c sees it (-Wl,--wrap=posix_fallocate, Makefile):
 * the real one unless a test asks for an error. */
int __real_posix_fallocate(int fd, off_t off, off_t len);
int __wrap_posix_fallocate(int fd, off_t off, off_t len);
static int fallocate_error;
static int fallocate_calls;

int __wrap_posix_fallocate(int fd, off_t off, off_t len)
{
	fallocate_calls++;
	return fallocate_error != 0 ? fallocate_error : __real_posix_fallocate(fd, off, len);
}

static char name[64];
static int serial;

static int setup(void **state)
{
	(void)state;
	snprintf(name, sizeof(name), "/mlip-test-%d-%d", (int)getpid(), serial++);
	shm_unlink(name);
	return 0;
}

static int teardown(void **state)
{
	(void)state;
	shm_unlink(name);
	return 0;
}

static void assert_contains(const char *hay, const char *needle)
{
	if (strstr(hay, needle) == NULL) {
		print_error("'%s' not in '%s'\n", needle, hay);
		fail();
	}
}

static void machine(struct mlip_machine *m, int n_axes)
{
	int k;

	memset(m, 0, sizeof(*m));
	m->n_axes = n_axes;
	m->max_feed_mm_s = 200.0;
	m->max_rot_feed_deg_s = 360.0;
	m->tolerance_mm = 0.01;
	m->period_s = 0.001;
	for (k = 0; k < n_axes; k++) {
		m->axis[k].letter = "XYZABC"[k];
		m->axis[k].kind = MLIP_AXIS_LINEAR;
		m->axis[k].max_accel = 1000.0 + k;
		m->axis[k].max_vel = 200.0;
		m->axis[k].min_limit = -1000.0;
		m->axis[k].max_limit = 1000.0;
		m->axis[k].can_node = k + 1;
		m->axis[k].counts_per_unit = 1000.0;
	}
}

/* What the kernel does when a controller dies: mapping and descriptor go
 * (the lock with them), the name stays. */
static void crash(struct mlip_shm *s)
{
	munmap(s->mem, s->bytes);
	close(s->fd);
	memset(s, 0, sizeof(*s));
	s->fd = -1;
}

static void set_heartbeat(struct mlip_ring *r, uint64_t ns)
{
	struct mlip_ring_status st;

	assert_int_equal(mlip_ring_status_read(r, &st), MLIP_OK);
	st.heartbeat++;
	st.heartbeat_ns = ns;
	mlip_ring_status_write(r, &st);
}

/* Heartbeat of a crashed controller's segment, written through an attach. */
static void set_heartbeat_named(uint64_t ns)
{
	struct mlip_shm a;
	char why[256];

	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), 0);
	set_heartbeat(a.ring, ns);
	mlip_shm_close(&a);
}

static int exists(void)
{
	int fd = shm_open(name, O_RDONLY, 0);

	if (fd < 0) {
		assert_int_equal(errno, ENOENT);
		return 0;
	}
	close(fd);
	return 1;
}

static void test_create_attach_close(void **state)
{
	struct mlip_shm s, a;
	struct mlip_machine m, got;
	struct mlip_ring_rec rec, out;
	struct mlip_ring_status st;
	struct mlip_block b;
	struct stat sb;
	char why[256] = "";
	int fd0_flags = fcntl(0, F_GETFD);

	(void)state;
	machine(&m, 3);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	assert_int_equal(s.owner, 1);
	assert_non_null(s.ring);
	assert_ptr_equal(s.ring, s.mem);
	assert_int_equal((uintptr_t)s.mem % MLIP_RING_LINE, 0);
	assert_int_equal(s.bytes, mlip_ring_bytes(CAP));
	assert_string_equal(s.name, name);
	assert_int_equal(fstat(s.fd, &sb), 0);
	assert_int_equal(sb.st_mode & 0777, 0600); /* only our user, whatever the umask */
	assert_int_equal(sb.st_uid, geteuid());
	assert_int_equal((size_t)sb.st_size, mlip_ring_bytes(CAP));

	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), 0);
	assert_int_equal(a.owner, 0);
	assert_int_equal(a.bytes, s.bytes);
	assert_int_equal(a.ring->capacity, CAP);
	assert_int_equal(a.ring->n_axes, 3);
	mlip_ring_machine(a.ring, &got);
	assert_memory_equal(&got, &m, sizeof(m));

	/* one segment seen through two mappings: feeder pushes, controller pops */
	memset(&b, 0, sizeof(b));
	b.target[0] = 1.5;
	b.feed_mm_s = 10.0;
	b.line = 7;
	mlip_ring_rec_from_block(&rec, &b, 1);
	assert_int_equal(mlip_ring_push(a.ring, &rec), MLIP_OK);
	assert_int_equal(mlip_ring_pop(s.ring, &out), MLIP_OK);
	assert_memory_equal(&out, &rec, sizeof(rec));
	set_heartbeat(s.ring, 12345);
	assert_int_equal(mlip_ring_status_read(a.ring, &st), MLIP_OK);
	assert_int_equal(st.heartbeat_ns, 12345);
	assert_int_equal(st.override_pct, 100);

	mlip_shm_close(&a); /* an attacher leaves the name */
	assert_null(a.mem);
	assert_int_equal(a.fd, -1);
	assert_true(exists());
	mlip_shm_close(&s); /* the owner removes it */
	assert_false(exists());
	mlip_shm_close(&s); /* twice: nothing */

	memset(&a, 0, sizeof(a)); /* a zeroed handle has fd 0: must not close stdin */
	mlip_shm_close(&a);
	assert_int_equal(fcntl(0, F_GETFD), fd0_flags);
}

static void test_create_refuses_live_process(void **state)
{
	struct mlip_shm s, t;
	struct mlip_machine m;
	char why[256] = "";

	(void)state;
	machine(&m, 3);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	/* no heartbeat yet (still starting up), but the process holds it */
	assert_int_equal(mlip_shm_create(&t, name, CAP, &m, why, sizeof(why)), -EBUSY);
	assert_contains(why, "a controller process holds");
	assert_contains(why, name);
	assert_contains(why, "no heartbeat yet");
	assert_null(t.mem);
	assert_int_equal(t.fd, -1);
	/* a stale heartbeat does not matter while the process is there */
	set_heartbeat(s.ring, mlip_now_ns() - 10 * (uint64_t)MLIP_PEER_TIMEOUT_NS);
	assert_int_equal(mlip_shm_create(&t, name, CAP, &m, why, sizeof(why)), -EBUSY);
	assert_contains(why, "last heartbeat");
	/* the refused create touched nothing */
	assert_int_equal(s.ring->capacity, CAP);
	assert_true(exists());
	mlip_shm_close(&s);
	assert_false(exists());
}

static void test_create_heartbeat_both_sides(void **state)
{
	struct mlip_shm s, t;
	struct mlip_machine m, m2, got;
	struct mlip_ring_status st;
	char why[256] = "";

	(void)state;
	machine(&m, 3);
	machine(&m2, 2);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	set_heartbeat(s.ring, mlip_now_ns());
	crash(&s);

	/* heartbeat younger than the timeout: a live controller, even unlocked */
	set_heartbeat_named(mlip_now_ns() - MLIP_PEER_TIMEOUT_NS / 2);
	assert_int_equal(mlip_shm_create(&t, name, CAP, &m2, why, sizeof(why)), -EBUSY);
	assert_contains(why, "a controller is already running on");
	assert_contains(why, name);
	assert_true(exists());

	/* older than the timeout: dead, taken over and formatted anew */
	set_heartbeat_named(mlip_now_ns() - 2 * (uint64_t)MLIP_PEER_TIMEOUT_NS);
	assert_int_equal(mlip_shm_create(&t, name, 2 * CAP, &m2, why, sizeof(why)), 0);
	assert_int_equal(t.owner, 1);
	assert_int_equal(t.bytes, mlip_ring_bytes(2 * CAP));
	assert_int_equal(t.ring->capacity, 2 * CAP);
	assert_int_equal(mlip_ring_status_read(t.ring, &st), MLIP_OK);
	assert_int_equal(st.heartbeat_ns, 0);
	assert_int_equal(st.heartbeat, 0);
	mlip_ring_machine(t.ring, &got);
	assert_memory_equal(&got, &m2, sizeof(m2));
	mlip_shm_close(&t);
	assert_false(exists());
}

static void test_create_takes_over_never_started(void **state)
{
	struct mlip_shm s;
	struct mlip_machine m;
	char why[256] = "";
	int fd;

	(void)state;
	machine(&m, 3);
	/* died before its first heartbeat */
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	crash(&s);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	crash(&s);
	/* died between shm_open and ftruncate: an empty object */
	shm_unlink(name);
	fd = shm_open(name, O_CREAT | O_RDWR, 0600);
	assert_true(fd >= 0);
	close(fd);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	mlip_shm_close(&s);
}

static void test_create_refuses_foreign(void **state)
{
	struct mlip_shm s;
	struct mlip_machine m;
	char why[256] = "", buf[8];
	int fd;

	(void)state;
	machine(&m, 3);
	fd = shm_open(name, O_CREAT | O_RDWR, 0600);
	assert_true(fd >= 0);
	assert_int_equal(ftruncate(fd, 4096), 0);
	assert_int_equal(pwrite(fd, "NOTMLIP!", 8, 0), 8);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), -EEXIST);
	assert_contains(why, "is not an mlip segment");
	assert_int_equal(pread(fd, buf, 8, 0), 8); /* left alone */
	assert_memory_equal(buf, "NOTMLIP!", 8);
	close(fd);
}

static void test_attach_version_mismatch(void **state)
{
	struct mlip_shm s, a;
	struct mlip_machine m;
	char why[256] = "", want[128];

	(void)state;
	machine(&m, 3);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	s.ring->version = MLIP_RING_VERSION + 1; /* a controller from another build */
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), -EPROTO);
	snprintf(want, sizeof(want), "segment %s has layout version %u, this program speaks %u",
	         name, MLIP_RING_VERSION + 1, MLIP_RING_VERSION);
	assert_contains(why, want);
	assert_contains(why, "restart mlip-rt from the same build");
	assert_null(a.mem);
	assert_null(a.ring);
	assert_int_equal(a.fd, -1);
	s.ring->version = MLIP_RING_VERSION;
	assert_int_equal(mlip_shm_attach(&a, name, NULL, 0), 0); /* why may be NULL */
	mlip_shm_close(&a);
	mlip_shm_close(&s);
}

static void test_create_refuses_other_version(void **state)
{
	/* a dead controller of another build left its segment: a new
	 * controller refuses it instead of reformatting under its feeders */
	struct mlip_shm s;
	struct mlip_machine m;
	char why[256] = "", want[160];

	(void)state;
	machine(&m, 3);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	s.ring->version = MLIP_RING_VERSION + 1;
	crash(&s);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), -EPROTO);
	snprintf(want, sizeof(want), "%s has layout version %u, this mlip-rt speaks %u", name,
	         MLIP_RING_VERSION + 1, MLIP_RING_VERSION);
	assert_contains(why, want);
	assert_true(exists()); /* left alone */
	/* the same build's stale segment is taken over */
	struct mlip_shm a;
	assert_int_equal(mlip_shm_attach(&a, name, NULL, 0), -EPROTO);
	int fd = shm_open(name, O_RDWR, 0);
	assert_true(fd >= 0);
	struct mlip_ring *r =
	    mmap(NULL, mlip_ring_bytes(CAP), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
	assert_true(r != MAP_FAILED);
	r->version = MLIP_RING_VERSION;
	munmap(r, mlip_ring_bytes(CAP));
	close(fd);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	mlip_shm_close(&s);
}

static void test_attach_other_mismatches(void **state)
{
	struct mlip_shm s, a;
	struct mlip_machine m;
	char why[256] = "", want[128];
	uint64_t magic;

	(void)state;
	machine(&m, 3);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);

	s.ring->rec_bytes = 72;
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), -EPROTO);
	snprintf(want, sizeof(want), "has record size 72, this program expects %zu",
	         sizeof(struct mlip_ring_rec));
	assert_contains(why, want);
	s.ring->rec_bytes = sizeof(struct mlip_ring_rec);

	magic = s.ring->magic;
	memcpy(&s.ring->magic, "SOMEONE!", 8);
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), -EPROTO);
	assert_contains(why, "is not an mlip segment");
	/* magic 0: a format in progress, worth a retry */
	s.ring->magic = 0;
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), -EAGAIN);
	assert_contains(why, "not formatted yet");
	s.ring->magic = magic;

	/* records cut off (the mapping of s beyond the new size is not touched) */
	assert_int_equal(ftruncate(s.fd, (off_t)mlip_ring_bytes(CAP / 2)), 0);
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), -EPROTO);
	snprintf(want, sizeof(want), "is %zu bytes, its header needs %zu", mlip_ring_bytes(CAP / 2),
	         mlip_ring_bytes(CAP));
	assert_contains(why, want);
	/* shorter than a header: a creator between ftruncate calls */
	assert_int_equal(ftruncate(s.fd, 100), 0);
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), -EAGAIN);
	assert_contains(why, "is 100 bytes");
	assert_int_equal(ftruncate(s.fd, 0), 0);
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), -EAGAIN);
	mlip_shm_close(&s);
}

static void test_attach_missing(void **state)
{
	struct mlip_shm a;
	char why[256] = "", want[128];

	(void)state;
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), -ENOENT);
	snprintf(want, sizeof(want), "no controller segment %s: is mlip-rt running?", name);
	assert_string_equal(why, want);
	assert_null(a.mem);
	assert_int_equal(a.fd, -1);
	mlip_shm_close(&a);
}

static void test_bad_arguments(void **state)
{
	struct mlip_shm s;
	struct mlip_machine m;
	char why[256] = "";
	char longname[80];

	(void)state;
	machine(&m, 3);
	memset(longname, 'x', sizeof(longname) - 1);
	longname[0] = '/';
	longname[sizeof(longname) - 1] = '\0';
	assert_int_equal(mlip_shm_create(&s, "mlip", CAP, &m, why, sizeof(why)), -EINVAL);
	assert_contains(why, "must be '/' followed by");
	assert_int_equal(mlip_shm_create(&s, "/a/b", CAP, &m, why, sizeof(why)), -EINVAL);
	assert_int_equal(mlip_shm_create(&s, "/", CAP, &m, why, sizeof(why)), -EINVAL);
	assert_int_equal(mlip_shm_create(&s, longname, CAP, &m, why, sizeof(why)), -EINVAL);
	assert_int_equal(mlip_shm_create(&s, NULL, CAP, &m, NULL, 0), -EINVAL);
	assert_int_equal(mlip_shm_attach(&s, "mlip", why, sizeof(why)), -EINVAL);
	assert_int_equal(mlip_shm_create(&s, name, 100, &m, why, sizeof(why)), -EINVAL);
	assert_contains(why, "power of two");
	assert_int_equal(mlip_shm_create(&s, name, 0, &m, why, sizeof(why)), -EINVAL);
	assert_int_equal(mlip_shm_create(&s, name, CAP, NULL, why, sizeof(why)), -EINVAL);
	assert_int_equal(s.fd, -1);
	assert_false(exists()); /* nothing created on a refusal */
	/* a tiny why buffer is truncated, not overrun */
	why[4] = 'Z';
	assert_int_equal(mlip_shm_attach(&s, name, why, 4), -ENOENT);
	assert_int_equal(strlen(why), 3);
	assert_int_equal(why[4], 'Z');
}

static void test_controller_alive(void **state)
{
	struct mlip_shm s;
	struct mlip_machine m;
	char why[256] = "";
	const int64_t ms = 1000000;

	(void)state;
	machine(&m, 3);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	assert_false(mlip_shm_controller_alive(s.ring)); /* never beat */
	set_heartbeat(s.ring, mlip_now_ns());
	assert_true(mlip_shm_controller_alive(s.ring));
	/* both sides of MLIP_PEER_TIMEOUT_NS (100 ms), with a 50 ms margin for
	 * the test's own run time */
	set_heartbeat(s.ring, mlip_now_ns() - 50 * (uint64_t)ms);
	assert_true(mlip_shm_controller_alive(s.ring));
	set_heartbeat(s.ring, mlip_now_ns() - 150 * (uint64_t)ms);
	assert_false(mlip_shm_controller_alive(s.ring));
	set_heartbeat(s.ring, mlip_now_ns() - 2 * (uint64_t)MLIP_PEER_TIMEOUT_NS);
	assert_false(mlip_shm_controller_alive(s.ring));
	assert_false(mlip_shm_controller_alive(NULL));
	mlip_shm_close(&s);
}

static void test_now_ns(void **state)
{
	struct timespec ts = {0, 2000000};
	uint64_t t0, t1;

	(void)state;
	t0 = mlip_now_ns();
	assert_true(t0 > 0);
	assert_int_equal(clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, NULL), 0);
	t1 = mlip_now_ns();
	assert_true(t1 - t0 >= 2000000u);
	assert_true(t1 - t0 < 1000000000u);
}

/* A full /dev/shm: a message at start-up, the name removed, no SIGBUS. */
static void test_create_no_room(void **state)
{
	struct mlip_shm s;
	struct mlip_machine m;
	char why[256] = "";

	(void)state;
	machine(&m, 3);
	fallocate_calls = 0;
	fallocate_error = ENOSPC;
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), -ENOSPC);
	fallocate_error = 0;
	assert_int_equal(fallocate_calls, 1);
	assert_contains(why, "no room for the segment's");
	assert_contains(why, "df -h /dev/shm");
	assert_null(s.mem);
	assert_int_equal(s.fd, -1);
	assert_false(exists());
	/* the real call reserves the pages: st_blocks covers the size */
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	assert_int_equal(fallocate_calls, 2);
	struct stat sb;
	assert_int_equal(fstat(s.fd, &sb), 0);
	assert_true((size_t)sb.st_blocks * 512u >= s.bytes);
	mlip_shm_close(&s);
}

/* A name another user made (an empty object, as anyone can make in
 * /dev/shm, or a valid-looking segment) is refused and left as it is. */
static void test_create_refuses_other_users_object(void **state)
{
	struct mlip_shm s;
	struct mlip_machine m;
	struct stat sb;
	char why[256] = "";
	int fd;

	(void)state;
	if (geteuid() != 0) {
		skip(); /* chown to another user needs root */
	}
	machine(&m, 3);
	fd = shm_open(name, O_CREAT | O_EXCL | O_RDWR, 0644);
	assert_true(fd >= 0);
	assert_int_equal(fchown(fd, NOBODY, NOBODY), 0);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), -EPERM);
	assert_contains(why, "exists and belongs to ");
	assert_contains(why, "not to this controller's user");
	assert_contains(why, "remove /dev/shm");
	assert_int_equal(fstat(fd, &sb), 0); /* untouched: still theirs, still empty */
	assert_int_equal(sb.st_uid, NOBODY);
	assert_int_equal(sb.st_size, 0);
	assert_int_equal(sb.st_mode & 0777, 0644);
	/* a formatted segment of theirs, dead: not ours to take over either */
	close(fd);
	shm_unlink(name);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	crash(&s);
	fd = shm_open(name, O_RDWR, 0);
	assert_true(fd >= 0);
	assert_int_equal(fchown(fd, NOBODY, NOBODY), 0);
	close(fd);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), -EPERM);
	assert_contains(why, "another user made it");
}

/* Our own stale object, but open to every user: someone may hold it open
 * already; refused. A stale 0660 one of ours (older builds) is taken over and
 * narrowed to 0600. */
static void test_create_refuses_world_open(void **state)
{
	struct mlip_shm s;
	struct mlip_machine m;
	struct stat sb;
	char why[256] = "";
	int fd;

	(void)state;
	machine(&m, 3);
	fd = shm_open(name, O_CREAT | O_EXCL | O_RDWR, 0600);
	assert_true(fd >= 0);
	assert_int_equal(fchmod(fd, 0666), 0);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), -EPERM);
	assert_contains(why, "has mode 0666: every user may open it");
	assert_int_equal(fchmod(fd, 0660), 0);
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	assert_int_equal(fstat(s.fd, &sb), 0);
	assert_int_equal(sb.st_mode & 0777, 0600);
	close(fd);
	mlip_shm_close(&s);
}

/* --shm-group: mode 0660 and that group, so its members may feed. */
static void test_create_group(void **state)
{
	struct mlip_shm s;
	struct mlip_machine m;
	struct stat sb;
	char why[256] = "";
	long gid = geteuid() == 0 ? NOBODY : (long)getegid();

	(void)state;
	machine(&m, 3);
	assert_int_equal(mlip_shm_create_group(&s, name, CAP, &m, gid, why, sizeof(why)), 0);
	assert_int_equal(fstat(s.fd, &sb), 0);
	assert_int_equal(sb.st_mode & 0777, 0660);
	assert_int_equal((long)sb.st_gid, gid);
	mlip_shm_close(&s);
}

/* Attaching tools trust their own user's segment, root's, and the user
 * MLIP_SHM_OWNER names; never one every user may write. */
static void test_attach_checks_owner(void **state)
{
	struct mlip_shm s, a;
	struct mlip_machine m;
	char why[256] = "";

	(void)state;
	if (geteuid() != 0) {
		skip();
	}
	machine(&m, 3);
	unsetenv("MLIP_SHM_OWNER");
	assert_int_equal(mlip_shm_create(&s, name, CAP, &m, why, sizeof(why)), 0);
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), 0); /* ours */
	mlip_shm_close(&a);
	assert_int_equal(fchown(s.fd, NOBODY, NOBODY), 0);
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), -EPERM);
	assert_contains(why, "neither you (root) nor root");
	assert_contains(why, "set MLIP_SHM_OWNER=");
	assert_null(a.mem);
	assert_int_equal(a.fd, -1);
	setenv("MLIP_SHM_OWNER", "65534", 1);
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), 0);
	mlip_shm_close(&a);
	setenv("MLIP_SHM_OWNER", "65533", 1);
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), -EPERM);
	/* a segment every user may write is refused even from a trusted owner */
	setenv("MLIP_SHM_OWNER", "65534", 1);
	assert_int_equal(fchmod(s.fd, 0662), 0);
	assert_int_equal(mlip_shm_attach(&a, name, why, sizeof(why)), -EPERM);
	assert_contains(why, "has mode 0662");
	unsetenv("MLIP_SHM_OWNER");
	mlip_shm_close(&s);
}

int main(void)
{
#define T(f) cmocka_unit_test_setup_teardown(f, setup, teardown)
	const struct CMUnitTest tests[] = {
	    T(test_create_attach_close),
	    T(test_create_refuses_live_process),
	    T(test_create_heartbeat_both_sides),
	    T(test_create_takes_over_never_started),
	    T(test_create_refuses_foreign),
	    T(test_attach_version_mismatch),
	    T(test_create_refuses_other_version),
	    T(test_attach_other_mismatches),
	    T(test_attach_missing),
	    T(test_bad_arguments),
	    T(test_controller_alive),
	    T(test_now_ns),
	    T(test_create_no_room),
	    T(test_create_refuses_other_users_object),
	    T(test_create_refuses_world_open),
	    T(test_create_group),
	    T(test_attach_checks_owner),
	};
#undef T

	return cmocka_run_group_tests_name("shm", tests, NULL, NULL);
}
