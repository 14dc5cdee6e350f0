"""``random_walk``: an obstacle whose heading and speed change at random, ignoring everything around it.

It starts on its scenario path (at ``start`` with ``velocity``, or at the first waypoint heading for the second
at ``speed``). Every step of dt seconds, heading and speed take a Gaussian step: heading += N(0, σ_θ²·dt)
(``heading_sigma_deg``, degrees per √s), speed += N(0, σ_v²·dt) (``speed_sigma_cm_s``, cm/s per √s), the
speed kept in [``speed_min_cm_s``, ``speed_max_cm_s``]; then it moves straight for the step. At the world's
bounds it is reflected (the velocity component into the wall is reversed, the disc stays inside). This is the
case the Trajectory Prediction Table's constant-velocity assumption fits worst; σ = 0 is constant velocity.

Draws come from the episode's obstacle stream (:func:`fuzzynav.pedestrians.crowd.obstacle_rng`) through
:mod:`fuzzynav.numerics.portable_random`: the same on every CPU. Units: cm, s, cm/s, degrees.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from fuzzynav.numerics.portable_math import atan2_deg_array, norm2, sin_cos_deg_array
from fuzzynav.numerics.portable_random import standard_normal
from fuzzynav.pedestrians.base import CrowdView, in_range, register_obstacle_model
from fuzzynav.pedestrians.intent import Intent

if TYPE_CHECKING:
    from fuzzynav.scenarios.scenario import DynamicObstacle


@dataclass(frozen=True)
class RandomWalkConfig:
    """How much heading and speed change (per √s), and the speed range (cm/s)."""

    heading_sigma_deg: float = 20.0
    speed_sigma_cm_s: float = 5.0
    speed_min_cm_s: float = 0.0
    speed_max_cm_s: float = 60.0

    def __post_init__(self) -> None:
        in_range(self.heading_sigma_deg, "heading_sigma_deg", 0, 360, "deg")
        in_range(self.speed_sigma_cm_s, "speed_sigma_cm_s", 0, 1_000, "cm/s")
        in_range(self.speed_min_cm_s, "speed_min_cm_s", 0, 1_000, "cm/s")
        in_range(self.speed_max_cm_s, "speed_max_cm_s", self.speed_min_cm_s, 1_000, "cm/s")


@register_obstacle_model("random_walk")
class RandomWalkModel:
    """The obstacles of one ``random_walk`` group (module docstring)."""

    config_class = RandomWalkConfig

    def __init__(self, obstacles: Sequence[DynamicObstacle], config: RandomWalkConfig) -> None:
        self.config = config
        self.intent = Intent(obstacles, arrive_cm=1.0)
        self.radii = np.array([o.radius for o in obstacles], dtype=float)
        self.rng: np.random.Generator | None = None

    def reset(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        self.rng = rng
        self.intent.reset()
        self.x = self.intent.starts.copy()
        v = self.intent.initial_velocities()
        self.speed = np.clip(norm2(v), self.config.speed_min_cm_s, self.config.speed_max_cm_s)
        self.heading = atan2_deg_array(v[:, 1], v[:, 0])
        return self.x.copy(), self._velocity()

    def _velocity(self) -> np.ndarray:
        s, c = sin_cos_deg_array(self.heading)
        return np.stack([self.speed * c, self.speed * s], axis=-1)

    def step(self, view: CrowdView, indices: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        n = len(self.x)
        noise = standard_normal(self.rng, 2 * n)
        root_dt = math.sqrt(dt)
        self.heading = (self.heading + c.heading_sigma_deg * root_dt * noise[:n]) % 360.0
        self.speed = np.clip(self.speed + c.speed_sigma_cm_s * root_dt * noise[n:], c.speed_min_cm_s,
                             c.speed_max_cm_s)
        v = self._velocity()
        x = self.x + v * dt
        xmin, ymin, xmax, ymax = view.world.bounds
        for axis, lo, hi in ((0, xmin, xmax), (1, ymin, ymax)):
            lo_r, hi_r = lo + self.radii, hi - self.radii
            fits = lo_r <= hi_r
            below, above = fits & (x[:, axis] < lo_r), fits & (x[:, axis] > hi_r)
            x[:, axis] = np.where(below, 2 * lo_r - x[:, axis], np.where(above, 2 * hi_r - x[:, axis], x[:, axis]))
            x[:, axis] = np.where(fits, np.clip(x[:, axis], lo_r, hi_r), x[:, axis])
            v[:, axis] = np.where(below | above, -v[:, axis], v[:, axis])
        self.heading = np.where(norm2(v) > 0.0, atan2_deg_array(v[:, 1], v[:, 0]), self.heading)
        self.x = x
        return x.copy(), v
