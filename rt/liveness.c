/*
 * liveness.c - the system side of the peers' liveness rule (mlip/ipc/peer.h):
 * the clock, and whether the peer's process is there, asked only when the
 * stamp alone does not decide. Not for the periodic loop (it may read /proc).
 */
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/types.h>

#include "rt.h"

int mlip_peer_process(uint32_t pid)
{
	char path[64], buf[256];
	const char *rp;
	size_t n;
	FILE *fp;

	/* EPERM: it exists, run by another user (a --shm-group peer) */
	if (pid == 0 || pid > (uint32_t)0x7fffffff ||
	    (kill((pid_t)pid, 0) != 0 && errno != EPERM)) {
		return 0;
	}
	snprintf(path, sizeof(path), "/proc/%u/stat", (unsigned)pid);
	fp = fopen(path, "r");
	if (fp == NULL) {
		return 1; /* no /proc: kill() said it exists */
	}
	n = fread(buf, 1, sizeof(buf) - 1, fp);
	fclose(fp);
	buf[n] = '\0';
	rp = strrchr(buf, ')'); /* "pid (comm) S ...": a zombie (Z) is gone */
	return !(rp != NULL && rp[1] == ' ' && rp[2] == 'Z');
}

mlip_peer_verdict mlip_peer_check(struct mlip_peer_seen *s, uint32_t pid, struct mlip_peer_watch *w,
                                  int64_t *quiet_ns)
{
	uint64_t now = mlip_now_ns();
	mlip_peer_verdict v;

	s->process = -1;
	v = mlip_peer_judge(s, w, now, quiet_ns);
	if (v == MLIP_PEER_LATE) {
		s->process = mlip_peer_process(pid);
		v = mlip_peer_judge(s, w, now, quiet_ns);
	}
	if (w != NULL) {
		mlip_peer_note(w, s, now);
	}
	return v;
}

mlip_peer_verdict mlip_peer_feeder(const struct mlip_ring_feeder *f)
{
	struct mlip_peer_seen s = {f->heartbeat, f->heartbeat_ns, f->pid == 0, -1}; /* 0: it left */

	return mlip_peer_check(&s, f->pid > 0 ? (uint32_t)f->pid : 0, NULL, NULL);
}
