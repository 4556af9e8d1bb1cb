"""The unscented Kalman filter core (Soh & Wu): parameters and its register and memory map."""
