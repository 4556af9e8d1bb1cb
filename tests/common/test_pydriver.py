"""The generated Python driver ``TOP_driver.py`` (:mod:`kfgen.gen.pydriver`) as a module: its
number packing against the simulation's own ``to_words``/``from_words`` for every kind of format
the engine takes, its VLNV against ``TOP.xml``'s, PYNQ's ``DefaultIP`` when PYNQ is there and the
fallback when it is not, and its errors (WrongCore, CoreFault, CoreTimeout) on the KF's golden
device. Each core's run of the driver on its golden device is in its own tests
(``tests/<core>/test_<core>_driver.py``), on the RTL in the cocotb runs."""

import math
import re
import sys
import types
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from kfgen.gen.ipxact import SPIRIT, component, vlnv
from kfgen.gen.pydriver import TAKEN, class_name, text
from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.kf.params import KfParams
from kfgen.hdl.kf.steps import programs
from kfgen.sim.engine.device import GoldenDevice
from kfgen.sim.kf.tb import system
from kfgen.sim.linalg.exec import from_words, to_words

from helpers import ROOT, python_driver

KF = dict(states=3, measurements=2, inputs=1, pes=1)


@pytest.fixture(scope="module")
def kf(tmp_path_factory):
    """(manifest, module) of a small KF's driver."""
    return python_driver(tmp_path_factory.mktemp("pydriver"), "kf", name="kf_drv", **KF)


def _values(fmt: FloatFormat, rng) -> list[float]:
    """Specials, the format's edges and ties, and random values across its range (and past it)."""
    M, emin, emax = fmt.frac_bits, fmt.emin, fmt.emax
    ulp = 2.0 ** (emin - M)
    edges = [0.0, -0.0, math.inf, -math.inf, math.nan, 1.0, -1.5, 1.0 + 2.0 ** -(M + 1),  # a tie, to even
             1.0 + 3 * 2.0 ** -(M + 1), ulp, ulp / 2, ulp * 1.5, -ulp / 3, 2.0 ** emin, 2.0 ** emin - ulp / 2]
    if emax < 1023:
        top = 2.0 ** emax * (2 - 2.0 ** -M)
        edges += [top, top * (1 + 2.0 ** -(M + 2)), 2.0 ** (emax + 1), -(2.0 ** emax) * (2 - 2.0 ** -(M + 1))]
    span = min(emax, 1000)
    return edges + list(rng.normal(size=200) * 2.0 ** rng.integers(max(emin - M - 2, -1070), span + 2, 200))


@pytest.mark.parametrize("name", ["binary16", "bfloat16", "binary32", "binary64", "e5m2", "e3m2", "e8m40",
                                  "e9m54", "e15m48", "e6m11"])
def test_packing_is_the_simulations(kf, name):
    """Every value rounds to the simulation's word (the numpy path of binary16/32/64 and the
    integer path of every format); words read back as the simulation's values."""
    _, drv = kf
    fmt = FloatFormat.parse(name)
    saved = drv.FORMAT
    drv.FORMAT = {"name": name, "exp_bits": fmt.exp_bits, "frac_bits": fmt.frac_bits, "words": 1 + (fmt.width > 32)}
    try:
        values = _values(fmt, np.random.default_rng(fmt.width))
        want = to_words(fmt, values)
        bus = drv.to_words(values)
        got = [lo | hi << 32 for lo, hi in zip(bus[::2], bus[1::2])] if fmt.width > 32 else bus
        assert got == want
        assert [drv._word(v) for v in values] == want  # the integer path on the numpy formats too
        if fmt.emax <= 1023 and fmt.precision <= 53:  # float64 holds every value exactly
            words = want + [int(w) for w in np.random.default_rng(1).integers(0, 1 << fmt.width, 200, dtype=np.uint64)]
            back = drv.from_words([h for w in words for h in ((w & 0xFFFFFFFF, w >> 32) if fmt.width > 32 else (w,))])
            expect = from_words(fmt, words)
            assert all(a == b or (math.isnan(a) and math.isnan(b)) for a, b in zip(back, expect))
    finally:
        drv.FORMAT = saved


def test_vlnv_is_the_ip_xact_components(kf):
    man, drv = kf
    root = ET.fromstring(component("kf_drv", "summary", man))
    vlnv = ":".join(root.find(f"{{{SPIRIT}}}{k}").text for k in ("vendor", "library", "name", "version"))
    assert drv.kf_drv.bindto == [vlnv] == [drv.VLNV]
    assert text("kf_drv", man) == text("kf_drv", man)  # deterministic


def test_without_pynq_an_ip_description_is_refused(kf):
    _, drv = kf
    assert "pynq" not in sys.modules
    with pytest.raises(TypeError, match="PYNQ is not installed"):
        drv.kf_drv({"phys_addr": 0x40000000, "addr_range": 0x10000})


def test_with_pynq_the_class_is_a_default_ip(kf, tmp_path, monkeypatch):
    """With PYNQ importable, the class subclasses its DefaultIP, which maps the core from the
    overlay's description."""
    man, _ = kf
    dev = GoldenDevice(man, KfParams, programs)
    pynq = types.ModuleType("pynq")

    class DefaultIP:
        def __init__(self, description):
            self.mmio = description["mmio"]  # (PYNQ's makes an MMIO of phys_addr, addr_range)
    pynq.DefaultIP = DefaultIP
    monkeypatch.setitem(sys.modules, "pynq", pynq)
    path = tmp_path / "kf_drv_driver.py"
    path.write_text(text("kf_drv", man))
    namespace = {"__name__": "kf_drv_driver"}
    exec(compile(path.read_text(), str(path), "exec"), namespace)
    core = namespace["kf_drv"]({"mmio": dev})
    assert isinstance(core, DefaultIP) and core.mmio is dev
    assert dev.accesses[:2] == [("r", 0, dev.ident & 0xFFFFFFFF), ("r", 4, dev.ident >> 32)]


def test_wrong_core(kf):
    man, drv = kf
    dev = GoldenDevice(man, KfParams, programs)
    dev.ident ^= 1 << 33  # n = 3 reads as 1
    with pytest.raises(drv.WrongCore, match=r"n 1 \(expected 3\)") as info:
        drv.kf_drv(dev)
    assert info.value.found == {"n": 1} and info.value.expected == {"n": 3}


def test_fault_and_status(kf):
    """R not positive definite: CoreFault with err_pivot, STATUS cleared after it."""
    man, drv = kf
    dev = GoldenDevice(man, KfParams, programs)
    core = drv.kf_drv(dev)
    p = KfParams(**man["parameters"])
    values = system(p, np.random.default_rng(2))
    values["R"] = -np.eye(p.m) * 50.0
    core.load(**{arg: values[name] for arg, name, _ in drv.LOAD})
    with pytest.raises(drv.CoreFault, match="iterate raised err_pivot") as info:
        core.step(np.ones(p.m), np.zeros(p.nu))
    assert info.value.bits == ["err_pivot"] and info.value.status["done"] == 1
    assert core.status == dict.fromkeys(("busy", "done", "err_pivot", "err_nan", "err_busy"), 0)
    with pytest.raises(ValueError, match="takes a control input u"):
        core.step(np.ones(p.m))
    with pytest.raises(ValueError, match=r"F holds 3 x 3 values, not 4"):
        core.write_region("F", np.ones(4))


def test_timeout_bounds_the_wait(kf):
    man, drv = kf

    class Stuck(GoldenDevice):
        def _start(self, word):
            self.status = 1  # busy, forever

    dev = Stuck(man, KfParams, programs)
    core = drv.kf_drv(dev)
    before = len(dev.accesses)
    with pytest.raises(drv.CoreTimeout, match=f"not done after {drv.POLLS} reads"):
        core.run("iterate")
    reads = [a for a in dev.accesses[before:] if a[0] == "r"]
    assert len(reads) == drv.POLLS == 2 * sum(man["cycles"].values()) + 1000


def test_class_name_never_hides_a_module_name(tmp_path, kf):
    _, module = kf
    assert {k for k in vars(module) if not k.startswith("__")} - {"kf_drv"} == TAKEN  # every name it defines
    assert class_name("kf_small") == "kf_small"
    assert class_name("match") == "match_core" and class_name("lambda") == "lambda_core"
    assert {class_name(t) for t in TAKEN} == {f"{t}_core" for t in TAKEN}
    man, drv = python_driver(tmp_path, "kf", name="np", **KF)
    assert drv.np_core.bindto == [drv.VLNV] and drv.np is np


def test_the_docs_pynq_example_runs(tmp_path, monkeypatch):
    """docs/vendor-flows.md's notebook, on a stand-in for PYNQ: its DefaultIP registers every
    subclass's ``bindto`` as PYNQ's does, its Overlay gives each IP of the design (here the
    core as TOP_ip.tcl names it, ``TOP_0``) as an object of the class bound to its VLNV, with
    the golden device as its MMIO."""
    code = re.search(r"^```python\n(# on the Zynq board.*?)^```", (ROOT / "docs" / "vendor-flows.md").read_text(),
                     re.M | re.S).group(1)
    command = re.search(r"^kfgen kf (.*) -o out/kf_small$", (ROOT / "docs" / "vendor-flows.md").read_text(), re.M)
    args = command.group(1).split()
    assert args == ["--states", "4", "--measurements", "2", "--inputs", "1", "--pes", "2", "--streams", "--name",
                    "kf_small"]
    man, _ = python_driver(tmp_path, "kf", states=4, measurements=2, inputs=1, pes=2, streams=True, name="kf_small")
    device = GoldenDevice(man, KfParams, programs)
    man_vlnv = vlnv("kf_small")
    bound = {}
    pynq = types.ModuleType("pynq")

    class DefaultIP:
        def __init_subclass__(cls, **kwargs):
            super().__init_subclass__(**kwargs)
            for vlnv in getattr(cls, "bindto", ()):
                bound[vlnv] = cls

        def __init__(self, description):
            self.mmio = description["mmio"]

    class Overlay:
        def __init__(self, bitfile):
            assert bitfile == "design.bit"

        def __getattr__(self, name):
            assert name == "kf_small_0", name
            return bound[man_vlnv]({"mmio": device})

    pynq.DefaultIP, pynq.Overlay = DefaultIP, Overlay
    monkeypatch.setitem(sys.modules, "pynq", pynq)
    monkeypatch.delitem(sys.modules, "kf_small_driver", raising=False)
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    namespace = {"__name__": "notebook"}
    exec(compile(code, "vendor-flows.md example", "exec"), namespace)
    assert device.steps == ["iterate"] * 5
    x, P = namespace["x"], namespace["P"]
    assert np.array_equal(x, device.values("x").ravel()) and np.array_equal(P, device.values("P"))
    assert namespace["kf"].last_status["done"] == 1
    sys.modules.pop("kf_small_driver", None)  # (imported by the notebook from tmp_path)
