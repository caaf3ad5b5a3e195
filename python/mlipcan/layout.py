"""Frame layouts of mlip's setpoint streams, read from tools/mlip.dbc with
cantools (cached in build/ under the DBC's SHA-256: cantools costs tens of
seconds to import in the emulated test VM) and checked against the machine
config. Offsets are byte offsets into the data."""

import hashlib
import json
import os
import socket
from pathlib import Path
from typing import Any, NamedTuple

from .config import Setup, StrPath, UsageError

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


def fd_len(n: int) -> int:
    """The CAN FD data length that holds n bytes (-1: more than 64)."""
    for ln in FD_LENS:
        if ln >= n:
            return ln
    return -1


class Signal(NamedTuple):
    """What the listener needs of a DBC signal."""

    name: str
    start: int
    length: int
    byte_order: str
    is_signed: bool
    scale: float


class Message(NamedTuple):
    """What the listener needs of a DBC message."""

    name: str
    frame_id: int
    length: int
    is_fd: bool
    signals: tuple[Signal, ...]


def _message(d: dict[str, Any]) -> Message:
    sigs = tuple(Signal(**sd) for sd in d["signals"])
    return Message(d["name"], d["frame_id"], d["length"], bool(d["is_fd"]), sigs)


def load_dbc(path: StrPath, cache_dir: StrPath | None = None) -> tuple[list[Message], str]:
    """The DBC's messages as plain records (name, frame_id, length, is_fd,
    signals: name, start, length, byte_order, is_signed, scale), read with
    cantools. cantools (which imports python-can) takes tens of seconds to
    import in the software-emulated test VM, so the extraction is cached in
    cache_dir keyed by the DBC's SHA-256: the same file gives the same
    records. Returns (messages, "cantools" | "cache FILE")."""
    try:
        raw = Path(path).read_bytes()
    except OSError as e:
        raise UsageError(f"{path}: {e}") from e
    digest = hashlib.sha256(raw).hexdigest()
    cache = Path(cache_dir) / f"mlip-listen-dbc-{digest[:16]}.json" if cache_dir else None
    if cache is not None:
        try:
            d = json.loads(cache.read_text())
            if d.get("sha256") == digest:
                return [_message(m) for m in d["messages"]], f"cache {cache}"
        except (OSError, ValueError, KeyError, TypeError):
            pass
    import cantools  # start-up only

    try:
        db = cantools.database.load_string(raw.decode("utf-8"), database_format="dbc", strict=True)
    except Exception as e:  # cantools raises many kinds
        raise UsageError(f"{path}: {e}") from e
    if not isinstance(db, cantools.database.can.Database):
        raise UsageError(f"{path}: not a CAN database")
    out = [
        {
            "name": m.name,
            "frame_id": m.frame_id,
            "length": m.length,
            "is_fd": bool(m.is_fd),
            "signals": [
                {
                    "name": s.name,
                    "start": s.start,
                    "length": s.length,
                    "byte_order": s.byte_order,
                    "is_signed": bool(s.is_signed),
                    "scale": float(s.scale),
                }
                for s in m.signals
            ],
        }
        for m in db.messages
    ]
    if cache is not None:
        try:
            cache.parent.mkdir(parents=True, exist_ok=True)
            tmp = cache.with_suffix(f".tmp{os.getpid()}")
            tmp.write_text(json.dumps({"sha256": digest, "dbc": str(path), "messages": out}))
            os.replace(tmp, cache)
        except OSError:
            pass
    return [_message(m) for m in out], "cantools"


def prime_cache(dbc: StrPath, cache_dir: StrPath) -> str:
    """Read the DBC with cantools once, so that listener processes find its
    layout in the cache and skip the (slow in the VM) cantools import.
    Returns where it was read from ("cantools" or "cache FILE")."""
    return load_dbc(dbc, cache_dir)[1]


class Layout:
    """Frame layouts for one profile and machine, taken from the DBC and
    checked against the config. Offsets are byte offsets into the data."""

    # the fields of each profile (set by __init__ for its profile only)
    sync_id: int
    rpdo: dict[int, tuple[int, int]]  # id -> (axis index, byte offset of the target)
    rpdo_len: int
    pos: dict[int, tuple[int, tuple[tuple[int, int], ...], int]]  # id -> (k, fields, length)
    commit_id: int
    npos: int
    fd_fields: list[int]
    fd_id: int
    fd_len: int
    fd_brs: bool

    def __init__(
        self, setup: Setup, profile: str, dbc_path: StrPath, cache_dir: StrPath | None = None
    ) -> None:
        self.setup = setup
        self.profile = profile
        self.n = n = len(setup.axes)
        self.notes: list[str] = []
        messages, self.dbc_source = load_dbc(dbc_path, cache_dir)
        self.dbc = str(dbc_path)
        by_name = {m.name: m for m in messages}

        def msg(name: str) -> Message:
            if name not in by_name:
                raise UsageError(f"{dbc_path}: no message {name} (needed by the {profile} profile)")
            return by_name[name]

        def field(m: Message, sig_name: str, start: int, signed: bool, what: str) -> Signal:
            """Check that m carries sig_name as a little-endian 32-bit field at
            bit `start` with the given signedness; return its byte offset."""
            sigs = {s.name: s for s in m.signals}
            if sig_name not in sigs:
                raise UsageError(f"{dbc_path}: {m.name} has no signal {sig_name} ({what})")
            s = sigs[sig_name]
            if (s.start, s.length, s.byte_order, bool(s.is_signed)) != (
                start,
                32,
                "little_endian",
                signed,
            ):
                raise UsageError(
                    f"{dbc_path}: {m.name}.{sig_name} is {s.length} bits at bit {s.start}, "
                    f"{s.byte_order}, {'signed' if s.is_signed else 'unsigned'}; canenc.h "
                    f"and this listener expect 32 bits at bit {start}, little_endian, "
                    f"{'signed' if signed else 'unsigned'} ({what})"
                )
            return s

        def check_id(m: Message, cfg_id: int, what: str) -> None:
            if m.frame_id != cfg_id:
                self.notes.append(
                    f"{m.name} is 0x{m.frame_id:03X} in the DBC, "
                    f"0x{cfg_id:03X} by the config ({what}): using the config's id"
                )

        def check_scale(sig: Signal, axis: int) -> None:
            cpu = setup.cpu[axis]
            if abs(sig.scale * cpu - 1.0) > 1e-12:
                self.notes.append(
                    f"{sig.name}: DBC factor {sig.scale} vs COUNTS_PER_UNIT {cpu:g} of axis "
                    f"{setup.axes[axis]}: positions use the config's counts"
                )

        def check_letter(sig: Signal, axis: int) -> None:
            want = setup.axes[axis] + "_target"
            if sig.name != want:
                self.notes.append(
                    f"the DBC's default setup calls this field {sig.name}; "
                    f"the config puts axis {setup.axes[axis]} there"
                )

        if profile == "cia402":
            sync = msg("SYNC")
            if sync.length != 0:
                raise UsageError(f"{dbc_path}: SYNC has length {sync.length}, canenc.h says 0")
            check_id(sync, setup.sync_id, "SYNC_ID")
            self.sync_id = setup.sync_id
            self.rpdo = {}  # id -> (axis index, byte offset)
            # The DBC describes the RPDO a CiA 402 drive brought up by mlip
            # receives: controlword 0x6040 (16 bits) then target 0x607A (32).
            # Without [DRIVES] ENABLE = 1 mlip-rt sends the target alone (4 bytes).
            self.rpdo_len = 6 if setup.drives else 4
            if not setup.drives:
                self.notes.append(
                    "target-only RPDOs (4 bytes, no [DRIVES] ENABLE = 1): the "
                    "target at byte 0, not after the DBC's controlword"
                )
            for i, node in enumerate(setup.nodes):
                m = msg(f"RPDO_NODE{node}")
                if m.length != 6:
                    raise UsageError(
                        f"{dbc_path}: {m.name} has length {m.length}, canenc.h says 6 "
                        f"(controlword + target)"
                    )
                sigs = {s.name: s for s in m.signals}
                cw = sigs.get("controlword")
                if cw is None or (cw.start, cw.length, cw.byte_order, bool(cw.is_signed)) != (
                    0,
                    16,
                    "little_endian",
                    False,
                ):
                    raise UsageError(
                        f"{dbc_path}: {m.name} needs a controlword: 16 bits at bit 0, "
                        f"little_endian, unsigned (0x6040)"
                    )
                tsig = [s for s in m.signals if s.name != "controlword"]
                if len(tsig) != 1:
                    raise UsageError(
                        f"{dbc_path}: {m.name} must carry the controlword and one target"
                    )
                sig = tsig[0]
                field(m, sig.name, 16, True, f"axis {setup.axes[i]}, node {node}")
                check_id(m, setup.rpdo_base + node, "RPDO_BASE + CAN_NODE")
                check_scale(sig, i)
                check_letter(sig, i)
                self.rpdo[setup.rpdo_base + node] = (i, sig.start // 8 if setup.drives else 0)
            ids = [self.sync_id] + list(self.rpdo)
            self.frames_per_cycle = 1 + n
        elif profile == "packed":
            npos = (n + 1) // 2
            self.pos = {}  # id -> (k, ((axis, offset), ...), length)
            pos0 = msg("PACKED_POS0")
            for k in range(npos):
                m = msg(f"PACKED_POS{k}")
                ordered = sorted(m.signals, key=lambda s: s.start)
                if m.length != 8 or len(ordered) != 2:
                    raise UsageError(f"{dbc_path}: {m.name} must be 8 bytes with two signals")
                fields: list[tuple[int, int]] = []
                for j, start in enumerate((0, 32)):
                    axis = 2 * k + j
                    field(m, ordered[j].name, start, True, f"packed frame {k}")
                    if axis < n:
                        check_scale(ordered[j], axis)
                        check_letter(ordered[j], axis)
                        fields.append((axis, start // 8))
                length = 8 if 2 * k + 1 < n else 4
                if length != m.length:
                    self.notes.append(
                        f"{m.name}: length {length} with {n} axes (the DBC's "
                        f"6-axis setup has {m.length})"
                    )
                check_id(m, setup.packed_base + k, "PACKED_BASE + k")
                self.pos[setup.packed_base + k] = (k, tuple(fields), length)
            commit = msg("PACKED_COMMIT")
            field(commit, "cycle", 0, False, "packed commit counter")  # checks it
            if commit.length != 4:
                raise UsageError(
                    f"{dbc_path}: PACKED_COMMIT has length {commit.length}, canenc.h says 4"
                )
            # the DBC describes 6 axes: its COMMIT follows its 3 POS frames
            if commit.frame_id - pos0.frame_id != 3:
                raise UsageError(f"{dbc_path}: PACKED_COMMIT is not PACKED_POS0 + ceil(6/2)")
            self.commit_id = setup.packed_base + npos
            if self.commit_id != commit.frame_id:
                self.notes.append(
                    f"PACKED_COMMIT is 0x{self.commit_id:03X} with {n} axes "
                    f"(packed_base + ceil(n/2)); the DBC's 6-axis setup has "
                    f"0x{commit.frame_id:03X}"
                )
            self.npos = npos
            ids = list(self.pos) + [self.commit_id]
            self.frames_per_cycle = npos + 1
        elif profile == "fd":
            m = msg("FD_SETPOINT")
            if not m.is_fd:
                raise UsageError(f"{dbc_path}: FD_SETPOINT is not a CAN FD frame")
            field(m, "cycle", 0, False, "fd cycle counter")
            ordered = sorted((s for s in m.signals if s.name != "cycle"), key=lambda s: s.start)
            self.fd_fields = []
            for i in range(n):
                if i >= len(ordered):
                    raise UsageError(f"{dbc_path}: FD_SETPOINT has only {len(ordered)} axis fields")
                field(m, ordered[i].name, 32 + 32 * i, True, f"fd axis {i}")
                check_scale(ordered[i], i)
                check_letter(ordered[i], i)
                self.fd_fields.append(ordered[i].start // 8)
            check_id(m, setup.fd_id, "FD_ID")
            self.fd_id = setup.fd_id
            self.fd_len = fd_len(4 + 4 * n)
            self.fd_brs = setup.data_bitrate > setup.bitrate
            ids = [self.fd_id]
            self.frames_per_cycle = 1
        else:
            raise UsageError(f"unknown profile '{profile}' (cia402, packed, fd)")
        if len(set(ids)) != len(ids) or any(i > CAN_SFF_MASK for i in ids):
            raise UsageError(
                f"the {profile} ids of this config collide or exceed 0x7FF: {[hex(i) for i in ids]}"
            )
        self.ids = ids

    def describe(self) -> dict[str, Any]:
        s = self.setup
        if self.profile == "cia402":
            return {
                "sync_id": f"0x{self.sync_id:03X}",
                "rpdo_len": self.rpdo_len,
                "rpdo": {f"0x{k:03X}": s.axes[v[0]] for k, v in self.rpdo.items()},
            }
        if self.profile == "packed":
            return {
                "pos": {f"0x{k:03X}": [s.axes[a] for a, _ in v[1]] for k, v in self.pos.items()},
                "commit": f"0x{self.commit_id:03X}",
            }
        return {"fd_id": f"0x{self.fd_id:03X}", "fd_len": self.fd_len, "brs": self.fd_brs}
