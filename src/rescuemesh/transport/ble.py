"""The Bluetooth LE advertising bearer: frames as Bluetooth Mesh network PDUs (AD type 0x2A) in
non-connectable advertisements, heard by passive scanning, through bumble's host stack and HCI.
Owns one bumble Device, its HCI transport and the send queue. Must not know what is inside a frame.
"""

# Theory of operation
# ===================
#
# Bluetooth Mesh's advertising bearer (Mesh Profile 1.0, 3.3.1) carries one network PDU of at most
# 29 bytes in one AD structure of type 0x2A ("Mesh Message") inside a legacy, non-connectable,
# non-scannable advertisement (ADV_NONCONN_IND). We do exactly that with our frames:
#
#     advertising data (AdvData, up to 31 bytes) = [1 + n, 0x2A, frame[0] .. frame[n-1]],  n <= 29
#
# Sending: send() only queues (it never blocks). One task takes frames in order; for each it sets
# the advertising data, enables advertising at adv_interval_ms (20 ms, the Core minimum), keeps it
# on air for hold_s = adv_events * adv_interval_ms (3 events, like Zephyr's default Network Transmit
# of 3 transmissions 20 ms apart), then disables it and takes the next frame. The repeats are the
# bearer's own redundancy: each advertising event is one chance for a scanner that was busy
# (switching channel, or transmitting) to hear the frame.
#
# Receiving: the device scans passively (no SCAN_REQ, so nothing leaks onto the air), continuously
# (window = interval = 30 ms, as Zephyr mesh does), with the controller's duplicate filter OFF: it
# would drop a new frame whose bytes happen to equal an earlier one from the same advertiser for
# the whole scan. Each advertising report is parsed as AD structures; every well-formed type-0x2A
# structure of 1..29 bytes is a frame; everything else (other AD types, scan responses, truncated
# structures) is counted and ignored. The bearer never reads inside a frame.
#
# Repeats: one frame sent once arrives adv_events times. The receiver hands the stack only the first
# copy of (advertiser address, bytes); a copy heard less than repeat_window_s (default hold_s + 2
# intervals = 100 ms) after the previous copy of the same key is a repeat. The window slides with
# each copy, so an advertisement that stays on air longer than planned (a late host) still counts
# once. The sender, for its part, keeps the same bytes off the air for repeat_window_s + one
# interval before sending them again, so a deliberate resend of identical bytes is never swallowed.
# Copies from other advertisers (relays) are other keys: dropping those is the mesh network
# cache's job, not the bearer's.
#
# Own frames: a controller may report a node's own advertisements to its own scanner (bumble's
# virtual controllers do not; some real ones do). The bearer drops nothing for that reason: the
# layer above recognises its own frames (the Endpoint counts them as frames_not_for_us).

from __future__ import annotations

import asyncio
import logging
import weakref
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import asdict, dataclass

try:
    from bumble import hci
    from bumble.controller import Controller
    from bumble.device import Advertisement, AdvertisingType, Device
    from bumble.host import Host
    from bumble.link import LocalLink
    from bumble.transport import open_transport
    from bumble.transport.common import AsyncPipeSink, Transport
except ImportError as exc:  # pragma: no cover - depends on the install
    raise ImportError(
        "rescuemesh.transport.ble needs the bumble package: pip install 'rescuemesh[ble]'"
    ) from exc

logger = logging.getLogger(__name__)

#: AD type "Mesh Message" (Bluetooth Assigned Numbers; Mesh Profile 1.0, 3.3.1).
MESH_MESSAGE_AD_TYPE = 0x2A
#: Legacy advertising data is at most 31 bytes (Core 5.x, Vol 6, Part B, 2.3.1.3).
LEGACY_ADV_DATA_BYTES = 31
#: A frame fills one AD structure: 31 bytes less the length and AD-type bytes = the Bluetooth Mesh
#: network-PDU maximum (Mesh Profile 1.0, 3.4.4).
MAX_FRAME_BYTES = LEGACY_ADV_DATA_BYTES - 2
#: Core 4.x required advInterval >= 100 ms for ADV_NONCONN_IND (5.0 lowered it to 20 ms); an old
#: controller answers a shorter interval with "Invalid HCI Command Parameters", and we fall back.
LEGACY_NONCONN_MIN_INTERVAL_MS = 100.0
#: HCI reports this RSSI when the controller has none (Core Vol 4, Part E, 7.7.65.2).
RSSI_NOT_AVAILABLE = 127

FrameCallback = Callable[[bytes, "float | None"], None]


class BleSetupError(RuntimeError):
    """The bearer could not start: bad HCI spec, no such dongle, or a controller that does not answer.
    The message is one line, fit to print."""


@dataclass(frozen=True, slots=True)
class BleTiming:
    """Air-time choices. adv_interval_ms: advertising interval (20 ms is the Core 5.x minimum;
    Vol 6, Part B, 4.4.2.2.1). adv_events: advertising events per frame (Zephyr mesh default: 3
    transmissions, 20 ms apart). scan_interval_ms = scan_window_ms: continuous scanning (Zephyr mesh:
    30 ms). repeat_window_s: a copy of the same bytes from the same advertiser heard within this many
    s of the previous copy is a repeat (None: hold_s + 2 intervals; 0: every copy). max_queue:
    frames waiting to go out before send() drops (counted). start_timeout_s: how long the
    controller may take to reset and start, in s."""

    adv_interval_ms: float = 20.0
    adv_events: int = 3
    scan_interval_ms: float = 30.0
    scan_window_ms: float = 30.0
    repeat_window_s: float | None = None
    max_queue: int = 64
    start_timeout_s: float = 10.0

    def __post_init__(self) -> None:
        if not 20.0 <= self.adv_interval_ms <= 10_240.0:
            raise ValueError(f"adv_interval_ms must be 20..10240, got {self.adv_interval_ms!r}")
        if not (isinstance(self.adv_events, int) and 1 <= self.adv_events <= 50):
            raise ValueError(f"adv_events must be an int 1..50, got {self.adv_events!r}")
        if not 2.5 <= self.scan_window_ms <= self.scan_interval_ms <= 10_240.0:
            raise ValueError("need 2.5 <= scan_window_ms <= scan_interval_ms <= 10240 ms")
        if self.repeat_window_s is not None and not self.repeat_window_s >= 0.0:
            raise ValueError(f"repeat_window_s must be >= 0, got {self.repeat_window_s!r}")
        if not (isinstance(self.max_queue, int) and self.max_queue >= 1):
            raise ValueError(f"max_queue must be an int >= 1, got {self.max_queue!r}")
        if not self.start_timeout_s > 0.0:
            raise ValueError(f"start_timeout_s must be > 0, got {self.start_timeout_s!r}")

    @property
    def hold_s(self) -> float:
        """How long each frame stays on air, in s."""
        return self.adv_events * self.adv_interval_ms / 1000.0

    @property
    def repeat_s(self) -> float:
        """The receiver's repeat window, in s."""
        if self.repeat_window_s is not None:
            return self.repeat_window_s
        return self.hold_s + 2.0 * self.adv_interval_ms / 1000.0


@dataclass(slots=True)
class BearerStats:
    """Counts since start(). A report is one advertising report from the controller."""

    frames_queued: int = 0  # accepted by send()
    frames_dropped: int = 0  # send() found the queue full
    frames_advertised: int = 0  # put on air
    advertise_errors: int = 0  # HCI errors while starting or stopping an advertisement
    reports: int = 0
    scan_responses_ignored: int = 0
    reports_without_frame: int = 0  # no AD type 0x2A (someone else's advertisement)
    malformed_reports: int = 0  # AD structures that overrun the data, or 0x2A of a bad size
    frames_received: int = 0  # handed to on_frame
    repeats_suppressed: int = 0  # further copies of a frame within repeat_window_s
    callback_errors: int = 0  # on_frame raised

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


def advertising_data(frame: bytes) -> bytes:
    """The advertising data that carries `frame`: one AD structure [1 + n, 0x2A, frame]. Raises
    ValueError unless 1 <= n <= MAX_FRAME_BYTES (29)."""
    if not isinstance(frame, (bytes, bytearray, memoryview)):
        raise TypeError(f"frame must be bytes, got {type(frame).__name__}")
    frame = bytes(frame)
    if not 1 <= len(frame) <= MAX_FRAME_BYTES:
        raise ValueError(f"a frame must be 1..{MAX_FRAME_BYTES} bytes, got {len(frame)}")
    return bytes((len(frame) + 1, MESH_MESSAGE_AD_TYPE)) + frame


def mesh_frames(data: bytes) -> tuple[list[bytes], bool]:
    """The frames in advertising data `data` (every AD structure of type 0x2A, 1..29 bytes) and
    whether the data was malformed (a structure overruns it, or a 0x2A structure is empty). Never
    raises for any bytes; a zero length byte ends the significant part (Core Vol 3, Part C, 11)."""
    frames: list[bytes] = []
    offset, size = 0, len(data)
    while offset < size:
        length = data[offset]
        if length == 0:
            break
        end = offset + 1 + length
        if end > size:
            return frames, True
        if data[offset + 1] == MESH_MESSAGE_AD_TYPE:
            if length - 1 < 1:  # an empty frame: nothing to deliver
                return frames, True
            frames.append(bytes(data[offset + 2 : end]))
        offset = end
    return frames, False


# One LocalLink per event loop: virtual controllers in one process hear each other through it.
_SHARED_LINKS: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, LocalLink] = weakref.WeakKeyDictionary()


def shared_virtual_link() -> LocalLink:
    """The LocalLink that `BleBearer(None)` joins by default, one per running event loop."""
    loop = asyncio.get_running_loop()
    link = _SHARED_LINKS.get(loop)
    if link is None:
        link = _SHARED_LINKS[loop] = LocalLink()
    return link


def new_virtual_link() -> LocalLink:
    """A fresh, empty virtual radio medium (bumble LocalLink) for a group of virtual bearers."""
    return LocalLink()


class BleBearer:
    """One Bluetooth LE radio used as a Bluetooth Mesh advertising bearer (asyncio).

    `hci_spec`: a bumble transport name (`usb:0`, `serial:/dev/ttyACM0,1000000`, `hci-socket:0`,
    ...) for a real controller, or None for a virtual controller on `link` (default: the loop's
    shared LocalLink). Use: `await start()`, `send(frame)` any number of times, `await stop()` (or
    `async with`). Frames heard go to `on_frame(data, rssi_dbm)` (rssi None when not reported).
    """

    def __init__(
        self,
        hci_spec: str | None = None,
        *,
        on_frame: FrameCallback | None = None,
        timing: BleTiming | None = None,
        link: LocalLink | None = None,
        name: str = "rescuemesh",
        address: str | None = None,
    ) -> None:
        self.hci_spec = hci_spec
        self.on_frame = on_frame
        self.timing = timing if timing is not None else BleTiming()
        self.name = name
        self.stats = BearerStats()
        self._link = link
        self._address = address
        self._transport: Transport | None = None
        self._controller: Controller | None = None
        self._device: Device | None = None
        self._queue: deque[bytes] = deque()
        self._wake = asyncio.Event()
        self._stopping = asyncio.Event()
        self._sender: asyncio.Task[None] | None = None
        self._seen: OrderedDict[tuple[str, bytes], float] = OrderedDict()  # last copy heard, in s
        self._last_end: dict[bytes, float] = {}  # advertising data -> loop time it last left the air
        self._interval_ms = self.timing.adv_interval_ms
        self._state = "new"  # new -> starting -> started -> stopped

    # --- lifecycle -----------------------------------------------------------------------------

    @property
    def started(self) -> bool:
        return self._state == "started"

    @property
    def address(self) -> str | None:
        """The random static address this bearer advertises from (known once started)."""
        return None if self._device is None else str(self._device.random_address)

    @property
    def description(self) -> str:
        return "virtual controller" if self.hci_spec is None else f"HCI {self.hci_spec}"

    async def start(self) -> None:
        """Open the HCI transport, reset the controller, start scanning and the sender task.
        Raises BleSetupError (one-line message) and leaves nothing open when that fails."""
        if self._state != "new":
            raise RuntimeError(f"a bearer starts once (it is {self._state})")
        self._state = "starting"
        try:
            await asyncio.wait_for(self._open(), self.timing.start_timeout_s)
        except asyncio.CancelledError:
            await self._close()
            raise
        except Exception as exc:
            await self._close()
            raise BleSetupError(self._setup_message(exc)) from exc
        self._state = "started"
        self._sender = asyncio.get_running_loop().create_task(self._send_loop(), name=f"ble-send-{self.name}")

    async def stop(self) -> None:
        """Drop the frames still queued, stop sending and scanning, power the controller off and close
        the transport. Never raises; safe to call twice or before start()."""
        if self._state == "stopped":
            return
        self._state = "stopped"
        self._queue.clear()
        self._stopping.set()
        self._wake.set()
        sender, self._sender = self._sender, None
        if sender is not None:
            # Let the sender finish the HCI command in flight rather than cancel it mid-command:
            # bumble's host does not recover well from that, and Python 3.11's wait_for can swallow
            # the cancellation. Cancel only if it does not end by itself.
            await asyncio.wait([sender], timeout=self.timing.hold_s + 2.0)
            if not sender.done():
                sender.cancel()
                await asyncio.wait([sender], timeout=1.0)
        await self._close()

    async def __aenter__(self) -> BleBearer:
        await self.start()
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.stop()

    # --- sending -------------------------------------------------------------------------------

    def send(self, frame: bytes) -> None:
        """Queue `frame` (1..29 bytes) for one advertisement; returns at once. Raises ValueError for
        a bad size and RuntimeError before start() or after stop(). A full queue drops the frame
        (stats.frames_dropped): a radio does not wait for the sender."""
        data = advertising_data(frame)  # validates before anything is queued
        if self._state != "started":
            raise RuntimeError(f"send() on a bearer that is {self._state}")
        if len(self._queue) >= self.timing.max_queue:
            self.stats.frames_dropped += 1
            return
        self._queue.append(data)
        self.stats.frames_queued += 1
        self._wake.set()

    async def _send_loop(self) -> None:
        loop = asyncio.get_running_loop()
        while self._state == "started":
            if not self._queue:
                self._wake.clear()
                await self._wake.wait()
                continue
            data = self._queue.popleft()
            last = self._last_end.get(data)
            if last is not None:  # same bytes again: stay silent longer than the receivers' window
                gap = self.timing.repeat_s + self._interval_ms / 1000.0
                await asyncio.sleep(max(0.0, last + gap - loop.time()))
                if self._state != "started":
                    break
            try:
                await self._advertise(data)
            except Exception as exc:  # an HCI error must not end the bearer: count, log, go on
                self.stats.advertise_errors += 1
                logger.warning("%s: advertising failed: %s", self.name, exc)

    async def _advertise(self, data: bytes) -> None:
        loop = asyncio.get_running_loop()
        try:
            await self._start_advertising(data)
        except hci.HCI_Error as exc:
            if not self._interval_too_short(exc):
                raise
            logger.warning(
                "%s: controller refuses %.0f ms non-connectable advertising (Bluetooth 4.x); using %.0f ms",
                self.name, self._interval_ms, LEGACY_NONCONN_MIN_INTERVAL_MS,
            )
            self._interval_ms = LEGACY_NONCONN_MIN_INTERVAL_MS
            await self._start_advertising(data)
        self.stats.frames_advertised += 1
        try:  # on air for hold_s, or until stop()
            await asyncio.wait_for(self._stopping.wait(), self.timing.hold_s)
        except asyncio.TimeoutError:
            pass
        finally:
            await self._device.stop_advertising()
            ended = loop.time()
            self._last_end[data] = ended
        horizon = ended - self.timing.repeat_s - 1.0  # forget what nobody can confuse any more
        for old in [d for d, t in self._last_end.items() if t < horizon]:
            del self._last_end[old]

    async def _start_advertising(self, data: bytes) -> None:
        # bumble uses extended-advertising commands with legacy PDUs when the controller has them,
        # the legacy LE Set Advertising commands otherwise; UNDIRECTED = ADV_NONCONN_IND.
        await self._device.start_advertising(
            advertising_type=AdvertisingType.UNDIRECTED,
            own_address_type=hci.OwnAddressType.RANDOM,
            advertising_data=data,
            advertising_interval_min=self._interval_ms,
            advertising_interval_max=self._interval_ms,
        )

    def _interval_too_short(self, exc: hci.HCI_Error) -> bool:
        return (
            getattr(exc, "error_code", None) == hci.HCI_INVALID_HCI_COMMAND_PARAMETERS_ERROR
            and self._interval_ms < LEGACY_NONCONN_MIN_INTERVAL_MS
        )

    # --- receiving -----------------------------------------------------------------------------

    def _on_advertisement(self, advertisement: Advertisement) -> None:
        stats = self.stats
        stats.reports += 1
        if advertisement.is_scan_response:  # a passive scan has none; bumble's virtual one fakes them
            stats.scan_responses_ignored += 1
            return
        frames, malformed = mesh_frames(advertisement.data_bytes)
        if malformed:
            stats.malformed_reports += 1
        if not frames:
            if not malformed:
                stats.reports_without_frame += 1
            return
        rssi = None if advertisement.rssi == RSSI_NOT_AVAILABLE else float(advertisement.rssi)
        now = asyncio.get_running_loop().time()
        sender = str(advertisement.address)
        for frame in frames:
            if self._is_repeat((sender, frame), now):
                stats.repeats_suppressed += 1
                continue
            stats.frames_received += 1
            if self.on_frame is None:
                continue
            try:
                self.on_frame(frame, rssi)
            except Exception:  # the stack's bug must not break bumble's HCI event handling
                stats.callback_errors += 1
                logger.exception("%s: on_frame raised", self.name)

    def _is_repeat(self, key: tuple[str, bytes], now: float) -> bool:
        """A copy is a repeat if the same advertiser sent the same bytes less than repeat_s before
        the previous copy: the window slides with every copy, so an advertisement that stays on
        air longer than planned (a late host, a slow USB link) still counts once."""
        window = self.timing.repeat_s
        seen = self._seen
        while seen:  # forget keys not heard for a window (least recently heard first)
            oldest_key, last = next(iter(seen.items()))
            if now - last < window:
                break
            del seen[oldest_key]
        last = seen.get(key)
        repeat = last is not None and now - last < window
        if window > 0.0:
            seen[key] = now
            seen.move_to_end(key)
        return repeat

    # --- setup and teardown --------------------------------------------------------------------

    async def _open(self) -> None:
        if self.hci_spec is None:
            link = self._link if self._link is not None else shared_virtual_link()
            self._controller = Controller(f"{self.name}-controller", link=link)
            host = Host(self._controller, AsyncPipeSink(self._controller))
        else:
            self._transport = await open_transport(self.hci_spec)
            host = Host(self._transport.source, self._transport.sink)
        self._device = Device(name=self.name, address=self._address, host=host)
        self._device.on(Device.EVENT_ADVERTISEMENT, self._on_advertisement)
        await self._device.power_on()
        await self._device.start_scanning(
            active=False,
            filter_duplicates=False,
            scan_interval=self.timing.scan_interval_ms,
            scan_window=self.timing.scan_window_ms,
        )

    async def _close(self) -> None:
        device, self._device = self._device, None
        if device is not None:
            device.remove_listener(Device.EVENT_ADVERTISEMENT, self._on_advertisement)
            for step in (device.stop_advertising, device.stop_scanning, device.power_off):
                try:
                    await asyncio.wait_for(step(), 2.0)
                except Exception as exc:  # a dead dongle must not keep us from closing the rest
                    logger.debug("%s: %s during stop: %r", self.name, step.__name__, exc)
        controller, self._controller = self._controller, None
        if controller is not None and controller in controller.link.controllers:
            controller.link.remove_controller(controller)
        transport, self._transport = self._transport, None
        if transport is not None:
            try:
                await asyncio.wait_for(transport.close(), 2.0)
            except Exception as exc:
                logger.debug("%s: closing %s: %r", self.name, self.hci_spec, exc)

    def _setup_message(self, exc: BaseException) -> str:
        where = self.description
        if isinstance(exc, (asyncio.TimeoutError, TimeoutError)):
            return (
                f"{where}: no answer from the Bluetooth controller within {self.timing.start_timeout_s:g} s "
                "(is it an HCI controller, and free?)"
            )
        if isinstance(exc, AssertionError) or type(exc).__name__ == "TransportSpecError":
            return (
                f"bad HCI spec {self.hci_spec!r}: expected a bumble transport such as usb:0, "
                "serial:/dev/ttyACM0,1000000 or hci-socket:0"
            )
        text = str(exc).strip() or type(exc).__name__
        hint = ""
        if self.hci_spec.split(":", 1)[0] in ("usb", "pyusb"):
            hint = " (plugged in, and readable by you? `bumble-usb-probe` lists dongles; see docs/ble.md)"
        return f"cannot open {where}: {text}{hint}"


async def open_bearer(
    hci_spec: str | None,
    *,
    on_frame: FrameCallback | None = None,
    timing: BleTiming | None = None,
    link: LocalLink | None = None,
    name: str = "rescuemesh",
    address: str | None = None,
) -> BleBearer:
    """A started BleBearer: on the controller named by `hci_spec` (a bumble transport: `usb:0`,
    `serial:/dev/ttyUSB0`, `hci-socket:0`), or on a virtual controller on `link` when it is None.
    Raises BleSetupError with a one-line message when the controller cannot be opened."""
    bearer = BleBearer(hci_spec, on_frame=on_frame, timing=timing, link=link, name=name, address=address)
    await bearer.start()
    return bearer
