"""The interface between a robot's brain and its body, and the sensor messages that cross it.

Owns: Body (what the brain may ask of a body), FlyingBody (what more a flying one offers), RobotKind,
FlightPhase, LandingTarget, LaserScan (sensor_msgs/LaserScan in spirit), CameraImage
(sensor_msgs/Image in spirit) and NoRendererError.
Must not know: what implements a body (MuJoCo, a remote process, a ROS robot).
"""

from __future__ import annotations

import abc
import enum
import functools
from dataclasses import dataclass

import numpy as np

from rescuemesh.body_kernels import scan_points
from rescuemesh.geometry import Pose2D


class RobotKind(enum.Enum):
    """What moves a robot: wheels on the floor or rotors in the air. Chosen per robot by the scenario."""

    GROUND = "ground"
    FLYING = "flying"


@dataclass(frozen=True)
class LaserScan:
    """One planar laser sweep, as sensor_msgs/LaserScan.

    Beam i points at `angle_min + i * angle_increment` rad in the sensor frame (x forward,
    anticlockwise positive). `ranges` in m; a beam with no return within `range_max` is `inf`.
    `origin` is the sensor pose in the map frame when the sweep was taken, at `stamp` s.
    """

    stamp: float
    origin: Pose2D
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: np.ndarray

    def angles(self) -> np.ndarray:
        """Beam angles in rad in the sensor frame."""
        return self.angle_min + self.angle_increment * np.arange(len(self.ranges))

    def points_in_map(self) -> np.ndarray:
        """(N, 2) map-frame points of the finite returns within [range_min, range_max]."""
        # one compiled pass (body_kernels.py): the ranges are read as float64, as every producer gives them
        r = np.ascontiguousarray(self.ranges, dtype=float)
        o = self.origin
        return scan_points(r, _beam_angles(self.angle_min, self.angle_increment, len(r)), float(self.range_min),
                           float(self.range_max), o.x, o.y, o.yaw)


@functools.lru_cache(maxsize=16)
def _beam_angles(angle_min: float, angle_increment: float, n: int) -> np.ndarray:
    """`LaserScan.angles()` of a sweep of `n` beams, kept read-only: every sweep of a lidar has the same."""
    a = angle_min + angle_increment * np.arange(n)
    a.flags.writeable = False
    return a


class NoRendererError(RuntimeError):
    """The body has a camera but cannot produce an image: no OpenGL context could be created (no EGL,
    no display) or rendering is disabled (MUJOCO_GL=disable). A brain answers FAILED "no renderer"."""


@dataclass(frozen=True, eq=False)
class CameraImage:
    """One RGB frame of a forward camera.

    `rgb` is (height, width, 3) uint8, row 0 at the top and column 0 at the left as seen by the
    camera. `origin` is the camera's pose in the map frame when the frame was taken, at `stamp` s:
    x, y of the optical centre in m and the yaw of the optical axis in rad; `z` its height above
    the floor in m. `fov_h` is the horizontal field of view in rad (the optical axis is horizontal).
    """

    stamp: float
    origin: Pose2D
    z: float
    fov_h: float
    rgb: np.ndarray

    def __post_init__(self) -> None:
        rgb = self.rgb
        if not (isinstance(rgb, np.ndarray) and rgb.dtype == np.uint8 and rgb.ndim == 3 and rgb.shape[2] == 3):
            raise ValueError(f"CameraImage.rgb must be an (H, W, 3) uint8 array, got {getattr(rgb, 'shape', rgb)!r}")

    @property
    def width(self) -> int:
        """Image width in pixels."""
        return int(self.rgb.shape[1])

    @property
    def height(self) -> int:
        """Image height in pixels."""
        return int(self.rgb.shape[0])


class Body(abc.ABC):
    """What a robot brain may read from and command to its body.

    Implemented by `rescuemesh.sim` for MuJoCo TurtleBots; later by a Zenoh proxy and a ROS bridge.
    A flying robot's body is a `FlyingBody` (below); `kind` tells the two apart without isinstance.
    """

    name: str
    max_linear_speed: float  # in m/s
    max_angular_speed: float  # in rad/s
    radius: float  # footprint radius in m
    kind: RobotKind = RobotKind.GROUND  # a default, so every existing Body is a ground robot
    top_height: float | None = None  # height in m above the floor of a top a drone may land on; None: none

    @abc.abstractmethod
    def pose(self) -> Pose2D:
        """Localised pose in the `map` frame (ground truth in simulation, as AMCL would give)."""

    @abc.abstractmethod
    def odometry(self) -> tuple[Pose2D, float, float]:
        """Odometry: (dead-reckoned pose, linear speed in m/s, angular speed in rad/s)."""

    @abc.abstractmethod
    def scan(self) -> LaserScan | None:
        """The latest complete laser sweep, or None before the first one."""

    def camera(self) -> CameraImage | None:
        """What the forward camera sees now, or None when this body has no camera (the default).

        Raises NoRendererError when the body has a camera but no image can be rendered.
        """
        return None

    @abc.abstractmethod
    def set_velocity(self, linear: float, angular: float) -> None:
        """Command a body twist: `linear` in m/s along x, `angular` in rad/s about z. Clamped to the limits."""


class FlightPhase(enum.Enum):
    """What a flying body is doing (its autopilot's state; see rescuemesh.sim.flight for the transitions)."""

    OFF = "off"  # rotors off, not landed on a robot (on the floor before take-off, or rotors_off() in the air)
    FLY = "fly"  # flying to a goal or, when landing, to above the target: climbs to the altitude first
    HOLD = "hold"  # hovering at the goal, or moving by set_velocity at a held altitude
    ALIGN = "align"  # landing: hovering above the target at cruise altitude, tracking it
    DESCEND = "descend"  # landing: descending onto the target, tracking it
    TOUCHDOWN = "touchdown"  # landing: feet down, rotors off, waiting for the contact to settle
    LANDED = "landed"  # rotors off, resting on the target


@dataclass(frozen=True, slots=True)
class LandingTarget:
    """The top to land on, as estimated at the moment it is handed to `FlyingBody.land_on`.

    `x`, `y`: centre of the top in the map frame, in m; `z`: height of its surface above the floor in m
    (a TurtleBot 2's top plate: `Body.top_height` of that robot); `vx`, `vy`: its velocity in m/s in the
    map frame. The body predicts the target forward with this velocity until the next estimate.
    """

    x: float
    y: float
    z: float
    vx: float = 0.0
    vy: float = 0.0


class FlyingBody(Body):
    """A body that flies (a quadrotor): the brain commands goals and landings; its autopilot flies them.

    `set_velocity(linear, angular)` still works, as a planar twist at the altitude held when it started
    (so the ground behaviours can steer a drone), with two rules that make the brain's every-tick call
    harmless: (0, 0) only stops a twist already running (it does not cancel a `fly_to` or a landing),
    and any twist is ignored while the rotors are off (a landed drone stays landed). A non-zero twist
    with the rotors running replaces a `fly_to` or a landing. `pose()` is the projection on the floor
    (x, y, yaw); `scan()` may be None (no lidar).
    """

    kind: RobotKind = RobotKind.FLYING
    cruise_altitude: float  # m above the floor: above every wall and piece of furniture

    @abc.abstractmethod
    def position_3d(self) -> tuple[float, float, float]:
        """Position (x, y, z) in m in the map frame (z above the floor)."""

    @abc.abstractmethod
    def velocity_3d(self) -> tuple[float, float, float]:
        """Velocity (vx, vy, vz) in m/s in the map frame."""

    @abc.abstractmethod
    def flight_phase(self) -> FlightPhase:
        """What the autopilot is doing now."""

    @abc.abstractmethod
    def fly_to(self, x: float, y: float, z: float | None = None, yaw: float | None = None) -> None:
        """Fly to (x, y) m at height `z` m (None: `cruise_altitude`) and hover there facing `yaw` rad
        (None: the present heading). Starts the rotors when they are off. Climbs vertically first when
        below the goal's height, so it never crosses furniture low. Cancels a landing."""

    @abc.abstractmethod
    def land_on(self, target: LandingTarget) -> None:
        """Land on `target` (start, or update the estimate of a landing under way). Call again with each
        fresh estimate (each PoseUpdate); ignored once LANDED. Phases FLY, ALIGN, DESCEND, TOUCHDOWN,
        then LANDED with the rotors off."""

    @abc.abstractmethod
    def hold(self) -> None:
        """Hover where it is now (cancels a `fly_to`, a twist or a landing). No-op while the rotors are off."""

    @abc.abstractmethod
    def rotors_off(self) -> None:
        """Stop the rotors now (in the air it falls: meant for an emergency). During a landing's
        TOUCHDOWN (rotors already off) it lets the landing finish."""

    @abc.abstractmethod
    def landed_on(self) -> str | None:
        """Name of the robot whose top the feet rest on now, or None (in the air, on the floor)."""
