"""Plots stay readable for a team of 30: colours, legend entries."""

from rescuemesh.report.plots import COLOURS, LEGEND_EVERY, SMALL_TEAM, legend_label, robot_colours
from rescuemesh.scenarios.team import team_names


def test_a_small_team_keeps_its_colours_and_every_robot_is_distinct():
    # robot_4 used to get matplotlib's next cycle colour, the same red as robot_2 in a six-robot convoy
    colours = robot_colours(team_names(6))
    assert all(colours[n] == COLOURS[n] for n in ("robot_1", "robot_2", "robot_3"))
    assert len(set(colours.values())) == 6


def test_a_team_of_thirty_runs_along_a_colour_map_and_names_every_fifth():
    names = team_names(30)
    colours = robot_colours(names)
    assert len(set(colours.values())) == 30
    labelled = [legend_label(names, i) for i in range(30)]
    assert [n for n in labelled if n] == ["robot_1", "robot_5", "robot_10", "robot_15", "robot_20", "robot_25",
                                          "robot_30"]
    assert LEGEND_EVERY == 5 and SMALL_TEAM == 10
