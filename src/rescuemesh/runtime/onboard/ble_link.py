"""The robot link over Bluetooth LE for a robot process: `rescuemesh robot --link ble --hci SPEC` moves the
robot's (authenticated) frames over the advertising bearer that `ble-check` uses (transport/ble.py).

Owns: a BleBearer on an asyncio loop of its own thread, and the hand-off between it and the robot's
real-time loop (the FrameLink shape RealtimeLoop and ZenohLink share: send, wait, drain, close, stats).
Must not know: what is inside a frame, robots, clocks.
"""

from __future__ import annotations

import asyncio
import threading
from collections import deque
from dataclasses import asdict, dataclass

#: Frames heard and not yet drained beyond which new ones are dropped (a radio's full receive buffer).
MAX_QUEUE = 1024
#: How long close() waits for the bearer to stop, in s.
CLOSE_TIMEOUT_S = 5.0


@dataclass
class BleLinkStats:
    frames_sent: int = 0
    frames_received: int = 0
    frames_too_long: int = 0  # longer than one advertisement carries: not sent
    frames_dropped: int = 0  # the receive queue was full

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


class BleLink:
    """Robot frames over one Bluetooth LE controller. `BleLink.open(hci_spec)` starts the bearer (raising
    BleSetupError, one line, when the controller cannot be opened); `send`, `wait`, `drain`, `close` as
    ZenohLink's. `hci_spec` is a bumble transport (`usb:0`, `hci-socket:0`, `serial:/dev/ttyACM0,1000000`,
    `tcp-client:127.0.0.1:9001` for a virtual controller served by bumble's controllers app)."""

    def __init__(self, hci_spec: str, *, name: str = "rescuemesh") -> None:
        from rescuemesh.transport.ble import MAX_FRAME_BYTES  # bumble only when a BLE link is asked for

        self.hci_spec, self.name = hci_spec, name
        self.max_frame = MAX_FRAME_BYTES
        self.stats = BleLinkStats()
        self._heard: deque[bytes] = deque()
        self._lock = threading.Lock()
        self._event = threading.Event()
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name=f"ble-{name}", daemon=True)
        self._bearer = None

    @classmethod
    def open(cls, hci_spec: str, *, name: str = "rescuemesh", start_timeout_s: float = 15.0) -> "BleLink":
        link = cls(hci_spec, name=name)
        link._thread.start()
        try:
            asyncio.run_coroutine_threadsafe(link._start(), link._loop).result(start_timeout_s)
        except BaseException:
            link._stop_thread()
            raise
        return link

    async def _start(self) -> None:
        from rescuemesh.transport.ble import BleBearer

        bearer = BleBearer(self.hci_spec, on_frame=self._on_frame, name=self.name)
        await bearer.start()
        self._bearer = bearer

    def _on_frame(self, frame: bytes, rssi_dbm: float | None) -> None:  # the bearer's loop thread
        with self._lock:
            if len(self._heard) >= MAX_QUEUE:
                self.stats.frames_dropped += 1
                return
            self._heard.append(bytes(frame))
            self.stats.frames_received += 1
        self._event.set()

    def send(self, frame: bytes) -> None:
        """Queue `frame` for one advertisement (returns at once)."""
        if not 1 <= len(frame) <= self.max_frame:
            self.stats.frames_too_long += 1
            return
        self.stats.frames_sent += 1
        self._loop.call_soon_threadsafe(self._send, bytes(frame))

    def _send(self, frame: bytes) -> None:
        if self._bearer is not None and self._bearer.started:
            self._bearer.send(frame)

    def wait(self, timeout_s: float | None) -> bool:
        """Block until a frame is heard or `timeout_s` passes; whether frames are waiting."""
        if self._event.wait(timeout_s):
            return True
        return False

    def drain(self, limit: int | None = None) -> list[bytes]:
        """The frames heard since the last drain, oldest first (at most MAX_QUEUE were kept). `limit` is
        the caller's share per wake-up: all are returned, and the real-time loop keeps `limit` of them
        at random, so that a flood does not push genuine frames out from the tail."""
        with self._lock:
            frames = list(self._heard)
            self._heard.clear()
            self._event.clear()
        return frames

    def new_peers(self) -> bool:
        """Whether another robot's link appeared since the last call: an advertising bearer has no
        presence to watch, so never (robots learn each other's epoch from the periodic Heartbeat)."""
        return False

    def close(self, timeout_s: float = CLOSE_TIMEOUT_S) -> bool:
        """Stop the bearer and its thread; whether that finished within `timeout_s` s."""
        clean = True
        if self._bearer is not None:
            try:
                asyncio.run_coroutine_threadsafe(self._bearer.stop(), self._loop).result(timeout_s)
            except Exception:
                clean = False
            self._bearer = None
        self._stop_thread()
        return clean

    def _stop_thread(self) -> None:
        if self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(2.0)
