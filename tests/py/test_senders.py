"""Real senders against mlip-grbl and mlip-rt on this host (--can none):
bCNC (PyPI bCNC, its own Sender thread and GRBL1 controller, driven without
its window by bcnc_driver.py) through pyserial's socket:// URL: it connects,
reads the DRO, runs a shared toolpath end to end in the time mlip-feed takes
(within 1 %), jogs as its jog pad does ($J=), holds and resumes it on the path. CNCjs (npm cncjs, its server
and Grbl controller, tests/cncjs/drive.js) through the pseudo-terminal: the
same, a jog as its axes widget sends it, and its page in headless Chromium
showing mlip's position (build/cncjs-dro.png)."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import BUILD, TOOLPATHS, status, tool
from test_grbl import MILL, grbl, logged, stop_rt, trace_rows  # noqa: F401  (the fixture)

DRIVER = Path(__file__).with_name("bcnc_driver.py")


def program(tmp_path, lines=3000):
    p = tmp_path / "flower.ngc"
    p.write_text("".join((TOOLPATHS / "flower-spiral-2d.ngc").read_text()
                         .splitlines(True)[:lines]))
    return p


def bcnc(port, prog, tmp_path, *opts):
    env = dict(os.environ, HOME=str(tmp_path))  # bCNC keeps its settings in ~/.bCNC
    p = subprocess.run([sys.executable, str(DRIVER), f"socket://127.0.0.1:{port}", str(prog),
                        *opts], capture_output=True, text=True, timeout=900, env=env)
    events = [json.loads(l) for l in p.stdout.splitlines() if l.startswith("{")]
    assert p.returncode == 0, p.stderr[-2000:]
    return events


def test_bcnc_runs_a_file_as_mlip_feed(grbl, controller, tmp_path):
    prog = program(tmp_path)
    rec_feed = tmp_path / "feed.csv"
    shm, rt = controller(MILL, "--record", rec_feed)
    logged(rt, "mlip-rt (mlip-feed)")
    f = subprocess.run([tool("mlip-feed"), "--shm", shm, "-q", str(prog)], capture_output=True,
                       text=True, timeout=600)
    assert f.returncode == 0, f.stderr
    stop_rt(rt)

    rec = tmp_path / "bcnc.csv"
    shm, rt, srv, port, _ = grbl(MILL, "--record", rec)
    ev = bcnc(port, prog, tmp_path)
    first = ev[0]
    assert first["event"] == "connected" and first["state"] == "Idle", first
    assert first["mpos"] == [0.0, 0.0, 0.0]
    assert not [e for e in ev if e["event"] in ("error", "timeout")], ev
    done = ev[-1]
    assert done["event"] == "done" and done["state"] == "Idle", done
    c = status(shm)
    # bCNC's DRO shows where mlip-rt stands
    assert done["mpos"] == pytest.approx([c["position"][k] for k in "XYZ"], abs=1e-3)
    stop_rt(rt)
    _, ta = trace_rows(rec_feed)
    _, tb = trace_rows(rec)
    print(f"bCNC: {tb} periods of motion, mlip-feed {ta}")
    assert abs(ta - tb) <= 0.01 * ta, (ta, tb)


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
    c = status(shm)
    assert done["mpos"] == pytest.approx([c["position"][k] for k in "XYZ"], abs=1e-3)


# ---- CNCjs (npm cncjs, tests/cncjs): its server opens mlip-grbl's pseudo-terminal as a
# Grbl serial port; driven through its socket.io API as its page does, and its page in
# headless Chromium for the screenshot (build/cncjs-dro.png)

CNCJS = Path(__file__).resolve().parents[1] / "cncjs"


def free_port():
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_cncjs_through_the_pty(grbl, tmp_path):
    prog = program(tmp_path, 1500)
    shm, rt, srv, port, tty = grbl(MILL)
    shot = BUILD / "cncjs-dro.png"  # kept: the page showing mlip's position
    p = subprocess.run(["node", str(CNCJS / "drive.js"), "--cncjs-port", str(free_port()),
                        "--tty", str(tty), "--file", str(prog),
                        "--config", str(tmp_path / "cncrc.json"), "--hold-after", "300",
                        "--shot", str(shot)], capture_output=True, text=True, timeout=900)
    ev = [json.loads(l) for l in p.stdout.splitlines() if l.startswith("{")]
    assert p.returncode == 0, (ev, p.stderr[-2000:])
    kinds = [e["event"] for e in ev]
    assert "connected" in kinds and "timeout" not in kinds and "error" not in kinds, ev
    assert [e for e in ev if e["event"] == "read" and e["line"].startswith("Grbl 1.1h")]
    jog = next(e for e in ev if e["event"] == "jogged")
    assert jog["mpos"] == [2, 1, 0]                          # G91 G0 X2 Y1, as its axes widget
    held = next(e for e in ev if e["event"] == "held")
    assert held["state"] == "Hold:0" and held["before"] == held["after"]
    done = next(e for e in ev if e["event"] == "done")
    assert done["state"] == "Idle" and done["errors"] == 0 and done["total"] == 1501
    c = status(shm)
    assert done["mpos"] == pytest.approx([c["position"][k] for k in "XYZ"], abs=1e-3)
    s = next(e for e in ev if e["event"] == "screenshot")
    assert s["dro_shows_x"], s                               # its page's DRO shows mlip's X
    assert shot.stat().st_size > 10000
