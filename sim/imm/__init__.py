"""Software side of the IMM core (Hackett et al., seed 004): :mod:`.reference` is the float64
reference of one IMM iteration, :mod:`.scenario` the satellite-link example, :mod:`.plots` its
figures."""
