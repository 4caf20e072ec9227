"""The MJCF text of a simulated office: floor, wall boxes and TurtleBot 2-like robots (Kobuki base).

Owns: robot dimensions and masses, contact filtering, geom groups, solver options, element names.
Must not know: how the world is stepped, sensed or commanded (see world.py, body.py, lidar.py).

Contacts: each tyre and caster touches the floor through an explicit <pair> and nothing else (their
contype and conaffinity are 0, so the collision broadphase never looks at them). Filtering
(contype/conaffinity bits) covers the rest: bit 1 = the floor (for flyers), bit 2 = body contacts
(chassis against walls and other chassis). So wheels and casters never touch walls or each other, and
a chassis never touches the floor: the only chassis contacts are collisions. Geom group 3 holds the
floor, wheels and casters; the lidar masks it off.
Bit 4 = tops (a TurtleBot's top plate, touched only by what lands on it) and bit 8 = flyers (see
quadrotor.py: a drone touches the floor, walls, chassis, tops and other drones through FLYER_CONTYPE).
Other parts (quadrotors) come in as `Part`s of MJCF text, so this module need not know them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

from rescuemesh.geometry import Pose2D
from rescuemesh.maps.model import MapModel

# TurtleBot 2 / Kobuki figures (Kobuki user guide, TurtleBot 2 specification).
CHASSIS_RADIUS = 0.177  # m, footprint radius (0.354 m diameter)
CHASSIS_BOTTOM = 0.015  # m above the floor
CHASSIS_TOP = 0.26  # m above the floor: Kobuki base (0.1 m) plus the plate stack up to the lidar plate
WHEEL_RADIUS = 0.035  # m
WHEEL_SEPARATION = 0.23  # m between the wheel contact points
CASTER_RADIUS = 0.015  # m
CASTER_OFFSET = 0.13  # m, front and back casters on the x axis
BASE_MASS = 3.6  # kg, chassis and plates (wheels add 2 x WHEEL_MASS)
BASE_COM_HEIGHT = 0.09  # m above the floor, over the axle (heavy battery and motors low down)
WHEEL_MASS = 0.15  # kg
MAX_LINEAR_SPEED = 0.7  # m/s
MAX_ANGULAR_SPEED = math.pi  # rad/s (180 deg/s)
# Wheel speed needed at both limits at once, in rad/s.
MAX_WHEEL_SPEED = (MAX_LINEAR_SPEED + MAX_ANGULAR_SPEED * WHEEL_SEPARATION / 2) / WHEEL_RADIUS

# Wheel motor: velocity servo torque = WHEEL_KV * (commanded - actual wheel speed), in N m,
# saturated at WHEEL_MAX_TORQUE (below the traction limit, so the wheels do not spin out).
WHEEL_KV = 0.6  # N m per rad/s
WHEEL_MAX_TORQUE = 0.25  # N m
WHEEL_FRICTION = 1.0  # sliding friction coefficient of the tyres on the floor
WHEEL_ARMATURE = 0.0005  # kg m^2, reflected inertia of motor and gearbox at the wheel
# Tyre-floor contact: time constant in s and damping ratio. Until the explicit <pair>s, MuJoCo mixed the
# tyre geom's (0.01, 1) with the floor's default (0.02, 1) by their solmix-weighted mean (MuJoCo docs,
# Computation > Contact parameters), so every run drove on (0.015, 1); the pair keeps that value.
WHEEL_SOLREF = (0.015, 1.0)
# Casters: frictionless (condim 1) with MuJoCo's default solref, as they were with priority="1".
CASTER_SOLREF = (0.02, 1.0)
# Physics step: MuJoCo wants a contact's time constant at least twice the timestep, or the contact
# goes unstable; with the refsafe flag (on by default) it silently raises a shorter one to 2 * timestep
# (MuJoCo docs, Modeling > Solver parameters, and XML reference, option/flag refsafe). The tyres' 15 ms
# is the shortest here (quadrotor.py keeps MuJoCo's default 20 ms), so the step may be up to 7.5 ms.
MAX_PHYSICS_DT = 0.5 * min(WHEEL_SOLREF[0], CASTER_SOLREF[0])  # s
# The default step: 8 to the 50 ms control tick and odometry period, 16 to the 100 ms lidar period, 20 %
# below MAX_PHYSICS_DT and exact in binary (docs/physics.md; it was 5 ms, 10 a tick).
PHYSICS_DT = 0.00625  # s

# Forward RGB camera (sim/camera.py; docs/sensors.md). A TurtleBot 2 carries a Kinect (57 x 43 deg,
# Microsoft "Kinect for Windows Sensor Components and Specifications") or an Orbbec Astra (60 x 49.5
# deg) with its optical centre 0.287 m above base_link (turtlebot_description, REP 119), about 0.30 m
# above the floor. Ours sits at that height but at the front edge, so no part of the robot is in view.
CAMERA_FOV_H = math.radians(58.0)  # rad, horizontal field of view
CAMERA_X = 0.15  # m ahead of the base centre
CAMERA_HEIGHT = 0.30  # m above the floor
CAMERA_FOVY_4_3 = 2.0 * math.degrees(math.atan(math.tan(0.5 * CAMERA_FOV_H) * 3.0 / 4.0))  # deg, at 4:3
ROBOT_RGBA = (0.9, 0.45, 0.1, 1.0)  # high-visibility orange, so robots stand out in camera images

# The top plate of a TurtleBot 2 (its fourth plate, above the Kinect), where a drone lands. TurtleBot 2
# specification: 354 x 354 x 420 mm overall, so the top plate's upper face is at about 0.4 m. It is a
# thin disc of the plates' size held by standoffs; it has no mass of its own (BASE_MASS includes it).
PLATE_TOP = 0.40  # m above the floor, the upper face
PLATE_THICKNESS = 0.006  # m
PLATE_RADIUS = 0.16  # m
PLATE_FRICTION = 1.0  # sliding friction coefficient (MuJoCo takes the larger of the two geoms')

LIDAR_GEOM_GROUPS = (1, 1, 1, 0, 0, 0)  # geom groups the lidar sees: everything but group 3
HIDDEN_GROUP = 3
GROUND_BIT = 1  # wheels, casters (and flyers) against the floor
BODY_BIT = 2  # chassis (and flyers) against walls and chassis
TOP_BIT = 4  # flyers against tops
FLYER_BIT = 8  # flyers against flyers
FLYER_CONTYPE = GROUND_BIT | BODY_BIT | TOP_BIT | FLYER_BIT  # contype of a flyer's geoms; conaffinity FLYER_BIT
_HIDDEN_GROUP = HIDDEN_GROUP
_GROUND_BIT = GROUND_BIT
_BODY_BIT = BODY_BIT


def wall_name(index: int) -> str:
    """Name of the geom of `MapModel.walls[index]`."""
    return f"wall_{index}"


def base_name(robot: str) -> str:
    return f"{robot}/base"


def chassis_name(robot: str) -> str:
    return f"{robot}/chassis"


def wheel_name(robot: str, side: str) -> str:
    """Name of the wheel joint and of its actuator; side is 'left' or 'right'."""
    return f"{robot}/wheel_{side}"


def tyre_name(robot: str, side: str) -> str:
    """Name of a wheel's tyre geom; side is 'left' or 'right'."""
    return f"{robot}/tyre_{side}"


def caster_name(robot: str, where: str) -> str:
    """Name of a caster geom; where is 'front' or 'back'."""
    return f"{robot}/caster_{where}"


def bump_sensor_name(robot: str) -> str:
    return f"{robot}/bump"


def plate_name(robot: str) -> str:
    """Name of a TurtleBot's top plate geom."""
    return f"{robot}/plate"


@dataclass(frozen=True)
class Part:
    """MJCF text of something added to the world beside the TurtleBots: a body for <worldbody>, its
    <actuator> and <sensor> entries. Its bump sensor (one per robot, named `bump_sensor_name`) goes in
    `bump`, so the World finds every robot's bump sensor in one contiguous run."""

    body: str
    actuators: str = ""
    bump: str = ""
    sensors: str = ""


def camera_name(robot: str) -> str:
    return f"{robot}/camera"


def _f(*values: float) -> str:
    return " ".join(f"{v:.10g}" for v in values)


def world_xml(map_model: MapModel, starts: Mapping[str, Pose2D], physics_dt: float, parts: Sequence[Part] = ()) -> str:
    """MJCF of the map's walls (height `map_model.wall_height` m), one TurtleBot per start pose, then `parts`.

    The bump sensors are the TurtleBots' in the order of `starts`, then the parts' in their order.
    """
    b = map_model.bounds
    cx, cy = 0.5 * (b.x_min + b.x_max), 0.5 * (b.y_min + b.y_max)
    h = map_model.wall_height
    walls = "\n".join(
        f'    <geom name="{wall_name(i)}" class="wall"'
        f' pos="{_f(0.5 * (w.x_min + w.x_max), 0.5 * (w.y_min + w.y_max), 0.5 * h)}"'
        f' size="{_f(0.5 * (w.x_max - w.x_min), 0.5 * (w.y_max - w.y_min), 0.5 * h)}"/>'
        for i, w in enumerate(map_model.walls)
    )
    robots = "\n".join([_robot_xml(name, pose) for name, pose in starts.items()] + [p.body for p in parts])
    actuators = "\n".join(
        f'    <velocity name={quoteattr(wheel_name(n, s))} joint={quoteattr(wheel_name(n, s))} kv="{WHEEL_KV}"'
        f' ctrlrange="{_f(-MAX_WHEEL_SPEED, MAX_WHEEL_SPEED)}" forcerange="{_f(-WHEEL_MAX_TORQUE, WHEEL_MAX_TORQUE)}"/>'
        for n in starts
        for s in ("left", "right")
    )
    actuators = "\n".join([actuators] + [p.actuators for p in parts if p.actuators])
    # Tyre friction: sliding in both tangent directions, then MuJoCo's default torsional and rolling
    # (unused at condim 3). MuJoCo takes explicit pairs as given, without mixing the geoms' parameters.
    tyre = f'condim="3" friction="{_f(WHEEL_FRICTION, WHEEL_FRICTION, 0.005, 0.0001, 0.0001)}" solref="{_f(*WHEEL_SOLREF)}"'
    caster = f'condim="1" solref="{_f(*CASTER_SOLREF)}"'
    pairs = "\n".join(
        [f'    <pair geom1="floor" geom2={quoteattr(tyre_name(n, s))} {tyre}/>' for n in starts for s in ("left", "right")]
        + [f'    <pair geom1="floor" geom2={quoteattr(caster_name(n, w))} {caster}/>' for n in starts for w in ("front", "back")]
    )
    sensors = "\n".join(
        f'    <contact name={quoteattr(bump_sensor_name(n))} geom1={quoteattr(chassis_name(n))} data="found" num="1"/>'
        for n in starts
    )
    sensors = "\n".join([sensors] + [p.bump for p in parts if p.bump] + [p.sensors for p in parts if p.sensors])
    # Solver: Newton on the whole system, not island by island (<flag island="disable"/>). The
    # islands are independent blocks of the same problem, so the solution is the same to the solver
    # tolerance, but finding them each step cost more than it saved: mj_step 15-20 % dearer with 10
    # to 30 robots, the same with 3 (measured with MuJoCo 4.0 on the office, issue 8).
    return f"""<mujoco model={quoteattr(map_model.name)}>
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{physics_dt!r}" integrator="implicitfast" cone="pyramidal" solver="Newton"
          iterations="20" ls_iterations="8" tolerance="1e-8">
    <flag island="disable"/>
  </option>
  <default>
    <default class="wall">
      <geom type="box" contype="0" conaffinity="{_BODY_BIT}" group="1" rgba="0.75 0.72 0.68 1"/>
    </default>
    <default class="ground">
      <geom contype="0" conaffinity="0" group="{_HIDDEN_GROUP}" rgba="0.1 0.1 0.1 1"/>
    </default>
  </default>
  <asset>
    <texture name="sky" type="skybox" builtin="gradient" rgb1="0.8 0.86 0.93" rgb2="0.45 0.52 0.62"
             width="64" height="64"/>
    <texture name="floor" type="2d" builtin="checker" rgb1="0.42 0.45 0.5" rgb2="0.34 0.37 0.42"
             width="64" height="64"/>
    <material name="floor" texture="floor" texrepeat="2 2" texuniform="true"/>
  </asset>
  <worldbody>
    <light pos="{_f(cx, cy, 10.0)}" dir="0 0 -1" directional="true"/>
    <light name="camera_key" dir="0.6 0.35 -0.5" directional="true" castshadow="false" diffuse="0.45 0.45 0.45"
           ambient="0.15 0.15 0.15"/>
    <light name="camera_fill" dir="-0.45 -0.7 -0.5" directional="true" castshadow="false" diffuse="0.35 0.35 0.35"/>
    <geom name="floor" type="plane" pos="{_f(cx, cy, 0.0)}" size="0 0 0.05" contype="0" conaffinity="{_GROUND_BIT}"
          group="{_HIDDEN_GROUP}" friction="1 0.005 0.0001" material="floor"/>
{walls}
{robots}
  </worldbody>
  <contact>
{pairs}
  </contact>
  <actuator>
{actuators}
  </actuator>
  <sensor>
{sensors}
  </sensor>
</mujoco>
"""


def _robot_xml(name: str, pose: Pose2D) -> str:
    """One robot: a free base at axle height with chassis and casters, and two wheel bodies."""
    half = 0.5 * (CHASSIS_TOP - CHASSIS_BOTTOM)
    chassis_z = CHASSIS_BOTTOM + half - WHEEL_RADIUS  # in the base frame (origin at axle height)
    caster_z = CASTER_RADIUS - WHEEL_RADIUS
    # Inertia of a uniform solid cylinder of the chassis size; centre of mass at BASE_COM_HEIGHT.
    izz = 0.5 * BASE_MASS * CHASSIS_RADIUS**2
    ixx = BASE_MASS * (3 * CHASSIS_RADIUS**2 + (CHASSIS_TOP - CHASSIS_BOTTOM) ** 2) / 12
    wheels = "\n".join(
        f"""      <body name={quoteattr(wheel_name(name, side))} pos="{_f(0.0, sign * WHEEL_SEPARATION / 2, 0.0)}">
        <joint name={quoteattr(wheel_name(name, side))} type="hinge" axis="0 1 0" armature="{WHEEL_ARMATURE}"/>
        <geom name={quoteattr(tyre_name(name, side))} class="ground" type="sphere" size="{WHEEL_RADIUS}"
              mass="{WHEEL_MASS}"/>
      </body>"""
        for side, sign in (("left", 1.0), ("right", -1.0))
    )
    casters = "\n".join(
        f'      <geom name={quoteattr(caster_name(name, where))} class="ground" type="sphere" size="{CASTER_RADIUS}"'
        f' pos="{_f(sign * CASTER_OFFSET, 0.0, caster_z)}" mass="0"/>'
        for where, sign in (("front", 1.0), ("back", -1.0))
    )
    # The top plate: touched only by flyers (TOP_BIT); three standoffs that touch nothing. All above the
    # chassis top (0.26 m), so a lidar at the default 0.2 m never sees them.
    plate_z = PLATE_TOP - 0.5 * PLATE_THICKNESS - WHEEL_RADIUS
    standoff_len = PLATE_TOP - PLATE_THICKNESS - CHASSIS_TOP
    standoffs = "\n".join(
        f'      <geom type="cylinder" size="{_f(0.006, 0.5 * standoff_len)}" contype="0" conaffinity="0" mass="0"'
        f' group="0" rgba="0.6 0.6 0.62 1"'
        f' pos="{_f(0.13 * math.cos(a), 0.13 * math.sin(a), CHASSIS_TOP + 0.5 * standoff_len - WHEEL_RADIUS)}"/>'
        for a in (0.0, 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0)
    )
    plate = (
        f'      <geom name={quoteattr(plate_name(name))} type="cylinder" size="{_f(PLATE_RADIUS, 0.5 * PLATE_THICKNESS)}"'
        f' pos="{_f(0.0, 0.0, plate_z)}" mass="0" contype="0" conaffinity="{TOP_BIT}" condim="3"'
        f' friction="{PLATE_FRICTION} 0.005 0.0001" group="0" rgba="0.25 0.25 0.27 1"/>\n{standoffs}'
    )
    qw, qz = math.cos(0.5 * pose.yaw), math.sin(0.5 * pose.yaw)
    placement = f'pos="{_f(pose.x, pose.y, WHEEL_RADIUS)}" quat="{_f(qw, 0.0, 0.0, qz)}"'
    return f"""    <body name={quoteattr(base_name(name))} {placement}>
      <freejoint name={quoteattr(f"{name}/root")}/>
      <inertial pos="{_f(0.0, 0.0, BASE_COM_HEIGHT - WHEEL_RADIUS)}" mass="{BASE_MASS}" diaginertia="{_f(ixx, ixx, izz)}"/>
      <geom name={quoteattr(chassis_name(name))} type="cylinder" size="{_f(CHASSIS_RADIUS, half)}"
            pos="{_f(0.0, 0.0, chassis_z)}" mass="0" contype="{_BODY_BIT}" conaffinity="{_BODY_BIT}" group="0"
            rgba="{_f(*ROBOT_RGBA)}"/>
      <camera name={quoteattr(camera_name(name))} pos="{_f(CAMERA_X, 0.0, CAMERA_HEIGHT - WHEEL_RADIUS)}"
              xyaxes="0 -1 0 0 0 1" fovy="{CAMERA_FOVY_4_3:.6g}"/>
{plate}
{casters}
{wheels}
    </body>"""
