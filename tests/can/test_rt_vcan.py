"""End to end on a real vcan0: mlip-rt puts setpoints on the bus, the listener
(mlip-listen) rebuilds them, and they must equal mlip-sim's trace for
the same program and machine to the last drive count.

Run it where vcan0 exists (on the host if its kernel has CAN, else in a VM):

    tools/vcan/run.sh '.venv/bin/python -m pytest -s -q tests/can/test_rt_vcan.py'

Without an UP vcan0 the bus tests FAIL (they never skip: a green run means the
SocketCAN path really was exercised). The listener's decoding is also tested
offline, from candump logs made here (test_listener_*: no bus needed).

Each bus run: the listener first, then mlip-rt with its own --shm segment,
then mlip-feed with the program (mlip-ctl commands in a thread meanwhile),
then SIGTERM to mlip-rt (a controlled stop) and to the listener. Checked:
  - every frame mlip-rt says it sent (its exit line) reached the listener, as
    complete cycles numbered 0..N-1 (no gap, no incomplete cycle, no stray,
    no socket drop);
  - without commands: the decoded counts equal round(trace * COUNTS_PER_UNIT)
    row for row (home position while idle and pre-reading, then trace rows
    1.. one per cycle, then the last point until the end);
  - mlip-check --quantum passes on the decoded positions;
  - mlip-feed exits 0, exec_seq = blocks + 1, the machine ends idle at rest
    on the program's last point;
  - override / hold / resume / stop while running: physics within bounds,
    the hold stops on the path and resumes, the stop rests on the path
    (mlip-feed exits 4, controller IDLE).
"""
import json
import signal
import struct
import time

import pytest

from conftest import S
from mlipcan import compare, decoders, layout, listen, procs, report, sources
from mlipcan.config import MachineLimits, UsageError, setup_of

IFACE = S.iface

FLOWER = S.toolpaths / "flower-spiral-2d.ngc"
MB23 = S.toolpaths / "MB-2.3_test.nc"
DEMO = S.root / "examples" / "demo.ngc"
PAPER = S.config_dir / "paper-2axis.ini"
MILL = S.config_dir / "mill-3axis.ini"
# Cuts: the first lines of each file (its header sets units and modes), a few
# seconds of machining at the machine's limits.
FLOWER_LINES = 2000   # 1998 blocks, 2.95 s
MB23_LINES = 400      # 398 blocks, ~3.6 s


def cut(src, n, tmp_path):
    return compare.cut_program(src, n, tmp_path / f"{src.stem}-{n}.ngc")


# ------------------------------------------------------------------ checks

def bus_complete(r, setup, profile):
    """Every frame sent arrived, as complete cycles 0..N-1. Returns N."""
    assert r["rt_rc"] == 0, f"mlip-rt exited {r['rt_rc']}:\n{r['rt_stderr']}"
    assert r["listen_rc"] == 0, f"listener exited {r['listen_rc']}:\n{r['listen_stderr']}"
    rt, rep = r["rt"], r["report"]
    n = len(setup.axes)
    per = {"cia402": 1 + n, "packed": (n + 1) // 2 + 1, "fd": 1}[profile]
    N = rt["periods"]
    assert rt["tx_dropped"] == 0, rt["line"]
    assert rt["frames_sent"] == N * per, \
        f"mlip-rt: {rt['frames_sent']} frames in {N} periods, {per} expected per period"
    bad = {k: rep[k] for k in ("gaps", "incomplete", "duplicates", "stray", "malformed",
                               "backwards", "socket_drops") if rep.get(k)}
    assert not bad, f"listener saw {bad}; events {rep['events'][:10]}"
    assert rep["frames_ours"] == rt["frames_sent"], \
        f"mlip-rt sent {rt['frames_sent']} frames, the listener saw {rep['frames_ours']}"
    assert rep["cycles"] == N, f"{N} periods sent, {rep['cycles']} cycles decoded"
    assert r["cycles"] == list(range(N)), "cycle numbers are not 0..N-1"
    if profile == "cia402":
        assert rep["syncs"] == N
    return N


def physics(rig, ngc, counts, quantum, tmp, end_on_last=True):
    """mlip-check --quantum on decoded positions (t = k T)."""
    setup = rig.setup
    csv = tmp / "decoded.csv"
    compare.write_positions_csv(csv, counts, setup.cpu, setup.period_s)
    p, js = compare.mlip_check(S, rig.config, ngc, csv, quantum, tmp / "check.json")
    if end_on_last:
        assert p.returncode == 0, f"mlip-check on the decoded positions:\n{p.stderr}"
    else:
        # mlip-check insists on ending at the program's last point; after a
        # stop we judge its measurements with the same bounds, minus that.
        assert js is not None, p.stderr
        max_abs = max(abs(c[i] / setup.cpu[i]) for c in counts for i in range(len(setup.cpu)))
        bad = compare.check_bounds(MachineLimits.of(S, rig.config), js, quantum, max_abs)
        assert not bad, f"decoded positions out of bounds: {bad}\n{p.stderr}"
    return js


def summary_line(name, rig, r, extra=""):
    rep = r["report"]
    tm = rep["timing"]
    print(f"\n[{name}] {rig.profile}: {r['rt']['periods']} periods, {rep['frames_ours']} frames, "
          f"{rep['cycles']} cycles, bus period p50 {tm.get('p50_us')} us p99 {tm.get('p99_us')} "
          f"us max {tm.get('max_us')} us, listener cpu {rep['cpu_s']} s for {rep['wall_s']} s, "
          f"overruns {r['rt'].get('overruns')}{extra}")


def exact_run(tmp_path, config, ngc, profile, exec_listener=S.exec_listener, strategy="mpct"):
    """A whole program, no commands: the bus must carry the simulator's trace."""
    rows, summ = compare.simulate(S, config, ngc, tmp_path, "--strategy", strategy)
    setup = setup_of(S, config)
    trc = compare.trace_counts(rows, setup.cpu)
    with procs.Rig(S, config, profile, tmp_path, exec_listener=exec_listener,
               rt_args=("--strategy", strategy)) as rig:
        rc, out, err = rig.feed(ngc)
        assert rc == 0, f"mlip-feed exited {rc}:\n{err}"
        done = rig.wait_state("idle", timeout=60)
    r = rig.result
    bus_complete(r, setup, profile)
    can = r["counts"]
    off, how = compare.align(can, trc)
    home = trc[0]
    assert off > 0, f"no idle cycle before the motion ({how})"
    assert all(c == home for c in can[:off]), "the bus moved before the trace's first row"
    bad = compare.first_mismatch(can, trc, off)
    # JERK_PLAN = path: a planning thread that fell behind the period (its
    # queue ran dry) brakes, as it must; mlip-rt says so on stderr
    dry = [ln for ln in r.get("rt_stderr", "").splitlines() if "queue ran dry" in ln]
    assert bad is None, f"bus != mlip-sim trace ({how}): {bad}" + "".join(f"\n{d}" for d in dry)
    tail = can[off + len(trc):]
    assert len(tail) > 0 and all(c == trc[-1] for c in tail), \
        "the bus does not stay on the last point after the program"
    quantum = max(1.0 / c for c in setup.cpu)
    js = physics(rig, ngc, can[off:], quantum, tmp_path)
    # every block executed, in order; at rest on the last point (the records
    # are the smoothed blocks with --strategy smooth)
    blocks = summ["blocks_run"]
    st = rig.final_status
    assert st["state"] == "idle", st
    assert st["exec_seq"] == blocks + 1 == done["exec_seq"], (st, blocks)
    assert st["total_blocks"] == blocks + 1 and st["program_end"], st
    assert r["report"]["last"]["counts"] == dict(zip(setup.axes, trc[-1]))
    summary_line(ngc.name, rig, r, f", trace {len(trc)} rows = bus cycles {off}..{off + len(trc) - 1}"
                 f" exactly, {blocks} blocks, max contour {js['max_contour_error_mm']:.6f} mm")
    return rig, r, off, trc


# ------------------------------------------------------------------ bus tests

@pytest.mark.parametrize("profile", ["cia402", "packed", "fd"])
def test_flower_2d_exact(vcan, fd_mtu, tmp_path, profile):
    """2-D micro-segments (flower-spiral-2d.ngc, cut) on the paper's machine."""
    exact_run(tmp_path, PAPER, cut(FLOWER, FLOWER_LINES, tmp_path), profile)


@pytest.mark.parametrize("profile", ["cia402", "packed", "fd"])
def test_mb23_3axis_exact(vcan, fd_mtu, tmp_path, profile):
    """3-D raster micro-segments (MB-2.3_test.nc, cut) on the 3-axis mill."""
    exact_run(tmp_path, MILL, cut(MB23, MB23_LINES, tmp_path), profile)


def test_mb23_smooth_exact(vcan, tmp_path):
    """--strategy smooth end to end: mlip-rt publishes it, mlip-feed sends the
    smoothed path, the bus carries mlip-sim's smooth trace to the count, and
    mlip-check judges it against the ORIGINAL program's polyline."""
    exact_run(tmp_path, MILL, cut(MB23, MB23_LINES, tmp_path), "cia402", strategy="smooth")


def test_mb23_jerk_exact(vcan, tmp_path):
    """A jerk-limited program end to end: MAX_JERK = 1e5 mm/s^3 on every
    axis of the mill, in the machine file mlip-rt, mlip-feed and mlip-sim
    read; smooth (the strategy the limit costs least). The bus carries
    mlip-sim's trace to the count, and that trace keeps the jerk limit in
    double precision (third differences, tools/lib/check.c) and uses it."""
    ini = MILL.read_text()
    cfg = tmp_path / "mill-jerk.ini"
    for axis in ("X", "Y", "Z"):
        ini = ini.replace(f"[AXIS_{axis}]\n", f"[AXIS_{axis}]\nMAX_JERK = 100000\n")
    cfg.write_text(ini)
    ngc = cut(MB23, MB23_LINES, tmp_path)
    _, summ = compare.simulate(S, cfg, ngc, tmp_path, "--strategy", "smooth")
    assert summ["jerk_limit"] == [100000] * 3 and summ["violations"] == 0, summ
    ratio = max(j / lim for j, lim in zip(summ["max_axis_jerk"], summ["jerk_limit"]))
    assert 0.5 <= ratio <= 1 + 1e-6, summ["max_axis_jerk"]  # used, and kept
    exact_run(tmp_path, cfg, ngc, "cia402", strategy="smooth")


def test_demo_whole_exact(vcan, tmp_path):
    """One whole program: examples/demo.ngc (1819 blocks, 6.5 s, arcs and a
    helix). No shared toolpath runs in under a minute: the shortest, 4006.nc
    on config/rotary-4axis.ini, takes 228 s of machining.
    The listener runs here as its own process (`mlip-listen`, the command
    line a user types, SIGTERM to end it); the other runs fork it
    from pytest to save the interpreter's start, 10-35 s in the emulated VM."""
    exact_run(tmp_path, MILL, DEMO, "cia402", exec_listener=True)


# -- commands while running (physics only: the timing of a command decides
#    the motion, so there is no trace to compare with)

def moving_span(counts):
    """First and last cycle index where the position changes."""
    first = next(i for i in range(1, len(counts)) if counts[i] != counts[i - 1])
    last = next(i for i in range(len(counts) - 1, 0, -1) if counts[i] != counts[i - 1])
    return first - 1, last


def wait_periods(rig, n, since):
    """Wait until the controller has run n periods after status `since`
    (heartbeat = periods run): a window measured in periods, whatever the
    speed of the (emulated) machine. Returns the status at its end."""
    target = since["heartbeat"] + n
    while True:
        s = rig.status()
        if s["heartbeat"] >= target:
            return s
        time.sleep(0.05)


# The heartbeat of a status read is the number of periods run so far: the
# frames of period p (cycle p on the bus, counted from 0) went out before a
# status showing heartbeat p + 1. A command acknowledged before a status read
# with heartbeat H acted at a cycle < H.


def test_override_changes(vcan, tmp_path):
    """Override 40 %, then 150 %, then 100 % during demo.ngc: the limits hold,
    the 40 % phase stays under 40 % of the feed cap, the program completes."""
    config, ngc = MILL, DEMO
    rows, summ = compare.simulate(S, config, ngc, tmp_path)
    lim = MachineLimits.of(S, config)
    m = {}

    def actions(rig):
        rig.wait_state("running", pred=lambda s: s["exec_seq"] > 50)
        rig.ctl("override", "40")
        m["slow_from"] = rig.status()
        m["slow_to"] = wait_periods(rig, 1200, m["slow_from"])
        rig.ctl("override", "150")
        wait_periods(rig, 600, rig.status())
        rig.ctl("override", "100")
        m["last"] = rig.status()

    with procs.Rig(S, config, "cia402", tmp_path) as rig:
        rc, out, err = rig.feed(ngc, actions)
        assert rc == 0, f"mlip-feed exited {rc}:\n{err}"
        rig.wait_state("idle", timeout=60)
    r = rig.result
    setup = rig.setup
    bus_complete(r, setup, "cia402")
    can = r["counts"]
    start, end = moving_span(can)
    quantum = max(1.0 / c for c in setup.cpu)
    physics(rig, ngc, can[start:], quantum, tmp_path)
    assert m["last"]["override_pct"] == 100, m["last"]
    st = rig.final_status
    assert st["state"] == "idle" and st["exec_seq"] == summ["blocks"] + 1, st
    assert can[-1] == compare.trace_counts(rows[-1:], setup.cpu)[0], "not at rest on the last point"
    # the 40 % phase: from the command plus the time to brake from v_m on
    brake = int(lim.vmax / min(lim.accel) / lim.period_s) + 20
    i0, i1 = m["slow_from"]["heartbeat"] + brake, m["slow_to"]["heartbeat"] - 1
    assert i1 - i0 >= 900 and start < i0 and i1 < end, (start, i0, i1, end)
    sp = compare.speeds(can[i0:i1], setup.cpu, setup.period_s, [True] * 3)
    cap = 0.40 * lim.vmax + 4 * quantum * 3 ** 0.5 / lim.period_s
    assert max(sp) <= cap, f"speed {max(sp):.3f} mm/s at 40 % override (cap {cap:.3f})"
    moving = end - start
    assert moving > len(rows) - 1 + 300, \
        f"{moving} periods of motion with a 40 % phase, {len(rows) - 1} at 100 %"
    summary_line("override", rig, r, f", motion {moving} periods vs {len(rows) - 1} simulated at "
                 f"100 %, max speed in the 40 % phase {max(sp):.2f} mm/s")


def test_hold_resume(vcan, tmp_path):
    """Feed hold mid-program: the machine brakes to rest on the path (the
    same setpoint on consecutive cycles while held), resumes, completes."""
    config, ngc = MILL, DEMO
    rows, summ = compare.simulate(S, config, ngc, tmp_path)
    m = {}

    def actions(rig):
        rig.wait_state("running", pred=lambda s: s["exec_seq"] > 400)
        m["hold"] = rig.status()
        rig.ctl("hold")
        m["held"] = rig.wait_state("held", timeout=60)
        m["resume"] = wait_periods(rig, 800, m["held"])
        rig.ctl("resume")
        m["after"] = rig.wait_state("running", timeout=60)

    with procs.Rig(S, config, "cia402", tmp_path) as rig:
        rc, out, err = rig.feed(ngc, actions)
        assert rc == 0, f"mlip-feed exited {rc}:\n{err}"
        rig.wait_state("idle", timeout=60)
    r = rig.result
    setup = rig.setup
    bus_complete(r, setup, "cia402")
    can = r["counts"]
    start, end = moving_span(can)
    quantum = max(1.0 / c for c in setup.cpu)
    # on the path, within every limit, braking and restarting included
    physics(rig, ngc, can[start:], quantum, tmp_path)
    # still from when HELD was reported until the resume
    h0, h1 = m["held"]["heartbeat"] - 1, m["resume"]["heartbeat"] - 1
    assert all(c == can[h0] for c in can[h0:h1 + 1]), "the setpoint moved while HELD"
    run_len, at = compare.longest_still_run(can, start + 1, end)
    assert at <= h0 and h1 < at + run_len, (at, run_len, h0, h1)
    assert start < at and at + run_len < end, "the still run is not inside the motion"
    # moving when the hold was sent (the rest began after it)
    assert at >= m["hold"]["heartbeat"] - 1, (at, m["hold"])
    assert 0 < m["held"]["exec_seq"] < summ["blocks"] + 1, m["held"]
    st = rig.final_status
    assert st["state"] == "idle" and st["exec_seq"] == summ["blocks"] + 1, st
    assert can[-1] == compare.trace_counts(rows[-1:], setup.cpu)[0], "not at rest on the last point"
    summary_line("hold", rig, r, f", still for {run_len} cycles from cycle {at} "
                 f"(block {m['held']['exec_seq']}), then resumed to the end")


def test_stop(vcan, tmp_path):
    """Stop mid-program: mlip-feed exits 4, the machine decelerates on the path
    to rest (contour and acceleration within bounds; no end-point condition),
    the controller is IDLE and the rest of the program is dropped."""
    config, ngc = MILL, DEMO
    rows, summ = compare.simulate(S, config, ngc, tmp_path)
    lim = MachineLimits.of(S, config)
    m = {}

    def actions(rig):
        rig.wait_state("running", pred=lambda s: s["exec_seq"] > 400)
        m["before"] = rig.status()
        rig.ctl("stop")
        m["after"] = rig.status()

    with procs.Rig(S, config, "cia402", tmp_path) as rig:
        rc, out, err = rig.feed(ngc, actions)
        assert rc == 4, f"mlip-feed exited {rc} after a stop (4 expected):\n{err}"
        idle = rig.wait_state("idle", timeout=60)
    r = rig.result
    setup = rig.setup
    bus_complete(r, setup, "cia402")
    can = r["counts"]
    start, end = moving_span(can)
    quantum = max(1.0 / c for c in setup.cpu)
    physics(rig, ngc, can[start:], quantum, tmp_path, end_on_last=False)
    last = compare.trace_counts(rows[-1:], setup.cpu)[0]
    assert can[-1] != last, "the program ran to its end despite the stop"
    assert all(c == can[end] for c in can[end:]), "not at rest after the stop"
    # moving when the stop was sent, at rest within the braking time after
    brake = int(lim.vmax / min(lim.accel) / lim.period_s) + 20
    assert end >= m["before"]["heartbeat"] - 1, "the motion ended before the stop was sent"
    assert end <= m["after"]["heartbeat"] + brake, \
        f"rest at cycle {end}, stop acknowledged by cycle {m['after']['heartbeat']}"
    fs = rig.final_status
    assert fs["state"] == "idle" and idle["state"] == "idle", fs
    assert 0 < fs["exec_seq"] < summ["blocks"] + 1, fs
    summary_line("stop", rig, r, f", stopped in block {fs['exec_seq']} of {summ['blocks']}, at rest "
                 f"{end - m['before']['heartbeat']} cycles after the last status before the stop")


EVENTS_NGC = ("G21 G90 G94\nG1 X20 F3000\nG1 X20 Y20\nG4 P0.3\nG1 X40 Y20\nM0\n"
              "G1 X40 Y40\nG1 X0 Y0\nM2\n")


def test_dwell_and_pause(vcan, tmp_path):
    """G4 P0.3 and M0 end to end: up to the M0 point the bus carries
    mlip-sim's trace to the count, the dwell included (the machine still at
    (20, 20) for exactly 300 periods); at the M0 point still from "paused"
    to the resume; mlip-check passes on all of it; the program completes."""
    config = MILL
    ngc = tmp_path / "events.ngc"
    ngc.write_text(EVENTS_NGC)
    rows, summ = compare.simulate(S, config, ngc, tmp_path)
    setup = setup_of(S, config)
    trc = compare.trace_counts(rows, setup.cpu)
    dwell_pt = tuple(compare.to_counts(x, c) for x, c in zip((20.0, 20.0, 0.0), setup.cpu))
    pause_pt = tuple(compare.to_counts(x, c) for x, c in zip((40.0, 20.0, 0.0), setup.cpu))
    j = trc.index(pause_pt)  # the trace reaches the M0 point
    m = {}

    def actions(rig):
        m["paused"] = rig.wait_state("paused", timeout=60)
        m["resume"] = wait_periods(rig, 500, m["paused"])
        rig.ctl("resume")

    with procs.Rig(S, config, "cia402", tmp_path) as rig:
        rc, out, err = rig.feed(ngc, actions)
        assert rc == 0, f"mlip-feed exited {rc}:\n{err}"
        assert "paused (pause (M0)) at line 6: mlip-ctl resume continues" in err, err
        rig.wait_state("idle", timeout=60)
    r = rig.result
    bus_complete(r, setup, "cia402")
    can = r["counts"]
    off, how = compare.align(can, trc)
    bad = compare.first_mismatch(can[:off + j + 1], trc[:j + 1], off)
    assert bad is None, f"bus != mlip-sim trace up to the pause ({how}): {bad}"
    # the dwell in the setpoints the bus carried (equal to the trace there):
    # exactly at (20, 20) for 301 samples, 300 periods (counts round a few
    # more samples of the approach and the departure onto that point)
    still = [i for i, r in enumerate(rows[:j]) if tuple(r[1:]) == (20.0, 20.0, 0.0)]
    assert len(still) == 301 and still[-1] - still[0] == 300, len(still)
    assert all(can[off + i] == dwell_pt for i in still)
    p0, p1 = m["paused"]["heartbeat"] - 1, m["resume"]["heartbeat"] - 1
    assert p1 - p0 >= 500 and all(c == pause_pt for c in can[p0:p1 + 1]), "moved while paused"
    quantum = max(1.0 / c for c in setup.cpu)
    physics(rig, ngc, can[off:], quantum, tmp_path)
    st = rig.final_status
    assert st["state"] == "idle" and st["exec_seq"] == summ["blocks"] + 1, st
    summary_line("events", rig, r, f", dwell 300 periods at (20, 20), paused {p1 - p0} "
                 f"periods at (40, 20)")


def test_stall_holds_without_jump(vcan, tmp_path):
    """SIGSTOP/SIGCONT to mlip-rt at speed (1 s): on the bus the positions
    after the gap repeat the last one sent, then the motion restarts from
    rest on mlip-ctl resume; mlip-check passes on the decoded positions with
    the gaps as holes (this guest adds stalls of its own: each is resumed)."""
    config, ngc = MILL, DEMO
    setup = setup_of(S, config)
    m = {}

    def resumed(rig):
        """The status, a stall hold the guest added by itself resumed (as an
        operator would)."""
        s = rig.status()
        if s["state"] == "held" and s["reason"] == "stall":
            rig.ctl("resume")
        return s

    def at_speed(rig, timeout=300):
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            s = resumed(rig)
            if s["state"] == "running" and s["exec_seq"] > 400 and s["speed_mm_s"] > 1.0:
                return
            time.sleep(0.05)
        raise AssertionError(f"not running at speed within {timeout} s: {rig.status_log[-1]}")

    def actions(rig):
        for _ in range(3):
            at_speed(rig)
            rig.rt.p.send_signal(signal.SIGSTOP)
            time.sleep(1.0)  # the stall itself: 1000 periods the loop does not run
            rig.rt.p.send_signal(signal.SIGCONT)
            m["held"] = rig.wait_state("held", timeout=60)
            if m["held"]["reason_value"] >= 900:
                break  # this SIGSTOP's (not a stall of the guest's just before it)
            rig.ctl("resume")
        while resumed(rig)["state"] != "idle":
            time.sleep(0.05)

    # 200 periods: above the spikes of an emulated guest (~0.3 s at worst)
    with procs.Rig(S, config, "cia402", tmp_path, rt_args=["--stall-periods", "200"]) as rig:
        rc, out, err = rig.feed(ngc, actions)
        assert rc == 0, f"mlip-feed exited {rc}:\n{err}"
        assert "stall: the controller missed" in err and "mlip-ctl resume" in err, err
    r = rig.result
    assert m["held"]["reason"] == "stall" and m["held"]["reason_value"] >= 900, m["held"]
    assert "stall: the loop missed" in r["rt_stderr"], r["rt_stderr"]
    bus_complete(r, setup, "cia402")
    can, t = r["counts"], r["t"]
    T = setup.period_s
    # the SIGSTOP: the longest gap between two cycles on the bus while moving
    # (a SIGSTOP that met a stall hold of the guest's own found it at rest)
    gap, k = max((t[i] - t[i - 1], i) for i in range(2, len(t)) if can[i - 1] != can[i - 2])
    assert gap > 0.8, gap
    assert can[k] == can[k - 1] and can[k + 1] == can[k], "a jump after the stall"
    j = next(i for i in range(k, len(can)) if can[i] != can[k])
    quantum = max(1.0 / c for c in setup.cpu)
    step = max(abs(a - b) / c for a, b, c in zip(can[j], can[j - 1], setup.cpu))
    amax = max(MachineLimits.of(S, config).accel)
    assert step <= amax * T * T + 2 * quantum, f"restarted with {step} mm in one period"
    # physics across the whole run, gaps of more than 10 periods as holes
    cycles = [0]
    for i in range(1, len(t)):
        d = t[i] - t[i - 1]
        cycles.append(cycles[-1] + (round(d / T) if d > 10 * T else 1))
    csv = tmp_path / "decoded.csv"
    compare.write_positions_csv(csv, can, setup.cpu, T, cycles)
    p, _ = compare.mlip_check(S, config, ngc, csv, quantum, tmp_path / "check.json")
    assert p.returncode == 0, f"mlip-check on the decoded positions:\n{p.stderr}"
    summary_line("stall", rig, r, f", gap {gap:.3f} s at cycle {k}, held {j - k} cycles, "
                 f"restart step {step * 1e3:.2f} um")


# ------------------------------------------------------------------ offline

def _frames(setup, profile, cycle, counts):
    """Reference encoder (canenc.h layouts) for the offline tests."""
    n = len(setup.axes)
    if profile == "cia402":
        return [(setup.sync_id, b"", False)] + \
            [(setup.rpdo_base + setup.nodes[i], struct.pack("<i", counts[i]), False) for i in range(n)]
    if profile == "packed":
        out = []
        for k in range((n + 1) // 2):
            vals = counts[2 * k:2 * k + 2]
            out.append((setup.packed_base + k, struct.pack("<" + "i" * len(vals), *vals), False))
        out.append((setup.packed_base + (n + 1) // 2, struct.pack("<I", cycle), False))
        return out
    ln = layout.fd_len(4 + 4 * n)
    data = struct.pack("<I" + "i" * n, cycle, *counts)
    return [(setup.fd_id, data + bytes(ln - len(data)), True)]


def _write_log(path, frames):
    with open(path, "w") as fh:
        for t, (cid, data, fd) in frames:
            ts = f"({t // 10**9}.{t % 10**9 // 1000:06d})"
            if fd:
                fh.write(f"{ts} vcan0 {cid:03X}##1{data.hex().upper()}\n")
            else:
                fh.write(f"{ts} vcan0 {cid:03X}#{data.hex().upper()}\n")


def _listen_offline(tmp_path, config, profile, frames):
    log = tmp_path / f"{profile}.log"
    _write_log(log, frames)
    rc = listen.main(["--from-log", str(log), "--config", str(config), "--profile", profile,
                        "--csv", str(tmp_path / "o.csv"), "--json", str(tmp_path / "o.json"),
                        "--log", str(tmp_path / "o.log"), "-q"], settings=S)
    assert rc == 0
    rep = json.loads((tmp_path / "o.json").read_text())
    assert (tmp_path / "o.log").read_text() == log.read_text(), "--log is not the same candump text"
    return rep, report.read_csv(tmp_path / "o.csv", len(setup_of(S, config).axes))


@pytest.mark.parametrize("profile", ["cia402", "packed", "fd"])
@pytest.mark.parametrize("config", [PAPER, MILL, S.config_dir / "rotary-4axis.ini"],
                         ids=["2axis", "3axis", "4axis"])
def test_listener_decodes_and_reports_loss(tmp_path, config, profile):
    """Frames of 20 periods with one period lost, one frame lost and one frame
    duplicated: the listener rebuilds the rest and names each anomaly."""
    setup = setup_of(S, config)
    n = len(setup.axes)
    npos = (n + 1) // 2
    t0 = 1_700_000_000_000_000_000
    seq, want = [], {}
    for c in range(20):
        counts = [(-1) ** i * (1000 * c + i) - (i == 1) * 2**30 for i in range(n)]
        want[c] = tuple(counts)
        fr = _frames(setup, profile, c, counts)
        if c == 5:
            continue                                  # a whole period lost
        if c == 9 and profile == "cia402":
            fr = fr[:1] + fr[2:]                      # the first RPDO lost
        if c == 9 and profile == "packed":
            fr = fr[:npos - 1] + fr[npos:]            # the last POS frame lost
        if c == 12:
            # cia402: an RPDO repeated after its cycle completed (stray);
            # packed: POS0 twice before the COMMIT (reads as a lost COMMIT);
            # fd: the frame twice (duplicate counter)
            fr = fr + fr[1:2] if profile == "cia402" else fr[:1] + fr
        seq += [(t0 + c * 1_000_000 + j * 1000, f) for j, f in enumerate(fr)]
    rep, (cyc, ts, cnt) = _listen_offline(tmp_path, config, profile, seq)
    if profile == "cia402":
        # no counter on the wire: the cycle number is the SYNC count, so
        # period 5 (SYNC lost too) cannot be seen; the rest can
        periods = [c for c in range(20) if c != 5]
        decoded = [periods[k] for k in cyc]
        assert decoded == [c for c in periods if c != 9]
        assert rep["syncs"] == 19 and rep["cycles"] == 18
        assert rep["incomplete"] == 1 and rep["missing_rpdo"] == 1      # period 9
        assert rep["stray"] == 1 and rep["missing_sync"] == 0           # period 12
    elif profile == "packed":
        decoded = cyc
        assert decoded == [c for c in range(20) if c not in (5, 9)]
        assert rep["gaps"] == 1 and rep["gap_events"] == 1              # period 5
        assert rep["incomplete"] == 2 and rep["commit_lost"] == 1       # 9, 12
    else:
        decoded = cyc
        assert decoded == [c for c in range(20) if c != 5]
        assert rep["gaps"] == 1 and rep["duplicates"] == 1              # 5, 12
    assert cnt == [want[c] for c in decoded]
    # t = the cycle's first frame (packed 12: the repeated POS0 restarted it)
    first = {c: 1 if profile == "packed" and c == 12 else 0 for c in decoded}
    assert [round(t * 1e6) for t in ts] == [(t0 + c * 1_000_000) // 1000 + first[c] for c in decoded]
    assert rep["timing"]["p50_us"] == 1000.0
    assert not rep["clean"]


def test_listener_missing_sync(tmp_path):
    """cia402: a whole set of RPDOs with no SYNC before it is a missing SYNC."""
    setup = setup_of(S, MILL)
    seq = []
    for c in range(6):
        fr = _frames(setup, "cia402", c, [c, c, c])
        if c == 3:
            fr = fr[1:]
        seq += [(1_700_000_000_000_000_000 + c * 1_000_000 + j, f) for j, f in enumerate(fr)]
    rep, (cyc, ts, cnt) = _listen_offline(tmp_path, MILL, "cia402", seq)
    assert rep["missing_sync"] == 1 and rep["stray"] == 3 and rep["cycles"] == 5
    assert cnt == [(c, c, c) for c in (0, 1, 2, 4, 5)]


def test_listener_counts_to_positions(tmp_path):
    """CSV positions are counts / COUNTS_PER_UNIT (100 counts/deg on A)."""
    config = S.config_dir / "rotary-4axis.ini"
    setup = setup_of(S, config)
    assert setup.cpu == [1000.0, 1000.0, 1000.0, 100.0] and setup.nodes == [1, 2, 3, 4]
    counts = [12345, -1, 2**31 - 1, -2**31]
    frames = [(1_700_000_000_000_000_000, f) for f in _frames(setup, "cia402", 0, counts)]
    rep, (cyc, ts, cnt) = _listen_offline(tmp_path, config, "cia402", frames)
    assert cnt == [tuple(counts)]
    line = (tmp_path / "o.csv").read_text().splitlines()[1].split(",")
    assert [float(v) for v in line[2:6]] == [12.345, -0.001, 2147483.647, -21474836.48]
    assert rep["clean"] and rep["last"]["pos"]["A"] == -21474836.48
    assert any("COUNTS_PER_UNIT 100" in n for n in rep["dbc_notes"])


def test_listener_records_a_cia402_deployment(tmp_path):
    """[DRIVES] ENABLE = 1 (--drives): 6-byte RPDOs (controlword, target),
    the drives' TPDOs (statusword, position actual value), an EMCY, heartbeats
    and NMT commands on the same bus: the cycles decode as before, the TPDOs
    go to --tpdo-csv and the report's "drives", the rest is named; the same
    frames through an .asc log (python-can's can.Logger / can.LogReader)
    decode the same."""
    setup = setup_of(S, MILL)
    t0 = 1_700_000_000_000_000_000
    seq = [(t0, (0x000, bytes([0x01, 0]), False))]
    for c in range(10):
        t = t0 + (c + 1) * 1_000_000
        fr = [(setup.sync_id, b"", False)]
        fr += [(0x180 + nd, struct.pack("<Hi", 0x1237, 500 * i + c - 1), False)
               for i, nd in enumerate(setup.nodes)]
        fr += [(setup.rpdo_base + nd, struct.pack("<Hi", 0x0F, 500 * i + c), False)
               for i, nd in enumerate(setup.nodes)]
        if c == 4:
            fr.append((0x082, bytes.fromhex("1086010000000000"), False))
        if c % 5 == 0:
            fr += [(0x700 + nd, b"\x05", False) for nd in setup.nodes]
        seq += [(t + j * 1000, f) for j, f in enumerate(fr)]
    log = tmp_path / "d.log"
    _write_log(log, seq)
    out = {}
    for name, src in (("log", log), ("asc", tmp_path / "d.asc")):
        if name == "asc":  # candump -> .asc through the listener's own --log
            assert listen.main(["--from-log", str(log), "--config", str(MILL), "--drives",
                                  "--log", str(src), "-q"], settings=S) == 0
        js = tmp_path / f"{name}.json"
        tp = tmp_path / f"{name}-tpdo.csv"
        assert listen.main(["--from-log", str(src), "--config", str(MILL), "--drives",
                              "--json", str(js), "--tpdo-csv", str(tp), "-q"], settings=S) == 0
        out[name] = (json.loads(js.read_text()), tp.read_text().splitlines())
    for rep, rows in out.values():
        assert rep["cycles"] == 10 and rep["incomplete"] == 0 and rep["malformed"] == 0
        assert rep["last"]["counts"] == {"X": 9, "Y": 509, "Z": 1009}
        assert rep["layout"]["rpdo_len"] == 6
        d = rep["drives"]
        assert [d[str(n)]["tpdos"] for n in setup.nodes] == [10, 10, 10]
        assert d["2"]["last"]["actual"] == 508 and d["2"]["last"]["state"] == "operation enabled"
        assert d["2"]["emcy"][0]["code"] == "0x8610" and d["2"]["emcy"][0]["error_register"] == 1
        assert d["1"]["heartbeats"] == 2 and d["1"]["heartbeat_state"] == "operational"
        assert rep["nmt"] == [{"t": rep["nmt"][0]["t"], "command": "0x01", "node": 0}]
        assert rows[0] == "t,node,axis,statusword,state,actual,pos" and len(rows) == 31
        assert rows[-1].split(",")[1:] == ["3", "Z", str(0x1237), "operation enabled", "1008",
                                           "1.008"]
    assert out["log"][1] == out["asc"][1] or \
        [r.split(",")[1:] for r in out["log"][1]] == [r.split(",")[1:] for r in out["asc"][1]]


def _batch(frames):
    """(t ns, id, data) frames as one recvmmsg would leave them in the fast
    path's buffers (frame, msg_len, the SO_TIMESTAMPNS control message)."""
    src = sources

    class NoSocket:
        def fileno(self):
            return -1

    mm = src.MMsg(NoSocket(), n=len(frames))
    for j, (t, cid, data) in enumerate(frames):
        o = j * src.CANFD_MTU
        struct.pack_into("=IB", mm.frames, o, cid, len(data))
        mm.frames[o + 8:o + 8 + len(data)] = data
        struct.pack_into("=Q", mm.hdr, mm.HDR * j + 40, 32)        # msg_controllen
        struct.pack_into("=I", mm.hdr, mm.HDR * j + 56, 16)        # msg_len: CAN_MTU
        struct.pack_into("=QiiQQ", mm.ctl, mm.CTL * j, 32, 1, src.SO_TIMESTAMPNS,
                         t // 10**9, t % 10**9)
    return src.Batch(mm, len(frames), 1)


def test_listener_fast_path_with_drives_frames():
    """The fast path (recvmmsg batches, the emulated VM's) on a deployment
    stream: 6-byte RPDOs, the drives' TPDOs between them in any order. It
    decodes what the frame-by-frame path decodes (cycles, times, counts,
    TPDOs), and most stream frames by slicing."""
    import random

    setup = setup_of(S, MILL)
    setup.drives = True
    lay = layout.Layout(setup, "cia402", S.dbc, S.build)
    fr, t = [], 1_700_000_000_000_000_000
    for c in range(60):
        t += 1_000_000
        tp = [(t + 10, 0x180 + n, struct.pack("<Hi", 0x1237, c * n - 1)) for n in (1, 2, 3)]
        rp = [(t + 20, 0x200 + n, struct.pack("<Hi", 15, c * n * 1000 - 7)) for n in (1, 2, 3)]
        mix = tp + rp
        random.Random(c).shuffle(mix)
        rpdos = iter(rp)  # the RPDOs stay in axis order (mlip-rt sends them so)
        fr += [(t, 0x80, b"")] + [x if x[1] < 0x200 else next(rpdos) for x in mix]
    fast = decoders.DECODERS["cia402"](lay)
    for i in range(0, len(fr), 97):
        fast.feed_batch(_batch(fr[i:i + 97]))
    slow = decoders.DECODERS["cia402"](lay)
    for t, cid, d in fr:
        slow.feed(t, cid, d, len(d), False)
    assert len(slow.cyc) == 60 and slow.counts[-1] == (58993, 117993, 176993)
    assert (fast.cyc, fast.tns, fast.counts) == (slow.cyc, slow.tns, slow.counts)
    assert sorted(fast.drives.tpdo) == sorted(slow.drives.tpdo) and len(fast.drives.tpdo) == 180
    assert fast.frames == slow.frames == len(fr) and fast.incomplete == fast.stray == 0
    assert fast.fast_frames > 0.9 * 60 * 4


@pytest.mark.parametrize("profile,message,change,error", [
    ("cia402", "RPDO_NODE2", {"length": 16}, "Y_target is 16 bits"),
    ("cia402", "RPDO_NODE1", {"is_signed": False}, "unsigned"),
    ("packed", "PACKED_POS0", {"byte_order": "big_endian"}, "big_endian"),
    ("fd", "FD_SETPOINT", {"start": 40}, "at bit 40"),
    ("packed", "PACKED_COMMIT", {"is_signed": True}, "cycle"),
])
def test_listener_refuses_a_dbc_that_disagrees(monkeypatch, profile, message, change, error):
    """The layout read from the DBC is checked field by field against what
    canenc.h sends for this config; a disagreement is an error (exit 2)."""
    msgs, _ = layout.load_dbc(S.dbc, S.build)
    bad = []
    for m in msgs:
        sigs = list(m.signals)
        if m.name == message:
            # the first axis field, or the counter when the error names it
            target = [s for s in sigs if (s.name == "cycle") == ("cycle" in error)
                      and s.name != "controlword"][:1]
            sigs = [s._replace(**change) if s in target else s for s in sigs]
        bad.append(m._replace(signals=tuple(sigs)))
    monkeypatch.setattr(layout, "load_dbc", lambda path, cache=None: (bad, "test"))
    with pytest.raises(UsageError, match=error):
        layout.Layout(setup_of(S, MILL), profile, S.dbc)
    rc = listen.main(["--check-layout", "--config", str(MILL), "--profile", profile], settings=S)
    assert rc == 2


def test_listener_layout_matches_config():
    """The DBC's default 6-axis setup against the shipped configs: ids and
    layouts agree; what differs (lengths, the COMMIT id for fewer axes,
    counts per unit) is noted, not refused."""
    for cfg in (PAPER, MILL, S.config_dir / "rotary-4axis.ini"):
        for profile in ("cia402", "packed", "fd"):
            lay = layout.Layout(setup_of(S, cfg), profile, S.dbc, S.build)
            assert lay.frames_per_cycle == {"cia402": 1 + lay.n, "packed": (lay.n + 1) // 2 + 1,
                                            "fd": 1}[profile]
            assert not any("0x" in n and "by the config" in n for n in lay.notes), lay.notes


def test_counts_rounding_matches_canenc():
    """round half away from zero, as mlip_can_counts (canenc.h)."""
    assert [compare.to_counts(v, 1000) for v in (0.0005, -0.0005, 0.0015, -0.0025, 1.2344999)] == \
        [1, -1, 2, -3, 1234]
    assert compare.to_counts(0.49999999999999994, 1) == 0
    assert compare.to_counts(2.5, 1) == 3 and compare.to_counts(-2.5, 1) == -3
