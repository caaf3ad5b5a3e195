"""Fixtures of the bus tests (tests/can): vcan0 must be there and up, and
CAN FD capable for the fd profile. They fail, never skip: a green run means
the SocketCAN path really was exercised."""
import os
from pathlib import Path

import pytest

import mlipcan  # the project's Python package (pip install -e . by tools/deps.sh)
from mlipcan import layout
from mlipcan.settings import Settings

ROOT = Path(__file__).resolve().parents[2]
if Path(mlipcan.__file__).resolve().parent != ROOT / "python" / "mlipcan":
    pytest.exit(f"mlipcan is imported from {Path(mlipcan.__file__).parent}, not from this "
                f"checkout ({ROOT}): run tools/deps.sh (pip install -e .)", returncode=4)
# where things are and how the runs behave (MLIP_BUILD, MLIP_SHARED,
# MLIP_VCAN_IFACE, MLIP_IN_VM, ...): read once here, passed to the package
S = Settings.from_environ(ROOT)
IFACE = S.iface
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
        if not Path(S.tool(t)).exists():
            pytest.fail(f"{S.tool(t)} missing: run make first")
    if not S.toolpaths.is_dir():
        pytest.fail(f"{S.toolpaths} missing: set MLIP_SHARED")
    layout.prime_cache(S.dbc, S.build)  # listener processes then skip the cantools import
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
