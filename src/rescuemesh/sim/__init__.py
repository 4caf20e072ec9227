"""The simulated world: a MuJoCo office built from a MapModel, TurtleBot 2 bodies and their lidars.

Owns everything MuJoCo (the only package that imports it). Must not know brains, navigation,
the radio or the protocol: they reach a robot only through `rescuemesh.body.Body`.
"""

from __future__ import annotations

import importlib

#: Public names and the module each lives in. Imported on first use (PEP 562), so that
#: `rescuemesh.sim.flight`, the drone's controller, loads on a robot without a physics engine.
_EXPORTS = {"LidarConfig": "rescuemesh.sim.lidar", "SimBody": "rescuemesh.sim.body", "World": "rescuemesh.sim.world"}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'rescuemesh.sim' has no attribute {name!r}")
