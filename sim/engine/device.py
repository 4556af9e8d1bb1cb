"""An engine core as 32-bit MMIO over its golden model, no RTL: what a driver sees of the core
(``read(offset)``, ``write(offset, value)``), for testing a driver in milliseconds.

:class:`GoldenDevice` keeps the golden memory (:func:`kfgen.sim.linalg.exec.run` on the core's
own programs, with its prologue), the registers of the manifest's map (ID's reset values,
CTRL, STATUS with its write-one-to-clear events, IRQ_ENABLE) and the buffer at the map's
offsets (a two-word element is stored when its high half is written, as the core does). A
write of ``CTRL.start`` runs the step at once: STATUS then reads ``done`` and the step's error
bits, never ``busy``.
"""

from __future__ import annotations

import numpy as np

from kfgen.sim.linalg.exec import from_words

from .prologue import Prologue

__all__ = ["GoldenDevice"]


class GoldenDevice:
    """The core of ``manifest`` (its ``TOP.json``) as MMIO over the golden model.

    Parameters
    ----------
    manifest : dict
        The core's manifest.
    params_cls : type
        The core's parameter class (``KfParams``, ...).
    programs : callable
        Parameters -> the core's programs (``fmt``, ``layout``, ``steps``, optional
        ``prologue``), as a testbench's ``PROGRAMS``.

    Attributes
    ----------
    mem : list of int
        The golden memory, the layout's words.
    accesses : list of tuple
        Every access: ``("r", offset, word)`` or ``("w", offset, word)``.
    steps : list of str
        The steps started, in order.
    ran : list of list of str
        For each start, the programs it ran in order (a prologue's first, as the core runs it).
    """

    def __init__(self, manifest, params_cls, programs):
        self.manifest = manifest
        self.programs = programs(params_cls(**manifest["parameters"]))
        self.layout = self.programs.layout
        self.mem = self.layout.initial_memory()
        self.prologue = Prologue(self.programs)
        self.regs = {r["name"]: r for r in manifest["registers"]}
        self.words = manifest["memories"][0]["words_per_element"]
        self.regions = [(m["offset"], m["offset"] + 4 * self.words * m["shape"][0] * m["shape"][1],
                         self.layout[m["name"]]) for m in manifest["memories"]]
        self.ident = sum(f["reset"] << f["lsb"] for f in self.regs["ID"]["fields"])
        self.status = 0
        self.irq_enable = 0
        self.low = 0
        self.accesses = []
        self.steps = []
        self.ran = []

    def lsb(self, reg: str, name: str) -> int:
        """The lowest bit of field ``name`` of register ``reg``."""
        return next(f["lsb"] for f in self.regs[reg]["fields"] if f["name"] == name)

    def offset(self, region: str) -> int:
        """The byte offset of buffer region ``region``."""
        return next(m["offset"] for m in self.manifest["memories"] if m["name"] == region)

    def _element(self, offset):
        for lo, hi, reg in self.regions:
            if lo <= offset < hi:
                k, half = divmod((offset - lo) // 4, self.words)
                return reg.base + k, half
        return None, None

    def read(self, offset: int) -> int:
        word = self._read(offset)
        self.accesses.append(("r", offset, word))
        return word

    def _read(self, offset: int) -> int:
        ident = self.regs["ID"]["offset"]
        if offset in (ident, ident + 4):
            return self.ident >> (8 * (offset - ident)) & 0xFFFFFFFF
        if offset == self.regs["STATUS"]["offset"]:
            return self.status
        if offset == self.regs["CTRL"]["offset"]:
            return 0
        if "IRQ_ENABLE" in self.regs and offset == self.regs["IRQ_ENABLE"]["offset"]:
            return self.irq_enable
        a, half = self._element(offset)
        if a is None:
            raise ValueError(f"no register or buffer word at {offset:#x}")
        return self.mem[a] >> (32 * half) & 0xFFFFFFFF

    def write(self, offset: int, value: int) -> None:
        value = int(value) & 0xFFFFFFFF
        self.accesses.append(("w", offset, value))
        if offset == self.regs["CTRL"]["offset"]:
            if value >> self.lsb("CTRL", "reset") & 1:
                self.status = 0
                self.prologue.stale = True
            if value >> self.lsb("CTRL", "start") & 1:
                self._start(value)
            return
        if offset == self.regs["STATUS"]["offset"]:
            self.status &= ~value | 1  # write 1 to clear the events; busy is read-only
            return
        if "IRQ_ENABLE" in self.regs and offset == self.regs["IRQ_ENABLE"]["offset"]:
            self.irq_enable = value
            return
        a, half = self._element(offset)
        if a is None:
            raise ValueError(f"no writable register or buffer word at {offset:#x}")
        if self.words == 1:
            self.mem[a] = value
        elif half == 0:
            self.low = value
        else:
            self.mem[a] = self.low | value << 32
        self.prologue.wrote_word(a)

    def _start(self, word: int) -> None:
        fields = {f["name"]: f for f in self.regs["CTRL"]["fields"]}
        if "step" in fields:
            fd = fields["step"]
            number = word >> fd["lsb"] & ((1 << fd["width"]) - 1)
            step = next(k for k, v in fd["values"].items() if v == number)
        else:
            step = next(iter(self.programs.steps))
        self.steps.append(step)
        self.ran.append(self.prologue.steps(step))
        st = self.prologue.run(step, self.mem, self.ran[-1])
        for name, on in (("done", True), ("err_pivot", st.pivot), ("err_nan", st.nan)):
            if on:
                self.status |= 1 << self.lsb("STATUS", name)

    def values(self, name: str):
        """Region ``name`` of the golden memory as float64 values (rows x cols)."""
        reg = self.layout[name]
        return np.array(from_words(self.programs.fmt, self.mem[reg.base:reg.base + reg.size])).reshape(reg.rows,
                                                                                                         reg.cols)
