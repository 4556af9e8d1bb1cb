"""The Schur-complement inversion as a dataflow graph of rounded floating-point operations.

Pure Python (no Amaranth import): :class:`~kfgen.hdl.schur.core.Schur` gives every operation
its own unit and :func:`kfgen.sim.schur.model.golden` evaluates the same graph with the exact
reference, so the hardware and the golden model agree bit for bit by construction; the float64
evaluation (:func:`kfgen.sim.schur.model.evaluate_float64`) against numpy's inverse checks the
graph itself.

For a symmetric positive-definite ``A`` split as ``[[P, Q], [Q^T, R]]`` (``P`` is ``d1 x d1``,
``d1 = d // 2``; ``R`` is ``d2 x d2``, ``d2 = d - d1``), with the Schur complement
``S = R - Q^T P^-1 Q``::

    det A = det P * det S
    A^-1  = [[P^-1 + T S^-1 T^T, -T S^-1],
             [.,                  S^-1  ]]      T = P^-1 Q

and ``P^-1``, ``S^-1`` the same way, down to ``1 x 1`` blocks, whose inverse is one division
(``1 / p``, the *pivot* ``p`` checked > 0) and whose determinant is ``p``. For ``d = 2``
(``[[a, b], [b, c]]``) that is the slides' formula: ``s = c - b^2/a``, ``det = a s``,
``A^-1 = [[1/a + b^2/(a^2 s), -b/(a s)], [., 1/s]]``, with two divisions (``1/a``, ``1/s``)
and everything else multiplies and adds. Odd ``d`` split the same way (``d = 3``: a ``1 x 1``
pivot then a ``2 x 2`` Schur complement), so every ``d`` is ``d`` divisions.

Where the split's inner size is 1 the triple products are re-associated so that the late
factor, the pivot's reciprocal, is multiplied last: ``S_ij = R_ij - (1/p) (q_i q_j)`` and
``X_ij = P^-1_ij + (1/s) (t_i t_j)``, the products ``q_i q_j``, ``t_i t_j`` formed while the
division runs. For ``d = 2`` the longest path is then two divisions, two multiplies and two
adds. Sums of more than two products are balanced trees in the listed order.
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Node", "Program", "schur_program", "schedule", "upper", "OPS", "SIZE_MAX"]

#: Operations: the input words, the constant 1, the four rounded operations of the FPU units
#: and ``neg`` (the sign bit flipped: exact, no unit).
OPS = ("in", "one", "mul", "add", "sub", "div", "neg")

#: The largest size built: units grow as d^3 (d = 4: 43 multipliers, d = 8: 295 and 224 adders).
SIZE_MAX = 8


@dataclass(frozen=True)
class Node:
    """One value: ``op`` applied to the values ``args`` (indices of earlier nodes). ``name``
    names the signal in the hardware."""

    op: str
    args: tuple[int, ...]
    name: str


@dataclass
class Program:
    """The graph for ``d x d`` matrices, nodes in an order where every argument comes first.

    Members
    -------
    inputs : dict
        ``(i, j) -> node`` for the upper triangle ``i <= j``.
    inverse : dict
        ``(i, j) -> node`` of ``A^-1`` for ``i <= j``.
    det : int
        The node of ``det A``.
    pivots : list of int
        The nodes that must be > 0 for ``A`` to be positive definite (one per ``1 x 1`` block).
    """

    d: int
    nodes: list[Node] = field(default_factory=list)
    inputs: dict = field(default_factory=dict)
    inverse: dict = field(default_factory=dict)
    det: int = -1
    pivots: list[int] = field(default_factory=list)

    def add(self, op: str, args=(), name: str = "") -> int:
        assert op in OPS and all(0 <= a < len(self.nodes) for a in args)
        self.nodes.append(Node(op, tuple(args), name or f"{op}{len(self.nodes)}"))
        return len(self.nodes) - 1

    def count(self, op: str) -> int:
        return sum(n.op == op for n in self.nodes)

    @property
    def outputs(self) -> list[int]:
        """The result in port order: the inverse's upper triangle row by row, then ``det``."""
        return [self.inverse[k] for k in upper(self.d)] + [self.det]


def upper(d: int) -> list[tuple[int, int]]:
    """``(i, j)`` with ``i <= j``, row by row: the order of the stream's words."""
    return [(i, j) for i in range(d) for j in range(i, d)]


class _Sym:
    """A symmetric matrix held as its upper triangle: ``m[i, j] == m[j, i]``."""

    def __init__(self, upper_nodes: dict):
        self.u = upper_nodes

    def __getitem__(self, ij):
        i, j = ij
        return self.u[(min(i, j), max(i, j))]


def _tree(prog: Program, terms: list[int], name: str) -> int:
    """The sum of ``terms`` as a balanced tree of adds, pairs in the listed order."""
    level = 0
    while len(terms) > 1:
        pairs = [prog.add("add", (a, b), f"{name}_s{level}_{k}")
                 for k, (a, b) in enumerate(zip(terms[0::2], terms[1::2]))]
        terms = pairs + terms[len(pairs) * 2:]
        level += 1
    return terms[0]


def _dot(prog: Program, xs, ys, name: str) -> int:
    products = [prog.add("mul", (x, y), f"{name}_p{k}") for k, (x, y) in enumerate(zip(xs, ys))]
    return _tree(prog, products, name)


def _invert(prog: Program, m: _Sym, n: int, tag: str, one: int):
    """``(inverse as a _Sym, det node)`` of the ``n x n`` symmetric block ``m``."""
    if n == 1:
        pivot = m[0, 0]
        prog.pivots.append(pivot)
        return _Sym({(0, 0): prog.add("div", (one, pivot), f"{tag}r")}), pivot
    n1 = n // 2
    n2 = n - n1
    p = _Sym({(i, j): m[i, j] for i, j in upper(n1)})
    q = [[m[k, n1 + j] for j in range(n2)] for k in range(n1)]
    pi, det_p = _invert(prog, p, n1, tag + "p", one)
    if n1 == 1:
        # T = P^-1 Q and S = R - (1/p)(q_i q_j): the q products wait for the division, not after it.
        r = pi[0, 0]
        t = [[prog.add("mul", (r, q[0][j]), f"{tag}t0{j}") for j in range(n2)]]
        s = {}
        for i, j in upper(n2):
            qq = prog.add("mul", (q[0][i], q[0][j]), f"{tag}qq{i}{j}")
            s[(i, j)] = prog.add("sub", (m[n1 + i, n1 + j], prog.add("mul", (r, qq), f"{tag}rqq{i}{j}")),
                                 f"{tag}s{i}{j}")
    else:
        t = [[_dot(prog, [pi[k, l] for l in range(n1)], [q[l][j] for l in range(n1)], f"{tag}t{k}{j}")
              for j in range(n2)] for k in range(n1)]
        s = {(i, j): prog.add("sub", (m[n1 + i, n1 + j],
                                      _dot(prog, [q[k][i] for k in range(n1)], [t[k][j] for k in range(n1)],
                                           f"{tag}qt{i}{j}")), f"{tag}s{i}{j}")
             for i, j in upper(n2)}
    si, det_s = _invert(prog, _Sym(s), n2, tag + "s", one)
    # U = T S^-1; the upper right block of the inverse is -U.
    u = [[_dot(prog, [t[k][l] for l in range(n2)], [si[l, j] for l in range(n2)], f"{tag}u{k}{j}")
          for j in range(n2)] for k in range(n1)]
    x = {}
    for i, j in upper(n1):
        if n2 == 1:
            tt = prog.add("mul", (t[i][0], t[j][0]), f"{tag}tt{i}{j}")
            extra = prog.add("mul", (si[0, 0], tt), f"{tag}rtt{i}{j}")
        else:
            extra = _dot(prog, [u[i][l] for l in range(n2)], [t[j][l] for l in range(n2)], f"{tag}ut{i}{j}")
        x[(i, j)] = prog.add("add", (pi[i, j], extra), f"{tag}x{i}{j}")
    inv = dict(x)
    for i in range(n1):
        for j in range(n2):
            inv[(i, n1 + j)] = prog.add("neg", (u[i][j],), f"{tag}nu{i}{j}")
    for i, j in upper(n2):
        inv[(n1 + i, n1 + j)] = si[i, j]
    return _Sym(inv), prog.add("mul", (det_p, det_s), f"{tag}det")


def schur_program(d: int) -> Program:
    """The graph that inverts a symmetric ``d x d`` matrix and gives its determinant."""
    if isinstance(d, bool) or not isinstance(d, int) or not 1 <= d <= SIZE_MAX:
        raise ValueError(f"d must be an integer in 1..{SIZE_MAX}, not {d!r}")
    prog = Program(d)
    prog.inputs = {(i, j): prog.add("in", (), f"a{i}{j}") for i, j in upper(d)}
    one = prog.add("one", (), "one")
    inv, det = _invert(prog, _Sym(prog.inputs), d, "", one)
    prog.inverse = {k: inv[k] for k in upper(d)}
    prog.det = det
    return prog


def schedule(prog: Program, latency: dict) -> list[int]:
    """As soon as possible: the cycle each node's value is ready, counted from the inputs
    (cycle 0). An operation starts when its last argument is ready and its value is ready
    ``latency[op]`` cycles later (``mul``, ``add``, ``sub``, ``div``); ``neg`` and the
    constant take no time."""
    ready = []
    for node in prog.nodes:
        start = max((ready[a] for a in node.args), default=0)
        ready.append(start + latency.get(node.op, 0) if node.op in ("mul", "add", "sub", "div") else start)
    return ready
