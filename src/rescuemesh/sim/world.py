"""World: a MuJoCo office with TurtleBots (and quadrotors), stepped in whole physics steps on simulated time.

Owns: the MjModel/MjData, the step loop, the lidar schedule, odometry commits and collision
episodes. Must not know: brains, navigation, the radio or the wall clock (the runtime calls step).

Theory of operation: time is an integer count of physics steps (time = steps * physics_dt), so
schedules never drift. Physics runs one mj_step at a time so that the chassis contact sensors are
read after every step; everything else happens at fixed step counts, independent of how the caller
slices `step()`: odometry commits every ODOMETRY_PERIOD_S, lidar sweeps every 1 / rate_hz (the
first at time 0). Same inputs and the same call sequence give bit-identical trajectories.
A quadrotor's autopilot runs before every physics step (160 Hz at the default 6.25 ms step, 200 Hz
at 5 ms; its flights measured the same at both, docs/physics.md): its attitude loop needs such a rate,
and it sees the state the physics will integrate from. Worlds without quadrotors
run the original loop untouched.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import mujoco
import numpy as np

from rescuemesh.body import RobotKind
from rescuemesh.geometry import Pose2D
from rescuemesh.maps.model import MapModel
from rescuemesh.sim import mjcf
from rescuemesh.sim.body import SimBody
from rescuemesh.sim.camera import CameraConfig, Cameras
from rescuemesh.sim.lidar import Lidar, LidarConfig, LidarScene
from rescuemesh.sim.quadrotor import SimQuadrotor, quadrotor_part

ODOMETRY_PERIOD_S = 0.05  # s between odometry commits (a Kobuki reports odometry at 50 Hz)
# A robot's chassis must be free of contact this long (s) before a new touch counts as a new
# collision episode; grinding along a wall with brief separations stays one episode.
COLLISION_GAP_S = 0.25


class World:
    """The simulated office: one MuJoCo model with the map's walls and one robot per start pose.

    - `map_model`: walls (extruded to `map_model.wall_height` m) and the grid used to check starts.
    - `starts`: robot name -> start pose in the map frame; names become MuJoCo element prefixes.
    - `physics_dt`: physics step in s, at most mjcf.MAX_PHYSICS_DT (7.5 ms).
    - `lidar`: the lidar of every robot.
    - `seed`: an int or a numpy Generator for the lidar noise (the only randomness; the physics is
      deterministic).
    - `kinds`: robot name -> RobotKind for robots that are not GROUND (TurtleBots); a FLYING robot is
      a quadrotor (sim/quadrotor.py) resting on the floor at its start pose, rotors off, no lidar.
    - `camera`: the forward camera of every TurtleBot (sim/camera.py), rendered only when a body's
      `camera()` is called; None: no cameras (`camera()` returns None).

    Attributes: `bodies` (name -> SimBody, or SimQuadrotor for a flying robot, in the order of
    `starts`), `model` and `data` (MuJoCo, for viewers and diagnostics; do not step them directly),
    `xml` (the MJCF text). Every TurtleBot has a top plate (`top_height` m) a quadrotor can land on.
    """

    def __init__(
        self,
        map_model: MapModel,
        starts: Mapping[str, Pose2D],
        *,
        physics_dt: float = mjcf.PHYSICS_DT,
        lidar: LidarConfig = LidarConfig(),
        seed: int | np.random.Generator = 0,
        kinds: Mapping[str, RobotKind] | None = None,
        camera: CameraConfig | None = CameraConfig(),
    ) -> None:
        if not (math.isfinite(physics_dt) and 0.0 < physics_dt <= mjcf.MAX_PHYSICS_DT):
            raise ValueError(f"physics_dt must be in (0, {mjcf.MAX_PHYSICS_DT}] s, got {physics_dt}")
        if not starts:
            raise ValueError("a World needs at least one robot start pose")
        for name, pose in starts.items():
            if not isinstance(name, str) or not name or any(c in name for c in "<>&\"'"):
                raise ValueError(f"robot name {name!r} must be a non-empty string without XML special characters")
            if map_model.grid.is_occupied(pose.x, pose.y):
                raise ValueError(f"start of {name} at ({pose.x:g}, {pose.y:g}) m is inside an obstacle or off the map")
        kinds = dict(kinds or {})
        for name, kind in kinds.items():
            if name not in starts or not isinstance(kind, RobotKind):
                raise ValueError(f"kinds: {name!r} -> {kind!r} must name a robot in starts and give a RobotKind")
        self.kinds: dict[str, RobotKind] = {n: kinds.get(n, RobotKind.GROUND) for n in starts}
        ground = [n for n in starts if self.kinds[n] is RobotKind.GROUND]
        flying = [n for n in starts if self.kinds[n] is RobotKind.FLYING]
        self.map_model = map_model
        self.physics_dt = float(physics_dt)
        self.lidar_config = lidar
        parts = [quadrotor_part(n, starts[n]) for n in flying]
        self.xml = mjcf.world_xml(map_model, {n: starts[n] for n in ground}, self.physics_dt, parts)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.data = mujoco.MjData(self.model)
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)

        names = list(starts)
        plates = {self.model.geom(mjcf.plate_name(n)).id: n for n in ground}
        self._flyers = [
            SimQuadrotor(n, self.model, self.data, lambda: self.time, self.physics_dt, plates) for n in flying
        ]
        flyer = {q.name: q for q in self._flyers}
        self.bodies: dict[str, SimBody | SimQuadrotor] = {
            n: flyer[n] if n in flyer else SimBody(n, self.model, self.data, starts[n]) for n in names
        }
        for n in ground:
            self.bodies[n].top_height = mjcf.PLATE_TOP
        child_rngs = rng.spawn(len(ground))
        mujoco.mj_kinematics(self.model, self.data)
        walls = [self.model.geom(mjcf.wall_name(i)).id for i in range(len(map_model.walls))]
        self._lidar_scene = LidarScene(self.model, self.data, map_model, walls)
        self._lidars = {
            n: Lidar(self._lidar_scene, self.bodies[n].body_id, lidar, child_rngs[i]) for i, n in enumerate(ground)
        }
        self.cameras = Cameras(self.model, self.data, ground, camera) if camera is not None else None
        if self.cameras is not None:
            for n in ground:
                self.bodies[n].attach_camera(lambda n=n: self.cameras.capture(n, self.time))
        order = ground + flying  # the order of the bump sensors (mjcf.world_xml)
        self._ground = [self.bodies[n] for n in ground]
        self._index = {n: order.index(n) for n in names}
        adr = [int(self.model.sensor_adr[self.model.sensor(mjcf.bump_sensor_name(n)).id]) for n in order]
        if adr != list(range(adr[0], adr[0] + len(adr))):
            raise RuntimeError("bump sensors are not contiguous in sensordata")  # guards the view below
        self._bump = self.data.sensordata[adr[0] : adr[0] + len(names)]  # view: contacts of each chassis

        self._steps = 0
        self._scan_every = max(1, round(1.0 / (lidar.rate_hz * self.physics_dt)))
        self._odom_every = max(1, round(ODOMETRY_PERIOD_S / self.physics_dt))
        self._gap_steps = max(1, round(COLLISION_GAP_S / self.physics_dt))
        self._collisions = [0] * len(names)  # indexed like self._bump
        self._open: dict[int, int] = {}  # open collision episodes: index like self._bump -> step of the last touch

        mujoco.mj_forward(self.model, self.data)
        self._sweep()

    # ------------------------------------------------------------ public

    @property
    def time(self) -> float:
        """Simulated time in s since the world was built."""
        return self._steps * self.physics_dt

    @property
    def steps(self) -> int:
        """Physics steps taken since the world was built."""
        return self._steps

    @property
    def scan_period(self) -> float:
        """Time in s between lidar sweeps: 1 / rate_hz rounded to whole physics steps."""
        return self._scan_every * self.physics_dt

    @property
    def collisions(self) -> dict[str, int]:
        """Robot name -> number of collision episodes so far (chassis against a wall or another chassis).

        An episode starts when a chassis touches after at least COLLISION_GAP_S s free of contact.
        """
        return {n: self._collisions[i] for n, i in self._index.items()}

    def contacts_now(self, name: str) -> bool:
        """True while `name`'s chassis touches a wall or another robot's chassis (after the last step).

        For a quadrotor: while its frame (not its feet) touches anything.
        """
        return bool(self._bump[self._index[name]] > 0.0)

    def top_offset(self, flyer: str, robot: str) -> float:
        """Horizontal distance in m from quadrotor `flyer`'s centre to the centre of `robot`'s top plate."""
        q = self.bodies[flyer]
        if not isinstance(q, SimQuadrotor) or self.kinds[robot] is not RobotKind.GROUND:
            raise ValueError(f"top_offset needs a flying robot and a ground robot, got {flyer!r} and {robot!r}")
        plate = self.bodies[robot].pose()  # the plate is centred on the base (its tilt moves it < 1 mm)
        x, y, _ = q.position_3d()
        return math.hypot(x - plate.x, y - plate.y)

    def close(self) -> None:
        """Free the cameras' OpenGL context, if one was made (a later image makes a new one)."""
        if self.cameras is not None:
            self.cameras.close()

    def step(self, duration_s: float) -> None:
        """Advance simulated time by `duration_s` s, rounded to a whole number of physics steps.

        A caller with a fixed control period that is not a whole number of physics steps should
        use `step_to` so the rounding does not accumulate.
        """
        if not (math.isfinite(duration_s) and duration_s >= 0.0):
            raise ValueError(f"step duration must be a finite number of s >= 0, got {duration_s}")
        self._advance(round(duration_s / self.physics_dt))

    def step_to(self, time_s: float) -> None:
        """Advance to the physics step nearest `time_s` s (no-op when already there or past it)."""
        if not math.isfinite(time_s):
            raise ValueError(f"target time must be finite, got {time_s}")
        self._advance(round(time_s / self.physics_dt) - self._steps)

    # ------------------------------------------------------------ the loop

    def _advance(self, n: int) -> None:
        target = self._steps + max(0, n)
        while self._steps < target:
            next_odom = (self._steps // self._odom_every + 1) * self._odom_every
            next_scan = (self._steps // self._scan_every + 1) * self._scan_every
            stop = min(target, next_odom, next_scan)
            self._physics(stop - self._steps)
            for body in self._ground:
                body.moved()
            if self._steps % self._odom_every == 0:
                for body in self.bodies.values():
                    body.commit_odometry()
            if self._steps % self._scan_every == 0:
                self._sweep()

    def _physics(self, n: int) -> None:
        """`n` physics steps, reading the chassis contact sensors after each."""
        m, d, bump, count_nonzero = self.model, self.data, self._bump, np.count_nonzero
        if self._flyers:
            return self._physics_flying(n)
        for _ in range(n):
            mujoco.mj_step(m, d)
            self._steps += 1
            if self._open or count_nonzero(bump):
                self._update_episodes()

    def _physics_flying(self, n: int) -> None:
        """As `_physics`, with every quadrotor's autopilot stepped before each physics step."""
        m, d, bump, flyers, dt = self.model, self.data, self._bump, self._flyers, self.physics_dt
        count_nonzero = np.count_nonzero
        for _ in range(n):
            now = self._steps * dt
            for q in flyers:
                q.control(now)
            mujoco.mj_step(m, d)
            self._steps += 1
            if self._open or count_nonzero(bump):
                self._update_episodes()

    def _update_episodes(self) -> None:
        """Open an episode for every chassis touching now and not in one; close those free for the gap.

        Visits only the touching chassis and the open episodes (a few), not every robot: with many
        robots this runs every physics step while any episode is open.
        """
        steps, episodes = self._steps, self._open
        for i in np.flatnonzero(self._bump).tolist():
            if i not in episodes:
                self._collisions[i] += 1
            episodes[i] = steps
        for i in [i for i, last in episodes.items() if steps - last >= self._gap_steps]:
            del episodes[i]

    def _sweep(self) -> None:
        """One lidar sweep per robot at the current time (kinematics refreshed for current qpos)."""
        mujoco.mj_kinematics(self.model, self.data)
        self._lidar_scene.refresh()
        now = self.time
        for name, lidar in self._lidars.items():
            body = self.bodies[name]
            body.set_scan(lidar.sweep(now, body.pose()))
