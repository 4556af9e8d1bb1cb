"""The ``kfgen`` command line: every error path, help, config files, determinism, the manifest."""

import dataclasses
import json
import re

import pytest

from kfgen.gen import __version__
from kfgen.gen.cli import option, resolved_defaults
from kfgen.gen.cores import discover
from kfgen.hdl.castella.core import Castella
from kfgen.hdl.castella.params import RANGES, CastellaParams

from helpers import kfgen, kfgen_in_process

FIELD_PORTS = ("s_axis_tdata", "s_axis_tuser", "m_axis_tdata", "m_axis_tuser")


def _lo_hi(key):
    lo, hi = RANGES[key]
    if isinstance(lo, int):
        return [lo - 1, hi + 1]
    return [lo / 2, hi * 2]


def _toml(tmp_path, text, name="cfg.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


# (id, arguments after `kfgen` with OUT for the output directory, text the error line must name)
ERRORS = [
    ("tracks-0", ["castella", "--tracks", "0"], "--tracks"),
    *[(f"{key}-{v}", ["castella", option(key), v], option(key)) for key in RANGES for v in _lo_hi(key)],
    ("tracks-float", ["castella", "--tracks", "2.5"], "--tracks"),
    ("tracks-word", ["castella", "--tracks", "abc"], "--tracks"),
    ("period-word", ["castella", "--period", "fast"], "--period"),
    ("period-nan", ["castella", "--period", "nan"], "--period"),
    ("alpha-empty", ["castella", "--alpha", ""], "--alpha"),
    ("alpha-0", ["castella", "--alpha", "0"], "--alpha"),
    ("alpha-1", ["castella", "--alpha", "1"], "--alpha"),
    ("alpha-1.5", ["castella", "--alpha", "1.5"], "--alpha"),
    ("alpha-inf", ["castella", "--alpha", "inf"], "--alpha"),
    ("z1-above-z2", ["castella", "--z1", "2", "--z2", "1.5"], "--z1"),
    ("z1-equals-z2", ["castella", "--z1", "1.5", "--z2", "1.5"], "--z1"),
    ("q1-above-q2", ["castella", "--q1", "300"], "--q1"),
    ("name-digit", ["castella", "--name", "9lives"], "--name"),
    ("name-dash", ["castella", "--name", "my-core"], "--name"),
    *[(f"name-{kw}", ["castella", "--name", kw], "--name")
      for kw in ("module", "wire", "reg", "logic", "always_ff", "endmodule", "interface")],
    ("name-300", ["castella", "--name", "n" * 300], "--name"),
    ("name-65", ["fpu", "--name", "f" * 65], "--name"),
    ("name-port-clk", ["castella", "--name", "clk"], "--name"),
    ("name-port-tdata", ["castella", "--name", "m_axis_tdata"], "--name"),
    ("fpu-name-port", ["fpu", "--name", "o_flags"], "--name"),
    ("fpu-name-keyword", ["fpu", "--name", "always_comb"], "--name"),
    ("unknown-option", ["castella", "--trakcs", "8"], "--trakcs"),
    ("unknown-option-eq", ["castella", "--colour=red"], "--colour"),
    ("abbreviation", ["castella", "--track", "8"], "--track"),
    ("stray-argument", ["castella", "eight"], "eight"),
    ("missing-value", ["castella", "--tracks"], "--tracks"),
    ("unknown-core", ["kalman"], "CORE"),
    ("no-core", [], "CORE"),
    ("no-output", ["castella", "--tracks", "2"], "-o"),
]


@pytest.mark.parametrize("case, args, param", ERRORS, ids=[e[0] for e in ERRORS])
def test_bad_input(tmp_path, case, args, param):
    out = tmp_path / "out"
    with_output = args[:1] in (["castella"], ["fpu"]) and case != "no-output"
    _check_error(kfgen_in_process(*args, *(["-o", out] if with_output else [])), param)
    assert not out.exists(), "a rejected command must write nothing"


def _check_error(proc, param):
    lines = proc.stderr.splitlines()
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"kfgen: error: {param}: "), lines[0]
    assert len(lines[0]) > len(f"kfgen: error: {param}: ") + 5, "the line must say what is allowed"
    assert proc.stdout == ""


CONFIG_ERRORS = [
    ("missing", None, "--config"),
    ("directory", "DIR", "--config"),
    ("not-toml", "tracks = \n", "--config"),
    ("not-utf8", b"\xff\xfe tracks = 1", "--config"),
    ("duplicate-toml", "tracks = 8\ntracks = 9\n", "--config"),
    ("unknown-key", "tracks = 8\ncolour = 'red'\n", "colour"),
    ("table", "[castella]\ntracks = 8\n", "castella"),
    ("both-spellings", "sigma_r = 50.0\nsigma-r = 60.0\n", "sigma-r"),
    ("string-for-int", "tracks = \"8\"\n", "--tracks"),
    ("float-for-int", "tracks = 8.0\n", "--tracks"),
    ("bad-alpha", "alpha = 2.0\n", "--alpha"),
    ("z-order", "z1 = 3.0\nz2 = 2.0\n", "--z1"),
]


@pytest.mark.parametrize("content, param", [e[1:] for e in CONFIG_ERRORS], ids=[e[0] for e in CONFIG_ERRORS])
def test_bad_config(tmp_path, content, param):
    cfg = tmp_path / "cfg.toml"
    if content == "DIR":
        cfg.mkdir()
    elif isinstance(content, bytes):
        cfg.write_bytes(content)
    elif content is not None:
        cfg.write_text(content)
    out = tmp_path / "out"
    proc = kfgen_in_process("castella", "--config", cfg, "-o", out)
    _check_error(proc, param)
    if param.startswith("--") and param != "--config":
        assert "cfg.toml" in proc.stderr, "a bad value from a file names the file"
    assert not out.exists()


def test_unwritable_output(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    _check_error(kfgen("castella", "-o", blocker, check=False), "-o")
    _check_error(kfgen("castella", "-o", blocker / "sub", check=False), "-o")
    assert blocker.read_text() == "not a directory"


def test_failed_write_leaves_nothing(tmp_path):
    """All or nothing: a file that cannot be written takes the others and the new directory
    with it."""
    from kfgen.gen.cli import UsageError, write_files

    out = tmp_path / "new" / "dir"
    with pytest.raises(UsageError, match="-o"):
        write_files(out, {"a.v": "x", "missing/b.v": "y"})
    assert not (tmp_path / "new").exists()
    (tmp_path / "keep").mkdir()
    (tmp_path / "keep" / "old.v").write_text("old")
    with pytest.raises(UsageError):
        write_files(tmp_path / "keep", {"a.v": "x", "missing/b.v": "y"})
    assert [f.name for f in (tmp_path / "keep").iterdir()] == ["old.v"]


def test_name_length_limit(tmp_path):
    """A name too long for a file name is refused up front, saying the limit (it once ended in
    an internal OSError and an empty output folder)."""
    from kfgen.gen.output import NAME_MAX

    proc = kfgen_in_process("castella", "--name", "n" * 300, "-o", tmp_path / "out")
    _check_error(proc, "--name")
    assert f"at most {NAME_MAX} characters" in proc.stderr and not (tmp_path / "out").exists()
    assert kfgen_in_process("castella", "--name", "n" * NAME_MAX, "-o", tmp_path / "ok").returncode == 0
    assert max(len(p.name) for p in (tmp_path / "ok").iterdir()) <= 255


@pytest.mark.parametrize("case", ["blocked", "empty", "long-name", "clk"])
def test_arguments_are_checked_before_generation(tmp_path, monkeypatch, case):
    """A bad -o or --name is refused before the seconds of generation: here the Verilog
    emission (and for -o the whole generation) fails the test if it is reached."""
    from kfgen.gen import cli, verilog

    def reached(*args, **kwargs):
        raise AssertionError("generation was reached")
    monkeypatch.setattr(verilog, "emit", reached)
    if case != "clk":
        monkeypatch.setattr(cli, "generate", reached)
    blocker = tmp_path / "file"
    blocker.write_text("")
    args = {"blocked": ["-o", blocker / "sub"], "empty": ["-o", ""],
            "long-name": ["--name", "x" * 100, "-o", tmp_path / "out"],
            "clk": ["--name", "clk", "-o", tmp_path / "out"]}[case]
    _check_error(kfgen_in_process("castella", *args), "--name" if "--name" in args else "-o")
    assert not (tmp_path / "out").exists()


def test_output_file_that_is_a_directory(tmp_path):
    """The error names the file in the way, and nothing in the folder changes."""
    out = tmp_path / "out"
    (out / "castella.json").mkdir(parents=True)
    (out / "castella.v").write_text("old")
    proc = kfgen_in_process("castella", "-o", out)
    _check_error(proc, "-o")
    assert f"cannot write {out / 'castella.json'}: " in proc.stderr, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["castella.json", "castella.v"]
    assert (out / "castella.v").read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out"], "no temporary folder is left beside it"


def test_failed_write_restores_replaced_files(tmp_path):
    """A failure while files are being moved into place puts back the ones already replaced."""
    from kfgen.gen.output import write_files
    from kfgen.hdl.describe import ParamError

    out = tmp_path / "keep"
    out.mkdir()
    (out / "a.v").write_text("old a")
    (out / "c.v").mkdir()
    with pytest.raises(ParamError, match=r"c\.v: "):
        write_files(out, {"a.v": "new a", "b.v": "new b", "c.v": "new c"})
    assert sorted(p.name for p in out.iterdir()) == ["a.v", "c.v"]
    assert (out / "a.v").read_text() == "old a"
    assert [p.name for p in tmp_path.iterdir()] == ["keep"]
    assert [p.name for p in write_files(out / "new", {"a.v": "x"})] == ["a.v"]
    assert (out / "new" / "a.v").read_text() == "x"


def test_lint_counts_warnings():
    """``kfgen lint``'s status line counts Verilator's warnings, not its closing line."""
    from kfgen.gen.cli import _count

    one = ["%Warning-UNUSEDSIGNAL: sloppy.v:3:14: Signal is not used: 'x'",
           "%Error: Exiting due to 1 warning(s)"]
    assert _count(one) == "1 warning"
    assert _count(one[:1] * 3 + ["%Error: sloppy.v:9:1: syntax error", "%Error: Exiting due to 1 error(s)"]) \
        == "3 warnings, 1 error"


def test_version():
    proc = kfgen("--version")
    assert proc.stdout.strip() == f"kfgen {__version__}"
    assert proc.stderr == ""


def _kfgen_help(*args) -> str:
    """``kfgen ARGS --help``'s output, through the command line's ``main`` in this process
    (argparse ends it with SystemExit 0); test_help_is_the_installed_commands runs the command."""
    import contextlib
    import io

    from kfgen.gen.cli import main
    with contextlib.redirect_stdout(io.StringIO()) as out, pytest.raises(SystemExit) as exc:
        main([*args, "--help"])
    assert exc.value.code in (0, None)
    return out.getvalue()


def test_help_is_the_installed_commands():
    assert kfgen("fpu", "--help").stdout.split() == _kfgen_help("fpu").split()  # (wrapped to other widths)


def test_help_lists_every_parameter(_written):
    top = _kfgen_help()
    for name, core in discover().items():
        assert name in top
        text = " ".join(_kfgen_help(name).split())  # undo line wrapping
        resolved = resolved_defaults(core)  # (the EKF's with its example's application)
        for f in dataclasses.fields(core.params):
            switch = f.default is True  # a switch: --no-<name>
            assert ("--no-" + option(f.name)[2:] if switch else option(f.name)) in text, f.name
            # None: worked out from the other parameters; the help gives the number for their defaults
            # (an application has none); False: a switch that is off
            shown = ("none" if f.name == "app" or f.default is None and getattr(resolved, f.name) is None else
                     f"{getattr(resolved, f.name)} (for the other options' defaults)" if f.default is None
                     else "on" if switch else "off" if f.default is False else f.default)
            assert f"default {shown}" in text, f.name
            doc = core.docs()[f.name]
            assert doc.meaning in text and doc.allowed in text and f"[{doc.unit}]" * bool(doc.unit) in text
        if name == "castella":  # RANGES are the Castella parameters' ranges
            for key, (lo, hi) in RANGES.items():
                assert str(lo) in text and str(hi) in text, key
        assert "--config" in text and "-o DIR" in text
        assert "default the unit's own" not in text, "a default is a value"
        written = re.search(r"This core writes: (.*?)\.$", text).group(1).split(", ")
        if name in ("castella", "fpu", "schur"):  # cheap to generate; the UKF's list is in HELP_DEFAULTS
            made = {p.name for p in _written(name)}
            assert {w.replace("DIR/TOP", core.params().name) for w in written} == made, name


@pytest.fixture(scope="module")
def _written(tmp_path_factory):
    """core -> the paths ``kfgen CORE -o DIR`` (default parameters) writes, generated once each."""
    done = {}

    def get(name):
        if name not in done:
            out = tmp_path_factory.mktemp(name)
            proc = kfgen_in_process(name, "-o", out)
            assert proc.returncode == 0, proc.stderr
            done[name] = list(out.iterdir())
        return done[name]
    return get


HELP_DEFAULTS = [  # (core, text its --help must hold): the latencies the units are designed with
    ("schur", "--mul-latency MUL_LATENCY multiplier latency"), ("schur", "default 7 (for the other options' defaults)"),
    ("schur", "default 6 (for the other options' defaults)"), ("schur", "default 32 (for the other options' defaults)"),
    ("fpu", "default 6 (for the other options' defaults)"),
    ("ukf", "default 2 (for the other options' defaults)"), ("ukf", "default iterative (for the other"),
    ("ukf", "default 13 (for the other options' defaults)"), ("imm", "default 2 (for the other options' defaults)"),
    ("ukf", "DIR/TOP_driver.h, DIR/TOP_driver.c"), ("ukf", "DIR/TOP_ip.tcl, DIR/TOP_driver.py, DIR/TOP.core"),
    ("imm", "DIR/TOP_ip.tcl, DIR/TOP_driver.py, DIR/TOP.core"),
    ("kf", "DIR/TOP_driver.h, DIR/TOP_driver.c"), ("ekf", "DIR/TOP_driver.h, DIR/TOP_driver.c"),
]


def _help_text(core) -> str:
    """``kfgen CORE --help`` in this process, line wrapping undone."""
    import contextlib
    import io

    from kfgen.gen.cli import main

    with contextlib.redirect_stdout(io.StringIO()) as out, pytest.raises(SystemExit) as done:
        main([core, "--help"])
    assert done.value.code == 0
    return " ".join(out.getvalue().split())


@pytest.mark.parametrize("core, expected", HELP_DEFAULTS)
def test_help_gives_resolved_defaults(core, expected):
    assert expected in _help_text(core)


# ---------------------------------------------------------------------------- generated files

@pytest.fixture(scope="module")
def default_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("default")
    proc = kfgen("castella", "-o", out)
    return out, proc


def test_prints_paths_written(default_out):
    out, proc = default_out
    assert proc.stdout.splitlines() == [str(out / name) for name in (
        "castella.v", "castella.vlt", "castella.json", "castella_tb.v", "castella.xdc", "castella.sdc",
        "castella.core")]
    assert proc.stderr == ""


def test_config_file_and_override(tmp_path):
    cfg = _toml(tmp_path, "tracks = 8\nsigma-r = 50.0\ndata_width = 20\nname = \"fromfile\"\n")
    out = tmp_path / "out"
    kfgen("castella", "--config", cfg, "--tracks", "4", "--name", "cli", "-o", out)
    manifest = json.loads((out / "cli.json").read_text())
    expect = CastellaParams(tracks=4, sigma_r=50.0, data_width=20, name="cli")
    assert manifest["parameters"] == expect.to_dict()
    assert not (out / "fromfile.json").exists()


def test_deterministic(tmp_path, default_out):
    first, _ = default_out
    second = tmp_path / "elsewhere" / "deeper"
    kfgen("castella", "-o", second)
    for name in ("castella.v", "castella.vlt", "castella.json", "castella.core", "castella.xdc", "castella.sdc",
                 "castella_tb.v"):
        a, b = (first / name).read_bytes(), (second / name).read_bytes()
        assert a == b, f"{name} differs between two runs"
        text = a.decode()
        for leak in (str(first), str(tmp_path), str(tmp_path.parent.parent), "/home/", "/tmp/", "/root/",
                     "/usr/", "site-packages"):
            assert leak not in text, f"{name} contains {leak!r}"
        assert not re.search(r"\b20\d\d-\d\d-\d\d\b|\b\d\d:\d\d:\d\d\b", text), f"{name} has a timestamp"
        assert "(* src" not in text


def test_header(default_out):
    out, _ = default_out
    text = (out / "castella.v").read_text()
    head = text[:text.index("module ")]
    assert f"kfgen {__version__}" in head
    for key, value in CastellaParams().to_dict().items():
        assert re.search(rf"//\s+{key}\s+= {re.escape(repr(value))}\n", head), key


def _modules(text):
    return re.findall(r"^\s*module\s+(\S+?)\s*[(;#]", text, re.M)


def test_modules_prefixed_by_top(tmp_path, default_out):
    out, _ = default_out
    kfgen("castella", "--tracks", "8", "--name", "castella8", "-o", tmp_path)
    one = _modules((out / "castella.v").read_text())
    eight = _modules((tmp_path / "castella8.v").read_text())
    assert one and all(m.startswith("castella") for m in one)
    assert eight and all(m.startswith("castella8") for m in eight)
    assert not set(one) & set(eight), "two configurations must be able to share one project"


@pytest.mark.parametrize("kwargs", [{}, {"tracks": 8, "name": "castella8"},
                                    {"tracks": 3, "data_width": 20, "gain_width": 10, "q_width": 5,
                                     "period": 0.5, "sigma_r": 50.0, "name": "castella_w20"}],
                         ids=["default", "tracks8", "w20"])
def test_manifest(tmp_path, kwargs):
    params = CastellaParams(**kwargs)
    args = []
    for k, v in kwargs.items():
        args += [option(k), v]
    kfgen("castella", *args, "-o", tmp_path)
    top = params.name
    manifest = json.loads((tmp_path / f"{top}.json").read_text())
    core = Castella(params)
    core._MustUse__silence = True  # built for its attributes only, never elaborated
    assert manifest["core"] == "castella"
    assert manifest["top"] == top
    assert manifest["generator"] == {"name": "kfgen", "version": __version__}
    assert manifest["parameters"] == params.to_dict()
    assert manifest["latency_cycles"] == core.latency
    assert manifest["initiation_interval"] == core.initiation_interval
    assert manifest["track_interval_cycles"] == core.track_interval
    ports = {p["name"]: p for p in manifest["ports"]}
    for name in FIELD_PORTS:
        assert ports[name]["fields"] == params.field_list(name)
        assert ports[name]["width"] == params.port_width(name)
    for name in ("s_axis_tid", "m_axis_tid"):
        assert ports[name]["width"] == params.tid_width
    for p in manifest["ports"]:
        assert set(p) == ({"name", "direction", "width", "fields"} if p["name"] in FIELD_PORTS
                          else {"name", "direction", "width"}), p["name"]
        for f in p.get("fields", []):
            assert set(f) == {"name", "lsb", "width", "signed", "frac_bits", "unit"}
    # The manifest's ports are the Verilog module's, in its order, with its widths.
    verilog = (tmp_path / f"{top}.v").read_text()
    header = re.search(rf"^module {top}\((.*?)\);", verilog, re.M | re.S).group(1)
    assert [p.strip() for p in header.split(",")] == [p["name"] for p in manifest["ports"]]
    for p in manifest["ports"]:
        rng = f"[{p['width'] - 1}:0] " if p["width"] > 1 else ""
        assert re.search(rf"^\s*{p['direction']} {re.escape(rng)}{p['name']};", verilog, re.M), p["name"]


SMALL_UKF = ("ukf", "--states", "2", "--observations", "1", "--process-noise", "1", "--measurement-noise", "1")


def test_unreachable_target_mhz_warns(tmp_path):
    """A --target-mhz the delay model predicts the core misses: generated (exit 0), with one
    warning line naming the predicted Fmax, and the manifest's met: false."""
    proc = kfgen_in_process(*SMALL_UKF, "--target-mhz", "1000", "-o", tmp_path / "fast")
    timing = json.loads((tmp_path / "fast" / "ukf.json").read_text())["timing"]
    assert proc.returncode == 0 and timing["met"] is False
    assert proc.stderr == (f"kfgen: warning: --target-mhz: 1000 MHz is above the predicted Fmax of "
                           f"{timing['predicted_fmax_mhz']:g} MHz; the core is generated (its manifest's timing: "
                           "met false)\n")
    proc = kfgen_in_process(*SMALL_UKF, "--target-mhz", "50", "-o", tmp_path / "slow")
    assert proc.returncode == 0 and proc.stderr == ""


@pytest.mark.parametrize("fmt", ["e3m2", "e4m10", "e8m3"])
def test_ukf_format_below_the_floor_exits_2(tmp_path, fmt):
    """A format too narrow for the filter (kfgen.hdl.ukf.params.FORMAT_FLOOR): one line, exit 2,
    nothing written; --help states the floor and its reason."""
    proc = kfgen_in_process("ukf", "--format", fmt, "-o", tmp_path / "x")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert proc.stderr.startswith(f"kfgen: error: --format: {fmt} is too narrow for the filter to work; it needs "
                                  "at least 5 exponent and 4 fraction bits")
    assert not (tmp_path / "x").exists()


def test_ukf_help_states_the_format_floor():
    text = " ".join(kfgen("ukf", "--help").stdout.split())
    assert "at least 5 exponent and 4 fraction bits: below them" in text and "test_format_floor.py" in text
