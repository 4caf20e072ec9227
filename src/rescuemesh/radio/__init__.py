"""Radio channel models: the physics of one frame from one place to another (simulation only).

Owns: ChannelModel and its registry, DiscChannel ("disc") and BleChannel ("ble", the default),
UniformStream (a Generator's uniforms a block at a time, for the per-frame draws); wall losses by
material (materials.py) and the model's validation against measured BLE data (validation.py).
Must not know: frame contents, queues, collisions, endpoints, robots (transport/'s medium does).
"""

from rescuemesh.radio.channel import (
    CHANNELS,
    DEFAULT_CHANNEL,
    ChannelModel,
    DiscChannel,
    LossCause,
    Reception,
    ble_adv_airtime_s,
    make_channel,
    register_channel,
)
from rescuemesh.radio.ble import BleChannel, BleParams, LinkBudget  # noqa: E402  (registers "ble")
from rescuemesh.radio.streams import UniformStream

__all__ = [
    "CHANNELS",
    "DEFAULT_CHANNEL",
    "BleChannel",
    "BleParams",
    "ChannelModel",
    "DiscChannel",
    "LinkBudget",
    "LossCause",
    "Reception",
    "UniformStream",
    "ble_adv_airtime_s",
    "make_channel",
    "register_channel",
]
