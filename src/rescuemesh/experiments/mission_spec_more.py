"""Mission-file keys added so that the built-in scenarios can be written as missions (issue 18):
a step's attempts, at_latest, data_wait and finish; drives by an offset or along a route; the
triggers knows, moving, landed, team_up, given_up and answered; criteria naming a group metric's part.

Owns: reading those keys (errors name the file and the line). Must not know: how a mission runs.
The typed values they read into live in mission_spec.py beside the others.
"""

from __future__ import annotations

from rescuemesh.experiments.mission_spec import (CommandType, Drive, OnAnswered, OnGivenUp, OnKnows, OnLanded,
                                                 OnMoving, OnTeamUp, SendCommand, Trigger, _robot)
from rescuemesh.experiments.yamlread import Reader


def _step_extras(r: Reader, f: dict, what: str, action) -> dict:
    """A step's optional `attempts`, `at_latest` and `data_wait`, checked against its action."""
    extra = {}
    if "attempts" in f:
        if not isinstance(action, SendCommand):
            raise r.fail(f["attempts"], f"{what}: `attempts` applies to a command step")
        extra["attempts"] = r.whole(f["attempts"], f"{what}.attempts", minimum=1, maximum=100)
    if "at_latest" in f:
        extra["at_latest"] = r.number(f["at_latest"], f"{what}.at_latest", minimum=0.0)
    if "data_wait" in f:
        inner = action.command.inner if isinstance(action, SendCommand) and action.command.inner else \
            (action.command if isinstance(action, SendCommand) else None)
        if inner is None or inner.type not in (CommandType.SHOW_SCAN, CommandType.SHOW_CAM):
            raise r.fail(f["data_wait"], f"{what}: `data_wait` applies to a show_scan or show_cam command")
        extra["data_wait_s"] = r.number(f["data_wait"], f"{what}.data_wait", minimum=0.0)
    if "finish" in f:
        if not isinstance(action, SendCommand):
            raise r.fail(f["finish"], f"{what}: `finish` applies to a command step")
        r.text(f["finish"], f"{what}.finish", ("answered",))
        extra["finish_on_answer"] = True
    return extra


def _drive(r: Reader, node, what: str, names: set[str]) -> Drive:
    f = r.keys(node, f"{what}.drive", {"robot": "who drives", "to": "[X, Y, YAW]",
                                       "route": "[[X, Y, YAW], ...]: one point after another",
                                       "by": "[DX, DY]: m from where it is, in the map frame"},
               required=("robot",))
    robot = _robot(r, f["robot"], f"{what}.drive.robot", names)
    forms = [k for k in ("to", "route", "by") if k in f]
    if len(forms) != 1:
        raise r.fail(node, f"{what}.drive takes one of `to`, `route` or `by`")
    if "to" in f:
        return Drive(robot, r.point(f["to"], f"{what}.drive.to", yaw=True))
    if "by" in f:
        return Drive(robot, None, by=r.point(f["by"], f"{what}.drive.by"))
    route = tuple(r.point(item, f"{what}.drive.route", yaw=True) for item in r.sequence(f["route"], f"{what}.drive.route"))
    return Drive(robot, None, route=route)


def _more_trigger(r: Reader, node, f: dict, what: str, names: set[str]) -> Trigger | None:
    """The triggers added for the built-ins (knows, moving, landed, team_up, given_up), or None."""
    if "team_up" in f:
        if set(f) != {"team_up"} or not r.flag(f["team_up"], f"{what}.on.team_up"):
            raise r.fail(node, f"{what}.on: team_up stands alone, as `team_up: true`")
        return OnTeamUp()
    if "answered" in f:
        if set(f) != {"step", "answered"} or not r.flag(f["answered"], f"{what}.on.answered"):
            raise r.fail(node, f"{what}.on: answered is `{{step: S, answered: true}}`")
        return OnAnswered(r.text(f["step"], f"{what}.on.step"))
    if "given_up" in f:
        if set(f) != {"step", "given_up"} or not r.flag(f["given_up"], f"{what}.on.given_up"):
            raise r.fail(node, f"{what}.on: given_up is `{{step: S, given_up: true}}`")
        return OnGivenUp(r.text(f["step"], f"{what}.on.step"))
    forms = [k for k in ("knows", "moving", "landed") if k in f]
    if not forms:
        return None
    if set(f) != {"robot", forms[0]}:
        raise r.fail(node, f"{what}.on: `{forms[0]}` takes `robot` and nothing else")
    robot = _robot(r, f["robot"], f"{what}.on.robot", names)
    if forms[0] == "knows":
        return OnKnows(robot, _robot(r, f["knows"], f"{what}.on.knows", names))
    if forms[0] == "moving":
        return OnMoving(robot, r.number(f["moving"], f"{what}.on.moving", above=0.0))
    if not r.flag(f["landed"], f"{what}.on.landed"):
        raise r.fail(f["landed"], f"{what}.on: landed takes `true`")
    return OnLanded(robot)


def _group_parts(metrics) -> set[str]:
    """GROUP.PART names of the parts of group metrics (a criterion may name one)."""
    from rescuemesh.experiments.measures import Measure

    return {f"{m.name}.{part.name}" for m in metrics if isinstance(m, Measure) and m.kind == "group" for part in m.arg}
