"""Vectorised ray casting against line segments and circles (numpy, no per-ray Python loop).

Lengths in cm; rays are given by unit direction vectors in the world frame. Every distance is computed
elementwise (one ray against one segment or circle at a time, always with the same operations), and the
nearest hit per ray is a plain minimum, so the result does not depend on the CPU or on which other segments
and circles are in the world.
"""

from __future__ import annotations

import numpy as np

from fuzzynav.numerics.geometry import segment_point_distance
from fuzzynav.numerics.portable_math import norm2


def cast_rays(origin: np.ndarray, directions: np.ndarray, segments: np.ndarray, circles: np.ndarray,
              max_range: float) -> tuple[np.ndarray, np.ndarray]:
    """Distance from ``origin`` along each ray (``directions``: (N, 2) unit vectors) to the first segment
    or circle, capped at ``max_range``.

    ``segments`` is (M, 4) rows ``x1, y1, x2, y2``; ``circles`` is (C, 3) rows ``cx, cy, r``. Returns the
    ranges (N,) and the index of what was hit (N,): ``-1`` nothing, ``0..M-1`` a segment, ``M..M+C-1`` a
    circle. A ray starting inside a circle has range 0. Segments and circles entirely beyond ``max_range``
    are dropped before casting (they cannot be hit), which keeps large worlds cheap. On equal distances the
    lower index wins (segments before circles).
    """
    d = np.asarray(directions, dtype=float).reshape(-1, 2)
    n = len(d)
    ox, oy = float(origin[0]), float(origin[1])
    segments, circles = segments.reshape(-1, 4), circles.reshape(-1, 3)
    reach = cull_reach(max_range)
    seg_gaps = segment_point_distance(segments[:, :2], segments[:, 2:], np.array([ox, oy]))
    seg_ids = np.flatnonzero(seg_gaps <= reach)
    circ_ids = np.flatnonzero(norm2(circles[:, :2] - (ox, oy)) - circles[:, 2] <= reach)
    best = np.full(n, float(max_range))
    hit = np.full(n, -1, dtype=np.int64)
    if not len(seg_ids) and not len(circ_ids):
        return best, hit
    _nearest(ox, oy, d, segments[seg_ids].astype(float), seg_ids, circles[circ_ids].astype(float),
             len(segments) + circ_ids, best, hit)
    return best, hit


def cull_reach(max_range: float) -> float:
    """How far (cm) an object may be and still be cast against: a hair beyond the range (culling must never drop
    a hit at the range)."""
    return max_range * (1.0 + 1e-9) + 1e-9


def _nearest(ox: float, oy: float, directions: np.ndarray, segments: np.ndarray, segment_ids: np.ndarray,
             circles: np.ndarray, circle_ids: np.ndarray, best: np.ndarray, hit: np.ndarray) -> None:
    """Lower ``best`` (N,) to each ray's first nearest segment, then circle, strictly nearer, and set ``hit`` to
    its id there (in place). ``directions`` (N, 2) unit vectors from (ox, oy) cm; ``segments`` (M, 4) and
    ``circles`` (C, 3) the ones kept after culling, with their ``segment_ids`` and ``circle_ids``."""
    dx, dy = directions[:, :1], directions[:, 1:]  # (N, 1) columns, broadcast against the (M,) or (C,) rows
    if len(segments):
        _keep_nearest(_segment_distances(dx, dy, segments, ox, oy), segment_ids, best, hit)
    if len(circles):
        _keep_nearest(_circle_distances(dx, dy, circles, ox, oy), circle_ids, best, hit)


def _segment_distances(dx: np.ndarray, dy: np.ndarray, segments: np.ndarray, ox: float, oy: float) -> np.ndarray:
    """(N, M) distance (cm) along each ray (direction columns ``dx``, ``dy``) from (ox, oy) to each segment;
    ``inf`` where the ray misses it or runs parallel to it."""
    ax = segments[:, 0] - ox
    ay = segments[:, 1] - oy
    ex = segments[:, 2] - segments[:, 0]
    ey = segments[:, 3] - segments[:, 1]
    denom = dx * ey - dy * ex  # cross(d, e)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # masked below (|denom| <= 1e-12)
        t = (ax * ey - ay * ex) / denom
        u = (ax * dy - ay * dx) / denom
    miss = np.abs(denom) <= 1e-12
    miss |= ~(t >= 0.0)  # also NaN
    miss |= ~(u >= 0.0)
    miss |= ~(u <= 1.0)
    t[miss] = np.inf
    return t


def _circle_distances(dx: np.ndarray, dy: np.ndarray, circles: np.ndarray, ox: float, oy: float) -> np.ndarray:
    """(N, C) distance (cm) along each ray from (ox, oy) to each circle's rim; 0 for every ray when the
    origin is inside the circle, ``inf`` where the ray misses it."""
    cx = circles[:, 0] - ox
    cy = circles[:, 1] - oy
    r2 = circles[:, 2] * circles[:, 2]
    b = dx * cx + dy * cy  # projection of the centre on the ray
    c = cx * cx + cy * cy - r2
    disc = b * b - c
    with np.errstate(invalid="ignore"):  # a negative discriminant: a miss, masked below
        t = b - np.sqrt(disc)
    t[~((disc >= 0.0) & (t >= 0.0))] = np.inf
    t[:, c <= 0.0] = 0.0  # the origin is inside: range 0 for every ray
    return t


def _keep_nearest(t: np.ndarray, ids: np.ndarray, best: np.ndarray, hit: np.ndarray) -> None:
    """Lower ``best`` (N,) to each row's minimum of ``t`` (N, K) where it is strictly nearer, and set ``hit`` there
    to the ``ids`` (K,) of the first column holding that minimum (in place)."""
    j = np.argmin(t, axis=1)
    tj = t[np.arange(len(t)), j]
    closer = tj < best
    best[closer] = tj[closer]
    hit[closer] = ids[j[closer]]
