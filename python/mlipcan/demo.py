"""The demo's bus stage (tools/demo.sh; `mlip-demo demo OUTDIR`): mlip-rt,
the listener and mlip-feed on one program; what happened, checked: every
frame sent was received, the bus carries mlip-sim's trace to the last count,
mlip-check finds the decoded positions within the limits. Standard library
only (the emulated test VM pays for every import)."""

import json
import re
import time
from pathlib import Path
from typing import Any

from .compare import align, first_mismatch, mlip_check, simulate, trace_counts, write_positions_csv
from .config import MachineLimits, StrPath, setup_of
from .procs import Rig
from .settings import Settings


def demo(
    s: Settings,
    outdir: StrPath,
    config: StrPath | None = None,
    ngc: StrPath | None = None,
    profile: str = "cia402",
) -> int:
    """mlip-rt + mlip-feed + the listener on one program (default
    examples/demo.ngc on config/mill-3axis.ini); what happened, checked.
    Writes outdir/decoded.csv (t,x,y,... from the first period on the bus),
    outdir/demo.json and the processes' logs. Returns the number of failed
    checks."""
    config = Path(config) if config is not None else s.config_dir / "mill-3axis.ini"
    ngc = Path(ngc) if ngc is not None else s.root / "examples" / "demo.ngc"
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    work = out / "run"
    work.mkdir(exist_ok=True)
    setup = setup_of(s, config)
    lim = MachineLimits.of(s, config)
    T = setup.period_s
    print(
        f"demo: {ngc.name} on {config.name} ({' '.join(setup.axes)}), CAN profile {profile} "
        f"on {s.iface}{' (inside the test VM)' if s.in_vm else ''}",
        flush=True,
    )
    rows, summ = simulate(s, config, ngc, work)
    trc = trace_counts(rows, setup.cpu)
    print(
        f"demo: mlip-sim says {summ['total_time_s']:.3f} s of machining, {summ['blocks']} blocks, "
        f"{summ['path_length_mm']:.1f} mm",
        flush=True,
    )
    t0 = time.monotonic()
    rig = Rig(s, config, profile, work)
    with rig:
        print(
            f"demo: listener and mlip-rt up ({time.monotonic() - t0:.1f} s); mlip-feed "
            f"{ngc.name} ...",
            flush=True,
        )
        rc, fout, ferr = rig.feed(ngc)
        done = rig.wait_state("idle", timeout=60)
    r = rig.result
    rep, rt = r["report"], r.get("rt", {})
    checks: list[tuple[bool, str]] = []

    def check(ok: object, what: str) -> None:
        checks.append((bool(ok), what))
        print(f"  [{'ok' if ok else 'FAILED'}] {what}", flush=True)

    can = r.get("counts", [])
    print(f"demo: mlip-feed exit {rc}; {ferr.strip().splitlines()[-1] if ferr.strip() else ''}")
    print(f"demo: mlip-rt: {rt.get('line', r['rt_stderr'].strip().splitlines()[-1:])}")
    print(f"demo: listener: {r['listen_stdout'].strip()}", flush=True)
    n = len(setup.axes)
    per = {"cia402": 1 + n, "packed": (n + 1) // 2 + 1, "fd": 1}[profile]
    check(rc == 0, f"mlip-feed exited {rc} (0: every block executed, machine at rest)")
    check(
        done["exec_seq"] == summ["blocks"] + 1,
        f"exec_seq {done['exec_seq']} = {summ['blocks']} blocks + END",
    )
    check(
        r["rt_rc"] == 0 and rt.get("tx_dropped") == 0,
        f"mlip-rt stopped cleanly on SIGTERM, {rt.get('tx_dropped')} frames dropped at send",
    )
    check(
        rep["frames_ours"] == rt.get("frames_sent") == rt.get("periods", -1) * per,
        f"frames: {rt.get('frames_sent')} sent in {rt.get('periods')} periods, "
        f"{rep['frames_ours']} received",
    )
    anomalies = ("gaps", "incomplete", "duplicates", "stray", "malformed", "socket_drops")
    clean = not any(rep.get(k) for k in anomalies)
    check(
        clean and rep["cycles"] == rt.get("periods") and r["cycles"] == list(range(rep["cycles"])),
        f"cycles: {rep['cycles']} complete, numbered 0..{rep['cycles'] - 1}, {rep['gaps']} lost, "
        f"{rep['incomplete']} incomplete, {rep['stray']} stray, {rep.get('socket_drops')} dropped",
    )
    bad: str | None
    try:
        off, _ = align(can, trc)
        bad = first_mismatch(can, trc, off)
    except AssertionError as e:
        off, bad = 0, str(e)
    check(
        bad is None,
        f"the bus carries mlip-sim's trace to the last count: {len(trc)} rows "
        f"= cycles {off}..{off + len(trc) - 1}" + (f" -- {bad}" if bad else ""),
    )
    tail = can[off + len(trc) :]
    check(
        tail and all(c == trc[-1] for c in tail),
        f"then at rest on the program's last point for {len(tail)} cycles",
    )
    moving = can[max(off, 0) :]
    quantum = max(1.0 / c for c in setup.cpu)
    write_positions_csv(out / "decoded.csv", moving, setup.cpu, T)
    p, js = mlip_check(s, config, ngc, out / "decoded.csv", quantum, out / "check.json")
    msg = p.stderr.strip().splitlines()[-1] if p.stderr.strip() else ""
    check(p.returncode == 0, f"mlip-check --quantum {quantum:g} on the decoded positions: {msg}")
    machining = (len(trc) - 1) * T
    tm = rep["timing"]
    info: dict[str, Any] = {
        "program": str(ngc),
        "config": str(config),
        "profile": profile,
        "in_vm": s.in_vm,
        "machining_s": machining,
        "sim_s": summ["total_time_s"],
        "blocks": summ["blocks"],
        "path_mm": summ["path_length_mm"],
        "frames": rep["frames_ours"],
        "cycles": rep["cycles"],
        "periods": rt.get("periods"),
        "overruns": rt.get("overruns"),
        "offset": off,
        "period_s": T,
        "vmax_mm_s": lim.vmax,
        "axes": setup.axes,
        "linear": [a in "XYZ" for a in setup.axes],
        "max_speed_mm_s": js and js.get("max_speed_mm_s"),
        "max_contour_mm": js and js.get("max_contour_error_mm"),
        "bus_period_us": {
            k: tm.get(k) for k in ("min_us", "p50_us", "p99_us", "p99_9_us", "max_us")
        },
        "feeds_mm_s": program_feeds(ngc),
        "checks": [{"ok": ok, "what": w} for ok, w in checks],
    }
    (out / "demo.json").write_text(json.dumps(info, indent=1) + "\n")
    for name in ("can.json", "rt.err", "feed.err", "listen.err"):
        if (work / name).exists():
            (out / name).write_text((work / name).read_text())
    failed = sum(1 for ok, _ in checks if not ok)
    print(
        f"demo: machining {machining:.3f} s ({summ['blocks']} blocks, "
        f"{summ['path_length_mm']:.1f} mm), {rep['frames_ours']} frames, {rep['cycles']} cycles; "
        f"bus period p50 {tm.get('p50_us')} us, p99 {tm.get('p99_us')} us, "
        f"max {tm.get('max_us')} us"
        + (" (emulated VM: timing says nothing about real time)" if s.in_vm else "")
    )
    print(f"demo: {len(checks) - failed} of {len(checks)} checks passed", flush=True)
    return failed


def program_feeds(ngc: StrPath) -> list[float]:
    """The distinct F words of a program, in mm/s (F is in units per minute)."""
    feeds = set()
    with open(ngc) as fh:
        for line in fh:
            code = re.sub(r"\(.*?\)|;.*", "", line)
            for m in re.finditer(r"[Ff]\s*([0-9.]+)", code):
                feeds.add(float(m.group(1)) / 60.0)
    return sorted(feeds)
