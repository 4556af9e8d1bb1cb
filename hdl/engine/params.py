"""The parameters every engine core shares, checked one way (pure Python, no Amaranth): the
float format of the buffer, the divider and square root, and the bus (``irq``,
``address_width``, ``name``). A core's frozen parameter dataclass calls these from its
``__post_init__`` (:class:`kfgen.hdl.ukf.params.UkfParams`,
:class:`kfgen.hdl.imm.params.ImmParams`).
"""

from __future__ import annotations

from ..arith.float.format import PRESETS, FloatFormat
from ..describe import ParamError, check_name

__all__ = ["BINARY32", "FORMAT_WIDTH_MAX", "ADDRESS_WIDTH_MAX", "DIV_SQRT", "GEN_PES_MAX", "GEN_CROSSBAR_MAX",
           "GEN_WORK_MAX", "GEN_WORK_PES", "WORK_RULE", "generation_work", "check_div_sqrt", "check_format", "check_bus",
           "check_generation", "check_work"]

#: The engine cores' default format.
BINARY32 = PRESETS["binary32"]
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
#: The scheduler's time grows with the programs' multiply-adds (faster than linearly), and the
#: program ROMs' elaboration with multiply-adds times P: generation stays within 60 s and 2 GB
#: while :func:`generation_work` is at most this (measured at the limit: 13-25 s at P <= 4,
#: 31-46 s at P = 16 with binary32 and binary64).
GEN_WORK_MAX = 20_000
GEN_WORK_PES = 4

_WHY = "generation above that needs more than 60 s or 2 GB; see docs/benchmarks.md"
#: The work rule in words, for the parameters' help.
WORK_RULE = (f"the programs' multiply-adds x max({GEN_WORK_PES}, P) / {GEN_WORK_PES} at most "
             f"{GEN_WORK_MAX:,}, the most that generates in 60 s and 2 GB")


def check_generation(pes: int, banks: int, default_banks) -> None:
    """Refuse, before any build, an engine core that would not generate in 60 s and 2 GB: at
    most :data:`GEN_PES_MAX` PEs and a crossbar of at most :data:`GEN_CROSSBAR_MAX` lanes times
    banks. ``default_banks(P)`` is the core's default bank count, for the message."""
    why = _WHY
    if pes > GEN_PES_MAX:
        raise ParamError("pes", f"at most {GEN_PES_MAX}, not {pes} ({why})")
    if pes * banks > GEN_CROSSBAR_MAX:
        top = max(p for p in range(1, GEN_PES_MAX + 1) if p * default_banks(p) <= GEN_CROSSBAR_MAX)
        raise ParamError("pes", f"P = {pes} with {banks} banks is a {pes} x {banks} crossbar; P x banks must be at "
                                f"most {GEN_CROSSBAR_MAX} (P <= {top} with the default banks; {why})")


def generation_work(fma: int, pes: int) -> int:
    """The generation work of programs of ``fma`` multiply-adds on ``pes`` PEs: the
    multiply-adds, times P / :data:`GEN_WORK_PES` above that many PEs."""
    return fma * max(GEN_WORK_PES, pes) // GEN_WORK_PES


def check_work(fma: int, pes: int, sizes: str, at_least: bool = False) -> None:
    """Refuse programs of ``fma`` multiply-adds on ``pes`` PEs whose :func:`generation_work`
    is above :data:`GEN_WORK_MAX`: ``ParamError("pes")`` when fewer PEs would generate,
    else ``ParamError(sizes)`` (the parameter that names the core's sizes). ``at_least``:
    ``fma`` is a lower bound from the sizes alone (checked before the programs are built)."""
    if generation_work(fma, pes) <= GEN_WORK_MAX:
        return
    held = f"these sizes' programs hold {'at least ' if at_least else ''}{fma:,} multiply-adds"
    rule = (f"multiply-adds x max({GEN_WORK_PES}, P) / {GEN_WORK_PES} must be at most {GEN_WORK_MAX:,}")
    if fma <= GEN_WORK_MAX:
        top = max(p for p in range(1, GEN_PES_MAX + 1) if generation_work(fma, p) <= GEN_WORK_MAX)
        fewer = f"fewer PEs than {pes}" if at_least else f"P <= {top} for these sizes"
        raise ParamError("pes", f"{held}: at P = {pes} that is more than generates ({rule}: {fewer}; {_WHY})")
    raise ParamError(sizes, f"{held}, more than generates ({rule}; {_WHY})")


def check_div_sqrt(value, pes: int) -> str:
    """``div_sqrt`` of an engine core: ``iterative`` or ``pipelined`` (any case); ``None`` is
    iterative at P = 1, pipelined above."""
    kind = value.lower() if isinstance(value, str) else value
    if kind is None:
        kind = DIV_SQRT[0] if pes == 1 else DIV_SQRT[1]
    if kind not in DIV_SQRT:
        raise ParamError("div_sqrt", f"must be {' or '.join(DIV_SQRT)}, not {value!r}")
    return kind


def check_format(value) -> FloatFormat:
    """The float format of an engine core's buffer (a :class:`FloatFormat`, or its name in
    any case): at most two bus words. The one value the parameters keep."""
    try:
        fmt = FloatFormat.parse(value)
    except ValueError as exc:
        raise ParamError("format", f"must be binary16, bfloat16, binary32, binary64 or eEmM: {exc}") from None
    if fmt.width > FORMAT_WIDTH_MAX:
        raise ParamError("format", f"{fmt.name} is {fmt.width} bits wide; the buffer holds formats of at "
                                   f"most {FORMAT_WIDTH_MAX} bits (two bus words)")
    return fmt


def check_bus(params) -> None:
    """``irq``, ``address_width`` (the range; whether the map fits is the map's check) and
    ``name`` of an AXI core."""
    if not isinstance(params.irq, bool):
        raise ParamError("irq", f"must be true or false, not {params.irq!r}")
    aw = params.address_width
    if aw is not None and (isinstance(aw, bool) or not isinstance(aw, int) or not 1 <= aw <= ADDRESS_WIDTH_MAX):
        raise ParamError("address_width", f"must be an integer in 1..{ADDRESS_WIDTH_MAX}, not {aw!r}")
    check_name(params.name)
