"""A mission file, run: its team on its map, its steps started on their triggers, its criteria and
metrics judged, through the same runner as the built-in scenarios (result.json, plots, run.mcap).

Owns: MissionScenario (a Scenario built from a Mission) and the step engine. Must not know: the
command line, the simulator's internals (it reads the runtime's brains, trajectories and map).
Everything it compares is a value (results, positions, reachability), never a log line's text.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

from rescuemesh.body import FlightPhase, RobotKind
from rescuemesh.experiments.measures import Measure, time_of_events, value_of
from rescuemesh.experiments.mission_measures import MovedInto, compute
from rescuemesh.experiments.mission_spec import (
    At, CommandSpec, CommandType, Distance, Drive, EndMission, EndsIn, EndsNear, LandsOn, Mission, MetricBound,
    NoCollision, OnAnswered, OnGivenUp, OnKnows, OnLanded, OnLink, OnMoving, OnNear, OnRegion, OnSettled, OnSpeed,
    OnStep, OnTeamUp, Outage, PathLength, RobotModel, SendCommand, Settle, Step, StepAnswer, StepData, StepDecoded,
    StepFinished, StepResult, TimeTo, Wait)
from rescuemesh.geometry import Pose2D
from rescuemesh.protocol import (
    Follow, ForwardMsg, Goto, LandOnTop, MoveAround, Pose, ResultCode, Return, ShowCam, ShowScan, Stop)
from rescuemesh.protocol.codec import encode_inner
from rescuemesh.robot import robot_address
from rescuemesh.robot.forwarding import FINAL_RESULTS  # results after which a command does no more
from rescuemesh.robot.records import power_on_s, to_wire_pose
from rescuemesh.runtime import RadioKind
from rescuemesh.robot.behaviours import MoveAroundBehaviour
from rescuemesh.scenarios.base import (CommandRequest, Scenario, ScenarioError, ScenarioOptions, Verdict, last_result,
                                       no_collisions, settled)
from rescuemesh.scenarios.move_around import waypoint_table

if TYPE_CHECKING:
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

#: Commands whose ACCEPTED is their outcome (they report no progress and no final result).
_ACCEPTED_IS_FINAL = frozenset({CommandType.FOLLOW, CommandType.STOP})
#: A mission has played out this long after its last step finished (reports still on the air land).
SETTLE_S = 2.0  # the default of a mission's `end_after`
#: How long a ShowScan/ShowCam step waits, after DONE, for data still on the way, in s.
DATA_GRACE_S = 5.0


@dataclass
class StepState:
    """What became of one step: when its trigger held, when it started and finished, what it saw."""

    step: Step
    triggered_s: float | None = None
    started_s: float | None = None
    finished_s: float | None = None
    request: CommandRequest | None = None
    results: dict[ResultCode, float] = field(default_factory=dict)  # each result seen -> first time, in s
    drive: object | None = None  # the Running a drive started
    was_heard: bool = False  # a `loses` trigger: its peer was heard at some point
    # what the receiver did with a command step's command (its Running, the result it ended it with ->
    # when), and the waypoints it planned for it (a MoveAround's: one row each, skipped ones last)
    receiver_running: object | None = None
    receiver_results: dict[ResultCode, float] = field(default_factory=dict)
    waypoints: list[dict] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)

    answers: dict = field(default_factory=dict)  # each (result, reason) seen -> first time, in s
    poses_at_start: dict | None = None  # every robot's pose when the step started (displacement metrics)
    route_left: list = field(default_factory=list)  # a drive's route points still to go
    goal: Pose2D | None = None  # a drive's current goal
    late: bool = False  # started by its `at_latest` time, not by its trigger

    def reports(self, result: ResultCode) -> int:
        """How many reports with `result` the sender got for this step's command (every copy)."""
        if self.request is None:
            return 0
        outgoing = self.request.brain.outgoing
        return sum(outgoing[seq].reports.get(result, 0) for seq in self.request.seqs)


class MissionScenario(Scenario):
    """A Scenario whose team, script and verdict come from a Mission."""

    name = "mission"
    summary = "a mission file"
    time_limit_s = 120.0

    def __init__(self, mission: Mission, options: ScenarioOptions, map_model) -> None:
        self.mission = mission
        self.name = mission.name
        self.summary = mission.summary
        self.time_limit_s = mission.time_limit_s
        self.robots = tuple(mission.team)
        self.states = [StepState(step) for step in mission.steps]
        self._by_name = {s.step.name: s for s in self.states}
        self._configured = False
        self._all_done_s: float | None = None
        self._end_now = False  # an `end` step has started
        self._stopped = False  # a stop_when event held
        self._stop_states = [StepState(Step("stop_when", t, 0.0, Wait(1.0))) for t in mission.stop_when]
        self._watched = [(m, StepState(Step(m.name, m.arg, 0.0, Wait(1.0)))) for m in time_of_events(mission.metrics)]
        self.event_times: dict[str, float] = {}  # a time_of metric's name -> when its event first held
        super().__init__(options, map_model)

    def state(self, step: str) -> StepState:
        """What became of step `step` (for metrics)."""
        return self._by_name[step]

    def target_of(self, step: str, rt: SimRuntime) -> tuple[float, float, float]:
        """Where step `step` sends a robot: its drive's or Goto's pose, or for a Return the receiver's
        base (the team's `base`, else the map's, else where it started, as the runtime sets it)."""
        action = self._by_name[step].step.action
        if isinstance(action, Drive):
            return action.pose
        if isinstance(action, SendCommand):
            command = action.command
            if command.type is CommandType.GOTO:
                return command.pose
            if command.type is CommandType.RETURN:
                robot = self.mission.team[action.receiver]
                if robot.base is not None:
                    return robot.base
                base = self.map.bases.get(action.receiver, rt.trajectories[action.receiver][0].pose)
                return (base.x, base.y, base.yaw)
        raise ScenarioError(f"{self.mission.path}: step {step!r} sends no robot to a pose (a drive, goto or return)")

    @classmethod
    def options_for(cls, mission: Mission, seed: int = 0, **overrides) -> ScenarioOptions:
        s = mission.settings
        values = dict(seed=seed, loss=s.loss, relay=s.relay, radio=RadioKind(s.radio), secure=s.secure)
        values.update({k: v for k, v in overrides.items() if v is not None})
        return ScenarioOptions(**values)

    def validate(self) -> None:
        regions = set(self.map.regions)
        for metric in self.mission.metrics:
            if isinstance(metric, MovedInto) and metric.region not in regions:
                raise ScenarioError(f"{self.mission.path}: metric {metric.name!r}: map {self.map.name!r} has no "
                                    f"region {metric.region!r}")
        for state in self.states:
            trigger = state.step.trigger
            if isinstance(trigger, OnRegion) and trigger.region not in regions:
                raise ScenarioError(f"{self.mission.path}: step {state.step.name!r} waits for region "
                                    f"{trigger.region!r}, which map {self.map.name!r} does not have "
                                    f"(regions: {', '.join(regions) or 'none'})")
            action = state.step.action
            if isinstance(action, Drive):
                for pose in ((action.pose,) if action.pose is not None else action.route):
                    self.require_free(f"step {state.step.name!r}'s drive target", Pose2D(*pose))
        for criterion in self.mission.criteria:
            if isinstance(criterion, EndsIn) and criterion.region not in regions:
                raise ScenarioError(f"{self.mission.path}: criterion ends_in {criterion.region!r}: map "
                                    f"{self.map.name!r} has no such region")

    def default_starts(self) -> dict[str, Pose2D]:
        starts = dict(self.map.starts)
        for name, robot in self.mission.team.items():
            if robot.start is not None:
                starts[name] = Pose2D(*robot.start)
            elif name not in starts:
                raise ScenarioError(f"{self.mission.path}: robot {name} has no start, and map {self.map.name!r} "
                                    f"gives none: set team.{name}.start")
        return starts

    def sim_config(self):
        config = super().sim_config()
        kinds = {name: RobotKind.FLYING for name, r in self.mission.team.items() if r.model is RobotModel.QUADROTOR}
        ranks = {robot_address(name): r.rank for name, r in self.mission.team.items()}
        brain = replace(config.brain, ranks=ranks)
        s = self.mission.settings
        if s.follow_distance_m is not None:
            brain = replace(brain, follow_distance_m=s.follow_distance_m)
        if s.power_on_spread_s is not None:
            brain = replace(brain, power_on_spread_s=s.power_on_spread_s)
        return replace(config, kinds=kinds, brain=brain)

    # --- the script ---

    def tick(self, rt: SimRuntime) -> None:
        now = rt.time
        if not self._configured:  # bases: each brain's own (the runtime gives every robot its start)
            for name, robot in self.mission.team.items():
                if robot.base is not None:
                    brain = rt.brain(name)
                    brain.config = replace(brain.config, base=Pose2D(*robot.base))
            self._configured = True
        for state in self.states:
            if state.started_s is None:
                armed = (state.step.armed_by is None or self._by_name[state.step.armed_by].finished_s is not None) \
                    and now >= state.step.not_before_s - 1e-9
                if state.triggered_s is None and armed and self._fires(state, rt):
                    state.triggered_s = now
                if state.triggered_s is None and state.step.at_latest is not None and \
                        now >= state.step.at_latest - 1e-9:
                    state.triggered_s, state.late = now, True
                after = 0.0 if state.late else state.step.after_s
                if state.triggered_s is not None and now >= state.triggered_s + after - 1e-9:
                    self._start(state, rt)
            if state.started_s is not None and state.finished_s is None:
                self._poll(state, rt)
            elif state.finished_s is not None and state.request is not None:  # later results (CANCELLED, ...)
                sent = _latest_answered(state.request)
                if sent is not None and sent.result is not None:
                    self._note_answer(state, sent, now)
            if state.request is not None and not state.receiver_results:
                self._watch_receiver(state, rt)
        if self._all_done_s is None and all(s.finished_s is not None for s in self.states):
            self._all_done_s = now
        for metric, watch in self._watched:
            if metric.name not in self.event_times and self._fires(watch, rt):
                self.event_times[metric.name] = now
        if not self._stopped and any(self._fires(s, rt) for s in self._stop_states):
            self._stopped = True

    def finished(self, rt: SimRuntime) -> bool:
        if self._end_now or self._stopped:  # an `end` step started, or a stop_when event held
            return True
        return self._all_done_s is not None and rt.time >= self._all_done_s + self.mission.end_after_s - 1e-9

    def _watch_receiver(self, state: StepState, rt: SimRuntime) -> None:
        """Note when the receiver runs this step's command (any copy) and the result it ends it with."""
        action = state.step.action
        brain = rt.brain(action.receiver)
        running = brain.running
        if running is not None and running.commander == robot_address(action.sender) and \
                running.seq in state.request.seqs and running is not state.receiver_running:
            state.receiver_running = running
            if not state.waypoints and isinstance(running.behaviour, MoveAroundBehaviour):
                state.waypoints = waypoint_table(running.behaviour)
                state.skipped = [str(i) for i in dict.fromkeys(w.index for w in running.behaviour.skipped)]
            return
        ran = state.receiver_running
        if ran is not None and running is not ran:
            ended = next((f for f in reversed(brain.finished)
                          if f.started_s == ran.started_s and f.name == ran.behaviour.name), None)
            if ended is not None:
                state.receiver_results[ended.result] = ended.ended_s

    def _fires(self, state: StepState, rt: SimRuntime) -> bool:
        trigger = state.step.trigger
        if isinstance(trigger, At):
            return rt.time >= trigger.time_s - 1e-9
        if isinstance(trigger, OnStep):
            other = self._by_name[trigger.step]
            if trigger.started:
                return other.started_s is not None
            if trigger.result is None:
                return other.finished_s is not None
            seen = other.receiver_results if trigger.at_receiver else other.results
            return any(r in seen for r in trigger.results)
        if isinstance(trigger, OnSpeed):
            return rt.trajectories[trigger.robot][-1].speed >= trigger.at_least
        if isinstance(trigger, OnSettled):
            armed_by = self._by_name[state.step.armed_by] if state.step.armed_by is not None else None
            since = max(armed_by.finished_s if armed_by is not None else 0.0, state.step.not_before_s)
            return settled(rt, trigger.robot, since)
        if isinstance(trigger, OnRegion):
            pose = rt.trajectories[trigger.robot][-1].pose
            return self.map.region_of(pose.x, pose.y) == trigger.region
        if isinstance(trigger, OnNear):  # where the robots are now (trajectories get this tick's pose after it)
            pose = rt.world.bodies[trigger.robot].pose()
            there = rt.world.bodies[trigger.other].pose() if trigger.other is not None else \
                Pose2D(trigger.point[0], trigger.point[1], 0.0)
            return math.hypot(pose.x - there.x, pose.y - there.y) <= trigger.distance
        if isinstance(trigger, OnLink):
            heard = rt.brain(trigger.robot).network.is_reachable(robot_address(trigger.peer), rt.time)
            if not trigger.lost:
                return heard
            state.was_heard = state.was_heard or heard  # losing needs having heard it first
            return state.was_heard and not heard
        return self._fires_more(trigger, rt)

    def _start(self, state: StepState, rt: SimRuntime) -> None:
        now, action = rt.time, state.step.action
        state.started_s = now
        state.poses_at_start = {name: rt.world.bodies[name].pose() for name in self.robots}
        if isinstance(action, Drive) and action.pose is None:
            self._start_drive(state, rt)
        elif isinstance(action, SendCommand):
            brain = rt.brain(action.sender)
            if action.command.type is CommandType.STOP:  # as a user's Stop: it also ends a pose stream to the peer
                send = brain.command_stop
            else:
                send = (lambda peer, t, b=brain, c=action.command: b.send(peer, _message(c, b), t))
            state.request = CommandRequest(brain, action.receiver, send, attempts=state.step.attempts)
            state.request.poll(now)
        elif isinstance(action, Drive):
            brain = rt.brain(action.robot)
            brain.navigate_to(Pose2D(*action.pose), now)
            state.drive = brain.running
        elif isinstance(action, Outage):
            rt.set_radio(action.robot, False)
        elif isinstance(action, EndMission):
            self._end_now = True
            state.finished_s = now

    def _poll(self, state: StepState, rt: SimRuntime) -> None:
        now, action = rt.time, state.step.action
        if isinstance(action, SendCommand):
            state.request.poll(now)
            sent = _latest_answered(state.request)
            if sent is not None and sent.result is not None:
                self._note_answer(state, sent, now)
                final = sent.result in FINAL_RESULTS or (sent.result == ResultCode.ACCEPTED
                                                 and action.command.type in _ACCEPTED_IS_FINAL)
                if final and sent.seq != state.request.seqs[-1] and not state.request.brain.outgoing[
                        state.request.seqs[-1]].failed:
                    final = False  # an older copy ended (replaced by our newer one, say): the newer one decides
                if final and self._awaits_data(state, rt, now):
                    final = False
                final = final or state.step.finish_on_answer
                if final:
                    state.finished_s = now
            elif state.request.given_up:
                state.finished_s = now
        elif isinstance(action, Drive):
            if rt.brain(action.robot).running is not state.drive:
                self._drive_ended(state, rt)
        elif isinstance(action, Settle):
            if all(settled(rt, name, state.started_s) for name in action.robots):
                state.finished_s = now
        elif isinstance(action, Outage):
            if now >= state.started_s + action.seconds - 1e-9:
                rt.set_radio(action.robot, True)
                state.finished_s = now
        elif isinstance(action, Wait):
            if now >= state.started_s + action.seconds - 1e-9:
                state.finished_s = now

    def _awaits_data(self, state: StepState, rt: SimRuntime, now: float) -> bool:
        """A ShowScan or ShowCam (forwarded or not) that ended DONE still has data on the way: a scan
        is segmented and slower than the DONE that follows it. Wait for `count` items, at most
        DATA_GRACE_S after DONE."""
        command = state.step.action.command
        if command.type is CommandType.FORWARD_MSG:
            command = command.inner
        if command.type not in (CommandType.SHOW_SCAN, CommandType.SHOW_CAM) or \
                ResultCode.DONE not in state.results:
            return False
        grace = DATA_GRACE_S if state.step.data_wait_s is None else state.step.data_wait_s
        return self._data_count(state, rt) < command.count and now < state.results[ResultCode.DONE] + grace

    # --- the verdict ---

    def _distance(self, rt: SimRuntime, robot: str, other: str | None, point) -> float:
        pose = rt.trajectories[robot][-1].pose
        if other is not None:
            there = rt.trajectories[other][-1].pose
            return pose.distance_to(there)
        return math.hypot(pose.x - point[0], pose.y - point[1])

    def _metric_values(self, rt: SimRuntime) -> dict[str, float | None]:
        values: dict[str, float | None] = {}
        for metric in self.mission.metrics:
            values[metric.name] = self._metric_value(metric, rt, values)
        return values

    def _metric_value(self, metric, rt: SimRuntime, values: dict | None = None):
        """One metric's value; `values`: the metrics computed before it (a metric may use an earlier one's)."""
        if isinstance(metric, Distance):
            return round(self._distance(rt, metric.robots[0], metric.robots[1], None), 3)
        if isinstance(metric, TimeTo):
            state = self._by_name[metric.step]
            seen = state.results.get(metric.result)
            return None if seen is None or state.started_s is None else round(seen - state.started_s, 3)
        if isinstance(metric, PathLength):
            samples = rt.trajectories[metric.robot]
            return round(sum(a.pose.distance_to(b.pose) for a, b in zip(samples, samples[1:])), 3)
        if isinstance(metric, Measure):  # experiments/measures.py
            return value_of(metric, self, rt)
        return compute(self, metric, rt, {} if values is None else values)  # experiments/mission_measures.py

    def evaluate(self, rt: SimRuntime) -> Verdict:
        metrics = self._metric_values(rt)
        criteria = []
        for c in self.mission.criteria:
            if isinstance(c, NoCollision):
                criteria.append(no_collisions(rt))
            elif isinstance(c, StepResult):
                state = self._by_name[c.step]
                seen = (state.receiver_results if c.at_receiver else state.results).get(c.result)
                ok = seen is not None and (c.within_s is None or seen - state.started_s <= c.within_s)
                when = "" if seen is None else f" at {seen:.1f} s"
                within = "" if c.within_s is None else f" within {c.within_s:g} s"
                where = " at its receiver" if c.at_receiver else ""
                criteria.append((f"step {c.step}: {c.result.name}{where}{within}{when}", ok))
            elif isinstance(c, StepData):
                count = self._data_count(self._by_name[c.step], rt)
                criteria.append((f"step {c.step}: at least {c.at_least} data items back ({count})", count >= c.at_least))
            elif isinstance(c, EndsIn):
                pose = rt.trajectories[c.robot][-1].pose
                region = self.map.region_of(pose.x, pose.y)
                criteria.append((f"{c.robot} ends in {c.region} ({region})", region == c.region))
            elif isinstance(c, EndsNear):
                d = self._distance(rt, c.robot, c.other, c.point)
                of = c.other if c.other is not None else f"({c.point[0]:g}, {c.point[1]:g})"
                criteria.append((f"{c.robot} ends within {c.distance:g} m of {of} ({d:.2f} m)", d <= c.distance))
            elif isinstance(c, MetricBound) and c.equals:
                value = _metric_named(metrics, c.metric)
                criteria.append((f"{c.metric} is {c.equals[0]!r} ({value!r})", value == c.equals[0]
                                 and isinstance(value, bool) == isinstance(c.equals[0], bool)))
            elif isinstance(c, MetricBound):
                value = _metric_named(metrics, c.metric)
                scale = 1.0 if c.relative_to is None else metrics.get(c.relative_to)
                ok = value is not None and scale is not None and \
                    (c.minimum is None or value >= c.minimum * scale) and \
                    (c.maximum is None or value <= c.maximum * scale)
                of = "" if c.relative_to is None else f" x {c.relative_to} ({scale})"
                bounds = " and ".join(x for x in (f">= {c.minimum:g}{of}" if c.minimum is not None else "",
                                                  f"<= {c.maximum:g}{of}" if c.maximum is not None else "") if x)
                criteria.append((f"{c.metric} {bounds} ({value})", ok))
            else:
                criteria.append(self._criterion_more(c, rt))
        for state in self.states:
            name = state.step.name
            metrics[f"{name}_started_s"] = state.started_s
            metrics[f"{name}_finished_s"] = state.finished_s
            if isinstance(state.step.action, SendCommand):
                last = _latest_answered(state.request) if state.request is not None else None
                metrics[f"{name}_result"] = None if last is None or last.result is None else last.result.name
        return Verdict(all(ok for _, ok in criteria), criteria, metrics)

    def _data_count(self, state: StepState, rt: SimRuntime) -> int:
        action = state.step.action
        if state.request is None or not isinstance(action, SendCommand):
            return 0
        seqs = set(state.request.seqs)
        peer = robot_address(action.receiver)
        return sum(1 for item in rt.brain(action.sender).received_data if item[1] == peer and item[3] in seqs)


    # --- additions for the built-in scenarios as missions (issue 18) ---

    def _fires_more(self, trigger, rt: SimRuntime) -> bool:
        if isinstance(trigger, OnKnows):
            return robot_address(trigger.peer) in rt.brain(trigger.robot).peer_capabilities
        if isinstance(trigger, OnMoving):
            return rt.trajectories[trigger.robot][-1].speed >= trigger.speed  # as of the last step's record
        if isinstance(trigger, OnLanded):
            body = rt.world.bodies[trigger.robot]
            return hasattr(body, "flight_phase") and body.flight_phase() is FlightPhase.LANDED
        if isinstance(trigger, OnTeamUp):
            config = rt.config.brain
            last = max(power_on_s(robot_address(name), config.power_on_spread_s) for name in self.robots)
            return rt.time >= (last + rt.config.mesh.heartbeat_period_s if last > 0.0 else 0.0)
        if isinstance(trigger, OnAnswered):
            return bool(self._by_name[trigger.step].results)
        if isinstance(trigger, OnGivenUp):
            request = self._by_name[trigger.step].request
            return request is not None and request.given_up
        raise TypeError(trigger)

    def _start_drive(self, state: StepState, rt: SimRuntime) -> None:
        """A drive by an offset or along a route (a drive `to` a pose starts in _start)."""
        action, now = state.step.action, rt.time
        brain = rt.brain(action.robot)
        if action.by is not None:
            here = rt.world.bodies[action.robot].pose()
            goal = Pose2D(here.x + action.by[0], here.y + action.by[1], here.yaw)
        else:
            state.route_left = [Pose2D(*p) for p in action.route]
            goal = state.route_left.pop(0)
        state.goal = goal
        brain.navigate_to(goal, now)
        state.drive = brain.running

    def _drive_ended(self, state: StepState, rt: SimRuntime) -> None:
        """A drive's leg ended: its result is the brain's navigate result; a route goes on after DONE."""
        brain, now = rt.brain(state.step.action.robot), rt.time
        result = last_result(brain, "navigate")
        if result == ResultCode.DONE and state.route_left:
            state.goal = state.route_left.pop(0)
            brain.navigate_to(state.goal, now)
            state.drive = brain.running
            return
        if result is not None:
            state.results.setdefault(result, now)
        state.finished_s = now

    def aim_of(self, state: StepState) -> list[float] | None:
        """[X, Y] a step heads for: its drive's (last) goal, or its command's pose or spot."""
        action = state.step.action
        if isinstance(action, Drive):
            if action.pose is not None:
                return [action.pose[0], action.pose[1]]
            if action.route:
                return [action.route[-1][0], action.route[-1][1]]
            return None if state.goal is None else [state.goal.x, state.goal.y]
        if isinstance(action, SendCommand):
            command = action.command.inner or action.command
            point = command.pose or command.spot
            return None if point is None else [point[0], point[1]]
        return None

    def data_items(self, state: StepState, rt: SimRuntime) -> list:
        """The data records (time, src, kind, ref_seq, bytes, hops) answering a command step, in order."""
        action = state.step.action
        if state.request is None or not isinstance(action, SendCommand):
            return []
        seqs = set(state.request.seqs)
        peer = robot_address(action.receiver)
        return [item for item in rt.brain(action.sender).received_data if item[1] == peer and item[3] in seqs]

    def data_source(self, state: StepState) -> str:
        """The robot that sends a command step's data (a forwarded command's target)."""
        action = state.step.action
        return action.command.target or action.receiver

    @staticmethod
    def _note_answer(state: StepState, sent, now: float) -> None:
        state.results.setdefault(sent.result, now)
        state.answers.setdefault((sent.result, sent.reason), now)

    def _criterion_more(self, c, rt: SimRuntime) -> tuple[str, bool]:
        if isinstance(c, StepAnswer):
            seen = self._by_name[c.step].answers.get((c.result, c.reason))
            when = "" if seen is None else f" at {seen:.1f} s"
            return (f"step {c.step}: {c.result.name} ({c.reason.name}){when}", seen is not None)
        if isinstance(c, StepFinished):
            when = self._by_name[c.step].finished_s
            return (f"step {c.step} finished" + ("" if when is None else f" at {when:.1f} s"), when is not None)
        if isinstance(c, StepDecoded):
            items = self.data_items(self._by_name[c.step], rt)
            good = sum(1 for item in items if _decodes(item))
            return (f"step {c.step}: at least {c.at_least} data items decode ({good} of {len(items)})",
                    good >= c.at_least and good == len(items))
        if isinstance(c, LandsOn):
            body = rt.world.bodies[c.robot]
            on = body.landed_on() if hasattr(body, "landed_on") else None
            off = hasattr(body, "flight_phase") and body.flight_phase() is FlightPhase.LANDED
            return (f"{c.robot} ends on {c.carrier}'s top plate, rotors off ({on}, rotors "
                    f"{'off' if off else 'on'})", on == c.carrier and off)
        raise TypeError(c)


def _metric_named(metrics: dict, name: str):
    """A metric's value by name; GROUP.PART names a part of a group metric."""
    if name in metrics or "." not in name:
        return metrics.get(name)
    group, part = name.split(".", 1)
    return (metrics.get(group) or {}).get(part)


def _decodes(item) -> bool:
    """A data record's bytes decode: a laser scan, or a camera image that shows something."""
    from rescuemesh.protocol import DataKind
    from rescuemesh.robot.sensor_codec import SensorDecodeError, decode_image, decode_scan, image_is_informative

    try:
        if item[2] == DataKind.LASER_SCAN:
            decode_scan(item[4])
            return True
        return image_is_informative(decode_image(item[4]))
    except SensorDecodeError:
        return False


def _latest_answered(request: CommandRequest):
    """The newest copy of a mission's command that was answered (the mission may have sent it again
    after the protocol gave a copy up; a later copy's outcome is the one that counts), or None."""
    outgoing = request.brain.outgoing
    return next((outgoing[s] for s in reversed(request.seqs)
                 if outgoing[s].result is not None and not outgoing[s].failed), None)


def _message(command: CommandSpec, brain):
    """The protocol message for `command`, sent now by `brain` (Follow, MoveAround and LandOnTop carry
    the sender's own pose)."""
    here = to_wire_pose(brain.body.pose())
    kind = command.type
    if kind is CommandType.FOLLOW:
        return Follow(here)
    if kind is CommandType.STOP:
        return Stop()
    if kind is CommandType.MOVE_AROUND:
        return MoveAround(here, command.radius)
    if kind is CommandType.GOTO:
        x, y, yaw = command.pose
        return Goto(Pose(x, y, 0.0, yaw))
    if kind is CommandType.RETURN:
        return Return()
    if kind is CommandType.LAND_ON_TOP:  # the sender's top plate: the height to land at
        return LandOnTop(Pose(here.x, here.y, brain.body.top_height or 0.0, here.yaw))
    if kind in (CommandType.SHOW_SCAN, CommandType.SHOW_CAM):
        cls = ShowScan if kind is CommandType.SHOW_SCAN else ShowCam
        period = command.period if command.count != 1 else 0.0
        return cls(Pose(command.spot[0], command.spot[1], 0.0, 0.0), period, command.count)
    if kind is CommandType.FORWARD_MSG:
        return ForwardMsg(robot_address(command.target), encode_inner(_message(command.inner, brain)))
    raise ValueError(kind)

