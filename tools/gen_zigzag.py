#!/usr/bin/env python3
"""Write a 2-D zigzag toolpath as G-code: strokes of --seg mm (0.3) across
each row, one after the other, --pitch mm (0.02) apart along the row, so
that every corner is sharp (the stroke turns back by 180 degrees less
2 atan(pitch/seg)) and every stroke lies within pitch of the next but one;
rows of --length mm, --rows of them, --row-gap mm between a row and the
next (the path comes back near itself at each row's end). Coordinates are
rounded to --decimals as CAM output is.

    tools/gen_zigzag.py > zigzag.ngc
    build/mlip-sim --accel 1000 --vmax 200 --eps 0.01 --trace t.csv zigzag.ngc
    build/mlip-check --accel 1000 --vmax 200 --eps 0.01 zigzag.ngc t.csv

--random SEED instead: a random walk of --segments segments of 0.05-0.6 mm,
each turning by up to 150 degrees either way (sharp corners of every angle,
the kind that is slow under a jerk limit), from a seeded generator.
"""

import argparse
import math
import random
import sys
from collections.abc import Sequence


def zigzag(
    seg: float, pitch: float, length: float, rows: int, row_gap: float
) -> list[tuple[float, float]]:
    """The points, start first: (x, y) in mm."""
    pts = [(0.0, 0.0)]
    n = int(round(length / pitch))
    for r in range(rows):
        y0 = r * (seg + row_gap)
        fwd = r % 2 == 0
        for i in range(1, n + 1):
            x = i * pitch if fwd else (n - i) * pitch
            y = y0 + (seg if i % 2 else 0.0)
            pts.append((x, y))
        if r + 1 < rows:
            pts.append((pts[-1][0], (r + 1) * (seg + row_gap)))
    return pts


def random_zigzag(seed: int, segments: int) -> list[tuple[float, float]]:
    # A seeded random walk: lengths 0.05-0.6 mm, turns up to 150 degrees.
    rng = random.Random(seed)
    x = y = heading = 0.0
    pts = [(0.0, 0.0)]
    for _ in range(segments):
        heading += math.radians(rng.uniform(-150.0, 150.0))
        d = rng.uniform(0.05, 0.6)
        x += d * math.cos(heading)
        y += d * math.sin(heading)
        pts.append((x, y))
    return pts


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--seg", type=float, default=0.3, help="stroke length, mm (0.3)")
    ap.add_argument("--pitch", type=float, default=0.02, help="stroke spacing, mm (0.02)")
    ap.add_argument("--length", type=float, default=20.0, help="row length, mm (20)")
    ap.add_argument("--rows", type=int, default=12, help="rows (12)")
    ap.add_argument("--row-gap", type=float, default=0.005, help="gap between rows, mm (0.005)")
    ap.add_argument("--feed", type=float, default=12000.0, help="F, mm/min (12000)")
    ap.add_argument("--decimals", type=int, default=4, help="coordinate decimals (4)")
    ap.add_argument(
        "--random", type=int, metavar="SEED", help="a random zigzag instead (see above)"
    )
    ap.add_argument("--segments", type=int, default=4000, help="--random: segments (4000)")
    a = ap.parse_args(argv)
    if not (a.seg > 0 and a.pitch > 0 and a.length >= a.pitch and a.rows >= 1 and a.row_gap >= 0):
        ap.error("--seg, --pitch, --length must be positive, --rows >= 1, --row-gap >= 0")
    out = sys.stdout
    if a.random is not None:
        out.write(
            f"(random zigzag: seed {a.random}, {a.segments} segments of 0.05-0.6 mm,"
            f" turns up to 150 degrees)\n"
        )
        pts = random_zigzag(a.random, a.segments)
    else:
        out.write(
            f"(zigzag: {a.seg} mm strokes {a.pitch} mm apart, {a.rows} rows of {a.length} mm)\n"
        )
        pts = zigzag(a.seg, a.pitch, a.length, a.rows, a.row_gap)
    out.write(f"G21 G90 G17\nG1 F{a.feed:g}\n")
    d = a.decimals
    for x, y in pts[1:]:
        out.write(f"G1 X{x:.{d}f} Y{y:.{d}f}\n")
    out.write("M2\n")


if __name__ == "__main__":
    main()
