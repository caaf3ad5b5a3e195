#!/bin/sh
# Install what the build and the tests need, only when it is missing:
# Debian packages with apt-get, Python packages into .venv. The first step of
# make test, demo, run and bench (their `deps` prerequisite).
set -e
cd "$(dirname "$0")/.."

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
[ -x /usr/bin/time ] || need="$need time" # GNU time: peak RSS of a program (bench/rss.py)
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

if [ ! -x .venv/bin/python ]; then
	echo "deps: creating .venv"
	python3 -m venv .venv
fi
if ! .venv/bin/python -c 'import pytest, numpy, cantools, matplotlib, canopen, can, serial, svgelements, shxparser' >/dev/null 2>&1; then
	echo "deps: pip install -r tests/requirements.txt"
	.venv/bin/pip install -q -r tests/requirements.txt
fi
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
