"""The cores as the generator finds them: one descriptor each, and netlists that do not drift."""

import dataclasses
import hashlib

import pytest

from kfgen.gen.cli import generate
from kfgen.gen.cores import discover
from kfgen.hdl.describe import RESERVED_WORDS, CoreDescriptor, ParamError, check_name

#: sha256 of the Verilog below its header comment, per example configuration (``make verilog``).
#: A change here is a change of the generated netlist: make it on purpose, and say so.
NETLISTS = {
    "castella": "ef05fd63074557751f76e783be018eeec355ee5d600346f626a6c9aabdb6f162",
    "castella8": "9e8de5dc0ad2a1fd8719a0efafc756b38cb570418772032192bc74bff5e3be80",
    "ekf": "ee2d8cbcb935bc1c48d7779e3b0d16acce27d2873d0eb958ee72fece19620d03",
    "fpu_add": "813fd0acf13b8fa1073da173466658b5de1c5fcb8f6a95254f77e250367c45a9",
    "fpu_div": "2b9c2787f9d4010536c13b5cd2d835deee2fd64ee8011b40e7d2e782417e6788",
    "fpu_exp": "d84b24fa3340f99d8e9e70e0be98cd97c8dc63e0a9d30f49ed5a32fc73fb2344",
    "fpu_f2i": "1b745472e3ecd97df70eaec4d01a77fca45ad8095a8cb47234dde7928ccbe84c",
    "fpu_fma": "c7abda6325b4b0e0c5de22e8b2480f7eb0e5e527d712505e6e9a18514b5c9813",
    "fpu_i2f": "3b5e399f4db9731fd98f60ae6a0d1b402f46e82d9ef794d2893e175abf0aed1d",
    "fpu_mul": "4e63bc87d479266d52cb587dc406803a3dd42ba600efc6751d89ae68e2c47aee",
    "fpu_sqrt": "0c09a7a131a064d0a361ab68fea53983e4f94afcb08c97acb9994081230d7988",
    "fpu_sin": "68b2c8e493e44137dc69ee399e5da2e25d57ffbc18be5b7f65658d16e00471f1",
    "fpu_cos": "be902df51fd4e178ace479cde29c41246759ab4de3667601e6c61c98951cee1e",
    "fpu_atan2": "0afd138e5bb08c54ba22eaa1103828b67f842228afa958c5bb8acafe33ad0d41",
    "fpu_sub": "344792bc3ff97dda64640f5e639075a0c531c82e6cee8ab02077f81bf4721fdc",
    "imm": "e172b2f77b0cdce7e12f57e3b9f15e0830c114ecbbb679b885a44e1347b9a0ca",
    "kf": "7b4cd2937bf50a2a6ad43062500687f3c2f09b83f0325688b34ac7973dca34b2",
    "kf_steady": "6d5f6ee34cb0661b600fb919cf2bd2713024bb47a4a017b3d8ce078422d1e643",
    "schur": "103f85caa5d1c231b094147f014decdfcb5061a06228c15b80c5ce611eaa1ae5",
    "ukf": "dcf287fd9c81cf33169e2291bd418492dc3bb82f5ccd634554e36405d3c35b8a",
}

EXAMPLES = [(core, ex) for core in discover().values() for ex in core.examples]


def test_every_core_is_found_once():
    cores = discover()
    assert list(cores) == sorted(cores) and {"castella", "fpu"} <= set(cores)
    for name, core in cores.items():
        assert isinstance(core, CoreDescriptor) and core.name == name


@pytest.mark.parametrize("core", discover().values(), ids=list(discover()))
def test_descriptor_documents_every_parameter(core):
    fields = [f.name for f in dataclasses.fields(core.params)]
    docs = core.docs()
    assert list(docs) == fields, "one Doc per parameter, in the dataclass's order"
    for name, doc in docs.items():
        assert doc.meaning and doc.allowed, name
    assert "name" in fields and core.examples
    names = [core.params(**ex).name for ex in core.examples]
    assert len(set(names)) == len(names), "each example needs its own directory"


# The FPU's twelve examples in make test-full (15 s; their units' tests run in make test).
@pytest.mark.parametrize("core, example", [(c, ex) if c.name != "fpu" else pytest.param(c, ex, marks=pytest.mark.full)
                                           for c, ex in EXAMPLES],
                         ids=[core.params(**ex).name for core, ex in EXAMPLES])
def test_example_netlists_are_unchanged(core, example):
    params = core.params(**example)
    text = generate(core, params)[f"{params.name}.v"]
    body = text[text.index("\n\n") + 2:]  # below the header comment (versions, parameters)
    assert hashlib.sha256(body.encode()).hexdigest() == NETLISTS[params.name], \
        f"the Verilog of {params.name} changed"
    assert set(NETLISTS) == {core.params(**ex).name for core, ex in EXAMPLES}


@pytest.mark.parametrize("name", ["module", "wire", "logic", "always_ff", "interface", "9x", "a-b", "", "é", None])
def test_check_name_rejects(name):
    with pytest.raises(ParamError) as info:
        check_name(name)
    assert info.value.param == "name"


def test_check_name_accepts_identifiers():
    for name in ("castella", "Module", "_x", "wire1", "my_core_2"):
        check_name(name)
    assert {"module", "wire", "reg", "logic", "always_ff", "always_comb", "bit", "int"} <= RESERVED_WORDS
