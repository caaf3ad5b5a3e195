"""tools/mlip.dbc against the frame layouts of include/mlip/can/canenc.h and the
CiA 301 / CiA 402 frames of a deployment with drives.

The expected bytes below are written by hand from the documented layout; the
very same position vectors are asserted byte for byte against the C encoder in
tests/unit/test_canenc.c (test_golden_*), so DBC and encoder are tied together
through them. The DBC's RPDO is the deployment form (controlword 0x6040, then
target 0x607A: [DRIVES] ENABLE = 1); its bytes 2..5 are the 4-byte target-only
RPDO of test_canenc.c. The other deployment frames (NMT, heartbeat, TPDO,
EMCY) are laid out as CiA 301 / CiA 402 say and as the simulated drives
(mlipcan.drive, on the canopen package) send them.
"""
from pathlib import Path

import pytest

import cantools  # installed by tools/deps.sh (tests/requirements.txt)

DBC = Path(__file__).resolve().parents[2] / "tools" / "mlip.dbc"

AXES = ["X", "Y", "Z", "A", "B", "C"]
# positions in mm / deg, 1000 counts per unit; C is exactly INT32_MIN counts
POS = {"X": 12.345, "Y": -0.001, "Z": -250.5, "A": 90.0, "B": 1000.0, "C": -2147483.648}
CYCLE = 0x12345678
LE = {  # int32 little-endian counts of POS
    "X": "39300000",  # 12345
    "Y": "ffffffff",  # -1
    "Z": "7c2dfcff",  # -250500
    "A": "905f0100",  # 90000
    "B": "40420f00",  # 1000000
    "C": "00000080",  # -2147483648
}
CYCLE_LE = "78563412"

CW_LE = "0f00"       # controlword 0x000F: enable operation
SW_LE = "3712"       # statusword 0x1237: operation enabled, CSP following
CIA402 = [(0x080, "")] + [(0x201 + i, CW_LE + LE[a]) for i, a in enumerate(AXES)]
DEPLOY = [(0x000, "0100"), (0x77F, "05")] + \
    [(0x181 + i, SW_LE + LE[a]) for i, a in enumerate(AXES)] + \
    [(0x081 + i, "10230100000000aa") for i in range(6)] + \
    [(0x701 + i, "7f") for i in range(6)]
PACKED = [
    (0x300, LE["X"] + LE["Y"]),
    (0x301, LE["Z"] + LE["A"]),
    (0x302, LE["B"] + LE["C"]),
    (0x303, CYCLE_LE),
]
FD = [(0x400, CYCLE_LE + "".join(LE[a] for a in AXES) + "00000000")]


@pytest.fixture(scope="module")
def db():
    return cantools.database.load_file(str(DBC), strict=True)


def expected_signals(frame_id):
    if frame_id == 0x080:
        return {}
    if 0x201 <= frame_id <= 0x206:
        a = AXES[frame_id - 0x201]
        return {"controlword": 0x000F, a + "_target": POS[a]}
    if frame_id == 0x000:
        return {"command": 1, "node": 0}
    if frame_id == 0x77F:
        return {"nmt_state": 5}
    if 0x181 <= frame_id <= 0x186:
        a = AXES[frame_id - 0x181]
        return {"statusword": 0x1237, a + "_actual": POS[a]}
    if 0x081 <= frame_id <= 0x086:
        return {"error_code": 0x2310, "error_register": 1, "manufacturer": 0xAA00000000}
    if 0x701 <= frame_id <= 0x706:
        return {"nmt_state": 0x7F}
    if 0x300 <= frame_id <= 0x302:
        k = frame_id - 0x300
        return {AXES[2 * k] + "_target": POS[AXES[2 * k]],
                AXES[2 * k + 1] + "_target": POS[AXES[2 * k + 1]]}
    if frame_id == 0x303:
        return {"cycle": CYCLE}
    if frame_id == 0x400:
        sig = {a + "_target": POS[a] for a in AXES}
        sig["cycle"] = CYCLE
        return sig
    raise AssertionError(hex(frame_id))


def test_every_frame_is_described(db):
    ids = {m.frame_id for m in db.messages}
    assert ids == {fid for fid, _ in CIA402 + PACKED + FD + DEPLOY}
    for m in db.messages:
        assert not m.is_extended_frame
        assert m.is_fd == (m.frame_id == 0x400)


def test_lengths(db):
    for fid, data in CIA402 + PACKED + FD + DEPLOY:
        assert db.get_message_by_frame_id(fid).length == len(bytes.fromhex(data))


@pytest.mark.parametrize("fid,data", CIA402 + PACKED + FD + DEPLOY,
                         ids=lambda v: hex(v) if isinstance(v, int) else None)
def test_decode_golden(db, fid, data):
    got = db.decode_message(fid, bytes.fromhex(data))
    want = expected_signals(fid)
    assert set(got) == set(want)
    for name, value in want.items():
        assert got[name] == pytest.approx(value, abs=1e-9), name


@pytest.mark.parametrize("fid,data", CIA402[1:] + PACKED + FD,
                         ids=lambda v: hex(v) if isinstance(v, int) else None)
def test_encode_golden(db, fid, data):
    # cantools encoding the physical values gives the same bytes as mlip
    assert db.encode_message(fid, expected_signals(fid)) == bytes.fromhex(data)


def test_scaling_one_count(db):
    # one count is 0.001 mm, both signs; int32 limits decode to the ends
    m = db.get_message_by_frame_id(0x201)
    assert m.decode(bytes.fromhex("0f0001000000"))["X_target"] == pytest.approx(0.001, abs=1e-12)
    assert m.decode(bytes.fromhex("0f00ffffffff"))["X_target"] == pytest.approx(-0.001, abs=1e-12)
    assert m.decode(bytes.fromhex("0f00ffffff7f"))["X_target"] == pytest.approx(2147483.647,
                                                                                 abs=1e-6)
    sig = m.get_signal_by_name("X_target")
    assert sig.unit == "mm" and sig.is_signed and sig.length == 32
    assert sig.byte_order == "little_endian"
    assert db.get_message_by_frame_id(0x204).get_signal_by_name("A_target").unit == "deg"


def test_deployment_frames_are_the_cia_ids(db):
    """Every node's RPDO1/TPDO1/EMCY/heartbeat at the CiA 301 pre-defined
    connection set ids (0x200/0x180/0x080/0x700 + node), sent by the right
    side (MLIP or DRIVEn); the RPDO's controlword is 16 bits before the target."""
    for n in range(1, 7):
        for base, name, sender in ((0x200, "RPDO_NODE", "MLIP"), (0x180, "TPDO_NODE", f"DRIVE{n}"),
                                   (0x080, "EMCY_NODE", f"DRIVE{n}"),
                                   (0x700, "HEARTBEAT_NODE", f"DRIVE{n}")):
            m = db.get_message_by_frame_id(base + n)
            assert m.name == f"{name}{n}" and m.senders == [sender], (hex(base + n), m.senders)
        cw = db.get_message_by_frame_id(0x200 + n).get_signal_by_name("controlword")
        assert (cw.start, cw.length, cw.is_signed) == (0, 16, False)
        sw = db.get_message_by_frame_id(0x180 + n).get_signal_by_name("statusword")
        assert (sw.start, sw.length, sw.is_signed) == (0, 16, False)
    assert db.get_message_by_frame_id(0x000).name == "NMT"
