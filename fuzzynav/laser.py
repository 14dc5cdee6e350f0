"""Laser range finder: omnidirectional, ``range_cm`` (250 cm) from the robot centre, N beams.

Beam i points at ``heading + angle_min + i * 360/N`` degrees (beam 0 straight ahead, counter-clockwise).
Ranges are in cm, measured from the robot centre; a beam with no return reads exactly ``range_cm``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from fuzzynav.raycast import cast_rays


@dataclass(frozen=True)
class LaserConfig:
    """Range (cm), number of beams, and Gaussian range noise (cm, standard deviation; 0 = exact)."""

    range_cm: float = 250.0
    beams: int = 360
    noise_std_cm: float = 0.0

    def __post_init__(self) -> None:
        if self.range_cm <= 0:
            raise ValueError(f"sensors.laser.range_cm: must be > 0, got {self.range_cm}")
        if self.beams < 8:
            raise ValueError(f"sensors.laser.beams: need at least 8, got {self.beams}")
        if self.noise_std_cm < 0:
            raise ValueError(f"sensors.laser.noise_std_cm: must be >= 0, got {self.noise_std_cm}")

    @property
    def relative_angles_rad(self) -> np.ndarray:
        """Beam angles relative to the heading, radians."""
        return np.arange(self.beams) * (2.0 * np.pi / self.beams)


@dataclass(frozen=True)
class LaserScan:
    """One laser frame: ranges (cm), world-frame beam angles (rad), and what each beam hit (ground truth,
    for tests and ablations: -1 nothing, 0 static, k+1 moving obstacle k). The tracker does not read
    ``labels``."""

    ranges: np.ndarray
    angles_world_rad: np.ndarray
    labels: np.ndarray
    origin: tuple[float, float]
    range_cm: float

    @cached_property
    def returned(self) -> np.ndarray:
        """Mask (N,) of the beams with a return (range below ``range_cm``)."""
        return self.ranges < self.range_cm

    @cached_property
    def xy(self) -> np.ndarray:
        """World coordinates (N, 2) in cm of every beam's end point (computed once per frame)."""
        a = self.angles_world_rad
        return np.stack([self.origin[0] + self.ranges * np.cos(a), self.origin[1] + self.ranges * np.sin(a)], axis=1)

    def points(self) -> np.ndarray:
        """World coordinates (K, 2) in cm of the beams that returned."""
        return self.xy[self.returned]


def scan(config: LaserConfig, x: float, y: float, heading_deg: float, segments: np.ndarray,
         static_circles: np.ndarray, discs: np.ndarray, rng: np.random.Generator | None = None) -> LaserScan:
    """Cast all beams from (x, y) cm against the static world and moving discs (K, 3: x, y, r in cm)."""
    angles = np.radians(heading_deg) + config.relative_angles_rad
    circles = np.vstack([static_circles.reshape(-1, 3), discs.reshape(-1, 3)])
    ranges, hit = cast_rays(np.array([x, y]), angles, segments, circles, config.range_cm)
    n_static = len(segments) + len(static_circles)
    labels = np.where(hit < 0, -1, np.where(hit < n_static, 0, hit - n_static + 1))
    if config.noise_std_cm > 0 and rng is not None:
        noisy = ranges + rng.normal(0.0, config.noise_std_cm, size=ranges.shape)
        ranges = np.where(hit >= 0, np.clip(noisy, 0.0, np.nextafter(config.range_cm, 0)), ranges)
    return LaserScan(ranges=ranges, angles_world_rad=angles % (2 * np.pi), labels=labels, origin=(x, y),
                     range_cm=config.range_cm)
