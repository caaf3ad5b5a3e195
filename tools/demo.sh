#!/bin/bash
# The main job, end to end, for a newcomer:
#
#   tools/demo.sh [--profile cia402|packed|fd] [--force-vm] [--only bus|drives] [PROGRAM.ngc]
#
#   1. builds everything (make);
#   2. brings up vcan0: on this machine when its kernel has CAN, else in a QEMU
#      VM (tools/vcan/run.sh: 12-25 s to boot, software emulation);
#   3. there: the listener (mlip-listen) on vcan0, then the controller
#      (build/mlip-rt, config/mill-3axis.ini), then build/mlip-feed with
#      examples/demo.ngc (our own: a rose engraved in micro-segments on a wavy
#      surface, and a helix; 1819 blocks, 6.5 s), then a controlled stop;
#   4. prints what happened: machining time, blocks, frames and cycles on the
#      bus, and the checks: every frame sent was received, the decoded
#      positions equal the simulator's (mlip-sim) to the last drive count,
#      mlip-check's physics (acceleration, speed, contour) on them;
#   then the drives stage, in the same place (mlipcan.demo_drives):
#      three simulated CiA 402 drives (mlip-drive-sim, the canopen
#      package) powered up away from HOME, one in fault, and a spindle drive
#      in profile velocity mode ([SPINDLE] TYPE = cia402, node 4: the program's
#      M3 waits for it at speed, the start-to-feed wait printed) and a CiA 401
#      I/O module (node 10: M8/M9 flood coolant); mlip-rt --drives
#      (config/mill-3axis-drives.ini at a 40 ms period) brings them up, runs a
#      short program (T1 M6, the operator resuming through mlip-ctl, G43 H1 from
#      examples/tool.tbl, M3, M8 ... G49, M9), shuts them down; prints the tool
#      change, the module's output bits and Z with the tool's length as the
#      devices saw them, each bring-up step as the
#      drives saw it, what they reported, homing with the drives' own homing
#      mode (Z first, then X and Y), the shut-down, and the checks
#      (first target = start position, the drives' targets = mlip-sim's
#      trace in counts, disabled in order, no fault);
#   5. plots the tool speed decoded from the bus against time, the feed limit
#      marked: build/demo-velocity.png;
#   6. the machine's I/O on this host: examples/demo-io.ngc (two tools, the
#      spindle, coolant) on config/mill-3axis-io.ini (manual spindle, tool
#      change at Z100, coolant) with examples/tool.tbl, in mlip-sim: what the
#      operator is told at each pause (the simulated operator resumes at once).
#
# Everything it wrote is in build/demo/ (decoded.csv, demo.json, the listener's
# report can.json, the logs of mlip-rt, mlip-feed and the listener; the drives
# stage's in build/demo/drives/: drives.json, the drives' events.jsonl and
# sync.csv, machine.ini). --only runs one stage (the program is the bus stage's).
# Exit status: 0 when every check passed.
set -u
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT" || exit 1

profile=cia402
runargs=()
program=examples/demo.ngc
only=all
while [ $# -gt 0 ]; do
	case "$1" in
		--profile) profile=${2:?--profile needs cia402, packed or fd}; shift 2 ;;
		--force-vm) runargs+=(--force-vm); shift ;;
		--only) only=${2:?--only needs bus or drives}; shift 2 ;;
		-h|--help) sed -n '2,/^set -u/p' "$0" | sed -e '$d' -e 's/^# \{0,1\}//'; exit 0 ;;
		-*) echo "usage: $0 [--profile cia402|packed|fd] [--force-vm] [--only bus|drives] [PROGRAM.ngc]" >&2; exit 2 ;;
		*) program=$1; shift ;;
	esac
done
case "$profile" in cia402|packed|fd) ;; *) echo "$0: unknown profile $profile" >&2; exit 2 ;; esac
case "$only" in all|bus|drives) ;; *) echo "$0: --only bus or drives, not $only" >&2; exit 2 ;; esac
# the VM sees the repository at the same path: keep the program inside it
program=$(realpath --relative-to="$ROOT" "$program") || exit 2
case "$program" in ../*) echo "$0: $program: put the program inside the repository" >&2; exit 2 ;; esac

say() { printf '\n== %s\n' "$*"; }

say "build (make)"
make -s || exit 1

say "Python packages (.venv: mlipcan, python-can, cantools, canopen; matplotlib for the plot)"
tools/deps.sh --python || exit 1
# The frame layout, read from tools/mlip.dbc with cantools and checked against
# the config, cached in build/: the listener in the VM then skips the import.
.venv/bin/mlip-listen --check-layout --config config/mill-3axis.ini \
	--profile "$profile" >/dev/null || exit 1

say "run on vcan0: listener, mlip-rt, mlip-feed $program; then mlip-rt --drives with simulated drives"
rm -rf build/demo
# One VM boot for both stages; the exit code is the first failing stage's.
bus=".venv/bin/mlip-demo demo --profile $profile \"\${MLIP_VM_OUTDIR:-build}/demo\" $program"
drv="echo; echo '== drives stage: mlip-rt --drives, three simulated CiA 402 drives on vcan0'; .venv/bin/mlip-demo drives \"\${MLIP_VM_OUTDIR:-build}/demo/drives\""
case "$only" in
	bus) cmd=$bus ;;
	drives) cmd=$drv ;;
	*) cmd="$bus; a=\$?; $drv; b=\$?; [ \$a != 0 ] && exit \$a; exit \$b" ;;
esac
err=$(mktemp "${TMPDIR:-/tmp}/mlip-demo.XXXXXX")
# Inside the VM the repository is a throw-away overlay: results go through the
# shared folder $MLIP_VM_OUTDIR, kept (MLIP_VM_KEEP) and copied back below.
t_run=$SECONDS
MLIP_VM_KEEP=1 tools/vcan/run.sh "${runargs[@]}" "$cmd" 2> >(tee "$err" >&2)
rc=$?
sleep 0.2 # let tee finish
kept=$(sed -n 's/^\[vcan\] kept //p' "$err" | tail -n 1)
rm -f "$err"
if [ -n "$kept" ] && [ -d "$kept" ]; then
	[ -d "$kept/demo" ] && cp -r "$kept/demo" build/demo
	rm -rf "$kept"
fi
echo "demo: on vcan0 for $((SECONDS - t_run)) s (VM boot included)"
if [ "$only" != drives ] && [ ! -f build/demo/demo.json ]; then
	echo "demo: no results (exit code $rc)" >&2
	exit 1
fi
if [ "$only" != bus ] && [ ! -f build/demo/drives/drives.json ]; then
	echo "demo: no results of the drives stage (exit code $rc)" >&2
	exit 1
fi
if [ "$only" = drives ]; then
	echo "results: build/demo/drives/ (drives.json, events.jsonl, sync.csv, logs)"
	exit "$rc"
fi

say "plot"
.venv/bin/mlip-demo plot build/demo build/demo-velocity.png || exit 1

say "the machine's I/O: M6, G43, M3, M8 on a manual machine (mlip-sim, the operator resuming at once)"
build/mlip-sim --config config/mill-3axis-io.ini --tools examples/tool.tbl examples/demo-io.ngc ||
	exit 1
echo "results: build/demo/ (decoded.csv, demo.json, can.json, logs; drives/), plot: build/demo-velocity.png"
exit "$rc"
