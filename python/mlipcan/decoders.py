"""Decoders: the frames of one output profile -> decoded cycles (cycle
number, first-frame time, counts per axis) and the anomaly counters (lost,
incomplete, duplicate, stray, malformed). feed() takes one frame;
feed_batch() a recvmmsg batch (whole regular cycles decoded by slicing)."""

import struct
from collections import Counter
from typing import Any, Protocol

from .config import Setup
from .layout import CAN_MTU, CANFD_MTU, Layout

MAX_EVENTS = 200
U32 = 1 << 32
BATCH = 512  # frames per recvmmsg


class FrameBatch(Protocol):
    """k frames received in one recvmmsg (sources.Batch), or the frames of
    the setpoint stream among them (SubBatch), as lists: ids (with the
    linux/can.h flag bits), data lengths, message lengths (CAN_MTU or
    CANFD_MTU), w[j] the j-th signed 32-bit word of each frame's data,
    raw_bad the flag bits (EFF, RTR, ERR) of each id."""

    k: int
    ids: list[int]
    lens: list[int]
    msglen: list[int]
    w: list[list[int]]

    @property
    def raw_bad(self) -> list[int]: ...

    @property
    def isfd(self) -> list[bool]: ...

    def t(self, j: int) -> int: ...

    def ts(self, i: int, end: int, step: int) -> list[int]: ...

    def data(self, j: int) -> bytes: ...


class RawFrameBatch(FrameBatch, Protocol):
    """A whole recvmmsg batch (sources.Batch): also the signed 32-bit word at
    data byte 2 of each frame (a 6-byte RPDO's target, after the controlword)."""

    @property
    def w2(self) -> list[int]: ...


class Decoder:
    """Common state: decoded cycles and the anomaly counters."""

    def __init__(self, layout: Layout) -> None:
        self.L = layout
        self.n = layout.n
        self.full = (1 << self.n) - 1
        self.frames = 0  # every frame received
        self.ours = 0  # frames with one of the profile's ids
        self.foreign: Counter[int] = Counter()  # other ids -> count
        self.malformed = 0
        self.stray = 0
        self.incomplete = 0
        self.duplicates = 0
        self.gaps = 0  # cycles lost (counter jumps; cia402: missing SYNCs)
        self.gap_events = 0
        self.backwards = 0
        self.events: list[dict[str, Any]] = []
        self.batches = 0  # live: recvmmsg calls that returned frames
        self.fast_frames = 0  # live: frames decoded as whole regular cycles
        # decoded cycles
        self.cyc: list[int] = []  # cycle numbers
        self.tns: list[int] = []  # first-frame timestamps, ns
        self.counts: list[tuple[int, ...]] = []  # n int32 each
        # cia402: SYNC timestamps (their differences are the bus period);
        # packed, fd: (counter, first-frame timestamp) of each cycle
        self.period_ts: list[int] = []
        self.period_pairs: list[tuple[int, int]] = []
        self.drives = DriveFrames(layout.setup) if layout.profile == "cia402" else None

    def feed(self, t: int, cid: int, data: bytes, ln: int, fd: bool) -> None:
        """One frame: receive time (ns), id, data, data length, CAN FD."""
        raise NotImplementedError

    def other(self, t: int, cid: int, data: bytes) -> None:
        """A frame that is not part of the setpoint stream: counted as foreign;
        the CiA 402 frames of a deployment (TPDO, EMCY, heartbeat, NMT) are
        also recorded (DriveFrames)."""
        self.foreign[cid] += 1
        if self.drives is not None:
            self.drives.frame(t, cid, data)

    def event(self, kind: str, t_ns: int, **kw: Any) -> None:
        if len(self.events) < MAX_EVENTS:
            e = {"kind": kind, "t": t_ns / 1e9}
            e.update(kw)
            self.events.append(e)

    def finish(self) -> None:
        pass

    def extra(self) -> dict[str, Any]:
        return {}

    # -- batches (live): whole regular cycles at C speed, the rest frame by frame
    def at_boundary(self) -> bool:
        return True

    def fast(self, B: FrameBatch, i: int, m: int) -> int:
        """Take m whole cycles from frame i of batch B if they are exactly
        what the profile sends (ids, lengths, frame kinds, counters); return
        the frames taken (m * frames_per_cycle) or 0."""
        return 0

    def feed_batch(self, B: RawFrameBatch) -> None:
        """A live batch of frames."""
        self.feed_frames(B)

    def feed_frames(self, B: FrameBatch) -> None:
        P = self.L.frames_per_cycle
        k = B.k
        i = 0
        feed = self.feed
        self.batches += 1
        while i < k:
            if self.at_boundary():
                m = (k - i) // P
                taken = self.fast(B, i, m) if m else 0
                if not taken and m > 1:
                    taken = self.fast(B, i, 1)
                if taken:
                    i += taken
                    self.fast_frames += taken
                    continue
            if B.raw_bad[i]:
                self.frames += 1
                self.foreign[B.ids[i]] += 1
            else:
                feed(B.t(i), B.ids[i], B.data(i), B.lens[i], B.isfd[i])
            i += 1


class SubBatch:
    """The frames keep of a Batch, as the batch path reads them; w[0] the
    target words (data byte 0 or 2)."""

    def __init__(self, B: FrameBatch, keep: list[int], words: list[int]) -> None:
        self.B, self.keep, self.k = B, keep, len(keep)
        self.ids = [B.ids[j] for j in keep]
        self.lens = [B.lens[j] for j in keep]
        self.msglen = [B.msglen[j] for j in keep]
        self.w = [[words[j] for j in keep]]
        self._raw_bad = [0] * self.k  # the stream's ids carry no flag bits
        isfd = B.isfd
        self._isfd = [isfd[j] for j in keep]
        self._t = [B.t(j) for j in keep]

    @property
    def raw_bad(self) -> list[int]:
        return self._raw_bad

    @property
    def isfd(self) -> list[bool]:
        return self._isfd

    def t(self, j: int) -> int:
        return self._t[j]

    def ts(self, i: int, end: int, step: int) -> list[int]:
        return self._t[i:end:step]

    def data(self, j: int) -> bytes:
        return self.B.data(self.keep[j])


class DriveFrames:
    """What CiA 402 drives say on the bus, for the report and --tpdo-csv:
    each node's TPDO1 (statusword u16 at byte 0, position actual value i32 at
    byte 2: the mapping mlip writes, tools/mlip.dbc TPDO_NODEn), its EMCYs
    (0x80 + node), heartbeats (0x700 + node) and the NMT commands (0x000)."""

    TPDO_BASE, EMCY_BASE, HB_BASE = 0x180, 0x080, 0x700

    def __init__(self, setup: Setup) -> None:
        self.setup = setup
        self.axis = {n: i for i, n in enumerate(setup.nodes)}
        self.tpdo: list[tuple[int, int, int, int]] = []  # (t ns, node, statusword, actual)
        self.emcy: list[dict[str, Any]] = []
        self.nmt: list[dict[str, Any]] = []
        self.hb_count = dict.fromkeys(setup.nodes, 0)
        self.hb_state: dict[int, int | None] = dict.fromkeys(setup.nodes)  # last state byte
        self.unpack = struct.Struct("<Hi").unpack_from

    def frame(self, t: int, cid: int, data: bytes) -> None:
        node = cid & 0x7F
        base = cid - node
        if node not in self.axis:
            if cid == 0 and len(data) == 2 and len(self.nmt) < MAX_EVENTS:
                self.nmt.append({"t": t / 1e9, "command": f"0x{data[0]:02X}", "node": data[1]})
            return
        if base == self.TPDO_BASE and len(data) == 6:
            sw, act = self.unpack(data, 0)
            self.tpdo.append((t, node, sw, act))
        elif base == self.EMCY_BASE and len(data) == 8 and len(self.emcy) < MAX_EVENTS:
            self.emcy.append(
                {
                    "t": t / 1e9,
                    "node": node,
                    "code": f"0x{data[0] | data[1] << 8:04X}",
                    "error_register": data[2],
                }
            )
        elif base == self.HB_BASE and len(data) == 1:
            self.hb_count[node] += 1
            self.hb_state[node] = data[0]

    def report(self) -> dict[str, Any]:
        from .cia402 import HB_STATE, state_of

        out: dict[str, Any] = {}
        for n, i in self.axis.items():
            rows = [r for r in self.tpdo if r[1] == n]
            cpu = self.setup.cpu[i]
            hb = self.hb_state[n]
            d: dict[str, Any] = {
                "axis": self.setup.axes[i],
                "tpdos": len(rows),
                "heartbeats": self.hb_count[n],
                "heartbeat_state": None if hb is None else HB_STATE.get(hb, hex(hb)),
                "emcy": [e for e in self.emcy if e["node"] == n],
            }
            for key, r in (("first", rows[:1]), ("last", rows[-1:])):
                if r:
                    t, _, sw, act = r[0]
                    d[key] = {
                        "t": t / 1e9,
                        "statusword": f"0x{sw:04X}",
                        "state": state_of(sw),
                        "actual": act,
                        "pos": act / cpu,
                    }
            out[str(n)] = d
        return {"drives": out, "nmt": self.nmt}

    def write_csv(self, path: str) -> None:
        from .cia402 import state_of

        with open(path, "w") as fh:
            fh.write("t,node,axis,statusword,state,actual,pos\n")
            for t, n, sw, act in self.tpdo:
                i = self.axis[n]
                fh.write(
                    f"{t // 1000000000}.{t % 1000000000:09d},{n},{self.setup.axes[i]},"
                    f"{sw},{state_of(sw)},{act},{act / self.setup.cpu[i]!r}\n"
                )


class Cia402Decoder(Decoder):
    def __init__(self, layout: Layout) -> None:
        super().__init__(layout)
        self.sync_id = layout.sync_id
        self.rpdo = layout.rpdo
        self.open = False
        self.seen = 0
        self.cur = [0] * self.n
        self.t_open = 0
        self.cycle = -1  # SYNCs seen - 1
        self.stray_seen = 0  # RPDOs since the last complete cycle, no SYNC
        self.missing_sync = 0
        self.missing_rpdo = 0
        self.duplicate_rpdo = 0
        self.unpack = struct.Struct("<i").unpack_from
        # what one period looks like: SYNC, then the RPDOs in axis order
        order = sorted(self.rpdo, key=lambda cid: self.rpdo[cid][0])
        # the fast path reads the target as one int32 word per frame: at data
        # byte 0 (4-byte target-only RPDO) or 2 (6-byte RPDO, controlword
        # first: Batch.w2, and the drives' frames set aside, feed_batch)
        self.rpdo_len = layout.rpdo_len
        self.stream_ids = frozenset([self.sync_id] + order)
        self.slot = list(range(self.n))  # RPDO of axis a is frame 1 + a
        reps = BATCH // (self.n + 1) + 2
        self.pat_ids = ([self.sync_id] + order) * reps
        self.pat_lens = ([0] + [self.rpdo_len] * self.n) * reps
        self.pat_mlen = [CAN_MTU] * ((self.n + 1) * reps)
        self.trailing_open = False  # finish(): a cycle was left open at the end

    def feed(self, t: int, cid: int, data: bytes, ln: int, fd: bool) -> None:
        self.frames += 1
        if cid == self.sync_id:
            self.ours += 1
            if ln != 0 or fd:
                self.malformed += 1
                return
            self.period_ts.append(t)
            if self.open:
                miss = self.n - bin(self.seen).count("1")
                self.incomplete += 1
                self.missing_rpdo += miss
                self.event("incomplete", t, cycle=self.cycle, missing_rpdo=miss)
            self.cycle += 1
            self.open = True
            self.seen = 0
            self.stray_seen = 0
            self.t_open = t
            return
        r = self.rpdo.get(cid)
        if r is None:
            self.other(t, cid, data)
            return
        self.ours += 1
        if ln != self.rpdo_len or fd:
            self.malformed += 1
            return
        i, off = r
        bit = 1 << i
        if not self.open:
            self.stray += 1
            if self.stray_seen & bit:
                self.stray_seen = 0
            self.stray_seen |= bit
            if self.stray_seen == self.full and self.cycle >= 0:
                # a whole set of RPDOs with no SYNC before it
                self.missing_sync += 1
                self.gaps += 1
                self.gap_events += 1
                self.stray_seen = 0
                self.event("missing_sync", t, after_cycle=self.cycle)
            return
        if self.seen & bit:
            self.duplicate_rpdo += 1
            self.duplicates += 1
            self.incomplete += 1
            self.open = False
            self.event("duplicate_rpdo", t, cycle=self.cycle, axis=self.L.setup.axes[i])
            return
        self.cur[i] = self.unpack(data, off)[0]
        self.seen |= bit
        if self.seen == self.full:
            self.open = False
            self.cyc.append(self.cycle)
            self.tns.append(self.t_open)
            self.counts.append(tuple(self.cur))

    def feed_batch(self, B: RawFrameBatch) -> None:
        """With drives the bus also carries their TPDOs, EMCYs, heartbeats
        (and the RPDO's target sits at byte 2): those go frame by frame to
        other(), the setpoint stream through the batch path on the rest."""
        if self.rpdo_len == 4 and not self.drives_seen(B):
            self.feed_frames(B)
            return
        ids, ours = B.ids, self.stream_ids
        keep = [j for j, cid in enumerate(ids) if cid in ours]
        if len(keep) != B.k:
            bad = B.raw_bad
            for j, cid in enumerate(ids):
                if cid not in ours:
                    self.frames += 1
                    if bad[j]:
                        self.foreign[cid] += 1
                    else:
                        self.other(B.t(j), cid, B.data(j))
        self.feed_frames(SubBatch(B, keep, B.w2 if self.rpdo_len == 6 else B.w[0]))

    def drives_seen(self, B: FrameBatch) -> bool:
        """Any frame of another id in this batch (C speed: set difference)."""
        return not self.stream_ids.issuperset(B.ids)

    def at_boundary(self) -> bool:
        return not self.open and not self.stray_seen

    def fast(self, B: FrameBatch, i: int, m: int) -> int:
        P = self.L.frames_per_cycle
        end = i + m * P
        if (
            B.ids[i:end] != self.pat_ids[: m * P]
            or B.lens[i:end] != self.pat_lens[: m * P]
            or B.msglen[i:end] != self.pat_mlen[: m * P]
        ):
            return 0
        n = self.n
        w0 = B.w[0]
        self.counts.extend(
            zip(*[w0[i + 1 + self.slot[a] : end : P] for a in range(n)], strict=True)
        )
        ts = B.ts(i, end, P)
        self.tns.extend(ts)
        self.period_ts.extend(ts)
        c0 = self.cycle + 1
        self.cyc.extend(range(c0, c0 + m))
        self.cycle += m
        self.frames += m * P
        self.ours += m * P
        return m * P

    def finish(self) -> None:
        self.trailing_open = bool(self.open and self.seen)

    def extra(self) -> dict[str, Any]:
        return {
            "syncs": self.cycle + 1,
            "missing_sync": self.missing_sync,
            "missing_rpdo": self.missing_rpdo,
            "duplicate_rpdo": self.duplicate_rpdo,
            "trailing_partial": int(self.trailing_open),
        }


class CounterDecoder(Decoder):
    """Shared counter logic of packed and fd."""

    def __init__(self, layout: Layout) -> None:
        super().__init__(layout)
        self.last: int | None = None
        self.first_counter: int | None = None

    def counter(self, c: int, t: int, t_first: int) -> bool:
        """Check the counter against the previous one; False for a duplicate
        (same counter again: not a new cycle)."""
        last = self.last
        if last is not None:
            d = (c - last) % U32
            if d == 0:
                self.duplicates += 1
                self.event("duplicate", t, cycle=c)
                return False
            if d == 1:
                pass
            elif d < U32 // 2:
                self.gaps += d - 1
                self.gap_events += 1
                self.event("gap", t, after=last, cycle=c, lost=d - 1)
            else:
                self.backwards += 1
                self.event("backwards", t, after=last, cycle=c)
        else:
            self.first_counter = c
        self.last = c
        self.period_pairs.append((c, t_first))
        return True


class PackedDecoder(CounterDecoder):
    def __init__(self, layout: Layout) -> None:
        super().__init__(layout)
        self.pos = layout.pos
        self.commit_id = layout.commit_id
        self.fullpos = (1 << layout.npos) - 1
        self.seen = 0
        self.cur = [0] * self.n
        self.t_first = 0
        self.commit_lost = 0
        self.u32 = struct.Struct("<I").unpack_from
        self.i32 = struct.Struct("<i").unpack_from
        order = sorted(self.pos, key=lambda cid: self.pos[cid][0])
        reps = BATCH // (layout.npos + 1) + 2
        self.pat_ids = (order + [self.commit_id]) * reps
        self.pat_lens = ([self.pos[cid][2] for cid in order] + [4]) * reps
        self.pat_mlen = [CAN_MTU] * ((layout.npos + 1) * reps)

        self.trailing = False

    def feed(self, t: int, cid: int, data: bytes, ln: int, fd: bool) -> None:
        self.frames += 1
        if cid == self.commit_id:
            self.ours += 1
            if ln != 4 or fd:
                self.malformed += 1
                return
            c = self.u32(data, 0)[0]
            complete = self.seen == self.fullpos
            new = self.counter(c, t, self.t_first if self.seen else t)
            if not complete:
                self.incomplete += 1
                self.event(
                    "incomplete",
                    t,
                    cycle=c,
                    missing_pos=[k for k in range(self.L.npos) if not self.seen >> k & 1],
                )
            elif new:
                self.cyc.append(c)
                self.tns.append(self.t_first)
                self.counts.append(tuple(self.cur))
            self.seen = 0
            return
        p = self.pos.get(cid)
        if p is None:
            self.other(t, cid, data)
            return
        self.ours += 1
        k, fields, length = p
        if ln != length or fd:
            self.malformed += 1
            return
        bit = 1 << k
        if self.seen & bit:
            # the COMMIT of the cycle these frames belonged to was lost
            self.commit_lost += 1
            self.incomplete += 1
            self.event("commit_lost", t, after=self.last)
            self.seen = 0
        if not self.seen:
            self.t_first = t
        self.seen |= bit
        cur, i32 = self.cur, self.i32
        for axis, off in fields:
            cur[axis] = i32(data, off)[0]

    def at_boundary(self) -> bool:
        return not self.seen

    def fast(self, B: FrameBatch, i: int, m: int) -> int:
        P = self.L.frames_per_cycle
        end = i + m * P
        if (
            B.ids[i:end] != self.pat_ids[: m * P]
            or B.lens[i:end] != self.pat_lens[: m * P]
            or B.msglen[i:end] != self.pat_mlen[: m * P]
        ):
            return 0
        npos = self.L.npos
        counters = B.w[0][i + npos : end : P]
        last = self.last
        c0 = counters[0] if last is None else last + 1
        if c0 + m > U32 or counters != list(range(c0, c0 + m)):
            return 0  # a gap, a duplicate or a wrap: frame by frame
        if last is None:
            self.first_counter = c0
        cols: list[list[int]] = []
        for a in range(self.n):
            cols.append(B.w[a % 2][i + a // 2 : end : P])
        self.counts.extend(zip(*cols, strict=True))
        ts = B.ts(i, end, P)
        self.tns.extend(ts)
        self.period_pairs.extend(zip(counters, ts, strict=True))
        self.cyc.extend(counters)
        self.last = counters[-1]
        self.frames += m * P
        self.ours += m * P
        return m * P

    def finish(self) -> None:
        self.trailing = bool(self.seen)
        if self.seen:
            self.stray += bin(self.seen).count("1")

    def extra(self) -> dict[str, Any]:
        return {
            "commit_lost": self.commit_lost,
            "first_counter": self.first_counter,
            "last_counter": self.last,
            "trailing_partial": int(self.trailing),
        }


class FdDecoder(CounterDecoder):
    def __init__(self, layout: Layout) -> None:
        super().__init__(layout)
        self.fd_id = layout.fd_id
        self.fd_len = layout.fd_len
        self.unpack = struct.Struct("<I" + "i" * self.n).unpack_from
        assert layout.fd_fields == [4 + 4 * i for i in range(self.n)]
        self.pat_ids = [self.fd_id] * (BATCH + 1)
        self.pat_lens = [self.fd_len] * (BATCH + 1)
        self.pat_mlen = [CANFD_MTU] * (BATCH + 1)

    def feed(self, t: int, cid: int, data: bytes, ln: int, fd: bool) -> None:
        self.frames += 1
        if cid != self.fd_id:
            self.other(t, cid, data)
            return
        self.ours += 1
        if ln != self.fd_len or not fd:
            self.malformed += 1
            return
        v = self.unpack(data, 0)
        c = v[0]
        if self.counter(c, t, t):
            self.cyc.append(c)
            self.tns.append(t)
            self.counts.append(v[1:])

    def fast(self, B: FrameBatch, i: int, m: int) -> int:
        end = i + m
        if (
            B.ids[i:end] != self.pat_ids[:m]
            or B.lens[i:end] != self.pat_lens[:m]
            or B.msglen[i:end] != self.pat_mlen[:m]
        ):
            return 0
        counters = B.w[0][i:end]
        last = self.last
        c0 = counters[0] if last is None else last + 1
        if c0 + m > U32 or counters != list(range(c0, c0 + m)):
            return 0
        if last is None:
            self.first_counter = c0
        self.counts.extend(zip(*[B.w[1 + a][i:end] for a in range(self.n)], strict=True))
        ts = B.ts(i, end, 1)
        self.tns.extend(ts)
        self.period_pairs.extend(zip(counters, ts, strict=True))
        self.cyc.extend(counters)
        self.last = counters[-1]
        self.frames += m
        self.ours += m
        return m

    def extra(self) -> dict[str, Any]:
        return {"first_counter": self.first_counter, "last_counter": self.last}


DECODERS: dict[str, type[Decoder]] = {
    "cia402": Cia402Decoder,
    "packed": PackedDecoder,
    "fd": FdDecoder,
}
