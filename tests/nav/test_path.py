import numpy as np
import pytest

from rescuemesh.nav.path import Path, cumulative_lengths, point_at, project, slice_path

L_SHAPE = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])


def test_path_length_and_end():
    path = Path.from_points(L_SHAPE)
    assert path.length_m == pytest.approx(4.0)
    np.testing.assert_allclose(path.end, (2.0, 2.0))
    np.testing.assert_allclose(cumulative_lengths(L_SHAPE), [0.0, 2.0, 4.0])


def test_project_finds_arc_length_and_distance():
    s, d = project(L_SHAPE, np.array([1.0, 0.3]))
    assert s == pytest.approx(1.0) and d == pytest.approx(0.3)
    s, d = project(L_SHAPE, np.array([2.4, 1.5]))
    assert s == pytest.approx(3.5) and d == pytest.approx(0.4)


def test_project_respects_the_search_window():
    # a U-turn: the way back passes near the start; a window keeps the robot on its leg
    u_turn = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 0.4], [0.0, 0.4]])
    s, _ = project(u_turn, np.array([0.5, 0.25]), s_max=1.0)
    assert s == pytest.approx(0.5)
    s, _ = project(u_turn, np.array([0.5, 0.25]), s_min=3.0)
    assert s == pytest.approx(5.9)


def test_point_at_and_slice():
    np.testing.assert_allclose(point_at(L_SHAPE, 3.0), (2.0, 1.0))
    np.testing.assert_allclose(point_at(L_SHAPE, 10.0), (2.0, 2.0))
    part = slice_path(L_SHAPE, 1.0, 3.0)
    np.testing.assert_allclose(part, [[1.0, 0.0], [2.0, 0.0], [2.0, 1.0]])
    assert len(slice_path(L_SHAPE, 4.0, 4.0)) == 1
    assert len(slice_path(L_SHAPE, 1.0, 0.5)) == 1
