"""The simulated world: a MuJoCo office built from a MapModel, TurtleBot 2 bodies and their lidars.

Owns everything MuJoCo (the only package that imports it). Must not know brains, navigation,
the radio or the protocol: they reach a robot only through `rescuemesh.body.Body`.
"""

from rescuemesh.sim.body import SimBody
from rescuemesh.sim.lidar import LidarConfig
from rescuemesh.sim.world import World

__all__ = ["LidarConfig", "SimBody", "World"]
