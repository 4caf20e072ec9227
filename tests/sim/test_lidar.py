"""The lidar's two casts: the map's walls on a grid (gridcast.py) and everything else in the LidarScene."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from rescuemesh.body import RobotKind
from rescuemesh.geometry import Pose2D
from rescuemesh.maps import MapModel, load_map, office_map_path
from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.maps.model import Rect
from rescuemesh.maps.raster import cells_to_rects
from rescuemesh.maps.slam_like import write_slam_like_map
from rescuemesh.sim import LidarConfig, World, mjcf
from rescuemesh.sim.gridcast import WallGrid
from rescuemesh.sim.lidar import LidarScene

CENTRE_BEAM = 341  # of 683 beams over 240 deg: the beam along the robot's x axis
RES = 0.05  # m per cell
MARCH_STEP = 0.0005  # m, the reference march's step (a tenth of a millimetre would change nothing)


@pytest.fixture(scope="module")
def office() -> MapModel:
    return load_map(office_map_path())


@pytest.fixture(scope="module")
def slam_like(tmp_path_factory: pytest.TempPathFactory) -> MapModel:
    return load_map(write_slam_like_map(Path(tmp_path_factory.mktemp("slam"))))


def _cells_map(occupied: np.ndarray, origin: tuple[float, float] = (-1.0, 2.0)) -> MapModel:
    """A MapModel whose walls are the occupied cells (as a ROS map's are)."""
    rows, cols = occupied.shape
    ox, oy = origin
    grid = OccupancyGrid(occupied=occupied, resolution=RES, origin_x=ox, origin_y=oy)
    return MapModel(name="cells", source=None, bounds=Rect(ox, oy, ox + cols * RES, oy + rows * RES),
                    walls=cells_to_rects(occupied, RES, ox, oy), grid=grid)


def _march(occupied: np.ndarray, origin: tuple[float, float], x: float, y: float, angles: np.ndarray,
           max_range: float) -> np.ndarray:
    """Reference ranges: step along each beam every MARCH_STEP m; the first sample in an occupied cell."""
    t = np.arange(0.0, max_range + MARCH_STEP, MARCH_STEP)
    px = x + np.outer(np.cos(angles), t)
    py = y + np.outer(np.sin(angles), t)
    col = np.floor((px - origin[0]) / RES).astype(int)
    row = np.floor((py - origin[1]) / RES).astype(int)
    inside = (row >= 0) & (row < occupied.shape[0]) & (col >= 0) & (col < occupied.shape[1])
    hit = np.zeros_like(inside)
    hit[inside] = occupied[row[inside], col[inside]]
    first = np.argmax(hit, axis=1)
    return np.where(hit.any(axis=1), t[first], np.inf)


def _cell_and_chord(origin: tuple[float, float], x: float, y: float, angle: float, t: float) -> tuple[int, int, float]:
    """The cell a beam is in just past distance `t` m, and the length in m of the beam inside that cell."""
    dx, dy = math.cos(angle), math.sin(angle)
    fx, fy = (x + (t + 1e-9) * dx - origin[0]) / RES, (y + (t + 1e-9) * dy - origin[1]) / RES
    col, row = math.floor(fx), math.floor(fy)
    exits = [((col + (dx > 0)) - fx) / dx if dx else math.inf, ((row + (dy > 0)) - fy) / dy if dy else math.inf]
    return row, col, min(exits) * RES + 1e-9


def _random_walls(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    occupied = rng.random(shape) < 0.02  # specks
    for _ in range(25):  # wall runs of 1 to 3 cells' thickness
        r, c = rng.integers(0, shape[0]), rng.integers(0, shape[1])
        length, thick = rng.integers(5, 60), rng.integers(1, 4)
        if rng.random() < 0.5:
            occupied[r : r + thick, c : c + length] = True
        else:
            occupied[r : r + length, c : c + thick] = True
    return occupied


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_grid_cast_agrees_with_a_fine_march_on_the_grid(seed: int) -> None:
    rng = np.random.default_rng(seed)
    occupied = _random_walls(rng, (90, 140))
    origin = (-1.0, 2.0)
    walls = WallGrid(_cells_map(occupied, origin))
    assert np.array_equal(walls.occupied.astype(bool), occupied)
    max_range = 5.6
    # Axis-parallel and diagonal beams (the walk's special cases), then random ones.
    angles = np.concatenate([np.arange(8) * math.pi / 4, rng.uniform(-math.pi, math.pi, 300)])
    checked = clipped = 0
    for _ in range(12):
        # Origins in free cells, some outside the grid (beams that enter it from outside).
        x = rng.uniform(origin[0] - 1.0, origin[0] + 140 * RES + 1.0)
        y = rng.uniform(origin[1] - 1.0, origin[1] + 90 * RES + 1.0)
        row, col = math.floor((y - origin[1]) / RES), math.floor((x - origin[0]) / RES)
        if 0 <= row < 90 and 0 <= col < 140 and occupied[row, col]:
            continue
        out = np.empty(len(angles))
        walls.cast(x, y, np.cos(angles), np.sin(angles), max_range, out)
        ref = _march(occupied, origin, x, y, angles, max_range)
        near_limit = np.abs(ref - max_range) <= MARCH_STEP  # either side of the range limit is right
        # Where the march finds a wall, the cast finds it too, never farther: the march's first sample
        # in a wall is past the true entry, by at most one step.
        marched = np.isfinite(ref) & ~near_limit
        assert np.all(out[marched] <= ref[marched] + 1e-9)
        for i in np.flatnonzero(np.isfinite(out)):
            row, col, chord = _cell_and_chord(origin, x, y, angles[i], out[i])
            assert occupied[row, col]  # the cast stops in a wall cell
            if not ref[i] - out[i] <= MARCH_STEP + 1e-9 and not near_limit[i]:
                # More than a step before the march (or where it found nothing): only where the beam
                # clips a cell's corner for less than a step, so that the march steps over it (the
                # cast, like MuJoCo's boxes, sees it).
                assert chord < MARCH_STEP
                clipped += 1
        checked += int(np.isfinite(out).sum())
    assert checked > 500  # the test saw many walls
    assert clipped < 0.02 * checked


def test_grid_cast_edge_cases() -> None:
    occupied = np.zeros((20, 20), dtype=bool)
    occupied[:, 10] = True  # a wall along x = 10 cells
    walls = WallGrid(_cells_map(occupied, (0.0, 0.0)))
    out = np.empty(3)
    cos, sin = np.array([1.0, -1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    walls.cast(0.125, 0.5, cos, sin, 5.0, out)
    assert out[0] == pytest.approx(0.5 - 0.125, abs=1e-12)  # east: the wall's face at x = 0.5 m
    assert out[1] == math.inf and out[2] == math.inf  # west and north leave the grid without a wall
    walls.cast(-2.0, 0.5, cos, sin, 5.0, out)  # from outside the grid
    assert out[0] == pytest.approx(2.5, abs=1e-12)
    walls.cast(-2.0, 0.5, cos, sin, 2.4, out)  # ... beyond the range limit
    assert out[0] == math.inf
    walls.cast(0.52, 0.5, cos, sin, 5.0, out)  # inside the wall
    assert out[0] == 0.0
    empty = WallGrid(_cells_map(np.zeros((5, 5), dtype=bool)))
    empty.cast(0.0, 2.5, cos, sin, 5.0, out)
    assert np.all(np.isinf(out))


def test_lidar_agrees_with_mujoco_on_the_wall_boxes(slam_like: MapModel) -> None:
    """The grid cast against ray truth from MuJoCo itself: mj_multiRay over the world's own wall boxes."""
    # This used to be the lidar: mj_multiRay over every geom, 1.1 ms a sweep on this map of ~1,000 boxes.
    starts = {"a": Pose2D(2.0, 4.6, 0.3), "b": Pose2D(5.0, 4.0, 2.0), "c": Pose2D(11.0, 4.6, -2.5),
              "d": Pose2D(16.0, 3.0, 1.0)}
    world = World(slam_like, starts, camera=None)
    model, data = world.model, world.data
    groups = np.array(mjcf.LIDAR_GEOM_GROUPS, dtype=np.uint8)
    assert len(slam_like.walls) > 500
    for name, body in world.bodies.items():
        scan = body.scan()
        pose = body.pose()
        angles = scan.angles() + pose.yaw
        vec = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
        dist = np.zeros(len(angles))
        mujoco.mj_multiRay(model, data, np.array([pose.x, pose.y, LidarConfig().height]), vec.reshape(-1), groups,
                           1, body.body_id, np.zeros(len(angles), dtype=np.int32), dist, None, len(angles), 5.6)
        truth = np.where((dist < 0) | (dist > 5.6), np.inf, dist)
        assert np.array_equal(np.isfinite(scan.ranges), np.isfinite(truth)), name
        hit = np.isfinite(truth)
        assert hit.sum() > 100
        np.testing.assert_allclose(scan.ranges[hit], truth[hit], atol=1e-9)


def test_lidar_sees_another_robot_on_a_map_of_many_walls(slam_like: MapModel) -> None:
    world = World(slam_like, {"a": Pose2D(4.0, 4.6, 0.0), "b": Pose2D(5.5, 4.6, math.pi / 2)}, camera=None)
    assert world.bodies["a"].scan().ranges[CENTRE_BEAM] == pytest.approx(1.5 - mjcf.CHASSIS_RADIUS, abs=1e-6)


def test_lidar_sees_a_quadrotor(office: MapModel) -> None:
    world = World(office, {"a": Pose2D(4.0, 4.6, 0.0), "drone": Pose2D(5.5, 4.6, 0.0)},
                  kinds={"drone": RobotKind.FLYING}, camera=None)
    assert math.isinf(world.bodies["a"].scan().ranges[CENTRE_BEAM])  # on the floor, below the beams
    joint = world.model.body(mjcf.base_name("drone")).jntadr[0]
    adr = world.model.jnt_qposadr[joint]
    world.data.qpos[adr + 2] = LidarConfig().height  # hull centre in the beam plane
    world._sweep()
    assert world.bodies["a"].scan().ranges[CENTRE_BEAM] == pytest.approx(1.5 - 0.05, abs=1e-6)  # hull face


def test_lidar_above_the_walls_sees_none(office: MapModel) -> None:
    world = World(office, {"a": Pose2D(5.0, 8.1, math.pi / 2)}, lidar=LidarConfig(height=0.6), camera=None)
    assert np.all(np.isinf(world.bodies["a"].scan().ranges))
    world = World(office, {"a": Pose2D(5.0, 8.1, math.pi / 2)}, lidar=LidarConfig(height=0.45), camera=None)
    assert world.bodies["a"].scan().ranges[CENTRE_BEAM] == pytest.approx(1.0, abs=1e-9)


def test_scene_copies_every_visible_geom_but_the_walls(office: MapModel) -> None:
    world = World(office, office.starts, camera=None)
    scene = world._lidar_scene
    # Per TurtleBot: chassis, top plate, three standoffs (wheels and casters are in the hidden group).
    assert scene.model.ngeom == 5 * len(office.starts)
    for name, body in world.bodies.items():
        assert scene.scene_body(body.body_id) >= 0
        np.testing.assert_allclose(scene.data.xpos[scene.scene_body(body.body_id)], world.data.xpos[body.body_id])


def test_scene_refuses_a_geom_it_cannot_copy(office: MapModel) -> None:
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><asset><mesh name="m" vertex="0 0 0 1 0 0 0 1 0 0 0 1"/></asset>'
        '<worldbody><body><freejoint/><geom type="mesh" mesh="m"/></body></worldbody></mujoco>'
    )
    with pytest.raises(ValueError, match="MESH"):
        LidarScene(model, mujoco.MjData(model), office, [])
