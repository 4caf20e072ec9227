"""Configuration of a mesh node: relay feature, TTL, cache size, liveness and SAR timers.
Owns the parameters and their validation only; must not know frames, clocks or robots.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rescuemesh.protocol.wire import DEFAULT_TTL, MAX_TTL


def _positive(name: str, value: object) -> None:
    if not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            and value > 0.0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


def _non_negative(name: str, value: object) -> None:
    if not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            and value >= 0.0):
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")


def _ttl(name: str, value: object, what: str = "") -> None:
    if not (isinstance(value, int) and 0 <= value <= MAX_TTL):
        raise ValueError(f"{name} must be 0..{MAX_TTL}{what}, got {value!r}")


def _count(name: str, value: object, low: int) -> None:
    if not (isinstance(value, int) and not isinstance(value, bool) and value >= low):
        raise ValueError(f"{name} must be an int >= {low}, got {value!r}")


#: Relay Retransmit count the simulated team and the benchmarks use (Zephyr's default).
TEAM_RELAY_RETRANSMIT_COUNT = 2


@dataclass(frozen=True, slots=True)
class MeshConfig:
    """Per-robot network-layer parameters (docs/mesh.md lists every one with its source).

    relay: the relay feature (Bluetooth Mesh Profile 1.0, 3.4.6.1): re-broadcast frames not for us.
    relay_retransmit_count, relay_retransmit_interval_s: a relayed frame goes out 1 + count times,
        interval s apart (Relay Retransmit state, Mesh Profile 4.2.20: count 0..7). 0 here (one
        copy per relay); the simulated team uses TEAM_RELAY_RETRANSMIT_COUNT = 2 at 20 ms, Zephyr's
        default: a command then crosses 30 % loss via two relays 99.9 % of the time or better
        (rescuemesh bench; 99.3 % with 0), at three times the relays' airtime.
    relay_suppress_after: counter-based relay suppression (Ni, Tseng, Chen, Sheu, "The broadcast
        storm problem in a mobile ad hoc network", MobiCom 1999, 3.2): a relay that hears this
        many further copies of a frame relayed by others (TTL at most its own copies'; not the
        Relay Retransmit copies of the node it heard) while its own copies still wait in the
        outbox cancels them. 0 or None: off. 1 (Ni's C = 2) measured best: 10 robots 1 m apart
        confirm every Follow (0 of 9 without), and a 6-hop round trip is faster (docs/mesh.md 12).
    relay_pace_s: relayed control copies leave the outbox at most one per this, in s, and one
        pace after any frame the node sends, so they wait here (where suppression can cancel
        them) and not in the radio's queue: 30 ms = the 20 ms advertising interval + the 10 ms
        maximum advDelay (Core Vol 6 Part B 4.4.2.2.1), what a radio needs per frame at worst.
        Segments are not paced here (their source paces them). 0: off.
    relay_max_wait_s: a relayed copy still in the outbox this long, in s, after its time is
        dropped (relays_expired): by then its source has resent or given up (endpoint ack
        timeout 150 ms), and a copy older than the neighbours' cache entries would flood again.
        math.inf: never.
    initial_ttl: TTL the team originates frames with, in hops (0..15); used to count hops from a
        source whose Heartbeat (which carries its own init_ttl) has not been heard. Default: the
        protocol's DEFAULT_TTL (7); a robot's endpoint is built with this value (runtime/assembly.py).
    unicast_ttl_from_hops: a unicast control frame, on its first send, to a destination heard
        recently (not lost) h hops away goes out with TTL min(initial_ttl, h + 1) instead of
        initial_ttl: one hop of slack, not a flood across the team (Mesh Profile 1.0, 3.6.7: hop
        counts from Heartbeats "may be used to determine the TTL"). Resends (attempt bits > 0),
        broadcasts, segmented frames and unknown or lost destinations keep initial_ttl.
    unicast_ttl_slack: hops added to h above (0: a first send to a direct neighbour is not relayed).
    sparse_neighbours: a node that reaches at most this many others adds one hop more: a small team
        has airtime to spare, and a relay's copy rescues a command on a lossy direct link (with 0,
        a command over a 30 % loss link was confirmed within 2 s 93 % of the time, 99.95 % with 1).
    heartbeat_ttl: TTL our Heartbeats go out with and announce (Heartbeat Publication TTL, Mesh
        Profile 4.2.17; None: initial_ttl): 3 reaches partners two hops away, not a team of 30.
        3 against initial_ttl's 7 on purpose: a Heartbeat only has to reach the partners whose
        liveness a robot tracks, a command must cross the whole team. The endpoint's own default
        (EndpointConfig.heartbeat_ttl None: initial_ttl) is for an endpoint without a mesh; a
        team's endpoints take this value instead (runtime/assembly.py).
    heartbeat_relay_delay_scale: a relayed Heartbeat waits the caller's relay delay times this
        (5: 0..50 ms), so that most relays hear another's copy first and cancel theirs (counter-
        based suppression); commands keep the short delay. 30 robots: 6.7 relays a beat at 1,
        about 4 at 5 (docs/mesh.md 12 says why not 10).
    cache_size: network message cache entries (Mesh Profile 1.0, 3.4.6.5; Zephyr keeps 10). 128
        covers the life of a flood (TTL x relay delay, about 0.2 s) at a few hundred frames per
        second, i.e. 30 robots streaming plus a segmented transfer (docs/mesh.md, "The cache").
    cache_lifetime_s: a cache entry older than this, in s, no longer suppresses a frame: longer
        than a flood lives, shorter than four SAR rounds (a segment's round bits repeat mod 4).
    heartbeat_period_s, lost_after_missed: a neighbour is lost once
        now >= last_heard + (lost_after_missed + 0.5) * heartbeat_period_s (half a period of grace).
        The one source of the heartbeat period: the robot above sends its Heartbeats this often
        (NetworkStack.heartbeat_period_s), so the count of missed ones means what it says.
    neighbour_expiry_s: a neighbour unheard this long, in s, is forgotten.
    segment_interval_s: at most one segment per interval, in s (Mesh Protocol 1.1 default 20 ms).
    sar_ack_base_s + sar_per_hop_s * hops: receiver's ack timer, in s (Mesh Profile 1.0 3.5.3.4:
        >= 150 + 50 * TTL ms). Same numbers as the endpoint's confirm timeout (ReliabilityConfig
        ack_timeout_s + per_hop_timeout_s, from the same rule) but another timer: a segment's block
        ack here, an end-to-end Confirm there; each tunes apart. sar_retransmit_base_s + sar_per_hop_s * hops: sender's wait after
        the last segment of a round, in s (3.5.3.3: >= 200 + 50 * TTL ms).
    duplicate_ack_interval_s: a segment the receiver already holds means its last ack was lost:
        it acks again at once, at most once per this interval, in s (docs/mesh.md, "Acks").
    max_retransmissions: rounds without progress before giving up (Zephyr: 4).
    incomplete_timeout_s: a reassembly that receives no new segment for this long is discarded,
        and a completed one is remembered this long (Mesh Profile 1.0 3.5.3.4: >= 10 s).
    max_reassemblies, max_reassemblies_per_source: concurrent reassemblies (memory bound: 8 KB
        each at most). completed_memory: completed transfers remembered (each keeps its frame).
    """

    relay: bool = True
    relay_retransmit_count: int = 0
    relay_retransmit_interval_s: float = 0.02
    relay_suppress_after: int | None = 1
    relay_pace_s: float = 0.03
    relay_max_wait_s: float = 0.1
    initial_ttl: int = DEFAULT_TTL
    unicast_ttl_from_hops: bool = True
    unicast_ttl_slack: int = 0
    sparse_neighbours: int = 6
    heartbeat_ttl: int | None = 3
    heartbeat_relay_delay_scale: float = 5.0
    cache_size: int = 128
    cache_lifetime_s: float = 0.75
    heartbeat_period_s: float = 1.0
    lost_after_missed: int = 3
    neighbour_expiry_s: float = 60.0
    segment_interval_s: float = 0.02
    sar_ack_base_s: float = 0.15
    sar_per_hop_s: float = 0.05
    sar_retransmit_base_s: float = 0.2
    duplicate_ack_interval_s: float = 0.06
    max_retransmissions: int = 4
    incomplete_timeout_s: float = 10.0
    max_reassemblies: int = 8
    max_reassemblies_per_source: int = 2
    completed_memory: int = 32

    def __post_init__(self) -> None:
        if not isinstance(self.relay, bool):
            raise ValueError(f"relay must be a bool, got {self.relay!r}")
        if not isinstance(self.unicast_ttl_from_hops, bool):
            raise ValueError(f"unicast_ttl_from_hops must be a bool, got {self.unicast_ttl_from_hops!r}")
        if self.relay_suppress_after is not None:
            _count("relay_suppress_after", self.relay_suppress_after, 0)
        _ttl("initial_ttl", self.initial_ttl, " hops")
        for name in ("cache_lifetime_s", "heartbeat_period_s", "neighbour_expiry_s", "segment_interval_s",
                     "sar_ack_base_s", "sar_retransmit_base_s", "duplicate_ack_interval_s",
                     "incomplete_timeout_s"):
            _positive(name, getattr(self, name))
        _non_negative("sar_per_hop_s", self.sar_per_hop_s)
        for name in ("cache_size", "lost_after_missed", "max_reassemblies",
                     "max_reassemblies_per_source", "completed_memory"):
            _count(name, getattr(self, name), 1)
        _count("max_retransmissions", self.max_retransmissions, 0)
        if not (isinstance(self.relay_retransmit_count, int) and 0 <= self.relay_retransmit_count <= 7):
            raise ValueError(f"relay_retransmit_count must be 0..7 (3 bits), got {self.relay_retransmit_count!r}")
        _positive("relay_retransmit_interval_s", self.relay_retransmit_interval_s)
        _non_negative("relay_pace_s", self.relay_pace_s)
        _positive("heartbeat_relay_delay_scale", self.heartbeat_relay_delay_scale)
        _count("unicast_ttl_slack", self.unicast_ttl_slack, 0)
        _count("sparse_neighbours", self.sparse_neighbours, 0)
        if self.heartbeat_ttl is not None:
            _ttl("heartbeat_ttl", self.heartbeat_ttl, " hops or None")
        if self.relay_max_wait_s != math.inf:  # inf: relays never go stale
            _positive("relay_max_wait_s", self.relay_max_wait_s)
        if self.max_reassemblies_per_source > self.max_reassemblies:
            raise ValueError(
                f"max_reassemblies_per_source ({self.max_reassemblies_per_source}) must not exceed "
                f"max_reassemblies ({self.max_reassemblies})"
            )
        if self.neighbour_expiry_s <= self.lost_after_seconds:
            raise ValueError(
                f"neighbour_expiry_s ({self.neighbour_expiry_s!r} s) must exceed the loss time "
                f"(lost_after_missed + 0.5) * heartbeat_period_s = {self.lost_after_seconds} s"
            )

    @property
    def lost_after_seconds(self) -> float:
        """Silence, in s, after which a neighbour is lost: (lost_after_missed + 0.5) * period."""
        return (self.lost_after_missed + 0.5) * self.heartbeat_period_s

    def ack_delay_s(self, hops: int) -> float:
        """Receiver's ack timer for a source `hops` away, in s (Mesh Profile 1.0 3.5.3.4)."""
        return self.sar_ack_base_s + self.sar_per_hop_s * hops

    def retransmit_timeout_s(self, hops: int) -> float:
        """Sender's wait after a round's last segment for a destination `hops` away, in s (3.5.3.3)."""
        return self.sar_retransmit_base_s + self.sar_per_hop_s * hops
