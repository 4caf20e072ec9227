"""Handoff: a first-in first-out queue that middleware threads fill and one thread (a robot's loop, the
world's control calls) waits on with a timeout, and whose timed wait ends on time even when a signal
(Ctrl-C, SIGTERM) interrupts it.

Why not `queue.SimpleQueue`: on CPython 3.11, `SimpleQueue.get(timeout=...)` blocks forever when a
signal interrupts its wait and the thread gets the interpreter back after the deadline (another
thread held it). Its retry then waits with a negative time, which the lock takes as "no limit". A
robot process on ROS 2 was seen frozen that way after Ctrl-C, its wheels stopped only by the base's
own cmd_vel timeout (tests/transport/test_handoff.py reproduces it). `threading.Lock.acquire(timeout=...)`
checks its deadline after a signal and gives up. The waits here are made of it. `queue.Queue` would
serve too, but its Python-level Condition costs a robot's loop a slower wake-up.

Owns: the items and the wake-up token (a lock held while no item is announced). Must not know: what
the items are. One thread gets; any number put.
"""

from __future__ import annotations

import queue
import threading
import time
from collections import deque
from typing import Generic, TypeVar

Item = TypeVar("Item")


class Handoff(Generic[Item]):
    """`put` from any thread; `get` (optionally with a timeout) and `get_nowait` from one thread.
    Raises `queue.Empty` as `queue.SimpleQueue` does."""

    def __init__(self) -> None:
        self._items: deque[Item] = deque()
        self._token = threading.Lock()
        self._token.acquire()  # held: nothing announced since the getter last woke

    def put(self, item: Item) -> None:
        self._items.append(item)
        if self._token.locked():
            try:
                self._token.release()  # wakes the getter, or leaves the token for its next wait
            except RuntimeError:  # another putter released it in between: one token is enough
                pass

    def get_nowait(self) -> Item:
        try:
            return self._items.popleft()
        except IndexError:
            raise queue.Empty from None

    def get(self, block: bool = True, timeout: float | None = None) -> Item:
        """The oldest item; waits up to `timeout` s for one (None: no limit). queue.Empty if none came."""
        items = self._items
        if items:
            return items.popleft()
        if not block or timeout is not None and timeout <= 0:
            raise queue.Empty
        deadline = None if timeout is None else time.monotonic() + timeout
        left = -1 if timeout is None else timeout
        while True:
            woke = self._token.acquire(timeout=left)  # a token left by an item already taken wakes it early
            if items:
                return items.popleft()
            if not woke:
                raise queue.Empty
            if deadline is not None:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise queue.Empty

    def qsize(self) -> int:
        """Items waiting (queue.SimpleQueue's name for it)."""
        return len(self._items)
