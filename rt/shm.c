/*
 * shm.c - the POSIX shared-memory segment that carries the ring, the status,
 * feeder and command areas and the machine (mlip/ipc/ring.h), and the monotonic
 * clock every process stamps its heartbeat with.
 *
 * Who may own the segment: one controller per name. Two guards, both needed:
 *   - flock(LOCK_EX) on the segment, held by the controller for its lifetime
 *     and dropped by the kernel when it dies: it covers the start-up window
 *     (segment formatted, no heartbeat yet) and a controller that is alive
 *     but stalled (SIGSTOP, debugger), which must not be reformatted under.
 *   - the status heartbeat: a controller that beats is alive even if it were
 *     built without the lock.
 * A segment that passes both (no lock, and not alive by mlip_peer_judge:
 * heartbeat older than MLIP_PEER_TIMEOUT_NS or never set) belongs to a dead controller and is
 * taken over: same object, truncated to the new size and reformatted.
 *
 * The owner unlinks the name before closing its descriptor, so the name is
 * never removed from under a successor that took the lock in between.
 *
 * Who may touch it: the name is created with O_EXCL, mode 0600 (0660 and a
 * chosen group with mlip_shm_create_group), fchmod'ed so the umask cannot
 * widen or narrow it. A name that already exists is taken over only when it
 * is a regular file of this controller's own user, open to no other user
 * (no "other" permission bits): /dev/shm is writable by everyone, and an
 * object pre-created by another local user would stay theirs after we
 * formatted it (they could then feed blocks and change the override of a
 * root controller). Attaching tools accept only a segment owned by
 * themselves, by root, or by the user MLIP_SHM_OWNER names (a controller run
 * as a service user with --shm-group), and never one open to every user.
 *
 * The segment's pages are reserved with posix_fallocate before it is
 * mapped: a full /dev/shm is a message at start-up, never SIGBUS at the
 * first touch of a page.
 *
 * Returns 0 or -errno; messages go to the caller's `why` buffer, never to
 * stdio (STYLE rule 5).
 */
#include "rt.h"

#include <errno.h>
#include <fcntl.h>
#include <grp.h>
#include <inttypes.h>
#include <pwd.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

uint64_t mlip_now_ns(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts); /* cannot fail for this clock */
	return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

static int say(char *why, size_t len, int rc, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

/* Fill why (may be NULL) and return rc, so error paths are one line. */
static int say(char *why, size_t len, int rc, const char *fmt, ...)
{
	va_list ap;

	if (why != NULL && len > 0) {
		va_start(ap, fmt);
		vsnprintf(why, len, fmt, ap);
		va_end(ap);
	}
	return rc;
}

static void shm_reset(struct mlip_shm *s)
{
	memset(s, 0, sizeof(*s));
	s->fd = -1;
}

/* POSIX leaves names without a leading '/' or with a second '/'
 * implementation-defined; accept only the portable form "/name". */
static int name_ok(const char *name)
{
	size_t n;

	if (name == NULL || name[0] != '/' || strchr(name + 1, '/') != NULL) {
		return 0;
	}
	n = strlen(name);
	return n > 1 && n < sizeof(((struct mlip_shm *)0)->name);
}

/* Age of a heartbeat in ns; -1 when there has never been one. */
static int64_t heartbeat_age_ns(uint64_t hb_ns)
{
	return mlip_peer_age_ns(hb_ns, mlip_now_ns());
}

/* The one liveness rule (mlip/ipc/peer.h) on the status stamp alone. */
/* looks at a controller that seems dead before saying so (5 x 100 ms) */
#define MLIP_SHM_ALIVE_LOOKS 5

static mlip_peer_verdict status_verdict(const struct mlip_ring_status *st)
{
	struct mlip_peer_seen seen = {st->heartbeat, st->heartbeat_ns, 0, -1};

	return mlip_peer_judge(&seen, NULL, mlip_now_ns(), NULL); /* clock after the read */
}

int mlip_shm_controller_alive(const struct mlip_ring *r)
{
	struct mlip_ring_status first, now;
	int have_first;

	if (r == NULL) {
		return 0;
	}
	have_first = mlip_ring_status_read(r, &first) == MLIP_OK;
	if (have_first && status_verdict(&first) == MLIP_PEER_ALIVE) {
		return 1;
	}
	/* An old stamp, or reads that kept meeting the writer, may be ours to
	 * blame (this process, or the whole host, was paused): look again for a
	 * few timeouts, as `mlip-ctl status` does; a heartbeat that moved is
	 * alive. A dead controller costs a command this wait, never a wrong
	 * "not running" for a live one on a loaded host. */
	for (int look = 0; look < MLIP_SHM_ALIVE_LOOKS; look++) {
		struct timespec ts = {0, (long)MLIP_PEER_TIMEOUT_NS};
		nanosleep(&ts, NULL);
		if (mlip_ring_status_read(r, &now) != MLIP_OK) {
			continue; /* mid-update again: look once more */
		}
		if ((have_first && now.heartbeat != first.heartbeat) ||
		    status_verdict(&now) == MLIP_PEER_ALIVE) {
			return 1;
		}
		if (!have_first) {
			first = now;
			have_first = 1;
		}
	}
	return 0; /* no consistent status, or a heartbeat that never moved */
}

/* "name" of uid (or "uid N" when it has none), for messages. */
static const char *user_name(uid_t uid, char *buf, size_t len)
{
	struct passwd *pw = getpwuid(uid); /* start-up only: not reentrant, fine here */

	if (pw != NULL && pw->pw_name != NULL) {
		snprintf(buf, len, "%s", pw->pw_name);
	} else {
		snprintf(buf, len, "uid %u", (unsigned)uid);
	}
	return buf;
}

/* The user MLIP_SHM_OWNER names (a name or a number); (uid_t)-1 when unset
 * or unknown. */
static uid_t trusted_owner(void)
{
	const char *v = getenv("MLIP_SHM_OWNER");
	struct passwd *pw;
	char *end;
	unsigned long n;

	if (v == NULL || *v == '\0') {
		return (uid_t)-1;
	}
	if ((pw = getpwnam(v)) != NULL) {
		return pw->pw_uid;
	}
	n = strtoul(v, &end, 10);
	return *end == '\0' && v[0] >= '0' && v[0] <= '9' ? (uid_t)n : (uid_t)-1;
}

/* May this process trust the object behind fd as a controller's segment?
 * 0, or -EPERM with a message. The controller (create) accepts only its own
 * user's; an attaching tool also root's and MLIP_SHM_OWNER's. Never a
 * non-regular file, never one every user may write. */
static int check_owner(int fd, const char *name, int creating, char *why, size_t len)
{
	struct stat sb;
	uid_t me = geteuid(), extra = creating ? (uid_t)-1 : trusted_owner();
	char who[64], self[64];

	if (fstat(fd, &sb) != 0) {
		int rc = -errno;
		return say(why, len, rc, "fstat %s: %s", name, strerror(-rc));
	}
	if (!S_ISREG(sb.st_mode)) {
		return say(why, len, -EPERM, "%s is not a regular shared-memory object: refused",
		           name);
	}
	if (sb.st_uid != me && (creating || (sb.st_uid != 0 && sb.st_uid != extra))) {
		user_name(sb.st_uid, who, sizeof(who));
		user_name(me, self, sizeof(self));
		if (creating) {
			return say(
			    why, len, -EPERM,
			    "%s exists and belongs to %s, not to this controller's user %s: "
			    "another user made it and could feed and command the machine "
			    "through it; remove /dev/shm%s (if no mlip-rt of theirs runs) or "
			    "choose another --shm name",
			    name, who, self, name);
		}
		return say(why, len, -EPERM,
		           "segment %s belongs to %s, neither you (%s) nor root: it may not be "
		           "your controller's; if mlip-rt really runs as %s, set "
		           "MLIP_SHM_OWNER=%s",
		           name, who, self, who, who);
	}
	if (sb.st_mode & 0007) {
		return say(why, len, -EPERM,
		           "%s has mode %04o: every user may open it, and mlip never makes it so; "
		           "remove /dev/shm%s (if no mlip-rt runs) and start mlip-rt again",
		           name, (unsigned)(sb.st_mode & 07777), name);
	}
	return 0;
}

/* What an existing object under our name holds, before we take it. */
enum existing { EX_EMPTY, EX_OURS_DEAD, EX_OURS_ALIVE, EX_FOREIGN, EX_OTHER_VERSION };

static enum existing inspect(int fd, int64_t *age_ns, uint64_t *magic, uint64_t *version)
{
	struct stat sb;
	struct mlip_ring *r;
	struct mlip_ring_mismatch mm;
	struct mlip_ring_status st;
	enum existing ex = EX_OURS_DEAD;
	void *mem;
	size_t bytes;

	*age_ns = -1;
	*magic = 0;
	if (fstat(fd, &sb) != 0 || sb.st_size <= 0) {
		return EX_EMPTY; /* just created, or a creator died before ftruncate */
	}
	bytes = (size_t)sb.st_size;
	mem = mmap(NULL, bytes, PROT_READ, MAP_SHARED, fd, 0);
	if (mem == MAP_FAILED) {
		return EX_OURS_DEAD;
	}
	if (mlip_ring_attach(mem, bytes, 0, &r, &mm) == MLIP_OK) {
		if (mlip_ring_status_read(r, &st) == MLIP_OK) {
			*age_ns = heartbeat_age_ns(st.heartbeat_ns);
			if (status_verdict(&st) == MLIP_PEER_ALIVE) {
				ex = EX_OURS_ALIVE;
			}
		}
	} else if (mm.reason == MLIP_RING_BAD_MAGIC && mm.found != 0) {
		/* not zero (a format in progress or never done) and not ours:
		 * some other program's object, never overwrite it */
		*magic = mm.found;
		ex = EX_FOREIGN;
	} else if (mm.reason == MLIP_RING_BAD_VERSION) {
		/* another build's segment: its feeders may still be attached and
		 * would read our layout as theirs; refuse rather than reformat */
		*version = mm.found;
		ex = EX_OTHER_VERSION;
	}
	/* a short or half-formatted segment: a dead controller's (whoever held
	 * it would hold the lock) */
	munmap(mem, bytes);
	return ex;
}

/* Write every page (with what is there) so each one is allocated and mapped
 * writable now: the RT thread must never take a page fault on its first
 * status write or record read. */
static void prefault(void *mem, size_t bytes)
{
	volatile unsigned char *p = mem;
	long page = sysconf(_SC_PAGESIZE);
	size_t step = page > 0 ? (size_t)page : 4096u;
	size_t i;

	for (i = 0; i < bytes; i += step) {
		p[i] = p[i];
	}
}

/* Common start of create and attach: a handle, reset, and a valid name. */
static int begin(struct mlip_shm *s, const char *name, char *why, size_t why_len)
{
	if (s == NULL) {
		return say(why, why_len, -EINVAL, "no shm handle");
	}
	shm_reset(s);
	if (!name_ok(name)) {
		return say(why, why_len, -EINVAL,
		           "shm name '%s' must be '/' followed by 1..62 characters without '/'",
		           name ? name : "(null)");
	}
	return 0;
}

/* Open name for the controller: a new object (O_EXCL, mode), or an existing
 * one of ours (check_owner). *created says which. */
static int open_exclusive(struct mlip_shm *s, const char *name, mode_t mode, int *created,
                          char *why, size_t why_len)
{
	int rc, tries;

	for (tries = 0; tries < 3; tries++) {
		s->fd = shm_open(name, O_CREAT | O_EXCL | O_RDWR, mode);
		if (s->fd >= 0) {
			*created = 1;
			return 0;
		}
		if (errno != EEXIST) {
			break;
		}
		s->fd = shm_open(name, O_RDWR, 0);
		if (s->fd >= 0) {
			*created = 0;
			rc = check_owner(s->fd, name, 1, why, why_len);
			if (rc != 0) {
				close(s->fd);
				s->fd = -1;
			}
			return rc;
		}
		if (errno != ENOENT) {
			break; /* else removed between the two opens: create it again */
		}
	}
	rc = -errno;
	if (rc == -EACCES) {
		return say(
		    why, why_len, rc,
		    "%s exists and belongs to another user (see ls -l /dev/shm%s): remove it "
		    "if no mlip-rt runs, or choose another --shm name",
		    name, name);
	}
	return say(why, why_len, rc, "shm_open %s: %s", name, strerror(-rc));
}

int mlip_shm_create(struct mlip_shm *s, const char *name, uint32_t capacity,
                    const struct mlip_machine *m, char *why, size_t why_len)
{
	return mlip_shm_create_group(s, name, capacity, m, -1, why, why_len);
}

int mlip_shm_create_group(struct mlip_shm *s, const char *name, uint32_t capacity,
                          const struct mlip_machine *m, long gid, char *why, size_t why_len)
{
	size_t bytes = mlip_ring_bytes(capacity);
	struct mlip_ring_mismatch mm;
	enum existing ex;
	int64_t age;
	uint64_t magic, version = 0;
	mode_t mode = gid < 0 ? 0600 : 0660;
	void *mem;
	int rc, flags = MAP_SHARED, created = 0;

	if ((rc = begin(s, name, why, why_len)) != 0) {
		return rc;
	}
	if (bytes == 0) {
		return say(why, why_len, -EINVAL,
		           "ring capacity %" PRIu32 " must be a power of two in 1..%u", capacity,
		           MLIP_RING_MAX_CAPACITY);
	}
	if (m == NULL || m->n_axes < 1 || m->n_axes > MLIP_MAX_AXES) {
		return say(why, why_len, -EINVAL, "no machine, or %d axes (1..%d)",
		           m ? m->n_axes : 0, MLIP_MAX_AXES);
	}
	strcpy(s->name, name);

	if ((rc = open_exclusive(s, name, mode, &created, why, why_len)) != 0) {
		shm_reset(s);
		return rc;
	}
	if (flock(s->fd, LOCK_EX | LOCK_NB) != 0) {
		rc = errno == EWOULDBLOCK ? -EBUSY : -errno;
		inspect(s->fd, &age, &magic, &version);
		close(s->fd);
		shm_reset(s);
		if (rc != -EBUSY) {
			return say(why, why_len, rc, "flock %s: %s", name, strerror(-rc));
		}
		if (age < 0) {
			return say(why, why_len, rc,
			           "a controller process holds %s (starting, no heartbeat yet): "
			           "stop that mlip-rt first",
			           name);
		}
		/* alive but not beating: stopped (SIGSTOP, debugger) or stuck */
		return say(why, why_len, rc,
		           "a controller process holds %s (last heartbeat %.1f %s ago): "
		           "stop that mlip-rt first",
		           name, age < 10000000000LL ? (double)age / 1e6 : (double)age / 1e9,
		           age < 10000000000LL ? "ms" : "s");
	}
	ex = created ? EX_EMPTY : inspect(s->fd, &age, &magic, &version);
	if (ex == EX_OURS_ALIVE) {
		close(s->fd);
		shm_reset(s);
		return say(why, why_len, -EBUSY,
		           "a controller is already running on %s (heartbeat %.1f ms ago): "
		           "stop it first (its pid is not in the segment: see pgrep mlip-rt)",
		           name, (double)age / 1e6);
	}
	if (ex == EX_OTHER_VERSION) {
		close(s->fd);
		shm_reset(s);
		return say(why, why_len, -EPROTO,
		           "%s has layout version %" PRIu64
		           ", this mlip-rt speaks %u: a controller of "
		           "another build left it, and its feeders may still use it; stop them and "
		           "remove /dev/shm%s, or choose another --shm name",
		           name, version, MLIP_RING_VERSION, name);
	}
	if (ex == EX_FOREIGN) {
		close(s->fd);
		shm_reset(s);
		return say(why, why_len, -EEXIST,
		           "%s exists and is not an mlip segment (magic 0x%016" PRIx64
		           "): choose another --shm name, or remove /dev/shm%s if it is stale",
		           name, magic, name);
	}
	/* explicit owner and mode, whatever the umask or a dead controller left */
	if (gid >= 0 && fchown(s->fd, (uid_t)-1, (gid_t)gid) != 0) {
		rc = -errno;
		shm_unlink(name);
		close(s->fd);
		shm_reset(s);
		return say(why, why_len, rc,
		           "%s: cannot give it to group %ld: %s (the controller's user must be a "
		           "member of the --shm-group)",
		           name, gid, strerror(-rc));
	}
	if (fchmod(s->fd, mode) != 0) {
		rc = -errno;
		goto fail;
	}
	if (ftruncate(s->fd, (off_t)bytes) != 0) {
		rc = -errno;
		goto fail;
	}
	/* reserve every page now (returns the error, does not set errno) */
	rc = posix_fallocate(s->fd, 0, (off_t)bytes);
	if (rc != 0) {
		rc = -rc;
		goto fail;
	}
#ifdef MAP_POPULATE
	flags |= MAP_POPULATE; /* prefault in the kernel; the loop below is the portable way */
#endif
	mem = mmap(NULL, bytes, PROT_READ | PROT_WRITE, flags, s->fd, 0);
	if (mem == MAP_FAILED) {
		rc = -errno;
		goto fail;
	}
	s->mem = mem;
	s->bytes = bytes;
	prefault(mem, bytes);
	/* mmap returns page-aligned memory, so MLIP_RING_LINE alignment holds */
	if (mlip_ring_format_machine(mem, bytes, capacity, m) != MLIP_OK ||
	    mlip_ring_attach(mem, bytes, m->n_axes, &s->ring, &mm) != MLIP_OK) {
		rc = -EINVAL;
		munmap(mem, bytes);
		shm_unlink(name);
		close(s->fd);
		shm_reset(s);
		return say(why, why_len, rc, "cannot format %s for %d axes", name, m->n_axes);
	}
	s->owner = 1;
	return 0;
fail:
	if (s->mem != NULL) {
		munmap(s->mem, s->bytes);
	}
	shm_unlink(name); /* ours now (we hold the lock); leave nothing half-made */
	close(s->fd);
	shm_reset(s);
	if (rc == -ENOSPC || rc == -ENOMEM || rc == -EFBIG) {
		return say(why, why_len, rc,
		           "%s: no room for the segment's %zu bytes in /dev/shm (%s): free space "
		           "there (df -h /dev/shm), or use a smaller --capacity",
		           name, bytes, strerror(-rc));
	}
	if (rc == -EAGAIN) {
		/* mmap of a segment under mlockall(MCL_FUTURE) beyond RLIMIT_MEMLOCK */
		return say(why, why_len, rc,
		           "%s: the segment's %zu bytes do not fit the locked-memory limit "
		           "(RLIMIT_MEMLOCK): raise it (ulimit -l, LimitMEMLOCK=infinity) or use a "
		           "smaller --capacity",
		           name, bytes);
	}
	return say(why, why_len, rc, "%s: %s", name, strerror(-rc));
}

/* One line for a refused attach (mismatch from mlip_ring_attach). */
static int attach_refused(const char *name, const struct mlip_ring_mismatch *mm, char *why,
                          size_t len)
{
	const char *what = mlip_ring_reason_str(mm->reason);
	unsigned long long found = mm->found, expected = mm->expected;

	switch (mm->reason) {
	case MLIP_RING_BAD_MAGIC:
		if (found == 0) {
			return say(why, len, -EAGAIN,
			           "segment %s is not formatted yet: mlip-rt is starting (or died "
			           "while starting); try again",
			           name);
		}
		return say(why, len, -EPROTO,
		           "%s is not an mlip segment (magic 0x%016llx): wrong --shm name?", name,
		           found);
	case MLIP_RING_SHORT:
		return say(why, len, -EAGAIN,
		           "segment %s is %llu bytes, not even a header (%llu): mlip-rt is "
		           "starting (or died while starting); try again",
		           name, found, expected);
	case MLIP_RING_BAD_VERSION:
		return say(why, len, -EPROTO,
		           "segment %s has layout version %llu, this program speaks %llu: "
		           "restart mlip-rt from the same build",
		           name, found, expected);
	case MLIP_RING_TRUNCATED:
		return say(why, len, -EPROTO,
		           "segment %s is %llu bytes, its header needs %llu: damaged segment; "
		           "restart mlip-rt",
		           name, found, expected);
	default:
		return say(why, len, -EPROTO,
		           "segment %s has %s %llu, this program expects %llu: restart mlip-rt "
		           "from the same build",
		           name, what, found, expected);
	}
}

int mlip_shm_attach(struct mlip_shm *s, const char *name, char *why, size_t why_len)
{
	struct mlip_ring_mismatch mm;
	struct stat sb;
	void *mem;
	size_t bytes;
	int rc;

	if ((rc = begin(s, name, why, why_len)) != 0) {
		return rc;
	}
	strcpy(s->name, name);
	s->fd = shm_open(name, O_RDWR, 0);
	if (s->fd < 0) {
		rc = -errno;
		shm_reset(s);
		if (rc == -ENOENT) {
			return say(why, why_len, rc,
			           "no controller segment %s: is mlip-rt running?", name);
		}
		if (rc == -EACCES) {
			return say(why, why_len, rc,
			           "%s: permission denied: run as mlip-rt's user or group "
			           "(see ls -l /dev/shm%s)",
			           name, name);
		}
		return say(why, why_len, rc, "shm_open %s: %s", name, strerror(-rc));
	}
	if ((rc = check_owner(s->fd, name, 0, why, why_len)) != 0) {
		close(s->fd);
		shm_reset(s);
		return rc;
	}
	if (fstat(s->fd, &sb) != 0) {
		rc = -errno;
		goto fail;
	}
	if ((uint64_t)sb.st_size < sizeof(struct mlip_ring)) {
		mm.reason = MLIP_RING_SHORT;
		mm.found = (uint64_t)sb.st_size;
		mm.expected = sizeof(struct mlip_ring);
		close(s->fd);
		shm_reset(s);
		return attach_refused(name, &mm, why, why_len);
	}
	bytes = (size_t)sb.st_size;
	mem = mmap(NULL, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, s->fd, 0);
	if (mem == MAP_FAILED) {
		rc = -errno;
		goto fail;
	}
	if (mlip_ring_attach(mem, bytes, 0, &s->ring, &mm) != MLIP_OK) {
		munmap(mem, bytes);
		close(s->fd);
		shm_reset(s);
		return attach_refused(name, &mm, why, why_len);
	}
	s->mem = mem;
	s->bytes = bytes;
	return 0;
fail:
	close(s->fd);
	shm_reset(s);
	return say(why, why_len, rc, "%s: %s", name, strerror(-rc));
}

static void producer_line(struct flock *fl)
{
	memset(fl, 0, sizeof(*fl));
	fl->l_type = F_WRLCK;
	fl->l_whence = SEEK_SET;
	fl->l_start = (off_t)offsetof(struct mlip_ring, head);
	fl->l_len = MLIP_RING_LINE;
}

int mlip_shm_feeder_lock(struct mlip_shm *s, int32_t *holder)
{
	struct flock fl;

	producer_line(&fl);
	if (fcntl(s->fd, F_SETLK, &fl) == 0) {
		return 0;
	}
	if (errno != EACCES && errno != EAGAIN) {
		return -errno;
	}
	*holder = mlip_shm_feeder_holder(s);
	return -EBUSY;
}

int32_t mlip_shm_feeder_holder(const struct mlip_shm *s)
{
	struct flock fl;

	producer_line(&fl);
	if (s->mem == NULL || fcntl(s->fd, F_GETLK, &fl) != 0 || fl.l_type == F_UNLCK) {
		return 0;
	}
	return (int32_t)fl.l_pid;
}

void mlip_shm_close(struct mlip_shm *s)
{
	/* only a handle that create/attach filled: a zeroed struct has fd 0 */
	if (s == NULL || s->mem == NULL) {
		return;
	}
	if (s->owner) {
		shm_unlink(s->name); /* while we still hold the lock, see the header */
	}
	munmap(s->mem, s->bytes);
	close(s->fd);
	shm_reset(s);
}
