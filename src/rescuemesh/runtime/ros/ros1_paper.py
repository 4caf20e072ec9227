"""The paper's ROS 1 interface to a robot: what it sends and receives on `/ROBOT/comm_protocol/command`
(a rescuemesh_msgs/Command with the paper's type names, COMMAND_FOLLOW, COMMAND_CONFIRM ...) and the
leader's pose on `/ROBOT/comm_protocol/follow` (geometry_msgs/PoseStamped), for ROS tools; and
requests from a ROS node on `/ROBOT/comm_protocol/command/input`, so a ROS node can command the team.

Owns: the Command message's Python classes (generated from data/ros1/rescuemesh_msgs with genpy
into a cache directory that both the robot and `rostopic` import), the tap that sees what the
brain sends and receives through its endpoint, the conversions to and from Command, and the
request table. Must not know: frames, the mesh, the transport (it never reads a frame: it sees the
brain's calls and the endpoint's decoded events), the loop (the runtime calls `step(now)`).

Why a separate input topic: the command topic is a record of what crossed the radio, written by
the robot alone; a request on the same topic would be read back by every bridge that writes it,
and a record fed back (a recorded bag played, a relay loop) would look like a request. On
`.../command/input` everything is a request, and one with `direction` set is refused as a record.
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import math
import os
import queue
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from rescuemesh.geometry import Pose2D, yaw_to_quaternion
from rescuemesh.protocol import (
    CommandReceived, ConfirmReceived, LandOnTop, MessageType, Pose, PoseUpdateReceived, Reason, ShowCam,
    ShowScan)
from rescuemesh.protocol.messages import Confirm, PoseUpdate
from rescuemesh.protocol.messages import COMMAND_TYPES, PROGRESS_UNKNOWN
from rescuemesh.robot import robot_address, robot_name
from rescuemesh.robot.records import to_wire_pose
from rescuemesh.runtime.ros.ros1_body import ROS1_INSTALL_HINT, Ros1Unavailable, import_rospy, quaternion_msg_to_yaw

MSG_PACKAGE = "rescuemesh_msgs"
#: Environment variable naming the directory the generated classes are cached under.
MSG_CACHE_ENV = "RESCUEMESH_ROS1_MSGS"
#: Message packages Command.msg uses, whose .msg definitions genpy reads.
MSG_DEPENDENCIES = ("std_msgs", "geometry_msgs")

#: The Command message's `type` of each protocol message (the paper's COMMAND_ prefix).
TYPE_NAME: dict[MessageType, str] = {t: f"COMMAND_{t.name}" for t in MessageType
                                     if t in COMMAND_TYPES or t in (MessageType.CONFIRM, MessageType.POSE_UPDATE)}
TYPE_BY_NAME: dict[str, MessageType] = {name: t for t, name in TYPE_NAME.items()}
SENT, RECEIVED = "SENT", "RECEIVED"
#: Received messages whose pose is the leader's, published on .../follow as well.
LEADER_POSE = frozenset({MessageType.FOLLOW, MessageType.LAND_ON_TOP, MessageType.POSE_UPDATE})
#: Commands with a `frame` a request must give (the others take the sender's pose, or none).
FRAME_REQUIRED = frozenset({MessageType.GOTO, MessageType.SHOW_CAM, MessageType.SHOW_SCAN})


# ----- the message classes -----

def msg_package_dir() -> Path:
    """The catkin-style package with Command.msg (package.xml beside it)."""
    return Path(__file__).resolve().parents[2] / "data" / "ros1" / MSG_PACKAGE  # rescuemesh/data


def _dependency_dirs() -> dict[str, list[str]]:
    roots = [p for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    roots += ["/usr/share", *sorted(str(p) for p in Path("/opt/ros").glob("*/share"))]
    found = {}
    for package in MSG_DEPENDENCIES:
        dirs = [str(Path(root) / package / "msg") for root in roots if (Path(root) / package / "msg").is_dir()]
        if not dirs:
            raise Ros1Unavailable(f"the .msg definitions of {package} are not found on ROS_PACKAGE_PATH or in "
                                  f"/usr/share (Debian: apt-get install ros-{package.replace('_', '-')}). "
                                  f"{ROS1_INSTALL_HINT}")
        found[package] = dirs[:1]
    return found


def message_path(base: str | os.PathLike | None = None) -> Path:
    """The directory to put on PYTHONPATH so that `import rescuemesh_msgs.msg` works (the robot
    and `rostopic` alike). The classes are generated with genpy once per message definition, under
    `base` (default: $RESCUEMESH_ROS1_MSGS, else ~/.cache/rescuemesh/ros1_msgs), named by its hash."""
    sources = sorted((msg_package_dir() / "msg").glob("*.msg"))
    digest = hashlib.sha256(b"".join(p.name.encode() + b"\0" + p.read_bytes() for p in sources)).hexdigest()[:16]
    if base is None:
        cache = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
        base = os.environ.get(MSG_CACHE_ENV) or Path(cache) / "rescuemesh" / "ros1_msgs"
    target = Path(base) / digest
    if (target / MSG_PACKAGE / "msg" / "__init__.py").is_file():
        return target
    try:
        from genpy.generate_initpy import write_modules
        from genpy.generator import MsgGenerator
    except ImportError as exc:
        raise Ros1Unavailable(f"cannot import genpy ({exc}). {ROS1_INSTALL_HINT}") from exc
    search = {MSG_PACKAGE: [str(msg_package_dir() / "msg")], **_dependency_dirs()}
    Path(base).mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".generating-", dir=base))
    try:
        out = staging / MSG_PACKAGE / "msg"
        if MsgGenerator().generate_messages(MSG_PACKAGE, [str(p) for p in sources], str(out), search) != 0:
            raise Ros1Unavailable(f"genpy could not generate {MSG_PACKAGE} from {msg_package_dir()} (see above)")
        write_modules(str(out))
        (staging / MSG_PACKAGE / "__init__.py").write_text("")
        try:
            staging.rename(target)  # atomic: robots starting together never see half a package
        except OSError:
            if not (target / MSG_PACKAGE / "msg" / "__init__.py").is_file():
                raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return target


def load_command_class(base: str | os.PathLike | None = None):
    """rescuemesh_msgs.msg.Command, generated if need be and its directory put on sys.path."""
    path = str(message_path(base))
    if path not in sys.path:
        sys.path.insert(0, path)
        importlib.invalidate_caches()
    from rescuemesh_msgs.msg import Command
    return Command


# ----- what the brain sends and receives -----

@dataclass(frozen=True, slots=True)
class Traffic:
    """One protocol message a robot sent or received: a command, a PoseUpdate or a Confirm.
    `seq`: the frame's sequence number (0 for a Confirm, which is matched by its ref_seq)."""

    direction: str  # SENT or RECEIVED
    sender: int
    receiver: int
    seq: int
    message: object


class EndpointTap:
    """Stands in for a brain's endpoint: passes every call through and hands `sink` a Traffic for
    each command, PoseUpdate and Confirm the brain sends, and for each the brain takes in. Cached
    copies the endpoint re-sends by itself (a lost Confirm, a repeated final report) are not seen."""

    def __init__(self, endpoint, sink) -> None:
        self._endpoint, self._sink = endpoint, sink
        self._received = {CommandReceived: lambda e: (e.src, e.seq, e.command),
                          PoseUpdateReceived: lambda e: (e.src, e.seq, PoseUpdate(e.pose)),
                          ConfirmReceived: lambda e: (e.src, 0, Confirm(e.ref_seq, e.ref_type, e.result, e.progress,
                                                                        e.reason))}

    def __getattr__(self, name: str):
        return getattr(self._endpoint, name)

    def send_command(self, dst: int, command, now: float) -> int:
        seq = self._endpoint.send_command(dst, command, now)
        self._sink(Traffic(SENT, self._endpoint.address, dst, seq, command))
        return seq

    def send_pose_update(self, dst: int, pose: Pose, now: float) -> int:
        seq = self._endpoint.send_pose_update(dst, pose, now)
        self._sink(Traffic(SENT, self._endpoint.address, dst, seq, PoseUpdate(pose)))
        return seq

    def confirm(self, dst: int, ref_seq: int, ref_type: MessageType, result, now: float,
                progress: int = PROGRESS_UNKNOWN, reason: Reason = Reason.NONE) -> None:
        self._endpoint.confirm(dst, ref_seq, ref_type, result, now, progress=progress, reason=reason)
        self._sink(Traffic(SENT, self._endpoint.address, dst, 0, Confirm(ref_seq, ref_type, result, progress, reason)))

    def next_event(self):
        event = self._endpoint.next_event()
        seen = self._received.get(type(event))
        if seen is not None:
            src, seq, message = seen(event)
            self._sink(Traffic(RECEIVED, src, self._endpoint.address, seq, message))
        return event


def _name(address: int) -> str:
    try:
        return robot_name(address)
    except ValueError:
        return str(address)


def fill_pose(msg_pose, pose: Pose) -> None:
    """Write a protocol Pose into a geometry_msgs/Pose."""
    msg_pose.position.x, msg_pose.position.y, msg_pose.position.z = pose.x, pose.y, pose.z
    o = msg_pose.orientation
    o.x, o.y, o.z, o.w = yaw_to_quaternion(pose.yaw)


def fill_command(msg, traffic: Traffic) -> None:
    """Write `traffic` into a rescuemesh_msgs/Command (the header's stamp is the caller's)."""
    m = traffic.message
    msg.header.frame_id = "map"
    msg.type = TYPE_NAME[m.TYPE]
    msg.direction, msg.sender, msg.receiver, msg.seq = (traffic.direction, _name(traffic.sender),
                                                        _name(traffic.receiver), traffic.seq)
    pose = getattr(m, "frame", None) or getattr(m, "center", None) or getattr(m, "pose", None)
    if pose is not None:
        fill_pose(msg.frame, pose)
    else:
        msg.frame.orientation.w = 1.0  # a valid quaternion where there is no pose (RViz refuses 0, 0, 0, 0)
    msg.radius = getattr(m, "radius_m", 0.0)
    msg.period, msg.count = getattr(m, "period_s", 0.0), getattr(m, "count", 0)
    if hasattr(m, "target"):
        msg.target = _name(m.target)
    if isinstance(m, Confirm):
        msg.ref_type = TYPE_NAME.get(m.ref_type, m.ref_type.name)
        msg.ref_seq, msg.result, msg.progress, msg.reason = m.ref_seq, m.result.name, m.progress, m.reason.name


# ----- requests from a ROS node -----

class RequestError(ValueError):
    """A Command on the input topic that cannot be carried out; the text says why."""


@dataclass(frozen=True, slots=True)
class Request:
    """A ROS node's request: this robot sends command `type` to robot `receiver` (an address)."""

    type: MessageType
    receiver: int
    frame: Pose2D | None = None
    radius_m: float = 0.0
    period_s: float = 0.0
    count: int = 1


#: What the brain does for each request type (any other is refused by parse_request).
REQUESTS = {
    MessageType.FOLLOW: lambda brain, r, now: brain.command_follow(r.receiver, now),
    MessageType.STOP: lambda brain, r, now: brain.command_stop(r.receiver, now),
    MessageType.RETURN: lambda brain, r, now: brain.command_return(r.receiver, now),
    MessageType.GOTO: lambda brain, r, now: brain.command_goto(r.receiver, r.frame, now),
    MessageType.MOVE_AROUND: lambda brain, r, now: brain.command_move_around(r.receiver, r.radius_m, now),
    MessageType.SHOW_SCAN: lambda brain, r, now: brain.send(
        r.receiver, ShowScan(to_wire_pose(r.frame), r.period_s, r.count), now),
    MessageType.SHOW_CAM: lambda brain, r, now: brain.send(
        r.receiver, ShowCam(to_wire_pose(r.frame), r.period_s, r.count), now),
    MessageType.LAND_ON_TOP: lambda brain, r, now: brain.send(
        r.receiver, LandOnTop(to_wire_pose(brain.body.pose())), now),
}


def parse_request(msg, robot: str) -> Request:
    """The request a Command on `robot`'s input topic makes, or RequestError saying what is wrong."""
    kind = TYPE_BY_NAME.get(msg.type)
    if kind is None:
        raise RequestError(f"unknown type {msg.type!r} (one of {', '.join(TYPE_BY_NAME)})")
    if kind not in REQUESTS:
        raise RequestError(f"{msg.type} is not accepted as a request (one of "
                           f"{', '.join(TYPE_NAME[t] for t in REQUESTS)})")
    if msg.direction:
        raise RequestError(f"direction {msg.direction!r} is set: a record of .../command, not a request")
    if msg.sender and msg.sender != robot:
        raise RequestError(f"sender {msg.sender!r}: a request on {robot}'s input is sent by {robot}")
    try:
        receiver = robot_address(msg.receiver)
    except ValueError as exc:
        raise RequestError(f"receiver: {exc}") from None
    if msg.receiver == robot:
        raise RequestError(f"receiver {robot} is this robot: a robot does not command itself")
    frame = None
    if kind in FRAME_REQUIRED:
        if msg.header.frame_id not in ("", "map"):
            raise RequestError(f"frame is in {msg.header.frame_id!r}; only 'map' is known")
        p, o = msg.frame.position, msg.frame.orientation
        if not all(math.isfinite(v) for v in (p.x, p.y, p.z, o.x, o.y, o.z, o.w)):
            raise RequestError("frame has a value that is not finite")
        frame = Pose2D(p.x, p.y, quaternion_msg_to_yaw(o))
    if kind is MessageType.MOVE_AROUND and not (math.isfinite(msg.radius) and msg.radius > 0):
        raise RequestError(f"radius must be a positive number of m, got {msg.radius}")
    if not (math.isfinite(msg.period) and msg.period >= 0):
        raise RequestError(f"period must be >= 0 s, got {msg.period}")
    return Request(kind, receiver, frame, float(msg.radius), float(msg.period), int(msg.count))


# ----- the bridge -----

class Ros1Paper:
    """The paper's topics for one robot's brain (the ROS node must be initialised: ros1_body.init_node).

    Publishes, from the moment it is made, every command, PoseUpdate and Confirm the brain sends or
    receives on `NS/comm_protocol/command` and the leader's pose a follower is given (the Follow's
    frame, each PoseUpdate) on `NS/comm_protocol/follow`; takes requests on
    `NS/comm_protocol/command/input` and carries them out in `step(now)`, on the runtime's thread
    (the brain is not thread-safe). `NS` is `/ROBOT` unless `namespace` says otherwise. A malformed
    request is a ROS warning and nothing else.
    """

    def __init__(self, brain, *, namespace: str | None = None, msg_cache: str | os.PathLike | None = None) -> None:
        rospy = import_rospy()
        from geometry_msgs.msg import PoseStamped
        self._rospy, self._pose_stamped = rospy, PoseStamped
        self._command_class = load_command_class(msg_cache)
        self.brain = brain
        self.namespace = (namespace if namespace is not None else f"/{brain.name}").rstrip("/")
        self.command_topic = f"{self.namespace}/comm_protocol/command"
        self.follow_topic = f"{self.namespace}/comm_protocol/follow"
        self.input_topic = f"{self.command_topic}/input"
        self.requests_done = 0
        self.requests_refused = 0
        self._requests: queue.SimpleQueue = queue.SimpleQueue()
        self._commands = rospy.Publisher(self.command_topic, self._command_class, queue_size=100)
        self._follow = rospy.Publisher(self.follow_topic, PoseStamped, queue_size=10)
        self._input = rospy.Subscriber(self.input_topic, self._command_class, self._on_input, queue_size=100)
        if not isinstance(brain.endpoint, EndpointTap):
            brain.endpoint = EndpointTap(brain.endpoint, self._publish)

    def _warn(self, text: str) -> None:
        self.requests_refused += 1
        self._rospy.logwarn("%s: ignored a Command on %s: %s", self.brain.name, self.input_topic, text)

    def _on_input(self, msg) -> None:
        """rospy's thread: check the request, queue it for the runtime's thread."""
        try:
            self._requests.put(parse_request(msg, self.brain.name))
        except RequestError as exc:
            self._warn(str(exc))

    def step(self, now: float) -> None:
        """Carry out the requests that arrived since the last step (call it each control tick)."""
        while True:
            try:
                request = self._requests.get_nowait()
            except queue.Empty:
                return
            try:
                REQUESTS[request.type](self.brain, request, now)
                self.requests_done += 1
            except ValueError as exc:  # values the wire format cannot carry (EncodeError), a bad peer
                self._warn(f"{TYPE_NAME[request.type]} to {_name(request.receiver)}: {exc}")

    def _publish(self, traffic: Traffic) -> None:
        """The tap's sink, on the runtime's thread inside brain.step."""
        stamp = self._rospy.Time.now()
        try:
            msg = self._command_class()
            fill_command(msg, traffic)
            msg.header.stamp = stamp
            self._commands.publish(msg)
            m = traffic.message
            if traffic.direction == RECEIVED and m.TYPE in LEADER_POSE:
                pose = self._pose_stamped()
                pose.header.stamp, pose.header.frame_id = stamp, "map"
                fill_pose(pose.pose, m.pose if isinstance(m, PoseUpdate) else m.frame)
                self._follow.publish(pose)
        except self._rospy.ROSException as exc:  # shutting down: the record is lost, the robot goes on
            self._rospy.logdebug("%s: not published: %s", self.brain.name, exc)

    def listeners(self) -> int:
        """How many subscribers the command topic has now (a runtime may wait for a recorder)."""
        return self._commands.get_num_connections()

    def close(self) -> None:
        """Leave the topics; the brain keeps the tap (it passes everything through)."""
        self._input.unregister()
        self._commands.unregister()
        self._follow.unregister()


def main(argv: list[str] | None = None) -> int:
    """`python -m rescuemesh.runtime.ros.ros1_paper`: generate the message classes, print their directory."""
    parser = argparse.ArgumentParser(prog="python -m rescuemesh.runtime.ros.ros1_paper",
                                     description="Generate rescuemesh_msgs for ROS 1 and print the directory to "
                                                 "put on PYTHONPATH (for rostopic and the robot).")
    parser.add_argument("--cache", help=f"cache directory (default: ${MSG_CACHE_ENV} or ~/.cache/rescuemesh/ros1_msgs)")
    parser.add_argument("--ros-package-path", action="store_true",
                        help="print the directory to add to ROS_PACKAGE_PATH instead (for rosmsg show)")
    args = parser.parse_args(argv)
    if args.ros_package_path:
        print(msg_package_dir().parent)
        return 0
    try:
        print(message_path(args.cache))
    except Ros1Unavailable as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
