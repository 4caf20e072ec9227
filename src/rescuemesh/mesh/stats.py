"""Counters of a mesh node since it was made, shared by its parts (relay, neighbours, SAR).
Owns the counter names and their meaning only; must not know when they are incremented.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass


@dataclass(slots=True)
class MeshStats:
    """What a node saw and did. Frames counted here are on-air frames unless "logical" is said."""

    received: int = 0  # receive() calls
    accepted: int = 0  # frames heard that passed every check (authentic, new) and were used
    delivered: int = 0  # FrameDelivered events (logical frames, reassembled ones included)
    relayed: int = 0  # frames queued for re-broadcast
    relays_suppressed: int = 0  # of those, cancelled with copies still pending (relay_suppress_after)
    relay_copies_suppressed: int = 0  # copies those cancellations kept off the air
    relays_expired: int = 0  # relayed copies dropped after waiting relay_max_wait_s past their time
    sent: int = 0  # logical frames accepted by send()
    sent_short_ttl: int = 0  # of those, unicast sent with a TTL from hops < initial_ttl (unicast_ttl_from_hops)
    transmitted: int = 0  # Transmissions drained by transmissions()
    bytes_transmitted: int = 0
    dropped_cached: int = 0  # already in the network message cache
    dropped_own: int = 0  # our own frame heard back
    dropped_passing: int = 0  # for another robot with TTL < 2 (its last hop): dropped unopened
    dropped_ttl: int = 0  # not for us, TTL < 2: not relayed
    dropped_corrupt: int = 0  # CRC mismatch
    dropped_unauthenticated: int = 0  # no AUTH flag in a team that authenticates
    dropped_unknown_epoch: int = 0  # from a source whose epoch is not known yet (no Heartbeat heard)
    dropped_forged: int = 0  # MIC did not verify (no key, wrong key, altered)
    dropped_replay: int = 0  # authentic but already accepted, too old, or from an old epoch
    dropped_malformed: int = 0  # any other bad frame or segment (length, version, AUTH, SegO/SegN)
    segments_sent: int = 0  # segment frames released, retransmissions included
    segments_retransmitted: int = 0  # of those, released in a round > 0
    segments_received: int = 0  # new segments for us
    segments_duplicate: int = 0  # segments for us already held
    segments_late: int = 0  # segments of a message already reassembled
    transfers_started: int = 0
    transfers_queued: int = 0  # started behind another transfer to the same destination
    transfers_complete: int = 0
    transfers_failed: int = 0
    resends_absorbed: int = 0  # endpoint resends of a frame whose transfer is still running
    transfers_abandoned: int = 0  # ended because the endpoint no longer awaits the frame
    reassemblies_complete: int = 0
    reassemblies_expired: int = 0  # incomplete timer
    reassemblies_rejected: int = 0  # segments dropped: too many concurrent reassemblies
    reassemblies_corrupt: int = 0  # complete, but the frame's own CRC-32 did not match
    redeliveries: int = 0  # a completed frame delivered again for an endpoint resend
    acks_sent: int = 0
    acks_received: int = 0
    acks_unmatched: int = 0  # for no transfer in progress, or reporting more segments than sent

    def as_dict(self) -> dict[str, int]:
        return asdict(self)
