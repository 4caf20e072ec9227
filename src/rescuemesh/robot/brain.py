"""RobotBrain: one robot's command handler, as section IV of the paper describes.

Owns: what the robot does with each protocol event (a table of command handlers), the leader's
PoseUpdate stream, heartbeats, and which behaviour runs. Must not know: the simulator, the
transport, wall-clock time. It drives a `Body` and an `Endpoint`, and is stepped with `now`.

Rules: every command and PoseUpdate gets a Confirm. Stop preempts everything. A newer motion
command replaces the running one, whose commander gets a CANCELLED report. Commands not built
yet are answered UNSUPPORTED. A Follow stream is given up after `max_sends` consecutive
PoseUpdates failed (docs/design.md says why the retry rule is applied per update).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from rescuemesh.body import Body
from rescuemesh.geometry import Pose2D
from rescuemesh.nav import Costmap, NavigateToPose
from rescuemesh.protocol import (
    CommandReceived,
    ConfirmReceived,
    DeliveryFailed,
    Endpoint,
    Follow,
    FrameRejected,
    HeartbeatReceived,
    MessageType,
    MoveAround,
    Pose,
    PoseUpdate,
    PoseUpdateReceived,
    ResultCode,
    Stop,
)
from rescuemesh.robot.behaviours import (
    Behaviour,
    FollowBehaviour,
    MoveAroundBehaviour,
    NavigateBehaviour,
    circle_waypoints,
)
from rescuemesh.robot.naming import robot_name


@dataclass(frozen=True)
class BrainConfig:
    """Behaviour settings; defaults from the issue and the paper."""

    follow_distance_m: float = 1.0
    pose_update_rate_hz: float = 2.0
    heartbeat_period_s: float = 1.0
    partner_timeout_s: float = 3.0  # follower stops when its leader is silent this long
    move_around_waypoints: int = 20


@dataclass(frozen=True, slots=True)
class BrainEvent:
    """One line of a robot's log, for result.json and timelines."""

    time_s: float
    robot: str
    kind: str
    detail: str = ""


@dataclass
class OutgoingCommand:
    """A command this robot sent, and what became of it."""

    seq: int
    peer: int
    kind: str
    sent_s: float
    result: ResultCode | None = None
    sends: int = 0
    failed: bool = False


@dataclass
class _PoseStream:
    """The leader side of a Follow: PoseUpdates to one follower."""

    follower: int
    follow_seq: int  # the Follow command this stream serves
    next_send_s: float
    failed_in_a_row: int = 0
    outstanding: set[int] = field(default_factory=set)


@dataclass(frozen=True, slots=True)
class FinishedBehaviour:
    """A behaviour that ran: its name, when it ran (s), its final result and why."""

    name: str
    started_s: float
    ended_s: float
    result: ResultCode
    reason: str


@dataclass
class _Running:
    behaviour: Behaviour
    started_s: float
    commander: int | None = None  # address of the robot whose command started it; None: own mission
    seq: int | None = None
    msg_type: MessageType | None = None


#: Commands that move the receiver: when one is given up, the sender sends Stop in case it runs.
MOTION_COMMANDS = frozenset({"Follow", "MoveAround", "Goto", "Return", "LandOnTop"})


def to_wire_pose(pose: Pose2D) -> Pose:
    return Pose(pose.x, pose.y, 0.0, pose.yaw)


def from_wire_pose(pose: Pose) -> Pose2D:
    return Pose2D(pose.x, pose.y, pose.yaw)


class RobotBrain:
    """The brain of robot `name`: give it a body, an endpoint, a navigator, and step it."""

    def __init__(self, name: str, body: Body, endpoint: Endpoint, nav: NavigateToPose, costmap: Costmap,
                 config: BrainConfig | None = None) -> None:
        self.name = name
        self.address = endpoint.address
        self.body = body
        self.endpoint = endpoint
        self.nav = nav
        self.costmap = costmap
        self.config = config or BrainConfig()
        self.log: list[BrainEvent] = []
        self.outgoing: dict[int, OutgoingCommand] = {}
        self.streams: dict[int, _PoseStream] = {}
        self.running: _Running | None = None
        self.finished: list[FinishedBehaviour] = []
        self.commands_failed = 0
        self.frames_rejected = 0
        self._next_heartbeat_s = 0.0
        self._handlers = {Follow: self._on_follow, Stop: self._on_stop, MoveAround: self._on_move_around}

    # ----- what a mission script (or, later, an operator or ROS node) asks of this robot -----

    def navigate_to(self, goal: Pose2D, now: float) -> None:
        """Drive to `goal` on this robot's own account (replaces the running behaviour)."""
        self._start(_Running(NavigateBehaviour(self.nav, goal, now), now), now)

    def command_follow(self, peer: int, now: float) -> int:
        """Send Follow to `peer`; once it is ACCEPTED, stream this robot's pose to it."""
        return self.send(peer, Follow(to_wire_pose(self.body.pose())), now)

    def command_stop(self, peer: int, now: float) -> int:
        """Send Stop to `peer`, and end any pose stream to it."""
        self.streams.pop(peer, None)
        return self.send(peer, Stop(), now)

    def command_move_around(self, peer: int, radius_m: float, now: float) -> int:
        """Send MoveAround: `peer` circles this robot's present position at `radius_m`."""
        return self.send(peer, MoveAround(to_wire_pose(self.body.pose()), radius_m), now)

    @property
    def behaviour(self) -> str:
        return self.running.behaviour.name if self.running else "idle"

    # ----- the loop -----

    def step(self, now: float) -> None:
        """Handle what the endpoint received, stream poses, heartbeat, and drive the body."""
        while (event := self.endpoint.next_event()) is not None:
            self._on_event(event, now)
        self._stream_poses(now)
        if now >= self._next_heartbeat_s:
            active = self.running.msg_type if self.running and self.running.msg_type else 0
            self.endpoint.send_heartbeat(now, active_command=int(active))
            self._next_heartbeat_s = now + self.config.heartbeat_period_s
        velocity = (0.0, 0.0)
        if self.running is not None:
            behaviour = self.running.behaviour
            velocity = behaviour.step(now, self.body.pose(), self.body.scan())
            if behaviour.finished:
                self._end_running(now, ResultCode.DONE if behaviour.outcome == "done" else ResultCode.FAILED,
                                  behaviour.reason)
        self.body.set_velocity(*velocity)

    # ----- receiving -----

    def _on_event(self, event, now: float) -> None:
        running = self.running
        if isinstance(event, (CommandReceived, PoseUpdateReceived)) and running is not None \
                and (running.commander, running.seq) == (event.src, event.seq):
            # The sender reused the running command's seq (it restarted, or its counter wrapped): a
            # final report for the old command would now answer this new frame. Report nothing.
            running.seq = None
        if isinstance(event, CommandReceived):
            self._note(event.now, "command_received", f"{type(event.command).__name__} from {robot_name(event.src)}")
            handler = self._handlers.get(type(event.command), self._on_unsupported)
            handler(event, now)
        elif isinstance(event, PoseUpdateReceived):
            self._on_pose_update(event, now)
        elif isinstance(event, ConfirmReceived):
            self._on_confirm(event, now)
        elif isinstance(event, DeliveryFailed):
            self._on_delivery_failed(event, now)
        elif isinstance(event, FrameRejected):
            self.frames_rejected += 1
            self._note(event.now, "frame_rejected", event.reason)
        elif isinstance(event, HeartbeatReceived):
            pass

    def _confirm(self, event, result: ResultCode, now: float, progress: int = 255) -> None:
        ref_type = MessageType.POSE_UPDATE if isinstance(event, PoseUpdateReceived) else event.command.TYPE
        self.endpoint.confirm(event.src, event.seq, ref_type, result, now, progress=progress)

    def _on_unsupported(self, event: CommandReceived, now: float) -> None:
        self._confirm(event, ResultCode.UNSUPPORTED, now)

    def _on_stop(self, event: CommandReceived, now: float) -> None:
        self.streams.clear()
        self._end_running(now, ResultCode.CANCELLED, f"stopped by {robot_name(event.src)}")
        self.body.set_velocity(0.0, 0.0)
        self._confirm(event, ResultCode.DONE, now)
        self._note(event.now, "stopped", f"by {robot_name(event.src)}")

    def _on_follow(self, event: CommandReceived, now: float) -> None:
        behaviour = FollowBehaviour(self.nav, event.src, from_wire_pose(event.command.frame), now,
                                    distance_m=self.config.follow_distance_m,
                                    partner_timeout_s=self.config.partner_timeout_s)
        self._start(_Running(behaviour, now, event.src, event.seq, event.command.TYPE), now)
        self._confirm(event, ResultCode.ACCEPTED, now)

    def _on_move_around(self, event: CommandReceived, now: float) -> None:
        command: MoveAround = event.command
        center = from_wire_pose(command.center)
        points = circle_waypoints(center, command.radius_m, self.config.move_around_waypoints, self.body.pose())
        free = [p for p in points if self.costmap.is_free(p.pose.x, p.pose.y)]
        skipped = [p for p in points if p not in free]
        if skipped:
            indices = dict.fromkeys(p.index for p in skipped)  # the closing repeat of the first is one waypoint
            self._note(now, "waypoints_skipped", ", ".join(str(i) for i in indices))
        if not free:
            self._confirm(event, ResultCode.DENIED, now)
            self._note(now, "command_denied", "MoveAround: every waypoint is inside an obstacle")
            return
        behaviour = MoveAroundBehaviour(self.nav, free, skipped, now)
        self._start(_Running(behaviour, now, event.src, event.seq, event.command.TYPE), now)
        self._confirm(event, ResultCode.ACCEPTED, now, progress=0)

    def _on_pose_update(self, event: PoseUpdateReceived, now: float) -> None:
        running = self.running
        if running is not None and isinstance(running.behaviour, FollowBehaviour) \
                and running.behaviour.leader == event.src:
            running.behaviour.on_pose_update(from_wire_pose(event.pose), event.now)
            self._confirm(event, ResultCode.ACCEPTED, now)
        else:
            self._confirm(event, ResultCode.DENIED, now)

    def _on_confirm(self, event: ConfirmReceived, now: float) -> None:
        stream = self.streams.get(event.src)
        if event.ref_type == MessageType.POSE_UPDATE:
            if stream is not None and event.ref_seq in stream.outstanding:
                stream.outstanding.discard(event.ref_seq)
                if event.result == ResultCode.ACCEPTED:
                    stream.failed_in_a_row = 0
                else:
                    del self.streams[event.src]
                    self._note(now, "follow_ended", f"{robot_name(event.src)} answered {event.result.name}")
            return
        sent = self.outgoing.get(event.ref_seq)
        if sent is None or sent.peer != event.src:
            return
        sent.result = event.result
        if event.solicited:
            sent.sends = event.sends
        self._note(event.now, "confirm", f"{sent.kind} by {robot_name(event.src)}: {event.result.name}")
        if sent.kind == "Follow" and event.solicited and event.result == ResultCode.ACCEPTED \
                and not self._stopped_since(event.src, sent.sent_s):
            self.streams[event.src] = _PoseStream(event.src, event.ref_seq, next_send_s=now)
        elif sent.kind == "Follow" and event.result in (ResultCode.CANCELLED, ResultCode.FAILED):
            stream = self.streams.get(event.src)
            if stream is not None and stream.follow_seq == event.ref_seq:
                del self.streams[event.src]

    def _on_delivery_failed(self, event: DeliveryFailed, now: float) -> None:
        if isinstance(event.message, PoseUpdate):
            stream = self.streams.get(event.dst)
            if stream is None or event.seq not in stream.outstanding:
                return
            stream.outstanding.discard(event.seq)
            stream.failed_in_a_row += 1
            if stream.failed_in_a_row >= self.endpoint.config.reliability.max_sends:  # the frame rule, per update
                del self.streams[event.dst]
                self.commands_failed += 1
                self._note(now, "follow_given_up",
                           f"{robot_name(event.dst)}: {stream.failed_in_a_row} PoseUpdates in a row unconfirmed")
                self.command_stop(event.dst, now)  # best effort; the follower also stops on its own timeout
            return
        sent = self.outgoing.get(event.seq)
        if sent is None:
            return
        sent.failed, sent.sends = True, event.sends
        self.commands_failed += 1
        self._note(now, "command_given_up", f"{sent.kind} to {robot_name(event.dst)} after {event.sends} sends")
        if sent.kind in MOTION_COMMANDS:
            # The receiver may have executed it with every Confirm lost: bring both sides to a stop.
            self.command_stop(event.dst, now)

    def _stopped_since(self, peer: int, since_s: float) -> bool:
        """Whether this robot sent `peer` a Stop at or after `since_s`."""
        return any(c.kind == "Stop" and c.peer == peer and c.sent_s >= since_s
                   for c in self.outgoing.values())

    # ----- sending (send is public, with the command_* helpers above) -----

    def send(self, peer: int, command, now: float) -> int:
        """Send any command message (its outcome is tracked in `outgoing`)."""
        seq = self.endpoint.send_command(peer, command, now)
        kind = type(command).__name__
        self.outgoing[seq] = OutgoingCommand(seq, peer, kind, now)
        self._note(now, "command_sent", f"{kind} to {robot_name(peer)}")
        return seq

    def _stream_poses(self, now: float) -> None:
        period = 1.0 / self.config.pose_update_rate_hz
        for stream in self.streams.values():
            if now + 1e-9 >= stream.next_send_s:
                seq = self.endpoint.send_pose_update(stream.follower, to_wire_pose(self.body.pose()), now)
                stream.outstanding.add(seq)
                stream.next_send_s = max(stream.next_send_s + period, now)

    # ----- running behaviours -----

    def _start(self, running: _Running, now: float) -> None:
        self._end_running(now, ResultCode.CANCELLED, f"replaced by {running.behaviour.name}")
        self.running = running
        self._note(now, "behaviour_started", running.behaviour.name)

    def _end_running(self, now: float, result: ResultCode, reason: str) -> None:
        running, self.running = self.running, None
        if running is None:
            return
        running.behaviour.halt(now)
        self.finished.append(FinishedBehaviour(running.behaviour.name, running.started_s, now, result, reason))
        self._note(now, "behaviour_ended", f"{running.behaviour.name}: {result.name} {reason}".rstrip())
        if running.commander is not None and running.seq is not None:
            # Report the final result to the commander (best effort: an unsolicited Confirm).
            self.endpoint.confirm(running.commander, running.seq, running.msg_type, result, now,
                                  progress=running.behaviour.progress() if result != ResultCode.DONE else 100)

    def _note(self, now: float, kind: str, detail: str = "") -> None:
        self.log.append(BrainEvent(round(now, 3), self.name, kind, detail))
