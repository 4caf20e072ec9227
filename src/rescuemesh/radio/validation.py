"""The BLE channel model checked against measured BLE data: its error in dB, per wall count.

Owns: reading the two packaged data sets (data/radio/, with their licences), predicting them with
BleChannel at the data sets' own antenna heights, the held-out figures and the goals (issue 20).
Must not know: the medium, robots, plots (report/radio_validation.py draws them), the CLI.

Kolakowski 2021 (a furnished flat, 6 anchors at 1.85-2.62 m, a tag on a robot at 1.3 m, 22,277
samples at 4,104 places): the flat's layout polygon becomes an occupancy grid (outside the polygon
is wall, tagged brick: the data set does not say what its walls are; the layout draws them
0.10-0.17 m thick); BleChannel predicts the mean power from every anchor to every place (no
shadowing). Only one number per anchor is fitted (transmit power, gains, RSSI bias: the mean of
measured minus predicted), and only on half of the flat: the places in the "black" squares of a
2 m checkerboard (an area split, not a random one: whole 2 x 2 m areas are held out, twice the
residuals' decorrelation distance). The other half is predicted. Local means: the held-out
residuals averaged per anchor over 0.5 m cells (and walls crossed); their mean and RMS per wall
count are the goals (|mean| <= 3 dB, RMS <= 5 dB).

Danis 2021 (an open-plan office, 12 sensors at 1.22 and 2.30 m, a beacon standing at 81 + 45
places at 1.85-1.90 m, RSSI histograms): no walls; the data's own fit (per-sensor offsets and one
exponent, bootstrap over places) gives the line-of-sight exponent and the spread of the places'
mean RSSI about it, each with a 95 % interval; the goals are the model's exponent and shadowing
sigma inside them.
"""

from __future__ import annotations

import ast
import csv
import enum
import json
import math
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

import numpy as np

from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.maps.model import WallMaterial
from rescuemesh.radio.ble import BleChannel, BleParams
from rescuemesh.radio.fading import gain_db_distribution
from rescuemesh.radio.walls import count_walls_many

#: Tag height on Kolakowski's robot (dataset_description.pdf, III: "at the height of 1.3 m").
KOLAKOWSKI_TAG_HEIGHT_M = 1.3
#: The material the Kolakowski flat's walls are taken to be (stated assumption, see above).
KOLAKOWSKI_WALL_MATERIAL = WallMaterial.BRICK
#: Side in m of the checkerboard squares that split the data into a fitted and a held-out half.
SPLIT_SQUARE_M = 2.0
#: Side in m of the cells residuals are averaged over (local means).
LOCAL_CELL_M = 0.5
#: Grid resolution in m for the flat's walls (the office's own).
GRID_RESOLUTION_M = 0.05
#: Goals (issue 20): |mean error| and RMS of the held-out local means, per wall count, in dB.
GOAL_MEAN_DB = 3.0
GOAL_RMS_DB = 5.0
#: Separations (m) the residuals' correlation is tabulated at, and the cells it is computed on.
CORRELATION_BINS_M = np.arange(0.0, 4.01, 0.25)
CORRELATION_CELL_M = 0.25
#: Bootstrap resamples for the Danis fit's intervals, and its seed (fixed: same figures every run).
BOOTSTRAP_RESAMPLES = 400
BOOTSTRAP_SEED = 0
#: The model before issue 20: one slope n = 4 from 1 m on the 2D distance, 4.6 dB per wall, walls
#: priced on the straight line alone.
PREVIOUS_MODEL = {"path_loss_exponent": 4.0, "far_path_loss_exponent": 4.0, "wall_loss_db": 4.6,
                  "wall_fresnel_rays": 1,
                  **{f"wall_loss_{m.value}_db": 4.6 for m in WallMaterial}}


class DataSet(enum.Enum):
    """The packaged measurement sets (`rescuemesh radio-validate --data NAME`)."""

    KOLAKOWSKI = "kolakowski"
    DANIS = "danis"


class ValidationDataError(RuntimeError):
    """A packaged data file is missing or unreadable (a broken install)."""


def data_folder(dataset: DataSet) -> Path:
    name = {DataSet.KOLAKOWSKI: "kolakowski2021", DataSet.DANIS: "danis2021"}[dataset]
    folder = Path(str(resources.files("rescuemesh") / "data" / "radio" / name))
    if not (folder / "ATTRIBUTION.md").is_file():
        raise ValidationDataError(f"the {dataset.value} data set is not installed at {folder} "
                                  "(package data missing: reinstall rescuemesh)")
    return folder


# ------------------------------------------------------------------------------------- results
@dataclass(frozen=True)
class WallRow:
    """Held-out local means crossing `walls` walls: how many, their mean error and RMS in dB."""

    walls: int | None  # None: all
    cells: int
    samples: int
    mean_db: float
    rms_db: float


@dataclass(frozen=True)
class Goal:
    what: str
    value: float
    limit: str
    met: bool


@dataclass
class KolakowskiResult:
    model: str
    rows: list[WallRow]
    sample_rms_db: float
    local_spread_db: float  # std of the held-out local means
    sample_spread_db: float  # std of the held-out samples' residuals
    model_sigma_db: float
    model_sample_sigma_db: float  # sqrt(sigma^2 + the Rician fading's spread in dB)
    offsets_db: dict[int, float]
    correlation: list[tuple[float, float, int]]  # (separation m, correlation, pairs)
    decorrelation_fit_m: float
    previous_rows: list[WallRow] = field(default_factory=list)
    scatter: dict[str, np.ndarray] = field(default_factory=dict)  # for the plot
    goals: list[Goal] = field(default_factory=list)


@dataclass
class DanisResult:
    model: str
    places: int
    pairs: int
    exponent_fit: float
    exponent_ci: tuple[float, float]
    spread_fit_db: float
    spread_ci_db: tuple[float, float]
    within_place_sd_db: float
    model_exponent: float
    model_sigma_db: float
    model_sample_sigma_db: float
    breakpoint_m: float
    max_distance_m: float
    holdout: WallRow
    scatter: dict[str, np.ndarray] = field(default_factory=dict)
    goals: list[Goal] = field(default_factory=list)


# ------------------------------------------------------------------------------------- helpers
def _inside_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule: which of `points` (N, 2) lie inside the closed `polygon` (M, 2)."""
    x, y = points[:, 0][:, None], points[:, 1][:, None]
    x0, y0 = polygon[:, 0][None, :], polygon[:, 1][None, :]
    x1, y1 = np.roll(polygon[:, 0], -1)[None, :], np.roll(polygon[:, 1], -1)[None, :]
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return np.count_nonzero(crosses & (x < x_at), axis=1) % 2 == 1


def fading_spread_db(params: BleParams) -> float:
    """Standard deviation in dB of the per-frame Rician gain 10 log10(g) (K = params.rician_k)."""
    gain_db, mass = gain_db_distribution(params.rician_k, step_db=0.01)
    mean = float(np.sum(gain_db * mass))
    return math.sqrt(float(np.sum((gain_db - mean) ** 2 * mass)))


def _wall_rows(walls: np.ndarray, local: np.ndarray, counts: np.ndarray) -> list[WallRow]:
    rows = []
    for w in [*sorted(set(walls.tolist())), None]:
        m = np.ones(len(walls), bool) if w is None else walls == w
        v = local[m]
        rows.append(WallRow(w, int(m.sum()), int(counts[m].sum()), float(v.mean()), float(np.sqrt(np.mean(v**2)))))
    return rows


def _local_means(keys: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique rows of `keys` (int), the mean of `values` over each, and the count."""
    uniq, inverse = np.unique(keys, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    counts = np.bincount(inverse)
    return uniq, np.bincount(inverse, values) / counts, counts


def _correlation(anchor: np.ndarray, xy: np.ndarray, residual: np.ndarray) -> list[tuple[float, float, int]]:
    """Correlation of residual local means (CORRELATION_CELL_M cells, per anchor) against separation."""
    keys = np.c_[anchor, np.floor(xy / CORRELATION_CELL_M).astype(np.int64)]
    uniq, local, _ = _local_means(keys, residual)
    centres = (uniq[:, 1:] + 0.5) * CORRELATION_CELL_M
    bins = CORRELATION_BINS_M
    num = np.zeros(len(bins))
    den = np.zeros(len(bins))
    var = 0.0
    n_var = 0
    for a in np.unique(uniq[:, 0]):
        m = uniq[:, 0] == a
        v = local[m] - local[m].mean()
        c = centres[m]
        d = np.hypot(c[:, None, 0] - c[None, :, 0], c[:, None, 1] - c[None, :, 1]).ravel()
        k = np.round(d / (bins[1] - bins[0])).astype(np.int64)
        ok = k < len(bins)
        prod = np.outer(v, v).ravel()
        num += np.bincount(k[ok], prod[ok], minlength=len(bins))[:len(bins)]
        den += np.bincount(k[ok], minlength=len(bins))[:len(bins)]
        var += float(np.sum(v**2))
        n_var += len(v)
    var /= max(n_var, 1)
    return [(float(b), float(nu / de / var), int(de)) for b, nu, de in zip(bins, num, den) if de > 0]


def _fit_decorrelation(corr: list[tuple[float, float, int]]) -> float:
    """Gudmundson's exp(-d / d_c) fitted (least squares on log-free form, pair-weighted) for d > 0."""
    pts = [(d, r, n) for d, r, n in corr if 0.0 < d <= 3.0]
    grid = np.arange(0.1, 5.0, 0.01)
    cost = [sum(n * (r - math.exp(-d / dc)) ** 2 for d, r, n in pts) for dc in grid]
    return float(grid[int(np.argmin(cost))])


# ------------------------------------------------------------------------------------- Kolakowski
def _read_kolakowski() -> tuple[np.ndarray, dict[int, np.ndarray], np.ndarray, np.ndarray]:
    """(places (N, 2), rssi by anchor id (N,) with NaN where not received, anchors (6, 4) id x y z,
    layout polygon (M, 2))."""
    folder = data_folder(DataSet.KOLAKOWSKI)
    with open(folder / "calibration_df.csv", newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    table = np.array([[float(v) if v else np.nan for v in r] for r in rows[1:]])
    col = {h: i for i, h in enumerate(header) if h}
    anchors = np.loadtxt(folder / "anchors.csv", delimiter=",", skiprows=1).reshape(-1, 4)
    layout = np.loadtxt(folder / "layout.csv", delimiter=",", skiprows=1).reshape(-1, 2)
    places = table[:, [col["x"], col["y"]]]
    rssi = {int(a[0]): table[:, col[f"rssi_{int(a[0])}"]] for a in anchors}
    return places, rssi, anchors, layout


def kolakowski_grid(layout: np.ndarray, material: WallMaterial = KOLAKOWSKI_WALL_MATERIAL) -> OccupancyGrid:
    """The flat as an occupancy grid: every cell whose centre is outside the layout polygon is wall."""
    res = GRID_RESOLUTION_M
    ox, oy = layout.min(axis=0) - 0.5
    cols, rows = np.ceil((layout.max(axis=0) + 0.5 - (ox, oy)) / res).astype(int)
    xs = ox + (np.arange(cols) + 0.5) * res
    ys = oy + (np.arange(rows) + 0.5) * res
    gx, gy = np.meshgrid(xs, ys)
    inside = _inside_polygon(np.c_[gx.ravel(), gy.ravel()], layout).reshape(rows, cols)
    occupied = ~inside
    materials = np.where(occupied, material.code, 0).astype(np.uint8)
    return OccupancyGrid(occupied, res, float(ox), float(oy), materials=materials)


def _predict_kolakowski(params: BleParams, grid: OccupancyGrid, places, anchors, *, two_d: bool = False):
    """Predicted mean power (no shadowing) and walls from every anchor to every place: (6, N) each."""
    power, walls = [], []
    for _, ax, ay, az in anchors:
        heights = (1.0, 1.0) if two_d else (float(az), KOLAKOWSKI_TAG_HEIGHT_M)
        p = replace(params, tx_antenna_height_m=heights[0], rx_antenna_height_m=heights[1], shadowing_sigma_db=0.0)
        channel = BleChannel(grid, params=p)
        power.append(channel.mean_rx_power_map((ax, ay), places))
        walls.append(count_walls_many(grid, channel._centre(*channel._cell((ax, ay))), places))
    return np.array(power), np.array(walls)


class Split(enum.Enum):
    """Which places fit the offsets (the rest are predicted)."""

    CHECKERBOARD = "checkerboard"  # the "black" 2 m squares (the goals' split)
    WEST = "west"  # x < 4 m: the flat's west rooms fit, the east ones are predicted (docs/radio.md)
    EAST = "east"  # x >= 4 m: the other way round


def validate_kolakowski(params: BleParams | None = None, split: Split = Split.CHECKERBOARD) -> KolakowskiResult:
    """Fit per-anchor offsets on half the flat (2 m checkerboard), predict the other half."""
    params = params or BleParams()
    places, rssi, anchors, layout = _read_kolakowski()
    grid = kolakowski_grid(layout)
    result = _kolakowski_figures(params, grid, places, rssi, anchors, two_d=False, split=split)
    previous = _kolakowski_figures(replace(params, **PREVIOUS_MODEL), grid, places, rssi, anchors, two_d=True,
                                   split=split)
    result.previous_rows = previous.rows
    goals = []
    for row in result.rows:
        label = "all" if row.walls is None else f"{row.walls} wall{'s' if row.walls != 1 else ''}"
        goals.append(Goal(f"held-out |mean error|, {label}", abs(row.mean_db), f"<= {GOAL_MEAN_DB:g} dB",
                          abs(row.mean_db) <= GOAL_MEAN_DB))
        goals.append(Goal(f"held-out RMS of local means, {label}", row.rms_db, f"<= {GOAL_RMS_DB:g} dB",
                          row.rms_db <= GOAL_RMS_DB))
    result.goals = goals
    return result


def _kolakowski_figures(params, grid, places, rssi, anchors, *, two_d: bool, split: Split) -> KolakowskiResult:
    power, walls = _predict_kolakowski(params, grid, places, anchors, two_d=two_d)
    a_idx, p_idx = [], []
    measured = []
    for k, a in enumerate(anchors):
        r = rssi[int(a[0])]
        ok = np.flatnonzero(~np.isnan(r))
        a_idx.append(np.full(len(ok), k))
        p_idx.append(ok)
        measured.append(r[ok])
    a_idx, p_idx, measured = np.concatenate(a_idx), np.concatenate(p_idx), np.concatenate(measured)
    predicted = power[a_idx, p_idx]
    wall_count = walls[a_idx, p_idx]
    xy = places[p_idx]
    square = np.floor(xy / SPLIT_SQUARE_M).astype(np.int64)
    fitted = {Split.CHECKERBOARD: (square[:, 0] + square[:, 1]) % 2 == 0, Split.WEST: xy[:, 0] < 4.0,
              Split.EAST: xy[:, 0] >= 4.0}[split]
    offsets = np.array([np.mean(measured[fitted & (a_idx == k)] - predicted[fitted & (a_idx == k)])
                        for k in range(len(anchors))])
    residual = measured - (predicted + offsets[a_idx])
    held = ~fitted
    keys = np.c_[a_idx, np.floor(xy / LOCAL_CELL_M).astype(np.int64), wall_count][held]
    uniq, local, counts = _local_means(keys, residual[held])
    rows = _wall_rows(uniq[:, 3], local, counts)
    _, local_pred, _ = _local_means(keys, (predicted + offsets[a_idx])[held])
    corr = _correlation(a_idx, xy, residual)
    sigma = params.shadowing_sigma_db
    fade = fading_spread_db(params)
    return KolakowskiResult(
        model=BleChannel(None, params=params).describe(), rows=rows,
        sample_rms_db=float(np.sqrt(np.mean(residual[held] ** 2))),
        local_spread_db=float(np.std(local)), sample_spread_db=float(np.std(residual[held])),
        model_sigma_db=sigma, model_sample_sigma_db=math.hypot(sigma, fade),
        offsets_db={int(anchors[k][0]): float(offsets[k]) for k in range(len(anchors))},
        correlation=corr, decorrelation_fit_m=_fit_decorrelation(corr),
        scatter={"predicted": local_pred, "measured": local_pred + local, "walls": uniq[:, 3]})


# ------------------------------------------------------------------------------------- Danis
def _read_danis() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(place id, place xyz (P, 3), sensor index, sensor xyz (12, 3), mean RSSI, within-place sd)
    per (place, sensor) with a histogram, both sets together."""
    folder = data_folder(DataSet.DANIS)
    sensors: dict[str, list[float]] = {}
    place_xyz: list[tuple[float, float, float]] = []
    rows = []
    for name in ("set_1.hst", "set_2.hst"):
        fields = {}
        for line in (folder / name).read_text().splitlines():
            key, _, value = line.partition(":")
            fields[key] = value
        bins = np.array(json.loads(fields["Bins"]), dtype=float)
        dongles = json.loads(fields["Dongles"])
        for mac, (xyz, _colour, _alias) in dongles.items():
            sensors.setdefault(mac, xyz)
        for pos, by_sensor in json.loads(fields["Fingerprints"]).items():
            place = tuple(float(v) for v in ast.literal_eval(pos))
            place_xyz.append(place)
            pid = len(place_xyz) - 1
            for mac, by_beacon in by_sensor.items():
                hist = np.asarray(next(iter(by_beacon.values())), dtype=float)
                if hist.sum() <= 0:
                    continue
                hist = hist / hist.sum()
                levels = bins[: len(hist)]  # one value per bin, from -100 dBm up
                mean = float(np.sum(hist * levels))
                rows.append((pid, list(sensors).index(mac), mean, math.sqrt(float(np.sum(hist * (levels - mean) ** 2)))))
    table = np.array(rows)
    return (table[:, 0].astype(int), np.array(place_xyz), table[:, 1].astype(int),
            np.array(list(sensors.values())), np.c_[table[:, 2], table[:, 3]])


def _lstsq_exponent(sensor: np.ndarray, distance: np.ndarray, rssi: np.ndarray, n_sensors: int):
    """Least squares rssi = offset[sensor] - 10 n log10(distance): (n, residual spread). Solved by
    removing each sensor's means (the offsets' normal equations), not by a dense solver."""
    x = -10.0 * np.log10(distance)
    count = np.bincount(sensor, minlength=n_sensors).astype(float)
    count[count == 0] = 1.0
    xc = x - (np.bincount(sensor, x, n_sensors) / count)[sensor]
    yc = rssi - (np.bincount(sensor, rssi, n_sensors) / count)[sensor]
    n = float(np.sum(xc * yc) / np.sum(xc * xc))
    return n, float(np.std(yc - n * xc))


def validate_danis(params: BleParams | None = None) -> DanisResult:
    params = params or BleParams()
    pid, places, sensor, sensors_xyz, stats = _read_danis()
    rssi, within = stats[:, 0], stats[:, 1]
    delta = places[pid] - sensors_xyz[sensor]
    d3 = np.sqrt(np.sum(delta**2, axis=1))
    n_fit, spread = _lstsq_exponent(sensor, d3, rssi, len(sensors_xyz))
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    by_place = [np.flatnonzero(pid == k) for k in range(len(places))]
    boot_n, boot_s = [], []
    for _ in range(BOOTSTRAP_RESAMPLES):
        idx = np.concatenate([by_place[k] for k in rng.integers(0, len(places), len(places))])
        n_b, s_b = _lstsq_exponent(sensor[idx], d3[idx], rssi[idx], len(sensors_xyz))
        boot_n.append(n_b)
        boot_s.append(s_b)
    n_ci = tuple(float(v) for v in np.percentile(boot_n, [2.5, 97.5]))
    s_ci = tuple(float(v) for v in np.percentile(boot_s, [2.5, 97.5]))
    # the model's prediction: each pair at its own heights, no walls, no shadowing
    predicted = np.empty(len(rssi))
    for k, (sx, sy, sz) in enumerate(sensors_xyz):
        m = sensor == k
        for z in np.unique(places[pid[m], 2]):
            mz = m & (places[pid, 2] == z)
            p = replace(params, tx_antenna_height_m=float(z), rx_antenna_height_m=float(sz), shadowing_sigma_db=0.0)
            d2 = np.hypot(delta[mz, 0], delta[mz, 1])
            predicted[mz] = p.tx_power_dbm + p.tx_antenna_gain_dbi + p.rx_antenna_gain_dbi \
                - p.path_loss_db(p.distance_3d(d2))
    # held out by area: offsets fitted on the west half of the office, the east half predicted
    west = places[pid, 0] < np.median(places[:, 0])
    offsets = np.array([np.mean((rssi - predicted)[west & (sensor == k)]) for k in range(len(sensors_xyz))])
    residual = rssi - (predicted + offsets[sensor])
    held = residual[~west]
    holdout = WallRow(0, int(np.count_nonzero(~west)), int(np.count_nonzero(~west)),
                      float(held.mean()), float(np.sqrt(np.mean(held**2))))
    sigma = params.shadowing_sigma_db
    fade = fading_spread_db(params)
    bp = min(replace(params, tx_antenna_height_m=float(z), rx_antenna_height_m=float(sz)).breakpoint_m
             for z in np.unique(places[:, 2]) for sz in np.unique(sensors_xyz[:, 2]))
    result = DanisResult(
        model=BleChannel(None, params=params).describe(), places=len(places), pairs=len(rssi),
        exponent_fit=n_fit, exponent_ci=n_ci, spread_fit_db=spread, spread_ci_db=s_ci,
        within_place_sd_db=float(np.sqrt(np.mean(within**2))), model_exponent=params.path_loss_exponent,
        model_sigma_db=sigma, model_sample_sigma_db=math.hypot(sigma, fade), breakpoint_m=bp,
        max_distance_m=float(d3.max()), holdout=holdout,
        scatter={"distance": d3, "measured": rssi - offsets[sensor], "predicted": predicted})
    result.goals = [
        Goal("line-of-sight exponent inside the data's 95 % interval", params.path_loss_exponent,
             f"{n_ci[0]:.2f}..{n_ci[1]:.2f}", n_ci[0] <= params.path_loss_exponent <= n_ci[1]),
        Goal("shadowing sigma inside the data's spread interval", sigma, f"{s_ci[0]:.2f}..{s_ci[1]:.2f} dB",
             s_ci[0] <= sigma <= s_ci[1]),
        Goal("the breakpoint beyond the data's distances (so the LOS slope is what is tested)", bp,
             f"> {d3.max():.1f} m", bp > d3.max()),
    ]
    return result


# ------------------------------------------------------------------------------------- text
def _rows_text(rows: list[WallRow]) -> list[str]:
    out = [f"    {'walls':>5} {'cells':>6} {'samples':>8} {'mean':>7} {'RMS':>6}"]
    for r in rows:
        out.append(f"    {'all' if r.walls is None else r.walls:>5} {r.cells:>6} {r.samples:>8} "
                   f"{r.mean_db:>+7.1f} {r.rms_db:>6.1f}")
    return out


def format_kolakowski(r: KolakowskiResult) -> str:
    lines = ["Kolakowski 2021 (furnished flat; CC BY 4.0): offsets per anchor fitted on half the flat "
             f"({SPLIT_SQUARE_M:g} m checkerboard), the other half predicted",
             f"  model: {r.model}",
             f"  held-out local means ({LOCAL_CELL_M:g} m cells), measured - predicted, dB:",
             *_rows_text(r.rows),
             "  the previous model (n 4 from 1 m, 2D distance, 4.6 dB per wall), same split:",
             *_rows_text(r.previous_rows),
             f"  per-sample RMS error {r.sample_rms_db:.1f} dB; offsets "
             + ", ".join(f"{k}: {v:+.1f}" for k, v in r.offsets_db.items()) + " dB",
             f"  spread of local means {r.local_spread_db:.1f} dB against the model's shadowing sigma "
             f"{r.model_sigma_db:.1f} dB; of samples {r.sample_spread_db:.1f} dB against sigma with fading "
             f"{r.model_sample_sigma_db:.1f} dB",
             "  correlation of residuals against separation (m: rho): "
             + ", ".join(f"{d:.2f}: {c:+.2f}" for d, c, _ in r.correlation[:11]),
             f"  fitted decorrelation distance (exp(-d/dc)) {r.decorrelation_fit_m:.2f} m",
             *_goals_text(r.goals)]
    return "\n".join(lines)


def format_danis(r: DanisResult) -> str:
    lines = [f"Danis 2021 (open-plan office, no walls; CC0): {r.places} places, {r.pairs} place-sensor pairs",
             f"  model: {r.model}",
             f"  data's own fit: exponent {r.exponent_fit:.2f} (95 % {r.exponent_ci[0]:.2f}..{r.exponent_ci[1]:.2f}), "
             f"spread of place means {r.spread_fit_db:.2f} dB ({r.spread_ci_db[0]:.2f}..{r.spread_ci_db[1]:.2f}); "
             f"within a place {r.within_place_sd_db:.1f} dB",
             f"  model: exponent {r.model_exponent:g} (breakpoint {r.breakpoint_m:.0f} m, data to "
             f"{r.max_distance_m:.1f} m), shadowing sigma {r.model_sigma_db:g} dB, with fading "
             f"{r.model_sample_sigma_db:.1f} dB (data per sample "
             f"{math.hypot(r.spread_fit_db, r.within_place_sd_db):.1f} dB)",
             f"  east half held out (offsets from the west half): mean error {r.holdout.mean_db:+.1f} dB, "
             f"RMS {r.holdout.rms_db:.1f} dB over {r.holdout.cells} place-sensor means",
             *_goals_text(r.goals)]
    return "\n".join(lines)


def _goals_text(goals: list[Goal]) -> list[str]:
    out = ["  goals:"]
    for g in goals:
        out.append(f"    [{'x' if g.met else ' '}] {g.what}: {g.value:.2f} ({g.limit})")
    return out
