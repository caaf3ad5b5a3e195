#!/usr/bin/env python3
"""mlip-listen - watch the setpoint frames mlip-rt puts on a CAN bus (and,
with CiA 402 drives, what the drives answer).

The command line of tools/mlipcan/listen.py (its docstring and --help tell
the options, outputs and the two receive paths: python-can, and the fast
recvmmsg path of the emulated test VM)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from mlipcan.listen import main  # noqa: E402  (tools/mlipcan/: bus, setup, layout, decoders, sources, report)

if __name__ == "__main__":
    sys.exit(main())
