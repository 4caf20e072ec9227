"""run.rosbag2/: a run as a rosbag2 (MCAP storage, CDR-encoded standard ROS 2 messages) for ROS 2 tools
(`ros2 bag info`, `ros2 bag play`, rosbags, Foxglove), written with the `rosbags` package.

Owns: the bag's topics and their conversion from what a run did: per robot `/ROBOT/odom`
(nav_msgs/msg/Odometry, map frame), `/ROBOT/scan` (sensor_msgs/msg/LaserScan, every other sweep),
`/ROBOT/cmd_vel` (geometry_msgs/msg/Twist, the body's last command, when it changes), `/tf`
(tf2_msgs/msg/TFMessage, map -> ROBOT/base_link), and the paper's `/ROBOT/comm_protocol/command`
(rescuemesh_msgs/msg/Command, from the air records: type, direction, sender, receiver). Must not know:
MuJoCo; it reads the runtime duck-typed as report/recording.py does. Time is simulated time from the
run's start (the bag starts at the epoch), as in run.mcap.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from rescuemesh.protocol import MessageType
from rescuemesh.protocol.messages import COMMAND_TYPES
from rescuemesh.robot import robot_name

#: ROS 2 type definitions of the standard messages (Kilted's; the same fields since Humble).
STORE = Stores.ROS2_KILTED
COMMAND_TYPE = "rescuemesh_msgs/msg/Command"
MAP_FRAME, BASE_LINK = "map", "base_link"
#: Least time between two recorded scans of one robot, in simulated s (as run.mcap: every other sweep).
SCAN_PERIOD_S = 0.2
#: Air records shown on the command topics (the paper's: commands, PoseUpdates, Confirms).
PAPER_TYPES = {int(t): f"COMMAND_{t.name}" for t in MessageType
               if t in COMMAND_TYPES or t in (MessageType.CONFIRM, MessageType.POSE_UPDATE)}


def command_msgdef() -> str:
    """The text of rescuemesh_msgs/msg/Command (the ROS 2 package's)."""
    path = Path(__file__).resolve().parent.parent / "data" / "ros2" / "rescuemesh_msgs" / "msg" / "Command.msg"
    return path.read_text(encoding="utf-8")


def typestore():
    """The standard ROS 2 types plus rescuemesh_msgs/msg/Command."""
    store = get_typestore(STORE)
    store.register(get_types_from_msg(command_msgdef(), COMMAND_TYPE))
    return store


def _ns(time_s: float) -> int:
    return int(round(time_s * 1e9))


class RosbagRecorder:
    """Writes the run to the rosbag2 folder `path` (replaced if there). `tick()` after every control step,
    `finish()` once at the end (safe twice)."""

    def __init__(self, rt, path: Path) -> None:
        self.rt, self.path = rt, Path(path)
        if self.path.exists():
            shutil.rmtree(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.store = store = typestore()
        self.T = store.types
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self.names = list(rt.trajectories)
        bodies = rt.world.bodies
        self._lidars = {n: bodies[n] for n in self.names if not callable(getattr(bodies[n], "position_3d", None))}
        self._bodies = bodies
        self._conn: dict[str, object] = {}
        self.counts: dict[str, int] = {}
        self._pose_done = dict.fromkeys(self.names, 0)
        self._scan_stamp: dict[str, float | None] = dict.fromkeys(self._lidars)
        self._cmd: dict[str, tuple[float, float] | None] = dict.fromkeys(self.names)
        self._radio_done = 0
        self._next_tf_s = 0.0
        self.tick()

    # --- writing ---

    def _write(self, topic: str, msgtype: str, message, time_s: float) -> None:
        conn = self._conn.get(topic)
        if conn is None:
            conn = self._conn[topic] = self._writer.add_connection(topic, msgtype, typestore=self.store)
        self._writer.write(conn, _ns(time_s), self.store.serialize_cdr(message, msgtype))
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def _header(self, time_s: float, frame: str):
        t = max(0, _ns(time_s))
        return self.T["std_msgs/msg/Header"](stamp=self.T["builtin_interfaces/msg/Time"](
            sec=t // 1_000_000_000, nanosec=t % 1_000_000_000), frame_id=frame)

    def _vector(self, x: float = 0.0, y: float = 0.0, z: float = 0.0):
        return self.T["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))

    def _quaternion(self, yaw: float):
        return self.T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(0.5 * yaw), w=math.cos(0.5 * yaw))

    def _twist(self, v: float, w: float):
        return self.T["geometry_msgs/msg/Twist"](linear=self._vector(v), angular=self._vector(0.0, 0.0, w))

    def _odom(self, name: str, sample):
        T, p = self.T, sample.pose
        pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=p.x, y=p.y, z=0.0),
                                           orientation=self._quaternion(p.yaw))
        return T["nav_msgs/msg/Odometry"](
            header=self._header(sample.time_s, MAP_FRAME), child_frame_id=f"{name}/{BASE_LINK}",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=self._twist(sample.speed, 0.0),
                                                             covariance=np.zeros(36)))

    def _scan(self, name: str, scan):
        n = len(scan.ranges)
        return self.T["sensor_msgs/msg/LaserScan"](
            header=self._header(scan.stamp, f"{name}/{BASE_LINK}"), angle_min=float(scan.angle_min),
            angle_max=float(scan.angle_min + scan.angle_increment * (n - 1)),
            angle_increment=float(scan.angle_increment), time_increment=0.0, scan_time=0.1,
            range_min=float(scan.range_min), range_max=float(scan.range_max),
            ranges=np.asarray(scan.ranges, dtype=np.float32), intensities=np.zeros(0, dtype=np.float32))

    def _transform(self, name: str, time_s: float, pose):
        T = self.T
        return T["geometry_msgs/msg/TransformStamped"](
            header=self._header(time_s, MAP_FRAME), child_frame_id=f"{name}/{BASE_LINK}",
            transform=T["geometry_msgs/msg/Transform"](translation=self._vector(pose.x, pose.y),
                                                       rotation=self._quaternion(pose.yaw)))

    def _command(self, time_s: float, kind: str, direction: str, sender: str, receiver: str):
        T = self.T
        pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                                           orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))
        return T[COMMAND_TYPE](header=self._header(time_s, MAP_FRAME), type=kind, direction=direction,
                               sender=sender, receiver=receiver, seq=0, frame=pose, radius=0.0, period=0.0, count=0,
                               target="", ref_type="", ref_seq=0, result="", progress=0, reason="")

    # --- per control step ---

    def tick(self) -> None:
        """Write what happened up to `rt.time`."""
        now = self.rt.time
        for name in self.names:
            samples = self.rt.trajectories[name]
            for sample in samples[self._pose_done[name]:]:
                self._write(f"/{name}/odom", "nav_msgs/msg/Odometry", self._odom(name, sample), sample.time_s)
            self._pose_done[name] = len(samples)
            command = getattr(self._bodies[name], "command", None)
            if isinstance(command, tuple) and command != self._cmd[name]:
                self._cmd[name] = command
                self._write(f"/{name}/cmd_vel", "geometry_msgs/msg/Twist", self._twist(*command), now)
        if now >= self._next_tf_s and self.names:
            transforms = [self._transform(n, now, self.rt.trajectories[n][-1].pose) for n in self.names
                          if self.rt.trajectories[n]]
            self._write("/tf", "tf2_msgs/msg/TFMessage", self.T["tf2_msgs/msg/TFMessage"](transforms=transforms), now)
            self._next_tf_s = now + 0.1
        for name, body in self._lidars.items():
            scan = body.scan()
            last = self._scan_stamp[name]
            if scan is not None and (last is None or scan.stamp >= last + SCAN_PERIOD_S - 1e-6):
                self._scan_stamp[name] = scan.stamp
                self._write(f"/{name}/scan", "sensor_msgs/msg/LaserScan", self._scan(name, scan), scan.stamp)
        self._write_air(now)

    def _write_air(self, until_s: float) -> None:
        """Each original transmission of a paper message: SENT on its sender's command topic when it
        started, RECEIVED on its receiver's when it ended and was heard there."""
        records = self.rt.medium.records or []
        i = self._radio_done
        while i < len(records) and records[i].end_s <= until_s:
            r = records[i]
            i += 1
            kind = PAPER_TYPES.get(r.msg_type)
            if kind is None or r.relayed:
                continue
            try:
                sender, receiver = robot_name(r.src), robot_name(r.dst)
            except ValueError:  # a broadcast
                continue
            self._write(f"/{sender}/comm_protocol/command", COMMAND_TYPE,
                        self._command(r.start_s, kind, "SENT", sender, receiver), r.start_s)
            if r.dst_heard:
                self._write(f"/{receiver}/comm_protocol/command", COMMAND_TYPE,
                            self._command(r.end_s, kind, "RECEIVED", sender, receiver), r.end_s)
        self._radio_done = i

    def finish(self) -> Path:
        """Write what is left and close the bag; returns its folder."""
        if self._writer is not None:
            self._write_air(math.inf)
            self._writer.close()
            self._writer = None
        return self.path

    close = finish
