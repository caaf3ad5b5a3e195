/*
 * canbus.c - the one SocketCAN socket of mlip-rt (rt.h: mlip_canbus): the
 * setpoints of every period go out on it, and the CANopen master talks to
 * the drives on it (SDO, NMT, heartbeats, EMCY, TPDOs), before, in and
 * after the loop.
 *
 * libsocketcan is for what it is for, outside the loop: is the interface
 * there and up, what state is the controller in, restart after bus-off.
 * vcan has no CAN controller, so can_get_state/can_do_restart fail there:
 * that is reported as "no state" and -EOPNOTSUPP, not as an error. On the
 * socket: non-blocking sends (a full queue, ENOBUFS/EAGAIN, is refused,
 * never waited on), a receive filter of exactly the identifiers asked for,
 * and error frames (CAN_RAW_ERR_FILTER), so a bus-off is seen without
 * reading the rest of the traffic.
 */
#define _GNU_SOURCE /* if_nametoindex, SIOCGIFFLAGS helpers on older libcs */

#include <errno.h>
#include <fcntl.h>
#include <net/if.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <libsocketcan.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/netlink.h>
#include <linux/can/raw.h>

#include "rt.h"

static const char *state_name(int st)
{
	static const char *names[] = {"error-active", "error-warning", "error-passive",
	                              "bus-off",      "stopped",       "sleeping"};
	return st >= 0 && st < (int)(sizeof(names) / sizeof(names[0])) ? names[st] : "unknown";
}

int mlip_canbus_check(const char *ifname, char *info, size_t info_len)
{
	if (if_nametoindex(ifname) == 0) {
		snprintf(info, info_len, "CAN interface %s does not exist (ip link add/set up?)",
		         ifname);
		return -ENODEV;
	}
	int s = socket(AF_INET, SOCK_DGRAM, 0), up = 0;
	if (s >= 0) {
		struct ifreq ifr;
		memset(&ifr, 0, sizeof(ifr));
		snprintf(ifr.ifr_name, sizeof(ifr.ifr_name), "%s", ifname);
		if (ioctl(s, SIOCGIFFLAGS, &ifr) == 0) {
			up = (ifr.ifr_flags & IFF_UP) != 0;
		}
		close(s);
	}
	if (!up) {
		snprintf(info, info_len, "CAN interface %s is down (ip link set %s up)", ifname,
		         ifname);
		return -ENETDOWN;
	}
	int st;
	if (can_get_state(ifname, &st) == 0) {
		snprintf(info, info_len, "%s up, controller %s", ifname, state_name(st));
		if (st == CAN_STATE_BUS_OFF || st == CAN_STATE_STOPPED) {
			return -ENETDOWN;
		}
	} else {
		snprintf(info, info_len, "%s up (no controller state: virtual interface)", ifname);
	}
	return 0;
}

int mlip_canbus_open(struct mlip_canbus *bus, const char *ifname, int fd_frames,
                     const uint32_t *rx_ids, int n_ids, char *why, size_t why_len)
{
	struct can_filter flt[MLIP_CANBUS_MAX_IDS];
	memset(bus, 0, sizeof(*bus));
	bus->fd = -1;
	snprintf(bus->ifname, sizeof(bus->ifname), "%s", ifname);
	if (n_ids < 0 || n_ids > MLIP_CANBUS_MAX_IDS) {
		snprintf(why, why_len, "%d identifiers to receive: at most %d", n_ids,
		         MLIP_CANBUS_MAX_IDS);
		return -EINVAL;
	}
	int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
	if (fd < 0) {
		int e = errno;
		snprintf(why, why_len, "socket(PF_CAN): %s%s", strerror(e),
		         e == EAFNOSUPPORT ? " (this kernel has no CAN: see docs/can-vm.md)" : "");
		return -e;
	}
	/* data frames: exactly these standard identifiers (none: the controller
	 * only talks); error frames: all of them */
	for (int i = 0; i < n_ids; i++) {
		flt[i].can_id = rx_ids[i];
		flt[i].can_mask = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG;
	}
	setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, n_ids > 0 ? flt : NULL,
	           (socklen_t)((size_t)n_ids * sizeof(flt[0])));
	can_err_mask_t errmask = CAN_ERR_MASK;
	setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errmask, sizeof(errmask));
	if (fd_frames) {
		int on = 1;
		if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof(on)) != 0) {
			int e = errno;
			snprintf(why, why_len, "CAN FD frames: %s", strerror(e));
			close(fd);
			return -e;
		}
	}
	struct sockaddr_can addr;
	memset(&addr, 0, sizeof(addr));
	addr.can_family = AF_CAN;
	addr.can_ifindex = (int)if_nametoindex(ifname);
	if (addr.can_ifindex == 0 || bind(fd, (struct sockaddr *)&addr, sizeof(addr)) != 0) {
		int e = addr.can_ifindex == 0 ? ENODEV : errno;
		snprintf(why, why_len, "bind to %s: %s", ifname, strerror(e));
		close(fd);
		return -e;
	}
	if (fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK) != 0) {
		int e = errno;
		snprintf(why, why_len, "%s: non-blocking: %s", ifname, strerror(e));
		close(fd);
		return -e;
	}
	if (fd_frames) {
		/* the MTU tells whether the interface carries FD frames at all */
		struct ifreq ifr;
		memset(&ifr, 0, sizeof(ifr));
		snprintf(ifr.ifr_name, sizeof(ifr.ifr_name), "%s", ifname);
		if (ioctl(fd, SIOCGIFMTU, &ifr) == 0 && ifr.ifr_mtu != CANFD_MTU) {
			snprintf(why, why_len, "%s has MTU %d: not CAN FD (ip link set %s mtu 72)",
			         ifname, ifr.ifr_mtu, ifname);
			close(fd);
			return -EPROTONOSUPPORT;
		}
	}
	bus->fd = fd;
	bus->fd_frames = fd_frames;
	return 0;
}

int mlip_canbus_send(struct mlip_canbus *bus, const struct mlip_can_frame *f)
{
	ssize_t n;
	if (f->flags & MLIP_CAN_FLAG_FD) {
		struct canfd_frame cf;
		memset(&cf, 0, sizeof(cf));
		cf.can_id = f->id;
		cf.len = f->len;
		cf.flags = (f->flags & MLIP_CAN_FLAG_BRS) ? CANFD_BRS : 0;
		memcpy(cf.data, f->data, f->len > CANFD_MAX_DLEN ? CANFD_MAX_DLEN : f->len);
		n = send(bus->fd, &cf, CANFD_MTU, MSG_DONTWAIT);
	} else {
		struct can_frame cf;
		memset(&cf, 0, sizeof(cf));
		cf.can_id = f->id | ((f->flags & MLIP_CAN_FLAG_EFF) ? CAN_EFF_FLAG : 0);
		cf.can_dlc = f->len > CAN_MAX_DLEN ? CAN_MAX_DLEN : f->len;
		memcpy(cf.data, f->data, cf.can_dlc);
		n = send(bus->fd, &cf, CAN_MTU, MSG_DONTWAIT);
	}
	return n >= 0 ? 0 : -errno;
}

int mlip_canbus_recv(struct mlip_canbus *bus, struct mlip_can_frame *f, int64_t timeout_ns)
{
	struct canfd_frame cf;
	if (timeout_ns > 0) {
		struct pollfd pf = {bus->fd, POLLIN, 0};
		int r = poll(&pf, 1, (int)((timeout_ns + 999999) / 1000000));
		if (r <= 0) {
			return r < 0 && errno != EINTR ? -errno : MLIP_CAN_RX_NONE;
		}
	}
	ssize_t n = recv(bus->fd, &cf, sizeof(cf), MSG_DONTWAIT);
	if (n < 0) {
		return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? MLIP_CAN_RX_NONE
		                                                                 : -errno;
	}
	memset(f, 0, sizeof(*f));
	if (cf.can_id & CAN_ERR_FLAG) {
		f->id = cf.can_id & CAN_ERR_MASK; /* the error class */
		return MLIP_CAN_RX_ERROR;
	}
	if ((n != CAN_MTU && n != CANFD_MTU) || (cf.can_id & CAN_RTR_FLAG)) {
		return MLIP_CAN_RX_OTHER;
	}
	f->id = cf.can_id & (cf.can_id & CAN_EFF_FLAG ? CAN_EFF_MASK : CAN_SFF_MASK);
	f->flags = (cf.can_id & CAN_EFF_FLAG) ? MLIP_CAN_FLAG_EFF : 0;
	if (n == CANFD_MTU) {
		f->flags |= MLIP_CAN_FLAG_FD;
	}
	f->len = cf.len > sizeof(f->data) ? (uint8_t)sizeof(f->data) : cf.len;
	memcpy(f->data, cf.data, f->len);
	return MLIP_CAN_RX_FRAME;
}

int mlip_canbus_error_bus_off(uint32_t err_class)
{
	/* both in one frame: the restart is the later news */
	return (err_class & CAN_ERR_RESTARTED) ? 0 : (err_class & CAN_ERR_BUSOFF) ? 1 : -1;
}

static int port_send(void *ctx, const struct mlip_can_frame *f)
{
	return mlip_canbus_send(ctx, f);
}

static int port_recv(void *ctx, struct mlip_can_frame *f, int64_t timeout_ns)
{
	return mlip_canbus_recv(ctx, f, timeout_ns);
}

static uint64_t port_now(void *ctx)
{
	(void)ctx;
	return mlip_now_ns();
}

void mlip_canbus_port(struct mlip_canbus *bus, struct mlip_can_port *p)
{
	p->ctx = bus;
	p->send = port_send;
	p->recv = port_recv;
	p->now_ns = port_now;
}

int mlip_canbus_restart(const char *ifname)
{
	if (can_do_restart(ifname) != 0) {
		return errno ? -errno : -EOPNOTSUPP;
	}
	return 0;
}

void mlip_canbus_close(struct mlip_canbus *bus)
{
	if (bus->fd >= 0) {
		close(bus->fd);
	}
	bus->fd = -1;
}
