"""How many walls a straight radio path crosses, counted on the map's occupancy grid, and their loss.

Owns: the wall count of a segment (one, between two cells, and one transmitter to many receivers),
the sum of the crossed walls' losses given a loss per material code, and that sum averaged over
the first Fresnel zone. Must not know: where those losses come from (radio/materials.py), radios,
the medium.

Each wall crossed (a run of occupied cells along the path) is priced by the dearest material among
its cells (the grid's `materials`, 0 when the map tags none): `wall_loss_cells` and `wall_loss_many`
add max(loss_by_code[code]) per wall. The dearest, not the first: where a light partition meets a
concrete wall a path may enter the junction through the partition's cells and go on through the
concrete, and pricing it as the partition drew stripes on the radio map.

The path is the straight line between the cells holding its two ends, rasterised with Bresenham's
algorithm (the cells of `skimage.draw.line`): one cell per step along the major axis, so it never
skips a row or a column and no axis-aligned wall, however thin, can be jumped. A wall is a run of
occupied cells along it: the count is the number of free -> occupied transitions met walking from
`a` to `b`. So a wall two cells thick counts once; furniture counts like a wall; a cell off the
grid counts as occupied (the map's outside is solid). Starting inside an obstacle does not count
that obstacle; ending inside one does (the path entered it).

Why not sample the segment every half cell: Bresenham visits the same walls on axis-aligned maps
and is exact integer arithmetic. A segment's cells come from the closed form of the algorithm (cell
i of a line whose major axis spans n cells has minor offset floor((2 i |d_minor| + n) / (2 n)), the
cells of `skimage.draw.line`), walked in a loop compiled with numba: 2.6 / 4.6 / 7.0 us for a 1,
10 and 20 m segment on a loaded machine, where drawing the line with scikit-image and counting with
numpy took 5.0 / 32.8 / 34.5 (a 30-robot convoy counts walls for some 360,000 new pairs of cells). The vectorised count for many receivers uses the same closed
form in numpy, so the two agree cell for cell (tests/radio/test_walls.py compares them).
Limitation: the line is 8-connected, so a diagonal wall one cell thick whose cells touch only at
corners can be slipped through; the office's walls are axis-aligned and two cells thick.

Across the first Fresnel zone (`wall_loss_fresnel`, `wall_loss_fresnel_many`; BleParams.
wall_fresnel_rays): the same pricing along a bundle of rays at the lateral offsets s r1(t),
s evenly spaced in [-1, 1], r1(t) = sqrt(lambda d t (1 - t)) the first Fresnel zone's radius at
the fraction t of the path (ITU-R P.526), each ray FRESNEL_SEGMENTS straight segments; the rays'
losses are averaged in power. A wall end, corner or door jamb that only clips the zone costs part
of its wall (docs/radio.md, "Walls across the first Fresnel zone"). Walls are still counted on the
straight line. One ray is the straight line: `wall_loss_cells` exactly.

The simulator's channel model is the only user, so this module needs the sim extra (numba).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from rescuemesh.maps.grid import OccupancyGrid

#: Upper bound on cells held in memory at once by the vectorised count.
_CHUNK_CELLS = 2_000_000
#: Padded occupancy (a border of occupied cells all round) of the last few grids, by identity.
_PADDED: dict[int, tuple[OccupancyGrid, np.ndarray]] = {}


def _padded(grid: OccupancyGrid) -> np.ndarray:
    entry = _PADDED.get(id(grid))
    if entry is None or entry[0] is not grid:
        if len(_PADDED) >= 8:
            _PADDED.clear()
        entry = _PADDED[id(grid)] = (grid, np.pad(np.asarray(grid.occupied, dtype=bool), 1, constant_values=True))
    return entry[1]


def _occupied_sat(grid: OccupancyGrid) -> np.ndarray:
    """The summed-area table of `_padded(grid)`: sat[r, c] = occupied cells in padded[:r, :c] (one
    row and column of zeros in front), so any box's count is four reads (`_box_free`)."""
    entry = _SAT.get(id(grid))
    if entry is None or entry[0] is not grid:
        if len(_SAT) >= 8:
            _SAT.clear()
        padded = _padded(grid)
        sat = np.zeros((padded.shape[0] + 1, padded.shape[1] + 1), dtype=np.int64)
        np.cumsum(np.cumsum(padded, axis=0, dtype=np.int64), axis=1, out=sat[1:, 1:])
        entry = _SAT[id(grid)] = (grid, sat)
    return entry[1]


_SAT: dict[int, tuple[OccupancyGrid, np.ndarray]] = {}


def _occupied_cells(grid: OccupancyGrid, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Occupancy of cells (row, col) of any shape; off the grid is occupied (the padded border)."""
    n_rows, n_cols = grid.occupied.shape
    rows = np.minimum(np.maximum(rows, -1), n_rows) + 1  # np.clip costs 4x more on small arrays
    cols = np.minimum(np.maximum(cols, -1), n_cols) + 1
    return _padded(grid)[rows, cols]


def _cell(grid: OccupancyGrid, x: float, y: float) -> tuple[int, int]:
    return (math.floor((y - grid.origin_y) / grid.resolution), math.floor((x - grid.origin_x) / grid.resolution))


def count_walls(grid: OccupancyGrid, a: tuple[float, float], b: tuple[float, float]) -> int:
    """Walls crossed on the straight path from `a` to `b` (points in m, frame map)."""
    return count_walls_cells(grid, *_cell(grid, float(a[0]), float(a[1])), *_cell(grid, float(b[0]), float(b[1])))


def count_walls_cells(grid: OccupancyGrid, r0: int, c0: int, r1: int, c1: int) -> int:
    """Walls crossed on the path from cell (row r0, col c0) to cell (r1, c1): count_walls between
    the two cells' centres, without mapping the points back to cells."""
    return _walls_on_line(_padded(grid), r0, c0, r1, c1)


# The Bresenham line the wall walks share: `_line` sets it up, `_line_cell` gives its i-th cell.
@numba.njit(inline="always")
def _line(r0, c0, r1, c1):  # pragma: no cover - compiled
    """(r0, c0, sign_r, sign_c, col_major, n, minor_span, steps) of the line from cell (r0, c0) to
    (r1, c1): n steps along the major axis, the minor axis rounded half up."""
    d_r = r1 - r0
    d_c = c1 - c0
    sign_r = (d_r > 0) - (d_r < 0)
    sign_c = (d_c > 0) - (d_c < 0)
    col_major = abs(d_c) >= abs(d_r)
    n = abs(d_c) if col_major else abs(d_r)
    minor_span = abs(d_r) if col_major else abs(d_c)
    return r0, c0, sign_r, sign_c, col_major, n, minor_span, max(n, 1)


@numba.njit(inline="always")
def _line_cell(line, i):  # pragma: no cover - compiled
    """(row, column) of cell i (0..n) of `line`."""
    r0, c0, sign_r, sign_c, col_major, n, minor_span, steps = line
    minor = (2 * i * minor_span + steps) // (2 * steps)
    if col_major:
        return r0 + sign_r * minor, c0 + sign_c * i
    return r0 + sign_r * i, c0 + sign_c * minor


@numba.njit(inline="always")
def _price_cells(padded, codes, loss_by_code, line, first, last, walls, loss, run, in_run, before):  # pragma: no cover
    """Walk cells first..last of `line`, counting walls entered (not at cell 0) and adding each wall's
    dearest loss_by_code[code] to `loss` when it is left; the walk's state (walls, loss, run: the
    dearest cell of the wall being crossed, in_run, before: whether the previous cell was occupied)
    goes in and comes out, so a walk may be done in pieces."""
    n_rows = padded.shape[0] - 2
    n_cols = padded.shape[1] - 2
    for i in range(first, last + 1):
        r, c = _line_cell(line, i)
        pr = min(max(r, -1), n_rows) + 1
        pc = min(max(c, -1), n_cols) + 1
        occupied = padded[pr, pc]
        if occupied and not before and i > 0:
            walls += 1
            run = loss_by_code[codes[pr, pc]]
            in_run = True
        elif occupied and in_run:
            run = max(run, loss_by_code[codes[pr, pc]])
        elif not occupied and in_run:
            loss += run
            in_run = False
        before = occupied
    return walls, loss, run, in_run, before


# Compiled when the module is imported (explicit signature), from numba's on-disk cache after the
# first time, as sim/gridcast.py.
@numba.njit("i8(b1[:, ::1], i8, i8, i8, i8)", cache=True, nogil=True)
def _walls_on_line(padded, r0, c0, r1, c1):  # pragma: no cover - compiled
    """Free -> occupied transitions on the Bresenham line from cell (r0, c0) to (r1, c1) of the
    grid whose padded occupancy is `padded` (off the grid: the occupied border)."""
    n_rows = padded.shape[0] - 2
    n_cols = padded.shape[1] - 2
    line = _line(r0, c0, r1, c1)
    walls = 0
    before = False
    for i in range(line[5] + 1):
        r, c = _line_cell(line, i)
        occupied = padded[min(max(r, -1), n_rows) + 1, min(max(c, -1), n_cols) + 1]
        if occupied and not before and i > 0:
            walls += 1
        before = occupied
    return walls


def _padded_codes(grid: OccupancyGrid) -> np.ndarray:
    """The grid's material codes padded like `_padded` (the border: code 0, an untagged wall)."""
    entry = _PADDED_CODES.get(id(grid))
    if entry is None or entry[0] is not grid:
        if len(_PADDED_CODES) >= 8:
            _PADDED_CODES.clear()
        codes = grid.materials if grid.materials is not None else np.zeros(grid.occupied.shape, dtype=np.uint8)
        entry = _PADDED_CODES[id(grid)] = (grid, np.pad(np.asarray(codes, dtype=np.uint8), 1, constant_values=0))
    return entry[1]


_PADDED_CODES: dict[int, tuple[OccupancyGrid, np.ndarray]] = {}
#: A loss table for any material code (uint8), all zero: for counting walls only.
_NO_LOSS = np.zeros(256)


def wall_loss_cells(grid: OccupancyGrid, r0: int, c0: int, r1: int, c1: int,
                    loss_by_code: np.ndarray) -> tuple[int, float]:
    """(walls, loss in dB) on the path from cell (r0, c0) to (r1, c1): the walls as
    `count_walls_cells` counts them, each priced by its dearest material (module docstring)."""
    if grid.materials is None:
        walls = _walls_on_line(_padded(grid), r0, c0, r1, c1)
        return walls, walls * float(loss_by_code[0])
    return _wall_loss_on_line(_padded(grid), _padded_codes(grid), loss_by_code, r0, c0, r1, c1)


@numba.njit("Tuple((i8, f8))(b1[:, ::1], u1[:, ::1], f8[::1], i8, i8, i8, i8)", cache=True, nogil=True)
def _wall_loss_on_line(padded, codes, loss_by_code, r0, c0, r1, c1):  # pragma: no cover - compiled
    """As `_walls_on_line`, also summing each wall's dearest loss_by_code[code] over its cells."""
    line = _line(r0, c0, r1, c1)
    walls, loss, run, in_run, _ = _price_cells(padded, codes, loss_by_code, line, 0, line[5], 0, 0.0, 0.0, False,
                                               False)
    return walls, loss + (run if in_run else 0.0)


#: Cells of a segment walked per summed-area look-up by `_wall_loss_skipping`.
SKIP_BLOCK_CELLS = 8


@numba.njit("b1(i8[:, ::1], i8, i8, i8, i8, i8, i8)", cache=True, nogil=True, inline="always")
def _box_free(sat, n_rows, n_cols, ra, ca, rb, cb):  # pragma: no cover - compiled
    """Whether the box of cells spanned by cells (ra, ca) and (rb, cb) (grid indices, clamped onto
    the padded border as the walks clamp them) holds no occupied cell: four summed-area reads."""
    lo_r = min(max(min(ra, rb), -1), n_rows) + 1
    hi_r = min(max(max(ra, rb), -1), n_rows) + 2
    lo_c = min(max(min(ca, cb), -1), n_cols) + 1
    hi_c = min(max(max(ca, cb), -1), n_cols) + 2
    return sat[hi_r, hi_c] - sat[lo_r, hi_c] - sat[hi_r, lo_c] + sat[lo_r, lo_c] == 0


@numba.njit("Tuple((i8, f8))(b1[:, ::1], i8[:, ::1], u1[:, ::1], f8[::1], i8, i8, i8, i8)", cache=True,
            nogil=True)
def _wall_loss_skipping(padded, sat, codes, loss_by_code, r0, c0, r1, c1):  # pragma: no cover - compiled
    """`_wall_loss_on_line`'s (walls, loss), the same numbers, skipping free stretches: a segment
    whose bounding box holds no occupied cell is (0, 0.0) in O(1); otherwise it is walked in blocks
    of SKIP_BLOCK_CELLS cells, and a block whose box (spanned by its first and last cell: Bresenham
    cells are monotone in both axes) is free only closes the wall being crossed, as its first free
    cell would. `sat` is `_occupied_sat` of the grid whose padded occupancy is `padded`."""
    n_rows = padded.shape[0] - 2
    n_cols = padded.shape[1] - 2
    if _box_free(sat, n_rows, n_cols, r0, c0, r1, c1):
        return 0, 0.0
    line = _line(r0, c0, r1, c1)
    n = line[5]
    walls, loss, run, in_run, before = 0, 0.0, 0.0, False, False
    first = 0
    while first <= n:
        last = min(first + SKIP_BLOCK_CELLS - 1, n)
        ra, ca = _line_cell(line, first)
        rb, cb = _line_cell(line, last)
        if _box_free(sat, n_rows, n_cols, ra, ca, rb, cb):
            if in_run:
                loss += run
                in_run = False
            before = False
        else:
            walls, loss, run, in_run, before = _price_cells(padded, codes, loss_by_code, line, first, last, walls,
                                                            loss, run, in_run, before)
        first = last + 1
    return walls, loss + (run if in_run else 0.0)


#: Straight segments each off-centre ray of the Fresnel bundle is drawn with (it follows the zone's
#: elliptical edge through SEGMENTS - 1 points; 8 and 16 give wall losses within 0.1 dB on average).
FRESNEL_SEGMENTS = 8


@numba.njit("Tuple((i8, f8))(b1[:, ::1], i8[:, ::1], u1[:, ::1], f8[::1], f8, f8, f8, f8, f8, f8, f8, f8, f8, "
            "i8)", cache=True, nogil=True)
def _fresnel_wall_loss(padded, sat, codes, loss_by_code, ox, oy, res, ax, ay, bx, by, wavelength, dh,
                       rays):  # pragma: no cover - compiled
    """(walls on the straight line a -> b, wall loss averaged in power over the first Fresnel zone).

    Ray k (of `rays`) runs at the lateral offset s_k r1(t) from the straight line, s_k evenly spaced
    in [-1, 1] and r1(t) = sqrt(wavelength d t (1 - t)) the radius of the first Fresnel zone at the
    fraction t of the path (d: the 3D distance, `dh` the antennas' height difference), drawn as
    FRESNEL_SEGMENTS straight segments; each segment's walls are priced as `_wall_loss_on_line`
    prices them (a wall at a joint counts once: a segment that ends inside it counts it, the next,
    starting inside it, does not). The wall loss is -10 log10 of the mean of 10^(-L_k / 10). The
    off-centre rays are drawn from the end with the lower (column, row), so a pair gives the same
    bundle both ways round; s = 0 is the straight line itself, from `a`.

    Free space costs O(1) (`sat`: `_occupied_sat`, the same numbers): each segment is priced by
    `_wall_loss_skipping`, and when the box around the whole bundle (the ends' box widened by the
    zone's largest radius and one cell for rounding) holds no occupied cell, no ray is walked."""
    r0 = int(math.floor((ay - oy) / res))
    c0 = int(math.floor((ax - ox) / res))
    r1 = int(math.floor((by - oy) / res))
    c1 = int(math.floor((bx - ox) / res))
    walls, central = _wall_loss_skipping(padded, sat, codes, loss_by_code, r0, c0, r1, c1)
    dx = bx - ax
    dy = by - ay
    d2 = math.sqrt(dx * dx + dy * dy)
    if rays <= 1 or d2 == 0.0:
        return walls, central
    if (c1, r1) < (c0, r0):  # canonical direction for the off-centre rays
        ax, ay, bx, by = bx, by, ax, ay
        r0, c0, r1, c1 = r1, c1, r0, c0
        dx, dy = -dx, -dy
    d3 = math.sqrt(dx * dx + dy * dy + dh * dh)
    nx = -dy / d2
    ny = dx / d2
    reach = math.sqrt(wavelength * d3 * 0.25) + res  # every ray's points lie within this of the ends' box
    n_rows = padded.shape[0] - 2
    n_cols = padded.shape[1] - 2
    bundle_free = _box_free(sat, n_rows, n_cols,
                            int(math.floor((min(ay, by) - reach - oy) / res)),
                            int(math.floor((min(ax, bx) - reach - ox) / res)),
                            int(math.floor((max(ay, by) + reach - oy) / res)),
                            int(math.floor((max(ax, bx) + reach - ox) / res)))
    total = 0.0
    for k in range(rays):
        s = -1.0 + 2.0 * k / (rays - 1)
        if 2 * k == rays - 1:
            loss = central
        elif bundle_free:
            loss = 0.0
        else:
            loss = 0.0
            pr = r0
            pc = c0
            for m in range(1, FRESNEL_SEGMENTS + 1):
                if m == FRESNEL_SEGMENTS:
                    r = r1
                    c = c1
                else:
                    t = m / FRESNEL_SEGMENTS
                    off = s * math.sqrt(wavelength * d3 * t * (1.0 - t))
                    r = int(math.floor((ay + dy * t + ny * off - oy) / res))
                    c = int(math.floor((ax + dx * t + nx * off - ox) / res))
                loss += _wall_loss_skipping(padded, sat, codes, loss_by_code, pr, pc, r, c)[1]
                pr = r
                pc = c
        total += 10.0 ** (-loss / 10.0)
    return walls, -10.0 * math.log10(total / rays)


@numba.njit("void(b1[:, ::1], i8[:, ::1], u1[:, ::1], f8[::1], f8, f8, f8, f8, f8, f8[:, ::1], f8, f8, i8, i8[::1], "
            "f8[::1])", cache=True, nogil=True)
def _fresnel_wall_loss_many(padded, sat, codes, loss_by_code, ox, oy, res, ax, ay, points, wavelength, dh, rays,
                            walls_out, loss_out):  # pragma: no cover - compiled
    for i in range(points.shape[0]):
        walls_out[i], loss_out[i] = _fresnel_wall_loss(padded, sat, codes, loss_by_code, ox, oy, res, ax, ay,
                                                       points[i, 0], points[i, 1], wavelength, dh, rays)


def wall_loss_fresnel(grid: OccupancyGrid, a: tuple[float, float], b: tuple[float, float],
                      loss_by_code: np.ndarray, wavelength_m: float, dh_m: float, rays: int) -> tuple[int, float]:
    """(walls on the straight line a -> b, wall loss in dB averaged in power over the first Fresnel
    zone's horizontal width, `rays` rays; module docstring). rays = 1: `wall_loss_cells`'s loss."""
    return _fresnel_wall_loss(_padded(grid), _occupied_sat(grid), _padded_codes(grid),
                              np.asarray(loss_by_code, dtype=float),
                              float(grid.origin_x), float(grid.origin_y), float(grid.resolution),
                              float(a[0]), float(a[1]), float(b[0]), float(b[1]), float(wavelength_m),
                              float(dh_m), int(rays))


def wall_loss_fresnel_many(grid: OccupancyGrid, a: tuple[float, float], points: np.ndarray,
                           loss_by_code: np.ndarray, wavelength_m: float, dh_m: float,
                           rays: int) -> tuple[np.ndarray, np.ndarray]:
    """`wall_loss_fresnel` from `a` to each of `points` (shape (N, 2), m): (walls, loss) arrays."""
    pts = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 2))
    walls = np.zeros(len(pts), dtype=np.int64)
    loss = np.zeros(len(pts))
    _fresnel_wall_loss_many(_padded(grid), _occupied_sat(grid), _padded_codes(grid),
                            np.asarray(loss_by_code, dtype=float),
                            float(grid.origin_x), float(grid.origin_y), float(grid.resolution),
                            float(a[0]), float(a[1]), pts, float(wavelength_m), float(dh_m), int(rays),
                            walls, loss)
    return walls, loss


def count_walls_many(grid: OccupancyGrid, a: tuple[float, float], points: np.ndarray) -> np.ndarray:
    """Walls crossed from `a` to each of `points` (shape (N, 2), m); int array of shape (N,).

    Equal to `count_walls(grid, a, p)` for every p. Shorter lines are padded with their end cell,
    which adds no transition.
    """
    return wall_loss_many(grid, a, points, _NO_LOSS)[0]


def wall_loss_many(grid: OccupancyGrid, a: tuple[float, float], points: np.ndarray,
                   loss_by_code: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(walls, loss in dB) from `a` to each of `points` (shape (N, 2), m), as `wall_loss_cells`."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    out = np.zeros(len(pts), dtype=np.int64)
    loss = np.zeros(len(pts))
    if len(pts) == 0:
        return out, loss
    table = np.asarray(loss_by_code, dtype=float)
    tagged = grid.materials is not None
    r0, c0 = _cell(grid, float(a[0]), float(a[1]))
    r1 = np.floor((pts[:, 1] - grid.origin_y) / grid.resolution).astype(np.int64)
    c1 = np.floor((pts[:, 0] - grid.origin_x) / grid.resolution).astype(np.int64)
    dr, dc = r1 - r0, c1 - c0
    n = np.maximum(np.abs(dr), np.abs(dc))  # steps along the major axis
    order = np.argsort(n, kind="stable")  # chunks of similar length waste little padding
    size = max(1, _CHUNK_CELLS // (int(n.max()) + 1))
    for start in range(0, len(pts), size):
        idx = order[start:start + size]
        ni = n[idx, None]
        i = np.minimum(np.arange(int(ni.max()) + 1)[None, :], ni)  # padded with the end cell
        steps = np.maximum(ni, 1)
        adr, adc = np.abs(dr[idx, None]), np.abs(dc[idx, None])
        sr, sc = np.sign(dr[idx, None]), np.sign(dc[idx, None])
        col_major = adc >= adr
        minor = (2 * i * np.where(col_major, adr, adc) + steps) // (2 * steps)
        rows = r0 + sr * np.where(col_major, minor, i)
        cols = c0 + sc * np.where(col_major, i, minor)
        occ = _occupied_cells(grid, rows, cols)
        entered = occ[:, 1:] & ~occ[:, :-1]
        out[idx] = np.count_nonzero(entered, axis=1)
        if tagged:
            n_rows, n_cols = grid.occupied.shape
            pr = np.minimum(np.maximum(rows[:, 1:], -1), n_rows) + 1
            pc = np.minimum(np.maximum(cols[:, 1:], -1), n_cols) + 1
            # each wall's dearest cell: number the walls along each line, take the max per number
            wall_no = np.cumsum(entered, axis=1)
            cell_loss = np.where(occ[:, 1:] & (wall_no > 0), table[_padded_codes(grid)[pr, pc]], 0.0)
            dearest = np.zeros((len(idx), int(wall_no.max()) + 1))
            np.maximum.at(dearest, (np.repeat(np.arange(len(idx)), wall_no.shape[1]), wall_no.ravel()),
                          cell_loss.ravel())
            loss[idx] = dearest[:, 1:].sum(axis=1)
    if not tagged:
        loss = out * float(table[0])
    return out, loss
