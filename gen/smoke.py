"""The self-checking smoke testbench shipped with a core (``TOP_tb.v``, FuseSoC's ``sim`` target).

A core's descriptor says what to check (``CoreDescriptor.smoke``: ``(params, manifest) ->``
a plan, plain data); this module writes the plan as plain Verilog-2005 that Icarus (and any
vendor simulator) runs without anything else: no cocotb, no Python. Two kinds of plan:

``{"kind": "stream", "inputs": {...}, "outputs": {...}, "about": "..."}``
    Each side names its handshake (``valid``, and ``ready`` or ``None``) and its data
    ``ports``, with ``words``: one list of port values per transfer. The testbench offers the
    inputs in order (``valid`` held until ``ready``), keeps the output ready, and compares
    every output transfer, in order, with the expected words: vectors from the golden model.
``{"kind": "axi_read", "reads": [(address, value, what), ...], "about": "..."}``
    Single-beat AXI4 reads on ``s_axi`` (the ID register of a core with a register map),
    each compared with the value the manifest records.

The output's ready inputs are held at one, every other input at zero. The testbench prints ``PASS: ...`` and finishes, or prints
``FAIL: ...`` and stops with ``$fatal`` (a nonzero exit status from ``vvp``), also on a
timeout.
"""

from __future__ import annotations

__all__ = ["testbench", "id_register_reads"]

#: Cycles the testbench waits for a transfer before it calls the run hung.
_PATIENCE = 20_000


def id_register_reads(manifest: dict) -> dict:
    """An ``axi_read`` plan reading the ID register of a core with a register map: each bus
    word compared with the value the manifest's field resets give."""
    bus = manifest["bus"]
    reg = next(r for r in manifest["registers"] if r["name"] == "ID")
    value = sum(f["reset"] << f["lsb"] for f in reg["fields"])
    width = bus["data_width"]
    words = reg["width"] // width
    reads = [(reg["offset"] + i * width // 8, value >> (i * width) & ((1 << width) - 1), f"ID word {i}")
             for i in range(words)]
    return {"kind": "axi_read", "reads": reads,
            "about": "reads the ID register over AXI4 and checks it against the manifest"}


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
        f"// Smoke test of {top}: {plan['about']}.",
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
    lines += [f"  reg {_decl(ports, n)} = {_lit(ports[n], int(n in ready))};" for n in inputs]
    lines += [f"  wire {_decl(ports, n)};" for n in outputs]
    lines += ["", f"  {top} dut (", "    .clk(clk),", "    .rst(rst),"]
    lines += [f"    .{n}({n})," for n in inputs + outputs]
    lines[-1] = lines[-1].rstrip(",")
    lines += ["  );", "", "  integer cycle = 0;", "  always @(posedge clk) cycle <= cycle + 1;", ""]
    body = _stream(top, ports, plan) if plan["kind"] == "stream" else _axi_read(top, ports, plan)
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


def _axi_read(top: str, ports: dict, plan: dict) -> list[str]:
    reads = plan["reads"]
    aw, dw = ports["s_axi_araddr"], ports["s_axi_rdata"]
    size = (dw // 8).bit_length() - 1
    lines = [
        "  task read_check(input [" + str(aw - 1) + ":0] address, input [" + str(dw - 1)
        + ":0] value, input [8*16-1:0] what);",
        "    integer wait_cycles;",
        "    begin",
        "      @(posedge clk);",
        "      s_axi_araddr <= address;",
        "      s_axi_arlen <= 8'd0;",
        f"      s_axi_arsize <= 3'd{size};",
        "      s_axi_arburst <= 2'b01;",
        "      s_axi_arvalid <= 1'b1;",
        "      wait_cycles = 0;",
        "      @(posedge clk);",
        "      while (!s_axi_arready) begin",
        "        wait_cycles = wait_cycles + 1;",
        f"        if (wait_cycles > {_PATIENCE}) begin $display(\"FAIL: no ARREADY\"); $fatal(1); end",
        "        @(posedge clk);",
        "      end",
        "      s_axi_arvalid <= 1'b0;",
        "      while (!s_axi_rvalid) begin",
        "        wait_cycles = wait_cycles + 1;",
        f"        if (wait_cycles > {_PATIENCE}) begin $display(\"FAIL: no RVALID\"); $fatal(1); end",
        "        @(posedge clk);",
        "      end",
        "      if (s_axi_rresp !== 2'b00 || s_axi_rlast !== 1'b1 || s_axi_rdata !== value) begin",
        "        $display(\"FAIL: %0s at %h: RDATA %h RRESP %b RLAST %b, expected %h OKAY, last\",",
        "                 what, address, s_axi_rdata, s_axi_rresp, s_axi_rlast, value);",
        "        $fatal(1);",
        "      end",
        "      $display(\"ok: %0s at %h = %h\", what, address, s_axi_rdata);",
        "    end",
        "  endtask",
        "",
        "  initial begin",
        "    repeat (4) @(posedge clk);",
        "    rst <= 1'b0;",
        "    repeat (2) @(posedge clk);",
    ]
    lines += [f"    read_check({_lit(aw, a)}, {_lit(dw, v)}, \"{what}\");" for a, v, what in reads]
    lines += [f"    $display(\"PASS: {top}: {len(reads)} read(s) equal the manifest ({plan['about']})\");",
              "    $finish;", "  end"]
    return lines
