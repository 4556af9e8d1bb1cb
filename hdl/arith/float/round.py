"""The pieces every floating-point unit shares: operand unpacking, the rounding and packing
stage, the pipeline-register placement, and constructor checks.

A unit is a straight-line datapath: unpack the operands (:func:`unpack`), compute an exact or
sticky-truncated raw result, and hand it to :func:`round_pack`, which normalises, denormalises,
rounds to nearest even, packs and raises the flags. Pipeline registers go at named
*boundaries* of that datapath (:class:`Cuts`); a unit lists which boundaries get a register for
each stage count, so the latency is exactly the number of registers on the path.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import NamedTuple

from amaranth.hdl import C, Cat, Const, Module, Mux, Shape, Signal, Value, unsigned
from amaranth.lib import data, wiring

from .format import FloatFormat
from .timing import longest_stage

__all__ = ["SUBNORMAL_MODES", "ROUND_BOUNDARIES", "as_format", "ROUND_COUNT", "ROUND_UP", "ROUND_HALF", "FloatUnit", "UnitPlan", "Cuts", "unpack",
           "leading_zeros", "prepare_exponent", "round_pack", "check_unit_params"]

SUBNORMAL_MODES = ("ieee", "ftz")

#: Boundaries inside :func:`round_pack`, in datapath order: before the normalising shifter,
#: before the rounding increment, before the final select of special results.
ROUND_BOUNDARIES = ("round.shift", "round.round", "round.select")

#: A boundary before those, inside the leading-zero count (after the counts of blocks of
#: :data:`LZ_BLOCK` bits), for wide significands. Only a unit that chooses it passes it.
ROUND_COUNT = "round.count"
#: A boundary inside the rounding, after the increment and the exponent's adds and compares
#: (before the selects), for a unit that chooses it: "round.select"'s logic in two.
ROUND_UP = "round.up"
#: A boundary inside the normalising left shift (after its high bits' part), for a unit that
#: chooses it: "round.round"'s logic in two.
ROUND_HALF = "round.half"


def as_format(fmt) -> FloatFormat:
    """``fmt`` as a :class:`FloatFormat` (it may be one or its name); ``ValueError`` if neither."""
    if isinstance(fmt, str):
        fmt = FloatFormat.parse(fmt)
    if not isinstance(fmt, FloatFormat):
        raise ValueError(f"fmt must be a FloatFormat or a format name, not {fmt!r}")
    return fmt


def check_unit_params(fmt, subnormals, stages, plans, default):
    """Validate the common constructor arguments of a unit; returns ``(fmt, stages)``.

    ``fmt`` may be a :class:`FloatFormat` or its name; ``plans`` maps each allowed stage count
    to the boundaries that get a register; ``stages=None`` means ``default``.
    """
    fmt = as_format(fmt)
    if subnormals not in SUBNORMAL_MODES:
        raise ValueError(f"subnormals must be one of {', '.join(map(repr, SUBNORMAL_MODES))}, "
                         f"not {subnormals!r}")
    if stages is None:
        stages = default
    if isinstance(stages, bool) or not isinstance(stages, int) or stages not in plans:
        raise ValueError(f"stages must be an integer from {min(plans)} to {max(plans)}, "
                         f"not {stages!r}")
    return fmt, stages


class UnitPlan(NamedTuple):
    """A float unit's timing for one set of parameters (:meth:`FloatUnit.plan`)."""

    stages: int
    latency: int
    initiation_interval: int
    #: Stage count -> boundaries that get a register: every count the unit can place.
    plans: dict


class FloatUnit(wiring.Component):
    """Common frame of the pipelined units: parameters, properties and the output stage.

    A subclass sets ``PLANS`` (stage count -> boundaries that get a register, in datapath
    order, ending with ``"out"`` for the output register) and ``DEFAULT_STAGES``, or overrides
    :meth:`stage_plans` when they depend on the format, and writes
    ``datapath(m, cuts) -> (word, flags)``; :meth:`elaborate` registers the result at ``"out"``
    and drives ``o_y``, ``o_flags`` and ``o_valid``.
    """

    PLANS: dict[int, tuple[str, ...]] = {}
    DEFAULT_STAGES = 0

    def __new__(cls, *args, src_loc_at=0, **kwargs):
        cls.plan(*args, **kwargs)  # a bad argument raises before the unit exists
        # (the caller's frame is where the unit is made, for Amaranth's UnusedElaboratable)
        return super().__new__(cls, *args, src_loc_at=src_loc_at + 1, **kwargs)

    @classmethod
    def plan(cls, *args, **kwargs) -> UnitPlan:
        """The :class:`UnitPlan` of the unit the same arguments would construct, without
        constructing it (so no unit is left unelaborated); raises ``ValueError`` as the
        constructor does."""
        probe = cls._probe(*args, **kwargs)
        return UnitPlan(probe.stages, probe.latency, probe.initiation_interval, probe.PLANS)

    @classmethod
    def _probe(cls, *args, **kwargs):
        """The constructor's checks and attributes, and no component."""
        probe = object.__new__(cls)
        probe._plan_only = True
        cls.__init__(probe, *args, **kwargs)
        return probe

    def __init__(self, fmt, subnormals, stages, ports):
        """``ports(fmt)`` gives the signature members for the checked format."""
        fmt = as_format(fmt)
        self.PLANS, self.DEFAULT_STAGES = self.stage_plans(fmt, subnormals)
        self._fmt, self._stages = check_unit_params(fmt, subnormals, stages, self.PLANS,
                                                    self.DEFAULT_STAGES)
        self._subnormals = subnormals
        if not getattr(self, "_plan_only", False):
            super().__init__(ports(self._fmt))

    def stage_plans(self, fmt: FloatFormat, subnormals: str):
        """``(plans, default stage count)`` for ``fmt``: the class's ``PLANS`` and
        ``DEFAULT_STAGES`` unless the unit overrides this."""
        return type(self).PLANS, type(self).DEFAULT_STAGES

    def stage_segments(self, fmt: FloatFormat, subnormals: str):
        """The datapath as ``(boundary, delay)`` in order, by the delay model of
        :mod:`.timing`, for a unit whose ``PLANS`` are a table; ``None`` where the unit has
        no model (the iterative sin, cos and atan2: their step control sets the clock)."""
        return None

    @classmethod
    def stage_delays(cls, *args, **kwargs) -> dict[int, float] | None:
        """Stage count -> the longest stage's delay (ns) by the delay model, for every count
        the unit the same arguments would construct can place (``stages`` is ignored); or
        ``None`` for a unit without a model."""
        probe = cls._probe(*args, **kwargs)
        plans = probe.PLANS
        if hasattr(plans, "longest"):
            return {k: plans.longest(k) for k in plans}
        segments = probe.stage_segments(probe.fmt, probe.subnormals)
        if segments is None:
            return None
        return {k: longest_stage(segments, plan) for k, plan in plans.items()}

    @property
    def fmt(self) -> FloatFormat:
        return self._fmt

    @property
    def subnormals(self) -> str:
        return self._subnormals

    @property
    def stages(self) -> int:
        return self._stages

    @property
    def latency(self) -> int:
        """Cycles from ``i_valid`` to ``o_valid``: the register stages."""
        return self._stages

    @property
    def initiation_interval(self) -> int:
        return 1

    def datapath(self, m: Module, cuts: Cuts):
        raise NotImplementedError

    def elaborate(self, platform):
        m = Module()
        cuts = Cuts(m, self.PLANS[self._stages], self.i_valid)
        word, flags = self.datapath(m, cuts)
        v = cuts("out", y=word, flags=flags)
        cuts.check()
        m.d.comb += [self.o_y.eq(v.y), self.o_flags.eq(v.flags), self.o_valid.eq(cuts.valid)]
        return m


#: Amaranth's class of concatenations (``Cat``), which it does not export.
_Concat = type(Cat())


def _is_constant(value) -> bool:
    """Whether ``value`` is a constant (a ``Const``, or a ``Cat`` of them)."""
    if isinstance(value, data.View):
        return False
    try:
        Const.cast(value)
    except TypeError:
        return False
    return True


class Cuts:
    """Pipeline registers at the chosen boundaries of a straight-line datapath.

    The datapath passes every live value through each boundary by name
    (``v = cuts("align", sign=s, exp=e)``); at a chosen boundary they are registered, elsewhere
    they pass through as wires (a ``data.View`` stays a view of its layout). Data registers
    have no reset; the ``valid`` bit beside them has one, so the pipeline comes out of reset
    empty.

    Parameters
    ----------
    m : Module
        Where the registers go (``sync`` domain).
    chosen : iterable of str
        The boundaries that get a register.
    valid : Value
        The input valid bit; :attr:`valid` is its copy at the current boundary.
    """

    def __init__(self, m: Module, chosen, valid):
        self._m = m
        self._chosen = frozenset(chosen)
        self._seen: list[str] = []
        self._drivers: dict[int, tuple[Signal, Value]] = {}  # id -> (wire, its value)
        self.valid = valid

    def __call__(self, name: str, **values) -> SimpleNamespace:
        if name in self._seen:
            raise ValueError(f"boundary {name!r} passed twice")
        self._seen.append(name)
        tag = name.replace(".", "_")
        if name not in self._chosen:
            return SimpleNamespace(**{k: self.wire(f"{tag}_{k}", v) for k, v in values.items()})
        out = {}
        for key, v in values.items():
            shape = v.shape() if isinstance(v, data.View) else Value.cast(v).shape()
            if Shape.cast(shape).width == 0:  # nothing to register (and no zero-width wire)
                out[key] = v
                continue
            reg = Signal(shape, name=f"{tag}_{key}", reset_less=True)  # a view stays a view
            self._m.d.sync += reg.eq(v)
            out[key] = reg
        valid = Signal(name=f"{tag}_valid")
        self._m.d.sync += valid.eq(self.valid)
        self.valid = valid
        return SimpleNamespace(**out)

    def chooses(self, name: str) -> bool:
        """Whether ``name`` is a chosen boundary (for one that only exists when chosen)."""
        return name in self._chosen

    def wire(self, name: str, value) -> Signal:
        """``value`` as a named combinational signal.

        Every value used more than once should be one: Amaranth expressions are trees, so a
        shared subexpression is otherwise copied into each use (exponentially, in a deep
        datapath such as a leading-zero counter) by the simulator.
        """
        shape = value.shape() if isinstance(value, data.View) else Value.cast(value).shape()
        if Shape.cast(shape).width == 0 or _is_constant(value):
            return value  # (a constant is folded into its uses: a wire of it would be unused)
        sig = Signal(shape, name=name)
        self._m.d.comb += sig.eq(value)
        if not isinstance(value, data.View):
            self._drivers[id(sig)] = (sig, Value.cast(value))
        return sig

    def bits(self, value) -> list:
        """The bits of ``value``, lowest first: ``0`` or ``1`` where they are known constants
        (constant parts of a ``Cat``, constant bits of the value a :meth:`wire` was given),
        else 1-bit values. Amaranth folds such constants in the netlist; a unit folding them
        itself builds no logic that would be left unused."""
        value = Value.cast(value)
        if isinstance(value, Const):
            return [(value.value >> i) & 1 for i in range(len(value))]
        if isinstance(value, _Concat):
            return [bit for part in value.parts for bit in self.bits(part)]
        wire, driver = self._drivers.get(id(value), (None, None))
        if wire is value:
            return [b if isinstance(b, int) else value[i]
                    for i, b in enumerate(self.bits(driver))]
        return [value[i] for i in range(len(value))]

    def check(self):
        """Raise if a chosen boundary was never passed (a misspelt plan)."""
        missing = self._chosen.difference(self._seen)
        if missing:
            raise ValueError(f"boundaries {sorted(missing)} are not in the datapath")


def unpack(fmt: FloatFormat, word, subnormals: str = "ieee") -> SimpleNamespace:
    """Decode an operand word.

    Returns a namespace of values: ``sign``; ``exp``, the unbiased exponent (signed, ``emin``
    for zeros and subnormals); ``biased``, the same biased (the exponent field, but 1 for
    zeros and subnormals: no add, so exponent arithmetic on it is shorter); ``sig``, the
    significand with its hidden bit (``fmt.precision`` bits, value
    ``sig * 2**(exp - frac_bits)``); and the class bits ``is_zero``, ``is_sub``,
    ``is_normal``, ``is_inf``, ``is_nan`` (either kind), ``is_qnan``, ``is_snan``. With
    ``subnormals="ftz"`` a subnormal reads as a zero of its sign (``is_zero`` set, ``sig``
    zero, ``is_sub`` clear).
    """
    word = Value.cast(word)
    m, e = fmt.frac_bits, fmt.exp_bits
    sign = word[m + e]
    field = word[m:m + e]
    frac = word[:m]
    field_zero = field == 0
    field_ones = field == fmt.exp_max_field
    frac_zero = frac == 0
    ftz = subnormals == "ftz"
    is_sub = C(0, 1) if ftz else field_zero & ~frac_zero
    is_zero = field_zero if ftz else field_zero & frac_zero
    is_nan = field_ones & ~frac_zero
    biased = Mux(field_zero, 1, field)
    exp = Cat(biased, C(0, 1)).as_signed() - fmt.bias
    sig = Mux(field_zero, 0, Cat(frac, C(1, 1))) if ftz else Cat(frac, ~field_zero)
    return SimpleNamespace(
        sign=sign, exp=exp, biased=biased, sig=sig, is_zero=is_zero, is_sub=is_sub,
        is_normal=~field_zero & ~field_ones, is_inf=field_ones & frac_zero, is_nan=is_nan,
        is_qnan=is_nan & frac[m - 1], is_snan=is_nan & ~frac[m - 1])


#: Width of the blocks whose leading zeros :func:`leading_zeros` counts before a ``cut``.
LZ_BLOCK = 16


def leading_zeros(cuts: Cuts, x, name: str = "lz", *, cut=None) -> Value:
    """Count of leading zero bits of ``x`` (``len(x)`` when ``x`` is zero), a log-depth tree.

    ``x`` is a value, or its bits lowest first (each ``0``, ``1`` or a 1-bit value). Bits known
    to be constants (see :meth:`Cuts.bits`) are worked out here: the count is made only of the
    bits above the highest constant one, and subtrees of constants are not built (the back
    end would fold them and leave their named signals unused). ``cuts`` gives the
    combinational signals the other nodes are made of. The count has
    ``len(x).bit_length()`` bits.

    ``cut``, if given, is called between the counts of :data:`LZ_BLOCK`-bit blocks and the
    rest of the tree with the values the rest is made of (a dict), and returns them as they
    come out of a pipeline boundary.
    """
    bits = list(x) if isinstance(x, (list, tuple)) else cuts.bits(x)
    out_width = len(bits).bit_length()
    ones = [i for i, b in enumerate(bits) if isinstance(b, int) and b]
    if ones:  # a one stops the count: what lies below it does not matter
        bits = bits[ones[-1] + 1:]
    width = len(bits)
    variable = [b for b in bits if not isinstance(b, int)]
    if variable:
        wire = cuts.wire(f"{name}_in", Cat(variable))
        wire_bits = iter(wire[i] for i in range(len(variable)))
        bits = [b if isinstance(b, int) else next(wire_bits) for b in bits]
    levels = width.bit_length()  # of the tree, over the padded bits
    # A one below ``x`` caps the count at ``width`` and keeps every subtree's answer defined.
    nodes = [(None, b) for b in [0] * ((1 << levels) - width - 1) + [1] + bits]

    def path(level, index):
        """The node's place from the root, ``h`` for an upper half and ``l`` for a lower."""
        return "".join("lh"[index >> k & 1] for k in reversed(range(levels - level)))

    def _any(lo, hi, where):
        """``lo | hi``, a named signal when it is made of two values (but not at the root,
        where nothing uses it)."""
        if isinstance(lo, int) or isinstance(hi, int) or not where:
            return _or(hi, lo)
        return cuts.wire(f"{name}_any{where}", hi | lo)

    def node(level, index, lo, hi):
        """``(count, any)`` of two halves' ``lo`` and ``hi``, ints where they are constants;
        the counts of the halves have ``level - 1`` bits."""
        (count_lo, any_lo), (count_hi, any_hi) = lo, hi
        where = path(level, index)
        if level == 1:  # halves of one bit: the count is whether the upper one is zero
            count = 1 - any_hi if isinstance(any_hi, int) else ~any_hi
            return count, _any(any_lo, any_hi, where)
        if isinstance(any_hi, int):  # the half that decides is known
            part, top = (count_hi, 0) if any_hi else (count_lo, 1)
            count = part + (top << level - 1) if isinstance(part, int) else Cat(part, C(top, 1))
        else:
            count = cuts.wire(f"{name}_count{where}", Cat(
                Mux(any_hi, _const(count_hi, level - 1), _const(count_lo, level - 1)), ~any_hi))
        return count, _any(any_lo, any_hi, where)

    for level in range(1, levels + 1):
        if level == LZ_BLOCK.bit_length() and cut is not None:
            nodes = _cut_nodes(nodes, name, cut)
        nodes = [node(level, i, nodes[2 * i], nodes[2 * i + 1]) for i in range(len(nodes) // 2)]
    if cut is not None and levels < LZ_BLOCK.bit_length():
        nodes = _cut_nodes(nodes, name, cut)
    if not levels:  # a constant one on top
        return C(0, out_width)
    count = _const(nodes[0][0], levels)
    return Cat(count, C(0, out_width - len(count))) if len(count) < out_width else count


def _cut_nodes(nodes, name, cut):
    """``nodes`` of a leading-zero tree through ``cut``, constants beside it."""
    values = {f"{name}_{kind}{i}": v for i, nd in enumerate(nodes)
              for kind, v in zip(("count", "any"), nd) if isinstance(v, Value)}
    out = cut(values)
    return [tuple(out.get(f"{name}_{kind}{i}", v) for kind, v in zip(("count", "any"), nd))
            for i, nd in enumerate(nodes)]


def _or(a, b):
    """``a | b`` of two bits, each ``0``, ``1`` or a 1-bit value."""
    if isinstance(a, int) or isinstance(b, int):
        known, other = (a, b) if isinstance(a, int) else (b, a)
        return 1 if known else other
    return a | b


def _const(value, width: int) -> Value:
    """``value`` as a value, an int as a ``width``-bit constant."""
    return C(value, width) if isinstance(value, int) else value


def _signed(v) -> Value:
    """``v`` as a signed value of the same magnitude (one bit wider if it was unsigned)."""
    v = Value.cast(v)
    return v if v.shape().signed else Cat(v, C(0, 1)).as_signed()


def prepare_exponent(cuts: Cuts, fmt: FloatFormat, exp, width: int,
                     denormalise: bool = True, *, room=None, marker: bool = False) -> data.View:
    """The exponent side of :func:`round_pack`, to compute before the significand is ready.

    Pass the result through the datapath's boundaries and give it to :func:`round_pack` as
    ``exp`` (with a ``width``-bit ``sig`` and the same ``denormalise``): the adds and compares
    on the exponent then stay off the path through the leading-zero count.

    Give either ``exp``, the exponent of ``sig``'s top bit (as :func:`round_pack` takes it), or
    ``room = exp - emin``: the left shift that brings the top bit to ``emin``, which is also
    the biased exponent field the top bit would have minus one. Units working on biased
    exponent fields get it without an add (``None`` for ``exp`` then).

    Fields: ``room``; ``below``, ``room < 0``; ``right``, the denormalising right shift
    (capped where every bit is sticky); ``cap``, ``room`` clamped to 0 .. ``width`` (for the
    one that limits the leading-zero count). With ``marker``, that one itself instead of
    ``cap``: a ``width``-bit one-hot (or zero) field, wide to carry through registers, but
    its decoder is then off the path through the leading-zero count too.
    """
    if (exp is None) == (room is None):
        raise ValueError("prepare_exponent takes one of exp and room")
    if room is None:
        room = _signed(exp) - fmt.emin
    room = cuts.wire("room", _signed(room))
    right_max = fmt.precision + 1 if denormalise else 0
    layout = data.StructLayout({
        "room": room.shape(),
        "below": unsigned(1),
        "right": unsigned(right_max.bit_length()),
        **({"marker": unsigned(width)} if marker else {"cap": unsigned(width.bit_length())}),
    })
    prep = Signal(layout, name="exponent")
    below = room < 0
    cuts._m.d.comb += [prep.room.eq(room), prep.below.eq(below)]
    if marker:
        # From ``room`` itself, by equalities without a carry chain: the one is at the top
        # for ``room <= 0``, ``room`` places under it for ``0 < room < width``.
        cuts._m.d.comb += prep.marker.eq(Cat(*(room == width - 1 - i for i in range(width - 1)),
                                             below | (room == 0)))
    else:
        cuts._m.d.comb += prep.cap.eq(Mux(below, 0, Mux(room > width, width, room)))
    if denormalise:
        # Past p + 1 places the round bit is zero and every bit is sticky.
        cuts._m.d.comb += prep.right.eq(Mux(room < -right_max, right_max, Mux(below, -room, 0)))
    return prep


def _marker_bits(cap, width: int) -> list:
    """The bits, lowest first, of a ``width``-bit vector with a one where a significand's top
    bit would weigh ``2**emin`` (none if it weighs less): the one ``cap`` places under it."""
    return [cap == width - 1 - i for i in range(width)]


def _marker(fmt: FloatFormat, prep, exp, width: int) -> list:
    """:func:`_marker_bits` for :func:`round_pack`: from ``prep``, made there or prepared
    (with ``marker``), or constants for a constant ``exp`` (a conversion's), so that the
    leading-zero count folds them in."""
    if "marker" in prep.shape().members:
        return [prep.marker[i] for i in range(width)]
    if not isinstance(exp, data.View):
        try:
            room = Const.cast(exp).value - fmt.emin
        except TypeError:  # not a constant
            pass
        else:
            return [int(b) for b in _marker_bits(min(max(room, 0), width), width)]
    return _marker_bits(prep.cap, width)


def round_pack(cuts: Cuts, fmt: FloatFormat, *, sign, exp, sig, sticky=0, zero_sign=None,
               is_nan=0, is_inf=0, is_zero=0, invalid=0, divbyzero=0,
               subnormals: str = "ieee", denormalise: bool = True):
    """Round a raw result to ``fmt`` (nearest, ties to even) and pack it with its flags.

    Parameters
    ----------
    cuts : Cuts
        Places registers at :data:`ROUND_BOUNDARIES` if chosen.
    fmt : FloatFormat
    sign : Value, 1 bit
        Sign of a nonzero result (and of ``is_inf``/``is_zero`` specials).
    exp : Value, signed, or the view from :func:`prepare_exponent`
        Exponent of the most significant bit of ``sig``: the raw value is
        ``(sig + f) * 2**(exp - len(sig) + 1)`` with ``0 < f < 1`` if ``sticky`` else ``f = 0``.
        Any width: the unit sizes it for its whole exponent range.
    sig : Value, unsigned, ``W >= fmt.precision + 2`` bits
        Significand, normalised or not: leading zeros are counted and shifted out here, never
        below ``emin``; below ``emin`` it is shifted right. The ``W - precision`` bits under
        the rounding point of a normalised ``sig`` are the guard bits. A zero ``sig`` (with
        ``sticky`` clear) is an exact zero.
    sticky : Value, 1 bit
        Some nonzero bits below ``sig`` were dropped. When ``sticky`` is set (or ``sig``'s lowest
        bit stands for dropped bits), ``sig`` must have fewer leading zeros than ``W - precision
        - 1`` so the dropped bits stay below the round bit and the bit under it.
    zero_sign : Value, 1 bit, optional
        Sign of an exact zero result (``sig == 0``): for sums, ``+0`` unless both addends are
        negative. Defaults to ``sign``.
    is_nan, is_inf, is_zero : Value, 1 bit
        Special results that bypass the datapath: canonical NaN, infinity or zero of ``sign``
        (in that priority).
    invalid, divbyzero : Value, 1 bit
        Raise NV / DZ (only meaningful with a special result).
    subnormals : "ieee" or "ftz"
        ``"ftz"`` flushes a result that is tiny after rounding to a zero of its sign, with UF|NX.
    denormalise : bool
        ``False`` when the unit guarantees ``exp >= emin``, so no right shift is built (add, sub).

    Returns
    -------
    (word, flags) : Values of ``fmt.width`` and 5 bits (NX, UF, OF, DZ, NV from bit 0).

    Tininess is detected after rounding: a nonzero result is tiny if, rounded to the precision
    with an unbounded exponent, it is below ``2**emin``; UF is raised when it is tiny and
    inexact (``ieee``) or flushed (``ftz``). Overflow gives an infinity with OF|NX.
    Combinational except for the registers at the boundaries ``cuts`` chose.
    """
    sig = Value.cast(sig)
    p, m = fmt.precision, fmt.frac_bits
    width = len(sig)
    guard = width - p
    if guard < 2:
        raise ValueError(f"round_pack needs at least {p + 2} significand bits for {fmt.name}, "
                         f"got {width}")
    # Normalise without letting the exponent fall below emin; a result below emin is shifted
    # right instead. Both shift amounts come without arithmetic after the leading-zero count:
    # the right shift depends on the exponent alone (and runs beside the count), and a one
    # placed at the emin position caps the count at the left shift that reaches emin.
    prep = exp if isinstance(exp, data.View) else \
        prepare_exponent(cuts, fmt, exp, width, denormalise)
    fits = len(prep.marker) == width if "marker" in prep.shape().members else \
        len(prep.cap) == width.bit_length()
    if not fits:
        raise ValueError(f"the prepared exponent is for another significand width than {width}")
    if denormalise:
        right = fmt.precision + 1
        sig_r = cuts.wire("denorm", sig >> prep.right)
        # The bits shifted out, found beside the shifter: those of sig below the shift amount.
        mask = Cat(prep.right > i for i in range(right))
        lost = (sig[:right] & mask).any() | sticky
    else:
        sig_r, lost = sig, sticky
    marker = _marker(fmt, prep, exp, width)
    sig_bits = cuts.bits(sig)
    nonzero = C(1, 1) if any(isinstance(b, int) and b for b in sig_bits) else \
        cuts.wire("nonzero", sig.any())
    v = SimpleNamespace(sign=sign, zero_sign=sign if zero_sign is None else zero_sign,
                        sig=sig_r, lost=lost, room=prep.room, below=prep.below, nonzero=nonzero,
                        is_nan=is_nan, is_inf=is_inf, is_zero=is_zero, invalid=invalid,
                        divbyzero=divbyzero)

    def count_cut(values):
        """The boundary inside the leading-zero count, where a unit chooses it."""
        nonlocal v
        v = cuts(ROUND_COUNT, **vars(v), **values)
        return {key: getattr(v, key) for key in values}

    left = leading_zeros(cuts, [_or(s, k) for s, k in zip(sig_bits, marker)],
                         cut=count_cut if cuts.chooses(ROUND_COUNT) else None)
    v = cuts("round.shift", sign=v.sign, zero_sign=v.zero_sign, sig=v.sig, lost=v.lost,
             left=left, room=v.room, below=v.below, nonzero=v.nonzero, is_nan=v.is_nan,
             is_inf=v.is_inf, is_zero=v.is_zero, invalid=v.invalid, divbyzero=v.divbyzero)

    if cuts.chooses(ROUND_HALF):
        # The normalising shift in two stages: by the count's high bits (beside the exponent's
        # subtract), then by its low bits.
        k = (len(v.left) + 1) // 2
        coarse = (v.sig << Cat(C(0, k), v.left[k:]))[:width]
        v = cuts(ROUND_HALF, sign=v.sign, zero_sign=v.zero_sign, coarse=coarse, fine=v.left[:k],
                 lost=v.lost, exp_base=Mux(v.nonzero & ~v.below, v.room - v.left, 0),
                 nonzero=v.nonzero, is_nan=v.is_nan, is_inf=v.is_inf, is_zero=v.is_zero,
                 invalid=v.invalid, divbyzero=v.divbyzero)
        shifted, exp_base = (v.coarse << v.fine)[:width], v.exp_base
    else:
        shifted = (v.sig << v.left)[:width]
        # Biased exponent minus one for a normal result (the rounded significand's hidden bit
        # adds the one back; a carry out of the significand adds two): ``room - left``, which
        # is zero for subnormals (there the left shift is the room, back to emin); zero for
        # zero too.
        exp_base = Mux(v.nonzero & ~v.below, v.room - v.left, 0)
    v = cuts("round.round", sign=v.sign, zero_sign=v.zero_sign, shifted=shifted, lost=v.lost,
             exp_base=exp_base, nonzero=v.nonzero, is_nan=v.is_nan, is_inf=v.is_inf,
             is_zero=v.is_zero, invalid=v.invalid, divbyzero=v.divbyzero)

    keep = v.shifted[guard:]
    round_bit = v.shifted[guard - 1]
    rest = cuts.wire("rest", v.shifted[:guard - 1].any() | v.lost)
    inexact = round_bit | rest
    # The incremented significand, the exponent plus the carry and hidden bits it may have,
    # and the overflow compares are all made beside the rounding decision, which selects.
    up = cuts.wire("up", keep + 1)
    top = fmt.exp_max_field
    if cuts.chooses(ROUND_UP):
        # The increment and the exponent's adds and compares registered: the selects after.
        tiny = v.nonzero & ~v.shifted[width - 1] & ~v.shifted[guard - 2:width - 1].all()
        r = cuts(ROUND_UP, keep=keep, up=up, round_bit=round_bit, rest=rest, exp_base=v.exp_base,
                 exp_1=v.exp_base + 1, exp_2=v.exp_base + 2, over_0=v.exp_base >= top,
                 over_1=v.exp_base >= top - 1, over_2=v.exp_base >= top - 2, tiny=tiny,
                 sign=v.sign, zero_sign=v.zero_sign, nonzero=v.nonzero, lost=v.lost,
                 is_nan=v.is_nan, is_inf=v.is_inf, is_zero=v.is_zero, invalid=v.invalid,
                 divbyzero=v.divbyzero)
        mant = cuts.wire("mant", Mux(r.round_bit & (r.rest | r.keep[0]), r.up, r.keep))
        exp_field = Mux(mant[p], r.exp_2, Mux(mant[m], r.exp_1, r.exp_base))
        overflow = Mux(mant[p], r.over_2, Mux(mant[m], r.over_1, r.over_0))
        inexact, tiny, v = r.round_bit | r.rest, r.tiny, r
    else:
        # carry | hidden | fraction
        mant = cuts.wire("mant", Mux(round_bit & (rest | keep[0]), up, keep))
        exp_field = Mux(mant[p], v.exp_base + 2, Mux(mant[m], v.exp_base + 1, v.exp_base))
        overflow = Mux(mant[p], v.exp_base >= top - 2,
                       Mux(mant[m], v.exp_base >= top - 1, v.exp_base >= top))
        # ``shifted`` has its top bit at 2**emin. Tiny after rounding: below 2**emin, unless in
        # [2**(emin-1), 2**emin) and rounding up to 2**emin at full precision, which needs the
        # ones from 2**(emin-1) down to the round bit at that precision (bit G-2 here).
        tiny = v.nonzero & ~v.shifted[width - 1] & ~v.shifted[guard - 2:width - 1].all()
    v = cuts("round.select", sign=Mux(v.nonzero | v.lost, v.sign, v.zero_sign),
             special_sign=v.sign, exp_field=exp_field[:fmt.exp_bits], frac=mant[:m],
             overflow=overflow, inexact=inexact, tiny=tiny,
             is_nan=v.is_nan, is_inf=v.is_inf, is_zero=v.is_zero, invalid=v.invalid,
             divbyzero=v.divbyzero)

    flush = v.tiny if subnormals == "ftz" else C(0, 1)
    finite = Cat(v.frac, v.exp_field, v.sign)
    # Tiny and overflowing results are disjoint, so a flush and an overflow never meet.
    rounded = Mux(v.overflow, Cat(C(0, m), C(fmt.exp_max_field, fmt.exp_bits), v.sign),
                  Mux(flush, Cat(C(0, fmt.width - 1), v.sign), finite))
    special = Cat(C(0, m), Mux(v.is_inf, fmt.exp_max_field, 0)[:fmt.exp_bits], v.special_sign)
    word = Mux(v.is_nan, fmt.canonical_nan, Mux(v.is_inf | v.is_zero, special, rounded))
    rounded_flags = Cat(v.inexact | v.overflow | flush, v.tiny & (v.inexact | flush), v.overflow,
                        C(0, 2))
    special_flags = Cat(C(0, 3), v.divbyzero, v.invalid)
    flags = Mux(v.is_nan | v.is_inf | v.is_zero, special_flags, rounded_flags)
    return word, flags
