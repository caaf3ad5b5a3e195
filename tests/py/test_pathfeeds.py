"""The path plan under each block's own feed (mlip-sim --jerk-plan path and
path-mean, pathplan.h Q5): a program with several F words and G0 rapids runs, each
block at or below its own feed (a rapid at the machine's speed), inside A
and J at every sample, the contour within eps.

The trace has no block column: each setpoint belongs to the program's
segments it lies near (within eps of the nearest one's distance: a point
of a corner lies on both of its segments), and the step from one setpoint
to the next is held to the lowest feed of the segments either end belongs
to, on both sides of every feed change. The bound: the programmed feed
times 1 + 1e-3 (the plan caps 0.995 of it; a period's mean speed is within
|j| T^2 / 12 of its ends', 0.008 mm/s at 1e5). The plan must also use each
cap: the fastest step of each run of one feed reaches 0.9 of it (path; 0.8
for path-mean, whose input is the mean's).
"""
import json
import math
import subprocess

import pytest

from conftest import BUILD
from test_jerk import assert_jerk_physics

SETTINGS = ["--accel", "1000", "--vmax", "200", "--eps", "0.01", "--period", "0.001"]
TOL = 1e-3  # on a feed: above the plan's own 0.995 (see the top)
EPS = 0.01


def two_feeds(path):
    """A line in at F600, a circle of radius 20 in 0.5 degree chords (each
    feed within what A and J allow there at 1e4) whose quarters alternate
    F600 (10 mm/s) and F3000 (50 mm/s), the line back at F600 (after a fast
    quarter: a feed change at a 90 degree corner). Returns the segments:
    (start, end, feed mm/s)."""
    r, feeds = 20.0, [600, 3000, 600, 3000]
    out, segs, at = ["G21 G90", f"G1 F600 X{r:.4f} Y0"], [], (r, 0.0)
    segs.append(((0.0, 0.0), at, 10.0))
    for q in range(4):
        out.append(f"F{feeds[q]}")
        for k in range(q * 180 + 1, (q + 1) * 180 + 1):
            a = math.radians(0.5 * k)
            p = (round(r * math.cos(a), 4), round(r * math.sin(a), 4))
            out.append(f"G1 X{p[0]:.4f} Y{p[1]:.4f}")
            segs.append((at, p, feeds[q] / 60.0))
            at = p
    out.append("G1 F600 X0 Y0")
    segs.append((at, (0.0, 0.0), 10.0))
    path.write_text("\n".join(out) + "\n")
    return segs


def rapids(path):
    """G0 out, a plunge-like move at F600, a cut at F3000, G0 back: the
    rapids at the machine's 200 mm/s (200 is the cap there, not a feed)."""
    path.write_text("G21 G90\nG0 X60\nG1 F600 Y10\nG1 F3000 X0\nG0 Y0\n")
    pts = [(0.0, 0.0), (60.0, 0.0), (60.0, 10.0), (0.0, 10.0), (0.0, 0.0)]
    return [(pts[i], pts[i + 1], f) for i, f in enumerate([200.0, 10.0, 50.0, 200.0])]


def dist(p, a, b):
    dx, dy = b[0] - a[0], b[1] - a[1]
    t = max(0.0, min(1.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / (dx * dx + dy * dy)))
    return math.hypot(p[0] - a[0] - t * dx, p[1] - a[1] - t * dy)


def blocks(p, segs, lo=0, hi=None):
    """The segments p belongs to: within eps of the nearest one's distance
    (among segments lo..hi: the last point's neighbourhood; all of them when
    none is within eps there)."""
    hi = len(segs) - 1 if hi is None else min(hi, len(segs) - 1)
    lo = max(lo, 0)
    d = {i: dist(p, segs[i][0], segs[i][1]) for i in range(lo, hi + 1)}
    near = min(d.values())
    if near > EPS and (lo, hi) != (0, len(segs) - 1):
        return blocks(p, segs)
    return [i for i, x in d.items() if x <= near + EPS]


def run(prog, jerk, trace, plan="path"):
    p = subprocess.run([str(BUILD / "mlip-sim"), "-q", "--strategy", "smooth", *SETTINGS,
                        "--jerk", str(jerk), "--jerk-plan", plan, "--trace", str(trace),
                        "--summary", "-", str(prog)], capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]  # not refused, and within its own check
    s = json.loads(p.stdout)
    assert_jerk_physics(s)  # J, A, speed, contour within eps, end
    chk = subprocess.run([str(BUILD / "mlip-check"), *SETTINGS, "--jerk", str(jerk), "--json",
                          "-", str(prog), str(trace)], capture_output=True, text=True,
                         timeout=600)
    assert chk.returncode == 0, chk.stdout[-2000:] + chk.stderr[-2000:]
    assert json.loads(chk.stdout)["samples"] == s["periods"] + 1
    return s


def steps(trace, segs, T=0.001):
    """Each step's speed and the segments its two ends belong to."""
    rows = trace.read_text().splitlines()[1:]
    pts = [tuple(float(v) for v in r.split(",")[1:3]) for r in rows]
    owner = [blocks(pts[0], segs)]
    for p in pts[1:]:
        owner.append(blocks(p, segs, min(owner[-1]) - 2, max(owner[-1]) + 20))
    for k in range(1, len(pts)):
        v = math.hypot(pts[k][0] - pts[k - 1][0], pts[k][1] - pts[k - 1][1]) / T
        yield v, set(owner[k - 1]) | set(owner[k])


# path-mean: the plan over the mean's setpoints, each tagged with the lowest
# cap of the mean's window (its rapid at 1e4 reaches 168 mm/s: the mean's)
@pytest.mark.parametrize("plan,reach", [("path", 0.9), ("path-mean", 0.8)])
@pytest.mark.parametrize("jerk", [1e4, 1e5])
@pytest.mark.parametrize("make", [two_feeds, rapids])
def test_each_block_at_its_own_feed(tmp_path, make, jerk, plan, reach):
    prog, trace = tmp_path / f"{make.__name__}.ngc", tmp_path / "t.csv"
    segs = make(prog)
    s = run(prog, jerk, trace, plan)
    fastest = {}  # each feed's fastest step wholly inside its blocks
    for v, own in steps(trace, segs):
        cap = min(segs[i][2] for i in own)
        assert v <= cap * (1 + TOL), (v, cap, sorted(own))
        feeds = {segs[i][2] for i in own}
        if len(feeds) == 1:
            fastest[cap] = max(fastest.get(cap, 0.0), v)
    for f in {f for _, _, f in segs}:
        assert fastest[f] >= reach * f, (f, fastest)  # the cap is used, not only kept
    assert s["max_speed_mm_s"] <= 200 * (1 + TOL)


def test_auto_considers_path(tmp_path):
    """--jerk-plan auto runs path as a candidate on a program of several
    feeds (it refused it before, as path did); the one it takes is the
    soonest of the three."""
    prog = tmp_path / "two.ngc"
    two_feeds(prog)
    times = {}
    for plan in ("mean", "path", "path-mean"):
        p = subprocess.run([str(BUILD / "mlip-sim"), "-q", "--strategy", "smooth", *SETTINGS,
                            "--jerk", "1e4", "--jerk-plan", plan, "--summary", "-", str(prog)],
                           capture_output=True, text=True, timeout=600)
        assert p.returncode == 0, (plan, p.stderr[-2000:])
        times[plan] = json.loads(p.stdout)["total_time_s"]
    p = subprocess.run([str(BUILD / "mlip-sim"), "-q", "--strategy", "smooth", *SETTINGS,
                        "--jerk", "1e4", "--jerk-plan", "auto", "--summary", "-", str(prog)],
                       capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, p.stderr[-2000:]
    s = json.loads(p.stdout)
    assert s["auto_path"] in ("sooner", "not sooner than the mean",
                              "not sooner than path-mean"), s["auto_path"]
    assert s["total_time_s"] == min(times.values()), (s["jerk_plan"], times)
    assert times["path"] < times["mean"], times  # path is the candidate that matters here
