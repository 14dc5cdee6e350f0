"""``orca``: Optimal Reciprocal Collision Avoidance (van den Berg, Guy, Lin & Manocha 2011, "Reciprocal n-body
collision avoidance", Robotics Research (ISRR 2009), Springer STAR 70) for the robot alone, written from the
paper and the algorithm of its authors' RVO2 library (``Agent::computeNewVelocity``, ``linearProgram1/2/3``).

Each step the policy chooses a velocity (cm/s, world frame) and turns it into the robot's command:

1. **Preferred velocity**: towards the goal at ``pref_speed_cm_s``, at most what lands on the goal in one
   step (as :mod:`fuzzynav.policies.direct`).
2. **ORCA half-planes** in velocity space, one per obstacle (paper, Sec. 4–5). With ``p`` the obstacle's
   position relative to the robot, ``r`` the robot's radius plus the obstacle's plus ``margin_cm``, ``τ``
   the time horizon and ``v`` the robot's current velocity (last speed along the heading), the velocity
   obstacle VO^τ is the truncated cone of relative velocities that hit the disc of radius ``r`` around
   ``p`` within ``τ``. ``u`` is the shortest vector from the current relative velocity to the boundary of
   VO^τ and ``n`` that boundary's outward normal; the permitted set is ``{v' : (v' − (v + ρ·u))·n ≥ 0}``.

   - *Moving obstacles* (tracks, velocity ``v_o``; relative velocity ``v − v_o``; ``τ = time_horizon_s``).
     The paper's ``ρ = ½`` (each of two agents takes half the avoidance) assumes the other side runs ORCA
     too. The pedestrians here are scripted and never react, so the default ``reciprocity = 1`` takes the
     full avoidance (the velocity obstacle linearised at the current velocity); ``0.5`` gives the paper's
     reciprocal share, which leaves half of every avoidance undone against non-reactive obstacles.
   - *Static obstacles*: each static laser return is a point (radius 0) with zero velocity, full
     responsibility, ``τ = time_horizon_obst_s`` (RVO2's ``timeHorizonObst``), in place of RVO2's polygon
     edges (the robot senses points, not polygons; a wall is a row of returns a few cm apart, narrower than
     the robot, so the row of discs closes it). Only returns nearer than ``τ_obst·v_max + r`` are used,
     RVO2's obstacle neighbour range (those whose VO can meet the speed disc; a farther return's half-plane
     can still cut the disc, in RVO2 as here); of these the ``max_static_points`` nearest are used (ties:
     the earlier return), which bounds the work per step.
   - *Which tracks*: every track adds its half-plane, nearest first — RVO2's neighbour rule
     (``Agent::computeNeighbors``: the ``maxNeighbors`` nearest agents within ``neighborDist``, each of
     which adds its ORCA line) with both bounds open, since the laser's range already bounds the tracks
     and there are few of them. A far track is not dropped because its VO cannot meet the speed disc: the half-plane is
     placed at ``v + ρ·u``, not on the VO, so with ``ρ < 1`` it lies between the current velocity and the
     VO and still binds (a walker 401 cm ahead closing at 30 cm/s limits a robot at rest to 20.1 cm/s at
     ``ρ = 0.5``, as in RVO2; ``docs/policies.md``).
   - *Overlap* (already within ``r``; the margin makes this possible without contact): as RVO2, the cut-off
     circle of the time step ``dt`` replaces that of ``τ`` for tracks, so the robot leaves the overlap
     within one step; for a static return the half-plane is RVO2's obstacle rule, "do not move towards
     it" (the line through the origin perpendicular to ``p``).
3. **Linear program** (paper Sec. 5.2, RVO2's ``linearProgram2``): the velocity inside the disc of radius
   ``v_max`` closest to the preferred velocity that satisfies every half-plane, by the incremental algorithm
   (each violated constraint re-solves a 1-D program on its line). The paper shuffles the constraints to
   get expected linear time; here their order is fixed (static returns nearest first, then tracks nearest
   first; ties by input order) so that a decision never depends on random numbers — with a few dozen lines
   the worst case is still cheap, and the optimum (unique: the objective is strictly convex) does not
   depend on the order beyond rounding.
4. **Fallback** when the half-planes and the speed disc have no common point (dense traffic): RVO2's 3-D
   program (``linearProgram3``) over (velocity, penetration) finds the velocity that minimises the largest
   penetration ``δ*`` (cm/s) into the tracks' half-planes, the static ones kept hard (zero velocity
   satisfies all of them, so they are always feasible together). RVO2 then keeps whatever extreme point
   that program ends on, which can be far from the preferred velocity (e.g. full speed backwards); here a
   second 2-D program picks, among the velocities of penetration at most ``δ*``, the one closest to the
   preferred velocity (the soft lines moved out by ``δ*``). Mode ``orca_fallback``.
5. **Command** (the robot turns by ``dθ`` and then moves straight for ``dt``, so a velocity within its turn
   limit is reached exactly in one step): ``dθ`` = the velocity's bearing − heading; ``v`` = its length
   clamped to ``[v_min, v_max]``. Beyond the turn limit the robot turns fully and drives the component of
   the velocity along its new heading (the part of the chosen motion it can make). A speed below
   ``v_min / 2`` (the nearer of 0 and ``v_min``) means stand still, turned towards the chosen velocity, or
   towards the goal when that velocity is exactly 0.

Known limitation (a property of the method, not of this implementation): ORCA is local. With the goal
straight behind a wall the velocity closest to the preferred one shrinks to 0 in front of the wall and the
robot stands there, keeping its margin; sliding along a wall towards a goal beyond it, the component along
the wall can drop below ``v_min / 2`` and the robot stops too (``tests/test_orca.py`` shows the first). A
detour is the job of the Trajectory Prediction Table's layer or of a global planner on top.

Fields: ``lines`` (number of ORCA half-planes), ``fallback`` (1 when the 3-D program ran, else 0),
``vx_cm_s``/``vy_cm_s`` (the chosen velocity), ``penetration_cm_s`` (δ*, 0 without fallback).
The sonar readings are not used: the laser's static returns cover the sonar's sectors and more.
Parameters (``conf/navigator/orca.yaml``): :class:`OrcaConfig`. Units: cm, s, degrees, cm/s.
Numerics are portable: plain Python floats, ``+ − × /`` and ``sqrt`` in a fixed order, the angles from
:mod:`fuzzynav.numerics.portable_math`; the only numpy used selects the nearest returns (elementwise, stable sort).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from fuzzynav.kinematics import RobotLimits
from fuzzynav.numerics.geometry import wrap_180
from fuzzynav.numerics.orca_lp import Line, Vec, choose_velocity, orca_line, static_point_line
from fuzzynav.numerics.portable_math import atan2_deg, bearing_deg, dist, hypot, norm2, sin_cos_deg
from fuzzynav.params.limits import MAX_SPEED_CM_S, WHY_MARGIN, WHY_SPEED, Range, ranged
from fuzzynav.params.parsing import from_dict
from fuzzynav.policies.base import Action, Observation, PolicyContext, register_policy
from fuzzynav.sensing.tracking import Track


@dataclass(frozen=True)
class OrcaConfig:
    """ORCA's parameters (see the module docstring); units in the names."""

    # chosen: the speed of the direct baseline and of the paper's navigator in open space (25 cm/s), so the
    # policies differ in avoidance, not in cruising speed; the speed disc is the robot's v_max (40 cm/s)
    pref_speed_cm_s: float = ranged(25.0, Range(0, MAX_SPEED_CM_S, "cm/s", "ORCA: " + WHY_SPEED, lo_open=True),
                                    robot_speed=True)
    # τ for tracks, chosen 5 s (CrowdNav's ORCA baseline uses 5 s at comparable pedestrian speeds): a head-on
    # obstacle at the laser's 250 cm range closes at up to 80 cm/s and is reached in about 3 s, so it is
    # inside the horizon as soon as it is seen
    time_horizon_s: float = ranged(5.0, Range(0, 600, "s", "ORCA: τ for tracks", lo_open=True))
    # τ_obst for static returns, chosen 2 s (two decisions): at 40 cm/s the robot then needs 80 cm of free
    # space ahead, enough to turn away next step, while corridors a little wider than the robot stay open
    time_horizon_obst_s: float = ranged(2.0, Range(0, 600, "s", "ORCA: τ for static returns", lo_open=True))
    # ρ: share of each avoidance the robot takes; 1 because the scripted pedestrians do not reciprocate
    # (the paper's 0.5 is for two ORCA agents); must be in [0.5, 1]
    reciprocity: float = ranged(1.0, Range(0.5, 1, "", "ORCA: share of each avoidance the robot takes"))
    # chosen: 10 cm, the planner's safety_margin_cm and DWA's margin (tracks are estimates, a few cm off)
    margin_cm: float = ranged(10.0, Range(0, 1_000, "cm", WHY_MARGIN))
    # chosen: 32 nearest returns (a 1.6 m arc at the 5 cm spacing of a wall), bounding the linear program
    max_static_points: int = ranged(32, Range(0, 1_000, "", "ORCA: static constraints per decision", integer=True))

    def __post_init__(self) -> None:
        for name in ("pref_speed_cm_s", "time_horizon_s", "time_horizon_obst_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"navigator.{name}: must be a finite number > 0, got {value}")
        if not 0.5 <= self.reciprocity <= 1.0:
            raise ValueError(f"navigator.reciprocity: must be in [0.5, 1] (1 = full responsibility, "
                             f"0.5 = the paper's reciprocal share), got {self.reciprocity}")
        if not (math.isfinite(self.margin_cm) and self.margin_cm >= 0):
            raise ValueError(f"navigator.margin_cm: must be a finite number >= 0, got {self.margin_cm}")
        if self.max_static_points < 0:
            raise ValueError(f"navigator.max_static_points: must be >= 0, got {self.max_static_points}")


def nearest_static_points(points: np.ndarray, x: float, y: float, reach_cm: float, limit: int) -> np.ndarray:
    """The at most ``limit`` static returns (world, cm) nearer than ``reach_cm`` to (x, y), nearest first
    (ties in input order)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    d = norm2(pts - np.array([x, y]))
    order = np.argsort(d, kind="stable")
    order = order[d[order] < reach_cm][:limit]
    return pts[order]


def orca_lines(x: float, y: float, velocity: Vec, tracks: Sequence[Track], static_points: np.ndarray,
               config: OrcaConfig, robot_radius: float, v_max: float, dt: float) -> tuple[tuple[Line, ...], int]:
    """(the half-planes, how many of them are static) for a robot at (x, y) (cm) moving at ``velocity``
    (cm/s): the nearest static returns within reach first, then every track, nearest first (ties in input
    order; module docstring, step 2)."""
    reach = config.time_horizon_obst_s * v_max + robot_radius + config.margin_cm
    static = nearest_static_points(static_points, x, y, reach, config.max_static_points)
    r_static = robot_radius + config.margin_cm
    lines: list[Line] = []
    for px, py in static.tolist():
        line = static_point_line((px - x, py - y), r_static, config.time_horizon_obst_s, dt, velocity)
        if line is not None:
            lines.append(line)
    hard = len(lines)
    # RVO2 adds the line of every neighbour: one whose VO cannot meet the speed disc still binds at ρ < 1
    neighbours = []
    for index, t in enumerate(tracks):
        rel = (t.x - x, t.y - y)
        neighbours.append((hypot(rel[0], rel[1]), index, rel, robot_radius + t.radius + config.margin_cm, t))
    for _, _, rel, r, t in sorted(neighbours, key=lambda item: (item[0], item[1])):
        lines.append(orca_line(rel, (velocity[0] - t.vx, velocity[1] - t.vy), r, config.time_horizon_s, dt,
                               config.reciprocity, velocity))
    return tuple(lines), hard


def preferred_velocity(x: float, y: float, goal: tuple[float, float], speed_cm_s: float, dt: float) -> Vec:
    """Towards the goal at ``speed_cm_s`` (cm/s), at most what lands on it in one step of ``dt`` (s)."""
    to_goal = dist((x, y), goal)
    if to_goal == 0.0:
        return 0.0, 0.0
    speed = min(speed_cm_s, to_goal / dt)
    return (goal[0] - x) * speed / to_goal, (goal[1] - y) * speed / to_goal


def velocity_command(velocity: Vec, heading_deg: float, goal_bearing_deg: float,
                     limits: RobotLimits) -> tuple[float, float]:
    """(steering increment in degrees, speed in cm/s) that realises ``velocity`` (cm/s) for a robot heading
    ``heading_deg`` that turns and then moves straight (module docstring, step 5)."""
    speed = hypot(velocity[0], velocity[1])
    if speed == 0.0:
        return wrap_180(goal_bearing_deg - heading_deg), 0.0
    dtheta = wrap_180(atan2_deg(velocity[1], velocity[0]) - heading_deg)
    if abs(dtheta) > limits.max_turn_deg:
        turned = math.copysign(limits.max_turn_deg, dtheta)
        # the component of the velocity along the heading the robot can reach this step
        speed = speed * sin_cos_deg(dtheta - turned)[1]
        dtheta = turned
    if speed < 0.5 * limits.v_min:
        return dtheta, 0.0
    return dtheta, max(limits.v_min, min(limits.v_max, speed))


def orca_action(observation: Observation, config: OrcaConfig, context: PolicyContext) -> Action:
    """The command of one step (mode ``orca``, or ``orca_fallback`` when the half-planes had no common
    point), with the fields of the module docstring."""
    s, lim = observation.state, context.limits
    sin, cos = sin_cos_deg(s.heading)
    velocity = (s.v * cos, s.v * sin)
    lines, hard = orca_lines(s.x, s.y, velocity, observation.tracks, observation.static_points, config,
                             context.robot_radius, lim.v_max, context.dt)
    preferred = preferred_velocity(s.x, s.y, observation.goal, config.pref_speed_cm_s, context.dt)
    result = choose_velocity(lines, hard, lim.v_max, preferred)
    dtheta, v = velocity_command(result.velocity, s.heading, bearing_deg(s.x, s.y, *observation.goal), lim)
    return Action("orca_fallback" if result.fallback else "orca", dtheta, v,
                  {"lines": len(lines), "fallback": 1.0 if result.fallback else 0.0,
                   "vx_cm_s": result.velocity[0], "vy_cm_s": result.velocity[1],
                   "penetration_cm_s": result.penetration_cm_s})


@register_policy("orca")
class OrcaPolicy:
    """Optimal Reciprocal Collision Avoidance for the robot (see the module docstring)."""

    name = "orca"
    config_class = OrcaConfig

    def __init__(self, params: Mapping[str, Any], context: PolicyContext) -> None:
        self.config: OrcaConfig = from_dict(OrcaConfig, params, "navigator")
        self.context = context

    def reset(self, seed: int) -> None:
        """Nothing to forget: the current velocity comes with each observation, and the policy draws no
        random numbers."""

    def act(self, observation: Observation) -> Action:
        return orca_action(observation, self.config, self.context)
