"""A SLAM-like ROS map made from the office, for the bench: ragged walls, clutter, unknown padding.

Owns: writing a map_server map (PGM + YAML) whose occupied cells come from the office's walls with
the noise a SLAM run leaves: wall faces one cell ragged, scattered specks near the walls (chair legs,
false returns), and an unknown border around the building. The bench measures how a run's cost grows
with the number of occupied-cell runs the loader turns into wall boxes (issue 8 asks for about
1,000). Must not know: scenarios, the simulator. The free space stays that of the office (nothing is
added more than NEAR_WALL_M from a wall), so the office's starts and goals stay usable.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import ndimage

from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.maps.loaders import load_map
from rescuemesh.maps.model import office_map_path

#: Noise only within this distance of an office wall (m): the corridors keep their width less this.
NEAR_WALL_M = 0.15
#: Unknown border around the building, as a SLAM map has (m).
PADDING_M = 3.0
#: map_server grey values: 0 occupied, 254 free, 205 unknown (as map_saver writes them).
OCCUPIED, FREE, UNKNOWN = 0, 254, 205


def write_slam_like_map(folder: Path, *, seed: int = 0, speck_fraction: float = 0.07,
                        ragged_fraction: float = 0.45) -> Path:
    """Write `slam_like.pgm` and `slam_like.yaml` into `folder`; return the YAML's path.

    `ragged_fraction`: share of free cells next to a wall turned occupied (ragged faces);
    `speck_fraction`: share of the other free cells within NEAR_WALL_M of a wall turned occupied.
    """
    if not (0 <= speck_fraction <= 1 and 0 <= ragged_fraction <= 1):
        raise ValueError("speck_fraction and ragged_fraction must be in [0, 1]")
    office = load_map(office_map_path())
    grid: OccupancyGrid = office.grid
    occupied = grid.occupied.copy()
    rng = np.random.default_rng(seed)
    near = _within(occupied, max(1, round(NEAR_WALL_M / grid.resolution))) & ~occupied
    touching = _within(occupied, 1) & ~occupied
    occupied |= touching & (rng.random(occupied.shape) < ragged_fraction)
    occupied |= near & ~touching & (rng.random(occupied.shape) < speck_fraction)
    pad = round(PADDING_M / grid.resolution)
    image = np.full((occupied.shape[0] + 2 * pad, occupied.shape[1] + 2 * pad), UNKNOWN, np.uint8)
    image[pad:-pad, pad:-pad] = np.where(occupied, OCCUPIED, FREE)
    folder.mkdir(parents=True, exist_ok=True)
    from PIL import Image  # Pillow is only needed for ROS maps

    Image.fromarray(image[::-1]).save(folder / "slam_like.pgm")  # image row 0 is the top (highest y)
    origin = (grid.origin_x - pad * grid.resolution, grid.origin_y - pad * grid.resolution)
    yaml_path = folder / "slam_like.yaml"
    yaml_path.write_text(
        "image: slam_like.pgm\n"
        f"resolution: {grid.resolution}\n"
        f"origin: [{origin[0]:.3f}, {origin[1]:.3f}, 0.0]\n"
        "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    return yaml_path


def _within(mask: np.ndarray, cells: int) -> np.ndarray:
    """Cells within `cells` steps (4-neighbour, Manhattan distance) of a True cell of `mask`."""
    return ndimage.binary_dilation(mask, iterations=cells)
