"""``orca`` pedestrians: each one chooses its velocity by Optimal Reciprocal Collision Avoidance (van den Berg,
Guy, Lin & Manocha 2011), the crowd model of CrowdNav and SocNavGym — with the half-planes and the linear program
of the robot's ORCA policy (:mod:`fuzzynav.numerics.orca_lp`: one implementation of the method).

Per pedestrian and substep (RVO2's ``Agent::computeNeighbors`` / ``computeNewVelocity``):

- preferred velocity: its intent (:mod:`fuzzynav.pedestrians.intent`);
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
Units: cm, s, cm/s. Pure Python arithmetic in a fixed order: the same on every CPU. With the optional compiled
kernel (``fuzzynav.pedestrians._orca``, off with ``FUZZYNAV_KERNEL=python``) one C call per substep computes every
pedestrian's velocity with the same operations in the same order: the same bits.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from fuzzynav.numerics import compiled, orca_lp
from fuzzynav.numerics.geometry import away_from_static, keep_inside
from fuzzynav.numerics.orca_lp import Line, choose_velocity, orca_line, static_point_line
from fuzzynav.numerics.portable_math import hypot, norm2
from fuzzynav.pedestrians.base import CrowdView, in_range, register_obstacle_model, substeps
from fuzzynav.pedestrians.intent import Intent

if TYPE_CHECKING:
    from fuzzynav.scenarios.scenario import DynamicObstacle
    from fuzzynav.scenarios.world import World

_kernel = compiled.load("fuzzynav.pedestrians._orca")
if _kernel is not None:
    # the linear program's tolerances have one definition, fuzzynav.numerics.orca_lp's
    _kernel.set_constants(orca_lp._PARALLEL, orca_lp._SLACK_REL, orca_lp._SLACK_ABS)


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
        use_kernel = _kernel is not None and not compiled.switched_off()
        for k in range(n_sub):
            pref = self.intent.preferred(x)
            pos_all = np.vstack([x, o_pos0 + o_vel * (k * h)])
            vel_all = np.vstack([v, o_vel])
            rad_all = np.concatenate([self.radii, o_rad])
            share = [0.5] * n + o_share
            if use_kernel:
                new_v = self._substep_compiled(x, pos_all, vel_all, rad_all, share, v, pref, max_speed, view.world,
                                               h)
            else:
                new_v = self._substep_python(x, pos_all, vel_all, rad_all, share, v, pref, max_speed, view.world, h)
            # the walls are hard constraints of the linear program, which a speed above what the horizon covers
            # can still overshoot in one substep: the walls are solid
            x, v = keep_inside(x + new_v * h, new_v, self.radii, view.world.bounds)
        self.x, self.v = x, v
        return x.copy(), v.copy()

    def _substep_python(self, x: np.ndarray, pos_all: np.ndarray, vel_all: np.ndarray, rad_all: np.ndarray,
                        share: list[float], v: np.ndarray, pref: np.ndarray, max_speed: np.ndarray, world: World,
                        h: float, only: Sequence[int] | None = None, out: np.ndarray | None = None) -> np.ndarray:
        """The new velocities (n, 2) cm/s of the own pedestrians at ``x`` (n, 2) cm moving at ``v`` (n, 2) cm/s
        (the reference path): everyone's positions ``pos_all`` (m, 2) cm, velocities ``vel_all`` (m, 2) cm/s,
        radii ``rad_all`` (m,) cm and shares of the avoidance ``share`` (m,), own pedestrians first; preferred
        velocities ``pref`` (n, 2) and speed limits ``max_speed`` (n,) cm/s; the walls, edges and circles of
        ``world``; the substep ``h`` (s). With ``only``, just those pedestrians, into ``out``."""
        c = self.config
        gaps, away = away_from_static(x, world.segments, world.circles)
        near = self._neighbours(x, pos_all)
        reach = c.time_horizon_obst_s * max_speed + self.radii
        close = (gaps - self.radii[:, None]) < reach[:, None]
        rel = pos_all[None, :, :] - x[:, None, :]
        return self._velocities_python(v, pref, max_speed, rel, vel_all, rad_all, share, gaps, away, close, near, h,
                                       only, out)

    def _substep_compiled(self, x: np.ndarray, pos_all: np.ndarray, vel_all: np.ndarray, rad_all: np.ndarray,
                          share: list[float], v: np.ndarray, pref: np.ndarray, max_speed: np.ndarray,
                          world: World, h: float) -> np.ndarray:
        """:meth:`_substep_python` (same arguments and units) in one call of the compiled kernel — the neighbours,
        the walls', edges' and circles' gaps and directions, the statics within reach and every pedestrian's
        velocity, with the same operations in the same order: the same bits. A pedestrian for which the Python
        path would raise (a division by zero) is flagged by the kernel and recomputed by the Python path, which
        raises the same error."""
        c = self.config
        f64 = np.float64
        new_v = np.empty((len(x), 2), dtype=f64)
        bad = np.zeros(len(x), dtype=bool)
        n_bad = _kernel.substep(
            float(c.neighbor_dist_cm), c.max_neighbors, float(c.time_horizon_obst_s), float(c.time_horizon_s),
            float(h), np.ascontiguousarray(x, dtype=f64), np.ascontiguousarray(pos_all, dtype=f64),
            np.ascontiguousarray(vel_all, dtype=f64), np.ascontiguousarray(rad_all, dtype=f64),
            np.asarray(share, dtype=f64), np.ascontiguousarray(v, dtype=f64), np.ascontiguousarray(pref, dtype=f64),
            np.ascontiguousarray(max_speed, dtype=f64),
            np.ascontiguousarray(world.segments, dtype=f64).reshape(-1, 4),
            np.ascontiguousarray(world.circles, dtype=f64).reshape(-1, 3), new_v, bad)
        if n_bad:
            self._substep_python(x, pos_all, vel_all, rad_all, share, v, pref, max_speed, world, h,
                                 only=np.flatnonzero(bad).tolist(), out=new_v)
        return new_v

    def _velocities_python(self, v: np.ndarray, pref: np.ndarray, max_speed: np.ndarray, rel: np.ndarray,
                           vel_all: np.ndarray, rad_all: np.ndarray, share: list[float], gaps: np.ndarray,
                           away: np.ndarray, close: np.ndarray, near: list[list[int]], h: float,
                           only: Sequence[int] | None = None, out: np.ndarray | None = None) -> np.ndarray:
        """The new velocities (n, 2) cm/s of the own pedestrians moving at ``v`` (n, 2) cm/s, by :meth:`_velocity`
        (the reference): ``pref`` (n, 2) cm/s preferred velocities, ``max_speed`` (n,) cm/s, ``rel`` (n, m, 2) cm
        everyone's positions relative to each own pedestrian, ``vel_all`` (m, 2) cm/s, ``rad_all`` (m,) cm,
        ``share`` (m,) the responsibilities, ``gaps`` (n, K) cm and ``away`` (n, K, 2) the walls', edges' and
        circles' distances and unit directions away from them, ``close`` (n, K) the ones within reach, ``near``
        the neighbours' indices, ``h`` the substep (s). With ``only``, just those pedestrians, into ``out``."""
        # every pedestrian's inputs as Python floats at once (the same values): indexing numpy element by element
        # inside the per-pedestrian loop would cost more than the loop's own arithmetic
        rows = _Rows(rel, vel_all, rad_all, gaps, away)
        close_rows = close.tolist()
        new_v = np.empty_like(v) if out is None else out
        v_rows, pref_rows, top_rows = v.tolist(), pref.tolist(), max_speed.tolist()
        for i in range(len(v_rows)) if only is None else only:
            statics = [k for k, ok in enumerate(close_rows[i]) if ok]
            new_v[i] = self._velocity(i, v_rows[i], pref_rows[i], top_rows[i], statics, near[i], rows, share, h)
        return new_v

    def _velocities_compiled(self, v: np.ndarray, pref: np.ndarray, max_speed: np.ndarray, rel: np.ndarray,
                             vel_all: np.ndarray, rad_all: np.ndarray, share: list[float], gaps: np.ndarray,
                             away: np.ndarray, close: np.ndarray, near: list[list[int]], h: float) -> np.ndarray:
        """:meth:`_velocities_python` (same arguments and units) in one call of the compiled kernel: the same
        bits. The kernel's velocity part alone, for given statics and neighbour lists (:meth:`_substep_compiled`
        computes those too, and is what :meth:`step` uses): the tests drive it with arbitrary ones. A
        pedestrian for which the Python path would raise (a division by zero) is flagged by the kernel and
        recomputed by the Python path, which raises the same error."""
        c = self.config
        n = len(v)
        # the neighbour lists padded to one (n, max_neighbors) array, with their lengths
        near_arr = np.zeros((n, c.max_neighbors), dtype=np.int64)
        counts = np.zeros(n, dtype=np.int64)
        for i, row in enumerate(near):
            near_arr[i, :len(row)] = row
            counts[i] = len(row)
        f64 = np.float64
        new_v = np.empty((n, 2), dtype=f64)
        bad = np.zeros(n, dtype=bool)
        n_bad = _kernel.velocities(
            float(c.time_horizon_obst_s), float(c.time_horizon_s), float(h),
            np.ascontiguousarray(v, dtype=f64), np.ascontiguousarray(pref, dtype=f64),
            np.ascontiguousarray(max_speed, dtype=f64), np.ascontiguousarray(rel, dtype=f64),
            np.ascontiguousarray(vel_all, dtype=f64), np.ascontiguousarray(rad_all, dtype=f64),
            np.asarray(share, dtype=f64), np.ascontiguousarray(gaps, dtype=f64), np.ascontiguousarray(away, dtype=f64),
            np.ascontiguousarray(close, dtype=bool), near_arr, counts, new_v, bad)
        if n_bad:
            self._velocities_python(v, pref, max_speed, rel, vel_all, rad_all, share, gaps, away, close, near, h,
                                    only=np.flatnonzero(bad).tolist(), out=new_v)
        return new_v

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
