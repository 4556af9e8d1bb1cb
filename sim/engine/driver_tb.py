"""The generated Python driver (``TOP_driver.py``, :mod:`kfgen.gen.pydriver`) on the Verilated
core: the driver runs unchanged in a thread (``cocotb.task.bridge``), its MMIO object
(:class:`BridgedMmio`) brings each access back into the simulation (``cocotb.task.resume``)
onto cocotbext-axi's ``AxiMaster`` through :class:`kfgen.sim.engine.mmio.TbMmio`, which mirrors
every access on the golden memory and holds every buffer word read, and every finished step's
STATUS, against the golden model.

A core's testbench calls :func:`python_driver` from a cocotb test of its own with a session:
what to load and run, in the thread, on the driver object.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import numpy as np
from cocotb.task import bridge, resume

from kfgen.sim.linalg.exec import from_words

from .mmio import TbMmio
from .tb import setup

__all__ = ["load_driver", "BridgedMmio", "python_driver", "golden"]


def load_driver(path):
    """The module ``path`` (a generated ``TOP_driver.py``), imported by its file name."""
    path = Path(path)
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class BridgedMmio:
    """The driver's MMIO object in the bridged thread: each access a :class:`TbMmio` coroutine
    run in the simulation; buffer regions as AXI4 bursts (``read_block``, ``write_block``);
    :meth:`wait_event` waits for ``irq`` (within the watchdog's bound of the running step)."""

    def __init__(self, mmio: TbMmio):
        self._read, self._write = resume(mmio.read32), resume(mmio.write32)
        self._read_block, self._write_block = resume(mmio.read_block), resume(mmio.write_block)
        self._wait = resume(mmio.wait_event)

    def read(self, offset):
        return self._read(offset)

    def write(self, offset, value):
        self._write(offset, int(value))

    def read_block(self, offset, count):
        return self._read_block(offset, count)

    def write_block(self, offset, words):
        self._write_block(offset, list(words))

    def wait_event(self):
        self._wait()


async def python_driver(dut, cls, session):
    """Set up ``cls`` (a :class:`kfgen.sim.engine.tb.TB`) on ``dut``, import the core's
    ``TOP_driver.py`` (beside ``KFGEN_TB_MANIFEST``) and run ``session(driver, tb, module)`` in a
    thread: ``driver`` is the driver's class on the bridged bus, waiting for each step on
    ``irq``; ``module`` the driver's module (its exceptions). Returns what the session returns."""
    tb = await setup(dut, cls)
    manifest = Path(os.environ["KFGEN_TB_MANIFEST"])
    module = load_driver(manifest.with_name(f"{tb.manifest['top']}_driver.py"))
    bus = BridgedMmio(TbMmio(tb))
    cls_name = next(name for name, value in vars(module).items()
                    if isinstance(value, type) and getattr(value, "bindto", None) == [module.VLNV])

    def run():
        driver = getattr(module, cls_name)(bus, wait_event=bus.wait_event)
        return session(driver, tb, module)

    return await bridge(run)()


def golden(tb, name):
    """Region ``name`` of ``tb``'s golden memory as float64 values (rows x cols)."""
    reg = tb.layout[name]
    return np.array(from_words(tb.fmt, tb.gold[reg.base:reg.base + reg.size])).reshape(reg.rows, reg.cols)
