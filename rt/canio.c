/*
 * canio.c - SocketCAN output for the controller.
 *
 * libsocketcan is for what it is for, outside the loop: is the interface
 * there and up, what state is the controller in, restart after bus-off.
 * vcan has no CAN controller, so can_get_state/can_do_restart fail there:
 * that is reported as "no state" and -EOPNOTSUPP, not as an error. In the
 * loop: one raw socket, non-blocking sends; a full queue (ENOBUFS/EAGAIN)
 * is counted, never waited on. The socket receives error frames only
 * (CAN_RAW_ERR_FILTER), so bus-off is seen without reading traffic.
 */
#define _GNU_SOURCE /* if_nametoindex, SIOCGIFFLAGS helpers on older libcs */

#include <errno.h>
#include <fcntl.h>
#include <net/if.h>
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

int mlip_canio_check(const char *ifname, char *info, size_t info_len)
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

int mlip_canio_open(struct mlip_canio *io, const char *ifname, int fd_frames, char *why,
                    size_t why_len)
{
	memset(io, 0, sizeof(*io));
	io->fd = -1;
	snprintf(io->ifname, sizeof(io->ifname), "%s", ifname);
	int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
	if (fd < 0) {
		int e = errno;
		snprintf(why, why_len, "socket(PF_CAN): %s%s", strerror(e),
		         e == EAFNOSUPPORT ? " (this kernel has no CAN: see docs/can-vm.md)" : "");
		return -e;
	}
	/* no data frames in: the controller only talks; error frames yes */
	setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, NULL, 0);
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
	io->fd = fd;
	io->fd_frames = fd_frames;
	return 0;
}

int mlip_canio_send(struct mlip_canio *io, const struct mlip_can_frame *f)
{
	ssize_t n;
	if (f->flags & MLIP_CAN_FLAG_FD) {
		struct canfd_frame cf;
		memset(&cf, 0, sizeof(cf));
		cf.can_id = f->id;
		cf.len = f->len;
		cf.flags = (f->flags & MLIP_CAN_FLAG_BRS) ? CANFD_BRS : 0;
		memcpy(cf.data, f->data, f->len);
		n = send(io->fd, &cf, CANFD_MTU, MSG_DONTWAIT);
	} else {
		struct can_frame cf;
		memset(&cf, 0, sizeof(cf));
		cf.can_id = f->id | ((f->flags & MLIP_CAN_FLAG_EFF) ? CAN_EFF_FLAG : 0);
		cf.can_dlc = f->len;
		memcpy(cf.data, f->data, f->len);
		n = send(io->fd, &cf, CAN_MTU, MSG_DONTWAIT);
	}
	if (n >= 0) {
		io->tx_ok++;
		return 0;
	}
	int e = errno;
	if (e == ENOBUFS || e == EAGAIN) {
		io->tx_dropped++;
	}
	return -e;
}

int mlip_canio_poll(struct mlip_canio *io)
{
	int count = 0;
	for (;;) {
		struct canfd_frame cf;
		ssize_t n = recv(io->fd, &cf, sizeof(cf), MSG_DONTWAIT);
		if (n <= 0) {
			break;
		}
		if (cf.can_id & CAN_ERR_FLAG) {
			io->bus_errors++;
			/* atomic: mlip-rt's monitor thread reads it to restart */
			if (cf.can_id & CAN_ERR_BUSOFF) {
				__atomic_store_n(&io->bus_off, 1, __ATOMIC_RELAXED);
			}
			if ((cf.can_id & CAN_ERR_RESTARTED)) {
				__atomic_store_n(&io->bus_off, 0, __ATOMIC_RELAXED);
			}
		}
		count++;
	}
	return count;
}

int mlip_canio_restart(const char *ifname)
{
	if (can_do_restart(ifname) != 0) {
		return errno ? -errno : -EOPNOTSUPP;
	}
	return 0;
}

void mlip_canio_close(struct mlip_canio *io)
{
	if (io->fd >= 0) {
		close(io->fd);
	}
	io->fd = -1;
}
