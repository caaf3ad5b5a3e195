"""Jogging (issue 18) on a real vcan0 with three simulated CiA 402 drives
(the canopen package), judged on the positions the drives reported at each
SYNC (sync.csv): a continuous jog released (mlip-ctl jog's SECONDS elapsed)
and one whose client is killed (its renewals stop: the controller's
dead-man ends it) each stop at the acceleration limit, v^2 / 2A to rest
within one period's travel; a jog toward a soft limit stops exactly at it,
to the count.

X and Y at A = 200 mm/s^2 here, so that a stop from 100 mm/s lasts 12
periods of 40 ms (the emulated VM's period). Each test prints a [jog] line.
"""

import re
import signal
import subprocess
import time

import pytest

from conftest import DRIVES_VM, S
from mlipcan import procs

MILL = S.config_dir / "mill-3axis.ini"
PERIOD_S = 0.04
A = 200.0  # mm/s^2, X and Y here
CPU = 1000.0  # counts/mm


def machine(tmp, x_max=1000):
    text = MILL.read_text().replace("PERIOD = 0.001", f"PERIOD = {PERIOD_S}")
    text = text.replace("CONTOUR_TOLERANCE = 0.01", "CONTOUR_TOLERANCE = 0.5")
    z = text.index("[AXIS_Z]")
    head = text[:z].replace("MAX_ACCELERATION = 1000", f"MAX_ACCELERATION = {A:g}")
    head = re.sub(r"^MAX_LIMIT = 1000$", f"MAX_LIMIT = {x_max}", head, count=1, flags=re.M)
    path = tmp / "jog.ini"
    path.write_text(head + text[z:] + DRIVES_VM)
    return path


@pytest.fixture
def sim(vcan, tmp_path_factory):
    """Per test: each starts with every axis at 0."""
    w = tmp_path_factory.mktemp("jogsim")
    s = procs.DriveSimProc(S, w, nodes=[1, 2, 3])
    yield s
    s.stop()


def positions(sim, node, t0):
    """(sync, actual counts) of one drive from t0 on, in SYNC order."""
    return [(r["sync"], r["actual"]) for r in sim.sync_rows() if r["node"] == node and r["t"] >= t0]


def stop_of(rows, v_jog):
    """The stop: speed (mm/s) of the last period at the jog's speed, the
    distance from there to rest (mm), the largest deceleration (mm/s^2)."""
    x = [c / CPU for _, c in rows]
    v = [(b - a) / PERIOD_S for a, b in zip(x, x[1:])]
    fast = [i for i, s in enumerate(v) if abs(abs(s) - v_jog) <= 0.01 * v_jog]
    assert fast, f"never at {v_jog} mm/s: {v[:50]}"
    last = fast[-1]
    rest = [i for i in range(last, len(v)) if v[i] == 0.0]
    assert rest, "never at rest"
    d = abs(x[rest[0]] - x[last + 1])
    dec = max(abs(b - a) / PERIOD_S for a, b in zip(v[last:rest[0] + 1], v[last + 1:rest[0] + 1]))
    return abs(v[last]), d, dec


def test_jog_released_and_deadman(sim, tmp_path):
    cfg = machine(tmp_path)
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        t0 = time.time()
        p = rig.ctl("jog", "X+", "6000", "3")  # 100 mm/s, released after 3 s
        assert "jog released" in p.stdout, p.stdout
        st = rig.wait_state("idle", timeout=120)
        assert st["reason"] == "jog released", st
        t1 = time.time()
        j = subprocess.Popen([S.tool("mlip-ctl"), "--shm", rig.shm, "jog", "Y-", "6000"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        rig.wait_state("jog", timeout=120, pred=lambda s: s["speed_mm_s"] >= 99.0)
        j.send_signal(signal.SIGKILL)  # its renewals stop: no release sent
        j.wait(timeout=30)
        st = rig.wait_state("idle", timeout=120)
        assert st["reason"] == "jog not renewed", st
    v1, d1, dec1 = stop_of(positions(sim, 1, t0), 100.0)
    v2, d2, dec2 = stop_of(positions(sim, 2, t1), 100.0)
    want = 100.0**2 / (2 * A)
    print(f"[jog] released at {v1:.1f} mm/s: {d1:.3f} mm to rest (v^2/2A = {want:.3f} mm), "
          f"deceleration max {dec1:.1f} mm/s^2; client killed at {v2:.1f} mm/s: {d2:.3f} mm "
          f"to rest, max {dec2:.1f} mm/s^2 (A = {A:g})")
    tol_a = A * 0.01 + 2 / PERIOD_S**2 / CPU  # 1 % and a count of rounding
    for d, dec in ((d1, dec1), (d2, dec2)):
        assert abs(d - want) <= 100.0 * PERIOD_S, (d, want)
        assert dec <= A + tol_a, dec


def test_jog_soft_limit(sim, tmp_path):
    cfg = machine(tmp_path, x_max=30)
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        t0 = time.time()
        p = rig.ctl("jog", "X+", "3000", "50")  # ends at the limit, long before 50 s
        assert p.returncode == 0, p.stderr
        st = rig.wait_state("idle", timeout=120)
        assert st["reason"] == "jog at the soft limit" and st["position"]["X"] == 30.0, st
        p = rig.ctl("jog", "X+", "3000", check=False)
        assert p.returncode == 1 and "error 15" in p.stderr, p.stderr
    rows = positions(sim, 1, t0)
    top = max(c for _, c in rows)
    print(f"[jog] toward MAX_LIMIT 30: drive 1 at most {top} counts, at rest at {rows[-1][1]}")
    assert top == 30000 and rows[-1][1] == 30000, (top, rows[-5:])
