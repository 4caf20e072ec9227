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


def test_a_large_map_is_drawn_reduced_in_blocks_keeping_one_cell_walls(tmp_path, monkeypatch):
    # a 4000 x 4000 map used to be handed whole to imshow: 4 s of resampling and 0.5 GB more peak
    import numpy as np
    from PIL import Image

    from rescuemesh.maps import load_map
    from rescuemesh.report import plots

    img = np.full((1000, 1000), 254, dtype=np.uint8)
    img[:, 501] = 0  # a wall one cell thick
    Image.fromarray(img).save(tmp_path / "m.pgm")
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n")
    monkeypatch.setattr(plots, "MAX_MAP_PIXELS", 300)
    image, shown = plots._display_map(load_map(tmp_path / "m.yaml"), (0.0, 50.0, 0.0, 50.0))
    assert max(image.shape) <= 300 and shown[0] == 0.0 and shown[1] >= 50.0
    dark_columns = np.flatnonzero((image < 0.5).all(axis=0))
    assert len(dark_columns) == 1  # the wall survives the reduction, one column wide
    assert abs(shown[0] + (dark_columns[0] + 0.5) * (shown[1] - shown[0]) / image.shape[1] - 25.05) < 0.2
