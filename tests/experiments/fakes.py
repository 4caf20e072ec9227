"""Tasks for the executor tests: top-level, so that spawned workers import them by name."""

import os

from rescuemesh.experiments.worker import execute


def die_on_seed_1(spec, artifacts=None):
    """A run whose worker process dies (as a segfault in a native library would) for seed 1."""
    if spec.seed == 1:
        os._exit(3)
    return execute(spec, artifacts)
