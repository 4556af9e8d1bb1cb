"""The linear Kalman filter core's models: a float64 reference (filterpy-style pure functions),
the steady-state gain, and the bit-exact golden model over a run."""
