"""rescuemesh: robots that command each other over a short-range mesh when the network is gone.

For scripts and notebooks: `from rescuemesh import Mission, run, sweep` (docs/missions.md,
docs/sweeps.md); `Mission.load(path)` reads a mission file. The layers are in docs/design.md and
checked as import-linter contracts (pyproject.toml). Importing this package loads nothing heavy:
the three names are resolved on first use.
"""

__version__ = "0.1.0"
__all__ = ["Mission", "run", "sweep"]


def __getattr__(name: str):
    if name in ("run", "sweep"):
        from rescuemesh.experiments import api

        return getattr(api, name)
    if name == "Mission":
        from rescuemesh.experiments.mission_spec import Mission

        return Mission
    raise AttributeError(f"module 'rescuemesh' has no attribute {name!r}")
