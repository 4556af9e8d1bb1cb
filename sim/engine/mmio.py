"""A generated C driver (:mod:`kfgen.gen.cdriver`) in a cocotb co-simulation: its MMIO hooks
(``-DKFGEN_MMIO_HOOKS``: ``TOP_set_hooks``) as ctypes callbacks into the simulation, and the
driver's functions as the blocking Python functions ``cocotb.task.bridge`` runs in a thread
(each hook brings its access back into the simulation with ``cocotb.task.resume``).

:class:`TbMmio` gives the hooks over the engine's harness (:class:`kfgen.sim.engine.tb.TB`):
every access through its ``AxiMaster``, mirrored on its golden memory (a write of
``CTRL.start`` runs the step's program), every buffer word and every finished step's ``STATUS``
read held against the golden model's. The UKF's co-simulation has its own bus
(:class:`kfgen.sim.ukf.cosim.CheckedBus`, which counts transfer cycles) and shares the rest.
"""

from __future__ import annotations

import ctypes

from cocotb.task import resume
from cocotbext.axi import AxiResp

from .watchdog import Watchdog, wait_irq

__all__ = ["READ32", "WRITE32", "BLOCK", "EVENT", "Hooks", "Dev", "Guard", "c_function", "set_hooks", "TbMmio"]

READ32 = ctypes.CFUNCTYPE(ctypes.c_uint32, ctypes.c_void_p, ctypes.c_uint64)
WRITE32 = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_uint64, ctypes.c_uint32)
BLOCK = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_uint64, ctypes.POINTER(ctypes.c_uint32), ctypes.c_uint32)
EVENT = ctypes.CFUNCTYPE(None, ctypes.c_void_p)


class Hooks(ctypes.Structure):
    """``TOP_hooks_t``."""
    _fields_ = [("read32", READ32), ("write32", WRITE32), ("read_block", BLOCK), ("write_block", BLOCK),
                ("wait_event", EVENT), ("ctx", ctypes.c_void_p)]


class Dev(ctypes.Structure):
    """``TOP_dev_t``."""
    _fields_ = [("base", ctypes.c_size_t), ("status", ctypes.c_uint32)]


class Guard:
    """Python callbacks the C code calls: an exception cannot cross the C code, so
    :meth:`wrap`'s callback keeps it (and returns 0) and :meth:`check`, after the C call,
    raises the first one kept."""

    def __init__(self):
        self.errors = []

    def wrap(self, fn):
        def call(*args):
            try:
                return fn(*args)
            except BaseException as exc:  # noqa: BLE001 (re-raised by check())
                self.errors.append(exc)
                return 0
        return call

    def check(self):
        if self.errors:
            raise self.errors[0]


def c_function(lib, top: str, symbol: str, restype=ctypes.c_int):
    """The driver's ``TOP_symbol`` as a Python function (what ``cocotb.task.bridge`` takes),
    returning ``restype``."""
    fn = getattr(lib, f"{top}_{symbol}")
    fn.restype = restype

    def call(*args):
        return fn(*args)
    call.__qualname__ = call.__name__ = f"{top}_{symbol}"
    return call


def set_hooks(lib, top: str, guard: Guard, read32, write32, read_block, write_block, wait_event,
              call=resume) -> list:
    """Set the driver's hooks (``TOP_set_hooks``) to the coroutine functions given, each run
    in the simulation (``resume``) and guarded by ``guard``: ``read32(addr)``,
    ``write32(addr, word)``, ``read_block(addr, count)`` (the words), ``write_block(addr,
    words)``, ``wait_event()`` (None: the driver polls STATUS). ``call``: how a hook runs one
    (``resume``; for plain functions, outside a simulation, ``lambda fn: fn``). The callbacks,
    which the caller keeps alive while the driver runs."""
    def read_into(_ctx, addr, dst, count):
        for i, w in enumerate(call(read_block)(addr, count)):
            dst[i] = w

    callbacks = [READ32(guard.wrap(lambda _c, a: call(read32)(a))),
                 WRITE32(guard.wrap(lambda _c, a, v: call(write32)(a, v))),
                 BLOCK(guard.wrap(read_into)),
                 BLOCK(guard.wrap(lambda _c, a, src, k: call(write_block)(a, [src[i] for i in range(k)]))),
                 EVENT(guard.wrap(lambda _c: call(wait_event)())) if wait_event is not None else EVENT()]
    hooks = Hooks(*callbacks, None)
    getattr(lib, f"{top}_set_hooks")(ctypes.byref(hooks))
    return [callbacks, hooks]


class TbMmio:
    """The MMIO hooks of a C driver over an engine testbench ``tb`` (after :func:`kfgen.sim.engine.tb.setup`).

    Attributes
    ----------
    last : kfgen.sim.linalg.exec.Status or None
        The golden model's status of the step started last.
    """

    def __init__(self, tb):
        self.tb = tb
        self.regions = [(mm["offset"], mm["offset"] + 4 * tb.words * tb.layout[name].size, tb.layout[name])
                        for name, mm in tb.mems.items()]
        self.ctrl, self.status = tb.regs["CTRL"]["offset"], tb.regs["STATUS"]["offset"]
        self.status_bits = {f["name"]: f["lsb"] for f in tb.regs["STATUS"]["fields"]}
        self.low = None
        self.running = None  # the step started last, until its STATUS is cleared
        self.last = None

    def _element(self, addr):
        for lo, hi, reg in self.regions:
            if lo <= addr < hi:
                k, half = divmod((addr - lo) // 4, self.tb.words)
                return reg.base + k, half
        return None, None

    def _step_of(self, word):
        tb = self.tb
        if not tb.has_step:
            return next(iter(tb.programs.steps))  # one step (the IMM's iterate)
        fd = tb.field("CTRL", "step")
        number = word >> fd["lsb"] & ((1 << fd["width"]) - 1)
        return next(k for k, v in fd["values"].items() if v == number)

    def _expect(self, addr, word):
        a, half = self._element(addr)
        if a is not None:
            want = self.tb.gold[a] >> (32 * half) & 0xFFFFFFFF
            assert word == want, f"word at {addr:#x}: core {word:#010x}, golden model {want:#010x}"

    def _mirror(self, addr, word):
        tb = self.tb
        if addr == self.ctrl and word >> tb.field("CTRL", "start")["lsb"] & 1:
            step = self._step_of(word)
            self.last = tb.prologue.run(step, tb.gold, tb.prologue.steps(step))
            self.running = (step, tb.now())
            return
        a, half = self._element(addr)
        if a is None:
            return
        if tb.words == 1:
            tb.gold[a] = word
        elif half == 0:
            self.low = word
        else:
            tb.gold[a] = self.low | word << 32
        tb.prologue.wrote_word(a)

    async def read32(self, addr):
        got = await self.tb.axi.read(addr, 4)
        assert got.resp == AxiResp.OKAY, (hex(addr), got.resp)
        word = int.from_bytes(got.data, "little")
        self._expect(addr, word)
        bits = self.status_bits
        if addr == self.status and word >> bits["done"] & 1:
            st = self.last
            assert (word >> bits["err_pivot"] & 1, word >> bits["err_nan"] & 1) == (int(st.pivot), int(st.nan)), \
                f"STATUS {word:#x} against the golden model's {st}"
        return word

    async def write32(self, addr, word):
        resp = (await self.tb.axi.write(addr, word.to_bytes(4, "little"))).resp
        assert resp == AxiResp.OKAY, (hex(addr), resp)
        self._mirror(addr, word)

    async def read_block(self, addr, count):
        got = await self.tb.axi.read(addr, 4 * count)
        assert got.resp == AxiResp.OKAY, (hex(addr), got.resp)
        words = [int.from_bytes(got.data[4 * i:4 * i + 4], "little") for i in range(count)]
        for i, w in enumerate(words):
            self._expect(addr + 4 * i, w)
        return words

    async def write_block(self, addr, words):
        resp = (await self.tb.axi.write(addr, b"".join(w.to_bytes(4, "little") for w in words))).resp
        assert resp == AxiResp.OKAY, (hex(addr), resp)
        for i, w in enumerate(words):
            self._mirror(addr + 4 * i, w)

    async def wait_event(self):
        """Until ``irq``, within the watchdog's bound of the running step's cycles."""
        cycles = self.tb.manifest["cycles"]
        step, start = self.running or (max(cycles, key=cycles.get), self.tb.now())
        await wait_irq(self.tb.dut, Watchdog(step, cycles[step], start), self.tb.now)
