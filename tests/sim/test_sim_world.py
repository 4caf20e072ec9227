"""The MuJoCo world: build, drive, sense, collide, repeat identically."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rescuemesh.geometry import Pose2D, quaternion_to_yaw, wrap_angle
from rescuemesh.maps import MapModel, load_map, office_map_path
from rescuemesh.sim import LidarConfig, SimBody, World

CENTRE_BEAM = 341  # of 683 beams over 240 deg: the beam along the robot's x axis


@pytest.fixture(scope="module")
def office() -> MapModel:
    return load_map(office_map_path())


def _world(office: MapModel, **starts: Pose2D) -> World:
    return World(office, starts or {"robot_1": office.starts["robot_1"]})


def test_world_builds_from_the_office(office: MapModel) -> None:
    world = World(office, office.starts)
    assert set(world.bodies) == {"robot_1", "robot_2", "robot_3"}
    assert world.time == 0.0
    assert world.collisions == {"robot_1": 0, "robot_2": 0, "robot_3": 0}
    body = world.bodies["robot_1"]
    assert isinstance(body, SimBody)
    assert (body.max_linear_speed, body.max_angular_speed, body.radius) == (0.7, math.pi, 0.177)
    assert body.pose().distance_to(office.starts["robot_1"]) < 1e-9
    scan = body.scan()
    assert scan is not None and scan.stamp == 0.0 and len(scan.ranges) == 683
    world.step(0.5)
    assert world.time == pytest.approx(0.5)
    assert body.pose().distance_to(office.starts["robot_1"]) < 0.005  # rests where it was put


def test_straight_drive_moves_along_the_heading(office: MapModel) -> None:
    start = Pose2D(4.0, 3.0, math.radians(30))
    world = _world(office, r=start)
    body = world.bodies["r"]
    body.set_velocity(0.3, 0.0)
    world.step(2.0)
    pose = body.pose()
    along = (pose.x - start.x) * math.cos(start.yaw) + (pose.y - start.y) * math.sin(start.yaw)
    across = -(pose.x - start.x) * math.sin(start.yaw) + (pose.y - start.y) * math.cos(start.yaw)
    assert along == pytest.approx(0.6, rel=0.1)
    assert abs(across) < 0.01 and abs(wrap_angle(pose.yaw - start.yaw)) < 0.01
    _, v, w = body.odometry()
    assert v == pytest.approx(0.3, rel=0.05) and abs(w) < 0.01


def test_turn_in_place(office: MapModel) -> None:
    world = _world(office)
    body = world.bodies["robot_1"]
    start = body.pose()
    body.set_velocity(0.0, 1.0)
    world.step(1.5)
    assert wrap_angle(body.pose().yaw - start.yaw) == pytest.approx(1.5, rel=0.1)
    assert body.pose().distance_to(start) < 0.01
    assert body.odometry()[2] == pytest.approx(1.0, rel=0.05)


def test_commands_are_clamped_to_the_limits(office: MapModel) -> None:
    world = _world(office)
    body = world.bodies["robot_1"]
    body.set_velocity(5.0, -10.0)
    assert body.command == (0.7, -math.pi)
    body.set_velocity(2.0, 0.0)
    world.step(1.0)
    assert body.odometry()[1] == pytest.approx(0.7, rel=0.05)
    body.set_velocity(0.0, -10.0)
    world.step(1.0)
    assert body.odometry()[2] == pytest.approx(-math.pi, rel=0.05)
    with pytest.raises(ValueError):
        body.set_velocity(float("nan"), 0.0)


def test_stops_quickly(office: MapModel) -> None:
    world = _world(office)
    body = world.bodies["robot_1"]
    body.set_velocity(0.5, 0.0)
    world.step(1.0)
    body.set_velocity(0.0, 0.0)
    world.step(0.3)
    assert abs(body.odometry()[1]) < 0.02
    _, v_after, _ = body.odometry()
    world.step(0.2)
    assert abs(body.odometry()[1]) < 0.02 and abs(v_after) < 0.02


@pytest.mark.parametrize(
    ("start", "distance"),
    [
        (Pose2D(3.0, 4.6, math.pi), 2.9),  # facing the west wall (inner face x = 0.1)
        (Pose2D(5.0, 8.1, math.pi / 2), 1.0),  # facing the north wall (inner face y = 9.1)
        (Pose2D(2.2, 3.2, -math.pi / 2), 0.8),  # facing the pillar (top face y = 2.4)
    ],
)
def test_lidar_sees_a_wall_at_a_known_distance(office: MapModel, start: Pose2D, distance: float) -> None:
    world = _world(office, r=start)
    scan = world.bodies["r"].scan()
    assert scan is not None
    assert scan.ranges[CENTRE_BEAM] == pytest.approx(distance, abs=0.03)
    assert scan.angles()[CENTRE_BEAM] == pytest.approx(0.0, abs=1e-9)
    assert scan.angle_min == pytest.approx(-math.radians(120))
    finite = scan.ranges[np.isfinite(scan.ranges)]
    assert finite.max() <= 5.6 and finite.min() > 0.2  # never its own chassis


def test_lidar_sees_another_robot(office: MapModel) -> None:
    world = _world(office, a=Pose2D(4.0, 4.6, 0.0), b=Pose2D(5.5, 4.6, math.pi / 2))
    scan_a, scan_b = world.bodies["a"].scan(), world.bodies["b"].scan()
    assert scan_a is not None and scan_b is not None
    assert scan_a.ranges[CENTRE_BEAM] == pytest.approx(1.5 - 0.177, abs=0.03)
    # b looks north; a is west of it, on its left, 90 deg anticlockwise
    left = int(np.argmin(np.abs(scan_b.angles() - math.pi / 2)))
    assert scan_b.ranges[left] == pytest.approx(1.5 - 0.177, abs=0.03)


def test_lidar_range_limit_gives_inf(office: MapModel) -> None:
    world = _world(office, r=Pose2D(4.5, 4.6, 0.0))  # facing the 2 m opening onto the 9 m passage
    scan = world.bodies["r"].scan()
    assert scan is not None and np.isinf(scan.ranges[CENTRE_BEAM])


def test_lidar_sweeps_on_its_schedule(office: MapModel) -> None:
    world = _world(office)
    body = world.bodies["robot_1"]
    world.step(0.25)
    assert body.scan().stamp == pytest.approx(0.2)
    world.step(0.05)
    assert body.scan().stamp == pytest.approx(0.3)
    assert world.scan_period == pytest.approx(0.1)


def test_driving_into_a_wall_counts_one_collision(office: MapModel) -> None:
    world = _world(office, r=Pose2D(0.9, 4.6, math.pi), other=Pose2D(4.0, 4.6, 0.0))
    body = world.bodies["r"]
    body.set_velocity(0.3, 0.0)
    for _ in range(60):  # 3 s at the 20 Hz control rate; contact after about 2.1 s
        world.step(0.05)
    assert world.contacts_now("r")
    assert world.collisions == {"r": 1, "other": 0}
    assert body.pose().x == pytest.approx(0.1 + 0.177, abs=0.02)  # pressed against the wall, not through
    body.set_velocity(-0.3, 0.0)
    world.step(1.0)
    assert not world.contacts_now("r")
    body.set_velocity(0.3, 0.0)
    world.step(1.5)
    assert world.collisions["r"] == 2  # backed off and came back: a second episode


def test_robots_bumping_count_for_both(office: MapModel) -> None:
    world = _world(office, a=Pose2D(3.0, 4.6, 0.0), b=Pose2D(4.0, 4.6, math.pi))
    for name in ("a", "b"):
        world.bodies[name].set_velocity(0.3, 0.0)
    world.step(2.0)
    assert world.collisions == {"a": 1, "b": 1}


def test_same_inputs_give_identical_trajectories(office: MapModel) -> None:
    def run(seed: int, chunk: float) -> tuple[np.ndarray, np.ndarray, tuple]:
        world = World(office, office.starts, lidar=LidarConfig(noise_std=0.01), seed=seed)
        for k in range(40):
            for i, body in enumerate(world.bodies.values()):
                body.set_velocity(0.4 * math.sin(0.1 * k + i), 0.8 * math.cos(0.07 * k * (i + 1)))
            for _ in range(round(0.1 / chunk)):
                world.step(chunk)
        scan = world.bodies["robot_2"].scan()
        return world.data.qpos.copy(), scan.ranges, world.bodies["robot_1"].odometry()

    q1, s1, o1 = run(3, 0.05)
    q2, s2, o2 = run(3, 0.1)
    assert np.array_equal(q1, q2) and np.array_equal(s1, s2) and o1 == o2
    _, s3, _ = run(4, 0.05)
    assert not np.array_equal(s1, s3)  # the seed drives the lidar noise


def test_odometry_tracks_the_pose_on_a_short_drive(office: MapModel) -> None:
    world = _world(office)
    body = world.bodies["robot_1"]
    body.set_velocity(0.4, 0.0)
    world.step(1.5)
    body.set_velocity(0.3, 0.5)
    world.step(1.5)
    odom, _, _ = body.odometry()
    truth = body.pose()
    assert odom.distance_to(truth) < 0.03
    assert abs(wrap_angle(odom.yaw - truth.yaw)) < 0.02


def test_pose_and_odometry_are_read_afresh_after_every_step(office: MapModel) -> None:
    # SimBody keeps them between steps (World calls moved()); a stale one would lag the physics.
    world = _world(office)
    body = world.bodies["robot_1"]
    body.set_velocity(0.5, 1.0)
    seen = set()
    for _ in range(12):  # single steps, across an odometry commit (every 8)
        world.step(world.physics_dt)
        adr = world.model.jnt_qposadr[world.model.joint("robot_1/root").id]
        x, y, _, qw, qx, qy, qz = world.data.qpos[adr : adr + 7].tolist()
        assert body.pose() == Pose2D(x, y, quaternion_to_yaw(qx, qy, qz, qw))
        odom, v, _ = body.odometry()
        seen.add((body.pose(), odom, v))
    assert len(seen) == 12


def test_bad_world_arguments(office: MapModel) -> None:
    with pytest.raises(ValueError, match="physics_dt"):
        World(office, office.starts, physics_dt=0.01)
    with pytest.raises(ValueError, match="inside an obstacle"):
        World(office, {"r": Pose2D(0.05, 4.0, 0.0)})
    with pytest.raises(ValueError, match="at least one"):
        World(office, {})
