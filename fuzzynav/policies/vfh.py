"""``vfh``: vector field histogram (Borenstein & Koren 1991, "The vector field histogram — fast obstacle
avoidance for mobile robots", IEEE Trans. Robotics and Automation 7(3)), with the obstacle enlargement of VFH+
(Ulrich & Borenstein 1998, "VFH+: reliable obstacle avoidance for fast mobile robots", ICRA).

Each step, from scratch (nothing is remembered between steps):

1. **Histogram grid.** The static laser returns, and points every ``perimeter_spacing_cm`` around each
   perceived moving obstacle's disc (at its present position: VFH has no notion of motion), are binned into
   world-fixed square cells of ``cell_cm``. Every occupied cell has certainty ``c = 1``: the paper's
   certainty counts repeated sonar hits over time, whereas here each step's grid is built from one scan of
   a laser whose returns are taken as reliable.
2. **Polar histogram** of ``n = 360/α`` sectors (sector k covers absolute directions [kα, (k+1)α)). A cell
   at distance ``d < window_cm`` from the robot's centre, in direction β, has magnitude
   ``m = c²·(a − b·d)`` with ``a = b·window_cm``, so that ``m`` falls to 0 at the window's edge (the paper
   chooses a, b so that ``a − b·d_max = 0``). VFH+ enlargement: the cell counts in every sector that meets
   [β − γ, β + γ], ``γ = asin(r/d)`` with ``r = robot radius + safety_cm`` (γ = 90° for d ≤ r), so the
   robot may be treated as a point. ``h_k`` is the sum of the magnitudes counted in sector k.
3. **Smoothing** (the paper's eq. 5), circular over the sectors::

       h'_k = (h_{k−l+1} + 2·h_{k−l+2} + … + l·h_k + … + 2·h_{k+l−2} + h_{k+l−1}) / (2l + 1)

   (as published: the weights sum to l², not to 2l + 1; the threshold below is on this scale).
4. **Valleys**: runs of consecutive sectors with ``h' < threshold``. The valley nearest to the target
   sector (containing it, else the fewest sectors from it to a border; a tie goes to the counter-clockwise
   valley) is selected. In a **wide** valley (more than ``s_max`` sectors) the robot steers ``s_max/2``
   sectors from the border nearest to the target (the paper's ``(k_n + k_f)/2`` with
   ``k_f = k_n ± s_max``), which keeps it off the obstacle it is passing; when the target lies in the wide
   valley at least ``s_max/2`` sectors from both borders, nothing is in the way and it steers straight at
   the target (as VFH+'s candidate directions do; the 1991 paper is silent on this case). In a **narrow**
   valley it steers at the valley's centre. With no sector above the threshold it steers at the target; with
   no valley at all it stands still (mode ``vfh_stop``).
5. **Speed** (the paper's speed reduction): ``h''_c = min(h'_c, h_m)`` at the sector of the current heading,
   ``V = v_max·(1 − h''_c/h_m)``, kept within [v_min, v_max] and at most what lands on the goal in one step.

Units: cm, s, degrees, cm/s. Portable numerics: elementwise numpy, strictly sequential sums (no BLAS).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from fuzzynav.numerics.geometry import angle_difference_deg, wrap_360
from fuzzynav.numerics.portable_math import atan2_deg_array, bearing_deg, dist, norm2, sequential_sum, sin_cos_deg_array
from fuzzynav.params.limits import WHY_MARGIN, WHY_REACH, Range, ranged
from fuzzynav.params.parsing import from_dict
from fuzzynav.policies.base import Action, Observation, PolicyContext, register_policy
from fuzzynav.sensing.tracking import Track


@dataclass(frozen=True)
class VfhConfig:
    """Parameters of the histogram, the valley choice and the speed (see the module docstring)."""

    # α (degrees): paper, 5° (72 sectors)
    sector_deg: float = ranged(5.0,
                               Range(0.5, 45, "deg", "VFH: α; 8 to 720 sectors (the histogram is sectors x cells)"))
    # histogram-grid cell (cm): paper, 10 cm
    cell_cm: float = ranged(10.0, Range(1, 1_000, "cm", "VFH: histogram-grid cell"))
    # radius (cm) of the active window: the paper's window is 33 x 33 cells of 10 cm; this is the circle of
    # its half-width, 160 cm, so that every direction sees equally far (within the 250 cm laser range)
    window_cm: float = ranged(160.0, Range(0, 10_000, "cm", "VFH: active window, " + WHY_REACH, lo_open=True))
    # b (magnitude per cm): chosen 1, so a magnitude reads as cm inside the window; a = b·window_cm
    b: float = ranged(1.0, Range(0, 1e6, "1/cm", "VFH: magnitude per cm", lo_open=True))
    # l, the smoothing window: paper, 5
    smoothing_l: int = ranged(5, Range(1, 180, "sectors", "VFH: l, at most half the sectors", integer=True))
    # threshold on h': chosen 100, so that a single occupied cell blocks directions from about 110 cm away
    # (and about its whole enlarged width, 60°, at 60 cm) and a wall across the path from about 150 cm
    threshold: float = ranged(100.0, Range(0, 1e12, "", "VFH: threshold on h'", lo_open=True))
    # s_max (sectors), the widest "narrow" valley: paper, 18
    wide_valley_sectors: int = ranged(18, Range(1, 359, "sectors", "VFH: s_max", integer=True))
    # h_m, the density that brings the speed to 0 before clamping: chosen 2·threshold, half speed when the
    # heading's sector is at the threshold
    h_m: float = ranged(200.0, Range(0, 1e12, "", "VFH: density that stops the robot", lo_open=True))
    # d_s (cm), VFH+'s safety distance added to the robot radius: chosen 10 cm, a quarter step at v_max
    safety_cm: float = ranged(10.0, Range(0, 1_000, "cm", "VFH: d_s, " + WHY_MARGIN))
    # spacing (cm) of the points sampled around a moving obstacle: chosen one cell, so every cell the
    # perimeter crosses is occupied
    perimeter_spacing_cm: float = ranged(10.0, Range(1, 1_000, "cm", "VFH: points around a moving obstacle"))

    def __post_init__(self) -> None:
        positive = ("sector_deg", "cell_cm", "window_cm", "b", "threshold", "h_m", "perimeter_spacing_cm")
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"navigator.{name}: must be a finite number > 0, got {value}")
        if not (math.isfinite(self.safety_cm) and self.safety_cm >= 0):
            raise ValueError(f"navigator.safety_cm: must be a finite number >= 0, got {self.safety_cm}")
        n = 360.0 / self.sector_deg
        if n != round(n) or n < 8:
            raise ValueError(f"navigator.sector_deg: must divide 360 into at least 8 sectors, got {self.sector_deg}")
        if not 1 <= self.smoothing_l <= n // 2:
            raise ValueError(f"navigator.smoothing_l: must be in [1, {int(n // 2)}], got {self.smoothing_l}")
        if not 1 <= self.wide_valley_sectors < n:
            raise ValueError(f"navigator.wide_valley_sectors: must be in [1, {int(n) - 1}], "
                             f"got {self.wide_valley_sectors}")
        if self.window_cm <= self.cell_cm:
            raise ValueError(f"navigator.window_cm: must exceed cell_cm ({self.cell_cm}), got {self.window_cm}")

    @property
    def sectors(self) -> int:
        """Number of sectors, 360/α."""
        return round(360.0 / self.sector_deg)


def perimeter_points(tracks: tuple[Track, ...], spacing_cm: float) -> np.ndarray:
    """Points (M x 2, cm) every ``spacing_cm`` or closer around each track's disc at its present position
    (at least 8 per disc), the tracks' points one after the other."""
    if not tracks:
        return np.zeros((0, 2))
    counts = [max(8, math.ceil(2.0 * math.pi * t.radius / spacing_cm)) for t in tracks]
    angles = np.concatenate([np.arange(c) * (360.0 / c) for c in counts])
    centre_x = np.repeat([t.x for t in tracks], counts)
    centre_y = np.repeat([t.y for t in tracks], counts)
    radius = np.repeat([t.radius for t in tracks], counts)
    sin, cos = sin_cos_deg_array(angles)  # one call for all discs: the cost is per call, not per point
    return np.stack([centre_x + radius * cos, centre_y + radius * sin], axis=1)


def occupied_cells(points: np.ndarray, cell_cm: float) -> np.ndarray:
    """Centres (K x 2, cm) of the distinct world-fixed cells of side ``cell_cm`` holding at least one of
    ``points`` (P x 2, cm), in a fixed (sorted) order."""
    if len(points) == 0:
        return np.zeros((0, 2))
    index = np.floor(np.asarray(points, dtype=float) / cell_cm).astype(np.int64)
    low = index.min(axis=0)
    rows = int(index[:, 1].max() - low[1]) + 1
    # one integer key per cell, ordered by x index then y index: a 1-D unique is far faster than rows
    key = np.unique((index[:, 0] - low[0]) * rows + (index[:, 1] - low[1]))
    return (np.stack([key // rows + low[0], key % rows + low[1]], axis=1) + 0.5) * cell_cm


def polar_histogram(x: float, y: float, cells: np.ndarray, config: VfhConfig, enlarge_cm: float) -> np.ndarray:
    """The polar obstacle density h (one value per sector) seen from (x, y) (cm): each occupied cell
    (centres in cm) within the window adds ``a − b·d`` to every sector its enlarged direction interval
    [β − γ, β + γ] meets, ``γ = asin(enlarge_cm / d)`` (90° when ``d <= enlarge_cm``)."""
    n = config.sectors
    rel = cells - np.array([x, y])
    d = norm2(rel)
    inside = d < config.window_cm
    rel, d = rel[inside], d[inside]
    if len(d) == 0:
        return np.zeros(n)
    magnitude = config.b * config.window_cm - config.b * d
    # β and γ in one call (the cost is per call, not per element); asin(r/d) = atan2(r, sqrt(d² − r²)), which
    # is exactly 0 for r = 0
    clear = d > enlarge_cm
    k = len(d)
    angles = atan2_deg_array(np.concatenate([rel[:, 1], np.full(k, enlarge_cm)]),
                             np.concatenate([rel[:, 0], np.sqrt(np.where(clear, d * d - enlarge_cm * enlarge_cm,
                                                                         0.0))]))
    beta, gamma = angles[:k], np.where(clear, angles[k:], 90.0)
    low = np.floor((beta - gamma) / config.sector_deg).astype(np.int64)
    first = low % n
    last = first + (np.floor((beta + gamma) / config.sector_deg).astype(np.int64) - low)  # past n - 1: wraps
    sector = np.arange(n)[:, None]
    hit = ((sector >= first) & (sector <= last)) | (sector + n <= last)
    return sequential_sum(np.where(hit, magnitude[None, :], 0.0))


def smooth_histogram(h: np.ndarray, l: int) -> np.ndarray:  # noqa: E741 - the paper's name
    """The paper's eq. 5, circular: h'_k = Σ_{|j| < l} (l − |j|)·h_{k+j} / (2l + 1)."""
    n = len(h)
    padded = np.concatenate([h[n - l + 1:], h, h[:l - 1]])  # wraps round: sector n - 1 neighbours sector 0
    total = np.zeros_like(h)
    for j in range(-(l - 1), l):  # fixed order of the additions: the same bits everywhere
        total = total + (l - abs(j)) * padded[l - 1 + j:l - 1 + j + n]
    return total / (2 * l + 1)


def valleys(free: np.ndarray) -> list[tuple[int, int]]:
    """Runs of consecutive free sectors, circularly, as (first sector, length), ordered by first sector;
    ``[(0, n)]`` when every sector is free, ``[]`` when none is."""
    n = len(free)
    if free.all():
        return [(0, n)]
    if not free.any():
        return []
    blocked = int(np.argmin(free))  # a blocked sector: runs are found walking round from just after it
    runs, start = [], None
    for step in range(1, n + 1):
        k = (blocked + step) % n
        if free[k] and start is None:
            start = k
        elif not free[k] and start is not None:
            runs.append((start, (k - start) % n))
            start = None
    return sorted(runs)


def sector_of(direction_deg: float, sector_deg: float, n: int) -> int:
    """The sector (0..n-1) holding an absolute direction (degrees)."""
    return math.floor(wrap_360(direction_deg) / sector_deg) % n


def valley_distance(start: int, length: int, k_t: int, n: int) -> tuple[int, bool]:
    """(sectors from sector ``k_t`` to the valley of ``length`` sectors from ``start``: 0 inside it, else to
    its nearer border; whether the border nearest ``k_t`` is the valley's last sector rather than its first).
    A tie between the borders goes to the first one, i.e. counter-clockwise from ``k_t`` when outside."""
    last = (start + length - 1) % n
    from_first, from_last = (k_t - start) % n, (last - k_t) % n
    if from_first < length:
        return 0, from_last < from_first
    ccw, cw = (start - k_t) % n, (k_t - last) % n
    return min(ccw, cw), cw < ccw


def steering_direction(smoothed: np.ndarray, target_deg: float, config: VfhConfig) -> tuple[float | None, int]:
    """(absolute steering direction in degrees, or None when no valley exists; number of valleys) for the
    smoothed histogram and the target's direction (degrees), by the module docstring's valley rules."""
    n, alpha, s_max = len(smoothed), config.sector_deg, config.wide_valley_sectors
    runs = valleys(smoothed < config.threshold)
    if not runs:
        return None, 0
    if runs[0][1] == n:
        return wrap_360(target_deg), 1
    k_t = sector_of(target_deg, alpha, n)
    start, length = min(runs, key=lambda run: valley_distance(run[0], run[1], k_t, n))
    if length <= s_max:
        return wrap_360((start + length / 2.0) * alpha), len(runs)
    from_first, from_last = (k_t - start) % n, (start + length - 1 - k_t) % n
    if from_first < length and min(from_first, from_last) >= s_max / 2.0:
        return wrap_360(target_deg), len(runs)
    if valley_distance(start, length, k_t, n)[1]:  # nearest border is the last sector: step back from it
        return wrap_360((start + length - 0.5 - s_max / 2.0) * alpha), len(runs)
    return wrap_360((start + 0.5 + s_max / 2.0) * alpha), len(runs)


def vfh_speed(density_heading: float, h_m: float, v_min: float, v_max: float, to_goal_cm: float,
              dt: float) -> float:
    """The paper's speed reduction (cm/s): ``v_max·(1 − min(h'_c, h_m)/h_m)`` for the smoothed density h'_c
    at the heading, within [v_min, v_max] and at most what covers ``to_goal_cm`` in one step of ``dt`` s."""
    v = v_max * (1.0 - min(density_heading, h_m) / h_m)
    return max(v_min, min(v, v_max, to_goal_cm / dt))


def vfh_command(x: float, y: float, heading_deg: float, goal: tuple[float, float], points: np.ndarray,
                tracks: tuple[Track, ...], config: VfhConfig, robot_radius: float, v_min: float, v_max: float,
                dt: float) -> tuple[str, float, float, dict[str, float]]:
    """(mode, steering increment in degrees, speed in cm/s, log fields) for a robot at (x, y) (cm) heading
    ``heading_deg`` among static ``points`` (cm) and ``tracks``. The fields: ``direction_deg``, the chosen
    absolute direction (the heading when standing still); ``valleys``, how many there are; and
    ``density_heading``, the smoothed density h'_c in the heading's sector."""
    cloud = np.concatenate([np.asarray(points, dtype=float).reshape(-1, 2),
                            perimeter_points(tracks, config.perimeter_spacing_cm)])
    # a point farther than the window plus a cell cannot have its cell's centre inside the window
    near = norm2(cloud - np.array([x, y])) < config.window_cm + config.cell_cm
    cells = occupied_cells(cloud[near], config.cell_cm)
    h = smooth_histogram(polar_histogram(x, y, cells, config, robot_radius + config.safety_cm),
                         config.smoothing_l)
    h_c = float(h[sector_of(heading_deg, config.sector_deg, config.sectors)])
    direction, count = steering_direction(h, bearing_deg(x, y, goal[0], goal[1]), config)
    if direction is None:
        return "vfh_stop", 0.0, 0.0, {"direction_deg": float(heading_deg), "valleys": 0, "density_heading": h_c}
    v = vfh_speed(h_c, config.h_m, v_min, v_max, dist((x, y), goal), dt)
    fields = {"direction_deg": direction, "valleys": count, "density_heading": h_c}
    return "vfh", angle_difference_deg(direction, heading_deg), v, fields


@register_policy("vfh")
class VfhPolicy:
    """Vector field histogram (see the module docstring)."""

    name = "vfh"
    config_class = VfhConfig

    def __init__(self, params: Mapping[str, Any], context: PolicyContext) -> None:
        self.config: VfhConfig = from_dict(VfhConfig, params, "navigator")
        self.context = context

    def reset(self, seed: int) -> None:
        """Nothing to forget: the policy keeps no state."""

    def act(self, observation: Observation) -> Action:
        s, lim = observation.state, self.context.limits
        mode, dtheta, v, fields = vfh_command(s.x, s.y, s.heading, observation.goal, observation.static_points,
                                              observation.tracks, self.config, self.context.robot_radius,
                                              lim.v_min, lim.v_max, self.context.dt)
        return Action(mode, dtheta, v, fields)
