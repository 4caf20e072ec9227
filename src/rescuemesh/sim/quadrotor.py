"""A simulated quadrotor: its MJCF (an X frame with four thrust rotors and four feet) and its FlyingBody.

Owns: the drone's geometry, element names and contact filtering; reading its state from MuJoCo and
writing rotor thrusts; which robot's top its feet rest on. Must not know: the control law (flight.py,
which imports no mujoco), when the world steps (the World calls `control` before every physics step),
any brain.

Rotors: a `motor` actuator on a site at each rotor hub, with gear "0 0 1 0 0 +-k": the control is the
rotor's thrust in N along the body z axis, and the same actuator applies the rotor's drag torque k * thrust
about body z, negative for a counter-clockwise rotor (the trick of MuJoCo Menagerie's Skydio X2).
Thrust is instantaneous (no motor lag) and there is no aerodynamic drag, ground effect or downwash.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from xml.sax.saxutils import quoteattr

import mujoco

from rescuemesh.body import FlightPhase, FlyingBody, LandingTarget, LaserScan
from rescuemesh.geometry import Pose2D
from rescuemesh.sim import mjcf
from rescuemesh.sim.flight import Autopilot, FlightGains, FlightState, LandingConfig, QuadrotorParams, yaw_of

PARAMS = QuadrotorParams()
PROP_RADIUS = 0.0635  # m, a 5-inch propeller (the size a 250-class frame carries)
HULL_HALF = (0.05, 0.035, 0.02)  # m, half sizes of the centre box (flight controller, battery)
ARM_RADIUS = 0.007  # m
ROTOR_HEIGHT = 0.025  # m above the centre of mass: the propeller plane
FOOT_RADIUS = 0.01  # m
FOOT_SPREAD = 0.055  # m: feet at (+-FOOT_SPREAD, +-FOOT_SPREAD), 0.078 m from the centre (inside a 0.16 m plate)
FOOT_FRICTION = 1.0  # rubber feet
DRONE_RGBA = (0.1, 0.45, 0.95, 1.0)  # blue, unlike the orange TurtleBots


def gear_name(robot: str) -> str:
    """The landing-gear body (feet and legs), a child of the base so its contacts are told apart."""
    return f"{robot}/gear"


def rotor_name(robot: str, i: int) -> str:
    """Rotor i (1..4) site and actuator."""
    return f"{robot}/rotor_{i}"


def feet_sensor_name(robot: str) -> str:
    return f"{robot}/feet"


def quadrotor_part(name: str, start: Pose2D, params: QuadrotorParams = PARAMS) -> mjcf.Part:
    """MJCF of one quadrotor resting on the floor at `start`, rotors off."""
    f, q = mjcf._f, quoteattr
    geom = f'contype="{mjcf.FLYER_CONTYPE}" conaffinity="{mjcf.FLYER_BIT}" mass="0" group="0"'
    rgba = f'rgba="{f(*DRONE_RGBA)}"'
    rotors = params.rotors
    arms = "\n".join(
        f'      <geom name={q(f"{name}/arm_{i}")} type="capsule" size="{ARM_RADIUS}"'
        f' fromto="{f(0, 0, 0, x, y, 0)}" {geom} {rgba}/>\n'
        f'      <geom name={q(f"{name}/motor_{i}")} type="cylinder" size="{f(0.014, 0.012)}"'
        f' pos="{f(x, y, 0.008)}" {geom} rgba="0.15 0.15 0.15 1"/>\n'
        f'      <geom name={q(f"{name}/prop_{i}")} type="cylinder" size="{f(PROP_RADIUS, 0.002)}"'
        f' pos="{f(x, y, ROTOR_HEIGHT)}" {geom} rgba="0.8 0.8 0.8 0.35"/>\n'
        f'      <site name={q(rotor_name(name, i))} pos="{f(x, y, ROTOR_HEIGHT)}" size="0.005"/>'
        for i, (x, y, _) in enumerate(rotors, start=1)
    )
    foot_z = -(params.gear_height - FOOT_RADIUS)
    feet = []
    for i, (sx, sy) in enumerate(((1, 1), (-1, 1), (-1, -1), (1, -1)), start=1):
        fx, fy = sx * FOOT_SPREAD, sy * FOOT_SPREAD
        feet.append(
            f'        <geom type="capsule" size="0.004" fromto="{f(0.6 * fx, 0.6 * fy, -HULL_HALF[2], fx, fy, foot_z)}"'
            f' contype="0" conaffinity="0" mass="0" group="0" rgba="0.15 0.15 0.15 1"/>\n'
            f'        <geom name={q(f"{name}/foot_{i}")} type="sphere" size="{FOOT_RADIUS}" pos="{f(fx, fy, foot_z)}"'
            f' {geom} condim="3" friction="{FOOT_FRICTION} 0.005 0.0001" rgba="0.1 0.1 0.1 1"/>'
        )
    qw, qz = math.cos(0.5 * start.yaw), math.sin(0.5 * start.yaw)
    placement = f'pos="{f(start.x, start.y, params.gear_height)}" quat="{f(qw, 0, 0, qz)}"'
    body = f"""    <body name={q(mjcf.base_name(name))} {placement}>
      <freejoint name={q(f"{name}/root")}/>
      <inertial pos="0 0 0" mass="{params.mass}" diaginertia="{f(*params.inertia)}"/>
      <geom name={q(f"{name}/hull")} type="box" size="{f(*HULL_HALF)}" {geom} {rgba}/>
{arms}
      <body name={q(gear_name(name))}>
{chr(10).join(feet)}
      </body>
    </body>"""
    hi = params.max_rotor_thrust
    actuators = "\n".join(
        f'    <motor name={q(rotor_name(name, i))} site={q(rotor_name(name, i))} ctrlrange="{f(0.0, hi)}"'
        f' gear="{f(0, 0, 1, 0, 0, spin * params.yaw_moment)}"/>'
        for i, (_, _, spin) in enumerate(rotors, start=1)
    )
    # Bump: the frame (hull, arms, motors, propellers) touches anything. Feet: the gear touches anything.
    bump = f'    <contact name={q(mjcf.bump_sensor_name(name))} body1={q(mjcf.base_name(name))} data="found" num="1"/>'
    sensors = f'    <contact name={q(feet_sensor_name(name))} body1={q(gear_name(name))} data="found" num="1"/>'
    return mjcf.Part(body=body, actuators=actuators, bump=bump, sensors=sensors)


class SimQuadrotor(FlyingBody):
    """One quadrotor in a World, flown by a `flight.Autopilot` that runs before every physics step.

    State for the autopilot is ground truth (as a motion-capture system or a good EKF would give);
    `touching` is the feet's contact sensor. `landed_on` reads the contact list for a top plate.
    """

    max_linear_speed: float = FlightGains().max_speed_xy  # m/s, horizontal
    max_angular_speed: float = math.pi / 2  # rad/s, yaw
    radius: float = PARAMS.arm_length + PROP_RADIUS  # m, to the propeller tips
    cruise_altitude: float = LandingConfig().cruise_altitude  # m

    def __init__(self, name: str, model: mujoco.MjModel, data: mujoco.MjData, clock: Callable[[], float],
                 physics_dt: float, plates: Mapping[int, str], autopilot: Autopilot | None = None) -> None:
        """`clock`: the world's time in s; `plates`: top plate geom id -> name of the robot it tops."""
        self.name = name
        self._data = data
        self._clock = clock
        self._dt = physics_dt
        self._plates = dict(plates)
        root = model.joint(f"{name}/root").id
        self._qpos = int(model.jnt_qposadr[root])
        self._qvel = int(model.jnt_dofadr[root])
        ids = [model.actuator(rotor_name(name, i)).id for i in range(1, 5)]
        if ids != list(range(ids[0], ids[0] + 4)):
            raise RuntimeError(f"{name}: rotor actuators are not contiguous")  # guards the slice in control()
        self._ctrl = slice(ids[0], ids[0] + 4)
        self._feet_adr = int(model.sensor_adr[model.sensor(feet_sensor_name(name)).id])
        gear = model.body(gear_name(name)).id
        self._feet = frozenset(
            int(g) for g in range(model.ngeom) if model.geom_bodyid[g] == gear and model.geom_contype[g]
        )
        self.body_id: int = model.body(mjcf.base_name(name)).id
        self.autopilot = autopilot or Autopilot(PARAMS)
        self._live = False  # rotor commands may be non-zero
        self.cruise_altitude = self.autopilot.landing_config.cruise_altitude

    # ------------------------------------------------------------ for the World

    def control(self, now: float) -> None:
        """One autopilot step at `now` s: rotor thrusts for the next physics step (called by the World)."""
        if self.autopilot.idle:  # rotors off, nothing to fly: zero them once, then skip the state read
            if self._live:
                self._data.ctrl[self._ctrl] = 0.0
                self._live = False
            return
        touching = self._data.sensordata[self._feet_adr] > 0.0
        self._data.ctrl[self._ctrl] = self.autopilot.step(now, self.state(), touching, self._dt)
        self._live = True

    def commit_odometry(self) -> None:
        """Nothing to commit: odometry is the (visual-inertial, here true) state itself."""

    def state(self) -> FlightState:
        q = self._data.qpos[self._qpos : self._qpos + 7].tolist()
        v = self._data.qvel[self._qvel : self._qvel + 6].tolist()
        return FlightState((q[0], q[1], q[2]), (v[0], v[1], v[2]), (q[3], q[4], q[5], q[6]), (v[3], v[4], v[5]))

    @property
    def thrusts(self) -> tuple[float, float, float, float]:
        """Rotor thrust commands in N (rotors 1..4) for the coming physics step; all 0 with the rotors off."""
        return tuple(self._data.ctrl[self._ctrl].tolist())  # type: ignore[return-value]

    def touching(self) -> bool:
        """True while the feet touch anything (floor, a plate, a wall)."""
        return bool(self._data.sensordata[self._feet_adr] > 0.0)

    # ------------------------------------------------------------ Body

    def pose(self) -> Pose2D:
        """Ground-truth pose projected on the floor: x, y in m, yaw of the body x axis in rad."""
        q = self._data.qpos[self._qpos : self._qpos + 7].tolist()
        return Pose2D(q[0], q[1], yaw_of((q[3], q[4], q[5], q[6])))

    def odometry(self) -> tuple[Pose2D, float, float]:
        """(pose, horizontal speed along the heading in m/s, yaw rate about the map z axis in rad/s)."""
        s = self.state()
        pose = self.pose()
        w, x, y, z = s.quaternion
        wx, wy, wz = s.angular_velocity
        yaw_rate = 2 * (x * z - w * y) * wx + 2 * (y * z + w * x) * wy + (1 - 2 * (x * x + y * y)) * wz  # (R omega)_z
        return pose, s.velocity[0] * math.cos(pose.yaw) + s.velocity[1] * math.sin(pose.yaw), yaw_rate

    def scan(self) -> LaserScan | None:
        """No lidar on the drone."""
        return None

    def set_velocity(self, linear: float, angular: float) -> None:
        """A planar twist at the held altitude (see FlyingBody): clamped; (0, 0) ends only a twist; ignored
        with the rotors off. Raises ValueError for a non-finite command."""
        if not (math.isfinite(linear) and math.isfinite(angular)):
            raise ValueError(f"{self.name}: velocity command must be finite, got ({linear}, {angular})")
        v = min(max(float(linear), -self.max_linear_speed), self.max_linear_speed)
        w = min(max(float(angular), -self.max_angular_speed), self.max_angular_speed)
        self.autopilot.twist(v, w, self.state())

    # ------------------------------------------------------------ FlyingBody

    def position_3d(self) -> tuple[float, float, float]:
        return self.state().position

    def velocity_3d(self) -> tuple[float, float, float]:
        return self.state().velocity

    def flight_phase(self) -> FlightPhase:
        return self.autopilot.phase

    def fly_to(self, x: float, y: float, z: float | None = None, yaw: float | None = None) -> None:
        z = self.cruise_altitude if z is None else z
        if not all(math.isfinite(v) for v in (x, y, z)) or (yaw is not None and not math.isfinite(yaw)):
            raise ValueError(f"{self.name}: fly_to needs finite numbers, got ({x}, {y}, {z}, {yaw})")
        self.autopilot.fly_to((float(x), float(y), float(z)), yaw, self.state())

    def land_on(self, target: LandingTarget) -> None:
        if not all(math.isfinite(v) for v in (target.x, target.y, target.z, target.vx, target.vy)):
            raise ValueError(f"{self.name}: landing target must be finite, got {target}")
        self.autopilot.land_on(target, self._clock(), self.state())

    def hold(self) -> None:
        self.autopilot.hold(self.state())

    def rotors_off(self) -> None:
        self.autopilot.rotors_off()
        self._data.ctrl[self._ctrl] = 0.0

    def landed_on(self) -> str | None:
        """The robot whose top plate a foot touches now (after the last step), or None."""
        d = self._data
        if d.ncon == 0 or d.sensordata[self._feet_adr] <= 0.0:
            return None
        for g1, g2 in d.contact.geom[: d.ncon].tolist():
            if g1 in self._feet and g2 in self._plates:
                return self._plates[g2]
            if g2 in self._feet and g1 in self._plates:
                return self._plates[g1]
        return None
