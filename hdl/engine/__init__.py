"""The engine-core layer: what every core on the linear-algebra engine shares above
:mod:`kfgen.hdl.linalg` (the AXI4 core and its back end, the register-map classes, the
shared parameter checks, the machine, the descriptor's docs, waivers and manifest block).
A core on the engine imports this and :mod:`kfgen.hdl.linalg`, never another core."""
