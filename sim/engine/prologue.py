"""The engine core's prologue on the golden side: the program a start runs first when the
inputs it depends on have changed, as the hardware does
(:class:`kfgen.hdl.engine.core.Prologue`)."""

from __future__ import annotations

from kfgen.sim.linalg.exec import Status, run

__all__ = ["Prologue"]


class Prologue:
    """The prologue of a core's programs (their ``prologue``: ``(pre, main, regions)``, or
    none) on the golden side: a start of ``main`` runs ``pre`` first when one of ``regions``
    has been written since ``pre`` last ran (and after reset). On the UKF: ``noise`` before an
    on-chip ``iteration`` (before ``sig_gen`` on a three-step core of the square-root form)
    once Q or R have been written; the IMM's programs have none."""

    def __init__(self, programs):
        self.programs = programs
        self.spec = getattr(programs, "prologue", None)
        self.stale = True
        regions = [programs.layout[r] for r in self.spec[2]] if self.spec is not None else []
        self._words = [(reg.base, reg.base + reg.size) for reg in regions]

    def wrote(self, name: str) -> None:
        """Region ``name`` was written."""
        if self.spec is not None and name in self.spec[2]:
            self.stale = True

    def wrote_word(self, address: int) -> None:
        """The word at ``address`` (the layout's) was written."""
        if any(lo <= address < hi for lo, hi in self._words):
            self.stale = True

    def steps(self, name: str) -> list[str]:
        """The programs a start of ``name`` runs now, in order (and the state that follows)."""
        if self.spec is None:
            return [name]
        pre, main, _ = self.spec
        out = [pre, main] if name == main and self.stale else [name]
        if pre in out:
            self.stale = False
        return out

    def run(self, name: str, mem: list[int], steps: list[str] | None = None) -> Status:
        """Start ``name`` on ``mem`` (the programs ``steps`` if given, else :meth:`steps`'):
        their statuses together."""
        pivot = nan = False
        flags = 0
        for step in steps or self.steps(name):
            st = run(self.programs.steps[step], mem)
            pivot, nan, flags = pivot or st.pivot, nan or st.nan, flags | st.flags
        return Status(pivot, nan, flags)
