"""Perception of moving obstacles: from the laser (``laser``, the paper's way) or from the simulator's
ground truth (``ground_truth``, an ablation, optionally with seeded Gaussian noise).

Both give :class:`fuzzynav.sensing.tracking.Track` objects (cm, cm/s) for the moving obstacles within the laser
range, plus the laser returns that are *not* moving obstacles (static points, cm, world frame), which
the planner may use to keep detours off walls.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fuzzynav.numerics.portable_math import hypot
from fuzzynav.numerics.portable_random import NormalStream
from fuzzynav.sensing import tracking
from fuzzynav.sensing.laser import LaserScan
from fuzzynav.sensing.tracking import Track, TrackerConfig, TrackerState

MODES = ("laser", "ground_truth")


@dataclass(frozen=True)
class PerceptionConfig:
    """``mode``: laser | ground_truth. Ground-truth noise: position and velocity standard deviations.
    ``confirm_frames``: ground truth reports an obstacle from its n-th consecutive frame within range — 2
    (default) gives it the laser tracker's latency (a track needs two frames for a velocity), so that the
    ablation removes estimation error, not delay; 1 reports it at once."""

    mode: str = "laser"
    position_noise_std_cm: float = 0.0
    velocity_noise_std_cm_s: float = 0.0
    confirm_frames: int = 2
    tracker: TrackerConfig = field(default_factory=TrackerConfig)

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"perception.mode: unknown mode {self.mode!r} (known: {', '.join(MODES)})")
        if self.position_noise_std_cm < 0 or self.velocity_noise_std_cm_s < 0:
            raise ValueError("perception: noise standard deviations must be >= 0")
        if self.confirm_frames < 1:
            raise ValueError(f"perception.confirm_frames: must be >= 1, got {self.confirm_frames}")


@dataclass(frozen=True)
class Perceived:
    """One frame of perception: moving-obstacle tracks, the beams attributed to them (bool mask over the
    scan) and the remaining laser returns as static points (K, 2) in cm."""

    tracks: tuple[Track, ...]
    moving_beams: np.ndarray
    static_points: np.ndarray


def perceive(config: PerceptionConfig, state: TrackerState, scan: LaserScan, time_s: float,
             truth_positions: np.ndarray, truth_velocities: np.ndarray, truth_radii: np.ndarray,
             noise: NormalStream, truth_present: np.ndarray | None = None) -> tuple[TrackerState, Perceived]:
    """Perceive the moving obstacles in this frame (see the module docstring). ``truth_present`` (N,) bool: which
    obstacles are in the world (None: all); an absent one is not perceived and its frame count starts again."""
    if config.mode == "laser":
        state, tracks, moving = tracking.update(state, scan, time_s, config.tracker)
        return state, Perceived(tuple(tracks), moving, static_points(scan, moving))
    ox, oy = scan.origin
    tracks = []
    frames = {t.id: t.hits for t in state.tracks}  # consecutive frames each obstacle has been in range
    in_range = []
    for k in range(len(truth_radii)):
        if truth_present is not None and not truth_present[k]:
            continue
        p = np.array(truth_positions[k], dtype=float)
        if hypot(float(p[0]) - ox, float(p[1]) - oy) - truth_radii[k] > scan.range_cm:
            continue
        seen = frames.get(k + 1, 0) + 1
        in_range.append(tracking.seen_frames(k + 1, seen, time_s))
        v = np.array(truth_velocities[k], dtype=float)
        if seen < config.confirm_frames or not v.any():
            continue  # not confirmed yet, or stopped (a stopped obstacle is not a moving obstacle)
        if config.position_noise_std_cm > 0:
            p = p + noise.draw(0.0, config.position_noise_std_cm, 2)
        if config.velocity_noise_std_cm_s > 0:
            v = v + noise.draw(0.0, config.velocity_noise_std_cm_s, 2)
        tracks.append(Track(k + 1, float(p[0]), float(p[1]), float(v[0]), float(v[1]), float(truth_radii[k])))
    moving = scan.returned & (scan.labels > 0)
    return TrackerState(tuple(in_range)), Perceived(tuple(tracks), moving, static_points(scan, moving))


def static_points(scan: LaserScan, moving_beams: np.ndarray) -> np.ndarray:
    """World coordinates (K, 2) cm of the returns not attributed to moving obstacles."""
    return scan.xy[scan.returned & ~moving_beams]
