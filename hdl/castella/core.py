# amaranth: UnusedElaboratable=no
# (The core builds its module once, on first need: asking only for its latency or track
# interval, as the manifest and tests do, builds a module nobody elaborates. This is
# Amaranth's public linter option for that; it covers only what this file creates.)
"""The Castella adaptive two-state tracker (Zaghar et al.), many tracks time-multiplexed.

The datapath follows the paper's units: U0 initial values (eqs. 17, 18), U1 prediction and
gains (eqs. 3-5), U2 state update (eq. 6), U3 covariance update (eq. 7), U4 manoeuvre
detector (eqs. 8-10), U5 q variation (Figure 2), U6 control (here: the stream handshake,
hazard check, credit counter and the reset sweep of the state memory).

It is one feed-forward pipeline that never stalls. Per-track state lives in a memory read
when a measurement is accepted and written back ``track_interval`` cycles later; a
measurement whose track is still in flight waits (``s_axis_tready`` low), so any input
order is correct. Results enter an output FIFO; a credit counter admits a measurement only
when the FIFO is sure to have room for it, so ``m_axis_tready`` backpressure never stalls
the datapath. With ``track_interval`` or more tracks in round robin the core accepts one
measurement every clock.

Bit-exact twin: :func:`kfgen.sim.castella.model.fixed_step`.
"""

from __future__ import annotations

from amaranth.hdl import C, Cat, Module, Mux, Signal, unsigned
from amaranth.lib import data, fifo, memory, wiring
from amaranth.lib.wiring import In, Out

from ..arith.divide import gain_divider
from ..arith.fixed import fmt_shape, rsr, saturate
from ..arith.multiply import dsp_multiply, shift_add_multiply
from ..arith.pipeline import Pipeline, Staged
from .params import ALPHA_FRAC, QSLOPE_SHIFT, RSQRT_INDEX_BITS, RSQRT_WIDTH, CastellaParams

__all__ = ["Castella", "state_layout"]

PHASE_FIRST, PHASE_INIT, PHASE_TRACK = 0, 1, 2
#: Up to this many state-memory entries, in-flight tracks are kept as a bitmap.
BUSY_BITMAP_MAX = 64


def state_layout(p: CastellaParams) -> data.StructLayout:
    """One track's words in state memory."""
    return data.StructLayout({
        "x1": fmt_shape(p.range_fmt),
        "x2": fmt_shape(p.vel_fmt),
        "p11": fmt_shape(p.p11_fmt),
        "p12": fmt_shape(p.p12_fmt),
        "p22": fmt_shape(p.p22_fmt),
        "zf": fmt_shape(p.z_fmt),
        "qc": unsigned(p.q_width),
        "phase": unsigned(2),
    })


class Castella(wiring.Component):
    """Castella tracking system core.

    Parameters
    ----------
    params : CastellaParams

    Members
    -------
    s_axis_tvalid, s_axis_tready, s_axis_tdata, s_axis_tid, s_axis_tuser
        Measurement stream: range (``params.range_fmt``), track index, restart flag.
    m_axis_tvalid, m_axis_tready, m_axis_tdata, m_axis_tid, m_axis_tuser
        Result stream, one per accepted measurement, in input order; fields as
        ``params.field_list``.

    Latency ``latency`` cycles from the input handshake to ``m_axis_tvalid`` (output
    ready); one measurement per clock aggregate; two measurements of one track at least
    ``track_interval`` cycles apart.
    """

    def __init__(self, params: CastellaParams):
        self._p = params
        super().__init__({
            "s_axis_tvalid": In(1),
            "s_axis_tready": Out(1),
            "s_axis_tdata": In(params.port_width("s_axis_tdata")),
            "s_axis_tid": In(params.tid_width),
            "s_axis_tuser": In(1),
            "m_axis_tvalid": Out(1),
            "m_axis_tready": In(1),
            "m_axis_tdata": Out(params.port_width("m_axis_tdata")),
            "m_axis_tid": Out(params.tid_width),
            "m_axis_tuser": Out(params.port_width("m_axis_tuser")),
        })
        # The module is built once, on first need: the schedule (and so the latency and the
        # FIFO depth) is only known once the datapath is built.
        self._module = None
        self._write_stage = None

    @property
    def params(self) -> CastellaParams:
        return self._p

    @property
    def track_interval(self) -> int:
        """Minimum cycles between two accepted measurements of the same track."""
        self._build()
        return self._write_stage

    @property
    def fifo_depth(self) -> int:
        return self.track_interval + 3

    @property
    def latency(self) -> int:
        """Cycles from the input handshake to the result on ``m_axis`` (output ready)."""
        return self.track_interval + 2

    @property
    def initiation_interval(self) -> int:
        """Fewest cycles between two accepted measurements: 1 (of different tracks) once there
        are two tracks; with one track, its own ``track_interval``."""
        return 1 if self._p.tracks > 1 else self.track_interval

    @property
    def sustained_rate(self) -> float:
        """Measurements per clock in steady state with every track in rotation:
        ``min(1, tracks / track_interval)``."""
        return min(1.0, self._p.tracks / self.track_interval)

    # ------------------------------------------------------------------ datapath
    def _datapath(self, m, state_in):
        """Build the datapath; return ``(write_stage, new_state, out_fields, flag)``.

        ``state_in`` is a dict of Staged inputs (``y``, ``restart`` and the stored state
        fields at stage 1).
        """
        p = self._p
        pl = Pipeline(m)
        # Register the state words once more: LUT RAM read and bypass make a slow path.
        s = {k: pl.reg(f"{k}_s2", lambda x: x, v) for k, v in state_in.items()}
        fr, fv = p.range_fmt, p.vel_fmt
        f11, f12, f22 = p.p11_fmt, p.p12_fmt, p.p22_fmt
        gw, fk2, fz = p.gain_width, p.k2_fmt.frac, p.z_fmt
        (tm, tf), (t2m, t2f), (tsm, tsf), (im, inf_) = p.t_const, p.t2x_const, p.tsq_const, p.inv_t_const

        def sat_reg(name, v, fmt, flagged=True):
            val = pl.reg(name, lambda x: saturate(x, fmt)[0], v, shape=fmt_shape(fmt))
            if not flagged:
                return val
            return val, pl.reg(name + "_sat", lambda x: saturate(x, fmt)[1], v)

        def rom(name, table, index: Staged, width):
            mem = memory.Memory(shape=unsigned(width), depth=len(table), init=table)
            m.submodules[name] = mem
            port = mem.read_port()  # read latency: 1 cycle
            m.d.comb += port.addr.eq(pl.at(index, index.stage))
            # and a register after it: a block RAM's clock-to-out is slow on ECP5
            return pl.reg(name + "_q", lambda x: x, Staged(port.data, index.stage + 1))

        phase = pl.comb("phase", lambda r, ph: Mux(r, PHASE_FIRST, ph), s["restart"], s["phase"])

        # U1: prediction, eqs. (3) and (4)
        tx2 = pl.reg("tx2", lambda x: x * tm, s["x2"])
        a12 = pl.reg("a12", lambda x: x * t2m, s["p12"])
        a22 = pl.reg("a22", lambda x: x * tsm, s["p22"])
        b22 = pl.reg("b22", lambda x: x * tm, s["p22"])
        q11, q12, q22 = (rom(f"q{i}_lut", t, s["qc"], fm.width)
                         for i, t, fm in zip((11, 12, 22), p.q_tables, (f11, f12, f22)))
        htx2 = pl.reg("htx2", lambda x: rsr(x, tf + fv.frac - fr.frac), tx2)
        ha12 = pl.reg("ha12", lambda x: rsr(x, t2f + f12.frac - f11.frac), a12)
        ha22 = pl.reg("ha22", lambda x: rsr(x, tsf + f22.frac - f11.frac), a22)
        hb22 = pl.reg("hb22", lambda x: rsr(x, tf + f22.frac - f12.frac), b22)
        x1p_w = pl.reg("x1p_w", lambda a, b: a + b, s["x1"], htx2)
        s11a = pl.reg("s11a", lambda a, b: a + b, s["p11"], ha12)
        s11b = pl.reg("s11b", lambda a, b: a + b, ha22, q11)
        s12a = pl.reg("s12a", lambda a, b: a + b, s["p12"], hb22)
        pp11_w = pl.reg("pp11_w", lambda a, b: a + b, s11a, s11b)
        pp12_w = pl.reg("pp12_w", lambda a, b: a + b, s12a, q12)
        pp22_w = pl.reg("pp22_w", lambda a, b: a + b, s["p22"], q22)
        x1p, fl_x1p = sat_reg("x1p", x1p_w, fr)
        pp11, fl_pp11 = sat_reg("pp11", pp11_w, f11)
        pp12, fl_pp12 = sat_reg("pp12", pp12_w, f12)
        pp22, fl_pp22 = sat_reg("pp22", pp22_w, f22)

        # U1: gains, eq. (5), by a restoring divider (exact, rounded) instead of a 1/x LUT
        ssum = pl.reg("s_innov", lambda a: a + p.sr2_code, pp11)
        k1 = gain_divider(pl, "k1", pp11, ssum, 0, gw)
        k2 = gain_divider(pl, "k2", pp12, ssum, fk2 + f11.frac - f12.frac - gw, gw)

        # U2 / U3: updates, eqs. (6) and (7)
        r = pl.reg("resid", lambda y, x: y - x, s["y"], x1p)
        # Gain products in LUTs (shift and add): faster than an unregistered ECP5 DSP; or, with
        # multipliers="dsp", in Xilinx DSP48E1 blocks with their registers (same values, latency).
        # (1 - K1) P is formed as P - K1 P, so every product has the 8-bit gain as selector.
        multiply = dsp_multiply if p.multipliers == "dsp" else shift_add_multiply
        m_k1r = multiply(pl, "m_k1r", k1, r)
        m_k2r = multiply(pl, "m_k2r", k2, r)
        m_k2p = multiply(pl, "m_k2p", k2, pp12)
        m_k1p11 = multiply(pl, "m_k1p11", k1, pp11)
        m_k1p12 = multiply(pl, "m_k1p12", k1, pp12)
        m_p11 = pl.reg("m_p11", lambda x, k: (x << gw) - k, pp11, m_k1p11)
        m_p12 = pl.reg("m_p12", lambda x, k: (x << gw) - k, pp12, m_k1p12)
        h_k1r = pl.reg("h_k1r", lambda x: rsr(x, gw), m_k1r)
        h_k2r = pl.reg("h_k2r", lambda x: rsr(x, fk2 + fr.frac - fv.frac), m_k2r)
        h_k2p = pl.reg("h_k2p", lambda x: rsr(x, fk2 + f12.frac - f22.frac), m_k2p)
        x1_w = pl.reg("x1_w", lambda a, b: a + b, x1p, h_k1r)
        x2_w = pl.reg("x2_w", lambda a, b: a + b, s["x2"], h_k2r)
        p22_w = pl.reg("p22_w", lambda a, b: a - b, pp22, h_k2p)
        p11_w = pl.reg("p11_w", lambda x: rsr(x, gw), m_p11)
        p12_w = pl.reg("p12_w", lambda x: rsr(x, gw), m_p12)
        x1n, fl_x1 = sat_reg("x1n", x1_w, fr)
        x2n, fl_x2 = sat_reg("x2n", x2_w, fv)
        p11n, fl_p11 = sat_reg("p11n", p11_w, f11)
        p12n, fl_p12 = sat_reg("p12n", p12_w, f12)
        p22n, fl_p22 = sat_reg("p22n", p22_w, f22)

        # U4: manoeuvre detector, eqs. (8)-(10)
        idx = pl.comb("rsq_idx", lambda x: x[p.data_width - RSQRT_INDEX_BITS:], pp11)
        rsq = rom("rsqrt_lut", p.rsqrt_table, idx, RSQRT_WIDTH)
        m_zn = multiply(pl, "m_zn", rsq, r)
        h_zn = pl.reg("h_zn", lambda x: rsr(x, fr.frac + p.rsqrt_frac - fz.frac), m_zn)
        zn = sat_reg("zn", h_zn, fz, flagged=False)  # z saturating is harmless: not flagged
        a = p.alpha_code
        za_ = pl.reg("zf_a", lambda x: x * a, zn)
        zb_ = pl.reg("zf_b", lambda x: x * ((1 << ALPHA_FRAC) - a), s["zf"])
        zsum = pl.reg("zf_sum", lambda u, v: u + v, za_, zb_)
        zfh = pl.reg("zf_h", lambda x: rsr(x, ALPHA_FRAC), zsum)
        zf = sat_reg("zf", zfh, fz, flagged=False)
        zabs = pl.reg("zabs", lambda x: abs(x), zf)
        manoeuvre = pl.reg("manoeuvre", lambda x: x > p.z1_code, zabs)
        # U5: q variation, the straight line of Figure 2
        dz = pl.reg("dz", lambda x: x - p.z1_code, zabs)
        dpos = pl.reg("dpos", lambda d: Mux(d > 0, d, 0)[:fz.width], dz)
        m_dq = multiply(pl, "m_dq", dpos, Staged(C(p.q_slope), 0))
        h_dq = pl.reg("h_dq", lambda x: rsr(x, QSLOPE_SHIFT), m_dq)
        qn = pl.reg("qn", lambda d, h: Mux(d <= 0, 0, Mux(h > p.q_max, p.q_max, h)),
                    dz, h_dq, shape=unsigned(p.q_width))

        # U0: initial values, eqs. (17) and (18)
        dy = pl.reg("dy", lambda y, x: y - x, s["y"], s["x1"])
        m_v0 = pl.reg("m_v0", lambda d: d * im, dy)
        h_v0 = pl.reg("h_v0", lambda x: rsr(x, fr.frac + inf_ - fv.frac), m_v0)
        v0, fl_v0 = sat_reg("v0", h_v0, fv)

        # Select by phase and register: the write-back stage
        flag = pl.comb("flag_any", lambda *f: Cat(*f).any(),
                       fl_x1p, fl_pp11, fl_pp12, fl_pp22, fl_x1, fl_x2, fl_p11, fl_p12, fl_p22)
        pi11, pi12, pi22 = p.p_init_codes

        def pick(name, first, init, track, shape):
            return pl.reg(name, lambda ph, a_, b_, c_: Mux(ph == PHASE_FIRST, a_, Mux(ph == PHASE_INIT, b_, c_)),
                          phase, first, init, track, shape=shape)

        def const(v, shape):
            return Staged(C(v, shape), 0)

        lay = state_layout(p)
        new = {
            "x1": pick("new_x1", s["y"], s["y"], x1n, lay["x1"].shape),
            "x2": pick("new_x2", const(0, lay["x2"].shape), v0, x2n, lay["x2"].shape),
            "p11": pick("new_p11", const(0, lay["p11"].shape), const(pi11, lay["p11"].shape), p11n, lay["p11"].shape),
            "p12": pick("new_p12", const(0, lay["p12"].shape), const(pi12, lay["p12"].shape), p12n, lay["p12"].shape),
            "p22": pick("new_p22", const(0, lay["p22"].shape), const(pi22, lay["p22"].shape), p22n, lay["p22"].shape),
            "zf": pick("new_zf", const(0, lay["zf"].shape), const(0, lay["zf"].shape), zf, lay["zf"].shape),
            "qc": pick("new_qc", const(0, lay["qc"].shape), const(0, lay["qc"].shape), qn, lay["qc"].shape),
            "phase": pick("new_phase", const(PHASE_INIT, 2), const(PHASE_TRACK, 2), const(PHASE_TRACK, 2), 2),
        }
        zero_g = const(0, unsigned(gw))
        out = {
            "k1": pick("out_k1", zero_g, zero_g, k1, unsigned(gw)),
            "k2": pick("out_k2", zero_g, zero_g, k2, unsigned(gw)),
            "q": pick("out_q", const(0, p.q_width), const(0, p.q_width), s["qc"], unsigned(p.q_width)),
            "phase": pl.reg("out_phase", lambda x: x, phase),
            "manoeuvre": pick("out_man", const(0, 1), const(0, 1), manoeuvre, 1),
            "saturated": pick("out_sat", const(0, 1), fl_v0, flag, 1),
        }
        stage = max(v.stage for v in [*new.values(), *out.values()])
        new = {k: pl.at(v, stage) for k, v in new.items()}
        out = {k: pl.at(v, stage) for k, v in out.items()}
        return stage, new, out, pl

    # ------------------------------------------------------------------ top level
    def elaborate(self, platform):
        return self._build()

    def _build(self) -> Module:
        if self._module is None:
            self._module = self._top()
        return self._module

    def _top(self) -> Module:
        p = self._p
        m = Module()
        lay = state_layout(p)
        depth = 1 << p.tid_width

        state = memory.Memory(shape=lay, depth=depth, init=[])
        m.submodules.state = state
        wr = state.write_port()
        rd = state.read_port(transparent_for=(wr,))  # read latency 1; sees the same-cycle write

        # U6: control. Reset sweep clears every track's phase, then measurements flow.
        sweeping = Signal(init=1)
        sweep_addr = Signal(p.tid_width)

        room = Signal(init=1)  # registered ``credits < fifo_depth``

        # Stage 0 (handshake) to stage 1 (state read data)
        v1 = Signal()
        tid1 = Signal(p.tid_width, reset_less=True)
        y1 = Signal(fmt_shape(p.range_fmt), reset_less=True)
        restart1 = Signal(reset_less=True)
        accept = Signal()
        stage1 = {"y": Staged(y1, 1), "restart": Staged(restart1, 1)}
        for name, field in lay:
            word = Signal(field.shape, name=f"st_{name}")
            m.d.comb += word.eq(getattr(rd.data, name))
            stage1[name] = Staged(word, 1)
        write_stage, new, out, pl = self._datapath(m, stage1)
        self._write_stage = write_stage
        fifo_depth = write_stage + 3
        out_bits = p.port_width("m_axis_tdata") + p.tid_width + p.port_width("m_axis_tuser")
        m.submodules.ofifo = ofifo = fifo.SyncFIFOBuffered(width=out_bits, depth=fifo_depth)
        credits = Signal(range(fifo_depth + 1))
        valid = Staged(v1, 1)
        tid = Staged(tid1, 1)
        # Hazard: the measurement's track is still in flight (accepted, not yet written back).
        hazard = Signal()
        wv, wtid = pl.at(valid, write_stage), pl.at(tid, write_stage)
        if depth <= BUSY_BITMAP_MAX:
            # a busy bit per track: one multiplexer on the ready path
            busy = Signal(depth)
            for t in range(depth):
                with m.If(accept & (self.s_axis_tid == t)):
                    m.d.sync += busy[t].eq(1)
                with m.Elif(wv & (wtid == t)):
                    m.d.sync += busy[t].eq(0)
            # the write-back of this very cycle is seen through the transparent read port
            m.d.comb += hazard.eq(busy.bit_select(self.s_axis_tid, 1) & ~(wv & (wtid == self.s_axis_tid)))
        else:
            # many tracks: compare with the track of every stage still before write-back
            tids = [(pl.at(valid, k), pl.at(tid, k)) for k in range(1, write_stage)]
            m.d.comb += hazard.eq(Cat(*(vk & (tk == self.s_axis_tid) for vk, tk in tids)).any())
        m.d.comb += [
            self.s_axis_tready.eq(~sweeping & room & ~hazard),
            accept.eq(self.s_axis_tvalid & self.s_axis_tready),
            rd.addr.eq(self.s_axis_tid),
        ]
        m.d.sync += [
            v1.eq(accept),
            tid1.eq(self.s_axis_tid),
            y1.eq(self.s_axis_tdata),
            restart1.eq(self.s_axis_tuser),
        ]

        with m.If(sweeping):
            m.d.comb += [wr.addr.eq(sweep_addr), wr.en.eq(1), wr.data.eq(0)]
            m.d.sync += sweep_addr.eq(sweep_addr + 1)
            with m.If(sweep_addr == depth - 1):
                m.d.sync += sweeping.eq(0)
        with m.Else():
            m.d.comb += [wr.addr.eq(wtid), wr.en.eq(wv)]
            m.d.comb += [getattr(wr.data, k).eq(v) for k, v in new.items()]

        # Results into the FIFO; the credit counter guarantees it has room.
        tdata = Cat(new["x1"], new["x2"], out["k1"], out["k2"], out["q"])
        tuser = Cat(out["phase"], out["manoeuvre"], out["saturated"])
        m.d.comb += [
            ofifo.w_data.eq(Cat(tdata, wtid, tuser)),
            ofifo.w_en.eq(wv),
            self.m_axis_tvalid.eq(ofifo.r_rdy),
            Cat(self.m_axis_tdata, self.m_axis_tid, self.m_axis_tuser).eq(ofifo.r_data),
            ofifo.r_en.eq(self.m_axis_tready),
        ]
        # Every candidate next value comes from registers alone; the handshakes (late
        # signals from the ports) only select among them.
        popped = self.m_axis_tvalid & self.m_axis_tready
        up, down = accept & ~popped, ~accept & popped
        m.d.sync += [
            credits.eq(Mux(up, credits + 1, Mux(down, credits - 1, credits))),
            room.eq(Mux(up, credits < fifo_depth - 1, Mux(down, 1, credits < fifo_depth))),
        ]
        return m
