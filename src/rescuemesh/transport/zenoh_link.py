"""The Zenoh bearer: a robot's mesh frames over a Zenoh session, one shared broadcast medium per team.
Owns: key expressions, the peer-to-peer session config, the put/subscribe pump and the thread-safe
hand-off of received frames to the robot's loop. Must not know: what is inside a frame, robots, clocks.
"""

# Theory of operation. Every robot of team T publishes each frame it transmits on its own key
# `rescuemesh/T/air/<address>` and subscribes to `rescuemesh/T/air/*`, so, as on a radio, every
# robot hears every frame and its mesh layer decides what is for it, what to relay and what to drop.
# Zenoh calls the subscriber back on one of its own threads; the callback checks the payload's length
# before copying it (a frame is at most MAX_FRAME_BYTES) and appends the bytes to the queue of the
# key it came on, and the robot's loop, blocked in `wait(timeout_s)`, wakes at once. A frame is never
# parsed here: garbage from a peer reaches the network stack, which rejects and counts it
# (tests/transport/test_zenoh_link.py sends it some).
#
# Fair under a flood. The queues are bounded together (`max_queue` frames): when they are full, the
# frame dropped is one of the source holding the most (the newest of that source: it is the arriving
# one when the arriving source is the longest), so a flooder fills only its own queue. `drain(limit)`
# takes round-robin over the sources, oldest first within each, so a robot's loop that takes at most
# 256 frames per wake-up gets every quiet source's frames before the flooder's backlog (a source is
# the key it publishes on; a member flooding on many keys gets a share per key, still not the tail).
#
# Closed to non-members (docs/security.md, "The Zenoh link"). A session opened with a team secret
# (`open_session(..., secret=...)`, derived from the team key by `link_secret`) authenticates every
# peer with Zenoh's user-password extension: a peer without the secret cannot open a transport to
# it at all, so it can neither put nor flood nor gossip. A message longer than LINK_MAX_MESSAGE_BYTES
# is refused by Zenoh's receiver before it is reassembled (transport/link/rx/max_message_size);
# shared memory is off (a local peer cannot hand us a buffer of its choosing), and gossip does not
# travel more than one hop (multihop off: a peer learns only the peers of those it is connected to).

from __future__ import annotations

import json
import os
import queue
import re
import shutil
import tempfile
import threading
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass

import zenoh

from rescuemesh.mesh.keys import FRAME_KEY_SALT, hkdf_sha256
from rescuemesh.transport.handoff import Handoff

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
#: The longest message a link session accepts, in bytes (Zenoh's default is 1 GiB: one put from a
#: peer cost a robot 2 GB). A frame is at most 29 bytes on the air and MAX_FRAME_BYTES here; Zenoh's
#: own declarations and gossip fit in a few KiB with a team's keys.
LINK_MAX_MESSAGE_BYTES = 4096
#: A link session returns from opening at once: its peers are explicit endpoints, and a robot announces
#: itself when another robot's link appears (ZenohLink.new_peers). Zenoh's 500 ms default made a
#: restarted robot's Follow take 0.5 s longer in one start out of two.
LINK_SCOUTING_DELAY_MS = 0
#: HKDF info of the link password: another use of the team key, so another label (mesh/keys.py).
LINK_PASSWORD_INFO = b"zenoh link password"
LINK_PASSWORD_BYTES = 16


def link_secret(team_key: bytes) -> bytes:
    """The Zenoh link password of a team: HKDF-SHA256(team_key, salt b"rescuemesh v1",
    info b"zenoh link password", 16 bytes). The team key itself never reaches Zenoh."""
    return hkdf_sha256(team_key, FRAME_KEY_SALT, LINK_PASSWORD_INFO, LINK_PASSWORD_BYTES)


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


def presence_key(team: str, address: int) -> str:
    """The liveliness token of robot `address`'s link: declared once it hears the team's air."""
    air_key(team, address)
    return f"{KEY_PREFIX}/{team}/present/{address}"


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


def session_config(listen: Sequence[str] = (), connect: Sequence[str] = (), *,
                   max_message_bytes: int | None = None, user: str | None = None, password: str | None = None,
                   dictionary_file: str | None = None, scouting_delay_ms: int | None = None) -> zenoh.Config:
    """A peer-to-peer session config: peer mode, explicit `listen` and `connect` endpoints
    (`tcp/IP:PORT`), multicast scouting off (robots find each other only through the endpoints
    they are given, and through gossip over the sessions those open, one hop). Connect attempts are
    retried in the background, CONNECT_RETRY apart (a peer that starts later, or comes back in range,
    is reached within about 2 s of it listening).

    `max_message_bytes`: the longest message Zenoh accepts from a peer (default: Zenoh's own, 1 GiB;
    a link gives LINK_MAX_MESSAGE_BYTES), shared memory off with it. `user`, `password` and
    `dictionary_file` (a file of `user:password` lines that must exist when the session opens):
    Zenoh's user-password authentication of every peer (open_session writes the file for you).
    `scouting_delay_ms`: how long opening waits to discover peers before it returns (Zenoh's default
    in peer mode is 500 ms; with explicit endpoints a link needs none)."""
    listen = [check_endpoint(e) for e in listen]
    connect = [check_endpoint(e) for e in connect]
    if not listen and not connect:
        raise ValueError("a robot needs at least one --listen or --connect endpoint")
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("listen/endpoints", json.dumps(listen))
    config.insert_json5("connect/endpoints", json.dumps(connect))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("scouting/gossip/multihop", "false")
    config.insert_json5("connect/retry", json.dumps(CONNECT_RETRY))
    if scouting_delay_ms is not None:
        config.insert_json5("scouting/delay", str(int(scouting_delay_ms)))
    if max_message_bytes is not None:
        if not (isinstance(max_message_bytes, int) and 1024 <= max_message_bytes <= 1 << 30):
            raise ValueError(f"max_message_bytes must be 1024..2**30, got {max_message_bytes!r}")
        config.insert_json5("transport/link/rx/max_message_size", str(max_message_bytes))
        config.insert_json5("transport/shared_memory/enabled", "false")
    auth = (user, password, dictionary_file)
    if any(v is not None for v in auth):
        if not all(isinstance(v, str) and v for v in auth):
            raise ValueError("user-password authentication needs user, password and dictionary_file")
        config.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
        config.insert_json5("transport/auth/usrpwd/password", json.dumps(password))
        config.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(dictionary_file))
    return config


def open_session(team: str, listen: Sequence[str] = (), connect: Sequence[str] = (), *,
                 secret: bytes | None = None, max_message_bytes: int | None = LINK_MAX_MESSAGE_BYTES
                 ) -> zenoh.Session:
    """Open a link session (session_config) for `team`. With `secret` (link_secret of the team key),
    every peer must prove it: user `rescuemesh-TEAM`, password the secret in hex; the dictionary
    Zenoh reads at opening lives in a private temporary folder (0700) removed once the session is
    open. Raises zenoh.ZError when Zenoh cannot open, ValueError for bad arguments."""
    check_team(team)
    if secret is None:
        return zenoh.open(session_config(listen, connect, max_message_bytes=max_message_bytes,
                                         scouting_delay_ms=LINK_SCOUTING_DELAY_MS))
    if not (isinstance(secret, bytes) and len(secret) >= 16):
        raise ValueError("the link secret must be at least 16 bytes")
    user, password = f"{KEY_PREFIX}-{team}", secret.hex()
    folder = tempfile.mkdtemp(prefix="rescuemesh-link-")  # mode 0700
    try:
        path = os.path.join(folder, "usrpwd")
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
        with os.fdopen(fd, "w", encoding="ascii") as handle:
            handle.write(f"{user}:{password}\n")
        return zenoh.open(session_config(listen, connect, max_message_bytes=max_message_bytes,
                                         user=user, password=password, dictionary_file=path,
                                         scouting_delay_ms=LINK_SCOUTING_DELAY_MS))
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@dataclass
class LinkStats:
    """What crossed the link: frames and bytes put and heard; heard frames dropped because they were
    our own echo, too long, or the queues were full (one of the longest source's); puts that Zenoh
    refused."""

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
    is heard or the timeout passes, and `drain(limit)` for the frames heard (round-robin over their
    sources when more than `limit` wait). `close()` undeclares the publisher and subscriber, and
    closes the session when the link opened it.
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
        self._lock = threading.Lock()
        # a token per frame that found the queues empty: wakes wait() (a Handoff: a threading Event's
        # Python-level Condition cost a round trip 0.3 ms more on a loaded machine, and a SimpleQueue's
        # timed wait can block forever after a signal: transport/handoff.py)
        self._wake: Handoff[None] = Handoff()
        self._queues: dict[str, deque[tuple[int, bytes]]] = {}  # key -> (arrival number, frame)
        self._waiting = 0
        self._arrivals = 0
        self._joined = threading.Event()  # another robot's presence token arrived (new_peers)
        self._closed = False
        # express: no batching (a 20-byte frame leaves at once); DROP: a congested link drops
        # frames like a busy radio instead of blocking the robot's loop (the protocol retries)
        self._publisher = session.declare_publisher(self.key, express=True,
                                                    congestion_control=zenoh.CongestionControl.DROP)
        self._subscriber = session.declare_subscriber(air_wildcard(team), self._on_sample,
                                                      allowed_origin=zenoh.Locality.REMOTE)
        self._presence_key = presence_key(team, address)
        liveliness = session.liveliness()
        self._presence = liveliness.declare_subscriber(f"{KEY_PREFIX}/{team}/present/*", self._on_presence,
                                                       history=True)
        self._token = liveliness.declare_token(self._presence_key)  # after the subscriber: we hear now

    @classmethod
    def open(cls, team: str, address: int, *, listen: Sequence[str] = (), connect: Sequence[str] = (),
             max_queue: int = DEFAULT_MAX_QUEUE, secret: bytes | None = None) -> "ZenohLink":
        """Open a peer session (open_session: LINK_MAX_MESSAGE_BYTES, peers authenticated with
        `secret` when given) and the link on it; close() closes both."""
        session_config(listen, connect)  # ValueError before a session opens
        air_key(team, address)
        session = open_session(team, listen, connect, secret=secret)
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
        if self._waiting or timeout_s is not None and timeout_s <= 0:
            return self._waiting > 0
        try:
            self._wake.get(timeout=timeout_s)
        except queue.Empty:
            return False
        return self._waiting > 0  # a token left from frames drained since is no frame

    def drain(self, limit: int | None = None) -> list[bytes]:
        """Frames heard and not yet drained, oldest first: all of them, or at most `limit` taken
        round-robin over their sources (each source's oldest first; the rest wait for the next call)."""
        with self._lock:
            queues = [q for q in self._queues.values() if q]
            if limit is None or self._waiting <= limit:
                taken = [item for q in queues for item in q]
                for q in queues:
                    q.clear()
            else:
                taken = []
                while len(taken) < limit:
                    for q in queues:
                        if q and len(taken) < limit:
                            taken.append(q.popleft())
                    queues = [q for q in queues if q]
            self._waiting -= len(taken)
            if not self._waiting:
                self._queues.clear()
        if not self._waiting:  # tokens of frames taken now; wait() looks at _waiting before any token
            try:
                while True:
                    self._wake.get_nowait()
            except queue.Empty:
                pass
        taken.sort(key=lambda item: item[0])
        return [frame for _, frame in taken]

    def new_peers(self) -> bool:
        """True when a robot's link came (or came back) on the team's air since the previous call: its
        presence token, declared after its subscriber, reached us, so it hears what we send now. The
        robot's loop then announces itself at once instead of at its next Heartbeat. (A token admits
        nobody: only frames that open under the team key count for the mesh.)"""
        if not self._joined.is_set():
            return False
        self._joined.clear()
        return True

    def close(self, timeout_s: float = CLOSE_TIMEOUT_S) -> bool:
        """Stop sending and hearing; close the session if this link opened it. Bounded: returns
        False when Zenoh did not finish within `timeout_s` s (its threads are left to the exit)."""
        if self._closed:
            return True
        self._closed = True

        def shut() -> None:
            for entity in (self._token, self._presence, self._subscriber, self._publisher):
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

    def _on_presence(self, sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT and str(sample.key_expr) != self._presence_key:
            self._joined.set()

    def _on_sample(self, sample: zenoh.Sample) -> None:
        stats = self.stats
        key = str(sample.key_expr)
        if key == self.key:  # our own frame (another session of ours, or a clone)
            stats.echoes_dropped += 1
            return
        payload = sample.payload
        if len(payload) > MAX_FRAME_BYTES:  # before any copy
            stats.oversize_dropped += 1
            return
        frame = payload.to_bytes()
        with self._lock:
            if self._waiting >= self._max_queue:
                longest = max(self._queues.values(), key=len)
                mine = self._queues.get(key)
                if mine is None or len(mine) >= len(longest):  # the arriving frame's source holds most
                    stats.overflow_dropped += 1
                    return
                evicted = longest.pop()[1]  # the newest of the source holding most makes room
                self._waiting -= 1
                stats.overflow_dropped += 1
                stats.frames_received -= 1
                stats.bytes_received -= len(evicted)
            queue = self._queues.get(key)
            if queue is None:
                queue = self._queues[key] = deque()
            self._arrivals += 1
            queue.append((self._arrivals, frame))
            self._waiting += 1
            stats.frames_received += 1
            stats.bytes_received += len(frame)
            if self._waiting == 1:
                self._wake.put(None)
