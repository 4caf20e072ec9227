"""Sweep files: validated before anything runs, every error naming the file and the line."""

from pathlib import Path

import pytest

from rescuemesh.experiments import SweepError, load_sweep
from rescuemesh.experiments.spec import run_key

GOOD = """\
sweep: loss-and-relay
scenario: follow
options:
  radio: ble
axes:
  loss: [0.0, 0.2]
  relay: [true, false]
seeds: 3
report:
  metrics: [protocol.retries]
  plots:
    - {y: success, x: loss, lines: relay}
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "sweep.yaml"
    path.write_text(text)
    return path


def test_a_good_file_expands_to_every_combination_for_every_seed(tmp_path):
    sweep = load_sweep(write(tmp_path, GOOD))
    runs = list(sweep.runs())
    assert sweep.size == len(runs) == 2 * 2 * 3
    combos = {(r.option_dict()["loss"], r.option_dict()["relay"], r.seed) for r in runs}
    assert combos == {(loss, relay, seed) for loss in (0.0, 0.2) for relay in (True, False) for seed in range(3)}
    assert all(r.option_dict()["radio"] == "ble" for r in runs)
    assert len({r.key for r in runs}) == len(runs)


def test_a_run_key_depends_on_every_option_and_the_seed_but_not_on_their_order():
    base = run_key("follow", {"loss": 0.2, "relay": True}, 3, None)
    assert base == run_key("follow", {"relay": True, "loss": 0.2}, 3, None)
    assert base != run_key("follow", {"loss": 0.2, "relay": True}, 4, None)
    assert base != run_key("follow", {"loss": 0.3, "relay": True}, 3, None)
    assert base != run_key("stop", {"loss": 0.2, "relay": True}, 3, None)
    assert base != run_key("follow", {"loss": 0.2, "relay": True}, 3, "abc")


@pytest.mark.parametrize("seeds, expected", [("4", [0, 1, 2, 3]), ("[5, 9]", [5, 9]),
                                             ("{from: 10, count: 2}", [10, 11])])
def test_seeds_as_a_count_a_list_or_a_range(tmp_path, seeds, expected):
    sweep = load_sweep(write(tmp_path, f"scenario: follow\naxes:\n  loss: [0.1]\nseeds: {seeds}\n"))
    assert sweep.seeds == expected


@pytest.mark.parametrize("text, line, words", [
    ("scenario: follow\naxes:\n  loss: [0.1]\nseeds: 2\ncolour: red\n", 5, "unknown key 'colour'"),
    ("scenario: folow\naxes:\n  loss: [0.1]\nseeds: 2\n", 1, "unknown scenario 'folow'"),
    ("scenario: follow\naxes:\n  los: [0.1]\nseeds: 2\n", 3, "unknown option 'los'"),
    ("scenario: follow\naxes:\n  loss: [0.1, 1.5]\nseeds: 2\n", 3, "loss must be below 1"),
    ("scenario: follow\naxes:\n  loss: 0.1\nseeds: 2\n", 3, "must be a list"),
    ("scenario: follow\naxes:\n  relay: [yes-please]\nseeds: 2\n", 3, "relay must be true or false"),
    ("scenario: follow\naxes:\n  robots: [2.5]\nseeds: 2\n", 3, "robots must be a whole number"),
    ("scenario: follow\naxes:\n  loss: [0.1, 0.1]\nseeds: 2\n", 3, "lists a value twice"),
    ("scenario: follow\noptions:\n  loss: 0.1\naxes:\n  loss: [0.2]\nseeds: 2\n", 5, "both held fixed"),
    ("scenario: follow\naxes:\n  loss: [0.1]\nseeds: -1\n", 4, "a seed is a whole number"),
    ("scenario: follow\naxes:\n  loss: [0.1]\n", 1, "missing 'seeds'"),
    ("scenario: follow\naxes:\n  loss: [0.1]\nseeds: 2\nreport:\n  plots:\n    - {y: success, x: relay}\n", 7,
     "not an axis"),
    ("scenario: follow\naxes:\n  loss: [0.1\nseeds: 2\n", 4, "not valid YAML"),
    ("scenario: follow\naxes:\n  goal: [[1, 2, 3]]\nseeds: 2\n", 3, "goal must be [X, Y]"),
    ("scenario: follow\naxes:\n  loss: [0.1]\nseeds: 100000\naxes2: 1\n", 5, "unknown key"),
])
def test_a_bad_file_names_the_file_the_line_and_what_was_expected(tmp_path, text, line, words):
    path = write(tmp_path, text)
    with pytest.raises(SweepError) as caught:
        load_sweep(path)
    message = str(caught.value)
    assert message.startswith(f"{path}:{line}: "), message
    assert words in message
    assert "\n" not in message


def test_a_grid_too_large_is_refused_before_anything_runs(tmp_path):
    with pytest.raises(SweepError, match="at most 100000"):
        load_sweep(write(tmp_path, "scenario: follow\naxes:\n  loss: [0.1, 0.2]\nseeds: 60000\n"))


def test_a_missing_or_empty_file_is_an_error(tmp_path):
    with pytest.raises(SweepError, match="no such file"):
        load_sweep(tmp_path / "nope.yaml")
    with pytest.raises(SweepError, match="empty"):
        load_sweep(write(tmp_path, ""))


def test_the_example_sweeps_are_valid():
    root = Path(__file__).resolve().parents[2] / "sweeps"
    files = sorted(root.glob("*.yaml"))
    assert len(files) >= 2
    assert sum(load_sweep(path).size for path in files) >= 200
