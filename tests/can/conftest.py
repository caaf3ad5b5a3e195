"""Fixtures of the bus tests (tests/can): vcan0 must be there and up, and
CAN FD capable for the fd profile. They fail, never skip: a green run means
the SocketCAN path really was exercised."""
import os
from collections.abc import Callable
from pathlib import Path

import pytest

import mlipcan  # the project's Python package (pip install -e . by tools/deps.sh)
from mlipcan import layout, procs
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


# ---- the I/O bus tests' machine (test_io_vcan, test_outputs_vcan): three
# CiA 402 drives (nodes 1..3) and a CiA 401 I/O module (node IO) at 40 ms,
# the timeouts long (the emulated VM)

# CiA 402 drives on the bus, the timeouts long for the emulated VM (the
# drive, homing and I/O tests' [DRIVES] section)
DRIVES_VM = """
[DRIVES]
ENABLE = 1
HEARTBEAT_MS = 100
HEARTBEAT_TIMEOUT_MS = 4000
FOLLOWING_ERROR = 2
SDO_TIMEOUT_MS = 5000
BOOT_TIMEOUT_MS = 8000
STATE_TIMEOUT_MS = 10000
"""
IO = 10
IO_PERIOD_S = 0.04
IO_DRIVES = DRIVES_VM + f"""
[IO]
NODE = {IO}
ESTOP = {IO} 0x6000:1 0 LOW
"""


def drives_machine(tmp: Path, edit: Callable[[str], str] = lambda t: t, tail: str = "",
                   name: str = "drives.ini") -> Path:
    """mill-3axis at 40 ms (contour tolerance 0.5 mm) on CiA 402 drives
    (nodes 1..3, DRIVES_VM); edit(text) changes the axes, tail adds
    sections after [DRIVES]."""
    text = (S.config_dir / "mill-3axis.ini").read_text()
    text = text.replace("PERIOD = 0.001", f"PERIOD = {IO_PERIOD_S}")
    text = text.replace("CONTOUR_TOLERANCE = 0.01", "CONTOUR_TOLERANCE = 0.5")
    path = tmp / name
    path.write_text(edit(text) + DRIVES_VM + tail)
    return path


def io_machine(tmp: Path, tail: str, edit: Callable[[str], str] = lambda t: t) -> Path:
    """drives_machine with IO_DRIVES: the module's E-stop active low (a
    normally closed contact) on input bit 0; edit(text) changes the axes,
    tail adds to [IO] and further sections."""
    return drives_machine(tmp, edit, IO_DRIVES[len(DRIVES_VM):] + tail, "io.ini")


@pytest.fixture(scope="module")
def io_sim(vcan, tmp_path_factory):
    """The drives and the I/O module in one simulator process (canopen
    package), the E-stop circuit closed (input bit 0 = 1) from power-up."""
    s = procs.DriveSimProc(S, tmp_path_factory.mktemp("iosim"), nodes=[1, 2, 3],
                           args=["--io", IO], inject=[f"{IO}:input=1.0=1"])
    yield s
    s.stop()


@pytest.fixture(scope="module")
def drives_sim(vcan, tmp_path_factory):
    """Three simulated CiA 402 drives (nodes 1..3, drives_machine's axes)."""
    s = procs.DriveSimProc(S, tmp_path_factory.mktemp("drives"), nodes=[1, 2, 3])
    yield s
    s.stop()
