"""Shared helpers for the system tests: where things are, how to run a tool."""
import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / os.environ.get("MLIP_BUILD", "build")
SHARED = Path(os.environ.get("MLIP_SHARED", ROOT.parent / "shared"))
TOOLPATHS = SHARED / "toolpaths"
CONFIG = ROOT / "config"

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


@pytest.fixture(scope="session", autouse=True)
def built():
    for t in ("mlip-sim", "mlip-check"):
        if not (BUILD / t).exists():
            pytest.fail(f"{BUILD / t} missing: run make first")
    if not TOOLPATHS.is_dir():
        pytest.fail(f"{TOOLPATHS} missing: the shared toolpaths are needed (set MLIP_SHARED)")
