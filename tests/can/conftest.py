"""Fixtures of the bus tests (tests/can): vcan0 must be there and up, and
CAN FD capable for the fd profile. They fail, never skip: a green run means
the SocketCAN path really was exercised."""
import os
import sys
from pathlib import Path

import pytest

# the tool-side harness and CAN code (tools/mlipcan): tests import tools, not
# the other way round
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))
import mlipcan.harness as h  # noqa: E402

IFACE = h.IFACE
SYS = Path("/sys/class/net") / IFACE
ARPHRD_CAN = 280
CANFD_MTU = 72


@pytest.fixture(scope="session")
def vcan():
    """vcan0 must exist, be a CAN interface and be up: fail, never skip."""
    if not SYS.is_dir():
        pytest.fail(f"no {IFACE}: run through tools/vcan/run.sh (these tests never skip)")
    assert int((SYS / "type").read_text()) == ARPHRD_CAN, f"{IFACE} is not a CAN interface"
    assert int((SYS / "flags").read_text(), 16) & 0x1, f"{IFACE} is down"
    for t in ("mlip-rt", "mlip-feed", "mlip-ctl", "mlip-sim", "mlip-check"):
        if not Path(h.tool(t)).exists():
            pytest.fail(f"{h.tool(t)} missing: run make first")
    if not h.TOOLPATHS.is_dir():
        pytest.fail(f"{h.TOOLPATHS} missing: set MLIP_SHARED")
    h.prime_dbc_cache()  # listener processes then skip the cantools import
    return IFACE


@pytest.fixture(scope="session")
def fd_mtu(vcan):
    mtu = int((SYS / "mtu").read_text())
    if mtu != CANFD_MTU:
        # tools/vcan/run.sh sets mtu 72; a host vcan0 made by hand may not have it
        os.system(f"ip link set {IFACE} down && ip link set {IFACE} mtu 72 && "
                  f"ip link set {IFACE} up")
        mtu = int((SYS / "mtu").read_text())
    assert mtu == CANFD_MTU, f"{IFACE} mtu {mtu}: the fd profile needs 'ip link set {IFACE} mtu 72'"
    return mtu
