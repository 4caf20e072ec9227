"""The sensor and flight commands of a robot's brain (ShowScan, ShowCam, LandOnTop) and its
capabilities, as a part of RobotBrain kept apart for size. Owns those handlers; must not know the
simulator: captures come from the Body, encodings from robot/sensor_codec.py.
"""

from __future__ import annotations

import math

from rescuemesh.body import NoRendererError, RobotKind
from rescuemesh.protocol import (
    CommandReceived, DataKind, HeartbeatReceived, LandOnTop, Pose, Reason, ResultCode, ShowCam)
from rescuemesh.protocol.messages import CAPABILITY_SETS, Capability
from rescuemesh.robot.landing import LandOnTopBehaviour
from rescuemesh.robot import events as ev
from rescuemesh.robot.commands import priority_of
from rescuemesh.robot.policy import Resource
from rescuemesh.robot.records import Running
from rescuemesh.robot.sensor_codec import STREAM_BYTES_PER_S, choose_jpeg, data_budget_bytes, encode_scan
from rescuemesh.robot.show import ShowBehaviour, sees


class SensorCommands:
    """Mixed into RobotBrain: uses its body, config, endpoint, network, running and sensing slots,
    _admit, _start, _running_for, _confirm, _end_running and _note."""

    @property
    def capabilities(self) -> Capability:
        """What this robot can do, as its Heartbeats announce it."""
        caps = Capability.NONE
        if self.body.kind is RobotKind.FLYING:
            caps |= Capability.FLYING
        if self.config.has_camera and self.body.kind is RobotKind.GROUND:
            caps |= Capability.CAMERA
        if self.config.has_laser and self.body.kind is RobotKind.GROUND:
            caps |= Capability.LASER
        if self.body.top_height:
            caps |= Capability.LANDING_PAD
        node = getattr(self.network, "node", None)
        if node is not None and node.config.relay:
            caps |= Capability.RELAY
        return caps

    def capabilities_of(self, peer: int) -> Capability | None:
        """What `peer` announced it can do (None before its first Heartbeat): look before asking."""
        return self.peer_capabilities.get(peer)

    def command_land_on_top(self, peer: int, now: float) -> int:
        """Send LandOnTop: flying robot `peer` lands on this robot's top (its height in the frame's z);
        once it is ACCEPTED this robot streams its pose to it, as for Follow."""
        pose = self.body.pose()
        top = self.body.top_height or 0.0
        return self.send(peer, LandOnTop(Pose(pose.x, pose.y, top, pose.yaw)), now)

    def _on_heartbeat(self, event: HeartbeatReceived, now: float) -> None:
        self.peer_capabilities[event.src] = CAPABILITY_SETS[event.capabilities]  # decoded: within ALL_CAPABILITIES

    def _on_show(self, event: CommandReceived, now: float) -> None:
        command = event.command
        camera = isinstance(command, ShowCam)
        if not (self.config.has_camera if camera else self.config.has_laser):
            self._confirm(event, ResultCode.UNSUPPORTED, now, reason=Reason.NO_SENSOR)
            return
        requester = event.src
        budget = data_budget_bytes(self.network.hops_to(requester) or 1)
        if command.count != 1:  # a stream must not send more than the link carries in one period
            budget = min(budget, max(200, int(STREAM_BYTES_PER_S * command.period_s)))
        capture = (lambda: self._capture_image(budget)) if camera else (lambda: self._capture_scan(budget))
        if not camera and self._scan_beside_drive(event, capture, now):
            return
        if not self._admit(event, now, also_needs=Resource.MOTION):  # it may drive to a viewpoint and turn
            return
        behaviour = ShowBehaviour(self.nav, self.costmap, "show-cam" if camera else "show-scan",
                                  (command.frame.x, command.frame.y),
                                  self.config.camera_range_m if camera else self.config.laser_range_m,
                                  command.period_s, command.count, capture, now, self.body.pose(),
                                  timeout_s=self.config.show_timeout_s)
        if behaviour.finished:  # no viewpoint at all
            self._confirm(event, ResultCode.FAILED, now, reason=behaviour.reason)
            self._note(ev.CommandFailed(now, self.name, command.TYPE, behaviour.reason, behaviour.detail))
            return
        running = self._running_for(event, behaviour, now)
        running.resources |= Resource.MOTION  # it may drive to a viewpoint and turn toward it
        self._start(running, now)
        self._confirm(event, ResultCode.ACCEPTED, now, progress=0)

    def _scan_beside_drive(self, event: CommandReceived, capture, now: float) -> bool:
        """A ShowScan while the robot drives runs beside the drive when the spot is already in the
        laser's sight (range, line of sight, field of view): it needs no turn. True if started (or
        refused because another ShowScan of higher priority holds the laser)."""
        if self.running is None or Resource.MOTION not in self.running.resources:
            return False
        command, pose = event.command, self.body.pose()
        target = (command.frame.x, command.frame.y)
        bearing = math.atan2(target[1] - pose.y, target[0] - pose.x) - pose.yaw
        in_view = abs(math.remainder(bearing, 2 * math.pi)) <= self.config.laser_fov_rad / 2
        if not (in_view and sees(self.costmap, pose, target, self.config.laser_range_m)):
            return False
        new = priority_of(command.TYPE, self.rank_of(event.src))
        if self.sensing is not None and new < self.sensing.priority:
            self._confirm(event, ResultCode.TEMPORARILY_REJECTED, now, reason=Reason.LASER_HELD)
            return True
        self._end_running(now, ResultCode.CANCELLED, Reason.REPLACED, "replaced by show-scan", sensing=True)
        behaviour = ShowBehaviour(self.nav, self.costmap, "show-scan", target, self.config.laser_range_m,
                                  command.period_s, command.count, capture, now, pose,
                                  timeout_s=self.config.show_timeout_s, stationary=True)
        self.sensing = self._running_for(event, behaviour, now)
        self._note(ev.BehaviourStarted(now, self.name, "show-scan", beside=True))
        self._confirm(event, ResultCode.ACCEPTED, now, progress=0)
        return True

    def _capture_scan(self, budget: int):
        scan = self.body.scan()
        if scan is None:
            return None
        return DataKind.LASER_SCAN, encode_scan(scan, max_bytes=budget)

    def _capture_image(self, budget: int):
        image = self.body.camera()
        if image is None:
            raise NoRendererError("this robot's body has no camera")
        return DataKind.IMAGE_JPEG, choose_jpeg(image.rgb, max_bytes=budget).data

    def _send_captures(self, now: float, running: Running | None = None) -> None:
        running = running if running is not None else self.running
        outbox = getattr(running.behaviour, "outbox", None)
        if not outbox:
            return
        for kind, data in outbox:
            if running.commander is not None and running.seq is not None:
                self.endpoint.send_data(running.commander, kind, running.seq, data, now)
                self._note(ev.DataSent(now, self.name, kind, len(data), running.commander))
        outbox.clear()

    def _on_land_on_top(self, event: CommandReceived, now: float) -> None:
        frame = event.command.frame
        if self.body.kind is not RobotKind.FLYING or frame.z <= 0.0:
            self._confirm(event, ResultCode.UNSUPPORTED, now, reason=Reason.NOT_FLYING)
            return
        if not self._admit(event, now):
            return
        behaviour = LandOnTopBehaviour(self.nav, self.body, event.src, from_wire_pose(frame), frame.z, now,
                                       partner_give_up_s=self.config.partner_give_up_s)
        self._start(self._running_for(event, behaviour, now), now)
        self._confirm(event, ResultCode.ACCEPTED, now, progress=0)


def from_wire_pose(pose: Pose):
    from rescuemesh.geometry import Pose2D

    return Pose2D(pose.x, pose.y, pose.yaw)
