"""A planar scanning laser rangefinder (Hokuyo URG-04LX by default) and what it sees (LidarScene).

Owns: LidarConfig (beam geometry, rate, range limits, noise), one sweep, and the split of the world
into the map's walls and everything else. Must not know when sweeps happen (the world schedules
them) nor who reads them.

Theory of operation (docs/sensors.md, section 9): a beam's range is the nearer of two casts. The
map's walls, often a thousand static boxes on a SLAM map, are cast on the grid they came from
(gridcast.py, an exact cell walk whose cost does not depend on the number of walls). Everything
else the lidar's geom groups hold (other robots, quadrotors, any non-wall geom) is cast in a small
MuJoCo model of its own, the LidarScene, holding copies of those geoms on mocap bodies that follow
the world's bodies. mj_multiRay visits every geom of a model for every beam, even geoms its group
mask rejects, so casting in the world's own model would cost in proportion to the wall count. The
world's model, its physics and its pictures keep the wall boxes.

mj_multiRay's cost is (beams cast) x (geoms in the scene): every beam visits every geom. So a sweep
tests each geom only against the beams that can reach it (`_cast_bodies`): a geom's bounding sphere
(geom_rbound, about its geom_xpos) cuts the beam plane in a disc, and only the beams whose angle lies
within that disc's angular extent seen from the lidar, and whose range reaches it, can hit the
geom. Each such (beam, geom) pair gets the test mj_multiRay makes, MuJoCo's own `mju_rayGeom`
(raygeom.py), and a beam's range is the nearest hit, as mj_multiRay's; a beam that cannot hit a
geom reads no return from it, as it would have. The robot's own geoms are skipped, as
mj_multiRay's bodyexclude skips them. In a convoy most beams reach no other robot, and a beam that
does is tested against the one or two robots in its way, not all thirty.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass

import mujoco
import numba
import numpy as np

from rescuemesh.body import LaserScan
from rescuemesh.geometry import Pose2D
from rescuemesh.maps.model import MapModel
from rescuemesh.sim.gridcast import WallGrid
from rescuemesh.sim.mjcf import LIDAR_GEOM_GROUPS
from rescuemesh.sim.raygeom import ray_geom


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


# Geom types the LidarScene can copy: MuJoCo primitives, whose shape is all in geom_size.
_PRIMITIVES = {
    mujoco.mjtGeom.mjGEOM_PLANE: "plane",
    mujoco.mjtGeom.mjGEOM_SPHERE: "sphere",
    mujoco.mjtGeom.mjGEOM_CAPSULE: "capsule",
    mujoco.mjtGeom.mjGEOM_ELLIPSOID: "ellipsoid",
    mujoco.mjtGeom.mjGEOM_CYLINDER: "cylinder",
    mujoco.mjtGeom.mjGEOM_BOX: "box",
}


def _f(values) -> str:
    return " ".join(f"{float(v)!r}" for v in values)


class LidarScene:
    """What every lidar of one World sees: the map's walls on a grid, the rest in a small MuJoCo model.

    - `model`, `data`: the World's MuJoCo model and data (read only: poses after mj_kinematics).
    - `map_model`: the map whose walls became the geoms `wall_geoms` (ids in `model`).

    Every other geom a lidar can see (in LIDAR_GEOM_GROUPS, not transparent: mj_ray's rules) is
    copied, with its type, size, pose in its body and group, onto a mocap body that `refresh` puts
    where the World's body is. Geoms of the world body are copied in place. Only primitive geom types
    can be copied; a mesh, height field or SDF raises ValueError.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, map_model: MapModel,
                 wall_geoms: Collection[int]) -> None:
        self._source = data
        self.walls = WallGrid(map_model)
        walls = set(int(g) for g in wall_geoms)
        by_body: dict[int, list[int]] = {}
        for g in range(model.ngeom):
            if g not in walls and _seen_by_lidar(model, g):
                by_body.setdefault(int(model.geom_bodyid[g]), []).append(g)
        fixed = "".join(_geom_xml(model, g) for g in by_body.pop(0, []))
        moving = sorted(by_body)
        bodies = "".join(
            f'    <body name="b{b}" mocap="true">\n{"".join(_geom_xml(model, g) for g in by_body[b])}    </body>\n'
            for b in moving
        )
        xml = f"""<mujoco model="lidar_scene">
  <worldbody>
{fixed}{bodies}  </worldbody>
</mujoco>
"""
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)
        self._moving = np.array(moving, dtype=np.intp)
        #: World body id -> scene body id (-1 for bodies with nothing the lidar sees).
        self._body = {b: self.model.body(f"b{b}").id for b in moving}
        self.refresh()

    def scene_body(self, body_id: int) -> int:
        """The scene's copy of the World's body `body_id`, or -1 when it has no geom a lidar sees."""
        return self._body.get(int(body_id), -1)

    def refresh(self) -> None:
        """Move the copies to the World's current body poses (the World's kinematics must be current)."""
        if len(self._moving):
            self.data.mocap_pos[:] = self._source.xpos[self._moving]
            self.data.mocap_quat[:] = self._source.xquat[self._moving]
        mujoco.mj_kinematics(self.model, self.data)


def _seen_by_lidar(model: mujoco.MjModel, g: int) -> bool:
    """mj_ray's rules (engine_ray.c, ray_eliminate): in a group the lidar casts on, and not transparent."""
    group = min(max(int(model.geom_group[g]), 0), len(LIDAR_GEOM_GROUPS) - 1)
    if not LIDAR_GEOM_GROUPS[group]:
        return False
    mat = int(model.geom_matid[g])
    alpha = model.mat_rgba[mat][3] if mat >= 0 else model.geom_rgba[g][3]
    return bool(alpha != 0.0)


def _geom_xml(model: mujoco.MjModel, g: int) -> str:
    """MJCF of a copy of geom `g`, with its type, size, pose in its body and group. Its contype and
    conaffinity stay at MuJoCo's defaults: the scene is never stepped, so nothing collides."""
    kind = _PRIMITIVES.get(int(model.geom_type[g]))
    if kind is None:
        name = model.geom(g).name or f"#{g}"
        raise ValueError(f"the lidar cannot see geom {name}: type {mujoco.mjtGeom(model.geom_type[g]).name}"
                         " is not a primitive (LidarScene copies primitives only)")
    return (f'      <geom type="{kind}" size="{_f(model.geom_size[g])}" pos="{_f(model.geom_pos[g])}"'
            f' quat="{_f(model.geom_quat[g])}" group="{int(model.geom_group[g])}"/>\n')


class Lidar:
    """Casts the beams of one robot's lidar in a World's LidarScene.

    The beams lie in the horizontal plane at `config.height` above the floor, centred on the robot's
    base (the sensor frame is the base frame). The robot's own base body is excluded; the floor,
    wheels and casters sit in a geom group the rays ignore.
    """

    def __init__(
        self,
        scene: LidarScene,
        body_id: int,
        config: LidarConfig,
        rng: np.random.Generator,
    ) -> None:
        self._scene = scene
        self._exclude = scene.scene_body(body_id)
        self.config = config
        self._rng = rng
        n = config.beams
        self._angles = config.angle_min + config.angle_increment * np.arange(n)
        self._sees_walls = 0.0 <= config.height <= scene.walls.wall_height
        self._pnt = np.zeros(3)
        self._world_angles = np.zeros(n)
        self._cos = np.zeros(n)
        self._sin = np.zeros(n)
        self._vec = np.zeros((n, 3))  # the beams' directions: (cos, sin, 0)
        self._wall_dist = np.full(n, np.inf)
        self._dist = np.zeros(n)  # MuJoCo's distance to the nearest scene geom, -1: none
        #: (x, y, yaw) of the last sweep, whose cos, sin and wall ranges are kept: a robot standing still
        #: (a third of the sweeps in the follow scenario) sweeps from the very same pose again.
        self._last_pose: tuple[float, float, float] | None = None

    def sweep(self, stamp: float, origin: Pose2D) -> LaserScan:
        """One sweep from `origin` (map frame) taken at `stamp` s; the scene must be current (refresh)."""
        cfg = self.config
        scene = self._scene
        cos, sin = self._cos, self._sin
        pose = (origin.x, origin.y, origin.yaw)
        if pose != self._last_pose:  # else the beams and the walls' ranges are those of the last sweep
            if self._last_pose is None or origin.yaw != self._last_pose[2]:
                world_angles = np.add(self._angles, origin.yaw, out=self._world_angles)
                np.cos(world_angles, out=cos)
                np.sin(world_angles, out=sin)
                self._vec[:, 0] = cos
                self._vec[:, 1] = sin
            if self._sees_walls:
                scene.walls.cast(origin.x, origin.y, cos, sin, cfg.range_max, self._wall_dist)
            self._last_pose = pose
        self._pnt[0] = origin.x
        self._pnt[1] = origin.y
        self._pnt[2] = cfg.height
        model = scene.model
        _cast_bodies(
            scene.data.geom_xpos, scene.data.geom_xmat, model.geom_size, model.geom_type, model.geom_rbound,
            model.geom_bodyid, self._exclude, self._pnt, cfg.angle_min + origin.yaw, cfg.angle_increment,
            cfg.range_max, self._vec, self._dist,
        )
        ranges = np.empty(cfg.beams)
        _nearer(self._wall_dist, self._dist, cfg.range_max, ranges)
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


# Radius in m added to a geom's disc in the beam plane: a beam tangent to a bounding sphere (a sphere
# geom's own surface) is tested whatever the rounding of the angles. Testing a beam too many costs a
# little time, never a different range.
_DISC_MARGIN = 1e-6


# Compiled at import from numba's on-disk cache, as gridcast._cast (explicit signatures).
@numba.njit(
    "i8(i8, i8, i8, f8[:, ::1], f8[:, ::1], f8[:, ::1], i4[::1], f8[::1], f8[:, ::1], f8[::1])", cache=True, nogil=True
)
def _test(g, lo, hi, geom_xpos, geom_xmat, geom_size, geom_type, pnt, vec, dist):  # pragma: no cover - compiled
    """Beams lo..hi against geom g: dist[i] becomes the nearer of itself and the hit; returns the tests made."""
    pos, mat, size, at = geom_xpos[g].ctypes.data, geom_xmat[g].ctypes.data, geom_size[g].ctypes.data, pnt.ctypes.data
    kind = geom_type[g]
    for i in range(lo, hi + 1):
        hit = ray_geom(pos, mat, size, at, vec[i].ctypes.data, kind, numba.uintp(0))  # NULL: no normal
        if hit >= 0.0 and (dist[i] < 0.0 or hit < dist[i]):
            dist[i] = hit
    return max(hi - lo + 1, 0)


@numba.njit(
    "i8(f8[:, ::1], f8[:, ::1], f8[:, ::1], i4[::1], f8[::1], i4[::1], i8, f8[::1], f8, f8, f8, f8[:, ::1], f8[::1])",
    cache=True, nogil=True,
)
def _cast_bodies(geom_xpos, geom_xmat, geom_size, geom_type, geom_rbound, geom_bodyid, exclude, pnt, first_angle,
                 increment, max_range, vec, dist):  # pragma: no cover - compiled
    """dist[i]: the distance along beam i (from `pnt`, direction `vec[i]`) to the nearest scene geom it
    hits, -1 for none, testing each geom (mju_rayGeom) only against the beams that can reach it; returns
    the number of (beam, geom) tests. Beam i points at `first_angle + i * increment` rad, lies in the
    plane z = pnt[2] and ends at `max_range` m. Geoms of body `exclude` are skipped; a geom with
    geom_rbound 0 (a plane: MuJoCo's convention for unbounded), a lidar inside a geom's disc and a
    single beam (increment 0) test every beam against that geom."""
    n = vec.shape[0]
    dist[:] = -1.0
    tests = 0
    for g in range(geom_xpos.shape[0]):
        if geom_bodyid[g] == exclude:
            continue
        rbound = geom_rbound[g]
        if rbound <= 0.0 or increment <= 0.0:
            tests += _test(g, 0, n - 1, geom_xpos, geom_xmat, geom_size, geom_type, pnt, vec, dist)
            continue
        dz = geom_xpos[g, 2] - pnt[2]
        if abs(dz) > rbound + _DISC_MARGIN:
            continue  # the bounding sphere does not reach the beam plane (a drone above the robots)
        radius = math.sqrt(max(rbound * rbound - dz * dz, 0.0)) + _DISC_MARGIN  # of the disc in the plane
        dx = geom_xpos[g, 0] - pnt[0]
        dy = geom_xpos[g, 1] - pnt[1]
        d = math.sqrt(dx * dx + dy * dy)
        if d - radius > max_range:
            continue  # beyond the beams' reach
        if d <= radius:  # the lidar is inside the disc: any beam may hit
            tests += _test(g, 0, n - 1, geom_xpos, geom_xmat, geom_size, geom_type, pnt, vec, dist)
            continue
        half = math.asin(radius / d)
        centre = (math.atan2(dy, dx) - first_angle) % (2.0 * math.pi)  # from the first beam, in [0, 2 pi)
        for turn in (-2.0 * math.pi, 0.0, 2.0 * math.pi):  # the disc's interval may wrap past either end
            lo = max(math.ceil((centre - half + turn) / increment), 0)
            hi = min(math.floor((centre + half + turn) / increment), n - 1)
            tests += _test(g, lo, hi, geom_xpos, geom_xmat, geom_size, geom_type, pnt, vec, dist)
    return tests


@numba.njit("void(f8[::1], f8[::1], f8, f8[::1])", cache=True, nogil=True)
def _nearer(wall, dist, max_range, ranges):  # pragma: no cover - compiled
    """ranges[i]: the nearer of the wall's range `wall[i]` and MuJoCo's `dist[i]` (dist < 0: no hit), inf
    beyond `max_range` m."""
    for i in range(wall.shape[0]):
        w = wall[i]
        r = w if w <= max_range else math.inf
        d = dist[i]
        if 0.0 <= d <= max_range and d < r:
            r = d
        ranges[i] = r
