#!/usr/bin/env python3
"""Generate examples/demo.ngc: mlip's own bundled program (no third-party
data). A 3-axis rose engraved in 0.05-0.5 mm G01 micro-segments over a
wavy surface, a helical G2 arc, rapids between them: what CAM output for a
curved surface looks like, small enough to run in a second of simulation."""

import math
import sys


def main(out: str) -> None:
    lines = [
        "%",
        "(mlip demo: rose on a wavy surface, micro-segments, one helix)",
        "G21 G90 G17 G94",
        "G54",
        "G0 Z5.000",
        "G0 X40.000 Y0.000",
        "G1 Z0.000 F600",
    ]
    # rose r = 40 cos(3 t) + wave in z, segment length varying 0.05-0.5 mm
    t, k = 0.0, 0
    lines.append("F6000")
    while t < 2 * math.pi:
        r = 25.0 + 15.0 * math.cos(3 * t)
        x, y = r * math.cos(t), r * math.sin(t)
        z = 0.8 * math.sin(0.35 * x) * math.cos(0.27 * y) - 1.0
        step = 0.05 + 0.45 * (0.5 + 0.5 * math.sin(7 * t))  # mm
        lines.append(f"G1 X{x:.4f} Y{y:.4f} Z{z:.4f}")
        dx = -r * math.sin(t) - 45.0 * math.sin(3 * t) * math.cos(t)
        dy = r * math.cos(t) - 45.0 * math.sin(3 * t) * math.sin(t)
        t += step / max(math.hypot(dx, dy), 1e-6)
        k += 1
    lines += [
        "G0 Z5.000",
        "G0 X10.000 Y0.000",
        "G1 Z-0.500 F600",
        "G2 X10.000 Y0.000 Z-2.000 I-10.000 J0.000 F3000 (a helix, full turn)",
        "G0 Z5.000",
        "M30",
        "%",
    ]
    with open(out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print(f"{out}: {k} micro-segments", file=sys.stderr)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "examples/demo.ngc")
