# mlip - one Makefile, output in $(BUILD).
#   make            library, tools, unit tests
#   make demo       the controller on vcan0 (or a VM) with the bundled program
#   make run        the simulator on the bundled demo, all three strategies
#   make test       install missing deps, build, run every test (what CI runs)
#   make can        the CAN tests alone (vcan0 on the host, or in a VM)
#   make bench      Table 1 and Table 2 of the paper, redone
#   make asan|ubsan the whole test suite under a sanitizer (build-asan/, build-ubsan/)
#   make fuzz       the fuzz targets, FUZZ_SECONDS each (default 60)

BUILD   ?= build
CC      ?= cc
OPT     ?= -O2
SAN     ?=
CFLAGS  := -std=c99 -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE $(OPT) -g \
           -Wall -Wextra -Wpedantic -Wshadow -Wstrict-prototypes -Wmissing-prototypes \
           -Wno-unused-function -Werror -MMD -MP -Iinclude -Itools/lib -Irt $(SAN) $(EXTRA_CFLAGS)
LDFLAGS := $(SAN) $(EXTRA_LDFLAGS)
LDLIBS  := -lm

LIB_SRC   := $(wildcard src/*.c)
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

# rt/ needs libsocketcan and threads; tools that use rt/ link it.
RT_LIBS   := -lsocketcan -lpthread -lrt

.PHONY: all test unit pytest can bench asan ubsan fuzz deps clean demo run
all: $(BUILD)/libmlip.a $(TOOLS) $(UNIT_BINS) $(BENCH_BINS)

$(BUILD)/obj/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -c $< -o $@

$(BUILD)/libmlip.a: $(LIB_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^

$(BUILD)/libmlip-host.a: $(HOST_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^ $(if $(HOST_OBJ),,&& true)

$(BUILD)/libmlip-rt.a: $(RT_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && ar rcs $@ $^

# Tools: host helpers + core; rt-based tools also get librt.
$(BUILD)/mlip-%: $(BUILD)/obj/tools/mlip-%.o $(BUILD)/libmlip-host.a $(BUILD)/libmlip.a $(if $(RT_OBJ),$(BUILD)/libmlip-rt.a)
	$(CC) $(LDFLAGS) -o $@ $< $(BUILD)/libmlip-host.a $(if $(RT_OBJ),$(BUILD)/libmlip-rt.a $(RT_LIBS)) $(BUILD)/libmlip.a $(LDLIBS)

$(BUILD)/tests/test_%: $(BUILD)/obj/tests/unit/test_%.o $(BUILD)/libmlip-host.a $(BUILD)/libmlip.a $(if $(RT_OBJ),$(BUILD)/libmlip-rt.a)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS) -o $@ $< $(BUILD)/libmlip-host.a $(if $(RT_OBJ),$(BUILD)/libmlip-rt.a $(RT_LIBS)) $(BUILD)/libmlip.a -lcmocka $(LDLIBS)

# test_shm fails posix_fallocate on demand (a full /dev/shm) through --wrap.
$(BUILD)/tests/test_shm: LDFLAGS += -Wl,--wrap=posix_fallocate

$(BUILD)/bench_%: $(BUILD)/obj/bench/bench_%.o $(BUILD)/libmlip-host.a $(BUILD)/libmlip.a
	$(CC) $(LDFLAGS) -o $@ $< $(BUILD)/libmlip-host.a $(BUILD)/libmlip.a $(LDLIBS)

deps:
	@tools/deps.sh

# The main job on its bundled default: examples/demo.ngc on the 3-axis mill.
run: all
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
pytest: all
	@. .venv/bin/activate && MLIP_BUILD=$(BUILD) python -m pytest -q tests/py

test: deps
	@$(MAKE) --no-print-directory all
	@$(MAKE) --no-print-directory unit
	@$(MAKE) --no-print-directory pytest
	@$(MAKE) --no-print-directory can

# The main job: mlip-rt + mlip-feed + the python-can listener on vcan0 (or
# in the VM) with the bundled program; prints what happened, plots speed.
demo: all
	@tools/demo.sh

# CAN tests on a real vcan0: on this host when it can make one, else in a
# QEMU VM (tools/vcan/README.md). One call, one boot.
can: all
	@tests/can/run-tests.sh

bench: all
	@. .venv/bin/activate 2>/dev/null; python3 bench/run.py --build $(BUILD)

# libFuzzer targets for the G-code and config readers (ASan + UBSan),
# FUZZ_SECONDS each (default 60); seeds from the shared toolpaths and config/.
fuzz:
	@fuzz/run.sh $(or $(FUZZ_SECONDS),60)

asan:
	@$(MAKE) --no-print-directory BUILD=build-asan OPT=-O1 SAN="-fsanitize=address -fno-omit-frame-pointer" unit pytest
ubsan:
	@$(MAKE) --no-print-directory BUILD=build-ubsan OPT=-O1 SAN="-fsanitize=undefined -fno-sanitize-recover=all" unit pytest

clean:
	rm -rf build build-asan build-ubsan

.SECONDARY:

-include $(shell find $(BUILD) -name '*.d' 2>/dev/null)
