"""``scripted``: the obstacle follows its scenario path and ignores everything (the paper's moving obstacles).

Constant velocity (``start``, ``velocity``) or a waypoint path (``waypoints``, ``speed``, ``loop``), as
:class:`fuzzynav.pedestrians.motion.ObstacleMotion` computes them: position at step k is the path at time k·dt
(not an integration), so these obstacles are where they were before models existed, to the last bit.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from fuzzynav.pedestrians.base import CrowdView, register_obstacle_model
from fuzzynav.pedestrians.motion import ObstacleMotion

if TYPE_CHECKING:
    from fuzzynav.scenarios.scenario import DynamicObstacle


@dataclass(frozen=True)
class ScriptedConfig:
    """No parameters: the path is the obstacle's ``start``/``velocity`` or ``waypoints``/``speed``/``loop``."""


@register_obstacle_model("scripted")
class ScriptedModel:
    """Pure function of time; the view is not used."""

    config_class = ScriptedConfig

    def __init__(self, obstacles: Sequence[DynamicObstacle], config: ScriptedConfig) -> None:
        self.motion = ObstacleMotion(obstacles)

    def reset(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        return self.motion.at(0.0)

    def step(self, view: CrowdView, indices: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        # (k + 1)·dt, not t + dt: with dt = 0.7 the two differ in the last bit
        return self.motion.at((view.step + 1) * dt)
