#!/usr/bin/env python3
"""Smooth curves cut into very short G01 segments, coordinates rounded as CAM
does: the case where the paper's corners are limited by the rounding noise
(0.0001 mm on a 0.02 mm segment is a 0.3 degree kink), not by eps.

  tools/gen_curves.py lissajous OUT.ngc [--seg 0.02] [--decimals 4]
  tools/gen_curves.py spiral OUT.ngc
  tools/gen_curves.py trochoid OUT.ngc
  tools/gen_curves.py lissajous-large OUT.ngc

lissajous: x = 40 sin(3 t + pi/2), y = 30 sin(4 t), one period (about 0.9 m);
spiral: an Archimedean spiral r = 2 + 0.5 theta over 12 turns (XY), with
Z = 0.5 sin(3 theta) (3-D); trochoid: the loops of trochoidal (adaptive)
clearing, x = 3 cos t + 0.5 t / (2 pi), y = 3 sin t, 40 loops of radius 3 mm
advancing 0.5 mm each; lissajous-large: the same figure 2.5 times the
size, x = 100 sin(3 t + pi/2), y = 75 sin(4 t) (added after the first one's
ceiling turned out 2.41x mpct: on the larger figure the rounding noise, not
the curvature, limits mpct over most of the path). Points are placed every
--seg mm of arc length.
"""

import argparse
import math
from collections.abc import Callable
from typing import Any

# a curve: t (a float, or a numpy array in bench/topp.py) and the module whose
# sin/cos to use -> (x, y, z)
Curve = Callable[..., tuple[Any, Any, Any]]


# m: the module whose sin/cos to use (math here; numpy arrays in bench/topp.py)
def lissajous(t: Any, m: Any = math) -> tuple[Any, Any, Any]:
    return (40.0 * m.sin(3.0 * t + math.pi / 2), 30.0 * m.sin(4.0 * t), 0.0 * t)


def lissajous_large(t: Any, m: Any = math) -> tuple[Any, Any, Any]:
    return (100.0 * m.sin(3.0 * t + math.pi / 2), 75.0 * m.sin(4.0 * t), 0.0 * t)


def spiral(t: Any, m: Any = math) -> tuple[Any, Any, Any]:
    r = 2.0 + 0.5 * t
    return (r * m.cos(t), r * m.sin(t), 0.5 * m.sin(3.0 * t))


def trochoid(t: Any, m: Any = math) -> tuple[Any, Any, Any]:
    return (3.0 * m.cos(t) + 0.5 * t / (2 * math.pi), 3.0 * m.sin(t), 0.0 * t)


CURVES: dict[str, tuple[Curve, float, int]] = {
    "lissajous": (lissajous, 2 * math.pi, 2),
    "spiral": (spiral, 24 * math.pi, 3),
    "trochoid": (trochoid, 80 * math.pi, 2),
    "lissajous-large": (lissajous_large, 2 * math.pi, 2),
}


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("curve", choices=sorted(CURVES))
    ap.add_argument("out")
    ap.add_argument("--seg", type=float, default=0.02, help="segment length, mm")
    ap.add_argument("--decimals", type=int, default=4)
    a = ap.parse_args()
    f, t_end, axes = CURVES[a.curve]
    # arc-length steps by a fine parameter walk
    dt = 1e-5
    pts, t, acc = [f(0.0)], 0.0, 0.0
    prev = pts[0]
    while t < t_end:
        t = min(t + dt, t_end)
        p = f(t)
        acc += math.dist(p, prev)
        prev = p
        if acc >= a.seg or t == t_end:
            pts.append(p)
            acc = 0.0
    fmt = f"{{:.{a.decimals}f}}"
    with open(a.out, "w") as o:
        o.write(
            f"(gen_curves.py {a.curve}: {len(pts) - 1} segments of {a.seg} mm, "
            f"{a.decimals} decimals)\nG21 G90\n"
        )
        x = pts[0]
        o.write(
            "G0 "
            + " ".join(f"{c}{fmt.format(v)}" for c, v in zip("XYZ", x[:axes], strict=False))
            + "\nG1 F12000\n"
        )
        for p in pts[1:]:
            o.write(
                "G1 "
                + " ".join(f"{c}{fmt.format(v)}" for c, v in zip("XYZ", p[:axes], strict=False))
                + "\n"
            )


if __name__ == "__main__":
    main()
