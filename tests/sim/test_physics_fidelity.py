"""The wheeled physics against references derived from the model's own figures (sim/mjcf.py).

A TurtleBot commanded (v, omega) should reach it at the torque-limited rate and then hold it: the
wheel servos saturate at WHEEL_MAX_TORQUE, so from rest the base accelerates at
a = 2 * WHEEL_MAX_TORQUE / (WHEEL_RADIUS * m_eff), where m_eff adds the wheels' spin inertia
(sphere plus armature) reflected through the wheel radius; the servo's unsaturated tail is a few ms
(m_eff * r^2 / (2 * WHEEL_KV)). A drive of T s from rest at speed v then covers v * T - v^2 / (2 a).
Turning in place works the same with the yaw inertia and the wheels' lever arm. These references
hold whatever the solver options and contact plumbing are, so they guard speed-ups of the stepping
(issue 8): a drive must stay within 1 cm and 1 degree of them, and walls must still stop and count.
"""

from __future__ import annotations

import math

import pytest

from rescuemesh.body import RobotKind
from rescuemesh.geometry import Pose2D, wrap_angle
from rescuemesh.maps import MapModel, load_map, office_map_path
from rescuemesh.runtime.config import SimConfig
from rescuemesh.sim import World, mjcf

START = Pose2D(4.0, 3.0, math.radians(30))  # open floor in the office, at least 1 m from any wall
POSITION_TOL = 0.01  # m
YAW_TOL = math.radians(1.0)  # rad

_R, _HALF = mjcf.WHEEL_RADIUS, 0.5 * mjcf.WHEEL_SEPARATION
_SPIN = 0.4 * mjcf.WHEEL_MASS * _R**2 + mjcf.WHEEL_ARMATURE  # kg m^2, a wheel about its axle (solid sphere)
# Linear: base and wheels, plus both wheels' spin inertia seen at the contact.
M_EFF = mjcf.BASE_MASS + 2 * mjcf.WHEEL_MASS + 2 * _SPIN / _R**2  # kg
LINEAR_ACCEL = 2 * mjcf.WHEEL_MAX_TORQUE / _R / M_EFF  # m/s^2, both wheels at the torque limit
# Yaw: the base's solid cylinder, the wheels at half the separation (own inertia plus offset) and
# their spin inertia geared by half-separation / radius.
I_YAW = 0.5 * mjcf.BASE_MASS * mjcf.CHASSIS_RADIUS**2 + 2 * (
    0.4 * mjcf.WHEEL_MASS * _R**2 + mjcf.WHEEL_MASS * _HALF**2 + _SPIN * (_HALF / _R) ** 2
)  # kg m^2
YAW_ACCEL = 2 * mjcf.WHEEL_MAX_TORQUE / _R * _HALF / I_YAW  # rad/s^2


def _ramped(rate: float, accel: float, duration: float) -> float:
    """Distance (or angle) covered in `duration` s from rest, accelerating at `accel` up to `rate`."""
    ramp = rate / accel
    return rate * duration - 0.5 * rate * ramp if duration >= ramp else 0.5 * accel * duration**2


@pytest.fixture(scope="module")
def office() -> MapModel:
    return load_map(office_map_path())


def _robot(office: MapModel, start: Pose2D = START, **others: Pose2D) -> tuple[World, object]:
    world = World(office, {"r": start, **others}, camera=None)
    return world, world.bodies["r"]


def _in_frame(pose: Pose2D, origin: Pose2D) -> tuple[float, float, float]:
    """`pose` in the frame of `origin`: (along, across, yaw difference)."""
    dx, dy = pose.x - origin.x, pose.y - origin.y
    c, s = math.cos(origin.yaw), math.sin(origin.yaw)
    return c * dx + s * dy, -s * dx + c * dy, wrap_angle(pose.yaw - origin.yaw)


def test_the_reference_figures() -> None:
    # Guards the arithmetic above against an edit of the model constants going unnoticed.
    assert LINEAR_ACCEL == pytest.approx(2.954, abs=0.001)
    assert YAW_ACCEL == pytest.approx(22.54, abs=0.01)


@pytest.mark.parametrize("speed", [0.3, 0.5, mjcf.MAX_LINEAR_SPEED])
def test_straight_drive_covers_the_torque_limited_distance(office: MapModel, speed: float) -> None:
    world, body = _robot(office)
    body.set_velocity(speed, 0.0)
    world.step(3.0)
    along, across, dyaw = _in_frame(body.pose(), START)
    assert along == pytest.approx(_ramped(speed, LINEAR_ACCEL, 3.0), abs=POSITION_TOL)
    assert abs(across) < POSITION_TOL and abs(dyaw) < YAW_TOL
    _, v, w = body.odometry()
    assert v == pytest.approx(speed, abs=0.005) and abs(w) < 0.005


def test_a_command_above_the_limit_drives_at_max_linear_speed(office: MapModel) -> None:
    world, body = _robot(office)
    body.set_velocity(5.0, 0.0)
    world.step(1.0)
    first = body.pose()
    world.step(1.0)  # steady: exactly MAX_LINEAR_SPEED m in 1 s
    along, across, _ = _in_frame(body.pose(), first)
    assert along == pytest.approx(mjcf.MAX_LINEAR_SPEED, abs=POSITION_TOL)
    assert abs(across) < POSITION_TOL


@pytest.mark.parametrize("rate", [1.0, mjcf.MAX_ANGULAR_SPEED])
def test_turn_in_place_stays_in_place(office: MapModel, rate: float) -> None:
    world, body = _robot(office)
    body.set_velocity(0.0, rate)
    world.step(1.0)
    along, across, dyaw = _in_frame(body.pose(), START)
    assert math.hypot(along, across) < POSITION_TOL
    assert dyaw == pytest.approx(wrap_angle(_ramped(rate, YAW_ACCEL, 1.0)), abs=YAW_TOL)
    assert body.odometry()[2] == pytest.approx(rate, abs=0.01)


def test_an_arc_follows_its_circle(office: MapModel) -> None:
    speed, rate = 0.4, 0.8  # radius 0.5 m
    world, body = _robot(office)
    body.set_velocity(speed, rate)
    world.step(0.5)  # past the ramp
    first = body.pose()
    world.step(2.0)
    along, across, dyaw = _in_frame(body.pose(), first)
    radius, turned = speed / rate, rate * 2.0
    assert along == pytest.approx(radius * math.sin(turned), abs=POSITION_TOL)
    assert across == pytest.approx(radius * (1.0 - math.cos(turned)), abs=POSITION_TOL)
    assert dyaw == pytest.approx(turned, abs=YAW_TOL)


def test_stopping_takes_the_torque_limited_distance(office: MapModel) -> None:
    world, body = _robot(office)
    speed = mjcf.MAX_LINEAR_SPEED
    body.set_velocity(speed, 0.0)
    world.step(1.0)
    braking = body.pose()
    body.set_velocity(0.0, 0.0)
    world.step(1.0)
    along, across, dyaw = _in_frame(body.pose(), braking)
    assert along == pytest.approx(speed**2 / (2 * LINEAR_ACCEL), abs=POSITION_TOL)
    assert abs(across) < POSITION_TOL and abs(dyaw) < YAW_TOL
    _, v, w = body.odometry()
    assert abs(v) < 1e-3 and abs(w) < 1e-3


def test_a_wall_is_touched_when_the_chassis_reaches_it(office: MapModel) -> None:
    # Facing the west wall (inner face x = 0.1) from x = 0.9 at 0.3 m/s: the chassis edge has
    # 0.9 - 0.1 - CHASSIS_RADIUS m to go, reached after that distance / v plus half the ramp time.
    start, speed = Pose2D(0.9, 4.6, math.pi), 0.3
    world, body = _robot(office, start)
    body.set_velocity(speed, 0.0)
    expected = (0.9 - 0.1 - mjcf.CHASSIS_RADIUS) / speed + 0.5 * speed / LINEAR_ACCEL
    while not world.contacts_now("r") and world.time < 4.0:
        world.step(world.physics_dt)
    assert world.time == pytest.approx(expected, abs=0.02)
    assert world.collisions["r"] == 1
    world.step(1.0)  # pushing on: the wall holds
    assert world.contacts_now("r") and world.collisions["r"] == 1
    assert body.pose().x == pytest.approx(0.1 + mjcf.CHASSIS_RADIUS, abs=0.005)


def test_robots_meeting_head_on_touch_at_their_combined_radius(office: MapModel) -> None:
    world, body = _robot(office, Pose2D(3.0, 4.6, 0.0), b=Pose2D(4.0, 4.6, math.pi))
    speed = 0.3
    for b in world.bodies.values():
        b.set_velocity(speed, 0.0)
    expected = 0.5 * (1.0 - 2 * mjcf.CHASSIS_RADIUS) / speed + 0.5 * speed / LINEAR_ACCEL
    while not world.contacts_now("r") and world.time < 3.0:
        world.step(world.physics_dt)
    assert world.time == pytest.approx(expected, abs=0.02)
    assert world.contacts_now("b") and world.collisions == {"r": 1, "b": 1}


def test_every_tyre_and_caster_rests_on_the_floor_with_its_contact_parameters(office: MapModel) -> None:
    world, _ = _robot(office)
    world.step(0.1)
    m, d = world.model, world.data
    found = {}
    for k in range(d.ncon):
        names = {m.geom(int(g)).name for g in d.contact.geom[k]}
        if "floor" in names:
            (other,) = names - {"floor"}
            found[other] = d.contact[k]
    tyres = [mjcf.tyre_name("r", s) for s in ("left", "right")]
    casters = [mjcf.caster_name("r", w) for w in ("front", "back")]
    assert sorted(found) == sorted(tyres + casters)
    for name in tyres:
        assert found[name].dim == 3 and found[name].friction[0] == mjcf.WHEEL_FRICTION
        assert tuple(found[name].solref) == mjcf.WHEEL_SOLREF
    for name in casters:
        assert found[name].dim == 1 and tuple(found[name].solref) == mjcf.CASTER_SOLREF


def test_the_default_step_is_at_most_half_of_every_contact_time_constant(office: MapModel) -> None:
    # MuJoCo wants a contact's time constant at least twice the step (with refsafe on it silently raises
    # a shorter one to 2 * step: no longer the contact we chose). Every kind of contact a run makes:
    # tyres, casters, a chassis on a wall, a drone's feet on the floor.
    world = World(office, {"r": Pose2D(0.9, 4.6, math.pi), "drone": Pose2D(4.0, 3.0, 0.0)},
                  kinds={"drone": RobotKind.FLYING}, camera=None)
    assert world.physics_dt == mjcf.PHYSICS_DT == SimConfig().physics_dt <= mjcf.MAX_PHYSICS_DT
    for period in (0.05, 0.1):  # the control tick and odometry; the lidar: whole steps
        assert period / mjcf.PHYSICS_DT == round(period / mjcf.PHYSICS_DT)
    world.bodies["r"].set_velocity(0.3, 0.0)
    world.step(3.0)
    assert world.contacts_now("r")
    solrefs = {float(world.data.contact.solref[k][0]) for k in range(world.data.ncon)}
    assert len(solrefs) >= 2 and min(solrefs) >= 2 * mjcf.MAX_PHYSICS_DT
    with pytest.raises(ValueError, match="physics step"):
        SimConfig(physics_dt=mjcf.MAX_PHYSICS_DT + 1e-4, control_dt=0.05)
