"""mlip-drive-sim - simulated CiA 402 servo drives (CSP) on a CAN bus.

    mlip-drive-sim [--can IFACE] (--nodes 1,2,3 | --config INI) [--start N=COUNTS]...
                   [--state N=fault|switch-on-disabled] [--inject N:WHAT[=ARG]]...
                   [--control FILE] [--record DIR] [--heartbeat-ms MS] [--lag ALPHA]
                   [--duration S]
    mlip-drive-sim --write-eds FILE [--nodes N]

One process plays N drives on one bus, each a canopen.LocalNode (the
`canopen` package: SDO server, NMT slave, heartbeat and EMCY producers, PDO
maps) with the CiA 402 drive profile on top (mlipcan.drive):

  NMT      boot-up message at start and after a reset (node / communication),
           pre-operational, operational (PDOs on), stopped
  SDO      the object dictionary: 0x1000 0x1001 0x1005 0x1014 0x1016 0x1017
           0x1018 0x1400 0x1600 0x1800 0x1801 0x1802 0x1A00 0x1A01 0x1A02
           0x6040 0x6041 0x605A 0x6060 0x6061 0x6064 0x6065 0x6066 0x606C
           0x606D 0x607A 0x6083 0x6084 0x6085 0x60B8 0x60B9 0x60BA 0x60BB
           0x60C2 0x60F4 0x60FD 0x60FF 0x6502
           (--write-eds exports it); PDO mapping changes only as CiA 301
           says (PDO invalid, sub 0 = 0 first), modes of operation 0, 3, 6 or 8
  CiA 402  the power state machine on the controlword (SDO or RPDO), the
           statusword per the standard; in operation enabled and mode 8
           (CSP), at each SYNC: the TPDO (statusword, position actual value)
           is sent, the RPDO received since the previous SYNC is applied, and
           the position follows the target: actual += ALPHA (target -
           actual) (ALPHA 1: the target of one SYNC is the actual value at
           the next); following error beyond 0x6065 for 0x6066 ms: fault
           (EMCY 0x8611); a consumed heartbeat (0x1016) lost: fault (0x8130);
           in mode 3 (profile velocity, a spindle): the velocity ramps to the
           target velocity 0x60FF at 0x6083 (up) / 0x6084 (down), statusword
           bit 10 target reached and bit 12 speed zero within 0x606D, the TPDO
           carries velocity actual 0x606C; not enabled: it brakes to 0 at 0x6084
           (--config: the [SPINDLE] NODE of TYPE = cia402 is one of the drives)
           quick stop (0x605A 1/2/5/6) while moving in CSP: the axis brakes
           on the drive's own ramp (0x6085, or 0x6084 for 1/5), then switch
           on disabled (1/2); digital inputs 0x60FD (bit 0/1/2: the neg/pos
           limit and home switches of --switches at the position actual) in
           TPDO3 when the master maps it: on change and every event timer
           0x1802:05 ms; touch probe 1 (0x60B8..0x60BB, TPDO2 when the
           master maps 0x60BA/0x60BB there); homing mode (6, 0x6098
           methods 1 2 3 5 17 18 19 21 33 34 35 37 on the switches and the
           index pulse of --switches; statusword bits 10, 12, 13)

Fault injection (--inject at start, or a line "N:WHAT[=ARG]" appended to the
--control file at run time, read within 20 ms):
  N:fault[=CODE]          fault (statusword bit 3), EMCY CODE (default 0x2310)
  N:heartbeat=off|on      stop / restart the heartbeat producer
  N:leave-enabled         drop to "switch on disabled" (voltage lost), no fault
  N:follow-error[=RATE]   the actual value lags by RATE more counts each SYNC
  N:refuse=IDX[:SUB][,ABORT]  refuse SDO writes to IDX (hex) with ABORT
                          (default 0x08000022)
  N:never-enable[=off]    "enable operation" is ignored: stays "switched on"
  N:move=COUNTS           a disabled drive's axis moved by hand: position
                          actual + COUNTS (refused in "operation enabled")
  N:absent / N:present    gone from the bus (no boot-up, SDO, heartbeat) / back
  N:load=COUNTS_S         a spindle (mode 3) loses COUNTS_S of its velocity to a load
                          it cannot hold (0: none)
  N:touch-probe=COUNTS,below|above   a touch probe wired to every drive's touch
                          probe input 1 is on while drive N's position is at or
                          below (above) COUNTS (off: none); each drive with 0x60B8
                          armed latches its own position at the instant drive N's
                          move between two SYNCs crosses COUNTS (0x60BA positive
                          edge, 0x60BB negative; status 0x60B9; events.jsonl
                          "touch_probe": latched, sync, frac of the period);
                          its level also in every drive's 0x60FD bit 16
  N:di=BIT=0|1|auto       digital input BIT of 0x60FD forced (auto: from the
                          switches again; bits 0/1/2 follow --switches neg/pos/home)
  N:di-silent[=off]       TPDO3 (0x60FD) no longer sent: the inputs go stale
  N:di-garbled[=VALUE]    one TPDO3 a byte short (VALUE's first 3 bytes)

Records (--record DIR): events.jsonl (every SDO write with its value or abort
code, NMT and power state transitions, EMCYs, injections, heartbeat losses;
one JSON object a line, written at once) and sync.csv (per drive per SYNC in
NMT operational: sync,node,t,state,controlword,target,fresh,actual,
statusword; target = the RPDO's target applied at that SYNC, empty without
one; fresh = an RPDO arrived since the previous SYNC; actual and statusword
as sent in the TPDO at that SYNC; sync counts SYNCs from 1 since start; a
drive in mode 3: target = the target velocity applied, actual = the velocity
actual sent, counts/s).

Frames are read by python-can's Notifier (canopen's own way), or in the
software-emulated test VM (MLIP_IN_VM=1, --receive fast) with the listener's
recvmmsg batches from the same socket, handed to canopen's Network.notify:
python-can's Bus.recv costs 1-2.6 ms a frame there, and three drives at a
4 ms SYNC would fall behind the bus. A consumed heartbeat is judged by the
receive time of the frames after it (frame order), so a simulator running
late does not see a heartbeat lost that was not; and the time the simulator
itself did not run (its emulator descheduled by the host: the drives' own
kernel-timed heartbeats then come stamped after the stall, before the
producer has run again) is not counted against the producer.

stderr: "mlip-drive-sim: ... ready" once every drive has sent its boot-up.
SIGTERM/SIGINT: records written, a summary line (SYNCs, CPU per cycle),
exit 0. Exit 1: the bus cannot be opened; 2: usage.
"""

import argparse
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from types import FrameType
from typing import TypeVar

from . import cia402 as P
from .config import Setup, UsageError
from .settings import Settings

PROG = "mlip-drive-sim"
STATES = {
    "switch-on-disabled": P.SWITCH_ON_DISABLED,
    "fault": P.FAULT,
    "not-ready": P.NOT_READY,
}
_STOP = threading.Event()  # SIGTERM, SIGINT
T = TypeVar("T")


def _on_signal(sig: int, frame: FrameType | None) -> None:
    _STOP.set()


def parse_injection(text: str) -> tuple[int, str, str | None]:
    """'N:WHAT[=ARG]' -> (node, what, arg)."""
    node, sep, rest = text.strip().partition(":")
    if not sep or not node.strip().isdigit() or not rest:
        raise UsageError(f"injection '{text}': expected NODE:WHAT[=ARG]")
    what, _, arg = rest.partition("=")
    return int(node), what.strip(), (arg.strip() or None)


def parse_switches(text: str) -> dict[str, int]:
    """'neg:-5000,home:200,index:4000' -> {'neg': -5000, 'home': 200, 'index': 4000}."""
    out: dict[str, int] = {}
    for item in text.split(","):
        kind, _, counts = item.partition(":")
        if kind not in ("neg", "pos", "home", "nhome", "index"):
            raise ValueError(f"switch kind '{kind}' (neg, pos, home, nhome or index)")
        out[kind] = int(counts, 0)
    if "home" in out and "nhome" in out:
        raise ValueError("one home switch: home (on in +) or nhome (on in -)")
    if out.get("index", 1) <= 0:
        raise ValueError("index: counts per revolution > 0")
    return out


def node_map(items: Sequence[str] | None, what: str, conv: Callable[[str], T]) -> dict[int, T]:
    out: dict[int, T] = {}
    for it in items or ():
        n, sep, v = it.partition("=")
        if not sep or not n.strip().isdigit():
            raise UsageError(f"{what} '{it}': expected NODE=VALUE")
        try:
            out[int(n)] = conv(v.strip())
        except (ValueError, KeyError) as e:
            raise UsageError(f"{what} '{it}': bad value '{v}'") from e
    return out


def main(argv: Sequence[str] | None = None, settings: Settings | None = None) -> int:
    """The command line; settings: the build (mlip-config reads --config) and
    whether this runs in the emulated test VM (default: the environment's)."""
    st = Settings.from_environ() if settings is None else settings
    ap = argparse.ArgumentParser(
        prog=PROG,
        description=(__doc__ or "").split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--can", metavar="IFACE", default="vcan0", help="SocketCAN interface (vcan0)")
    ap.add_argument("--nodes", metavar="LIST", help="node ids, e.g. 1,2,3")
    ap.add_argument("--config", metavar="INI", help="machine INI: one drive per axis' CAN_NODE")
    ap.add_argument(
        "--start",
        metavar="N=COUNTS",
        action="append",
        help="position actual value of node N at power-up (counts; default 0)",
    )
    ap.add_argument(
        "--state",
        metavar="N=STATE",
        action="append",
        help=f"power state of node N at power-up: {', '.join(STATES)}",
    )
    ap.add_argument(
        "--inject",
        metavar="N:WHAT[=ARG]",
        action="append",
        default=[],
        help="fault injection from the start (see above)",
    )
    ap.add_argument("--control", metavar="FILE", help="injections at run time: lines appended here")
    ap.add_argument("--record", metavar="DIR", help="events.jsonl and sync.csv here")
    ap.add_argument(
        "--heartbeat-ms",
        type=int,
        default=100,
        help="producer heartbeat time 0x1017 at power-up (default 100; 0: off)",
    )
    ap.add_argument(
        "--lag",
        type=float,
        default=1.0,
        metavar="ALPHA",
        help="position loop: actual += ALPHA (target - actual) per SYNC (default 1)",
    )
    ap.add_argument(
        "--sync-id",
        type=lambda s: int(s, 0),
        default=0x80,
        help="the SYNC COB-ID counted for sync.csv (default 0x80)",
    )
    ap.add_argument(
        "--receive",
        choices=["auto", "python-can", "fast"],
        default="auto",
        help="how frames are read: python-can's Notifier, or the listener's recvmmsg "
        "batches from the same socket (auto: fast in the emulated VM)",
    )
    ap.add_argument(
        "--switches",
        metavar="N=KIND:COUNTS,...",
        action="append",
        help="where node N's switches are, for its homing mode (counts): neg and pos "
        "(limit switches, on beyond them), home (on from it in +) or nhome (on from it in "
        "-), and index: its encoder's index pulse every that many counts (at the multiples "
        "of it from power-up), e.g. 1=neg:-5000,home:200,index:4096",
    )
    ap.add_argument(
        "--io",
        metavar="NODE",
        type=int,
        action="append",
        default=[],
        help="a CiA 401 I/O module at NODE on the same bus (mlipcan.io401; injections "
        "NODE:input=BYTE.BIT=0|1, probe=BYTE.BIT,DRIVE,COUNTS,below|above (the input "
        "follows that drive's position against a surface; probe=off), heartbeat=off|on, "
        "fault[=CODE], reboot[=PRODUCT] (a power cycle: defaults, outputs off, boot-up; "
        "PRODUCT: another module in its place, that product code 0x1018:02), absent, "
        "present); its outputs at every SYNC in RECORD/io.csv",
    )
    ap.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    ap.add_argument("--write-eds", metavar="FILE", help="export a drive's object dictionary, exit")
    a = ap.parse_args(argv)
    try:
        if a.config:
            cs = Setup.from_ini(a.config, st.build)
            nodes = cs.nodes + ([cs.spindle_node] if cs.spindle_node else [])
        elif a.nodes:
            nodes = [int(v) for v in a.nodes.split(",")]
        else:
            nodes = [1]
        allnodes = nodes + list(a.io)
        if any(not 1 <= n <= 127 for n in allnodes) or len(set(allnodes)) != len(allnodes):
            raise UsageError(f"node ids must be distinct, 1..127: {allnodes}")
        starts = node_map(a.start, "--start", int)
        states = node_map(a.state, "--state", lambda v: STATES[v])
        switches = node_map(a.switches, "--switches", parse_switches)
        injections = [parse_injection(t) for t in a.inject]
        for n in list(starts) + list(states) + list(switches):
            if n not in nodes:
                raise UsageError(f"node {n} is not one of the drives {nodes}")
        for n in [i[0] for i in injections]:
            if n not in allnodes:
                raise UsageError(f"node {n} is not one of the devices {allnodes}")
    except (UsageError, ValueError) as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 2

    from . import drive as D  # canopen: slow to import in the emulated VM

    if a.write_eds:
        import canopen

        canopen.export_od(D.build_od(nodes[0], a.heartbeat_ms), a.write_eds, "eds")
        print(f"{PROG}: {a.write_eds}: the object dictionary of node {nodes[0]}", file=sys.stderr)
        return 0

    rec = D.Recorder(Path(a.record) if a.record else None)
    specs: list[D.DriveSpec] = [
        {
            "node_id": n,
            "start_position": starts.get(n, 0),
            "start_state": states.get(n, P.SWITCH_ON_DISABLED),
            "heartbeat_ms": a.heartbeat_ms,
            "lag_alpha": a.lag,
            "switches": switches.get(n, {}),
        }
        for n in nodes
    ]
    sim = D.DriveSim(a.can, specs, rec, sync_id=a.sync_id)
    for n in a.io:
        sim.add_module(n, a.heartbeat_ms)
    absent = {n for n, w, _ in injections if w == "absent"}
    signal.signal(signal.SIGTERM, _on_signal)
    signal.signal(signal.SIGINT, _on_signal)
    try:
        fast = a.receive == "fast" or (a.receive == "auto" and st.in_vm)
        sim.start(absent=absent, fast=fast)
    except (RuntimeError, OSError) as e:
        print(f"{PROG}: {e}", file=sys.stderr)
        return 1
    for n, w, arg in injections:
        if w != "absent":
            sim.inject(n, w, arg)
    print(
        f"{PROG}: {len(nodes)} drives (nodes {','.join(map(str, nodes))}) on {a.can}, "
        + (f"I/O module {','.join(map(str, a.io))}, " if a.io else "")
        + f"{'recvmmsg' if fast else 'python-can'} receive"
        + (f", absent: {sorted(absent)}" if absent else "")
        + ": ready",
        file=sys.stderr,
        flush=True,
    )
    ctl_pos = 0
    if a.control:
        Path(a.control).touch()
    t_end = time.monotonic() + a.duration if a.duration else None
    cpu0 = os.times()
    while not _STOP.is_set() and (t_end is None or time.monotonic() < t_end):
        time.sleep(0.005)
        sim.tick()
        if a.control:
            try:
                with open(a.control) as fh:
                    fh.seek(ctl_pos)
                    chunk = fh.read()
            except OSError:
                chunk = ""
            # whole lines only: a writer may be mid-line
            done = chunk.rfind("\n") + 1
            ctl_pos += done
            for line in chunk[:done].splitlines():
                if line.strip() and not line.lstrip().startswith("#"):
                    try:
                        sim.inject(*parse_injection(line))
                    except (UsageError, ValueError) as e:
                        print(f"{PROG}: {a.control}: {e}", file=sys.stderr, flush=True)
    cpu1 = os.times()
    sim.stop()
    per = sim.cycle_cpu_s / sim.cycles * 1e6 if sim.cycles else 0.0
    print(
        f"{PROG}: {sim.sync_no} SYNCs, {sim.cycles} drive cycles, "
        f"{per:.0f} us CPU per drive cycle (handler only), socket drops "
        f"{'n/a' if sim.socket_drops is None else sim.socket_drops}, stalls of its own "
        f"{sim.stalls} (longest {sim.stall_s:.2f} s), process CPU "
        f"{cpu1.user + cpu1.system - cpu0.user - cpu0.system:.2f} s",
        file=sys.stderr,
        flush=True,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
