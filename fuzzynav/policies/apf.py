"""``apf``: artificial potential field (Khatib 1986, "Real-time obstacle avoidance for manipulators and mobile
robots", IJRR 5(1)) — the robot follows the negative gradient of an attractive potential around the goal plus
a repulsive potential around every obstacle it senses.

Forces (arbitrary units; only their direction and their size relative to the conic attraction matter):

- **Attraction** (the usual combination of Khatib's quadratic goal potential with a cone far away):
  ``U_att = ½·ξ·d²`` within ``d* = attractive_switch_cm`` of the goal, ``ξ·d*·d − ½·ξ·d*²`` beyond, so the
  force ``−∇U_att`` is ``ξ·(goal − x)`` near the goal (shrinking to 0 on it: the robot lands softly) and
  ``ξ·d*`` towards the goal far away (a constant pull, so distant goals do not swamp the repulsion).
- **Repulsion** (Khatib's FIRAS function): ``U_rep = ½·η·(1/ρ − 1/ρ0)²`` for ``ρ ≤ ρ0``, 0 beyond, whose
  force is ``η·(1/ρ − 1/ρ0)·(1/ρ²)·∇ρ``, ``∇ρ`` the unit vector from the obstacle to the robot. ``ρ`` is the
  gap between the robot's surface and the obstacle's: centre distance minus the robot radius minus the
  obstacle radius (0 for a static laser return). Every static laser return and every perceived moving
  obstacle repels; a moving obstacle repels from where it will be ``lookahead_s`` seconds ahead at its
  perceived velocity (0 = where it is now, as Khatib's static obstacles). The gap is floored at
  ``min_gap_cm`` so that contact or overlap (ρ ≤ 0) gives a large finite push away instead of infinity.

Command: the steering increment turns the heading onto the total force's direction (the robot clamps it to
its turn limit). The speed grows with the force's size and shrinks with the turn::

    v = v_min + (v_max − v_min) · min(1, |F| / (ξ·d*)) · max(0, cos Δθ)

— full speed when the force is at least the far-field pull and points straight ahead, ``v_min`` when it is
weak or points sideways or backwards (a sharp turn at full speed would swing the path wide). ``v`` is at most
what lands on the goal in one step (never below ``v_min``). A zero total force (no direction: an exact
balance, e.g. on the goal) means stand still.

Known limitation (a property of the method, not of this implementation): where the repulsion exactly
cancels the attraction — e.g. an obstacle symmetric about the straight line to the goal — the robot is in a
local minimum of the potential and stalls or oscillates in front of it (``tests/test_apf.py`` shows it).

Units: cm, s, degrees, cm/s. Portable numerics: elementwise numpy and ``math.fsum`` only (no BLAS).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from fuzzynav.numerics.geometry import angle_difference_deg
from fuzzynav.numerics.portable_math import atan2_deg, dist, hypot, norm2, sin_cos_deg
from fuzzynav.params.limits import WHY_REACH, Range, ranged
from fuzzynav.params.parsing import from_dict
from fuzzynav.policies.base import Action, Observation, PolicyContext, register_policy
from fuzzynav.sensing.tracking import Track


@dataclass(frozen=True)
class ApfConfig:
    """Gains and distances of the potential field (see the module docstring)."""

    # ξ (1/s): only the ratio η/ξ shapes the path; chosen 1 so that the far-field pull ξ·d* reads in cm
    attractive_gain: float = ranged(1.0, Range(0, 1e6, "1/s", "APF: ξ", lo_open=True))
    # d* (cm), the quadratic/conic switch: chosen 100 cm (2.5 steps at v_max) so the robot slows over its
    # last metre instead of arriving at full speed
    attractive_switch_cm: float = ranged(100.0, Range(0, 10_000, "cm", "APF: d*, " + WHY_REACH, lo_open=True))
    # η (cm³ per unit of ξ·d*): chosen so that one static return 20 cm from the robot's surface pushes about
    # as hard as the far-field pull: η·(1/20 − 1/80)/20² ≈ 107 vs ξ·d* = 100
    repulsive_gain: float = ranged(1.0e6, Range(0, 1e12, "", "APF: η"))
    # ρ0 (cm), Khatib's limit distance of influence: chosen 80 cm, two steps at v_max, so an obstacle is felt
    # at least two decisions before contact
    influence_cm: float = ranged(80.0, Range(0, 10_000, "cm", "APF: ρ0, " + WHY_REACH, lo_open=True))
    # (s) where moving obstacles repel from: chosen 1 s, one decision step, i.e. where the obstacle will be
    # when this step's move ends (0 = present position, as in Khatib's paper)
    lookahead_s: float = ranged(1.0, Range(0, 60, "s", "APF: where moving obstacles repel from"))
    # (cm) floor of the gap ρ: chosen 1 cm, below any gap the simulation resolves, to keep forces finite
    min_gap_cm: float = ranged(1.0, Range(0, 1_000, "cm", "APF: floor of the gap ρ", lo_open=True))

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            low_ok = value >= 0 if f.name == "lookahead_s" else value > 0
            if not (math.isfinite(value) and low_ok):
                bound = ">= 0" if f.name == "lookahead_s" else "> 0"
                raise ValueError(f"navigator.{f.name}: must be a finite number {bound}, got {value}")
        if self.min_gap_cm >= self.influence_cm:
            raise ValueError(f"navigator.min_gap_cm: must be below influence_cm ({self.influence_cm}), "
                             f"got {self.min_gap_cm}")


def attractive_force(x: float, y: float, goal: tuple[float, float], gain: float,
                     switch_cm: float) -> tuple[float, float]:
    """The goal's pull on a robot at (x, y) (cm): ``gain·(goal − x)`` within ``switch_cm`` of the goal,
    the same direction at the constant size ``gain·switch_cm`` beyond."""
    gx, gy = goal[0] - x, goal[1] - y
    d = hypot(gx, gy)
    scale = gain if d <= switch_cm else gain * switch_cm / d
    return gx * scale, gy * scale


def repulsive_force(x: float, y: float, centres: np.ndarray, radii: np.ndarray, robot_radius: float,
                    gain: float, influence_cm: float, min_gap_cm: float) -> tuple[float, float]:
    """The summed push (Khatib's ``η(1/ρ − 1/ρ0)(1/ρ²)``, away from each obstacle) on a robot of radius
    ``robot_radius`` (cm) at (x, y) from obstacles at ``centres`` (K x 2, cm) with ``radii`` (K, cm).
    Obstacles whose gap ρ exceeds ``influence_cm`` do not push; a gap below ``min_gap_cm`` counts as
    ``min_gap_cm``. An obstacle exactly at the robot's centre has no direction and does not push."""
    if len(centres) == 0:
        return 0.0, 0.0
    away = np.array([x, y]) - centres
    centre_dist = norm2(away)
    rho = np.maximum(centre_dist - robot_radius - radii, min_gap_cm)
    magnitude = np.where(rho <= influence_cm, gain * (1.0 / rho - 1.0 / influence_cm) / (rho * rho), 0.0)
    per_length = np.where(centre_dist > 0.0, magnitude / np.where(centre_dist > 0.0, centre_dist, 1.0), 0.0)
    return math.fsum((away[:, 0] * per_length).tolist()), math.fsum((away[:, 1] * per_length).tolist())


def obstacle_discs(static_points: np.ndarray, tracks: tuple[Track, ...],
                   lookahead_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Centres (K x 2, cm) and radii (K, cm) of everything that repels: the static returns (radius 0), then
    the tracks at their positions ``lookahead_s`` seconds ahead (constant velocity)."""
    moving = np.array([(t.x + t.vx * lookahead_s, t.y + t.vy * lookahead_s) for t in tracks], dtype=float)
    centres = np.concatenate([np.asarray(static_points, dtype=float).reshape(-1, 2), moving.reshape(-1, 2)])
    radii = np.concatenate([np.zeros(len(static_points)), np.array([t.radius for t in tracks], dtype=float)])
    return centres, radii


def apf_command(x: float, y: float, heading_deg: float, goal: tuple[float, float], centres: np.ndarray,
                radii: np.ndarray, config: ApfConfig, robot_radius: float, v_min: float, v_max: float,
                dt: float) -> tuple[float, float, float, float]:
    """(steering increment in degrees, speed in cm/s, size of the attraction, size of the repulsion) for a
    robot at (x, y) (cm) heading ``heading_deg`` among obstacle discs ``centres``/``radii`` (cm); the speed
    mapping is the module docstring's."""
    ax, ay = attractive_force(x, y, goal, config.attractive_gain, config.attractive_switch_cm)
    rx, ry = repulsive_force(x, y, centres, radii, robot_radius, config.repulsive_gain, config.influence_cm,
                             config.min_gap_cm)
    fx, fy = ax + rx, ay + ry
    size = hypot(fx, fy)
    if size == 0.0:
        return 0.0, 0.0, hypot(ax, ay), hypot(rx, ry)
    dtheta = angle_difference_deg(atan2_deg(fy, fx), heading_deg)
    strength = min(1.0, size / (config.attractive_gain * config.attractive_switch_cm))
    alignment = max(0.0, sin_cos_deg(dtheta)[1])
    v = v_min + (v_max - v_min) * strength * alignment
    v = max(v_min, min(v, dist((x, y), goal) / dt))
    return dtheta, v, hypot(ax, ay), hypot(rx, ry)


@register_policy("apf")
class ApfPolicy:
    """Artificial potential field (see the module docstring)."""

    name = "apf"
    config_class = ApfConfig

    def __init__(self, params: Mapping[str, Any], context: PolicyContext) -> None:
        self.config: ApfConfig = from_dict(ApfConfig, params, "navigator")
        self.context = context

    def reset(self, seed: int) -> None:
        """Nothing to forget: the policy keeps no state."""

    def act(self, observation: Observation) -> Action:
        s, lim, cfg = observation.state, self.context.limits, self.config
        centres, radii = obstacle_discs(observation.static_points, observation.tracks, cfg.lookahead_s)
        dtheta, v, attraction, repulsion = apf_command(s.x, s.y, s.heading, observation.goal, centres, radii, cfg,
                                                       self.context.robot_radius, lim.v_min, lim.v_max,
                                                       self.context.dt)
        return Action("apf", dtheta, v, {"attractive": attraction, "repulsive": repulsion})
