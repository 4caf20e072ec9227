"""The Zenoh bearer: a robot's mesh frames over a Zenoh session, one shared broadcast medium per team.
Owns: key expressions, the peer-to-peer session config, the put/subscribe pump and the thread-safe
hand-off of received frames to the robot's loop. Must not know: what is inside a frame, robots, clocks.
"""

# Theory of operation. Every robot of team T publishes each frame it transmits on its own key
# `rescuemesh/T/air/<address>` and subscribes to `rescuemesh/T/air/*`, so, as on a radio, every
# robot hears every frame and its mesh layer decides what is for it, what to relay and what to drop.
# Zenoh calls the subscriber back on one of its own threads; the callback only appends the bytes to
# a queue (bounded: beyond `max_queue` waiting frames new ones are dropped and counted, as a radio's
# full receive buffer would) and the robot's loop, blocked in `wait(timeout_s)`, wakes at once. A
# frame is never parsed here: garbage from a peer reaches the network stack, which rejects and
# counts it (tests/transport/test_zenoh_link.py sends it some).

from __future__ import annotations

import json
import queue
import re
import threading
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass

import zenoh

#: First chunk of every rescuemesh key expression.
KEY_PREFIX = "rescuemesh"
#: A team name is one key chunk: no '/', no wildcards, no '$'.
_TEAM = re.compile(r"[A-Za-z0-9_.-]{1,64}")
#: `tcp/IP:PORT` or `udp/IP:PORT` (IPv6 in brackets, or a host name), the endpoints a robot is given.
_ENDPOINT = re.compile(r"(tcp|udp)/(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})")
#: Frames waiting for the loop beyond which new ones are dropped (about 1 s of a busy team's air).
DEFAULT_MAX_QUEUE = 4096
#: A frame longer than this is dropped unread: the protocol's longest frame is far shorter.
MAX_FRAME_BYTES = 1024
#: Connect retries: the first 0.25 s after a failure, doubling up to 2 s (Zenoh's default starts at 1 s).
CONNECT_RETRY = {"period_init_ms": 250, "period_max_ms": 2000, "period_increase_factor": 2}
#: How long close() waits for Zenoh to shut down, in s (a dead peer must not hang the exit).
CLOSE_TIMEOUT_S = 3.0


def air_key(team: str, address: int) -> str:
    """The key robot `address` of `team` publishes its frames on."""
    check_team(team)
    if not (isinstance(address, int) and 0 <= address <= 255):
        raise ValueError(f"address must be 0..255, got {address!r}")
    return f"{KEY_PREFIX}/{team}/air/{address}"


def air_wildcard(team: str) -> str:
    """The key expression of the team's whole air (every robot's frames)."""
    check_team(team)
    return f"{KEY_PREFIX}/{team}/air/*"


def check_team(team: str) -> str:
    """`team` if it is a valid team name (one key chunk); else ValueError."""
    if not (isinstance(team, str) and _TEAM.fullmatch(team)):
        raise ValueError(f"bad team name {team!r}: 1-64 letters, digits, '_', '.' or '-'")
    return team


def check_endpoint(endpoint: str) -> str:
    """`endpoint` if it is `tcp/HOST:PORT` or `udp/HOST:PORT` with a port 0..65535; else ValueError."""
    match = _ENDPOINT.fullmatch(endpoint) if isinstance(endpoint, str) else None
    if match is None or int(match.group(3)) > 65535:
        raise ValueError(f"bad endpoint {endpoint!r}: expected tcp/IP:PORT (or udp/IP:PORT)")
    return endpoint


def session_config(listen: Sequence[str] = (), connect: Sequence[str] = ()) -> zenoh.Config:
    """A peer-to-peer session config: peer mode, explicit `listen` and `connect` endpoints
    (`tcp/IP:PORT`), multicast scouting off (robots find each other only through the endpoints
    they are given, and through gossip over the sessions those open). Connect attempts are retried
    in the background, CONNECT_RETRY apart (a peer that starts later, or comes back in range, is
    reached within about 2 s of it listening)."""
    listen = [check_endpoint(e) for e in listen]
    connect = [check_endpoint(e) for e in connect]
    if not listen and not connect:
        raise ValueError("a robot needs at least one --listen or --connect endpoint")
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("listen/endpoints", json.dumps(listen))
    config.insert_json5("connect/endpoints", json.dumps(connect))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("connect/retry", json.dumps(CONNECT_RETRY))
    return config


@dataclass
class LinkStats:
    """What crossed the link: frames and bytes put and heard; heard frames dropped because they were
    our own echo, too long, or the queue was full; puts that Zenoh refused."""

    frames_sent: int = 0
    bytes_sent: int = 0
    send_errors: int = 0
    frames_received: int = 0
    bytes_received: int = 0
    echoes_dropped: int = 0
    oversize_dropped: int = 0
    overflow_dropped: int = 0

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


class ZenohLink:
    """Robot `address`'s frames on `team`'s air over an open Zenoh `session`.

    The robot's loop calls `send(frame)` (or `send_all`), `wait(timeout_s)` to block until a frame
    is heard or the timeout passes, and `drain()` for the frames heard, oldest first. `close()`
    undeclares the publisher and subscriber, and closes the session when the link opened it.
    """

    def __init__(self, session: zenoh.Session, team: str, address: int, *, max_queue: int = DEFAULT_MAX_QUEUE,
                 owns_session: bool = False) -> None:
        if max_queue < 1:
            raise ValueError(f"max_queue must be >= 1, got {max_queue}")
        self.team, self.address = team, address
        self.key = air_key(team, address)
        self.stats = LinkStats()
        self._session, self._owns_session = session, owns_session
        self._max_queue = max_queue
        self._queue: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        self._held: list[bytes] = []  # frames taken off the queue by wait(), not drained yet
        self._closed = False
        # express: no batching (a 20-byte frame leaves at once); DROP: a congested link drops
        # frames like a busy radio instead of blocking the robot's loop (the protocol retries)
        self._publisher = session.declare_publisher(self.key, express=True,
                                                    congestion_control=zenoh.CongestionControl.DROP)
        self._subscriber = session.declare_subscriber(air_wildcard(team), self._on_sample,
                                                      allowed_origin=zenoh.Locality.REMOTE)

    @classmethod
    def open(cls, team: str, address: int, *, listen: Sequence[str] = (), connect: Sequence[str] = (),
             max_queue: int = DEFAULT_MAX_QUEUE) -> "ZenohLink":
        """Open a peer session (session_config) and the link on it; close() closes both."""
        config = session_config(listen, connect)
        air_key(team, address)  # ValueError before a session opens
        session = zenoh.open(config)
        try:
            return cls(session, team, address, max_queue=max_queue, owns_session=True)
        except BaseException:
            session.close()
            raise

    # --- the robot loop's side -------------------------------------------------------------------

    def send(self, frame: bytes) -> None:
        """Put one frame on the air (never raises: a refused put is counted in `send_errors`)."""
        if self._closed:
            return
        try:
            self._publisher.put(frame)
        except zenoh.ZError:
            self.stats.send_errors += 1
            return
        self.stats.frames_sent += 1
        self.stats.bytes_sent += len(frame)

    def send_all(self, frames: Iterable[bytes]) -> None:
        for frame in frames:
            self.send(frame)

    def wait(self, timeout_s: float | None) -> bool:
        """Block until a frame is waiting or `timeout_s` s pass (None: no limit; <= 0: just look).
        True when frames are waiting."""
        if self._held:
            return True
        try:
            if timeout_s is not None and timeout_s <= 0:
                self._held.append(self._queue.get_nowait())
            else:
                self._held.append(self._queue.get(timeout=timeout_s))
        except queue.Empty:
            return False
        return True

    def drain(self) -> list[bytes]:
        """Every frame heard and not yet drained, oldest first."""
        frames, self._held = self._held, []
        get = self._queue.get_nowait
        try:
            while True:
                frames.append(get())
        except queue.Empty:
            return frames

    def close(self, timeout_s: float = CLOSE_TIMEOUT_S) -> bool:
        """Stop sending and hearing; close the session if this link opened it. Bounded: returns
        False when Zenoh did not finish within `timeout_s` s (its threads are left to the exit)."""
        if self._closed:
            return True
        self._closed = True

        def shut() -> None:
            for entity in (self._subscriber, self._publisher):
                try:
                    entity.undeclare()
                except zenoh.ZError:
                    pass
            if self._owns_session:
                self._session.close()

        closer = threading.Thread(target=shut, name=f"zenoh-close-{self.address}", daemon=True)
        closer.start()
        closer.join(timeout_s)
        return not closer.is_alive()

    # --- Zenoh's side (its threads) --------------------------------------------------------------

    def _on_sample(self, sample: zenoh.Sample) -> None:
        stats = self.stats
        if str(sample.key_expr) == self.key:  # our own frame (another session of ours, or a clone)
            stats.echoes_dropped += 1
            return
        frame = sample.payload.to_bytes()
        if len(frame) > MAX_FRAME_BYTES:
            stats.oversize_dropped += 1
            return
        if self._queue.qsize() >= self._max_queue:
            stats.overflow_dropped += 1
            return
        stats.frames_received += 1
        stats.bytes_received += len(frame)
        self._queue.put(frame)

