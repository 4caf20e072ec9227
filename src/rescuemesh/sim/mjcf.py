"""The MJCF text of a simulated office: floor, wall boxes and TurtleBot 2-like robots (Kobuki base).

Owns: robot dimensions and masses, contact filtering, geom groups, solver options, element names.
Must not know: how the world is stepped, sensed or commanded (see world.py, body.py, lidar.py).

Contact filtering (contype/conaffinity bits): bit 1 = ground contacts (wheels and casters against
the floor), bit 2 = body contacts (chassis against walls and other chassis). So wheels and casters
never touch walls or each other, and a chassis never touches the floor: the only chassis contacts
are collisions. Geom group 3 holds the floor, wheels and casters; the lidar masks it off.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
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
WHEEL_SOLREF = (0.01, 1.0)  # tyre contact time constant in s and damping ratio

LIDAR_GEOM_GROUPS = (1, 1, 1, 0, 0, 0)  # geom groups the lidar sees: everything but group 3
_HIDDEN_GROUP = 3
_GROUND_BIT = 1
_BODY_BIT = 2


def base_name(robot: str) -> str:
    return f"{robot}/base"


def chassis_name(robot: str) -> str:
    return f"{robot}/chassis"


def wheel_name(robot: str, side: str) -> str:
    """Name of the wheel joint and of its actuator; side is 'left' or 'right'."""
    return f"{robot}/wheel_{side}"


def bump_sensor_name(robot: str) -> str:
    return f"{robot}/bump"


def _f(*values: float) -> str:
    return " ".join(f"{v:.10g}" for v in values)


def world_xml(map_model: MapModel, starts: Mapping[str, Pose2D], physics_dt: float) -> str:
    """MJCF of the map's walls (height `map_model.wall_height` m) and one robot per start pose."""
    b = map_model.bounds
    cx, cy = 0.5 * (b.x_min + b.x_max), 0.5 * (b.y_min + b.y_max)
    h = map_model.wall_height
    walls = "\n".join(
        f'    <geom name="wall_{i}" class="wall"'
        f' pos="{_f(0.5 * (w.x_min + w.x_max), 0.5 * (w.y_min + w.y_max), 0.5 * h)}"'
        f' size="{_f(0.5 * (w.x_max - w.x_min), 0.5 * (w.y_max - w.y_min), 0.5 * h)}"/>'
        for i, w in enumerate(map_model.walls)
    )
    robots = "\n".join(_robot_xml(name, pose) for name, pose in starts.items())
    actuators = "\n".join(
        f'    <velocity name={quoteattr(wheel_name(n, s))} joint={quoteattr(wheel_name(n, s))} kv="{WHEEL_KV}"'
        f' ctrlrange="{_f(-MAX_WHEEL_SPEED, MAX_WHEEL_SPEED)}" forcerange="{_f(-WHEEL_MAX_TORQUE, WHEEL_MAX_TORQUE)}"/>'
        for n in starts
        for s in ("left", "right")
    )
    sensors = "\n".join(
        f'    <contact name={quoteattr(bump_sensor_name(n))} geom1={quoteattr(chassis_name(n))} data="found" num="1"/>'
        for n in starts
    )
    return f"""<mujoco model={quoteattr(map_model.name)}>
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{physics_dt!r}" integrator="implicitfast" cone="pyramidal" solver="Newton"
          iterations="20" ls_iterations="8" tolerance="1e-8"/>
  <default>
    <default class="wall">
      <geom type="box" contype="0" conaffinity="{_BODY_BIT}" group="1" rgba="0.75 0.72 0.68 1"/>
    </default>
    <default class="ground">
      <geom contype="{_GROUND_BIT}" conaffinity="0" group="{_HIDDEN_GROUP}" rgba="0.1 0.1 0.1 1"/>
    </default>
  </default>
  <worldbody>
    <light pos="{_f(cx, cy, 10.0)}" dir="0 0 -1" directional="true"/>
    <geom name="floor" type="plane" pos="{_f(cx, cy, 0.0)}" size="0 0 0.05" contype="0" conaffinity="{_GROUND_BIT}"
          group="{_HIDDEN_GROUP}" friction="1 0.005 0.0001" rgba="0.55 0.55 0.5 1"/>
{walls}
{robots}
  </worldbody>
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
        <geom class="ground" type="sphere" size="{WHEEL_RADIUS}" mass="{WHEEL_MASS}" condim="3"
              friction="{WHEEL_FRICTION} 0.005 0.0001" solref="{_f(*WHEEL_SOLREF)}"/>
      </body>"""
        for side, sign in (("left", 1.0), ("right", -1.0))
    )
    casters = "\n".join(
        f'      <geom name={quoteattr(f"{name}/caster_{where}")} class="ground" type="sphere" size="{CASTER_RADIUS}"'
        f' pos="{_f(sign * CASTER_OFFSET, 0.0, caster_z)}" mass="0" priority="1" condim="1"/>'
        for where, sign in (("front", 1.0), ("back", -1.0))
    )
    qw, qz = math.cos(0.5 * pose.yaw), math.sin(0.5 * pose.yaw)
    placement = f'pos="{_f(pose.x, pose.y, WHEEL_RADIUS)}" quat="{_f(qw, 0.0, 0.0, qz)}"'
    return f"""    <body name={quoteattr(base_name(name))} {placement}>
      <freejoint name={quoteattr(f"{name}/root")}/>
      <inertial pos="{_f(0.0, 0.0, BASE_COM_HEIGHT - WHEEL_RADIUS)}" mass="{BASE_MASS}" diaginertia="{_f(ixx, ixx, izz)}"/>
      <geom name={quoteattr(chassis_name(name))} type="cylinder" size="{_f(CHASSIS_RADIUS, half)}"
            pos="{_f(0.0, 0.0, chassis_z)}" mass="0" contype="{_BODY_BIT}" conaffinity="{_BODY_BIT}" group="0"
            rgba="0.2 0.2 0.22 1"/>
{casters}
{wheels}
    </body>"""
