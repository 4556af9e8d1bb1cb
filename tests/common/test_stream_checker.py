"""The stream protocol checker fails a source that breaks the AXI4-Stream handshake rules.

A hand-written source (a few flops) runs under Verilator with random backpressure; it is
correct unless its ``fault`` input makes it change one payload signal, or drop valid, while
valid waits for ready. X and Z, which Verilator (two-state) never shows, are checked on
stand-in handles.
"""

import pytest
from cocotb.types import Logic, LogicArray

from kfgen.sim.streams import StreamChecker, StreamProtocolError
from kfgen.sim.verilator import build, run_test

from stream_checker_tb import FAULTS

SOURCE = """\
// A counting AXI4-Stream source: one idle cycle after every odd word. fault = 0 is correct;
// 1..4 break a rule while valid waits for ready: change tdata, tid or tuser, or drop tvalid.
module stream_source (
  input  wire       clk,
  input  wire       rst,
  input  wire [2:0] fault,
  output reg        m_axis_tvalid,
  input  wire       m_axis_tready,
  output reg  [7:0] m_axis_tdata,
  output reg  [1:0] m_axis_tid,
  output reg        m_axis_tuser
);
  wire stalled = m_axis_tvalid & ~m_axis_tready;
  always @(posedge clk) begin
    if (rst) begin
      m_axis_tvalid <= 1'b0;
      m_axis_tdata <= 8'd0;
      m_axis_tid <= 2'd0;
      m_axis_tuser <= 1'b0;
    end else if (stalled) begin
      if (fault == 3'd1) m_axis_tdata <= m_axis_tdata + 8'd1;
      if (fault == 3'd2) m_axis_tid <= m_axis_tid + 2'd1;
      if (fault == 3'd3) m_axis_tuser <= ~m_axis_tuser;
      if (fault == 3'd4) m_axis_tvalid <= 1'b0;
    end else if (m_axis_tvalid) begin
      m_axis_tvalid <= ~m_axis_tdata[0];
      m_axis_tdata <= m_axis_tdata + 8'd1;
      m_axis_tid <= m_axis_tid + 2'd1;
      m_axis_tuser <= m_axis_tdata[1];
    end else begin
      m_axis_tvalid <= 1'b1;
    end
  end
endmodule
"""


@pytest.fixture(scope="module")
def source(build_root):
    build_dir = build_root / "stream_checker"
    build_dir.mkdir(parents=True, exist_ok=True)
    src = build_dir / "stream_source.v"
    src.write_text(SOURCE)
    return build([src], "stream_source", build_dir / "cache"), build_dir


def run(source, fault):
    model, run_dir = source
    run_test(model, "stream_checker_tb", run_dir, f"fault_{fault}",
             {"KFGEN_TB_FAULT": fault})


@pytest.mark.xdist_group("stream_checker")
def test_correct_source_passes(source):
    run(source, "none")


@pytest.mark.parametrize("fault, message", [
    ("tdata", "payload changed while valid waited for ready: tdata"),
    ("tid", "payload changed while valid waited for ready: tid"),
    ("tuser", "payload changed while valid waited for ready: tuser"),
    ("tvalid", "valid fell before the transfer"),
])
@pytest.mark.xdist_group("stream_checker")
def test_broken_source_fails(source, fault, message):
    assert fault in FAULTS
    with pytest.raises(AssertionError, match="StreamProtocolError: m_axis, cycle [0-9]+: " + message):
        run(source, fault)


class _Handle:
    def __init__(self, value):
        self.value = value


@pytest.mark.parametrize("level", ["X", "Z"])
def test_unknown_valid_fails(level):
    checker = StreamChecker("m_axis", _Handle(Logic(level)), _Handle(Logic("0")),
                            {"tdata": _Handle(LogicArray("0101"))})
    with pytest.raises(StreamProtocolError, match=f"m_axis, cycle 7: valid is {level} after reset"):
        checker.sample(7)


def test_unknown_payload_must_hold_too():
    data = _Handle(LogicArray("01X1"))
    checker = StreamChecker("m_axis", _Handle(Logic("1")), _Handle(Logic("0")), {"tdata": data})
    checker.sample(1)
    checker.sample(2)  # X held as X is stable
    data.value = LogicArray("0101")
    with pytest.raises(StreamProtocolError, match="tdata 01X1 -> 0x5"):
        checker.sample(3)
