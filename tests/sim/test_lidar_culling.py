"""The lidar tests each body only against the beams that can reach it; its scans equal casting every beam."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from rescuemesh.body import RobotKind
from rescuemesh.geometry import Pose2D
from rescuemesh.maps import MapModel, load_map, office_map_path
from rescuemesh.sim import LidarConfig, World, mjcf
from rescuemesh.sim import lidar as lidar_module
from rescuemesh.sim.lidar import Lidar

FULL_CIRCLE = LidarConfig(fov_rad=2.0 * math.pi, beams=360)  # first and last beam both point backwards
OTHERS = ["b", "c", "d", "e", "f", "g"]  # ground robots placed around robot "a" in each case


@pytest.fixture(scope="module")
def office() -> MapModel:
    return load_map(office_map_path())


@pytest.fixture(scope="module")
def world(office: MapModel) -> World:
    """Seven robots and two drones; the tests move them about (the world is never stepped)."""
    starts = {n: Pose2D(1.0 + 0.6 * i, 4.6, 0.0) for i, n in enumerate(["a", *OTHERS])}
    starts["drone_low"] = Pose2D(6.0, 1.0, 0.0)
    starts["drone_high"] = Pose2D(7.0, 1.0, 0.0)
    return World(office, starts, kinds={"drone_low": RobotKind.FLYING, "drone_high": RobotKind.FLYING}, camera=None)


def _place(world: World, name: str, x: float, y: float, yaw: float, z: float | None = None) -> None:
    """Put a body's free joint at (x, y) m, heading yaw rad (height z m, or where it is)."""
    joint = world.model.body_jntadr[world.bodies[name].body_id]
    adr = world.model.jnt_qposadr[joint]
    world.data.qpos[adr : adr + 2] = (x, y)
    if z is not None:
        world.data.qpos[adr + 2] = z
    world.data.qpos[adr + 3 : adr + 7] = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))


def _refresh(world: World) -> None:
    mujoco.mj_kinematics(world.model, world.data)
    world._lidar_scene.refresh()


def _every_beam(world: World, name: str, config: LidarConfig, origin: Pose2D) -> np.ndarray:
    """The reference: every beam cast in the scene (the lidar before it culled), nearer of that and the walls."""
    scene = world._lidar_scene
    angles = config.angle_min + config.angle_increment * np.arange(config.beams) + origin.yaw
    cos, sin = np.cos(angles), np.sin(angles)
    walls = np.full(config.beams, np.inf)
    if config.height <= scene.walls.wall_height:
        scene.walls.cast(origin.x, origin.y, cos, sin, config.range_max, walls)
    vec = np.stack([cos, sin, np.zeros_like(cos)], axis=1)
    dist = np.zeros(config.beams)
    mujoco.mj_multiRay(scene.model, scene.data, np.array([origin.x, origin.y, config.height]), vec.reshape(-1),
                       np.array(mjcf.LIDAR_GEOM_GROUPS, dtype=np.uint8), 1,
                       scene.scene_body(world.bodies[name].body_id), np.zeros(config.beams, dtype=np.int32), dist,
                       None, config.beams, config.range_max)
    ranges = np.minimum(np.where(dist < 0.0, np.inf, dist), walls)
    ranges[ranges > config.range_max] = np.inf
    return ranges


def _robots_seen(world: World, config: LidarConfig, origin: Pose2D, ranges: np.ndarray) -> int:
    """How many beams end on another body (nearer than the walls)."""
    scene = world._lidar_scene
    angles = config.angle_min + config.angle_increment * np.arange(config.beams) + origin.yaw
    walls = np.full(config.beams, np.inf)
    scene.walls.cast(origin.x, origin.y, np.cos(angles), np.sin(angles), config.range_max, walls)
    return int(np.sum(ranges < walls))


def _at(origin: Pose2D, bearing: float, distance: float) -> tuple[float, float]:
    """The point `distance` m from `origin` at `bearing` rad from its heading."""
    return origin.x + distance * math.cos(origin.yaw + bearing), origin.y + distance * math.sin(origin.yaw + bearing)


def _case(world: World, origin: Pose2D, others: list[tuple[float, float, float]], drone_z: float = 0.2) -> None:
    """Robot "a" at `origin`, the others at (bearing rad, distance m, yaw rad) from it, the rest far away."""
    _place(world, "a", origin.x, origin.y, origin.yaw)
    for i, name in enumerate(OTHERS):
        if i < len(others):
            bearing, distance, yaw = others[i]
            _place(world, name, *_at(origin, bearing, distance), yaw)
        else:
            _place(world, name, 30.0 + i, 30.0, 0.0)  # off the map, out of range
    _place(world, "drone_low", *_at(origin, 0.5, 1.2), 0.0, z=drone_z)  # hull in the beam plane (at 0.2 m)
    _place(world, "drone_high", *_at(origin, -0.5, 1.2), 0.0, z=1.5)  # far above it
    _refresh(world)


CONFIGS = [LidarConfig(), FULL_CIRCLE]


@pytest.mark.parametrize("config", CONFIGS, ids=["240deg", "360deg"])
def test_culled_sweep_equals_every_beam_cast_in_chosen_cases(world: World, config: LidarConfig) -> None:
    lidar = Lidar(world._lidar_scene, world.bodies["a"].body_id, config, np.random.default_rng(0))
    edge = 0.5 * config.fov_rad  # the fan's first and last beams: -edge and +edge from the heading
    r = mjcf.CHASSIS_RADIUS
    far_beam = round((-0.3 - config.angle_min) / config.angle_increment)
    far = config.angle_min + far_beam * config.angle_increment  # bearing of that beam, about -0.3 rad
    cases = {
        # Near and far, on both edges of the fan, behind (outside a 240 deg fan; across the seam of a full
        # circle), and at the end of the range: one chassis's face just within 5.6 m, one just beyond.
        # (From (2, 4.6) the hall is clear of walls for over 6 m at headings -0.5 to 0.5 rad.)
        "mixed": (Pose2D(2.0, 4.6, 0.3), [(0.35, 0.6, 0.0), (edge, 1.0, 1.0), (-edge, 2.5, 2.0), (math.pi, 1.5, 0.0),
                                          (far, config.range_max + r - 0.002, 0.0),
                                          (-0.75, config.range_max + r + 0.002, 0.0)]),
        # The heading at +-pi in the map frame: the robot ahead lies across atan2's seam.
        "seam ahead": (Pose2D(9.0, 4.6, math.pi - 0.01), [(0.0, 1.0, 0.0), (0.05, 3.0, 0.0), (edge - 0.05, 0.8, 0.0)]),
        "seam behind": (Pose2D(9.0, 4.6, 0.02), [(math.pi, 0.8, 0.0), (math.pi - 0.1, 2.0, 0.0)]),
        # Touching robot "a" (0.36 m apart) and none around.
        # Centred just outside either edge of the fan, partly in view.
        "outside the edges": (Pose2D(9.0, 4.6, 1.0), [(-edge - 0.1, 0.9, 0.0), (edge + 0.1, 1.1, 0.0)]),
        "touching": (Pose2D(12.0, 4.6, -1.0), [(0.1, 0.36, 0.0), (2.0, 0.4, 0.5)]),
        "alone": (Pose2D(12.0, 4.6, -1.0), []),
    }
    for label, (origin, others) in cases.items():
        for drone_z in (0.2, 0.215):  # the drone's hull (0.04 m tall) centred on the beam plane, or just cut by it
            _case(world, origin, others, drone_z)
            got = lidar.sweep(0.0, origin).ranges
            want = _every_beam(world, "a", config, origin)
            assert np.array_equal(got, want), (label, drone_z, np.flatnonzero(got != want))
            if others:
                assert _robots_seen(world, config, origin, want) > 0, label  # the case has bodies in view
    # The body at the end of the range is seen by the beam through its near face (the case's sanity).
    origin, others = cases["mixed"]
    _case(world, origin, others)
    assert lidar.sweep(0.0, origin).ranges[far_beam] == pytest.approx(config.range_max - 0.002, abs=1e-6)


@pytest.mark.parametrize("config", CONFIGS, ids=["240deg", "360deg"])
def test_culled_sweep_equals_every_beam_cast_in_random_scenes(world: World, config: LidarConfig) -> None:
    rng = np.random.default_rng(8)
    lidar = Lidar(world._lidar_scene, world.bodies["a"].body_id, config, np.random.default_rng(0))
    seen = 0
    for _ in range(150):
        origin = Pose2D(rng.uniform(2.0, 17.0), rng.uniform(1.0, 8.0), rng.uniform(-4.0, 4.0))
        others = [(rng.uniform(-math.pi, math.pi), rng.uniform(0.36, 7.0), rng.uniform(-math.pi, math.pi))
                  for _ in OTHERS]
        _case(world, origin, others, drone_z=rng.uniform(0.0, 0.4))
        got = lidar.sweep(0.0, origin).ranges
        want = _every_beam(world, "a", config, origin)
        assert np.array_equal(got, want), (origin, np.flatnonzero(got != want))
        seen += _robots_seen(world, config, origin, want)
    assert seen > 1000  # the scenes put many robots in view


def test_only_the_beams_that_can_reach_a_body_are_tested(world: World, monkeypatch: pytest.MonkeyPatch) -> None:
    tests: list[int] = []
    cast_bodies = lidar_module._cast_bodies

    def counting(*args):
        tests.append(cast_bodies(*args))  # (beam, geom) pairs given to mju_rayGeom
        return tests[-1]

    config = LidarConfig()
    lidar = Lidar(world._lidar_scene, world.bodies["a"].body_id, config, np.random.default_rng(0))
    monkeypatch.setattr(lidar_module, "_cast_bodies", counting)
    origin = Pose2D(9.0, 4.6, 0.0)
    _case(world, origin, [], drone_z=1.5)  # every other body out of range or above the beams
    lidar.sweep(0.0, origin)
    assert tests == [0]
    # One chassis 1 m ahead: about 24 deg of the fan, its chassis only (its top plate and standoffs lie
    # above the beam plane), and none of the bodies out of range.
    _case(world, origin, [(0.0, 1.0, 0.0)], drone_z=1.5)
    scan = lidar.sweep(0.0, origin)
    assert scan.ranges[341] == pytest.approx(1.0 - mjcf.CHASSIS_RADIUS, abs=1e-6)
    assert 0 < tests[1] < 100


def test_a_sweep_from_the_last_pose_again_still_sees_the_others_move(world: World) -> None:
    """A lidar keeps its last pose's wall ranges; what moves is cast afresh, and a new pose recasts all."""
    config = LidarConfig()
    lidar = Lidar(world._lidar_scene, world.bodies["a"].body_id, config, np.random.default_rng(0))
    here, there = Pose2D(9.0, 4.6, 0.0), Pose2D(2.0, 4.6, 0.3)
    for origin, others in [(here, [(0.0, 1.0, 0.0)]), (here, [(0.2, 2.0, 0.0)]), (there, [(0.0, 1.0, 0.0)]),
                           (Pose2D(2.0, 4.6, 1.3), []), (Pose2D(2.5, 4.6, 1.3), []), (here, [])]:
        _case(world, origin, others)
        assert np.array_equal(lidar.sweep(0.0, origin).ranges, _every_beam(world, "a", config, origin)), origin
