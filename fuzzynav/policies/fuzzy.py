"""``fuzzy``: the paper's static navigation (section III.B, Fig. 1) as a policy — straight to the target when
no static obstacle is near, else the fuzzy controller (Table 1, or any controller of the ``controller`` group).

Our choices where the paper is silent (README, "Navigation loop"):

- "A static obstacle is near" when a sonar reading is below ``static_near_cm`` (default 100 cm: the
  distance from which the default "far" term is fully true) in the front sector or the sector on the
  target's side (``near_sectors = target_side``; ``all`` reads every sector). An obstacle on the far
  side is not in the way of a robot turning to the target, and the Table 1 rules, which ignore the
  target, would otherwise drive the robot along a wall past its goal. With ``goal_overrides_static`` the robot
  still heads straight for the goal when the goal lies in the front sector and is nearer than the front
  reading (otherwise the fuzzy rules, which ignore the target, can circle a goal placed near a wall).
- Going straight to the target: turn towards it and drive at ``direct_speed_cm_s`` (default 25 cm/s, the
  Medium speed: the paper's nTraj = 9 steps "within the 250 cm laser range" implies about 250 / 9 ≈ 28 cm
  per step), slowing to land on the goal; ``direct_needs_clear_path`` first checks that move against the
  static laser returns.

Modes: ``direct`` and ``fuzzy``. Parameters: :class:`FuzzyPolicyConfig` (``conf/navigator/fuzzy_tpt.yaml``).
Units: cm, s, degrees (dtheta positive = counter-clockwise = to the left), cm/s.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from fuzzynav.kinematics import RobotState, bearing_deg, wrap_deg
from fuzzynav.numerics.clearance import segment_point_clearance
from fuzzynav.numerics.portable_math import dist, sin_cos_deg
from fuzzynav.params.limits import MAX_SPEED_CM_S, WHY_MARGIN, WHY_REACH, WHY_SPEED, Range, ranged
from fuzzynav.params.parsing import from_dict
from fuzzynav.policies.base import Action, Observation, PolicyContext, register_policy


@dataclass(frozen=True)
class FuzzyPolicyConfig:
    """When static navigation uses the fuzzy controller (see the module docstring)."""

    static_near_cm: float = ranged(100.0, Range(0, 10_000, "cm", WHY_REACH))
    direct_speed_cm_s: float = ranged(25.0, Range(0, MAX_SPEED_CM_S, "cm/s", WHY_SPEED, lo_open=True),
                                      robot_speed=True)
    near_sectors: str = "target_side"
    goal_overrides_static: bool = True
    direct_needs_clear_path: bool = True
    clear_path_margin_cm: float = ranged(5.0, Range(0, 1_000, "cm", WHY_MARGIN))

    def __post_init__(self) -> None:
        if self.near_sectors not in ("all", "target_side"):
            raise ValueError(f"navigator.near_sectors: unknown value {self.near_sectors!r} (known: all, target_side)")
        if self.static_near_cm < 0:
            raise ValueError(f"navigator.static_near_cm: must be >= 0, got {self.static_near_cm}")
        if self.direct_speed_cm_s <= 0:
            raise ValueError(f"navigator.direct_speed_cm_s: must be > 0, got {self.direct_speed_cm_s}")
        if self.clear_path_margin_cm < 0:
            raise ValueError(f"navigator.clear_path_margin_cm: must be >= 0, got {self.clear_path_margin_cm}")


def included_angle_deg(state: RobotState, goal: tuple[float, float]) -> float:
    """Angle (degrees, [0, 180]) between the robot's right-hand axis and the bearing to the goal:
    0 = goal to the right, 90 = straight ahead, 180 = to the left; a goal behind is clipped to 0 or 180."""
    rel = wrap_deg(bearing_deg(state.x, state.y, goal[0], goal[1]) - state.heading)
    return float(min(180.0, max(0.0, 90.0 + rel)))


@register_policy("fuzzy")
class FuzzyPolicy:
    """The paper's static navigation (see the module docstring); the controller comes from the context."""

    name = "fuzzy"
    config_class = FuzzyPolicyConfig

    def __init__(self, params: Mapping[str, Any], context: PolicyContext) -> None:
        if context.controller is None:
            raise ValueError("controller: the fuzzy policy needs a fuzzy controller (the controller group)")

        self.config: FuzzyPolicyConfig = from_dict(FuzzyPolicyConfig, params, "navigator")
        self.evaluator = context.controller
        self.limits = context.limits
        self.robot_radius = context.robot_radius
        self.dt = context.dt
        self.front_sector = context.front_sector_deg
        self._sources = {v.name: (v.source, v.scale) for v in self.evaluator.spec.inputs}

    def reset(self, seed: int) -> None:
        """Nothing to forget: the controller and the rules keep no state."""

    def fuzzy(self, inputs: Mapping[str, float]) -> tuple[float, float]:
        """Controller output (dtheta degrees, v cm/s) for observations keyed by source
        (left/front/right in cm, angle in degrees)."""
        values = {name: inputs[src] * scale for name, (src, scale) in self._sources.items()}
        return self.evaluator.evaluate(values)

    def act(self, observation: Observation) -> Action:
        mode, dtheta, v = self._static_command(observation, included_angle_deg(observation.state, observation.goal))
        return Action(mode, dtheta, v)

    def _static_command(self, obs: Observation, angle: float) -> tuple[str, float, float]:
        """What the robot does when no plan intervenes: ``direct`` (turn to the goal, ``direct_speed_cm_s``,
        slowing to land on it) or ``fuzzy`` (Table 1) — (mode, steering increment in degrees, speed in cm/s)."""
        s = obs.state
        to_goal = dist((s.x, s.y), obs.goal)
        v = max(self.limits.v_min, min(self.config.direct_speed_cm_s, self.limits.v_max, to_goal / self.dt))
        dtheta = wrap_deg(bearing_deg(s.x, s.y, *obs.goal) - s.heading)
        near = self._static_near(obs.sonar, angle) and not self._goal_in_reach(obs, angle)
        if near or not self._direct_is_clear(obs, dtheta, v):
            left, front, right = obs.sonar
            dtheta, v = self.fuzzy({"left": left, "front": front, "right": right, "angle": angle})
            return "fuzzy", dtheta, v
        return "direct", dtheta, v

    def _direct_is_clear(self, obs: Observation, dtheta: float, v: float) -> bool:
        """Whether the straight move towards the goal stays clear of static laser returns (the sonar
        only sees the front half; turning to the goal can face what it has not seen)."""
        if not self.config.direct_needs_clear_path:
            return True
        s = obs.state
        turn = max(-self.limits.max_turn_deg, min(self.limits.max_turn_deg, dtheta))
        sin, cos = sin_cos_deg(s.heading + turn)
        here = np.array([s.x, s.y])
        end = here + v * self.dt * np.array([cos, sin])
        gap = segment_point_clearance(here, end, obs.static_points)[0]
        return bool(gap >= self.robot_radius + self.config.clear_path_margin_cm)

    def _static_near(self, sonar: tuple[float, float, float], angle: float) -> bool:
        """Is a static obstacle near? ``all`` sectors, or only the front and the target's side."""
        left, front, right = sonar
        if self.config.near_sectors == "all":
            return min(sonar) < self.config.static_near_cm
        side = left if angle >= 90.0 else right
        return min(front, side) < self.config.static_near_cm

    def _goal_in_reach(self, obs: Observation, angle: float) -> bool:
        if not self.config.goal_overrides_static:
            return False
        rel = angle - 90.0  # bearing of the goal relative to the heading, degrees
        lo, hi = self.front_sector
        to_goal = dist(obs.state.position, obs.goal) - self.robot_radius
        return lo <= rel <= hi and to_goal < obs.sonar[1]
