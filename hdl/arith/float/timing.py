"""A delay model of the floating-point datapaths, and the register placement it drives.

Units whose stage count is a parameter over a long datapath (the digit recurrences of
:mod:`.div` and :mod:`.sqrt`, the conversions) describe it as segments between named
boundaries, each with a delay from this model, and :class:`StagePlans` places their
registers: for any stage count, where the longest stage is shortest; by default, as few as
fit a 100 MHz clock.

The figures are ECP5 ones (ns, clock-to-output and routing included) for a LUT level and a
carry chain, fitted to nextpnr's critical paths of binary32 units on an LFE5U-85F: a
recurrence step ~5 ns whatever its width (routing dominates), two ~10 ns; the denormalising
shift by a registered amount with the OR of its lost bits ~8 ns (~10 ns in binary64); the
rounding increment to the output word ~7 ns. The model errs long on the rounding (by ~2 ns):
only the relative sizes matter for balancing the stages; the absolute ones set the default
stage counts.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from .format import FloatFormat

__all__ = ["CLOCK_MHZ", "LUT_NS", "BUDGET_NS", "lut_delay", "carry_delay", "tree_levels", "shifter_delay",
           "dsp_delay", "block_ram_delay", "prepare_delay", "round_delays", "StagePlans",
           "longest_stage", "CALIBRATION", "MEASURED_MHZ", "TARGET_RANGE", "predicted_mhz", "stages_for_target"]

#: The clock the default stage counts are designed for: an ECP5-85, binary32. The units placed
#: by this model meet it by the model; add, sub, mul and fma have fixed defaults, measured
#: above it (README, Performance).
CLOCK_MHZ = 100
LUT_NS = 1.2
BUDGET_NS = 1000 / CLOCK_MHZ - 0.5  # less a margin for placement


def lut_delay(levels: float) -> float:
    return LUT_NS * levels


def carry_delay(width: int) -> float:
    """An adder or comparator of ``width`` bits: entry LUT, carry chain, exit routing."""
    return 2.4 + 0.03 * width


def tree_levels(width: int, fan_in: int = 2) -> int:
    """Levels of a ``fan_in``-input tree over ``width`` bits (a reduction, a priority count)."""
    return max(1, math.ceil(math.log(max(width, 2), fan_in)))


def shifter_delay(width: int) -> float:
    """A barrel shifter over ``width`` bits (a 4:1 multiplexer takes a LUT and a PFUMX)."""
    return lut_delay(0.7 * tree_levels(width))


def dsp_delay() -> float:
    """A multiplier block's product (MULT18X18D without its registers), routing in and out
    included: most of a stage, so a product gets one to itself."""
    return 7.0


def block_ram_delay() -> float:
    """What a table read from a block RAM adds after its register: a synthesis tool turns a
    table whose output is registered into one (an ECP5 DP16KD without its output register
    has a 5.6 ns clock-to-out, where a flip-flop has about 0.5 ns)."""
    return 5.0


def prepare_delay(fmt: FloatFormat, from_room: bool = False) -> float:
    """:func:`~.round.prepare_exponent`: the room above emin (an add, unless ``from_room``),
    then beside each other the compares that clamp it and the negation that gives the right
    shift, and their selects."""
    compare = carry_delay(fmt.exp_bits + 3) + lut_delay(1)
    return compare if from_room else carry_delay(fmt.exp_bits + 3) + compare


def round_delays(fmt: FloatFormat, width: int, denormalise: bool = True,
                 leading_one: bool = False, prepared: bool = False) -> list[float]:
    """Logic before each of :data:`~.round.ROUND_BOUNDARIES` and ``"out"`` in
    :func:`~.round.round_pack`, for a ``width``-bit significand.

    ``leading_one``: its top bit is a constant one, so the leading-zero count and the left
    shift fold away. ``prepared``: the exponent comes from :func:`~.round.prepare_exponent`
    through a register, not computed before ``"round.shift"``.

    Before ``"round.shift"``, beside each other: the denormalising right shift (by the
    prepared amount) with the OR of the bits it loses, and the leading-zero count capped at
    emin. Before ``"round.round"``: the normalising left shift, beside the biased exponent
    (``room - left``). Before ``"round.select"``: the increment beside the reduction of the
    bits under the round bit, the round-up select, then the exponent and overflow selects
    by the carry and hidden bits (their adds and compares run beside). Before ``"out"``: the
    special-result selects.
    """
    p = fmt.precision
    exp_width = fmt.exp_bits + 3
    count = 0.0 if leading_one else lut_delay(1 + tree_levels(width) + 1)  # marker, tree
    if denormalise:
        lost = lut_delay(tree_levels(p + 1, 4))
        shift_right = shifter_delay(width + p + 1) + lost
    else:
        shift_right = 0.0
    shift = (0.0 if prepared else prepare_delay(fmt)) + max(count, shift_right)
    if leading_one:
        normalise = lut_delay(1)  # the exponent's select for a subnormal result
    else:
        normalise = max(shifter_delay(width), carry_delay(exp_width)) + lut_delay(1)
    rest = lut_delay(tree_levels(width - p, 4))
    round_up = max(carry_delay(p + 1), rest) + lut_delay(3)
    return [shift, normalise, round_up, lut_delay(2)]


class StagePlans(Mapping):
    """Register placements for every stage count of a straight-line datapath.

    ``segments`` lists ``(boundary, delay)`` in datapath order, ``delay`` being the logic
    between the previous boundary and this one. The last boundary (``"out"``) and those in
    ``forced`` always get a register, except in the all-combinational plan of zero stages
    (allowed when nothing else is forced). For a stage count, the longest stage (by the delay
    model) is made as short as possible: registers go as late as that bound allows, and any
    left over split the stages where that shortens them most. ``offset`` is added to the
    register count and boundaries in ``hidden`` are left out of the plans: an iterative core
    is a forced boundary whose registers the unit makes itself, ``offset + 1`` cycles of
    latency.

    A mapping ``stages -> tuple of boundaries`` (computed on demand), as
    :class:`~.round.FloatUnit` expects of ``PLANS``.
    """

    def __init__(self, segments, forced=(), offset=0, hidden=()):
        self._names = [name for name, _ in segments]
        self._hidden = set(hidden)
        self._delays = [float(d) for _, d in segments]
        self._forced = set(forced) | {self._names[-1]}
        self._offset = offset
        self._prefix = [0.0]
        for d in self._delays:
            self._prefix.append(self._prefix[-1] + d)
        n = len(self._names)
        # Without a forced register inside, zero stages (all combinational) is allowed too.
        self._lo = 0 if len(self._forced) == 1 and not offset else len(self._forced) + offset
        self._hi = n + offset
        self._bounds = sorted({self._prefix[j + 1] - self._prefix[i]
                               for i in range(n + 1) for j in range(i, n)})

    def __len__(self):
        return self._hi - self._lo + 1

    def __iter__(self):
        return iter(range(self._lo, self._hi + 1))

    def __contains__(self, stages):
        return isinstance(stages, int) and not isinstance(stages, bool) \
            and self._lo <= stages <= self._hi

    def _cost(self, i, j):
        """Delay of the stage between chosen boundaries ``i`` and ``j`` (``i = -1``: input)."""
        return self._prefix[j + 1] - self._prefix[i + 1]

    def _latest(self, bound):
        """Boundary indices chosen as late as ``bound`` allows (a longer single segment gets a
        stage of its own)."""
        chosen, last = [], -1
        for j, name in enumerate(self._names):
            if j + 1 < len(self._names) and name not in self._forced \
                    and self._cost(last, j + 1) <= bound:
                continue
            chosen.append(j)
            last = j
        return chosen

    def __getitem__(self, stages):
        if stages not in self:
            raise KeyError(stages)
        count = stages - self._offset
        if count == 0:
            return ()
        return tuple(self._names[j] for j in self._chosen(count) if self._names[j] not in self._hidden)

    def longest(self, stages) -> float:
        """The longest stage's delay by the model with ``stages`` registers (forced and hidden
        boundaries included)."""
        if stages not in self:
            raise KeyError(stages)
        count = stages - self._offset
        if count == 0:
            return self._prefix[-1]
        chosen = self._chosen(count)
        return max(self._cost(i, j) for i, j in zip([-1] + chosen, chosen))

    def _chosen(self, count):
        # The smallest bound met with at most ``count`` registers, by bisection.
        lo, hi = 0, len(self._bounds) - 1
        while lo < hi:
            mid = (lo + hi) // 2
            if len(self._latest(self._bounds[mid])) <= count:
                hi = mid
            else:
                lo = mid + 1
        chosen = self._latest(self._bounds[lo])
        while len(chosen) < count:
            chosen = self._split_longest(chosen)
        return chosen

    def _split_longest(self, chosen):
        best = None
        for k, j in enumerate(chosen):
            i = chosen[k - 1] if k else -1
            for c in range(i + 1, j):
                key = (max(self._cost(i, c), self._cost(c, j)) - self._cost(i, j), c)
                if best is None or key < best[0]:
                    best = (key, c)
        return sorted(chosen + [best[1]])

    def default(self, budget=BUDGET_NS):
        """The fewest stages that meet ``budget``, or the delay of a forced boundary's own
        segment if longer (an iterative core's cycle sets the clock: the logic around it
        need not be faster). A single segment over the bound gets a stage of its own."""
        index = {name: j for j, name in enumerate(self._names)}
        bound = max([budget] + [self._cost(index[n] - 1, index[n]) for n in self._forced])
        return len(self._latest(bound)) + self._offset


def longest_stage(segments, boundaries) -> float:
    """The longest stage's delay when ``boundaries`` (names among ``segments``' ``(name,
    delay)``) get the registers: the whole path for none."""
    chosen, longest, run = set(boundaries), 0.0, 0.0
    for name, delay in segments:
        run += delay
        if name in chosen:
            longest, run = max(longest, run), 0.0
    return max(longest, run)


#: The model against nextpnr-ecp5: an op's clock period on an LFE5U-85F is about its
#: ``scale`` times its longest stage by this model (routing and the flip-flops' own delays
#: grow with the stage, and the model's figures err long by a factor that depends on the
#: kind of logic). Each scale is the median, over the op's binary32 plans that
#: ``python -m kfgen.gen.bench_timing`` measured (median of 3 seeds each), of the measured period
#: over the model's figure, as that bench prints it; an op without one takes ``"other"``, the
#: median of the others. Only ``--target-mhz`` reads it:
#: the default stage counts do not, so a new calibration changes no default core.
CALIBRATION = {"add": 0.80, "sub": 0.78, "mul": 0.81, "div": 0.86, "sqrt": 0.80, "fma": 0.89, "i2f": 0.58,
               "f2i": 0.83, "exp": 0.80, "other": 0.80}
#: Where the clock of a unit without stage choices comes from (``--target-mhz`` has nothing
#: to pick for the iterative sin, cos and atan2: their step control sets it), MHz, binary32
#: (``python -m kfgen.gen.bench_fpu``).
MEASURED_MHZ = {"sin": 95.4, "cos": 93.4, "atan2": 106.0}
#: The highest and lowest ``--target-mhz`` taken.
TARGET_RANGE = (10.0, 1000.0)


def predicted_mhz(op: str, longest_ns: float) -> float:
    """The Fmax the calibrated model predicts for ``op`` with a longest stage of ``longest_ns``."""
    return 1000.0 / (CALIBRATION.get(op, CALIBRATION["other"]) * longest_ns)


def stages_for_target(op: str, delays: Mapping[int, float], target_mhz: float) -> tuple[int, float]:
    """``(stages, predicted MHz)``: the fewest of ``delays`` (stage count -> longest stage,
    :meth:`~.round.FloatUnit.stage_delays`) whose predicted Fmax reaches ``target_mhz``, or,
    when none does, the most (the model's figure is then that of a stage it cannot split, and
    registers elsewhere still shorten what it does not see)."""
    options = sorted((k, predicted_mhz(op, d)) for k, d in delays.items() if k > 0)
    for k, mhz in options:
        if mhz >= target_mhz:
            return k, mhz
    return options[-1]
