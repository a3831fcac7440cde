# motecal: `make demo` and `make test` do all set-up on a fresh Debian machine.
#
#   make demo    the main job end to end on the simulator (sqlite), ends with a report
#   make test    every test: Python (pytest), C logic with gcc, and avr-gcc + simavr,
#                in parallel on every core
#   make bench   benchmarks: measured figures next to the goals (not pass/fail),
#                written to bench/RESULTS.md and README.md's goals table

SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
REQUIREMENTS := host/requirements.txt host/requirements-test.txt host/pyproject.toml
STAMP := $(VENV)/.installed-$(shell cat $(REQUIREMENTS) | md5sum | cut -c1-8)
# Debian packages: the demo needs a C compiler (the simulated motes run the
# firmware's C code); the tests also need avr-gcc + simavr, libsimavr-dev +
# libelf-dev + pkg-config (the emulator harness, emu/), a PostgreSQL server
# and a MariaDB server (the store's server tests, which start their own in a
# temporary folder: the server core packages, so no system service is set up
# or started), and Chromium (the browser view's test, headless).  Installed
# with apt-get when missing.
# The emulator's commands (make emulate, fault-matrix, release-check) need
# only the harness's packages (EMU_PACKAGES); nesC and the TinyOS tree are
# the user's (docs/toolchain.md).
DEMO_PACKAGES := gcc libc6-dev
EMU_PACKAGES := $(DEMO_PACKAGES) gcc-avr avr-libc simavr libsimavr-dev libelf-dev pkg-config
TEST_PACKAGES := $(EMU_PACKAGES) postgresql mariadb-server-core mariadb-client-core chromium
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
PYTEST_ARGS ?=
DEMO_DIR ?= demo-out

.PHONY: all venv sysdeps demodeps emudeps test demo bench emulate release-check fault-matrix clean

all: test

# --- set-up -------------------------------------------------------------
$(STAMP): $(REQUIREMENTS)
	@command -v python3 >/dev/null && python3 -c 'import sys; sys.exit(sys.version_info < (3, 10))' \
	  || $(call apt_install,python3 python3-venv)
	rm -rf $(VENV)
	python3 -m venv $(VENV) || { rm -rf $(VENV); $(call apt_install,python3-venv) && python3 -m venv $(VENV); }
	$(VENV)/bin/pip install -q --disable-pip-version-check -r host/requirements-test.txt
	$(VENV)/bin/pip install -q --disable-pip-version-check --no-deps -e host
	touch $@

venv: $(STAMP)

apt_install = { echo "installing Debian packages: $(1)"; \
  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(1) >/dev/null; }
missing = $(shell for p in $(1); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done)

sysdeps:
	@$(if $(call missing,$(TEST_PACKAGES)),$(call apt_install,$(call missing,$(TEST_PACKAGES))),true)

demodeps:
	@$(if $(call missing,$(DEMO_PACKAGES)),$(call apt_install,$(call missing,$(DEMO_PACKAGES))),true)

emudeps:
	@$(if $(call missing,$(EMU_PACKAGES)),$(call apt_install,$(call missing,$(EMU_PACKAGES))),true)

# --- the two commands -----------------------------------------------------
# in parallel (pytest-xdist): one worker per core, a test module at a time on a
# worker, modules with slow tests first (tests/conftest.py); TEST_JOBS=0: all in
# this process
TEST_JOBS ?= auto
test: venv sysdeps
	$(PY) -m pytest -q -p no:cacheprovider -n $(TEST_JOBS) --dist loadfile --no-loadscope-reorder \
	  $(PYTEST_ARGS) tests

demo: venv demodeps
	$(PY) scripts/demo.py --out $(DEMO_DIR)

# Every bench prints its tables and records its figures (bench/results.py);
# the figures then go to bench/RESULTS.md and README.md's goals table.
BENCH_RESULTS := build/bench-results.jsonl
bench: venv sysdeps
	@mkdir -p build && rm -f $(BENCH_RESULTS)
	@for b in bench/bench_*.py; do echo "== $$b"; \
	  MOTECAL_BENCH_RESULTS=$(CURDIR)/$(BENCH_RESULTS) $(PY) $$b || exit 1; done
	$(PY) bench/results.py $(BENCH_RESULTS) bench/RESULTS.md
	$(PY) bench/goals_table.py

# N sensor motes + BaseStation in the emulator harness (needs a TinyOS tree and
# nesC >= 1.4.0, docs/toolchain.md: make emulate TINYOS_ROOT_DIR=...
# EMULATE_ARGS="--motes 3"; docs/emulation.md)
EMULATE_ARGS ?=
emulate: venv emudeps
	TINYOS_ROOT_DIR="$(TINYOS_ROOT_DIR)" $(PY) emu/emulate.py $(EMULATE_ARGS)

# the release check (outside CI): 3 motes + BaseStation emulated, guided static80 log,
# calibrate --upload, reset, corrected samples; and the fault cases (docs/emulation.md)
RELEASE_ARGS ?=
release-check: venv emudeps
	TINYOS_ROOT_DIR="$(TINYOS_ROOT_DIR)" $(PY) emu/release_check.py $(RELEASE_ARGS)

FAULT_ARGS ?=
fault-matrix: venv emudeps
	TINYOS_ROOT_DIR="$(TINYOS_ROOT_DIR)" $(PY) emu/fault_matrix.py $(FAULT_ARGS)

clean:
	rm -rf $(VENV) $(DEMO_DIR) build .pytest_cache emu/build
