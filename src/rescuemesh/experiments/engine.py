"""A sweep end to end: every run of the grid not yet done, on an executor, rows kept as they come.

Owns: the sweep's folder (`sweep.yaml` as run, `rows/KEY.json` one per finished run, written
atomically the moment it arrives, `results.parquet` and `results.csv` gathered from them), resuming
(finished keys are skipped), the progress line, and Ctrl-C (workers stopped, finished rows kept).
Must not know: how one run works (worker.py) or where workers live (executors.py).
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rescuemesh.experiments.executors import Executor, LocalPool
from rescuemesh.experiments.spec import OPTIONS, Sweep, SweepError
from rescuemesh.experiments.worker import WALL_CLOCK_COLUMNS, RunStatus

ROWS_DIR = "rows"
#: The tables' first columns: what the run was, then how it ended; the measured columns follow by name.
FIRST_COLUMNS = ("run_key", "scenario", "seed", *OPTIONS, "status", "success", "error", "criteria_failed",
                 "sim_time_s", "wall_time_s", "real_time_factor", "worker_s")
STATE_FILE = "sweep.json"


@dataclass
class SweepSummary:
    """What a sweep call did: runs in the grid, skipped as already done, run now, by status."""

    total: int
    skipped: int
    ran: int
    by_status: dict[str, int]
    interrupted: bool
    wall_s: float
    out: Path


def prepare_folder(sweep: Sweep, out: Path) -> None:
    """Create `out` for this sweep, or check that it already holds this same sweep (resume)."""
    state = out / STATE_FILE
    identity = {"sweep": sweep.name, "identity": sweep.identity(), "scenario": sweep.scenario}
    try:
        if state.exists():
            held = json.loads(state.read_text())
            if held.get("identity") != identity["identity"]:
                raise SweepError(f"{out} holds another sweep ({held.get('sweep')!r}, a different grid): "
                                 f"give another --out, or remove the folder")
        (out / ROWS_DIR).mkdir(parents=True, exist_ok=True)
        _write_atomic(state, json.dumps(identity, indent=2) + "\n")
        if sweep.path.resolve() != (out / "sweep.yaml").resolve():
            shutil.copyfile(sweep.path, out / "sweep.yaml")
    except OSError as error:
        raise SweepError(f"cannot use output folder {str(out)!r}: {error.strerror or error}") from None
    except json.JSONDecodeError:
        raise SweepError(f"{state} is not a sweep state file: give another --out") from None


def finished_keys(out: Path) -> set[str]:
    return {p.stem for p in (out / ROWS_DIR).glob("*.json")}


def load_rows(out: Path) -> list[dict[str, Any]]:
    """Every finished row in the folder, in run-key order (so the tables do not depend on timing)."""
    rows = []
    for path in sorted((out / ROWS_DIR).glob("*.json")):
        try:
            rows.append(json.loads(path.read_text()))
        except (OSError, json.JSONDecodeError):
            print(f"rescuemesh: warning: {path} is unreadable; that run will be redone", file=sys.stderr)
    return rows


def run_sweep(sweep: Sweep, out: Path, executor: Executor | None = None, *, keep_artifacts: bool = False,
              progress: Callable[[int, int, dict[str, int], float | None], None] | None = None) -> SweepSummary:
    """Run every run of `sweep` that `out` does not hold yet. Ctrl-C: workers stopped, rows kept,
    tables written, `interrupted` set (run again to resume)."""
    started = time.perf_counter()
    prepare_folder(sweep, out)
    done = finished_keys(out)
    specs = [spec for spec in sweep.runs() if spec.key not in done]
    total, skipped = sweep.size, sweep.size - len(specs)
    executor = executor or LocalPool()
    artifacts = str((out / "artifacts").resolve()) if keep_artifacts else None
    counts: dict[str, int] = {s.value: 0 for s in RunStatus}
    interrupted = False
    ran = 0
    run_started = time.perf_counter()
    if progress:
        progress(skipped, total, counts, None)
    try:
        for spec, row in executor.map_unordered(specs, artifacts):
            _write_atomic(out / ROWS_DIR / f"{spec.key}.json", json.dumps(row, sort_keys=True) + "\n")
            ran += 1
            counts[row["status"]] = counts.get(row["status"], 0) + 1
            if progress:
                per_run = (time.perf_counter() - run_started) / ran
                progress(skipped + ran, total, counts, per_run * (len(specs) - ran))
    except KeyboardInterrupt:
        interrupted = True
    finally:
        executor.close()
    write_tables(out)
    return SweepSummary(total, skipped, ran, counts, interrupted, time.perf_counter() - started, out)


def write_tables(out: Path) -> None:
    """results.parquet and results.csv from every row in the folder (pyarrow)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    rows = load_rows(out)
    if not rows:
        return
    seen = {k for row in rows for k in row if k != "traceback"}
    first = [c for c in FIRST_COLUMNS if c in seen]
    columns = first + sorted(seen - set(first))
    arrays = {}
    for column in columns:
        values = [row.get(column) for row in rows]
        try:
            arrays[column] = pa.array(values)
        except (pa.ArrowInvalid, pa.ArrowTypeError, TypeError):  # mixed kinds: kept as text
            arrays[column] = pa.array([None if v is None else str(v) for v in values], pa.string())
    table = pa.table(arrays)
    pq.write_table(table, out / "results.parquet")
    pacsv.write_csv(table, out / "results.csv")


def comparable(row: dict[str, Any]) -> dict[str, Any]:
    """A row without its wall-clock columns: equal for the same configuration and seed anywhere."""
    return {k: v for k, v in row.items() if k not in WALL_CLOCK_COLUMNS}


def _write_atomic(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
