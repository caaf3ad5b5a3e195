"""Real senders against mlip-grbl and mlip-rt on this host (--can none):
bCNC (PyPI bCNC, its own Sender thread and GRBL1 controller, driven without
its window by bcnc_driver.py) through pyserial's socket:// URL: it connects,
reads the DRO, runs a shared toolpath end to end in the time mlip-feed takes
(within 1 %), jogs as its jog pad does ($J=), holds and resumes it on the
path. CNCjs (npm cncjs, its server and Grbl controller, tests/cncjs/drive.js)
through the pseudo-terminal: the same, a jog as its axes widget sends it, and
its page in headless Chromium showing mlip's position (build/cncjs-dro.png).
Both run through tests/py/senders.py, as the bus tests in the VM do
(tests/can/test_senders_vcan.py)."""
import subprocess

import pytest

from conftest import BUILD, TOOLPATHS, status, tool
from senders import bcnc, cncjs, event
from test_grbl import MILL, grbl, logged, stop_rt, trace_rows  # noqa: F401  (the fixture)


def program(tmp_path, lines=3000):
    p = tmp_path / "flower.ngc"
    p.write_text("".join((TOOLPATHS / "flower-spiral-2d.ngc").read_text()
                         .splitlines(True)[:lines]))
    return p


def feed_periods(controller, prog, tmp_path):
    """The periods of motion mlip-feed FILE takes (mlip-rt --record)."""
    rec = tmp_path / "feed.csv"
    shm, rt = controller(MILL, "--record", rec)
    logged(rt, "mlip-rt (mlip-feed)")
    f = subprocess.run([tool("mlip-feed"), "--shm", shm, "-q", str(prog)], capture_output=True,
                       text=True, timeout=600)
    assert f.returncode == 0, f.stderr
    stop_rt(rt)
    return trace_rows(rec)[1]


def dro_shows(done, shm):
    """The sender's DRO shows where mlip-rt stands."""
    c = status(shm)
    assert done["mpos"] == pytest.approx([c["position"][k] for k in "XYZ"], abs=1e-3)


def as_mlip_feed(grbl, controller, tmp_path, name, run):
    """run(port, tty, prog) -> the sender's last event: it ran the file in
    the periods of motion mlip-feed FILE takes, within 1 %."""
    prog = program(tmp_path)
    ta = feed_periods(controller, prog, tmp_path)
    rec = tmp_path / f"{name}.csv"
    shm, rt, srv, port, tty = grbl(MILL, "--record", rec)
    dro_shows(run(port, tty, prog), shm)
    stop_rt(rt)
    _, tb = trace_rows(rec)
    print(f"{name}: {tb} periods of motion, mlip-feed {ta}")
    assert abs(ta - tb) <= 0.01 * ta, (ta, tb)


def test_bcnc_runs_a_file_as_mlip_feed(grbl, controller, tmp_path):
    def run(port, tty, prog):
        ev = bcnc(port, prog, tmp_path)
        first = ev[0]
        assert first["event"] == "connected" and first["state"] == "Idle", first
        assert first["mpos"] == [0.0, 0.0, 0.0]
        assert not [e for e in ev if e["event"] in ("error", "timeout")], ev
        done = ev[-1]
        assert done["event"] == "done" and done["state"] == "Idle", done
        return done

    as_mlip_feed(grbl, controller, tmp_path, "bCNC", run)


def test_bcnc_hold_resume(grbl, tmp_path):
    prog = program(tmp_path, 3000)
    shm, rt, srv, port, _ = grbl(MILL)
    ev = bcnc(port, prog, tmp_path, "--hold-after", "500", "--jog", "X2Y1")
    jog = next(e for e in ev if e["event"] == "jogged")
    assert jog["state"] == "Idle" and jog["mpos"] == [2, 1, 0], jog   # $J=G91 X2Y1 F100000
    assert not [e for e in ev if e["event"] == "error"], ev
    held = [e for e in ev if e["event"] == "held"]
    assert held, ev
    h = held[0]
    assert h["before"]["state"] == "Hold:0" and h["after"]["state"] == "Hold:0"
    assert h["before"]["mpos"] == h["after"]["mpos"]          # at rest on the path
    assert h["before"]["mpos"] != [0.0, 0.0, 0.0]
    done = ev[-1]
    assert done["event"] == "done" and done["state"] == "Idle", done
    dro_shows(done, shm)




# ---- CNCjs (npm cncjs, tests/cncjs): its server opens mlip-grbl's pseudo-terminal as a
# Grbl serial port; driven through its socket.io API as its page does, and its page in
# headless Chromium for the screenshot (build/cncjs-dro.png)


def test_cncjs_runs_a_file_as_mlip_feed(grbl, controller, tmp_path):
    """Its file runner, nothing else."""
    def run(port, tty, prog):
        done = event(cncjs(tty, prog, tmp_path), "done")
        assert done["state"] == "Idle" and done["errors"] == 0 and done["total"] == 3001, done
        return done

    as_mlip_feed(grbl, controller, tmp_path, "CNCjs", run)


def test_cncjs_through_the_pty(grbl, tmp_path):
    prog = program(tmp_path, 1500)
    shm, rt, srv, port, tty = grbl(MILL)
    shot = BUILD / "cncjs-dro.png"  # kept: the page showing mlip's position
    ev = cncjs(tty, prog, tmp_path, "--jog", "--hold-after", "300", "--shot", shot)
    jog = event(ev, "jogged")
    assert jog["mpos"] == [2, 1, 0]                          # G91 G0 X2 Y1, as its axes widget
    hold = event(ev, "hold")                                 # within one report
    assert hold["reports"][-1].startswith("<Hold:"), hold
    held = event(ev, "held")
    assert held["state"] == "Hold:0" and held["before"] == held["after"]
    resumed = event(ev, "resumed")
    assert resumed["reports"][-1].startswith("<Run"), resumed
    done = event(ev, "done")
    assert done["state"] == "Idle" and done["errors"] == 0 and done["total"] == 1501
    dro_shows(done, shm)
    s = event(ev, "screenshot")
    assert s["dro_shows_x"], s                               # its page's DRO shows mlip's X
    assert shot.stat().st_size > 10000
