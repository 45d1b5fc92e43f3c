# Two entry points (see README): `make run` sets up and runs the main job on embedded data,
# `make test` sets up and runs the default test suite. Both create .venv on first use.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
PIPELINE ?= pipelines/filter_vs_smoother.yaml
OUT ?= runs/filter_vs_smoother

.PHONY: setup run test test-all docs bench clean

setup: $(STAMP)

# the C kernels are compiled by setup.py at install: reinstall when a source changes
KERNEL_SOURCES := $(wildcard slamkit/*/*.c slamkit/*/*/*.c)

$(STAMP): pyproject.toml constraints.txt setup.py $(KERNEL_SOURCES)
	@# open3d links against libusb-1.0, which minimal Debian images lack.
	@ldconfig -p | grep -q 'libusb-1.0.so.0' || { $(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq libusb-1.0-0; }
	@# the recording tests open each pipeline's recording in Rerun's web viewer inside headless
	@# Chromium (Playwright drives Debian's browser: no browser download)
	@command -v chromium >/dev/null && [ -e /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf ] || { $(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq chromium fonts-dejavu-core; }
	@# the kernels need Python's C headers (Debian's python3 ships them in python3-dev)
	@$(PYTHON) -c 'import os, sysconfig, sys; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))' || { $(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq python3-dev; }
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	@# constraints.txt pins every dependency to the versions the figures were measured with
	@# (README, "Reproducibility"): a fresh machine must not resolve newer numpy/scipy/BLAS builds
	$(BIN)/pip install -q -c constraints.txt -e '.[test]'
	@# The rerun CLI phones home for analytics and can hang without network.
	$(BIN)/python -m rerun analytics disable >/dev/null 2>&1 || true
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/slamkit run $(PIPELINE) --out $(OUT) --overwrite

test: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow"

test-all: $(STAMP)
	$(BIN)/python -m pytest -q 

# the documentation site into site/ (tests/docs builds it too, strict, and runs the tutorials)
docs: $(STAMP)
	$(BIN)/mkdocs build --strict

# every benchmark suite (slamkit.bench.SUITES), each against its same-run reference; QUICK=1 for smoke sizes
bench: $(STAMP)
	@for name in $$($(BIN)/python -c 'from slamkit.bench import SUITES; print(" ".join(SUITES))'); do \
		$(BIN)/slamkit bench $$name $(if $(QUICK),--quick) || exit 1; done

clean:
	rm -rf $(VENV) runs site .pytest_cache
