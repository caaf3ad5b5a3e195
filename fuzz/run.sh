#!/bin/sh
# fuzz/run.sh [SECONDS] - build and run the two libFuzzer targets under ASan
# and UBSan, SECONDS each (default 60; 0 only replays the corpus once).
#
#   fuzz_gcode   the G-code front end (src/gcode/) and tools/lib/program.c (with
#                the rest of tools/lib/, whatever program.c comes to need)
#   fuzz_config  the machine configuration reader (src/machine/)
#
# Both targets are built from whole folders (the core's, Makefile LAYERS, and
# tools/lib/), so a file added to one of them is in, and a new dependency of
# program.c does not break the build.
#
# Installs clang and its runtimes (libclang-rt-14-dev) with apt-get when
# missing. Output in build/fuzz/ (override with FUZZ_OUT): the binaries, the
# corpora corpus-gcode/ and corpus-config/ (seeded from the toolpaths in
# $MLIP_SHARED/toolpaths, default ../shared/toolpaths, config/*.ini and
# fuzz/regress/; kept between runs, so a local corpus grows), the logs, and
# crash/leak/timeout/oom artifacts in artifacts/. Exits non-zero when a
# target finds anything: reproduce with build/fuzz/fuzz_gcode ARTIFACT, then
# add the input to fuzz/regress/ and its outcome to
# tests/unit/test_fuzz_regress.c.
#
# Environment: CC (default clang), FUZZ_OUT, FUZZ_ARGS (extra libFuzzer
# options), MLIP_SHARED.
set -eu
cd "$(dirname "$0")/.."

T=${1:-60}
case $T in
'' | *[!0-9]*) echo "usage: fuzz/run.sh [SECONDS]" >&2; exit 2 ;;
esac
OUT=${FUZZ_OUT:-build/fuzz}
CC=${CC:-clang}
case $CC in cc | gcc*) CC=clang ;; esac # make passes CC=cc: libFuzzer needs clang
SAN="-fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined"
CFLAGS="-std=c99 -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE -g -O1 -fno-omit-frame-pointer
        -Wall -Wextra -Wpedantic -Wshadow -Wstrict-prototypes -Wmissing-prototypes
        -Wno-unused-function -Iinclude -Itools/lib -Ifuzz"
SHARED=${MLIP_SHARED:-../shared}
start=$(date +%s)
mkdir -p "$OUT/artifacts"
ROOT=$(pwd)
ABS=$(cd "$OUT" && pwd)

# ---- a compiler that links libFuzzer, ASan and UBSan ------------------------
probe() {
	printf '%s\n' '#include <stddef.h>' '#include <stdint.h>' \
		'int LLVMFuzzerTestOneInput(const uint8_t *d, size_t n);' \
		'int LLVMFuzzerTestOneInput(const uint8_t *d, size_t n) { (void)d; return (int)n * 0; }' \
		>"$OUT/probe.c"
	command -v "$CC" >/dev/null 2>&1 &&
		$CC $SAN -o "$OUT/probe" "$OUT/probe.c" >"$OUT/probe.log" 2>&1
}
if ! probe; then
	echo "fuzz: $CC cannot build a libFuzzer target: apt-get install clang libclang-rt-14-dev"
	SUDO=""
	[ "$(id -u)" = 0 ] || SUDO=sudo
	export DEBIAN_FRONTEND=noninteractive
	$SUDO apt-get update -qq
	$SUDO apt-get install -y -qq clang libclang-rt-14-dev >"$OUT/apt.log" 2>&1 ||
		{ cat "$OUT/apt.log" >&2; exit 1; }
	if ! probe; then
		cat "$OUT/probe.log" >&2
		echo "fuzz: $CC still cannot build a libFuzzer target" >&2
		exit 1
	fi
fi

# ---- the targets ------------------------------------------------------------
echo "fuzz: building with $($CC --version | head -n 1)"
# shellcheck disable=SC2086 # word splitting of the flag lists is intended
# the core by its folders (Makefile LAYERS) and the host library, whatever
# the readers and program.c come to need
srcs=""
for d in $(sed -n 's/^LAYERS *:= *//p' Makefile); do
	for f in src/"$d"/*.c; do
		[ -e "$f" ] && srcs="$srcs $f" # a folder of headers only has none
	done
done
# shellcheck disable=SC2086
$CC $CFLAGS $SAN -o "$OUT/fuzz_gcode" fuzz/fuzz_gcode.c $srcs tools/lib/*.c -lm -lpthread
# shellcheck disable=SC2086
$CC $CFLAGS $SAN -o "$OUT/fuzz_config" fuzz/fuzz_config.c $srcs -lm

# ---- seeds --------------------------------------------------------------------
if [ ! -d "$SHARED/toolpaths" ]; then
	echo "fuzz: warning: $SHARED/toolpaths not found (set MLIP_SHARED): G-code seeds" \
		"from examples/ and fuzz/regress/ only"
fi
python3 fuzz/seeds.py "$SHARED/toolpaths" "$OUT/corpus-gcode" "$OUT/corpus-config"

# ---- runs -------------------------------------------------------------------------
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0:symbolize=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
status=0
summary=""
for t in gcode config; do
	log="$OUT/fuzz_$t.log"
	before=$(ls "$OUT/artifacts" | grep -c "^$t-" || true)
	if [ "$T" = 0 ]; then
		limit="-runs=0"
	else
		limit="-max_total_time=$T"
	fi
	echo "fuzz: fuzz_$t for ${T}s (log: $log)"
	rc=0
	# -jobs=1 runs the target in a worker process whose output goes to
	# fuzz-0.log in the current directory (the parent then prints it): run
	# from $OUT so that the file lands there
	# shellcheck disable=SC2086
	(cd "$OUT" && exec "$ABS/fuzz_$t" $limit -max_len=8192 -timeout=10 -rss_limit_mb=2048 \
		-jobs=1 -workers=1 -print_final_stats=1 -dict="$ROOT/fuzz/$t.dict" \
		-artifact_prefix="$ABS/artifacts/$t-" ${FUZZ_ARGS:-} "$ABS/corpus-$t") \
		>"$log" 2>&1 || rc=$?
	rm -f "$OUT/fuzz-0.log"
	after=$(ls "$OUT/artifacts" | grep -c "^$t-" || true)
	found=$((after - before))
	execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
	speed=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -n 1)
	cov=$(grep -o 'cov: [0-9]* ft: [0-9]*' "$log" | tail -n 1)
	corp=$(ls "$OUT/corpus-$t" | wc -l)
	line="fuzz_$t: ${execs:-?} execs (${speed:-?}/s), ${cov:-cov: ?}, corpus $corp"
	line="$line, new artifacts $found"
	bad='invariant violated\|runtime error:\|^==[0-9]*==ERROR'
	if [ "$rc" != 0 ] || [ "$found" -gt 0 ] || grep -q "$bad" "$log"; then
		status=1
		line="$line, FAILED (exit $rc)"
		grep -m 6 "$bad\\|Test unit written" "$log" || true
	fi
	summary="$summary$line
"
done

echo "fuzz: summary after $(($(date +%s) - start)) s"
printf '%s' "$summary"
if [ "$status" != 0 ]; then
	echo "fuzz: FAILED: artifacts in $OUT/artifacts; reproduce with $OUT/fuzz_<target> FILE" >&2
fi
exit $status
