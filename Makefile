# motecal: `make demo` and `make test` do all set-up on a fresh Debian machine.
#
#   make demo    the main job end to end on the simulator (sqlite), ends with a report
#   make test    every test: Python (pytest), C logic with gcc, and avr-gcc + simavr
#   make bench   benchmarks: measured figures next to the goals (not pass/fail)

SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-$(shell cat host/requirements.txt host/pyproject.toml | md5sum | cut -c1-8)
APT_PACKAGES := gcc make gcc-avr avr-libc simavr postgresql
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
PYTEST_ARGS ?=
DEMO_DIR ?= demo-out

.PHONY: all venv sysdeps test demo bench clean cbuild

all: test

# --- set-up -------------------------------------------------------------
$(STAMP): host/requirements.txt host/pyproject.toml
	@if ! python3 -c 'import venv, ensurepip' 2>/dev/null; then \
	  echo "installing python3-venv"; \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq python3-venv python3-pip; fi
	rm -rf $(VENV)
	python3 -m venv $(VENV)
	$(VENV)/bin/pip install -q --disable-pip-version-check -r host/requirements.txt
	$(VENV)/bin/pip install -q --disable-pip-version-check --no-deps -e host
	touch $@

venv: $(STAMP)

# Debian packages the tests need (gcc, avr-gcc, simavr; postgresql for the store's
# server test), installed when missing.
sysdeps:
	@missing=""; for p in $(APT_PACKAGES); do \
	  dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then echo "installing Debian packages:$$missing"; \
	  $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $$missing >/dev/null; fi

# --- the two commands -----------------------------------------------------
test: venv sysdeps
	$(PY) -m pytest -q -p no:cacheprovider $(PYTEST_ARGS) tests

demo: venv
	$(PY) scripts/demo.py --out $(DEMO_DIR)

bench: venv sysdeps
	@for b in bench/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) $(DEMO_DIR) build .pytest_cache
