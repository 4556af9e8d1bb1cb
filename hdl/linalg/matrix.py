"""Matrix operations as engine programs: the vocabulary the cores' programs are written in.

Pure Python (no Amaranth import). Each function emits, into a :class:`~.program.Program`,
the operations of one matrix operation in a fixed order: the order of a sum's terms and of
the entries is part of the program (:mod:`.program`), so the same call always gives the same
instructions, and so the same bits.

A matrix is a *view*: a callable ``a(i, j)`` giving the address of entry ``(i, j)``. A
:class:`~.program.Region` is one (a one-column region is also a vector, ``v(i)``); the views
below rearrange one without moving a word: :func:`transpose`, :func:`block` (a sub-matrix, e.g.
one model's rows of matrices stacked model by model), :func:`row` (a matrix's row as a column
vector) and :func:`fill` (one word everywhere, a scalar). A destination view may return two
addresses, the entry and its mirror (:func:`mirrored`): one triangle of a symmetric matrix is
computed and written to both, so the matrix stays exactly symmetric.

A linear Kalman filter in this vocabulary (n states, m measurements; ``x``, ``P``, ``F``,
``Q``, ``H``, ``R``, ``z`` regions of the layout, the rest work regions, ``one`` the address
of the constant 1 from :func:`const`)::

    # predict: x^- = F x (into xp), P = F P F^T + Q (one triangle, mirrored)
    product(prog, xp, F, x, n, n, 1)
    product(prog, FP, F, P, n, n, n)
    product(prog, mirrored(P), FP, transpose(F), n, n, n, init=Q, lower=True)
    # update: y = z - H x^-, S = H P H^T + R, K = P H^T S^-1 (by LDL^T), x = x^- + K y,
    # P -= K (H P)
    product(prog, y, H, xp, m, n, 1, init=z, neg=True)
    product(prog, HP, H, P, m, n, n)
    product(prog, S, HP, transpose(H), m, n, m, init=R, lower=True)
    ldl(prog, S, m, FS, LS, DS, rDS, one)
    solve_ldl(prog, K, transpose(HP), n, m, LS, DS, rDS, one, Yfw, Udiv)
    product(prog, x, K, y, n, m, 1, init=xp, check="finite")
    product(prog, mirrored(P), K, HP, n, m, n, init=P, neg=True, lower=True, check="finite")

(``tests/engine/test_linalg_matrix.py`` runs it against numpy's equations.) An extended
Kalman filter is the same with F and H the Jacobians (x^- = f(x) and the prediction h(x^-)
computed by the core's models instead of the first products).

Structure known at generation (a Jacobian's zeros and ones, a block-diagonal covariance) is
told by the views: an entry ``None`` is a structural zero, and :func:`product` drops its
terms; given ``one`` (the constant 1's address) it takes a term ``1 * b`` as the sum's addend,
and :func:`sparse_product` returns a view whose entries that are one word times 1 are that
word, no operation: ``sparse_product(prog, W, beside(F, L, n), diagonal_blocks(P, Q, n), ...)``
is ``[F L] diag(P, Q)`` on the nonzero terms only (:mod:`kfgen.hdl.ekf.programs`). The Joseph form
P = (I - K H) P (I - K H)^T + K R K^T is five products: A = I - K H (``init`` a view of the
constant words 1 and 0), A P, (A P) A^T, K R, and (K R) K^T added to the third, mirrored.
"""

from __future__ import annotations

from fractions import Fraction

from kfgen.hdl.arith.float.exact import round_to_format

from .program import Copy, Div, Dot, Sqrt

__all__ = ["word", "const", "transpose", "block", "row", "fill", "mirrored", "beside", "diagonal_blocks", "product",
           "sparse_product", "add", "hadamard", "ldl", "cholesky", "forward_substitute", "back_substitute",
           "solve_ldl"]


def word(fmt, value) -> int:
    """The word of ``value`` (a number or :class:`~fractions.Fraction`, exactly converted)
    rounded once to ``fmt``."""
    value = Fraction(value)
    return round_to_format(fmt, int(value < 0), abs(value))[0]


def const(layout, fmt, name, values):
    """A constant region ``name`` of ``layout`` holding ``values`` (one row) in ``fmt``."""
    return layout.const(name, [word(fmt, v) for v in values])


# ---- views -------------------------------------------------------------------------------

def transpose(a):
    """``a^T``: entry ``(i, j)`` is ``a``'s ``(j, i)``."""
    return lambda i, j=0: a(j, i)


def block(a, row0=0, col0=0):
    """The sub-matrix of ``a`` from entry ``(row0, col0)``."""
    return lambda i, j=0: a(row0 + i, col0 + j)


def row(a, i):
    """Row ``i`` of ``a`` as a vector (a one-column matrix): entry ``k`` is ``a(i, k)``."""
    def view(k, j=0):
        assert j == 0, "a row view is one column"
        return a(i, k)
    return view


def fill(address):
    """Every entry at ``address`` (a scalar broadcast)."""
    return lambda i=0, j=0: address


def mirrored(a):
    """A destination writing entry ``(i, j)`` of a symmetric matrix and its mirror ``(j, i)``."""
    return lambda i, j=0: (a(i, j),) if i == j else (a(i, j), a(j, i))


def beside(a, b, cols):
    """``[a b]``: ``a`` (``cols`` columns) and ``b`` side by side."""
    return lambda i, j=0: a(i, j) if j < cols else b(i, j - cols)


def diagonal_blocks(a, b, n):
    """``[[a, 0], [0, b]]`` for the ``n x n`` ``a``: ``None`` (a structural zero) off the blocks."""
    def view(i, j=0):
        if (i < n) != (j < n):
            return None
        return a(i, j) if i < n else b(i - n, j - n)
    return view


def _check(check, i, j):
    return check(i, j) if callable(check) else check


# ---- operations --------------------------------------------------------------------------

def product(prog, dst, a, b, rows, inner, cols, *, init=None, neg=False, lower=False, reverse=False,
            check=None, one=None):
    """``dst = init + a b`` (``init - a b`` with ``neg``): ``a`` is ``rows x inner``, ``b``
    ``inner x cols``; ``init`` a view of ``dst``'s shape, or ``None`` for none.

    One :class:`~.program.Dot` an entry, row by row; with ``lower`` only the lower triangle
    ``j <= i`` (a symmetric result: give ``dst`` as :func:`mirrored` to write both halves).
    A sum's terms run over ``k`` ascending, descending with ``reverse`` (put last the term
    whose operands are ready last). ``check`` is ``None``, ``"pivot"``, ``"finite"`` or a
    function ``(i, j) -> check``.

    Structural zeros (an ``a``, ``b`` or ``init`` entry ``None``) are dropped, and with
    ``one`` (the constant 1's address) the first term ``1 * b`` not negated becomes the
    addend of an entry without ``init``; an entry left with no term is its addend copied, or
    with none not written at all (a structural zero of the result)."""
    ks = range(inner - 1, -1, -1) if reverse else range(inner)
    for i in range(rows):
        for j in range(i + 1 if lower else cols):
            start, terms = _terms(a, b, i, j, ks, neg, None if init is None else init(i, j), one)
            if terms:
                prog.emit(Dot(dst(i, j), start, terms, _check(check, i, j)))
            elif start is not None:
                prog.emit(Copy(dst(i, j), start, _check(check, i, j)))


def _terms(a, b, i, j, ks, neg, start, one):
    """The addend and the terms of entry ``(i, j)`` of ``a b``: a structural zero's (a view's
    ``None``) dropped, and with ``one`` the first term ``1 * b`` (or ``a * 1``), not negated,
    taken as the addend when there is none."""
    terms = []
    for k in ks:
        x, y = a(i, k), b(k, j)
        if x is None or y is None:
            continue
        if one is not None and start is None and not neg and one in (x, y):
            start = y if x == one else x
            continue
        terms.append((x, y, neg))
    return start, terms


def sparse_product(prog, work, a, b, rows, inner, cols, one):
    """``a b`` for operands whose structure is known at generation (views giving ``None`` for
    a structural zero, ``one``'s address for a 1), as a view of the result: an entry that is
    one word times 1 is that word and one with no term a structural zero (``None``), neither
    costing an operation; any other is one :class:`~.program.Dot` into ``work(i, j)`` (its
    first ``1 * b`` the addend), row by row."""
    out = {}
    for i in range(rows):
        for j in range(cols):
            start, terms = _terms(a, b, i, j, range(inner), False, None, one)
            if terms:
                prog.emit(Dot(work(i, j), start, terms))
                start = work(i, j)
            out[i, j] = start
    return lambda i, j=0: out[i, j]


def add(prog, dst, a, b, one, rows, cols=1, *, neg=False, check=None):
    """``dst = a + b`` (``a - b`` with ``neg``) entry by entry, row by row: one multiply-add
    ``a + 1 * b`` each (exact in the product), ``one`` the address of the constant 1."""
    for i in range(rows):
        for j in range(cols):
            prog.emit(Dot(dst(i, j), a(i, j), [(one, b(i, j), neg)], _check(check, i, j)))


def hadamard(prog, dst, a, b, rows, cols=1, check=None):
    """``dst = a * b`` entry by entry (one multiply each), row by row; a :func:`fill` ``b``
    scales ``a`` by one word."""
    for i in range(rows):
        for j in range(cols):
            prog.emit(Dot(dst(i, j), None, [(a(i, j), b(i, j), False)], _check(check, i, j)))


def ldl(prog, a, n, f, l, d, rd, one) -> None:
    """``a = L D L^T`` for the symmetric ``n x n`` ``a`` (its lower triangle read), column by
    column (Soh & Wu (23)-(24)).

    Writes L's strictly lower part into ``l(i, j)``, the pivots into ``d(j)`` (the first a
    copy of ``a(0, 0)``; each checked: err_pivot) and ``1 / d(j)`` into ``rd(j)`` for the
    columns with entries below the diagonal (one division a pivot; :func:`solve_ldl` forms
    the last). ``f(i, j) = L_ij D_j``, ``j >= 1``, is work (column 0's is ``a``'s own)."""
    def fa(i, j):
        return a(i, j) if j == 0 else f(i, j)
    for j in range(n):
        if j == 0:
            prog.emit(Copy(d(j), a(j, j), "pivot"))
        else:
            prog.emit(Dot(d(j), a(j, j), [(l(j, k), fa(j, k), True) for k in range(j)], "pivot"))
        for i in range(j + 1, n):
            if j:
                prog.emit(Dot(fa(i, j), a(i, j), [(l(i, k), fa(j, k), True) for k in range(j)]))
        if j + 1 < n:
            prog.emit(Div(rd(j), one, d(j)))
        for i in range(j + 1, n):
            prog.emit(Dot(l(i, j), None, [(fa(i, j), rd(j), False)]))


def cholesky(prog, a, n, l, s, d, rs, f, one) -> None:
    """``a = C C^T`` for the symmetric ``n x n`` ``a`` (its lower triangle read), column by
    column: C's diagonal into ``s(j)``, its strictly lower part into ``l(i, j)``.

    ``d(j) = a_jj - sum_k C_jk^2`` is checked as a pivot (err_pivot), ``rs(j) = 1 / s(j)``
    multiplies the column (no ``1 / d``: in binary16 the reciprocal of a variance such as
    1e-6 overflows, that of its square root does not); ``f(i, j)``, ``j >= 1``, is work."""
    for j in range(n):
        if j == 0:
            prog.emit(Copy(d(j), a(j, j), "pivot"))
        else:
            prog.emit(Dot(d(j), a(j, j), [(l(j, k), l(j, k), True) for k in range(j)], "pivot"))
        prog.emit(Sqrt(s(j), d(j)))
        prog.emit(Div(rs(j), one, s(j)))
        for i in range(j + 1, n):
            src = a(i, j)
            if j:
                src = f(i, j)
                prog.emit(Dot(src, a(i, j), [(l(i, k), l(j, k), True) for k in range(j)]))
            prog.emit(Dot(l(i, j), None, [(src, rs(j), False)]))


def forward_substitute(prog, y, b, l, n, rdiag=None, work=None) -> list[int]:
    """``y = L^-1 b`` for the vector ``b`` and the lower-triangular ``L``, whose strictly lower
    part is ``l(i, j)``: unit diagonal when ``rdiag`` is ``None``, else ``rdiag(i)`` holding
    ``1 / L_ii`` (``b_i - sum_j L_ij y_j`` then goes to ``work(i)`` and is multiplied).

    Returns the addresses of ``y``'s entries: with a unit diagonal ``y_0`` is ``b_0``'s own
    word (no copy), the others ``y(i)``."""
    out = []
    for i in range(n):
        terms = [(l(i, j), out[j], True) for j in range(i)]
        if rdiag is None:
            if i:
                prog.emit(Dot(y(i), b(i), terms))
            out.append(y(i) if i else b(i))
            continue
        src = b(i)
        if i:
            prog.emit(Dot(work(i), b(i), terms))
            src = work(i)
        prog.emit(Dot(y(i), None, [(src, rdiag(i), False)]))
        out.append(y(i))
    return out


def back_substitute(prog, x, b, l, n) -> None:
    """``x = L^-T b`` for the unit lower-triangular ``L`` (strictly lower part ``l(i, j)``),
    from the last entry up, each sum's terms from the last column down. ``x(n - 1)`` must
    already hold ``b_(n-1)`` (the step before writes it there: no copy)."""
    for j in range(n - 2, -1, -1):
        prog.emit(Dot(x(j), b(j), [(l(i, j), x(i), True) for i in range(n - 1, j, -1)]))


def solve_ldl(prog, x, b, rows, n, l, d, rd, one, fw, dv) -> None:
    """The right divide ``x = b (L D L^T)^-1`` (``x L D L^T = b``, ``b`` is ``rows x n``) with
    :func:`ldl`'s factor, one row of ``x`` at a time: forward substitution into ``fw``, a
    multiply by ``1 / D`` into ``dv`` (the last entry straight into ``x``), back substitution.
    Forms the last pivot's reciprocal ``rd(n - 1)`` first. ``fw`` and ``dv`` are ``rows x n``
    work (column 0 of ``fw`` and column ``n - 1`` of ``dv`` unused)."""
    prog.emit(Div(rd(n - 1), one, d(n - 1)))
    for p in range(rows):
        y = forward_substitute(prog, row(fw, p), row(b, p), l, n)
        xp, dp = row(x, p), row(dv, p)
        for j in range(n):
            prog.emit(Dot(dp(j) if j < n - 1 else xp(j), None, [(y[j], rd(j), False)]))
        back_substitute(prog, xp, dp, l, n)
