#!/bin/bash
# The CAN tests, wherever vcan0 can exist: on this machine when its kernel has
# CAN, else in a QEMU VM (tools/vcan/run.sh). One VM boot for the whole folder.
#
#   tests/can/run-tests.sh [--force-vm] [PYTEST ARGS...]
#     e.g. tests/can/run-tests.sh -k flower   (no test path given: all of tests/can)
#
# Before booting: build (make), the Python packages (tools/deps.sh --python),
# and the listener's frame layout read from tools/mlip.dbc with cantools into
# build/ (cached by the DBC's hash): importing cantools inside the emulated VM
# costs 30-60 s, reading the cache nothing. Exit status: pytest's (124/125:
# the VM timed out / could not start, see tools/vcan/run.sh).
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
cd "$ROOT" || exit 1

vm=()
if [ "${1:-}" = --force-vm ]; then vm=(--force-vm); shift; fi
args=("$@")
# no test path among the arguments: the whole folder
has_path=0
for a in "${args[@]}"; do case "$a" in tests/*|*.py|*::*) has_path=1 ;; esac; done
[ "$has_path" = 1 ] || args+=(tests/can)

make -s || exit 1
tools/deps.sh --python || exit 1
.venv/bin/mlip-listen --check-layout --config config/mill-3axis.ini >/dev/null || exit 1

q=$(printf ' %q' "${args[@]}")
exec tools/vcan/run.sh "${vm[@]}" ".venv/bin/python -m pytest -s -q -p no:cacheprovider -rfE$q"
