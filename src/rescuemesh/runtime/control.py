"""The control plane between a world process and its robot processes, over Zenoh.

Owns: the key expressions, the Zenoh session settings (peer to peer, explicit endpoints, no
multicast scouting), request/reply calls (a robot serves a queryable, the world calls it), liveliness
tokens that tell each side the other is gone, and the restricted pickle the calls are encoded with.
Must not know: what the calls mean (runtime/robot_process.py and runtime/process_world.py do).

Protocol frames between robots never travel here: in a simulated world they cross the world's radio
medium, on a real network the Zenoh link (transport/zenoh_link.py). This plane carries simulation
state (poses, scans, calls into a brain) between processes of one run on one trusted host or network;
its decoder refuses any class outside rescuemesh, numpy arrays and plain Python values, so a stray
peer cannot make it run code.
"""

from __future__ import annotations

import builtins
import enum
import io
import pickle
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from rescuemesh.transport.zenoh_link import check_endpoint, session_config

__all__ = ["CALL_TIMEOUT_S", "Answer", "Call", "CallClient", "CallServer", "ControlError", "Keys", "Liveliness",
           "RemoteError", "check_endpoint", "dumps", "loads", "open_session"]

#: How long one call waits for its reply, in s: a robot that does not answer in this time is gone.
CALL_TIMEOUT_S = 20.0

#: Plain values a call may carry besides rescuemesh's own classes.
_SAFE_BUILTINS = frozenset({
    "bool", "bytearray", "bytes", "complex", "dict", "float", "frozenset", "int", "list", "object", "range",
    "set", "slice", "str", "tuple", "ArithmeticError", "AttributeError", "Exception", "IndexError",
    "KeyError", "LookupError", "NotImplementedError", "RuntimeError", "TypeError", "ValueError",
    "ZeroDivisionError",
})
_SAFE_GLOBALS = {
    ("collections", "OrderedDict"), ("collections", "deque"), ("collections", "Counter"),
    ("collections", "defaultdict"), ("copyreg", "_reconstructor"), ("numpy", "dtype"), ("numpy", "ndarray"),
    ("pathlib", "PosixPath"), ("pathlib", "PurePosixPath"),
    ("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
    ("numpy.core.multiarray", "scalar"), ("numpy._core.multiarray", "scalar"),
    ("numpy._core.numeric", "_frombuffer"), ("numpy.core.numeric", "_frombuffer"),
}


class Call(enum.Enum):
    """What the world asks a robot (the first item of every request: `(Call.TICK, now, state)`)."""

    SETUP = "setup"  # (RobotSetup): assemble the robot; answers its stack's timer
    TICK = "tick"  # (now, BodyState): step the brain; answers (transmissions, timer, wheel command)
    FLUSH = "flush"  # (now,): what the stack sends now; answers as TICK does
    RECEIVE = "receive"  # (frame, now, rssi, relay delay): a frame heard; answers (transmissions, timer)
    TIMER = "timer"  # (now,): the stack's timer is due; answers (transmissions, timer)
    GET = "get"  # (path,): read an attribute; answers (Answer, value or None)
    CALL = "call"  # (path, args, kwargs): call a method; answers its value
    STATS = "stats"  # (): pid and CPU time
    BYE = "bye"  # (): halt and leave


class Answer(enum.Enum):
    """What a GET found: data (copied), a method, or another object (read by reference)."""

    VALUE = "value"
    CALLABLE = "callable"
    REFERENCE = "reference"


class ControlError(RuntimeError):
    """The control plane failed: a peer is gone, did not answer in time, or sent what we refuse."""


class RemoteError(RuntimeError):
    """A call raised inside the robot process; the message carries the robot's traceback."""


def _enum_member(cls, name: str):
    """What pickle's `getattr(EnumClass, "MEMBER")` does for an enum member, and nothing else."""
    if isinstance(cls, type) and issubclass(cls, enum.Enum) and cls.__module__.startswith("rescuemesh.") \
            and name in cls.__members__:
        return cls[name]
    raise ControlError(f"refused to decode an attribute {name!r} of {cls!r} from the control plane")


class _SafeUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str):
        if (module, name) == ("builtins", "getattr"):
            return _enum_member
        if module == "rescuemesh" or module.startswith("rescuemesh."):
            return super().find_class(module, name)
        if module == "builtins" and name in _SAFE_BUILTINS:
            return getattr(builtins, name)
        if (module, name) in _SAFE_GLOBALS:
            return super().find_class(module, name)
        raise ControlError(f"refused to decode {module}.{name} from the control plane")


def dumps(value: Any) -> bytes:
    return pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)


def loads(data: bytes) -> Any:
    try:
        return _SafeUnpickler(io.BytesIO(data)).load()
    except ControlError:
        raise
    except Exception as error:  # truncated or garbage bytes
        raise ControlError(f"undecodable control message ({type(error).__name__}: {error})") from None


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

    def robot_rpc(self, name: str) -> str:
        return f"rescuemesh/{self.run}/robot/{name}/rpc"

    @staticmethod
    def robot_of(key: str) -> str:
        """The robot name in a `.../robot/<name>/alive` key."""
        parts = str(key).split("/")
        return parts[-2]


def open_session(*, listen: list[str] = (), connect: list[str] = ()) -> zenoh.Session:
    """A Zenoh peer that listens and connects only where told, multicast scouting off: the same
    session settings as the robots' frame link (transport/zenoh_link.py)."""
    config = session_config(listen, connect)  # ValueError for a bad endpoint
    try:
        return zenoh.open(config)
    except zenoh.ZError as error:
        raise ControlError(f"cannot open a Zenoh session (listen {list(listen)}, connect {list(connect)}): "
                           f"{str(error).splitlines()[0]}") from None


class CallServer:
    """A robot's side: calls arrive on its queryable and wait in a queue for the main thread, which
    answers them one at a time (the brain is not thread-safe). Other wake-ups (the world's token
    gone, a signal) go into the same queue as plain strings."""

    def __init__(self, session: zenoh.Session, key: str) -> None:
        self.inbox: queue.Queue = queue.Queue()
        self._queryable = session.declare_queryable(key, self.inbox.put)

    def wake(self, reason: str) -> None:
        self.inbox.put(reason)

    @staticmethod
    def answer(query, handler: Callable[[Any], Any]) -> None:
        """Decode the call, run `handler`, reply with its value or its exception."""
        try:
            try:
                request = loads(query.payload.to_bytes() if query.payload is not None else b"")
                reply = ("ok", handler(request))
            except Exception as error:  # the caller re-raises it: one robot's bug is not this plane's
                import traceback

                reply = ("error", f"{type(error).__name__}: {error}", traceback.format_exc())
            try:
                payload = dumps(reply)
            except Exception as error:
                payload = dumps(("error", f"reply is not data ({type(error).__name__}: {error})", ""))
            query.reply(query.key_expr, payload)
        finally:
            query.drop()  # the reply completes only when the query is dropped

    def close(self) -> None:
        self._queryable.undeclare()


class CallClient:
    """The world's side: calls to robots by name, one at a time or to several at once."""

    def __init__(self, session: zenoh.Session, keys: Keys, *, timeout_s: float = CALL_TIMEOUT_S) -> None:
        self.session, self.keys, self.timeout_s = session, keys, timeout_s
        self.calls = 0

    def call(self, robot: str, request: Any) -> Any:
        return self._result(robot, self._send(robot, request))

    def call_all(self, requests: dict[str, Any], *, tolerate: bool = False) -> dict[str, Any]:
        """The same moment's calls to several robots, sent together, answered in parallel. With
        `tolerate`, a robot that does not answer gets its ControlError as its value instead of raising."""
        pending = {robot: self._send(robot, request) for robot, request in requests.items()}
        answers = {}
        for robot, handler in pending.items():
            try:
                answers[robot] = self._result(robot, handler)
            except ControlError as error:
                if not tolerate:
                    raise
                answers[robot] = error
        return answers

    def _send(self, robot: str, request: Any):
        self.calls += 1
        return self.session.get(self.keys.robot_rpc(robot), payload=dumps(request), timeout=self.timeout_s)

    def _result(self, robot: str, handler) -> Any:
        try:
            reply = handler.recv()
        except Exception:  # the reply channel closed with no reply: nothing serves that key
            raise ControlError(f"{robot} did not answer (its process is gone?)") from None
        if reply.ok is None:
            raise ControlError(f"{robot} did not answer within {self.timeout_s:g} s")
        answer = loads(reply.ok.payload.to_bytes())
        if answer[0] == "ok":
            return answer[1]
        raise RemoteError(f"{robot}: {answer[1]}\n--- in the robot process ---\n{answer[2]}")


class Liveliness:
    """Who is alive: a subscriber to liveliness tokens under `key` with history, so tokens declared
    before we looked count. `alive` is a set of keys; `on_change(key, alive)` runs on Zenoh's thread."""

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
