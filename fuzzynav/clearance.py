"""Distances from straight robot moves to point obstacles (laser returns). Lengths in cm."""

from __future__ import annotations

import numpy as np

from fuzzynav.portable_math import dot2, norm2


def segment_point_clearance(start: np.ndarray, ends: np.ndarray, points: np.ndarray) -> np.ndarray:
    """For each move ``start -> ends[i]`` (cm), the smallest distance (cm) from the segment to any of
    ``points`` (P, 2); ``inf`` when there are no points."""
    ends = np.atleast_2d(np.asarray(ends, dtype=float))
    if points is None or len(points) == 0:
        return np.full(len(ends), np.inf)
    start = np.asarray(start, dtype=float)
    seg = ends - start[None, :]  # (S, 2)
    rel = points[None, :, :] - start[None, None, :]  # (1, P, 2)
    ll = dot2(seg, seg)[:, None]
    s = np.clip(dot2(rel, seg[:, None, :]) / np.where(ll > 0, ll, 1.0), 0.0, 1.0)
    return norm2(rel - s[..., None] * seg[:, None, :]).min(axis=1)
