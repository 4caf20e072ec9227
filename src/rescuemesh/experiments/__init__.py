"""Experiments as data: sweeps over a scenario's options and seeds, run on every core or on a Ray
cluster, kept as one row per run (Parquet, CSV) and summarised with intervals and plots.

Owns: the sweep file (spec), one run as a row (worker), the executors (local pool, Ray), the sweep's
folder (engine) and the report. Must not know: the command line. Only executors.py imports ray.
"""

from rescuemesh.experiments.engine import SweepSummary, load_rows, run_sweep, write_tables
from rescuemesh.experiments.executors import Executor, ExecutorError, LocalPool, RayExecutor
from rescuemesh.experiments.spec import RunSpec, Sweep, SweepError, load_sweep
from rescuemesh.experiments.worker import RunStatus

__all__ = ["Executor", "ExecutorError", "LocalPool", "RayExecutor", "RunSpec", "RunStatus", "Sweep", "SweepError",
           "SweepSummary", "load_rows", "load_sweep", "run_sweep", "write_tables"]
