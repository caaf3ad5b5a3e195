#!/usr/bin/env python3
"""make bench: the paper's Table 2 and Table 1, redone on real toolpaths, and
Table 2's jerk columns (a per-axis jerk limit, mlip/motion/jerk.h).

Table 2: total machining time of mpct (the paper), bisector, stop and smooth
(mpct on the path smoothed within the tolerance, beyond the paper) on
MB-2.3_test.nc, flower-spiral-2d.ngc and four generated smooth curves in
0.02 mm segments rounded to 4 decimals (tools/gen_curves.py) at feed
200 mm/s, eps 0.01 mm, T 1 ms and the paper's four per-axis acceleration
settings. Times are the simulator's, i.e. exact periods of the motion the
controller would run.

For the generated curves, the time-optimal ceiling too (bench/topp.py): the
shortest time any planner could take along the exact curve under the same
limits, so the ratios say how much of the possible the strategies reach.

Table 1: look-ahead cost (medians of timed runs; instruction counts from
callgrind, which do not depend on what else the shared machine is doing).
"""
import argparse
import concurrent.futures as cf
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import topp  # bench/topp.py, beside this script (its folder is sys.path[0])

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.environ.get("MLIP_SHARED", os.path.join(ROOT, "..", "shared"))
TOOLPATHS = os.path.join(SHARED, "toolpaths")

# (label, --accel): the paper's x/y settings; for 3-axis files Z gets the
# value of Y (toolpaths/README.md: "the same value on Z").
SETTINGS = [("1000/1000", "1000,1000,1000"), ("3000/1000", "3000,1000,1000"),
            ("3000/3000", "3000,3000,3000"), ("6000/6000", "6000,6000,6000")]
PAPER = {  # the vase, Table 2: minutes
    "1000/1000": (22.78, 40.52, 57.13), "3000/1000": (18.62, 31.59, 44.16),
    "3000/3000": (13.15, 21.22, 34.92), "6000/6000": (9.30, 14.33, 26.15)}
STRATEGIES = ["mpct", "bisector", "stop", "smooth"]
CURVES = ["lissajous", "spiral", "trochoid", "lissajous-large"]  # tools/gen_curves.py


def sim(build, path, accel, strategy):
    n_axes = 2 if path.endswith(("flower-spiral-2d.ngc", "lissajous.ngc", "trochoid.ngc", "lissajous-large.ngc")) else 3
    accel = ",".join(accel.split(",")[:n_axes])
    out = subprocess.run(
        [os.path.join(build, "mlip-sim"), "-q", "--strategy", strategy, "--accel", accel,
         "--vmax", "200", "--feed", "200", "--eps", "0.01", "--period", "0.001",
         "--summary", "-", path], check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def table2(build):
    # plus smooth curves in 0.02 mm segments, coordinates rounded to 4 decimals
    gen = os.path.abspath(os.path.join(build, "curves"))  # make bench gives a relative build
    os.makedirs(gen, exist_ok=True)
    for c in CURVES:
        subprocess.run([sys.executable, os.path.join(ROOT, "tools", "gen_curves.py"), c,
                        os.path.join(gen, c + ".ngc")], check=True)
    files = ["MB-2.3_test.nc", "flower-spiral-2d.ngc"] + [os.path.join(gen, c + ".ngc") for c in CURVES]
    jobs = {}
    with cf.ThreadPoolExecutor(max_workers=2) as ex:
        for f in files:
            for label, accel in SETTINGS:
                for st in STRATEGIES:
                    jobs[(f, label, st)] = ex.submit(sim, build, os.path.join(TOOLPATHS, f), accel, st)
    # os.path.join keeps an absolute path (the generated curves) as it is
        res = {k: v.result() for k, v in jobs.items()}
    print("## Table 2, redone: total machining time (feed 200 mm/s, eps 0.01 mm, T 1 ms)\n")
    for f in files:
        s0 = res[(f, SETTINGS[0][0], "mpct")]
        print(f"### {os.path.basename(f)}: {s0['blocks']} blocks, {s0['path_length_mm'] / 1000:.2f} m\n")
        print("| accel x/y (mm/s^2) | mpct | bisector | stop | smooth | mpct vs bisector | mpct vs stop |"
              " smooth vs mpct | paper (vase): mpct / bisector / stop, gains |")
        print("|---|---|---|---|---|---|---|---|---|")
        for label, _ in SETTINGS:
            t = [res[(f, label, st)]["total_time_s"] for st in STRATEGIES]
            p = PAPER[label]
            print(f"| {label} | {t[0]:.1f} s | {t[1]:.1f} s | {t[2]:.1f} s | {t[3]:.1f} s "
                  f"| +{(t[1] / t[0] - 1) * 100:.1f} % ({t[1] / t[0]:.2f}x) "
                  f"| +{(t[2] / t[0] - 1) * 100:.1f} % ({t[2] / t[0]:.2f}x) "
                  f"| {t[0] / t[3]:.2f}x faster "
                  f"| {p[0]:.2f} / {p[1]:.2f} / {p[2]:.2f} min, +{(p[1] / p[0] - 1) * 100:.1f} %, "
                  f"+{(p[2] / p[0] - 1) * 100:.1f} % |")
        curve = os.path.basename(f)[:-4] if f.startswith(gen) else None
        if curve is not None:
            # the ceiling: no planner can be faster under the same limits
            print(f"\n{curve}: the time-optimal traversal of the exact curve (bench/topp.py: per-axis"
                  " |a_k| <= A_k, tangential and normal together, speed <= 200 mm/s; the rapid from the"
                  " origin counted as a rest-to-rest straight move in all three; a path elsewhere in the"
                  " tolerance band may be a little faster still):\n")
            print("| accel x/y (mm/s^2) | mpct | smooth | time-optimal | smooth vs mpct |"
                  " time-optimal vs mpct (the most possible) | smooth reaches |")
            print("|---|---|---|---|---|---|---|")
            for label, accel in SETTINGS:
                t0, t3 = (res[(f, label, st)]["total_time_s"] for st in ("mpct", "smooth"))
                c = topp.ceiling_curve(curve, [float(a) for a in accel.split(",")] * 2, 200.0, 0.02)
                tc = c["total_s"]
                print(f"| {label} | {t0:.2f} s | {t3:.2f} s | {tc:.2f} s | {t0 / t3:.2f}x | {t0 / tc:.2f}x"
                      f" | {tc / t3 * 100:.1f} % of the ceiling |")
        worst = max(max(a / l for a, l in zip(r["max_axis_accel"], r["accel_limit"]))
                    for k, r in res.items() if k[0] == f)
        cont = max(r["max_contour_error_mm"] for k, r in res.items() if k[0] == f)
        print(f"\nAll runs: max axis acceleration / limit = {worst:.12f}, "
              f"max contour error {cont:.5f} mm (eps 0.01).\n")
    return res


JERKS = [100000, 10000]  # 100 A and 10 A at A = 1000 mm/s^2 (mm/s^3)
# LinuxCNC 2.10's S-curve planner as the issue measured it (master of 2026,
# PLANNER_TYPE 1, MAX_LINEAR_JERK and per-joint MAX_JERK = J, G64 P0.01, 1 ms
# servo, sim, A = 1000 mm/s^2): on a Lissajous of amplitudes 60 and 45 mm in
# 0.018 mm segments and a random zigzag of 0.05-0.6 mm segments (its own).
PEERS = {"Lissajous 60 x 45 mm, 0.018 mm": ("6.89 s", "52.1 s (max jerk 1.7 J)", "25.5 s"),
         "random zigzag, 0.05-0.6 mm": ("547 s", "1848 s (contour 0.0127 mm, jerk 70 J at corners)",
                                        "1209 s (contour 0.0126 mm)")}


def sim_jerk(build, path, n_axes, strategy, jerk, plan=None):
    extra = ["--jerk", str(jerk)] if jerk else []
    extra += ["--jerk-plan", plan] if plan else []
    return json.loads(subprocess.run(
        [os.path.join(build, "mlip-sim"), "-q", "--strategy", strategy, "--accel",
         ",".join(["1000"] * n_axes), "--vmax", "200", "--feed", "200", "--eps", "0.01",
         "--period", "0.001", *extra, "--summary", "-", path],
        check=True, capture_output=True, text=True).stdout)


def table2_jerk(build):
    """Table 2's jerk columns: mpct and smooth under a per-axis jerk limit
    (the mean, mlip-rt's default), and smooth with --jerk-plan auto (the
    soonest of the mean, the path plan, the plan over the mean and mpct)."""
    gen = os.path.abspath(os.path.join(build, "curves"))
    os.makedirs(gen, exist_ok=True)
    for c in CURVES:
        if not os.path.exists(os.path.join(gen, c + ".ngc")):
            subprocess.run([sys.executable, os.path.join(ROOT, "tools", "gen_curves.py"), c,
                            os.path.join(gen, c + ".ngc")], check=True)
    zz = os.path.join(gen, "random-zigzag.ngc")
    with open(zz, "w") as fh:
        subprocess.run([sys.executable, os.path.join(ROOT, "tools", "gen_zigzag.py"), "--random", "1",
                        "--segments", "4000"], check=True, stdout=fh)
    files = [(os.path.join(TOOLPATHS, "MB-2.3_test.nc"), 3), (os.path.join(TOOLPATHS, "flower-spiral-2d.ngc"), 2)]
    files += [(os.path.join(gen, c + ".ngc"), 3 if c == "spiral" else 2) for c in CURVES]
    files += [(zz, 2)]
    jobs = {}
    with cf.ThreadPoolExecutor(max_workers=2) as ex:
        for f, n in files:
            jobs[(f, "smooth", 0)] = ex.submit(sim_jerk, build, f, n, "smooth", 0)
            for j in JERKS:
                for st in ("mpct", "smooth"):
                    jobs[(f, st, j)] = ex.submit(sim_jerk, build, f, n, st, j)
                jobs[(f, "auto", j)] = ex.submit(sim_jerk, build, f, n, "smooth", j, "auto")
        res = {k: v.result() for k, v in jobs.items()}
    print("## Table 2, jerk columns: a per-axis jerk limit J (A 1000 mm/s^2 per axis, 200 mm/s,"
          " eps 0.01 mm, T 1 ms)\n")
    print("Machining time and against smooth without a jerk limit; the worst axis's jerk over J and"
          " acceleration over A at any sample (third and second differences of the setpoints /"
          " T^3, T^2), the largest contour error against the original polyline.\n")
    print("| file | smooth, no J | J | mpct | smooth | smooth vs no J | smooth, auto (plan) |"
          " auto vs no J | max jerk / J | max accel / A | max contour (mm) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for f, n in files:
        t0 = res[(f, "smooth", 0)]["total_time_s"]
        for j in JERKS:
            rm, rs, ra = (res[(f, st, j)] for st in ("mpct", "smooth", "auto"))
            jr = max(max(a / j for a in r["max_axis_jerk"]) for r in (rm, rs, ra))
            ar = max(max(a / 1000 for a in r["max_axis_accel"]) for r in (rm, rs, ra))
            ce = max(r["max_contour_error_mm"] for r in (rm, rs, ra))
            print(f"| {os.path.basename(f)} | {t0:.2f} s | {j:.0e} | {rm['total_time_s']:.2f} s |"
                  f" {rs['total_time_s']:.2f} s | {rs['total_time_s'] / t0:.2f}x |"
                  f" {ra['total_time_s']:.2f} s ({'mpct' if ra.get('strategy') == 'mpct' else ra.get('jerk_plan', '?')}) |"
                  f" {ra['total_time_s'] / t0:.2f}x | {jr:.9f} | {ar:.4f} | {ce:.5f} |")
    print("\nThe generated curves' quasi-static bounds (bench/topp.py --jerk: the exact curve at the"
          " largest steady speed its own acceleration and jerk allow, transitions ignored) against the"
          " same bound without J: what the jerk limit costs there at the least.\n")
    print("| curve | J | quasi-static, no J | with J | bound's ratio | smooth's ratio (above) |"
          " auto's ratio (above) |")
    print("|---|---|---|---|---|---|---|")
    for c in CURVES:
        f = os.path.join(gen, c + ".ngc")
        for j in JERKS:
            q = topp.quasi_static_curve(c, [1000.0] * 6, [float(j)] * 6, 200.0, 0.02)
            t0 = res[(f, "smooth", 0)]["total_time_s"]
            rs, ra = (res[(f, st, j)]["total_time_s"] / t0 for st in ("smooth", "auto"))
            print(f"| {c} | {j:.0e} | {q['accel_s']:.3f} s | {q['jerk_s']:.3f} s |"
                  f" {q['jerk_s'] / q['accel_s']:.3f}x | {rs:.2f}x | {ra:.2f}x |")
    print("\nPeers, for context (the issue's measurements; their files, not these): LinuxCNC 2.10's"
          " S-curve planner (PLANNER_TYPE 1, MAX_LINEAR_JERK = per-joint MAX_JERK = J, G64 P0.01,"
          " 1 ms servo, A 1000 mm/s^2):\n")
    print("| file | planner 0 (no jerk limit) | J = 1e4 | J = 1e5 |")
    print("|---|---|---|---|")
    for name, (t0, t4, t5) in PEERS.items():
        print(f"| {name} | {t0} | {t4} | {t5} |")
    print()
    return res


def callgrind(build, args, func):
    if shutil.which("valgrind") is None:
        return None
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "cg.out")
        subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
                        f"--toggle-collect={func}", os.path.join(build, "bench_lookahead")] + args,
                       check=True, capture_output=True)
        with open(out) as fh:
            for line in fh:
                m = re.match(r"(?:summary|totals):\s+(\d+)", line)
                if m:
                    return int(m.group(1))
    return None


def table1(build):
    mb = os.path.join(TOOLPATHS, "MB-2.3_test.nc")
    r = json.loads(subprocess.run([os.path.join(build, "bench_lookahead"), mb, "--reps", "41"],
                                  check=True, capture_output=True, text=True).stdout)
    print("## Table 1, redone: look-ahead cost on MB-2.3_test.nc (A = 1000 mm/s^2)\n")
    print("Medians of 41 windows spread over the file. Pre-read = push N blocks from rest "
          "(corner of each, eqs 1-20, + backward reachability with the termination "
          "condition); full pass = one backward pass over N blocks without termination; "
          "corners = eqs 1-20 alone.\n")
    print("| look-ahead blocks | pre-read (µs) | instructions / block | full backward pass (µs) |"
          " corners alone (µs) | corners re-visited / block | paper pre-read (ms, 2011) |")
    print("|---|---|---|---|---|---|---|")
    paper = {1000: 0.14, 2000: 0.24, 3000: 0.38, 4000: 0.49}
    for row in r["preread"]:
        n = row["blocks"]
        ir = callgrind(build, [mb, "--mode", "preread", str(n), "--reps", "3"], "bench_preread")
        irs = f"{ir / (3 * n):.0f}" if ir else "n/a"
        print(f"| {n} | {row['preread_us']:.1f} | {irs} | {row['full_pass_us']:.1f} | "
              f"{row['corners_us']:.1f} | {row['visits_per_block']:.1f} | {paper[n]} |")
    a = r["add_one_block"]
    ir = callgrind(build, [mb, "--mode", "push", "20000"], "bench_push_one")
    irc = callgrind(build, [mb, "--mode", "corners", "4000", "--reps", "3"], "bench_corners")
    print(f"\nAdding one block while running (look-ahead full, 4096): median {a['median_ns']} ns,"
          f" p99 {a['p99_ns']} ns, max {a['max_ns']} ns over {a['pushes']} pushes"
          f" (timer overhead included); {ir / 20000:.0f} instructions per push;"
          if ir else f"\nAdding one block: median {a['median_ns']} ns;", end="")
    print(f" a re-run visits {a['visits_per_block']:.1f} corners on average before the termination"
          f" condition stops it (paper: about 200 on the vase; 0.025-0.032 ms per block).")
    if irc:
        print(f"One corner's parameters (eqs 1-20): {irc / (3 * 3998):.0f} instructions"
              f" (paper: 0.00558 ms).")
    print()


def sim_speed(build):
    mb = os.path.join(TOOLPATHS, "MB-2.3_test.nc")
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        subprocess.run([os.path.join(build, "mlip-sim"), "-q", "--accel", "1000", "--feed", "200", mb],
                       check=True)
        times.append(time.perf_counter() - t0)
    s = sim(build, mb, "1000,1000,1000", "mpct")
    print(f"## Simulator speed\n\nmlip-sim on MB-2.3_test.nc ({s['total_time_s'] / 60:.1f} min of machining"
          f" at 1000 mm/s^2), no trace: median {statistics.median(times):.3f} s wall over 5 runs "
          f"(parse + plan + interpolate + check).\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--only", choices=["table1", "table2", "jerk", "speed"])
    a = ap.parse_args()
    if not os.path.isdir(TOOLPATHS):
        sys.exit(f"bench: {TOOLPATHS} not found (set MLIP_SHARED)")
    if a.only in (None, "table2"):
        table2(a.build)
    if a.only in (None, "table2", "jerk"):
        table2_jerk(a.build)
    if a.only in (None, "table1"):
        table1(a.build)
    if a.only in (None, "speed"):
        sim_speed(a.build)


if __name__ == "__main__":
    main()
