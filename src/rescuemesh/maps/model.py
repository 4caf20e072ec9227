"""MapModel: what every layer may know of a map.

Owns: the map data model, MapError and the packaged office map's path. The loaders
(`maps/loaders.py`, `load_map`) import this module, never the reverse.
Must not know: physics, navigation, scenarios, file formats.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from rescuemesh.geometry import Pose2D
from rescuemesh.maps.grid import OccupancyGrid


class WallMaterial(enum.Enum):
    """What a wall is made of, as a map file may tag it (the radio prices each; docs/radio.md).

    The code of a material in `OccupancyGrid.materials` is its position here plus 1; 0 is a wall with
    no tag (ROS maps, untagged boxes), which the radio prices with its default.
    """

    LIGHT = "light"  # plasterboard on studs
    BRICK = "brick"
    CONCRETE = "concrete"
    GLASS = "glass"
    WOOD = "wood"  # furniture, doors

    @property
    def code(self) -> int:
        return _MATERIAL_CODES[self]


_MATERIAL_CODES = {m: i + 1 for i, m in enumerate(WallMaterial)}


class MapError(ValueError):
    """A map file is missing, unreadable or malformed. The message names the file and the problem."""


@dataclass(frozen=True, slots=True)
class Rect:
    """An axis-aligned rectangle in the map frame, in m."""

    x_min: float
    y_min: float
    x_max: float
    y_max: float

    def contains(self, x: float, y: float) -> bool:
        return self.x_min <= x <= self.x_max and self.y_min <= y <= self.y_max

    @property
    def center(self) -> tuple[float, float]:
        return (0.5 * (self.x_min + self.x_max), 0.5 * (self.y_min + self.y_max))


@dataclass(frozen=True)
class MapModel:
    """A map as physics, navigation, scenarios and plots see it.

    - `walls`: boxes that become static geoms in the physics world (height `wall_height` m).
    - `wall_materials`: the material each wall is tagged with (None: untagged), same order as `walls`.
    - `grid`: the occupancy grid navigation plans on (rasterised walls, or the map_server image).
    - `bounds`: the rectangle the map covers.
    - `regions`: named areas ("hall", "room_east", ...) for success criteria and plot labels.
    - `doorways`: openings to mark on plots.
    - `starts`: default robot start poses by robot name; `goals`: named default goals;
      `bases`: where each named robot's Return goes (default: its start pose).
    """

    name: str
    source: Path | None
    bounds: Rect
    walls: tuple[Rect, ...]
    grid: OccupancyGrid
    wall_height: float = 0.5
    regions: dict[str, Rect] = field(default_factory=dict)
    doorways: tuple[Rect, ...] = ()
    starts: dict[str, Pose2D] = field(default_factory=dict)
    goals: dict[str, Pose2D] = field(default_factory=dict)
    bases: dict[str, Pose2D] = field(default_factory=dict)
    wall_materials: tuple[WallMaterial | None, ...] = ()

    def region_of(self, x: float, y: float) -> str | None:
        """Name of the first region that contains (x, y), or None."""
        for name, rect in self.regions.items():
            if rect.contains(x, y):
                return name
        return None


def office_map_path() -> Path:
    """Path of the packaged office map (`rescuemesh/data/office.yaml`)."""
    return Path(str(resources.files("rescuemesh") / "data" / "office.yaml"))

