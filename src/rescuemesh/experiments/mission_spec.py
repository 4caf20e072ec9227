"""A mission file: a team on a map, settings, a script of steps (actions started at a time or on an
event) and success criteria and metrics from a documented vocabulary (docs/missions.md).

Owns: reading a mission from YAML into its typed form (experiments/mission_types.py), every error naming
the file and the line. Must not know: how a mission runs (experiments/mission.py) or the simulator.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from rescuemesh.experiments.mission_measures import KEYS as TIMED_METRIC_KEYS
from rescuemesh.experiments.mission_measures import MODIFIERS as TIMED_METRIC_MODIFIERS
from rescuemesh.experiments.mission_measures import read_timed_metric
from rescuemesh.experiments.yamlread import Reader, read_yaml
from rescuemesh.protocol import Reason, ResultCode
from rescuemesh.robot.policy import Rank

from rescuemesh.experiments.mission_types import (  # noqa: F401  (the typed form, re-exported)
    MissionError, CommandType, RobotModel, CommandSpec, SendCommand, Drive, Outage, Wait, EndMission, Settle,
    Action, At, OnStep, OnRegion, OnNear, OnLink, OnSpeed, OnSettled, OnKnows, OnMoving, OnLanded, OnTeamUp,
    OnAnswered, OnGivenUp, Trigger, Step, StepResult, StepData, EndsIn, EndsNear, NoCollision, MetricBound,
    StepAnswer, StepFinished, StepDecoded, LandsOn, Criterion, Distance, TimeTo, PathLength, Metric, RobotSpec,
    Settings, Mission)

MAX_FILE_BYTES = 256 * 1024


# --- reading ------------------------------------------------------------------------------------------

_TOP = {"mission": "its name", "summary": "one line on what it shows", "map": "office, or a map file",
        "time_limit": "simulated seconds", "settings": "loss, relay, radio, secure", "team": "the robots",
        "steps": "the script", "criteria": "what success means", "metrics": "figures to report",
        "end_after": "s the mission plays on once every step has finished (default 2)",
        "stop_when": "events that end the mission"}
_RESULTS = {r.name.lower(): r for r in ResultCode}


def load_mission(path: Path) -> Mission:
    """Read and validate a mission file; MissionError (one line, file and line) if anything is off."""
    path = Path(path)
    r, root = read_yaml(path, MissionError, MAX_FILE_BYTES, "a mission file")
    top = r.keys(root, "a mission file", _TOP, required=("team", "steps", "criteria"))
    name = r.text(top["mission"], "mission") if "mission" in top else path.stem
    summary = str(r.scalar(top["summary"])) if "summary" in top else ""
    map_path = None
    if "map" in top and r.text(top["map"], "map") != "office":
        map_path = (path.parent / r.text(top["map"], "map")).resolve()
        if not map_path.is_file():
            raise r.fail(top["map"], f"map file {str(map_path)!r} does not exist")
    limit = r.number(top["time_limit"], "time_limit", above=0.0) if "time_limit" in top else 120.0
    settings = _settings(r, top["settings"]) if "settings" in top else Settings()
    team = _team(r, top["team"])
    names = set(team)
    steps = _steps(r, top["steps"], names)
    step_names = {s.name for s in steps}
    for step in steps:
        for other in (step.trigger.step if isinstance(step.trigger, (OnStep, OnGivenUp, OnAnswered)) else None,
                      step.armed_by):
            if other is not None and other not in step_names:
                raise r.fail(top["steps"], f"step {step.name!r} waits for step {other!r}, which does not exist")
    metrics: list[Metric] = []
    for item in r.sequence(top["metrics"], "metrics") if "metrics" in top else ():
        metric = _metric(r, item, names, step_names, {m.name for m in metrics})
        if any(m.name == metric.name for m in metrics):
            raise r.fail(item, f"metrics: the name {metric.name!r} is used twice")
        metrics.append(metric)
    metric_names = [m.name for m in metrics]
    criteria = tuple(_criterion(r, item, names, step_names, set(metric_names) | _group_parts(metrics))
                     for item in r.sequence(top["criteria"], "criteria"))
    end_after = r.number(top["end_after"], "end_after", minimum=0.0) if "end_after" in top else 2.0
    stop_when = tuple(_trigger(r, item, "stop_when", names) for item in r.sequence(top["stop_when"], "stop_when")) \
        if "stop_when" in top else ()
    for trigger in stop_when:
        if isinstance(trigger, (OnStep, OnGivenUp, OnAnswered)) and trigger.step not in step_names:
            raise r.fail(top["stop_when"], f"stop_when waits for step {trigger.step!r}, which does not exist")
    return Mission(name, path, summary, map_path, limit, settings, team, steps, criteria, tuple(metrics), end_after,
                   stop_when)


def _settings(r: Reader, node) -> Settings:
    f = r.keys(node, "settings", {"loss": "in [0, 1)", "relay": "true or false", "radio": "ble or disc",
                                  "secure": "true or false", "follow_distance": "m a follower keeps",
                                  "power_on_spread": "s over which the team is switched on"})
    loss = r.number(f["loss"], "settings.loss", minimum=0.0) if "loss" in f else 0.0
    if loss >= 1.0:
        raise r.fail(f["loss"], f"settings.loss must be below 1, got {loss!r}")
    return Settings(loss, r.flag(f["relay"], "settings.relay") if "relay" in f else True,
                    r.text(f["radio"], "settings.radio", ("ble", "disc")) if "radio" in f else "ble",
                    r.flag(f["secure"], "settings.secure") if "secure" in f else True,
                    r.number(f["follow_distance"], "settings.follow_distance", above=0.0)
                    if "follow_distance" in f else None,
                    r.number(f["power_on_spread"], "settings.power_on_spread", minimum=0.0)
                    if "power_on_spread" in f else None)


def _team(r: Reader, node) -> dict[str, RobotSpec]:
    from rescuemesh.robot import robot_address

    team = {}
    for name, (key_node, value_node) in r.mapping(node, "team").items():
        try:
            robot_address(name)
        except ValueError as error:
            raise r.fail(key_node, str(error)) from None
        f = r.keys(value_node, f"team.{name}", {"model": "turtlebot2 or quadrotor", "start": "[X, Y, YAW]",
                                                  "base": "[X, Y, YAW]", "rank": "peer, team_lead or operator"}) \
            if value_node.tag != "tag:yaml.org,2002:null" else {}
        team[name] = RobotSpec(
            name,
            RobotModel(r.text(f["model"], f"team.{name}.model", tuple(m.value for m in RobotModel)))
            if "model" in f else RobotModel.TURTLEBOT2,
            r.point(f["start"], f"team.{name}.start", yaw=True) if "start" in f else None,
            r.point(f["base"], f"team.{name}.base", yaw=True) if "base" in f else None,
            Rank[r.text(f["rank"], f"team.{name}.rank", ("peer", "team_lead", "operator")).upper()]
            if "rank" in f else Rank.PEER)
    if len(team) < 2:
        raise r.fail(node, "team: a mission needs at least two robots")
    return team


def _robot(r: Reader, node, what: str, names: set[str]) -> str:
    name = r.text(node, what)
    if name not in names:
        raise r.fail(node, f"{what}: unknown robot {name!r}; the team is {', '.join(sorted(names))}")
    return name


def read_results(r: Reader, node, what: str) -> frozenset[ResultCode]:
    """One result or a list of them (any of which will do)."""
    import yaml

    items = r.sequence(node, what) if isinstance(node, yaml.SequenceNode) else [node]
    return frozenset(_result(r, item, what) for item in items)


def _result(r: Reader, node, what: str) -> ResultCode:
    text = r.text(node, what).lower()
    if text not in _RESULTS:
        raise r.fail(node, f"{what} must be one of {', '.join(_RESULTS)}, got {text!r}")
    return _RESULTS[text]


_COMMAND_KEYS = {"type": "a command", "pose": "goto: [X, Y, YAW]", "radius": "move_around: m",
                 "spot": "show_scan/show_cam: [X, Y]", "count": "show_scan/show_cam: how many",
                 "period": "show_scan/show_cam: s between them", "target": "forward_msg: the robot it goes to",
                 "command": "forward_msg: the command to forward"}
_NEEDS = {CommandType.GOTO: ("pose",), CommandType.MOVE_AROUND: ("radius",), CommandType.SHOW_SCAN: ("spot",),
          CommandType.SHOW_CAM: ("spot",), CommandType.FORWARD_MSG: ("target", "command")}


def _command(r: Reader, node, what: str, names: set[str], *, nested: bool = False) -> CommandSpec:
    f = r.keys(node, what, _COMMAND_KEYS, required=("type",))
    kind = CommandType(r.text(f["type"], f"{what}.type", tuple(c.value for c in CommandType)))
    if nested and kind is CommandType.FORWARD_MSG:
        raise r.fail(f["type"], f"{what}: a forward_msg cannot forward another forward_msg")
    needs = _NEEDS.get(kind, ())
    for key in needs:
        if key not in f:
            raise r.fail(node, f"{what}: {kind.value} needs {key!r} ({_COMMAND_KEYS[key]})")
    for key in f:
        if key != "type" and key not in needs and not (key in ("count", "period") and "spot" in needs):
            raise r.fail(f[key], f"{what}: {key!r} does not apply to {kind.value}")
    return CommandSpec(
        kind,
        pose=r.point(f["pose"], f"{what}.pose", yaw=True) if "pose" in f else None,
        radius=r.number(f["radius"], f"{what}.radius", above=0.0) if "radius" in f else None,
        spot=r.point(f["spot"], f"{what}.spot") if "spot" in f else None,
        count=r.whole(f["count"], f"{what}.count", minimum=1, maximum=255) if "count" in f else 1,
        period=r.number(f["period"], f"{what}.period", above=0.0) if "period" in f else 1.0,
        target=_robot(r, f["target"], f"{what}.target", names) if "target" in f else None,
        inner=_command(r, f["command"], f"{what}.command", names, nested=True) if "command" in f else None)


_STEP_KEYS = {"name": "a name other steps and criteria use", "at": "simulated time in s",
              "on": "an event (docs/missions.md)", "after": "s to wait after the event",
              "after_step": "a step that must have finished before the trigger is checked",
              "command": "{from, to, type, ...}", "drive": "{robot, to: [X, Y, YAW]}",
              "outage": "{robot, seconds}", "wait": "s", "end": "true: the mission ends",
              "not_before": "simulated s before which the trigger is not checked",
              "settle": "[ROBOT, ...]: until they are still",
              "attempts": "a command: copies sent at most (default 3)",
              "finish": "a command: `answered` (finished at its first answer)",
              "at_latest": "s: the step starts then at the latest", "data_wait": "s to wait for data (default 5)"}
_ACTIONS = ("command", "drive", "outage", "wait", "end", "settle")


def _steps(r: Reader, node, names: set[str]) -> tuple[Step, ...]:
    steps: list[Step] = []
    for i, item in enumerate(r.sequence(node, "steps")):
        f = r.keys(item, f"step {i + 1}", _STEP_KEYS)
        name = r.text(f["name"], f"step {i + 1}.name") if "name" in f else f"step_{i + 1}"
        if any(s.name == name for s in steps):
            raise r.fail(item, f"step name {name!r} is used twice")
        what = f"step {name!r}"
        actions = [a for a in _ACTIONS if a in f]
        if len(actions) != 1:
            raise r.fail(item, f"{what} needs exactly one action of: {', '.join(_ACTIONS)}")
        if ("at" in f) == ("on" in f):
            raise r.fail(item, f"{what} needs exactly one of `at` (a time) or `on` (an event)")
        trigger = At(r.number(f["at"], f"{what}.at", minimum=0.0)) if "at" in f else _trigger(r, f["on"], what, names)
        after = r.number(f["after"], f"{what}.after", minimum=0.0) if "after" in f else 0.0
        armed_by = r.text(f["after_step"], f"{what}.after_step") if "after_step" in f else None
        not_before = r.number(f["not_before"], f"{what}.not_before", minimum=0.0) if "not_before" in f else 0.0
        action = _action(r, actions[0], f[actions[0]], what, names)
        extra = _step_extras(r, f, what, action)
        steps.append(Step(name, trigger, after, action, armed_by, not_before, **extra))
    return tuple(steps)


def _action(r: Reader, kind: str, node, what: str, names: set[str]) -> Action:
    if kind == "wait":
        return Wait(r.number(node, f"{what}.wait", minimum=0.0))
    if kind == "end":
        if not r.flag(node, f"{what}.end"):
            raise r.fail(node, f"{what}: an end step is `end: true`")
        return EndMission()
    if kind == "command":
        f = r.keys(node, f"{what}.command", dict(_COMMAND_KEYS, **{"from": "the sender", "to": "the receiver"}),
                   required=("from", "to", "type"))
        sender, receiver = _robot(r, f.pop("from"), f"{what}.from", names), _robot(r, f.pop("to"), f"{what}.to", names)
        if sender == receiver:
            raise r.fail(node, f"{what}: a robot does not command itself")
        # the rest is the command: re-read it from the node without from/to
        command = _command_from_fields(r, node, f, f"{what}.command", names)
        return SendCommand(sender, receiver, command)
    if kind == "drive":
        return _drive(r, node, what, names)
    if kind == "settle":
        return Settle(tuple(_robot(r, item, f"{what}.settle", names) for item in r.sequence(node, f"{what}.settle")))
    f = r.keys(node, f"{what}.outage", {"robot": "whose radio", "seconds": "how long"}, required=("robot", "seconds"))
    return Outage(_robot(r, f["robot"], f"{what}.outage.robot", names),
                  r.number(f["seconds"], f"{what}.outage.seconds", above=0.0))


def _command_from_fields(r: Reader, node, fields: dict, what: str, names: set[str]) -> CommandSpec:
    import yaml

    kept = [(k, v) for k, v in node.value if k.value in fields]
    return _command(r, yaml.MappingNode(node.tag, kept, node.start_mark, node.end_mark), what, names)


_TRIGGER_KEYS = {"step": "a step's name", "result": "a result (accepted, in_progress, done, failed, ...)",
                 "robot": "a robot", "enters": "a region of the map", "within": "m", "of": "a robot or [X, Y]",
                 "loses": "a robot it stops hearing", "hears": "a robot it hears (again)",
                 "started": "true: when the step starts", "given_up": "true, with step: its command was given up",
                 "at_receiver": "true: `result` as the receiver ended the command",
                 "speed_at_least": "m/s: the robot moves at least this fast", "settled": "true: the robot is still",
                 "knows": "a robot whose Heartbeat it has had", "moving": "m/s, at least",
                 "landed": "true: a quadrotor has landed, rotors off", "team_up": "true: the whole team is on",
                 "answered": "true, with step: its command had an answer"}


def _near(r: Reader, f: dict, what: str, names: set[str]):
    of = f["of"]
    if isinstance(of, __import__("yaml").SequenceNode):
        return None, r.point(of, f"{what}.of")
    return _robot(r, of, f"{what}.of", names), None


def _trigger(r: Reader, node, what: str, names: set[str]) -> Trigger:
    f = r.keys(node, f"{what}.on", _TRIGGER_KEYS)
    more = _more_trigger(r, node, f, what, names)
    if more is not None:
        return more
    if "step" in f:
        return _step_event(r, node, f, what)
    if "robot" not in f:
        raise r.fail(node, f"{what}.on needs `step` or `robot`")
    robot = _robot(r, f["robot"], f"{what}.on.robot", names)
    if "speed_at_least" in f or "settled" in f:
        if len(f) != 2:
            raise r.fail(node, f"{what}.on: speed_at_least and settled stand alone beside `robot`")
        if "settled" in f:
            if not r.flag(f["settled"], f"{what}.on.settled"):
                raise r.fail(f["settled"], f"{what}.on: settled is `settled: true`")
            return OnSettled(robot)
        return OnSpeed(robot, r.number(f["speed_at_least"], f"{what}.on.speed_at_least", minimum=0.0))
    forms = [k for k in ("enters", "within", "loses", "hears") if k in f]
    if len(forms) != 1:
        raise r.fail(node, f"{what}.on: a robot event takes one of enters, within (with of), loses, hears")
    if forms[0] == "enters":
        return OnRegion(robot, r.text(f["enters"], f"{what}.on.enters"))
    if forms[0] == "within":
        if "of" not in f:
            raise r.fail(node, f"{what}.on: within needs `of` (a robot or [X, Y])")
        other, point = _near(r, f, f"{what}.on", names)
        return OnNear(robot, r.number(f["within"], f"{what}.on.within", above=0.0), other, point)
    peer = _robot(r, f[forms[0]], f"{what}.on.{forms[0]}", names)
    return OnLink(robot, peer, lost=forms[0] == "loses")


def _step_event(r: Reader, node, f: dict, what: str) -> OnStep:
    """`{step: S}`, `{step: S, result: X or [X, ...] [, at_receiver: true]}`, `{step: S, started: true}`,
    (`{step: S, given_up: true}` is read by mission_spec_more)."""
    step = r.text(f["step"], f"{what}.on.step")
    extra = set(f) - {"step"}
    if extra - {"result", "at_receiver", "started"}:
        raise r.fail(node, f"{what}.on: a step event takes `result` (and `at_receiver`), `started` or `given_up`")
    if "started" in f:  # (`given_up` is read by mission_spec_more._more_trigger, before this)
        if extra != {"started"} or not r.flag(f["started"], f"{what}.on.started"):
            raise r.fail(node, f"{what}.on: `started: true` stands alone beside `step`")
        return OnStep(step, None, started=True)
    if "at_receiver" in f and "result" not in f:
        raise r.fail(f["at_receiver"], f"{what}.on: at_receiver goes with `result`")
    if "result" not in f:
        return OnStep(step, None)
    results = read_results(r, f["result"], f"{what}.on.result")
    at_receiver = r.flag(f["at_receiver"], f"{what}.on.at_receiver") if "at_receiver" in f else False
    return OnStep(step, next(iter(results)) if len(results) == 1 else results, at_receiver=at_receiver)


_CRITERION_KEYS = {"step": "a command step", "result": "its result", "within": "s, or m with `of`",
                   "data": "how many data items it must bring back", "robot": "a robot",
                   "ends_in": "a region", "of": "a robot or [X, Y]", "no_collision": "true",
                   "metric": "a metric's name", "min": "lowest allowed", "max": "highest allowed",
                   "at_receiver": "true: the result the receiver ended the command with",
                   "finished": "true: the step finished", "decoded": "how many data items must decode",
                   "lands_on": "a robot whose top plate it ends on", "relative_to": "a metric the bounds are shares of",
                   "equals": "the value a metric must have", "reason": "with result: the reason it came with"}


def _criterion(r: Reader, node, names: set[str], steps: set[str], metrics: set[str]) -> Criterion:
    f = r.keys(node, "a criterion", _CRITERION_KEYS)
    if "no_collision" in f:
        if set(f) != {"no_collision"} or not r.flag(f["no_collision"], "no_collision"):
            raise r.fail(node, "no_collision stands alone, as `no_collision: true`")
        return NoCollision()
    if "metric" in f:
        metric = r.text(f["metric"], "metric")
        if metric not in metrics:
            raise r.fail(f["metric"], f"unknown metric {metric!r}; the mission's metrics: {', '.join(sorted(metrics))}")
        if "equals" in f:
            if set(f) != {"metric", "equals"}:
                raise r.fail(node, "a metric criterion takes `equals` alone, or `min`, `max` or both")
            return MetricBound(metric, None, None, None, (r.scalar(f["equals"]),))
        if set(f) - {"metric", "min", "max", "relative_to"} or not ({"min", "max"} & set(f)):
            raise r.fail(node, "a metric criterion takes `min`, `max` or both (and optionally `relative_to`), "
                               "or `equals`")
        relative = r.text(f["relative_to"], "relative_to") if "relative_to" in f else None
        if relative is not None and relative not in metrics:
            raise r.fail(f["relative_to"], f"unknown metric {relative!r}; the mission's metrics: "
                                           f"{', '.join(sorted(metrics))}")
        return MetricBound(metric, r.number(f["min"], "min") if "min" in f else None,
                           r.number(f["max"], "max") if "max" in f else None, relative)
    if "step" in f:
        step = r.text(f["step"], "step")
        if step not in steps:
            raise r.fail(f["step"], f"unknown step {step!r}")
        if "data" in f:
            return StepData(step, r.whole(f["data"], "data", minimum=1))
        if "decoded" in f:
            return StepDecoded(step, r.whole(f["decoded"], "decoded", minimum=1))
        if "finished" in f:
            if set(f) != {"step", "finished"} or not r.flag(f["finished"], "finished"):
                raise r.fail(node, "a finished criterion is `{step: S, finished: true}`")
            return StepFinished(step)
        if "result" not in f:
            raise r.fail(node, "a step criterion takes `result` (and optionally `within` s) or `data`")
        if "reason" in f:
            if set(f) != {"step", "result", "reason"}:
                raise r.fail(node, "a reason criterion is `{step: S, result: X, reason: Y}`")
            text = r.text(f["reason"], "reason").upper()
            if text not in Reason.__members__:
                raise r.fail(f["reason"], f"reason must be one of {', '.join(m.lower() for m in Reason.__members__)}")
            return StepAnswer(step, _result(r, f["result"], "result"), Reason[text])
        return StepResult(step, _result(r, f["result"], "result"),
                          r.number(f["within"], "within", above=0.0) if "within" in f else None,
                          r.flag(f["at_receiver"], "at_receiver") if "at_receiver" in f else False)
    if "robot" in f:
        robot = _robot(r, f["robot"], "robot", names)
        if "ends_in" in f:
            return EndsIn(robot, r.text(f["ends_in"], "ends_in"))
        if "lands_on" in f:
            return LandsOn(robot, _robot(r, f["lands_on"], "lands_on", names))
        if "within" in f and "of" in f:
            other, point = _near(r, f, "criterion", names)
            return EndsNear(robot, r.number(f["within"], "within", above=0.0), other, point)
        raise r.fail(node, "a robot criterion takes `ends_in` or `within` with `of`")
    raise r.fail(node, "a criterion names a step, a robot, a metric or no_collision")


def _metric(r: Reader, node, names: set[str], steps: set[str], metrics: frozenset[str] | set[str] = frozenset()) -> Metric:
    from rescuemesh.experiments.measures import MEASURES, read_measure

    f = r.keys(node, "a metric", {"name": "its name in result.json", "distance": "[ROBOT, ROBOT] at the end",
                                  "time_to": "{step, result}: s from the step's start",
                                  "path_length": "a robot: m driven", **MEASURES, **TIMED_METRIC_KEYS},
               required=("name",))
    name = r.text(f["name"], "metric name")
    if _measured_over_events(f):  # the measures of experiments/measures.py
        return read_measure(r, node, f, name, names, steps)
    timed = read_timed_metric(r, node, f, name, names, steps, metrics)
    if timed is not None:
        if {"distance", "time_to", "path_length"} & set(f):
            raise r.fail(node, f"metric {name!r}: one measure per metric")
        return timed
    stray = [k for k in f if k in TIMED_METRIC_MODIFIERS]
    if stray:
        raise r.fail(node, f"metric {name!r}: {stray[0]!r} does not apply to distance, time_to or path_length")
    if "distance" in f:
        items = r.sequence(f["distance"], "distance")
        if len(items) != 2:
            raise r.fail(f["distance"], "distance takes two robots")
        return Distance(name, (_robot(r, items[0], "distance", names), _robot(r, items[1], "distance", names)))
    if "time_to" in f:
        g = r.keys(f["time_to"], "time_to", {"step": "a step", "result": "a result"}, required=("step", "result"))
        step = r.text(g["step"], "time_to.step")
        if step not in steps:
            raise r.fail(g["step"], f"unknown step {step!r}")
        return TimeTo(name, step, _result(r, g["result"], "time_to.result"))
    if "path_length" in f:
        return PathLength(name, _robot(r, f["path_length"], "path_length", names))
    measures = sorted(set(k for k in TIMED_METRIC_KEYS if k not in TIMED_METRIC_MODIFIERS) | set(MEASURES))
    raise r.fail(node, f"a metric is one of distance, time_to, path_length, {', '.join(measures)}")


#: Moments that experiments/mission_measures.py reads from a step's record; any other `time_of` event (a
#: robot's, an answer, a give-up) is watched every control step by experiments/measures.py.
_STEP_MOMENT_KEYS = frozenset({"step", "result", "started", "at_receiver"})


def _measured_over_events(f: dict) -> bool:
    """Whether metric fields `f` are one of experiments/measures.py's: its own keys, a `time_of` of an event
    other than a step's moment, or a `following_error` over a chain (`{robots: [...], from, to}`)."""
    from rescuemesh.experiments.measures import MEASURES

    if "time_of" in f:
        when = f["time_of"]
        return not (isinstance(when, yaml.MappingNode) and
                    {key.value for key, _ in when.value} <= _STEP_MOMENT_KEYS)
    if "following_error" in f:
        return isinstance(f["following_error"], yaml.MappingNode)
    return bool(set(f) & (set(MEASURES) - set(TIMED_METRIC_KEYS)))


# the keys added for the built-in scenarios (issue 18) are read in mission_spec_more.py
from rescuemesh.experiments.mission_spec_more import (  # noqa: E402  (it reads into the types above)
    _drive, _group_parts, _more_trigger, _step_extras)
