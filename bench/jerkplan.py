#!/usr/bin/env python3
"""What a jerk-continuous plan would take on a polyline: the paper's corners
with a ramped acceleration and S-curve lines, no moving mean (a design study
for issue 21; mlip's planner today uses the mean of mlip/motion/jerk.h).

The plan's acceleration is continuous and every axis's jerk is within J_k,
so the 1 ms samples keep J too (a third difference of samples of a C2
piecewise cubic is a mean of its jerk, as a second difference is of its
acceleration), and every corner keeps the whole of eps (no E_f).

Corner (Sec. 1 of the paper, eqs. (1)-(6), (14)-(20)) with a(t) = lam phi(t)
a0, a0 = alpha e_e - beta e_s the LP vertex on the acceleration polygon at A
(Theorem 2), phi a symmetric trapezoid of height 1 and ramps r = lam rho,
rho = max_k |a0_k| / J_k (each axis ramps at J_k), length t_m = r + h:

    v_e e_e - v_s e_s = lam a0 h            (1): v_s = beta u, v_e = alpha u, u = lam h
    l_s = v_s t_m / 2, l_e = v_e t_m / 2    (5)(6): phi symmetric, unchanged
    |P - s(t_m / 2)| = lam |a0| (h^2 / 8 + r^2 / 24)    (17) with ramps

(the curve stays in the angle at P, its oblique coordinates monotone, so its
distance to the polyline is at most its distance to P there, as in (17)).
For a speed factor u the shortest corner is a triangle (h = r) while
u <= rho, then lam = 1 and h = u; (18)-(20) bound u, all monotone in it.

Line: from v0 to v1 over L, the acceleration 0 at both ends and at the peak
speed, jerk j_l = min_k J_k / |e_k|, acceleration a_l = min_k A_k / |e_k|:
a speed change dv takes dv / a + a / j (dv >= a^2 / j) or 2 sqrt(dv / j),
over (v0 + v1) / 2 times that. The look-ahead (backward from rest at the
end, then forward from rest at the start) bounds each corner's u by
bisection: every constraint is monotone in it.

    bench/jerkplan.py FILE.ngc [--accel 1000] [--jerk 1e5] [--vmax 200] [--eps 0.01]

Without --jerk the corners are the paper's and the lines trapezoids: the
figure then models mpct's plan (a check of the model: on the bench's random
zigzag 101.62 s where mlip-sim's mpct takes 98.44 s, 3 % slower).
--free-corners: the corners without the jerk limit (the paper's), the lines
with it (S-curves from and to zero acceleration at every corner): what the
lines' jerk alone costs in such a plan.
Reads G0/G1 X Y [Z] moves in absolute mm; prints the time.
"""

import argparse
import math
import re
import sys


def read_points(path, n):
    pts = [[0.0] * n]
    cur = [0.0] * n
    word = re.compile(r"([XYZ])\s*(-?[0-9.]+)")
    for line in open(path):
        line = line.split(";")[0].split("(")[0].upper()
        if not re.search(r"\bG0?[01]\b", line) and not word.search(line):
            continue
        hit = False
        for ax, val in word.findall(line):
            k = "XYZ".index(ax)
            if k < n:
                cur[k] = float(val)
                hit = True
        if hit and cur != pts[-1]:
            pts.append(list(cur))
    return pts


def unit(a, b):
    d = [y - x for x, y in zip(a, b, strict=True)]
    n = math.sqrt(sum(x * x for x in d))
    return [x / n for x in d], n


def corner_lp(es, ee, acc):
    """(alpha, beta) of the LP vertex (corner.c mlip_corner_lp), or None."""
    c = [(ee[k] + es[k]) / acc[k] for k in range(len(es))]
    d = [es[k] / acc[k] for k in range(len(es))]
    cand = [0.5, 0.0, 1.0]
    m = len(c)
    for i in range(m):
        for j in range(i + 1, m):
            if c[i] != c[j]:
                cand.append((d[i] - d[j]) / (c[i] - c[j]))
            if c[i] != -c[j]:
                cand.append((d[i] + d[j]) / (c[i] + c[j]))
    best = (math.inf, 0.5)
    for w in cand:
        if 0.0 <= w <= 1.0:
            g = max(abs(c[k] * w - d[k]) for k in range(m))
            if g < best[0] * (1 - 1e-12):
                best = (g, w)
    g, w = best
    if not g > 1e-9:
        return None
    return w / g, (1.0 - w) / g


class Corner:
    def __init__(self, es, ee, ds, de, acc, jerk, eps, vmax):
        self.turn = math.sqrt(sum((x - y) ** 2 for x, y in zip(es, ee, strict=True)))
        self.vmax = vmax
        if self.turn < 1e-9:
            self.alpha = self.beta = 1.0
            self.rho = 0.0
            self.straight = True
            self.umax = vmax
            return
        self.straight = False
        ab = corner_lp(es, ee, acc)
        self.alpha, self.beta = ab
        a0 = [self.alpha * ee[k] - self.beta * es[k] for k in range(len(es))]
        self.a0 = math.sqrt(sum(x * x for x in a0))
        self.rho = max(abs(a0[k]) / jerk[k] for k in range(len(es))) if jerk else 0.0
        self.ds, self.de = ds, de
        hi = vmax / max(self.alpha, self.beta)

        def ok(u):
            return self.dev(u) <= eps and self.ls(u) <= ds / 2 and self.le(u) <= de / 2

        lo = 0.0
        if ok(hi):
            lo = hi
        else:
            for _ in range(100):
                mid = 0.5 * (lo + hi)
                if ok(mid):
                    lo = mid
                else:
                    hi = mid
        self.umax = lo

    def tm(self, u):
        if self.straight:
            return 0.0
        if u <= self.rho:
            return 2.0 * math.sqrt(u * self.rho)
        return self.rho + u

    def dev(self, u):
        if self.rho > 0.0 and u <= self.rho:
            lam = math.sqrt(u / self.rho)
            r = lam * self.rho
            return lam * self.a0 * (r * r / 8 + r * r / 24)
        return self.a0 * (u * u / 8 + self.rho * self.rho / 24)

    def vs(self, u):
        return self.beta * u

    def ve(self, u):
        return self.alpha * u

    def ls(self, u):
        return self.vs(u) * self.tm(u) / 2

    def le(self, u):
        return self.ve(u) * self.tm(u) / 2


def dv_time(dv, a, j):
    if j is None:
        return dv / a
    if dv >= a * a / j:
        return dv / a + a / j
    return 2.0 * math.sqrt(dv / j)


def dv_dist(v0, v1, a, j):
    return 0.5 * (v0 + v1) * dv_time(abs(v1 - v0), a, j)


def line_time(v0, v1, L, a, j, vmax):
    def f(vp):
        return dv_dist(v0, vp, a, j) + dv_dist(vp, v1, a, j)

    if f(vmax) <= L:
        return dv_time(vmax - v0, a, j) + dv_time(vmax - v1, a, j) + (L - f(vmax)) / vmax
    lo, hi = max(v0, v1), vmax
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if f(mid) <= L:
            lo = mid
        else:
            hi = mid
    vp = lo
    return dv_time(vp - v0, a, j) + dv_time(vp - v1, a, j) + max(L - f(vp), 0.0) / max(vp, 1e-9)


def plan(pts, acc, jerk, eps, vmax, corner_jerk=True):
    n = len(acc)
    segs = []
    for i in range(1, len(pts)):
        e, d = unit(pts[i - 1], pts[i])
        a = min(acc[k] / abs(e[k]) for k in range(n) if e[k] != 0.0)
        j = min(jerk[k] / abs(e[k]) for k in range(n) if e[k] != 0.0) if jerk else None
        segs.append((e, d, a, j))
    corners = [None]  # corner i joins segment i-1 and i (0: the start, at rest)
    for i in range(1, len(segs)):
        corners.append(
            Corner(
                segs[i - 1][0],
                segs[i][0],
                segs[i - 1][1],
                segs[i][1],
                acc,
                jerk if corner_jerk else None,
                eps,
                vmax,
            )
        )
    u = [0.0] + [c.umax for c in corners[1:]] + [0.0]

    def v_in(i):  # speed entering segment i (leaving corner i)
        return 0.0 if i == 0 else corners[i].ve(u[i])

    def v_out(i):  # speed leaving segment i (entering corner i + 1)
        return 0.0 if i + 1 >= len(corners) else corners[i + 1].vs(u[i + 1])

    def room(i):
        lin = 0.0 if i == 0 else corners[i].le(u[i])
        lout = 0.0 if i + 1 >= len(corners) else corners[i + 1].ls(u[i + 1])
        return segs[i][1] - lin - lout

    def fits(i):
        return dv_dist(v_in(i), v_out(i), segs[i][2], segs[i][3]) <= room(i) + 1e-12

    # backward: corner i from segment i (to corner i + 1, fixed)
    for i in range(len(segs) - 1, 0, -1):
        if fits(i):
            continue
        lo, hi = 0.0, u[i]
        for _ in range(80):
            u[i] = 0.5 * (lo + hi)
            if fits(i):
                lo = u[i]
            else:
                hi = u[i]
        u[i] = lo
    # forward: corner i + 1 from segment i (from corner i, fixed)
    for i in range(0, len(segs) - 1):
        if fits(i):
            continue
        lo, hi = 0.0, u[i + 1]
        for _ in range(80):
            u[i + 1] = 0.5 * (lo + hi)
            if fits(i):
                lo = u[i + 1]
            else:
                hi = u[i + 1]
        u[i + 1] = lo
    t = 0.0
    for i, (_e, _d, a, j) in enumerate(segs):
        t += line_time(v_in(i), v_out(i), max(room(i), 0.0), a, j, vmax)
        if i + 1 < len(corners):
            t += corners[i + 1].tm(u[i + 1])
    return t


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("file")
    ap.add_argument("--axes", type=int, default=2)
    ap.add_argument("--accel", type=float, default=1000.0)
    ap.add_argument("--jerk", type=float, default=None)
    ap.add_argument("--vmax", type=float, default=200.0)
    ap.add_argument("--eps", type=float, default=0.01)
    ap.add_argument(
        "--free-corners",
        action="store_true",
        help="corners without the jerk limit (the paper's), lines with it: what the"
        " lines' S-curves alone cost",
    )
    a = ap.parse_args()
    pts = read_points(a.file, a.axes)
    acc = [a.accel] * a.axes
    jerk = [a.jerk] * a.axes if a.jerk else None
    print(f"{plan(pts, acc, jerk, a.eps, a.vmax, not a.free_corners):.3f}")


if __name__ == "__main__":
    sys.exit(main())
