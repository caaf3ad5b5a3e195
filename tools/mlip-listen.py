#!/usr/bin/env python3
"""mlip-listen - watch the setpoint frames mlip-rt puts on a CAN bus.

    mlip-listen.py (--can IFACE | --from-log FILE) [--config FILE] [--profile P]
                   [--csv OUT] [--log OUT] [--json OUT] [--duration S]
    mlip-listen.py --check-layout [--config FILE] [--profile P]

Rebuilds every axis position of every period from the frames of the output
profile (include/mlip/canenc.h, tools/mlip.dbc) and reports what a drive would
have seen: cycles, lost cycles, incomplete cycles, strays, and the period as
seen on the bus.

  cia402  a cycle is a SYNC followed by one RPDO per node; the cycle number is
          the SYNC count from 0 (there is no counter on the wire). Reported: a
          SYNC that arrives before every RPDO of the previous one did
          (incomplete, missing RPDOs), an RPDO twice after one SYNC (duplicate,
          the cycle is dropped), RPDOs with no SYNC before them (stray; a whole
          set of them: a missing SYNC).
  packed  POS frames then a COMMIT carrying the cycle counter: a COMMIT with a
          POS frame missing is incomplete, a POS id twice before a COMMIT
          means the COMMIT was lost, the counter stepping by more than 1 means
          whole cycles lost (gaps), by 0 a duplicate.
  fd      one frame per cycle carrying the counter: gaps and duplicates.

Outputs:
  stdout      one summary line
  --csv OUT   one row per decoded (complete) cycle: cycle,t,x,y,...,cx,cy,...
              t = receive timestamp (s, CLOCK_REALTIME, kernel) of the cycle's
              first frame; positions in mm/deg = counts / COUNTS_PER_UNIT;
              cx,... the raw drive counts
  --log OUT   every frame, candump -l format: (1700000000.123456) vcan0 201#39300000
  --json OUT  the report: counters, period statistics (min/p50/p99/p99.9/max,
              1-us histogram), first and last positions, socket drops

Live (--can): a raw CAN socket (CAN FD frames on), its receive buffer
enlarged (SO_RCVBUFFORCE as root, --rcvbuf, default 16 MiB; the kernel
doubles it) so bursts are not dropped, kernel receive timestamps
(SO_TIMESTAMPNS) and the kernel's drop counter (SO_RXQ_OVFL): "socket_drops"
> 0 means the listener did not keep up. Frames are read with recvmmsg(2) (up
to 512 per call, through ctypes) and, after a call that did not fill the
batch, the listener sleeps 10 ms so that the next call finds tens of frames:
whole regular cycles are then decoded by slicing the batch (C speed), anything
irregular frame by frame. In the software-emulated test VM this takes about
100 us of CPU per frame, against 280 us for one recvmsg per frame
(--no-batch) and 740-2600 us for python-can's Bus.recv (--python-can-recv),
which cannot keep up with 4000 frames/s there. The socket is made with the
standard library (what python-can's socketcan interface does): importing
python-can costs tens of seconds in that VM (--python-can to use it).
SIGTERM/SIGINT: the frames already queued are read, every output is written,
exit 0.

The layout (byte offsets, sizes, signedness of every field) is read from the
DBC with cantools at start-up and checked against the config (axis count,
nodes, ids): a disagreement is an error. cantools is slow to import in the VM,
so what it read is cached in --dbc-cache (default build/) under the DBC's
SHA-256; --check-layout fills the cache and prints the layout. The hot path
then decodes with struct and slicing. Exit status: 0 done, 1 runtime error
(interface, log file), 2 usage or a layout mismatch.
"""
import argparse
import configparser
import errno
import hashlib
import json
import math
import os
import signal
import socket
import struct
import sys
import time
from collections import Counter
from pathlib import Path

PROG = "mlip-listen"
ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DBC = ROOT / "tools" / "mlip.dbc"
LETTERS = "XYZABC"

# linux/can.h
CAN_EFF_FLAG = 0x80000000
CAN_RTR_FLAG = 0x40000000
CAN_ERR_FLAG = 0x20000000
CAN_EFF_MASK = 0x1FFFFFFF
CAN_SFF_MASK = 0x7FF
CANFD_BRS = 0x01
CANFD_ESI = 0x02
CAN_MTU = 16
CANFD_MTU = 72
FD_LENS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)
# asm-generic/socket.h (x86, arm, ...)
SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)
SO_RXQ_OVFL = getattr(socket, "SO_RXQ_OVFL", 40)
SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)


class UsageError(Exception):
    pass


def fd_len(n):
    for ln in FD_LENS:
        if ln >= n:
            return ln
    return -1


# --------------------------------------------------------------------- config

def parse_int(text, what):
    """Integer as mlip/config.h reads it: decimal digits or 0x hex (a leading 0
    is still decimal)."""
    t = text.strip()
    try:
        if t[:2] in ("0x", "0X"):
            return int(t[2:], 16)
        if not t.isdigit():
            raise ValueError
        return int(t, 10)
    except ValueError:
        raise UsageError(f"{what}: '{text}' is not an integer (decimal or 0x hex)")


def parse_num(text, what):
    try:
        v = float(text)
    except ValueError:
        raise UsageError(f"{what}: '{text}' is not a number")
    if not math.isfinite(v):
        raise UsageError(f"{what}: '{text}' is not finite")
    return v


class Setup:
    """What the listener needs of the machine: axes, nodes, counts, ids."""

    def __init__(self):
        self.axes = list("XYZ")
        self.nodes = [1, 2, 3]
        self.cpu = [1000.0] * 3
        self.period_s = 0.001
        self.profile = "cia402"
        self.bitrate = 1000000
        self.data_bitrate = 5000000
        self.sync_id = 0x080
        self.rpdo_base = 0x200
        self.packed_base = 0x300
        self.fd_id = 0x400
        self.status_id = 0x180
        self.source = "defaults (X Y Z, nodes 1..3, 1000 counts/unit)"

    @classmethod
    def from_ini(cls, path):
        s = cls()
        cp = configparser.ConfigParser(inline_comment_prefixes=("#", ";"),
                                       comment_prefixes=("#", ";"),
                                       interpolation=None, strict=True)
        cp.optionxform = str  # keys are case-sensitive upper case
        try:
            with open(path, encoding="utf-8-sig") as fh:
                cp.read_file(fh)
        except (OSError, configparser.Error) as e:
            raise UsageError(f"{path}: {e}")
        if not cp.has_option("TRAJ", "COORDINATES"):
            raise UsageError(f"{path}: no [TRAJ] COORDINATES")
        axes = cp.get("TRAJ", "COORDINATES").split()
        if not 1 <= len(axes) <= 6 or any(a not in LETTERS for a in axes) or \
                len(set(axes)) != len(axes):
            raise UsageError(f"{path}: COORDINATES '{' '.join(axes)}' is not 1..6 distinct of XYZABC")
        s.axes = axes
        s.nodes, s.cpu = [], []
        for i, a in enumerate(axes):
            sec = "AXIS_" + a
            if not cp.has_section(sec):
                raise UsageError(f"{path}: no [{sec}]")
            s.nodes.append(parse_int(cp.get(sec, "CAN_NODE", fallback=str(i + 1)),
                                     f"{path}: [{sec}] CAN_NODE"))
            c = parse_num(cp.get(sec, "COUNTS_PER_UNIT", fallback="1000"),
                          f"{path}: [{sec}] COUNTS_PER_UNIT")
            if not c > 0:
                raise UsageError(f"{path}: [{sec}] COUNTS_PER_UNIT must be > 0")
            s.cpu.append(c)
        s.period_s = parse_num(cp.get("TRAJ", "PERIOD", fallback="0.001"), f"{path}: PERIOD")
        if cp.has_section("CAN"):
            g = lambda k, d: cp.get("CAN", k, fallback=d)
            s.profile = g("PROFILE", "cia402")
            s.bitrate = parse_int(g("BITRATE", "1000000"), f"{path}: [CAN] BITRATE")
            s.data_bitrate = parse_int(g("DATA_BITRATE", "5000000"), f"{path}: [CAN] DATA_BITRATE")
            for key in ("SYNC_ID", "RPDO_BASE", "PACKED_BASE", "FD_ID", "STATUS_ID"):
                setattr(s, key.lower(), parse_int(g(key, hex(getattr(s, key.lower()))),
                                                  f"{path}: [CAN] {key}"))
        if len(set(s.nodes)) != len(s.nodes) or any(not 1 <= n <= 127 for n in s.nodes):
            raise UsageError(f"{path}: CAN_NODEs must be distinct, 1..127: {s.nodes}")
        s.source = str(path)
        return s


# --------------------------------------------------------------------- layout

def _ns(d):
    from types import SimpleNamespace
    return SimpleNamespace(**d)


def load_dbc(path, cache_dir=None):
    """The DBC's messages as plain records (name, frame_id, length, is_fd,
    signals: name, start, length, byte_order, is_signed, scale), read with
    cantools. cantools (which imports python-can) takes tens of seconds to
    import in the software-emulated test VM, so the extraction is cached in
    cache_dir keyed by the DBC's SHA-256: the same file gives the same
    records. Returns (messages, "cantools" | "cache FILE")."""
    try:
        raw = Path(path).read_bytes()
    except OSError as e:
        raise UsageError(f"{path}: {e}")
    digest = hashlib.sha256(raw).hexdigest()
    cache = Path(cache_dir) / f"mlip-listen-dbc-{digest[:16]}.json" if cache_dir else None
    if cache is not None:
        try:
            d = json.loads(cache.read_text())
            if d.get("sha256") == digest:
                msgs = [_ns(dict(m, signals=[_ns(s) for s in m["signals"]])) for m in d["messages"]]
                return msgs, f"cache {cache}"
        except (OSError, ValueError, KeyError, TypeError):
            pass
    import cantools  # start-up only

    try:
        db = cantools.database.load_string(raw.decode("utf-8"), database_format="dbc", strict=True)
    except Exception as e:  # cantools raises many kinds
        raise UsageError(f"{path}: {e}")
    out = [{"name": m.name, "frame_id": m.frame_id, "length": m.length, "is_fd": bool(m.is_fd),
            "signals": [{"name": s.name, "start": s.start, "length": s.length,
                         "byte_order": s.byte_order, "is_signed": bool(s.is_signed),
                         "scale": float(s.scale)} for s in m.signals]}
           for m in db.messages]
    if cache is not None:
        try:
            cache.parent.mkdir(parents=True, exist_ok=True)
            tmp = cache.with_suffix(f".tmp{os.getpid()}")
            tmp.write_text(json.dumps({"sha256": digest, "dbc": str(path), "messages": out}))
            os.replace(tmp, cache)
        except OSError:
            pass
    return [_ns(dict(m, signals=[_ns(s) for s in m["signals"]])) for m in out], "cantools"


class Layout:
    """Frame layouts for one profile and machine, taken from the DBC and
    checked against the config. Offsets are byte offsets into the data."""

    def __init__(self, setup, profile, dbc_path, cache_dir=None):
        self.setup = setup
        self.profile = profile
        self.n = n = len(setup.axes)
        self.notes = []
        messages, self.dbc_source = load_dbc(dbc_path, cache_dir)
        self.dbc = str(dbc_path)
        by_name = {m.name: m for m in messages}

        def msg(name):
            if name not in by_name:
                raise UsageError(f"{dbc_path}: no message {name} (needed by the {profile} profile)")
            return by_name[name]

        def field(m, sig_name, start, signed, what):
            """Check that m carries sig_name as a little-endian 32-bit field at
            bit `start` with the given signedness; return its byte offset."""
            sigs = {s.name: s for s in m.signals}
            if sig_name not in sigs:
                raise UsageError(f"{dbc_path}: {m.name} has no signal {sig_name} ({what})")
            s = sigs[sig_name]
            if (s.start, s.length, s.byte_order, bool(s.is_signed)) != \
                    (start, 32, "little_endian", signed):
                raise UsageError(
                    f"{dbc_path}: {m.name}.{sig_name} is {s.length} bits at bit {s.start}, "
                    f"{s.byte_order}, {'signed' if s.is_signed else 'unsigned'}; canenc.h "
                    f"and this listener expect 32 bits at bit {start}, little_endian, "
                    f"{'signed' if signed else 'unsigned'} ({what})")
            return s

        def check_id(m, cfg_id, what):
            if m.frame_id != cfg_id:
                self.notes.append(f"{m.name} is 0x{m.frame_id:03X} in the DBC, "
                                  f"0x{cfg_id:03X} by the config ({what}): using the config's id")

        def check_scale(sig, axis):
            cpu = setup.cpu[axis]
            if abs(sig.scale * cpu - 1.0) > 1e-12:
                self.notes.append(
                    f"{sig.name}: DBC factor {sig.scale} vs COUNTS_PER_UNIT {cpu:g} of axis "
                    f"{setup.axes[axis]}: positions use the config's counts")

        def check_letter(sig, axis):
            want = setup.axes[axis] + "_target"
            if sig.name != want:
                self.notes.append(f"the DBC's default setup calls this field {sig.name}; "
                                  f"the config puts axis {setup.axes[axis]} there")

        if profile == "cia402":
            sync = msg("SYNC")
            if sync.length != 0:
                raise UsageError(f"{dbc_path}: SYNC has length {sync.length}, canenc.h says 0")
            check_id(sync, setup.sync_id, "SYNC_ID")
            self.sync_id = setup.sync_id
            self.rpdo = {}  # id -> (axis index, byte offset)
            for i, node in enumerate(setup.nodes):
                m = msg(f"RPDO_NODE{node}")
                if m.length != 4:
                    raise UsageError(f"{dbc_path}: {m.name} has length {m.length}, canenc.h says 4")
                sig = m.signals[0] if len(m.signals) == 1 else None
                if sig is None:
                    raise UsageError(f"{dbc_path}: {m.name} must carry one signal")
                field(m, sig.name, 0, True, f"axis {setup.axes[i]}, node {node}")
                check_id(m, setup.rpdo_base + node, "RPDO_BASE + CAN_NODE")
                check_scale(sig, i)
                check_letter(sig, i)
                self.rpdo[setup.rpdo_base + node] = (i, sig.start // 8)
            ids = [self.sync_id] + list(self.rpdo)
            self.frames_per_cycle = 1 + n
        elif profile == "packed":
            npos = (n + 1) // 2
            self.pos = {}  # id -> (k, ((axis, offset), ...), length)
            pos0 = msg("PACKED_POS0")
            for k in range(npos):
                m = msg(f"PACKED_POS{k}")
                sigs = sorted(m.signals, key=lambda s: s.start)
                if m.length != 8 or len(sigs) != 2:
                    raise UsageError(f"{dbc_path}: {m.name} must be 8 bytes with two signals")
                fields = []
                for j, start in enumerate((0, 32)):
                    axis = 2 * k + j
                    field(m, sigs[j].name, start, True, f"packed frame {k}")
                    if axis < n:
                        check_scale(sigs[j], axis)
                        check_letter(sigs[j], axis)
                        fields.append((axis, start // 8))
                length = 8 if 2 * k + 1 < n else 4
                if length != m.length:
                    self.notes.append(f"{m.name}: length {length} with {n} axes (the DBC's "
                                      f"6-axis setup has {m.length})")
                check_id(m, setup.packed_base + k, "PACKED_BASE + k")
                self.pos[setup.packed_base + k] = (k, tuple(fields), length)
            commit = msg("PACKED_COMMIT")
            field(commit, "cycle", 0, False, "packed commit counter")  # checks it
            if commit.length != 4:
                raise UsageError(f"{dbc_path}: PACKED_COMMIT has length {commit.length}, canenc.h says 4")
            # the DBC describes 6 axes: its COMMIT follows its 3 POS frames
            if commit.frame_id - pos0.frame_id != 3:
                raise UsageError(f"{dbc_path}: PACKED_COMMIT is not PACKED_POS0 + ceil(6/2)")
            self.commit_id = setup.packed_base + npos
            if self.commit_id != commit.frame_id:
                self.notes.append(f"PACKED_COMMIT is 0x{self.commit_id:03X} with {n} axes "
                                  f"(packed_base + ceil(n/2)); the DBC's 6-axis setup has "
                                  f"0x{commit.frame_id:03X}")
            self.npos = npos
            ids = list(self.pos) + [self.commit_id]
            self.frames_per_cycle = npos + 1
        elif profile == "fd":
            m = msg("FD_SETPOINT")
            if not m.is_fd:
                raise UsageError(f"{dbc_path}: FD_SETPOINT is not a CAN FD frame")
            field(m, "cycle", 0, False, "fd cycle counter")
            sigs = sorted((s for s in m.signals if s.name != "cycle"), key=lambda s: s.start)
            self.fd_fields = []
            for i in range(n):
                if i >= len(sigs):
                    raise UsageError(f"{dbc_path}: FD_SETPOINT has only {len(sigs)} axis fields")
                field(m, sigs[i].name, 32 + 32 * i, True, f"fd axis {i}")
                check_scale(sigs[i], i)
                check_letter(sigs[i], i)
                self.fd_fields.append(sigs[i].start // 8)
            check_id(m, setup.fd_id, "FD_ID")
            self.fd_id = setup.fd_id
            self.fd_len = fd_len(4 + 4 * n)
            self.fd_brs = setup.data_bitrate > setup.bitrate
            ids = [self.fd_id]
            self.frames_per_cycle = 1
        else:
            raise UsageError(f"unknown profile '{profile}' (cia402, packed, fd)")
        if len(set(ids)) != len(ids) or any(i > CAN_SFF_MASK for i in ids):
            raise UsageError(f"the {profile} ids of this config collide or exceed 0x7FF: "
                             f"{[hex(i) for i in ids]}")
        self.ids = ids

    def describe(self):
        s = self.setup
        if self.profile == "cia402":
            return {"sync_id": f"0x{self.sync_id:03X}",
                    "rpdo": {f"0x{k:03X}": s.axes[v[0]] for k, v in self.rpdo.items()}}
        if self.profile == "packed":
            return {"pos": {f"0x{k:03X}": [s.axes[a] for a, _ in v[1]] for k, v in self.pos.items()},
                    "commit": f"0x{self.commit_id:03X}"}
        return {"fd_id": f"0x{self.fd_id:03X}", "fd_len": self.fd_len, "brs": self.fd_brs}


# --------------------------------------------------------------------- decoders

MAX_EVENTS = 200
U32 = 1 << 32
BATCH = 512  # frames per recvmmsg


class Decoder:
    """Common state: decoded cycles and the anomaly counters."""

    def __init__(self, layout):
        self.L = layout
        self.n = layout.n
        self.full = (1 << self.n) - 1
        self.frames = 0          # every frame received
        self.ours = 0            # frames with one of the profile's ids
        self.foreign = Counter() # other ids -> count
        self.malformed = 0
        self.stray = 0
        self.incomplete = 0
        self.duplicates = 0
        self.gaps = 0            # cycles lost (counter jumps; cia402: missing SYNCs)
        self.gap_events = 0
        self.backwards = 0
        self.events = []
        self.batches = 0         # live: recvmmsg calls that returned frames
        self.fast_frames = 0     # live: frames decoded as whole regular cycles
        # decoded cycles
        self.cyc = []            # cycle numbers
        self.tns = []            # first-frame timestamps, ns
        self.counts = []         # tuples of n int32
        self.period_ts = []      # timestamps whose differences are the bus period

    def event(self, kind, t_ns, **kw):
        if len(self.events) < MAX_EVENTS:
            e = {"kind": kind, "t": t_ns / 1e9}
            e.update(kw)
            self.events.append(e)

    def finish(self):
        pass

    def extra(self):
        return {}

    # -- batches (live): whole regular cycles at C speed, the rest frame by frame
    def at_boundary(self):
        return True

    def fast(self, B, i, m):
        """Take m whole cycles from frame i of batch B if they are exactly
        what the profile sends (ids, lengths, frame kinds, counters); return
        the frames taken (m * frames_per_cycle) or 0."""
        return 0

    def feed_batch(self, B):
        P = self.L.frames_per_cycle
        k = B.k
        i = 0
        feed = self.feed
        self.batches += 1
        while i < k:
            if self.at_boundary():
                m = (k - i) // P
                if m and (self.fast(B, i, m) or (m > 1 and self.fast(B, i, 1))):
                    i += self._taken
                    self.fast_frames += self._taken
                    continue
            if B.raw_bad[i]:
                self.frames += 1
                self.foreign[B.ids[i]] += 1
            else:
                feed(B.t(i), B.ids[i], B.data(i), B.lens[i], B.isfd[i])
            i += 1


class Cia402Decoder(Decoder):
    def __init__(self, layout):
        super().__init__(layout)
        self.sync_id = layout.sync_id
        self.rpdo = layout.rpdo
        self.open = False
        self.seen = 0
        self.cur = [0] * self.n
        self.t_open = 0
        self.cycle = -1          # SYNCs seen - 1
        self.stray_seen = 0      # RPDOs since the last complete cycle, no SYNC
        self.missing_sync = 0
        self.missing_rpdo = 0
        self.duplicate_rpdo = 0
        self.unpack = struct.Struct("<i").unpack_from
        # what one period looks like: SYNC, then the RPDOs in axis order
        order = sorted(self.rpdo, key=lambda cid: self.rpdo[cid][0])
        assert all(self.rpdo[cid][1] == 0 for cid in order)
        self.slot = list(range(self.n))  # RPDO of axis a is frame 1 + a
        reps = BATCH // (self.n + 1) + 2
        self.pat_ids = ([self.sync_id] + order) * reps
        self.pat_lens = ([0] + [4] * self.n) * reps
        self.pat_mlen = [CAN_MTU] * ((self.n + 1) * reps)

    def feed(self, t, cid, data, ln, fd):
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
            self.foreign[cid] += 1
            return
        self.ours += 1
        if ln != 4 or fd:
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

    def at_boundary(self):
        return not self.open and not self.stray_seen

    def fast(self, B, i, m):
        P = self.L.frames_per_cycle
        end = i + m * P
        if B.ids[i:end] != self.pat_ids[:m * P] or B.lens[i:end] != self.pat_lens[:m * P] \
                or B.msglen[i:end] != self.pat_mlen[:m * P]:
            return 0
        n = self.n
        w0 = B.w[0]
        self.counts.extend(zip(*[w0[i + 1 + self.slot[a]:end:P] for a in range(n)]))
        ts = B.ts(i, end, P)
        self.tns.extend(ts)
        self.period_ts.extend(ts)
        c0 = self.cycle + 1
        self.cyc.extend(range(c0, c0 + m))
        self.cycle += m
        self.frames += m * P
        self.ours += m * P
        self._taken = m * P
        return m * P

    def finish(self):
        self.trailing_open = bool(self.open and self.seen)

    def extra(self):
        return {"syncs": self.cycle + 1, "missing_sync": self.missing_sync,
                "missing_rpdo": self.missing_rpdo, "duplicate_rpdo": self.duplicate_rpdo,
                "trailing_partial": int(getattr(self, "trailing_open", False))}


class CounterDecoder(Decoder):
    """Shared counter logic of packed and fd."""

    def __init__(self, layout):
        super().__init__(layout)
        self.last = None
        self.first_counter = None

    def counter(self, c, t, t_first):
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
        self.period_ts.append((c, t_first))
        return True


class PackedDecoder(CounterDecoder):
    def __init__(self, layout):
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
        self.pat_lens = [self.pos[cid][2] for cid in order] + [4]
        self.pat_lens *= reps
        self.pat_mlen = [CAN_MTU] * ((layout.npos + 1) * reps)

    def feed(self, t, cid, data, ln, fd):
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
                self.event("incomplete", t, cycle=c,
                           missing_pos=[k for k in range(self.L.npos) if not self.seen >> k & 1])
            elif new:
                self.cyc.append(c)
                self.tns.append(self.t_first)
                self.counts.append(tuple(self.cur))
            self.seen = 0
            return
        p = self.pos.get(cid)
        if p is None:
            self.foreign[cid] += 1
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

    def at_boundary(self):
        return not self.seen

    def fast(self, B, i, m):
        P = self.L.frames_per_cycle
        end = i + m * P
        if B.ids[i:end] != self.pat_ids[:m * P] or B.lens[i:end] != self.pat_lens[:m * P] \
                or B.msglen[i:end] != self.pat_mlen[:m * P]:
            return 0
        npos = self.L.npos
        counters = B.w[0][i + npos:end:P]
        last = self.last
        c0 = counters[0] if last is None else last + 1
        if c0 + m > U32 or counters != list(range(c0, c0 + m)):
            return 0  # a gap, a duplicate or a wrap: frame by frame
        if last is None:
            self.first_counter = c0
        cols = []
        for a in range(self.n):
            cols.append(B.w[a % 2][i + a // 2:end:P])
        self.counts.extend(zip(*cols))
        ts = B.ts(i, end, P)
        self.tns.extend(ts)
        self.period_ts.extend(zip(counters, ts))
        self.cyc.extend(counters)
        self.last = counters[-1]
        self.frames += m * P
        self.ours += m * P
        self._taken = m * P
        return m * P

    def finish(self):
        self.trailing = bool(self.seen)
        if self.seen:
            self.stray += bin(self.seen).count("1")

    def extra(self):
        return {"commit_lost": self.commit_lost, "first_counter": self.first_counter,
                "last_counter": self.last, "trailing_partial": int(getattr(self, "trailing", False))}


class FdDecoder(CounterDecoder):
    def __init__(self, layout):
        super().__init__(layout)
        self.fd_id = layout.fd_id
        self.fd_len = layout.fd_len
        self.unpack = struct.Struct("<I" + "i" * self.n).unpack_from
        assert layout.fd_fields == [4 + 4 * i for i in range(self.n)]
        self.pat_ids = [self.fd_id] * (BATCH + 1)
        self.pat_lens = [self.fd_len] * (BATCH + 1)
        self.pat_mlen = [CANFD_MTU] * (BATCH + 1)

    def feed(self, t, cid, data, ln, fd):
        self.frames += 1
        if cid != self.fd_id:
            self.foreign[cid] += 1
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

    def fast(self, B, i, m):
        end = i + m
        if B.ids[i:end] != self.pat_ids[:m] or B.lens[i:end] != self.pat_lens[:m] \
                or B.msglen[i:end] != self.pat_mlen[:m]:
            return 0
        counters = B.w[0][i:end]
        last = self.last
        c0 = counters[0] if last is None else last + 1
        if c0 + m > U32 or counters != list(range(c0, c0 + m)):
            return 0
        if last is None:
            self.first_counter = c0
        self.counts.extend(zip(*[B.w[1 + a][i:end] for a in range(self.n)]))
        ts = B.ts(i, end, 1)
        self.tns.extend(ts)
        self.period_ts.extend(zip(counters, ts))
        self.cyc.extend(counters)
        self.last = counters[-1]
        self.frames += m
        self.ours += m
        self._taken = m
        return m

    def extra(self):
        return {"first_counter": self.first_counter, "last_counter": self.last}


DECODERS = {"cia402": Cia402Decoder, "packed": PackedDecoder, "fd": FdDecoder}


# --------------------------------------------------------------------- sources

_stop = False


def _on_signal(sig, frame):
    global _stop
    _stop = True


def open_socket(iface, rcvbuf, want_fd, use_python_can=False):
    """A raw CAN socket bound to iface, CAN FD frames on, kernel timestamps
    (SO_TIMESTAMPNS) and the drop counter (SO_RXQ_OVFL) enabled, a large
    receive buffer. By default it is made with the standard library's socket
    module (AF_CAN, exactly what python-can's socketcan interface does):
    importing python-can costs tens of seconds in the emulated VM.
    use_python_can: open it through can.Bus(interface="socketcan") instead;
    the hot loop is the same (recvmsg on the bus's socket) unless --python-can-recv.
    Returns (closer, socket, info)."""
    info = {"rcvbuf_requested": rcvbuf}
    if use_python_can:
        import can

        try:
            bus = can.Bus(interface="socketcan", channel=iface, fd=True,
                          receive_own_messages=False)
        except (OSError, can.CanError) as e:
            raise RuntimeError(f"cannot open {iface}: {e}")
        sock = bus.socket
        closer = bus
        info["opened_by"] = f"python-can {can.__version__}"
    else:
        if not hasattr(socket, "AF_CAN"):
            raise RuntimeError("this Python has no AF_CAN support")
        try:
            sock = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
        except OSError as e:
            raise RuntimeError(f"socket(AF_CAN): {e}"
                               + (" (this kernel has no CAN: run through tools/vcan/run.sh)"
                                  if e.errno == errno.EAFNOSUPPORT else ""))
        try:
            sock.setsockopt(socket.SOL_CAN_RAW, socket.CAN_RAW_FD_FRAMES, 1)
            sock.bind((iface,))
        except OSError as e:
            sock.close()
            raise RuntimeError(f"cannot bind to {iface}: {e}")
        closer = sock
        info["opened_by"] = "socket (stdlib)"
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
    sock.settimeout(None)  # blocking; SO_RCVTIMEO wakes us to check for a stop
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, struct.pack("ll", 0, 100000))
    try:
        mtu = int(Path(f"/sys/class/net/{iface}/mtu").read_text())
        info["mtu"] = mtu
        if want_fd and mtu != CANFD_MTU:
            info["warning"] = f"{iface} mtu {mtu}: CAN FD frames cannot pass (ip link set {iface} mtu 72)"
    except OSError:
        pass
    return closer, sock, info


def run_python_can(bus, dec, frames_out, deadline_mono):
    """python-can's own receive path (Bus.recv, one can.Message per frame), for
    comparison with the recvmsg hot loop (--python-can-recv)."""
    feed = dec.feed
    keep = frames_out.append if frames_out is not None else None
    mono = time.monotonic
    while not _stop and (deadline_mono is None or mono() < deadline_mono):
        m = bus.recv(timeout=0.1)
        if m is None:
            continue
        t = int(m.timestamp * 1e9)
        data = bytes(m.data)
        raw_id = m.arbitration_id | (CAN_EFF_FLAG if m.is_extended_id else 0) | \
            (CAN_RTR_FLAG if m.is_remote_frame else 0) | (CAN_ERR_FLAG if m.is_error_frame else 0)
        fl = ((CANFD_BRS if m.bitrate_switch else 0) | (CANFD_ESI if m.error_state_indicator else 0)) \
            if m.is_fd else None
        if keep is not None:
            keep((t, raw_id, fl, data))
        if raw_id & (CAN_ERR_FLAG | CAN_RTR_FLAG | CAN_EFF_FLAG):
            dec.frames += 1
            dec.foreign[raw_id] += 1
        else:
            feed(t, raw_id, data, len(data), m.is_fd)
    return None


class MMsg:
    """recvmmsg(2) through ctypes: up to BATCH frames per system call into one
    flat buffer, each with its own control buffer (the SO_TIMESTAMPNS
    timestamp, and the SO_RXQ_OVFL drop counter when there were drops). The
    fields of all frames are then read as strided slices of memoryviews (C
    speed, no per-frame Python work) by Batch."""

    HDR = 64   # sizeof(struct mmsghdr) on LP64: msghdr 56 + msg_len 4 + pad
    CTL = 64   # control buffer per frame: timestamp cmsg 32 + drop counter cmsg 24

    def __init__(self, sock, n=BATCH):
        import ctypes

        if struct.calcsize("P") != 8:
            raise OSError("recvmmsg layout assumes a 64-bit ABI")
        libc = ctypes.CDLL(None, use_errno=True)
        self._recvmmsg = libc.recvmmsg
        self._recvmmsg.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_uint, ctypes.c_int,
                                   ctypes.c_void_p]
        self._recvmmsg.restype = ctypes.c_int
        self.ctypes = ctypes
        self.fd = sock.fileno()
        self.n = n
        self.frames = bytearray(n * CANFD_MTU)
        self.ctl = bytearray(n * self.CTL)
        self.iov = bytearray(n * 16)
        self.hdr = bytearray(n * self.HDR)
        addr = lambda b: ctypes.addressof((ctypes.c_char * len(b)).from_buffer(b))
        fa, ca, ia = addr(self.frames), addr(self.ctl), addr(self.iov)
        for j in range(n):
            struct.pack_into("=QQ", self.iov, 16 * j, fa + j * CANFD_MTU, CANFD_MTU)
            # msghdr: name, namelen(+pad), iov, iovlen, control, controllen, flags(+pad)
            struct.pack_into("=QQQQQQQ", self.hdr, self.HDR * j, 0, 0, ia + 16 * j, 1,
                             ca + j * self.CTL, self.CTL, 0)
        self.pristine = bytes(self.hdr)
        self.hdr_addr = addr(self.hdr)
        self.pristine_buf = ctypes.create_string_buffer(self.pristine, len(self.pristine))
        self.fv = memoryview(self.frames)
        self.fw = self.fv.cast("i")   # signed 32-bit words of the frames
        self.fu = self.fv.cast("I")
        self.hv = memoryview(self.hdr).cast("I")
        self.cv = memoryview(self.ctl).cast("q")
        self.ci = memoryview(self.ctl).cast("i")
        self.cu = memoryview(self.ctl).cast("I")

    def recv(self, block=True):
        """Frames received (0: timeout, signal or nothing queued)."""
        ctypes = self.ctypes
        ctypes.memmove(self.hdr_addr, self.pristine_buf, len(self.pristine))
        flags = 0x10000 if block else socket.MSG_DONTWAIT  # MSG_WAITFORONE
        r = self._recvmmsg(self.fd, self.hdr_addr, self.n, flags, None)
        if r < 0:
            e = ctypes.get_errno()
            if e in (errno.EAGAIN, errno.EINTR):
                return 0
            raise OSError(e, os.strerror(e))
        return r


class Batch:
    """The k frames of one recvmmsg as lists (C-speed strided slices)."""

    def __init__(self, mm, k, nwords):
        self.k = k
        self.mm = mm
        fu, fw = mm.fu, mm.fw
        self.ids = fu[0:k * 18:18].tolist()
        self.lens = mm.fv[4:k * CANFD_MTU:CANFD_MTU].tolist()
        self.msglen = mm.hv[14:k * 16:16].tolist()
        self.w = [fw[2 + j:k * 18:18].tolist() for j in range(nwords)]
        # timestamps: first cmsg of each control buffer is SO_TIMESTAMPNS
        self.sec = mm.cv[2:k * 8:8].tolist()
        self.nsec = mm.cv[3:k * 8:8].tolist()
        ctl_len = mm.hv[10:k * 16:16].tolist()  # msg_controllen (low word)
        self.drops = None
        if min(ctl_len) < 32 or mm.ci[3:k * 16:16].tolist().count(SO_TIMESTAMPNS) != k:
            types = mm.ci[3:k * 16:16].tolist()
            now = time.time_ns()
            for j in range(k):
                if ctl_len[j] < 32 or types[j] != SO_TIMESTAMPNS:
                    self.sec[j], self.nsec[j] = divmod(now, 1000000000)
        if max(ctl_len) > 32:
            for j in range(k):
                if ctl_len[j] > 32 and mm.ci[j * 16 + 11] == SO_RXQ_OVFL:
                    self.drops = mm.cu[j * 16 + 12]
        self.fv = mm.fv
        self._isfd = self._bad = None

    @property
    def isfd(self):
        if self._isfd is None:
            self._isfd = [v == CANFD_MTU for v in self.msglen]
        return self._isfd

    @property
    def raw_bad(self):  # EFF, RTR, ERR flags
        if self._bad is None:
            self._bad = [r & 0xE0000000 for r in self.ids]
        return self._bad

    @property
    def flags(self):
        return self.fv[5:self.k * CANFD_MTU:CANFD_MTU].tolist()

    def t(self, j):
        return self.sec[j] * 1000000000 + self.nsec[j]

    def ts(self, i, end, step):
        return [s * 1000000000 + n for s, n in zip(self.sec[i:end:step], self.nsec[i:end:step])]

    def data(self, j):
        o = j * CANFD_MTU + 8
        return bytes(self.fv[o:o + self.lens[j]])

    def keep(self):
        """What --log needs, copied: (raw ids, lens, msg lengths, sec, nsec, frames)."""
        return (self.ids, self.lens, self.msglen, self.sec, self.nsec,
                bytes(self.fv[:self.k * CANFD_MTU]))


def expand_kept(kept):
    """Frames kept by the batch receiver -> (t, raw_id, fd flags or None, data)."""
    for ids, lens, msglen, sec, nsec, buf in kept:
        for j in range(len(ids)):
            o = j * CANFD_MTU + 8
            yield (sec[j] * 1000000000 + nsec[j], ids[j],
                   buf[o - 3] if msglen[j] == CANFD_MTU else None, buf[o:o + lens[j]])


def run_live_batch(sock, dec, kept, deadline_mono, nwords, gather_s=0.01):
    """The hot path: recvmmsg batches, regular cycles decoded by slicing.
    After a batch that did not fill the buffer, sleep gather_s so that the
    next call finds many frames queued (the socket buffer holds them; their
    timestamps are the kernel's): the cost per call, large in an emulated VM,
    is then shared by tens of frames instead of one or four."""
    mm = MMsg(sock)
    drops = 0
    mono = time.monotonic
    sleep = time.sleep
    while True:
        k = mm.recv()
        if k:
            B = Batch(mm, k, nwords)
            if B.drops is not None:
                drops = B.drops
            if kept is not None:
                kept.append(B.keep())
            dec.feed_batch(B)
        if _stop or (deadline_mono is not None and mono() >= deadline_mono):
            break
        if 0 < k < mm.n:
            sleep(gather_s)
    while True:  # drain what is already queued: a stop loses nothing already here
        k = mm.recv(block=False)
        if not k:
            break
        B = Batch(mm, k, nwords)
        if B.drops is not None:
            drops = B.drops
        if kept is not None:
            kept.append(B.keep())
        dec.feed_batch(B)
    return drops


def run_live(sock, dec, frames_out, deadline_mono, iface):
    """The hot path: one recvmsg per frame, the kernel timestamp from the
    ancillary data, decode with struct. Returns (drops, wall seconds)."""
    recvmsg = sock.recvmsg
    anc_size = socket.CMSG_SPACE(16) + socket.CMSG_SPACE(4)
    ts_unpack = struct.Struct("@qq").unpack_from
    hdr_unpack = struct.Struct("=IB B").unpack_from
    u32 = struct.Struct("=I").unpack_from
    feed = dec.feed
    keep = frames_out.append if frames_out is not None else None
    drops = 0
    mono = time.monotonic

    def handle(data, anc):
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
            keep((t, raw_id, fl if fd else None, bytes(data[8:8 + ln])))
        if raw_id & (CAN_ERR_FLAG | CAN_RTR_FLAG | CAN_EFF_FLAG):
            dec.frames += 1
            dec.foreign[raw_id] += 1
        else:
            feed(t, raw_id, data[8:8 + ln], ln, fd)

    while True:
        try:
            data, anc, _flags, _addr = recvmsg(CANFD_MTU, anc_size)
        except BlockingIOError:  # SO_RCVTIMEO: nothing for 100 ms
            if _stop or (deadline_mono is not None and mono() >= deadline_mono):
                break
            continue
        handle(data, anc)
        if _stop:
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


def parse_log_line(line):
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
    rest = line[close + 1:].split()
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


def run_log(path, dec, frames_out, want_iface=None):
    keep = frames_out.append if frames_out is not None else None
    feed = dec.feed
    with open(path) as fh:
        for lineno, line in enumerate(fh, 1):
            try:
                r = parse_log_line(line)
            except (ValueError, IndexError) as e:
                raise RuntimeError(f"{path}:{lineno}: not candump -l format: {e}")
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
            if _stop:
                break


# --------------------------------------------------------------------- outputs

def fmt_ts(t_ns, digits=6):
    s, ns = divmod(t_ns, 1000000000)
    if digits == 6:
        return f"{s}.{ns // 1000:06d}"
    return f"{s}.{ns:09d}"


def write_log(path, frames, iface):
    with open(path, "w") as fh:
        w = fh.write
        for t, raw_id, fl, data in frames:
            if raw_id & CAN_ERR_FLAG or raw_id & CAN_EFF_FLAG:
                cid = f"{raw_id & (CAN_EFF_MASK | CAN_ERR_FLAG):08X}"
            else:
                cid = f"{raw_id & CAN_SFF_MASK:03X}"
            if fl is not None:
                w(f"({fmt_ts(t)}) {iface} {cid}##{fl & 0xF:X}{data.hex().upper()}\n")
            elif raw_id & CAN_RTR_FLAG:
                w(f"({fmt_ts(t)}) {iface} {cid}#R\n")
            else:
                w(f"({fmt_ts(t)}) {iface} {cid}#{data.hex().upper()}\n")


def write_csv(path, dec, setup):
    axes = [a.lower() for a in setup.axes]
    cpu = setup.cpu
    n = len(axes)
    with open(path, "w") as fh:
        fh.write(",".join(["cycle", "t"] + axes + ["c" + a for a in axes]) + "\n")
        w = fh.write
        for c, t, cnt in zip(dec.cyc, dec.tns, dec.counts):
            w(f"{c},{fmt_ts(t, 9)}," + ",".join(repr(cnt[i] / cpu[i]) for i in range(n)) + ","
              + ",".join(str(v) for v in cnt) + "\n")


def percentile(sorted_vals, q):
    """Nearest-rank percentile (q in 0..100) of a sorted list."""
    if not sorted_vals:
        return None
    k = max(0, min(len(sorted_vals) - 1, math.ceil(q / 100.0 * len(sorted_vals)) - 1))
    return sorted_vals[k]


def timing(dec, profile, period_s):
    """Period as seen on the bus: differences of SYNC timestamps (cia402) or of
    the first-frame timestamps of consecutive counter values (packed, fd)."""
    if profile == "cia402":
        ts = dec.period_ts
        iv = [b - a for a, b in zip(ts, ts[1:])]
        what = "SYNC to SYNC"
    else:
        iv = []
        pts = dec.period_ts
        for (c0, t0), (c1, t1) in zip(pts, pts[1:]):
            if (c1 - c0) % U32 == 1:
                iv.append(t1 - t0)
        what = "first frame of cycle k to cycle k+1 (consecutive counters)"
    out = {"what": what, "nominal_us": period_s * 1e6, "intervals": len(iv)}
    if not iv:
        return out
    s = sorted(iv)
    us = lambda v: None if v is None else round(v / 1000.0, 3)
    mean = sum(s) / len(s)
    var = sum((v - mean) ** 2 for v in s) / len(s)
    nom = period_s * 1e9
    hist = Counter(v // 1000 for v in s)  # 1-us bins, [k, k+1) us
    bins = sorted(hist.items())
    within = lambda d: sum(1 for v in s if abs(v - nom) <= d * 1000) / len(s)
    top = hist.most_common(10)
    out.update({
        "min_us": us(s[0]), "p50_us": us(percentile(s, 50)), "p99_us": us(percentile(s, 99)),
        "p99_9_us": us(percentile(s, 99.9)), "max_us": us(s[-1]),
        "mean_us": round(mean / 1000.0, 3), "std_us": round(math.sqrt(var) / 1000.0, 3),
        "within_10us": round(within(10), 6), "within_100us": round(within(100), 6),
        "within_500us": round(within(500), 6),
        "over_2x": sum(1 for v in s if v > 2 * nom),
        "histogram": {
            "bin_us": 1,
            "note": "bin k counts intervals in [k, k+1) us",
            "bins_used": len(bins),
            "top": [[int(k), c] for k, c in top],
            "bins": [[int(k), c] for k, c in bins],
        },
    })
    return out


def position_record(dec, setup, idx):
    c = dec.counts[idx]
    return {"cycle": dec.cyc[idx], "t": dec.tns[idx] / 1e9,
            "pos": {a: c[i] / setup.cpu[i] for i, a in enumerate(setup.axes)},
            "counts": {a: c[i] for i, a in enumerate(setup.axes)}}


# --------------------------------------------------------------------- main

def main(argv=None):
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    src = ap.add_mutually_exclusive_group()
    src.add_argument("--can", metavar="IFACE", help="SocketCAN interface to listen on, e.g. vcan0")
    src.add_argument("--from-log", metavar="FILE", help="candump -l/-L log to decode instead")
    ap.add_argument("--config", metavar="FILE", help="machine INI (axes, CAN_NODE, COUNTS_PER_UNIT, [CAN])")
    ap.add_argument("--profile", choices=sorted(DECODERS), help="output profile (default: [CAN] PROFILE)")
    ap.add_argument("--dbc", metavar="FILE", default=str(DEFAULT_DBC), help="frame layouts (default tools/mlip.dbc)")
    ap.add_argument("--csv", metavar="OUT", help="decoded cycles: cycle,t,x,...,cx,...")
    ap.add_argument("--log", metavar="OUT", help="every frame, candump -l format")
    ap.add_argument("--json", metavar="OUT", help="the report as JSON ('-': stdout)")
    ap.add_argument("--duration", metavar="S", type=float, help="stop after S seconds (live)")
    ap.add_argument("--rcvbuf", metavar="BYTES", type=int, default=16 << 20,
                    help="socket receive buffer (default 16 MiB)")
    ap.add_argument("--log-iface", metavar="NAME", help="--from-log: only frames of this interface")
    ap.add_argument("--python-can", action="store_true",
                    help="open the socket through python-can's can.Bus (slow to import)")
    ap.add_argument("--python-can-recv", action="store_true",
                    help="and receive with Bus.recv() instead of the recvmsg loop (for comparison)")
    ap.add_argument("--no-batch", action="store_true",
                    help="one recvmsg per frame instead of recvmmsg batches (for comparison)")
    ap.add_argument("--dbc-cache", metavar="DIR", default=str(ROOT / "build"),
                    help="where the layout read from the DBC is cached (default build/; '' : none)")
    ap.add_argument("--check-layout", action="store_true",
                    help="read the DBC (filling the cache), check it against the config, print "
                         "the layout as JSON and exit (no --can/--from-log needed)")
    ap.add_argument("-q", "--quiet", action="store_true", help="no summary line")
    a = ap.parse_args(argv)

    try:
        setup = Setup.from_ini(a.config) if a.config else Setup()
        profile = a.profile or setup.profile
        layout = Layout(setup, profile, a.dbc, a.dbc_cache or None)
    except UsageError as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 2
    if a.check_layout:
        print(json.dumps({"profile": profile, "config": setup.source, "dbc": layout.dbc,
                          "dbc_read_by": layout.dbc_source, "axes": setup.axes,
                          "layout": layout.describe(), "dbc_notes": layout.notes}, indent=1))
        return 0
    if not a.can and not a.from_log:
        ap.error("one of --can IFACE or --from-log FILE is required")
    dec = DECODERS[profile](layout)
    frames = [] if a.log else None
    signal.signal(signal.SIGTERM, _on_signal)
    signal.signal(signal.SIGINT, _on_signal)

    report = {"tool": PROG, "profile": profile, "config": setup.source, "dbc": layout.dbc,
              "dbc_read_by": layout.dbc_source,
              "axes": setup.axes, "nodes": setup.nodes, "counts_per_unit": setup.cpu,
              "period_s": setup.period_s, "frames_per_cycle": layout.frames_per_cycle,
              "layout": layout.describe(), "dbc_notes": layout.notes}
    cpu0 = os.times()
    t0 = time.monotonic()
    iface = a.can or "vcan0"
    try:
        if a.can:
            if a.python_can_recv:
                a.python_can = True
            closer, sock, info = open_socket(a.can, a.rcvbuf, profile == "fd", a.python_can)
            report["source"] = a.can
            report["socket"] = info
            if "warning" in info:
                print(f"{PROG}: warning: {info['warning']}", file=sys.stderr)
            print(f"{PROG}: listening on {a.can} ({profile}, {len(setup.axes)} axes "
                  f"{''.join(setup.axes)}, rcvbuf {info['rcvbuf_bytes']} bytes)",
                  file=sys.stderr, flush=True)
            t0 = time.monotonic()
            cpu0 = os.times()
            deadline = t0 + a.duration if a.duration else None
            try:
                if a.python_can_recv:
                    drops = run_python_can(closer, dec, frames, deadline)
                    report["receive"] = "python-can Bus.recv"
                elif a.no_batch:
                    drops = run_live(sock, dec, frames, deadline, a.can)
                    report["receive"] = "recvmsg per frame"
                else:
                    kept = [] if frames is not None else None
                    nwords = {"cia402": 1, "packed": 2, "fd": 1 + len(setup.axes)}[profile]
                    drops = run_live_batch(sock, dec, kept, deadline, nwords)
                    if kept is not None:
                        frames = expand_kept(kept)
                    report["receive"] = f"recvmmsg, up to {BATCH} frames per call"
            finally:
                closer.shutdown() if a.python_can else closer.close()
            report["socket_drops"] = drops
        else:
            report["source"] = a.from_log
            run_log(a.from_log, dec, frames, a.log_iface)
            report["socket_drops"] = None
            if frames:
                iface = a.log_iface or "vcan0"
    except (RuntimeError, OSError) as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1
    wall = time.monotonic() - t0
    cpu1 = os.times()
    cpu_user, cpu_sys = cpu1.user - cpu0.user, cpu1.system - cpu0.system
    cpu = cpu_user + cpu_sys
    dec.finish()

    n_cyc = len(dec.cyc)
    report.update({
        "wall_s": round(wall, 3), "cpu_s": round(cpu, 3),
        "cpu_user_s": round(cpu_user, 3), "cpu_sys_s": round(cpu_sys, 3),
        "frames": dec.frames, "frames_ours": dec.ours,
        "foreign": sum(dec.foreign.values()),
        "foreign_ids": {f"0x{k:X}": v for k, v in sorted(dec.foreign.items())},
        "malformed": dec.malformed,
        "cycles": n_cyc,
        "first_cycle": dec.cyc[0] if n_cyc else None,
        "last_cycle": dec.cyc[-1] if n_cyc else None,
        "gaps": dec.gaps, "gap_events": dec.gap_events,
        "incomplete": dec.incomplete, "duplicates": dec.duplicates,
        "backwards": dec.backwards, "stray": dec.stray,
    })
    if dec.batches:
        report["batches"] = dec.batches
        report["frames_per_batch"] = round(dec.frames / dec.batches, 1)
        report["fast_path_frames"] = dec.fast_frames
    report.update(dec.extra())
    if wall > 0:
        report["frames_per_s"] = round(dec.frames / wall, 1)
        report["cpu_per_frame_us"] = round(cpu / dec.frames * 1e6, 2) if dec.frames else None
    report["timing"] = timing(dec, profile, setup.period_s)
    report["first"] = position_record(dec, setup, 0) if n_cyc else None
    report["last"] = position_record(dec, setup, -1) if n_cyc else None
    report["events"] = dec.events
    ok = (dec.gaps == 0 and dec.incomplete == 0 and dec.stray == 0 and dec.duplicates == 0
          and dec.malformed == 0 and dec.backwards == 0 and not report.get("socket_drops"))
    report["clean"] = ok

    try:
        if a.csv:
            write_csv(a.csv, dec, setup)
        if a.log:
            write_log(a.log, frames, iface)
        if a.json:
            text = json.dumps(report, indent=1) + "\n"
            if a.json == "-":
                sys.stdout.write(text)
            else:
                Path(a.json).write_text(text)
    except OSError as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1

    if not a.quiet:
        tm = report["timing"]
        per = (f"period p50 {tm['p50_us']} us p99 {tm['p99_us']} us max {tm['max_us']} us"
               if tm.get("intervals") else "period: n/a")
        last = ""
        if n_cyc:
            last = " last " + " ".join(f"{k}={v:g}" for k, v in report["last"]["pos"].items())
        drops = report.get("socket_drops")
        print(f"{PROG}: {report['source']} {profile}: {dec.frames} frames, {n_cyc} cycles, "
              f"{dec.gaps} lost, {dec.incomplete} incomplete, {dec.duplicates} duplicate, "
              f"{dec.stray} stray, {dec.malformed} malformed, "
              f"{'n/a' if drops is None else drops} socket drops; {per};{last}",
              file=sys.stdout if a.json != "-" else sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
