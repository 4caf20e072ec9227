"""End-to-end delivery and latency per message type, read from the radio medium's air records, and
each command's time to its first Confirm (docs/results.md, "protocol.by_type", "protocol.confirm_latency_s").

Owns: grouping the transmissions of a run into messages (one source, one sequence number: a
message's first send, its resends, its relayed copies and its segments share it) and judging each
at its destination. Must not know: frame contents, how the medium decided a reception, plotting.
"""

from __future__ import annotations

from collections import defaultdict
from functools import cache

from rescuemesh.protocol import BROADCAST, MessageType


@cache
def _type_name(msg_type: int) -> str:
    try:
        return MessageType(msg_type).name
    except ValueError:
        return f"TYPE_{msg_type}"


def _quantiles(values: list[float]) -> dict | None:
    """{"n", "p50", "p95", "max"} of `values` in s (nearest-rank), rounded to 0.1 ms; None for none."""
    if not values:
        return None
    ordered = sorted(values)

    def rank(q: float) -> float:
        return ordered[min(len(ordered) - 1, max(0, int(-(-q * len(ordered) // 1)) - 1))]

    return {"n": len(ordered), "p50": round(rank(0.5), 4), "p95": round(rank(0.95), 4), "max": round(ordered[-1], 4)}


def _unicast_message(records: list) -> tuple[int, int, bool, bool, float | None]:
    """(sends, sends delivered, delivered, first send delivered, latency in s) of one unicast message.

    A send is a transmission by the source itself (first send or resend; for a segmented message
    the first transmission of each segment count as one send). A copy the destination heard (the
    source's own or a relay's) counts for the last send that started before it. Latency: from the
    start of the first send on the air to the end of the first copy the destination heard (for a
    segmented message: the first copy of its last missing segment)."""
    first_start = records[0].start_s
    segmented = any(r.segment is not None for r in records)
    if segmented:
        needed = {r.segment for r in records}
        arrived: dict[int, float] = {}
        for r in records:
            if r.dst_heard and r.segment not in arrived:
                arrived[r.segment] = r.end_s
        delivered = set(arrived) == needed
        latency = max(arrived.values()) - first_start if delivered else None
        return 1, int(delivered), delivered, delivered, latency
    sends = [r.start_s for r in records if not r.relayed and r.transmitter == r.src]
    heard = [r for r in records if r.dst_heard]
    delivered_sends = set()
    for r in heard:
        index = sum(1 for s in sends if s <= r.start_s) - 1
        delivered_sends.add(max(index, 0))
    latency = min(r.end_s for r in heard) - first_start if heard else None
    return len(sends), len(delivered_sends), bool(heard), 0 in delivered_sends, latency


def by_message_type(records: list, team_size: int) -> dict:
    """Per message type (FOLLOW, POSE_UPDATE, CONFIRM, HEARTBEAT, ...), what reached its receivers.

    Unicast types: `messages` (distinct messages originated), `delivered` (reached their destination,
    by any path, at least once), `first_send_delivered`, `sends` and `sends_delivered` (per send,
    end to end), `delivery_ratio` (sends_delivered / sends) and `latency_s` (first send on the air
    to first arrival at the destination, over the delivered messages). Broadcast types (Heartbeat):
    `messages`, `receptions_expected` (messages x the other robots), `receptions_delivered` (other
    robots that heard the source's own transmission) and their ratio."""
    groups: dict[tuple, list] = defaultdict(list)
    for r in records:
        groups[(r.src, r.seq, r.dst, r.msg_type)].append(r)
    table: dict[str, dict] = {}
    latencies: dict[str, list[float]] = defaultdict(list)
    for (src, _, dst, msg_type), group in groups.items():
        name = _type_name(msg_type)
        if dst == BROADCAST:
            row = table.setdefault(name, {"messages": 0, "receptions_expected": 0, "receptions_delivered": 0})
            own = [r for r in group if not r.relayed and r.transmitter == src]
            row["messages"] += 1
            row["receptions_expected"] += max(team_size - 1, 0)
            row["receptions_delivered"] += min(max((r.heard_by for r in own), default=0), max(team_size - 1, 0))
            continue
        row = table.setdefault(name, {"messages": 0, "delivered": 0, "first_send_delivered": 0,
                                      "sends": 0, "sends_delivered": 0})
        sends, sends_ok, delivered, first_ok, latency = _unicast_message(group)
        row["messages"] += 1
        row["delivered"] += int(delivered)
        row["first_send_delivered"] += int(first_ok)
        row["sends"] += sends
        row["sends_delivered"] += sends_ok
        if latency is not None:
            latencies[name].append(latency)
    for name, row in table.items():
        if "sends" in row:
            row["delivery_ratio"] = round(row["sends_delivered"] / row["sends"], 4) if row["sends"] else None
            row["latency_s"] = _quantiles(latencies[name])
        else:
            expected = row["receptions_expected"]
            row["reception_ratio"] = round(row["receptions_delivered"] / expected, 4) if expected else None
    return {name: table[name] for name in sorted(table)}


def unicast_sends(records: list) -> tuple[int, int]:
    """(sends, sends delivered end to end) over every unicast message of the run (by_message_type's
    definition): the run's `delivery_ratio` is their quotient."""
    sends = delivered = 0
    for row in by_message_type(records, 0).values():
        if "sends" in row:
            sends += row["sends"]
            delivered += row["sends_delivered"]
    return sends, delivered


def confirm_latency(commands: list) -> dict:
    """Per command kind (Follow, Stop, Goto, ...), the time in s from the mission's first send to the
    first Confirm of any result (`OutgoingCommand.confirmed_s - sent_s`), over the confirmed ones."""
    by_kind: dict[str, list[float]] = defaultdict(list)
    for c in commands:
        if c.confirmed_s is not None:
            by_kind[c.kind].append(c.confirmed_s - c.sent_s)
    return {kind: _quantiles(values) for kind, values in sorted(by_kind.items())}
