"""tools/mlip.dbc against the frame layouts of include/mlip/canenc.h.

The expected bytes below are written by hand from the documented layout; the
very same vectors are asserted byte for byte against the C encoder in
tests/unit/test_canenc.c (test_golden_*), so DBC and encoder are tied together
through them.
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

CIA402 = [(0x080, "")] + [(0x201 + i, LE[a]) for i, a in enumerate(AXES)]
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
        return {a + "_target": POS[a]}
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
    assert ids == {fid for fid, _ in CIA402 + PACKED + FD}
    for m in db.messages:
        assert not m.is_extended_frame
        assert m.is_fd == (m.frame_id == 0x400)


def test_lengths(db):
    for fid, data in CIA402 + PACKED + FD:
        assert db.get_message_by_frame_id(fid).length == len(bytes.fromhex(data))


@pytest.mark.parametrize("fid,data", CIA402 + PACKED + FD,
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
    assert m.decode(bytes.fromhex("01000000"))["X_target"] == pytest.approx(0.001, abs=1e-12)
    assert m.decode(bytes.fromhex("ffffffff"))["X_target"] == pytest.approx(-0.001, abs=1e-12)
    assert m.decode(bytes.fromhex("ffffff7f"))["X_target"] == pytest.approx(2147483.647, abs=1e-6)
    sig = m.get_signal_by_name("X_target")
    assert sig.unit == "mm" and sig.is_signed and sig.length == 32
    assert sig.byte_order == "little_endian"
    assert db.get_message_by_frame_id(0x204).get_signal_by_name("A_target").unit == "deg"
