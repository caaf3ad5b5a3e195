"""The contour measure of mlip-sim's summary and of mlip-check against an
independent brute force (numpy, every sample against every segment), on a
2-D zigzag with sharp corners and 0.3 mm segments at 1000 mm/s^2 whose
rows come within 4 um of each other (tools/gen_zigzag.py); a real
excursion injected into the trace is caught; mlip-sim exits non-zero when
its own check sees a violation (a test build that pushes one setpoint off
the path)."""
import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import BUILD, ROOT, run, sim_summary

EPS = 0.01
MACHINE = ["--accel", "1000", "--vmax", "200", "--eps", str(EPS)]
EXACT = 1e-12  # mm: the checker's distance and numpy's, both in doubles


def polyline(ngc):
    """Home (0, 0) then every G1 target of a generated 2-D program."""
    pts = [(0.0, 0.0)]
    for line in open(ngc):
        if line.startswith("G1 X"):
            w = line.split()
            pts.append((float(w[1][1:]), float(w[2][1:])))
    return np.array(pts)


def brute(pts, xs):
    """min over every segment of |x - (a + t (b - a))|, t clamped to [0, 1]."""
    best = np.full(len(xs), np.inf)
    for a, b in zip(pts[:-1], pts[1:]):
        d = b - a
        ax = xs - a
        t = np.clip(ax @ d / (d @ d), 0.0, 1.0)
        e = ax - t[:, None] * d
        np.minimum(best, np.einsum("ij,ij->i", e, e), out=best)
    return np.sqrt(best)


@pytest.fixture(scope="module")
def zigzag(tmp_path_factory):
    """30 rows of 8 mm, 0.3 mm teeth at 60 degrees that come within 4 um
    of the next row's: 1619 segments, 49000 setpoints."""
    d = tmp_path_factory.mktemp("zz")
    ngc, trace = d / "zz.ngc", d / "zz.csv"
    gen = [sys.executable, str(ROOT / "tools" / "gen_zigzag.py"), "--seg", "0.26", "--pitch",
           "0.15", "--length", "8", "--rows", "30", "--row-gap", "0.004"]
    ngc.write_text(subprocess.run(gen, check=True, capture_output=True, text=True).stdout)
    s = sim_summary(ngc, *MACHINE, "--trace", trace)
    return ngc, trace, s


def check_errors(tmp_path, ngc, trace, expect_rc):
    errs = tmp_path / "e.csv"
    p = run(["mlip-check", *MACHINE, "--errors", errs, ngc, trace], check=False)
    assert p.returncode == expect_rc, p.stderr
    return p, np.loadtxt(errs, delimiter=",", ndmin=2)[:, 1]


def test_zigzag_within_eps_and_equal_to_brute_force(tmp_path, zigzag):
    ngc, trace, s = zigzag
    assert s["violations"] == 0 and s["order_errors"] == 0
    pts = polyline(ngc)
    assert len(pts) - 1 == s["blocks"]
    d = np.loadtxt(trace, delimiter=",", skiprows=1)
    want = brute(pts, d[:, 1:])
    p, got = check_errors(tmp_path, ngc, trace, 0)
    assert "within limits" in p.stderr
    assert len(got) == len(d) == s["periods"] + 1
    assert np.abs(got - want).max() <= EXACT
    # both sides: inside the band, and mpct uses it (corners fill half of
    # each 0.3 mm segment, eq. 19)
    assert want.max() <= EPS * (1 + 1e-9)
    assert want.max() >= 0.4 * EPS
    assert abs(s["max_contour_error_mm"] - want.max()) <= 1e-9  # %.9g in the summary


def test_excursion_is_caught(tmp_path, zigzag):
    """One setpoint pushed 0.08 mm off the path (across the row, where the
    nearest other row is 0.26 mm away) is a contour error of exactly its
    distance to the polyline; the rest of the trace stays exact."""
    ngc, trace, _ = zigzag
    rows = open(trace).read().splitlines()
    i = len(rows) // 2
    cols = rows[i].split(",")
    cols[2] = repr(float(cols[2]) + 0.08)
    rows[i] = ",".join(cols)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(rows) + "\n")
    d = np.loadtxt(bad, delimiter=",", skiprows=1)
    want = brute(polyline(ngc), d[:, 1:])
    p, got = check_errors(tmp_path, ngc, bad, 1)
    assert np.abs(got - want).max() <= EXACT
    k = i - 1  # sample index: rows[0] is the header
    assert want.argmax() == k and want[k] > 2 * EPS, want[k]
    assert f"contour error {want[k]:.12g} exceeds 0.01 at sample {k} " in p.stderr, p.stderr
    assert "nearest block: line" in p.stderr


def test_sim_exits_nonzero_on_its_own_violation(tmp_path):
    """A test build of mlip-sim that pushes setpoint 500 by 0.05 mm on every
    axis (tests/py/sim_fault.c wraps the trace's sample: nothing in mlip-sim):
    the summary's check sees it, says which check, sample, time and line,
    and the exit status is 4; the real build on the same program exits 0."""
    exe = tmp_path / "mlip-sim-fault"
    cc = ["cc", "-std=c99", "-D_POSIX_C_SOURCE=200809L", "-D_DEFAULT_SOURCE", "-O1",
          f"-I{ROOT / 'include'}", f"-I{ROOT / 'tools' / 'lib'}", "-DMLIP_SIM_FAULT_AT=500",
          str(ROOT / "tools" / "mlip-sim.c"), str(ROOT / "tools" / "simopts.c"),
          str(ROOT / "tests" / "py" / "sim_fault.c"),
          "-Wl,--wrap=mlip_trace_sample", str(BUILD / "libmlip-host.a"),
          str(BUILD / "libmlip.a"), "-lm", "-o", str(exe)]
    cc[1:1] = os.environ.get("MLIP_SAN", "").split()  # make asan/ubsan: the library's flags
    subprocess.run(cc, check=True)
    demo = ROOT / "examples" / "demo.ngc"
    p = subprocess.run([str(exe), "-q", *MACHINE, str(demo)], capture_output=True, text=True)
    assert p.returncode == 4, p.stderr
    assert "the trace breaks the machine's limits" in p.stderr
    assert "contour error 0.0707106781" in p.stderr and "at sample 500 (t = 0.500000 s)" in p.stderr
    assert "nearest block: line " in p.stderr
    ok = run(["mlip-sim", "-q", *MACHINE, demo], check=False)
    assert ok.returncode == 0, ok.stderr
