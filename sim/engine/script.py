"""A session with an engine core recorded as a script of bus operations: what the shipped
Verilog testbench (``TOP_tb.v``, :mod:`kfgen.gen.smoke`) replays against the RTL from
``TOP_vectors.hex``.

:class:`Script` drives the golden device (:class:`kfgen.sim.engine.device.GoldenDevice`) as
software drives the core, single 32-bit accesses in the order of the C and Python drivers,
and records each access: a write, a read with the word the golden model gives (the testbench
compares the core's with it), a start of a step with the cycles the manifest guarantees for
what the start runs (a prologue's program too), the end of an iteration. A core's plan
(``sim/<core>/smoke.py``) writes its initial state and model, then a few iterations of its
default scenario, and reads the estimate after each.
"""

from __future__ import annotations

import numpy as np

from kfgen.sim.linalg.exec import Status, from_words, to_words

from .device import GoldenDevice

__all__ = ["END", "WRITE", "READ", "START", "ITERATION", "Script"]

#: Operation codes of a script (and of ``TOP_vectors.hex``): the last operation, its data the
#: number of operations before it.
END = 0
#: A single-beat AXI4 write (address, data), answered OKAY.
WRITE = 1
#: A single-beat AXI4 read (address), answered OKAY with the data the golden model gives.
READ = 2
#: A write of CTRL.start (address, data), then the wait for the step: its argument the cycles
#: the manifest guarantees from the write to STATUS.done (0: none guaranteed).
START = 3
#: The end of an iteration (its argument its number, from 0): the testbench prints its cycles.
ITERATION = 4

_MASK = 0xFFFFFFFF


class Script:
    """Records a session with the core of ``manifest`` on its golden device.

    Parameters
    ----------
    manifest : dict
        The core's manifest (``TOP.json``).
    params
        The core's parameters (those it was generated from: an application's file by its
        path, where the manifest records its name alone).
    programs : callable
        Parameters -> the core's programs (as :class:`~kfgen.sim.engine.device.GoldenDevice`).

    Attributes
    ----------
    ops : list of tuple
        ``(op, address, data, argument, note)`` in order; ``note`` says what it is, for a reader.
    """

    def __init__(self, manifest, params, programs):
        self.device = GoldenDevice(manifest, lambda **_: params, programs)
        self.manifest = manifest
        self.fmt = self.device.programs.fmt
        self.regs = self.device.regs
        self.mems = {m["name"]: m for m in manifest["memories"]}
        self.words = self.device.words
        self.ops: list[tuple[int, int, int, int, str]] = []

    # ------------------------------------------------------------- single accesses
    def read(self, offset: int, note: str) -> int:
        word = self.device.read(offset)
        self.ops.append((READ, offset, word, 0, note))
        return word

    def write(self, offset: int, value: int, note: str) -> None:
        self.device.write(offset, value)
        self.ops.append((WRITE, offset, value & _MASK, 0, note))

    def _events(self) -> int:
        return sum(1 << self.device.lsb("STATUS", e) for e in ("done", "err_pivot", "err_nan", "err_busy"))

    def begin(self) -> None:
        """What a driver does first: read the ID register, reset the core softly, enable every
        interrupt (where the core has ``irq``) and read the enables back."""
        ident = self.regs["ID"]["offset"]
        self.read(ident, "ID[31:0]")
        self.read(ident + 4, "ID[63:32]")
        self.write(self.regs["CTRL"]["offset"], 1 << self.device.lsb("CTRL", "reset"), "CTRL.reset")
        if "IRQ_ENABLE" in self.regs:
            self.write(self.regs["IRQ_ENABLE"]["offset"], self._events(), "IRQ_ENABLE: every event")
            self.read(self.regs["IRQ_ENABLE"]["offset"], "IRQ_ENABLE")

    # ------------------------------------------------------------- the buffer
    def put_words(self, name: str, words) -> None:
        """Region ``name`` from its element words (a two-word element low word first)."""
        mem = self.mems[name]
        size = mem["shape"][0] * mem["shape"][1]
        if len(words) != size:
            raise ValueError(f"{name} holds {size} elements, not {len(words)}")
        for k, w in enumerate(words):
            for half in range(self.words):
                self.write(mem["offset"] + 4 * (k * self.words + half), int(w) >> (32 * half) & _MASK,
                           f"{name}[{k}]" + (f".{half}" if self.words > 1 else ""))

    def put(self, name: str, values) -> None:
        """Region ``name`` from float64 ``values`` (row-major), rounded to the core's format."""
        self.put_words(name, to_words(self.fmt, np.ravel(np.asarray(values, dtype=np.float64))))

    def get_words(self, name: str) -> list[int]:
        """Region ``name`` read word by word, each compared with the golden model's; its element words."""
        mem = self.mems[name]
        out = []
        for k in range(mem["shape"][0] * mem["shape"][1]):
            word = 0
            for half in range(self.words):
                word |= self.read(mem["offset"] + 4 * (k * self.words + half),
                                  f"{name}[{k}]" + (f".{half}" if self.words > 1 else "")) << (32 * half)
            out.append(word)
        return out

    def get(self, name: str) -> np.ndarray:
        """Region ``name`` read and compared word by word; its values (rows x cols)."""
        rows, cols = self.mems[name]["shape"]
        return np.array(from_words(self.fmt, self.get_words(name))).reshape(rows, cols)

    # ------------------------------------------------------------- steps
    def step(self, name: str) -> Status:
        """Start ``name``, wait for it (the testbench: ``irq``, or STATUS polled without one,
        its cycles checked), read STATUS (done and the error bits the golden model gives),
        clear it and read it clear. The golden model's status of the start."""
        ctrl = self.regs["CTRL"]
        word = 1 << self.device.lsb("CTRL", "start")
        step_field = next((f for f in ctrl["fields"] if f["name"] == "step"), None)
        if step_field is not None:
            word |= step_field["values"][name] << step_field["lsb"]
        before = len(self.device.ran)
        self.device.write(ctrl["offset"], word)
        ran = self.device.ran[before]
        cycles = sum(self.manifest["cycles"][s] for s in ran)
        self.ops.append((START, ctrl["offset"], word, cycles, "start " + " + ".join(ran)))
        status = self.regs["STATUS"]["offset"]
        word = self.read(status, "STATUS after " + name)
        self.write(status, word & self._events(), "STATUS: write 1 to clear")
        self.read(status, "STATUS clear")
        return Status(bool(word >> self.device.lsb("STATUS", "err_pivot") & 1),
                      bool(word >> self.device.lsb("STATUS", "err_nan") & 1), 0)

    def end_iteration(self, number: int) -> None:
        self.ops.append((ITERATION, 0, 0, number, f"end of iteration {number}"))

    def plan(self, about: str) -> dict:
        """The smoke testbench's plan (:mod:`kfgen.gen.smoke`): kind ``axi_script``, the
        operations, and what the testbench needs to wait without ``irq`` (STATUS and its done bit)."""
        ops = self.ops + [(END, 0, len(self.ops), 0, "end")]
        return {"kind": "axi_script", "about": about, "ops": ops,
                "status": self.regs["STATUS"]["offset"], "done_bit": self.device.lsb("STATUS", "done")}
