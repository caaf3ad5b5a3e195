#!/usr/bin/env python3
"""The streaming path-speed plan (mlip-sim --jerk-plan path,
mlip/motion/pathrun.h) against smooth without J, the mean (--jerk alone) and
the whole-output plan of bench/pathspeed.py --c (its C plan's periods,
marked +, when pathspeed.py's own end fails after it), on the generated curves of
make bench (tools/gen_curves.py), each shifted to start at the origin as
pathspeed.py --poly shifts it (its G0 left out). A 1000 mm/s^2, 200 mm/s,
eps 0.01 mm, T 1 ms. Prints a markdown table.

    bench/pathrun.py [--build build] [--curves trochoid,...] [--jerks 1e4,1e5] [--no-whole]
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))


def shift(src, dst):
    """pathspeed.py's shift_program (imported: one copy)."""
    code = open(os.path.join(ROOT, "bench", "pathspeed.py")).read()
    ns = {}
    exec(code[code.index("def shift_program") : code.index("def natural_m")], ns)
    ns["shift_program"](src, dst)


def sim(build, prog, jerk=None, path=False):
    extra = ["--jerk", repr(jerk)] if jerk else []
    extra += ["--jerk-plan", "path"] if path else []
    r = subprocess.run(
        [os.path.join(build, "mlip-sim"), "-q", "--strategy", "smooth", "--accel", "1000"]
        + ["--vmax", "200", "--feed", "200", "--eps", "0.01", "--period", "0.001"]
        + extra + ["--summary", "-", prog],
        capture_output=True,
        text=True,
    )
    if r.returncode != 0:
        return {"error": (r.stderr.strip() or f"exit {r.returncode}")[:200]}
    return json.loads(r.stdout)


def whole(build, curve, gen, jerk):
    """bench/pathspeed.py --c: the plan over one spline through all of
    smooth's output; its time (curve only), or None."""
    r = subprocess.run(
        [sys.executable, os.path.join(ROOT, "bench", "pathspeed.py"), curve, "--jerk", repr(jerk)]
        + ["--poly", gen, "--c", "--build", build],
        capture_output=True,
        text=True,
    )
    m = re.search(r": ([0-9.]+) s \(curve only\)", r.stdout)
    if m and r.returncode == 0:
        return float(m.group(1)), ""
    # pathspeed.py's own end (its model's tail) may fail after the C plan
    # ran: the C plan's periods then, a lower bound ("+": its tail not counted)
    m = re.search(r"^C plan: .*, (\d+) periods", r.stdout, re.M)
    return (int(m.group(1)) * 1e-3, "+") if m else (None, "")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--curves", default="trochoid,spiral,lissajous,lissajous-large")
    ap.add_argument("--jerks", default="1e4,1e5")
    ap.add_argument("--no-whole", action="store_true", help="skip pathspeed.py --c")
    args = ap.parse_args()
    build = os.path.abspath(args.build)
    tmp = tempfile.mkdtemp(prefix="pathrun-")
    print("| curve | J | smooth no J | mean | vs no J | whole-output plan | vs no J |"
          " streaming plan | vs no J | vs whole | jerk/J | accel/A | contour mm |"
          " window peak | sag max mm |")
    print("|---" * 15 + "|")
    for c in args.curves.split(","):
        gen = os.path.join(build, "curves", c + ".ngc")
        if not os.path.exists(gen):
            os.makedirs(os.path.dirname(gen), exist_ok=True)
            subprocess.run([sys.executable, os.path.join(ROOT, "tools", "gen_curves.py"), c, gen],
                           check=True)
        prog = os.path.join(tmp, c + ".ngc")
        shift(gen, prog)
        base = sim(build, prog)["total_time_s"]
        for js in args.jerks.split(","):
            j = float(js)
            mean, path = sim(build, prog, j), sim(build, prog, j, True)
            w, plus = (None, "") if args.no_whole else whole(build, c, gen, j)
            if "error" in path:
                print(f"| {c} | {j:.0e} | {base:.3f} | {mean['total_time_s']:.3f} | | | |"
                      f" {path['error']} |")
                continue
            t = path["total_time_s"]
            jr = max(a / b for a, b in zip(path["max_axis_jerk"], path["jerk_limit"], strict=True))
            ar = max(a / b for a, b in zip(path["max_axis_accel"], path["accel_limit"], strict=True))
            ws = f"{w:.3f}{plus} | {w / base:.3f}x{plus}" if w else "- | -"
            vw = f"{t / w:.3f}x" if w else "-"
            print(f"| {c} | {j:.0e} | {base:.3f} | {mean['total_time_s']:.3f} |"
                  f" {mean['total_time_s'] / base:.3f}x | {ws} | {t:.3f} | {t / base:.3f}x | {vw} |"
                  f" {jr:.4f} | {ar:.4f} | {path['max_contour_error_mm']:.6f} |"
                  f" {path['path_window_peak']} ({path['path_window_bytes'] // 1024} KiB) |"
                  f" {path['path_max_sag_mm']:.2g} |", flush=True)


if __name__ == "__main__":
    main()
