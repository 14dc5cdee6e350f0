"""Unicycle kinematics of the robot. Positions in cm, headings in degrees (CCW from +x), speeds in cm/s."""

from __future__ import annotations

from dataclasses import dataclass

from fuzzynav.numerics import portable_math
from fuzzynav.numerics.geometry import wrap_180, wrap_360
from fuzzynav.numerics.portable_math import bearing_deg

# navigator.py takes its goal bearing and heading wrap from here, under these names
wrap_deg = wrap_180
__all__ = ["RobotLimits", "RobotState", "bearing_deg", "step_unicycle", "wrap_deg"]


@dataclass(frozen=True)
class RobotLimits:
    """Steering and speed limits: |dtheta| <= max_turn_deg per step; v in [v_min, v_max] cm/s when moving."""

    max_turn_deg: float = 120.0
    v_min: float = 10.0
    v_max: float = 40.0

    def __post_init__(self) -> None:
        if not 0 < self.max_turn_deg <= 180:
            raise ValueError(f"robot.max_turn_deg: must be in (0, 180], got {self.max_turn_deg}")
        if not 0 < self.v_min <= self.v_max:
            raise ValueError(f"robot.v_min/v_max: need 0 < v_min <= v_max, got {self.v_min}, {self.v_max}")


@dataclass(frozen=True)
class RobotState:
    """Pose (x, y in cm; heading in degrees CCW from +x, in [0, 360)) and last commanded speed v (cm/s)."""

    x: float
    y: float
    heading: float
    v: float = 0.0

    @property
    def position(self) -> tuple[float, float]:
        return (self.x, self.y)


def step_unicycle(state: RobotState, dtheta_deg: float, v_cm_s: float, dt: float,
                  limits: RobotLimits) -> RobotState:
    """Turn by ``dtheta_deg`` (clamped to ±max_turn_deg), then move ``v·dt`` along the new heading.

    ``v_cm_s`` is clamped to [v_min, v_max]; a speed of 0 (or less) means stand still (waiting)."""
    dtheta = max(-limits.max_turn_deg, min(limits.max_turn_deg, dtheta_deg))
    heading = wrap_360(state.heading + dtheta)
    v = 0.0 if v_cm_s <= 0.0 else max(limits.v_min, min(limits.v_max, v_cm_s))
    sin, cos = portable_math.sin_cos_deg(heading)
    return RobotState(x=state.x + v * dt * cos, y=state.y + v * dt * sin, heading=heading, v=v)
