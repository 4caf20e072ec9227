"""Scenario `land-on-top` (paper Table III: "flying robots land on ground one"): robot_4 is a
quadrotor; robot_2 sends it LandOnTop and streams its pose; the drone lands on robot_2's top plate
and switches its rotors off; then robot_2 drives 2 m and carries it.

Owns: the mission, its criteria and metrics. Must not know how the drone flies (the world does).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import replace

from rescuemesh.body import FlightPhase, RobotKind
from rescuemesh.geometry import Pose2D
from rescuemesh.protocol import ResultCode
from rescuemesh.protocol.messages import Capability
from rescuemesh.runtime import SimConfig
from rescuemesh.scenarios.base import CommandRequest, Scenario, Verdict, no_collisions, settled

if TYPE_CHECKING:  # annotations only: importing a scenario does not import MuJoCo
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

CARRIER, DRONE = "robot_2", "robot_4"
#: The drone waits on the floor of the hall, 2.3 m from robot_2.
OFFICE_DRONE_START = Pose2D(3.5, 6.2, 0.0)
DRIVE_M = 2.0
MAX_CENTRE_ERROR_M = 0.08
#: The drone counts as carried when it moved at least this share of what robot_2 drove.
CARRIED_SHARE = 0.95


class LandOnTopScenario(Scenario):
    name = "land-on-top"
    summary = "robot_4, a quadrotor, lands on robot_2's top plate on LandOnTop; robot_2 then carries it 2 m"
    time_limit_s = 90.0
    robots = ("robot_1", "robot_2", "robot_3", "robot_4")
    office_extra_starts = {DRONE: (OFFICE_DRONE_START, "the drone")}

    def sim_config(self) -> SimConfig:
        return replace(super().sim_config(), kinds={DRONE: RobotKind.FLYING})

    def __init__(self, options, map_model) -> None:
        super().__init__(options, map_model)
        self._request: CommandRequest | None = None
        self.landed_s: float | None = None
        self.drive_start: tuple[Pose2D, tuple[float, float, float]] | None = None
        self.drove_s: float | None = None
        self.settled_s: float | None = None

    def _sent(self, rt: SimRuntime):
        return None if self._request is None else self._request.confirmed()

    def tick(self, rt: SimRuntime) -> None:
        carrier = rt.brain(CARRIER)
        drone = rt.world.bodies[DRONE]
        if self._request is None:
            self._request = CommandRequest(carrier, DRONE, carrier.command_land_on_top)
        self._request.poll(rt.time)
        if self.landed_s is None:
            if drone.flight_phase() is FlightPhase.LANDED:
                self.landed_s = rt.time
            return
        if self.drive_start is None and rt.time >= self.landed_s + 1.0:
            start = rt.world.bodies[CARRIER].pose()
            self.drive_start = (start, drone.position_3d())
            goal = Pose2D(start.x + DRIVE_M, start.y, start.yaw)
            carrier.navigate_to(goal, rt.time)
        if self.drive_start is not None and self.drove_s is None and carrier.running is None:
            self.drove_s = rt.time
        if self.drove_s is not None and self.settled_s is None and settled(rt, CARRIER, self.drove_s):
            self.settled_s = rt.time

    def finished(self, rt: SimRuntime) -> bool:
        sent = self._sent(rt)
        failed = sent is not None and sent.result in (ResultCode.FAILED, ResultCode.UNSUPPORTED, ResultCode.DENIED)
        return self.settled_s is not None or failed or (self._request is not None and self._request.given_up)

    def evaluate(self, rt: SimRuntime) -> Verdict:
        drone = rt.world.bodies[DRONE]
        sent = self._sent(rt)
        offset = rt.world.top_offset(DRONE, CARRIER)
        landed_on = drone.landed_on()
        rotors_off = drone.flight_phase() is FlightPhase.LANDED
        carried = drove = None
        if self.drive_start is not None:
            start, drone_start = self.drive_start
            end, drone_end = rt.world.bodies[CARRIER].pose(), drone.position_3d()
            drove = start.distance_to(end)
            carried = ((drone_end[0] - drone_start[0]) ** 2 + (drone_end[1] - drone_start[1]) ** 2) ** 0.5
        criteria = [
            ("LandOnTop confirmed DONE", sent is not None and sent.result == ResultCode.DONE),
            (f"the drone rests on robot_2's plate ({landed_on})", landed_on == CARRIER),
            (f"centre within {MAX_CENTRE_ERROR_M} m of the plate's ({offset:.3f} m)", offset <= MAX_CENTRE_ERROR_M),
            ("rotors off", rotors_off),
            (f"carried with robot_2 ({carried if carried is None else round(carried, 2)} m of "
             f"{drove if drove is None else round(drove, 2)} m)",
             carried is not None and drove is not None and drove >= 0.9 * DRIVE_M and carried >= CARRIED_SHARE * drove),
            no_collisions(rt),
        ]
        metrics = {
            "landing_error_m": round(offset, 4),
            "time_to_land_s": self.landed_s,
            "carried_distance_m": None if carried is None else round(carried, 3),
            "carrier_drove_m": None if drove is None else round(drove, 3),
            "landed_on": landed_on,
            "capabilities_seen": {  # what each announced in its Heartbeats, as the other saw it
                "robot_4_by_robot_2": _names(rt.brain(CARRIER).capabilities_of(4)),
                "robot_2_by_robot_4": _names(rt.brain(DRONE).capabilities_of(2)),
            },
        }
        return Verdict(all(ok for _, ok in criteria), criteria, metrics)


def _names(caps) -> list[str] | None:
    return None if caps is None else [c.name for c in Capability if c.value and c in caps]
