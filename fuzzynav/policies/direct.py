"""``direct``: straight to the goal, no avoidance at all — the floor every other policy must beat.

Each step the robot turns towards the goal (the robot clamps the turn to its limit) and drives at
``speed_cm_s``, slowing to land on the goal. Parameters (``conf/navigator/direct.yaml``): ``speed_cm_s``
(default 25 cm/s, the fuzzy policy's direct speed). Units: cm, s, degrees, cm/s.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from fuzzynav.numerics.geometry import wrap_180
from fuzzynav.numerics.portable_math import bearing_deg, dist
from fuzzynav.params.limits import MAX_SPEED_CM_S, WHY_SPEED, Range, ranged
from fuzzynav.params.parsing import from_dict
from fuzzynav.policies.base import Action, Observation, PolicyContext, register_policy


@dataclass(frozen=True)
class DirectConfig:
    """Cruise speed (cm/s)."""

    speed_cm_s: float = ranged(25.0, Range(0, MAX_SPEED_CM_S, "cm/s", "direct: " + WHY_SPEED, lo_open=True),
                               robot_speed=True)

    def __post_init__(self) -> None:
        if not self.speed_cm_s > 0:
            raise ValueError(f"navigator.speed_cm_s: must be > 0, got {self.speed_cm_s}")


def direct_command(x: float, y: float, heading_deg: float, goal: tuple[float, float], speed_cm_s: float,
                   v_min: float, v_max: float, dt: float) -> tuple[float, float]:
    """(steering increment in degrees towards the goal, speed in cm/s): ``speed_cm_s``, at most what lands on
    the goal in one step, within [v_min, v_max]."""
    to_goal = dist((x, y), goal)
    v = max(v_min, min(speed_cm_s, v_max, to_goal / dt))
    return wrap_180(bearing_deg(x, y, goal[0], goal[1]) - heading_deg), v


@register_policy("direct")
class DirectPolicy:
    """Straight to the goal (see the module docstring)."""

    name = "direct"
    config_class = DirectConfig

    def __init__(self, params: Mapping[str, Any], context: PolicyContext) -> None:
        self.config: DirectConfig = from_dict(DirectConfig, params, "navigator")
        self.context = context

    def reset(self, seed: int) -> None:
        """Nothing to forget: the policy keeps no state."""

    def act(self, observation: Observation) -> Action:
        s, lim = observation.state, self.context.limits
        dtheta, v = direct_command(s.x, s.y, s.heading, observation.goal, self.config.speed_cm_s, lim.v_min,
                                   lim.v_max, self.context.dt)
        return Action("direct", dtheta, v)
