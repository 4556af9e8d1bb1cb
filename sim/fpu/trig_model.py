"""Bit-exact golden model of the trigonometric units (:mod:`kfgen.hdl.arith.float.trig`):
``sin``, ``cos`` and ``atan2``.

The units' integer arithmetic step by step (the Payne-Hanek product, the CORDIC's shifts and
table additions, the restoring division, the one product by ``pi/2``), with the constants of
:func:`~kfgen.hdl.arith.float.trig_plan.trig_plan`, rounded once by the shared exact
rounding (:func:`~kfgen.hdl.arith.float.exact.round_magnitude`, which is what the units'
rounding stage does). How close the results are to the true functions is checked separately
against the multi-precision reference :mod:`.trig_exact`.
"""

from __future__ import annotations

import numpy as np

from kfgen.hdl.arith.float.exact import format_consts, round_magnitude
from kfgen.hdl.arith.float.format import FLAG_NV, FLAG_NX, FLAG_UF, FloatFormat
from kfgen.hdl.arith.float.trig_plan import FUNCTIONS, constant_word, trig_plan

__all__ = ["trig_word", "trig_model"]


def _decode(k, w: int, ftz: bool):
    """``(kind, sign, M, e)``: kind 0 zero, 1 finite nonzero, 2 inf, 3 qNaN, 4 sNaN; a finite
    nonzero value is ``M 2**(e - p + 1)`` with ``M`` normalised to ``p`` bits (``e`` the
    exponent of its leading bit)."""
    s, field, frac = w >> k.sshift, (w >> k.fb) & k.emask, w & k.fmask
    if field == k.emask:
        return (2 if frac == 0 else (3 if frac & k.qbit else 4)), s, 0, 0
    if field == 0:
        if frac == 0 or ftz:
            return 0, s, 0, 0
        n = frac.bit_length()
        return 1, s, frac << (k.p - n), k.emin - (k.p - n)
    return 1, s, frac | k.hidden, field - k.bias


def _cordic(plan, x: int, y: int, z: int, table, rotate: bool):
    """``iterations`` steps: rotation (``z`` to 0) or vectoring (``y`` to 0)."""
    for i, a in enumerate(table):
        up = z >= 0 if rotate else y < 0
        if up:
            x, y, z = x - (y >> i), y + (x >> i), z - a
        else:
            x, y, z = x + (y >> i), y - (x >> i), z + a
    return x, y, z


def _sin_cos(k, plan, fn: str, w: int, ftz: bool) -> tuple[int, int]:
    kind, s, M, e = _decode(k, w, ftz)
    one = k.bias << k.fb
    if kind >= 3:
        return k.nan, FLAG_NV if kind == 4 else 0
    if kind == 2:
        return k.nan, FLAG_NV
    if kind == 0:
        return (s << k.sshift, 0) if fn == "sin" else (one, 0)
    if e < -plan.tiny_bits:
        if fn == "cos":
            return one, FLAG_NX
        return w, FLAG_NX | (FLAG_UF if e < k.emin else 0)
    if e >= plan.range_bits:
        return k.nan, FLAG_NV
    p, F = plan.p, plan.t_frac
    E = e - (p - 1)
    # Payne-Hanek: T = M * window mod 2**acc, MSB first (the hardware's order; exact).
    T = (M * plan.window[E - plan.e_low]) & ((1 << plan.acc_bits) - 1)
    t = T >> p
    kq = ((t >> (F - 1)) + 1) >> 1 & 3
    f = ((t + (1 << (F - 1))) & ((1 << F) - 1)) - (1 << (F - 1))
    q = (kq + (1 if fn == "cos" else 0)) & 3
    fa = abs(f)
    sign = (q >> 1) ^ (s if fn == "sin" else 0)
    if q & 1 == 0:
        sign ^= f < 0
    if q & 1 == 0 and fa < 1 << (F - plan.tiny_bits - 1):
        # sin r ~ r = |f| pi/2: |f| normalised, its top mul_bits times pi/2.
        lz = F - fa.bit_length()
        top = (fa << lz) >> (F - plan.mul_bits)
        prod = top * plan.pi_half_mul
        return round_magnitude(k, sign, prod, -(plan.mul_bits + lz) - plan.mul_bits, True, ftz)
    W = plan.cordic_bits
    z = fa << (W - F) if W >= F else fa >> (F - W)
    cx, cy, _ = _cordic(plan, plan.inv_gain, 0, z, plan.atan_quarter, True)
    value = cy if q & 1 == 0 else cx
    return round_magnitude(k, sign, value, -W, True, ftz)


def _atan2(k, plan, wy: int, wx: int, ftz: bool) -> tuple[int, int]:
    ky, sy, My, ey = _decode(k, wy, ftz)
    kx, sx, Mx, ex = _decode(k, wx, ftz)
    if ky >= 3 or kx >= 3:
        return k.nan, FLAG_NV if 4 in (ky, kx) else 0
    fmt = k.fmt
    if ky == 0:
        if sx == 0:  # +0, a positive x, +inf
            return sy << k.sshift, 0
        return constant_word(fmt, (1, 0), sy), FLAG_NX
    if ky == 2:
        if kx == 2:
            return constant_word(fmt, (3, 2) if sx else (1, 2), sy), FLAG_NX
        return constant_word(fmt, (1, 1), sy), FLAG_NX
    if kx == 0:
        return constant_word(fmt, (1, 1), sy), FLAG_NX
    if kx == 2:
        return (sy << k.sshift, 0) if sx == 0 else (constant_word(fmt, (1, 0), sy), FLAG_NX)
    d = ey - ex
    if sx == 0 and d < -plan.tiny_bits:
        # atan(q) ~ q = |y| / x: a restoring division, div_bits + 1 quotient bits.
        Q = (My << plan.div_bits) // Mx
        return round_magnitude(k, sy, Q, d - plan.div_bits, True, ftz)
    W, p = plan.cordic_bits, plan.p
    top = max(ey, ex)
    A = _align(My, top - ey, W, p)
    B = _align(Mx, top - ex, W, p)
    x0, y0, z0 = (B, A, 0) if sx == 0 else (A, B, plan.pi_half)
    _, _, z = _cordic(plan, x0, y0, z0, plan.atan_radians, False)
    return round_magnitude(k, sy, z, -W, True, ftz)


def _align(M: int, right: int, W: int, p: int) -> int:
    """``M 2**-(p-1)`` (in ``[1, 2)``) shifted right by ``right``, at ``W`` fraction bits."""
    v = M << (W - p + 1)
    return v >> right if right <= W + 1 else 0


def trig_word(fn: str, fmt, a: int, b: int | None = None, subnormals: str = "ieee") -> tuple[int, int]:
    """``(word, flags)`` of one operation: ``sin(a)``, ``cos(a)`` or ``atan2(a, b)`` (``a`` is
    ``y``, ``b`` is ``x``), as the unit computes it."""
    if fn not in FUNCTIONS:
        raise ValueError(f"fn must be one of {', '.join(FUNCTIONS)}, not {fn!r}")
    if subnormals not in ("ieee", "ftz"):
        raise ValueError(f"subnormals must be 'ieee' or 'ftz', not {subnormals!r}")
    k = format_consts(fmt)
    plan = trig_plan(k.fmt)
    ftz = subnormals == "ftz"
    if fn == "atan2":
        return _atan2(k, plan, a, b, ftz)
    return _sin_cos(k, plan, fn, a, ftz)


def trig_model(fn: str, fmt, a, b=None, subnormals: str = "ieee"):
    """:func:`trig_word` over arrays of words: ``(words, flags)`` (``int64`` arrays, or
    ``object`` arrays of Python integers for formats wider than 62 bits)."""
    fmt = FloatFormat.parse(fmt)
    a = [int(w) for w in np.ravel(a)]
    b = [None] * len(a) if b is None else [int(w) for w in np.ravel(b)]
    rows = [trig_word(fn, fmt, x, y, subnormals) for x, y in zip(a, b)]
    dtype = np.int64 if fmt.width <= 62 else object
    words = np.asarray([r[0] for r in rows], dtype=dtype)
    return words, np.asarray([r[1] for r in rows], dtype=np.int64)
