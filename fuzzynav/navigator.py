"""The navigation decision of one time step: the main loop of the paper's Fig. 1.

    detect moving obstacles -> Trajectory Prediction Table
    if no predicted collision:  straight to the target if no static obstacle is near, else fuzzy control
    else:                       follow the wait / detour plan of the dynamic path planner

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
  per step), slowing to land on the goal.
- A plan, once made, is followed step by step and re-checked against each new table; the robot re-plans
  when the plan would now come closer than ``plan_check_margin_cm`` (5 cm, half the planning margin, so
  that noisy re-estimates do not discard a good plan) or the robot is more than ``plan_tolerance_cm`` off
  it (``replan_every_step`` re-plans on every step instead).
- The table predicts the robot at the speed the navigator will command next if no plan intervenes — the
  direct speed or the fuzzy controller's (``planner.predict_speed = command``); a table that assumed the
  present speed would predict a motion the robot does not make (``present``: the present speed, or
  ``cruise_speed`` when standing).

Units: cm, s, degrees (dtheta positive = counter-clockwise = to the left), cm/s.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from fuzzynav.clearance import segment_point_clearance
from fuzzynav.fuzzy_fast import FastEvaluator
from fuzzynav.kinematics import RobotLimits, RobotState, bearing_deg, wrap_deg
from fuzzynav.planner import (
    Plan,
    PlannerConfig,
    find_new_path,
    hold_to_horizon,
    path_collides,
    plan_heading_change,
)
from fuzzynav.portable_math import dist, sin_cos_deg
from fuzzynav.tpt import TrajectoryPredictionTable, build_tpt
from fuzzynav.tracking import Track

MODES = ("direct", "fuzzy", "wait", "detour", "evade", "stop")


@dataclass(frozen=True)
class NavigatorConfig:
    """When static navigation uses the fuzzy controller (see the module docstring)."""

    static_near_cm: float = 100.0
    direct_speed_cm_s: float = 25.0
    near_sectors: str = "target_side"
    goal_overrides_static: bool = True
    direct_needs_clear_path: bool = True
    clear_path_margin_cm: float = 5.0

    def __post_init__(self) -> None:
        if self.near_sectors not in ("all", "target_side"):
            raise ValueError(f"navigator.near_sectors: unknown value {self.near_sectors!r} (known: all, target_side)")
        if self.static_near_cm < 0:
            raise ValueError(f"navigator.static_near_cm: must be >= 0, got {self.static_near_cm}")
        if self.direct_speed_cm_s <= 0:
            raise ValueError(f"navigator.direct_speed_cm_s: must be > 0, got {self.direct_speed_cm_s}")
        if self.clear_path_margin_cm < 0:
            raise ValueError(f"navigator.clear_path_margin_cm: must be >= 0, got {self.clear_path_margin_cm}")


@dataclass(frozen=True)
class Observation:
    """What the robot knows at one step: its own state (odometry), the goal (cm), sonar readings
    (left, front, right; cm), perceived moving obstacles and static laser points (P, 2; cm)."""

    state: RobotState
    goal: tuple[float, float]
    sonar: tuple[float, float, float]
    tracks: tuple[Track, ...]
    static_points: np.ndarray


@dataclass(frozen=True)
class ActivePlan:
    """A plan being followed: ``done`` of its steps have been executed."""

    plan: Plan
    done: int = 0

    @property
    def remaining(self) -> np.ndarray:
        return self.plan.path[self.done:]


@dataclass(frozen=True)
class Decision:
    """The command of one step and why: ``mode`` (direct | fuzzy | wait | detour | evade | stop), the steering
    increment (degrees) and speed (cm/s; 0 = stand still), the controller inputs (left, front, right in cm;
    included angle in degrees), the table (None when no moving obstacle is perceived or strategy none),
    the plan being followed and whether it was made on this step."""

    mode: str
    dtheta_deg: float
    v_cm_s: float
    inputs: tuple[float, float, float, float]
    tpt: TrajectoryPredictionTable | None
    plan: Plan | None
    new_plan: bool


def included_angle_deg(state: RobotState, goal: tuple[float, float]) -> float:
    """Angle (degrees, [0, 180]) between the robot's right-hand axis and the bearing to the goal:
    0 = goal to the right, 90 = straight ahead, 180 = to the left; a goal behind is clipped to 0 or 180."""
    rel = wrap_deg(bearing_deg(state.x, state.y, goal[0], goal[1]) - state.heading)
    return float(min(180.0, max(0.0, 90.0 + rel)))


class Navigator:
    """Decides one step at a time; holds no state between steps (the active plan is passed in and out)."""

    def __init__(self, evaluator: FastEvaluator, planner: PlannerConfig, navigator: NavigatorConfig,
                 limits: RobotLimits, robot_radius: float, dt: float = 1.0,
                 front_sector_deg: tuple[float, float] = (-30.0, 30.0)) -> None:
        self.evaluator = evaluator
        self.planner = planner
        self.config = navigator
        self.limits = limits
        self.robot_radius = robot_radius
        self.dt = dt
        self.front_sector = front_sector_deg
        self._sources = {v.name: (v.source, v.scale) for v in evaluator.spec.inputs}

    def fuzzy(self, inputs: Mapping[str, float]) -> tuple[float, float]:
        """Controller output (dtheta degrees, v cm/s) for observations keyed by source
        (left/front/right in cm, angle in degrees)."""
        values = {name: inputs[src] * scale for name, (src, scale) in self._sources.items()}
        return self.evaluator.evaluate(values)

    def decide(self, obs: Observation, active: ActivePlan | None) -> tuple[Decision, ActivePlan | None]:
        """The decision for this step, and the plan to carry into the next step."""
        s = obs.state
        left, front, right = obs.sonar
        angle = included_angle_deg(s, obs.goal)
        inputs = (left, front, right, angle)
        static_mode, static_dtheta, static_v = self._static_command(obs, angle)
        tpt = None
        if self.planner.strategy != "none" and obs.tracks:
            if self.planner.predict_speed == "command":
                speed = static_v
            else:
                speed = s.v if s.v > 0 else self.planner.cruise_speed
            tpt = build_tpt((s.x, s.y), obs.goal, speed, obs.tracks, self.robot_radius, self.planner.n_traj,
                            self.dt, self.planner.safety_margin_cm, self.planner.swept_tpt)
        if active is not None and (self.planner.replan_every_step
                                   or (self.planner.recheck_plan and not self._still_valid(active, obs, tpt))):
            active = None
        new_plan = False
        if active is None and tpt is not None and tpt.any_collision:
            plan = find_new_path(tpt, self.planner, s.heading, obs.static_points, self.robot_radius,
                                 self.limits.max_turn_deg)
            if plan is not None:
                active, new_plan = ActivePlan(plan), True
        if active is not None:
            target = active.remaining[0]
            here = (s.x, s.y)
            step = dist(here, target)
            after = ActivePlan(active.plan, active.done + 1)
            carry = after if after.done < len(after.plan.path) else None
            if step < 1e-6:
                mode = "stop" if active.plan.strategy == "stop" else "wait"
                return Decision(mode, 0.0, 0.0, inputs, tpt, active.plan, new_plan), carry
            mode = active.plan.strategy if active.plan.strategy in ("detour", "evade") else "wait"
            return Decision(mode, plan_heading_change(s.heading, here, target), step / self.dt, inputs, tpt,
                            active.plan, new_plan), carry
        return Decision(static_mode, static_dtheta, static_v, inputs, tpt, None, False), None

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

    def _still_valid(self, active: ActivePlan, obs: Observation, tpt: TrajectoryPredictionTable | None) -> bool:
        expected = active.plan.path[active.done - 1] if active.done > 0 else None
        here = np.array(obs.state.position)
        if expected is not None and dist(here, expected) > self.planner.plan_tolerance_cm:
            return False
        pts = obs.static_points if self.planner.avoid_static_points else None
        if tpt is None and pts is None:
            return True
        remaining = active.remaining
        if tpt is None:  # no track this frame: a lost track's returns look static, so only the next move counts
            remaining = remaining[:1]
        if tpt is not None and active.plan.strategy == "wait" and self.planner.wait_check_horizon:
            remaining = hold_to_horizon(remaining, tpt.n_traj)  # safe to stand there to the end of the table
        return not path_collides(tpt, remaining, here, pts, self.robot_radius + self.planner.static_margin_cm,
                                 margin=self.planner.plan_check_margin_cm)
