"""``dwa``: the Dynamic Window Approach (Fox, Burgard & Thrun 1997, "The dynamic window approach to collision
avoidance", IEEE Robotics & Automation Magazine 4(1)), adapted to this robot's discrete unicycle.

Each step the policy searches a grid of commands (steering increment dθ, speed v) and keeps the best one:

1. **Dynamic window.** Speeds reachable from the last commanded speed within one step,
   ``[v - decel·dt, v + accel·dt]`` inside ``[v_min, v_max]``, capped to land on the goal rather than pass it
   (as :mod:`fuzzynav.policies.direct`), sampled at ``speed_samples`` speeds, plus 0 (stand still, which the robot
   can always do). Turns: ``turn_samples`` increments evenly across ``±min(max_turn_rate·dt, max_turn)``
   plus the turn that faces the goal. The turn has no window around the last turn: the robot's model
   (:func:`fuzzynav.kinematics.step_unicycle`) has no angular inertia, it turns any dθ within its limit
   from any state.
2. **Rollout.** Each candidate is predicted for ``horizon_steps`` steps the way the robot moves: turn once,
   then straight at v (the paper's circular arc of constant (v, ω) becomes this polyline; holding a turn
   of up to 120° at every step would predict a tight loop the policy never intends to drive, because it
   chooses again next step). The rollout stops at the goal, where the episode ends.
3. **Clearance.** The smallest gap (cm) over the rollout between the robot's disc and (a) the static laser
   returns (distance from the rollout's segment) and (b) every perceived moving obstacle predicted at
   constant velocity, compared at the same times (closest approach of the two straight motions within
   each step, :func:`fuzzynav.numerics.geometry.swept_distance`).
4. **Admissible velocities** (the paper's V_a: the robot can stop before it hits): the rollout keeps a gap
   of at least ``margin_cm``, and ``v <= sqrt(2·(gap - margin)·decel)`` where the gap is the one to the
   obstacles the rollout closes on (those it comes nearer to than it is now). Obstacles the rollout does
   not approach only need the margin; otherwise a robot beside a wall could never drive away from it.
5. **Objective** (the paper's ``G = α·heading + β·dist + γ·vel``), over the candidates the choice is made
   from (step 6): heading = ``(180 - |θ|) / 180`` with θ the angle between the robot's heading and the
   goal's bearing at the rollout's end (0 once the rollout reaches the goal); clearance = the gap capped at
   ``clearance_cap_cm``; velocity = v. The paper normalises each term to [0, 1] without saying how; here
   each term is divided by its largest value among those candidates (a term that is 0 for all of them
   stays 0), which keeps the ratios between candidates, unlike min-max scaling, which would give a 0.1 cm
   difference in clearance the full weight β.
   The paper's smoothing σ is omitted: its job (more side clearance) is done here by the
   clearance-dependent speed limit of step 4 and the cap.
6. **Choice.** The admissible moving candidate of highest score; exact ties go to the smaller |dθ|, then
   the higher speed, then the turn to the right (negative dθ). Standing still (turning in place) is chosen
   only when no moving candidate is admissible: with the paper's heading-dominant weights a robot facing
   the goal would otherwise prefer standing in front of an obstacle for ever to any detour (the detour
   loses more heading than γ·velocity gives back). Waiting for a moving obstacle to pass is the job of the
   Trajectory Prediction Table's wait layer, which can run on top of this policy. No admissible candidate
   at all: stand still (mode ``dwa_stop``).

The sonar readings are not used: the laser's static returns cover the sonar's sectors and more.
Parameters (``conf/navigator/dwa.yaml``): :class:`DWAConfig`. Units: cm, s, degrees, cm/s.
Numerics are portable (:mod:`fuzzynav.numerics.portable_math`, :mod:`fuzzynav.numerics.geometry`: elementwise
operations and
``min``/``max`` only), so every decision is the same bits on every CPU.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from fuzzynav.kinematics import RobotLimits, RobotState
from fuzzynav.numerics.geometry import angle_difference_deg, closest_approach_fraction, swept_distance, wrap_180
from fuzzynav.numerics.portable_math import atan2_deg_array, bearing_deg, dist, norm2, sin_cos_deg_array
from fuzzynav.params.limits import WHY_MARGIN, WHY_REACH, Range, ranged
from fuzzynav.params.parsing import from_dict
from fuzzynav.policies.base import Action, Observation, PolicyContext, register_policy
from fuzzynav.sensing.tracking import Track

# A rollout ending this close to the goal has reached it: the bearing from there is rounding noise, and
# 1 cm is far inside the goal tolerance (the robot radius, 20 cm, by default)
_ARRIVED_CM = 1.0


@dataclass(frozen=True)
class DWAConfig:
    """The Dynamic Window Approach's parameters (see the module docstring); units in the names."""

    # chosen: 10° between turn samples across ±120° (the robot's turn limit); odd, so that 0 (straight on)
    # and both extremes are samples. The paper samples (v, ω) at the resolution of its velocity space.
    turn_samples: int = ranged(25,
                               Range(3, 721, "", "DWA: turn samples per speed, odd (each is rolled out)", integer=True))
    # chosen: 5 cm/s between samples of the widest window from rest ([10, 15] cm/s: 2 samples) to the usual
    # [v - 30, v + 15]; both ends of the window are always samples
    speed_samples: int = ranged(4, Range(1, 100, "", "DWA: speed samples per turn", integer=True))
    # chosen: 15 cm/s² lets the robot start (v_min = 10 cm/s is reachable from rest in one 1 s step) and reach
    # v_max = 40 cm/s in three steps (15, 30, 40), a gentle start as in the paper's RHINO, whose window is
    # its acceleration over one interval; must be at least v_min / dt
    accel_cm_s2: float = ranged(15.0,
                                Range(0, 100_000, "cm/s²", "DWA: the speed window's reach in one step", lo_open=True))
    # chosen: 30 cm/s² brings v_max down to v_min in one step, so the window never forces the robot to keep
    # speed (its model can change speed at once); it is also the paper's braking deceleration v̇_b of the
    # admissibility test: from 40 cm/s the robot needs a gap of 40² / 60 ≈ 27 cm beyond the margin
    decel_cm_s2: float = ranged(30.0, Range(0, 100_000, "cm/s²", "DWA: braking deceleration", lo_open=True))
    # chosen: 120 °/s, the robot's default turn limit per 1 s step: the window on turns is then the whole
    # turn range (no angular inertia in the model); lower it to emulate a robot with a slew-rate limit
    max_turn_rate_deg_s: float = ranged(120.0, Range(0, 36_000, "deg/s", "DWA: the turn window", lo_open=True))
    # chosen: 3 steps (3 s; 120 cm at v_max, inside the laser's 250 cm): long enough to see a crossing
    # obstacle's approach, short enough for constant-velocity predictions of tracks to hold. The paper
    # looks one interval ahead plus the braking distance.
    horizon_steps: int = ranged(3, Range(1, 100, "steps", "DWA: rollout length; work grows with it", integer=True))
    # paper: α = 2, β = 0.2, γ = 0.2 (RHINO's weights): the goal's heading dominates, clearance and speed
    # break the choice between similar headings
    alpha_heading: float = ranged(2.0, Range(0, 1e6, "", "DWA: weight of the heading term"))
    beta_clearance: float = ranged(0.2, Range(0, 1e6, "", "DWA: weight of the clearance term"))
    gamma_velocity: float = ranged(0.2, Range(0, 1e6, "", "DWA: weight of the velocity term"))
    # paper: dist is a large constant when no obstacle is on the trajectory; chosen 100 cm (2.5 robot
    # diameters, the fuzzy policy's static_near_cm): obstacles farther than that do not change the choice
    clearance_cap_cm: float = ranged(100.0, Range(0, 10_000, "cm", "DWA: " + WHY_REACH, lo_open=True))
    # chosen: 10 cm, the planner's safety_margin_cm (tracks are estimates: a few cm off in position and
    # speed); the paper's robot stops at the obstacle itself
    margin_cm: float = ranged(10.0, Range(0, 1_000, "cm", WHY_MARGIN))

    def __post_init__(self) -> None:
        if self.turn_samples < 3 or self.turn_samples % 2 == 0:
            raise ValueError(f"navigator.turn_samples: must be an odd number >= 3 (so that 0 is a sample), "
                             f"got {self.turn_samples}")
        for name in ("speed_samples", "horizon_steps"):
            if getattr(self, name) < 1:
                raise ValueError(f"navigator.{name}: must be >= 1, got {getattr(self, name)}")
        for name in ("accel_cm_s2", "decel_cm_s2", "max_turn_rate_deg_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"navigator.{name}: must be > 0, got {getattr(self, name)}")
        for name in ("alpha_heading", "beta_clearance", "gamma_velocity", "margin_cm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"navigator.{name}: must be a finite number >= 0, got {value}")
        if self.alpha_heading + self.beta_clearance + self.gamma_velocity == 0:
            raise ValueError("navigator.alpha_heading: the weights alpha_heading, beta_clearance and "
                             "gamma_velocity are all 0; at least one must be > 0")
        if not (math.isfinite(self.clearance_cap_cm) and self.clearance_cap_cm > self.margin_cm):
            raise ValueError(f"navigator.clearance_cap_cm: must be finite and > margin_cm ({self.margin_cm}), "
                             f"got {self.clearance_cap_cm}")


@dataclass(frozen=True)
class Candidates:
    """The commands searched in one step: steering increments (degrees) and speeds (cm/s), one per
    candidate (arrays of equal length; speed 0 = stand still)."""

    dtheta_deg: np.ndarray
    v_cm_s: np.ndarray


@dataclass(frozen=True)
class Evaluation:
    """Per candidate: the smallest gap over the rollout capped at ``clearance_cap_cm`` (cm), whether it is
    admissible, whether it is among those the choice is made from (the admissible moving candidates, or the
    admissible standing ones when no moving one is admissible), and the three normalised terms and their
    weighted sum (0 outside the choice)."""

    candidates: Candidates
    clearance_cm: np.ndarray
    admissible: np.ndarray
    chosen_from: np.ndarray
    heading: np.ndarray
    clearance: np.ndarray
    velocity: np.ndarray
    score: np.ndarray


def speed_window(v_last: float, to_goal_cm: float, config: DWAConfig, limits: RobotLimits,
                 dt: float) -> tuple[float, float]:
    """(lowest, highest) moving speed (cm/s) of the dynamic window around the last commanded speed
    ``v_last`` (cm/s; 0 when standing): within the acceleration limits and [v_min, v_max], the top capped
    at the speed that lands on the goal in one step (never below v_min, the robot's slowest move), and the
    bottom lowered to that cap when landing needs more braking than ``decel_cm_s2`` (the robot's model
    allows it; passing the goal would not help)."""
    reach_hi = min(limits.v_max, v_last + config.accel_cm_s2 * dt)
    reach_lo = max(limits.v_min, v_last - config.decel_cm_s2 * dt)
    hi = max(limits.v_min, min(reach_hi, to_goal_cm / dt))
    return min(reach_lo, hi), hi


def make_candidates(state: RobotState, goal: tuple[float, float], config: DWAConfig, limits: RobotLimits,
                    dt: float) -> Candidates:
    """Every (turn, speed) pair of the window: the turn grid plus the turn facing the goal (clamped to the
    window), each with the sampled speeds and with 0 (stand still)."""
    window = min(config.max_turn_rate_deg_s * dt, limits.max_turn_deg)
    n = config.turn_samples
    grid = -window + (2.0 * window) * (np.arange(n, dtype=float) / (n - 1))
    to_goal = wrap_180(bearing_deg(state.x, state.y, goal[0], goal[1]) - state.heading)
    turns = np.append(grid, max(-window, min(window, to_goal)))
    lo, hi = speed_window(state.v, dist(state.position, goal), config, limits, dt)
    m = config.speed_samples
    moving = np.array([hi]) if m == 1 else lo + (hi - lo) * (np.arange(m, dtype=float) / (m - 1))
    speeds = np.append(moving, 0.0)
    return Candidates(np.repeat(turns, len(speeds)), np.tile(speeds, len(turns)))


def rollouts(state: RobotState, goal: tuple[float, float], cand: Candidates, horizon_steps: int,
             dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(positions (C, H + 1, 2) in cm at the times 0, dt, ..., H·dt; headings (C,) in degrees) of each
    candidate turned once and then driven straight, stopping at the goal's distance."""
    heading = state.heading + cand.dtheta_deg
    sin, cos = sin_cos_deg_array(heading)
    to_goal = dist(state.position, goal)
    steps = np.arange(horizon_steps + 1, dtype=float) * dt
    travel = np.minimum(cand.v_cm_s[:, None] * steps[None, :], to_goal)
    x = state.x + travel * cos[:, None]
    y = state.y + travel * sin[:, None]
    return np.stack([x, y], axis=-1), heading


def _segment_distances(start: np.ndarray, ends: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distances (cm) from each segment ``start -> ends[i]`` (C, 2) to each of ``points`` (P, 2), shape (C, P):
    :func:`fuzzynav.numerics.geometry.segment_point_distance` (``ends[:, None]``) to the last bit, with the final
    ``rel0 + s·step`` and its length taken one coordinate at a time, which saves the (C, P, 2) temporaries
    and half the time."""
    rel0 = start - points
    step = ends[:, None, :] - start
    s = closest_approach_fraction(rel0, step)
    x = rel0[:, 0] + s * step[..., 0]
    y = rel0[:, 1] + s * step[..., 1]
    return np.sqrt(x * x + y * y)


def _static_gaps(path: np.ndarray, moving: np.ndarray, points: np.ndarray, robot_radius: float,
                 reach_cm: float) -> tuple[np.ndarray, np.ndarray]:
    """(smallest gap, smallest gap among the points approached) in cm per candidate, from the straight
    rollouts ``path`` (C, H + 1, 2) to the static ``points`` (P, 2); ``inf`` without points.

    Only what can change the choice is computed: points whose gap now exceeds ``reach_cm`` plus the longest
    rollout stay farther than ``reach_cm`` (beyond the clearance cap and every braking distance of the
    window), so they are skipped; a candidate that does not move (``moving`` False) keeps today's gap and
    approaches nothing."""
    count = len(path)
    start = path[0, 0]
    now = norm2(start - points)
    longest = float(np.max(norm2(path[:, -1] - start))) if count else 0.0
    near = now - robot_radius - longest < reach_cm
    points, now = points[near], now[near]
    if len(points) == 0:
        inf = np.full(count, np.inf)
        return inf, inf
    gap = np.full(count, float(np.min(now)) - robot_radius)
    approached = np.full(count, np.inf)
    along = _segment_distances(start, path[moving, -1], points)  # (moving, P)
    gap[moving] = np.min(along, axis=1) - robot_radius
    approached[moving] = np.min(np.where(along < now, along, np.inf), axis=1) - robot_radius
    return gap, approached


def _track_gaps(path: np.ndarray, tracks: tuple[Track, ...], robot_radius: float,
                dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(smallest gap, smallest gap among the tracks approached) in cm per candidate, between the rollouts
    ``path`` (C, H + 1, 2) and the tracks predicted at constant velocity over the same steps (closest
    approach within each step); ``inf`` without tracks."""
    if not tracks:
        inf = np.full(len(path), np.inf)
        return inf, inf
    pos = np.array([[t.x, t.y] for t in tracks])
    vel = np.array([[t.vx, t.vy] for t in tracks])
    radii = np.array([t.radius for t in tracks])
    steps = np.arange(path.shape[1], dtype=float) * dt
    predicted = pos[:, None, :] + steps[None, :, None] * vel[:, None, :]  # (T, H + 1, 2)
    robot = path[:, None]  # (C, 1, H + 1, 2)
    closest = swept_distance(robot[..., :-1, :], robot[..., 1:, :], predicted[:, :-1], predicted[:, 1:])
    along = np.min(closest, axis=2)  # (C, T)
    now = norm2(path[0, 0] - pos)  # (T,)
    gap = along - robot_radius - radii
    approached = np.where(along < now, gap, np.inf)
    return np.min(gap, axis=1), np.min(approached, axis=1)


def _normalised(term: np.ndarray, admissible: np.ndarray) -> np.ndarray:
    """``term`` divided by its largest value over the admissible candidates (0 elsewhere, and everywhere
    when that largest value is 0)."""
    top = float(np.max(np.where(admissible, term, 0.0))) if admissible.any() else 0.0
    return np.where(admissible, term / top, 0.0) if top > 0 else np.zeros_like(term)


def evaluate(state: RobotState, goal: tuple[float, float], tracks: tuple[Track, ...], static_points: np.ndarray,
             config: DWAConfig, limits: RobotLimits, robot_radius: float, dt: float) -> Evaluation:
    """Every candidate of the window, rolled out and scored (see the module docstring)."""
    cand = make_candidates(state, goal, config, limits, dt)
    path, heading = rollouts(state, goal, cand, config.horizon_steps, dt)
    points = np.asarray(static_points, dtype=float).reshape(-1, 2)
    # a gap beyond this changes neither the capped clearance nor admissibility at any speed of the window
    v_top = float(np.max(cand.v_cm_s))  # v * v, not v ** 2: pow is the C library's (portable numerics)
    reach = max(config.clearance_cap_cm, config.margin_cm + v_top * v_top / (2.0 * config.decel_cm_s2))
    static_gap, static_near = _static_gaps(path, cand.v_cm_s > 0, points, robot_radius, reach)
    track_gap, track_near = _track_gaps(path, tracks, robot_radius, dt)
    gap = np.minimum(static_gap, track_gap)
    approached = np.minimum(static_near, track_near)
    stop_speed = np.sqrt(2.0 * np.maximum(approached - config.margin_cm, 0.0) * config.decel_cm_s2)
    admissible = (gap >= config.margin_cm) & (cand.v_cm_s <= stop_speed)
    moving = admissible & (cand.v_cm_s > 0)
    chosen_from = moving if moving.any() else admissible

    end = path[:, -1]
    to_goal_x, to_goal_y = goal[0] - end[:, 0], goal[1] - end[:, 1]
    off = np.abs(angle_difference_deg(atan2_deg_array(to_goal_y, to_goal_x), heading))
    arrived = norm2(end - np.asarray(goal, dtype=float)) <= _ARRIVED_CM
    heading_raw = (180.0 - np.where(arrived, 0.0, off)) / 180.0
    clearance_cm = np.minimum(gap, config.clearance_cap_cm)

    h = _normalised(heading_raw, chosen_from)
    c = _normalised(clearance_cm, chosen_from)
    v = _normalised(cand.v_cm_s, chosen_from)
    score = np.where(chosen_from,
                     config.alpha_heading * h + config.beta_clearance * c + config.gamma_velocity * v, 0.0)
    return Evaluation(cand, clearance_cm, admissible, chosen_from, h, c, v, score)


def best_index(ev: Evaluation) -> int | None:
    """Index of the chosen candidate: the highest score among those it is chosen from; exact ties to the smaller
    |dθ|, then the higher speed, then the negative (rightward) dθ. ``None`` when none is admissible."""
    idx = np.nonzero(ev.chosen_from)[0]
    if len(idx) == 0:
        return None
    dtheta, v = ev.candidates.dtheta_deg[idx], ev.candidates.v_cm_s[idx]
    order = np.lexsort((dtheta, -v, np.abs(dtheta), -ev.score[idx]))  # last key is the primary one
    return int(idx[order[0]])


def dwa_action(observation: Observation, config: DWAConfig, context: PolicyContext) -> Action:
    """The command of one step: the best admissible candidate (mode ``dwa``), or stand still (``dwa_stop``)
    when none is admissible. ``fields``: the chosen candidate's normalised heading, clearance and velocity
    terms, its score, its gap capped at ``clearance_cap_cm`` (cm; the largest over all candidates for
    ``dwa_stop``), and the numbers of admissible and of all candidates."""
    s = observation.state
    ev = evaluate(s, observation.goal, observation.tracks, observation.static_points, config, context.limits,
                  context.robot_radius, context.dt)
    k = best_index(ev)
    counts = {"admissible": int(np.count_nonzero(ev.admissible)), "candidates": len(ev.score)}
    if k is None:
        return Action("dwa_stop", 0.0, 0.0, {"heading": 0.0, "clearance": 0.0, "velocity": 0.0, "score": 0.0,
                                            "clearance_cm": float(np.max(ev.clearance_cm)), **counts})
    return Action("dwa", float(ev.candidates.dtheta_deg[k]), float(ev.candidates.v_cm_s[k]),
                  {"heading": float(ev.heading[k]), "clearance": float(ev.clearance[k]),
                   "velocity": float(ev.velocity[k]), "score": float(ev.score[k]),
                   "clearance_cm": float(ev.clearance_cm[k]), **counts})


@register_policy("dwa")
class DWAPolicy:
    """The Dynamic Window Approach (see the module docstring)."""

    name = "dwa"
    config_class = DWAConfig

    def __init__(self, params: Mapping[str, Any], context: PolicyContext) -> None:
        self.config: DWAConfig = from_dict(DWAConfig, params, "navigator")
        if self.config.accel_cm_s2 * context.dt < context.limits.v_min:
            raise ValueError(f"navigator.accel_cm_s2: {self.config.accel_cm_s2} cm/s² cannot reach the robot's "
                             f"v_min ({context.limits.v_min} cm/s) from rest in one step of {context.dt} s")
        self.context = context

    def reset(self, seed: int) -> None:
        """Nothing to forget: the last speed comes with each observation, and the policy draws no random
        numbers."""

    def act(self, observation: Observation) -> Action:
        return dwa_action(observation, self.config, self.context)
