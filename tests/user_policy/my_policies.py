"""A navigation policy defined outside fuzzynav, for the tests of the policy seam from the outside (the
Gymnasium environment, ``runners.run``/``runners.sweep`` with ``navigator=custom``).

Import path: ``my_policies.Straight`` with ``tests/user_policy`` on ``PYTHONPATH``. Keep it tiny and stable:
other tests compare its logs.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from fuzzynav.numerics.geometry import wrap_180
from fuzzynav.numerics.portable_math import bearing_deg
from fuzzynav.policies.base import Action, Observation, PolicyContext


class Straight:
    """Turn towards the goal (at most the robot's turn limit per step) and drive at ``speed_cm_s`` (parameter,
    cm/s; default the robot's v_max). Units: cm, degrees, cm/s."""

    name = "straight"

    def __init__(self, params: Mapping[str, Any], context: PolicyContext) -> None:
        self.limits = context.limits
        self.speed = float(params.get("speed_cm_s", context.limits.v_max))

    def reset(self, seed: int) -> None:
        """Nothing to forget and no randomness."""

    def act(self, observation: Observation) -> Action:
        s = observation.state
        turn = wrap_180(bearing_deg(s.x, s.y, *observation.goal) - s.heading)
        turn = max(-self.limits.max_turn_deg, min(self.limits.max_turn_deg, turn))
        return Action("straight", turn, self.speed, {"turn_deg": turn})
