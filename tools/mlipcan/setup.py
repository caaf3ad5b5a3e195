"""The machine INI as the CAN tools need it: axes, CAN nodes, counts per
unit, period, the [CAN] ids and profile, [DRIVES]: read by mlip-config
--json (the C reader), never parsed here. Standard library only (the
emulated test VM pays for every import)."""
import json
import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def mlip_config_tool():
    """build/mlip-config of this repo, or of $MLIP_BUILD (relative to the repo)."""
    return ROOT / os.environ.get("MLIP_BUILD", "build") / "mlip-config"


class UsageError(Exception):
    pass


def read_config(path):
    """mlip-config --json FILE as a dict; its own error message otherwise."""
    tool = mlip_config_tool()
    try:
        p = subprocess.run([str(tool), "--json", str(path)], capture_output=True, text=True)
    except OSError as e:
        raise UsageError(f"{tool}: {e.strerror} (the C tools read the config: run make)")
    if p.returncode != 0:
        raise UsageError(p.stderr.strip() or f"{tool} failed ({p.returncode})")
    try:
        return json.loads(p.stdout)
    except ValueError as e:
        raise UsageError(f"{tool} --json {path}: not JSON: {e}")


class Setup:
    """What the listener needs of the machine: axes, nodes, counts, ids."""

    def __init__(self):
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
        self.drives = False      # [DRIVES] ENABLE: CiA 402 bring-up, 6-byte RPDOs
        self.master_node = 127   # [DRIVES] MASTER_NODE (heartbeat 0x700 + it)
        self.source = "defaults (X Y Z, nodes 1..3, 1000 counts/unit)"

    @classmethod
    def from_ini(cls, path):
        """The machine as the C reader parsed it (mlip-config --json): one INI
        reader for every tool, so an invalid file gets its file:line:col error."""
        c = read_config(path)
        m, can = c["machine"], c["can"]
        s = cls()
        s.axes = [a["letter"] for a in m["axes"]]
        s.nodes = [a["can_node"] for a in m["axes"]]
        s.cpu = [a["counts_per_unit"] for a in m["axes"]]
        s.period_s = m["period"]
        s.profile = can["profile"]
        for key in ("bitrate", "data_bitrate", "sync_id", "rpdo_base", "packed_base", "fd_id",
                    "status_id"):
            setattr(s, key, can[key])
        s.drives = c["drives"]["enable"]
        s.master_node = c["drives"]["master_node"]
        s.source = str(path)
        return s
