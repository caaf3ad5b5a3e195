"""mlip-rt --drives against the simulated CiA 402 drives (mlip-drive-sim,
the `canopen` package) on a real vcan0: the bring-up as the drives saw it
(every SDO write, every state transition), a program from where the drives
stand, the drives' recorded targets against the bus, the shut-down order.

Needs mlip-rt's CANopen master (`--drives`, [DRIVES], rt/drives.c: branch
drivec); written and passed on a merge of drivepy and drivec.

The period is 4 ms here: the drive simulator (Python, three drives) takes
about 1.2 ms a SYNC in the emulated VM; the timeouts of [DRIVES] are widened
for the same reason (there mlip-rt's own heartbeats were seen 2.3-4.1 s apart
on the bus while its loop overran: HEARTBEAT_TIMEOUT_MS 20000)."""
import time

from conftest import S
from mlipcan import cia402 as P
from mlipcan import compare, procs
from mlipcan.config import setup_of

MILL = S.config_dir / "mill-3axis.ini"
START = {1: 1234, 2: -5000, 3: 2500}   # counts: X 1.234, Y -5, Z 2.5 mm
SETUP_OBJECTS = {("0x1400", 1), ("0x1400", 2), ("0x1600", 0), ("0x1600", 1), ("0x1600", 2),
                 ("0x1800", 1), ("0x1800", 2), ("0x1A00", 0), ("0x1A00", 1), ("0x1A00", 2),
                 ("0x1005", 0), ("0x6060", 0), ("0x60C2", 1), ("0x60C2", 2), ("0x6065", 0),
                 ("0x1017", 0), ("0x1016", 1)}


def drives_config(tmp_path, period_s=0.004):
    text = MILL.read_text().replace("PERIOD = 0.001", f"PERIOD = {period_s}")
    assert f"PERIOD = {period_s}" in text
    text += ("\n[DRIVES]\nENABLE = 1\nMASTER_NODE = 127\nHEARTBEAT_MS = 100\n"
             "HEARTBEAT_TIMEOUT_MS = 20000\nFOLLOWING_ERROR = 5\nSDO_TIMEOUT_MS = 3000\n"
             "BOOT_TIMEOUT_MS = 20000\nSTATE_TIMEOUT_MS = 5000\n")
    p = tmp_path / "mill-drives.ini"
    p.write_text(text)
    return p


def test_bringup_program_shutdown(vcan, tmp_path):
    config = drives_config(tmp_path)
    setup = setup_of(S, config)
    assert setup.drives
    ngc = compare.cut_program(S.toolpaths / "flower-spiral-2d.ngc", 300, tmp_path / "flower-300.ngc")
    sim = procs.DriveSimProc(S, tmp_path, config=config, starts=START, states={2: "fault"})
    rig = None

    def story():
        """What mlip-rt and the drives said, for a failure message."""
        rt = rig.rt.stderr() if rig is not None and rig.rt is not None else ""
        ev = [e for e in sim.events() if e["kind"] in ("state", "emcy", "nmt", "heartbeat_lost",
                                                       "refused_enable", "sdo_write")]
        return ("mlip-rt:\n" + "\n".join(rt.splitlines()[-25:]) + "\ndrives:\n"
                + "\n".join(str(e) for e in ev[-30:]))

    try:
        with procs.Rig(S, config, "cia402", tmp_path) as rig:
            rc, out, err = rig.feed(ngc, timeout=900)
            try:
                rig.wait_state("idle", timeout=120)
            except AssertionError as e:
                raise AssertionError(f"{e}\n{story()}")
            # the status: where the drives stood at bring-up, and, at rest
            # after the program, their positions actual equal the commanded
            # ones to a count (1000 counts/mm)
            st = rig.wait_state("idle", timeout=30, pred=lambda s: all(
                abs(s["position_actual"][a] - s["position"][a]) <= 1e-3 + 1e-9 for a in "XYZ"))
            for a, n in zip("XYZ", (1, 2, 3)):
                assert abs(st["start_position"][a] - START[n] / 1000.0) < 1e-9, st
        r = rig.result
    finally:
        sim_rc = sim.stop()
    assert sim_rc == 0, sim.proc.stderr()
    assert rc == 0, err
    assert r["rt_rc"] == 0, r["rt_stderr"]
    try:
        # bring-up as the drives saw it: every set-up object written and accepted
        for n in setup.nodes:
            writes = sim.events("sdo_write", n)
            bad = [w for w in writes if "abort" in w]
            assert not bad, f"node {n}: refused writes {bad}"
            got = {(w["index"], w["sub"]) for w in writes}
            assert SETUP_OBJECTS <= got, f"node {n}: not written: {SETUP_OBJECTS - got}"
            nmt = [e["to"] for e in sim.events("nmt", n)]
            assert "OPERATIONAL" in nmt, nmt
            states = [e["to"] for e in sim.events("state", n)]
            assert P.OPERATION_ENABLED in states, states
            # shut-down: from operation enabled, disabled in order, not dropped to a fault
            after = states[len(states) - 1 - states[::-1].index(P.OPERATION_ENABLED):]
            assert P.FAULT not in after and after[-1] in (P.SWITCHED_ON, P.READY,
                                                          P.SWITCH_ON_DISABLED), after
        states2 = [e["to"] for e in sim.events("state", 2)]
        assert states2[:2] == [P.FAULT, P.SWITCH_ON_DISABLED], states2  # the fault reset first
        # the drives followed: the targets applied in operation enabled, per node,
        # start at the drive's start position and equal the bus as the listener saw it
        rows = sim.sync_rows()
        can = r["counts"]
        for i, n in enumerate(setup.nodes):
            applied = [x["target"] for x in rows
                       if x["node"] == n and x["fresh"] and x["state"] == P.OPERATION_ENABLED]
            assert applied, f"node {n}: no target applied in operation enabled"
            assert applied[0] == START[n], f"node {n}: first setpoint {applied[0]} != start {START[n]}"
            bus = [c[i] for c in can]
            a0 = next((j for j, v in enumerate(applied) if v != START[n]), None)
            if a0 is None:  # an axis the program does not move (Z of a 2-D file)
                assert set(bus) == {START[n]}, f"node {n}: moved on the bus, not in the drive"
                continue
            # from the first target that is not the start position on, the drive
            # applied what the bus carried, every period, in order (before it,
            # RPDOs of drives not yet enabled are muted: the listener's cycles
            # are incomplete there)
            b0 = next(j for j, v in enumerate(bus) if v != START[n])
            moving = applied[a0:]
            assert bus[b0:b0 + len(moving)] == moving, f"node {n}: drive != bus"
            assert max(applied) - min(applied) > 1000, f"node {n} hardly moved"
    except AssertionError as e:
        raise AssertionError(f"{e}\n{story()}")
    print(f"drives: {len(rows)} drive-SYNCs recorded; mlip-rt: {r['rt_stderr'].splitlines()[-1]}")
