"""Run a generated UKF core (``kfgen ukf``) on Verilator: its testbench (:mod:`kfgen.sim.ukf.tb`,
on :mod:`kfgen.sim.engine.run`'s build) and the co-simulation of an application
(:mod:`kfgen.sim.ukf.cosim`) with the Python processor or the generated C driver. Generating
the core and simulating it in one command is gen's (:mod:`kfgen.gen.cosim`)."""

from __future__ import annotations

from ..engine.run import CosimFault, build_driver
from ..engine.run import run_cosim as engine_cosim
from ..verilator import Build
from .software import StepError

__all__ = ["TB", "build_driver", "run_cosim"]

#: The UKF's cocotb testbench (:func:`kfgen.sim.engine.run.run_tb`'s ``module``).
TB = "kfgen.sim.ukf.tb"


def run_cosim(model: Build, rtl_dir, top: str, test: str, name: str, app: str, steps: int, *, seed: int = 1,
              beats: str = "burst", wait: str = "irq", out=None, driver=None, app_dir=None) -> None:
    """Run co-simulation ``test`` (``python_processor`` or ``c_processor``, :mod:`kfgen.sim.ukf.cosim`)
    of application ``app`` (``module:Class`` or ``file.py:Class``, found from ``app_dir``: by
    default the current directory) for ``steps`` iterations on a build of the core generated
    into ``rtl_dir``; ``out``: an ``.npz`` for the estimates and cycles; ``driver``: the C
    driver's library (:func:`build_driver`).

    Raises
    ------
    kfgen.sim.ukf.software.StepError
        When a step of the core raised ``err_pivot`` or ``err_nan`` (its ``iteration``,
        ``step`` and ``bit`` say where).
    AssertionError
        When the run failed otherwise (a word unlike the golden model's), with the log's tail.
    """
    env = {"KFGEN_STEPS": str(steps), "KFGEN_SEED": str(seed), "KFGEN_BEATS": beats, "KFGEN_WAIT": wait}
    try:
        engine_cosim(model, rtl_dir, top, "kfgen.sim.ukf.cosim", test, name, app, app_dir=app_dir, out=out,
                     driver=driver, env=env)
    except CosimFault as exc:
        raise StepError(exc.step, exc.bit, exc.iteration) from None
