"""Where things are and how the end-to-end runs behave: one Settings value,
made by an entry point (a command line, the tests' conftest) and passed to
whatever needs it. Nothing in the package reads the environment on import."""

import os
from collections.abc import Mapping
from pathlib import Path


def source_root() -> Path:
    """The repository this package runs from (an editable install keeps it in
    python/mlipcan of the checkout), else the current directory."""
    here = Path(__file__).resolve().parents[2]
    return here if (here / "tools" / "mlip.dbc").is_file() else Path.cwd()


class Settings:
    """root: the repository (config/, examples/, tools/mlip.dbc); build: the C
    tools (mlip-rt, mlip-sim, mlip-config, ...) and caches; shared: the shared
    toolpaths' parent; iface: the CAN interface of the end-to-end runs; in_vm:
    inside the software-emulated test VM (every Python import costs seconds
    there: the listener and drive simulator read the bus with recvmmsg);
    start_timeout: generous waits for a process to come up (s); exec_listener:
    start the listener as its own interpreter instead of a fork; keep_log:
    the listener also writes a candump log of each run. (A plain class, not
    a dataclass: importing dataclasses costs about a second in the VM.)"""

    def __init__(
        self,
        root: Path,
        build: Path,
        shared: Path,
        iface: str = "vcan0",
        in_vm: bool = False,
        start_timeout: float = 240.0,
        exec_listener: bool = False,
        keep_log: bool = False,
    ) -> None:
        self.root = root
        self.build = build
        self.shared = shared
        self.iface = iface
        self.in_vm = in_vm
        self.start_timeout = start_timeout
        self.exec_listener = exec_listener
        self.keep_log = keep_log

    def __repr__(self) -> str:
        return f"Settings({', '.join(f'{k}={v!r}' for k, v in vars(self).items())})"

    @classmethod
    def from_environ(
        cls, root: Path | None = None, environ: Mapping[str, str] | None = None
    ) -> "Settings":
        """The settings the environment gives (MLIP_BUILD, relative to root;
        MLIP_SHARED; MLIP_VCAN_IFACE; MLIP_IN_VM=1; MLIP_CAN_START_TIMEOUT;
        MLIP_CAN_LISTEN_EXEC=1; MLIP_CAN_LOG=1), read when called."""
        env = os.environ if environ is None else environ
        r = source_root() if root is None else root
        return cls(
            root=r,
            build=r / env.get("MLIP_BUILD", "build"),
            shared=Path(env.get("MLIP_SHARED", str(r.parent / "shared"))),
            iface=env.get("MLIP_VCAN_IFACE", "vcan0"),
            in_vm=env.get("MLIP_IN_VM") == "1",
            start_timeout=float(env.get("MLIP_CAN_START_TIMEOUT", "240")),
            exec_listener=env.get("MLIP_CAN_LISTEN_EXEC") == "1",
            keep_log=env.get("MLIP_CAN_LOG") == "1",
        )

    def tool(self, name: str) -> str:
        """A C tool of the build, e.g. tool("mlip-rt")."""
        return str(self.build / name)

    @property
    def config_dir(self) -> Path:
        return self.root / "config"

    @property
    def toolpaths(self) -> Path:
        return self.shared / "toolpaths"

    @property
    def dbc(self) -> Path:
        """The frame layouts of every profile (cantools reads it)."""
        return self.root / "tools" / "mlip.dbc"
