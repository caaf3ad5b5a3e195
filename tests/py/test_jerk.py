"""The jerk limit (MAX_JERK, mlip-sim --jerk; mlip/motion/jerk.h) on every
shared toolpath and sender file, every strategy, at the bench's settings
(A 1000 mm/s^2 per axis, 200 mm/s, eps 0.01 mm, T 1 ms): the physics of the
setpoints, measured from the samples alone (tools/lib/check.c), judged
against the ORIGINAL program's polyline.

  per-axis jerk (third differences / T^3) <= J_k (1 + 1e-9) + the rounding
  floor, and reached (>= 0.5 J_k on some axis: the bound from both sides)
  per-axis acceleration <= A_k (1 + 1e-9), velocity, tool speed, contour
  error <= eps (1 + 1e-9), the trace ends on the last point at rest
and without a jerk limit the traces carry the jerk the issue measured
(mlip-sim --strategy smooth on examples/demo.ngc: about 1.5e6 mm/s^3).
"""
import json
import math
import re
import subprocess
import sys

import pytest

from conftest import BUILD, REL, ROOT, TOOLPATHS, run, sim_summary
from test_toolpaths import FILES, SENDERS

STRATEGIES = ["mpct", "bisector", "stop", "smooth"]
ALL = list(FILES) + ["senders/" + n for n in SENDERS]


def opts(name, strategy, jerk, *extra):
    if name in FILES:
        cfg, n = FILES[name]
        o = ["--accel", ",".join(["1000"] * n)]
        if cfg is not None:  # its spindle and tool words run as nothing: the motion is tested
            o = ["--config", cfg, "--ignore-spindle", "--ignore-coolant", "--ignore-tools"] + o
    else:  # the axes the program uses; F-less programs at 600/min
        o = ["--accel", "1000", "--default-feed", "600"]
    return o + ["--strategy", strategy, "--vmax", "200", "--feed", "200", "--eps", "0.01",
                "--period", "0.001", "--jerk", str(jerk), *extra]


def floor(s):
    """The rounding floor of a third difference: twice the second's over T
    (tools/lib/check.h), from the largest coordinate the trace reaches."""
    return 16 * 2.3e-16 * 2000 / s["period_s"] ** 3


def assert_jerk_physics(s, used=True):
    for k, (j, lim) in enumerate(zip(s["max_axis_jerk"], s["jerk_limit"])):
        assert lim > 0 and j <= lim * (1 + REL) + floor(s), f"axis {s['axes'][k]}: jerk {j} > {lim}"
    if used:
        assert max(j / lim for j, lim in zip(s["max_axis_jerk"], s["jerk_limit"])) >= 0.5
    for k, (a, lim) in enumerate(zip(s["max_axis_accel"], s["accel_limit"])):
        assert a <= lim * (1 + REL), f"axis {s['axes'][k]}: {a} > {lim}"
    for k, (v, lim) in enumerate(zip(s["max_axis_vel"], s["vel_limit"])):
        assert v <= lim * (1 + REL), f"axis {s['axes'][k]} velocity {v} > {lim}"
    assert s["max_speed_mm_s"] <= s["vmax_mm_s"] * (1 + REL)
    assert s["max_contour_error_mm"] <= s["eps_mm"] * (1 + REL)
    assert s["end_error_mm"] <= 1e-9
    assert s["violations"] == 0


# every strategy at J = 100 A; the two the bench's table has (mpct, smooth)
# at J = 10 A too, and the others there on the short files
CASES = [(n, st, 1e5) for n in ALL for st in STRATEGIES] + \
        [(n, st, 1e4) for n in ALL for st in STRATEGIES
         if st in ("mpct", "smooth") or n.startswith("senders/")]


@pytest.mark.parametrize("name,strategy,jerk", CASES)
def test_jerk_physics(name, strategy, jerk):
    s = sim_summary(TOOLPATHS / name, *opts(name, strategy, int(jerk)))
    assert_jerk_physics(s, used=not name.endswith("line_skip_test.gcode"))


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_jerk_override_storm(strategy):
    """Random override changes (0-200 %), holds and resumes every 5-200
    periods: the jerk too stays within its limit, and the program ends."""
    s = sim_summary(TOOLPATHS / "senders" / "ShapeOko_Calibration_Pattern_01b.ngc",
                    *opts("senders/ShapeOko_Calibration_Pattern_01b.ngc", strategy, 10000,
                          "--storm", "3"))
    assert s["override_events"] > 100
    assert_jerk_physics(s, used=False)


def test_without_a_limit_the_jerk_is_unbounded():
    """What the issue measured on main: the acceleration steps between
    periods, about 1.5e6 mm/s^3 on the demo with smooth; the same program
    with --jerk 1e5 keeps it."""
    demo = ROOT / "examples" / "demo.ngc"
    base = ["--strategy", "smooth", "--accel", "1000", "--vmax", "200", "--eps", "0.01", "--feed",
            "200"]
    s = sim_summary(demo, *base)
    assert max(s["max_axis_jerk"]) > 1e6 and s["jerk_limit"] == [0] * len(s["axes"])
    s = sim_summary(demo, *base, "--jerk", "100000")
    assert_jerk_physics(s)


def test_check_refuses_a_jerk_beyond_the_limit(tmp_path):
    """mlip-check judges the third difference when a limit is set: the
    trace of an unlimited run breaks --jerk 1e5, the limited run's passes."""
    demo = ROOT / "examples" / "demo.ngc"
    base = ["--accel", "1000", "--vmax", "200", "--eps", "0.01"]
    for j, want in ((None, 1), ("100000", 0)):
        trace = tmp_path / f"t{j}.csv"
        extra = ["--jerk", j] if j else []
        run(["mlip-sim", "-q", "--strategy", "mpct", *base, *extra, "--trace", trace, demo])
        p = run(["mlip-check", *base, "--jerk", "100000", demo, trace], check=False)
        assert p.returncode == want, p.stderr
        if want:
            assert "jerk" in p.stderr and "exceeds 100000" in p.stderr


def test_max_jerk_in_the_machine_file(tmp_path):
    """MAX_JERK in each [AXIS_*] is the same limit as --jerk: the same
    trace, kept and used; a key absent is no limit (the trace without)."""
    demo = ROOT / "examples" / "demo.ngc"
    ini = (ROOT / "config" / "mill-3axis.ini").read_text()
    limited = tmp_path / "jerk.ini"
    limited.write_text(ini.replace("[AXIS_X]\n", "[AXIS_X]\nMAX_JERK = 100000\n")
                       .replace("[AXIS_Y]\n", "[AXIS_Y]\nMAX_JERK = 100000\n")
                       .replace("[AXIS_Z]\n", "[AXIS_Z]\nMAX_JERK = 100000\n"))
    assert limited.read_text().count("MAX_JERK") == 3
    traces = {}
    for name, args in (("file", ["--config", limited]),
                       ("option", ["--config", ROOT / "config" / "mill-3axis.ini",
                                   "--jerk", "100000"]),
                       ("none", ["--config", ROOT / "config" / "mill-3axis.ini"])):
        trace = tmp_path / f"{name}.csv"
        summary = tmp_path / f"{name}.json"
        run(["mlip-sim", "-q", "--strategy", "smooth", *args, "--trace", trace, "--summary",
             summary, demo])
        traces[name] = trace.read_bytes()
        if name != "none":
            s = json.loads(summary.read_text())
            assert s["jerk_limit"] == [100000] * 3
            assert_jerk_physics(s)
    assert traces["file"] == traces["option"] != traces["none"]


def hand_over(tmp_path, program, jerk, *extra):
    """bench/pathspeed.py --c --hand-over on PROGRAM: (P6 pieces over their
    band, the mean's time, what was chosen, its time, the rests line or
    None); the script itself exits non-zero when the chosen trace fails
    mlip-check --jerk."""
    p = subprocess.run([sys.executable, str(ROOT / "bench" / "pathspeed.py"), "x", "--jerk",
                        str(jerk), "--poly", str(program), "--c", "--hand-over", "--build",
                        str(BUILD), *extra], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    over = int(re.search(r"^\(P6\): (\d+) of", p.stdout, re.M).group(1))
    m = re.search(r"^hand-over: the mean ([\d.]+) s.*chosen: (path plan|mean|rests), ([\d.]+) s.*"
                  r"mlip-check --jerk: exit 0 \(pass", p.stdout, re.M)
    assert m, p.stdout[-2000:]
    rests = re.search(r"^rests: the path plan at rest at (\d+) breaks: ([\d.]+) s, "
                      r"mlip-check --jerk exit (\d+)", p.stdout, re.M)
    return over, float(m.group(1)), m.group(2), float(m.group(3)), rests


@pytest.mark.parametrize("jerk", [1e5, 1e4])
def test_hand_over_never_slower_than_the_mean(tmp_path, jerk):
    """The choice between the path-speed plan and the mean (docs/algorithm.md,
    "The hand-over to the mean"): on a circle (every spline piece within the
    (P6) band) the path plan runs and is faster than the mean, and no faster
    than the circle at vmax; on a random zigzag (the spline through its sharp
    vertices strays by up to 0.7 mm) it may not run and the mean's trace is
    the result unless the path plan at rest at its sharp vertices (--rests)
    is faster. Every candidate passes mlip-check --jerk."""
    circle = tmp_path / "circle.ngc"
    n, r = 2 * 2513, 20.0  # two laps of 0.05 mm chords
    circle.write_text("G21 G90\nG1 F12000\n" + "".join(
        f"G1 X{r * math.cos(i * 2 * math.pi / 2513):.4f} Y{r * math.sin(i * 2 * math.pi / 2513):.4f}\n"
        for i in range(n + 1)))
    over, t_mean, chosen, t, _ = hand_over(tmp_path, circle, jerk)
    assert over == 0 and chosen == "path plan"
    assert 2 * 2 * math.pi * r / 200.0 <= t < t_mean
    zigzag = tmp_path / "zigzag.ngc"
    zigzag.write_text(subprocess.run(
        [sys.executable, str(ROOT / "tools" / "gen_zigzag.py"), "--random", "2", "--segments",
         "300"], capture_output=True, text=True, check=True).stdout)
    over, t_mean, chosen, t, rests = hand_over(tmp_path, zigzag, jerk, "--rests")
    assert over > 0 and chosen in ("mean", "rests") and t <= t_mean
    # the third candidate, the path plan at rest at breaks where P6 refused
    # a piece, keeps every limit too (its trace judged like the others)
    assert rests and int(rests.group(1)) > 0 and rests.group(3) == "0"
    assert (chosen == "mean") == (float(rests.group(2)) >= t_mean)
