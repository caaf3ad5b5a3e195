#!/usr/bin/env python3
"""The controller's instructions per period, counted by callgrind.

Runs build/bench_period under callgrind with the `insns` flag (collection
toggled around each period, one dump part a period, all parts in one file)
and reads each part's instruction count: a figure the other jobs on a shared
host do not change. The program runs twice and the second run is read (the
first pays the dynamic linker's lazy binding inside its first period).

  bench/period_insns.py CONFIG PROGRAM STRATEGY [--periods N] [--jerk J]
                        [--lookahead L] [--sync] [--top K] [--build DIR] [--bin FILE]

Prints the percentiles (first period apart), the largest periods and, for
the largest one, the functions its instructions were spent in (self cost).
"""

import argparse
import os
import subprocess
import sys
import tempfile


def parts(path: str) -> list[tuple[int, dict[str, int]]]:
    """(summary, {fn: self instructions}) for each dump part, in order."""
    out: list[tuple[int, dict[str, int]]] = []
    summary: int | None = None
    fns: dict[str, int] = {}
    fn: str | None = None
    names: dict[str, str] = {}
    skip = False
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if line.startswith("part:"):
                if summary is not None:
                    out.append((summary, fns))
                summary, fns, fn, skip = None, {}, None, False
            elif line.startswith("summary:"):
                summary = int(line.split()[1])
            elif line.startswith("fn="):
                ref = line[3:].strip()
                if ref.startswith("("):
                    num, _, name = ref.partition(")")
                    name = name.strip()
                    if name:
                        names[num] = name
                    fn = names.get(num, num)
                else:
                    fn = ref
            elif line.startswith("cfn="):
                num, _, name = line[4:].strip().partition(")")
                if name.strip():
                    names[num] = name.strip()
            elif line.startswith("calls="):
                skip = True  # the next cost line is the call's inclusive cost
            elif line[:1].isdigit() or line[:1] in "+-*":
                if skip:
                    skip = False
                elif fn is not None:
                    cost = line.split()
                    if len(cost) >= 2:
                        fns[fn] = fns.get(fn, 0) + int(cost[1])
    if summary is not None:
        out.append((summary, fns))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("config")
    ap.add_argument("program")
    ap.add_argument("strategy")
    ap.add_argument("--periods", type=int, default=20000)
    ap.add_argument("--jerk", type=float, default=0.0)
    ap.add_argument("--lookahead", type=int, default=0, help="0: the config's")
    ap.add_argument("--sync", action="store_true", help="the look-ahead all at once")
    ap.add_argument("--top", type=int, default=5)
    ap.add_argument("--build", default="build")
    ap.add_argument("--bin", help="a bench_period binary (another commit's)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "cg.out")
        cmd = [
            "valgrind",
            "--tool=callgrind",
            "--collect-atstart=no",
            "--combine-dumps=yes",
            "--dump-instr=no",
            "--dump-line=no",
            f"--callgrind-out-file={out}",
            a.bin or os.path.join(a.build, "bench_period"),
            a.config,
            a.program,
            a.strategy,
            str(a.periods),
            "2",
            repr(a.jerk),
            "insns" + (",sync" if a.sync else ""),
        ]
        if a.lookahead:
            cmd.append(str(a.lookahead))
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            sys.stderr.write(r.stderr[-2000:])
            return 1
        ps = parts(out)
    if len(ps) < 2 * a.periods:  # and one at the exit
        print(f"period_insns: {len(ps)} parts for 2 x {a.periods} periods", file=sys.stderr)
        return 1
    ps = ps[a.periods : 2 * a.periods]  # the second run
    n = [s for s, _ in ps]
    order = sorted(n)

    def q(p: float) -> int:
        return order[int(p * (len(order) - 1))]

    worst = sorted(range(len(n)), key=lambda k: -n[k])[: a.top]
    print(
        f"{os.path.basename(a.program)} {a.strategy} J {a.jerk:g}"
        f"{' all at once' if a.sync else ''} lookahead {a.lookahead or 'config'}:"
        f" {a.periods} periods, instructions: first {n[0]} p50 {q(0.5)} p99 {q(0.99)}"
        f" p99.9 {q(0.999)} p99.99 {q(0.9999)} max {n[worst[0]]} at {worst[0]}"
    )
    print("  largest: " + ", ".join(f"{n[k]} at {k}" for k in worst))
    fns = sorted(ps[worst[0]][1].items(), key=lambda kv: -kv[1])[:8]
    print(f"  in period {worst[0]}: " + ", ".join(f"{f} {c}" for f, c in fns))
    return 0


if __name__ == "__main__":
    sys.exit(main())
