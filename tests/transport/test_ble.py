"""The Bluetooth advertising bearer on bumble's virtual controllers, and ble-check over three of them."""

from __future__ import annotations

import ast
import asyncio
import io
import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

pytest.importorskip("bumble", reason="the [ble] extra is not installed")

from bumble import hci  # noqa: E402  (tests may drive bumble directly to make foreign advertisers)
from bumble.controller import Controller  # noqa: E402
from bumble.device import AdvertisingType, Device  # noqa: E402
from bumble.host import Host  # noqa: E402
from bumble.transport.common import AsyncPipeSink  # noqa: E402

import rescuemesh.transport.ble as ble  # noqa: E402
from rescuemesh.mesh import NetworkStack  # noqa: E402
from rescuemesh.protocol import Endpoint, EndpointConfig, ReliabilityConfig  # noqa: E402
from rescuemesh.checks.ble_check import (  # noqa: E402
    BLE_ACK_TIMEOUT_S,
    default_stack,
    main_ble_check,
    run_ble_check,
)
from rescuemesh.checks.ble_measure import FrameLog, percentile  # noqa: E402
from rescuemesh.transport.asyncio_pump import Cause  # noqa: E402
from rescuemesh.transport.ble import (  # noqa: E402
    MAX_FRAME_BYTES,
    BleBearer,
    BleTiming,
    advertising_data,
    mesh_frames,
    new_virtual_link,
)


def run(coro, timeout_s: float = 10.0):
    """Run `coro` on a fresh loop, bounded in time."""
    return asyncio.run(asyncio.wait_for(coro, timeout_s))


async def _foreign_advertiser(link, data: bytes, address: str) -> Device:
    """A plain bumble device on `link` advertising `data` (connectable, like any gadget)."""
    controller = Controller("foreign", link=link)
    host = Host(controller, AsyncPipeSink(controller))
    device = Device(name="foreign", address=hci.Address(address), host=host)
    await device.power_on()
    await device.start_advertising(
        advertising_type=AdvertisingType.UNDIRECTED_CONNECTABLE_SCANNABLE,
        advertising_data=data,
        advertising_interval_min=20,
        advertising_interval_max=20,
    )
    return device


async def _wait_until(predicate, timeout_s: float = 2.0) -> None:
    async with asyncio.timeout(timeout_s):
        while not predicate():
            await asyncio.sleep(0.01)


# --- the AD structure ------------------------------------------------------------------------------


def test_a_frame_is_one_ad_structure_of_type_0x2a():
    assert advertising_data(b"\x41\x01\x02") == bytes([4, 0x2A, 0x41, 0x01, 0x02])
    assert len(advertising_data(bytes(MAX_FRAME_BYTES))) == 31  # the whole legacy AdvData


@given(st.binary(min_size=1, max_size=MAX_FRAME_BYTES))
def test_mesh_frames_reads_back_what_advertising_data_wrote(frame):
    assert mesh_frames(advertising_data(frame)) == ([frame], False)


@given(st.binary(max_size=40))
def test_mesh_frames_never_raises_and_yields_only_frames_of_a_legal_size(data):
    frames, _ = mesh_frames(data)
    assert all(1 <= len(f) <= MAX_FRAME_BYTES for f in frames)


@pytest.mark.parametrize(
    "data, frames, malformed",
    [
        (bytes([0x1E, 0x2A, 1, 2, 3]), [], True),  # length runs past the data
        (bytes([0x01, 0x2A]), [], True),  # an empty frame
        (bytes([0x02, 0x01, 0x06, 0x03, 0x2A, 7, 8]), [b"\x07\x08"], False),  # flags, then a frame
        (bytes([0x03, 0x2A, 7, 8, 0x00, 0xFF]), [b"\x07\x08"], False),  # zero length ends the data
        (bytes([0x05, 0x09]) + b"name", [], False),  # a local name: not ours
        (b"", [], False),
    ],
)
def test_mesh_frames_on_odd_advertising_data(data, frames, malformed):
    assert mesh_frames(data) == (frames, malformed)


@pytest.mark.parametrize("size", [0, MAX_FRAME_BYTES + 1, 31, 64])
def test_send_rejects_frames_that_do_not_fit_one_network_pdu(size):
    bearer = BleBearer(None)
    with pytest.raises(ValueError, match="1..29 bytes"):
        bearer.send(bytes(size))
    assert bearer.stats.frames_queued == 0


def test_send_before_start_is_an_error_not_a_silent_drop():
    with pytest.raises(RuntimeError, match="new"):
        BleBearer(None).send(b"x")


# --- two bearers on virtual controllers ------------------------------------------------------------


def test_frames_cross_between_virtual_devices_and_other_advertisements_are_ignored():
    async def scenario():
        link = new_virtual_link()
        heard: list[tuple[bytes, float | None]] = []
        a = BleBearer(None, link=link, name="a")
        b = BleBearer(None, link=link, name="b", on_frame=lambda data, rssi: heard.append((data, rssi)))
        name_ad = bytes([0x05, 0x09]) + b"lamp"  # a gadget advertising its complete local name
        broken_ad = bytes([0x1E, 0x2A, 1, 2, 3])  # claims 30 bytes, carries 4
        others = []
        try:
            await a.start()
            await b.start()
            others = [
                await _foreign_advertiser(link, name_ad, "C1:00:00:00:00:01"),
                await _foreign_advertiser(link, broken_ad, "C2:00:00:00:00:02"),
            ]
            frames = [b"\x41\x21\x01\x02\x00\x07hello", bytes(range(MAX_FRAME_BYTES))]
            for frame in frames:
                a.send(frame)
            await _wait_until(lambda: len(heard) >= 2 and b.stats.malformed_reports > 0)
            await asyncio.sleep(0.15)  # let every repeat and foreign advertisement come and go
            return frames, heard, b.stats
        finally:
            for device in others:
                await device.stop_advertising()
                await device.power_off()
            await a.stop()
            await b.stop()

    frames, heard, stats = run(scenario())
    assert [data for data, _ in heard] == frames  # in order, each once, nothing else
    assert all(isinstance(rssi, float) for _, rssi in heard)
    assert stats.reports_without_frame > 0 and stats.malformed_reports > 0
    assert stats.repeats_suppressed > 0  # each frame was on air for several advertising events


@pytest.mark.parametrize("events", [1, 2, 3])
def test_identical_bytes_sent_twice_arrive_twice(events):
    # The receiver collapses the copies of one advertisement, not two sends that look alike: the
    # sender waits out the repeat window before it puts the same bytes on air again.
    async def scenario():
        link = new_virtual_link()
        heard: list[bytes] = []
        timing = BleTiming(adv_events=events)
        async with BleBearer(None, link=link, timing=timing) as a, BleBearer(
            None, link=link, timing=timing, on_frame=lambda d, r: heard.append(d)
        ):
            a.send(b"same")
            a.send(b"same")
            await _wait_until(lambda: len(heard) >= 2)
        return heard

    assert run(scenario()) == [b"same", b"same"]


def test_an_advertisement_left_on_air_longer_than_the_window_still_counts_once():
    # A late host (a loaded CPU, a slow USB link) may disable advertising after the repeat window:
    # the window runs from the previous copy, not the first, so the stack still gets one frame.
    async def scenario():
        link = new_virtual_link()
        heard: list[bytes] = []
        slow = BleTiming(adv_events=12)  # 240 ms on air against the receiver's 100 ms window
        async with BleBearer(None, link=link, timing=slow) as a, BleBearer(
            None, link=link, on_frame=lambda d, r: heard.append(d)
        ) as b:
            a.send(b"long")
            await asyncio.sleep(slow.hold_s + 0.05)
            return heard, b.stats

    heard, stats = run(scenario())
    assert heard == [b"long"]
    assert stats.repeats_suppressed >= 10


def test_with_no_repeat_window_every_advertising_event_is_delivered_but_no_scan_response():
    # bumble's virtual controller reports each event twice, once as a fake scan response.
    async def scenario():
        link = new_virtual_link()
        heard: list[bytes] = []
        timing = BleTiming(repeat_window_s=0.0)
        async with BleBearer(None, link=link) as a, BleBearer(
            None, link=link, timing=timing, on_frame=lambda d, r: heard.append(d)
        ) as b:
            a.send(b"once")
            await asyncio.sleep(timing.hold_s + 0.05)
            return heard, b.stats

    heard, stats = run(scenario())
    assert len(heard) >= 2 and set(heard) == {b"once"}  # several advertising events
    assert stats.scan_responses_ignored == len(heard)


def test_frames_queued_at_once_go_out_in_order_one_hold_apart():
    # One advertiser, one frame on air at a time: each stays hold_s (its advertising events) before
    # the next starts. Load can only stretch the gaps, so they are bounded from below.
    async def scenario():
        link = new_virtual_link()
        loop = asyncio.get_running_loop()
        heard: list[tuple[bytes, float]] = []
        async with BleBearer(None, link=link) as a, BleBearer(
            None, link=link, on_frame=lambda d, r: heard.append((d, loop.time()))
        ):
            frames = [bytes([7, i]) for i in range(4)]
            for frame in frames:
                a.send(frame)
            await _wait_until(lambda: len(heard) >= len(frames), timeout_s=5.0)
        return frames, heard

    frames, heard = run(scenario())
    assert [data for data, _ in heard] == frames
    gaps = [later - earlier for (_, earlier), (_, later) in zip(heard, heard[1:])]
    assert min(gaps) >= 0.9 * BleTiming().hold_s, gaps


def test_stop_in_the_middle_of_sending_is_prompt_and_leaves_no_task():
    # This used to hang until the caller's timeout now and then: stop() cancelled the sender in the
    # middle of bumble's HCI commands, and the cancellation could be swallowed.
    async def scenario():
        link = new_virtual_link()
        loop = asyncio.get_running_loop()
        slowest = 0.0
        for step in range(20):
            before = asyncio.all_tasks()
            a = BleBearer(None, link=link, name="a")
            await a.start()
            for i in range(3):
                a.send(bytes([step, i]))
            await asyncio.sleep(step * 0.0002)  # stop at a different point of the HCI exchange
            started = loop.time()
            await asyncio.wait_for(a.stop(), 1.0)
            slowest = max(slowest, loop.time() - started)
            assert asyncio.all_tasks() - before == set()
        return slowest

    assert run(scenario(), timeout_s=20.0) < BleTiming().hold_s + 0.05


def test_an_old_controller_that_refuses_20_ms_gets_100_ms(monkeypatch):
    class Bluetooth4Controller(Controller):
        """Core 4.x: ADV_NONCONN_IND needs advInterval >= 100 ms (160 x 0.625 ms)."""

        def on_hci_le_set_extended_advertising_parameters_command(self, command):
            if command.primary_advertising_interval_min < 160:
                return hci.HCI_LE_Set_Extended_Advertising_Parameters_ReturnParameters(
                    status=hci.HCI_ErrorCode.INVALID_COMMAND_PARAMETERS_ERROR, selected_tx_power=0
                )
            return super().on_hci_le_set_extended_advertising_parameters_command(command)

    async def scenario():
        link = new_virtual_link()
        heard: list[bytes] = []
        async with BleBearer(None, link=link, on_frame=lambda d, r: heard.append(d)):
            monkeypatch.setattr(ble, "Controller", Bluetooth4Controller)
            async with BleBearer(None, link=link, name="old") as old:
                old.send(b"slow")
                await _wait_until(lambda: heard == [b"slow"])
                return old.stats

    stats = run(scenario())
    assert stats.advertise_errors == 0 and stats.frames_advertised == 1


def test_a_bad_hci_spec_is_a_one_line_setup_error():
    with pytest.raises(ble.BleSetupError, match="bad HCI spec 'nonsense:0'") as info:
        run(BleBearer("nonsense:0").start())
    assert "\n" not in str(info.value)


# --- ble-check -------------------------------------------------------------------------------------


def test_ble_check_on_virtual_controllers_confirms_everything():
    report = run(run_ble_check(updates=2, timeout_s=10.0), timeout_s=20.0)
    assert report.passed, report.summary()
    assert (report.commands_sent, report.commands_confirmed) == (4, 4)  # Follow x 2, Stop x 2
    assert (report.pose_updates_sent, report.pose_updates_confirmed) == (4, 4)
    assert report.resends == 0
    assert report.frames_advertised == report.frames_sent  # nothing left in a queue
    assert report.receptions == report.receptions_expected == 2 * report.frames_sent  # none lost
    # Wall-clock latencies are figures the report prints, not bounds to test: a loaded machine
    # stretches them (p95 250 ms once, beside other jobs). What must hold is that no frame and no
    # confirm took longer than the ack timeout, as nothing was resent; the queue's spacing is
    # tested from below in test_frames_queued_at_once_go_out_in_order_one_hold_apart.
    assert 0.0 < report.frame_latency_p50_ms <= report.frame_latency_p95_ms < BLE_ACK_TIMEOUT_S * 1000.0
    assert 0.0 < report.confirm_rtt_p50_ms <= report.confirm_rtt_p95_ms < BLE_ACK_TIMEOUT_S * 1000.0
    assert "commands 4/4 confirmed" in report.summary()


class _DeafStack(Endpoint):
    """An Endpoint whose radio hears nothing."""

    def receive(self, data: bytes, now: float) -> None:
        pass


def test_ble_check_that_times_out_reports_the_phase_and_closes_everything():
    def make_stack(address):
        return _DeafStack(address) if address == 3 else Endpoint(address)

    async def scenario():
        before = asyncio.all_tasks()
        report = await run_ble_check(updates=1, timeout_s=0.4, make_stack=make_stack)
        return report, asyncio.all_tasks() - before

    report, leftovers = run(scenario())
    assert not report.passed
    assert report.failure == "timed out after 0.4 s in the Follow phase"
    assert report.commands_confirmed == 0  # the Follow phase never finished
    assert leftovers == set()  # the bearers' sender tasks are gone


def endpoint_stack(address: int) -> Endpoint:
    """A bare Endpoint with the BLE ack timeout (no mesh layer: no relaying)."""
    return Endpoint(address, EndpointConfig(reliability=ReliabilityConfig(ack_timeout_s=BLE_ACK_TIMEOUT_S)))


class _DropsFirstFrame(Endpoint):
    """An Endpoint whose radio misses the first frame it hears."""

    missed = False

    def receive(self, data: bytes, now: float) -> None:
        if not self.missed:
            self.missed = True
            return
        super().receive(data, now)


def test_ble_check_recovers_a_lost_frame_by_the_endpoints_resend():
    def make_stack(address):
        if address == 2:
            return _DropsFirstFrame(address, EndpointConfig(reliability=ReliabilityConfig(ack_timeout_s=BLE_ACK_TIMEOUT_S)))
        return endpoint_stack(address)

    report = run(run_ble_check(updates=1, timeout_s=5.0, make_stack=make_stack))
    assert report.passed, report.summary()
    assert report.resends == 1  # robot_1's Follow to robot_2
    assert report.resent_samples >= 2  # heard by robot_2 and robot_3
    assert report.confirm_rtt_max_ms > BLE_ACK_TIMEOUT_S * 1000.0  # that Follow took a resend


class _MeshShapedStack:
    """The shape of mesh.NetworkStack: an `endpoint` inside, receive() with rssi_dbm and
    relay_delay_s, next_event() for network events only."""

    def __init__(self, address: int) -> None:
        self.endpoint = endpoint_stack(address)
        self.extras: list[tuple[float | None, float]] = []

    def receive(self, data, now, *, rssi_dbm=None, relay_delay_s=0.0):
        self.extras.append((rssi_dbm, relay_delay_s))
        self.endpoint.receive(data, now)

    def frames_to_send(self, now):
        return self.endpoint.frames_to_send(now)

    def get_timer(self):
        return self.endpoint.get_timer()

    def handle_timer(self, now):
        self.endpoint.handle_timer(now)

    def next_event(self):
        return None


def test_ble_check_drives_a_stack_with_the_mesh_network_stack_shape():
    stacks: list[_MeshShapedStack] = []

    def make_stack(address):
        stacks.append(_MeshShapedStack(address))
        return stacks[-1]

    report = run(run_ble_check(updates=1, timeout_s=5.0, make_stack=make_stack))
    assert report.passed, report.summary()
    extras = [extra for stack in stacks for extra in stack.extras]
    assert extras and all(rssi == -50.0 for rssi, _ in extras)  # bumble's virtual controller RSSI
    assert all(0.0 <= delay <= 0.010 for _, delay in extras) and len({d for _, d in extras}) > 1


class _BrokenStack(Endpoint):
    def receive(self, data: bytes, now: float) -> None:
        raise KeyError("boom")


def test_a_stack_that_raises_fails_the_check_with_its_error_instead_of_crashing():
    def make_stack(address):
        return _BrokenStack(address) if address == 2 else Endpoint(address)

    report = run(run_ble_check(updates=1, timeout_s=0.4, make_stack=make_stack))
    assert not report.passed
    assert "timed out" in report.failure  # robot_2 never confirms...
    assert "error(s) in the pump, first: robot_2: KeyError: 'boom'" in report.failure  # ...and says why


def test_main_ble_check_prints_a_short_report_and_exits_0():
    out = io.StringIO()
    assert main_ble_check([], out, updates=1) == 0
    text = out.getvalue()
    assert text.startswith("ble-check: PASS, 3 robots on virtual controllers")
    assert "frame latency p50" in text and "confirm RTT p50" in text


@pytest.mark.parametrize(
    "specs, message",
    [
        (["usb:0"], "needs one per robot"),
        (["usb:0", "usb:1"], "needs one per robot"),
        (["usb:0", "usb:0", "usb:1"], "the same controller twice"),
        (["nonsense:0", "nonsense:1", "nonsense:2"], "bad HCI spec 'nonsense:0'"),
        (["usb:97", "usb:98", "usb:99"], "cannot open HCI usb:97"),  # no such dongle
        (["serial:/dev/no-such-tty", "serial:/dev/b", "serial:/dev/c"], "cannot open HCI serial:/dev/no-such"),
    ],
)
def test_main_ble_check_bad_hci_exits_2_with_one_line(specs, message):
    out = io.StringIO()
    assert main_ble_check(specs, out) == 2
    text = out.getvalue()
    assert text.count("\n") == 1 and message in text, text


def test_only_transport_and_runtime_import_bumble():
    package = Path(ble.__file__).parents[1]
    for path in package.rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
        names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.level == 0]
        if any(name.split(".")[0] == "bumble" for name in names):
            assert path.parent.name in ("transport", "runtime"), path


# --- measurement helpers ---------------------------------------------------------------------------


def test_frame_log_matches_a_reception_to_the_latest_send_of_those_bytes_by_someone_else():
    log = FrameLog()
    log.sent(1, b"f", 10.0, Cause.APP)
    log.sent(1, b"f", 11.0, Cause.RECEIVE)  # the same bytes again: a cached Confirm re-sent
    log.received(1, b"f", 11.5)  # our own frame heard back: not a sample
    log.received(2, b"f", 11.25)
    log.received(2, b"f", 11.3)  # the same send heard twice counts once
    log.received(3, b"g", 12.0)  # nobody here sent it
    samples = [(s.src, s.dst, s.latency_s, s.cause, s.repeat) for s in log.samples]
    assert samples == [(1, 2, 0.25, Cause.RECEIVE, True)]
    assert log.unmatched == 2 and log.frames_received == 4


def test_percentile_interpolates_between_ranks():
    assert percentile([1.0, 2.0, 3.0, 4.0], 50) == 2.5
    assert percentile([5.0], 95) == 5.0
    assert math.isnan(percentile([], 50))


def test_the_default_stack_is_the_mesh_network_stack_and_its_relays_carry_a_lost_frame():
    # robot_2's radio misses robot_1's first Follow; robot_3's mesh node relays it, so no resend is needed
    from rescuemesh.mesh.security import FrameSealer

    class DropsFirst(NetworkStack):
        missed = False

        def receive(self, data, now, **kw):
            # the first frame of robot_1 (source: header byte 2, in the clear) that is not a Heartbeat of
            # the warm-up: its Follow, first heard from robot_1 itself; robot_3's relayed copy comes after
            if not self.missed and data[2] == 1 and FrameSealer.heartbeat_epoch(data) is None:
                self.missed = True
                return
            super().receive(data, now, **kw)

    made = []

    def make_stack(address):
        stack = default_stack(address)
        if address == 2:
            made.append(DropsFirst(stack.endpoint, stack.node))
            return made[-1]
        return stack

    assert isinstance(default_stack(1), NetworkStack)
    report = run(run_ble_check(updates=1, timeout_s=5.0, make_stack=make_stack))
    assert report.passed, report.summary()
    assert made[0].missed and report.resends == 0


def test_ble_check_frames_are_authenticated_a_robot_with_another_key_is_never_heard():
    # this used to run unauthenticated: any radio could command the check's robots
    from rescuemesh.mesh import MeshConfig, MeshNode, NetworkStack
    from rescuemesh.mesh.keys import team_key_from_seed
    from rescuemesh.mesh.security import FrameSealer
    from rescuemesh.checks.ble_check import default_stack

    def make_stack(address):
        if address != 3:
            return default_stack(address)
        stranger = FrameSealer.from_team_key(team_key_from_seed(12345))
        return NetworkStack(Endpoint(address), MeshNode(address, MeshConfig(), stranger))

    report = run(run_ble_check(updates=1, timeout_s=3.0, make_stack=make_stack), timeout_s=15.0)
    assert not report.passed and "Heartbeat warm-up" in report.failure  # robot_3's frames never open
    good = run(run_ble_check(updates=1, timeout_s=10.0), timeout_s=20.0)
    assert good.passed and good.authenticated and "authenticated frames" in good.summary()
