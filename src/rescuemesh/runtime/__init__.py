"""The runtime owns simulated time and the loop: world, radio link and brains, stepped together.

Owns: assembling a simulated team and stepping it. Must not know: scenario success criteria, plots.
"""

from rescuemesh.runtime.sim_loop import SimConfig, SimRuntime, TrajectorySample

__all__ = ["SimConfig", "SimRuntime", "TrajectorySample"]
