"""The control plane's decoder and authentication (issue 17): no pickle, typed messages only, every
message sealed with the run's control key, replays and forgeries refused and counted.

These drive CallServer and CallClient through stand-ins for Zenoh's query and reply objects; the
intruder tests in test_control_intruder.py do the same against real processes.
"""

from __future__ import annotations

import numpy as np
import pytest

from rescuemesh.geometry import Pose2D
from rescuemesh.maps import load_map, office_map_path
from rescuemesh.protocol import MessageType, ResultCode
from rescuemesh.protocol.messages import Capability
from rescuemesh.robot.events import CommandSent
from rescuemesh.robot.records import BrainLog, OutgoingCommand
from rescuemesh.runtime.processes import control_messages as msg
from rescuemesh.runtime.processes.control import (
    PUBLIC_CONTROL_KEY,
    CallClient,
    CallServer,
    ControlError,
    ControlKey,
    Keys,
    control_key_from_team_key,
)
from rescuemesh.runtime.processes.control_codec import CodecError, decode, encode
from rescuemesh.checks.control_fuzz import fuzz, pickle_call

KEY = ControlKey(bytes(range(32)))
OTHER_KEY = ControlKey(bytes(range(1, 33)))
REQUEST, REPLY = 1, 2


@pytest.mark.parametrize("module, name", [("rescuemesh.cli", "os.system"),
                                          ("rescuemesh.runtime.processes.spawn", "subprocess.Popen")])
def test_the_pickle_payloads_of_issue_17_are_refused_by_the_decoder(tmp_path, module, name):
    # this used to run the command: the old decoder admitted any name under rescuemesh., and pickle
    # protocol 4 resolves rescuemesh.cli + os.system to os.system itself
    marker = tmp_path / "pwned"
    payload = pickle_call(module, name, f"touch {marker}" if name == "os.system" else str(marker))
    with pytest.raises(CodecError):
        decode(payload)
    server, replies = _server()
    server._on_query(_Query(KEY.seal(REQUEST, b"w" * 16, 1, "robot_1", payload)))  # even sealed with the key
    assert not marker.exists() and replies == [] and server.refusals.count == 1


def test_only_registered_types_decode_and_each_checks_its_fields():
    grid = load_map(office_map_path()).grid
    setup = msg.RobotSetup("robot_1", Pose2D(1.0, 2.0, 0.5), _config(), grid, 2, _ground(), None, True, b"n" * 16,
                           Pose2D(1.0, 2.0, 0.5))
    copy = decode(encode(setup))
    assert copy.config == setup.config and copy.start == setup.start and copy.epoch == 2
    assert np.array_equal(copy.grid.occupied, grid.occupied) and copy.grid.occupied.dtype == bool
    with pytest.raises(CodecError, match="may not cross"):
        encode(object())
    with pytest.raises(CodecError, match="may not cross"):
        encode(np.array([object()]))
    # a field of the wrong type is refused before the class is built
    import msgpack

    def record(name, *fields):  # the wire form: an array that opens with the class's tag
        return [msgpack.ExtType(5, name.encode()), *fields]

    with pytest.raises(CodecError, match="Tick.now"):
        decode(msgpack.packb(record("Tick", "one", None)))
    with pytest.raises(CodecError, match="Tick.body"):
        decode(msgpack.packb(record("Tick", 1.0, None)))
    with pytest.raises(CodecError, match="takes 2 fields"):
        decode(msgpack.packb(record("Tick", 1.0)))
    with pytest.raises(CodecError, match="unknown record type"):
        decode(msgpack.packb(record("Popen", ["touch", "x"])))
    with pytest.raises(CodecError, match="unknown extension type 2"):  # version 1's record: no longer read
        decode(msgpack.packb(msgpack.ExtType(2, msgpack.packb(["Stats", []]))))


def test_a_tag_anywhere_but_at_the_head_of_an_array_is_refused():
    import msgpack

    stats, pair = msgpack.ExtType(5, b"Stats"), msgpack.ExtType(6, b"")
    assert decode(msgpack.packb([stats])) == msg.Stats()
    assert decode(msgpack.packb([pair, 1, "a"])) == (1, "a")
    assert decode(msgpack.packb([[pair], [stats]])) == [(), msg.Stats()]
    # two IntEnum members with the same value are equal in Python; each keeps its own type
    from rescuemesh.protocol.messages import Reason, ResultCode

    assert [type(v) for v in decode(encode([ResultCode(0), Reason(0), ResultCode(0)]))] == [ResultCode, Reason, ResultCode]
    for hostile in (stats, [1, stats], {"a": stats}, {"a": [0, pair]}, [[0, stats]], msgpack.ExtType(6, b"x")):
        with pytest.raises(CodecError):
            decode(msgpack.packb(hostile))


def test_an_array_is_refused_unless_its_dtype_shape_and_bytes_agree():
    import msgpack

    def array(dtype, shape, raw):
        return msgpack.packb(msgpack.ExtType(1, msgpack.packb([dtype, shape, raw])))

    assert np.array_equal(decode(array("<f8", [2], b"\x00" * 16)), np.zeros(2))
    for dtype, shape, raw in [("|O", [1], b"\x00" * 8), ("<f8", [3], b"\x00" * 16), ("<f8", [1 << 30, 1 << 30], b""),
                              ("<f8", [1, 1, 1, 1], b"\x00" * 8), ("<f8", [-1], b""), ("|V8", [1], b"\x00" * 8),
                              ("<U1", [2], b"\x00" * 8), ("|u1", [17, 1 << 20], bytes(17 << 20))]:  # over 16 MiB
        with pytest.raises(CodecError):
            decode(array(dtype, shape, raw))


def test_a_request_sealed_with_another_key_or_replayed_is_refused_and_counted():
    server, replies = _server()
    world = b"w" * 16
    server._on_query(_Query(KEY.seal(REQUEST, world, 1, "robot_1", encode(msg.Hello()))))
    nonce = decode(KEY.open(replies[-1])[4]).robot_nonce
    setup = KEY.seal(REQUEST, world, 2, "robot_1", encode(_setup(nonce)))
    server._on_query(_Query(setup))
    assert isinstance(decode(KEY.open(replies[-1])[4]), msg.SetupReply) and len(replies) == 2
    stats = KEY.seal(REQUEST, world, 3, "robot_1", encode(msg.Stats()))
    server._on_query(_Query(stats))
    assert len(replies) == 3
    for forged in [stats,  # replayed: counter 3 again
                   setup,  # a replayed set-up
                   OTHER_KEY.seal(REQUEST, world, 9, "robot_1", encode(msg.Stats())),  # not the run's key
                   KEY.seal(REQUEST, b"x" * 16, 9, "robot_1", encode(msg.Stats())),  # another run
                   KEY.seal(REQUEST, world, 9, "robot_2", encode(msg.Stats())),  # for another robot
                   KEY.seal(REPLY, world, 9, "robot_1", encode(msg.Stats())),  # a reply reflected
                   KEY.seal(REQUEST, world, 9, "robot_1", encode(msg.Done())),  # not a request
                   stats[:-1] + bytes([stats[-1] ^ 1]), b"", b"\x00" * 40]:
        server._on_query(_Query(forged))
    assert len(replies) == 3 and server.refusals.count == 10


def test_a_set_up_recorded_in_another_run_is_refused():
    server, replies = _server()
    server._on_query(_Query(KEY.seal(REQUEST, b"w" * 16, 1, "robot_1", encode(_setup(b"o" * 16)))))
    assert replies == [] and server.refusals.count == 1


def test_a_forged_and_a_replayed_reply_are_dropped_and_counted_and_the_genuine_one_counts():
    recorded = []

    def answer(counter, nonce):  # an intruder answers first, then replays an old genuine reply, then the robot
        forged = OTHER_KEY.seal(REPLY, nonce, counter, "robot_1", encode(msg.StatsReply(666, 0.0)))
        replayed = recorded[-1] if recorded else forged
        genuine = KEY.seal(REPLY, nonce, counter, "robot_1", encode(msg.StatsReply(42, 1.5)))
        recorded.append(genuine)
        return [forged, replayed, genuine]

    client = CallClient(_Session(answer), Keys("t"), KEY)
    assert client.call("robot_1", msg.Stats()) == msg.StatsReply(42, 1.5)
    assert client.refusals.count == 2
    assert client.call("robot_1", msg.Stats()) == msg.StatsReply(42, 1.5)
    assert client.refusals.count == 4  # forged, and the first call's reply replayed


def test_a_robot_that_answers_without_the_key_does_not_count_as_answering():
    client = CallClient(_Session(lambda counter, nonce: [pickle_call("rescuemesh.cli", "os.system", "true")]),
                        Keys("t"), KEY, timeout_s=0.2)
    with pytest.raises(ControlError, match="did not answer with the run's control key"):
        client.call("robot_1", msg.Hello())
    assert client.refusals.count == 1


def test_the_control_key_is_the_team_keys_own_derivation():
    team = bytes(16)
    key = control_key_from_team_key(team)
    from rescuemesh.mesh.keys import derive_frame_key

    assert len(key) == 32 and key != PUBLIC_CONTROL_KEY and key[:16] != derive_frame_key(team) and team not in key


def test_two_thousand_random_and_mutated_control_messages_none_accepted_no_untyped_exception():
    counts = fuzz(2000, seed=1)
    assert counts.messages == 2000
    assert counts.accepted == 0 and counts.untyped == 0, counts.findings[:3]
    assert counts.refused_sealed == 2000 and counts.refused_body > 1500


# --- the status a robot sends and the world's stand-in -------------------------------------


def test_the_brains_status_reaches_the_stand_in_as_it_changes():
    from rescuemesh.runtime.processes.remote import RemoteBrain, RemoteStack
    from rescuemesh.runtime.processes.robot_process import StatusTracker

    class Brain:  # what StatusTracker reads of a RobotBrain
        running, finished, outgoing, log, commands_failed = None, [], {}, BrainLog(), 0
        received_data = []
        peer_capabilities = {}

    brain = Brain()
    tracker = StatusTracker(brain)
    stand_in = RemoteBrain(_Link(), "robot_1", 1, None, RemoteStack(_Link(), "robot_1", 1))
    brain.outgoing = {1: OutgoingCommand(1, 2, "Follow", 0.5)}
    brain.log = BrainLog()  # the brain's own log type (robot/records.py)
    brain.log.append(CommandSent(0.5, "robot_1", MessageType.FOLLOW, 2, 1))
    stand_in.update(decode(encode(tracker.delta())))
    brain.outgoing[1].result = ResultCode.ACCEPTED
    delta = tracker.delta()
    assert delta.log == [] and [c.seq for c in delta.outgoing] == [1]  # only what changed
    stand_in.update(decode(encode(delta)))
    assert stand_in.outgoing[1].result == ResultCode.ACCEPTED and stand_in.log == brain.log
    assert stand_in.running is None and stand_in.behaviour == "idle"
    assert tracker.delta() == msg.StatusDelta()  # nothing changed: nothing sent
    # a scenario waits on the peers' Heartbeats (relay: robot_3 heard by robot_1); the stand-in had no
    # peer_capabilities, and `relay --processes` died with an AttributeError
    assert stand_in.peer_capabilities == {} and stand_in.capabilities_of(3) is None
    brain.peer_capabilities = {3: Capability.LASER | Capability.RELAY}
    stand_in.update(decode(encode(tracker.delta())))
    assert stand_in.capabilities_of(3) == Capability.LASER | Capability.RELAY
    assert tracker.delta() == msg.StatusDelta()
    with pytest.raises(AttributeError):
        stand_in.stack  # noqa: B018 - nothing else of the robot can be read


# --- stand-ins ----------------------------------------------------------------------------


class _Payload:
    def __init__(self, data: bytes) -> None:
        self.data = data

    def __len__(self) -> int:
        return len(self.data)

    def to_bytes(self) -> bytes:
        return self.data


class _Sample:
    def __init__(self, data: bytes, key: str = "rescuemesh/t/robot/robot_1/reply") -> None:
        self.payload, self.key_expr = _Payload(data), key


def _Query(data: bytes) -> _Sample:  # a request as the robot's subscriber gets it
    return _Sample(data, "rescuemesh/t/robot/robot_1/request")


class _Declared:
    def __init__(self, put=None) -> None:
        self.put = put

    def undeclare(self) -> None:
        pass


class _ServerSession:
    def __init__(self, replies: list) -> None:
        self.replies = replies

    def declare_publisher(self, key, **options):
        return _Declared(self.replies.append)

    def declare_subscriber(self, key, callback):
        return _Declared()


def _server():
    from rescuemesh.runtime.processes.robot_process import RobotWorker

    replies: list[bytes] = []
    server = CallServer(_ServerSession(replies), Keys("t"), "robot_1", KEY, RobotWorker("robot_1").handle)
    server._on_query = server._on_request
    return server, replies


class _Session:
    """A world's session whose robot_1 answers each request with `answer(counter, nonce)`'s replies."""

    def __init__(self, answer) -> None:
        self.answer, self.deliver = answer, None

    def declare_subscriber(self, key, callback):
        self.deliver = callback
        return _Declared()

    def declare_publisher(self, key, **options):
        def put(payload: bytes) -> None:
            _, nonce, counter, _, _ = KEY.open(payload)
            for reply in self.answer(counter, nonce):
                self.deliver(_Sample(reply))

        return _Declared(put)


class _Link:
    def check_live(self, name: str) -> None:
        pass


def _config():
    from rescuemesh.runtime.config import SimConfig

    return SimConfig()


def _ground():
    from rescuemesh.body import RobotKind

    return RobotKind.GROUND


def _setup(nonce: bytes) -> msg.RobotSetup:
    return msg.RobotSetup("robot_1", Pose2D(6.6, 4.6, 0.0), _config(), load_map(office_map_path()).grid, 0,
                          _ground(), None, True, nonce, Pose2D(6.6, 4.6, 0.0))


def test_a_flood_on_a_robots_reply_key_is_bounded_and_counted():
    flood = [OTHER_KEY.seal(REPLY, bytes(16), 1, "robot_1", b"x")] * 1000
    client = CallClient(_Session(lambda counter, nonce: flood), Keys("t"), KEY, timeout_s=0.2)
    sent = client._send("robot_1", msg.Hello(), None)  # the flood arrives before the world reads any of it
    assert client._inbox["robot_1"].qsize() == 256 and client.refusals.count == 1000 - 256
    with pytest.raises(ControlError, match="did not answer with the run's control key"):
        client._result("robot_1", msg.Hello(), sent)
    assert client.refusals.count == 1000


def test_a_message_of_another_control_plane_version_is_refused_by_name():
    # version 2 changed the body (records as tagged arrays) and the tag (keyed BLAKE2b): a version-1
    # peer is refused, and a version-1 header under the new tag is told so by name, not misread
    import hashlib
    import hmac
    import struct

    signed = struct.pack(">BB16sQB", 1, REQUEST, b"w" * 16, 1, 7) + b"robot_1" + encode(msg.Stats())
    with pytest.raises(ControlError, match="not authenticated"):  # as a version-1 peer seals it
        KEY.open(hmac.digest(bytes(range(32)), signed, "sha256")[:16] + signed)
    with pytest.raises(ControlError, match="version 1, expected 2"):
        KEY.open(hashlib.blake2b(signed, key=bytes(range(32)), digest_size=16).digest() + signed)
    assert KEY.open(KEY.seal(REQUEST, b"w" * 16, 1, "robot_1", encode(msg.Stats())))[3] == "robot_1"
