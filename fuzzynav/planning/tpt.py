"""Trajectory Prediction Table (paper section III.C, Table 2).

Row ``k`` (k = 1 .. n_traj) is the prediction for time ``now + k·dt``; row 0 holds the present. The
robot is predicted to move straight towards the target at ``speed`` — the speed the policy will command
next if no plan intervenes (stopping on the target); every tracked obstacle at constant velocity.
``collide[k, j]`` is True when robot and obstacle j are closer than the sum of their radii plus
``safety_margin_cm`` at step k, as in the paper's table. With ``swept`` (default, ours) a collision that
happens only *between* two samples — the discs come too close between step k-1 and step k although
neither sample is marked (both move straight within a step, so the closest approach is exact) — marks
step k too: sampling alone misses an obstacle passing the robot between two steps (at 1 s steps, a
30 cm/s obstacle meeting a 40 cm/s robot closes 70 cm per step). Collisions the samples see keep exactly
the paper's rows. Row 0 (the present) is not a predicted row: a robot already inside the margin has
step 1 marked (the motion from now to step 1 starts too close), so the planner moves it out instead of
seeing an empty table. Units: cm, s, cm/s.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fuzzynav.numerics.geometry import wrap_360
from fuzzynav.numerics.portable_math import atan2_deg_array
from fuzzynav.numerics.prediction import predict_robot, table_rows
from fuzzynav.sensing.tracking import Track


@dataclass(frozen=True)
class TrajectoryPredictionTable:
    """The table as arrays (row 0 = now, rows 1..n_traj = future steps).

    ``robot``: (n_traj+1, 2) cm; ``obstacles``: (n_traj+1, J, 2) cm; ``collide``: (n_traj+1, J) bool;
    ``obstacle_ids``, ``obstacle_radii`` (cm), ``obstacle_angles_deg`` (moving angle φ); the robot's
    predicted speed (cm/s), its radius and the safety margin (cm), ``dt`` (s)."""

    robot: np.ndarray
    obstacles: np.ndarray
    collide: np.ndarray
    obstacle_ids: tuple[int, ...]
    obstacle_radii: np.ndarray
    obstacle_velocities: np.ndarray
    robot_speed: float
    robot_radius: float
    safety_margin: float
    dt: float
    goal: tuple[float, float]

    @property
    def n_traj(self) -> int:
        return self.robot.shape[0] - 1

    @property
    def obstacle_angles_deg(self) -> np.ndarray:
        """Moving angle φ of each obstacle, degrees [0, 360)."""
        v = self.obstacle_velocities.reshape(-1, 2)
        return wrap_360(atan2_deg_array(v[:, 1], v[:, 0]))

    @property
    def any_collision(self) -> bool:
        return bool(self.collide[1:].any())

    def first_collision(self) -> tuple[int, int] | None:
        """(tc, obstacle column) of the earliest predicted collision in rows 1..n_traj, or None.

        Follows the listing's loop order: time outer, obstacles inner."""
        rows, cols = np.nonzero(self.collide[1:])
        if len(rows) == 0:
            return None
        return int(rows[0]) + 1, int(cols[0])

    def robot_at(self, k: int) -> np.ndarray:
        """Robot position (cm) at step k, extrapolated beyond the table (needed for tG = n_traj + 1)."""
        return predict_robot(self.robot[0], self.goal, self.robot_speed, self.dt, k)[-1]

    def obstacles_at(self, k: float) -> np.ndarray:
        """Obstacle positions (J, 2) cm at (possibly fractional or beyond-table) step k."""
        return self.obstacles[0] + self.obstacle_velocities * (k * self.dt)


def build_tpt(position: Sequence[float], goal: Sequence[float], speed: float, tracks: Sequence[Track],
              robot_radius: float, n_traj: int = 9, dt: float = 1.0, safety_margin: float = 10.0,
              swept: bool = True) -> TrajectoryPredictionTable:
    """Build the table for a robot at ``position`` (cm) heading for ``goal`` at ``speed`` (cm/s)."""
    if n_traj < 1:
        raise ValueError(f"planner.n_traj: must be >= 1, got {n_traj}")
    j = len(tracks)
    pos0 = np.array([[t.x, t.y] for t in tracks], dtype=float).reshape(j, 2)
    vel = np.array([[t.vx, t.vy] for t in tracks], dtype=float).reshape(j, 2)
    radii = np.array([t.radius for t in tracks], dtype=float)
    robot, obstacles, collide = table_rows(position, goal, speed, pos0, vel, radii, robot_radius, n_traj, dt,
                                           safety_margin, swept)
    return TrajectoryPredictionTable(
        robot=robot, obstacles=obstacles, collide=collide, obstacle_ids=tuple(t.id for t in tracks),
        obstacle_radii=radii, obstacle_velocities=vel, robot_speed=float(speed),
        robot_radius=float(robot_radius), safety_margin=float(safety_margin), dt=float(dt),
        goal=(float(goal[0]), float(goal[1])))
