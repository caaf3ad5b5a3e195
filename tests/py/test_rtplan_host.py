"""mlip-rt with [TRAJ] JERK_PLAN = path on this host (--can none): its
planning thread (tools/rtplan.c) takes the ring's records, the period
follows the planned queue; mlip-feed smooths on the plan's controller's
machine and refuses what the plan cannot run, as mlip-sim does."""

import math
import mmap
import re
import signal
import struct
import subprocess

from conftest import (
    HEAD,
    TAIL,
    TOOLPATHS,
    Proc,
    Ring,
    periods_on,
    record_checked,
    record_rows,
    status,
    terminate,
    tool,
    wait_for,
)
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
    for k, prog in enumerate(progs):
        rec = tmp_path / f"rt{k}.csv"
        shm, rt = controller(cfg, "--strategy", "smooth", "--record", rec)
        p = feed(shm, prog)
        assert p.returncode == 0, p.stderr
        s = status(shm)
        assert s["state"] == "idle" and s["exec_seq"] == s["blocks_consumed"] > 1, s
        p = feed(shm, progs[0])  # the thread starts afresh for the next program
        assert p.returncode == 0, p.stderr
        rt.send_signal(signal.SIGTERM)
        _, err = rt.communicate(timeout=10)
        assert rt.returncode == 0, err
        sim = sim_trace(cfg, prog, tmp_path / f"sim{k}.csv")
        assert len(sim.splitlines()) > 1000
        # the positions to the byte, row by row (t: the record's counts the
        # deadlines, with a hole where this non-real-time host missed one)
        got, want = positions(rec.read_text()), positions(sim)
        assert len(got) == len(want) and got == want, (len(got), len(want))


def test_feed_refuses_what_the_plan_cannot_run(controller, tmp_path):
    """A G0 and a second F: refused by mlip-feed at their lines, as mlip-sim
    refuses them, before anything is sent."""
    cfg = machine(tmp_path)
    shm, _ = controller(cfg, "--strategy", "smooth")
    for body, line in (
        ("G21 G90\nG1 F600 X1\nG0 X5\n", 3),
        ("G21 G90\nG1 F600 X1\nG1 F900 X2\n", 3),
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


def test_hold_mid_move(controller, tmp_path):
    """A hold at speed: the queue's braking run to rest, the point held for
    300 periods, resumed to the end; the record within every limit, J
    included (mlip-check with the machine's MAX_JERK)."""
    cfg, prog, rec, shm, rt, f = moving(
        controller, tmp_path, "G21 G90\nG1 F6000\nG1 X300\nG1 X300 Y300\nG1 X0 Y0\n", 50
    )
    assert ctl(shm, "hold").returncode == 0
    held = wait_for(
        lambda: (lambda s: s if s["state"] == "held" and s["speed_mm_s"] == 0.0 else None)(
            status(shm)
        ),
        60,
    )
    assert held, status(shm)
    later = periods_on(shm, 300)
    assert later and later["position"] == held["position"], later
    assert ctl(shm, "resume").returncode == 0
    ending(cfg, prog, rec, rt, f)


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
    recs = [(k + 1, k + 3, 0, 0, x, 0.0, 0.0, 0.0, 0.0, 0.0, 10.0, 0.01, 0.0)
            for k, x in enumerate(xs)]
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
    rt2 = Proc([tool("mlip-rt"), "--config", cfg, "--can", "none", "--shm", shm,
                "--stall-periods", "100000", "--strategy", "smooth", "--record", rec],
               stderr=subprocess.PIPE, text=True)
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
