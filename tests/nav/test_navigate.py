import math

import pytest
from navworld import drive, fake_scan, room_with_door

from rescuemesh.geometry import Pose2D, wrap_angle
from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.nav import Costmap, GoalStatus, NavigateToPose, NavParams, NavReason, NavResult

DOOR_GOAL = Pose2D(5.0, 3.0, math.pi / 2)


def results(nav) -> list[NavResult]:
    out = []
    while (r := nav.next_result()) is not None:
        out.append(r)
    return out


def test_idle_action_commands_nothing(room_costmap):
    nav = NavigateToPose(room_costmap)
    assert nav.status is GoalStatus.IDLE
    assert nav.step(0.0, Pose2D(1.0, 1.0), None) == (0.0, 0.0)
    assert nav.feedback is None and nav.next_result() is None and nav.path is None and nav.goal is None
    nav.cancel(0.0)
    assert nav.next_result() is None


def test_reaches_a_goal_through_the_doorway_exactly_once(room_costmap):
    nav = NavigateToPose(room_costmap)
    gid = nav.send_goal(DOOR_GOAL, 0.0)
    run = drive(nav, Pose2D(1.0, 1.0, 0.0), 0.0, 40.0)
    assert nav.status is GoalStatus.SUCCEEDED
    assert run.pose.distance_to(DOOR_GOAL) <= 0.15
    assert abs(wrap_angle(run.pose.yaw - DOOR_GOAL.yaw)) <= 0.3
    assert results(nav) == [NavResult(gid, GoalStatus.SUCCEEDED, NavReason.REACHED, run.last_step)]
    assert drive(nav, run.pose, run.now, 1.0, until_done=False).commands == [(0.0, 0.0)] * 20
    assert nav.next_result() is None


def test_feedback_distance_decreases(room_costmap):
    nav = NavigateToPose(room_costmap)
    nav.send_goal(DOOR_GOAL, 0.0)
    pose, now, seen = Pose2D(1.0, 1.0, 0.0), 0.0, []
    for _ in range(8):
        run = drive(nav, pose, now, 1.0)
        pose, now = run.pose, run.now
        assert nav.feedback is not None and nav.feedback.goal_id == nav.goal_id
        seen.append(nav.feedback.distance_remaining_m)
    assert all(b < a for a, b in zip(seen[1:], seen[2:]))  # the first second is mostly turning
    assert seen[-1] < seen[0] - 2.0


def test_a_new_goal_preempts_the_running_one(room_costmap):
    nav = NavigateToPose(room_costmap)
    first = nav.send_goal(DOOR_GOAL, 0.0)
    run = drive(nav, Pose2D(1.0, 1.0, 0.0), 0.0, 2.0)
    second = nav.send_goal(Pose2D(1.0, 3.0, 0.0), run.now)
    assert second != first and nav.goal_id == second
    assert results(nav) == [NavResult(first, GoalStatus.CANCELED, NavReason.PREEMPTED, run.now)]
    run = drive(nav, run.pose, run.now, 30.0)
    assert [(r.goal_id, r.status) for r in results(nav)] == [(second, GoalStatus.SUCCEEDED)]


def test_update_goal_moves_the_goal_without_a_result(room_costmap):
    nav = NavigateToPose(room_costmap)
    gid = nav.send_goal(DOOR_GOAL, 0.0)
    run = drive(nav, Pose2D(1.0, 1.0, 0.0), 0.0, 2.0)
    assert nav.update_goal(Pose2D(1.0, 3.0, 0.0), run.now)
    assert nav.next_result() is None and nav.goal_id == gid
    drive(nav, run.pose, run.now, 30.0)
    assert [(r.goal_id, r.status) for r in results(nav)] == [(gid, GoalStatus.SUCCEEDED)]
    assert not nav.update_goal(DOOR_GOAL, run.now)


def test_a_goal_nudged_a_little_extends_the_path_without_a_new_plan(room_costmap):
    # a follower's goal moves ~0.5 m per PoseUpdate: that used to throw the path away and plan again
    nav = NavigateToPose(room_costmap)
    nav.send_goal(DOOR_GOAL, 0.0)
    run = drive(nav, Pose2D(1.0, 1.0, 0.0), 0.0, 0.5)
    planned = nav.path
    nudged = Pose2D(DOOR_GOAL.x, DOOR_GOAL.y + 0.5, DOOR_GOAL.yaw)
    assert nav.update_goal(nudged, run.now)
    assert nav.path is not None and nav.path.points[:-1].tolist() == planned.points.tolist()
    assert nav.path.end.tolist() == [nudged.x, nudged.y]
    drive(nav, run.pose, run.now, 30.0)
    assert [r.status for r in results(nav)] == [GoalStatus.SUCCEEDED]


def test_a_goal_moved_far_or_behind_a_wall_is_planned_again(room_costmap):
    nav = NavigateToPose(room_costmap)
    nav.send_goal(DOOR_GOAL, 0.0)
    run = drive(nav, Pose2D(1.0, 1.0, 0.0), 0.0, 0.5)
    assert nav.update_goal(Pose2D(1.0, 3.0, 0.0), run.now)  # 4 m from the path's end: no extension
    assert nav.path is None
    east_of_wall = Pose2D(3.6, 3.0, 0.0)  # the wall is x 3.0..3.1 (doorway y 1.5..2.5)
    nav.send_goal(east_of_wall, run.now)
    run = drive(nav, run.pose, run.now, 0.5)
    assert nav.path is not None and nav.path.end.tolist() == [3.6, 3.0]
    assert nav.update_goal(Pose2D(2.7, 3.0, 0.0), run.now)  # 0.9 m away, but through the wall
    assert nav.path is None


def test_cancel_stops_and_reports_canceled(room_costmap):
    nav = NavigateToPose(room_costmap)
    gid = nav.send_goal(DOOR_GOAL, 0.0)
    run = drive(nav, Pose2D(1.0, 1.0, 0.0), 0.0, 3.0)
    assert run.commands[-1] != (0.0, 0.0)
    nav.cancel(run.now)
    assert nav.status is GoalStatus.CANCELED
    assert nav.step(run.now, run.pose, None) == (0.0, 0.0)
    nav.cancel(run.now + 0.05)
    assert results(nav) == [NavResult(gid, GoalStatus.CANCELED, NavReason.CANCELED, run.now)]


@pytest.mark.parametrize("goal", [Pose2D(5.0, 3.0), Pose2D(3.05, 0.5)], ids=["walled-off", "in-a-wall"])
def test_unreachable_goal_aborts_with_no_path(goal):
    grid = room_with_door()
    occ = grid.occupied.copy()
    occ[:, 60:62] = True
    nav = NavigateToPose(Costmap(OccupancyGrid(occ, grid.resolution, 0.0, 0.0)))
    gid = nav.send_goal(goal, 0.0)
    assert nav.step(0.0, Pose2D(1.0, 1.0), None) == (0.0, 0.0)
    assert nav.status is GoalStatus.ABORTED
    assert results(nav) == [NavResult(gid, GoalStatus.ABORTED, NavReason.NO_PATH, 0.0)]


def test_stop_distance_stops_with_about_that_much_path_left(corridor_costmap):
    nav = NavigateToPose(corridor_costmap)
    goal = Pose2D(6.0, 1.1, math.pi)
    nav.send_goal(goal, 0.0, stop_distance=1.0)
    run = drive(nav, Pose2D(1.0, 1.1, 0.0), 0.0, 20.0)
    assert nav.status is GoalStatus.SUCCEEDED
    assert 0.95 <= run.pose.distance_to(goal) <= 1.0
    assert abs(run.commands[-1][0]) < 0.1  # it was slowing down to stop there, not cruising through


def test_follower_plans_to_its_leader_but_never_rams_it(corridor_costmap):
    leader = (6.0, 1.1, 0.177)
    nav = NavigateToPose(corridor_costmap)
    nav.send_goal(Pose2D(6.0, 1.1), 0.0, stop_distance=1.0, clear_radius=0.5)
    run = drive(nav, Pose2D(1.0, 1.1, 0.0), 0.0, 20.0, discs=[leader])
    assert nav.status is GoalStatus.SUCCEEDED
    assert 0.9 <= math.hypot(run.pose.x - 6.0, run.pose.y - 1.1) <= 1.05


def test_robot_in_the_way_is_driven_around(corridor_costmap):
    other = (4.0, 1.1, 0.2)
    nav = NavigateToPose(corridor_costmap)
    nav.send_goal(Pose2D(7.0, 1.1, 0.0), 0.0)
    pose, now, closest = Pose2D(1.0, 1.1, 0.0), 0.0, math.inf
    while nav.status is GoalStatus.ACTIVE and now < 30.0:
        run = drive(nav, pose, now, 0.5, discs=[other])
        pose, now = run.pose, run.now
        closest = min(closest, math.hypot(pose.x - 4.0, pose.y - 1.1))
    assert nav.status is GoalStatus.SUCCEEDED
    assert closest >= 0.177 + 0.2


def test_blocked_doorway_ends_stuck(room_costmap):
    blocker = (3.05, 2.0, 0.3)  # fills the doorway: no path around, the controller stops short
    nav = NavigateToPose(room_costmap, params=NavParams(stuck_timeout_s=3.0))
    gid = nav.send_goal(DOOR_GOAL, 0.0)
    run = drive(nav, Pose2D(1.0, 2.0, 0.0), 0.0, 20.0, discs=[blocker])
    assert results(nav) == [NavResult(gid, GoalStatus.ABORTED, NavReason.STUCK, run.last_step)]
    assert math.hypot(run.pose.x - 3.05, run.pose.y - 2.0) > 0.3 + 0.177


def test_start_brushing_a_wall_still_gets_out(room_costmap):
    nav = NavigateToPose(room_costmap)
    nav.send_goal(Pose2D(1.5, 2.0, 0.0), 0.0, check_yaw=False)
    drive(nav, Pose2D(0.22, 1.0, math.pi / 2), 0.0, 20.0)
    assert nav.status is GoalStatus.SUCCEEDED


def test_scan_is_read_once_per_sweep(room_costmap):
    nav = NavigateToPose(room_costmap)
    nav.send_goal(DOOR_GOAL, 0.0)
    scan = fake_scan(Pose2D(1.0, 1.0), [(2.0, 1.0, 0.2)], 0.0)
    nav.step(0.0, Pose2D(1.0, 1.0), scan)
    cm = nav._costmap_for(nav._goal)
    nav.step(0.05, Pose2D(1.0, 1.0), scan)
    assert nav._costmap_for(nav._goal) is cm
    assert not cm.is_free(1.85, 1.0)


def test_goal_close_in_front_of_an_obstacle_is_reached(corridor_costmap):
    post = (5.5, 1.1, 0.2)  # its surface 0.3 m beyond the goal: closer than the controller's stop distance
    nav = NavigateToPose(corridor_costmap)
    nav.send_goal(Pose2D(5.0, 1.1, 0.0), 0.0)
    run = drive(nav, Pose2D(1.0, 1.1, 0.0), 0.0, 20.0, discs=[post])
    assert nav.status is GoalStatus.SUCCEEDED
    assert math.hypot(run.pose.x - 5.5, run.pose.y - 1.1) > 0.2 + 0.177
