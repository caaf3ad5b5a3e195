#!/usr/bin/env python3
"""The CAN demo's driver (tools/demo.sh): run mlip-rt, the listener and
mlip-feed on vcan0 and check what happened, or plot it.

    mlip-demo.py demo OUTDIR [--config INI] [--profile P] [PROGRAM]
    mlip-demo.py drives OUTDIR [--config INI] [--period S] [PROGRAM]
                                (mlip-rt --drives with simulated CiA 402 drives:
                                 tools/mlipcan/drivedemo.py)
    mlip-demo.py plot OUTDIR PNG
    mlip-demo.py prime          (fill the DBC layout cache)

The work is in tools/mlipcan/harness.py, which the CAN tests use too."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from mlipcan.harness import cli  # noqa: E402

if __name__ == "__main__":
    cli()
