"""The linear Kalman filter core's models: a float64 reference (filterpy-style pure functions),
the steady-state gain, the bit-exact golden model over a run, and the core's cocotb testbench
(:mod:`.tb`)."""
