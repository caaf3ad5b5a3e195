/*
 * ctljog.c - mlip-ctl jog and home (ctltool.h): mailbox commands renewed
 * or followed until the controller is done.
 */
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "ctltool.h"
#include "mlip/ipc/ring.h"
#include "mlip/machine/config.h"
#include "rt.h"

static volatile sig_atomic_t jog_signal;

static void on_jog_signal(int sig)
{
	jog_signal = sig;
}

/* Post a command and wait for its result (1 s each): 0 with *result, or -1. */
static int post_wait(struct mlip_shm *s, mlip_ring_cmd_op op, int32_t arg, int32_t *result)
{
	uint32_t seq = 0;
	uint64_t t0 = mlip_now_ns();
	mlip_status rc;
	while ((rc = mlip_ring_cmd_post(s->ring, op, arg, &seq)) == MLIP_E_FULL &&
	       mlip_now_ns() - t0 < (uint64_t)WAIT_NS) {
		sleep_ns(POLL_NS);
	}
	if (rc != MLIP_OK) {
		return -1;
	}
	t0 = mlip_now_ns();
	while ((rc = mlip_ring_cmd_result(s->ring, seq, result)) != MLIP_OK) {
		if (rc == MLIP_E_RANGE || mlip_now_ns() - t0 >= (uint64_t)WAIT_NS) {
			return -1;
		}
		sleep_ns(POLL_NS);
	}
	return 0;
}

/* jog X+|X- SPEED [SECONDS]: a continuous jog at SPEED mm/min (deg/min),
 * renewed every 100 ms (the controller stops one not renewed within
 * MLIP_JOG_DEADMAN_S) until SECONDS pass, a signal comes (SIGINT, SIGTERM,
 * SIGHUP: a dropped ssh session), or the axis reaches its soft limit; then
 * released: a stop on the path at the acceleration limit. */
/* One axis of a jog: "X+", "z-", "X+1.5" (a distance: incremental). */
struct jog_axis {
	int axis, neg;
	double dist; /* 0: continuous */
};

static int jog_axis_word(const struct mlip_machine *m, const char *w, struct jog_axis *j)
{
	size_t n = strlen(w);
	j->axis = -1;
	for (int k = 0; k < m->n_axes && n >= 2; k++) {
		if (w[0] == m->axis[k].letter || w[0] == m->axis[k].letter + ('a' - 'A')) {
			j->axis = k;
		}
	}
	if (j->axis < 0 || (w[1] != '+' && w[1] != '-')) {
		return -1;
	}
	j->neg = w[1] == '-';
	j->dist = 0.0;
	if (n > 2 && (mlip_cli_number(w + 2, &j->dist) != 0 || !(j->dist > 0.0) || w[2] == '+' ||
	              w[2] == '-')) {
		return -1;
	}
	return 0;
}

/* jog AXIS+|AXIS-[DIST]... [--distance D] SPEED [SECONDS]: one axis or
 * several along one line, continuous (until SECONDS, a signal, or the soft
 * limit) or incremental (each a distance), renewed every 100 ms (the
 * controller's dead-man stops it 250 ms after the last renewal). */
int cmd_jog(struct mlip_shm *s, int argc, char **argv)
{
	struct mlip_machine m;
	struct mlip_ring_status st;
	struct jog_axis ax[MLIP_MAX_AXES];
	double v = 0.0, dur = -1.0, dist = 0.0;
	const char *speed = NULL, *secs = NULL;
	char words[128] = "";
	int n = 0, with = 0;
	int32_t result;

	mlip_ring_machine(s->ring, &m);
	for (int i = 0; i < argc; i++) {
		const char *w = argv[i];
		if (strcmp(w, "--distance") == 0 || strncmp(w, "--distance=", 11) == 0) {
			const char *d = w[10] == '=' ? w + 11 : i + 1 < argc ? argv[++i] : "";
			if (mlip_cli_number(d, &dist) != 0 || !(dist > 0.0)) {
				fprintf(stderr,
				        PROG
				        ": jog: --distance must be a positive number, got '%s'\n",
				        d);
				return EXIT_USAGE;
			}
		} else if (speed == NULL && n < MLIP_MAX_AXES &&
		           jog_axis_word(&m, w, &ax[n]) == 0) {
			for (int k = 0; k < n; k++) {
				if (ax[k].axis == ax[n].axis) {
					fprintf(stderr, PROG ": jog: axis %c given twice\n", w[0]);
					return EXIT_USAGE;
				}
			}
			snprintf(words + strlen(words), sizeof(words) - strlen(words), "%s%s",
			         n ? " " : "", w);
			n++;
		} else if (n > 0 && speed == NULL) {
			speed = w;
		} else if (n > 0 && secs == NULL) {
			secs = w;
		} else {
			fprintf(stderr,
			        PROG
			        ": jog: '%s' is not an axis of this machine and a direction, with "
			        "a distance or not (e.g. X+, Z-, X+1.5)\n",
			        w);
			return EXIT_USAGE;
		}
	}
	if (n == 0) {
		fprintf(stderr, PROG ": jog: expected AXIS+|AXIS-[DIST]... [--distance D] SPEED "
		                     "[SECONDS]\n");
		return EXIT_USAGE;
	}
	for (int k = 0; k < n; k++) {
		ax[k].dist = ax[k].dist > 0.0 ? ax[k].dist : dist;
		with += ax[k].dist > 0.0;
		if (ax[k].dist > 0.0 && !(ax[k].dist * 1e3 + 0.5 <= (double)MLIP_JOG_DIST_MAX &&
		                          ax[k].dist * 1e3 >= 0.5)) {
			fprintf(stderr, PROG ": jog: a distance is 0.001 .. %.6g (mm or deg)\n",
			        MLIP_JOG_DIST_MAX * 1e-3);
			return EXIT_USAGE;
		}
	}
	if (with != 0 && with != n) {
		fprintf(stderr,
		        PROG ": jog: every axis a distance (incremental) or none (continuous)\n");
		return EXIT_USAGE;
	}
	if (speed == NULL || mlip_cli_number(speed, &v) != 0 || !(v >= 1.0) ||
	    v > (double)MLIP_JOG_SPEED_MAX) {
		fprintf(stderr,
		        PROG ": jog: the speed must be a number of mm/min (deg/min) in 1..%u, "
		             "got '%s'\n",
		        MLIP_JOG_SPEED_MAX, speed != NULL ? speed : "");
		return EXIT_USAGE;
	}
	if (secs != NULL && (mlip_cli_number(secs, &dur) != 0 || !(dur > 0.0) || dur > 86400.0)) {
		fprintf(stderr, PROG ": jog: SECONDS must be in (0, 86400], got '%s'\n", secs);
		return EXIT_USAGE;
	}
	const char *dir = words;
	int axis = ax[0].axis, neg = ax[0].neg;
	int32_t arg = MLIP_JOG_ARG(axis, neg, (uint32_t)(v + 0.5)),
	        stop = MLIP_JOG_ARG(axis, neg, 0);
	mlip_cli_on_stop_signals(on_jog_signal);
	/* the other axes (and the distances) first, then the jog itself; a jog
	 * away from a limit switch waits (REST_WAIT_S) while the axes still
	 * brake on their drives' quick stop ramps */
	uint64_t t_rest = mlip_now_ns();
	int bad, told = 0;
again:
	bad = 0;
	for (int k = n - 1; k >= 0 && !bad; k--) {
		if (k == 0 && ax[0].dist == 0.0) {
			break;
		}
		int32_t a =
		    MLIP_JOG_AXIS_ARG(ax[k].axis, ax[k].neg, (uint32_t)(ax[k].dist * 1e3 + 0.5));
		bad = post_wait(s, MLIP_CMD_JOG_AXIS, a, &result) != 0 ? -1 : result != MLIP_OK;
	}
	if (bad < 0 || (!bad && post_wait(s, MLIP_CMD_JOG, arg, &result) != 0)) {
		fprintf(stderr, PROG ": jog: no answer from the controller on %s within 1 s\n",
		        s->name);
		return EXIT_FAIL;
	}
	if (!bad && result == MLIP_E_FULL &&
	    mlip_now_ns() - t_rest < REST_WAIT_S * (uint64_t)WAIT_NS) {
		if (!told) {
			fprintf(stderr, "jog %s: waiting for the axes to stand still\n", dir);
			told = 1;
		}
		sleep_ns(20 * POLL_NS);
		goto again;
	}
	if (bad || result != MLIP_OK) {
		read_status(s->ring, &st);
		if (!bad && result == MLIP_E_RANGE) {
			/* the axis that leaves the travel */
			int k0 = 0;
			double t = st.pos[ax[0].axis];
			for (int k = 0; k < n; k++) {
				const struct mlip_axis *a = &m.axis[ax[k].axis];
				double p = st.pos[ax[k].axis];
				double tk = p + (ax[k].neg ? -ax[k].dist : ax[k].dist);
				if (ax[k].neg ? tk <= a->min_limit : tk >= a->max_limit) {
					k0 = k;
					t = tk;
					break;
				}
			}
			const struct mlip_axis *a = &m.axis[ax[k0].axis];
			fprintf(stderr,
			        PROG
			        ": jog %s: refused: %c is at %.4f%s, %s its soft limit %s %g (Grbl "
			        "error 15: jog target exceeds machine travel)\n",
			        dir, a->letter, st.pos[ax[k0].axis], with ? ", its target" : "",
			        with ? "beyond" : "at or beyond",
			        ax[k0].neg ? "MIN_LIMIT" : "MAX_LIMIT",
			        ax[k0].neg ? a->min_limit : a->max_limit);
			if (with) {
				fprintf(stderr,
				        PROG ": jog %s: the target %c %.4f; nothing moved\n", dir,
				        a->letter, t);
			}
		} else if (!bad && result == MLIP_E_FULL) {
			fprintf(
			    stderr,
			    PROG
			    ": jog %s: refused: the axes are still braking on their drives' quick "
			    "stop ramps after the limit switch (leaving the quick stop disables "
			    "the drives): jog again once they stand still\n",
			    dir);
		} else if (!bad && result == MLIP_E_SYNTAX) {
			fprintf(stderr,
			        PROG
			        ": jog %s: refused: the controller got other axes for this jog "
			        "(another client jogging at the same moment?): try again\n",
			        dir);
		} else if (st.state == MLIP_STATE_IDLE &&
		           mlip_state_hold_latched(st.state, st.held_by)) {
			fprintf(stderr,
			        PROG
			        ": jog %s: refused: the controller is idle with a hold latched "
			        "(%s; Grbl's Hold:0): mlip-ctl resume releases it, moving "
			        "nothing\n",
			        dir, mlip_state_why_name(st.held_by));
		} else {
			fprintf(stderr,
			        PROG ": jog %s: refused: the controller is %s (%s), not idle\n",
			        dir, mlip_ctl_state_name(st.state), mlip_state_why_name(st.reason));
		}
		return EXIT_FAIL;
	}
	printf("jog %s at %.0f mm/min: started (renewed every 100 ms; Ctrl-C stops it)\n", dir, v);
	fflush(stdout);
	uint64_t t0 = mlip_now_ns();
	int rc = EXIT_DONE;
	for (;;) {
		sleep_ns(100000000L);
		if (jog_signal || (dur > 0.0 && (double)(mlip_now_ns() - t0) * 1e-9 >= dur)) {
			break;
		}
		if (read_status(s->ring, &st) != 0 || st.state != MLIP_STATE_JOGGING) {
			break; /* it ended (its target, a soft limit, a stop, an E-stop, a fault) */
		}
		if (post_wait(s, MLIP_CMD_JOG, arg, &result) != 0 || result != MLIP_OK) {
			break;
		}
	}
	post_wait(s, MLIP_CMD_JOG, stop, &result); /* released: a stop at the acceleration limit */
	uint64_t t1 = mlip_now_ns();
	while (read_status(s->ring, &st) == 0 && st.state == MLIP_STATE_JOGGING &&
	       mlip_now_ns() - t1 < 10ull * (uint64_t)WAIT_NS) {
		sleep_ns(5 * POLL_NS);
	}
	if (st.state == MLIP_STATE_IDLE) {
		printf("jog %s: at rest at", dir);
		for (int k = 0; k < n; k++) {
			printf(" %c %.4f", m.axis[ax[k].axis].letter, st.pos[ax[k].axis]);
		}
		printf(" (%s%s", mlip_state_why_name(st.reason), jog_signal ? ", on " : "");
		if (jog_signal) {
			printf("%s", mlip_cli_signal_name(jog_signal));
		}
		if (st.reason == MLIP_WHY_JOG_RELEASED || st.reason == MLIP_WHY_JOG_DEADMAN) {
			printf("; %.3f mm from the release to rest", (double)st.stop_nm * 1e-6);
		}
		printf(")\n");
	} else {
		fprintf(stderr, PROG ": jog %s: ended %s (%s)\n", dir,
		        mlip_ctl_state_name(st.state), mlip_state_why_name(st.reason));
		rc = EXIT_FAIL;
	}
	return rc;
}

/* home [AXES]: the axes (letters, e.g. XZ; none: every axis with a
 * HOME_METHOD) homed by their drives' homing mode, in HOME_SEQUENCE order;
 * waits for the end and says how it went. */
int cmd_home(struct mlip_shm *s, const char *axes)
{
	struct mlip_machine m;
	struct mlip_ring_status st;
	uint32_t mask = 0;
	int32_t result;
	char fname[32];

	mlip_ring_machine(s->ring, &m);
	for (const char *p = axes; p != NULL && *p; p++) {
		int k = -1;
		for (int i = 0; i < m.n_axes; i++) {
			if (m.axis[i].letter == *p || m.axis[i].letter + ('a' - 'A') == *p) {
				k = i;
			}
		}
		if (k < 0) {
			fprintf(stderr, PROG ": home: '%c' is not an axis of this machine\n", *p);
			return EXIT_USAGE;
		}
		mask |= 1u << k;
	}
	if (post_wait(s, MLIP_CMD_HOME, (int32_t)mask, &result) != 0) {
		fprintf(stderr, PROG ": home: no answer from the controller on %s within 1 s\n",
		        s->name);
		return EXIT_FAIL;
	}
	read_status(s->ring, &st);
	if (result == MLIP_E_RANGE) {
		fprintf(stderr,
		        PROG ": home: refused: an axis without HOME_METHOD in the machine's "
		             "configuration (or no CiA 402 drives)\n");
		return EXIT_FAIL;
	}
	if (result != MLIP_OK && st.state == MLIP_STATE_IDLE &&
	    mlip_state_hold_latched(st.state, st.held_by)) {
		fprintf(stderr,
		        PROG ": home: refused: the controller is idle with a hold latched (%s; "
		             "Grbl's Hold:0): mlip-ctl resume releases it, moving nothing (or "
		             "mlip-ctl stop), then home\n",
		        mlip_state_why_name(st.held_by));
		return EXIT_FAIL;
	}
	if (result != MLIP_OK && st.state == MLIP_STATE_IDLE) {
		fprintf(stderr,
		        PROG ": home: refused: the controller is idle with a program waiting in "
		             "the ring (mlip-ctl stop drops it)\n");
		return EXIT_FAIL;
	}
	if (result != MLIP_OK) {
		fprintf(stderr, PROG ": home: refused: the controller is %s (%s), not idle\n",
		        mlip_ctl_state_name(st.state), mlip_state_why_name(st.reason));
		return EXIT_FAIL;
	}
	/* the command's result comes before the status of its period: wait for
	 * a later one, then for the end (a controller late for a while, as in an
	 * emulated machine, is waited for; one gone for 5 s is not) */
	uint64_t t0 = mlip_now_ns(), hb0 = st.heartbeat, quiet = 0;
	while (read_status(s->ring, &st) == 0 && st.heartbeat <= hb0 + 1 &&
	       mlip_now_ns() - t0 < 2ull * (uint64_t)WAIT_NS) {
		sleep_ns(5 * POLL_NS);
	}
	while (read_status(s->ring, &st) == 0 && st.state == MLIP_STATE_HOMING) {
		if (mlip_shm_controller_alive(s->ring)) {
			quiet = 0;
		} else if (quiet == 0) {
			quiet = mlip_now_ns();
		} else if (mlip_now_ns() - quiet > 5ull * (uint64_t)WAIT_NS) {
			fprintf(stderr,
			        PROG ": home: the controller stopped answering while homing\n");
			return EXIT_FAIL;
		}
		sleep_ns(20 * POLL_NS);
	}
	double secs = (double)(mlip_now_ns() - t0) * 1e-9;
	if (st.state == MLIP_STATE_IDLE && st.reason == MLIP_WHY_HOMED) {
		printf("homed in %.2f s:", secs);
		for (int k = 0; k < m.n_axes; k++) {
			if (st.homed & (1u << k)) {
				printf(" %c %.4f", m.axis[k].letter, st.pos[k]);
			}
		}
		printf("\n");
		return EXIT_DONE;
	}
	if (st.reason == MLIP_WHY_HOMING_SDO) {
		fprintf(stderr,
		        PROG
		        ": home: node %u refused 0x%04X:%02X: %s (0x%08X): every axis stopped; "
		        "mlip-ctl reset, then check HOME_* of that axis\n",
		        (unsigned)st.reason_node, st.reason_field >> 8, st.reason_field & 0xFFu,
		        mlip_sdo_abort_text((uint32_t)st.reason_value), (uint32_t)st.reason_value);
	} else if (st.reason == MLIP_WHY_HOMING_ERROR || st.reason == MLIP_WHY_HOMING_TIMEOUT) {
		fprintf(stderr,
		        PROG
		        ": home: node %u, method %u: %s (statusword 0x%04X) after %.2f s: every "
		        "axis stopped; mlip-ctl reset\n",
		        (unsigned)st.reason_node, st.reason_field,
		        st.reason == MLIP_WHY_HOMING_ERROR ? "homing error (statusword bit 13)"
		                                           : "not attained within HOME_TIMEOUT",
		        (unsigned)st.reason_value, secs);
	} else {
		fprintf(stderr, PROG ": home: ended %s (%s)%s\n", mlip_ctl_state_name(st.state),
		        mlip_state_why_name(st.reason),
		        st.reason == MLIP_WHY_ESTOP
		            ? mlip_io_function_name(st.reason_field, &m, fname, sizeof(fname))
		            : "");
	}
	return EXIT_FAIL;
}
