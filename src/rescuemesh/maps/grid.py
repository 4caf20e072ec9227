"""A 2D occupancy grid in the ROS nav_msgs/OccupancyGrid convention.

Owns: cell <-> map-frame conversions. Must not know where the grid came from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class OccupancyGrid:
    """`occupied[row, col]` is True for an obstacle cell.

    Row 0 is the lowest y (as nav_msgs/OccupancyGrid; PGM images are flipped on load). Cell (0, 0)
    has its lower-left corner at (`origin_x`, `origin_y`) m in the map frame; cells are
    `resolution` m square. `materials` (optional, same shape, uint8) holds the code of the wall
    material of each occupied cell (`maps.model.WallMaterial.code`; 0: untagged); None: all untagged.
    """

    occupied: np.ndarray
    resolution: float
    origin_x: float
    origin_y: float
    materials: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return self.occupied.shape  # (rows, cols)

    def world_to_cell(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell holding map point (x, y); may lie outside the grid."""
        return (math.floor((y - self.origin_y) / self.resolution), math.floor((x - self.origin_x) / self.resolution))

    def cell_to_world(self, row: int, col: int) -> tuple[float, float]:
        """Map-frame (x, y) in m of the centre of cell (row, col)."""
        return (self.origin_x + (col + 0.5) * self.resolution, self.origin_y + (row + 0.5) * self.resolution)

    def in_bounds(self, row: int, col: int) -> bool:
        rows, cols = self.occupied.shape
        return 0 <= row < rows and 0 <= col < cols

    def is_occupied(self, x: float, y: float) -> bool:
        """True for an obstacle cell or a point outside the grid."""
        row, col = self.world_to_cell(x, y)
        return not self.in_bounds(row, col) or bool(self.occupied[row, col])
