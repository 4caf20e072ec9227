"""run.mcap: a run as a Foxglove recording, and the same channels live on a Foxglove WebSocket.

Owns: the channel list (topics, schemas, frames, rates; docs/recording.md), turning what a run did
into messages stamped with simulated time, the MCAP file and the optional server on 127.0.0.1.
Must not know: MuJoCo or `rescuemesh.sim`, scenarios' scripts. It reads the runtime duck-typed:
`rt.time`, `rt.trajectories`, `rt.world.bodies`, `rt.medium.records`, and `rt.brains[name].log`
at most once per LOG_PERIOD_S per robot (a brain may live in another process: every read there is
a round trip).
"""

from __future__ import annotations

import math
import threading
from pathlib import Path

import foxglove
from foxglove.channels import (FrameTransformsChannel, GridChannel, LaserScanChannel, LogChannel,
                               PoseInFrameChannel, PosesInFrameChannel, SceneUpdateChannel)
from foxglove.messages import (Color, CubePrimitive, CylinderPrimitive, FrameTransform, FrameTransforms, Grid,
                               LaserScan, Log, LogLevel, PackedElementField, PackedElementFieldNumericType, Pose,
                               PoseInFrame, PosesInFrame, Quaternion, SceneEntity, SceneUpdate, TextPrimitive,
                               Timestamp, Vector2, Vector3)
from matplotlib.colors import to_rgb

from rescuemesh.protocol import BROADCAST, MessageType
from rescuemesh.report.live_origin import OriginGuard, origins_from_env
from rescuemesh.report.plots import robot_colours
from rescuemesh.robot import robot_name
from rescuemesh.robot.events import BehaviourEnded, BehaviourStarted, BrainEventKind

#: The fixed frame (REP-105); each robot's body frame is f"{name}/{BASE_LINK}".
MAP_FRAME, BASE_LINK = "map", "base_link"
#: How often the brains' logs are read, in simulated s (at most once per robot per period).
LOG_PERIOD_S = 1.0
#: How often each robot's path travelled is published, in simulated s (and once at the end).
PATH_PERIOD_S = 1.0
#: A pose joins the published path when it is this far from the last one kept, in m or rad.
PATH_STEP_M, PATH_STEP_RAD = 0.05, 0.2
#: Least time between two published scans of one robot, in simulated s: every other sweep of the
#: 10 Hz lidar (a scan is 683 ranges; at the full rate scans were about 40 % of the recording's cost).
SCAN_PERIOD_S = 0.2
#: Height in m of the scan plane drawn when the world does not say (sim.LidarConfig.height).
DEFAULT_SCAN_HEIGHT_M = 0.2
#: Height in m of a robot's body in the scene when the body has no `top_height`.
DEFAULT_BODY_HEIGHT_M = 0.3
#: Brain log kinds shown as warnings in Foxglove's Log panel; every other kind is INFO.
_K = BrainEventKind
WARNING_KINDS = frozenset({_K.COMMAND_GIVEN_UP, _K.FOLLOW_GIVEN_UP, _K.COMMAND_FAILED, _K.COMMAND_DENIED,
                           _K.COMMAND_REJECTED, _K.LINK_LOST, _K.TRANSFER_FAILED, _K.FORWARD_UNDELIVERED,
                           _K.FRAME_REJECTED, _K.PEER_RESTARTED, _K.WAYPOINTS_SKIPPED})

#: /radio/frames: one message per transmission on the air (rescuemesh.transport.sim_medium.AirRecord, decoded).
RADIO_SCHEMA = {
    "title": "rescuemesh.RadioFrame", "type": "object",
    "properties": {
        "time_s": {"type": "number", "description": "start of the transmission, simulated s"},
        "end_s": {"type": "number", "description": "end of the transmission, simulated s"},
        "transmitter": {"type": "string", "description": "the radio that put it on the air"},
        "source": {"type": "string", "description": "the robot that originated the frame"},
        "destination": {"type": "string", "description": "a robot, or 'broadcast'"},
        "type": {"type": "string", "description": "message type (rescuemesh.protocol.MessageType)"},
        "relayed": {"type": "boolean", "description": "a relay's copy, not the original"},
        "segment": {"type": ["integer", "null"], "description": "segment index of bulk data, or null"},
        "bytes": {"type": "integer", "description": "frame length on the air"},
        "result": {"type": "string", "enum": ["delivered", "lost"],
                   "description": "unicast: heard by the destination; broadcast: heard by any radio"},
        "heard_by": {"type": "integer", "description": "radios that received this transmission"},
        "collided": {"type": "boolean", "description": "a collision spoiled a reception somewhere"},
    },
}
#: /behaviours: a behaviour started or ended on a robot (from the brains' logs).
BEHAVIOUR_SCHEMA = {
    "title": "rescuemesh.Behaviour", "type": "object",
    "properties": {
        "time_s": {"type": "number"}, "robot": {"type": "string"},
        "event": {"type": "string", "enum": ["started", "ended"]},
        "behaviour": {"type": "string"}, "result": {"type": "string", "description": "ended: e.g. DONE, FAILED"},
        "detail": {"type": "string", "description": "the log line as the brain wrote it"},
    },
}


class LiveServerError(ValueError):
    """The live WebSocket server could not start (the port is taken, ...)."""


def ns(time_s: float) -> int:
    """Simulated seconds -> integer nanoseconds (MCAP log time; rounded, so 0.3 s is 300000000)."""
    return round(time_s * 1e9)


def _stamp(time_s: float) -> Timestamp:
    t = ns(time_s)
    return Timestamp(t // 1_000_000_000, t % 1_000_000_000)


def _pose(x: float, y: float, z: float, yaw: float) -> Pose:
    return Pose(position=Vector3(x=x, y=y, z=z), orientation=_yaw(yaw))


def _yaw(yaw: float) -> Quaternion:
    return Quaternion(z=math.sin(0.5 * yaw), w=math.cos(0.5 * yaw))


class RunRecorder:
    """Records a run to `path` (an MCAP file; None: no file) and, with `live_port`, serves the same
    channels on ws://127.0.0.1:live_port while it runs. Call `tick()` after every control step and
    `finish()` once at the end (or use it as a context manager: the file is closed and the server
    stopped even when the run fails). Messages carry simulated time: log time = publish time =
    header timestamp, in ns from the start of the run."""

    def __init__(self, rt, map_model, path: Path | None, *, live_port: int | None = None,
                 rosbag: Path | None = None, allowed_origins: tuple[str, ...] | None = None) -> None:
        """`allowed_origins`: web origins besides the local ones that may watch --live (default: from
        $RESCUEMESH_LIVE_ORIGINS; report/live_origin.py)."""
        self.rt = rt
        self.path = path
        self.rosbag = None  # with `rosbag`, the run also goes to a rosbag2 folder (report/rosbag.py)
        if rosbag is not None:
            from rescuemesh.report.rosbag import RosbagRecorder  # imports rosbags: only when asked for

            self.rosbag = RosbagRecorder(rt, rosbag)
        self._context = foxglove.Context()
        self._writer = self._server = self._guard = None
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._writer = foxglove.open_mcap(path, allow_overwrite=True, context=self._context)
        self._resend: set[str] = set()
        self._lock = threading.Lock()
        if live_port is not None:
            # the SDK's server on a private port, behind a front that checks each client's Origin
            # (a web page in the operator's browser must not read the run: live_origin.py)
            try:
                self._guard = OriginGuard("127.0.0.1", live_port, 0, allowed_origins
                                          if allowed_origins is not None else origins_from_env())
                self._server = foxglove.start_server(name="rescuemesh", host="127.0.0.1", port=0,
                                                     context=self._context, server_listener=_Subscriptions(self))
                self._guard.backend_port = self._server.port
            except Exception as error:  # the SDK raises its own RuntimeError subclasses
                if self._guard is not None:
                    self._guard.close()
                self._close_writer()
                raise LiveServerError(f"cannot serve --live on 127.0.0.1:{live_port}: {error}") from None
        ctx = self._context
        self.names = list(rt.trajectories)
        self._map = GridChannel("/map", context=ctx)
        self._scene = SceneUpdateChannel("/scene", context=ctx)
        self._tf = FrameTransformsChannel("/tf", context=ctx)
        self._log = LogChannel("/log", context=ctx)
        self._radio = foxglove.Channel("/radio/frames", schema=RADIO_SCHEMA, context=ctx)
        self._behaviours = foxglove.Channel("/behaviours", schema=BEHAVIOUR_SCHEMA, context=ctx)
        bodies = rt.world.bodies
        self._pose = {n: PoseInFrameChannel(f"/{n}/pose", context=ctx) for n in self.names}
        self._path = {n: PosesInFrameChannel(f"/{n}/path", context=ctx) for n in self.names}
        self._flyers = {n: bodies[n] for n in self.names if callable(getattr(bodies[n], "position_3d", None))}
        self._lidars = {n: bodies[n] for n in self.names if n not in self._flyers}
        self._scan = {n: LaserScanChannel(f"/{n}/scan", context=ctx) for n in self._lidars}
        lidar = getattr(rt.world, "lidar_config", None)
        self._scan_z = float(getattr(lidar, "height", DEFAULT_SCAN_HEIGHT_M))
        self._static = {"/map": (self._map, _grid(map_model)),
                        "/scene": (self._scene, _scene(map_model, bodies, self.names))}
        self._pose_done = dict.fromkeys(self.names, 0)
        self._topics = {n: (f"/{n}/pose", f"/{n}/scan", f"/{n}/path", f"{n}/{BASE_LINK}") for n in self.names}
        self._kept: dict[str, list[tuple[float, float, float, float]]] = {n: [] for n in self.names}
        self._kept_poses: dict[str, list[Pose]] = {n: [] for n in self.names}
        self._last_kept: dict[str, tuple[float, float, float]] = {}
        self._scan_stamp: dict[str, float | None] = dict.fromkeys(self._lidars)
        self._log_done = dict.fromkeys(self.names, 0)
        self._radio_done = 0
        self._next_log_s = self._next_path_s = 0.0
        self.counts: dict[str, int] = {}
        for topic, (channel, message) in self._static.items():
            self._emit(channel, topic, message, 0.0)
        self.tick()

    # --- per control step --------------------------------------------------------------------

    def tick(self) -> None:
        """Publish what happened up to `rt.time`: poses and transforms of new trajectory samples,
        new scans, radio frames whose fate is known, and (each LOG_PERIOD_S) new log lines."""
        now = self.rt.time
        if self.rosbag is not None:
            self.rosbag.tick()
        if self._resend:
            self._send_static_again(now)
        transforms = []
        for name in self.names:
            samples = self.rt.trajectories[name]
            z = self._flyers[name].position_3d()[2] if name in self._flyers else 0.0
            position = rotation = None
            for sample in samples[self._pose_done[name]:]:
                p = sample.pose
                position, rotation = Vector3(x=p.x, y=p.y, z=z), _yaw(p.yaw)
                self._emit(self._pose[name], self._topics[name][0],
                           PoseInFrame(timestamp=_stamp(sample.time_s), frame_id=MAP_FRAME,
                                       pose=Pose(position=position, orientation=rotation)), sample.time_s)
                self._keep(name, p.x, p.y, z, p.yaw)
            self._pose_done[name] = len(samples)
            if position is None:  # no new sample since the last tick
                p = samples[-1].pose
                position, rotation = Vector3(x=p.x, y=p.y, z=z), _yaw(p.yaw)
            transforms.append(FrameTransform(timestamp=_stamp(now), parent_frame_id=MAP_FRAME,
                                             child_frame_id=self._topics[name][3], translation=position,
                                             rotation=rotation))
        self._emit(self._tf, "/tf", FrameTransforms(transforms=transforms), now)
        for name, body in self._lidars.items():
            scan = body.scan()
            last = self._scan_stamp[name]
            if scan is not None and (last is None or scan.stamp >= last + SCAN_PERIOD_S - 1e-6):
                self._scan_stamp[name] = scan.stamp
                self._publish_scan(name, scan)
        self._publish_radio(now)
        if now >= self._next_log_s:
            self._publish_logs()
            self._next_log_s = now + LOG_PERIOD_S
        if now >= self._next_path_s:
            self._publish_paths(now)
            self._next_path_s = now + PATH_PERIOD_S

    def finish(self) -> Path | None:
        """Publish what is left (every radio frame, log line, the final paths), close the file and
        stop the server. Returns the file's path (None without a file). Safe to call twice."""
        if self._context is None:
            return self.path
        if self.rosbag is not None:
            self.rosbag.finish()
        self._publish_radio(math.inf)
        self._publish_logs()
        self._publish_paths(self.rt.time)
        self.close()
        return self.path

    def close(self) -> None:
        """Close the file and stop the server, publishing nothing more."""
        if self.rosbag is not None:
            self.rosbag.close()
        if self._guard is not None:
            self._guard.close()
            self._guard = None
        if self._server is not None:
            self._server.stop()
            self._server = None
        self._close_writer()
        self._context = None

    def __enter__(self) -> "RunRecorder":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def live_url(self) -> str | None:
        """ws://127.0.0.1:PORT while the live server runs, else None."""
        return f"ws://127.0.0.1:{self._guard.port}" if self._guard is not None else None

    # --- publishing --------------------------------------------------------------------------

    def _emit(self, channel, topic: str, message, time_s: float) -> None:
        channel.log(message, log_time=ns(time_s))
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def _publish_scan(self, name: str, scan) -> None:
        o = scan.origin
        end = scan.angle_min + scan.angle_increment * (len(scan.ranges) - 1)
        message = LaserScan(timestamp=_stamp(scan.stamp), frame_id=MAP_FRAME, pose=_pose(o.x, o.y, self._scan_z, o.yaw),
                            start_angle=scan.angle_min, end_angle=end, ranges=scan.ranges.tolist())
        self._emit(self._scan[name], self._topics[name][1], message, scan.stamp)

    def _publish_radio(self, until_s: float) -> None:
        """Each transmission once its fate is known (it ended by `until_s`), in the order sent."""
        records = self.rt.medium.records or []
        i = self._radio_done
        while i < len(records) and records[i].end_s <= until_s:
            r = records[i]
            heard = r.dst_heard if r.dst_heard is not None else r.heard_by > 0
            try:
                kind = MessageType(r.msg_type).name
            except ValueError:
                kind = str(r.msg_type)
            frame = {"time_s": r.start_s, "end_s": r.end_s, "transmitter": _who(r.transmitter), "source": _who(r.src),
                     "destination": _who(r.dst), "type": kind, "relayed": r.relayed, "segment": r.segment,
                     "bytes": len(r.frame), "result": "delivered" if heard else "lost", "heard_by": r.heard_by,
                     "collided": r.collided}
            self._emit(self._radio, "/radio/frames", frame, r.start_s)
            i += 1
        self._radio_done = i

    def _publish_logs(self) -> None:
        for name in self.names:
            log = self.rt.brains[name].log  # the one read of this brain this period (a ring: brain.BrainLog)
            for event in log.since(self._log_done[name]):
                level = LogLevel.Warning if event.kind in WARNING_KINDS else LogLevel.Info
                detail = event.detail  # the one rendering of the event as text
                text = f"{event.kind}: {detail}" if detail else str(event.kind)
                self._emit(self._log, "/log", Log(timestamp=_stamp(event.time_s), level=level, message=text,
                                                  name=event.robot), event.time_s)
                if isinstance(event, (BehaviourStarted, BehaviourEnded)):
                    self._emit(self._behaviours, "/behaviours", _behaviour(event), event.time_s)
            self._log_done[name] = log.total

    def _keep(self, name: str, x: float, y: float, z: float, yaw: float) -> None:
        last = self._last_kept.get(name)
        if last is None or math.hypot(x - last[0], y - last[1]) >= PATH_STEP_M or abs(
                math.remainder(yaw - last[2], math.tau)) >= PATH_STEP_RAD:
            self._kept[name].append((x, y, z, yaw))
            self._last_kept[name] = (x, y, yaw)

    def _publish_paths(self, now: float) -> None:
        for name in self.names:
            p = self.rt.trajectories[name][-1].pose
            z = self._flyers[name].position_3d()[2] if name in self._flyers else 0.0
            built = self._kept_poses[name]  # Pose objects made once, at the first publish after each keep
            built.extend(_pose(*kept) for kept in self._kept[name][len(built):])
            poses = built + [_pose(p.x, p.y, z, p.yaw)]  # up to where the robot is now
            self._emit(self._path[name], self._topics[name][2],
                       PosesInFrame(timestamp=_stamp(now), frame_id=MAP_FRAME, poses=poses), now)

    def _send_static_again(self, now: float) -> None:
        """A live client subscribed to /map or /scene after it was sent: send it again, now."""
        with self._lock:
            topics, self._resend = self._resend, set()
        for topic in sorted(topics):
            channel, message = self._static[topic]
            self._emit(channel, topic, message, now)

    def _close_writer(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None


class _Subscriptions:
    """The live server's listener (called on the server's thread): notes late subscribers to the
    messages sent once, so the next tick sends them again."""

    def __init__(self, recorder: RunRecorder) -> None:
        self.recorder = recorder

    def on_subscribe(self, client, channel) -> None:
        if channel.topic in ("/map", "/scene"):
            with self.recorder._lock:
                self.recorder._resend.add(channel.topic)

    def on_unsubscribe(self, client, channel) -> None:
        pass


def _who(address: int) -> str:
    if address == BROADCAST:
        return "broadcast"
    return robot_name(address) if 1 <= address <= 254 else str(address)


def _behaviour(event: BehaviourStarted | BehaviourEnded) -> dict:
    started = isinstance(event, BehaviourStarted)
    return {"time_s": event.time_s, "robot": event.robot, "event": "started" if started else "ended",
            "behaviour": event.detail if started else event.behaviour, "result": "" if started else event.result.name,
            "detail": event.detail}


def _grid(map_model) -> Grid:
    """The occupancy grid as nav_msgs/OccupancyGrid values: 100 occupied, 0 free (int8, row 0 at
    the lowest y, cell (0, 0)'s corner at the grid's origin)."""
    grid = map_model.grid
    rows, cols = grid.shape
    data = (grid.occupied.astype("int8") * 100).tobytes()
    return Grid(timestamp=_stamp(0.0), frame_id=MAP_FRAME, pose=_pose(grid.origin_x, grid.origin_y, 0.0, 0.0),
                column_count=cols, cell_size=Vector2(x=grid.resolution, y=grid.resolution), row_stride=cols,
                cell_stride=1, fields=[PackedElementField(name="occupancy", offset=0,
                                                          type=PackedElementFieldNumericType.Int8)], data=data)


def _scene(map_model, bodies, names) -> SceneUpdate:
    """The walls (boxes in `map`) and one body per robot, a cylinder with its name, locked to its
    base_link so it moves with /tf. Colours as in trajectory.png."""
    h = map_model.wall_height
    walls = [CubePrimitive(pose=_pose(0.5 * (w.x_min + w.x_max), 0.5 * (w.y_min + w.y_max), 0.5 * h, 0.0),
                           size=Vector3(x=w.x_max - w.x_min, y=w.y_max - w.y_min, z=h),
                           color=Color(r=0.55, g=0.55, b=0.6, a=0.8)) for w in map_model.walls]
    entities = [SceneEntity(timestamp=_stamp(0.0), frame_id=MAP_FRAME, id="walls", cubes=walls)]
    for name, colour in robot_colours(names).items():
        r, g, b = to_rgb(colour)
        body = bodies[name]
        radius = float(getattr(body, "radius", 0.18))
        height = float(getattr(body, "top_height", None) or DEFAULT_BODY_HEIGHT_M)
        entities.append(SceneEntity(
            timestamp=_stamp(0.0), frame_id=f"{name}/{BASE_LINK}", id=name, frame_locked=True,
            cylinders=[CylinderPrimitive(pose=_pose(0.0, 0.0, 0.5 * height, 0.0),
                                         size=Vector3(x=2 * radius, y=2 * radius, z=height),
                                         bottom_scale=1.0, top_scale=1.0, color=Color(r=r, g=g, b=b, a=0.9))],
            cubes=[CubePrimitive(pose=_pose(0.7 * radius, 0.0, height + 0.01, 0.0),  # a mark on the side it faces
                                 size=Vector3(x=0.6 * radius, y=0.2 * radius, z=0.02),
                                 color=Color(r=0, g=0, b=0, a=1))],
            texts=[TextPrimitive(pose=_pose(0.0, 0.0, height + 0.25, 0.0), billboard=True, font_size=14,
                                 scale_invariant=True, color=Color(r=r, g=g, b=b, a=1.0), text=name)]))
    return SceneUpdate(entities=entities)
