"""Exact rounding of a rational magnitude to a :class:`~.format.FloatFormat` word: the one
rounding that the generator (constants of the engine's programs), the exact reference model
(:mod:`kfgen.sim.float_ref`, whose docstring gives the rules) and the golden models share.

Pure Python (no Amaranth): round to nearest, ties to even; tininess after rounding; overflow
to infinity; flags in RISC-V ``fflags`` order (NX, UF, OF, DZ, NV = bits 0..4).
"""

from __future__ import annotations

from functools import lru_cache
from numbers import Rational

from .format import FLAG_NX, FLAG_OF, FLAG_UF, FloatFormat

__all__ = ["FormatConsts", "format_consts", "round_magnitude", "round_to_format"]


class FormatConsts:
    """A format's constants as plain attributes (property look-ups cost per operation)."""

    __slots__ = ("fmt", "fb", "p", "bias", "emin", "emax", "sshift", "emask", "fmask", "hidden",
                 "qbit", "sub_exp", "inf_mag", "nan", "limit")

    def __init__(self, fmt: FloatFormat):
        self.fmt = fmt
        self.fb = fmt.frac_bits
        self.p = fmt.precision
        self.bias = fmt.bias
        self.emin = fmt.emin
        self.emax = fmt.emax
        self.sshift = fmt.width - 1
        self.emask = fmt.exp_max_field
        self.fmask = fmt.frac_mask
        self.hidden = 1 << fmt.frac_bits
        self.qbit = fmt.quiet_bit
        self.sub_exp = fmt.emin - fmt.frac_bits  # weight of a subnormal's LSB
        self.inf_mag = fmt.inf(0)
        self.nan = fmt.canonical_nan
        self.limit = 1 << fmt.width


@lru_cache(maxsize=None)
def format_consts(fmt) -> FormatConsts:
    """The :class:`FormatConsts` of ``fmt`` (a FloatFormat or its name), cached."""
    return FormatConsts(FloatFormat.parse(fmt))


def round_magnitude(k: FormatConsts, sign: int, mant: int, exp: int, sticky: bool, ftz: bool):
    """Round the magnitude ``(mant + t) * 2**exp`` (``0 < t < 1`` if ``sticky`` else ``t = 0``).

    ``mant > 0``; with ``sticky``, ``mant`` must have at least ``p + 2`` bits so that the
    guard bit is in ``mant`` and the sticky bit only breaks ties.
    """
    n = mant.bit_length()
    top = exp + n - 1  # 2**top <= magnitude < 2**(top + 1)
    emin = k.emin
    tiny = False
    if top < emin:
        tiny = True
        if top == emin - 1:
            # Not tiny after all if rounding to p bits with an unbounded exponent carries to
            # 2**emin: the p significant bits and the guard bit below them are all ones.
            r = n - k.p
            if r > 0 and mant >> (r - 1) == (k.hidden << 2) - 1:
                tiny = False
        if tiny and ftz:
            return sign << k.sshift, FLAG_UF | FLAG_NX
        lsb = k.sub_exp
        scale = 0
    else:
        lsb = top - k.fb
        scale = top + k.bias - 1
    r = lsb - exp
    if r <= 0:
        q = mant << -r
        inexact = False
    else:
        q = mant >> r
        rem = mant & ((1 << r) - 1)
        half = 1 << (r - 1)
        if rem > half or (rem == half and (sticky or q & 1)):
            q += 1
        inexact = bool(rem) or sticky
    # The hidden bit adds one to the exponent field, so a carry out of the significand
    # (q == 2**p, or 2**fb for a subnormal) lands on the next binade by itself.
    mag = (scale << k.fb) + q
    if mag >= k.inf_mag:
        return sign << k.sshift | k.inf_mag, FLAG_OF | FLAG_NX
    if not inexact:
        return sign << k.sshift | mag, 0
    return sign << k.sshift | mag, (FLAG_UF | FLAG_NX) if tiny else FLAG_NX


def round_to_format(fmt: FloatFormat, sign: int, value, subnormals: str = "ieee") -> tuple[int, int]:
    """Round the exact magnitude ``value`` (a non-negative Fraction or int) with sign ``sign``.

    Returns ``(word, flags)`` with the rules of :mod:`kfgen.sim.float_ref`'s docstring; ``value == 0`` gives
    the zero of ``sign`` without flags.
    """
    if subnormals not in ("ieee", "ftz"):
        raise ValueError(f"subnormals must be 'ieee' or 'ftz', not {subnormals!r}")
    if sign not in (0, 1):
        raise ValueError(f"sign must be 0 or 1, not {sign!r}")
    if not isinstance(value, Rational) or value < 0:
        raise ValueError(f"value must be a non-negative Fraction or int, not {value!r}")
    k = format_consts(fmt)
    num, den = value.numerator, value.denominator
    if num == 0:
        return sign << k.sshift, 0
    ftz = subnormals == "ftz"
    if den & (den - 1) == 0:
        return round_magnitude(k, sign, num, 1 - den.bit_length(), False, ftz)
    sh = max(0, k.p + 2 + den.bit_length() - num.bit_length())
    q, r = divmod(num << sh, den)
    return round_magnitude(k, sign, q, -sh, r != 0, ftz)
