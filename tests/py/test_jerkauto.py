"""mlip-sim --jerk-plan auto: the path plan where it ends the program
sooner than the mean, else the mean; never slower than the mean.

Both candidates are deterministic functions of the program and share its
start and end (rests): auto runs the mean counted, the path plan counted
up to the mean's periods, and writes the one that ends sooner (the mean on
a tie). Asserted on a generated curve (tools/gen_curves.py lissajous, where
the plan is faster) and a sharp random zigzag (tools/gen_zigzag.py, where
the mean is) at J = 1e4 and 1e5, at the bench's settings (A 1000 mm/s^2,
200 mm/s, feed 200, eps 0.01 mm, T 1 ms):
- auto's trace is the taken candidate's, byte for byte;
- it takes no period more than the mean (tolerance 0 periods), and it takes
  the path plan exactly when that ends in fewer periods (each candidate
  also run alone);
- the written trace passes mlip-check --jerk and mlip-sim's own check
  (J, A, speed, contour, end).
"""
import json
import subprocess
import sys

import pytest

from conftest import BUILD, ROOT
from test_jerk import assert_jerk_physics
from test_pathrun import sim  # mlip-sim -q --strategy smooth at the bench's settings


@pytest.fixture(scope="module")
def programs(tmp_path_factory):
    d = tmp_path_factory.mktemp("jerkauto")
    curve, zigzag = d / "lissajous.ngc", d / "zigzag.ngc"
    subprocess.run([sys.executable, str(ROOT / "tools" / "gen_curves.py"), "lissajous",
                    str(curve)], check=True, capture_output=True)
    with open(zigzag, "w", encoding="ascii") as f:
        subprocess.run([sys.executable, str(ROOT / "tools" / "gen_zigzag.py"), "--random", "1",
                        "--segments", "300"], stdout=f, check=True)
    return {"curve": curve, "zigzag": zigzag}


def check(prog, trace, jerk):
    p = subprocess.run([str(BUILD / "mlip-check"), "--accel", "1000", "--vmax", "200", "--eps",
                        "0.01", "--period", "0.001", "--jerk", str(jerk), "--json", "-",
                        str(prog), str(trace)],
                       capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    return json.loads(p.stdout)


@pytest.mark.parametrize("name,jerk,taken", [
    ("curve", 1e4, "path"), ("curve", 1e5, "path"),
    ("zigzag", 1e4, "mean"), ("zigzag", 1e5, "mean"),
])
def test_auto_never_slower_than_the_mean(tmp_path, programs, name, jerk, taken):
    prog = programs[name]
    runs, traces = {}, {}
    for plan in ("mean", "path", "auto"):
        traces[plan] = tmp_path / f"{plan}.csv"
        runs[plan] = sim(prog, "--jerk", str(jerk), "--jerk-plan", plan, trace=traces[plan])
    mean, path, auto = runs["mean"], runs["path"], runs["auto"]
    # the choice: the path plan exactly when it ends sooner (a tie: the mean)
    want = "path" if path["periods"] < mean["periods"] else "mean"
    assert auto["jerk_plan"] == want == taken, (mean["periods"], path["periods"])
    assert traces["auto"].read_bytes() == traces[want].read_bytes()
    # never slower than the mean: 0 periods of tolerance
    assert auto["periods"] == runs[want]["periods"] <= mean["periods"]
    assert auto["auto_mean_s"] == pytest.approx(mean["total_time_s"], abs=1e-9)
    if want == "path":
        assert auto["auto_path"] == "sooner"
        assert auto["auto_path_s"] == pytest.approx(path["total_time_s"], abs=1e-9)
        assert auto["periods"] < mean["periods"]
    else:
        assert auto["auto_path"] == "not sooner than the mean" and "auto_path_s" not in auto
    assert_jerk_physics(auto)
    assert check(prog, traces["auto"], jerk)["samples"] == auto["periods"] + 1


def test_auto_takes_the_mean_where_the_plan_cannot_run(tmp_path, programs):
    """No plan for mpct (the plan re-times smooth's path) nor across a pause
    (the plan refuses M0): auto is the mean there, byte for byte."""
    prog = programs["curve"]
    for label, strategy, p in [("mpct", "mpct", prog), ("pause", "smooth", None)]:
        st = ["--strategy", strategy]  # the last --strategy is taken
        if p is None:
            p = tmp_path / "pause.ngc"
            p.write_text("G21 G90\nG1 F12000\nG1 X10 Y2\nM0\nG1 X20 Y0\nG1 X0 Y5\n")
        mean, auto = tmp_path / f"{label}-mean.csv", tmp_path / f"{label}-auto.csv"
        sim(p, *st, "--jerk", "1e5", trace=mean)
        s = sim(p, *st, "--jerk", "1e5", "--jerk-plan", "auto", trace=auto)
        assert s["jerk_plan"] == "mean" and auto.read_bytes() == mean.read_bytes(), label
        assert s["auto_path"] == ("refused" if label == "pause" else
                                  "not a candidate (--strategy smooth, --feed, a jerk limit)")
        assert_jerk_physics(s)


def test_auto_without_a_jerk_limit_is_the_motion_without_it(tmp_path, programs):
    prog = programs["zigzag"]
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    sim(prog, trace=a)
    s = sim(prog, "--jerk-plan", "auto", trace=b)
    assert s["jerk_plan"] == "mean" and a.read_bytes() == b.read_bytes()
