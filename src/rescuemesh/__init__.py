"""rescuemesh: robots that command each other over a short-range mesh when the network is gone.

Layers (imports point down only): cli > scenarios > report > runtime > robot/nav/sim/radio/transport > protocol.
See docs/design.md.
"""

__version__ = "0.1.0"
