"""The navigation decision of one time step: the main loop of the paper's Fig. 1.

    detect moving obstacles -> Trajectory Prediction Table
    if no predicted collision:  straight to the target if no static obstacle is near, else fuzzy control
    else:                       follow the wait / detour plan of the dynamic path planner

The static command (no plan intervening) comes from a policy (:mod:`fuzzynav.policies.base`): the paper's
``fuzzy`` (:mod:`fuzzynav.policies.fuzzy`: straight to the target, or Table 1 near a static obstacle) or any
other (DWA, APF, VFH, ORCA, direct, your own); the wait/detour layer below runs on top of whichever it is
(``planner.strategy``; ``none`` leaves the policy alone). Our choices where the paper is silent:

- A plan, once made, is followed step by step and re-checked against each new table; the robot re-plans
  when the plan would now come closer than ``plan_check_margin_cm`` (5 cm, half the planning margin, so
  that noisy re-estimates do not discard a good plan) or the robot is more than ``plan_tolerance_cm`` off
  it (``replan_every_step`` re-plans on every step instead).
- The table predicts the robot at the speed the policy will command next if no plan intervenes — the
  policy's (for ``fuzzy``: the direct speed or the fuzzy controller's; ``planner.predict_speed = command``);
  a table that assumed the present speed would predict a motion the robot does not make (``present``: the
  present speed, or ``cruise_speed`` when standing).

Units: cm, s, degrees (dtheta positive = counter-clockwise = to the left), cm/s.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fuzzynav.kinematics import RobotLimits
from fuzzynav.numerics.portable_math import dist
from fuzzynav.params import limits
from fuzzynav.params.names import NAME as MODE_NAME
from fuzzynav.planning.planner import (
    Plan,
    PlannerConfig,
    find_new_path,
    hold_to_horizon,
    path_collides,
    plan_heading_change,
)
from fuzzynav.planning.tpt import TrajectoryPredictionTable, build_tpt
from fuzzynav.policies.base import Action, Observation, Policy, PolicyContext, make_policy
from fuzzynav.policies.fuzzy import FuzzyPolicyConfig, included_angle_deg
from fuzzynav.registry import one_line

PLAN_MODES = ("wait", "detour", "evade", "stop")
"""The modes of a step that follows a plan of the wait/detour layer; any other mode is the policy's own."""

__all__ = [
    "PLAN_MODES",
    "ActivePlan",
    "Decision",
    "FuzzyPolicyConfig",
    "Observation",
    "PlanningLayer",
    "build_planning_layer",
    "included_angle_deg",
]


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
    """The command of one step and why: ``mode`` (the policy's, e.g. direct | fuzzy | dwa, or a plan's: wait |
    detour | evade | stop), the steering increment (degrees) and speed (cm/s; 0 = stand still), the sonar and
    included-angle inputs (left, front, right in cm; angle in degrees), the table (None when no moving obstacle
    is perceived or strategy none), the plan being followed and whether it was made on this step, the policy's
    name and its own values of this step (``fields``; the policy's command even where a plan overrides it)."""

    mode: str
    dtheta_deg: float
    v_cm_s: float
    inputs: tuple[float, float, float, float]
    tpt: TrajectoryPredictionTable | None
    plan: Plan | None
    new_plan: bool
    policy: str = "fuzzy"
    fields: Mapping[str, Any] = field(default_factory=dict)


class PlanningLayer:
    """Decides one step at a time: the policy's command, overridden by a plan of the wait/detour layer when
    the table predicts a collision. Holds no state between steps but the policy's own (the active plan is
    passed in and out)."""

    def __init__(self, policy: Policy, planner: PlannerConfig, limits: RobotLimits, robot_radius: float,
                 dt: float = 1.0, name: str | None = None) -> None:
        """``name``: the policy as the configuration names it (a registered name, or the import path of a
        ``_target_``), recorded with every decision; None records the policy object's own ``name``."""
        self.policy = policy
        self.name = name
        self.planner = planner
        self.limits = limits
        self.robot_radius = robot_radius
        self.dt = dt

    @property
    def policy_name(self) -> str:
        """The policy as decisions record it (see ``name``)."""
        return self.name if self.name is not None else self.policy.name

    def reset(self, seed: int) -> None:
        """Before an episode: the policy forgets the last one (and draws its randomness from ``seed``)."""
        try:
            self.policy.reset(seed)
        except KeyboardInterrupt as err:  # a signal's, or the policy's own: the runner tells them apart
            err.add_note(f"{POLICY_NOTE}{self.policy_name}: reset(seed)")
            raise
        except BaseException as err:  # a policy's own code (SystemExit included) fails the episode, not the run
            raise PolicyError(f"policy {self.policy_name}: reset(seed) failed: {one_line(err)}") from err

    def decide(self, obs: Observation, active: ActivePlan | None) -> tuple[Decision, ActivePlan | None]:
        """The decision for this step, and the plan to carry into the next step."""
        s = obs.state
        left, front, right = obs.sonar
        angle = included_angle_deg(s, obs.goal)
        inputs = (left, front, right, angle)
        name = self.policy_name
        try:
            raw = self.policy.act(obs)
        except KeyboardInterrupt as err:  # a signal's, or the policy's own: the runner tells them apart
            err.add_note(f"{POLICY_NOTE}{name}: act()")
            raise
        except BaseException as err:  # SystemExit from a policy's code must not end a whole sweep
            raise PolicyError(f"policy {name}: act() failed: {one_line(err)}") from err
        action = checked_action(raw, name)
        static_v = action.v_cm_s
        fields = action.fields
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
                return Decision(mode, 0.0, 0.0, inputs, tpt, active.plan, new_plan, name, fields), carry
            mode = active.plan.strategy if active.plan.strategy in ("detour", "evade") else "wait"
            return Decision(mode, plan_heading_change(s.heading, here, target), step / self.dt, inputs, tpt,
                            active.plan, new_plan, name, fields), carry
        return Decision(action.mode, action.dtheta_deg, action.v_cm_s, inputs, tpt, None, False, name, fields), None

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


#: start of the note a KeyboardInterrupt gets when it comes out of a policy's reset() or act(): "policy <name>: act()"
POLICY_NOTE = "policy "


class PolicyError(ValueError):
    """A policy's own code failed, or returned a command the robot cannot execute: the episode ends as ``error``
    with this message (which names the policy)."""


MAX_DTHETA_DEG = 1e6  # a steering increment beyond it is no command (the robot clamps to its turn limit anyway)


def checked_action(action: Any, policy: str) -> Action:
    """``action`` if it is a command the robot can execute and the log can hold: an :class:`Action` with a mode
    name (lowercase, digits, ``_``; not a plan's mode), a finite steering increment (degrees, |Δθ| <=
    :data:`MAX_DTHETA_DEG`) and a speed in [0, ``limits.MAX_SPEED_CM_S``] (cm/s), and fields named by strings
    holding finite numbers, booleans or (UTF-8) strings. A policy that returns anything else (NaN from a division
    by zero, a negative speed, 1e308) stops the episode with a :class:`PolicyError` naming the policy and the
    field, instead of moving the robot by a wrong amount or writing a log no reader accepts.

    Returned as a new plain :class:`Action` of the values read once here and checked, as Python ``str``, ``float``
    (``int`` and ``bool`` fields as such): numpy scalars of any precision move the robot and fill the log as the
    same command in float64, and a subclass (a property, a mapping of its own) cannot answer a later read with
    another value."""
    if not isinstance(action, Action):
        raise PolicyError(f"policy {policy}: act() returned {type(action).__name__}, not a "
                          "fuzzynav.policies.base.Action")
    mode = _plain_str(action.mode)
    if mode is None or not MODE_NAME.fullmatch(mode) or mode in PLAN_MODES:
        raise PolicyError(f"policy {policy}: mode {_shown(action.mode)} is not a mode name (lowercase "
                          f"letters, digits, _; not one of the plan modes {', '.join(PLAN_MODES)})")
    bounds = (("dtheta_deg", action.dtheta_deg, -MAX_DTHETA_DEG, MAX_DTHETA_DEG),
              ("v_cm_s", action.v_cm_s, 0.0, limits.MAX_SPEED_CM_S))
    numbers = []
    for name, value, lo, hi in bounds:
        number = _plain_number(value)
        if number is None:
            raise PolicyError(f"policy {policy}: {name} = {_shown(value)} is not a finite number")
        if not lo <= number <= hi:
            raise PolicyError(f"policy {policy}: {name} = {number:g} is outside [{lo:g}, {hi:g}]"
                              + (" (0 = stand still)" if name == "v_cm_s" else ""))
        numbers.append(float(number))
    given = action.fields
    if not isinstance(given, Mapping):
        raise PolicyError(f"policy {policy}: fields is {type(given).__name__}, not a mapping")
    # read once, at most one past the limit (a mapping of its own may say any len())
    items = list(itertools.islice(given.items(), limits.MAX_POLICY_FIELDS + 1))
    if len(items) > limits.MAX_POLICY_FIELDS:
        raise PolicyError(f"policy {policy}: more than the limit of {limits.MAX_POLICY_FIELDS} fields (they are "
                          "logged at every step)")
    fields: dict[str, float | int | bool | str] = {}
    for raw_key, raw_value in items:
        key = _plain_str(raw_key)
        if key is None or not key:
            raise PolicyError(f"policy {policy}: field name {_shown(raw_key)} is not a (UTF-8) string")
        value: float | int | bool | str | None
        if isinstance(raw_value, bool | np.bool_):
            value = bool(raw_value)
        elif isinstance(raw_value, str):
            value = _plain_str(raw_value)
            if value is None:
                raise PolicyError(f"policy {policy}: field {key[:40]!r} = {_shown(raw_value)} is not a (UTF-8) "
                                  "string")
        else:
            value = _plain_number(raw_value)
            if value is None:
                raise PolicyError(f"policy {policy}: field {key[:40]!r} = {_shown(raw_value)} is not a finite "
                                  "number, a boolean or a (UTF-8) string")
        for what, text in (("name", key), ("value", value)):
            if isinstance(text, str) and len(text) > limits.MAX_POLICY_FIELD_CHARS:
                raise PolicyError(f"policy {policy}: field {key[:40]!r}: {what} of {len(text):,} characters, more "
                                  f"than the limit of {limits.MAX_POLICY_FIELD_CHARS}")
        fields[key] = value
    return Action(mode, numbers[0], numbers[1], fields)


def _plain_str(value: Any) -> str | None:
    """``value``'s text as a plain ``str`` (a subclass's own value: a ``str``-valued enum gives its value), or None
    if it is no string or holds a lone surrogate (no log can hold it)."""
    if not isinstance(value, str):
        return None
    text = str.__str__(value)
    return text if _utf8(text) else None


def _plain_number(value: Any) -> float | int | None:
    """``value`` as a plain Python ``int`` (integers) or ``float`` if it is a real number (not a boolean) whose float
    value is finite, else None. A subclass of ``int`` or ``float`` gives its own value, whatever its ``__int__`` or
    ``__float__`` say."""
    if isinstance(value, bool | np.bool_):
        return None
    number: float | int
    if isinstance(value, int):
        number = int.__int__(value)
    elif isinstance(value, float):
        number = float.__float__(value)
    elif isinstance(value, np.integer):
        number = int(value)
    elif isinstance(value, np.floating):
        number = float(value)
    else:
        return None
    try:
        return number if math.isfinite(float(number)) else None
    except OverflowError:  # an int beyond float range
        return None


def _shown(value: Any) -> str:
    """``value`` in an error line: a string quoted, anything else as it prints, at most 40 characters."""
    try:
        text = repr(str.__str__(value)) if isinstance(value, str) else str(value)
    except Exception:  # a value whose __str__ fails: named by its type
        text = f"<{type(value).__name__}>"
    return text[:40]


def _utf8(text: str) -> bool:
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:  # a lone surrogate: no log can hold it
        return False
    return True


def build_planning_layer(policy: str, params: Any, planner: PlannerConfig, limits: RobotLimits, robot_radius: float,
                    dt: float = 1.0, front_sector_deg: tuple[float, float] = (-30.0, 30.0),
                    controller: Any = None) -> PlanningLayer:
    """The planning layer of a run: policy ``policy`` (a registered name or an import path) with ``params`` (its
    ``navigator`` section, or the checked config), under the wait/detour layer ``planner``, for a robot of
    ``robot_radius`` cm with ``limits``; ``controller`` is the fuzzy controller for policies that use one."""
    context = PolicyContext(limits, robot_radius, dt, front_sector_deg, controller)
    return PlanningLayer(make_policy(policy, params, context), planner, limits, robot_radius, dt, name=policy)
