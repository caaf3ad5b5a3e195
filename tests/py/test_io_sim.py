"""The simulated CiA 401 I/O module and the drive's homing mode (issue 18) on
the host, without vcan: simulator and master are both the real `canopen`
package, joined by python-can's in-process virtual bus. The bus version (with
mlip-rt) is tests/can/test_io_vcan.py and tests/can/test_homing_vcan.py."""

import json
import time

import canopen
import pytest

from conftest import wait_for as wait
from mlipcan import drive as D
from conftest import virtual_bus_sim
from mlipcan import io401


@pytest.fixture
def pair(tmp_path):
    sim, net = virtual_bus_sim(tmp_path, [dict(node_id=5, start_position=7000, heartbeat_ms=0,
                                               lag_alpha=1.0, switches={"neg": 2000})], 10)
    io = net.add_node(10, io401.build_od(10))
    drive = net.add_node(5, D.build_od(5))
    for n in (io, drive):
        n.sdo.RESPONSE_TIMEOUT = 2.0
    yield sim, net, io, drive
    sim.stop()
    net.disconnect()


def test_module_inputs_outputs(pair):
    sim, net, io, _ = pair
    assert io.sdo[0x1000].raw & 0xFFFF == 401
    got = []
    net.subscribe(0x18A, lambda cob, data, t: got.append(bytes(data)))
    # the master's mapping, as mlip writes it: two input bytes, on change
    io.sdo[0x1800][1].raw = 0xC000018A
    io.sdo[0x1A00][0].raw = 0
    io.sdo[0x1A00][1].raw = 0x60000108
    io.sdo[0x1A00][2].raw = 0x60000208
    io.sdo[0x1A00][0].raw = 2
    io.sdo[0x1800][1].raw = 0x4000018A
    with pytest.raises(canopen.SdoAbortedError):
        io.sdo[0x1A00][1].raw = 0x62000108  # mapping while valid: refused (CiA 301)
    net.nmt.send_command(0x01)
    assert wait(lambda: got), "no TPDO on entering operational"
    assert got[-1] == b"\x00\x00"
    sim.inject(10, "input", "2.3=1")
    assert wait(lambda: got[-1] == b"\x00\x08"), got
    assert io.sdo[0x6000][2].raw == 0x08
    n = len(got)
    sim.inject(10, "input", "2.3=1")  # no change: no TPDO
    sim.inject(10, "input", "2.4=1")  # a change: its TPDO, the first after n
    assert wait(lambda: len(got) > n)
    assert got[n:] == [b"\x00\x18"], got[n:]
    # outputs by RPDO (default mapping 0x6200:1), and off when the master's
    # heartbeat is lost
    io.sdo[0x1016][1].raw = (127 << 16) | 300
    hb = net.send_periodic(0x77F, b"\x05", 0.02)  # the master's heartbeat while it runs
    try:
        net.send_message(0x20A, b"\x81")
        assert wait(lambda: io.sdo[0x6200][1].raw == 0x81)
    finally:
        hb.stop()
    # no more heartbeat: once the consumer time has passed, the module (judged
    # at the bus time by sim.tick, the simulator's main loop) switches them off
    assert wait(lambda: sim.tick() or sim.modules[10].outputs[0] == 0)
    assert io.sdo[0x6200][1].raw == 0


def test_drive_homing_limit_switch(pair):
    sim, net, _, drive = pair
    with pytest.raises(canopen.SdoAbortedError):
        drive.sdo[0x6098].raw = 7  # not a method of this drive
    drive.sdo[0x6098].raw = 17
    drive.sdo[0x6099][1].raw = 50000  # counts/s: 500 a SYNC of 10 ms
    drive.sdo[0x6099][2].raw = 1000
    drive.sdo[0x609A].raw = 10**6
    drive.sdo[0x607C].raw = -1500
    drive.sdo[0x60C2][1].raw = 10  # 10 ms
    drive.sdo[0x6060].raw = 6
    assert drive.sdo[0x6061].raw == 6
    for cw in (0x06, 0x07, 0x0F):
        drive.sdo[0x6040].raw = cw
    net.nmt.send_command(0x01)
    d = sim.drives[5]
    d.cw = 0x1F  # bit 4's rising edge, as an RPDO applied at a SYNC
    # SYNCs in lockstep with the drive (each taken before the next is sent):
    # homing's length is a count of SYNCs, whatever the host's load
    for i in range(200):
        s0 = sim.sync_no
        net.sync.transmit()
        assert wait(lambda: sim.sync_no > s0), f"SYNC {i} not taken"
        if d.home_phase in ("done", "error"):
            break
    assert d.home_phase == "done" and d.actual == -1500
    sw = drive.sdo[0x6041].raw
    assert sw & 0x1400 == 0x1400 and not sw & 0x2000, hex(sw)
    # the switch is where it was, in the new reference: within a latch step
    # (10 counts) beyond the home position
    assert -1500 - 10 <= d.switches["neg"] < -1500, d.switches


def test_module_probe_surface_and_outputs_per_sync(pair, tmp_path):
    """The probe input follows drive 5's position against a surface (on at
    or below it), sent in the module's TPDO at once; the outputs in force
    are recorded at every SYNC (io.csv)."""
    sim, net, _, _ = pair
    m = sim.modules[10]
    got = []
    net.subscribe(0x18A, lambda cob, data, t: got.append(bytes(data)))
    net.nmt.send_command(0x01)  # default mapping: TPDO1 = 0x6000:1
    assert wait(lambda: got), "no TPDO on entering operational"
    with pytest.raises(ValueError):
        sim.inject(10, "probe", "1.3,5,5000,sideways")
    sim.inject(10, "probe", "1.3,5,5000,below")  # the drive stands at 7000: off
    assert m.inputs[0] & 0x08 == 0
    n = len(got)
    m.follow(5, 5001, 7)
    assert len(got) == n and m.inputs[0] == 0
    m.follow(5, 5000, 8)  # on the surface: on, sent now
    assert wait(lambda: got[-1] == b"\x08"), got
    m.follow(4, 100, 9)  # another drive: nothing
    assert m.inputs[0] == 0x08
    m.follow(5, 5200, 10)
    assert wait(lambda: got[-1] == b"\x00"), got
    ev = [
        e
        for e in map(json.loads, (tmp_path / "events.jsonl").read_text().splitlines())
        if e["kind"] == "probe"
    ]
    assert [(e["on"], e["sync"], e["actual"]) for e in ev] == [(True, 8, 5000), (False, 10, 5200)]
    # the outputs as RPDO1 set them, at every SYNC after
    net.send_message(0x20A, b"\x05")
    assert wait(lambda: m.outputs[0] == 0x05)
    s0 = sim.sync_no
    for _ in range(3):
        net.sync.transmit()
    assert wait(lambda: sim.sync_no >= s0 + 3)
    sim.tick()  # the records to disk
    rows = (tmp_path / "io.csv").read_text().splitlines()
    assert rows[0] == "sync,node,t,outputs,inputs"
    last = rows[-1].split(",")
    assert int(last[1]) == 10 and bytes.fromhex(last[3])[0] == 0x05, rows[-3:]
    assert len(rows) >= 4


# each homing method against switches and an index pulse every 1000 counts
# (power-up reference), the drive at START: (method, start, switches, home =
# where the method puts the home position in the power-up reference, exact
# for an index pulse, within a latch step (50 counts) past the switch's edge
# for a switch alone, index: it reports homing attained before it stands there)
HOME_CASES = [
    (1, 7000, {"neg": 2000}, 3000, True),  # neg limit, then the index in +
    (2, 7000, {"pos": 9000}, 8000, True),  # pos limit, then the index in -
    (3, 3000, {"home": 5000}, 4000, True),  # to the switch in +, back off it, index in -
    (3, 6500, {"home": 5000}, 4000, True),  # on it at the start: off it in -, the same
    (5, 7000, {"nhome": 5000}, 6000, True),  # negative home switch, the index in +
    (17, 7000, {"neg": 2000}, 2000, False),
    (18, 7000, {"pos": 9000}, 9000, False),
    (19, 3000, {"home": 5000}, 5000, False),
    (19, 6500, {"home": 5000}, 5000, False),  # on it at the start
    (21, 7000, {"nhome": 5000}, 5000, False),
    (33, 7300, {}, 7000, True),  # the first index pulse in -
    (34, 7300, {}, 8000, True),  # in +
    (37, 7300, {}, 7300, False),  # the current position
]


def homing_drive(tmp_path, start, switches):
    """Drive 5 at start on a virtual bus, with these switches, a master."""
    sim, net = virtual_bus_sim(tmp_path, [dict(node_id=5, start_position=start, heartbeat_ms=0,
                                               lag_alpha=1.0, start_state="switch on disabled",
                                               switches=switches)])
    drive = net.add_node(5, D.build_od(5))
    drive.sdo.RESPONSE_TIMEOUT = 2.0
    return sim, net, drive


@pytest.mark.parametrize("method,start,switches,home,index", HOME_CASES)
def test_drive_homing_methods(tmp_path, method, start, switches, home, index):
    sim, net, drive = homing_drive(tmp_path, start, dict(switches, index=1000))
    try:
        drive.sdo[0x6098].raw = method
        drive.sdo[0x6099][1].raw = 50000  # counts/s: 500 a SYNC of 10 ms
        drive.sdo[0x6099][2].raw = 5000  # 50 a SYNC
        drive.sdo[0x609A].raw = 10**6
        drive.sdo[0x607C].raw = -1500
        drive.sdo[0x60C2][1].raw = 10  # 10 ms
        drive.sdo[0x6060].raw = 6
        for cw in (0x06, 0x07, 0x0F):
            drive.sdo[0x6040].raw = cw
        net.nmt.send_command(0x01)
        d = sim.drives[5]
        d.cw = 0x1F  # bit 4's rising edge, as an RPDO applied at a SYNC
        sws = []
        for i in range(1, 400):
            net.sync.transmit()
            assert wait(lambda: d.move_sync == i, 10.0), f"SYNC {i} not handled"
            sws.append(d.statusword())
            if d.home_phase in ("done", "error"):
                break
        assert d.home_phase == "done", (d.home_phase, [e for e in rec_events(tmp_path)][-5:])
        assert d.actual == -1500 and d.target == -1500
        assert sws[-1] & 0x3400 == 0x1400, hex(sws[-1])  # 10 and 12, not 13
        assert not any(sw & 0x2000 for sw in sws)
        # while it moved, never 10 with 12; after an index pulse 12 alone first
        assert all(sw & 0x1400 != 0x1400 for sw in sws[:-1]), [hex(s) for s in sws]
        assert any(sw & 0x1400 == 0x1000 for sw in sws) == index, [hex(s) for s in sws]
        ev = [e for e in rec_events(tmp_path) if e["kind"] == "homing"]
        at = next(e for e in ev if e["phase"] in ("index", "done"))["home"]
        if index or method == 37:
            assert at == home, ev
        else:
            # the switch's edge, found at the latch speed: within one step past it
            assert 0 < (at - home) * HOME_DIR[method] <= 50, ev
    finally:
        sim.stop()
        net.disconnect()


# the direction the latch (the last move) runs in, for the switch methods
HOME_DIR = {17: 1, 18: -1, 19: -1, 21: 1}


def rec_events(tmp_path):
    return [json.loads(line) for line in (tmp_path / "events.jsonl").read_text().splitlines()]


def test_drive_homing_without_its_switch_or_index(tmp_path):
    """A method whose switch or index pulse the drive has not: homing error
    (bit 13 with 10: at rest), nothing moves."""
    sim, net, drive = homing_drive(tmp_path, 100, {"neg": -900})
    try:
        drive.sdo[0x6060].raw = 6
        for cw in (0x06, 0x07, 0x0F):
            drive.sdo[0x6040].raw = cw
        net.nmt.send_command(0x01)
        d = sim.drives[5]
        for k, method in enumerate((1, 19, 34), 1):
            drive.sdo[0x6098].raw = method
            d.cw = 0x0F
            net.sync.transmit()
            assert wait(lambda: d.move_sync == 2 * k - 1, 10.0)
            d.cw = 0x1F
            net.sync.transmit()
            assert wait(lambda: d.move_sync == 2 * k, 10.0)
            assert d.home_phase == "error" and d.statusword() & 0x3400 == 0x2400
            assert d.actual == 100
        why = [e["why"] for e in rec_events(tmp_path) if e.get("phase") == "error"]
        assert why == ["no index pulse", "no home switch", "no index pulse"], why
    finally:
        sim.stop()
        net.disconnect()


def test_module_reboot_as_another(pair):
    """reboot=PRODUCT: another module boots on the node; its product code
    0x1018:02 is that from then on (an NMT reset does not bring the old one
    back); vendor and device type as before."""
    sim, net, io, _ = pair
    assert io.sdo[0x1018][2].raw == 0x4D4C4950
    sim.inject(10, "reboot", "0x4D4C4951")
    assert io.sdo[0x1018][2].raw == 0x4D4C4951
    net.nmt.send_command(0x82)  # reset communication
    assert wait(lambda: sim.modules[10].node.nmt.state == "PRE-OPERATIONAL")
    assert io.sdo[0x1018][2].raw == 0x4D4C4951
    assert io.sdo[0x1000].raw & 0xFFFF == 401


def test_module_fault_error_register(pair):
    """fault=CODE: EMCY CODE with error register 0x01, and 0x1001 reads 0x01
    through an NMT reset communication (the fault is the hardware's);
    fault=off: EMCY 0x0000 (error reset), 0x1001 back to 0."""
    sim, net, io, _ = pair
    got = []
    net.subscribe(0x08A, lambda cob, data, t: got.append(bytes(data)))
    assert io.sdo[0x1001].raw == 0
    sim.inject(10, "fault", "0x5000")
    assert wait(lambda: got), "no EMCY"
    assert got[-1][:3] == b"\x00\x50\x01", got
    assert io.sdo[0x1001].raw == 0x01
    net.nmt.send_command(0x82)  # reset communication
    assert wait(lambda: sim.modules[10].node.nmt.state == "PRE-OPERATIONAL")
    assert io.sdo[0x1001].raw == 0x01
    sim.inject(10, "fault", "off")
    assert wait(lambda: len(got) == 2), got
    assert got[-1][:3] == b"\x00\x00\x00", got
    assert io.sdo[0x1001].raw == 0
