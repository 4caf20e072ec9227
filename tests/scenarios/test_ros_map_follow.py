"""follow on a ROS map_server map (PGM + YAML), with --start and --goal, as a SLAM user would run it."""

import json

import numpy as np
from PIL import Image

from rescuemesh.cli import main


def write_ros_map(folder):
    """A 10 x 5 m map at 0.05 m/cell: outer walls and an inner wall at x = 5 m with a 1.2 m doorway."""
    img = np.full((100, 200), 254, dtype=np.uint8)  # free (white); row 0 is the top (highest y)
    img[:2, :] = img[-2:, :] = img[:, :2] = img[:, -2:] = 0
    img[:, 99:101] = 0
    img[38:62, 99:101] = 254  # doorway: y from 1.9 to 3.1 m
    Image.fromarray(img).save(folder / "lab.pgm")
    (folder / "lab.yaml").write_text(
        "image: lab.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return folder / "lab.yaml"


def test_follow_on_a_ros_map(tmp_path):
    map_file = write_ros_map(tmp_path)
    out = tmp_path / "out"
    code = main(["run", "follow", "--map", str(map_file), "--quiet", "--out", str(out),
                 "--start", "robot_1=2.5,2.5,0", "--start", "robot_2=1.2,2.5,0", "--start", "robot_3=1.0,4.3,0",
                 "--goal", "8.5,2.5"])
    result = json.loads((out / "result.json").read_text())
    assert code == 0, result["criteria"]
    leader, follower = result["robots"]["robot_1"]["final_pose"], result["robots"]["robot_2"]["final_pose"]
    assert abs(leader["x"] - 8.5) < 0.2 and follower["x"] > 5.0  # both passed the doorway
    assert np.hypot(leader["x"] - follower["x"], leader["y"] - follower["y"]) <= 2.0


def test_ros_map_without_start_poses_asks_for_them(tmp_path, capsys):
    map_file = write_ros_map(tmp_path)
    assert main(["run", "follow", "--map", str(map_file), "--goal", "8,2.5", "--out", str(tmp_path / "o")]) == 2
    assert "--start" in capsys.readouterr().err
