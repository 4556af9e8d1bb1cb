"""The watchdog that bounds every wait of the engine cores' testbenches and co-simulation
(:mod:`kfgen.sim.engine.watchdog`), on a fake core without a simulator: a poll that never sees done
fails at the bound, naming the step; one that does returns the word. The wait on ``irq``
under cocotb is exercised by the testbenches' ``errors`` cases (a wait with no start)."""

import asyncio

import pytest

from kfgen.sim.engine.watchdog import MARGIN, SLACK, Expired, Watchdog, bound, poll


class FakeCore:
    """STATUS reads that take ``read_cycles`` clock cycles each and say done from cycle
    ``done_at`` on (never, by default)."""

    def __init__(self, read_cycles=3, done_at=None, start=17):
        self.cycle, self.read_cycles, self.done_at, self.reads = start, read_cycles, done_at, 0

    async def read(self):
        self.cycle += self.read_cycles
        self.reads += 1
        assert self.reads < 10_000, "no watchdog: the poll went on"  # a failure, not a hang
        return 1 if self.done_at is not None and self.cycle >= self.done_at else 0

    async def pause(self):
        self.cycle += 1

    def now(self):
        return self.cycle


def test_bound_from_the_manifest_cycles():
    assert bound(0) == SLACK
    assert bound(733) == MARGIN * 733 + SLACK
    assert MARGIN >= 2  # a healthy step never comes close


def test_a_poll_that_never_sees_done_fails_at_the_bound():
    core = FakeCore()
    with pytest.raises(Expired) as info:
        asyncio.run(poll(core.read, lambda w: w & 1, core.pause, core.now, "sig_gen", 400))
    waited = core.cycle - 17
    assert bound(400) < waited <= bound(400) + core.read_cycles + 1  # given up at once, not later
    assert info.value.waited == waited and info.value.step == "sig_gen"
    assert str(info.value) == (f"watchdog: step sig_gen not done after {waited} cycles "
                               f"(bound {bound(400)} = {MARGIN} x the manifest's 400 cycles + {SLACK})")


def test_a_poll_returns_the_done_word():
    core = FakeCore(done_at=17 + 400)
    assert asyncio.run(poll(core.read, lambda w: w & 1, core.pause, core.now, "iterate", 400)) == 1
    assert core.cycle < 17 + 400 + 4


def test_the_bound_counts_from_the_start():
    dog = Watchdog("update", 100, start=50)
    assert dog.left(50) == bound(100) and dog.left(50 + bound(100)) == 0
    dog.check(50 + bound(100))  # at the bound: still waiting
    with pytest.raises(Expired, match=r"step update not done after 1201 cycles \(bound 1200 "):
        dog.check(51 + bound(100))
