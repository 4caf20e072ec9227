"""Maps: the office wall file and ROS map_server maps, as walls for physics and a grid for navigation.

Owns: MapModel, OccupancyGrid, load_map. Pure numpy/PyYAML/Pillow (and SciPy for the bench's
SLAM-like map, slam_like.py): no MuJoCo, no navigation.
"""

from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.maps.loaders import load_map
from rescuemesh.maps.model import MapError, MapModel, Rect, WallMaterial, office_map_path

__all__ = ["MapError", "MapModel", "OccupancyGrid", "Rect", "WallMaterial", "load_map", "office_map_path"]
