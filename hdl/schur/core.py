"""The Schur-complement inversion unit: a stream of symmetric matrices in, their inverses and
determinants out (Hackett et al.'s Schur-complement unit, generalised to ``d x d``).

The datapath is the graph of :func:`~kfgen.hdl.schur.program.schur_program`, one
floating-point unit per operation, scheduled as soon as possible
(:func:`~kfgen.hdl.schur.program.schedule`): every operand waits in a delay line (registers
without reset, which map to shift-register LUTs) until its partner is ready, and every result
until the last one. The units never stall, so backpressure on ``m_axis`` is taken by an output
FIFO: a credit counter admits a matrix only when the FIFO is sure to have room for it. A
status word travels beside the matrix: each pivot's check where the pivot is computed, each
unit's IEEE flags where its result appears, OR-ed in on the way.

Bit-exact twin: :func:`kfgen.sim.schur.model.golden`.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import data, fifo, wiring
from amaranth.lib.wiring import In, Out

from ..arith.float.add import FloatAdd, FloatSub
from ..arith.float.div import FloatDiv
from ..arith.float.format import FloatFormat
from ..arith.float.mul import FloatMul
from ..arith.pipeline import Pipeline, Staged
from .params import SchurParams
from .program import schedule, schur_program, upper

__all__ = ["Schur", "matrix_layout", "result_layout", "status_layout", "FIFO_LATENCY"]

#: Cycles from the FIFO's write to its output (``SyncFIFOBuffered``: its memory, then its
#: output register).
FIFO_LATENCY = 2


def matrix_layout(fmt: FloatFormat, d: int) -> data.StructLayout:
    """The input payload: the upper triangle ``a_ij``, ``i <= j``, row by row, LSB first."""
    return data.StructLayout({f"a{i}{j}": fmt.width for i, j in upper(d)})


def result_layout(fmt: FloatFormat, d: int) -> data.StructLayout:
    """The output payload: the inverse's upper triangle ``inv_ij`` row by row, then ``det``."""
    return data.StructLayout({**{f"inv{i}{j}": fmt.width for i, j in upper(d)}, "det": fmt.width})


def status_layout() -> data.StructLayout:
    """``pivot``: a pivot was not > 0 (zero, negative or NaN: not positive definite); ``nan``: an
    input word was NaN; ``flags``: the OR of every operation's IEEE flags (NX, UF, OF, DZ, NV
    from bit 0)."""
    return data.StructLayout({"pivot": 1, "nan": 1, "flags": 5})


_UNITS = {"mul": FloatMul, "add": FloatAdd, "sub": FloatSub, "div": FloatDiv}


def _is_nan(fmt: FloatFormat, w):
    return (w[fmt.frac_bits:fmt.width - 1] == fmt.exp_max_field) & (w[:fmt.frac_bits] != 0)


def _not_positive(fmt: FloatFormat, w):
    """``not (w > 0)``: NaN, a negative number, or a zero of either sign."""
    return _is_nan(fmt, w) | w[fmt.width - 1] | (w[:fmt.width - 1] == 0)


class Schur(wiring.Component):
    """Inverse and determinant of symmetric positive-definite ``d x d`` matrices.

    Parameters
    ----------
    params : SchurParams

    Members
    -------
    s_axis_tvalid : In(1); s_axis_tready : Out(1)
        The matrix stream's handshake; ``s_axis_tready`` does not depend on ``s_axis_tvalid``.
    s_axis_tdata : In(matrix_layout(fmt, d))
        The upper triangle of the matrix.
    m_axis_tvalid : Out(1); m_axis_tready : In(1)
        The result stream's handshake; ``m_axis_tvalid`` does not depend on ``m_axis_tready``.
    m_axis_tdata : Out(result_layout(fmt, d))
        The upper triangle of the inverse and the determinant.
    m_axis_tuser : Out(status_layout())
        The status of this result.

    One result per accepted matrix, in order, ``latency`` cycles after it was accepted when
    ``m_axis`` is ready; a new matrix every ``initiation_interval`` cycles (the dividers'
    cycles per operation: one a clock when they are pipelined).
    """

    def __init__(self, params: SchurParams):
        self._p = params
        self._prog = schur_program(params.d)
        self._ready = schedule(self._prog, params.latencies)
        self._end = max(self._ready[n] for n in self._prog.outputs)
        fmt = params.fmt
        super().__init__({
            "s_axis_tvalid": In(1),
            "s_axis_tready": Out(1),
            "s_axis_tdata": In(matrix_layout(fmt, params.d)),
            "m_axis_tvalid": Out(1),
            "m_axis_tready": In(1),
            "m_axis_tdata": Out(result_layout(fmt, params.d)),
            "m_axis_tuser": Out(status_layout()),
        })

    @property
    def params(self) -> SchurParams:
        return self._p

    @property
    def program(self):
        return self._prog

    @property
    def datapath_latency(self) -> int:
        """Cycles from the registered matrix to its last result: the graph's longest path."""
        return self._end

    @property
    def latency(self) -> int:
        """Cycles from the input handshake to ``m_axis_tvalid`` (with ``m_axis`` ready): the
        input register, the datapath and the FIFO."""
        return 1 + self._end + FIFO_LATENCY

    @property
    def initiation_interval(self) -> int:
        return self._p.div_cycles_per_op

    @property
    def fifo_depth(self) -> int:
        """Results the FIFO holds: every matrix that can be in flight, and one more, so that
        with ``m_axis`` ready a matrix is admitted every ``initiation_interval`` cycles."""
        return -(-self.latency // self.initiation_interval) + 1

    def elaborate(self, platform):
        m = Module()
        p, prog, fmt = self._p, self._prog, self._p.fmt
        pl = Pipeline(m)
        accept = Signal()
        m.d.comb += accept.eq(self.s_axis_tvalid & self.s_axis_tready)

        # Stage 0: the accepted matrix, registered.
        valid0 = Signal()
        m.d.sync += valid0.eq(accept)
        valid = Staged(valid0, 0)
        value = {}  # node -> Staged, or ("neg", node)
        status = {}  # stage -> status words OR-ed in there
        sign = Const(fmt.sign_mask, fmt.width)

        def get(node, stage):
            v = value[node]
            if isinstance(v, tuple):  # a negation, on the delayed operand
                return get(v[1], stage) ^ sign
            return pl.at(v, stage)

        def flag(stage, **fields):
            word = Signal(status_layout(), name=f"status_in_{stage}_{len(status.get(stage, ()))}")
            m.d.comb += [getattr(word, k).eq(v) for k, v in fields.items()]
            status.setdefault(stage, []).append(word.as_value())

        for n, node in enumerate(prog.nodes):
            if node.op == "in":
                word = Signal(fmt.width, name=node.name, reset_less=True)
                m.d.sync += word.eq(getattr(self.s_axis_tdata, node.name))
                value[n] = Staged(word, 0)
                flag(0, nan=_is_nan(fmt, word))
            elif node.op == "one":
                value[n] = Staged(Const(fmt.pack(0, fmt.bias, 0), fmt.width), 0)
            elif node.op == "neg":
                value[n] = ("neg", node.args[0])
            else:
                unit = _UNITS[node.op](fmt, stages=p.latencies[node.op],
                                       **({"cycles_per_op": p.div_cycles_per_op} if node.op == "div" else {}))
                m.submodules[f"{node.op}_{node.name}"] = unit
                start = max(self._ready[a] for a in node.args)
                go = pl.at(valid, start)
                # An iterative divider is always ready here: matrices enter no closer than its
                # cycles per operation, and every path keeps their spacing.
                m.d.comb += [
                    unit.i_valid.eq(go & unit.i_ready if hasattr(unit, "i_ready") else go),
                    unit.i_a.eq(get(node.args[0], start)),
                    unit.i_b.eq(get(node.args[1], start)),
                ]
                assert start + unit.latency == self._ready[n]
                y = Signal(fmt.width, name=node.name, reset_less=True)
                m.d.comb += y.eq(unit.o_y)
                value[n] = Staged(y, self._ready[n])
                flag(self._ready[n], flags=Mux(unit.o_valid, unit.o_flags, 0))
        for n in prog.pivots:
            flag(self._ready[n], pivot=_not_positive(fmt, get(n, self._ready[n])))

        # The status word travels with the matrix, the flags of each stage OR-ed in.
        acc = None
        for stage in sorted(status):
            assert stage <= self._end
            terms = status[stage] + ([pl.at(acc, stage)] if acc is not None else [])
            word = Signal(len(terms[0]), name=f"status_{stage}", reset_less=True)
            m.d.comb += word.eq(_or(terms))
            acc = Staged(word, stage)
        end = self._end
        result = Cat(get(node, end) for node in prog.outputs)

        # Results into the FIFO; the credit counter guarantees it has room.
        depth = self.fifo_depth
        m.submodules.ofifo = ofifo = fifo.SyncFIFOBuffered(width=len(result) + len(acc.sig), depth=depth)
        m.d.comb += [
            ofifo.w_data.eq(Cat(result, pl.at(acc, end))),
            ofifo.w_en.eq(pl.at(valid, end)),
            self.m_axis_tvalid.eq(ofifo.r_rdy),
            Cat(self.m_axis_tdata.as_value(), self.m_axis_tuser.as_value()).eq(ofifo.r_data),
            ofifo.r_en.eq(self.m_axis_tready),
        ]
        credits = Signal(range(depth + 1))
        room = Signal(init=1)  # registered ``credits < depth``
        popped = self.m_axis_tvalid & self.m_axis_tready
        up, down = accept & ~popped, ~accept & popped
        m.d.sync += [
            credits.eq(Mux(up, credits + 1, Mux(down, credits - 1, credits))),
            room.eq(Mux(up, credits < depth - 1, Mux(down, 1, credits < depth))),
        ]
        ii = self.initiation_interval
        if ii > 1:
            # One matrix every ii cycles, what the iterative dividers take.
            wait = Signal(range(ii), name="accept_wait")
            with m.If(accept):
                m.d.sync += wait.eq(ii - 1)
            with m.Elif(wait != 0):
                m.d.sync += wait.eq(wait - 1)
            m.d.comb += self.s_axis_tready.eq(room & (wait == 0))
        else:
            m.d.comb += self.s_axis_tready.eq(room)
        return m


def _or(terms):
    out = terms[0]
    for t in terms[1:]:
        out = out | t
    return out
