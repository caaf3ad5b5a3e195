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
# (Few external commands on purpose: each exec costs ~0.3 s under emulation.)
out=${1:?usage: run_in_vcan.sh OUTDIR}
exec >>"$out/log" 2>&1 </dev/null

finish() {
	echo "$1" >"$out/rc"   # the host reads it once the VM is gone
	exit "$1"
}

ROOT=${BASH_SOURCE[0]%/*}/../..
cd "$ROOT" || finish 125
ROOT=$PWD

read -r up _ </proc/uptime
read -r kver </proc/sys/kernel/osrelease
echo "[vm] $kver up after ${up}s (guest clock)"

# vcan0, CAN FD capable.  modprobe finds the modules of the unpacked Debian kernel
# (vng links them at /lib/modules/$(uname -r)).
modprobe -a vcan can-raw 2>/dev/null
if [ ! -e /sys/class/net/vcan0 ]; then
	ip link add dev vcan0 type vcan || { echo "[vm] cannot create vcan0"; finish 125; }
fi
ip -batch - <<'IP' || { echo "[vm] cannot bring vcan0 up with mtu 72"; finish 125; }
link set dev vcan0 down
link set dev vcan0 mtu 72
link set dev vcan0 up
IP

# Environment for CMD: host's MLIP_*/CI/PYTEST_* variables, the venv first on PATH.
[ -f "$out/env" ] && . "$out/env"
export MLIP_IN_VM=1
export MLIP_VM_OUTDIR="$out"          # files written here come back to the host
export VIRTUAL_ENV="$ROOT/.venv"
export PATH="$ROOT/.venv/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"
export PYTHONDONTWRITEBYTECODE=1
export HOME=/tmp TMPDIR=/tmp

bash -c "$(<"$out/cmd")"
finish $?
