import numpy as np
import pytest

from reference_polyline import point_at, project, slice_path

from rescuemesh.nav.path import Path, Polyline, cumulative_lengths

L_SHAPE = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])


def test_path_length_and_end():
    path = Path.from_points(L_SHAPE)
    assert path.length_m == pytest.approx(4.0)
    np.testing.assert_allclose(path.end, (2.0, 2.0))
    np.testing.assert_allclose(cumulative_lengths(L_SHAPE), [0.0, 2.0, 4.0])


def test_project_finds_arc_length_and_distance():
    line = Polyline.from_points(L_SHAPE)
    s, d = line.project(1.0, 0.3)
    assert s == pytest.approx(1.0) and d == pytest.approx(0.3)
    s, d = line.project(2.4, 1.5)
    assert s == pytest.approx(3.5) and d == pytest.approx(0.4)


def test_project_respects_the_search_window():
    # a U-turn: the way back passes near the start; a window keeps the robot on its leg
    u_turn = Polyline.from_points(np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 0.4], [0.0, 0.4]]))
    s, _ = u_turn.project(0.5, 0.25, s_max=1.0)
    assert s == pytest.approx(0.5)
    s, _ = u_turn.project(0.5, 0.25, s_min=3.0)
    assert s == pytest.approx(5.9)


def test_point_at_and_slice():
    line = Polyline.from_points(L_SHAPE)
    np.testing.assert_allclose(line.point_at(3.0), (2.0, 1.0))
    np.testing.assert_allclose(line.point_at(10.0), (2.0, 2.0))
    part = line.slice(1.0, 3.0)
    np.testing.assert_allclose(part.to_array(), [[1.0, 0.0], [2.0, 0.0], [2.0, 1.0]])
    assert len(line.slice(4.0, 4.0)) == 1
    assert len(line.slice(1.0, 0.5)) == 1


U_TURN = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 0.4], [3.0, 0.4], [0.0, 0.4]])  # with a zero-length segment


@pytest.mark.parametrize("points", [L_SHAPE, U_TURN, L_SHAPE[:1]], ids=["L", "U-turn", "one-point"])
def test_polyline_agrees_with_the_numpy_reference(points):
    line = Polyline.from_points(points)
    assert line.length == pytest.approx(cumulative_lengths(points)[-1])
    for xy in [(1.0, 0.3), (2.4, 1.5), (0.5, 0.25), (3.2, 0.45), (-1.0, -1.0)]:
        for s_min, s_max in [(0.0, np.inf), (0.0, 1.0), (3.0, 5.0), (3.0, 1.0), (9.0, 12.0)]:
            expected = project(points, np.array(xy), s_min=s_min, s_max=s_max)
            assert line.project(*xy, s_min=s_min, s_max=s_max) == pytest.approx(expected, abs=1e-12)
    for s in (-1.0, 0.0, 1.5, 2.0, 3.2, 10.0):
        np.testing.assert_allclose(line.point_at(s), point_at(points, s), atol=1e-12)
    for s0, s1 in [(1.0, 3.0), (4.0, 4.0), (1.0, 0.5), (0.0, np.inf), (2.0, 2.0 + 1e-12), (3.0, 3.2)]:
        part = line.slice(s0, s1)
        np.testing.assert_allclose(part.to_array(), slice_path(points, s0, s1), atol=1e-12)
        np.testing.assert_allclose(part.cum, cumulative_lengths(part.to_array()), atol=1e-12)


def test_path_computes_its_geometry_once():
    path = Path.from_points(L_SHAPE)
    assert path.polyline is path.polyline and path.cum is path.cum
    np.testing.assert_allclose(path.cum, [0.0, 2.0, 4.0])
    assert path.polyline.xs == [0.0, 2.0, 2.0] and path.polyline.length == path.length_m
