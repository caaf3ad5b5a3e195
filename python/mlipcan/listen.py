"""mlip-listen - watch the setpoint frames mlip-rt puts on a CAN bus.

    mlip-listen (--can IFACE | --from-log FILE) [--config FILE] [--profile P]
                [--csv OUT] [--log OUT] [--json OUT] [--tpdo-csv OUT] [--duration S]
                [--receive auto|python-can|fast|recvmsg]
    mlip-listen --check-layout [--config FILE] [--profile P]

Rebuilds every axis position of every period from the frames of the output
profile (include/mlip/can/canenc.h, tools/mlip.dbc) and reports what a drive would
have seen: cycles, lost cycles, incomplete cycles, strays, and the period as
seen on the bus.

  cia402  a cycle is a SYNC followed by one RPDO per node; the cycle number is
          the SYNC count from 0 (there is no counter on the wire). Reported: a
          SYNC that arrives before every RPDO of the previous one did
          (incomplete, missing RPDOs), an RPDO twice after one SYNC (duplicate,
          the cycle is dropped), RPDOs with no SYNC before them (stray; a whole
          set of them: a missing SYNC).
  packed  POS frames then a COMMIT carrying the cycle counter: a COMMIT with a
          POS frame missing is incomplete, a POS id twice before a COMMIT
          means the COMMIT was lost, the counter stepping by more than 1 means
          whole cycles lost (gaps), by 0 a duplicate.
  fd      one frame per cycle carrying the counter: gaps and duplicates.

Outputs:
  stdout      one summary line
  --csv OUT   one row per decoded (complete) cycle: cycle,t,x,y,...,cx,cy,...
              t = receive timestamp (s, CLOCK_REALTIME, kernel) of the cycle's
              first frame; positions in mm/deg = counts / COUNTS_PER_UNIT;
              cx,... the raw drive counts
  --log OUT   every frame: candump -l text (.log: (1700000000.123456) vcan0 201#39300000),
              or any format can.Logger writes (.asc, .blf, ...)
  --json OUT  the report: counters, period statistics (min/p50/p99/p99.9/max,
              1-us histogram), first and last positions, socket drops

Live (--can), two receive paths (--receive, default auto):
  python-can  can.Bus on SocketCAN (mlipcan.bus, shared with the drive
              simulator), a can.Notifier feeding the decoder, --log through
              can.Logger (the format by extension: .log candump -L, .asc, .blf).
              Used wherever the kernel has vcan/CAN (a real controller, any
              distribution kernel): python-can keeps up with thousands of
              frames a second there. Kernel drops are not reported
              ("socket_drops": null).
  fast        a raw CAN socket (stdlib, set up as python-can's socketcan
              interface does) read with recvmmsg(2) through ctypes, up to 512
              frames a call, whole regular cycles decoded by slicing; kernel
              timestamps (SO_TIMESTAMPNS) and the drop counter (SO_RXQ_OVFL).
              Used in the software-emulated test VM (MLIP_IN_VM=1: auto picks
              it): there importing python-can alone costs tens of seconds and
              Bus.recv 740-2600 us a frame (cannot keep up with 4000 frames/s),
              the batches about 100 us. --receive recvmsg: one recvmsg a frame.
Both enlarge the receive buffer (SO_RCVBUFFORCE as root, --rcvbuf, default
16 MiB). With a CiA 402 deployment ([DRIVES] ENABLE = 1: 6-byte RPDOs with
the controlword) the drives' TPDOs (statusword, position actual value),
EMCYs, heartbeats and NMT commands are recorded too: the report's "drives"
and "nmt", --tpdo-csv OUT one row per TPDO (t,node,axis,statusword,state,
actual,pos).
SIGTERM/SIGINT: the frames already queued are read, every output is written,
exit 0.

The layout (byte offsets, sizes, signedness of every field) is read from the
DBC with cantools at start-up and checked against the config (axis count,
nodes, ids): a disagreement is an error. cantools is slow to import in the VM,
so what it read is cached in --dbc-cache (default build/) under the DBC's
SHA-256; --check-layout fills the cache and prints the layout. The hot path
then decodes with struct and slicing. Exit status: 0 done, 1 runtime error
(interface, log file), 2 usage or a layout mismatch.
"""

import argparse
import json
import os
import signal
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from . import sources
from .config import Setup, StrPath, UsageError
from .decoders import BATCH, DECODERS
from .layout import Layout
from .report import Frame, position_record, timing, write_csv, write_log
from .settings import Settings
from .sources import (
    Kept,
    expand_kept,
    open_python_can,
    open_socket,
    run_live,
    run_live_batch,
    run_log,
    run_python_can,
)

PROG = "mlip-listen"


def write_any_log(path: StrPath, frames: Iterable[Frame], iface: str) -> None:
    """candump text (.log) written here; other formats through can.Logger."""
    if str(path).endswith(".log"):
        return write_log(path, frames, iface)
    import can

    from .layout import CAN_EFF_FLAG, CAN_EFF_MASK, CAN_ERR_FLAG, CAN_RTR_FLAG, CAN_SFF_MASK

    with can.Logger(str(path)) as lg:
        for t, raw_id, fl, data in frames:
            ext = bool(raw_id & CAN_EFF_FLAG)
            lg.on_message_received(
                can.Message(
                    timestamp=t / 1e9,
                    arbitration_id=raw_id & (CAN_EFF_MASK if ext else CAN_SFF_MASK),
                    is_extended_id=ext,
                    is_remote_frame=bool(raw_id & CAN_RTR_FLAG),
                    is_error_frame=bool(raw_id & CAN_ERR_FLAG),
                    is_fd=fl is not None,
                    bitrate_switch=bool(fl and fl & 1),
                    error_state_indicator=bool(fl and fl & 2),
                    data=data,
                    channel=iface,
                    is_rx=True,
                )
            )


def main(argv: Sequence[str] | None = None, settings: Settings | None = None) -> int:
    """The command line; settings: where the build (mlip-config), the DBC and
    its cache are, and whether this runs in the emulated test VM (default:
    from the environment, Settings.from_environ)."""
    st = Settings.from_environ() if settings is None else settings
    ap = argparse.ArgumentParser(
        prog=PROG,
        description=(__doc__ or "").split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    src = ap.add_mutually_exclusive_group()
    src.add_argument("--can", metavar="IFACE", help="SocketCAN interface to listen on, e.g. vcan0")
    src.add_argument(
        "--from-log",
        metavar="FILE",
        help="a log to decode instead: candump -l/-L text, or .asc/.blf/... (can.LogReader)",
    )
    ap.add_argument(
        "--config", metavar="FILE", help="machine INI (axes, CAN_NODE, COUNTS_PER_UNIT, [CAN])"
    )
    ap.add_argument(
        "--profile", choices=sorted(DECODERS), help="output profile (default: [CAN] PROFILE)"
    )
    ap.add_argument(
        "--dbc", metavar="FILE", default=str(st.dbc), help="frame layouts (default tools/mlip.dbc)"
    )
    ap.add_argument("--csv", metavar="OUT", help="decoded cycles: cycle,t,x,...,cx,...")
    ap.add_argument(
        "--log",
        metavar="OUT",
        help="every frame: .log candump -l text, or .asc/.blf/... (can.Logger)",
    )
    ap.add_argument(
        "--tpdo-csv",
        metavar="OUT",
        help="cia402: the drives' TPDOs, t,node,axis,statusword,state,actual,pos",
    )
    ap.add_argument(
        "--drives",
        action="store_true",
        help="cia402: 6-byte RPDOs (controlword + target), as [DRIVES] ENABLE = 1",
    )
    ap.add_argument(
        "--receive",
        choices=["auto", "python-can", "fast", "recvmsg"],
        default="auto",
        help="live receive path (default auto: fast in the emulated VM, else python-can)",
    )
    ap.add_argument("--json", metavar="OUT", help="the report as JSON ('-': stdout)")
    ap.add_argument("--duration", metavar="S", type=float, help="stop after S seconds (live)")
    ap.add_argument(
        "--rcvbuf",
        metavar="BYTES",
        type=int,
        default=16 << 20,
        help="socket receive buffer (default 16 MiB)",
    )
    ap.add_argument("--log-iface", metavar="NAME", help="--from-log: only frames of this interface")
    ap.add_argument(
        "--python-can",
        "--python-can-recv",
        dest="receive",
        action="store_const",
        const="python-can",
        help="= --receive python-can",
    )
    ap.add_argument(
        "--no-batch",
        dest="receive",
        action="store_const",
        const="recvmsg",
        help="= --receive recvmsg",
    )
    ap.add_argument(
        "--dbc-cache",
        metavar="DIR",
        default=str(st.build),
        help="where the layout read from the DBC is cached (default build/; '' : none)",
    )
    ap.add_argument(
        "--check-layout",
        action="store_true",
        help="read the DBC (filling the cache), check it against the config, print "
        "the layout as JSON and exit (no --can/--from-log needed)",
    )
    ap.add_argument("-q", "--quiet", action="store_true", help="no summary line")
    a = ap.parse_args(argv)

    try:
        setup = Setup.from_ini(a.config, st.build) if a.config else Setup()
        if a.drives:
            setup.drives = True
        profile = a.profile or setup.profile
        layout = Layout(setup, profile, a.dbc, a.dbc_cache or None)
    except UsageError as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 2
    if a.check_layout:
        print(
            json.dumps(
                {
                    "profile": profile,
                    "config": setup.source,
                    "dbc": layout.dbc,
                    "dbc_read_by": layout.dbc_source,
                    "axes": setup.axes,
                    "layout": layout.describe(),
                    "dbc_notes": layout.notes,
                },
                indent=1,
            )
        )
        return 0
    if not a.can and not a.from_log:
        ap.error("one of --can IFACE or --from-log FILE is required")
    dec = DECODERS[profile](layout)
    frames: list[Frame] | None = [] if a.log else None
    sources.STOP.clear()
    signal.signal(signal.SIGTERM, sources.on_signal)
    signal.signal(signal.SIGINT, sources.on_signal)

    report: dict[str, Any] = {
        "tool": PROG,
        "profile": profile,
        "config": setup.source,
        "dbc": layout.dbc,
        "dbc_read_by": layout.dbc_source,
        "axes": setup.axes,
        "nodes": setup.nodes,
        "counts_per_unit": setup.cpu,
        "period_s": setup.period_s,
        "frames_per_cycle": layout.frames_per_cycle,
        "layout": layout.describe(),
        "dbc_notes": layout.notes,
    }
    cpu0 = os.times()
    t0 = time.monotonic()
    iface = a.can or "vcan0"
    how = a.receive
    if how == "auto":
        how = "fast" if st.in_vm else "python-can"
    try:
        if a.can:
            if how == "python-can":
                bus, info = open_python_can(a.can, a.rcvbuf, profile == "fd")
                sock = sources.bus_socket(bus)
            else:
                sock, info = open_socket(a.can, a.rcvbuf, profile == "fd")
            report["source"] = a.can
            report["socket"] = info
            if "warning" in info:
                print(f"{PROG}: warning: {info['warning']}", file=sys.stderr)
            print(
                f"{PROG}: listening on {a.can} ({profile}, {len(setup.axes)} axes "
                f"{''.join(setup.axes)}, {how}, rcvbuf {info['rcvbuf_bytes']} bytes)",
                file=sys.stderr,
                flush=True,
            )
            t0 = time.monotonic()
            cpu0 = os.times()
            deadline = t0 + a.duration if a.duration else None
            try:
                drops: int | None
                if how == "python-can":
                    run_python_can(bus, dec, a.log, deadline)
                    drops = None  # python-can does not report kernel drops
                    report["receive"] = "python-can can.Notifier" + (
                        ", can.Logger" if a.log else ""
                    )
                    frames = None  # can.Logger wrote the log
                elif how == "recvmsg":
                    drops = run_live(sock, dec, frames, deadline)
                    report["receive"] = "recvmsg per frame"
                else:
                    kept: list[Kept] | None = [] if frames is not None else None
                    nwords = {"cia402": 1, "packed": 2, "fd": 1 + len(setup.axes)}[profile]
                    drops = run_live_batch(sock, dec, kept, deadline, nwords)
                    if kept is not None:
                        frames = list(expand_kept(kept))
                    report["receive"] = f"recvmmsg, up to {BATCH} frames per call"
            finally:
                if how == "python-can":
                    bus.shutdown()
                else:
                    sock.close()
            report["socket_drops"] = drops
        else:
            report["source"] = a.from_log
            run_log(a.from_log, dec, frames, a.log_iface)
            report["socket_drops"] = None
            if frames:
                iface = a.log_iface or "vcan0"
    except (RuntimeError, OSError) as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1
    wall = time.monotonic() - t0
    cpu1 = os.times()
    cpu_user, cpu_sys = cpu1.user - cpu0.user, cpu1.system - cpu0.system
    cpu = cpu_user + cpu_sys
    dec.finish()

    n_cyc = len(dec.cyc)
    report.update(
        {
            "wall_s": round(wall, 3),
            "cpu_s": round(cpu, 3),
            "cpu_user_s": round(cpu_user, 3),
            "cpu_sys_s": round(cpu_sys, 3),
            "frames": dec.frames,
            "frames_ours": dec.ours,
            "foreign": sum(dec.foreign.values()),
            "foreign_ids": {f"0x{k:X}": v for k, v in sorted(dec.foreign.items())},
            "malformed": dec.malformed,
            "cycles": n_cyc,
            "first_cycle": dec.cyc[0] if n_cyc else None,
            "last_cycle": dec.cyc[-1] if n_cyc else None,
            "gaps": dec.gaps,
            "gap_events": dec.gap_events,
            "incomplete": dec.incomplete,
            "duplicates": dec.duplicates,
            "backwards": dec.backwards,
            "stray": dec.stray,
        }
    )
    if dec.batches:
        report["batches"] = dec.batches
        report["frames_per_batch"] = round(dec.frames / dec.batches, 1)
        report["fast_path_frames"] = dec.fast_frames
    report.update(dec.extra())
    if wall > 0:
        report["frames_per_s"] = round(dec.frames / wall, 1)
        report["cpu_per_frame_us"] = round(cpu / dec.frames * 1e6, 2) if dec.frames else None
    report["timing"] = timing(dec, profile, setup.period_s)
    report["first"] = position_record(dec, setup, 0) if n_cyc else None
    report["last"] = position_record(dec, setup, -1) if n_cyc else None
    report["events"] = dec.events
    if dec.drives is not None:
        report.update(dec.drives.report())
    ok = (
        dec.gaps == 0
        and dec.incomplete == 0
        and dec.stray == 0
        and dec.duplicates == 0
        and dec.malformed == 0
        and dec.backwards == 0
        and not report.get("socket_drops")
    )
    report["clean"] = ok

    try:
        if a.csv:
            write_csv(a.csv, dec, setup)
        if a.log and frames is not None:
            write_any_log(a.log, frames, iface)
        if a.tpdo_csv and dec.drives is not None:
            dec.drives.write_csv(a.tpdo_csv)
        if a.json:
            text = json.dumps(report, indent=1) + "\n"
            if a.json == "-":
                sys.stdout.write(text)
            else:
                Path(a.json).write_text(text)
    except OSError as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1

    if not a.quiet:
        tm = report["timing"]
        per = (
            f"period p50 {tm['p50_us']} us p99 {tm['p99_us']} us max {tm['max_us']} us"
            if tm.get("intervals")
            else "period: n/a"
        )
        last = ""
        if n_cyc:
            last = " last " + " ".join(f"{k}={v:g}" for k, v in report["last"]["pos"].items())
        drops = report.get("socket_drops")
        print(
            f"{PROG}: {report['source']} {profile}: {dec.frames} frames, {n_cyc} cycles, "
            f"{dec.gaps} lost, {dec.incomplete} incomplete, {dec.duplicates} duplicate, "
            f"{dec.stray} stray, {dec.malformed} malformed, "
            f"{'n/a' if drops is None else drops} socket drops; {per};{last}",
            file=sys.stdout if a.json != "-" else sys.stderr,
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
