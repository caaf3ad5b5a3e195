"""The listener's outputs: decoded cycles (CSV), every frame (candump -l
text, written here for speed; other formats through can.Logger), the
report's period statistics."""

import math
from collections import Counter
from collections.abc import Iterable
from typing import Any

from .config import Setup, StrPath
from .decoders import U32, Decoder
from .layout import CAN_EFF_FLAG, CAN_EFF_MASK, CAN_ERR_FLAG, CAN_RTR_FLAG, CAN_SFF_MASK

# one frame as the listener keeps it: (t ns, raw id with the linux/can.h
# flags, CAN FD flags or None for a classic frame, data)
Frame = tuple[int, int, int | None, bytes]


def fmt_ts(t_ns: int, digits: int = 6) -> str:
    s, ns = divmod(t_ns, 1000000000)
    if digits == 6:
        return f"{s}.{ns // 1000:06d}"
    return f"{s}.{ns:09d}"


def write_log(path: StrPath, frames: Iterable[Frame], iface: str) -> None:
    with open(path, "w") as fh:
        w = fh.write
        for t, raw_id, fl, data in frames:
            if raw_id & CAN_ERR_FLAG or raw_id & CAN_EFF_FLAG:
                cid = f"{raw_id & (CAN_EFF_MASK | CAN_ERR_FLAG):08X}"
            else:
                cid = f"{raw_id & CAN_SFF_MASK:03X}"
            if fl is not None:
                w(f"({fmt_ts(t)}) {iface} {cid}##{fl & 0xF:X}{data.hex().upper()}\n")
            elif raw_id & CAN_RTR_FLAG:
                w(f"({fmt_ts(t)}) {iface} {cid}#R\n")
            else:
                w(f"({fmt_ts(t)}) {iface} {cid}#{data.hex().upper()}\n")


def write_csv(path: StrPath, dec: Decoder, setup: Setup) -> None:
    axes = [a.lower() for a in setup.axes]
    cpu = setup.cpu
    n = len(axes)
    with open(path, "w") as fh:
        fh.write(",".join(["cycle", "t"] + axes + ["c" + a for a in axes]) + "\n")
        w = fh.write
        for c, t, cnt in zip(dec.cyc, dec.tns, dec.counts, strict=True):
            w(
                f"{c},{fmt_ts(t, 9)},"
                + ",".join(repr(cnt[i] / cpu[i]) for i in range(n))
                + ","
                + ",".join(str(v) for v in cnt)
                + "\n"
            )


def percentile(sorted_vals: list[int], q: float) -> int | None:
    """Nearest-rank percentile (q in 0..100) of a sorted list."""
    if not sorted_vals:
        return None
    k = max(0, min(len(sorted_vals) - 1, math.ceil(q / 100.0 * len(sorted_vals)) - 1))
    return sorted_vals[k]


def timing(dec: Decoder, profile: str, period_s: float) -> dict[str, Any]:
    """Period as seen on the bus: differences of SYNC timestamps (cia402) or of
    the first-frame timestamps of consecutive counter values (packed, fd)."""
    if profile == "cia402":
        ts = dec.period_ts
        iv = [b - a for a, b in zip(ts, ts[1:], strict=False)]
        what = "SYNC to SYNC"
    else:
        iv = []
        pts = dec.period_pairs
        for (c0, t0), (c1, t1) in zip(pts, pts[1:], strict=False):
            if (c1 - c0) % U32 == 1:
                iv.append(t1 - t0)
        what = "first frame of cycle k to cycle k+1 (consecutive counters)"
    out: dict[str, Any] = {"what": what, "nominal_us": period_s * 1e6, "intervals": len(iv)}
    if not iv:
        return out
    s = sorted(iv)

    def us(v: int | None) -> float | None:
        return None if v is None else round(v / 1000.0, 3)

    mean = sum(s) / len(s)
    var = sum((v - mean) ** 2 for v in s) / len(s)
    nom = period_s * 1e9
    hist = Counter(v // 1000 for v in s)  # 1-us bins, [k, k+1) us
    bins = sorted(hist.items())

    def within(d: float) -> float:
        return sum(1 for v in s if abs(v - nom) <= d * 1000) / len(s)

    top = hist.most_common(10)
    out.update(
        {
            "min_us": us(s[0]),
            "p50_us": us(percentile(s, 50)),
            "p99_us": us(percentile(s, 99)),
            "p99_9_us": us(percentile(s, 99.9)),
            "max_us": us(s[-1]),
            "mean_us": round(mean / 1000.0, 3),
            "std_us": round(math.sqrt(var) / 1000.0, 3),
            "within_10us": round(within(10), 6),
            "within_100us": round(within(100), 6),
            "within_500us": round(within(500), 6),
            "over_2x": sum(1 for v in s if v > 2 * nom),
            "histogram": {
                "bin_us": 1,
                "note": "bin k counts intervals in [k, k+1) us",
                "bins_used": len(bins),
                "top": [[int(k), c] for k, c in top],
                "bins": [[int(k), c] for k, c in bins],
            },
        }
    )
    return out


def position_record(dec: Decoder, setup: Setup, idx: int) -> dict[str, Any]:
    c = dec.counts[idx]
    return {
        "cycle": dec.cyc[idx],
        "t": dec.tns[idx] / 1e9,
        "pos": {a: c[i] / setup.cpu[i] for i, a in enumerate(setup.axes)},
        "counts": {a: c[i] for i, a in enumerate(setup.axes)},
    }


def read_csv(path: StrPath, n: int) -> tuple[list[int], list[float], list[tuple[int, ...]]]:
    """write_csv's file (the listener's --csv) -> (cycles, t seconds, counts)."""
    cyc, ts, cnt = [], [], []
    with open(path) as fh:
        header = fh.readline().strip().split(",")
        if header[:2] != ["cycle", "t"] or len(header) != 2 + 2 * n:
            raise ValueError(f"{path}: not the listener's CSV of {n} axes: {header}")
        for line in fh:
            f = line.rstrip("\n").split(",")
            cyc.append(int(f[0]))
            ts.append(float(f[1]))
            cnt.append(tuple(int(v) for v in f[2 + n :]))
    return cyc, ts, cnt
