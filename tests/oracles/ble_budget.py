"""Oracle of BleChannel's link budget: the Python `_budget_terms` computed before the scalar called the
compiled row (radio/ble.py `_budget_row`), kept verbatim but for reading the channel's fields from
outside and taking the shadow field's units from the field's own oracle (oracles/shadowing.py), as
the channel took them from the field's Python then. The wall walks it calls are walls.py's public
functions, checked against their own oracles (oracles/walls.py)."""

from __future__ import annotations

import math

from oracles.shadowing import unit
from rescuemesh.radio.walls import wall_loss_cells, wall_loss_fresnel

_SQRT2 = math.sqrt(2.0)


def budget_terms(ch, ai: int, aj: int, bi: int, bj: int) -> tuple[float, float, int, float, float, float]:
    """(distance, path loss, walls, shadow, mean power, wall loss) between the centres of cells
    (ai, aj) <= (bi, bj) of BleChannel `ch`."""
    pa, pb = ch._centre(ai, aj), ch._centre(bi, bj)
    p = ch.params
    d = math.hypot(pb[0] - pa[0], pb[1] - pa[1], ch._dh)
    dd = max(d, p.min_distance_m)
    bp = ch._bp
    path_loss = p.reference_loss_db + ch._near10 * math.log10(min(dd, bp)) \
        + (ch._far10 * math.log10(dd / bp) if dd > bp else 0.0)
    if ch.grid is None:
        walls, wall_loss = 0, 0.0
    elif ch._rays == 1:
        walls, wall_loss = wall_loss_cells(ch.grid, aj, ai, bj, bi, ch._loss_by_code)
    else:
        walls, wall_loss = wall_loss_fresnel(ch.grid, pa, pb, ch._loss_by_code, ch._wavelength, ch._dh, ch._rays)
    shadow = ch.shadow.sigma_db * (unit(ch.shadow, *pa) + unit(ch.shadow, *pb)) / _SQRT2 \
        if ch.shadow.sigma_db != 0.0 else 0.0
    power = p.tx_power_dbm + p.tx_antenna_gain_dbi + p.rx_antenna_gain_dbi - path_loss - wall_loss - shadow
    return d, path_loss, walls, shadow, power, wall_loss
