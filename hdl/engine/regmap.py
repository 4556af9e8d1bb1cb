"""An engine core's registers and memory buffer, declared once as data: the classes and the
placement rules every core on the engine shares (the UKF's map is
:func:`kfgen.hdl.ukf.regmap.ukf_map`, the IMM's :func:`kfgen.hdl.imm.regmap.imm_map`).

The map drives the bus decoder, the manifest (:func:`kfgen.gen.regdoc.map_manifest`), the
SystemRDL description and through PeakRDL the C header and the Markdown document
(:mod:`kfgen.gen.regdoc`). Pure Python (no Amaranth).

Placement
---------
One AXI4 slave, 32-bit data, byte addresses. The aperture is ``2 * B`` bytes, ``B`` the
smallest power of two that holds the buffer::

    0x0 .. 0x13      registers ID (64 bits), CTRL, STATUS, IRQ_ENABLE (with ``irq``)
    B   .. B + size  the buffer: the core's regions (the UKF's x, P, Q, R, sigma_points, ...)

The buffer regions follow one another with no gaps, in the order and with the element
addresses that the engine's operand memory gives them (the core's programs,
:mod:`kfgen.hdl.ukf.programs` for one, place them first, from word 0). So decoding is one address bit (registers or buffer), the
engine's word address is a slice of the bus address (``addr[log2 B - 1 : 2 + log2 words]``,
no adder), and region names only matter for the access check (one comparison against a
constant: the UKF's ``sigma_points`` is read-only). Everything else in the aperture is a hole.

Words
-----
An element of a format up to 32 bits wide takes one bus word (its value in the low bits;
the upper bits read 0 and are ignored on write); a wider one (binary64) takes two, low half
first, at consecutive addresses. Matrices are row-major: element (i, j) of a ``rows x cols``
region is at ``offset + (i * cols + j) * bytes per element``.

Access
------
``ro`` (register or region): reads return the value, a write answers SLVERR and changes
nothing. ``rw``: reads and writes. Fields: ``ro`` (writes ignored), ``rw``, ``w1c`` (reads
the bit; writing 1 clears it, 0 keeps it), ``w1p`` (reads 0; writing 1 acts once). A hole
answers SLVERR and reads 0.

Byte strobes: in registers a byte lane whose WSTRB bit is low keeps its byte, and w1c and w1p
bits act only where their lane's strobe is high (every field sits in byte 0). The buffer takes
whole bus words: a beat with all four strobes writes, one with none writes nothing (OKAY), any
other answers SLVERR and writes nothing (the engine's memory has no byte enables). A
two-word element (binary64) is written by its high half: writing the low half holds it in the
core, writing the high half then writes the element from both.

While STATUS.busy: a buffer write answers SLVERR and changes nothing (a step's operands are
never corrupted); a buffer read is answered (OKAY) once the step leaves its memory bank a
port, the R channel waiting until then, with the word as it is at that moment (a region the
step does not write reads as written); the registers stay readable and writable
(CTRL.reset stops the step, STATUS bits clear), but a write of CTRL with start set answers
SLVERR, changes nothing and sets STATUS.err_busy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from ..describe import ParamError

__all__ = ["Value", "Field", "Register", "Memory", "Decoded", "RegisterMap", "place_map", "status_registers",
           "Identity", "engine_registers",
           "BUS_DATA_WIDTH", "BUS_ID_WIDTH", "FIELD_ACCESS", "BLOCK_ACCESS",
           "REGION_ROLES"]

BUS_DATA_WIDTH = 32
#: AXI ID width of the slave (AWID/BID, ARID/RID); transactions complete in order.
BUS_ID_WIDTH = 4
FIELD_ACCESS = ("ro", "rw", "w1c", "w1p")
BLOCK_ACCESS = ("ro", "rw")
#: What a buffer region is for (a memory's ``role``), and what each role means.
REGION_ROLES = {
    "input": "software writes it, the core only reads it",
    "state": "software writes the initial value; the core reads it and overwrites it in place, a step or "
             "iteration at a time",
    "output": "the core writes it and software reads it; the core never reads what was there before",
}

_WORD = BUS_DATA_WIDTH // 8


class Value(NamedTuple):
    """A named value of a field."""

    name: str
    value: int
    desc: str


@dataclass(frozen=True)
class Field:
    """``width`` bits of a register from bit ``lsb``; ``reset`` is what it reads after reset
    (for ID's fields, the configuration)."""

    name: str
    lsb: int
    width: int
    access: str
    desc: str
    values: tuple[Value, ...] = ()
    reset: int = 0

    def __post_init__(self):
        if self.access not in FIELD_ACCESS:
            raise ValueError(f"field {self.name}: access must be one of {FIELD_ACCESS}, not {self.access!r}")
        if not 0 <= self.reset < 1 << self.width:
            raise ValueError(f"field {self.name}: reset {self.reset} does not fit {self.width} bits")
        for v in self.values:
            if not 0 <= v.value < 1 << self.width:
                raise ValueError(f"field {self.name}: value {v.name} = {v.value} does not fit {self.width} bits")

    @property
    def msb(self) -> int:
        return self.lsb + self.width - 1

    @property
    def mask(self) -> int:
        """The field's bits in its register."""
        return ((1 << self.width) - 1) << self.lsb


@dataclass(frozen=True)
class Register:
    """A register of ``width`` bits (a multiple of 32: wider ones are read word by word, low
    word first) at byte ``offset``."""

    name: str
    offset: int
    width: int
    desc: str
    fields: tuple[Field, ...]

    def __post_init__(self):
        if self.width % BUS_DATA_WIDTH or self.offset % (self.width // 8):
            raise ValueError(f"register {self.name}: width {self.width} at offset {self.offset:#x} "
                             "is not whole, aligned bus words")
        used = 0
        for f in sorted(self.fields, key=lambda f: f.lsb):
            if f.lsb < 0 or f.mask & used or f.msb >= self.width:
                raise ValueError(f"register {self.name}: field {f.name} overlaps another or leaves the register")
            if f.lsb // BUS_DATA_WIDTH != f.msb // BUS_DATA_WIDTH:
                raise ValueError(f"register {self.name}: field {f.name} straddles two bus words")
            used |= f.mask

    @property
    def access(self) -> str:
        return "ro" if all(f.access == "ro" for f in self.fields) else "rw"

    @property
    def size(self) -> int:
        """Bytes."""
        return self.width // 8

    @property
    def end(self) -> int:
        return self.offset + self.size

    def field(self, name: str) -> Field:
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(f"register {self.name} has no field {name!r}")


@dataclass(frozen=True)
class Memory:
    """A ``rows x cols`` row-major matrix of ``format`` elements at byte ``offset``, each
    element ``words`` bus words (low word first)."""

    name: str
    offset: int
    shape: tuple[int, int]
    format: str
    words: int
    access: str
    desc: str
    order: str = "row-major"
    role: str = ""     # one of REGION_ROLES ("" undeclared)
    layout: str = ""   # what a row and a column hold, how models or points are stacked

    def __post_init__(self):
        if self.access not in BLOCK_ACCESS:
            raise ValueError(f"memory {self.name}: access must be one of {BLOCK_ACCESS}, not {self.access!r}")
        if self.role and self.role not in REGION_ROLES:
            raise ValueError(f"memory {self.name}: role must be one of {tuple(REGION_ROLES)}, not {self.role!r}")
        if self.words not in (1, 2) or self.offset % _WORD:
            raise ValueError(f"memory {self.name}: {self.words} words per element at {self.offset:#x}")

    @property
    def rows(self) -> int:
        return self.shape[0]

    @property
    def cols(self) -> int:
        return self.shape[1]

    @property
    def elements(self) -> int:
        return self.rows * self.cols

    @property
    def element_size(self) -> int:
        """Bytes per element."""
        return self.words * _WORD

    @property
    def size(self) -> int:
        """Bytes."""
        return self.elements * self.element_size

    @property
    def end(self) -> int:
        return self.offset + self.size

    def address(self, row: int, col: int = 0, word: int = 0) -> int:
        """Byte address of bus word ``word`` (0 = low) of element (row, col)."""
        if not (0 <= row < self.rows and 0 <= col < self.cols and 0 <= word < self.words):
            raise IndexError(f"{self.name}[{row}, {col}] word {word} outside {self.rows} x {self.cols} "
                             f"x {self.words}")
        return self.offset + (row * self.cols + col) * self.element_size + word * _WORD

    def locate(self, index: int) -> tuple[int, int, int]:
        """(row, col, word) of the ``index``-th bus word of the region."""
        element, word = divmod(index, self.words)
        return (*divmod(element, self.cols), word)


class Decoded(NamedTuple):
    """What a bus address selects: ``kind`` ``"register"`` or ``"memory"``, its ``name``, and
    ``index``, the bus word inside it (``Memory.locate`` turns it into row, col, word)."""

    kind: str
    name: str
    index: int


@dataclass(frozen=True)
class RegisterMap:
    """Registers and memories in an aperture of ``2**address_width`` bytes."""

    registers: tuple[Register, ...]
    memories: tuple[Memory, ...]
    address_width: int
    buffer_base: int

    @property
    def size(self) -> int:
        """Bytes of the aperture (what an interconnect assigns the slave)."""
        return 1 << self.address_width

    @property
    def data_width(self) -> int:
        return BUS_DATA_WIDTH

    @property
    def id_width(self) -> int:
        return BUS_ID_WIDTH

    def __getitem__(self, name: str) -> Register | Memory:
        for block in self.registers + self.memories:
            if block.name == name:
                return block
        raise KeyError(f"no register or memory named {name!r}")

    def decode(self, addr: int) -> Decoded | None:
        """What byte address ``addr`` reaches (its bus word: the two low bits are byte lanes),
        or ``None`` for a hole or an address outside the aperture."""
        if not 0 <= addr < self.size:
            return None
        word = addr & ~(_WORD - 1)
        for kind, blocks in (("register", self.registers), ("memory", self.memories)):
            for b in blocks:
                if b.offset <= word < b.end:
                    return Decoded(kind, b.name, (word - b.offset) // _WORD)
        return None


def status_registers(events, what: str, irq: bool) -> list[Register]:
    """STATUS at 0xC (``busy``, then the w1c ``events``: (name, lsb, desc)) and, with ``irq``,
    IRQ_ENABLE at 0x10, of a core whose unit of work is a ``what`` (step, iteration)."""
    regs = [Register("STATUS", 0xC, 32, f"What the core is doing and how the last {what} ended; the event "
                     "bits stay set until written 1.", (
                         Field("busy", 0, 1, "ro", f"a{'n' if what[0] in 'aeiou' else ''} {what} is running; buffer "
                               "writes answer SLVERR, buffer reads wait for a free port"),
                         *(Field(name, lsb, 1, "w1c", desc) for name, lsb, desc in events),
                     ))]
    if irq:
        regs.append(Register(
            "IRQ_ENABLE", 0x10, 32, "Which STATUS events drive irq: irq = (STATUS & IRQ_ENABLE) != 0, a "
            "level, high until the event bits are cleared.",
            tuple(Field(name, lsb, 1, "rw", f"irq on STATUS.{name}") for name, lsb, _ in events)))
    return regs


@dataclass(frozen=True)
class Identity:
    """What a core on the engine declares about itself for the registers every such core
    has (:func:`engine_registers`): the rest of ID and CTRL is the engine's.

    Parameters
    ----------
    core : int
        ID.core, an ASCII letter (``0x55``, 'U').
    title : str
        The core as ID.core's description names it (``the UKF``).
    version : int
        ID.version of this configuration's map.
    sizes : tuple of (name, meaning, value)
        ID's 8-bit size fields from bit 32, in order (the UKF's n, nw, nv, m).
    work : str
        What one start runs (``step``, ``iteration``), in CTRL's and STATUS's descriptions.
    start : str
        CTRL.start's description.
    events : tuple of (name, lsb, desc)
        STATUS's w1c event bits (:func:`status_registers`).
    step : Field or None
        CTRL.step, for a core with several steps.
    """

    core: int
    title: str
    version: int
    sizes: tuple[tuple[str, str, int], ...]
    work: str
    start: str
    events: tuple[tuple[str, int, str], ...]
    step: Field | None = None


def engine_registers(identity: Identity, params) -> tuple[Register, ...]:
    """ID (64 bits: the core, the map's version, the format, P and the core's sizes), CTRL
    (start, reset and the core's step field), STATUS and with ``params.irq`` IRQ_ENABLE of an
    engine core that declares ``identity``."""
    fmt, work = params.fmt, identity.work
    article = "an" if work[0] in "aeiou" else "a"
    return (
        Register("ID", 0x0, 64, "What the core is and how it was generated, so software can discover its "
                 "configuration. Two bus words, low word first.", (
                     Field("core", 0, 8, "ro", f"core identifier, {identity.core:#04x} ({chr(identity.core)!r}) "
                           f"for {identity.title}", reset=identity.core),
                     Field("version", 8, 4, "ro", "version of this register and memory map", reset=identity.version),
                     Field("exp_bits", 12, 4, "ro", "float format of the buffer: exponent bits", reset=fmt.exp_bits),
                     Field("frac_bits", 16, 6, "ro", "float format of the buffer: stored fraction bits",
                           reset=fmt.frac_bits),
                     Field("pes", 22, 10, "ro", "processing elements P", reset=params.pes),
                     *(Field(name, 32 + 8 * i, 8, "ro", meaning, reset=value)
                       for i, (name, meaning, value) in enumerate(identity.sizes)),
                 )),
        Register("CTRL", 0x8, 32, f"Starts {article} {work}, or resets the core to idle.", (
            Field("start", 0, 1, "w1p", identity.start),
            Field("reset", 1, 1, "w1p", f"write 1 for a soft reset: a running {work} stops, the core is idle, "
                                        "STATUS is cleared; the buffer is kept"),
            *((identity.step,) if identity.step is not None else ()),
        )),
        *status_registers(identity.events, work, params.irq),
    )


def place_map(registers, regions, fmt, address_width=None) -> RegisterMap:
    """The map of ``registers`` (from 0x0) and a buffer of ``regions`` ((name, rows, cols,
    access, role, desc, layout), one after another in the engine's order) of ``fmt`` elements, at the
    smallest power of two above the registers and at least the buffer's size.

    Raises
    ------
    ParamError
        ``address_width`` when ``address_width`` is too narrow for the map.
    """
    words = 1 if fmt.width <= BUS_DATA_WIDTH else 2
    elements = sum(rows * cols for _, rows, cols, *_ in regions)
    need = max(elements * words * _WORD, registers[-1].end)
    base = 1 << (need - 1).bit_length()
    width = base.bit_length()  # registers in [0, base), buffer in [base, 2 base)
    if address_width is not None and address_width < width:
        raise ParamError("address_width", f"the map needs {width} address bits (registers at 0x0, the "
                                          f"{elements * words * _WORD}-byte buffer at {base:#x}), not "
                                          f"{address_width}")
    memories, offset = [], base
    for name, rows, cols, access, role, desc, layout in regions:
        mem = Memory(name, offset, (rows, cols), fmt.name, words, access, desc, role=role, layout=layout)
        memories.append(mem)
        offset = mem.end
    return RegisterMap(registers, tuple(memories), address_width or width, base)
