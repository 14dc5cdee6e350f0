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
- hard half-planes for the walls and static polygons (horizon ``time_horizon_obst_s``): RVO2's obstacle lines
  (:func:`fuzzynav.numerics.orca_lp.edge_lines`) for each edge the pedestrian faces within ``time_horizon_obst_s``
  · its top speed + its radius, nearest first — the velocity obstacle of the whole edge (end discs, legs,
  cut-off segment; convex and concave corners; the line through the origin when it already overlaps the edge),
  skipped where an earlier edge's line covers it. The walls are a polygon seen from inside (all four corners
  concave);
- one hard half-plane per static circle within reach: its nearest rim point as a disc of radius 0, the robot
  policy's rule for static returns;
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
from fuzzynav.numerics.orca_lp import (
    Line,
    ObstacleVertices,
    choose_velocity,
    edge_lines,
    obstacle_vertices,
    orca_line,
    static_point_line,
    world_chains,
)
from fuzzynav.numerics.portable_math import hypot, norm2
from fuzzynav.pedestrians.base import CrowdView, in_range, register_obstacle_model, substeps
from fuzzynav.pedestrians.intent import Intent

if TYPE_CHECKING:
    from fuzzynav.scenarios.scenario import DynamicObstacle
    from fuzzynav.scenarios.world import World

_kernel = compiled.load("fuzzynav.pedestrians._orca")
if _kernel is not None:
    # the linear program's tolerances have one definition, fuzzynav.numerics.orca_lp's
    _kernel.set_constants(orca_lp._PARALLEL, orca_lp._SLACK_REL, orca_lp._SLACK_ABS, orca_lp._COVERED)


class _Obstacles:
    """A world's walls and static polygons as RVO2's obstacle vertices (:class:`ObstacleVertices`, for the
    per-pedestrian lines) and as arrays (for the edges within reach, and the compiled kernel): ``points`` (V, 2)
    cm, ``directions`` (V, 2) unit vectors, ``next`` and ``previous`` (V,) vertex indices, ``convex`` (V,)."""

    def __init__(self, bounds: Sequence[float], polygons: Sequence[np.ndarray]) -> None:
        self.vertices = obstacle_vertices(world_chains(bounds, polygons))
        ov = self.vertices
        self.points = np.array(ov.points, dtype=np.float64).reshape(-1, 2)
        self.directions = np.array(ov.directions, dtype=np.float64).reshape(-1, 2)
        self.next = np.array(ov.next, dtype=np.int64)
        self.previous = np.array(ov.previous, dtype=np.int64)
        self.convex = np.array(ov.convex, dtype=bool)


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
        self._obstacles: tuple[World, _Obstacles] | None = None

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
        obstacles = self._obstacles_of(world)
        edges = self._edges_within_reach(obstacles, x, max_speed)
        gaps, away = away_from_static(x, np.zeros((0, 4)), world.circles)
        near = self._neighbours(x, pos_all)
        reach = c.time_horizon_obst_s * max_speed + self.radii
        close = (gaps - self.radii[:, None]) < reach[:, None]
        rel = pos_all[None, :, :] - x[:, None, :]
        return self._velocities_python(obstacles, x, v, pref, max_speed, rel, vel_all, rad_all, share, edges, gaps,
                                       away, close, near, h, only, out)

    def _obstacles_of(self, world: World) -> _Obstacles:
        """The walls and polygons of ``world`` as :class:`_Obstacles`, built once per world (a world is shared by
        the episodes of a scenario and does not change)."""
        if self._obstacles is None or self._obstacles[0] is not world:
            self._obstacles = (world, _Obstacles(world.bounds, world.polygons))
        return self._obstacles[1]

    def _edges_within_reach(self, obstacles: _Obstacles, x: np.ndarray, max_speed: np.ndarray) -> list[list[int]]:
        """For each own pedestrian at ``x`` (n, 2) cm, the edges (their first vertices' indices) it faces — strictly
        on their outer side — whose nearest point is within ``time_horizon_obst_s`` · ``max_speed`` (n,) cm/s + its
        radius (RVO2's obstacle range), nearest first (a stable sort: equal distances keep the vertices' order)."""
        a = obstacles.points[None, :, :]
        b = obstacles.points[obstacles.next][None, :, :]
        e = b - a
        x3 = x[:, None, :]
        to_a = a - x3
        # twice the signed area of (a, b, x): negative when x is right of the edge, outside the obstacle
        left = to_a[..., 0] * e[..., 1] - to_a[..., 1] * e[..., 0]
        from_a = x3 - a
        length_sq = e[..., 0] * e[..., 0] + e[..., 1] * e[..., 1]
        along = (from_a[..., 0] * e[..., 0] + from_a[..., 1] * e[..., 1]) / length_sq
        from_b = x3 - b
        foot = x3 - (a + along[..., None] * e)
        dist_sq = np.where(along < 0.0, from_a[..., 0] * from_a[..., 0] + from_a[..., 1] * from_a[..., 1],
                           np.where(along > 1.0, from_b[..., 0] * from_b[..., 0] + from_b[..., 1] * from_b[..., 1],
                                    foot[..., 0] * foot[..., 0] + foot[..., 1] * foot[..., 1]))
        reach = self.config.time_horizon_obst_s * max_speed + self.radii
        within = (left < 0.0) & (dist_sq < (reach * reach)[:, None])
        order = np.argsort(np.where(within, dist_sq, math.inf), axis=1, kind="stable")
        return [row[:count] for row, count in zip(order.tolist(), within.sum(axis=1).tolist(), strict=True)]

    def _substep_compiled(self, x: np.ndarray, pos_all: np.ndarray, vel_all: np.ndarray, rad_all: np.ndarray,
                          share: list[float], v: np.ndarray, pref: np.ndarray, max_speed: np.ndarray,
                          world: World, h: float) -> np.ndarray:
        """:meth:`_substep_python` (same arguments and units) in one call of the compiled kernel — the neighbours,
        the edges within reach, the circles' gaps and directions and every pedestrian's velocity, with the same
        operations in the same order: the same bits. A pedestrian for which the Python path would raise (a
        division by zero) is flagged by the kernel and recomputed by the Python path, which raises the same
        error."""
        c = self.config
        obstacles = self._obstacles_of(world)
        f64 = np.float64
        new_v = np.empty((len(x), 2), dtype=f64)
        bad = np.zeros(len(x), dtype=bool)
        n_bad = _kernel.substep(
            float(c.neighbor_dist_cm), c.max_neighbors, float(c.time_horizon_obst_s), float(c.time_horizon_s),
            float(h), np.ascontiguousarray(x, dtype=f64), np.ascontiguousarray(pos_all, dtype=f64),
            np.ascontiguousarray(vel_all, dtype=f64), np.ascontiguousarray(rad_all, dtype=f64),
            np.asarray(share, dtype=f64), np.ascontiguousarray(v, dtype=f64), np.ascontiguousarray(pref, dtype=f64),
            np.ascontiguousarray(max_speed, dtype=f64), obstacles.points, obstacles.directions, obstacles.next,
            obstacles.previous, obstacles.convex, np.ascontiguousarray(world.circles, dtype=f64).reshape(-1, 3),
            new_v, bad)
        if n_bad:
            self._substep_python(x, pos_all, vel_all, rad_all, share, v, pref, max_speed, world, h,
                                 only=np.flatnonzero(bad).tolist(), out=new_v)
        return new_v

    def _velocities_python(self, obstacles: _Obstacles, x: np.ndarray, v: np.ndarray, pref: np.ndarray,
                           max_speed: np.ndarray, rel: np.ndarray, vel_all: np.ndarray, rad_all: np.ndarray,
                           share: list[float], edges: list[list[int]], gaps: np.ndarray, away: np.ndarray,
                           close: np.ndarray, near: list[list[int]], h: float, only: Sequence[int] | None = None,
                           out: np.ndarray | None = None) -> np.ndarray:
        """The new velocities (n, 2) cm/s of the own pedestrians at ``x`` (n, 2) cm moving at ``v`` (n, 2) cm/s, by
        :meth:`_velocity` (the reference): ``obstacles`` the walls and polygons, ``pref`` (n, 2) cm/s preferred
        velocities, ``max_speed`` (n,) cm/s, ``rel`` (n, m, 2) cm everyone's positions relative to each own
        pedestrian, ``vel_all`` (m, 2) cm/s, ``rad_all`` (m,) cm, ``share`` (m,) the responsibilities, ``edges``
        each one's edges to avoid (vertex indices, nearest first), ``gaps`` (n, C) cm and ``away`` (n, C, 2) the
        static circles' distances and unit directions away from them, ``close`` (n, C) the ones within reach,
        ``near`` the neighbours' indices, ``h`` the substep (s). With ``only``, just those pedestrians, into
        ``out``."""
        # every pedestrian's inputs as Python floats at once (the same values): indexing numpy element by element
        # inside the per-pedestrian loop would cost more than the loop's own arithmetic
        rows = _Rows(x, rel, vel_all, rad_all, gaps, away)
        close_rows = close.tolist()
        new_v = np.empty_like(v) if out is None else out
        v_rows, pref_rows, top_rows = v.tolist(), pref.tolist(), max_speed.tolist()
        for i in range(len(v_rows)) if only is None else only:
            statics = [k for k, ok in enumerate(close_rows[i]) if ok]
            new_v[i] = self._velocity(i, v_rows[i], pref_rows[i], top_rows[i], obstacles.vertices, edges[i],
                                      statics, near[i], rows, share, h)
        return new_v

    def _velocities_compiled(self, obstacles: _Obstacles, x: np.ndarray, v: np.ndarray, pref: np.ndarray,
                             max_speed: np.ndarray, rel: np.ndarray, vel_all: np.ndarray, rad_all: np.ndarray,
                             share: list[float], edges: list[list[int]], gaps: np.ndarray, away: np.ndarray,
                             close: np.ndarray, near: list[list[int]], h: float) -> np.ndarray:
        """:meth:`_velocities_python` (same arguments and units) in one call of the compiled kernel: the same
        bits. The kernel's velocity part alone, for given statics and neighbour lists (:meth:`_substep_compiled`
        computes those too, and is what :meth:`step` uses): the tests drive it with arbitrary ones. A
        pedestrian for which the Python path would raise (a division by zero) is flagged by the kernel and
        recomputed by the Python path, which raises the same error."""
        c = self.config
        n = len(v)
        near_arr, counts = _padded(near, c.max_neighbors)
        edge_arr, edge_counts = _padded(edges, len(obstacles.points))
        f64 = np.float64
        new_v = np.empty((n, 2), dtype=f64)
        bad = np.zeros(n, dtype=bool)
        n_bad = _kernel.velocities(
            float(c.time_horizon_obst_s), float(c.time_horizon_s), float(h), np.ascontiguousarray(x, dtype=f64),
            np.ascontiguousarray(v, dtype=f64), np.ascontiguousarray(pref, dtype=f64),
            np.ascontiguousarray(max_speed, dtype=f64), np.ascontiguousarray(rel, dtype=f64),
            np.ascontiguousarray(vel_all, dtype=f64), np.ascontiguousarray(rad_all, dtype=f64),
            np.asarray(share, dtype=f64), obstacles.points, obstacles.directions, obstacles.next, obstacles.previous,
            obstacles.convex, edge_arr, edge_counts, np.ascontiguousarray(gaps, dtype=f64),
            np.ascontiguousarray(away, dtype=f64), np.ascontiguousarray(close, dtype=bool), near_arr, counts, new_v,
            bad)
        if n_bad:
            self._velocities_python(obstacles, x, v, pref, max_speed, rel, vel_all, rad_all, share, edges, gaps, away,
                                    close, near, h, only=np.flatnonzero(bad).tolist(), out=new_v)
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

    def _velocity(self, i: int, vi: list[float], pref: list[float], max_speed: float, vertices: ObstacleVertices,
                  edges: list[int], statics: list[int], near: list[int], rows: _Rows, share: list[float],
                  h: float) -> tuple[float, float]:
        """The new velocity (cm/s) of own pedestrian ``i`` moving at ``vi``: ``edges`` are the wall and polygon
        edges within its reach (nearest first), ``statics`` the circles within it, ``near`` its neighbours
        (indices into ``rows``)."""
        c = self.config
        velocity = (vi[0], vi[1])
        r = rows.radii[i]
        position = (rows.x[i][0], rows.x[i][1])
        lines: list[Line] = edge_lines(vertices, edges, position, velocity, r, c.time_horizon_obst_s)
        gaps, away = rows.gaps[i], rows.away[i]
        for k in statics:
            # the nearest point of the rim, relative to the pedestrian (cm)
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


def _padded(rows: list[list[int]], width: int) -> tuple[np.ndarray, np.ndarray]:
    """Index lists as one (n, ``width``) int64 array, zero-padded, and their lengths (n,): the kernel's form."""
    arr = np.zeros((len(rows), width), dtype=np.int64)
    counts = np.zeros(len(rows), dtype=np.int64)
    for i, row in enumerate(rows):
        arr[i, :len(row)] = row
        counts[i] = len(row)
    return arr, counts


class _Rows:
    """One substep's inputs of :meth:`PedestrianOrcaModel._velocity` as Python floats: the own pedestrians'
    positions (n, 2) cm, relative positions (n, m, 2) of everyone from each own pedestrian (cm), velocities (m, 2)
    cm/s and radii (m,) cm of everyone (own pedestrians first), and each own pedestrian's gaps (n, C) cm to the
    static circles with the unit vectors (n, C, 2) pointing away from them."""

    def __init__(self, x: np.ndarray, rel: np.ndarray, vel: np.ndarray, radii: np.ndarray, gaps: np.ndarray,
                 away: np.ndarray) -> None:
        self.x, self.rel, self.vel, self.radii = x.tolist(), rel.tolist(), vel.tolist(), radii.tolist()
        self.gaps, self.away = gaps.tolist(), away.tolist()
