"""The rows of the Trajectory Prediction Table (paper section III.C; :mod:`fuzzynav.planning.tpt` builds the table
around them): the robot moving straight to its goal, each obstacle at constant velocity, and the collision marks
of those positions. One definition for the planner, which makes the tables, and the analysis, which checks that a
logged table is the one its first row makes (:mod:`analysis.episode_check`); the recorded logs depend on these
operations to the last bit (see :mod:`fuzzynav.numerics.geometry`). Units: cm, s, cm/s.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fuzzynav.numerics.geometry import closest_approach
from fuzzynav.numerics.portable_math import hypot, norm2


def predict_robot(position: Sequence[float], goal: Sequence[float], speed: float, dt: float,
                  n: int) -> np.ndarray:
    """Positions (n+1, 2) cm of a robot at ``position`` (cm) moving straight to ``goal`` (cm) at ``speed`` cm/s,
    stopping on it, sampled every ``dt`` s."""
    p = np.asarray(position, dtype=float)
    g = np.asarray(goal, dtype=float)
    d = g - p
    dist = hypot(float(d[0]), float(d[1]))
    steps = np.arange(n + 1) * speed * dt
    travel = np.minimum(steps, dist)
    unit = d / dist if dist > 0 else np.zeros(2)
    return p + travel[:, None] * unit


def table_rows(position: Sequence[float], goal: Sequence[float], speed: float, pos0: np.ndarray,
               vel: np.ndarray, radii: np.ndarray, robot_radius: float, n_traj: int, dt: float,
               safety_margin: float, swept: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The table's robot rows (n+1, 2) cm, obstacle rows (n+1, J, 2) cm and collision marks (n+1, J), by numpy: the
    robot from ``position`` to ``goal`` (cm) at ``speed`` cm/s (:func:`predict_robot`), the tracks from their
    positions ``pos0`` (J, 2) cm at velocities ``vel`` (J, 2) cm/s, marked where closer than ``robot_radius`` +
    ``radii`` (J,) + ``safety_margin`` (cm; between two rows too with ``swept``), every ``dt`` s. The analysis
    recomputes a logged table with it (:mod:`analysis.episode_check`)."""
    robot = predict_robot(position, goal, speed, dt, n_traj)
    k = np.arange(n_traj + 1)[:, None, None] * dt
    obstacles = pos0[None, :, :] + vel[None, :, :] * k
    rel = obstacles - robot[:, None, :]  # (n+1, J, 2)
    limit = robot_radius + radii[None, :] + safety_margin
    collide = norm2(rel) < limit
    if swept and len(radii):
        # the relative motion over each step from the table's rows, not geometry.swept_distance's
        # (p1 - p0) - (o1 - o0): the two round differently and the recorded tables depend on these bits
        between = closest_approach(rel[:-1], rel[1:] - rel[:-1]) < limit
        earlier = collide[:-1].copy()  # a pass that starts in a marked predicted row is already in the table
        earlier[0] = False  # ... but row 0 is the present, not a prediction
        collide[1:] |= between & ~earlier
    return robot, obstacles, collide
