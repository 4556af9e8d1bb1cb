"""The unscented Kalman filter core (Soh & Wu) on the linear-algebra engine: parameters, the
three step programs, its register and memory map."""
