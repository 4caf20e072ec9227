"""The world's stand-ins for robots that run in other processes: a brain (or any object in the
robot) read and called remotely, and a network stack the radio medium can pump.

Owns: turning attribute reads and method calls into control-plane calls, and the stack stand-in's
rule that keeps the medium exact (below). Must not know: Zenoh (it talks to a CallClient), MuJoCo,
scenarios.

The medium calls a stack in a fixed pattern: `receive` or `handle_timer`, then `transmissions` and
`get_timer`. A robot answers `receive` and `handle_timer` with the stack's new transmissions and
timer at once, and the world primes the stand-in with the same pair at every flush (after the
brains ran and the mission script called into them). Between those calls nothing else touches a
robot's stack, so the stand-in's cached answers are what the stack itself would say, one round trip
per event instead of three.
"""

from __future__ import annotations

from typing import Any

from rescuemesh.runtime.control import Answer, Call, ControlError


class RobotGone(ControlError):
    """The robot's process is gone (killed, crashed or left); it may join again."""


class RemoteObject:
    """An object inside robot `robot`'s process at `path` (("brain",), ("stack", "node"), ...).

    Reading an attribute asks the robot: data comes back as a copy, methods as callables that call
    into the robot, other objects as another RemoteObject. Read-only use: scenario scripts and
    reports read what a brain did and call its command methods; they never assign.
    """

    def __init__(self, link, robot: str, path: tuple[str, ...]) -> None:
        object.__setattr__(self, "_link", link)
        object.__setattr__(self, "_robot", robot)
        object.__setattr__(self, "_path", path)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        path = self._path + (name,)
        kind, value = self._link.call(self._robot, (Call.GET, path))
        if kind is Answer.VALUE:
            return value
        if kind is Answer.CALLABLE:
            return _RemoteMethod(self._link, self._robot, path)
        return RemoteObject(self._link, self._robot, path)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"{self._robot}'s {'.'.join(self._path)} runs in another process: it is read-only here")

    def __repr__(self) -> str:
        return f"<{'.'.join(self._path)} of {self._robot} (in its own process)>"


class _RemoteMethod:
    def __init__(self, link, robot: str, path: tuple[str, ...]) -> None:
        self._link, self._robot, self._path = link, robot, path

    def __call__(self, *args, **kwargs) -> Any:
        return self._link.call(self._robot, (Call.CALL, self._path, args, kwargs))


class RemoteStack(RemoteObject):
    """A robot's network stack as the radio medium sees it (transport.sim_medium.NetworkStack)."""

    def __init__(self, link, robot: str, address: int) -> None:
        super().__init__(link, robot, ("stack",))
        object.__setattr__(self, "address", address)
        object.__setattr__(self, "_pending", [])
        object.__setattr__(self, "_timer", None)

    def prime(self, transmissions: list, timer: float | None) -> None:
        """What the robot's stack answered last: handed out by the next transmissions() and get_timer()."""
        object.__setattr__(self, "_pending", list(transmissions))
        object.__setattr__(self, "_timer", timer)

    def receive(self, data: bytes, now: float, *, rssi_dbm: float | None = None, relay_delay_s: float = 0.0) -> None:
        self.prime(*self._link.call_stack(self._robot, (Call.RECEIVE, data, now, rssi_dbm, relay_delay_s)))

    def handle_timer(self, now: float) -> None:
        self.prime(*self._link.call_stack(self._robot, (Call.TIMER, now)))

    def transmissions(self, now: float) -> list:
        pending = self._pending
        object.__setattr__(self, "_pending", [])
        return pending

    def get_timer(self) -> float | None:
        return self._timer
