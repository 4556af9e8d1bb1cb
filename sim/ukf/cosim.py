"""HW/SW co-simulation of a UKF application: a simulated processor drives the generated core
(Verilog in Verilator) through ``s_axi`` with cocotbext-axi's ``AxiMaster``, and every word it
reads back is held against the bit-exact golden model.

Two processors run the same iterations of an application (:mod:`kfgen.sim.ukf.app`):

* ``python_processor``: the software side written once in Python
  (:func:`kfgen.sim.ukf.software.iteration`) over :class:`AxiIO`;
* ``c_processor``: the generated C driver (``TOP_driver.c``, built as a shared library with
  ``-DKFGEN_MMIO_HOOKS``) whose MMIO hooks call back into the same AXI master through
  ctypes (``cocotb.task.bridge`` runs the C in a thread, ``cocotb.task.resume`` brings each
  access back into the simulation); f and h are the application's, as C callbacks.

Both go through :class:`CheckedBus`, which mirrors every access on :class:`GoldenBus` (the
golden model behind the same address map: writes land in its memory, a write of
``CTRL.start`` runs the step's program) and asserts that every word read from the buffer,
and every step's ``STATUS``, equals the model's. Nothing awaits every clock: the test waits
on ``irq`` (or polls ``STATUS``) and on the master's transfers, each wait for a step bounded
by :func:`kfgen.sim.engine.watchdog.bound` of its manifest cycles.

Environment: ``KFGEN_TB_MANIFEST`` (the core's ``TOP.json``), ``KFGEN_APP`` (``module:Class``),
``KFGEN_APP_DIR`` (the directory it is found from, put on ``sys.path``: there a module, and
the file name an on-chip core's manifest records, are found; a ``file.py:Class`` spec in
``KFGEN_APP`` must be absolute, the simulation runs elsewhere), ``KFGEN_STEPS``
(iterations), ``KFGEN_SEED``, ``KFGEN_BEATS`` (``burst`` or ``single``: every
transfer one beat at a time, as the chapter's processor), ``KFGEN_WAIT`` (``irq`` or ``poll``),
``KFGEN_DRIVER_LIB`` (the C driver's shared library, for ``c_processor``), ``KFGEN_COSIM_OUT``
(an ``.npz`` to write: the estimates after every iteration, the truth, and the cycles of
every step and transfer), ``KFGEN_COSIM_FAULT`` (a ``.json`` written when a step raises
``err_pivot`` or ``err_nan``: ``{"step", "bit", "iteration"}``, the test then fails).
"""

from __future__ import annotations

import ctypes
import json
import logging
import os
import time

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.simtime import get_sim_time
from cocotb.task import bridge
from cocotb.triggers import ClockCycles, RisingEdge
from cocotbext.axi import AxiBus, AxiMaster, AxiResp

from kfgen.hdl.ukf.params import UkfParams, covariance_region
from kfgen.hdl.ukf.steps import programs
from kfgen.sim.engine.mmio import Dev, Guard, c_function, set_hooks
from kfgen.sim.engine.prologue import Prologue
from kfgen.sim.engine.tb import CLOCK_NS, load_manifest
from kfgen.sim.engine.watchdog import Expired, Watchdog, wait_irq
from kfgen.sim.linalg.exec import Status, from_words

from .app import checked_scenario, load_app
from .software import StepError, initial_words, iteration


def steps_of(manifest) -> list[str]:
    """The steps software starts, in CTRL.step's order (not a prologue, which the core runs
    by itself: its cycles count in the step it precedes)."""
    ctrl = next(r for r in manifest["registers"] if r["name"] == "CTRL")
    values = next(f for f in ctrl["fields"] if f["name"] == "step")["values"]
    pre = manifest.get("prologue", {}).get("step")
    return [s for s in sorted(values, key=values.get) if s != pre]


class GoldenBus:
    """The golden model as the bus sees it: the manifest's map over the model's memory.

    ``write(addr, word)`` stores buffer words (a two-word element when its high half is
    written, as the core does) and runs a step on ``CTRL.start``; ``expect(addr)`` is the
    word a buffer read must return (None for a register)."""

    def __init__(self, manifest):
        self.params = UkfParams(**manifest["parameters"])
        self.ukf = programs(self.params)
        self.fmt, self.layout = self.ukf.fmt, self.ukf.layout
        self.mem = self.layout.initial_memory()
        self.words = manifest["memories"][0]["words_per_element"]
        self.regions = [(m["offset"], m["offset"] + 4 * self.words * m["shape"][0] * m["shape"][1],
                         self.layout[m["name"]]) for m in manifest["memories"]]
        regs = {r["name"]: r for r in manifest["registers"]}
        self.ctrl = regs["CTRL"]["offset"]
        fields = {f["name"]: f for f in regs["CTRL"]["fields"]}
        self.start_bit, self.step_field = fields["start"]["lsb"], fields["step"]
        self.steps = {v: k for k, v in self.step_field["values"].items()}
        self.low = None
        self.last = None  # the Status of the last step started
        self.prologue = Prologue(self.ukf)

    def _element(self, addr):
        for lo, hi, reg in self.regions:
            if lo <= addr < hi:
                k, half = divmod((addr - lo) // 4, self.words)
                return reg.base + k, half
        return None, None

    def write(self, addr, word):
        if addr == self.ctrl:
            if word >> self.start_bit & 1:
                f = self.step_field
                step = self.steps[word >> f["lsb"] & ((1 << f["width"]) - 1)]
                self.last = self.prologue.run(step, self.mem)
            return
        a, half = self._element(addr)
        if a is None:
            return
        if self.words == 1:
            self.mem[a] = word
        elif half == 0:
            self.low = word
        else:
            self.mem[a] = self.low | word << 32
        self.prologue.wrote_word(a)

    def expect(self, addr):
        a, half = self._element(addr)
        if a is None:
            return None
        return self.mem[a] >> (32 * half) & 0xFFFFFFFF


class CheckedBus:
    """The processor's bus: ``AxiMaster`` transfers, each mirrored on :class:`GoldenBus` and
    every buffer word read checked against it; cycles spent in transfers and steps counted."""

    def __init__(self, dut, manifest, beats="burst", wait="irq"):
        self.dut, self.beats, self.wait = dut, beats, wait
        self.gold = GoldenBus(manifest)
        self.manifest = manifest
        self.axi = AxiMaster(AxiBus.from_prefix(dut, "s_axi"), dut.clk, dut.rst)
        logging.getLogger(f"cocotb.{dut._name}.s_axi").setLevel(logging.WARNING)
        regs = {r["name"]: r for r in manifest["registers"]}
        self.status_addr = regs["STATUS"]["offset"]
        self.status_bits = {f["name"]: f["lsb"] for f in regs["STATUS"]["fields"]}
        self.cycles = {"transfer": 0, **{step: 0 for step in steps_of(manifest)}}
        self.words_moved = 0
        self.ctrl_addr = regs["CTRL"]["offset"]
        self.running = None  # (step, cycle of its start) from CTRL.start to the STATUS clear
        self.expired = None  # the watchdog's Expired, once a wait has run past its bound
        self.last_step = None  # the step last started

    @staticmethod
    def now():
        return int(get_sim_time("ns")) // CLOCK_NS

    async def read(self, addr, n):
        t0 = self.now()
        if self.beats == "burst" or n == 1:
            got = await self.axi.read(addr, 4 * n)
            assert got.resp == AxiResp.OKAY, (hex(addr), got.resp)
            data = got.data
        else:
            data = b""
            for i in range(n):
                got = await self.axi.read(addr + 4 * i, 4)
                assert got.resp == AxiResp.OKAY, (hex(addr + 4 * i), got.resp)
                data += got.data
        words = [int.from_bytes(data[4 * i:4 * i + 4], "little") for i in range(n)]
        for i, w in enumerate(words):
            want = self.gold.expect(addr + 4 * i)
            assert want is None or w == want, f"word at {addr + 4 * i:#x}: core {w:#010x}, golden model {want:#010x}"
        self.cycles["transfer"] += self.now() - t0
        self.words_moved += n
        return words

    async def write(self, addr, words):
        t0 = self.now()
        data = b"".join(w.to_bytes(4, "little") for w in words)
        if self.beats == "burst" or len(words) == 1:
            resp = (await self.axi.write(addr, data)).resp
            assert resp == AxiResp.OKAY, (hex(addr), resp)
        else:
            for i in range(len(words)):
                resp = (await self.axi.write(addr + 4 * i, data[4 * i:4 * i + 4])).resp
                assert resp == AxiResp.OKAY, (hex(addr + 4 * i), resp)
        for i, w in enumerate(words):
            self.gold.write(addr + 4 * i, w)
        self.cycles["transfer"] += self.now() - t0
        self.words_moved += len(words)

    async def read32(self, addr):
        if self.expired is not None and addr == self.status_addr:
            # the watchdog has fired: STATUS answers done | err_busy without a transfer, so that
            # a driver's poll loop in C (which cannot see the exception) ends and the test
            # reports the watchdog's Expired
            return 1 << self.status_bits["done"] | 1 << self.status_bits["err_busy"]
        got = await self.axi.read(addr, 4)
        assert got.resp == AxiResp.OKAY, (hex(addr), got.resp)
        word = int.from_bytes(got.data, "little")
        want = self.gold.expect(addr)
        assert want is None or word == want, f"word at {addr:#x}: core {word:#010x}, golden model {want:#010x}"
        if addr == self.status_addr and word >> self.status_bits["done"] & 1:
            st = self.gold.last
            assert (word >> self.status_bits["err_pivot"] & 1, word >> self.status_bits["err_nan"] & 1) \
                == (int(st.pivot), int(st.nan)), f"STATUS {word:#x} against the golden model's {st}"
        return word

    async def write32(self, addr, word):
        t0 = self.now()
        resp = (await self.axi.write(addr, word.to_bytes(4, "little"))).resp
        assert resp == AxiResp.OKAY, (hex(addr), resp)
        self.gold.write(addr, word)
        if addr == self.ctrl_addr and word >> self.gold.start_bit & 1:
            f = self.gold.step_field
            self.running = (self.gold.steps[word >> f["lsb"] & ((1 << f["width"]) - 1)], t0)
            self.last_step = self.running[0]
        elif addr == self.status_addr and self.running and word >> self.status_bits["done"] & 1:
            step, start = self.running
            self.cycles[step] = self.cycles.get(step, 0) + self.now() - start
            self.running = None

    async def wait_event(self):
        """Until ``irq`` is high (``wait = irq``), or one poll interval; :class:`kfgen.sim.engine.watchdog.Expired`
        once the running step (the longest, with none started) is past its bound."""
        cycles = self.manifest["cycles"]
        step, start = self.running or (max(cycles, key=cycles.get), self.now())
        dog = Watchdog(step, cycles[step], start)
        try:
            if self.wait == "irq":
                await wait_irq(self.dut, dog, self.now)
            else:
                dog.check(self.now())
                await ClockCycles(self.dut.clk, 1)
        except Expired as exc:
            self.expired = exc
            raise


class AxiIO:
    """:class:`kfgen.sim.ukf.software.CoreIO` over :class:`CheckedBus`: regions by name."""

    def __init__(self, bus: CheckedBus):
        self.bus = bus
        m = bus.manifest
        self.mems = {mm["name"]: mm for mm in m["memories"]}
        regs = {r["name"]: r for r in m["registers"]}
        self.ctrl = regs["CTRL"]["offset"]
        self.fields = {r: {f["name"]: f for f in regs[r]["fields"]} for r in ("CTRL", "STATUS")}

    def _words(self, name):
        mm = self.mems[name]
        return mm["shape"][0] * mm["shape"][1] * mm["words_per_element"]

    async def step(self, name):
        b, f = self.bus, self.fields
        ctrl = 1 << f["CTRL"]["start"]["lsb"] | f["CTRL"]["step"]["values"][name] << f["CTRL"]["step"]["lsb"]
        await b.write32(self.ctrl, ctrl)
        done = 1 << f["STATUS"]["done"]["lsb"]
        while True:
            status = await b.read32(b.status_addr)
            if status & done:
                break
            await b.wait_event()
        await b.write32(b.status_addr, status)  # write 1 to clear
        return Status(bool(status >> f["STATUS"]["err_pivot"]["lsb"] & 1),
                      bool(status >> f["STATUS"]["err_nan"]["lsb"] & 1))

    async def read(self, name):
        words = await self.bus.read(self.mems[name]["offset"], self._words(name))
        return _elements(words, self.bus.gold.words)

    async def write(self, name, words):
        await self.bus.write(self.mems[name]["offset"], _bus_words(words, self.bus.gold.words))


def _elements(words, per):
    return words if per == 1 else [words[i] | words[i + 1] << 32 for i in range(0, len(words), 2)]


def _bus_words(elements, per):
    if per == 1:
        return list(elements)
    return [w for e in elements for w in (e & 0xFFFFFFFF, e >> 32)]


# ---------------------------------------------------------------------------- the runs

class Run:
    def __init__(self, dut):
        self.dut = dut
        self.manifest = load_manifest()
        self.app = load_app(os.environ["KFGEN_APP"])
        self.steps = int(os.environ.get("KFGEN_STEPS", "20"))
        self.scenario = checked_scenario(self.app, self.steps, int(os.environ.get("KFGEN_SEED", "1")))
        cocotb.start_soon(Clock(dut.clk, CLOCK_NS, unit="ns").start())
        self.bus = CheckedBus(dut, self.manifest, os.environ.get("KFGEN_BEATS", "burst"),
                              os.environ.get("KFGEN_WAIT", "irq"))
        self.io = AxiIO(self.bus)
        self.fmt = self.bus.gold.fmt
        self.estimates = np.empty((self.steps, self.app.n))
        self.per_iteration = []

    async def reset(self):
        self.dut.rst.value = 1
        await ClockCycles(self.dut.clk, 3)
        self.dut.rst.value = 0
        await RisingEdge(self.dut.clk)
        irq = next((r for r in self.manifest["registers"] if r["name"] == "IRQ_ENABLE"), None)
        if irq is not None and self.bus.wait == "irq":
            await self.bus.write32(irq["offset"], sum(1 << f["lsb"] for f in irq["fields"]))

    def fault(self, exc: StepError):
        """Leave ``exc`` (placed at its iteration) for the runner in ``KFGEN_COSIM_FAULT``;
        raises it, which fails the test."""
        path = os.environ.get("KFGEN_COSIM_FAULT")
        if path:
            with open(path, "w") as f:
                json.dump({"step": exc.step, "bit": exc.bit, "iteration": exc.iteration}, f)
        raise exc

    def record(self, k, x_words, before):
        self.estimates[k] = from_words(self.fmt, x_words)
        self.per_iteration.append({key: self.bus.cycles[key] - before[key] for key in before})

    def finish(self, wall):
        columns = [*steps_of(self.manifest), "transfer"]
        cyc = np.array([[it[k] for k in columns] for it in self.per_iteration])
        total = self.bus.now()
        each = ", ".join(f"{k} {c:.0f}" for k, c in zip(columns, np.rint(cyc.mean(axis=0))))
        self.dut._log.info("%d iterations, %d cycles (%.0f cycles/s of simulation, %.1f s); per iteration: "
                           "%s cycles (%d words moved in all)", self.steps, total, total / wall, wall, each,
                           self.bus.words_moved)
        out = os.environ.get("KFGEN_COSIM_OUT")
        if out:
            np.savez(out, estimates=self.estimates, truth=self.scenario.truth, t=self.scenario.t,
                     cycles=cyc, cycles_columns=np.array(columns), wall_s=wall, sim_cycles=total)


@cocotb.test()
async def python_processor(dut):
    """The application's iterations by the Python software side over AXI."""
    r = Run(dut)
    await r.reset()
    wall = time.monotonic()
    form = r.bus.gold.params.form
    for name, words in initial_words(r.app, r.fmt, form).items():
        await r.io.write(name, words)
    for k, (u, z) in enumerate(r.scenario.inputs()):
        before = dict(r.bus.cycles)
        try:
            await iteration(r.io, r.app, r.fmt, u, z, r.bus.gold.params.on_chip)
        except StepError as exc:
            r.fault(exc.at(k))
        r.record(k, await r.io.read("x"), before)
    await r.io.read(covariance_region(form))
    r.finish(time.monotonic() - wall)


# ---------------------------------------------------------------------------- the C processor

_MODEL = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double),
                          ctypes.POINTER(ctypes.c_double))


@cocotb.test()
async def c_processor(dut):
    """The same iterations by the generated C driver, its MMIO hooks on the same AXI master."""
    r = Run(dut)
    await r.reset()
    bus, app = r.bus, r.app
    top = r.manifest["parameters"]["name"]
    lib = ctypes.CDLL(os.environ["KFGEN_DRIVER_LIB"])
    n, nw, nv, m = app.n, app.nw, app.nv, app.m
    state = {"u": None}

    def f_cb(_ctx, x, w, out):
        y = app.f(np.ctypeslib.as_array(x, (n,)).copy(), np.ctypeslib.as_array(w, (nw,)).copy(), state["u"], app.dt)
        np.ctypeslib.as_array(out, (n,))[:] = y

    def h_cb(_ctx, x, v, out):
        y = app.h(np.ctypeslib.as_array(x, (n,)).copy(), np.ctypeslib.as_array(v, (nv,)).copy())
        np.ctypeslib.as_array(out, (m,))[:] = y

    guard = Guard()
    hooks = set_hooks(lib, top, guard, bus.read32, bus.write32, bus.read, bus.write, bus.wait_event)
    models = (_MODEL(guard.wrap(f_cb)), _MODEL(guard.wrap(h_cb)))
    check = guard.check
    dev = Dev()
    dbl = ctypes.POINTER(ctypes.c_double)

    def arr(values):
        a = np.ascontiguousarray(np.ravel(np.asarray(values, dtype=np.float64)))
        return a, a.ctypes.data_as(dbl)

    init, iterate, load = (c_function(lib, top, s) for s in ("init", "iterate", "load"))
    estimate = c_function(lib, top, "estimate", None)
    wall = time.monotonic()
    ok = await bridge(init)(ctypes.byref(dev), ctypes.c_size_t(0))
    check()
    assert ok == 0, "the core's ID does not match the driver's header"
    keep = [arr(v) for v in (app.x0, app.P0, app.Q, app.R)]
    await bridge(load)(ctypes.byref(dev), *(p for _, p in keep))
    check()
    x_out, P_out = arr(np.zeros(n)), arr(np.zeros(n * n))
    for k, (u, z) in enumerate(r.scenario.inputs()):
        before = dict(bus.cycles)
        state["u"] = u
        z_arr = arr(z)
        if bus.gold.params.on_chip:  # f and h in the core: TOP_iterate(dev, u, z)
            u_arr = arr(u if len(u) else [0.0])
            err = await bridge(iterate)(ctypes.byref(dev), u_arr[1], z_arr[1])
        else:
            err = await bridge(iterate)(ctypes.byref(dev), models[0], models[1], None, z_arr[1])
        check()
        if err:  # the STATUS bits of the step that failed (TOP_run's return)
            r.fault(StepError(bus.last_step, "err_pivot" if err >> bus.status_bits["err_pivot"] & 1 else "err_nan", k))
        await bridge(estimate)(ctypes.byref(dev), x_out[1], P_out[1])
        check()
        r.estimates[k] = x_out[0]
        r.per_iteration.append({key: bus.cycles[key] - before[key] for key in before})
    assert hooks  # the callbacks lived while the driver ran
    r.finish(time.monotonic() - wall)
