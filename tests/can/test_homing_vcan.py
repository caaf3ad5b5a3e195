"""Homing with the drives' own homing mode (issue 18, CiA 402 mode 6) on a
real vcan0, against the canopen package's drives with switches at given
positions: the master writes 0x6098, 0x6099:1/2, 0x609A, 0x607C and 0x6060 by
SDO in the loop (SYNC, heartbeats and supervision running), each read back,
starts with controlword bit 4, waits for statusword bits 10 and 12, and
returns the drive to mode 8 with the target equal to the position actual.
Judged on what the drives recorded (events.jsonl: the SDO writes, the homing
phases; sync.csv: the target and actual of every SYNC).

Drives (one simulator): 1 at 12345 counts (method 35), 2 at 7000 with its
negative limit switch at 2000 (method 17), 3 at 3000 with its home switch at
5000 (method 19); 4 without switches (method 17: a homing error); 5 that
never finishes (a timeout). The index pulse methods and 37 (the listener
knows nodes 1-6): X on 1 again (method 37, CiA 402-2016's current
position), Y on 6 at 9000 with its negative limit switch at 1000 and an
encoder index pulse every 2000 counts (method 1: the first index pulse past
the switch's edge, at 2000), Z on 4 with the same index (method 33: the
first index pulse in -, at 0). Period 40 ms, as the other drive tests.
"""

import re
import time

import pytest

from conftest import DRIVES_VM, S
from mlipcan import procs

MILL = S.config_dir / "mill-3axis.ini"
PERIOD_S = 0.04
HOMES = {"X": (35, 0.0, 1), "Y": (17, -1.5, 1), "Z": (19, 10.0, 0)}  # method, offset, seq
# the index pulse methods and 37 (nodes 1, 6, 4)
HOMES_37_1_33 = {"X": (37, 2.0, 1), "Y": (1, -1.5, 1), "Z": (33, 10.0, 0)}
DRIVES = DRIVES_VM + "HOMING_REQUIRED = 1\n"
LIMITS = {"X": (-5.0, 20.0), "Y": (-5.0, 20.0), "Z": (0.0, 20.0)}  # mm, the program's box


def machine(tmp, nodes, homes=HOMES, timeout=30, name="home.ini", limits=None):
    text = MILL.read_text().replace("PERIOD = 0.001", f"PERIOD = {PERIOD_S}")
    text = text.replace("CONTOUR_TOLERANCE = 0.01", "CONTOUR_TOLERANCE = 0.5")
    for axis, (lo, hi) in (limits or {}).items():
        sec = rf"(^\[AXIS_{axis}\]$(?:\n(?!\[).*)*?\n"
        text = re.sub(sec + r"MIN_LIMIT = )\S+", rf"\g<1>{lo}", text, count=1, flags=re.M)
        text = re.sub(sec + r"MAX_LIMIT = )\S+", rf"\g<1>{hi}", text, count=1, flags=re.M)
    for axis, node in zip("XYZ", nodes):
        sec = rf"(^\[AXIS_{axis}\]$(?:\n(?!\[).*)*?\n"
        text = re.sub(sec + r"CAN_NODE = )\d+", rf"\g<1>{node}", text, count=1, flags=re.M)
        method, offset, seq = homes[axis]
        text = re.sub(rf"^\[AXIS_{axis}\]$",
                      f"[AXIS_{axis}]\nHOME_METHOD = {method}\nHOME_OFFSET = {offset}\n"
                      f"HOME_SEQUENCE = {seq}\nHOME_SEARCH_VEL = 5\nHOME_LATCH_VEL = 0.5\n"
                      f"HOME_ACCEL = 20\n"
                      f"HOME_TIMEOUT = {timeout}", text, count=1, flags=re.M)
    path = tmp / name
    path.write_text(text + DRIVES)
    return path


@pytest.fixture(scope="module")
def sim(vcan, tmp_path_factory):
    w = tmp_path_factory.mktemp("homesim")
    s = procs.DriveSimProc(S, w, nodes=[1, 2, 3, 4, 5, 6],
                           starts={1: 12345, 2: 7000, 3: 3000, 4: 100, 5: 200, 6: 9000},
                           args=["--switches", "2=neg:2000", "--switches", "3=home:5000",
                                 "--switches", "4=index:2000", "--switches", "5=neg:-100000",
                                 "--switches", "6=neg:1000,index:2000"],
                           inject=["5:homing-stall"])
    yield s
    s.stop()


def homing_events(sim, t0):
    out = {}
    for e in sim.events("homing"):
        if e["t"] >= t0:
            out.setdefault(e["node"], []).append(e)
    return out


@pytest.mark.parametrize("nodes,homes", [((1, 2, 3), HOMES), ((1, 6, 4), HOMES_37_1_33)],
                         ids=["35-17-19", "37-1-33"])
def test_homing_in_sequence(sim, tmp_path, nodes, homes):
    cfg = machine(tmp_path, nodes, homes=homes, limits=LIMITS)
    offs = {ax: homes[ax][1] for ax in "XYZ"}
    nx, ny, nz = nodes
    ngc = tmp_path / "p.ngc"
    ngc.write_text("G21 G90\nG1 X5 Y5 Z12 F1200\nG1 X0 Y0 Z10\n")
    t0 = time.time()
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        st = rig.status()
        assert st["homed"] == {"X": False, "Y": False, "Z": False}, st
        assert "homed       X no Y no Z no\n" in rig.ctl("status").stdout
        # HOMING_REQUIRED: a program before homing is refused, nothing moves;
        # so are MDI moves (a line of modes alone moves nothing: it runs)
        rc, _, err = rig.feed(ngc, timeout=300)
        assert rc == 1 and "HOMING_REQUIRED" in err and "not homed: X Y Z" in err, err
        st = rig.wait_state("idle", timeout=60, pred=lambda s: s["reason"] == "not homed")
        p = rig.ctl("mdi", "G0 X1", check=False)
        assert p.returncode == 1 and "HOMING_REQUIRED" in p.stderr, p.stderr
        assert rig.ctl("mdi", "G91", check=False).returncode == 0
        assert rig.status()["position"] == st["position"]
        p = rig.ctl("home", check=False)
        home_said = p.stdout.strip()
        assert p.returncode == 0, p.stdout + p.stderr
        want = " ".join(f"{ax} {offs[ax]:.4f}" for ax in "XYZ")
        assert "homed in" in p.stdout and want in p.stdout, p.stdout
        st = rig.status()
        assert st["homed"] == {"X": True, "Y": True, "Z": True}, st
        assert "homed       X yes Y yes Z yes\n" in rig.ctl("status").stdout
        assert st["position_actual"] == offs, st
        assert st["position"] == st["position_actual"]
        t_prog = time.time()
        rc, out, err = rig.feed(ngc, timeout=600)
        assert rc == 0, err
    ev = homing_events(sim, t0)
    # Z (sequence 0) first, then X and Y together
    start = {n: min(e["sync"] for e in ev[n] if e["phase"] == "start") for n in nodes}
    done = {n: max(e["sync"] for e in ev[n] if e["phase"] == "done") for n in nodes}
    assert done[nz] < start[nx] and done[nz] < start[ny], (start, done)
    assert start[nx] == start[ny], start
    # each drive's objects as configured, in counts, read back (no abort)
    for n, ax in zip(nodes, "XYZ"):
        method, offset = homes[ax][0], round(offs[ax] * 1000)
        w = {(e["index"], e["sub"]): e.get("value") for e in sim.events("sdo_write", n)
             if e["t"] >= t0 and not e.get("abort")}
        assert w[("0x6098", 0)] == method and w[("0x607C", 0)] == offset, w
        assert w[("0x6099", 1)] == 5000 and w[("0x6099", 2)] == 500, w
        assert w[("0x6060", 0)] == 8  # the last mode written: back to CSP
    rows = [r for r in sim.sync_rows() if r["t"] >= t0]
    # Y searched at 5 mm/s (200 counts a SYNC), braked past the switch at
    # HOME_ACCEL 20 mm/s^2 (32 counts less a SYNC), latched back at 0.5 mm/s
    # (20 counts a SYNC) until it released (method 1: and on to the index
    # pulse, then back onto it, less than a latch step)
    # (the rows' actual is sampled at each SYNC before that SYNC's move: up
    # to the SYNC of the home event, in the power-up reference)
    idx = [e for e in ev[ny] if e["phase"] == "index"]
    end = idx[0]["sync"] if idx else done[ny]
    ys = [r["actual"] for r in rows if r["node"] == ny and start[ny] < r["sync"] <= end]
    steps = [b - a for a, b in zip(ys, ys[1:]) if b != a]
    assert steps.count(-200) >= 20 and steps.count(20) >= 10, steps
    assert all(s == 20 or -200 <= s < 0 for s in steps), steps
    if homes["Y"][0] == 1:
        # the pulse at 2000 counts of the power-up reference is home: the
        # index event there, 1000 counts (50 latch steps) past the switch
        assert len(idx) == 1 and idx[0]["home"] == 2000.0, idx
        assert steps.count(20) >= 50, steps
        # then in the new reference: less than a latch step past the home
        # position, back onto it (its offset) at the latch speed, at rest
        off = round(offs["Y"] * 1000)
        back = [r["actual"] for r in rows if r["node"] == ny and end < r["sync"] <= done[ny] + 1]
        assert back and back[-1] == off and all(off <= a < off + 20 for a in back), back
        # homing attained (bit 12) before it stood on the home position (bit 10)
        sw = [r["sw"] for r in rows if r["node"] == ny and r["sync"] <= done[ny] + 1]
        assert any(s & 0x1400 == 0x1000 for s in sw), [hex(s) for s in sw]
    # no step at the return to CSP: the first target each drive applied after
    # 0x6060 = 8 equals its position actual, the home offset, to the count
    csp = {}
    for n, ax in zip(nodes, "XYZ"):
        off = round(offs[ax] * 1000)
        t_csp = max(e["t"] for e in sim.events("sdo_write", n)
                    if e["t"] >= t0 and e["index"] == "0x6060" and e.get("value") == 8)
        after = [r for r in rows if r["node"] == n and r["t"] > t_csp and r["target"] is not None]
        assert after[0]["target"] == off and after[0]["actual"] == off, (n, after[:3])
        csp[ax] = (off, after[0]["actual"], after[0]["target"] - after[0]["actual"])
        # the program after homing: every target applied inside the soft limits
        lo, hi = LIMITS[ax]
        prog = [r["target"] for r in after if r["t"] >= t_prog]
        assert prog and lo * 1000 <= min(prog) and max(prog) <= hi * 1000, (ax, min(prog),
                                                                            max(prog))
    per_s = {n: round((done[n] - start[n]) * PERIOD_S, 2) for n in nodes}
    print(f"\n[home] methods X {homes['X'][0]} Y {homes['Y'][0]} Z {homes['Z'][0]}: SYNCs from "
          f"bit 4 to bits 10+12: {dict((n, done[n] - start[n]) for n in nodes)} = {per_s} s at "
          f"40 ms (search 5 mm/s, latch 0.5 mm/s, accel 20 mm/s^2); per axis (offset, actual "
          f"at CSP, first CSP target - actual) in counts: {csp}; mlip-ctl home (set-up by "
          f"SDO, homing, back to CSP, whole machine): {home_said!r}")


@pytest.mark.parametrize("node,what,reason", [(4, "error", "homing error"),
                                              (5, "timeout", "homing timeout")])
def test_homing_fails(sim, tmp_path, node, what, reason):
    homes = dict(HOMES, X=(17, 0.0, 0))
    cfg = machine(tmp_path, [node, 2, 3], homes=homes, timeout=3)
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        p = rig.ctl("home", "X", check=False)
        assert p.returncode == 1, p.stdout
        assert f"node {node}, method 17" in p.stderr, p.stderr
        st = rig.status()
        assert st["state"] == "fault" and st["reason"] == reason, st
        assert st["drives"] == "quick stop" and st["homed"]["X"] is False, st
        rig.wait_state("fault", timeout=60)
        p = rig.ctl("reset", check=False)
        assert p.returncode == 0, p.stderr
        rig.wait_state("idle", timeout=60)
    w = [e for e in sim.events("sdo_write", node) if e["index"] == "0x6060"]
    assert w[-1]["value"] == 8, w[-3:]  # back to CSP after the failure
    if what == "timeout":
        sim.inject(f"{node}:homing-stall=off")


def test_homing_method_refused(sim, tmp_path):
    homes = dict(HOMES, X=(7, 0.0, 0))  # a method this drive does not have
    cfg = machine(tmp_path, [1, 2, 3], homes=homes)
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        p = rig.ctl("home", "X", check=False)
        assert p.returncode == 1
        assert "node 1 refused 0x6098:00" in p.stderr and "0x06090030" in p.stderr, p.stderr
        assert rig.status()["reason"] == "homing object refused"


def test_homed_lost_on_reboot(sim, tmp_path):
    """A drive that reboots (gone from the bus, then back with its boot-up and
    NMT pre-operational) has lost its home: its axis is no longer homed, the
    others stay homed, the machine stops (a drive fault)."""
    homes = {"X": (35, 0.0, 0), "Y": (35, -1.5, 0), "Z": (35, 10.0, 0)}
    cfg = machine(tmp_path, [1, 2, 3], homes=homes)
    with procs.Rig(S, cfg, "cia402", tmp_path, priority=0, rt_args=["--drives"]) as rig:
        p = rig.ctl("home", check=False)
        assert p.returncode == 0, p.stdout + p.stderr
        assert rig.status()["homed"] == {"X": True, "Y": True, "Z": True}
        sim.inject("2:absent")
        sim.inject("2:present")
        st = rig.wait_state("fault", timeout=60)
        assert st["reason"] == "drive fault" and st["reason_node"] == 2, st
        assert st["homed"] == {"X": True, "Y": False, "Z": True}, st
