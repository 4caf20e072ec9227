"""SimBody: the rescuemesh Body of one simulated TurtleBot, read from and written to MuJoCo data.

Owns: ground-truth pose, wheel odometry, twist-to-wheel kinematics and command clamping.
Must not know: when the world steps or sweeps the lidar (the World calls in), nor any brain.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco

from rescuemesh.body import Body, CameraImage, LaserScan
from rescuemesh.geometry import Pose2D, quaternion_to_yaw, wrap_angle
from rescuemesh.sim import mjcf


class SimBody(Body):
    """One differential-drive robot in a World (a TurtleBot 2 on a Kobuki base).

    `pose()` is ground truth from the free joint. `odometry()` dead-reckons from the wheel joint
    angles (as Kobuki wheel encoders would), in the map frame and starting at the start pose.
    Commands are body twists, clamped to `max_linear_speed` and `max_angular_speed`, and turned
    into wheel speeds: left = (v - omega * L / 2) / r, right = (v + omega * L / 2) / r.
    """

    max_linear_speed: float = mjcf.MAX_LINEAR_SPEED  # m/s
    max_angular_speed: float = mjcf.MAX_ANGULAR_SPEED  # rad/s
    radius: float = mjcf.CHASSIS_RADIUS  # m

    def __init__(self, name: str, model: mujoco.MjModel, data: mujoco.MjData, start: Pose2D) -> None:
        self.name = name
        self._data = data
        root = model.joint(f"{name}/root").id
        self._qpos_adr = int(model.jnt_qposadr[root])
        left, right = model.joint(mjcf.wheel_name(name, "left")), model.joint(mjcf.wheel_name(name, "right"))
        self._wheel_qpos = (int(model.jnt_qposadr[left.id]), int(model.jnt_qposadr[right.id]))
        self._wheel_qvel = (int(model.jnt_dofadr[left.id]), int(model.jnt_dofadr[right.id]))
        self._ctrl = (
            model.actuator(mjcf.wheel_name(name, "left")).id,
            model.actuator(mjcf.wheel_name(name, "right")).id,
        )
        self.body_id: int = model.body(mjcf.base_name(name)).id
        self._command = (0.0, 0.0)
        # pose() and odometry() of the current physics state, computed on first use after each step:
        # the World calls moved() after stepping (a follow reads a pose ~8 times a tick per robot).
        self._pose: Pose2D | None = None
        self._odometry: tuple[Pose2D, float, float] | None = None
        self._scan: LaserScan | None = None
        self._camera: Callable[[], CameraImage] | None = None
        # Odometry committed at the last integration point: pose and the wheel angles there.
        self._odom = (start.x, start.y, start.yaw)
        self._odom_wheels = self._wheel_angles()

    # ------------------------------------------------------------ Body interface

    def pose(self) -> Pose2D:
        """Ground-truth pose of the base in the map frame (x, y in m, yaw in rad)."""
        if self._pose is None:
            x, y, _, qw, qx, qy, qz = self._data.qpos[self._qpos_adr : self._qpos_adr + 7].tolist()
            self._pose = Pose2D(x, y, quaternion_to_yaw(qx, qy, qz, qw))
        return self._pose

    def odometry(self) -> tuple[Pose2D, float, float]:
        """(wheel-odometry pose in the map frame, linear speed in m/s, angular speed in rad/s).

        The speeds are measured from the current wheel speeds, not the commanded ones.
        """
        if self._odometry is None:
            x, y, yaw = self._integrate(self._wheel_angles())
            qvel = self._data.qvel
            wl, wr = float(qvel[self._wheel_qvel[0]]), float(qvel[self._wheel_qvel[1]])
            r, sep = mjcf.WHEEL_RADIUS, mjcf.WHEEL_SEPARATION
            self._odometry = (Pose2D(x, y, wrap_angle(yaw)), 0.5 * r * (wl + wr), r * (wr - wl) / sep)
        return self._odometry

    def scan(self) -> LaserScan | None:
        """The latest lidar sweep (taken by the World at the lidar rate), or None before the first."""
        return self._scan

    def camera(self) -> CameraImage | None:
        """What the forward camera sees now (rendered on demand; sim/camera.py), or None without a camera.

        Raises NoRendererError when no OpenGL context can be made (docs/sensors.md).
        """
        return self._camera() if self._camera is not None else None

    def set_velocity(self, linear: float, angular: float) -> None:
        """Command `linear` m/s along x and `angular` rad/s about z, each clamped to its limit.

        Raises ValueError for a non-finite command (a brain bug must not reach the physics).
        """
        if not (math.isfinite(linear) and math.isfinite(angular)):
            raise ValueError(f"{self.name}: velocity command must be finite, got ({linear}, {angular})")
        v = min(max(float(linear), -self.max_linear_speed), self.max_linear_speed)
        w = min(max(float(angular), -self.max_angular_speed), self.max_angular_speed)
        self._command = (v, w)
        r, half = mjcf.WHEEL_RADIUS, 0.5 * mjcf.WHEEL_SEPARATION
        self._data.ctrl[self._ctrl[0]] = (v - w * half) / r
        self._data.ctrl[self._ctrl[1]] = (v + w * half) / r

    # ------------------------------------------------------------ for the World and for tests

    @property
    def command(self) -> tuple[float, float]:
        """The last command after clamping: (linear in m/s, angular in rad/s)."""
        return self._command

    def moved(self) -> None:
        """The physics stepped (called by the World): pose and odometry are read afresh."""
        self._pose = None
        self._odometry = None

    def commit_odometry(self) -> None:
        """Fold the wheel motion since the last commit into the odometry pose (called by the World).

        The World commits on a fixed schedule of physics steps, so odometry does not depend on how
        often the caller steps or reads it.
        """
        wheels = self._wheel_angles()
        self._odom = self._integrate(wheels)
        self._odom_wheels = wheels

    def set_scan(self, scan: LaserScan) -> None:
        self._scan = scan

    def attach_camera(self, capture: Callable[[], CameraImage] | None) -> None:
        """Give the body a camera: `capture()` renders the current view (called by the World)."""
        self._camera = capture

    def _wheel_angles(self) -> tuple[float, float]:
        return (float(self._data.qpos[self._wheel_qpos[0]]), float(self._data.qpos[self._wheel_qpos[1]]))

    def _integrate(self, wheels: tuple[float, float]) -> tuple[float, float, float]:
        """Odometry pose (x, y, unwrapped yaw) at wheel angles `wheels`: the committed pose plus one
        midpoint-heading arc."""
        x, y, yaw = self._odom
        (l0, r0), (l1, r1) = self._odom_wheels, wheels
        dl, dr = mjcf.WHEEL_RADIUS * (l1 - l0), mjcf.WHEEL_RADIUS * (r1 - r0)
        ds, dyaw = 0.5 * (dl + dr), (dr - dl) / mjcf.WHEEL_SEPARATION
        mid = yaw + 0.5 * dyaw
        return (x + ds * math.cos(mid), y + ds * math.sin(mid), yaw + dyaw)

