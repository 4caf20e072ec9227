"""The asyncio pump between one sans-IO network stack and one frame bearer (aioquic's asyncio adapter
shape): frames heard, timers and application calls go into the stack with the loop's clock; frames out go
to the bearer. Owns: the pump and why a frame left (Cause). Must not know: frame layouts, the check's script.
"""

from __future__ import annotations

import asyncio
import inspect
from collections.abc import Callable
from enum import Enum
from typing import Any, Protocol

#: Events pulled from a stack per input: a runaway guard.
MAX_EVENTS_PER_INPUT = 10_000


class Cause(Enum):
    """Why a frame left a stack: the application asked, a received frame was answered, or a timer
    fired (for an Endpoint, a timer frame is always a resend)."""

    APP = "app"
    RECEIVE = "receive"
    TIMER = "timer"


class FrameStack(Protocol):
    """What the pump needs of a stack (the aioquic shape). rescuemesh.protocol.Endpoint has it, and so
    has mesh.NetworkStack, whose receive() also takes rssi_dbm= and relay_delay_s=: the pump passes
    them when the stack's receive() names them."""

    def receive(self, data: bytes, now: float) -> None: ...
    def frames_to_send(self, now: float) -> list[bytes]: ...
    def get_timer(self) -> float | None: ...
    def handle_timer(self, now: float) -> None: ...
    def next_event(self) -> Any: ...


def endpoint_of(stack: FrameStack) -> Any:
    """The protocol endpoint inside `stack`: its `endpoint` attribute (a mesh NetworkStack over an
    Endpoint), or the stack itself (a bare Endpoint)."""
    return getattr(stack, "endpoint", stack)


class FrameSink(Protocol):
    """What the pump needs of a bearer (transport.ble.BleBearer has it)."""

    def send(self, frame: bytes) -> None: ...


class StackPump:
    """Moves frames between one sans-IO stack and one bearer on an asyncio loop (aioquic's asyncio
    adapter shape): each input (a frame heard, a timer, an application call followed by transmit())
    is handed to the stack with `now = loop.time()`; events (the stack's, then its endpoint's when
    that is another object) go to `on_event`; frames out go to the bearer; the stack's timer is
    re-armed with loop.call_at. `relay_delay()` draws a relay delay in s for stacks that take one.
    Errors are kept in `errors`, not raised: the caller is bumble's HCI event handling."""

    def __init__(
        self,
        stack: FrameStack,
        bearer: FrameSink,
        *,
        on_event: Callable[[Any], None] = lambda event: None,
        on_sent: Callable[[bytes, float, Cause], None] = lambda frame, now, cause: None,
        on_received: Callable[[bytes, float], None] = lambda frame, now: None,
        relay_delay: Callable[[], float] = lambda: 0.0,
    ) -> None:
        self.stack = stack
        self.bearer = bearer
        self.errors: list[str] = []
        endpoint = endpoint_of(stack)
        self._event_sources = [stack] if endpoint is stack else [stack, endpoint]
        accepts = inspect.signature(stack.receive).parameters
        self._pass_rssi = "rssi_dbm" in accepts
        self._pass_relay_delay = "relay_delay_s" in accepts
        self._relay_delay = relay_delay
        self._on_event = on_event
        self._on_sent = on_sent
        self._on_received = on_received
        self._loop = asyncio.get_running_loop()
        self._timer: asyncio.TimerHandle | None = None
        self._timer_at: float | None = None
        self._closed = False

    def frame_received(self, data: bytes, rssi_dbm: float | None = None) -> None:
        """The bearer's on_frame callback."""
        if self._closed:
            return
        now = self._loop.time()
        self._guard(self._receive, data, now, rssi_dbm)

    def transmit(self, cause: Cause = Cause.APP) -> None:
        """Send what the stack has queued and re-arm its timer; call after any application call."""
        if self._closed:
            return
        self._guard(self._transmit, cause)

    def close(self) -> None:
        self._closed = True
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _receive(self, data: bytes, now: float, rssi_dbm: float | None) -> None:
        self._on_received(data, now)
        extra: dict[str, Any] = {}
        if self._pass_rssi:
            extra["rssi_dbm"] = rssi_dbm
        if self._pass_relay_delay:
            extra["relay_delay_s"] = self._relay_delay()
        self.stack.receive(data, now, **extra)
        self._drain_events()
        self._transmit(Cause.RECEIVE)

    def _on_timer(self) -> None:
        self._timer, self._timer_at = None, None
        if self._closed:
            return
        self._guard(self._fire_timer)

    def _fire_timer(self) -> None:
        self.stack.handle_timer(self._loop.time())
        self._drain_events()
        self._transmit(Cause.TIMER)

    def _drain_events(self) -> None:
        for source in self._event_sources:
            for _ in range(MAX_EVENTS_PER_INPUT):
                event = source.next_event()
                if event is None:
                    break
                self._on_event(event)
            else:
                raise RuntimeError(f"more than {MAX_EVENTS_PER_INPUT} events from one input")

    def _transmit(self, cause: Cause) -> None:
        now = self._loop.time()
        for frame in self.stack.frames_to_send(now):
            self._on_sent(frame, now, cause)
            self.bearer.send(frame)
        at = self.stack.get_timer()
        if at != self._timer_at:
            if self._timer is not None:
                self._timer.cancel()
            self._timer = None if at is None else self._loop.call_at(at, self._on_timer)
            self._timer_at = at

    def _guard(self, step: Callable[..., None], *args: Any) -> None:
        try:
            step(*args)
        except Exception as exc:  # kept for the report; raising here would land in bumble's HCI loop
            self.errors.append(f"{type(exc).__name__}: {exc}")
