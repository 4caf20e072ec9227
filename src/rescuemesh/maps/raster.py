"""Conversions between wall boxes and occupancy cells: rasterise boxes, merge cells into boxes.

Owns: the two geometric conversions the map loaders need. Must not know file formats,
physics or navigation.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.maps.model import Rect, WallMaterial

# Tolerance in cells when snapping box edges to cell edges: a 0.1 m wall at 0.05 m resolution
# covers exactly 2 cells, not 3 because of floating-point round-off.
_SNAP = 1e-6


def rasterise_walls(walls: Iterable[Rect], bounds: Rect, resolution: float,
                    materials: Iterable[WallMaterial | None] | None = None) -> OccupancyGrid:
    """An occupancy grid over `bounds` at `resolution` m per cell, with every cell a wall overlaps occupied.

    Cell (0, 0) has its lower-left corner at (bounds.x_min, bounds.y_min); a cell is occupied when a
    wall covers any part of it with positive area (conservative for planning). `materials` (one per
    wall, None: untagged) fills the grid's material codes; where walls overlap the later one wins.
    """
    walls = list(walls)
    tags = list(materials) if materials is not None else []
    cols = max(1, math.ceil((bounds.x_max - bounds.x_min) / resolution - _SNAP))
    rows = max(1, math.ceil((bounds.y_max - bounds.y_min) / resolution - _SNAP))
    occupied = np.zeros((rows, cols), dtype=bool)
    codes = np.zeros((rows, cols), dtype=np.uint8) if any(t is not None for t in tags) else None
    for k, wall in enumerate(walls):
        c0 = max(0, math.floor((wall.x_min - bounds.x_min) / resolution + _SNAP))
        c1 = min(cols, math.ceil((wall.x_max - bounds.x_min) / resolution - _SNAP))
        r0 = max(0, math.floor((wall.y_min - bounds.y_min) / resolution + _SNAP))
        r1 = min(rows, math.ceil((wall.y_max - bounds.y_min) / resolution - _SNAP))
        if c1 > c0 and r1 > r0:
            occupied[r0:r1, c0:c1] = True
            if codes is not None:
                tag = tags[k] if k < len(tags) else None
                codes[r0:r1, c0:c1] = tag.code if tag is not None else 0
    return OccupancyGrid(occupied=occupied, resolution=resolution, origin_x=bounds.x_min, origin_y=bounds.y_min,
                         materials=codes)


class TooManyBoxes(ValueError):
    """More than `limit` rectangles would cover the mask (at least `count` were found)."""

    def __init__(self, count: int, limit: int) -> None:
        super().__init__(f"at least {count} boxes, more than {limit}")
        self.count, self.limit = count, limit


def merge_cells(occupied: np.ndarray, limit: int | None = None) -> list[tuple[int, int, int, int]]:
    """Cover the True cells of a 2D mask with few axis-aligned rectangles, exactly and without overlap.

    Greedy: each row is cut into maximal horizontal runs, then a run identical (same first and last
    column) in consecutive rows extends one rectangle. Returns (row0, col0, row1, col1) with row1 and
    col1 exclusive, sorted. With `limit`, raises TooManyBoxes as soon as more rectangles than that are
    certain (every run open is one more), so a checkerboard costs no more than `limit` rectangles.
    """
    mask = np.asarray(occupied, dtype=bool)
    rows = mask.shape[0]
    open_runs: dict[tuple[int, int], int] = {}  # (col0, col1) -> first row of the growing rectangle
    rects: list[tuple[int, int, int, int]] = []
    pad = np.zeros(1, dtype=np.int8)
    for r in range(rows + 1):
        if r < rows:
            edges = np.diff(np.concatenate((pad, mask[r].astype(np.int8), pad)))
            runs = set(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))
        else:
            runs = set()
        for run in [run for run in open_runs if run not in runs]:
            rects.append((open_runs.pop(run), run[0], r, run[1]))
        for run in runs:
            open_runs.setdefault(run, r)
        if limit is not None and len(rects) + len(open_runs) > limit:
            raise TooManyBoxes(len(rects) + len(open_runs), limit)
    rects.sort()
    return rects


def cells_to_rects(occupied: np.ndarray, resolution: float, origin_x: float, origin_y: float,
                   limit: int | None = None) -> tuple[Rect, ...]:
    """Map-frame boxes in m covering the True cells of `occupied` (row 0 = lowest y), see `merge_cells`
    (TooManyBoxes beyond `limit`)."""
    return tuple(
        Rect(
            origin_x + c0 * resolution,
            origin_y + r0 * resolution,
            origin_x + c1 * resolution,
            origin_y + r1 * resolution,
        )
        for r0, c0, r1, c1 in merge_cells(occupied, limit)
    )
