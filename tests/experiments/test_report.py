"""The report: Wilson and bootstrap intervals, grouping by the sweep's axes, labelled plots."""

import math
from pathlib import Path

import pytest

from rescuemesh.experiments import load_sweep
from rescuemesh.experiments.report import bootstrap_mean, draw_plot, format_table, summarise, wilson
from rescuemesh.experiments.spec import PlotSpec


def test_wilson_interval_matches_the_textbook_value():
    # Wilson score interval for 8 of 10 at 95 % (Agresti & Coull 1998): 0.490 .. 0.943
    iv = wilson(8, 10)
    assert iv.estimate == 0.8
    assert iv.low == pytest.approx(0.4902, abs=5e-4)
    assert iv.high == pytest.approx(0.9433, abs=5e-4)
    all_ok = wilson(5, 5)
    assert all_ok.high == 1.0 and all_ok.low == pytest.approx(0.5655, abs=5e-4)
    assert math.isnan(wilson(0, 0).estimate)


def test_bootstrap_interval_holds_the_mean_and_narrows_with_more_samples():
    few = bootstrap_mean([1.0, 2.0, 3.0, 4.0])
    many = bootstrap_mean([1.0, 2.0, 3.0, 4.0] * 25)
    assert few.estimate == many.estimate == 2.5
    assert few.low < 2.5 < few.high
    assert (many.high - many.low) < (few.high - few.low)
    assert bootstrap_mean([1.0, 2.0, 3.0, 4.0]) == few  # a fixed resampling seed: the same report twice
    same = bootstrap_mean([0.7, 0.7, 0.7])
    assert (same.low, same.estimate, same.high) == (0.7, 0.7, 0.7)
    assert bootstrap_mean([None, float("nan")]).n == 0


def sweep_file(tmp_path: Path):
    path = tmp_path / "s.yaml"
    path.write_text("scenario: follow\naxes:\n  loss: [0.0, 0.2]\n  relay: [true, false]\nseeds: 3\n")
    return load_sweep(path)


def rows_for(sweep):
    rows = []
    for spec in sweep.runs():
        o = spec.option_dict()
        ok = not (o["loss"] == 0.2 and not o["relay"] and spec.seed == 0)
        rows.append({"run_key": spec.key, "loss": o["loss"], "relay": o["relay"], "seed": spec.seed,
                     "status": "success" if ok else "failed", "success": ok,
                     "protocol.retries": 10 * o["loss"] + spec.seed})
    rows.append({"run_key": "x", "loss": 0.0, "relay": True, "seed": 9, "status": "error", "success": False})
    return rows


def test_summary_groups_rows_by_point_and_leaves_errors_out_of_the_rates(tmp_path):
    sweep = sweep_file(tmp_path)
    points = summarise(sweep, rows_for(sweep), ["protocol.retries"])
    assert [p.point for p in points] == [(("loss", 0.0), ("relay", True)), (("loss", 0.0), ("relay", False)),
                                         (("loss", 0.2), ("relay", True)), (("loss", 0.2), ("relay", False))]
    first, _, _, last = points
    assert (first.runs, first.errors, first.success.n, first.success.estimate) == (4, 1, 3, 1.0)
    assert last.success.estimate == pytest.approx(2 / 3)
    assert last.metrics["protocol.retries"].estimate == pytest.approx(3.0)
    text = format_table(sweep, points, ["protocol.retries"])
    assert "loss=0.2, relay=False: 3 runs; success 0.67 [" in text
    assert "1 error/crashed" in text


def test_a_plot_is_labelled_with_its_axes_lines_and_interval(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    sweep = sweep_file(tmp_path)
    saved = {}
    monkeypatch.setattr(plt, "close", lambda fig: saved.setdefault("fig", fig))
    path = draw_plot(sweep, rows_for(sweep), PlotSpec("protocol.retries", "loss", "relay"), tmp_path / "p.png")
    assert path.stat().st_size > 1000
    ax = saved["fig"].axes[0]
    assert ax.get_xlabel() == "loss" and ax.get_ylabel() == "protocol.retries"
    assert "95 % interval over 3 seeds" in ax.get_title()
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["relay = True", "relay = False"]
    assert len(ax.collections) == 2  # one interval band per line
