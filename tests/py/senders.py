"""Real G-code senders run for the tests, as their users run them: bCNC (PyPI
bCNC: its Sender and GRBL1 controller, driven by bcnc_driver.py) through
pyserial's socket:// URL, and CNCjs (npm cncjs: its server and Grbl
controller, driven by tests/cncjs/drive.js through its socket.io API)
through mlip-grbl's pseudo-terminal. Each prints one JSON line per event
(with `wall`, the wall clock in seconds, to place events among the bus
cycles); these return them. Standard library only: shared by the host tests
(tests/py/test_senders.py) and the bus tests in the VM
(tests/can/test_senders_vcan.py), each with its own conftest."""
import json
import os
import socket
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
BCNC_DRIVER = HERE / "bcnc_driver.py"
CNCJS = HERE.parent / "cncjs"  # package.json: cncjs, socket.io-client (make deps: npm ci)


def events_of(p):
    return [json.loads(line) for line in p.stdout.splitlines() if line.startswith("{")]


def bcnc(port, prog, home, *opts, timeout=900):
    """bCNC streams prog through socket://127.0.0.1:port; opts to
    bcnc_driver.py (--hold-after N, --jog X2Y1, --deadline S). Its events;
    home: its settings folder (~/.bCNC)."""
    env = dict(os.environ, HOME=str(home))
    p = subprocess.run([sys.executable, str(BCNC_DRIVER), f"socket://127.0.0.1:{port}", str(prog),
                        *map(str, opts)], capture_output=True, text=True, timeout=timeout, env=env)
    events = events_of(p)
    assert p.returncode == 0, (events[-5:], p.stderr[-2000:])
    return events


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def cncjs(tty, prog, workdir, *opts, timeout=900):
    """CNCjs's server (on a free local port) opens the pseudo-terminal tty
    as a Grbl port and runs prog; opts to drive.js (--jog, --hold-after N,
    --hold-at-line N, --shot PNG, --deadline S). Its events."""
    p = subprocess.run(["node", str(CNCJS / "drive.js"), "--cncjs-port", str(free_port()),
                        "--tty", str(tty), "--file", str(prog),
                        "--config", str(Path(workdir) / "cncrc.json"), *map(str, opts)],
                       capture_output=True, text=True, timeout=timeout)
    ev = events_of(p)
    assert p.returncode == 0, (ev, p.stderr[-2000:])
    kinds = [e["event"] for e in ev]
    assert "connected" in kinds and "timeout" not in kinds and "error" not in kinds, ev
    assert [e for e in ev if e["event"] == "read" and e["line"].startswith("Grbl 1.1h")]
    return ev


def event(ev, kind):
    """The first event of kind (an AssertionError naming what came)."""
    e = next((e for e in ev if e["event"] == kind), None)
    assert e is not None, f"no '{kind}' event: {ev}"
    return e
