"""The machine INI as the Python side needs it: axes, CAN nodes, counts per
unit, period, the [CAN] ids and profile, [DRIVES], the limits. Read by
mlip-config --json (the C reader, one INI reader for every tool, so an
invalid file gets its file:line:col error), never parsed here. Standard
library only (the emulated test VM pays for every import)."""

import json
import subprocess
from pathlib import Path
from typing import Any

from .settings import Settings

StrPath = str | Path


class UsageError(Exception):
    """A bad command line or input file: the message says which and why."""


def read_config(path: StrPath, build: Path) -> dict[str, Any]:
    """mlip-config --json FILE (the build's) as a dict; its own error otherwise."""
    tool = build / "mlip-config"
    try:
        p = subprocess.run([str(tool), "--json", str(path)], capture_output=True, text=True)
    except OSError as e:
        raise UsageError(f"{tool}: {e.strerror} (the C tools read the config: run make)") from e
    if p.returncode != 0:
        raise UsageError(p.stderr.strip() or f"{tool} failed ({p.returncode})")
    try:
        out: dict[str, Any] = json.loads(p.stdout)
    except ValueError as e:
        raise UsageError(f"{tool} --json {path}: not JSON: {e}") from e
    return out


class Setup:
    """What the CAN tools need of the machine: axes, nodes, counts, ids (the
    defaults: X Y Z on nodes 1..3, 1000 counts per unit, the [CAN] defaults)."""

    def __init__(self) -> None:
        self.axes = list("XYZ")
        self.nodes = [1, 2, 3]
        self.cpu = [1000.0] * 3
        self.period_s = 0.001
        self.profile = "cia402"
        self.bitrate = 1000000
        self.data_bitrate = 5000000
        self.sync_id = 0x080
        self.rpdo_base = 0x200
        self.packed_base = 0x300
        self.fd_id = 0x400
        self.status_id = 0x180
        self.drives = False  # [DRIVES] ENABLE: CiA 402 bring-up, 6-byte RPDOs
        self.master_node = 127  # [DRIVES] MASTER_NODE (heartbeat 0x700 + it)
        self.spindle_node = 0  # [SPINDLE] TYPE = cia402: its drive's node (0: none)
        self.source = "defaults (X Y Z, nodes 1..3, 1000 counts/unit)"

    @classmethod
    def from_ini(cls, path: StrPath, build: Path) -> "Setup":
        """The machine as the C reader parsed it (mlip-config --json of build)."""
        c = read_config(path, build)
        m, can = c["machine"], c["can"]
        st = cls()
        st.axes = [a["letter"] for a in m["axes"]]
        st.nodes = [a["can_node"] for a in m["axes"]]
        st.cpu = [float(a["counts_per_unit"]) for a in m["axes"]]
        st.period_s = float(m["period"])
        st.profile = can["profile"]
        st.bitrate = can["bitrate"]
        st.data_bitrate = can["data_bitrate"]
        st.sync_id = can["sync_id"]
        st.rpdo_base = can["rpdo_base"]
        st.packed_base = can["packed_base"]
        st.fd_id = can["fd_id"]
        st.status_id = can["status_id"]
        st.drives = bool(c["drives"]["enable"])
        st.master_node = c["drives"]["master_node"]
        st.spindle_node = int(c.get("spindle", {}).get("node", 0))
        st.source = str(path)
        return st


def setup_of(s: Settings, path: StrPath) -> Setup:
    """Setup.from_ini with the settings' build."""
    return Setup.from_ini(path, s.build)


class MachineLimits:
    """The [TRAJ]/[AXIS_*] numbers the checks need."""

    def __init__(self, machine: dict[str, Any]) -> None:
        """machine: the "machine" object of mlip-config --json."""
        axes = machine["axes"]
        self.axes: list[str] = [a["letter"] for a in axes]
        self.vmax = float(machine["max_linear_velocity"])
        self.eps = float(machine["contour_tolerance"])
        self.period_s = float(machine["period"])
        self.accel = [float(a["max_acceleration"]) for a in axes]
        self.jerk = [float(a.get("max_jerk", 0.0)) for a in axes]  # 0: no limit
        self.vel = [float(a["max_velocity"]) for a in axes]
        self.home = [float(a["home"]) for a in axes]

    @classmethod
    def of(cls, s: Settings, path: StrPath) -> "MachineLimits":
        """The limits of a machine INI, read by the settings' mlip-config."""
        return cls(read_config(path, s.build)["machine"])
