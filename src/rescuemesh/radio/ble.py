"""BleChannel: a Bluetooth LE advertising link in an office, from link budget to one frame's fate.

Owns: the BLE link budget (transmit power, antenna gains, indoor path loss, walls, shadowing),
the per-frame draw (Rician fading, then the packet-error curve) and its expectation. Must not know:
queues, collisions, the extra loss (the medium's), frame contents, the clock.

Theory of operation (every figure's source is on BleParams and in docs/radio.md):

    P_mean(tx, rx) = P_tx + G_tx + G_rx - PL(d) - sum_walls L(material) - S(tx, rx)      [dBm]
    d              = 3D distance between the antennas (heights h_t, h_r above the floor)
    PL(d)          = PL(1 m) + 10 n log10(d)                          d <= d_bp   (line of sight, n 1.6)
                   = PL(1 m) + 10 n log10(d_bp) + 10 n_far log10(d / d_bp)   beyond (two-ray, n_far = 4)
    d_bp           = 4 h_t h_r / lambda                                (the two-ray breakpoint)
    walls          = the walls the straight segment tx -> rx crosses on the map grid, each priced by
                     its material (radio/walls.py, radio/materials.py: ITU-R P.2040 slabs), the
                     loss averaged in power over rays spread across the first Fresnel zone (a wall
                     end or corner that only clips the zone costs part of its loss)
    S              = seeded, spatially correlated log-normal shadowing            (radio/shadowing.py)
    per frame:  rssi = P_mean + 10 log10(g),  g ~ Rician(K), mean 1               (radio/fading.py)
                lost with probability PER(rssi - P_sens, frame bytes)            (radio/per.py)

Validated against two public BLE data sets (radio/validation.py, `rescuemesh radio-validate`).

A receiver whose mean power is more than `out_of_range_margin_db` below the sensitivity is out of
range: nothing is drawn, it cannot receive, and it is not `audible` (the medium skips it, so it
cannot be disturbed by the frame either).

Positions are quantised to the centre of the grid cell holding them (no grid: a 5 cm lattice)
before anything is computed, so the mean power of a pair of cells is computed once and cached
(LRU), and it is symmetric: P_mean(a, b) == P_mean(b, a). `reception` then costs one cache look-up,
three uniforms (`rng.random(3)`, or the next three of a UniformStream: the same numbers) and a few
`math` calls. `delivery_probability` reads a table of the expected
delivery against the margin over sensitivity, built once per frame size by averaging 1 - PER over
the exact fading distribution.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from functools import lru_cache
from typing import Any, ClassVar

import numpy as np

from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.maps.model import WallMaterial
from rescuemesh.radio.channel import ChannelModel, LossCause, Point, Reception, ble_adv_airtime_s, register_channel
from rescuemesh.radio.fading import gain_db_distribution, rician_gain_from_uniforms
from rescuemesh.radio.per import crc_covered_bits, packet_error_rate, packet_error_rate_scalar
from rescuemesh.radio.shadowing import ShadowField, field_unit
from rescuemesh.radio.streams import UniformStream, uniforms
from rescuemesh.radio.materials import C_M_S
from rescuemesh.jit import compiled
from rescuemesh.pymath import py_hypot3
from rescuemesh.radio.walls import (_fresnel_wall_loss, _occupied_sat, _padded, _padded_codes, _wall_loss_on_line,
                                    wall_loss_cells, wall_loss_fresnel, wall_loss_fresnel_many, wall_loss_many)

#: Position quantum in m when the channel has no map grid.
DEFAULT_QUANTUM_M = 0.05
#: Pairs of cells whose mean power is kept (LRU). 30 robots make 435 pairs; moving ones make more.
DEFAULT_CACHE_PAIRS = 1 << 16
_SQRT2 = math.sqrt(2.0)
#: Resolution in dB of the expected-delivery table, and how far above sensitivity it reaches
#: (beyond, its last value is used: within 1e-6 of the truth even for Rayleigh fading).
_TABLE_STEP_DB = 0.01
_TABLE_TOP_DB = 60.0


@dataclass(frozen=True)
class BleParams:
    """Every parameter of BleChannel. Sources and the validation in docs/radio.md.

    - `tx_power_dbm`: 0 dBm, the usual default of BLE modules (anchors; Class 2 allows 4 dBm).
    - `tx_antenna_gain_dbi`, `rx_antenna_gain_dbi`: -2 dBi each, a small chip/PCB antenna on a
      robot (stated assumption: such antennas have about -3..+1 dBi peak, less on average over
      directions and with a robot body next to them).
    - `sensitivity_dbm`: -93 dBm at 0.1 % BER (Core Vol 6 Part A 4.1 asks -70 dBm or better;
      modules are -90..-97 dBm, anchors). Unchanged by the validation (it fits levels per anchor).
    - `frequency_mhz`: 2440 MHz, the middle of the 2.4 GHz band (advertising channels 37, 38,
      39 are at 2402, 2426, 2480 MHz); sets PL(1 m) = 20 log10(f_MHz) - 28 = 39.75 dB (P.1238).
    - `tx_antenna_height_m`, `rx_antenna_height_m`: 0.40 m, a module on a TurtleBot 2's top plate
      (sim/mjcf.py PLATE_TOP, turtlebot_description). They set the 3D distance and the breakpoint.
    - `path_loss_exponent`: 1.6, the line-of-sight slope up to the two-ray breakpoint d_bp = 4 h_t
      h_r / lambda (5.2 m for antennas 0.4 m up): Rappaport, Wireless Communications 2nd ed., Table
      4.2, "in building, line-of-sight: 1.6 to 1.8" (below free space's 2: corridors and rooms guide
      the wave); the Danis office's own fit is 1.55 (95 % 1.45..1.64), where 2.0 lies outside
      (`rescuemesh radio-validate`). The breakpoint is Rappaport 4.6 / Goldsmith 2.4.
    - `far_path_loss_exponent`: 4.0, the plane-earth law beyond the breakpoint (same sources).
    - `min_distance_m`: 1 m, the distance P.1238's reference loss is given at; closer is 1 m.
    - `wall_loss_db`: 3.4 dB, a wall the map does not tag (ROS maps): an interior brick wall.
    - `wall_loss_light_db` 2.2, `wall_loss_brick_db` 3.4, `wall_loss_concrete_db` 14.8,
      `wall_loss_glass_db` 1.9, `wall_loss_wood_db` 0.6: one wall of each material as built in
      radio/materials.py (two 12.5 mm plasterboards; 0.12 m brick; 0.20 m concrete; 6 mm glass;
      40 mm wood), its transmission loss at 2.44 GHz and normal incidence from ITU-R P.2040-3
      Table 3 (rounded to 0.1 dB; tests check they match the computation).
    - `wall_fresnel_rays`: 9. The wall loss is averaged in power over this many rays spread across
      the horizontal width of the first Fresnel zone, radius r1 = sqrt(lambda d1 d2 / d) (ITU-R
      P.526, Fresnel ellipsoids; Rappaport 4.7.1: an obstacle outside the first Fresnel zone
      costs little, one blocking part of it part of its loss), not priced on the straight line.
      The map's walls are vertical, so their ends, corners and door jambs are vertical edges and
      the horizontal width is the one that matters. 1 is the straight line alone (the model before).
      9: the bundle's loss is then within 0.24 dB on average (95 % within 1.2 dB) of 129 rays' over
      3,000 random pairs of the office (docs/radio.md). Walls are still counted on the straight line.
    - `shadowing_sigma_db`: 4 dB, WINNER II D1.1.2 Tables 4-4/4-5, indoor office A1 NLOS (a model
      that, like this one, counts walls explicitly); the Danis office's spread of place means about
      its own fit is 3.98 dB (95 % 3.85..4.08). 0 disables shadowing.
    - `shadowing_decorrelation_m`: 0.9 m, the lattice spacing of the field, whose correlation falls
      to 1/e at 0.9 spacings (0.8 m): fitted to the Kolakowski flat's residuals, exp(-d / 0.79 m)
      (`rescuemesh radio-validate`); it was WINNER II A1 NLOS's 4 m, four times what the flat shows.
    - `rician_k`: 5.0 (7.0 dB) linear K-factor of the per-frame fading, the mean of WINNER II
      A1 LOS (7 dB, spread 6 dB); 0 is Rayleigh.
    - `out_of_range_margin_db`: 20 dB. A receiver whose mean power is more than this below the
      sensitivity is out of range: not audible, OUT_OF_RANGE, delivery 0. Delivering from there
      would need a fading gain of ~17 dB (Rayleigh: P = e^-50); and an interferer that weak cannot
      spoil a frame received near sensitivity, which the spec asks to survive a co-channel
      interferer 21 dB below it (C/I 21 dB, Core Vol 6 Part A 4.2).
    """

    tx_power_dbm: float = 0.0
    tx_antenna_gain_dbi: float = -2.0
    rx_antenna_gain_dbi: float = -2.0
    sensitivity_dbm: float = -93.0
    frequency_mhz: float = 2440.0
    tx_antenna_height_m: float = 0.40
    rx_antenna_height_m: float = 0.40
    path_loss_exponent: float = 1.6
    far_path_loss_exponent: float = 4.0
    min_distance_m: float = 1.0
    wall_loss_db: float = 3.4
    wall_loss_light_db: float = 2.2
    wall_loss_brick_db: float = 3.4
    wall_loss_concrete_db: float = 14.8
    wall_loss_glass_db: float = 1.9
    wall_loss_wood_db: float = 0.6
    wall_fresnel_rays: float = 9.0
    shadowing_sigma_db: float = 4.0
    shadowing_decorrelation_m: float = 0.9
    rician_k: float = 5.0
    out_of_range_margin_db: float = 20.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"{f.name} must be a number, got {value!r}") from None
            if not math.isfinite(number):
                raise ValueError(f"{f.name} must be finite, got {value!r}")
            object.__setattr__(self, f.name, number)
        positive = ("frequency_mhz", "tx_antenna_height_m", "rx_antenna_height_m", "path_loss_exponent",
                    "far_path_loss_exponent", "min_distance_m", "shadowing_decorrelation_m")
        for name in positive:
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not (self.wall_fresnel_rays >= 1.0 and self.wall_fresnel_rays == int(self.wall_fresnel_rays)):
            raise ValueError(f"wall_fresnel_rays must be a whole number >= 1, got {self.wall_fresnel_rays:g}")
        for name in ("wall_loss_db", *_MATERIAL_PARAMS.values(), "shadowing_sigma_db", "rician_k",
                     "out_of_range_margin_db"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")

    @property
    def reference_loss_db(self) -> float:
        """PL(1 m) = 20 log10(f_MHz) - 28 dB (ITU-R P.1238): 39.75 dB at 2440 MHz."""
        return 20.0 * math.log10(self.frequency_mhz) - 28.0

    @property
    def wavelength_m(self) -> float:
        return C_M_S / (self.frequency_mhz * 1e6)

    @property
    def breakpoint_m(self) -> float:
        """The two-ray breakpoint 4 h_t h_r / lambda in m (5.2 m for antennas 0.4 m up at 2440 MHz)."""
        return 4.0 * self.tx_antenna_height_m * self.rx_antenna_height_m * self.frequency_mhz * 1e6 / C_M_S

    @property
    def loss_by_code(self) -> np.ndarray:
        """Loss in dB of one wall by material code (0: untagged, then maps.model.WallMaterial's order)."""
        return np.array([self.wall_loss_db, *(getattr(self, _MATERIAL_PARAMS[m]) for m in WallMaterial)])

    def path_loss_db(self, d_m):
        """PL(d) in dB for the 3D distance `d_m` (float or array): dual slope around the breakpoint."""
        d_min = self.min_distance_m
        bp = max(self.breakpoint_m, d_min)
        d = np.maximum(d_m, d_min)
        near = 10.0 * self.path_loss_exponent * np.log10(np.minimum(d, bp))
        far = 10.0 * self.far_path_loss_exponent * np.log10(np.maximum(d, bp) / bp)
        out = self.reference_loss_db + near + far
        return float(out) if np.ndim(out) == 0 else out

    def distance_3d(self, d2_m):
        """The distance between the antennas for a horizontal distance `d2_m` (float or array)."""
        dh = self.tx_antenna_height_m - self.rx_antenna_height_m
        return np.hypot(d2_m, dh) if np.ndim(d2_m) else math.hypot(d2_m, dh)

    @property
    def rician_k_db(self) -> float:
        return 10.0 * math.log10(self.rician_k) if self.rician_k > 0 else -math.inf


#: The BleParams field that prices one wall of each material.
_MATERIAL_PARAMS = {m: f"wall_loss_{m.value}_db" for m in WallMaterial}


@dataclass(frozen=True, slots=True)
class LinkBudget:
    """The terms of P_mean for one pair of places (for docs, maps and tests), in m and dB."""

    distance_m: float
    path_loss_db: float
    walls: int
    wall_loss_db: float  # the crossed walls' loss, summed
    shadow_db: float
    mean_rx_power_dbm: float
    margin_db: float  # mean power minus sensitivity


@register_channel
class BleChannel(ChannelModel):
    """BLE 1M advertising on an office map: dual-slope path loss, walls by material, shadowing, fading.

    `BleChannel(grid, seed=0, params=BleParams(...))`; `grid` is the map's OccupancyGrid (None: no
    walls), `seed` fixes the shadowing field. Build by name with `make_channel("ble", grid=...,
    seed=..., **overrides)`.
    """

    name: ClassVar[str] = "ble"

    def __init__(self, grid: OccupancyGrid | None = None, *, seed: int = 0, params: BleParams | None = None,
                 cache_pairs: int = DEFAULT_CACHE_PAIRS) -> None:
        self.grid = grid
        self.seed = int(seed)
        self.params = params if params is not None else BleParams()
        p = self.params
        self.shadow = ShadowField(self.seed, p.shadowing_sigma_db, p.shadowing_decorrelation_m)
        if grid is not None:
            self._quantum, self._ox, self._oy = float(grid.resolution), float(grid.origin_x), float(grid.origin_y)
        else:
            self._quantum, self._ox, self._oy = DEFAULT_QUANTUM_M, 0.0, 0.0
        self._sens = p.sensitivity_dbm
        self._floor = p.sensitivity_dbm - p.out_of_range_margin_db  # audible iff mean power >= this
        self._k = p.rician_k
        self._dh = p.tx_antenna_height_m - p.rx_antenna_height_m
        self._bp = max(p.breakpoint_m, p.min_distance_m)
        self._near10 = 10.0 * p.path_loss_exponent
        self._far10 = 10.0 * p.far_path_loss_exponent
        self._loss_by_code = p.loss_by_code
        self._rays = int(p.wall_fresnel_rays)
        self._wavelength = p.wavelength_m
        self._mean_power_cells = lru_cache(maxsize=cache_pairs)(self._compute_mean_power_cells)
        self._row_args: tuple | None = None
        self._tables: dict[int, np.ndarray] = {}
        self._bits: dict[int, int] = {}

    # --- registry --------------------------------------------------------------------------------
    @classmethod
    def param_names(cls) -> list[str]:
        return [f.name for f in fields(BleParams)]

    @classmethod
    def from_params(cls, *, grid: OccupancyGrid | None, seed: int, **params: Any) -> BleChannel:
        return cls(grid, seed=seed, params=BleParams(**params))

    def with_params(self, **changes: Any) -> BleChannel:
        """A channel on the same map and seed with some parameters changed."""
        return BleChannel(self.grid, seed=self.seed, params=replace(self.params, **changes))

    # --- geometry and the deterministic link budget ----------------------------------------------
    def _cell(self, xy: Point) -> tuple[int, int]:
        q = self._quantum
        return (math.floor((xy[0] - self._ox) / q), math.floor((xy[1] - self._oy) / q))

    def _centre(self, i: int, j: int) -> tuple[float, float]:
        q = self._quantum
        return (self._ox + (i + 0.5) * q, self._oy + (j + 0.5) * q)

    def link_budget(self, tx_xy: Point, rx_xy: Point) -> LinkBudget:
        """The terms of the mean received power between the cells holding tx and rx."""
        a, b = sorted((self._cell(tx_xy), self._cell(rx_xy)))
        return self._budget_cells(*a, *b)

    def _budget_cells(self, ai: int, aj: int, bi: int, bj: int) -> LinkBudget:
        """The link budget between the centres of cells (ai, aj) <= (bi, bj)."""
        d, path_loss, walls, shadow, power, wall_loss = self._budget_terms(ai, aj, bi, bj)
        return LinkBudget(d, path_loss, walls, wall_loss, shadow, power, power - self._sens)

    def _budget_terms(self, ai: int, aj: int, bi: int, bj: int) -> tuple[float, float, int, float, float, float]:
        """(distance, path loss, walls, shadow, mean power, wall loss) between the centres of cells
        (ai, aj) <= (bi, bj): the compiled row (`_budget_row`) for one receiver, so the scalar and the
        row are one implementation (the Python it replaced is the oracle in tests/oracles/ble_budget.py).
        `d` is the 3D distance of the antennas."""
        terms = self._terms_row(ai, aj, np.array([[bi, bj]], dtype=np.int64))[0]
        return (float(terms[_DISTANCE]), float(terms[_PATH_LOSS]), int(terms[_WALLS]), float(terms[_SHADOW]),
                float(terms[_POWER]), float(terms[_WALL_LOSS]))

    def _compute_mean_power_cells(self, ai: int, aj: int, bi: int, bj: int) -> float:
        return self._budget_terms(ai, aj, bi, bj)[4]

    def mean_rx_power_dbm(self, tx_xy: Point, rx_xy: Point) -> float:
        q = self._quantum
        ai = math.floor((tx_xy[0] - self._ox) / q)
        aj = math.floor((tx_xy[1] - self._oy) / q)
        bi = math.floor((rx_xy[0] - self._ox) / q)
        bj = math.floor((rx_xy[1] - self._oy) / q)
        if (bi, bj) < (ai, aj):
            return self._mean_power_cells(bi, bj, ai, aj)
        return self._mean_power_cells(ai, aj, bi, bj)

    def mean_rx_power_row(self, tx_xy: Point, rx_xy: np.ndarray) -> np.ndarray:
        """`mean_rx_power_dbm(tx_xy, p)` for each p of `rx_xy` (shape (N, 2)), the same numbers, in one
        compiled call (`_power_row`: the cells, then `_budget_row`'s budget for each) instead of one
        Python call per receiver. The pair cache is neither read nor filled (a moving team hardly meets
        a pair twice: see docs/radio.md)."""
        if type(self).mean_rx_power_dbm is not BleChannel.mean_rx_power_dbm \
                or type(self)._budget_terms is not BleChannel._budget_terms:
            return super().mean_rx_power_row(tx_xy, rx_xy)  # a subclass's own model: ask it per pair
        pts = np.ascontiguousarray(rx_xy, dtype=float).reshape(-1, 2)
        if self._row_args is None:
            self._row_args = self._row_arguments()
        power = np.empty(len(pts))
        _power_row(*self._row_args, float(tx_xy[0]), float(tx_xy[1]), pts, power)
        return power

    def _terms_row(self, ai: int, aj: int, cells: np.ndarray) -> np.ndarray:
        """The link budget's terms (columns _DISTANCE, _PATH_LOSS, _WALLS, _WALL_LOSS, _SHADOW, _POWER)
        from the cell (ai, aj) to each cell of `cells` (int64 (N, 2))."""
        if self._row_args is None:
            self._row_args = self._row_arguments()
        terms = np.empty((len(cells), _TERMS))
        _budget_row(*self._row_args, ai, aj, cells, terms)
        return terms

    def _row_arguments(self) -> tuple:
        """The map and the parameters `_budget_row` reads, packed once per channel."""
        grid, p = self.grid, self.params
        if grid is None:
            mode, padded, sat, codes = _NO_WALLS, _EMPTY_PADDED, _EMPTY_SAT, _EMPTY_CODES
        else:
            mode = _FRESNEL if self._rays > 1 else (_LINE_TAGGED if grid.materials is not None else _LINE)
            padded, sat, codes = _padded(grid), _occupied_sat(grid), _padded_codes(grid)
        numbers = np.array([self._ox, self._oy, self._quantum, self._wavelength, self._dh, p.min_distance_m,
                            self._bp, p.reference_loss_db, self._near10, self._far10, self.shadow.sigma_db,
                            p.tx_power_dbm, p.tx_antenna_gain_dbi, p.rx_antenna_gain_dbi,
                            self.shadow.decorrelation_m])
        return (mode, self._rays, padded, sat, codes, np.ascontiguousarray(self._loss_by_code, dtype=float), numbers,
                self.shadow.key)

    def mean_rx_power_map(self, tx_xy: Point, rx_xy: np.ndarray) -> np.ndarray:
        """Mean power from tx to each point (shape (N, 2)); vectorised, same model as above.

        Walls are counted from tx outwards; this differs from the scalar only for a point inside
        an obstacle (the scalar counts from the lower cell index).
        """
        pts = np.asarray(rx_xy, dtype=float).reshape(-1, 2)
        q = self._quantum
        tc = self._centre(*self._cell(tx_xy))
        cells = np.floor((pts - (self._ox, self._oy)) / q)
        centres = (self._ox, self._oy) + (cells + 0.5) * q
        p = self.params
        d = p.distance_3d(np.hypot(centres[:, 0] - tc[0], centres[:, 1] - tc[1]))
        path_loss = p.path_loss_db(d)
        if self.grid is None:
            wall_loss = np.zeros(len(pts))
        elif self._rays == 1:
            wall_loss = wall_loss_many(self.grid, tc, centres, self._loss_by_code)[1]
        else:
            wall_loss = wall_loss_fresnel_many(self.grid, tc, centres, self._loss_by_code, self._wavelength,
                                               self._dh, self._rays)[1]
        shadow = self.shadow.link_db_many(tc, centres)
        return p.tx_power_dbm + p.tx_antenna_gain_dbi + p.rx_antenna_gain_dbi - path_loss \
            - wall_loss - shadow

    # --- the interface ---------------------------------------------------------------------------
    def airtime_s(self, frame_bytes: int) -> float:
        return ble_adv_airtime_s(frame_bytes)

    def audible(self, tx_xy: Point, rx_xy: Point) -> bool:
        return self.mean_rx_power_dbm(tx_xy, rx_xy) >= self._floor

    def reception(self, tx_xy: Point, rx_xy: Point, frame_bytes: int,
                  rng: np.random.Generator | UniformStream) -> Reception:
        mean = self.mean_rx_power_dbm(tx_xy, rx_xy)
        if mean < self._floor:
            return Reception(False, mean, LossCause.OUT_OF_RANGE)
        bits = self._bits.get(frame_bytes)
        if bits is None:
            bits = self._bits[frame_bytes] = crc_covered_bits(frame_bytes)
        u_radius, u_angle, u_error = uniforms(rng, 3)
        gain = rician_gain_from_uniforms(u_radius, u_angle, self._k)
        # a loss on a link whose mean power is below sensitivity is that link's lack of reach (it gets
        # through only on a fading peak), not bad luck on a working link: counted apart
        cause = LossCause.BELOW_SENSITIVITY if mean < self._sens else LossCause.BIT_ERRORS
        if gain <= 0.0:
            return Reception(False, -math.inf, cause)
        rssi = mean + 10.0 * math.log10(gain)
        if u_error < packet_error_rate_scalar(rssi - self._sens, bits):
            return Reception(False, rssi, cause)
        return Reception(True, rssi, None)

    def delivery_probability(self, tx_xy: Point, rx_xy: Point, frame_bytes: int) -> float:
        margin = self.mean_rx_power_dbm(tx_xy, rx_xy) - self._sens
        return float(self._delivery_at_margin(np.asarray([margin]), frame_bytes)[0])

    def delivery_probability_map(self, tx_xy: Point, rx_xy: np.ndarray, frame_bytes: int) -> np.ndarray:
        return self._delivery_at_margin(self.mean_rx_power_map(tx_xy, rx_xy) - self._sens, frame_bytes)

    def delivery_at_margin(self, margin_db, frame_bytes: int):
        """Expected delivery over fading for a mean power `margin_db` dB above sensitivity."""
        out = self._delivery_at_margin(np.asarray(margin_db, dtype=float).reshape(-1), frame_bytes)
        return float(out[0]) if np.ndim(margin_db) == 0 else out.reshape(np.shape(margin_db))

    def _delivery_at_margin(self, margin: np.ndarray, frame_bytes: int) -> np.ndarray:
        table = self._tables.get(frame_bytes)
        if table is None:
            table = self._tables[frame_bytes] = self._delivery_table(frame_bytes)
        low = -self.params.out_of_range_margin_db
        x = (margin - low) / _TABLE_STEP_DB
        out = np.interp(x, np.arange(len(table)), table)
        return np.where(margin < low, 0.0, out)

    def _delivery_table(self, frame_bytes: int) -> np.ndarray:
        """E_g[1 - PER(m + 10 log10 g)] for m from -out_of_range_margin to +60 dB, every 0.01 dB."""
        step = _TABLE_STEP_DB
        gain_db, mass = gain_db_distribution(self._k, step_db=step)
        low = -self.params.out_of_range_margin_db
        n_margin = int(round((_TABLE_TOP_DB - low) / step)) + 1
        # success at m_j + x_i = low + gain_db[0] + (i + j) * step, for every i + j
        shifted = low + gain_db[0] + step * np.arange(n_margin + len(gain_db) - 1)
        success = 1.0 - packet_error_rate(shifted, frame_bytes)
        table = np.correlate(success, mass, mode="valid")
        return np.clip(table, 0.0, 1.0)

    def settings(self) -> dict[str, Any]:
        p = self.params
        return {"name": self.name, **asdict(p), "seed": self.seed,
                "reference_loss_db": round(p.reference_loss_db, 4),
                "rician_k_db": round(p.rician_k_db, 4) if p.rician_k > 0 else None,
                "position_quantum_m": self._quantum, "walls_from_map": self.grid is not None}

    def describe(self) -> str:
        p = self.params
        k = f"K {p.rician_k_db:.1f} dB" if p.rician_k > 0 else "Rayleigh"
        return (f"ble: Ptx {p.tx_power_dbm:g} dBm, G {p.tx_antenna_gain_dbi:g}/{p.rx_antenna_gain_dbi:g} dBi, "
                f"sens {p.sensitivity_dbm:g} dBm, n {p.path_loss_exponent:g}/{p.far_path_loss_exponent:g} "
                f"beyond {p.breakpoint_m:.1f} m, walls by material ({p.wall_fresnel_rays:g} Fresnel rays), "
                f"σ {p.shadowing_sigma_db:g} dB/{p.shadowing_decorrelation_m:g} m, {k}, seed {self.seed}")

    def __repr__(self) -> str:
        return f"BleChannel(grid={'yes' if self.grid is not None else 'None'}, seed={self.seed}, params={self.params})"


# How `_budget_row` prices the walls (from the map's grid: none, one line of cells, line with the walls'
# materials, a bundle of Fresnel rays).
_NO_WALLS, _LINE, _LINE_TAGGED, _FRESNEL = 0, 1, 2, 3
_EMPTY_PADDED = np.ones((3, 3), dtype=bool)
_EMPTY_SAT = np.zeros((4, 4), dtype=np.int64)
_EMPTY_CODES = np.zeros((3, 3), dtype=np.uint8)
# The columns of `_budget_row`'s terms.
_DISTANCE, _PATH_LOSS, _WALLS, _WALL_LOSS, _SHADOW, _POWER = range(6)
_TERMS = 6
_ROW_ARGUMENTS = "i8, i8, b1[:, ::1], i8[:, ::1], u1[:, ::1], f8[::1], f8[::1], u8"  # BleChannel._row_arguments's


@compiled()  # no signature: compiled into its callers
def _transmitter(numbers, key, ai, aj):
    """(x, y, shadow field unit) of the centre of the transmitter's cell (ai, aj)."""
    ox, oy, q, sigma, decorrelation = numbers[0], numbers[1], numbers[2], numbers[10], numbers[14]
    tcx = ox + (ai + 0.5) * q
    tcy = oy + (aj + 0.5) * q
    return tcx, tcy, (field_unit(key, decorrelation, tcx, tcy) if sigma != 0.0 else 0.0)


@compiled()  # no signature: compiled into its callers
def _pair(mode, rays, padded, sat, codes, loss_by_code, numbers, key, ai, aj, tcx, tcy, unit_tx, bi, bj):
    """The link budget from the transmitter's cell (ai, aj) (centre (tcx, tcy), shadow field unit_tx)
    to the cell (bi, bj), the two taken lower cell first (so a pair gives the same numbers either way
    round): (distance, path loss, walls, wall loss, shadowing, mean power). The one implementation of
    the budget (docs/radio.md)."""
    ox, oy, res, wavelength, dh, min_d, bp, ref_loss, near10, far10, sigma, tx_dbm, g_tx, g_rx, decorrelation = (
        numbers[0], numbers[1], numbers[2], numbers[3], numbers[4], numbers[5], numbers[6], numbers[7], numbers[8],
        numbers[9], numbers[10], numbers[11], numbers[12], numbers[13], numbers[14])
    cx = ox + (bi + 0.5) * res
    cy = oy + (bj + 0.5) * res
    d = py_hypot3(cx - tcx, cy - tcy, dh)
    unit_rx = field_unit(key, decorrelation, cx, cy) if sigma != 0.0 else 0.0
    if bi < ai or (bi == ai and bj < aj):  # (bi, bj) first
        li, lj, hi, hj = bi, bj, ai, aj
        pax, pay, pbx, pby = cx, cy, tcx, tcy
        ua, ub = unit_rx, unit_tx
    else:
        li, lj, hi, hj = ai, aj, bi, bj
        pax, pay, pbx, pby = tcx, tcy, cx, cy
        ua, ub = unit_tx, unit_rx
    dd = max(d, min_d)
    path_loss = ref_loss + near10 * math.log10(min(dd, bp)) + (far10 * math.log10(dd / bp) if dd > bp else 0.0)
    if mode == _NO_WALLS:
        walls, wall_loss = 0, 0.0
    elif mode == _FRESNEL:
        walls, wall_loss = _fresnel_wall_loss(padded, sat, codes, loss_by_code, ox, oy, res, pax, pay, pbx, pby,
                                              wavelength, dh, rays)
    else:  # the cells' line, rows first; without materials every wall costs loss_by_code[0]
        walls, line_loss = _wall_loss_on_line(padded, codes, loss_by_code, lj, li, hj, hi)
        wall_loss = line_loss if mode == _LINE_TAGGED else walls * loss_by_code[0]
    shadow = sigma * (ua + ub) / math.sqrt(2.0) if sigma != 0.0 else 0.0
    return d, path_loss, walls, wall_loss, shadow, tx_dbm + g_tx + g_rx - path_loss - wall_loss - shadow


@compiled(f"void({_ROW_ARGUMENTS}, i8, i8, i8[:, ::1], f8[:, ::1])")
def _budget_row(mode, rays, padded, sat, codes, loss_by_code, numbers, key, ai, aj, cells, terms):  # pragma: no cover
    """The link budget from the cell (ai, aj) to each cell i of `cells`: terms[i] gets the distance, the
    path loss, the walls, the wall loss, the shadowing and the mean power (columns _DISTANCE .. _POWER).
    The scalar calls it for one receiver."""
    tcx, tcy, unit_tx = _transmitter(numbers, key, ai, aj)
    for i in range(terms.shape[0]):
        d, path_loss, walls, wall_loss, shadow, power = _pair(mode, rays, padded, sat, codes, loss_by_code, numbers,
                                                               key, ai, aj, tcx, tcy, unit_tx, cells[i, 0], cells[i, 1])
        terms[i, _DISTANCE] = d
        terms[i, _PATH_LOSS] = path_loss
        terms[i, _WALLS] = walls
        terms[i, _WALL_LOSS] = wall_loss
        terms[i, _SHADOW] = shadow
        terms[i, _POWER] = power


@compiled(f"void({_ROW_ARGUMENTS}, f8, f8, f8[:, ::1], f8[::1])")
def _power_row(mode, rays, padded, sat, codes, loss_by_code, numbers, key, x, y, points, power):  # pragma: no cover
    """The mean power from the place (x, y) to each place of `points` (m): the cells holding them, then
    `_pair`'s budget, as mean_rx_power_dbm has it for each pair."""
    ox, oy, q = numbers[0], numbers[1], numbers[2]
    ai = math.floor((x - ox) / q)
    aj = math.floor((y - oy) / q)
    tcx, tcy, unit_tx = _transmitter(numbers, key, ai, aj)
    for i in range(power.shape[0]):
        bi = math.floor((points[i, 0] - ox) / q)
        bj = math.floor((points[i, 1] - oy) / q)
        power[i] = _pair(mode, rays, padded, sat, codes, loss_by_code, numbers, key, ai, aj, tcx, tcy, unit_tx,
                         bi, bj)[5]
