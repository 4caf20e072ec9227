"""Channel models decide, per frame and per receiver, whether a frame arrives and after what delay.

Owns: the ChannelModel interface, the simple range/loss/latency model, a name registry so a later
Bluetooth channel model plugs in by name. Must not know: frame formats, endpoints, the clock.
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

#: Nominal Bluetooth range in m (the paper's Table II).
BLUETOOTH_NOMINAL_RANGE_M = 10.0
#: Bluetooth maximum signal rate in bit/s (the paper's Table II): sets a frame's airtime.
BLUETOOTH_SIGNAL_RATE_BPS = 1_000_000.0


class ChannelModel(abc.ABC):
    """Decides the fate of one frame on its way from one radio to another."""

    name: ClassVar[str]

    @abc.abstractmethod
    def transmit(
        self,
        sender_xy: tuple[float, float],
        receiver_xy: tuple[float, float],
        frame_bytes: int,
        rng: np.random.Generator,
    ) -> float | None:
        """Delay in s after which the frame arrives, or None when it is lost."""

    @abc.abstractmethod
    def in_range(self, sender_xy: tuple[float, float], receiver_xy: tuple[float, float]) -> bool:
        """Whether the receiver can hear the sender at all."""


@dataclass(frozen=True)
class RangeLossChannel(ChannelModel):
    """Independent per-frame loss, a fixed latency plus airtime, and a hard range limit.

    - `loss`: probability in [0, 1) that a frame in range is lost, drawn per frame and receiver.
    - `latency_s`: fixed delay in s (stack and scheduling), to which the airtime
      `8 * frame_bytes / bitrate_bps` is added.
    - `range_m`: beyond this distance in m nothing is heard (10 m: the paper's Table II).
    """

    name: ClassVar[str] = "range-loss"
    loss: float = 0.0
    latency_s: float = 0.01
    range_m: float = BLUETOOTH_NOMINAL_RANGE_M
    bitrate_bps: float = BLUETOOTH_SIGNAL_RATE_BPS

    def __post_init__(self) -> None:
        if not (0.0 <= self.loss < 1.0) or math.isnan(self.loss):
            raise ValueError(f"loss must be in [0, 1), got {self.loss}")
        if not self.latency_s >= 0.0:
            raise ValueError(f"latency must be >= 0 s, got {self.latency_s}")
        if not self.range_m > 0.0:
            raise ValueError(f"range must be > 0 m, got {self.range_m}")
        if not self.bitrate_bps > 0.0:
            raise ValueError(f"bitrate must be > 0 bit/s, got {self.bitrate_bps}")

    def in_range(self, sender_xy: tuple[float, float], receiver_xy: tuple[float, float]) -> bool:
        dx = receiver_xy[0] - sender_xy[0]
        dy = receiver_xy[1] - sender_xy[1]
        return dx * dx + dy * dy <= self.range_m * self.range_m

    def transmit(self, sender_xy, receiver_xy, frame_bytes, rng):
        if not self.in_range(sender_xy, receiver_xy):
            return None
        if self.loss > 0.0 and rng.random() < self.loss:
            return None
        return self.latency_s + 8.0 * frame_bytes / self.bitrate_bps


#: Channel models by name, for configuration files and the CLI.
CHANNELS: dict[str, type[ChannelModel]] = {RangeLossChannel.name: RangeLossChannel}


def make_channel(name: str, **params: float) -> ChannelModel:
    """Build a registered channel model by name; ValueError names the known ones."""
    try:
        cls = CHANNELS[name]
    except KeyError:
        raise ValueError(f"unknown channel model {name!r}; known: {', '.join(sorted(CHANNELS))}") from None
    return cls(**params)
