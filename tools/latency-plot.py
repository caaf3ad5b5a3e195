#!/usr/bin/env python3
"""Histogram plots of mlip-latency results (PNG).

    tools/latency-plot.py RUN.json [-o OUT.png]            one run
    tools/latency-plot.py A.json B.json [-o OUT.png]       two runs side by side
    tools/latency-plot.py RUN.json --cyclictest            the run beside the
                                                           cyclictest run that
                                                           --compare-cyclictest made

One row per series (wake-up latency, period jitter, compute time, CAN send
time when measured; --metric picks), one column per run. Counts on a log
scale over 1 us bins; p50, p99, p99.9, p99.99 and max marked. Rows share
their axes, so two runs compare at a glance. The x axis is linear up to
10 us and logarithmic above (--linear for a plain linear axis).

Reads mlip-latency's --json files and plain cyclictest --json files (its
single histogram is the wake-up latency). Percentiles are recomputed from the
histogram with mlip-latency's rule (nearest rank, the bin's upper edge capped
at the max), so both kinds of file are read the same way.
"""

import argparse
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

SERIES = {
    "wakeup_latency": "wake-up latency",
    "period_jitter": "period jitter",
    "compute": "compute time",
    "send": "CAN send time",
}
PCTS = [(50.0, "p50"), (99.0, "p99"), (99.9, "p99.9"), (99.99, "p99.99")]
COLORS = {
    "p50": "tab:green",
    "p99": "tab:orange",
    "p99.9": "tab:purple",
    "p99.99": "tab:brown",
    "max": "tab:red",
}


def percentile(hist: Mapping[int, int], count: int, max_us: float, pct: float) -> float:
    """mlip-latency's rule (tools/lib/latstats.h): the r-th smallest sample,
    r = ceil(pct/100 n), reported as its 1 us bin's upper edge, capped at max;
    max when it lies in the overflow."""
    if count == 0:
        return 0.0
    ppm = int(pct * 1e4 + 0.5)
    r = min(max(1, -(-count * ppm // 1000000)), count)
    seen = 0
    for b in sorted(hist):
        seen += hist[b]
        if seen >= r:
            return min(b + 1.0, max_us)
    return max_us


class Series:
    """One histogram: 1 us bins, the count, min/avg/max, the percentiles."""

    def __init__(
        self,
        hist: Mapping[str, Any],
        count: int,
        min_us: float,
        avg_us: float,
        max_us: float,
        pct: dict[str, float] | None = None,
    ) -> None:
        self.hist = {int(k): int(v) for k, v in hist.items() if int(v) > 0}
        self.count = int(count)
        self.overflow = self.count - sum(self.hist.values())
        self.min, self.avg, self.max = float(min_us), float(avg_us), float(max_us)
        # mlip-latency's own percentiles come from its full histogram (0..100 ms
        # at least), which the file may show only in part (-h): prefer them
        self.pct = pct or {name: percentile(self.hist, self.count, self.max, p) for p, name in PCTS}


class Run:
    """One column: a title and its series."""

    def __init__(self, title: str, series: dict[str, Series]) -> None:
        self.title = title
        self.series = series


def _ours(d: dict[str, Any], name: str) -> Run:
    m = d["mlip"]
    series = {}
    for key in SERIES:
        s = m.get(key)
        if s:
            pct = {name: float(s[name.replace(".", "_")]) for _, name in PCTS}
            series[key] = Series(s["histogram"], s["samples"], s["min"], s["avg"], s["max"], pct)
    rt = m.get("realtime", {})
    load = m["mode"] if m["mode"] == "idle" else f"{m['mode']} {Path(m.get('program', '')).name}"
    sched = f"FIFO {rt.get('priority')}" if rt.get("sched_fifo") else "SCHED_OTHER"
    kern = rt.get("kernel", "?") + (" PREEMPT_RT" if rt.get("preempt_rt") else "")
    title = (
        f"{name}: mlip-latency {load}\n{m['periods']} periods of {m['period_us']:g} us, "
        f"{sched}, {kern}"
    )
    return Run(title, series)


def _cyclictest(d: dict[str, Any], name: str, cmdline: str | None = None) -> Run:
    t = d["thread"]["0"]
    s = Series(t.get("histogram", {}), t["cycles"], t["min"], t["avg"], t["max"])
    cmd = cmdline or d.get("cmdline:", d.get("cmdline", "cyclictest"))
    kern = d.get("sysinfo", {}).get("release", "?")
    title = f"{name}: {cmd}\n{t['cycles']} cycles, {kern}"
    return Run(title, {"wakeup_latency": s})


def load_runs(path: str, with_cyclictest: bool) -> list[Run]:
    d = json.loads(Path(path).read_text())
    name = Path(path).name
    if "mlip" in d:
        runs = [_ours(d, name)]
        if with_cyclictest:
            ct = d.get("cyclictest")
            if not ct or not ct.get("json"):
                sys.exit(
                    f"latency-plot: {path}: no cyclictest run in it "
                    "(made by mlip-latency --compare-cyclictest --json)"
                )
            runs.append(_cyclictest(ct["json"], name, ct.get("cmdline")))
        return runs
    if "thread" in d:
        return [_cyclictest(d, name)]
    sys.exit(f"latency-plot: {path}: neither an mlip-latency nor a cyclictest JSON file")


def plot(runs: Sequence[Run], metrics: Sequence[str], out: str, linear: bool) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [m for m in metrics if any(m in r.series for r in runs)]
    if not rows:
        sys.exit("latency-plot: none of the chosen series is in the input")
    ncol = len(runs)
    fig, axes = plt.subplots(
        len(rows),
        ncol,
        figsize=(6.4 * ncol, 3.3 * len(rows) + 0.6),
        squeeze=False,
        sharex="row",
        sharey="row",
    )
    for i, key in enumerate(rows):
        xmax = max((r.series[key].max for r in runs if key in r.series), default=1.0)
        ymax = max(
            (max(r.series[key].hist.values(), default=1) for r in runs if key in r.series),
            default=1,
        )
        for j, run in enumerate(runs):
            ax = axes[i][j]
            s = run.series.get(key)
            if i == 0:
                ax.set_title(run.title, fontsize=8.5, loc="left")
            if s is None:
                ax.text(
                    0.5,
                    0.5,
                    f"no {SERIES[key]} in this run",
                    ha="center",
                    va="center",
                    transform=ax.transAxes,
                    color="0.4",
                )
                ax.set_axis_off()
                continue
            top = max(s.hist) + 1 if s.hist else 1
            edges = list(range(top + 1))
            counts = [s.hist.get(b, 0) for b in range(top)]
            ax.stairs(counts, edges, fill=True, color="tab:blue", alpha=0.55, lw=0)
            ax.stairs(counts, edges, color="tab:blue", lw=0.8)
            ax.set_yscale("log")
            ax.set_ylim(0.7, ymax * 3)
            marks = [(n, v) for n, v in s.pct.items()] + [("max", s.max)]
            for n, v in marks:
                ax.axvline(v, color=COLORS[n], ls="-" if n == "max" else "--", lw=1.1)
            legend = [f"{n} {v:.1f} us" for n, v in marks]
            for k, (n, _) in enumerate(marks):
                ax.plot([], [], color=COLORS[n], ls="-" if n == "max" else "--", label=legend[k])
            ax.legend(
                fontsize=7.5,
                loc="upper right",
                framealpha=0.85,
                title=f"{s.count} samples, avg {s.avg:.1f} us"
                + (f"\n{s.overflow} beyond the histogram shown" if s.overflow else ""),
                title_fontsize=7.5,
            )
            ax.set_xlabel(f"{SERIES[key]}, us (1 us bins)", fontsize=9)
            if j == 0:
                ax.set_ylabel("periods", fontsize=9)
            ax.grid(True, which="major", alpha=0.3)
            ax.tick_params(labelsize=8)
        ax0 = axes[i][0]
        if linear:
            ax0.set_xlim(0, xmax * 1.05 + 1)
        else:
            ax0.set_xscale("symlog", linthresh=10, linscale=0.6)
            ax0.set_xlim(0, max(20.0, xmax * 1.3))
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    doc = __doc__ or "\n\n"
    ap = argparse.ArgumentParser(
        description=doc.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=doc.split("\n\n", 1)[1],
    )
    ap.add_argument("json", nargs="+", help="one or two result files")
    ap.add_argument("-o", "--output", help="PNG to write (default: first input with .png)")
    ap.add_argument(
        "--metric",
        action="append",
        choices=list(SERIES),
        help="series to plot (repeatable; default: all that were measured)",
    )
    ap.add_argument(
        "--cyclictest",
        action="store_true",
        help="add the cyclictest run stored by --compare-cyclictest as a column",
    )
    ap.add_argument("--linear", action="store_true", help="linear x axis")
    a = ap.parse_args(argv)
    if len(a.json) > 2:
        ap.error("at most two result files (side by side)")
    runs = []
    for p in a.json:
        runs += load_runs(p, a.cyclictest)
    out = a.output or str(Path(a.json[0]).with_suffix(".png"))
    plot(runs, a.metric or list(SERIES), out, a.linear)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
