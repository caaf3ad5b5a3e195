#!/bin/sh
# Install what the build and the tests need, only when it is missing:
# Debian packages with apt-get, Python packages into .venv, and the project's
# own Python package (python/mlipcan) into .venv from this checkout (pip
# install -e .). The first step of make test, demo, run and bench (their
# `deps` prerequisite).
#
#   tools/deps.sh            everything
#   tools/deps.sh --python   the Python part only (.venv, its packages, mlipcan)
set -e
cd "$(dirname "$0")/.."
ROOT=$(pwd)

python_part() {
	if [ ! -x .venv/bin/python ]; then
		echo "deps: creating .venv"
		python3 -m venv .venv
	fi
	# one pip at a time in a .venv (two make runs, or trees sharing it)
	exec 9>.venv/.deps.lock
	flock 9
	if ! .venv/bin/python -c 'import pytest, numpy, cantools, matplotlib, canopen, can, mypy, serial, svgelements, shxparser' \
		>/dev/null 2>&1 || [ ! -x .venv/bin/ruff ]; then
		echo "deps: pip install -r tests/requirements.txt"
		.venv/bin/pip install -q -r tests/requirements.txt
	fi
	# mlipcan, editable, from this checkout: the tests import it, the
	# console scripts (mlip-listen, mlip-drive-sim, mlip-demo) run it
	where=$(cd / && "$ROOT/.venv/bin/python" -c \
		'import mlipcan, os; print(os.path.dirname(os.path.realpath(mlipcan.__file__)))' \
		2>/dev/null || true)
	if [ "$where" != "$ROOT/python/mlipcan" ] || [ ! -x .venv/bin/mlip-listen ]; then
		echo "deps: pip install -e . (mlipcan from $ROOT${where:+, was $where})"
		.venv/bin/pip install -q --no-deps -e .
	fi
	exec 9>&-
}

if [ "${1:-}" = --python ]; then
	python3 -c 'import venv, ensurepip' >/dev/null 2>&1 || exec "$0"
	python_part
	exit 0
fi

need=""
# the build itself (make demo, run, bench and test all start here): a C
# compiler with its ThreadSanitizer runtime (make tsan), nm (make purity)
command -v cc >/dev/null 2>&1 || need="$need build-essential"
command -v nm >/dev/null 2>&1 || need="$need binutils"
command -v clang-format >/dev/null 2>&1 || need="$need clang-format" # make format-check
[ -f /usr/include/cmocka.h ] || need="$need libcmocka-dev"
[ -f /usr/include/libsocketcan.h ] || need="$need libsocketcan-dev"
command -v valgrind >/dev/null 2>&1 || need="$need valgrind"
command -v cyclictest >/dev/null 2>&1 || need="$need rt-tests"
command -v candump >/dev/null 2>&1 || need="$need can-utils"
command -v flock >/dev/null 2>&1 || need="$need util-linux"
[ -x /usr/bin/time ] || need="$need time" # GNU time: peak RSS of a program (bench/rss.py)
command -v strace >/dev/null 2>&1 || need="$need strace" # the state files' fsync order (tests)
# CNCjs, a real sender, and its page in a real browser (tests/py/test_senders.py)
command -v npm >/dev/null 2>&1 || need="$need nodejs npm"
[ -x /usr/bin/chromium ] || need="$need chromium chromium-driver"
python3 -c 'import venv, ensurepip' >/dev/null 2>&1 || need="$need python3-venv"
if [ -n "$need" ]; then
	echo "deps: apt-get install$need"
	SUDO=""; [ "$(id -u)" = 0 ] || SUDO=sudo
	$SUDO apt-get update -qq
	DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $need >/dev/null
fi

python_part

# CNCjs (npm, tests/cncjs/package-lock.json): its server, Grbl controller and page
if [ ! -f tests/cncjs/node_modules/cncjs/package.json ] ||
	[ ! -f tests/cncjs/node_modules/playwright-core/package.json ]; then
	echo "deps: npm ci (tests/cncjs)"
	(cd tests/cncjs && npm ci --no-audit --no-fund --loglevel=error >/dev/null)
fi
# bCNC, a real G-code sender for the Grbl front-end's tests (tests/py/test_senders.py):
# its Sender and GRBL1 controller only, so not its camera's opencv (--no-deps; what
# it imports is in tests/requirements.txt); tkinter comes with Python
if ! .venv/bin/python -c 'import bCNC' >/dev/null 2>&1; then
	echo "deps: pip install --no-deps bCNC==0.9.16"
	.venv/bin/pip install -q --no-deps bCNC==0.9.16
fi
