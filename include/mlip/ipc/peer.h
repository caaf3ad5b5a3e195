/*
 * mlip/ipc/peer.h - is the process on the other side of the segment still there?
 * The one rule every side uses: the controller judging its feeder, mlip-feed
 * and mlip-ctl judging the controller, a new controller deciding whether it
 * may take a segment over.
 *
 * Pure: the caller passes what it read (the peer's beat counter and stamp),
 * what it knows of the peer's process, its own history of reads, and the
 * time; rt/ (mlip_peer_check) fills those from the clock, kill() and /proc.
 *
 *   alive  the peer beat within MLIP_PEER_TIMEOUT_NS (its stamp is that
 *          young, or its counter moved since our previous read);
 *   late   no beat for that long but its process is there (stopped, or
 *          starved of CPU), or not asked: it is not feeding or commanding,
 *          and when it runs again it goes on; report it once it has been
 *          quiet MLIP_PEER_LATE_NS while we watched;
 *   dead   no beat for that long and its process is gone, or it said
 *          goodbye (the feeder's pid 0).
 *
 * The history excuses our own pauses: a gap between two of our reads longer
 * than MLIP_PEER_TIMEOUT_NS / 2 (we were stopped or starved ourselves)
 * restarts the count of how long we have seen the peer quiet, so a pause
 * that stopped both processes, us first, is never blamed on the peer.
 */
#ifndef MLIP_PEER_H
#define MLIP_PEER_H

#include <stdint.h>

/* A peer without a beat this long is not alive (feeder <-> controller). */
#define MLIP_PEER_TIMEOUT_NS 100000000LL
/* A late peer (its process there, not beating) is reported after this. */
#define MLIP_PEER_LATE_NS    1000000000LL

typedef enum { MLIP_PEER_ALIVE = 0, MLIP_PEER_LATE, MLIP_PEER_DEAD } mlip_peer_verdict;

/* What the reader found of the peer this time. */
struct mlip_peer_seen {
	uint64_t beat;     /* its counter, +1 every beat */
	uint64_t stamp_ns; /* CLOCK_MONOTONIC of its last beat; 0: never beat */
	int left;          /* it said goodbye (the feeder area's pid 0) */
	int process;       /* its process: 1 there, 0 gone, -1 not asked */
};

/* The reader's own history of reads; zero it before the first. */
struct mlip_peer_watch {
	uint64_t beat;           /* the counter at our previous read */
	uint64_t read_ns;        /* our clock then; 0: no read yet */
	uint64_t quiet_since_ns; /* our clock when we began seeing it unmoved */
};

/* Age of a stamp at now_ns (0 for a stamp ahead); -1: never stamped (0). */
int64_t mlip_peer_age_ns(uint64_t stamp_ns, uint64_t now_ns);
/* The verdict at now_ns. w (may be NULL: judge on the stamp alone) is only
 * read; *quiet_ns (may be NULL) gets how long the peer has been without a
 * beat, counting only time we watched when w is given (-1: never beat, no
 * history). Same inputs, same answer: a caller may judge with process -1
 * first and ask the process only when the verdict is late. */
mlip_peer_verdict mlip_peer_judge(const struct mlip_peer_seen *s, const struct mlip_peer_watch *w,
                                  uint64_t now_ns, int64_t *quiet_ns);
/* Record this read in the history (after judging it). */
void mlip_peer_note(struct mlip_peer_watch *w, const struct mlip_peer_seen *s, uint64_t now_ns);
const char *mlip_peer_verdict_name(mlip_peer_verdict v);

#endif
