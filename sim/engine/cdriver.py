"""A generated C driver (``TOP_driver.c``, :mod:`kfgen.gen.cdriver`) run from Python, for every
core on the engine: compiled as a shared library with its MMIO hooks
(:func:`kfgen.sim.engine.run.build_driver`), its functions called through ctypes with numpy
arrays, its bus accesses going to any MMIO object.

:class:`CDriver` is the library on an MMIO object with ``read32(addr)``, ``write32(addr,
word)``, ``read_block(addr, count)``, ``write_block(addr, words)`` and ``wait_event()``:
:class:`kfgen.sim.engine.mmio.TbMmio`'s coroutines on the Verilated core (each access brought
back into the simulation with ``cocotb.task.resume``, every buffer word and finished step's
STATUS held against the golden model), or a golden device's plain functions
(:meth:`CDriver.on_device`, no RTL). :func:`c_driver` runs a core's session of it in a cocotb
test, in a thread (``cocotb.task.bridge``), as :func:`kfgen.sim.engine.driver_tb.python_driver`
does for the Python driver.
"""

from __future__ import annotations

import ctypes
import os
from pathlib import Path

import numpy as np
from cocotb.task import bridge, resume

from .mmio import Dev, Guard, TbMmio, set_hooks
from .run import build_driver
from .tb import setup

__all__ = ["CDriver", "c_driver"]

_DOUBLES = ctypes.POINTER(ctypes.c_double)


class _DeviceMmio:
    """A golden device's ``read``/``write`` (:class:`kfgen.sim.engine.device.GoldenDevice`) as
    the hooks' plain functions; a step is done when started, so ``wait_event`` never waits."""

    def __init__(self, device):
        self.read32, self.write32 = device.read, device.write
        self.read_block = lambda addr, count: [device.read(addr + 4 * i) for i in range(count)]
        self.write_block = lambda addr, words: [device.write(addr + 4 * i, w) for i, w in enumerate(words)]
        self.wait_event = lambda: None


class CDriver:
    """The C driver in the shared library ``lib`` of the core named ``top``, its hooks on
    ``mmio`` (each access run by ``call``: ``resume`` in a simulation) and one ``TOP_dev_t``
    at base address 0.

    ``driver("iterate", u, z)`` calls ``TOP_iterate(&dev, u, z)``: numpy arrays go as
    ``const double *`` (an output array must be float64 and C-contiguous, as ``np.zeros``
    makes it, for the C to write into it), ``None`` as NULL, ints as ``uint32_t``, ctypes values
    as they are; it returns
    the function's int (``TOP_run``'s: 0 or the STATUS error bits). An exception raised in a
    hook (a word unlike the golden model's) is raised after the call returns.
    """

    def __init__(self, lib, top: str, mmio, call=resume):
        self.lib = ctypes.CDLL(str(lib))
        self.top, self.mmio, self.call = top, mmio, call
        self.guard = Guard()
        self.dev = Dev()
        self._hooks = None
        self.wait = True

    @classmethod
    def on_device(cls, lib, top: str, device) -> CDriver:
        """The driver on a golden device (no simulation: the hooks call it directly)."""
        return cls(lib, top, _DeviceMmio(device), call=lambda fn: fn)

    @property
    def wait(self) -> bool:
        """True: the driver waits for a step through ``KFGEN_WAIT_EVENT`` (``mmio.wait_event``:
        on the core, until ``irq``); False: it polls STATUS."""
        return self._wait

    @wait.setter
    def wait(self, on: bool) -> None:
        m = self.mmio
        self._wait = bool(on)
        self._hooks = set_hooks(self.lib, self.top, self.guard, m.read32, m.write32, m.read_block, m.write_block,
                                m.wait_event if on else None, call=self.call)

    @property
    def status(self) -> int:
        """STATUS as the last step ended (``dev->status``)."""
        return self.dev.status

    @staticmethod
    def _arg(value, keep):
        if value is None or isinstance(value, ctypes._SimpleCData):
            return value
        if isinstance(value, (int, np.integer)):
            return ctypes.c_uint32(int(value))
        a = value
        if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous):
            a = np.ascontiguousarray(np.ravel(np.asarray(value, dtype=np.float64)))
        keep.append(a)
        return a.ctypes.data_as(_DOUBLES)

    def __call__(self, symbol: str, *args) -> int:
        fn = getattr(self.lib, f"{self.top}_{symbol}")
        fn.restype = ctypes.c_int
        keep = []
        result = fn(ctypes.byref(self.dev), *(self._arg(a, keep) for a in args))
        self.guard.check()
        return result

    def init(self) -> int:
        """``TOP_init`` at base 0: 0, or -1 when the core's ID does not match the driver's header."""
        return self("init", ctypes.c_size_t(0))


async def c_driver(dut, cls, session):
    """Set up ``cls`` (a :class:`kfgen.sim.engine.tb.TB`) on ``dut``, compile the core's
    ``TOP_driver.c`` (beside ``KFGEN_TB_MANIFEST``; into the run's directory, or take the
    library ``KFGEN_DRIVER_LIB``) and run ``session(driver, tb)`` in a thread: ``driver`` is a
    :class:`CDriver` on :class:`kfgen.sim.engine.mmio.TbMmio` (every word it reads checked),
    initialised, waiting for each step on ``irq``. Returns what the session returns."""
    tb = await setup(dut, cls)
    manifest = Path(os.environ["KFGEN_TB_MANIFEST"])
    top = tb.manifest["top"]
    lib = os.environ.get("KFGEN_DRIVER_LIB") or build_driver(manifest.parent, top, Path.cwd())
    driver = CDriver(lib, top, TbMmio(tb))

    def run():
        assert driver.init() == 0, "the core's ID does not match the driver's header"
        return session(driver, tb)

    return await bridge(run)()
