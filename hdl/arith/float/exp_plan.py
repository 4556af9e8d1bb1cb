"""The numbers of the exponential unit :class:`~.exp.FloatExp`: widths, constants, tables, and
the error bound that makes its results faithful.

Pure Python (no Amaranth), shared by the hardware (:mod:`.exp`) and its bit-exact golden model
(:mod:`kfgen.sim.fpu.exp_model`), so that the two read one set of numbers. Every constant is
computed from exact rationals (ln 2 and ``e**A`` as rational intervals, narrowed until the
rounding they feed is decided), and :func:`exp_plan` picks, for a format, the fewest working
bits whose error bound (a sum of rational upper bounds, one per truncation and rounding) is
below ``2**-(p+1)`` relative to ``e**x``: see :class:`ExpPlan` for why that is faithful.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

from .format import FloatFormat

__all__ = ["ExpPlan", "exp_plan", "CHUNK", "K_FRAC", "MAX_INDEX_BITS", "ln2_bounds", "exp_bounds"]

#: The constant multipliers (``k * ln 2`` and ``x / ln 2``) take their variable this many bits
#: at a time: a table of ``2**CHUNK`` constants per slice, one LUT4 per bit on an ECP5.
CHUNK = 4
#: Fraction bits of ``|x|`` that go into ``k = round(x / ln 2)``.
K_FRAC = 4
#: The largest table of ``e**A``: ``2**8`` entries, a ROM of 8 inputs per bit.
MAX_INDEX_BITS = 8


# ------------------------------------------------------------------------- exact constants
@lru_cache(maxsize=None)
def ln2_bounds(n: int) -> tuple[int, int]:
    """``(lo, lo + 1)`` with ``lo < ln(2) * 2**n < lo + 1``.

    ``ln 2 = sum 1 / (j 2**j)``: ``K`` terms floored at ``n + g`` bits each lose less than one
    unit, and the tail after them is below ``2**-K``, one unit.
    """
    g = 16
    K = n + g
    total = sum((1 << (n + g)) // (j << j) for j in range(1, K + 1))
    lo, hi = total >> g, -(-(total + K + 1) >> g)
    if hi - lo > 1:  # the interval straddles a unit: ln 2 is irrational, more bits settle it
        lo = ln2_bounds(n + 8)[0] >> 8
    return lo, lo + 1


def _ln2(n: int) -> tuple[Fraction, Fraction]:
    lo, hi = ln2_bounds(n)
    return Fraction(lo, 1 << n), Fraction(hi, 1 << n)


def exp_bounds(x: Fraction, n: int) -> tuple[Fraction, Fraction]:
    """Rationals ``lo < e**x < hi`` with ``hi - lo <= 2**-n``, for ``|x| <= 1``: the Taylor
    series summed exactly up to a term ``t``, the rest below ``3 |t x| / (j + 1)``."""
    if abs(x) > 1:
        raise ValueError(f"exp_bounds takes |x| <= 1, not {x}")
    s, term, j = Fraction(1), Fraction(1), 0
    while True:
        j += 1
        term = term * x / j
        s += term
        rest = abs(term * x) / (j + 1) * 3
        if rest * (2 << n) <= 1:
            return s - rest, s + rest


def _nearest(lo: Fraction, hi: Fraction, scale: int):
    """``round(v * scale)`` for every ``v`` in ``[lo, hi]``, or ``None`` if that interval holds
    a tie point (the caller narrows it)."""
    a, b = lo * scale + Fraction(1, 2), hi * scale + Fraction(1, 2)
    fa, fb = a.numerator // a.denominator, b.numerator // b.denominator
    return fa if fa == fb else None


def _exp_rounded(x: Fraction, bits: int) -> int:
    """``round(e**x * 2**bits)`` to nearest: never a tie, ``e**x`` being irrational for a
    rational ``x != 0`` (and ``e**0 = 1`` exactly)."""
    if x == 0:
        return 1 << bits
    n = bits + 24
    while (got := _nearest(*exp_bounds(x, n), 1 << bits)) is None:
        n += 32
    return got


def _ln2_rounded(bits: int, multiple: int) -> int:
    """``round(multiple * ln 2 * 2**bits)`` to nearest (irrational for ``multiple != 0``)."""
    if multiple == 0:
        return 0
    n = bits + multiple.bit_length() + 24
    while (got := _nearest(*(v * multiple for v in _ln2(n)), 1 << bits)) is None:
        n += 32
    return got


def _ln_overflow_bounds(fmt: FloatFormat, n: int) -> tuple[Fraction, Fraction]:
    """Rationals around ``ln`` of the overflow threshold ``(2 - 2**-p) 2**emax`` (the least
    value that rounds to infinity), ``2**-n`` apart at most: ``(emax + 1) ln 2 + ln(1 - u)``,
    ``u = 2**-(p+1)``, the logarithm's series summed until its tail (below twice the next
    term) is small enough."""
    lo2, hi2 = _ln2(n + fmt.exp_bits + 2)
    u = Fraction(1, 1 << (fmt.precision + 1))
    s, j, power = Fraction(0), 0, Fraction(1)
    while True:
        j += 1
        power *= u
        s += power / j
        tail = 2 * power * u
        if tail * (4 << n) <= 1:
            break
    return (fmt.emax + 1) * lo2 - s - tail, (fmt.emax + 1) * hi2 - s


def _exp_upper(u: Fraction) -> Fraction:
    """``>= e**u`` for ``0 <= u <= 1``: ``1 + u + u**2`` (the series after ``u`` is at most
    ``u**2 (e - 2)``)."""
    return 1 + u + u * u


def _exp_neg_lower(u: Fraction) -> Fraction:
    """``<= e**-u`` for ``0 <= u <= 1``: the series to ``-u**3/6`` (alternating, decreasing
    terms: a partial sum that ends on a negative term is below the sum)."""
    return 1 - u + u * u / 2 - u ** 3 / 6


def _inv_factorial(j: int) -> Fraction:
    f = 1
    for i in range(2, j + 1):
        f *= i
    return Fraction(1, f)


def _floor(value: Fraction) -> int:
    return value.numerator // value.denominator


def _unit(bits: int) -> Fraction:
    return Fraction(1, 1 << bits)


# ------------------------------------------------------------------------- the plan
@dataclass(frozen=True)
class ExpPlan:
    """Every width and constant of :class:`~.exp.FloatExp` for one format.

    A fixed-point value is an integer in units of ``2**-bits`` (its fraction bits).

    Range reduction: ``X = floor(|x| * 2**frac_bits)``; ``|x| >= 2**int_bits`` always
    overflows (``x > 0``) or rounds to ``+0`` (``x < 0``), and such an ``x`` only decides
    ``k`` (``k_over``, ``k_under``). ``k = round(X / ln 2)``: the top ``int_bits + K_FRAC``
    bits of ``X`` times ``inv_ln2 = round(2**inv_ln2_bits / ln 2)``, plus one half, floored.
    ``r = +-(X - k ln 2)`` modulo 1 at ``frac_bits``, ``k ln 2`` being the sum of one entry
    of each of ``ln2_tables`` (for the ``i``-th :data:`CHUNK`-bit slice ``j`` of ``k``,
    ``round(j * 16**i * ln 2 * 2**frac_bits) mod 2**frac_bits``). ``|r| < 1/2``, so its
    ``frac_bits`` bits read as two's complement are ``r``.

    ``e**r``: the top ``index_bits`` bits of ``r`` pick ``T = table[index] = round(e**A *
    2**work_bits)``, ``A`` being ``r`` with the bits below cleared; the rest, ``Z = r - A``
    in ``[0, 2**-index_bits)``, goes into ``Q ~ e**Z - 1``, the Taylor polynomial of
    ``degree``, in Horner form: from ``H = coeff_top`` (``1/degree!`` at ``coeff_top_bits``),
    each of ``steps``, ``(z_bits, bits, c, largest)``, makes ``H = c + floor(Z_z * H)`` at
    ``bits`` (``Z_z``: ``Z`` floored to ``z_bits``; ``largest`` bounds the result); the last step (``c = 0``) gives ``W = Z * (1/2 +
    Z/6 + ...)``, and ``Q = Z_q + floor(Z_z0 * W)`` at ``q_bits`` (``Z_q``, ``Z_z0``: ``Z``
    floored to ``q_bits`` and ``q_z_bits``). For degree 1, ``Q = Z_q``. Then ``y = T +
    floor(T_t * Q)`` at ``work_bits`` (``T_t``: ``T`` floored to ``t_bits``), in ``[0.6,
    1.7)``, and ``e**x ~ y * 2**k`` is rounded once, with a sticky bit for every ``x != 0``.

    ``error_bound`` is a rational upper bound of ``|y' 2**k - e**x| / e**x`` over every
    input, ``y'`` being ``y`` plus the sticky bit's share (under one unit of
    ``work_bits``). It is below ``2**-(p+1)``, so rounding ``y' 2**k`` to nearest is faithful
    (gives one of the two floats around ``e**x``): an error below a quarter of the spacing
    just below a power of two and half the spacing elsewhere, subnormal results included. It
    is also below the distance from ``x`` to ``ln`` of the overflow threshold at the two
    floats around that (``overflow_margins``), so a result overflows exactly when ``e**x``
    rounded to nearest does.
    """

    fmt: FloatFormat
    int_bits: int
    frac_bits: int
    inv_ln2_bits: int
    inv_ln2: int
    k_bits: int
    ln2_tables: tuple
    index_bits: int
    work_bits: int
    table: tuple
    degree: int
    coeff_top: int
    coeff_top_bits: int
    steps: tuple
    q_bits: int
    q_z_bits: int
    t_bits: int
    k_over: int
    k_under: int
    error_bound: Fraction
    overflow_margins: tuple

    @property
    def k_frac(self) -> int:
        """Fraction bits of ``|x|`` that go into ``k``."""
        return K_FRAC


def _widths(fmt: FloatFormat, guard: int, extra: int, degree: int, finer: int) -> dict | None:
    """The widths for ``work_bits = p + guard``, ``frac_bits = work_bits + extra``, a Taylor
    polynomial of ``degree`` and ``Q`` computed to about ``2**-(work_bits + finer)``, and the
    error bound they give (relative, rational); ``None`` if a Horner product would always
    floor to zero (a degree too many)."""
    p = fmt.precision
    work = p + guard
    frac = work + extra
    # 2**I above (emax + 1) ln 2 (above ln of the overflow threshold) and (bias + m) ln 2,
    # where e**-|x| is below half the smallest subnormal.
    span = max(fmt.emax + 1, fmt.bias + fmt.frac_bits)
    int_bits = 1
    while (1 << int_bits) * 10 <= span * 7:
        int_bits += 1

    # k from X's top bits and 1/ln 2 at c bits: |k - X / ln 2| <= 1/2 + eps_k.
    c = int_bits + 4
    lo2, hi2 = _ln2(c + 40)
    inv_ln2 = _floor(Fraction(1 << c) / hi2 + Fraction(1, 2))
    inv_err = max(abs(Fraction(inv_ln2, 1 << c) - 1 / lo2), abs(Fraction(inv_ln2, 1 << c) - 1 / hi2))
    eps_k = _unit(K_FRAC) / lo2 + (1 << int_bits) * inv_err
    shift = K_FRAC + c
    k_max = (((1 << (int_bits + K_FRAC)) - 1) * inv_ln2 + (1 << (shift - 1))) >> shift
    k_bits = k_max.bit_length()
    slices = -(-k_bits // CHUNK)
    # r: X floored (< 1 unit), each slice's table entry rounded (1/2 unit).
    delta_r = Fraction(2 + slices, 2) * _unit(frac)
    r_max = hi2 * (Fraction(1, 2) + eps_k) + _unit(frac) + delta_r

    target = work + finer  # Q to about 2**-target
    # The table as large as a degree-1 polynomial needs (Z**2 / 2 < 2**-(target + 1)), up to
    # MAX_INDEX_BITS.
    a = min(frac, MAX_INDEX_BITS, -(-(target + 2) // 2))
    z_max = _unit(a)  # Z < 2**-a

    d = degree
    taylor = z_max ** (d + 1) * _inv_factorial(d + 1) * (1 + 2 * z_max)  # e**xi < 1 + 2 Z

    q_bits = min(frac, target)
    zq_err = _unit(q_bits) if q_bits < frac else 0
    steps = []

    def vanishes(z_bits, h_bits, h_largest, bits):
        """Whether floor(Z_z H) at ``bits`` is always zero."""
        return ((1 << (z_bits - a)) - 1) * h_largest < 1 << (z_bits + h_bits - bits)

    if d == 1:
        coeff_top = coeff_top_bits = 0
        q_z_bits = q_bits
        q_err = zq_err
    else:
        # H_j's error weighs Z**j in Q: bits = target - j a (+ 1 for the floors' sum).
        coeff_top_bits = max(1, target + 1 - d * a)
        coeff_top = _floor(_inv_factorial(d) * (1 << coeff_top_bits) + Fraction(1, 2))
        h_bits = coeff_top_bits
        h_val = Fraction(coeff_top, 1 << h_bits)  # the computed H's largest value
        h_err = abs(h_val - _inv_factorial(d))   # |H - H*| (H*: exact Horner at exact Z)
        for j in range(d - 1, 0, -1):             # H_{d-1} .. H_2, then W = H_1 - 1
            bits = max(a + 1, target + 1 - j * a)  # (Z_z keeps a bit at least)
            z_bits = min(frac, bits)
            const = 0 if j == 1 else _floor(_inv_factorial(j) * (1 << bits) + Fraction(1, 2))
            c_err = 0 if j == 1 else abs(Fraction(const, 1 << bits) - _inv_factorial(j))
            z_err = _unit(z_bits) if z_bits < frac else 0
            floor_err = _unit(bits) if z_bits + h_bits > bits else 0
            h_star = _inv_factorial(j + 1) * (1 + 2 * z_max)  # >= the exact H*_{j+1}
            h_err = c_err + floor_err + z_max * h_err + z_err * h_star
            if vanishes(z_bits, h_bits, _floor(h_val * (1 << h_bits)), bits):
                return None
            h_val = Fraction(const, 1 << bits) + z_max * h_val
            h_bits = bits
            steps.append((z_bits, bits, const, _floor(h_val * (1 << bits))))
        q_z_bits = min(frac, max(a + 1, target - a))
        z0_err = _unit(q_z_bits) if q_z_bits < frac else 0
        floor_err = _unit(q_bits) if q_z_bits + h_bits > q_bits else 0
        w_star = z_max * _inv_factorial(2) * (1 + 2 * z_max)  # >= the exact W = Z H*_2
        q_err = zq_err + floor_err + z_max * h_err + z0_err * w_star
        if vanishes(q_z_bits, h_bits, _floor(h_val * (1 << h_bits)), q_bits):
            return None
    q_total = taylor + q_err
    q_max = _exp_upper(z_max) - 1 + q_total

    # y = T + floor(T_t Q) at G bits.
    t_bits = min(work, max(1, work + 3 - a))
    t_max = Fraction(17, 10)  # e**(1/2) < 1.65
    y_err = (_unit(work + 1) * _exp_upper(z_max)                  # T rounded to nearest
             + _unit(work)                                       # the product floored
             + (_unit(t_bits) if t_bits < work else 0) * q_max   # T floored to T_t
             + t_max * q_total                                   # Q
             + _unit(work))                                      # the sticky bit
    bound = y_err / _exp_neg_lower(r_max) + delta_r + 2 * delta_r * delta_r  # e**d - 1 <= d + 2 d**2
    return dict(work=work, frac=frac, int_bits=int_bits, c=c, inv_ln2=inv_ln2, k_bits=k_bits,
                slices=slices, r_max=r_max, a=a, d=d, coeff_top=coeff_top,
                coeff_top_bits=coeff_top_bits, steps=tuple(steps), q_bits=q_bits,
                q_z_bits=q_z_bits, t_bits=t_bits, bound=bound)


def _overflow_margins(fmt: FloatFormat) -> tuple[Fraction, Fraction]:
    """Lower bounds of ``ln T - x`` and ``x+ - ln T`` for the float ``x`` just below ``ln T``
    (``T`` the overflow threshold) and the one just above, ``x+``."""
    n = 2 * fmt.precision + 64
    while True:
        lo, hi = _ln_overflow_bounds(fmt, n)
        top = _floor(lo).bit_length() - 1  # ln T >= 1 in every format
        ulp = Fraction(1 << top, 1 << fmt.frac_bits)
        below = _floor(lo / ulp)
        if below == _floor(hi / ulp):
            return lo - below * ulp, (below + 1) * ulp - hi
        n += 32


@lru_cache(maxsize=None)
def exp_plan(fmt) -> ExpPlan:
    """The plan of ``fmt`` (a :class:`~.format.FloatFormat` or its name): the fewest work bits,
    then fraction bits, then the lowest degree, then the fewest bits of ``Q``, whose error
    bound is below ``2**-(p+1)`` and below both overflow margins."""
    fmt = FloatFormat.parse(fmt)
    margin_below, margin_above = _overflow_margins(fmt)
    limit = min(_unit(fmt.precision + 1), margin_below)
    for guard in range(2, 64):
        for extra in (0, 1, 2):
            # The lowest degree, then the coarsest Q: the fewest and narrowest products.
            for degree in range(1, 16):
                for finer in (1, 2, 3, 4):
                    w = _widths(fmt, guard, extra, degree, finer)
                    if w is None:
                        continue
                    eps = w["bound"]
                    if eps < limit and eps + eps * eps <= margin_above:
                        return _tabulate(fmt, w, (margin_below, margin_above))
    raise AssertionError(f"no exp plan for {fmt}")


def _tabulate(fmt: FloatFormat, w: dict, margins) -> ExpPlan:
    frac, work, a, k_bits = w["frac"], w["work"], w["a"], w["k_bits"]
    if w["r_max"] >= Fraction(1, 2):
        raise AssertionError(f"exp plan for {fmt}: |r| may reach 1/2")
    ln2_tables = tuple(
        tuple(_ln2_rounded(frac, j << (CHUNK * i)) % (1 << frac) for j in range(1 << min(CHUNK, k_bits - CHUNK * i)))
        for i in range(w["slices"]))
    table = tuple(_exp_rounded(Fraction(idx - (1 << a) if idx >> (a - 1) else idx, 1 << a), work)
                  for idx in range(1 << a))
    return ExpPlan(fmt=fmt, int_bits=w["int_bits"], frac_bits=frac, inv_ln2_bits=w["c"],
                   inv_ln2=w["inv_ln2"], k_bits=k_bits, ln2_tables=ln2_tables, index_bits=a,
                   work_bits=work, table=table, degree=w["d"], coeff_top=w["coeff_top"],
                   coeff_top_bits=w["coeff_top_bits"], steps=w["steps"], q_bits=w["q_bits"],
                   q_z_bits=w["q_z_bits"], t_bits=w["t_bits"], k_over=fmt.emax + 2,
                   k_under=fmt.emin - fmt.frac_bits - 2, error_bound=w["bound"],
                   overflow_margins=margins)
