"""The control plane over pipes, for the robot processes a world starts itself (`run --processes`).

Owns: the framing of sealed control messages on a byte stream (a 4-byte big-endian length, then the
message), reading it with a time limit, the world's caller over each robot's pair of pipes
(`PipeCaller`) and the world's host with WorldHost's interface but no Zenoh session (`PipeHost`).
Must not know: what the messages mean (control_messages.py), how they are sealed (control.py), how
the processes are started (spawn.py hands over the pipes' ends it keeps).

Why pipes: a round of calls over Zenoh costs the world about 0.4 ms for three robots on the 2-core
machine (a put, the robot's Zenoh thread, the reply's put, the world's Zenoh thread handing the reply
to the loop), against about 0.04 ms over pipes (a write and a blocking read each way, no thread in
between). The lockstep makes several rounds per tick, so this is most of what a run in processes
costs beyond the one-process run (docs/processes.md, "Speed").

Only the world and the one robot process it started hold a pair's ends (os.pipe's descriptors are not
inherited by other children), so nothing else on the machine or the network can write to or read a
robot's control plane. The messages are sealed all the same: one code path checks every request and
reply, whatever carries it.
"""

from __future__ import annotations

import os
import queue
import select
import struct
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from rescuemesh.runtime.processes.control import CALL_TIMEOUT_S, MAX_SEALED_BYTES, Caller, ControlError, ControlKey
from rescuemesh.runtime.processes.spawn import ControlCarrier

__all__ = ["READY", "PipeCaller", "PipeChannel", "PipeHost", "PipeReader", "write_frame"]

_LENGTH = struct.Struct(">I")
_READ_BYTES = 1 << 20
#: A robot process's first message on its reply pipe, once it has imported and can answer (what its
#: liveliness token says over Zenoh): until then the world does not call it, so a robot that takes
#: long to start costs the world no wait.
READY = b"rescuemesh robot ready"


def write_frame(fd: int, message: bytes) -> None:
    """Write one message to `fd` whole (a blocking pipe may take a long one in parts). BrokenPipeError
    (an OSError) when the other end is closed."""
    if len(message) > MAX_SEALED_BYTES:
        raise ControlError(f"{len(message)} bytes: over the control message limit")
    view = memoryview(_LENGTH.pack(len(message)) + message)
    while view:
        view = view[os.write(fd, view):]


class PipeReader:
    """The messages arriving on one pipe, each whole, oldest first."""

    def __init__(self, fd: int, limit: int = MAX_SEALED_BYTES) -> None:
        self.fd, self.limit = fd, limit
        self.ended = False  # the writer closed its end (its process is gone) and all was read
        self._buffer = bytearray()
        self._poll = select.poll()
        self._poll.register(fd, select.POLLIN)

    def next(self, timeout_s: float | None) -> bytes | None:
        """The next message; None when the writer is gone. queue.Empty when none came within
        `timeout_s` s (None: no limit); ControlError for a length over the limit (the stream cannot
        be read on after it)."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            message = self._message()
            if message is not None:
                return message
            if self.ended:
                return None
            wait_ms = None if deadline is None else max(0, int((deadline - time.monotonic()) * 1000 + 0.999))
            if not self._poll.poll(wait_ms):
                if deadline is None or time.monotonic() < deadline:
                    continue  # woken early (a signal): wait out the rest
                raise queue.Empty
            try:
                chunk = os.read(self.fd, _READ_BYTES)
            except OSError:
                chunk = b""
            if chunk:
                self._buffer += chunk
            else:
                self.ended = True
                if self._buffer:
                    self._buffer.clear()  # a message cut off by the writer's end is no message

    def hung_up(self) -> bool:
        """Whether the writer has closed its end (looks without reading or waiting)."""
        if self.ended:
            return True
        return any(events & select.POLLHUP for _, events in self._poll.poll(0))

    def _message(self) -> bytes | None:
        buffer = self._buffer
        if len(buffer) < _LENGTH.size:
            return None
        (length,) = _LENGTH.unpack_from(buffer)
        if length > self.limit:
            raise ControlError(f"a control message of {length} bytes announced: over the {self.limit} byte limit")
        end = _LENGTH.size + length
        if len(buffer) < end:
            return None
        message = bytes(buffer[_LENGTH.size:end])
        del buffer[:end]
        return message

    def close(self) -> None:
        """Close the pipe's end (once: the number may be another file's afterwards)."""
        if self.fd >= 0:
            fd, self.fd = self.fd, -1
            self.ended = True
            os.close(fd)


@dataclass
class PipeChannel:
    """The world's ends of one robot process's pipes: requests go into `to_robot`, replies come from
    `from_robot`. `process` is the robot's (a subprocess.Popen) when the world started it."""

    to_robot: int
    from_robot: PipeReader
    process: Any = None
    ready: bool = False  # the robot said READY
    broken: str | None = None  # why this channel is useless (its first message was not READY)

    def check_ready(self) -> bool:
        """Whether the robot has said READY (looks without waiting)."""
        if not self.ready and self.broken is None and not self.from_robot.ended:
            try:
                first = self.from_robot.next(0.0)
            except queue.Empty:
                return False
            except ControlError as error:
                self.broken = str(error)
                return False
            if first == READY:
                self.ready = True
            elif first is not None:
                self.broken = f"its first message was {len(first)} bytes, not READY"
        return self.ready

    def alive(self) -> bool:
        return (self.check_ready() and not self.from_robot.hung_up()
                and (self.process is None or self.process.poll() is None))

    def close(self) -> None:
        """Close the world's ends (once each)."""
        if self.to_robot >= 0:
            fd, self.to_robot = self.to_robot, -1
            os.close(fd)
        self.from_robot.close()


class PipeCaller(Caller):
    """The world's calls to robots over each robot's channel in `channels` (a mapping the starter
    keeps up to date: a robot started again has a new channel)."""

    gone_because = "its control pipe closed"

    def __init__(self, channels: Mapping[str, PipeChannel], control_key: ControlKey, *,
                 timeout_s: float = CALL_TIMEOUT_S) -> None:
        super().__init__(control_key, timeout_s=timeout_s)
        self._channels = channels
        self._bound: dict[str, PipeChannel] = {}

    def expect(self, robot: str) -> None:
        """Talk to robot `robot`'s newest process from now on."""
        channel = self._channels.get(robot)
        if channel is None:
            raise ControlError(f"{robot} has no robot process started by this world")
        self._bound[robot] = channel

    def _channel(self, robot: str) -> PipeChannel:
        if robot not in self._bound:
            self.expect(robot)
        return self._bound[robot]

    def _put(self, robot: str, payload: bytes) -> None:
        try:
            write_frame(self._channel(robot).to_robot, payload)
        except OSError as error:
            raise ControlError(f"{robot}'s process is gone (its control pipe: {error.strerror})") from None

    def _take(self, robot: str, timeout_s: float) -> bytes | None:
        return self._channel(robot).from_robot.next(timeout_s)

    def close(self) -> None:
        """Nothing of its own: the starter closes the channels."""


class PipeHost:
    """WorldHost's interface for robots started by this world and spoken to over pipes: the joins
    are the channels the starter opened, once their robot said READY (a robot started again joins
    again); a robot is lost when its pipe closes. No Zenoh session: no liveliness tokens and no
    published clock."""

    def __init__(self, channels: Mapping[str, PipeChannel], control_key: bytes, *, log_dir=None) -> None:
        self.channels = channels
        self.client = PipeCaller(channels, ControlKey(control_key))
        self.carrier = ControlCarrier.PIPES
        self.join_hint = f"their output is in {log_dir}" if log_dir is not None else "they were started by this world"
        self._seen: dict[str, PipeChannel] = {}

    def take_events(self) -> list[tuple[str, bool]]:
        """Robots whose process was started (again) and has said READY since the last call: (name,
        True) each. A process still importing is looked at again at the next call."""
        events = []
        for name, channel in list(self.channels.items()):
            if self._seen.get(name) is not channel and channel.check_ready():
                self._seen[name] = channel
                events.append((name, True))
        return events

    def alive(self) -> set[str]:
        return {name for name, channel in list(self.channels.items()) if channel.alive()}

    def wait_for(self, names: Iterable[str], timeout_s: float) -> bool:
        wanted = set(names)
        return self._wait(lambda alive: wanted <= alive, timeout_s)

    def wait_for_any(self, names: Iterable[str], timeout_s: float) -> bool:
        wanted = set(names)
        return self._wait(lambda alive: bool(wanted & alive), timeout_s)

    def _wait(self, predicate, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while not predicate(self.alive()):
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)
        return True

    def publish_clock(self, now: float) -> None:
        """No clock without a Zenoh session (`--control zenoh` publishes one)."""

    def close(self) -> None:
        self.client.close()
