"""Bounded waits for an engine core's step: a testbench or a co-simulation that waits on
``irq`` or polls ``STATUS`` gives up after :func:`bound` cycles and fails with
:class:`Expired`, naming the step and the bound, instead of hanging.

The bound comes from the manifest's ``cycles`` (the step's exact length):
``MARGIN * cycles + SLACK`` clock cycles from the start of the wait. The margin and the slack
cover what lies around the step in a wait (the start's write response, STATUS reads under
random backpressure, reads of the buffer while busy), so a healthy core never comes close.
"""

from __future__ import annotations

MARGIN = 2
SLACK = 1000


def bound(cycles: int) -> int:
    """The most clock cycles a wait for a step of ``cycles`` cycles (the manifest's) may take."""
    return MARGIN * int(cycles) + SLACK


class Expired(AssertionError):
    """A wait for a step ran past its bound (an ``AssertionError``: a test failure)."""

    def __init__(self, step: str, cycles: int, waited: int):
        super().__init__(f"watchdog: step {step} not done after {waited} cycles (bound {bound(cycles)} = "
                         f"{MARGIN} x the manifest's {cycles} cycles + {SLACK})")
        self.step, self.cycles, self.waited = step, cycles, waited


class Watchdog:
    """The bound on one wait for ``step`` (``cycles`` from the manifest), started at clock
    cycle ``start`` (any clock count that ``now`` values share)."""

    def __init__(self, step: str, cycles: int, start: int):
        self.step, self.cycles, self.start = step, int(cycles), int(start)
        self.limit = bound(cycles)

    def left(self, now: int) -> int:
        """Cycles left before the bound (0 or less: expired)."""
        return self.limit - (now - self.start)

    def check(self, now: int) -> None:
        """Raise :class:`Expired` if ``now`` is past the bound."""
        if now - self.start > self.limit:
            raise Expired(self.step, self.cycles, now - self.start)


async def poll(read, done, pause, now, step: str, cycles: int):
    """``await read()`` until ``done(word)``; ``await pause()`` between reads; :class:`Expired`
    once ``now()`` (clock cycles) is past the bound. The word that said done."""
    dog = Watchdog(step, cycles, now())
    while True:
        word = await read()
        if done(word):
            return word
        dog.check(now())
        await pause()


async def wait_irq(dut, dog: Watchdog, now) -> None:
    """Until ``dut.irq`` is high, at most to ``dog``'s bound (then :class:`Expired`);
    ``now()`` counts ``dut.clk``'s cycles."""
    from cocotb.triggers import ClockCycles, First, RisingEdge  # deferred: cocotb, only in a simulation

    while not int(dut.irq.value):
        dog.check(now())
        await First(RisingEdge(dut.irq), ClockCycles(dut.clk, max(1, dog.left(now())) + 1))
