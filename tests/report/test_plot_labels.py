"""Each plot is labelled for what it shows: judged on the figures a real run saves."""

import matplotlib.figure
import pytest

from rescuemesh.cli import main


@pytest.fixture
def saved(monkeypatch):
    """Every figure saved: file name -> its axes' legend texts and y limits."""
    figures = {}
    save = matplotlib.figure.Figure.savefig

    def savefig(fig, path, *args, **kwargs):
        figures[str(path).rsplit("/", 1)[-1]] = [
            ([t.get_text() for t in ax.get_legend().get_texts()] if ax.get_legend() else [], ax.get_ylim())
            for ax in fig.axes]
        return save(fig, path, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", savefig)
    return figures


def test_goto_trajectory_names_robot_2s_target_not_a_leader_goal(tmp_path, saved):
    # this used to label robot_2's Goto target "leader goal"
    main(["run", "goto", "--quiet", "--out", str(tmp_path)])
    (legend, _), = saved["trajectory.png"]
    assert "robot_2's Goto target" in legend and not any("leader" in text for text in legend)


def test_a_still_team_gets_a_speed_axis_that_shows_its_markers(tmp_path, saved):
    # this used to be -0.02..0 m/s with the markers at 0 cut in half (nobody moved)
    main(["run", "relay", "--no-relay", "--quiet", "--out", str(tmp_path)])
    (_, (bottom, top)), _ = saved["timeline.png"]
    assert bottom < 0 and top >= 0.1


def test_each_scan_png_marks_the_spot_asked_for(tmp_path, saved):
    # this used to draw the scan without the spot robot_1 asked about
    assert main(["run", "show-scan", "--quiet", "--out", str(tmp_path)]) == 0
    scans = [name for name in saved if name.startswith("scan_")]
    assert len(scans) == 3
    for name in scans:
        (legend, _), = saved[name]
        assert "spot asked for (11.30, 7.60)" in legend
    (legend, _), = saved["trajectory.png"]
    assert "spot asked for" in legend
