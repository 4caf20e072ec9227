"""A planar scanning laser rangefinder cast with mujoco.mj_multiRay (Hokuyo URG-04LX by default).

Owns: LidarConfig (beam geometry, rate, range limits, noise) and one sweep. Must not know when
sweeps happen (the world schedules them) nor who reads them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from rescuemesh.body import LaserScan
from rescuemesh.geometry import Pose2D
from rescuemesh.sim.mjcf import LIDAR_GEOM_GROUPS


@dataclass(frozen=True)
class LidarConfig:
    """Beam geometry and timing of the simulated lidar; defaults after the Hokuyo URG-04LX.

    - `fov_rad`: field of view in rad, centred on the robot's x axis (240 deg).
    - `rate_hz`: sweeps per second of simulated time (10 Hz).
    - `range_min`, `range_max`: valid range in m (0.02 to 5.6 m); no return within `range_max` is inf.
    - `beams`: number of beams, spread evenly from -fov/2 to +fov/2 inclusive (683).
    - `height`: height of the beam plane above the floor in m (0.2: below the 0.26 m chassis top,
      so other robots are seen; above the wheels and casters).
    - `noise_std`: standard deviation in m of Gaussian range noise (0: exact ranges).
    """

    fov_rad: float = math.radians(240.0)
    rate_hz: float = 10.0
    range_min: float = 0.02
    range_max: float = 5.6
    beams: int = 683
    height: float = 0.2
    noise_std: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 < self.fov_rad <= 2.0 * math.pi:
            raise ValueError(f"LidarConfig.fov_rad must be in (0, 2 pi] rad, got {self.fov_rad}")
        if not self.rate_hz > 0.0:
            raise ValueError(f"LidarConfig.rate_hz must be > 0 Hz, got {self.rate_hz}")
        if not 0.0 <= self.range_min < self.range_max:
            raise ValueError(f"LidarConfig needs 0 <= range_min < range_max m, got {self.range_min}, {self.range_max}")
        if not (isinstance(self.beams, int) and self.beams >= 1):
            raise ValueError(f"LidarConfig.beams must be a positive int, got {self.beams!r}")
        if not self.height > 0.0:
            raise ValueError(f"LidarConfig.height must be > 0 m, got {self.height}")
        if not self.noise_std >= 0.0:
            raise ValueError(f"LidarConfig.noise_std must be >= 0 m, got {self.noise_std}")

    @property
    def angle_min(self) -> float:
        """Angle of the first beam in rad in the sensor frame."""
        return -0.5 * self.fov_rad if self.beams > 1 else 0.0

    @property
    def angle_increment(self) -> float:
        """Angle between neighbouring beams in rad."""
        return self.fov_rad / (self.beams - 1) if self.beams > 1 else 0.0


class Lidar:
    """Casts the beams of one robot's lidar in a MuJoCo world.

    The beams lie in the horizontal plane at `config.height` above the floor, centred on the robot's
    base (the sensor frame is the base frame). The robot's own base body is excluded; the floor,
    wheels and casters sit in a geom group the rays ignore.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        body_id: int,
        config: LidarConfig,
        rng: np.random.Generator,
    ) -> None:
        self._model = model
        self._data = data
        self._body_id = body_id
        self.config = config
        self._rng = rng
        n = config.beams
        self._angles = config.angle_min + config.angle_increment * np.arange(n)
        self._groups = np.array(LIDAR_GEOM_GROUPS, dtype=np.uint8)
        self._pnt = np.zeros(3)
        self._vec = np.zeros((n, 3))
        self._geomid = np.zeros(n, dtype=np.int32)
        self._dist = np.zeros(n)

    def sweep(self, stamp: float, origin: Pose2D) -> LaserScan:
        """One sweep from `origin` (map frame) taken at `stamp` s; geometry must be current (mj_kinematics)."""
        cfg = self.config
        self._pnt[:] = (origin.x, origin.y, cfg.height)
        world_angles = self._angles + origin.yaw
        self._vec[:, 0] = np.cos(world_angles)
        self._vec[:, 1] = np.sin(world_angles)
        mujoco.mj_multiRay(
            self._model,
            self._data,
            self._pnt,
            self._vec.reshape(-1),
            self._groups,
            1,  # include static geoms (walls)
            self._body_id,
            self._geomid,
            self._dist,
            None,
            cfg.beams,
            cfg.range_max,
        )
        ranges = self._dist.copy()
        ranges[(ranges < 0.0) | (ranges > cfg.range_max)] = np.inf
        if cfg.noise_std > 0.0:
            hit = np.isfinite(ranges)
            ranges[hit] += self._rng.normal(0.0, cfg.noise_std, int(hit.sum()))
            ranges[hit] = np.maximum(ranges[hit], 0.0)
        return LaserScan(
            stamp=stamp,
            origin=origin,
            angle_min=cfg.angle_min,
            angle_increment=cfg.angle_increment,
            range_min=cfg.range_min,
            range_max=cfg.range_max,
            ranges=ranges,
        )
