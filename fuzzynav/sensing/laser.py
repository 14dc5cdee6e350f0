"""Laser range finder: omnidirectional, ``range_cm`` (250 cm) from the robot centre, N beams.

Beam i points at ``heading + angle_min + i * 360/N`` degrees (beam 0 straight ahead, counter-clockwise).
Ranges are in cm, measured from the robot centre; a beam with no return reads exactly ``range_cm``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from fuzzynav.numerics.portable_math import sin_cos_deg, sin_cos_deg_array
from fuzzynav.numerics.portable_random import NormalStream
from fuzzynav.sensing.raycast import cast_rays


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
    def relative_angles_deg(self) -> np.ndarray:
        """Beam angles relative to the heading, degrees."""
        return np.arange(self.beams) * (360.0 / self.beams)

    @cached_property
    def relative_directions(self) -> tuple[np.ndarray, np.ndarray]:
        """(sin, cos) of every beam angle relative to the heading (computed once per configuration)."""
        return sin_cos_deg_array(self.relative_angles_deg)


@dataclass(frozen=True)
class LaserScan:
    """One laser frame: ranges (cm), world-frame beam directions (unit vectors, (N, 2)), and what each beam
    hit (ground truth, for tests and ablations: -1 nothing, 0 static, k+1 moving obstacle k). The tracker
    does not read ``labels``."""

    ranges: np.ndarray
    directions: np.ndarray
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
        d = self.directions
        return np.stack([self.origin[0] + self.ranges * d[:, 0], self.origin[1] + self.ranges * d[:, 1]], axis=1)

    def points(self) -> np.ndarray:
        """World coordinates (K, 2) in cm of the beams that returned."""
        return self.xy[self.returned]


def beam_directions(config: LaserConfig, heading_deg: float) -> np.ndarray:
    """World-frame unit vectors (N, 2) of the beams of a robot heading ``heading_deg`` (degrees): the relative
    directions rotated by the heading (one sin/cos per frame, not one per beam). Replay rebuilds a frame's
    points with this same function, so that they are the episode's to the last bit."""
    s, c = sin_cos_deg(heading_deg)
    rel_sin, rel_cos = config.relative_directions
    out = np.empty((len(rel_sin), 2))
    np.subtract(c * rel_cos, s * rel_sin, out=out[:, 0])
    np.add(s * rel_cos, c * rel_sin, out=out[:, 1])
    return out


def scan(config: LaserConfig, x: float, y: float, heading_deg: float, segments: np.ndarray,
         static_circles: np.ndarray, discs: np.ndarray, noise: NormalStream | None = None) -> LaserScan:
    """Cast all beams from (x, y) cm against the static world and moving discs (K, 3: x, y, r in cm)."""
    static_circles, discs = static_circles.reshape(-1, 3), discs.reshape(-1, 3)
    circles = np.concatenate([static_circles, discs]) if len(static_circles) else discs
    n_static = len(segments) + len(static_circles)
    directions = beam_directions(config, heading_deg)
    ranges, hit = cast_rays(np.array([x, y]), directions, segments, circles, config.range_cm)
    labels = np.where(hit < 0, -1, np.where(hit < n_static, 0, hit - n_static + 1))
    if config.noise_std_cm > 0 and noise is not None:
        noisy = ranges + noise.draw(0.0, config.noise_std_cm, len(ranges))
        ranges = np.where(hit >= 0, np.clip(noisy, 0.0, np.nextafter(config.range_cm, 0)), ranges)
    return LaserScan(ranges=ranges, directions=directions, labels=labels, origin=(x, y), range_cm=config.range_cm)
