"""``make bench``'s IMM part without synthesis or simulation: its notes for a core built for a
clock (``--target-mhz``), on made-up rows."""

from types import SimpleNamespace

from kfgen.gen.bench_imm import render

ENGINE = {"fma_latency": 14, "div_latency": 32, "sqrt_latency": 29, "exp_latency": 18, "unit_register": 1,
          "read_latency": 3, "banks": 2, "program_store": {"bits": 36864}, "memory_words": 1024}
TIMING = {"target_mhz": 125.0, "predicted_fmax_mhz": 110.2, "met": False, "fetch_register": True,
          "units": {"fma": {"stages": 14, "predicted_fmax_mhz": 126.5},
                    "exp": {"stages": 18, "predicted_fmax_mhz": 110.2}}}


def row(R, overhead=7, **more):
    return {"R": R, "pes": 1, "cycles": 5294, "bounds": {"fma": 4816, "fma_per_pe": 4816, "chain": 1187},
            "engine": ENGINE, "div_sqrt": "iterative", "overhead": overhead, **more}


def test_target_notes():
    args = SimpleNamespace(freq=125.0, seeds=[1], out="build/bench_imm")
    text = render([row(2, timing=TIMING), row(5, timing=TIMING, fmax_mhz=104.5, fmax_best_mhz=104.5,
                                                  utilization={"TRELLIS_COMB": 1})], args, {"all": 1.0})
    assert "The cycles include 7 per iteration for the start register, the program store's fetch lead and fetch " \
        "register, the last write's lane register" in text
    # the target's note for the largest R only; the iteration at Fmax: 5,294 cycles at 104.5 MHz
    assert text.count("--target-mhz 125: ") == 1
    assert "* R = 5, P = 1: --target-mhz 125: FMA 14 stages (126.5 MHz), exponential 18 stages (110.2 MHz), the " \
        "program store's fetch register (a step a cycle longer); predicted Fmax 110.2 MHz" in text
    assert "| 5 | 1 | 104.5 | 104.5 | 1 | 0 | 0 | 0 | 50.7 |" in text
    assert "fetch register" not in render([row(5, overhead=6)], args, {})
