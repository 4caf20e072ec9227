"""The runtime owns time and the loop: world, radio medium and brains, stepped together in one
process, or a world process and one process per robot.

Owns: assembling a team and stepping it. Must not know: scenario success criteria, plots.
Importing this package does not import MuJoCo: SimRuntime and TrajectorySample load on first use.
"""

from rescuemesh.runtime.config import RadioKind, SimConfig

__all__ = ["RadioKind", "SimConfig", "SimRuntime", "TrajectorySample"]


def __getattr__(name: str):
    if name in ("SimRuntime", "TrajectorySample"):
        from rescuemesh.runtime.inprocess import sim_loop

        return getattr(sim_loop, name)
    raise AttributeError(f"module 'rescuemesh.runtime' has no attribute {name!r}")
