# amaranth: UnusedElaboratable=no
# (Some tests build units with parameters the units must reject.)
"""`kfgen fpu`: parameters, errors, manifest, and the generated Verilog in Icarus and Verilator."""

import json
import multiprocessing
import subprocess
from concurrent.futures import ProcessPoolExecutor

import pytest

from kfgen.hdl.arith.float.params import (CLOCK_MHZ, OPS, FpuParams, cycles_per_op_range,
                                         ranges_text, stages_range)
from kfgen.hdl.describe import ParamError
from kfgen.sim.toolchain import iverilog, lint

from helpers import ROOT, kfgen, kfgen_in_process


@pytest.mark.parametrize("args,param", [
    (["--op", "pow"], "--op"),
    (["--format", "binary128"], "--format"),
    (["--format", "e2m10"], "--format"),
    (["--subnormals", "daz"], "--subnormals"),
    (["--op", "add", "--cycles-per-op", "2"], "--cycles-per-op"),
    (["--op", "div", "--cycles-per-op", "0"], "--cycles-per-op"),
    (["--stages", "0"], "--stages"),
    (["--stages", "99"], "--stages"),
    (["--stages", "two"], "--stages"),
    (["--name", "9x"], "--name"),
])
def test_bad_parameters_exit_2_with_one_line(tmp_path, args, param):
    proc = kfgen_in_process("fpu", *args, "-o", tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"kfgen: error: {param}:"), proc.stderr
    assert "Traceback" not in proc.stderr and not list(tmp_path.iterdir())


def _error(tmp_path, *args):
    proc = kfgen_in_process("fpu", *args, "-o", tmp_path)
    assert proc.returncode == 2 and not list(tmp_path.iterdir())
    return proc.stderr.strip()


def test_count_errors_quote_the_range_functions(tmp_path):
    """Stages 0, one too many and ``x``, and cycles per operation one too many for binary32
    div: every error gives the range :func:`stages_range` or :func:`cycles_per_op_range` gives."""
    lo, hi = stages_range("add", "binary32")
    for value in (lo - 1, hi + 1):
        assert _error(tmp_path, "--stages", value) == \
            f"kfgen: error: --stages: must be an integer in {lo}..{hi} for add binary32, not {value}"
    assert _error(tmp_path, "--stages", "x") == \
        f"kfgen: error: --stages: must be an integer in {lo}..{hi} for add binary32, not 'x'"
    config = tmp_path.parent / "stages_x.toml"
    config.write_text('stages = "x"\n')
    assert _error(tmp_path, "--config", config) == f"kfgen: error: --stages: must be an integer in " \
                                                   f"{lo}..{hi} for add binary32, not 'x' (from {config})"

    lo, hi = cycles_per_op_range("div", "binary32")
    assert _error(tmp_path, "--op", "div", "--cycles-per-op", hi + 1) == \
        f"kfgen: error: --cycles-per-op: must be an integer in {lo}..{hi} for div binary32, not {hi + 1}"
    assert _error(tmp_path, "--op", "div", "--cycles-per-op", "x") == \
        f"kfgen: error: --cycles-per-op: must be an integer in {lo}..{hi} for div binary32, not 'x'"
    lo, hi = stages_range("div", "binary32", "ftz", 4)
    assert _error(tmp_path, "--op", "div", "--subnormals", "ftz", "--cycles-per-op", 4, "--stages", hi + 1) == \
        f"kfgen: error: --stages: must be an integer in {lo}..{hi} for div binary32, ftz, cycles_per_op 4, " \
        f"not {hi + 1}"


def test_help_and_docs_quote_the_ranges_and_the_design_clock():
    help_text = " ".join(kfgen("fpu", "--help").stdout.split())
    page = " ".join((ROOT / "docs" / "fpu.md").read_text().split())
    for text in (help_text, page):
        assert f"in binary32: {ranges_text('stages')}" in text
        assert f"in binary32: {ranges_text('cycles_per_op')}" in text
        assert f"designed for {CLOCK_MHZ} MHz" in text


@pytest.mark.parametrize("fmt", ["binary16", "binary32", "e3m2", "e15m64"])
@pytest.mark.parametrize("op", list(OPS))
def test_ranges_are_what_the_units_build(op, fmt):
    """The ranges' ends build, one past them does not, in the core and in the unit (the
    iterative sin, cos and atan2 have one stage count, their latency, and refuse formats whose
    subnormals reach 2**-S)."""
    iterative = op in ("sin", "cos", "atan2")
    if iterative and fmt == "e3m2":
        with pytest.raises(ParamError, match="subnormals are below"):
            FpuParams(op=op, format=fmt)
        return
    unit_cls = type(FpuParams(op=op, format=fmt).build())
    k_lo, k_hi = cycles_per_op_range(op, fmt)
    assert k_lo == 1 and (k_hi > 1) == OPS[op][2]
    if OPS[op][2]:
        with pytest.raises(ValueError, match="cycles_per_op"):
            unit_cls(fmt, cycles_per_op=k_hi + 1)
    with pytest.raises(match=f"in 1..{k_hi} for {op} {fmt}, not {k_hi + 1}"):
        FpuParams(op=op, format=fmt, cycles_per_op=k_hi + 1)
    for subnormals in ("ieee", "ftz"):
        for k in sorted({k_lo, (k_lo + k_hi) // 2, k_hi}):
            lo, hi = stages_range(op, fmt, subnormals, k)
            assert 1 <= lo <= hi and (lo == hi) == iterative
            for stages in (lo, hi):
                assert FpuParams(op=op, format=fmt, subnormals=subnormals, stages=stages,
                                 cycles_per_op=k).build().latency == stages
            kw = {"cycles_per_op": k} if OPS[op][2] else {}
            with pytest.raises(ValueError, match="stages"):
                unit_cls(fmt, subnormals=subnormals, stages=hi + 1, **kw)
            for stages in (lo - 1, hi + 1):
                with pytest.raises(match=f"in {lo}..{hi} for {op} {fmt}"):
                    FpuParams(op=op, format=fmt, subnormals=subnormals, stages=stages, cycles_per_op=k)


@pytest.mark.parametrize("op", list(OPS))
def test_manifest_matches_the_unit(tmp_path, op):
    proc = kfgen_in_process("fpu", "--op", op, "--format", "binary16", "--name", f"u_{op}", "-o", tmp_path)
    assert proc.returncode == 0, proc.stderr
    man = json.loads((tmp_path / f"u_{op}.json").read_text())
    unit = FpuParams(op=op, format="binary16").build()
    assert man["latency_cycles"] == unit.latency
    iterative = op in ("sin", "cos", "atan2")  # one operation per latency, with i_ready
    assert man["initiation_interval"] == unit.initiation_interval == (unit.latency if iterative else 1)
    ports = {p["name"]: p for p in man["ports"]}
    assert set(ports) >= {"clk", "rst", "i_valid", "i_a", "o_valid", "o_y", "o_flags"}
    assert ("i_b" in ports) == (op in ("add", "sub", "mul", "div", "fma", "atan2"))
    assert ("i_c" in ports) == (op == "fma") and ("i_ready" in ports) == iterative
    assert [f["name"] for f in ports["o_flags"]["fields"]] == ["NX", "UF", "OF", "DZ", "NV"]
    a_field, y_field = ports["i_a"]["fields"][0], ports["o_y"]["fields"][0]
    assert (a_field.get("format") == "binary16") == (op != "i2f")
    assert (y_field.get("format") == "binary16") == (op != "f2i")
    assert ports["i_a"]["width"] == (32 if op == "i2f" else 16)
    assert ports["o_y"]["width"] == (32 if op == "f2i" else 16)


def test_iterative_divider_has_ready_and_exact_interval(tmp_path):
    kfgen("fpu", "--op", "div", "--cycles-per-op", "4", "--name", "d4", "-o", tmp_path)
    man = json.loads((tmp_path / "d4.json").read_text())
    assert man["initiation_interval"] == 4
    assert {"name": "i_ready", "direction": "output", "width": 1} in man["ports"]


def test_deterministic(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        kfgen("fpu", "--op", "fma", "--name", "f", "-o", out)
    for name in ("f.v", "f.vlt", "f.json"):
        assert (a / name).read_bytes() == (b / name).read_bytes()
        assert str(tmp_path) not in (a / name).read_text()


#: Spellings of one core, by the parameters it records.
SPELLINGS = {
    ("mul", "binary32", "ftz"): [
        ["--op", "mul", "--format", "binary32", "--subnormals", "ftz"],
        ["--op", "MUL", "--format", "E8M23", "--subnormals", "FTZ"],
        ["--op", "Mul", "--format", "e8m23", "--subnormals", "Ftz"],
        ["--op", "mul", "--format", "BINARY32", "--subnormals", "ftz"],
        ["--config", 'op = "MUL"\nformat = "E8M23"\nsubnormals = "FTZ"\n']],
    ("div", "bfloat16", "ieee"): [
        ["--op", "div", "--format", "bfloat16"], ["--op", "DIV", "--format", "e8m7"],
        ["--op", "div", "--format", "E8M7", "--subnormals", "IEEE"], ["--op", "div", "--format", "BFloat16"]],
    ("sqrt", "binary16", "ieee"): [["--op", "sqrt", "--format", "binary16"], ["--op", "sqrt", "--format", "e5m10"]],
    ("i2f", "binary64", "ieee"): [["--op", "i2f", "--format", "binary64"], ["--op", "I2F", "--format", "E11M52"]],
    ("fma", "e6m11", "ieee"): [["--op", "fma", "--format", "e6m11"], ["--op", "FMA", "--format", "E6M11"]],
}


#: Run in make test (the rest in make test-full): an op, a format and a subnormal mode each spelt
#: every way between them.
SPELLINGS_EVERY_RUN = {("mul", "binary32", "ftz"), ("i2f", "binary64", "ieee")}


@pytest.mark.parametrize("core", [c if c in SPELLINGS_EVERY_RUN else pytest.param(c, marks=pytest.mark.full)
                                  for c in SPELLINGS], ids=["_".join(c) for c in SPELLINGS])
def test_every_spelling_gives_the_same_bytes(tmp_path, core):
    """Names are read whatever their case, and an eEmM that is a named format as that format:
    the parameters, and so the files, record one spelling."""
    outputs = []
    for k, args in enumerate(SPELLINGS[core]):
        if args[0] == "--config":
            (tmp_path / "spelling.toml").write_text(args[1])
            args = ["--config", tmp_path / "spelling.toml"]
        out = tmp_path / str(k)
        proc = kfgen_in_process("fpu", *args, "--name", "u", "-o", out)
        assert proc.returncode == 0, proc.stderr
        outputs.append({name: (out / name).read_bytes() for name in ("u.v", "u.vlt", "u.json")})
    assert all(files == outputs[0] for files in outputs[1:])
    recorded = json.loads(outputs[0]["u.json"])["parameters"]
    assert (recorded["op"], recorded["format"], recorded["subnormals"]) == core


# mul, fma, div, sqrt and exp in make test-full: make test's engine cores carry them through
# Icarus whole (their shipped testbenches, tests/ukf/test_ukf_core.py).
@pytest.mark.parametrize("args", [["--op", "add"], *(pytest.param(a, marks=pytest.mark.full) for a in (
                                      ["--op", "mul"], ["--op", "fma"], ["--op", "div"], ["--op", "sqrt", "--cycles-per-op", "4"])),
                                  ["--op", "i2f"], ["--op", "f2i"],
                                  pytest.param(["--op", "exp"], marks=pytest.mark.full), ["--op", "add", "--subnormals", "ftz"]])
def test_icarus_compiles(tmp_path, args):
    kfgen("fpu", *args, "--name", "u", "-o", tmp_path)
    ic = subprocess.run([iverilog(), "-g2012", "-o", str(tmp_path / "u.vvp"), str(tmp_path / "u.v")],
                        capture_output=True, text=True)
    assert ic.returncode == 0, ic.stderr


#: Formats linted with every operation: the named ones, and eEmM across the widths the command
#: line accepts (exponent 3..15 bits, fraction 2..64): the narrowest; significands mul takes in
#: LUT rows alone (up to 8 bits: e4m3 to e5m7), in one multiplier block (e6m11), in several; a
#: narrow exponent with a wide fraction, the reverse, and the widest.
LINT_FORMATS = ("binary16", "bfloat16", "binary32", "binary64", "e3m2", "e4m3", "e5m5", "e6m6",
                "e5m7", "e6m11", "e3m40", "e15m2", "e15m64")
#: Linted in every run (binary32's defaults; its ftz cores in make test-full); the rest in make test-full (binary32's
#: fewest-stages and iterative variants; binary16 builds what binary32 does, narrower;
#: binary64 the same code wider).
LINT_EVERY_RUN = ("binary32",)
#: Formats also linted with ftz; with the fewest stages (the most logic between registers,
#: where Yosys folds the most); with div and sqrt iterative.
FTZ_FORMATS = ("binary32", "bfloat16", "e3m2", "e6m11")
MIN_STAGES_FORMATS = ("binary32", "binary16", "e5m5", "e15m2")
ITERATIVE_FORMATS = ("binary32", "binary64", "e3m2", "e15m64")


def _lint_configs(fmt, variants=True):
    """id -> ``kfgen fpu`` arguments of the cores linted in ``fmt``: every operation's default;
    in samples of formats ftz, the fewest stages, and div and sqrt at their most cycles per
    operation (one recurrence step a cycle), in binary32 also at two and four. Without
    ``variants``, only the defaults and ftz; with ``variants="only"``, only the others."""
    configs = _lint_configs_all(fmt)
    if variants is True:
        return configs
    basic = {k: v for k, v in configs.items() if k in OPS or k.endswith("_ftz")}
    return basic if not variants else {k: v for k, v in configs.items() if k not in basic}


def _lint_configs_all(fmt):
    configs = {}
    for op in OPS:
        args = ["--op", op, "--format", fmt]
        configs[op] = args
        if fmt in FTZ_FORMATS:
            configs[f"{op}_ftz"] = args + ["--subnormals", "ftz"]
        if fmt in MIN_STAGES_FORMATS:
            configs[f"{op}_min"] = args + ["--stages", str(stages_range(op, fmt)[0])]
        if OPS[op][2] and fmt in ITERATIVE_FORMATS:
            for k in ([2, 4] if fmt == "binary32" else []) + [cycles_per_op_range(op, fmt)[1]]:
                configs[f"{op}_cpo{k}"] = args + ["--cycles-per-op", str(k)]
    return configs


def _generate_and_lint(args, out):
    """Warnings of ``verilator -Wall --lint-only`` with the core's own waivers on the core that
    ``kfgen fpu ARGS`` writes into ``out`` (in a worker process)."""
    proc = kfgen_in_process("fpu", *args, "--name", "u", "-o", out)
    if proc.returncode != 0:
        return [proc.stderr.strip()]
    rc, messages = lint(f"{out}/u.v")  # what `kfgen lint` runs
    return messages or ([f"verilator exit status {rc}"] if rc else [])


@pytest.fixture(scope="module")
def lint_pool():
    # Processes, not threads: generating a core is Python under the GIL. Two, for two cores.
    with ProcessPoolExecutor(max_workers=2, mp_context=multiprocessing.get_context("spawn")) as pool:
        yield pool


@pytest.mark.parametrize("fmt", [f if f in LINT_EVERY_RUN else pytest.param(f, marks=pytest.mark.full)
                                 for f in LINT_FORMATS]
                         + [pytest.param(f"{f}-{part}", marks=pytest.mark.full)
                            for f in LINT_EVERY_RUN for part in ("ftz", "variants")])
def test_verilator_lint_clean(tmp_path, lint_pool, fmt):
    """``verilator -Wall --lint-only`` with the core's own waivers: not one warning. make test
    lints binary32's defaults (one core an operation); its ftz cores and variants, and the other
    formats, in make test-full."""
    fmt, _, part = fmt.partition("-")
    configs = _lint_configs(fmt, "only" if part == "variants" else fmt not in LINT_EVERY_RUN)
    if fmt in LINT_EVERY_RUN and part != "variants":
        configs = {k: v for k, v in configs.items() if (k in OPS) == (part != "ftz")}
    jobs = {key: lint_pool.submit(_generate_and_lint, args, str(tmp_path / key)) for key, args in configs.items()}
    failed = {key: job.result() for key, job in jobs.items() if job.result()}
    assert not failed, "\n".join(f"kfgen fpu {' '.join(configs[k])}:\n  " + "\n  ".join(m)
                                  for k, m in failed.items())
