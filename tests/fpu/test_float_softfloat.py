"""The exact floating-point reference (kfgen.sim.float_ref) against Berkeley SoftFloat 3.

SoftFloat is the engine of TestFloat, the field's conformance reference; ``softfloatpy`` wraps
it. Every operation (add, sub, mul, div, sqrt, fma, i2f, f2i) in binary16, binary32 and binary64
is run on float_ref's directed corpus, its conversion boundary sweeps and seeded random operand
sets, and the result word and all five flags (NX UF OF DZ NV) must be equal.

SoftFloat is set up as float_ref is specified:

* rounding: round to nearest, ties to even;
* tininess: detected **after** rounding (float_ref's choice, which IEEE 754 allows next to
  "before rounding"; RISC-V and ARM detect after, x86 before). ``test_tininess_mode_matters``
  shows that the directed corpus would catch the other mode (mul and fma; the modes cannot
  differ on the other operations).

No deliberate difference remains, so words are compared bit for bit, NaNs included. The wheel is
built with SoftFloat's RISC-V specialization (``test_softfloat_is_the_riscv_specialization``):
every NaN result is the canonical quiet NaN (no payload propagation, as in float_ref), 0 * inf
+ qNaN in fma is invalid, and f32_to_i32 saturates like RISC-V ``fcvt.w`` (NaN and +overflow to
2**31 - 1, -overflow to -2**31, NV alone). Another specialization (8086-SSE propagates payloads
and returns -2**31 for NaN and +overflow) would make that test fail.

f2i maps to ``fN_to_i32(x, NEAR_EVEN, exact=True)``: ``exact=True`` raises NX for an inexact
conversion, as float_ref (and ``fcvt.w``) do; ``exact=False`` would suppress it.

Out of scope: float_ref's ``subnormals="ftz"`` mode. SoftFloat has no flush-to-zero or
denormals-are-zero mode, so ftz is checked only by tests/test_float_ref.py.
"""

import zlib

import numpy as np
import pytest
import softfloatpy as sf

from kfgen.hdl.arith.float.format import (FLAG_DZ, FLAG_NAMES, FLAG_NV, FLAG_NX, FLAG_OF, FLAG_UF,
                                          FloatFormat)
from kfgen.sim.float_ref import (INT32_MAX, INT32_MIN, OPS, conversion_sweep, directed_corpus,
                                 random_operands, ref_op)

B16, B32, B64 = (FloatFormat.parse(n) for n in ("binary16", "binary32", "binary64"))
FORMATS = [B16, B32, B64]
PREFIX = {B16: "f16", B32: "f32", B64: "f64"}
CLASS = {B16: sf.Float16, B32: sf.Float32, B64: sf.Float64}
FUNC = {"add": "add", "sub": "sub", "mul": "mul", "div": "div", "sqrt": "sqrt", "fma": "mul_add"}
# SoftFloat's flag names against ours (the bit values happen to agree; the map does not rely on it).
FLAG_MAP = ((sf.ExceptionFlag.INEXACT, FLAG_NX), (sf.ExceptionFlag.UNDERFLOW, FLAG_UF),
            (sf.ExceptionFlag.OVERFLOW, FLAG_OF), (sf.ExceptionFlag.INFINITE, FLAG_DZ),
            (sf.ExceptionFlag.INVALID, FLAG_NV))
MASK32 = (1 << 32) - 1
N_RANDOM = 5000  # per format and op in the default run
N_FULL = 200_000  # per format and op with --full

fmt_ids = pytest.mark.parametrize("fmt", FORMATS, ids=lambda f: f.name)


@pytest.fixture(autouse=True)
def softfloat_modes():
    """Round to nearest even, tininess after rounding; SoftFloat's global modes restored after."""
    saved = sf.get_rounding_mode(), sf.get_tininess_mode(), sf.get_exception_flags()
    sf.set_rounding_mode(sf.RoundingMode.NEAR_EVEN)
    sf.set_tininess_mode(sf.TininessMode.AFTER_ROUNDING)
    yield
    sf.set_rounding_mode(saved[0])
    sf.set_tininess_mode(saved[1])
    sf.set_exception_flags(saved[2])


def softfloat_op(op, fmt, *operands):
    """``(word, flags)`` from SoftFloat, in float_ref's conventions (f2i: a 32-bit word)."""
    nbytes = fmt.width // 8
    sf.set_exception_flags(0)
    if op == "i2f":
        v = operands[0]
        r = getattr(sf, f"i32_to_{PREFIX[fmt]}")(sf.Int32.from_int(v - (v >> 31 << 32)))
    else:
        xs = [CLASS[fmt].from_bytes(w.to_bytes(nbytes, "big")) for w in operands]
        if op == "f2i":
            r = getattr(sf, f"{PREFIX[fmt]}_to_i32")(xs[0], sf.RoundingMode.NEAR_EVEN, True)
        else:
            r = getattr(sf, f"{PREFIX[fmt]}_{FUNC[op]}")(*xs)
    raised = sf.get_exception_flags()
    flags = sum(ours for theirs, ours in FLAG_MAP if raised & theirs)
    word = r.to_int() & MASK32 if op == "f2i" else int.from_bytes(r.to_bytes(), "big")
    return word, flags


def flag_names(flags):
    return "|".join(n for i, n in enumerate(FLAG_NAMES) if flags >> i & 1) or "-"


def mismatches(fmt, op, sets):
    """Every operand set where float_ref and SoftFloat differ, as lines (all of them counted)."""
    digits = (fmt.width + 3) // 4
    bad = []
    for s in sets:
        ours, theirs = ref_op(op, fmt, *s), softfloat_op(op, fmt, *s)
        if ours != theirs:
            w = 8 if op == "i2f" else digits
            bad.append(f"{op}({', '.join(f'{x:0{w}x}' for x in s)}): float_ref {ours[0]:x} "
                       f"{flag_names(ours[1])}, SoftFloat {theirs[0]:x} {flag_names(theirs[1])}")
    return bad


def assert_agree(fmt, op, sets):
    bad = mismatches(fmt, op, sets)
    assert not bad, (f"{len(bad)} of {len(sets)} {fmt.name} {op} operand sets differ "
                     f"(first 10):\n" + "\n".join(bad[:10]))


def random_sets(fmt, op, n, tag):
    rng = np.random.default_rng(zlib.crc32(repr((fmt.name, op, tag)).encode()))
    return random_operands(fmt, n, rng, op)


def boundary_sets(fmt, op):
    """float_ref's directed corpus, and for conversions its boundary sweep too."""
    sets = directed_corpus(fmt, op)
    if op in ("i2f", "f2i"):
        sets += conversion_sweep(fmt, op)
    return sets


@pytest.mark.parametrize("op", list(OPS))
@fmt_ids
def test_directed_against_softfloat(fmt, op):
    assert_agree(fmt, op, boundary_sets(fmt, op))


@pytest.mark.parametrize("op", list(OPS))
@fmt_ids
def test_random_against_softfloat(fmt, op):
    assert_agree(fmt, op, random_sets(fmt, op, N_RANDOM, "default"))


@pytest.mark.parametrize("op", ["sqrt", "f2i"])
def test_binary16_unary_exhaustive(op):
    assert_agree(B16, op, [(w,) for w in range(1 << 16)])


@pytest.mark.full
@pytest.mark.parametrize("op", list(OPS))
@fmt_ids
def test_random_against_softfloat_full(fmt, op):
    assert_agree(fmt, op, random_sets(fmt, op, N_FULL, "full"))


@pytest.mark.parametrize("op", ["mul", "fma"])
@fmt_ids
def test_tininess_mode_matters(fmt, op):
    """The directed corpus tells the two tininess modes apart, by UF alone.

    Only a product can land between the largest subnormal and 2**emin and round up to 2**emin
    (tiny before rounding, not after): a sum of tiny values is exact, a square root is never
    tiny, and no quotient of two words falls close enough below 2**emin. For example binary32
    00800001 * 3f7ffffe = 2**-126 (1 - 2**-46) rounds to 00800000; tiny before rounding, it
    would raise UF. Random operand sets hit such a product a few times in 20000 at most.
    """
    sets = directed_corpus(fmt, op)
    sf.set_tininess_mode(sf.TininessMode.BEFORE_ROUNDING)
    before = [softfloat_op(op, fmt, *s) for s in sets]
    sf.set_tininess_mode(sf.TininessMode.AFTER_ROUNDING)
    ours = [ref_op(op, fmt, *s) for s in sets]
    differ = [(s, o, b) for s, o, b in zip(sets, ours, before) if o != b]
    assert len(differ) >= 8
    assert all(o[0] == b[0] and o[1] ^ b[1] == FLAG_UF and not o[1] & FLAG_UF for _, o, b in differ)
    if fmt == B32 and op == "mul":
        assert ((0x00800001, 0x3F7FFFFE), (0x00800000, FLAG_NX), (0x00800000, FLAG_UF | FLAG_NX)) in differ


# (op, fmt, operand, word, flags) both references must give: the cases where SoftFloat's
# specializations differ from one another.
RISCV_CASES = [
    ("add", B32, (0x7FC00001, 0x3F800000), 0x7FC00000, 0),  # qNaN payload dropped
    ("add", B32, (0xFFC00000, 0x3F800000), 0x7FC00000, 0),  # the canonical NaN is positive
    ("mul", B32, (0x3F800000, 0xFF800001), 0x7FC00000, FLAG_NV),  # sNaN
    ("add", B16, (0x7E01, 0x3C00), 0x7E00, 0),
    ("add", B64, (0x7FF8000000000001, 0x3FF0000000000000), 0x7FF8000000000000, 0),
    ("fma", B32, (0x00000000, 0x7F800000, 0x7FC00000), 0x7FC00000, FLAG_NV),  # 0 * inf + qNaN
    ("f2i", B32, (0x7FC00000,), INT32_MAX, FLAG_NV),
    ("f2i", B32, (0xFFC00000,), INT32_MAX, FLAG_NV),  # a NaN's sign does not matter
    ("f2i", B32, (0x7F800001,), INT32_MAX, FLAG_NV),
    ("f2i", B32, (0x7F800000,), INT32_MAX, FLAG_NV),
    ("f2i", B32, (0xFF800000,), INT32_MIN & MASK32, FLAG_NV),
    ("f2i", B32, (0x4F000000,), INT32_MAX, FLAG_NV),  # 2**31: out of range, NV without NX
    ("f2i", B32, (0xCF000001,), INT32_MIN & MASK32, FLAG_NV),
    ("f2i", B64, (0x41DFFFFFFFE00000,), INT32_MAX, FLAG_NV),  # 2**31 - 1/2 rounds out of range
    ("f2i", B64, (0xC1E0000000100000,), INT32_MIN & MASK32, FLAG_NX),  # -(2**31 + 1/2) rounds in
    ("f2i", B16, (0xFC00,), INT32_MIN & MASK32, FLAG_NV),
    ("f2i", B16, (0x7BFF,), 65504, 0),  # binary16 never overflows an int32
]


@pytest.mark.parametrize("op, fmt, operands, word, flags", RISCV_CASES,
                         ids=[f"{c[1].name}-{c[0]}-{'-'.join(f'{x:x}' for x in c[2])}"
                              for c in RISCV_CASES])
def test_softfloat_is_the_riscv_specialization(op, fmt, operands, word, flags):
    """The NaN and saturation results that make word-for-word comparison possible."""
    assert softfloat_op(op, fmt, *operands) == (word, flags)
    assert ref_op(op, fmt, *operands) == (word, flags)


def test_f2i_exact_false_would_drop_inexact():
    """Why f2i calls SoftFloat with exact=True: float_ref raises NX for 2.5 -> 2."""
    sf.set_exception_flags(0)
    assert sf.f32_to_i32(CLASS[B32].from_bytes(bytes.fromhex("40200000")), sf.RoundingMode.NEAR_EVEN,
                         False).to_int() == 2
    assert sf.get_exception_flags() == 0
    assert softfloat_op("f2i", B32, 0x40200000) == ref_op("f2i", B32, 0x40200000) == (2, FLAG_NX)
