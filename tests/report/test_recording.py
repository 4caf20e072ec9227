"""run.mcap: read back with the mcap reader and checked against result.json and the run itself;
--live: a Foxglove WebSocket on 127.0.0.1 during the run, gone after it."""

import base64
import json
import os
import socket

import numpy as np
import pytest
from mcap.reader import make_reader

from rescuemesh.maps import load_map, office_map_path
from rescuemesh.protocol import Reason, ResultCode
from rescuemesh.report.recording import SCAN_PERIOD_S, LiveServerError, RunRecorder, _behaviour, ns
from rescuemesh.robot.events import BehaviourEnded, BehaviourStarted
from rescuemesh.runtime import SimRuntime
from rescuemesh.scenarios import ScenarioOptions, get_scenario
from rescuemesh.scenarios.runner import run_scenario

ROBOTS = ("robot_1", "robot_2", "robot_3")
SCHEMAS = {
    "/map": "foxglove.Grid", "/scene": "foxglove.SceneUpdate", "/tf": "foxglove.FrameTransforms",
    "/log": "foxglove.Log", "/radio/frames": "rescuemesh.RadioFrame", "/behaviours": "rescuemesh.Behaviour",
    **{f"/{n}/pose": "foxglove.PoseInFrame" for n in ROBOTS},
    **{f"/{n}/path": "foxglove.PosesInFrame" for n in ROBOTS},
    **{f"/{n}/scan": "foxglove.LaserScan" for n in ROBOTS},
}


def read_mcap(path):
    """(summary, {topic: [(log_time, publish_time, data), ...]}) in log-time order."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        messages = {}
        for _, channel, message in reader.iter_messages(log_time_order=True):
            messages.setdefault(channel.topic, []).append((message.log_time, message.publish_time, message.data))
    return summary, messages


@pytest.fixture(scope="module")
def follow(tmp_path_factory):
    out = tmp_path_factory.mktemp("follow")
    outcome = run_scenario("follow", ScenarioOptions(seed=0), out_dir=out)
    result = json.loads((out / "result.json").read_text())
    summary, messages = read_mcap(out / "run.mcap")
    return outcome, result, summary, messages


def test_the_run_lists_run_mcap_with_the_foxglove_schemas_on_every_channel(follow):
    outcome, _, summary, messages = follow
    assert outcome.files[-1].name == "run.mcap"
    schemas = {ch.topic: summary.schemas[ch.schema_id].name for ch in summary.channels.values()}
    assert schemas == SCHEMAS
    encodings = {ch.topic: (ch.message_encoding, summary.schemas[ch.schema_id].encoding)
                 for ch in summary.channels.values()}
    assert encodings["/radio/frames"] == encodings["/behaviours"] == ("json", "jsonschema")
    assert encodings["/tf"] == ("protobuf", "protobuf")
    assert set(messages) == set(SCHEMAS)  # every channel carries messages


def test_each_robot_has_one_pose_per_trajectory_sample_at_its_simulated_time(follow):
    outcome, _, _, messages = follow
    for name in ROBOTS:
        samples = outcome.runtime.trajectories[name]
        times = [t for t, _, _ in messages[f"/{name}/pose"]]
        assert times == [ns(s.time_s) for s in samples]
    assert len(messages["/tf"]) == len(outcome.runtime.trajectories["robot_1"])  # one transform set a tick


def test_radio_frames_are_the_transmissions_of_result_json_decoded(follow):
    _, result, _, messages = follow
    frames = [json.loads(data) for _, _, data in messages["/radio/frames"]]
    assert len(frames) == result["network"]["transmissions"]
    assert sum(f["relayed"] for f in frames) == result["network"]["relayed_frames"]
    unicast = [f for f in frames if f["destination"] != "broadcast" and not f["relayed"]]  # the source's own
    assert sum(f["result"] == "delivered" for f in unicast) == result["protocol"]["unicast_receptions"]["delivered"]
    assert sum(f["result"] == "lost" for f in unicast) == result["protocol"]["unicast_receptions"]["lost"]
    assert {f["type"] for f in frames} >= {"HEARTBEAT", "FOLLOW", "CONFIRM", "POSE_UPDATE"}
    assert {f["source"] for f in frames} == set(ROBOTS)
    for (log_time, publish_time, _), frame in zip(messages["/radio/frames"], frames):
        assert log_time == publish_time == ns(frame["time_s"]) and frame["end_s"] > frame["time_s"]


def test_every_message_is_stamped_with_simulated_time_within_the_run(follow):
    _, result, summary, messages = follow
    end = ns(result["sim_time_s"])
    stats = summary.statistics
    assert stats.message_start_time == 0 and stats.message_end_time == end
    assert stats.message_count == sum(len(m) for m in messages.values())
    for topic, items in messages.items():
        assert all(0 <= log == pub <= end for log, pub, _ in items), topic


def test_the_map_is_sent_once_with_the_occupancy_grid(follow):
    _, _, _, messages = follow
    assert len(messages["/map"]) == len(messages["/scene"]) == 1
    [(log_time, _, data)] = messages["/map"]
    grid = load_map(office_map_path()).grid
    assert log_time == 0
    assert (grid.occupied.astype(np.int8) * 100).tobytes() in data  # nav_msgs values, row 0 at the lowest y


def test_log_lines_and_behaviours_are_the_brains_events(follow):
    _, result, _, messages = follow
    events = result["events"]
    assert len(messages["/log"]) == len(events)
    behaviours = [json.loads(data) for _, _, data in messages["/behaviours"]]
    assert len(behaviours) == sum(e[2] in ("behaviour_started", "behaviour_ended") for e in events)
    assert {"robot": "robot_2", "event": "started", "behaviour": "follow"}.items() <= behaviours[0].items()
    ended = [b for b in behaviours if b["event"] == "ended"]
    assert ended and ended[0]["robot"] == "robot_1" and ended[0]["result"] == "DONE"


def test_scans_are_published_at_the_documented_rate_and_paths_every_second(follow):
    _, result, _, messages = follow
    for name in ROBOTS:
        times = [t for t, _, _ in messages[f"/{name}/scan"]]
        assert np.all(np.diff(times) >= ns(SCAN_PERIOD_S) - 1000)
        assert len(times) >= int(result["sim_time_s"] / SCAN_PERIOD_S) - 1
        assert len(messages[f"/{name}/path"]) == int(result["sim_time_s"]) + 2  # each second, and at the end


def record_short_run(path, seconds=3.0, seed=4):
    map_model = load_map(office_map_path())
    scenario = get_scenario("follow")(ScenarioOptions(seed=seed), map_model)
    rt = SimRuntime(map_model, scenario.starts(), scenario.sim_config())
    with RunRecorder(rt, map_model, path) as recorder:
        while rt.time < seconds:
            rt.step(scenario.tick)
            recorder.tick()
        recorder.finish()
    _, messages = read_mcap(path)
    return {topic: [t for t, _, _ in items] for topic, items in messages.items()}


def test_log_lines_written_after_the_last_read_are_published_at_the_end(tmp_path):
    # the brains' logs are read once per simulated second: a run that ends 0.5 s in has read none yet
    path = tmp_path / "short.mcap"
    times = record_short_run(path, seconds=0.5)
    assert len(times["/log"]) >= 3 and max(times["/log"]) <= ns(0.5)


@pytest.mark.parametrize("event, detail, expected", [
    (BehaviourStarted(1.5, "robot_2", "follow"), "follow", ("started", "follow", "")),
    (BehaviourEnded(1.5, "robot_2", "follow", ResultCode.FAILED, Reason.LINK_LOST, "link lost"),
     "follow: FAILED link lost", ("ended", "follow", "FAILED")),
    (BehaviourEnded(1.5, "robot_2", "navigate", ResultCode.DONE, Reason.NONE), "navigate: DONE",
     ("ended", "navigate", "DONE")),
])
def test_a_behaviour_line_is_decoded(event, detail, expected):
    decoded = _behaviour(event)
    assert (decoded["event"], decoded["behaviour"], decoded["result"]) == expected
    assert decoded["detail"] == detail and decoded["robot"] == "robot_2"


class Watched:
    """A brain as a remote stand-in would be (every read a round trip): counts what is read of it."""

    def __init__(self, brain, reads):
        self._brain, self._reads = brain, reads

    def __getattr__(self, name):
        self._reads.append(name)
        return getattr(self._brain, name)


class WatchedRuntime:
    def __init__(self, rt, reads):
        self._rt = rt
        self.brains = {name: Watched(brain, reads.setdefault(name, [])) for name, brain in rt.brains.items()}

    def __getattr__(self, name):
        return getattr(self._rt, name)


def test_each_brain_is_read_at_most_once_per_simulated_second(tmp_path):
    map_model = load_map(office_map_path())
    scenario = get_scenario("follow")(ScenarioOptions(), map_model)
    rt = SimRuntime(map_model, scenario.starts(), scenario.sim_config())
    reads = {}
    with RunRecorder(WatchedRuntime(rt, reads), map_model, tmp_path / "run.mcap") as recorder:
        while rt.time < 5.0:
            rt.step(scenario.tick)
            recorder.tick()
        recorder.finish()
    assert reads == {name: ["log"] * 7 for name in ROBOTS}  # at 0, 1, ..., 5 s and at the end


def test_same_seed_same_messages_and_timestamps(tmp_path):
    first = record_short_run(tmp_path / "a.mcap")
    assert first == record_short_run(tmp_path / "b.mcap")
    assert first["/radio/frames"] and first["/robot_1/scan"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class FoxgloveClient:
    """Just enough of a WebSocket client (RFC 6455) to speak the Foxglove protocol, bounded by timeouts."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=5)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                           f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
                           f"Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n").encode())
        self.buffer = b""
        while b"\r\n\r\n" not in self.buffer:
            self.buffer += self._recv()
        head, self.buffer = self.buffer.split(b"\r\n\r\n", 1)
        self.status = head.split(b"\r\n")[0].decode()

    def _recv(self) -> bytes:
        data = self.sock.recv(65536)
        if not data:
            raise ConnectionError("closed")
        return data

    def _take(self, n: int) -> bytes:
        while len(self.buffer) < n:
            self.buffer += self._recv()
        data, self.buffer = self.buffer[:n], self.buffer[n:]
        return data

    def read(self):
        """The next message: a dict (text) or bytes (binary)."""
        opcode, length = self._take(2)
        length &= 0x7F
        if length >= 126:
            length = int.from_bytes(self._take(2 if length == 126 else 8), "big")
        payload = self._take(length)
        return json.loads(payload) if opcode & 0x0F == 1 else payload

    def send(self, message: dict) -> None:
        payload, mask = json.dumps(message).encode(), os.urandom(4)
        assert len(payload) < 126
        masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
        self.sock.sendall(bytes([0x81, 0x80 | len(payload)]) + mask + masked)


def test_live_serves_the_channels_during_the_run_and_stops_after(tmp_path):
    port = free_port()
    seen, clients = {}, []

    def watch(sim_s, limit_s):  # called by the run loop each simulated second: the run waits while we look
        if not clients:  # at 0 s: connect and subscribe to the map, sent before we came
            client = FoxgloveClient(port)
            clients.append(client)
            seen["status"], seen["server"] = client.status, client.read()["name"]
            channels = {}
            while "/map" not in channels:
                message = client.read()
                if isinstance(message, dict) and message.get("op") == "advertise":
                    channels.update({c["topic"]: c for c in message["channels"]})
            seen["schema"] = channels["/map"]["schemaName"]
            client.send({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": channels["/map"]["id"]}]})
        elif "map" not in seen:  # at 1 s: it was sent again for us (subscription 7), stamped with sim time
            message = clients[0].read()
            while not (isinstance(message, bytes) and message[0] == 1):
                message = clients[0].read()
            seen["map"] = int.from_bytes(message[1:5], "little")
            seen["map_time_s"] = int.from_bytes(message[5:13], "little") / 1e9

    outcome = run_scenario("follow", ScenarioOptions(seed=0, time_limit_s=3.0), live_port=port, progress=watch)
    clients[0].sock.close()
    assert seen.pop("map_time_s") <= 1.0
    assert seen == {"status": "HTTP/1.1 101 Switching Protocols", "server": "rescuemesh",
                    "schema": "foxglove.Grid", "map": 7}
    assert outcome.files == []  # no out_dir: served, not written
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(("127.0.0.1", port), timeout=2).close()


def test_a_live_port_already_taken_is_a_one_line_error_and_nothing_is_left_running(tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(LiveServerError, match=f"127.0.0.1:{port}"):
            run_scenario("follow", ScenarioOptions(time_limit_s=1.0), out_dir=tmp_path, live_port=port)


def _upgrade_status(port: int, origin: str | None) -> str:
    """The status line the live server answers a WebSocket upgrade with, sent with `origin`."""
    with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
        key = base64.b64encode(os.urandom(16)).decode()
        header = f"Origin: {origin}\r\n" if origin is not None else ""
        sock.sendall((f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                      f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n{header}"
                      f"Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n").encode())
        data = b""
        while b"\r\n" not in data:
            chunk = sock.recv(4096)
            if not chunk:
                break
            data += chunk
        return data.split(b"\r\n")[0].decode()


def test_the_live_server_admits_local_origins_only_by_default(monkeypatch):
    # this used to accept any Origin: a web page in the operator's browser could read the stream
    monkeypatch.delenv("RESCUEMESH_LIVE_ORIGINS", raising=False)
    map_model = load_map(office_map_path())
    scenario = get_scenario("follow")(ScenarioOptions(seed=0), map_model)
    rt = SimRuntime(map_model, scenario.starts(), scenario.sim_config())
    port = free_port()
    with RunRecorder(rt, map_model, None, live_port=port, allowed_origins=("https://app.foxglove.dev",)):
        switching = "HTTP/1.1 101 Switching Protocols"
        assert _upgrade_status(port, None) == switching  # a native client (the desktop app, a script)
        assert _upgrade_status(port, "http://localhost:3000") == switching
        assert _upgrade_status(port, "http://127.0.0.1") == switching
        assert _upgrade_status(port, "https://app.foxglove.dev") == switching  # allowed by the operator
        for origin in ("https://evil.example", "http://localhost.evil.example", "null", "file://"):
            assert _upgrade_status(port, origin) == "HTTP/1.1 403 Forbidden", origin
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(("127.0.0.1", port), timeout=2).close()
