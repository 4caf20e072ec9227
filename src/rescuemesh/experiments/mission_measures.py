"""Mission metrics that measure over time: moments (`WHEN`: a step's start, end or result, an earlier
metric), windows between two moments, a robot's pose, speed, halt and drift, an orbit's error, the
reports a command got, the waypoints its receiver planned (docs/missions.md, "metrics").

Owns: these metrics' typed form, reading them from YAML (file:line errors) and computing them from a
finished run. Must not know: the step engine (it reads what experiments/mission.py recorded).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from rescuemesh.experiments.yamlread import Reader
from rescuemesh.protocol import ResultCode
from rescuemesh.robot.events import BrainEventKind
from rescuemesh.scenarios.base import following_error, mean_distance

if TYPE_CHECKING:
    from rescuemesh.experiments.mission import MissionScenario

#: Brain log kinds a `brain_event` metric may name: every kind of brain event.
BRAIN_EVENT_KINDS = frozenset(k.value for k in BrainEventKind)
#: An orbit counts from the robot's first sample this close (m) to its circle: the approach is not orbiting.
ON_CIRCLE_M = 0.1


class Moment(enum.Enum):
    STARTED = "started"
    FINISHED = "finished"
    RESULT = "result"
    METRIC = "metric"


@dataclass(frozen=True)
class When:
    """A moment of the run: a step's start, finish or result (at its sender, or at its receiver), or
    the value of an earlier metric (a time in s)."""

    moment: Moment
    name: str  # the step's, or the metric's
    results: frozenset[ResultCode] = frozenset()
    at_receiver: bool = False


@dataclass(frozen=True)
class TimeOf:
    name: str
    when: When


@dataclass(frozen=True)
class MeanDistance:
    name: str
    robots: tuple[str, str]
    start: When
    end: When | None
    digits: int = 3


@dataclass(frozen=True)
class FollowingError:
    name: str
    robots: tuple[str, str]  # leader, follower
    start: When
    end: When | None
    set_distance_m: float | None  # None: the brains' follow distance


@dataclass(frozen=True)
class Halted:
    name: str
    robot: str
    below: float
    start: When


@dataclass(frozen=True)
class Difference:
    name: str
    metrics: tuple[str, str]
    digits: int = 3


@dataclass(frozen=True)
class Drift:
    name: str
    robot: str
    start: When
    digits: int = 3


@dataclass(frozen=True)
class SpeedAt:
    name: str
    robot: str
    at: When
    digits: int = 3


@dataclass(frozen=True)
class PositionAt:
    name: str
    robot: str
    at: When
    digits: int = 3


@dataclass(frozen=True)
class PoseError:
    name: str
    robot: str
    target: str | None  # a step whose target it is measured against, or
    point: tuple[float, float, float] | None  # a pose
    at: When | None  # None (or never): the run's end
    heading: bool  # True: the yaw error in rad; False: the distance in m
    digits: int = 3


@dataclass(frozen=True)
class Target:
    name: str
    step: str
    region: bool  # True: the name of the region the target lies in
    digits: int | None = None


@dataclass(frozen=True)
class Value:
    name: str
    value: Any


@dataclass(frozen=True)
class Reports:
    name: str
    step: str
    result: ResultCode


@dataclass(frozen=True)
class BrainEventTime:
    name: str
    robot: str
    kind: BrainEventKind
    start: When


@dataclass(frozen=True)
class MovedInto:
    name: str
    robot: str
    region: str


class OrbitMeasure(enum.Enum):
    RMS_ERROR = "rms_error"
    ANGLE = "angle"
    TIME = "time"


@dataclass(frozen=True)
class Orbit:
    name: str
    robot: str
    around: str
    radius: float
    start: When
    end: When | None
    measure: OrbitMeasure
    digits: int = 3


@dataclass(frozen=True)
class Waypoints:
    name: str
    step: str
    skipped_only: bool


TimedMetric = (TimeOf | MeanDistance | FollowingError | Halted | Difference | Drift | SpeedAt | PositionAt | PoseError
               | Target | Value | Reports | BrainEventTime | MovedInto | Orbit | Waypoints)

#: The keys that make a metric one of these, and what each is (for "unknown key" messages).
KEYS = {"time_of": "WHEN: the simulated time it happened", "mean_distance": "[R1, R2] over from..to",
        "following_error": "[LEADER, FOLLOWER] over from..to", "halted": "a robot: when it first goes below `below`",
        "difference": "[METRIC, METRIC]: the first minus the second", "drift": "a robot: m it moves after `from`",
        "speed": "a robot: its speed at `at`", "position": "a robot: [X, Y] at `at`",
        "position_error": "{robot, of, at}: m from a target", "heading_error": "{robot, of, at}: rad from a target",
        "target": "a step: [X, Y] it sends a robot to", "target_region": "a step: the region of its target",
        "value": "a constant", "reports": "{step, result}: how many such reports its sender got",
        "brain_event": "{robot, kind}: time of its first such log entry from `from`",
        "moved_into": "{robot, region}: started outside, ended inside", "orbit": "a robot circling another",
        "waypoints": "a step: the waypoints its receiver planned", "waypoints_skipped": "a step: those it skipped",
        "from": "WHEN a window or search starts", "to": "WHEN a window ends (default: the run's end)",
        "at": "WHEN", "below": "m/s", "set_distance": "m", "around": "the robot at the centre",
        "radius": "m", "measure": "rms_error, angle or time", "round": "decimal places"}
_WHEN = "{step: S} (finished), {step: S, started: true}, {step: S, result: X [, at_receiver: true]}, {metric: M}"


def read_when(r: Reader, node, what: str, steps: set[str], metrics: set[str]) -> When:
    """A WHEN: `{step: S}`, `{step: S, started: true}`, `{step: S, result: X or [X, ...], at_receiver:
    true}` or `{metric: M}` (an earlier metric)."""
    from rescuemesh.experiments.mission_spec import read_results

    f = r.keys(node, what, {"step": "a step", "started": "true", "result": "a result or a list of them",
                            "at_receiver": "true: the receiver's own result", "metric": "an earlier metric"})
    if "metric" in f:
        if len(f) != 1:
            raise r.fail(node, f"{what}: a metric moment is `{{metric: NAME}}` alone")
        name = r.text(f["metric"], f"{what}.metric")
        if name not in metrics:
            raise r.fail(f["metric"], f"{what}: {name!r} is not a metric defined above this one")
        return When(Moment.METRIC, name)
    if "step" not in f:
        raise r.fail(node, f"{what} must be one of {_WHEN}")
    step = r.text(f["step"], f"{what}.step")
    if step not in steps:
        raise r.fail(f["step"], f"{what}: unknown step {step!r}")
    if "started" in f:
        if set(f) != {"step", "started"} or not r.flag(f["started"], f"{what}.started"):
            raise r.fail(node, f"{what}: a start is `{{step: S, started: true}}`")
        return When(Moment.STARTED, step)
    if "result" in f:
        receiver = r.flag(f["at_receiver"], f"{what}.at_receiver") if "at_receiver" in f else False
        return When(Moment.RESULT, step, read_results(r, f["result"], f"{what}.result"), receiver)
    if "at_receiver" in f:
        raise r.fail(f["at_receiver"], f"{what}: at_receiver goes with `result`")
    return When(Moment.FINISHED, step)


def read_timed_metric(r: Reader, node, f: dict, name: str, robots: set[str], steps: set[str],
                      metrics: set[str]) -> TimedMetric | None:
    """The metric `f` (its keys' value nodes) if it is one of this module's, else None."""
    form = [k for k in KEYS if k in f and k not in MODIFIERS]
    if not form:
        return None
    if len(form) > 1:
        raise r.fail(node, f"metric {name!r}: one measure per metric, got {', '.join(form)}")
    kind, value = form[0], f[form[0]]
    allowed = MODIFIERS_OF.get(kind, ())
    for key in f:
        if key in MODIFIERS and key not in allowed:
            raise r.fail(f[key], f"metric {name!r}: {key!r} does not apply to {kind}")
    for key in _REQUIRED.get(kind, ()):
        if key not in f:
            raise r.fail(node, f"metric {name!r}: {kind} needs {key!r} ({KEYS[key]})")
    what = f"metric {name!r}"

    def robot(n, label=kind) -> str:
        text = r.text(n, f"{what}.{label}")
        if text not in robots:
            raise r.fail(n, f"{what}.{label}: unknown robot {text!r}; the team is {', '.join(sorted(robots))}")
        return text

    def step(n, label=kind) -> str:
        text = r.text(n, f"{what}.{label}")
        if text not in steps:
            raise r.fail(n, f"{what}.{label}: unknown step {text!r}")
        return text

    def pair(n) -> tuple[str, str]:
        items = r.sequence(n, f"{what}.{kind}")
        if len(items) != 2:
            raise r.fail(n, f"{what}.{kind} takes two robots")
        return robot(items[0]), robot(items[1])

    def when(key) -> When | None:
        return read_when(r, f[key], f"{what}.{key}", steps, metrics) if key in f else None

    digits = r.whole(f["round"], f"{what}.round", maximum=9) if "round" in f else None
    d3 = 3 if digits is None else digits
    if kind == "time_of":
        return TimeOf(name, read_when(r, value, f"{what}.time_of", steps, metrics))
    if kind == "mean_distance":
        return MeanDistance(name, pair(value), when("from"), when("to"), d3)
    if kind == "following_error":
        set_distance = r.number(f["set_distance"], f"{what}.set_distance", above=0.0) if "set_distance" in f else None
        return FollowingError(name, pair(value), when("from"), when("to"), set_distance)
    if kind == "halted":
        return Halted(name, robot(value), r.number(f["below"], f"{what}.below", above=0.0), when("from"))
    if kind == "difference":
        items = r.sequence(value, f"{what}.difference")
        if len(items) != 2:
            raise r.fail(value, f"{what}.difference takes two metrics")
        names = tuple(r.text(i, f"{what}.difference") for i in items)
        for i, n in zip(items, names):
            if n not in metrics:
                raise r.fail(i, f"{what}.difference: {n!r} is not a metric defined above this one")
        return Difference(name, names, d3)
    if kind == "drift":
        return Drift(name, robot(value), when("from"), d3)
    if kind == "speed":
        return SpeedAt(name, robot(value), when("at"), d3)
    if kind == "position":
        return PositionAt(name, robot(value), when("at"), d3)
    if kind in ("position_error", "heading_error"):
        g = r.keys(value, f"{what}.{kind}", {"robot": "a robot", "of": "a step (its target) or [X, Y, YAW]",
                                             "at": "WHEN (default: the run's end)"}, required=("robot", "of"))
        of = g["of"]
        target, point = (None, r.point(of, f"{what}.{kind}.of", yaw=True)) if isinstance(of, yaml.SequenceNode) \
            else (step(of, f"{kind}.of"), None)
        at = read_when(r, g["at"], f"{what}.{kind}.at", steps, metrics) if "at" in g else None
        return PoseError(name, robot(g["robot"], f"{kind}.robot"), target, point, at, kind == "heading_error", d3)
    if kind in ("target", "target_region"):
        return Target(name, step(value), kind == "target_region", digits)
    if kind == "value":
        return Value(name, r.scalar(value) if isinstance(value, yaml.ScalarNode) else
                     [r.scalar(item) for item in r.sequence(value, f"{what}.value")])
    if kind == "reports":
        from rescuemesh.experiments.mission_spec import read_results

        g = r.keys(value, f"{what}.reports", {"step": "a command step", "result": "a result"},
                   required=("step", "result"))
        results = read_results(r, g["result"], f"{what}.reports.result")
        if len(results) != 1:
            raise r.fail(g["result"], f"{what}.reports: one result")
        return Reports(name, step(g["step"], "reports.step"), next(iter(results)))
    if kind == "brain_event":
        g = r.keys(value, f"{what}.brain_event", {"robot": "a robot", "kind": "a log entry's kind"},
                   required=("robot", "kind"))
        event_kind = r.text(g["kind"], f"{what}.brain_event.kind")
        if event_kind not in BRAIN_EVENT_KINDS:
            raise r.fail(g["kind"], f"{what}.brain_event.kind must be one of {', '.join(sorted(BRAIN_EVENT_KINDS))}")
        return BrainEventTime(name, robot(g["robot"], "brain_event.robot"), BrainEventKind(event_kind), when("from"))
    if kind == "moved_into":
        g = r.keys(value, f"{what}.moved_into", {"robot": "a robot", "region": "a region of the map"},
                   required=("robot", "region"))
        return MovedInto(name, robot(g["robot"], "moved_into.robot"), r.text(g["region"], f"{what}.moved_into.region"))
    if kind == "orbit":
        measure = r.text(f["measure"], f"{what}.measure", tuple(m.value for m in OrbitMeasure))
        return Orbit(name, robot(value), robot(f["around"], "around"),
                     r.number(f["radius"], f"{what}.radius", above=0.0), when("from"), when("to"),
                     OrbitMeasure(measure), d3)
    return Waypoints(name, step(value), kind == "waypoints_skipped")


MODIFIERS = ("from", "to", "at", "below", "set_distance", "around", "radius", "measure", "round")
MODIFIERS_OF = {"mean_distance": ("from", "to", "round"), "following_error": ("from", "to", "set_distance"),
                 "halted": ("below", "from"), "difference": ("round",), "drift": ("from", "round"),
                 "speed": ("at", "round"), "position": ("at", "round"), "position_error": ("round",),
                 "heading_error": ("round",), "target": ("round",), "brain_event": ("from",),
                 "orbit": ("around", "radius", "from", "to", "measure", "round")}
_REQUIRED = {"mean_distance": ("from",), "following_error": ("from",), "halted": ("below", "from"),
             "drift": ("from",), "speed": ("at",), "position": ("at",), "brain_event": ("from",),
             "orbit": ("around", "radius", "from", "measure")}


# --- computing ------------------------------------------------------------------------------------------

def moment(scenario: MissionScenario, when: When, values: dict[str, Any]) -> float | None:
    """The simulated time of `when` in s, or None if it never happened."""
    if when.moment is Moment.METRIC:
        return values.get(when.name)
    state = scenario.state(when.name)
    if when.moment is Moment.STARTED:
        return state.started_s
    if when.moment is Moment.FINISHED:
        return state.finished_s
    seen = state.receiver_results if when.at_receiver else state.results
    times = [seen[r] for r in when.results if r in seen]
    return min(times) if times else None


def _sample_at(samples, t: float):
    """The first trajectory sample at or after `t`, or None."""
    return next((s for s in samples if s.time_s >= t), None)


def _round(value, digits: int | None):
    if value is None or digits is None:
        return value
    return None if value != value else round(value, digits)


def compute(scenario: MissionScenario, metric: TimedMetric, rt, values: dict[str, Any]) -> Any:
    """The value of `metric` in a finished run (`values`: the metrics computed before it)."""
    traj = rt.trajectories
    at = (lambda w: None if w is None else moment(scenario, w, values))
    if isinstance(metric, TimeOf):
        return at(metric.when)
    if isinstance(metric, Value):
        return metric.value
    if isinstance(metric, Difference):
        a, b = (values.get(n) for n in metric.metrics)
        return None if a is None or b is None else round(a - b, metric.digits)
    if isinstance(metric, (MeanDistance, FollowingError)):
        t0 = at(metric.start)
        if t0 is None:
            return None
        t1 = at(metric.end)
        t1 = rt.time if t1 is None else t1
        a, b = traj[metric.robots[0]], traj[metric.robots[1]]
        if isinstance(metric, MeanDistance):
            return _round(mean_distance(a, b, t0, t1), metric.digits)
        set_distance = metric.set_distance_m if metric.set_distance_m is not None else rt.config.brain.follow_distance_m
        return following_error(a, b, t0, t1, set_distance)
    if isinstance(metric, Halted):
        t0 = at(metric.start)
        if t0 is None:
            return None
        return next((s.time_s for s in traj[metric.robot] if s.time_s >= t0 and s.speed < metric.below), None)
    if isinstance(metric, Drift):
        t0 = at(metric.start)
        samples = traj[metric.robot]
        first = None if t0 is None else _sample_at(samples, t0)
        if first is None:
            return None
        return round(max(s.pose.distance_to(first.pose) for s in samples if s.time_s >= t0), metric.digits)
    if isinstance(metric, (SpeedAt, PositionAt)):
        t = at(metric.at)
        if t is None:
            return None
        samples = traj[metric.robot]
        sample = _sample_at(samples, t) or samples[-1]
        if isinstance(metric, SpeedAt):
            return round(sample.speed, metric.digits)
        return [round(sample.pose.x, metric.digits), round(sample.pose.y, metric.digits)]
    if isinstance(metric, PoseError):
        samples = traj[metric.robot]
        t = at(metric.at)
        pose = (None if t is None else _sample_at(samples, t)) or samples[-1]
        pose = pose.pose
        goal = scenario.target_of(metric.target, rt) if metric.target is not None else metric.point
        if metric.heading:
            return round(abs(math.remainder(pose.yaw - goal[2], 2 * math.pi)), metric.digits)
        return round(math.hypot(pose.x - goal[0], pose.y - goal[1]), metric.digits)
    if isinstance(metric, Target):
        goal = scenario.target_of(metric.step, rt)
        if metric.region:
            return scenario.map.region_of(goal[0], goal[1])
        return [_round(goal[0], metric.digits), _round(goal[1], metric.digits)]
    if isinstance(metric, Reports):
        return scenario.state(metric.step).reports(metric.result)
    if isinstance(metric, BrainEventTime):
        t0 = at(metric.start)
        if t0 is None:
            return None
        return next((e.time_s for e in rt.brain(metric.robot).log
                     if e.kind is metric.kind and e.time_s >= t0), None)
    if isinstance(metric, MovedInto):
        start, end = traj[metric.robot][0].pose, traj[metric.robot][-1].pose
        region_of = scenario.map.region_of
        return region_of(start.x, start.y) != metric.region and region_of(end.x, end.y) == metric.region
    if isinstance(metric, Orbit):
        return _orbit(metric, traj, at, rt.time)
    if isinstance(metric, Waypoints):
        state = scenario.state(metric.step)
        return list(state.skipped) if metric.skipped_only else list(state.waypoints)
    raise TypeError(metric)


def _orbit(metric: Orbit, traj, at, now: float) -> float | None:
    """RMS radius error (m), anticlockwise angle swept (degrees) or time (s) of `robot` circling where
    `around` was at `from`, counted from its first sample within ON_CIRCLE_M of the circle to `to`."""
    t0 = at(metric.start)
    if t0 is None:
        return None
    centre_sample = _sample_at(traj[metric.around], t0) or traj[metric.around][-1]
    cx, cy = centre_sample.pose.x, centre_sample.pose.y
    end = at(metric.end)
    end = now if end is None else end
    samples = [s for s in traj[metric.robot] if s.time_s <= end]
    if not samples:
        return None
    xy = np.array([[s.pose.x, s.pose.y] for s in samples])
    dist = np.hypot(xy[:, 0] - cx, xy[:, 1] - cy)
    on = np.flatnonzero(np.abs(dist - metric.radius) <= ON_CIRCLE_M)
    if not on.size:
        return None
    window = slice(on[0], None)
    if metric.measure is OrbitMeasure.RMS_ERROR:
        return round(float(np.sqrt(np.mean((dist[window] - metric.radius) ** 2))), metric.digits)
    if metric.measure is OrbitMeasure.ANGLE:
        theta = np.unwrap(np.arctan2(xy[window, 1] - cy, xy[window, 0] - cx))
        return round(float(np.degrees(theta[-1] - theta[0])), metric.digits)
    return round(end - samples[on[0]].time_s, metric.digits)
