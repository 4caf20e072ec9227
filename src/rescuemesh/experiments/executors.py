"""Where a sweep's runs execute: a pool of local processes, or a Ray cluster.

Owns: handing RunSpecs to workers and yielding rows as runs finish, in any order; turning a dead
worker into a `crashed` row; stopping every worker on Ctrl-C. Must not know: the grid, storage,
reports. Only this module imports ray (the `cluster` extra), and only when asked for it.
"""

from __future__ import annotations

import abc
import multiprocessing
import os
import signal
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from rescuemesh.experiments.spec import RunSpec
from rescuemesh.experiments.worker import RunStatus, execute, failed_row

#: How long the pool waits for any run before it looks again (Ctrl-C is handled in between), in s.
_POLL_S = 0.5


class ExecutorError(RuntimeError):
    """An executor that cannot start (Ray not installed, no cluster at the address)."""


class Executor(abc.ABC):
    """Runs RunSpecs and yields (spec, row) as each finishes."""

    workers: int

    @abc.abstractmethod
    def map_unordered(self, specs: Iterable[RunSpec], artifacts: str | None) -> Iterator[tuple[RunSpec, dict[str, Any]]]:
        ...

    def close(self) -> None:
        """Stop every worker now (Ctrl-C, or the sweep is done)."""


def _ignore_sigint() -> None:
    # Ctrl-C goes to the whole process group: the parent decides, the workers must not die mid-row.
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class LocalPool(Executor):
    """A pool of `workers` processes on this machine (spawned, so no MuJoCo state is forked)."""

    def __init__(self, workers: int | None = None, task: Callable[..., dict[str, Any]] = execute) -> None:
        self.workers = max(1, workers or os.cpu_count() or 1)
        self._task = task  # a top-level function (spawned workers import it by name)
        self._pool: ProcessPoolExecutor | None = None

    def _new_pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_ignore_sigint)

    def map_unordered(self, specs, artifacts):
        pending = list(specs)
        pending.reverse()
        # Runs that were in the pool when one of its workers died are each run again alone: the pool
        # cannot tell which run killed it, and only that one may become a crashed row.
        suspects: list[RunSpec] = []
        self._pool = self._new_pool()
        running: dict[Future, RunSpec] = {}
        while pending or suspects or running:
            alone = False
            if suspects:
                if not running:
                    spec = suspects.pop()
                    running[self._pool.submit(self._task, spec, artifacts)] = spec
                alone = True
            else:
                while pending and len(running) < 2 * self.workers:  # a short queue: Ctrl-C leaves little to cancel
                    spec = pending.pop()
                    running[self._pool.submit(self._task, spec, artifacts)] = spec
            done, _ = wait(running, timeout=_POLL_S, return_when=FIRST_COMPLETED)
            broken: list[RunSpec] = []
            for future in done:
                spec = running.pop(future)
                try:
                    row = future.result()
                except BrokenProcessPool:
                    broken.append(spec)
                    continue
                yield spec, row
            if broken:
                if alone:
                    yield broken[0], failed_row(broken[0], RunStatus.CRASHED, "the worker process died during this run")
                else:
                    suspects.extend(reversed(broken + list(running.values())))
                running.clear()
                self._pool.shutdown(wait=False, cancel_futures=True)
                self._pool = self._new_pool()
        self._pool.shutdown(wait=True)
        self._pool = None

    def close(self) -> None:
        pool, self._pool = self._pool, None
        if pool is None:
            return
        processes = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:  # a run in progress is abandoned: its row was never written
            if process.is_alive():
                process.terminate()
        for process in processes:
            process.join(timeout=5)
            if process.is_alive():
                process.kill()


class RayExecutor(Executor):
    """The same runs as Ray tasks, one CPU each, on the cluster at `address` ("auto": the one this
    machine belongs to; "local": a new single-machine instance, for tests and laptops)."""

    def __init__(self, address: str, workers: int | None = None) -> None:
        try:
            import ray
        except ImportError:
            raise ExecutorError("--ray needs the cluster extra (ray not installed): "
                                "pip install 'rescuemesh[cluster]'") from None
        self._ray = ray
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False, "configure_logging": False}
        if address == "local":
            kwargs["num_cpus"] = workers or os.cpu_count() or 1
        else:
            kwargs["address"] = address
        try:
            ray.init(**kwargs)
        except (ConnectionError, RuntimeError, ValueError) as error:
            raise ExecutorError(f"cannot reach a Ray cluster at {address!r}: {str(error).splitlines()[0]}") from None
        self.workers = int(ray.cluster_resources().get("CPU", 1))
        self._task = ray.remote(num_cpus=1, max_retries=0)(execute)
        self._refs: dict[Any, RunSpec] = {}

    def map_unordered(self, specs, artifacts):
        ray = self._ray
        pending = list(specs)
        pending.reverse()
        while pending or self._refs:
            while pending and len(self._refs) < 2 * self.workers:
                spec = pending.pop()
                self._refs[self._task.remote(spec, artifacts)] = spec
            done, _ = ray.wait(list(self._refs), num_returns=1, timeout=_POLL_S)
            for ref in done:
                spec = self._refs.pop(ref)
                try:
                    yield spec, ray.get(ref)
                except ray.exceptions.RayError as error:  # the worker died or the node went away
                    yield spec, failed_row(spec, RunStatus.CRASHED, f"Ray: {type(error).__name__}")

    def close(self) -> None:
        ray = self._ray
        for ref in list(self._refs):
            try:
                ray.cancel(ref, force=True)
            except Exception:  # already finished or gone: nothing to stop
                pass
        self._refs.clear()
        if ray.is_initialized():
            ray.shutdown()
