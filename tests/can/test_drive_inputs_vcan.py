"""Limit switches wired to the drives' own digital inputs (issue 18, CiA 402
0x60FD: bit 0 negative limit, bit 1 positive limit, bit 2 home switch) on a
real vcan0, against the canopen package's drives (one simulator process),
no I/O module. mlip-rt maps 0x60FD in each such drive's TPDO3 (on change,
event timer = HEARTBEAT_MS), each SDO read back, reads it once by SDO, then
from the TPDO3s in the loop.

  - X's positive limit switch (the simulated drive's switch at 60 mm) trips
    mid-move at 100 mm/s: quick stop to every drive in one period, each axis
    braking on its drive's own ramp (0x6085, written from X's
    MAX_ACCELERATION): stop distance v^2 / 2A within one period's travel,
    deceleration never beyond A; state fault, reason naming the axis, the
    drive's node and the switch; only a jog away leaves it.
  - a garbled TPDO3 (3 bytes, the positive limit bit set) is ignored: the
    program runs on; a drive whose TPDO3 stops (its inputs stale) is a
    drive fault after HEARTBEAT_TIMEOUT_MS naming it ("digital inputs lost").

Period 40 ms and long timeouts (the emulated VM). Each test prints a
[di] line with the measured figures.
"""

import re
import time

import pytest

from conftest import DRIVES_VM, S
from mlipcan import procs

MILL = S.config_dir / "mill-3axis.ini"
PERIOD_S = 0.04
A_X = 200.0  # mm/s^2: X's MAX_ACCELERATION here (a stop long enough to measure at 40 ms)
CPU = 1000.0  # counts/mm
SWITCH_MM = 60.0
PROGRAM = "G21 G90\nG1 X150 F6000\n"  # 100 mm/s through the switch at 60 mm


def machine(tmp, tail=""):
    """mill-3axis at 40 ms, X at A = 200 mm/s^2 with its drive's own switches
    (LIMIT_INPUTS = drive: 0x60FD bits 0, 1, 2), Y's negative limit on drive
    2 by its bit; tail: more sections."""
    text = MILL.read_text().replace("PERIOD = 0.001", f"PERIOD = {PERIOD_S}")
    text = text.replace("CONTOUR_TOLERANCE = 0.01", "CONTOUR_TOLERANCE = 0.5")
    text = re.sub(
        r"^\[AXIS_X\]$",
        "[AXIS_X]\nLIMIT_INPUTS = drive",
        text,
        count=1,
        flags=re.M,
    )
    text = re.sub(r"^\[AXIS_Y\]$", "[AXIS_Y]\nLIMIT_NEG = 2 0x60FD:0 0 HIGH", text, count=1,
                  flags=re.M)
    x = text.index("[AXIS_X]")
    y = text.index("[AXIS_Y]")
    text = text[:x] + text[x:y].replace("MAX_ACCELERATION = 1000",
                                        f"MAX_ACCELERATION = {A_X:g}") + text[y:]
    path = tmp / "di.ini"
    path.write_text(text + DRIVES_VM + tail)
    return path


@pytest.fixture
def sim(vcan, tmp_path_factory):
    """Per test: each starts with X at 0, off its switches."""
    w = tmp_path_factory.mktemp("disim")
    s = procs.DriveSimProc(
        S, w, nodes=[1, 2, 3],
        args=["--switches", f"1=pos:{int(SWITCH_MM * CPU)},neg:-900000",
              "--switches", "2=neg:-900000"],
    )
    yield s
    s.stop()


def rows_of(sim, node, t0):
    return [r for r in sim.sync_rows() if r["node"] == node and r["t"] >= t0]


def test_drive_limit_trips_mid_move(sim, tmp_path):
    cfg = machine(tmp_path)
    ngc = tmp_path / "p.ngc"
    ngc.write_text(PROGRAM)
    bad = None
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        st = rig.status()
        assert st["inputs"] == {"X limit -": False, "X limit +": False, "X home switch": False,
                                "Y limit -": False}, st
        t0 = time.time()
        feed = rig.feeder(ngc)
        st = rig.wait_state("fault", timeout=300)
        if st["reason"] != "limit switch":
            bad = st  # judged below, with what the drives and mlip-rt said
        else:
            assert st["reason_input"] == "X limit +", st
            assert st["reason_node"] == 1 and st["drives"] == "quick stop", st
            assert st["inputs"]["X limit +"] is True, st
            feed.p.wait(timeout=120)
            assert "limit switch (X limit +, node 1)" in feed.stderr(), feed.stderr()
            # at rest on the switch; reset refused while it is on, a jog toward it too
            p = rig.ctl("reset", check=False)
            assert p.returncode == 1 and "still on" in p.stderr, p.stderr
            p = rig.ctl("jog", "X+5", "600", check=False)
            assert p.returncode != 0, p.stdout
            # a jog away from it leaves the stop; off the switch it releases
            j = rig.ctl("jog", "X-40", "1200", check=False)
            try:
                rig.wait_state("idle", timeout=300,
                               pred=lambda s: s["inputs"]["X limit +"] is False)
            except AssertionError:
                bad = {"jog away": (j.returncode, j.stdout, j.stderr), **rig.status_log[-1]}
    # the bus's silences: the longest gap between two SYNCs (their receive
    # times): a stalled producer (or emulator) shows here
    ts = sorted(r["t"] for r in sim.sync_rows() if r["node"] == 1 and r["t"] >= t0)
    sync_gap = max((b - a for a, b in zip(ts, ts[1:])), default=0.0)
    if bad is not None:
        seen = [e for e in sim.events() if e["kind"] in ("emcy", "heartbeat_lost", "di")]
        raise AssertionError(f"{bad}\nlongest SYNC gap {sync_gap:.3f} s\n{seen[-12:]}\n"
                             f"{rig.result['rt_stderr'][-3000:]}")
    # the drives' records: the TPDO3 with the switch on, then the quick stop
    on = sim.wait_event(lambda e: e["kind"] == "di" and e["node"] == 1 and e["t"] >= t0
                        and int(e["value"], 16) & 2, "X+ on")[0]
    assert on["actual"] >= SWITCH_MM * CPU, on
    s_in = max(r["sync"] for r in sim.sync_rows() if r["t"] < on["t_bus"])
    qs = {}
    for r in sim.sync_rows():
        if r["sync"] > s_in - 1 and r["cw"] == 0x0002:
            qs.setdefault(r["node"], r["sync"])
    assert set(qs) == {1, 2, 3} and len(set(qs.values())) == 1, qs
    delay = qs[1] - s_in
    assert 1 <= delay <= 2, (s_in, qs)
    # X's stop on its drive's ramp (0x6085 = A_X in counts/s^2)
    x = {r["sync"]: r for r in rows_of(sim, 1, t0)}
    s_q = qs[1]
    v0 = (x[s_q]["actual"] - x[s_q - 1]["actual"]) / PERIOD_S / CPU  # mm/s
    # at rest: the first SYNC from which its position no longer changes; held
    # there in "quick stop active" (0x605A = 6: the ramp, then hold)
    rest = [s for s in sorted(x) if s > s_q and s + 1 in x and x[s + 1]["actual"] == x[s]["actual"]]
    assert rest, "X never came to rest"
    s_end = rest[0]
    assert x[s_end]["state"] == "quick stop active", x[s_end]
    dist = (x[s_end]["actual"] - x[s_q]["actual"]) / CPU
    want = v0 * v0 / (2 * A_X)
    dec = [
        -((x[s + 1]["actual"] - x[s]["actual"]) - (x[s]["actual"] - x[s - 1]["actual"]))
        / PERIOD_S**2 / CPU
        for s in range(s_q, s_end)
    ]
    print(f"[di] X limit + (drive 1 0x60FD bit 1) at {on['actual'] / CPU:.3f} mm: TPDO3 after "
          f"SYNC {s_in}, quick stop applied by all 3 drives at SYNC {s_q} ({delay} SYNCs); "
          f"X from {v0:.1f} mm/s stopped in {dist:.3f} mm over {s_end - s_q} periods "
          f"(v^2/2A = {want:.3f} mm), deceleration max {max(dec):.1f} mm/s^2 (A = {A_X:g}); "
          f"longest SYNC gap {sync_gap * 1000:.0f} ms")
    assert 90.0 <= v0 <= 101.0, v0  # at the programmed feed when it tripped
    # the discrete ramp stops half a period's travel short of v^2/2A
    assert abs(dist - want) <= v0 * PERIOD_S, (dist, want)
    # every period's deceleration within the limit (1 % and a count of rounding)
    tol = A_X * 0.01 + 2 / PERIOD_S**2 / CPU
    assert max(dec) <= A_X + tol and min(dec) >= -tol, dec
    # the switch's position: the drive's inputs said on only beyond it
    for e in sim.events("di", 1):
        if e["t"] >= t0 and not int(e["value"], 16) & 2:
            assert e["actual"] < SWITCH_MM * CPU, e


def test_drive_inputs_garbled_and_stale(sim, tmp_path):
    # the drives' touch probe too ([PROBE] SOURCE = drive): TPDO2 carries its
    # latched positions every SYNC, the inputs stay on TPDO3
    cfg = machine(tmp_path, "\n[PROBE]\nSOURCE = drive\n")
    t0 = time.time()
    ngc = tmp_path / "p.ngc"
    ngc.write_text("G21 G90\nG1 X-20 F600\nG1 X-40 F600\n")  # 10 mm/s, 4 s
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        feed = rig.feeder(ngc)
        rig.wait_state("running", timeout=180, pred=lambda st: st["speed_mm_s"] > 1.0)
        # a 3-byte TPDO3 with the positive limit bit set: not taken
        sim.inject("1:di-garbled=0x2")
        ev = sim.wait_event(lambda e: e["kind"] == "di" and e["why"] == "injected: garbled",
                            "garbled TPDO3")[0]
        s_ev = ev["sync"]
        sim.wait_event(lambda e: e["kind"] == "inject" and e["what"] == "di-garbled", "inject")
        deadline = time.monotonic() + 120
        while max((r["sync"] for r in sim.sync_rows()), default=0) < s_ev + 10:
            assert time.monotonic() < deadline, "no SYNCs"
            time.sleep(0.05)
        st = rig.status()
        assert st["state"] == "running" and st["inputs"]["X limit +"] is False, st
        # Y's drive stops sending its inputs: a drive fault after the timeout
        t_silent = time.time()
        sim.inject("2:di-silent")
        st = rig.wait_state("fault", timeout=300)
        waited = time.time() - t_silent
        assert st["reason"] == "drive fault" and st["reason_node"] == 2, st
        assert st["reason_field"] == "digital inputs lost", st
        assert st["inputs"]["Y limit -"] is None, st  # unknown now
        feed.p.wait(timeout=120)
        sim.inject("2:di-silent=off")
    maps = {e["node"]: e for e in sim.events() if e["kind"] == "pdo_maps" and e["t"] >= t0}
    for node in (1, 2):
        m = maps[node]
        assert m["tpdo2"]["valid"] and m["tpdo2"]["map"] == ["0x60BA:0/32", "0x60BB:0/32"], m
        assert m["tpdo3"] == {"cob_id": f"0x{0x380 + node:03X}", "valid": True,
                              "event_ms": 100}, m
    assert maps[3]["tpdo2"]["valid"] and not maps[3]["tpdo3"]["valid"], maps[3]
    print(f"[di] garbled TPDO3 ignored (program ran on 10 SYNCs after it); Y's TPDO3 silent: "
          f"drive fault 'digital inputs lost' after {waited:.1f} s (timeout 4 s)")
    assert waited >= 4.0, waited
