"""Simulated CiA 402 servo drives in cyclic synchronous position mode, on the
`canopen` package: each drive is a canopen.LocalNode (its SDO server, NMT
slave, heartbeat producer, EMCY producer and PDO maps are canopen's), plus the
drive profile on top: the CiA 402 power state machine driven by the
controlword, the statusword, modes of operation, and a position loop that
follows the target position with a lag on each SYNC.

An independent implementation to test mlip-rt's drive bring-up, supervision
and shut-down against (issue 10): nothing here is shared with the C side but
the standards (CiA 301, CiA 402). Every SDO write received, every NMT and
power state transition and every target applied at a SYNC is recorded for
the tests to judge (see Recorder).

The object dictionary is built in code (build_od); `mlip-drive-sim
--write-eds FILE` exports it as an EDS (canopen's exporter) for a master or
a person to read."""

import json
import math
import select
import socket
import struct
import sys
import threading
import time
from collections.abc import Iterable
from pathlib import Path
from typing import IO, Any, TypedDict, cast

from canopen.objectdictionary import ODRecord, ODVariable
from canopen.pdo.base import PdoMap
from canopen.sdo.exceptions import SdoAbortedError

import can
import canopen
from canopen import objectdictionary as odm

from . import cia402 as P
from .device import PDO_INVALID, SimDevice, SimNode, new_od, od_identity, od_record, od_var

# one drive at one SYNC (sync.csv): sync, node, t, state, controlword,
# target applied (None: no RPDO), an RPDO arrived since the previous SYNC,
# position actual and statusword sent
SyncRow = tuple[int, int, float, str | None, int, int | None, bool, int, int]
# one I/O module at one SYNC (io.csv): sync, node, t, outputs hex, inputs hex
IoRow = tuple[int, int, float, str, str]

U8, U16, U32 = odm.UNSIGNED8, odm.UNSIGNED16, odm.UNSIGNED32
I8, I32 = odm.INTEGER8, odm.INTEGER32
MODE_HOMING = 6  # 0x6060: homing mode
# homing methods this drive runs (CiA 402-2: 0x6098), each as (the switch
# searched, the direction toward it, then the encoder's index pulse): the
# switch's edge is found at the search speed 0x6099:1 toward it, braking at
# 0x609A past it, then back at the latch speed 0x6099:2 until it releases;
# that edge is home, or (index) the first index pulse beyond it in that
# direction. 1/2 the negative/positive limit switch and the index pulse;
# 3 the positive home switch (on at and above its edge) and the index pulse
# on its negative side, 5 the negative home switch (on at and below) and the
# index pulse on its positive side; 17/18/19/21 the same without the index
# (the edge is home); 33/34 the first index pulse in the negative/positive
# direction (at the latch speed); 35/37 the current position (37: CiA
# 402-2016's number for it, 35 obsolete). A drive already on the switch at
# the start moves off it at the latch speed (the edge it finds is the same).
HOMING_METHODS: dict[int, tuple[str | None, int, bool]] = {
    1: ("neg", -1, True),
    2: ("pos", 1, True),
    3: ("home", 1, True),
    5: ("nhome", -1, True),
    17: ("neg", -1, False),
    18: ("pos", 1, False),
    19: ("home", 1, False),
    21: ("nhome", -1, False),
    33: (None, -1, True),
    34: (None, 1, True),
    35: (None, 0, False),
    37: (None, 0, False),
}
SW_HOMING_ATTAINED = 1 << 12  # mode 6
SW_HOMING_ERROR = 1 << 13  # mode 6
FE_WINDOW_OFF = 0xFFFFFFFF  # 0x6065 = this: following error monitoring off (CiA 402)
MODE_PV = 3  # 0x6060: profile velocity mode (a spindle drive, issue 19)
SW_SPEED_ZERO = 1 << 12  # mode 3: |velocity actual| within the velocity window
PV_WINDOW_DEFAULT = 1000  # 0x606D, counts/s


def build_od(
    node_id: int,
    heartbeat_ms: int = 0,
    start_position: int = 0,
    fe_window: int = 10000,
    fe_time_ms: int = 10,
) -> odm.ObjectDictionary:
    """The object dictionary of one drive (CiA 301 communication area, CiA 402
    objects for CSP). Defaults: RPDO1 = controlword + target position, TPDO1 =
    statusword + position actual value, both synchronous (type 1), COB-IDs of
    the pre-defined connection set; the master (mlip-rt) writes them again."""
    od = new_od(node_id, "mlip (simulated drive)", "mlip-drive-sim CiA 402 CSP")

    def add(v: ODVariable) -> None:
        od.add_object(v)

    def record(name: str, index: int, members: list[tuple[str, int, str, int]]) -> None:
        od_record(od, name, index, members)

    add(od_var("Device type", 0x1000, 0, U32, "ro", 0x00020192, desc="CiA 402 servo drive"))
    add(od_var("Error register", 0x1001, 0, U8, "ro", 0))
    add(od_var("COB-ID SYNC", 0x1005, 0, U32, "rw", 0x80))
    add(od_var("COB-ID EMCY", 0x1014, 0, U32, "rw", 0x80 + node_id))
    # consumer heartbeat: sub n = node id << 16 | time ms (0: not used)
    record(
        "Consumer heartbeat time",
        0x1016,
        [("Consumer heartbeat time 1", U32, "rw", 0), ("Consumer heartbeat time 2", U32, "rw", 0)],
    )
    add(od_var("Producer heartbeat time", 0x1017, 0, U16, "rw", heartbeat_ms))
    od_identity(od, node_id)

    def pdo(kind: str, com: int, cob: int, entries: tuple[int, ...]) -> None:
        """PDO n: communication record (COB-ID, transmission type 1: synchronous)
        and mapping record (sub 0 = number of entries, 4 entries)."""
        num = (com & 0xFF) + 1
        record(
            f"{kind}{num} communication parameter",
            com,
            [(f"COB-ID used by {kind}", U32, "rw", cob), ("Transmission type", U8, "rw", 1)],
        )
        r = ODRecord(f"{kind}{num} mapping parameter", com + 0x200)
        r.add_member(od_var("Number of mapped objects", com + 0x200, 0, U8, "rw", len(entries)))
        for i, val in enumerate(entries + (0,) * (4 - len(entries)), 1):
            r.add_member(od_var(f"Mapped object {i}", com + 0x200, i, U32, "rw", val))
        od.add_object(r)

    pdo("RPDO", 0x1400, 0x200 + node_id, (0x60400010, 0x607A0020))
    pdo("TPDO", 0x1800, 0x180 + node_id, (0x60410010, 0x60640020))
    # TPDO2 (touch probe 1's latched positions), not valid until the master maps it
    pdo("TPDO", 0x1801, PDO_INVALID | 0x280 + node_id, (0x60BA0020, 0x60BB0020))
    # TPDO3: the digital inputs 0x60FD, event driven (on change, and every
    # event timer ms), invalid until the master enables it
    record(
        "TPDO3 communication parameter",
        0x1802,
        [
            ("COB-ID used by TPDO", U32, "rw", PDO_INVALID | 0x380 + node_id),
            ("Transmission type", U8, "rw", 255),
            ("Inhibit time", U16, "rw", 0),
            ("Compatibility entry", U8, "rw", 0),
            ("Event timer", U16, "rw", 0),
        ],
    )
    r3 = ODRecord("TPDO3 mapping parameter", 0x1A02)
    r3.add_member(od_var("Number of mapped objects", 0x1A02, 0, U8, "rw", 1))
    for i, val in enumerate((0x60FD0020, 0, 0, 0), 1):
        r3.add_member(od_var(f"Mapped object {i}", 0x1A02, i, U32, "rw", val))
    od.add_object(r3)

    add(od_var("Controlword", 0x6040, 0, U16, "rw", 0, True))
    add(od_var("Statusword", 0x6041, 0, U16, "ro", 0x0250, True))
    add(od_var("Quick stop option code", 0x605A, 0, odm.INTEGER16, "rw", 2))
    add(od_var("Modes of operation", 0x6060, 0, I8, "rw", 0, True))
    add(od_var("Modes of operation display", 0x6061, 0, I8, "ro", 0, True))
    add(od_var("Position actual value", 0x6064, 0, I32, "ro", start_position, True))
    add(od_var("Following error window", 0x6065, 0, U32, "rw", fe_window))
    add(od_var("Following error time out", 0x6066, 0, U16, "rw", fe_time_ms))
    add(od_var("Target position", 0x607A, 0, I32, "rw", start_position, True))
    record(
        "Interpolation time period",
        0x60C2,
        [
            ("Interpolation time period value", U8, "rw", 1),
            ("Interpolation time index", I8, "rw", -3),
        ],
    )
    add(od_var("Following error actual value", 0x60F4, 0, I32, "ro", 0, True))
    # touch probe 1 (CiA 402): function, status, positions latched at its edges
    add(od_var("Touch probe function", 0x60B8, 0, U16, "rw", 0, True))
    add(od_var("Touch probe status", 0x60B9, 0, U16, "ro", 0, True))
    add(od_var("Touch probe pos1 pos value", 0x60BA, 0, I32, "ro", 0, True))
    add(od_var("Touch probe pos1 neg value", 0x60BB, 0, I32, "ro", 0, True))
    # profile velocity mode (3, a spindle): counts/s, counts/s^2
    add(od_var("Velocity actual value", 0x606C, 0, I32, "ro", 0, True))
    add(od_var("Velocity window", 0x606D, 0, U16, "rw", PV_WINDOW_DEFAULT))
    add(od_var("Profile acceleration", 0x6083, 0, U32, "rw", 100000))
    add(od_var("Profile deceleration", 0x6084, 0, U32, "rw", 100000))
    add(od_var("Quick stop deceleration", 0x6085, 0, U32, "rw", 100000))
    # bit 0 negative limit switch, 1 positive limit switch, 2 home switch
    # (from the switches' positions), 16..31 manufacturer specific
    add(od_var("Digital inputs", 0x60FD, 0, U32, "ro", 0, True))
    add(od_var("Target velocity", 0x60FF, 0, I32, "rw", 0, True))
    # homing mode (6): method, speeds (search, latch), acceleration, offset
    add(od_var("Homing method", 0x6098, 0, I8, "rw", 0))
    record(
        "Homing speeds",
        0x6099,
        [
            ("Speed during search for switch", U32, "rw", 1000),
            ("Speed during search for zero", U32, "rw", 100),
        ],
    )
    add(od_var("Homing acceleration", 0x609A, 0, U32, "rw", 10000))
    add(od_var("Home offset", 0x607C, 0, I32, "rw", 0))
    add(
        od_var(
            "Supported drive modes",
            0x6502,
            0,
            U32,
            "ro",
            1 << (P.MODE_CSP - 1) | 1 << (MODE_HOMING - 1) | 1 << (MODE_PV - 1),
        )
    )
    return od


# the receiving thread this long (s) not running between two receives, its
# 20 ms receive timeout aside (DriveSim.own_stall)
OWN_STALL_S = 0.25
# objects the cycle reads, cached in Drive.load_params() after each write
PARAM_OBJECTS = (0x6060, 0x6065, 0x6066, 0x60C2, 0x605A, 0x606D, 0x6083, 0x6084, 0x6085)
MAPPABLE_RX = {(0x6040, 0), (0x607A, 0), (0x6060, 0), (0x60FF, 0), (0x60B8, 0)}
MAPPABLE_TX = {
    (0x6041, 0),
    (0x6064, 0),
    (0x6061, 0),
    (0x60F4, 0),
    (0x606C, 0),
    (0x60B9, 0),
    (0x60BA, 0),
    (0x60BB, 0),
    (0x60FD, 0),
}
# the touch probe input's level in 0x60FD: CiA 402's 0x60B9 has none (bits
# 3..7 reserved), drives show their probe input among 0x60FD's manufacturer
# bits 16..31; this simulator's is bit 16 ([IO] PROBE = N 0x60FD:0 16 HIGH)
TOUCH_DI_BIT = 16
MAPPABLE_TX3 = {(0x60FD, 0)}  # TPDO3 (event driven): the digital inputs only
# 0x60B8 touch probe function / 0x60B9 status, touch probe 1 (CiA 402)
TP_ENABLE = 0x0001  # function and status bit 0: switched on
TP_CONTINUOUS = 0x0002  # function bit 1: every event (0: the first one only)
TP_POS_EDGE = 0x0010  # function bit 4: latch at the positive edge
TP_NEG_EDGE = 0x0020  # function bit 5: latch at the negative edge
TP_POS_STORED = 0x0002  # status bit 1: 0x60BA holds a positive edge's position
TP_NEG_STORED = 0x0004  # status bit 2: 0x60BB holds a negative edge's position


class Recorder:
    """What the drives saw, for the tests: events.jsonl (one JSON object a
    line, written at once: SDO writes with their outcome, NMT and power
    state transitions, EMCYs sent, injected faults, heartbeat losses) and
    sync.csv (one row per drive per SYNC while the drive is NMT
    operational: the target applied at that SYNC, the position actual value
    and statusword sent in its TPDO). Rows are kept in memory and written by
    flush() from the main thread (no file I/O in the bus thread)."""

    SYNC_HEADER = "sync,node,t,state,controlword,target,fresh,actual,statusword\n"

    def __init__(self, outdir: Path | None) -> None:
        self.outdir = outdir
        self.lock = threading.Lock()
        self.rows: list[SyncRow] = []
        self.io_rows: list[IoRow] = []
        self.io_fh: IO[str] | None = None
        self.events_fh: IO[str] | None = None
        self.sync_fh: IO[str] | None = None
        if outdir is not None:
            outdir.mkdir(parents=True, exist_ok=True)
            self.events_fh = open(outdir / "events.jsonl", "w", buffering=1)
            self.sync_fh = open(outdir / "sync.csv", "w")
            self.sync_fh.write(self.SYNC_HEADER)
            self.io_fh = open(outdir / "io.csv", "w")
            self.io_fh.write("sync,node,t,outputs,inputs\n")

    def event(self, node: int, kind: str, **kw: Any) -> None:
        e: dict[str, Any] = {"t": time.time(), "node": node, "kind": kind}
        e.update(kw)
        if self.events_fh is not None:
            with self.lock:
                self.events_fh.write(json.dumps(e) + "\n")

    def sync(self, row: SyncRow) -> None:
        self.rows.append(row)  # list.append is atomic; flush() swaps the list

    def io_row(self, row: IoRow) -> None:
        """An I/O module at one SYNC (io.csv): sync, node, t, outputs, inputs."""
        self.io_rows.append(row)

    def flush(self) -> None:
        if self.sync_fh is None:
            return
        rows, self.rows = self.rows, []
        w = self.sync_fh.write
        for s, node, t, state, cw, target, fresh, actual, sw in rows:
            w(
                f"{s},{node},{t:.6f},{state},{cw},{'' if target is None else target},"
                f"{int(fresh)},{actual},{sw}\n"
            )
        self.sync_fh.flush()
        if self.io_fh is not None:
            io_rows, self.io_rows = self.io_rows, []
            for s, node, t, outs, ins in io_rows:
                self.io_fh.write(f"{s},{node},{t:.6f},{outs},{ins}\n")
            self.io_fh.flush()

    def close(self) -> None:
        self.flush()
        for fh in (self.events_fh, self.sync_fh, self.io_fh):
            if fh is not None:
                fh.close()


class Drive(SimDevice):
    """One simulated servo drive: node id, position (counts), power state."""

    def __init__(
        self,
        sim: "DriveSim",
        node_id: int,
        start_position: int = 0,
        start_state: str = P.SWITCH_ON_DISABLED,
        heartbeat_ms: int = 0,
        lag_alpha: float = 1.0,
        switches: dict[str, int] | None = None,
    ) -> None:
        super().__init__(sim, node_id)
        # where the axis' switches are (counts): "neg", "pos" (limit switches,
        # on beyond them), "home" (a positive home switch: on at and beyond
        # it in +), "nhome" (a negative one: on at and below it); "index": the
        # encoder's index pulse once every that many counts (one revolution),
        # at the multiples of it in the power-up reference
        self.switches = dict(switches or {})
        self.index_rev = self.switches.pop("index", 0)
        self.index_at = 0.0  # where one index pulse is, in the current reference
        self.start_position = start_position
        self.start_state = start_state
        self.heartbeat_ms = heartbeat_ms
        self.lag_alpha = lag_alpha
        self.state: str | None = None  # None until powered up
        # injected faults
        self.refuse: dict[tuple[int, int | None], int] = {}  # (index, sub or None) -> abort
        self.never_enable = False
        self.follow_error_rate = 0.0  # counts added to the lag per SYNC
        # digital inputs 0x60FD: bits forced by injection (bit -> 0/1), the
        # TPDO3 silenced (injected), the last sent (value, bus time)
        self.di_force: dict[int, int] = {}
        self.di_silent = False
        self.di_sent: tuple[int, float] | None = None
        self.di_cob: int | None = None  # TPDO3's COB-ID while operational and valid
        self.di_event_s = 0.0
        self._pdo_live = False
        self._sync_cob = 0
        self._reset_application()
        self.node = SimNode(self, self.id, build_od(self.id, heartbeat_ms, start_position))
        # canopen's LocalNode, untyped there (inherited: not excluded by name)
        self.node.add_write_callback(self._on_write)  # type: ignore[no-untyped-call]
        self.node.add_read_callback(self._on_read)  # type: ignore[no-untyped-call]
        self.load_params()

    # ------------------------------------------------------------ set-up
    def _reset_application(self) -> None:
        # idle, search, brake, latch, index, return, done, error
        self.home_phase = "idle"
        self.home_attained = False
        self.home_dir = 1
        self.home_index = False  # the index pulse after the switch (or alone)
        self.home_stall = getattr(self, "home_stall", False)
        self.home_method = 0
        self.home_switch = "home"
        self.home_v = 0.0
        self._cw_prev_home = 0
        self.actual = self.start_position
        self.actual_f = float(self.start_position)
        self.target = self.start_position
        self.pending_target: int | None = None  # from the RPDO since the last SYNC
        self.pending_cw: int | None = None
        self.cw = 0
        # profile velocity mode (a spindle): counts/s
        self.vel_f = 0.0
        self.csp_v = 0.0  # CSP: counts/s of the last SYNC's move (a quick stop ramps it down)
        self.vel_target = 0
        self.pending_vel: int | None = None
        self.load_drop = 0.0  # injected: a load the spindle cannot hold (counts/s lost)
        self.fe_extra = 0.0
        self.fe_cycles = 0
        self.error_register = 0
        # touch probe 1: function in force, status, latched positions; the
        # move of the last SYNC (for a latch between two SYNCs)
        self.tp_fn = 0
        self.tp_status = 0
        self.tp_pos = 0
        self.tp_neg = 0
        self.pending_tp: int | None = None
        self.move_sync = -1
        self.move_from = 0.0
        self.move_to = 0.0
        self.edge_seen = 0
        # producer node -> [time ms, last seen (receive time, s) or None]
        self.hb_consumed: dict[int, tuple[int, float | None]] = {}
        self.hb_lost: set[int] = set()

    def load_params(self) -> None:
        """What the cycle needs of the OD, read once per change, not per SYNC."""
        od = self.sim.od_int
        n = self.node
        self.p_mode = od(n, 0x6060, "<b")
        self.p_window = od(n, 0x6065, "<I")
        self.p_fe_ms = od(n, 0x6066, "<H")
        self.p_period_ms = self.sim.period_ms(n)
        self.p_quick_stop = od(n, 0x605A, "<h")
        self.p_pv_window = od(n, 0x606D, "<H")
        self.p_pv_acc = od(n, 0x6083, "<I")
        self.p_pv_dec = od(n, 0x6084, "<I")
        self.p_qs_dec = od(n, 0x6085, "<I")

    def written(self, index: int, sub: int, data: bytes) -> None:
        if index in PARAM_OBJECTS:
            self.load_params()

    def _on_bus(self, network: canopen.Network) -> None:
        self._sync_cob = self.sim.od_u32(self.node, 0x1005) & 0x7FF
        network.subscribe(self._sync_cob, self._on_sync)
        self._set_state(self.start_state if self.state is None else self.state, "power on")

    def _off_bus(self, network: canopen.Network) -> None:
        network.unsubscribe(self._sync_cob, self._on_sync)
        for cob in list(self._hb_subs()):
            network.unsubscribe(cob, self._on_heartbeat)

    def _hb_subs(self) -> list[int]:
        return [0x700 + p for p in self.hb_consumed]

    # ------------------------------------------------------------ OD access
    def _store(self, index: int, sub: int, fmt: str, value: int) -> None:
        self.node.data_store.setdefault(index, {})[sub] = struct.pack(fmt, value)

    def _publish(self) -> None:
        """The drive's own objects into the OD (SDO reads, TPDO)."""
        self._store(0x6041, 0, "<H", self.statusword())
        self._store(0x6064, 0, "<i", self.actual)
        self._store(0x60F4, 0, "<i", self.target - self.actual)
        self._store(0x6061, 0, "<b", self.mode_display())
        self._store(0x606C, 0, "<i", self.vel_actual())
        self._store(0x60FD, 0, "<I", self.digital_inputs())
        self._store(0x1001, 0, "B", self.error_register)
        self._store(0x60B9, 0, "<H", self.tp_status)
        self._store(0x60BA, 0, "<i", self.tp_pos)
        self._store(0x60BB, 0, "<i", self.tp_neg)

    def digital_inputs(self) -> int:
        """0x60FD: the switches at the position actual, the touch probe's
        input level (TOUCH_DI_BIT), then the forced bits."""
        v = 0
        for bit, which in ((0, "neg"), (1, "pos"), (2, "home"), (2, "nhome")):
            if self._switch_on(which, self.actual):
                v |= 1 << bit
        if self.sim.touch is not None and self.sim.touch_on:
            v |= 1 << TOUCH_DI_BIT
        for bit, on in self.di_force.items():
            v = v | 1 << bit if on else v & ~(1 << bit)
        return v & 0xFFFFFFFF

    def _send_garbled(self, value: int) -> None:
        """A TPDO3 one byte short of its mapping (the first 3 bytes of value):
        what a master must not take."""
        if self.di_cob is None or not self._pdo_live:
            raise ValueError("di-garbled: TPDO3 is not configured and operational")
        data = struct.pack("<I", value & 0xFFFFFFFF)[:3]
        self.node.network.send_message(self.di_cob, data)
        self._di_event(value, data, "injected: garbled")

    def _di_event(self, value: int, data: bytes, why: str) -> None:
        """A TPDO3 sent (events.jsonl "di"): its bus time orders it among the
        SYNCs' receive times in sync.csv, whatever this simulator's own lag."""
        self.rec.event(
            self.id,
            "di",
            value=f"0x{value & 0xFFFFFFFF:08X}",
            data=data.hex(),
            sync=self.sim.sync_no,
            t_bus=time.time(),
            actual=self.actual,
            why=why,
        )

    def _send_inputs(self, t: float, why: str) -> None:
        """TPDO3 (0x60FD) when it is valid and the drive operational: on
        change, or when the event timer 0x1802:05 ran out since the last."""
        if not self._pdo_live or self.di_silent or self.di_cob is None:
            return
        v = self.digital_inputs()
        last = self.di_sent
        ev = self.di_event_s
        if not (last is None or v != last[0] or (ev > 0 and t - last[1] >= ev)):
            return
        data = struct.pack("<I", v)
        self.node.network.send_message(self.di_cob, data)
        self.di_sent = (v, t)
        if last is None or v != last[0]:
            self._di_event(v, data, why)

    def _on_read(self, index: int, subindex: int, od: ODVariable) -> None:
        if index in (
            0x6041,
            0x6064,
            0x60F4,
            0x6061,
            0x1001,
            0x606C,
            0x60B9,
            0x60BA,
            0x60BB,
            0x60FD,
        ):
            self._publish()
        # then the stored data

    def mode(self) -> int:
        return self.p_mode

    def mode_display(self) -> int:
        return self.mode()  # the drive runs the mode it was told (validated on write)

    # ------------------------------------------------------------ SDO writes
    def _on_write(self, index: int, subindex: int, od: ODVariable, data: bytes) -> None:
        """Validation as a drive does it (raise SdoAbortedError to refuse),
        then the side effects. Called by canopen before it stores the data."""
        for key in ((index, subindex), (index, None)):
            if key in self.refuse:
                raise SdoAbortedError(self.refuse[key])
        raw = od.decode_raw(data)
        if not isinstance(raw, int):
            return  # no such object here: every one the drive acts on is an integer
        val = raw
        if index == 0x6060:
            if val not in (0, P.MODE_CSP, MODE_HOMING, MODE_PV):
                raise SdoAbortedError(0x06090030)
        elif index == 0x6098:
            if val not in HOMING_METHODS:
                raise SdoAbortedError(0x06090030)  # a method this drive does not have
        elif index == 0x6040:
            self._controlword(val, "SDO")
        elif index == 0x607A:
            self.pending_target = val
        elif index == 0x60FF:
            self.pending_vel = val
        elif index == 0x60B8:
            self._touch_probe_fn(val, "SDO")
        elif index == 0x1005:
            if val & 0x40000000:  # this device does not generate SYNC
                raise SdoAbortedError(0x06090030)
            net = self.node.network
            net.unsubscribe(self._sync_cob, self._on_sync)
            self._sync_cob = val & 0x7FF
            net.subscribe(self._sync_cob, self._on_sync)
        elif index == 0x1016 and subindex >= 1:
            self._consumer(subindex, val)
        elif index in (0x1400, 0x1800, 0x1801, 0x1802) and subindex == 1:
            self.check_cob_id(index, val)
        elif index in (0x1600, 0x1A00, 0x1A01, 0x1A02):
            self._check_mapping(index, subindex, val)

    def _check_mapping(self, index: int, sub: int, val: int) -> None:
        com = index - 0x200
        valid = not self.sim.od_u32(self.node, com, 1) & PDO_INVALID
        n_now = self.sim.od_int(self.node, index, "B", 0)
        if valid or (sub >= 1 and n_now != 0):
            # CiA 301: disable the PDO, set sub 0 to 0, write the entries, set sub 0
            raise SdoAbortedError(0x06010000)
        allowed = {0x1600: MAPPABLE_RX, 0x1A02: MAPPABLE_TX3}.get(index, MAPPABLE_TX)
        if sub >= 1:
            if val and ((val >> 16, (val >> 8) & 0xFF) not in allowed):
                if (val >> 16) not in self.node.object_dictionary:
                    raise SdoAbortedError(0x06020000)
                raise SdoAbortedError(0x06040041)
            return
        if val > 4:
            raise SdoAbortedError(0x06090031)
        bits = sum(self.sim.od_int(self.node, index, "<I", k) & 0xFF for k in range(1, val + 1))
        if bits > 64:
            raise SdoAbortedError(0x06040042)

    def _consumer(self, sub: int, val: int) -> None:
        """0x1016 sub: monitor node (val >> 16 & 0x7F) every (val & 0xFFFF) ms."""
        net = self.node.network
        # drop this sub-index's old entry
        old = self.sim.od_int(self.node, 0x1016, "<I", sub)
        if old and (old >> 16) & 0x7F in self.hb_consumed:
            p = (old >> 16) & 0x7F
            del self.hb_consumed[p]
            net.unsubscribe(0x700 + p, self._on_heartbeat)
        producer, ms = (val >> 16) & 0x7F, val & 0xFFFF
        if producer and ms:
            self.hb_consumed[producer] = (ms, None)
            net.subscribe(0x700 + producer, self._on_heartbeat)

    def _on_heartbeat(self, can_id: int, data: bytearray, timestamp: float) -> None:
        p = can_id - 0x700
        e = self.hb_consumed.get(p)
        if e is not None:
            # the frame's receive time (kernel), s; never back: a stall of the
            # simulator itself may have moved it on (DriveSim.own_stall)
            self.hb_consumed[p] = (e[0], max(timestamp, e[1] or 0.0))
            self.hb_lost.discard(p)

    def stalled(self, s: float) -> None:
        """The simulator was not running for s seconds: not counted against
        the producers (their heartbeats' consumer time moves on by s)."""
        for p, (ms, seen) in list(self.hb_consumed.items()):
            if seen is not None:
                self.hb_consumed[p] = (ms, seen + s)

    def check_heartbeats(self, now: float) -> None:
        """A consumed heartbeat overdue at bus time `now` (the receive time of
        a later frame, so a simulator running behind the bus judges by frame
        order, not by its own lateness) is a heartbeat event (CiA 301): EMCY
        0x8130, and the drive faults (its communication error reaction)."""
        for p, (ms, seen) in list(self.hb_consumed.items()):
            if seen is None or p in self.hb_lost:
                continue  # CiA 301: monitoring starts with the first heartbeat
            if now - seen > ms / 1000.0:
                self.hb_lost.add(p)
                prev = self.sim.prev_sync_t
                self.rec.event(
                    self.id,
                    "heartbeat_lost",
                    producer=p,
                    ms=ms,
                    late_s=round(now - seen, 4),
                    # how it was judged (a SYNC's receive time, the newest
                    # frame's, or the wall clock on a silent bus), and the
                    # bus's own silence before it: the SYNCs' gap
                    via=self.sim.judge_via,
                    sync_gap_s=None if prev is None else round(now - prev, 4),
                )
                self.fault(0x8130, f"heartbeat of node {p} lost")

    # ------------------------------------------------------------ NMT
    def nmt_state(self) -> str:
        return self.node.nmt.state

    def _on_nmt(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if not self._for_me(data):
            return
        cmd = data[0]
        old = self.nmt_state()
        nmt = self.node.nmt
        if cmd in (P.NMT_RESET_NODE, P.NMT_RESET_COMM):
            if cmd == P.NMT_RESET_NODE:
                # reset application: the profile area to its defaults (the
                # axis does not move: the position is physical)
                self._reset_od(0x2000, 0xFFFF)
                self.start_position = self.actual
                pos = self.actual
                self._reset_application()
                self.actual = self.target = pos
                self.actual_f = float(pos)
                self._set_state(P.SWITCH_ON_DISABLED, "NMT reset node")
            self._reset_od(0x1000, 0x1FFF)
            self._leave_operational(old, "NMT reset")
            self._boot("NMT reset node" if cmd == P.NMT_RESET_NODE else "NMT reset communication")
            return
        if cmd == P.NMT_START:
            nmt.send_command(cmd)
            if old != "OPERATIONAL":
                self._pdo_on()
        elif cmd in (P.NMT_STOP, P.NMT_PREOP):
            nmt.send_command(cmd)
            self._leave_operational(old, "NMT")
        else:
            return
        if self.hb_stopped:
            nmt.stop_heartbeat()
        if self.nmt_state() != old:
            self.rec.event(self.id, "nmt", to=self.nmt_state(), why=f"NMT command 0x{cmd:02X}")

    def _reset_od(self, lo: int, hi: int) -> None:
        ds = self.node.data_store
        for k in [k for k in ds if lo <= k <= hi]:
            del ds[k]
        self.load_params()
        if lo <= 0x1016 <= hi:
            for cob in self._hb_subs():
                self.node.network.unsubscribe(cob, self._on_heartbeat)
            self.hb_consumed.clear()
        if lo <= 0x1005 <= hi:
            net = self.node.network
            net.unsubscribe(self._sync_cob, self._on_sync)
            self._sync_cob = self.sim.od_u32(self.node, 0x1005) & 0x7FF
            net.subscribe(self._sync_cob, self._on_sync)

    def _leave_operational(self, old: str, why: str) -> None:
        if old == "OPERATIONAL":
            self._pdo_off()
            if self.state in (P.OPERATION_ENABLED, P.QUICK_STOP):
                # no more setpoints: stop where it is (communication error reaction)
                self._set_state(P.SWITCH_ON_DISABLED, f"{why}: left NMT operational")

    def _pdo_on(self) -> None:
        """Entering operational: the PDO maps as the master configured them,
        read through canopen's own PdoMap.read() from this node's OD."""
        self._pdo_off()
        self.rpdo = self.node.rpdo[1]
        self.tpdo = self.node.tpdo[1]
        self.tpdo2 = self.node.tpdo[2]
        self.rpdo.read()  # subscribes the RPDO when valid
        self.tpdo.read()
        self.tpdo.pdo_node.network.unsubscribe(self.tpdo.cob_id)  # read() subscribes TPDOs too
        self.tpdo2.read()
        if self.tpdo2.enabled:
            self.tpdo2.pdo_node.network.unsubscribe(self.tpdo2.cob_id)
        self.rpdo.add_callback(self._on_rpdo)
        self._rx = self._codec(self.rpdo)
        self._tx = self._codec(self.tpdo)
        self._tx2 = self._codec(self.tpdo2) if self.tpdo2.enabled else []
        self.tpdo_every = self.tpdo.trans_type if 1 <= (self.tpdo.trans_type or 0) <= 240 else 1
        # TPDO3 as the master configured it: valid and mapping 0x60FD alone
        # (the only mapping it takes), read once here, not per SYNC
        cob3 = self.od_u32(0x1802, 1)
        n3 = self.sim.od_int(self.node, 0x1A02, "B", 0)
        ok = not cob3 & PDO_INVALID and n3 == 1 and self.od_u32(0x1A02, 1) == 0x60FD0020
        self.di_cob = cob3 & 0x7FF if ok else None
        self.di_event_s = self.sim.od_int(self.node, 0x1802, "<H", 5) / 1000.0
        self.rec.event(
            self.id,
            "pdo_maps",
            rpdo={
                "cob_id": f"0x{self.rpdo.cob_id:03X}",
                "valid": self.rpdo.enabled,
                "type": self.rpdo.trans_type,
                "map": [f"0x{v.index:04X}:{v.subindex}/{v.length}" for v in self.rpdo.map],
            },
            tpdo={
                "cob_id": f"0x{self.tpdo.cob_id:03X}",
                "valid": self.tpdo.enabled,
                "type": self.tpdo.trans_type,
                "map": [f"0x{v.index:04X}:{v.subindex}/{v.length}" for v in self.tpdo.map],
            },
            tpdo2={
                "cob_id": f"0x{self.tpdo2.cob_id:03X}",
                "valid": self.tpdo2.enabled,
                "type": self.tpdo2.trans_type,
                "map": [f"0x{v.index:04X}:{v.subindex}/{v.length}" for v in self.tpdo2.map],
            },
            tpdo3={  # the digital inputs 0x60FD, on change and every event timer
                "cob_id": f"0x{cob3 & 0x7FF:03X}",
                "valid": self.di_cob is not None,
                "event_ms": round(self.di_event_s * 1000),
            },
        )
        self._pdo_live = True
        self.di_sent = None
        self._send_inputs(time.time(), "operational")  # the inputs once on entering it

    @staticmethod
    def _codec(pdo: PdoMap) -> list[tuple[int, int, struct.Struct]]:
        """(index, byte offset, struct) of each object a PDO map carries (whole
        bytes: what CiA 402 maps), from canopen's PdoMap: the cycle then packs
        and unpacks with struct instead of canopen's per-variable codec."""
        out = []
        for v in pdo.map:
            dt = v.od.data_type
            st = None if dt is None else v.od.STRUCT_TYPES.get(dt)
            off = v.offset or 0
            if st is None or off % 8 or v.length != 8 * st.size:
                raise ValueError(
                    f"PDO 0x{pdo.cob_id or 0:03X}: 0x{v.index:04X} is not byte-aligned "
                    f"whole (offset {v.offset}, {v.length} bits)"
                )
            out.append((v.index, off // 8, st))
        return out

    def _pdo_off(self) -> None:
        if self._pdo_live:
            net = self.node.network
            if self.rpdo.enabled:
                net.unsubscribe(self.rpdo.cob_id, self.rpdo.on_message)
            self.rpdo.callbacks.clear()
        self._pdo_live = False
        self.di_sent = None
        self.pending_target = self.pending_cw = self.pending_vel = self.pending_tp = None

    def _on_rpdo(self, m: PdoMap) -> None:
        """An RPDO: latched, applied at the next SYNC (synchronous types)."""
        with self.sim.lock:
            self._rpdo_latch()

    def _rpdo_latch(self) -> None:
        data = self.rpdo.data
        if len(data) < self.rpdo.length // 8:
            return  # shorter than its map: ignored (CiA 301 would EMCY 0x8210)
        for index, off, st in self._rx:
            val = st.unpack_from(data, off)[0]
            if index == 0x607A:
                self.pending_target = val
            elif index == 0x60FF:
                self.pending_vel = val
            elif index == 0x6040:
                self.pending_cw = val
            elif index == 0x60B8:
                self.pending_tp = val
            elif index == 0x6060:
                self._store(0x6060, 0, "<b", val)
                self.load_params()
        if self.rpdo.trans_type is not None and self.rpdo.trans_type >= 254:
            self._apply_rpdo()  # event driven: at once

    def _apply_rpdo(self) -> int | None:
        cw, self.pending_cw = self.pending_cw, None
        if cw is not None:
            self._store(0x6040, 0, "<H", cw)
            self._controlword(cw, "RPDO")
        tp, self.pending_tp = self.pending_tp, None
        if tp is not None:
            self._store(0x60B8, 0, "<H", tp)
            self._touch_probe_fn(tp, "RPDO")
        tgt, self.pending_target = self.pending_target, None
        if tgt is not None:
            self._store(0x607A, 0, "<i", tgt)
        vel, self.pending_vel = self.pending_vel, None
        if vel is not None:
            self._store(0x60FF, 0, "<i", vel)
            self.vel_target = vel
            if self.mode() == MODE_PV:
                return vel  # what sync.csv records for a drive in pv mode
        return tgt

    # ------------------------------------------------------------ CiA 402
    def statusword(self) -> int:
        if self.state is None:
            return 0
        mask, value = P.SW_PATTERN[self.state]
        sw = value | P.SW_REMOTE
        if self.state not in (P.QUICK_STOP,) and value & 0x21 == 0x21:
            sw |= P.SW_QUICK_STOP
        if self.state in (P.READY, P.SWITCHED_ON, P.OPERATION_ENABLED, P.QUICK_STOP):
            sw |= P.SW_VOLTAGE_ENABLED
        if self.state == P.OPERATION_ENABLED and self.mode() == P.MODE_CSP:
            sw |= P.SW_CSP_FOLLOWING
        if self.fe_cycles and self.mode() == P.MODE_CSP:
            sw |= P.SW_FOLLOWING_ERROR
        if self.mode() == MODE_PV and self.state == P.OPERATION_ENABLED:
            # bit 10 target reached, bit 12 speed zero (within 0x606D)
            if abs(self.vel_target - self.vel_actual()) <= self.p_pv_window:
                sw |= P.SW_TARGET_REACHED
            if abs(self.vel_actual()) <= self.p_pv_window:
                sw |= SW_SPEED_ZERO
        if self.mode() == MODE_HOMING:
            # bit 10 target reached (at rest: done or halted), 12 homing
            # attained, 13 homing error
            if self.home_phase in ("done", "error", "idle"):
                sw |= P.SW_TARGET_REACHED
            # attained, still moving back onto the home position (after an
            # index pulse): 12 without 10 (CiA 402: "homing attained, target
            # not reached")
            if self.home_phase in ("done", "return") and self.home_attained:
                sw |= SW_HOMING_ATTAINED
            if self.home_phase == "error":
                sw |= SW_HOMING_ERROR
        return sw

    def _set_state(self, new: str, why: str) -> None:
        old = self.state
        if new == old:
            return
        self.state = new
        if new == P.OPERATION_ENABLED:
            # enabling holds the position: the loop starts from where it is
            self.target = self.actual
            self.fe_cycles = 0
        self._publish()
        self.rec.event(
            self.id, "state", frm=old, to=new, why=why, statusword=f"0x{self.statusword():04X}"
        )

    def _controlword(self, cw: int, via: str) -> None:
        """CiA 402 transitions 2-16 on a controlword (bit 7 rising: fault reset)."""
        prev, self.cw = self.cw, cw
        s = self.state
        if s == P.FAULT:
            if cw & P.CW_FAULT_RESET and not prev & P.CW_FAULT_RESET:
                self.error_register = 0
                self.fe_extra = 0.0
                if self.present:
                    self.node.emcy.reset()
                    self.rec.event(self.id, "emcy", code="0x0000", meaning=P.EMCY[0])
                self._set_state(P.SWITCH_ON_DISABLED, f"fault reset ({via})")  # 15
            return
        if s in (P.FAULT_REACTION, P.NOT_READY):
            return
        cmd = P.command_of(cw)
        why = f"controlword 0x{cw:04X} {cmd} ({via})"
        if cmd == "disable voltage":
            if s != P.SWITCH_ON_DISABLED:
                self._set_state(P.SWITCH_ON_DISABLED, why)  # 7, 9, 10, 12
        elif cmd == "quick stop":
            if s in (P.READY, P.SWITCHED_ON):
                self._set_state(P.SWITCH_ON_DISABLED, why)  # 7, 10
            elif s == P.OPERATION_ENABLED:
                self._set_state(P.QUICK_STOP, why)  # 11
                moving = self.csp_v != 0.0
                if moving and self.mode() == P.MODE_CSP and self.p_quick_stop in (1, 2, 5, 6):
                    pass  # brakes on its ramp at the SYNCs (_quick_stop_ramp), then 12
                elif self.p_quick_stop in (1, 2, 3, 4):
                    self._set_state(P.SWITCH_ON_DISABLED, "quick stop done")  # 12
        elif cmd == "shutdown":
            if s in (P.SWITCH_ON_DISABLED, P.SWITCHED_ON, P.OPERATION_ENABLED):
                self._set_state(P.READY, why)  # 2, 6, 8
        elif cmd == "switch on":
            if s == P.READY:
                self._set_state(P.SWITCHED_ON, why)  # 3
            elif s == P.OPERATION_ENABLED:
                self._set_state(P.SWITCHED_ON, why.replace("switch on", "disable operation"))  # 5
        elif cmd == "enable operation":
            if s == P.READY:
                self._set_state(P.SWITCHED_ON, why)  # 3
                s = P.SWITCHED_ON
            if s in (P.SWITCHED_ON, P.QUICK_STOP):
                if self.never_enable:
                    self.rec.event(self.id, "refused_enable", why="injected never-enable")
                else:
                    self._set_state(P.OPERATION_ENABLED, why)  # 4, 16

    # ------------------------------------------------------------ touch probe 1
    def _touch_probe_fn(self, fn: int, via: str) -> None:
        """0x60B8 applied (at a SYNC from the RPDO, at once by SDO): bit 0
        switching on clears what was stored and arms the latch; off clears
        the status (CiA 402)."""
        old, self.tp_fn = self.tp_fn, fn
        if not fn & TP_ENABLE:
            self.tp_status = 0
        elif not old & TP_ENABLE:
            self.tp_status = TP_ENABLE
        if fn != old:
            self._publish()
            self.rec.event(self.id, "touch_probe_fn", fn=f"0x{fn:04X}", via=via)

    def touch_probe_edge(self, frac: float, positive: bool, sync_no: int, edge: int) -> None:
        """The probe's input changed at frac (0..1) of this SYNC's move: the
        position there is latched (not the position at a SYNC), at the edge
        the function enables, the first one only unless continuous."""
        if edge == self.edge_seen or self.move_sync != sync_no:
            return
        self.edge_seen = edge
        fn = self.tp_fn
        stored = TP_POS_STORED if positive else TP_NEG_STORED
        if not fn & TP_ENABLE or not fn & (TP_POS_EDGE if positive else TP_NEG_EDGE):
            return
        if self.tp_status & stored and not fn & TP_CONTINUOUS:
            return  # first event only: re-armed by switching the function on again
        at = int(round(self.move_from + frac * (self.move_to - self.move_from)))
        if positive:
            self.tp_pos = at
        else:
            self.tp_neg = at
        self.tp_status |= stored
        self._publish()
        self.rec.event(
            self.id,
            "touch_probe",
            edge="positive" if positive else "negative",
            latched=at,
            sync=sync_no,
            frac=round(frac, 6),
            from_=round(self.move_from, 3),
            to=round(self.move_to, 3),
        )

    def fault(self, code: int, why: str) -> None:
        """Fault reaction (CiA 402 transitions 13, 14): statusword fault bit,
        EMCY with the error code, error register bit 0 (generic)."""
        if self.state in (P.FAULT, P.FAULT_REACTION):
            return
        self.error_register |= 0x01 | (0x10 if code in (0x8130, 0x7500) else 0)
        self._set_state(P.FAULT_REACTION, why)
        self._set_state(P.FAULT, "fault reaction done")
        if self.present:
            self.node.emcy.send(code, self.error_register)
        self.rec.event(
            self.id,
            "emcy",
            code=f"0x{code:04X}",
            meaning=P.EMCY.get(code, "?"),
            error_register=self.error_register,
            why=why,
        )

    # ------------------------------------------------------------ the cycle
    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if self.present:
            self.sim.on_sync(self, timestamp)

    def cycle(self, sync_no: int, t: float) -> None:
        """One SYNC (CiA 301 synchronous PDOs): send the TPDO with the state
        sampled now, then apply the RPDO received since the previous SYNC,
        then move: position actual = previous actual + alpha (target -
        previous actual), i.e. with alpha = 1 the target of this SYNC is
        reached at the next one (a one-period lag)."""
        if not self._pdo_live:
            return
        sw, sent = self.statusword(), self.actual
        vel = self.vel_actual()
        if self.tpdo.enabled and sync_no % self.tpdo_every == 0:
            tp = self.tpdo
            now = {
                0x6041: sw,
                0x6064: sent,
                0x6061: self.p_mode,
                0x60F4: self.target - sent,
                0x606C: vel,
                0x60B9: self.tp_status,
                0x60BA: self.tp_pos,
                0x60BB: self.tp_neg,
                0x60FD: self.digital_inputs(),
            }
            for index, off, st in self._tx:
                st.pack_into(tp.data, off, now[index])
            tp.transmit()
            if self._tx2:  # sampled at the same SYNC
                for index, off, st in self._tx2:
                    st.pack_into(self.tpdo2.data, off, now[index])
                self.tpdo2.transmit()
        fresh = self.pending_target is not None
        if self.rpdo.trans_type is None or self.rpdo.trans_type <= 240:
            tgt = self._apply_rpdo()
        else:
            tgt = None
        if self.state == P.OPERATION_ENABLED and self.mode() == MODE_HOMING:
            self._homing(sync_no)
        pos_from = self.actual_f - self.fe_extra
        if self.state == P.OPERATION_ENABLED and self.mode() == P.MODE_CSP:
            if tgt is not None:
                self.target = tgt
            self.fe_extra += self.follow_error_rate
            before = self.actual_f
            self.actual_f += self.lag_alpha * (self.target - self.actual_f)
            self.csp_v = (self.actual_f - before) / (self.p_period_ms / 1000.0)
            self.actual = int(round(self.actual_f - self.fe_extra))
            self._following(self.target - self.actual)
        elif self.state == P.QUICK_STOP and self.mode() == P.MODE_CSP:
            self._quick_stop_ramp()
        else:
            self.csp_v = 0.0
        # the move from this SYNC to the next (a quick stop's ramp too), for
        # the touch probe's latch
        self.move_sync, self.move_from, self.move_to = (
            sync_no,
            pos_from,
            self.actual_f - self.fe_extra,
        )
        self.sim.touch_probe_moved(self, sync_no)
        self._send_inputs(t, "change")
        if self.mode() == MODE_PV:
            fresh = tgt is not None
            self._velocity()
            sent = vel  # a pv drive's row: target and actual velocities, counts/s
        self.rec.sync((sync_no, self.id, t, self.state, self.cw, tgt, fresh, sent, sw))

    def _quick_stop_ramp(self) -> None:
        """CSP quick stop (0x605A 1/2: the profile deceleration 0x6084 /
        the quick stop deceleration 0x6085, then switch on disabled; 5/6:
        the same, staying in quick stop active): the axis brakes from its
        speed on the drive's own ramp, whatever the master sends."""
        per_s = self.p_period_ms / 1000.0
        dec = self.p_pv_dec if self.p_quick_stop in (1, 5) else self.p_qs_dec
        v = self.csp_v
        step = dec * per_s
        v = 0.0 if abs(v) <= step else v - step * (1 if v > 0 else -1)
        self.actual_f += v * per_s
        self.actual = int(round(self.actual_f - self.fe_extra))
        self.csp_v = v
        if v == 0.0 and self.p_quick_stop in (1, 2):
            self._set_state(P.SWITCH_ON_DISABLED, "quick stop done")  # 12

    def vel_actual(self) -> int:
        return int(round(self.vel_f - self.load_drop))

    def _velocity(self) -> None:
        """Profile velocity mode, one SYNC: the velocity ramps toward the target
        velocity 0x60FF at the profile acceleration 0x6083 (speeding up) or
        deceleration 0x6084 (slowing down); not in operation enabled (disabled,
        quick stop, fault) toward 0 at the deceleration (the drive brakes the
        spindle by itself). The position turns with it."""
        per_s = self.p_period_ms / 1000.0
        want = float(self.vel_target) if self.state == P.OPERATION_ENABLED else 0.0
        up = abs(want) > abs(self.vel_f) and want * self.vel_f >= 0
        step = (self.p_pv_acc if up else self.p_pv_dec) * per_s
        err = want - self.vel_f
        self.vel_f += err if abs(err) <= step else (step if err > 0 else -step)
        self.actual_f += self.vel_f * per_s
        self.actual = int(round(self.actual_f))

    def _switch_on(self, which: str, pos: int) -> bool:
        at = self.switches.get(which)
        if at is None:
            return False
        return pos <= at if which in ("neg", "nhome") else pos >= at

    def _homing(self, sync_no: int) -> None:
        """CiA 402 homing mode, one SYNC: started by controlword bit 4's
        rising edge, the method's moves (HOMING_METHODS); at the home
        position, position actual := home offset (0x607C), homing attained."""
        od = self.sim.od_int
        n = self.node
        start = bool(self.cw & 0x10) and not (self._cw_prev_home & 0x10)
        self._cw_prev_home = self.cw
        if start:
            method = od(n, 0x6098, "<b")
            self.home_method = method
            self.home_attained = False
            self.rec.event(
                self.id, "homing", phase="start", method=method, at=self.actual, sync=sync_no
            )
            which, toward, index = HOMING_METHODS[method]
            if toward == 0:
                self._home_here(sync_no, self.actual_f)
                return
            why = None
            if which is not None and which not in self.switches:
                why = f"no {which} switch"
            elif index and self.index_rev <= 0:
                why = "no index pulse"
            if why is not None:
                self.home_phase = "error"
                self.rec.event(self.id, "homing", phase="error", why=why, sync=sync_no)
                return
            self.home_index = index
            self.home_dir = toward
            if which is None:
                self.home_phase = "index"  # 33/34: toward the first index pulse
            else:
                self.home_switch = which
                # on it already: off it at the latch speed (the same edge)
                on = self._switch_on(which, self.actual)
                self.home_phase = "latch" if on else "search"
            return
        if self.home_phase in ("idle", "done", "error") or self.home_stall:
            return
        per_s = self.p_period_ms / 1000.0
        frm = self.actual_f
        if self.home_phase == "search":
            v = od(n, 0x6099, "<I", 1)
            self.home_v = float(v)
            self.actual_f += self.home_dir * v * per_s
            self.actual = int(round(self.actual_f))
            if self._switch_on(self.home_switch, self.actual):
                self.home_phase = "brake"
                self.rec.event(self.id, "homing", phase="switch", at=self.actual, sync=sync_no)
        elif self.home_phase == "brake":
            # past the switch at the homing acceleration 0x609A, to rest
            self.home_v = max(0.0, self.home_v - od(n, 0x609A, "<I") * per_s)
            self.actual_f += self.home_dir * self.home_v * per_s
            self.actual = int(round(self.actual_f))
            if self.home_v == 0.0:
                self.home_phase = "latch"
        elif self.home_phase == "latch":
            v = od(n, 0x6099, "<I", 2)
            self.actual_f -= self.home_dir * v * per_s
            self.actual = int(round(self.actual_f))
            if not self._switch_on(self.home_switch, self.actual):
                if not self.home_index:
                    self._home_here(sync_no, self.actual_f)
                    return
                # on to the first index pulse beyond the edge, this way
                self.rec.event(self.id, "homing", phase="edge", at=self.actual, sync=sync_no)
                self.home_phase = "index"
                self.home_dir = -self.home_dir
                frm = self.actual_f  # a pulse from the edge on
                self._index_step(sync_no, frm, frm)
        elif self.home_phase == "index":
            v = od(n, 0x6099, "<I", 2)
            self.actual_f += self.home_dir * v * per_s
            self.actual = int(round(self.actual_f))
            self._index_step(sync_no, frm, self.actual_f)
        else:  # return: back onto the home position at the latch speed
            off = float(od(n, 0x607C, "<i"))
            step = od(n, 0x6099, "<I", 2) * per_s
            d = off - self.actual_f
            self.actual_f = off if abs(d) <= step else self.actual_f + step * (1 if d > 0 else -1)
            self.actual = int(round(self.actual_f))
            if self.actual_f == off:
                self.home_phase = "done"
                self.rec.event(self.id, "homing", phase="done", at=self.actual, sync=sync_no)

    def _index_step(self, sync_no: int, a: float, b: float) -> None:
        """An index pulse passed between a and b (moving home_dir, a
        excluded unless a == b): the drive latches the pulse's position (its
        encoder's own capture, not where the SYNC finds it), that is home;
        it goes on moving back onto it (homing attained, target not reached
        until it stands there)."""
        rev, ph = float(self.index_rev), self.index_at
        k = (a - ph) / rev
        if self.home_dir > 0:
            q = ph + (math.floor(k) + (0 if a == b else 1)) * rev
            hit = a <= q <= b if a == b else a < q <= b
        else:
            q = ph + (math.ceil(k) - (0 if a == b else 1)) * rev
            hit = b <= q <= a if a == b else b <= q < a
        if hit:
            self._home_here(sync_no, q, done=False)

    def _home_here(self, sync_no: int, at: float, done: bool = True) -> None:
        """The home position is at (counts, the current reference): it
        becomes the home offset 0x607C; done: the axis stands there."""
        offset = self.sim.od_int(self.node, 0x607C, "<i")
        self.rec.event(
            self.id,
            "homing",
            phase="done" if done else "index",
            at=self.actual,
            home=round(at, 3),
            offset=offset,
            sync=sync_no,
        )
        # the reference moves, not the axis: the switches and the index
        # pulses move with it
        shift = offset - at
        self.switches = {k: int(round(v + shift)) for k, v in self.switches.items()}
        if self.index_rev > 0:
            self.index_at = math.fmod(self.index_at + shift, float(self.index_rev))
        self.actual_f += shift
        self.actual = int(round(self.actual_f))
        self.target = self.actual
        self.home_attained = True
        self.home_phase = "done" if done else "return"

    def _following(self, fe: int) -> None:
        """CiA 402: statusword bit 13 while |following error| > 0x6065 for
        longer than 0x6066 ms; the drive then faults (EMCY 0x8611)."""
        win = self.p_window
        if win == FE_WINDOW_OFF or abs(fe) <= win:
            self.fe_cycles = 0
            return
        self.fe_cycles += 1
        if self.fe_cycles * self.p_period_ms > self.p_fe_ms:
            self.fault(
                0x8611, f"following error {fe} counts > window {win} for {self.fe_cycles} periods"
            )

    # ------------------------------------------------------------ injections
    def inject(self, what: str, arg: str | None = None) -> None:
        """Fault injection (at start or at run time), recorded as an event."""
        self.rec.event(self.id, "inject", what=what, arg=arg)
        if self.inject_common(what, arg):
            return
        if what == "fault":
            self.fault(int(arg, 0) if arg else 0x2310, "injected")
        elif what == "leave-enabled":
            if self.state in (P.OPERATION_ENABLED, P.SWITCHED_ON, P.READY, P.QUICK_STOP):
                self._set_state(P.SWITCH_ON_DISABLED, "injected: voltage lost")
        elif what == "follow-error":
            self.follow_error_rate = float(arg or 1)
        elif what == "refuse":
            obj, _, code = (arg or "").partition(",")
            idx, _, sub = obj.partition(":")
            key = (int(idx, 16), int(sub, 0) if sub else None)
            self.refuse[key] = int(code, 0) if code else 0x08000022
        elif what == "move":
            # a disabled axis pushed by hand (or by gravity): ARG counts more;
            # an enabled drive holds its position against it
            if self.state == P.OPERATION_ENABLED:
                self.rec.event(self.id, "move_refused", why="operation enabled: holding")
            else:
                self.actual += int(arg or "0", 0)
                self.actual_f = float(self.actual)
                self.target = self.actual
                self._publish()
                self.rec.event(self.id, "moved", to=self.actual, state=self.state)
        elif what == "load":
            # a spindle drive: ARG counts/s of its velocity lost to a load it cannot
            # hold (0: none); the ramp goes on, what it reports drops
            self.load_drop = float(arg or "0")
        elif what == "touch-probe":
            # the touch probe wired to every drive's input 1 touches a surface
            # at COUNTS of this drive's position: on at and below (or above) it
            self.sim.set_touch_surface(self.id, arg)
        elif what == "di":
            # the digital input BIT of 0x60FD forced to 0 or 1 (auto: from the
            # switches again): BIT=0|1|auto
            bit_s, _, val = (arg or "").partition("=")
            bit = int(bit_s, 0)
            if not 0 <= bit <= 31 or val not in ("0", "1", "auto"):
                raise ValueError(f"di '{arg}': expected BIT=0|1|auto, BIT 0..31")
            if val == "auto":
                self.di_force.pop(bit, None)
            else:
                self.di_force[bit] = int(val)
            self._publish()
            self._send_inputs(time.time(), f"injected di {arg}")
        elif what == "di-silent":
            self.di_silent = arg != "off"  # TPDO3 no longer sent (stale inputs)
        elif what == "di-garbled":
            self._send_garbled(int(arg, 0) if arg else self.digital_inputs())
        elif what == "homing-stall":
            self.home_stall = arg != "off"  # a homing that never ends (a timeout)
        elif what == "never-enable":
            self.never_enable = arg != "off"
        else:
            raise ValueError(f"unknown injection '{what}'")


class DriveSim:
    """N drives on one bus (one canopen Network, one python-can bus)."""

    def __init__(
        self,
        channel: str,
        drives: Iterable["DriveSpec"],
        rec: Recorder,
        bus: can.BusABC | None = None,
        sync_id: int = 0x80,
    ) -> None:
        self.channel = channel
        self.sync_id = sync_id
        self.rec = rec
        self.lock = threading.RLock()
        self.drives: dict[int, Drive] = {}
        self.modules: dict[int, Any] = {}  # CiA 401 I/O modules (mlipcan.io401.IoModule)
        self.network = canopen.Network(bus)
        self.sync_no = 0
        self.t_last_sync: float | None = None
        self.prev_sync_t: float | None = None  # the SYNC before the last one
        self.judge_via = "sync"  # what the heartbeat consumers are judged at now
        self.stalls = 0  # this simulator not running (own_stall): how often, longest (s)
        self.stall_s = 0.0
        self.cycle_cpu_s = 0.0
        self.cycles = 0
        self.last_rx_mono = time.monotonic()  # when the last frame was taken off the bus
        self.last_rx_t = 0.0  # its receive time (kernel clock, s): the bus time reached
        self.rx_busy = False  # fast receive: a batch taken off the socket, not all handled
        self._stopping = False
        self._pump: threading.Thread | None = None
        self.pump_errors = 0
        self.socket_drops: int | None = None  # fast receive: the kernel's frames dropped
        # the touch probe's surface: (drive node, counts, on below it), its input, edges
        self.touch: tuple[int, int, bool] | None = None
        self.touch_on = False
        self.touch_edges = 0
        self.touch_edge: tuple[int, float, bool, int] | None = None  # sync, frac, positive, n
        for spec in drives:
            d = Drive(self, **spec)
            self.drives[d.id] = d

    # helpers reading this node's OD (stored data or the default)
    @staticmethod
    def od_u32(node: canopen.LocalNode, index: int, sub: int = 0) -> int:
        return DriveSim.od_int(node, index, "<I", sub)

    @staticmethod
    def od_int(node: canopen.LocalNode, index: int, fmt: str, sub: int = 0) -> int:
        raw = node.data_store.get(index, {}).get(sub)
        if raw is None:
            obj = node._find_object(index, sub)
            return int(obj.default)
        return int(struct.unpack(fmt, raw)[0])

    def period_ms(self, node: canopen.LocalNode) -> float:
        """0x60C2: value x 10^index s, in ms."""
        v = self.od_int(node, 0x60C2, "B", 1)
        e = self.od_int(node, 0x60C2, "<b", 2)
        return v * 10.0 ** (e + 3)

    def start(self, absent: Iterable[int] = (), fast: bool = False) -> None:
        """Open the bus, then power the drives up. fast: frames are read with
        the listener's recvmmsg batches (mlipcan.sources) from the bus's own
        socket and handed to canopen's Network.notify, instead of python-can's
        Notifier (Bus.recv costs ~1-2.6 ms a frame in the emulated VM: three
        drives at a 4 ms SYNC fall behind the bus there)."""
        if self.network.bus is None:
            from .bus import open_bus

            self.network.bus = open_bus(self.channel)
        if not fast:  # python-can reads it; a simulator behind the bus must not lose frames
            from .layout import SO_RCVBUFFORCE

            sock = getattr(self.network.bus, "socket", None)
            if isinstance(sock, socket.socket):  # not python-can's virtual bus (the host test)
                try:
                    sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, 16 << 20)
                except OSError:
                    pass  # not root
        if fast:
            self.socket_drops = 0
            self._pump = threading.Thread(
                target=self._pump_frames, name="drive-sim rx", daemon=True
            )
            self._pump.start()
        else:
            # canopen types its listeners as its own MessageListener; the
            # Notifier it makes takes any can.Listener
            self.network.listeners.append(cast(Any, SeenListener(self)))
            self.network.connect()
        # the SYNC count, before any drive's handler sees the SYNC
        self.network.subscribe(self.sync_id, self._count_sync)
        absent = set(absent)
        with self.lock:
            for d in self.drives.values():
                if d.id in absent:
                    self.rec.event(d.id, "absent", why="at start")
                    continue
                d.attach(self.network)
            for m in self.modules.values():
                if m.id in absent:
                    self.rec.event(m.id, "absent", why="at start")
                    continue
                m.attach(self.network)

    def add_module(self, node_id: int, heartbeat_ms: int) -> None:
        """A CiA 401 I/O module on the same bus (before start())."""
        from .io401 import IoModule

        self.modules[node_id] = IoModule(self, node_id, heartbeat_ms)

    def _pump_frames(self) -> None:
        from .sources import Batch, MMsg, bus_socket, tune_socket

        assert self.network.bus is not None
        sock = bus_socket(self.network.bus)
        # 20 ms without a frame: a silent bus (judged below)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, struct.pack("ll", 0, 20000))
        # a simulator running behind the bus must not lose frames: a large
        # buffer, and the kernel's drop counter (reported at exit)
        tune_socket(sock, self.channel, 16 << 20, False, {})
        mm = MMsg(sock)
        notify = self.network.notify
        m0, c0 = time.monotonic(), time.thread_time()
        while not self._stopping:
            self.rx_busy = False
            k = mm.recv()
            # the time since the last receive returned that this thread did
            # not run (not its CPU time, not the receive's 20 ms timeout):
            # beyond OWN_STALL_S it was not running (starved, or its emulator
            # descheduled by the host: every process in it stopped at once)
            m1, c1 = time.monotonic(), time.thread_time()
            late = (m1 - m0) - (c1 - c0) - 0.02
            m0, c0 = m1, c1
            if late > OWN_STALL_S:
                self.own_stall(late)
            if not k:
                # nothing for 20 ms and every frame before handled (by this
                # thread, in order): the wall clock is the bus time now
                if self.last_rx_t > 0.0:
                    self._judge(max(self.last_rx_t, time.time()), "silent bus")
                continue
            self.rx_busy = True
            B = Batch(mm, k, 1)
            if B.drops is not None:
                self.socket_drops = B.drops
            ids, bad = B.ids, B.raw_bad
            for j in range(k):
                if bad[j]:
                    continue
                self.last_rx_t = B.t(j) / 1e9
                self.last_rx_mono = time.monotonic()
                try:
                    notify(ids[j], bytearray(B.data(j)), B.t(j) / 1e9)
                except Exception as e:  # as canopen's own listener: log, go on
                    self.pump_errors += 1
                    if self.pump_errors <= 5:
                        print(
                            f"mlip-drive-sim: frame 0x{ids[j]:03X}: {e!r}",
                            file=sys.stderr,
                            flush=True,
                        )
            # judged at the newest frame's receive time, every frame before
            # it handled: frame order, whatever this thread's own lateness
            self._judge(self.last_rx_t, "bus")

    def _count_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        with self.lock:
            self.sync_no += 1
            self.prev_sync_t = self.t_last_sync
            self.t_last_sync = timestamp
            self.last_rx_mono = time.monotonic()
            self._judge(timestamp, "sync")
            for m in self.modules.values():
                if m.present:
                    # the outputs in force at this SYNC (what the RPDOs before it set)
                    self.rec.io_row((self.sync_no, m.id, timestamp, *m.outputs_row()))

    def own_stall(self, s: float) -> None:
        """This simulator was not running for s seconds. A drive's consumer
        counts the time the drive listens: a stall of the whole emulated host
        stops the producer too, and the kernel's timers (the drives' own
        heartbeats) then put frames stamped after the stall on the bus before
        the producer runs again, so frame order alone would blame it for the
        simulator's own stall (EMCY 0x8130 with the master's heartbeat the
        next frame). A producer that is really gone is still judged, s later."""
        with self.lock:
            self.stalls += 1
            self.stall_s = max(self.stall_s, s)
            for d in self.drives.values():
                d.stalled(s)
            for m in self.modules.values():
                if m.master_seen is not None:
                    m.master_seen += s
        self.rec.event(0, "own_stall", s=round(s, 3), sync=self.sync_no)

    def _judge(self, now: float, via: str) -> None:
        """Every consumed heartbeat judged at bus time now (CiA 301: the
        consumer time counted from the last heartbeat received before it)."""
        with self.lock:
            self.judge_via = via
            for d in self.drives.values():
                if d.present:
                    d.check_heartbeats(now)
            for m in self.modules.values():
                if m.present:
                    m.check_heartbeats(now)

    def on_sync(self, drive: Drive, t: float) -> None:
        """Called once per drive per SYNC (canopen calls each subscriber)."""
        with self.lock:
            c0 = time.thread_time()
            drive.cycle(self.sync_no, t)
            for m in self.modules.values():
                if m.present:
                    m.follow(drive.id, drive.actual, self.sync_no)  # a probe on this axis
            self.cycle_cpu_s += time.thread_time() - c0
            self.cycles += 1

    def set_touch_surface(self, node: int, arg: str | None) -> None:
        """touch-probe=COUNTS,below|above on drive NODE (off: none)."""
        if arg in (None, "off"):
            self.touch = None
            return
        counts, _, side = (arg or "").partition(",")
        if side not in ("below", "above"):
            raise ValueError(f"touch-probe '{arg}': expected COUNTS,below|above or off")
        self.touch = (node, int(counts, 0), side == "below")
        d = self.drives[node]
        self.touch_on = self._touching(d.actual_f - d.fe_extra)

    def _touching(self, pos: float) -> bool:
        assert self.touch is not None
        _, s, below = self.touch
        return pos <= s if below else pos >= s

    def touch_probe_moved(self, drive: "Drive", sync_no: int) -> None:
        """After a drive's move at this SYNC: the surface drive's move may
        cross the surface (an edge at a fraction of the period, the same
        instant for every drive: one wire to every touch probe input); each
        drive latches where its own move is at that instant (a drive that
        moves later in this SYNC's handling latches when it has)."""
        if self.touch is not None and drive.id == self.touch[0]:
            on = self._touching(drive.move_to)
            if on != self.touch_on:
                self.touch_on = on
                s, a, b = self.touch[1], drive.move_from, drive.move_to
                frac = (s - a) / (b - a) if b != a else 1.0
                self.touch_edges += 1
                self.touch_edge = (sync_no, min(1.0, max(0.0, frac)), on, self.touch_edges)
                self.rec.event(drive.id, "touch_input", on=on, sync=sync_no, frac=round(frac, 6))
                for d in self.drives.values():
                    d.touch_probe_edge(frac, on, sync_no, self.touch_edges)
                return
        e = self.touch_edge
        if e is not None and e[0] == sync_no:
            drive.touch_probe_edge(e[1], e[2], sync_no, e[3])

    def inject(self, node: int, what: str, arg: str | None = None) -> None:
        with self.lock:
            if node in self.modules:
                self.modules[node].inject(what, arg)
                return
            if node not in self.drives:
                raise ValueError(f"no drive with node id {node}")
            self.drives[node].inject(what, arg)

    def tick(self) -> None:
        """Main thread, every few ms: records to disk. Fast receive: the
        heartbeat consumers are judged by the receiving thread itself (at
        each SYNC, after each batch at its newest frame's receive time, and
        at the wall clock when a receive found the bus silent for 20 ms), so
        never at a bus time whose frames are not all handled yet. python-can's
        receive (its Notifier's thread): judged here at the receive time of
        the newest frame taken off the bus (frame order: a simulator running
        behind the bus does not blame the producer for its own lateness), or
        by the wall clock once nothing has been taken off the bus for 50 ms
        and nothing waits to be (a silent bus). Without SYNCs other frames
        (the drives' own heartbeats, sent by the kernel's timer) still flow,
        so the bus time must come from them too."""
        if self._pump is not None:
            self.rec.flush()
            return
        now = self.last_rx_t
        if time.monotonic() - self.last_rx_mono > 0.05 and self._rx_drained():
            now = max(now, time.time())
        if now > 0.0:
            self._judge(now, "tick")
        self.rec.flush()

    def _rx_drained(self) -> bool:
        """Every frame on the bus so far handled: no batch being handled and
        none queued in the socket. A receive thread stalled for longer than
        the 50 ms (a loaded VM: a descheduled process, a slow disk write of
        the records) is behind, not on a silent bus: the wall clock would
        judge its backlog's heartbeats lost before it reads them (EMCY 0x8130
        with the master's heartbeat on the bus all along)."""
        if self.rx_busy:
            return False
        sock = getattr(self.network.bus, "socket", None)
        if not isinstance(sock, socket.socket):
            return True  # python-can's virtual bus (host tests): nothing to ask
        try:
            readable, _, _ = select.select([sock], [], [], 0)
        except (OSError, ValueError):
            return True  # closed
        return not readable

    def stop(self) -> None:
        with self.lock:
            for d in self.drives.values():
                if d.present:
                    d.node.nmt.stop_heartbeat()
            for m in self.modules.values():
                if m.present:
                    m.node.nmt.stop_heartbeat()
        self._stopping = True
        if self._pump is not None:
            self._pump.join(timeout=5)
        self.network.disconnect()
        self.rec.close()


class DriveSpec(TypedDict):
    """The keyword arguments of one Drive (DriveSim's drives)."""

    node_id: int
    start_position: int
    start_state: str
    heartbeat_ms: int
    lag_alpha: float
    switches: dict[str, int]


class SeenListener(can.Listener):
    """python-can's path: the receive time of the newest frame taken off the
    bus, the bus time the heartbeat consumers are judged at (DriveSim.tick)."""

    def __init__(self, sim: DriveSim) -> None:
        self.sim = sim

    def on_message_received(self, msg: can.Message) -> None:
        self.sim.last_rx_t = msg.timestamp
        self.sim.last_rx_mono = time.monotonic()
