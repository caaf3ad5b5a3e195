"""Smoke test of the CAN test environment: frames round-trip on a real vcan0.

Run it through tools/vcan/run.sh, which makes vcan0 on the host or, on a kernel
without CAN, in a QEMU VM:

    tools/vcan/run.sh '.venv/bin/python -m pytest -q tests/can/test_vcan_smoke.py'

Without an UP vcan0 these tests fail (they do not skip): a green run means that
the SocketCAN path really was exercised.
"""

import os
import socket

import can
import pytest

IFACE = os.environ.get("MLIP_VCAN_IFACE", "vcan0")
SYS = f"/sys/class/net/{IFACE}"
ARPHRD_CAN = 280
CANFD_MTU = 72
RECV_TIMEOUT = 5.0  # s; generous, the VM is software-emulated


def _sys(name):
    with open(os.path.join(SYS, name)) as f:
        return f.read().strip()


@pytest.fixture(scope="module")
def iface():
    if not hasattr(socket, "AF_CAN"):
        pytest.fail("this Python has no AF_CAN support")
    if not os.path.isdir(SYS):
        pytest.fail(f"no {IFACE}: run through tools/vcan/run.sh")
    assert int(_sys("type")) == ARPHRD_CAN, f"{IFACE} is not a CAN interface"
    assert int(_sys("flags"), 16) & 0x1, f"{IFACE} is down"
    return IFACE


@pytest.fixture
def buses(iface):
    """A sender and a receiver on the same vcan, both CAN FD enabled."""
    tx = can.Bus(interface="socketcan", channel=iface, fd=True)
    rx = can.Bus(
        interface="socketcan",
        channel=iface,
        fd=True,
        can_filters=[
            {"can_id": 0x123, "can_mask": 0x7FF, "extended": False},
            {"can_id": 0x1ABCDE0, "can_mask": 0x1FFFFFFF, "extended": True},
            {"can_id": 0x0F1, "can_mask": 0x7FF, "extended": False},
        ],
    )
    try:
        yield tx, rx
    finally:
        tx.shutdown()
        rx.shutdown()


def _roundtrip(tx, rx, msg):
    tx.send(msg, timeout=RECV_TIMEOUT)
    got = rx.recv(timeout=RECV_TIMEOUT)
    assert got is not None, f"no frame received on {rx.channel_info}"
    return got


def test_classic_frames_roundtrip(buses):
    tx, rx = buses
    std = can.Message(arbitration_id=0x123, is_extended_id=False,
                      data=bytes([0xDE, 0xAD, 0xBE, 0xEF, 1, 2, 3, 4]))
    got = _roundtrip(tx, rx, std)
    assert got.arbitration_id == 0x123
    assert not got.is_extended_id
    assert not got.is_fd
    assert got.dlc == 8
    assert bytes(got.data) == std.data

    ext = can.Message(arbitration_id=0x1ABCDE0, is_extended_id=True, data=b"\x55\xaa")
    got = _roundtrip(tx, rx, ext)
    assert got.arbitration_id == 0x1ABCDE0
    assert got.is_extended_id
    assert bytes(got.data) == b"\x55\xaa"


def test_fd_frame_roundtrip(buses):
    mtu = int(_sys("mtu"))
    assert mtu == CANFD_MTU, f"{IFACE} mtu is {mtu}: CAN FD needs 'ip link set {IFACE} mtu 72'"
    tx, rx = buses
    payload = bytes(range(64))
    fd = can.Message(arbitration_id=0x0F1, is_extended_id=False, is_fd=True,
                     bitrate_switch=True, data=payload)
    got = _roundtrip(tx, rx, fd)
    assert got.is_fd
    assert got.bitrate_switch
    assert got.arbitration_id == 0x0F1
    assert got.dlc == 64
    assert bytes(got.data) == payload


def test_receiver_sees_nothing_stray(buses):
    """The filters hold: a frame for another id does not reach the receiver."""
    tx, rx = buses
    tx.send(can.Message(arbitration_id=0x7FF, is_extended_id=False, data=b"\x00"))
    assert rx.recv(timeout=0.2) is None
