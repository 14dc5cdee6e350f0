"""``orca`` pedestrians: each one chooses its velocity by Optimal Reciprocal Collision Avoidance (van den Berg,
Guy, Lin & Manocha 2011), the crowd model of CrowdNav and SocNavGym — with the half-planes and the linear program
of the robot's ORCA policy (:mod:`fuzzynav.orca`: one implementation of the method).

Per pedestrian and substep (RVO2's ``Agent::computeNeighbors`` / ``computeNewVelocity``):

- preferred velocity: its intent (:mod:`fuzzynav.pedestrian_intent`);
- one half-plane per neighbour — the ``max_neighbors`` nearest other moving obstacles within
  ``neighbor_dist_cm`` (and the robot when ``sees_robot``), time horizon ``time_horizon_s``. Pedestrians of the
  same ``orca`` group take half of each avoidance (the paper's reciprocity: the other one takes the other half);
  against anything else (scripted obstacles, pedestrians of other models) they take it all, and against the
  robot ``robot_responsibility`` (0.5, as CrowdNav's humans, assumes the robot avoids them too);
- one hard half-plane per wall, polygon edge and static circle within reach (its nearest point as a disc of
  radius 0, horizon ``time_horizon_obst_s``), the robot policy's rule for static returns;
- the velocity in the disc of ``max_speed_factor``·(its walking speed) nearest the preferred one.

All pedestrians of a substep choose from the same state (as RVO2: compute all, then update all). Integration:
substeps of at most ``substep_s`` (RVO2's time step); positions advance with the chosen velocity.
Units: cm, s, cm/s. Pure Python arithmetic in a fixed order: the same on every CPU.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fuzzynav.geometry import away_from_static, keep_inside
from fuzzynav.obstacle_model import CrowdView, in_range, register_obstacle_model, substeps
from fuzzynav.orca import Line, choose_velocity, orca_line, static_point_line
from fuzzynav.pedestrian_intent import Intent
from fuzzynav.portable_math import hypot, norm2
from fuzzynav.scenario import DynamicObstacle


@dataclass(frozen=True)
class PedestrianOrcaConfig:
    """RVO2's agent parameters (cm, s), defaults as CrowdNav's ORCA humans (converted from metres)."""

    neighbor_dist_cm: float = 1_000.0
    max_neighbors: int = 10
    time_horizon_s: float = 5.0
    time_horizon_obst_s: float = 5.0
    max_speed_factor: float = 1.0  # the speed disc's radius over the walking speed
    robot_responsibility: float = 0.5
    sees_robot: bool = True
    substep_s: float = 0.25
    arrive_cm: float = 30.0

    def __post_init__(self) -> None:
        in_range(self.neighbor_dist_cm, "neighbor_dist_cm", 0, 100_000, "cm")
        in_range(self.max_neighbors, "max_neighbors", 0, 100)
        in_range(self.time_horizon_s, "time_horizon_s", 0, 600, "s", lo_open=True)
        in_range(self.time_horizon_obst_s, "time_horizon_obst_s", 0, 600, "s", lo_open=True)
        in_range(self.max_speed_factor, "max_speed_factor", 1, 10)
        in_range(self.robot_responsibility, "robot_responsibility", 0.5, 1)
        in_range(self.substep_s, "substep_s", 0.01, 10, "s")
        in_range(self.arrive_cm, "arrive_cm", 0, 10_000, "cm", lo_open=True)


@register_obstacle_model("orca")
class PedestrianOrcaModel:
    """The pedestrians of one ``orca`` group (module docstring)."""

    config_class = PedestrianOrcaConfig

    def __init__(self, obstacles: Sequence[DynamicObstacle], config: PedestrianOrcaConfig) -> None:
        self.config = config
        self.intent = Intent(obstacles, config.arrive_cm)
        self.radii = np.array([o.radius for o in obstacles], dtype=float)
        self.x = self.intent.starts.copy()
        self.v = np.zeros_like(self.x)

    def reset(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        self.intent.reset()
        self.x = self.intent.starts.copy()
        self.v = self.intent.initial_velocities()
        return self.x.copy(), self.v.copy()

    def step(self, view: CrowdView, indices: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        n_sub, h = substeps(dt, c.substep_s)
        o_pos0, o_vel, o_rad = view.others(indices, c.sees_robot)
        # all of each avoidance against obstacles of other models, the robot's share against the robot (last)
        o_share = [1.0] * (len(o_pos0) - c.sees_robot) + [c.robot_responsibility] * c.sees_robot
        max_speed = c.max_speed_factor * self.intent.speeds
        x, v = self.x, self.v
        n = len(x)
        for k in range(n_sub):
            pref = self.intent.preferred(x)
            pos_all = np.vstack([x, o_pos0 + o_vel * (k * h)])
            vel_all = np.vstack([v, o_vel])
            rad_all = np.concatenate([self.radii, o_rad])
            share = [0.5] * n + o_share
            gaps, away = away_from_static(x, view.world.segments, view.world.circles)
            new_v = np.empty_like(v)
            for i in range(n):
                new_v[i] = self._velocity(i, x[i], v[i], pref[i], float(max_speed[i]), pos_all, vel_all, rad_all,
                                          share, gaps[i], away[i], h)
            # the walls are hard constraints of the linear program, which a speed above what the horizon covers
            # can still overshoot in one substep: the walls are solid
            x, v = keep_inside(x + new_v * h, new_v, self.radii, view.world.bounds)
        self.x, self.v = x, v
        return x.copy(), v.copy()

    def _velocity(self, i: int, xi: np.ndarray, vi: np.ndarray, pref: np.ndarray, max_speed: float,
                  pos_all: np.ndarray, vel_all: np.ndarray, rad_all: np.ndarray, share: list[float],
                  gaps: np.ndarray, away: np.ndarray, h: float) -> np.ndarray:
        """The new velocity (cm/s) of own pedestrian ``i`` at ``xi`` moving at ``vi``."""
        c = self.config
        velocity = (float(vi[0]), float(vi[1]))
        r = float(self.radii[i])
        lines: list[Line] = []
        reach = c.time_horizon_obst_s * max_speed + r
        for k in np.nonzero(gaps - r < reach)[0].tolist():
            # the nearest point of the edge or rim, relative to the pedestrian (cm)
            g = float(gaps[k])
            rel = (-float(away[k][0]) * g, -float(away[k][1]) * g)
            line = static_point_line(rel, r, c.time_horizon_obst_s, h, velocity)
            if line is not None:
                lines.append(line)
        hard = len(lines)
        rel_all = pos_all - xi
        d = norm2(rel_all)
        d[i] = math.inf
        order = np.argsort(d, kind="stable")
        near = order[d[order] < c.neighbor_dist_cm][:c.max_neighbors].tolist()  # nearest first, within reach
        # Python floats of the rows (the same values; indexing numpy element by element is what would cost)
        rel_rows, vel_rows, rad_list = rel_all.tolist(), vel_all.tolist(), rad_all.tolist()
        for j in near:
            rel = (rel_rows[j][0], rel_rows[j][1])
            rel_vel = (velocity[0] - vel_rows[j][0], velocity[1] - vel_rows[j][1])
            lines.append(orca_line(rel, rel_vel, r + rad_list[j], c.time_horizon_s, h, share[j], velocity))
        preferred = (float(pref[0]), float(pref[1]))
        speed = hypot(*preferred)
        if speed > max_speed:
            preferred = (preferred[0] * max_speed / speed, preferred[1] * max_speed / speed)
        result = choose_velocity(lines, hard, max_speed, preferred)
        return np.array(result.velocity)
