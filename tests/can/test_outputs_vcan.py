"""The machine's outputs and probing (issue 19) on a real vcan0: a CiA 401 I/O
module and three CiA 402 drives, all on the canopen package (one simulator
process), mlip-rt --drives sending the module's outputs in its RPDO1 and
reading its probe input. Judged on what the devices recorded: the module's
outputs in force at every SYNC (io.csv), the drives' targets and controlwords
at every SYNC (sync.csv), the probe's trips (events.jsonl).

  - coolant (M8, off by M9) and a digital output (M64/M65) on while the
    program asks, every output off once it ends;
  - a stop and an E-stop: the outputs off in the period the machine starts
    to brake (a stop) or quick stops (the E-stop);
  - G38.2 toward a surface the simulated Z drive crosses: the latched
    position against the surface (counts), the stop inside the acceleration
    limit, the program going on.

The period is 40 ms and the timeouts long (the emulated VM). Each test prints
an [outputs] or [probe] line with the measured figures.
"""

import re
import subprocess
import time

import pytest

from conftest import IO, S, io_machine
from conftest import IO_PERIOD_S as PERIOD_S
from mlipcan import procs

CPU = 1000  # counts per mm (mill-3axis)
CONFIG_TAIL = f"""PROBE = {IO} 0x6000:1 3 HIGH
OUTPUT_0 = {IO} 0x6200:1 2

[COOLANT]
TYPE = io
MIST = {IO} 0x6200:1 0
FLOOD = {IO} 0x6200:1 1
"""
FLOOD, P0 = 0x02, 0x04
X_TOP, X_MID = 20 * CPU, 10 * CPU  # test_coolant_and_output_follow_the_program's X20, X10


def machine(tmp):
    """io_machine with the probe on input bit 3, output 0 and coolant."""
    def has_z(text):
        assert re.search(r"^\[AXIS_Z\]$", text, flags=re.M)
        return text
    return io_machine(tmp, CONFIG_TAIL, has_z)


@pytest.fixture(scope="module")
def sim(io_sim):
    return io_sim


def io_after(sim, t0):
    """The module's rows (outputs byte 1) from the first SYNC after time t0."""
    return [r for r in sim.io_rows() if r["node"] == IO and r["t"] >= t0]


def targets(sim, node, t0):
    """Drive node's (sync, target applied) from time t0 (None: no RPDO)."""
    return [(r["sync"], r["target"]) for r in sim.sync_rows() if r["node"] == node and r["t"] >= t0]


def switch_context(sim, t0, xs, io):
    """What a failed ordering check needs: the SYNCs around X's reversal
    (X's target and RPDO freshness, the outputs in force, the SYNC's bus
    time) and the module's output frames (the SYNC count they were taken
    at, their bus time)."""
    turn = next((s for s, t in xs if t == X_TOP), None)
    if turn is None:
        return "X never at X20"
    rows = {r["sync"]: r for r in sim.sync_rows() if r["node"] == 1 and r["t"] >= t0}
    t_io = {r["sync"]: r["t"] for r in io_after(sim, t0)}
    around = []
    for s in range(turn - 3, turn + 3):
        r = rows.get(s, {})
        around.append((s, r.get("target"), r.get("fresh"), hex(io.get(s, -1)), t_io.get(s)))
    frames = [(e["sync"], e.get("t_bus"), e["data"])
              for e in sim.events("outputs", IO) if e["t"] >= t0]
    return f"(sync, X target, fresh, outputs, t) {around}; module frames {frames}"


def test_coolant_and_output_follow_the_program(sim, tmp_path):
    cfg = machine(tmp_path)
    ngc = tmp_path / "p.ngc"
    ngc.write_text("G21 G90\nM8\nM64 P0\nG1 X20 F1200\nM65 P0\nG1 X10\nM9\nG1 X0\nM2\n")
    t0 = time.time()
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        # mlip-feed checks against the running controller's outputs: refused
        # at line:col, nothing sent
        for text, where, what in (
            ("G1 X1 F600\nM64 P1\n", "2:5", "digital output 1 is not mapped ([IO] OUTPUT_1)"),
            ("G1 X1 F600\nM62 P1\n", "2:5", "digital output 1 is not mapped ([IO] OUTPUT_1)"),
            ("G1 X1 F600\nG38.2 X1\n", "2:1", "to the current position"),
        ):
            bad = tmp_path / "bad.ngc"
            bad.write_text(text)
            rc, out, err = rig.feed(bad, timeout=120)
            assert rc == 1 and f"bad.ngc:{where}: error:" in err and what in err, (rc, err)
        t_good = time.time()
        rc, out, err = rig.feed(ngc, timeout=600)
        assert rc == 0, err
        st = rig.status()
        assert st["coolant"] == {"mist": False, "flood": False} and st["outputs"] == {}, st
        assert "outputs    coolant off, module outputs all off" in rig.ctl("status").stdout
    # the refused programs (their line 1 a move): nothing on the bus moved
    refused = {(r["node"], r["target"]) for r in sim.sync_rows()
               if t0 <= r["t"] < t_good and r["target"] is not None}
    assert len(refused) <= 3 and len({n for n, t in refused}) == len(refused), refused
    io = {r["sync"]: r["outputs"][0] for r in io_after(sim, t0)}
    xs = [(s, t) for s, t in targets(sim, 1, t0) if t is not None]
    # the outputs at every SYNC X moved at, by move: up to X20's first SYNC
    # the first, then up to X10's the second, then the third. By time, not
    # by each step's sign: the emulated VM's vcan may hand two successive
    # RPDOs to the simulator out of order (per-CPU backlogs), which a drive
    # that applies the last one received records as a step back
    s_top = min(s for s, t in xs if t == X_TOP)
    s_mid = min(s for s, t in xs if t == X_MID and s > s_top)
    out_moving = []
    for (s0, a), (s1, b) in zip(xs, xs[1:]):
        if b != a and s1 in io:
            out_moving.append((1 if s1 <= s_top else 2 if s1 <= s_mid else 3, io[s1]))
    by_move = {k: {o for m, o in out_moving if m == k} for k in (1, 2, 3)}
    # flood and P0 on through the first move, flood alone through the
    # second, nothing through the third (M9 between them, at rest)
    assert by_move == {1: {FLOOD | P0}, 2: {FLOOD}, 3: {0}}, (
        out_moving, switch_context(sim, t0, xs, io))
    # off once the program ended: after X's last move, within a few periods
    last_move = max(s1 for (s0, a), (s1, b) in zip(xs, xs[1:]) if b != a)
    off = [s for s, o in sorted(io.items()) if s > last_move and o == 0]
    assert off, sorted(io.items())[-10:]
    seq = []
    for s, o in sorted(io.items()):
        if not seq or seq[-1] != o:
            seq.append(o)
    print(
        f"[outputs] refused programs (M64/M62 P1 unmapped, G38.2 to the current position): "
        f"targets on the bus meanwhile {sorted(refused)} (one per node: nothing moved)"
    )
    print(
        f"[outputs] program: outputs byte 1 over the SYNCs {[hex(o) for o in seq]}, "
        f"{len(out_moving)} SYNCs of motion judged, off {off[0] - last_move} SYNCs after "
        f"the last target change"
    )
    assert seq == [0, FLOOD, FLOOD | P0, FLOOD, 0], seq


def test_m62_switches_with_the_next_move(sim, tmp_path):
    """M62/M63 (with the next move): the module's output bit flips at the same
    SYNC as the first target of the move after it (io.csv against sync.csv:
    both applied at that SYNC), through a corner, without a stop."""
    cfg = machine(tmp_path)
    ngc = tmp_path / "p.ngc"
    ngc.write_text("G21 G90\nG1 X5 F1200\nM62 P0\nG1 X5 Y5\nM63 P0\nG1 X10 Y5\nM2\n")
    t0 = time.time()
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        rc, out, err = rig.feed(ngc, timeout=600)
        assert rc == 0, err
    sim.wait_sync_rows(lambda rs: True)
    io = {r["sync"]: r["outputs"][0] for r in io_after(sim, t0)}
    ys = [(s, t) for s, t in targets(sim, 2, t0) if t is not None]
    xs = [(s, t) for s, t in targets(sim, 1, t0) if t is not None]
    y_first = min(s for s, t in ys if t > 0)  # block 4's first target
    x_first = min(s for s, t in xs if t > 5000)  # block 6's first target
    on = min(s for s, o in io.items() if o & P0)
    off = min(s for s, o in io.items() if s > on and not o & P0)
    # no stop at the corners: X (or Y) moved at every SYNC between the first
    # move's start and the last's end
    x0 = min(s for s, t in xs if t > 0)
    moving = {s for (s0, a), (s, b) in zip(xs, xs[1:]) if b != a}
    moving |= {s for (s0, a), (s, b) in zip(ys, ys[1:]) if b != a}
    gaps = [s for s in range(x0 + 1, x_first) if s not in moving]
    print(
        f"[outputs] M62 P0 on at SYNC {on} (Y's first target {y_first}), M63 P0 off at "
        f"SYNC {off} (X's first target past 5 mm {x_first}); SYNCs at rest between: {gaps}"
    )
    assert on == y_first and off == x_first, (on, y_first, off, x_first)
    assert gaps == [], gaps


def brake_sync(sim, node, t0, cruise):
    """The first SYNC from t0 at which drive node's target advanced less
    than 90 % of cruise counts after advancing at cruise."""
    xs = [(s, t) for s, t in targets(sim, node, t0) if t is not None]
    at_speed = False
    for (s0, a), (s1, b) in zip(xs, xs[1:]):
        d = abs(b - a)
        if d >= 0.99 * cruise:
            at_speed = True
        elif at_speed and d < 0.9 * cruise:
            return s1
    return None


def test_outputs_off_on_stop_and_estop(sim, tmp_path):
    cfg = machine(tmp_path)
    ngc = tmp_path / "p.ngc"
    # 20 mm/s: 0.8 mm (800 counts) a period; the brake takes one period at 1000 mm/s^2
    ngc.write_text("G21 G90\nM7 M8\nM64 P0\nG1 X400 F1200\nM2\n")
    cruise = 20.0 * PERIOD_S * CPU
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        t0 = time.time()
        feed = rig.feeder(ngc)
        rig.wait_state("running", timeout=180, pred=lambda st: st["speed_mm_s"] > 19.0)
        st = rig.status()
        assert st["coolant"] == {"mist": True, "flood": True}, st
        assert st["outputs"] == {"0x6200:1": 0x07}, st
        text = rig.ctl("status").stdout
        assert "outputs    coolant mist+flood, 0x6200:1 = 0x07" in text, text
        t_stop = time.time()
        rig.ctl("stop")
        rig.wait_state("idle", timeout=120)
        feed.p.wait(timeout=120)
        assert rig.status()["outputs"] == {}
        # the E-stop: a second program, its outputs on, the circuit opened
        t1 = time.time()
        feed = rig.feeder(ngc)
        rig.wait_state("running", timeout=180, pred=lambda st: st["speed_mm_s"] > 19.0)
        t_estop = time.time()
        sim.inject(f"{IO}:input=1.0=0")
        rig.wait_state("estop", timeout=60)
        feed.p.wait(timeout=120)
        sim.inject(f"{IO}:input=1.0=1")
        rig.wait_state("estop", timeout=60, pred=lambda s: s["inputs"]["estop"] is False)
        rig.ctl("reset")
        rig.wait_state("idle", timeout=60)
    sim.wait_sync_rows(lambda rs: True)
    # the stop: the module's outputs off against the drive's first braking target
    io = [(r["sync"], r["outputs"][0]) for r in io_after(sim, t0) if r["t"] < t1]
    on = [s for s, o in io if o == 0x07]
    assert on, io[:20]
    s_brake = brake_sync(sim, 1, t0, cruise)
    assert s_brake is not None
    s_off = min(s for s, o in io if s > on[0] and o == 0)
    s_req = min(r["sync"] for r in sim.sync_rows() if r["node"] == 1 and r["t"] >= t_stop)
    print(
        f"[outputs] stop: requested before SYNC {s_req}, first braking target at SYNC "
        f"{s_brake}, outputs off at SYNC {s_off} ({s_off - s_brake:+d} SYNCs)"
    )
    # the same controller period sends both: the module applies its RPDO on
    # reception, the drive its target at the next SYNC
    assert -1 <= s_off - s_brake <= 1, (s_off, s_brake)
    # the E-stop: off with the quick stop
    qs = min(
        r["sync"]
        for r in sim.sync_rows()
        if r["node"] == 1 and r["t"] >= t_estop and r["cw"] == 0x0002
    )
    io2 = [(r["sync"], r["outputs"][0]) for r in io_after(sim, t1)]
    on2 = [s for s, o in io2 if o == 0x07]
    assert on2, io2[:20]
    s_off2 = min(s for s, o in io2 if s > on2[0] and o == 0)
    print(
        f"[outputs] E-stop: quick stop applied at SYNC {qs}, outputs off at SYNC {s_off2} "
        f"({s_off2 - qs:+d} SYNCs)"
    )
    assert -1 <= s_off2 - qs <= 1, (s_off2, qs)


def test_probe_latches_the_surface(sim, tmp_path):
    cfg = machine(tmp_path)
    ngc = tmp_path / "p.ngc"
    surface = -5000  # counts: Z -5 mm
    feed_mm_min = 120.0  # 2 mm/s: 80 counts a period
    ngc.write_text(f"G21 G90\nG0 Z0\nG38.2 Z-10 F{feed_mm_min:g}\nG0 Z5\nM2\n")
    sim.inject(f"{IO}:probe=1.3,3,{surface},below")
    try:
        t0 = time.time()
        with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
            rc, out, err = rig.feed(ngc, timeout=600)
            assert rc == 0, err
            st = rig.status()
    finally:
        sim.inject(f"{IO}:probe=off")
    pr = st["probe"]
    assert pr is not None and pr["tripped"] is True and pr["line"] == 3, st
    assert pr["parameters"]["5070"] == 1 and pr["parameters"]["5063"] == pr["position"]["Z"]
    assert abs(st["position"]["Z"] - 5.0) < 1e-9, st  # the program went on
    latched = round(pr["position"]["Z"] * CPU)
    err_counts = latched - surface
    per_period = feed_mm_min / 60.0 * PERIOD_S * CPU
    trips = sim.wait_event(lambda e: e["kind"] == "probe" and e["on"] and e["t"] >= t0, "a trip")
    sim.wait_sync_rows(lambda rs: True)
    zs = [(s, t) for s, t in targets(sim, 3, t0) if t is not None]
    s_trip = trips[0]["sync"]
    # from the trip to rest: the targets brake inside the acceleration limit
    # (second difference <= A T^2 + 2 counts of rounding), and rest beyond
    # the surface by at most v^2/2A plus the periods of the loop
    after = [t for s, t in zs if s >= s_trip - 1]
    acc = (
        max((abs(c - 2 * b + a) for a, b, c in zip(after, after[1:], after[2:])), default=0)
        / (PERIOD_S**2)
        / CPU
    )
    rest = min(t for s, t in zs if s >= s_trip and t <= -4000)
    # the first SYNC from the trip whose target no longer goes down: the
    # stop as the drive saw it (the simulator's SYNC count, which lags the
    # bus in the emulated VM: mlip-rt is that many periods further)
    s_stop = min(s1 for (s0, a), (s1, b) in zip(zs, zs[1:]) if s1 > s_trip and b >= a)
    # the SYNC before the probe's TPDO by the bus's clock (the SYNCs' receive
    # times against the frame's send time, as tests/can/test_io_vcan.py)
    tp = sim.wait_event(
        lambda e: (
            e["kind"] == "tpdo" and e["node"] == IO and e["t"] >= t0 and e["why"] == "probe on"
        ),
        "the probe's TPDO",
    )
    s_bus = max(r["sync"] for r in sim.sync_rows() if r["t"] < tp[0]["t_bus"])
    v = feed_mm_min / 60.0
    print(
        f"[probe] surface Z {surface} counts, latched {latched} counts (error {err_counts:+d} "
        f"counts, {err_counts / per_period:+.2f} periods of travel at {v:g} mm/s, "
        f"{per_period:.0f} counts a period), tripped at SYNC {s_trip} (drive at "
        f"{trips[0]['actual']}), came to rest at {rest} counts by SYNC {s_stop} "
        f"({s_stop - s_trip} SYNCs of the simulator after the trip, {s_stop - s_bus} after "
        f"the SYNC before its frame by the bus's clock), max braking "
        f"{acc:.1f} mm/s^2"
    )
    assert acc <= 1000.0 * (1 + 1e-9) + 2 / (PERIOD_S**2) / CPU, acc
    # the latched position: where the drive was in the period the input's
    # frame arrived, within a few periods of travel beyond the surface
    # (the module reads the drive one period after its move, mlip reads
    # the module's frame in the period after that)
    # (the drive's position actual of that period: at or past the trip, or
    # the sample before it when its TPDO and the module's came together)
    assert -3 * per_period <= err_counts <= per_period, err_counts
    # on the path: the axis never went back up before the stop, and came to
    # rest no further than the periods it took to react plus v^2/2A
    assert rest >= latched - (s_stop - s_trip + 2) * per_period - v * v / 2000.0 * CPU, rest
    assert all(b <= a for (s0, a), (s1, b) in zip(zs, zs[1:]) if s_trip - 5 <= s1 < s_stop)


def test_drive_touch_probe_latch(sim, tmp_path):
    """[PROBE] SOURCE = drive: every axis drive's touch probe 1 (CiA 402
    0x60B8 in RPDO1, 0x60B9 in TPDO1, TPDO2 = 0x60BA + 0x60BB) mapped at
    bring-up and read back; G38.2 switches the latch off, on (enable, first
    event, positive edge), watches 0x60B9 and takes the position each drive
    LATCHED at the instant Z crossed the surface between two SYNCs: equal to
    the surface to the count, not where Z came to rest."""
    text = machine(tmp_path).read_text()
    text = text.replace(f"PROBE = {IO} 0x6000:1 3 HIGH\n", "") + "\n[PROBE]\nSOURCE = drive\n"
    cfg = tmp_path / "tp.ini"
    cfg.write_text(text)
    ngc = tmp_path / "p.ngc"
    surface = -4987  # counts: not a multiple of the 80 counts a period at the feed
    feed_mm_min = 120.0
    ngc.write_text(f"G21 G90\nG0 X1 Y2 Z0\nG38.2 Z-10 F{feed_mm_min:g}\nG0 Z5\nM2\n")
    sim.inject(f"3:touch-probe={surface},below")
    try:
        t0 = time.time()
        with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
            rc, out, err = rig.feed(ngc, timeout=600)
            if rc != 0:
                sim.wait_sync_rows(lambda rs: True)
                ev = [e for e in sim.events() if e["t"] >= t0 and e["kind"] != "sdo"]
                rt = rig._rt().stderr()
                pytest.fail(f"{err}\n{ev[-40:]}\n{rt[-3000:]}")
            st = rig.status()
    finally:
        sim.inject("3:touch-probe=off")
    pr = st["probe"]
    assert pr is not None and pr["tripped"] is True and pr["line"] == 3, st
    assert abs(st["position"]["Z"] - 5.0) < 1e-9, st  # the program went on
    latched = pr["position"]["Z"] * CPU
    # the drives' records: their touch probe latches, the PDO maps of the bring-up
    tps = sim.wait_event(lambda e: e["kind"] == "touch_probe" and e["t"] >= t0, "a latch")
    maps = [e for e in sim.events() if e["kind"] == "pdo_maps" and e["t"] >= t0]
    fns = [
        (e["node"], e["fn"], e["via"])
        for e in sim.events()
        if e["kind"] == "touch_probe_fn" and e["t"] >= t0
    ]
    sim.wait_sync_rows(lambda rs: True)
    zs = [(s, t) for s, t in targets(sim, 3, t0) if t is not None]
    actual = [r["actual"] for r in sim.sync_rows() if r["node"] == 3 and r["t"] >= t0]
    z = {e["node"]: e for e in tps}
    assert z[3]["latched"] == surface and 0 < z[3]["frac"] < 1, tps
    assert round(latched) == surface, (latched, surface)  # the latch, to the count
    assert abs(pr["position"]["X"] - 1.0) < 1e-9 and abs(pr["position"]["Y"] - 2.0) < 1e-9
    assert surface not in actual  # between two SYNCs' positions
    rest = min(t for s, t in zs)
    assert rest < surface - 40, (rest, surface)  # at rest beyond it, braking on the path
    for node in (1, 2, 3):
        m = [e for e in maps if e["node"] == node][-1]
        assert "0x60B8:0/16" in m["rpdo"]["map"] and "0x60B9:0/16" in m["tpdo"]["map"], m
        assert m["tpdo2"]["valid"] and m["tpdo2"]["map"] == ["0x60BA:0/32", "0x60BB:0/32"], m
        seq = [f for n, f, v in fns if n == node]
        assert "0x0011" in seq and seq[-1] == "0x0000", seq  # on for the move, off after it
    after = [t for s, t in zs if s >= z[3]["sync"] - 1]
    acc = (
        max((abs(c - 2 * b + a) for a, b, c in zip(after, after[1:], after[2:])), default=0)
        / (PERIOD_S**2)
        / CPU
    )
    assert acc <= 1000.0 * (1 + 1e-9) + 2 / (PERIOD_S**2) / CPU, acc
    print(
        f"[probe] drive touch probe: surface Z {surface} counts, latched {round(latched)} "
        f"counts at {z[3]['frac']:.3f} of the period after SYNC {z[3]['sync']} (X, Y latched "
        f"{pr['position']['X']:.4f}, {pr['position']['Y']:.4f}), at rest at {rest} counts "
        f"({surface - rest} counts beyond), max braking {acc:.1f} mm/s^2"
    )


def test_drive_probe_on_at_start(sim, tmp_path):
    """[PROBE] SOURCE = drive with the probe's level read from the drives'
    own digital inputs ([IO] PROBE = 3 0x60FD:0 16: CiA 402's 0x60B9 has no
    level, drives show the probe input among 0x60FD's manufacturer bits):
    G38.2 with the probe already on is refused at its line before anything
    moves or a latch is armed (exit 5); once it is off, the same G38.2 runs
    and the latch, not the level, is the result."""
    text = machine(tmp_path).read_text()
    text = text.replace(f"PROBE = {IO} 0x6000:1 3 HIGH\n", "PROBE = 3 0x60FD:0 16 HIGH\n")
    cfg = tmp_path / "tplevel.ini"
    cfg.write_text(text + "\n[PROBE]\nSOURCE = drive\n")
    home = tmp_path / "home.ngc"
    home.write_text("G21 G90\nG0 X0 Y0 Z1\nG0 Z0\nM2\n")  # a move, wherever it stands
    ngc = tmp_path / "p.ngc"
    ngc.write_text("G21 G90\nG38.2 Z-10 F120\nG0 Z5\nM2\n")
    surface = -3013  # counts
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        rc, out, err = rig.feed(home, timeout=600)
        assert rc == 0, err
        # the probe on from Z 0 down (a surface above the tool: pressed)
        sim.inject("3:touch-probe=1000,below")
        try:
            rig.wait_state("idle", timeout=60, pred=lambda s: s["inputs"].get("probe") is True)
            t0 = time.time()
            rc, out, err = rig.feed(ngc, timeout=600)
            assert rc == 5 and "probe already tripped at the start" in err, (rc, err)
            assert rig.status()["probe"] is None  # no G38 result: it never started
            sim.wait_sync_rows(lambda rs: True)
            fns = [e for e in sim.events("touch_probe_fn") if e["t"] >= t0]
            zs = {t for s, t in targets(sim, 3, t0) if t is not None}
            t1 = time.time()
            sim.inject(f"3:touch-probe={surface},below")
            rig.wait_state("idle", timeout=60, pred=lambda s: s["inputs"].get("probe") is False)
            rc, out, err = rig.feed(ngc, timeout=600)
            assert rc == 0, err
            st = rig.status()
        finally:
            sim.inject("3:touch-probe=off")
    assert zs == {0}, zs  # nothing moved on the bus
    assert all(e["fn"] == "0x0000" for e in fns), fns  # the latch never armed
    pr = st["probe"]
    assert pr["tripped"] is True and round(pr["position"]["Z"] * CPU) == surface, pr
    armed = [e for e in sim.events("touch_probe_fn") if e["t"] >= t1 and e["fn"] == "0x0011"]
    assert armed
    print(f"[probe] drive touch probe, level on 0x60FD bit 16: G38.2 with the probe on refused "
          f"('probe already tripped at the start', exit 5), Z held at {sorted(zs)} counts, "
          f"0x60B8 never armed; then off: latched {round(pr['position']['Z'] * CPU)} counts "
          f"against the surface {surface}")


def test_probe_no_trip_and_touch_off(sim, tmp_path):
    """The G38 cases without a surface, and the result put to use: G38.3
    reaches its target and the program goes on (#5070 = 0, the result the
    target); G38.2 reaching its target stops the program there (exit 5
    naming the line, the move after it never on the bus); then G38.2 trips on
    a surface and an MDI G10 L20 P1 Z makes the latched #5063 Z0 of G54 (the
    touch-off after the probe): an MDI G0 Z0 puts Z's target on the bus at
    the latched position, to the count."""
    cfg = machine(tmp_path)
    offs = tmp_path / "offsets"
    subprocess.run([S.tool("mlip-offsets"), "--init", "--config", cfg, offs], check=True,
                   capture_output=True)
    ngc = tmp_path / "p.ngc"
    surface = -3000  # counts: Z -3 mm
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        ngc.write_text("G21 G90\nG0 Z0\nG38.3 Z-2 F300\nG0 Z1\nM2\n")
        rc, out, err = rig.feed(ngc, timeout=600)
        assert rc == 0, err
        st = rig.wait_state("idle", timeout=300)
        pr = st["probe"]
        assert pr is not None and pr["tripped"] is False and pr["line"] == 3, st
        assert pr["parameters"]["5070"] == 0 and abs(pr["position"]["Z"] + 2.0) < 1e-9, pr
        assert abs(st["position"]["Z"] - 1.0) < 1e-9, st  # the program went on
        t1 = time.time()
        ngc.write_text("G21 G90\nG0 Z0\nG38.2 Z-2 F300\nG0 Z5\nM2\n")
        rc, out, err = rig.feed(ngc, timeout=600)
        assert rc == 5 and "p.ngc:3: probe not tripped (G38.2/G38.4)" in err, (rc, err)
        st = rig.wait_state("idle", timeout=300)
        assert st["probe"]["tripped"] is False and st["probe"]["line"] == 3, st
        assert abs(st["position"]["Z"] + 2.0) < 1e-9, st  # at rest at its target
        # the simulator's records lag the bus in the emulated VM
        sim.wait_sync_rows(lambda rs: any(
            r["node"] == 3 and r["target"] == -2000 and r["t"] >= t1 for r in rs), timeout=120)
        z2 = [t for s, t in targets(sim, 3, t1) if t is not None]
        assert min(z2) == -2000 and max(z2) <= 1000 and z2[-1] == -2000, z2[-5:]
        sim.inject(f"{IO}:probe=1.3,3,{surface},below")
        try:
            ngc.write_text("G21 G90\nG0 Z0\nG38.2 Z-10 F120\nG0 Z-1\nM2\n")
            rc, out, err = rig.feed(ngc, timeout=600)
            assert rc == 0, err
            st = rig.wait_state("idle", timeout=300)
            pr = st["probe"]
            assert pr["tripped"] is True and pr["line"] == 3, st
            latched = pr["parameters"]["5063"]
            assert abs(st["position"]["Z"] + 1.0) < 1e-9, st
            # the current point (Z-1) reads -1 - #5063: the latched point is Z0
            rig.ctl("mdi", "--offsets", offs, f"G10 L20 P1 Z{-1.0 - latched:.6f}")
            t2 = time.time()
            rig.ctl("mdi", "--offsets", offs, "G0 Z0")
            st = rig.wait_state("idle", timeout=300)
        finally:
            sim.inject(f"{IO}:probe=off")
    want = round(latched * CPU)
    sim.wait_sync_rows(lambda rs: any(
        r["node"] == 3 and r["target"] == want and r["t"] >= t2 for r in rs), timeout=120)
    z3 = [t for s, t in targets(sim, 3, t2) if t is not None]
    print(f"[probe] G38.3 to Z-2 untripped (#5070 = 0), G38.2 to Z-2 untripped: exit 5 at "
          f"line 3, Z held at {z2[-1]} counts; surface {surface} counts, #5063 = {latched:g} "
          f"mm; after MDI G10 L20 P1 Z{-1.0 - latched:g} and G0 Z0 Z's target {z3[-1]} counts")
    assert abs(st["position"]["Z"] - latched) < 1e-9, st
    assert z3 and z3[-1] == want, (z3[-3:], want)
    assert -3 * 80 <= want - surface <= 80, (want, surface)  # the trip: near the surface


def home_z0(rig, tmp_path):
    """A move, wherever Z stands, to X0 Y0 Z0 (the program ends there)."""
    home = tmp_path / "home.ngc"
    home.write_text("G21 G90\nG0 X0 Y0 Z1\nG0 Z0\nM2\n")
    rc, out, err = rig.feed(home, timeout=600)
    assert rc == 0, err
    return rig.wait_state("idle", timeout=300)


def probe_level(rig, on):
    """The controller sees the module's probe input at `on`."""
    return rig.wait_state("idle", timeout=60, pred=lambda s: s["inputs"].get("probe") is on)


def test_module_probe_on_at_start(sim, tmp_path):
    """The probe on the I/O module (input bit 3) already on where Z stands:
    G38.2 and G38.3 are refused at their line (exit 5, "probe already
    tripped at the start") with nothing moving: Z's target on the bus stays
    at 0, the move after the G38 never on the bus, no G38 result."""
    cfg = machine(tmp_path)
    ngc = tmp_path / "p.ngc"
    surface = 1000  # counts: the probe is on at and below Z 1 mm, so at Z0
    results = []
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        home_z0(rig, tmp_path)
        sim.inject(f"{IO}:probe=1.3,3,{surface},below")
        try:
            probe_level(rig, True)
            t0 = time.time()
            for code in ("G38.2", "G38.3"):
                ngc.write_text(f"G21 G90\n{code} Z-5 F120\nG0 X3 Z5\nM2\n")
                rc, out, err = rig.feed(ngc, timeout=600)
                results.append((code, rc))
                assert rc == 5 and "p.ngc:2: probe already tripped at the start" in err, (
                    code, rc, err)
                st = rig.wait_state("idle", timeout=300)
                assert st["probe"] is None, st  # no G38 result: it never started
                assert abs(st["position"]["Z"]) < 1e-9 and abs(st["position"]["X"]) < 1e-9, st
            t1 = time.time()
        finally:
            sim.inject(f"{IO}:probe=off")
            sim.inject(f"{IO}:input=1.3=0")
    # the records lag the bus in the emulated VM: to the SYNCs after the refusals
    sim.wait_sync_rows(lambda rs: any(r["node"] == 3 and r["t"] >= t1 for r in rs), timeout=120)
    s1 = max_sync(sim, t1)
    zs = {t for s, t in targets(sim, 3, t0) if t is not None and s <= s1}
    xs = {t for s, t in targets(sim, 1, t0) if t is not None and s <= s1}
    print(f"[probe] module probe on at Z0 (surface {surface} counts): {results} "
          f"(exit codes), Z's targets on the bus meanwhile {sorted(zs)}, X's {sorted(xs)}")
    assert zs <= {0} and xs <= {0}, (zs, xs)


def max_sync(sim, t):
    """The last SYNC the simulator recorded before time t."""
    return max(r["sync"] for r in sim.sync_rows() if r["t"] <= t)


def test_probe_away_g38_4_g38_5(sim, tmp_path):
    """G38.4 / G38.5, probing away from the workpiece with the probe on the
    I/O module: from Z0 in contact (the probe on at and below Z 1 mm), the
    move up trips on losing contact: the latched Z against the surface, Z
    braking inside its acceleration well short of the target, the program
    going on. G38.5 the same; G38.5 that never loses contact reaches its
    target and the program goes on (#5070 = 0); G38.4 that never loses it
    stops the program there (exit 5, the move after it never on the bus);
    G38.4 with the probe not in contact at the start is refused, nothing
    moving."""
    cfg = machine(tmp_path)
    ngc = tmp_path / "p.ngc"
    surface = 1000  # counts
    feed_mm_min = 120.0  # 2 mm/s: 80 counts a period
    per_period = feed_mm_min / 60.0 * PERIOD_S * CPU
    got = {}
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        home_z0(rig, tmp_path)
        sim.inject(f"{IO}:probe=1.3,3,{surface},below")
        try:
            probe_level(rig, True)
            for code in ("G38.4", "G38.5"):
                t0 = time.time()
                ngc.write_text(f"G21 G90\n{code} Z5 F{feed_mm_min:g}\nG0 Z0\nM2\n")
                rc, out, err = rig.feed(ngc, timeout=600)
                assert rc == 0, (code, err)
                st = rig.wait_state("idle", timeout=300)
                pr = st["probe"]
                assert pr["tripped"] is True and pr["line"] == 2, (code, st)
                assert pr["parameters"]["5070"] == 1 and pr["parameters"]["5063"] == pr[
                    "position"]["Z"], pr
                assert abs(st["position"]["Z"]) < 1e-9, st  # the program went on: G0 Z0
                probe_level(rig, True)  # back in contact at Z0
                got[code] = (t0, time.time(), round(pr["position"]["Z"] * CPU))
            # in contact up to Z 10 mm: G38.5 to Z3 reaches it, G38.4 stops there
            sim.inject(f"{IO}:probe=1.3,3,10000,below")
            ngc.write_text("G21 G90\nG38.5 Z3 F300\nG0 Z0\nM2\n")
            rc, out, err = rig.feed(ngc, timeout=600)
            assert rc == 0, err
            st = rig.wait_state("idle", timeout=300)
            pr = st["probe"]
            assert pr["tripped"] is False and pr["parameters"]["5070"] == 0, st
            assert abs(pr["position"]["Z"] - 3.0) < 1e-9 and abs(st["position"]["Z"]) < 1e-9, st
            t_g384 = time.time()
            ngc.write_text("G21 G90\nG38.4 Z3 F300\nG0 Z0\nM2\n")
            rc, out, err = rig.feed(ngc, timeout=600)
            assert rc == 5 and "p.ngc:2: probe not tripped (G38.2/G38.4)" in err, (rc, err)
            st = rig.wait_state("idle", timeout=300)
            assert abs(st["position"]["Z"] - 3.0) < 1e-9, st  # at rest at its target
            # out of contact (the probe lifted off): G38.4 refused at its line
            sim.inject(f"{IO}:probe=off")
            sim.inject(f"{IO}:input=1.3=0")
            probe_level(rig, False)
            t_off = time.time()
            ngc.write_text("G21 G90\nG38.4 Z5 F300\nG0 Z0\nM2\n")
            rc, out, err = rig.feed(ngc, timeout=600)
            assert rc == 5 and "p.ngc:2: probe not in contact at the start" in err, (rc, err)
            st = rig.wait_state("idle", timeout=300)
            assert abs(st["position"]["Z"] - 3.0) < 1e-9, st
            t_end = time.time()
        finally:
            sim.inject(f"{IO}:probe=off")
            sim.inject(f"{IO}:input=1.3=0")
    sim.wait_sync_rows(lambda rs: any(r["node"] == 3 and r["t"] >= t_end for r in rs),
                       timeout=120)
    line = []
    for code, (t0, t1, latched) in got.items():
        s1 = max_sync(sim, t1)
        zs = [t for s, t in targets(sim, 3, t0) if t is not None and s <= s1]
        top = max(zs)
        i_top = zs.index(top)
        up = zs[: i_top + 1]
        acc = (max((abs(c - 2 * b + a) for a, b, c in zip(up, up[1:], up[2:])), default=0)
               / (PERIOD_S**2) / CPU)
        err_counts = latched - surface
        line.append(f"{code}: latched {latched} counts (error {err_counts:+d}, "
                    f"{err_counts / per_period:+.2f} periods of travel), at rest at {top} "
                    f"counts, max acceleration on the way up {acc:.1f} mm/s^2")
        # lost contact above the surface: the drive's position in the period
        # the module's frame arrived (at most a period before it is read,
        # up to three periods of travel beyond)
        assert -per_period <= err_counts <= 3 * per_period, (code, err_counts)
        # stopped by the trip: well short of Z5, beyond the latch by at most
        # a few periods of reaction and v^2/2A
        v = feed_mm_min / 60.0
        react = (10 if S.in_vm else 4) * per_period
        assert latched <= top <= latched + react + v * v / 2000.0 * CPU, (code, top)
        assert acc <= 1000.0 * (1 + 1e-9) + 2 / (PERIOD_S**2) / CPU, (code, acc)
    s_off = max_sync(sim, t_off)
    z4 = [t for s, t in targets(sim, 3, t_g384) if t is not None and s <= s_off]
    z_off = {t for s, t in targets(sim, 3, t_off) if t is not None}
    print(f"[probe] away, surface {surface} counts: " + "; ".join(line) +
          f"; G38.5 in contact to Z3: untripped, went on; G38.4 in contact to Z3: exit 5, "
          f"Z at {z4[-1]} counts (max {max(z4)}); G38.4 out of contact: exit 5, Z's targets "
          f"{sorted(z_off)}")
    assert z4[-1] == 3000 and max(z4) == 3000, z4[-5:]  # the G0 Z0 never on the bus
    assert z_off <= {3000}, z_off  # nothing moved
