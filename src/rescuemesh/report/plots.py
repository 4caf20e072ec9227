"""trajectory.png: a top-down map with each robot's path, like the paper's Fig. 3 and 5.

Owns: the matplotlib figure (Agg, no screen). Must not know: how the run was scripted.
Shows walls (the occupancy grid), doorways, region names, each robot's path with start (circle),
end (square) and direction arrows, the leader's goal (star) and a MoveAround circle (dashed).
The view is cropped to the known part of the map and the paths (`view_extent`): a SLAM map padded
with unknown space shows its building, not the padding.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402
from rescuemesh.maps.model import Rect  # noqa: E402
from rescuemesh.maps.raster import rasterise_walls  # noqa: E402

COLOURS = {"robot_1": "#1f77b4", "robot_2": "#d62728", "robot_3": "#2ca02c"}
#: Further colours of a small team (matplotlib's tab10 without the three above).
_MORE_COLOURS = ("#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")
#: A team larger than this is drawn as a chain: colours run along a colour map in team order, and
#: the legend names every LEGEND_EVERY-th robot only.
SMALL_TEAM = 10
LEGEND_EVERY = 5


def robot_colours(names) -> dict[str, str]:
    """A colour per robot: fixed for robot_1..3, distinct for a team of up to SMALL_TEAM, and along
    the 'turbo' colour map in team order for a larger team (neighbours in a chain look alike)."""
    names = list(names)
    if len(names) <= SMALL_TEAM:
        spare = iter(_MORE_COLOURS)
        return {n: COLOURS[n] if n in COLOURS else next(spare) for n in names}
    cmap = matplotlib.colormaps["turbo"]
    return {n: matplotlib.colors.to_hex(cmap(0.05 + 0.9 * i / (len(names) - 1))) for i, n in enumerate(names)}


def legend_label(names, index: int) -> str | None:
    """The legend entry of the robot at `index`: every robot of a small team; the first, every
    LEGEND_EVERY-th and the last of a large one (matplotlib leaves a None label out)."""
    names = list(names)
    if len(names) <= SMALL_TEAM or index in (0, len(names) - 1) or (index + 1) % LEGEND_EVERY == 0:
        return names[index]
    return None
ARROW_EVERY_M = 1.0
#: Room shown around the known part of the map and the paths, in m.
VIEW_MARGIN_M = 1.0


def view_extent(map_model, trajectories, margin_m: float = VIEW_MARGIN_M,
                points=()) -> tuple[float, float, float, float]:
    """(x_min, x_max, y_min, y_max) in m to show: the bounding box of the map's free cells, its walls
    (occupied cells; unknown cells do not count), every robot's path (`trajectories`: name ->
    samples with a `.pose`) and `points` (x, y), grown by `margin_m` and clipped to the grid."""
    grid = map_model.grid
    rows, cols = grid.shape
    res = grid.resolution
    full = (grid.origin_x, grid.origin_x + cols * res, grid.origin_y, grid.origin_y + rows * res)
    xs: list[float] = []
    ys: list[float] = []
    free = ~np.asarray(grid.occupied, dtype=bool)
    free_rows, free_cols = np.flatnonzero(free.any(axis=1)), np.flatnonzero(free.any(axis=0))
    if free_rows.size:
        xs += [grid.origin_x + free_cols[0] * res, grid.origin_x + (free_cols[-1] + 1) * res]
        ys += [grid.origin_y + free_rows[0] * res, grid.origin_y + (free_rows[-1] + 1) * res]
    for wall in map_model.walls:
        xs += [wall.x_min, wall.x_max]
        ys += [wall.y_min, wall.y_max]
    for samples in trajectories.values():
        xs += [s.pose.x for s in samples]
        ys += [s.pose.y for s in samples]
    for x, y in points:
        xs.append(x)
        ys.append(y)
    if not xs:
        return full
    x0, x1 = max(full[0], min(xs) - margin_m), min(full[1], max(xs) + margin_m)
    y0, y1 = max(full[2], min(ys) - margin_m), min(full[3], max(ys) + margin_m)
    if x1 <= x0 or y1 <= y0:  # everything off the grid
        return full
    return (x0, x1, y0, y1)


#: Grey levels of the map in trajectory.png: walls dark, unknown space (blocked for planning, but
#: no wall) light grey as map_server viewers show it, free space white.
WALL_SHADE, UNKNOWN_SHADE, FREE_SHADE = 0.15, 0.72, 1.0


def map_shades(map_model) -> np.ndarray:
    """The grid as grey levels (row 0 the lowest y): WALL_SHADE where a wall box covers a blocked
    cell, UNKNOWN_SHADE where a cell is blocked without a wall (unknown space), FREE_SHADE elsewhere."""
    grid = map_model.grid
    rows, cols = grid.shape
    res = grid.resolution
    bounds = Rect(grid.origin_x, grid.origin_y, grid.origin_x + cols * res, grid.origin_y + rows * res)
    walls = rasterise_walls(map_model.walls, bounds, res).occupied[:rows, :cols]
    blocked = np.asarray(grid.occupied, dtype=bool)
    return np.where(blocked, np.where(walls, WALL_SHADE, UNKNOWN_SHADE), FREE_SHADE)


def plot_trajectories(rt, map_model, path: Path, *, title: str = "", metrics: dict | None = None,
                      goal_label: str = "goal") -> Path:
    """Draw trajectory.png. `metrics` may hold what to mark: `goal` (a star labelled `goal_label`:
    whose goal it is, e.g. "leader's goal" or "robot_2's Goto target"), `target` (a spot asked to be
    shown), `base` (where Return goes), `stop_position`, a MoveAround `center` and `radius_m`."""
    metrics = metrics or {}
    view = view_extent(map_model, rt.trajectories, VIEW_MARGIN_M, _metric_points(metrics))
    width = view[1] - view[0]
    height = view[3] - view[2]
    fig, ax = plt.subplots(figsize=(min(16, 3.5 + 0.75 * width), min(12, 1.5 + 0.75 * height)), dpi=110)
    image, shown = _display_map(map_model, view)
    ax.imshow(image, cmap="gray", vmin=0, vmax=1, origin="lower", extent=shown, interpolation="nearest")
    for name, rect in map_model.regions.items():
        cx, cy = rect.center
        ax.text(cx, cy, name, color="0.55", fontsize=8, ha="center", va="center", style="italic", zorder=1,
                clip_on=True)
    for door in map_model.doorways:
        ax.add_patch(Rectangle((door.x_min, door.y_min), door.x_max - door.x_min, door.y_max - door.y_min,
                               facecolor="#ffd54f", edgecolor="#b28704", alpha=0.7, lw=0.8, zorder=2))
    if "goal" in metrics and metrics["goal"]:
        gx, gy = metrics["goal"]
        ax.plot(gx, gy, marker="*", ms=16, color="gold", mec="k", zorder=6, ls="none", label=goal_label)
    if metrics.get("target"):
        tx, ty = metrics["target"][:2]
        ax.plot(tx, ty, marker="P", ms=13, color="#00bcd4", mec="k", zorder=6, ls="none", label="spot asked for")
    if metrics.get("base"):
        bx, by = metrics["base"][:2]
        ax.plot(bx, by, marker="h", ms=13, color="#8bc34a", mec="k", zorder=6, ls="none", label="base (Return)")
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
    names = list(rt.trajectories)
    colours = robot_colours(names)
    large = len(names) > SMALL_TEAM
    for index, (name, samples) in enumerate(rt.trajectories.items()):
        colour = colours[name]
        xy = np.array([[s.pose.x, s.pose.y] for s in samples])
        # later robots drawn thinner on top: a follower's path stays visible
        width = 0.9 if large else max(1.2, 3.4 - 1.1 * index)
        ax.plot(xy[:, 0], xy[:, 1], "-", lw=width, color=colour, label=legend_label(names, index),
                zorder=4 + 0.1 * index / len(names))
        ax.plot(*xy[0], "o", ms=5 if large else 9, mfc="white", mec=colour, mew=1.5 if large else 2, zorder=5)
        ax.plot(*xy[-1], "s", ms=5 if large else 8, color=colour, zorder=5)
        if not large or index == 0:  # a team of 30 with arrows is a thicket: the leader's show the way
            _arrows(ax, xy, colour)
    if large:
        ax.plot([], [], ls="none", label=f"({len(names)} robots: colour runs\nrobot_1 -> {names[-1]})")
    ax.plot([], [], "o", mfc="white", mec="k", ls="none", label="start")
    ax.plot([], [], "s", color="k", ls="none", label="end")
    if map_model.doorways:
        ax.add_patch(Rectangle((0, 0), 0, 0, facecolor="#ffd54f", edgecolor="#b28704", label="doorway"))
    ax.set_xlim(view[0], view[1])
    ax.set_ylim(view[2], view[3])
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


#: Most map cells drawn along either side of trajectory.png; a larger view is reduced in blocks.
MAX_MAP_PIXELS = 1600


def _display_map(map_model, view) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """The grey map cropped to `view` (x0, x1, y0, y1) and, beyond MAX_MAP_PIXELS cells a side,
    reduced in k x k blocks keeping each block's darkest shade (a wall one cell thick stays drawn),
    with the extent it covers: a 4000 x 4000 map took 4 s of image resampling to draw in full."""
    grid = map_model.grid
    res, ox, oy = grid.resolution, grid.origin_x, grid.origin_y
    rows, cols = grid.shape
    c0, c1 = max(0, int((view[0] - ox) // res)), min(cols, int(-(-(view[1] - ox) // res)))
    r0, r1 = max(0, int((view[2] - oy) // res)), min(rows, int(-(-(view[3] - oy) // res)))
    shades = map_shades(map_model)[r0:r1, c0:c1]
    k = max(1, -(-max(shades.shape) // MAX_MAP_PIXELS))
    if k > 1:
        h, w = -(-shades.shape[0] // k) * k, -(-shades.shape[1] // k) * k
        padded = np.full((h, w), FREE_SHADE)
        padded[:shades.shape[0], :shades.shape[1]] = shades
        shades = padded.reshape(h // k, k, w // k, k).min(axis=(1, 3))
        r1, c1 = r0 + h, c0 + w
    return shades, (ox + c0 * res, ox + c1 * res, oy + r0 * res, oy + r1 * res)


def _metric_points(metrics: dict) -> list[tuple[float, float]]:
    """Points the view must hold besides the map and the paths: the goal, a Stop, a MoveAround circle."""
    points = [tuple(metrics[key][:2]) for key in ("goal", "target", "base", "stop_position") if metrics.get(key)]
    if metrics.get("center") and metrics.get("radius_m"):
        (cx, cy), r = metrics["center"][:2], metrics["radius_m"]
        points += [(cx - r, cy - r), (cx + r, cy + r)]
    return points


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
