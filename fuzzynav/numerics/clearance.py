"""Distances from straight robot moves to point obstacles (laser returns). Lengths in cm."""

from __future__ import annotations

import numpy as np

from fuzzynav.numerics.geometry import segment_point_distance


def segment_point_clearance(start: np.ndarray, ends: np.ndarray, points: np.ndarray) -> np.ndarray:
    """For each move ``start -> ends[i]`` (cm), the smallest distance (cm) from the segment to any of
    ``points`` (P, 2); ``inf`` when there are no points."""
    ends = np.atleast_2d(np.asarray(ends, dtype=float))
    if points is None or len(points) == 0:
        return np.full(len(ends), np.inf)
    start = np.asarray(start, dtype=float)
    return segment_point_distance(start, ends[:, None, :], points).min(axis=1)
