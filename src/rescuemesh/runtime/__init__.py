"""The runtime owns simulated time and the loop: world, radio medium and brains, stepped together.

Owns: assembling a simulated team and stepping it. Must not know: scenario success criteria, plots.
"""

from rescuemesh.runtime.sim_loop import RadioKind, SimConfig, SimRuntime, TrajectorySample

__all__ = ["RadioKind", "SimConfig", "SimRuntime", "TrajectorySample"]
