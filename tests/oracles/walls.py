"""Oracle of radio/walls.py's Fresnel kernel: `_fresnel_wall_loss` as it was before it learned to skip
free space with a summed-area table (verbatim but for the names; compiled without a cache, for speed
on the many pairs the tests compare)."""

from __future__ import annotations

import math

import numba

FRESNEL_SEGMENTS = 8


@numba.njit(cache=False)
def wall_loss_on_line(padded, codes, loss_by_code, r0, c0, r1, c1):
    n_rows = padded.shape[0] - 2
    n_cols = padded.shape[1] - 2
    d_r = r1 - r0
    d_c = c1 - c0
    sign_r = (d_r > 0) - (d_r < 0)
    sign_c = (d_c > 0) - (d_c < 0)
    col_major = abs(d_c) >= abs(d_r)
    n = abs(d_c) if col_major else abs(d_r)
    minor_span = abs(d_r) if col_major else abs(d_c)
    steps = max(n, 1)
    walls = 0
    loss = 0.0
    run = 0.0
    in_run = False
    before = False
    for i in range(n + 1):
        minor = (2 * i * minor_span + steps) // (2 * steps)
        if col_major:
            r = r0 + sign_r * minor
            c = c0 + sign_c * i
        else:
            r = r0 + sign_r * i
            c = c0 + sign_c * minor
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
    return walls, loss + (run if in_run else 0.0)


@numba.njit(cache=False)
def fresnel_wall_loss(padded, codes, loss_by_code, ox, oy, res, ax, ay, bx, by, wavelength, dh, rays):
    r0 = int(math.floor((ay - oy) / res))
    c0 = int(math.floor((ax - ox) / res))
    r1 = int(math.floor((by - oy) / res))
    c1 = int(math.floor((bx - ox) / res))
    walls, central = wall_loss_on_line(padded, codes, loss_by_code, r0, c0, r1, c1)
    dx = bx - ax
    dy = by - ay
    d2 = math.sqrt(dx * dx + dy * dy)
    if rays <= 1 or d2 == 0.0:
        return walls, central
    if (c1, r1) < (c0, r0):
        ax, ay, bx, by = bx, by, ax, ay
        r0, c0, r1, c1 = r1, c1, r0, c0
        dx, dy = -dx, -dy
    d3 = math.sqrt(dx * dx + dy * dy + dh * dh)
    nx = -dy / d2
    ny = dx / d2
    total = 0.0
    for k in range(rays):
        s = -1.0 + 2.0 * k / (rays - 1)
        if 2 * k == rays - 1:
            loss = central
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
                loss += wall_loss_on_line(padded, codes, loss_by_code, pr, pc, r, c)[1]
                pr = r
                pc = c
        total += 10.0 ** (-loss / 10.0)
    return walls, -10.0 * math.log10(total / rays)
