"""mlip-rt with [TRAJ] JERK_PLAN = path on this host (--can none): its
planning thread (tools/rtplan.c) takes the ring's records, the period
follows the planned queue; mlip-feed smooths on the plan's controller's
machine and refuses what the plan cannot run, as mlip-sim does."""

import math
import mmap
import random
import re
import signal
import struct
import subprocess
import sys
import time

import pytest

from conftest import (
    HEAD,
    ROOT,
    TAIL,
    TOOLPATHS,
    Proc,
    Ring,
    frozen,
    periods_on,
    record_checked,
    record_rows,
    status,
    terminate,
    tool,
    wait_for,
)
from test_pathfeeds import two_feeds
from test_planfeed import SQUARE, machine, one_feed


def feed(shm, program, timeout=120):
    return subprocess.run(
        [tool("mlip-feed"), "--shm", shm, "-q", str(program)],
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def sim_trace(cfg, program, trace):
    p = subprocess.run(
        [
            tool("mlip-sim"),
            "-q",
            "--config",
            cfg,
            "--strategy",
            "smooth",
            "--trace",
            trace,
            program,
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert p.returncode == 0, p.stderr
    return trace.read_text()


def positions(trace):
    """A trace's rows without their t."""
    return [r.split(",", 1)[1] for r in trace.splitlines()[1:]]


def test_path_plan_runs_as_mlip_sim(controller, tmp_path):
    """The setpoints mlip-rt sent (--record) are mlip-sim --config's, byte
    for byte and to the count (the plan's start, every period, the end at
    rest); the status
    counts the program's records; a second program runs after it."""
    cfg = machine(tmp_path)
    progs = [tmp_path / "square.ngc"]
    progs[0].write_text(SQUARE)
    if (TOOLPATHS / "MB-2.3_test.nc").exists():
        progs.append(one_feed(TOOLPATHS / "MB-2.3_test.nc", 400, tmp_path / "mb.ngc"))
    progs.append(tmp_path / "two-feeds.ngc")  # several F words: each block's own cap
    two_feeds(progs[-1])
    for k, prog in enumerate(progs):
        sim = sim_trace(cfg, prog, tmp_path / f"sim{k}.csv")
        assert len(sim.splitlines()) > 1000

        def more(shm):
            s = status(shm)
            assert s["state"] == "idle" and s["exec_seq"] == s["blocks_consumed"] > 1, s
            p = feed(shm, progs[0])  # the thread starts afresh for the next program
            assert p.returncode == 0, p.stderr

        runs_as_sim(controller, cfg, prog, sim, tmp_path / f"rt{k}", more)


def runs_as_sim(controller, cfg, prog, sim, rec_base, more=None):
    """mlip-rt's --record of prog is mlip-sim's trace sim, the positions to
    the byte, row by row (t: the record's counts the deadlines, with a hole
    where this non-real-time host missed one); run again, 3 runs at most,
    only when the queue ran dry (a loaded host). more(shm): after the feed,
    before mlip-rt stops."""
    for attempt in range(3):
        rec = rec_base.with_name(f"{rec_base.name}-{attempt}.csv")
        shm, rt = controller(cfg, "--strategy", "smooth", "--record", rec)
        p = feed(shm, prog)
        assert p.returncode == 0, p.stderr
        if more is not None:
            more(shm)
        rt.send_signal(signal.SIGTERM)
        _, err = rt.communicate(timeout=10)
        assert rt.returncode == 0, err
        got, want = positions(rec.read_text()), positions(sim)
        if got == want or "queue ran dry" not in err:
            break
    assert len(got) == len(want) and got == want, (len(got), len(want), err[-3000:])


def test_path_plan_on_a_fast_machine_runs_as_mlip_sim(controller, tmp_path):
    """A machine of A 5000 mm/s^2 (J 5e5): smooth runs for the plan at band
    / T^2 (tools/lib/simpath.c), the same in mlip-feed, the planning thread
    and mlip-sim: mlip-rt's setpoints are mlip-sim's byte for byte (the
    spiral's centre, which the plan refused on such a machine before)."""
    ini = machine(tmp_path).read_text().replace("MAX_JERK = 100000", "MAX_JERK = 500000")
    cfg = tmp_path / "mill-path-5000.ini"
    cfg.write_text(re.sub(r"MAX_ACCELERATION = [0-9.]+", "MAX_ACCELERATION = 5000", ini))
    gen, prog = tmp_path / "spiral.ngc", tmp_path / "spiral-2k.ngc"
    subprocess.run(
        [sys.executable, str(ROOT / "tools" / "gen_curves.py"), "spiral", str(gen)],
        check=True,
        capture_output=True,
    )
    prog.write_text("".join(gen.read_text().splitlines(True)[:2004]))
    sim = sim_trace(cfg, prog, tmp_path / "sim.csv")
    assert len(sim.splitlines()) > 300
    runs_as_sim(controller, cfg, prog, sim, tmp_path / "rt")


def test_feed_refuses_what_the_plan_cannot_run(controller, tmp_path):
    """A dwell and G61: refused by mlip-feed at their lines, as mlip-sim
    refuses them, before anything is sent (a G0 and a second F run:
    test_path_plan_runs_as_mlip_sim)."""
    cfg = machine(tmp_path)
    shm, _ = controller(cfg, "--strategy", "smooth")
    for body, line in (
        ("G21 G90\nG1 F600 X1\nG4 P0.5\nG1 X5\n", 3),
        ("G21 G90\nG1 F600 X1\nG61\nG1 X2\n", 4),
    ):
        prog = tmp_path / "bad.ngc"
        prog.write_text(body)
        p = feed(shm, prog)
        sim = subprocess.run(
            [tool("mlip-sim"), "-q", "--config", cfg, "--strategy", "smooth", prog],
            capture_output=True,
            text=True,
        )
        assert p.returncode == 1 and sim.returncode == 2, (p.stderr, sim.stderr)
        what = re.search(rf"bad.ngc:{line}: (.*): the path plan cannot run it yet", sim.stderr)
        assert what, sim.stderr
        assert (
            f"bad.ngc:{line}: {what.group(1)}: the path plan cannot run it yet "
            "(the controller's JERK_PLAN = path)"
        ) in p.stderr, p.stderr
        assert status(shm)["blocks_consumed"] == 0


def textured(seed, lines):
    """A program of random strokes and curves (the texture of a test's
    storm of holds and feeds that found the refusal below mid-run): parts
    of 20-200 strokes of 0.05-0.6 mm turning by up to 1.2 rad, or 200-1500
    chords of 0.05 mm on curves of 0.5-10 mm radius, at F3000-12000; its
    first `lines` lines."""
    r = random.Random(seed)
    out = ["G21 G90", "G1 F%d" % r.choice([3000, 6000, 12000])]
    x = y = 0.0
    for _ in range(r.randint(2, 4)):
        if r.random() < 0.5:
            h, rad, th = 0.05, r.uniform(0.5, 10), r.uniform(0, 6)
            for i in range(r.randint(200, 1500)):
                th += h / rad * (1 + 0.5 * math.sin(i * 0.05))
                x, y = x + h * math.cos(th), y + h * math.sin(th)
                out.append("G1 X%.4f Y%.4f" % (x, y))
        else:
            d = r.uniform(0, 6)
            for _ in range(r.randint(20, 200)):
                d += r.uniform(-1.2, 1.2)
                s = r.uniform(0.05, 0.6)
                x, y = x + s * math.cos(d), y + s * math.sin(d)
                out.append("G1 X%.4f Y%.4f" % (x, y))
    return "\n".join(out[:lines]) + "\n"


def test_feed_refuses_what_the_plan_refuses(controller, tmp_path):
    """A program whose spline strays past the band ((P6), found only by
    running the plan): mlip-feed runs the plan first, as the planning thread
    will, and refuses it with mlip-sim's reason and figures, nothing sent
    (before: the machine ran it to line 300 of its 347, where the plan's
    refusal was a fault on the path, the program cut short, mlip-rt to be
    restarted); a
    program the plan runs goes on after it, to its end at mlip-sim's last
    setpoint."""
    cfg = machine(tmp_path)
    shm, rt = controller(cfg, "--strategy", "smooth")
    prog = tmp_path / "textured.ngc"
    prog.write_text(textured(98, 347))
    sim = subprocess.run(
        [tool("mlip-sim"), "-q", "--config", cfg, "--strategy", "smooth", prog],
        capture_output=True,
        text=True,
    )
    where = re.search(
        r"\(P6\), .* at ([0-9.]+ mm of the path \([0-9.]+ mm, the band [0-9.]+ mm\))", sim.stderr
    )
    assert sim.returncode == 1 and where, sim.stderr
    p = feed(shm, prog)
    assert p.returncode == 1, p.stderr
    assert (
        "textured.ngc: the controller's JERK_PLAN = path cannot run this program: a spline "
        "piece strays from its chord by more than the band (P6)" in p.stderr
    ), p.stderr
    assert f"at {where.group(1)}; nothing was sent" in p.stderr, (p.stderr, where.group(1))
    s = status(shm)
    assert s["state"] == "idle" and s["blocks_consumed"] == 0, s
    assert all(v == 0.0 for v in s["position"].values()), s
    good = tmp_path / "good.ngc"
    good.write_text(textured(98, 300))
    assert feed(shm, good).returncode == 0
    s = status(shm)
    assert s["state"] == "idle" and s["reason"] == "program end", s
    end = record_rows(sim_trace_file(cfg, good, tmp_path / "good.csv"))[-1][1:3]
    assert [s["position"]["X"], s["position"]["Y"]] == end, (s, end)
    assert rt.poll() is None


def sim_trace_file(cfg, program, trace):
    sim_trace(cfg, program, trace)
    return trace


def test_path_plan_needs_smooth(tmp_path):
    p = subprocess.run(
        [
            tool("mlip-rt"),
            "--config",
            machine(tmp_path),
            "--can",
            "none",
            "--shm",
            "/mlip-rtplan-refused",
        ],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert p.returncode == 2 and "JERK_PLAN = path needs --strategy smooth" in p.stderr, p.stderr


def moving(controller, tmp_path, body, speed):
    """mlip-rt on the path machine (--record) running body, once its speed
    is above `speed`: (config, program, record, mlip-rt, feeder, mlip-ctl)."""
    cfg = machine(tmp_path)
    prog = tmp_path / "line.ngc"
    prog.write_text(body)
    rec = tmp_path / "rt.csv"
    shm, rt = controller(cfg, "--strategy", "smooth", "--record", rec)
    f = subprocess.Popen(
        [tool("mlip-feed"), "--shm", shm, "-q", str(prog)], stderr=subprocess.PIPE, text=True
    )
    assert wait_for(lambda: (status(shm) or {}).get("speed_mm_s", 0) > speed, 60), status(shm)
    return cfg, prog, rec, shm, rt, f


def ending(cfg, prog, rec, rt, f):
    """The feeder done, mlip-rt stopped; its record ends at the origin,
    within A, J and the path (mlip-check with the machine's MAX_JERK)."""
    assert f.wait(120) == 0, f.stderr.read()
    rt.send_signal(signal.SIGTERM)
    assert rt.wait(10) == 0
    assert record_rows(rec)[-1][1:3] == [0.0, 0.0]
    record_checked(cfg, prog, rec)


def ctl(shm, *a):
    return subprocess.run([tool("mlip-ctl"), "--shm", shm, *a], capture_output=True, text=True)


def hold(shm):
    """mlip-ctl hold: the status once held at rest."""
    assert ctl(shm, "hold").returncode == 0
    held = wait_for(
        lambda: (lambda s: s if s["state"] == "held" and s["speed_mm_s"] == 0.0 else None)(
            status(shm)
        ),
        60,
    )
    assert held, status(shm)
    return held


def test_hold_mid_move(controller, tmp_path):
    """A hold at speed: the queue's braking run to rest, the point held for
    300 periods, resumed to the end; the record within every limit, J
    included (mlip-check with the machine's MAX_JERK)."""
    cfg, prog, rec, shm, rt, f = moving(
        controller, tmp_path, "G21 G90\nG1 F6000\nG1 X300\nG1 X300 Y300\nG1 X0 Y0\n", 50
    )
    held = hold(shm)
    later = periods_on(shm, 300)
    assert later and later["position"] == held["position"], later
    assert ctl(shm, "resume").returncode == 0
    ending(cfg, prog, rec, rt, f)


def test_hold_after_a_tight_curve_brakes_hard(controller, tmp_path):
    """A hold on a straight line after a tight circle (r 1 mm, where only
    the gentler braking policies certify the plan's states) brakes at the
    hardest policy's 0.9 A (tools/lib/simpath.c): each state keeps the
    hardest policy whose run certifies it. Before, a state tried its
    predecessor's policy first and the straight kept the circle's gentle
    one: a hold at 90 mm/s braked at 0.1-0.3 A, metres of travel at a real
    feed. Asserted on the record's falling tail into the hold's rest: the
    path's deceleration (chord speed) within [0.85 A, A (1 + 1e-6)], A and
    J of every axis within (1 + 1e-6); mlip-check on the whole record."""
    cfg, prog, rec, shm, rt, f = moving(
        controller,
        tmp_path,
        "G21 G90\nG1 F6000\nG2 X0 Y0 I1 J0\nG1 X300\nG1 X0\n",
        60,
    )
    s = status(shm)
    assert s["position"]["X"] > 2.0, s  # past the circle (its x is 0..2 mm)
    held = hold(shm)
    assert 2.0 < held["position"]["X"] < 300.0, held
    assert ctl(shm, "resume").returncode == 0
    ending(cfg, prog, rec, rt, f)
    rows, T, A = record_rows(rec), 0.001, 1000.0
    v = [math.dist(a[1:], b[1:]) / T for a, b in zip(rows, rows[1:], strict=False)]
    # the hold's rest: the first still period at the held point
    hx = held["position"]["X"]
    e = next(k for k in range(1, len(v)) if v[k] == 0.0 and abs(rows[k][1] - hx) < 1e-3)
    b = e
    while b > 0 and v[b - 1] > v[b]:
        b -= 1
    assert v[b] > 50.0, (b, v[b])  # braked from speed
    dec = max((p - q) / T for p, q in zip(v[b:e], v[b + 1 : e + 1], strict=False))
    assert 0.85 * A <= dec <= A * (1 + 1e-6), dec


def test_stop_then_next_program(controller, tmp_path):
    """mlip-ctl stop mid-move: the queue's braking run to rest (the feeder
    told, 4), the rest of the program dropped by the planning thread; the
    next program then runs from where the machine stands to its end."""
    cfg = machine(tmp_path)
    prog = tmp_path / "line.ngc"
    prog.write_text("G21 G90\nG1 F6000\nG1 X300\nG1 X300 Y300\nG1 X0 Y0\n")
    shm, rt = controller(cfg, "--strategy", "smooth")
    f = subprocess.Popen(
        [tool("mlip-feed"), "--shm", shm, "-q", str(prog)], stderr=subprocess.PIPE, text=True
    )
    assert wait_for(lambda: (status(shm) or {}).get("speed_mm_s", 0) > 50, 60), status(shm)
    assert subprocess.run([tool("mlip-ctl"), "--shm", shm, "stop"]).returncode == 0
    assert f.wait(60) == 4, f.stderr.read()
    s = status(shm)
    assert s["state"] == "idle" and s["speed_mm_s"] == 0.0, s
    assert 0.0 < s["position"]["X"] < 300.0, s  # stopped short of the first corner
    sq = tmp_path / "square.ngc"
    sq.write_text(SQUARE)
    p = feed(shm, sq)
    assert p.returncode == 0, p.stderr
    s = status(shm)
    assert s["state"] == "idle" and s["position"]["X"] == 0.0 and s["position"]["Y"] == 0.0, s


def throttled(controller, tmp_path, steps):
    """mlip-rt on the path machine and a feeder sending `steps` 1 mm moves
    at 100 records/s (no END for steps/100 s: the thread's FIFO neither
    full nor ended), once it is sending: (segment, feeder)."""
    prog = tmp_path / "steps.ngc"
    prog.write_text(
        "G21 G90\nG1 F600\n" + "".join(f"G1 X{k} Y{k % 2}\n" for k in range(1, steps + 1))
    )
    shm, _ = controller(machine(tmp_path), "--strategy", "smooth")
    f = subprocess.Popen(
        [tool("mlip-feed"), "--shm", shm, "-q", "--rate", "100", str(prog)],
        stderr=subprocess.PIPE,
        text=True,
    )
    # sending (its area carries its pid from its first record on)
    assert wait_for(lambda: (status(shm) or {}).get("feeder_pid") == f.pid, 30), status(shm)
    return shm, f


def test_stop_before_the_queue_starts(controller, tmp_path):
    """A stop while the thread still fills the queue (a feeder throttled to
    100 records/s: no END, no full queue for ~1 s): the program never
    starts (stop before the start), nothing moves, the feeder told (4)."""
    shm, f = throttled(controller, tmp_path, 100)
    assert subprocess.run([tool("mlip-ctl"), "--shm", shm, "stop"]).returncode == 0
    assert f.wait(60) == 4, f.stderr.read()
    s = status(shm)
    assert s["state"] == "idle" and s["reason"] == "stop before the start", s
    assert all(v == 0.0 for v in s["position"].values()), s


def test_feeder_killed_before_its_end(controller, tmp_path):
    """The feeder killed before it sent its END (throttled to 100 records/s):
    the planning thread ends the plan at rest on the last point sent
    (idle, program end); the next program then runs to its end."""
    shm, f = throttled(controller, tmp_path, 1000)
    assert periods_on(shm, 300)  # some records sent (at most 1000 by 10 s)
    f.kill()
    f.wait(10)
    s = wait_for(
        lambda: (lambda s: s if s["state"] == "idle" and s["reason"] == "program end" else None)(
            status(shm)
        ),
        60,
    )
    assert s, status(shm)
    assert 0.0 < s["position"]["X"] < 1000.0 and s["speed_mm_s"] == 0.0, s
    sq = tmp_path / "square.ngc"
    sq.write_text(SQUARE)
    p = feed(shm, sq)
    assert p.returncode == 0, p.stderr


def test_override_on_the_plan(controller, tmp_path):
    """Override 50 % mid-move: the plan's cap halved (99.5 mm/s, 0.995 F,
    to 49.75), the speed then stays within it and reaches it; 100 % again:
    above it; the program ends; the record within A, J and the path."""
    cfg, prog, rec, shm, rt, f = moving(
        controller, tmp_path, "G21 G90\nG1 F6000\nG1 X600\nG1 X0\n", 90
    )
    assert ctl(shm, "override", "50").returncode == 0
    cap = 0.5 * 0.995 * 100.0
    assert wait_for(lambda: status(shm)["speed_mm_s"] <= cap * (1 + 1e-9), 10), status(shm)
    seen = []
    end = status(shm)["heartbeat"] + 500  # the controller's periods, still on the first line
    while (s := status(shm))["heartbeat"] < end:
        seen.append(s["speed_mm_s"])
    assert max(seen) <= cap * (1 + 1e-9) and max(seen) >= 0.999 * cap, (min(seen), max(seen))
    assert ctl(shm, "override", "100").returncode == 0
    assert wait_for(lambda: status(shm)["speed_mm_s"] > 1.2 * cap, 10), status(shm)
    ending(cfg, prog, rec, rt, f)


def write_records(shm, xs):
    """A program written into a fresh ring directly (mlip-feed never sends
    a NaN): a MOVE to each X of xs at 10 mm/s, then END."""
    recs = [
        (k + 1, k + 3, 0, 0, x, 0.0, 0.0, 0.0, 0.0, 0.0, 10.0, 0.01, 0.0) for k, x in enumerate(xs)
    ]
    recs.append((len(xs) + 1, len(xs) + 3, 1, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    with open("/dev/shm" + shm, "r+b") as fd:
        mem = mmap.mmap(fd.fileno(), 0)
        mask = struct.unpack_from("<I", mem, 16)[0]
        for r in recs:
            struct.pack_into("<QIHH6d3d", mem, 1472 + 88 * ((r[0] - 1) & mask), *r)
        struct.pack_into("<I", mem, 64, len(recs))  # head, after the records (x86: in order)
        mem.close()


def test_refused_plan_is_a_fault(controller, tmp_path):
    """Records the plan's controller faults on (a NaN target, written
    into the ring directly: mlip-feed never sends one): the planning thread
    refuses the program, the controller goes to FAULT (path plan refused),
    nothing moves, mlip-rt names the reason."""
    shm, rt = controller(machine(tmp_path), "--strategy", "smooth")
    write_records(shm, [1.0, math.nan])
    s = wait_for(lambda: (lambda s: s if s["state"] == "fault" else None)(status(shm)), 30)
    assert s and s["reason"] == "path plan refused", status(shm)
    assert all(v == 0.0 for v in s["position"].values()), s
    rt.send_signal(signal.SIGTERM)
    _, err = rt.communicate(timeout=10)
    assert "the plan refused the program" in err and "faulted" in err, err


def test_late_feeder_is_not_gone(controller, tmp_path):
    """A feeder that stops beating for a while before its END (SIGSTOP for
    300 periods: a loaded host's scheduling, not an exit) is late, not
    gone: the plan waits for its records (nothing moves meanwhile, no END
    made up at the last record sent), and the program runs to its END once
    the feeder beats again (it exits 0, the machine at rest on the last
    step's point)."""
    shm, f = throttled(controller, tmp_path, 400)  # 4 s of records
    assert periods_on(shm, 100)
    with frozen(f):
        assert periods_on(shm, 300)  # 300 ms late: 3x the peers' timeout
        s = status(shm)
        assert s["state"] == "idle" and s["speed_mm_s"] == 0.0, s
        assert all(v == 0.0 for v in s["position"].values()), s
    assert f.wait(120) == 0, f.stderr.read()
    s = status(shm)
    assert s["state"] == "idle" and s["reason"] == "program end", s
    assert s["position"]["X"] == 400.0 and s["position"]["Y"] == 0.0, s


def test_stall_rests_where_the_drives_stood(controller, tmp_path):
    """mlip-rt stopped at speed on the plan (SIGSTOP for 1 s, --stall-periods
    200): the drives stood at the last setpoint meanwhile. The record after
    the gap repeats it (before: the queue's run went on from the plan's
    state, a step of v T from rest), held (stall) for 300 periods, then
    mlip-ctl resume moves on from rest there (the first step within A T^2)
    to the program's end; mlip-check on the whole record, J included, the
    gap a hole. A stall hold this host adds by itself before it is resumed."""
    cfg = machine(tmp_path)
    prog = tmp_path / "line.ngc"
    prog.write_text("G21 G90\nG1 F6000\nG1 X300\nG1 X300 Y300\nG1 X0 Y0\n")
    rec = tmp_path / "rt.csv"
    shm, rt = controller(cfg, "--strategy", "smooth", "--record", rec, "--stall-periods", "200")
    f = subprocess.Popen(
        [tool("mlip-feed"), "--shm", shm, "-q", str(prog)], stderr=subprocess.PIPE, text=True
    )

    def resumed():
        s = status(shm)
        if s["state"] == "held" and s["reason"] == "stall":
            ctl(shm, "resume")
        return s

    def stalled():
        s = status(shm)
        return s if s["state"] == "held" and s["reason"] == "stall" else None

    held = None
    for _ in range(3):
        assert wait_for(
            lambda: (lambda s: s["state"] == "running" and s["speed_mm_s"] > 50)(resumed()), 60
        ), status(shm)
        with frozen(rt):
            time.sleep(1.0)  # the stall itself: 1000 periods the loop does not run
        held = wait_for(stalled, 60)
        assert held, status(shm)
        if held["reason_value"] >= 900:
            break  # this SIGSTOP's (not a stall of the host's just before it)
        assert ctl(shm, "resume").returncode == 0
    assert held["reason_value"] >= 900 and held["speed_mm_s"] == 0.0, held
    later = periods_on(shm, 300)
    assert later and later["state"] == "held" and later["position"] == held["position"], later
    assert ctl(shm, "resume").returncode == 0
    ending(cfg, prog, rec, rt, f)
    rows, T, A = record_rows(rec), 0.001, 1000.0
    gap, k = max(
        (rows[i][0] - rows[i - 1][0], i)
        for i in range(2, len(rows))
        if rows[i - 1][1:] != rows[i - 2][1:]
    )
    assert gap > 0.8, gap
    assert rows[k][1:] == rows[k - 1][1:] and rows[k + 1][1:] == rows[k][1:], rows[k - 2 : k + 2]
    j = next(i for i in range(k, len(rows)) if rows[i][1:] != rows[k][1:])
    step = max(abs(a - b) for a, b in zip(rows[j][1:], rows[j - 1][1:], strict=True))
    assert j - k >= 300 and step <= A * T * T, (j - k, step)


def test_hold_in_the_queues_last_periods(controller, tmp_path):
    """A hold within the queue's last MLIP_PLANQ_LEN periods (the plan has
    queued the program's last setpoint): the braking run to rest, and the
    resume plans the rest from there (the thread still takes the queue's
    request) to the program's end. At 5 mm/s the last 1 mm is 200 periods;
    a hold sent later than that (a slow host) is tried again with the next
    run of the program, 5 tries."""
    cfg = machine(tmp_path)
    prog = tmp_path / "back.ngc"
    prog.write_text("G21 G90\nG1 F300\nG1 X10\nG1 X0\n")
    for k in range(5):
        rec = tmp_path / f"rt{k}.csv"
        shm, rt = controller(cfg, "--strategy", "smooth", "--record", rec)
        f = subprocess.Popen(
            [tool("mlip-feed"), "--shm", shm, "-q", str(prog)], stderr=subprocess.PIPE, text=True
        )
        assert wait_for(lambda: status(shm)["position"]["X"] > 9.0, 60), status(shm)
        assert wait_for(lambda: status(shm)["position"]["X"] < 1.0, 60), status(shm)
        assert ctl(shm, "hold").returncode == 0
        s = wait_for(
            lambda: (
                lambda s: s if s["state"] in ("held", "idle") and s["speed_mm_s"] == 0.0 else None
            )(status(shm)),
            60,
        )
        assert s, status(shm)
        if s["state"] == "idle":  # the hold came after the end: again
            assert f.wait(60) == 0, f.stderr.read()
            rt.send_signal(signal.SIGTERM)
            assert rt.wait(10) == 0
            continue
        assert 0.0 < s["position"]["X"] < 1.0, s
        assert periods_on(shm, 100)["position"] == s["position"]
        assert ctl(shm, "resume").returncode == 0
        ending(cfg, prog, rec, rt, f)
        return
    raise AssertionError("no hold within the program's last 1 mm in 5 tries")


POLY_N, POLY_R = 72, 50.0  # sides, radius (mm): line k + 2 the side ending at k sides' angle
POLY_SIDE = 2 * math.pi / POLY_N


def polygon(tmp_path):
    """A polygon through the origin (centre X POLY_R), then a last line of
    1 s at F6000 (100 mm/s) to X-100."""
    r, side = POLY_R, POLY_SIDE
    body = (
        "G21 G90\nG1 F6000\n"
        + "".join(
            f"G1 X{r - r * math.cos(k * side):.4f} Y{r * math.sin(k * side):.4f}\n"
            for k in range(1, POLY_N + 1)
        )
        + "G1 X-100 Y0\n"
    )
    prog = tmp_path / "polygon.ngc"
    prog.write_text(body)
    return prog


def angle(s):
    """The position's angle on the polygon's circle (0 .. 2 pi)."""
    x, y = s["position"]["X"], s["position"]["Y"]
    return math.atan2(y, POLY_R - x) % (2 * math.pi)


def on_its_side(line, a):
    """The angle a on line's side, within a fifth of a side either way
    (the smoothing's corner blends, the attribution's one period)."""
    lo, hi = (line - 3) * POLY_SIDE, (line - 2) * POLY_SIDE
    return lo - 0.2 * POLY_SIDE <= a <= hi + 0.2 * POLY_SIDE


def test_progress_follows_the_program(controller, tmp_path):
    """The status names the block the queue's state lies in (its record
    and source line), as with the controller's own planner: a hold in the
    middle of a polygon (72 sides of 5 degrees, line k + 2 the side ending
    at 5k degrees) reports the line whose side the held position lies on
    (within a fifth of a side either way: the smoothing's corner blends
    and the attribution's one period), mlip-feed says it (held, its
    progress line), the resumed program goes on through every later block
    without going back, the last one (100 %) runs, and the END is the
    status's exec_seq as before."""
    n = POLY_N
    prog = polygon(tmp_path)  # its last line of 1 s: 100 % seen while it runs
    shm, _ = controller(machine(tmp_path), "--strategy", "smooth")
    log = (tmp_path / "feed.err").open("w")
    f = subprocess.Popen([tool("mlip-feed"), "--shm", shm, str(prog)], stderr=log, text=True)
    seen = []

    def running(pred):
        """The status while running (each one's block kept) once pred."""
        s = status(shm) or {}
        if s.get("state") == "running":
            seen.append(s["exec_seq"])
            return s if pred(s) else None
        return None

    assert wait_for(lambda: running(lambda s: angle(s) > 0.8 * math.pi), 60), status(shm)
    held = hold(shm)
    line = held["exec_line"]
    assert 20 < line < n + 2, held  # in the middle of the program
    assert on_its_side(line, angle(held)), (line, math.degrees(angle(held)))
    total = held["total_blocks"] - 1  # the records (smoothed pieces), END excluded
    assert 0 < held["exec_seq"] < total, held
    assert periods_on(shm, 3000)  # a progress line of mlip-feed's (every 2 s) while held
    assert ctl(shm, "resume").returncode == 0
    last = wait_for(lambda: running(lambda s: s["exec_seq"] == total), 60)
    assert last and last["exec_line"] == n + 3, last  # the last block, 100 %
    assert f.wait(120) == 0
    log.close()
    err = (tmp_path / "feed.err").read_text()
    assert f"held (feed hold) at line {line}:" in err, err
    pct = [
        (int(m[0]), int(m[1]), int(m[2]))
        for m in re.findall(r"(\d+)/\d+ blocks executed \((\d+) %\), \d+ queued, line (\d+)", err)
    ]
    assert any(p[0] == held["exec_seq"] and 0 < p[1] < 100 and p[2] == line for p in pct), err
    assert [p[0] for p in pct] == sorted(p[0] for p in pct), pct
    assert seen == sorted(seen) and len(set(seen)) > 20, seen[:50]
    end = status(shm)
    assert end["state"] == "idle" and end["exec_seq"] == total + 1, end


def test_stop_names_the_block_to_resume(controller, tmp_path):
    """mlip-feed interrupted mid-program (SIGTERM: a stop on the path): at
    rest it names the block to resume from, whose line's side the machine
    rests on (so continuing there skips no motion) and which the status's
    last completed block precedes; --start-seq with any other block is
    refused, with that one the program runs from there to its end."""
    prog = polygon(tmp_path)
    shm, _ = controller(machine(tmp_path), "--strategy", "smooth")
    f = subprocess.Popen(
        [tool("mlip-feed"), "--shm", shm, "-q", str(prog)], stderr=subprocess.PIPE, text=True
    )
    assert wait_for(
        lambda: (lambda s: s and s["state"] == "running" and angle(s) > 0.8 * math.pi)(status(shm)),
        60,
    ), status(shm)
    f.send_signal(signal.SIGTERM)
    err = f.communicate(timeout=60)[1]
    assert f.returncode == 143, err
    m = re.search(
        r"stopped on the path at line (\d+) \(block (\d+) of (\d+)\); "
        r"resume with --start-seq (\d+)",
        err,
    )
    assert m, err
    line, block, n, hint = (int(g) for g in m.groups())
    s = status(shm)
    assert s["state"] == "idle" and s["speed_mm_s"] == 0.0, s
    assert hint == block == s["exec_seq"] + 1 and 1 < block < n, (err, s)
    assert 20 < line < POLY_N + 2 and on_its_side(line, angle(s)), (line, math.degrees(angle(s)))
    for wrong in (block - 1, block + 1):
        p = subprocess.run(
            [tool("mlip-feed"), "--shm", shm, "-q", "--start-seq", str(wrong), str(prog)],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert p.returncode == 1 and f"only --start-seq {block} continues it" in p.stderr, p.stderr
    p = subprocess.run(
        [tool("mlip-feed"), "--shm", shm, "-q", "--start-seq", str(block), str(prog)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 0, p.stderr
    e = status(shm)
    assert e["state"] == "idle" and e["exec_seq"] == n + 1, e
    assert e["position"]["X"] == -100.0 and e["position"]["Y"] == 0.0, e


@pytest.mark.parametrize("k", range(8))
def test_continue_from_a_rest_in_a_corner(controller, tmp_path, k):
    """mlip-feed stopped (SIGTERM) at 8 points around the polygon's vertex 30
    (the stop, 5.5 mm at 0.9 A, asked from 142.0 to 144.0 degrees), then
    continued with the block it names: each runs to the program's end.
    A rest inside the corner's second half (0.37 mm past the vertex, where
    smooth's blend ends) named the corner's own block, and the
    continuation went back to the vertex: the plan refused that reversal
    ((P6), a fault; 4 of 20 such stops). Now the plan's knots count a
    corner's block done once nearer to the next segment
    (mlip_planner_resume_done, the rule of a stall's rest)."""
    prog = polygon(tmp_path)
    shm, _ = controller(machine(tmp_path), "--strategy", "smooth")
    f = subprocess.Popen(
        [tool("mlip-feed"), "--shm", shm, "-q", str(prog)], stderr=subprocess.PIPE, text=True
    )
    th = 2.478 + k * 0.005  # radians: 142.0 .. 144.0 degrees
    assert wait_for(
        lambda: (lambda s: s and s["state"] == "running" and angle(s) > th)(status(shm)), 60
    ), status(shm)
    f.send_signal(signal.SIGTERM)
    err = f.communicate(timeout=60)[1]
    m = re.search(r"resume with --start-seq (\d+)", err)
    assert f.returncode == 143 and m, err
    p = subprocess.run(
        [tool("mlip-feed"), "--shm", shm, "-q", "--start-seq", m[1], str(prog)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 0, p.stderr
    e = status(shm)
    assert e["position"]["X"] == -100.0 and e["position"]["Y"] == 0.0, e


def test_refused_plan_then_restart_runs_the_next(controller, tmp_path):
    """A refused plan is a fault on the path, as a bad record is: left the
    way every such fault is, by restarting mlip-rt (or a reset after an
    E-stop: test_ctl_follow, test_rtplan; a reset alone leaves a quick stop
    only, and is refused here), as mlip-ctl status says; a program sent
    meanwhile never moves. mlip-rt restarted on the same segment: the next
    program plans and runs to its end from where the machine stands, within
    A, J and the path; the refused program's records after its bad one (a
    move to X 50) never run."""
    cfg = machine(tmp_path)
    shm, rt = controller(cfg, "--strategy", "smooth")
    write_records(shm, [1.0, math.nan, 50.0])
    s = wait_for(lambda: (lambda s: s if s["state"] == "fault" else None)(status(shm)), 30)
    assert s and s["reason"] == "path plan refused", status(shm)
    r = ctl(shm, "reset")
    assert r.returncode != 0, r.stdout
    st = ctl(shm, "status")
    assert "to continue restart mlip-rt (the fault stays until then)" in st.stdout, st.stdout
    sq = tmp_path / "square.ngc"
    sq.write_text(SQUARE)
    p = feed(shm, sq, timeout=60)
    assert p.returncode != 0, p.stderr
    s = status(shm)
    assert s["state"] == "fault" and all(v == 0.0 for v in s["position"].values()), s
    rt.send_signal(signal.SIGTERM)
    _, err = rt.communicate(timeout=10)
    assert "the plan refused the program" in err, err
    rec = tmp_path / "rt.csv"
    rt2 = Proc(
        [
            tool("mlip-rt"),
            "--config",
            cfg,
            "--can",
            "none",
            "--shm",
            shm,
            "--stall-periods",
            "100000",
            "--strategy",
            "smooth",
            "--record",
            rec,
        ],
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        s = wait_for(lambda: (lambda s: s if s and s["alive"] else None)(status(shm)), 60)
        assert s and s["state"] == "idle", (s, rt2.said())
        p = feed(shm, sq)
        assert p.returncode == 0, p.stderr
        s = status(shm)
        assert s["state"] == "idle" and s["reason"] == "program end", s
        assert s["position"]["X"] == 0.0 and s["position"]["Y"] == 0.0, s
        assert rt2.poll() is None, rt2.said()
    finally:
        assert terminate(rt2) == 0, rt2.said()
    rows = record_rows(rec)
    # the square's corners blended within the path tolerance (0.01 mm)
    assert len(rows) > 100 and max(r[1] for r in rows) <= 20.0 + 0.01, max(r[1] for r in rows)
    record_checked(cfg, sq, rec)


def test_corrupt_ring_on_the_plan_is_a_fault(controller, tmp_path):
    """The ring's indices made more than a capacity apart while a program
    runs on the plan (the planning thread owns the ring: its check, not the
    period's): the thread refuses the program ("the ring is corrupt"), the
    controller ends in FAULT at rest after the queue's braking run, never
    further: the record stays on the program's first line, within A, J and
    the path (mlip-check, a stop allowed); the feeder is told."""
    cfg, prog, rec, shm, rt, f = moving(
        controller, tmp_path, "G21 G90\nG1 F6000\nG1 X300\nG1 X300 Y300\nG1 X0 Y0\n", 50
    )
    ring = Ring(shm)
    # the whole program taken (3 moves, END): nothing more will be written
    assert wait_for(lambda: ring.u32(HEAD) == 4 and ring.count() == 0, 30), ring.u32(HEAD)
    s0 = status(shm)
    assert s0["state"] == "running" and s0["position"]["X"] < 250.0, s0
    struct.pack_into("<I", ring.mem, HEAD, ring.u32(TAIL) + 2 * ring.cap)
    s = wait_for(
        lambda: (lambda s: s if s["state"] == "fault" and s["speed_mm_s"] == 0.0 else None)(
            status(shm)
        ),
        30,
    )
    assert s and s["reason"] == "path plan refused", status(shm)
    assert s0["position"]["X"] < s["position"]["X"] < 300.0 and s["position"]["Y"] == 0.0, s
    later = periods_on(shm, 300)
    assert later and later["state"] == "fault" and later["position"] == s["position"], later
    assert f.wait(60) != 0
    rt.send_signal(signal.SIGTERM)
    _, err = rt.communicate(timeout=10)
    assert "the plan refused the program" in err and "the ring is corrupt" in err, err
    record_checked(cfg, prog, rec)
