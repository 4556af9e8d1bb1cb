"""cocotb testbench of a generated Castella core (run under Verilator by :mod:`kfgen.sim.castella.run`).

It reads everything from files, so one build serves every stimulus:

* ``KFGEN_TB_MANIFEST``: the core's manifest (``TOP.json``): port widths and fields.
* ``KFGEN_TB_STIM``: an ``.npz`` with ``tid``, ``tdata``, ``tuser`` input words, the
  probabilities ``gap`` (an idle input cycle) and ``stall`` (``m_axis_tready`` low),
  ``seed``, and optionally ``expect_tdata``, ``expect_tid``, ``expect_tuser``.
* ``KFGEN_TB_OUT``: where the collected output words and handshake cycles are written, and
  how many cycles each stream's valid waited for ready (``m_axis_waits``, ``s_axis_waits``).

One coroutine does the whole cycle: at the falling edge it drives both streams, in the
read-only phase it samples both handshakes (a transfer is valid and ready at the rising edge)
without races. There too a :class:`~kfgen.sim.streams.StreamChecker` holds the core's
``m_axis`` to the AXI4-Stream rules (valid, once high, and the payload hold until the
transfer), and the testbench's own ``s_axis`` driving as a self-check.
Every output word is compared with the golden model's as it arrives.
"""

from __future__ import annotations

import json
import os

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, ReadOnly

from ..streams import StreamChecker


def _field_text(manifest, port, word):
    spec = next(p for p in manifest["ports"] if p["name"] == port)
    parts = []
    for f in spec.get("fields", []):
        v = (word >> f["lsb"]) & ((1 << f["width"]) - 1)
        if f["signed"] and v >> (f["width"] - 1):
            v -= 1 << f["width"]
        parts.append(f"{f['name']}={v}")
    return " ".join(parts) or hex(word)


async def _reset(dut, cycles=2):
    """``rst`` high for ``cycles`` falling edges, from the next one (never in a read-only phase)."""
    await FallingEdge(dut.clk)
    dut.rst.value = 1
    dut.s_axis_tvalid.value = 0
    dut.m_axis_tready.value = 0
    for _ in range(cycles):
        await FallingEdge(dut.clk)
    dut.rst.value = 0


async def _clean_run(dut, manifest, stim, rng):
    """Stream the stimulus's measurements (random gaps and stalls), compare every result with
    the expectation as it arrives, then idle: nothing more may come out. The results."""
    tids, tdata, tuser = (stim[k].astype(np.int64) for k in ("tid", "tdata", "tuser"))
    gap, stall = float(stim["gap"]), float(stim["stall"])
    expect = {k: stim[f"expect_{k}"] for k in ("tdata", "tid", "tuser") if f"expect_{k}" in stim}
    n = len(tids)
    streams = [StreamChecker.axis(dut, "m_axis"), StreamChecker.axis(dut, "s_axis")]
    got = {"tdata": [], "tid": [], "tuser": []}
    in_cycle, out_cycle = [], []
    sent, cycle, idle_limit = 0, 0, 2000 + 200 * n
    mismatches = []
    valid = False
    while len(got["tid"]) < n:
        await FallingEdge(dut.clk)
        cycle += 1
        if cycle > idle_limit:
            raise AssertionError(f"timeout: {len(got['tid'])} of {n} results after {cycle} cycles")
        # drive: a new item once the previous one was taken; valid is never withdrawn
        if not valid and sent < n and rng.random() >= gap:
            dut.s_axis_tdata.value = int(tdata[sent])
            dut.s_axis_tid.value = int(tids[sent])
            dut.s_axis_tuser.value = int(tuser[sent])
            valid = True
        dut.s_axis_tvalid.value = int(valid)
        ready_out = rng.random() >= stall
        dut.m_axis_tready.value = int(ready_out)
        await ReadOnly()
        for checker in streams:
            checker.sample(cycle)
        if valid and dut.s_axis_tready.value:
            in_cycle.append(cycle)
            sent += 1
            valid = False
        if ready_out and dut.m_axis_tvalid.value:
            i = len(got["tid"])
            words = {"tdata": int(dut.m_axis_tdata.value), "tid": int(dut.m_axis_tid.value),
                     "tuser": int(dut.m_axis_tuser.value)}
            for k, w in words.items():
                got[k].append(w)
            out_cycle.append(cycle)
            if expect and any(words[k] != int(expect[k][i]) for k in expect):
                mismatches.append(
                    f"result {i}: got tid={words['tid']} {_field_text(manifest, 'm_axis_tdata', words['tdata'])} "
                    f"{_field_text(manifest, 'm_axis_tuser', words['tuser'])}; expected tid={int(expect['tid'][i])} "
                    f"{_field_text(manifest, 'm_axis_tdata', int(expect['tdata'][i]))} "
                    f"{_field_text(manifest, 'm_axis_tuser', int(expect['tuser'][i]))}")
    # A further few cycles: nothing more may come out.
    extra = 0
    for k in range(manifest["latency_cycles"] + 4):
        await FallingEdge(dut.clk)
        dut.s_axis_tvalid.value = 0
        dut.m_axis_tready.value = 1
        await ReadOnly()
        for checker in streams:
            checker.sample(cycle + 1 + k)
        extra += int(dut.m_axis_tvalid.value)
    assert extra == 0, f"{extra} results beyond the {n} inputs"
    assert not mismatches, f"{len(mismatches)} of {n} results differ from the golden model:\n" + \
        "\n".join(mismatches[:20])
    return got, in_cycle, out_cycle, cycle, streams


@cocotb.test()
async def stream(dut):
    manifest = json.loads(open(os.environ["KFGEN_TB_MANIFEST"]).read())
    stim = np.load(os.environ["KFGEN_TB_STIM"], allow_pickle=True)
    rng = np.random.default_rng(int(stim["seed"]))
    cocotb.start_soon(Clock(dut.clk, 10, unit="ns").start())
    await _reset(dut)
    got, in_cycle, out_cycle, cycle, streams = await _clean_run(dut, manifest, stim, rng)
    np.savez(os.environ["KFGEN_TB_OUT"], tdata=np.array(got["tdata"], dtype=object),
             tid=np.array(got["tid"]), tuser=np.array(got["tuser"]),
             in_cycle=np.array(in_cycle), out_cycle=np.array(out_cycle), cycles=cycle,
             **{f"{c.name}_waits": c.waits for c in streams})


@cocotb.test()
async def fault_campaign(dut):
    """``KFGEN_TB_SEQUENCES`` sequences: random traffic on both streams (any track, any data,
    restart flags, random valid and ready, m_axis still held to the AXI4-Stream rules) cut by
    resets (``rst``) at random cycles, in flight or not; then, after a reset, the stimulus's
    clean run, every result against the golden model, and nothing more out. Nothing may hang:
    a clean run has its timeout."""
    manifest = json.loads(open(os.environ["KFGEN_TB_MANIFEST"]).read())
    stim = np.load(os.environ["KFGEN_TB_STIM"], allow_pickle=True)
    rng = np.random.default_rng(int(stim["seed"]))
    tracks = manifest["parameters"]["tracks"]
    widths = {p["name"]: p["width"] for p in manifest["ports"]}
    cocotb.start_soon(Clock(dut.clk, 10, unit="ns").start())
    resets = 0
    for _ in range(int(os.environ.get("KFGEN_TB_SEQUENCES", "20"))):
        await _reset(dut)
        checker = StreamChecker.axis(dut, "m_axis")
        valid = False
        for cycle in range(int(rng.integers(10, 4 * manifest["latency_cycles"]))):
            await FallingEdge(dut.clk)
            if rng.random() < 0.02:  # a reset in the middle of the traffic
                await _reset(dut, int(rng.integers(1, 4)))
                checker = StreamChecker.axis(dut, "m_axis")
                valid = False
                resets += 1
                continue
            if not valid and rng.random() < 0.7:
                dut.s_axis_tdata.value = int(rng.integers(0, 1 << widths["s_axis_tdata"]))
                dut.s_axis_tid.value = int(rng.integers(0, tracks))
                dut.s_axis_tuser.value = int(rng.integers(0, 2))
                valid = True
            dut.s_axis_tvalid.value = int(valid)
            dut.m_axis_tready.value = int(rng.random() < 0.6)
            await ReadOnly()
            checker.sample(cycle)
            if valid and dut.s_axis_tready.value:
                valid = False
        await FallingEdge(dut.clk)
        await _reset(dut)
        await _clean_run(dut, manifest, stim, rng)
    dut._log.info("fault campaign: %d resets in the traffic", resets)
