#!/usr/bin/env python3
"""A path-speed plan along a curve under the per-axis jerk limit: a design
study for issue 21 (not the planner; mlip's planner today uses the moving
mean of mlip/motion/jerk.h). It answers one question: on smooth curves, can a
plan that moves along the curve at a jerk-limited path speed meet the
targets (1.10x at J 1e5, 1.5x at J 1e4) where the mean cannot?

The path x(s) is the EXACT curve of tools/gen_curves.py by arc length (the
curve only, from rest to rest, no rapid). The state is (s, v, a): arc
length, path speed, path acceleration; a step of T = 1 ms applies a constant
path jerk j. Every axis k keeps, jointly (no fixed shares between the normal
and tangential terms):

    acceleration  x'_k a + x''_k v^2                          within A_k
    jerk          x'''_k v^3 + 3 x''_k v a + x'_k j           within J_k

(at the planning margin: --margin of J, 0.98 of A). A jerk is admissible
for a period only if it lies in the jerk interval throughout the step, each
checkpoint at the step's own (v, a) there (jrange, pick; --poly: the
checkpoints of src/motion/pathplan.c, the exact curve: its grid points): the
interval's ends move within a period (x''' from spline piece to piece, and
3 x'' v a with a), and a jerk at an end of the start's interval broke J by
3.6 % on the trochoid at 1e4. Each step takes the largest admissible j (of
five across [j_lo, j_hi]) whose next state still has a safe braking run:
the policy "brake toward max(a_lo, -BRAKE), release so that a is back to 0
when v reaches a crawl of 2 mm/s", each of its jerks admissible for its
whole period too, simulated until the crawl (where the rest of the curve is
slow enough) and before the end; when none is, the braking run's own first
step (that state's run was checked, period by period, so the plan never
leaves the safe states and that step exists). The end:
the crawl, then a jerk-limited stop at the curve's end exactly. The
positions are the exact curve's at the planned s (no contour error against
the curve); their third and second differences / T^3, T^2 are measured.

The path speed stays within 0.995 vmax (the samples, judged, differ a hair).

--poly NGC: the same plan along the path the product's `smooth` hands its
planner instead: the program shifted to start at the origin (its G0 left
out), through bench_smoothdump, and that polyline read as a curve by a
natural cubic spline through its points by chord length (C2: its positions'
own jerk is bounded; a cubic through each four points, as P4 of
mlip/motion/pathspeed.h reads derivatives, is only C0 where the windows
meet, and its kinks show as jerk at low speed). The positions are the
spline's at the planned s, its own parameter (chord length), so (P1)(P2)
take its derivatives by that parameter (they hold for any), not by arc
length; the trace is judged by mlip-check --jerk against the shifted
program (its original polyline: contour, acceleration, jerk, velocity), and
mlip-sim's smooth runs the same program without and with J for the ratios.

A greedy, not time-optimal: BRAKE is a knob (300 at J 1e5, 100 at J 1e4
measured best of a few), and the crawl at the end costs up to ~0.3 s. What a
real planner must add: the look-ahead over the block stream (here the whole
curve is known), the spline over a sliding window, sharp corners (the mean),
and the work outside the period (docs/algorithm.md, "The path-speed plan";
the braking-run periods simulated per planned period are printed: the
plan's cost; src/motion/pathplan.c is this plan's period in C).

--c (with --poly): the plan by its C period instead (build/bench_pathplan
--points: src/motion/pathplan.c over the same spline, its checkpoints exact;
--brake B,B2,...: several policies, a state certified by any of their runs;
default 900,300, as docs/benchmarks.md): its runs end at rest, not at a
crawl, and it plans to the curve's end at rest itself (no tail), the rest
as above; --keep keeps the temporary files (the points, for
callgrind on bench_pathplan).

--hand-over (with --c): the product's choice between the path plan and the
mean (docs/algorithm.md, "The hand-over to the mean"): the path plan runs
only if (P6) keeps every spline piece within its band (smooth's tol_mm at
either end; --band B: B mm), the faster trace between the states both share
(the program's start and end) is taken and judged by mlip-check --jerk (the
script fails otherwise), and the mean's cruise points, where a stretch could
change hands mid-program, and the stretches between them are counted.
--rests: a third candidate, the path plan at rest at breaks where (P6)
refuses a piece (rest_plan; chosen only if its trace passes mlip-check).

    bench/pathspeed.py lissajous --jerk 1e5 [--brake 300] [--margin 0.95]
    bench/pathspeed.py trochoid --jerk 1e5 --poly build/curves/trochoid.ngc [--c]
"""

import argparse
import atexit
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
import topp as tp  # noqa: E402


def shift_program(src_path, dst_path):
    """The program's feed moves, shifted so that its first point (the G0's
    target) is the origin, the machine's start; the G0 left out."""
    first = None
    with open(src_path) as fi, open(dst_path, "w") as fo:
        fo.write("G21 G90\nG1 F12000\n")
        for line in fi:
            w = line.split()
            if not w or w[0] not in ("G0", "G1") or len(w) < 2:
                continue
            xyz = {t[0]: float(t[1:]) for t in w[1:] if t[0] in "XYZ"}
            if not xyz:
                continue
            if first is None:
                first = xyz
                continue
            fo.write(
                "G1 " + " ".join(f"{k}{v - first.get(k, 0.0):.4f}" for k, v in xyz.items()) + "\n"
            )


def natural_m(P, hs):
    """The natural cubic spline through the points P by chord length (hs):
    its second derivatives M at the points (P5), by Thomas' algorithm."""
    m_seg = len(hs)
    hh = hs[:, None]
    rhs = np.zeros_like(P)
    rhs[1:-1] = 6 * ((P[2:] - P[1:-1]) / hh[1:] - (P[1:-1] - P[:-2]) / hh[:-1])
    dia = np.ones(m_seg + 1)
    dia[1:-1] = 2 * (hs[:-1] + hs[1:])
    lo_ = np.concatenate([hs[:-1], [0.0]])  # sub-diagonal (row i: h_{i-1})
    up_ = np.concatenate([[0.0], hs[1:]])  # super-diagonal (row i: h_i)
    cp = np.zeros(m_seg + 1)
    dp = np.zeros_like(P)
    cp[0], dp[0] = 0.0, 0.0
    for i in range(1, m_seg + 1):  # Thomas; rows 0 and m_seg: M = 0
        sub = lo_[i - 1] if i < m_seg else 0.0
        den = dia[i] - sub * cp[i - 1]
        cp[i] = (up_[i] if i < m_seg else 0.0) / den
        dp[i] = (rhs[i] - sub * dp[i - 1]) / den
    M = np.zeros_like(P)
    for i in range(m_seg - 1, 0, -1):
        M[i] = dp[i] - cp[i] * M[i + 1]
    return M


ap = argparse.ArgumentParser(description="A path-speed plan under a per-axis jerk limit")
ap.add_argument("curve")
ap.add_argument("--jerk", type=float, required=True)
ap.add_argument("--margin", type=float, default=0.95, help="share of J planned")
ap.add_argument(
    "--brake",
    default=None,
    help="the braking policy's deceleration (300); --c: B[,B2...], a state certified by"
    " any of their runs (900,300; the model takes the first)",
)
ap.add_argument(
    "--poly", metavar="NGC", help="plan along smooth's output for this program (see above)"
)
ap.add_argument(
    "--c",
    action="store_true",
    help="with --poly: plan with the C period (build/bench_pathplan, src/motion/pathplan.c)",
)
ap.add_argument("--keep", action="store_true", help="with --poly: keep the temporary files")
ap.add_argument(
    "--hand-over",
    action="store_true",
    help="with --c: the product's choice between the path plan and the mean (see above)",
)
ap.add_argument(
    "--rests",
    action="store_true",
    help="--hand-over: also the path plan broken at the pieces (P6) refuses, at rest there",
)
ap.add_argument(
    "--band",
    type=float,
    default=None,
    help="--hand-over: the (P6) bound a piece may stray from its chord, mm"
    " (default: smooth's tol_mm at either end of the piece, less 1e-6 mm)",
)
ap.add_argument(
    "--build", default=os.path.join(ROOT, "build"), help="where bench_smoothdump and mlip-check are"
)
args = ap.parse_args()
if args.c and not args.poly:
    ap.error("--c plans along smooth's output: give --poly")
if args.hand_over and not args.c:
    ap.error("--hand-over chooses between the C plan and the mean: give --c")
if args.rests and not args.hand_over:
    ap.error("--rests is a candidate of --hand-over")
name = args.curve
J = args.jerk * args.margin
A = 1000.0
Aplan = 0.98 * A
vmax = 200.0
T = 1e-3
VC = 2.0
BRAKES = [float(b) for b in (args.brake or ("900,300" if args.c else "300")).split(",")]
ABR = BRAKES[0]
if args.poly:
    # smooth's output for the program shifted to start at the origin (its G0
    # left out), read as a curve by (P4): positions and derivatives of the
    # cubic through the four points around each segment, by chord length
    tmp = tempfile.mkdtemp(prefix="pathspeed-")
    if args.keep:
        print(f"kept: {tmp} (shifted.ngc, points.csv with --c, trace.csv)")
    else:
        atexit.register(shutil.rmtree, tmp, True)  # the shifted program and the trace
    prog = os.path.join(tmp, "shifted.ngc")
    shift_program(args.poly, prog)
    csv = subprocess.run(
        [os.path.join(args.build, "bench_smoothdump"), prog],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    dump = np.loadtxt(csv.splitlines(), delimiter=",", ndmin=2)
    pts, TOL = dump[:, :-1], dump[:, -1]  # TOL: each point's tol_mm (smooth.h)
    n_ax = pts.shape[1]
    hs = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    pts, TOL = pts[np.concatenate([[True], hs > 1e-9])], TOL[np.concatenate([[True], hs > 1e-9])]
    hs = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    m_seg = len(hs)
    cum = np.concatenate([[0.0], np.cumsum(hs)])
    L = float(cum[-1])
    # a natural cubic spline through the points by chord length: C2, so
    # that the positions' own jerk is bounded (a cubic through each four
    # points, as P4 reads derivatives, is only C0 where the windows meet)
    hh = hs[:, None]
    M = natural_m(pts, hs)
    bb = (pts[1:] - pts[:-1]) / hh - hh * (2 * M[:-1] + M[1:]) / 6

    def cubic(s):
        s = np.clip(np.asarray(s, float), 0.0, L)
        j = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, m_seg - 1)
        u = (s - cum[j])[:, None]
        dm = (M[j + 1] - M[j]) / hh[j]
        x = pts[j] + bb[j] * u + M[j] * u * u / 2 + dm * u**3 / 6
        return x, bb[j] + M[j] * u + dm * u * u / 2, M[j] + dm * u, dm

    def positions(s_arr):
        return cubic(s_arr)[0]

    ds = 0.005
    n = int(math.ceil(L / ds)) + 1
    sg = np.linspace(0.0, L, n)
    _, x1, x2, x3 = cubic(sg)
    # (P1)(P2) hold for any parameter: the plan advances the spline's own
    # (chord length), so its derivatives by it, unconverted (converted by
    # P4 they are by arc length, which the positions are not evaluated at)
    d1, d2, d3 = x1, x2, x3 * np.ones_like(x1)
else:
    # the exact curve by arc length, as topp.py's TOPP reads it
    ds = 0.005
    f, n_ax, tt, s_all, sg, _, d1, d2 = tp.arc_frame(name, ds)
    L, n = float(s_all[-1]), len(sg)
    d3 = np.gradient(d2, sg, axis=0)

    def positions(s_arr):
        return np.array(f(np.interp(s_arr, s_all, tt), np))[:n_ax].T


D1, D2, D3 = d1.tolist(), d2.tolist(), d3.tolist()
KNOTS = cum[1:-1] if args.poly else None  # the spline's inner knots
# the same as arrays, for a period's many grid points at once (jrange)
D2a, D3a = np.asarray(d2, float), np.asarray(d3, float) * np.ones_like(d1)
ZEROa = np.abs(d1) < 1e-9
P1a = np.where(ZEROa, 1.0, d1)
NIDX = np.arange(n, dtype=float)


def ix(s):
    return min(max(int(s / ds + 0.5), 0), n - 1)


def interval(ps, cs, lim, lo=-1e18, hi=1e18):
    """The x with |p x + c| <= lim for every axis (p, c per axis), intersected
    into [lo, hi]: (P1) with x = a, (P2) with x = j (intersect() in
    src/motion/pathspeed.c). An axis the path does not move along allows
    every x or none; (1, -1) when none does."""
    for p, c in zip(ps, cs, strict=True):
        if abs(p) < 1e-9:
            if abs(c) > lim:
                return 1.0, -1.0
            continue
        x1, x2 = (-lim - c) / p, (lim - c) / p
        if x1 > x2:
            x1, x2 = x2, x1
        lo, hi = max(lo, x1), min(hi, x2)
    return lo, hi


def alim(s, v):
    """(P1): the path accelerations every axis allows at s, at speed v"""
    i = ix(s)
    return interval(D1[i], [q * v * v for q in D2[i]], Aplan)


def jlim_at(i, v, a, lo=-1e18, hi=1e18):
    """(P2): the path jerks every axis allows at grid point i, at speed v
    and path acceleration a, intersected into [lo, hi]"""
    cs = [r * v**3 + 3 * q * v * a for q, r in zip(D2[i], D3[i], strict=True)]
    return interval(D1[i], cs, J, lo, hi)


def jlim(s, v, a):
    return jlim_at(ix(s), v, a)


def jrange(s, v, a, j):
    """The path jerks every axis allows throughout the step of constant jerk
    j from (s, v, a): the interval a jerk must lie in for the whole period.
    On a spline read from points x''' changes from piece to piece, and the
    bounds of (P2) move with v and a within the period: an end of the
    interval at the period's start can be outside it at the period's end.
    --poly: at the checkpoints of src/motion/pathplan.c (Q2): the step's
    start and end, every knot it crosses on both sides, the middle of each
    stretch between, the spline's exact derivatives there (grid points
    rounded to the nearest missed a knot within ds / 2 of the step's end at
    low speed: 1.004 J at the spiral's start at 1e4); each at the step's
    state there (the time at a knot by linear interpolation). The exact
    curve: every grid point the step crosses."""
    s1 = step(s, v, a, j)[0]
    if KNOTS is not None:
        kn = KNOTS[np.searchsorted(KNOTS, s, side="right") : np.searchsorted(KNOTS, s1)]
        hk = T * (kn - s) / (s1 - s) if len(kn) else kn
        hp = np.concatenate([[0.0], hk, [T]])
        hm = 0.5 * (hp[:-1] + hp[1:])
        e = 1e-12 * (1.0 + kn)
        H = np.concatenate([[0.0], hm, hk, hk, [T]])
        S = np.concatenate([[s], step(s, v, a, j, hm)[0], kn - e, kn + e, [s1]])
        _, x1, x2, x3 = cubic(S)
        vi, ai = v + a * H + j * H * H / 2, a + j * H
        c = x3 * (vi**3)[:, None] + 3 * x2 * (vi * ai)[:, None]
        z = np.abs(x1) < 1e-9
        if z.any() and bool((np.abs(c[z]) > J).any()):
            return 1.0, -1.0
        p = np.where(z, 1.0, x1)
        j1, j2 = (-J - c) / p, (J - c) / p
        lo_, hi_ = np.where(z, -1e18, np.minimum(j1, j2)), np.where(z, 1e18, np.maximum(j1, j2))
        return max(float(lo_.max()), -1e18), min(float(hi_.min()), 1e18)
    i0, i1 = ix(s), ix(s1)
    if i1 <= i0:  # within one grid point (or back): its start and end state
        lo, hi = jlim_at(i0, v, a)
        return jlim_at(i0, v + a * T + j * T * T / 2, a + j * T, lo, hi)
    if i1 - i0 < 6:  # a few points: the loop is the faster
        lo, hi = -1e18, 1e18
        for i in range(i0, i1 + 1):
            h = T * (i - i0) / (i1 - i0)
            lo, hi = jlim_at(i, v + a * h + j * h * h / 2, a + j * h, lo, hi)
            if lo > hi:
                break
        return lo, hi
    # the same intersection over the points at once (numpy)
    h = T * (NIDX[: i1 - i0 + 1]) / (i1 - i0)
    vi, ai = v + a * h + j * h * h / 2, a + j * h
    c = D3a[i0 : i1 + 1] * (vi**3)[:, None] + 3 * D2a[i0 : i1 + 1] * (vi * ai)[:, None]
    z = ZEROa[i0 : i1 + 1]
    if z.any() and bool((np.abs(c[z]) > J).any()):
        return 1.0, -1.0
    p = P1a[i0 : i1 + 1]
    j1, j2 = (-J - c) / p, (J - c) / p
    lo_, hi_ = np.where(z, -1e18, np.minimum(j1, j2)), np.where(z, 1e18, np.maximum(j1, j2))
    return max(float(lo_.max()), -1e18), min(float(hi_.min()), 1e18)


def pick(s, v, a, jt):
    """The jerk nearest jt that stays inside the limits for the whole period
    (jrange of the step it makes), or None. The interval depends on j itself
    (through v and a within the period, weakly: 3 x'' v T per unit of j), so
    clamp jt into the interval of the last choice's step, a few times, and
    accept only a j inside the interval of its own step."""
    jl, jh = jlim(s, v, a)
    if jl > jh:
        return None
    j = min(max(jt, jl), jh)
    for _ in range(4):
        lo, hi = jrange(s, v, a, j)
        if lo > hi:
            return None
        if lo <= j <= hi:
            return j
        j = min(max(jt, lo), hi)
    return None


def step(s, v, a, j, h=T):
    return s + v * h + a * h * h / 2 + j * h**3 / 6, v + a * h + j * h * h / 2, a + j * h


def ok(s, v, a):
    if v < 0 or v > 0.995 * vmax or s > L + 1e-9:  # the samples, not v, are judged
        return False
    lo, hi = alim(s, v)
    if not (lo - 1e-9 <= a <= hi + 1e-9):
        return False
    jl, jh = jlim(s, v, a)
    return jl <= jh


def brake_j(s, v, a):
    """The braking policy: as hard as the limits allow, toward the lowest a;
    its jerk inside the limits for the whole period (pick), or None when no
    jerk is (the state is then not safe)."""
    jl, jh = jlim(s, v, a)
    if jl > jh:
        return None
    alo, ahi = alim(s, v)
    target = max(alo, -ABR) if v > VC else 0.0
    if v <= VC:  # crawl: release toward zero acceleration
        return pick(s, v, a, (0.0 - a) / T)
    if a < 0 and jh > 0 and v - VC <= a * a / (2 * 0.8 * jh):
        return pick(s, v, a, (0.0 - a) / T)  # release: a back to 0 as v reaches VC
    j = jl
    if a + j * T < target:
        j = (target - a) / T
    return pick(s, v, a, j)


WORK = [0]  # braking-run periods simulated (the plan's cost: the C planner's)


def safe(s, v, a):
    for _ in range(3000):
        WORK[0] += 1
        if not ok(s, v, a):
            return False
        if v <= VC and abs(a) < 1.0:
            # crawl: at VC the rest of the path is slow enough; the end: room to stop
            return L - s >= v * 0.05
        # the path's end: stop before it (the crawl's own small stop)
        if L - s < v * v / (2 * 200.0) + v * 0.05:
            return False
        jb = brake_j(s, v, a)
        if jb is None:
            return False
        s, v, a = step(s, v, a, jb)
    return False


def tail(s, v, a, L):
    """The path positions after a plan that ends at (s, v, a) short of L:
    the end below, sampled every T (none when it is at L or at rest)."""
    if not (L - s > 1e-9 and v > 0):
        return []
    jr = 0.5 * J
    xs = []
    ta = abs(a) / jr
    j0 = -jr if a > 0 else jr
    va = v + a * ta + j0 * ta * ta / 2
    sa = s + v * ta + a * ta * ta / 2 + j0 * ta**3 / 6
    tb = 2 * math.sqrt(va / jr)
    db = va * tb / 2
    tc = ta + max(L - sa - db, 0.0) / va
    tt_ = 0.0
    s0 = sa - va * ta  # the cruise's line, extended back to the tail's start
    v0 = va
    while True:
        tt_ += T
        if tt_ <= ta:
            x = s + v * tt_ + a * tt_ * tt_ / 2 + j0 * tt_**3 / 6
        elif tt_ <= tc:
            x = s0 + v0 * tt_
        elif tt_ <= tc + tb:
            u = tt_ - tc
            h = tb / 2
            if u <= h:
                x = s0 + v0 * tc + v0 * u - jr * u**3 / 6
            else:
                xm = s0 + v0 * tc + v0 * h - jr * h**3 / 6
                vm = v0 - jr * h * h / 2
                w = u - h
                x = xm + vm * w - jr * h * w * w / 2 + jr * w**3 / 6
        else:
            x = L
            xs.append(x)
            break
        xs.append(min(x, L))
    return xs + [L] * 3


s = v = a = 0.0
out = [0.0]
PER, sum_w = [], 0  # braking-run periods simulated for each planned period
GATE = True  # --hand-over: may the path plan run on this stretch (P6)?
if args.hand_over:
    # (P6), mlip_path_piece_sag: a piece strays from its chord by at most
    # h^2 / 8 max(|M_i|, |M_i+1|); the path plan may run only on a stretch
    # whose every piece keeps that within the band (the spline through a
    # sharp vertex overshoots: 6.4 mm on the random zigzag)
    # The band of a piece (a segment of smooth's output): what smooth left
    # of its budget, tol_mm at either end (smooth.h: tol = budget - the
    # largest deviation of the two segments its corner touches, so a point
    # within tol of the chord is within the budget of the original
    # polyline); --band B: a fixed B mm instead
    Mn = np.linalg.norm(M, axis=1)
    SAG = hs * hs / 8.0 * np.maximum(Mn[:-1], Mn[1:])
    BAND = np.maximum(TOL[:-1], TOL[1:]) - 1e-6 if args.band is None else args.band
    N_OVER = int(np.sum(SAG > BAND))
    GATE = N_OVER == 0
    print(
        f"(P6): {N_OVER} of {m_seg} pieces over"
        f" {'their tol_mm' if args.band is None else format(args.band, 'g') + ' mm'}"
        f" (largest {SAG.max():.3g} mm): the path plan"
        f" {'may run' if GATE else 'may not run'} from rest to rest"
    )
if args.c and GATE:
    # the same plan by the C period over the same spline (its checkpoints:
    # the knots' times by bisection, not by linear interpolation); the end
    # stop, the samples and the checks below as for the model
    ptsf = os.path.join(tmp, "points.csv")
    np.savetxt(ptsf, pts, delimiter=",", fmt="%.17g")
    plan = os.path.join(tmp, "plan.csv")
    r = subprocess.run(
        [os.path.join(args.build, "bench_pathplan"), f"{J!r}", "--points", ptsf]
        + ["--brake", ",".join(f"{b!r}" for b in BRAKES), "--out", plan],
        check=True,
        capture_output=True,
        text=True,
    )
    res = json.loads(r.stdout)
    rows = np.loadtxt(plan, delimiter=",", ndmin=2)
    out += [min(float(x), L) for x in rows[:, 0]]
    PER = [int(x) for x in rows[:, 1]]
    s, v, a = res["s"], res["v"], res["a"]
    print(f"C plan: length {res['length']:.6f} (model {L:.6f}), {res['periods']} periods")
while (
    not args.c and L - s > 1e-3 and not (v <= VC and abs(a) < 1.0 and L - s < 1.0 and len(out) > 10)
):
    jl, jh = jlim(s, v, a)
    moved = False
    if jl <= jh:
        for w in (1.0, 0.75, 0.5, 0.25, 0.0):
            # j holds for the whole period (pick: within the limits at every
            # grid point it crosses, at the state there), and the next state
            # has a braking run each of whose periods is inside them too
            j = pick(s, v, a, jl + w * (jh - jl))
            if j is None:
                break
            s2, v2, a2 = step(s, v, a, j)
            if safe(s2, v2, a2):
                moved = True
                break
    if not moved:
        # the braking run's first step: this state's run was checked, period
        # by period, when the state was chosen, so the plan never leaves the
        # safe states and this jerk exists
        jb = brake_j(s, v, a)
        if jb is None:
            raise SystemExit(f"no braking jerk at s={s} v={v} a={a}: the invariant broke")
        s2, v2, a2 = step(s, v, a, jb)
        if v2 < 0:
            s2, v2, a2 = s, 0.0, 0.0
    if not moved and v2 <= 0.0 and L - s2 > 1.0:
        raise SystemExit(f"stopped at s={s2} of {L}")
    s, v, a = s2, v2, a2
    out.append(min(s, L))
    PER.append(WORK[0] - sum_w)
    sum_w = WORK[0]
    if len(out) > 200000:
        raise SystemExit(f"too long at s={s}")
# the end: the model cruises at the crawl speed, then stops at L exactly by
# a jerk-limited tail (a triangle of jerk: v = jr t^2 ... over 2 sqrt(v /
# jr), distance v sqrt(v / jr)); --c: the C plan ends at rest at L itself
# (bench_pathplan fails otherwise), held there a few samples
out += [L] * 3 if args.c else tail(s, v, a, L)


def cruise_points(X, taps):
    """The samples of the mean's trace X (rows: positions) that a path plan
    could take over at or hand back to: the trace moves on a line at one
    speed, acceleration 0, for taps - 1 periods either side (there the
    mean's output is the plan's cruise delayed, J1, so both traces share
    position, velocity, zero acceleration and zero jerk). A list of
    (first, last) sample ranges of such points."""
    w = taps - 1
    acc = np.abs(np.diff(X, 2, axis=0)).max(axis=1) / T**2  # at sample i + 1
    spd = np.linalg.norm(np.diff(X, axis=0), axis=1) / T
    flat = np.concatenate([[False], acc < 1e-3, [False]])  # 1e-3 mm/s^2: the rounding's
    flat &= np.concatenate([[False], spd > VC]) & np.concatenate([spd > VC, [False]])
    # a point needs flat samples w either side: a run of flat samples
    # [r0, r1] gives the points [r0 + w, r1 - w]
    runs, i, n_ = [], 0, len(flat)
    while i < n_:
        if flat[i]:
            k = i
            while k + 1 < n_ and flat[k + 1]:
                k += 1
            if k - i >= 2 * w:
                runs.append((i + w, k - w))
            i = k + 1
        else:
            i += 1
    return runs


def stretches(Xm, runs):
    """The stretches between consecutive shared states (the start, the
    middle of each cruise run, the end) and whether (P6) lets the path plan
    run on each: a list of (mean's samples, accepted). A cruise point is
    located on smooth's polyline at the first segment, at or after the
    last one found, within 1e-3 mm of it (the path may come back near
    itself)."""
    over = SAG > BAND
    bnd, prev = [(0, 0)], 0
    for a, b in runs:
        c = (a + b) // 2
        p0, d = pts[prev:-1], np.diff(pts[prev:], axis=0)
        u = np.clip(
            np.sum((Xm[c] - p0) * d, axis=1) / np.maximum(np.sum(d * d, axis=1), 1e-30), 0, 1
        )
        near = np.nonzero(np.linalg.norm(p0 + u[:, None] * d - Xm[c], axis=1) < 1e-3)[0]
        if len(near):
            prev = prev + int(near[0])
            bnd.append((prev, c))
    bnd.append((m_seg, len(Xm) - 1))
    return [
        (t1 - t0, not over[j0:j1].any())
        for (j0, t0), (j1, t1) in zip(bnd[:-1], bnd[1:], strict=True)
    ]


def rest_plan(prog, mach):
    """A third candidate from rest to rest: the path plan along smooth's
    output broken into natural splines at stations where (P6) refuses a
    piece (the largest turn of each run of refused pieces, one round after
    another until every piece of every part is within its band), each part
    planned by the C period from rest to rest, so the machine stops at each
    break (a rest: the parts share it). Returns (trace, time, breaks,
    mlip-check's exit) or None when no set of breaks was found."""
    n_pts = len(pts)
    d_ = np.diff(pts, axis=0)
    u_ = d_ / np.linalg.norm(d_, axis=1)[:, None]
    turn = np.zeros(n_pts)
    turn[1:-1] = np.arccos(np.clip(np.sum(u_[1:] * u_[:-1], axis=1), -1.0, 1.0))
    breaks = {0, n_pts - 1}
    for _ in range(40):
        bs, more = sorted(breaks), []
        for a0, b0 in zip(bs[:-1], bs[1:], strict=True):
            h_ = np.linalg.norm(np.diff(pts[a0 : b0 + 1], axis=0), axis=1)
            mn = np.linalg.norm(natural_m(pts[a0 : b0 + 1], h_), axis=1)
            sag = h_ * h_ / 8.0 * np.maximum(mn[:-1], mn[1:])
            band = np.maximum(TOL[a0:b0], TOL[a0 + 1 : b0 + 1]) - 1e-6
            bad = np.nonzero(sag > (band if args.band is None else args.band))[0]
            i = 0
            while i < len(bad):
                k = i
                while k + 1 < len(bad) and bad[k + 1] - bad[k] <= 1:
                    k += 1
                # the stations of the run, inside the part
                cand = range(max(a0 + bad[i], a0 + 1), min(a0 + bad[k] + 1, b0 - 1) + 1)
                if cand:
                    more.append(max(cand, key=lambda c: turn[c]))
                i = k + 1
        if not more:
            break
        breaks |= set(more)
    else:
        print("rests: pieces still refused after 40 rounds of breaks")
        return None
    bs = sorted(breaks)
    X = [pts[:1]]
    for a0, b0 in zip(bs[:-1], bs[1:], strict=True):
        P_ = pts[a0 : b0 + 1]
        h_ = np.linalg.norm(np.diff(P_, axis=0), axis=1)
        M_ = natural_m(P_, h_)
        c_ = np.concatenate([[0.0], np.cumsum(h_)])
        L_ = float(c_[-1])
        f_ = os.path.join(tmp, "part.csv")
        np.savetxt(f_, P_, delimiter=",", fmt="%.17g")
        r_ = subprocess.run(
            [os.path.join(args.build, "bench_pathplan"), f"{J!r}", "--points", f_]
            + ["--brake", ",".join(f"{b!r}" for b in BRAKES), "--out", f_ + ".out"],
            capture_output=True,
            text=True,
        )
        if r_.returncode != 0:
            print(f"rests: the part of stations {a0}-{b0} not planned: {r_.stderr.strip()}")
            return None
        res_ = json.loads(r_.stdout)
        rows_ = np.loadtxt(f_ + ".out", delimiter=",", ndmin=2)
        sq = [min(float(x), L_) for x in rows_.reshape(-1, 2)[:, 0]]
        sq += [L_] * 3  # the C plan ends at rest at L_ (bench_pathplan)
        sq = np.clip(np.array(sq), 0.0, L_)
        j_ = np.clip(np.searchsorted(c_, sq, side="right") - 1, 0, len(h_) - 1)
        w_ = (sq - c_[j_])[:, None]
        hj = h_[j_][:, None]
        b_ = (P_[1:] - P_[:-1]) / h_[:, None] - h_[:, None] * (2 * M_[:-1] + M_[1:]) / 6
        X.append(
            P_[j_] + b_[j_] * w_ + M_[j_] * w_ * w_ / 2 + (M_[j_ + 1] - M_[j_]) / hj * w_**3 / 6
        )
    Xa = np.concatenate(X)
    path = os.path.join(tmp, "rests.csv")
    with open(path, "w") as fh:
        for i, row in enumerate(Xa):
            fh.write(f"{i * T:.6f}," + ",".join(f"{x:.9f}" for x in row) + "\n")
    c = subprocess.run(
        [os.path.join(args.build, "mlip-check"), *mach, "--json", "-", prog, path],
        capture_output=True,
        text=True,
    )
    return path, len(Xa) * T, len(bs) - 2, c.returncode


def hand_over(plan_trace, mean_trace, prog, mach, plan_ok):
    """The product's choice (docs/algorithm.md, "The hand-over to the
    mean"): between shared states the faster of the path plan (only where
    (P6) lets it run) and the mean; so never slower than the mean. The
    shared states used here are the program's start and end (rests); the
    mean's cruise points, where a stretch could change hands mid-program,
    are counted (the C plan does not yet start or end at a cruise)."""
    Xm = np.loadtxt(mean_trace, delimiter=",", ndmin=2, comments=("t", "#"))[:, 1:]
    t_mean = len(Xm) * T
    jmax = max(float(v) for v in mach[mach.index("--jerk") + 1].split(","))
    amax = np.abs(np.diff(Xm, 2, axis=0)).max() / T**2
    taps = min(int(round(2 * amax / (jmax * T))) + 2, 63)  # A' = J m T / 2 (J4), and a margin
    runs = cruise_points(Xm, taps)
    st = stretches(Xm, runs)
    acc_ = [n for n, ok in st if ok]
    t_plan = len(ss) * T if GATE else math.inf
    take_plan = GATE and plan_ok and t_plan < t_mean
    chosen = plan_trace if take_plan else mean_trace
    t_take = t_plan if take_plan else t_mean
    if args.rests and not GATE:
        rp = rest_plan(prog, mach)
        if rp is not None:  # else it said why
            print(
                f"rests: the path plan at rest at {rp[2]} breaks: {rp[1]:.3f} s,"
                f" mlip-check --jerk exit {rp[3]}"
            )
            if rp[3] == 0 and rp[1] < t_take:
                chosen, t_take, take_plan = rp[0], rp[1], True
    which = "mean" if chosen == mean_trace else "path plan" if chosen == plan_trace else "rests"
    chk2 = subprocess.run(
        [os.path.join(args.build, "mlip-check"), *mach, "--json", "-", prog, chosen],
        capture_output=True,
        text=True,
    )
    ok_ = chk2.returncode == 0
    try:
        cj = json.loads(chk2.stdout)
        what = (
            f"jerk/J {max(cj['max_axis_jerk']) / jmax:.3f},"
            f" contour {cj['max_contour_error_mm']:.5f} mm"
        )
    except (ValueError, KeyError, TypeError):
        what = chk2.stdout.strip()[:200]
    print(
        f"hand-over: the mean {t_mean:.3f} s, the path plan "
        + (f"{t_plan:.3f} s{'' if plan_ok else ' (failed mlip-check)'}" if GATE else "not run (P6)")
        + f"; the mean's cruise points (window {taps}): {len(runs)} runs,"
        f" {sum(b - a + 1 for a, b in runs)} samples; stretches between shared states"
        f" {len(st)}, (P6) accepts {len(acc_)} ({sum(acc_) * T:.3f} s of the mean's);"
        f" chosen: {which}, {t_take:.3f} s"
        f" ({t_take / t_mean:.3f}x of the mean);"
        f" mlip-check --jerk: exit {chk2.returncode} ({'pass' if ok_ else 'FAIL'}; {what})"
    )
    if not ok_:
        raise SystemExit("hand-over: the chosen trace breaks a limit")


Jr = args.jerk
ss = np.array(out)
if GATE:  # planned (--hand-over: not where P6 refuses)
    P = positions(ss)
    j3 = np.abs(np.diff(P, 3, axis=0)) / T**3
    a2_ = np.abs(np.diff(P, 2, axis=0)) / T**2
    print(
        f"{name} J={Jr:g} (plan {J:g}, A {Aplan:g}): {len(ss) * T:.3f} s (curve only),"
        f" max jerk/J {j3.max() / Jr:.3f}, max accel/A {a2_.max() / A:.3f}"
    )
    w = j3.max(axis=1)
    per = np.array(PER)
    print(
        f"braking-run periods simulated a planned period: median {np.median(per):.0f},"
        f" p99 {np.percentile(per, 99):.0f}, max {per.max()}, mean {per.mean():.0f}"
    )
    print(
        f"samples above J: {int(np.sum(w > Jr))};"
        f" the worst at sample {int(np.argmax(w))} of {len(w)}"
    )
if args.poly:
    # the trace, judged by mlip-check against the shifted program (its
    # original polyline), and mlip-sim's smooth on the same program
    trace = os.path.join(tmp, "trace.csv")
    with open(trace, "w") as fh:
        for i, row in enumerate(P if GATE else []):
            fh.write(f"{i * T:.6f}," + ",".join(f"{x:.9f}" for x in row) + "\n")
    mach = [
        "--accel",
        ",".join(["1000"] * n_ax),
        "--vmax",
        "200",
        "--eps",
        "0.01",
        "--period",
        "0.001",
        "--jerk",
        f"{Jr:g}",
    ]
    if GATE:
        chk = subprocess.run(
            [os.path.join(args.build, "mlip-check"), *mach, "--json", "-", prog, trace],
            capture_output=True,
            text=True,
        )
        print(f"mlip-check --jerk {Jr:g}: exit {chk.returncode}; {chk.stdout.strip()}")
    mean_trace = os.path.join(tmp, "mean.csv")
    for jerk in (None, Jr):
        extra = ["--jerk", f"{jerk:g}"] if jerk else []
        if jerk and args.hand_over:
            extra += ["--trace", mean_trace]
        r = subprocess.run(
            [
                os.path.join(args.build, "mlip-sim"),
                "-q",
                "--strategy",
                "smooth",
                *mach[:8],
                "--feed",
                "200",
                *extra,
                "--summary",
                "-",
                prog,
            ],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        print(
            f"mlip-sim smooth {'J ' + format(jerk, 'g') if jerk else 'no J'}: "
            f"{json.loads(r)['total_time_s']:.3f} s"
        )
    if args.hand_over:
        hand_over(trace, mean_trace, prog, mach, GATE and chk.returncode == 0)
