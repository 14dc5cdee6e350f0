"""Vectorised ray casting against line segments and circles (numpy, no per-ray Python loop).

Lengths in cm; rays are given by unit direction vectors in the world frame.
"""

from __future__ import annotations

import numpy as np

from fuzzynav.geometry import segment_point_distance
from fuzzynav.portable_math import norm2


def cast_rays(origin: np.ndarray, directions: np.ndarray, segments: np.ndarray, circles: np.ndarray,
              max_range: float) -> tuple[np.ndarray, np.ndarray]:
    """Distance from ``origin`` along each ray (``directions``: (N, 2) unit vectors) to the first segment
    or circle, capped at ``max_range``.

    ``segments`` is (M, 4) rows ``x1, y1, x2, y2``; ``circles`` is (C, 3) rows ``cx, cy, r``. Returns the
    ranges (N,) and the index of what was hit (N,): ``-1`` nothing, ``0..M-1`` a segment, ``M..M+C-1`` a
    circle. A ray starting inside a circle has range 0. Segments and circles entirely beyond ``max_range``
    are dropped before casting (they cannot be hit), which keeps large worlds cheap.
    """
    d = np.asarray(directions, dtype=float).reshape(-1, 2)
    n = len(d)
    best = np.full(n, float(max_range))
    hit = np.full(n, -1, dtype=np.intp)
    ox, oy = float(origin[0]), float(origin[1])
    segments, circles = segments.reshape(-1, 4), circles.reshape(-1, 3)
    reach = max_range * (1.0 + 1e-9) + 1e-9  # a hair of slack: culling must never drop a hit at the range
    seg_gaps = segment_point_distance(segments[:, :2], segments[:, 2:], np.array([ox, oy]))
    seg_ids = np.nonzero(seg_gaps <= reach)[0]
    circ_ids = np.nonzero(norm2(circles[:, :2] - (ox, oy)) - circles[:, 2] <= reach)[0]
    all_segments = len(segments)
    segments, circles = segments[seg_ids], circles[circ_ids]
    if len(segments):
        ax = segments[:, 0] - ox
        ay = segments[:, 1] - oy
        ex = segments[:, 2] - segments[:, 0]
        ey = segments[:, 3] - segments[:, 1]
        denom = d[:, :1] * ey[None, :] - d[:, 1:] * ex[None, :]  # cross(d, e)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # masked below (|denom| <= 1e-12)
            t = (ax[None, :] * ey[None, :] - ay[None, :] * ex[None, :]) / denom
            u = (ax[None, :] * d[:, 1:] - ay[None, :] * d[:, :1]) / denom
        ok = (np.abs(denom) > 1e-12) & (t >= 0.0) & (u >= 0.0) & (u <= 1.0)
        t = np.where(ok, t, np.inf)
        j = np.argmin(t, axis=1)
        tj = t[np.arange(n), j]
        closer = tj < best
        best = np.where(closer, tj, best)
        hit = np.where(closer, seg_ids[j], hit)
    if len(circles):
        cx = circles[:, 0] - ox
        cy = circles[:, 1] - oy
        r2 = circles[:, 2] * circles[:, 2]
        b = d[:, :1] * cx[None, :] + d[:, 1:] * cy[None, :]  # projection of centre on the ray
        c = (cx * cx + cy * cy - r2)[None, :]
        disc = b * b - c
        with np.errstate(invalid="ignore"):
            t = b - np.sqrt(disc)
        inside = np.broadcast_to(c <= 0.0, t.shape)
        t = np.where(inside, 0.0, np.where((disc >= 0.0) & (t >= 0.0), t, np.inf))
        j = np.argmin(t, axis=1)
        tj = t[np.arange(n), j]
        closer = tj < best
        best = np.where(closer, tj, best)
        hit = np.where(closer, all_segments + circ_ids[j], hit)
    return best, hit
