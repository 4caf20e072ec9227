"""RobotBrain: one robot's command handler, as section IV of the paper describes.

Owns: what the robot does with each protocol and network event (tables of handlers), the leader's
PoseUpdate stream, heartbeats, link-loss pauses, ForwardMsg jobs, which behaviour runs. Must not
know: the simulator, the transport, wall-clock time. It drives a `Body` and a network stack.

Rules: every command and PoseUpdate gets a Confirm. Stop preempts everything. A motion command
of equal or higher priority (robot/policy.py: sender's rank, then the type's level) replaces the
running one, whose commander gets a CANCELLED report; a lower one is TEMPORARILY_REJECTED with
the resource that is held. Goto and Return report IN_PROGRESS with their progress periodically.
Commands not built yet are answered UNSUPPORTED. Link loss (paper IV.A, "stop command execution in case of
disconnecting and failing to reconnect"): when the mesh layer reports a peer lost (missed
heartbeats), a command shared with it pauses at once (a moving robot halts) and a reconnect
window opens; heard again within it, the command resumes; if not, both sides end it FAILED
(LINK_LOST), unless the command type's link-loss policy says continue or return to base. Those
handlers, and final reports held for a commander out of reach, are in robot/link_loss.py.
docs/design.md has the timings.
"""

from __future__ import annotations

import dataclasses
import logging
from collections import deque

from rescuemesh.body import Body, RobotKind
from rescuemesh.geometry import Pose2D
from rescuemesh.mesh import NeighbourFound, NeighbourLost, PeerRestarted, TransferComplete, TransferFailed
from rescuemesh.nav import Costmap, NavigateToPose
from rescuemesh.protocol import (
    CommandReceived, DataKind, Goto, Return, ConfirmReceived, DataReceived, DeliveryFailed, EncodeError,
    Follow, ForwardMsg, FrameRejected, HeartbeatReceived, MessageType, MoveAround, PoseUpdateReceived, Reason,
    ResultCode, Stop)
from rescuemesh.protocol.messages import Capability, Data, PoseUpdate
from rescuemesh.robot.behaviours import (
    Behaviour,
    FollowBehaviour,
    MoveAroundBehaviour,
    NavigateBehaviour,
    circle_waypoints,
)
from rescuemesh.robot import events as ev
from rescuemesh.robot.commands import COMMANDS, priority_of, resources_of, traits
from rescuemesh.robot.custody import ReportCustody
from rescuemesh.robot.forwarding import Forwarder, JobProgress
from rescuemesh.robot.naming import robot_name
from rescuemesh.robot.policy import MOTION_LEVEL, Priority, Rank, Resource, conflict
from rescuemesh.robot.landing import LandOnTopBehaviour
from rescuemesh.robot.link_loss import LinkLossAndReports
from rescuemesh.robot.records import (
    BrainConfig,
    BrainLog,
    FinishedBehaviour,
    OutgoingCommand,
    PoseStream,
    Running,
    fits_wire,
    from_wire_pose,
    heartbeat_phase_s,
    power_on_s,
    to_wire_pose,
)
from rescuemesh.robot.sensing import SensorCommands

_LOG = logging.getLogger(__name__)


class RobotBrain(LinkLossAndReports, SensorCommands):
    """The brain of robot `name`: give it a body, an endpoint, a navigator, and step it."""

    def __init__(self, name: str, body: Body, network, nav: NavigateToPose, costmap: Costmap,
                 config: BrainConfig | None = None) -> None:
        """`network`: the robot's network stack (rescuemesh.mesh.NetworkStack: `.endpoint`,
        `next_event()`, `is_reachable(address, now)`, `heartbeat_period_s`)."""
        self.name = name
        self.address = network.endpoint.address
        self.body = body
        self.network = network
        self.endpoint = network.endpoint
        self.nav = nav
        self.costmap = costmap
        self.config = config or BrainConfig()
        #: The robot's log: a ring (records.LOG_CAPACITY entries) with a count of what it dropped.
        self.log = BrainLog()
        #: Why the robot is halted for its own pose (outside the wire's range or not finite), or None.
        self.pose_fault: str | None = None
        self.outgoing: dict[int, OutgoingCommand] = {}
        self.streams: dict[int, PoseStream] = {}
        self.running: Running | None = None
        #: A ShowScan running beside the motion command (it needs the laser only: no turn, no drive).
        self.sensing: Running | None = None
        self.finished: list[FinishedBehaviour] = []
        self.commands_failed = 0
        self.frames_rejected = 0
        self.lost_peers: dict[int, float] = {}  # peer with a shared command -> end of its reconnect window (s)
        self._repeats: list[tuple[float, int, int, int]] = []  # (due s, commander, seq, copies left)
        #: What each peer announced it can do, from its latest Heartbeat.
        self.peer_capabilities: dict[int, Capability] = {}
        #: Bulk data received (scans, images): (time s, source, kind, command seq, bytes, hops).
        self.received_data: deque[tuple[float, int, DataKind, int, bytes, int]] = deque(maxlen=64)
        self.forwarder = Forwarder(self.address, timeout_s=self.config.forward_timeout_s,
                                   capacity=self.config.forward_capacity,
                                   result_timeout_s=self.config.forward_result_timeout_s)
        #: Final reports held for commanders out of reach, sent again once they are heard.
        self.custody = ReportCustody(capacity=self.config.report_custody_capacity,
                                     hold_s=self.config.report_custody_hold_s)
        #: When this robot is switched on (BrainConfig.power_on_spread_s); it does nothing before.
        self.power_on_s = power_on_s(self.address, self.config.power_on_spread_s)
        self._next_heartbeat_s = 0.0  # the first at once (peers learn our epoch from it), then on our phase
        self._heartbeat_phase_s = heartbeat_phase_s(self.address, network.heartbeat_period_s)
        #: Each command type's handler, named in robot/commands.py's table.
        self._handlers = {msg_type: getattr(self, row.handler) for msg_type, row in COMMANDS.items()}
        self._on_protocol = {
            CommandReceived: self._on_command, PoseUpdateReceived: self._on_pose_update,
            ConfirmReceived: self._on_confirm, DeliveryFailed: self._on_delivery_failed,
            FrameRejected: self._on_frame_rejected, HeartbeatReceived: self._on_heartbeat, DataReceived: self._on_data,
        }
        self._on_network = {
            NeighbourLost: self._on_neighbour_lost, NeighbourFound: self._on_neighbour_found,
            TransferComplete: _ignore, TransferFailed: self._on_transfer_failed,
            PeerRestarted: self._on_peer_restarted,
        }

    # ----- what a mission script (or, later, an operator or ROS node) asks of this robot -----

    def navigate_to(self, goal: Pose2D, now: float) -> None:
        """Drive to `goal` on this robot's own account (replaces the running behaviour)."""
        own = Priority(self.rank_of(self.address), MOTION_LEVEL)
        self._start(Running(NavigateBehaviour(self.nav, goal, now), now, priority=own), now)

    def rank_of(self, address: int) -> Rank:
        return Rank(self.config.ranks.get(address, Rank.PEER))

    def command_goto(self, peer: int, goal: Pose2D, now: float) -> int:
        """Send Goto: `peer` drives to `goal` and reports progress, then DONE or FAILED."""
        return self.send(peer, Goto(to_wire_pose(goal)), now)

    def command_return(self, peer: int, now: float) -> int:
        """Send Return: `peer` drives back to its base."""
        return self.send(peer, Return(), now)

    def command_follow(self, peer: int, now: float) -> int:
        """Send Follow to `peer`; once it is ACCEPTED, stream this robot's pose to it."""
        return self.send(peer, Follow(to_wire_pose(self.body.pose())), now)

    def command_stop(self, peer: int, now: float, *, automatic: bool = False) -> int:
        """Send Stop to `peer`, and end any pose stream to it (`automatic`: the brain's own safety
        Stop, not a mission's or user's command; counted apart in result.json)."""
        self.streams.pop(peer, None)
        seq = self.send(peer, Stop(), now)
        self.outgoing[seq].automatic = automatic
        return seq

    def command_move_around(self, peer: int, radius_m: float, now: float) -> int:
        """Send MoveAround: `peer` circles this robot's present position at `radius_m`."""
        return self.send(peer, MoveAround(to_wire_pose(self.body.pose()), radius_m), now)

    @property
    def behaviour(self) -> str:
        return self.running.behaviour.name if self.running else "idle"

    # ----- the loop -----

    def heartbeat_now(self) -> None:
        """Send a Heartbeat at the next step, then keep the usual period: a runtime that learns of a
        new peer (a Zenoh session connecting) lets it hear our epoch and know us at once."""
        self._next_heartbeat_s = 0.0

    def step(self, now: float) -> None:
        """Handle what the endpoint and the network reported, keep links and jobs, stream poses,
        heartbeat, and drive the body. A pose the wire cannot carry (|x| or |y| beyond 327.67 m, or
        not finite: a drifting odometry, a bad driver) is reported once, never sent, and halts the
        robot (`pose_fault`) until the pose is good again; it never raises out of here. Before the
        robot is switched on (`power_on_s`): nothing."""
        if now < self.power_on_s:
            return
        pose = self.body.pose()
        if not fits_wire(pose):
            return self._halt_for_pose(now, f"pose ({pose.x:.2f}, {pose.y:.2f}, {pose.yaw:.2f}) is outside the "
                                            "wire's range (|x|, |y| <= 327.67 m, finite)")
        if self.pose_fault is not None:
            self.pose_fault = None
            self._note(ev.PoseFaultCleared(now, self.name, pose.x, pose.y))
        try:
            self._step(now)
        except EncodeError as exc:  # the pose moved out of range during the step
            self._halt_for_pose(now, str(exc))

    def _halt_for_pose(self, now: float, why: str) -> None:
        """Halted for our own pose: events handled (commands are answered, then failed), pose streams
        ended, nothing that carries the pose sent, Heartbeats go on, the body stands still."""
        if self.pose_fault is None:
            self.pose_fault = why
            self._note(ev.PoseFault(now, self.name, why))
            _LOG.warning("%s: %s: halted, the pose is not sent", self.name, why)
        self.streams.clear()
        try:
            while (event := self.endpoint.next_event()) is not None:
                self._on_protocol[type(event)](event, now)
            while (event := self.network.next_event()) is not None:
                self._on_network[type(event)](event, now)
        except EncodeError:
            pass  # a handler that needed our pose: nothing sent
        self._end_running(now, ResultCode.FAILED, Reason.STUCK, "own pose outside the wire's range")
        self._end_running(now, ResultCode.FAILED, Reason.STUCK, "own pose outside the wire's range", sensing=True)
        self._heartbeat(now)
        self.body.set_velocity(0.0, 0.0)

    def _heartbeat(self, now: float) -> None:
        if now >= self._next_heartbeat_s:
            active = self.running.msg_type if self.running and self.running.msg_type else 0
            self.endpoint.send_heartbeat(now, active_command=int(active), capabilities=int(self.capabilities))
            period = self.network.heartbeat_period_s  # the mesh node's: it counts missed ones
            if self._heartbeat_phase_s is not None:  # after the first: on this robot's phase
                self._next_heartbeat_s = now + (self._heartbeat_phase_s - now) % period or period
                self._heartbeat_phase_s = None
            else:
                self._next_heartbeat_s = now + period

    def _step(self, now: float) -> None:
        while (event := self.endpoint.next_event()) is not None:
            self._on_protocol[type(event)](event, now)
        while (event := self.network.next_event()) is not None:
            self._on_network[type(event)](event, now)
        self._end_lost_links(now)
        self._repeat_final_reports(now)
        if self.custody.reports:
            self._deliver_held_reports(now)
        self._forward(now)
        self._stream_poses(now)
        self._heartbeat(now)
        velocity = (0.0, 0.0)
        if self.running is not None:
            behaviour = self.running.behaviour
            velocity = behaviour.step(now, self.body.pose(), self.body.scan())
            self._send_captures(now)
            if behaviour.finished:
                self._end_running(now, behaviour.outcome, behaviour.reason, behaviour.detail)
            else:
                self._report_progress(now)
        if self.sensing is not None:
            sensing = self.sensing.behaviour
            sensing.step(now, self.body.pose(), self.body.scan())  # it never drives
            self._send_captures(now, self.sensing)
            if sensing.finished:
                self._end_running(now, sensing.outcome, sensing.reason, sensing.detail, sensing=True)
        self.body.set_velocity(*velocity)

    def _report_progress(self, now: float) -> None:
        """MAVLink's long-running command pattern: IN_PROGRESS with a percentage, every period."""
        running = self.running
        if running.commander is None or running.seq is None or not traits(running.msg_type).reports_progress \
                or now < running.next_report_s:
            return
        if not self.network.is_reachable(running.commander, now):
            return  # nobody to hear it: the final report is held for the commander instead
        running.next_report_s = now + self.config.progress_period_s
        self.endpoint.confirm(running.commander, running.seq, running.msg_type, ResultCode.IN_PROGRESS, now,
                              progress=running.behaviour.progress())

    # ----- receiving -----

    def _forget_reused_seq(self, event) -> None:
        running = self.running
        if running is not None and (running.commander, running.seq) == (event.src, event.seq):
            # The sender reused the running command's seq (it restarted, or its counter wrapped): a
            # final report for the old command would now answer this new frame. Report nothing.
            running.seq = None

    def _on_command(self, event: CommandReceived, now: float) -> None:
        self._forget_reused_seq(event)
        self._note(ev.CommandReceived(event.now, self.name, event.command.TYPE, event.src, event.seq, event.hops))
        self._handlers.get(event.command.TYPE, self._on_unsupported)(event, now)

    def _on_frame_rejected(self, event: FrameRejected, now: float) -> None:
        self.frames_rejected += 1
        self._note(ev.FrameRejected(event.now, self.name, event.reason, event.error_type))

    def _on_data(self, event: DataReceived, now: float) -> None:
        self.endpoint.confirm(event.src, event.seq, MessageType.DATA, ResultCode.ACCEPTED, now)
        job = self.forwarder.answering(event.src, event.ref_seq)
        if job is not None:  # a forwarded command's data: on to the robot that asked, answering its ForwardMsg
            self.endpoint.send_data(job.sender, event.kind, job.seq, event.data, now)
            self._note(ev.ForwardData(now, self.name, event.kind, len(event.data), event.src, job.sender))
            return
        self.received_data.append((event.now, event.src, event.kind, event.ref_seq, event.data, event.hops))
        self._note(ev.DataReceived(event.now, self.name, event.kind, len(event.data), event.src))

    def _confirm(self, event, result: ResultCode, now: float, progress: int = 255,
                 reason: Reason = Reason.NONE) -> None:
        ref_type = MessageType.POSE_UPDATE if isinstance(event, PoseUpdateReceived) else event.command.TYPE
        self.endpoint.confirm(event.src, event.seq, ref_type, result, now, progress=progress, reason=reason)

    def _on_unsupported(self, event: CommandReceived, now: float) -> None:
        self._confirm(event, ResultCode.UNSUPPORTED, now)

    def _on_stop(self, event: CommandReceived, now: float) -> None:
        self.streams.clear()
        self._end_running(now, ResultCode.CANCELLED, Reason.STOPPED, f"stopped by {robot_name(event.src)}")
        self._end_running(now, ResultCode.CANCELLED, Reason.STOPPED, f"stopped by {robot_name(event.src)}", sensing=True)
        self.body.set_velocity(0.0, 0.0)
        if self.body.kind is RobotKind.FLYING:
            self.body.hold()  # hover where it is (on a top with its rotors off it stays there)
        self._confirm(event, ResultCode.DONE, now)
        self._note(ev.Stopped(event.now, self.name, event.src))

    def _admit(self, event: CommandReceived, now: float, also_needs: Resource = Resource.NONE) -> bool:
        """Whether the command may start now (policy.py); otherwise answer TEMPORARILY_REJECTED."""
        running = self.running
        if running is None:
            return True
        msg_type = event.command.TYPE
        reason = conflict(priority_of(msg_type, self.rank_of(event.src)), resources_of(msg_type) | also_needs,
                          running.resources, running.priority)
        if reason is None:
            return True
        self._confirm(event, ResultCode.TEMPORARILY_REJECTED, now, reason=reason)
        self._note(ev.CommandRejected(now, self.name, msg_type, event.src, reason, running.msg_type,
                                      running.commander))
        return False

    def _running_for(self, event: CommandReceived, behaviour: Behaviour, now: float) -> Running:
        return Running(behaviour, now, event.src, event.seq, event.command.TYPE,
                        priority_of(event.command.TYPE, self.rank_of(event.src)), resources_of(event.command.TYPE),
                        next_report_s=now + self.config.progress_period_s)

    def _on_goto(self, event: CommandReceived, now: float) -> None:
        self._drive_to(event, from_wire_pose(event.command.frame), now)

    def _on_return(self, event: CommandReceived, now: float) -> None:
        base = self.config.base if self.config.base is not None else self.body.pose()
        self._drive_to(event, base, now)

    def _drive_to(self, event: CommandReceived, goal: Pose2D, now: float) -> None:
        if not self._admit(event, now):
            return
        self._start(self._running_for(event, NavigateBehaviour(self.nav, goal, now), now), now)
        self._confirm(event, ResultCode.ACCEPTED, now, progress=0)

    def _on_follow(self, event: CommandReceived, now: float) -> None:
        if not self._admit(event, now):
            return
        behaviour = FollowBehaviour(self.nav, event.src, from_wire_pose(event.command.frame), now,
                                    distance_m=self.config.follow_distance_m,
                                    partner_timeout_s=self.config.partner_timeout_s,
                                    partner_give_up_s=self.config.partner_give_up_s)
        self._start(self._running_for(event, behaviour, now), now)
        self._confirm(event, ResultCode.ACCEPTED, now)

    def _on_move_around(self, event: CommandReceived, now: float) -> None:
        if not self._admit(event, now):
            return
        command: MoveAround = event.command
        center = from_wire_pose(command.center)
        points = circle_waypoints(center, command.radius_m, self.config.move_around_waypoints, self.body.pose())
        free = [p for p in points if self.costmap.is_free(p.pose.x, p.pose.y)]
        skipped = [p for p in points if p not in free]
        if skipped:
            indices = dict.fromkeys(p.index for p in skipped)  # the closing repeat of the first is one waypoint
            self._note(ev.WaypointsSkipped(now, self.name, tuple(indices)))
        if not free:
            self._confirm(event, ResultCode.DENIED, now, reason=Reason.BLOCKED)
            self._note(ev.CommandDenied(now, self.name, MessageType.MOVE_AROUND, Reason.BLOCKED))
            return
        behaviour = MoveAroundBehaviour(self.nav, free, skipped, now)
        self._start(self._running_for(event, behaviour, now), now)
        self._confirm(event, ResultCode.ACCEPTED, now, progress=0)

    def _on_forward(self, event: CommandReceived, now: float) -> None:
        command: ForwardMsg = event.command
        job = self.forwarder.accept(event.src, event.seq, command.target, command.message, now)
        if isinstance(job, Reason):
            self._confirm(event, ResultCode.DENIED, now, reason=job)
            self._note(ev.CommandDenied(now, self.name, MessageType.FORWARD_MSG, job, command.target))
            return
        self._confirm(event, ResultCode.ACCEPTED, now)
        self._note(ev.ForwardAccepted(now, self.name, job.inner.TYPE, job.target))

    def _on_pose_update(self, event: PoseUpdateReceived, now: float) -> None:
        self._forget_reused_seq(event)
        running = self.running
        streamed = (isinstance(running.behaviour, FollowBehaviour) and running.behaviour.leader == event.src) or \
            (isinstance(running.behaviour, LandOnTopBehaviour) and running.behaviour.carrier == event.src) \
            if running is not None else False
        if streamed:
            running.behaviour.on_pose_update(from_wire_pose(event.pose), event.now)
            self._confirm(event, ResultCode.ACCEPTED, now)
        else:
            self._confirm(event, ResultCode.DENIED, now, reason=Reason.NOT_FOLLOWING)

    def _on_confirm(self, event: ConfirmReceived, now: float) -> None:
        stream = self.streams.get(event.src)
        if event.ref_type == MessageType.POSE_UPDATE:
            if stream is not None and event.ref_seq in stream.outstanding:
                stream.outstanding.discard(event.ref_seq)
                if event.result == ResultCode.ACCEPTED:
                    stream.failed_in_a_row, stream.last_confirmed_s = 0, now
                else:
                    del self.streams[event.src]
                    self._note(ev.FollowEnded(now, self.name, event.src, event.result))
            return
        update = self.forwarder.confirmed(event.src, event.ref_seq, event.result, event.reason, event.progress, now)
        if isinstance(update, JobProgress):  # the target runs it: tell the robot that asked
            job = update.job
            self.endpoint.confirm(job.sender, job.seq, MessageType.FORWARD_MSG, ResultCode.IN_PROGRESS, now,
                                  progress=update.progress)
            return
        if update is not None:
            self._report_forward(update, now, event.src, answered=event.result)
            return
        sent = self.outgoing.get(event.ref_seq)
        if sent is None or sent.peer != event.src:
            return
        sent.result, sent.reason = event.result, event.reason
        sent.reports[event.result] = sent.reports.get(event.result, 0) + 1
        if sent.confirmed_s is None:
            sent.confirmed_s = event.now
        if event.solicited:
            sent.sends, sent.hops = event.sends, event.hops
        self._note(ev.Confirm(event.now, self.name, sent.msg_type, event.src, event.ref_seq, event.result,
                              event.reason, event.progress, event.hops))
        streamed = traits(sent.msg_type).streamed
        if streamed and event.solicited and event.result == ResultCode.ACCEPTED \
                and not self._stopped_since(event.src, sent.sent_s):
            self.streams[event.src] = PoseStream(event.src, event.ref_seq, next_send_s=now, last_confirmed_s=now)
        elif streamed and event.result in (ResultCode.CANCELLED, ResultCode.FAILED, ResultCode.DONE):
            stream = self.streams.get(event.src)
            if stream is not None and stream.follow_seq == event.ref_seq:
                del self.streams[event.src]

    def _on_delivery_failed(self, event: DeliveryFailed, now: float) -> None:
        if isinstance(event.message, PoseUpdate):
            # Counted only: a lost follower is found out by its missed heartbeats (link-loss rule),
            # and a stream that gets no Confirm at all is ended by the give-up safety net.
            stream = self.streams.get(event.dst)
            if stream is not None and event.seq in stream.outstanding:
                stream.outstanding.discard(event.seq)
                stream.failed_in_a_row += 1
            return
        if self.forwarder.undelivered(event.dst, event.seq):
            self._note(ev.ForwardUndelivered(now, self.name, event.dst))
            return
        sent = self.outgoing.get(event.seq)
        if sent is None:
            return
        sent.failed, sent.sends = True, event.sends
        self.commands_failed += 1
        self._note(ev.CommandGivenUp(now, self.name, sent.msg_type, event.dst, event.seq, event.sends))
        if traits(sent.msg_type).motion:
            # The receiver may have executed it with every Confirm lost: bring both sides to a stop.
            self.command_stop(event.dst, now, automatic=True)

    def _on_peer_restarted(self, event: PeerRestarted, now: float) -> None:
        self._note(ev.PeerRestarted(now, self.name, event.address, event.epoch))

    def _on_transfer_failed(self, event: TransferFailed, now: float) -> None:
        self._note(ev.TransferFailed(now, self.name, event.dst, event.acked, event.total))

    # ----- ForwardMsg jobs -----

    def _forward(self, now: float) -> None:
        for job in self.forwarder.due(now, self.network.is_reachable):
            if isinstance(job.inner, Data):
                seq = self.endpoint.send_data(job.target, job.inner.kind, job.inner.ref_seq, job.inner.data, now)
            else:
                seq = self.endpoint.send_command(job.target, job.inner, now)
            self.forwarder.sent(job, seq)
            self._note(ev.ForwardSent(now, self.name, job.inner.TYPE, job.target, job.sender))
        for ended in self.forwarder.expired(now):
            self._report_forward(ended, now, ended.job.target, waited_s=self.config.forward_timeout_s)

    def _report_forward(self, ended, now: float, peer: int, answered: ResultCode | None = None,
                        waited_s: float | None = None) -> None:
        job = ended.job
        self._final_report(job.sender, job.seq, MessageType.FORWARD_MSG, ended.result, ended.reason, now,
                           ended.progress)
        self._note(ev.ForwardEnded(now, self.name, ended.result, ended.reason, peer, answered, waited_s))

    def _stopped_since(self, peer: int, since_s: float) -> bool:
        """Whether this robot sent `peer` a Stop at or after `since_s`."""
        return any(c.msg_type is MessageType.STOP and c.peer == peer and c.sent_s >= since_s
                   for c in self.outgoing.values())

    # ----- sending (send is public, with the command_* helpers above) -----

    def send(self, peer: int, command, now: float) -> int:
        """Send any command message (its outcome is tracked in `outgoing`)."""
        seq = self.endpoint.send_command(peer, command, now)
        kind = type(command).__name__
        self.outgoing[seq] = OutgoingCommand(seq, peer, kind, now, command.TYPE)
        self._note(ev.CommandSent(now, self.name, command.TYPE, peer, seq))
        return seq

    def _stream_poses(self, now: float) -> None:
        period = 1.0 / self.config.pose_update_rate_hz
        for stream in self.streams.values():
            if not stream.paused and now + 1e-9 >= stream.next_send_s:
                seq = self.endpoint.send_pose_update(stream.follower, to_wire_pose(self.body.pose()), now)
                stream.outstanding.add(seq)
                stream.next_send_s = max(stream.next_send_s + period, now)

    # ----- running behaviours -----

    def _start(self, running: Running, now: float) -> None:
        self._end_running(now, ResultCode.CANCELLED, Reason.REPLACED, f"replaced by {running.behaviour.name}")
        self.running = running
        self._note(ev.BehaviourStarted(now, self.name, running.behaviour.name))

    def _end_running(self, now: float, result: ResultCode, code: Reason, reason: str = "",
                     sensing: bool = False) -> None:
        """End the motion command (or, with `sensing`, the ShowScan beside it) and report it."""
        if sensing:
            running, self.sensing = self.sensing, None
        else:
            running, self.running = self.running, None
        if running is None:
            return
        if not sensing:
            running.behaviour.halt(now)
        if running.commander is not None:
            self.lost_peers.pop(running.commander, None)
        self.finished.append(FinishedBehaviour(running.behaviour.name, running.started_s, now, result, reason, code))
        self._note(ev.BehaviourEnded(now, self.name, running.behaviour.name, result, code, reason))
        if running.commander is not None and running.seq is not None:
            self._final_report(running.commander, running.seq, running.msg_type, result, code, now,
                               progress=running.behaviour.progress() if result != ResultCode.DONE else 100)

    def _note(self, event: ev.BrainEvent) -> None:
        """Log `event` (its time rounded to the ms, as the log has always kept it)."""
        self.log.append(dataclasses.replace(event, time_s=round(event.time_s, 3)))


def _ignore(event, now: float) -> None:
    """Events this brain has nothing to do with (a heartbeat: the mesh layer keeps liveness)."""
