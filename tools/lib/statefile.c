/* statefile.c - see statefile.h */
#include "statefile.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define MARKER    "end"
#define CHECK_HEX 16 /* hex digits of the checksum in the marker */
#define TMP_TRIES 16

/* ---- records -------------------------------------------------------------- */

void mlip_sf_init(struct mlip_sf *sf)
{
	memset(sf, 0, sizeof(*sf));
}

void mlip_sf_free(struct mlip_sf *sf)
{
	for (size_t i = 0; i < sf->n; i++) {
		free(sf->rec[i].value);
	}
	free(sf->rec);
	mlip_sf_init(sf);
}

const struct mlip_sf_rec *mlip_sf_find(const struct mlip_sf *sf, const char *key)
{
	for (size_t i = 0; sf != NULL && i < sf->n; i++) {
		if (strcmp(sf->rec[i].key, key) == 0) {
			return &sf->rec[i];
		}
	}
	return NULL;
}

const char *mlip_sf_get(const struct mlip_sf *sf, const char *key)
{
	const struct mlip_sf_rec *r = mlip_sf_find(sf, key);
	return r ? r->value : NULL;
}

static int put_line(struct mlip_sf *sf, const char *key, const char *value, uint32_t line)
{
	char *v;
	if (strlen(key) >= MLIP_SF_KEY || (v = strdup(value)) == NULL) {
		return -1;
	}
	struct mlip_sf_rec *r = (struct mlip_sf_rec *)mlip_sf_find(sf, key);
	if (r != NULL) {
		free(r->value);
		r->value = v;
		r->line = line;
		return 0;
	}
	if (sf->n == sf->cap) {
		size_t cap = sf->cap ? 2 * sf->cap : 32;
		struct mlip_sf_rec *nr = realloc(sf->rec, cap * sizeof(*nr));
		if (nr == NULL) {
			free(v);
			return -1;
		}
		sf->rec = nr;
		sf->cap = cap;
	}
	r = &sf->rec[sf->n++];
	memset(r, 0, sizeof(*r));
	strcpy(r->key, key);
	r->value = v;
	r->line = line;
	return 0;
}

int mlip_sf_put(struct mlip_sf *sf, const char *key, const char *value)
{
	return put_line(sf, key, value, 0);
}

/* ---- paths: the folder and the name in it ----------------------------------- */

static int say(char *why, size_t len, int rc, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static int say(char *why, size_t len, int rc, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(why, len, fmt, ap);
	va_end(ap);
	return rc;
}

/* The folder of path, opened, and the name in it (a pointer into path). */
static int open_dir(const char *path, const char **name, char *why, size_t len)
{
	const char *slash = strrchr(path, '/');
	char dir[4096];
	int fd;

	*name = slash ? slash + 1 : path;
	if (**name == '\0' || strcmp(*name, ".") == 0 || strcmp(*name, "..") == 0) {
		return say(why, len, -1, "%s: not a file name", path);
	}
	if (slash == NULL) {
		strcpy(dir, ".");
	} else if (slash == path) {
		strcpy(dir, "/");
	} else if ((size_t)(slash - path) < sizeof(dir)) {
		memcpy(dir, path, (size_t)(slash - path));
		dir[slash - path] = '\0';
	} else {
		return say(why, len, -1, "%s: path too long", path);
	}
	fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (fd < 0) {
		return say(why, len, -1, "%s: its folder %s: %s", path, dir, strerror(errno));
	}
	return fd;
}

const char *mlip_file_kind(unsigned mode)
{
	return S_ISDIR(mode)    ? "a directory"
	       : S_ISLNK(mode)  ? "a symbolic link"
	       : S_ISFIFO(mode) ? "a FIFO (pipe)"
	       : S_ISCHR(mode)  ? "a character device"
	       : S_ISBLK(mode)  ? "a block device"
	       : S_ISSOCK(mode) ? "a socket"
	                        : "not a regular file";
}

static int not_regular(const char *path, mode_t mode, char *why, size_t len)
{
	if (S_ISLNK(mode)) {
		return say(why, len, -1,
		           "%s is a symbolic link: mlip writes this file by renaming a new one "
		           "over its name, which would replace the link (and it never writes "
		           "through one): give the file's real path (readlink -f %s)",
		           path, path);
	}
	return say(why, len, -1, "%s is %s, not a regular file", path, mlip_file_kind(mode));
}

/* ---- reading ---------------------------------------------------------------- */

/* Read the whole regular file `name` in dirfd: 0 with *buf (NUL-terminated,
 * caller frees) and id filled; -ENOENT; -1 with why. */
static int slurp(int dirfd, const char *name, const char *path, char **buf, size_t *len,
                 struct mlip_sf_id *id, char *why, size_t wlen)
{
	struct stat st;
	int fd = openat(dirfd, name, O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
	if (fd < 0) {
		int e = errno;
		if (e == ENOENT) {
			return -ENOENT;
		}
		if (e == ELOOP ||
		    (fstatat(dirfd, name, &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISLNK(st.st_mode))) {
			return not_regular(path, S_IFLNK, why, wlen);
		}
		return say(why, wlen, -1, "%s: %s", path, strerror(e));
	}
	if (fstat(fd, &st) != 0) {
		int e = errno;
		close(fd);
		return say(why, wlen, -1, "%s: %s", path, strerror(e));
	}
	if (!S_ISREG(st.st_mode)) {
		close(fd);
		return not_regular(path, st.st_mode, why, wlen);
	}
	if ((uint64_t)st.st_size > MLIP_SF_MAX_BYTES) {
		close(fd);
		return say(why, wlen, -1, "%s: %llu bytes, more than a state file holds (%u)", path,
		           (unsigned long long)st.st_size, MLIP_SF_MAX_BYTES);
	}
	char *b = malloc((size_t)st.st_size + 1);
	size_t n = 0;
	if (b == NULL) {
		close(fd);
		return say(why, wlen, -1, "%s: %s", path, strerror(ENOMEM));
	}
	for (;;) {
		ssize_t got = read(fd, b + n, (size_t)st.st_size + 1 - n);
		if (got < 0 && errno == EINTR) {
			continue;
		}
		if (got < 0) {
			int e = errno;
			free(b);
			close(fd);
			return say(why, wlen, -1, "%s: %s", path, strerror(e));
		}
		if (got == 0 || n + (size_t)got > (size_t)st.st_size) {
			n += (size_t)got;
			break;
		}
		n += (size_t)got;
	}
	close(fd);
	if (n != (size_t)st.st_size) {
		free(b);
		return say(why, wlen, -1, "%s changed while it was read: try again", path);
	}
	b[n] = '\0';
	memset(id, 0, sizeof(*id));
	id->exists = 1;
	id->dev = (uint64_t)st.st_dev;
	id->ino = (uint64_t)st.st_ino;
	id->size = (uint64_t)st.st_size;
	id->mtime_s = (int64_t)st.st_mtim.tv_sec;
	id->mtime_ns = (int64_t)st.st_mtim.tv_nsec;
	mlip_sha256(b, n, id->sha);
	*buf = b;
	*len = n;
	return 0;
}

/* Length of a valid UTF-8 sequence at s (n bytes left), 0 when invalid. */
static size_t utf8_len(const unsigned char *s, size_t n)
{
	size_t k;
	unsigned c = s[0];
	uint32_t cp;
	if (c < 0x80) {
		return 1;
	}
	if (c >= 0xc2 && c <= 0xdf) {
		k = 2, cp = c & 0x1f;
	} else if (c >= 0xe0 && c <= 0xef) {
		k = 3, cp = c & 0x0f;
	} else if (c >= 0xf0 && c <= 0xf4) {
		k = 4, cp = c & 0x07;
	} else {
		return 0;
	}
	if (n < k) {
		return 0;
	}
	for (size_t i = 1; i < k; i++) {
		if ((s[i] & 0xc0) != 0x80) {
			return 0;
		}
		cp = cp << 6 | (s[i] & 0x3f);
	}
	if ((k == 3 && (cp < 0x800 || (cp >= 0xd800 && cp <= 0xdfff))) ||
	    (k == 4 && (cp < 0x10000 || cp > 0x10ffff))) {
		return 0;
	}
	return k;
}

/* 1-based line of byte offset off. */
static unsigned line_at(const char *b, size_t off)
{
	unsigned line = 1;
	for (size_t i = 0; i < off; i++) {
		line += b[i] == '\n';
	}
	return line;
}

static char *trim(char *s)
{
	while (*s == ' ' || *s == '\t') {
		s++;
	}
	char *e = s + strlen(s);
	while (e > s && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\r')) {
		*--e = '\0';
	}
	return s;
}

/* "# end N lines sha256 HEX": 1 with N and HEX; 0 when the line is not one. */
static int parse_marker(const char *s, char comment, unsigned long *count, char *hex)
{
	char c, tail;
	unsigned long n;
	char h[CHECK_HEX + 2];
	if (sscanf(s, "%c " MARKER " %lu lines sha256 %17s%c", &c, &n, h, &tail) != 3 ||
	    c != comment || strlen(h) != CHECK_HEX || strspn(h, "0123456789abcdef") != CHECK_HEX) {
		return 0;
	}
	*count = n;
	strcpy(hex, h);
	return 1;
}

static void checksum_hex(const char *b, size_t n, char *hex)
{
	uint8_t d[MLIP_SHA256_BYTES];
	mlip_sha256(b, n, d);
	mlip_sha256_hex(d, hex, CHECK_HEX);
}

/* Parse and check the bytes b (n long) of path into sf. */
static int parse(struct mlip_sf *sf, char *b, size_t n, const char *path,
                 const struct mlip_sf_kind *k, unsigned flags, char *why, size_t wlen)
{
	const char *fix = k->repair ? k->repair : "restore it from a backup";
	unsigned lines = 0;
	size_t body = n; /* bytes before the marker line */
	int sealed = !(flags & MLIP_SF_UNSEALED);

	if (n == 0) {
		return say(why, wlen, -1,
		           "%s is empty: a write cut short (a power cut, a full disk) leaves that; "
		           "its values are lost: %s",
		           path, fix);
	}
	for (size_t i = 0; i < n;) {
		unsigned char c = (unsigned char)b[i];
		if (c == '\0') {
			return say(
			    why, wlen, -1,
			    "%s:%u: a NUL byte (offset %zu): what a power cut leaves of a file "
			    "that was being written; its values cannot be trusted: %s",
			    path, line_at(b, i), i, fix);
		}
		if (c < 0x20 && c != '\n' && c != '\t' && c != '\r') {
			return say(why, wlen, -1, "%s:%u: control byte 0x%02x: not a text file; %s",
			           path, line_at(b, i), c, fix);
		}
		size_t u = utf8_len((const unsigned char *)b + i, n - i);
		if (u == 0) {
			return say(why, wlen, -1, "%s:%u: not UTF-8 text (byte 0x%02x); %s", path,
			           line_at(b, i), c, fix);
		}
		i += u;
	}
	/* the marker: the last line, complete */
	if (sealed) {
		unsigned long count;
		char hex[CHECK_HEX + 2], want[CHECK_HEX + 1];
		size_t last = n - 1;
		if (b[n - 1] != '\n') {
			return say(
			    why, wlen, -1,
			    "%s:%u: the last line is cut short (no end of line): the file was "
			    "not written to its end (a power cut, a full disk); %s",
			    path, line_at(b, n - 1), fix);
		}
		while (last > 0 && b[last - 1] != '\n') {
			last--;
		}
		b[n - 1] = '\0';
		if (!parse_marker(b + last, k->comment, &count, hex)) {
			return say(
			    why, wlen, -1,
			    "%s:%u: no end marker ('%c %s N lines sha256 ...' as the last line): "
			    "the "
			    "file was cut short (a power cut, a full disk) or not written by mlip. "
			    "If you wrote it by hand and checked it: %s %s; if it was cut short: "
			    "%s",
			    path, line_at(b, last), k->comment, MARKER, k->accept, path, fix);
		}
		checksum_hex(b, last, want);
		lines = line_at(b, last) - 1;
		if (count != lines || strcmp(hex, want) != 0) {
			return say(
			    why, wlen, -1,
			    "%s: changed after mlip wrote it (%s does not match its %s): a hand "
			    "edit, or a damaged disk. Check every value; if they are right: %s "
			    "%s (it checks them and seals the file); else %s",
			    path,
			    count != lines ? "the end marker's line count"
			                   : "the end marker's checksum",
			    count != lines ? "lines" : "bytes", k->accept, path, fix);
		}
		body = last;
	}
	/* the records */
	char *s = b;
	unsigned line = 0;
	while ((size_t)(s - b) < body) {
		char *nl = memchr(s, '\n', body - (size_t)(s - b));
		char *next = nl ? nl + 1 : b + body;
		if (nl) {
			*nl = '\0';
		} else {
			b[body] = '\0';
		}
		line++;
		if (strlen(s) >= MLIP_SF_MAX_LINE) {
			return say(why, wlen, -1, "%s:%u: line longer than %d bytes", path, line,
			           MLIP_SF_MAX_LINE - 1);
		}
		char *t = trim(s);
		if (*t == '\0' || *t == k->comment) {
			s = next;
			continue;
		}
		char key[MLIP_SF_KEY], val[MLIP_SF_MAX_LINE], canon[MLIP_SF_MAX_LINE];
		char what[MLIP_SF_WHY / 2];
		size_t kl = strcspn(t, " \t");
		if (kl >= MLIP_SF_KEY) {
			return say(why, wlen, -1, "%s:%u: '%.40s...': not a key", path, line, t);
		}
		memcpy(key, t, kl);
		key[kl] = '\0';
		snprintf(val, sizeof(val), "%s", trim(t + kl));
		const struct mlip_sf_rec *dup = mlip_sf_find(sf, key);
		if (dup != NULL) {
			return say(why, wlen, -1,
			           "%s:%u: %s a second time (first on line %u): which one holds? "
			           "Keep one, then %s %s",
			           path, line, key, dup->line, k->accept, path);
		}
		if (k->canon(k->ctx, key, val, canon, sizeof(canon), what, sizeof(what)) != 0) {
			return say(why, wlen, -1, "%s:%u: %s", path, line, what);
		}
		if (put_line(sf, key, canon, line) != 0) {
			return say(why, wlen, -1, "%s: %s", path, strerror(ENOMEM));
		}
		s = next;
	}
	for (const char *const *r = k->required; r != NULL && *r != NULL; r++) {
		if (mlip_sf_find(sf, *r) == NULL) {
			return say(
			    why, wlen, -1,
			    "%s: no %s line: every %s holds one (a line lost in an edit?); %s",
			    path, *r, k->what, fix);
		}
	}
	return 0;
}

int mlip_sf_load(struct mlip_sf *sf, const char *path, const struct mlip_sf_kind *k, unsigned flags,
                 char *why, size_t why_len)
{
	const char *name;
	char *b = NULL;
	size_t n;
	int rc, dirfd;

	mlip_sf_init(sf);
	if ((dirfd = open_dir(path, &name, why, why_len)) < 0) {
		return -1;
	}
	rc = slurp(dirfd, name, path, &b, &n, &sf->id, why, why_len);
	close(dirfd);
	if (rc == -ENOENT) {
		say(why, why_len, rc, "%s: no such file", path);
		return rc;
	}
	if (rc != 0) {
		return -1;
	}
	rc = parse(sf, b, n, path, k, flags, why, why_len);
	free(b);
	if (rc != 0) {
		struct mlip_sf_id id = sf->id;
		mlip_sf_free(sf);
		sf->id = id;
		return -1;
	}
	return 0;
}

/* ---- writing ---------------------------------------------------------------- */

struct out {
	char *b;
	size_t n, cap;
	int bad;
};

static void outf(struct out *o, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void outf(struct out *o, const char *fmt, ...)
{
	va_list ap;
	for (;;) {
		va_start(ap, fmt);
		int w = vsnprintf(o->b + o->n, o->cap - o->n, fmt, ap);
		va_end(ap);
		if (w < 0) {
			o->bad = 1;
			return;
		}
		if ((size_t)w < o->cap - o->n) {
			o->n += (size_t)w;
			return;
		}
		size_t cap = 2 * o->cap + (size_t)w + 1;
		char *nb = realloc(o->b, cap);
		if (nb == NULL) {
			o->bad = 1;
			return;
		}
		o->b = nb;
		o->cap = cap;
	}
}

/* The whole text of a file holding recs. */
static int render(const struct mlip_sf_kind *k, const struct mlip_sf *recs, struct out *o)
{
	char hex[CHECK_HEX + 1];
	unsigned lines = 0;
	o->cap = 4096;
	o->b = malloc(o->cap);
	o->n = 0;
	o->bad = o->b == NULL;
	if (o->bad) {
		return -1;
	}
	o->b[0] = '\0';
	for (const char *const *h = k->header; h != NULL && *h != NULL; h++, lines++) {
		outf(o, "%c%s%s\n", k->comment, **h ? " " : "", *h);
	}
	for (size_t i = 0; i < recs->n; i++, lines++) {
		outf(o, "%s %s\n", recs->rec[i].key, recs->rec[i].value);
	}
	if (o->bad) {
		return -1;
	}
	checksum_hex(o->b, o->n, hex);
	outf(o, "%c " MARKER " %u lines sha256 %s\n", k->comment, lines, hex);
	return o->bad ? -1 : 0;
}

static int write_all(int fd, const char *b, size_t n)
{
	while (n > 0) {
		ssize_t w = write(fd, b, n);
		if (w < 0 && errno == EINTR) {
			continue;
		}
		if (w <= 0) {
			return w < 0 ? -errno : -EIO;
		}
		b += w;
		n -= (size_t)w;
	}
	return 0;
}

static int same_value(const char *a, const char *b)
{
	return (a == NULL && b == NULL) || (a != NULL && b != NULL && strcmp(a, b) == 0);
}

static void append(char *s, size_t len, const char *what)
{
	size_t n = strlen(s);
	snprintf(s + n, len - n, "%s%s", n ? ", " : "", what);
}

/* ours merged with theirs against base, per key, into out. 0, or -1 with
 * the keys both changed in why. note gets the keys kept from theirs. */
static int merge(const struct mlip_sf *base, const struct mlip_sf *ours,
                 const struct mlip_sf *theirs, struct mlip_sf *out, char *note, size_t note_len,
                 char *conflicts, size_t clen)
{
	int bad = 0;
	const struct mlip_sf *order[2] = {ours, theirs};

	conflicts[0] = '\0';
	note[0] = '\0';
	for (int pass = 0; pass < 2; pass++) {
		for (size_t i = 0; i < order[pass]->n; i++) {
			const char *key = order[pass]->rec[i].key;
			if (pass == 1 && mlip_sf_find(ours, key) != NULL) {
				continue; /* done in the first pass */
			}
			const char *b = mlip_sf_get(base, key), *o = mlip_sf_get(ours, key),
			           *t = mlip_sf_get(theirs, key), *r;
			if (same_value(o, b)) {
				r = t; /* only they changed it (or nobody) */
				if (!same_value(t, b)) {
					append(note, note_len, key);
				}
			} else if (same_value(t, b) || same_value(o, t)) {
				r = o; /* only we changed it, or both the same way */
			} else {
				append(conflicts, clen, key);
				bad = 1;
				continue;
			}
			if (r != NULL && mlip_sf_put(out, key, r) != 0) {
				return -1;
			}
		}
	}
	return bad ? -1 : 0;
}

static int same_id(const struct mlip_sf_id *a, const struct mlip_sf_id *b)
{
	return a->exists == b->exists &&
	       (!a->exists || (a->dev == b->dev && a->ino == b->ino && a->size == b->size &&
	                       a->mtime_s == b->mtime_s && a->mtime_ns == b->mtime_ns &&
	                       memcmp(a->sha, b->sha, sizeof(a->sha)) == 0));
}

/* The file as it is now in dirfd: its identity, and its records (checked
 * as a sealed file) when it differs from base's. 0, or -1 with why. */
static int current(int dirfd, const char *name, const char *path, const struct mlip_sf_kind *k,
                   const struct mlip_sf *base, struct mlip_sf *now, char *why, size_t wlen)
{
	char *b = NULL;
	size_t n;
	mlip_sf_init(now);
	int rc = slurp(dirfd, name, path, &b, &n, &now->id, why, wlen);
	if (rc == -ENOENT) {
		return 0; /* deleted: no records, id.exists 0 */
	}
	if (rc != 0) {
		return -1;
	}
	rc = same_id(&now->id, &base->id) ? 0 : parse(now, b, n, path, k, 0, why, wlen);
	free(b);
	return rc;
}

static void tmp_name(char *buf, size_t len, const char *name)
{
	unsigned char r[6];
	if (getrandom(r, sizeof(r), GRND_NONBLOCK) != (ssize_t)sizeof(r)) {
		struct timespec ts;
		clock_gettime(CLOCK_MONOTONIC, &ts);
		uint64_t x =
		    (uint64_t)ts.tv_nsec ^ (uint64_t)ts.tv_sec << 30 ^ (uint64_t)getpid() << 16;
		for (size_t i = 0; i < sizeof(r); i++) {
			r[i] = (unsigned char)(x >> (8 * i));
		}
	}
	snprintf(buf, len, "%s.tmp.%02x%02x%02x%02x%02x%02x", name, r[0], r[1], r[2], r[3], r[4],
	         r[5]);
}

/* Create the new file with the owner and mode of st (NULL: a new one).
 * The fd, or -1 with why. */
static int create_tmp(int dirfd, const char *name, const char *path, const struct stat *st,
                      char *tmp, size_t tmp_len, char *why, size_t wlen)
{
	int fd = -1;
	for (int i = 0; i < TMP_TRIES && fd < 0; i++) {
		tmp_name(tmp, tmp_len, name);
		/* O_EXCL: never an entry that exists, a planted link least of all */
		fd = openat(dirfd, tmp, O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC,
		            st ? 0600 : 0666);
		if (fd < 0 && errno != EEXIST) {
			return say(why, wlen, -1, "%s: creating %s in its folder: %s", path, tmp,
			           strerror(errno));
		}
	}
	if (fd < 0) {
		return say(why, wlen, -1, "%s: no free temporary name in its folder", path);
	}
	if (st != NULL) {
		if ((st->st_uid != geteuid() || st->st_gid != getegid()) &&
		    fchown(fd, st->st_uid, st->st_gid) != 0) {
			int e = errno;
			close(fd);
			unlinkat(dirfd, tmp, 0);
			return say(why, wlen, -1,
			           "%s belongs to uid %u gid %u: written as uid %u it would change "
			           "owner (%s): run as its owner (or root), or chown it",
			           path, (unsigned)st->st_uid, (unsigned)st->st_gid,
			           (unsigned)geteuid(), strerror(e));
		}
		if (fchmod(fd, st->st_mode & 0777) != 0) {
			int e = errno;
			close(fd);
			unlinkat(dirfd, tmp, 0);
			return say(why, wlen, -1, "%s: keeping its mode: %s", path, strerror(e));
		}
	}
	return fd;
}

int mlip_sf_save(const char *path, const struct mlip_sf_kind *k, const struct mlip_sf *ours,
                 const struct mlip_sf *base, char *note, size_t note_len, char *why, size_t why_len)
{
	const char *name;
	char tmp[4096 + 32], conflicts[MLIP_SF_WHY / 2];
	struct mlip_sf now, merged;
	const struct mlip_sf *write = ours;
	struct out o = {NULL, 0, 0, 0};
	struct stat st;
	int dirfd, fd = -1, rc = -1, merged_rc = 0, exists;

	note[0] = '\0';
	mlip_sf_init(&now);
	mlip_sf_init(&merged);
	if ((dirfd = open_dir(path, &name, why, why_len)) < 0) {
		return -1;
	}
	(void)flock(dirfd, LOCK_EX); /* mlip writers of this folder, one at a time */
	exists = fstatat(dirfd, name, &st, AT_SYMLINK_NOFOLLOW) == 0;
	if (!exists && errno != ENOENT) {
		say(why, why_len, -1, "%s: %s", path, strerror(errno));
		goto out;
	}
	if (exists && !S_ISREG(st.st_mode)) {
		not_regular(path, st.st_mode, why, why_len);
		goto out;
	}
	if (base != NULL) {
		/* the file as it is now, against the one loaded before the run */
		if (current(dirfd, name, path, k, base, &now, why, why_len) != 0) {
			char inner[MLIP_SF_WHY];
			snprintf(inner, sizeof(inner), "%s", why);
			say(why, why_len, -1,
			    "%s was changed while the program ran and cannot be read now, so "
			    "nothing "
			    "was written to it: %s",
			    path, inner);
			goto out;
		}
		if (!now.id.exists && base->id.exists) {
			/* deleted meanwhile: nothing to merge with; ours again, said */
			snprintf(note, note_len,
			         "the file was deleted during the run: written again");
			merged_rc = 1;
		} else if (!same_id(&now.id, &base->id)) {
			if (merge(base, ours, &now, &merged, note, note_len, conflicts,
			          sizeof(conflicts)) != 0) {
				say(why, why_len, -1,
				    "%s was changed while the program ran, and %s changed both "
				    "there and "
				    "by the program: nothing was written (the file keeps the "
				    "values "
				    "entered meanwhile)",
				    path, conflicts[0] ? conflicts : "memory ran out");
				goto out;
			}
			write = &merged;
			merged_rc = note[0] != '\0';
		}
	}
	if (render(k, write, &o) != 0) {
		say(why, why_len, -1, "%s: %s", path, strerror(ENOMEM));
		goto out;
	}
	fd = create_tmp(dirfd, name, path, exists ? &st : NULL, tmp, sizeof(tmp), why, why_len);
	if (fd < 0) {
		goto out;
	}
	int e = write_all(fd, o.b, o.n);
	if (e == 0 && fsync(fd) != 0) {
		e = -errno;
	}
	if (close(fd) != 0 && e == 0) {
		e = -errno;
	}
	fd = -1;
	if (e != 0) {
		unlinkat(dirfd, tmp, 0);
		say(why, why_len, -1, "%s: writing %s: %s; the file is as it was", path, tmp,
		    strerror(-e));
		goto out;
	}
	if (renameat(dirfd, tmp, dirfd, name) != 0) {
		e = errno;
		unlinkat(dirfd, tmp, 0);
		say(why, why_len, -1, "%s: renaming %s over it: %s; the file is as it was", path,
		    tmp, strerror(e));
		goto out;
	}
	if (fsync(dirfd) != 0) {
		say(why, why_len, -1,
		    "%s: written, but its folder could not be synced (%s): a power cut now may "
		    "lose it",
		    path, strerror(errno));
		goto out;
	}
	rc = merged_rc;
out:
	free(o.b);
	mlip_sf_free(&now);
	mlip_sf_free(&merged);
	close(dirfd); /* drops the lock */
	return rc;
}

int mlip_sf_save_told(const char *path, const struct mlip_sf_kind *k, const struct mlip_sf *ours,
                      const struct mlip_sf *base, const char *what, const char *run,
                      const char *prog, FILE *err)
{
	char why[MLIP_SF_WHY], note[MLIP_SF_WHY / 2];
	int rc = mlip_sf_save(path, k, ours, base, note, sizeof(note), why, sizeof(why));

	if (rc == 1 && strncmp(note, "the file was deleted", 20) == 0) {
		fprintf(err, "%s: %s: deleted during the %s: written again with its values\n", prog,
		        path, run);
	} else if (rc == 1) {
		fprintf(
		    err,
		    "%s: %s: merged with a change made during the %s: %s kept as the file had it\n",
		    prog, path, run, note);
	}
	if (rc < 0) {
		fprintf(err, "%s: error: %s\n%s: the %s the %s left, not written:\n", prog, why,
		        prog, what, run);
		for (size_t i = 0; i < ours->n; i++) {
			fprintf(err, "%s:   %s %s\n", prog, ours->rec[i].key, ours->rec[i].value);
		}
	}
	return rc < 0 ? -1 : 0;
}
