"""The control plane between a world process and its robot processes, over Zenoh.

Owns: the key expressions, the Zenoh session settings (peer to peer, explicit endpoints, no
multicast scouting), authenticated request/reply calls (the world publishes a request on a robot's
request key, the robot answers on its reply key), liveliness tokens that tell each side the other is gone, and what a refused message costs: one
log line and a count. Must not know: what the calls mean (runtime/processes/robot_process.py and
runtime/processes/process_world.py do), how values are written (runtime/processes/control_codec.py).

Every message is sealed: a keyed BLAKE2b tag (RFC 7693, 16 bytes; version 1 used HMAC-SHA256) over
a header (version, direction, the world's run nonce, a counter, the robot's name) and the body,
under a key derived from the team key with its own HKDF label; the team key never crosses the wire.
A request counts only if its counter is above the last one the robot accepted from this run; a reply
counts only if it echoes the request's nonce, counter and robot. Nothing is decoded before its tag
checks, and the decoder builds only the registered types (no pickle). docs/processes.md has the
threat model.

Protocol frames between robots never travel here: in a simulated world they cross the world's radio
medium, on a real network the Zenoh link (transport/zenoh_link.py).
"""

from __future__ import annotations

import hashlib
import hmac
import itertools
import logging
import os
import queue
import struct
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from rescuemesh.mesh.keys import hkdf_sha256
from rescuemesh.runtime.processes import control_messages as msg
from rescuemesh.runtime.processes.control_codec import MAX_MESSAGE_BYTES, CodecError, decode, encode
from rescuemesh.transport.handoff import Handoff
from rescuemesh.transport.zenoh_link import check_endpoint, session_config

__all__ = ["CALL_TIMEOUT_S", "MAX_SEALED_BYTES", "Answerer", "CallClient", "CallServer", "Caller", "ControlError",
           "ControlKey", "Keys", "Liveliness",
           "PUBLIC_CONTROL_KEY", "RemoteError", "check_endpoint", "control_key_from_team_key", "open_session"]

log = logging.getLogger("rescuemesh.control")

#: How long one call waits for its reply, in s: a robot that does not answer in this time is gone.
CALL_TIMEOUT_S = 20.0
#: HKDF salt and info of the control-plane key (a use of the team key of its own: docs/security.md).
CONTROL_KEY_SALT, CONTROL_KEY_INFO = b"rescuemesh v1", b"process control plane authentication"
#: The environment variable a spawned robot process reads its run's control key from (hex).
CONTROL_KEY_ENV = "RESCUEMESH_CONTROL_KEY"

#: The sealed message's version: 2 since records and tuples are tagged arrays in the body
#: (runtime/processes/control_codec.py) and the tag is keyed BLAKE2b, not HMAC-SHA256 (half the
#: cost: in a robot process woken once per request, HMAC through OpenSSL was about 45 us of a
#: request's 100 us of sealing and coding). A world and a robot of different versions refuse each other.
_VERSION = 2
_TAG_BYTES = 16
_HEADER = struct.Struct(">BB16sQB")  # version, direction, run nonce, counter, length of the robot's name
_REQUEST, _REPLY = 1, 2
#: Replies waiting for one robot's call at most; more are refused (a flood on its reply key).
_MAX_WAITING = 256
#: Requests and replies are sent at once (not batched) and never dropped under congestion.
_PROMPT = {"congestion_control": zenoh.CongestionControl.BLOCK, "express": True}
#: Refusals logged one by one; after these, one line per power of ten (a flood is not a log flood).
_LOGGED_REFUSALS = 20


def control_key_from_team_key(team_key: bytes) -> bytes:
    """The control plane's 32-byte MAC key: HKDF-SHA256(team key, salt b"rescuemesh v1",
    info b"process control plane authentication")."""
    return hkdf_sha256(team_key, CONTROL_KEY_SALT, CONTROL_KEY_INFO, 32)


#: The key of a world and robots run by hand without a key file: public (it is in this source), so
#: it keeps out a stray or naive peer only. Give both sides --key FILE on a network (docs/processes.md).
PUBLIC_CONTROL_KEY = hkdf_sha256(b"", CONTROL_KEY_SALT, b"process control plane public development key", 32)


class ControlError(RuntimeError):
    """The control plane failed: a peer is gone, did not answer in time, or sent what we refuse."""


class RemoteError(RuntimeError):
    """A call raised inside the robot process; the message carries the robot's traceback."""


class Refusals:
    """Messages refused (forged, replayed, malformed, unexpected): counted, and logged one line each
    (the first ones; then one line per power of ten)."""

    def __init__(self, who: str) -> None:
        self.who, self.count = who, 0
        self._lock = threading.Lock()

    def refuse(self, reason: str) -> None:
        with self._lock:
            self.count += 1
            count = self.count
        if count <= _LOGGED_REFUSALS or str(count).rstrip("0") == "1":
            log.warning("%s: refused a control message (%d so far): %s", self.who, count, reason)


class ControlKey:
    """Seals and opens control messages with one run's key."""

    def __init__(self, key: bytes) -> None:
        if len(key) < 16:
            raise ValueError("a control key has at least 16 bytes")
        self._key = bytes(key)

    def _tag(self, signed: bytes) -> bytes:
        """The tag of `signed` (header and body): keyed BLAKE2b, 16 bytes (RFC 7693)."""
        return hashlib.blake2b(signed, key=self._key, digest_size=_TAG_BYTES).digest()

    def seal(self, direction: int, nonce: bytes, counter: int, robot: str, body: bytes) -> bytes:
        name = robot.encode()
        signed = _HEADER.pack(_VERSION, direction, nonce, counter, len(name)) + name + body
        return self._tag(signed) + signed

    def open(self, data: bytes) -> tuple[int, bytes, int, str, bytes]:
        """(direction, nonce, counter, robot, body) of an authentic message; ControlError otherwise."""
        if len(data) < _TAG_BYTES + _HEADER.size:
            raise ControlError(f"{len(data)} bytes: too short to be a control message")
        tag, signed = data[:_TAG_BYTES], data[_TAG_BYTES:]
        if not hmac.compare_digest(tag, self._tag(signed)):
            raise ControlError("not authenticated with this run's control key")
        version, direction, nonce, counter, length = _HEADER.unpack_from(signed)
        if version != _VERSION:
            raise ControlError(f"control message version {version}, expected {_VERSION}")
        end = _HEADER.size + length
        try:
            robot = signed[_HEADER.size:end].decode()
        except UnicodeDecodeError:
            raise ControlError("a robot name that is not UTF-8") from None
        return direction, nonce, counter, robot, signed[end:]


@dataclass(frozen=True)
class Keys:
    """The key expressions of one run (docs/processes.md): `rescuemesh/<run>/...`."""

    run: str = "default"

    def __post_init__(self) -> None:
        if not self.run or any(c in self.run for c in "/*$?#"):
            raise ValueError(f"run id must be a non-empty name without / * $ ? #, got {self.run!r}")

    @property
    def world_alive(self) -> str:
        return f"rescuemesh/{self.run}/world/alive"

    @property
    def clock(self) -> str:
        return f"rescuemesh/{self.run}/clock"

    @property
    def robots_alive(self) -> str:
        return f"rescuemesh/{self.run}/robot/*/alive"

    def robot_alive(self, name: str) -> str:
        return f"rescuemesh/{self.run}/robot/{name}/alive"

    def robot_request(self, name: str) -> str:
        return f"rescuemesh/{self.run}/robot/{name}/request"

    def robot_reply(self, name: str) -> str:
        return f"rescuemesh/{self.run}/robot/{name}/reply"

    @property
    def robots_reply(self) -> str:
        return f"rescuemesh/{self.run}/robot/*/reply"

    @staticmethod
    def robot_of(key: str) -> str:
        """The robot name in a `.../robot/<name>/alive` (or `/reply`) key."""
        parts = str(key).split("/")
        return parts[-2]


def open_session(*, listen: list[str] = (), connect: list[str] = ()) -> zenoh.Session:
    """A Zenoh peer that listens and connects only where told, multicast scouting off: the same
    session settings as the robots' frame link (transport/zenoh_link.py), with room for the largest
    control message (a set-up carries the occupancy grid)."""
    config = session_config(listen, connect)  # ValueError for a bad endpoint
    config.insert_json5("transport/link/rx/max_message_size", str(MAX_MESSAGE_BYTES + 4096))
    try:
        return zenoh.open(config)
    except zenoh.ZError as error:
        raise ControlError(f"cannot open a Zenoh session (listen {list(listen)}, connect {list(connect)}): "
                           f"{str(error).splitlines()[0]}") from None


#: The longest sealed message either carrier takes: the codec's limit, the seal and the longest name.
MAX_SEALED_BYTES = MAX_MESSAGE_BYTES + _TAG_BYTES + _HEADER.size + 255


def _payload(carrier) -> bytes:
    payload = carrier.payload
    if payload is None:
        return b""
    if len(payload) > MAX_SEALED_BYTES:
        raise ControlError(f"{len(payload)} bytes: over the control message limit")
    return payload.to_bytes()


class Answerer:
    """A robot's side of the plane, whatever carries it: an authenticated request from its world in,
    the sealed reply out (`handler` answers it). A request that is forged, replayed, malformed or not
    for this robot is refused (logged, counted) and not answered.

    A set-up must carry this process's nonce (its answer to a Hello), so a set-up recorded in another
    run is refused; the set-up binds the world's run nonce, and from then on each request's counter
    must exceed the last one accepted."""

    def __init__(self, name: str, control_key: ControlKey, handler: Callable[[Any], Any]) -> None:
        self.name, self.control_key, self.handler = name, control_key, handler
        self.nonce = os.urandom(16)  # this process's: a set-up must echo it
        self.refusals = Refusals(name)
        self.calls = 0
        self._world: bytes | None = None  # the run nonce of the world that set us up
        self._last = 0

    def answer(self, data: bytes) -> bytes | None:
        """The sealed reply to one request, or None for a request refused."""
        try:
            direction, nonce, counter, robot, body = self.control_key.open(data)
            if direction != _REQUEST or robot != self.name:
                raise ControlError(f"a {'reply' if direction == _REPLY else 'message'} for {robot!r} on {self.name}'s key")
            request = decode(body)
            if type(request) not in msg.ANSWERS:
                raise ControlError(f"{type(request).__name__} is not a request")
            if isinstance(request, msg.RobotSetup):
                if request.robot_nonce != self.nonce:
                    raise ControlError("a set-up that does not echo this process's nonce (replayed?)")
                if nonce == self._world and counter <= self._last:
                    raise ControlError(f"replayed set-up (counter {counter} <= {self._last})")
                self._world = nonce
            elif not isinstance(request, msg.Hello):
                if nonce != self._world:
                    raise ControlError("a request from another run than the one that set this robot up")
                if counter <= self._last:
                    raise ControlError(f"replayed request (counter {counter} <= {self._last})")
        except (ControlError, CodecError) as error:
            self.refusals.refuse(str(error))
            return None
        if not isinstance(request, msg.Hello):
            self._last = counter
        self.calls += 1
        try:
            reply = msg.HelloReply(self.nonce) if isinstance(request, msg.Hello) else self.handler(request)
            payload = encode(reply)
        except Exception as error:  # the caller re-raises it: one robot's bug is not this plane's
            import traceback

            payload = encode(msg.ErrorReply(f"{type(error).__name__}: {error}", traceback.format_exc()))
        return self.control_key.seal(_REPLY, nonce, counter, self.name, payload)


class CallServer(Answerer):
    """A robot's side over Zenoh: requests on its request key, answered at once on Zenoh's thread,
    one at a time (the brain is not thread-safe), on its reply key."""

    def __init__(self, session: zenoh.Session, keys: Keys, name: str, control_key: ControlKey,
                 handler: Callable[[Any], Any]) -> None:
        super().__init__(name, control_key, handler)
        self._lock = threading.Lock()
        self._closed = False
        self._publisher = session.declare_publisher(keys.robot_reply(name), **_PROMPT)
        self._subscriber = session.declare_subscriber(keys.robot_request(name), self._on_request)

    def _on_request(self, sample) -> None:
        with self._lock:
            try:
                reply = self.answer(_payload(sample))
            except ControlError as error:  # over the size limit
                self.refusals.refuse(str(error))
                return
            if reply is not None and not self._closed:
                try:
                    self._publisher.put(reply)
                except zenoh.ZError:
                    pass  # the session is closing

    def close(self) -> None:
        """Stop answering. The reply to the last request (a Bye) may still be going out on Zenoh's
        thread: the publisher is undeclared only after it (undeclaring it during a put raised
        'Already borrowed' and left the process hanging)."""
        self._subscriber.undeclare()
        with self._lock:
            self._closed = True
            self._publisher.undeclare()


class Caller:
    """The world's side of the plane, whatever carries it: calls to robots by name, one at a time or
    to several at once. A reply that does not authenticate as the robot asked, for this call, is
    dropped and counted. A carrier supplies `_put` (send one sealed request) and `_take` (the next
    message from a robot, None when its process is gone, queue.Empty after `timeout_s`)."""

    def __init__(self, control_key: ControlKey, *, timeout_s: float = CALL_TIMEOUT_S) -> None:
        self.control_key, self.timeout_s = control_key, timeout_s
        self.nonce = os.urandom(16)  # this run's
        self.refusals = Refusals("world")
        self.calls = 0
        #: Requests sent, by type, and rounds waited for (a call, or one call_all of several robots).
        self.requests: Counter[str] = Counter()
        self.rounds: Counter[str] = Counter()
        self._counter = itertools.count(1)

    def expect(self, robot: str) -> None:
        """Robot `robot` (re)joins: forget what its previous process left (late replies, its leaving)."""

    def _put(self, robot: str, payload: bytes) -> None:
        raise NotImplementedError

    def _take(self, robot: str, timeout_s: float) -> bytes | None:
        raise NotImplementedError

    def call(self, robot: str, request: Any, *, timeout_s: float | None = None) -> Any:
        self.rounds[type(request).__name__] += 1
        return self._result(robot, request, self._send(robot, request, timeout_s))

    def call_all(self, requests: dict[str, Any], *, tolerate: bool = False) -> dict[str, Any]:
        """The same moment's calls to several robots, sent together, answered in parallel. With
        `tolerate`, a robot that does not answer gets its ControlError as its value instead of raising."""
        for request in requests.values():
            self.rounds[type(request).__name__] += 1
            break
        pending = {}
        answers = {}
        for robot, request in requests.items():
            try:
                pending[robot] = (request, self._send(robot, request, None))
            except ControlError as error:
                if not tolerate:
                    raise
                answers[robot] = error
        for robot, (request, sent) in pending.items():
            try:
                answers[robot] = self._result(robot, request, sent)
            except ControlError as error:
                if not tolerate:
                    raise
                answers[robot] = error
        return {robot: answers[robot] for robot in requests}

    def _send(self, robot: str, request: Any, timeout_s: float | None):
        self.calls += 1
        self.requests[type(request).__name__] += 1
        counter = next(self._counter)
        self._put(robot, self.control_key.seal(_REQUEST, self.nonce, counter, robot, encode(request)))
        return counter, self.timeout_s if timeout_s is None else timeout_s

    def _result(self, robot: str, request: Any, sent) -> Any:
        counter, timeout_s = sent
        expected = msg.ANSWERS[type(request)]
        deadline = time.monotonic() + timeout_s
        refused = 0
        while True:
            try:
                data = self._take(robot, max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                if refused:
                    raise ControlError(f"{robot} did not answer with the run's control key within {timeout_s:g} s "
                                       f"({refused} repl{'y' if refused == 1 else 'ies'} refused)") from None
                raise ControlError(f"{robot} did not answer within {timeout_s:g} s (its process is gone, or it "
                                   f"does not hold the run's control key?)") from None
            if data is None:
                raise ControlError(f"{robot}'s process is gone ({self.gone_because})")
            try:
                direction, nonce, count, name, body = self.control_key.open(data)
                if direction != _REPLY or nonce != self.nonce or count != counter or name != robot:
                    raise ControlError(f"a reply that is not {robot}'s to call {counter} (replayed or late?)")
                answer = decode(body)
                if isinstance(answer, msg.ErrorReply):
                    raise RemoteError(f"{robot}: {answer.message}\n--- in the robot process ---\n{answer.traceback}")
                if type(answer) is not expected:
                    raise ControlError(f"{type(answer).__name__} does not answer {type(request).__name__}")
                return answer
            except (ControlError, CodecError) as error:
                refused += 1
                self.refusals.refuse(f"reply for {robot}: {error}")

    #: What ends a call when `_take` says the robot's process is gone (each carrier says its own).
    gone_because = "its carrier says so"


class CallClient(Caller):
    """The world's side over Zenoh: requests on each robot's request key, replies from their reply
    keys; any reply beyond _MAX_WAITING queued for one robot (a flood) is dropped and counted."""

    gone_because = "its liveliness token went"

    def __init__(self, session: zenoh.Session, keys: Keys, control_key: ControlKey, *,
                 timeout_s: float = CALL_TIMEOUT_S) -> None:
        super().__init__(control_key, timeout_s=timeout_s)
        self.session, self.keys = session, keys
        self._inbox: dict[str, Handoff] = {}  # a Handoff: its timed wait ends on time after a signal
        self._publishers: dict[str, Any] = {}
        self._subscriber = session.declare_subscriber(keys.robots_reply, self._on_reply)

    def expect(self, robot: str) -> None:
        self._inbox[robot] = Handoff()

    def gone(self, robot: str) -> None:
        """Robot `robot`'s process is gone (its token went): a call waiting for it ends now."""
        inbox = self._inbox.get(robot)
        if inbox is not None:
            inbox.put(None)

    def _on_reply(self, sample) -> None:
        robot = Keys.robot_of(str(sample.key_expr))
        inbox = self._inbox.get(robot)
        try:
            if inbox is None:
                raise ControlError(f"a reply for {robot[:40]!r}, which no call waits for")
            if inbox.qsize() >= _MAX_WAITING:
                raise ControlError(f"more than {_MAX_WAITING} replies waiting for {robot}")
            inbox.put(_payload(sample))
        except ControlError as error:
            self.refusals.refuse(str(error))

    def _put(self, robot: str, payload: bytes) -> None:
        if robot not in self._inbox:
            self.expect(robot)
        publisher = self._publishers.get(robot)
        if publisher is None:
            publisher = self._publishers[robot] = self.session.declare_publisher(self.keys.robot_request(robot),
                                                                                 **_PROMPT)
        publisher.put(payload)

    def _take(self, robot: str, timeout_s: float) -> bytes | None:
        return self._inbox[robot].get(timeout=timeout_s)

    def close(self) -> None:
        self._subscriber.undeclare()
        for publisher in self._publishers.values():
            publisher.undeclare()


class Liveliness:
    """Who is alive: a subscriber to liveliness tokens under `key` with history, so tokens declared
    before we looked count. `alive` is a set of keys; `on_change(key, alive)` runs on Zenoh's thread.
    A token admits nobody by itself: the world still has to hear the robot answer with the key."""

    def __init__(self, session: zenoh.Session, key: str,
                 on_change: Callable[[str, bool], None] | None = None) -> None:
        self.alive: set[str] = set()
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._on_change = on_change
        self._subscriber = session.liveliness().declare_subscriber(key, self._sample, history=True)

    def _sample(self, sample) -> None:
        key, up = str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT
        with self._lock:
            (self.alive.add if up else self.alive.discard)(key)
            self._changed.notify_all()
        if self._on_change is not None:
            self._on_change(key, up)

    def wait_for(self, predicate: Callable[[set[str]], bool], timeout_s: float) -> bool:
        with self._lock:
            return self._changed.wait_for(lambda: predicate(set(self.alive)), timeout=timeout_s)

    def close(self) -> None:
        self._subscriber.undeclare()
