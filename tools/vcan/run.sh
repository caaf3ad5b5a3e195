#!/bin/bash
# Run a command where an UP vcan0 (CAN FD capable, mtu 72) exists.
#
#   tools/vcan/run.sh [--force-vm] CMD...
#
# CMD is one shell command line (several arguments are joined with spaces, as ssh
# does), run by bash from the repo root.  Its output is printed and its exit code
# is run.sh's exit code.
#
#   1. vcan0 is up on the host, or can be made there (modprobe vcan; ip link add
#      dev vcan0 type vcan): CMD runs on the host.
#   2. otherwise (a kernel without CAN) a stock Debian kernel is booted under QEMU
#      with virtme-ng (vng), sharing the host file system; vcan0 is made inside
#      and CMD runs there, as root, with MLIP_IN_VM=1 and .venv/bin first on PATH.
#      Its log and exit code come back through a --rwdir folder; the log is
#      streamed while it runs.
#
# Environment:
#   MLIP_VCAN_FORCE_VM=1   same as --force-vm
#   MLIP_VM_TIMEOUT=3600   seconds before a hung VM is killed (exit code 124): the whole CAN suite in one software-emulated boot takes 15-25 min
#   MLIP_VM_KVM=auto|0|1   use KVM: auto probes it once per host kernel (cached)
#   MLIP_VM_MEMORY=1G      guest memory;  MLIP_VM_CPUS=2 guest CPUs
#   MLIP_VM_VERBOSE=1      show the guest's boot console
#   MLIP_VM_KEEP=1         keep the shared folder (cmd, env, log, rc, vng.out)
#   MLIP_VM_DIR            cache of the kernel and the KVM probe (build/vm)
# Exit codes besides CMD's: 124 VM timed out, 125 VM or vcan setup failed.
set -u

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
cd "$ROOT" || exit 125

force_vm=${MLIP_VCAN_FORCE_VM:-0}
[ "$force_vm" = 1 ] || force_vm=0
while [ $# -gt 0 ]; do
	case "$1" in
		--force-vm) force_vm=1; shift ;;
		--) shift; break ;;
		-h|--help) sed -n '2,/^set -u/p' "$0" | sed -e '$d' -e 's/^# \{0,1\}//'; exit 0 ;;
		*) break ;;
	esac
done
[ $# -gt 0 ] || { echo "usage: $0 [--force-vm] CMD..." >&2; exit 2; }
CMD="$*"

VM_DIR=${MLIP_VM_DIR:-$ROOT/build/vm}
TIMEOUT=${MLIP_VM_TIMEOUT:-3600}
say() { echo "[vcan] $*" >&2; }

SUDO=""
if [ "$(id -u)" != 0 ] && command -v sudo >/dev/null 2>&1; then SUDO="sudo -n"; fi
IP=$(command -v ip || { [ -x /sbin/ip ] && echo /sbin/ip; } || true)
MODPROBE=$(command -v modprobe || { [ -x /sbin/modprobe ] && echo /sbin/modprobe; } || true)

# vcan0 exists, is a CAN device (ARPHRD_CAN = 280) and is up.
vcan0_up() {
	[ -r /sys/class/net/vcan0/flags ] || return 1
	[ "$(cat /sys/class/net/vcan0/type)" = 280 ] || return 1
	[ $(( $(cat /sys/class/net/vcan0/flags) & 1 )) = 1 ]
}

# Make vcan0 exist, with mtu 72 (CAN FD), and up.  Fails harmlessly.
host_vcan() {
	[ -n "$IP" ] || return 1
	if [ -e /sys/class/net/vcan0 ] && [ "$(cat /sys/class/net/vcan0/type)" != 280 ]; then
		say "vcan0 exists but is not a CAN device: ignoring it"
		return 1
	fi
	if [ ! -e /sys/class/net/vcan0 ]; then
		[ -n "$MODPROBE" ] && $SUDO "$MODPROBE" vcan >/dev/null 2>&1
		$SUDO "$IP" link add dev vcan0 type vcan >/dev/null 2>&1 || return 1
	fi
	if [ "$(cat /sys/class/net/vcan0/mtu 2>/dev/null)" != 72 ]; then
		# vcan refuses an MTU change while up
		{ $SUDO "$IP" link set dev vcan0 down && $SUDO "$IP" link set dev vcan0 mtu 72; } >/dev/null 2>&1 ||
			say "warning: could not set vcan0 mtu 72: CAN FD frames will not pass"
	fi
	vcan0_up || $SUDO "$IP" link set dev vcan0 up >/dev/null 2>&1
	vcan0_up
}

run_host() {
	say "vcan0 is up on the host: running there"
	MLIP_IN_VM=0 bash -c "$CMD"
	exit $?
}

# KVM under nested virtualisation can hang the guest at its first instruction
# (seen here: /dev/kvm present, the guest never starts), so try a real boot
# first: the Debian kernel with no root fs panics within ~2 s under KVM.
kvm_usable() {
	local kimg=$1 cache
	case "${MLIP_VM_KVM:-auto}" in
		0|no|off) return 1 ;;
		1|yes|on) return 0 ;;
	esac
	[ -r /dev/kvm ] && [ -w /dev/kvm ] || return 1
	cache="$VM_DIR/kvm-probe.$(uname -r).$(basename "$kimg")"
	if [ ! -f "$cache" ]; then
		local out
		out=$(timeout -k 2 10 qemu-system-x86_64 -machine accel=kvm -cpu host -m 256M \
			-nodefaults -nographic -no-reboot -serial stdio -kernel "$kimg" \
			-append 'console=ttyS0 panic=-1 root=/dev/nonexistent' </dev/null 2>&1)
		if printf '%s' "$out" | grep -q 'Linux version'; then echo 1; else echo 0; fi >"$cache"
		say "KVM probe: $( [ "$(cat "$cache")" = 1 ] && echo works || echo 'does not work, using TCG (software emulation)')"
	fi
	[ "$(cat "$cache")" = 1 ]
}

run_vm() {
	local t0 kimg bootimg outdir vng_pid tail_pid vng_rc rc
	t0=$(date +%s%N)
	"$ROOT/tools/vcan/setup.sh" || { say "setup failed"; exit 125; }
	export PATH="$ROOT/.venv/bin:$PATH"   # vng calls virtme-run by name
	kimg=$(ls "$VM_DIR"/kernel/boot/vmlinuz-* 2>/dev/null | head -n 1)
	[ -n "$kimg" ] || { say "no kernel in $VM_DIR/kernel"; exit 125; }
	# The uncompressed ELF boots ~5 s faster under TCG; vng reads its version
	# with strings(1), so use it only when that is there.
	local elf=${kimg/\/vmlinuz-//vmlinux-}
	if [ -f "$elf" ] && command -v strings >/dev/null 2>&1; then bootimg=$elf; else bootimg=$kimg; fi

	local -a vng=(vng --run "$bootimg" --user root --force-9p --cwd "$ROOT"
		--overlay-rwdir "$ROOT" --memory "${MLIP_VM_MEMORY:-1G}" --cpus "${MLIP_VM_CPUS:-2}")
	if kvm_usable "$kimg"; then accel=KVM; else accel=TCG; vng+=(--disable-kvm); fi
	[ "${MLIP_VM_VERBOSE:-0}" = 1 ] && vng+=(--verbose)

	outdir=$(mktemp -d "${TMPDIR:-/tmp}/mlip-vcan.XXXXXX") || exit 125
	chmod 755 "$outdir"
	printf '%s\n' "$CMD" >"$outdir/cmd"
	# Host variables the command may rely on.
	local name
	: >"$outdir/env"
	for name in $(compgen -e); do
		case "$name" in
			MLIP_IN_VM|MLIP_VM_OUTDIR) ;;
			MLIP_*|CI|PYTEST_*|CC|CFLAGS|BUILD) printf 'export %s=%q\n' "$name" "${!name}" >>"$outdir/env" ;;
		esac
	done
	: >"$outdir/log"
	vng+=(--rwdir "$outdir" --exec "bash tests/can/run_in_vcan.sh $(printf %q "$outdir")")

	say "no vcan on this kernel: booting $(basename "$bootimg") under QEMU ($accel) to run it"
	# timeout runs vng in its own process group and kills all of it (QEMU too).
	timeout -k 15 "$TIMEOUT" "${vng[@]}" </dev/null >"$outdir/vng.out" 2>&1 &
	vng_pid=$!
	# Stream the log; tail ends by itself once vng has gone and the rest is out.
	tail -n +1 -s 0.2 --pid="$vng_pid" -f "$outdir/log" &
	tail_pid=$!
	# Stopped ourselves (Ctrl-C, kill): take the VM down too.  `wait` is
	# interruptible where a foreground command is not.
	trap 'trap - INT TERM HUP; say "interrupted: stopping the VM"; kill -TERM $vng_pid 2>/dev/null;
		wait $vng_pid 2>/dev/null; kill $tail_pid 2>/dev/null; rm -rf "$outdir"; exit 130' INT TERM HUP
	wait "$vng_pid"; vng_rc=$?
	wait "$tail_pid"
	trap - INT TERM HUP

	if [ -f "$outdir/rc" ]; then
		rc=$(cat "$outdir/rc")
	elif [ "$vng_rc" = 124 ] || [ "$vng_rc" = 137 ]; then
		say "VM killed after MLIP_VM_TIMEOUT=${TIMEOUT}s"
		rc=124
	else
		say "the VM stopped before the command finished (vng exit $vng_rc); its output:"
		tail -n 40 "$outdir/vng.out" >&2
		[ "${MLIP_VM_VERBOSE:-0}" = 1 ] || say "(MLIP_VM_VERBOSE=1 shows the guest's boot console)"
		rc=125
	fi
	local ms=$(( ($(date +%s%N) - t0) / 1000000 ))
	say "VM run took $((ms / 1000)).$((ms % 1000 / 100))s, exit code $rc"
	if [ "${MLIP_VM_KEEP:-0}" = 1 ]; then say "kept $outdir"; else rm -rf "$outdir"; fi
	exit "$rc"
}

if [ "$force_vm" = 0 ] && host_vcan; then
	"$ROOT/tools/vcan/setup.sh" --python || exit 125
	run_host
fi
run_vm
