"""Where a reactive pedestrian wants to go: its scenario path read as an intent.

- ``start`` + ``velocity``: it wants to keep walking at that velocity (preferred velocity, cm/s);
- ``waypoints`` + ``speed`` (+ ``loop``): it starts at the first waypoint and walks towards each next one at
  ``speed`` cm/s, the next once it is within ``arrive_cm`` of it; after the last it stands (or, with ``loop``,
  heads back to the first and goes round again).

Reactive models (social force, ORCA) steer between this preferred velocity and what they avoid.
Positions in cm, velocities in cm/s.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fuzzynav.portable_math import norm2
from fuzzynav.scenario import DynamicObstacle


class Intent:
    """Preferred velocities of a group of pedestrians, with their progress along their waypoints."""

    def __init__(self, obstacles: Sequence[DynamicObstacle], arrive_cm: float) -> None:
        self.arrive_cm = arrive_cm
        self.starts = np.array([o.start if o.waypoints is None else o.waypoints[0] for o in obstacles],
                               dtype=float).reshape(-1, 2)
        self.constant = np.array([o.waypoints is None for o in obstacles], dtype=bool)
        self.start_velocities = np.array([o.velocity if o.waypoints is None else (0.0, 0.0) for o in obstacles],
                                         dtype=float).reshape(-1, 2)
        self.speeds = np.array([norm2(np.array(o.velocity, float)) if o.waypoints is None else o.speed
                                for o in obstacles], dtype=float)
        self.paths = [np.array(o.waypoints, float) if o.waypoints is not None else np.zeros((0, 2))
                      for o in obstacles]
        self.loops = [bool(o.loop) for o in obstacles]
        self.reset()

    def reset(self) -> None:
        """Back to the first target: the waypoint after the start (index 1)."""
        self.target = np.ones(len(self.paths), dtype=int)

    def initial_velocities(self) -> np.ndarray:
        """Velocities at t = 0 (cm/s): the given velocity, or ``speed`` towards the second waypoint (0 when there
        is none)."""
        vel = self.start_velocities.copy()
        for i in np.nonzero(~self.constant)[0]:
            vel[i] = self._towards(int(i), self.starts[i])
        return vel

    def _goal_of(self, i: int) -> np.ndarray | None:
        path = self.paths[i]
        k = int(self.target[i])
        if k < len(path):
            return path[k]
        if self.loops[i] and len(path) > 1:
            return path[k % len(path)]
        return None

    def _towards(self, i: int, position: np.ndarray) -> np.ndarray:
        goal = self._goal_of(i)
        if goal is None:
            return np.zeros(2)
        d = goal - position
        length = float(norm2(d))
        if length == 0.0:
            return np.zeros(2)
        return d * (self.speeds[i] / length)

    def preferred(self, positions: np.ndarray) -> np.ndarray:
        """Preferred velocities (n, 2) cm/s at ``positions`` (n, 2) cm, first moving each pedestrian that has
        reached its waypoint on to the next one."""
        pref = self.start_velocities.copy()
        for i in np.nonzero(~self.constant)[0]:
            i = int(i)
            goal = self._goal_of(i)
            # a waypoint reached: on to the next (at most one per call: the steps are shorter than the legs)
            if goal is not None and float(norm2(goal - positions[i])) <= self.arrive_cm:
                self.target[i] += 1
                if self.loops[i] and self.target[i] >= 2 * len(self.paths[i]):
                    self.target[i] -= len(self.paths[i])  # keep the index small on a long loop
            pref[i] = self._towards(i, positions[i])
        return pref
