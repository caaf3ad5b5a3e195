"""The simulated CiA 402 drives (mlip-drive-sim) on a real vcan0,
driven by an independent master: canopen's RemoteNode (SDO client, NMT
master, EMCY consumer, PDO configuration) and raw SYNC/RPDO frames from this
process. What the drives must do is what CiA 301 / CiA 402 say; what they
recorded (events.jsonl, sync.csv) is judged against what was sent.

One simulator process for the module (a Python start with canopen costs
20-40 s in the emulated VM), seven drives:
  1, 2, 3  healthy, start positions 1234, -5000, 250500 counts
  4        refuses writes to 0x6060 (abort 0x06090030), injected at start
  5        powers up in "fault" and never reaches "operation enabled"
  6        absent from the start
The tests run in file order (module state: NMT, power states).

SYNCs are sent in lockstep: SYNC, wait for the TPDO of every enabled drive,
then the RPDOs; so frame order, not timing, decides, and the results are
exact even in the slow emulated VM.
"""
import json
import struct
import sys
import threading
import time
from pathlib import Path

import pytest

from conftest import S
from mlipcan import listen, procs, sources

from mlipcan import cia402 as P

NODES = [1, 2, 3, 4, 5, 6]
HEALTHY = [1, 2, 3]
START = {1: 1234, 2: -5000, 3: 250500}
PERIOD_MS = 4       # 0x60C2 written: 4 x 10^-3 s
FE_WINDOW = 5000    # 0x6065, counts
HB_MS = 50          # 0x1017 written to the healthy drives
T_WAIT = 20.0 if S.in_vm else 5.0


class Frames:
    """Every frame this process receives (a python-can listener on canopen's
    notifier), with a condition to wait on."""

    def __init__(self):
        self.frames = []  # (monotonic, id, bytes)
        self.cv = threading.Condition()

    def on_message_received(self, msg):
        with self.cv:
            self.frames.append((time.monotonic(), msg.arbitration_id, bytes(msg.data)))
            self.cv.notify_all()

    __call__ = on_message_received  # can.Notifier calls its listeners

    def stop(self):
        pass

    def mark(self):
        with self.cv:
            return len(self.frames)

    def since(self, mark, cob=None):
        with self.cv:
            return [f for f in self.frames[mark:] if cob is None or f[1] == cob]

    def wait(self, pred, timeout=T_WAIT, what="frames"):
        t_end = time.monotonic() + timeout
        with self.cv:
            while True:
                r = pred()
                if r:
                    return r
                left = t_end - time.monotonic()
                if left <= 0:
                    raise AssertionError(f"no {what} within {timeout} s")
                self.cv.wait(left)

    def wait_for(self, mark, cob, timeout=T_WAIT):
        return self.wait(lambda: [f for f in self.frames[mark:] if f[1] == cob], timeout,
                         f"frame 0x{cob:03X}")[0]


class Bench:
    def __init__(self, tmp):
        import canopen  # slow in the emulated VM: only when these tests run

        from mlipcan import drive as D

        self.canopen = canopen
        self.tmp = tmp
        self.frames = Frames()
        self.net = canopen.Network()
        self.net.listeners.append(self.frames)
        self.net.connect(interface="socketcan", channel=S.iface)
        self.nodes = {}
        for n in NODES:
            r = self.net.add_node(n, D.build_od(n))  # the master's view of the OD
            r.sdo.RESPONSE_TIMEOUT = T_WAIT / 4
            self.nodes[n] = r
        self.mark0 = self.frames.mark()
        self.sim = procs.DriveSimProc(S, tmp, nodes=NODES, starts=START, states={5: "fault"},
                              inject=["4:refuse=0x6060,0x06090030", "5:never-enable", "6:absent"])
        self.proc = self.sim.proc
        self.inject, self.events, self.wait_event = \
            self.sim.inject, self.sim.events, self.sim.wait_event
        self.targets = {n: [] for n in HEALTHY}  # every target sent, in order

    def cycle(self, targets, cw=0x0F, expect=HEALTHY):
        """SYNC; the TPDO of each node in expect; then one RPDO per node of
        targets (controlword cw + target). Returns {node: (statusword, actual)}."""
        m = self.frames.mark()
        self.net.send_message(0x80, b"")
        got = {}
        for n in expect:
            _, _, d = self.frames.wait_for(m, 0x180 + n)
            assert len(d) == 6, f"node {n}: TPDO of {len(d)} bytes: {d.hex()}"
            got[n] = struct.unpack("<Hi", d)
        for n, t in targets.items():
            self.net.send_message(0x200 + n, struct.pack("<Hi", cw, t))
            self.targets[n].append(t)
        return got

    def close(self):
        try:
            self.sim.stop(timeout=60)
        finally:
            self.net.disconnect()


@pytest.fixture(scope="module")
def bench(vcan, tmp_path_factory):
    b = Bench(tmp_path_factory.mktemp("drivesim"))
    yield b
    b.close()
    assert b.proc.rc == 0, b.proc.stderr()
    print(b.proc.stderr().strip().splitlines()[-1])  # SYNCs, CPU per drive cycle


def test_bootup_and_absent_drive(bench):
    """Boot-up (0x700 + node, one byte 0) from each present drive, then its
    heartbeat (0x7F pre-operational); nothing from the absent one, whose
    SDO requests time out."""
    b = bench
    for n in NODES[:-1]:
        _, _, d = b.frames.wait_for(b.mark0, 0x700 + n)
        assert d == b"\x00", f"node {n}: first 0x{0x700 + n:03X} frame {d.hex()} is no boot-up"
    for n in NODES[:-1]:
        b.frames.wait(lambda: len(b.frames.since(b.mark0, 0x700 + n)) >= 2, what=f"heartbeat {n}")
        assert b.frames.since(b.mark0, 0x700 + n)[1][2] == b"\x7f"
    assert not b.frames.since(b.mark0, 0x706)
    b.nodes[6].sdo.RESPONSE_TIMEOUT = 1.0
    with pytest.raises(b.canopen.SdoCommunicationError):
        b.nodes[6].sdo[0x1000].raw
    assert b.events("absent", 6)


def test_sdo_configuration_read_back(bench):
    """Each configuration write reads back; the identity and start positions
    are there; a refused write names its abort code; the drive recorded every
    write with its value or abort code."""
    b = bench
    for n in HEALTHY:
        r = b.nodes[n]
        assert r.sdo[0x1000].raw == 0x00020192
        assert r.sdo[0x1018][2].raw == 0x4D4C4950
        assert r.sdo[0x6064].raw == START[n], f"node {n}: position actual value"
        for obj, val in (((0x6060,), P.MODE_CSP), ((0x60C2, 1), PERIOD_MS), ((0x60C2, 2), -3),
                         ((0x6065,), FE_WINDOW), ((0x1017,), HB_MS)):
            v = r.sdo[obj[0]] if len(obj) == 1 else r.sdo[obj[0]][obj[1]]
            v.raw = val
            assert v.raw == val, f"node {n} 0x{obj[0]:04X}: wrote {val}, read {v.raw}"
        assert r.sdo[0x6061].raw == P.MODE_CSP
        # PDO mapping through canopen's own PdoMap (disable, map, enable: CiA 301)
        r.rpdo.read()
        r.tpdo.read()
        rp, tp = r.rpdo[1], r.tpdo[1]
        rp.clear()
        rp.add_variable(0x6040)
        rp.add_variable(0x607A)
        rp.trans_type, rp.enabled = 1, True
        tp.clear()
        tp.add_variable(0x6041)
        tp.add_variable(0x6064)
        tp.trans_type, tp.enabled = 1, True
        r.rpdo.save()
        r.tpdo.save()
        assert r.sdo[0x1600][1].raw == 0x60400010 and r.sdo[0x1600][2].raw == 0x607A0020
        assert r.sdo[0x1A00][1].raw == 0x60410010 and r.sdo[0x1A00][2].raw == 0x60640020
        assert r.sdo[0x1400][1].raw == 0x200 + n and r.sdo[0x1800][1].raw == 0x180 + n
        assert r.sdo[0x1800][2].raw == 1
    r = b.nodes[1]
    # CiA 301: a mapping entry of a valid PDO cannot change; a mode the drive lacks
    # (1, profile position: it has 0, 3, 6 and 8) is refused
    with pytest.raises(b.canopen.SdoAbortedError) as e:
        r.sdo[0x1600][1].raw = 0x60410010
    assert e.value.code == 0x06010000
    with pytest.raises(b.canopen.SdoAbortedError) as e:
        r.sdo[0x6060].raw = 1
    assert e.value.code == 0x06090030
    with pytest.raises(b.canopen.SdoAbortedError) as e:
        b.nodes[4].sdo[0x6060].raw = 8
    assert e.value.code == 0x06090030
    writes = b.events("sdo_write", 4)
    assert writes and writes[-1]["index"] == "0x6060" and writes[-1]["abort"] == "0x06090030"
    w1 = [(e["index"], e["sub"], e.get("value"), e.get("abort")) for e in b.events("sdo_write", 1)]
    assert ("0x6060", 0, 8, None) in w1 and ("0x60C2", 1, PERIOD_MS, None) in w1
    assert ("0x6065", 0, FE_WINDOW, None) in w1 and ("0x6060", 0, None, "0x06090030") in w1
    # the heartbeat now every HB_MS
    m = b.frames.mark()
    b.frames.wait(lambda: len(b.frames.since(m, 0x701)) >= 6, what="6 heartbeats")
    ts = [f[0] for f in b.frames.since(m, 0x701)]
    gaps = [y - x for x, y in zip(ts[1:], ts[2:])]
    if not S.in_vm:  # the emulated VM delays user space by tens of ms at times
        assert all(0.5 * HB_MS / 1e3 < g < 2 * HB_MS / 1e3 for g in gaps), gaps


def sdo_state(r):
    return P.state_of(r.sdo[0x6041].raw)


def test_nmt_start_and_power_state_machine(bench):
    """NMT start; shutdown, switch on, enable operation, each step confirmed
    by the statusword; the drive in fault needs a fault reset and then
    never reaches operation enabled (injected)."""
    b = bench
    for n in HEALTHY + [5]:
        b.nodes[n].nmt.state = "OPERATIONAL"
    for n in HEALTHY:
        r = b.nodes[n]
        assert sdo_state(r) == P.SWITCH_ON_DISABLED
        for cw, want in ((0x06, P.READY), (0x07, P.SWITCHED_ON), (0x0F, P.OPERATION_ENABLED)):
            r.sdo[0x6040].raw = cw
            assert sdo_state(r) == want, f"node {n}: controlword 0x{cw:02X}"
        sw = r.sdo[0x6041].raw
        assert sw & P.SW_CSP_FOLLOWING and sw & P.SW_VOLTAGE_ENABLED and sw & P.SW_QUICK_STOP
    r5 = b.nodes[5]
    assert sdo_state(r5) == P.FAULT
    r5.sdo[0x6040].raw = 0x06
    assert sdo_state(r5) == P.FAULT, "shutdown must not leave fault"
    r5.sdo[0x6040].raw = 0x80
    assert sdo_state(r5) == P.SWITCH_ON_DISABLED
    for cw in (0x06, 0x07, 0x0F):
        r5.sdo[0x6040].raw = cw
    assert sdo_state(r5) == P.SWITCHED_ON
    assert b.events("refused_enable", 5)
    for n in HEALTHY:
        path = [e["to"] for e in b.events("state", n)]
        assert path[-3:] == [P.READY, P.SWITCHED_ON, P.OPERATION_ENABLED], path
        assert [e["to"] for e in b.events("nmt", n)][-1] == "OPERATIONAL"
    # the heartbeat says operational (0x05)
    m = b.frames.mark()
    _, _, d = b.frames.wait_for(m, 0x701)
    assert d == b"\x05"


def test_csp_follows_targets_on_sync(bench):
    """In CSP the TPDO at SYNC j carries the target of the RPDO sent after
    SYNC j-2 (applied at SYNC j-1, reached one period later), to the count;
    the drive recorded every target at the SYNC it applied it."""
    b = bench
    n_cyc = 40
    sent, got = [], []
    # the listener on python-can (can.Bus, can.Notifier, can.Logger to .blf)
    # records the same bus: a fork of this process, python-can already imported
    w = b.tmp
    largs = ["--can", S.iface, "--config", str(S.config_dir / "mill-3axis.ini"), "--drives",
             "--receive", "python-can", "--json", str(w / "can.json"),
             "--tpdo-csv", str(w / "tpdo.csv"), "--log", str(w / "can.blf")]

    def listener():
        sources.STOP.clear()
        return listen.main(largs, settings=S)

    lis = procs.Proc("listen", largs, w, fn=listener)
    lis.wait_for("listening on")
    try:
        for j in range(n_cyc):
            tg = {n: START[n] + 37 * j * (1 if n != 2 else -1) for n in HEALTHY}
            got.append(b.cycle(tg))
            sent.append(tg)
        # a frame after our last RPDOs (a drive's heartbeat): the bus has
        # delivered them to every socket, the listener's too, whose SIGTERM
        # reads what is queued
        m = b.frames.mark()
        b.frames.wait(lambda: b.frames.since(m), what="a frame after the last RPDOs")
    finally:
        assert lis.terminate() == 0, lis.stderr()
    for n in HEALTHY:
        acts = [g[n][1] for g in got]
        assert acts[0] == START[n] and acts[1] == START[n]
        for j in range(2, n_cyc):
            assert acts[j] == sent[j - 2][n], f"node {n} SYNC {j}: actual {acts[j]}, " \
                                              f"target sent after SYNC {j - 2}: {sent[j - 2][n]}"
        for sw, _ in (g[n] for g in got):
            assert P.state_of(sw) == P.OPERATION_ENABLED and sw & P.SW_CSP_FOLLOWING
            assert not sw & P.SW_FOLLOWING_ERROR
    # the drive's record: the targets applied, in order, all of them but the last
    rows = b.sim.wait_sync_rows(lambda rows: all(
        len([r for r in rows if r["node"] == n and r["fresh"]]) >= n_cyc - 1 for n in HEALTHY))
    for n in HEALTHY:
        applied = [r["target"] for r in rows if r["node"] == n and r["fresh"]]
        assert applied[:n_cyc - 1] == [s[n] for s in sent[:n_cyc - 1]]
    # the listener: n_cyc cycles of 6-byte RPDOs carrying what was sent, and
    # every TPDO the master received, in order
    rep = json.loads((w / "can.json").read_text())
    assert rep["receive"].startswith("python-can") and rep["cycles"] == n_cyc, (
        {k: rep.get(k) for k in ("receive", "cycles", "frames", "frames_ours", "first_cycle",
                                 "last_cycle", "incomplete", "wall_s")}, lis.stderr()[-2000:])
    assert rep["incomplete"] == 0 and rep["malformed"] == 0
    assert rep["last"]["counts"] == {a: sent[-1][n] for a, n in zip("XYZ", HEALTHY)}
    tp = [ln.split(",") for ln in (w / "tpdo.csv").read_text().splitlines()[1:]]
    for n in HEALTHY:
        acts = [int(f[5]) for f in tp if int(f[1]) == n]
        assert acts == [g[n][1] for g in got], f"node {n}: the listener's TPDOs"
    # and the can.Logger .blf decodes offline to the same cycles
    assert listen.main(["--from-log", str(w / "can.blf"), "--config",
                          str(S.config_dir / "mill-3axis.ini"), "--drives",
                          "--json", str(w / "blf.json"), "-q"], settings=S) == 0
    rep2 = json.loads((w / "blf.json").read_text())
    assert rep2["cycles"] == n_cyc and rep2["last"]["counts"] == rep["last"]["counts"]


def hold(b, n_cyc, expect=HEALTHY, targets=None):
    """n_cyc lockstep cycles holding each healthy drive at its last target."""
    out = []
    for _ in range(n_cyc):
        tg = targets or {n: b.targets[n][-1] for n in HEALTHY}
        out.append(b.cycle(tg, expect=expect))
    return out


def test_inject_fault_emcy(bench):
    """Fault injected at run time: EMCY (0x80 + node) with the code and error
    register bit 0, the statusword's fault state in the next TPDO; the
    others go on; a fault reset (controlword bit 7 by RPDO) clears it with
    an EMCY 0x0000."""
    b = bench
    m = b.frames.mark()
    b.inject("1:fault=0x3210")
    _, _, d = b.frames.wait_for(m, 0x81)
    code, reg = struct.unpack_from("<HB", d)
    assert (code, reg & 1) == (0x3210, 1), d.hex()
    g = hold(b, 2)
    assert P.state_of(g[-1][1][0]) == P.FAULT
    assert all(P.state_of(g[-1][n][0]) == P.OPERATION_ENABLED for n in (2, 3))
    m = b.frames.mark()
    b.cycle({1: b.targets[1][-1]}, cw=0x80)
    b.cycle({1: b.targets[1][-1]}, cw=0x80)
    g = b.cycle({})
    assert P.state_of(g[1][0]) == P.SWITCH_ON_DISABLED
    assert struct.unpack_from("<H", b.frames.since(m, 0x81)[-1][2])[0] == 0x0000


def test_inject_heartbeat_stop(bench):
    """Heartbeat producer stopped on node 3: no 0x703 for 10 heartbeat
    periods while node 2's keep coming; back on when asked."""
    b = bench
    b.inject("3:heartbeat=off")
    b.wait_event(lambda e: e["kind"] == "inject" and e["node"] == 3, "heartbeat=off")
    # the time on the bus, counted in node 2's heartbeats (the kernel's timer):
    # two for one of node 3 already on its way, then ten of silence
    m = b.frames.mark()
    b.frames.wait(lambda: len(b.frames.since(m, 0x702)) >= 2, what="node 2 heartbeats")
    m = b.frames.mark()
    b.frames.wait(lambda: len(b.frames.since(m, 0x702)) >= 10, what="node 2 heartbeats")
    assert not b.frames.since(m, 0x703)
    b.inject("3:heartbeat=on")
    b.frames.wait_for(m, 0x703)


def test_inject_leave_operation_enabled(bench):
    """Node 3 drops out of operation enabled (voltage lost): its TPDO shows
    switch on disabled, without an EMCY."""
    b = bench
    m = b.frames.mark()
    b.inject("3:leave-enabled")
    b.wait_event(lambda e: e["kind"] == "state" and e["node"] == 3
                 and e["to"] == P.SWITCH_ON_DISABLED, "leave-enabled")
    g = hold(b, 1)
    assert P.state_of(g[0][3][0]) == P.SWITCH_ON_DISABLED
    assert P.state_of(g[0][2][0]) == P.OPERATION_ENABLED
    assert not b.frames.since(m, 0x83)


def test_inject_growing_following_error(bench):
    """Node 2 follows with an error growing by 1000 counts a SYNC: its TPDO
    shows it exactly; beyond the window (5000) the statusword's bit 13;
    after 0x6066 (10 ms = 3 periods of 4 ms) the drive faults, EMCY 0x8611."""
    b = bench
    m = b.frames.mark()
    b.inject("2:follow-error=1000")
    b.wait_event(lambda e: e["kind"] == "inject" and e["node"] == 2, "follow-error")
    tgt = b.targets[2][-1]
    g = hold(b, 14, expect=[2])
    errs = [tgt - x[2][1] for x in g]
    states = [P.state_of(x[2][0]) for x in g]
    k_fault = states.index(P.FAULT)
    assert errs[:k_fault] == [1000 * k for k in range(k_fault)], errs
    fe_bit = [bool(x[2][0] & P.SW_FOLLOWING_ERROR) for x in g[:k_fault]]
    assert fe_bit == [e > FE_WINDOW for e in errs[:k_fault]], (errs, fe_bit)
    # TPDO k carries the error of SYNC k-1: over the window from SYNC 5 on (6000);
    # 0x6066 = 10 ms is passed in the 3rd period of 4 ms over it (SYNC 7): fault
    # in TPDO 8
    assert k_fault == 8, (errs, states)
    _, _, d = b.frames.wait_for(m, 0x82)
    assert struct.unpack_from("<H", d)[0] == 0x8611


def test_inject_refuse_sdo_at_run_time(bench):
    b = bench
    b.inject("1:refuse=0x6065")
    b.wait_event(lambda e: e["kind"] == "inject" and e["node"] == 1 and e["what"] == "refuse",
                 "refuse")
    with pytest.raises(b.canopen.SdoAbortedError) as e:
        b.nodes[1].sdo[0x6065].raw = 1
    assert e.value.code == 0x08000022
    assert b.nodes[1].sdo[0x6065].raw == FE_WINDOW


def test_consumer_heartbeat_lost(bench):
    """Node 1 consumes the master's heartbeat (0x1016 sub 1 = node 127, 300 ms):
    while it comes nothing happens; once it stops, within the consumer time
    (plus the simulator's 5 ms poll), EMCY 0x8130 and fault."""
    b = bench
    r = b.nodes[1]
    r.sdo[0x1016][1].raw = (127 << 16) | 300
    assert r.sdo[0x1016][1].raw == (127 << 16) | 300
    task = b.net.send_periodic(0x77F, b"\x05", 0.05)
    try:
        # a second on the bus (20 of node 2's heartbeats, the kernel's timer
        # as ours): over three consumer times
        m = b.frames.mark()
        b.frames.wait(lambda: len(b.frames.since(m, 0x702)) >= 20, what="node 2 heartbeats")
        assert not b.events("heartbeat_lost", 1) and sdo_state(r) == P.SWITCH_ON_DISABLED
        m = b.frames.mark()
    finally:
        # before the stop: our last heartbeat went out at most one period
        # (50 ms) before it, however late this thread runs
        t_stop = time.monotonic()
        task.stop()
    t, _, d = b.frames.wait_for(m, 0x81)
    assert struct.unpack_from("<H", d)[0] == 0x8130
    assert t - t_stop > 0.2, "EMCY before the consumer time ran out"
    if not S.in_vm:
        assert t - t_stop < 0.3 + 0.1
    assert b.events("heartbeat_lost", 1)[0]["producer"] == 127
    assert sdo_state(r) == P.FAULT
    r.sdo[0x6040].raw = 0x80
    assert sdo_state(r) == P.SWITCH_ON_DISABLED


def test_nmt_reset_communication_and_absent(bench):
    """NMT reset communication: boot-up again, communication objects back to
    their defaults (0x1017), pre-operational. A drive made absent at run
    time stops answering and heartbeating; back present, it boots up."""
    b = bench
    m = b.frames.mark()
    b.nodes[1].nmt.send_command(0x82)
    bootup = lambda node: lambda: [f for f in b.frames.since(m, 0x700 + node) if f[2] == b"\x00"]
    b.frames.wait(bootup(1), what="boot-up of node 1")  # heartbeats (kernel timer) may come first
    assert b.frames.since(m, 0x701)[-1][2] in (b"\x00", b"\x7f")  # then pre-operational
    assert b.nodes[1].sdo[0x1017].raw == 100
    assert b.nodes[1].sdo[0x6060].raw == P.MODE_CSP  # the profile area survives
    m = b.frames.mark()
    b.inject("3:absent")
    b.wait_event(lambda e: e["kind"] == "absent" and e["node"] == 3, "absent")
    # counted in node 2's heartbeats: two for a frame of node 3 on its way,
    # then ten (0.5 s) without one
    m = b.frames.mark()
    b.frames.wait(lambda: len(b.frames.since(m, 0x702)) >= 2, what="node 2 heartbeats")
    m = b.frames.mark()
    b.frames.wait(lambda: len(b.frames.since(m, 0x702)) >= 10, what="node 2 heartbeats")
    assert not b.frames.since(m, 0x703)
    b.nodes[3].sdo.RESPONSE_TIMEOUT = 1.0
    with pytest.raises(b.canopen.SdoCommunicationError):
        b.nodes[3].sdo[0x1000].raw
    b.inject("3:present")
    _, _, d = b.frames.wait_for(m, 0x703)
    assert d == b"\x00", "the first frame of a drive back on the bus is its boot-up"
