"""trajectory.png: the view is cropped to the known part of the map and the robots' paths."""

from types import SimpleNamespace

import matplotlib.figure
import numpy as np
import pytest
from PIL import Image

from rescuemesh.geometry import Pose2D
from rescuemesh.maps import load_map
from rescuemesh.maps.model import office_map_path
from rescuemesh.report.plots import plot_trajectories, view_extent
from rescuemesh.runtime import TrajectorySample


def write_padded_slam_map(folder):
    """A 20 x 20 m map_server map (origin -10, -10) of unknown space, with a 5 x 5 m walled room
    (x and y from -2.5 to 2.5 m) in the middle, as a SLAM tool saves it."""
    img = np.full((400, 400), 205, dtype=np.uint8)  # unknown
    img[150:250, 150:250] = 0  # walls 0.1 m thick ...
    img[152:248, 152:248] = 254  # ... around free space
    Image.fromarray(img).save(folder / "slam.pgm")
    (folder / "slam.yaml").write_text("image: slam.pgm\nresolution: 0.05\norigin: [-10.0, -10.0, 0.0]\n"
                                      "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return load_map(folder / "slam.yaml")


def trajectories(**paths):
    return {name: [TrajectorySample(0.1 * i, Pose2D(x, y, 0.0), 0.2) for i, (x, y) in enumerate(points)]
            for name, points in paths.items()}


def test_a_padded_slam_map_is_cropped_to_the_room_plus_the_margin(tmp_path):
    # this used to show the whole 20 x 20 m image with the room a small patch in the middle
    slam = write_padded_slam_map(tmp_path)
    x0, x1, y0, y1 = view_extent(slam, trajectories(robot_1=[(-1.0, 0.0), (1.5, 1.0)]), 1.0)
    assert (x0, x1, y0, y1) == pytest.approx((-3.5, 3.5, -3.5, 3.5), abs=0.051)


def test_a_path_outside_the_known_area_stays_in_view_and_the_margin_is_clipped_to_the_map(tmp_path):
    slam = write_padded_slam_map(tmp_path)
    x0, x1, y0, y1 = view_extent(slam, trajectories(robot_1=[(0.0, 0.0), (6.0, 0.5)], robot_2=[(0.0, -9.8)]), 1.0)
    assert x0 == pytest.approx(-3.5, abs=0.051) and x1 == pytest.approx(7.0)
    assert y0 == pytest.approx(-10.0) and y1 == pytest.approx(3.5, abs=0.051)  # not below the map's edge


def test_the_office_keeps_its_whole_extent():
    office = load_map(office_map_path())
    extent = view_extent(office, trajectories(robot_1=[(6.6, 4.6), (15.4, 3.6)]), 1.0)
    assert extent == pytest.approx((0.0, 19.5, 0.0, 9.2))


def saved_limits(monkeypatch):
    """Record the axes limits of every figure saved."""
    seen = []
    save = matplotlib.figure.Figure.savefig

    def savefig(fig, *args, **kwargs):
        seen.append(fig.axes[0].get_xlim() + fig.axes[0].get_ylim())
        return save(fig, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", savefig)
    return seen


def test_trajectory_png_of_a_padded_map_shows_the_room_not_the_padding(tmp_path, monkeypatch):
    # this used to set the axes to the whole grid: x and y from -10 to 10 m
    slam = write_padded_slam_map(tmp_path)
    seen = saved_limits(monkeypatch)
    rt = SimpleNamespace(trajectories=trajectories(robot_1=[(-1.0, 0.0), (0.0, 0.5), (1.5, 1.0)],
                                                   robot_2=[(-1.8, -1.5), (-0.5, -1.0)]))
    path = plot_trajectories(rt, slam, tmp_path / "trajectory.png", title="padded SLAM map")
    assert path == tmp_path / "trajectory.png" and path.stat().st_size > 5_000
    (x0, x1, y0, y1), = seen
    assert -3.6 <= x0 and x1 <= 3.6 and -3.6 <= y0 and y1 <= 3.6
    assert x0 <= -2.5 and x1 >= 2.5 and y0 <= -2.5 and y1 >= 2.5  # the whole room


def test_trajectory_png_of_the_office_shows_the_whole_office(tmp_path, monkeypatch):
    office = load_map(office_map_path())
    seen = saved_limits(monkeypatch)
    rt = SimpleNamespace(trajectories=trajectories(robot_1=[(6.6, 4.6), (12.0, 4.6), (15.4, 3.6)],
                                                   robot_2=[(5.1, 4.6), (11.0, 4.6), (14.4, 4.0)]))
    plot_trajectories(rt, office, tmp_path / "trajectory.png", title="office")
    assert seen == [pytest.approx((0.0, 19.5, 0.0, 9.2))]


def test_unknown_space_is_drawn_lighter_than_walls_and_darker_than_free_space(tmp_path):
    # this used to draw unknown padding exactly as dark as the walls
    from rescuemesh.report.plots import FREE_SHADE, UNKNOWN_SHADE, WALL_SHADE, map_shades

    slam = write_padded_slam_map(tmp_path)
    shades = map_shades(slam)
    grid = slam.grid
    at = lambda x, y: shades[grid.world_to_cell(x, y)]  # noqa: E731
    assert at(-8.0, -8.0) == UNKNOWN_SHADE  # the padding
    assert at(-2.45, 0.0) == WALL_SHADE  # the room's west wall
    assert at(0.0, 0.0) == FREE_SHADE
    assert WALL_SHADE < UNKNOWN_SHADE < FREE_SHADE


def test_the_office_has_no_unknown_shade():
    from rescuemesh.report.plots import UNKNOWN_SHADE, map_shades

    office = load_map(office_map_path())
    shades = map_shades(office)
    assert not (shades == UNKNOWN_SHADE).any()
    assert (shades[office.grid.occupied] < UNKNOWN_SHADE).all()
