"""Sonar: distance from the robot's surface to the nearest obstacle in the Left, Front and Right sectors.

Sector angles are degrees relative to the heading (positive = to the left); distances in cm. Each sector
is a wedge with its apex at the robot centre and radius ``robot radius + range``; the reading is the
distance from the robot's surface to the nearest point of an obstacle or wall inside the wedge, clipped
to [0, range], and ``range`` when the wedge is empty. The world is first clipped to the square around
the robot that holds the three wedges (a cheap rectangle clip), then intersected with the wedges in one
vectorised shapely call.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import shapely

from fuzzynav.numerics.portable_math import sin_cos_deg, sin_cos_deg_array

SECTOR_NAMES = ("left", "front", "right")


#: what the sonar sees besides the static map (:attr:`SonarConfig.sees`)
SEES = ("stationary", "all", "static_map")


@dataclass(frozen=True)
class SonarConfig:
    """Sectors (degrees relative to the heading), range (cm), arc sampling step (degrees), and what it sees.

    ``sees``: ``stationary`` (default) — the paper's division of labour, "the sonar sensors detect the
    stationary obstacles" and the laser the moving ones: the static map plus every moving obstacle slower than
    ``stationary_below_cm_s`` (a person standing still, or one that stopped; the default equals the tracker's
    ``min_speed_cm_s``, below which the laser reports no moving obstacle, so that nothing is seen by neither);
    ``all`` — a physical sonar, which echoes off people walking too; ``static_map`` — the static obstacles and
    walls only (a person standing in the path is then invisible to the fuzzy controller)."""

    left: tuple[float, float] = (30.0, 90.0)
    front: tuple[float, float] = (-30.0, 30.0)
    right: tuple[float, float] = (-90.0, -30.0)
    range_cm: float = 130.0
    arc_step_deg: float = 2.0
    sees: str = "stationary"
    stationary_below_cm_s: float = 5.0

    def __post_init__(self) -> None:
        for name in SECTOR_NAMES:
            lo, hi = getattr(self, name)
            if not lo < hi or hi - lo > 360:
                raise ValueError(f"sensors.sonar.{name}: need lo < hi (degrees), got [{lo}, {hi}]")
        if self.range_cm <= 0:
            raise ValueError(f"sensors.sonar.range_cm: must be > 0, got {self.range_cm}")
        if not 0 < self.arc_step_deg <= 30:
            raise ValueError(f"sensors.sonar.arc_step_deg: must be in (0, 30], got {self.arc_step_deg}")
        if self.sees not in SEES:
            raise ValueError(f"sensors.sonar.sees: unknown value {self.sees!r} (known: {', '.join(SEES)})")


class Sonar:
    """Sonar model for one robot radius; :meth:`read` returns (left, front, right) in cm."""

    def __init__(self, config: SonarConfig, robot_radius: float) -> None:
        self.config = config
        self.robot_radius = robot_radius
        reach = robot_radius + config.range_cm
        self._reach = reach
        self._templates, self._stacked = _wedge_templates(config, reach)

    def wedges(self, x: float, y: float, heading_deg: float) -> np.ndarray:
        """The three sector wedges (shapely polygons, world frame, cm) of a robot at (x, y) with ``heading_deg``."""
        s, c = sin_cos_deg(heading_deg)
        # rotate the templates by the heading elementwise (a matrix product would go through BLAS); the same
        # operations in the same order either way, so the stacked and the per-sector paths give the same bits
        if self._stacked is not None:
            tx, ty = self._stacked
            coords = np.empty((*tx.shape, 2))
            coords[..., 0] = tx * c - ty * s + x
            coords[..., 1] = tx * s + ty * c + y
            return shapely.polygons(coords)
        # sectors of different widths: one polygon at a time (their outlines have different lengths)
        return np.array([shapely.polygons(np.stack([t[:, 0] * c - t[:, 1] * s + x, t[:, 0] * s + t[:, 1] * c + y],
                                                   axis=1)) for t in self._templates], dtype=object)

    def seen_discs(self, discs: np.ndarray | None, speeds: np.ndarray | None) -> np.ndarray | None:
        """The rows of ``discs`` (K, 3: x, y, r in cm) this sonar sees, given the obstacles' ``speeds`` (K,) in
        cm/s (:attr:`SonarConfig.sees`); None when it sees none of them."""
        if discs is None or not len(discs) or self.config.sees == "static_map":
            return None
        if self.config.sees == "stationary":
            if speeds is None:
                raise ValueError("Sonar.read: sees 'stationary' needs the moving obstacles' speeds")
            discs = discs[np.asarray(speeds, dtype=float) < self.config.stationary_below_cm_s]
        return discs if len(discs) else None

    def read(self, x: float, y: float, heading_deg: float, solid: shapely.Geometry,
             discs: np.ndarray | None = None, speeds: np.ndarray | None = None) -> tuple[float, float, float]:
        """Readings (left, front, right) in cm for a robot at (x, y) cm with ``heading_deg``.

        ``solid`` is the static world (obstacles + walls); ``discs`` (K, 3) rows ``x, y, r`` are the moving
        obstacles and ``speeds`` (K,) their speeds in cm/s, of which the sonar sees those :meth:`seen_discs`
        says."""
        wedges = self.wedges(x, y, heading_deg)
        reach = self._reach
        seen = self.seen_discs(discs, speeds)
        with np.errstate(divide="ignore", invalid="ignore"):  # GEOS on degenerate slivers; NaN is handled below
            target = shapely.clip_by_rect(solid, x - reach, y - reach, x + reach, y + reach)
            if seen is not None:
                target = shapely.union_all([target, *shapely.buffer(shapely.points(seen[:, :2]), seen[:, 2])])
            hits = shapely.intersection(wedges, target)
            dist = shapely.distance(hits, shapely.points((x, y)))  # NaN for an empty intersection
        left, front, right = (self._reading(d) for d in dist.tolist())
        return left, front, right

    def _reading(self, distance: float) -> float:
        """A sector's reading (cm) from the distance (cm) of the robot centre to what is in its wedge (NaN: nothing):
        the gap to the robot's surface, clipped to [0, range]."""
        if math.isnan(distance):
            return float(self.config.range_cm)
        return float(min(max(distance - self.robot_radius, 0.0), self.config.range_cm))


@functools.lru_cache(maxsize=16)
def _wedge_templates(config: SonarConfig, reach: float) -> tuple[tuple[np.ndarray, ...],
                                                                  tuple[np.ndarray, np.ndarray] | None]:
    """The wedge of each sector in the robot frame (apex at the origin, heading along +x, radius ``reach`` cm),
    made once per configuration and shared read-only by every episode's sonar. Sectors of one width (the usual
    case) have templates of one length, also given stacked as (3, K) x and y rows: all three wedges are then
    rotated by one set of array operations per frame."""
    templates = []
    for name in SECTOR_NAMES:
        lo, hi = getattr(config, name)
        n = max(2, math.ceil((hi - lo) / config.arc_step_deg) + 1)
        sin, cos = sin_cos_deg_array(np.linspace(lo, hi, n))
        arc = np.stack([cos, sin], axis=1) * reach
        templates.append(np.vstack([[0.0, 0.0], arc, [0.0, 0.0]]))
    stacked = None
    if len({len(t) for t in templates}) == 1:
        stacked = (np.stack([t[:, 0] for t in templates]), np.stack([t[:, 1] for t in templates]))
    for array in (*templates, *(stacked or ())):
        array.flags.writeable = False
    return tuple(templates), stacked
