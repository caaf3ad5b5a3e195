/*
 * peer.c - the one liveness rule (mlip/ipc/peer.h): alive while it beats, late
 * while its process is there without beating, dead when the process is gone
 * too. Pure: the clock and the process come from the caller.
 */
#include <stddef.h>

#include "mlip/ipc/peer.h"

/* Our previous read is too far back to count the time in between as watched
 * (we were stopped or starved ourselves), or there is none. */
static int watch_broken(const struct mlip_peer_watch *w, uint64_t now_ns)
{
	return w->read_ns == 0 ||
	       (now_ns > w->read_ns && now_ns - w->read_ns > (uint64_t)MLIP_PEER_TIMEOUT_NS / 2);
}

int64_t mlip_peer_age_ns(uint64_t stamp_ns, uint64_t now_ns)
{
	if (stamp_ns == 0) {
		return -1;
	}
	return now_ns > stamp_ns ? (int64_t)(now_ns - stamp_ns) : 0;
}

mlip_peer_verdict mlip_peer_judge(const struct mlip_peer_seen *s, const struct mlip_peer_watch *w,
                                  uint64_t now_ns, int64_t *quiet_ns)
{
	int64_t age = mlip_peer_age_ns(s->stamp_ns, now_ns), quiet = age;
	int moved = w != NULL && w->read_ns != 0 && s->beat != w->beat;

	if (moved) {
		quiet = 0;
	} else if (w != NULL) {
		/* only what we saw: never blame the peer for our own pause */
		int64_t watched = watch_broken(w, now_ns) || now_ns < w->quiet_since_ns
		                      ? 0
		                      : (int64_t)(now_ns - w->quiet_since_ns);
		quiet = age >= 0 && age < watched ? age : watched;
	}
	if (quiet_ns != NULL) {
		*quiet_ns = quiet;
	}
	if (s->left) {
		return MLIP_PEER_DEAD;
	}
	if (moved || (age >= 0 && age < MLIP_PEER_TIMEOUT_NS)) {
		return MLIP_PEER_ALIVE;
	}
	return s->process == 0 ? MLIP_PEER_DEAD : MLIP_PEER_LATE;
}

void mlip_peer_note(struct mlip_peer_watch *w, const struct mlip_peer_seen *s, uint64_t now_ns)
{
	if (watch_broken(w, now_ns) || s->beat != w->beat) {
		w->quiet_since_ns = now_ns; /* moving, or we were away: watch anew */
	}
	w->beat = s->beat;
	w->read_ns = now_ns;
}

const char *mlip_peer_verdict_name(mlip_peer_verdict v)
{
	switch (v) {
	case MLIP_PEER_ALIVE:
		return "alive";
	case MLIP_PEER_LATE:
		return "late";
	case MLIP_PEER_DEAD:
		return "dead";
	}
	return "?";
}
