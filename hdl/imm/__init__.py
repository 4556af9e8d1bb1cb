"""The IMM filter core (Hackett et al.) on the linear-algebra engine."""
