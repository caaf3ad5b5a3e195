"""The controller's processes on this host, without a CAN bus (--can none):
a real SCHED_FIFO mlip-rt, a real shared-memory segment, the real mlip-feed
and mlip-ctl. The CAN side is tested on a real vcan0 in tests/can."""
import json
import math
import re
import signal
import subprocess

from conftest import (CONFIG, ROOT, TOOLPATHS, Proc, longest_rest, periods_on, program_end,
                      record_checked, record_rows, shm_name, status, tool, wait_for)

DEMO = ROOT / "examples" / "demo.ngc"
def feed(shm, program, *extra, **kw):
    return subprocess.run([tool("mlip-feed"), "--shm", shm, *extra, str(program)],
                          capture_output=True, text=True, **kw)


def assert_sim_periods(rows, periods, log):
    """A record of one program (mlip-rt --record: the start at t = 0, then a
    row a period) against the simulator's periods: as many, unless the
    controller starved (a feeder that did not keep ahead on a loaded host: a
    stop and a restart on the path), which only adds periods."""
    first = log.split("(program end)")[0]
    if "-> starved" in first:
        assert len(rows) > periods + 1, (len(rows), periods)
    else:
        assert len(rows) == periods + 1, (len(rows), periods)


def test_program_runs_to_completion(controller, tmp_path):
    rec = tmp_path / "rt.csv"
    shm, rt = controller(CONFIG / "mill-3axis.ini", "--record", rec)
    hb0 = status(shm)["heartbeat"]
    p = feed(shm, DEMO, timeout=60)
    assert p.returncode == 0, p.stderr
    assert "program complete" in p.stderr
    s = status(shm)
    assert s["state"] == "idle" and s["exec_seq"] == 1820 and s["blocks_consumed"] == 1820
    sim = json.loads(subprocess.run([tool("mlip-sim"), "-q", "--config", CONFIG / "mill-3axis.ini",
                                     "--summary", "-", DEMO], capture_output=True, text=True).stdout)
    # the controller runs the simulated motion, counted in its own periods
    # (not the wall clock, which a loaded host stretches): its loop ran at
    # least the program's periods meanwhile
    assert s["heartbeat"] - hb0 >= sim["periods"], (s["heartbeat"] - hb0, sim["periods"])
    # a second program on the same controller starts where the first ended
    # (X40 Y0 Z5 after the demo's last G0 Z5), not at HOME: its first block
    # G0 Z5 moves nothing and is merged away, 1819 records
    end1 = [status(shm)["position"][a] for a in "XYZ"]
    assert [status(shm)["program_start"][a] for a in "XYZ"] == [0.0, 0.0, 0.0]  # HOME
    p = feed(shm, DEMO, timeout=60)
    assert p.returncode == 0, p.stderr
    assert "checked from where the machine stands: X%.4f Y%.4f Z%.4f" % tuple(end1) in p.stderr
    assert status(shm)["blocks_consumed"] == 1820 + 1819
    # an axis a G90 move leaves out stays where it stands: Y here
    assert [status(shm)["program_start"][a] for a in "XYZ"] == end1
    end2 = [status(shm)["position"][a] for a in "XYZ"]
    prog = tmp_path / "z.ngc"
    prog.write_text("G21 G90\nG0 Z10\nG1 X5 F600\nM30\n")
    assert feed(shm, prog, timeout=60).returncode == 0
    end3 = [status(shm)["position"][a] for a in "XYZ"]
    assert abs(end3[0] - 5) < 1e-9 and abs(end3[1] - end2[1]) < 1e-9 and abs(end3[2] - 10) < 1e-9
    rt.send_signal(signal.SIGTERM)
    _, err = rt.communicate(timeout=10)
    assert rt.returncode == 0
    assert "stopped after" in err and "3642 records taken" in err
    # the first program's setpoints (--record): within the machine's limits,
    # and the simulator's motion to the period
    record_checked(CONFIG / "mill-3axis.ini", DEMO, rec)
    assert_sim_periods(record_rows(rec), sim["periods"], err)


def test_smooth_program_runs_to_completion(controller, tmp_path):
    """mlip-rt --strategy smooth publishes it in the machine area; mlip-feed
    then sends the smoothed path and the controller runs it in the
    simulator's periods (its record of the setpoints)."""
    rec = tmp_path / "rt.csv"
    shm, rt = controller(CONFIG / "mill-3axis.ini", "--strategy", "smooth", "--record", rec)
    sim = {st: json.loads(subprocess.run(
        [tool("mlip-sim"), "-q", "--config", CONFIG / "mill-3axis.ini", "--strategy", st,
         "--summary", "-", DEMO], capture_output=True, text=True).stdout) for st in ("smooth",)}
    hb0 = status(shm)["heartbeat"]
    p = feed(shm, DEMO, timeout=60)
    assert p.returncode == 0, p.stderr
    s = status(shm)
    assert s["state"] == "idle" and s["exec_seq"] == s["blocks_consumed"]
    # in the controller's own periods, not the wall clock's
    assert s["heartbeat"] - hb0 >= sim["smooth"]["periods"]
    assert sim["smooth"]["max_contour_error_mm"] <= 0.01 * (1 + 1e-9)
    rt.send_signal(signal.SIGTERM)
    _, err = rt.communicate(timeout=10)
    assert rt.returncode == 0, err
    assert_sim_periods(record_rows(rec), sim["smooth"]["periods"], err)


def test_bad_program_sends_nothing(controller, tmp_path):
    shm, _ = controller()
    bad = tmp_path / "bad.ngc"
    bad.write_text("G1 X1 F600\nG1 X1.2.3\nG41\nG1 X5000\n")
    p = feed(shm, bad)
    assert p.returncode == 1
    errors = [l for l in p.stderr.splitlines() if ": error: " in l]
    assert [e.split(":")[1] for e in errors] == ["2", "3", "4"]
    assert status(shm)["blocks_consumed"] == 0  # a rejected program never starts moving


def flower_fed(controller, tmp_path):
    """mlip-rt (paper-2axis, --record) fed 6000 blocks of the flower spiral:
    (program, config, record, segment, mlip-rt, mlip-feed)."""
    prog = tmp_path / "flower.ngc"
    prog.write_text("".join((TOOLPATHS / "flower-spiral-2d.ngc").read_text().splitlines(True)[:6000]))
    cfg = CONFIG / "paper-2axis.ini"
    rec = tmp_path / "rt.csv"
    shm, rt = controller(cfg, "--record", rec)
    f = Proc([tool("mlip-feed"), "--shm", shm, "--quiet", str(prog)],
             stderr=subprocess.PIPE, text=True)
    return prog, cfg, rec, shm, rt, f


def test_override_hold_resume_stop(controller, tmp_path):
    """Override, hold, resume and stop, judged by the setpoints the
    controller sent (--record): at rest at the held point while held, and
    after the stop at rest short of the program's end, every limit kept
    along the way (mlip-check)."""
    prog, cfg, rec, shm, rt, f = flower_fed(controller, tmp_path)
    assert wait_for(lambda: (status(shm) or {}).get("exec_seq", 0) > 50)
    ctl = lambda *a: subprocess.run([tool("mlip-ctl"), "--shm", shm, *a], capture_output=True,
                                    text=True)
    r = ctl("override", "50")
    assert r.returncode == 0 and "done" in r.stdout + r.stderr
    assert status(shm)["override_pct"] == 50
    assert ctl("override", "250").returncode != 0  # beyond 0..200
    assert ctl("hold").returncode == 0
    held = wait_for(lambda: (lambda s: s if s["state"] == "held" and s["speed_mm_s"] == 0.0
                             else None)(status(shm)), 60)
    assert held, status(shm)
    later = periods_on(shm, 300)
    assert later and later["position"] == held["position"], later  # nothing moves while held
    assert ctl("resume").returncode == 0
    assert wait_for(lambda: status(shm)["position"] != held["position"], 60)
    assert ctl("stop").returncode == 0
    f.wait(10)
    assert f.returncode == 4, f.said()
    assert wait_for(lambda: status(shm)["state"] == "idle", 60)
    rt.send_signal(signal.SIGTERM)
    assert rt.wait(10) == 0
    rows = record_rows(rec)
    # the hold: the setpoints stood at the held point for the 300 periods at least
    # (t counts the periods that ran; the hold was in the middle of the run)
    still, where = longest_rest(rows[:-1])
    assert still >= 0.25 and where == [held["position"][a] for a in "XY"], (still, where)
    # the stop: at rest (the last step at most one period of braking from
    # rest, A T^2), short of the program's end, every limit kept
    T, A = 0.001, 1000.0  # paper-2axis.ini
    assert math.dist(rows[-1][1:], rows[-2][1:]) <= A * T * T * (1 + 1e-9), rows[-2:]
    end = program_end(cfg, prog, tmp_path)
    assert math.dist(rows[-1][1:], end) > 1.0, (rows[-1], end)
    record_checked(cfg, prog, rec)


def test_second_controller_refused(controller):
    shm, _ = controller()
    p = subprocess.run([tool("mlip-rt"), "--config", CONFIG / "mill-3axis.ini", "--can", "none",
                        "--shm", shm], capture_output=True, text=True, timeout=10)
    assert p.returncode == 1 and "stop that mlip-rt first" in p.stderr


def test_bus_load_budget_refused(tmp_path):
    cfg = tmp_path / "slow.ini"
    text = (CONFIG / "mill-3axis.ini").read_text()
    # 3 axes, cia402, 1 ms at 125 kbit/s: 340 bits = 2.7 ms per 1 ms period
    cfg.write_text(re.sub(r"(?m)^BITRATE\s*=.*$", "BITRATE = 125000", text, count=1))
    p = subprocess.run([tool("mlip-rt"), "--config", cfg, "--can", "vcan0", "--shm", shm_name()],
                       capture_output=True, text=True, timeout=10)
    assert p.returncode == 1
    assert "bus load 272.0 %" in p.stderr and "refusing" in p.stderr


def test_sigterm_is_a_controlled_stop(controller, tmp_path):
    """SIGTERM mid-program: mlip-rt brakes on the path and exits 0, judged by
    the setpoints it sent (--record): moving, then a deceleration to rest
    short of the program's end within every limit (mlip-check), no drop."""
    prog, cfg, rec, shm, rt, f = flower_fed(controller, tmp_path)
    assert wait_for(lambda: (status(shm) or {}).get("speed_mm_s", 0) > 10)
    rt.send_signal(signal.SIGTERM)
    _, err = rt.communicate(timeout=10)
    assert rt.returncode == 0, err  # stopped on the path, then exit 0
    f.wait(10)
    assert f.returncode != 0  # the feeder is told: its program did not finish
    rows = record_rows(rec)
    T, A = 0.001, 1000.0  # paper-2axis.ini
    # at rest: the last step is at most one period of braking from rest
    assert math.dist(rows[-1][1:], rows[-2][1:]) <= A * T * T * (1 + 1e-9), rows[-2:]
    assert math.dist(rows[-1][1:], program_end(cfg, prog, tmp_path)) > 1.0
    tail = rows[-2000:]
    speeds = [math.dist(p[1:], q[1:]) / T for p, q in zip(tail, tail[1:])]
    assert max(speeds) > 10.0  # it was moving when the signal came
    record_checked(cfg, prog, rec)


def test_ctl_commands_from_stdin(controller):
    """mlip-ctl -: one process, a command per line, each answered in turn;
    a refused one is reported and the rest still applied (exit 1); a line
    that is no command ends it (exit 2)."""
    shm, _ = controller()
    p = subprocess.run([tool("mlip-ctl"), "--shm", shm, "-"], capture_output=True, text=True,
                       input="override 40\n# a comment\n\nhold\nresume\noverride 120\n", timeout=20)
    assert p.returncode == 0, p.stderr
    assert p.stdout.splitlines() == ["override 40 %: done", "hold: done", "resume: done",
                                     "override 120 %: done"]
    assert status(shm)["override_pct"] == 120
    p = subprocess.run([tool("mlip-ctl"), "--shm", shm, "-"], capture_output=True, text=True,
                       input="override 70\noverride 300\n", timeout=20)
    assert p.returncode == 2 and "stdin:2: expected one of" in p.stderr, p.stderr
    assert p.stdout.splitlines() == ["override 70 %: done"]
    assert status(shm)["override_pct"] == 70


def test_start_seq_must_continue_the_last_block(controller, tmp_path):
    """--start-seq N continues only after the last block the controller
    completed: any other N would move in a straight line from where the
    machine rests to block N's end. Refused before anything is sent."""
    prog = tmp_path / "flower.ngc"
    prog.write_text("".join((TOOLPATHS / "flower-spiral-2d.ngc").read_text().splitlines(True)[:3000]))
    shm, _ = controller(CONFIG / "paper-2axis.ini")
    # a controller that has run nothing continues nothing
    p = feed(shm, prog, "--start-seq", "100", timeout=30)
    assert p.returncode == 1 and "has run no block of a program" in p.stderr, p.stderr
    assert status(shm)["blocks_consumed"] == 0
    f = Proc([tool("mlip-feed"), "--shm", shm, "--quiet", str(prog)],
             stderr=subprocess.PIPE, text=True)
    assert wait_for(lambda: (status(shm) or {}).get("exec_seq", 0) > 300)
    f.send_signal(signal.SIGTERM)  # the controller stops on the path
    err = f.communicate(timeout=30)[1]
    assert f.returncode == 143, err
    s = wait_for(lambda: (lambda s: s if s["state"] == "idle" else None)(status(shm)), 60)
    done = s["exec_seq"]
    hint = int(err.split("resume with --start-seq ")[1].split()[0])
    assert hint == done + 1, err
    consumed = s["blocks_consumed"]
    for wrong in (done, done + 2, 1 + done // 2):
        p = feed(shm, prog, "--start-seq", str(wrong), timeout=30)
        assert p.returncode == 1, p.stderr
        assert f"completed block {done} (line {s['exec_line']}) last, so only --start-seq " \
               f"{done + 1} continues it" in p.stderr
    assert status(shm)["blocks_consumed"] == consumed  # nothing was sent
    p = feed(shm, prog, "--quiet", "--start-seq", str(hint), timeout=60)
    assert p.returncode == 0, p.stderr
    assert status(shm)["exec_seq"] == 2999 and status(shm)["state"] == "idle"


def test_smooth_start_seq_continues_the_smoothed_records(controller, tmp_path):
    """With a `smooth` controller the records are the filter's output, numbered
    1..n (each piece its own seq, with its source line): the status reports
    them, mlip-feed's resume hint names one, and --start-seq continues there
    with the same records, since the output depends on the program alone."""
    prog = tmp_path / "flower.ngc"
    prog.write_text("".join((TOOLPATHS / "flower-spiral-2d.ngc").read_text().splitlines(True)[:3000]))
    sim = json.loads(subprocess.run(
        [tool("mlip-sim"), "-q", "--config", CONFIG / "paper-2axis.ini", "--strategy", "smooth",
         "--summary", "-", prog], capture_output=True, text=True).stdout)
    n = sim["blocks_run"]
    assert n > sim["blocks"]  # pieces: more records than the program's blocks
    shm, _ = controller(CONFIG / "paper-2axis.ini", "--strategy", "smooth")
    f = Proc([tool("mlip-feed"), "--shm", shm, "--quiet", str(prog)],
             stderr=subprocess.PIPE, text=True)
    assert wait_for(lambda: (status(shm) or {}).get("exec_seq", 0) > n // 3)
    mid = status(shm)
    assert 1 <= mid["exec_line"] <= 3000 and mid["total_blocks"] <= n + 1
    f.send_signal(signal.SIGTERM)
    err = f.communicate(timeout=30)[1]
    assert f.returncode == 143, err
    s = wait_for(lambda: (lambda s: s if s["state"] == "idle" else None)(status(shm)), 60)
    done = s["exec_seq"]
    assert n // 3 < done < n
    hint = int(err.split("resume with --start-seq ")[1].split()[0])
    assert hint == done + 1, err
    assert f"of {n})" in err, err  # the records counted before sending
    consumed = s["blocks_consumed"]
    p = feed(shm, prog, "--quiet", "--start-seq", str(done + 2), timeout=30)
    assert p.returncode == 1 and f"only --start-seq {done + 1} continues it" in p.stderr, p.stderr
    p = feed(shm, prog, "--start-seq", str(hint), timeout=120)
    assert p.returncode == 0, p.stderr
    assert f"{n - hint + 1} blocks" in p.stderr, p.stderr
    e = status(shm)
    assert e["state"] == "idle" and e["exec_seq"] == n + 1
    assert e["blocks_consumed"] == consumed + n + 2 - hint  # the rest and END, once


IO_TAIL = """
[SPINDLE]
TYPE = cia402
MAX_RPM = 24000
NODE = 5
COUNTS_PER_REV = 4096
ACCELERATION = 5000

[IO]
NODE = 10
ESTOP = 10 0x6000:1 0 LOW
PROBE = 10 0x6000:1 3 HIGH

[COOLANT]
TYPE = io
MIST = 10 0x6200:1 0
FLOOD = 10 0x6200:1 1
"""


def test_bus_load_budget_spindle_and_module(tmp_path):
    """The budget counts a CiA 402 spindle (a 6-byte RPDO and TPDO every
    SYNC) and the I/O module (heartbeat, inputs, outputs every 100 ms)
    beside 3 axis drives: at 1 ms and 1 Mbit/s 98.0 % without the drives'
    touch probe (74.8 % the axes alone, + 2 x 115 bits + heartbeats) and
    150.5 % with it (TPDO2), both refused; at 4 ms 38.0 % passes the budget
    (then the bus, absent here, is the error)."""
    text = (CONFIG / "mill-3axis-drives.ini").read_text() + IO_TAIL
    for period, probe, load, refused in (("0.001", "", "98.0", True),
                                         ("0.001", "\n[PROBE]\nSOURCE = drive\n", "150.5", True),
                                         ("0.004", "\n[PROBE]\nSOURCE = drive\n", "38.0", False)):
        cfg = tmp_path / "m.ini"
        cfg.write_text(re.sub(r"(?m)^PERIOD\s*=.*$", f"PERIOD = {period}", text) + probe)
        p = subprocess.run([tool("mlip-rt"), "--config", cfg, "--can", "mlipnone9", "--drives",
                            "--shm", shm_name()], capture_output=True, text=True, timeout=10)
        assert p.returncode == 1 and f"bus load {load} %" in p.stderr, p.stderr
        assert ("refusing" in p.stderr) == refused, p.stderr
