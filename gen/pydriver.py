"""The Python driver of an engine core, written beside it as ``TOP_driver.py``: a class in the
PYNQ style that binds to the core's VLNV (the one of ``TOP.xml``, :func:`kfgen.gen.ipxact.vlnv`)
as a PYNQ ``DefaultIP`` does, and runs the filter with numpy arrays in and out.

The file is made from the manifest alone (its ``registers``, ``memories``, ``cycles`` and the ID
register's format fields) and stands alone: it imports numpy and, when it is installed, PYNQ,
never kfgen. Without PYNQ its class takes any object with ``read(offset)`` and
``write(offset, value)`` (32-bit MMIO at byte offsets from the core's base): a test's golden
device (:class:`kfgen.sim.engine.device.GoldenDevice`), a cocotb bridge onto the Verilated core
(:mod:`kfgen.sim.engine.driver_tb`), a ``/dev/uio`` mapping.

What a step does is the C driver's sequence (:mod:`kfgen.gen.cdriver`): write the step's inputs
(``z``, ``u``), write ``CTRL.start`` (with the step's number where CTRL has a ``step`` field),
read ``STATUS`` until ``done`` (or ``err_busy``), write the events back to clear them, and raise
on ``err_pivot``/``err_nan``. A UKF of the chapter's three steps runs f and h here, between
``sig_gen``, ``predict`` and ``update``, as :mod:`kfgen.sim.ukf.software` does. Which regions
``load`` writes, and which ``step`` writes and reads, follow from the map's region names and
roles, the same for every core on the engine:

- ``x0`` is region ``x`` (the IMM: ``x_model``, every model's state), ``P0`` region ``P``
  (the IMM: ``P_model``; the square-root UKF: ``sqrtP``, which ``load`` writes as P0's
  Cholesky factor), then ``Q`` and ``R``; every other region of role ``input`` or ``state``
  but the step's own (``z``, ``u``, the host's ``sigma_points_f``/``sigma_points_h``) is a
  keyword argument of ``load`` named after it (the KF's ``F``, ``B``, ``H``, ``K``, the IMM's
  ``pi``, ``mu``, ``F``, ``H``);
- ``step`` and ``estimate`` return ``x`` and ``P`` (from ``sqrtP`` as S S^T; ``None`` when the
  core keeps no covariance, the steady-gain KF).

Numbers are packed as the buffer's format (the ID register's ``exp_bits`` and ``frac_bits``; two
bus words, low first, above 32 bits): rounded once from float64 to nearest, ties to even, with
IEEE subnormals, overflow to infinity and NaN as the canonical quiet NaN, as the golden model's
``to_words`` does, for every format the engine takes (``binary16``, ``bfloat16``, ``binary32``,
``binary64``, ``eEmM``).
"""

from __future__ import annotations

import keyword

from .ipxact import vlnv

__all__ = ["files", "text", "plan", "class_name", "TAKEN"]

#: Regions a step writes (in this order) before its start.
_STEP_INPUTS = ("z", "u")
#: Regions of the UKF's three-step form that software computes between the steps.
_HOST = ("sigma_points", "sigma_points_f", "sigma_points_h")

#: The names the driver's module defines; a class named after the top must not hide one.
TAKEN = frozenset({"annotations", "math", "np", "DefaultIP", "VLNV", "CORE", "TOP", "FORMAT", "ID", "REGISTERS",
                   "REGIONS", "LOAD", "STEPS", "INPUTS", "ESTIMATE", "POLLS", "CoreError", "WrongCore",
                   "CoreFault", "CoreTimeout", "to_words", "from_words", "field", "fields", "_word", "_value",
                   "_NUMPY"})


def class_name(top: str) -> str:
    """The driver's class: ``top``, or ``top_core`` when ``top`` is a Python keyword or a
    name the module already defines (:data:`TAKEN`)."""
    return f"{top}_core" if keyword.iskeyword(top) or keyword.issoftkeyword(top) or top in TAKEN else top


def plan(manifest) -> dict:
    """What the driver does, from the manifest: ``load`` ((argument, region, how) in order:
    ``how`` is ``"cholesky"`` for sqrtP, else ``None``; the first four arguments positional,
    x0, P0, Q, R where the core has them, the rest keyword-only), ``inputs`` (the step's
    regions), ``steps`` (the steps ``step`` starts, in order: CTRL.step's names, or the one
    cycles key of a CTRL without a step field), ``estimate`` ((x region, P region or None))."""
    mems = {m["name"]: m for m in manifest["memories"]}
    ctrl = next(r for r in manifest["registers"] if r["name"] == "CTRL")
    step_field = next((f for f in ctrl["fields"] if f["name"] == "step"), None)
    load = []
    for arg, names in (("x0", ("x_model", "x")), ("P0", ("P_model", "sqrtP", "P")), ("Q", ("Q",)), ("R", ("R",))):
        name = next((n for n in names if n in mems and mems[n]["role"] != "output"), None)
        if name is not None:
            load.append((arg, name, "cholesky" if name == "sqrtP" else None))
    taken = {name for _, name, _ in load}
    load += [(name, name, None) for name, m in mems.items()
             if m["role"] in ("input", "state") and name not in taken and name not in _STEP_INPUTS + _HOST]
    if step_field is None:  # one step, the manifest's one cycles key
        steps = list(manifest["cycles"])
    elif "sig_gen" in step_field["values"] and "sigma_points" in mems:
        steps = ["sig_gen", "predict", "update"]
    else:  # one start an iteration (a steady-gain KF's gain is its prologue, which the core runs)
        steps = [next(s for s in ("iteration", "iterate") if s in step_field["values"])]
    estimate = ("x", next((n for n in ("P", "sqrtP") if n in mems), None))
    return {"load": load, "inputs": [n for n in _STEP_INPUTS if n in mems], "steps": steps, "estimate": estimate}


def _literal(name: str, value) -> str:
    """``name = value``: a dict or list one entry a line when it does not fit on one."""
    line = f"{name} = {value!r}\n"
    if len(line) <= 100 or not isinstance(value, (dict, list)):
        return line
    items = [f"{k!r}: {v!r}" for k, v in value.items()] if isinstance(value, dict) else [repr(v) for v in value]
    ends = "{}" if isinstance(value, dict) else "[]"
    return f"{name} = {ends[0]}\n" + "".join(f"    {item},\n" for item in items) + f"{ends[1]}\n"


def _data(top: str, manifest) -> str:
    regs = {r["name"]: r for r in manifest["registers"]}
    ident = {f["name"]: f for f in regs["ID"]["fields"]}
    words = manifest["memories"][0]["words_per_element"]
    fmt = {"name": manifest["memories"][0]["format"], "exp_bits": ident["exp_bits"]["reset"],
           "frac_bits": ident["frac_bits"]["reset"], "words": words}
    p = plan(manifest)
    ctrl_steps = next((f["values"] for f in regs["CTRL"]["fields"] if f["name"] == "step"), {})
    steps = {s: ctrl_steps.get(s) for s in p["steps"]}
    return "".join([
        _literal("VLNV", vlnv(top)),
        _literal("CORE", manifest["core"]),
        _literal("TOP", top),
        "#: The buffer's float format: exponent and fraction bits, bus words per element.\n",
        _literal("FORMAT", fmt),
        "#: The ID fields this driver checks (all but pes) and their values for this core.\n",
        _literal("ID", {name: f["reset"] for name, f in ident.items() if name != "pes"}),
        "#: Register -> (byte offset, {field: (lsb, width)}).\n",
        _literal("REGISTERS", {r["name"]: (r["offset"], {f["name"]: (f["lsb"], f["width"]) for f in r["fields"]})
                               for r in manifest["registers"]}),
        "#: Buffer region -> (byte offset, rows, cols, role).\n",
        _literal("REGIONS", {m["name"]: (m["offset"], *m["shape"], m["role"]) for m in manifest["memories"]}),
        "#: load's arguments: (argument, region, conversion).\n",
        _literal("LOAD", p["load"]),
        "#: The regions a step writes, and the steps it starts: name -> CTRL.step value (None: CTRL has\n"
        "#: no step field).\n",
        _literal("INPUTS", p["inputs"]),
        _literal("STEPS", steps),
        "#: The regions of the estimate: x and P (P: None when the core keeps no covariance).\n",
        _literal("ESTIMATE", p["estimate"]),
        "#: The most STATUS reads a wait for a step takes (each read takes at least a clock cycle):\n"
        "#: twice the manifest's cycles of every step together, and 1000.\n",
        _literal("POLLS", 2 * sum(manifest["cycles"].values()) + 1000),
    ])


def _signature(load) -> tuple[str, str]:
    """``load``'s parameters (after ``self``) and the dict of arguments by region it builds."""
    positional = [arg for arg, _, _ in load if arg in ("x0", "P0", "Q", "R")]
    keywords = [arg for arg, _, _ in load if arg not in positional]
    params = ", ".join(positional + (["*"] + keywords if keywords else []))
    values = ", ".join(f"{arg!r}: {arg}" for arg, _, _ in load)
    return params, "{" + values + "}"


_TEMPLATE = r'''"""@TOP@_driver.py: a Python driver of the @TOP@ core, generated by kfgen; do not edit.

The core: kfgen @CORE@, VLNV @VLNV@.

On a Zynq with PYNQ, the class binds to the core in an overlay by its VLNV, as a DefaultIP:

    from pynq import Overlay
    import @TOP@_driver  # registers the class with PYNQ
    ol = Overlay("design.bit")
    core = ol.@TOP@_0  # @TOP@_driver.@CLASS@, the ID register checked
    core.load(@LOAD_ARGS@)
    x, P = core.step(@STEP_ARGS@)

Without PYNQ, pass any object with read(offset) and write(offset, value) (32-bit words at byte
offsets from the core's base): @CLASS@(mmio). numpy is the only other requirement.
"""

from __future__ import annotations

import math

import numpy as np

try:
    from pynq import DefaultIP
except ImportError:  # no PYNQ: the class takes an MMIO object
    class DefaultIP:
        """What the driver needs of PYNQ's DefaultIP (PYNQ is not installed)."""

        def __init__(self, description):
            raise TypeError("PYNQ is not installed: pass an object with read(offset) and write(offset, value)")


@DATA@

class CoreError(RuntimeError):
    """The core could not do what was asked."""


class WrongCore(CoreError):
    """The ID register does not match this driver's core: ``found`` and ``expected`` are the
    fields that differ."""

    def __init__(self, found: dict, expected: dict):
        self.found, self.expected = found, expected
        super().__init__("the core's ID does not match " + TOP + "_driver.py: " + ", ".join(
            f"{k} {found[k]} (expected {expected[k]})" for k in expected))


class CoreFault(CoreError):
    """A step ended with an error bit: ``step`` (its name), ``status`` (STATUS, decoded) and
    ``bits`` (the error bits set: err_pivot, a factorisation's pivot not positive, a
    covariance not positive definite; err_nan, a NaN or infinity in a result; err_busy, a
    start refused while busy)."""

    def __init__(self, step: str, status: dict):
        self.step, self.status = step, status
        self.bits = [k for k in ("err_pivot", "err_nan", "err_busy") if status.get(k)]
        super().__init__(f"{step} raised {', '.join(self.bits)}")


class CoreTimeout(CoreError):
    """A step's STATUS.done did not come within POLLS reads of STATUS."""


def field(word: int, register: str, name: str) -> int:
    """Field ``name`` of ``register`` in ``word``."""
    lsb, width = REGISTERS[register][1][name]
    return word >> lsb & ((1 << width) - 1)


def fields(word: int, register: str) -> dict:
    """Every field of ``register`` in ``word``, by name."""
    return {name: field(word, register, name) for name in REGISTERS[register][1]}


def _word(value: float) -> int:
    """``value`` rounded to FORMAT: to nearest, ties to even; NaN: the canonical quiet NaN."""
    E, M = FORMAT["exp_bits"], FORMAT["frac_bits"]
    bias, sign = (1 << (E - 1)) - 1, int(math.copysign(1.0, value) < 0) << (E + M)
    top = ((1 << E) - 1) << M
    if math.isnan(value):
        return top | 1 << (M - 1)
    if math.isinf(value):
        return sign | top
    if value == 0:
        return sign
    num, den = abs(value).as_integer_ratio()  # den is a power of two: value = num * 2**e2
    e2 = 1 - den.bit_length()
    exp = max(num.bit_length() - 1 + e2, 1 - bias)  # the result's exponent (subnormal: the least)
    shift = exp - M - e2  # the bits of num below the result's last place
    if shift > 0:
        q, r = num >> shift, num & ((1 << shift) - 1)
        half = 1 << (shift - 1)
        q += r > half or (r == half and q & 1)
        if q >> (M + 1):  # rounded up into the next binade
            q, exp = q >> 1, exp + 1
    else:
        q = num << -shift
    biased = exp + bias if q >> M else 0
    if biased >= (1 << E) - 1:
        return sign | top
    return sign | biased << M | (q & ((1 << M) - 1))


_NUMPY = {(5, 10): (np.float16, np.uint16), (8, 23): (np.float32, np.uint32), (11, 52): (np.float64, np.uint64)}


def to_words(values) -> list:
    """float64 values as the buffer's bus words (32 bits each; two per element above 32 bits,
    low first)."""
    v = np.ravel(np.asarray(values, dtype=np.float64))
    kind = _NUMPY.get((FORMAT["exp_bits"], FORMAT["frac_bits"]))
    if kind is not None:  # numpy rounds to nearest even as well; NaNs are made canonical
        with np.errstate(over="ignore", invalid="ignore"):  # (overflow rounds to infinity)
            elements = [int(w) for w in v.astype(kind[0]).view(kind[1])]
        nan = np.isnan(v)
        if nan.any():
            elements = [_word(math.nan) if n else w for w, n in zip(elements, nan)]
    else:
        elements = [_word(float(x)) for x in v]
    if FORMAT["words"] == 1:
        return elements
    return [w for e in elements for w in (e & 0xFFFFFFFF, e >> 32)]


def _value(word: int) -> float:
    E, M = FORMAT["exp_bits"], FORMAT["frac_bits"]
    bias = (1 << (E - 1)) - 1
    sign, e, frac = word >> (E + M) & 1, word >> M & ((1 << E) - 1), word & ((1 << M) - 1)
    if e == (1 << E) - 1:
        mag = math.nan if frac else math.inf
    else:
        try:
            mag = math.ldexp(frac, 1 - bias - M) if e == 0 else math.ldexp(frac | 1 << M, e - bias - M)
        except OverflowError:  # wider than binary64's range
            mag = math.inf
    return -mag if sign else mag


def from_words(words) -> np.ndarray:
    """Bus words (as :func:`to_words` gives them) as float64 values."""
    if FORMAT["words"] == 2:
        words = [lo | hi << 32 for lo, hi in zip(words[::2], words[1::2])]
    return np.array([_value(w) for w in words], dtype=np.float64)


class @CLASS@(DefaultIP):
    """The @TOP@ core (kfgen @CORE@).

    Parameters
    ----------
    description : dict or object
        PYNQ's description of the IP (an overlay makes it), or an object with ``read(offset)``
        and ``write(offset, value)``: 32-bit accesses at byte offsets from the core's base.
        Where it also has ``read_block(offset, count)`` and ``write_block(offset, words)``, the
        buffer's regions move in bursts.
    wait_event : callable, optional
        Called between reads of STATUS while a step runs (to wait for the core's irq); by
        default STATUS is read again at once.

    Every region of the buffer is at hand by name: ``read_region(name)`` (an array of its
    shape), ``write_region(name, values)`` (the IMM's model probabilities: ``read_region("mu")``).
    ``self.mmio`` is the MMIO object (PYNQ's, or the one given).

    Raises
    ------
    WrongCore
        When the ID register does not match this driver's core.
    """

    bindto = [VLNV]

    def __init__(self, description, wait_event=None):
        if isinstance(description, dict):
            super().__init__(description)  # PYNQ maps the core: self.mmio
        else:
            self.mmio = description
        self.wait_event = wait_event
        self.last_status = None
        ident = self._reg("ID") | self.mmio.read(REGISTERS["ID"][0] + 4) << 32
        found = fields(ident, "ID")
        if any(found[k] != v for k, v in ID.items()):
            raise WrongCore({k: found[k] for k in ID if found[k] != ID[k]},
                            {k: v for k, v in ID.items() if found[k] != v})
        self._write_reg("CTRL", 1 << REGISTERS["CTRL"][1]["reset"][0])  # idle, STATUS clear
        if "IRQ_ENABLE" in REGISTERS:
            self._write_reg("IRQ_ENABLE", self._events())

    # ------------------------------------------------------------- registers
    def _reg(self, name: str) -> int:
        return self.mmio.read(REGISTERS[name][0])

    def _write_reg(self, name: str, value: int) -> None:
        self.mmio.write(REGISTERS[name][0], value)

    @staticmethod
    def _events() -> int:
        return sum(1 << REGISTERS["STATUS"][1][k][0] for k in ("done", "err_pivot", "err_nan", "err_busy"))

    @property
    def status(self) -> dict:
        """STATUS now, by field (busy, done, err_pivot, err_nan, err_busy)."""
        return fields(self._reg("STATUS"), "STATUS")

    # ------------------------------------------------------------- the buffer
    def write_region(self, name: str, values) -> None:
        """Region ``name`` (row-major, every element) from ``values``."""
        offset, rows, cols, _ = REGIONS[name]
        v = np.asarray(values, dtype=np.float64)
        if v.size != rows * cols:
            raise ValueError(f"{name} holds {rows} x {cols} values, not {v.size}")
        words = to_words(v)
        if hasattr(self.mmio, "write_block"):
            self.mmio.write_block(offset, words)
        else:
            for i, w in enumerate(words):
                self.mmio.write(offset + 4 * i, w)

    def read_region(self, name: str) -> np.ndarray:
        """Region ``name`` as a rows x cols array."""
        offset, rows, cols, _ = REGIONS[name]
        count = rows * cols * FORMAT["words"]
        if hasattr(self.mmio, "read_block"):
            words = list(self.mmio.read_block(offset, count))
        else:
            words = [self.mmio.read(offset + 4 * i) for i in range(count)]
        return from_words(words).reshape(rows, cols)

    # ------------------------------------------------------------- steps
    def run(self, step: str) -> dict:
        """Start ``step`` (one of STEPS), wait for it, clear STATUS; STATUS as it ended, decoded.

        Raises
        ------
        CoreFault
            When the step ended with err_pivot or err_nan, or the start was refused (err_busy).
        CoreTimeout
            When STATUS.done did not come within POLLS reads.
        """
        ctrl = REGISTERS["CTRL"][1]
        word = 1 << ctrl["start"][0]
        if STEPS[step] is not None:
            word |= STEPS[step] << ctrl["step"][0]
        self._write_reg("CTRL", word)
        for _ in range(POLLS):
            status = self._reg("STATUS")
            if field(status, "STATUS", "done") or field(status, "STATUS", "err_busy"):
                break
            if self.wait_event is not None:
                self.wait_event()
        else:
            raise CoreTimeout(f"{step} not done after {POLLS} reads of STATUS")
        self._write_reg("STATUS", status & self._events())  # write 1 to clear
        self.last_status = fields(status, "STATUS")
        if status & (self._events() & ~(1 << REGISTERS["STATUS"][1]["done"][0])):
            raise CoreFault(step, self.last_status)
        return self.last_status

    def load(self, @LOAD_PARAMS@) -> None:
        """The filter's initial state and model: @LOAD_DOC@ (arrays of the regions' shapes,
        row-major; covariances with both triangles).@CHOL_DOC@"""
        for (arg, name, how), value in zip(LOAD, @LOAD_DICT@.values()):
            if value is None:
                raise ValueError(f"load needs {arg}")
            if how == "cholesky":
                try:
                    value = np.linalg.cholesky(np.asarray(value, dtype=np.float64))
                except np.linalg.LinAlgError:
                    raise CoreFault("load", {"err_pivot": 1}) from None
            self.write_region(name, value)

    def step(self, z=None, u=None, f=None, h=None):
        """One filter iteration on the measurement ``z`` (and the control input ``u``, where the
        core has one); the estimate ``(x, P)`` after it (:meth:`estimate`).

        A UKF whose f and h run here (the chapter's three steps) takes them as ``f(x, w, u)``
        (the state after one step, of a sigma point's state x and process noise w; u as given)
        and ``h(x, v)`` (the observation of a moved state x with measurement noise v), or from
        the attributes ``f`` and ``h``.

        Raises
        ------
        CoreFault
            When a step raised err_pivot or err_nan (the estimate is then not usable).
        """
        if "sig_gen" in STEPS:
            self._three_steps(z, u, f or self.f, h or self.h)
        else:
            for name, value in (("z", z), ("u", u)):
                if name in INPUTS:
                    if value is None:
                        raise ValueError(f"this core takes {'a measurement' if name == 'z' else 'a control input'} "
                                         f"{name}")
                    self.write_region(name, value)
            self.run(next(iter(STEPS)))
        return self.estimate()

    f = h = None

    def _three_steps(self, z, u, f, h):
        if f is None or h is None:
            raise ValueError("this core runs f and h in software: pass f(x, w, u) and h(x, v)")
        n, nw = REGIONS["x"][1], REGIONS["Q"][1]
        self.run("sig_gen")
        chi = self.read_region("sigma_points")
        moved = np.array([np.ravel(f(c[:n], c[n:n + nw], u)) for c in chi])
        words = to_words(moved)
        self.write_region("sigma_points_f", moved)
        self.run("predict")
        moved = from_words(words).reshape(moved.shape)  # h sees each moved point as the core holds it
        self.write_region("sigma_points_h", np.array([np.ravel(h(xf, c[n + nw:])) for xf, c in zip(moved, chi)]))
        self.write_region("z", z)
        self.run("update")

    def estimate(self):
        """``(x, P)``: the state estimate (n,) and its covariance (n, n) (``None`` where the core
        keeps none)."""
        xr, pr = ESTIMATE
        x = self.read_region(xr).ravel()
        if pr is None:
            return x, None
        P = self.read_region(pr)
        if pr == "sqrtP":  # P = S S^T of the lower triangle
            S = np.tril(P)
            P = S @ S.T
        return x, P
'''


def _doc_args(load) -> str:
    return ", ".join(f"``{arg}`` (region {name})" for arg, name, _ in load)


def text(top: str, manifest) -> str:
    """The text of ``TOP_driver.py`` for the core of ``manifest``."""
    p = plan(manifest)
    params, values = _signature(p["load"])
    positional = [a for a, _, _ in p["load"] if a in ("x0", "P0", "Q", "R")]
    keywords = [a for a, _, _ in p["load"] if a not in positional]
    load_args = ", ".join(positional + [f"{k}={k}" for k in keywords])
    step_args = "z" + (", u" if "u" in p["inputs"] else "") + (", f=f, h=h" if p["steps"] and "sig_gen" in p["steps"]
                                                              else "")
    chol = (" P0 is written as its Cholesky factor (region sqrtP); CoreFault (err_pivot) if it is not positive "
            "definite." if any(how == "cholesky" for _, _, how in p["load"]) else "")
    out = (_TEMPLATE.replace("@DATA@", _data(top, manifest)).replace("@LOAD_PARAMS@", params)
           .replace("@LOAD_DICT@", values).replace("@LOAD_DOC@", _doc_args(p["load"])).replace("@CHOL_DOC@", chol)
           .replace("@LOAD_ARGS@", load_args).replace("@STEP_ARGS@", step_args))
    return (out.replace("@CLASS@", class_name(top)).replace("@TOP@", top).replace("@CORE@", manifest["core"])
            .replace("@VLNV@", vlnv(top)))


def files(top: str, manifest) -> dict[str, str]:
    """``TOP_driver.py`` of a core with a register and memory map (an AXI4 slave); none for
    one without."""
    if "bus" not in manifest or "memories" not in manifest:
        return {}
    return {f"{top}_driver.py": text(top, manifest)}
