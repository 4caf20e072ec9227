"""Teams of N: automatic start poses behind the leader, and the convoy scenario's set-up."""

import math

import numpy as np
import pytest
from PIL import Image

from rescuemesh.geometry import Pose2D
from rescuemesh.maps import load_map
from rescuemesh.maps.model import office_map_path
from rescuemesh.scenarios import ScenarioError, ScenarioOptions, get_scenario
from rescuemesh.scenarios.base import MIN_START_SEPARATION_M, START_CLEARANCE_M, _clearance
from rescuemesh.scenarios.convoy import OFFICE_LEADER_START
from rescuemesh.scenarios.team import PlacementError, place_behind, team_names


@pytest.fixture(scope="module")
def office():
    return load_map(office_map_path())


def convoy_starts(map_model, robots=None, goal=None, **starts):
    return get_scenario("convoy")(ScenarioOptions(robots=robots, goal=goal, starts=starts), map_model).starts()


def test_team_names_run_from_robot_1():
    assert team_names(3) == ("robot_1", "robot_2", "robot_3")


def test_thirty_robots_start_in_the_east_rooms_clear_of_walls_and_of_each_other(office):
    starts = convoy_starts(office, robots=30)
    assert list(starts) == list(team_names(30))
    assert starts["robot_1"] == OFFICE_LEADER_START
    poses = list(starts.values())
    for name, pose in starts.items():
        assert office.region_of(pose.x, pose.y) in ("room_east", "room_northeast"), name
        assert _clearance(office.grid, pose.x, pose.y, 0.5) >= START_CLEARANCE_M
    gaps = [p.distance_to(q) for i, p in enumerate(poses) for q in poses[i + 1:]]
    assert min(gaps) >= MIN_START_SEPARATION_M


def test_each_robot_starts_a_lattice_step_from_the_one_it_follows(office):
    # numbered by distance to the goal, robot_3 started on the far side of robot_1 from robot_2, drove
    # round it into the doorway while the chain formed, and the leader was stuck there for good
    starts = list(convoy_starts(office, robots=30).values())
    steps = [a.distance_to(b) for a, b in zip(starts, starts[1:])]
    assert sum(step <= 0.96 for step in steps) >= len(steps) - 2  # a snake through the lattice
    assert max(steps) < 2.5


def test_on_an_open_map_the_team_is_placed_behind_the_leader_away_from_the_goal(tmp_path):
    img = np.full((120, 200), 254, dtype=np.uint8)  # 10 m x 6 m, free, 0.05 m cells
    img[0, :] = img[-1, :] = img[:, 0] = img[:, -1] = 0
    Image.fromarray(img).save(tmp_path / "open.pgm")
    (tmp_path / "open.yaml").write_text("image: open.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n")
    open_map = load_map(tmp_path / "open.yaml")
    poses = place_behind(open_map.grid, Pose2D(5.0, 3.0, 0.0), (9.0, 3.0), 8)
    assert poses[0] == Pose2D(5.0, 3.0, 0.0)
    # nobody starts nearer the goal than the leader (4 m); here the open space makes that a straight line
    assert all(math.hypot(9.0 - p.x, 3.0 - p.y) >= 4.0 - 0.1 for p in poses)
    assert all(abs(p.yaw) <= math.pi / 4 + 1e-9 for p in poses[1:])  # facing the goal (east), 8-connected
    starts = convoy_starts(open_map, robots=5, goal=Pose2D(9.0, 3.0, 0.0), robot_1=Pose2D(5.0, 3.0, 0.0))
    assert list(starts) == list(team_names(5))


def test_a_map_too_small_for_the_team_says_how_many_fit(office):
    with pytest.raises(ScenarioError, match=r"convoy of 60 on map 'small_office': room for 45 robots"):
        convoy_starts(office, robots=60)


def test_a_leader_walled_off_from_the_goal_is_refused(office):
    with pytest.raises(PlacementError, match="has no path to the goal"):
        place_behind(office.grid, Pose2D(5.0, 4.6, 0.0), (0.05, 0.05), 3)


def test_a_given_start_overrides_the_automatic_one(office):
    starts = convoy_starts(office, robots=4, robot_3=Pose2D(16.0, 1.0, 0.0))
    assert starts["robot_3"] == Pose2D(16.0, 1.0, 0.0)
