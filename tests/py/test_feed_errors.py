"""mlip-feed and mlip-ctl where no controller is needed: no segment, bad
arguments, bad files. Each test uses its own --shm name so parallel runs
never meet, and checks that no segment was left behind.

The system tests against a running controller (feeding, commands, stop,
signals, a dead controller, a rejected program) are in test_feed_ctl.py:
they need build/mlip-rt."""
import itertools
import os
from pathlib import Path

import pytest

from conftest import BUILD, ROOT, run

DEMO = ROOT / "examples" / "demo.ngc"
_serial = itertools.count()


@pytest.fixture(autouse=True, scope="module")
def tools_built():
    for t in ("mlip-feed", "mlip-ctl"):
        if not (BUILD / t).exists():
            pytest.fail(f"{BUILD / t} missing: run make first")


@pytest.fixture
def shm():
    """A segment name nobody uses; fails the test if a tool created it."""
    name = f"/mlip-test-{os.getpid()}-{next(_serial)}"
    yield name
    assert not Path("/dev/shm" + name).exists(), f"{name} left behind"


def no_segment_msg(name):
    return f"no controller segment {name}: is mlip-rt running?"


# ---- mlip-feed ---------------------------------------------------------------

def test_feed_no_segment(shm):
    p = run(["mlip-feed", "--shm", shm, DEMO], check=False)
    assert p.returncode == 1
    assert f"mlip-feed: {no_segment_msg(shm)}" in p.stderr, p.stderr
    assert p.stdout == ""


def test_feed_missing_file(shm, tmp_path):
    # the file is read before the segment is looked for
    p = run(["mlip-feed", "--shm", shm, tmp_path / "nope.ngc"], check=False)
    assert p.returncode == 1
    assert f"mlip-feed: {tmp_path / 'nope.ngc'}: No such file or directory" in p.stderr
    assert "segment" not in p.stderr


def test_feed_bad_shm_name(tmp_path):
    p = run(["mlip-feed", "--shm", "no-slash", DEMO], check=False)
    assert p.returncode == 1
    assert "shm name 'no-slash' must be '/' followed by" in p.stderr


@pytest.mark.parametrize("args", [[], ["a.ngc", "b.ngc"], ["--start-seq", "0", "a.ngc"],
                                  ["--start-seq", "-3", "a.ngc"], ["--start-seq", "1x", "a.ngc"],
                                  ["--start-seq", "", "a.ngc"], ["--bogus", "a.ngc"]])
def test_feed_usage_errors(shm, args):
    p = run(["mlip-feed", "--shm", shm, *args], check=False)
    assert p.returncode == 2, p.stderr
    assert p.stderr, "a usage error says something"


def test_feed_help():
    p = run(["mlip-feed", "--help"])
    assert p.stdout.startswith("usage: mlip-feed")
    for word in ("--shm NAME", "default /mlip", "--start-seq N", "--quiet", "exit status"):
        assert word in p.stdout


# ---- mlip-ctl ----------------------------------------------------------------

@pytest.mark.parametrize("json", [False, True])
def test_ctl_status_no_segment(shm, json):
    p = run(["mlip-ctl", "--shm", shm, "status", *(["--json"] if json else [])], check=False)
    assert p.returncode == 2
    assert f"mlip-ctl: {no_segment_msg(shm)}" in p.stderr
    assert "hint: start the controller (mlip-rt) first, or pass its --shm NAME" in p.stderr
    assert p.stdout == ""  # no half JSON for a script to choke on


@pytest.mark.parametrize("cmd", [["hold"], ["resume"], ["stop"], ["override", "50"]])
def test_ctl_command_no_segment(shm, cmd):
    p = run(["mlip-ctl", "--shm", shm, *cmd], check=False)
    assert p.returncode == 2
    assert no_segment_msg(shm) in p.stderr


# Both sides of each bound: 0 and 200 pass the parser (and then find no
# segment, exit 2 with that message); -1 and 201 do not.
@pytest.mark.parametrize("pct", ["0", "200", "100", "007"])
def test_ctl_override_accepted(shm, pct):
    p = run(["mlip-ctl", "--shm", shm, "override", pct], check=False)
    assert p.returncode == 2
    assert no_segment_msg(shm) in p.stderr, p.stderr


@pytest.mark.parametrize("pct", ["201", "-1", "1000", "50.5", "1e2", "", " 50", "50 ", "+50",
                                 "50%", "abc", "0x10"])
def test_ctl_override_rejected(shm, pct):
    p = run(["mlip-ctl", "--shm", shm, "override", pct], check=False)
    assert p.returncode == 2
    assert f"mlip-ctl: override: '{pct}' is not a whole percentage in 0..200" in p.stderr
    assert "segment" not in p.stderr  # refused before looking for a controller


@pytest.mark.parametrize("args,msg", [
    ([], "usage: mlip-ctl"),
    (["jig"], "unknown command 'jig'"),
    (["override"], "override: missing PCT"),
    (["hold", "now"], "hold: unexpected 'now'"),
    (["override", "50", "60"], "override: unexpected '60'"),
    (["status", "--yaml"], "status: unexpected '--yaml'"),
    (["--json", "stop"], "--json goes with status only"),
])
def test_ctl_usage_errors(shm, args, msg):
    p = run(["mlip-ctl", "--shm", shm, *args], check=False)
    assert p.returncode == 2
    assert msg in p.stderr, p.stderr


def test_ctl_help():
    p = run(["mlip-ctl", "--help"])
    assert p.stdout.startswith("usage: mlip-ctl")
    for word in ("override PCT", "0..200", "hold", "resume", "stop", "status [--json]",
                 "default /mlip", "exit status"):
        assert word in p.stdout
