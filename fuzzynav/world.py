"""Static world geometry of a scenario: obstacles and walls as shapely geometry and as numpy arrays.

Lengths in cm. The walls are the edges of ``bounds``; the region outside them counts as an obstacle.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence

import numpy as np
import shapely
from shapely.geometry import box

from fuzzynav.portable_math import dist
from fuzzynav.scenario import StaticObstacle

_FRAME = 1.0e4  # thickness (cm) of the solid frame that stands for "outside the bounds"


class World:
    """Static obstacles and walls (``bounds`` = xmin, ymin, xmax, ymax in cm), prepared for sensing and
    contact checks. Build it from a scenario with ``World(s.bounds, s.static_obstacles)``."""

    def __init__(self, bounds: Sequence[float], static_obstacles: Sequence[StaticObstacle] = ()) -> None:
        xmin, ymin, xmax, ymax = (float(b) for b in bounds)
        self.bounds = (xmin, ymin, xmax, ymax)
        self.area = box(xmin, ymin, xmax, ymax)
        with np.errstate(divide="ignore", invalid="ignore"):  # GEOS on touching degenerate shapes
            self.obstacles = shapely.union_all([o.geometry() for o in static_obstacles]) \
                if static_obstacles else shapely.GeometryCollection()
        frame = box(xmin - _FRAME, ymin - _FRAME, xmax + _FRAME, ymax + _FRAME).difference(self.area)
        #: everything solid: static obstacles plus the frame outside the walls (what the sonar sees)
        self.solid = shapely.union_all([self.obstacles, frame])
        shapely.prepare(self.solid)
        segs = [[xmin, ymin, xmax, ymin], [xmax, ymin, xmax, ymax], [xmax, ymax, xmin, ymax],
                [xmin, ymax, xmin, ymin]]
        circles = []
        for o in static_obstacles:
            if o.circle is not None:
                circles.append([*o.circle.center, o.circle.radius])
            else:
                pts = [*o.polygon, o.polygon[0]]
                segs.extend([[*a, *b] for a, b in itertools.pairwise(pts)])
        #: (M, 4) wall and polygon edges; (C, 3) static circles (exact, for ray casting); read-only, as a world is
        #: shared by the episodes of one scenario (:func:`world_of`)
        self.segments = np.array(segs, dtype=float)
        self.circles = np.array(circles, dtype=float).reshape(-1, 3)
        self.segments.flags.writeable = self.circles.flags.writeable = False

    def static_contact(self, p0: np.ndarray, p1: np.ndarray, radius: float) -> bool:
        """True if a disc of ``radius`` cm moving straight from ``p0`` to ``p1`` touches an obstacle or wall."""
        # shapely's array constructors: the same geometry as Point / LineString, without their Python-level checks
        path = shapely.points(p1) if dist(p0, p1) < 1e-9 else shapely.linestrings(np.array([p0, p1], dtype=float))
        with np.errstate(divide="ignore", invalid="ignore"):
            return bool(shapely.dwithin(self.solid, path, radius - 1e-9))


@functools.lru_cache(maxsize=16)
def _world_of_text(key: str, bounds: tuple[float, ...], static_obstacles: tuple[StaticObstacle, ...]) -> World:
    return World(bounds, static_obstacles)


def world_of(bounds: Sequence[float], static_obstacles: Sequence[StaticObstacle] = ()) -> World:
    """The :class:`World` of ``bounds`` and ``static_obstacles``, built once and shared (building one unions the
    obstacles with GEOS, ~1 ms: a sweep runs one scenario for many seeds). Keyed by the inputs' ``repr``, which
    tells ``0.0`` from ``-0.0`` and ``1`` from ``1.0`` (equal numbers that could still give other bits)."""
    bounds, static_obstacles = tuple(bounds), tuple(static_obstacles)
    return _world_of_text(repr((bounds, static_obstacles)), bounds, static_obstacles)
