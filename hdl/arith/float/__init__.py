"""IEEE-754 floating-point units, parameterised by format (:mod:`.format`).

One unit per file (``add``, ``mul``, ``fma``, ``div``, ``sqrt``, ``i2f``, ``f2i``, ``exp``), each
a raw operation followed by the shared rounding stage in :mod:`.round`. Semantics: round to
nearest, ties to even; signed zeros, infinities, gradual underflow with tininess detected after
rounding; the canonical quiet NaN for every NaN result; 5 flags in RISC-V ``fflags`` order. The
exact reference model is :mod:`kfgen.sim.float_ref`; ``exp`` is faithfully rounded instead
(its numbers in :mod:`.exp_plan`), with a bit-exact golden model in
:mod:`kfgen.sim.fpu.exp_model` and an exact reference in :mod:`kfgen.sim.fpu.exp_exact`.
"""
