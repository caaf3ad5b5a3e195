"""The simulated CiA 402 drive (mlipcan.drive) on the host, without
vcan: drive and master are both the real `canopen` package, joined by
python-can's in-process virtual bus. The power state machine is walked
through every transition of CiA 402's figure by SDO controlword writes and
checked on the statusword the master reads back; the bus version of these
checks (and the PDOs on SYNC) is tests/can/test_drive_sim_vcan.py."""
import time

import can  # the package's dependencies, installed by tools/deps.sh
import canopen
import pytest

from conftest import virtual_bus_sim
from mlipcan import cia402 as P
from mlipcan import drive as D


@pytest.fixture
def pair(tmp_path):
    sim, net = virtual_bus_sim(tmp_path, [dict(node_id=5, start_position=-777, heartbeat_ms=0)])
    node = net.add_node(5, D.build_od(5))
    node.sdo.RESPONSE_TIMEOUT = 2.0
    yield sim, node, tmp_path
    sim.stop()
    net.disconnect()


def state(node):
    return P.state_of(node.sdo[0x6041].raw)


# (from, controlword, to): CiA 402 transitions 2-12 and 15-16
WALK = [
    (P.SWITCH_ON_DISABLED, 0x06, P.READY),              # 2
    (P.READY, 0x07, P.SWITCHED_ON),                     # 3
    (P.SWITCHED_ON, 0x0F, P.OPERATION_ENABLED),         # 4
    (P.OPERATION_ENABLED, 0x07, P.SWITCHED_ON),         # 5
    (P.SWITCHED_ON, 0x06, P.READY),                     # 6
    (P.READY, 0x00, P.SWITCH_ON_DISABLED),              # 7
    (P.SWITCH_ON_DISABLED, 0x06, P.READY),
    (P.READY, 0x0F, P.OPERATION_ENABLED),               # 3 + 4 in one command
    (P.OPERATION_ENABLED, 0x06, P.READY),               # 8
    (P.READY, 0x07, P.SWITCHED_ON),
    (P.SWITCHED_ON, 0x02, P.SWITCH_ON_DISABLED),        # 10 (quick stop)
    (P.SWITCH_ON_DISABLED, 0x0F, P.SWITCH_ON_DISABLED), # no transition from there
    (P.SWITCH_ON_DISABLED, 0x06, P.READY),
    (P.READY, 0x0F, P.OPERATION_ENABLED),
    (P.OPERATION_ENABLED, 0x00, P.SWITCH_ON_DISABLED),  # 9
]


def test_power_state_machine_walk(pair):
    sim, node, rec = pair
    assert state(node) == P.SWITCH_ON_DISABLED
    assert node.sdo[0x6064].raw == -777
    for frm, cw, to in WALK:
        assert state(node) == frm
        node.sdo[0x6040].raw = cw
        assert state(node) == to, f"{frm} + controlword 0x{cw:02X}"
    # quick stop from operation enabled: option code 2 -> switch on disabled (11, 12);
    # option code 6 stays in quick stop active, enable operation leaves it (16)
    for cw in (0x06, 0x0F, 0x02):
        node.sdo[0x6040].raw = cw
    assert state(node) == P.SWITCH_ON_DISABLED
    node.sdo[0x605A].raw = 6
    for cw in (0x06, 0x0F, 0x02):
        node.sdo[0x6040].raw = cw
    assert state(node) == P.QUICK_STOP
    assert not node.sdo[0x6041].raw & P.SW_QUICK_STOP  # bit 5 = 0: quick stop active
    node.sdo[0x6040].raw = 0x0F
    assert state(node) == P.OPERATION_ENABLED
    # a fault (13, 14), then the fault reset edge (15); shutdown alone does not leave fault
    sim.inject(5, "fault", "0x3210")
    assert state(node) == P.FAULT and node.sdo[0x1001].raw & 1
    node.sdo[0x6040].raw = 0x06
    assert state(node) == P.FAULT
    node.sdo[0x6040].raw = 0x86
    assert state(node) == P.SWITCH_ON_DISABLED and node.sdo[0x1001].raw == 0
    sim.tick()
    kinds = [ln for ln in (rec / "events.jsonl").read_text().splitlines() if '"state"' in ln]
    assert len(kinds) >= len(WALK)


def test_move_by_hand_only_while_disabled(pair):
    """N:move=COUNTS: a disabled axis pushed by hand changes its position
    actual; an enabled drive holds its position against it."""
    sim, node, rec = pair
    sim.inject(5, "move", "250")
    assert node.sdo[0x6064].raw == -777 + 250
    for cw in (0x06, 0x07):
        node.sdo[0x6040].raw = cw
    sim.inject(5, "move", "-50")  # switched on: no torque yet
    assert node.sdo[0x6064].raw == -777 + 200
    node.sdo[0x6040].raw = 0x0F
    assert state(node) == P.OPERATION_ENABLED
    sim.inject(5, "move", "1000")
    assert node.sdo[0x6064].raw == -777 + 200
    sim.tick()
    ev = [ln for ln in (rec / "events.jsonl").read_text().splitlines()
          if '"moved"' in ln or '"move_refused"' in ln]
    assert len(ev) == 3 and '"move_refused"' in ev[-1], ev


def test_profile_velocity_ramps_to_target(pair):
    """Mode 3 (a spindle, issue 19): enabled, the velocity actual 0x606C ramps
    to the target velocity 0x60FF at 0x6083 per SYNC (0x60C2: 1 ms), with
    statusword bit 10 (target reached) only within 0x606D of it and bit 12
    (speed zero) only near 0; a quick stop brakes it to 0 at 0x6084."""
    sim, node, rec = pair
    node.sdo[0x6060].raw = 3
    node.sdo[0x6083].raw = 200000  # counts/s^2: 200 counts/s per 1 ms SYNC
    node.sdo[0x6084].raw = 400000
    node.sdo[0x606D].raw = 100
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw
    assert state(node) == P.OPERATION_ENABLED
    node.nmt.state = "OPERATIONAL"
    deadline = time.monotonic() + 10
    while sim.drives[5].nmt_state() != "OPERATIONAL" and time.monotonic() < deadline:
        time.sleep(0.01)
    node.sdo[0x60FF].raw = 10000  # applied at the next SYNC, as an RPDO's
    assert node.sdo[0x6041].raw & D.SW_SPEED_ZERO
    seen = []
    for k in range(80):  # 10000 / 200 = 50 SYNCs of ramp
        node.network.sync.transmit()
        while sim.sync_no < k + 1 and time.monotonic() < deadline:
            time.sleep(0.001)
        seen.append((node.sdo[0x606C].raw, node.sdo[0x6041].raw))
    v = [a for a, _ in seen]
    assert v[0] == 200 and v[1] == 400, v[:5]  # the ramp, to the count
    assert v[49] == 10000 and v[-1] == 10000
    reached = [k for k, (a, s) in enumerate(seen) if s & P.SW_TARGET_REACHED]
    assert reached == list(range(49, 80)), reached[:3]  # 9800 is not within 100, 10000 is
    assert seen[48][0] == 9800
    assert not any(s & D.SW_SPEED_ZERO for _, s in seen[1:])
    node.sdo[0x6040].raw = 0x02  # quick stop: switch on disabled, braking at 0x6084
    for k in range(80, 120):
        node.network.sync.transmit()
        while sim.sync_no < k + 1 and time.monotonic() < deadline:
            time.sleep(0.001)
    assert node.sdo[0x606C].raw == 0


@pytest.fixture
def two(tmp_path):
    chan = f"drive-{time.monotonic_ns()}"
    rec = D.Recorder(tmp_path)
    sim = D.DriveSim(
        chan,
        [
            dict(node_id=5, start_position=0, heartbeat_ms=0),
            dict(node_id=6, start_position=100, heartbeat_ms=0),
        ],
        rec,
        bus=can.Bus(interface="virtual", channel=chan),
    )
    net = canopen.Network(can.Bus(interface="virtual", channel=chan))
    net.connect()
    sim.start()
    nodes = [net.add_node(n, D.build_od(n)) for n in (5, 6)]
    for node in nodes:
        node.sdo.RESPONSE_TIMEOUT = 2.0
    yield sim, nodes, net, tmp_path
    sim.stop()
    net.disconnect()


@pytest.fixture
def sw_pair(tmp_path):
    """Drive 5 at 0 with its positive limit switch at 1500 counts."""
    chan = f"drive-{time.monotonic_ns()}"
    rec = D.Recorder(tmp_path)
    sim = D.DriveSim(chan, [dict(node_id=5, start_position=0, heartbeat_ms=0,
                                 switches={"pos": 1500})], rec,
                     bus=can.Bus(interface="virtual", channel=chan))
    net = canopen.Network(can.Bus(interface="virtual", channel=chan))
    net.connect()
    sim.start()
    node = net.add_node(5, D.build_od(5))
    node.sdo.RESPONSE_TIMEOUT = 2.0
    yield sim, node, net
    sim.stop()
    net.disconnect()


def test_touch_probe_latches_between_syncs(two):
    """Touch probe 1 (CiA 402 0x60B8..0x60BB, issue 19): armed for its positive
    edge, each drive latches its own position at the instant drive 5's move
    crosses the surface (a third of the way between two SYNCs here), not a
    position of a SYNC; the first event only, until switched on again; off
    clears the status; the negative edge latches 0x60BB."""
    sim, (a, b), net, rec = two
    for node in (a, b):
        node.sdo[0x6060].raw = P.MODE_CSP
        for cw in (0x06, 0x07, 0x0F):
            node.sdo[0x6040].raw = cw
        assert state(node) == P.OPERATION_ENABLED
        node.nmt.state = "OPERATIONAL"
    deadline = time.monotonic() + 10
    while any(d.nmt_state() != "OPERATIONAL" for d in sim.drives.values()):
        assert time.monotonic() < deadline
        time.sleep(0.01)
    sim.inject(5, "touch-probe", "-1000,below")
    for node in (a, b):
        node.sdo[0x60B8].raw = D.TP_ENABLE | D.TP_POS_EDGE
        assert node.sdo[0x60B9].raw == D.TP_ENABLE  # on, nothing stored

    def sync_to(ta, tb):
        a.sdo[0x607A].raw = ta  # applied at the next SYNC, as an RPDO's
        b.sdo[0x607A].raw = tb
        n = sim.sync_no
        net.sync.transmit()
        while sim.sync_no < n + 1:
            assert time.monotonic() < deadline
            time.sleep(0.001)
        return a.sdo[0x6064].raw, b.sdo[0x6064].raw

    rows = [sync_to(-300 * k, 100 + 30 * k) for k in range(1, 5)]
    assert rows[-1] == (-1200, 220)  # the last SYNC's move crossed -1000 at 1/3 of it
    for node in (a, b):
        assert node.sdo[0x60B9].raw == D.TP_ENABLE | D.TP_POS_STORED
    assert a.sdo[0x60BA].raw == -1000  # where it crossed, to the count
    assert b.sdo[0x60BA].raw == 190 + 10  # 190 -> 220 at 1/3: 200, no SYNC's position
    assert 200 not in [r[1] for r in rows]
    # further, back off and on again: the first event stays (not continuous)
    sync_to(-1500, 220)
    sync_to(-500, 220)
    sync_to(-1300, 220)
    assert a.sdo[0x60BA].raw == -1000 and b.sdo[0x60BA].raw == 200
    # off: status cleared; on for the negative edge: the way off the surface
    for node in (a, b):
        node.sdo[0x60B8].raw = 0
        assert node.sdo[0x60B9].raw == 0
        node.sdo[0x60B8].raw = D.TP_ENABLE | D.TP_NEG_EDGE
    sync_to(-700, 220)  # -1300 -> -700 crosses -1000 at half of the move
    assert a.sdo[0x60B9].raw == D.TP_ENABLE | D.TP_NEG_STORED
    assert a.sdo[0x60BB].raw == -1000 and b.sdo[0x60BB].raw == 220
    sim.tick()
    ev = [ln for ln in (rec / "events.jsonl").read_text().splitlines() if '"touch_probe"' in ln]
    assert len(ev) == 4, ev  # two drives, two edges


def test_csp_quick_stop_ramp_and_digital_inputs(sw_pair):
    """CSP (issue 18): 0x60FD from the switch positions, sent in TPDO3 when
    the master maps it (on change; a garbled one by injection), while TPDO2
    carries the touch probe's positions at every SYNC (both on one drive);
    a quick stop while moving brakes on 0x6085, the distance that of the
    discrete ramp, then switch on disabled (0x605A = 2)."""
    sim, node, net = sw_pair
    got, tp2 = [], []
    net.subscribe(0x385, lambda cob, data, ts: got.append(bytes(data)))
    net.subscribe(0x285, lambda cob, data, ts: tp2.append(bytes(data)))
    node.sdo[0x6060].raw = 8
    node.sdo[0x6085].raw = 10_000_000  # counts/s^2: 10000 counts/s less per 1 ms SYNC
    assert node.sdo[0x60FD].raw == 0
    node.sdo[0x1802][1].raw = 0x80000385
    node.sdo[0x1A02][0].raw = 0
    node.sdo[0x1A02][1].raw = 0x60FD0020
    node.sdo[0x1A02][0].raw = 1
    node.sdo[0x1802][1].raw = 0x40000385
    node.sdo[0x1801][1].raw = 0x80000285  # TPDO2: the touch probe's, as mlip maps it
    node.sdo[0x1A01][0].raw = 0
    node.sdo[0x1A01][1].raw = 0x60BA0020
    node.sdo[0x1A01][2].raw = 0x60BB0020
    node.sdo[0x1A01][0].raw = 2
    node.sdo[0x1801][1].raw = 0x40000285
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw
    assert state(node) == P.OPERATION_ENABLED
    node.nmt.state = "OPERATIONAL"
    deadline = time.monotonic() + 20

    def until(cond):
        while not cond():
            assert time.monotonic() < deadline, "timed out"
            time.sleep(0.001)

    until(lambda: got)  # the inputs once on entering operational
    assert got[0] == bytes(4)
    pos = []
    for k in range(1, 21):  # 100 counts a SYNC: 100000 counts/s, over the switch at 1500
        node.sdo[0x607A].raw = 100 * k  # applied at the next SYNC, as an RPDO's
        node.network.sync.transmit()
        until(lambda: sim.sync_no >= k)
        pos.append(node.sdo[0x6064].raw)
    assert pos[-1] == 2000, pos
    until(lambda: len(got) >= 2)
    assert got[1] == bytes([2, 0, 0, 0]), got  # bit 1: the positive limit switch
    assert len(got) == 2, got  # TPDO3 on change only, not per SYNC
    until(lambda: len(tp2) >= 20)
    assert len(tp2) == 20 and tp2[0] == bytes(8), tp2  # TPDO2 at every SYNC
    x0 = pos[-1]
    node.sdo[0x6040].raw = 0x02
    assert state(node) == P.QUICK_STOP  # braking
    for k in range(21, 41):
        node.network.sync.transmit()
        until(lambda: sim.sync_no >= k)
        pos.append(node.sdo[0x6064].raw)
    steps = [b - a for a, b in zip(pos[19:], pos[20:])]
    # 100000 counts/s less 10000 each SYNC: 90, 80, .. 10 counts, then at rest
    assert steps[:10] == [90, 80, 70, 60, 50, 40, 30, 20, 10, 0], steps
    assert pos[-1] - x0 == 450  # v^2/2a - vT/2 = 500 - 50
    assert state(node) == P.SWITCH_ON_DISABLED
    n = len(got)
    sim.inject(5, "di-garbled", "0x4")
    until(lambda: len(got) > n)
    assert got[n] == bytes([4, 0, 0]), got  # a frame one byte short
    sim.inject(5, "di", "1=0")  # forced off on the switch
    until(lambda: len(got) > n + 1)
    assert got[n + 1] == bytes(4) and node.sdo[0x60FD].raw == 0


def test_consumer_not_blamed_for_own_stall(pair):
    """The consumer counts the time the drive listens (mlipcan.drive
    DriveSim.own_stall): a stall of the simulator itself moves the master's
    last heartbeat on by its length, and a heartbeat frame received later
    but stamped before that never moves it back; a master that stays silent
    is still judged lost, the stall's length later."""
    sim, node, _ = pair
    node.sdo[0x1016][1].raw = (127 << 16) | 300  # master 127, 300 ms
    node.network.send_message(0x77F, b"\x05")
    d = sim.drives[5]
    end = time.monotonic() + 5
    while d.hb_consumed[127][1] is None:
        assert time.monotonic() < end, "the heartbeat never seen"
        time.sleep(0.01)
    seen = d.hb_consumed[127][1]
    sim.own_stall(1.0)
    assert d.hb_consumed[127][1] == seen + 1.0
    d._on_heartbeat(0x77F, bytearray(b"\x05"), seen + 0.1)  # stamped before the stall's end
    assert d.hb_consumed[127][1] == seen + 1.0
    sim._judge(seen + 1.25, "bus")
    assert not d.hb_lost and d.state != P.FAULT
    sim._judge(seen + 1.31, "bus")
    assert d.hb_lost == {127} and d.state == P.FAULT
