"""result.json: what a run did, in a stable schema (docs/results.md defines every field).

Owns: turning a finished run into a JSON-able dict and writing it. Must not know: plotting.
Same seed, same result except the wall-clock fields (`wall_time_s`, `real_time_factor`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from rescuemesh.protocol import MessageType, Reason


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
    protocol = protocol_summary(rt)
    network = network_summary(rt)
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
            "radio": rt.config.radio.value,
            "radio_model": rt.channel.settings(),
            "relay": rt.config.relay,
            "security": {
                "authenticated": rt.config.secure,
                "frames": "AES-CCM-128, 4-byte MIC, replay window" if rt.config.secure
                else "INSECURE: CRC-32 only, no authentication, no encryption, no replay protection",
                "team_key": scenario.options.key_source,
            },
            "initial_ttl": rt.config.mesh.initial_ttl,
            "heartbeat_period_s": rt.config.mesh.heartbeat_period_s,
            "link_lost_after_missed_heartbeats": rt.config.mesh.lost_after_missed,
            "reconnect_window_s": rt.config.brain.reconnect_window_s,
            "link_loss_policy": {t.name: rt.config.brain.policy_for(t).value  # the nine commands (types 1..9)
                                 for t in MessageType if 1 <= t.value <= 9},
            "ack_timeout_s": rt.config.ack_timeout_s,
            "max_sends": rt.config.max_sends,
            "physics_dt_s": rt.config.physics_dt,
            "control_dt_s": rt.config.control_dt,
        },
        "robots": robots,
        "protocol": protocol,
        "network": network,
        "metrics": _clean(verdict.metrics),
        "events": [[e.time_s, e.robot, e.kind, e.detail] for b in rt.brains.values() for e in b.log],
    }


def protocol_summary(rt) -> dict:
    """End-to-end protocol figures: frames the endpoints originated (unicast and broadcast apart),
    what the radio did with them at their intended receivers, end-to-end delivery and latency per
    message type, and the commands the missions sent, confirmed, given up and left open
    (docs/results.md defines every field)."""
    from rescuemesh.report.delivery import by_message_type, confirm_latency

    endpoints = [b.endpoint.stats for b in rt.brains.values()]
    medium = rt.medium.stats
    every_command = [c for b in rt.brains.values() for c in b.outgoing.values()]
    commands = [c for c in every_command if not c.automatic]
    automatic = [c for c in every_command if c.automatic]
    confirmed = sum(1 for c in commands if c.confirmed_s is not None)
    records = rt.medium.records or []
    by_type = by_message_type(records, len(rt.brains))
    sends = sum(row.get("sends", 0) for row in by_type.values())
    sends_delivered = sum(row.get("sends_delivered", 0) for row in by_type.values())
    return {
        "frames_sent": sum(s.frames_sent for s in endpoints),
        "unicast_frames_sent": sum(s.frames_sent - s.broadcasts_sent for s in endpoints),
        "broadcast_frames_sent": sum(s.broadcasts_sent for s in endpoints),
        "unicast_receptions": {"delivered": medium.unicast_delivered, "lost": medium.unicast_lost},
        "broadcast_receptions": {"delivered": medium.broadcast_delivered, "lost": medium.broadcast_lost},
        "relayed_receptions": {"delivered": medium.relayed_delivered, "lost": medium.relayed_lost},
        "frames_lost": medium.unicast_lost + medium.broadcast_lost + medium.relayed_lost,
        "retries": sum(s.retries for s in endpoints),
        "confirms": sum(s.confirms_sent for s in endpoints),
        "confirms_received": sum(s.confirms_received for s in endpoints),
        "duplicates_suppressed": sum(s.duplicates for s in endpoints),
        "frames_rejected": sum(s.frames_rejected for s in endpoints),
        "delivery_failures": sum(s.delivery_failures for s in endpoints),
        "unicast_sends": sends,
        "unicast_sends_delivered": sends_delivered,
        "delivery_ratio": round(sends_delivered / sends, 4) if sends else None,
        "by_type": by_type,
        "commands_sent": len(commands),
        "commands_confirmed": confirmed,
        "command_confirm_ratio": round(confirmed / len(commands), 4) if commands else None,
        "commands_failed": sum(1 for c in commands if c.failed),
        "commands_pending": sum(1 for c in commands if not c.failed and c.result is None),
        "streams_failed": sum(1 for c in commands if not c.failed and c.result is not None
                              and c.msg_type is MessageType.FOLLOW
                              and c.reason in (Reason.LINK_LOST, Reason.PARTNER_SILENT)),
        "automatic_stops": {"sent": len(automatic), "confirmed": sum(1 for c in automatic if c.confirmed_s is not None),
                            "failed": sum(1 for c in automatic if c.failed),
                            "pending": sum(1 for c in automatic if not c.failed and c.result is None)},
        "confirm_latency_s": confirm_latency(commands),
        "bytes_sent": sum(s.bytes_sent for s in endpoints),
        "max_frame_bytes": medium.max_frame_bytes,
        "max_logical_frame_bytes": max((s.max_frame_bytes for s in endpoints), default=0),
    }


def network_summary(rt) -> dict:
    """The mesh and the air: relaying, hops, collisions, airtime, segmentation, neighbour tables."""
    medium = rt.medium.stats
    hops: dict[int, int] = {}
    for stack in rt.stacks.values():
        for count, n in stack.hops_histogram.items():
            hops[count] = hops.get(count, 0) + n
    nodes = [stack.node.stats for stack in rt.stacks.values()]
    return {
        "relayed_frames": medium.relayed_transmissions,
        "max_hops_delivered": max(hops, default=0),
        "hops_histogram": {str(k): hops[k] for k in sorted(hops)},
        "collisions": medium.collisions,
        "airtime_s": round(medium.airtime_s, 4),
        "transmissions": medium.transmissions,
        "segment_transmissions": medium.segment_transmissions,
        "segmented_messages": sum(n.transfers_started for n in nodes),
        "segmented_messages_complete": sum(n.transfers_complete for n in nodes),
        "receptions_delivered": medium.receptions_delivered,
        "receptions_lost": dict(medium.receptions_lost),
        "neighbours": {name: [_neighbour(n) for n in stack.node.neighbours()] for name, stack in rt.stacks.items()},
    }


def _neighbour(info) -> dict:
    from rescuemesh.robot import robot_name

    return {"robot": robot_name(info.address) if 1 <= info.address <= 254 else info.address, "hops": info.hops,
            "rssi_dbm": None if info.rssi_dbm is None else round(info.rssi_dbm, 1),
            "last_heard_s": round(info.last_heard_s, 3), "lost": info.lost}


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
