"""LandOnTop (paper Table III: "flying robots land on ground one"), the flying robot's side: follow
the ground robot's PoseUpdates down onto its top plate, then rotors off.

Owns: turning PoseUpdates into landing targets and the verdict. Must not know the simulator: it
drives a `rescuemesh.body.FlyingBody` (its autopilot does the flying).
"""

from __future__ import annotations

from rescuemesh.body import FlightPhase, FlyingBody, LandingTarget
from rescuemesh.geometry import Pose2D
from rescuemesh.nav import NavigateToPose
from rescuemesh.protocol import Reason, ResultCode
from rescuemesh.robot.behaviours import STOPPED, Behaviour


class LandOnTopBehaviour(Behaviour):
    """Land on the top of robot `carrier` whose pose (top height `top_z` m) comes by PoseUpdates.
    DONE once the body reports LANDED (rotors off); FAILED when the carrier is silent for
    `partner_give_up_s` or the landing takes longer than `timeout_s`."""

    name = "land-on-top"

    def __init__(self, nav: NavigateToPose, body: FlyingBody, carrier: int, target: Pose2D, top_z: float,
                 now: float, *, partner_give_up_s: float, timeout_s: float = 60.0) -> None:
        super().__init__(nav)
        self.body, self.carrier, self.top_z = body, carrier, top_z
        self.partner_give_up_s, self.timeout_s = partner_give_up_s, timeout_s
        self.started_s = self.last_heard = now
        self.target, self.velocity = target, (0.0, 0.0)
        self._aim(now)

    def on_pose_update(self, pose: Pose2D, now: float) -> None:
        dt = now - self.last_heard
        if dt > 0.05:
            self.velocity = ((pose.x - self.target.x) / dt, (pose.y - self.target.y) / dt)
        self.target, self.last_heard = pose, now
        if not self.paused:
            self._aim(now)

    def _aim(self, now: float) -> None:
        if self.body.flight_phase() is not FlightPhase.LANDED:
            self.body.land_on(LandingTarget(self.target.x, self.target.y, self.top_z, *self.velocity))

    def _restart(self, now: float) -> None:
        self._aim(now)

    def halt(self, now: float) -> None:
        self.body.hold()  # in the air: hover where it is; on a top: rotors stay off

    def progress(self) -> int:
        order = [FlightPhase.FLY, FlightPhase.ALIGN, FlightPhase.DESCEND, FlightPhase.TOUCHDOWN, FlightPhase.LANDED]
        phase = self.body.flight_phase()
        return 25 * order.index(phase) if phase in order else 0

    def step(self, now, pose, scan):
        if self.body.flight_phase() is FlightPhase.LANDED:
            return self._finish(ResultCode.DONE, Reason.NONE, f"landed on robot_{self.carrier}")
        if self.paused:
            return STOPPED
        if now - self.last_heard > self.partner_give_up_s:
            self.body.hold()
            return self._finish(ResultCode.FAILED, Reason.PARTNER_SILENT, f"carrier silent for {now - self.last_heard:.1f} s")
        if now - self.started_s > self.timeout_s:
            self.body.hold()
            return self._finish(ResultCode.FAILED, Reason.TIMEOUT, f"not landed in {self.timeout_s:g} s")
        return STOPPED
