"""Sensor pictures for a run directory: a laser scan drawn on the map (`DIR/scans/*.png`) and camera
images saved as PNG (`DIR/images/*.png`).

Owns: the matplotlib figure of a scan (Agg, no screen). Must not know: how the scan or image
travelled (decode them with rescuemesh.robot.sensor_codec first).
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Rectangle, Wedge  # noqa: E402
from PIL import Image  # noqa: E402

from rescuemesh.body import LaserScan  # noqa: E402

MARGIN_M = 1.0  # around the map


def draw_scan_png(scan: LaserScan, map_model, path: str | Path, *, title: str = "",
                  spot: tuple[float, float] | None = None) -> Path:
    """Draw `scan` on `map_model` and write a PNG to `path` (parent folders made as needed).

    Walls grey, doorways yellow, the scan's field of view as a light wedge of radius range_max, its
    returns as red dots, the robot's pose as a blue arrow, the `spot` asked for (x, y) as a cyan
    cross; the title gives the stamp, pose and beams.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    b = map_model.bounds
    width, height = b.x_max - b.x_min + 2 * MARGIN_M, b.y_max - b.y_min + 2 * MARGIN_M
    fig, ax = plt.subplots(figsize=(min(16.0, 2 + 0.6 * width), min(12.0, 1.5 + 0.6 * height)), dpi=100)
    try:
        for wall in map_model.walls:
            ax.add_patch(Rectangle((wall.x_min, wall.y_min), wall.x_max - wall.x_min, wall.y_max - wall.y_min,
                                   facecolor="0.35", edgecolor="none", zorder=1))
        for door in map_model.doorways:
            ax.add_patch(Rectangle((door.x_min, door.y_min), door.x_max - door.x_min, door.y_max - door.y_min,
                                   facecolor="#ffd54f", edgecolor="#b28704", alpha=0.7, lw=0.8, zorder=2))
        o = scan.origin
        n = len(scan.ranges)
        first = math.degrees(o.yaw + scan.angle_min)
        last = math.degrees(o.yaw + scan.angle_min + scan.angle_increment * max(n - 1, 0))
        ax.add_patch(Wedge((o.x, o.y), scan.range_max, min(first, last), max(first, last), facecolor="#90caf9",
                           alpha=0.18, edgecolor="none", zorder=0.5, label=f"field of view, {scan.range_max:g} m"))
        points = scan.points_in_map()
        ax.plot(points[:, 0], points[:, 1], ".", ms=2.5, color="#d62728", zorder=4,
                label=f"returns ({len(points)} of {n} beams)")
        ax.arrow(o.x, o.y, 0.5 * math.cos(o.yaw), 0.5 * math.sin(o.yaw), width=0.06, head_width=0.25,
                 length_includes_head=True, color="#1f77b4", zorder=5)
        ax.plot([o.x], [o.y], "o", ms=6, color="#1f77b4", zorder=5, label="robot")
        if spot is not None:
            ax.plot([spot[0]], [spot[1]], marker="P", ms=13, color="#00bcd4", mec="k", ls="none", zorder=6,
                    label=f"spot asked for ({spot[0]:.2f}, {spot[1]:.2f})")
        ax.set_xlim(b.x_min - MARGIN_M, b.x_max + MARGIN_M)
        ax.set_ylim(b.y_min - MARGIN_M, b.y_max + MARGIN_M)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
        heading = f"scan at t = {scan.stamp:.2f} s from ({o.x:.2f}, {o.y:.2f}) m, yaw {math.degrees(o.yaw):.0f} deg"
        ax.set_title(f"{title}\n{heading}" if title else heading, fontsize=10)
        fig.tight_layout()
        fig.savefig(path)
    finally:
        plt.close(fig)
    return path


def save_image_png(rgb: np.ndarray, path: str | Path, *, scale: int = 1) -> Path:
    """Write an (H, W, 3) uint8 image as PNG, enlarged `scale` times (nearest neighbour) for viewing."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    image = Image.fromarray(np.ascontiguousarray(rgb, dtype=np.uint8), "RGB")
    if scale != 1:
        image = image.resize((image.width * scale, image.height * scale), Image.Resampling.NEAREST)
    image.save(path)
    return path
