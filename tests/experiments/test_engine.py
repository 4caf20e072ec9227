"""Sweeps end to end: rows kept as runs finish, resumed without redoing, the same rows on one
worker, on two and on Ray, a dying worker a row and not the end, Ctrl-C leaving nothing behind."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rescuemesh.experiments import LocalPool, RunStatus, load_rows, load_sweep, run_sweep
from rescuemesh.experiments.engine import comparable

# Short runs: a follow cut at 2 simulated seconds (its verdict fails: a row is a row either way).
TINY = """\
sweep: tiny
scenario: follow
options:
  time_limit: 2
axes:
  loss: [0.0, 0.3]
seeds: 2
"""


def tiny(tmp_path: Path, text: str = TINY):
    path = tmp_path / "tiny.yaml"
    path.write_text(text)
    return load_sweep(path)


def by_key(rows):
    return {r["run_key"]: comparable(r) for r in rows}


def test_a_sweep_writes_a_row_per_run_and_resumes_without_redoing(tmp_path):
    sweep = tiny(tmp_path)
    out = tmp_path / "out"
    first = run_sweep(sweep, out, LocalPool(2))
    assert (first.total, first.skipped, first.ran) == (4, 0, 4)
    rows = load_rows(out)
    assert sorted((r["loss"], r["seed"]) for r in rows) == [(0.0, 0), (0.0, 1), (0.3, 0), (0.3, 1)]
    assert {r["status"] for r in rows} <= {"success", "failed"}
    assert all(r["sim_time_s"] == pytest.approx(2.0, abs=0.1) for r in rows)
    # one row lost (as a crash would before its write): only that run is done again
    victim = rows[0]["run_key"]
    (out / "rows" / f"{victim}.json").unlink()
    again = run_sweep(sweep, out, LocalPool(1))
    assert (again.skipped, again.ran) == (3, 1)
    assert by_key(load_rows(out)) == by_key(rows)
    # the tables hold every row, configuration first
    import pyarrow.parquet as pq

    table = pq.read_table(out / "results.parquet")
    assert table.num_rows == 4
    assert table.column_names[:4] == ["run_key", "scenario", "seed", "loss"]
    assert (out / "results.csv").read_text().count("\n") == 5


def test_the_same_rows_on_one_worker_on_two_and_on_ray(tmp_path):
    sweep = tiny(tmp_path)
    one = tmp_path / "one"
    run_sweep(sweep, one, LocalPool(1))
    two = tmp_path / "two"
    run_sweep(sweep, two, LocalPool(2))
    assert by_key(load_rows(one)) == by_key(load_rows(two))
    pytest.importorskip("ray")
    from rescuemesh.experiments import RayExecutor

    on_ray = tmp_path / "ray"
    run_sweep(sweep, on_ray, RayExecutor("local", 2))
    assert by_key(load_rows(one)) == by_key(load_rows(on_ray))


def test_a_worker_that_dies_is_a_crashed_row_and_the_sweep_goes_on(tmp_path):
    from experiments.fakes import die_on_seed_1

    sweep = tiny(tmp_path)
    out = tmp_path / "out"
    summary = run_sweep(sweep, out, LocalPool(1, task=die_on_seed_1))
    rows = load_rows(out)
    assert len(rows) == 4 and summary.ran == 4
    crashed = [r for r in rows if r["status"] == RunStatus.CRASHED.value]
    assert sorted((r["loss"], r["seed"]) for r in crashed) == [(0.0, 1), (0.3, 1)]
    assert all(r["status"] in ("success", "failed") for r in rows if r["seed"] == 0)


def test_a_run_that_raises_is_an_error_row(tmp_path):
    # goal outside the map: the scenario refuses it when it is built, inside the worker
    sweep = tiny(tmp_path, TINY.replace("  time_limit: 2\n", "  time_limit: 2\n  goal: [500, 500]\n"))
    out = tmp_path / "out"
    run_sweep(sweep, out, LocalPool(1))
    rows = load_rows(out)
    assert len(rows) == 4
    assert all(r["status"] == "error" and r["success"] is False for r in rows)
    assert all(r["error"] and "500" in r["error"] for r in rows)


def test_another_sweep_in_the_same_folder_is_refused(tmp_path):
    from rescuemesh.experiments import SweepError

    out = tmp_path / "out"
    run_sweep(tiny(tmp_path), out, LocalPool(1))
    with pytest.raises(SweepError, match="holds another sweep"):
        run_sweep(tiny(tmp_path, TINY.replace("seeds: 2", "seeds: 3")), out, LocalPool(1))


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def test_ctrl_c_stops_cleanly_and_the_same_command_resumes(tmp_path):
    path = tmp_path / "sweep.yaml"
    path.write_text(TINY.replace("seeds: 2", "seeds: 6").replace("time_limit: 2", "time_limit: 6"))
    out = tmp_path / "out"
    command = [sys.executable, "-m", "rescuemesh", "sweep", str(path), "--out", str(out), "--workers", "1", "--quiet"]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    deadline = time.monotonic() + 120
    while not list((out / "rows").glob("*.json")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.2)
    assert list((out / "rows").glob("*.json")), "no run finished in time"
    os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole group
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "interrupted" in stderr and "resume" in stderr
    assert "Traceback" not in stderr
    deadline = time.monotonic() + 10
    while _group_alive(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _group_alive(proc.pid), "a worker outlived the sweep"
    kept = len(list((out / "rows").glob("*.json")))
    assert 1 <= kept < 12
    done = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert f"{kept} already done, {12 - kept} run now" in done.stdout
    assert len(load_rows(out)) == 12


def test_the_command_refuses_bad_input_with_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("scenario: follow\naxes:\n  loss: [2]\nseeds: 1\n")
    result = subprocess.run([sys.executable, "-m", "rescuemesh", "sweep", str(bad), "--out", str(tmp_path / "o")],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert result.stderr.strip().count("\n") == 0
    assert f"{bad}:3:" in result.stderr and "loss must be below 1" in result.stderr
    result = subprocess.run([sys.executable, "-m", "rescuemesh", "report", str(tmp_path)],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and "not a sweep folder" in result.stderr


def test_a_sweep_over_a_mission_file_runs_the_mission(tmp_path):
    mission = Path(__file__).resolve().parents[2] / "missions" / "forwarded-show-scan.yaml"
    path = tmp_path / "s.yaml"
    path.write_text(f"mission: {mission}\naxes:\n  loss: [0.0]\nseeds: 1\n")
    sweep = load_sweep(path)
    assert sweep.scenario == "forwarded-show-scan"
    out = tmp_path / "out"
    run_sweep(sweep, out, LocalPool(1))
    (row,) = load_rows(out)
    assert row["status"] == "success" and row["metrics.scan_result"] == "DONE"
    bad = tmp_path / "bad.yaml"
    bad.write_text(f"mission: {mission}\naxes:\n  robots: [3]\nseeds: 1\n")
    from rescuemesh.experiments import SweepError

    with pytest.raises(SweepError, match="not a mission setting"):
        load_sweep(bad)
