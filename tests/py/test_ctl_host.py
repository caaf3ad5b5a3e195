"""The pure controller on this host (mlip-rt --can none): the setpoints
mlip-rt computed (--record, written by its monitor thread) equal mlip-sim's
trace for the same program, count for count; a stall (SIGSTOP/SIGCONT) holds
at the last setpoint with no jump and goes on only on resume; a corrupt
record in the ring is a fault named by record, field and value, and the
feeder reports failure, never "complete"."""
import json
import math
import os
import signal
import subprocess
import time

import pytest

from conftest import (CONFIG, HEAD, ROOT, TAIL, TOOLPATHS, Proc, Ring, frozen, periods_on,
                      record_checked, record_rows, status, tool, wait_for)

DEMO = ROOT / "examples" / "demo.ngc"
MILL = CONFIG / "mill-3axis.ini"
PAPER = CONFIG / "paper-2axis.ini"


def ctl(shm, *args):
    return subprocess.run([tool("mlip-ctl"), "--shm", shm, *args], capture_output=True, text=True)


def sim_trace(config, program, path, *opts):
    p = subprocess.run([tool("mlip-sim"), "-q", "--config", config, "--trace", path, *opts,
                        program], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    return path.read_text().splitlines()


def flower(tmp_path, lines=6000):
    prog = tmp_path / "flower.ngc"
    prog.write_text("".join((TOOLPATHS / "flower-spiral-2d.ngc").read_text()
                            .splitlines(True)[:lines]))
    return prog


def stop(rt):
    rt.send_signal(signal.SIGTERM)
    _, err = rt.communicate(timeout=20)
    assert rt.returncode == 0, err
    return err


def same_rows(a, b):
    """Setpoints equal to the last digit, count for count; t may differ where
    this non-real-time host missed deadlines (holes in mlip-rt's record)."""
    assert len(a) == len(b), f"{len(a)} rows from mlip-rt, {len(b)} from mlip-sim"
    for i, (x, y) in enumerate(zip(a, b)):
        assert x.split(",", 1)[1] == y.split(",", 1)[1], f"row {i}: mlip-rt {x} != mlip-sim {y}"


@pytest.mark.parametrize("case", ["demo", "flower"])
def test_record_equals_sim(controller, tmp_path, case):
    """demo: END within the look-ahead, the pre-read ends on END; flower: 6000
    blocks, the pre-read fills the look-ahead (4096), then 16 a period."""
    config, prog = (MILL, DEMO) if case == "demo" else (PAPER, flower(tmp_path))
    rec = tmp_path / "rt.csv"
    shm, rt = controller(config, "--record", rec)
    p = subprocess.run([tool("mlip-feed"), "--shm", shm, "--quiet", prog], capture_output=True,
                       text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    stop(rt)
    rows = rec.read_text().splitlines()
    same_rows(rows, sim_trace(config, prog, tmp_path / "sim.csv"))
    assert len(rows) > 1000


def test_stall_holds_at_rest_without_jump(controller, tmp_path):
    """SIGSTOP for 0.5 s at speed: after SIGCONT the setpoints stay at the last
    one sent (state held, reason stall) until resume, and the whole recorded
    motion passes mlip-check (acceleration, speed, contour): no jump."""
    prog = flower(tmp_path)
    rec = tmp_path / "rt.csv"
    # a stall is more than 100 missed periods: the SIGSTOP's 500 are. This
    # non-real-time VM misses tens of periods by itself under load, now and
    # then more: a stall hold it adds is resumed, as an operator would
    shm, rt = controller(PAPER, "--stall-periods", "100", "--record", rec)
    f = Proc([tool("mlip-feed"), "--shm", shm, prog], stderr=subprocess.PIPE, text=True)

    def resumed():
        st = status(shm) or {}
        if st.get("state") == "held" and st.get("reason") == "stall":
            assert ctl(shm, "resume").returncode == 0
        return st

    def held():
        st = status(shm) or {}
        return st if st.get("state") == "held" else None

    for _ in range(3):
        assert wait_for(lambda: (lambda st: st.get("state") == "running" and
                                 st["exec_seq"] > 1500 and st["speed_mm_s"] > 50)(resumed()),
                        60), f"not running at speed: {status(shm)}\n{rt.said()}"
        with frozen(rt):  # every thread stopped: 500 periods the loop does not run
            time.sleep(0.5)
        s = wait_for(held, 60)
        assert s and s["reason"] == "stall", f"{s}\n{rt.said()}"
        if s["reason_value"] >= 499:
            break  # this SIGSTOP's stall (at least 499 deadlines passed in it)
        # the VM's own stall held it just before the SIGSTOP: again
        assert ctl(shm, "resume").returncode == 0
    else:
        pytest.fail(f"no stall of the SIGSTOP's size in 3 tries: {s}\n{rt.said()}")
    assert s["speed_mm_s"] == 0.0
    # 300 periods on (the loop's count, not the host's clock): nothing moves
    later = periods_on(shm, 300)
    assert later and later["state"] == "held" and later["position"] == s["position"], later
    text = ctl(shm, "status").stdout
    assert "stall" in text and "to continue mlip-ctl resume" in text
    # resume (again after any stall this non-real-time VM adds by itself)
    assert wait_for(lambda: resumed() and f.poll() is not None, 120), \
        f"the feeder did not finish: {status(shm)}\n{f.said()}"
    _, ferr = f.communicate(timeout=60)
    assert f.returncode == 0, ferr
    assert "stall: the controller missed" in ferr and "mlip-ctl resume" in ferr
    err = stop(rt)
    assert "stall: the loop missed" in err and "mlip-ctl resume" in err, err
    chk = subprocess.run([tool("mlip-check"), "--config", PAPER, prog, rec], capture_output=True,
                         text=True)
    assert chk.returncode == 0, chk.stdout + chk.stderr
    # the record has a hole where the deadlines were missed (the drives got
    # nothing): after it the setpoints start from rest, not at speed. The
    # SIGSTOP's hole is the one that ends held where the status said
    rows = [list(map(float, r.split(","))) for r in rec.read_text().splitlines()[1:]]
    T = 0.001
    at = [s["position"][a] for a in ("X", "Y")]
    gaps = [(rows[i][0] - rows[i - 1][0], i) for i in range(1, len(rows))
            if math.dist(rows[i - 1][1:], at) < 1e-9]
    gap, i = max(gaps, default=(0.0, 0))
    assert gap > 0.4, (gap, at)  # the 0.5 s SIGSTOP
    before = math.dist(rows[i - 1][1:], rows[i - 2][1:]) / T
    assert before > 50.0, before  # it was moving when stopped
    assert rows[i][1:] == rows[i - 1][1:] and rows[i + 1][1:] == rows[i][1:]  # held there
    k = next(j for j in range(i, len(rows)) if rows[j][1:] != rows[i][1:])  # resumed
    v = math.dist(rows[k][1:], rows[k - 1][1:]) / T
    assert v <= 1000.0 * T * (1 + 1e-9), v  # from rest: one period of A = 1000 at most


# ---- records the controller did not expect --------------------------------

def zigzag(tmp_path, rows=40, per_row=300):
    """0.1 mm segments at 200 mm/s, a turn every 30 mm: many blocks quickly."""
    lines = ["G21 G90 F12000"]
    for r in range(rows):
        for i in range(1, per_row + 1):
            x = i * 0.1 if r % 2 == 0 else (per_row - i) * 0.1
            lines.append(f"G1 X{x:.3f} Y{r * 0.5:.3f}")
        lines.append(f"G1 Y{(r + 1) * 0.5:.3f}")
    prog = tmp_path / "zigzag.ngc"
    prog.write_text("\n".join(lines) + "\n")
    return prog


def test_corrupt_record_is_a_fault_never_complete(controller, tmp_path):
    """A local user writes a NaN target into a record already queued, once
    the motion has begun: the controller takes nothing from it on and stops
    at rest exactly at the end of the last good block (the look-ahead plans
    its newest block to rest), says fault with the record, field and value;
    the feeder exits 5 and never says complete. mlip-rt is frozen while the
    record is written 1000 records ahead of what it took (it takes at most
    16 a period while moving), so it meets the record after the write
    whatever the host's load."""
    prog = zigzag(tmp_path)
    rec_csv = tmp_path / "rt.csv"
    shm, rt = controller(MILL, "--record", rec_csv)
    f = Proc([tool("mlip-feed"), "--shm", shm, prog], stderr=subprocess.PIPE,
             text=True)
    ring = Ring(shm)
    assert wait_for(lambda: (lambda s: s["state"] == "running" and s["exec_seq"] > 0)(
        status(shm)), 60), status(shm)
    with frozen(rt):
        index = ring.u32(TAIL) + 1000
        assert wait_for(lambda: ring.u32(HEAD) > index, 30)  # the feeder runs on
        rec = ring.read(index)
        seq, line = rec[0], rec[1]
        assert rec[2] == 0  # a MOVE record
        good = ring.read(index - 1)[4:7]  # where the last good block ends: X Y Z
        rec[4] = float("nan")  # target X
        ring.write(index, rec)
    _, ferr = f.communicate(timeout=120)
    assert f.returncode == 5, ferr
    assert f"bad record {seq} (line {line}): target[0] = nan" in ferr, ferr
    assert "NOT complete" in ferr and "program complete" not in ferr
    s = wait_for(lambda: (lambda s: s if s["speed_mm_s"] == 0.0 and s["state"] == "fault"
                          and s["exec_seq"] == seq - 1 else None)(status(shm)), 30)
    assert s, status(shm)
    assert [s["position"][a] for a in "XYZ"] == good, (s, good)  # exactly its end
    assert s["reason"] == "bad record"
    assert s["reason_seq"] == seq and s["reason_line"] == line
    assert s["reason_field"] == "target X" and s["reason_value"] is None  # NaN
    assert ctl(shm, "resume").returncode == 1  # a fault is not resumed
    st = ctl(shm, "status")
    assert st.returncode == 1 and "in fault (bad record)" in st.stderr  # failure, not done
    assert f"record {seq} (line {line}), target X = nan" in st.stdout
    err = stop(rt)
    assert (f"fault: bad record {seq} (line {line}): target X = nan; nothing after it is "
            f"taken, the machine stops at rest at the end of block {seq - 1};") in err, err
    # the setpoints sent: along the path (mlip-check, a stop allowed), the
    # last one the end of block seq - 1, nothing after it
    rows = record_rows(rec_csv)
    assert rows[-1][1:] == good and rows[-2][1:] == good
    record_checked(MILL, prog, rec_csv)


def test_corrupt_record_in_the_preread_never_moves(controller, tmp_path):
    """Issue 17: a bad record met while the controller still pre-reads (the
    motion's first periods; seen under make sanitize's slow build) stopped
    the machine on the path inside the first block: the planner's stop
    followed the plan in force, which accelerates from rest. Now a program
    refused before its first motion period never moves: every setpoint
    mlip-rt sent is where the machine stood. Record 4000 is made bad while
    mlip-rt is frozen before its pre-read reached it; the pre-read takes the
    look-ahead's 4096 blocks before anything moves. The feeder sends 1000
    blocks/s (the pre-read waits for them): mlip-rt is frozen seconds before
    its pre-read could reach record 4000, however late this host freezes it."""
    prog = zigzag(tmp_path)
    rec_csv = tmp_path / "rt.csv"
    shm, rt = controller(MILL, "--record", rec_csv)
    home = status(shm)["position"]
    f = Proc([tool("mlip-feed"), "--shm", shm, "--rate", "1000", prog],
             stderr=subprocess.PIPE, text=True)
    ring = Ring(shm)
    assert wait_for(lambda: ring.u32(HEAD) > 0 or f.poll() is not None, 60, 0.001)
    with frozen(rt):
        assert ring.u32(TAIL) < 4000 - 16, ring.u32(TAIL)  # not reached (and not moved)
        assert wait_for(lambda: ring.u32(HEAD) >= 4000, 30)  # the feeder runs on
        rec = ring.read(3999)
        assert rec[0] == 4000 and rec[2] == 0, rec  # seq 4000 (a fresh ring), a MOVE
        line = rec[1]
        rec[4] = float("nan")
        ring.write(3999, rec)
    _, ferr = f.communicate(timeout=120)
    assert f.returncode == 5, ferr
    assert f"bad record 4000 (line {line}): target[0] = nan" in ferr, ferr
    s = wait_for(lambda: (lambda s: s if s["state"] == "fault" else None)(status(shm)), 30)
    assert s and s["reason"] == "bad record" and s["reason_seq"] == 4000, s
    assert s["exec_seq"] == 0 and s["position"] == home and s["speed_mm_s"] == 0.0, s
    err = stop(rt)
    assert ("fault: bad record 4000 (line %d): target X = nan; nothing after it is taken, the "
            "machine stays at rest where the program started (nothing of it moved)" % line) \
        in err, err
    # mlip-rt's record begins when the controller leaves the pre-read (here
    # for the fault): every setpoint where the machine stood
    rows = record_rows(rec_csv)
    assert rows and all(r[1:] == [home[a] for a in "XYZ"] for r in rows), rows


def test_bad_record_met_in_a_dwell_names_where_the_machine_rests(controller, tmp_path):
    """Issue 17 item 8, the dwell case: a dwell record out of range (here
    written into the ring, as the reader now refuses G4 P100000) is met in
    the pre-read of a dwell: nothing after the dwell starts, the recorded
    setpoints stay at the end of block 1, and mlip-rt's log says block 1 (it
    said "stops at rest at the end of block 3", the block before the bad
    record, which never ran)."""
    prog = tmp_path / "dwells.ngc"
    prog.write_text("G21 G90 G1 X200 F6000\nG4 P0.5\nG1 X250\nG4 P1\nG1 X300\nM2\n")
    rec_csv = tmp_path / "rt.csv"
    shm, rt = controller(MILL, "--record", rec_csv)
    f = Proc([tool("mlip-feed"), "--shm", shm, prog], stderr=subprocess.PIPE,
             text=True)
    ring = Ring(shm)
    # the whole program in the ring while block 1 (2 s) still runs
    assert wait_for(lambda: ring.u32(HEAD) >= 6, 30)
    s = status(shm)
    assert s["state"] in ("preread", "running") and s["exec_seq"] <= 1, s
    rec = ring.read(3)
    assert rec[0] == 4 and rec[2] == 2  # seq 4, a DWELL record (G4 P1; mlip_rec_type)
    rec[-1] = 100000.0  # its dwell, s
    ring.write(3, rec)
    _, ferr = f.communicate(timeout=60)
    assert f.returncode == 5, ferr
    s = wait_for(lambda: (lambda s: s if s["state"] == "fault" else None)(status(shm)), 30)
    assert s and s["reason"] == "bad record" and s["reason_seq"] == 4, s
    assert s["exec_seq"] == 1 and s["position"]["X"] == 200.0, s
    err = stop(rt)
    assert ("fault: bad record 4 (line 4): dwell/value = 100000; nothing after it is taken, the "
            "machine stays at rest at the end of block 1;") in err, err
    rows = [list(map(float, r.split(",")[1:])) for r in rec_csv.read_text().splitlines()[1:]]
    assert rows[-1] == [200.0, 0.0, 0.0] and max(r[0] for r in rows) == 200.0


def test_status_json_position_and_reason(controller, tmp_path):
    shm, _ = controller(MILL)
    s = status(shm)
    assert s["state"] == "idle" and s["reason"] == "none"
    assert set(s["position"]) == {"X", "Y", "Z"} and s["speed_mm_s"] == 0.0
    assert s["optional_stop"] is False
    assert ctl(shm, "optional-stop", "on").returncode == 0
    assert status(shm)["optional_stop"] is True
    assert ctl(shm, "optional-stop", "maybe").returncode == 2
    prog = zigzag(tmp_path, rows=4)
    f = Proc([tool("mlip-feed"), "--shm", shm, "--quiet", prog])
    moving = wait_for(lambda: (lambda s: s if s["speed_mm_s"] > 100 else None)(status(shm)), 60)
    assert moving and moving["state"] == "running"
    assert 0.0 <= moving["position"]["X"] <= 30.0 and moving["speed_mm_s"] <= 200.0 * (1 + 1e-9)
    assert f.wait(60) == 0
    s = status(shm)
    assert s["state"] == "idle" and s["reason"] == "program end"
    assert math.isclose(s["position"]["Y"], 2.0, abs_tol=1e-12)


# ---- program events through mlip-sim (the controller's own) --------------

EVENTS = "G21 G90\nG1 X10 F6000\nG4 P0.25\nG1 X20\nM0\nG1 X30\nM1\nG1 X40\nM2\n"


def rests(rows):
    """{x: periods at rest there} for every point the trace stands still at."""
    out, run = {}, 0
    for prev, cur in zip(rows, rows[1:]):
        if cur == prev:
            run += 1
        elif run:
            out[float(prev.split(",")[0])] = run
            run = 0
    return out


@pytest.mark.parametrize("optional", [False, True])
def test_sim_dwell_and_pauses_to_the_period(tmp_path, optional):
    """G4 P0.25: 250 periods at rest at X10; M0 with --resume-after 0.5: 500
    at X20; M1: 500 at X30 only with --optional-stop, else not even a stop."""
    prog = tmp_path / "events.ngc"
    prog.write_text(EVENTS)
    trace = tmp_path / "t.csv"
    opts = ["--resume-after", "0.5"] + (["--optional-stop"] if optional else [])
    p = subprocess.run([tool("mlip-sim"), "-q", "--config", MILL, "--trace", trace,
                        "--summary", "-", *opts, prog], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    s = json.loads(p.stdout)
    assert s["dwells"] == 1 and s["pauses"] == (2 if optional else 1)
    rows = [",".join(r.split(",")[1:]) for r in trace.read_text().splitlines()[1:]]
    r = rests(rows)
    assert r.get(10.0) == 250 and r.get(20.0) == 500, r
    assert r.get(30.0) == (500 if optional else None), r
    chk = subprocess.run([tool("mlip-check"), "--config", MILL, prog, trace], capture_output=True,
                         text=True)
    assert chk.returncode == 0, chk.stdout + chk.stderr


def test_status_liveness_alive_late_dead(controller):
    """mlip-ctl judges the controller by the one rule (mlip/ipc/peer.h): alive
    while it beats; stopped (SIGSTOP), its process is there: late, exit 1,
    "not responding"; killed: dead, "not running"."""
    shm, rt = controller(MILL)
    s = status(shm)
    assert s["alive"] is True and s["liveness"] == "alive"
    with frozen(rt):  # late once the beat is older than MLIP_PEER_TIMEOUT_NS (100 ms)
        def late():
            p = ctl(shm, "status", "--json")
            return (p, json.loads(p.stdout)) if '"liveness": "late"' in p.stdout else None
        got = wait_for(late, 60)
        assert got, ctl(shm, "status", "--json").stdout
        p, s = got
        assert p.returncode == 1 and s["alive"] is False, p.stdout
        assert s["heartbeat_age_ms"] >= 100.0, s
        p = ctl(shm, "status")
        assert p.returncode == 1 and "NOT RESPONDING" in p.stdout
        assert f"its process (pid {rt.pid}) is there: stopped or starved of CPU" in p.stderr
    assert wait_for(lambda: (status(shm) or {}).get("liveness") == "alive", 60)
    rt.kill()
    rt.wait(10)
    try:
        def dead():
            p = ctl(shm, "status", "--json")
            return p if '"liveness": "dead"' in p.stdout else None
        p = wait_for(dead, 60)
        assert p, ctl(shm, "status", "--json").stdout
        s = json.loads(p.stdout)
        assert p.returncode == 1 and s["alive"] is False and s["liveness"] == "dead", p.stdout
        assert "is not running: start mlip-rt" in ctl(shm, "status").stderr
    finally:
        try:
            os.unlink("/dev/shm" + shm)  # a killed controller leaves its segment
        except FileNotFoundError:
            pass


def test_hold_latched_at_rest_is_said(controller, tmp_path):
    """A hold at rest stays latched (Grbl 1.1's Hold:0 from Idle): mlip-ctl
    status says so (`idle (hold latched: resume to start)`, JSON hold_latched
    and held_by) instead of a bare idle; a jog is refused, naming it; a
    program sent then waits held, unmoved, and mlip-feed says why instead of
    seeming stuck; resume starts it. A resume at rest clears the latch
    moving nothing; so does a stop."""
    prog = tmp_path / "p.ngc"
    prog.write_text("G21 G90 G94\nG1 X5 F600\nM2\n")
    shm, rt = controller(PAPER)
    latched = "a hold at rest while idle (hold): latched, the next program starts held until " \
        "mlip-ctl resume"

    def logged(text, n):
        """mlip-rt's monitor (a status sampled every 50 ms) logged text n times."""
        return wait_for(lambda: rt.said().count(text) >= n, 60), rt.said()
    assert wait_for(lambda: (status(shm) or {}).get("state") == "idle", 60)
    st = status(shm)
    assert st["hold_latched"] is False and st["held_by"] is None, st
    assert ctl(shm, "hold").returncode == 0
    st = wait_for(lambda: (lambda s: s if s["hold_latched"] else None)(status(shm)), 60)
    assert st and st["state"] == "idle" and st["held_by"] == "hold", status(shm)
    text = ctl(shm, "status").stdout
    assert ": idle (hold latched: resume to start), alive" in text, text
    assert "to continue mlip-ctl resume (or cycle start)" in text, text
    assert logged(latched, 1)
    j = ctl(shm, "jog", "X+", "600", "0.2")
    assert j.returncode != 0 and "a hold latched" in j.stderr, j.stderr
    # resumed at rest: cleared, nothing moved
    x0 = st["position"]
    assert ctl(shm, "resume").returncode == 0
    st = wait_for(lambda: (lambda s: s if not s["hold_latched"] else None)(status(shm)), 60)
    assert st and st["state"] == "idle" and st["held_by"] is None, status(shm)
    assert st["position"] == x0, st
    assert logged("the hold latched at rest ended", 1)
    # latched again, then a stop at rest: cleared too
    assert ctl(shm, "hold").returncode == 0
    assert wait_for(lambda: status(shm)["hold_latched"], 60), status(shm)
    assert logged(latched, 2)
    assert ctl(shm, "stop").returncode == 0
    assert wait_for(lambda: not status(shm)["hold_latched"], 60), status(shm)
    assert logged("the hold latched at rest ended", 2)
    # latched, then a program: held before its first move, and said so
    assert ctl(shm, "hold").returncode == 0
    assert wait_for(lambda: status(shm)["hold_latched"], 60), status(shm)
    f = Proc([tool("mlip-feed"), "--shm", shm, prog], stderr=subprocess.PIPE, text=True)
    held = wait_for(lambda: (lambda s: s if s["state"] == "held" else None)(status(shm)), 60)
    assert held and held["reason"] == "hold" and held["held_by"] == "hold", status(shm)
    assert held["hold_latched"] is False, held  # held: the state says it now
    assert wait_for(lambda: "held before its first move" in f.said(), 60), f.said()
    later = periods_on(shm, 200)
    assert later and later["state"] == "held" and later["position"] == x0, later
    assert f.poll() is None  # waiting, not failed
    assert ctl(shm, "resume").returncode == 0
    _, ferr = f.communicate(timeout=60)
    assert f.returncode == 0, ferr
    assert "a hold was latched while the machine was idle" in ferr and "resume" in ferr, ferr
    st = status(shm)
    assert st["state"] == "idle" and st["position"]["X"] == 5.0, st
    err = stop(rt)
    assert "held (hold): at rest in block 1 (line 2); mlip-ctl resume continues" in err, err


def test_override_zero_is_said(controller, tmp_path):
    """Feed override 0 holds the path, and every reader says what ends it: a
    higher override, not a resume. At rest mlip-ctl status says `idle (feed
    override 0 %: raise the override to start)` (JSON held_by "override 0",
    hold_latched false: no resume is awaited); a program sent then waits
    held, unmoved, mlip-feed and mlip-ctl saying to raise the override; a
    resume changes nothing; override 100 runs it to its end."""
    prog = tmp_path / "p.ngc"
    prog.write_text("G21 G90 G94\nG1 X5 F600\nM2\n")
    shm, rt = controller(PAPER)
    assert wait_for(lambda: (status(shm) or {}).get("state") == "idle", 60)
    assert ctl(shm, "override", "0").returncode == 0
    st = wait_for(lambda: (lambda s: s if s["held_by"] else None)(status(shm)), 60)
    assert st and st["state"] == "idle" and st["held_by"] == "override 0", status(shm)
    assert st["hold_latched"] is False, st
    text = ctl(shm, "status").stdout
    assert ": idle (feed override 0 %: raise the override to start), alive" in text, text
    assert ("to continue raise the feed override (mlip-ctl override PCT, 1..200); it is 0 %: "
            "resume does not end it\n") in text, text
    assert "hold latched" not in text, text
    x0 = st["position"]
    f = Proc([tool("mlip-feed"), "--shm", shm, prog], stderr=subprocess.PIPE, text=True)
    held = wait_for(lambda: (lambda s: s if s["state"] == "held" else None)(status(shm)), 60)
    assert held and held["reason"] == "override 0" and held["held_by"] == "override 0", held
    assert wait_for(lambda: "the feed override is 0 %: raise it to continue" in f.said(), 60), \
        f.said()
    text = ctl(shm, "status").stdout
    assert ": held, alive" in text and "to continue raise the feed override" in text, text
    assert ctl(shm, "resume").returncode == 0
    later = periods_on(shm, 200)
    assert later and later["state"] == "held" and later["position"] == x0, later
    assert f.poll() is None  # waiting, not failed
    assert ctl(shm, "override", "100").returncode == 0
    _, ferr = f.communicate(timeout=60)
    assert f.returncode == 0, ferr
    st = status(shm)
    assert st["state"] == "idle" and st["held_by"] is None and st["position"]["X"] == 5.0, st
