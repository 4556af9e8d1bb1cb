"""One generation builds each heavy object once: the register map, the programs, the machine
and the application's trace, whoever asks for them (validation, the component, the
manifest, the documents)."""

from collections import Counter

import kfgen.hdl.engine.machine as engine_machine
import kfgen.hdl.imm.regmap as imm_regmap
import kfgen.hdl.imm.steps as imm_steps
import kfgen.hdl.ukf.models as ukf_models
import kfgen.hdl.ukf.regmap as ukf_regmap
import kfgen.hdl.ukf.steps as ukf_steps
from kfgen.gen.api import generate_core
from kfgen.hdl.describe import _BUILT, once_per_params


def _counted(monkeypatch, module, name, counts):
    real = getattr(module, name)

    def counted(*args, **kwargs):
        counts[name] += 1
        return real(*args, **kwargs)
    monkeypatch.setattr(module, name, counted)


def test_a_streams_generation_builds_each_once(monkeypatch):
    """``kfgen ukf --app tracker:Tracker --on-chip --streams --target-mhz 150`` through the API:
    the map (validation, core, manifest, documents), the programs (core, stream documents),
    the machine (schedules, timing) and the trace of f and h, each once."""
    counts = Counter()
    for module, name in ((ukf_regmap, "place_map"), (ukf_steps, "build_ukf"), (engine_machine, "Machine"),
                         (ukf_models, "trace")):
        _counted(monkeypatch, module, name, counts)
    ukf_models.compile_models.cache_clear()
    made = generate_core("ukf", app="tracker:Tracker", on_chip=True, streams=True, target_mhz=150)
    assert made.manifest["streams"] and made.manifest["timing"]
    assert counts == {"place_map": 1, "build_ukf": 1, "Machine": 1, "trace": 2}  # f and h


def test_an_imm_generation_builds_each_once(monkeypatch):
    """``kfgen imm --models 2 --states 2 --measurements 1 --target-mhz 150`` through the
    API: the map (validation, core, manifest, documents), the program (core, waivers) and
    the machine (schedules, timing), each once."""
    counts = Counter()
    for module, name in ((imm_regmap, "place_map"), (imm_steps, "build_imm"), (engine_machine, "Machine")):
        _counted(monkeypatch, module, name, counts)
    made = generate_core("imm", models=2, states=2, measurements=1, target_mhz=150)
    assert made.manifest["timing"]
    assert counts == {"place_map": 1, "build_imm": 1, "Machine": 1}


def test_once_per_params_keeps_by_identity():
    """Equal objects build their own; what one built goes with it."""
    calls = Counter()

    @once_per_params
    def built(params):
        calls[id(params)] += 1
        return object()

    class P:
        pass

    a, b = P(), P()
    assert built(a) is built(a) and built(b) is not built(a) and set(calls.values()) == {1}
    key = id(a)
    del a
    assert key not in _BUILT
