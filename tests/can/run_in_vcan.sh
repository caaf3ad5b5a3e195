#!/bin/bash
# Guest side of tools/vcan/run.sh: runs inside the virtme-ng VM, as root, with the
# repo root as working directory and the host file system visible (read-only, the
# repo itself behind a throw-away overlay).
#
#   tests/can/run_in_vcan.sh OUTDIR
#
# OUTDIR is the --rwdir shared with the host.  Reads OUTDIR/cmd (the shell command
# line) and OUTDIR/env (exports from the host), brings up vcan0, runs the command
# and writes its output to OUTDIR/log (the host streams it) and its exit code to
# OUTDIR/rc.  Not meant to be run by hand.
out=${1:?usage: run_in_vcan.sh OUTDIR}
exec >>"$out/log" 2>&1 </dev/null

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
cd "$ROOT" || exit 1

finish() {
	echo "$1" >"$out/rc.tmp" && mv -f "$out/rc.tmp" "$out/rc"
	sync
	exit "$1"
}

read -r up _ </proc/uptime
echo "[vm] $(uname -r) up after ${up}s (guest clock)"

# vcan0, CAN FD capable.  modprobe finds the modules of the unpacked Debian kernel
# (vng links them at /lib/modules/$(uname -r)).
modprobe vcan 2>/dev/null
modprobe can-raw 2>/dev/null
if ! ip link show dev vcan0 >/dev/null 2>&1; then
	ip link add dev vcan0 type vcan || { echo "[vm] cannot create vcan0"; finish 125; }
fi
ip link set dev vcan0 down
ip link set dev vcan0 mtu 72 || echo "[vm] warning: vcan0 mtu 72 (CAN FD) failed"
ip link set dev vcan0 up || { echo "[vm] cannot bring vcan0 up"; finish 125; }

# Environment for CMD: host's MLIP_*/CI/PYTEST_* variables, the venv first on PATH.
[ -f "$out/env" ] && . "$out/env"
export MLIP_IN_VM=1
export MLIP_VM_OUTDIR="$out"          # files written here come back to the host
export VIRTUAL_ENV="$ROOT/.venv"
export PATH="$ROOT/.venv/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"
export PYTHONDONTWRITEBYTECODE=1
export HOME=/tmp/mlip-home TMPDIR=/tmp
mkdir -p "$HOME"

bash -c "$(cat "$out/cmd")"
finish $?
