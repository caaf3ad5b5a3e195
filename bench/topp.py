#!/usr/bin/env python3
"""The time-optimal ceiling: the shortest time any planner could take along a
path under the bench's limits (per-axis |a_k| <= A_k, speed <= vmax), from
rest to rest. Classic TOPP on a fine arc-length grid, in the discretisation
of TOPP-RA (Pham & Pham 2018): state x = v^2, control u = s'' constant on
each step (x_{i+1} = x_i + 2 h_i u_i), the per-axis constraint at grid point i

    |x'_k(s_i) u_i + x''_k(s_i) x_i| <= A_k          (tangential + normal)

so the limit curve, the backward pass (largest x from which the end can still
be reached: the controllable sets) and the forward pass (largest u) are 1-D
problems solved exactly. Time = sum 2 h_i / (v_i + v_{i+1}) (exact for a
constant u). The result converges from below in h (a constraint is only
enforced at the grid points); `--check` shows the convergence.

Paths:
  curve NAME       the EXACT parametric curve of tools/gen_curves.py (not the
                   rounded polyline it writes), by its arc length;
  poly FILE.csv    a polyline (bench_smoothdump's output: the path `smooth`
                   hands the planner) read as a curve: the tangent at a vertex
                   is the mean of its two segments' directions, its curvature
                   vector (e_i - e_{i-1}) / min(h_{i-1}, h_i), both
                   interpolated linearly at grid points every <= --ds mm
                   between vertices. A model for finely sampled smooth
                   paths: a sharp vertex becomes an arc of radius ~h /
                   theta, tighter than a corner within eps may be, so on
                   CAM output with sharp corners (MB-2.3) it is no ceiling.

The rapid: every generated file starts with a G0 from the machine's start
(the origin) to the curve's first point, which the bench runs as a feed move
(mlip-sim --feed). It is counted here as a straight move from rest to rest
(bang-bang under the line's limit min_k A_k / |e_k| and vmax) plus the curve
from rest to rest: the same for every path, and within ~10 ms of what a
planner blending the corner at the curve's start (within eps) could gain.

The jerk limit (--jerk J, every axis; mlip/motion/jerk.h): a quasi-static
bound, the time along the exact curve at the largest speed its own
acceleration and jerk allow at each point, transitions ignored (no
tangential acceleration anywhere): at a steady speed v, x'' = K v^2 and
x''' = K' v^3 (K = x''(s) the curvature vector, K' its derivative by arc
length), so

    v(s) = min(vmax, min_k sqrt(A_k / |K_k|), min_k (J_k / |K'_k|)^(1/3)).

Without a jerk limit the same bound (its accelerations only) is printed
beside it: their ratio is what the jerk limit costs on that curve at the
least, the curve's own jerk alone. Not a ceiling for a planner (it ignores
the time to change speed), a scale.

  bench/topp.py curve lissajous [--accel 1000,1000] [--vmax 200] [--ds 0.01]
  bench/topp.py curve lissajous --jerk 10000     # the quasi-static bounds
  bench/topp.py poly smoothed.csv [--accel ...]
  bench/topp.py poly smoothed.csv --jerk 1e4   # the same bounds on a polyline read by (P4)
  bench/topp.py curve spiral --check      # ds 0.04, 0.02, 0.01, 0.005
"""
import argparse
import importlib.util
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def gen_curves():
    spec = importlib.util.spec_from_file_location("gen_curves", os.path.join(ROOT, "tools", "gen_curves.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def topp(h, d1, d2, accel, vmax):
    """Time-optimal rest-to-rest time along a grid: h[i] the step from point
    i to i+1 (N-1 steps), d1[i], d2[i] the path's first and second
    derivatives by arc length at point i (N x n). Returns (time, v)."""
    n_pts, n_ax = d1.shape
    A = np.asarray(accel, float)[:n_ax]
    a = np.abs(d1)
    small = a < 1e-12
    # axis k: u in [-g_k + q_k x, g_k + q_k x], g_k = A_k / |x'_k|, q_k = -x''_k / x'_k
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.where(small, np.inf, A / a)
        q = np.where(small, 0.0, -d2 / np.where(small, 1.0, d1))
    # limit curve: the largest x with max_k lower_k(x) <= min_j upper_j(x)
    mvc = np.full(n_pts, vmax * vmax)
    with np.errstate(divide="ignore", invalid="ignore"):
        for k in range(n_ax):
            # an axis the path does not move along at this point: |x''_k| x <= A_k
            cap = np.where(small[:, k] & (np.abs(d2[:, k]) > 0), A[k] / np.abs(d2[:, k]), np.inf)
            mvc = np.minimum(mvc, cap)
            for j in range(n_ax):
                dq = q[:, k] - q[:, j]
                ok = ~small[:, k] & ~small[:, j] & (dq > 0)
                mvc = np.minimum(mvc, np.where(ok, (g[:, j] + g[:, k]) / np.where(ok, dq, 1.0), np.inf))
    # backward: K_i, the largest x at i from which the end (rest) is reachable
    gl, ql, hl, mv = g.tolist(), q.tolist(), h.tolist(), mvc.tolist()
    K = [0.0] * n_pts
    nxt = 0.0
    for i in range(n_pts - 2, -1, -1):
        inv = 0.5 / hl[i]
        x = mv[i]
        gi, qi = gl[i], ql[i]
        for k in range(n_ax):
            c = qi[k] + inv
            if c > 0.0:  # max_k lower_k(x) <= (K - x) / (2h)
                b = (nxt * inv + gi[k]) / c
            elif c < 0.0:  # min_k upper_k(x) >= -x / (2h): never below rest
                b = gi[k] / -c
            else:
                continue
            if b < x:
                x = b
        K[i] = x if x > 0.0 else 0.0
        nxt = K[i]
    K[0] = 0.0
    # forward: the largest u allowed, capped by what can still stop
    x = [0.0] * n_pts
    cur = 0.0
    for i in range(n_pts - 1):
        gi, qi = gl[i], ql[i]
        u = math.inf
        for k in range(n_ax):
            u = min(u, gi[k] + qi[k] * cur)
        cur = min(K[i + 1], cur + 2.0 * hl[i] * u)
        cur = cur if cur > 0.0 else 0.0
        x[i + 1] = cur
    v = np.sqrt(np.array(x))
    t = float(np.sum(2.0 * h / np.maximum(v[:-1] + v[1:], 1e-300)))
    return t, v


def rapid_time(p0, p1, accel, vmax):
    """Straight move from rest to rest: bang-bang at the line's limit."""
    e = np.asarray(p1, float) - np.asarray(p0, float)
    d = float(np.linalg.norm(e))
    if d == 0.0:
        return 0.0
    e /= d
    a = min(A / abs(ek) for A, ek in zip(accel, e) if ek != 0.0)
    if d >= vmax * vmax / a:
        return d / vmax + vmax / a
    return 2.0 * math.sqrt(d / a)


def arc_frame(name, ds):
    """The exact curve of gen_curves.py by arc length: the curve f and its
    axes, the parameter-to-arc table (tt, s), a grid of steps ~ds of arc
    length (sg, its parameters t), the unit tangent x'(s) and x''(s) there."""
    gc = gen_curves()
    f, t_end, n_ax = gc.CURVES[name]
    # |f'(t)| on a fine parameter grid: arc length by the trapezoid rule,
    # then a parameter grid whose steps are ~ds of arc length
    tt = np.linspace(0.0, t_end, 2_000_001)
    dt = 1e-6
    fp = (np.array(f(tt + dt, np)) - np.array(f(tt - dt, np))) / (2 * dt)
    speed = np.linalg.norm(fp[:n_ax], axis=0)
    s = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(tt))])
    n = int(math.ceil(s[-1] / ds)) + 1
    sg = np.linspace(0.0, s[-1], n)
    t = np.interp(sg, s, tt)
    e = 1e-4
    fp = ((np.array(f(t + e, np)) - np.array(f(t - e, np))) / (2 * e))[:n_ax].T
    fpp = ((np.array(f(t + e, np)) - 2 * np.array(f(t, np)) + np.array(f(t - e, np))) / (e * e))[:n_ax].T
    sp = np.linalg.norm(fp, axis=1)[:, None]
    T = fp / sp
    N = (fpp - np.sum(fpp * T, axis=1)[:, None] * T) / (sp * sp)  # x''(s)
    return f, n_ax, tt, s, sg, t, T, N


def curve_grid(name, ds):
    """The exact curve of gen_curves.py by arc length: steps h, x'(s), x''(s)."""
    f, n_ax, _, s, _, t, T, N = arc_frame(name, ds)
    f0 = np.array(f(t, np))[:n_ax].T
    h = np.linalg.norm(np.diff(f0, axis=0), axis=1)
    return h, T, N, f0[0], float(s[-1])


def poly_grid(pts, ds):
    """A polyline read as a curve (see the module's doc)."""
    seg = np.diff(pts, axis=0)
    hs = np.linalg.norm(seg, axis=1)
    keep = hs > 1e-9
    pts = np.concatenate([pts[:1], pts[1:][keep]])
    seg, hs = seg[keep], hs[keep]
    e = seg / hs[:, None]
    n_ax = pts.shape[1]
    # at the vertices: tangent the mean of the two directions, curvature
    # vector the turn over the shorter leg; the ends straight
    t_v = np.concatenate([e[:1], e[:-1] + e[1:], e[-1:]])
    nt = np.linalg.norm(t_v, axis=1)
    rev = nt < 1e-12  # a reversal: the direction it leaves in
    t_v[rev] = np.concatenate([e, e[-1:]])[rev]
    t_v /= np.where(rev, 1.0, nt)[:, None]
    k_v = np.zeros((len(pts), n_ax))
    k_v[1:-1] = (e[1:] - e[:-1]) / np.minimum(hs[1:], hs[:-1])[:, None]
    # grid: every vertex, and points every <= ds between, where tangent and
    # curvature are interpolated linearly (a curvature concentrated at the
    # vertices would let the grid brake at them and speed up between)
    m = np.maximum(1, np.ceil(hs / ds - 1e-9).astype(int))
    f = np.concatenate([np.arange(mi) / mi for mi in m] + [np.zeros(1)])
    i = np.concatenate([np.full(mi, j) for j, mi in enumerate(m)] + [np.array([len(hs) - 1])])
    f[-1] = 1.0
    d1 = (1 - f)[:, None] * t_v[i] + f[:, None] * t_v[i + 1]
    d1 /= np.linalg.norm(d1, axis=1)[:, None]
    d2 = (1 - f)[:, None] * k_v[i] + f[:, None] * k_v[i + 1]
    h = np.repeat(hs / m, m)
    return h, d1, d2, float(hs.sum())


def quasi_static(h, d2, d3, accel, jerk, vmax):
    # Time along a grid at the largest steady speed the path's own
    # acceleration (and, with jerk, its jerk) allows at each point.
    n_ax = d2.shape[1]
    A = np.asarray(accel, float)[:n_ax]
    with np.errstate(divide="ignore"):
        v = np.min(np.sqrt(A / np.abs(d2)), axis=1)
        if jerk is not None:
            J = np.asarray(jerk, float)[:n_ax]
            v = np.minimum(v, np.min(np.cbrt(J / np.abs(d3)), axis=1))
    v = np.minimum(v, vmax)
    return float(np.sum(2.0 * h / (v[:-1] + v[1:])))


def poly_derivs(pts):
    """x', x'', x''' at the middle of every segment of a polyline: the cubic
    through the four points around it by chord length, its derivatives by arc
    length (mlip/motion/pathspeed.h, P4; the ends take the nearest four).
    Returns the lengths of the segments and the three (segment, axis) arrays."""
    hs = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    pts = pts[np.concatenate([[True], hs > 1e-9])]
    hs = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    m = len(hs)
    if m < 3:
        raise SystemExit("poly --jerk: fewer than four distinct points")
    i = np.clip(np.arange(m) - 1, 0, m - 3)  # the window p[i..i+3] around segment j
    p0, p1, p2, p3 = (pts[i + r] for r in range(4))
    c = np.concatenate([[0.0], np.cumsum(hs)])
    t = (0.5 * (c[:-1] + c[1:]) - c[i])[:, None]  # chord parameter of the middle of segment j
    s1 = hs[i][:, None]
    s2 = s1 + hs[i + 1][:, None]
    s3 = s2 + hs[i + 2][:, None]
    f01, f12, f23 = (p1 - p0) / s1, (p2 - p1) / (s2 - s1), (p3 - p2) / (s3 - s2)
    f012, f123 = (f12 - f01) / s2, (f23 - f12) / (s3 - s1)
    c3 = (f123 - f012) / s3
    u0, u1, u2 = t, t - s1, t - s2
    x1 = f01 + f012 * (u0 + u1) + c3 * (u0 * u1 + u0 * u2 + u1 * u2)
    x2 = 2 * f012 + 2 * c3 * (u0 + u1 + u2)
    x3 = 6 * c3
    sg = np.linalg.norm(x1, axis=1)[:, None]
    st = np.sum(x1 * x2, axis=1)[:, None] / sg
    stt = (np.sum(x2 * x2, axis=1)[:, None] + np.sum(x1 * x3, axis=1)[:, None]) / sg - st * st / sg
    d1 = x1 / sg
    d2 = x2 / sg**2 - x1 * st / sg**3
    d3 = (x3 / sg**2 - 3 * x2 * st / sg**3 - x1 * stt / sg**3 + 3 * x1 * st * st / sg**4) / sg
    return hs, d1, d2, d3


def quasi_static_poly(path, accel, jerk, vmax):
    # The quasi-static bounds of a polyline read as a curve by (P4), each
    # segment at the speed of its middle; the first move (the rapid) left out.
    data = np.loadtxt(path, delimiter=",", ndmin=2)
    pts = data[1:, :-1]
    hs, d1, d2, d3 = poly_derivs(pts)
    n_ax = pts.shape[1]
    A = np.asarray(accel, float)[:n_ax]
    J = np.asarray(jerk, float)[:n_ax]
    with np.errstate(divide="ignore"):
        va = np.minimum(np.min(np.sqrt(A / np.abs(d2)), axis=1), vmax)
        vj = np.minimum(va, np.min(np.cbrt(J / np.abs(d3)), axis=1))
    return {"path": os.path.basename(path), "length_mm": float(hs.sum()),
            "accel_s": float(np.sum(hs / va)), "jerk_s": float(np.sum(hs / vj))}


def quasi_static_curve(name, accel, jerk, vmax, ds):
    # The quasi-static bounds of the exact curve without and with jerk.
    h, d1, d2, p0, length = curve_grid(name, ds)
    s = np.concatenate([[0.0], np.cumsum(h)])
    d3 = np.gradient(d2, s, axis=0)  # K'(s), the curvature vector's derivative
    return {"path": f"{name} (exact)", "length_mm": length, "ds_mm": ds,
            "accel_s": quasi_static(h, d2, d3, accel, None, vmax),
            "jerk_s": quasi_static(h, d2, d3, accel, jerk, vmax)}


def ceiling_curve(name, accel, vmax, ds):
    h, d1, d2, p0, length = curve_grid(name, ds)
    n_ax = d1.shape[1]
    t, v = topp(h, d1, d2, accel, vmax)
    tr = rapid_time(np.zeros(n_ax), p0, accel[:n_ax], vmax)
    return {"path": f"{name} (exact)", "length_mm": length, "curve_s": t, "rapid_s": tr,
            "total_s": t + tr, "ds_mm": ds, "vmean": length / t}


def ceiling_poly(path, accel, vmax, ds):
    data = np.loadtxt(path, delimiter=",", ndmin=2)
    pts = data[:, :-1]
    n_ax = pts.shape[1]
    # the first move (the G0 the filter passes unchanged) as a rapid
    tr = rapid_time(pts[0], pts[1], accel[:n_ax], vmax)
    h, d1, d2, length = poly_grid(pts[1:], ds)
    t, v = topp(h, d1, d2, accel, vmax)
    return {"path": os.path.basename(path), "length_mm": length, "curve_s": t, "rapid_s": tr,
            "total_s": t + tr, "ds_mm": ds, "vmean": length / t}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("kind", choices=["curve", "poly"])
    ap.add_argument("what", help="curve name (gen_curves.py) or CSV file (bench_smoothdump)")
    ap.add_argument("--accel", default="1000,1000,1000")
    ap.add_argument("--vmax", type=float, default=200.0)
    ap.add_argument("--ds", type=float, default=0.01, help="grid step, mm")
    ap.add_argument("--check", action="store_true", help="the same at ds 0.04, 0.02, 0.01, 0.005")
    ap.add_argument("--jerk", help="J or J1,J2,...: the quasi-static bounds with and without it")
    a = ap.parse_args()
    accel = [float(x) for x in a.accel.split(",")]
    accel += [accel[-1]] * (6 - len(accel))
    if a.jerk is not None:
        jerk = [float(x) for x in a.jerk.split(",")]
        jerk += [jerk[-1]] * (6 - len(jerk))
        if a.kind == "poly":
            r = quasi_static_poly(a.what, accel, jerk, a.vmax)
            print(f"{r['path']} (P4): quasi-static {r['accel_s']:.4f} s without a jerk limit, "
                  f"{r['jerk_s']:.4f} s with J {a.jerk} (+{(r['jerk_s'] / r['accel_s'] - 1) * 100:.1f} %),"
                  f" {r['length_mm']:.2f} mm")
            return
        for ds in ([0.04, 0.02, 0.01, 0.005] if a.check else [a.ds]):
            r = quasi_static_curve(a.what, accel, jerk, a.vmax, ds)
            print(f"{r['path']}: quasi-static {r['accel_s']:.4f} s without a jerk limit, "
                  f"{r['jerk_s']:.4f} s with J {a.jerk} (+{(r['jerk_s'] / r['accel_s'] - 1) * 100:.1f} %),"
                  f" {r['length_mm']:.2f} mm, ds {ds} mm")
            sys.stdout.flush()
        return
    for ds in ([0.04, 0.02, 0.01, 0.005] if a.check else [a.ds]):
        r = (ceiling_curve if a.kind == "curve" else ceiling_poly)(a.what, accel, a.vmax, ds)
        print(f"{r['path']}: {r['total_s']:.4f} s (curve {r['curve_s']:.4f} s + rapid {r['rapid_s']:.4f} s),"
              f" {r['length_mm']:.2f} mm, ds {ds} mm")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
