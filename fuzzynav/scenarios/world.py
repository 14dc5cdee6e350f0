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

from fuzzynav.numerics.portable_math import dist, hypot, norm2
from fuzzynav.params.limits import MAX_COORD_CM
from fuzzynav.scenarios.scenario import StaticObstacle

_FRAME = 1.0e4  # thickness (cm) of the solid frame that stands for "outside the bounds"
# static_contact answers without GEOS only when its own bound clears the disc by this much (cm): far more than the
# rounding of the bound's few operations on any coordinates a scenario can have, so the answer is GEOS's answer
_CLEAR_CM = 0.01
_MAX_BOUNDING_DISCS = 12  # more obstacles than this: a loop over their discs costs more than GEOS's prepared test
_BOUND_MAX_CM = 10 * MAX_COORD_CM  # larger numbers (a World built directly, not from a scenario): GEOS only


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
        polygons = []
        for o in static_obstacles:
            if o.circle is not None:
                circles.append([*o.circle.center, o.circle.radius])
            else:
                pts = [*o.polygon, o.polygon[0]]
                segs.extend([[*a, *b] for a, b in itertools.pairwise(pts)])
                polygons.append(np.array(o.polygon, dtype=float).reshape(-1, 2))
                polygons[-1].flags.writeable = False
        #: each static polygon's vertices (k, 2) cm as the scenario gives them (either orientation, a closing
        #: repeat of the first vertex kept): the ORCA pedestrians need the edges' order, not just the edges
        self.polygons: tuple[np.ndarray, ...] = tuple(polygons)
        #: (M, 4) wall and polygon edges; (C, 3) static circles (exact, for ray casting); read-only, as a world is
        #: shared by the episodes of one scenario (:func:`world_of`)
        self.segments = np.array(segs, dtype=float)
        self.circles = np.array(circles, dtype=float).reshape(-1, 3)
        self.segments.flags.writeable = self.circles.flags.writeable = False
        #: (x, y, r) cm of a disc around each static obstacle's GEOS geometry (its vertices' bounding box centre and
        #: their largest distance from it: the polygon is inside), for :meth:`static_contact`'s quick "far from
        #: everything"; None when there are too many obstacles for that to pay
        self.bounding_discs: tuple[tuple[float, float, float], ...] | None = None
        parts = shapely.get_parts(self.obstacles)
        if len(parts) <= _MAX_BOUNDING_DISCS:
            discs = []
            for part in parts:
                xy = shapely.get_coordinates(part)
                centre = (xy.min(axis=0) + xy.max(axis=0)) / 2.0
                discs.append((float(centre[0]), float(centre[1]), float(norm2(xy - centre).max())))
            # the bound's rounding stays far below _CLEAR_CM only for numbers of a scenario's size
            if all(abs(v) <= _BOUND_MAX_CM for v in (*self.bounds, *itertools.chain.from_iterable(discs))):
                self.bounding_discs = tuple(discs)

    def _clear_of_everything(self, p0: np.ndarray, p1: np.ndarray, radius: float) -> bool:
        """True when the path from ``p0`` to ``p1`` (cm) is, by a bound computed here, more than ``radius`` +
        ``_CLEAR_CM`` cm from the walls and from every obstacle's bounding disc: then no disc of ``radius`` on it
        touches anything, and GEOS would say so too. False means "ask GEOS" (also for NaN and for paths outside
        the bounds)."""
        if self.bounding_discs is None:
            return False
        x0, y0, x1, y1 = float(p0[0]), float(p0[1]), float(p1[0]), float(p1[1])
        xmin, ymin, xmax, ymax = self.bounds
        limit = radius + _CLEAR_CM
        # the distance to the outside of the (convex) bounds is smallest at an end of the path
        if not min(x0 - xmin, xmax - x0, y0 - ymin, ymax - y0, x1 - xmin, xmax - x1, y1 - ymin, ymax - y1) > limit:
            return False
        dx, dy = x1 - x0, y1 - y0
        length2 = dx * dx + dy * dy
        for cx, cy, r in self.bounding_discs:
            s = 0.0 if not length2 > 0.0 else min(max(((cx - x0) * dx + (cy - y0) * dy) / length2, 0.0), 1.0)
            if not hypot(x0 + s * dx - cx, y0 + s * dy - cy) - r > limit:
                return False
        return True

    def static_contact(self, p0: np.ndarray, p1: np.ndarray, radius: float) -> bool:
        """True if a disc of ``radius`` cm moving straight from ``p0`` to ``p1`` touches an obstacle or wall."""
        if self._clear_of_everything(p0, p1, radius):
            return False
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
