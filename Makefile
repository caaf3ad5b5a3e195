# mlip - one Makefile, output in $(BUILD).
#   make            library, tools, unit tests
#   make demo       the controller on vcan0 (or a VM) with the bundled program
#   make run        the simulator on the bundled demo, all three strategies
#   make test       install missing deps, build, run every test (what CI runs)
#   make purity     the core (libmlip.a) uses libm and pure string functions only
#   make format-check  clang-format on every C file (make test runs it)
#   make pycheck    the Python: ruff format and lint, mypy --strict (make test runs it)
#   make format     rewrite C and Python files as the checks want them
#   make tsan       ThreadSanitizer: the ring's thread tests, controller + feeder threads
#   make can        the CAN tests alone (vcan0 on the host, or in a VM)
#   make bench      Table 1 and Table 2 of the paper, redone
#   make asan|ubsan the unit and system tests under a sanitizer (build-asan/, build-ubsan/)
#   make sanitize   both sanitizers in one build, the unit tests and the system
#                   tests but test_toolpaths (build-san/; what CI runs)
#   make fuzz       the fuzz targets, FUZZ_SECONDS each (default 60)
#   make mutate     each validation rule removed in turn: a test must fail

BUILD   ?= build
CC      ?= cc
OPT     ?= -O2
SAN     ?=
CFLAGS  := -std=c99 -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE $(OPT) -g \
           -Wall -Wextra -Wpedantic -Wshadow -Wstrict-prototypes -Wmissing-prototypes \
           -Wno-unused-function -Werror -MMD -MP $(SAN) $(EXTRA_CFLAGS)
LDFLAGS := $(SAN) $(EXTRA_LDFLAGS)
LDLIBS  := -lm

LIB_SRC   := $(wildcard src/*/*.c)
LIB_OBJ   := $(LIB_SRC:%.c=$(BUILD)/obj/%.o)
HOST_SRC  := $(wildcard tools/lib/*.c)
HOST_OBJ  := $(HOST_SRC:%.c=$(BUILD)/obj/%.o)
RT_SRC    := $(wildcard rt/*.c)
RT_OBJ    := $(RT_SRC:%.c=$(BUILD)/obj/%.o)
TOOL_SRC  := $(wildcard tools/mlip-*.c)
TOOLS     := $(TOOL_SRC:tools/%.c=$(BUILD)/%)
UNIT_SRC  := $(wildcard tests/unit/test_*.c)
UNIT_BINS := $(UNIT_SRC:tests/unit/%.c=$(BUILD)/tests/%)
BENCH_SRC := $(wildcard bench/bench_*.c)
BENCH_BINS:= $(BENCH_SRC:bench/%.c=$(BUILD)/%)

# rt/ needs libsocketcan and threads; only the tools and tests that use rt/
# (those including rt.h) link it: mlip-sim, mlip-check, the benchmarks and
# the pure unit tests build and run without rt/ and libsocketcan.
RT_LIBS   := -lsocketcan -lpthread -lrt
RT_TOOLS  := $(patsubst tools/%.c,$(BUILD)/%,$(shell grep -l '"rt.h"' $(TOOL_SRC) /dev/null))
RT_TESTS  := $(patsubst tests/unit/%.c,$(BUILD)/tests/%,$(shell grep -l '"rt.h"' $(UNIT_SRC) /dev/null))

# Layers: src/ sees include/ only (the pure core), rt/ include/ and itself,
# tools/lib/ include/ and itself; tools and tests see everything.
# Inside the core, src/F/ and include/mlip/F/ are one folder along the data
# path: a folder includes mlip/types.h, its own headers (src/F/NAME.h, its
# private ones, by their bare name) and those of the folders before it in
# LAYERS, nothing else (tools/layers.sh; libmlip.a depends on the check, so
# a forbidden include fails the build). text/ is the readers' lowest layer
# (formatter, number lexer, UTF-8); machine/ reads the [CAN] section that
# can/ defines and checks.
LAYERS    := text gcode can machine motion canopen ipc ctl
CORE_HDR  := $(wildcard include/mlip/*.h include/mlip/*/*.h src/*/*.h)
INC       := -Iinclude -Itools/lib -Irt
$(LIB_OBJ): INC := -Iinclude
$(RT_OBJ): INC := -Iinclude -Irt
$(HOST_OBJ): INC := -Iinclude -Itools/lib

.PHONY: all test unit pytest can bench asan ubsan sanitize fuzz deps clean demo run purity tsan \
        format-check pycheck format mutate
all: $(BUILD)/libmlip.a $(TOOLS) $(UNIT_BINS) $(BENCH_BINS)

$(BUILD)/obj/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) $(INC) -c $< -o $@

$(BUILD)/layers.ok: tools/layers.sh Makefile $(LIB_SRC) $(CORE_HDR)
	@mkdir -p $(dir $@)
	@tools/layers.sh "$(LAYERS)" $(LIB_SRC) $(CORE_HDR)
	@touch $@

$(BUILD)/libmlip.a: $(LIB_OBJ) $(BUILD)/layers.ok
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $(LIB_OBJ)

$(BUILD)/libmlip-host.a: $(HOST_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^ $(if $(HOST_OBJ),,&& true)

$(BUILD)/libmlip-rt.a: $(RT_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^

# Tools: host helpers + core; those using rt/ also get libmlip-rt.a and its
# libraries (RT_TOOLS, RT_TESTS: target-specific, so the others never see them).
$(RT_TOOLS) $(RT_TESTS): RT_LINK := $(BUILD)/libmlip-rt.a $(RT_LIBS)
$(RT_TOOLS) $(RT_TESTS): $(BUILD)/libmlip-rt.a

# Parts of a tool in tools/ beside it (they use rt/, so not in tools/lib/,
# which every binary and the fuzz targets may link): mlip-feed and mlip-ctl
# (mdi) share the feeder, tools/feed*.c (feedstate.h); mlip-ctl's own parts
# are tools/ctl*.c (ctltool.h); mlip-rt's tools/rtparts.c (rtparts.h);
# mlip-sim's options tools/simopts.c (simopts.h).
FEED_OBJ  := $(patsubst %.c,$(BUILD)/obj/%.o,$(wildcard tools/feed*.c))
CTL_OBJ   := $(patsubst %.c,$(BUILD)/obj/%.o,$(wildcard tools/ctl*.c))
$(BUILD)/mlip-feed: PART_OBJ := $(FEED_OBJ)
$(BUILD)/mlip-feed: $(FEED_OBJ)
$(BUILD)/mlip-ctl: PART_OBJ := $(CTL_OBJ) $(FEED_OBJ)
$(BUILD)/mlip-ctl: $(CTL_OBJ) $(FEED_OBJ)
SIM_OBJ   := $(BUILD)/obj/tools/simopts.o
$(BUILD)/mlip-sim: PART_OBJ := $(SIM_OBJ)
$(BUILD)/mlip-sim: $(SIM_OBJ)
RT_OBJ    := $(BUILD)/obj/tools/rtparts.o $(BUILD)/obj/tools/rtplan.o
$(BUILD)/mlip-rt: PART_OBJ := $(RT_OBJ)
$(BUILD)/mlip-rt: $(RT_OBJ)

$(BUILD)/mlip-%: $(BUILD)/obj/tools/mlip-%.o $(BUILD)/libmlip-host.a $(BUILD)/libmlip.a
	$(CC) $(LDFLAGS) -o $@ $< $(PART_OBJ) $(BUILD)/libmlip-host.a $(RT_LINK) $(BUILD)/libmlip.a $(LDLIBS)

$(BUILD)/tests/test_%: $(BUILD)/obj/tests/unit/test_%.o $(BUILD)/libmlip-host.a $(BUILD)/libmlip.a
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS) -o $@ $< $(BUILD)/libmlip-host.a $(RT_LINK) $(BUILD)/libmlip.a -lcmocka -pthread $(LDLIBS)

# test_shm fails posix_fallocate on demand (a full /dev/shm) through --wrap.
$(BUILD)/tests/test_shm: LDFLAGS += -Wl,--wrap=posix_fallocate

$(BUILD)/bench_%: $(BUILD)/obj/bench/bench_%.o $(BUILD)/libmlip-host.a $(BUILD)/libmlip.a
	$(CC) $(LDFLAGS) -o $@ $< $(BUILD)/libmlip-host.a $(BUILD)/libmlip.a $(LDLIBS)

deps:
	@tools/deps.sh

# The core is pure: undefined symbols of libmlip.a against an allow-list;
# and what must run without rt/ (mlip-sim, mlip-check, the benchmarks, the
# pure unit tests) holds none of it.
PURE_BINS := $(filter-out $(RT_TOOLS),$(TOOLS)) $(BENCH_BINS) $(filter-out $(RT_TESTS),$(UNIT_BINS))
purity: $(BUILD)/libmlip.a $(PURE_BINS)
	@tools/purity.sh $(BUILD)/libmlip.a
	@for b in $(PURE_BINS); do \
		if nm $$b | grep -q ' [TU] \(mlip_shm_\|mlip_rt_\|mlip_canbus_\|mlip_period_\|mlip_drives_\|can_do_\|can_get_\)'; then \
			echo "purity: $$b links rt/ or libsocketcan"; exit 1; fi; done
	@echo "purity: $(words $(PURE_BINS)) tools, benchmarks and tests without rt/ or libsocketcan"

# ThreadSanitizer (build-tsan/): the ring's two-thread stress tests, then the
# controller's loop thread and a feeder thread on one ring in one process
# (mlip-latency --plan: the real tick, SCHED_OTHER, memory not locked, since
# TSan's shadow memory must not be locked).
tsan:
	@$(MAKE) --no-print-directory BUILD=build-tsan OPT=-O1 SAN="-fsanitize=thread" \
		build-tsan/tests/test_ring build-tsan/tests/test_planq build-tsan/tests/test_rtplan \
		build-tsan/mlip-latency build-tsan/bench_planfeed
	TSAN_OPTIONS="halt_on_error=1 exitcode=66" build-tsan/tests/test_ring
	TSAN_OPTIONS="halt_on_error=1 exitcode=66" build-tsan/tests/test_planq
	TSAN_OPTIONS="halt_on_error=1 exitcode=66" build-tsan/tests/test_rtplan
	@sed -e 's/^\[TRAJ\]$$/[TRAJ]\nJERK_PLAN = path/' -e 's/^\(\[AXIS_.\]\)$$/\1\nMAX_JERK = 100000/' \
		config/mill-3axis.ini > build-tsan/planfeed.ini
	@printf 'G21 G90\nG1 F12000\nG1 X20\nG1 Y20\nG1 X0\nG1 Y0\n' > build-tsan/planfeed.ngc
	TSAN_OPTIONS="halt_on_error=1 exitcode=66" build-tsan/bench_planfeed --paced \
		--config build-tsan/planfeed.ini build-tsan/planfeed.ngc >/dev/null
	@TSAN_OPTIONS="halt_on_error=1 exitcode=66" build-tsan/mlip-latency --plan examples/demo.ngc \
		-D 3 -p 0 --no-mlockall -q >/dev/null 2>build-tsan/latency.err || \
		{ cat build-tsan/latency.err; exit 1; }
	@echo "tsan: no data race in the ring and planned-queue tests, the planning thread or the controller/feeder threads"

# The main job on its bundled default: examples/demo.ngc on the 3-axis mill.
# demo, run and bench install what they need first, as test does.
run: deps
	@$(MAKE) --no-print-directory all
	@$(BUILD)/mlip-sim --config config/mill-3axis.ini --trace $(BUILD)/demo-trace.csv \
		--summary $(BUILD)/demo-summary.json examples/demo.ngc
	@$(BUILD)/mlip-sim --config config/mill-3axis.ini --no-notes --strategy bisector examples/demo.ngc
	@$(BUILD)/mlip-sim --config config/mill-3axis.ini --no-notes --strategy stop examples/demo.ngc
	@echo "setpoints: $(BUILD)/demo-trace.csv  summary: $(BUILD)/demo-summary.json"
	@$(BUILD)/mlip-check --config config/mill-3axis.ini examples/demo.ngc $(BUILD)/demo-trace.csv

# Unit tests: each binary is a cmocka group; run them all, fail if any fails.
unit: $(UNIT_BINS)
	@fail=0; for t in $(UNIT_BINS); do echo "== $$t"; $$t || fail=1; done; exit $$fail

# System tests (pytest): physics checks on the real toolpaths, CLI behaviour.
# PYTEST_ARGS: which tests (default all of tests/py); MLIP_SAN tells a test
# that compiles a program of its own the sanitizer flags of this build.
PYTEST_ARGS ?= tests/py
pytest: all
	@. .venv/bin/activate && MLIP_BUILD=$(BUILD) MLIP_SAN="$(SAN)" python -m pytest -q $(PYTEST_ARGS)

# Formatting: every C file as .clang-format says (Debian's clang-format 14);
# a difference fails with the file and line (clang-format -i FILE mends it).
C_FILES := $(shell git ls-files 'src/*.c' 'include/*.h' 'rt/*.c' 'rt/*.h' 'tools/*.c' \
             'tools/*.h' 'tests/unit/*.c' 'tests/unit/*.h' 'tests/py/*.c' 'bench/*.c' 'fuzz/*.c' 'fuzz/*.h' \
             2>/dev/null)
format-check:
	@clang-format --dry-run -Werror $(C_FILES)
	@echo "format: $(words $(C_FILES)) C files as .clang-format says"

# The Python package (python/mlipcan) and the Python tools (tools/*.py):
# ruff's format (a difference fails, with the diff) and lint, and mypy
# --strict (pyproject.toml says what and how). tools/deps.sh installs them.
PY_DIRS := python tools
pycheck:
	@.venv/bin/ruff format --check --diff $(PY_DIRS)
	@.venv/bin/ruff check --no-fix $(PY_DIRS)
	@.venv/bin/mypy
	@echo "pycheck: ruff format and lint, mypy --strict: clean"

format:
	clang-format -i $(C_FILES)
	.venv/bin/ruff format $(PY_DIRS)
	.venv/bin/ruff check --fix $(PY_DIRS)

test: deps
	@$(MAKE) --no-print-directory format-check
	@$(MAKE) --no-print-directory pycheck
	@$(MAKE) --no-print-directory all
	@$(MAKE) --no-print-directory purity
	@$(MAKE) --no-print-directory unit
	@$(MAKE) --no-print-directory tsan
	@$(MAKE) --no-print-directory pytest
	@$(MAKE) --no-print-directory can

# The main job: mlip-rt + mlip-feed + the python-can listener on vcan0 (or
# in the VM) with the bundled program; prints what happened, plots speed.
demo: deps
	@$(MAKE) --no-print-directory all
	@tools/demo.sh

# CAN tests on a real vcan0: on this host when it can make one, else in a
# QEMU VM (docs/can-vm.md). One call, one boot.
can: all
	@tests/can/run-tests.sh

bench: deps
	@$(MAKE) --no-print-directory all
	@. .venv/bin/activate 2>/dev/null; python3 bench/run.py --build $(BUILD)

# libFuzzer targets for the G-code and config readers (ASan + UBSan),
# FUZZ_SECONDS each (default 60); seeds from the shared toolpaths and config/.
fuzz:
	@fuzz/run.sh $(or $(FUZZ_SECONDS),60)

# Each validation rule removed in turn in a scratch copy: a test must fail
# (tools/mutate.py; a few minutes, by hand or in CI when time allows).
mutate: deps
	@.venv/bin/python tools/mutate.py

# Sanitizers: the unit tests and the system tests (every tool the tests run
# is this build's) under AddressSanitizer and UndefinedBehaviorSanitizer.
# make asan, make ubsan: all of tests/py, each in its own build. make
# sanitize: both at once in one build, tests/py but test_toolpaths (two
# thirds of the sanitized time: physics of every toolpath x setting x
# strategy, the code every other test runs too): what .ci/run runs before
# make test. Times: docs/testing.md.
SAN_ADDRESS   := -fsanitize=address -fno-omit-frame-pointer
SAN_UNDEFINED := -fsanitize=undefined -fno-sanitize-recover=all
asan: deps
	@$(MAKE) --no-print-directory BUILD=build-asan OPT=-O1 SAN="$(SAN_ADDRESS)" unit pytest
ubsan: deps
	@$(MAKE) --no-print-directory BUILD=build-ubsan OPT=-O1 SAN="$(SAN_UNDEFINED)" unit pytest
sanitize: deps
	@$(MAKE) --no-print-directory BUILD=build-san OPT=-O1 SAN="$(SAN_ADDRESS) $(SAN_UNDEFINED)" \
		PYTEST_ARGS="tests/py --ignore=tests/py/test_toolpaths.py" unit pytest

clean:
	rm -rf build build-asan build-ubsan build-tsan build-san

.SECONDARY:

-include $(shell find $(BUILD) -name '*.d' 2>/dev/null)
