#!/bin/sh
# Idempotent installer for the vcan test environment.
#
#   tools/vcan/setup.sh          Python test deps + everything the VM path needs
#   tools/vcan/setup.sh --python only the Python test deps (python-can, cantools, pytest)
#
# Python deps go into the repo's .venv (created if missing; tools/deps.sh adds its
# own packages to the same venv).  The VM pieces are:
#   - Debian packages: qemu-system-x86 (QEMU), busybox-static (vng's initramfs),
#     kmod (depmod on the host, modprobe in the guest, which runs the host's
#     userland), iproute2 (ip, in the guest);
#   - virtme-ng (the `vng` runner) from PyPI, into .venv;
#   - a stock Debian kernel (the one `linux-image-amd64` depends on), unpacked with
#     dpkg -x into $MLIP_VM_DIR/kernel (default build/vm/kernel), depmod'ed, and
#     checked for vcan.ko.
# Nothing is done when everything is already there (a few checks, well under 1 s).
# Works as root (CI) or as a user with sudo; needs no TTY.
set -eu

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
cd "$ROOT"

VM_DIR=${MLIP_VM_DIR:-$ROOT/build/vm}
KDIR=$VM_DIR/kernel
VENV=$ROOT/.venv
VNG_REQ='virtme-ng==1.42'
REQ=$ROOT/tests/can/requirements.txt

mode=all
case "${1:-}" in
	--python) mode=python ;;
	"") ;;
	*) echo "usage: $0 [--python]" >&2; exit 2 ;;
esac

log() { echo "vcan-setup: $*" >&2; }
SUDO=""
[ "$(id -u)" = 0 ] || SUDO="sudo -n"
export DEBIAN_FRONTEND=noninteractive

APT_UPDATED=""
apt_update() {
	[ -n "$APT_UPDATED" ] && return 0
	log "apt-get update"
	$SUDO apt-get update -qq >&2
	APT_UPDATED=1
}

# One setup at a time (two run.sh started together must not pip-install into
# the same venv at once).
mkdir -p "$VM_DIR"
if command -v flock >/dev/null 2>&1 && [ -z "${MLIP_VCAN_SETUP_LOCKED:-}" ]; then
	export MLIP_VCAN_SETUP_LOCKED=1
	exec flock "$VM_DIR/.setup.lock" "$0" "$@"
fi

# ---------------------------------------------------------------- Debian packages
need=""
python3 -c 'import venv, ensurepip' >/dev/null 2>&1 || need="$need python3-venv"
if [ "$mode" = all ]; then
	command -v qemu-system-x86_64 >/dev/null 2>&1 || need="$need qemu-system-x86"
	[ -x /bin/busybox ] || [ -x /usr/bin/busybox ] || need="$need busybox-static"
	command -v depmod >/dev/null 2>&1 || [ -x /sbin/depmod ] || [ -x /usr/sbin/depmod ] || need="$need kmod"
	command -v ip >/dev/null 2>&1 || [ -x /sbin/ip ] || [ -x /usr/sbin/ip ] || need="$need iproute2"
fi
if [ -n "$need" ]; then
	apt_update
	log "apt-get install$need"
	# shellcheck disable=SC2086
	$SUDO apt-get install -y -qq --no-install-recommends $need >&2
fi

# ---------------------------------------------------------------- Python (.venv)
if [ ! -x "$VENV/bin/python" ]; then
	log "creating .venv"
	python3 -m venv "$VENV"
fi
have_py() {   # find_spec, not import: a no-op run stays fast
	"$VENV/bin/python" -c 'import sys, importlib.util as u
sys.exit(any(u.find_spec(m) is None for m in sys.argv[1:]))' "$@" >/dev/null 2>&1
}
if ! have_py can cantools pytest canopen; then
	log "pip install -r tests/can/requirements.txt"
	"$VENV/bin/pip" install -q --disable-pip-version-check -r "$REQ" >&2
fi
[ "$mode" = python ] && exit 0

if [ ! -x "$VENV/bin/vng" ] || [ ! -x "$VENV/bin/virtme-run" ] || ! have_py virtme; then
	log "pip install $VNG_REQ"
	"$VENV/bin/pip" install -q --disable-pip-version-check "$VNG_REQ" >&2
fi

# ---------------------------------------------------------------- Debian kernel
# The unpacked tree is kept; its stamp names the package.  A new Debian kernel
# is not fetched while a verified one is cached (remove $KDIR to refresh, or set
# MLIP_VM_KERNEL_PKG=linux-image-...-amd64 to pick one).
# QEMU boots an uncompressed kernel ELF directly (PVH entry), skipping the xz
# decompression that takes ~5 s under software emulation.  Optional: run.sh
# falls back to vmlinuz when boot/vmlinux-* is missing.
extract_vmlinux() {
	"$VENV/bin/python" "$ROOT/tools/vcan/extract_vmlinux.py" "$1" "$2" ||
		log "note: could not uncompress $1 (boots will be ~5 s slower)"
}

if [ -f "$KDIR/.ok" ] && { [ -z "${MLIP_VM_KERNEL_PKG:-}" ] || [ "$(cat "$KDIR/.ok")" = "$MLIP_VM_KERNEL_PKG" ]; }; then
	if ! ls "$KDIR"/boot/vmlinux-* >/dev/null 2>&1; then   # a cache made before vmlinux was kept
		for z in "$KDIR"/boot/vmlinuz-*; do extract_vmlinux "$z" "$KDIR/boot/vmlinux-${z##*/vmlinuz-}"; done
	fi
	exit 0
fi

kernel_pkg() {
	apt-cache depends linux-image-amd64 2>/dev/null |
		sed -n 's/^ *Depends: \(linux-image-[0-9][^ ]*-amd64\)$/\1/p' | head -n 1
}
pkg=${MLIP_VM_KERNEL_PKG:-}
if [ -z "$pkg" ]; then
	pkg=$(kernel_pkg)
	if [ -z "$pkg" ]; then
		apt_update
		pkg=$(kernel_pkg)
	fi
	[ -n "$pkg" ] || { log "cannot tell which kernel linux-image-amd64 depends on"; exit 1; }
fi

tmp=$(mktemp -d "$VM_DIR/kernel.tmp.XXXXXX")
trap 'rm -rf "$tmp"' EXIT INT TERM
log "apt-get download $pkg"
dl() { (cd "$tmp" && apt-get download -q -o APT::Sandbox::User="$(id -un)" "$pkg" >&2); }
if ! dl; then
	# stale package lists (the mirror moved on): refresh once and try again
	APT_UPDATED=""
	apt_update
	if [ -z "${MLIP_VM_KERNEL_PKG:-}" ]; then pkg=$(kernel_pkg); fi
	dl
fi
deb=$(ls "$tmp"/linux-image-*.deb)
log "unpacking $(basename "$deb")"
dpkg -x "$deb" "$tmp/tree"
rm -f "$deb"

vmlinuz=$(ls "$tmp"/tree/boot/vmlinuz-* 2>/dev/null | head -n 1)
[ -n "$vmlinuz" ] || { log "no vmlinuz in $pkg"; exit 1; }
kver=${vmlinuz##*/vmlinuz-}
moddir=$tmp/tree/lib/modules/$kver
# vng would run depmod on first boot; do it now so the cache is complete.
depmod=$(command -v depmod || echo /sbin/depmod)
"$depmod" -a -b "$tmp/tree" "$kver"
for m in vcan can can-raw; do
	if ! find "$moddir/kernel" -name "$m.ko*" | grep -q .; then
		log "$pkg has no $m module"; exit 1
	fi
done
grep -q 'vcan\.ko' "$moddir/modules.dep" || { log "depmod did not index vcan"; exit 1; }

# Also keep the kernel uncompressed (boot/vmlinux-*), see extract_vmlinux.
extract_vmlinux "$vmlinuz" "$tmp/tree/boot/vmlinux-$kver"

echo "$pkg" > "$tmp/tree/.ok"
rm -rf "$KDIR.old"
[ -e "$KDIR" ] && mv "$KDIR" "$KDIR.old"
mv "$tmp/tree" "$KDIR"
rm -rf "$KDIR.old"
log "kernel $kver ready in $KDIR"
