"""Scenarios `show-scan` and `show-cam` (paper Table III: "send image of the specified position"):
robot_1 asks robot_2 for scans (images) of a position around a corner from robot_2; robot_2 moves
to see it and sends them; they are saved to DIR/scans/ (DIR/images/).

Owns: the two missions, criteria, metrics and the saved captures. Must not know the simulator.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pathlib import Path

from rescuemesh.geometry import Pose2D
from rescuemesh.protocol import DataKind, Pose, ResultCode, ShowCam, ShowScan
from rescuemesh.robot import events as ev
from rescuemesh.robot.sensor_codec import SensorDecodeError, decode_image, decode_scan, image_is_informative
from rescuemesh.scenarios.base import CommandRequest, Scenario, ScenarioError, Verdict, no_collisions

if TYPE_CHECKING:  # annotations only: importing a scenario does not import MuJoCo
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

#: In room_north, out of robot_2's sight from its start in the hall (the hall's east wall is between).
OFFICE_TARGET = Pose2D(11.3, 7.6, 0.0)
COUNT, PERIOD_S = 3, 1.0
#: The map's named goal (map YAML `goals:`) used as the spot when no --goal is given.
MAP_GOAL = "show"
#: Images are larger: one every 3 s, so that each has the link to itself (docs/sensors.md).
CAM_PERIOD_S = 3.0
MIN_MOVE_M = 0.5
#: Seconds to wait for the last capture after the command's final report.
LATE_DATA_S = 10.0


class ShowScanScenario(Scenario):
    name = "show-scan"
    runs_as_processes = True
    takes_goal = True
    summary = "robot_1 asks robot_2 for 3 scans of a spot around a corner; robot_2 moves to see it and sends them"
    time_limit_s = 120.0
    asker, sensor = "robot_1", "robot_2"
    kind = DataKind.LASER_SCAN
    folder = "scans"

    def mission_point(self) -> Pose2D:
        return self.target()

    def target(self) -> Pose2D:
        if self.options.goal is not None:
            return self.options.goal
        if self.on_office:
            return OFFICE_TARGET
        if MAP_GOAL in self.map.goals:
            return self.map.goals[MAP_GOAL]
        raise ScenarioError(f"map {self.map.name!r} has no default position to look at (goals: {MAP_GOAL}): "
                            f"give --goal X,Y")

    def validate(self) -> None:
        self.require_free("position", self.target())

    def command(self):
        t = self.target()
        return ShowScan(Pose(t.x, t.y, 0.0, 0.0), PERIOD_S, COUNT)

    def __init__(self, options, map_model) -> None:
        super().__init__(options, map_model)
        self._request: CommandRequest | None = None
        self.asked_s: float | None = None
        self.final_s: float | None = None

    def _sent(self, rt: SimRuntime):
        return None if self._request is None else self._request.confirmed()

    def received(self, rt: SimRuntime) -> list:
        sent = self._sent(rt)
        if sent is None:
            return []
        return [d for d in rt.brain(self.asker).received_data if d[2] == self.kind and d[3] == sent.seq]

    def tick(self, rt: SimRuntime) -> None:
        brain = rt.brain(self.asker)
        if self._request is None:
            self.asked_s = rt.time
            self._request = CommandRequest(brain, self.sensor, lambda peer, now: brain.send(peer, self.command(), now))
        self._request.poll(rt.time)
        sent = self._sent(rt)
        if self.final_s is None and sent is not None and sent.result not in (ResultCode.ACCEPTED, ResultCode.IN_PROGRESS):
            self.final_s = rt.time

    def finished(self, rt: SimRuntime) -> bool:
        if self._request is not None and self._request.given_up:
            return True
        if self.final_s is None:
            return False
        return len(self.received(rt)) >= COUNT or rt.time >= self.final_s + LATE_DATA_S

    def _decoded_ok(self, data: bytes) -> bool:
        try:
            decode_scan(data)
        except SensorDecodeError:
            return False
        return True

    def evaluate(self, rt: SimRuntime) -> Verdict:
        sent = self._sent(rt)
        received = self.received(rt)
        samples = rt.trajectories[self.sensor]
        moved = sum(a.pose.distance_to(b.pose) for a, b in zip(samples, samples[1:]))
        sent_times = [e.time_s for e in rt.brain(self.sensor).log if isinstance(e, ev.DataSent)]
        latencies = [round(r[0] - s, 3) for r, s in zip(received, sent_times)]
        good = [r for r in received if self._decoded_ok(r[4])]
        criteria = [
            (f"{type(self.command()).__name__} confirmed DONE", sent is not None and sent.result == ResultCode.DONE),
            (f"robot_2 moved to see the position ({moved:.2f} m)", moved >= MIN_MOVE_M),
            (f"{COUNT} {self.folder} received ({len(received)})", len(received) == COUNT),
            (f"every one decodes and shows something ({len(good)})", len(good) == len(received) == COUNT),
            no_collisions(rt),
        ]
        metrics = {
            "target": [self.target().x, self.target().y],
            f"{self.folder}_received": len(received),
            "bytes": [len(r[4]) for r in received],
            "hops": [r[5] for r in received],
            "first_delivery_s": None if not received or self.asked_s is None else round(received[0][0] - self.asked_s, 3),
            "delivery_latency_s": latencies,
            "robot_2_moved_m": round(moved, 3),
        }
        return Verdict(all(ok for _, ok in criteria), criteria, metrics)

    def write_files(self, rt: SimRuntime, out_dir: Path) -> list[Path]:
        folder = out_dir / self.folder
        folder.mkdir(parents=True, exist_ok=True)
        paths = []
        for k, item in enumerate(self.received(rt), start=1):
            try:
                scan = decode_scan(item[4])
            except SensorDecodeError:
                continue
            from rescuemesh.report.sensors import draw_scan_png  # matplotlib: only to write files

            paths.append(draw_scan_png(scan, self.map, folder / f"scan_{k}.png",
                                       title=f"scan {k} from robot_2, received at {item[0]:.2f} s ({len(item[4])} B)",
                                       spot=(self.target().x, self.target().y)))
        return paths


class ShowCamScenario(ShowScanScenario):
    name = "show-cam"
    runs_as_processes = False  # camera images are not carried between processes
    summary = "robot_1 asks robot_2 for 3 camera images of a spot around a corner; robot_2 moves, looks, sends them"
    kind = DataKind.IMAGE_JPEG
    folder = "images"

    def command(self):
        t = self.target()
        return ShowCam(Pose(t.x, t.y, 0.0, 0.0), CAM_PERIOD_S, COUNT)

    def _decoded_ok(self, data: bytes) -> bool:
        try:
            return image_is_informative(decode_image(data))
        except SensorDecodeError:
            return False

    def write_files(self, rt: SimRuntime, out_dir: Path) -> list[Path]:
        folder = out_dir / self.folder
        folder.mkdir(parents=True, exist_ok=True)
        paths = []
        for k, item in enumerate(self.received(rt), start=1):
            path = folder / f"image_{k}.jpg"
            path.write_bytes(item[4])  # as received: a JPEG file
            paths.append(path)
        return paths
