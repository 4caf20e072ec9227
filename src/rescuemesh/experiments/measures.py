"""The larger metric vocabulary of mission files (docs/missions.md, "More metrics"): times of events
and steps, what a command's copies and Confirm carried, data brought back, frames carried by the
mesh, landings, displacements, chain gaps and following quality, settings and protocol constants.

Owns: Measure (a named metric of one kind), reading it from YAML and computing its value from a
finished run. Must not know: how a mission is read or stepped (it is given the MissionScenario).
Every value comes from typed records (results, reasons, data records, counters, poses).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from rescuemesh.protocol import Reason, ResultCode
from rescuemesh.protocol.messages import Capability

#: A robot counts as stopped below this speed (m/s), as the disconnect scenario's HALTED_SPEED.
STOPPED_SPEED = 0.02

#: Metric kinds (the key naming the kind) -> what they take; docs/missions.md lists each.
MEASURES = {
    "time_of": "an event, as a step's `on:`: simulated s when it first held",
    "started": "a step: simulated s it started", "finished": "a step: simulated s it finished",
    "duration": "a step: s from its start to its finish",
    "confirm_hops": "a command step: hops its answered copy's Confirm took",
    "sends": "a command step: radio sends of its answered copy", "attempts": "a command step: copies sent",
    "frames_received": "{robot, min_hops}: frames the robot received over at least min_hops hops",
    "frames_relayed": "a robot: frames it relayed", "setting": "loss, relay, radio or secure",
    "target_of": "a step: its drive's goal or its command's pose or spot, [X, Y]",
    "region_of_target": "a step: the map region of target_of",
    "data": "a command step: data items back", "data_bytes": "a command step: each item's size",
    "data_hops": "a command step: each item's hops", "first_data_after": "a command step: s from its start",
    "data_latency": "a command step: each item's time on the way, s",
    "landing_offset": "[FLYER, CARRIER]: m from the flyer's centre to the carrier's top plate's",
    "landed_on": "a flyer: the robot it rests on, or null",
    "displacement": "{robot, since: STEP}: m from where it was at the step's start to its end",
    "capabilities": "[ROBOT, PEER]: what ROBOT heard PEER announce", "group": "a list of metrics, as one",
    "config": "link_loss_timeout_s, reconnect_window_s, heartbeat_period_s or follow_distance_m",
    "stopped_after": "{robot, step}: s from the step's start until the robot was still",
    "stopped_at": "{robot, step}: [X, Y] where it was then",
    "first_event": "{robot, kind}: simulated s of the robot's first brain event of that kind",
    "outage_outcome": "an outage step: resume, fail or either (the link-loss rule)",
    "command_failed": "{step, reason}: its command ended FAILED with that reason at its sender",
    "behaviour_failed": "{robot, behaviour, reason}: the robot's behaviour ended FAILED with that reason",
    "team_size": "true: robots in the team", "ranks": "true: each robot's rank",
    "answer": "a command step: [RESULT, REASON] of its answered copy, now",
    "gaps": "{robots: [...], stat: min, mean, max or all}: final distances along the chain",
    "following": "{robots: [...], from: STEP, to: STEP}: mean distance along the chain in the window",
    "following_error": "{robots: [...], from: STEP, to: STEP}: distance minus the following distance",
}
_SETTINGS = ("loss", "relay", "radio", "secure")
_CONFIG = ("link_loss_timeout_s", "reconnect_window_s", "heartbeat_period_s", "follow_distance_m")
_STATS = ("min", "mean", "max", "all")


@dataclass(frozen=True)
class Measure:
    """A metric of the larger vocabulary: its name, its kind (a MEASURES key) and what it takes."""

    name: str
    kind: str
    arg: Any


def read_measure(r, node, f: dict, name: str, names: set[str], steps: set[str]) -> Measure:
    """Read a metric mapping whose kind is a MEASURES key; errors name the line."""
    from rescuemesh.experiments.mission_spec import OnGivenUp, OnStep, _robot, _trigger

    kinds = [k for k in f if k in MEASURES]
    if len(kinds) != 1 or set(f) - {"name", kinds[0]}:
        raise r.fail(node, f"metric {name!r}: one kind per metric, beside `name`")
    kind, value = kinds[0], f[kinds[0]]
    what = f"metric {name!r}.{kind}"

    def step(node_) -> str:
        text = r.text(node_, what)
        if text not in steps:
            raise r.fail(node_, f"{what}: unknown step {text!r}")
        return text

    def fields(allowed: dict, required: tuple) -> dict:
        return r.keys(value, what, allowed, required=required)

    if kind == "time_of":
        trigger = _trigger(r, value, what, names)
        if isinstance(trigger, (OnStep, OnGivenUp)) and trigger.step not in steps:
            raise r.fail(value, f"{what}: unknown step {trigger.step!r}")
        return Measure(name, kind, trigger)
    if kind in ("started", "finished", "duration", "confirm_hops", "sends", "attempts", "target_of",
                "region_of_target", "data", "data_bytes", "data_hops", "first_data_after", "data_latency",
                "outage_outcome", "answer"):
        return Measure(name, kind, step(value))
    if kind in ("frames_relayed", "landed_on"):
        return Measure(name, kind, _robot(r, value, what, names))
    if kind in ("landing_offset", "capabilities"):
        items = r.sequence(value, what)
        if len(items) != 2:
            raise r.fail(value, f"{what} takes two robots")
        return Measure(name, kind, tuple(_robot(r, item, what, names) for item in items))
    if kind == "frames_received":
        g = fields({"robot": "a robot", "min_hops": "hops, at least (default 1)"}, ("robot",))
        return Measure(name, kind, (_robot(r, g["robot"], what, names),
                                    r.whole(g["min_hops"], f"{what}.min_hops", minimum=1) if "min_hops" in g else 1))
    if kind == "setting":
        return Measure(name, kind, r.text(value, what, _SETTINGS))
    if kind == "config":
        return Measure(name, kind, r.text(value, what, _CONFIG))
    if kind in ("team_size", "ranks"):
        if not r.flag(value, what):
            raise r.fail(value, f"{what} takes `true`")
        return Measure(name, kind, True)
    if kind == "group":
        from rescuemesh.experiments.mission_spec import _metric

        parts = tuple(_metric(r, item, names, steps) for item in r.sequence(value, what))
        if len({p.name for p in parts}) != len(parts):
            raise r.fail(value, f"{what}: a name is used twice")
        return Measure(name, kind, parts)
    if kind in ("displacement", "stopped_after", "stopped_at"):
        key = "since" if kind == "displacement" else "step"
        g = fields({"robot": "a robot", key: "a step"}, ("robot", key))
        return Measure(name, kind, (_robot(r, g["robot"], what, names), step(g[key])))
    if kind == "first_event":
        g = fields({"robot": "a robot", "kind": "a brain event's kind (link_lost, link_resumed, ...)"},
                   ("robot", "kind"))
        return Measure(name, kind, (_robot(r, g["robot"], what, names), r.text(g["kind"], f"{what}.kind")))
    if kind in ("command_failed", "behaviour_failed"):
        allowed = {"reason": "a Reason (link_lost, no_path, ...)"}
        allowed.update({"step": "a command step"} if kind == "command_failed" else
                       {"robot": "a robot", "behaviour": "follow, navigate, ..."})
        g = fields(allowed, tuple(allowed))
        reason_text = r.text(g["reason"], f"{what}.reason").upper()
        if reason_text not in Reason.__members__:
            raise r.fail(g["reason"], f"{what}.reason must be one of "
                                      f"{', '.join(m.lower() for m in Reason.__members__)}")
        reason = Reason[reason_text]
        if kind == "command_failed":
            return Measure(name, kind, (step(g["step"]), reason))
        return Measure(name, kind, (_robot(r, g["robot"], what, names), r.text(g["behaviour"], what), reason))
    if kind == "gaps":
        g = fields({"robots": "the chain, front first", "stat": "min, mean, max or all"}, ("robots",))
        chain = _chain(r, g["robots"], what, names)
        return Measure(name, kind, (chain, r.text(g["stat"], f"{what}.stat", _STATS) if "stat" in g else "all"))
    g = fields({"robots": "the chain, front first", "from": "a step: the window opens as it finishes",
                "to": "a step: the window closes as it finishes (or at the end)"}, ("robots", "from", "to"))
    return Measure(name, kind, (_chain(r, g["robots"], what, names), step(g["from"]), step(g["to"])))


def _chain(r, node, what: str, names: set[str]) -> tuple[str, ...]:
    from rescuemesh.experiments.mission_spec import _robot

    chain = tuple(_robot(r, item, what, names) for item in r.sequence(node, what))
    if len(chain) < 2:
        raise r.fail(node, f"{what}: a chain has at least two robots")
    return chain


# --- values -----------------------------------------------------------------------------------------

def time_of_events(measures) -> list[Measure]:
    """Every time_of measure, groups opened: the mission watches their events each tick."""
    out = []
    for m in measures:
        if isinstance(m, Measure) and m.kind == "group":
            out += time_of_events(m.arg)
        elif isinstance(m, Measure) and m.kind == "time_of":
            out.append(m)
    return out


def _r3(value):
    return None if value is None else round(value, 3)


def value_of(m: Measure, sc, rt) -> Any:
    """The value of measure `m` at the end of the run of MissionScenario `sc` on runtime `rt`."""
    kind, arg = m.kind, m.arg
    if kind == "group":
        return {part.name: sc._metric_value(part, rt) for part in arg}
    if kind == "time_of":
        return sc.event_times.get(m.name)
    if kind == "setting":
        value = getattr(sc.options, arg)
        return value.value if hasattr(value, "value") else value
    if kind == "config":
        mesh, brain = rt.config.mesh, rt.config.brain
        return {"link_loss_timeout_s": (mesh.lost_after_missed + 0.5) * mesh.heartbeat_period_s,
                "reconnect_window_s": brain.reconnect_window_s, "heartbeat_period_s": mesh.heartbeat_period_s,
                "follow_distance_m": brain.follow_distance_m}[arg]
    if kind == "team_size":
        return len(sc.robots)
    if kind == "ranks":
        return {name: robot.rank.name for name, robot in sc.mission.team.items()}
    if kind == "frames_relayed":
        return rt.stacks[arg].node.stats.relayed
    if kind == "frames_received":
        robot, min_hops = arg
        return sum(n for h, n in rt.stacks[robot].hops_histogram.items() if h >= min_hops)
    if kind == "landing_offset":
        return round(rt.world.top_offset(*arg), 4)
    if kind == "landed_on":
        return rt.world.bodies[arg].landed_on()
    if kind == "capabilities":
        robot, peer = arg
        from rescuemesh.robot import robot_address

        caps = rt.brain(robot).capabilities_of(robot_address(peer))
        return None if caps is None else [c.name for c in Capability if c.value and c in caps]
    if kind in ("displacement", "stopped_after", "stopped_at"):
        robot, step = arg
        state = sc.state(step)
        if kind == "displacement":
            start = state.poses_at_start.get(robot) if state.poses_at_start else None
            return None if start is None else _r3(start.distance_to(rt.world.bodies[robot].pose()))
        if state.started_s is None:
            return None
        sample = next((s for s in rt.trajectories[robot] if s.time_s >= state.started_s and s.speed < STOPPED_SPEED),
                      None)
        if sample is None:
            return None
        if kind == "stopped_after":
            return round(sample.time_s - state.started_s, 3)
        return [round(sample.pose.x, 3), round(sample.pose.y, 3)]
    if kind == "first_event":
        robot, event_kind = arg
        return next((e.time_s for e in rt.brain(robot).log if e.kind == event_kind), None)  # typed-events
    if kind == "behaviour_failed":
        robot, behaviour, reason = arg
        return any(f.name == behaviour and f.result == ResultCode.FAILED and f.code == reason
                   for f in rt.brain(robot).finished)
    if kind in ("gaps", "following", "following_error"):
        return _chain_value(kind, arg, sc, rt)
    state = sc.state(arg if isinstance(arg, str) else arg[0])
    return _step_value(kind, arg, state, sc, rt)


def _step_value(kind: str, arg, state, sc, rt) -> Any:
    if kind == "started":
        return state.started_s
    if kind == "finished":
        return state.finished_s
    if kind == "duration":
        return None if state.finished_s is None else round(state.finished_s - state.started_s, 3)
    if kind in ("target_of", "region_of_target"):
        point = sc.aim_of(state)
        if kind == "target_of" or point is None:
            return point
        return sc.map.region_of(point[0], point[1])
    if kind == "outage_outcome":
        window = rt.config.brain.reconnect_window_s
        mesh = rt.config.mesh
        seconds = state.step.action.seconds
        if seconds <= window:
            return "resume"
        timeout = (mesh.lost_after_missed + 0.5) * mesh.heartbeat_period_s
        return "fail" if seconds >= timeout + window + mesh.heartbeat_period_s else "either"
    request = state.request
    if kind == "attempts":
        return 0 if request is None else len(request.seqs)
    if kind == "command_failed":
        return request is not None and any(
            request.brain.outgoing[s].result == ResultCode.FAILED and request.brain.outgoing[s].reason == arg[1]
            for s in request.seqs)
    answered = None if request is None else request.confirmed()
    if kind == "answer":
        return None if answered is None else [answered.result.name, answered.reason.name]
    if kind == "confirm_hops":
        return None if answered is None else answered.hops
    if kind == "sends":
        return None if answered is None else answered.sends
    items = sc.data_items(state, rt)
    if kind == "data":
        return len(items)
    if kind == "data_bytes":
        return [len(item[4]) for item in items]
    if kind == "data_hops":
        return [item[5] for item in items]
    if kind == "first_data_after":
        return None if not items or state.started_s is None else round(items[0][0] - state.started_s, 3)
    # data_latency: each item's arrival minus when the robot that sent data logged it (in order)
    sender = sc.data_source(state)
    sent = [e.time_s for e in rt.brain(sender).log if e.kind == "data_sent"]  # typed-events
    return [round(item[0] - t, 3) for item, t in zip(items, sent)]


def _chain_value(kind: str, arg, sc, rt) -> Any:
    from rescuemesh.scenarios.base import following_error, mean_distance

    if kind == "gaps":
        chain, stat = arg
        ends = [rt.trajectories[name][-1].pose for name in chain]
        gaps = [ends[k].distance_to(ends[k + 1]) for k in range(len(ends) - 1)]
        if stat == "all":
            return [round(g, 3) for g in gaps]
        return round({"min": min, "max": max, "mean": lambda v: sum(v) / len(v)}[stat](gaps), 3)
    chain, first, last = arg
    t0 = sc.state(first).finished_s
    if t0 is None:
        return None
    t1 = sc.state(last).finished_s or rt.time
    paths = [rt.trajectories[name] for name in chain]
    if kind == "following":
        means = [mean_distance(paths[k], paths[k + 1], t0, t1) for k in range(len(chain) - 1)]
        means = [v for v in means if v == v]
        return round(sum(means) / len(means), 3) if means else None
    set_distance = rt.config.brain.follow_distance_m
    errors = [following_error(paths[k], paths[k + 1], t0, t1, set_distance) for k in range(len(chain) - 1)]
    errors = [e for e in errors if e is not None]
    n = sum(e["samples"] for e in errors)
    if not n:
        return None
    return {"set_distance_m": set_distance,
            "mean_m": round(sum(e["mean_m"] * e["samples"] for e in errors) / n, 3),
            "rms_m": round(math.sqrt(sum(e["rms_m"] ** 2 * e["samples"] for e in errors) / n), 3),
            "max_m": max(e["max_m"] for e in errors), "samples": n, "links": len(errors)}
