"""The parameters every engine core shares, checked one way (pure Python, no Amaranth): the
float format of the buffer, the divider and square root, and the bus (``irq``,
``address_width``, ``name``). A core's frozen parameter dataclass calls these from its
``__post_init__`` (:class:`kfgen.hdl.ukf.params.UkfParams`,
:class:`kfgen.hdl.imm.params.ImmParams`).
"""

from __future__ import annotations

from ..arith.float.format import FloatFormat
from ..describe import ParamError, check_name

__all__ = ["FORMAT_WIDTH_MAX", "ADDRESS_WIDTH_MAX", "DIV_SQRT", "GEN_PES_MAX", "GEN_CROSSBAR_MAX",
           "check_div_sqrt", "check_format", "check_bus", "check_generation"]

#: Widest float format: one element is at most two 32-bit bus words.
FORMAT_WIDTH_MAX = 64
#: Widest AXI address the core accepts (a 32-bit processor's address space).
ADDRESS_WIDTH_MAX = 32

#: The shared divider and square root: one result bit a cycle, or one operation a cycle.
DIV_SQRT = ("iterative", "pipelined")

#: Generation limits of an engine core (P processing elements, B operand banks): Amaranth's
#: netlist, its RTLIL and Yosys grow with the P x B crossbar between lanes and banks and with
#: the P-lane microcode word; above these, ``kfgen`` needs more than 60 s or 2 GB on a
#: two-core machine (docs/benchmarks.md; ``python -m kfgen.gen.bench_gen`` measures them).
GEN_PES_MAX = 16
GEN_CROSSBAR_MAX = 128


def check_generation(pes: int, banks: int, default_banks) -> None:
    """Refuse, before any build, an engine core that would not generate in 60 s and 2 GB: at
    most :data:`GEN_PES_MAX` PEs and a crossbar of at most :data:`GEN_CROSSBAR_MAX` lanes times
    banks. ``default_banks(P)`` is the core's default bank count, for the message."""
    why = "generation above that needs more than 60 s or 2 GB; see docs/benchmarks.md"
    if pes > GEN_PES_MAX:
        raise ParamError("pes", f"at most {GEN_PES_MAX}, not {pes} ({why})")
    if pes * banks > GEN_CROSSBAR_MAX:
        top = max(p for p in range(1, GEN_PES_MAX + 1) if p * default_banks(p) <= GEN_CROSSBAR_MAX)
        raise ParamError("pes", f"P = {pes} with {banks} banks is a {pes} x {banks} crossbar; P x banks must be at "
                                f"most {GEN_CROSSBAR_MAX} (P <= {top} with the default banks; {why})")


def check_div_sqrt(value, pes: int) -> str:
    """``div_sqrt`` of an engine core: ``iterative`` or ``pipelined`` (any case); ``None`` is
    iterative at P = 1, pipelined above."""
    kind = value.lower() if isinstance(value, str) else value
    if kind is None:
        kind = DIV_SQRT[0] if pes == 1 else DIV_SQRT[1]
    if kind not in DIV_SQRT:
        raise ParamError("div_sqrt", f"must be {' or '.join(DIV_SQRT)}, not {value!r}")
    return kind


def check_format(value) -> str:
    """The float format of an engine core's buffer, by its name: at most two bus words."""
    try:
        fmt = FloatFormat.parse(value)
    except ValueError as exc:
        raise ParamError("format", f"must be binary16, bfloat16, binary32, binary64 or eEmM: {exc}") from None
    if fmt.width > FORMAT_WIDTH_MAX:
        raise ParamError("format", f"{fmt.name} is {fmt.width} bits wide; the buffer holds formats of at "
                                   f"most {FORMAT_WIDTH_MAX} bits (two bus words)")
    return fmt.name


def check_bus(params) -> None:
    """``irq``, ``address_width`` (the range; whether the map fits is the map's check) and
    ``name`` of an AXI core."""
    if not isinstance(params.irq, bool):
        raise ParamError("irq", f"must be true or false, not {params.irq!r}")
    aw = params.address_width
    if aw is not None and (isinstance(aw, bool) or not isinstance(aw, int) or not 1 <= aw <= ADDRESS_WIDTH_MAX):
        raise ParamError("address_width", f"must be an integer in 1..{ADDRESS_WIDTH_MAX}, not {aw!r}")
    check_name(params.name)
