"""What an endpoint is told (EndpointConfig) and what it counts (EndpointStats). Must not know how an
endpoint sends, receives or retries (endpoint.py, reliability.py)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

from .codec import DEFAULT_TTL, MAX_EPOCH, MAX_SEQ, MAX_TTL
from .reliability import ReliabilityConfig


@dataclass(frozen=True, slots=True)
class EndpointConfig:
    """reliability: retry and duplicate rules. initial_ttl: TTL of every frame we originate, in hops
    (0..15). heartbeat_ttl: TTL of our Heartbeats (Bluetooth Mesh's Heartbeat Publication TTL;
    None: initial_ttl): how far they reach. initial_seq: first sequence number (0..65535); a runtime that restarts an endpoint can
    draw it from its seeded generator so old seqs are not reused at once. announce_epoch_on_resend:
    our resend to a robot that has not answered any of our frames, and a cached Confirm re-sent for
    its resend, go after a repeat of our latest Heartbeat (bounded: docs/protocol.md section 7),
    since in an authenticated team a robot that missed our Heartbeats cannot open anything we send;
    an authenticated team's assembly turns it on."""

    reliability: ReliabilityConfig = field(default_factory=ReliabilityConfig)
    initial_ttl: int = DEFAULT_TTL
    heartbeat_ttl: int | None = None
    initial_seq: int = 0
    initial_epoch: int = 0
    announce_epoch_on_resend: bool = False

    def __post_init__(self) -> None:
        if not (isinstance(self.initial_ttl, int) and 0 <= self.initial_ttl <= MAX_TTL):
            raise ValueError(f"initial_ttl must be 0..{MAX_TTL}, got {self.initial_ttl!r}")
        heartbeat_ttl = self.heartbeat_ttl
        if heartbeat_ttl is not None and not (isinstance(heartbeat_ttl, int) and 0 <= heartbeat_ttl <= MAX_TTL):
            raise ValueError(f"heartbeat_ttl must be 0..{MAX_TTL} or None, got {self.heartbeat_ttl!r}")
        if not (isinstance(self.initial_seq, int) and 0 <= self.initial_seq <= MAX_SEQ):
            raise ValueError(f"initial_seq must be 0..{MAX_SEQ}, got {self.initial_seq!r}")
        if not (isinstance(self.initial_epoch, int) and 0 <= self.initial_epoch <= MAX_EPOCH):
            raise ValueError(f"initial_epoch must be 0..{MAX_EPOCH}, got {self.initial_epoch!r}")


@dataclass(slots=True)
class EndpointStats:
    """Counters since the endpoint was made. Frames and bytes sent count frames drained by
    frames_to_send(); frames_received counts every receive() call, including the rejected ones and
    the ones not for us (other destination, or our own frames heard back)."""

    frames_sent: int = 0
    broadcasts_sent: int = 0  # of frames_sent, those to BROADCAST (Heartbeats)
    bytes_sent: int = 0
    max_frame_bytes: int = 0
    retries: int = 0  # resends (a frame sent 3 times counts 2)
    confirms_sent: int = 0  # Confirm frames drained, cached re-sends included
    confirms_received: int = 0
    delivery_failures: int = 0
    duplicates: int = 0  # commands/PoseUpdates recognised as resends
    frames_rejected: int = 0
    frames_not_for_us: int = 0
    frames_received: int = 0
    confirms_unmatched: int = 0  # Confirms answering nothing we sent or still await: dropped
    epochs: int = 0  # sequence wraps (each starts a new epoch)
    epoch_announcements: int = 0  # Heartbeats repeated before a resend to a robot that never answered

    def as_dict(self) -> dict[str, int]:
        return asdict(self)
