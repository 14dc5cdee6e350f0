"""Moving-obstacle tracking from successive laser frames (not from the simulator's state).

Per frame:

1. **Segmentation.** Beams are taken in angular order; two neighbouring returns whose end points are at
   most ``cluster_gap_cm`` apart belong to one cluster.
2. **Disc fit.** Each cluster of at least ``min_points`` returns is fitted with a circle (Kasa's algebraic
   least squares). Clusters that are not small discs — radius above ``max_radius_cm``, a poor fit (walls,
   polygon corners), or a centre nearer to the robot than the returns — are static structure.
3. **Association.** Detections are matched to the tracks' predicted positions (constant velocity) by the
   Hungarian method (``scipy.optimize.linear_sum_assignment``). A track with a velocity is gated at ``gate_cm``
   around its prediction (what the prediction may miss by: turns, speed changes, fit noise); a track seen in
   one frame only has no velocity yet, so its gate is where an obstacle as fast as ``max_speed_cm_s`` can
   have gone in the time since, ``max_speed_cm_s`` x elapsed (at least ``gate_cm``): at 1 s steps the
   default follows obstacles up to 150 cm/s, a brisk walk, whatever ``dt`` is.
4. **Velocity.** Finite difference of successive fitted centres over the elapsed time, blended with the
   previous estimate by ``velocity_alpha`` (1 = plain finite difference).

A track is reported as a moving obstacle once it has been seen in two frames and its speed is at least
``min_speed_cm_s``; small static obstacles therefore never enter the Trajectory Prediction Table.
Units: cm, s, cm/s; moving angle φ in degrees [0, 360) CCW from +x.

Known limits (documented in the README): an obstacle touching a wall or another obstacle merges with it
into one cluster and is lost while they touch; occlusion hides obstacles behind others.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from fuzzynav.numerics.portable_math import atan2_deg, hypot, norm2
from fuzzynav.sensing.laser import LaserScan


@dataclass(frozen=True)
class Track:
    """A moving obstacle as perceived: position (cm), velocity (cm/s), radius (cm)."""

    id: int
    x: float
    y: float
    vx: float
    vy: float
    radius: float

    @property
    def speed(self) -> float:
        """Speed in cm/s."""
        return hypot(self.vx, self.vy)

    @property
    def moving_angle_deg(self) -> float:
        """Moving angle φ in degrees [0, 360), counter-clockwise from +x."""
        return atan2_deg(self.vy, self.vx) % 360.0


@dataclass(frozen=True)
class TrackerConfig:
    """Parameters of the laser tracker (cm, cm/s)."""

    cluster_gap_cm: float = 15.0
    min_points: int = 3
    max_radius_cm: float = 60.0
    max_fit_rms_cm: float = 3.0
    gate_cm: float = 60.0
    max_speed_cm_s: float = 150.0
    min_speed_cm_s: float = 5.0
    max_missed: int = 2
    velocity_alpha: float = 1.0

    def __post_init__(self) -> None:
        for name in ("cluster_gap_cm", "max_radius_cm", "max_fit_rms_cm", "gate_cm", "max_speed_cm_s"):
            if getattr(self, name) <= 0:
                raise ValueError(f"perception.tracker.{name}: must be > 0, got {getattr(self, name)}")
        if self.min_points < 3:
            raise ValueError(f"perception.tracker.min_points: need at least 3, got {self.min_points}")
        if not 0 < self.velocity_alpha <= 1:
            raise ValueError(f"perception.tracker.velocity_alpha: must be in (0, 1], got {self.velocity_alpha}")


@dataclass(frozen=True)
class _Tracked:
    id: int
    x: float
    y: float
    vx: float
    vy: float
    radius: float
    time: float  # time (s) of the last measurement
    hits: int
    missed: int


def seen_frames(obstacle_id: int, frames: int, time_s: float) -> _Tracked:
    """A ground-truth obstacle's record in :class:`TrackerState` (``perception.mode=ground_truth``): only its
    id and the number of consecutive frames it has been in range (``hits``) are used."""
    return _Tracked(obstacle_id, 0.0, 0.0, 0.0, 0.0, 0.0, time_s, frames, 0)


@dataclass(frozen=True)
class TrackerState:
    """Everything the tracker remembers between frames."""

    tracks: tuple[_Tracked, ...] = ()
    next_id: int = 1


@dataclass(frozen=True)
class Detection:
    """A disc found in one frame: centre (cm), radius (cm), and the beam indices it came from."""

    x: float
    y: float
    radius: float
    beams: np.ndarray


def segment(scan: LaserScan, gap_cm: float) -> list[np.ndarray]:
    """Split the returned beams into clusters of neighbouring returns; each cluster is an index array (beam
    indices in angular order, the clusters starting from the first beam that starts one)."""
    beams, cuts = _clusters(scan, gap_cm)
    return [beams[i:j] for i, j in itertools.pairwise(cuts)]


def _clusters(scan: LaserScan, gap_cm: float) -> tuple[np.ndarray, list[int]]:
    """The clusters of :func:`segment` as one array of beam indices and the positions where each cluster starts
    in it (plus its length at the end): cluster k is ``beams[cuts[k]:cuts[k + 1]]``."""
    n = len(scan.ranges)
    ret = scan.returned
    if not ret.any():
        return np.empty(0, dtype=np.intp), [0]
    pts = scan.xy
    to_next = np.empty_like(pts)  # to the next beam, wrapping around
    np.subtract(pts[1:], pts[:-1], out=to_next[:-1])
    np.subtract(pts[:1], pts[-1:], out=to_next[-1:])
    linked = norm2(to_next) <= gap_cm
    linked &= ret
    linked[:-1] &= ret[1:]
    linked[-1] &= ret[0]
    if linked.all():
        return np.arange(n), [0, n]
    # a cluster starts at each returned beam not linked from its predecessor; list the returned beams from the
    # first start on (wrapping around) and cut that list at every other start
    starts = ret.copy()
    starts[1:] &= ~linked[:-1]
    starts[0] &= ~linked[-1]
    beams = np.flatnonzero(ret)
    k = int(np.searchsorted(beams, int(np.argmax(starts))))
    beams = np.concatenate([beams[k:], beams[:k]])
    return beams, [0, *np.flatnonzero(starts[beams])[1:].tolist(), len(beams)]


def fit_disc(points: np.ndarray) -> tuple[float, float, float, float]:
    """Kasa least-squares circle fit: centre x, y, radius and RMS radial residual (cm).

    Solved in coordinates centred on the points' mean, where Kasa's normal equations reduce to a 2 x 2
    system for the centre offset (a, b): [Suu Suv; Suv Svv] (a, b) = ½ (Suz, Svz) with z = u² + v²; then
    r² = a² + b² + mean(z). Collinear points (no circle) give an infinite radius.

    Computed with Python floats over the few points of a cluster (numpy's per-call overhead would dominate):
    the same IEEE operations elementwise, and correctly rounded sums (math.fsum), never u @ v (BLAS's dot
    product depends on the CPU's kernel)."""
    xs, ys = points[:, 0].tolist(), points[:, 1].tolist()
    n = len(xs)
    mx, my = math.fsum(xs) / n, math.fsum(ys) / n
    u = [x - mx for x in xs]
    v = [y - my for y in ys]
    z = [p * p + q * q for p, q in zip(u, v, strict=True)]
    suu, svv = math.fsum([p * p for p in u]), math.fsum([q * q for q in v])
    suv = math.fsum([p * q for p, q in zip(u, v, strict=True)])
    suz = math.fsum([p * w for p, w in zip(u, z, strict=True)])
    svz = math.fsum([q * w for q, w in zip(v, z, strict=True)])
    det = suu * svv - suv * suv
    if not det > 1e-12 * (suu + svv) * (suu + svv):
        return float(mx), float(my), math.inf, math.inf
    a = (suz * svv - svz * suv) / (2.0 * det)
    b = (svz * suu - suz * suv) / (2.0 * det)
    r = math.sqrt(a * a + b * b + math.fsum(z) / n)
    residual = [math.sqrt((p - a) * (p - a) + (q - b) * (q - b)) - r for p, q in zip(u, v, strict=True)]
    rms = math.sqrt(math.fsum([e * e for e in residual]) / n)
    return float(mx + a), float(my + b), r, rms


def detect(scan: LaserScan, config: TrackerConfig) -> list[Detection]:
    """Disc-shaped clusters of one laser frame (world coordinates)."""
    beams, cuts = _clusters(scan, config.cluster_gap_cm)
    if len(beams) == 0:
        return []
    # every cluster's extent (cm, the diagonal of its bounding box) and nearest range at once: exact minima and
    # maxima, so the same numbers as cluster by cluster
    pts = scan.xy[beams]
    first = np.array(cuts[:-1])
    extent = norm2(np.maximum.reduceat(pts, first, axis=0) - np.minimum.reduceat(pts, first, axis=0))
    nearest = np.minimum.reduceat(scan.ranges[beams], first).tolist()
    small = (np.diff(cuts) >= config.min_points) & (extent <= 2.0 * config.max_radius_cm)
    ox, oy = scan.origin
    out = []
    for k in np.flatnonzero(small).tolist():
        i, j = cuts[k], cuts[k + 1]
        cx, cy, radius, rms = fit_disc(pts[i:j])
        if radius > config.max_radius_cm or rms > config.max_fit_rms_cm:
            continue
        if hypot(cx - ox, cy - oy) <= nearest[k]:  # concave side towards us: not a disc
            continue
        out.append(Detection(cx, cy, radius, beams[i:j]))
    return out


def associate(cost: np.ndarray, inside: np.ndarray) -> dict[int, int]:
    """The detection -> track pairs of the minimum-cost assignment of tracks (rows) to detections (columns) over
    the pairs ``inside`` the gate: as many gated pairs as possible, then the least total ``cost`` (cm).

    Where no track and no detection has two gated partners (one person in sight, people far apart) the gated
    pairs are the assignment itself, taken without the Hungarian method; otherwise
    ``scipy.optimize.linear_sum_assignment`` on the cost with 1e9 outside the gate (a pair outside it is never
    kept). Same pairs either way: the gated pairs are disjoint, so every assignment with fewer of them costs 1e9
    more. The fast case spares a run's first frames scipy.optimize's import (~0.25 s) and most steps its call."""
    if (inside.sum(axis=0) <= 1).all() and (inside.sum(axis=1) <= 1).all():
        rows, cols = np.nonzero(inside)
        return {int(c): int(r) for r, c in zip(rows, cols, strict=True)}
    # imported here: scipy.optimize takes ~0.25 s to import, which every process importing fuzzynav (a sweep's
    # launching process, the analysis' tests, a single run's start-up) would otherwise pay
    from scipy.optimize import linear_sum_assignment

    rows, cols = linear_sum_assignment(np.where(inside, cost, 1e9))
    return {int(c): int(r) for r, c in zip(rows, cols, strict=True) if inside[r, c]}


def update(state: TrackerState, scan: LaserScan, time_s: float,
           config: TrackerConfig) -> tuple[TrackerState, list[Track], np.ndarray]:
    """Advance the tracker by one frame taken at ``time_s`` seconds.

    Returns the new state, the moving obstacles (confirmed tracks at least ``min_speed_cm_s`` fast, seen
    in this frame), and a boolean mask over the beams that belong to those moving obstacles."""
    dets = detect(scan, config)
    prev = state.tracks
    matched: dict[int, int] = {}
    if prev and dets:
        cost = np.empty((len(prev), len(dets)))
        gate = np.empty((len(prev), 1))
        for i, t in enumerate(prev):
            dt = time_s - t.time
            px, py = t.x + t.vx * dt, t.y + t.vy * dt
            gate[i, 0] = config.gate_cm if t.hits >= 2 else max(config.gate_cm, config.max_speed_cm_s * dt)
            for j, d in enumerate(dets):
                cost[i, j] = hypot(d.x - px, d.y - py)
        matched = associate(cost, cost <= gate)
    tracks: list[_Tracked] = []
    next_id = state.next_id
    used = set(matched.values())
    moving_mask = np.zeros(len(scan.ranges), dtype=bool)
    reported: list[Track] = []
    for j, d in enumerate(dets):
        if j in matched:
            t = prev[matched[j]]
            dt = time_s - t.time
            vx_m, vy_m = (d.x - t.x) / dt, (d.y - t.y) / dt
            al = config.velocity_alpha if t.hits >= 2 else 1.0
            new = _Tracked(t.id, d.x, d.y, al * vx_m + (1 - al) * t.vx, al * vy_m + (1 - al) * t.vy,
                           d.radius, time_s, t.hits + 1, 0)
        else:
            new = _Tracked(next_id, d.x, d.y, 0.0, 0.0, d.radius, time_s, 1, 0)
            next_id += 1
        tracks.append(new)
        if new.hits >= 2 and hypot(new.vx, new.vy) >= config.min_speed_cm_s:
            reported.append(Track(new.id, new.x, new.y, new.vx, new.vy, new.radius))
            moving_mask[d.beams] = True
    for i, t in enumerate(prev):
        if i not in used and t.missed < config.max_missed:
            tracks.append(_Tracked(t.id, t.x, t.y, t.vx, t.vy, t.radius, t.time, t.hits, t.missed + 1))
    return TrackerState(tuple(tracks), next_id), reported, moving_mask
