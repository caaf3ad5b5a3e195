"""The demo's plot: the tool speed decoded from the bus against time, the
feed limits marked (matplotlib, imported when called)."""

import json
import math
from pathlib import Path

from .config import StrPath


def plot(outdir: StrPath, png: StrPath) -> None:
    """Speed vs time from the bus stage's decoded positions (outdir/decoded.csv,
    outdir/demo.json), written to png."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(outdir)
    info = json.loads((out / "demo.json").read_text())
    T = info["period_s"]
    n = len(info["axes"])
    t, pos = [], []
    with open(out / "decoded.csv") as fh:
        fh.readline()
        for line in fh:
            f = [float(v) for v in line.split(",")]
            t.append(f[0])
            pos.append(f[1 : 1 + n])
    lin = info["linear"]
    sp, ts = [], []
    for k in range(1, len(pos)):
        d = sum((pos[k][i] - pos[k - 1][i]) ** 2 for i in range(n) if lin[i])
        sp.append(math.sqrt(d) / T)
        ts.append((t[k] + t[k - 1]) / 2)
    w = 9  # a centred moving average over 9 periods, to see through the 1-count steps
    avg = []
    for i in range(len(sp)):
        win = sp[max(0, i - w // 2) : i + w // 2 + 1]
        avg.append(sum(win) / len(win))
    fig, ax = plt.subplots(figsize=(11, 5.6), dpi=110)
    ax.plot(
        ts,
        sp,
        lw=0.5,
        color="#9ecae1",
        label="tool speed from the decoded CAN positions, per period",
    )
    ax.plot(ts, avg, lw=1.2, color="#08519c", label=f"the same, {w}-period moving average")
    vmax = info["vmax_mm_s"]
    ax.axhline(
        vmax,
        color="#d62728",
        ls="--",
        lw=1.4,
        label=f"feed limit v_m (MAX_LINEAR_VELOCITY) = {vmax:g} mm/s: G0 moves run at it",
    )
    feeds = [f for f in info["feeds_mm_s"] if f < vmax]
    for j, fmm in enumerate(feeds):
        label = "programmed feeds: " + ", ".join(f"F{f * 60:g} = {f:g} mm/s" for f in feeds)
        ax.axhline(fmm, color="#ff7f0e", ls=":", lw=1.3, label=label if j == 0 else None)
    ax.set_xlim(0, t[-1] if t else 1)
    ax.set_ylim(0, vmax * 1.1)
    ax.set_xlabel("time since the program's first period on the bus (s)")
    ax.set_ylabel("tool speed, X Y Z (mm/s)")
    ok = sum(1 for c in info["checks"] if c["ok"])
    ax.set_title(
        f"{Path(info['program']).name}: mlip-rt -> CAN ({info['profile']}) -> mlip-listen\n"
        f"{info['machining_s']:.3f} s of machining, {info['blocks']} blocks, "
        f"{info['cycles']} cycles on the bus, {ok} of {len(info['checks'])} checks passed "
        f"(bus == mlip-sim to the count, mlip-check)",
        fontsize=10,
    )
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8.5, frameon=False)
    fig.tight_layout()
    fig.savefig(png)
    print(f"demo: velocity profile written to {png}")
