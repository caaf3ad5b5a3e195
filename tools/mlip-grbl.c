/*
 * mlip-grbl - a Grbl 1.1 front-end for a running mlip-rt: G-code senders
 * (CNCjs, bCNC, UGS, gSender, ...) drive mlip over TCP or a pseudo-terminal
 * as they drive a Grbl board. The protocol is tools/lib/grbl.h (pure); the
 * lines become the ring's records as mlip-feed makes them
 * (tools/lib/grblstream.h); the server's parts share one state
 * (tools/lib/grblsrv.h: grblproto.c the protocol and flow control,
 * grblreport.c the status, grblsetting.c the `$` lines, grblfeed.c the
 * streaming); this file owns the sockets, the pseudo-terminal, the
 * segment's producer lock (rt/) and the loop.
 *
 * One loop, never blocking: poll the sockets (1 ms while anything is under
 * way), take real-time bytes at once (commands posted to the mailbox in the
 * same pass: the controller applies them in its next period; `?` answered
 * from the status of the last period), then the lines in order: each checked
 * whole by the G-code reader, its records staged and pushed to the ring, and
 * `ok` sent as soon as they are queued, so a character-counting sender keeps
 * the controller's look-ahead full. A line the reader refuses is answered
 * "[MSG:line N col C: ...]" and error:N, and nothing after it is taken until
 * the sender resumes (~) or resets (ctrl-x): the machine stops at rest at the
 * end of the last good line.
 *
 * A program, for the controller, is what runs between two END records. The
 * stream is cut into programs where it must be: at M2/M30, at a refused line,
 * and when the sender has gone quiet (no line for --quiet-ms) while the
 * controller waits for more (pre-reading, or starved at rest): then the
 * smoothing filter is finished and END sent, so a single MDI line runs at
 * once. A sender streaming a file never goes quiet while the controller
 * runs, so the file runs as one program, as mlip-feed would run it.
 *
 * One controlling client: the first to connect (TCP) or to open the
 * pseudo-terminal. Another gets a clear refusal and is closed. The
 * controlling client's disconnect finishes what was acknowledged (the
 * machine stops at rest after it, as after a lost feeder) and cancels a jog.
 */
#define _XOPEN_SOURCE 700 /* posix_openpt, grantpt, unlockpt, ptsname */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <math.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"
#include "confload.h"
#include "grbl.h"
#include "grblmach.h"
#include "grblsrv.h"
#include "grblstream.h"
#include "mlip/ctl/state.h"
#include "mlip/ipc/ring.h"
#include "mlip/machine/config.h"
#include "offsetfile.h"
#include "rt.h"
#include "tooltable.h"

#define DEFAULT_QUIET 100 /* ms */
#define DEFAULT_PORT  "2323"

static volatile sig_atomic_t got_signal;
static void on_signal(int sig)
{
	got_signal = sig;
}
static struct mlip_shm seg;           /* the controller's segment */
static struct mlip_smooth smooth_mem; /* ~1 MB: the smoothing filter's window */

/* ---- --offsets FILE: what Grbl keeps in its EEPROM ------------------------------ */

/* The systems G54..G59.3, the G28/G30 positions and the tool in the spindle
 * (M6, M61): what a restart of mlip-grbl keeps. SELECT and G92 are not
 * (Grbl starts in G54 without G92): the file's stay as they are. */
static struct {
	const char *path;
	struct mlip_offsets_file file;  /* as last read: the write-back's merge base */
	struct mlip_gcode_offsets kept; /* the file's values, ours written over them */
} offs;

static int offsets_same(const struct mlip_gcode_offsets *a, const struct mlip_gcode_offsets *b)
{
	return memcmp(a->coord, b->coord, sizeof(a->coord)) == 0 &&
	       memcmp(a->g28, b->g28, sizeof(a->g28)) == 0 &&
	       memcmp(a->g30, b->g30, sizeof(a->g30)) == 0 && a->tool == b->tool;
}

static void offsets_take(struct mlip_gcode_offsets *to, const struct mlip_gcode_offsets *from)
{
	memcpy(to->coord, from->coord, sizeof(to->coord));
	memcpy(to->g28, from->g28, sizeof(to->g28));
	memcpy(to->g30, from->g30, sizeof(to->g30));
	to->tool = from->tool;
}

static int offsets_read(void)
{
	mlip_offsets_file_free(&offs.file);
	return mlip_offsets_load(&offs.file, offs.path, &S.m, &offs.kept, PROG, stderr);
}

/* At rest, nothing of a program open: what the lines taken changed, written
 * back (merged with a change made to the file meanwhile, as mlip-feed
 * does); a refused write is said once per change. */
static void offsets_keep(void)
{
	if (offs.path == NULL || S.st.open || !quiet_controller() ||
	    offsets_same(&S.st.g.off, &offs.kept)) {
		return;
	}
	struct mlip_gcode_offsets o = offs.kept;
	offsets_take(&o, &S.st.g.off);
	if (mlip_offsets_save(&offs.file, &S.m, &o, PROG, stderr) != 0 || offsets_read() != 0) {
		if (S.ctl) {
			send_msg(S.ctl, "--offsets %s: not written (mlip-grbl's log says why)",
			         offs.path);
		}
		offsets_take(&offs.kept, &S.st.g.off); /* not tried again until the next change */
	}
}

/* ---- the ring's producer side ------------------------------------------------ */

static void producer_unlock(void)
{
	struct flock fl;
	memset(&fl, 0, sizeof(fl));
	fl.l_type = F_UNLCK;
	fl.l_whence = SEEK_SET;
	fl.l_start = (off_t)offsetof(struct mlip_ring, head);
	fl.l_len = MLIP_RING_LINE;
	(void)fcntl(seg.fd, F_SETLK, &fl);
	S.locked = 0;
	S.port_open = 0;
}

/* Take the producer side for a line that moves: 0, or a refusal said. */
static int take_producer(void)
{
	int32_t holder = 0;
	struct mlip_ring_feeder other;
	if (S.locked) {
		return 0;
	}
	if (mlip_shm_feeder_lock(&seg, &holder) != 0) {
		send_msg(S.ctl,
		         "another feeder (pid %d) is feeding %s: wait for it to finish, or stop "
		         "it (mlip-ctl stop)",
		         (int)holder, S.shm_name);
		return -1;
	}
	if (mlip_ring_feeder_read(S.r, &other) == MLIP_OK && other.pid != 0 &&
	    other.pid != (int32_t)getpid() && mlip_peer_feeder(&other) == MLIP_PEER_ALIVE) {
		send_msg(S.ctl, "another feeder (pid %d) is feeding %s", (int)other.pid,
		         S.shm_name);
		producer_unlock();
		return -1;
	}
	if (mlip_ring_port_open(&S.tx, S.r, 1) != MLIP_OK) {
		send_msg(S.ctl, "%s: the ring's header is not valid: restart mlip-rt", S.shm_name);
		producer_unlock();
		return -1;
	}
	S.locked = 1;
	S.port_open = 1;
	S.fa.pid = (int32_t)getpid();
	S.fa.total_blocks = 0;
	S.fa.program_end = 0;
	beat();
	return 0;
}

/* ---- connections -------------------------------------------------------------- */

static void peer_close(struct peer *p)
{
	for (int i = 0; i < MAX_PEERS; i++) {
		if (S.peers[i] == p) {
			S.peers[i] = NULL;
		}
	}
	if (!p->pty) {
		close(p->fd);
	}
	free(p);
}

/* The controlling client left: what it was told is queued runs to its end
 * (the machine stops at rest after it, as after a lost feeder); the rest of
 * what it sent is dropped. */
static void lose_controller(const char *why)
{
	if (S.jog) {
		/* a jog is the operator's hand on the machine: it stops with them */
		logf_("%s %s mid-jog: the jog is cancelled (a stop on its path)", S.ctl->name, why);
		jog_cancel("the sender left");
		grbl_rx_reset(&S.rx);
		S.check_mode = 0;
		S.err_hold = 0;
		S.hold_idle = 0;
		struct peer *p = S.ctl;
		S.ctl = NULL;
		if (!p->pty) {
			peer_close(p);
		}
		return;
	}
	if (S.st.open || S.program_live || S.partial) {
		logf_("%s %s mid-program (line %u): the machine runs what was acknowledged to its "
		      "end and stops at rest there; lines not acknowledged are dropped",
		      S.ctl->name, why, (unsigned)S.lineno);
	} else {
		logf_("%s %s (line %u)", S.ctl->name, why, (unsigned)S.lineno);
	}
	if (S.partial) {
		/* its line was not acknowledged: none of it runs */
		grbl_stream_restart(&S.st, grbl_stream_pos(&S.st), 1);
		S.partial = 0;
	}
	if (S.st.open) {
		grbl_stream_end(&S.st);
	}
	grbl_rx_reset(&S.rx);
	S.check_mode = 0;
	S.err_hold = 0;
	S.hold_idle = 0;
	if (S.ctl->pty) {
		S.ctl = NULL; /* the pseudo-terminal stays ours */
		return;
	}
	struct peer *p = S.ctl;
	S.ctl = NULL;
	peer_close(p);
}

static void take_control(struct peer *p)
{
	S.ctl = p;
	S.last_rx_ns = now_ns();
	logf_("%s is the controlling sender", p->name);
	/* a new sender finds Grbl as after a reset: the parser's defaults, from
	 * where the machine stands (or will, once what was queued has run) */
	if (grbl_stream_staged(&S.st) == 0 && !S.st.end_pending && !S.st.open) {
		if (quiet_controller() && !S.program_live) {
			resync(0);
		} else {
			/* what is queued still runs: its spindle and coolant too */
			double at[MLIP_MAX_AXES];
			const struct mlip_gcode *g = &S.st.g;
			double rpm = g->spindle == 3 ? g->s_rpm : g->spindle == 4 ? -g->s_rpm : 0.0;
			unsigned cool = g->coolant;
			memcpy(at, grbl_stream_pos(&S.st), sizeof(at));
			grbl_stream_restart(&S.st, at, 0);
			grbl_stream_machine_io(&S.st, rpm, cool);
		}
	}
	welcome();
}

static void refuse(int fd, const char *who)
{
	char b[256];
	int n = snprintf(b, sizeof(b),
	                 "\r\n[MSG:mlip-grbl: %s already controls this machine: one sender at a "
	                 "time; this connection is closed]\r\n",
	                 who);
	if (n > 0) {
		(void)!write(fd, b, (size_t)n);
	}
}

static void accept_peer(void)
{
	struct sockaddr_storage sa;
	socklen_t sl = sizeof(sa);
	int fd = accept(S.listen_fd, (struct sockaddr *)&sa, &sl);
	if (fd < 0) {
		return;
	}
	char host[64] = "?", serv[16] = "?";
	getnameinfo((struct sockaddr *)&sa, sl, host, sizeof(host), serv, sizeof(serv),
	            NI_NUMERICHOST | NI_NUMERICSERV);
	if (S.ctl != NULL) {
		refuse(fd, S.ctl->name);
		logf_("refused %s:%s: %s controls the machine", host, serv, S.ctl->name);
		close(fd);
		return;
	}
	int slot = -1;
	for (int i = 0; i < MAX_PEERS; i++) {
		if (S.peers[i] == NULL) {
			slot = i;
			break;
		}
	}
	struct peer *p = slot >= 0 ? calloc(1, sizeof(*p)) : NULL;
	if (p == NULL) {
		close(fd);
		return;
	}
	int one = 1;
	setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
	fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK);
	p->fd = fd;
	snprintf(p->name, sizeof(p->name), "%s:%s", host, serv);
	S.peers[slot] = p;
	take_control(p);
}

static void read_peer(struct peer *p)
{
	unsigned char b[4096];
	for (;;) {
		ssize_t n = read(p->fd, b, sizeof(b));
		if (n > 0) {
			if (p != S.ctl) {
				continue; /* not in control: nothing it says is taken */
			}
			for (ssize_t i = 0; i < n; i++) {
				if (grbl_rt_of(b[i]) == GRBL_RT_NONE) {
					S.last_rx_ns =
					    now_ns(); /* a line byte: the sender is not quiet */
					break;
				}
			}
			grbl_rx_feed(&S.rx, b, (size_t)n, rt_cmd, NULL);
			if ((size_t)n < sizeof(b)) {
				return;
			}
			continue;
		}
		if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
			return;
		}
		/* closed (or EIO: the pseudo-terminal's other side closed); a
		 * socket's peer is freed here (lose_controller, peer_close):
		 * nothing of it is read after */
		int pty = p->pty;
		if (p == S.ctl) {
			lose_controller("disconnected");
		} else if (!pty) {
			peer_close(p);
		}
		if (pty) {
			S.pty_open = 0;
		}
		return;
	}
}

/* ---- the pseudo-terminal ---------------------------------------------------------- */

static int pty_setup(const char *link)
{
	int fd = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK);
	if (fd < 0 || grantpt(fd) != 0 || unlockpt(fd) != 0) {
		logf_("pseudo-terminal: %s", strerror(errno));
		return -1;
	}
	const char *name = ptsname(fd);
	if (name == NULL) {
		return -1;
	}
	snprintf(S.pty_name, sizeof(S.pty_name), "%s", name);
	/* raw: no echo, no line editing, no signals from ^C/^X, 8 bits clean */
	int sfd = open(name, O_RDWR | O_NOCTTY);
	if (sfd >= 0) {
		struct termios t;
		if (tcgetattr(sfd, &t) == 0) {
			cfmakeraw(&t);
			cfsetispeed(&t, B115200);
			cfsetospeed(&t, B115200);
			tcsetattr(sfd, TCSANOW, &t);
		}
		close(sfd); /* from now on the master sees POLLHUP until a sender opens it */
	}
	/* the stable path: a symlink made beside it and renamed over the old one */
	char tmp[300];
	snprintf(tmp, sizeof(tmp), "%s.%d.tmp", link, (int)getpid());
	unlink(tmp);
	if (symlink(name, tmp) != 0 || rename(tmp, link) != 0) {
		logf_("pseudo-terminal: cannot make %s -> %s: %s", link, name, strerror(errno));
		unlink(tmp);
		close(fd);
		return -1;
	}
	snprintf(S.pty_link, sizeof(S.pty_link), "%s", link);
	S.pty_fd = fd;
	struct peer *p = calloc(1, sizeof(*p));
	if (p == NULL) {
		return -1;
	}
	p->fd = fd;
	p->pty = 1;
	snprintf(p->name, sizeof(p->name), "pseudo-terminal %.60s", link);
	S.peers[MAX_PEERS - 1] = p;
	return 0;
}

/* A sender opened (or closed) the pseudo-terminal's other side. */
static void pty_check(void)
{
	struct peer *p = S.peers[MAX_PEERS - 1];
	if (S.pty_fd < 0 || p == NULL) {
		return;
	}
	struct pollfd pf = {S.pty_fd, POLLIN, 0};
	if (poll(&pf, 1, 0) < 0) {
		return;
	}
	int open_now = !(pf.revents & POLLHUP);
	if (open_now && !S.pty_open) {
		S.pty_open = 1;
		if (S.ctl == NULL) {
			take_control(p);
		} else {
			char b[256];
			snprintf(
			    b, sizeof(b),
			    "\r\n[MSG:mlip-grbl: %s already controls this machine: one sender at a "
			    "time]\r\n",
			    S.ctl->name);
			(void)!write(S.pty_fd, b, strlen(b));
		}
	} else if (!open_now && S.pty_open) {
		S.pty_open = 0;
		if (S.ctl == p) {
			lose_controller("closed the pseudo-terminal");
		}
		p->tx_len = 0;
	}
}

/* ---- setup -------------------------------------------------------------------------- */

static int listen_on(const char *spec)
{
	char host[128] = "127.0.0.1", port[16] = DEFAULT_PORT;
	const char *colon = strrchr(spec, ':');
	if (colon == NULL) {
		snprintf(port, sizeof(port), "%s", spec);
	} else {
		size_t hl = (size_t)(colon - spec);
		if (hl > 0) {
			if (spec[0] == '[' && hl >= 2 && spec[hl - 1] == ']') {
				snprintf(host, sizeof(host), "%.*s", (int)(hl - 2), spec + 1);
			} else {
				snprintf(host, sizeof(host), "%.*s", (int)hl, spec);
			}
		}
		snprintf(port, sizeof(port), "%s", colon + 1);
	}
	struct addrinfo hints, *ai = NULL;
	memset(&hints, 0, sizeof(hints));
	hints.ai_socktype = SOCK_STREAM;
	hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
	int rc = getaddrinfo(host, port, &hints, &ai);
	if (rc != 0) {
		logf_("--listen %s: %s", spec, gai_strerror(rc));
		return -1;
	}
	int fd = socket(ai->ai_family, ai->ai_socktype | SOCK_CLOEXEC, 0);
	int one = 1;
	if (fd >= 0) {
		setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
	}
	if (fd < 0 || bind(fd, ai->ai_addr, ai->ai_addrlen) != 0 || listen(fd, 4) != 0) {
		logf_("--listen %s: %s", spec, strerror(errno));
		freeaddrinfo(ai);
		if (fd >= 0) {
			close(fd);
		}
		return -1;
	}
	freeaddrinfo(ai);
	fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK);
	S.listen_fd = fd;
	struct sockaddr_storage sa;
	socklen_t sl = sizeof(sa);
	char h[64] = "?", sv[16] = "?";
	if (getsockname(fd, (struct sockaddr *)&sa, &sl) == 0) {
		getnameinfo((struct sockaddr *)&sa, sl, h, sizeof(h), sv, sizeof(sv),
		            NI_NUMERICHOST | NI_NUMERICSERV);
	}
	logf_("listening on %s:%s", h, sv); /* the port bound (port 0: the kernel's choice) */
	return 0;
}

static void usage(FILE *f)
{
	fprintf(
	    f,
	    "usage: " PROG " [options]\n"
	    "Speak Grbl 1.1 to G-code senders (CNCjs, bCNC, UGS, gSender) for a running\n"
	    "mlip-rt: status, overrides, hold/resume/reset, and programs streamed line by line,\n"
	    "each line checked as mlip-feed checks a file.\n\n"
	    "  --shm NAME          controller's shared-memory segment (default " MLIP_SHM_DEFAULT
	    ")\n"
	    "  --listen [ADDR:]PORT  TCP address (default 127.0.0.1:" DEFAULT_PORT
	    "; another address\n"
	    "                      only when given, e.g. 0.0.0.0:2323)\n"
	    "  --pty PATH          also a pseudo-terminal for serial-only senders, linked at\n"
	    "                      PATH (default /tmp/mlip-grbl-NAME.tty; 'none': no terminal)\n"
	    "  --quiet-ms N        a sender quiet this long while the controller waits ends\n"
	    "                      the program there, so it runs (default %d)\n"
	    "  --default-feed F    feed (units/min) for feed moves before any F\n"
	    "  --config FILE       the machine's INI (the one mlip-rt runs): $22..$25 from\n"
	    "                      its homing (HOME_METHOD, HOME_*_VEL of each axis)\n"
	    "  --tools FILE        the tool table (as mlip-feed --tools): T, M6, M61, G43\n"
	    "  --offsets FILE      the offsets file (mlip-offsets): G54..G59.3, G28/G30 and\n"
	    "                      the tool in the spindle read at the start, written back\n"
	    "                      at rest when a line changed them (SELECT, G92: Grbl's\n"
	    "                      defaults at each start, the file's kept)\n"
	    "  -v, --verbose       log each connection's lines to stderr\n"
	    "  -h, --help          this help\n",
	    DEFAULT_QUIET);
}

int main(int argc, char **argv)
{
	static const struct option opts[] = {{"shm", required_argument, 0, 's'},
	                                     {"listen", required_argument, 0, 'l'},
	                                     {"pty", required_argument, 0, 'p'},
	                                     {"quiet-ms", required_argument, 0, 'Q'},
	                                     {"default-feed", required_argument, 0, 'D'},
	                                     {"config", required_argument, 0, 'C'},
	                                     {"tools", required_argument, 0, 'T'},
	                                     {"offsets", required_argument, 0, 'O'},
	                                     {"verbose", no_argument, 0, 'v'},
	                                     {"help", no_argument, 0, 'h'},
	                                     {0, 0, 0, 0}};
	const char *shm = MLIP_SHM_DEFAULT, *listen_spec = "127.0.0.1:" DEFAULT_PORT;
	const char *pty = NULL, *config = NULL, *tools = NULL;
	char why[256], pty_default[200];
	struct mlip_config_error cerr;
	int c, quiet_ms = DEFAULT_QUIET;

	while ((c = getopt_long(argc, argv, "vh", opts, NULL)) != -1) {
		switch (c) {
		case 's':
			shm = optarg;
			break;
		case 'l':
			listen_spec = optarg;
			break;
		case 'p':
			pty = optarg;
			break;
		case 'Q': {
			char *end;
			long v = strtol(optarg, &end, 10);
			if (*end != '\0' || v < 1 || v > 60000) {
				logf_("--quiet-ms: '%s' is not 1..60000", optarg);
				return 2;
			}
			quiet_ms = (int)v;
			break;
		}
		case 'D': {
			char *end;
			S.default_feed = strtod(optarg, &end);
			if (*end != '\0' || !(S.default_feed > 0.0) || S.default_feed > 1e9) {
				logf_("--default-feed: '%s' is not a positive number", optarg);
				return 2;
			}
			break;
		}
		case 'C':
			config = optarg;
			break;
		case 'T':
			tools = optarg;
			break;
		case 'O':
			offs.path = optarg;
			break;
		case 'v':
			S.verbose = 1;
			break;
		case 'h':
			usage(stdout);
			return 0;
		default:
			usage(stderr);
			return 2;
		}
	}
	if (optind != argc) {
		usage(stderr);
		return 2;
	}
	S.quiet_ns = (uint64_t)quiet_ms * 1000000ull;
	S.listen_fd = S.pty_fd = -1;
	S.ov_feed = S.ov_rapid = S.ov_spindle = 100;
	S.ov_post = -1;
	S.sp_post = -1;
	S.ovs_last = 100;
	S.fmt.mask = 1; /* Grbl's default $10=1: MPos */
	grbl_rx_init(&S.rx);

	if (mlip_shm_attach(&seg, shm, why, sizeof(why)) != 0) {
		logf_("%s", why);
		return 1;
	}
	S.r = seg.ring;
	S.take_producer = take_producer;
	S.shm_name = seg.name;
	mlip_ring_machine(S.r, &S.m);
	if (mlip_machine_check(&S.m, &cerr) != MLIP_OK) {
		logf_("%s publishes no usable machine (%s): restart mlip-rt", shm, cerr.msg);
		return 1;
	}
	grbl_axes_of(&S.m, &S.ax);
	S.z_index = -1;
	for (int k = 0; k < S.m.n_axes; k++) {
		S.z_index = S.m.axis[k].letter == 'Z' ? k : S.z_index;
	}
	if (config != NULL) {
		static struct mlip_config cfg; /* large: not on the stack */
		char diff[160];
		if (mlip_config_load(config, &cfg, stderr) != 0) {
			return 1;
		}
		if (grbl_machine_differs(&cfg.machine, &S.m, diff, sizeof(diff))) {
			logf_(
			    "--config %s is not the machine mlip-rt runs on %s (%s): give the INI "
			    "mlip-rt was started with",
			    config, shm, diff);
			return 1;
		}
		grbl_homing_of(&cfg, &S.homing);
	}
	poll_controller();
	S.stop_seen = S.cs.stop_seen;
	if (!S.cs_ok || S.cs.heartbeat == 0) {
		logf_("controller not running on %s: start mlip-rt", shm);
		return 1;
	}
	grbl_stream_init(&S.st, &S.m, S.cs.pos, &smooth_mem);
	{ /* the machine's I/O is the controller's ([SPINDLE], [TOOL], [COOLANT]) */
		struct mlip_ring_io rio;
		if (mlip_ring_io_read(S.r, &rio) != MLIP_OK) {
			logf_("%s publishes no machine I/O yet (mlip-rt starting?): try again",
			      shm);
			return 1;
		}
		if (mlip_cli_io_from_ring(&rio, &S.m, &S.io) != 0) {
			logf_(
			    "%s publishes a machine I/O this mlip-grbl cannot use: restart mlip-rt",
			    shm);
			return 1;
		}
		if (tools != NULL) {
			if (mlip_tooltable_load(&S.table, tools, 0, PROG, stderr) != 0) {
				return 1;
			}
			S.have_table = 1;
			S.io.tools = S.table.tools;
			S.io.n_tools = S.table.n;
		}
		grbl_stream_set_io(&S.st, &S.io);
		S.sp_bus = S.io.spindle == MLIP_IO_CIA402;
		S.sp_ov = 100;
	}
	if (S.default_feed > 0.0) {
		mlip_gcode_set_initial_feed(&S.st.g, S.default_feed);
	}
	if (offs.path != NULL) {
		if (offsets_read() != 0) {
			return 1;
		}
		offsets_take(&S.st.g.off, &offs.kept);
	}
	if (listen_on(listen_spec) != 0) {
		return 1;
	}
	if (pty == NULL) {
		const char *base = shm[0] == '/' ? shm + 1 : shm;
		snprintf(pty_default, sizeof(pty_default), "/tmp/mlip-grbl-%s.tty", base);
		pty = pty_default;
	}
	if (strcmp(pty, "none") != 0) {
		if (pty_setup(pty) != 0) {
			return 1;
		}
		logf_("pseudo-terminal %s -> %s", S.pty_link, S.pty_name);
	}
	signal(SIGPIPE, SIG_IGN);
	mlip_cli_on_stop_signals(on_signal);

	while (!got_signal) {
		struct pollfd pf[MAX_PEERS + 2];
		struct peer *who[MAX_PEERS + 2];
		int n = 0;
		pf[n] = (struct pollfd){S.listen_fd, POLLIN, 0};
		who[n++] = NULL;
		for (int i = 0; i < MAX_PEERS; i++) {
			struct peer *p = S.peers[i];
			if (p == NULL || (p->pty && !S.pty_open)) {
				continue; /* a closed terminal polls as hung up: looked at by time
				           */
			}
			pf[n] =
			    (struct pollfd){p->fd, (short)(POLLIN | (p->tx_len ? POLLOUT : 0)), 0};
			who[n++] = p;
		}
		int busy =
		    S.ctl != NULL && (grbl_rx_pending(&S.rx) || S.st.open ||
		                      grbl_stream_staged(&S.st) > 0 || S.qn > 0 || S.ov_post >= 0 ||
		                      S.sp_post >= 0 || S.reset_wait || S.program_live);
		(void)poll(pf, (nfds_t)n, busy ? 1 : 10);
		if (pf[0].revents & POLLIN) {
			accept_peer();
		}
		for (int i = 1; i < n; i++) {
			if (pf[i].revents & (POLLIN | POLLHUP | POLLERR)) {
				read_peer(who[i]);
			}
		}
		if (S.pty_fd >= 0 && now_ns() - S.pty_checked > PTY_CHECK_NS) {
			S.pty_checked = now_ns();
			pty_check();
		}
		poll_controller();
		follow_controller();
		cmd_pump();
		await_pump();
		/* a report after a command shows its effect: the controller applies
		 * it in its next period (at most 50 ms waited) */
		int applied = S.cs.heartbeat >= S.cmd_hb + 2 || now_ns() - S.cmd_ns > 50000000ull;
		if (S.status_req && S.ctl != NULL && S.qn == 0 && S.ov_post < 0 && S.sp_post < 0 &&
		    applied) {
			S.status_req = 0;
			status_report();
		}
		process_lines();
		quiet_end();
		push_records();
		offsets_keep();
		if (S.locked) {
			if (S.ctl == NULL && !S.program_live && !S.st.open &&
			    grbl_stream_staged(&S.st) == 0) {
				S.fa.pid = 0; /* nobody feeds: mlip-feed may */
				beat();
				producer_unlock();
			} else {
				beat();
			}
		}
		for (int i = 0; i < MAX_PEERS; i++) {
			if (S.peers[i] != NULL && S.peers[i]->tx_len > 0) {
				flush_peer(S.peers[i]);
			}
		}
	}
	logf_("%s: leaving", mlip_cli_signal_name(got_signal));
	if (S.locked) {
		if (S.st.open) {
			grbl_stream_end(&S.st);
			push_records();
		}
		S.fa.pid = 0;
		beat();
	}
	if (S.pty_link[0]) {
		unlink(S.pty_link);
	}
	mlip_shm_close(&seg);
	if (S.have_table) {
		mlip_tooltable_free(&S.table);
	}
	return 0;
}
