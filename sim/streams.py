"""The transmitter's side of a valid/ready stream, checked while a cocotb testbench runs.

:class:`StreamChecker` holds the AXI4-Stream handshake rules (ARM IHI 0051, "Handshake process")
that bind whoever drives ``TVALID``:

* once ``TVALID`` is high it stays high until the transfer (``TVALID`` and ``TREADY`` high at
  a rising edge);
* the payload (``TDATA``, ``TID``, ``TUSER`` ... whichever exist) stays stable meanwhile;
* ``TVALID`` is never X or Z once reset is over.

It does not start a coroutine of its own: a cocotb process costs a Python wake-up per awaited
edge, and kfgen's testbenches already wake once a clock, in the read-only phase before each
rising edge (they drive at the falling edge). There they call :meth:`StreamChecker.sample`,
which reads the handles and raises :class:`StreamProtocolError` at the first broken rule.
(cocotbext-axi's ``AxiStreamMonitor`` only records transfers; it checks none of these rules.)
"""

from __future__ import annotations

__all__ = ["StreamChecker", "StreamProtocolError"]

#: AXI4-Stream payload signals, in the order a message names them.
AXIS_PAYLOAD = ("tdata", "tstrb", "tkeep", "tlast", "tid", "tdest", "tuser")


class StreamProtocolError(AssertionError):
    """A stream's transmitter broke a handshake rule."""


class StreamChecker:
    """Checks one stream's transmitter once a clock.

    Parameters
    ----------
    name : str
        For messages, e.g. ``"m_axis"``.
    valid, ready
        Handles of the valid and ready signals.
    payload : dict
        Name to handle of each signal that must hold while valid waits for ready.

    Members
    -------
    transfers : int
        Cycles sampled with valid and ready high.
    waits : int
        Cycles sampled with valid high and ready low (the ones that bind the next cycle).
    """

    def __init__(self, name: str, valid, ready, payload: dict):
        self.name = name
        self._valid = valid
        self._ready = ready
        self._payload = dict(payload)
        self._held = None  # the payload offered without ready at the last sampled edge
        self.transfers = 0
        self.waits = 0

    @classmethod
    def axis(cls, dut, prefix: str) -> StreamChecker:
        """The AXI4-Stream ``<prefix>_tvalid``/``_tready`` of ``dut`` and whichever payload
        signals it has."""
        def handle(suffix):
            return getattr(dut, f"{prefix}_{suffix}", None)
        return cls(prefix, handle("tvalid"), handle("tready"),
                   {s: h for s in AXIS_PAYLOAD if (h := handle(s)) is not None})

    def sample(self, cycle: int) -> None:
        """Check the values the next rising edge will see; call once a clock, in the read-only
        phase before the edge, from the first clock after reset. ``cycle`` is for messages."""
        valid = self._valid.value
        if not valid.is_resolvable:
            self._fail(cycle, f"valid is {valid} after reset")
        now = None
        if self._held is not None:
            if not valid:
                self._fail(cycle, "valid fell before the transfer (it was high without ready at the "
                                  "previous edge)")
            now = self._read()
            changed = [f"{k} {_text(self._held[k])} -> {_text(now[k])}" for k in now if now[k] != self._held[k]]
            if changed:
                self._fail(cycle, "payload changed while valid waited for ready: " + ", ".join(changed))
        if valid and not self._ready.value:
            self._held = now if now is not None else self._read()
            self.waits += 1
        else:
            self._held = None
            self.transfers += int(valid)

    def _read(self) -> dict:
        return {k: h.value for k, h in self._payload.items()}

    def _fail(self, cycle, what):
        raise StreamProtocolError(f"{self.name}, cycle {cycle}: {what}")


def _text(value):
    return hex(int(value)) if value.is_resolvable else str(value)
