"""IEEE-754 floating-point units, parameterised by format (:mod:`.format`).

One unit per file (``add``, ``mul``, ``fma``, ``div``, ``sqrt``, ``i2f``, ``f2i``), each a raw
operation followed by the shared rounding stage in :mod:`.round`. Semantics: round to nearest,
ties to even; signed zeros, infinities, gradual underflow with tininess detected after rounding;
the canonical quiet NaN for every NaN result; 5 flags in RISC-V ``fflags`` order. The exact
reference model is :mod:`kfgen.sim.float_ref`.
"""
