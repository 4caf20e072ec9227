"""The polyline geometry of rescuemesh.nav.path.Polyline over whole numpy arrays: the reference
its per-tick, plain-Python answers are checked against."""

from __future__ import annotations

import numpy as np

from rescuemesh.nav.path import cumulative_lengths


def project(points: np.ndarray, xy: np.ndarray, *, s_min: float = 0.0, s_max: float = np.inf) -> tuple[float, float]:
    """Project `xy` onto the polyline: (arc length s in m of the nearest point, distance in m to it).

    Only segments overlapping the arc-length window [s_min, s_max] are searched, so a path that
    passes near itself twice is not short-cut (Nav2's `max_robot_pose_search_dist`).
    """
    xy = np.asarray(xy, dtype=float)
    if len(points) == 1:
        return 0.0, float(np.hypot(*(xy - points[0])))
    cum = cumulative_lengths(points)
    a, b = points[:-1], points[1:]
    d = b - a
    seg_len2 = np.einsum("ij,ij->i", d, d)
    t = np.einsum("ij,ij->i", xy - a, d) / np.where(seg_len2 > 0.0, seg_len2, 1.0)
    t = np.clip(t, 0.0, 1.0)
    s_seg = cum[:-1] + t * np.sqrt(seg_len2)
    lo, hi = s_min, max(s_min, s_max)
    # restrict to the window, clamping each segment's candidate into it
    s_cand = np.clip(s_seg, np.maximum(cum[:-1], lo), np.minimum(cum[1:], hi))
    usable = cum[1:] >= lo
    usable &= cum[:-1] <= hi
    if not usable.any():
        usable[-1] = True
    near = point_at(points, s_cand, cum=cum)
    dist = np.hypot(*(near - xy).T)
    dist = np.where(usable, dist, np.inf)
    i = int(np.argmin(dist))
    return float(s_cand[i]), float(dist[i])


def point_at(points: np.ndarray, s, *, cum: np.ndarray | None = None) -> np.ndarray:
    """Point(s) (x, y) in m at arc length(s) `s` along the polyline, clamped to its ends."""
    cum = cumulative_lengths(points) if cum is None else cum
    s_arr = np.clip(np.asarray(s, dtype=float), 0.0, cum[-1])
    x = np.interp(s_arr, cum, points[:, 0])
    y = np.interp(s_arr, cum, points[:, 1])
    return np.stack([x, y], axis=-1)


def slice_path(points: np.ndarray, s_start: float = 0.0, s_end: float = np.inf) -> np.ndarray:
    """The part of the polyline between arc lengths `s_start` and `s_end` in m, as an (M, 2) array, M >= 1."""
    cum = cumulative_lengths(points)
    s0 = float(np.clip(s_start, 0.0, cum[-1]))
    s1 = float(np.clip(s_end, s0, cum[-1]))
    inner = points[(cum > s0) & (cum < s1)]
    ends = point_at(points, [s0, s1], cum=cum)
    out = np.vstack([ends[:1], inner, ends[1:]])
    if len(out) == 2 and s1 - s0 <= 1e-9:
        out = out[:1]
    return out
