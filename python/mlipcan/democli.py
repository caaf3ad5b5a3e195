"""mlip-demo - the CAN demo's driver (tools/demo.sh): run mlip-rt, the
listener and mlip-feed on vcan0 and check what happened, or plot it.

    mlip-demo demo OUTDIR [--config INI] [--profile P] [PROGRAM]
    mlip-demo drives OUTDIR [--config INI] [--period S] [PROGRAM]
                       (mlip-rt --drives with simulated CiA 402 drives)
    mlip-demo plot OUTDIR PNG
    mlip-demo prime    (read the DBC into the layout cache in build/)

Where things are (the build, the CAN interface, the VM) comes from the
environment, as Settings.from_environ reads it; inside the test VM,
MLIP_VM_OUTDIR is the shared folder tools/demo.sh copies back."""

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from .settings import Settings


def main(argv: Sequence[str] | None = None) -> int:
    s = Settings.from_environ()
    ap = argparse.ArgumentParser(
        prog="mlip-demo", description="the CAN demo: run it, or plot its result"
    )
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("demo", help="the bus stage: mlip-rt, the listener, mlip-feed")
    d.add_argument("outdir")
    d.add_argument("--config", default=str(s.config_dir / "mill-3axis.ini"))
    d.add_argument("--profile", default="cia402", choices=["cia402", "packed", "fd"])
    d.add_argument("program", nargs="?", default=str(s.root / "examples" / "demo.ngc"))
    dr = sub.add_parser("drives", help="the drives stage: mlip-rt --drives with simulated drives")
    dr.add_argument("outdir")
    dr.add_argument("--config", default=str(s.config_dir / "mill-3axis-drives.ini"))
    dr.add_argument("--period", type=float, default=None, help="s (default 0.04)")
    dr.add_argument("program", nargs="?", help="default: a small program of its own")
    p = sub.add_parser("plot", help="the tool speed decoded from the bus, as a PNG")
    p.add_argument("outdir")
    p.add_argument("png")
    sub.add_parser("prime", help="read the DBC into the layout cache (build/)")
    a = ap.parse_args(argv)
    if a.cmd == "demo":
        from .demo import demo

        return 1 if demo(s, a.outdir, Path(a.config), Path(a.program), a.profile) else 0
    if a.cmd == "drives":
        from . import demo_drives

        period = demo_drives.PERIOD_S if a.period is None else a.period
        failed = demo_drives.run(
            s,
            a.outdir,
            Path(a.config),
            a.program and Path(a.program),
            period_s=period,
            vm_out=os.environ.get("MLIP_VM_OUTDIR"),
        )
        return 1 if failed else 0
    if a.cmd == "plot":
        from .plot import plot

        plot(a.outdir, a.png)
        return 0
    from .layout import prime_cache

    print(prime_cache(s.dbc, s.build))
    return 0


if __name__ == "__main__":
    sys.exit(main())
