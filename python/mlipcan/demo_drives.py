"""The demo's drives stage (tools/demo.sh; `mlip-demo drives OUTDIR`):
mlip-rt --drives brings three simulated CiA 402 drives up, runs a short
program on them and shuts them down; printed as the drives saw it, checked.

The drives are mlip-drive-sim (the `canopen` package: an
implementation independent of mlip's C master), powered up away from HOME
and one of them in "fault". Everything shown about the bring-up comes from
what the drives recorded (events.jsonl: each NMT command, SDO write and
power state transition with its time; sync.csv: per drive per SYNC the
target applied, the statusword and position actual sent), not from mlip's
own log. The checks are those of tests/can/test_drive_master_vcan.py,
computed with the same helpers (mlipcan.compare).

Standard library only: the drives' process imports canopen, this one does
not."""

import json
import math
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from . import cia402 as P
from .compare import ini_set, simulate, targets_by_sync, trace_counts, trim
from .config import MachineLimits, StrPath, setup_of
from .procs import DriveSimProc, Rig
from .settings import Settings

CONFIG = "mill-3axis-drives.ini"  # in the settings' config/
# counts at power-up of the 1st, 2nd, 3rd axis' drive: none at HOME (0), as a
# machine stands after a day's work; the 2nd powers up in "fault", the others
# in "switch on disabled"
STARTS = (12345, -5000, 2500)
FAULTED = 1
# The Python drives keep up with a 40 ms SYNC in the emulated VM, not with the
# config's 2 ms: 1.2-1.4 ms of CPU per drive and SYNC there (measured, printed
# at the end), 3-4 ms when other VMs share the host; three drives.
PERIOD_S = 0.04
# Answers that late need longer timeouts than a real drive's; a following
# error window of 2 mm (one period of travel at 15 mm/s is 0.6 mm, and mlip's
# own check allows up to 2 periods more while moving).
DEMO_DRIVES = {
    "HEARTBEAT_TIMEOUT_MS": 4000,
    "FOLLOWING_ERROR": 2,
    "SDO_TIMEOUT_MS": 5000,
    "BOOT_TIMEOUT_MS": 8000,
    "STATE_TIMEOUT_MS": 10000,
}
# homing after the program, with each drive's homing mode (CiA 402 mode 6),
# per axis index: method, HOME_OFFSET mm, HOME_SEQUENCE, and the switch the
# simulated drive has (kind, counts from its start position): X the current
# position (35), Y its negative limit switch (17), Z its home switch (19),
# Z first
HOMING = (
    (35, 0.0, 1, None),
    (17, -1.0, 1, ("neg", -3000)),
    (19, 0.0, 0, ("home", 1500)),
)
# the spindle (issue 19): a CiA 402 drive in profile velocity mode on the
# same bus, node 4, 6000 rpm in 1.2 s; the program starts it before its
# first move and its end stops it; a long AT_SPEED_TIMEOUT, as the other
# timeouts: the simulated drive may answer its SYNCs late in the VM
SPINDLE_NODE = 4
SPINDLE = f"""
[SPINDLE]
TYPE = cia402
MAX_RPM = 6000
NODE = {SPINDLE_NODE}
COUNTS_PER_REV = 4096
ACCELERATION = 5000
AT_SPEED_BAND = 100
AT_SPEED_TIMEOUT = 30
"""
# the rest of the machine's I/O (issue 19): flood coolant on a simulated
# CiA 401 module's output (node 10, 0x6200:1 bit 1), a manual tool change
# (the demo's operator resumes at once through mlip-ctl), the shipped tool
# table (examples/tool.tbl: T1 is 42.5 mm long)
IO_NODE = 10
FLOOD_BIT = 0x02
TOOL_TABLE = "tool.tbl"
MACHINE_IO = f"""
[IO]
NODE = {IO_NODE}

[COOLANT]
TYPE = io
FLOOD = {IO_NODE} 0x6200:1 {FLOOD_BIT.bit_length() - 1}

[TOOL]
CHANGE = manual
"""
# tool 1 and its length, the spindle to speed, flood coolant, a rectangle at
# two depths, the length offset off and back to where the drives stood
PROGRAM = """(mlip demo, drives stage: tool 1, a 10 x 10 mm outline, then back to the start)
G21 G90 G17
T1 M6
G43 H1
M3 S6000
M8
G0 X20 Y0 Z5
G1 X30 Y0 F900
G1 X30 Y10 Z4
G1 X20 Y10
G1 X20 Y0 Z5
G49
G0 X12.345 Y-5 Z2.5
M9
"""
PROGRAM_Z_TOP = 5.0  # the program's highest Z under G43 H1
SHORT = {
    P.SWITCH_ON_DISABLED: "disabled",
    P.READY: "ready",
    P.SWITCHED_ON: "switched on",
    P.OPERATION_ENABLED: "enabled",
    P.FAULT: "FAULT",
    P.FAULT_REACTION: "FAULT",
    P.QUICK_STOP: "quick stop",
    P.NOT_READY: "not ready",
}
NMT_WHY = {
    "NMT command 0x01": "NMT start",
    "NMT command 0x02": "NMT stop",
    "NMT command 0x80": "NMT enter pre-operational",
}


def demo_machine(
    s: Settings, base: StrPath, period_s: float, starts: Mapping[str, float] | None = None
) -> tuple[str, float | None, float]:
    """The drive machine's text at period_s: the accelerations lowered so the
    period keeps the tolerance (eq. 17: |A| T^2 / 8 <= eps, |A| the norm of
    the per-axis limits), the VM's timeouts; HOME = starts (mm) if given.
    Returns (text, acceleration or None when unchanged, |A| T^2 / 8)."""
    text = Path(base).read_text()
    lim = MachineLimits.of(s, base)
    n = len(lim.axes)
    a_max = 8.0 * lim.eps / (math.sqrt(n) * period_s**2)
    a_new: float | None = None
    if math.sqrt(sum(a * a for a in lim.accel)) * period_s**2 / 8.0 > lim.eps:
        a_new = math.floor(a_max / 5.0) * 5.0 if a_max >= 5.0 else math.floor(a_max * 100) / 100
        for ax in lim.axes:
            text = ini_set(text, f"AXIS_{ax}", "MAX_ACCELERATION", f"{a_new:g}")
    text = ini_set(text, "TRAJ", "PERIOD", repr(period_s))
    for k, v in DEMO_DRIVES.items():
        text = ini_set(text, "DRIVES", k, v)
    for ax, mm in (starts or {}).items():
        text = ini_set(text, f"AXIS_{ax}", "HOME", repr(mm))
    acc = [a_new if a_new is not None else a for a in lim.accel]
    return text, a_new, math.sqrt(sum(a * a for a in acc)) * period_s**2 / 8.0


def shown(index: str, v: Any) -> str:
    """An SDO value as a person reads it: COB-IDs and mappings in hex."""
    if index == "0x6040" and isinstance(v, int):
        return f"{v:02X}"  # controlword, hex: 06 shutdown, 07 switch on, 0F enable, 80 fault reset
    if isinstance(v, int) and int(index, 16) < 0x2000 and v > 9:
        return f"0x{v:X}"
    return str(v)


def shown_path(path: StrPath, vm_out: str | None) -> str:
    """Where a file ends up for the person: in the VM the outdir is the shared
    folder vm_out that tools/demo.sh copies back to build/."""
    p = Path(path)
    if vm_out and p.is_relative_to(vm_out):
        return str(Path("build") / p.relative_to(vm_out))
    return str(p)


def rt_lines(log: str, *keys: str) -> list[str]:
    """mlip-rt's log lines holding one of keys, without the program name."""
    return [
        line.split("mlip-rt: ", 1)[-1] for line in log.splitlines() if any(k in line for k in keys)
    ]


def run(
    s: Settings,
    outdir: StrPath,
    config: StrPath | None = None,
    ngc: StrPath | None = None,
    period_s: float = PERIOD_S,
    vm_out: str | None = None,
) -> int:
    """The drives stage; returns the number of failed checks. config: the
    machine (default config/mill-3axis-drives.ini), ngc: the program (default:
    a small one of its own), vm_out: the VM's shared output folder (paths
    under it are shown as build/...)."""
    if config is None:
        config = s.config_dir / CONFIG
    out = Path(outdir)
    work = out / "run"
    work.mkdir(parents=True, exist_ok=True)
    setup = setup_of(s, config)
    nodes, axes, cpu = setup.nodes, setup.axes, setup.cpu
    ax_of = dict(zip(nodes, axes, strict=True))
    starts = {n: STARTS[i % len(STARTS)] for i, n in enumerate(nodes)}
    states = {nodes[FAULTED]: "fault"} if len(nodes) > FAULTED else {}
    base = MachineLimits.of(s, config)
    text, a_new, dev = demo_machine(s, config, period_s)
    switches: list[str] = []
    for i, ax in enumerate(axes):
        method, offset, seq, sw = HOMING[i % len(HOMING)]
        for key, val in (
            ("HOME_METHOD", method),
            ("HOME_OFFSET", offset),
            ("HOME_SEQUENCE", seq),
            ("HOME_SEARCH_VEL", 5),
            ("HOME_LATCH_VEL", 0.5),
            ("HOME_ACCEL", 20),
        ):
            text = text.replace(f"[AXIS_{ax}]\n", f"[AXIS_{ax}]\n{key} = {val}\n", 1)
        if sw is not None:
            switches += ["--switches", f"{nodes[i]}={sw[0]}:{starts[nodes[i]] + sw[1]}"]
    cfg = out / "machine.ini"
    cfg.write_text(text + SPINDLE + MACHINE_IO)
    tbl = s.root / "examples" / TOOL_TABLE
    lim = MachineLimits.of(s, cfg)  # mlip-config accepts it, or this raises with its message
    print(
        f"drives: {Path(config).name} (PERIOD {base.period_s:g} s, the starting point for a real "
        f"machine) copied to {shown_path(cfg, vm_out)}, with",
        flush=True,
    )
    print(
        f"  PERIOD {period_s:g} s: the drives here are Python processes (the canopen package) "
        f"that keep up with a {period_s * 1e3:g} ms SYNC"
        f"{' in this emulated VM' if s.in_vm else ''}, not with {base.period_s * 1e3:g} ms;"
    )
    if a_new is not None:
        print(
            f"  MAX_ACCELERATION {a_new:g} mm/s^2 (was {max(base.accel):g}): at a longer period a "
            f"drive moves in a straight line between setpoints and may leave the curve by "
            f"|A| T^2/8 (eq. 17), which must stay within CONTOUR_TOLERANCE {lim.eps:g} mm: "
            f"now {dev:.4f} mm;"
        )
    print(
        "  "
        + ", ".join(f"{k} {v}" for k, v in DEMO_DRIVES.items())
        + ": the simulated drives answer late"
    )
    if ngc is None:
        prog = out / "drives.ngc"
        prog.write_text(PROGRAM)
    else:
        prog = Path(ngc)
    # mlip-sim on the same machine from where the drives stand: the reference
    home = {ax_of[n]: starts[n] / c for n, c in zip(nodes, cpu, strict=True)}
    sim_cfg = out / "machine-sim.ini"
    sim_cfg.write_text(demo_machine(s, config, period_s, home)[0] + SPINDLE + MACHINE_IO)
    trc, summ = simulate(s, sim_cfg, prog, work, "--tools", tbl)
    want = trim(trace_counts(trc, cpu))
    print(
        f"drives: program {shown_path(prog, vm_out)} ({summ['blocks']} blocks, "
        f"{summ['path_length_mm']:.1f} mm, {summ['total_time_s']:.2f} s in mlip-sim from the "
        "drives' start positions)",
        flush=True,
    )

    print(
        f"drives: powering up {len(nodes)} simulated drives: "
        + "; ".join(
            f'node {n} (axis {ax_of[n]}) in "{states.get(n, "switch on disabled")}" '
            f"at {starts[n]} counts = {starts[n] / c:g} mm"
            for n, c in zip(nodes, cpu, strict=True)
        ),
        flush=True,
    )
    t_boot = time.monotonic()
    sim = DriveSimProc(
        s,
        work,
        nodes=[*nodes, SPINDLE_NODE],
        starts=starts,
        states=states,
        name="drivesim",
        args=[*switches, "--io", IO_NODE],
    )
    ax_of[SPINDLE_NODE] = "spindle"
    ax_of[IO_NODE] = "I/O module"
    print(
        f"drives: drives up after {time.monotonic() - t_boot:.1f} s; mlip-rt --drives, then "
        f"mlip-feed {prog.name}, then SIGTERM (a controlled stop) ...",
        flush=True,
    )
    t0 = time.time()
    feed: tuple[int | None, str, str] = (None, "", "")
    rig = Rig(s, cfg, "cia402", work, priority=0, rt_args=["--drives"])
    t_home0 = t_home1 = float("inf")
    home_out = ("", "", -1)
    home_st: dict[str, Any] = {}
    pauses: list[tuple[float, dict[str, Any]]] = []  # (resumed at, status when paused)
    try:
        with rig:
            feed = operate(rig, prog, ["--tools", tbl], pauses)
            # then homing, with the drives' own homing mode (mlip-ctl home)
            t_home0 = time.time()
            hp = rig.ctl("home", check=False)
            t_home1 = time.time()
            home_out = (hp.stdout, hp.stderr, hp.returncode)
            home_st = rig.status()
    finally:
        sim.stop()
    r = rig.result
    log = r["rt_stderr"]
    ev = [e for e in sim.events() if e["t"] >= t0]
    rows = [x for x in sim.sync_rows() if x["t"] >= t0 and x["node"] in nodes]
    t_ref = min([e["t"] for e in ev] or [t0])
    first: dict[int, int] = {}  # node -> the first target it applied (counts)
    for x in rows:
        if x["target"] is not None:
            first.setdefault(x["node"], x["target"])

    def at(t: float) -> str:
        return f"{t - t_ref:8.3f} s"

    # ---- bring-up, shut-down: the drives' own records
    def phase(e: dict[str, Any]) -> int:
        if e["t"] < rig.t_ready:
            return 0
        if t_home0 <= e["t"] <= t_home1:
            return 3  # homing: its own section
        return 1 if e["t"] < rig.t_feed_end else 2

    def report_run() -> tuple[dict[int, int], list[int]]:
        run_rows = [x for x in rows if rig.t_ready <= x["t"] <= rig.t_feed_end]
        print(
            f"  what the drives sent in their TPDO (statusword, position actual) and the target "
            f"they applied, at every {max(1, round(1.0 / period_s))}th SYNC:"
        )
        by_sync: dict[int, dict[int, dict[str, Any]]] = {}
        for x in run_rows:
            by_sync.setdefault(x["sync"], {})[x["node"]] = x
        syncs = sorted(by_sync)
        step = max(1, round(1.0 / period_s))
        print(
            (
                f"    {'t':>10}"
                + "".join(f"  {'node ' + str(n) + ' (' + ax_of[n] + ')':<38}" for n in nodes)
            ).rstrip()
        )
        for i, sy in enumerate(syncs):
            if i % step and i != len(syncs) - 1:
                continue
            cells = []
            for n in nodes:
                row = by_sync[sy].get(n)
                if row is None:
                    cells.append(f"{'-':<38}")
                    continue
                tg = "-" if row["target"] is None else row["target"]
                cells.append(
                    f"{SHORT.get(row['state'], row['state']):<8} sw 0x{row['sw']:04X} "
                    f"{row['actual']:>7} / {tg!s:<7}"
                )
            print(
                (
                    f"    {at(by_sync[sy][min(by_sync[sy])]['t'])}"
                    + "".join(f"  {c:<38}" for c in cells)
                ).rstrip()
            )
        print("    (per node: state, statusword, position actual / target, counts)")
        fe: dict[int, int] = {}
        for n, c in zip(nodes, cpu, strict=True):
            mine = [
                x
                for x in run_rows
                if x["node"] == n and x["target"] is not None and x["state"] == P.OPERATION_ENABLED
            ]
            fe[n] = max((abs(x["target"] - x["actual"]) for x in mine), default=0)
            sws = sorted({x["sw"] for x in run_rows if x["node"] == n})
            tg = [x["target"] for x in mine]
            print(
                f"  node {n} ({ax_of[n]}): {len(mine)} SYNCs in operation enabled, statusword "
                f"{', '.join(f'0x{v:04X}' for v in sws)}; "
                f"target {min(tg, default=0)}..{max(tg, default=0)}; "
                f"following error max {fe[n]} counts = {fe[n] / c:.3f} mm (window 0x6065: "
                f"{sdo_value(ev, n, '0x6065')})"
            )
        print(
            "  (following error: target applied - position actual at the same SYNC; these drives "
            "reach each target at the next SYNC, so it is one period of travel)"
        )
        return fe, syncs

    titles = [
        "bring-up, as the drives saw it (t from the first frame mlip sent them):",
        "the program (mlip-feed), as the drives reported it:",
        "shut-down (after the program, then SIGTERM to mlip-rt):",
    ]
    sdo: dict[tuple[str, int], dict[int, str]] = {}
    fe: dict[int, int] = {}
    syncs: list[int] = []
    for k, title in enumerate(titles):
        print(f"\n{title}")
        shown_n = 0
        first_sdo = set()
        for e in ev:
            if phase(e) != k:
                continue
            n = e["node"]
            who = f"node {n} ({ax_of.get(n, '?')})"
            if e["kind"] == "nmt":
                why = NMT_WHY.get(e.get("why", ""), e.get("why", ""))
                if e["to"] == "INITIALISING":
                    print(f"  {at(e['t'])}  {who}  {why} -> boot-up message, pre-operational")
                elif e.get("why") != "boot-up sent":
                    print(f"  {at(e['t'])}  {who}  {why} -> {e['to'].lower()}")
                shown_n += 1
            elif e["kind"] == "state":
                print(
                    f"  {at(e['t'])}  {who}  {e['frm']} -> {e['to']} ({e['why']}; statusword "
                    f"{e['statusword']})"
                )
                shown_n += 1
            elif e["kind"] == "sdo_write":
                v = f"abort {e['abort']}" if e.get("abort") else shown(e["index"], e.get("value"))
                vals = sdo.setdefault((e["index"], e["sub"]), {})
                # the controlword's steps all shown; other objects their last value
                vals[n] = f"{vals[n]} {v}" if n in vals and e["index"] == "0x6040" else v
                if k:
                    print(
                        f"  {at(e['t'])}  {who}  SDO write {e['index']}:{e['sub']:02X} "
                        f"{P.OBJECT.get(int(e['index'], 16), '')} = "
                        f"{e.get('abort') or shown(e['index'], e.get('value'))}"
                    )
                    shown_n += 1
                elif n not in first_sdo:
                    first_sdo.add(n)
                    cnt = sum(
                        1
                        for x in ev
                        if x["kind"] == "sdo_write" and x["node"] == n and phase(x) == 0
                    )
                    print(
                        f"  {at(e['t'])}  {who}  SDO writes begin ({cnt} in the bring-up, "
                        f"each read back by mlip: table below)"
                    )
                    shown_n += 1
            elif e["kind"] == "emcy":
                print(f"  {at(e['t'])}  {who}  EMCY {e['code']} ({e['meaning']}) sent")
                shown_n += 1
            elif e["kind"] in ("heartbeat_lost", "inject", "absent", "refused_enable"):
                print(
                    f"  {at(e['t'])}  {who}  {e['kind']}: "
                    + ", ".join(f"{a}={b}" for a, b in e.items() if a not in ("t", "node", "kind"))
                )
                shown_n += 1
        if not shown_n:
            print("  (no NMT command, SDO write or state transition)")
        if k == 1:
            fe, syncs = report_run()
        if k == 0 and sdo:
            print("\n  the SDO writes, value per node as the drive received it:")
            print(
                f"    {'object':<10} {'what':<24}"
                + "".join(f" {'node ' + str(n):>15}" for n in nodes)
            )
            for (idx, sub), vals in sdo.items():
                name = P.OBJECT.get(int(idx, 16), "")
                print(
                    f"    {idx}:{sub:02X}  {name:<24}"
                    + "".join(f" {vals.get(n, '-'):>15}" for n in nodes)
                )
            sdo = {}
            for line in rt_lines(log, "bus load", "start position"):
                print(f"  mlip-rt: {line}")
            print(
                "  the first target each drive applied: "
                + ", ".join(f"node {n} {first.get(n)}" for n in nodes)
                + " counts; where they stood: "
                + ", ".join(str(starts[n]) for n in nodes)
            )
        if k == 2:
            for line in rt_lines(log, "drives disabled"):
                print(f"  mlip-rt: {line}")

    # ---- homing, as the drives did it
    print("\nhoming (mlip-ctl home, after the program), as the drives did it:")
    homing = [e for e in ev if e["kind"] == "homing" and t_home0 <= e["t"] <= t_home1]
    for e in homing:
        n = e["node"]
        what = {
            "start": f"homing started (method {e.get('method')}) at {e.get('at')} counts",
            "switch": f"switch reached at {e.get('at')} counts: braking, then back at the "
            "latch speed",
            "done": f"homing attained at {e.get('at')} counts: position := home offset "
            f"{e.get('offset')}",
            "error": f"homing error ({e.get('why')})",
        }.get(e["phase"], e["phase"])
        print(f"  {at(e['t'])}  node {n} ({ax_of.get(n, '?')})  SYNC {e['sync']}: {what}")
    print(f"  mlip-ctl home: {(home_out[0] or home_out[1]).strip()}")
    offsets = {
        n: round(HOMING[i % len(HOMING)][1] * c)
        for i, (n, c) in enumerate(zip(nodes, cpu, strict=True))
    }

    # ---- checks
    checks: list[tuple[bool, str]] = []

    def check(ok: object, what: str) -> None:
        checks.append((bool(ok), what))

    rc, fout, ferr = feed
    check(
        rc == 0 and r["rt_rc"] == 0,
        f"mlip-feed exited {rc}, mlip-rt {r['rt_rc']} (0, 0: the program ran, a clean stop)",
    )
    check(
        first == starts,
        "first target = start position to the count: "
        + ", ".join(f"node {n} {first.get(n)} = {starts[n]}" for n in nodes),
    )
    got = trim(targets_by_sync([x for x in rows if x["t"] < t_home0], nodes))
    bad = next((i for i, (a, b) in enumerate(zip(got, want, strict=False)) if a != b), None)
    if bad is None and len(got) != len(want):
        bad = min(len(got), len(want))
    check(
        bad is None,
        f"the drives applied mlip-sim's trace in counts: {len(got)} SYNCs of motion, "
        f"mlip-sim {len(want)} periods"
        + (
            ""
            if bad is None
            else f" -- first difference at SYNC {bad} of the motion: drives "
            f"{got[bad] if bad < len(got) else '-'}, "
            f"mlip-sim {want[bad] if bad < len(want) else '-'}"
        ),
    )
    order = []
    for n in nodes:
        st = [(e["frm"], e["to"]) for e in ev if e["kind"] == "state" and e["node"] == n]
        ok = st[-2:] == [(P.OPERATION_ENABLED, P.SWITCHED_ON), (P.SWITCHED_ON, P.READY)]
        ok = ok and any(x["node"] == n and x["state"] == P.READY for x in rows)
        order.append(ok)
    check(
        all(order),
        "every drive disabled in order at the end: operation enabled -> switched on "
        "(disable operation 0x07) -> ready to switch on (shutdown 0x06), the SYNC "
        "still running: "
        + ", ".join(f"node {n} {'yes' if o else 'NO'}" for n, o in zip(nodes, order, strict=True)),
    )
    check(
        home_out[2] == 0,
        f"homed in HOME_SEQUENCE order (Z first), the drives' own homing mode: mlip-ctl home "
        f"exited {home_out[2]}",
    )
    order_ok = False
    starts_h = {e["node"]: e["sync"] for e in homing if e["phase"] == "start"}
    dones_h = {e["node"]: e["sync"] for e in homing if e["phase"] == "done"}
    if len(nodes) >= 3 and len(dones_h) == len(nodes) and len(starts_h) == len(nodes):
        order_ok = dones_h[nodes[2]] < min(starts_h[nodes[0]], starts_h[nodes[1]])
    check(order_ok, f"Z ({HOMING[2][2]}) homed before X and Y: starts {starts_h}, done {dones_h}")
    csp_first: dict[int, int | None] = {}
    for n in nodes:
        t_csp = [
            e["t"]
            for e in ev
            if e["kind"] == "sdo_write"
            and e["node"] == n
            and e["index"] == "0x6060"
            and e.get("value") == 8
            and t_home0 <= e["t"]
        ]
        after = [
            x
            for x in rows
            if x["node"] == n and t_csp and x["t"] > max(t_csp) and x["target"] is not None
        ]
        csp_first[n] = after[0]["target"] if after else None
    check(
        csp_first == offsets,
        "after homing every drive is at its home offset and its first target in CSP equals "
        "it, to the count (no step): "
        + ", ".join(f"node {n} {csp_first.get(n)} = {offsets[n]}" for n in nodes),
    )
    check(
        home_st.get("homed") == {ax: True for ax in axes},
        f"mlip-ctl status: homed {home_st.get('homed')}",
    )
    faults = [
        e
        for e in ev
        if e["t"] >= rig.t_ready
        and (
            (e["kind"] == "state" and e["to"] in (P.FAULT, P.FAULT_REACTION))
            or (e["kind"] == "emcy" and e.get("code") != "0x0000")
        )
    ]
    faults += [x for x in rows if x["t"] >= rig.t_ready and x["sw"] & 0x08]
    check(
        not faults and "drive fault" not in log,
        f"no drive fault after the bring-up (fault state, EMCY, statusword bit 3, mlip-rt's "
        f"'drive fault'): {len(faults)} seen",
    )
    # the spindle: no axis moves before its TPDO said target reached at speed
    sp = [x for x in sim.sync_rows() if x["node"] == SPINDLE_NODE and x["t"] >= t0]
    s_cmd = next((x["sync"] for x in sp if x["target"]), None)
    s_reach = next(
        (
            x["sync"]
            for x in sp
            if s_cmd is not None
            and x["sync"] > s_cmd
            and x["sw"] & P.SW_TARGET_REACHED
            and abs(x["actual"] * 60.0 / 4096 - 6000) <= 100
        ),
        None,
    )
    moved = [x["sync"] for x in rows if x["target"] is not None and x["target"] != first[x["node"]]]
    s_move = min(moved, default=None)
    wait = None
    if s_cmd is not None and s_reach is not None and s_move is not None:
        wait = s_move - s_cmd if s_cmd < s_reach < s_move else None
    wait_ok = wait is not None
    print(
        f"\nspindle (node {SPINDLE_NODE}, profile velocity): target 6000 rpm applied at SYNC "
        f"{s_cmd}, target reached in its TPDO at SYNC {s_reach}, the axes' first move at SYNC "
        f"{s_move}: start-to-feed "
        + (f"{wait * period_s:.2f} s" if wait is not None else "-")
        + " (its ramp 6000 / 5000 rpm/s = 1.20 s; from its TPDO to the first move: the "
        "TPDO read, the RPDO applied at the next SYNC, and how late the simulated drives "
        "answer here)"
    )
    check(
        wait_ok,
        "the spindle (CiA 402, profile velocity) at speed before any axis moved: M3 S6000 at "
        f"SYNC {s_cmd}, at speed at {s_reach}, first move at {s_move}",
    )
    at_move = next((x for x in sp if s_move is not None and x["sync"] >= s_move), None)
    if at_move is not None:
        print(
            f"  its velocity actual (0x606C) at the first move: "
            f"{at_move['actual'] * 60.0 / 4096:.0f} rpm ({at_move['actual']} counts/s)"
        )
    last = [x for x in sp if x["target"] is not None]
    stopped = bool(last) and last[-1]["target"] == 0 and abs(last[-1]["actual"]) <= 1000
    check(stopped, "the spindle stopped at the program's end (target 0, at standstill)")
    if ngc is None:
        run_rows = [x for x in rows if x["t"] < t_home0]  # the program's, not homing's
        io_report(s, sim, t0, t_ref, pauses, run_rows, nodes, cpu, s_move, tbl, check)
    cpu_line = [x for x in sim.proc.stderr().splitlines() if "CPU per drive cycle" in x]
    if cpu_line:
        print(f"\n{cpu_line[-1]} (why the long period)")
    print("\ndrives: checks")
    for ok, what in checks:
        print(f"  [{'ok' if ok else 'FAILED'}] {what}")
    failed = sum(1 for ok, _ in checks if not ok)
    print(f"drives: {len(checks) - failed} of {len(checks)} checks passed", flush=True)
    info = {
        "config": str(config),
        "machine": str(cfg),
        "program": str(prog),
        "period_s": period_s,
        "acceleration_mm_s2": a_new,
        "starts": starts,
        "states": states,
        "first_target": first,
        "following_error_max_counts": fe,
        "syncs": len(syncs),
        "motion_syncs": len(got),
        "checks": [{"ok": ok, "what": w} for ok, w in checks],
    }
    (out / "drives.json").write_text(json.dumps(info, indent=1) + "\n")
    for name in ("rt.err", "feed.err", "drivesim.err"):
        if (work / name).exists():
            (out / name).write_text((work / name).read_text())
    for name in ("events.jsonl", "sync.csv"):
        if (work / "drives" / name).exists():
            (out / name).write_text((work / "drives" / name).read_text())
    return failed


def operate(
    rig: Rig, prog: StrPath, args: list[object], pauses: list[tuple[float, dict[str, Any]]]
) -> tuple[int | None, str, str]:
    """mlip-feed prog to its end, the operator resuming each pause (a manual
    tool change) at once through mlip-ctl; pauses gets (time resumed, the
    status that said what to do). Returns (exit code, stdout, stderr)."""
    f = rig.feeder(prog, *args)
    rig.t_feed = time.time()
    last = None
    t_end = time.monotonic() + 900
    while f.p.poll() is None and time.monotonic() < t_end:
        st = rig.status()
        if st["state"] == "paused" and st["reason_seq"] != last:
            last = st["reason_seq"]
            rig.ctl("resume")
            pauses.append((time.time(), st))
        time.sleep(0.05)
    if f.p.poll() is None:
        f.kill()
    rig.t_feed_end = time.time()
    rc = f.p.wait(timeout=60)
    out, err = f.stdout(), f.stderr()
    f.close_files()
    return rc, out, err


def io_report(
    s: Settings,
    sim: DriveSimProc,
    t0: float,
    t_ref: float,
    pauses: list[tuple[float, dict[str, Any]]],
    rows: list[dict[str, Any]],
    nodes: list[int],
    cpu: list[float],
    s_move: int | None,
    tbl: Path,
    check: Any,
) -> None:
    """The tool change, the coolant and the tool's length as the devices
    saw them: the pause and its resume, the module's output bits at every
    SYNC against the axes' motion, Z's targets with the length."""
    for t, st in pauses:
        print(
            f"\ntool change: paused at line {st['reason_line']} ({st['reason']}, at rest, speed "
            f"{st['speed_mm_s']:g} mm/s): {st['operator']}; the demo's operator resumed "
            f"({t - t_ref:.3f} s)"
        )
    check(
        [(st["reason_line"], st["reason"]) for t, st in pauses] == [(3, "tool change (manual)")],
        "T1 M6 paused the program at rest for the operator, once, and resume went on",
    )
    io = [(x["sync"], x["outputs"][0]) for x in sim.io_rows() if x["node"] == IO_NODE]
    io = [(sy, o) for sy, o in io if sy >= min((x["sync"] for x in rows), default=0)]
    seq: list[tuple[int, int]] = []
    for sy, o in io:
        if not seq or seq[-1][1] != o:
            seq.append((sy, o))
    moving = [
        x["sync"] for x in rows if x["target"] is not None and x["node"] in nodes
    ]  # every SYNC with a target: the motion's span is its changes
    by_node: dict[int, list[tuple[int, int]]] = {}
    for x in rows:
        if x["target"] is not None:
            by_node.setdefault(x["node"], []).append((x["sync"], x["target"]))
    changes = [
        b[0] for v in by_node.values() for a, b in zip(v, v[1:], strict=False) if b[1] != a[1]
    ]
    s_last = max(changes, default=None)
    on = next((sy for sy, o in seq if o & FLOOD_BIT), None)
    off = next((sy for sy, o in seq if on is not None and sy > on and not o & FLOOD_BIT), None)
    print(
        f"coolant (M8 ... M9 on the CiA 401 module, node {IO_NODE}, 0x6200:1 bit "
        f"{FLOOD_BIT.bit_length() - 1}): its outputs byte as it applied it, by SYNC: "
        + ", ".join(f"SYNC {sy} 0x{o:02X}" for sy, o in seq)
        + f"; the axes moved from SYNC {s_move} to {s_last} ({len(set(moving))} SYNCs seen)"
    )
    check(
        on is not None
        and s_move is not None
        and s_last is not None
        and on < s_move
        and off is not None
        and off >= s_last,
        f"flood coolant on at the module before the first move (SYNC {on} < {s_move}) and off "
        f"at rest after the last (SYNC {off} >= {s_last})",
    )
    length = next(
        float(w[1:])
        for line in tbl.read_text().splitlines()
        if line.startswith("T1 ")
        for w in line.split(";")[0].split()
        if w.startswith("Z")
    )
    z = [t for sy, t in by_node.get(nodes[2], [])]
    want = round((PROGRAM_Z_TOP + length) * cpu[2])
    print(
        f"tool length (G43 H1, tool 1 {length:g} mm in {tbl.name}): Z's targets on its drive "
        f"reached {max(z, default=0)} counts = program Z{PROGRAM_Z_TOP:g} + {length:g} mm; after "
        f"G49 the last {z[-1] if z else '-'} counts (Z2.5, no offset)"
    )
    check(
        max(z, default=0) == want and bool(z) and z[-1] == round(2.5 * cpu[2]),
        f"Z on the bus carries the tool's length: {max(z, default=0)} = {want} counts",
    )


def sdo_value(ev: list[dict[str, Any]], node: int, index: str, sub: int = 0) -> Any:
    """The last value node received by SDO for index:sub (None: none)."""
    v = None
    for e in ev:
        if (
            e["kind"] == "sdo_write"
            and e["node"] == node
            and e["index"] == index
            and e["sub"] == sub
            and not e.get("abort")
        ):
            v = e.get("value")
    return v
