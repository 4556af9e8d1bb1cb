"""Models of the UKF IP core (Soh & Wu, seed 000): :mod:`.reference` is the float64 reference."""
