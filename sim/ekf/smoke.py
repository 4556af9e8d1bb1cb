"""The EKF core's smoke testbench (``TOP_tb.v``): the script of a session on the golden device
(:mod:`kfgen.sim.engine.script`) that the testbench replays on the RTL, every word read
compared with the golden model's."""

from __future__ import annotations

from kfgen.hdl.ekf.steps import programs
from kfgen.hdl.engine.app import load_app
from kfgen.sim.engine.script import Script

from .reference import measurements

__all__ = ["ITERATIONS", "smoke_plan"]

#: Filter iterations the testbench runs.
ITERATIONS = 2
#: The application's scenario seed.
SEED = 1


def smoke_plan(params, manifest: dict) -> dict:
    """The application's x0, P0, Q and R, then ``ITERATIONS`` iterations of its scenario
    (u where it has one, z, start), x and P read after each."""
    app = load_app(params.app)
    s = Script(manifest, params, programs)
    s.begin()
    for name, value in (("x", app.x0), ("P", app.P0), ("Q", app.Q), ("R", app.R)):
        s.put(name, value)
    us, zs = measurements(app, ITERATIONS, SEED)
    for it, (u, z) in enumerate(zip(us, zs)):
        if params.nu:
            s.put("u", u)
        s.put("z", z)
        s.step("iterate")
        s.get("x")
        s.get("P")
        s.end_iteration(it)
    return s.plan(f"{ITERATIONS} iterations of {type(app).__name__}'s scenario, x and P against the golden model")
