#!/usr/bin/env python3
"""How much jerk a spline through a trace's setpoints asks for at the
trace's own speed (why --jerk-plan path-mean crawls where the mean does
not: docs/benchmarks.md, "The plan over the mean").

A natural cubic spline per axis through the trace's points (chord length;
points within 1e-6 mm of the previous one skipped, as pathrun skips
them), each piece's |x'''| v^3 with v the trace's own speed over that
piece (chord / T), against J; and the trace's own third differences / T^3.
Needs numpy.

    bench/meanspline.py TRACE.csv J [--period 0.001]
"""

import argparse

import numpy as np


def second_derivatives(h, y):
    """The natural spline's x'' at the knots (Thomas' algorithm)."""
    n = len(y)
    a, b, c, r = np.zeros(n), np.ones(n), np.zeros(n), np.zeros(n)
    a[1:-1], b[1:-1], c[1:-1] = h[:-1] / 6, (h[:-1] + h[1:]) / 3, h[1:] / 6
    r[1:-1] = (y[2:] - y[1:-1]) / h[1:] - (y[1:-1] - y[:-2]) / h[:-1]
    for i in range(1, n):
        m = a[i] / b[i - 1]
        b[i] -= m * c[i - 1]
        r[i] -= m * r[i - 1]
    out = np.zeros(n)
    out[-1] = r[-1] / b[-1]
    for i in range(n - 2, -1, -1):
        out[i] = (r[i] - c[i] * out[i + 1]) / b[i]
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trace")
    ap.add_argument("jerk", type=float)
    ap.add_argument("--period", type=float, default=0.001)
    args = ap.parse_args()
    x = np.loadtxt(args.trace, delimiter=",", skiprows=1)[:, 1:]
    step = np.linalg.norm(np.diff(x, axis=0), axis=1)
    x = x[np.concatenate([[True], step > 1e-6])]
    h = np.linalg.norm(np.diff(x, axis=0), axis=1)
    v = h / args.period
    jerk = (
        np.max(
            [np.abs(np.diff(second_derivatives(h, x[:, k])) / h) * v**3 for k in range(x.shape[1])],
            axis=0,
        )
        / args.jerk
    )
    own = np.max(np.abs(np.diff(x, 3, axis=0)), axis=1) / args.period**3 / args.jerk
    print(
        f"{len(h)} pieces: the spline's |x'''| v^3 / J max {jerk.max():.2f}, p99"
        f" {np.percentile(jerk, 99):.2f}, p90 {np.percentile(jerk, 90):.2f};"
        f" {(jerk > 0.95).sum()} pieces above 0.95 J; the trace's own third"
        f" differences / J max {own.max():.3f}"
    )


if __name__ == "__main__":
    main()
