"""trajectory.png: a top-down map with each robot's path, like the paper's Fig. 3 and 5.

Owns: the matplotlib figure (Agg, no screen). Must not know: how the run was scripted.
Shows walls (the occupancy grid), doorways, region names, each robot's path with start (circle),
end (square) and direction arrows, the leader's goal (star) and a MoveAround circle (dashed).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402

COLOURS = {"robot_1": "#1f77b4", "robot_2": "#d62728", "robot_3": "#2ca02c"}
ARROW_EVERY_M = 1.0


def plot_trajectories(rt, map_model, path: Path, *, title: str = "", metrics: dict | None = None) -> Path:
    grid = map_model.grid
    rows, cols = grid.shape
    extent = (grid.origin_x, grid.origin_x + cols * grid.resolution,
              grid.origin_y, grid.origin_y + rows * grid.resolution)
    width = extent[1] - extent[0]
    height = extent[3] - extent[2]
    fig, ax = plt.subplots(figsize=(min(16, 2 + 0.75 * width), min(12, 1.5 + 0.75 * height)), dpi=110)
    ax.imshow(np.where(grid.occupied, 0.15, 1.0), cmap="gray", vmin=0, vmax=1, origin="lower",
              extent=extent, interpolation="nearest")
    for name, rect in map_model.regions.items():
        cx, cy = rect.center
        ax.text(cx, cy, name, color="0.55", fontsize=8, ha="center", va="center", style="italic", zorder=1)
    for door in map_model.doorways:
        ax.add_patch(Rectangle((door.x_min, door.y_min), door.x_max - door.x_min, door.y_max - door.y_min,
                               facecolor="#ffd54f", edgecolor="#b28704", alpha=0.7, lw=0.8, zorder=2))
    metrics = metrics or {}
    if "goal" in metrics and metrics["goal"]:
        gx, gy = metrics["goal"]
        ax.plot(gx, gy, marker="*", ms=16, color="gold", mec="k", zorder=6, ls="none", label="leader goal")
    if metrics.get("stop_position"):
        sx, sy = metrics["stop_position"]
        ax.plot(sx, sy, marker="X", ms=12, color="k", mfc="#ff7f0e", ls="none", zorder=7,
                label=f"Stop arrived (t = {metrics.get('stop_arrived_s')} s)")
    if metrics.get("center") and metrics.get("radius_m"):
        cx, cy = metrics["center"]
        ax.add_patch(Circle((cx, cy), metrics["radius_m"], fill=False, ls="--", lw=1.2, ec="0.3", zorder=3,
                            label=f"MoveAround r = {metrics['radius_m']} m"))
        visited = [w for w in metrics.get("waypoints", []) if not w["skipped"]]
        if visited:
            ax.plot([w["x"] for w in visited], [w["y"] for w in visited], "D", ms=4, color="0.25", zorder=3.5,
                    ls="none", label=f"waypoints ({len({w['index'] for w in visited})})")
        skipped = [w["index"] for w in metrics.get("waypoints", []) if w["skipped"]]
        if skipped:
            ax.plot([], [], ls="none", label=f"skipped (in obstacles): {', '.join(map(str, skipped))}")
    for index, (name, samples) in enumerate(rt.trajectories.items()):
        colour = COLOURS.get(name, None)
        xy = np.array([[s.pose.x, s.pose.y] for s in samples])
        width = max(1.2, 3.4 - 1.1 * index)  # later robots drawn thinner on top: a follower's path stays visible
        line, = ax.plot(xy[:, 0], xy[:, 1], "-", lw=width, color=colour, label=name, zorder=4 + 0.1 * index)
        colour = line.get_color()
        ax.plot(*xy[0], "o", ms=9, mfc="white", mec=colour, mew=2, zorder=5)
        ax.plot(*xy[-1], "s", ms=8, color=colour, zorder=5)
        _arrows(ax, xy, colour)
    ax.plot([], [], "o", mfc="white", mec="k", ls="none", label="start")
    ax.plot([], [], "s", color="k", ls="none", label="end")
    if map_model.doorways:
        ax.add_patch(Rectangle((0, 0), 0, 0, facecolor="#ffd54f", edgecolor="#b28704", label="doorway"))
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (frame map)")
    ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize=11)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    ax.grid(True, lw=0.3, alpha=0.4)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def _arrows(ax, xy: np.ndarray, colour) -> None:
    """Direction arrows along a path, one every ARROW_EVERY_M metres travelled."""
    if len(xy) < 2:
        return
    steps = np.hypot(*np.diff(xy, axis=0).T)
    travelled = np.concatenate([[0.0], np.cumsum(steps)])
    for mark in np.arange(ARROW_EVERY_M, travelled[-1], ARROW_EVERY_M):
        i = int(np.searchsorted(travelled, mark))
        j = min(i + 1, len(xy) - 1)
        while j < len(xy) - 1 and np.hypot(*(xy[j] - xy[i])) < 0.05:
            j += 1
        if np.hypot(*(xy[j] - xy[i])) < 1e-3:
            continue
        ax.annotate("", xy=xy[j], xytext=xy[i], zorder=5,
                    arrowprops=dict(arrowstyle="-|>", color=colour, lw=1.2, mutation_scale=14))
