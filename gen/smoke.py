"""The self-checking testbench shipped with a core (``TOP_tb.v``, FuseSoC's ``sim`` targets).

A core's descriptor says what to check (``CoreDescriptor.smoke``: ``(params, manifest) ->``
a plan, plain data); this module writes the plan as plain Verilog-2005 that Icarus, Verilator
(``--binary --timing``) and a vendor simulator run without anything else: no cocotb, no
Python. Two kinds of plan:

``{"kind": "stream", "inputs": {...}, "outputs": {...}, "about": "..."}``
    Each side names its handshake (``valid``, and ``ready`` or ``None``) and its data
    ``ports``, with ``words``: one list of port values per transfer. The testbench offers the
    inputs in order (``valid`` held until ``ready``), keeps the output ready, and compares
    every output transfer, in order, with the expected words: vectors from the golden model.
``{"kind": "axi_script", "ops": [...], "status": offset, "done_bit": lsb, "about": "..."}``
    A session on ``s_axi`` recorded on the golden model (:mod:`kfgen.sim.engine.script`:
    ``(op, address, data, argument, note)``). The operations go to ``TOP_vectors.hex``
    (:func:`vectors`, read with ``$readmemh``; ``+vectors=FILE`` names another), and the
    testbench is a small AXI4 task library and an interpreter of them, the same text for any
    number of iterations: single-beat writes (OKAY), reads compared with the golden model's
    word (OKAY, last), starts of a step waited for on ``irq`` (or by polling STATUS when the
    core has no ``irq``) and their cycles printed and checked against the manifest's, and the
    cycles of each iteration printed.

Inputs the plan does not drive are held at zero, the outputs' ready inputs at one. The
testbench prints ``PASS: ...`` and finishes, or prints ``FAIL: ...`` and stops with
``$fatal`` (a nonzero exit status from ``vvp`` and a Verilated model), also on a timeout.
"""

from __future__ import annotations

from kfgen.sim.engine.script import END, ITERATION, READ, START, WRITE

__all__ = ["testbench", "vectors", "vectors_name"]

#: Cycles the testbench waits for a transfer before it calls the run hung.
_PATIENCE = 20_000

#: A polled step (no ``irq``) may be seen done this many cycles after the manifest's count at
#: most: the STATUS read that sees it (a few cycles) and the one before it.
_POLL_SLACK = 64


def vectors_name(top: str) -> str:
    """The vectors file of an ``axi_script`` plan's testbench."""
    return f"{top}_vectors.hex"


def _lit(width: int, value: int) -> str:
    return f"{width}'h{value & ((1 << width) - 1):x}"


def _decl(ports: dict, name: str) -> str:
    width = ports[name]
    return f"[{width - 1}:0] {name}" if width > 1 else name


def testbench(top: str, manifest: dict, plan: dict, header_lines: list[str]) -> str:
    """The Verilog text of ``TOP_tb`` running ``plan`` against ``top``."""
    ports = {p["name"]: p["width"] for p in manifest["ports"]}
    inputs = [p["name"] for p in manifest["ports"] if p["direction"] == "input" and p["name"] not in ("clk", "rst")]
    outputs = [p["name"] for p in manifest["ports"] if p["direction"] == "output"]
    lines = [f"// {line}".rstrip() for line in header_lines]
    lines += [
        "//",
        f"// Self-checking testbench of {top}: {plan['about']}.",
        "// Prints PASS and finishes, or prints FAIL and stops with $fatal (nonzero exit).",
        "",
        "`timescale 1ns / 1ps",
        "",
        f"module {top}_tb;",
        "  reg clk = 1'b0;",
        "  reg rst = 1'b1;",
        "  always #5 clk = ~clk;",
        "",
    ]
    ready = ({plan["outputs"]["ready"]} if plan["kind"] == "stream" else {"s_axi_rready", "s_axi_bready"}) - {None}
    if plan["kind"] == "axi_script":  # a --streams core's output stream, ready and unused
        ready |= {n for n in inputs if n == "m_axis_tready"}
    lines += [f"  reg {_decl(ports, n)} = {_lit(ports[n], int(n in ready))};" for n in inputs]
    lines += [f"  wire {_decl(ports, n)};" for n in outputs]
    lines += ["", f"  {top} dut (", "    .clk(clk),", "    .rst(rst),"]
    lines += [f"    .{n}({n})," for n in inputs + outputs]
    lines[-1] = lines[-1].rstrip(",")
    lines += ["  );", "", "  integer cycle = 0;", "  always @(posedge clk) cycle <= cycle + 1;", ""]
    body = _stream(top, ports, plan) if plan["kind"] == "stream" else _axi_script(top, ports, plan)
    return "\n".join(lines + body + ["endmodule", ""])


def _stream(top: str, ports: dict, plan: dict) -> list[str]:
    src, dst = plan["inputs"], plan["outputs"]
    n_in, n_out = len(src["words"]), len(dst["words"])
    in_width = sum(ports[p] for p in src["ports"])
    out_width = sum(ports[p] for p in dst["ports"])
    in_cat = "{" + ", ".join(src["ports"]) + "}"
    out_cat = "{" + ", ".join(dst["ports"]) + "}"

    def packed(names, words):
        value, width = 0, 0
        for name, word in reversed(list(zip(names, words))):  # concatenation: the first port on top
            value |= (word & ((1 << ports[name]) - 1)) << width
            width += ports[name]
        return value

    in_ready = src["ready"] or "1'b1"
    lines = [
        f"  // {n_in} input transfer(s) on {src['valid']}, {n_out} expected on {dst['valid']}",
        f"  reg [{in_width - 1}:0] stimulus [0:{n_in - 1}];",
        f"  reg [{out_width - 1}:0] expected [0:{n_out - 1}];",
        "  initial begin",
    ]
    lines += [f"    stimulus[{i}] = {_lit(in_width, packed(src['ports'], w))};" for i, w in enumerate(src["words"])]
    lines += [f"    expected[{i}] = {_lit(out_width, packed(dst['ports'], w))};" for i, w in enumerate(dst["words"])]
    lines += [
        "  end",
        "",
        "  integer sent = 0, got = 0, idle = 0;",
        "  reg done = 1'b0;",
        "  initial begin",
        "    repeat (4) @(posedge clk);",
        "    rst <= 1'b0;",
        "  end",
        "",
        "  // Inputs: the standard register stage; valid is never withdrawn before ready.",
        "  always @(posedge clk) begin",
        "    if (!rst) begin",
        f"      if (!{src['valid']} || {in_ready}) begin",
        f"        if (sent < {n_in}) begin",
        f"          {src['valid']} <= 1'b1;",
        f"          {in_cat} <= stimulus[sent];",
        "          sent <= sent + 1;",
        "        end else begin",
        f"          {src['valid']} <= 1'b0;",
        "        end",
        "      end",
        "    end",
        "  end",
        "",
    ]
    lines += [
        "  // Outputs: every transfer, in order, against the golden model's words.",
        "  always @(posedge clk) begin",
        "    if (!rst) begin",
        "      idle <= idle + 1;",
        f"      if ({dst['valid']}" + (f" && {dst['ready']}" if dst["ready"] else "") + ") begin",
        "        idle <= 0;",
        f"        if (got >= {n_out}) begin",
        f"          $display(\"FAIL: {top}: output transfer %0d beyond the {n_out} expected: %h\", got, {out_cat});",
        "          $fatal(1);",
        f"        end else if ({out_cat} !== expected[got]) begin",
        f"          $display(\"FAIL: {top}: output transfer %0d is %h, the golden model's is %h\",",
        f"                   got, {out_cat}, expected[got]);",
        "          $fatal(1);",
        "        end",
        "        got <= got + 1;",
        "      end",
        f"      if (idle > {_PATIENCE}) begin",
        f"        $display(\"FAIL: {top}: timeout after %0d cycles, %0d of {n_out} outputs\", cycle, got);",
        "        $fatal(1);",
        "      end",
        f"      if (got == {n_out} && !done) begin",
        "        done <= 1'b1;",
        "        // nothing more may come out",
        f"        repeat (64) @(posedge clk);",
        f"        if (got != {n_out}) begin",
        f"          $display(\"FAIL: {top}: %0d outputs, {n_out} expected\", got);",
        "          $fatal(1);",
        "        end",
        f"        $display(\"PASS: {top}: {n_out} output transfer(s) equal the golden model's ({plan['about']})\");",
        "        $finish;",
        "      end",
        "    end",
        "  end",
    ]
    return lines




def vectors(top: str, plan: dict, header_lines: list[str]) -> str:
    """The text of ``TOP_vectors.hex`` of an ``axi_script`` plan: one operation a line, four
    hexadecimal words (operation, address, data, argument) and a comment saying what it is."""
    lines = [f"// {line}".rstrip() for line in header_lines]
    lines += [
        "//",
        f"// Vectors of {top}_tb.v ($readmemh): {plan['about']}.",
        "// One operation a line: op address data argument (hexadecimal), then what it is.",
        f"//   {WRITE:x} write data at address (single beat, OKAY expected)",
        f"//   {READ:x} read at address: OKAY, the golden model's data expected",
        f"//   {START:x} write data (CTRL.start) at address, wait for the step: argument = the manifest's "
        "cycles (0: none guaranteed)",
        f"//   {ITERATION:x} end of iteration <argument>: print its cycles",
        f"//   {END:x} end: data = the number of operations before it",
    ]
    lines += [f"{op:x} {address:08x} {data:08x} {arg:08x} // {k}: {note}"
              for k, (op, address, data, arg, note) in enumerate(plan["ops"])]
    return "\n".join(lines) + "\n"


def _axi_script(top: str, ports: dict, plan: dict) -> list[str]:
    aw = ports["s_axi_awaddr"]
    if ports["s_axi_wdata"] != 32:
        raise ValueError("an axi_script plan drives a 32-bit AXI4 slave")
    has_irq = "irq" in ports
    words = 4 * len(plan["ops"])
    fail = f'$display("FAIL: {top}: '
    lines = [
        f"  // The operations of {vectors_name(top)} (or +vectors=FILE): four words each",
        f"  localparam WORDS = {words};",
        f"  localparam PATIENCE = {_PATIENCE};",
        f"  localparam [{aw - 1}:0] STATUS = {_lit(aw, plan['status'])};",
        f"  localparam DONE_BIT = {plan['done_bit']};",
        "  reg [31:0] vec [0:WORDS-1];",
        "  reg [8*256-1:0] vectors;",
        "",
        "  integer w_beat, r_beat, waited;",
        "  reg [31:0] got;",
        "  reg [1:0] resp;",
        "  reg last;",
        "",
        "  task fail_timeout(input [8*24-1:0] what);",
        "    begin",
        f"      {fail}no %0s within %0d cycles\", what, PATIENCE);",
        "      $fatal(1);",
        "    end",
        "  endtask",
        "",
        "  // The tasks drive the bus on the falling edge and sample the core's outputs 1 ns later:",
        "  // what they see is what the next rising edge takes (no race with the core's registers in",
        "  // any simulator). cycle then holds the number of that edge.",
        "",
        "  // One single-beat write; w_beat: the edge that took the W beat.",
        f"  task axi_write(input [{aw - 1}:0] address, input [31:0] data);",
        "    reg aw_done, w_done, aw_take, w_take;",
        "    begin",
        "      @(negedge clk);",
        "      s_axi_awaddr = address;",
        "      s_axi_awlen = 8'd0;",
        "      s_axi_awsize = 3'd2;",
        "      s_axi_awburst = 2'b01;",
        "      s_axi_awvalid = 1'b1;",
        "      s_axi_wdata = data;",
        "      s_axi_wstrb = 4'hf;",
        "      s_axi_wlast = 1'b1;",
        "      s_axi_wvalid = 1'b1;",
        "      aw_done = 1'b0;",
        "      w_done = 1'b0;",
        "      waited = 0;",
        "      while (!(aw_done && w_done)) begin",
        "        #1;",
        "        aw_take = s_axi_awvalid && s_axi_awready;",
        "        w_take = s_axi_wvalid && s_axi_wready;",
        "        if (w_take) w_beat = cycle;",
        "        @(negedge clk);",
        "        if (aw_take) begin aw_done = 1'b1; s_axi_awvalid = 1'b0; end",
        "        if (w_take) begin w_done = 1'b1; s_axi_wvalid = 1'b0; end",
        "        waited = waited + 1;",
        "        if (waited > PATIENCE) fail_timeout(\"AWREADY/WREADY\");",
        "      end",
        "      #1;",
        "      while (!s_axi_bvalid) begin",
        "        @(negedge clk);",
        "        #1;",
        "        waited = waited + 1;",
        "        if (waited > PATIENCE) fail_timeout(\"BVALID\");",
        "      end",
        "      resp = s_axi_bresp;",
        "    end",
        "  endtask",
        "",
        "  // One single-beat read into got, resp, last; r_beat: the edge that took the R beat.",
        f"  task axi_read(input [{aw - 1}:0] address);",
        "    begin",
        "      @(negedge clk);",
        "      s_axi_araddr = address;",
        "      s_axi_arlen = 8'd0;",
        "      s_axi_arsize = 3'd2;",
        "      s_axi_arburst = 2'b01;",
        "      s_axi_arvalid = 1'b1;",
        "      waited = 0;",
        "      #1;",
        "      while (!s_axi_arready) begin",
        "        @(negedge clk);",
        "        #1;",
        "        waited = waited + 1;",
        "        if (waited > PATIENCE) fail_timeout(\"ARREADY\");",
        "      end",
        "      @(negedge clk);",
        "      s_axi_arvalid = 1'b0;",
        "      #1;",
        "      while (!s_axi_rvalid) begin",
        "        @(negedge clk);",
        "        #1;",
        "        waited = waited + 1;",
        "        if (waited > PATIENCE) fail_timeout(\"RVALID\");",
        "      end",
        "      got = s_axi_rdata;",
        "      resp = s_axi_rresp;",
        "      last = s_axi_rlast;",
        "      r_beat = cycle;",
        "    end",
        "  endtask",
        "",
    ]
    if has_irq:
        lines += [
            "  // irq's rises, seen on the falling edge: cycle - 1 is the edge that raised it.",
            "  reg irq_q = 1'b0;",
            "  integer irq_rise = -1;",
            "  always @(negedge clk) begin",
            "    if (irq && !irq_q) irq_rise = cycle;",
            "    irq_q = irq;",
            "  end",
            "",
            "  // Start a step (the write of CTRL.start) and wait for irq: measured, its cycles (STATUS.done",
            "  // reads 1 after the edge `cycles` edges after the W beat's, and irq rises one edge later).",
            "  task start_and_wait(input [" + str(aw - 1) + ":0] address, input [31:0] data, input integer cycles,",
            "                      output integer measured);",
            "    integer limit;",
            "    begin",
            "      irq_rise = -1;",
            "      axi_write(address, data);",
            "      if (resp !== 2'b00) begin",
            f"        {fail}start %h at %h: BRESP %b\", data, address, resp);",
            "        $fatal(1);",
            "      end",
            "      limit = 2 * cycles + 1000;",
            "      waited = 0;",
            "      while (irq_rise < 0) begin",
            "        @(negedge clk);",
            "        waited = waited + 1;",
            "        if (waited > limit) begin",
            f"          {fail}no irq within %0d cycles of start %h\", limit, data);",
            "          $fatal(1);",
            "        end",
            "      end",
            "      measured = irq_rise - w_beat - 1;",
            "      if (cycles != 0 && measured != cycles) begin",
            f"        {fail}start %h took %0d cycles, the manifest's %0d\", data, measured, cycles);",
            "        $fatal(1);",
            "      end",
            "    end",
            "  endtask",
            "",
        ]
    else:
        lines += [
            "  // Start a step (the write of CTRL.start) and poll STATUS until done: measured, the",
            "  // cycles until the STATUS read that saw it; no irq, so the count is checked within",
            f"  // {_POLL_SLACK} cycles of the manifest's.",
            "  task start_and_wait(input [" + str(aw - 1) + ":0] address, input [31:0] data, input integer cycles,",
            "                      output integer measured);",
            "    integer limit, polled, t0;",
            "    begin",
            "      axi_write(address, data);",
            "      t0 = w_beat;",
            "      if (resp !== 2'b00) begin",
            f"        {fail}start %h at %h: BRESP %b\", data, address, resp);",
            "        $fatal(1);",
            "      end",
            "      limit = 2 * cycles + 1000;",
            "      got = 32'd0;",
            "      polled = 0;",
            "      while (!got[DONE_BIT]) begin",
            "        axi_read(STATUS);",
            "        polled = r_beat - t0;",
            "        if (polled > limit) begin",
            f"          {fail}STATUS.done not within %0d cycles of start %h\", limit, data);",
            "          $fatal(1);",
            "        end",
            "      end",
            "      measured = polled;",
            f"      if (cycles != 0 && (measured < cycles || measured > cycles + {_POLL_SLACK})) begin",
            f"        {fail}start %h: done seen %0d cycles after, the manifest's %0d\", data, measured, cycles);",
            "        $fatal(1);",
            "      end",
            "    end",
            "  endtask",
            "",
        ]
    lines += [
        "  // The interpreter.",
        "  integer pc, measured, iteration_cycles, starts, reads, writes;",
        "  reg finished = 1'b0;",
        "  reg [31:0] op, address, data, argument;",
        "  initial begin",
        f"    if (!$value$plusargs(\"vectors=%s\", vectors)) vectors = \"{vectors_name(top)}\";",
        "    $readmemh(vectors, vec);",
        "    repeat (4) @(negedge clk);",
        "    rst = 1'b0;",
        "    repeat (2) @(negedge clk);",
        "    iteration_cycles = 0;",
        "    starts = 0;",
        "    reads = 0;",
        "    writes = 0;",
        "    for (pc = 0; pc < WORDS / 4 && !finished; pc = pc + 1) begin",
        "      op = vec[4 * pc];",
        "      address = vec[4 * pc + 1];",
        "      data = vec[4 * pc + 2];",
        "      argument = vec[4 * pc + 3];",
        "      case (op)",
        f"        32'd{WRITE}: begin",
        f"          axi_write(address[{aw - 1}:0], data);",
        "          writes = writes + 1;",
        "          if (resp !== 2'b00) begin",
        f"            {fail}op %0d: write %h at %h: BRESP %b\", pc, data, address, resp);",
        "            $fatal(1);",
        "          end",
        "        end",
        f"        32'd{READ}: begin",
        f"          axi_read(address[{aw - 1}:0]);",
        "          reads = reads + 1;",
        "          if (got !== data || resp !== 2'b00 || last !== 1'b1) begin",
        f"            {fail}op %0d: read at %h: %h (RRESP %b RLAST %b), the golden model's %h\",",
        "                     pc, address, got, resp, last, data);",
        "            $fatal(1);",
        "          end",
        "        end",
        f"        32'd{START}: begin",
        f"          start_and_wait(address[{aw - 1}:0], data, argument, measured);",
        "          starts = starts + 1;",
        "          iteration_cycles = iteration_cycles + measured;",
        "          $display(\"op %0d, start %h: %0d cycles (the manifest's %0d)\", pc, data, measured, argument);",
        "        end",
        f"        32'd{ITERATION}: begin",
        "          $display(\"iteration %0d: %0d cycles\", argument, iteration_cycles);",
        "          iteration_cycles = 0;",
        "        end",
        f"        32'd{END}: begin",
        "          if (data != pc) begin",
        f"            {fail}the vectors end after %0d operations, their END says %0d\", pc, data);",
        "            $fatal(1);",
        "          end",
        f"          $display(\"PASS: {top}: %0d reads equal the golden model's, %0d writes, %0d starts in the "
        f"manifest's cycles ({plan['about']})\", reads, writes, starts);",
        "          finished = 1'b1;",
        "          $finish;",
        "        end",
        "        default: begin",
        f"          {fail}op %0d of %0s is %h: not an operation (a vectors file of another core?)\", pc, vectors, op);",
        "          $fatal(1);",
        "        end",
        "      endcase",
        "    end",
        "    if (!finished) begin",
        f"      {fail}no END in %0s\", vectors);",
        "      $fatal(1);",
        "    end",
        "  end",
    ]
    return lines
