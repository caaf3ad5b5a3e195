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

from mlipcan import cia402 as P
from mlipcan import drive as D


@pytest.fixture
def pair(tmp_path):
    chan = f"drive-{time.monotonic_ns()}"
    rec = D.Recorder(tmp_path)
    sim = D.DriveSim(chan, [dict(node_id=5, start_position=-777, heartbeat_ms=0)], rec,
                     bus=can.Bus(interface="virtual", channel=chan))
    net = canopen.Network(can.Bus(interface="virtual", channel=chan))
    net.connect()
    sim.start()
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
