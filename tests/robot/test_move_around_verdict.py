"""MoveAround ends DONE only when the circle was driven (issue: a false DONE on a tight map)."""

import pytest

from rescuemesh.geometry import Pose2D
from rescuemesh.nav import GoalStatus, NavReason
from rescuemesh.nav.navigate import NavResult
from rescuemesh.protocol import Reason, ResultCode
from rescuemesh.robot.behaviours import MoveAroundBehaviour, circle_waypoints


class ScriptedNav:
    """A navigator whose goals end as scripted: True reached, False aborted (stuck)."""

    def __init__(self, outcomes):
        self.outcomes, self.goal_id, self._results = list(outcomes), None, []
        self._next = 1

    def send_goal(self, goal, now, **options):
        self.goal_id, self._next = self._next, self._next + 1
        reached = self.outcomes.pop(0)
        status = GoalStatus.SUCCEEDED if reached else GoalStatus.ABORTED
        self._results.append(NavResult(self.goal_id, status, NavReason.REACHED if reached else NavReason.STUCK, now))
        return self.goal_id

    def step(self, now, pose, scan):
        return (0.0, 0.0)

    def next_result(self):
        return self._results.pop(0) if self._results else None

    def cancel(self, now):
        self.goal_id = None


def run_circle(outcomes):
    points = circle_waypoints(Pose2D(0, 0), 0.6, 20, Pose2D(1, 0))
    behaviour = MoveAroundBehaviour(ScriptedNav(outcomes), points, [], 0.0)
    far = Pose2D(50, 50)  # never passes a waypoint on its own: every goal ends by the navigator
    for k in range(100):
        behaviour.step(0.05 * k, far, None)
        if behaviour.finished:
            break
    return behaviour


def test_a_circle_whose_waypoints_were_mostly_unreachable_fails_instead_of_done():
    # this used to report DONE after 125 s although robot_2 reached almost no waypoint
    behaviour = run_circle([True, True] + [False] * 19)
    assert (behaviour.outcome, behaviour.reason) == (ResultCode.FAILED, Reason.STUCK)
    assert (len(behaviour.waypoints), len(behaviour.unreached)) == (21, 19)  # reached 2 of 21


@pytest.mark.parametrize("unreached, outcome", [(0, ResultCode.DONE), (2, ResultCode.DONE), (3, ResultCode.FAILED)])
def test_a_circle_is_done_when_at_least_90_percent_of_waypoints_were_reached(unreached, outcome):
    behaviour = run_circle([False] * unreached + [True] * (21 - unreached))
    assert behaviour.outcome == outcome


def test_no_reachable_waypoint_is_blocked():
    assert run_circle([False] * 21).reason == Reason.BLOCKED
