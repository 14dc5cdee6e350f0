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
            near = self._neighbours(x, pos_all)
            # every pedestrian's inputs as Python floats at once (the same values): indexing numpy element by element
            # inside the per-pedestrian loop would cost more than the loop's own arithmetic
            reach = c.time_horizon_obst_s * max_speed + self.radii
            close = ((gaps - self.radii[:, None]) < reach[:, None]).tolist()
            rows = _Rows(pos_all[None, :, :] - x[:, None, :], vel_all, rad_all, gaps, away)
            new_v = np.empty_like(v)
            for i, (vi, pi, top) in enumerate(zip(v.tolist(), pref.tolist(), max_speed.tolist(), strict=True)):
                statics = [k for k, ok in enumerate(close[i]) if ok]
                new_v[i] = self._velocity(i, vi, pi, top, statics, near[i], rows, share, h)
            # the walls are hard constraints of the linear program, which a speed above what the horizon covers
            # can still overshoot in one substep: the walls are solid
            x, v = keep_inside(x + new_v * h, new_v, self.radii, view.world.bounds)
        self.x, self.v = x, v
        return x.copy(), v.copy()

    def _neighbours(self, x: np.ndarray, pos_all: np.ndarray) -> list[list[int]]:
        """For each own pedestrian, the indices into ``pos_all`` of its ``max_neighbors`` nearest others within
        ``neighbor_dist_cm``, nearest first (a stable sort: equal distances keep their order)."""
        c = self.config
        n = len(x)
        d = norm2(pos_all[None, :, :] - x[:, None, :])
        d[np.arange(n), np.arange(n)] = math.inf  # not itself
        order = np.argsort(d, axis=1, kind="stable")
        within = (np.take_along_axis(d, order, axis=1) < c.neighbor_dist_cm).tolist()
        return [[j for j, ok in zip(row, inside, strict=True) if ok][:c.max_neighbors]
                for row, inside in zip(order.tolist(), within, strict=True)]

    def _velocity(self, i: int, vi: list[float], pref: list[float], max_speed: float, statics: list[int],
                  near: list[int], rows: _Rows, share: list[float], h: float) -> tuple[float, float]:
        """The new velocity (cm/s) of own pedestrian ``i`` moving at ``vi``: ``statics`` are the walls, edges and
        circles within its reach, ``near`` its neighbours (indices into ``rows``)."""
        c = self.config
        velocity = (vi[0], vi[1])
        r = rows.radii[i]
        lines: list[Line] = []
        gaps, away = rows.gaps[i], rows.away[i]
        for k in statics:
            # the nearest point of the edge or rim, relative to the pedestrian (cm)
            g = gaps[k]
            rel = (-away[k][0] * g, -away[k][1] * g)
            line = static_point_line(rel, r, c.time_horizon_obst_s, h, velocity)
            if line is not None:
                lines.append(line)
        hard = len(lines)
        rel_row = rows.rel[i]
        for j in near:
            rel = (rel_row[j][0], rel_row[j][1])
            rel_vel = (velocity[0] - rows.vel[j][0], velocity[1] - rows.vel[j][1])
            lines.append(orca_line(rel, rel_vel, r + rows.radii[j], c.time_horizon_s, h, share[j], velocity))
        preferred = (pref[0], pref[1])
        speed = hypot(*preferred)
        if speed > max_speed:
            preferred = (preferred[0] * max_speed / speed, preferred[1] * max_speed / speed)
        return choose_velocity(lines, hard, max_speed, preferred).velocity


class _Rows:
    """One substep's inputs of :meth:`PedestrianOrcaModel._velocity` as Python floats: relative positions (n, m, 2)
    of everyone from each own pedestrian (cm), velocities (m, 2) cm/s and radii (m,) cm of everyone (own
    pedestrians first), and each own pedestrian's gaps (n, K) cm to the walls, edges and circles with the unit
    vectors (n, K, 2) pointing away from them."""

    def __init__(self, rel: np.ndarray, vel: np.ndarray, radii: np.ndarray, gaps: np.ndarray, away: np.ndarray) -> None:
        self.rel, self.vel, self.radii = rel.tolist(), vel.tolist(), radii.tolist()
        self.gaps, self.away = gaps.tolist(), away.tolist()
