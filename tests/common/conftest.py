"""Fixtures of the tests of what every core shares."""

import gc

import pytest


@pytest.fixture
def elaboratables_collected():
    """Collects garbage after the test, inside it: Amaranth warns of an elaboratable built and
    never elaborated (``UnusedElaboratable``) only when the object is collected, and its
    self-reference leaves that to the cycle collector, at any later time. With
    :data:`helpers.EVERY_ELABORATABLE_USED`'s marks the warning then fails this test."""
    yield
    gc.collect()
