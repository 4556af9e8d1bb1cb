"""What every core on the engine (the UKF, the IMM) shares to simulate: the cocotb harness
(:mod:`.tb`), the Verilator build and run of a generated core (:mod:`.run`), the golden side
of the core's prologue (:mod:`.prologue`), the bounded waits (:mod:`.watchdog`) and the fault
campaigns on the bus (:mod:`.campaign`), the generated C driver's hooks (:mod:`.mmio`), and for
the generated Python driver a golden MMIO device (:mod:`.device`) and its run on the Verilated
core (:mod:`.driver_tb`); a session on that device recorded as the script the shipped Verilog
testbench replays (:mod:`.script`)."""
