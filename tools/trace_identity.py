#!/usr/bin/env python3
"""Setpoint traces of this tree against another commit's, byte for byte.

    tools/trace_identity.py [--base REV] [--shared DIR] [--jobs N] [--quick]

Builds REV (default: origin/main, else main) in a temporary git worktree,
then runs both builds' mlip-sim on every file of ../shared/toolpaths (and
senders/) with every strategy (mpct, bisector, stop, smooth) at the paper's
setting (1000 mm/s^2, 200 mm/s, eps 0.01, F words ignored), with the
programs' own feeds, and under a seeded override storm, and compares the
SHA-256 of each trace and the exit status. A refactor that must not change
behaviour (layout, renames, formatting) passes only if every trace is the
same. Exit 0: all identical; 1: a difference (each one listed); 2: setup.
"""

import argparse
import concurrent.futures
import hashlib
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STRATEGIES = ("mpct", "bisector", "stop", "smooth")
SETTINGS = {
    "paper": ["--accel", "1000", "--vmax", "200", "--eps", "0.01", "--feed", "200"],
    "program": ["--accel", "3000", "--vmax", "200", "--eps", "0.01"],
    "storm": ["--accel", "1000", "--vmax", "200", "--eps", "0.01", "--feed", "200", "--storm", "7"],
}


def build(tree: Path, build_dir: Path) -> Path:
    r = subprocess.run(
        ["make", "-s", "-j2", f"BUILD={build_dir}", f"{build_dir}/mlip-sim"],
        cwd=tree,
        capture_output=True,
        text=True,
    )
    if r.returncode != 0:
        sys.exit(f"trace_identity: build of {tree} failed:\n{r.stdout}{r.stderr}")
    return build_dir / "mlip-sim"


def run(sim: Path, prog: Path, strategy: str, setting: str, tmp: Path) -> tuple[int, str]:
    out = tmp / f"{os.getpid()}-{sim.parent.name}-{prog.name}-{strategy}-{setting}.csv"
    r = subprocess.run(
        [
            str(sim),
            "-q",
            "--strategy",
            strategy,
            *SETTINGS[setting],
            "--trace",
            str(out),
            str(prog),
        ],
        capture_output=True,
    )
    h = hashlib.sha256()
    if out.exists():
        with open(out, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        out.unlink()
    return r.returncode, h.hexdigest()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--base", default=None, help="commit to compare with (default origin/main or main)"
    )
    ap.add_argument("--shared", default=os.environ.get("MLIP_SHARED", str(ROOT.parent / "shared")))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="the paper setting only")
    a = ap.parse_args()

    tp = Path(a.shared) / "toolpaths"
    progs = sorted(p for p in tp.iterdir() if p.is_file() and p.suffix != ".md")
    progs += sorted(p for p in (tp / "senders").iterdir() if p.is_file())
    if not progs:
        print(f"trace_identity: no toolpaths in {tp}", file=sys.stderr)
        return 2
    base = a.base
    if base is None:
        for cand in ("origin/main", "main"):
            if (
                subprocess.run(
                    ["git", "rev-parse", "-q", "--verify", cand], cwd=ROOT, capture_output=True
                ).returncode
                == 0
            ):
                base = cand
                break
    rev = subprocess.run(
        ["git", "rev-parse", base], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    if not rev:
        print(f"trace_identity: no commit {base}", file=sys.stderr)
        return 2

    with tempfile.TemporaryDirectory(prefix="mlip-traces-") as td:
        tmp = Path(td)
        wt = tmp / "base"
        subprocess.run(
            ["git", "worktree", "add", "--detach", str(wt), rev],
            cwd=ROOT,
            check=True,
            capture_output=True,
        )
        try:
            sims = {"base": build(wt, tmp / "build-base"), "this": build(ROOT, tmp / "build-this")}
            settings = ["paper"] if a.quick else list(SETTINGS)
            jobs = [(p, s, st) for p in progs for s in STRATEGIES for st in settings]
            res: dict[tuple[str, Path, str, str], tuple[int, str]] = {}
            with concurrent.futures.ThreadPoolExecutor(a.jobs) as ex:
                futs = {
                    ex.submit(run, sims[w], p, s, st, tmp): (w, p, s, st)
                    for (p, s, st) in jobs
                    for w in sims
                }
                for f in concurrent.futures.as_completed(futs):
                    res[futs[f]] = f.result()
        finally:
            subprocess.run(
                ["git", "worktree", "remove", "--force", str(wt)], cwd=ROOT, capture_output=True
            )
    diff = 0
    for p, s, st in jobs:
        b, t = res[("base", p, s, st)], res[("this", p, s, st)]
        if b != t:
            diff += 1
            print(
                f"DIFFERS {p.name} {s} {st}: base exit {b[0]} {b[1][:12]}, "
                f"this exit {t[0]} {t[1][:12]}"
            )
    print(
        f"trace_identity: {len(jobs) - diff} of {len(jobs)} traces identical to {base} "
        f"({rev[:10]}): {len(progs)} files x {len(STRATEGIES)} strategies x "
        f"{len(settings)} settings"
    )
    return 1 if diff else 0


if __name__ == "__main__":
    sys.exit(main())
