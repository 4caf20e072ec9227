"""radio_map.png: a top-down map of what one transmitter's frames reach, for any channel model.

Owns: the matplotlib figure (Agg, no screen). Must not know: the medium, robots, runs.
Shows, over the map at RECEIVER_STEP_M, the expected delivery of a 20-byte frame or the mean
received power, with walls drawn on top, the transmitter marked, a colour bar with units and the
50 % delivery contour (or the sensitivity contour on a power map).
"""

from __future__ import annotations

import enum
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import patheffects  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402

from rescuemesh.maps.model import WallMaterial  # noqa: E402

from rescuemesh.radio.channel import ChannelModel  # noqa: E402

#: Wall colours by material code (0: untagged, then maps.model.WallMaterial's order: light, brick,
#: concrete, glass, wood): the heavier the wall, the darker.
_MATERIAL_COLOURS = ("#aaaaaa", "#e0e0e0", "#b5653d", "#4d4d4d", "#9ecae1", "#8c6d46")
#: Spacing in m of the receiver points the map is computed at.
RECEIVER_STEP_M = 0.1
#: Frame size in bytes of the delivery map: a control frame (ARCHITECTURE: wire budget).
MAP_FRAME_BYTES = 20


class RadioMapQuantity(enum.Enum):
    """What the map colours."""

    DELIVERY = "delivery"  # expected delivery probability of a MAP_FRAME_BYTES frame (fading averaged)
    POWER = "power"  # mean received power in dBm (path loss, walls, shadowing; no fading)


def write_radio_map(map_model, channel: ChannelModel, tx_xy: tuple[float, float], out_path: Path, *,
                    quantity: RadioMapQuantity | str = RadioMapQuantity.DELIVERY) -> Path:
    """Draw what a transmitter at `tx_xy` (m, frame map) reaches on `map_model`; write a PNG.

    Raises ValueError (one line) for an unknown quantity or a transmitter off the map or inside an
    obstacle.
    """
    try:
        quantity = RadioMapQuantity(quantity)
    except ValueError:
        known = ", ".join(q.value for q in RadioMapQuantity)
        raise ValueError(f"unknown radio map quantity {quantity!r}; known: {known}") from None
    grid = map_model.grid
    tx = (float(tx_xy[0]), float(tx_xy[1]))
    if not map_model.bounds.contains(*tx) or not grid.in_bounds(*grid.world_to_cell(*tx)):
        b = map_model.bounds
        raise ValueError(f"transmitter ({tx[0]:g}, {tx[1]:g}) is off the map "
                         f"(x {b.x_min:g}..{b.x_max:g}, y {b.y_min:g}..{b.y_max:g} m)")
    if grid.is_occupied(*tx):
        raise ValueError(f"transmitter ({tx[0]:g}, {tx[1]:g}) is inside a wall or obstacle; pick a free spot")

    rows, cols = grid.shape
    extent = (grid.origin_x, grid.origin_x + cols * grid.resolution,
              grid.origin_y, grid.origin_y + rows * grid.resolution)
    xs = np.arange(extent[0] + RECEIVER_STEP_M / 2, extent[1], RECEIVER_STEP_M)
    ys = np.arange(extent[2] + RECEIVER_STEP_M / 2, extent[3], RECEIVER_STEP_M)
    gx, gy = np.meshgrid(xs, ys)
    points = np.column_stack([gx.ravel(), gy.ravel()])
    if quantity is RadioMapQuantity.DELIVERY:
        values = channel.delivery_probability_map(tx, points, MAP_FRAME_BYTES)
    else:
        values = channel.mean_rx_power_map(tx, points)
    values = np.asarray(values, dtype=float).reshape(gy.shape)
    values[~np.isfinite(values)] = np.nan

    width = extent[1] - extent[0]
    height = extent[3] - extent[2]
    fig_w = min(16.0, 3.0 + 0.75 * width)  # like plots.py; the map keeps its aspect, so the height
    fig_h = min(12.0, 2.2 + (fig_w - 3.0) * height / width)  # follows from the width left for it
    fig, ax = plt.subplots(figsize=(fig_w, fig_h), dpi=110)
    if quantity is RadioMapQuantity.DELIVERY:
        image = ax.imshow(values, origin="lower", extent=extent, cmap="viridis", vmin=0.0, vmax=1.0,
                          interpolation="nearest", zorder=1)
        label = f"delivery probability of a {MAP_FRAME_BYTES}-byte frame"
        _contour(ax, xs, ys, values, 0.5, "50 % delivery")
    else:
        finite = values[np.isfinite(values)]
        vmax = float(np.nanmax(finite)) if finite.size else 0.0
        vmin = float(np.nanpercentile(finite, 1)) if finite.size else -1.0
        image = ax.imshow(values, origin="lower", extent=extent, cmap="magma", vmin=min(vmin, vmax - 1.0),
                          vmax=vmax, interpolation="nearest", zorder=1)
        label = "mean received power [dBm]"
        sensitivity = channel.settings().get("sensitivity_dbm")
        if sensitivity is not None:
            _contour(ax, xs, ys, values, float(sensitivity), f"sensitivity {sensitivity:g} dBm")
    fig.colorbar(image, ax=ax, label=label, shrink=0.85, pad=0.02)

    codes = grid.materials if grid.materials is not None else np.zeros(grid.shape, dtype=np.uint8)
    walls = np.ma.masked_where(~grid.occupied, codes)
    ax.imshow(walls, origin="lower", extent=extent, cmap=ListedColormap(_MATERIAL_COLOURS), vmin=-0.5,
              vmax=len(_MATERIAL_COLOURS) - 0.5, interpolation="nearest", zorder=3)
    if grid.materials is not None:  # a legend entry per material the map uses
        for code in sorted(set(np.unique(codes[grid.occupied]).tolist())):
            name = "untagged wall" if code == 0 else f"{list(WallMaterial)[code - 1].value} wall"
            ax.add_patch(Rectangle((0, 0), 0, 0, facecolor=_MATERIAL_COLOURS[code], label=name))
    for name, rect in map_model.regions.items():
        cx, cy = rect.center
        ax.text(cx, cy, name, color="white", fontsize=8, ha="center", va="center", style="italic", zorder=4,
                alpha=0.8)
    for door in map_model.doorways:
        ax.add_patch(Rectangle((door.x_min, door.y_min), door.x_max - door.x_min, door.y_max - door.y_min,
                               facecolor="#ffd54f", edgecolor="#b28704", lw=0.6, zorder=4))
    ax.plot(*tx, marker="*", ms=18, color="red", mec="white", mew=1.2, ls="none", zorder=6,
            label=f"transmitter ({tx[0]:g}, {tx[1]:g})")
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (frame map)")
    ax.set_ylabel("y [m]")
    title = f"{map_model.name}: {quantity.value} from ({tx[0]:g}, {tx[1]:g})\n{channel.describe()}"
    ax.set_title("\n".join(part for line in title.split("\n") for part in textwrap.wrap(line, 160)), fontsize=9)
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.08), fontsize=8, frameon=False, ncol=4)
    fig.tight_layout()
    out_path = Path(out_path)
    fig.savefig(out_path)
    plt.close(fig)
    return out_path


def _contour(ax, xs: np.ndarray, ys: np.ndarray, values: np.ndarray, level: float, label: str) -> None:
    """Draw one labelled contour line (skipped when the field never crosses `level`)."""
    finite = values[np.isfinite(values)]
    if finite.size == 0 or not (finite.min() < level < finite.max()):
        return
    filled = np.where(np.isfinite(values), values, finite.min())  # walls: treat as unreachable
    outline = [patheffects.withStroke(linewidth=2.4, foreground="black")]  # visible on any colour
    contour = ax.contour(xs, ys, filled, levels=[level], colors="white", linewidths=1.2, linestyles="--", zorder=2)
    contour.set_path_effects(outline)
    ax.plot([], [], color="white", ls="--", lw=1.2, label=label, path_effects=outline)
