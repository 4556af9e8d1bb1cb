"""Parameters of the Castella tracker core, and every number format derived from them.

One frozen dataclass feeds the Amaranth core (``kfgen.hdl.castella``), the bit-accurate
golden model (``kfgen.sim.castella.model``), the manifest writer and the testbenches, so the
hardware and its model cannot drift apart. This module is pure Python (no Amaranth).

Number formats (``frac`` = fraction bits; a value is ``integer * 2**-frac``)
--------------------------------------------------------------------------
========  =========  ==================  ==========================================
quantity  signed     width               fraction bits
========  =========  ==================  ==========================================
range     no         ``data_width``      ``data_width - 16``  (0..65535 m at 16 bits)
velocity  yes        ``data_width``      ``data_width - 12``  (+-2048 m/s)
P11       no         ``data_width``      fits 5 sigma_r^2 + q2 T^3/3 (m^2)
P12       no         ``data_width``      fits 3 sigma_r^2/T + q2 T^2/2 (m^2/s)
P22       no         ``data_width``      fits 2 sigma_r^2/T^2 + q2 T (m^2/s^2)
K1        no         ``gain_width``      ``gain_width`` (0 <= K1 < 1)
K2        no         ``gain_width``      ``gain_width + 1 + floor(log2 T)`` (1/s)
q code    no         ``q_width``         code c: q = q1 + (q2 - q1) c / (2**q_width - 1)
z         yes        12                  8 (normalised residual, +-8)
========  =========  ==================  ==========================================

P12 is unsigned: with P22 >= 0 every term of the recursion that feeds it is non-negative.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from ..describe import ParamError, check_name

__all__ = ["CastellaParams", "ParamError", "Fmt"]

#: Fraction bits and width of the normalised residual z and of the alpha_R constant.
Z_WIDTH = 12
Z_FRAC = 8
ALPHA_FRAC = 8
#: Index bits of the 1/sqrt(P11 + sigma_r^2) look-up table (the paper's U4 LUT).
RSQRT_INDEX_BITS = 8
RSQRT_WIDTH = 16
#: Significant bits kept for constant multipliers (T, 2T, T^2, 1/T): an 18x18 DSP operand.
CONST_BITS = 17
#: Fraction bits of the q-line slope multiplier.
QSLOPE_SHIFT = 16
#: Largest q2 (m^2/s^3) and z2 (sigma, the integer range of the z format) accepted.
Q2_MAX = 1e6
Z_MAX = (1 << (Z_WIDTH - 1 - Z_FRAC)) - 1


@dataclass(frozen=True)
class Fmt:
    """A fixed-point format: ``width`` bits, ``frac`` fraction bits, signed or not."""

    width: int
    frac: int
    signed: bool

    @property
    def min(self) -> int:
        return -(1 << (self.width - 1)) if self.signed else 0

    @property
    def max(self) -> int:
        return (1 << (self.width - 1)) - 1 if self.signed else (1 << self.width) - 1

    def to_int(self, value: float) -> int:
        """Nearest representable integer code of a real value, saturated."""
        return max(self.min, min(self.max, round(value * 2.0 ** self.frac)))


def _const(value: float, bits: int = CONST_BITS) -> tuple[int, int]:
    """A positive real constant as ``(mantissa, frac)``, mantissa below ``2**bits``."""
    frac = bits - 1 - math.floor(math.log2(value))
    mant = round(value * 2.0 ** frac)
    if mant >= 1 << bits:  # rounding carried into a new bit
        frac -= 1
        mant = round(value * 2.0 ** frac)
    return mant, frac


def _frac_for(width: int, max_value: float, signed: bool) -> int:
    """Fraction bits that leave enough integer bits for ``max_value``."""
    int_bits = max(0, math.ceil(math.log2(max_value + 1)))
    return width - int_bits - (1 if signed else 0)


#: How the gain products are built: shift-and-add trees in LUTs (fast on ECP5, whose DSP
#: blocks Yosys maps without their registers), or ``*`` between registers that a Xilinx 7
#: series DSP48E1 absorbs. The same values and latency either way.
MULTIPLIERS = ("lut", "dsp")

# Allowed ranges: (low, high) inclusive, the one place the CLI and the classes read them.
RANGES = {
    "tracks": (1, 4096),
    "data_width": (16, 24),
    "gain_width": (6, 12),
    "q_width": (2, 8),
    "period": (1e-3, 60.0),
    "sigma_r": (1.0, 1000.0),
}


@dataclass(frozen=True)
class CastellaParams:
    """Generation parameters of the Castella adaptive tracker.

    What each parameter means, its unit and the values it takes are written once, in
    ``RANGES`` and :mod:`kfgen.hdl.castella.descriptor` (which ``kfgen castella --help``
    prints). The constructor validates every value and raises :class:`ParamError`; alpha,
    z1 and z2 are then replaced by the values the datapath holds (multiples of 2**-8).
    """

    tracks: int = 1
    data_width: int = 16
    gain_width: int = 8
    q_width: int = 6
    period: float = 1.0
    sigma_r: float = 100.0
    alpha: float = 0.5
    q1: float = 2.16
    q2: float = 200.0
    z1: float = 1.132
    z2: float = 1.693
    multipliers: str = "lut"
    name: str = "castella"

    # ------------------------------------------------------------------ validation
    def __post_init__(self):
        for key, (lo, hi) in RANGES.items():
            value = getattr(self, key)
            is_int = key not in ("period", "sigma_r")
            if is_int and (not isinstance(value, int) or isinstance(value, bool)):
                raise ParamError(key, f"must be an integer in {lo}..{hi}, not {value!r}")
            if not is_int and not isinstance(value, (int, float)) or isinstance(value, bool):
                raise ParamError(key, f"must be a number in [{lo}, {hi}], not {value!r}")
            if not lo <= value <= hi or (not is_int and not math.isfinite(value)):
                rng = f"{lo}..{hi}" if is_int else f"[{lo}, {hi}]"
                raise ParamError(key, f"must be in {rng}, not {value!r}")
        for key in ("alpha", "q1", "q2", "z1", "z2"):
            value = getattr(self, key)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
                raise ParamError(key, f"must be a finite number, not {value!r}")
        if not 0 < self.alpha < 1:
            raise ParamError("alpha", f"must be in the open interval (0, 1), not {self.alpha!r}")
        alpha_code = round(self.alpha * (1 << ALPHA_FRAC))
        if not 1 <= alpha_code < (1 << ALPHA_FRAC):
            raise ParamError("alpha", f"must be in [{1 / 512}, {1 - 1 / 512}] to be representable in "
                             f"{ALPHA_FRAC} fraction bits, not {self.alpha!r}")
        if not 0 < self.q1 < self.q2:
            raise ParamError("q1", f"must satisfy 0 < q1 < q2, got q1={self.q1!r} q2={self.q2!r}")
        if self.q2 > Q2_MAX:
            raise ParamError("q2", f"must be at most {Q2_MAX:g} m^2/s^3, not {self.q2!r}")
        if not 0 < self.z1 < self.z2 <= Z_MAX:
            raise ParamError("z1", f"must satisfy 0 < z1 < z2 <= {Z_MAX}, got z1={self.z1!r} z2={self.z2!r}")
        if self.z2_code - self.z1_code < 1:
            raise ParamError("z2", f"must exceed z1 by at least {2 ** -Z_FRAC}")
        multipliers = self.multipliers.strip().lower() if isinstance(self.multipliers, str) else self.multipliers
        if multipliers not in MULTIPLIERS:
            raise ParamError("multipliers", f"must be one of {', '.join(MULTIPLIERS)}, not {self.multipliers!r}")
        object.__setattr__(self, "multipliers", multipliers)
        check_name(self.name)
        # The datapath holds alpha, z1 and z2 as multiples of 2**-8: record the values built,
        # so the header, the manifest and the models say what the hardware does, and every
        # spelling of one core gives the same bytes.
        for key, code in (("alpha", self.alpha_code), ("z1", self.z1_code), ("z2", self.z2_code)):
            object.__setattr__(self, key, code / (1 << (ALPHA_FRAC if key == "alpha" else Z_FRAC)))
        # The covariance formats must resolve sigma_r^2.
        sr_code = self.sigma_r ** 2 * 2.0 ** self.p11_fmt.frac
        if sr_code < 16:
            raise ParamError("sigma_r", f"{self.sigma_r!r} m is too small for data_width {self.data_width}: "
                             "sigma_r^2 needs at least 4 significant bits in P11")

    # ------------------------------------------------------------------ formats
    @property
    def range_fmt(self) -> Fmt:
        return Fmt(self.data_width, self.data_width - 16, False)

    @property
    def vel_fmt(self) -> Fmt:
        return Fmt(self.data_width, self.data_width - 12, True)

    @property
    def p11_fmt(self) -> Fmt:
        T, r2 = self.period, self.sigma_r ** 2
        return Fmt(self.data_width, _frac_for(self.data_width, 5 * r2 + self.q2 * T ** 3 / 3, False), False)

    @property
    def p12_fmt(self) -> Fmt:
        T, r2 = self.period, self.sigma_r ** 2
        return Fmt(self.data_width, _frac_for(self.data_width, 3 * r2 / T + self.q2 * T ** 2 / 2, False), False)

    @property
    def p22_fmt(self) -> Fmt:
        T, r2 = self.period, self.sigma_r ** 2
        return Fmt(self.data_width, _frac_for(self.data_width, 2 * r2 / T ** 2 + self.q2 * T, False), False)

    @property
    def k1_fmt(self) -> Fmt:
        return Fmt(self.gain_width, self.gain_width, False)

    @property
    def k2_fmt(self) -> Fmt:
        return Fmt(self.gain_width, self.gain_width + 1 + math.floor(math.log2(self.period)), False)

    @property
    def z_fmt(self) -> Fmt:
        return Fmt(Z_WIDTH, Z_FRAC, True)

    @property
    def q_max(self) -> int:
        return (1 << self.q_width) - 1

    # ------------------------------------------------------------------ constants
    @property
    def t_const(self) -> tuple[int, int]:
        """T as (mantissa, frac)."""
        return _const(self.period)

    @property
    def t2x_const(self) -> tuple[int, int]:
        """2T."""
        return _const(2 * self.period)

    @property
    def tsq_const(self) -> tuple[int, int]:
        """T^2."""
        return _const(self.period ** 2)

    @property
    def inv_t_const(self) -> tuple[int, int]:
        """1/T."""
        return _const(1 / self.period)

    @property
    def sr2_code(self) -> int:
        """sigma_r^2 in the P11 format (may exceed the format: it is only an addend)."""
        return round(self.sigma_r ** 2 * 2.0 ** self.p11_fmt.frac)

    @property
    def p_init_codes(self) -> tuple[int, int, int]:
        """P(1/1) of eq. (18): sigma_r^2, sigma_r^2/T, 2 sigma_r^2/T^2, saturated to the formats."""
        T, r2 = self.period, self.sigma_r ** 2
        return (self.p11_fmt.to_int(r2), self.p12_fmt.to_int(r2 / T), self.p22_fmt.to_int(2 * r2 / T ** 2))

    @property
    def built_constants(self) -> dict:
        """The real constants the datapath multiplies by, as built (rounded to ``CONST_BITS``
        significant bits or to the P11 format), for the manifest."""
        def value(const):
            mant, frac = const
            return mant * 2.0 ** -frac

        return {"period_s": value(self.t_const), "two_period_s": value(self.t2x_const),
                "period_squared_s2": value(self.tsq_const), "inverse_period_hz": value(self.inv_t_const),
                "sigma_r_squared_m2": self.sr2_code * 2.0 ** -self.p11_fmt.frac}

    @property
    def alpha_code(self) -> int:
        return round(self.alpha * (1 << ALPHA_FRAC))

    @property
    def z1_code(self) -> int:
        return round(self.z1 * (1 << Z_FRAC))

    @property
    def z2_code(self) -> int:
        return round(self.z2 * (1 << Z_FRAC))

    @property
    def q_slope(self) -> int:
        """Codes per z LSB above z1, times 2**QSLOPE_SHIFT: the straight line of Figure 2."""
        return round(self.q_max * (1 << QSLOPE_SHIFT) / (self.z2_code - self.z1_code))

    def q_of_code(self, code):
        """The spectral density q (m^2/s^3) a q code stands for."""
        return self.q1 + (self.q2 - self.q1) * code / self.q_max

    @property
    def q_tables(self) -> tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]]:
        """Per q code, q*T^3/3, q*T^2/2 and q*T in the P11, P12 and P22 formats (the Q LUTs of U5)."""
        T = self.period
        codes = range(self.q_max + 1)
        return (tuple(self.p11_fmt.to_int(self.q_of_code(c) * T ** 3 / 3) for c in codes),
                tuple(self.p12_fmt.to_int(self.q_of_code(c) * T ** 2 / 2) for c in codes),
                tuple(self.p22_fmt.to_int(self.q_of_code(c) * T) for c in codes))

    @property
    def rsqrt_frac(self) -> int:
        smallest = self.sigma_r ** 2 + 0.5 * self._rsqrt_step
        return math.floor(math.log2(((1 << RSQRT_WIDTH) - 1) * math.sqrt(smallest)))

    @property
    def _rsqrt_step(self) -> float:
        """Width in m^2 of one rsqrt table bin."""
        return 2.0 ** (self.data_width - RSQRT_INDEX_BITS - self.p11_fmt.frac)

    @property
    def rsqrt_table(self) -> tuple[int, ...]:
        """1/sqrt(P11 + sigma_r^2) at each bin's midpoint, frac ``rsqrt_frac`` (eq. 9)."""
        step, f = self._rsqrt_step, self.rsqrt_frac
        return tuple(round(2.0 ** f / math.sqrt(self.sigma_r ** 2 + (i + 0.5) * step))
                     for i in range(1 << RSQRT_INDEX_BITS))

    # ------------------------------------------------------------------ helpers
    @property
    def tid_width(self) -> int:
        """Width of the track index (at least 1 bit, as AXI4-Stream TID)."""
        return max(1, (self.tracks - 1).bit_length())

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    # ------------------------------------------------------------------ stream layouts
    def field_list(self, port: str) -> list[dict]:
        """Packed fields of a stream port, LSB first: name, lsb, width, signed, frac_bits, unit.

        ``port`` is ``s_axis_tdata``, ``s_axis_tuser``, ``m_axis_tdata`` or ``m_axis_tuser``.
        """
        def fmt_fields(items):
            out, lsb = [], 0
            for name, width, signed, frac, unit in items:
                out.append({"name": name, "lsb": lsb, "width": width, "signed": signed,
                            "frac_bits": frac, "unit": unit})
                lsb += width
            return out

        rf, vf, k1, k2 = self.range_fmt, self.vel_fmt, self.k1_fmt, self.k2_fmt
        layouts = {
            "s_axis_tdata": [("range", rf.width, False, rf.frac, "m")],
            "s_axis_tuser": [("restart", 1, False, 0, "")],
            "m_axis_tdata": [
                ("range", rf.width, False, rf.frac, "m"),
                ("velocity", vf.width, True, vf.frac, "m/s"),
                ("k1", k1.width, False, k1.frac, ""),
                ("k2", k2.width, False, k2.frac, "1/s"),
                ("q", self.q_width, False, 0,
                 f"code: q = {self.q1!r} + ({self.q2!r} - {self.q1!r}) * code / {self.q_max} m^2/s^3"),
            ],
            "m_axis_tuser": [
                ("phase", 2, False, 0, "0 first measurement, 1 initialised, 2 tracking"),
                ("manoeuvre", 1, False, 0, "filtered residual above z1"),
                ("saturated", 1, False, 0, "a state or covariance word saturated in this update"),
            ],
        }
        return fmt_fields(layouts[port])

    def port_width(self, port: str) -> int:
        return sum(f["width"] for f in self.field_list(port))
