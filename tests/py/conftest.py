"""Shared helpers for the system tests: where things are, how to run a tool."""
import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

import mlipcan  # the project's Python package (pip install -e . by tools/deps.sh)
from mlipcan.settings import Settings

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / os.environ.get("MLIP_BUILD", "build")
SHARED = Path(os.environ.get("MLIP_SHARED", ROOT.parent / "shared"))
TOOLPATHS = SHARED / "toolpaths"
CONFIG = ROOT / "config"
# the package's view of the same: what its functions take as settings
S = Settings.from_environ(ROOT)
if Path(mlipcan.__file__).resolve().parent != ROOT / "python" / "mlipcan":
    pytest.exit(f"mlipcan is imported from {Path(mlipcan.__file__).parent}, not from this "
                f"checkout ({ROOT}): run tools/deps.sh (pip install -e .)", returncode=4)

# Every physical limit is asserted with this relative tolerance, above; and
# "the limit is used" is asserted below it (both sides of each bound).
REL = 1e-9


def tool(name):
    return str(BUILD / name)


def run(args, check=True, **kw):
    """Run a built tool; returns CompletedProcess with text output."""
    p = subprocess.run([tool(args[0])] + [str(a) for a in args[1:]], capture_output=True,
                       text=True, **kw)
    if check and p.returncode != 0:
        raise AssertionError(f"{args} exited {p.returncode}:\n{p.stderr}")
    return p


def sim_summary(path, *opts):
    p = run(["mlip-sim", "-q", "--summary", "-", *opts, path])
    return json.loads(p.stdout)


def offsets_file(path, *sets, config=CONFIG / "mill-3axis.ini"):
    """A sealed offsets file: mlip-offsets --init (all zero, G54, G28/G30 at
    HOME), then --set for each "KEY VALUES" (e.g. "G55 X10 Y20")."""
    run(["mlip-offsets", "--init", "--config", config, path])
    if sets:
        run(["mlip-offsets", *[a for s in sets for a in ("--set", s)], path])
    return path


@pytest.fixture(scope="session", autouse=True)
def built():
    for t in ("mlip-sim", "mlip-check"):
        if not (BUILD / t).exists():
            pytest.fail(f"{BUILD / t} missing: run make first")
    if not TOOLPATHS.is_dir():
        pytest.fail(f"{TOOLPATHS} missing: the shared toolpaths are needed (set MLIP_SHARED)")


# ---- the controller's processes on this host (--can none)

_n = [0]


def shm_name():
    _n[0] += 1
    return f"/mlip-pytest-{os.getpid()}-{_n[0]}"


def status(shm):
    p = subprocess.run([tool("mlip-ctl"), "--shm", shm, "status", "--json"], capture_output=True,
                       text=True)
    return json.loads(p.stdout) if p.stdout.strip() else None


def wait_for(pred, timeout=10.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        v = pred()
        if v:
            return v
        time.sleep(0.02)
    return None


@pytest.fixture
def controller():
    """Start mlip-rt --can none on a fresh segment; stop it (SIGTERM) after."""
    procs = []

    def start(config=CONFIG / "mill-3axis.ini", *extra):
        shm = shm_name()
        # this shared 2-core VM is not real-time (wake-ups late by tens of ms):
        # a stall hold (default 3 missed periods) would stop any long run here;
        # the stall tests give their own limit
        if "--stall-periods" not in extra:
            extra = ("--stall-periods", "100000", *extra)
        p = subprocess.Popen([tool("mlip-rt"), "--config", str(config), "--can", "none", "--shm", shm,
                              *extra], stderr=subprocess.PIPE, text=True)
        procs.append(p)
        assert wait_for(lambda: (status(shm) or {}).get("alive")), "controller did not come up"
        return shm, p

    yield start
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
