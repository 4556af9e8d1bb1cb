"""List scheduler: a step program onto P processing elements, one divider, one square root
and a banked operand memory, cycle for cycle as the hardware will run it.

The machine (:class:`Machine`):

* A PE is an FMA of latency ``Lf`` whose output feeds back to its addend input, so it
  interleaves up to ``Lf`` accumulations: an accumulation of K terms issued on a PE at cycle
  ``t`` issues its terms at ``t, t + Lf, ..., t + (K - 1) Lf`` (exactly ``Lf`` apart: the
  previous result meets the next product with no FIFO), one issue per PE per cycle. ``init``
  (else the addend is ``-0``) is read one cycle before the first issue, on the PE's third
  read lane, so that no cycle of one accumulation needs more than two reads.
* One divider and one square root, each issuing once every ``div_interval`` /
  ``sqrt_interval`` cycles (1: pipelined; more: an iterative unit, far smaller, which is
  enough for the rare pivots and sqrt(D)); one move unit for copies (read a word, write it
  back). Every unit but the PEs adds ``unit_register`` cycles (1) to its own latency: the
  divider, square root and exponential take their operands through a register, the move
  unit and the comparator write their result from one (their latency is that register).
* Reads happen at issue and take ``read_latency`` cycles (the engine's: its lane register,
  the block RAM, the data register: 3); a result is written ``read_latency + L`` cycles
  after its (last) issue and may be read from the next cycle (no bypass). A mirrored result
  is written to both addresses in that cycle.
* The operand memory has ``banks`` banks, word ``a`` in bank ``a % banks``, each with
  ``ports`` ports per cycle (a dual-port RAM: 2), each port one read or one write. The
  scheduler assigns the ports: each lane of an operation (``a``, ``b``, ``init``, each
  destination) keeps one port for the whole operation, and no port of a bank is asked for
  two things in one cycle, except reads of one word (a broadcast). So the hardware's
  crossbar needs no arbitration: a port's address is the OR of the lanes that name it.

Operations are placed one at a time, most critical first (longest latency path to the end
of the step), each at the earliest cycle where its operands are ready, the words it
overwrites have been read (and written) by every earlier operation, and its PE slots and
bank ports are free. ``pes=None`` gives the dependency-chain bound: unlimited PEs, dividers
and ports, the same latencies.
"""

from __future__ import annotations

import heapq
from collections import defaultdict
from dataclasses import dataclass, field

from . import isa
from .program import Program

__all__ = ["Machine", "Placement", "Schedule", "schedule", "chain_bound", "LANE_READ_LATENCY",
           "UNIT_REGISTER"]


#: Cycles from a lane's read to its data in the engine: the lane register in front of the
#: crossbar, the block RAM, the port's register behind it.
LANE_READ_LATENCY = 3

#: Registers a shared unit (divider, square root, exponential, move, comparator) adds to its
#: own latency: the operands' register in front of an arithmetic unit, so that its first
#: stage does not sit behind a lane's port select; the result's register behind a move or a
#: maximum, so that a word read is not checked and written in one cycle.
UNIT_REGISTER = 1


#: The machine fields of the trigonometric units' latencies and initiation intervals.
TRIG_FIELDS = tuple(f"{fn}_{what}" for fn in ("sin", "cos", "atan2") for what in ("latency", "interval"))


@dataclass(frozen=True)
class Machine:
    """The engine's timing. ``pes=None``: unlimited resources (the chain bound)."""

    pes: int | None
    fma_latency: int
    div_latency: int
    sqrt_latency: int
    banks: int | None = None  # None: 2 * pes (two reads a PE a cycle; the core's choice)
    ports: int = 2
    read_latency: int = LANE_READ_LATENCY
    div_interval: int = 1  # cycles between issues: an iterative unit's cycles_per_op
    sqrt_interval: int = 1
    exp_latency: int = 1  # the exponential's pipeline (only programs with Exp use it)
    sin_latency: int = 1  # the iterative sin, cos and atan2 (only programs with them use them)
    sin_interval: int = 1
    cos_latency: int = 1
    cos_interval: int = 1
    atan2_latency: int = 1
    atan2_interval: int = 1
    unit_register: int = UNIT_REGISTER  # added to every unit's latency but the FMA's
    fetch_register: int = 0  # 1: the program store's word registered behind its ROM (a step's lead + 1)

    def __post_init__(self):
        if self.pes is not None and (isinstance(self.pes, bool) or not isinstance(self.pes, int)
                                     or self.pes < 1):
            raise ValueError(f"pes must be a positive integer or None, not {self.pes!r}")
        for k in ("fma_latency", "div_latency", "sqrt_latency", "read_latency", "ports", "div_interval",
                  "sqrt_interval", "exp_latency", "unit_register", *TRIG_FIELDS):
            v, lo = getattr(self, k), 0 if k in ("read_latency", "unit_register") else 1
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise ValueError(f"{k} must be an integer of at least {lo}, not {v!r}")
        if self.fetch_register not in (0, 1) or isinstance(self.fetch_register, bool):
            raise ValueError(f"fetch_register must be 0 or 1, not {self.fetch_register!r}")
        if self.banks is None and self.pes is not None:
            object.__setattr__(self, "banks", 2 * self.pes)

    def latency(self, unit: str) -> int:
        """Cycles from the arrival of ``unit``'s operands to its write (the scheduler's ``L``)."""
        return isa.unit(unit).cycles(self)

    def interval(self, unit: str) -> int:
        """Cycles from one issue to the next on ``unit`` (1: pipelined)."""
        return isa.unit(unit).issue_interval(self)

    def unlimited(self) -> Machine:
        """Unlimited PEs, banks and ports, and a divider and square root per operation."""
        return Machine(None, self.fma_latency, self.div_latency, self.sqrt_latency,
                       None, self.ports, self.read_latency, exp_latency=self.exp_latency,
                       unit_register=self.unit_register, fetch_register=self.fetch_register,
                       **{k: getattr(self, k) for k in TRIG_FIELDS})


@dataclass(frozen=True)
class Placement:
    """Where one operation runs: ``unit``, PE index (fma), first issue cycle, the cycle its
    result is written, and the memory port of each lane: ``ports[lane]`` for the lanes
    ``a``, ``b``, ``init``, ``dst0``, ``dst1`` that the operation has (empty on unlimited
    machines)."""

    op: int
    unit: str
    pe: int
    start: int
    write: int
    ports: dict = field(default_factory=dict, compare=False)


@dataclass
class Schedule:
    program: Program
    machine: Machine
    placements: list[Placement] = field(default_factory=list)  # in program order

    @property
    def cycles(self) -> int:
        """The step's exact length: from the first issue to the last write, inclusive."""
        return max(p.write for p in self.placements) + 1 if self.placements else 0

    def issues(self):
        """Per-cycle issue information: ``{cycle: [(unit, pe, op, term), ...]}``; ``term`` is
        the term index (0 for the first issue, a division, a square root or a copy)."""
        out = defaultdict(list)
        lf = self.machine.fma_latency
        for p in self.placements:
            op = self.program.ops[p.op]
            for k in range(len(op.terms) if p.unit == "fma" else 1):
                out[p.start + k * lf].append((p.unit, p.pe, p.op, k))
        return dict(sorted(out.items()))

    def reads(self, p: Placement):
        """``(cycle, address)`` of every read of placement ``p``."""
        op = self.program.ops[p.op]
        if p.unit != "fma":
            return [(p.start, a) for a in op.reads]
        return [(p.start + off, a) for off, a in _reads_at(op, self.machine)]


def _shape(op, mc: Machine):
    """(issue offsets, write offset from the first issue)."""
    if op.unit == "fma":
        offs = [i * mc.fma_latency for i in range(len(op.terms))]
        return offs, offs[-1] + mc.read_latency + mc.fma_latency
    return [0], mc.read_latency + mc.latency(op.unit)


def _reads_at(op, mc: Machine):
    """[(offset, address)] of the reads, relative to the first issue."""
    return [r for lane in _lanes(op, mc).values() for r in lane]


def _lanes(op, mc: Machine):
    """{lane: [(offset, address)]} of the reads, by read lane (``a``, ``b``, ``init``)."""
    if op.unit != "fma":
        return {k: [(0, a)] for k, a in zip("ab", op.reads)}
    lf = mc.fma_latency
    lanes = {"a": [(k * lf, t[0]) for k, t in enumerate(op.terms)],
             "b": [(k * lf, t[1]) for k, t in enumerate(op.terms)]}
    if op.init is not None:
        lanes["init"] = [(-1, op.init)]
    return lanes


_WRITE = -1  # a port's use by a write (addresses are >= 0)

#: Port choices tried for a pair of lanes (different ports first) and for one lane.
_PAIRS = ((0, 1), (1, 0), (0, 0), (1, 1))
_ONE = ((0,), (1,))


def schedule(prog: Program, mc: Machine) -> Schedule:
    """Place every operation of ``prog`` on machine ``mc``."""
    ops = prog.ops
    nops = len(ops)
    shapes = [_shape(op, mc) for op in ops]
    reads = [_reads_at(op, mc) for op in ops]
    # Dependencies in program order: read after write, write after read, write after write.
    succ = [[] for _ in range(nops)]
    npred = [0] * nops
    last_write, readers = {}, defaultdict(list)
    for i, op in enumerate(ops):
        preds = set()
        for a in op.reads:
            if a in last_write:
                preds.add(last_write[a])
        for a in op.dst:
            preds.update(readers[a])
            if a in last_write:
                preds.add(last_write[a])
        preds.discard(i)
        for p in preds:
            succ[p].append(i)
        npred[i] = len(preds)
        for a in op.reads:
            readers[a].append(i)
        for a in op.dst:
            last_write[a] = i
            readers[a] = []
    # Priority: the longest latency path from the op's start to the end of the step.
    prio = [0] * nops
    for i in range(nops - 1, -1, -1):
        tail = max((prio[j] for j in succ[i]), default=0)
        prio[i] = shapes[i][1] + 1 + tail
    unlimited = mc.pes is None
    pe_busy = set()  # (pe, cycle)
    unit_busy = set()  # (unit, cycle)
    port_use = {}  # (bank, port, cycle) -> the address read there, or _WRITE
    ready = {}  # address -> first cycle it may be read (written by this step)
    read_last = defaultdict(lambda: -1)  # address -> last cycle it is read
    write_last = defaultdict(lambda: -1)
    pe_floor = defaultdict(int)  # every slot of a PE below this cycle is taken
    placed = [None] * nops
    lanes = [_lanes(op, mc) for op in ops]
    if not unlimited:
        for i, op in enumerate(ops):
            per = defaultdict(set)
            for off, a in reads[i]:
                per[off, a % mc.banks].add(a)
            if max(map(len, per.values()), default=0) > mc.ports or len(op.dst) > mc.ports:
                raise ValueError(f"operation {i} needs more than {mc.ports} ports of one bank in "
                                 f"one cycle: {op!r}")
    heap = [(-prio[i], i) for i in range(nops) if npred[i] == 0]
    heapq.heapify(heap)

    plans = {}  # op -> [(lane names, port choices, [[(bank, offset or None, address)] per lane])]

    def port_plan(i):
        """Operation ``i``'s lanes in the order :func:`choose_ports` chooses them: ``a`` and
        ``b`` together, then ``init``, then the destinations (offset None: at the write)."""
        rd, groups = lanes[i], []
        for names in (tuple(k for k in ("a", "b") if k in rd), ("init",) if "init" in rd else (),
                      tuple(f"dst{k}" for k in range(len(ops[i].dst)))):
            if names:
                reads = [[(ops[i].dst[int(n[3:])] % mc.banks, None, _WRITE)] if n.startswith("dst")
                         else [(a % mc.banks, off, a) for off, a in rd[n]] for n in names]
                groups.append((names, _PAIRS if len(names) == 2 else _ONE, reads))
        return groups

    def choose_ports(i, t, w):
        """Ports for each lane of operation ``i`` issued at ``t`` and written at ``w``, or
        None. Lanes ``a`` and ``b`` are chosen together (they read in the same cycles), then
        ``init`` (the cycle before) and the destinations (at ``w``, no read cycle of the
        operation), each independently: one word read, or one write, per port and cycle,
        agreeing with the ports taken and with each other."""
        plan = plans.get(i)
        if plan is None:
            plan = plans[i] = port_plan(i)
        chosen = {}
        for names, choices, reads in plan:
            for ports in choices:
                mine = {}
                for lane, port in zip(reads, ports):
                    for bank, off, a in lane:
                        key = (bank, port, w if off is None else t + off)
                        have = port_use.get(key)
                        if have is None:
                            have = mine.get(key)
                        if have is not None and (have != a or a == _WRITE):
                            break
                        mine[key] = a
                    else:
                        continue
                    break
                else:
                    chosen.update(zip(names, ports))
                    break
            else:
                return None
        return chosen

    lf = mc.fma_latency

    def pe_free_from(pe, t, terms, bound):
        """The first cycle in [t, bound) at which PE ``pe`` can issue ``terms`` terms, one
        every ``lf`` cycles, or ``bound`` (the search a cycle at a time finds the same cycle):
        in each of the ``lf`` residue classes, past the last busy slot of the window at once."""
        best = bound
        for r in range(lf):
            t1 = t + r
            if t1 >= best:
                break
            while t1 < best:
                j = terms - 1
                while j >= 0 and (pe, t1 + j * lf) not in pe_busy:
                    j -= 1
                if j < 0:
                    best = t1
                    break
                t1 += (j + 1) * lf  # every start before it meets that busy slot
        return best

    def first_pe(t, terms):
        """(the first cycle >= ``t`` with a PE free for ``terms`` terms, the lowest such PE)."""
        best, pe = None, None
        for p in range(mc.pes):
            tp = pe_free_from(p, t, terms, float("inf") if best is None else best)
            if best is None or tp < best:
                best, pe = tp, p
                if best == t:
                    break
        return best, pe

    def unit_free_from(unit, t, interval):
        """The first cycle >= ``t`` with ``interval`` free cycles of ``unit`` from it."""
        while True:
            k = interval - 1
            while k >= 0 and (unit, t + k) not in unit_busy:
                k -= 1
            if k < 0:
                return t
            t += k + 1  # every start up to t + k meets that busy cycle

    while heap:
        _, i = heapq.heappop(heap)
        op = ops[i]
        offs, woff = shapes[i]
        rd = reads[i]
        t = -min(off for off, _ in rd) if rd else 0
        for off, a in rd:
            if a in ready:
                t = max(t, ready[a] - off)
        for a in op.dst:
            t = max(t, read_last[a] + 1 - woff, write_last[a] + 1 - woff)
        ports = {}
        if unlimited:
            pe = 0
        else:
            if op.unit == "fma":
                t = max(t, min(pe_floor[p] for p in range(mc.pes)))
            while True:
                # the first cycle from t with a PE (the lowest) or the unit free, then its ports
                if op.unit == "fma":
                    t, pe = first_pe(t, len(offs))
                else:
                    pe = 0
                    t = unit_free_from(op.unit, t, mc.interval(op.unit))
                ports = choose_ports(i, t, t + woff)
                if ports is not None:
                    break
                t += 1
            if op.unit == "fma":
                for o in offs:
                    pe_busy.add((pe, t + o))
                f = pe_floor[pe]
                while (pe, f) in pe_busy:
                    f += 1
                pe_floor[pe] = f
            else:
                unit_busy.update((op.unit, t + k) for k in range(mc.interval(op.unit)))
            for name, lane in lanes[i].items():
                for off, a in lane:
                    port_use[a % mc.banks, ports[name], t + off] = a
            for k, a in enumerate(op.dst):
                port_use[a % mc.banks, ports[f"dst{k}"], t + woff] = _WRITE
        w = t + woff
        for off, a in rd:
            read_last[a] = max(read_last[a], t + off)
        for a in op.dst:
            ready[a] = w + 1
            write_last[a] = w
        placed[i] = Placement(i, op.unit, pe, t, w, ports)
        for j in succ[i]:
            npred[j] -= 1
            if npred[j] == 0:
                heapq.heappush(heap, (-prio[j], j))
    return Schedule(prog, mc, placed)


def chain_bound(prog: Program, mc: Machine) -> int:
    """The dependency-chain bound of ``prog``: its length on unlimited PEs, dividers and
    ports with ``mc``'s latencies, which no number of PEs can beat."""
    return schedule(prog, mc.unlimited()).cycles
