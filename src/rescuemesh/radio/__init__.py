"""Radio channel models: who hears whom, and when (simulation only).

Owns: ChannelModel and its registry. Must not know: frame contents, endpoints, robots.
"""

from rescuemesh.radio.channel import CHANNELS, ChannelModel, RangeLossChannel, make_channel

__all__ = ["CHANNELS", "ChannelModel", "RangeLossChannel", "make_channel"]
