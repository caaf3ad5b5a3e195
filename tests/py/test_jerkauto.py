"""mlip-sim --jerk-plan auto: whichever of the mean, the plan over the
mean's setpoints (path-mean), the plan over smooth's without J (path) and
mpct (the program's own path, its mean) ends the program soonest; never
slower than the mean, and smooth never slower than mpct, by construction.

Every candidate is a deterministic function of the program and all share
its start and end (rests): auto runs the mean counted, then path-mean,
path and mpct each counted up to the fewest periods so far, and writes the
one that ends soonest (the earlier of mean, path-mean, path, mpct on a
tie). Asserted on a generated curve (tools/gen_curves.py lissajous, where
path is the fastest at 1e4 and path-mean, by 0.4 %, at 1e5), a sharp
random zigzag (tools/gen_zigzag.py, where mpct is: 22.446 s against
smooth's mean 22.465 s at 1e4, 10.606 s against 10.612 s at 1e5) and the
first 3,000 lines of the
shared flower-spiral-2d.ngc (CAM output, where path is since its knots are
faired) at J = 1e4 and 1e5, at the bench's settings (A 1000 mm/s^2, 200 mm/s,
feed 200, eps 0.01 mm, T 1 ms):
- auto's trace is the taken candidate's, byte for byte;
- it takes no period more than any candidate (tolerance 0 periods), and
  the one it takes is the soonest (each candidate also run alone);
- the written trace, and path-mean's, pass mlip-check --jerk and mlip-sim's
  own check (J, A, speed, contour, end).
"""
import json
import subprocess
import sys

import pytest

from conftest import BUILD, ROOT, TOOLPATHS
from test_jerk import assert_jerk_physics
from test_pathrun import sim  # mlip-sim -q --strategy smooth at the bench's settings

ORDER = ("mean", "path-mean", "path", "mpct")  # auto's order: the earlier wins a tie
KEY = {"path": "auto_path", "path-mean": "auto_path_mean", "mpct": "auto_mpct"}
NOT_SOONER = {"mean": "not sooner than the mean", "path-mean": "not sooner than path-mean",
              "path": "not sooner than path"}


def taken_by(summary):
    """The candidate auto wrote: mpct's mean, or smooth's plan."""
    return "mpct" if summary["strategy"] == "mpct" else summary["jerk_plan"]


@pytest.fixture(scope="module")
def programs(tmp_path_factory):
    d = tmp_path_factory.mktemp("jerkauto")
    curve, zigzag, cam = d / "lissajous.ngc", d / "zigzag.ngc", d / "flower-head.ngc"
    subprocess.run([sys.executable, str(ROOT / "tools" / "gen_curves.py"), "lissajous",
                    str(curve)], check=True, capture_output=True)
    with open(zigzag, "w", encoding="ascii") as f:
        subprocess.run([sys.executable, str(ROOT / "tools" / "gen_zigzag.py"), "--random", "1",
                        "--segments", "300"], stdout=f, check=True)
    lines = (TOOLPATHS / "flower-spiral-2d.ngc").read_text().splitlines(keepends=True)
    cam.write_text("".join(lines[:3000]))
    return {"curve": curve, "zigzag": zigzag, "cam": cam}


def check(prog, trace, jerk):
    p = subprocess.run([str(BUILD / "mlip-check"), "--accel", "1000", "--vmax", "200", "--eps",
                        "0.01", "--period", "0.001", "--jerk", str(jerk), "--json", "-",
                        str(prog), str(trace)],
                       capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    return json.loads(p.stdout)


@pytest.mark.parametrize("name,jerk,taken", [
    ("curve", 1e4, "path"), ("curve", 1e5, "path-mean"),
    ("zigzag", 1e4, "mpct"), ("zigzag", 1e5, "mpct"),
    ("cam", 1e4, "path"), ("cam", 1e5, "path"),
])
def test_auto_never_slower_than_any_candidate(tmp_path, programs, name, jerk, taken):
    prog = programs[name]
    runs, traces = {}, {}
    for plan in ORDER + ("auto",):
        traces[plan] = tmp_path / f"{plan}.csv"
        # the last --strategy is taken; auto's mean is smooth's own (its
        # candidate mpct is counted apart): --smooth-only
        how = ("--strategy", "mpct", "--jerk-plan", "mean") if plan == "mpct" else (
            "--jerk-plan", plan, *(("--smooth-only",) if plan == "mean" else ()))
        runs[plan] = sim(prog, "--jerk", str(jerk), *how, trace=traces[plan])
    auto = runs["auto"]
    periods = {p: runs[p]["periods"] for p in ORDER}
    # the choice: the soonest, the earlier of ORDER on a tie
    want = min(ORDER, key=lambda p: (periods[p], ORDER.index(p)))
    assert taken_by(auto) == want == taken, periods
    assert traces["auto"].read_bytes() == traces[want].read_bytes()
    # never slower than the mean nor any candidate: 0 periods of tolerance
    assert auto["periods"] == periods[want] == min(periods.values())
    assert auto["auto_mean_s"] == pytest.approx(runs["mean"]["total_time_s"], abs=1e-9)
    # each plan counted up to the fewest periods before it: sooner, or why not
    best = "mean"
    for p in ORDER[1:]:
        if periods[p] < periods[best]:
            assert auto[KEY[p]] == "sooner", p
            assert auto[KEY[p] + "_s"] == pytest.approx(runs[p]["total_time_s"], abs=1e-9)
            best = p
        else:
            assert auto[KEY[p]] == NOT_SOONER[best], p
            assert KEY[p] + "_s" not in auto
    assert_jerk_physics(auto)
    assert_jerk_physics(runs["path-mean"])
    assert check(prog, traces["auto"], jerk)["samples"] == auto["periods"] + 1
    assert check(prog, traces["path-mean"], jerk)["samples"] == periods["path-mean"] + 1


@pytest.mark.parametrize("jerk", [None, 1e4, 1e5])
def test_smooth_never_slower_than_mpct(tmp_path, jerk):
    """By construction: auto counts mpct's run last, up to the fewest
    periods so far, and takes it when it ends sooner. Random sharp zigzags
    (seeds 1-4, 200 segments), without J and at 1e4 and 1e5: auto's periods
    at most mpct's and smooth's mean's (0 periods of tolerance); where mpct
    is sooner, auto's trace is mpct's byte for byte (measured: it is at
    both J on seed 1, so the candidate is exercised). Plain smooth (the
    choice of corners per program, simcount.h) ends with the fewer of
    mpct's and smooth's own, 0 periods of tolerance."""
    lim = [] if jerk is None else ["--jerk", str(jerk)]
    took = 0
    for seed in range(1, 5):
        prog = tmp_path / f"zigzag{seed}.ngc"
        with open(prog, "w", encoding="ascii") as f:
            subprocess.run([sys.executable, str(ROOT / "tools" / "gen_zigzag.py"), "--random",
                            str(seed), "--segments", "200"], stdout=f, check=True)
        a, m = tmp_path / "auto.csv", tmp_path / "mpct.csv"
        mpct = sim(prog, *lim, "--strategy", "mpct", trace=m)
        mean = sim(prog, *lim, "--smooth-only")
        plain = sim(prog, *lim)
        assert plain["periods"] == min(mpct["periods"], mean["periods"]), (seed, jerk)
        auto = sim(prog, *lim, "--jerk-plan", "auto", trace=a)
        assert auto["periods"] <= min(mpct["periods"], mean["periods"]), (seed, jerk)
        if mpct["periods"] < mean["periods"]:
            assert taken_by(auto) == "mpct" and auto["auto_mpct"] == "sooner", seed
            assert auto["auto_mpct_s"] == pytest.approx(mpct["total_time_s"], abs=1e-9)
            assert a.read_bytes() == m.read_bytes(), seed
            took += 1
        else:
            assert taken_by(auto) != "mpct" and auto["auto_mpct"].startswith("not sooner")
        if jerk is not None:
            assert_jerk_physics(auto)
    if jerk is not None:
        assert took >= 1, "mpct never sooner: the candidate is not exercised"


@pytest.mark.parametrize("jerk,faired", [(1e4, 0.75), (1e5, 1.0)])
def test_path_mean_on_cam_output(tmp_path, programs, jerk, faired):
    """On CAM output the plan over the mean's rounded corners is faster than
    the mean: measured 0.76x (1e4) and 0.80x (1e5); asserted 0.65-0.90x of
    the mean. The plan over smooth's setpoints, its knots faired (pathrun.h
    F1 F2), is faster still: measured 0.64x (1e4) and 0.988x (1e5) of
    path-mean (unfaired it was 1.27x and 1.05x); asserted at most faired x
    path-mean, and no faster than smooth without J (a bound no plan
    passes)."""
    prog = programs["cam"]
    no_j = sim(prog)["total_time_s"]
    t = {p: sim(prog, "--jerk", str(jerk), "--jerk-plan", p)["total_time_s"]
         for p in ORDER[:3]}
    assert 0.65 * t["mean"] <= t["path-mean"] <= 0.90 * t["mean"], t
    assert no_j <= t["path"] <= faired * t["path-mean"], (no_j, t)


def test_path_mean_needs_the_plan_settings(programs):
    """path-mean, like path: --strategy smooth, --feed, a jerk limit."""
    prog = programs["zigzag"]
    for extra, why in [(["--strategy", "mpct"], "need --strategy smooth"),
                       ([], "every axis needs a jerk limit")]:
        cmd = [str(BUILD / "mlip-sim"), "-q", "--strategy", "smooth", "--feed", "200",
               "--jerk-plan", "path-mean", *extra, str(prog)]
        if extra:
            cmd[6:6] = ["--jerk", "1e5"]
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
        assert p.returncode == 2 and why in p.stderr, p.stderr


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
        for key in ("auto_path", "auto_path_mean"):
            assert s[key] == ("refused" if label == "pause" else
                              "not a candidate (--strategy smooth, --feed, a jerk limit)")
        assert_jerk_physics(s)


def test_auto_without_a_jerk_limit_is_the_motion_without_it(tmp_path, programs):
    prog = programs["zigzag"]
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    sim(prog, trace=a)
    s = sim(prog, "--jerk-plan", "auto", trace=b)
    assert s["jerk_plan"] == "mean" and a.read_bytes() == b.read_bytes()
