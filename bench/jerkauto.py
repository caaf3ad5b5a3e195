#!/usr/bin/env python3
"""mlip-sim --jerk-plan auto against the mean (--jerk alone), the path
plan (--jerk-plan path) and the plan over the mean (--jerk-plan path-mean),
smooth without J as the scale: the generated curves
of make bench (tools/gen_curves.py, unshifted: their G0 from the origin
first), the shared CAM files and a random sharp zigzag
(tools/gen_zigzag.py --random 1 --segments 4000). A 1000 mm/s^2, 200 mm/s,
eps 0.01 mm, feed 200, T 1 ms. Every trace (mean, path, path-mean, auto) is
judged by mlip-check --jerk; auto must take no period more than the mean,
nor more than any candidate whose trace passes.

    bench/jerkauto.py [--build build] [--files a,b] [--jerks 1e4,1e5] [--out DIR]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.join(ROOT, "..", "shared", "toolpaths")
CURVES = ["trochoid", "spiral", "lissajous", "lissajous-large"]
CAM = ["MB-2.3_test.nc", "flower-spiral-2d.ngc", "tball-pocket.gcode", "SheepTile-v2.nc"]
MACHINE = ["--accel", "1000", "--vmax", "200", "--eps", "0.01", "--period", "0.001"]


def sim(build, prog, trace, jerk=None, plan=None):
    """mlip-sim's summary, or {"error": its stderr's last line}."""
    extra = ["--jerk", repr(jerk)] if jerk else []
    extra += ["--jerk-plan", plan] if plan else []
    r = subprocess.run(
        [os.path.join(build, "mlip-sim"), "-q", "--strategy", "smooth", "--feed", "200"]
        + MACHINE + extra + ["--trace", trace, "--summary", "-", prog],
        capture_output=True, text=True, check=False)
    if r.returncode != 0:
        return {"error": (r.stderr.strip().splitlines() or ["exit %d" % r.returncode])[-1]}
    return json.loads(r.stdout)


def check(build, prog, trace, jerk):
    """mlip-check --jerk's verdict and its measured maxima."""
    r = subprocess.run(
        [os.path.join(build, "mlip-check")] + MACHINE + ["--jerk", repr(jerk), "--json", "-",
                                                         prog, trace],
        capture_output=True, text=True, check=False)
    return r.returncode, (json.loads(r.stdout) if r.stdout.strip() else {})


def ratios(s):
    """The largest axis jerk / J and acceleration / A of a summary."""
    return (max(x / y for x, y in zip(s["max_axis_jerk"], s["jerk_limit"], strict=True)),
            max(x / y for x, y in zip(s["max_axis_accel"], s["accel_limit"], strict=True)))


def programs(build, names, tmp):
    for name in names:
        if name in CURVES:
            gen = os.path.join(build, "curves", name + ".ngc")
            if not os.path.exists(gen):
                os.makedirs(os.path.dirname(gen), exist_ok=True)
                subprocess.run([sys.executable, os.path.join(ROOT, "tools", "gen_curves.py"),
                                name, gen], check=True)
            yield name, gen
        elif name == "zigzag":
            gen = os.path.join(tmp, "zigzag-random1.ngc")
            with open(gen, "w", encoding="ascii") as f:
                subprocess.run([sys.executable, os.path.join(ROOT, "tools", "gen_zigzag.py"),
                                "--random", "1", "--segments", "4000"], stdout=f, check=True)
            yield name, gen
        else:
            yield name, os.path.join(SHARED, name)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--files", default=",".join(CURVES + CAM + ["zigzag"]))
    ap.add_argument("--jerks", default="1e4,1e5")
    ap.add_argument("--out", default=None, help="keep the traces here")
    args = ap.parse_args()
    tmp = args.out or tempfile.mkdtemp(prefix="jerkauto-")
    os.makedirs(tmp, exist_ok=True)
    print("| file | J | no J (s) | mean (s) | path (s) | path-mean (s) | auto (s) | taken |"
          " auto / mean | path-mean / mean | path-mean / path | auto / no J | jerk / J |"
          " accel / A | contour (mm) | path-mean jerk / J, accel / A, contour |"
          " mlip-check mean, path, path-mean, auto |")
    print("|---" * 17 + "|")
    bad = 0
    for name, prog in programs(args.build, args.files.split(","), tmp):
        tag = os.path.splitext(os.path.basename(prog))[0]
        base = sim(args.build, prog, os.devnull)
        for js in args.jerks.split(","):
            j = float(js)
            runs, verdicts = {}, []
            for plan in ("mean", "path", "path-mean", "auto"):
                tr = os.path.join(tmp, f"{tag}-{js}-{plan}.csv")
                runs[plan] = sim(args.build, prog, tr, j, plan)
                if "error" in runs[plan]:
                    verdicts.append("-")
                    continue
                rc, _ = check(args.build, prog, tr, j)
                verdicts.append("pass" if rc == 0 else f"FAIL {rc}")
                if not args.out:
                    os.remove(tr)
                bad += rc != 0 and plan in ("mean", "auto")
            m, p, a, pm = runs["mean"], runs["path"], runs["auto"], runs["path-mean"]
            pt = f"{p['total_time_s']:.3f}" if "error" not in p else "refused"
            pmt = f"{pm['total_time_s']:.3f}" if "error" not in pm else "refused"
            if "error" in a or "error" in m:
                print(f"| {name} | {js} | | {m.get('total_time_s', m.get('error'))} | {pt} |"
                      f" {pmt} | {a.get('error')} |", flush=True)
                bad += 1
                continue
            # never slower than the mean, nor than a candidate whose trace passes
            passing = [runs[k]["periods"] for k, v in zip(("mean", "path", "path-mean"), verdicts)
                       if v == "pass"]
            bad += a["periods"] > min(passing)
            jr, ar = ratios(a)
            pmr = ("-" if "error" in pm else
                   "%.4f, %.4f, %.5f" % (*ratios(pm), pm["max_contour_error_mm"]))
            rel = (lambda x, y: f"{x['total_time_s'] / y['total_time_s']:.3f}x"
                   if "error" not in x and "error" not in y else "-")
            print(f"| {name} | {js} | {base['total_time_s']:.3f} | {m['total_time_s']:.3f} |"
                  f" {pt} | {pmt} | {a['total_time_s']:.3f} | {'mpct' if a['strategy'] == 'mpct' else a['jerk_plan']} |"
                  f" {rel(a, m)} | {rel(pm, m)} | {rel(pm, p)} | {rel(a, base)} |"
                  f" {jr:.4f} | {ar:.4f} | {a['max_contour_error_mm']:.5f} | {pmr} |"
                  f" {', '.join(verdicts)} |", flush=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
