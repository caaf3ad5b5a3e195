#!/usr/bin/env python3
"""Peak RSS of program loading against program size (issue 9: memory
independent of program length).

Generates programs of the given sizes (default 2, 20, 200 MB): a smooth
spiral of 0.05 mm G1 segments at 200 mm/s, so that the simulator runs them
quickly, and measures the peak resident set size (ru_maxrss of the child,
os.wait4) of
  - bench_load: mlip-feed's loading (check the whole file, then stream it),
  - mlip-sim:   the simulator on the same program (summary only).
Prints a table and exits 1 when a tool's RSS grows by more than --tol
(default 10 %) over the smallest program's. Each figure is the least of
--repeat runs, without address-space randomization (setarch -R).

  python3 bench/rss.py [--build build] [--sizes 2,20,200] [--tools bench_load,mlip-sim]
"""
import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def generate(path, size_bytes):
    """A spiral of short G1 segments filling size_bytes (inside +-1000 mm)."""
    step_mm = 0.05
    with open(path, "w") as f:
        f.write("G21 G90 G64\nG0 X100 Y0\nG1 F12000\n")
        a, r, n = 0.0, 100.0, 0
        buf = []
        while f.tell() < size_bytes:
            for _ in range(10000):
                a += step_mm / r
                r = 100.0 + 50.0 * math.sin(a / 50.0)
                buf.append("X%.4f Y%.4f\n" % (r * math.cos(a), r * math.sin(a)))
                n += 1
            f.write("".join(buf))
            buf.clear()
        f.write("M2\n")
    return n


def peak_rss_kb(cmd):
    """Run cmd; return (exit code, peak RSS in kB of that child), measured by
    GNU time (/usr/bin/time -f %M). Not os.wait4 here: a child of this
    Python inherits the interpreter's peak RSS through fork and exec."""
    # without address-space randomization (setarch -R) a run's RSS varies
    # by a page or two instead of ~150 kB
    aslr_off = ["setarch", "-R"] if shutil.which("setarch") else []
    with tempfile.TemporaryFile() as out:
        p = subprocess.run([*aslr_off, "/usr/bin/time", "-f", "MAXRSS %M", *cmd],
                           stdout=subprocess.DEVNULL, stderr=out)
        out.seek(0)
        err = out.read().decode(errors="replace")
    kb = [int(l.split()[1]) for l in err.splitlines() if l.startswith("MAXRSS ")]
    code = p.returncode
    if code != 0 or not kb:
        sys.stderr.write(f"{cmd}: exit {code}\n{err}\n")
        return code or 1, None
    return 0, kb[-1]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--sizes", default="2,20,200", help="program sizes, MB")
    ap.add_argument("--tools", default="bench_load,mlip-sim")
    ap.add_argument("--tol", type=float, default=0.10)
    ap.add_argument("--repeat", type=int, default=3,
                    help="runs per tool and size, the least RSS kept (a run varies by ~150 kB)")
    ap.add_argument("--dir", default=None, help="where to write the programs (default: a temp dir)")
    a = ap.parse_args()
    sizes = [float(s) for s in a.sizes.split(",")]
    tools = a.tools.split(",")
    cmds = {
        "bench_load": lambda p: [os.path.join(a.build, "bench_load"), p],
        "mlip-sim": lambda p: [os.path.join(a.build, "mlip-sim"), "-q", "--summary", os.devnull, p],
    }
    rows = {}
    with tempfile.TemporaryDirectory(dir=a.dir) as d:
        for mb in sizes:
            path = os.path.join(d, f"p{mb:g}MB.ngc")
            blocks = generate(path, int(mb * 1e6))
            rows[mb] = {"blocks": blocks}
            for t in tools:
                runs = [peak_rss_kb(cmds[t](path)) for _ in range(max(1, a.repeat))]
                ok = [kb for code, kb in runs if code == 0]
                rows[mb][t] = min(ok) if len(ok) == len(runs) else None
            os.remove(path)
    print("| program | blocks | " + " | ".join(f"{t} peak RSS (kB)" for t in tools) + " |")
    print("|---|---|" + "---|" * len(tools))
    for mb in sizes:
        r = rows[mb]
        print(f"| {mb:g} MB | {r['blocks']} | " +
              " | ".join(str(r[t]) for t in tools) + " |")
    bad = 0
    for t in tools:
        vals = [rows[mb][t] for mb in sizes]
        if None in vals:
            bad = 1
            continue
        growth = max(vals) / vals[0] - 1.0  # against the smallest program's
        flat = growth <= a.tol
        print(f"{t}: largest RSS / the {sizes[0]:g} MB program's - 1 = {growth * 100:.1f} % "
              f"({'flat' if flat else 'NOT flat'} within {a.tol * 100:g} %)")
        bad |= not flat
    return bad


if __name__ == "__main__":
    sys.exit(main())
