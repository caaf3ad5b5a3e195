"""Commands cannot be lost or misread, and the status tells the truth (issue
17, items 5, 6, 10, 11), with the real mlip-rt (--can none), mlip-feed and
mlip-ctl on a real segment: a stop during the feeder's check prevents the
program; `mlip-ctl -` never splits a line; a poster that died mid-post
blocks neither stop (its own path) nor the next command; the reason follows
the state; the block and line after a stop in a dwell or a pause are the
ones before the wait; a dead controller's JSON says so in "state"."""
import mmap
import os
import signal
import struct
import subprocess

import pytest

from conftest import (CONFIG, HEAD, ROOT, TAIL, TOOLPATHS, Proc, Ring, frozen, periods_on,
                      status, tool, wait_for)

MILL = CONFIG / "mill-3axis.ini"
PAPER = CONFIG / "paper-2axis.ini"
DEMO = ROOT / "examples" / "demo.ngc"
MAILBOX = 640  # include/mlip/ipc/ring.h: the command mailbox's line


def ctl(shm, *args, **kw):
    return subprocess.run([tool("mlip-ctl"), "--shm", shm, *args], capture_output=True,
                          text=True, timeout=30, **kw)


def flower(tmp_path, lines=6000):
    prog = tmp_path / "flower.ngc"
    prog.write_text("".join((TOOLPATHS / "flower-spiral-2d.ngc").read_text()
                            .splitlines(True)[:lines]))
    return prog


def moving(controller, tmp_path):
    """The flower on the paper's machine, running."""
    shm, rt = controller(PAPER)
    f = Proc([tool("mlip-feed"), "--shm", shm, str(flower(tmp_path))],
             stderr=subprocess.PIPE, text=True)
    assert wait_for(lambda: (status(shm) or {}).get("exec_seq", 0) > 50, 30), "did not start"
    return shm, rt, f


def in_state(shm, state, timeout=60):
    return wait_for(lambda: (lambda s: s if s and s["state"] == state else None)(status(shm)),
                    timeout)


def long_program(tmp_path):
    """20000 short moves at 50 mm/s (a check of some length; 4096 blocks
    pre-read before the first motion period)."""
    prog = tmp_path / "long.ngc"
    prog.write_text("G21 G90 F3000\n" + "".join(f"G1 X{(k % 200) * 0.5:.1f} Y{k * 0.001:.3f}\n"
                                                for k in range(20000)) + "M2\n")
    return prog


def holds_a_lock(pid):
    """pid holds a POSIX record lock (mlip-feed: the ring's producer line)."""
    with open("/proc/locks") as f:
        return any(l.split()[1:5] == ["POSIX", "ADVISORY", "WRITE", str(pid)] for l in f)


# ---- item 5: a stop during the feeder's check pass --------------------------

def test_stop_during_the_check_prevents_the_program(controller, tmp_path):
    """Observed on main: the controller idle, `mlip-ctl stop` answered done
    and the program ran 1.5 s later. The feeder here is frozen while it
    checks its program (it holds the producer lock from its start on), the
    stop is given, then it runs on: the program never moves, the feeder
    says so (exit 4), mlip-ctl names it."""
    shm, rt = controller(MILL)
    prog = long_program(tmp_path)
    before = status(shm)
    f = Proc([tool("mlip-feed"), "--shm", shm, str(prog)], stderr=subprocess.PIPE,
             text=True)
    try:
        assert wait_for(lambda: holds_a_lock(f.pid) or f.poll() is not None, 30)
        f.send_signal(signal.SIGSTOP)
        c = ctl(shm, "stop")
    finally:
        f.send_signal(signal.SIGCONT)
    # the feeder ends, or the machine moves (main: the program ran)
    wait_for(lambda: f.poll() is not None or status(shm)["position"] != before["position"], 60)
    if f.poll() is None:
        f.kill()
        f.communicate()
        pytest.fail(f"the program ran after the stop: {status(shm)}")
    err = f.communicate(timeout=10)[1]
    s = status(shm)
    assert s["state"] == "idle" and s["position"] == before["position"], s  # nothing moved
    assert s["exec_seq"] == 0 and s["stops"] == 0, s
    assert f.returncode == 4, err
    assert "mlip-ctl stop came" in err and "program complete" not in err, err
    assert c.returncode == 0, c.stderr
    assert f"program of mlip-feed pid {f.pid}, begun before this stop, will not start" \
        in c.stdout, c.stdout
    # the stop was for that program only: the next one runs
    p = subprocess.run([tool("mlip-feed"), "--shm", shm, "-q", str(DEMO)], capture_output=True,
                       text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert status(shm)["exec_seq"] == 1820


def test_stop_in_the_preread_prevents_the_program(controller, tmp_path):
    """A stop that comes once the controller has begun the program's
    pre-read (its first 4096 blocks taken before the first motion period)
    but before anything moved: the program never moves (it moved 1-4 um on
    the path: the planner's stop followed the plan in force, which
    accelerates from rest), as a stop during its check. mlip-rt is frozen
    in its pre-read while mlip-ctl posts the stop (it cannot answer: exit
    1, the stop posted), then goes on: it is dropped unmoved (stop before
    the start: no stop on the path counted, the position to the last bit
    where it stood); the next program runs."""
    shm, rt = controller(MILL)
    prog = long_program(tmp_path)
    before = status(shm)
    f = Proc([tool("mlip-feed"), "--shm", shm, str(prog)], stderr=subprocess.PIPE,
             text=True)
    ring = Ring(shm)
    # the pre-read has begun (a record taken); it ends with the 4096th
    assert wait_for(lambda: ring.u32(TAIL) > 0 or f.poll() is not None, 60, 0.001)
    with frozen(rt):
        assert 0 < ring.u32(TAIL) < 4096 and ring.u32(HEAD) > 0, ring.u32(TAIL)
        c = ctl(shm, "stop")
    assert c.returncode == 1 and "posted" in c.stderr, (c.stdout, c.stderr)
    err = f.communicate(timeout=60)[1]
    assert f.returncode == 4, err
    assert "mlip-ctl stop came before the program started: the controller dropped it, " \
        "nothing moved" in err, err
    s = wait_for(lambda: (lambda s: s if s["state"] == "idle" else None)(status(shm)), 30)
    assert s and s["reason"] == "stop before the start" and s["reason_seq"] == 1, s
    assert s["position"] == before["position"] and s["exec_seq"] == 0 and s["stops"] == 0, s
    p = subprocess.run([tool("mlip-feed"), "--shm", shm, "-q", str(DEMO)], capture_output=True,
                       text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert status(shm)["exec_seq"] == 1820


def test_a_stop_older_than_the_feeder_is_stale(controller):
    """A stop given to an idle controller with no feeder is for nothing
    that follows: the next program runs."""
    shm, _ = controller(MILL)
    c = ctl(shm, "stop")
    assert c.returncode == 0 and c.stdout == "stop: done (the machine was idle)\n", c.stdout
    p = subprocess.run([tool("mlip-feed"), "--shm", shm, "-q", str(DEMO)], capture_output=True,
                       text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert status(shm)["exec_seq"] == 1820


# ---- item 6: `mlip-ctl -` reads whole lines ---------------------------------

def test_ctl_stdin_never_splits_a_long_line(controller, tmp_path):
    """Observed on main: 128-byte reads; a comment of 128 bytes ending in
    ` resume` ran `resume` and the held machine moved. Now a comment of
    any length is one line, ignored; a command line longer than 255 bytes
    is refused whole (exit 2), nothing of it applied."""
    shm, rt, f = moving(controller, tmp_path)
    assert ctl(shm, "hold").returncode == 0
    held = in_state(shm, "held")
    assert held and held["reason"] == "hold", held
    comment = "#" + "x" * 126 + " resume\n"  # main read "#x..x" then " resume"
    p = ctl(shm, "-", input=comment + "#" + "y" * 100000 + " resume\n")
    assert p.returncode == 0 and p.stdout == "" and p.stderr == "", (p.stdout, p.stderr)
    p = ctl(shm, "-", input="override 50" + " " * 300 + "resume\n")
    assert p.returncode == 2 and "stdin:1: line longer than 255 bytes: not a command" \
        in p.stderr, p.stderr
    assert p.stdout == ""
    s = periods_on(shm, 300)  # nothing may move while held: 300 periods to
    assert s["state"] == "held" and s["reason"] == "hold" and s["override_pct"] == 100, s
    assert s["position"] == held["position"] and s["exec_seq"] == held["exec_seq"]
    assert ctl(shm, "stop").returncode == 0
    assert f.wait(30) == 4


# ---- item 10: a poster that died mid-post ----------------------------------

def leave_mailbox_mid_post(shm):
    """What a mlip-ctl killed between claiming the mailbox and publishing
    its command left on main (its odd 'being written' sequence): an odd
    value in the mailbox's first word."""
    fd = os.open("/dev/shm" + shm, os.O_RDWR)
    try:
        mem = mmap.mmap(fd, 4096)
        seq = struct.unpack_from("<I", mem, MAILBOX)[0]
        struct.pack_into("<I", mem, MAILBOX, seq | 1)
        mem.close()
    finally:
        os.close(fd)


def test_a_dead_poster_blocks_neither_stop_nor_commands(controller, tmp_path):
    """Observed on main: every later `mlip-ctl stop` failed ("mailbox stayed
    busy") and the machine kept running. Now stop has its own path (a
    counter) and the mailbox takes the next command."""
    shm, rt, f = moving(controller, tmp_path)
    leave_mailbox_mid_post(shm)
    c = ctl(shm, "stop")
    assert c.returncode == 0 and c.stdout == "stop: done\n", c.stderr
    err = f.communicate(timeout=30)[1]
    assert f.returncode == 4 and "program stopped on the path at line" in err, err
    s = in_state(shm, "idle")
    assert s and s["reason"] == "stop" and s["exec_seq"] < 6000, s
    c = ctl(shm, "override", "70")
    assert c.returncode == 0 and c.stdout == "override 70 %: done\n", c.stderr
    assert status(shm)["override_pct"] == 70


def test_feeder_sigint_stops_with_a_dead_poster(controller, tmp_path):
    """Observed on main: SIGINT to mlip-feed could not post its stop and the
    machine ran on. Now the feeder's stop goes through the counter."""
    shm, rt, f = moving(controller, tmp_path)
    leave_mailbox_mid_post(shm)
    f.send_signal(signal.SIGINT)
    err = f.communicate(timeout=30)[1]
    assert f.returncode == 130, err
    assert "interrupted: machine stopped on the path at line" in err, err
    s = in_state(shm, "idle")
    assert s and s["reason"] == "stop" and s["speed_mm_s"] == 0.0, s


# ---- item 11: the status tells the truth ------------------------------------

def test_reason_follows_the_state(controller, tmp_path):
    """Observed on main: override 0, hold, override 100 left `held, why
    override 0` at 100 %. The reason is the hold then, and `resume` is
    what continues; hold, override 0, resume: held by the override."""
    shm, rt, f = moving(controller, tmp_path)
    assert ctl(shm, "override", "0").returncode == 0
    s = in_state(shm, "held")
    assert s and s["reason"] == "override 0", s
    assert ctl(shm, "hold").returncode == 0
    assert wait_for(lambda: status(shm)["reason"] == "hold", 60), status(shm)
    assert ctl(shm, "override", "100").returncode == 0
    s = periods_on(shm, 200)  # a held machine must not move on with the override
    assert s["state"] == "held" and s["reason"] == "hold" and s["override_pct"] == 100, s
    text = ctl(shm, "status").stdout
    assert "why         hold\n" in text and "to continue mlip-ctl resume" in text, text
    assert ctl(shm, "override", "0").returncode == 0
    assert ctl(shm, "resume").returncode == 0
    assert wait_for(lambda: status(shm)["reason"] == "override 0", 60), status(shm)
    assert status(shm)["state"] == "held"
    assert ctl(shm, "override", "100").returncode == 0
    s = in_state(shm, "running")
    assert s and s["reason"] == "resume", s
    assert ctl(shm, "stop").returncode == 0
    assert f.wait(30) == 4


WAIT_PROGRAM = "G21 G90 F6000\nG1 X10\nG1 X20\n{wait}\nG1 X30\nG1 X40\nM2\n"


@pytest.mark.parametrize("wait,how", [("G4 P30", "stop"), ("M0", "stop"),
                                      ("G4 P30", "SIGTERM")])
def test_stop_in_a_wait_names_the_block_before_it(controller, tmp_path, wait, how):
    """Observed on main: after a stop or SIGTERM in a dwell or an M0 the log
    and exec_line said line 0. The wait is not done: the block completed is
    the G1 X20 before it (block 2, line 3), in the status, mlip-rt's log and
    mlip-feed's resume hint (block 3, the wait, line 4)."""
    shm, rt = controller(MILL)
    prog = tmp_path / "wait.ngc"
    prog.write_text(WAIT_PROGRAM.format(wait=wait))
    f = Proc([tool("mlip-feed"), "--shm", shm, str(prog)], stderr=subprocess.PIPE,
             text=True)
    assert in_state(shm, "dwelling" if wait.startswith("G4") else "paused", 30)
    if how == "stop":
        assert ctl(shm, "stop").returncode == 0
        s = in_state(shm, "idle")
        assert s and s["exec_seq"] == 2 and s["exec_line"] == 3, s
        assert s["position"]["X"] == 20.0
        rt.send_signal(signal.SIGTERM)
    else:
        rt.send_signal(signal.SIGTERM)
    log = rt.communicate(timeout=20)[1]
    why = "stop" if how == "stop" else "exit signal"
    assert f"-> idle ({why}): at rest, block 2 (line 3) the last completed" in log, log
    err = f.communicate(timeout=20)[1]
    assert f.returncode == 4, err
    assert "stopped on the path at line 4 (block 3 of 5)" in err, err


def test_dead_controller_json_says_so_in_state(controller, tmp_path):
    """Observed on main: after mlip-rt was killed, `status --json` kept
    "state": "running" and "speed_mm_s": 50 (alive false). Now the state is
    "not running" (the last one published beside it) and the speed null."""
    shm, rt, f = moving(controller, tmp_path)
    assert wait_for(lambda: status(shm)["speed_mm_s"] > 1.0, 60)
    rt.kill()
    rt.wait(10)
    try:
        f.communicate(timeout=30)
        assert f.returncode == 3
        p = ctl(shm, "status", "--json")
        import json
        s = json.loads(p.stdout)
        assert p.returncode == 1
        assert s["state"] == "not running" and s["last_state"] == "running", s
        assert s["alive"] is False and s["speed_mm_s"] is None, s
        text = ctl(shm, "status").stdout
        assert "NOT RUNNING, last state running" in text and "speed unknown" in text, text
    finally:
        try:
            os.unlink("/dev/shm" + shm)  # a killed controller leaves its segment
        except FileNotFoundError:
            pass
