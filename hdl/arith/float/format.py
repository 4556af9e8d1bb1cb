"""Floating-point formats: exponent and fraction widths, and the constants derived from them.

Pure Python (no Amaranth import), shared by the hardware units and the exact reference model
:mod:`kfgen.sim.float_ref`. A word is ``sign | exponent | fraction`` from MSB to LSB.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["FloatFormat", "PRESETS", "FLAG_NX", "FLAG_UF", "FLAG_OF", "FLAG_DZ", "FLAG_NV",
           "FLAG_NAMES"]

# Exception flags, RISC-V fflags bit order.
FLAG_NX, FLAG_UF, FLAG_OF, FLAG_DZ, FLAG_NV = 1, 2, 4, 8, 16
FLAG_NAMES = ("NX", "UF", "OF", "DZ", "NV")

EXP_BITS_RANGE = (3, 15)
FRAC_BITS_RANGE = (2, 64)

_CUSTOM = re.compile(r"e(\d+)m(\d+)")


@dataclass(frozen=True)
class FloatFormat:
    """A binary floating-point format.

    Parameters
    ----------
    exp_bits : int
        Exponent field width, 3..15.
    frac_bits : int
        Stored fraction width (without the hidden bit), 2..64.

    Raises
    ------
    ValueError
        If a width is not an integer in its range.
    """

    exp_bits: int = 8
    frac_bits: int = 23

    def __post_init__(self):
        for what, v, (lo, hi) in (("exp_bits", self.exp_bits, EXP_BITS_RANGE),
                                  ("frac_bits", self.frac_bits, FRAC_BITS_RANGE)):
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise ValueError(f"{what} must be an integer from {lo} to {hi}, not {v!r}")

    @classmethod
    def parse(cls, name) -> FloatFormat:
        """A preset name (``binary16``, ``bfloat16``, ``binary32``, ``binary64``) or ``eEmM``."""
        if isinstance(name, FloatFormat):
            return name
        if not isinstance(name, str):
            raise ValueError(f"format must be a preset name or 'eEmM', not {name!r}")
        key = name.strip().lower()
        if key in PRESETS:
            return PRESETS[key]
        match = _CUSTOM.fullmatch(key)
        if match is None:
            raise ValueError(f"unknown format {name!r}: use one of {', '.join(PRESETS)} "
                             f"or 'eEmM' (for example e6m11)")
        return cls(int(match[1]), int(match[2]))

    @property
    def name(self) -> str:
        """The preset name if there is one, else ``eEmM``."""
        for key, fmt in PRESETS.items():
            if fmt == self:
                return key
        return f"e{self.exp_bits}m{self.frac_bits}"

    def __str__(self):
        return self.name

    @property
    def width(self) -> int:
        return 1 + self.exp_bits + self.frac_bits

    @property
    def precision(self) -> int:
        """Significand bits including the hidden bit."""
        return self.frac_bits + 1

    @property
    def bias(self) -> int:
        return (1 << (self.exp_bits - 1)) - 1

    @property
    def emin(self) -> int:
        return 1 - self.bias

    @property
    def emax(self) -> int:
        return self.bias

    @property
    def exp_max_field(self) -> int:
        """The all-ones exponent field (infinities and NaNs)."""
        return (1 << self.exp_bits) - 1

    @property
    def sign_mask(self) -> int:
        return 1 << (self.width - 1)

    @property
    def frac_mask(self) -> int:
        return (1 << self.frac_bits) - 1

    @property
    def quiet_bit(self) -> int:
        """The top fraction bit: set in a quiet NaN."""
        return 1 << (self.frac_bits - 1)

    def pack(self, sign: int, exp_field: int, frac: int) -> int:
        return ((sign & 1) << (self.width - 1)) | (exp_field << self.frac_bits) | frac

    def unpack(self, word: int) -> tuple[int, int, int]:
        """``(sign, exponent field, fraction field)`` of a word."""
        return (word >> (self.width - 1)) & 1, (word >> self.frac_bits) & self.exp_max_field, \
            word & self.frac_mask

    @property
    def canonical_nan(self) -> int:
        return self.pack(0, self.exp_max_field, self.quiet_bit)

    def inf(self, sign: int = 0) -> int:
        return self.pack(sign, self.exp_max_field, 0)

    def zero(self, sign: int = 0) -> int:
        return self.pack(sign, 0, 0)

    @property
    def max_finite(self) -> int:
        return self.pack(0, self.exp_max_field - 1, self.frac_mask)

    @property
    def min_normal(self) -> int:
        return self.pack(0, 1, 0)

    @property
    def min_subnormal(self) -> int:
        return self.pack(0, 0, 1)

    @property
    def max_subnormal(self) -> int:
        return self.pack(0, 0, self.frac_mask)

    def is_nan(self, word: int) -> bool:
        _, e, f = self.unpack(word)
        return e == self.exp_max_field and f != 0

    def is_snan(self, word: int) -> bool:
        return self.is_nan(word) and not word & self.quiet_bit

    def is_inf(self, word: int) -> bool:
        _, e, f = self.unpack(word)
        return e == self.exp_max_field and f == 0

    def is_zero(self, word: int) -> bool:
        _, e, f = self.unpack(word)
        return e == 0 and f == 0

    def is_subnormal(self, word: int) -> bool:
        _, e, f = self.unpack(word)
        return e == 0 and f != 0


PRESETS = {
    "binary16": FloatFormat(5, 10),
    "bfloat16": FloatFormat(8, 7),
    "binary32": FloatFormat(8, 23),
    "binary64": FloatFormat(11, 52),
}
