"""cocotb testbench for a group of generated floating-point units in one Verilator build.

``KFGEN_TB_GROUP`` names a JSON file: ``{"units": [{"prefix", "manifest", "stim", "out"}]}``.
The simulated top (written by :func:`kfgen.sim.fpu.run.fpu_group_wrapper`) exposes each
unit's ports as ``<prefix>_<port>``. Each stimulus ``.npz`` holds operand words ``a``
(and ``b``, ``c``), expected ``y`` and ``flags``, a ``gap`` probability and a ``seed``.

One coroutine drives every unit each cycle: operands at the falling edge (a new operation
when the previous one was accepted, i.e. ``i_valid & i_ready`` for iterative units, and not
during a random gap), handshakes and results sampled in the read-only phase. Each result
must arrive exactly ``latency_cycles`` after its operation was accepted, in order, and
equal the exact reference bit for bit and flag for flag.

Of the stream rules only the transmitter's apply, and only to the inputs of iterative units:
the testbench holds ``i_valid`` and the operands while ``i_ready`` is low, which a
:class:`~kfgen.sim.streams.StreamChecker` checks as a self-check. The results have no ready
(``o_valid`` is a one-cycle strobe the receiver must take), so nothing there has to hold.
"""

from __future__ import annotations

import json
import os

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, ReadOnly

from ..streams import StreamChecker

_FLAGS = ("NX", "UF", "OF", "DZ", "NV")


class _Unit:
    def __init__(self, dut, spec):
        self.prefix = spec["prefix"]
        self.manifest = json.loads(open(spec["manifest"]).read())
        self.out_path = spec["out"]
        stim = np.load(spec["stim"], allow_pickle=True)
        ports = {p["name"] for p in self.manifest["ports"]}
        self.operands = [k for k in ("a", "b", "c") if f"i_{k}" in ports]
        self.ops = {k: [int(x) for x in stim[k]] for k in self.operands}
        self.expect_y = [int(x) for x in stim["y"]]
        self.expect_flags = [int(x) for x in stim["flags"]]
        self.gap = float(stim["gap"])
        self.rng = np.random.default_rng(int(stim["seed"]))
        self.n = len(self.expect_y)
        self.latency = self.manifest["latency_cycles"]
        self.sig = {name: getattr(dut, f"{self.prefix}_{name}") for name in ports if name not in ("clk", "rst")}
        self.has_ready = "i_ready" in ports
        self.stream = StreamChecker(f"{self.prefix}_i", self.sig["i_valid"], self.sig["i_ready"],
                                    {f"i_{k}": self.sig[f"i_{k}"] for k in self.operands}) \
            if self.has_ready else None
        self.sent = 0
        self.valid = False
        self.accepted_at: list[int] = []
        self.got: list[tuple[int, int, int]] = []  # (y, flags, cycle)
        self.errors: list[str] = []

    def drive(self):
        if not self.valid and self.sent < self.n and self.rng.random() >= self.gap:
            for k in self.operands:
                self.sig[f"i_{k}"].value = self.ops[k][self.sent]
            self.valid = True
        self.sig["i_valid"].value = int(self.valid)

    def sample(self, cycle):
        if self.stream:
            self.stream.sample(cycle)
        if self.valid and (not self.has_ready or self.sig["i_ready"].value):
            self.accepted_at.append(cycle)
            self.sent += 1
            self.valid = False
        if self.sig["o_valid"].value:
            i = len(self.got)
            y, fl = int(self.sig["o_y"].value), int(self.sig["o_flags"].value)
            self.got.append((y, fl, cycle))
            if i >= self.n:
                self.errors.append(f"result {i} beyond the {self.n} operations")
            elif (y, fl) != (self.expect_y[i], self.expect_flags[i]) and len(self.errors) < 20:
                ops = " ".join(f"{k}={self.ops[k][i]:#x}" for k in self.operands)
                self.errors.append(
                    f"{self.prefix} #{i}: {ops}: got y={y:#x} flags={_names(fl)}, "
                    f"expected y={self.expect_y[i]:#x} flags={_names(self.expect_flags[i])}")
            elif i < len(self.accepted_at) and cycle - self.accepted_at[i] != self.latency \
                    and len(self.errors) < 20:
                self.errors.append(f"{self.prefix} #{i}: latency {cycle - self.accepted_at[i]}, "
                                   f"manifest says {self.latency}")

    @property
    def done(self):
        return len(self.got) >= self.n


def _names(flags):
    return "|".join(n for i, n in enumerate(_FLAGS) if flags >> i & 1) or "-"


@cocotb.test()
async def stream(dut):
    group = json.loads(open(os.environ["KFGEN_TB_GROUP"]).read())
    units = [_Unit(dut, spec) for spec in group["units"]]
    cocotb.start_soon(Clock(dut.clk, 10, unit="ns").start())
    dut.rst.value = 1
    for u in units:
        u.sig["i_valid"].value = 0
    for _ in range(2):
        await FallingEdge(dut.clk)
    dut.rst.value = 0
    cycle = 0
    limit = 1000 + 4 * max(u.n * (u.manifest["initiation_interval"] + 1) for u in units)
    while not all(u.done for u in units):
        await FallingEdge(dut.clk)
        cycle += 1
        assert cycle < limit, "timeout: " + ", ".join(f"{u.prefix} {len(u.got)}/{u.n}" for u in units)
        for u in units:
            u.drive()
        await ReadOnly()
        for u in units:
            u.sample(cycle)
    # nothing more may come out
    for _ in range(max(u.latency for u in units) + 4):
        await FallingEdge(dut.clk)
        cycle += 1
        for u in units:
            u.sig["i_valid"].value = 0
        await ReadOnly()
        for u in units:
            u.sample(cycle)
    for u in units:
        np.savez(u.out_path, y=np.array([g[0] for g in u.got], dtype=object),
                 flags=np.array([g[1] for g in u.got]), out_cycle=np.array([g[2] for g in u.got]),
                 in_cycle=np.array(u.accepted_at))
    errors = [e for u in units for e in u.errors]
    extra = [f"{u.prefix}: {len(u.got) - u.n} results too many" for u in units if len(u.got) != u.n]
    assert not errors and not extra, "\n".join(extra + errors)
