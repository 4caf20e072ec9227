"""result.json: what a run did, in a stable schema (see README "Reading the output").

Owns: turning a finished run into a JSON-able dict and writing it. Must not know: plotting.
Same seed, same result except the wall-clock fields (`wall_time_s`, `real_time_factor`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path


def _path_length(samples) -> float:
    return sum(a.pose.distance_to(b.pose) for a, b in zip(samples, samples[1:]))


def build_result(scenario, rt, verdict, wall_time_s: float, map_model) -> dict:
    robots = {}
    for name, samples in rt.trajectories.items():
        end = samples[-1].pose
        robots[name] = {
            "path_length_m": round(_path_length(samples), 3),
            "final_pose": {"x": round(end.x, 3), "y": round(end.y, 3), "yaw": round(end.yaw, 3)},
            "final_region": map_model.region_of(end.x, end.y),
            "collisions": rt.world.collisions.get(name, 0),
            "endpoint": rt.brains[name].endpoint.stats.as_dict(),
        }
    endpoints = [b.endpoint.stats for b in rt.brains.values()]
    link = rt.link.stats
    protocol = {
        "frames_sent": link.frames_sent,
        "frames_delivered": link.frames_delivered,
        "frames_lost": link.frames_lost,
        "frames_out_of_range": link.frames_out_of_range,
        "retries": sum(s.retries for s in endpoints),
        "confirms": sum(s.confirms_sent for s in endpoints),
        "confirms_received": sum(s.confirms_received for s in endpoints),
        "duplicates_suppressed": sum(s.duplicates for s in endpoints),
        "frames_rejected": sum(s.frames_rejected for s in endpoints),
        "delivery_failures": sum(s.delivery_failures for s in endpoints),
        "commands_failed": sum(b.commands_failed for b in rt.brains.values()),
        "bytes_sent": link.bytes_sent,
        "max_frame_bytes": link.max_frame_bytes,
    }
    sim_time = rt.time
    return {
        "scenario": scenario.name,
        "seed": scenario.options.seed,
        "success": verdict.success,
        "criteria": [{"check": text, "ok": ok} for text, ok in verdict.criteria],
        "sim_time_s": round(sim_time, 3),
        "wall_time_s": round(wall_time_s, 3),
        "real_time_factor": round(sim_time / wall_time_s, 2) if wall_time_s > 0 else None,
        "settings": {
            "map": map_model.name,
            "loss": scenario.options.loss,
            "radio_range_m": rt.config.range_m,
            "radio_latency_s": rt.config.latency_s,
            "ack_timeout_s": rt.config.ack_timeout_s,
            "max_sends": rt.config.max_sends,
            "physics_dt_s": rt.config.physics_dt,
            "control_dt_s": rt.config.control_dt,
        },
        "robots": robots,
        "protocol": protocol,
        "metrics": _clean(verdict.metrics),
        "events": [[e.time_s, e.robot, e.kind, e.detail] for b in rt.brains.values() for e in b.log],
    }


def _clean(value):
    """JSON-safe: NaN and inf become None, tuples become lists."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_result(result: dict, path: Path) -> Path:
    result = dict(result, events=sorted(result["events"], key=lambda e: e[0]))
    path.write_text(json.dumps(result, indent=2) + "\n")
    return path
