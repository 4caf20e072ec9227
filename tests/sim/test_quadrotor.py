"""The quadrotor: its controller alone, then hover, a step, and landings on a TurtleBot's top plate."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rescuemesh.body import Body, FlightPhase, FlyingBody, LandingTarget, RobotKind
from rescuemesh.geometry import Pose2D
from rescuemesh.maps import MapModel, load_map, office_map_path
from rescuemesh.sim import SimBody, World, mjcf
from rescuemesh.sim.flight import (
    ZERO3,
    Autopilot,
    FlightState,
    LandingController,
    QuadrotorParams,
    allocation,
    mix,
)
from rescuemesh.sim.quadrotor import SimQuadrotor

FLIGHT_PY = Path(__file__).resolve().parents[2] / "src" / "rescuemesh" / "sim" / "flight.py"
LEVEL = (1.0, 0.0, 0.0, 0.0)  # quaternion (w, x, y, z) of a level drone facing +x


@pytest.fixture(scope="module")
def office() -> MapModel:
    return load_map(office_map_path())


def _drone_world(office: MapModel, drone: Pose2D, **ground: Pose2D) -> World:
    starts = {**ground, "drone": drone}
    return World(office, starts, kinds={"drone": RobotKind.FLYING})


def _hovering(office: MapModel, at=(3.0, 4.6, 1.2), **ground: Pose2D) -> tuple[World, SimQuadrotor]:
    world = _drone_world(office, Pose2D(at[0], at[1], 0.0), **ground)
    drone = world.bodies["drone"]
    drone.fly_to(*at)
    world.step(4.0)
    return world, drone


# ------------------------------------------------------------------ the controller without a simulator


def test_flight_module_runs_without_mujoco() -> None:
    # The file is loaded on its own (not through rescuemesh.sim, whose __init__ builds the World) in a
    # process where importing mujoco fails, and one control step is run.
    code = f"""
import importlib.util, sys
sys.modules["mujoco"] = None
spec = importlib.util.spec_from_file_location("flight", {str(FLIGHT_PY)!r})
flight = importlib.util.module_from_spec(spec)
sys.modules["flight"] = flight
spec.loader.exec_module(flight)
state = flight.FlightState((0.0, 0.0, 1.0), (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
thrusts = flight.FlightController().step(state, flight.Setpoint((0.0, 0.0, 1.0), 0.0), 0.005)
assert abs(sum(thrusts) - 0.5 * 9.81) < 1e-6, thrusts
assert not any(m == "mujoco" or m.startswith("mujoco.") for m in sys.modules if sys.modules[m] is not None)
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr


def test_flight_module_imports_through_its_package_without_mujoco() -> None:
    # this used to fail: rescuemesh/sim/__init__.py imported World (and so mujoco) eagerly
    code = "import sys; sys.modules['mujoco'] = None; import rescuemesh.sim.flight"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr


def test_mixer_gives_the_asked_wrench_and_yaw_gives_way_first() -> None:
    p = QuadrotorParams()
    a = np.linalg.inv(np.array(allocation(p)))  # thrusts -> (collective, torque x, y, z)
    for wrench in [(p.mass * 9.81, 0.0, 0.0, 0.0), (5.0, 0.05, -0.03, 0.01), (6.0, -0.1, 0.1, -0.02)]:
        f = mix(p, wrench[0], wrench[1:])
        assert a @ np.array(f) == pytest.approx(wrench, abs=1e-9)
    # Sign conventions: +x torque (left side up) loads the left rotors (y > 0): rotors 2 and 3.
    f = mix(p, 4.0, (0.05, 0.0, 0.0))
    assert f[1] > 1.0 > f[0] and f[2] > 1.0 > f[3]
    # Saturated: near-full collective with a large yaw torque keeps the collective, roll and pitch, and
    # gets as much yaw as fits (some rotor at a limit), not none.
    collective = 4 * p.max_rotor_thrust * 0.95
    f = mix(p, collective, (0.0, 0.01, 0.05))
    wrench = a @ np.array(f)
    assert all(0.0 <= v <= p.max_rotor_thrust for v in f) and max(f) == pytest.approx(p.max_rotor_thrust)
    assert wrench[:3] == pytest.approx((collective, 0.0, 0.01), abs=1e-9) and 0.001 < wrench[3] < 0.05
    # this used to drop the yaw whole, so a drone asked to turn 1.5 rad at hover never turned
    f = mix(p, p.mass * 9.81, (0.0, 0.0, 0.1))
    assert min(f) == pytest.approx(0.0) and (a @ np.array(f))[3] == pytest.approx(0.075, abs=0.001)


def _descending(target: LandingTarget) -> tuple[LandingController, float]:
    """A LandingController stepped over a static target at cruise altitude until it DESCENDs."""
    above = FlightState((target.x, target.y, 1.2), ZERO3, LEVEL, ZERO3)
    landing, now = LandingController(target, 0.0, above), 0.0
    while landing.phase is not FlightPhase.DESCEND and now < 5.0:
        landing.step(now, above, False, 0.005)
        now += 0.005
    return landing, now


def test_landing_goes_around_when_the_target_jumps_away() -> None:
    # Pure state machine: FLY -> ALIGN at once (over the target at altitude), DESCEND after the 0.4 s
    # hold; then an estimate 0.3 m off sends it back to ALIGN instead of down beside the robot.
    landing, now = _descending(LandingTarget(0.0, 0.0, 0.4))
    assert now == pytest.approx(0.41, abs=0.011)
    landing.update_target(LandingTarget(0.3, 0.0, 0.4), now)
    cmd = landing.step(now, FlightState((0.0, 0.0, 0.9), ZERO3, LEVEL, ZERO3), False, 0.005)
    assert landing.phase is FlightPhase.ALIGN and cmd.setpoint.position == pytest.approx((0.3, 0.0, 1.2))


def test_touchdown_cuts_the_rotors_and_lands_once_the_contact_holds() -> None:
    landing, now = _descending(LandingTarget(0.0, 0.0, 0.4))
    on_top = FlightState((0.0, 0.0, 0.46), (0.0, 0.0, -0.2), LEVEL, ZERO3)
    cmd = landing.step(now, on_top, True, 0.005)  # feet touch
    assert cmd.phase is FlightPhase.TOUCHDOWN and cmd.thrusts == (0.0, 0.0, 0.0, 0.0) and cmd.setpoint is None
    for _ in range(round(0.3 / 0.005)):
        now += 0.005
        cmd = landing.step(now, on_top, True, 0.005)
    assert cmd.phase is FlightPhase.LANDED and cmd.thrusts == (0.0, 0.0, 0.0, 0.0)
    # Without a contact signal, feet within 1.5 cm of the top at low vertical speed count too.
    landing, now = _descending(LandingTarget(0.0, 0.0, 0.4))
    def phase_at(z: float, vz: float) -> FlightPhase:
        return landing.step(now, FlightState((0.0, 0.0, z), (0.0, 0.0, vz), LEVEL, ZERO3), False, 0.005).phase

    assert phase_at(0.48, -0.1) is FlightPhase.DESCEND  # feet 2 cm up
    assert phase_at(0.47, -0.5) is FlightPhase.DESCEND  # 1 cm up but falling fast: not yet
    assert phase_at(0.47, -0.1) is FlightPhase.TOUCHDOWN


# ------------------------------------------------------------------ the world


def test_world_with_a_flying_robot(office: MapModel) -> None:
    world = World(office, {**office.starts, "robot_4": Pose2D(3.0, 6.0, 0.5)}, kinds={"robot_4": RobotKind.FLYING})
    drone, ground = world.bodies["robot_4"], world.bodies["robot_1"]
    assert isinstance(drone, SimQuadrotor) and isinstance(drone, FlyingBody) and isinstance(drone, Body)
    assert isinstance(ground, SimBody) and not isinstance(ground, FlyingBody)
    assert (drone.kind, ground.kind) == (RobotKind.FLYING, RobotKind.GROUND)
    assert world.kinds["robot_4"] is RobotKind.FLYING and world.kinds["robot_2"] is RobotKind.GROUND
    assert ground.top_height == mjcf.PLATE_TOP and drone.top_height is None
    assert drone.scan() is None and ground.scan() is not None
    assert world.collisions == {"robot_1": 0, "robot_2": 0, "robot_3": 0, "robot_4": 0}
    world.step(1.0)
    # At rest on the floor, rotors off: a twist (the brain's every-tick call) or a hold (a Stop) does
    # not take off.
    drone.set_velocity(0.5, 0.3)
    drone.hold()
    world.step(0.5)
    assert drone.flight_phase() is FlightPhase.OFF and drone.thrusts == (0.0, 0.0, 0.0, 0.0)
    assert drone.position_3d() == pytest.approx((3.0, 6.0, 0.06), abs=2e-3) and drone.touching()
    assert drone.landed_on() is None  # on the floor, not on a robot
    assert drone.pose().yaw == pytest.approx(0.5, abs=1e-3)
    assert world.collisions["robot_4"] == 0  # resting on its feet is no collision


def test_bad_kinds(office: MapModel) -> None:
    with pytest.raises(ValueError, match="kinds"):
        World(office, office.starts, kinds={"robot_9": RobotKind.FLYING})
    with pytest.raises(ValueError, match="kinds"):
        World(office, office.starts, kinds={"robot_1": "flying"})  # type: ignore[dict-item]


def test_hover_holds_position(office: MapModel) -> None:
    world, drone = _hovering(office)
    assert drone.flight_phase() is FlightPhase.HOLD
    errors = []
    for _ in range(100):  # 2 s after 4 s of take-off and settling
        world.step(0.02)
        errors.append(math.dist(drone.position_3d(), (3.0, 4.6, 1.2)))
    assert max(errors) < 0.05  # measured: 1 mm
    assert sum(drone.thrusts) == pytest.approx(0.5 * 9.81, rel=0.01)  # hovering on its weight
    assert max(abs(v) for v in drone.velocity_3d()) < 0.02
    drone.fly_to(3.0, 4.6, 1.2, yaw=1.5)  # turn on the spot (yaw by the rotors' drag torques)
    world.step(3.0)
    assert drone.pose().yaw == pytest.approx(1.5, abs=0.02)
    assert math.dist(drone.position_3d(), (3.0, 4.6, 1.2)) < 0.05


def test_integrator_trims_a_mass_error(office: MapModel) -> None:
    # The autopilot believes the drone 10 % lighter than it is: the velocity integrator makes up the
    # thrust (without it the hover would sag by 9 cm).
    world = _drone_world(office, Pose2D(3.0, 4.6, 0.0))
    drone = world.bodies["drone"]
    drone.autopilot = Autopilot(QuadrotorParams(mass=0.45))
    drone.fly_to(3.0, 4.6, 1.2)
    world.step(8.0)
    assert math.dist(drone.position_3d(), (3.0, 4.6, 1.2)) < 0.02


def test_one_metre_step_settles_without_much_overshoot(office: MapModel) -> None:
    world, drone = _hovering(office)
    drone.fly_to(4.0, 4.6, 1.2)
    xs, zs = [], []
    for _ in range(300):  # 3 s
        world.step(0.01)
        x, _, z = drone.position_3d()
        xs.append(x - 3.0)
        zs.append(z)
    settled = next(i for i in range(len(xs)) if all(abs(x - 1.0) < 0.05 for x in xs[i:])) * 0.01
    assert settled < 2.0  # measured: 1.3 s to within 5 cm
    assert max(xs) - 1.0 < 0.1  # measured: 2.7 cm overshoot
    assert max(abs(z - 1.2) for z in zs) < 0.05  # altitude held while tilting (measured: 3.5 mm)
    assert abs(xs[-1] - 1.0) < 0.02 and drone.flight_phase() is FlightPhase.HOLD


def test_twist_moves_at_the_held_altitude(office: MapModel) -> None:
    world, drone = _hovering(office)
    drone.set_velocity(0.5, 0.0)  # 0.5 m/s along +x (the drone faces +x)
    world.step(2.0)
    x, y, z = drone.position_3d()
    assert x - 3.0 == pytest.approx(1.0, abs=0.1) and abs(y - 4.6) < 0.02 and abs(z - 1.2) < 0.03
    assert drone.odometry()[1] == pytest.approx(0.5, abs=0.05)
    drone.set_velocity(0.0, 0.0)  # ends the twist: hover
    world.step(2.0)
    assert max(abs(v) for v in drone.velocity_3d()) < 0.02
    drone.fly_to(3.0, 4.6)
    drone.set_velocity(0.0, 0.0)  # a zero twist does not cancel a fly_to
    world.step(3.0)
    assert math.dist(drone.position_3d(), (3.0, 4.6, 1.2)) < 0.05


def _land(world: World, ground: str, speed: float, carry_m: float = 0.0, limit_s: float = 30.0) -> dict:
    """Drive `ground` straight at `speed` m/s and land the drone on it, the target estimate coming as
    2 Hz PoseUpdates would (pose, and velocity from the last two); then carry for `carry_m` m."""
    robot, drone = world.bodies[ground], world.bodies["drone"]
    last, last_t, sent = robot.pose(), world.time, False
    out: dict = {}
    while world.time < limit_s:
        robot.set_velocity(speed, 0.0)
        if not sent or world.time - last_t >= 0.5 - 1e-9:
            pose, dt = robot.pose(), world.time - last_t
            v = ((pose.x - last.x) / dt, (pose.y - last.y) / dt) if dt > 0 else (0.0, 0.0)
            drone.land_on(LandingTarget(pose.x, pose.y, robot.top_height, *v))
            last, last_t, sent = pose, world.time, True
        world.step(0.05)
        if "landed_s" not in out and drone.flight_phase() is FlightPhase.LANDED:
            out.update(landed_s=world.time, offset=world.top_offset("drone", ground), on=drone.landed_on(),
                       thrusts=drone.thrusts, robot_at=robot.pose(), drone_at=drone.position_3d())
        if "landed_s" in out and robot.pose().distance_to(out["robot_at"]) >= carry_m:
            return out
    raise AssertionError(f"no landing in {limit_s} s: phase {drone.flight_phase()}")


def test_rotors_off_in_the_air_drops_it_but_not_a_touchdown(office: MapModel) -> None:
    world, drone = _hovering(office, at=(4.0, 6.5, 1.2))
    drone.rotors_off()
    world.step(1.0)
    assert drone.flight_phase() is FlightPhase.OFF and drone.position_3d()[2] == pytest.approx(0.06, abs=0.01)
    world = _drone_world(office, Pose2D(5.0, 6.5, 0.0), robot_2=Pose2D(4.0, 4.6, 0.0))
    drone, robot = world.bodies["drone"], world.bodies["robot_2"]
    drone.land_on(LandingTarget(4.0, 4.6, robot.top_height))
    while drone.flight_phase() is not FlightPhase.TOUCHDOWN and world.time < 12.0:
        world.step(0.005)
    drone.rotors_off()  # a brain that cuts the rotors on its own touchdown signal: the landing completes
    world.step(0.5)
    assert drone.flight_phase() is FlightPhase.LANDED and drone.landed_on() == "robot_2"


def test_lands_on_a_static_turtlebot(office: MapModel) -> None:
    world = _drone_world(office, Pose2D(5.0, 6.5, 0.0), robot_2=Pose2D(4.0, 4.6, 0.0))
    out = _land(world, "robot_2", 0.0)
    drone = world.bodies["drone"]
    assert out["on"] == "robot_2" and out["offset"] < 0.08  # measured: 0.0 mm
    assert out["thrusts"] == (0.0, 0.0, 0.0, 0.0) and out["landed_s"] < 12.0  # measured: 6.9 s from the floor
    assert drone.position_3d()[2] == pytest.approx(0.40 + 0.06, abs=0.005)  # feet on the TurtleBot 2's 0.40 m plate
    world.step(3.0)  # stays there, rotors off, and it was never a collision
    assert drone.landed_on() == "robot_2" and drone.flight_phase() is FlightPhase.LANDED
    assert world.top_offset("drone", "robot_2") == pytest.approx(out["offset"], abs=0.002)
    assert drone.thrusts == (0.0, 0.0, 0.0, 0.0) and world.collisions == {"robot_2": 0, "drone": 0}
    drone.land_on(LandingTarget(9.0, 9.0, 0.4))  # a new estimate after landing is ignored
    drone.set_velocity(0.3, 0.0)  # and so is a twist: rotors stay off
    drone.hold()  # and a hold (what a Stop does)
    world.step(0.5)
    assert drone.flight_phase() is FlightPhase.LANDED and drone.thrusts == (0.0, 0.0, 0.0, 0.0)


def test_lands_on_a_moving_turtlebot_and_is_carried(office: MapModel) -> None:
    world = _drone_world(office, Pose2D(1.5, 6.0, 1.0), robot_2=Pose2D(1.0, 4.6, 0.0))
    out = _land(world, "robot_2", 0.25, carry_m=2.0)
    drone, robot = world.bodies["drone"], world.bodies["robot_2"]
    assert out["on"] == "robot_2" and out["offset"] < 0.08  # measured: 0.4 mm
    assert out["thrusts"] == (0.0, 0.0, 0.0, 0.0) and out["landed_s"] < 12.0  # measured: 6.2 s
    # Carried: 2 m later it is still on the plate, where it was, and moved as the robot did.
    assert drone.landed_on() == "robot_2" and drone.flight_phase() is FlightPhase.LANDED
    assert world.top_offset("drone", "robot_2") == pytest.approx(out["offset"], abs=0.01)
    moved = np.subtract(drone.position_3d()[:2], out["drone_at"][:2])
    assert np.hypot(*moved) >= 2.0
    assert moved == pytest.approx((robot.pose().x - out["robot_at"].x, robot.pose().y - out["robot_at"].y), abs=0.01)
    robot.set_velocity(0.0, 0.0)  # a sharp stop: friction holds it
    world.step(1.0)
    assert drone.landed_on() == "robot_2" and world.top_offset("drone", "robot_2") < 0.08
    assert world.collisions == {"robot_2": 0, "drone": 0}


def test_same_inputs_give_identical_flights(office: MapModel) -> None:
    def run(chunk: float) -> np.ndarray:
        world = _drone_world(office, Pose2D(3.0, 6.0, 0.0), robot_2=Pose2D(3.0, 4.6, 0.0))
        world.bodies["drone"].fly_to(3.5, 5.0)
        for _ in range(round(2.0 / chunk)):
            world.bodies["robot_2"].set_velocity(0.2, 0.1)
            world.step(chunk)
        return world.data.qpos.copy()

    assert np.array_equal(run(0.05), run(0.1))
