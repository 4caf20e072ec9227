"""Channel models: the physics of one frame sent from one place and heard at another.

Owns: the ChannelModel interface (airtime, mean received power, one reception, audibility,
expected delivery, settings), the Reception result and its LossCause, the BLE advertising airtime,
the disc model, and the name registry. Must not know: frame contents, queues, airtime scheduling,
collisions or the extra --loss (the simulated medium in transport/ owns those), the clock.

How the medium uses a model, per frame sent at `tx_xy`:
  1. `airtime_s(frame_bytes)`: how long the frame occupies the air (for scheduling, collisions).
  2. for every other radio at `rx_xy`: skip it unless `audible(tx_xy, rx_xy)` (such a radio can
     neither receive nor be disturbed by this frame); else `reception(..., rng)` decides this
     frame's fate with the pair's own random stream (a numpy Generator, or the medium's
     UniformStream over one: models draw through radio.streams.uniforms, the same numbers). The medium may then still lose a delivered
     frame to a collision, the extra loss, a radio that is off or busy sending, using the last
     four LossCause values.
Positions are (x, y) in m in the map frame. Models are deterministic given their seed except for
the draws made from the `rng` handed to `reception`.
"""

from __future__ import annotations

import abc
import enum
import inspect
import math
from typing import Any, ClassVar, NamedTuple

import numpy as np

from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.radio.streams import UniformStream

#: Nominal Bluetooth range in m (the paper's Table II).
BLUETOOTH_NOMINAL_RANGE_M = 10.0
#: Duration of one bit on the BLE 1M PHY in s (Bluetooth Core 5.4, Vol 6 Part A 3.1: 1 Msym/s).
BLE_1M_BIT_S = 1e-6
#: Bytes of a legacy ADV_NONCONN_IND around a Bluetooth Mesh message (AD type 0x2A): 1 B preamble
#: + 4 B access address + 2 B PDU header + 6 B AdvA + 1 B AD length + 1 B AD type + 3 B CRC
#: (Core Vol 6 Part B 2.1 and 2.3; Mesh Protocol 1.1, 3.3.1).
ADV_MESH_OVERHEAD_BYTES = 1 + 4 + 2 + 6 + 1 + 1 + 3
#: Largest mesh message in one legacy advertising PDU: 31 B of AD data minus the 2 B AD header.
MAX_ADV_MESH_FRAME_BYTES = 29
#: A mesh message is sent on the three primary advertising channels 37, 38, 39, back to back.
ADV_CHANNELS = 3


def ble_adv_airtime_s(frame_bytes: int) -> float:
    """On-air time in s of one mesh frame of `frame_bytes` bytes as a legacy advertisement.

    3 channels x (18 + N) bytes x 8 us: 912 us for 20 bytes, 1128 us for 29 (the anchors' 1.1 ms).
    Frames over MAX_ADV_MESH_FRAME_BYTES do not fit one legacy PDU; the formula is extended
    linearly for them (as one over-long PDU) rather than refused.
    """
    if frame_bytes < 0:
        raise ValueError(f"frame size must be >= 0 bytes, got {frame_bytes}")
    return ADV_CHANNELS * (ADV_MESH_OVERHEAD_BYTES + frame_bytes) * 8 * BLE_1M_BIT_S


class LossCause(enum.Enum):
    """Why a reception failed. Models produce the first three; the medium uses the last four."""

    OUT_OF_RANGE = "out_of_range"  # mean power far below sensitivity (disc: beyond the range): not audible
    BELOW_SENSITIVITY = "below_sensitivity"  # audible, but mean power below sensitivity: out of reach on average
    BIT_ERRORS = "bit_errors"  # mean power at or above sensitivity; the packet-error draw failed (fading, noise)
    COLLISION = "collision"  # another audible frame overlapped this one at the receiver
    EXTRA_LOSS = "extra_loss"  # the configured extra independent loss (--loss)
    RADIO_OFF = "radio_off"  # the receiving radio was switched off
    HALF_DUPLEX = "half_duplex"  # the receiving radio was itself transmitting


class Reception(NamedTuple):
    """The fate of one frame at one receiver, as the channel model decided it (immutable; a named
    tuple, as it is made per frame per receiver: a frozen dataclass cost 2.6 times as much).

    - `delivered`: the frame arrived intact.
    - `rssi_dbm`: this frame's received power in dBm including fast fading (the disc model: 0.0
      in range, -inf beyond; BLE out of range: the mean power, no fading drawn).
    - `cause`: why it failed; None when delivered.
    """

    delivered: bool
    rssi_dbm: float
    cause: LossCause | None


Point = tuple[float, float]


class ChannelModel(abc.ABC):
    """Decides the physics of one frame from one place to another. Register subclasses by name."""

    name: ClassVar[str]

    @abc.abstractmethod
    def airtime_s(self, frame_bytes: int) -> float:
        """On-air time in s of one frame of `frame_bytes` bytes."""

    @abc.abstractmethod
    def mean_rx_power_dbm(self, tx_xy: Point, rx_xy: Point) -> float:
        """Deterministic received power in dBm: path loss, walls, shadowing; no fast fading."""

    @abc.abstractmethod
    def reception(self, tx_xy: Point, rx_xy: Point, frame_bytes: int,
                  rng: np.random.Generator | UniformStream) -> Reception:
        """Draw the fate of one frame at one receiver (fast: runs per frame per receiver); `rng` is a
        numpy Generator or a UniformStream (draw with radio.streams.uniforms). Must give
        cause OUT_OF_RANGE exactly when `audible` is False, and then draw nothing from `rng`: the
        medium asks this alone and treats such a receiver as out of earshot."""

    @abc.abstractmethod
    def audible(self, tx_xy: Point, rx_xy: Point) -> bool:
        """Whether the transmitter's energy can reach rx at all (to deliver or to collide)."""

    @abc.abstractmethod
    def delivery_probability(self, tx_xy: Point, rx_xy: Point, frame_bytes: int) -> float:
        """Probability that `reception` delivers, expected over fast fading (maps, calibration)."""

    @abc.abstractmethod
    def settings(self) -> dict[str, Any]:
        """Every parameter with its value, JSON-able (for result.json); includes `name`."""

    # --- optional, vectorised over receivers (maps); override when a faster way exists ---------
    def mean_rx_power_map(self, tx_xy: Point, rx_xy: np.ndarray) -> np.ndarray:
        """`mean_rx_power_dbm` from one transmitter to each of `rx_xy` (shape (N, 2))."""
        pts = np.asarray(rx_xy, dtype=float).reshape(-1, 2)
        return np.array([self.mean_rx_power_dbm(tx_xy, (x, y)) for x, y in pts])

    def delivery_probability_map(self, tx_xy: Point, rx_xy: np.ndarray, frame_bytes: int) -> np.ndarray:
        """`delivery_probability` from one transmitter to each of `rx_xy` (shape (N, 2))."""
        pts = np.asarray(rx_xy, dtype=float).reshape(-1, 2)
        return np.array([self.delivery_probability(tx_xy, (x, y), frame_bytes) for x, y in pts])

    def mean_rx_power_row(self, tx_xy: Point, rx_xy: np.ndarray) -> np.ndarray:
        """`mean_rx_power_dbm(tx_xy, p)` for each p of `rx_xy` (shape (N, 2)): exactly its numbers,
        where `mean_rx_power_map` may differ in detail (the simulated medium's per-transmission row).
        This default asks the scalar once per receiver; override when a faster way gives the same."""
        power = self.mean_rx_power_dbm
        return np.array([power(tx_xy, (x, y)) for x, y in np.asarray(rx_xy, dtype=float).reshape(-1, 2).tolist()],
                        dtype=float)

    def describe(self) -> str:
        """One line naming the model and its main settings (plot titles, logs)."""
        items = ", ".join(f"{k} {v}" for k, v in self.settings().items() if k != "name")
        return f"{self.name}: {items}" if items else self.name

    @classmethod
    def from_params(cls, *, grid: OccupancyGrid | None, seed: int, **params: Any) -> ChannelModel:
        """Build from the registry's arguments; models that need no map or seed ignore them."""
        return cls(**params)


class DiscChannel(ChannelModel):
    """The unit-disc model: every frame within `range_m` arrives, nothing beyond; no walls.

    `range_m` defaults to the paper's nominal 10 m (Table II). Airtime as BLE advertising.
    """

    name: ClassVar[str] = "disc"

    def __init__(self, range_m: float = BLUETOOTH_NOMINAL_RANGE_M) -> None:
        range_m = float(range_m)
        if not range_m > 0.0 or math.isinf(range_m):
            raise ValueError(f"range must be a finite number > 0 m, got {range_m}")
        self.range_m = range_m
        self._range2 = range_m * range_m

    def airtime_s(self, frame_bytes: int) -> float:
        return ble_adv_airtime_s(frame_bytes)

    def audible(self, tx_xy: Point, rx_xy: Point) -> bool:
        dx = rx_xy[0] - tx_xy[0]
        dy = rx_xy[1] - tx_xy[1]
        return dx * dx + dy * dy <= self._range2

    def mean_rx_power_dbm(self, tx_xy: Point, rx_xy: Point) -> float:
        return 0.0 if self.audible(tx_xy, rx_xy) else -math.inf

    def reception(self, tx_xy: Point, rx_xy: Point, frame_bytes: int,
                  rng: np.random.Generator | UniformStream) -> Reception:
        if self.audible(tx_xy, rx_xy):
            return _DISC_DELIVERED
        return _DISC_OUT_OF_RANGE

    def delivery_probability(self, tx_xy: Point, rx_xy: Point, frame_bytes: int) -> float:
        return 1.0 if self.audible(tx_xy, rx_xy) else 0.0

    def mean_rx_power_map(self, tx_xy: Point, rx_xy: np.ndarray) -> np.ndarray:
        return np.where(self._in_range_many(tx_xy, rx_xy), 0.0, -np.inf)

    def delivery_probability_map(self, tx_xy: Point, rx_xy: np.ndarray, frame_bytes: int) -> np.ndarray:
        return self._in_range_many(tx_xy, rx_xy).astype(float)

    def _in_range_many(self, tx_xy: Point, rx_xy: np.ndarray) -> np.ndarray:
        pts = np.asarray(rx_xy, dtype=float).reshape(-1, 2)
        d2 = (pts[:, 0] - tx_xy[0]) ** 2 + (pts[:, 1] - tx_xy[1]) ** 2
        return d2 <= self._range2

    def settings(self) -> dict[str, Any]:
        return {"name": self.name, "range_m": self.range_m}

    def __repr__(self) -> str:
        return f"DiscChannel(range_m={self.range_m})"


_DISC_DELIVERED = Reception(True, 0.0, None)
_DISC_OUT_OF_RANGE = Reception(False, -math.inf, LossCause.OUT_OF_RANGE)

#: Channel models by name, for configuration files and the CLI (filled by `register_channel`).
CHANNELS: dict[str, type[ChannelModel]] = {}
#: The model a run uses when none is named.
DEFAULT_CHANNEL = "ble"


def register_channel(cls: type[ChannelModel]) -> type[ChannelModel]:
    """Class decorator: make `cls` buildable by `make_channel(cls.name, ...)`."""
    if cls.name in CHANNELS and CHANNELS[cls.name] is not cls:
        raise ValueError(f"channel model name {cls.name!r} is already registered")
    CHANNELS[cls.name] = cls
    return cls


register_channel(DiscChannel)


def make_channel(name: str, *, grid: OccupancyGrid | None = None, seed: int = 0, **params: Any) -> ChannelModel:
    """Build the registered channel model `name` on the map `grid` with the run's `seed`.

    `params` override the model's defaults (see its `settings()`). Raises ValueError naming the
    known models for an unknown name, and the accepted parameters for an unknown one.
    """
    try:
        cls = CHANNELS[name]
    except KeyError:
        raise ValueError(f"unknown channel model {name!r}; known: {', '.join(sorted(CHANNELS))}") from None
    accepted = _accepted_params(cls)
    unknown = sorted(set(params) - set(accepted))
    if unknown:
        raise ValueError(f"channel model {name!r} has no parameter {', '.join(map(repr, unknown))}; "
                         f"accepted: {', '.join(accepted) or 'none'}")
    return cls.from_params(grid=grid, seed=seed, **params)


def _accepted_params(cls: type[ChannelModel]) -> list[str]:
    names = getattr(cls, "param_names", None)
    if names is not None:
        return list(names())
    return [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
