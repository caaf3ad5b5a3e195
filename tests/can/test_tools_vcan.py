"""A manual spindle, manual tool changes and tool length offsets (issue 19)
on a real vcan0: mlip-rt --drives with three simulated CiA 402 drives
(nodes 1..3, the canopen package), mlip-feed with a sealed tool table and
an offsets file, the operator (this test) resuming through mlip-ctl. Judged
on what the drives recorded at every SYNC (sync.csv), not only on mlip's
messages:

  - [SPINDLE] TYPE = manual: M3/M4 S and M5 pause the program at rest with
    what to do (the axes' targets constant through the pause);
  - M6 Tn with [TOOL] CHANGE = manual and CHANGE_Z: the spindle stopped
    first (its pause with Z still down), then Z at the change position,
    paused with "insert tool n (comment)"; resume goes on;
  - G43 Hn / G43.1 Z / G49 / M61 Qn + G43: Z's targets on the bus are the
    program's Z plus the length, to the count; the tool in the spindle
    survives a restart of mlip-rt in the offsets file;
  - TYPE = none: S/M3 refused at load with line and column, nothing moves;
    --ignore-spindle runs it;
  - the bad inputs the issue lists, each refused with its reason, nothing
    on the bus moving meanwhile.

The period is 40 ms (the emulated VM); each test prints a [tools] line.
"""

import subprocess
import time

from conftest import S, drives_machine
from mlipcan import procs

CPU = 1000  # counts per mm (mill-3axis)
TABLE = "T1 P1 Z12.5 D6 ;6 mm flat\nT2 P2 Z30.25 D3.175 ;1/8 ball\n"
MANUAL = """
[SPINDLE]
TYPE = manual
MIN_RPM = 1000
MAX_RPM = 24000

[TOOL]
CHANGE = manual
CHANGE_Z = 100
"""
# G4 P0: an exact stop, so each Z target below is a turning point on the bus
PROGRAM = """G21 G90
G0 X5 Y2 Z10
S12000 M3
G1 X10 F1200
T2 M6
G43 H2
S8000 M4
G0 X20 Y5 Z10
G1 Z-1 F600
G4 P0
G49
G0 Z50
G4 P0
G43.1 Z7.5
G0 Z10
G4 P0
M61 Q1
G43
G0 Z20
M5
M2
"""
# (line, reason, what mlip-ctl status says; mlip-feed adds the tool's comment)
PAUSES = [
    (3, "spindle (manual)", "start the spindle clockwise at 12000 rpm, then resume"),
    (5, "spindle (manual)", "stop the spindle, then resume"),
    (5, "tool change (manual)", "insert tool 2, then resume"),
    (7, "spindle (manual)", "start the spindle counter-clockwise at 8000 rpm, then resume"),
    (20, "spindle (manual)", "stop the spindle, then resume"),
]
# Z's turning points (machine coordinates, counts): the change position,
# Z-1 + T2 (30.25), Z50 without offset, Z10 + 7.5 (G43.1), Z20 + T1 (12.5)
Z_TURNS = [100000, 29250, 50000, 17500, 32500]


def sealed_table(tmp):
    tbl = tmp / "tool.tbl"
    tbl.write_text(TABLE)
    subprocess.run([S.tool("mlip-tools"), "--accept", tbl], check=True, capture_output=True)
    return tbl


def offsets(tmp, cfg):
    path = tmp / "offsets"
    subprocess.run([S.tool("mlip-offsets"), "--init", "--config", cfg, path], check=True,
                   capture_output=True)
    return path


def targets(sim, t0, t1=float("inf")):
    """sync -> {node: target} of the SYNCs recorded between times t0 and t1."""
    out = {}
    for r in sim.sync_rows():
        if t0 <= r["t"] < t1 and r["target"] is not None:
            out.setdefault(r["sync"], {})[r["node"]] = r["target"]
    return out


def turning_points(values):
    d = [values[0]]
    for v in values[1:]:
        if v != d[-1]:
            d.append(v)
    return [d[0]] + [d[i] for i in range(1, len(d) - 1)
                     if (d[i] - d[i - 1]) * (d[i + 1] - d[i]) < 0] + [d[-1]]


def still(sim, t0, what):
    """The SYNCs between t0 and now: at least two recorded (the simulator
    writes each SYNC's row), every axis' target one value in them."""
    # two SYNCs with targets from t0 (the simulator's records lag the bus)
    sim.wait_sync_rows(lambda rs: len({r["sync"] for r in rs if r["t"] >= t0
                                       and r["target"] is not None}) >= 2, timeout=120)
    tg = targets(sim, t0)
    per = {n: {v[n] for v in tg.values() if n in v} for n in (1, 2, 3)}
    assert len(tg) >= 2 and all(len(v) == 1 for v in per.values()), (what, per)
    return {n: next(iter(v)) for n, v in per.items()}


def operator(rig, sim, feed, expected):
    """The operator at each pause in order: checks it at rest on the bus,
    waits until mlip-feed told it (as a person reads it), then resumes.
    Returns (line, reason, time seen, time resumed, axes' targets) each."""
    seen = []
    last = None
    for line, why, what in expected:
        st = rig.wait_state("paused", timeout=300,
                            pred=lambda s, last=last: s["reason_seq"] != last)
        assert (st["reason_line"], st["reason"], st["operator"]) == (line, why, what), st
        assert st["speed_mm_s"] == 0.0, st
        axes = still(sim, st["_t"], (line, why))
        told = what.replace("insert tool 2,", "insert tool 2 (1/8 ball),")
        told = f"paused at line {line}, {why}: {told} (mlip-ctl resume)"
        t_end = time.monotonic() + 120
        while told not in feed.stderr():
            assert time.monotonic() < t_end and feed.p.poll() is None, feed.stderr()
            time.sleep(0.05)
        seen.append((line, why, st["_t"], time.time(), axes))
        last = st["reason_seq"]
        rig.ctl("resume")
    return seen


def test_manual_spindle_tool_change_and_length_offsets(drives_sim, tmp_path):
    sim = drives_sim
    cfg = drives_machine(tmp_path, tail=MANUAL)
    tbl = sealed_table(tmp_path)
    offs = offsets(tmp_path, cfg)
    ngc = tmp_path / "io.ngc"
    ngc.write_text(PROGRAM)
    t0 = time.time()
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        feed = rig.feeder(ngc, "--tools", tbl, "--offsets", offs)
        seen = operator(rig, sim, feed, PAUSES)
        assert feed.p.wait(timeout=600) == 0, feed.stderr()
        err = feed.stderr()
    assert f"tool 1 in the spindle now ({offs})" in err, err
    # the spindle stopped first, Z still down; then at the change position
    assert seen[1][4] == {1: 10000, 2: 2000, 3: 10000}, seen[1]
    assert seen[2][4] == {1: 10000, 2: 2000, 3: 100000}, seen[2]
    # Z left 10 mm for the change position only after the stop's resume
    sim.wait_sync_rows(lambda rs: True)
    tg = targets(sim, t0)
    t_up = min(r["t"] for r in sim.sync_rows()
               if r["t"] >= t0 and r["node"] == 3 and (r["target"] or 0) > 10000)
    assert t_up > seen[1][3], (t_up, seen[1][3])
    zs = [v[3] for s, v in sorted(tg.items()) if 3 in v]
    turns = turning_points(zs)
    assert turns[-len(Z_TURNS):] == Z_TURNS, turns
    assert seen[4][4][3] == 32500  # the M5 pause: at rest at Z20 + T1
    assert "TOOL 1" in offs.read_text()

    # mlip-rt restarted: the tool in the spindle is still T1 (the offsets file)
    ngc2 = tmp_path / "again.ngc"
    ngc2.write_text("G21 G90\nG43\nG0 X0 Y0 Z0\nM2\n")
    t1 = time.time()
    with procs.Rig(S, cfg, "cia402", tmp_path / "again", priority=0,
                   rt_args=["--drives"]) as rig:
        rc, out, err2 = rig.feed(ngc2, timeout=600, args=["--tools", tbl, "--offsets", offs])
        assert rc == 0, err2
    sim.wait_sync_rows(lambda rs: any(
        r["node"] == 3 and r["target"] == 12500 and r["t"] >= t1 for r in rs), timeout=120)
    z_end = [v[3] for s, v in sorted(targets(sim, t1).items()) if 3 in v][-1]
    assert z_end == 12500, z_end
    print(f"[tools] manual spindle + M6 T2 on the bus: paused at rest {len(seen)} times "
          f"(lines {[s[0] for s in seen]}), Z at {seen[1][4][3]} counts for the spindle stop, "
          f"{seen[2][4][3]} for the change; Z's turning points {turns[-len(Z_TURNS):]} "
          f"(T2 30.25, none, G43.1 7.5, T1 12.5); after a restart G43 Z0 -> {z_end} counts")


def test_spindle_none_and_bad_inputs_refused(drives_sim, tmp_path):
    sim = drives_sim
    plain = drives_machine(tmp_path, name="plain.ini")
    cfg = drives_machine(tmp_path, tail=MANUAL)
    tbl = sealed_table(tmp_path)
    dup = tmp_path / "dup.tbl"
    dup.write_text("T1 P1 Z12.5\nT1 P2 Z3\n")
    bad = tmp_path / "bad.tbl"
    bad.write_text("T1 P1 Zq\n")
    prog = tmp_path / "p.ngc"
    cases = [  # (machine, program, feed args, error as file:line:col, reason)
        (plain, "G21 G90\nG0 X5\nM3 S1000\nG1 X10 F600\nM2\n", [], "p.ngc:3:4",
         "S: this machine has no spindle ([SPINDLE] TYPE = none)"),
        (plain, "G21 G90\nG0 X5\nM3\nG1 X10 F600\nM2\n", [], "p.ngc:3:1",
         "M3: this machine has no spindle ([SPINDLE] TYPE = none)"),
        (cfg, "G1 X1 F600\nS30000 M3\n", [], "p.ngc:2:1",
         "S30000 beyond the spindle's MAX_RPM 24000: refused"),
        (cfg, "G1 X1 F600\nM3\n", [], "p.ngc:2:1", "M3 with no S: the spindle speed was never set"),
        (cfg, "G1 X1 F600\nM6\n", ["--tools", tbl], "p.ngc:2:1", "M6 with no T"),
        (cfg, "G1 X1 F600\nG43 H7\n", ["--tools", tbl], "p.ngc:2:5",
         "H7: tool 7 is not in the tool table"),
        (cfg, "G1 X1 F600\nT9 M6\n", ["--tools", tbl], "p.ngc:2:1",
         "T9: tool 9 is not in the tool table"),
        (cfg, "G1 X1 F600\nG43 H2\nG0 Z480\n", ["--tools", tbl], "p.ngc:3:4",
         "Z 510.250 beyond soft limit 500.000"),
        (cfg, "G1 X1 F600\nG38.2 Z-3 F100\n", [], "p.ngc:2:1",
         "G38.2: this machine has no probe input"),
        (cfg, "G1 X1 F600\nT1 M6\n", ["--tools", dup], "dup.tbl:2:1", "tool 1 a second time"),
        (cfg, "G1 X1 F600\nT1 M6\n", ["--tools", bad], "bad.tbl:1:7", "'Zq': not a number"),
    ]
    said = []
    for machine in (plain, cfg):
        t0 = time.time()
        with procs.Rig(S, machine, "cia402", tmp_path / machine.stem, priority=0,
                       rt_args=["--drives"]) as rig:
            for m, text, args, where, why in cases:
                if m != machine:
                    continue
                prog.write_text(text)
                rc, out, err = rig.feed(prog, timeout=300, args=args)
                # a program's error: FILE:LINE:COL: error: ...; the table's:
                # mlip-feed: error: TABLE:LINE:COL: ...
                said_where = f"{where}: error: " in err or ("error: " in err and f"/{where}: " in err)
                assert rc != 0 and said_where and why in err, (text, rc, err)
                said.append(f"{where}: {why}")
            assert rig.status()["state"] == "idle"
            axes = still(sim, t0, machine.stem)  # nothing moved on the bus
            if machine == plain:
                # --ignore-spindle: on purpose, the same program runs
                prog.write_text(cases[0][1])
                rc, out, err = rig.feed(prog, timeout=600, args=["--ignore-spindle"])
                assert rc == 0 and "ignored on purpose (--ignore-spindle)" in err, err
                # the simulator's records lag the bus in the emulated VM
                sim.wait_sync_rows(lambda rs: any(
                    r["node"] == 1 and r["target"] == 10000 and r["t"] >= t0 for r in rs),
                    timeout=120)
                xs = [v[1] for s, v in sorted(targets(sim, t0).items()) if 1 in v]
                assert xs[-1] == 10000 and max(xs) == 10000, (axes, xs[-5:])
    assert len(said) == len(cases)
    print(f"[tools] refused at load, the drives' targets constant meanwhile: {said}")
