"""Comparisons for the end-to-end runs: the setpoints mlip-sim computes
against what the bus carried and what the drives applied, in drive counts,
and the physics of decoded positions judged by mlip-check. Standard library
only (the emulated test VM pays for every import)."""

import json
import math
import re
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .config import MachineLimits, StrPath
from .procs import run_tool
from .settings import Settings

Counts = tuple[int, ...]


# ------------------------------------------------------------------ numbers


def to_counts(pos: float, cpu: float) -> int:
    """round(pos * cpu), ties away from zero: mlip_can_counts of canenc.h (the
    product is the same IEEE double multiplication as in C)."""
    x = pos * cpu
    a = abs(x)
    r = math.floor(a)
    if a - r >= 0.5:  # exact for |x| < 2^52
        r += 1
    return int(-r if x < 0 else r)


def read_trace(path: StrPath) -> tuple[list[str], list[tuple[float, ...]]]:
    """mlip-sim --trace CSV -> (header, rows of floats)."""
    with open(path) as fh:
        header = fh.readline().strip().split(",")
        rows = [tuple(float(v) for v in line.split(",")) for line in fh if line.strip()]
    return header, rows


def trace_counts(rows: Sequence[Sequence[float]], cpu: Sequence[float]) -> list[Counts]:
    """Trace rows (t, x, y, ...) -> drive counts per axis."""
    return [tuple(to_counts(r[1 + i], c) for i, c in enumerate(cpu)) for r in rows]


def write_positions_csv(
    path: StrPath,
    counts: Sequence[Counts],
    cpu: Sequence[float],
    period_s: float,
    cycles: Sequence[int] | None = None,
) -> None:
    """A trace for mlip-check: t,x,y,... from decoded counts, t = k T, k the
    row's index or, given cycles, its bus cycle number (holes where cycles
    were lost: mlip-check takes no difference across them)."""
    n = len(cpu)
    names = "xyzabc"[:n]  # header only; mlip-check reads the columns by position
    ks = range(len(counts)) if cycles is None else [c - cycles[0] for c in cycles]
    with open(path, "w") as fh:
        fh.write("t," + ",".join(names) + "\n")
        for k, c in zip(ks, counts, strict=False):
            fh.write(
                repr(k * period_s) + "," + ",".join(repr(c[i] / cpu[i]) for i in range(n)) + "\n"
            )


def cut_program(src: StrPath, n_lines: int, dst: Path) -> Path:
    """The first n_lines lines of a program (its header sets units and modes)."""
    with open(src) as fh, open(dst, "w") as out:
        for i, line in enumerate(fh):
            if i >= n_lines:
                break
            out.write(line)
    return dst


def ini_set(text: str, section: str, key: str, value: object) -> str:
    """A machine INI's text with KEY's value in [SECTION] replaced (the key
    must be there: the change is asserted, never silently lost)."""
    pat = rf"(^\[{section}\][ \t]*$(?:\n(?!\[).*)*?\n{key}[ \t]*=[ \t]*)[^\s#;]+"
    out, n = re.subn(pat, lambda m: m.group(1) + str(value), text, count=1, flags=re.M)
    if n != 1:
        raise ValueError(f"no {key} in [{section}]")
    return out


# ------------------------------------------------------------------ the C tools


def simulate(
    s: Settings, config: StrPath, ngc: StrPath, workdir: StrPath, *sim_args: object
) -> tuple[list[tuple[float, ...]], dict[str, Any]]:
    """mlip-sim on the same machine and program: (trace rows, summary)."""
    trace = Path(workdir) / "sim.csv"
    summ = Path(workdir) / "sim.json"
    run_tool(
        [s.tool("mlip-sim"), "-q", "--config", config, "--trace", trace, "--summary", summ]
        + list(sim_args)
        + [ngc]
    )
    summary: dict[str, Any] = json.loads(summ.read_text())
    return read_trace(trace)[1], summary


def mlip_check(
    s: Settings,
    config: StrPath,
    ngc: StrPath,
    trace_csv: StrPath,
    quantum: float,
    json_out: StrPath | None = None,
) -> tuple["subprocess.CompletedProcess[str]", dict[str, Any] | None]:
    """mlip-check --quantum on a trace of decoded positions: (process, its
    --json measurements or None)."""
    args: list[object] = [s.tool("mlip-check"), "--config", config, "--quantum", repr(quantum)]
    if json_out:
        args += ["--json", json_out]
    p = run_tool(args + [ngc, trace_csv], check=False)
    js = None
    if json_out and Path(json_out).exists():
        js = json.loads(Path(json_out).read_text())
    return p, js


def check_bounds(
    m: MachineLimits, js: dict[str, Any], quantum: float, max_abs: float, rel: float = 1e-9
) -> list[str]:
    """mlip-check's verdict redone from its --json measurements, without the
    end-on-the-last-point condition (after a stop the machine rests elsewhere
    on the path): the bounds of tools/mlip-check.c and check.c exactly, with
    abs_acc = rounding floor (8 max|x| DBL_EPSILON / T^2) + 4 quantum / T^2:
    acceleration <= A (1 + rel) + abs_acc, jerk (an axis with MAX_JERK)
    <= J (1 + rel) + 2 abs_acc / T, axis velocity and tool speed
    <= limit (1 + rel) + abs_acc T, contour <= eps (1 + rel) + quantum, no
    sample out of order.
    Returns the violations (strings)."""
    T = m.period_s
    abs_acc = 8 * max_abs * sys.float_info.epsilon / T**2 + 4 * quantum / T**2
    bad = []
    for k, a in enumerate(js["max_axis_accel"]):
        lim = m.accel[k] * (1 + rel) + abs_acc
        if a > lim:
            bad.append(f"axis {m.axes[k]} acceleration {a:.12g} > {lim:.12g}")
    for k, j in enumerate(js.get("max_axis_jerk", [])):
        if m.jerk[k] > 0:
            lim = m.jerk[k] * (1 + rel) + 2 * abs_acc / T
            if j > lim:
                bad.append(f"axis {m.axes[k]} jerk {j:.12g} > {lim:.12g}")
    for k, v in enumerate(js["max_axis_vel"]):
        lim = m.vel[k] * (1 + rel) + abs_acc * T
        if v > lim:
            bad.append(f"axis {m.axes[k]} velocity {v:.12g} > {lim:.12g}")
    lim = m.vmax * (1 + rel) + abs_acc * T
    if js["max_speed_mm_s"] > lim:
        bad.append(f"tool speed {js['max_speed_mm_s']:.12g} > {lim:.12g}")
    lim = m.eps * (1 + rel) + quantum
    if js["max_contour_error_mm"] > lim:
        bad.append(f"contour error {js['max_contour_error_mm']:.12g} > {lim:.12g}")
    if js.get("order_errors"):
        bad.append(f"{js['order_errors']} sample(s) out of order along the path")
    return bad


# ------------------------------------------------------------------ alignment


def align(can_counts: Sequence[Counts], trc: Sequence[Counts]) -> tuple[int, str]:
    """Offset o such that CAN cycle o + i carries trace row i. The controller
    sends the home position while idle and pre-reading; the first row of the
    trace that differs from its start is matched with the first cycle on the
    bus that differs from home. Returns (offset, explanation)."""
    home = trc[0]
    k0 = next((i for i, c in enumerate(trc) if c != home), None)
    c0 = next((i for i, c in enumerate(can_counts) if c != home), None)
    if k0 is None:
        raise AssertionError("the simulated trace never leaves its start point (in counts)")
    if c0 is None:
        raise AssertionError(
            f"the bus never leaves the home position {home} (counts): {len(can_counts)} cycles seen"
        )
    return c0 - k0, f"trace row {k0} (first to move) is bus cycle index {c0}"


def first_mismatch(can_counts: Sequence[Counts], trc: Sequence[Counts], offset: int) -> str | None:
    """None when can_counts[offset + i] == trc[i] for every row, else a message."""
    if offset < 0:
        return f"negative offset {offset}: the bus moved before the trace did"
    if offset + len(trc) > len(can_counts):
        return (
            f"the bus has {len(can_counts)} cycles, the trace needs {offset + len(trc)} "
            f"(offset {offset} + {len(trc)} rows)"
        )
    for i, want in enumerate(trc):
        got = can_counts[offset + i]
        if got != want:
            return f"trace row {i} (bus cycle index {offset + i}): bus {got}, sim {want}"
    return None


def targets_by_sync(rows: Sequence[dict[str, Any]], nodes: Sequence[int]) -> list[Counts]:
    """The drive simulator's sync rows (procs.DriveSimProc.sync_rows) -> per
    SYNC with a fresh target for every node: the tuple of targets (counts), in
    SYNC order."""
    by: dict[int, dict[int, int]] = {}
    for r in rows:
        if r["node"] in nodes and r["target"] is not None and r["fresh"]:
            by.setdefault(r["sync"], {})[r["node"]] = r["target"]
    return [tuple(d[n] for n in nodes) for _, d in sorted(by.items()) if len(d) == len(nodes)]


def trim(seq: Sequence[Counts]) -> Sequence[Counts]:
    """Without the leading and trailing repeats (the machine at rest)."""
    i = 0
    while i + 1 < len(seq) and seq[i + 1] == seq[i]:
        i += 1
    j = len(seq)
    while j - 1 > i and seq[j - 2] == seq[j - 1]:
        j -= 1
    return seq[i:j]


def longest_still_run(counts: Sequence[Counts], start: int, end: int) -> tuple[int, int]:
    """Longest run of identical consecutive positions in counts[start:end]:
    (length, index of its first cycle)."""
    best, best_at, run_len, run_at = 0, start, 1, start
    for i in range(start + 1, end):
        if counts[i] == counts[i - 1]:
            run_len += 1
        else:
            run_len, run_at = 1, i
        if run_len > best:
            best, best_at = run_len, run_at
    return best, best_at


def speeds(
    counts: Sequence[Counts], cpu: Sequence[float], period_s: float, linear: Sequence[bool]
) -> list[float]:
    """Tool speed (linear axes, mm/s) between consecutive cycles."""
    out = []
    for a, b in zip(counts, counts[1:], strict=False):
        s = 0.0
        for i, c in enumerate(cpu):
            if linear[i]:
                d = (b[i] - a[i]) / c
                s += d * d
        out.append(math.sqrt(s) / period_s)
    return out
