"""Reports of a run: result.json and trajectory plots.

Owns: the result schema and matplotlib figures. Must not know: how the run was scripted.
"""

from rescuemesh.report.plots import plot_trajectories
from rescuemesh.report.result import build_result, write_result
from rescuemesh.report.timeline import plot_timeline

__all__ = ["build_result", "plot_timeline", "plot_trajectories", "write_result"]
