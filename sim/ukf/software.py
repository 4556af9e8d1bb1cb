"""The processor's side of the HW/SW codesign: what software does around the core's steps.

One UKF iteration as the chapter's processor runs it (section 3), on bus words:

1. start ``sig_gen``; read ``sigma_points`` (N x M, point by point);
2. apply the application's f to each point's state and process-noise parts, with this
   iteration's control input, and write the results, rounded to the core's format, to
   ``sigma_points_f`` (eq. 9);
3. start ``predict`` (x, P now hold x^-, P^-);
4. apply h to each moved point *as written* (the words of step 2) and the point's
   measurement-noise part into ``sigma_points_h`` (eq. 12); write the measurement ``z``;
5. start ``update`` (x, P now hold the estimate).

f and h run in float64 on the words' values; each result is rounded once to the format,
as software writing a float of that format would. :func:`iteration` is written once, as a
coroutine over a small bus interface (:class:`CoreIO`), so that the bit-exact golden model
(:class:`GoldenCore`, driven by :func:`complete`) and a cocotb processor driving the
generated Verilog through AXI run the same software.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from kfgen.hdl.ukf.params import covariance_region
from kfgen.hdl.ukf.steps import programs
from kfgen.sim.engine.prologue import Prologue
from kfgen.sim.linalg.exec import Status, from_words, to_words

from .app import UkfApplication

__all__ = ["CoreIO", "StepError", "initial_words", "iteration", "GoldenCore", "complete"]


class CoreIO(Protocol):
    """The bus as software sees it: regions of the core's buffer by name, in words."""

    async def step(self, name: str) -> Status:
        """Start step ``name`` (``sig_gen``, ``predict``, ``update``), wait for it to end,
        clear STATUS; its ``pivot`` and ``nan`` bits."""

    async def read(self, name: str) -> list[int]:
        """Every word of region ``name``, row-major."""

    async def write(self, name: str, words: list[int]) -> None:
        """Every word of region ``name``, row-major."""


class StepError(RuntimeError):
    """A step raised ``err_pivot`` or ``err_nan``: the filter has failed numerically.

    Parameters
    ----------
    step : str
        The step that raised it (``sig_gen``, ``predict``, ``update``).
    bit : str
        The STATUS bit, ``err_pivot`` (a pivot of a factorisation not positive: a covariance
        that is not positive definite) or ``err_nan`` (a NaN or infinity in a result).
    iteration : int or None
        The filter iteration (from 0), when the caller knows it (:meth:`at`).
    """

    def __init__(self, step: str, bit: str, iteration: int | None = None):
        self.step, self.bit, self.iteration = step, bit, iteration
        where = "" if iteration is None else f"iteration {iteration}: "
        super().__init__(f"{where}{step} raised {bit}")

    def at(self, iteration: int) -> "StepError":
        """The same fault, placed at filter iteration ``iteration``."""
        return StepError(self.step, self.bit, iteration)


def initial_words(app: UkfApplication, fmt, form: str = "ldl") -> dict[str, list[int]]:
    """x0, P0, Q, R as words of ``fmt``, by region name (written once, before the first
    iteration). A core of the square-root form (``form="sqrt"``) takes P0 as its Cholesky
    factor, in region ``sqrtP``."""
    P0 = np.asarray(app.P0, dtype=np.float64)
    P = np.linalg.cholesky(P0) if form == "sqrt" else P0
    return {name: to_words(fmt, np.ravel(np.asarray(value, dtype=np.float64)))
            for name, value in (("x", app.x0), (covariance_region(form), P), ("Q", app.Q), ("R", app.R))}


async def _step(io: CoreIO, name: str) -> None:
    st = await io.step(name)
    if st.pivot or st.nan:
        raise StepError(name, "err_pivot" if st.pivot else "err_nan")


async def iteration(io: CoreIO, app: UkfApplication, fmt, u, z, on_chip: bool = False) -> None:
    """One filter iteration with control input ``u`` and measurement ``z`` (steps 1-5 above);
    on a core with f and h on chip (``on_chip``), software writes ``u`` (when the application
    has one) and ``z`` and starts the one step ``iteration``.

    Raises
    ------
    StepError
        When a step reports a covariance that is not positive definite or a NaN.
    """
    if on_chip:
        if app.nu:
            await io.write("u", to_words(fmt, np.ravel(np.asarray(u, dtype=np.float64))))
        await io.write("z", to_words(fmt, np.ravel(np.asarray(z, dtype=np.float64))))
        await _step(io, "iteration")
        return
    n, nw, M = app.n, app.nw, app.n + app.nw + app.nv
    await _step(io, "sig_gen")
    chi = np.array(from_words(fmt, await io.read("sigma_points"))).reshape(-1, M)
    words_f = to_words(fmt, np.ravel([app.f(c[:n], c[n:n + nw], u, app.dt) for c in chi]))
    await io.write("sigma_points_f", words_f)
    await _step(io, "predict")
    moved = np.array(from_words(fmt, words_f)).reshape(-1, n)
    await io.write("sigma_points_h", to_words(fmt, np.ravel([app.h(xf, c[n + nw:]) for xf, c in zip(moved, chi)])))
    await io.write("z", to_words(fmt, np.ravel(np.asarray(z, dtype=np.float64))))
    await _step(io, "update")


class GoldenCore:
    """:class:`CoreIO` on the bit-exact golden model: the core's memory as words, each step
    its program run by :func:`kfgen.sim.linalg.exec.run`.

    Parameters
    ----------
    params : :class:`~kfgen.hdl.ukf.params.UkfParams`
        The core's configuration (sizes, W0, format).
    """

    def __init__(self, params):
        self.ukf = programs(params)
        self.fmt = self.ukf.fmt
        self.mem = self.ukf.layout.initial_memory()
        self.prologue = Prologue(self.ukf)

    async def step(self, name: str) -> Status:
        return self.prologue.run(name, self.mem)

    async def read(self, name: str) -> list[int]:
        reg = self.ukf.layout[name]
        return self.mem[reg.base:reg.base + reg.size]

    async def write(self, name: str, words: list[int]) -> None:
        reg = self.ukf.layout[name]
        if len(words) != reg.size:
            raise ValueError(f"{name} holds {reg.size} words, not {len(words)}")
        self.mem[reg.base:reg.base + reg.size] = words
        self.prologue.wrote(name)


def complete(coro):
    """Run a coroutine that never waits (one over :class:`GoldenCore`) to its end; its result."""
    try:
        coro.send(None)
    except StopIteration as stop:
        return stop.value
    coro.close()
    raise RuntimeError("the coroutine waited for something: it needs an event loop (cocotb's)")
