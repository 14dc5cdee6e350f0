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
from typing import TYPE_CHECKING

import numpy as np

from fuzzynav.numerics.portable_math import norm2

if TYPE_CHECKING:
    from fuzzynav.scenarios.scenario import DynamicObstacle


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
        self.lengths = np.array([len(p) for p in self.paths], dtype=int)
        #: a looping path of at least two points goes round again after its last waypoint
        self.loop_ok = np.array([bool(o.loop) for o in obstacles], dtype=bool) & (self.lengths > 1)
        # what a pedestrian without a waypoint to walk to prefers: its given velocity (constant-velocity ones), else
        # to stand
        self._standing = np.where(self.constant[:, None], self.start_velocities, 0.0)
        self._all_constant = bool(self.constant.all())
        self.padded = np.zeros((len(self.paths), max(1, int(self.lengths.max(initial=0))), 2))
        for i, path in enumerate(self.paths):
            self.padded[i, :len(path)] = path
        self.reset()

    def reset(self) -> None:
        """Back to the first target: the waypoint after the start (index 1)."""
        self.target = np.ones(len(self.paths), dtype=int)
        self._current = self._goals()  # the waypoints change only when a pedestrian reaches one

    def initial_velocities(self) -> np.ndarray:
        """Velocities at t = 0 (cm/s): the given velocity, or ``speed`` towards the second waypoint (0 when there
        is none)."""
        goal, has = self._current
        d = goal - self.starts
        return self._towards(d, norm2(d), has)

    def _goals(self) -> tuple[np.ndarray, np.ndarray]:
        """Each pedestrian's current waypoint (n, 2) cm and whether it has one (n,): none for constant-velocity
        pedestrians and after the last waypoint of a path without ``loop``."""
        k = self.target
        inside = k < self.lengths
        wrapped = self.loop_ok & ~inside
        index = np.where(inside, k, np.where(wrapped, k % np.maximum(self.lengths, 1), 0))
        has = (inside | wrapped) & ~self.constant
        return self.padded[np.arange(len(k)), index], has

    def _towards(self, d: np.ndarray, length: np.ndarray, has: np.ndarray) -> np.ndarray:
        """The preferred velocities: each waypoint pedestrian's ``speed`` along ``d`` (cm, to its current waypoint,
        ``length`` long; 0 without one, ``has`` False, or when it stands on it), the others' given velocity."""
        moving = has & (length > 0.0)
        # selections, not masked assignments: the same values (each moving row is d * (speed / length)), fewer numpy
        # calls; this runs in every substep of a reactive crowd
        scale = self.speeds / np.where(moving, length, 1.0)
        return np.where(moving[:, None], d * scale[:, None], self._standing)

    def preferred(self, positions: np.ndarray) -> np.ndarray:
        """Preferred velocities (n, 2) cm/s at ``positions`` (n, 2) cm, first moving each pedestrian that has
        reached its waypoint on to the next one."""
        if self._all_constant:
            return self.start_velocities.copy()
        goal, has = self._current
        d = goal - positions
        length = norm2(d)
        # a waypoint reached: on to the next (at most one per call: the steps are shorter than the legs)
        arrived = has & (length <= self.arrive_cm)
        if arrived.any():
            self.target[arrived] += 1
            # keep the index small on a long loop
            self.target = np.where(self.loop_ok & (self.target >= 2 * self.lengths), self.target - self.lengths,
                                   self.target)
            self._current = goal, has = self._goals()
            d = goal - positions
            length = norm2(d)
        return self._towards(d, length, has)
