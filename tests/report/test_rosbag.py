"""`rescuemesh run follow --rosbag`: the run as a rosbag2 (MCAP storage, CDR standard messages), read back
with the rosbags package and checked against result.json."""

import json
import math
import subprocess
import sys

import pytest
import yaml

rosbags = pytest.importorskip("rosbags")  # in the sim extra
from rosbags.rosbag2 import Reader  # noqa: E402

from rescuemesh.report.rosbag import typestore  # noqa: E402


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    out = tmp_path_factory.mktemp("follow_rosbag")
    done = subprocess.run([sys.executable, "-m", "rescuemesh", "run", "follow", "--out", str(out), "--rosbag",
                           "--quiet"], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads((out / "result.json").read_text())
    info = yaml.safe_load((out / "run.rosbag2" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    storage = info["storage_identifier"]
    store = typestore()
    messages: dict[str, list] = {}
    with Reader(out / "run.rosbag2") as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        for conn, stamp, raw in reader.messages():
            messages.setdefault(conn.topic, []).append((stamp, store.deserialize_cdr(raw, conn.msgtype)))
    return result, types, storage, messages


def test_the_rosbag_has_each_robots_standard_topics_and_the_papers(bag):
    result, types, storage, messages = bag
    assert storage == "mcap"
    robots = sorted(result["robots"])
    expected = {"/tf": "tf2_msgs/msg/TFMessage"}
    for name in robots:
        expected |= {f"/{name}/odom": "nav_msgs/msg/Odometry", f"/{name}/scan": "sensor_msgs/msg/LaserScan",
                     f"/{name}/cmd_vel": "geometry_msgs/msg/Twist"}
    # the paper's topic of each robot that sent or received a command (robot_3 only relays in follow)
    papers = {t: k for t, k in types.items() if t.endswith("/comm_protocol/command")}
    assert set(papers) >= {"/robot_1/comm_protocol/command", "/robot_2/comm_protocol/command"}
    assert set(papers.values()) == {"rescuemesh_msgs/msg/Command"}
    assert {t: k for t, k in types.items() if t not in papers} == expected
    assert all(messages[topic] for topic in types)  # every topic carries messages


def test_the_rosbag_agrees_with_result_json(bag):
    result, _, _, messages = bag
    end_ns = max(stamp for topic in messages.values() for stamp, _ in topic)
    assert abs(end_ns * 1e-9 - result["sim_time_s"]) < 0.2  # the bag spans the run, in simulated time
    for name, robot in result["robots"].items():
        odom = messages[f"/{name}/odom"]
        last = odom[-1][1].pose.pose.position
        final = robot["final_pose"]
        assert (round(last.x, 3), round(last.y, 3)) == (final["x"], final["y"])
        path = sum(math.hypot(b.pose.pose.position.x - a.pose.pose.position.x,
                              b.pose.pose.position.y - a.pose.pose.position.y)
                   for (_, a), (_, b) in zip(odom, odom[1:]))
        assert path == pytest.approx(robot["path_length_m"], abs=0.01)
        stamps = [stamp for stamp, _ in odom]
        assert stamps == sorted(stamps) and all(m.header.frame_id == "map" for _, m in odom[:5])
    leader = messages["/robot_1/comm_protocol/command"]
    follows = [m for _, m in leader if m.type == "COMMAND_FOLLOW" and m.direction == "SENT"]
    assert follows and follows[0].sender == "robot_1" and follows[0].receiver == "robot_2"
    heard = [m for _, m in messages["/robot_2/comm_protocol/command"] if m.type == "COMMAND_FOLLOW"]
    assert heard and heard[0].direction == "RECEIVED"
    scans = messages["/robot_1/scan"]
    assert len(scans[0][1].ranges) > 100 and scans[0][1].range_max > 1.0
