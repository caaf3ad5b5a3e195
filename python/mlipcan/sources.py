"""Where the listener's frames come from.

python-can (default where the kernel has vcan: a real controller, a
    distribution kernel): can.Bus on SocketCAN, a can.Notifier feeding the
    decoder and, for --log, a can.Logger (candump .log, .asc, .blf, ...).
fast (the software-emulated test VM, MLIP_IN_VM=1, or --receive fast): a
    raw CAN socket set up as python-can's socketcan interface does it, read
    with recvmmsg(2) through ctypes in batches; whole regular cycles are
    decoded by slicing. In that VM importing python-can alone costs tens of
    seconds and Bus.recv 740-2600 us a frame, too slow for 4000 frames/s;
    the batches cost about 100 us a frame there.
logs: candump -l/-L text read here (fast, no import); other formats
    (.asc, .blf, ...) through can.LogReader.
"""

import errno
import os
import socket
import struct
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any

from .config import StrPath
from .decoders import BATCH, Decoder
from .layout import (
    CAN_EFF_FLAG,
    CAN_ERR_FLAG,
    CAN_RTR_FLAG,
    CANFD_BRS,
    CANFD_ESI,
    CANFD_MTU,
    SO_RCVBUFFORCE,
    SO_RXQ_OVFL,
    SO_TIMESTAMPNS,
)
from .report import Frame

if TYPE_CHECKING:
    import can

# Set by SIGTERM/SIGINT (on_signal): the receive loops drain what is queued
# and return. A process-wide flag, as the signal is.
STOP = threading.Event()

# what the batch receiver keeps of a batch for --log: (raw ids, lens,
# message lengths, seconds, nanoseconds, the frames' bytes)
Kept = tuple[list[int], list[int], list[int], list[int], list[int], bytes]


def on_signal(sig: int, frame: FrameType | None) -> None:
    STOP.set()


def tune_socket(
    sock: socket.socket, iface: str, rcvbuf: int, want_fd: bool, info: dict[str, Any]
) -> None:
    """A large receive buffer (SO_RCVBUFFORCE as root), kernel timestamps
    (SO_TIMESTAMPNS), the kernel's drop counter (SO_RXQ_OVFL), a 100 ms
    receive timeout (to notice a stop)."""
    info["rcvbuf_requested"] = rcvbuf
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, rcvbuf)
        info["rcvbuf_method"] = "SO_RCVBUFFORCE"
    except OSError:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        info["rcvbuf_method"] = "SO_RCVBUF (not root: capped by net.core.rmem_max)"
    info["rcvbuf_bytes"] = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
    sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_RXQ_OVFL, 1)
        info["drop_counter"] = True
    except OSError:
        info["drop_counter"] = False
    try:
        mtu = int(Path(f"/sys/class/net/{iface}/mtu").read_text())
        info["mtu"] = mtu
        if want_fd and mtu != CANFD_MTU:
            info["warning"] = (
                f"{iface} mtu {mtu}: CAN FD frames cannot pass (ip link set {iface} mtu 72)"
            )
    except OSError:
        pass


def open_socket(iface: str, rcvbuf: int, want_fd: bool) -> tuple[socket.socket, dict[str, Any]]:
    """The fast path's raw CAN socket bound to iface, CAN FD frames on, made
    with the standard library (AF_CAN, what python-can's socketcan interface
    does, without its import). Returns (socket, info)."""
    info: dict[str, Any] = {}
    if not hasattr(socket, "AF_CAN"):
        raise RuntimeError("this Python has no AF_CAN support")
    try:
        sock = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    except OSError as e:
        raise RuntimeError(
            f"socket(AF_CAN): {e}"
            + (
                " (this kernel has no CAN: run through tools/vcan/run.sh)"
                if e.errno == errno.EAFNOSUPPORT
                else ""
            )
        ) from e
    try:
        sock.setsockopt(socket.SOL_CAN_RAW, socket.CAN_RAW_FD_FRAMES, 1)
        sock.bind((iface,))
    except OSError as e:
        sock.close()
        raise RuntimeError(f"cannot bind to {iface}: {e}") from e
    info["opened_by"] = "socket (stdlib)"
    tune_socket(sock, iface, rcvbuf, want_fd, info)
    sock.settimeout(None)  # blocking; SO_RCVTIMEO wakes us to check for a stop
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, struct.pack("ll", 0, 100000))
    return sock, info


def open_python_can(iface: str, rcvbuf: int, want_fd: bool) -> tuple["can.BusABC", dict[str, Any]]:
    """can.Bus on SocketCAN (mlipcan.bus, what the drive simulator uses too),
    its socket's receive buffer enlarged. Returns (bus, info)."""
    from .bus import open_bus, python_can_version

    bus = open_bus(iface, fd=True)
    info: dict[str, Any] = {
        "opened_by": f"python-can {python_can_version()} can.Bus(interface='socketcan')"
    }
    tune_socket(bus_socket(bus), iface, rcvbuf, want_fd, info)
    info["drop_counter"] = False  # python-can does not hand SO_RXQ_OVFL on
    return bus, info


def bus_socket(bus: "can.BusABC") -> socket.socket:
    """The raw socket under a SocketCAN bus of python-can."""
    sock = getattr(bus, "socket", None)
    if not isinstance(sock, socket.socket):
        raise RuntimeError(f"{bus.channel_info}: not a SocketCAN bus")
    return sock


def msg_frame(m: "can.Message") -> Frame:
    """A can.Message -> (t ns, raw id with the linux/can.h flags, FD flags or None, data)."""
    raw_id = (
        m.arbitration_id
        | (CAN_EFF_FLAG if m.is_extended_id else 0)
        | (CAN_RTR_FLAG if m.is_remote_frame else 0)
        | (CAN_ERR_FLAG if m.is_error_frame else 0)
    )
    fl = (
        ((CANFD_BRS if m.bitrate_switch else 0) | (CANFD_ESI if m.error_state_indicator else 0))
        if m.is_fd
        else None
    )
    return int(round(m.timestamp * 1e9)), raw_id, fl, bytes(m.data)


def feed_frame(dec: Decoder, t: int, raw_id: int, data: bytes, fd: bool) -> None:
    if raw_id & (CAN_ERR_FLAG | CAN_RTR_FLAG | CAN_EFF_FLAG):
        dec.frames += 1
        dec.foreign[raw_id] += 1
    else:
        dec.feed(t, raw_id, data, len(data), fd)


class DecodeListener:
    """A python-can listener feeding a decoder (duck-typed can.Listener)."""

    def __init__(self, dec: Decoder) -> None:
        self.dec = dec
        self.last_ts = 0.0  # the last frame's receive time (s)
        self.last_mono = time.monotonic()  # when it was handled

    def on_message_received(self, m: "can.Message") -> None:
        self.last_ts, self.last_mono = m.timestamp, time.monotonic()
        t, raw_id, fl, data = msg_frame(m)
        feed_frame(self.dec, t, raw_id, data, fl is not None)

    __call__ = on_message_received  # can.Notifier calls its listeners

    def on_error(self, exc: Exception) -> None:
        raise exc

    def stop(self) -> None:
        pass


def run_python_can(
    bus: "can.BusABC", dec: Decoder, log_path: StrPath | None, deadline_mono: float | None
) -> None:
    """python-can's path: a can.Notifier thread hands every can.Message to the
    decoder and, with log_path, to a can.Logger (the format by the file's
    extension: .log candump -L, .asc, .blf, ...). Returns None (python-can
    does not report kernel drops)."""
    import can

    dl = DecodeListener(dec)
    listeners: list[can.notifier.MessageRecipient] = [dl]
    if log_path:
        listeners.append(can.Logger(str(log_path)))
    notifier = can.Notifier(bus, listeners, timeout=0.1)
    mono = time.monotonic
    try:
        while not STOP.is_set() and (deadline_mono is None or mono() < deadline_mono):
            time.sleep(0.05)
    finally:
        # what is already queued in the socket is still read (a stop loses
        # nothing already here): until a frame received after the stop, or
        # 0.3 s without any, counted from the stop at the earliest (a
        # notifier thread behind, descheduled in a loaded VM, catches up;
        # at most 60 s)
        t_stop, m_stop, t_end = time.time(), mono(), mono() + 60
        while dl.last_ts < t_stop and mono() - max(dl.last_mono, m_stop) < 0.3 and mono() < t_end:
            time.sleep(0.02)
        notifier.stop(timeout=5)  # stops the listeners too: the logger is closed
    if notifier.exception is not None:
        raise RuntimeError(f"python-can notifier: {notifier.exception}")


class MMsg:
    """recvmmsg(2) through ctypes: up to BATCH frames per system call into one
    flat buffer, each with its own control buffer (the SO_TIMESTAMPNS
    timestamp, and the SO_RXQ_OVFL drop counter when there were drops). The
    fields of all frames are then read as strided slices of memoryviews (C
    speed, no per-frame Python work) by Batch."""

    HDR = 64  # sizeof(struct mmsghdr) on LP64: msghdr 56 + msg_len 4 + pad
    CTL = 64  # control buffer per frame: timestamp cmsg 32 + drop counter cmsg 24

    def __init__(self, sock: socket.socket, n: int = BATCH) -> None:
        import ctypes  # here: the python-can path and the tests do without it

        if struct.calcsize("P") != 8:
            raise OSError("recvmmsg layout assumes a 64-bit ABI")
        libc = ctypes.CDLL(None, use_errno=True)
        self._recvmmsg = libc.recvmmsg
        self._recvmmsg.argtypes = [
            ctypes.c_int,
            ctypes.c_void_p,
            ctypes.c_uint,
            ctypes.c_int,
            ctypes.c_void_p,
        ]
        self._recvmmsg.restype = ctypes.c_int
        self.ctypes = ctypes
        self.fd = sock.fileno()
        self.n = n
        self.frames = bytearray(n * CANFD_MTU)
        self.ctl = bytearray(n * self.CTL)
        self.iov = bytearray(n * 16)
        self.hdr = bytearray(n * self.HDR)

        def addr(b: bytearray) -> int:
            return ctypes.addressof((ctypes.c_char * len(b)).from_buffer(b))

        fa, ca, ia = addr(self.frames), addr(self.ctl), addr(self.iov)
        for j in range(n):
            struct.pack_into("=QQ", self.iov, 16 * j, fa + j * CANFD_MTU, CANFD_MTU)
            # msghdr: name, namelen(+pad), iov, iovlen, control, controllen, flags(+pad)
            struct.pack_into(
                "=QQQQQQQ",
                self.hdr,
                self.HDR * j,
                0,
                0,
                ia + 16 * j,
                1,
                ca + j * self.CTL,
                self.CTL,
                0,
            )
        self.pristine = bytes(self.hdr)
        self.hdr_addr = addr(self.hdr)
        self.pristine_buf = ctypes.create_string_buffer(self.pristine, len(self.pristine))
        self.fv = memoryview(self.frames)
        self.fw = self.fv.cast("i")  # signed 32-bit words of the frames
        # the words 2 bytes further on: a 6-byte RPDO's target (data byte 2)
        self.fw2 = self.fv[2 : n * CANFD_MTU - 2].cast("i")
        self.fu = self.fv.cast("I")
        self.hv = memoryview(self.hdr).cast("I")
        self.cv = memoryview(self.ctl).cast("q")
        self.ci = memoryview(self.ctl).cast("i")
        self.cu = memoryview(self.ctl).cast("I")

    def recv(self, block: bool = True) -> int:
        """Frames received (0: timeout, signal or nothing queued)."""
        ctypes = self.ctypes
        ctypes.memmove(self.hdr_addr, self.pristine_buf, len(self.pristine))
        flags = 0x10000 if block else socket.MSG_DONTWAIT  # MSG_WAITFORONE
        r: int = self._recvmmsg(self.fd, self.hdr_addr, self.n, flags, None)
        if r < 0:
            e = ctypes.get_errno()
            if e in (errno.EAGAIN, errno.EINTR):
                return 0
            raise OSError(e, os.strerror(e))
        return r


class Batch:
    """The k frames of one recvmmsg as lists (C-speed strided slices)."""

    def __init__(self, mm: MMsg, k: int, nwords: int) -> None:
        self.k = k
        self.mm = mm
        fu, fw = mm.fu, mm.fw
        self.ids = fu[0 : k * 18 : 18].tolist()
        self.lens = mm.fv[4 : k * CANFD_MTU : CANFD_MTU].tolist()
        self.msglen = mm.hv[14 : k * 16 : 16].tolist()
        self.w = [fw[2 + j : k * 18 : 18].tolist() for j in range(nwords)]
        # timestamps: first cmsg of each control buffer is SO_TIMESTAMPNS
        self.sec = mm.cv[2 : k * 8 : 8].tolist()
        self.nsec = mm.cv[3 : k * 8 : 8].tolist()
        ctl_len = mm.hv[10 : k * 16 : 16].tolist()  # msg_controllen (low word)
        self.drops: int | None = None
        if min(ctl_len) < 32 or mm.ci[3 : k * 16 : 16].tolist().count(SO_TIMESTAMPNS) != k:
            types = mm.ci[3 : k * 16 : 16].tolist()
            now = time.time_ns()
            for j in range(k):
                if ctl_len[j] < 32 or types[j] != SO_TIMESTAMPNS:
                    self.sec[j], self.nsec[j] = divmod(now, 1000000000)
        if max(ctl_len) > 32:
            for j in range(k):
                if ctl_len[j] > 32 and mm.ci[j * 16 + 11] == SO_RXQ_OVFL:
                    self.drops = mm.cu[j * 16 + 12]
        self.fv = mm.fv
        self._isfd: list[bool] | None = None
        self._bad: list[int] | None = None

    @property
    def w2(self) -> list[int]:
        """The int32 at data byte 2 of each frame (a 6-byte RPDO's target)."""
        return self.mm.fw2[2 : self.k * 18 : 18].tolist()

    @property
    def isfd(self) -> list[bool]:
        if self._isfd is None:
            self._isfd = [v == CANFD_MTU for v in self.msglen]
        return self._isfd

    @property
    def raw_bad(self) -> list[int]:  # EFF, RTR, ERR flags
        if self._bad is None:
            self._bad = [r & 0xE0000000 for r in self.ids]
        return self._bad

    @property
    def flags(self) -> list[int]:
        return self.fv[5 : self.k * CANFD_MTU : CANFD_MTU].tolist()

    def t(self, j: int) -> int:
        return self.sec[j] * 1000000000 + self.nsec[j]

    def ts(self, i: int, end: int, step: int) -> list[int]:
        sec, nsec = self.sec[i:end:step], self.nsec[i:end:step]
        return [s * 1000000000 + n for s, n in zip(sec, nsec, strict=True)]

    def data(self, j: int) -> bytes:
        o = j * CANFD_MTU + 8
        return bytes(self.fv[o : o + self.lens[j]])

    def keep(self) -> Kept:
        """What --log needs, copied: (raw ids, lens, msg lengths, sec, nsec, frames)."""
        return (
            self.ids,
            self.lens,
            self.msglen,
            self.sec,
            self.nsec,
            bytes(self.fv[: self.k * CANFD_MTU]),
        )


def expand_kept(kept: list[Kept]) -> Iterator[Frame]:
    """Frames kept by the batch receiver -> (t, raw_id, fd flags or None, data)."""
    for ids, lens, msglen, sec, nsec, buf in kept:
        for j in range(len(ids)):
            o = j * CANFD_MTU + 8
            yield (
                sec[j] * 1000000000 + nsec[j],
                ids[j],
                buf[o - 3] if msglen[j] == CANFD_MTU else None,
                buf[o : o + lens[j]],
            )


def run_live_batch(
    sock: socket.socket,
    dec: Decoder,
    kept: list[Kept] | None,
    deadline_mono: float | None,
    nwords: int,
    gather_s: float = 0.01,
) -> int:
    """The hot path: recvmmsg batches, regular cycles decoded by slicing.
    After a batch that did not fill the buffer, sleep gather_s so that the
    next call finds many frames queued (the socket buffer holds them; their
    timestamps are the kernel's): the cost per call, large in an emulated VM,
    is then shared by tens of frames instead of one or four."""
    mm = MMsg(sock)
    drops = 0
    mono = time.monotonic
    sleep = time.sleep

    def take(k: int) -> None:
        nonlocal drops
        B = Batch(mm, k, nwords)
        if B.drops is not None:
            drops = B.drops
        if kept is not None:
            kept.append(B.keep())
        dec.feed_batch(B)

    while True:
        k = mm.recv()
        if k:
            take(k)
        if STOP.is_set() or (deadline_mono is not None and mono() >= deadline_mono):
            break
        if 0 < k < mm.n:
            sleep(gather_s)
    while True:  # drain what is already queued: a stop loses nothing already here
        k = mm.recv(block=False)
        if not k:
            break
        take(k)
    return drops


def run_live(
    sock: socket.socket,
    dec: Decoder,
    frames_out: list[Frame] | None,
    deadline_mono: float | None,
) -> int:
    """One recvmsg per frame, the kernel timestamp from the ancillary data,
    decode with struct. Returns the kernel's drop count."""
    recvmsg = sock.recvmsg
    anc_size = socket.CMSG_SPACE(16) + socket.CMSG_SPACE(4)
    ts_unpack = struct.Struct("@qq").unpack_from
    hdr_unpack = struct.Struct("=IB B").unpack_from
    u32 = struct.Struct("=I").unpack_from
    feed = dec.feed
    keep = frames_out.append if frames_out is not None else None
    drops = 0
    mono = time.monotonic

    def handle(data: bytes, anc: list[tuple[int, int, bytes]]) -> None:
        """One received frame: its time, then decode (or count it as foreign)."""
        nonlocal drops
        t = 0
        for _lvl, typ, cd in anc:
            if typ == SO_TIMESTAMPNS:
                s, ns = ts_unpack(cd)
                t = s * 1000000000 + ns
            elif typ == SO_RXQ_OVFL:
                drops = u32(cd)[0]
        raw_id, ln, fl = hdr_unpack(data)
        fd = len(data) == CANFD_MTU
        if t == 0:
            t = time.time_ns()
        if keep is not None:
            keep((t, raw_id, fl if fd else None, bytes(data[8 : 8 + ln])))
        if raw_id & (CAN_ERR_FLAG | CAN_RTR_FLAG | CAN_EFF_FLAG):
            dec.frames += 1
            dec.foreign[raw_id] += 1
        else:
            feed(t, raw_id, data[8 : 8 + ln], ln, fd)

    while True:
        try:
            data, anc, _flags, _addr = recvmsg(CANFD_MTU, anc_size)
        except BlockingIOError:  # SO_RCVTIMEO: nothing for 100 ms
            if STOP.is_set() or (deadline_mono is not None and mono() >= deadline_mono):
                break
            continue
        handle(data, anc)
        if STOP.is_set():
            break
        if deadline_mono is not None and (dec.frames & 255) == 0 and mono() >= deadline_mono:
            break
    # drain what is already queued (a stop must not lose frames already here)
    sock.setblocking(False)
    while True:
        try:
            data, anc, _f, _a = recvmsg(CANFD_MTU, anc_size)
        except (BlockingIOError, InterruptedError):
            break
        handle(data, anc)
    return drops


def parse_log_line(line: str) -> tuple[int, int, int | None, bytes, str] | None:
    """One candump -l/-L line -> (t_ns, raw_id, fd_flags or None, data, iface),
    or None for a blank/comment line. Raises ValueError when malformed."""
    line = line.strip()
    if not line or line.startswith("#"):
        return None
    if not line.startswith("("):
        raise ValueError("expected '(timestamp) iface frame'")
    close = line.index(")")
    ts = line[1:close]
    sec, _, frac = ts.partition(".")
    t = int(sec) * 1000000000 + int((frac + "000000000")[:9])
    rest = line[close + 1 :].split()
    if len(rest) < 2:
        raise ValueError("expected '(timestamp) iface frame'")
    iface, frame = rest[0], rest[1]
    cid_s, sep, payload = frame.partition("#")
    if not sep:
        raise ValueError("no '#' in the frame")
    raw_id = int(cid_s, 16)
    if len(cid_s) == 8 and not raw_id & CAN_ERR_FLAG:
        raw_id |= CAN_EFF_FLAG
    fl = None
    if payload.startswith("#"):  # FD: ID##<flags><data>
        fl = int(payload[1], 16)
        payload = payload[2:]
    elif payload.startswith("R"):
        return t, raw_id | CAN_RTR_FLAG, None, b"", iface
    payload = payload.replace(".", "")
    data = bytes.fromhex(payload)
    return t, raw_id, fl, data, iface


def run_log(
    path: StrPath, dec: Decoder, frames_out: list[Frame] | None, want_iface: str | None = None
) -> None:
    """Decode a log: candump -l/-L text here, anything else python-can reads
    (.asc, .blf, .trc, ...) through can.LogReader."""
    if not str(path).endswith((".log", ".txt")) and not Path(path).suffix == "":
        return run_log_python_can(path, dec, frames_out, want_iface)
    keep = frames_out.append if frames_out is not None else None
    feed = dec.feed
    with open(path) as fh:
        for lineno, line in enumerate(fh, 1):
            try:
                r = parse_log_line(line)
            except (ValueError, IndexError) as e:
                raise RuntimeError(f"{path}:{lineno}: not candump -l format: {e}") from e
            if r is None:
                continue
            t, raw_id, fl, data, iface = r
            if want_iface is not None and iface != want_iface:
                continue
            if keep is not None:
                keep((t, raw_id, fl, data))
            if raw_id & (CAN_ERR_FLAG | CAN_RTR_FLAG | CAN_EFF_FLAG):
                dec.frames += 1
                dec.foreign[raw_id] += 1
            else:
                feed(t, raw_id, data, len(data), fl is not None)
            if STOP.is_set():
                break


def run_log_python_can(
    path: StrPath, dec: Decoder, frames_out: list[Frame] | None, want_iface: str | None = None
) -> None:
    import can

    keep = frames_out.append if frames_out is not None else None
    try:
        for m in can.LogReader(str(path)):
            if want_iface is not None and m.channel not in (None, want_iface):
                continue
            t, raw_id, fl, data = msg_frame(m)
            if keep is not None:
                keep((t, raw_id, fl, data))
            feed_frame(dec, t, raw_id, data, fl is not None)
    except (ValueError, OSError, can.CanError) as e:
        raise RuntimeError(f"{path}: {e}") from e
