"""The list scheduler: every schedule keeps the program's dependencies and the machine's
resource limits; cycle counts against the bounds and the chapter's Table 4."""

from collections import Counter, defaultdict

import pytest

from kfgen.gen.bench_ukf import CHAPTER_CYCLES as CHAPTER  # Table 4, cycles per iteration at 100 MHz
from kfgen.hdl.linalg.engine import program_roms
from kfgen.hdl.linalg.microcode import compile_steps
from kfgen.hdl.linalg.schedule import Machine, chain_bound, schedule
from kfgen.hdl.linalg.store import encode
from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.programs import build_ukf
from kfgen.hdl.ukf.steps import machine as ukf_machine


def ukf_programs(sizes, w0=0.0, fmt="binary32"):
    """The UKF's programs for ``sizes`` (n, nw, nv, m)."""
    n, nw, nv, m = sizes
    return build_ukf(UkfParams(states=n, observations=m, process_noise=nw, measurement_noise=nv, w0=w0,
                               format=fmt))


def machine(pes, fmt="binary32", div_sqrt=None):
    """The core's machine (:func:`kfgen.hdl.ukf.steps.machine`) for P PEs."""
    return ukf_machine(UkfParams(states=pes, observations=1, process_noise=1, measurement_noise=1,
                                 pes=pes, format=fmt, div_sqrt=div_sqrt))


def check_schedule(s):
    """Dependencies in program order and resource limits, from the placements alone."""
    prog, mc = s.program, s.machine
    ops, pl = prog.ops, s.placements
    reads = [s.reads(p) for p in pl]
    last_write, readers = {}, defaultdict(list)
    for i, op in enumerate(ops):
        for cyc, a in reads[i]:
            if a in last_write:  # read after write: from the next cycle on
                assert cyc > pl[last_write[a]].write, (i, a)
        for a in op.dst:
            for j in readers[a]:  # write after read
                assert pl[i].write > max(c for c, b in reads[j] if b == a), (i, j, a)
            if a in last_write:
                assert pl[i].write > pl[last_write[a]].write, (i, a)
        for _, a in reads[i]:
            readers[a].append(i)
        for a in op.dst:
            last_write[a] = i
            readers[a] = []
    issues = Counter()
    for cyc, lst in s.issues().items():
        for unit, pe, _, _ in lst:
            issues[unit, pe if unit == "fma" else 0, cyc] += 1
    assert max(issues.values()) == 1  # one issue per PE, divider, square root, move unit
    for unit in ("div", "sqrt"):  # an iterative unit: issues at least its interval apart
        starts = sorted(p.start for p in pl if p.unit == unit)
        assert all(b - a >= mc.interval(unit) for a, b in zip(starts, starts[1:])), unit
    assert all(p.pe < mc.pes for p in pl)
    for p in pl:  # terms exactly Lf apart; result after the last term's latency
        op = ops[p.op]
        n = len(op.terms) if p.unit == "fma" else 1
        lat = mc.latency(p.unit)
        assert p.write == p.start + (n - 1) * mc.fma_latency * (p.unit == "fma") + mc.read_latency + lat
    # every lane on the port its placement names; a port a cycle serves one write or reads of
    # one word (the hardware ORs the addresses of the lanes naming a port)
    use = defaultdict(set)
    for i, p in enumerate(pl):
        op = ops[i]
        lane_reads = {"a": [], "b": [], "init": []}
        if p.unit == "fma":
            for k, (a, b, _) in enumerate(op.terms):
                lane_reads["a"].append((p.start + k * mc.fma_latency, a))
                lane_reads["b"].append((p.start + k * mc.fma_latency, b))
            if op.init is not None:
                lane_reads["init"].append((p.start - 1, op.init))
        else:
            for lane, a in zip("ab", op.reads):
                lane_reads[lane].append((p.start, a))
        assert sorted(r for rs in lane_reads.values() for r in rs) == sorted(reads[i])
        for lane, rs in lane_reads.items():
            for cyc, a in rs:
                use[a % mc.banks, p.ports[lane], cyc].add(a)
        for k, a in enumerate(op.dst):
            use[a % mc.banks, p.ports[f"dst{k}"], p.write].add(("write", i, k))
    for key, what in use.items():
        assert len(what) == 1, (key, what)
        assert key[1] in (0, 1)
    # no word read in the cycle it is written: the block RAM's word would be undefined there
    written = {(p.write, a) for i, p in enumerate(pl) for a in ops[i].dst}
    assert not written & {r for rs in reads for r in rs}
    assert s.cycles == max(p.write for p in pl) + 1


@pytest.mark.parametrize("sizes,pes,fmt,div_sqrt", [
    ((2, 1, 1, 1), 1, "binary32", "iterative"), ((2, 1, 1, 1), 3, "binary64", "iterative"),
    ((2, 1, 1, 1), 1, "binary32", "pipelined"),
    ((7, 6, 7, 6), 1, "binary32", "iterative"), ((7, 6, 7, 6), 2, "binary32", "iterative"),
    ((7, 6, 7, 6), 5, "binary32", "iterative"), ((7, 6, 7, 6), 10, "binary32", "iterative"),
    ((7, 6, 7, 6), 2, "binary32", "pipelined"),
])
def test_schedule_invariants(sizes, pes, fmt, div_sqrt):
    ukf = ukf_programs(sizes, 0.25, fmt)
    for prog in ukf.steps.values():
        check_schedule(schedule(prog, machine(pes, fmt, div_sqrt)))


@pytest.mark.parametrize("div_sqrt", [None, "pipelined"], ids=["default", "pipelined"])
def test_cycles_against_bounds_and_chapter(capsys, div_sqrt):
    """M = 20 (7/6/7/6), binary32, the core's default divider and square root (iterative at
    P = 1, pipelined above) and pipelined ones: each step within 1.3x of max(multiply-adds /
    P, chain bound, the divider's and square root's occupancy), the iteration within 1.3x of
    max(multiply-adds / P, chain bound), and at least 2x fewer cycles than Table 4."""
    ukf = ukf_programs((7, 6, 7, 6), 0.0, "binary32")
    chain = {k: chain_bound(p, machine(1)) for k, p in ukf.steps.items()}
    rows = [f"chain bound {chain}"]
    for pes in (1, 2, 5, 10):
        mc = machine(pes, div_sqrt=div_sqrt)
        rows.append(f"P={pes:2}: FMA {mc.fma_latency}, div {mc.div_latency} (every {mc.div_interval}), "
                    f"sqrt {mc.sqrt_latency} (every {mc.sqrt_interval}), {mc.banks} banks")
        scheds = {k: schedule(p, mc) for k, p in ukf.steps.items()}
        total = sum(s.cycles for s in scheds.values())
        fmas = sum(p.fma_count for p in ukf.steps.values())
        for k, s in scheds.items():
            # an iterative unit bounds a step too: its issues, then the last one's read and
            # latency
            busy = max(sum(op.unit == u for op in ukf.steps[k].ops) * mc.interval(u)
                       + mc.read_latency + mc.latency(u) for u in ("div", "sqrt"))
            bound = max(ukf.steps[k].fma_count / pes, chain[k], busy)
            assert s.cycles <= 1.3 * bound, (pes, k, s.cycles, bound)
        bound = max(fmas / pes, sum(chain.values()))
        assert total <= 1.3 * bound
        assert 2 * total <= CHAPTER[pes]
        roms = program_roms(compile_steps(list(scheds.values())))
        rows.append(f"P={pes:2}: " + ", ".join(f"{k} {s.cycles}" for k, s in scheds.items())
                    + f"; iteration {total} (bound {bound:.0f}, x{total / bound:.2f}; "
                    f"FMAs/P {fmas / pes:.0f}; chapter {CHAPTER[pes]}, /{CHAPTER[pes] / total:.1f}); "
                    f"program ROMs {sum(w for w, _ in roms.values())} words, "
                    f"{sum(w * b for w, b in roms.values())} bits")
    with capsys.disabled():
        print("\n" + "\n".join(rows))


def test_store_covers_every_term():
    ukf = ukf_programs((3, 2, 2, 2), 0.0)
    for prog in ukf.steps.values():
        s = schedule(prog, machine(2))
        ins = encode(s)
        assert sum(i.count for i in ins if i.unit == "fma") == prog.fma_count
        assert sum(1 for i in ins if i.last) == len(prog.ops)
        # replay the address generators: the same reads at the same cycles as the schedule
        lf = s.machine.fma_latency
        got = sorted((i.start + k * lf, i.a0 + k * i.sa, i.b0 + k * i.sb, i.pe)
                     for i in ins if i.unit == "fma" for k in range(i.count))
        want = sorted((p.start + k * lf, a, b, p.pe) for p in s.placements if p.unit == "fma"
                      for k, (a, b, _) in enumerate(prog.ops[p.op].terms))
        assert got == want


def test_machine_rules():
    with pytest.raises(ValueError, match="pes"):
        Machine(0, 9, 32, 29)
    with pytest.raises(ValueError, match="ports"):
        schedule(ukf_programs((2, 1, 1, 1)).update, Machine(1, 9, 32, 29, banks=1, ports=1))
