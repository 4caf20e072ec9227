"""radio/validation.py and `rescuemesh radio-validate`: the model against measured BLE data (issue 20).

The figures are the model's; the goals are the issue's. A change to the model that breaks a goal
fails here, with the figure in the message.
"""

from __future__ import annotations

import pytest

from rescuemesh.radio import BleParams
from rescuemesh.radio.validation import (
    GOAL_MEAN_DB,
    GOAL_RMS_DB,
    validate_danis,
    validate_kolakowski,
)


@pytest.fixture(scope="module")
def kolakowski():
    return validate_kolakowski(BleParams())


@pytest.fixture(scope="module")
def danis():
    return validate_danis(BleParams())


def test_kolakowski_held_out_goals_per_wall_count(kolakowski):
    rows = {r.walls: r for r in kolakowski.rows}
    assert set(rows) == {0, 1, 2, 3, None}
    for walls in (0, 1, 2, 3, None):
        assert abs(rows[walls].mean_db) <= GOAL_MEAN_DB, rows[walls]
        assert rows[walls].rms_db <= GOAL_RMS_DB, rows[walls]
    assert rows[None].samples > 10_000  # the held-out half is half the data, not a corner of it


def test_kolakowski_three_walls_mean_within_goal(kolakowski):
    # this used to read +3.2 dB (the 11 held-out cells through 3 walls, 2 anchors): the straight
    # line clipped door jambs and wall corners and paid each whole wall (docs/radio.md)
    row = next(r for r in kolakowski.rows if r.walls == 3)
    assert abs(row.mean_db) <= GOAL_MEAN_DB
    assert row.cells >= 10


def test_walls_priced_on_the_straight_line_alone_miss_three_walls():
    """What meets the three-wall goal is the Fresnel-zone average, nothing fitted: priced on the
    straight line alone (wall_fresnel_rays 1), the same model misses it."""
    straight = {r.walls: r for r in validate_kolakowski(BleParams(wall_fresnel_rays=1)).rows}
    assert straight[3].mean_db > GOAL_MEAN_DB


def test_the_previous_model_missed_what_this_one_meets(kolakowski):
    # this used to be the model (n 4 from 1 m, 4.6 dB per wall): +11 dB at 3 walls, 7.7 dB RMS
    previous = {r.walls: r for r in kolakowski.previous_rows}
    assert previous[3].mean_db > 3 * GOAL_MEAN_DB
    assert previous[None].rms_db > GOAL_RMS_DB


def test_shadowing_matches_the_data(kolakowski, danis):
    p = BleParams()
    # the field's correlation falls to 1/e at 0.9 lattice spacings: the flat's residuals at 0.79 m
    assert kolakowski.decorrelation_fit_m == pytest.approx(0.9 * p.shadowing_decorrelation_m, rel=0.15)
    assert danis.spread_ci_db[0] <= p.shadowing_sigma_db <= danis.spread_ci_db[1]


def test_danis_line_of_sight_goals(danis):
    assert all(g.met for g in danis.goals), [g for g in danis.goals if not g.met]
    assert danis.exponent_ci[0] <= BleParams().path_loss_exponent <= danis.exponent_ci[1]
    assert abs(danis.holdout.mean_db) <= GOAL_MEAN_DB and danis.holdout.rms_db <= GOAL_RMS_DB


def test_free_space_slope_is_outside_the_danis_interval(danis):
    # why the line-of-sight exponent is 1.6 and not Friis' 2: the office's own fit excludes 2
    assert danis.exponent_ci[1] < 2.0


def test_the_command_prints_the_goals_and_draws_the_plot(tmp_path, capsys):
    from rescuemesh.cli import main

    rc = main(["radio-validate", "--data", "danis", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "goals met: 3 of 3" in out and "exponent 1.55" in out
    assert (tmp_path / "radio_validation.png").stat().st_size > 10_000
