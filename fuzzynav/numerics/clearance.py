"""Distances from straight robot moves to point obstacles (laser returns). Lengths in cm."""

from __future__ import annotations

import numpy as np

from fuzzynav.numerics import compiled
from fuzzynav.numerics.geometry import segment_point_distance

_kernel = compiled.load("fuzzynav.numerics._closest_approach")


def segment_point_clearance(start: np.ndarray, ends: np.ndarray, points: np.ndarray) -> np.ndarray:
    """For each move ``start -> ends[i]`` (cm), the smallest distance (cm) from the segment to any of
    ``points`` (P, 2); ``inf`` when there are no points."""
    ends = np.atleast_2d(np.asarray(ends, dtype=float))
    if points is None or len(points) == 0:
        return np.full(len(ends), np.inf)
    start = np.asarray(start, dtype=float)
    if (_kernel is not None and type(points) is np.ndarray and points.dtype == np.float64 and points.ndim == 2
            and points.shape[1] == 2 and start.shape == (2,) and ends.ndim == 2 and ends.shape[1] == 2
            and not compiled.switched_off()):
        # the same numbers without the (moves, points, 2) arrays (the planner scores ~60 moves against ~360
        # returns): each distance the numpy form's bits, the minimum exact
        out = np.empty(len(ends))
        _kernel.segment_point_clearance(*(a if a.flags.c_contiguous and a.flags.aligned else a.copy()
                                          for a in (start, ends, points)), out)
        return out
    return segment_point_distance(start, ends[:, None, :], points).min(axis=1)
