/*
 * statefile.h - the files mlip keeps for the operator (the offsets file
 * today; the tool table and the current tool next): small keyed text files
 * that outlive a run, written and read the way a database keeps its state.
 *
 * Format, human-editable:
 *
 *   # comment lines (the kind's comment character first: '#' or ';')
 *   KEY VALUE...                 one record a line: KEY the first word,
 *   KEY VALUE...                 VALUE the rest (trimmed); each KEY once
 *   # end 14 lines sha256 3f2a9c5b1d7e0a42
 *
 * The last line is the end marker mlip writes: the number of lines before
 * it and the first 16 hex digits of the SHA-256 of their bytes. A file
 * without it was cut short (a power cut, a full disk) or not written by
 * mlip; one whose count or checksum differs was changed after mlip wrote it
 * (an editor, a damaged disk). Both are refused with the reason and what to
 * do: after a hand edit, the kind's accept command (e.g. `mlip-offsets
 * --accept FILE`) checks every record and writes the marker again, which is
 * how a control asks "accept these values?" after an edit.
 *
 * Reading (mlip_sf_load): the path names a regular file, not a symbolic
 * link (mlip writes by renaming a new file over the name: a link would be
 * replaced, and a link into another user's file must never be written
 * through), at most MLIP_SF_MAX_BYTES, not empty, no NUL or other control
 * byte, UTF-8, the marker last and matching; every record checked by the
 * kind (canon: the value parsed strictly and given back as mlip writes it),
 * every required key present, none twice. Its identity (device, inode,
 * size, mtime and the SHA-256 of its bytes) is kept for the write-back.
 *
 * Writing (mlip_sf_save), in the file's folder and under an advisory lock
 * on that folder (mlip writers one at a time):
 *   1. a new file FILE.tmp.XXXXXXXXXXXX (random name) created with
 *      O_EXCL | O_NOFOLLOW | O_CLOEXEC: never through a link someone
 *      planted; owner and mode of the file it replaces (a new file: 0666
 *      less the umask);
 *   2. written, fsync'd, closed;
 *   3. renamed over FILE, the folder fsync'd (so the rename survives a power
 *      cut). A failure at any step leaves FILE as it was and removes the
 *      new file.
 * A concurrent change: given base (the file as loaded before a run), a FILE
 * whose identity or bytes differ at the write-back (an operator entered a
 * G56 for the next fixture meanwhile) is read again and merged per key:
 * ours where only we changed a record, theirs where only they did; a record
 * both changed differently refuses the whole write, naming the keys, and
 * FILE stays as they left it (the caller shows what was not written).
 *
 * Host tools only (malloc, stdio, system calls).
 */
#ifndef MLIP_TOOLS_STATEFILE_H
#define MLIP_TOOLS_STATEFILE_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "sha256.h"

#define MLIP_SF_MAX_BYTES (4u << 20) /* a larger file is refused */
#define MLIP_SF_MAX_LINE  1024       /* bytes of one line */
#define MLIP_SF_KEY       32         /* bytes of a key, NUL included */
#define MLIP_SF_WHY       1024       /* room for a message */

/* What kind of file, for the checks and the messages. */
struct mlip_sf_kind {
	const char *what;            /* "offsets file" */
	char comment;                /* '#' or ';' */
	const char *accept;          /* the command that accepts a hand edit of FILE,
	                                e.g. "mlip-offsets --accept" */
	const char *repair;          /* what to do with a damaged file (a sentence) */
	const char *const *required; /* keys every file has, NULL-terminated (or NULL) */
	const char *const *header;   /* comment lines written on top, NULL-terminated */
	/* One record: 0 with its value as mlip writes it in out (the same text
	 * for the same value, so that records compare as text), or -1 with why
	 * (no file or line in it). */
	int (*canon)(const void *ctx, const char *key, const char *value, char *out, size_t out_len,
	             char *why, size_t why_len);
	const void *ctx;
};

struct mlip_sf_rec {
	char key[MLIP_SF_KEY];
	char *value;   /* canonical, owned */
	uint32_t line; /* in the file it was read from (0: made by a tool) */
};

/* A file's identity, as loaded. */
struct mlip_sf_id {
	int exists;
	uint64_t dev, ino, size;
	int64_t mtime_s, mtime_ns;
	uint8_t sha[MLIP_SHA256_BYTES];
};

/* The records of a file, in order. */
struct mlip_sf {
	struct mlip_sf_rec *rec;
	size_t n, cap;
	struct mlip_sf_id id;
};

void mlip_sf_init(struct mlip_sf *sf);
void mlip_sf_free(struct mlip_sf *sf);
/* Set key to value (appended, or replaced in place). 0, or -1 (no memory,
 * a key too long). */
int mlip_sf_put(struct mlip_sf *sf, const char *key, const char *value);
/* The value of key, or NULL. */
const char *mlip_sf_get(const struct mlip_sf *sf, const char *key);
const struct mlip_sf_rec *mlip_sf_find(const struct mlip_sf *sf, const char *key);

#define MLIP_SF_UNSEALED 0x1 /* load: no end marker needed (a hand edit, to accept) */

/* Load path into sf (initialised here). 0; -ENOENT when there is no such
 * file (sf empty, id.exists 0; why says so); -1 refused, why = "PATH:LINE:
 * the problem; what to do". */
int mlip_sf_load(struct mlip_sf *sf, const char *path, const struct mlip_sf_kind *k, unsigned flags,
                 char *why, size_t why_len);

/* Write ours to path as described above. base: the file as loaded before
 * ours was made (its identity and records), for the merge; NULL: replace
 * whatever is there. Returns 0 written as ours, 1 written merged with a
 * change made meanwhile (note says which keys were kept from the file), -1
 * refused or failed (why; path unchanged). */
int mlip_sf_save(const char *path, const struct mlip_sf_kind *k, const struct mlip_sf *ours,
                 const struct mlip_sf *base, char *note, size_t note_len, char *why,
                 size_t why_len);

/* mlip_sf_save, told to the operator on err: a merge ("PATH: merged with a
 * change made during the RUN: KEYS kept as the file had it"), a file deleted
 * meanwhile ("written again"), a failure (why, then "the WHAT the RUN left,
 * not written:" and every record of ours). what: "offsets"; run: "program".
 * 0 written, -1 not. */
int mlip_sf_save_told(const char *path, const struct mlip_sf_kind *k, const struct mlip_sf *ours,
                      const struct mlip_sf *base, const char *what, const char *run,
                      const char *prog, FILE *err);

/* What a path is when it is not a regular file, for messages ("a
 * directory", "a FIFO (pipe)", ...): the tools' one wording (program.c too). */
const char *mlip_file_kind(unsigned mode);

#endif
